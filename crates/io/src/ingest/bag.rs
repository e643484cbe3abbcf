//! MCAP input: the `sensor_msgs/msg/LaserScan` messages of a ROS 2 bag as beam frames,
//! with poses from a `nav_msgs/msg/Odometry` topic or the `/tf` tree.
//!
//! The file is streamed record by record (never mapped or read whole), with every
//! record, compressed chunks included, bounded by [`MAX_RECORD_BYTES`]. When poses are
//! asked for, a first pass collects the transforms (small messages) and a second emits
//! the scans, so a scan can take a pose logged after it.

use std::collections::{BTreeMap, HashMap};
use std::io::Read as _;
use std::ops::ControlFlow;
use std::path::Path;

use mcap::records::Record;
use mcap::sans_io::linear_reader::{LinearReadEvent, LinearReader, LinearReaderOptions};

use super::ros::{self, LaserScan};
use super::{BadFrame, Frame, Item};
use crate::error::{Error, Result};
use crate::format::FrameRecord;
use isoline_core::geom::Pose;
use isoline_core::MAX_BEAMS;

/// The largest record read (a chunk, compressed or not, or a message); a larger one
/// is an error rather than memory. Recorders write chunks of a few MiB.
pub const MAX_RECORD_BYTES: usize = 256 << 20;

/// The largest LaserScan message decoded: 16 MiB, as an NDJSON line
/// (`input.max_line_bytes`' default); a larger one gets an error record.
pub const MAX_MESSAGE_BYTES: usize = 16 << 20;

/// The longest a scan's time may be from the nearest pose sample of a moving transform
/// for the pose to be used without bracketing samples.
pub const MAX_POSE_GAP: f64 = 0.25;

/// What to read from a bag.
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BagOptions {
    /// LaserScan topics to read; empty: every LaserScan topic.
    #[serde(default)]
    pub topics: Vec<String>,
    /// A `nav_msgs/msg/Odometry` topic whose poses (with the `/tf` tree's static links
    /// from its child frame to the scanner) give each scan's pose.
    #[serde(default)]
    pub odometry: Option<String>,
    /// The frame the poses are in, found through `/tf` and `/tf_static` (and the
    /// odometry, if any): by default the odometry's parent frame.
    #[serde(default)]
    pub world_frame: Option<String>,
}

impl BagOptions {
    fn wants_poses(&self) -> bool {
        self.odometry.is_some() || self.world_frame.is_some()
    }
}

/// A channel of the bag, as far as isoline cares.
#[derive(Clone, Debug)]
struct Channel {
    topic: String,
    schema: String,
    encoding: String,
}

/// Streams the records of `path` to `each`, channels resolved. A damaged or cut file
/// ends the stream with `Err(description)` after the records before the damage.
fn stream(
    path: &Path,
    mut each: impl FnMut(&Channel, &[u8], u64) -> ControlFlow<()>,
) -> Result<std::result::Result<(), String>> {
    let mut file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let mut reader = LinearReader::new_with_options(
        // Chunks are checked against their CRC before any of their messages is used:
        // damage inside a chunk is an error, never a scan read with altered ranges.
        LinearReaderOptions::default()
            .with_record_length_limit(MAX_RECORD_BYTES)
            .with_prevalidate_chunk_crcs(true),
    );
    let mut schemas: HashMap<u16, String> = HashMap::new();
    let mut channels: HashMap<u16, Channel> = HashMap::new();
    let mut records = 0u64;
    while let Some(event) = reader.next_event() {
        let event = match event {
            Ok(e) => e,
            Err(e) if records == 0 => {
                return Err(Error::Recording {
                    path: path.to_path_buf(),
                    message: format!("not an MCAP file: {e}"),
                })
            }
            Err(e) => return Ok(Err(damaged(records, &e.to_string()))),
        };
        match event {
            LinearReadEvent::ReadRequest(need) => {
                let n = file
                    .read(reader.insert(need))
                    .map_err(|e| Error::io(path, e))?;
                reader.notify_read(n);
            }
            LinearReadEvent::Record { opcode, data } => {
                records += 1;
                match mcap::parse_record(opcode, data) {
                    Ok(Record::Schema { header, .. }) => {
                        schemas.insert(header.id, header.name);
                    }
                    Ok(Record::Channel(c)) => {
                        let schema = schemas.get(&c.schema_id).cloned().unwrap_or_default();
                        channels.insert(
                            c.id,
                            Channel {
                                topic: c.topic,
                                schema,
                                encoding: c.message_encoding,
                            },
                        );
                    }
                    Ok(Record::Message { header, data }) => {
                        let Some(ch) = channels.get(&header.channel_id) else {
                            return Ok(Err(damaged(
                                records,
                                &format!("a message on unknown channel {}", header.channel_id),
                            )));
                        };
                        if each(ch, &data, header.log_time).is_break() {
                            return Ok(Ok(()));
                        }
                    }
                    Ok(_) => {}
                    Err(e) => return Ok(Err(damaged(records, &e.to_string()))),
                }
            }
        }
    }
    Ok(Ok(()))
}

