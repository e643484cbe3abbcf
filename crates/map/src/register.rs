//! The pose stage: each scan registered against the local map of the last keyframes,
//! from the input poses' motion taken as a prior; keyframes in a pose graph; loops
//! searched near each closed keyframe within the graph's uncertainty, verified by
//! matching, checked against the graph, and the graph solved when one closes
//! (docs/method.md, "Poses").
//!
//! A keyframe is the scan that opens it plus the scans registered while it is the
//! newest, in its own frame, thinned to a lattice: a submap that moves rigidly with its
//! node when the graph moves it (Cartographer's submaps, Hess et al. 2016). Every scan
//! keeps its pose relative to its keyframe, so the whole trajectory follows the graph.

use isoline_core::{Point, Polyline, Pose, Scan};
use nalgebra::Matrix3;

use crate::correlate::{in_reach, search, Likelihood, Window};
use crate::graph::{Edge, PoseGraph};
use crate::icp::{register, Match, Prior};
use crate::se2::{between, compose, compose_cov, diag, diff, inverse_cov, rotate_cov, Cov3};
use crate::submap::{thin, Surface};

/// How scans are registered and loops closed.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(default, deny_unknown_fields))]
pub struct RegisterParams {
    /// A new keyframe opens once the sensor has moved this far from the last one,
    /// metres.
    pub keyframe_distance: f64,
    /// ... or turned this far, radians.
    pub keyframe_angle: f64,
    /// Keyframes in the local map a scan is registered against.
    pub local_keyframes: usize,
    /// The lattice returns are thinned to, metres: one target point per cell.
    pub cell: f64,
    /// The measurement noise of a return against the map (range noise and the map's
    /// own), metres: the robust kernel's floor and the inlier band's third.
    pub noise: f64,
    /// The farthest a return's target may lie from where the prior puts it, metres.
    pub reach: f64,
    /// Returns beyond this range are not registered, metres.
    pub max_range: f64,
    /// The input motion's error: standard deviation per metre travelled (a fraction)
    /// and per radian turned (a fraction), as wheel odometry's error grows.
    pub odometry_noise: [f64; 2],
    /// Scan matching's own drift, the floor under a keyframe edge's covariance:
    /// standard deviation per metre (a fraction) and radians per metre.
    pub drift: [f64; 2],
    /// Search for loops and close them.
    pub loops: bool,
    /// Path travelled before a place may close a loop with itself, metres (within it
    /// the local map already holds it).
    pub loop_min_path: f64,
    /// Share of a keyframe's returns that must lie on the older keyframe's walls for a
    /// loop to close.
    pub loop_min_overlap: f64,
    /// Keyframes whose submaps are kept for loops; older ones keep their node and lose
    /// their points (a bound on memory: a submap holds at most a few thousand points).
    pub max_keyframes: usize,
}

impl Default for RegisterParams {
    fn default() -> Self {
        RegisterParams {
            keyframe_distance: 0.5,
            keyframe_angle: 15f64.to_radians(),
            local_keyframes: 12,
            cell: 0.03,
            noise: 0.02,
            reach: 0.5,
            max_range: 20.0,
            odometry_noise: [0.1, 0.1],
            drift: [0.01, 0.5f64.to_radians()],
            loops: true,
            loop_min_path: 10.0,
            loop_min_overlap: 0.5,
            max_keyframes: 2000,
        }
    }
}

impl RegisterParams {
    /// Every problem with the parameters, each naming its key (`register.cell`).
    pub fn validate(&self) -> std::result::Result<(), Vec<String>> {
        let mut problems = Vec::new();
        let mut check = |key: &str, v: f64, lo: f64, hi: f64| {
            if !(v.is_finite() && v >= lo && v <= hi) {
                problems.push(format!("register.{key} = {v}: must be {lo} to {hi}"));
            }
        };
        check("keyframe_distance", self.keyframe_distance, 0.01, 100.0);
        check("keyframe_angle", self.keyframe_angle, 0.001, 3.2);
        check("cell", self.cell, 0.001, 1.0);
        check("noise", self.noise, 0.0001, 1.0);
        check("reach", self.reach, 0.01, 10.0);
        check("max_range", self.max_range, 0.1, 1000.0);
        check("odometry_noise[0]", self.odometry_noise[0], 0.0, 10.0);
        check("odometry_noise[1]", self.odometry_noise[1], 0.0, 10.0);
        check("drift[0]", self.drift[0], 0.0, 1.0);
        check("drift[1]", self.drift[1], 0.0, 1.0);
        check("loop_min_path", self.loop_min_path, 0.0, 1e6);
        check("loop_min_overlap", self.loop_min_overlap, 0.0, 1.0);
        if !(self.local_keyframes..=1_000_000).contains(&self.max_keyframes) {
            problems.push(format!(
                "register.max_keyframes = {}: must be local_keyframes ({}) to 1000000",
                self.max_keyframes, self.local_keyframes
            ));
        }
        if !(1..=1000).contains(&self.local_keyframes) {
            problems.push(format!(
                "register.local_keyframes = {}: must be 1 to 1000",
                self.local_keyframes
            ));
        }
        if problems.is_empty() {
            Ok(())
        } else {
            Err(problems)
        }
    }
}

