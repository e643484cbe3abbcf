//! The sensor's view of a frame: beams from a known origin, what each one saw, and what
//! follows from it (docs/method.md, scanner frames).
//!
//! A [`Scan`] holds one frame's beams in bearing order: each beam either returned (a
//! point at its range) or did not (no echo, beyond `range_max`, below `range_min`, NaN).
//! From it come:
//! - the **runs** ([`Scan::runs`]): consecutive returns that lie on one surface, split at
//!   depth jumps and gaps by the adaptive breakpoint test (Borges & Aldon 2004): two
//!   returns `dphi` apart in bearing belong together when they are closer than
//!   `r sin(dphi) / sin(lambda - dphi) + 3 sigma sqrt(2)`, the spacing of a surface
//!   seen at incidence `90 - lambda` degrees, plus the range noise;
//! - the **free space** ([`Scan::free_space`]): the star-shaped polygon swept by the
//!   rays, from the origin to each return, and to `range_max` along a beam that returned
//!   nothing; a beam with no return between two returns of one run is a dropout, not a
//!   hole in the surface, and is closed at the run's range;
//! - the **scales** ([`Scan::scales`]): the range noise, estimated from how far each
//!   return lies off the chord of its neighbours, and the beam spacing, `r dphi`.
//!
//! Everything here is in the frame's coordinates: the sensor at `origin`, bearings
//! counter-clockwise from the x axis.

use std::f64::consts::TAU;

use crate::error::{Error, Result};
use crate::field::{MeshParams, MetricField};
use crate::geom::{add, dist, point_segment_dist2, sub, Placement, Point, Polyline};

mod deskew;
pub use deskew::{velocity, Sweep};

/// The most beams a scan may have. 2D scanners have up to a few thousand (36,000 at a
/// hundredth of a degree over a full turn); the bound keeps a forged message's beam
/// count from deciding how much memory a frame takes.
pub const MAX_BEAMS: usize = 1 << 16;

/// How far short of its return a beam saw through a curve's place, for a frame of
/// range noise `noise` meshed down to `hmin`: the curves' accuracy bound, `3 noise +
/// 2 hmin`. The return's surface lies nearer than three noises with a chance of one in
/// 740 (Gaussian noise), and a curve is placed to within two elements of its level set
/// (the P1 isoline rounds the free space's corners, where a wall ends at the field of
/// view's edge, by about one).
pub(crate) fn seen_margin(noise: f64, hmin: f64) -> f64 {
    3.0 * noise + 2.0 * hmin
}

/// Returns a side of the line that smooths a return along its run: four smooth a
/// frame's noise along its runs and still follow the turn of a wall within a few beams.
pub const SMOOTHING: usize = 4;

/// A scan's runs and scales as the pipeline reads them ([`Scan::run_returns`]): what a
/// caller needs to lay other returns onto its surfaces.
#[derive(Clone, Debug, PartialEq)]
pub struct RunReturns {
    /// Each run's returns, in bearing order.
    pub runs: Vec<Vec<Point>>,
    /// The range noise (the configured one, or the frame's estimate).
    pub noise: f64,
    /// The median beam spacing, `r dphi`.
    pub spacing: f64,
}

/// How scan frames are read: the breakpoint test, dropouts and small clusters.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub struct ScanParams {
    /// Range noise (standard deviation, data units). Default: estimated per frame from
    /// the returns (`Scan::scales`).
    pub range_noise: Option<f64>,
    /// The breakpoint test's `lambda`, in degrees: consecutive returns stay on one
    /// surface while it is seen at incidence below `90 - lambda`. Default 10.
    pub incidence_limit: f64,
    /// Runs of fewer returns are features (legs, clutter), not curves. Default 3.
    pub min_run: usize,
    /// At most this many consecutive beams without a return inside a run are dropouts
    /// rather than gaps. Default 2.
    pub dropout_beams: usize,
    /// Set by the daemon's refinement over frames (`[pipeline] accumulate`), not a key
    /// of `[scan]`: the window's average takes the noise down, so the refined curves'
    /// corners are sharpened along their walls' lines.
    pub refine: bool,
}

impl Default for ScanParams {
    fn default() -> Self {
        ScanParams {
            range_noise: None,
            incidence_limit: 10.0,
            min_run: 3,
            dropout_beams: 2,
            refine: false,
        }
    }
}

impl ScanParams {
    /// The same parameters with every length multiplied by `s` (into other units).
    pub fn scaled(&self, s: f64) -> ScanParams {
        ScanParams {
            range_noise: self.range_noise.map(|x| x * s),
            ..self.clone()
        }
    }

    /// Checks the values; every problem is listed with its key in `[scan]`.
    pub fn validate(&self) -> std::result::Result<(), Vec<String>> {
        let mut problems = Vec::new();
        crate::error::check_positive(&mut problems, "scan.range_noise", self.range_noise);
        if !(self.incidence_limit > 0.0 && self.incidence_limit < 90.0) {
            problems.push(format!(
                "scan.incidence_limit = {}: must be in (0, 90) degrees",
                self.incidence_limit
            ));
        }
        if !(1..=1000).contains(&self.min_run) {
            problems.push(format!(
                "scan.min_run = {}: must be in 1..=1000",
                self.min_run
            ));
        }
        if self.dropout_beams > 100 {
            problems.push(format!(
                "scan.dropout_beams = {}: must be at most 100",
                self.dropout_beams
            ));
        }
        if problems.is_empty() {
            Ok(())
        } else {
            Err(problems)
        }
    }
}

/// One frame's beams, in increasing bearing.
#[derive(Clone, Debug, PartialEq)]
pub struct Scan {
    /// The sensor's position, in the frame's coordinates.
    pub origin: Point,
    /// Each beam's bearing in radians, counter-clockwise from the frame's x axis,
    /// strictly increasing over less than a full turn plus one step.
    pub angles: Vec<f64>,
    /// Each beam's range, NaN where it returned nothing.
    pub ranges: Vec<f64>,
    /// Returns beyond this are no returns; a beam without one is free up to it.
    pub range_max: f64,
    /// The angular step between beams (radians, positive): the sensor's, or for points
    /// given around an origin the median step between their bearings.
    pub step: f64,
    /// Whether a beam without a return is evidence of free space (a sensor's beams), or
    /// the frame had only points, whose bearing gaps say nothing: they are treated as
    /// unseen.
    pub free_rays: bool,
}