fn damaged(records: u64, why: &str) -> String {
    format!("the file is damaged or cut short after record {records}: {why}")
}

/// One link of the transform tree: the pose of a child frame in its parent over time.
#[derive(Debug, Default)]
struct Link {
    parent: String,
    /// Static (from `/tf_static`): its latest pose holds at all times.
    fixed: bool,
    /// (time, pose), sorted by time once collected.
    samples: Vec<(f64, Pose)>,
}

/// The poses of frames in one another, as `/tf` and odometry tell them.
#[derive(Debug, Default)]
pub struct Transforms {
    links: HashMap<String, Link>,
    /// The odometry's child frame: the scanner sits there when no link says where it is.
    base: Option<String>,
    /// The odometry's parent frame.
    odom_parent: Option<String>,
}

impl Transforms {
    fn add(&mut self, parent: &str, child: &str, fixed: bool, t: f64, pose: Pose) {
        if !pose.iter().all(|v| v.is_finite()) || parent.is_empty() || child.is_empty() {
            return;
        }
        let link = self.links.entry(child.to_string()).or_default();
        // A child re-parented mid-bag: the latest parent wins, its own samples only.
        if link.parent != parent {
            link.parent = parent.to_string();
            link.samples.clear();
        }
        link.fixed |= fixed;
        link.samples.push((t, pose));
    }

    fn sort(&mut self) {
        for l in self.links.values_mut() {
            l.samples.sort_by(|a, b| a.0.total_cmp(&b.0));
        }
    }

    /// The pose of `child` in its parent at `t`.
    fn link_at(link: &Link, t: f64) -> Option<Pose> {
        let s = &link.samples;
        let last = *s.last()?;
        if link.fixed {
            return Some(last.1);
        }
        let i = s.partition_point(|&(ts, _)| ts < t);
        if i == 0 {
            return ((s[0].0 - t) <= MAX_POSE_GAP).then_some(s[0].1);
        }
        if i == s.len() {
            return ((t - last.0) <= MAX_POSE_GAP).then_some(last.1);
        }
        let ((t0, a), (t1, b)) = (s[i - 1], s[i]);
        let f = if t1 > t0 { (t - t0) / (t1 - t0) } else { 0.0 };
        let turn = (b[2] - a[2] + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
            - std::f64::consts::PI;
        Some([
            a[0] + f * (b[0] - a[0]),
            a[1] + f * (b[1] - a[1]),
            a[2] + f * turn,
        ])
    }

    /// The pose of `frame` in `world` at `t`, through the links from `frame` up; the
    /// odometry's child frame stands in for a scanner frame the tree does not reach.
    pub fn pose(&self, world: &str, frame: &str, t: f64) -> Option<Pose> {
        self.walk(world, frame, t)
            .or_else(|| self.walk(world, self.base.as_deref()?, t))
    }

    fn walk<'a>(&'a self, world: &str, mut f: &'a str, t: f64) -> Option<Pose> {
        let mut pose: Pose = [0.0, 0.0, 0.0];
        // A cycle in a broken tree ends at the depth limit.
        for _ in 0..64 {
            if f == world {
                return Some(pose);
            }
            let link = self.links.get(f)?;
            pose = compose(Self::link_at(link, t)?, pose);
            f = &link.parent;
        }
        None
    }
}

