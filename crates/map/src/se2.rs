//! Rigid motions of the plane as poses `[x, y, theta]`: composition, inverse, the
//! relative pose of two poses, and covariances carried between frames.

use isoline_core::Pose;
use nalgebra::{Matrix3, Vector3};

/// A 3x3 covariance (or information) of a pose, in the order `x, y, theta`.
pub type Cov3 = Matrix3<f64>;

pub use isoline_core::geom::wrap;

/// `a` then `b`: the pose `b` (given in the frame at `a`) in `a`'s frame's parent.
pub fn compose(a: Pose, b: Pose) -> Pose {
    let (s, c) = a[2].sin_cos();
    [
        a[0] + c * b[0] - s * b[1],
        a[1] + s * b[0] + c * b[1],
        wrap(a[2] + b[2]),
    ]
}

/// The pose that undoes `a`.
pub fn inverse(a: Pose) -> Pose {
    let (s, c) = a[2].sin_cos();
    [-c * a[0] - s * a[1], s * a[0] - c * a[1], wrap(-a[2])]
}

/// `b` seen from `a`: `compose(a, between(a, b)) == b`.
pub fn between(a: Pose, b: Pose) -> Pose {
    compose(inverse(a), b)
}

/// The rotation of a covariance given in the frame at heading `theta` into the
/// parent frame (its translation block turns, the heading's variance stays).
pub fn rotate_cov(cov: &Cov3, theta: f64) -> Cov3 {
    let (s, c) = theta.sin_cos();
    let r = Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0);
    r * cov * r.transpose()
}

/// The covariance of `compose(a, b)` from those of `a` (parent frame) and `b` (in
/// `a`'s frame), independent, to first order.
pub fn compose_cov(a: Pose, cov_a: &Cov3, b: Pose, cov_b: &Cov3) -> Cov3 {
    let (s, c) = a[2].sin_cos();
    // d compose / d a: the translation of b swings with a's heading.
    let ja = Matrix3::new(
        1.0,
        0.0,
        -s * b[0] - c * b[1],
        0.0,
        1.0,
        c * b[0] - s * b[1],
        0.0,
        0.0,
        1.0,
    );
    ja * cov_a * ja.transpose() + rotate_cov(cov_b, a[2])
}

/// The covariance of `inverse(z)` (in the frame at `z`) from that of `z` (in its
/// parent frame), to first order.
pub fn inverse_cov(z: Pose, cov: &Cov3) -> Cov3 {
    let (s, c) = z[2].sin_cos();
    // inverse(z) = (-R^T t, -theta): d/dt = -R^T, d/dtheta = -(dR^T/dtheta) t.
    let j = Matrix3::new(
        -c,
        -s,
        s * z[0] - c * z[1],
        s,
        -c,
        c * z[0] + s * z[1],
        0.0,
        0.0,
        -1.0,
    );
    j * cov * j.transpose()
}

/// The difference `a - b` of two poses, the heading wrapped.
pub fn diff(a: Pose, b: Pose) -> Vector3<f64> {
    Vector3::new(a[0] - b[0], a[1] - b[1], wrap(a[2] - b[2]))
}

/// A diagonal covariance from standard deviations.
pub fn diag(sx: f64, sy: f64, st: f64) -> Cov3 {
    Matrix3::from_diagonal(&Vector3::new(sx * sx, sy * sy, st * st))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: Pose, b: Pose) -> bool {
        (a[0] - b[0]).abs() < 1e-12
            && (a[1] - b[1]).abs() < 1e-12
            && wrap(a[2] - b[2]).abs() < 1e-12
    }

    #[test]
    fn between_undoes_compose() {
        let a = [1.0, -2.0, 2.9];
        let b = [-0.3, 0.7, 0.8];
        assert!(close(compose(a, between(a, b)), b));
        assert!(close(compose(a, inverse(a)), [0.0, 0.0, 0.0]));
        assert!(close(between(a, compose(a, b)), b));
    }

    #[test]
    fn a_turn_swings_the_translations_variance() {
        // A heading known to 0.1 rad swings a point 10 m ahead by about 1 m across.
        let a = [0.0, 0.0, 0.0];
        let cov = compose_cov(a, &diag(0.0, 0.0, 0.1), [10.0, 0.0, 0.0], &Cov3::zeros());
        assert!((cov[(1, 1)] - 1.0).abs() < 1e-12, "{cov}");
        assert_eq!(cov[(0, 0)], 0.0);
    }

    #[test]
    fn the_inverse_covariance_matches_a_finite_difference() {
        let z = [1.3, -0.4, 0.7];
        let h = 1e-6;
        for k in 0..3 {
            let mut dz = z;
            dz[k] += h;
            let (a, b) = (inverse(dz), inverse(z));
            let col = diff(a, b) / h;
            // A unit variance along k alone: the covariance is that column's outer
            // product.
            let mut unit = Cov3::zeros();
            unit[(k, k)] = 1.0;
            let cov = inverse_cov(z, &unit);
            let want = col * col.transpose();
            assert!((cov - want).abs().max() < 1e-5, "{k}: {cov} {want}");
        }
    }

    #[test]
    fn headings_wrap_into_one_turn() {
        assert!((wrap(3.0 * std::f64::consts::PI) - std::f64::consts::PI).abs() < 1e-12);
        assert!((wrap(-0.1) + 0.1).abs() < 1e-15);
    }
}
