//! CARMEN log input (the format of the classic public SLAM datasets): `FLASER`,
//! `RLASER` and `ROBOTLASER1` lines as beam frames, each with the laser's pose the line
//! carries. Other messages (`ODOM`, `PARAM`, `SYNC`, ...) and `#` comments are skipped;
//! the lasers' lines carry the odometry-integrated pose already.
//!
//! Old-style `FLASER`/`RLASER` lines do not say their beams' geometry: as CARMEN's own
//! reader, 180 or 181 beams are 1 degree apart, 360 or 361 half a degree, 400 or 401 a
//! quarter, and any other count spans 180 degrees; the sweep starts at -90 degrees.
//! Returns reach less than the laser's maximum range as the log declares it
//! (`PARAM robot_front_laser_max` and `robot_rear_laser_max`, CARMEN's own
//! parameters), and at most [`FLASER_RANGE_MAX`] (SICK scanners report 81.9 m for
//! none). A scanner that reports no return as a reading within its range, without the
//! log saying so, is found by the pile its code makes at the top of the log's readings
//! ([`reading_piles`]): the ACES log's SICK reads exactly 50 m 620 times, an Örebro
//! log's 32.759 to 32.767 m (the top of the 15-bit range in millimetres, SICK's codes for
//! no return, dazzle and other errors) 968 times, where true far readings come once
//! each. Readings in the pile are no returns, and each frame's record says how many
//! were dropped.

use std::io::{BufRead, Seek};
use std::path::Path;

use super::{BadFrame, Frame, Item};
use crate::error::{Error, Result};
use crate::format::FrameRecord;

/// Old-style laser lines: ranges at or beyond this are no returns, metres.
pub const FLASER_RANGE_MAX: f64 = 80.0;

/// What a log's `PARAM` lines say of its lasers' reach, metres.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LaserReach {
    /// `robot_front_laser_max`: the `FLASER` laser's maximum range.
    pub front: Option<f64>,
    /// `robot_rear_laser_max`: the `RLASER` laser's.
    pub rear: Option<f64>,
    /// Where the pile of the `FLASER` laser's no-return code starts ([`reading_piles`]):
    /// its readings from here on are no returns.
    pub front_code: Option<f64>,
    /// The same for the `RLASER` laser.
    pub rear_code: Option<f64>,
}

impl LaserReach {
    /// Takes in a `PARAM` line's fields after the keyword, if it names a reach (a
    /// positive, finite number of metres).
    fn read_param(&mut self, fields: &str) {
        let mut w = fields.split_whitespace();
        let (Some(name), Some(value)) = (w.next(), w.next()) else {
            return;
        };
        let Some(v) = value
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite() && *v > 0.0)
        else {
            return;
        };
        match name {
            "robot_front_laser_max" => self.front = Some(v),
            "robot_rear_laser_max" => self.rear = Some(v),
            _ => {}
        }
    }
}

/// Readings are counted in bins this wide, metres: the finest resolution logs write.
const BIN: f64 = 1e-3;

/// The widest a scanner's no-return codes spread, metres: SICK's millimetre-mode codes
/// span 9 mm; one code read at one value spans none.
const PILE_WIDTH: f64 = 0.01;

/// Where each old-style laser's no-return code starts, if it reports no return as its
/// largest readings: `[FLASER, RLASER]`. A log's true ranges thin out towards their
/// largest, each far distance read about once; a code is read whenever a beam sees
/// nothing, so it piles up. The readings within a centimetre of the largest (below
/// [`FLASER_RANGE_MAX`]) are taken for a code when they are more than any other
/// centimetre of readings of at least half that range: in the ACES log 50 m is read
/// 620 times and the readings below it about once each. A log whose largest reading is
/// a far wall has none (`None`); so has an unreadable log (the reading pass says what
/// is wrong with it). Memory is one counter a millimetre up to [`FLASER_RANGE_MAX`] per
/// laser, whatever the log's length.
pub fn reading_piles(path: &Path) -> [Option<f64>; 2] {
    let Ok(reader) = open(path) else {
        return [None, None];
    };
    let bins = (FLASER_RANGE_MAX / BIN) as usize + 1;
    let mut counts: [Vec<u32>; 2] = [Vec::new(), Vec::new()];
    let _ = super::bounded_lines(reader, path, MAX_LINE_BYTES, |_, line| {
        let Ok(text) = line else { return true };
        let mut w = text.split_whitespace();
        let k = match w.next() {
            Some("FLASER") => 0,
            Some("RLASER") => 1,
            _ => return true,
        };
        let Some(n) = w.next().and_then(|n| n.parse::<usize>().ok()) else {
            return true;
        };
        let c = &mut counts[k];
        if c.is_empty() {
            c.resize(bins, 0);
        }
        for v in w.take(n).filter_map(|f| f.parse::<f64>().ok()) {
            if v.is_finite() && v > 0.0 && v < FLASER_RANGE_MAX {
                let b = ((v / BIN).round() as usize).min(bins - 1);
                c[b] = c[b].saturating_add(1);
            }
        }
        true
    });
    counts.map(|c| top_pile(&c))
}

