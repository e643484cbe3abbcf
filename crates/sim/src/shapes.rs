//! Digitized shapes with ground truth, deterministic in the seed: sampled with noise,
//! outliers, uneven density and rigid motion between frames.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use std::f64::consts::{PI, TAU};
use std::str::FromStr;

use isoline_core::geom::{add, dist, sub, Point, Polyline};

/// Segments per smooth closed curve in the truth polylines: chord error
/// `r (1 - cos(pi / n))` below 2e-6 at radius 0.4, far below any mesh size in use.
const SMOOTH_SEGMENTS: usize = 1024;

/// The shapes the simulator knows, all inside the unit square around (0.5, 0.5).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Shape {
    /// Circle of radius 0.4.
    Circle,
    /// Ellipse with semi-axes 0.4 and 0.25.
    Ellipse,
    /// Square of side 0.6 (sharp corners).
    Square,
    /// Smooth five-lobed star `r = 0.3 (1 + 0.3 cos 5t)` (non-convex).
    Star,
    /// A 'C': an annular sector with round caps (deeply non-convex).
    CShape,
    /// Two disjoint circles of radius 0.18.
    TwoCircles,
    /// An annulus: circles of radius 0.4 and 0.2 (a shape with a hole).
    Annulus,
    /// A band wound as an Archimedean spiral, its centre line from radius 0.1 out to
    /// 0.4 with round caps: the band and the corridor between its turns are both `gap`
    /// wide, so every wall lies `gap` from the next.
    Spiral,
    /// A disc of radius 0.4 with three round bays of radius 0.09 inside it, each
    /// reached from outside through a straight inlet `gap` wide.
    Bays,
    /// A line drawing of five open strokes: two T-junctions, one crossing, and a free
    /// stroke touching nothing. Each stroke's two ends are among the samples, as a
    /// pen records where it touches down and lifts; the rest lie at random along the
    /// strokes.
    Strokes,
}

impl Shape {
    /// Every shape, for help texts and sweeps.
    pub const ALL: [Shape; 10] = [
        Shape::Circle,
        Shape::Ellipse,
        Shape::Square,
        Shape::Star,
        Shape::CShape,
        Shape::TwoCircles,
        Shape::Annulus,
        Shape::Spiral,
        Shape::Bays,
        Shape::Strokes,
    ];

    /// The command-line name.
    pub fn name(self) -> &'static str {
        match self {
            Shape::Circle => "circle",
            Shape::Ellipse => "ellipse",
            Shape::Square => "square",
            Shape::Star => "star",
            Shape::CShape => "c",
            Shape::TwoCircles => "two-circles",
            Shape::Annulus => "annulus",
            Shape::Spiral => "spiral",
            Shape::Bays => "bays",
            Shape::Strokes => "strokes",
        }
    }

    /// The exact curves (smooth ones as fine polygons), counter-clockwise outer loops and
    /// clockwise holes; open polylines for the strokes. `gap` is the spiral's and the
    /// inlets' width (see [`SynthParams::gap`]); the other shapes ignore it.
    pub fn truth(self, gap: f64) -> Vec<Polyline> {
        let c = [0.5, 0.5];
        match self {
            Shape::Circle => vec![ellipse(c, 0.4, 0.4)],
            Shape::Ellipse => vec![ellipse(c, 0.4, 0.25)],
            Shape::Square => vec![Polyline {
                closed: true,
                points: vec![[0.2, 0.2], [0.8, 0.2], [0.8, 0.8], [0.2, 0.8]],
            }],
            Shape::Star => vec![polar(c, |t| 0.3 * (1.0 + 0.3 * (5.0 * t).cos()))],
            Shape::CShape => vec![c_shape(c)],
            Shape::TwoCircles => vec![
                ellipse([0.28, 0.5], 0.18, 0.18),
                ellipse([0.72, 0.5], 0.18, 0.18),
            ],
            Shape::Annulus => {
                let mut hole = ellipse(c, 0.2, 0.2);
                hole.points.reverse();
                vec![ellipse(c, 0.4, 0.4), hole]
            }
            Shape::Spiral => vec![spiral(c, gap)],
            Shape::Bays => vec![bays(c, gap)],
            Shape::Strokes => strokes(),
        }
    }

    /// Whether the shape is a drawing of open strokes rather than closed curves.
    pub fn is_open(self) -> bool {
        self == Shape::Strokes
    }
}

