//! A sweep's beams brought to one instant: a scanner takes its beams one after another
//! while it moves, so a frame read as if taken at once is bent by the motion during the
//! sweep (a Hokuyo URG-04LX turning at 90 degrees a second turns 6 degrees over its
//! 240-degree sweep, and its mount ahead of the axle moves sideways with the turn).
//! Each return is moved into the frame's coordinates at the first beam's time, by the
//! sensor's motion until its own, taken as constant over the sweep.

use std::f64::consts::TAU;

use super::{next_up, Scan};
use crate::geom::{dist, sub, wrap, Point, Pose};

/// When each beam of a sweep was taken, as a ROS `sensor_msgs/LaserScan` says it:
/// beam `i`, at bearing `angle_min + i angle_increment`, `i time_increment` seconds
/// after the first (the message's time stamp).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sweep {
    /// Bearing of the first beam taken, radians.
    pub angle_min: f64,
    /// Angle from one beam to the next, radians (negative for a clockwise sweep).
    pub angle_increment: f64,
    /// Seconds from one beam to the next.
    pub time_increment: f64,
}

impl Sweep {
    /// Seconds after the first beam that the beam at `bearing` was taken.
    pub fn time(&self, bearing: f64) -> f64 {
        (bearing - self.angle_min) / self.angle_increment * self.time_increment
    }

    /// The sweep, with `time_increment` for its beams' timing where it gives none (0).
    pub fn or_timing(self, time_increment: f64) -> Sweep {
        if self.time_increment > 0.0 {
            self
        } else {
            Sweep {
                time_increment,
                ..self
            }
        }
    }

    /// Points the sweep saw (in the frame's coordinates, seen from `origin`: a scan's
    /// returns, or curves drawn through them), each where it lies at the first beam's
    /// time for a sensor moving at `velocity` ([`Scan::deskewed`]): taken when the beam
    /// at its bearing was. Unchanged where the timing or the velocity is not valid.
    pub fn unbend(&self, points: &[Point], origin: Point, velocity: [f64; 3]) -> Vec<Point> {
        if !self.is_valid() || !velocity.iter().all(|v| v.is_finite()) {
            return points.to_vec();
        }
        points
            .iter()
            .map(|&p| {
                let d = sub(p, origin);
                // The bearing within the turn the sweep goes round from its first beam.
                let from = d[1].atan2(d[0]) - self.angle_min;
                let turned = if self.angle_increment > 0.0 {
                    from.rem_euclid(TAU)
                } else {
                    -(-from).rem_euclid(TAU)
                };
                moved(
                    p,
                    turned / self.angle_increment * self.time_increment,
                    velocity,
                )
            })
            .collect()
    }

    /// Whether the timing is one a scan can be corrected by: finite, a step that is not
    /// zero, and beams not taken backwards in time.
    pub fn is_valid(&self) -> bool {
        self.angle_min.is_finite()
            && self.angle_increment.is_finite()
            && self.angle_increment != 0.0
            && self.time_increment.is_finite()
            && self.time_increment >= 0.0
    }
}

/// The velocity `[vx, vy, omega]` (metres and radians a second, in the coordinates of
/// pose `to`) of a sensor that went from pose `from` to pose `to` in `dt` seconds at
/// constant velocity; `None` unless `dt` is positive and everything finite.
pub fn velocity(from: Pose, to: Pose, dt: f64) -> Option<[f64; 3]> {
    if !(dt > 0.0 && dt.is_finite()) {
        return None;
    }
    let (s, c) = to[2].sin_cos();
    let (dx, dy) = (to[0] - from[0], to[1] - from[1]);
    let turn = wrap(to[2] - from[2]);
    let v = [(c * dx + s * dy) / dt, (c * dy - s * dx) / dt, turn / dt];
    v.iter().all(|x| x.is_finite()).then_some(v)
}

