//! Reconstruct the walls a 2D laser scanner saw: beams in (like a ROS LaserScan), open
//! wall curves out, with the free side on their left, and the returns no wall explains.
//!
//! `cargo run --release --example scan_frame`

use isoline_core::{reconstruct_scan, Params};
use isoline_core::{LaserScan, Scan};
use isoline_sim::lidar::{simulate, LidarParams, SceneKind};

fn main() {
    // One scan of the simulated room with clutter, by a Hokuyo UTM-30LX-like sensor:
    // 1,080 beams over 270 degrees, 1 cm of range noise, 2% of the beams dropped.
    let mut sim = LidarParams::new(SceneKind::Clutter);
    sim.noise = Some(0.01);
    sim.dropout = 0.02;
    let frame = simulate(&sim).expect("valid options").remove(0);
    let scan = Scan::from_laser(&LaserScan {
        origin: [0.0, 0.0],
        angle_min: frame.angle_min,
        angle_increment: frame.angle_increment,
        ranges: &frame.ranges,
        range_min: frame.range_min,
        range_max: frame.range_max,
    })
    .expect("a well-formed scan");
    let r = reconstruct_scan(&scan, &Params::default()).expect("enough returns");
    for (k, wall) in r.polylines.iter().enumerate() {
        let (a, b) = (wall.points[0], wall.points[wall.points.len() - 1]);
        println!(
            "wall {k}: {:.2} m from ({:.2}, {:.2}) to ({:.2}, {:.2})",
            wall.length(),
            a[0],
            a[1],
            b[0],
            b[1]
        );
    }
    for f in &r.features {
        println!(
            "feature: {} returns around ({:.2}, {:.2})",
            f.returns, f.center[0], f.center[1]
        );
    }
    println!(
        "range noise {:.4} m, hmin {:.4} m, {:.1} ms",
        r.stats.range_noise.unwrap_or(0.0),
        r.stats.hmin,
        r.stats.ms.total
    );
    assert!(r.polylines.iter().all(|p| !p.closed));
    assert!(r.polylines.iter().map(|p| p.length()).sum::<f64>() > 20.0);
}

#[test]
fn runs() {
    main();
}
