use super::*;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

/// A sensor at the origin looking along +x over 180 degrees in `n` beams, with ranges
/// from `range` (bearing -> range; `None`: no return).
fn scan(n: usize, mut range: impl FnMut(f64) -> Option<f64>) -> Scan {
    let inc = std::f64::consts::PI / (n - 1) as f64;
    let a0 = -std::f64::consts::FRAC_PI_2;
    let ranges: Vec<Option<f64>> = (0..n).map(|i| range(a0 + i as f64 * inc)).collect();
    Scan::from_laser(&LaserScan {
        origin: [0.0, 0.0],
        angle_min: a0,
        angle_increment: inc,
        ranges: &ranges,
        range_min: 0.05,
        range_max: 20.0,
    })
    .unwrap()
}

/// A wall at x = 2 in front, and a box 1 m deep behind a doorway in it (|y| < 0.4).
fn wall_with_doorway(bearing: f64) -> Option<f64> {
    let (s, c) = bearing.sin_cos();
    if c <= 1e-9 {
        return None;
    }
    let at_wall = 2.0 / c;
    if (at_wall * s).abs() < 0.4 {
        Some(3.0 / c)
    } else {
        Some(at_wall).filter(|&r| r < 20.0)
    }
}

#[test]
fn runs_break_at_depth_jumps_and_bridge_dropouts() {
    let s = scan(721, wall_with_doorway);
    let p = ScanParams::default();
    let runs = s.runs(0.01, &p);
    // Wall left of the doorway, the far wall seen through it, the wall to its right.
    let big: Vec<&Run> = runs.iter().filter(|r| r.beams.len() > 20).collect();
    assert_eq!(
        big.len(),
        3,
        "{:?}",
        runs.iter().map(|r| r.beams.len()).collect::<Vec<_>>()
    );
    // Two missing beams inside the far wall are a dropout; three are a gap.
    let drop = |k: usize| {
        let mut t = s.clone();
        let mid = 360;
        for i in mid..mid + k {
            t.ranges[i] = f64::NAN;
        }
        t.runs(0.01, &p)
            .iter()
            .filter(|r| r.beams.len() > 20)
            .count()
    };
    assert_eq!(drop(2), 3);
    assert_eq!(drop(3), 4);
}

#[test]
fn the_noise_estimate_recovers_the_range_noise() {
    let sigma = 0.01;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
    let noise = Normal::new(0.0, sigma).unwrap();
    let s = scan(1081, |a| {
        wall_with_doorway(a).map(|r| r + noise.sample(&mut rng))
    });
    let p = ScanParams::default();
    let runs = s.runs(sigma, &p);
    let scales = s.scales(&runs, &p);
    // About 900 offsets: the median's relative standard error is 1.25 / sqrt(900) = 4%;
    // the chord's own curvature error is nil on straight walls. 15% is 3.5 errors.
    let est = scales.noise_estimate.unwrap();
    assert!((est - sigma).abs() < 0.15 * sigma, "{est}");
    // A configured noise wins.
    let q = ScanParams {
        range_noise: Some(0.03),
        ..p
    };
    assert_eq!(s.scales(&runs, &q).noise, 0.03);
    // Spacing: the median range times the step.
    assert!(scales.spacing > 2.0 * s.step && scales.spacing < 4.0 * s.step);
}

/// Ranges rounded to 5 cm with noise far below that: a flat wall's returns round to the
/// same few values and lie on their neighbours' chords, which see no noise, but each is
/// off by up to 2.5 cm. The estimate is the rounding's deviation, `0.05 / sqrt 12`; and
/// with the noise above the step, the chords' own estimate stands.
#[test]
fn rounded_ranges_are_as_noisy_as_their_rounding() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
    let noise = Normal::new(0.0, 0.002).unwrap();
    let s = scan(1081, |a| {
        wall_with_doorway(a).map(|r| ((r + noise.sample(&mut rng)) / 0.05).round() * 0.05)
    });
    let p = ScanParams::default();
    let runs = s.runs(0.01, &p);
    let est = s.scales(&runs, &p).noise_estimate.unwrap();
    assert!((est - 0.05 / 12f64.sqrt()).abs() < 1e-9, "{est}");
    // As in the_noise_estimate_recovers_the_range_noise, within 15%.
    let noise = Normal::new(0.0, 0.01).unwrap();
    let s = scan(1081, |a| {
        wall_with_doorway(a).map(|r| ((r + noise.sample(&mut rng)) / 0.001).round() * 0.001)
    });
    let runs = s.runs(0.01, &p);
    let est = s.scales(&runs, &p).noise_estimate.unwrap();
    assert!((est - 0.01).abs() < 0.15 * 0.01, "{est}");
}