/// What registration made of one scan.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Registered {
    /// The scan's estimated pose in the world, as known when it came.
    pub pose: Pose,
    /// Its covariance (`x, y, theta`), row by row.
    pub cov: [[f64; 3]; 3],
    /// Whether some direction was decided by the prior (the input's motion), not the
    /// returns: a featureless corridor along its axis.
    pub degenerate: bool,
    /// Share of the scan's returns on the local map's walls (0 for the first scan).
    pub inlier_share: f64,
    /// Loops closed when this scan's keyframe closed.
    pub loops_closed: usize,
}

/// Points every `step` along `curves` (in a scan's frame), those within `reach` of
/// its origin.
fn sample(curves: &[Polyline], step: f64, reach: f64) -> Vec<Point> {
    let mut out = Vec::new();
    for c in curves {
        for (a, b) in c.segments() {
            let n = (isoline_core::geom::dist(a, b) / step).ceil().max(1.0) as usize;
            out.extend((0..n).map(|i| {
                let t = i as f64 / n as f64;
                [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]
            }));
        }
        if let (false, Some(&last)) = (c.closed, c.points.last()) {
            out.push(last);
        }
    }
    out.retain(|p| p[0].hypot(p[1]) <= reach && p[0].is_finite() && p[1].is_finite());
    out
}

/// A keyframe: its submap in its own frame.
struct Keyframe {
    /// Thinned returns of its scans.
    points: Vec<Point>,
    /// The share of a measurement each of its points is: its scans' mean (see
    /// [`Registrar::push_curves`]).
    weight: f64,
    surface: Surface,
    /// Path travelled when it opened, metres.
    path: f64,
}

/// Registers a stream of scans, keeps the pose graph and closes loops.
pub struct Registrar {
    params: RegisterParams,
    graph: PoseGraph,
    keyframes: Vec<Keyframe>,
    /// Raw returns of the open (newest) keyframe's scans, in its frame.
    open: Vec<Point>,
    /// The open keyframe's scans' weights: their sum and count.
    open_weight: (f64, usize),
    /// Each scan's keyframe and pose relative to it (kept when the trajectory is).
    anchors: Vec<(usize, Pose)>,
    keep_trajectory: bool,
    /// Scans registered.
    count: usize,
    /// The previous scan's input pose and estimate.
    last: Option<(Option<Pose>, Pose)>,
    /// The local map in the world, and the keyframes it was built from.
    local: Option<Surface>,
    path: f64,
    loops: usize,
    /// Each node's edges: the node at the other end and the edge's index.
    links: Vec<Vec<(usize, usize)>>,
    /// Each edge's covariance, in its `from` node's frame.
    edge_covs: Vec<Cov3>,
    /// Loops closed since the graph was last solved.
    unsolved: bool,
    /// The last two scans pushed with a time ([`Registrar::push_swept`]): their times
    /// and estimates, newest first.
    timed: [Option<(f64, Pose)>; 2],
}

impl std::fmt::Debug for Registrar {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Registrar")
            .field("scans", &self.count)
            .field("keyframes", &self.keyframes.len())
            .field("loops", &self.loops)
            .finish()
    }
}

/// The farthest a loop's correlative search looks from where the graph puts the old
/// place, metres: a 400 m run on odometry that scan matching corrects to a percent.
const MAX_LOOP_SHIFT: f64 = 10.0;

/// Old keyframes a loop's search matches against at once, nearest first: a bound on
/// the search's cost.
const MAX_LOOP_TARGETS: usize = 30;

/// The 95th percentile of a chi-square with three degrees of freedom.
const CHI2_3_95: f64 = 7.815;

/// Wide uncertainty of a still-standing prior for scans without input poses: a person
/// walks half a metre and turns half a radian between scans at most.
const STILL: [f64; 2] = [0.5, 0.5];

impl Registrar {
    /// An empty registrar, or the problems with `params`.
    pub fn new(params: RegisterParams) -> std::result::Result<Registrar, Vec<String>> {
        params.validate()?;
        Ok(Registrar {
            params,
            graph: PoseGraph::default(),
            keyframes: Vec::new(),
            open: Vec::new(),
            open_weight: (1.0, 0),
            anchors: Vec::new(),
            keep_trajectory: true,
            count: 0,
            last: None,
            local: None,
            path: 0.0,
            loops: 0,
            links: Vec::new(),
            edge_covs: Vec::new(),
            unsolved: false,
            timed: [None, None],
        })
    }

