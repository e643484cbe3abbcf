//! Each stream's scanner frames corrected for the sensor's motion during the sweep
//! ([`Scan::deskewed`]): the motion is the stream's, from the previous frame's pose and
//! time to this one's, taken as the velocity through this frame's sweep.

use std::collections::HashMap;

use isoline_core::Pose;

use super::Frame;

/// The longest time between a stream's frames whose motion is taken for the next
/// sweep's, seconds: a vehicle's velocity a second ago says little of it now.
const MAX_GAP: f64 = 1.0;

/// Streams whose last pose is kept at once; more (a forged input naming a new stream a
/// line) start again from none, which leaves their next frame as it came.
const MAX_STREAMS: usize = 4096;

/// Corrects a sequence of frames, stream by stream, for the motion during each sweep.
#[derive(Debug, Default)]
pub struct Deskew {
    /// Seconds between beams for frames that do not say; 0: those are left as they are.
    default_time_increment: f64,
    /// Each stream's last frame's time and pose.
    last: HashMap<Option<String>, (f64, Pose)>,
}

impl Deskew {
    /// A corrector for frames whose beams are `default_time_increment` seconds apart
    /// when they do not say (`None`: left as taken at once).
    pub fn new(default_time_increment: Option<f64>) -> Deskew {
        Deskew {
            default_time_increment: default_time_increment
                .filter(|t| t.is_finite() && *t >= 0.0)
                .unwrap_or(0.0),
            last: HashMap::new(),
        }
    }

    /// Corrects `frame` for the motion since its stream's previous frame, when it has
    /// beams, beam timing, a time and a pose, and the previous frame came less than a
    /// second before; remembers its time and pose either way.
    pub fn apply(&mut self, frame: &mut Frame) {
        let key = frame.stream.clone();
        let (Some(t), Some(pose)) = (frame.t, frame.pose) else {
            self.last.remove(&key);
            return;
        };
        if self.last.len() >= MAX_STREAMS && !self.last.contains_key(&key) {
            self.last.clear();
        }
        let previous = self.last.insert(key, (t, pose));
        let (Some((t0, p0)), Some(scan), Some(sweep)) = (previous, &frame.scan, frame.sweep) else {
            return;
        };
        let sweep = sweep.or_timing(self.default_time_increment);
        if sweep.time_increment <= 0.0 || t - t0 > MAX_GAP {
            return;
        }
        let Some(velocity) = isoline_core::velocity(p0, pose, t - t0) else {
            return;
        };
        let fixed = scan.deskewed(&sweep, velocity);
        frame.replace_scan(fixed);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::format::FrameRecord;

    /// A frame of a sensor at `pose` at time `t` facing a wall at x = 3 (in the world),
    /// its 201 beams over 100 degrees swept 1 ms apart while it turns at `omega`.
    fn frame(t: f64, pose: Pose, omega: f64, timed: bool) -> Frame {
        let (a0, inc) = (-50f64.to_radians(), 0.5f64.to_radians());
        let ranges = (0..201)
            .map(|i| {
                let b = pose[2] + omega * i as f64 * 1e-3 + a0 + i as f64 * inc;
                Some((3.0 - pose[0]) / b.cos())
            })
            .collect();
        Frame::from_record(FrameRecord {
            stream: Some("s".into()),
            frame: 0,
            t: Some(t),
            pose: Some(pose),
            ranges: Some(ranges),
            angle_min: Some(a0),
            angle_increment: Some(inc),
            time_increment: timed.then_some(1e-3),
            range_max: Some(20.0),
            ..Default::default()
        })
        .unwrap()
    }

    /// The largest distance of the frame's returns from the wall, placed by its pose.
    fn off_wall(f: &Frame) -> f64 {
        f.points
            .iter()
            .map(|&p| (isoline_core::geom::to_world(f.pose.unwrap(), p)[0] - 3.0).abs())
            .fold(0.0, f64::max)
    }

    #[test]
    fn a_turning_streams_frames_are_corrected_by_its_poses() {
        // Turning at one radian a second: 0.2 rad over the 200 ms sweep.
        let mut d = Deskew::new(None);
        let mut first = frame(0.0, [0.0, 0.0, 0.0], 1.0, true);
        d.apply(&mut first);
        // No earlier frame: no motion known, the frame as it came.
        assert!(off_wall(&first) > 0.1, "{}", off_wall(&first));
        let mut second = frame(0.1, [0.0, 0.0, 0.1], 1.0, true);
        d.apply(&mut second);
        assert!(off_wall(&second) < 1e-9, "{}", off_wall(&second));
        // Without timing, a default; without one either, as it came.
        let mut untimed = frame(0.2, [0.0, 0.0, 0.2], 1.0, false);
        let mut d = Deskew::new(None);
        d.apply(&mut frame(0.1, [0.0, 0.0, 0.1], 1.0, false));
        d.apply(&mut untimed);
        let mut d = Deskew::new(Some(1e-3));
        d.apply(&mut frame(0.1, [0.0, 0.0, 0.1], 1.0, false));
        let mut defaulted = frame(0.2, [0.0, 0.0, 0.2], 1.0, false);
        d.apply(&mut defaulted);
        assert!(off_wall(&untimed) > 0.1);
        assert!(off_wall(&defaulted) < 1e-9, "{}", off_wall(&defaulted));
        // A frame two seconds after the last: its motion is not this sweep's.
        let mut late = frame(1.3, [0.0, 0.0, 0.1], 1.0, true);
        d.apply(&mut late);
        assert!(off_wall(&late) > 0.1);
    }
}