/// The pose `inner` (in `outer`'s frame) in the frame `outer` is in.
fn compose(outer: Pose, inner: Pose) -> Pose {
    let [x, y] = isoline_core::geom::to_world(outer, [inner[0], inner[1]]);
    [x, y, outer[2] + inner[2]]
}

fn time_of(stamp: ros::Time, log_time: u64) -> f64 {
    stamp.seconds().unwrap_or(log_time as f64 * 1e-9)
}

/// The transforms of `path`: `/tf`, `/tf_static` (any `TFMessage` topic; static when
/// its name ends in `tf_static`) and the odometry topic.
fn transforms(path: &Path, opts: &BagOptions) -> Result<Transforms> {
    let mut tf = Transforms::default();
    let end = stream(path, |ch, data, log_time| {
        if ch.encoding != "cdr" {
            return ControlFlow::Continue(());
        }
        if ch.schema == ros::TF_MESSAGE {
            if let Ok(m) = ros::decode::<ros::TfMessage>(data) {
                let fixed = ch.topic.ends_with("tf_static");
                for x in m.transforms {
                    let p = x.transform;
                    let pose = [p.translation.x, p.translation.y, p.rotation.yaw()];
                    let t = time_of(x.header.stamp, log_time);
                    tf.add(&x.header.frame_id, &x.child_frame_id, fixed, t, pose);
                }
            }
        } else if opts.odometry.as_deref() == Some(ch.topic.as_str()) && ch.schema == ros::ODOMETRY
        {
            if let Ok(m) = ros::decode::<ros::Odometry>(data) {
                let p = m.pose.pose;
                let pose = [p.position.x, p.position.y, p.orientation.yaw()];
                let t = time_of(m.header.stamp, log_time);
                tf.add(&m.header.frame_id, &m.child_frame_id, false, t, pose);
                tf.base.get_or_insert(m.child_frame_id);
                tf.odom_parent.get_or_insert(m.header.frame_id);
            }
        }
        ControlFlow::Continue(())
    })?;
    // Damage is reported by the pass over the scans, with the scans it cuts off.
    drop(end);
    tf.sort();
    Ok(tf)
}

/// The frame record of a LaserScan: ranges outside the scanner's limits, NaN or
/// infinite are no returns.
pub fn scan_record(scan: &LaserScan, stream: String, frame: u64, t: f64) -> FrameRecord {
    let (lo, hi) = (f64::from(scan.range_min), f64::from(scan.range_max));
    let ranges = scan
        .ranges
        .iter()
        .map(|&r| {
            let r = f64::from(r);
            (r.is_finite() && r >= lo && r <= hi).then_some(r)
        })
        .collect();
    let intensities = (scan.intensities.len() == scan.ranges.len() && !scan.ranges.is_empty())
        .then(|| {
            scan.intensities
                .iter()
                .map(|&i| Some(f64::from(i)).filter(|v| v.is_finite()))
                .collect()
        });
    FrameRecord {
        stream: Some(stream),
        frame,
        t: Some(t),
        ranges: Some(ranges),
        angle_min: Some(f64::from(scan.angle_min)),
        angle_increment: Some(f64::from(scan.angle_increment)),
        // Drivers that do not time their beams write 0, as a frame taken at once.
        time_increment: (scan.time_increment.is_finite() && scan.time_increment > 0.0)
            .then(|| f64::from(scan.time_increment)),
        range_min: Some(lo),
        range_max: Some(hi),
        intensities,
        ..Default::default()
    }
}

/// What a pass over a bag found.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BagSummary {
    /// Scans read per topic.
    pub scans: BTreeMap<String, u64>,
    /// Scans given a pose.
    pub posed: u64,
}

/// Reads the scans of the bag `path` in file order, calling `each` with every frame or,
/// for a message that does not decode or validate and for damage that ends the file
/// early, a [`BadFrame`] naming the file, topic and message index; `each` returns
/// `false` to stop. Fails when the file cannot be opened or is not MCAP, or when a
/// chosen topic (or, with no topics chosen, any LaserScan topic) is not in it.
pub fn read_bag(
    path: &Path,
    opts: &BagOptions,
    each: impl FnMut(Item) -> bool,
) -> Result<BagSummary> {
    read_bag_with(
        path,
        opts,
        |rec| Frame::from_record(rec).map_err(|e| e.to_string()),
        each,
    )
}

