//! `isoline eval`: accuracy of reconstructed curves against the simulator's truth.

use std::io::BufRead;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use serde_json::json;

use isoline::eval;
use isoline::format::{PolylineJson, TruthFile};
use isoline::geom::Polyline;

/// `isoline eval` options.
#[derive(clap::Args)]
pub struct Args {
    /// Polylines: NDJSON result records or a JSON file with "polylines".
    recon: PathBuf,
    /// Truth file written by `isoline synth`.
    #[arg(long)]
    truth: PathBuf,
}

/// Prints the accuracy as JSON: one object, or the worst Hausdorff distance and one
/// object per frame.
pub fn run(a: Args) -> Result<()> {
    let truth_file: TruthFile = serde_json::from_str(&super::read(&a.truth)?)
        .with_context(|| format!("{}: not a truth file", a.truth.display()))?;
    let records = read_polyline_records(&a.recon)?;
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
        results.into_iter().next().expect("one result")
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

/// Polylines per record: a JSON document with "polylines", or NDJSON records with
/// "polylines" (and "frame"); error records fail with their frame named.
fn read_polyline_records(path: &Path) -> Result<Vec<(Option<u64>, Vec<Polyline>)>> {
    #[derive(serde::Deserialize)]
    struct Rec {
        frame: Option<u64>,
        polylines: Option<Vec<PolylineJson>>,
        error: Option<String>,
    }
    let text = super::read(path)?;
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
