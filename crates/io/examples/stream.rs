//! A stream of frames through the stages, each warm-started from the one before it, and
//! the results as the daemon writes them: one NDJSON record per frame.
//!
//! `cargo run --release --example stream`

use isoline_core::{stages::reconstruct_with, Params, Reconstruction};
use isoline_io::format::ResultRecord;
use isoline_io::parse_frame;

fn main() {
    // Frames as they would arrive from a file, stdin or TCP: a shape drifting by 0.01 a
    // frame, 400 points each.
    let lines: Vec<String> = (0..5)
        .map(|k| {
            let pts: Vec<[f64; 2]> = (0..400)
                .map(|i| {
                    let a = i as f64 * std::f64::consts::TAU / 400.0;
                    [0.5 + 0.01 * k as f64 + 0.3 * a.cos(), 0.5 + 0.2 * a.sin()]
                })
                .collect();
            serde_json::json!({"stream": "demo", "frame": k, "points": pts}).to_string()
        })
        .collect();
    let params = Params::default();
    let mut previous: Option<Reconstruction> = None;
    for (n, line) in lines.iter().enumerate() {
        let frame = parse_frame(line, "example", n + 1).expect("a valid frame");
        let r = reconstruct_with(
            &frame.points,
            frame.scan.as_ref(),
            &params,
            previous.as_ref(),
        )
        .expect("a valid frame");
        let record = ResultRecord::of(frame.stream.clone(), frame.frame, &r);
        // What `isoline run` writes, and how to read it back.
        let text = serde_json::to_string(&record).expect("serializable");
        let back: ResultRecord = serde_json::from_str(&text).expect("round trip");
        let stats = back.stats.expect("a reconstructed frame has stats");
        println!(
            "frame {}: {} polyline(s), warm start {}, {:.1} ms",
            frame.frame,
            back.polylines.map_or(0, |p| p.len()),
            stats.warm_start,
            stats.ms.total
        );
        assert_eq!(stats.warm_start, n > 0);
        previous = Some(r);
    }
}

#[test]
fn runs() {
    main();
}
