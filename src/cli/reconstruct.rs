//! `isoline reconstruct`: curves from a point file or from each frame of a stream.

use std::path::PathBuf;

use anyhow::{bail, Context, Result};

use isoline::export::svg;
use isoline::ingest::Frame;

/// `isoline reconstruct` options.
#[derive(clap::Args)]
pub struct Args {
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
}

/// Reconstructs every frame (or `--frame`) and writes one record per frame in the
/// output's format; fails when a frame failed, after writing the others.
pub fn run(a: Args) -> Result<()> {
    use isoline::export::writers::{self, Format};

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

    let format = match output {
        None => Format::Ndjson,
        Some(p) => Format::from_path(p).with_context(|| {
            format!(
                "{}: unknown output extension (use .ndjson, .json, .geojson, .csv or .svg)",
                p.display()
            )
        })?,
    };
    super::refuse_overwrite(input, &[output, stats])?;
    let all = isoline::ingest::read_input(input)?;
    let frames: Vec<Frame> = match frame {
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
            let features: Vec<_> = r.features.iter().map(|f| f.center).collect();
            svg::render(
                &svg::of_reconstruction(&frames[0].points, r, &features, &[], draw_mesh),
                1200.0,
            )
        }
        other => writers::render(other, &records),
    };
    match output {
        Some(p) => super::write(p, text)?,
        None => super::print(&text)?,
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
