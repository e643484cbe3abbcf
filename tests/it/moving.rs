//! Streams from moving sensors through the daemon, warm against cold on the same frames:
//! a warm start must never leave a frame worse than a cold start would.

use std::path::{Path, PathBuf};

use crate::common::{ok, p};

use serde_json::Value;

/// Runs `isoline` with `args`; its stderr.
fn isoline(args: &[&str]) -> String {
    String::from_utf8_lossy(&ok(args).stderr).to_string()
}

/// Replays `frames` through the daemon as fast as it goes, warm or cold; the records.
fn replay(dir: &Path, frames: &Path, warm: bool) -> Vec<Value> {
    let name = if warm { "warm" } else { "cold" };
    replay_with(dir, frames, name, &format!("warm_start = {warm}"))
}

/// Replays `frames` with the `[pipeline]` settings `pipeline` into `name.ndjson`; the
/// records.
fn replay_with(dir: &Path, frames: &Path, name: &str, pipeline: &str) -> Vec<Value> {
    let out = dir.join(format!("{name}.ndjson"));
    let cfg = dir.join(format!("{name}.toml"));
    std::fs::write(
        &cfg,
        format!(
            "[input]\npath = {frames:?}\nreplay = \"fast\"\n[output]\npath = {out:?}\n\
             [pipeline]\n{pipeline}\n"
        ),
    )
    .unwrap();
    let summary = isoline(&["run", "-c", cfg.to_str().unwrap()]);
    eprintln!("{name}: {}", summary.lines().last().unwrap_or(""));
    std::fs::read_to_string(&out)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

/// Per frame: a warm frame has a curve wherever the cold one has; at least 90% of the
/// frames are warm; the robust fit (90th percentile of the points' distances to the
/// curves) and, if `compare_residuals`, the eq. 11 residual are within a quarter of the
/// cold ones; the share of points explained within `slack`
/// of the cold one; no warnings. Returns the warm share.
fn warm_is_never_worse(warm: &[Value], cold: &[Value], slack: f64, compare_residuals: bool) -> f64 {
    assert_eq!(warm.len(), cold.len());
    let mut warm_frames = 0;
    for (w, c) in warm.iter().zip(cold) {
        let f = &w["frame"];
        assert_eq!(f, &c["frame"]);
        let curves = |r: &Value| r["polylines"].as_array().map_or(0, |p| p.len());
        assert!(
            curves(w) > 0 || curves(c) == 0,
            "frame {f}: no curve warm, {} cold",
            curves(c)
        );
        let (sw, sc) = (&w["stats"], &c["stats"]);
        warm_frames += usize::from(sw["warm_start"] == true);
        let (pw, pc) = (
            sw["fit_p90"].as_f64().unwrap(),
            sc["fit_p90"].as_f64().unwrap(),
        );
        // Measured at most 1.09 (fit) and 1.15 (residual) over these streams; the bound
        // is a quarter above the cold one.
        assert!(pw <= 1.25 * pc, "frame {f}: fit p90 {pw} warm, {pc} cold");
        let (rw, rc) = (
            sw["residual"].as_f64().unwrap(),
            sc["residual"].as_f64().unwrap(),
        );
        // On scans the eq. 11 maximum falls on a return at a run's end, where meshes
        // that differ anywhere place the curve's end differently (it moves by a factor
        // of 2.6 between consecutive cold frames): there the robust fit is compared.
        assert!(
            !compare_residuals || rw <= 1.25 * rc,
            "frame {f}: residual {rw} warm, {rc} cold"
        );
        let (ew, ec) = (
            sw["explained"].as_f64().unwrap(),
            sc["explained"].as_f64().unwrap(),
        );
        assert!(
            ew >= ec - slack,
            "frame {f}: explained {ew} warm, {ec} cold"
        );
        assert!(w.get("warnings").is_none(), "frame {f}: {}", w["warnings"]);
    }
    let share = warm_frames as f64 / warm.len() as f64;
    assert!(share >= 0.9, "warm share {share}");
    share
}

/// Point frames with 3% outliers: the eq. 11 residual (a maximum) follows the outliers,
/// and a warm start decided by it once ran away (the residual doubling each frame to
/// 1.6e12, half the frames empty). Decided by robust measures it stays warm and as good
/// as cold, residual included.
#[test]
fn point_streams_with_outliers_stay_warm_and_never_run_away() {
    let dir = tempfile::tempdir().unwrap();
    let frames = dir.path().join("frames.ndjson");
    isoline(&[
        "synth",
        "ellipse",
        "--points",
        "800",
        "--noise",
        "0.003",
        "--outliers",
        "0.03",
        "--frames",
        "60",
        "--motion",
        "0.003",
        "--seed",
        "2",
        "-o",
        frames.to_str().unwrap(),
    ]);
    let warm = replay(dir.path(), &frames, true);
    let cold = replay(dir.path(), &frames, false);
    warm_is_never_worse(&warm, &cold, 0.02, true);
}

/// A scanner driving round the room, 300 frames of up to 0.1 m and 0.1 rad each, range
/// noise 1 cm, 1% spurious short returns and 2% dropouts. A scan frame is built from
/// its own scan (its band and its free space) whether warm starts are on or not, so no
/// warm frame can lose a wall a cold start keeps: the two runs are the same.
#[test]
fn a_scanner_moving_round_the_room_is_built_from_each_scan_warm_or_cold() {
    moving_scanner_is_built_from_each_scan("room");
}

/// The same scanner driving along the corridor.
#[test]
fn a_scanner_moving_along_the_corridor_is_built_from_each_scan_warm_or_cold() {
    moving_scanner_is_built_from_each_scan("corridor");
}

fn moving_scanner_is_built_from_each_scan(scene: &str) {
    const FRAMES: u64 = 200;
    let dir = tempfile::tempdir().unwrap();
    let frames = dir.path().join("frames.ndjson");
    let truth = dir.path().join("truth.json");
    let count = FRAMES.to_string();
    isoline(&[
        "synth",
        scene,
        "--noise",
        "0.01",
        "--outliers",
        "0.01",
        "--dropout",
        "0.02",
        "--frames",
        &count,
        "--motion",
        "0.1",
        "--seed",
        "3",
        "-o",
        frames.to_str().unwrap(),
        "--truth",
        truth.to_str().unwrap(),
    ]);
    let poses: Vec<[f64; 3]> = std::fs::read_to_string(&frames)
        .unwrap()
        .lines()
        .map(|l| {
            serde_json::from_value(serde_json::from_str::<Value>(l).unwrap()["pose"].clone())
                .unwrap()
        })
        .collect();
    let turn = poses
        .windows(2)
        .map(|w| {
            let d = w[1][2] - w[0][2];
            (d + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI
        })
        .fold(0.0f64, |m, d| m.max(d.abs()));
    assert!(
        turn > 0.09,
        "{scene}: the trajectory turns at most {turn} rad a frame"
    );
    let warm = replay(dir.path(), &frames, true);
    let cold = replay(dir.path(), &frames, false);
    assert_eq!(warm.len(), cold.len());
    for (w, c) in warm.iter().zip(&cold) {
        let f = &w["frame"];
        assert_eq!(w["stats"]["start"], "scan", "frame {f}");
        assert_eq!(w["polylines"], c["polylines"], "frame {f}");
        assert!(w.get("warnings").is_none(), "frame {f}: {}", w["warnings"]);
    }
    // Against the scene: per frame, the Hausdorff distance to the walls in view and
    // the walls the curves miss. A wall seen at grazing incidence by a few returns may
    // be missed. The median frame measured 0.050 m (room) and 0.066 m (corridor, whose
    // far ends are seen at grazing incidence); the bound is a quarter above the worse.
    let (h, missed) = accuracy(dir.path(), "warm", &frames, &truth);
    eprintln!("{scene}: median Hausdorff {h:.4}; walls missed {missed} in {FRAMES} frames");
    assert!(h <= 0.085, "{scene}: median Hausdorff {h}");
    // At most one frame in a hundred misses a wall.
    assert!(
        100 * missed <= FRAMES,
        "{scene}: walls missed {missed} in {FRAMES} frames"
    );
}

/// The median per-frame Hausdorff distance of the run `name` to the scene's walls in
/// view, and how many walls its frames missed in all.
fn accuracy(dir: &Path, name: &str, frames: &Path, truth: &Path) -> (f64, u64) {
    let frames = evaluate(dir, name, frames, truth);
    let missed = frames
        .iter()
        .map(|f| f["walls_missed"].as_u64().unwrap())
        .sum();
    (median(&frames, "hausdorff"), missed)
}

/// `isoline eval` of the run `name`, frame by frame.
fn evaluate(dir: &Path, name: &str, frames: &Path, truth: &Path) -> Vec<Value> {
    let run = dir.join(format!("{name}.ndjson"));
    let out = ok(&["eval", p(&run), "--truth", p(truth), "--frames", p(frames)]);
    let report: Value = serde_json::from_slice(&out.stdout).unwrap();
    report["frames"].as_array().unwrap().clone()
}

/// The median of `key` over `frames`.
fn median(frames: &[Value], key: &str) -> f64 {
    let mut v: Vec<f64> = frames.iter().map(|f| f[key].as_f64().unwrap()).collect();
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Synthesizes `frames` scans of `scene` (1 cm range noise) driving `motion` metres a
/// frame; the frames and the truth files.
fn scans(
    dir: &Path,
    scene: &str,
    frames: usize,
    motion: f64,
    extra: &[&str],
) -> (PathBuf, PathBuf) {
    let out = dir.join(format!("{scene}.ndjson"));
    let truth = dir.join(format!("{scene}.truth.json"));
    let n = frames.to_string();
    let m = motion.to_string();
    let mut args = vec![
        "synth",
        scene,
        "--noise",
        "0.01",
        "--frames",
        &n,
        "--motion",
        &m,
        "--seed",
        "5",
        "-o",
        out.to_str().unwrap(),
        "--truth",
        truth.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    isoline(&args);
    (out, truth)
}

/// Refinement over frames on a static scanner, 20 frames of the room at 1 cm range
/// noise. From the 10th frame on each frame averages ten frames' level sets where they
/// agree with its own within the noise: its curves stray about half as far from the
/// walls as a single frame's (independent noise alone would give 1/sqrt 10 = 0.32; the
/// smoothing along the runs rounds corners alike in every frame, which no average
/// removes: at most 0.6). The Hausdorff distance of one frame is set by its spikes,
/// returns three or more deviations off the wall that its runs' lines leave raw; the
/// window averages a spike of one frame alone away, so the refined frame's worst stretch
/// is a corner again: at most 0.6 of one frame's too.
#[test]
fn refinement_over_frames_averages_the_noise_down() {
    let dir = tempfile::tempdir().unwrap();
    let (frames, truth) = scans(dir.path(), "room", 20, 0.0, &[]);
    replay_with(dir.path(), &frames, "single", "warm_start = true");
    let refined = replay_with(dir.path(), &frames, "refined", "accumulate = 10");
    for (i, r) in refined.iter().enumerate() {
        assert_eq!(r["stats"]["window"]["frames"], (i + 1).min(10), "frame {i}");
    }
    let single = evaluate(dir.path(), "single", &frames, &truth);
    let refined = evaluate(dir.path(), "refined", &frames, &truth);
    let (ms, mr) = (
        median(&single[9..], "mean_distance"),
        median(&refined[9..], "mean_distance"),
    );
    let (hs, hr) = (
        median(&single[9..], "hausdorff"),
        median(&refined[9..], "hausdorff"),
    );
    eprintln!(
        "mean distance: one frame {ms:.5}, ten {mr:.5}; Hausdorff: one frame {hs:.4}, ten {hr:.4}"
    );
    assert!(mr <= 0.6 * ms, "mean distance {mr} refined, {ms} one frame");
    assert!(hr <= 0.6 * hs, "Hausdorff {hr} refined, {hs} one frame");
}

/// Refinement over frames on the moving scanner (60 frames round the room, 0.1 m and
/// up to 0.1 rad a frame): every frame has curves, the last frame's, taken into the
/// world by its pose, lie within 3 sigma + 2 hmin (5 cm) of the scene's walls, and the
/// curves stray from the walls at most 0.7 as far as a single frame's (the static
/// scanner's bound, 0.6, plus the alignments' error: each older frame is laid onto the
/// newest by its own alignment, off by a fraction of a millimetre; an alignment biased
/// by a millimetre, as a point-to-line ICP on the returns' own zigzag is, leaves 0.9).
#[test]
fn refinement_on_a_moving_scanner_stays_on_the_walls() {
    let dir = tempfile::tempdir().unwrap();
    let (frames, truth) = scans(dir.path(), "room", 60, 0.1, &["--outliers", "0.01"]);
    replay_with(dir.path(), &frames, "single", "warm_start = true");
    let refined = replay_with(dir.path(), &frames, "refined", "accumulate = 10");
    let (ms, mr) = (
        median(
            &evaluate(dir.path(), "single", &frames, &truth)[9..],
            "mean_distance",
        ),
        median(
            &evaluate(dir.path(), "refined", &frames, &truth)[9..],
            "mean_distance",
        ),
    );
    eprintln!("mean distance: one frame {ms:.5}, ten {mr:.5}");
    assert!(mr <= 0.7 * ms, "mean distance {mr} refined, {ms} one frame");
    assert!(refined
        .iter()
        .all(|r| r["polylines"].as_array().is_some_and(|p| !p.is_empty())));
    let scene: Value = serde_json::from_str(&std::fs::read_to_string(&truth).unwrap()).unwrap();
    let walls: Vec<[[f64; 2]; 2]> = scene["scene"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|w| {
            let p: Vec<[f64; 2]> = serde_json::from_value(w["points"].clone()).unwrap();
            p.windows(2).map(|s| [s[0], s[1]]).collect::<Vec<_>>()
        })
        .collect();
    let last_frame: Value = serde_json::from_str(
        std::fs::read_to_string(&frames)
            .unwrap()
            .lines()
            .last()
            .unwrap(),
    )
    .unwrap();
    let pose: [f64; 3] = serde_json::from_value(last_frame["pose"].clone()).unwrap();
    let (s, c) = pose[2].sin_cos();
    let last = refined.last().unwrap();
    let mut worst = 0.0f64;
    for pl in last["polylines"].as_array().unwrap() {
        for p in pl["points"].as_array().unwrap() {
            let (x, y) = (p[0].as_f64().unwrap(), p[1].as_f64().unwrap());
            let w = [pose[0] + c * x - s * y, pose[1] + s * x + c * y];
            let d = walls
                .iter()
                .map(|&[a, b]| segment_distance(w, a, b))
                .fold(f64::INFINITY, f64::min);
            worst = worst.max(d);
        }
    }
    let bound = 3.0 * 0.01 + 2.0 * last["stats"]["hmin"].as_f64().unwrap();
    eprintln!("last frame: farthest curve point {worst:.4} m from a wall (bound {bound:.4})");
    assert!(worst <= bound, "{worst} > {bound}");
}

/// A person (a post 0.4 m across) walking across the room at 2 m/s in front of a static
/// scanner, refined over 10 frames (a quarter of a second: the person moves 0.5 m
/// within the window). Every frame's curves lie within 3 sigma + 2 hmin of a surface the
/// frame sees, the person where it is now included: a person's arc from an older frame
/// (a ghost 0.05 to 0.5 m from the present one), or a wall drawn through the shadow the
/// person casts, would break it. And the person is drawn where it is: the frame's returns
/// on it are explained, as are all but a few of the others.
#[test]
fn a_person_walking_through_is_not_fused_into_the_walls() {
    let dir = tempfile::tempdir().unwrap();
    let (frames, truth) = scans(dir.path(), "room", 60, 0.0, &["--walker", "2"]);
    let refined = replay_with(dir.path(), &frames, "refined", "accumulate = 10");
    let scored = evaluate(dir.path(), "refined", &frames, &truth);
    for (r, s) in refined.iter().zip(&scored) {
        let bound = 3.0 * 0.01 + 2.0 * r["stats"]["hmin"].as_f64().unwrap();
        let off = s["recon_to_truth"].as_f64().unwrap();
        assert!(
            off <= bound,
            "frame {}: a curve {off} m from every surface",
            s["frame"]
        );
        let explained = s["returns_explained"].as_f64().unwrap();
        assert!(
            explained >= 0.97,
            "frame {}: {explained} explained",
            s["frame"]
        );
    }
}

fn segment_distance(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let l2 = dx * dx + dy * dy;
    let t = if l2 > 0.0 {
        (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p[0] - a[0] - t * dx).hypot(p[1] - a[1] - t * dy)
}
