//! A 2D laser scanner simulator: scenes of walls, doorways and clutter ray-cast from a
//! sensor pose (or a trajectory of poses), through a sensor model with range noise,
//! dropout, spurious returns and a maximum range, with the visible truth of each frame.
//!
//! Each beam is cast from the sensor's position along its bearing and stops at the
//! nearest surface. Its return is that range plus Gaussian noise, unless it is beyond the
//! sensor's range, dropped (no echo, with probability `dropout`), or replaced by a
//! spurious short return (dust, a mixed pixel: probability `outliers`, uniform between
//! the minimum range and the true one).
//!
//! The truth of a frame is what the sensor could see of each surface, in the sensor's
//! frame: the stretches between neighbouring beams that hit the same surface within
//! range, at incidence below [`TRUTH_INCIDENCE_DEG`] (beyond it the returns are too
//! sparse for any extractor to call them a wall), from the first beam that returned its
//! range to the last (a beam that dropped out or returned a spurious range shows
//! nothing; more than [`TRUTH_MAX_DROPOUT`] of them in a row split the stretch), over at
//! least [`TRUTH_MIN_BEAMS`] returned beams (fewer are point features: legs, clutter).
//! Range noise does not change the truth: it is made of the exact hits.

use std::f64::consts::{PI, TAU};

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use isoline_core::geom::{add, cross, dist, dot, norm, scale, sub, Point, Polyline};

/// The incidence (degrees from the surface normal) beyond which a stretch of surface is
/// not part of the visible truth: the breakpoint test's default `lambda` of 10 degrees.
pub const TRUTH_INCIDENCE_DEG: f64 = 80.0;

/// Stretches seen by fewer beams are features, not walls, in the truth (the default
/// `scan.min_run`).
pub const TRUTH_MIN_BEAMS: usize = 3;

/// More beams than this in a row without their return split a stretch of the truth (the
/// default `scan.dropout_beams`).
pub const TRUTH_MAX_DROPOUT: usize = 2;

pub use isoline_core::geom::Pose;

/// A scanner model.
#[derive(Clone, Debug, PartialEq)]
pub struct SensorModel {
    /// The preset's name.
    pub name: &'static str,
    /// Field of view, degrees (360: a full turn).
    pub fov_deg: f64,
    /// Beams per scan.
    pub beams: usize,
    /// Nearest valid range, metres.
    pub range_min: f64,
    /// Farthest valid range, metres.
    pub range_max: f64,
    /// Range noise (standard deviation), metres.
    pub noise: f64,
    /// Scans per second.
    pub rate_hz: f64,
}

impl SensorModel {
    /// The presets, after the data sheets of the sensors they are named after.
    pub const PRESETS: [SensorModel; 5] = [
        SensorModel {
            name: "sick-tim",
            fov_deg: 270.0,
            beams: 811,
            range_min: 0.05,
            range_max: 25.0,
            noise: 0.02,
            rate_hz: 15.0,
        },
        SensorModel {
            name: "sick-lms1xx",
            fov_deg: 270.0,
            beams: 541,
            range_min: 0.5,
            range_max: 20.0,
            noise: 0.012,
            rate_hz: 50.0,
        },
        SensorModel {
            name: "hokuyo-utm30lx",
            fov_deg: 270.0,
            beams: 1080,
            range_min: 0.1,
            range_max: 30.0,
            noise: 0.01,
            rate_hz: 40.0,
        },
        SensorModel {
            name: "hokuyo-urg04lx",
            fov_deg: 240.0,
            beams: 683,
            range_min: 0.02,
            range_max: 4.0,
            noise: 0.01,
            rate_hz: 10.0,
        },
        SensorModel {
            name: "rplidar-a1",
            fov_deg: 360.0,
            beams: 360,
            range_min: 0.15,
            range_max: 12.0,
            noise: 0.01,
            rate_hz: 10.0,
        },
    ];

    /// The preset called `name`.
    pub fn named(name: &str) -> Result<SensorModel, String> {
        Self::PRESETS
            .iter()
            .find(|s| s.name == name)
            .cloned()
            .ok_or_else(|| {
                let names: Vec<_> = Self::PRESETS.iter().map(|s| s.name).collect();
                format!("unknown sensor '{name}' (known: {})", names.join(", "))
            })
    }

    /// Whether the beams go all the way round.
    pub fn full_turn(&self) -> bool {
        self.fov_deg >= 360.0
    }

    /// The first beam's bearing and the step, radians (the sensor's x axis forward, y
    /// left, as in ROS).
    pub fn angles(&self) -> (f64, f64) {
        if self.full_turn() {
            (-PI, TAU / self.beams as f64)
        } else {
            let fov = self.fov_deg.to_radians();
            (-0.5 * fov, fov / (self.beams - 1).max(1) as f64)
        }
    }
}

/// A surface of a scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Surface {
    /// A wall from one point to another (seen from both sides).
    Wall(Point, Point),
    /// A round obstacle: centre and radius (pillars, legs).
    Post(Point, f64),
}

