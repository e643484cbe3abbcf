//! Plain 2D geometry: points as `[f64; 2]`, exact orientation, bounding boxes, segment
//! distances and symmetric 2x2 tensors (metrics and Hessians).

/// A point or vector in the plane.
pub type Point = [f64; 2];

/// `a - b`.
#[inline]
pub fn sub(a: Point, b: Point) -> Point {
    [a[0] - b[0], a[1] - b[1]]
}

/// `a + b`.
#[inline]
pub fn add(a: Point, b: Point) -> Point {
    [a[0] + b[0], a[1] + b[1]]
}

/// `s * a`.
#[inline]
pub fn scale(a: Point, s: f64) -> Point {
    [a[0] * s, a[1] * s]
}

/// Dot product.
#[inline]
pub fn dot(a: Point, b: Point) -> f64 {
    a[0] * b[0] + a[1] * b[1]
}

/// z-component of the cross product.
#[inline]
pub fn cross(a: Point, b: Point) -> f64 {
    a[0] * b[1] - a[1] * b[0]
}

/// Euclidean norm. Not `hypot`: input coordinates are validated below 1e150, so the
/// squares cannot overflow, and `sqrt` is several times faster in the hot loops.
#[inline]
pub fn norm(a: Point) -> f64 {
    dot(a, a).sqrt()
}

/// Squared distance.
#[inline]
pub fn dist2(a: Point, b: Point) -> f64 {
    let d = sub(a, b);
    dot(d, d)
}

/// Distance.
#[inline]
pub fn dist(a: Point, b: Point) -> f64 {
    dist2(a, b).sqrt()
}

/// Midpoint of `a` and `b`.
#[inline]
pub fn mid(a: Point, b: Point) -> Point {
    [0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1])]
}

/// Twice the signed area of `(a, b, c)`, computed exactly in sign: positive when the
/// triangle is counter-clockwise. Topology decisions use this, never a float cross product.
#[inline]
pub fn orient(a: Point, b: Point, c: Point) -> f64 {
    robust::orient2d(
        robust::Coord { x: a[0], y: a[1] },
        robust::Coord { x: b[0], y: b[1] },
        robust::Coord { x: c[0], y: c[1] },
    )
}

/// Signed area of triangle `(a, b, c)` (positive when counter-clockwise), in floats.
#[inline]
pub fn area(a: Point, b: Point, c: Point) -> f64 {
    0.5 * cross(sub(b, a), sub(c, a))
}

/// Distance from `p` to the open polyline through `pts` (infinite with fewer than two).
pub fn polyline_dist(p: Point, pts: &[Point]) -> f64 {
    pts.windows(2)
        .map(|w| point_segment_dist2(p, w[0], w[1]).0)
        .fold(f64::INFINITY, f64::min)
        .sqrt()
}

/// Squared distance from `p` to the segment `[a, b]`, and the parameter in [0, 1] of the
/// closest point.
#[inline]
pub fn point_segment_dist2(p: Point, a: Point, b: Point) -> (f64, f64) {
    let ab = sub(b, a);
    let ap = sub(p, a);
    let len2 = dot(ab, ab);
    let t = if len2 > 0.0 {
        (dot(ap, ab) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let q = add(a, scale(ab, t));
    (dist2(p, q), t)
}

/// Where a frame's data sit: every stage after ingest works in coordinates centred on
/// the data's bounding box and scaled by about its diagonal, so that the data span about
/// one unit whatever their units or offset. Element shapes then lose no precision to large
/// offsets, no absolute threshold inside the numerics depends on the data's units, and
/// data from 1e-150 to 1e150 mesh alike.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placement {
    /// The data's centre, in data coordinates.
    pub center: Point,
    /// Data units per local unit: about the data's bounding-box diagonal.
    pub scale: f64,
}

impl Placement {
    /// The placement of data whose bounding box is `b`: its centre, and the power of two
    /// nearest its diagonal (a zero diagonal scales by one). A power of two scales every
    /// float exactly, so data already of unit size compute exactly as they would
    /// unscaled, and data of any other size exactly as their unit-size copy.
    pub fn of(b: &BBox) -> Placement {
        let d = b.diag();
        let scale = if d > 0.0 && d.is_finite() {
            2f64.powi(d.log2().round() as i32)
        } else {
            1.0
        };
        Placement {
            center: b.center(),
            scale,
        }
    }

    /// A point in local coordinates.
    #[inline]
    pub fn to_local(&self, p: Point) -> Point {
        let inv = 1.0 / self.scale;
        [(p[0] - self.center[0]) * inv, (p[1] - self.center[1]) * inv]
    }

    /// A local point in data coordinates.
    #[inline]
    pub fn to_data(&self, q: Point) -> Point {
        [
            q[0] * self.scale + self.center[0],
            q[1] * self.scale + self.center[1],
        ]
    }

    /// A length in local units.
    #[inline]
    pub fn len_to_local(&self, x: f64) -> f64 {
        x / self.scale
    }

    /// A local length in data units.
    #[inline]
    pub fn len_to_data(&self, x: f64) -> f64 {
        x * self.scale
    }
}

/// An axis-aligned bounding box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BBox {
    /// Lower-left corner.
    pub min: Point,
    /// Upper-right corner.
    pub max: Point,
}