impl FromStr for Shape {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Shape::ALL
            .into_iter()
            .find(|sh| sh.name() == s)
            .ok_or_else(|| {
                let names: Vec<_> = Shape::ALL.iter().map(|s| s.name()).collect();
                format!("unknown shape '{s}' (known: {})", names.join(", "))
            })
    }
}

fn polar(c: Point, r: impl Fn(f64) -> f64) -> Polyline {
    let points = (0..SMOOTH_SEGMENTS)
        .map(|i| {
            let t = TAU * i as f64 / SMOOTH_SEGMENTS as f64;
            add(c, [r(t) * t.cos(), r(t) * t.sin()])
        })
        .collect();
    Polyline {
        closed: true,
        points,
    }
}

fn ellipse(c: Point, a: f64, b: f64) -> Polyline {
    let points = (0..SMOOTH_SEGMENTS)
        .map(|i| {
            let t = TAU * i as f64 / SMOOTH_SEGMENTS as f64;
            add(c, [a * t.cos(), b * t.sin()])
        })
        .collect();
    Polyline {
        closed: true,
        points,
    }
}

/// Outer arc radius 0.38 and inner 0.22 over angles [45, 315] degrees, joined by
/// semicircular caps, traversed counter-clockwise.
fn c_shape(c: Point) -> Polyline {
    let (ro, ri) = (0.38, 0.22);
    let (a0, a1) = (PI / 4.0, 7.0 * PI / 4.0);
    let rc = 0.5 * (ro - ri);
    let rm = 0.5 * (ro + ri);
    let n = SMOOTH_SEGMENTS / 4;
    let at = |r: f64, a: f64| add(c, [r * a.cos(), r * a.sin()]);
    let mut pts = Vec::new();
    for i in 0..n {
        pts.push(at(ro, a0 + (a1 - a0) * i as f64 / n as f64));
    }
    // Cap at a1: from the outer to the inner arc, around the cap centre.
    let cc = at(rm, a1);
    for i in 0..n / 4 {
        let t = a1 + PI * i as f64 / (n / 4) as f64;
        pts.push(add(cc, [rc * t.cos(), rc * t.sin()]));
    }
    for i in 0..n {
        pts.push(at(ri, a1 - (a1 - a0) * i as f64 / n as f64));
    }
    let cc = at(rm, a0);
    for i in 0..n / 4 {
        let t = a0 + PI + PI * i as f64 / (n / 4) as f64;
        pts.push(add(cc, [rc * t.cos(), rc * t.sin()]));
    }
    Polyline {
        closed: true,
        points: pts,
    }
}

/// The spiral band: its centre line `r = 0.1 + (2 gap / 2 pi) t` for `t` from 0 to the
/// turn reaching radius 0.4, walls `gap / 2` either side of it along the radius (the
/// Archimedean spiral's normal is within `atan(2 gap / (2 pi r))`, a few degrees, of the
/// radius), joined by half-circle caps; counter-clockwise round the band.
fn spiral(c: Point, gap: f64) -> Polyline {
    let pitch = 2.0 * gap;
    let (r0, r1) = (0.1, 0.4 - 0.5 * gap);
    let turns = (r1 - r0) / pitch;
    let t1 = TAU * turns;
    let n = (SMOOTH_SEGMENTS as f64 * turns).ceil() as usize;
    let at = |t: f64, off: f64| {
        let r = r0 + pitch * t / TAU + off;
        add(c, [r * t.cos(), r * t.sin()])
    };
    let h = 0.5 * gap;
    let mut pts: Vec<Point> = (0..=n).map(|i| at(t1 * i as f64 / n as f64, -h)).collect();
    // The outer cap turns from the inner wall to the outer one around the centre line's
    // end, on the far side of its tangent.
    let cap = |t: f64, forward: bool, pts: &mut Vec<Point>| {
        let m = at(t, 0.0);
        let (s, co) = t.sin_cos();
        let radial = [co, s];
        let tangent = if forward { [-s, co] } else { [s, -co] };
        for i in 1..SMOOTH_SEGMENTS / 16 {
            let a = PI * i as f64 / (SMOOTH_SEGMENTS / 16) as f64;
            let (sa, ca) = a.sin_cos();
            let sign = if forward { 1.0 } else { -1.0 };
            pts.push(add(
                m,
                [
                    h * (-ca * radial[0] * sign + sa * tangent[0]),
                    h * (-ca * radial[1] * sign + sa * tangent[1]),
                ],
            ));
        }
    };
    cap(t1, true, &mut pts);
    pts.extend((0..=n).rev().map(|i| at(t1 * i as f64 / n as f64, h)));
    cap(0.0, false, &mut pts);
    // Out along the inner wall with the centre on the left is clockwise round the band.
    pts.reverse();
    Polyline {
        closed: true,
        points: pts,
    }
}

