//! `isoline synth`: the simulators' frames and truth as files: a digitized shape, or a
//! scene seen by a 2D laser scanner.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};

use isoline_core::geom::Polyline;
use isoline_io::format::{
    FrameRecord, OpeningJson, PolylineJson, SensorJson, TruthFile, TruthFrame,
};
use isoline_sim::lidar::{self, LidarParams, SceneKind, SensorModel};
use isoline_sim::{self as synth, Shape, SynthParams};

/// `isoline synth` options.
#[derive(clap::Args)]
pub struct Args {
    /// A shape (circle, ellipse, square, star, c, two-circles, annulus, spiral, bays:
    /// points around closed curves; strokes: points along open strokes that meet) or a
    /// scene seen by a laser scanner (room, corridor, clutter; loop: a 926 m corridor
    /// loop with rooms, for long drives).
    what: String,
    /// Shapes: points per frame.
    #[arg(long, default_value_t = 2000)]
    points: usize,
    /// Shapes: Gaussian noise sigma per coordinate. Scenes: range noise (default the
    /// sensor's).
    #[arg(long)]
    noise: Option<f64>,
    /// Shapes: fraction of points that are outliers. Scenes: probability that a beam
    /// returns a spurious short range.
    #[arg(long, default_value_t = 0.0)]
    outliers: f64,
    /// Shapes: density variation along the curve, in [0, 1).
    #[arg(long, default_value_t = 0.0)]
    density: f64,
    /// Scenes: the sensor model (sick-tim, sick-lms1xx, hokuyo-utm30lx,
    /// hokuyo-urg04lx, rplidar-a1).
    #[arg(long, default_value = "hokuyo-utm30lx")]
    sensor: String,
    /// Scenes: probability that a beam returns nothing.
    #[arg(long, default_value_t = 0.0)]
    dropout: f64,
    /// Scenes: the sensor's pose "x,y,theta" (metres, radians) instead of the scene's.
    #[arg(long, value_parser = parse_pose)]
    pose: Option<[f64; 3]>,
    /// Shapes: the spiral's turn spacing and the bays' inlet width.
    #[arg(long, default_value_t = 0.05)]
    gap: f64,
    /// Number of frames.
    #[arg(long, default_value_t = 1)]
    frames: usize,
    /// Shapes: largest displacement between frames. Scenes: metres driven along the
    /// scene's path between frames.
    #[arg(long, default_value_t = 0.0)]
    motion: f64,
    /// Scenes: a person (a post 0.4 m across) walking back and forth across the scene
    /// at this speed, metres per second: in the scans and each frame's truth, not in the
    /// static scene.
    #[arg(long)]
    walker: Option<f64>,
    /// Scenes: beams taken one after another over the sensor's turn while it drives on
    /// (`--motion`), as a spinning scanner takes them; each frame carries its beams'
    /// `time_increment`.
    #[arg(long)]
    sweep: bool,
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

fn parse_pose(s: &str) -> std::result::Result<[f64; 3], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>().map_err(|e| format!("{x:?}: {e}")))
        .collect::<std::result::Result<_, _>>()?;
    match v[..] {
        [x, y, t] => Ok([x, y, t]),
        _ => Err(format!("expected x,y,theta, got {s:?}")),
    }
}

/// Writes the frames and, if asked, the truth.
pub fn run(a: Args) -> Result<()> {
    match SceneKind::named(&a.what) {
        Some(scene) => scan(a, scene),
        None => match a.what.parse::<Shape>() {
            Ok(shape) => shape_frames(a, shape),
            Err(e) => {
                let scenes: Vec<_> = SceneKind::ALL.iter().map(|s| s.name()).collect();
                bail!("{e}; or a scene: {}", scenes.join(", "))
            }
        },
    }
}

/// Seven decimals: quantisation 5e-8 on unit-scale shapes, far below any noise or mesh
/// size, and files half as long.
fn round7(q: &mut [f64; 2]) {
    *q = q.map(|c| (c * 1e7).round() / 1e7);
}

fn pj(pls: &[Polyline]) -> Vec<PolylineJson> {
    pls.iter().map(PolylineJson::from).collect()
}

fn write_frames(path: &Path, frames: impl Iterator<Item = FrameRecord>) -> Result<()> {
    let (part, file) = super::create_part(path)?;
    let mut out = std::io::BufWriter::new(file);
    for rec in frames {
        serde_json::to_writer(&mut out, &rec)?;
        out.write_all(b"\n")?;
    }
    out.flush()
        .with_context(|| format!("writing {}", path.display()))?;
    drop(out);
    part.commit()
        .with_context(|| format!("writing {}", path.display()))
}