/// The reading where the pile at the top of `counts` (per [`BIN`]) starts, if there is
/// one (see [`reading_piles`]).
fn top_pile(counts: &[u32]) -> Option<f64> {
    let top = counts.iter().rposition(|&n| n > 0)?;
    let w = (PILE_WIDTH / BIN).round() as usize;
    let from = (top + 1).saturating_sub(w);
    let sum = |a: usize, b: usize| counts[a..b].iter().map(|&n| u64::from(n)).sum::<u64>();
    let pile = sum(from, top + 1);
    // Every other window as wide among the readings of at least half the top's range.
    let low = top / 2;
    let mut rival = 0u64;
    if from > low + w {
        let mut s = sum(low, low + w);
        rival = s;
        for a in low + 1..=from - w {
            s = s + u64::from(counts[a + w - 1]) - u64::from(counts[a - 1]);
            rival = rival.max(s);
        }
    }
    (pile > rival.max(1)).then_some((from as f64 - 0.5) * BIN)
}

/// The longest line read; a longer one is an error record, not memory.
pub const MAX_LINE_BYTES: usize = 1 << 20;

/// Whether `path` is to be read as a CARMEN log: it is named like one (`.log`, `.clf`,
/// `.carmen`, each maybe with `.gz`; the reader then says which line is not CARMEN if
/// it is not), or, whatever its name, its first line that is not blank or a `#`
/// comment starts with a CARMEN message name (`PARAM`, `FLASER`, `ROBOTLASER1`, ...).
/// Bags and NDJSON streams (by extension) never are.
pub fn is_carmen(path: &Path) -> bool {
    let ext = |p: &Path| {
        p.extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
    };
    let inner = match ext(path).as_deref() {
        Some("gz") => path.file_stem().map(Path::new).and_then(ext),
        e => e.map(str::to_string),
    };
    match inner.as_deref() {
        Some("log" | "clf" | "carmen") => true,
        Some("mcap" | "ndjson" | "jsonl") => false,
        _ => first_line(path).is_some_and(|l| is_message_line(&l)),
    }
}

/// A log's lines start with an upper-case message name (`FLASER 180 ...`).
fn is_message_line(text: &str) -> bool {
    let name = text.split_whitespace().next().unwrap_or("");
    name.len() >= 3
        && name.starts_with(|c: char| c.is_ascii_uppercase())
        && name
            .chars()
            .all(|c| c.is_ascii_uppercase() || c.is_ascii_digit() || c == '_')
}

/// The file's first line that is not blank or a `#` comment, among its first 100 lines
/// (each read up to 64 KiB).
fn first_line(path: &Path) -> Option<String> {
    use std::io::Read;
    let mut reader = open(path).ok()?;
    for _ in 0..100 {
        let mut buf = Vec::new();
        let n = Read::take(&mut reader, 64 << 10)
            .read_until(b'\n', &mut buf)
            .ok()?;
        if n == 0 {
            return None;
        }
        let text = String::from_utf8_lossy(&buf);
        let t = text.trim();
        if !t.is_empty() && !t.starts_with('#') {
            return Some(t.to_string());
        }
    }
    None
}

