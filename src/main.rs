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
use isoline::mesh::adapt_to_points;
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
    /// Reconstruct curves from a point file or from each frame of an NDJSON stream.
    Reconstruct {
        /// Point file (`x y` per line) or NDJSON frame stream (.ndjson/.jsonl).
        input: PathBuf,
        /// TOML configuration ([mesh], [solver], [export] tables).
        #[arg(short, long)]
        config: Option<PathBuf>,
        /// Output; the extension picks the format: .ndjson .json .geojson .csv .svg.
        /// Default: NDJSON on stdout.
        #[arg(short, long)]
        output: Option<PathBuf>,
        /// Per-frame statistics as JSON (an object, or an array for several frames).
        #[arg(long)]
        stats: Option<PathBuf>,
        /// Only this frame of an NDJSON input.
        #[arg(long)]
        frame: Option<u64>,
        /// Override the configured scheme: explicit or semi-implicit.
        #[arg(long)]
        scheme: Option<isoline::levelset::Scheme>,
        /// Override the configured starting curve: medial, tube, box or circle.
        #[arg(long)]
        init: Option<isoline::levelset::Init>,
        /// Draw the mesh in SVG output.
        #[arg(long)]
        mesh: bool,
    },
    /// Reconstruct many files in parallel, as a TOML job file says.
    Batch {
        /// Job file: [batch] inputs, output, formats, workers; [mesh] [solver] [export];
        /// [files."GLOB".*] overrides.
        #[arg(short, long)]
        config: PathBuf,
        /// Redo inputs whose outputs are up to date.
        #[arg(long)]
        force: bool,
    },
    /// The streaming daemon: frames from a file, stdin or TCP through the staged
    /// pipeline, each warm-started from the previous frame of its stream.
    Run {
        /// Daemon configuration: [input] [output] [pipeline] [tracing], and [mesh]
        /// [solver] [export].
        #[arg(short, long)]
        config: PathBuf,
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
    let cli = Cli::parse();
    let result = match &cli.command {
        Command::Run { config } => daemon_cmd(config),
        _ => init_tracing("warn", None).and_then(|_| run(cli)),
    };
    if let Err(e) = result {
        eprintln!("isoline: {e:#}");
        std::process::exit(1);
    }
}

/// Logs to stderr, filtered by `RUST_LOG` or else `default`; with `chrome`, also writes
/// every span of isoline's stages (whatever the log filter) as a Chrome/Perfetto trace,
/// complete once the returned guard is dropped.
fn init_tracing(
    default: &str,
    chrome: Option<&Path>,
) -> Result<Option<tracing_chrome::FlushGuard>> {
    use tracing_subscriber::prelude::*;
    use tracing_subscriber::EnvFilter;
    let filter = EnvFilter::try_from_default_env().unwrap_or_else(|_| EnvFilter::new(default));
    let (chrome_layer, guard) = match chrome {
        Some(path) => {
            let file = create(path)?;
            let (layer, guard) = tracing_chrome::ChromeLayerBuilder::new()
                .writer(file)
                .include_args(true)
                .build();
            let spans = tracing_subscriber::filter::Targets::new()
                .with_target("isoline", tracing::Level::INFO);
            (Some(layer.with_filter(spans)), Some(guard))
        }
        None => (None, None),
    };
    tracing_subscriber::registry()
        .with(
            tracing_subscriber::fmt::layer()
                .with_writer(std::io::stderr)
                .with_filter(filter),
        )
        .with(chrome_layer)
        .try_init()
        .context("setting up tracing")?;
    Ok(guard)
}

/// `isoline run`: the daemon until end of input or a signal. The first SIGINT or SIGTERM
/// stops ingest and lets the frames in flight finish; a second one exits at once.
fn daemon_cmd(config: &Path) -> Result<()> {
    use std::sync::atomic::AtomicBool;
    use std::sync::Arc;
    let cfg = isoline::pipeline::DaemonConfig::load(config)?;
    let guard = init_tracing(&cfg.log, cfg.chrome_trace.as_deref())?;
    let stop = Arc::new(AtomicBool::new(false));
    for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        // Registered first, so it sees the flag as the previous signal left it.
        signal_hook::flag::register_conditional_shutdown(sig, 130, stop.clone())
            .context("installing signal handlers")?;
        signal_hook::flag::register(sig, stop.clone()).context("installing signal handlers")?;
    }
    let daemon = isoline::pipeline::Daemon::start(&cfg, stop)?;
    if let Some(addr) = daemon.tcp_addr {
        eprintln!("isoline run: listening on {addr}");
    }
    let summary = daemon.wait()?;
    drop(guard);
    eprintln!("isoline run: {summary}");
    Ok(())
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
        Command::Reconstruct {
            input,
            config,
            output,
            stats,
            frame,
            scheme,
            init,
            mesh,
        } => {
            let cfg = match &config {
                Some(p) => Config::load(p)?,
                None => Config::default(),
            };
            let mut params = cfg.params();
            if let Some(s) = scheme {
                params.solver.scheme = s;
            }
            if let Some(i) = init {
                params.solver.init = i;
            }
            reconstruct_cmd(
                &input,
                &params,
                output.as_deref(),
                stats.as_deref(),
                frame,
                mesh,
            )
        }
        Command::Batch { config, force } => batch_cmd(&config, force),
        Command::Run { .. } => unreachable!("handled in main"),
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