    /// The parameters.
    pub fn params(&self) -> &RegisterParams {
        &self.params
    }

    /// A registrar for a live stream: it keeps no pose a scan ([`trajectory`] is
    /// empty), so its memory is bounded by `max_keyframes` submaps and a node a
    /// keyframe.
    ///
    /// [`trajectory`]: Registrar::trajectory
    pub fn streaming(params: RegisterParams) -> std::result::Result<Registrar, Vec<String>> {
        let mut r = Registrar::new(params)?;
        r.keep_trajectory = false;
        Ok(r)
    }

    /// Scans registered.
    pub fn scans(&self) -> usize {
        self.count
    }

    /// Counts a scan, and keeps its keyframe and pose relative to it when the
    /// trajectory is kept.
    fn anchor(&mut self, k: usize, rel: Pose) {
        self.count += 1;
        if self.keep_trajectory {
            self.anchors.push((k, rel));
        }
    }

    /// Keyframes in the graph.
    pub fn keyframes(&self) -> usize {
        self.keyframes.len()
    }

    /// Loops closed so far.
    pub fn loops(&self) -> usize {
        self.loops
    }

    /// Registers the next scan. `input` is its pose from the source (odometry, a
    /// recording's poses), taken for its motion since the previous scan; `None`
    /// registers the scan from the returns alone.
    pub fn push(&mut self, scan: &Scan, input: Option<Pose>) -> Registered {
        let points = self.returns(scan);
        self.push_points(points, input)
    }

    /// Registers the next scan, taken at time `t` (its first beam's, seconds) by a sweep
    /// timed by `sweep`, corrected for the sensor's motion during the sweep by the
    /// motion registration itself gives: for a stream without input poses, whose frames
    /// nothing else corrects. Returns the estimate and the corrected scan.
    ///
    /// The motion between the last two scans (a constant velocity, as KISS-ICP
    /// predicts) gives a first correction and a first estimate without keeping it; the
    /// motion from the last scan to that estimate gives the correction the scan is
    /// registered with. Taking the prediction alone feeds the correction's error back:
    /// a scan bent by a wrong turn rate is fitted with part of the bend as a turn,
    /// which sets the next turn rate wrong the other way, and for a sweep as long as
    /// the time between frames (a 360-degree scanner) that error does not die out
    /// (the heading over 1 m of a simulated RPLIDAR's drive: 0.6 degrees read as taken
    /// at once, 2.2 corrected by the prediction alone). The scan is left as it came
    /// without timing, or where the last scan is more than a second old.
    pub fn push_swept(
        &mut self,
        scan: &Scan,
        sweep: &isoline_core::Sweep,
        t: f64,
        input: Option<Pose>,
    ) -> (Registered, Scan) {
        let velocity = self.sweep_velocity(t, sweep, input, |v| {
            (self.returns(&scan.deskewed(sweep, v)), 1.0)
        });
        let fixed = velocity.map_or_else(|| scan.clone(), |v| scan.deskewed(sweep, v));
        let r = self.push(&fixed, input);
        self.timed = [Some((t, r.pose)), self.timed[0]];
        (r, fixed)
    }

    /// [`Registrar::push_swept`] for a scan registered by its curves
    /// ([`Registrar::push_curves`]), drawn from the scan as it came: the curves are
    /// moved as the returns they run through would be ([`isoline_core::Sweep::unbend`]).
    /// Returns the estimate and the velocity the curves were corrected by (`None`: left
    /// as they came), which corrects the scan the same way ([`Scan::deskewed`]).
    pub fn push_swept_curves(
        &mut self,
        scan: &Scan,
        curves: &[Polyline],
        sweep: &isoline_core::Sweep,
        t: f64,
        input: Option<Pose>,
    ) -> (Registered, Option<[f64; 3]>) {
        let unbent = |v: [f64; 3]| -> Vec<Polyline> {
            curves
                .iter()
                .map(|c| Polyline {
                    closed: c.closed,
                    points: sweep.unbend(&c.points, scan.origin, v),
                })
                .collect()
        };
        let returns = self.in_range(scan).len();
        let samples = |curves: &[Polyline]| {
            let points = sample(curves, self.params.cell, self.params.max_range);
            let weight = (returns as f64 / points.len().max(1) as f64).min(1.0);
            (points, weight)
        };
        let velocity = self.sweep_velocity(t, sweep, input, |v| samples(&unbent(v)));
        let (points, weight) = match velocity {
            Some(v) => samples(&unbent(v)),
            None => samples(curves),
        };
        let r = self.push_weighted(points, weight, input);
        self.timed = [Some((t, r.pose)), self.timed[0]];
        (r, velocity)
    }

