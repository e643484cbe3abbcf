//! Correlative scan matching (Olson 2009, "Real-time correlative scan matching"): the
//! pose within a window that lays the most of a scan's points on a likelihood lattice
//! of the target, found by exhaustive search, coarse then fine.
//!
//! Why a search and not Gauss-Newton: a loop is found after tens of metres of drift,
//! when where the graph puts the old place may be a metre and several degrees off,
//! beyond where ICP's nearest pairs pull the right way. The search looks at every pose
//! in the window the graph's uncertainty gives, so it needs no start inside the basin;
//! ICP then refines its best.

use isoline_core::{Point, Pose};

use crate::se2::wrap;

/// A lattice of the likelihood that a point falls there: `exp(-d^2 / 2 s^2)` of the
/// distance `d` to the nearest target point, cut at `2 s`.
pub struct Likelihood {
    origin: Point,
    res: f64,
    w: usize,
    h: usize,
    v: Vec<f32>,
}

impl Likelihood {
    /// The lattice of `points` at spacing `res`, blurred by `s` (at least `res`), with a
    /// margin `margin` round the points' box.
    pub fn new(points: &[Point], res: f64, s: f64, margin: f64) -> Option<Likelihood> {
        let s = s.max(res);
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in points {
            lo = [lo[0].min(p[0]), lo[1].min(p[1])];
            hi = [hi[0].max(p[0]), hi[1].max(p[1])];
        }
        if !(lo[0].is_finite() && hi[0].is_finite()) {
            return None;
        }
        let pad = margin + 2.0 * s;
        // On the lattice of multiples of `res` in the points' frame: where the lattice's
        // nodes lie does not depend on which points are in reach.
        let origin = [
            ((lo[0] - pad) / res).floor() * res,
            ((lo[1] - pad) / res).floor() * res,
        ];
        let w = ((hi[0] + pad - origin[0]) / res).ceil() as usize + 1;
        let h = ((hi[1] + pad - origin[1]) / res).ceil() as usize + 1;
        // A bound: 40 m square submaps at 5 cm hold 640,000 cells.
        if w.saturating_mul(h) > 4_000_000 {
            return None;
        }
        // The nearest point's squared distance a cell, then one exponential a cell: the
        // likelihood falls with the distance, so the largest is the nearest's.
        let cut = 4.0 * s * s;
        let mut v = vec![f32::INFINITY; w * h];
        let r = (2.0 * s / res).ceil() as i64;
        for p in points {
            let (ci, cj) = (
                ((p[0] - origin[0]) / res).round() as i64,
                ((p[1] - origin[1]) / res).round() as i64,
            );
            for dj in -r..=r {
                for di in -r..=r {
                    let (i, j) = (ci + di, cj + dj);
                    if i < 0 || j < 0 || i >= w as i64 || j >= h as i64 {
                        continue;
                    }
                    let c = [
                        origin[0] + i as f64 * res - p[0],
                        origin[1] + j as f64 * res - p[1],
                    ];
                    let d2 = c[0] * c[0] + c[1] * c[1];
                    let k = j as usize * w + i as usize;
                    v[k] = v[k].min(d2 as f32);
                }
            }
        }
        for x in &mut v {
            *x = if f64::from(*x) <= cut {
                (-0.5 * f64::from(*x) / (s * s)).exp() as f32
            } else {
                0.0
            };
        }
        Some(Likelihood {
            origin,
            res,
            w,
            h,
            v,
        })
    }

    /// The cell of `p` (nearest lattice node), which may lie outside the lattice.
    fn cell(&self, p: Point) -> (i64, i64) {
        // Rounding by adding a half and flooring through the integer cast: `f64::round`
        // is a library call on the baseline x86-64, and this is the search's inner loop.
        let x = (p[0] - self.origin[0]) / self.res + 0.5;
        let y = (p[1] - self.origin[1]) / self.res + 0.5;
        (x.floor_fast(), y.floor_fast())
    }

    /// The likelihood at cell `(i, j)`, zero outside the lattice.
    fn at_cell(&self, i: i64, j: i64) -> f32 {
        if i < 0 || j < 0 || i >= self.w as i64 || j >= self.h as i64 {
            return 0.0;
        }
        self.v[j as usize * self.w + i as usize]
    }
}