/// A set of beams like a ROS `sensor_msgs/LaserScan` message, in the frame's coordinates.
#[derive(Clone, Debug, PartialEq)]
pub struct LaserScan<'a> {
    /// The sensor's position in the frame.
    pub origin: Point,
    /// Bearing of the first beam, radians.
    pub angle_min: f64,
    /// Angle between beams, radians (negative for a clockwise sweep).
    pub angle_increment: f64,
    /// Ranges, `None` (JSON `null`, the sensor's NaN or inf) where there was no return.
    pub ranges: &'a [Option<f64>],
    /// Returns nearer than this are no returns.
    pub range_min: f64,
    /// Returns at or beyond this are no returns.
    pub range_max: f64,
}

/// Consecutive returns on one surface: indices into [`Scan::returns`] order.
#[derive(Clone, Debug, PartialEq)]
pub struct Run {
    /// Indices of the beams in the run, in bearing order (valid returns only).
    pub beams: Vec<u32>,
}

/// Noise and sampling scales of a scan.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Scales {
    /// Range noise: the configured value or the estimate.
    pub noise: f64,
    /// The estimate from the returns (the median deviation from their neighbours'
    /// chord), `None` when fewer than 8 returns have two neighbours in their run.
    pub noise_estimate: Option<f64>,
    /// The median distance between neighbouring beams at the returns' ranges, `r dphi`.
    pub spacing: f64,
}

impl Scan {
    /// Its runs' returns, range noise and beam spacing, read with `params` as a frame's
    /// reconstruction reads them.
    pub fn run_returns(&self, params: &ScanParams) -> RunReturns {
        let a = Analysis::new(self.clone(), params);
        RunReturns {
            runs: a.run_points(),
            noise: a.scales.noise,
            spacing: a.scales.spacing,
        }
    }

    /// A scan from a sensor's beams. Ranges outside `[range_min, range_max)` or not
    /// finite are no returns. Fails when the message is malformed: no beams, a step that
    /// is zero, not finite or sweeps more than a turn, or a bad range limit.
    pub fn from_laser(l: &LaserScan<'_>) -> Result<Scan> {
        let bad = Error::Scan;
        let n = l.ranges.len();
        if n == 0 {
            return Err(bad("\"ranges\" is empty".into()));
        }
        if n > MAX_BEAMS {
            return Err(bad(format!(
                "{n} beams: more than the {MAX_BEAMS} a scan may have"
            )));
        }
        if !(l.angle_increment.is_finite() && l.angle_increment != 0.0) {
            return Err(bad(format!(
                "angle_increment = {}: must be finite and not zero",
                l.angle_increment
            )));
        }
        if !l.angle_min.is_finite() || l.angle_min.abs() > 1e3 {
            return Err(bad(format!(
                "angle_min = {}: must be a finite angle in radians",
                l.angle_min
            )));
        }
        let sweep = l.angle_increment.abs() * (n - 1) as f64;
        if sweep > TAU + 1e-6 {
            return Err(bad(format!(
                "{n} beams {} rad apart sweep {sweep:.3} rad, more than a turn",
                l.angle_increment
            )));
        }
        if !(l.range_max.is_finite() && l.range_max > 0.0 && l.range_max <= 1e9) {
            return Err(bad(format!(
                "range_max = {}: must be positive and finite",
                l.range_max
            )));
        }
        if !(l.range_min.is_finite() && l.range_min >= 0.0 && l.range_min < l.range_max) {
            return Err(bad(format!(
                "range_min = {}: must be in [0, range_max)",
                l.range_min
            )));
        }
        if !(l.origin[0].is_finite() && l.origin[1].is_finite())
            || l.origin[0].abs().max(l.origin[1].abs()) > crate::distance::MAX_COORDINATE
        {
            return Err(bad(format!("origin {:?} is not a finite point", l.origin)));
        }
        let valid = |r: Option<f64>| match r {
            Some(r) if r.is_finite() && r >= l.range_min && r < l.range_max => r,
            _ => f64::NAN,
        };
        let mut angles: Vec<f64> = (0..n)
            .map(|i| l.angle_min + i as f64 * l.angle_increment)
            .collect();
        let mut ranges: Vec<f64> = l.ranges.iter().map(|&r| valid(r)).collect();
        if l.angle_increment < 0.0 {
            angles.reverse();
            ranges.reverse();
        }
        Ok(Scan {
            origin: l.origin,
            angles,
            ranges,
            range_max: l.range_max,
            step: l.angle_increment.abs(),
            free_rays: true,
        })
    }

    /// A scan from points seen from `origin`: each point is a return on its own beam,
    /// in order of bearing; bearing gaps carry no free-space evidence. Points at the
    /// origin itself are dropped (they have no bearing).
    pub fn from_points(points: &[Point], origin: Point) -> Scan {
        let mut beams: Vec<(f64, f64)> = points
            .iter()
            .map(|&p| {
                let d = sub(p, origin);
                (d[1].atan2(d[0]), dist(p, origin))
            })
            .filter(|&(_, r)| r > 0.0)
            .collect();
        beams.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
        // Points on one bearing: the nearest is the return, the others lie behind it and
        // could not have been seen; keep them all as beams a hair apart in bearing, so
        // that every point stays a return.
        for i in 1..beams.len() {
            if beams[i].0 <= beams[i - 1].0 {
                beams[i].0 = next_up(beams[i - 1].0);
            }
        }
        let mut gaps: Vec<f64> = beams.windows(2).map(|w| w[1].0 - w[0].0).collect();
        let step = if gaps.is_empty() {
            1e-3
        } else {
            let mid = gaps.len() / 2;
            *gaps.select_nth_unstable_by(mid, f64::total_cmp).1
        }
        .max(1e-9);
        let range_max = beams.iter().map(|b| b.1).fold(0.0, f64::max) * 1.5 + 1e-300;
        Scan {
            origin,
            angles: beams.iter().map(|b| b.0).collect(),
            ranges: beams.iter().map(|b| b.1).collect(),
            range_max,
            step,
            free_rays: false,
        }
    }