/// The disc with bays: outer circle radius 0.4; bays of radius 0.09 centred 0.2 from the
/// centre at 90, 210 and 330 degrees, each joined to the outside by an inlet of width
/// `gap` along its radius. Traced counter-clockwise: along the outer circle, in along
/// an inlet's first wall, clockwise round the bay, out along the other wall.
fn bays(c: Point, gap: f64) -> Polyline {
    let (big, bay, at_r) = (0.4, 0.09, 0.2);
    let o = 0.5 * gap.min(1.6 * bay);
    let alpha = (o / big).asin();
    let mut pts = Vec::new();
    let arc_steps = |span: f64, r: f64| {
        ((SMOOTH_SEGMENTS as f64 * span.abs() * r / (TAU * 0.4)).ceil() as usize).max(2)
    };
    let dirs: Vec<f64> = [90.0f64, 210.0, 330.0]
        .iter()
        .map(|d| d.to_radians())
        .collect();
    for (k, &phi) in dirs.iter().enumerate() {
        let u = [phi.cos(), phi.sin()];
        let v = [-phi.sin(), phi.cos()];
        let at = |t: f64, off: f64| add(c, [t * u[0] + off * v[0], t * u[1] + off * v[1]]);
        // The wall at offset -o, from the outer circle in to the bay.
        let (t_out, t_in) = (
            (big * big - o * o).sqrt(),
            at_r + (bay * bay - o * o).sqrt(),
        );
        let wall = |pts: &mut Vec<Point>, off: f64, inwards: bool| {
            let m = ((t_out - t_in) / 0.002).ceil().max(1.0) as usize;
            for i in 0..m {
                let f = i as f64 / m as f64;
                let t = if inwards {
                    t_out + (t_in - t_out) * f
                } else {
                    t_in + (t_out - t_in) * f
                };
                pts.push(at(t, off));
            }
        };
        wall(&mut pts, -o, true);
        // Clockwise round the bay from angle -gamma to gamma - 2 pi (in the u, v frame).
        let gamma = (o / bay).asin();
        let span = TAU - 2.0 * gamma;
        let m = arc_steps(span, bay);
        let centre = at(at_r, 0.0);
        for i in 0..m {
            let b = -gamma - span * i as f64 / m as f64;
            let (sb, cb) = b.sin_cos();
            pts.push(add(
                centre,
                [bay * (cb * u[0] + sb * v[0]), bay * (cb * u[1] + sb * v[1])],
            ));
        }
        wall(&mut pts, o, false);
        // The outer circle to the next inlet.
        let next = dirs[(k + 1) % dirs.len()] + if k + 1 == dirs.len() { TAU } else { 0.0 };
        let (a0, a1) = (phi + alpha, next - alpha);
        let m = arc_steps(a1 - a0, big);
        for i in 0..m {
            let a = a0 + (a1 - a0) * i as f64 / m as f64;
            pts.push(add(c, [big * a.cos(), big * a.sin()]));
        }
    }
    Polyline {
        closed: true,
        points: pts,
    }
}

