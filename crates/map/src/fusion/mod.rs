//! Refinement over frames (`[pipeline] accumulate`): a stream whose scan frames carry a
//! pose keeps its last frames' curves in the world's coordinates, and each new frame's
//! curves are moved along their normals to the average of where the window's frames
//! drew the same wall.
//!
//! Every frame's curve lies within its own noise of the wall, and frames whose noise is
//! independent put the average about `sqrt k` closer over `k` frames. Each older
//! frame's curves are first laid onto the newest frame's by point-to-line ICP
//! (`Window::push`): the recordings' poses are off by more than the noise, and a curve
//! averaged where its pose put it drags the wall by its pose error. A frame's curve
//! counts at a point of the newest curve only where its perpendicular foot lies within
//! twice the newest frame's range noise, on a curve facing the same way (`Window::refined`):
//! two curves each within the noise of one wall differ by less than that, and a curve
//! farther off saw something else there (a door since opened, a person since gone, a
//! pose error the alignment did not catch). Besides the newest frame's curves, only
//! stretches of older curves within its support tolerance of the returns it drew no
//! curve through are drawn ([`filled`]), so a wall it has no return of is not drawn,
//! and no older evidence can remove a wall it does see. The window is what the sensor
//! sees now, sharpened by what it saw a moment ago, not a map.

use std::collections::VecDeque;

use rayon::prelude::*;

mod align;

use align::{Rigid, Surface};

use isoline_core::geom::{Point, Polyline};
use isoline_core::{RefineFrame, Refined, Refiner, SegmentIndex, WindowStats, SMOOTHING};

/// Deviations of the newest frame's range noise a curve point must stand off its
/// chord before the window looks for older curves between the two: the refinement
/// gate's own width, so a point within it is averaged as before and one beyond it
/// (a spike no gate round the point would reach past) is not left alone.
const SPIKE: f64 = 2.0;

/// Offsets a view needs before its mean square offset, a variance, counts: ten give it
/// to within about half (its relative standard error is `sqrt(2 / n)`).
const MIN_OFFSETS: usize = 10;

/// How long frames stay in a window.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WindowLimits {
    /// Frames at most (the newest included).
    pub frames: usize,
    /// Frames whose time stamp `t` is older than the newest's by more than this leave.
    pub seconds: Option<f64>,
    /// Bytes the window may hold ([`Window::bytes`]): the oldest frames leave while it
    /// holds more (the newest always stays).
    pub max_bytes: Option<usize>,
}

/// One frame of a window, in the world's coordinates and the data's units.
pub(crate) struct View {
    /// The frame's number.
    pub frame: u64,
    /// Its time stamp, if it had one.
    pub t: Option<f64>,
    /// Its curves, no segment longer than `tol`: where the average may move them.
    curves: Vec<Polyline>,
    index: SegmentIndex,
    /// Per segment of `index`: whether its start (bit 0) or its end (bit 1) is an open
    /// curve's end, where a foot is not perpendicular and the frame saw no farther.
    ends: Vec<u8>,
    /// Its runs' returns, the evidence the refined curves are checked against.
    returns: Vec<Point>,
    /// Its returns its own curves leave unexplained, while it is the newest: where older
    /// curves may fill in.
    unexplained: Vec<Point>,
    /// Its range noise.
    sigma: f64,
    /// Its support's tolerance, `2 sigma + hmin`.
    tol: f64,
    /// The motion that lays it onto the window's newest view.
    to_newest: Rigid,
}

impl View {
    /// A view of the frame with `curves` and its runs' `returns` (in the world's
    /// coordinates), range noise `sigma` and support tolerance `tol`.
    pub(crate) fn new(
        frame: u64,
        t: Option<f64>,
        curves: &[Polyline],
        returns: Vec<Point>,
        sigma: f64,
        tol: f64,
    ) -> View {
        let curves: Vec<Polyline> = curves.iter().map(|c| subdivided(c, tol)).collect();
        let index = SegmentIndex::new(&curves);
        let mut ends = vec![0u8; index.segments().len()];
        for (k, c) in curves.iter().enumerate() {
            let n = c.segments().count();
            if c.closed || n == 0 {
                continue;
            }
            ends[index.start(k)] |= 1;
            ends[index.start(k) + n - 1] |= 2;
        }
        View {
            frame,
            t,
            curves,
            index,
            ends,
            returns,
            unexplained: Vec::new(),
            sigma,
            tol,
            to_newest: Rigid::IDENTITY,
        }
    }

    /// The view with `returns` (world coordinates) that its own curves leave
    /// unexplained.
    pub(crate) fn with_unexplained(mut self, returns: Vec<Point>) -> View {
        self.unexplained = returns;
        self
    }

