//! How well a frame's curves fit its data, in the measures a user judges by, and the
//! warnings a record carries when the answer is bad: no curve where the data have
//! support, or most of the data unexplained. Robust measures (a share and a quantile),
//! because a maximum follows the farthest outlier.

use rayon::prelude::*;

use crate::geom::{Point, Polyline};
use crate::index::SegmentIndex;
use crate::warning::Warning;

/// The fit of curves to points.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fit {
    /// The share of the points within `tolerance` of a curve.
    pub explained: f64,
    /// The 90th percentile of the points' distances to the curves (infinite without
    /// curves).
    pub p90: f64,
}

/// The fit of `polylines` to `points`, with `tolerance` (the accuracy bound,
/// `3 sigma + 2 hmin`) deciding what a curve explains.
pub fn fit(points: &[Point], polylines: &[Polyline], tolerance: f64) -> Fit {
    if points.is_empty() {
        return Fit {
            explained: 1.0,
            p90: 0.0,
        };
    }
    let index = SegmentIndex::new(polylines);
    let mut d: Vec<f64> = points.par_iter().map(|&p| index.distance(p)).collect();
    let explained = d.iter().filter(|&&x| x <= tolerance).count() as f64 / d.len() as f64;
    let k = ((0.9 * d.len() as f64).ceil() as usize).clamp(1, d.len()) - 1;
    let (_, p90, _) = d.select_nth_unstable_by(k, f64::total_cmp);
    Fit {
        explained,
        p90: *p90,
    }
}

/// Below this share of explained data a record says so.
pub const EXPLAINED_WARNING: f64 = 0.5;

/// The warnings of a frame whose `supported` points (for a scan, the returns in runs;
/// else all of them) gave `polylines` with `fit`.
pub fn warnings(
    supported: usize,
    polylines: &[Polyline],
    fit: &Fit,
    tolerance: f64,
) -> Vec<Warning> {
    let mut w = Vec::new();
    if polylines.is_empty() && supported >= 3 {
        w.push(Warning::NoCurve { supported });
    } else if fit.explained < EXPLAINED_WARNING {
        w.push(Warning::FewExplained {
            explained: fit.explained,
            tolerance,
        });
    }
    w
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_fit_is_robust_to_outliers_and_empty_results_are_named() {
        let wall = Polyline {
            closed: false,
            points: vec![[0.0, 0.0], [10.0, 0.0]],
        };
        // 95 returns 1 cm off the wall, 5 outliers a metre away.
        let mut pts: Vec<Point> = (0..95).map(|i| [0.1 * i as f64, 0.01]).collect();
        pts.extend((0..5).map(|i| [i as f64, 1.0]));
        let f = fit(&pts, std::slice::from_ref(&wall), 0.05);
        assert!((f.explained - 0.95).abs() < 1e-12);
        assert!((f.p90 - 0.01).abs() < 1e-12, "{}", f.p90);
        assert!(warnings(100, std::slice::from_ref(&wall), &f, 0.05).is_empty());
        let none = fit(&pts, &[], 0.05);
        assert_eq!(none.explained, 0.0);
        let w = warnings(100, &[], &none, 0.05);
        assert_eq!(w, [Warning::NoCurve { supported: 100 }]);
        let text = w[0].to_string();
        assert!(
            text.contains("no curve") && text.contains("100 points"),
            "{text}"
        );
        let far: Vec<Point> = (0..10).map(|i| [i as f64, 0.5]).collect();
        let f = fit(&far, std::slice::from_ref(&wall), 0.05);
        let w = warnings(10, std::slice::from_ref(&wall), &f, 0.05);
        assert!(w[0].to_string().contains("only 0%"), "{w:?}");
    }
}