    /// The same scan in the local coordinates of `at` (lengths scaled with them).
    pub(crate) fn placed(&self, at: &Placement) -> Scan {
        Scan {
            origin: at.to_local(self.origin),
            ranges: self.ranges.iter().map(|&r| at.len_to_local(r)).collect(),
            range_max: at.len_to_local(self.range_max),
            ..self.clone()
        }
    }

    /// Whether beam `i` returned.
    #[inline]
    pub fn valid(&self, i: usize) -> bool {
        !self.ranges[i].is_nan()
    }

    /// The unit direction of beam `i`.
    #[inline]
    pub fn direction(&self, i: usize) -> Point {
        let (s, c) = self.angles[i].sin_cos();
        [c, s]
    }

    /// The point at range `r` on beam `i`.
    #[inline]
    pub fn at(&self, i: usize, r: f64) -> Point {
        let d = self.direction(i);
        add(self.origin, [r * d[0], r * d[1]])
    }

    /// Beam indices of the returns, in bearing order.
    pub fn return_beams(&self) -> Vec<u32> {
        (0..self.ranges.len())
            .filter(|&i| self.valid(i))
            .map(|i| i as u32)
            .collect()
    }

    /// The returns as points, in bearing order.
    pub fn returns(&self) -> Vec<Point> {
        (0..self.ranges.len())
            .filter(|&i| self.valid(i))
            .map(|i| self.at(i, self.ranges[i]))
            .collect()
    }

    /// Whether the beams cover a whole turn (the last beam is a neighbour of the first).
    pub fn full_turn(&self) -> bool {
        match (self.angles.first(), self.angles.last()) {
            (Some(a), Some(b)) => b - a + 1.5 * self.step >= TAU,
            _ => false,
        }
    }

    /// Bearing difference from beam `i` to beam `j` (j after i, wrapping on a full turn).
    fn gap(&self, i: usize, j: usize) -> f64 {
        let d = self.angles[j] - self.angles[i];
        if d < 0.0 {
            d + TAU
        } else {
            d
        }
    }

    /// Whether the returns of beams `i` and `j` lie on one surface by the adaptive
    /// breakpoint test (see the module doc), `sigma` the range noise and `lambda` in
    /// radians.
    pub(crate) fn joined(&self, i: usize, j: usize, sigma: f64, lambda: f64) -> bool {
        let dphi = self.gap(i, j);
        if dphi >= lambda {
            return false;
        }
        let (ri, rj) = (self.ranges[i], self.ranges[j]);
        let reach = ri.min(rj) * dphi.sin() / (lambda - dphi).sin()
            + 3.0 * std::f64::consts::SQRT_2 * sigma;
        dist(self.at(i, ri), self.at(j, rj)) <= reach
    }

    /// The runs: consecutive returns joined by the breakpoint test, across at most
    /// `params.dropout_beams` beams without a return, in bearing order; on a full turn a
    /// run may wrap from the last beams to the first.
    pub(crate) fn runs(&self, sigma: f64, params: &ScanParams) -> Vec<Run> {
        let lambda = params.incidence_limit.to_radians();
        let beams = self.return_beams();
        let mut runs: Vec<Run> = Vec::new();
        for (k, &b) in beams.iter().enumerate() {
            let joined = k > 0 && {
                let a = beams[k - 1];
                (b - a - 1) as usize <= params.dropout_beams
                    && self.joined(a as usize, b as usize, sigma, lambda)
            };
            if joined {
                runs.last_mut().expect("a run before").beams.push(b);
            } else {
                runs.push(Run { beams: vec![b] });
            }
        }
        if runs.len() > 1 && self.full_turn() {
            let (first, last) = (beams[0], *beams.last().expect("returns"));
            let skipped = (self.angles.len() as u32 - 1 - last) + first;
            if skipped as usize <= params.dropout_beams
                && self.joined(last as usize, first as usize, sigma, lambda)
            {
                let head = runs.remove(0);
                runs.last_mut().expect("a run").beams.extend(head.beams);
            }
        }
        runs
    }

    /// Range noise and beam spacing. The noise estimate: each return with both
    /// neighbours in its run lies off their chord by about its own noise across the
    /// surface (a straight surface; the chord error of a curved one is second order in
    /// the spacing), which is the range noise times the cosine of the incidence. For
    /// independent noise, that offset divided by the cosine has deviation
    /// `sigma sqrt(1.5)`, and its median absolute value is `0.6745` of that. Returns seen
    /// at more than 60 degrees of incidence, where the cosine amplifies the chord's own
    /// error, are left out unless too few remain.
    pub(crate) fn scales(&self, runs: &[Run], params: &ScanParams) -> Scales {
        let mut offsets: Vec<f64> = Vec::new();
        let mut grazing: Vec<f64> = Vec::new();
        for run in runs {
            for w in run.beams.windows(3) {
                let [a, b, c] =
                    [w[0], w[1], w[2]].map(|i| self.at(i as usize, self.ranges[i as usize]));
                let off = point_segment_dist2(b, a, c).0.sqrt();
                let chord = sub(c, a);
                let len = crate::geom::norm(chord);
                if len <= 0.0 {
                    continue;
                }
                // Cosine of the incidence: the beam against the chord's normal.
                let beam = self.direction(w[1] as usize);
                let cos = (crate::geom::cross(beam, chord) / len).abs();
                if cos >= 0.5 {
                    offsets.push(off / cos);
                } else {
                    grazing.push(off / cos.max(1e-3));
                }
            }
        }
        if offsets.len() < 8 {
            offsets.append(&mut grazing);
        }
        // Ranges rounded to a step `q` (some scanners and logs keep 5 cm) are off by up
        // to `q / 2`, uniformly: a deviation of `q / sqrt 12` at least. Where the noise
        // is well below the step, a flat wall's returns round to the same step and lie
        // exactly on their neighbours' chord, and the chords would see no noise at all.
        let rounding = self.range_resolution() / 12f64.sqrt();
        let noise_estimate = (offsets.len() >= 8).then(|| {
            let mid = offsets.len() / 2;
            let m = *offsets.select_nth_unstable_by(mid, f64::total_cmp).1;
            (m / (0.6745 * 1.5f64.sqrt())).max(rounding)
        });
        let mut spacing: Vec<f64> = self
            .ranges
            .iter()
            .filter(|r| !r.is_nan())
            .map(|r| r * self.step)
            .collect();
        let spacing = if spacing.is_empty() {
            0.0
        } else {
            let mid = spacing.len() / 2;
            *spacing.select_nth_unstable_by(mid, f64::total_cmp).1
        };
        Scales {
            noise: params
                .range_noise
                .or(noise_estimate)
                .unwrap_or(0.25 * spacing),
            noise_estimate,
            spacing,
        }
    }

