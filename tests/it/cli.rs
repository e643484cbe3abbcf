//! Tests that run the real `isoline` binary.

use std::path::Path;
use std::process::Command;

use serde_json::Value;

fn isoline(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_isoline"))
        .args(args)
        .output()
        .expect("run isoline")
}

fn ok_json(args: &[&str]) -> Value {
    let out = isoline(args);
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("JSON on stdout")
}

fn p(path: &Path) -> &str {
    path.to_str().unwrap()
}

/// Issue acceptance: circle of radius 0.4, 2,000 points, noise 0.002, hmin = eps = 1e-3.
#[test]
fn anisotropic_mesh_beats_isotropic_on_the_circle() {
    let dir = tempfile::tempdir().unwrap();
    let frames = dir.path().join("circle.ndjson");
    let svg = dir.path().join("mesh.svg");
    let stats = dir.path().join("stats.json");
    let cfg = concat!(env!("CARGO_MANIFEST_DIR"), "/config/circle-hmin1e-3.toml");
    let out = isoline(&[
        "synth",
        "circle",
        "--points",
        "2000",
        "--noise",
        "0.002",
        "--seed",
        "5",
        "-o",
        p(&frames),
    ]);
    assert!(out.status.success());
    let out = isoline(&[
        "mesh",
        p(&frames),
        "-c",
        cfg,
        "-o",
        p(&svg),
        "--stats",
        p(&stats),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let aniso: Value = serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
    for key in [
        "vertices",
        "triangles",
        "edges_unit_share",
        "min_quality",
        "ms",
    ] {
        assert!(aniso.get(key).is_some(), "missing {key}");
    }
    let iso = ok_json(&["mesh", p(&frames), "-c", cfg, "--isotropic"]);
    let (va, vi) = (
        aniso["vertices"].as_f64().unwrap(),
        iso["vertices"].as_f64().unwrap(),
    );
    assert!(va <= 0.35 * vi, "anisotropic {va} vs isotropic {vi}");
    assert!(
        aniso["edges_unit_share"].as_f64().unwrap() >= 0.85,
        "{aniso}"
    );
    // No inverted triangle: quality is positive exactly when every triangle is.
    assert!(aniso["min_quality"].as_f64().unwrap() > 0.0);
    let doc = std::fs::read_to_string(&svg).unwrap();
    assert!(doc.starts_with("<svg") && doc.trim_end().ends_with("</svg>"));
}

#[test]
fn eval_measures_concentric_circles_and_synth_is_deterministic() {
    let dir = tempfile::tempdir().unwrap();
    let make = |r: &str, name: &str| {
        let path = dir.path().join(name);
        let n = 2000;
        let r: f64 = r.parse().unwrap();
        let pts: Vec<[f64; 2]> = (0..n)
            .map(|i| {
                let a = std::f64::consts::TAU * i as f64 / n as f64;
                [r * a.cos(), r * a.sin()]
            })
            .collect();
        let doc = serde_json::json!({"polylines": [{"closed": true, "points": pts}]});
        std::fs::write(&path, doc.to_string()).unwrap();
        path
    };
    let a = make("0.4", "a.json");
    let b = make("0.25", "b.json");
    let v = ok_json(&["eval", p(&a), "--truth", p(&b)]);
    assert!(
        (v["hausdorff"].as_f64().unwrap() - 0.15).abs() < 1e-6,
        "{v}"
    );
    assert_eq!(v["components_recon"], 1);

    let s1 = dir.path().join("s1.ndjson");
    let s2 = dir.path().join("s2.ndjson");
    let t = dir.path().join("t.json");
    for s in [&s1, &s2] {
        let out = isoline(&[
            "synth",
            "annulus",
            "--points",
            "300",
            "--noise",
            "0.001",
            "--outliers",
            "0.05",
            "--density",
            "0.5",
            "--frames",
            "3",
            "--motion",
            "0.01",
            "--seed",
            "9",
            "-o",
            p(s),
            "--truth",
            p(&t),
        ]);
        assert!(out.status.success());
    }
    assert_eq!(std::fs::read(&s1).unwrap(), std::fs::read(&s2).unwrap());
    let text = std::fs::read_to_string(&s1).unwrap();
    assert_eq!(text.lines().count(), 3);
    let truth: Value = serde_json::from_str(&std::fs::read_to_string(&t).unwrap()).unwrap();
    assert_eq!(truth["polylines"].as_array().unwrap().len(), 2);
    assert_eq!(truth["frames"].as_array().unwrap().len(), 3);
}

#[test]
fn bad_input_is_reported_with_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let pts = dir.path().join("bad.xy");
    std::fs::write(&pts, "0 0\n1 1\n0.5 NaN\n").unwrap();
    let out = isoline(&["mesh", p(&pts)]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("bad.xy, line 3") && err.contains("not finite"),
        "{err}"
    );

    let cfg = dir.path().join("bad.toml");
    std::fs::write(&cfg, "[mesh]\nhmin = 0.01\nhmax_typo = 3\n").unwrap();
    std::fs::write(&pts, "0 0\n1 1\n").unwrap();
    let out = isoline(&["mesh", p(&pts), "-c", p(&cfg)]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("bad.toml") && err.contains("hmax_typo"),
        "{err}"
    );

    let frames = dir.path().join("cut.ndjson");
    std::fs::write(
        &frames,
        "{\"frame\":0,\"points\":[[0,0],[1,1]]}\n{\"frame\":1,\"points\":[[0,",
    )
    .unwrap();
    let out = isoline(&["mesh", p(&frames)]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("cut.ndjson, line 2"),
        "{err}"
    );
}

#[test]
fn degenerate_point_sets_mesh_validly() {
    let dir = tempfile::tempdir().unwrap();
    for (name, text) in [
        ("one.xy", "3 4\n".to_string()),
        ("same.xy", "1 1\n".repeat(50)),
        (
            "line.xy",
            (0..40).map(|i| format!("{i} {}\n", 2 * i)).collect(),
        ),
        (
            "huge.xy",
            "1e12 1e12\n1.000001e12 1e12\n1e12 1.000001e12\n".to_string(),
        ),
    ] {
        let path = dir.path().join(name);
        std::fs::write(&path, text).unwrap();
        let v = ok_json(&["mesh", p(&path)]);
        assert!(v["min_quality"].as_f64().unwrap() > 0.0, "{name}: {v}");
        assert!(v["vertices"].as_u64().unwrap() >= 4, "{name}: {v}");
    }
}

/// A log that is not a terminal (a file, a pipe: here the test's pipe) holds plain
/// text, no colour codes.
#[test]
fn logs_to_a_file_or_pipe_have_no_colour_codes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let input = d.join("in.ndjson");
    std::fs::write(&input, "{\"frame\": 0, \"points\": 7}\nnot json\n").unwrap();
    let cfg = crate::common::replay_config(d, &input, &d.join("out.ndjson"), "");
    let out = isoline(&["run", "-c", p(&cfg)]);
    assert!(out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("bad input line"), "{err}");
    assert!(!err.contains('\u{1b}'), "{err:?}");
}