/// The stroke drawing: a baseline; a stem standing on it (a T-junction); a wave crossing
/// the stem; a hook standing on the baseline (a second T-junction) and ending free; and
/// a free arc below.
fn strokes() -> Vec<Polyline> {
    let open = |points: Vec<Point>| Polyline {
        closed: false,
        points,
    };
    let curve = |f: &dyn Fn(f64) -> Point| -> Polyline {
        open((0..=256).map(|i| f(i as f64 / 256.0)).collect())
    };
    vec![
        open(vec![[0.08, 0.3], [0.92, 0.3]]),
        open(vec![[0.45, 0.3], [0.45, 0.92]]),
        curve(&|s| [0.1 + 0.8 * s, 0.62 + 0.08 * (TAU * s).sin()]),
        curve(&|s| {
            let a = PI * (1.0 - 0.5 * s);
            [0.88 + 0.16 * a.cos(), 0.3 + 0.16 * a.sin()]
        }),
        curve(&|s| {
            let a = PI * (0.15 + 0.7 * s);
            [0.5 + 0.3 * a.cos(), 0.35 - 0.25 * a.sin()]
        }),
    ]
}

/// Simulator options.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub struct SynthParams {
    /// The shape.
    pub shape: Shape,
    /// Points per frame (outliers included).
    pub points: usize,
    /// Standard deviation of the Gaussian noise on each coordinate.
    pub noise: f64,
    /// Fraction of points replaced by outliers uniform over the shape's padded box.
    pub outliers: f64,
    /// Sampling density varies along the curve by a factor `(1 + a) / (1 - a)`; 0 is
    /// uniform, must be in [0, 1).
    pub density_variation: f64,
    /// Number of frames.
    pub frames: usize,
    /// Largest displacement of a curve point between frames (rotation about the shape's
    /// centre plus a translation along a slowly turning direction).
    pub motion: f64,
    /// Seed.
    pub seed: u64,
    /// Frame rate written in the `t` field.
    pub rate_hz: f64,
    /// The spiral's turn spacing and the bays' inlet width. Default 0.05.
    pub gap: f64,
}

impl SynthParams {
    /// Defaults for `shape`: 2,000 points, no noise, one frame, seed 1.
    pub fn new(shape: Shape) -> Self {
        SynthParams {
            shape,
            points: 2000,
            noise: 0.0,
            outliers: 0.0,
            density_variation: 0.0,
            frames: 1,
            motion: 0.0,
            seed: 1,
            rate_hz: 20.0,
            gap: 0.05,
        }
    }

    /// With `points` points per frame.
    pub fn with_points(mut self, points: usize) -> Self {
        self.points = points;
        self
    }

    /// With Gaussian noise of standard deviation `noise`.
    pub fn with_noise(mut self, noise: f64) -> Self {
        self.noise = noise;
        self
    }

    /// With the spiral's turn spacing or the bays' inlet width `gap`.
    pub fn with_gap(mut self, gap: f64) -> Self {
        self.gap = gap;
        self
    }

    /// With the seed `seed`.
    pub fn with_seed(mut self, seed: u64) -> Self {
        self.seed = seed;
        self
    }

    /// Checks the options.
    pub fn validate(&self) -> Result<(), String> {
        if self.points == 0 {
            return Err("--points must be at least 1".into());
        }
        if !(self.noise.is_finite() && self.noise >= 0.0) {
            return Err(format!("--noise {} must be >= 0", self.noise));
        }
        if !(0.0..=1.0).contains(&self.outliers) {
            return Err(format!("--outliers {} must be in [0, 1]", self.outliers));
        }
        if !(0.0..1.0).contains(&self.density_variation) {
            return Err(format!(
                "--density {} must be in [0, 1)",
                self.density_variation
            ));
        }
        if !(self.motion.is_finite() && self.motion >= 0.0) {
            return Err(format!("--motion {} must be >= 0", self.motion));
        }
        if self.frames == 0 {
            return Err("--frames must be at least 1".into());
        }
        // The spiral needs a turn between radius 0.1 and 0.4, and an inlet must fit in
        // its bay.
        if !(self.gap.is_finite() && (0.001..=0.12).contains(&self.gap)) {
            return Err(format!("--gap {} must be in [0.001, 0.12]", self.gap));
        }
        Ok(())
    }
}

/// One simulated frame.
#[derive(Clone, Debug, PartialEq)]
pub struct SynthFrame {
    /// Frame number, from 0.
    pub frame: u64,
    /// Time stamp in seconds.
    pub t: f64,
    /// The points, in random order.
    pub points: Vec<Point>,
    /// The exact curves of this frame.
    pub truth: Vec<Polyline>,
}