/// [`read_bag`] with each scan's record made into a `T` by `make` (an error from it is
/// the message's [`BadFrame`]): [`read_bag`] validates frames, conversions keep the
/// records.
// One function: one pass over the bag's messages, each decoded by its channel's schema
// and placed by the transforms read so far; the pass's state (transforms, streams'
// numbering, the summary) stays in it.
pub fn read_bag_with<T>(
    path: &Path,
    opts: &BagOptions,
    make: impl Fn(FrameRecord) -> std::result::Result<T, String>,
    mut each: impl FnMut(std::result::Result<T, BadFrame>) -> bool,
) -> Result<BagSummary> {
    let name = path.display().to_string();
    let tf = if opts.wants_poses() {
        Some(transforms(path, opts)?)
    } else {
        None
    };
    let world = opts
        .world_frame
        .clone()
        .or_else(|| tf.as_ref().and_then(|t| t.odom_parent.clone()));
    let mut summary = BagSummary::default();
    let mut laser_topics: Vec<String> = Vec::new();
    // Per stream, the next frame number; per topic, the last stream its scans went to.
    let mut next: HashMap<String, u64> = HashMap::new();
    let mut topic_stream: HashMap<String, String> = HashMap::new();
    let mut stopped = false;
    let end = stream(path, |ch, data, log_time| {
        if ch.schema == ros::LASER_SCAN && !laser_topics.contains(&ch.topic) {
            laser_topics.push(ch.topic.clone());
        }
        let chosen = if opts.topics.is_empty() {
            ch.schema == ros::LASER_SCAN
        } else {
            opts.topics.contains(&ch.topic)
        };
        if !chosen {
            return ControlFlow::Continue(());
        }
        let index = summary.scans.entry(ch.topic.clone()).or_insert(0);
        let k = *index;
        *index += 1;
        let decoded = if data.len() > MAX_MESSAGE_BYTES {
            Err(format!(
                "{} bytes, more than the {MAX_MESSAGE_BYTES} a scan message may take",
                data.len()
            ))
        } else if ch.schema != ros::LASER_SCAN {
            Err(format!("schema {:?}, not {}", ch.schema, ros::LASER_SCAN))
        } else if ch.encoding != "cdr" {
            Err(format!("message encoding {:?}, not cdr", ch.encoding))
        } else {
            ros::decode::<LaserScan>(data).and_then(|s: LaserScan| {
                if s.ranges.len() > MAX_BEAMS {
                    Err(format!(
                        "{} beams, more than the {MAX_BEAMS} a scan may have",
                        s.ranges.len()
                    ))
                } else {
                    Ok(s)
                }
            })
        };
        let item = match decoded {
            Ok(scan) => {
                let stream = if scan.header.frame_id.is_empty() {
                    ch.topic.clone()
                } else {
                    scan.header.frame_id.clone()
                };
                topic_stream.insert(ch.topic.clone(), stream.clone());
                let n = next.entry(stream.clone()).or_insert(0);
                let frame = *n;
                *n += 1;
                let t = time_of(scan.header.stamp, log_time);
                let mut rec = scan_record(&scan, stream.clone(), frame, t);
                rec.frame_id = Some(scan.header.frame_id.clone()).filter(|f| !f.is_empty());
                if let (Some(tf), Some(w)) = (&tf, &world) {
                    rec.pose = tf.pose(w, &scan.header.frame_id, t);
                    summary.posed += u64::from(rec.pose.is_some());
                }
                make(rec).map_err(|e| BadFrame {
                    stream: Some(stream),
                    frame: Some(frame),
                    message: format!("{name}: topic {}, message {k}: {e}", ch.topic),
                })
            }
            Err(e) => {
                let stream = topic_stream
                    .get(&ch.topic)
                    .cloned()
                    .unwrap_or_else(|| ch.topic.clone());
                let n = next.entry(stream.clone()).or_insert(0);
                let frame = *n;
                *n += 1;
                Err(BadFrame {
                    stream: Some(stream),
                    frame: Some(frame),
                    message: format!("{name}: topic {}, message {k}: {e}", ch.topic),
                })
            }
        };
        if each(item) {
            ControlFlow::Continue(())
        } else {
            stopped = true;
            ControlFlow::Break(())
        }
    })?;
    if let Err(damage) = end {
        let last = summary
            .scans
            .iter()
            .map(|(t, n)| format!("{n} messages of {t}"))
            .collect::<Vec<_>>()
            .join(", ");
        let read = if last.is_empty() {
            "no scans read".to_string()
        } else {
            format!("read {last}")
        };
        each(Err(BadFrame {
            stream: None,
            frame: None,
            message: format!("{name}: {damage} ({read})"),
        }));
        return Ok(summary);
    }
    if stopped {
        return Ok(summary);
    }
    let missing: Vec<&String> = opts
        .topics
        .iter()
        .filter(|t| !summary.scans.contains_key(*t))
        .collect();
    if !missing.is_empty() || summary.scans.is_empty() {
        let what = if missing.is_empty() {
            "no sensor_msgs/msg/LaserScan topic".to_string()
        } else {
            format!("no messages on {missing:?}")
        };
        return Err(Error::Recording {
            path: path.to_path_buf(),
            message: format!("{what}; LaserScan topics in the file: {laser_topics:?}"),
        });
    }
    if let Some(o) = &opts.odometry {
        if tf.as_ref().is_some_and(|t| t.base.is_none()) {
            tracing::warn!(file = %name, topic = %o, "no odometry on the topic: frames without poses");
        }
    }
    Ok(summary)
}

