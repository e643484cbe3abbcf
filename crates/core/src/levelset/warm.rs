//! Warm starts: the previous frame's level set carried onto the new frame's mesh, and the
//! decision whether it is a better start than a cold one.
//!
//! The previous level set was renormalized, so interpolated onto the new mesh it is a
//! signed distance to within the interpolation error. How far its curve is from the new
//! data is measured robustly, by the 90th percentile of `|u|` there (the spread): the
//! maximum (eq. 11) follows the farthest outlier or isolated return, which no curve
//! reaches, and once made every warm start fail, be pushed outward by it and end farther
//! out, frame after frame. Where the spread is within the median settle's reach the level
//! set is used as it is: the capture phase then stagnates within its (warm) patience
//! window and the settle moves the curve the rest of the way, in either direction.
//! Otherwise, while it is no farther from the data than a cold tube start would be (twice
//! the larger of the tube radius and the previous frame's spread), it is offset outward
//! past nine samples in ten, because the evolution only moves the curve inward. Farther
//! (a jump, a restarted stream): cold start. Beyond the previous mesh the level set is
//! extended as a distance ([`carry`]), so a new mesh over data whose extent moved still
//! starts warm. The
//! solve stage then checks the result against the previous frame's and falls back to a
//! cold start when it is clearly worse ([`crate::levelset::evolve::solve`]).

use crate::fem::locate::{gap, locate_all, Location};
use crate::geom::{Placement, Point};
use crate::levelset::solver::spread;
use crate::mesh::Mesh;

/// The level set a frame may start from: the previous frame's mesh, its renormalized
/// level set and how well it fitted its own data.
#[derive(Clone, Copy, Debug)]
pub struct Previous<'a> {
    /// The previous frame's mesh, in data coordinates.
    pub mesh: &'a Mesh,
    /// Its level set, in data units.
    pub u: &'a [f64],
    /// Its spread (90th percentile of `|u|` at its data), in data units.
    pub spread: f64,
    /// The share of its data within the median settle's reach of its curve.
    pub near: f64,
    /// Whether its data enclosed anything (false for a drawing of open strokes):
    /// the box's loop round a drawing of strokes is no start for the next frame.
    pub enclosed: bool,
}

/// What decides between a warm and a cold start.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WarmCriteria {
    /// How far the median settle reaches (`4 sigma + 4 hmin`): a curve this close to
    /// every sample is used as it is.
    pub settle_width: f64,
    /// The tube start's radius: a cold start begins about this far from the data.
    pub tube_radius: f64,
    /// The stopping tolerance of eq. 11.
    pub eps: f64,
    /// Whether the median settle follows the solve (without it, a curve near the data
    /// is offset like any other).
    pub median_settle: bool,
}

/// How the carried level set is used.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Decision {
    /// As it is: the curve is at the data.
    Near,
    /// Offset outward by this distance (`u` minus it), past every sample.
    Offset(f64),
    /// Not at all: start cold.
    Cold,
}

/// The decision for a carried level set whose spread on the new data is `spread`, when
/// the previous frame ended with `previous_spread` on its own data.
pub fn decide(spread: f64, previous_spread: f64, c: &WarmCriteria) -> Decision {
    let near = spread <= c.settle_width && c.median_settle;
    if near {
        return Decision::Near;
    }
    // A cold tube start begins about one tube radius from the data, and the previous
    // frame ended `previous_spread` from its own.
    if spread <= 2.0 * c.tube_radius.max(previous_spread) + c.eps {
        Decision::Offset(spread + c.eps)
    } else {
        Decision::Cold
    }
}

/// The level set `u` of `old` (in data coordinates and units) at each of `coords` (in
/// the local coordinates of `at`), in local units, by walking to each point. Beyond the
/// old mesh (a new mesh made where data whose extent moved need it) the old frame says
/// only that its closed curves lie inside its domain, so the level set is extended as a
/// distance: its value where the walk leaves the domain plus the way out, the most a
/// signed distance can grow over that way (it is 1-Lipschitz). The outside stays
/// outside, and how well the carried curve fits the new data is for the spread to say.
pub fn carry(old: &Mesh, u: &[f64], at: &Placement, coords: &[Point]) -> Vec<f64> {
    let mut old = old.clone();
    for c in &mut old.coords {
        *c = at.to_local(*c);
    }
    let loc = locate_all(&old, coords);
    loc.iter()
        .zip(coords)
        .map(|(l, &p)| at.len_to_local(l.interpolate(&old, u)) + gap(&old, l, p))
        .collect()
}