impl Scan {
    /// The scan as taken at its first beam's time by a sensor moving at `velocity`
    /// (`[vx, vy, omega]`: metres and radians a second, in the frame's coordinates at
    /// that time) during the sweep `sweep`: each return moved by the sensor's motion
    /// until its beam's time, its bearing and range taken again from `origin`.
    ///
    /// A beam without a return keeps its range and turns with the sensor. Moved returns
    /// may change order where a near return's bearing moves past a farther one's; the
    /// beams are put back in bearing order (the corrected frame is what a sensor at the
    /// first beam's pose would see, each surface where it was when its beam fell), and
    /// over a full turn a beam that comes round onto the first ones' bearings is dropped
    /// (it saw again what they saw). The scan is returned unchanged when the timing is
    /// invalid, the motion would turn a beam past its neighbour (a sensor turning
    /// faster than its own mirror), or it would carry the sensor farther than
    /// `range_max` over the sweep (a jump in the poses the motion came from).
    pub fn deskewed(&self, sweep: &Sweep, velocity: [f64; 3]) -> Scan {
        let omega = velocity[2];
        if !sweep.is_valid() || !velocity.iter().all(|v| v.is_finite()) {
            return self.clone();
        }
        // The turn over one beam's time against the angle between beams.
        let per_beam = (omega * sweep.time_increment).abs();
        if per_beam >= 0.5 * self.step || self.angles.is_empty() {
            return self.clone();
        }
        let o = self.origin;
        let mut beams: Vec<(f64, f64)> = self
            .angles
            .iter()
            .zip(&self.ranges)
            .map(|(&a, &r)| {
                let t = sweep.time(a);
                let turn = omega * t;
                if r.is_nan() {
                    return (a + turn, r);
                }
                let (s, c) = a.sin_cos();
                let q = moved([o[0] + r * c, o[1] + r * s], t, velocity);
                let d = sub(q, o);
                (d[1].atan2(d[0]), dist(q, o))
            })
            .collect();
        // Bearings from atan2 lie in (-pi, pi]; each is brought next to its beam's own so
        // that a sweep across the back keeps its order.
        for (b, &a) in beams.iter_mut().zip(&self.angles) {
            b.0 = a + wrap(b.0 - a);
        }
        // A sensor carried farther over one sweep than it sees (or to no finite place)
        // is no motion a sensor makes, but a jump in the poses the motion came from: the
        // scan is kept as it came rather than given returns it could not have had. A
        // return near the reach may be carried a little past it by a true motion.
        let longest = self
            .angles
            .iter()
            .map(|&a| sweep.time(a).abs())
            .fold(0.0, f64::max);
        let travel = velocity[0].hypot(velocity[1]) * longest;
        if !travel.is_finite()
            || travel >= self.range_max
            || beams.iter().any(|b| !b.0.is_finite() || b.1.is_infinite())
        {
            return self.clone();
        }
        beams.sort_by(|x, y| x.0.total_cmp(&y.0));
        let first = beams[0].0;
        beams.retain(|b| b.0 < first + TAU);
        for i in 1..beams.len() {
            if beams[i].0 <= beams[i - 1].0 {
                beams[i].0 = next_up(beams[i - 1].0);
            }
        }
        Scan {
            origin: o,
            angles: beams.iter().map(|b| b.0).collect(),
            ranges: beams.iter().map(|b| b.1).collect(),
            ..self.clone()
        }
    }
}