    /// Its curves' points, run after run: the source of its alignment.
    fn points(&self) -> impl Iterator<Item = Point> + '_ {
        self.curves.iter().flat_map(|c| c.points.iter().copied())
    }

    /// Its curves as the target of an alignment: normals fitted over two tolerances
    /// each side, as a scan's runs are (`Surface::of`).
    fn surface(&self) -> Surface {
        let runs: Vec<Vec<Point>> = self
            .curves
            .iter()
            .map(|c| {
                let mut pts = c.points.clone();
                if c.closed {
                    pts.extend(c.points.first());
                }
                pts
            })
            .collect();
        Surface::new(&runs, 2.0 * self.tol, self.sigma)
    }

    /// Where its curve crosses the normal line `p + s n` nearest to `p`, as the offset
    /// `s`, when it does so within `gate` of `p`, perpendicularly (not at one of its
    /// curves' ends) and facing the same way as the tangent `t` there. `p`, `n` and `t`
    /// are in its own coordinates.
    fn offset(&self, p: Point, n: Point, t: Point, gate: f64) -> Option<f64> {
        let (d, i, s) = self.index.nearest(p)?;
        if d > gate {
            return None;
        }
        let at_end = (s <= 0.0 && self.ends[i] & 1 != 0) || (s >= 1.0 && self.ends[i] & 2 != 0);
        let (a, b) = self.index.segments()[i];
        let dir = isoline_core::geom::sub(b, a);
        if at_end || isoline_core::geom::dot(dir, t) <= 0.0 {
            return None;
        }
        let foot = isoline_core::geom::add(a, isoline_core::geom::scale(dir, s));
        Some(isoline_core::geom::dot(isoline_core::geom::sub(foot, p), n))
    }

    /// Bytes this view holds: its curves, returns and index.
    pub fn bytes(&self) -> usize {
        let point = std::mem::size_of::<Point>();
        self.curves
            .iter()
            .map(|c| c.points.len() * point)
            .sum::<usize>()
            + (self.returns.len() + self.unexplained.len()) * point
            + self.ends.len()
            + self.index.bytes()
    }
}

/// `c` with every segment longer than `step` cut into equal pieces no longer than it.
fn subdivided(c: &Polyline, step: f64) -> Polyline {
    let mut points = Vec::with_capacity(c.points.len());
    for (a, b) in c.segments() {
        points.push(a);
        let n = (isoline_core::geom::dist(a, b) / step).ceil();
        if n.is_finite() && n > 1.0 {
            for k in 1..n as usize {
                let f = k as f64 / n;
                points.push(isoline_core::geom::add(
                    a,
                    isoline_core::geom::scale(isoline_core::geom::sub(b, a), f),
                ));
            }
        }
    }
    if !c.closed {
        points.extend(c.points.last());
    } else if c.points.len() < 2 {
        points = c.points.clone();
    }
    Polyline {
        closed: c.closed,
        points,
    }
}

/// A stream's window of views, oldest first.
pub struct Window {
    views: VecDeque<View>,
    limits: WindowLimits,
}

impl std::fmt::Debug for Window {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Window")
            .field("frames", &self.len())
            .field("bytes", &self.bytes())
            .finish()
    }
}

impl Window {
    /// An empty window that keeps frames within `limits`.
    pub fn new(limits: WindowLimits) -> Window {
        Window {
            views: VecDeque::new(),
            limits,
        }
    }

    /// Adds the newest view, lays every older one onto it, and lets the views the limits
    /// no longer allow leave. A frame number that does not follow the last one's (a
    /// restarted stream) or a time that goes back empties the window first.
    pub(crate) fn push(&mut self, view: View) {
        let limits = self.limits;
        let restarted = self.views.back().is_some_and(|last| {
            view.frame <= last.frame || matches!((last.t, view.t), (Some(a), Some(b)) if b < a)
        });
        if restarted {
            self.views.clear();
        }
        self.views.push_back(view);
        let newest_t = self.views.back().and_then(|v| v.t);
        while self.views.len() > 1 {
            let too_old = match (limits.seconds, newest_t, self.views[0].t) {
                (Some(s), Some(now), Some(then)) => now - then > s,
                _ => false,
            };
            let too_big = limits.max_bytes.is_some_and(|m| self.bytes() > m);
            if self.views.len() > limits.frames.max(1) || too_old || too_big {
                self.views.pop_front();
            } else {
                break;
            }
        }
        let Some((newest, older)) = self.views.make_contiguous().split_last_mut() else {
            return;
        };
        if older.is_empty() {
            return;
        }
        // Each older view is laid straight onto the newest from where the poses put it:
        // a chain of consecutive alignments lets its errors add up over the window (on
        // the recordings, nine frames back, a chain's motion moved the older curves 3.5
        // cm (median) from where a plain ICP puts them, a direct alignment 1.5 cm).
        let target = newest.surface();
        older.par_iter_mut().for_each(|v| {
            // Only the newest view's unexplained returns are filled about.
            v.unexplained = Vec::new();
            let pts: Vec<Point> = v.points().collect();
            v.to_newest = align::align(&pts, &target);
        });
    }