    /// The velocity a scan taken at `t` by `sweep` is corrected by, from the scans
    /// pushed before it with their times (`None` where the last is more than a second
    /// old or the sweep is not timed): the motion between the last two corrects the
    /// scan's `points` (as `corrected` gives them for a velocity) for a first estimate,
    /// kept nowhere; the motion from the last scan to that estimate is the answer.
    fn sweep_velocity(
        &self,
        t: f64,
        sweep: &isoline_core::Sweep,
        input: Option<Pose>,
        corrected: impl Fn([f64; 3]) -> (Vec<Point>, f64),
    ) -> Option<[f64; 3]> {
        /// A vehicle's velocity a second ago says little of it now.
        const MAX_GAP: f64 = 1.0;
        let fresh = |since: f64| since > 0.0 && since <= MAX_GAP;
        let [Some((t1, p1)), before] = self.timed else {
            return None;
        };
        if !(fresh(t - t1) && sweep.is_valid() && sweep.time_increment > 0.0) {
            return None;
        }
        let predicted = before
            .filter(|&(t0, _)| fresh(t1 - t0))
            .and_then(|(t0, p0)| isoline_core::velocity(p0, p1, t1 - t0))
            .unwrap_or([0.0; 3]);
        let (points, weight) = corrected(predicted);
        let first = self.estimate(&points, weight, input).pose;
        isoline_core::velocity(p1, first, t - t1)
    }

    /// Registers the next scan by its curves (its reconstruction, in its frame) rather
    /// than its raw returns: points every `cell` along them. The curves are the walls
    /// with the range noise averaged along each run, so the point-to-line residuals
    /// measure where the walls are, not the noise of one scan (on the SICK logs the
    /// error over 10 m of path falls by about half; docs/benchmarks.md, "Poses").
    ///
    /// The samples hold no more of the walls than the returns of `scan` (the scan the
    /// curves were drawn from) within `max_range`: where there are more samples than
    /// returns (a wall 10 m from a 1-degree scanner has returns 17 cm apart, samples
    /// 3 cm apart), each weighs as that share of a return. Counted as independent
    /// measurements they would claim millimetres along a corridor that its door jambs'
    /// few returns place only to centimetres, and outweigh the odometry there.
    pub fn push_curves(
        &mut self,
        scan: &Scan,
        curves: &[Polyline],
        input: Option<Pose>,
    ) -> Registered {
        let points = sample(curves, self.params.cell, self.params.max_range);
        let returns = self.in_range(scan).len();
        let weight = (returns as f64 / points.len().max(1) as f64).min(1.0);
        self.push_weighted(points, weight, input)
    }

    /// Registers the next scan given as points in its frame, as
    /// [`push`](Registrar::push) does with its returns.
    pub fn push_points(&mut self, points: Vec<Point>, input: Option<Pose>) -> Registered {
        self.push_weighted(points, 1.0, input)
    }

    /// Registers the next scan's `points`, each `weight` of a measurement.
    fn push_weighted(
        &mut self,
        points: Vec<Point>,
        weight: f64,
        input: Option<Pose>,
    ) -> Registered {
        let _span = tracing::debug_span!("register", scan = self.count).entered();
        let Some((_, last)) = self.last else {
            // The first scan fixes the world: where its input puts it, else the origin.
            let pose = input.unwrap_or([0.0, 0.0, 0.0]);
            self.open_keyframe(pose, &points, weight, Cov3::zeros());
            self.last = Some((input, pose));
            self.anchor(0, [0.0, 0.0, 0.0]);
            return Registered {
                pose,
                cov: [[0.0; 3]; 3],
                degenerate: false,
                inlier_share: 0.0,
                loops_closed: 0,
            };
        };
        let m = self.estimate(&points, weight, input);
        let pose = m.pose;
        self.path += diff(pose, last).xy().norm();
        self.last = Some((input, pose));
        let kf = self.keyframes.len() - 1;
        let anchor = self.graph.nodes[kf];
        let rel = between(anchor, pose);
        let mut loops_closed = 0;
        let moved = rel[0].hypot(rel[1]);
        if moved >= self.params.keyframe_distance || rel[2].abs() >= self.params.keyframe_angle {
            loops_closed = self.close_keyframe();
            // The graph may have moved the old keyframe: the scan keeps its place
            // relative to it.
            let pose = compose(self.graph.nodes[kf], rel);
            let cov = self.edge_cov(&m, rel);
            self.open_keyframe(pose, &points, weight, cov);
            self.last = Some((input, pose));
            self.anchor(kf + 1, [0.0, 0.0, 0.0]);
        } else {
            self.open
                .extend(points.iter().map(|&p| isoline_core::geom::to_world(rel, p)));
            self.open_weight.0 += weight;
            self.open_weight.1 += 1;
            self.anchor(kf, rel);
        }
        let pose = self.last.expect("set above").1;
        let c = m.cov;
        Registered {
            pose,
            cov: [
                [c[(0, 0)], c[(0, 1)], c[(0, 2)]],
                [c[(1, 0)], c[(1, 1)], c[(1, 2)]],
                [c[(2, 0)], c[(2, 1)], c[(2, 2)]],
            ],
            degenerate: m.degenerate,
            inlier_share: m.inlier_share(),
            loops_closed,
        }
    }

