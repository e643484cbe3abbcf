//! Point-to-line registration of a scan onto a [`Surface`]: Gauss-Newton on the
//! distances of the scan's returns to the lines of their nearest targets (Chen &
//! Medioni 1992; Censi's PL-ICP for 2D scans, 2008), robust, with a prior on the pose.
//!
//! - **Robust residuals.** Each residual weighs by the Geman-McClure kernel
//!   `1 / (1 + (r/k)^2)^2`, whose scale `k` starts at a fifth of the correspondence reach
//!   (a start off by that much still pulls the right way) and shrinks each round to
//!   `1.4826` times the residuals' median absolute value (their standard deviation where
//!   most returns match), never below the measurement noise. A return on something the
//!   target does not hold (a person, a door since opened) then stops pulling, as in
//!   KISS-ICP's adaptive threshold (Vizzo et al. 2023).
//! - **Rounds.** A round pairs every return with its nearest target (a kd-tree query
//!   each, the cost) and, once the kernel has stopped narrowing, minimises over those
//!   pairs until the pose settles; before, it takes one step, as a coarse start's pairs
//!   may be wrong ones. A single step per query round creeps along a wall a few
//!   millimetres a round: this takes 13 rounds on average where that took 18, and lays
//!   a scan onto a map in half the time (`cargo bench -p isoline-bench --bench
//!   mapping`).
//! - **The prior.** The predicted pose (the odometry's motion since the previous scan)
//!   enters as a Gaussian: its information is added to the normal equations, so that
//!   where the returns constrain nothing (a featureless corridor along its axis) the
//!   prior decides, and the covariance `(H_scan / s^2 + prior)^-1` says so.
//! - **Degeneracy.** A direction is unobservable by the scan when the scan's
//!   information along it is below the prior's: the generalised eigenvalues of the
//!   scan's information against the prior's are compared with 1. No threshold to tune:
//!   it asks which of the two decides.

use isoline_core::{Point, Pose};
use nalgebra::{Matrix3, SymmetricEigen, Vector3};

use crate::se2::{diff, wrap, Cov3};
use crate::submap::Surface;

/// A Gaussian prior on the pose: its mean and information (inverse covariance), both
/// in the world frame.
#[derive(Clone, Copy, Debug)]
pub struct Prior {
    /// The predicted pose.
    pub mean: Pose,
    /// Its information matrix.
    pub info: Matrix3<f64>,
}

/// What a registration found.
#[derive(Clone, Copy, Debug)]
pub struct Match {
    /// The pose that lays the scan on the target.
    pub pose: Pose,
    /// Its covariance (scan and prior together).
    pub cov: Cov3,
    /// The scan's information alone (`H / s^2`).
    pub info: Matrix3<f64>,
    /// Returns with a target within reach at the end.
    pub paired: usize,
    /// Returns within three noise widths of their target's line at the end.
    pub inliers: usize,
    /// Returns offered.
    pub offered: usize,
    /// The residuals' robust standard deviation at the end, metres.
    pub spread: f64,
    /// Whether some direction is decided by the prior rather than the scan.
    pub degenerate: bool,
}

impl Match {
    /// The share of the returns offered that lie on the target.
    pub fn inlier_share(&self) -> f64 {
        self.inliers as f64 / self.offered.max(1) as f64
    }
}

/// Correspondence rounds at most: from within the reach most runs take 5-20 (on the
/// CARMEN logs, 13 on average; up to one in twenty stops here, its pairs trading places
/// between neighbouring targets by a millimetre).
const STEPS: usize = 30;

/// Gauss-Newton steps a round on the round's fixed pairs, at most: on fixed pairs the
/// problem is a weighted least squares whose weights move only with the residuals, and
/// it settles in about three.
const INNER_STEPS: usize = 8;