/// A warm start for the frame meshed by `mesh` (in the local coordinates of `at`; the
/// previous frame is in data coordinates) with samples located at `data`: the carried
/// level set and whether it was near (taken as it is), or `None` for a cold start.
pub fn warm_start(
    prev: Previous<'_>,
    at: &Placement,
    mesh: &Mesh,
    data: &[Location],
    c: &WarmCriteria,
) -> Option<(Vec<f64>, bool)> {
    let mut u = carry(prev.mesh, prev.u, at, &mesh.coords);
    let (spread, _) = spread(mesh, data, &u, c.settle_width);
    let decision = decide(spread, at.len_to_local(prev.spread), c);
    tracing::debug!(spread, ?decision, "warm start");
    match decision {
        Decision::Near => Some((u, true)),
        Decision::Offset(offset) => {
            // u is a distance, so subtracting a constant offsets the curve outward.
            u.iter_mut().for_each(|x| *x -= offset);
            Some((u, false))
        }
        Decision::Cold => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::{dist, BBox};

    const UNIT: Placement = Placement {
        center: [0.0, 0.0],
        scale: 1.0,
    };

    const C: WarmCriteria = WarmCriteria {
        settle_width: 0.02,
        tube_radius: 0.01,
        eps: 0.001,
        median_settle: true,
    };

    #[test]
    fn decisions_follow_the_distance_to_the_data() {
        let offset = |d: Decision| match d {
            Decision::Offset(x) => x,
            other => panic!("{other:?}"),
        };
        assert_eq!(decide(0.015, 0.005, &C), Decision::Near);
        assert!((offset(decide(0.021, 0.005, &C)) - 0.022).abs() < 1e-15);
        assert_eq!(decide(0.05, 0.005, &C), Decision::Cold);
        // A previous frame that ended far from its data widens the offset range.
        assert!((offset(decide(0.05, 0.03, &C)) - 0.051).abs() < 1e-15);
        let flow = WarmCriteria {
            median_settle: false,
            ..C
        };
        assert!((offset(decide(0.015, 0.005, &flow)) - 0.016).abs() < 1e-15);
    }

    #[test]
    fn carrying_interpolates_and_extends_beyond_the_old_mesh_as_a_distance() {
        let bbox = BBox {
            min: [-1.0, -1.0],
            max: [1.0, 1.0],
        };
        let old = Mesh::structured(&bbox, 40);
        // A linear field is carried exactly by P1 interpolation.
        let u: Vec<f64> = old.coords.iter().map(|p| 2.0 * p[0] - p[1]).collect();
        // Local coordinates centred at (0.1, -0.2) and half the size: values halve too.
        let at = Placement {
            center: [0.1, -0.2],
            scale: 0.5,
        };
        let probes = [[0.0, 0.0], [0.5, -0.3], [-1.7, 1.5]];
        let got = carry(&old, &u, &at, &probes);
        for (p, g) in probes.iter().zip(&got) {
            let q = at.to_data(*p);
            assert!((g - (2.0 * q[0] - q[1]) / 0.5).abs() < 1e-12, "{p:?}: {g}");
        }
        // Beyond the old mesh, (1.05, -0.2) in data coordinates: the value at the nearest
        // point of its domain, (1, -0.2), plus the way out (0.05, 0.1 in local units).
        let out = carry(&old, &u, &at, &[[1.9, 0.0]]);
        assert!((out[0] - (2.2 / 0.5 + 0.1)).abs() < 1e-12, "{}", out[0]);
    }

    #[test]
    fn a_curve_at_the_data_is_kept_and_one_farther_is_offset() {
        let bbox = BBox {
            min: [-1.0, -1.0],
            max: [1.0, 1.0],
        };
        let mesh = Mesh::structured(&bbox, 80);
        let circle = |r: f64| -> Vec<f64> {
            mesh.coords
                .iter()
                .map(|&p| dist(p, [0.0, 0.0]) - r)
                .collect()
        };
        let samples: Vec<Point> = (0..100)
            .map(|i| {
                let a = i as f64 * 0.0628;
                [0.5 * a.cos(), 0.5 * a.sin()]
            })
            .collect();
        let data = locate_all(&mesh, &samples);
        let prev_u = circle(0.51);
        let prev = Previous {
            mesh: &mesh,
            u: &prev_u,
            spread: 0.0,
            near: 1.0,
            enclosed: true,
        };
        let (u, near) = warm_start(prev, &UNIT, &mesh, &data, &C).unwrap();
        assert!(near && u == prev_u);
        // 0.03 inside the samples: too far for the settle, within twice the previous
        // spread, so offset outward past the samples by eps (P1 interpolation of the
        // circle's distance errs by h^2 / (8 r) = 1.6e-4 on this mesh).
        let prev_u = circle(0.47);
        let prev = Previous {
            u: &prev_u,
            spread: 0.02,
            ..prev
        };
        let (u, near) = warm_start(prev, &UNIT, &mesh, &data, &C).unwrap();
        assert!(!near);
        let (res, _) = crate::levelset::solver::residual(&mesh, &data, &u);
        assert!((res - C.eps).abs() < 5e-4, "{res}");
        let prev_u = circle(0.3);
        let prev = Previous {
            u: &prev_u,
            spread: 0.0,
            ..prev
        };
        assert!(warm_start(prev, &UNIT, &mesh, &data, &C).is_none());
    }

    /// A tenth of the samples far out (outliers, isolated returns) do not decide: the
    /// curve at the other nine tenths is near, and is kept. Decided by the maximum, it
    /// was offset by the outliers' distance, and the next frame farther still.
    #[test]
    fn outliers_do_not_push_a_warm_start_away() {
        let bbox = BBox {
            min: [-1.0, -1.0],
            max: [1.0, 1.0],
        };
        let mesh = Mesh::structured(&bbox, 80);
        let mut samples: Vec<Point> = (0..95)
            .map(|i| {
                let a = i as f64 * 0.066;
                [0.5 * a.cos(), 0.5 * a.sin()]
            })
            .collect();
        samples.extend((0..5).map(|i| [0.9, -0.8 + 0.3 * i as f64]));
        let data = locate_all(&mesh, &samples);
        let u: Vec<f64> = mesh
            .coords
            .iter()
            .map(|&p| dist(p, [0.0, 0.0]) - 0.5)
            .collect();
        let prev = Previous {
            mesh: &mesh,
            u: &u,
            spread: 0.0,
            near: 0.95,
            enclosed: true,
        };
        let (carried, near) = warm_start(prev, &UNIT, &mesh, &data, &C).unwrap();
        assert!(near && carried == u);
    }
}