    /// The step the ranges are rounded to: the smallest difference between two of
    /// their distinct values (values within a relative `1e-9` of each other are one, so
    /// that a step's float multiples count once). On ranges not rounded it is far below
    /// their noise.
    fn range_resolution(&self) -> f64 {
        let mut r: Vec<f64> = self
            .ranges
            .iter()
            .copied()
            .filter(|r| r.is_finite())
            .collect();
        r.sort_by(f64::total_cmp);
        let Some(&far) = r.last() else {
            return 0.0;
        };
        let same = 1e-9 * far.abs();
        r.windows(2)
            .map(|w| w[1] - w[0])
            .filter(|&d| d > same)
            .reduce(f64::min)
            .unwrap_or(0.0)
    }

    /// How far each beam saw free space: its range where it returned; inside a run, a
    /// dropout's range interpolated between its neighbours; between two runs, a stretch
    /// of at most `dropout_beams` beams without a return reaches the nearer of the two
    /// (a dropout next to a corner or a depth jump, whose beam may well have hit the
    /// near surface, must not pierce it as a thin ray of free space: claiming too little
    /// free space costs nothing, the curve there is cut anyway); `range_max` on the
    /// other beams with no return (or 0, unseen, when the scan has no free rays).
    ///
    /// A return's range is taken from `ranges` (the scan's own, or
    /// [`smoothed_ranges`](Self::smoothed_ranges)).
    pub(crate) fn reach(&self, runs: &[Run], dropout_beams: usize, ranges: &[f64]) -> Vec<f64> {
        let n = self.angles.len();
        let free = if self.free_rays { self.range_max } else { 0.0 };
        let mut reach: Vec<f64> = (0..n)
            .map(|i| if self.valid(i) { ranges[i] } else { free })
            .collect();
        // Short stretches without a return between two returns.
        let beams = self.return_beams();
        let pairs = beams.windows(2).map(|w| (w[0], w[1]));
        let wrap = (self.full_turn() && beams.len() > 1)
            .then(|| (*beams.last().expect("returns"), beams[0]));
        for (a, b) in pairs.chain(wrap) {
            let (a, b) = (a as usize, b as usize);
            let missing: Vec<usize> = if b > a {
                (a + 1..b).collect()
            } else {
                (a + 1..n).chain(0..b).collect()
            };
            if !missing.is_empty() && missing.len() <= dropout_beams {
                let near = ranges[a].min(ranges[b]);
                for i in missing {
                    reach[i] = near;
                }
            }
        }
        for run in runs {
            for w in run.beams.windows(2) {
                let (a, b) = (w[0] as usize, w[1] as usize);
                let missing: Vec<usize> = if b > a {
                    (a + 1..b).collect()
                } else {
                    (a + 1..n).chain(0..b).collect()
                };
                let m = missing.len() as f64 + 1.0;
                for (k, &i) in missing.iter().enumerate() {
                    let f = (k + 1) as f64 / m;
                    reach[i] = ranges[a] * (1.0 - f) + ranges[b] * f;
                }
            }
        }
        reach
    }

    /// The ranges of the returns with their noise smoothed along each run: a return
    /// moves along its beam onto the line fitted to its run neighbours (up to `window`
    /// on either side, or ending at the return where the window round it straddles a
    /// corner), unless the beam meets that line at a grazing angle (beyond 75 degrees)
    /// or the move exceeds `3 sigma` (shape the line does not follow). NaN where the
    /// beam returned nothing.
    ///
    /// The free space through the raw returns zigzags across the noise band at every
    /// beam; on a mesh whose elements are long along the walls that zigzag folds the
    /// P1 zero isoline back on itself. Through the smoothed returns it runs straight.
    pub(crate) fn smoothed_ranges(&self, runs: &[Run], window: usize, sigma: f64) -> Vec<f64> {
        let mut out = self.ranges.clone();
        for run in runs {
            let pts: Vec<Point> = run
                .beams
                .iter()
                .map(|&b| self.at(b as usize, self.ranges[b as usize]))
                .collect();
            let m = pts.len();
            if m < 3 {
                continue;
            }
            // The total-least-squares line of `pts[lo..hi]`: its centroid, direction,
            // and mean square residual (the smaller scatter eigenvalue over the
            // degrees of freedom a line leaves).
            let line = |lo: usize, hi: usize| {
                let w = &pts[lo..hi];
                let inv = 1.0 / w.len() as f64;
                let c = w
                    .iter()
                    .fold([0.0, 0.0], |s, p| add(s, [p[0] * inv, p[1] * inv]));
                let mut cov = crate::geom::Sym2::default();
                for p in w {
                    cov = cov.plus(crate::geom::Sym2::outer(sub(*p, c)));
                }
                let (_, small, t) = cov.eigen();
                (c, t, small / (w.len() as f64 - 2.0).max(1.0))
            };
            for (k, &b) in run.beams.iter().enumerate() {
                let centred = line(k.saturating_sub(window), (k + window + 1).min(m));
                // A window that straddles a corner fits neither wall: where a window
                // ending at the return fits its side significantly better (an F test
                // at 95% on the residuals, F(7, 7) = 3.79 for four returns a side), the
                // return is smoothed along that side, as edge-preserving filters choose
                // the stencil that does not cross the edge. On a straight wall the
                // centred window stays: it places the return best.
                let sides = [
                    (k >= window).then(|| line(k.saturating_sub(2 * window), k + 1)),
                    (k + window < m).then(|| line(k, (k + 2 * window + 1).min(m))),
                ];
                let (c, t, _) = sides
                    .into_iter()
                    .flatten()
                    .filter(|side| 3.79 * side.2 < centred.2)
                    .min_by(|a, b| a.2.total_cmp(&b.2))
                    .unwrap_or(centred);
                let d = self.direction(b as usize);
                let den = crate::geom::cross(d, t);
                if den.abs() < 0.25 {
                    continue;
                }
                let r = crate::geom::cross(sub(c, self.origin), t) / den;
                let raw = self.ranges[b as usize];
                if r > 0.0 && (r - raw).abs() <= 3.0 * sigma {
                    out[b as usize] = r;
                }
            }
        }
        out
    }