/// Writes frames as a ROS 2 bag: each frame of beams a LaserScan on `topic` (its stream
/// as the frame id), each pose an Odometry on `odometry` (frame `world`, child the
/// stream). Frames of points cannot be LaserScans and are refused.
pub struct BagWriter<W: std::io::Write + std::io::Seek> {
    writer: mcap::Writer<W>,
    scan: u16,
    odom: u16,
    sequence: u32,
    world: String,
}

impl<W: std::io::Write + std::io::Seek> BagWriter<W> {
    /// Starts a bag on `w`, zstd-compressed as rosbag2 writes them.
    pub fn new(w: W, topic: &str, odometry: &str, world: &str) -> mcap::McapResult<Self> {
        let mut writer = mcap::WriteOptions::new().profile("ros2").create(w)?;
        let schema = |w: &mut mcap::Writer<W>, name: &str| {
            let text = ros::schema_text(name).expect("a known schema");
            w.add_schema(name, "ros2msg", text.as_bytes())
        };
        let s = schema(&mut writer, ros::LASER_SCAN)?;
        let o = schema(&mut writer, ros::ODOMETRY)?;
        let none = BTreeMap::new();
        let scan = writer.add_channel(s, topic, "cdr", &none)?;
        let odom = writer.add_channel(o, odometry, "cdr", &none)?;
        Ok(BagWriter {
            writer,
            scan,
            odom,
            sequence: 0,
            world: world.to_string(),
        })
    }

    fn put(&mut self, channel: u16, t: f64, data: &[u8]) -> mcap::McapResult<()> {
        let ns = (t.max(0.0) * 1e9) as u64;
        self.sequence = self.sequence.wrapping_add(1);
        self.writer.write_to_known_channel(
            &mcap::records::MessageHeader {
                channel_id: channel,
                sequence: self.sequence,
                log_time: ns,
                publish_time: ns,
            },
            data,
        )
    }

