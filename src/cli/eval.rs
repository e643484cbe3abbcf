//! `isoline eval`: accuracy of reconstructed curves against the simulator's truth, or,
//! without truth, the scores a scan's own returns and free space give.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use serde_json::json;

use isoline_core::geom::{Point, Polyline, Pose};
use isoline_io::format::{PolylineJson, TruthFile};
use isoline_sim as eval;

/// `isoline eval` options.
#[derive(clap::Args)]
pub struct Args {
    /// Polylines: NDJSON result records or a JSON file with "polylines".
    recon: PathBuf,
    /// Truth file written by `isoline synth`. Without one, `--frames` is required and
    /// the scores are the ones the scans alone give.
    #[arg(long)]
    truth: Option<PathBuf>,
    /// The input frames (NDJSON, a bag or a CARMEN log): for scan frames, adds the
    /// scan-aware scores.
    #[arg(long)]
    frames: Option<PathBuf>,
    /// Tolerance of the scan-aware scores; default three times the truth's range noise
    /// (5 cm without one). With --map: the hit tolerance (default 5 cm).
    #[arg(long)]
    tolerance: Option<f64>,
    /// The curves are a world-frame map (`isoline map`'s record, or any GeoJSON of
    /// LineStrings): scored by the votes of every scan in --frames placed by its pose,
    /// and, with --truth, against the scene's walls.
    #[arg(long)]
    map: bool,
    /// The input is an estimated trajectory (TUM: `t x y z qx qy qz qw` a line, as
    /// `isoline map --trajectory` writes): scored against this reference trajectory,
    /// poses paired by time, as the absolute trajectory error after the best rigid
    /// alignment and the relative pose error over 1 m and 10 m of path.
    #[arg(long)]
    reference: Option<PathBuf>,
    /// A bag's topics, odometry and world frame, for --frames that is a bag (as
    /// `isoline map` reads it).
    #[command(flatten)]
    bag: super::BagArgs,
    /// What `bag` says, once checked against --frames.
    #[arg(skip)]
    bag_options: isoline_io::bag::BagOptions,
}

/// Prints the accuracy as JSON: one object, or the worst Hausdorff distance and one
/// object per frame.
pub fn run(mut a: Args) -> Result<()> {
    let bag = std::mem::take(&mut a.bag);
    a.bag_options = match &a.frames {
        Some(f) => bag.options(f)?,
        None => bag.options(&a.recon)?,
    };
    if let Some(reference) = &a.reference {
        return run_trajectory(&a.recon, reference);
    }
    if a.map {
        return run_map(&a);
    }
    let Some(truth_path) = &a.truth else {
        return run_without_truth(&a);
    };
    let truth_file: TruthFile = serde_json::from_str(&super::read(truth_path)?)
        .with_context(|| format!("{}: not a truth file", truth_path.display()))?;
    let records = read_polyline_records(&a.recon)?;
    let frames: Vec<isoline_io::Frame> = match &a.frames {
        Some(p) => isoline_io::read_frames(p)?,
        None => Vec::new(),
    };
    let tol = a.tolerance.unwrap_or_else(|| {
        truth_file
            .sensor
            .as_ref()
            .map_or(0.05, |s| 3.0 * s.range_noise)
    });
    if !(tol.is_finite() && tol > 0.0) {
        bail!("--tolerance {tol}: must be a positive number");
    }
    let results: Vec<serde_json::Value> = records
        .iter()
        .map(|(frame, pls)| -> Result<serde_json::Value> {
            let (truth, openings, _) = truth_file.frame(*frame);
            let truth: Vec<Polyline> = truth.iter().cloned().map(Into::into).collect();
            let surfaces = truth_file.surfaces(*frame);
            let acc = eval::compare_surfaces(pls, &truth, &surfaces, None);
            let mut v = accuracy_json(&acc);
            if let Some(f) = frame {
                v["frame"] = json!(f);
            }
            if a.frames.is_some() {
                let input = frames
                    .iter()
                    .find(|f| Some(f.frame) == *frame || (frame.is_none() && frames.len() == 1))
                    .with_context(|| format!("no input frame {frame:?}"))?;
                if let Some(scan) = &input.scan {
                    let openings: Vec<_> = openings.iter().map(|o| (o[0], o[1])).collect();
                    let s = eval::scan_scores(pls, &truth, &surfaces, &openings, scan, tol);
                    for (k, x) in [
                        ("tolerance", json!(s.tolerance)),
                        ("returns", json!(s.returns)),
                        ("returns_explained", json!(s.returns_explained)),
                        ("free_space_share", json!(s.free_space_share)),
                        ("openings", json!(s.openings)),
                        ("openings_bridged", json!(s.openings_bridged)),
                        ("gaps_bridged", json!(s.gaps_bridged)),
                        ("walls_missed", json!(s.walls_missed)),
                    ] {
                        v[k] = x;
                    }
                }
            }
            Ok(v)
        })
        .collect::<Result<_>>()?;
    let out = if results.len() == 1 {
        results.into_iter().next().expect("one result")
    } else {
        let worst = results
            .iter()
            .map(|r| r["hausdorff"].as_f64().unwrap_or(f64::INFINITY))
            .fold(0.0, f64::max);
        let mut v = json!({ "hausdorff": finite(worst) });
        let values =
            |k: &str| -> Vec<f64> { results.iter().filter_map(|r| r[k].as_f64()).collect() };
        let explained = values("returns_explained");
        if !explained.is_empty() {
            let free = values("free_space_share");
            let sum = |k: &str| values(k).iter().sum::<f64>();
            v["returns_explained_min"] = json!(explained.iter().copied().fold(1.0, f64::min));
            v["returns_explained_mean"] =
                json!(explained.iter().sum::<f64>() / explained.len() as f64);
            v["free_space_share_max"] = json!(free.iter().copied().fold(0.0, f64::max));
            v["free_space_share_mean"] = json!(free.iter().sum::<f64>() / free.len() as f64);
            v["openings_bridged"] = json!(sum("openings_bridged"));
            v["gaps_bridged"] = json!(sum("gaps_bridged"));
            v["walls_missed"] = json!(sum("walls_missed"));
        }
        v["frames"] = json!(results);
        v
    };
    super::print(&format!("{out}\n"))
}