    /// The views, oldest first.
    #[cfg(test)]
    pub(crate) fn views(
        &self,
    ) -> impl DoubleEndedIterator<Item = &View> + ExactSizeIterator + Clone {
        self.views.iter()
    }

    /// How many frames the window holds.
    pub fn len(&self) -> usize {
        self.views.len()
    }

    /// Whether it holds none.
    pub fn is_empty(&self) -> bool {
        self.views.is_empty()
    }

    /// The returns of its views.
    pub fn points(&self) -> usize {
        self.views.iter().map(|v| v.returns.len()).sum()
    }

    /// Bytes the window holds, roughly.
    pub fn bytes(&self) -> usize {
        self.views.iter().map(View::bytes).sum()
    }

    /// The newest view's curves, each point within its support's tolerance of its own
    /// returns moved along the curve's normal by the weighted mean of the offsets to
    /// the older views' curves that agree with it (`View::offset`, within twice the
    /// newest frame's range noise of the point, or of the stretch from the point to its
    /// own curve's chord where it stands off that chord by more), the newest counting
    /// with offset zero; each view weighs by the inverse of the variance with which it
    /// places the wall, its curve's noise and what the alignment left of its pose error
    /// (`view_weights`). Returns the curves and the
    /// older views' returns as the alignment placed them (the evidence the refined
    /// curves are checked against), and the pieces of older curves that fill where the
    /// newest frame sees a surface it drew no curve of ([`filled`]), all in the world's
    /// coordinates. Empty when the window is.
    pub(crate) fn refined(&self) -> Refined {
        let Some(newest) = self.views.back() else {
            return Refined::default();
        };
        let older: Vec<&View> = self.views.iter().take(self.views.len() - 1).collect();
        let found = found(newest, &older);
        let weights = view_weights(&found, older.len(), newest.sigma);
        let curves = moved(&newest.curves, &found, &weights);
        let evidence = older
            .iter()
            .flat_map(|v| v.returns.iter().map(|&q| v.to_newest.apply(q)))
            .collect();
        Refined {
            curves,
            filled: filled(newest, &older),
            evidence,
        }
    }
}

/// Pieces of the `older` views' curves, laid onto the `newest`, where the newest frame
/// has returns its own curves leave unexplained: each point of a piece lies within the
/// newest frame's support tolerance of such a return and farther than that from the
/// newest frame's curves and from the pieces already taken, and a piece has at least two
/// points. The most recent views are asked first.
///
/// A return no curve of its frame explains is a surface the frame saw too sparsely to
/// draw (a wall far off or at grazing incidence, where its returns are fewer than a
/// run): a single frame says nothing about its shape, and an older frame that saw it
/// from nearer did. Every point drawn is one the newest frame vouches for with a return
/// within its noise, so an older curve where the newest sees nothing, or where the
/// scene has changed (a door since opened, a person since gone), is not drawn; the
/// export cuts whatever of it the newest frame's beams saw through, as it cuts the
/// frame's own curves.
fn filled(newest: &View, older: &[&View]) -> Vec<Polyline> {
    let tol = newest.tol;
    if newest.unexplained.is_empty() {
        return Vec::new();
    }
    let Ok(support) = kiddo::ImmutableKdTree::<f64, 2>::new_from_slice(&newest.unexplained) else {
        return Vec::new();
    };
    let supported = |p: Point| {
        support
            .query(&p)
            .nearest_one::<kiddo::SquaredEuclidean<f64>>()
            .execute()
            .distance
            <= tol * tol
    };
    let far = |index: &SegmentIndex, p: Point| index.nearest(p).is_none_or(|(d, _, _)| d > tol);
    let mut pieces: Vec<Polyline> = Vec::new();
    for v in older.iter().rev() {
        let taken = SegmentIndex::new(&pieces);
        let mut found = Vec::new();
        for c in &v.curves {
            let mut piece: Vec<Point> = Vec::new();
            for &q in &c.points {
                let p = v.to_newest.apply(q);
                if supported(p) && far(&newest.index, p) && far(&taken, p) {
                    piece.push(p);
                } else if piece.len() >= 2 {
                    found.push(std::mem::take(&mut piece));
                } else {
                    piece.clear();
                }
            }
            if piece.len() >= 2 {
                found.push(piece);
            }
        }
        pieces.extend(found.into_iter().map(|points| Polyline {
            closed: false,
            points,
        }));
    }
    pieces
}