/// `isoline batch`: a progress bar on a terminal, a log line per file otherwise, and the
/// summary table at the end; fails when a file failed.
fn batch_cmd(config: &Path, force: bool) -> Result<()> {
    use std::io::IsTerminal;
    let job = isoline::batch::Job::load(config)?;
    let n = job.tasks.len();
    let bar = std::io::stderr().is_terminal().then(|| {
        let b = indicatif::ProgressBar::new(n as u64);
        b.set_style(
            indicatif::ProgressStyle::with_template(
                "{elapsed_precise} [{bar:40}] {pos}/{len} files, {per_sec}, eta {eta} {msg}",
            )
            .expect("valid template")
            .progress_chars("=> "),
        );
        b
    });
    let done = std::sync::atomic::AtomicUsize::new(0);
    eprintln!(
        "isoline batch: {n} files, {} workers, output {}",
        job.workers,
        job.output.display()
    );
    let summary = job.run(force, |f| {
        let k = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
        match &bar {
            Some(b) => {
                b.set_message(f.file.clone());
                b.inc(1);
            }
            None => eprintln!(
                "[{k}/{n}] {} {}{} ({:.0} ms)",
                f.file,
                f.status,
                f.reason
                    .as_deref()
                    .map(|r| format!(": {r}"))
                    .unwrap_or_default(),
                f.ms
            ),
        }
    })?;
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    println!(
        "{:<40} {:>8} {:>7} {:>9} {:>9} {:>9} {:>10} {:>9}",
        "file", "status", "points", "polylines", "vertices", "iterations", "residual", "ms"
    );
    for f in &summary.files {
        let name = Path::new(&f.file)
            .file_name()
            .map_or(f.file.clone(), |n| n.to_string_lossy().into_owned());
        println!(
            "{:<40} {:>8} {:>7} {:>9} {:>9} {:>9} {:>10.2e} {:>9.0}",
            name, f.status, f.points, f.polylines, f.vertices, f.iterations, f.residual, f.ms
        );
        if let Some(r) = &f.reason {
            println!("    {r}");
        }
    }
    let t = &summary.totals;
    println!(
        "total: {} files, {} reconstructed, {} skipped, {} failed; {} points, {} polylines; {:.1} s, {:.2} files/s",
        t.files, t.ok, t.skipped, t.failed, t.points, t.polylines, t.ms / 1e3, t.files_per_second
    );
    println!("summary: {}", job.output.join("summary.json").display());
    if t.failed > 0 {
        bail!(
            "{} of {} files failed (reasons in summary.json)",
            t.failed,
            t.files
        );
    }
    Ok(())
}

/// `isoline reconstruct`: one record per frame, written in the output's format.
fn reconstruct_cmd(
    input: &Path,
    params: &isoline::Params,
    output: Option<&Path>,
    stats: Option<&Path>,
    frame: Option<u64>,
    draw_mesh: bool,
) -> Result<()> {
    use isoline::export::writers::{self, Format};

    let format = match output {
        None => Format::Ndjson,
        Some(p) => Format::from_path(p).with_context(|| {
            format!(
                "{}: unknown output extension (use .ndjson, .json, .geojson, .csv or .svg)",
                p.display()
            )
        })?,
    };
    let all = isoline::ingest::read_input(input)?;
    let frames: Vec<FrameRecord> = match frame {
        Some(f) => all.into_iter().filter(|r| r.frame == f).collect(),
        None => all,
    };
    if frames.is_empty() {
        bail!(
            "{}: no frame {}",
            input.display(),
            frame.map_or("at all".into(), |f| f.to_string())
        );
    }
    if format == Format::Svg && frames.len() > 1 {
        bail!(
            "{} has {} frames and an SVG holds one: pick one with --frame",
            input.display(),
            frames.len()
        );
    }
    let mut records = Vec::with_capacity(frames.len());
    let mut last = None;
    let mut failed = 0;
    for f in &frames {
        let (rec, r) = isoline::reconstruct::reconstruct_frame(f, params);
        if let Some(e) = &rec.error {
            failed += 1;
            let what = if frames.len() > 1 || f.stream.is_some() {
                format!("{}, frame {}: {e}", input.display(), f.frame)
            } else {
                format!("{}: {e}", input.display())
            };
            if frames.len() == 1 {
                bail!(what);
            }
            eprintln!("isoline: {what}");
        }
        if r.is_some() {
            last = r;
        }
        records.push(rec);
    }
    let text = match format {
        Format::Svg => {
            let r = last.as_ref().expect("one frame, reconstructed");
            let pts = &frames[0].points;
            svg::render(
                &svg::Drawing {
                    mesh: draw_mesh.then_some(&r.mesh),
                    points: pts,
                    polylines: &r.polylines,
                    view: isoline::geom::BBox::of(pts).map(|b| b.padded(0.05 * b.diag())),
                },
                1200.0,
            )
        }
        other => writers::render(other, &records),
    };
    match output {
        Some(p) => std::fs::write(p, text).with_context(|| format!("writing {}", p.display()))?,
        None => {
            let mut out = std::io::stdout().lock();
            out.write_all(text.as_bytes())?;
            out.flush()?;
        }
    }
    if let Some(path) = stats {
        let all: Vec<_> = records.iter().map(|r| &r.stats).collect();
        let v = if all.len() == 1 {
            serde_json::to_value(all[0])?
        } else {
            serde_json::to_value(&all)?
        };
        std::fs::write(path, format!("{v:#}\n"))
            .with_context(|| format!("writing {}", path.display()))?;
    }
    if failed > 0 {
        bail!(
            "{failed} of {} frames failed (error records written)",
            frames.len()
        );
    }
    Ok(())
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