/// A world-frame map scored as [`isoline_map::MapScores`] says, by the votes of the
/// recording's scans (placed by their poses, not aligned: the map is judged where the
/// poses put the returns); with truth, also its distance to the scene's walls and its
/// cover of the walls the scans saw.
fn run_map(a: &Args) -> Result<()> {
    let Some(frames_path) = &a.frames else {
        bail!("--map needs --frames: the recording whose scans score the map");
    };
    let tol = a.tolerance.unwrap_or(0.05);
    if !(tol.is_finite() && tol > 0.0) {
        bail!("--tolerance {tol}: must be a positive number");
    }
    let curves = read_map(&a.recon)?;
    let params = isoline_map::MapParams {
        align: false,
        hit_tolerance: tol,
        ..Default::default()
    };
    let store = isoline_io::DiskTiles::new(None)
        .context("creating the directory for tiles that leave memory")?;
    let mut map = isoline_map::Map::new(params, Box::new(store))?;
    // The walls the scans saw, from their returns on a lattice of half the tolerance
    // (memory grows with the area seen, not with the scans).
    let q = 0.5 * tol;
    let mut seen: std::collections::HashSet<(i64, i64)> = Default::default();
    let (mut scans, mut unplaced) = (0u64, 0u64);
    let mut failure = None;
    // The scans as the map command read them: corrected for their sweeps.
    let mut deskew = isoline_io::Deskew::new(None);
    isoline_io::for_each_item(frames_path, &a.bag_options, |item| {
        let Ok(mut f) = item else {
            unplaced += 1;
            return true;
        };
        deskew.apply(&mut f);
        let (Some(scan), Some(pose)) = (&f.scan, f.pose) else {
            unplaced += 1;
            return true;
        };
        if let Err(e) = map.insert(scan, pose, &[], 0.0) {
            failure = Some(e);
            return false;
        }
        scans += 1;
        if a.truth.is_some() {
            // Returns beyond the map's reach are not evidence it could have drawn from.
            let reach = params.max_range;
            for p in scan.returns() {
                if isoline_core::geom::dist(p, scan.origin) > reach {
                    continue;
                }
                let w = isoline_core::geom::to_world(pose, p);
                seen.insert(((w[0] / q).round() as i64, (w[1] / q).round() as i64));
            }
        }
        true
    })
    .with_context(|| format!("reading {}", frames_path.display()))?;
    if let Some(e) = failure {
        return Err(e.into());
    }
    if scans == 0 {
        bail!(
            "{}: no scan with a pose to score the map by ({unplaced} frames without)",
            frames_path.display()
        );
    }
    let s = map.score(&curves)?;
    let mut out = json!({
        "tolerance": tol, "scans": scans, "unplaced": unplaced,
        "returns_scored": s.returns_scored, "static_share": s.static_share,
        "static_within": s.static_within, "seen_through": s.seen_through,
        "length": s.length, "pieces": s.pieces,
    });
    if let Some(truth_path) = &a.truth {
        let truth: TruthFile = serde_json::from_str(&super::read(truth_path)?)
            .with_context(|| format!("{}: not a truth file", truth_path.display()))?;
        let Some(scene) = truth.scene else {
            bail!(
                "{}: no \"scene\" to score a map against",
                truth_path.display()
            );
        };
        let walls: Vec<Polyline> = scene.into_iter().map(Into::into).collect();
        let sigma = truth.sensor.as_ref().map_or(0.01, |s| s.range_noise);
        let cell = isoline_map::MapParams::default().cell;
        let bound = 3.0 * sigma + 2.0 * cell;
        let returns: Vec<Point> = seen
            .iter()
            .map(|&(i, j)| [i as f64 * q, j as f64 * q])
            .collect();
        let m = eval::map_accuracy(&curves, &walls, &returns, tol, bound, 0.5 * cell);
        out["truth"] = json!({
            "bound": bound,
            "to_walls_max": m.to_walls_max, "to_walls_p95": m.to_walls_p95,
            "to_walls_mean": m.to_walls_mean, "within_bound": m.within_bound,
            "walls_seen": m.walls_seen, "walls_seen_covered": m.walls_seen_covered,
        });
    }
    super::print(&format!("{out}\n"))
}