/// What the `older` views say at each point of the `newest` view's curves (see
/// [`Window::refined`]): none where the point has no returns of its own near it.
fn found(newest: &View, older: &[&View]) -> Vec<Vec<Option<Found>>> {
    let gate = 2.0 * newest.sigma;
    // The farthest one frame's curve lies from its wall: the accuracy bound.
    let reach = 3.0 * newest.sigma + 2.0 * (newest.tol - 2.0 * newest.sigma);
    // Only where the newest frame has returns of its own: elsewhere (a piece bridging
    // a gap between its runs) it has no wall of its own to sharpen.
    let returns = kiddo::ImmutableKdTree::<f64, 2>::new_from_slice(&newest.returns).ok();
    // The nearest of its returns within its support's tolerance, and the spacing of
    // its run's returns there (to the nearer neighbour in the run's order, as the
    // returns are laid out run after run).
    let own_near = |p: Point| -> Option<f64> {
        let t = returns.as_ref()?;
        let nn = t
            .query(&p)
            .nearest_one::<kiddo::SquaredEuclidean<f64>>()
            .execute();
        if nn.distance > newest.tol * newest.tol {
            return None;
        }
        let j = nn.item as usize;
        let r = &newest.returns;
        let spacing = [j.checked_sub(1), Some(j + 1)]
            .into_iter()
            .flatten()
            .filter_map(|k| r.get(k))
            .map(|q| isoline_core::geom::dist(*q, r[j]))
            .fold(f64::INFINITY, f64::min);
        Some(spacing)
    };
    newest
        .curves
        .par_iter()
        .map(|c| {
            (0..c.points.len())
                .map(|i| {
                    let p = c.points[i];
                    // The chord of the newest frame's own curve over the returns
                    // its run's smoothing line spanned (`SMOOTHING` a side, at most
                    // the two tolerances a side the alignment fits its normals
                    // over), and where it puts the wall here: a point standing off
                    // it follows a return that line left raw (a shape, or a return
                    // a few deviations off: one frame cannot tell). The window can,
                    // so a curve of an older frame counts anywhere from the point
                    // to the chord, widened by the gate, and the point moves across
                    // the chord's direction, not along the flank of its own spike.
                    let spacing = own_near(p)?;
                    let len = (SMOOTHING as f64 * spacing).min(2.0 * newest.tol);
                    let chord = spacing
                        .is_finite()
                        .then(|| chord_offset(c, i, len))
                        .flatten();
                    let t = chord.map_or_else(|| tangent(c, i), |(_, d)| d);
                    if t == [0.0, 0.0] {
                        return None;
                    }
                    let n = [-t[1], t[0]];
                    let dev = chord
                        .map_or(0.0, |(f, _)| {
                            isoline_core::geom::dot(isoline_core::geom::sub(f, p), n)
                        })
                        .clamp(-reach, reach);
                    let dev = if dev.abs() > SPIKE * newest.sigma {
                        dev
                    } else {
                        0.0
                    };
                    let (lo, hi) = (dev.min(0.0) - gate, dev.max(0.0) + gate);
                    let offsets = older
                        .iter()
                        .map(|v| {
                            // Into the older view's coordinates: its motion is rigid,
                            // so offsets along the turned normal are the same lengths.
                            let m = &v.to_newest;
                            let tq = rotate_back(m, t);
                            v.offset(m.inverse(p), [-tq[1], tq[0]], tq, gate + dev.abs())
                                .filter(|s| (lo..=hi).contains(s))
                        })
                        .collect();
                    Some(Found {
                        tangent: t,
                        spike: dev != 0.0,
                        offsets,
                    })
                })
                .collect()
        })
        .collect()
}

/// The `curves` with each point moved along its normal by the weighted mean of the
/// offsets `found` there, the newest view weighing 1 with offset zero.
fn moved(curves: &[Polyline], found: &[Vec<Option<Found>>], weights: &[f64]) -> Vec<Polyline> {
    curves
        .iter()
        .zip(found)
        .map(|(c, found)| {
            let points = c
                .points
                .iter()
                .zip(found)
                .map(|(&p, f)| {
                    let Some(Found {
                        tangent: t,
                        offsets,
                        ..
                    }) = f
                    else {
                        return p;
                    };
                    // The newest weighs 1, with offset zero.
                    let (mut sum, mut total) = (0.0, 1.0);
                    for (s, w) in offsets.iter().zip(weights) {
                        if let Some(s) = s {
                            sum += w * s;
                            total += w;
                        }
                    }
                    isoline_core::geom::add(
                        p,
                        isoline_core::geom::scale([-t[1], t[0]], sum / total),
                    )
                })
                .collect();
            Polyline {
                closed: c.closed,
                points,
            }
        })
        .collect()
}

/// What the older views say at one point of the newest curves.
#[derive(Clone, Debug)]
struct Found {
    /// The direction the point moves across.
    tangent: Point,
    /// Whether the point stood off its own chord.
    spike: bool,
    /// Each older view's offset along the normal, None where it says nothing.
    offsets: Vec<Option<f64>>,
}

