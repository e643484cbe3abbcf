//! The `isoline` command line.

use std::io::{BufRead, Write};
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use clap::{Parser, Subcommand};
use serde_json::json;

use isoline::config::Config;
use isoline::eval;
use isoline::export::svg;
use isoline::format::{FrameRecord, PolylineJson, TruthFile, TruthFrame};
use isoline::geom::Polyline;
use isoline::meshing::adapt_to_points;
use isoline::synth::{self, Shape, SynthParams};

#[derive(Parser)]
#[command(
    name = "isoline",
    version,
    about = "Level-set curve reconstruction from noisy 2D points"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Simulate a scanner: sample a shape with noise, outliers and motion.
    Synth {
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
    },
    /// Accuracy of a reconstruction against a truth file, as JSON.
    Eval {
        /// Polylines: NDJSON result records or a JSON file with "polylines".
        recon: PathBuf,
        /// Truth file written by `isoline synth`.
        #[arg(long)]
        truth: PathBuf,
    },
    /// Adapt an anisotropic mesh to a point set and draw it.
    Mesh {
        /// Point file, or NDJSON frame stream (first frame unless --frame).
        input: PathBuf,
        /// TOML configuration ([mesh] table).
        #[arg(short, long)]
        config: Option<PathBuf>,
        /// Frame of an NDJSON input.
        #[arg(long)]
        frame: Option<u64>,
        /// Isotropic comparison mesh (size hmin in the band).
        #[arg(long)]
        isotropic: bool,
        /// SVG drawing of the mesh over the points.
        #[arg(short, long)]
        output: Option<PathBuf>,
        /// Mesh statistics as JSON.
        #[arg(long)]
        stats: Option<PathBuf>,
    },
}

fn main() {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "warn".into()),
        )
        .with_writer(std::io::stderr)
        .init();
    if let Err(e) = run(Cli::parse()) {
        eprintln!("isoline: {e:#}");
        std::process::exit(1);
    }
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Synth {
            shape,
            points,
            noise,
            outliers,
            density,
            frames,
            motion,
            seed,
            stream,
            output,
            truth,
        } => {
            let mut p = SynthParams::new(shape);
            p.points = points;
            p.noise = noise;
            p.outliers = outliers;
            p.density_variation = density;
            p.frames = frames;
            p.motion = motion;
            p.seed = seed;
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
            let mut out = std::io::BufWriter::new(create(&output)?);
            for f in &frames {
                let rec = FrameRecord {
                    stream: Some(stream.clone()),
                    frame: f.frame,
                    t: Some(f.t),
                    points: f.points.clone(),
                    origin: None,
                };
                serde_json::to_writer(&mut out, &rec)?;
                out.write_all(b"\n")?;
            }
            out.flush()
                .with_context(|| format!("writing {}", output.display()))?;
            if let Some(path) = truth {
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
                let w = std::io::BufWriter::new(create(&path)?);
                serde_json::to_writer(w, &file)
                    .with_context(|| format!("writing {}", path.display()))?;
            }
            Ok(())
        }
        Command::Eval { recon, truth } => {
            let truth_file: TruthFile = serde_json::from_str(&read(&truth)?)
                .with_context(|| format!("{}: not a truth file", truth.display()))?;
            let records = read_polyline_records(&recon)?;
            let results: Vec<serde_json::Value> = records
                .iter()
                .map(|(frame, pls)| {
                    let acc = eval::compare(pls, &truth_file.for_frame(*frame), None);
                    let mut v = accuracy_json(&acc);
                    if let Some(f) = frame {
                        v["frame"] = json!(f);
                    }
                    v
                })
                .collect();
            let out = if results.len() == 1 {
                results.into_iter().next().unwrap()
            } else {
                let worst = results
                    .iter()
                    .map(|r| r["hausdorff"].as_f64().unwrap_or(f64::INFINITY))
                    .fold(0.0, f64::max);
                json!({ "hausdorff": finite(worst), "frames": results })
            };
            println!("{out}");
            Ok(())
        }
        Command::Mesh {
            input,
            config,
            frame,
            isotropic,
            output,
            stats,
        } => {
            let cfg = match &config {
                Some(p) => Config::load(p)?,
                None => Config::default(),
            };
            let mut params = cfg.mesh_params();
            params.isotropic |= isotropic;
            let points = isoline::ingest::read_points(&input, frame)?;
            let m = adapt_to_points(&points, &params)
                .with_context(|| format!("meshing {}", input.display()))?;
            let s = &m.stats;
            let summary = json!({
                "vertices": s.vertices,
                "triangles": s.triangles,
                "edges": s.edges,
                "edges_unit_share": s.edges_unit_share,
                "median_edge_length": s.median_edge_length,
                "min_quality": s.min_quality,
                "mean_quality": s.mean_quality,
                "points": points.len(),
                "passes": m.report.passes,
                "converged": m.report.converged,
                "vertex_cap_reached": m.report.vertex_cap_reached,
                "hmin": m.params.hmin,
                "hmax": m.params.hmax,
                "eps": m.params.eps,
                "band": m.params.band,
                "isotropic": m.params.isotropic,
                "noise_estimate": m.noise_estimate,
                "ms": {
                    "distance": m.ms.distance,
                    "metric": m.ms.metric,
                    "adapt": m.ms.adapt,
                    "total": m.ms.total,
                },
            });
            if let Some(path) = output {
                let doc = svg::render(
                    &svg::Drawing {
                        mesh: Some(&m.mesh),
                        points: &points,
                        view: Some(m.domain),
                        ..Default::default()
                    },
                    1600.0,
                );
                std::fs::write(&path, doc)
                    .with_context(|| format!("writing {}", path.display()))?;
            }
            match stats {
                Some(path) => std::fs::write(&path, format!("{summary:#}\n"))
                    .with_context(|| format!("writing {}", path.display()))?,
                None => println!("{summary}"),
            }
            Ok(())
        }
    }
}