/// The rigid motion of frame `k`: rotation about `c` then translation.
fn motion_of(k: usize, motion: f64, c: Point) -> impl Fn(Point) -> Point {
    // A point at radius 0.4 moves by `motion / 2` from the rotation and the centre by
    // `motion / 2` along a direction turning 0.05 rad per frame, so the shape circles
    // within 10 * motion of where it started instead of drifting away.
    let angle = k as f64 * 0.5 * motion / 0.4;
    let (s, co) = angle.sin_cos();
    let step = 0.5 * motion;
    let shift = (0..k).fold([0.0, 0.0], |acc, j| {
        let th = 0.05 * j as f64;
        add(acc, [step * th.cos(), step * th.sin()])
    });
    move |p: Point| {
        let q = sub(p, c);
        add(add(c, [co * q[0] - s * q[1], s * q[0] + co * q[1]]), shift)
    }
}

/// Generates the frames.
pub fn generate(params: &SynthParams) -> Result<Vec<SynthFrame>, String> {
    params.validate()?;
    let base = params.shape.truth(params.gap);
    let center = [0.5, 0.5];
    // Cumulative arc length over all segments of all components.
    let segs: Vec<(Point, Point)> = base
        .iter()
        .flat_map(|pl| pl.segments().collect::<Vec<_>>())
        .collect();
    let mut cum = Vec::with_capacity(segs.len() + 1);
    cum.push(0.0);
    for (a, b) in &segs {
        cum.push(cum.last().unwrap() + dist(*a, *b));
    }
    let total = *cum.last().unwrap();
    let normal = Normal::new(0.0, params.noise.max(f64::MIN_POSITIVE)).expect("valid sigma");
    let a = params.density_variation;
    let mut frames = Vec::with_capacity(params.frames);
    for k in 0..params.frames {
        let mut rng =
            ChaCha8Rng::seed_from_u64(params.seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ k as u64);
        let mv = motion_of(k, params.motion, center);
        let n_out = (params.outliers * params.points as f64).round() as usize;
        let mut points = Vec::with_capacity(params.points);
        // A pen's stroke is recorded from where it touches down to where it lifts: the
        // ends of open curves are samples, drawn after the random ones so that those
        // stay the stream's first draws. Without them a stroke's last sample lies an
        // exponential gap short of its end (7e-3 past it in the clean drawing), which
        // no reconstruction from the samples can know.
        let ends: Vec<Point> = base
            .iter()
            .filter(|pl| !pl.closed)
            .flat_map(|pl| [pl.points[0], pl.points[pl.points.len() - 1]])
            .take(params.points - n_out)
            .collect();
        while points.len() + ends.len() < params.points - n_out {
            let s = rng.random::<f64>() * total;
            // Density (1 + a sin(6 pi s / L)) / (1 + a), by rejection.
            if a > 0.0 && rng.random::<f64>() * (1.0 + a) > 1.0 + a * (3.0 * TAU * s / total).sin()
            {
                continue;
            }
            let i = cum.partition_point(|&c| c <= s).clamp(1, segs.len()) - 1;
            let (p, q) = segs[i];
            let len = cum[i + 1] - cum[i];
            let f = if len > 0.0 { (s - cum[i]) / len } else { 0.0 };
            let mut x = add(p, [(q[0] - p[0]) * f, (q[1] - p[1]) * f]);
            if params.noise > 0.0 {
                x = add(x, [normal.sample(&mut rng), normal.sample(&mut rng)]);
            }
            points.push(mv(x));
        }
        for &x in &ends {
            let x = if params.noise > 0.0 {
                add(x, [normal.sample(&mut rng), normal.sample(&mut rng)])
            } else {
                x
            };
            points.push(mv(x));
        }
        for _ in 0..n_out {
            let x = [
                rng.random::<f64>() * 1.2 - 0.1,
                rng.random::<f64>() * 1.2 - 0.1,
            ];
            points.push(mv(x));
        }
        // Unorganised: no ordering information survives.
        for i in (1..points.len()).rev() {
            let j = rng.random_range(0..=i);
            points.swap(i, j);
        }
        let truth = base
            .iter()
            .map(|pl| Polyline {
                closed: pl.closed,
                points: pl.points.iter().map(|&p| mv(p)).collect(),
            })
            .collect();
        frames.push(SynthFrame {
            frame: k as u64,
            t: k as f64 / params.rate_hz,
            points,
            truth,
        });
    }
    Ok(frames)
}

