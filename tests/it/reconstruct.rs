//! `isoline reconstruct` end to end, through the real binary.

use std::path::Path;
use std::process::Command;

use crate::common::{ok, p};
use serde_json::Value;

fn isoline(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_isoline"))
        .args(args)
        .output()
        .expect("run isoline")
}

fn fixture(name: &str) -> String {
    format!("{}/fixtures/{name}", env!("CARGO_MANIFEST_DIR"))
}

fn json_file(path: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// The circle with `points` samples and noise `sigma` (seed `seed`) simulated,
/// reconstructed with the defaults and scored: (the reconstruction's stats, `eval`'s
/// scores).
fn circle_run(dir: &Path, points: usize, sigma: f64, seed: u64) -> (Value, Value) {
    shape_run(dir, "circle", points, sigma, seed, 0.05)
}

/// [`circle_run`] for any of the simulator's shapes (`gap`: the spiral's and the bays').
fn shape_run(
    dir: &Path,
    shape: &str,
    points: usize,
    sigma: f64,
    seed: u64,
    gap: f64,
) -> (Value, Value) {
    let name = format!("{shape}{points}-{sigma}-{seed}");
    let [frames, truth, recon, stats] = ["ndjson", "truth.json", "recon.ndjson", "stats.json"]
        .map(|ext| dir.join(format!("{name}.{ext}")));
    ok(&[
        "synth",
        shape,
        "--points",
        &points.to_string(),
        "--noise",
        &sigma.to_string(),
        "--seed",
        &seed.to_string(),
        "--gap",
        &gap.to_string(),
        "-o",
        p(&frames),
        "--truth",
        p(&truth),
    ]);
    ok(&[
        "reconstruct",
        p(&frames),
        "-o",
        p(&recon),
        "--stats",
        p(&stats),
    ]);
    let out = ok(&["eval", p(&recon), "--truth", p(&truth)]);
    (
        json_file(&stats),
        serde_json::from_slice(&out.stdout).unwrap(),
    )
}

/// Whether every curve of [`shape_run`]'s run is a closed loop.
fn all_closed(dir: &Path, shape: &str, points: usize, sigma: f64, seed: u64) -> bool {
    let recon = dir.join(format!("{shape}{points}-{sigma}-{seed}.recon.ndjson"));
    let record: Value = serde_json::from_str(&std::fs::read_to_string(recon).unwrap()).unwrap();
    record["polylines"]
        .as_array()
        .unwrap()
        .iter()
        .all(|c| c["closed"] == true)
}

/// Walls closer than the tube around the data (issue 17): the spiral band, its walls
/// and the corridor between its turns 0.08 wide, and the disc whose three bays lie
/// behind inlets 0.08 wide, each sampled so that the gap is 8 sample spacings (498 and
/// 442 points), at sigma = 0.5% of the unit box's diagonal (0.0071, a gap of 11 sigma);
/// and both at the default gap 0.05 with 2,000 points and sigma = 0.002. One loop each,
/// within 3 sigma + 2 hmin of the truth, neither the spiral's turns nor the bays filled.
#[test]
fn a_spiral_and_bays_behind_narrow_inlets_stay_open() {
    let dir = tempfile::tempdir().unwrap();
    let diag = 0.005 * 2f64.sqrt();
    // Seeds 2 and 5 of the noisy spiral once had a turn's normals signed across the
    // corridor by a sample in the noise's tail between two walls. Bays seed 3 came out
    // as four curves: its samples fell into two open sheets, cut by gaps in the
    // sampling, so no orientation was given, and the tube start merged walls. Bays seed
    // 27 kept a hole in the disc's noisy interior that the arcs shrank to a speck.
    // Spiral seed 22 came out as two loops: its one sheet's normals sum to 0.11 of their
    // number, past a closed curve's 0.1 by the sampling's chance, and it has no ends.
    // Spiral seed 24 (7 curves) and bays seed 33 (a bay turned inside out, 0.14 off) had
    // a stretch of normals that the spanning forest turned against the rest; spiral
    // seed 28 (8 curves), samples straddling two walls turned against most of their
    // edges. Bays seed 37 got no orientation and came out as one open curve: its one
    // sheet's ends, across a bay's wall with no sample over 0.1, both ran out. The last
    // column: whether the samples show every bend and corner, so that the bound holds
    // without half a spacing more (bays seed 34's inlet corner has no sample over eight
    // spacings of the disc's circle; seed 37's gap is past the gap between walls).
    for (shape, points, sigma, gap, seed, shown) in [
        ("spiral", 498, diag, 0.08, 7, true),
        ("spiral", 498, diag, 0.08, 22, true),
        ("spiral", 498, diag, 0.08, 24, true),
        ("spiral", 498, diag, 0.08, 28, true),
        ("bays", 442, diag, 0.08, 33, true),
        ("bays", 442, diag, 0.08, 34, false),
        ("bays", 442, diag, 0.08, 37, false),
        ("spiral", 498, diag, 0.08, 2, true),
        ("spiral", 498, diag, 0.08, 5, true),
        ("bays", 442, diag, 0.08, 7, true),
        ("bays", 442, diag, 0.08, 3, true),
        ("bays", 442, diag, 0.08, 27, true),
        ("spiral", 2000, 0.002, 0.05, 7, true),
        ("bays", 2000, 0.002, 0.05, 7, true),
    ] {
        let (s, acc) = shape_run(dir.path(), shape, points, sigma, seed, gap);
        let hmin = s["hmin"].as_f64().unwrap();
        let h = acc["hausdorff"].as_f64().unwrap();
        let spacing = if shown { 0.0 } else { gap / 8.0 };
        let bound = 3.0 * sigma + 2.0 * hmin + 0.5 * spacing;
        assert_eq!(acc["components_recon"], 1, "{shape} {points} {seed}: {acc}");
        assert!(all_closed(dir.path(), shape, points, sigma, seed));
        assert!(
            h <= bound,
            "{shape} {points} {seed}: Hausdorff {h} > {bound}; {acc}"
        );
    }
}

/// The clean spiral and bays with their walls 8 sample spacings apart (0.08 apart with
/// 498 and 442 points; 0.06 apart with 914 and 604): one closed loop each. A random
/// sampling leaves stretches of up to five spacings with no sample, across which the
/// level set cuts a bend by up to two spacings, or a wall's corner with a circle by
/// more; the arcs and corners put across them (`export::gaps`) follow what the samples
/// on either side imply. Between consecutive samples the curve is drawn through them
/// (`export::through`, `export::between`): their circles, and the corners where two
/// walls' circles cross. Where the samples show the shape, that is within `2 hmin` as
/// for any clean shape: spiral seeds 7 and 9 were 2.17e-3 and 2.63e-3 off before the
/// projection onto the samples (against 1.86e-3 and 2.01e-3); bays seeds 2 and 8 were
/// 3.6e-3 and 6.0e-3 off before the corners between samples, spiral seed 5 2.7e-3.
/// The bays 0.06 apart (604 points, seed 2) estimate a noise of 2.6e-3, their bays'
/// bend seen by the 32-neighbour fits, and were left as the level set drew them
/// (1.2e-2 off) until the samples were judged clean over one wall's window; seed 6
/// cut an inlet's acute corner by 9.1e-3 (against 5.3e-3), the loop counted as held
/// within that estimate's tolerance until the mending used the one wall's residual.
/// Where no sample shows it (bays seed 6's acute corner, the next sample on its wall
/// 0.023 past it) the error is within half a spacing on top of `2 hmin`. The spiral's
/// inner end (seeds 3 and 15), a corner of 23 degrees in a gap of 0.043 to 0.05, is
/// within `2 hmin`: its cap's circle passes the wall's last sample by chance, and the
/// corner was put at that sample, 1.9e-3 and 2.1e-3 off (against 1.86e-3); now the
/// curve runs midway between the two crossings that the samples leave in doubt. Without the arcs
/// the spiral (seed 7) was 1.5e-2 away; without the corners the bays (seed 2) 1.6e-2;
/// and bays seed 8 came out as one open stroke round the disc, its loop judged a bridge
/// where it had passed a sparse wall by. Spiral seed 5 came out as three curves through
/// the corridors: the merged tube's middle, off the samples along the inner turn only,
/// had been kept over the oriented start. The spiral 0.06 apart (seed 4) came out as
/// two curves, one round its centre: a gap of 12 spacings and a cap missing its
/// samples cut its samples into two open sheets, and no orientation was given. Spiral
/// seed 27 came out as two loops, pinched where both walls of its outer turn have a gap
/// of five spacings (`export::pinches`). Bays seed 11 got no orientation and ran round
/// its bays 0.05 inside their samples: an inlet's wall with a gap where it meets the
/// disc's circle left its bay an open sheet, and the rest one long sheet whose normals
/// sum to less than a closed one's may, so the two were not joined. Bays seed 32 bowed
/// 0.01 into an inlet across a gap in its straight wall that reaches a sample beside
/// the corner, whose fit spans the corner (a Hermite arc with that tangent). The
/// spiral 0.06 apart, seed 16, ballooned 0.03 into a corridor past three samples of a
/// wall, which the balloon passed in the reverse order, so the arc through them doubled
/// back and was refused; seed 32 came out as five curves: gaps cut one wall twice,
/// nearly a turn apart, and both sheets, their normals summing as closed curves', were
/// turned outward on their own.
#[test]
fn clean_walls_keep_their_bends_and_corners_across_sampling_gaps() {
    let dir = tempfile::tempdir().unwrap();
    // The last column: whether the samples show the whole shape, so that 2 hmin holds.
    for (shape, points, seed, gap, shown) in [
        ("spiral", 498, 7, 0.08, true),
        ("spiral", 498, 5, 0.08, true),
        ("spiral", 498, 3, 0.08, true),
        ("spiral", 498, 15, 0.08, true),
        ("spiral", 498, 27, 0.08, true),
        ("spiral", 914, 4, 0.06, true),
        ("spiral", 914, 9, 0.06, true),
        ("spiral", 914, 16, 0.06, true),
        ("spiral", 914, 32, 0.06, true),
        ("bays", 442, 2, 0.08, true),
        ("bays", 442, 8, 0.08, true),
        ("bays", 442, 6, 0.08, false),
        ("bays", 442, 11, 0.08, true),
        ("bays", 442, 32, 0.08, true),
        ("bays", 442, 18, 0.08, true),
        ("bays", 442, 24, 0.08, true),
        ("bays", 442, 38, 0.08, true),
        ("bays", 442, 14, 0.08, true),
        ("bays", 604, 2, 0.06, true),
        ("bays", 604, 6, 0.06, true),
    ] {
        let (s, acc) = shape_run(dir.path(), shape, points, 0.0, seed, gap);
        let spacing = if shown { 0.0 } else { gap / 8.0 };
        let bound = 2.0 * s["hmin"].as_f64().unwrap() + 0.5 * spacing;
        assert_eq!(acc["components_recon"], 1, "{shape} {seed}: {acc}");
        assert!(
            all_closed(dir.path(), shape, points, 0.0, seed),
            "{shape} {seed}"
        );
        let h = acc["hausdorff"].as_f64().unwrap();
        assert!(h <= bound, "{shape} {seed}: Hausdorff {h} > {bound}: {acc}");
    }
}

/// The simulator's drawing of five open strokes (a baseline with a stem and a hook
/// standing on it, a wave crossing the stem, a free arc whose ends come within 0.065 of
/// the baseline), clean and at sigma = 0.002, 0.005 and 0.00707 (0.5% of the unit box's
/// diagonal): one open polyline per stroke, split only where strokes meet (the baseline
/// in three, the stem and the wave in two: 9 in all), junctions of 4 (the crossing) and
/// 3 (the two T's) where they meet, and every curve and every truth point within
/// 3 sigma + 2 hmin (2 hmin clean: the strokes' ends are samples, as a pen's are).
/// No loop: at 0.005 and 0.00707 the tube closes the arc onto the baseline, a loop
/// through empty space that is left to the strokes, also where that space is narrower
/// than the bridge test sees and the baseline runs on past both ends of the loop (its
/// end curling into the loop's turn at 0.005, seeds 7 and 16, or its chain straight
/// from a T's foot, seed 49), and where small loops
/// round a T's foot stay beside the baseline that the dropped loop held (0.00707, seeds
/// 18, 29 and 37). Nor are the arc's ends joined to the baseline 9 sigma away (0.00707,
/// seed 7). A stroke stays whole across a lone sample between two sampling gaps (clean
/// seed 14); a T's foot whose last samples the thinning moved onto the bar stands on it
/// (clean seeds 4 and 15); a crossing's arm that ends short of it meets it (clean seeds
/// 3, 10 and 26, 0.002 seed 30).
#[test]
fn open_strokes_come_out_as_open_polylines_meeting_at_junctions() {
    let dir = tempfile::tempdir().unwrap();
    let runs = [
        (0.0, 3),
        (0.0, 4),
        (0.0, 10),
        (0.0, 14),
        (0.0, 15),
        (0.0, 26),
        (0.002, 7),
        (0.002, 30),
        (0.005, 7),
        (0.005, 16),
        (0.005, 49),
        (0.00707, 7),
        (0.00707, 2),
        (0.00707, 18),
        (0.00707, 29),
        (0.00707, 37),
    ];
    for (sigma, seed) in runs {
        let (s, acc) = shape_run(dir.path(), "strokes", 2000, sigma, seed, 0.05);
        let record: Value = serde_json::from_str(
            std::fs::read_to_string(
                dir.path()
                    .join(format!("strokes2000-{sigma}-{seed}.recon.ndjson")),
            )
            .unwrap()
            .lines()
            .next()
            .unwrap(),
        )
        .unwrap();
        let polylines = record["polylines"].as_array().unwrap();
        assert_eq!(polylines.len(), 9, "{sigma} {seed}: {acc}");
        assert!(
            polylines.iter().all(|p| p["closed"] == false),
            "{sigma} {seed}"
        );
        let mut degrees: Vec<usize> = record["junctions"]
            .as_array()
            .unwrap()
            .iter()
            .map(|j| j["polylines"].as_array().unwrap().len())
            .collect();
        degrees.sort_unstable();
        assert_eq!(
            degrees,
            [3, 3, 4],
            "{sigma} {seed}: {}",
            record["junctions"]
        );
        let bound = 3.0 * sigma + 2.0 * s["hmin"].as_f64().unwrap();
        for side in ["recon_to_truth", "truth_to_recon"] {
            let d = acc[side].as_f64().unwrap();
            assert!(d <= bound, "{sigma} {seed}: {side} {d} > {bound}: {acc}");
        }
    }
}

/// Issue acceptance: the circle of radius 0.4 with 2,000 points, Hausdorff distance to
/// the truth at most 3 sigma + 2 hmin at each noise level.
#[test]
fn circle_accuracy_is_within_three_sigma_plus_two_hmin() {
    let dir = tempfile::tempdir().unwrap();
    for sigma in [0.0, 0.002, 0.005] {
        let (s, acc) = circle_run(dir.path(), 2000, sigma, 11);
        // The default hmin grows with the noise; the bound is held to the finer of the
        // two sizes it can take (D/1000: the circle's box has diagonal about 0.8 sqrt 2),
        // so the coarser mesh must not cost accuracy either.
        let hmin = s["hmin"]
            .as_f64()
            .unwrap()
            .min(0.8 * 2f64.sqrt() / 1000.0 * 1.05);
        let h = acc["hausdorff"].as_f64().unwrap();
        let bound = 3.0 * sigma + 2.0 * hmin;
        assert!(
            h <= bound,
            "sigma {sigma}: Hausdorff {h} > {bound}; stats {s}"
        );
        assert_eq!(acc["components_recon"], 1, "sigma {sigma}");
        if sigma == 0.0 {
            assert_eq!(s["converged"], true, "clean data meets eq. 11: {s}");
        }
    }
}

/// Denser data of the same noise give the same curve or a better one: the circle with
/// σ = 0.005 at 10,000 and 100,000 points comes out as one loop, within half of the
/// 1.3e-2 reported for CGAL's optimal-transport reconstruction at 100,000, its mean
/// distance to the truth no larger at the higher density, and its noise measured the
/// same (hmin is the noise estimate: within 10% of each other and of σ).
#[test]
fn more_points_of_the_same_noise_give_the_same_curve_or_better() {
    let dir = tempfile::tempdir().unwrap();
    let mut results = Vec::new();
    for n in [10_000, 100_000] {
        let (s, acc) = circle_run(dir.path(), n, 0.005, 1);
        assert_eq!(acc["components_recon"], 1, "{n} points: {acc}");
        let h = acc["hausdorff"].as_f64().unwrap();
        assert!(h <= 0.5 * 1.3e-2, "{n} points: Hausdorff {h}");
        let hmin = s["hmin"].as_f64().unwrap();
        assert!((hmin / 0.005 - 1.0).abs() < 0.1, "{n} points: hmin {hmin}");
        results.push((hmin, acc["mean_distance"].as_f64().unwrap()));
    }
    let [(h10k, m10k), (h100k, m100k)] = results[..] else {
        unreachable!()
    };
    assert!((h100k / h10k - 1.0).abs() < 0.1, "hmin {h10k} -> {h100k}");
    assert!(m100k <= m10k, "mean distance {m10k} -> {m100k}");
}

/// Two shapes whose topology the enclosing-circle start cannot find: two separate
/// circles, and an annulus (its hole must come out as a clockwise loop).
#[test]
fn separate_components_and_holes_come_out_right() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("two.json");
    ok(&[
        "reconstruct",
        &fixture("two-circles-600-n001.ndjson"),
        "-o",
        p(&out),
    ]);
    let r = json_file(&out);
    let pls = r["polylines"].as_array().unwrap();
    assert_eq!(pls.len(), 2, "{r}");
    let area = |pl: &Value| -> f64 {
        let pts: Vec<[f64; 2]> = serde_json::from_value(pl["points"].clone()).unwrap();
        let n = pts.len();
        0.5 * (0..n)
            .map(|i| {
                let (a, b) = (pts[i], pts[(i + 1) % n]);
                a[0] * b[1] - a[1] * b[0]
            })
            .sum::<f64>()
    };
    for pl in pls {
        assert_eq!(pl["closed"], true);
        // Radius 0.18: area 0.102.
        assert!((area(pl) - 0.1018).abs() < 0.005, "{}", area(pl));
    }
    let out = dir.path().join("annulus.ndjson");
    ok(&[
        "reconstruct",
        &fixture("annulus-800-n001.ndjson"),
        "-o",
        p(&out),
    ]);
    let text = std::fs::read_to_string(&out).unwrap();
    let r: Value = serde_json::from_str(text.lines().next().unwrap()).unwrap();
    let pls = r["polylines"].as_array().unwrap();
    assert_eq!(pls.len(), 2, "{r}");
    let (outer, hole) = (area(&pls[0]), area(&pls[1]));
    assert!(outer > 0.0 && hole < 0.0, "outer {outer}, hole {hole}");
    let acc = ok(&[
        "eval",
        p(&out),
        "--truth",
        &fixture("annulus-800-n001.truth.json"),
    ]);
    let acc: Value = serde_json::from_slice(&acc.stdout).unwrap();
    assert_eq!(acc["components_truth"], acc["components_recon"]);
}

