//! Refinement over frames (`[pipeline] accumulate`): a stream whose scan frames carry a
//! pose keeps its last frames' level sets in the world's coordinates, and each new
//! frame's level set is averaged with theirs before its curves are drawn.
//!
//! Every frame's level set is a signed distance to its own curve (negative on the
//! sensor's side), so near a wall the frames saw, the average's zero crossing is the
//! average of their crossings: `k` frames of independent noise put the curve about
//! `sqrt k` closer to the wall. Each frame counts only near its own data (within the
//! support's tolerance of its runs of returns, fading to nothing at twice that): away
//! from them its level set says where its free space ended, not where a wall is, and
//! would drag the curves of walls it did not see.
//!
//! The average is taken on the new frame's mesh, and the curves are cut to the supports
//! of the whole window. A wall seen by earlier frames of the window stays in the
//! records while it lies within the new frame's meshed domain, even hidden from the new
//! frame; when the last frame that saw it leaves the window, it leaves the records: the
//! window is what the sensor sees now and saw a moment ago, not a map that grows
//! without bound (that is a mapping system's job, and its memory would grow with the
//! distance driven).

use std::collections::VecDeque;

use rayon::prelude::*;

use crate::fem::locate::locate;
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
        View {
            frame,
            t,
            mesh,
            u,
            analysis,
            tol,
            index,
            ends,
        }
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

    /// Bytes this view holds, roughly.
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
    }
}

/// A stream's window of views, oldest first.
#[derive(Default)]
pub struct Window {
    views: VecDeque<View>,
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
        self.views.push_back(view);
        let newest_t = self.views.back().and_then(|v| v.t);
        while self.views.len() > 1 {
            let too_old = match (limits.seconds, newest_t, self.views[0].t) {
                (Some(s), Some(now), Some(then)) => now - then > s,
                _ => false,
            };
            if self.views.len() > limits.frames.max(1) || too_old {
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

    /// Replaces `u` (at `points`, in the world's coordinates) by the weighted average of
    /// the window's level sets (`View::weight`) that lie within their tolerance of the
    /// median of them all; where none counts, or `u` is farther from zero than twice the
    /// largest tolerance, `u` stays.
    pub(crate) fn fuse(&self, points: &[Point], u: &mut [f64]) {
        const CHUNK: usize = 256;
        let views: Vec<&View> = self.views.iter().collect();
        // Far from zero `u` keeps its sign whatever the other frames say, and the
        // curves' course does not depend on it.
        let band = 2.0 * views.iter().map(|v| v.tol).fold(0.0, f64::max);
        points
            .par_chunks(CHUNK)
            .zip(u.par_chunks_mut(CHUNK))
            .for_each(|(pts, us)| {
                // Each walk starts where the previous point of the chunk was found.
                let mut hints = vec![0u32; views.len()];
                let mut found: Vec<(f64, f64, f64)> = Vec::with_capacity(views.len());
                let mut sorted: Vec<f64> = Vec::with_capacity(views.len());
                for (&p, x) in pts.iter().zip(us.iter_mut()) {
                    if x.abs() > band {
                        continue;
                    }
                    found.clear();
                    for (view, hint) in views.iter().zip(hints.iter_mut()) {
                        let w = view.weight(p);
                        if w <= 0.0 {
                            continue;
                        }
                        let at = locate(&view.mesh, p, *hint);
                        *hint = at.tri;
                        found.push((at.interpolate(&view.mesh, &view.u), w, view.tol));
                    }
                    if found.is_empty() {
                        continue;
                    }
                    // Frames farther from the frames' median than their noise allows saw
                    // something else here (a junction seen from elsewhere, a free space
                    // that turned): only the agreeing ones average.
                    sorted.clear();
                    sorted.extend(found.iter().map(|f| f.0));
                    sorted.sort_unstable_by(f64::total_cmp);
                    let median = sorted[sorted.len() / 2];
                    let (mut sum, mut total) = (0.0, 0.0);
                    for &(v, w, tol) in &found {
                        if (v - median).abs() <= tol {
                            sum += w * v;
                            total += w;
                        }
                    }
                    if total > 0.0 {
                        *x = sum / total;
                    }
                }
            });
    }
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
        let analysis = Analysis::new(scan, &crate::scan::ScanParams::default());
        View::new(frame, Some(t), mesh, u, analysis, 0.05)
    }

    /// Near the walls the frames saw, the average crossing is the average of theirs; a
    /// frame that saw the wall elsewhere (farther than its tolerance from the median) is
    /// left out; far from the curve the newest frame's value stays.
    #[test]
    fn level_sets_average_near_the_walls_the_frames_saw() {
        let limits = WindowLimits {
            frames: 10,
            seconds: None,
        };
        let mut w = Window::default();
        for (i, y) in [1.3, 1.0, 1.02, 0.98, 1.04].into_iter().enumerate() {
            w.push(wall(i as u64, i as f64, y), &limits);
        }
        let pts = [[0.0, 1.0], [0.3, 1.01], [0.0, -1.5]];
        // The newest frame's own level set: its wall is at 1.04.
        let mut u = pts.map(|p| p[1] - 1.04);
        w.fuse(&pts, &mut u);
        // The median wall is at 1.02; the mean of those within 0.05 of it is at 1.01 (P1
        // on a uniform mesh is exact for a linear field); the wall at 1.3 is left out.
        assert!((u[0] - (1.0 - 1.01)).abs() < 1e-9, "{}", u[0]);
        assert!(u[1].abs() < 1e-9, "{}", u[1]);
        assert_eq!(u[2], -1.5 - 1.04);
    }

    /// Frames leave by count and by age, and a restart empties the window.
    #[test]
    fn frames_leave_the_window_by_count_and_age() {
        let limits = WindowLimits {
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
}