fn write_truth(path: &Path, file: &TruthFile) -> Result<()> {
    let text = serde_json::to_vec(file)?;
    super::write(path, text)
}

fn shape_frames(a: Args, shape: Shape) -> Result<()> {
    let mut p = SynthParams::new(shape);
    p.points = a.points;
    p.noise = a.noise.unwrap_or(0.0);
    p.outliers = a.outliers;
    p.density_variation = a.density;
    p.frames = a.frames;
    p.motion = a.motion;
    p.seed = a.seed;
    p.gap = a.gap;
    let mut frames = synth::generate(&p).map_err(anyhow::Error::msg)?;
    for f in &mut frames {
        f.points.iter_mut().for_each(round7);
        f.truth
            .iter_mut()
            .flat_map(|pl| pl.points.iter_mut())
            .for_each(round7);
    }
    write_frames(
        &a.output,
        frames.iter().map(|f| FrameRecord {
            stream: Some(a.stream.clone()),
            frame: f.frame,
            t: Some(f.t),
            points: f.points.clone(),
            ..Default::default()
        }),
    )?;
    if let Some(path) = &a.truth {
        let file = TruthFile {
            polylines: pj(&frames[0].truth),
            frames: (frames.len() > 1).then(|| {
                frames
                    .iter()
                    .map(|f| TruthFrame {
                        frame: f.frame,
                        polylines: pj(&f.truth),
                        ..Default::default()
                    })
                    .collect()
            }),
            ..Default::default()
        };
        write_truth(path, &file)?;
    }
    Ok(())
}

fn scan(a: Args, scene: SceneKind) -> Result<()> {
    let mut p = LidarParams::new(scene);
    p.sensor = SensorModel::named(&a.sensor).map_err(anyhow::Error::msg)?;
    p.noise = a.noise;
    p.dropout = a.dropout;
    p.outliers = a.outliers;
    p.frames = a.frames;
    p.motion = a.motion;
    p.pose = a.pose;
    p.walker = a.walker;
    p.sweep = a.sweep;
    p.seed = a.seed;
    let frames = lidar::simulate(&p).map_err(anyhow::Error::msg)?;
    let r7 = |x: f64| (x * 1e7).round() / 1e7;
    write_frames(
        &a.output,
        frames.iter().map(|f| FrameRecord {
            stream: Some(a.stream.clone()),
            frame: f.frame,
            t: Some(r7(f.t)),
            ranges: Some(f.ranges.clone()),
            angle_min: Some(f.angle_min),
            angle_increment: Some(f.angle_increment),
            time_increment: (f.time_increment > 0.0).then_some(f.time_increment),
            range_min: Some(f.range_min),
            range_max: Some(f.range_max),
            pose: Some(f.pose.map(r7)),
            ..Default::default()
        }),
    )?;
    if let Some(path) = &a.truth {
        let truth_of = |f: &lidar::ScanFrame| {
            let mut t = f.truth.clone();
            t.iter_mut()
                .flat_map(|pl| pl.points.iter_mut())
                .for_each(round7);
            pj(&t)
        };
        let openings = |f: &lidar::ScanFrame| -> Vec<OpeningJson> {
            f.openings
                .iter()
                .map(|&(mut x, mut y)| {
                    round7(&mut x);
                    round7(&mut y);
                    [x, y]
                })
                .collect()
        };
        let file = TruthFile {
            polylines: truth_of(&frames[0]),
            openings: Some(openings(&frames[0])),
            frames: (frames.len() > 1).then(|| {
                frames
                    .iter()
                    .map(|f| TruthFrame {
                        frame: f.frame,
                        polylines: truth_of(f),
                        openings: Some(openings(f)),
                        pose: Some(f.pose.map(r7)),
                        walker: f.walker.map(|w| [r7(w[0]), r7(w[1]), lidar::WALKER_RADIUS]),
                    })
                    .collect()
            }),
            sensor: Some(SensorJson {
                name: p.sensor.name.into(),
                range_noise: p.noise.unwrap_or(p.sensor.noise),
                dropout: p.dropout,
                outliers: p.outliers,
            }),
            scene: Some(pj(&lidar::Scene::new(scene).polylines())),
            pose: Some(frames[0].pose.map(r7)),
        };
        write_truth(path, &file)?;
    }
    Ok(())
}