    /// Writes one frame record of beams (and its pose); time `t` or else the frame
    /// number at 10 Hz.
    pub fn write(&mut self, rec: &FrameRecord) -> std::result::Result<(), String> {
        let ranges = rec
            .ranges
            .as_ref()
            .ok_or("a frame of points has no beams to write as a LaserScan")?;
        let (a0, da) = (
            rec.angle_min.ok_or("no angle_min")?,
            rec.angle_increment.ok_or("no angle_increment")?,
        );
        let t = rec.t.unwrap_or(rec.frame as f64 * 0.1);
        // The record's own frame id, else its stream's name (a bag read back gives the
        // same stream).
        let frame_id = rec
            .frame_id
            .clone()
            .or_else(|| rec.stream.clone())
            .unwrap_or_else(|| "laser".into());
        let stamp = ros::Time::from_seconds(t);
        let scan = LaserScan {
            header: ros::Header {
                stamp,
                frame_id: frame_id.clone(),
            },
            angle_min: a0 as f32,
            angle_max: (a0 + da * ranges.len().saturating_sub(1) as f64) as f32,
            angle_increment: da as f32,
            range_min: rec.range_min.unwrap_or(0.0) as f32,
            range_max: rec.range_max.ok_or("no range_max")? as f32,
            ranges: ranges
                .iter()
                .map(|r| r.map_or(f32::INFINITY, |r| r as f32))
                .collect(),
            intensities: rec
                .intensities
                .as_ref()
                .map(|v| v.iter().map(|i| i.unwrap_or(0.0) as f32).collect())
                .unwrap_or_default(),
            time_increment: rec.time_increment.unwrap_or(0.0) as f32,
            ..Default::default()
        };
        self.put(self.scan, t, &ros::encode(&scan))
            .map_err(|e| e.to_string())?;
        if let Some(p) = rec.pose {
            let odom = ros::Odometry {
                header: ros::Header {
                    stamp,
                    frame_id: self.world.clone(),
                },
                child_frame_id: frame_id,
                pose: ros::PoseWithCovariance {
                    pose: ros::Pose {
                        position: ros::Vector3 {
                            x: p[0],
                            y: p[1],
                            z: 0.0,
                        },
                        orientation: ros::Quaternion::of_yaw(p[2]),
                    },
                    ..Default::default()
                },
                ..Default::default()
            };
            self.put(self.odom, t, &ros::encode(&odom))
                .map_err(|e| e.to_string())?;
        }
        Ok(())
    }

    /// Writes the summary and hands back the writer.
    pub fn finish(mut self) -> mcap::McapResult<()> {
        self.writer.finish().map(|_| ())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small bag: `n` scans of 40 beams with poses, on `/scan` and `/odom`.
    fn small_bag(n: u64) -> Vec<u8> {
        let mut w =
            BagWriter::new(std::io::Cursor::new(Vec::new()), "/scan", "/odom", "odom").unwrap();
        for k in 0..n {
            w.write(&FrameRecord {
                stream: Some("laser".into()),
                frame: k,
                t: Some(1.0 + 0.1 * k as f64),
                pose: Some([0.1 * k as f64, 0.0, 0.01 * k as f64]),
                ranges: Some((0..40).map(|i| Some(2.0 + 0.01 * f64::from(i))).collect()),
                angle_min: Some(-1.0),
                angle_increment: Some(0.05),
                time_increment: Some(2.5e-4),
                range_max: Some(10.0),
                ..Default::default()
            })
            .unwrap();
        }
        let mut w = w;
        w.writer.finish().unwrap();
        w.writer.into_inner().into_inner()
    }

    #[test]
    fn a_bag_reads_back_with_its_poses() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("b.mcap");
        std::fs::write(&path, small_bag(5)).unwrap();
        let opts = BagOptions {
            odometry: Some("/odom".into()),
            ..Default::default()
        };
        let mut frames = Vec::new();
        let summary = read_bag(&path, &opts, |i| {
            frames.push(i.unwrap());
            true
        })
        .unwrap();
        assert_eq!((frames.len(), summary.posed), (5, 5));
        let f = &frames[3];
        assert_eq!((f.stream.as_deref(), f.frame), (Some("laser"), 3));
        let pose = f.pose.unwrap();
        assert!((pose[0] - 0.3).abs() < 1e-12 && (pose[2] - 0.03).abs() < 1e-12);
        assert!((f.t.unwrap() - 1.3).abs() < 1e-9);
        // The beams' timing, as a float32 holds it.
        let sweep = f.sweep.unwrap();
        assert!((sweep.time_increment - 2.5e-4).abs() < 1e-10, "{sweep:?}");
        assert_eq!(sweep.angle_increment, f64::from(0.05f32));
    }