/// Registers `points` (in the scan's frame) onto `target` (world), starting at
/// `start`: the pose minimising the robust point-to-line distances plus the prior's
/// term. `weight` is the share of an independent measurement each point is (1 for
/// returns; below 1 for points sampled along curves more densely than the returns they
/// were drawn from, which hold no more of the walls than those returns). `noise` is the
/// measurement noise (the returns' and the target's together), `reach` the farthest a
/// return's target may lie at the start.
///
/// Each round pairs every return with its nearest target and then minimises over
/// those pairs until the pose settles (Censi's PL-ICP: the pairs are the expensive
/// part, a kd-tree query each, and one Gauss-Newton step per query round creeps
/// along a wall a few millimetres a round).
pub fn register(
    points: &[Point],
    weight: f64,
    target: &Surface,
    start: Pose,
    prior: Option<&Prior>,
    noise: f64,
    reach: f64,
) -> Match {
    let noise = noise.max(1e-4);
    let mut pose = start;
    let mut k = (reach / 5.0).max(noise);
    let mut residuals: Vec<f64> = Vec::with_capacity(points.len());
    // Each pair: the return in the scan's frame, its target and the target's normal.
    let mut pairs: Vec<(Point, Point, Point)> = Vec::with_capacity(points.len());
    // A step that moves no return by more than a hundredth of the noise: the rest is far
    // below what the returns can tell.
    let tiny = 0.01 * noise;
    let far = points
        .iter()
        .map(|p| p[0].hypot(p[1]))
        .fold(0.0f64, f64::max)
        .max(1.0);
    let moved = |a: Pose, b: Pose| (a[0] - b[0]).hypot(a[1] - b[1]) + far * wrap(a[2] - b[2]).abs();
    // Whether the kernel's scale stopped narrowing in the last round: before, the pairs
    // are those of a coarse start and the rounds take one step each, as the pairs they
    // would settle on may be wrong ones.
    let mut settled = false;
    for _ in 0..STEPS {
        let gate = (5.0 * k).min(reach);
        pairs.clear();
        pair(points, target, pose, gate, &mut pairs);
        if pairs.len() < 3 && prior.is_none() {
            break;
        }
        let round_start = pose;
        for _ in 0..if settled { INNER_STEPS } else { 1 } {
            let (mut h, mut g) = (Matrix3::zeros(), Vector3::zeros());
            for (j, r, w) in terms(&pairs, pose, k) {
                h += w * j * j.transpose();
                g += w * r * j;
            }
            // Weighted by the kernel's scale (the residuals are in units of k^2) and by
            // the points' share of a measurement.
            let (mut h, mut g) = (weight * h / (k * k), weight * g / (k * k));
            if let Some(p) = prior {
                h += p.info;
                g += p.info * diff(pose, p.mean);
            }
            let Some(step) = solve(&h, &g) else { break };
            pose = [
                pose[0] + step[0],
                pose[1] + step[1],
                wrap(pose[2] + step[2]),
            ];
            if step.xy().norm() + far * step[2].abs() < tiny {
                break;
            }
        }
        let before = k;
        if !pairs.is_empty() {
            residuals.clear();
            residuals.extend(terms(&pairs, pose, k).map(|(_, r, _)| r.abs()));
            let median = median(&mut residuals);
            k = (1.4826 * median).clamp(noise, k);
        }
        // Converged once a round no longer moves the pose and the kernel has stopped
        // narrowing: a pose that stands still under a kernel still shrinking would move
        // under the next.
        settled = before - k < tiny;
        if moved(pose, round_start) < tiny && settled {
            break;
        }
    }
    pairs.clear();
    let k = k.min(reach);
    pair(points, target, pose, 5.0 * k, &mut pairs);
    finish(&pairs, points.len(), weight, pose, prior, noise, k)
}

/// Pairs every return with its nearest target within `gate` at `pose`.
fn pair(
    points: &[Point],
    target: &Surface,
    pose: Pose,
    gate: f64,
    pairs: &mut Vec<(Point, Point, Point)>,
) {
    let (s, c) = pose[2].sin_cos();
    pairs.extend(points.iter().filter_map(|&p| {
        let q = [pose[0] + c * p[0] - s * p[1], pose[1] + s * p[0] + c * p[1]];
        let (m, n) = target.nearest(q, gate)?;
        Some((p, m, n))
    }));
}

