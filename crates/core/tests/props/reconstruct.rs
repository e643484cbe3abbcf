//! Properties of `reconstruct` over generated inputs: it returns curves or a typed
//! error for anything finite within the documented limits (never a panic), and its
//! result does not depend on the data's units: scaled and translated data give the same
//! curves, scaled and translated.

use isoline_core::geom::Polyline;
use isoline_core::{reconstruct, reconstruct_scan, Params};
use isoline_core::{LaserScan, Scan};
use proptest::prelude::*;

/// A coordinate of any magnitude the contract accepts (|x| <= 1e150).
fn coord() -> impl Strategy<Value = f64> {
    (-1.0f64..1.0, -140i32..140).prop_map(|(m, e)| m * 10f64.powi(e))
}

/// Noisy points around a circle of radius 0.4: the simulator's, noise 0.002.
fn circle(n: usize, seed: u64) -> Vec<[f64; 2]> {
    let mut p = isoline_sim::SynthParams::new(isoline_sim::Shape::Circle);
    p.points = n;
    p.noise = 0.002;
    p.seed = seed;
    isoline_sim::generate(&p).unwrap().remove(0).points
}

fn hausdorff(a: &[Polyline], b: &[Polyline]) -> f64 {
    isoline_sim::compare(a, b, None)
        .hausdorff
        .unwrap_or(f64::INFINITY)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    /// Any finite point set within the limits: curves or a typed error, no panic.
    #[test]
    fn any_point_set_gives_curves_or_an_error(
        pts in prop::collection::vec([coord(), coord()], 1..60),
        spread in prop::sample::select(vec![1e-140, 1e-9, 1.0, 1e9, 1e140]),
    ) {
        // Points spread around one place, at one of several sizes: far-flung
        // magnitudes at random would almost always be one cluster per point.
        let c = pts[0];
        let local: Vec<[f64; 2]> = pts
            .iter()
            .map(|p| [c[0] + spread * (p[0] / (1.0 + p[0].abs())), c[1] + spread * (p[1] / (1.0 + p[1].abs()))])
            .collect();
        match reconstruct(&local, &Params::default()) {
            Ok(r) => {
                for pl in &r.polylines {
                    prop_assert!(pl.points.iter().all(|p| p[0].is_finite() && p[1].is_finite()));
                }
            }
            Err(e) => prop_assert!(!e.to_string().is_empty()),
        }
    }

    /// Any beams: ranges of any size, missing returns, any step up to a turn.
    #[test]
    fn any_scan_gives_curves_or_an_error(
        ranges in prop::collection::vec(prop::option::of(0.0f64..50.0), 1..200),
        angle_min in -4.0f64..4.0,
        step in 1e-4f64..0.03,
        range_max in 0.5f64..60.0,
    ) {
        let scan = Scan::from_laser(&LaserScan {
            origin: [0.0, 0.0],
            angle_min,
            angle_increment: step,
            ranges: &ranges,
            range_min: 0.0,
            range_max,
        });
        if let Ok(scan) = scan {
            if let Ok(r) = reconstruct_scan(&scan, &Params::default()) {
                prop_assert!(r.polylines.iter().all(|p| !p.closed || p.points.len() >= 3));
            }
        }
    }

    /// The same shape in other units and elsewhere: the same components, and curves
    /// that, scaled and moved back, lie within twice 3 sigma + 2 hmin of the
    /// original's (sigma the noise's deviation, 0.004 / sqrt 12 for noise uniform over
    /// 0.004), with the same hmin in the new units. Not once: the result depends on
    /// rounding, whatever the units. On the regression case kept in
    /// proptest-regressions/ (seed 144, 1e-14 units, shifted 1,600 shape sizes) the
    /// curves lie 1.54 bounds apart, and so do those of the same data at unit scale
    /// with every coordinate moved by a relative 1e-13 (1.55 bounds): where the noise
    /// leaves the curve two places to settle, rounding picks one. This test asks that
    /// other units change the curves no more than that; the rounding sensitivity
    /// itself is a defect to remove, not a property.
    #[test]
    fn results_follow_the_data_units(
        seed in 0u64..1000,
        exponent in -100i32..100,
        mantissa in 1.0f64..10.0,
        shift in [-1e3f64..1e3, -1e3f64..1e3],
    ) {
        let pts = circle(800, seed);
        let base = reconstruct(&pts, &Params::default()).unwrap();
        let s = mantissa * 10f64.powi(exponent);
        let t = [shift[0] * s, shift[1] * s];
        let moved: Vec<[f64; 2]> = pts.iter().map(|p| [p[0] * s + t[0], p[1] * s + t[1]]).collect();
        let r = reconstruct(&moved, &Params::default()).unwrap();
        prop_assert_eq!(r.polylines.len(), base.polylines.len());
        let back: Vec<Polyline> = r
            .polylines
            .iter()
            .map(|pl| Polyline {
                closed: pl.closed,
                points: pl.points.iter().map(|p| [(p[0] - t[0]) / s, (p[1] - t[1]) / s]).collect(),
            })
            .collect();
        let h = hausdorff(&back, &base.polylines);
        let bound = 2.0 * (3.0 * 0.004 / 12f64.sqrt() + 2.0 * base.stats.hmin);
        prop_assert!(h <= bound, "{h} against {bound}");
        let ratio = r.stats.hmin / (s * base.stats.hmin);
        prop_assert!((ratio - 1.0).abs() < 1e-6, "hmin ratio {ratio}");
        // Nor the cost: at 1e-12 the mesh was once 12 times larger (an absolute
        // threshold in the metric). Rounding moves a few vertices, not a tenth of them.
        let cost = r.stats.vertices as f64 / base.stats.vertices as f64;
        prop_assert!((cost - 1.0).abs() < 0.1, "vertices {} against {}", r.stats.vertices, base.stats.vertices);
    }
}