/// A map's curves: a GeoJSON FeatureCollection of LineStrings (or MultiLineStrings), or
/// the one result record of `isoline map` (the last, if the file holds several).
fn read_map(path: &Path) -> Result<Vec<Polyline>> {
    let text = super::read(path)?;
    let v: Option<serde_json::Value> = serde_json::from_str(&text).ok();
    if let Some(features) = v.as_ref().and_then(|v| v["features"].as_array()) {
        let mut out = Vec::new();
        for f in features {
            let g = &f["geometry"];
            let lines: Vec<Vec<Point>> = match g["type"].as_str() {
                Some("LineString") => vec![serde_json::from_value(g["coordinates"].clone())?],
                Some("MultiLineString") => serde_json::from_value(g["coordinates"].clone())?,
                _ => continue,
            };
            for points in lines {
                // A ring repeats its first point.
                let closed = points.len() > 3 && points.first() == points.last();
                let mut points = points;
                if closed {
                    points.pop();
                }
                out.push(Polyline { closed, points });
            }
        }
        return Ok(out);
    }
    let records = read_polyline_records(path)?;
    Ok(records.into_iter().last().map(|r| r.1).unwrap_or_default())
}

/// Scores from the scans alone: per frame, the returns within the tolerance of a curve
/// and their mean distance to it, the curve on the data, in free space, closed curves
/// and phantoms near the sensor; then the medians and totals over the frames.
fn run_without_truth(a: &Args) -> Result<()> {
    let Some(frames_path) = &a.frames else {
        bail!("without --truth, --frames names the scans the curves are scored against");
    };
    let tol = a.tolerance.unwrap_or(0.05);
    if !(tol.is_finite() && tol > 0.0) {
        bail!("--tolerance {tol}: must be a positive number");
    }
    let mut frames = isoline_io::read_items(frames_path, &a.bag_options)?;
    // The scans as the reconstruction read them: corrected for their sweeps (frames
    // that carry their beams' timing, by their input poses).
    let mut deskew = isoline_io::Deskew::new(None);
    for f in frames.iter_mut().flatten() {
        deskew.apply(f);
    }
    let scans: std::collections::HashMap<(Option<String>, u64), &isoline_core::Scan> = frames
        .iter()
        .flatten()
        .filter_map(|f| Some(((f.stream.clone(), f.frame), f.scan.as_ref()?)))
        .collect();
    // Each stream's scans with poses, in frame order: the next one's returns are the
    // held-out evidence of a frame's curves.
    let mut posed: Posed<'_> = Default::default();
    for f in frames.iter().flatten() {
        if let (Some(scan), Some(pose)) = (&f.scan, f.pose) {
            posed.insert((f.stream.clone(), f.frame), (scan, pose));
        }
    }
    let records = read_records(&a.recon)?;
    // The records' own placements, by stream and frame: the input pose and, from a
    // daemon with `register = true`, the registered one.
    let placements: Placements = records
        .iter()
        .map(|r| {
            (
                (r.stream.clone(), r.frame.unwrap_or(0)),
                (r.pose, r.registered_pose),
            )
        })
        .collect();
    let mut rows = Vec::new();
    let mut errors = 0;
    for r in &records {
        let Some(pls) = &r.polylines else {
            errors += 1;
            continue;
        };
        let key = (r.stream.clone(), r.frame.unwrap_or(0));
        let scan = scans
            .get(&key)
            .with_context(|| format!("no scan for stream {:?} frame {}", key.0, key.1))?;
        let pls: Vec<Polyline> = pls.iter().cloned().map(Into::into).collect();
        let s = eval::data_scores(&pls, scan, tol);
        // isoline's own contract: no crossing by more than the curves' accuracy bound.
        let past_bound = r.stats.as_ref().and_then(|st| {
            st.range_noise
                .map(|noise| eval::beam_crossings(&pls, scan, 3.0 * noise + 2.0 * st.hmin))
        });
        let held_out = held_out(&posed, &key, &pls, tol);
        let placed =
            |which: Pick| placed_next(&posed, &placements, &key, &pls, which, (tol, 3.0 * tol));
        let ms = r.stats.as_ref().map(|st| st.ms.total);
        rows.push(json!({
            "stream": r.stream, "frame": r.frame, "returns": s.returns,
            "returns_explained": s.returns_explained, "mean_distance": s.mean_distance,
            "held_out_distance": held_out,
            "next_scan_by_input_pose": placed(|p| p.0),
            "next_scan_by_registered_pose": placed(|p| p.1),
            "curve_on_data": s.curve_on_data, "free_space_share": s.free_space_share,
            "length": s.length, "closed": s.closed, "phantoms": s.phantoms,
            "beam_crossings": s.beam_crossings, "beam_crossings_past_bound": past_bound,
            "ms": ms,
        }));
    }
    let median = |k: &str| -> serde_json::Value {
        let mut v: Vec<f64> = rows.iter().filter_map(|r| r[k].as_f64()).collect();
        v.sort_by(f64::total_cmp);
        v.get(v.len() / 2)
            .map_or(serde_json::Value::Null, |x| json!(x))
    };
    let mean = |k: &str| -> serde_json::Value {
        let v: Vec<f64> = rows.iter().filter_map(|r| r[k].as_f64()).collect();
        if v.is_empty() {
            serde_json::Value::Null
        } else {
            json!(v.iter().sum::<f64>() / v.len() as f64)
        }
    };
    let count = |k: &str| {
        rows.iter()
            .filter(|r| r[k].as_u64().unwrap_or(0) > 0)
            .count()
    };
    let out = json!({
        "tolerance": tol,
        "records": records.len(),
        "errors": errors,
        "returns_explained": median("returns_explained"),
        "mean_distance": median("mean_distance"),
        "held_out_distance": median("held_out_distance"),
        "next_scan_by_input_pose": mean("next_scan_by_input_pose"),
        "next_scan_by_registered_pose": mean("next_scan_by_registered_pose"),
        "curve_on_data": median("curve_on_data"),
        "free_space_share": median("free_space_share"),
        "ms": median("ms"),
        "frames_with_closed_curves": count("closed"),
        "frames_with_phantoms": count("phantoms"),
        "frames_crossing_beams": count("beam_crossings"),
        // Records from other tools carry no noise estimate.
        "frames_crossing_beams_past_bound": rows
            .iter()
            .any(|r| !r["beam_crossings_past_bound"].is_null())
            .then(|| count("beam_crossings_past_bound")),
        "frames": rows,
    });
    super::print(&format!("{out}\n"))
}

