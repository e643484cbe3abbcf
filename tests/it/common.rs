//! What the integration tests share: running the real binary.

use std::path::Path;
use std::process::{Command, Output};

/// Runs `isoline` with `args` and checks that it succeeded (its stderr in the message).
pub fn ok(args: &[&str]) -> Output {
    let out = Command::new(env!("CARGO_BIN_EXE_isoline"))
        .args(args)
        .output()
        .expect("run isoline");
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// A path as an argument.
#[allow(dead_code)] // Not every test file passes paths.
pub fn p(path: &Path) -> &str {
    path.to_str().expect("a UTF-8 path")
}

/// Distance from `q` to the nearest segment of `walls` (polylines).
#[allow(dead_code)] // Only the map tests measure against walls.
pub fn to_walls(q: [f64; 2], walls: &[Vec<[f64; 2]>]) -> f64 {
    let mut best = f64::INFINITY;
    for w in walls {
        for s in w.windows(2) {
            let (a, b) = (s[0], s[1]);
            let d = [b[0] - a[0], b[1] - a[1]];
            let l2 = d[0] * d[0] + d[1] * d[1];
            let t = if l2 > 0.0 {
                (((q[0] - a[0]) * d[0] + (q[1] - a[1]) * d[1]) / l2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            best = best.min((q[0] - a[0] - t * d[0]).hypot(q[1] - a[1] - t * d[1]));
        }
    }
    best
}

/// The static walls of a truth file's scene (`isoline synth` of a scene).
#[allow(dead_code)] // Only the map tests measure against walls.
pub fn scene_walls(truth: &Path) -> Vec<Vec<[f64; 2]>> {
    let truth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(truth).unwrap()).unwrap();
    truth["scene"]
        .as_array()
        .expect("a scene's truth")
        .iter()
        .map(|pl| serde_json::from_value(pl["points"].clone()).unwrap())
        .collect()
}

/// `isoline synth room` into `out`: `frames` scans `motion` metres apart along the
/// room's path, with `extra` options (noise, seed, stream) after them.
pub fn synth_room(out: &Path, frames: usize, motion: f64, extra: &[&str]) {
    let (frames, motion) = (frames.to_string(), motion.to_string());
    let mut args = vec!["synth", "room", "--frames", &frames, "--motion", &motion];
    args.extend_from_slice(extra);
    args.extend(["-o", p(out)]);
    ok(&args);
}

/// Runs `isoline` with `args`, checks that it failed, and gives its stderr.
#[allow(dead_code)] // Not every test file expects failures.
pub fn fails(args: &[&str]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_isoline"))
        .args(args)
        .output()
        .expect("run isoline");
    assert!(!out.status.success(), "{args:?} succeeded");
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// A daemon configuration in `dir` (`run.toml`) that replays `input` as fast as it can
/// into the NDJSON file `output`, with the further tables `extra`; its path.
#[allow(dead_code)] // Only some test files run the daemon.
pub fn replay_config(dir: &Path, input: &Path, output: &Path, extra: &str) -> std::path::PathBuf {
    let cfg = dir.join("run.toml");
    std::fs::write(
        &cfg,
        format!(
            "[input]\npath = {:?}\nreplay = \"fast\"\n[output]\npath = {:?}\n{extra}",
            p(input),
            p(output)
        ),
    )
    .expect("write the configuration");
    cfg
}