/// A closed path the sensor drives round, at constant speed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Path {
    /// An ellipse: centre and semi-axes, counter-clockwise from its rightmost point.
    Ellipse(Point, f64, f64),
    /// A stadium: along `y0` from `x0` to `x1`, a half turn up to `y1`, back along `y1`,
    /// a half turn down.
    Stadium {
        /// Left end of the straights.
        x0: f64,
        /// Right end.
        x1: f64,
        /// The outbound straight.
        y0: f64,
        /// The return straight.
        y1: f64,
    },
}

impl Path {
    /// The pose at arc length `s` (wrapping round): position and the heading of travel.
    /// For many poses along one path, [`poses`](Path::poses) builds the ellipse's
    /// arc-length table once.
    pub fn pose_at(&self, s: f64) -> Pose {
        self.poses().at(s)
    }

    /// The path ready for pose queries.
    pub fn poses(&self) -> Poses {
        let arc = match *self {
            Path::Ellipse(c, a, b) => {
                // Arc length by a fine table; the step keeps the chord error far below
                // the sensor's noise.
                let at = |t: f64| add(c, [a * t.cos(), b * t.sin()]);
                let mut cum = Vec::with_capacity(ELLIPSE_STEPS + 1);
                cum.push(0.0);
                for k in 0..ELLIPSE_STEPS {
                    let t0 = TAU * k as f64 / ELLIPSE_STEPS as f64;
                    let t1 = TAU * (k + 1) as f64 / ELLIPSE_STEPS as f64;
                    cum.push(cum[k] + dist(at(t0), at(t1)));
                }
                cum
            }
            Path::Stadium { .. } => Vec::new(),
        };
        Poses { path: *self, arc }
    }
}

/// Steps of an ellipse path's arc-length table.
const ELLIPSE_STEPS: usize = 4096;

/// A [`Path`] with what its pose queries need computed once.
#[derive(Clone, Debug)]
pub struct Poses {
    path: Path,
    /// An ellipse's arc length at each of its table's steps.
    arc: Vec<f64>,
}

impl Poses {
    /// The pose at arc length `s` (wrapping round): position and the heading of travel.
    pub fn at(&self, s: f64) -> Pose {
        match self.path {
            Path::Ellipse(c, a, b) => {
                const N: usize = ELLIPSE_STEPS;
                let at = |t: f64| add(c, [a * t.cos(), b * t.sin()]);
                let cum = &self.arc;
                let total = cum[N];
                let s = s.rem_euclid(total);
                let k = cum.partition_point(|&x| x <= s).clamp(1, N) - 1;
                let f = (s - cum[k]) / (cum[k + 1] - cum[k]);
                let t = TAU * (k as f64 + f) / N as f64;
                let p = at(t);
                let tangent = [-a * t.sin(), b * t.cos()];
                [p[0], p[1], tangent[1].atan2(tangent[0])]
            }
            Path::Stadium { x0, x1, y0, y1 } => {
                let r = 0.5 * (y1 - y0);
                let ym = 0.5 * (y0 + y1);
                let straight = x1 - x0;
                let total = 2.0 * straight + TAU * r;
                let mut s = s.rem_euclid(total);
                if s < straight {
                    return [x0 + s, y0, 0.0];
                }
                s -= straight;
                if s < PI * r {
                    let a = -PI / 2.0 + s / r;
                    return [x1 + r * a.cos(), ym + r * a.sin(), a + PI / 2.0];
                }
                s -= PI * r;
                if s < straight {
                    return [x1 - s, y1, PI];
                }
                s -= straight;
                let a = PI / 2.0 + s / r;
                [x0 + r * a.cos(), ym + r * a.sin(), a + PI / 2.0]
            }
        }
    }
}

/// The scenes the simulator knows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SceneKind {
    /// A room of 8 x 6 m with two doorways into a larger hall.
    Room,
    /// A corridor 20 m long and 3 m wide with three side openings into rooms.
    Corridor,
    /// The room with two pillars, a table's four legs and a person's two legs.
    Clutter,
    /// A building's floor for long drives: a corridor 3 m wide round a loop of 926 m
    /// (two straights of 400 m joined by half turns), with a doorway every 50 m into a
    /// room of 6 x 4 m.
    Loop,
}

impl SceneKind {
    /// Every scene.
    pub const ALL: [SceneKind; 4] = [
        SceneKind::Room,
        SceneKind::Corridor,
        SceneKind::Clutter,
        SceneKind::Loop,
    ];

    /// The command-line name.
    pub fn name(self) -> &'static str {
        match self {
            SceneKind::Room => "room",
            SceneKind::Corridor => "corridor",
            SceneKind::Clutter => "clutter",
            SceneKind::Loop => "loop",
        }
    }

    /// The scene called `name`, if any.
    pub fn named(name: &str) -> Option<SceneKind> {
        Self::ALL.into_iter().find(|k| k.name() == name)
    }
}

