//! Refinement over frames (`[pipeline] accumulate`): a stream whose scan frames carry a
//! pose keeps its last frames' band meshes and level sets in the world's coordinates,
//! and each new frame's level set is averaged with theirs before its curves are drawn.
//!
//! Every frame's level set is a signed distance to its own curve (negative on the
//! sensor's side), so near a wall the frames saw, the average's zero crossing is the
//! average of their crossings: `k` frames of independent noise put the curve about
//! `sqrt k` closer to the wall. Each frame counts only near its own data (within the
//! support's tolerance of its runs of returns, fading to nothing at twice that): away
//! from them its level set says where its free space ended, not where a wall is.
//!
//! Older frames are laid onto the newest by point-to-line ICP (`Window::push`), and
//! count only where they agree with the newest frame within its range noise
//! (`Window::fuse`). The average is taken on the newest frame's band, which holds only
//! its own runs: a wall the newest frame does not see is not drawn, and nothing older
//! frames saw can remove a wall it does see. The window is what the sensor sees now,
//! sharpened by what it saw a moment ago, not a map.

use std::collections::VecDeque;

use rayon::prelude::*;

mod align;

use align::{Rigid, Surface};

use crate::fem::locate::VertexIndex;
use crate::geom::Point;
use crate::index::SegmentIndex;
use crate::mesh::Mesh;
use crate::scan::Analysis;

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
    /// Its mesh.
    pub mesh: Mesh,
    /// Its level set on the mesh.
    pub u: Vec<f64>,
    /// Its runs, scales, free space and support.
    pub analysis: Analysis,
    /// How near its support its level set counts in full.
    pub tol: f64,
    index: SegmentIndex,
    /// The ends of its runs that are not closed.
    ends: Vec<Point>,
    /// Its mesh's vertices, to start a walk from the vertex nearest a point: a band
    /// mesh has gaps that a walk from anywhere else cannot cross.
    vertices: Option<VertexIndex>,
    /// Its runs' returns, with normals, as the target of the next view's alignment.
    surface: Surface,
    /// The motion that lays it onto the window's newest view.
    to_newest: Rigid,
}

impl View {
    /// A view of the frame with `mesh`, level set `u` and `analysis` (all in the world's
    /// coordinates), whose level set counts within `tol` of its support.
    pub(crate) fn new(
        frame: u64,
        t: Option<f64>,
        mesh: Mesh,
        u: Vec<f64>,
        analysis: Analysis,
        tol: f64,
    ) -> View {
        let index = SegmentIndex::new(&analysis.support);
        let ends = analysis
            .support
            .iter()
            .filter(|s| !s.closed)
            .flat_map(|s| s.points.first().into_iter().chain(s.points.last()))
            .copied()
            .collect();
        let vertices = VertexIndex::new(&mesh);
        let surface = Surface::of(&analysis, tol);
        View {
            frame,
            t,
            mesh,
            u,
            analysis,
            tol,
            index,
            ends,
            vertices,
            surface,
            to_newest: Rigid::IDENTITY,
        }
    }

    /// Its level set at `p`, or `None` where its mesh does not reach (farther than a
    /// thousandth of its tolerance from every triangle).
    pub(crate) fn sample(&self, p: Point) -> Option<f64> {
        let at = self
            .vertices
            .as_ref()?
            .locate_within(&self.mesh, p, 1e-3 * self.tol)?;
        Some(at.interpolate(&self.mesh, &self.u))
    }

    /// How much this view's level set counts at `p`: 1 within `tol` of its support,
    /// falling linearly to 0 at `2 tol`; and near the end of one of its runs, falling
    /// to 0 at the end, from `4 tol` away: round a run's end (an occluder's edge, a
    /// doorway) the frame's free space turns along the beam that grazed it, and its
    /// level set would bend a curve that another frame sees going on.
    pub(crate) fn weight(&self, p: Point) -> f64 {
        if self.index.is_empty() {
            return 0.0;
        }
        let d = self.index.distance(p);
        let near = (2.0 - d / self.tol).clamp(0.0, 1.0);
        if near == 0.0 {
            return 0.0;
        }
        let end = self
            .ends
            .iter()
            .map(|&e| crate::geom::dist(e, p))
            .fold(f64::INFINITY, f64::min);
        near * (end / (4.0 * self.tol)).clamp(0.0, 1.0)
    }

    /// Bytes this view holds: its arrays' lengths and its indices' entries, which
    /// the daemon's resident memory per stream matches within a few per cent
    /// (docs/daemon.md).
    pub fn bytes(&self) -> usize {
        let a = &self.analysis;
        let point = std::mem::size_of::<Point>();
        self.mesh.bytes()
            + self.u.len() * 8
            + (a.scan.angles.len() + a.scan.ranges.len()) * 8
            + (a.free.angles.len() + a.free.reach.len()) * 8
            + a.runs.iter().map(|r| r.beams.len() * 4).sum::<usize>()
            + 2 * a
                .support
                .iter()
                .map(|s| s.points.len() * point)
                .sum::<usize>()
            + self.index.bytes()
            + self.vertices.as_ref().map_or(0, VertexIndex::bytes)
            + self.ends.len() * point
            + self.surface.bytes()
    }
}