/// How well the poses place frames: the mean distance to `curves` (frame `key`'s),
/// capped at `cap`, of the next scan's returns that see what this frame saw (those
/// [`overlap`] keeps, chosen by the scans alone), placed in this frame by the two
/// records' poses as `which` picks them (the input's, or the registered ones) and not
/// aligned. The same returns count under either pose, so the two means differ only by
/// where the poses put them. `None` where either record lacks that pose.
fn placed_next(
    posed: &Posed<'_>,
    placements: &Placements,
    key: &(Option<String>, u64),
    curves: &[Polyline],
    which: Pick,
    (tol, cap): (f64, f64),
) -> Option<f64> {
    use isoline_core::geom::{to_sensor, to_world};
    let pose = which(placements.get(key)?)?;
    let next_key = (key.0.clone(), key.1.checked_add(1)?);
    let ((stream, frame), next) = placements.range(next_key..).next()?;
    if *stream != key.0 {
        return None;
    }
    let next_pose = which(next)?;
    let (next_scan, _) = posed.get(&(stream.clone(), *frame))?;
    let (_, kept) = overlap(posed, key, tol)?;
    let returns = next_scan.returns();
    let index = isoline_core::SegmentIndex::new(curves);
    let d: Vec<f64> = kept
        .iter()
        .map(|&i| to_sensor(pose, to_world(next_pose, returns[i])))
        .map(|q| index.distance(q).min(cap))
        .collect();
    (!d.is_empty()).then(|| d.iter().sum::<f64>() / d.len() as f64)
}