    /// The next scan's `points` (each `weight` of a measurement) matched against the
    /// local map from the prior its `input` gives, kept nowhere.
    fn estimate(&self, points: &[Point], weight: f64, input: Option<Pose>) -> Match {
        let Some((last_input, last)) = self.last else {
            return Match {
                pose: input.unwrap_or([0.0, 0.0, 0.0]),
                cov: Cov3::zeros(),
                info: Matrix3::zeros(),
                paired: 0,
                inliers: 0,
                offered: points.len(),
                spread: 0.0,
                degenerate: false,
            };
        };
        let prior = self.prior(last, last_input, input);
        match &self.local {
            Some(local) if !local.is_empty() => register(
                points,
                weight,
                local,
                prior.mean,
                Some(&prior),
                self.params.noise,
                self.params.reach,
            ),
            _ => Match {
                pose: prior.mean,
                cov: prior.info.try_inverse().unwrap_or_else(Cov3::identity),
                info: Matrix3::zeros(),
                paired: 0,
                inliers: 0,
                offered: points.len(),
                spread: 0.0,
                degenerate: true,
            },
        }
    }

    /// Every scan's pose as the graph now places it (after the loops closed since it
    /// was registered), in the order pushed.
    pub fn trajectory(&self) -> Vec<Pose> {
        self.anchors
            .iter()
            .map(|&(k, rel)| compose(self.graph.nodes[k], rel))
            .collect()
    }

    /// Closes the newest keyframe (its submap from all its scans) and searches loops
    /// for it: the trajectory after this is final.
    pub fn finish(&mut self) -> Vec<Pose> {
        if !self.keyframes.is_empty() {
            self.close_keyframe();
        }
        if self.unsolved {
            self.solve();
        }
        self.trajectory()
    }

    /// Solves the graph with every loop closed so far.
    fn solve(&mut self) {
        let solved = self.graph.optimize(20);
        tracing::debug!(?solved, "graph solved");
        self.unsolved = false;
    }

    /// The scan's returns within `max_range`, thinned to the lattice.
    fn returns(&self, scan: &Scan) -> Vec<Point> {
        thin(&self.in_range(scan), self.params.cell)
    }

    /// The scan's returns within `max_range`.
    fn in_range(&self, scan: &Scan) -> Vec<Point> {
        let r = self.params.max_range;
        let mut pts = scan.returns();
        pts.retain(|&p| isoline_core::geom::dist(p, scan.origin) <= r);
        pts
    }

    /// The prior on the scan's pose: the input's motion since the previous scan from
    /// the previous estimate, with the odometry's error model; without inputs, standing
    /// still with a wide uncertainty.
    fn prior(&self, last: Pose, last_input: Option<Pose>, input: Option<Pose>) -> Prior {
        let (mean, cov) = match (last_input, input) {
            (Some(a), Some(b)) => {
                let step = between(a, b);
                let (d, turn) = (step[0].hypot(step[1]), step[2].abs());
                let [per_m, per_rad] = self.params.odometry_noise;
                // A floor of a centimetre and a degree: odometry at a stop still slips.
                let st = per_m * d + 0.01;
                let sr = per_rad * turn + per_m * d + 1f64.to_radians();
                (compose(last, step), rotate_cov(&diag(st, st, sr), last[2]))
            }
            _ => (last, diag(STILL[0], STILL[0], STILL[1])),
        };
        Prior {
            mean,
            info: cov.try_inverse().unwrap_or_else(Matrix3::zeros),
        }
    }

    /// A keyframe edge's covariance: the match's, in the previous keyframe's frame,
    /// never below scan matching's drift over the edge's length.
    fn edge_cov(&self, m: &Match, rel: Pose) -> Cov3 {
        let kf = self.keyframes.len() - 1;
        let d = rel[0].hypot(rel[1]);
        let [per_m, rad_per_m] = self.params.drift;
        let floor = diag(
            per_m * d + 0.5 * self.params.cell,
            per_m * d + 0.5 * self.params.cell,
            rad_per_m * d + 0.1f64.to_radians(),
        );
        rotate_cov(&m.cov, -self.graph.nodes[kf][2]) + floor
    }