impl BBox {
    /// The bounding box of `points`, or `None` when there are none.
    pub fn of(points: &[Point]) -> Option<BBox> {
        let first = *points.first()?;
        let mut b = BBox {
            min: first,
            max: first,
        };
        for p in points {
            b.min = [b.min[0].min(p[0]), b.min[1].min(p[1])];
            b.max = [b.max[0].max(p[0]), b.max[1].max(p[1])];
        }
        Some(b)
    }

    /// Width and height.
    pub fn size(&self) -> Point {
        sub(self.max, self.min)
    }

    /// Length of the diagonal.
    pub fn diag(&self) -> f64 {
        norm(self.size())
    }

    /// Centre.
    pub fn center(&self) -> Point {
        mid(self.min, self.max)
    }

    /// The box grown by `margin` on every side.
    pub fn padded(&self, margin: f64) -> BBox {
        BBox {
            min: [self.min[0] - margin, self.min[1] - margin],
            max: [self.max[0] + margin, self.max[1] + margin],
        }
    }

    /// Whether `p` lies in the closed box.
    pub fn contains(&self, p: Point) -> bool {
        p[0] >= self.min[0] && p[0] <= self.max[0] && p[1] >= self.min[1] && p[1] <= self.max[1]
    }
}

/// Where the segments `a0 a1` and `b0 b1` cross, if they do.
pub fn crossing(a0: Point, a1: Point, b0: Point, b1: Point) -> Option<Point> {
    let (da, db) = (sub(a1, a0), sub(b1, b0));
    let den = cross(da, db);
    if den.abs() < 1e-300 {
        return None;
    }
    let d = sub(b0, a0);
    let s = cross(d, db) / den;
    let r = cross(d, da) / den;
    ((0.0..=1.0).contains(&s) && (0.0..=1.0).contains(&r)).then(|| add(a0, scale(da, s)))
}

/// A polyline; `closed` means the last point connects back to the first (which is not
/// repeated).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Polyline {
    /// Whether the last point joins the first.
    pub closed: bool,
    /// The vertices, in order.
    pub points: Vec<Point>,
}

impl Polyline {
    /// The segments, including the closing one of a closed polyline.
    pub fn segments(&self) -> impl Iterator<Item = (Point, Point)> + '_ {
        let n = self.points.len();
        let count = match (self.closed, n) {
            (_, 0 | 1) => 0,
            (true, 2) => 1,
            (true, _) => n,
            (false, _) => n - 1,
        };
        (0..count).map(move |i| (self.points[i], self.points[(i + 1) % n]))
    }

    /// Total length.
    pub fn length(&self) -> f64 {
        self.segments().map(|(a, b)| dist(a, b)).sum()
    }

    /// Whether `p` lies inside the closed polyline (even-odd rule); false for an open
    /// one.
    pub fn encloses(&self, p: Point) -> bool {
        if !self.closed {
            return false;
        }
        let pts = &self.points;
        let mut inside = false;
        for (i, &a) in pts.iter().enumerate() {
            let b = pts[(i + 1) % pts.len()];
            if (a[1] > p[1]) != (b[1] > p[1]) {
                let x = a[0] + (p[1] - a[1]) / (b[1] - a[1]) * (b[0] - a[0]);
                if p[0] < x {
                    inside = !inside;
                }
            }
        }
        inside
    }

    /// Signed area (positive when counter-clockwise); zero for an open polyline.
    pub fn signed_area(&self) -> f64 {
        if !self.closed {
            return 0.0;
        }
        0.5 * self.segments().map(|(a, b)| cross(a, b)).sum::<f64>()
    }
}