/// The weight of each older view, the newest weighing 1: the inverse variance of where
/// each puts the wall, relative to the newest's. Two views' curves differ by both curves' noise and by what the
/// alignment left of the older view's pose error, so each older view's mean square
/// offset from the newest (over the points off no chord, where the offsets are the
/// wall's) is `2 c^2 + p_v^2`: the curves' variance `c^2`, taken from the view that
/// agrees best (its pose error the least), and the rest is that view's pose variance.
/// A view with fewer than `MIN_OFFSETS` offsets (its variance not known to within
/// half) weighs as the newest; so do all when none has them, as with equal noise.
fn view_weights(found: &[Vec<Option<Found>>], views: usize, sigma: f64) -> Vec<f64> {
    let mut sums = vec![(0.0, 0usize); views];
    for f in found.iter().flatten().flatten() {
        if f.spike {
            continue;
        }
        for (acc, s) in sums.iter_mut().zip(&f.offsets) {
            if let Some(s) = s {
                acc.0 += s * s;
                acc.1 += 1;
            }
        }
    }
    let floor = (1e-3 * sigma).powi(2);
    let ms: Vec<Option<f64>> = sums
        .iter()
        .map(|&(sq, n)| (n >= MIN_OFFSETS).then(|| (sq / n as f64).max(floor)))
        .collect();
    let Some(c2) = ms
        .iter()
        .flatten()
        .copied()
        .reduce(f64::min)
        .map(|m| m / 2.0)
    else {
        return vec![1.0; views];
    };
    ms.iter()
        .map(|m| m.map_or(1.0, |m| c2 / (m - c2).max(c2)))
        .collect()
}

/// The unit tangent of `c` at its point `i`: along the chord of its two neighbours
/// (one at an open curve's end), zero where they coincide.
fn tangent(c: &Polyline, i: usize) -> Point {
    let n = c.points.len();
    if n < 2 {
        return [0.0, 0.0];
    }
    let (a, b) = match (i, c.closed) {
        (0, true) => (c.points[n - 1], c.points[1]),
        (0, false) => (c.points[0], c.points[1]),
        (i, true) if i + 1 == n => (c.points[i - 1], c.points[0]),
        (i, false) if i + 1 == n => (c.points[i - 1], c.points[i]),
        (i, _) => (c.points[i - 1], c.points[i + 1]),
    };
    let d = isoline_core::geom::sub(b, a);
    let len = isoline_core::geom::norm(d);
    if len > 0.0 {
        isoline_core::geom::scale(d, 1.0 / len)
    } else {
        [0.0, 0.0]
    }
}

/// The foot of `c`'s point `i` on the chord between the points of `c` an arc length
/// `len` before and after it; near an open curve's end, on the line through the points
/// `len` and `2 len` along the side it has, and that line's unit direction (along the
/// curve). None where the curve is shorter than that.
fn chord_offset(c: &Polyline, i: usize, len: f64) -> Option<(Point, Point)> {
    let n = c.points.len();
    if n < 3 {
        return None;
    }
    // The point an arc length `len` along the curve from `i`, stepping by `step`.
    let walk = |step: isize, len: f64| -> Option<Point> {
        let (mut j, mut left) = (i, len);
        loop {
            let k = j as isize + step;
            let k = if c.closed {
                k.rem_euclid(n as isize) as usize
            } else if k < 0 || k >= n as isize {
                return None;
            } else {
                k as usize
            };
            if k == i {
                return None;
            }
            let (a, b) = (c.points[j], c.points[k]);
            let l = isoline_core::geom::dist(a, b);
            if l >= left {
                return Some(isoline_core::geom::add(
                    a,
                    isoline_core::geom::scale(isoline_core::geom::sub(b, a), left / l),
                ));
            }
            left -= l;
            j = k;
        }
    };
    let (a, b) = match (walk(-1, len), walk(1, len)) {
        (Some(a), Some(b)) => (a, b),
        (None, Some(b)) => (b, walk(1, 2.0 * len)?),
        (Some(a), None) => (walk(-1, 2.0 * len)?, a),
        (None, None) => return None,
    };
    let d = isoline_core::geom::sub(b, a);
    let l2 = isoline_core::geom::dot(d, d);
    if l2 <= 0.0 {
        return None;
    }
    let s = isoline_core::geom::dot(isoline_core::geom::sub(c.points[i], a), d) / l2;
    Some((
        isoline_core::geom::add(a, isoline_core::geom::scale(d, s)),
        isoline_core::geom::scale(d, 1.0 / l2.sqrt()),
    ))
}

/// The direction `d` turned back by `m`'s rotation.
fn rotate_back(m: &Rigid, d: Point) -> Point {
    [m.cos * d[0] + m.sin * d[1], -m.sin * d[0] + m.cos * d[1]]
}