#[test]
fn free_space_is_in_front_of_the_returns_and_along_free_rays() {
    // A wall at x = 2 except for a gap of beams with no return around y = 0.
    let s = scan(361, |a| {
        let r = 2.0 / a.cos();
        ((r * a.sin()).abs() > 0.3 && r < 20.0).then_some(r)
    });
    let p = ScanParams::default();
    let runs = s.runs(0.01, &p);
    let free = s.free_space(&runs, 2, &s.ranges);
    assert!(free.contains([1.0, 1.0]), "in front of the wall");
    assert!(!free.contains([2.5, 1.0]), "behind the wall");
    assert!(
        free.contains([10.0, 0.0]),
        "along the rays without a return"
    );
    assert!(!free.contains([-1.0, 0.0]), "outside the field of view");
    assert!(!free.contains([25.0, 0.0]), "beyond the maximum range");
    // The same scan as points seen from the origin: no free rays, the gap is unseen.
    let pts = s.returns();
    let from_points = Scan::from_points(&pts, [0.0, 0.0]);
    let runs = from_points.runs(0.01, &p);
    let free = from_points.free_space(&runs, 2, &s.ranges);
    assert!(free.contains([1.0, 1.0]));
    assert!(!free.contains([10.0, 0.0]));
    // The polygon bounds the same region: a point in it is near no boundary edge it
    // crosses, and it is closed and counter-clockwise.
    let poly = s.free_space(&s.runs(0.01, &p), 2, &s.ranges).polygon();
    assert!(poly.closed && poly.signed_area() > 0.0);
}

#[test]
fn a_full_turn_wraps_round_and_a_closed_room_closes() {
    // A square room 4 x 4 around a sensor at its centre, seen over 360 beams.
    let n = 360;
    let inc = std::f64::consts::TAU / n as f64;
    let ranges: Vec<Option<f64>> = (0..n)
        .map(|i| {
            let a = -std::f64::consts::PI + i as f64 * inc;
            let (s, c) = a.sin_cos();
            Some(2.0 / c.abs().max(s.abs()))
        })
        .collect();
    let s = Scan::from_laser(&LaserScan {
        origin: [0.0, 0.0],
        angle_min: -std::f64::consts::PI,
        angle_increment: inc,
        ranges: &ranges,
        range_min: 0.1,
        range_max: 12.0,
    })
    .unwrap();
    assert!(s.full_turn());
    let a = Analysis::new(s, &ScanParams::default());
    assert_eq!(a.runs.len(), 1);
    assert_eq!(a.support.len(), 1);
    assert!(a.support[0].closed);
    assert!(a.free.contains([1.9, 0.0]) && a.free.contains([-1.9, -1.9]));
    assert!(!a.free.contains([2.1, 0.0]));
}

/// The boundary's distances by bearing equal the polygon's segment index everywhere:
/// near the returns, far from them, near the sensor, behind it, past the field of
/// view's edges, across dropouts and depth jumps, for a half turn, a full turn and a
/// scan made from points (free rays off), noisy, with and without a limit.
#[test]
fn boundary_distances_by_bearing_are_exact() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let noise = Normal::new(0.0, 0.01).unwrap();
    let mut uniform = {
        let mut r = rand_chacha::ChaCha8Rng::seed_from_u64(6);
        move || rand::Rng::random::<f64>(&mut r)
    };
    let half = scan(361, |a| {
        wall_with_doorway(a).filter(|_| (a * 40.0).sin() < 0.9)
    });
    let n = 720;
    let inc = std::f64::consts::TAU / n as f64;
    let ranges: Vec<Option<f64>> = (0..n)
        .map(|i| {
            let a = i as f64 * inc;
            let r = 2.0 / a.cos().abs().max(a.sin().abs());
            (i % 97 > 3).then_some(r + noise.sample(&mut rng))
        })
        .collect();
    let full = Scan::from_laser(&LaserScan {
        origin: [0.3, -0.2],
        angle_min: 0.0,
        angle_increment: inc,
        ranges: &ranges,
        range_min: 0.05,
        range_max: 20.0,
    })
    .unwrap();
    let from_points = Scan::from_points(&half.returns(), [0.0, 0.0]);
    let p = ScanParams::default();
    let mut checked = 0;
    let mut by_bearing = 0;
    for s in [&half, &full, &from_points] {
        let runs = s.runs(0.01, &p);
        let free = s.free_space(&runs, 2, &s.ranges);
        let index = crate::index::SegmentIndex::new(&[free.polygon()]);
        let boundary = free.boundary();
        for k in 0..4000 {
            // Half the points within 0.3 m of a return, the rest anywhere within 6 m.
            let q = if k % 2 == 0 {
                let r = s.returns();
                let c = r[(uniform() * r.len() as f64) as usize];
                [c[0] + 0.6 * uniform() - 0.3, c[1] + 0.6 * uniform() - 0.3]
            } else {
                [12.0 * uniform() - 6.0, 12.0 * uniform() - 6.0]
            };
            let exact = index.distance(q);
            for limit in [f64::INFINITY, 0.05] {
                let d = boundary.distance_within(q, limit);
                by_bearing += usize::from(
                    free.bearing(q)
                        .and_then(|b| boundary.local(q, &b, limit))
                        .is_some(),
                );
                let signed = boundary.signed_within(q, limit);
                assert_eq!(signed < 0.0, free.contains(q), "{q:?}: {signed}");
                assert!(
                    (d - exact.min(limit)).abs() <= 1e-12,
                    "{q:?}: {d} against {exact} (limit {limit})"
                );
                checked += 1;
            }
        }
    }
    assert_eq!(checked, 3 * 4000 * 2);
    // Most answers came from the beams round the bearing, not the index.
    assert!(by_bearing * 2 > checked, "{by_bearing} of {checked}");
}