/// A stream's window of views, oldest first.
#[derive(Default)]
pub struct Window {
    views: VecDeque<View>,
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
    /// Adds the newest view and lets the views the limits no longer allow leave. A
    /// frame number that does not follow the last one's (a restarted stream) or a time
    /// that goes back empties the window first.
    pub(crate) fn push(&mut self, view: View, limits: &WindowLimits) {
        let restarted = self.views.back().is_some_and(|last| {
            view.frame <= last.frame || matches!((last.t, view.t), (Some(a), Some(b)) if b < a)
        });
        if restarted {
            self.views.clear();
        }
        // Each older view is laid onto the newest through the chain of consecutive
        // alignments: one ICP a frame (each older view aligned afresh cost 4 ms a frame
        // of ten on a 180-beam scan), the chain's error growing only with the window.
        if let Some(last) = self.views.back() {
            let step = align::align(last.surface.points(), &view.surface);
            for v in &mut self.views {
                v.to_newest = v.to_newest.followed_by(&step);
            }
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
    }

    /// The views, oldest first.
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

    /// The median position of the run ends of the window's views within `radius` of
    /// `end` (the nearest of each view's), or `None` when no view has one there.
    pub(crate) fn median_end(&self, end: Point, radius: f64) -> Option<Point> {
        let mut xs = Vec::new();
        let mut ys = Vec::new();
        for v in &self.views {
            let nearest = v
                .ends
                .iter()
                .map(|&e| (crate::geom::dist(e, end), e))
                .filter(|&(d, _)| d <= radius)
                .min_by(|a, b| a.0.total_cmp(&b.0));
            if let Some((_, e)) = nearest {
                xs.push(e[0]);
                ys.push(e[1]);
            }
        }
        if xs.is_empty() {
            return None;
        }
        xs.sort_by(f64::total_cmp);
        ys.sort_by(f64::total_cmp);
        Some([xs[xs.len() / 2], ys[ys.len() / 2]])
    }

    /// The returns of its runs.
    pub fn points(&self) -> usize {
        self.views
            .iter()
            .map(|v| v.analysis.run_points().iter().map(Vec::len).sum::<usize>())
            .sum()
    }

    /// Bytes the window holds, roughly.
    pub fn bytes(&self) -> usize {
        self.views.iter().map(View::bytes).sum()
    }

    /// Replaces `u`, the newest view's level set at its own vertices `points` (in the
    /// world's coordinates), by the weighted average (`View::weight`) of the views'
    /// level sets that agree with it there: a view whose value lies farther from the
    /// newest one's than the newest frame's range noise saw something else at this
    /// place (a door since opened, a person since gone, a pose error the alignment did
    /// not catch) and is left out. So the fused zero crossing never leaves the newest
    /// frame's noise band, and no older evidence can remove a wall the newest frame
    /// sees.
    /// Where `u` is farther from zero than twice the largest tolerance, it stays.
    ///
    /// Returns the older views' returns as the alignment placed them (the evidence the
    /// fused level set is checked against).
    pub(crate) fn fuse(&self, points: &[Point], u: &mut [f64]) -> Vec<Point> {
        const CHUNK: usize = 256;
        let views: Vec<&View> = self.views.iter().collect();
        let Some((&newest, older)) = views.split_last() else {
            return Vec::new();
        };
        // Far from zero `u` keeps its sign whatever the other frames say, and the
        // curves' course does not depend on it.
        let band = 2.0 * self.views.iter().map(|v| v.tol).fold(0.0, f64::max);
        // Each older view as the newest one's support places it (`Window::push`):
        // poses are off by more than the noise, and a view averaged where its pose put
        // it would drag the newest frame's walls by its pose error.
        let moves: Vec<Rigid> = older.iter().map(|v| v.to_newest).collect();
        points
            .par_chunks(CHUNK)
            .zip(u.par_chunks_mut(CHUNK))
            .for_each(|(pts, us)| {
                for (&p, x) in pts.iter().zip(us.iter_mut()) {
                    if x.abs() > band {
                        continue;
                    }
                    let own = *x;
                    // The newest view counts in full on its own mesh: its end fade only
                    // speaks of where other frames may bend its curve.
                    let (mut sum, mut total) = (own, 1.0);
                    for (view, m) in older.iter().zip(&moves) {
                        let q = m.inverse(p);
                        let w = view.weight(q);
                        if w <= 0.0 {
                            continue;
                        }
                        if let Some(v) = view.sample(q) {
                            if (v - own).abs() <= newest.analysis.scales.noise {
                                sum += w * v;
                                total += w;
                            }
                        }
                    }
                    *x = sum / total;
                }
            });
        older
            .iter()
            .zip(&moves)
            .flat_map(|(v, m)| {
                v.analysis
                    .support
                    .iter()
                    .flat_map(move |s| s.points.iter().map(move |&q| m.apply(q)))
            })
            .collect()
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
/// use isoline_core::{align_returns, LaserScan, Scan, ScanParams};
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
    target: &crate::scan::Scan,
    params: &crate::scan::ScanParams,
) -> crate::geom::Pose {
    let analysis = Analysis::new(target.clone(), params);
    let tol = 2.0 * analysis.scales.noise + analysis.scales.spacing;
    let m = align::align(source, &Surface::of(&analysis, tol));
    [m.t[0], m.t[1], m.sin.atan2(m.cos)]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::BBox;

    /// A view of a straight wall `y = wall` seen from below, its level set the signed
    /// distance `y - wall`, meshed over `[-2, 2]^2`.
    fn wall(frame: u64, t: f64, wall: f64) -> View {
        let b = BBox {
            min: [-2.0, -2.0],
            max: [2.0, 2.0],
        };
        let mesh = Mesh::of_box(&b, 0.1);
        let u = mesh.coords.iter().map(|p| p[1] - wall).collect();
        let ranges: Vec<Option<f64>> = (0..61)
            .map(|i| {
                let a = std::f64::consts::FRAC_PI_3 + i as f64 * std::f64::consts::FRAC_PI_3 / 60.0;
                Some(wall / a.sin())
            })
            .collect();
        let scan = crate::scan::Scan::from_laser(&crate::scan::LaserScan {
            origin: [0.0, 0.0],
            angle_min: std::f64::consts::FRAC_PI_3,
            angle_increment: std::f64::consts::FRAC_PI_3 / 60.0,
            ranges: &ranges,
            range_min: 0.1,
            range_max: 10.0,
        })
        .unwrap();
        let params = crate::scan::ScanParams {
            range_noise: Some(0.01),
            ..Default::default()
        };
        let analysis = Analysis::new(scan, &params);
        View::new(frame, Some(t), mesh, u, analysis, 0.05)
    }

    /// A view that agrees with the newest one within the noise averages in by its
    /// weight; one that saw something else here (farther than the noise) is left out,
    /// so the newest frame's wall cannot move by more than its noise; far from the
    /// curve the newest value stays.
    #[test]
    fn agreeing_views_average_and_others_are_left_out() {
        let limits = WindowLimits {
            max_bytes: None,
            frames: 10,
            seconds: None,
        };
        let newest = wall(3, 3.0, 1.0);
        let sigma = newest.analysis.scales.noise;
        assert!(sigma > 0.0 && sigma < 0.05, "{sigma}");
        let shifted = |frame: u64, by: f64| {
            let mut v = wall(frame, frame as f64, 1.0);
            v.u.iter_mut().for_each(|x| *x += by);
            v
        };
        let mut w = Window::default();
        w.push(shifted(0, 10.0 * sigma), &limits);
        w.push(shifted(1, 0.5 * sigma), &limits);
        w.push(newest, &limits);
        let p = [0.0, 1.0];
        let weight = w.views().nth(1).unwrap().weight(p);
        assert!(weight > 0.0);
        let mut u = [0.0, -1.5 - 1.0];
        let pts = [p, [0.0, -1.5]];
        w.fuse(&pts, &mut u);
        let expected = weight * 0.5 * sigma / (1.0 + weight);
        assert!(
            (u[0] - expected).abs() < 1e-9,
            "{} against {expected}",
            u[0]
        );
        assert_eq!(u[1], -1.5 - 1.0);
    }

    /// Frames leave by count and by age, and a restart empties the window.
    #[test]
    fn frames_leave_the_window_by_count_and_age() {
        let limits = WindowLimits {
            max_bytes: None,
            frames: 3,
            seconds: Some(2.5),
        };
        let mut w = Window::default();
        for i in 0..5u64 {
            w.push(wall(i, 0.1 * i as f64, 1.0), &limits);
        }
        assert_eq!(w.views().map(|v| v.frame).collect::<Vec<_>>(), [2, 3, 4]);
        w.push(wall(5, 2.85, 1.0), &limits);
        // 2.85 - 0.3 > 2.5: frame 3 leaves with frame 2; 2.85 - 0.4 < 2.5.
        assert_eq!(w.views().map(|v| v.frame).collect::<Vec<_>>(), [4, 5]);
        w.push(wall(1, 4.0, 1.0), &limits);
        assert_eq!(w.len(), 1);
        assert!(w.bytes() > 0);
    }

    /// A byte budget holds whatever the frame count allows: the oldest frames leave
    /// until the window fits, and the newest stays even when it alone is over.
    #[test]
    fn frames_leave_the_window_by_bytes() {
        let one = wall(0, 0.0, 1.0).bytes();
        let mut limits = WindowLimits {
            max_bytes: Some(3 * one + one / 2),
            frames: 10,
            seconds: None,
        };
        let mut w = Window::default();
        for i in 0..8u64 {
            w.push(wall(i, 0.1 * i as f64, 1.0), &limits);
            assert!(w.bytes() <= limits.max_bytes.unwrap());
        }
        assert_eq!(w.views().map(|v| v.frame).collect::<Vec<_>>(), [5, 6, 7]);
        limits.max_bytes = Some(one / 2);
        w.push(wall(8, 0.8, 1.0), &limits);
        assert_eq!(w.views().map(|v| v.frame).collect::<Vec<_>>(), [8]);
    }
}
