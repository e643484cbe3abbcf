//! Replays every input kept for the fuzz targets (the seeds, and each input a fuzzer
//! found to crash or hang, in `fuzz/regressions/TARGET`) through the same harness the
//! fuzzers use, on the stable toolchain. The inputs of the hardening issue that once
//! panicked are replayed here too.

#[path = "../../fuzz/harness.rs"]
mod harness;

use std::path::Path;

fn replay(target: &str, run: fn(&[u8])) -> usize {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz");
    let mut n = 0;
    for dir in ["seeds", "regressions"] {
        let Ok(entries) = std::fs::read_dir(root.join(dir).join(target)) else {
            continue;
        };
        for e in entries {
            let path = e.unwrap().path();
            let data = std::fs::read(&path).unwrap();
            // A panic names the file through the test's output.
            eprintln!("{}", path.display());
            run(&data);
            n += 1;
        }
    }
    n
}

#[test]
fn recordings() {
    assert!(replay("recording", harness::recording) >= 2);
}

#[test]
fn maps() {
    assert!(replay("map", harness::map) >= 2);
}

#[test]
fn carmen_logs() {
    assert!(replay("carmen", harness::carmen) >= 2);
}

#[test]
fn point_files() {
    assert!(replay("points", harness::points) > 0);
    harness::points(b"1e999 0\n0 0\n");
    harness::points(b"\xff\xfe 1 2\n");
}

#[test]
fn frames() {
    assert!(replay("frame", harness::frame) > 0);
    for line in [
        r#"{"frame":18446744073709551615,"points":[[0,0],[1,0],[0,1]]}"#,
        r#"{"frame":1,"t":1e19,"points":[[0,0],[1e-300,0],[0,1e300]]}"#,
        r#"{"frame":1,"ranges":[1,2,3],"angle_min":0,"angle_increment":1e-300}"#,
        r#"{"frame":1,"ranges":[1e308,1e308,1e308],"angle_min":0,"angle_increment":0.1,"range_max":1e309}"#,
    ] {
        harness::frame(line.as_bytes());
    }
}

#[test]
fn configurations() {
    assert!(replay("config", harness::config) > 0);
    for text in [
        "[mesh]\nhmin = 1e300\n",
        "[mesh]\npadding = 1e300\n",
        "[mesh]\npadding = 20\nmax_vertices = 10000\n",
        "[input]\npath = \"f\"\nreplay = 1e-19\n",
        "[solver]\nmax_iterations = 18446744073709551615\n",
    ] {
        harness::config(text.as_bytes());
    }
}

#[test]
fn small_point_sets() {
    replay("reconstruct", harness::reconstruct_points);
    // Every scale byte on a square: extents from 1e-150 to 1e150.
    for s in (0..=255u8).step_by(17) {
        let mut data = vec![s];
        for (x, y) in [
            (0i16, 0i16),
            (100, 0),
            (100, 100),
            (0, 100),
            (50, 50),
            (50, 50),
        ] {
            data.extend(x.to_le_bytes());
            data.extend(y.to_le_bytes());
        }
        harness::reconstruct_points(&data);
    }
}

/// Three distinct points a few ulps apart (23 samples of them): the curve came out as a
/// long chord among specks of zero length, and indexing its segments for the fit
/// statistics once asked for a billion pieces and aborted out of memory (found by the
/// property test of reconstruct).
#[test]
fn points_a_few_ulps_apart_do_not_exhaust_memory() {
    let x = 1.6850288147230907e-27;
    let ys = [
        -7.788671795046529e-126,
        -7.788671795046519e-126,
        -7.788671795046508e-126,
    ];
    let pts: Vec<[f64; 2]> = [
        1, 1, 1, 1, 2, 2, 0, 1, 1, 1, 0, 0, 1, 0, 1, 1, 0, 2, 2, 0, 2, 1, 1,
    ]
    .iter()
    .map(|&i| [x, ys[i]])
    .collect();
    match isoline_core::reconstruct(&pts, &isoline_core::Params::default()) {
        Ok(r) => assert!(r.polylines.iter().all(|p| p
            .points
            .iter()
            .flatten()
            .all(|c| c.is_finite()))),
        Err(e) => assert!(!e.to_string().is_empty()),
    }
}
