//! What each fuzz target does with its input, shared with `tests/fuzz_regressions.rs`
//! so that every input a fuzzer kept is replayed by `cargo test` on stable.
//!
//! Each function must return for any input; a panic is the bug the fuzzer looks for.

#![allow(dead_code)]

use std::path::Path;

use isoline_core::geom::Point;
use isoline_core::{reconstruct, Params};
use isoline_io::reconstruct_frame;

/// The point-file reader: any text is points or a typed error, and the points read
/// are finite.
pub fn points(data: &[u8]) {
    let text = String::from_utf8_lossy(data);
    if let Ok(pts) = isoline_io::parse_points(&text, "fuzz") {
        assert!(pts.iter().flatten().all(|c| c.is_finite()));
    }
}

/// The NDJSON frame parser, then (for small frames) the whole reconstruction, which
/// covers scan frames' range handling.
pub fn frame(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(frame) = isoline_io::parse_frame(text, "fuzz", 1) {
        assert!(frame.points.iter().flatten().all(|c| c.is_finite()));
        if frame.points.len() <= 300 {
            let _ = reconstruct_frame(&frame, &Params::default());
        }
    }
}

/// Every configuration reader: the shared tables and the daemon's.
pub fn config(data: &[u8]) {
    let text = String::from_utf8_lossy(data);
    if let Ok(c) = isoline::config::Config::parse(&text, "fuzz") {
        let _ = c.params();
    }
    let _ = isoline::pipeline::DaemonConfig::parse(&text, "fuzz", Path::new("/nonexistent"));
}

/// The recording readers: the first byte picks a ROS 2 bag (even) or a CARMEN log (odd),
/// the rest is the file, read with poses asked for. Any bytes are frames, bad frames or
/// an error naming the file.
pub fn recording(data: &[u8]) {
    let Some((&kind, rest)) = data.split_first() else {
        return;
    };
    let dir = std::env::temp_dir().join(format!("isoline-fuzz-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("a temporary folder");
    let path = dir.join(if kind % 2 == 0 { "in.mcap" } else { "in.clf" });
    std::fs::write(&path, rest).expect("a temporary file");
    let opts = isoline_io::bag::BagOptions {
        odometry: Some("/odom".into()),
        ..Default::default()
    };
    if let Ok(items) = isoline_io::read_items(&path, &opts) {
        for f in items.iter().flatten() {
            assert!(f.points.iter().flatten().all(|c| c.is_finite()));
        }
    }
}

/// The whole reconstruction on up to 128 points decoded from the bytes: the first byte
/// picks a scale from 1e-150 to 1e150, then each 4 bytes are two 16-bit coordinates,
/// so duplicates, lines, clusters and extreme extents all occur.
pub fn reconstruct_points(data: &[u8]) {
    let Some((&s, rest)) = data.split_first() else {
        return;
    };
    let scale = 10f64.powi(i32::from(s) * 300 / 255 - 150);
    let pts: Vec<Point> = rest
        .chunks_exact(4)
        .take(128)
        .map(|c| {
            let x = i16::from_le_bytes([c[0], c[1]]);
            let y = i16::from_le_bytes([c[2], c[3]]);
            [f64::from(x) * scale, f64::from(y) * scale]
        })
        .collect();
    if let Ok(r) = reconstruct(&pts, &Params::default()) {
        for pl in &r.polylines {
            assert!(pl.points.iter().flatten().all(|c| c.is_finite()));
        }
    }
}