    /// The free space swept by the rays, as far as [`reach`](Self::reach) says (with
    /// `ranges` for the returns): each pair of neighbouring beams sweeps the triangle from
    /// the origin to their reaches. A bearing gap wider than three steps in a scan made
    /// from points is unseen.
    pub(crate) fn free_space(
        &self,
        runs: &[Run],
        dropout_beams: usize,
        ranges: &[f64],
    ) -> FreeSpace {
        FreeSpace {
            origin: self.origin,
            angles: self.angles.clone(),
            reach: self.reach(runs, dropout_beams, ranges),
            full_turn: self.full_turn(),
            max_gap: if self.free_rays {
                f64::INFINITY
            } else {
                3.0 * self.step
            },
        }
    }
}

/// What the stages need of a scan frame, worked out once by the distance stage.
#[derive(Clone, Debug, PartialEq)]
pub struct Analysis {
    /// The scan.
    pub scan: Scan,
    /// Its runs.
    pub runs: Vec<Run>,
    /// Its noise and sampling scales.
    pub scales: Scales,
    /// The free space its rays swept.
    pub free: FreeSpace,
    /// The space its beams swept up to their own ranges (not smoothed): less
    /// [`seen_margin`], what they certainly crossed, where no curve may cross a beam.
    pub seen: FreeSpace,
    /// Runs with at least `min_run` returns, as open polylines through their returns
    /// smoothed along the run ([`Scan::smoothed_ranges`]; a run that wraps all the way
    /// round a full turn closes): where curves may run.
    pub support: Vec<Polyline>,
    /// Analysed for refinement over frames ([`ScanParams::refine`]).
    pub refine: bool,
}

impl Analysis {
    /// Runs, scales, free space and support of `scan`. The runs are found twice: first
    /// with a generous noise (half the beam spacing, or the configured noise) to estimate
    /// the noise from, then with the estimate.
    pub fn new(scan: Scan, params: &ScanParams) -> Analysis {
        let first = {
            let spacing = scan.scales(&[], params).spacing;
            let sigma = params.range_noise.unwrap_or(0.5 * spacing);
            scan.runs(sigma, params)
        };
        let scales = scan.scales(&first, params);
        let runs = if params.range_noise.is_some() {
            first
        } else {
            scan.runs(scales.noise, params)
        };
        // Four returns a side smooth a frame's noise along its runs. A refined frame is
        // analysed alike: its own level set is the one the window must beat.
        let smooth = scan.smoothed_ranges(&runs, SMOOTHING, scales.noise);
        let free = scan.free_space(&runs, params.dropout_beams, &smooth);
        let seen = scan.free_space(&runs, params.dropout_beams, &scan.ranges);
        let n = scan.angles.len();
        let support = runs
            .iter()
            .filter(|r| r.beams.len() >= params.min_run)
            .map(|r| {
                let points: Vec<Point> = r
                    .beams
                    .iter()
                    .map(|&b| scan.at(b as usize, smooth[b as usize]))
                    .collect();
                // Closed only when the run goes round the whole turn back to its start.
                let closed = runs.len() == 1
                    && scan.full_turn()
                    && r.beams.len() >= 3
                    && scan.return_beams().len() == r.beams.len()
                    && {
                        let (a, b) = (*r.beams.last().expect("beams"), r.beams[0]);
                        let skipped = (n as u32 - 1 - a) + b;
                        skipped as usize <= params.dropout_beams
                            && scan.joined(
                                a as usize,
                                b as usize,
                                scales.noise,
                                params.incidence_limit.to_radians(),
                            )
                    };
                Polyline { closed, points }
            })
            .collect();
        Analysis {
            scan,
            runs,
            scales,
            free,
            seen,
            support,
            refine: params.refine,
        }
    }

    /// The mesh parameters for this scan from the configured ones: sizes from the sensor.
    /// Far from the sensor the beams are sparse, but the noise is the range noise
    /// everywhere: `hmin` resolves the noise band, or where the beams are denser than
    /// that a quarter of their spacing (at least `1e-4 diag`, so that a noiseless, dense
    /// scan does not mesh without bound). The curve starts on the data, so the fine band
    /// only holds the noise band and the settle's moves (`4 hmin`), and the mesh may
    /// coarsen faster away from it (gradation 0.6). Set values win.
    pub fn mesh_params(&self, mesh: &MeshParams, diag: f64) -> MeshParams {
        let mut p = mesh.clone();
        let s = &self.scales;
        let hmin = p
            .hmin
            .unwrap_or_else(|| s.noise.max(0.25 * s.spacing).max(1e-4 * diag));
        p.hmin = Some(hmin);
        p.band = Some(p.band.unwrap_or(4.0 * hmin));
        p.gradation = Some(p.gradation.unwrap_or(0.6));
        p
    }

    /// The distance field of this scan's band: only the runs long enough to become
    /// curves are meshed (a lone return, a spurious echo or a far table leg, is a
    /// feature), each sample with its chain window along its run (8 returns a side span
    /// the local shape without reaching across a corner), which the settle takes its
    /// median over. A scan with no such run falls back to the field of all its returns
    /// (`points`), adapted as a point cloud's.
    pub fn metric_field(&self, params: &MeshParams, points: &[Point]) -> Result<MetricField> {
        let chains: Vec<Vec<Point>> = self.support.iter().map(|pl| pl.points.clone()).collect();
        if chains.iter().map(Vec::len).sum::<usize>() < 2 {
            return MetricField::new(points, params);
        }
        let mut m = MetricField::of_chains(&chains, params, 8)?;
        m.noise_estimate = self.scales.noise;
        m.one_wall_noise = self.scales.noise;
        Ok(m)
    }