/// A scene: surfaces, the openings in its walls (for scoring), where the sensor sits
/// and the path it drives.
#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    /// What is there.
    pub surfaces: Vec<Surface>,
    /// Doorways and side openings, as the segment across each.
    pub openings: Vec<(Point, Point)>,
    /// The static pose.
    pub home: Pose,
    /// The trajectory.
    pub path: Path,
    /// The line a walking person paces back and forth ([`LidarParams::walker`]).
    pub walk: (Point, Point),
}

/// A walking person's radius at a scanner's height, metres: a torso 0.4 m across.
pub const WALKER_RADIUS: f64 = 0.2;

impl Scene {
    /// Where a person walking at `speed` (m/s) from the start of [`Scene::walk`], back
    /// and forth along it, is at time `t` (seconds).
    pub fn walker_at(&self, speed: f64, t: f64) -> Point {
        let (a, b) = self.walk;
        let len = dist(a, b);
        if len == 0.0 {
            return a;
        }
        // Distance along the walk, folded into one back-and-forth lap.
        let s = (speed * t).rem_euclid(2.0 * len);
        let f = if s <= len { s / len } else { 2.0 - s / len };
        add(a, scale(sub(b, a), f))
    }
}

/// A wall from `a` to `b` with doorways: each `(from, to)` is cut out, as fractions of
/// the wall's length. Returns the wall pieces and the openings.
fn wall_with_doors(
    a: Point,
    b: Point,
    doors: &[(f64, f64)],
) -> (Vec<Surface>, Vec<(Point, Point)>) {
    let at = |f: f64| add(a, scale(sub(b, a), f));
    let mut walls = Vec::new();
    let mut openings = Vec::new();
    let mut from = 0.0;
    for &(d0, d1) in doors {
        walls.push(Surface::Wall(at(from), at(d0)));
        openings.push((at(d0), at(d1)));
        from = d1;
    }
    walls.push(Surface::Wall(at(from), at(1.0)));
    (walls, openings)
}

fn boxed(min: Point, max: Point) -> Vec<Surface> {
    let c = [
        [min[0], min[1]],
        [max[0], min[1]],
        [max[0], max[1]],
        [min[0], max[1]],
    ];
    (0..4)
        .map(|i| Surface::Wall(c[i], c[(i + 1) % 4]))
        .collect()
}

impl Scene {
    /// The scene of `kind`.
    pub fn new(kind: SceneKind) -> Scene {
        let mut surfaces = Vec::new();
        let mut openings = Vec::new();
        let mut add_wall = |a: Point, b: Point, doors: &[(f64, f64)]| {
            let (w, o) = wall_with_doors(a, b, doors);
            surfaces.extend(w);
            openings.extend(o);
        };
        match kind {
            SceneKind::Room | SceneKind::Clutter => {
                // Doorways 0.9 m wide: in the bottom wall at x = 2.0, in the right wall
                // at y = 3.5.
                add_wall([0.0, 0.0], [8.0, 0.0], &[(2.0 / 8.0, 2.9 / 8.0)]);
                add_wall([8.0, 0.0], [8.0, 6.0], &[(3.5 / 6.0, 4.4 / 6.0)]);
                add_wall([8.0, 6.0], [0.0, 6.0], &[]);
                add_wall([0.0, 6.0], [0.0, 0.0], &[]);
                // The hall around the room, seen through the doorways.
                surfaces.extend(boxed([-4.0, -5.0], [14.0, 10.0]));
                if kind == SceneKind::Clutter {
                    surfaces.extend([
                        Surface::Post([1.5, 4.8], 0.2),
                        Surface::Post([6.8, 1.0], 0.2),
                        Surface::Post([5.0, 4.6], 0.025),
                        Surface::Post([5.6, 4.6], 0.025),
                        Surface::Post([5.0, 5.1], 0.025),
                        Surface::Post([5.6, 5.1], 0.025),
                        Surface::Post([3.3, 1.0], 0.06),
                        Surface::Post([3.55, 1.05], 0.06),
                    ]);
                }
                Scene {
                    surfaces,
                    openings,
                    home: [4.0, 2.6, 0.3],
                    path: Path::Ellipse([4.0, 3.0], 2.0, 1.4),
                    // Across the room 1.4 m in front of the sensor's home, clear of
                    // the clutter's posts.
                    walk: ([1.0, 4.0], [7.0, 4.0]),
                }
            }
            SceneKind::Loop => Scene::floor_loop(),
            SceneKind::Corridor => {
                // Openings 1.0-1.2 m wide: two in the upper wall, one in the lower.
                add_wall([0.0, 0.0], [20.0, 0.0], &[(8.5 / 20.0, 9.5 / 20.0)]);
                add_wall(
                    [0.0, 3.0],
                    [20.0, 3.0],
                    &[(5.0 / 20.0, 6.0 / 20.0), (12.0 / 20.0, 13.2 / 20.0)],
                );
                add_wall([0.0, 0.0], [0.0, 3.0], &[]);
                add_wall([20.0, 0.0], [20.0, 3.0], &[]);
                // Side rooms behind the openings (their walls along the corridor are the
                // corridor's).
                for (x0, x1, y0, y1) in [
                    (11.0, 14.5, 3.0, 7.0),
                    (4.0, 7.0, 3.0, 6.5),
                    (7.5, 10.5, -4.0, 0.0),
                ] {
                    let far = if y1 > 3.0 { y1 } else { y0 };
                    surfaces.push(Surface::Wall([x0, far], [x1, far]));
                    let (near0, near1) = if y1 > 3.0 { (y0, y1) } else { (y1, y0) };
                    surfaces.push(Surface::Wall([x0, near0], [x0, near1]));
                    surfaces.push(Surface::Wall([x1, near0], [x1, near1]));
                }
                Scene {
                    surfaces,
                    openings,
                    home: [6.0, 1.4, 0.0],
                    // Along the corridor, 0.8 m from the upper wall.
                    walk: ([2.0, 2.2], [18.0, 2.2]),
                    path: Path::Stadium {
                        x0: 2.0,
                        x1: 18.0,
                        y0: 0.5,
                        y1: 2.5,
                    },
                }
            }
        }
    }