    /// Whatever the bytes (flipped, cut, overwritten, lengths made huge), reading a bag
    /// returns frames, bad frames or an error: it never panics, and never holds more
    /// than its record bound.
    #[test]
    fn damaged_bags_never_panic() {
        use rand::{Rng, SeedableRng};
        let good = small_bag(6);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.mcap");
        let opts = BagOptions {
            odometry: Some("/odom".into()),
            ..Default::default()
        };
        let mut outcomes = [0usize; 3];
        for seed in 0..300u64 {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let mut b = good.clone();
            for _ in 0..rng.random_range(1..4) {
                let at = rng.random_range(0..b.len());
                match rng.random_range(0..4) {
                    0 => b[at] ^= 1 << rng.random_range(0..8),
                    1 => b.truncate(at),
                    2 => {
                        let end = (at + 4).min(b.len());
                        b[at..end].fill(0xff);
                    }
                    _ => b[at] = rng.random(),
                }
                if b.is_empty() {
                    break;
                }
            }
            std::fs::write(&path, &b).unwrap();
            let (mut ok, mut bad) = (0, 0);
            match read_bag(&path, &opts, |i| {
                if i.is_ok() {
                    ok += 1;
                } else {
                    bad += 1;
                }
                true
            }) {
                Ok(_) => {
                    outcomes[0] += usize::from(bad == 0);
                    outcomes[1] += usize::from(bad > 0);
                }
                Err(_) => outcomes[2] += 1,
            }
            assert!(ok <= 6, "seed {seed}: {ok} frames from 6 scans");
        }
        // Some damage goes unnoticed (a flipped range), some is reported per message or
        // as a cut.
        assert!(outcomes[0] > 0 && outcomes[1] > 0, "{outcomes:?}");
        std::fs::write(&path, b"#not a bag\n").unwrap();
        let e = read_bag(&path, &opts, |_| true).unwrap_err().to_string();
        assert!(e.contains("m.mcap: not an MCAP file"), "{e}");
    }

    #[test]
    fn poses_chain_through_the_tree_and_interpolate_in_time() {
        let mut tf = Transforms::default();
        // map -> odom fixed, odom -> base moving, base -> laser fixed.
        tf.add(
            "map",
            "odom",
            true,
            0.0,
            [10.0, 0.0, std::f64::consts::FRAC_PI_2],
        );
        tf.add("odom", "base", false, 1.0, [0.0, 0.0, 0.0]);
        tf.add("odom", "base", false, 2.0, [2.0, 0.0, 3.0]);
        tf.add("odom", "base", false, 3.0, [2.0, 0.0, -3.0]);
        tf.add("base", "laser", true, 0.0, [0.5, 0.0, 0.0]);
        tf.sort();
        let p = tf.pose("map", "laser", 1.5).unwrap();
        // Halfway: base at (1, 0) heading 1.5 in odom; the laser 0.5 ahead of it; odom
        // turned a quarter turn in map.
        let (s, c) = 1.5f64.sin_cos();
        let in_odom = [1.0 + 0.5 * c, 0.5 * s];
        let want = [
            10.0 - in_odom[1],
            in_odom[0],
            std::f64::consts::FRAC_PI_2 + 1.5,
        ];
        for i in 0..3 {
            assert!((p[i] - want[i]).abs() < 1e-12, "{p:?} {want:?}");
        }
        // Headings interpolate the short way round (3 to -3 through pi).
        let h = tf.pose("odom", "base", 2.5).unwrap()[2];
        assert!((h.rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI).abs() < 1e-9);
        // Outside the samples by more than the gap, or no path: no pose.
        assert!(tf.pose("odom", "base", 3.0 + MAX_POSE_GAP / 2.0).is_some());
        assert!(tf.pose("odom", "base", 3.0 + 2.0 * MAX_POSE_GAP).is_none());
        assert!(tf.pose("map", "camera", 1.5).is_none());
        // A cycle ends.
        tf.add("laser", "map", true, 0.0, [0.0; 3]);
        assert!(tf.pose("nowhere", "laser", 1.5).is_none());
    }
}