impl Refiner for Window {
    fn refine(&mut self, f: RefineFrame) -> Option<Refined> {
        self.push(
            View::new(f.frame, f.t, &f.curves, f.returns, f.sigma, f.tol)
                .with_unexplained(f.unexplained),
        );
        (self.len() > 1).then(|| self.refined())
    }

    fn stats(&self) -> WindowStats {
        WindowStats {
            frames: self.len(),
            points: self.points(),
            bytes: self.bytes(),
        }
    }
}

/// The rigid motion `[x, y, theta]` (`p -> R(theta) p + (x, y)`) that lays `source`,
/// returns of another scan placed in `target`'s coordinates (by the two scans' poses),
/// onto `target`'s runs: the alignment refinement lays each frame onto the next with
/// (docs/method.md, "Refinement over frames"), with the target's own noise estimate,
/// its normals fitted over `2 (2 sigma + spacing)` and pose errors up to four times that
/// corrected. `[0, 0, 0]` when too few returns pair.
///
/// ```
/// use isoline_core::{LaserScan, Scan, ScanParams};
/// use isoline_map::align_returns;
/// // A corner seen from the origin, and the same corner's returns moved by 2 cm.
/// let ranges: Vec<Option<f64>> = (0..90)
///     .map(|i| {
///         let a = (i as f64).to_radians();
///         Some((1.0 / a.cos()).min(1.5 / a.sin()))
///     })
///     .collect();
/// let laser = LaserScan {
///     origin: [0.0, 0.0], angle_min: 0.0, angle_increment: 1f64.to_radians(),
///     ranges: &ranges, range_min: 0.1, range_max: 10.0,
/// };
/// let target = Scan::from_laser(&laser).unwrap();
/// let source: Vec<[f64; 2]> = target.returns().iter().map(|p| [p[0] + 0.02, p[1]]).collect();
/// let [x, y, theta] = align_returns(&source, &target, &ScanParams::default());
/// assert!((x + 0.02).abs() < 1e-3 && y.abs() < 1e-3 && theta.abs() < 1e-3);
/// ```
pub fn align_returns(
    source: &[Point],
    target: &isoline_core::Scan,
    params: &isoline_core::ScanParams,
) -> isoline_core::geom::Pose {
    let target = target.run_returns(params);
    let tol = 2.0 * target.noise + target.spacing;
    let m = align::align(source, &Surface::of(&target, tol));
    [m.t[0], m.t[1], m.sin.atan2(m.cos)]
}

#[cfg(test)]
mod tests {
    use super::*;

    const SIGMA: f64 = 0.01;

    /// A view of the straight wall `y = wall` from `x = 1` to `x = -1` seen from below
    /// (the free side on the curve's left), with returns every 2 cm along it.
    fn wall(frame: u64, t: f64, wall: f64) -> View {
        let curve = Polyline {
            closed: false,
            points: vec![[1.0, wall], [-1.0, wall]],
        };
        let returns = (0..=100).map(|i| [-1.0 + 0.02 * i as f64, wall]).collect();
        View::new(frame, Some(t), &[curve], returns, SIGMA, 3.0 * SIGMA)
    }

    /// A far wall the older frames drew and the newest saw with a few lone returns,
    /// beside a nearer wall of its own: the older curve is drawn about each lone return,
    /// once however many frames drew it, and nowhere else.
    #[test]
    fn older_curves_fill_where_the_newest_frame_saw_too_sparsely_to_draw() {
        let mut w = Window::new(limits(10));
        w.push(wall(0, 0.0, 1.0));
        w.push(wall(1, 1.0, 1.0));
        // The newest frame draws the wall y = 0 and has lone returns on y = 1 (and one
        // where no frame drew anything, and one beside its own curve).
        let lone: Vec<Point> = vec![
            [-0.8, 1.0],
            [-0.2, 1.004],
            [0.5, 0.995],
            [0.0, 3.0],
            [0.3, 0.01],
        ];
        let newest = wall(2, 2.0, 0.0).with_unexplained(lone.clone());
        let tol = newest.tol;
        w.push(newest);
        w.views
            .iter_mut()
            .for_each(|v| v.to_newest = Rigid::IDENTITY);
        let filled = w.refined().filled;
        // One piece about each lone return on the far wall, from one older frame only
        // (the older curve runs from x = 1 to x = -1).
        assert_eq!(filled.len(), 3, "{filled:?}");
        for (piece, at) in filled
            .iter()
            .zip([[0.5, 0.995], [-0.2, 1.004], [-0.8, 1.0]])
        {
            assert!(piece.points.len() >= 2);
            for p in &piece.points {
                // On the older curve, and within the support's tolerance of its return.
                assert!((p[1] - 1.0).abs() < 1e-12, "{p:?}");
                assert!(
                    isoline_core::geom::dist(*p, at) <= tol + 1e-12,
                    "{p:?} {at:?}"
                );
            }
        }
    }