/// The mean distance to `curves` (frame `key`'s), capped at `tol`, of the next scan's
/// returns in the same stream that lie within `tol` of this frame's returns: the next
/// scan placed in this frame by the two poses, then laid onto this frame's returns by
/// the alignment refinement uses ([`isoline_map::align_returns`]; poses are off by
/// more than the noise). Returns the curves never saw, so a curve fitted to its own
/// frame's noise gains nothing here: the score falls as the curves come nearer the
/// walls. Which returns count depends on the two scans alone, not on the curves
/// scored: a mean over the returns within `tol` of the curves would reward curves that
/// explain fewer of them. `None` without a next scan, poses, or returns within `tol`.
fn held_out(
    posed: &Posed<'_>,
    key: &(Option<String>, u64),
    curves: &[Polyline],
    tol: f64,
) -> Option<f64> {
    let (aligned, _) = overlap(posed, key, tol)?;
    let index = isoline_core::SegmentIndex::new(curves);
    let near: Vec<f64> = aligned
        .iter()
        .map(|&q| index.distance(q).min(tol))
        .collect();
    (!near.is_empty()).then(|| near.iter().sum::<f64>() / near.len() as f64)
}

/// Each record's input pose and registered pose, by stream and frame.
type Placements = std::collections::BTreeMap<(Option<String>, u64), (Option<Pose>, Option<Pose>)>;

/// Which of a record's two poses to place it by.
type Pick = fn(&(Option<Pose>, Option<Pose>)) -> Option<Pose>;

/// Each stream's scans with poses, by stream and frame.
type Posed<'a> = std::collections::BTreeMap<(Option<String>, u64), (&'a isoline_core::Scan, Pose)>;

/// The next scan's returns that see what frame `key` saw: placed in this frame by the
/// two poses, laid onto this frame's returns by the alignment refinement uses, and
/// kept within `tol` of them; aligned, with their indices among the next scan's
/// returns. Independent of the curves and of any pose being judged.
fn overlap(
    posed: &Posed<'_>,
    key: &(Option<String>, u64),
    tol: f64,
) -> Option<(Vec<Point>, Vec<usize>)> {
    use isoline_core::geom::{to_sensor, to_world};
    let &(scan, pose) = posed.get(key)?;
    let next_key = (key.0.clone(), key.1.checked_add(1)?);
    let ((stream, _), &(next, next_pose)) = posed.range(next_key..).next()?;
    if *stream != key.0 {
        return None;
    }
    let placed: Vec<Point> = next
        .returns()
        .into_iter()
        .map(|p| to_sensor(pose, to_world(next_pose, p)))
        .collect();
    let [x, y, theta] = isoline_map::align_returns(&placed, scan, &Default::default());
    let (s, c) = theta.sin_cos();
    let own = isoline_core::SegmentIndex::new(
        &scan
            .returns()
            .into_iter()
            .map(|p| Polyline {
                closed: false,
                points: vec![p],
            })
            .collect::<Vec<_>>(),
    );
    Some(
        placed
            .iter()
            .map(|p| [c * p[0] - s * p[1] + x, s * p[0] + c * p[1] + y])
            .enumerate()
            .filter(|&(_, q)| own.distance(q) <= tol)
            .map(|(i, q)| (q, i))
            .unzip(),
    )
}