/// `floor` through an integer cast, for values well within `i64`.
trait FloorFast {
    fn floor_fast(self) -> i64;
}

impl FloorFast for f64 {
    fn floor_fast(self) -> i64 {
        // Non-finite and huge values saturate in the cast: far outside any lattice.
        let t = self as i64;
        if (t as f64) > self {
            t - 1
        } else {
            t
        }
    }
}

/// Whether a target point lies where a search of `source` within `window` of `guess`
/// can score on it: within `pad` of the box the source sweeps (its box at `guess`,
/// grown by the window's shift and by the chord its farthest point turns through).
/// The lattice is built over those alone: a loop's target holds tens of old keyframes,
/// a search's window covers a few of them.
pub fn in_reach(
    source: &[Point],
    guess: Pose,
    window: Window,
    pad: f64,
) -> impl Fn(&Point) -> bool {
    let (s, c) = guess[2].sin_cos();
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    let mut reach = 0.0f64;
    for p in source {
        let q = [
            c * p[0] - s * p[1] + guess[0],
            s * p[0] + c * p[1] + guess[1],
        ];
        lo = [lo[0].min(q[0]), lo[1].min(q[1])];
        hi = [hi[0].max(q[0]), hi[1].max(q[1])];
        reach = reach.max(p[0].hypot(p[1]));
    }
    let grow =
        window.linear + 2.0 * reach * (0.5 * window.angular.min(std::f64::consts::PI)).sin() + pad;
    move |q: &Point| {
        q[0] >= lo[0] - grow && q[0] <= hi[0] + grow && q[1] >= lo[1] - grow && q[1] <= hi[1] + grow
    }
}

/// The window searched: half-widths in translation (metres) and heading (radians).
#[derive(Clone, Copy, Debug)]
pub struct Window {
    /// Translation half-width.
    pub linear: f64,
    /// Heading half-width.
    pub angular: f64,
}

/// What a search found: the best pose and its score (the mean likelihood of the
/// points, in `[0, 1]`), and the best score of the poses apart from it (more than
/// two translation steps or two heading steps away).
#[derive(Clone, Copy, Debug)]
pub struct Found {
    /// The best pose.
    pub pose: Pose,
    /// Its score.
    pub score: f64,
    /// The best score away from it.
    pub runner_up: f64,
}

impl Found {
    /// Whether another place scores within three standard errors of the best: the
    /// points' share on the walls, read as a proportion of `n` points, cannot tell
    /// the two apart (a corridor's repeated doors, a building's parallel corridors).
    pub fn ambiguous(&self, n: usize) -> bool {
        let se = (self.score * (1.0 - self.score) / n.max(1) as f64).sqrt();
        self.runner_up >= self.score - 3.0 * se
    }
}

