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

/// The map's frames: the first four bytes pick the cell, the tile, the beams' reach and
/// the hit tolerance (from 1 mm to 1000 m); then each 64 bytes are a scan of eight
/// beams with a pose and a range noise of any bits (NaN, infinite, 1e300, 2.8e17 m),
/// fused with a curve through its returns. Settings the map refuses are refused; every
/// scan is fused or refused; memory and the store stay within their bounds.
pub fn map(data: &[u8]) {
    use isoline_core::{LaserScan, Polyline, Scan};
    use isoline_map::{Map, MapParams, MemoryStore};
    let Some((head, rest)) = data.split_at_checked(4) else {
        return;
    };
    let base = MapParams {
        cell: [0.01, 0.03, 0.1, 1.0][usize::from(head[0] % 4)],
        tile: [4, 8, 16, 128][usize::from(head[1] % 4)],
        max_range: [1.0, 5.0, 20.0][usize::from(head[2] % 3)],
        hit_tolerance: 10f64.powf(f64::from(head[3]) * 6.0 / 255.0 - 3.0),
        max_stored_tiles: 16,
        ..MapParams::default()
    };
    // The fewest tiles in memory the settings allow, if any.
    let Some(params) = (0..24)
        .map(|k| MapParams {
            max_tiles: 1 << k,
            ..base
        })
        .find(|p| p.validate().is_ok())
    else {
        return;
    };
    let Ok(mut map) = Map::new(params, Box::new(MemoryStore::default())) else {
        return;
    };
    let f = |b: &[u8]| f64::from_le_bytes(b.try_into().expect("eight bytes"));
    for c in rest.chunks_exact(64).take(64) {
        let pose = [f(&c[0..8]), f(&c[8..16]), f(&c[16..24])];
        let noise = f(&c[24..32]);
        let ranges: Vec<Option<f64>> = c[32..40]
            .iter()
            .map(|&b| (b > 0).then(|| f64::from(b) / 10.0))
            .collect();
        let Ok(scan) = Scan::from_laser(&LaserScan {
            origin: [0.0, 0.0],
            angle_min: -1.0,
            angle_increment: 0.25,
            ranges: &ranges,
            range_min: 0.0,
            range_max: 30.0,
        }) else {
            continue;
        };
        let curve = Polyline {
            closed: false,
            points: scan.returns(),
        };
        let _ = map.insert(&scan, pose, &[curve], noise);
        let s = map.stats();
        assert!(s.tiles_resident <= params.max_tiles, "{s:?}");
        assert!(s.tiles_stored <= params.max_stored_tiles, "{s:?}");
    }
    for pl in map.curves().expect("a memory store does not fail") {
        assert!(pl.points.iter().flatten().all(|c| c.is_finite()));
    }
}

/// The CARMEN reader on any bytes (gzip-compressed when they start as gzip does): the
/// pile of no-return codes, `PARAM` reach and the three laser messages. Every laser
/// line is a frame or a bad frame; readings are finite and within the frame's reach.
pub fn carmen(data: &[u8]) {
    let dir = std::env::temp_dir().join(format!("isoline-fuzz-carmen-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("a temporary folder");
    let path = dir.join("in.log");
    std::fs::write(&path, data).expect("a temporary file");
    let _ = isoline_io::carmen::read_carmen_with(&path, Ok, |item| {
        if let Ok(rec) = item {
            let reach = rec.range_max.unwrap_or(f64::INFINITY);
            for r in rec.ranges.iter().flatten().flatten() {
                assert!(
                    r.is_finite() && *r > 0.0 && *r < reach + 1e-9,
                    "{r} {reach}"
                );
            }
        }
        true
    });
}
