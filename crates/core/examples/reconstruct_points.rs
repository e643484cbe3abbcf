//! Reconstruct a closed curve from an unorganized, noisy point set.
//!
//! `cargo run --release --example reconstruct_points`

use isoline_core::{reconstruct, Params};

fn main() {
    // 1,000 points around a circle of radius 0.4, scattered by up to 0.005.
    let points: Vec<[f64; 2]> = (0..1000)
        .map(|i| {
            let a = i as f64 * 2.399_963; // golden angle: no ordering information
            let r = 0.4 + 0.005 * (i as f64 * 12.9898).sin();
            [0.5 + r * a.cos(), 0.5 + r * a.sin()]
        })
        .collect();
    let r = reconstruct(&points, &Params::default()).expect("a valid point set");
    for pl in &r.polylines {
        println!(
            "{} polyline of {} vertices, length {:.3}, area {:.3}",
            if pl.closed { "closed" } else { "open" },
            pl.points.len(),
            pl.length(),
            pl.signed_area()
        );
    }
    let s = &r.stats;
    println!(
        "{} points, {} mesh vertices, hmin {:.4}, {:.1} ms",
        s.points, s.vertices, s.hmin, s.ms.total
    );
    // One loop, counter-clockwise, enclosing about pi r^2.
    assert_eq!(r.polylines.len(), 1);
    let area = r.polylines[0].signed_area();
    assert!((area - std::f64::consts::PI * 0.16).abs() < 0.01, "{area}");
}

#[test]
fn runs() {
    main();
}