/// The file's text: gzip-compressed (by its first bytes, whatever its name) or not.
fn open(path: &Path) -> Result<Box<dyn BufRead>> {
    use std::io::Read;
    let mut file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let mut magic = [0u8; 2];
    let gz = file.read_exact(&mut magic).is_ok() && magic == [0x1f, 0x8b];
    file.rewind().map_err(|e| Error::io(path, e))?;
    Ok(if gz {
        Box::new(std::io::BufReader::new(flate2::read::MultiGzDecoder::new(
            std::io::BufReader::new(file),
        )))
    } else {
        Box::new(std::io::BufReader::new(file))
    })
}

/// The angle between beams of an old-style line of `n` beams.
fn old_increment(n: usize) -> f64 {
    use std::f64::consts::PI;
    match n {
        180 | 181 => PI / 180.0,
        360 | 361 => PI / 360.0,
        400 | 401 => PI / 720.0,
        _ => PI / (n.max(2) - 1) as f64,
    }
}

/// Parses one laser line (its fields after the keyword) into a frame record; `None`
/// for lines that are not laser messages.
pub fn parse_line(line: &str) -> Option<std::result::Result<FrameRecord, String>> {
    parse_line_with(line, &LaserReach::default())
}

/// [`parse_line`] for a log whose `PARAM` lines declared `reach`.
// One function: one line's fields in their order, whose positions depend on the message
// kind read first.
pub fn parse_line_with(
    line: &str,
    reach: &LaserReach,
) -> Option<std::result::Result<FrameRecord, String>> {
    let mut words = line.split_whitespace();
    let key = words.next()?;
    let stream = match key {
        "FLASER" => "flaser",
        "RLASER" => "rlaser",
        "ROBOTLASER1" => "robotlaser1",
        _ => return None,
    };
    let fields: Vec<&str> = words.collect();
    let mut at = 0usize;
    let mut num = |what: &str| -> std::result::Result<f64, String> {
        let f = fields
            .get(at)
            .ok_or_else(|| format!("{key}: the line ends before {what}"))?;
        at += 1;
        f.parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("{key}: {what} '{f}' is not a finite number"))
    };
    let count = |v: f64, what: &str| -> std::result::Result<usize, String> {
        if v >= 0.0 && v.fract() == 0.0 && v <= fields.len() as f64 {
            Ok(v as usize)
        } else {
            Err(format!(
                "{key}: {what} {v} is not a count the line can hold"
            ))
        }
    };
    let result = (|| {
        let (angle_min, increment, range_max, ranges, pose);
        let mut code: Option<f64> = None;
        if key == "ROBOTLASER1" {
            let _laser_type = num("laser_type")?;
            angle_min = num("start_angle")?;
            let _fov = num("field_of_view")?;
            increment = num("angular_resolution")?;
            range_max = num("maximum_range")?;
            let _accuracy = num("accuracy")?;
            let _remission_mode = num("remission_mode")?;
            let n = count(num("num_readings")?, "num_readings")?;
            ranges = (0..n)
                .map(|_| num("a range"))
                .collect::<std::result::Result<Vec<f64>, String>>()?;
            let m = count(num("num_remissions")?, "num_remissions")?;
            for _ in 0..m {
                num("a remission")?;
            }
            pose = [
                num("laser_pose_x")?,
                num("laser_pose_y")?,
                num("laser_pose_theta")?,
            ];
            for what in ["robot_pose_x", "robot_pose_y", "robot_pose_theta"] {
                num(what)?;
            }
            for what in [
                "tv",
                "rv",
                "forward_safety_dist",
                "side_safety_dist",
                "turn_axis",
            ] {
                num(what)?;
            }
        } else {
            let n = count(num("num_readings")?, "num_readings")?;
            ranges = (0..n)
                .map(|_| num("a range"))
                .collect::<std::result::Result<Vec<f64>, String>>()?;
            angle_min = -std::f64::consts::FRAC_PI_2;
            increment = old_increment(n);
            let declared = if key == "RLASER" {
                reach.rear
            } else {
                reach.front
            };
            range_max = declared.map_or(FLASER_RANGE_MAX, |m| m.min(FLASER_RANGE_MAX));
            code = if key == "RLASER" {
                reach.rear_code
            } else {
                reach.front_code
            };
            pose = [num("x")?, num("y")?, num("theta")?];
            for what in ["odom_x", "odom_y", "odom_theta"] {
                num(what)?;
            }
        }
        let t = num("ipc_timestamp")?;
        // Readings in the code's pile are no returns; the record says how many.
        let reach = code.map_or(range_max, |c| c.min(range_max));
        let coded = code.map_or(0, |c| {
            ranges.iter().filter(|&&r| r >= c && r < range_max).count()
        });
        let notes = (coded > 0).then(|| {
            vec![format!(
                "{coded} readings of {:.3} m or more dropped: the scanner's no-return code \
                 (the pile at the top of the log's readings)",
                code.unwrap_or(0.0)
            )]
        });
        Ok(FrameRecord {
            notes,
            stream: Some(stream.into()),
            t: Some(t),
            pose: Some(pose),
            ranges: Some(
                ranges
                    .into_iter()
                    .map(|r| (r > 0.0 && r < reach).then_some(r))
                    .collect(),
            ),
            angle_min: Some(angle_min),
            angle_increment: Some(increment),
            range_min: Some(0.0),
            range_max: Some(reach),
            ..Default::default()
        })
    })();
    Some(result)
}