#[cfg(test)]
mod tests {
    use super::*;
    use isoline_core::SegmentIndex;

    #[test]
    fn deterministic_and_on_the_curve_within_the_noise() {
        for shape in Shape::ALL {
            let mut p = SynthParams::new(shape);
            p.points = 500;
            p.noise = 0.001;
            p.frames = 3;
            p.motion = 0.01;
            let a = generate(&p).unwrap();
            assert_eq!(a, generate(&p).unwrap(), "{shape:?} not deterministic");
            for f in &a {
                assert_eq!(f.points.len(), 500);
                let idx = SegmentIndex::new(&f.truth);
                let worst = f
                    .points
                    .iter()
                    .map(|&q| idx.distance(q))
                    .fold(0.0, f64::max);
                // Gaussian noise in 2D: |offset| > 6 sigma has probability e^-18 per point.
                assert!(worst < 6.0 * 0.001, "{shape:?} {worst}");
            }
        }
    }

    #[test]
    fn truth_orientation_and_motion_are_rigid() {
        let ann = Shape::Annulus.truth(0.05);
        assert!(ann[0].signed_area() > 0.0 && ann[1].signed_area() < 0.0);
        assert!(Shape::CShape.truth(0.05)[0].signed_area() > 0.0);
        // The spiral's walls and the bays' inlet walls lie `gap` apart, the band's area
        // is its centre line's length times `gap`, and the bays cut their area (with
        // the inlets') out of the disc.
        for gap in [0.02, 0.05] {
            let sp = &Shape::Spiral.truth(gap)[0];
            let area = sp.signed_area();
            let centre_line = 0.5 * sp.length() - gap;
            assert!(
                (area / (centre_line * gap) - 1.0).abs() < 0.02,
                "{gap}: {area}"
            );
            let bays = &Shape::Bays.truth(gap)[0];
            let cut = 3.0 * (PI * 0.09 * 0.09 + gap * (0.4 - 0.2 - 0.09));
            let expected = PI * 0.16 - cut;
            assert!((bays.signed_area() / expected - 1.0).abs() < 0.01, "{gap}");
        }
        let strokes = Shape::Strokes.truth(0.05);
        assert!(Shape::Strokes.is_open() && strokes.iter().all(|s| !s.closed));
        assert_eq!(strokes.len(), 5);
        // Every stroke's ends are samples; closed shapes' samples are all random.
        let mut p = SynthParams::new(Shape::Strokes);
        p.points = 100;
        let points = &generate(&p).unwrap()[0].points;
        assert_eq!(points.len(), 100);
        for end in strokes
            .iter()
            .flat_map(|s| [s.points[0], *s.points.last().unwrap()])
        {
            assert!(points.iter().any(|&q| dist(q, end) < 1e-12), "{end:?}");
        }
        let mut p = SynthParams::new(Shape::Square);
        p.frames = 5;
        p.motion = 0.02;
        let f = generate(&p).unwrap();
        let side = |pl: &Polyline| dist(pl.points[0], pl.points[1]);
        assert!((side(&f[4].truth[0]) - 0.6).abs() < 1e-12);
        let moved = dist(f[0].truth[0].points[0], f[1].truth[0].points[0]);
        assert!(moved > 0.0 && moved <= 0.02 + 1e-12, "{moved}");
    }

    #[test]
    fn outliers_and_bad_options() {
        let mut p = SynthParams::new(Shape::Circle);
        p.outliers = 0.1;
        let f = &generate(&p).unwrap()[0];
        let idx = SegmentIndex::new(&f.truth);
        let far = f.points.iter().filter(|&&q| idx.distance(q) > 0.01).count();
        assert!((150..=200).contains(&far), "{far}");
        p.density_variation = 1.0;
        assert!(generate(&p).is_err());
    }
}