#[test]
fn every_output_format_is_written_and_parses() {
    let dir = tempfile::tempdir().unwrap();
    let input = fixture("ellipse-500-n001.ndjson");
    let geo = dir.path().join("e.geojson");
    ok(&["reconstruct", &input, "-o", p(&geo)]);
    let g = json_file(&geo);
    assert_eq!(g["type"], "FeatureCollection");
    let coords = g["features"][0]["geometry"]["coordinates"]
        .as_array()
        .unwrap();
    assert_eq!(
        coords.first(),
        coords.last(),
        "closed rings repeat their first point"
    );
    let csv = dir.path().join("e.csv");
    ok(&["reconstruct", &input, "-o", p(&csv)]);
    let text = std::fs::read_to_string(&csv).unwrap();
    assert!(text.starts_with("stream,frame,polyline,closed,vertex,x,y,junction\n"));
    assert!(text.lines().count() > 100);
    let svg = dir.path().join("e.svg");
    ok(&["reconstruct", &input, "-o", p(&svg), "--mesh"]);
    let text = std::fs::read_to_string(&svg).unwrap();
    assert!(text.starts_with("<svg") && text.trim_end().ends_with("</svg>"));
    // Without -o: one NDJSON record on stdout.
    let out = ok(&["reconstruct", &fixture("circle-500.xy")]);
    let text = String::from_utf8(out.stdout).unwrap();
    assert_eq!(text.lines().count(), 1);
    let r: Value = serde_json::from_str(&text).unwrap();
    assert_eq!(r["frame"], 0);
    assert!(r["stats"]["vertices"].as_u64().unwrap() > 100);
    let bad = isoline(&["reconstruct", &input, "-o", p(&dir.path().join("e.txt"))]);
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("unknown output extension"));
}

