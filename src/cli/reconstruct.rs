//! `isoline reconstruct`: curves from a point file or from each frame of a stream.

use std::path::PathBuf;

use anyhow::{bail, Context, Result};

use isoline_io::format::ResultRecord;
use isoline_io::foxglove::{FrameView, McapOut};
use isoline_io::write::svg;
use isoline_io::Item;

/// `isoline reconstruct` options.
#[derive(clap::Args)]
pub struct Args {
    /// Point file (`x y` per line), NDJSON frame stream (.ndjson/.jsonl), ROS 2 bag
    /// (.mcap) or CARMEN log (.log, .clf, .carmen, maybe .gz, or by its lines).
    input: PathBuf,
    /// TOML configuration ([mesh], [solver], [export] tables).
    #[arg(short, long)]
    config: Option<PathBuf>,
    /// Output; the extension picks the format: .ndjson .json .geojson .csv .svg, or
    /// .mcap (curves, points and records for Foxglove). Default: NDJSON on stdout.
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
    scheme: Option<isoline_core::Scheme>,
    /// Override the configured starting curve: medial, tube, box or circle.
    #[arg(long)]
    init: Option<isoline_core::Init>,
    /// Draw the mesh in SVG output.
    #[arg(long)]
    mesh: bool,
    #[command(flatten)]
    bag: super::BagArgs,
}

/// Reconstructs every frame (or `--frame`) and writes one record per frame in the
/// output's format; fails when a frame failed, after writing the others.
pub fn run(a: Args) -> Result<()> {
    use isoline_io::write::{self as writers, Format};

    let cfg = super::load_config(a.config.as_deref())?;
    let mut params = cfg.params();
    if let Some(s) = a.scheme {
        params.solver.scheme = s;
    }
    if let Some(i) = a.init {
        params.solver.init = i;
    }
    let params = &params;
    let (input, output, stats, frame, draw_mesh) = (
        a.input.as_path(),
        a.output.as_deref(),
        a.stats.as_deref(),
        a.frame,
        a.mesh,
    );

    let mcap = output.is_some_and(isoline_io::is_bag);
    let format = match output {
        None => Format::Ndjson,
        Some(_) if mcap => Format::Ndjson,
        Some(p) => Format::from_path(p).with_context(|| {
            format!(
                "{}: unknown output extension (use .ndjson, .json, .geojson, .csv, .svg or \
                 .mcap)",
                p.display()
            )
        })?,
    };
    super::refuse_overwrite(input, &[output, stats])?;
    let bag = a.bag.options(input)?;
    let all = isoline_io::read_items(input, &bag)?;
    let frames: Vec<Item> = match frame {
        Some(f) => all
            .into_iter()
            .filter(|r| match r {
                Ok(r) => r.frame == f,
                Err(b) => b.frame == Some(f),
            })
            .collect(),
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
    let mut out_mcap = match output {
        Some(p) if mcap => Some(McapOut::create(p)?),
        _ => None,
    };
    for item in &frames {
        let (rec, r) = match item {
            Ok(f) => isoline_io::reconstruct_frame(f, params),
            Err(b) => (
                ResultRecord {
                    stream: b.stream.clone(),
                    frame: b.frame,
                    error: Some(b.message.clone()),
                    ..Default::default()
                },
                None,
            ),
        };
        if let Some(e) = &rec.error {
            failed += 1;
            let what = match item {
                Err(_) => e.clone(),
                Ok(f) if frames.len() > 1 || f.stream.is_some() => {
                    format!("{}, frame {}: {e}", input.display(), f.frame)
                }
                Ok(_) => format!("{}: {e}", input.display()),
            };
            // One frame of points: the error is the answer. A recording's frames all
            // get records, whatever their number.
            if frames.len() == 1 && !isoline_io::is_recording(input) {
                bail!(what);
            }
            eprintln!("isoline: {what}");
        }
        if let Some(m) = &mut out_mcap {
            let f = item.as_ref().ok();
            m.write(&FrameView {
                record: rec.clone(),
                points: f.map(|f| f.points.clone()).unwrap_or_default(),
                t: f.and_then(|f| f.t),
                pose: f.and_then(|f| f.pose),
            })?;
        }
        if r.is_some() {
            last = r;
        }
        records.push(rec);
    }
    if let Some(m) = out_mcap {
        m.finish()?;
    } else {
        let text = match format {
            Format::Svg => {
                let r = last.as_ref().expect("one frame, reconstructed");
                let features: Vec<_> = r.features.iter().map(|f| f.center).collect();
                let points = frames[0]
                    .as_ref()
                    .map(|f| f.points.as_slice())
                    .unwrap_or(&[]);
                svg::render(
                    &svg::of_reconstruction(points, r, &features, &[], draw_mesh),
                    1200.0,
                )
            }
            other => writers::render(other, &records),
        };
        match output {
            Some(p) => super::write(p, text)?,
            None => super::print(&text)?,
        }
    }
    if let Some(path) = stats {
        let all: Vec<_> = records.iter().map(|r| &r.stats).collect();
        let v = if all.len() == 1 {
            serde_json::to_value(all[0])?
        } else {
            serde_json::to_value(&all)?
        };
        super::write(path, format!("{v:#}\n"))?;
    }
    if failed > 0 {
        bail!(
            "{failed} of {} frames failed (error records written)",
            frames.len()
        );
    }
    Ok(())
}