/// Each pair's Jacobian, point-to-line residual and robust weight (kernel scale `k`)
/// at `pose`.
fn terms(
    pairs: &[(Point, Point, Point)],
    pose: Pose,
    k: f64,
) -> impl Iterator<Item = (Vector3<f64>, f64, f64)> + '_ {
    let (s, c) = pose[2].sin_cos();
    pairs.iter().map(move |&(p, m, n)| {
        let d = [c * p[0] - s * p[1], s * p[0] + c * p[1]];
        let r = n[0] * (pose[0] + d[0] - m[0]) + n[1] * (pose[1] + d[1] - m[1]);
        let u = r / k;
        let w = 1.0 / (1.0 + u * u).powi(2);
        // d q / d theta = the rotated point turned a quarter.
        (Vector3::new(n[0], n[1], n[0] * -d[1] + n[1] * d[0]), r, w)
    })
}

/// The match at `pose` from its `pairs` (of `offered` returns): pairs, inliers, the
/// scan's information and the covariance.
fn finish(
    pairs: &[(Point, Point, Point)],
    offered: usize,
    weight: f64,
    pose: Pose,
    prior: Option<&Prior>,
    noise: f64,
    k: f64,
) -> Match {
    let (mut h, mut inliers) = (Matrix3::zeros(), 0usize);
    let (mut wsum, mut wr2) = (0.0, 0.0);
    for (j, r, w) in terms(pairs, pose, k) {
        h += w * j * j.transpose();
        wsum += w;
        wr2 += w * r * r;
        if r.abs() <= 3.0 * noise {
            inliers += 1;
        }
    }
    // The residuals' variance as they scatter, never below the noise's.
    let s2 = if wsum > 0.0 {
        (wr2 / wsum).max(noise * noise)
    } else {
        noise * noise
    };
    let info = weight * h / s2;
    let prior_info = prior.map_or(Matrix3::zeros(), |p| p.info);
    let total = info + prior_info;
    let cov = total
        .try_inverse()
        .unwrap_or_else(|| Matrix3::from_diagonal_element(f64::INFINITY));
    Match {
        pose,
        cov,
        info,
        paired: pairs.len(),
        inliers,
        offered,
        spread: s2.sqrt(),
        degenerate: degenerate(&info, &prior_info),
    }
}

/// The Gauss-Newton step `-H^-1 g`, where `H` is invertible.
fn solve(h: &Matrix3<f64>, g: &Vector3<f64>) -> Option<Vector3<f64>> {
    let step = h.cholesky()?.solve(g);
    step.iter().all(|v| v.is_finite()).then_some(-step)
}

/// Whether the scan's information `info` falls below the prior's `prior` along some
/// direction: the smallest generalised eigenvalue of `(info, prior)` is below 1. With
/// no prior, whether `info` is singular against its own largest eigenvalue (to
/// rounding: no scan pins a direction it does not see).
pub(crate) fn degenerate(info: &Matrix3<f64>, prior: &Matrix3<f64>) -> bool {
    match prior.cholesky() {
        Some(l) => {
            // L^-1 info L^-T has the generalised eigenvalues.
            let linv = l.l().try_inverse().unwrap_or_else(Matrix3::zeros);
            let m = linv * info * linv.transpose();
            let e = SymmetricEigen::new((m + m.transpose()) * 0.5);
            e.eigenvalues.min() < 1.0
        }
        None => {
            let e = SymmetricEigen::new(*info);
            e.eigenvalues.min() <= 1e-9 * e.eigenvalues.max().max(0.0)
        }
    }
}