/// Point `p` seen `t` seconds after the first beam, in the frame at that time: turned
/// by the sensor's turn since and moved by its motion since.
fn moved(p: Point, t: f64, [vx, vy, omega]: [f64; 3]) -> Point {
    let (s, c) = (omega * t).sin_cos();
    [c * p[0] - s * p[1] + vx * t, s * p[0] + c * p[1] + vy * t]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scan::LaserScan;

    /// A square room 8 m wide seen by a sensor at `pose` in the room that sweeps
    /// `beams` beams over 240 degrees counter-clockwise, `dt` seconds apart, while it
    /// moves at `velocity` (in its frame at the first beam): each beam cast from where
    /// the sensor is at its time.
    fn swept(pose: [f64; 3], velocity: [f64; 3], beams: usize, dt: f64) -> (Scan, Sweep) {
        swept_over(
            pose,
            velocity,
            beams,
            dt,
            -120f64.to_radians(),
            240f64.to_radians(),
        )
    }

    /// The same room swept from `angle_min` through `span` radians (negative: clockwise).
    fn swept_over(
        pose: [f64; 3],
        velocity: [f64; 3],
        beams: usize,
        dt: f64,
        angle_min: f64,
        span: f64,
    ) -> (Scan, Sweep) {
        let inc = span / (beams - 1) as f64;
        let ranges: Vec<Option<f64>> = (0..beams)
            .map(|i| {
                let t = i as f64 * dt;
                let (s, c) = pose[2].sin_cos();
                let at = [
                    pose[0] + (c * velocity[0] - s * velocity[1]) * t,
                    pose[1] + (s * velocity[0] + c * velocity[1]) * t,
                    pose[2] + velocity[2] * t,
                ];
                let b = at[2] + angle_min + i as f64 * inc;
                let d = [b.cos(), b.sin()];
                // The nearest of the four walls at x, y = +-4 along the ray.
                [(0, 4.0), (0, -4.0), (1, 4.0), (1, -4.0)]
                    .iter()
                    .filter_map(|&(k, w): &(usize, f64)| {
                        let t = (w - at[k]) / d[k];
                        (t > 0.0).then_some(t)
                    })
                    .fold(None, |m: Option<f64>, t| Some(m.map_or(t, |m| m.min(t))))
            })
            .collect();
        let scan = Scan::from_laser(&LaserScan {
            origin: [0.0, 0.0],
            angle_min,
            angle_increment: inc,
            ranges: &ranges,
            range_min: 0.0,
            range_max: 30.0,
        })
        .unwrap();
        let sweep = Sweep {
            angle_min,
            angle_increment: inc,
            time_increment: dt,
        };
        (scan, sweep)
    }

    /// The largest distance of a return of `scan` (placed at `pose`) from the room's
    /// walls.
    fn off_walls(scan: &Scan, pose: [f64; 3]) -> f64 {
        scan.returns()
            .iter()
            .map(|&p| {
                let w = crate::geom::to_world(pose, p);
                (4.0 - w[0].abs()).abs().min((4.0 - w[1].abs()).abs())
            })
            .fold(0.0, f64::max)
    }

    /// A Hokuyo URG-04LX's sweep (683 beams over 240 degrees in 67 ms) turning at 120
    /// degrees a second about an axle 15 cm behind it, while driving at 0.6 m/s: its
    /// first beam's pose, the velocity, the scan and its timing.
    fn turning_urg() -> (Pose, [f64; 3], Scan, Sweep) {
        let omega = 120f64.to_radians();
        let velocity = [0.6, 0.15 * omega, omega];
        let pose = [0.5, -1.0, 0.3];
        let (scan, sweep) = swept(pose, velocity, 683, 0.1 / 1024.0);
        (pose, velocity, scan, sweep)
    }

    #[test]
    fn a_turning_sweep_lies_on_its_walls_once_corrected() {
        let (pose, velocity, scan, sweep) = turning_urg();
        // Read as taken at once, the sweep's last returns lie where the sensor had
        // turned 8 degrees since the first: far off the walls.
        assert!(off_walls(&scan, pose) > 0.3, "{}", off_walls(&scan, pose));
        let fixed = scan.deskewed(&sweep, velocity);
        // Corrected, every return lies on its wall: the simulated sensor moves as the
        // correction's model says (constant velocity in the first beam's frame), so what
        // is left is rounding.
        assert!(
            off_walls(&fixed, pose) < 1e-9,
            "{}",
            off_walls(&fixed, pose)
        );
        assert_eq!(fixed.returns().len(), scan.returns().len());
        assert!(fixed.angles.windows(2).all(|w| w[0] < w[1]));
    }

    #[test]
    fn points_the_sweep_saw_are_unbent_as_its_returns_are() {
        let (pose, velocity, scan, sweep) = turning_urg();
        // Midpoints of neighbouring returns: curve vertices between beams.
        let returns = scan.returns();
        let mids: Vec<Point> = returns
            .windows(2)
            .map(|w| [0.5 * (w[0][0] + w[1][0]), 0.5 * (w[0][1] + w[1][1])])
            .collect();
        let fixed = sweep.unbend(&returns, scan.origin, velocity);
        for (a, b) in fixed.iter().zip(scan.deskewed(&sweep, velocity).returns()) {
            assert!(dist(*a, b) < 1e-9, "{a:?} {b:?}");
        }
        let room = |p: Point| {
            let w = crate::geom::to_world(pose, p);
            (4.0 - w[0].abs()).abs().min((4.0 - w[1].abs()).abs())
        };
        // A midpoint across a corner lies off the walls by the corner's chord; those
        // between two returns on one wall lie on it once unbent.
        let on = sweep
            .unbend(&mids, scan.origin, velocity)
            .iter()
            .filter(|&&p| room(p) < 1e-3)
            .count();
        assert!(on + 8 >= mids.len(), "{on} of {}", mids.len());
    }

    #[test]
    fn a_still_sensor_or_no_timing_leaves_the_scan_as_it_is() {
        let (scan, sweep) = swept([0.0, 0.0, 0.0], [0.0; 3], 181, 1e-4);
        let fixed = scan.deskewed(&sweep, [0.0; 3]);
        assert_eq!(fixed.angles.len(), scan.angles.len());
        for (a, b) in fixed.returns().iter().zip(scan.returns()) {
            assert!(dist(*a, b) < 1e-12);
        }
        let untimed = Sweep {
            time_increment: f64::NAN,
            ..sweep
        };
        assert_eq!(scan.deskewed(&untimed, [1.0, 0.0, 1.0]), scan);
        // A turn faster than the mirror's: no correction can be right.
        assert_eq!(scan.deskewed(&sweep, [0.0, 0.0, 1e3]), scan);
        // A jump in the input's poses (ten kilometres a second): the sensor would be
        // carried beyond its reach within the sweep.
        assert_eq!(scan.deskewed(&sweep, [1e4, 0.0, 0.0]), scan);
        assert_eq!(scan.deskewed(&sweep, [f64::MAX, 0.0, 0.0]), scan);
    }

    #[test]
    fn a_clockwise_sweep_is_corrected_the_same() {
        // The same room swept clockwise: the beams come reversed, and the timing says
        // the first beam taken is the last in bearing order.
        let omega = -90f64.to_radians();
        let velocity = [0.4, 0.0, omega];
        let pose: [f64; 3] = [0.0, 1.0, -0.4];
        let (scan, sweep) = swept_over(
            pose,
            velocity,
            541,
            0.025 / 1440.0,
            120f64.to_radians(),
            -240f64.to_radians(),
        );
        assert!(off_walls(&scan, pose) > 0.05);
        let fixed = scan.deskewed(&sweep, velocity);
        assert!(
            off_walls(&fixed, pose) < 1e-9,
            "{}",
            off_walls(&fixed, pose)
        );
    }
}