    /// [`SceneKind::Loop`]: the corridor's walls 1.5 m either side of the path, the
    /// half turns' walls as 48-gons (their chords are the truth, as every wall's is).
    fn floor_loop() -> Scene {
        const LENGTH: f64 = 400.0;
        const RADIUS: f64 = 20.0;
        const HALF_WIDTH: f64 = 1.5;
        const DOOR_EVERY: f64 = 50.0;
        let mut surfaces = Vec::new();
        let mut openings = Vec::new();
        let doors: Vec<(f64, f64)> = (0..(LENGTH / DOOR_EVERY) as usize)
            .map(|k| {
                let x = (k as f64 + 0.5) * DOOR_EVERY;
                ((x - 0.5) / LENGTH, (x + 0.5) / LENGTH)
            })
            .collect();
        let top = 2.0 * RADIUS;
        // The outer walls, with doorways into rooms beyond them; the inner walls whole.
        for (y_wall, room_far) in [
            (-HALF_WIDTH, -HALF_WIDTH - 4.0),
            (top + HALF_WIDTH, top + HALF_WIDTH + 4.0),
        ] {
            let (w, o) = wall_with_doors([0.0, y_wall], [LENGTH, y_wall], &doors);
            surfaces.extend(w);
            openings.extend(o);
            for &(d0, _) in &doors {
                let x = d0 * LENGTH + 0.5;
                surfaces.push(Surface::Wall([x - 3.0, y_wall], [x - 3.0, room_far]));
                surfaces.push(Surface::Wall([x - 3.0, room_far], [x + 3.0, room_far]));
                surfaces.push(Surface::Wall([x + 3.0, room_far], [x + 3.0, y_wall]));
            }
        }
        surfaces.push(Surface::Wall([0.0, HALF_WIDTH], [LENGTH, HALF_WIDTH]));
        surfaces.push(Surface::Wall(
            [0.0, top - HALF_WIDTH],
            [LENGTH, top - HALF_WIDTH],
        ));
        // The half turns: right round (LENGTH, RADIUS) from below, left round (0, RADIUS)
        // from above.
        const SIDES: usize = 48;
        for (cx, from) in [(LENGTH, -PI / 2.0), (0.0, PI / 2.0)] {
            for r in [RADIUS - HALF_WIDTH, RADIUS + HALF_WIDTH] {
                let at = |k: usize| {
                    let a = from + PI * k as f64 / SIDES as f64;
                    [cx + r * a.cos(), RADIUS + r * a.sin()]
                };
                for k in 0..SIDES {
                    surfaces.push(Surface::Wall(at(k), at(k + 1)));
                }
            }
        }
        Scene {
            surfaces,
            openings,
            home: [10.0, 0.0, 0.0],
            path: Path::Stadium {
                x0: 0.0,
                x1: LENGTH,
                y0: 0.0,
                y1: top,
            },
            // Along the lower straight, 0.8 m beside the path.
            walk: ([100.0, 0.8], [140.0, 0.8]),
        }
    }

    /// Every surface as a polyline (posts as 64-gons, chord error below 0.13% of the
    /// radius), for scoring against.
    pub fn polylines(&self) -> Vec<Polyline> {
        self.surfaces
            .iter()
            .map(|s| match *s {
                Surface::Wall(a, b) => Polyline {
                    closed: false,
                    points: vec![a, b],
                },
                Surface::Post(c, r) => Polyline {
                    closed: true,
                    points: (0..64)
                        .map(|k| {
                            let a = TAU * k as f64 / 64.0;
                            add(c, [r * a.cos(), r * a.sin()])
                        })
                        .collect(),
                },
            })
            .collect()
    }