    /// How many returns lie in runs of at least `min_run` returns: those a curve should
    /// explain (the others are features by design).
    pub(crate) fn supported(&self, min_run: usize) -> usize {
        self.runs
            .iter()
            .map(|r| r.beams.len())
            .filter(|&n| n >= min_run)
            .sum()
    }

    /// The free space's origin and polygon, placed into data coordinates by `at`.
    pub(crate) fn free_space_in(&self, at: &crate::geom::Placement) -> (Point, Polyline) {
        let mut poly = self.free.polygon();
        poly.points.iter_mut().for_each(|p| *p = at.to_data(*p));
        (at.to_data(self.free.origin), poly)
    }

    /// Each run's returns, in bearing order.
    pub fn run_points(&self) -> Vec<Vec<Point>> {
        self.runs
            .iter()
            .map(|r| {
                r.beams
                    .iter()
                    .map(|&b| self.scan.at(b as usize, self.scan.ranges[b as usize]))
                    .collect()
            })
            .collect()
    }
}

/// Where the line through `p` and `q` meets the line through `c` and `d`: the fractions
/// `(s, t)` of the two, `p + s (q - p) = c + t (d - c)`; `None` where they are parallel.
fn meet(p: Point, q: Point, c: Point, d: Point) -> Option<(f64, f64)> {
    let (e, f) = (sub(q, p), sub(d, c));
    let den = crate::geom::cross(e, f);
    if den == 0.0 {
        return None;
    }
    let g = sub(c, p);
    Some((
        crate::geom::cross(g, f) / den,
        crate::geom::cross(g, e) / den,
    ))
}

/// Where the segment from `p` to `q` meets the segment from `c` to `d`, as a fraction of
/// the first.
fn segment_parameter(p: Point, q: Point, c: Point, d: Point) -> Option<f64> {
    let (s, t) = meet(p, q, c, d)?;
    ((0.0..=1.0).contains(&s) && (0.0..=1.0).contains(&t)).then_some(s)
}

/// Where the segment from `p` to `q` crosses the ray from `origin` at `bearing`, as a
/// fraction of the segment.
fn ray_parameter(p: Point, q: Point, origin: Point, bearing: f64) -> Option<f64> {
    let (sin, cos) = bearing.sin_cos();
    let (s, t) = meet(p, q, origin, add(origin, [cos, sin]))?;
    (t > 0.0 && (0.0..=1.0).contains(&s)).then_some(s)
}

/// The next float above `x` (towards +inf).
fn next_up(x: f64) -> f64 {
    if x.is_nan() || x == f64::INFINITY {
        return x;
    }
    let bits = x.to_bits();
    let next = if x == 0.0 {
        1
    } else if x > 0.0 {
        bits + 1
    } else {
        bits - 1
    };
    f64::from_bits(next).max(x + x.abs() * 1e-15)
}

/// The star-shaped free space of a scan.
#[derive(Clone, Debug, PartialEq)]
pub struct FreeSpace {
    /// The sensor.
    pub origin: Point,
    /// Beam bearings, increasing.
    pub angles: Vec<f64>,
    /// How far each beam saw free space (0: unseen).
    pub reach: Vec<f64>,
    /// Whether the last beam neighbours the first.
    pub full_turn: bool,
    /// Neighbouring beams farther apart than this sweep nothing between them.
    pub max_gap: f64,
}

impl FreeSpace {
    /// Whether `p` lies in the free space: between two neighbouring beams (of bearings
    /// around `p`'s), on the origin's side of the segment joining their reaches.
    pub fn contains(&self, p: Point) -> bool {
        self.contains_by(p, |i| self.point(i, self.reach[i]))
    }

    /// Each beam's reach as a point, to test many points without their sines and
    /// cosines.
    fn tips(&self) -> Vec<Point> {
        (0..self.angles.len())
            .map(|i| self.point(i, self.reach[i]))
            .collect()
    }

    fn contains_by(&self, p: Point, tip: impl Fn(usize) -> Point) -> bool {
        match self.bearing(p) {
            None => !self.angles.is_empty() && self.reach.iter().any(|&r| r > 0.0),
            Some(b) => self.contains_at(p, &b, tip),
        }
    }

    /// Where `p` lies as seen from the origin; `None` at the origin or without beams.
    fn bearing(&self, p: Point) -> Option<Bearing> {
        let n = self.angles.len();
        let d = sub(p, self.origin);
        if n == 0 || d == [0.0, 0.0] {
            return None;
        }
        let a0 = self.angles[0];
        // Bring phi into [a0, a0 + 2 pi).
        let phi = a0 + (d[1].atan2(d[0]) - a0).rem_euclid(TAU);
        Some(Bearing {
            rho: crate::geom::norm(d),
            phi,
            next: self.angles.partition_point(|&a| a <= phi),
        })
    }

    /// [`contains`](Self::contains) for `p` at bearing `b`.
    fn contains_at(&self, p: Point, b: &Bearing, tip: impl Fn(usize) -> Point) -> bool {
        let n = self.angles.len();
        let (phi, k) = (b.phi, b.next);
        let (i, j) = if k == 0 {
            return false;
        } else if k < n {
            (k - 1, k)
        } else if self.full_turn {
            (n - 1, 0)
        } else {
            // Past the last beam: inside only on it (within rounding).
            return phi - self.angles[n - 1] <= 1e-12 && b.rho < self.reach[n - 1];
        };
        let gap = (self.angles[j] - self.angles[i]).rem_euclid(TAU);
        if gap > self.max_gap {
            return false;
        }
        let (ri, rj) = (self.reach[i], self.reach[j]);
        if ri <= 0.0 || rj <= 0.0 {
            return false;
        }
        let (a, b) = (tip(i), tip(j));
        // The origin's side of a -> b (the triangle origin, a, b is counter-clockwise).
        crate::geom::orient(a, b, p) > 0.0
    }