    fn limits(frames: usize) -> WindowLimits {
        WindowLimits {
            max_bytes: None,
            frames,
            seconds: None,
        }
    }

    /// A view whose curve lies within twice the noise of the newest one's averages in;
    /// one farther off (it saw something else there) and one facing the other way (the
    /// other side of a thin wall) are left out. Alignment is set aside here (every view
    /// where its pose put it) to test the average alone.
    #[test]
    fn agreeing_views_average_and_others_are_left_out() {
        let mut w = Window::new(limits(10));
        w.push(wall(0, 0.0, 1.0 + 10.0 * SIGMA));
        w.push(wall(1, 1.0, 1.0 + 0.5 * SIGMA));
        let mut reversed = wall(2, 2.0, 1.0 + 0.5 * SIGMA);
        reversed.curves[0].points.reverse();
        reversed.index = SegmentIndex::new(&reversed.curves);
        w.push(reversed);
        w.push(wall(3, 3.0, 1.0));
        w.views
            .iter_mut()
            .for_each(|v| v.to_newest = Rigid::IDENTITY);
        let Refined {
            curves, evidence, ..
        } = w.refined();
        assert_eq!(evidence.len(), 3 * 101);
        let c = &curves[0];
        // Equal noise: the newest and the one agreeing view weigh alike.
        for p in &c.points[1..c.points.len() - 1] {
            assert!((p[1] - (1.0 + 0.25 * SIGMA)).abs() < 1e-12, "{p:?}");
        }
    }

    /// An older view off by a pose error (about 1.4 cm and 0.2 degrees: within the
    /// average's gate of 2 sigma, so unaligned it would pull the newest curve by half
    /// of it) is laid back onto the newest before it counts: a frame of the same wall,
    /// noise-free, moves the newest curve by nothing the alignment's convergence (a
    /// thousandth of the noise) would not explain.
    #[test]
    fn a_pose_error_is_aligned_away_before_averaging() {
        let corner = |frame: u64, m: Rigid| {
            let pts = [[2.0, -1.0], [2.0, 1.0], [-1.0, 1.0]].map(|p| m.apply(p));
            let curve = Polyline {
                closed: false,
                points: pts.to_vec(),
            };
            let mut returns = Vec::new();
            for i in 0..=100 {
                let s = i as f64 / 100.0;
                returns.push(m.apply([2.0, -1.0 + 2.0 * s]));
                returns.push(m.apply([2.0 - 3.0 * s, 1.0]));
            }
            View::new(frame, None, &[curve], returns, SIGMA, 3.0 * SIGMA)
        };
        let error = Rigid::IDENTITY.then(0.2f64.to_radians(), [0.5, 0.0], [0.012, -0.008]);
        let mut w = Window::new(limits(10));
        w.push(corner(0, error));
        w.push(corner(1, Rigid::IDENTITY));
        let curves = w.refined().curves;
        let own = subdivided(
            &Polyline {
                closed: false,
                points: vec![[2.0, -1.0], [2.0, 1.0], [-1.0, 1.0]],
            },
            3.0 * SIGMA,
        );
        assert_eq!(curves[0].points.len(), own.points.len());
        for (p, q) in curves[0].points.iter().zip(&own.points) {
            assert!(
                isoline_core::geom::dist(*p, *q) < 0.05 * SIGMA,
                "{p:?} against {q:?}"
            );
        }
    }

    /// The wall `y = 1` seen as `wall` sees it, but with a spike `height` off it at
    /// `x = 0`, 6 cm wide, through the return there: a return the run's line did not
    /// follow.
    fn spiked(frame: u64, height: f64) -> View {
        let curve = Polyline {
            closed: false,
            points: vec![
                [1.0, 1.0],
                [0.03, 1.0],
                [0.0, 1.0 + height],
                [-0.03, 1.0],
                [-1.0, 1.0],
            ],
        };
        let returns = (0..=100)
            .map(|i| {
                [
                    -1.0 + 0.02 * i as f64,
                    if i == 50 { 1.0 + height } else { 1.0 },
                ]
            })
            .collect();
        View::new(
            frame,
            Some(frame as f64),
            &[curve],
            returns,
            SIGMA,
            3.0 * SIGMA,
        )
    }