    /// The nearest surface along the ray from `p` in direction `d` (unit): its index,
    /// the range, and the cosine of the incidence.
    pub fn cast(&self, p: Point, d: Point) -> Option<(usize, f64, f64)> {
        let mut best: Option<(usize, f64, f64)> = None;
        for (k, s) in self.surfaces.iter().enumerate() {
            let hit = match *s {
                Surface::Wall(a, b) => {
                    let e = sub(b, a);
                    let den = cross(d, e);
                    if den.abs() < 1e-15 {
                        None
                    } else {
                        let ap = sub(a, p);
                        let t = cross(ap, e) / den;
                        let u = cross(ap, d) / den;
                        (t > 1e-9 && (0.0..=1.0).contains(&u)).then(|| {
                            let n = norm(e);
                            (t, (cross(d, e) / n).abs())
                        })
                    }
                }
                Surface::Post(c, r) => {
                    let m = sub(p, c);
                    let b = dot(m, d);
                    let disc = b * b - (dot(m, m) - r * r);
                    (disc >= 0.0)
                        .then(|| -b - disc.sqrt())
                        .filter(|&t| t > 1e-9)
                        .map(|t| {
                            let h = add(p, scale(d, t));
                            let n = scale(sub(h, c), 1.0 / r);
                            (t, dot(d, n).abs())
                        })
                }
            };
            if let Some((t, cos)) = hit {
                if best.is_none_or(|b| t < b.1) {
                    best = Some((k, t, cos));
                }
            }
        }
        best
    }
}

/// Simulator options for a scanner.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub struct LidarParams {
    /// The scene.
    pub scene: SceneKind,
    /// The sensor.
    pub sensor: SensorModel,
    /// Range noise; default the sensor's.
    pub noise: Option<f64>,
    /// Probability that a beam returns nothing.
    pub dropout: f64,
    /// Probability that a beam returns a spurious short range.
    pub outliers: f64,
    /// Frames.
    pub frames: usize,
    /// Metres driven along the scene's path between frames (0: a static sensor).
    pub motion: f64,
    /// The static pose (or the trajectory's start), instead of the scene's.
    pub pose: Option<Pose>,
    /// A person walking back and forth along the scene's walk at this speed, m/s
    /// (a post of [`WALKER_RADIUS`]): seen in the scans and in each frame's truth, not
    /// in the scene's static surfaces. The person walks through the sensor's path as if
    /// it were not there.
    pub walker: Option<f64>,
    /// Beams taken one after another over the sensor's turn, as a spinning mirror takes
    /// them (a turn every `1 / rate_hz` seconds, the beams evenly spaced over it), while
    /// the sensor drives on along its path: each beam cast from where the sensor is at
    /// its own time, and the frames carry their beams' timing (`time_increment`). Off:
    /// every beam cast from the frame's pose, as if taken at once.
    pub sweep: bool,
    /// Seed.
    pub seed: u64,
}

impl LidarParams {
    /// Defaults: the Hokuyo UTM-30LX-like sensor, its noise, one static frame, seed 1.
    pub fn new(scene: SceneKind) -> LidarParams {
        LidarParams {
            scene,
            sensor: SensorModel::named("hokuyo-utm30lx").expect("a preset"),
            noise: None,
            dropout: 0.0,
            outliers: 0.0,
            frames: 1,
            motion: 0.0,
            pose: None,
            walker: None,
            sweep: false,
            seed: 1,
        }
    }

    /// Checks the options.
    pub fn validate(&self) -> Result<(), String> {
        let noise = self.noise.unwrap_or(self.sensor.noise);
        if !(noise.is_finite() && (0.0..1.0).contains(&noise)) {
            return Err(format!("--noise {noise} must be in [0, 1) metres"));
        }
        if !(0.0..=1.0).contains(&self.dropout) {
            return Err(format!("--dropout {} must be in [0, 1]", self.dropout));
        }
        if !(0.0..=1.0).contains(&self.outliers) {
            return Err(format!("--outliers {} must be in [0, 1]", self.outliers));
        }
        if !(self.motion.is_finite() && (0.0..=1.0).contains(&self.motion)) {
            return Err(format!(
                "--motion {} must be in [0, 1] metres per frame",
                self.motion
            ));
        }
        if let Some(v) = self.walker {
            if !(v.is_finite() && v > 0.0 && v <= 10.0) {
                return Err(format!("--walker {v} must be in (0, 10] metres per second"));
            }
        }
        if self.frames == 0 || self.frames > 1_000_000 {
            return Err("--frames must be in 1..=1000000".into());
        }
        if let Some(p) = self.pose {
            if !p.iter().all(|v| v.is_finite()) {
                return Err(format!("--pose {p:?} must be finite"));
            }
        }
        Ok(())
    }
}

/// One simulated scan.
#[derive(Clone, Debug, PartialEq)]
pub struct ScanFrame {
    /// Frame number, from 0.
    pub frame: u64,
    /// Time stamp, seconds (at the sensor's rate).
    pub t: f64,
    /// The sensor's pose in the scene.
    pub pose: Pose,
    /// Bearing of the first beam, radians, in the sensor frame.
    pub angle_min: f64,
    /// Angle between beams, radians.
    pub angle_increment: f64,
    /// Seconds from one beam to the next (0: taken at once, without
    /// [`LidarParams::sweep`]).
    pub time_increment: f64,
    /// Nearest valid range.
    pub range_min: f64,
    /// Farthest valid range.
    pub range_max: f64,
    /// Ranges; `None` where the beam returned nothing.
    pub ranges: Vec<Option<f64>>,
    /// What the sensor could see, in the sensor frame (see the module doc).
    pub truth: Vec<Polyline>,
    /// The scene's openings, in the sensor frame.
    pub openings: Vec<(Point, Point)>,
    /// Where the walking person is, in the scene's (world) coordinates.
    pub walker: Option<Point>,
}

