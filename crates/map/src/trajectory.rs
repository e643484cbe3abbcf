//! Trajectories: the TUM format (`t x y z qx qy qz qw` a line, which evo and most SLAM
//! tools read), and the scores of an estimate against a reference: the absolute
//! trajectory error after the best rigid alignment (Sturm et al. 2012) and the relative
//! pose error over a length of path (Geiger et al. 2012's KITTI measure, as evo's
//! `rpe --delta D --delta_unit m` computes it).

use isoline_core::Pose;

use crate::se2::{between, wrap};

/// One line of a TUM trajectory for a pose at time `t` (z = 0, the heading as a
/// quaternion about z).
pub fn tum_line(t: f64, pose: Pose) -> String {
    let (s, c) = (0.5 * pose[2]).sin_cos();
    format!("{t:.6} {:.6} {:.6} 0 0 0 {s:.9} {c:.9}", pose[0], pose[1])
}

/// A TUM line's time and planar pose; `None` for a comment, a blank or a malformed
/// line.
pub fn parse_tum_line(line: &str) -> Option<(f64, Pose)> {
    let line = line.trim();
    if line.is_empty() || line.starts_with('#') {
        return None;
    }
    let v: Vec<f64> = line
        .split_whitespace()
        .map(|w| w.parse().ok())
        .collect::<Option<_>>()?;
    if v.len() != 8 || !v.iter().all(|x| x.is_finite()) {
        return None;
    }
    // The heading of the quaternion's rotation about z (x and y parts ignored: planar).
    let theta = 2.0 * v[6].atan2(v[7]);
    Some((v[0], [v[1], v[2], wrap(theta)]))
}

/// The scores of an estimate against a reference, pose for pose.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct Errors {
    /// Poses compared.
    pub poses: usize,
    /// Path length of the reference, metres.
    pub length: f64,
    /// Absolute trajectory error after the best rigid alignment: RMS of the positions'
    /// distances, metres.
    pub ate: f64,
    /// The same, the headings' RMS, radians.
    pub ate_heading: f64,
}

/// The relative pose error over a length of path: RMS of the translation and heading
/// errors of the motion between each pose and the first one at least `delta` metres
/// further along the reference.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct Relative {
    /// The path length, metres.
    pub delta: f64,
    /// Pairs compared.
    pub pairs: usize,
    /// RMS translation error, metres.
    pub translation: f64,
    /// RMS heading error, radians.
    pub heading: f64,
}

/// The rigid motion `(theta, t)` that best lays `est` on `reference` in the least
/// squares sense (Umeyama 1991 without scale, in the plane).
pub fn align(est: &[Pose], reference: &[Pose]) -> (f64, [f64; 2]) {
    let n = est.len().min(reference.len()).max(1) as f64;
    let mean = |v: &[Pose]| {
        v.iter()
            .fold([0.0, 0.0], |a, p| [a[0] + p[0] / n, a[1] + p[1] / n])
    };
    let (me, mr) = (mean(est), mean(reference));
    let (mut sxx, mut sxy) = (0.0, 0.0);
    for (e, r) in est.iter().zip(reference) {
        let (a, b) = ([e[0] - me[0], e[1] - me[1]], [r[0] - mr[0], r[1] - mr[1]]);
        sxx += a[0] * b[0] + a[1] * b[1];
        sxy += a[0] * b[1] - a[1] * b[0];
    }
    let theta = sxy.atan2(sxx);
    let (s, c) = theta.sin_cos();
    (
        theta,
        [
            mr[0] - (c * me[0] - s * me[1]),
            mr[1] - (s * me[0] + c * me[1]),
        ],
    )
}

/// The absolute trajectory error of `est` against `reference` (pose for pose).
pub fn absolute(est: &[Pose], reference: &[Pose]) -> Errors {
    let n = est.len().min(reference.len());
    let (theta, t) = align(&est[..n], &reference[..n]);
    let (s, c) = theta.sin_cos();
    let (mut e2, mut h2) = (0.0, 0.0);
    for (e, r) in est.iter().zip(reference) {
        let p = [c * e[0] - s * e[1] + t[0], s * e[0] + c * e[1] + t[1]];
        e2 += (p[0] - r[0]).powi(2) + (p[1] - r[1]).powi(2);
        h2 += wrap(e[2] + theta - r[2]).powi(2);
    }
    let length = reference
        .windows(2)
        .map(|w| (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]))
        .sum();
    let m = n.max(1) as f64;
    Errors {
        poses: n,
        length,
        ate: (e2 / m).sqrt(),
        ate_heading: (h2 / m).sqrt(),
    }
}

/// The relative pose error over `delta` metres of the reference's path.
pub fn relative(est: &[Pose], reference: &[Pose], delta: f64) -> Relative {
    let n = est.len().min(reference.len());
    let mut along = vec![0.0; n];
    for k in 1..n {
        along[k] = along[k - 1]
            + (reference[k][0] - reference[k - 1][0]).hypot(reference[k][1] - reference[k - 1][1]);
    }
    let (mut pairs, mut t2, mut h2) = (0usize, 0.0, 0.0);
    let mut j = 0;
    for i in 0..n {
        j = j.max(i);
        while j < n && along[j] - along[i] < delta {
            j += 1;
        }
        if j >= n {
            break;
        }
        let (de, dr) = (between(est[i], est[j]), between(reference[i], reference[j]));
        let err = between(dr, de);
        t2 += err[0] * err[0] + err[1] * err[1];
        h2 += err[2] * err[2];
        pairs += 1;
    }
    let m = pairs.max(1) as f64;
    Relative {
        delta,
        pairs,
        translation: (t2 / m).sqrt(),
        heading: (h2 / m).sqrt(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::se2::compose;

    #[test]
    fn tum_lines_read_back() {
        let line = tum_line(12.5, [1.25, -3.5, 2.9]);
        let (t, p) = parse_tum_line(&line).unwrap();
        assert_eq!(t, 12.5);
        assert!((p[0] - 1.25).abs() < 1e-6 && (p[1] + 3.5).abs() < 1e-6);
        assert!((p[2] - 2.9).abs() < 1e-8);
        assert!(parse_tum_line("# t x y").is_none());
        assert!(parse_tum_line("1 2 3").is_none());
    }

    #[test]
    fn a_moved_copy_has_no_absolute_error_and_a_drift_has_relative() {
        let reference: Vec<Pose> = (0..200)
            .map(|k| {
                let a = k as f64 * 0.05;
                [5.0 * a.cos(), 3.0 * a.sin(), a + 1.5]
            })
            .collect();
        let moved: Vec<Pose> = reference
            .iter()
            .map(|&p| compose([10.0, -4.0, 0.7], p))
            .collect();
        let e = absolute(&moved, &reference);
        assert!(e.ate < 1e-9 && e.ate_heading < 1e-9, "{e:?}");
        assert!(relative(&moved, &reference, 1.0).translation < 1e-9);
        // Every step 1% too long: over 1 m of path the motion is 1 cm off.
        let mut scaled = vec![reference[0]];
        for w in reference.windows(2) {
            let mut s = between(w[0], w[1]);
            s[0] *= 1.01;
            s[1] *= 1.01;
            scaled.push(compose(*scaled.last().unwrap(), s));
        }
        let r = relative(&scaled, &reference, 1.0);
        assert!(r.pairs > 100, "{r:?}");
        // Within a step's length of 1 m (steps are 0.2 m): 1% of 1.0-1.2 m.
        assert!((0.0099..0.0121).contains(&r.translation), "{r:?}");
    }
}