/// `isoline --help` starts with what a new user reaches for, shows examples and says
/// where the configuration and the docs are.
#[test]
fn the_help_shows_examples_and_the_main_commands_first() {
    let out = isoline(&["--help"]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("Examples:")
            && text.contains("config/example.toml")
            && text.contains("docs/"),
        "{text}"
    );
    let at = |c: &str| {
        text.find(&format!("\n  {c} "))
            .unwrap_or_else(|| panic!("{c} in {text}"))
    };
    for first in ["reconstruct", "map", "run"] {
        for later in ["synth", "eval", "mesh"] {
            assert!(at(first) < at(later), "{first} after {later}: {text}");
        }
    }
}

/// An operating system's error is said once, with the file it concerns.
#[test]
fn an_os_error_is_said_once() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("missing.xy");
    let out = isoline(&["reconstruct", p(&missing)]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("missing.xy"), "{err}");
    assert_eq!(err.matches("No such file or directory").count(), 1, "{err}");
}

/// The README's bag: `isoline map` without `--odometry` says how its scans get poses,
/// and `isoline eval --map` scores the map with the same options `map` took.
#[test]
fn a_bag_without_odometry_says_so_and_eval_reads_the_bag_as_map_does() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let bag = root.join("fixtures/room-laser-80.mcap");
    let map = d.join("map.geojson");
    let out = isoline(&["map", p(&bag), "-o", p(&map), "--quiet"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("--odometry TOPIC") && err.contains("--register"),
        "{err}"
    );
    let out = isoline(&[
        "map",
        p(&bag),
        "--odometry",
        "/odom",
        "-o",
        p(&map),
        "--quiet",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let e = ok_json(&[
        "eval",
        p(&map),
        "--map",
        "--frames",
        p(&bag),
        "--odometry",
        "/odom",
    ]);
    assert_eq!(e["scans"], 80, "{e}");
    assert!(e["static_within"].as_f64().unwrap() > 0.9, "{e}");
}

/// The daemon's summary says where each frame's level set came from: scans are built
/// from their own scan (not "0 warm starts" with warm starts on), points warm.
#[test]
fn the_run_summary_counts_what_each_frame_started_from() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let frames = d.join("f.ndjson");
    crate::common::synth_room(&frames, 5, 0.1, &[]);
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    for (input, expect) in [
        (frames.clone(), "starts: 5 scan;"),
        (root.join("fixtures/ellipse-500-n001.ndjson"), "warm"),
    ] {
        let out_path = d.join("out.ndjson");
        let cfg =
            crate::common::replay_config(d, &input, &out_path, "[pipeline]\nwarm_start = true\n");
        let _ = std::fs::remove_file(d.join("out.ndjson"));
        let out = isoline(&["run", "-c", p(&cfg)]);
        assert!(out.status.success());
        let err = String::from_utf8_lossy(&out.stderr);
        let line = err
            .lines()
            .find(|l| l.contains("records ("))
            .unwrap_or_default();
        assert!(
            line.contains(expect) && !line.contains("warm starts") && line.contains("waiting"),
            "{err}"
        );
    }
}
