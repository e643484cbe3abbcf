//! A scan's curves never cross a beam nearer than its return by more than their
//! accuracy bound (three range noises and two elements of the mesh), on scans
//! generated as a scanner returns them near furniture: the space a beam saw through
//! holds no curve (docs/method.md, scanner frames).

use isoline_core::{reconstruct_scan, LaserScan, Params, Scan};
use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// A leg: its centre's range and bearing from the sensor, and its radius (metres,
/// radians).
#[derive(Clone, Debug)]
struct Leg {
    range: f64,
    bearing: f64,
    radius: f64,
}

/// The beams of a scanner at the origin (half a turn, `beams` of them) in a room of
/// half-sizes `room` with `legs`: each beam stops at the nearest surface. A beam next
/// to a depth jump of more than 10 cm returns, with probability `mixed`, a range
/// between the two surfaces (the mixed pixels of a beam whose footprint straddles an
/// edge, as SICK LMS scanners return them: Ye & Borenstein 2002); then Gaussian range
/// noise `sigma`, and ranges rounded to `step` when it is not zero (some logs keep
/// 5 cm steps).
fn furniture_scan(
    room: [f64; 2],
    legs: &[Leg],
    beams: usize,
    (sigma, mixed, step): (f64, f64, f64),
    seed: u64,
) -> Vec<Option<f64>> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, sigma).expect("sigma is positive");
    let bearing = |i: usize| std::f64::consts::PI * i as f64 / (beams - 1) as f64;
    let cast = |a: f64| {
        let d = [a.cos(), a.sin()];
        // The room's walls: the rectangle round the sensor.
        let mut r = f64::INFINITY;
        for (k, half) in room.iter().enumerate() {
            if d[k].abs() > 1e-12 {
                r = r.min(half / d[k].abs());
            }
        }
        for leg in legs {
            let c = [leg.range * leg.bearing.cos(), leg.range * leg.bearing.sin()];
            let along = c[0] * d[0] + c[1] * d[1];
            let off2 = (c[0] * c[0] + c[1] * c[1]) - along * along;
            let h2 = leg.radius * leg.radius - off2;
            if along > 0.0 && h2 >= 0.0 {
                r = r.min(along - h2.sqrt());
            }
        }
        r
    };
    let truth: Vec<f64> = (0..beams).map(|i| cast(bearing(i))).collect();
    (0..beams)
        .map(|i| {
            let mut r = truth[i];
            let far = [i.checked_sub(1), (i + 1 < beams).then_some(i + 1)]
                .into_iter()
                .flatten()
                .map(|j| truth[j])
                .fold(r, f64::max);
            if far - r > 0.1 && rng.random::<f64>() < mixed {
                r += rng.random::<f64>() * (far - r);
            }
            r += noise.sample(&mut rng);
            if step > 0.0 {
                r = (r / step).round() * step;
            }
            (r > 0.05).then_some(r)
        })
        .collect()
}

fn leg() -> impl Strategy<Value = Leg> {
    (0.3f64..1.5, 0.1f64..3.0, 0.008f64..0.03).prop_map(|(range, bearing, radius)| Leg {
        range,
        bearing,
        radius,
    })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    /// Rooms of 1 to 6 m with up to eight legs near the sensor, beams 0.25 to 1 degree
    /// apart, noise 2 mm to 3 cm, mixed pixels, with and without 5 cm steps: no curve
    /// crosses a beam nearer than its return by more than `3 sigma + 2 hmin` (the
    /// frame's own noise estimate and mesh size, which it reports), to rounding.
    #[test]
    fn no_curve_crosses_a_beam_nearer_than_its_return(
        room in [1.0f64..6.0, 1.0f64..6.0],
        legs in prop::collection::vec(leg(), 0..8),
        beams in prop::sample::select(vec![181usize, 361, 721]),
        sigma in 0.002f64..0.03,
        mixed in 0.0f64..1.0,
        stepped in any::<bool>(),
        seed in any::<u64>(),
    ) {
        let step = if stepped { 0.05 } else { 0.0 };
        let ranges = furniture_scan(room, &legs, beams, (sigma, mixed, step), seed);
        let increment = std::f64::consts::PI / (beams - 1) as f64;
        let scan = Scan::from_laser(&LaserScan {
            origin: [0.0, 0.0],
            angle_min: 0.0,
            angle_increment: increment,
            ranges: &ranges,
            range_min: 0.0,
            range_max: 20.0,
        })
        .unwrap();
        let r = reconstruct_scan(&scan, &Params::default()).unwrap();
        let noise = r.stats.range_noise.expect("a scan reports its noise");
        // The evaluation's count (isoline eval's beam_crossings), a rounding inside the
        // bound.
        let margin = 3.0 * noise + 2.0 * r.stats.hmin;
        let crossings = isoline_sim::beam_crossings(&r.polylines, &scan, margin * (1.0 + 1e-9));
        prop_assert_eq!(crossings, 0, "curves cross beams past the bound {}", margin);
    }
}