/// Every record of an NDJSON result file, error records included.
fn read_records(path: &Path) -> Result<Vec<isoline_io::format::ResultRecord>> {
    let text = super::read(path)?;
    let mut out = Vec::new();
    for (i, l) in whole_lines(&text, path) {
        out.push(
            serde_json::from_str(l)
                .with_context(|| format!("{}, line {i}: not a result record", path.display()))?,
        );
    }
    Ok(out)
}

/// The non-blank lines of an NDJSON file with their 1-based numbers, less a last line
/// without its newline that is not JSON: a record cut short by a writer that was
/// killed mid-write (records are written one whole line at a time), skipped with a
/// warning.
fn whole_lines<'a>(text: &'a str, path: &Path) -> Vec<(usize, &'a str)> {
    let mut lines: Vec<(usize, &str)> = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l))
        .filter(|(_, l)| !l.trim().is_empty())
        .collect();
    if !text.ends_with('\n') {
        if let Some((i, last)) = lines.last().copied() {
            if serde_json::from_str::<serde::de::IgnoredAny>(last).is_err() {
                eprintln!(
                    "isoline: {}, line {i}: an unterminated last line, cut short; skipped",
                    path.display()
                );
                lines.pop();
            }
        }
    }
    lines
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
    for (i, line) in whole_lines(&text, path) {
        out.push(parse(line, i)?);
    }
    if out.is_empty() {
        bail!("{}: no polyline records", path.display());
    }
    Ok(out)
}

/// A TUM trajectory's timed poses, in the file's order.
fn read_tum(path: &std::path::Path) -> Result<Vec<(f64, isoline_core::Pose)>> {
    let text = super::read(path)?;
    let poses: Vec<_> = text
        .lines()
        .filter_map(isoline_map::trajectory::parse_tum_line)
        .collect();
    if poses.is_empty() {
        bail!(
            "{}: no pose (TUM lines: t x y z qx qy qz qw)",
            path.display()
        );
    }
    Ok(poses)
}

/// Prints the trajectory's errors against the reference as JSON: the estimate's poses
/// paired with the reference's at the same time (within a millisecond), or in order
/// where either's time stamps repeat.
fn run_trajectory(estimate: &std::path::Path, reference_path: &std::path::Path) -> Result<()> {
    use isoline_map::trajectory::{absolute, relative};
    let est = read_tum(estimate)?;
    let reference = read_tum(reference_path)?;
    // Recordings whose time stamps repeat (some CARMEN logs stamp every line alike)
    // can only be paired pose for pose, in order.
    let distinct = |v: &[(f64, isoline_core::Pose)]| v.windows(2).all(|w| w[1].0 > w[0].0);
    let by_order = !(distinct(&est) && distinct(&reference));
    let (mut e, mut r) = (Vec::new(), Vec::new());
    if by_order {
        if est.len() != reference.len() {
            bail!(
                "{} ({} poses) and {} ({}): time stamps repeat, so the poses pair in order, and the counts differ",
                estimate.display(),
                est.len(),
                reference_path.display(),
                reference.len()
            );
        }
        e = est.iter().map(|p| p.1).collect();
        r = reference.iter().map(|p| p.1).collect();
    } else {
        for &(t, p) in &est {
            let k = reference.partition_point(|q| q.0 < t - 1e-3);
            if let Some(&(tr, q)) = reference.get(k) {
                if (tr - t).abs() <= 1e-3 {
                    e.push(p);
                    r.push(q);
                }
            }
        }
    }
    if e.len() < 2 {
        bail!(
            "{} and {}: fewer than two poses at the same times",
            estimate.display(),
            reference_path.display()
        );
    }
    let abs = absolute(&e, &r);
    let rel = |d: f64| {
        let x = relative(&e, &r, d);
        json!({"delta_m": d, "pairs": x.pairs, "translation_m": x.translation,
               "heading_deg": x.heading.to_degrees()})
    };
    let out = json!({
        "poses": abs.poses,
        "paired_by": if by_order { "order" } else { "time" },
        "unpaired": est.len() - abs.poses,
        "length_m": abs.length,
        "ate_m": abs.ate,
        "ate_heading_deg": abs.ate_heading.to_degrees(),
        "rpe": [rel(1.0), rel(10.0)],
    });
    println!("{}", serde_json::to_string_pretty(&out)?);
    Ok(())
}
