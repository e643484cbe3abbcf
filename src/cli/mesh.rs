//! `isoline mesh`: the adapted mesh of a point set, drawn, with its statistics.

use std::path::PathBuf;

use anyhow::{Context, Result};
use serde_json::json;

use isoline_core::stages::adapt_to_points;
use isoline_io::write::svg;

/// `isoline mesh` options.
#[derive(clap::Args)]
pub struct Args {
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
}

/// Adapts, draws and reports.
pub fn run(a: Args) -> Result<()> {
    let cfg = super::load_config(a.config.as_deref())?;
    let mut params = cfg.mesh_params();
    params.isotropic |= a.isotropic;
    super::refuse_overwrite(&a.input, &[a.output.as_deref(), a.stats.as_deref()])?;
    let points = isoline_io::read_points(&a.input, a.frame)?;
    let m = adapt_to_points(&points, &params)
        .with_context(|| format!("meshing {}", a.input.display()))?;
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
    if let Some(path) = a.output {
        let doc = svg::render(
            &svg::Drawing {
                mesh: Some(&m.mesh),
                points: &points,
                view: Some(m.domain),
                ..Default::default()
            },
            1600.0,
        );
        super::write(&path, doc)?;
    }
    match a.stats {
        Some(path) => super::write(&path, format!("{summary:#}\n"))?,
        None => super::print(&format!("{summary}\n"))?,
    }
    Ok(())
}