pub use isoline_core::geom::{to_sensor, to_world};

impl ScanFrame {
    /// When the frame's beams were taken (`time_increment` 0 without
    /// [`LidarParams::sweep`]).
    pub fn sweep(&self) -> isoline_core::Sweep {
        isoline_core::Sweep {
            angle_min: self.angle_min,
            angle_increment: self.angle_increment,
            time_increment: self.time_increment,
        }
    }

    /// The frame as the core's scan (beams from the sensor at the origin).
    pub fn scan(&self) -> Result<isoline_core::Scan, isoline_core::Error> {
        isoline_core::Scan::from_laser(&isoline_core::LaserScan {
            origin: [0.0, 0.0],
            angle_min: self.angle_min,
            angle_increment: self.angle_increment,
            ranges: &self.ranges,
            range_min: self.range_min,
            range_max: self.range_max,
        })
    }
}

/// Simulates the scans.
pub fn simulate(params: &LidarParams) -> Result<Vec<ScanFrame>, String> {
    params.validate()?;
    let mut scene = Scene::new(params.scene);
    let statics = scene.surfaces.len();
    let sensor = &params.sensor;
    let sigma = params.noise.unwrap_or(sensor.noise);
    let normal = Normal::new(0.0, sigma.max(f64::MIN_POSITIVE)).expect("valid sigma");
    let (angle_min, step) = sensor.angles();
    let n = sensor.beams;
    let start = params.pose.unwrap_or(scene.home);
    // The path point nearest the start, so a trajectory begins where the sensor sits.
    let path = scene.path.poses();
    let s0 = if params.motion > 0.0 {
        (0..2000)
            .map(|k| {
                let s = k as f64 * 0.02;
                let p = path.at(s);
                (s, dist([p[0], p[1]], [start[0], start[1]]))
            })
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map_or(0.0, |(s, _)| s)
    } else {
        0.0
    };
    let mut frames = Vec::with_capacity(params.frames);
    for k in 0..params.frames {
        let mut rng =
            ChaCha8Rng::seed_from_u64(params.seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ k as u64);
        let pose = if params.motion > 0.0 {
            path.at(s0 + k as f64 * params.motion)
        } else {
            start
        };
        let walker = params
            .walker
            .map(|v| scene.walker_at(v, k as f64 / sensor.rate_hz));
        scene.surfaces.truncate(statics);
        scene
            .surfaces
            .extend(walker.map(|w| Surface::Post(w, WALKER_RADIUS)));
        let mut hits: Vec<Option<(usize, f64, f64)>> = Vec::with_capacity(n);
        let mut at: Vec<Option<Point>> = Vec::with_capacity(n);
        let mut seen = Vec::with_capacity(n);
        let mut ranges = Vec::with_capacity(n);
        for i in 0..n {
            // Where the sensor is when beam i is taken: i steps of a turn after the first.
            let beam_pose = if params.sweep && params.motion > 0.0 {
                path.at(s0 + (k as f64 + i as f64 * step / TAU) * params.motion)
            } else {
                pose
            };
            let a = beam_pose[2] + angle_min + i as f64 * step;
            let d = [a.cos(), a.sin()];
            let hit = scene
                .cast([beam_pose[0], beam_pose[1]], d)
                .filter(|h| h.1 < sensor.range_max && h.1 >= sensor.range_min);
            hits.push(hit);
            // The exact hit in the frame at its first beam's pose.
            at.push(hit.map(|(_, t, _)| {
                to_sensor(pose, [beam_pose[0] + t * d[0], beam_pose[1] + t * d[1]])
            }));
            // Draw every random number on every beam, so that one beam's fate does not
            // shift the others'.
            let (drop, spurious, frac, e) = (
                rng.random::<f64>(),
                rng.random::<f64>(),
                rng.random::<f64>(),
                normal.sample(&mut rng),
            );
            seen.push(hit.is_some() && drop >= params.dropout && spurious >= params.outliers);
            let r = hit.and_then(|(_, t, _)| {
                if drop < params.dropout {
                    return None;
                }
                let r = if spurious < params.outliers {
                    sensor.range_min + frac * (t - sensor.range_min)
                } else if sigma > 0.0 {
                    t + e
                } else {
                    t
                };
                (r >= sensor.range_min && r < sensor.range_max).then_some((r * 1e4).round() / 1e4)
            });
            ranges.push(r);
        }
        // A return noise pushed out of range is not seen either.
        for (s, r) in seen.iter_mut().zip(&ranges) {
            *s &= r.is_some();
        }
        let truth = visible(&hits, &at, &seen, sensor.full_turn());
        frames.push(ScanFrame {
            frame: k as u64,
            t: k as f64 / sensor.rate_hz,
            pose,
            angle_min,
            angle_increment: step,
            time_increment: if params.sweep {
                step / (TAU * sensor.rate_hz)
            } else {
                0.0
            },
            range_min: sensor.range_min,
            range_max: sensor.range_max,
            ranges,
            truth,
            openings: scene
                .openings
                .iter()
                .map(|&(a, b)| (to_sensor(pose, a), to_sensor(pose, b)))
                .collect(),
            walker,
        });
    }
    Ok(frames)
}