    fn open_keyframe(&mut self, pose: Pose, points: &[Point], weight: f64, cov: Cov3) {
        let k = self.keyframes.len();
        self.graph.nodes.push(pose);
        self.links.push(Vec::new());
        if k > 0 {
            let info = cov.try_inverse().unwrap_or_else(Matrix3::identity);
            self.add_edge(
                Edge {
                    from: k - 1,
                    to: k,
                    z: between(self.graph.nodes[k - 1], pose),
                    info,
                    loop_closure: false,
                },
                cov,
            );
        }
        self.open = points.to_vec();
        self.open_weight = (weight, 1);
        let surface = Surface::new(points, self.normal_radius());
        self.keyframes.push(Keyframe {
            // Its points are those of all its scans, set when it closes.
            points: Vec::new(),
            weight,
            surface,
            path: self.path,
        });
        if let Some(old) = self
            .keyframes
            .len()
            .checked_sub(self.params.max_keyframes + 1)
        {
            let kf = &mut self.keyframes[old];
            kf.points = Vec::new();
            kf.surface = Surface::with_normals(Vec::new(), Vec::new());
        }
        self.rebuild_local();
    }

    fn add_edge(&mut self, edge: Edge, cov: Cov3) {
        let e = self.graph.edges.len();
        self.links[edge.from].push((edge.to, e));
        self.links[edge.to].push((edge.from, e));
        self.graph.edges.push(edge);
        self.edge_covs.push(cov);
    }