    /// A spike 3.5 sigma off the wall in the newest frame alone (beyond the gate round
    /// the point) is one frame's noise: the older frames' curves, on the wall, count
    /// from the point to the chord of its own curve either side, so it falls to the
    /// average, a quarter of its height with three older frames of equal noise. The
    /// same spike in every frame is a shape, and stays.
    #[test]
    fn a_spike_of_the_newest_frame_alone_is_averaged_away() {
        const HEIGHT: f64 = 3.5 * SIGMA;
        let refined = |older: fn(u64) -> View| {
            let mut w = Window::new(limits(10));
            for i in 0..3 {
                w.push(older(i));
            }
            w.push(spiked(3, HEIGHT));
            w.views
                .iter_mut()
                .for_each(|v| v.to_newest = Rigid::IDENTITY);
            w.refined().curves
        };
        let own = &spiked(3, HEIGHT).curves[0];
        let averaged = refined(|i| wall(i, i as f64, 1.0));
        // The spike's tip, whose chord is the wall, exactly; the points on its flanks,
        // whose chords reach onto the other flank and tilt, within a hundredth of the
        // noise of that.
        for (p, q) in averaged[0].points.iter().zip(&own.points) {
            let expected = (q[1] - 1.0) / 4.0;
            let slack = if q[1] == 1.0 + HEIGHT {
                1e-9
            } else {
                0.01 * SIGMA
            };
            assert!((p[1] - 1.0).abs() <= expected + slack, "{p:?} from {q:?}");
        }
        let tip = averaged[0].points.iter().map(|p| p[1]).fold(0.0, f64::max);
        assert!((tip - (1.0 + HEIGHT / 4.0)).abs() < 1e-9, "{tip}");
        let kept = refined(|i| spiked(i, HEIGHT));
        for (p, q) in kept[0].points.iter().zip(&own.points) {
            assert!(isoline_core::geom::dist(*p, *q) < 1e-9, "{p:?} from {q:?}");
        }
    }

    /// A view whose offsets from the newest scatter as the best one's weighs as the
    /// newest; one shifted by its pose error `d` as well weighs `c^2 / (c^2 + d^2)`
    /// of it, `c^2` being the variance of one curve (half the best view's mean square
    /// offset). Points off their chord and views with too few offsets do not count.
    #[test]
    fn a_view_weighs_by_what_its_pose_error_adds_to_its_noise() {
        let c = 0.004;
        let d = 0.004;
        let point = |a: f64, b: f64, spike: bool| {
            Some(Found {
                tangent: [1.0, 0.0],
                spike,
                offsets: vec![Some(a), Some(b), None],
            })
        };
        let mut found: Vec<_> = (0..40)
            .map(|k| {
                let e = if k % 2 == 0 { c } else { -c };
                point(
                    e * std::f64::consts::SQRT_2,
                    e * std::f64::consts::SQRT_2 + d,
                    false,
                )
            })
            .collect();
        // Spikes, however far, are left out, and so is a point with no view.
        found.push(point(1.0, 1.0, true));
        found.push(None);
        let mut few = found.clone();
        few.push(Some(Found {
            tangent: [1.0, 0.0],
            spike: false,
            offsets: vec![None, None, Some(0.1)],
        }));
        let w = view_weights(&[few], 3, 0.01);
        let c2 = c * c;
        assert!((w[0] - 1.0).abs() < 1e-9, "{w:?}");
        assert!((w[1] - c2 / (c2 + d * d)).abs() < 1e-9, "{w:?}");
        assert_eq!(w[2], 1.0, "one offset: weighs as the newest");
    }

    /// Frames leave by count and by age, and a restart empties the window.
    #[test]
    fn frames_leave_the_window_by_count_and_age() {
        let limits = WindowLimits {
            max_bytes: None,
            frames: 3,
            seconds: Some(2.5),
        };
        let mut w = Window::new(limits);
        for i in 0..5u64 {
            w.push(wall(i, 0.1 * i as f64, 1.0));
        }
        assert_eq!(w.views().map(|v| v.frame).collect::<Vec<_>>(), [2, 3, 4]);
        w.push(wall(5, 2.85, 1.0));
        // 2.85 - 0.3 > 2.5: frame 3 leaves with frame 2; 2.85 - 0.4 < 2.5.
        assert_eq!(w.views().map(|v| v.frame).collect::<Vec<_>>(), [4, 5]);
        w.push(wall(1, 4.0, 1.0));
        assert_eq!(w.len(), 1);
        assert!(w.bytes() > 0);
    }

    /// A byte budget holds whatever the frame count allows: the oldest frames leave
    /// until the window fits, and the newest stays even when it alone is over.
    #[test]
    fn frames_leave_the_window_by_bytes() {
        let one = wall(0, 0.0, 1.0).bytes();
        let mut w = Window::new(WindowLimits {
            max_bytes: Some(3 * one + one / 2),
            frames: 10,
            seconds: None,
        });
        for i in 0..8u64 {
            w.push(wall(i, 0.1 * i as f64, 1.0));
            assert!(w.bytes() <= 3 * one + one / 2);
        }
        assert_eq!(w.views().map(|v| v.frame).collect::<Vec<_>>(), [5, 6, 7]);
        w.limits.max_bytes = Some(one / 2);
        w.push(wall(8, 0.8, 1.0));
        assert_eq!(w.views().map(|v| v.frame).collect::<Vec<_>>(), [8]);
    }
}