/// A corner 2 m in front: the wall x = 2 below y = 0.5, the wall y = 0.5 beyond it.
fn corner(bearing: f64) -> Option<f64> {
    let (s, c) = bearing.sin_cos();
    let to_wall = (c > 1e-9).then(|| 2.0 / c);
    let to_side = (s > 1e-9).then(|| 0.5 / s);
    match (to_wall, to_side) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    }
    .filter(|&r| r < 20.0)
}

/// The distance from `p` to the corner's two walls (as far as the scan sees them).
fn off_corner(p: Point) -> f64 {
    let to_wall = if p[1] <= 0.5 {
        (p[0] - 2.0).abs()
    } else {
        crate::geom::dist(p, [2.0, 0.5])
    };
    let to_side = if p[0] <= 2.0 {
        (p[1] - 0.5).abs()
    } else {
        crate::geom::dist(p, [2.0, 0.5])
    };
    to_wall.min(to_side)
}

/// Smoothing along a run keeps a corner: a window of returns round the corner fits
/// neither wall, and the returns near it are smoothed along the wall they are on
/// (one-sided windows), so noise-free returns stay exactly where they are; the window
/// round them would have moved the ones beside the corner up to 3 sigma into it. With
/// 1 cm of noise no smoothed return near the corner is farther from the walls than
/// the noise's 3 sigma.
#[test]
fn smoothing_keeps_corners() {
    let clean = scan(361, corner);
    let runs = clean.runs(0.01, &ScanParams::default());
    let smooth = clean.smoothed_ranges(&runs, 4, 0.01);
    for (i, (&r, &s)) in clean.ranges.iter().zip(&smooth).enumerate() {
        if r.is_finite() {
            assert!((r - s).abs() < 1e-9, "beam {i}: {r} smoothed to {s}");
        }
    }
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let noise = Normal::new(0.0, 0.01).unwrap();
    let noisy = scan(361, |b| corner(b).map(|r| r + noise.sample(&mut rng)));
    let runs = noisy.runs(0.01, &ScanParams::default());
    let smooth = noisy.smoothed_ranges(&runs, 4, 0.01);
    let worst = (0..noisy.ranges.len())
        .filter(|&i| smooth[i].is_finite())
        .map(|i| noisy.at(i, smooth[i]))
        .filter(|&p| crate::geom::dist(p, [2.0, 0.5]) < 0.3)
        .map(off_corner)
        .fold(0.0, f64::max);
    assert!(
        worst <= 0.03,
        "a smoothed return {worst} m off the corner's walls"
    );
}

/// The depth along a point's bearing is where the ray through it leaves the free
/// space (the segment joining the reaches of the beams round it) less its range; on
/// the last beam it is that beam's reach less the range, and past it there is none.
#[test]
fn depth_is_measured_along_the_bearing() {
    let free = FreeSpace {
        origin: [0.0, 0.0],
        angles: vec![0.0, std::f64::consts::FRAC_PI_2],
        reach: vec![1.0, 1.0],
        full_turn: false,
        max_gap: f64::INFINITY,
    };
    let d = free.depth([0.2, 0.2]).unwrap();
    assert!((d - (0.5f64.sqrt() - 0.08f64.sqrt())).abs() < 1e-12, "{d}");
    let behind = free.depth([0.6, 0.6]).unwrap();
    assert!(
        (behind - (0.5f64.sqrt() - 0.72f64.sqrt())).abs() < 1e-12,
        "{behind}"
    );
    let on_last = free.depth([0.0, 0.25]).unwrap();
    assert!((on_last - 0.75).abs() < 1e-12, "{on_last}");
    assert_eq!(free.depth([-0.1, 0.5]), None);
    assert_eq!(free.depth([0.0, 0.0]), None);
}