    /// For every node `j`, the covariance of node `k` seen from `j` (in `j`'s frame)
    /// along the graph's least uncertain path between them: the Dijkstra projection of
    /// Bosse et al. (2003, ATLAS), the path's length the trace of the translation's
    /// covariance. Once a loop has closed, a place on it is near in uncertainty though
    /// far along the chain of keyframes, so the loop search there looks within the
    /// metres the graph leaves open, not those the whole path since would.
    fn uncertainty_from(&self, k: usize) -> Vec<Option<Cov3>> {
        use std::cmp::Reverse;
        use std::collections::BinaryHeap;
        /// A length ordered as its float.
        #[derive(PartialEq)]
        struct Len(f64);
        impl Eq for Len {}
        impl PartialOrd for Len {
            fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
                Some(self.cmp(other))
            }
        }
        impl Ord for Len {
            fn cmp(&self, other: &Self) -> std::cmp::Ordering {
                self.0.total_cmp(&other.0)
            }
        }
        let nodes = &self.graph.nodes;
        let mut best: Vec<Option<Cov3>> = vec![None; nodes.len()];
        let mut done = vec![false; nodes.len()];
        let mut heap = BinaryHeap::new();
        best[k] = Some(Cov3::zeros());
        heap.push(Reverse((Len(0.0), k)));
        while let Some(Reverse((_, m))) = heap.pop() {
            if std::mem::replace(&mut done[m], true) {
                continue;
            }
            let chain = best[m].expect("pushed with one");
            // k seen from m.
            let rel = between(nodes[m], nodes[k]);
            for &(n, e) in &self.links[m] {
                if done[n] {
                    continue;
                }
                let edge = &self.graph.edges[e];
                // The step from n to m and its covariance in n's frame.
                let step = between(nodes[n], nodes[m]);
                let step_cov = if edge.from == n {
                    self.edge_covs[e]
                } else {
                    inverse_cov(between(nodes[m], nodes[n]), &self.edge_covs[e])
                };
                let cov = compose_cov(step, &step_cov, rel, &chain);
                let len = cov[(0, 0)] + cov[(1, 1)];
                if best[n].is_none_or(|b| len < b[(0, 0)] + b[(1, 1)]) {
                    best[n] = Some(cov);
                    heap.push(Reverse((Len(len), n)));
                }
            }
        }
        best
    }

    /// The farthest a normal's neighbours may lie: returns farther apart than half a
    /// metre along a wall are too sparse to say where it runs between them.
    fn normal_radius(&self) -> f64 {
        0.5
    }

    /// The newest keyframe's submap from all its scans, then the loops it closes.
    fn close_keyframe(&mut self) -> usize {
        let k = self.keyframes.len() - 1;
        let points = thin(&std::mem::take(&mut self.open), self.params.cell);
        let surface = Surface::new(&points, self.normal_radius());
        self.keyframes[k].points = points;
        self.keyframes[k].weight = self.open_weight.0 / self.open_weight.1.max(1) as f64;
        self.keyframes[k].surface = surface;
        let closed = if self.params.loops {
            self.close_loops(k)
        } else {
            0
        };
        self.rebuild_local();
        closed
    }

    /// The local map: the last keyframes' target points and normals, in the world.
    fn rebuild_local(&mut self) {
        let n = self.keyframes.len();
        let from = n.saturating_sub(self.params.local_keyframes);
        let mut points = Vec::new();
        let mut normals = Vec::new();
        for k in from..n {
            let pose = self.graph.nodes[k];
            let (s, c) = pose[2].sin_cos();
            let kf = &self.keyframes[k];
            for (p, nrm) in kf.surface.points().iter().zip(kf.surface.normals()) {
                points.push(isoline_core::geom::to_world(pose, *p));
                normals.push([c * nrm[0] - s * nrm[1], s * nrm[0] + c * nrm[1]]);
            }
        }
        self.local = Some(Surface::with_normals(points, normals));
    }

    /// Searches older keyframes near keyframe `k` for loops, adds the edges that pass
    /// the checks, and solves the graph if any did. Returns how many closed.
    fn close_loops(&mut self, k: usize) -> usize {
        let p = self.params;
        let here = self.graph.nodes[k];
        let path = self.keyframes[k].path;
        // The candidates: far enough back along the path, within reach of the
        // uncertainty the graph leaves between them and here.
        let uncertainty = self.uncertainty_from(k);
        let mut candidates: Vec<(f64, usize, Cov3)> = Vec::new();
        for (j, chain) in uncertainty.into_iter().enumerate().take(k) {
            let Some(chain) = chain else { continue };
            if path - self.keyframes[j].path < p.loop_min_path {
                continue;
            }
            let spread = chain
                .fixed_view::<2, 2>(0, 0)
                .symmetric_eigenvalues()
                .max()
                .sqrt();
            let d = diff(here, self.graph.nodes[j]).xy().norm();
            if d <= p.max_range.min(0.5 * p.loop_min_path) + 3.0 * spread {
                candidates.push((d, j, chain));
            }
        }
        candidates.sort_by(|a, b| a.0.total_cmp(&b.0));
        // The nearest candidate, matched against it and the other candidates nearest
        // (where the drift is metres, the nearest old node need not be the one that saw
        // the same walls).
        let others: Vec<usize> = candidates
            .iter()
            .take(MAX_LOOP_TARGETS)
            .map(|c| c.1)
            .collect();
        let found = candidates.first().and_then(|&(_, j, chain)| {
            let (edge, cov) = self.verify(j, k, &chain, &others)?;
            Some((j, edge, cov))
        });
        let mut closed = 0;
        if let Some((_, edge, cov)) = found {
            // A loop the graph already agrees with (its error within the 95% of a
            // chi-square with three degrees of freedom) would move the nodes by less
            // than its own noise: it is kept, and solved with the next loop that
            // disagrees, or at the end.
            let disagrees = self.graph.edge_chi2(&edge) > CHI2_3_95;
            self.add_edge(edge, cov);
            closed = 1;
            self.unsolved = true;
            if disagrees {
                self.solve();
            }
            tracing::debug!(keyframe = k, closed, disagrees, "loop closed");
            self.loops += closed;
        }
        closed
    }

    /// The target a loop from keyframe `k` to `j` is matched on: keyframe `j` with its
    /// neighbours along the path and the other candidates `others` (where the drift is
    /// metres, the nearest old node need not be the one that saw the same walls), points
    /// and normals in `j`'s frame.
    fn loop_target(&self, j: usize, k: usize, others: &[usize]) -> (Vec<Point>, Vec<Point>) {
        let (lo, hi) = (j.saturating_sub(2), (j + 2).min(k.saturating_sub(1)));
        let mut chosen: Vec<usize> = (lo..=hi).chain(others.iter().copied()).collect();
        chosen.sort_unstable();
        chosen.dedup();
        let mut points = Vec::new();
        let mut normals = Vec::new();
        for i in chosen {
            let rel = between(self.graph.nodes[j], self.graph.nodes[i]);
            let (s, c) = rel[2].sin_cos();
            let kf = &self.keyframes[i];
            for (q, n) in kf.surface.points().iter().zip(kf.surface.normals()) {
                points.push(isoline_core::geom::to_world(rel, *q));
                normals.push([c * n[0] - s * n[1], s * n[0] + c * n[1]]);
            }
        }
        (points, normals)
    }

    /// Correlative search for `source` on the target `points` within `window` of
    /// `guess`, coarse to fine; `None` where the whole window does not point at one place
    /// (`(j, k)` name the loop for the log).
    fn loop_search(
        &self,
        source: &[Point],
        points: &[Point],
        guess: Pose,
        window: Window,
        (j, k): (usize, usize),
    ) -> Option<Pose> {
        let p = self.params;
        // Coarse to fine: each level searches two of the coarser level's cells and
        // one of its heading steps about the coarser best. The points within 8 m
        // (farther ones turn the heading step finer for little gain), at most 150 at
        // the coarse levels.
        let near: Vec<Point> = source
            .iter()
            .copied()
            .filter(|q| q[0].hypot(q[1]) <= 8.0)
            .collect();
        let every = near.len().div_ceil(150).max(1);
        let sparse: Vec<Point> = near.iter().step_by(every).copied().collect();
        // The fine level at most 400: it refines within a few cells.
        let every = near.len().div_ceil(400).max(1);
        let near: Vec<Point> = near.iter().step_by(every).copied().collect();
        let mut at = guess;
        let mut win = window;
        for (level, (res, pts)) in [(0.5, &sparse), (0.2, &sparse), (0.05, &near)]
            .into_iter()
            .enumerate()
        {
            let blur = f64::max(res, p.noise);
            let keep = in_reach(pts, at, win, 2.0 * blur + res);
            let reachable: Vec<Point> = points.iter().copied().filter(|q| keep(q)).collect();
            let grid = Likelihood::new(&reachable, res, blur, win.linear)?;
            let found = search(pts, &grid, at, win);
            // The whole window's search must point at one place.
            if level == 0 && found.ambiguous(pts.len()) {
                tracing::debug!(
                    j,
                    k,
                    score = found.score,
                    runner_up = found.runner_up,
                    linear = window.linear,
                    angular = window.angular,
                    "loop search ambiguous"
                );
                return None;
            }
            at = found.pose;
            win = Window {
                linear: 2.0 * res,
                angular: res / 8.0,
            };
        }
        Some(at)
    }

    /// Matches keyframe `k`'s submap onto the submaps of keyframe `j`, its neighbours
    /// and `others` from where the graph puts them: a correlative search over the
    /// window the chain's uncertainty gives (three standard deviations, at most
    /// [`MAX_LOOP_SHIFT`] and 30 degrees) on lattices of 50, 20 and 5 cm, then ICP from
    /// its best. The edge if the search points at one place (no other within three
    /// standard errors of its score), the match is good (overlap, more informative than
    /// the chain along every direction) and consistent with the graph (its correction
    /// within the chain's 99.9% ellipsoid).
    fn verify(&self, j: usize, k: usize, chain: &Cov3, others: &[usize]) -> Option<(Edge, Cov3)> {
        let p = self.params;
        let guess = between(self.graph.nodes[j], self.graph.nodes[k]);
        let source = &self.keyframes[k].points;
        let (points, normals) = self.loop_target(j, k, others);
        if points.len() < 20 || source.len() < 20 {
            return None;
        }
        let spread = chain
            .fixed_view::<2, 2>(0, 0)
            .symmetric_eigenvalues()
            .max()
            .sqrt();
        let window = Window {
            linear: (3.0 * spread).clamp(p.reach, MAX_LOOP_SHIFT),
            angular: (3.0 * chain[(2, 2)].sqrt()).clamp(3f64.to_radians(), 30f64.to_radians()),
        };
        let at = self.loop_search(source, &points, guess, window, (j, k))?;
        // ICP's target: what lies within its reach of the source where the search put
        // it.
        let still = Window {
            linear: 0.0,
            angular: 0.0,
        };
        let keep = in_reach(source, at, still, p.reach);
        let (points, normals): (Vec<Point>, Vec<Point>) = points
            .into_iter()
            .zip(normals)
            .filter(|(q, _)| keep(q))
            .unzip();
        let target = Surface::with_normals(points, normals);
        let best = register(
            source,
            self.keyframes[k].weight,
            &target,
            at,
            None,
            p.noise,
            p.reach,
        );
        let c = diff(best.pose, guess);
        let s = chain + best.cov;
        let m2 = s.try_inverse().map(|inv| (c.transpose() * inv * c)[0]);
        tracing::debug!(
            j,
            k,
            share = best.inlier_share(),
            degenerate = best.degenerate,
            ?m2,
            "loop candidate"
        );
        // The match must say more than the graph already knows along every direction:
        // along a corridor's axis it does not, and there a repeated door or a column
        // would close the loop at the wrong place.
        let chain_info = chain.try_inverse()?;
        if best.inlier_share() < p.loop_min_overlap
            || crate::icp::degenerate(&best.info, &chain_info)
        {
            return None;
        }
        // Consistency: the correction against the chain's and the match's uncertainty,
        // chi-square with three degrees of freedom at 99.9%.
        let m2 = m2?;
        if m2.is_nan() || m2 > 16.27 {
            return None;
        }
        let floor = diag(0.5 * p.cell, 0.5 * p.cell, 0.1f64.to_radians());
        let cov = best.cov + floor;
        Some((
            Edge {
                from: j,
                to: k,
                z: best.pose,
                info: cov.try_inverse()?,
                loop_closure: true,
            },
            cov,
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn curves_are_sampled_every_step_within_reach() {
        let curves = [
            Polyline {
                closed: false,
                points: vec![[1.0, 0.0], [1.0, 0.3]],
            },
            Polyline {
                closed: true,
                points: vec![[30.0, 0.0], [30.0, 1.0], [31.0, 0.0]],
            },
        ];
        let pts = sample(&curves, 0.1, 20.0);
        // 0.3 m in three steps and its end; the closed curve lies beyond the reach.
        assert_eq!(pts.len(), 4, "{pts:?}");
        assert!(pts.iter().all(|p| (p[0] - 1.0).abs() < 1e-12));
        assert!((pts[3][1] - 0.3).abs() < 1e-12);
    }
}