#[test]
fn bad_frames_get_error_records_and_a_failing_exit_code() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("mixed.ndjson");
    let good = std::fs::read_to_string(fixture("ellipse-500-n001.ndjson")).unwrap();
    let good = good
        .lines()
        .next()
        .unwrap()
        .replace("\"frame\":0", "\"frame\":1");
    std::fs::write(
        &input,
        format!("{good}\n{{\"frame\":2,\"points\":[[0.5,0.5]]}}\n{{\"frame\":3,\"points\":[]}}\n"),
    )
    .unwrap();
    let out_path = dir.path().join("out.ndjson");
    let out = isoline(&["reconstruct", p(&input), "-o", p(&out_path)]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("2 of 3 frames failed"), "{err}");
    assert!(err.contains("frame 2") && err.contains("frame 3"), "{err}");
    let recs: Vec<Value> = std::fs::read_to_string(&out_path)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(recs.len(), 3);
    assert!(recs[0]["polylines"].is_array());
    assert!(recs[1]["error"].as_str().unwrap().contains("coincide"));
    assert!(recs[2]["error"].as_str().unwrap().contains("empty"));
    // A single bad point file fails with its name and line.
    let xy = dir.path().join("bad.xy");
    std::fs::write(&xy, "0 0\n1 oops\n").unwrap();
    let out = isoline(&["reconstruct", p(&xy)]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("bad.xy") && err.contains("line 2"), "{err}");
}

/// A point cloud's record says the noise it measured, the sigma of its accuracy bound:
/// the median residual of local fits, which for Gaussian scatter across a curve whose
/// bend the fits' window resolves lies between 0.8 and 1.05 sigma (the window's edge
/// cuts the tails, the fit takes a few degrees of freedom; the core's
/// `the_noise_estimate_does_not_fall_as_the_density_rises` measures that band on a
/// line). A scan's record gives its `range_noise` instead.
#[test]
fn a_point_clouds_stats_give_the_noise_it_measured() {
    let dir = tempfile::tempdir().unwrap();
    for (sigma, seed) in [(0.002, 1), (0.005, 2), (0.01, 3)] {
        let (s, _) = circle_run(dir.path(), 2000, sigma, seed);
        let ratio = s["noise"].as_f64().expect("a cloud reports its noise") / sigma;
        assert!((0.8..=1.05).contains(&ratio), "sigma {sigma}: {ratio}");
        assert!(s.get("range_noise").is_none(), "{s}");
    }
}
