//! `isoline synth`: the simulator's frames and truth as files.

use std::io::Write;
use std::path::PathBuf;

use anyhow::{Context, Result};

use isoline::format::{FrameRecord, PolylineJson, TruthFile, TruthFrame};
use isoline::geom::Polyline;
use isoline::synth::{self, Shape, SynthParams};

/// `isoline synth` options.
#[derive(clap::Args)]
pub struct Args {
    /// circle, ellipse, square, star, c, two-circles or annulus.
    shape: Shape,
    /// Points per frame.
    #[arg(long, default_value_t = 2000)]
    points: usize,
    /// Gaussian noise sigma per coordinate.
    #[arg(long, default_value_t = 0.0)]
    noise: f64,
    /// Fraction of points that are outliers.
    #[arg(long, default_value_t = 0.0)]
    outliers: f64,
    /// Density variation along the curve, in [0, 1).
    #[arg(long, default_value_t = 0.0)]
    density: f64,
    /// Number of frames.
    #[arg(long, default_value_t = 1)]
    frames: usize,
    /// Largest displacement between frames.
    #[arg(long, default_value_t = 0.0)]
    motion: f64,
    /// Random seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Stream id written in each frame.
    #[arg(long, default_value = "synth")]
    stream: String,
    /// Output NDJSON frame stream.
    #[arg(short, long)]
    output: PathBuf,
    /// Output truth file.
    #[arg(long)]
    truth: Option<PathBuf>,
}

/// Writes the frames and, if asked, the truth.
pub fn run(a: Args) -> Result<()> {
    let mut p = SynthParams::new(a.shape);
    p.points = a.points;
    p.noise = a.noise;
    p.outliers = a.outliers;
    p.density_variation = a.density;
    p.frames = a.frames;
    p.motion = a.motion;
    p.seed = a.seed;
    let mut frames = synth::generate(&p).map_err(anyhow::Error::msg)?;
    // Seven decimals (quantisation 5e-8 on unit-scale shapes, far below any noise or
    // mesh size) halve the files.
    let round = |q: &mut [f64; 2]| *q = q.map(|c| (c * 1e7).round() / 1e7);
    for f in &mut frames {
        f.points.iter_mut().for_each(round);
        f.truth
            .iter_mut()
            .flat_map(|pl| pl.points.iter_mut())
            .for_each(round);
    }
    let mut out = std::io::BufWriter::new(super::create(&a.output)?);
    for f in &frames {
        let rec = FrameRecord {
            stream: Some(a.stream.clone()),
            frame: f.frame,
            t: Some(f.t),
            points: f.points.clone(),
            origin: None,
        };
        serde_json::to_writer(&mut out, &rec)?;
        out.write_all(b"\n")?;
    }
    out.flush()
        .with_context(|| format!("writing {}", a.output.display()))?;
    if let Some(path) = a.truth {
        let pj = |pls: &[Polyline]| pls.iter().map(PolylineJson::from).collect::<Vec<_>>();
        let file = TruthFile {
            polylines: pj(&frames[0].truth),
            frames: (frames.len() > 1).then(|| {
                frames
                    .iter()
                    .map(|f| TruthFrame {
                        frame: f.frame,
                        polylines: pj(&f.truth),
                    })
                    .collect()
            }),
        };
        let w = std::io::BufWriter::new(super::create(&path)?);
        serde_json::to_writer(w, &file).with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}