fn finite(x: f64) -> serde_json::Value {
    if x.is_finite() {
        json!(x)
    } else {
        serde_json::Value::Null
    }
}

fn accuracy_json(a: &eval::Accuracy) -> serde_json::Value {
    json!({
        "hausdorff": a.hausdorff,
        "mean_distance": a.mean_distance,
        "recon_to_truth": a.recon_to_truth,
        "truth_to_recon": a.truth_to_recon,
        "components_truth": a.components_truth,
        "components_recon": a.components_recon,
    })
}

fn create(path: &Path) -> Result<std::fs::File> {
    std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))
}

fn read(path: &Path) -> Result<String> {
    std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))
}

/// Polylines per record: a JSON document with "polylines", or NDJSON records with
/// "polylines" (and "frame"); error records fail with their frame named.
fn read_polyline_records(path: &Path) -> Result<Vec<(Option<u64>, Vec<Polyline>)>> {
    #[derive(serde::Deserialize)]
    struct Rec {
        frame: Option<u64>,
        polylines: Option<Vec<PolylineJson>>,
        error: Option<String>,
    }
    let text = read(path)?;
    let parse = |s: &str, line: usize| -> Result<(Option<u64>, Vec<Polyline>)> {
        let r: Rec = serde_json::from_str(s)
            .with_context(|| format!("{}, line {line}: not a polyline record", path.display()))?;
        match (r.polylines, r.error) {
            (Some(p), _) => Ok((r.frame, p.into_iter().map(Into::into).collect())),
            (None, Some(e)) => bail!(
                "{}, line {line}: frame {:?} is an error record: {e}",
                path.display(),
                r.frame
            ),
            (None, None) => bail!("{}, line {line}: no \"polylines\"", path.display()),
        }
    };
    if let Ok(whole) = parse(&text, 1) {
        return Ok(vec![whole]);
    }
    let mut out = Vec::new();
    for (i, line) in text.as_bytes().lines().enumerate() {
        let line = line?;
        if !line.trim().is_empty() {
            out.push(parse(&line, i + 1)?);
        }
    }
    if out.is_empty() {
        bail!("{}: no polyline records", path.display());
    }
    Ok(out)
}