fn median(v: &mut [f64]) -> f64 {
    let mid = v.len() / 2;
    *v.select_nth_unstable_by(mid, f64::total_cmp).1
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::se2::diag;

    /// A room 6 x 4 m sampled every 2 cm, as world points.
    fn room() -> Vec<Point> {
        let mut pts = Vec::new();
        for i in 0..=300 {
            let x = -3.0 + i as f64 * 0.02;
            pts.push([x, -2.0]);
            pts.push([x, 2.0]);
        }
        for i in 0..=200 {
            let y = -2.0 + i as f64 * 0.02;
            pts.push([-3.0, y]);
            pts.push([3.0, y]);
        }
        pts
    }

    /// `world` seen from `pose`.
    fn seen_from(world: &[Point], pose: Pose) -> Vec<Point> {
        world
            .iter()
            .map(|&p| isoline_core::geom::to_sensor(pose, p))
            .collect()
    }

    #[test]
    fn a_scan_returns_to_the_pose_it_was_taken_from() {
        let target = Surface::new(&room(), 0.1);
        let truth = [0.3, -0.2, 0.05];
        let scan = seen_from(&room(), truth);
        // Started 20 cm and 3 degrees off: well within the reach.
        let m = register(&scan, 1.0, &target, [0.45, -0.05, 0.0], None, 0.005, 0.5);
        let e = diff(m.pose, truth);
        assert!(e.xy().norm() < 1e-4 && e[2].abs() < 1e-4, "{:?}", m.pose);
        assert!(m.inlier_share() > 0.95 && !m.degenerate, "{m:?}");
    }

    #[test]
    fn along_a_corridor_the_prior_decides_and_the_covariance_says_so() {
        // Two parallel walls: nothing fixes x.
        let mut world = Vec::new();
        for i in 0..=500 {
            let x = -5.0 + i as f64 * 0.02;
            world.push([x, -1.0]);
            world.push([x, 1.0]);
        }
        let target = Surface::new(&world, 0.1);
        let truth = [0.0, 0.1, 0.02];
        let scan: Vec<Point> = seen_from(&world, truth)
            .into_iter()
            .filter(|p| p[0].abs() < 3.0)
            .collect();
        // The prior puts x at 0.3 with 10 cm of uncertainty, y and theta loosely.
        let prior = Prior {
            mean: [0.3, 0.0, 0.0],
            info: diag(0.1, 1.0, 1.0).try_inverse().unwrap(),
        };
        let m = register(&scan, 1.0, &target, prior.mean, Some(&prior), 0.005, 0.5);
        assert!(m.degenerate);
        // y and theta come from the walls, x stays the prior's.
        assert!(
            (m.pose[1] - 0.1).abs() < 1e-3 && (m.pose[2] - 0.02).abs() < 1e-3,
            "{m:?}"
        );
        assert!((m.pose[0] - 0.3).abs() < 1e-3, "{m:?}");
        // The covariance keeps the prior's 10 cm along the corridor, millimetres across.
        assert!((m.cov[(0, 0)].sqrt() - 0.1).abs() < 0.01, "{}", m.cov);
        assert!(m.cov[(1, 1)].sqrt() < 0.005, "{}", m.cov);
    }

    #[test]
    fn a_points_weight_scales_its_information_not_the_pose() {
        // Without a prior the weight scales the whole objective: the same minimum, its
        // information the weight's share (to rounding).
        let target = Surface::new(&room(), 0.1);
        let scan = seen_from(&room(), [0.3, -0.2, 0.05]);
        let one = register(&scan, 1.0, &target, [0.4, -0.1, 0.0], None, 0.005, 0.5);
        let fifth = register(&scan, 0.2, &target, [0.4, -0.1, 0.0], None, 0.005, 0.5);
        assert!(
            diff(one.pose, fifth.pose).norm() < 1e-9,
            "{one:?} {fifth:?}"
        );
        assert!((fifth.info - 0.2 * one.info).norm() < 1e-9 * one.info.norm());
        // With the odometry's prior, a lighter scan leaves the pose nearer the prior.
        let prior = Prior {
            mean: [0.3, -0.2 + 0.02, 0.05],
            info: diag(0.01, 0.01, 0.01).try_inverse().unwrap(),
        };
        let heavy = register(&scan, 1.0, &target, prior.mean, Some(&prior), 0.005, 0.5);
        let light = register(&scan, 0.01, &target, prior.mean, Some(&prior), 0.005, 0.5);
        assert!(
            diff(light.pose, prior.mean).norm() < diff(heavy.pose, prior.mean).norm(),
            "{heavy:?} {light:?}"
        );
    }

    #[test]
    fn returns_on_something_new_stop_pulling() {
        let target = Surface::new(&room(), 0.1);
        let truth = [0.0, 0.0, 0.0];
        let mut scan = seen_from(&room(), truth);
        // A third as many returns again on a box the map does not hold, 30 cm off a wall.
        scan.extend((0..300).map(|i| [-1.0 + i as f64 * 0.005, 1.7]));
        let m = register(&scan, 1.0, &target, [0.05, 0.05, 0.01], None, 0.005, 0.5);
        let e = diff(m.pose, truth);
        assert!(e.xy().norm() < 2e-3 && e[2].abs() < 1e-3, "{:?}", m.pose);
    }
}