    /// The same free space with every beam's reach less `by` (none below 0).
    pub(crate) fn shrunk(&self, by: f64) -> FreeSpace {
        FreeSpace {
            reach: self.reach.iter().map(|r| (r - by).max(0.0)).collect(),
            ..self.clone()
        }
    }

    /// How far `p` lies inside the free space along its own bearing: the range at which
    /// the ray from the origin through `p` leaves it (where it meets the segment joining
    /// the reaches of the two beams round it), less `p`'s range; negative beyond that.
    /// `None` where no two neighbouring beams sweep `p`'s bearing (outside the field of
    /// view, across a wide gap, beside an unseen beam) or at the origin.
    pub fn depth(&self, p: Point) -> Option<f64> {
        self.depth_by(p, |i| self.point(i, self.reach[i]))
    }

    fn depth_by(&self, p: Point, tip: impl Fn(usize) -> Point) -> Option<f64> {
        let b = self.bearing(p)?;
        let n = self.angles.len();
        let (i, j) = match b.next {
            0 => return None,
            k if k < n => (k - 1, k),
            _ if self.full_turn => (n - 1, 0),
            // Past the last beam: only the last beam itself, or the first one a rounding
            // put a turn round, was seen (within rounding).
            _ => {
                let on = if b.phi - self.angles[n - 1] <= 1e-12 {
                    n - 1
                } else if self.angles[0] + TAU - b.phi <= 1e-12 {
                    0
                } else {
                    return None;
                };
                return (self.reach[on] > 0.0).then(|| self.reach[on] - b.rho);
            }
        };
        let gap = (self.angles[j] - self.angles[i]).rem_euclid(TAU);
        if gap > self.max_gap || self.reach[i] <= 0.0 || self.reach[j] <= 0.0 {
            return None;
        }
        let (a, c) = (tip(i), tip(j));
        let d = sub(p, self.origin);
        let e = sub(c, a);
        let den = crate::geom::cross(d, e);
        if den == 0.0 {
            return None;
        }
        // The ray o + t d meets a + s e at t = cross(a - o, e) / cross(d, e), in units of
        // |d| = rho.
        let t = crate::geom::cross(sub(a, self.origin), e) / den;
        Some((t - 1.0) * b.rho)
    }

    /// The parameters `s` in `(0, 1)` at which the segment from `a` to `b` crosses a beam
    /// or the segment joining two neighbouring beams' reaches, appended to `out` in no
    /// order: between two of them the segment lies wholly in the free space or wholly
    /// out of it.
    pub(crate) fn crossings(&self, a: Point, b: Point, out: &mut Vec<f64>) {
        let (Some(ba), Some(bb)) = (self.bearing(a), self.bearing(b)) else {
            return;
        };
        let n = self.angles.len();
        // The segment sweeps the bearings between its ends the shorter way round.
        let ccw = (bb.phi - ba.phi).rem_euclid(TAU);
        let (from, sweep, flip) = if ccw <= std::f64::consts::PI {
            (ba, ccw, false)
        } else {
            (bb, TAU - ccw, true)
        };
        let (p, q) = if flip { (b, a) } else { (a, b) };
        let mut push = |s: Option<f64>| {
            if let Some(s) = s.filter(|s| *s > 0.0 && *s < 1.0) {
                out.push(if flip { 1.0 - s } else { s });
            }
        };
        let chord = |i: usize, j: usize, push: &mut dyn FnMut(Option<f64>)| {
            if i < n && j < n && self.reach[i] > 0.0 && self.reach[j] > 0.0 {
                let (c, d) = (self.point(i, self.reach[i]), self.point(j, self.reach[j]));
                push(segment_parameter(p, q, c, d));
            }
        };
        let next = |k: usize| {
            if k + 1 < n {
                Some(k + 1)
            } else if self.full_turn {
                Some(0)
            } else {
                None
            }
        };
        // The wedge `from` lies in, then each beam the segment passes and the wedge
        // after it. Past the last beam of a field of view, the next beam round is the
        // first, across the unseen gap.
        let mut k = if from.next < n { from.next } else { 0 };
        let prev = if k > 0 {
            Some(k - 1)
        } else if self.full_turn {
            Some(n - 1)
        } else {
            None
        };
        if let Some(i) = prev {
            chord(i, k, &mut push);
        }
        for _ in 0..n {
            if (self.angles[k] - from.phi).rem_euclid(TAU) > sweep {
                break;
            }
            push(ray_parameter(p, q, self.origin, self.angles[k]));
            let Some(j) = next(k) else { break };
            chord(k, j, &mut push);
            k = j;
        }
    }

    fn point(&self, i: usize, r: f64) -> Point {
        let (s, c) = self.angles[i].sin_cos();
        add(self.origin, [r * c, r * s])
    }

    /// The boundary of the free space as a closed polygon (counter-clockwise): the origin,
    /// then each beam's reach; an unseen stretch goes back through the origin.
    pub fn polygon(&self) -> Polyline {
        self.polygon_by_beam().0
    }

    /// [`polygon`](Self::polygon), and for each beam the index of its first point in it
    /// (the origin that an unseen gap before it goes back through, else its reach).
    fn polygon_by_beam(&self) -> (Polyline, Vec<usize>) {
        let n = self.angles.len();
        let mut pts = Vec::with_capacity(n + 2);
        let mut first = Vec::with_capacity(n);
        if !self.full_turn {
            pts.push(self.origin);
        }
        for i in 0..n {
            // A field of view's first beam starts at the origin before it: past its
            // edges the polygon goes through the origin.
            first.push(if i == 0 { 0 } else { pts.len() });
            if i > 0 {
                let gap = self.angles[i] - self.angles[i - 1];
                if gap > self.max_gap && pts.last() != Some(&self.origin) {
                    pts.push(self.origin);
                }
            }
            if self.reach[i] > 0.0 {
                pts.push(self.point(i, self.reach[i]));
            } else if pts.last() != Some(&self.origin) {
                pts.push(self.origin);
            }
        }
        (
            Polyline {
                closed: true,
                points: pts,
            },
            first,
        )
    }