/// Reads the laser frames of the CARMEN log `path` in file order, numbered per stream
/// (`flaser`, `rlaser`, `robotlaser1`), calling `each` with every frame or a
/// [`BadFrame`] naming the file and line; `each` returns `false` to stop. Fails when the
/// file cannot be read, or holds no laser line.
pub fn read_carmen(path: &Path, each: impl FnMut(Item) -> bool) -> Result<u64> {
    read_carmen_with(
        path,
        |rec| Frame::from_record(rec).map_err(|e| e.to_string()),
        each,
    )
}

/// [`read_carmen`] with each laser line's record made into a `T` by `make`.
pub fn read_carmen_with<T>(
    path: &Path,
    make: impl Fn(FrameRecord) -> std::result::Result<T, String>,
    mut each: impl FnMut(std::result::Result<T, BadFrame>) -> bool,
) -> Result<u64> {
    let reader = open(path)?;
    let name = path.display().to_string();
    let mut next = std::collections::HashMap::<&'static str, u64>::new();
    let mut frames = 0u64;
    let mut first = true;
    let mut not_carmen = None;
    let mut reach = LaserReach::default();
    let piles = reading_piles(path);
    super::bounded_lines(reader, path, MAX_LINE_BYTES, |line_no, line| {
        let bad = |message: String| BadFrame {
            stream: None,
            frame: None,
            message: format!("{name}, line {line_no}: {message}"),
        };
        let text = match line {
            Ok(t) => t,
            Err(why) => return each(Err(bad(why))),
        };
        let text = text.trim();
        if text.is_empty() || text.starts_with('#') {
            return true;
        }
        if std::mem::take(&mut first) && !is_message_line(text) {
            let shown: String = text.chars().take(40).collect();
            not_carmen = Some(format!(
                "line {line_no}: not a CARMEN log: its lines start with a message name \
                 (PARAM, FLASER, ROBOTLASER1, ODOM, ...), this one with {shown:?}"
            ));
            return false;
        }
        if let Some(fields) = text.strip_prefix("PARAM ") {
            reach.read_param(fields);
            return true;
        }
        // A pile at the top of the readings is no return, whatever the log declares.
        let reach = LaserReach {
            front_code: piles[0],
            rear_code: piles[1],
            ..reach
        };
        let Some(parsed) = parse_line_with(text, &reach) else {
            return true;
        };
        let stream: &'static str = match text.split_whitespace().next() {
            Some("FLASER") => "flaser",
            Some("RLASER") => "rlaser",
            _ => "robotlaser1",
        };
        let k = next.entry(stream).or_insert(0);
        let frame = *k;
        *k += 1;
        frames += 1;
        let item = parsed
            .and_then(|mut rec| {
                rec.frame = frame;
                make(rec)
            })
            .map_err(|e| BadFrame {
                stream: Some(stream.into()),
                frame: Some(frame),
                ..bad(e)
            });
        each(item)
    })?;
    if let Some(message) = not_carmen {
        return Err(Error::Recording {
            path: path.to_path_buf(),
            message,
        });
    }
    if frames == 0 {
        return Err(Error::Recording {
            path: path.to_path_buf(),
            message: "no FLASER, RLASER or ROBOTLASER1 line".into(),
        });
    }
    Ok(frames)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn laser_lines_become_frames_and_bad_ones_are_named() {
        let rec = parse_line("FLASER 3 1.0 81.9 2.5 1 2 0.5 1 2 0.5 12.5 host 0.1")
            .unwrap()
            .unwrap();
        assert_eq!(rec.ranges, Some(vec![Some(1.0), None, Some(2.5)]));
        assert_eq!(rec.pose, Some([1.0, 2.0, 0.5]));
        assert_eq!(rec.t, Some(12.5));
        assert!((rec.angle_increment.unwrap() - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        let rec = parse_line(
            "ROBOTLASER1 0 -1.5 3.0 0.75 30 0.01 0 5 1 2 3 4 5 0 0.1 0.2 0.3 0 0 0 0 0 0 0 0 \
             7.25 host 7.3",
        )
        .unwrap()
        .unwrap();
        assert_eq!(rec.ranges.as_ref().unwrap().len(), 5);
        assert_eq!(
            (rec.angle_min, rec.angle_increment, rec.range_max),
            (Some(-1.5), Some(0.75), Some(30.0))
        );
        assert_eq!((rec.pose, rec.t), (Some([0.1, 0.2, 0.3]), Some(7.25)));
        assert!(parse_line("ODOM 1 2 3 0 0 0 5 host 5").is_none());
        for (bad, what) in [
            ("FLASER 3 1.0 2.0", "ends before"),
            ("FLASER 2 1.0 x 0 0 0 0 0 0 1 h 1", "'x'"),
            ("FLASER 1e12 1", "num_readings"),
            ("FLASER -1 1", "num_readings"),
        ] {
            let e = parse_line(bad).unwrap().unwrap_err();
            assert!(e.contains(what), "{bad}: {e}");
        }
    }

    /// The ranges of every laser line of the log at `path`.
    fn ranges_of(path: &Path) -> Vec<Vec<Option<f64>>> {
        let mut ranges = Vec::new();
        read_carmen_with(
            path,
            |rec| Ok(rec.ranges.unwrap()),
            |r| {
                ranges.push(r.unwrap());
                true
            },
        )
        .unwrap();
        ranges
    }

    /// A log's declared reach bounds its returns, per laser; a single reading where a
    /// scanner's codes lie (32.763 m) is a reading like any other.
    #[test]
    fn declared_reach_bounds_the_returns() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("run.log");
        std::fs::write(
            &path,
            "PARAM robot_front_laser_max 50 host 0
PARAM robot_rear_laser_max 120 host 0
             FLASER 4 49.9 50.0 32.763 32.7 1 2 0.5 1 2 0.5 12.5 host 0.1
             RLASER 4 49.9 50.0 81.9 32.767 1 2 0.5 1 2 0.5 12.5 host 0.1
",
        )
        .unwrap();
        let ranges = ranges_of(&path);
        assert_eq!(ranges[0], [Some(49.9), None, Some(32.763), Some(32.7)]);
        // A declared reach beyond 80 m keeps SICK's 81.9 m out all the same.
        assert_eq!(ranges[1], [Some(49.9), Some(50.0), None, Some(32.767)]);
    }

    /// Codes spread over a few millimetres at the top of the readings (SICK's
    /// millimetre mode: 32.759 to 32.767 m) are one pile, found from the log's own
    /// readings; each frame's record says how many of its readings were dropped.
    #[test]
    fn a_pile_of_codes_a_few_millimetres_wide_is_no_return_and_said() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("run.log");
        let mut log = String::new();
        for k in 0..20 {
            let code = 32.759 + 0.001 * (k % 9) as f64;
            let wall = 10.0 + 0.37 * k as f64;
            log += &format!(
                "FLASER 4 {wall:.3} {code:.3} {:.3} 2.5 1 2 0.5 1 2 0.5 {k} host {k}\n",
                wall + 11.3
            );
        }
        std::fs::write(&path, log).unwrap();
        let piles = reading_piles(&path);
        let from = piles[0].expect("a pile");
        // Within a centimetre below the largest code, 32.767 m.
        assert!((32.757..=32.759).contains(&from), "{from}");
        let mut notes = Vec::new();
        let mut ranges = Vec::new();
        read_carmen_with(&path, Ok, |r| {
            let rec = r.unwrap();
            notes.push(rec.notes.clone());
            ranges.push(rec.ranges.unwrap());
            true
        })
        .unwrap();
        assert!(ranges
            .iter()
            .all(|r| r[1].is_none() && r[0].is_some() && r[2].is_some()));
        assert!(notes.iter().all(|n| n
            .as_ref()
            .is_some_and(|n| n[0].starts_with("1 readings of 32.75"))));
    }

    /// A log that reports no return as its largest reading, without declaring its
    /// reach, has those readings piled at the top: they are no returns. A largest
    /// reading that is a far wall, read once, stays a return.
    #[test]
    fn a_pile_at_the_top_of_the_readings_is_no_return() {
        let dir = tempfile::tempdir().unwrap();
        let read = |log: &str| {
            let path = dir.path().join("run.log");
            std::fs::write(&path, log).unwrap();
            (reading_piles(&path), ranges_of(&path))
        };
        let (piles, ranges) = read(
            "FLASER 4 12.3 50.0 50.0 27.5 1 2 0.5 1 2 0.5 12.5 host 0.1
             FLASER 4 12.4 50.0 31.0 27.4 1 2 0.5 1 2 0.5 12.6 host 0.2
",
        );
        assert!(
            piles[0].is_some_and(|p| (49.99..50.0).contains(&p)),
            "{piles:?}"
        );
        assert_eq!(piles[1], None);
        assert_eq!(ranges[0], [Some(12.3), None, None, Some(27.5)]);
        assert_eq!(ranges[1], [Some(12.4), None, Some(31.0), Some(27.4)]);
        let (piles, ranges) = read(
            "FLASER 4 12.3 40.0 33.0 27.5 1 2 0.5 1 2 0.5 12.5 host 0.1
             FLASER 4 12.4 39.9 33.0 27.4 1 2 0.5 1 2 0.5 12.6 host 0.2
",
        );
        assert_eq!(piles, [None, None]);
        assert_eq!(ranges[0], [Some(12.3), Some(40.0), Some(33.0), Some(27.5)]);
    }

    /// Logs are recognised by their lines, gzip-compressed or not, whatever their
    /// name; a file named like a log that is not one is an error naming its line.
    #[test]
    fn logs_are_read_as_published_and_recognised_by_their_lines() {
        use std::io::Write;
        let log = "# CARMEN log\nPARAM robot_front_laser_max 81.9 host 0\n\
                   ODOM 1 2 3 0 0 0 5 host 5\n\
                   FLASER 3 1.0 81.9 2.5 1 2 0.5 1 2 0.5 12.5 host 0.1\n\
                   FLASER 3 1.1 81.9 2.4 1 2 0.5 1 2 0.5 12.6 host 0.2\n";
        let dir = tempfile::tempdir().unwrap();
        let gz = dir.path().join("run.log.gz");
        let mut enc =
            flate2::write::GzEncoder::new(std::fs::File::create(&gz).unwrap(), Default::default());
        enc.write_all(log.as_bytes()).unwrap();
        enc.finish().unwrap();
        let plain = dir.path().join("run.txt");
        std::fs::write(&plain, log).unwrap();
        for path in [&gz, &plain] {
            assert!(is_carmen(path), "{}", path.display());
            let mut frames = Vec::new();
            let n = read_carmen(path, |i| {
                frames.push(i.unwrap());
                true
            })
            .unwrap();
            assert_eq!((n, frames.len()), (2, 2));
            assert_eq!(frames[1].frame, 1);
        }
        let points = dir.path().join("points.txt");
        std::fs::write(&points, "# x y\n0 1\n2 3\n").unwrap();
        assert!(!is_carmen(&points));
        let not = dir.path().join("server.log");
        std::fs::write(&not, "\n2026-11-28 started\nFLASER 3 1 2 3\n").unwrap();
        assert!(is_carmen(&not));
        let e = read_carmen(&not, |_| true).unwrap_err().to_string();
        assert!(
            e.contains("server.log") && e.contains("line 2: not a CARMEN log"),
            "{e}"
        );
    }
}