/// A symmetric 2x2 tensor `[[xx, xy], [xy, yy]]`: a metric or a Hessian.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Sym2 {
    /// Entry (0, 0).
    pub xx: f64,
    /// Entries (0, 1) and (1, 0).
    pub xy: f64,
    /// Entry (1, 1).
    pub yy: f64,
}

/// The centroid of `pts` and their covariance (unnormalized): its eigenvector of the
/// larger eigenvalue ([`Sym2::eigen`]) is their principal axis.
pub fn principal(pts: impl Iterator<Item = Point> + Clone) -> (Point, Sym2) {
    let (n, sum) = pts.clone().fold((0.0, [0.0, 0.0]), |(n, s), q| {
        (n + 1.0, [s[0] + q[0], s[1] + q[1]])
    });
    let c = [sum[0] / n, sum[1] / n];
    let cov = pts.fold(Sym2::default(), |cov, q| {
        cov.plus(Sym2::outer([q[0] - c[0], q[1] - c[1]]))
    });
    (c, cov)
}

impl Sym2 {
    /// `s * I`.
    pub fn iso(s: f64) -> Sym2 {
        Sym2 {
            xx: s,
            xy: 0.0,
            yy: s,
        }
    }

    /// `v v^T`.
    pub fn outer(v: Point) -> Sym2 {
        Sym2 {
            xx: v[0] * v[0],
            xy: v[0] * v[1],
            yy: v[1] * v[1],
        }
    }

    /// `l1 e e^T + l2 e_perp e_perp^T` for a unit vector `e`.
    pub fn from_eigen(l1: f64, l2: f64, e: Point) -> Sym2 {
        let p = [-e[1], e[0]];
        Sym2::outer(e).scaled(l1).plus(Sym2::outer(p).scaled(l2))
    }

    /// `self + o`.
    pub fn plus(self, o: Sym2) -> Sym2 {
        Sym2 {
            xx: self.xx + o.xx,
            xy: self.xy + o.xy,
            yy: self.yy + o.yy,
        }
    }

    /// `s * self`.
    pub fn scaled(self, s: f64) -> Sym2 {
        Sym2 {
            xx: self.xx * s,
            xy: self.xy * s,
            yy: self.yy * s,
        }
    }

    /// `v^T self v`.
    #[inline]
    pub fn quad(&self, v: Point) -> f64 {
        self.xx * v[0] * v[0] + 2.0 * self.xy * v[0] * v[1] + self.yy * v[1] * v[1]
    }

    /// Determinant.
    pub fn det(&self) -> f64 {
        self.xx * self.yy - self.xy * self.xy
    }

    /// Trace.
    pub fn trace(&self) -> f64 {
        self.xx + self.yy
    }

    /// Eigenvalues `(l1, l2)` with `l1 >= l2` and the unit eigenvector of `l1`.
    pub fn eigen(&self) -> (f64, f64, Point) {
        let half_tr = 0.5 * (self.xx + self.yy);
        let half_diff = 0.5 * (self.xx - self.yy);
        let r = half_diff.hypot(self.xy);
        let (l1, l2) = (half_tr + r, half_tr - r);
        // The eigenvector angle of the larger eigenvalue: tan(2 theta) = 2 xy / (xx - yy).
        let theta = 0.5 * self.xy.atan2(half_diff);
        (l1, l2, [theta.cos(), theta.sin()])
    }

    /// The SPD tensor with the same eigenvectors and eigenvalues `|l|` clamped to
    /// `[lo, hi]`: how the paper's metric is made usable.
    pub fn abs_clamped(&self, lo: f64, hi: f64) -> Sym2 {
        let (l1, l2, e) = self.eigen();
        Sym2::from_eigen(l1.abs().clamp(lo, hi), l2.abs().clamp(lo, hi), e)
    }
}

/// A pose `[x, y, theta]`: where a frame's coordinates sit in a world frame (metres and
/// radians, counter-clockwise), as scanners' odometry gives it.
pub type Pose = [f64; 3];