    /// Signed distances to the boundary of the free space (negative in it), for many
    /// points.
    pub(crate) fn boundary(&self) -> Boundary<'_> {
        let (polygon, first) = self.polygon_by_beam();
        // A segment between neighbouring beams sweeps the bearings between them, unless
        // they are half a turn or more apart (then it crosses other beams' wedges).
        let n = self.angles.len();
        let pairs = if self.full_turn {
            n
        } else {
            n.saturating_sub(1)
        };
        // The polygon goes through the origin across a wide gap, but not across a full
        // turn's wrap.
        let local = (0..pairs).all(|i| {
            let gap = (self.angles[(i + 1) % n] - self.angles[i]).rem_euclid(TAU);
            gap < std::f64::consts::PI || (i + 1 < n && gap > self.max_gap)
        });
        Boundary {
            free: self,
            tips: self.tips(),
            polygon,
            first,
            local,
            index: std::sync::OnceLock::new(),
        }
    }
}

/// Exact distances to a free space's boundary polygon ([`FreeSpace::polygon`]), for
/// points near it: the polygon runs round the sensor in bearing order, so the segments
/// of the few beams either side of a point's bearing hold its nearest one, and which
/// they hold is certain when the nearest of them is nearer than the sides of their
/// wedge (everything else lies beyond those). Where it is not certain (far from the
/// boundary, near the sensor, at the edges of a field of view) the polygon's segment
/// index answers.
pub(crate) struct Boundary<'a> {
    free: &'a FreeSpace,
    /// The beams' reaches, as points.
    tips: Vec<Point>,
    polygon: Polyline,
    /// Each beam's first point in the polygon.
    first: Vec<usize>,
    /// Whether each segment keeps to its beams' bearings, so that the beams round a
    /// point hold its nearest segments.
    local: bool,
    index: std::sync::OnceLock<crate::index::SegmentIndex>,
}

/// A point's place round a free space's origin.
struct Bearing {
    /// Its distance from the origin.
    rho: f64,
    /// Its bearing, in `[a0, a0 + 2 pi)` for the first beam's `a0`.
    phi: f64,
    /// The first beam past the bearing.
    next: usize,
}

impl Boundary<'_> {
    /// Beams either side of a point's bearing searched first.
    const BEAMS: usize = 4;
    /// Beams either side searched at most before the segment index is asked.
    const MAX_BEAMS: usize = 64;

    /// The signed distance from `p` to the boundary (negative in the free space), or
    /// `limit` with its sign when the distance is more.
    pub(crate) fn signed_within(&self, p: Point, limit: f64) -> f64 {
        let bearing = self.free.bearing(p);
        let inside = match &bearing {
            None => self.free.contains(p),
            Some(b) => self.free.contains_at(p, b, |i| self.tips[i]),
        };
        let d = bearing
            .and_then(|b| self.local(p, &b, limit))
            .unwrap_or_else(|| self.indexed(p).min(limit));
        if inside {
            -d
        } else {
            d
        }
    }

    /// The distance from `p` to the boundary, or `limit` when that is less.
    #[cfg(test)]
    pub(crate) fn distance_within(&self, p: Point, limit: f64) -> f64 {
        self.signed_within(p, limit).abs()
    }

    fn indexed(&self, p: Point) -> f64 {
        self.index
            .get_or_init(|| crate::index::SegmentIndex::new(std::slice::from_ref(&self.polygon)))
            .distance(p)
    }

    /// The distance (at most `limit`) to the segments of the beams round bearing `b`,
    /// the wedge widened until every other segment is certainly farther; `None` where
    /// that would take a wide wedge (near the sensor, far from the boundary, on a
    /// coarse scan).
    fn local(&self, p: Point, b: &Bearing, limit: f64) -> Option<f64> {
        let free = self.free;
        let n = free.angles.len();
        let pts = &self.polygon.points;
        let len = pts.len();
        if !self.local || n < 2 * Self::BEAMS + 2 || len < 2 || b.rho == 0.0 {
            return None;
        }
        let step = (free.angles[n - 1] - free.angles[0]) / (n - 1) as f64;
        // The beam at or before the bearing.
        let i = b.next as isize - 1;
        let wrap = |k: isize| k.rem_euclid(n as isize) as usize;
        // The nearest of the segments from the first point of beam `from` to that of
        // beam `to`.
        let nearest = |from: isize, to: isize| {
            let (from, to) = (self.first[wrap(from)], self.first[wrap(to)]);
            (0..(to + len - from) % len)
                .map(|s| {
                    let m = (from + s) % len;
                    point_segment_dist2(p, pts[m], pts[(m + 1) % len]).0
                })
                .fold(f64::INFINITY, f64::min)
        };
        let mut k = Self::BEAMS as isize;
        let mut best2 = nearest(i - k, i + 1 + k);
        loop {
            // The wedge from `k` beams before the bearing's to `k` after the next one.
            // Past a field of view's edge it runs on through the unseen bearings, where
            // the polygon only goes to the origin and back.
            let (lo, hi) = (wrap(i - k), wrap(i + 1 + k));
            let below = (b.phi - free.angles[lo]).rem_euclid(TAU);
            let above = (free.angles[hi] - b.phi).rem_euclid(TAU);
            if below + above >= std::f64::consts::PI {
                return None;
            }
            // Beyond the wedge's sides (rays from the origin) every point is at least the
            // distance to the nearer side away: `rho sin(side)`, and `x - x^3 / 6` is
            // below the sine.
            let side = below.min(above);
            let certain = b.rho * side * (1.0 - side * side / 6.0);
            let best = best2.sqrt();
            if best <= certain || best.min(certain) >= limit {
                return Some(best.min(limit));
            }
            // Wide enough for the nearest so far (or the limit) to be certain.
            let need = (best.min(limit) / b.rho).min(1.0).asin();
            let wider = ((need / step).ceil() as isize + 1).max(2 * k);
            if 2 * wider + 2 > n as isize || wider > Self::MAX_BEAMS as isize {
                return None;
            }
            best2 = best2
                .min(nearest(i - wider, i - k))
                .min(nearest(i + 1 + k, i + 1 + wider));
            k = wider;
        }
    }
}

#[cfg(test)]
mod tests;