/// The best pose within `window` of `guess` for `points` on `grid`. Steps: the
/// lattice's spacing in translation, and in heading the angle that moves the farthest
/// point by it.
pub fn search(points: &[Point], grid: &Likelihood, guess: Pose, window: Window) -> Found {
    let reach = points
        .iter()
        .map(|p| p[0].hypot(p[1]))
        .fold(0.0f64, f64::max)
        .max(grid.res);
    let lin_step = grid.res;
    let ang_step = (grid.res / reach).min(0.05);
    let nl = (window.linear / lin_step).ceil() as i64;
    let na = (window.angular / ang_step).ceil() as i64;
    let side = (2 * nl + 1) as usize;
    let mut scores = vec![0.0f64; side * side * (2 * na + 1) as usize];
    // A translation step is one lattice cell: each rotated point's cell is found once,
    // and a shift moves every cell by whole steps (Olson 2009).
    let mut cells: Vec<(i64, i64)> = Vec::with_capacity(points.len());
    for a in -na..=na {
        let theta = guess[2] + a as f64 * ang_step;
        let (s, c) = theta.sin_cos();
        cells.clear();
        cells.extend(points.iter().map(|p| {
            grid.cell([
                c * p[0] - s * p[1] + guess[0],
                s * p[0] + c * p[1] + guess[1],
            ])
        }));
        let layer = (a + na) as usize * side * side;
        for dj in -nl..=nl {
            for di in -nl..=nl {
                let score: f32 = cells
                    .iter()
                    .map(|&(i, j)| grid.at_cell(i + di, j + dj))
                    .sum();
                scores[layer + (dj + nl) as usize * side + (di + nl) as usize] =
                    f64::from(score) / points.len().max(1) as f64;
            }
        }
    }
    let index = |k: usize| -> (i64, i64, i64) {
        let a = (k / (side * side)) as i64 - na;
        let r = k % (side * side);
        ((r % side) as i64 - nl, (r / side) as i64 - nl, a)
    };
    let (best, score) = scores
        .iter()
        .copied()
        .enumerate()
        .fold((0, -1.0), |b, (k, v)| if v > b.1 { (k, v) } else { b });
    let (bi, bj, ba) = index(best);
    let runner_up = scores
        .iter()
        .enumerate()
        .filter(|&(k, _)| {
            let (i, j, a) = index(k);
            (i - bi).abs().max((j - bj).abs()) > 2 || (a - ba).abs() > 2
        })
        .map(|(_, &v)| v)
        .fold(0.0, f64::max);
    Found {
        pose: [
            guess[0] + bi as f64 * lin_step,
            guess[1] + bj as f64 * lin_step,
            wrap(guess[2] + ba as f64 * ang_step),
        ],
        score,
        runner_up,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use isoline_core::geom::to_sensor;

    #[test]
    fn the_target_within_reach_scores_as_the_whole_target() {
        // A long wall with a short scan of its middle: the far ends are out of reach,
        // and the search on what is kept finds what it finds on the whole.
        let world: Vec<Point> = (0..2000).map(|i| [i as f64 * 0.02 - 20.0, 1.0]).collect();
        let scan: Vec<Point> = (0..100).map(|i| [i as f64 * 0.02 - 1.0, 1.0]).collect();
        let mut scan_l = scan.clone();
        scan_l.extend((0..50).map(|i| [-1.0, 1.0 - i as f64 * 0.02]));
        let mut world_l = world.clone();
        world_l.extend((0..50).map(|i| [-0.9, 1.0 - i as f64 * 0.02]));
        let window = Window {
            linear: 0.3,
            angular: 0.1,
        };
        let guess = [0.0, 0.0, 0.0];
        let keep = in_reach(&scan_l, guess, window, 0.1);
        let kept: Vec<Point> = world_l.iter().copied().filter(|q| keep(q)).collect();
        assert!(kept.len() < world_l.len() / 4, "{}", kept.len());
        let whole = Likelihood::new(&world_l, 0.02, 0.02, window.linear).unwrap();
        let near = Likelihood::new(&kept, 0.02, 0.02, window.linear).unwrap();
        let (a, b) = (
            search(&scan_l, &whole, guess, window),
            search(&scan_l, &near, guess, window),
        );
        assert_eq!(a.pose, b.pose);
        assert!((a.score - b.score).abs() < 1e-9, "{a:?} {b:?}");
        assert!((a.pose[0] - 0.1).abs() < 0.03, "{a:?}");
    }

    #[test]
    fn a_scan_a_metre_and_ten_degrees_off_is_found() {
        // An L-shaped room corner with a pillar, sampled every 2 cm.
        let mut world: Vec<Point> = (0..250).map(|i| [i as f64 * 0.02, 0.0]).collect();
        world.extend((0..200).map(|i| [0.0, i as f64 * 0.02]));
        world.extend((0..40).map(|i| {
            let a = i as f64 * std::f64::consts::TAU / 40.0;
            [2.5 + 0.2 * a.cos(), 2.0 + 0.2 * a.sin()]
        }));
        let truth = [1.5, 1.0, 0.3];
        let scan: Vec<Point> = world.iter().map(|&p| to_sensor(truth, p)).collect();
        let grid = Likelihood::new(&world, 0.05, 0.05, 1.0).unwrap();
        let guess = [2.3, 0.4, 0.3 + 10f64.to_radians()];
        let found = search(
            &scan,
            &grid,
            guess,
            Window {
                linear: 1.2,
                angular: 0.25,
            },
        );
        let (pose, score) = (found.pose, found.score);
        assert!(score > 0.9, "{score}");
        assert!(!found.ambiguous(scan.len()), "{found:?}");
        assert!(
            (pose[0] - truth[0]).hypot(pose[1] - truth[1]) < 0.06,
            "{pose:?}"
        );
        assert!((pose[2] - truth[2]).abs() < 0.02, "{pose:?}");
    }
}