/// The visible truth in the sensor frame from each beam's exact hit (surface, range,
/// cosine of incidence) and where it lies (`at`, in the frame): see the module doc.
fn visible(
    hits: &[Option<(usize, f64, f64)>],
    at: &[Option<Point>],
    seen: &[bool],
    full_turn: bool,
) -> Vec<Polyline> {
    let min_cos = TRUTH_INCIDENCE_DEG.to_radians().cos();
    let n = hits.len();
    let point = |i: usize| at[i];
    let links = |i: usize, j: usize| match (hits[i], hits[j]) {
        (Some((si, _, ci)), Some((sj, _, cj))) => si == sj && ci >= min_cos && cj >= min_cos,
        _ => false,
    };
    // Stretches of beams linked to their successor.
    let mut stretches: Vec<Vec<usize>> = Vec::new();
    let mut cur: Vec<usize> = Vec::new();
    for (i, hit) in hits.iter().enumerate() {
        if hit.is_none() {
            continue;
        }
        if let Some(&last) = cur.last() {
            if last + 1 == i && links(last, i) {
                cur.push(i);
                continue;
            }
            stretches.push(std::mem::take(&mut cur));
        }
        cur.push(i);
    }
    if !cur.is_empty() {
        stretches.push(cur);
    }
    if full_turn && stretches.len() > 1 {
        let (first, last) = (stretches[0][0], *stretches.last().unwrap().last().unwrap());
        if first == 0 && last == n - 1 && links(n - 1, 0) {
            let head = stretches.remove(0);
            stretches.last_mut().unwrap().extend(head);
        }
    }
    // What the scan shows of each stretch: from its first beam that returned its range
    // to its last, split where more than TRUTH_MAX_DROPOUT beams in a row did not.
    let mut shown: Vec<Vec<usize>> = Vec::new();
    for s in stretches {
        let mut cur: Vec<usize> = Vec::new();
        let mut missing = 0;
        for &i in &s {
            if seen[i] {
                if missing > TRUTH_MAX_DROPOUT && !cur.is_empty() {
                    shown.push(std::mem::take(&mut cur));
                } else if !cur.is_empty() {
                    let last = *cur.last().expect("not empty");
                    cur.extend(
                        s.iter()
                            .copied()
                            .skip_while(|&j| j != last)
                            .skip(1)
                            .take_while(|&j| j != i),
                    );
                }
                cur.push(i);
                missing = 0;
            } else {
                missing += 1;
            }
        }
        if !cur.is_empty() {
            shown.push(cur);
        }
    }
    shown
        .into_iter()
        .filter(|s| s.iter().filter(|&&i| seen[i]).count() >= TRUTH_MIN_BEAMS)
        .map(|s| Polyline {
            closed: false,
            points: s.iter().filter_map(|&i| point(i)).collect(),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The long drive keeps to the middle of its corridor all the way round (1.5 m from
    /// the walls, less the half turns' chord sag), so no scan starts inside a wall.
    #[test]
    fn the_loop_drive_keeps_to_its_corridor() {
        let scene = Scene::new(SceneKind::Loop);
        let walls = isoline_core::SegmentIndex::new(&scene.polylines());
        let path = scene.path.poses();
        for k in 0..2000 {
            let p = path.at(k as f64 * 0.5);
            let d = walls.distance([p[0], p[1]]);
            assert!((1.45..=1.5 + 1e-9).contains(&d), "{p:?}: {d} m from a wall");
        }
    }

    /// The walker paces its line back and forth at its speed, and the scans see it:
    /// the beam towards it returns its near side.
    #[test]
    fn the_walker_paces_its_line_and_is_seen() {
        let scene = Scene::new(SceneKind::Room);
        let (a, b) = scene.walk;
        let len = dist(a, b);
        assert!(dist(scene.walker_at(1.0, 0.0), a) < 1e-12);
        assert!(dist(scene.walker_at(1.0, len), b) < 1e-12);
        assert!(dist(scene.walker_at(2.0, len), a) < 1e-12);
        let mid = scene.walker_at(1.0, 0.5 * len);
        assert!(dist(mid, add(a, scale(sub(b, a), 0.5))) < 1e-12);
        let mut p = LidarParams::new(SceneKind::Room);
        p.noise = Some(0.0);
        p.walker = Some(1.0);
        p.frames = 2;
        // Facing the walk's start.
        p.pose = Some([4.0, 2.6, 2.4]);
        let frames = simulate(&p).unwrap();
        let w = frames[1].walker.unwrap();
        assert!(dist(w, scene.walker_at(1.0, frames[1].t)) < 1e-12);
        // The beam from the sensor towards the walker's centre returns the distance to
        // its near side.
        let pose = frames[1].pose;
        let to = to_sensor(pose, w);
        let bearing = to[1].atan2(to[0]);
        let i = ((bearing - frames[1].angle_min) / frames[1].angle_increment).round() as usize;
        let r = frames[1].ranges[i].unwrap();
        assert!((r - (norm(to) - WALKER_RADIUS)).abs() < 1e-3, "{r}");
        p.walker = Some(f64::NAN);
        assert!(p.validate().is_err());
    }

    #[test]
    fn presets_and_poses() {
        let h = SensorModel::named("hokuyo-utm30lx").unwrap();
        let (a0, step) = h.angles();
        assert!((a0 + 135f64.to_radians()).abs() < 1e-12);
        assert!((a0 + step * 1079.0 - 135f64.to_radians()).abs() < 1e-12);
        let r = SensorModel::named("rplidar-a1").unwrap();
        assert!(r.full_turn() && (r.angles().1 - 1f64.to_radians()).abs() < 1e-12);
        assert!(SensorModel::named("nope").is_err());
        let pose = [1.0, 2.0, 0.7];
        let p = [3.0, -1.0];
        let q = to_world(pose, to_sensor(pose, p));
        assert!(dist(p, q) < 1e-12);
        // Paths are continuous and turn at most 1 / radius per metre.
        for path in [
            Scene::new(SceneKind::Room).path,
            Scene::new(SceneKind::Corridor).path,
        ] {
            let path = path.poses();
            let mut last = path.at(0.0);
            for k in 1..2000 {
                let p = path.at(k as f64 * 0.02);
                assert!(dist([p[0], p[1]], [last[0], last[1]]) <= 0.0201, "{k}");
                let turn = (p[2] - last[2] + PI).rem_euclid(TAU) - PI;
                assert!(turn.abs() <= 0.021, "{k}: {turn}");
                last = p;
            }
        }
    }

    #[test]
    fn a_static_scan_sees_the_walls_at_their_range_and_the_doorways_open() {
        let mut p = LidarParams::new(SceneKind::Room);
        p.noise = Some(0.0);
        let f = &simulate(&p).unwrap()[0];
        assert_eq!(f.ranges.len(), 1080);
        let pose = f.pose;
        let scene = Scene::new(SceneKind::Room);
        // Every return lies on a surface of the scene.
        for (i, r) in f.ranges.iter().enumerate() {
            let Some(r) = r else { continue };
            let a = f.angle_min + i as f64 * f.angle_increment;
            let w = to_world(pose, [r * a.cos(), r * a.sin()]);
            let on = scene.surfaces.iter().any(|s| match *s {
                Surface::Wall(a, b) => isoline_core::geom::point_segment_dist2(w, a, b).0 < 1e-8,
                Surface::Post(c, rad) => (dist(w, c) - rad).abs() < 1e-4,
            });
            assert!(on, "beam {i}: {w:?}");
        }
        // The truth is on the walls too, and never spans a doorway.
        assert!(f.truth.len() >= 4, "{}", f.truth.len());
        for pl in &f.truth {
            for s in pl.segments() {
                for &(a, b) in &f.openings {
                    let m = isoline_core::geom::mid(a, b);
                    let d = isoline_core::geom::point_segment_dist2(m, s.0, s.1)
                        .0
                        .sqrt();
                    assert!(d > 0.3, "truth crosses the opening at {m:?}");
                }
            }
        }
    }

    #[test]
    fn noise_dropout_and_determinism() {
        let mut p = LidarParams::new(SceneKind::Corridor);
        p.dropout = 0.1;
        p.frames = 3;
        p.motion = 0.1;
        let a = simulate(&p).unwrap();
        assert_eq!(a, simulate(&p).unwrap());
        let clean = {
            let mut q = p.clone();
            q.dropout = 0.0;
            q.noise = Some(0.0);
            simulate(&q).unwrap()
        };
        for (f, c) in a.iter().zip(&clean) {
            // Dropout shortens or splits the truth, never extends it.
            let len = |t: &[Polyline]| t.iter().map(|p| p.length()).sum::<f64>();
            assert!(len(&f.truth) <= len(&c.truth) + 1e-9);
            assert!(
                len(&f.truth) >= 0.8 * len(&c.truth),
                "{} {}",
                len(&f.truth),
                len(&c.truth)
            );
            let valid = c.ranges.iter().filter(|r| r.is_some()).count();
            let dropped = f.ranges.iter().filter(|r| r.is_none()).count()
                - c.ranges.iter().filter(|r| r.is_none()).count();
            // Binomial(valid, 0.1): within 5 standard deviations.
            let sd = (valid as f64 * 0.09).sqrt();
            assert!(
                (dropped as f64 - 0.1 * valid as f64).abs() < 5.0 * sd,
                "{dropped} of {valid}"
            );
            let moved = dist([f.pose[0], f.pose[1]], [a[0].pose[0], a[0].pose[1]]);
            assert!(moved <= 0.1 * f.frame as f64 + 1e-9);
        }
    }
}