/// Angle `theta` wrapped into `(-pi, pi]`.
pub fn wrap(theta: f64) -> f64 {
    let t = theta.rem_euclid(std::f64::consts::TAU);
    if t > std::f64::consts::PI {
        t - std::f64::consts::TAU
    } else {
        t
    }
}

/// `p` (world) in the frame at `pose`.
pub fn to_sensor(pose: Pose, p: Point) -> Point {
    let (s, c) = pose[2].sin_cos();
    let d = sub(p, [pose[0], pose[1]]);
    [c * d[0] + s * d[1], -s * d[0] + c * d[1]]
}

/// `p` (in the frame at `pose`) in the world.
pub fn to_world(pose: Pose, p: Point) -> Point {
    let (s, c) = pose[2].sin_cos();
    [pose[0] + c * p[0] - s * p[1], pose[1] + s * p[0] + c * p[1]]
}

/// Moves points given in the frame at pose `from` into the frame at pose `to`: how a
/// moving sensor's previous frame is seen from its new one.
pub fn reframe(from: Pose, to: Pose, points: &mut [Point]) {
    for p in points {
        *p = to_sensor(to, to_world(from, *p));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_moving_frames_points_follow_it() {
        // A wall point 2 m ahead of a sensor at the origin facing +x, seen again after
        // the sensor drove 0.5 m forward and turned left by 90 degrees: 1.5 m to its
        // right.
        let (from, to) = ([0.0, 0.0, 0.0], [0.5, 0.0, std::f64::consts::FRAC_PI_2]);
        let mut pts = [[2.0, 0.0]];
        reframe(from, to, &mut pts);
        assert!(dist(pts[0], [0.0, -1.5]) < 1e-12, "{:?}", pts[0]);
        for pose in [[1.0, -2.0, 0.3], [0.0, 0.0, -3.0]] {
            let p = [0.7, 0.2];
            assert!(dist(to_sensor(pose, to_world(pose, p)), p) < 1e-12);
        }
    }

    #[test]
    fn eigen_matches_nalgebra() {
        let cases = [
            Sym2 {
                xx: 3.0,
                xy: 1.0,
                yy: -2.0,
            },
            Sym2 {
                xx: 1.0,
                xy: 0.0,
                yy: 1.0,
            },
            Sym2 {
                xx: 0.0,
                xy: 5.0,
                yy: 0.0,
            },
            Sym2 {
                xx: 1e6,
                xy: -3e3,
                yy: 2.0,
            },
        ];
        for s in cases {
            let (l1, l2, e) = s.eigen();
            let m = nalgebra::Matrix2::new(s.xx, s.xy, s.xy, s.yy);
            let eig = m.symmetric_eigen();
            let (mut a, mut b) = (eig.eigenvalues[0], eig.eigenvalues[1]);
            if a < b {
                std::mem::swap(&mut a, &mut b);
            }
            let tol = 1e-12 * (1.0 + a.abs().max(b.abs()));
            assert!((l1 - a).abs() < tol && (l2 - b).abs() < tol, "{s:?}");
            // e is an eigenvector of l1.
            let me = [s.xx * e[0] + s.xy * e[1], s.xy * e[0] + s.yy * e[1]];
            assert!(dist(me, scale(e, l1)) < tol, "{s:?}");
            let back = Sym2::from_eigen(l1, l2, e);
            assert!((back.xx - s.xx).abs() < tol && (back.xy - s.xy).abs() < tol);
        }
    }

    #[test]
    fn segment_distance_and_polyline_area() {
        let (d2, t) = point_segment_dist2([0.5, 1.0], [0.0, 0.0], [1.0, 0.0]);
        assert_eq!((d2, t), (1.0, 0.5));
        let (d2, t) = point_segment_dist2([2.0, 0.0], [0.0, 0.0], [1.0, 0.0]);
        assert_eq!((d2, t), (1.0, 1.0));
        let sq = Polyline {
            closed: true,
            points: vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
        };
        assert_eq!(sq.signed_area(), 1.0);
        assert_eq!(sq.length(), 4.0);
        assert!(orient([0.0, 0.0], [1.0, 0.0], [0.0, 1.0]) > 0.0);
        assert_eq!(orient([0.0, 0.0], [1.0, 1.0], [2.0, 2.0]), 0.0);
    }
}
