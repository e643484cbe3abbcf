//! Results for Foxglove: each frame's curves as a scene update (line strips in the
//! frame's coordinates, under the stream's frame id, with a sphere at each junction of
//! strokes), its points as a point cloud, its
//! record as JSON and, with a pose, the frame's transform from `world`. The messages are
//! made by one plain function, [`frame_messages`]; [`McapOut`] writes them to an MCAP
//! file, and the daemon's live view serves them over the Foxglove WebSocket protocol.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use foxglove::messages::{
    line_primitive, packed_element_field, Color, FrameTransform, FrameTransforms, LinePrimitive,
    PackedElementField, Point3, PointCloud, Pose as FoxglovePose, Quaternion, SceneEntity,
    SceneUpdate, SpherePrimitive, Timestamp, Vector3,
};
use foxglove::Encode;

use crate::error::{Error, Result};
use crate::format::ResultRecord;
use crate::write::PartFile;
use isoline_core::geom::{Point, Pose};

/// The frame the poses are in.
pub const WORLD_FRAME: &str = "world";

/// The topics written, with what each holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Topic {
    /// `/isoline/curves`: `foxglove.SceneUpdate`, one entity per stream.
    Curves,
    /// `/isoline/points`: `foxglove.PointCloud`, the frame's points (a scan's returns).
    Points,
    /// `/isoline/records`: the result record as JSON (stats, warnings, errors).
    Records,
    /// `/isoline/tf`: `foxglove.FrameTransforms`, the frame's pose in `world`.
    Transforms,
}

impl Topic {
    /// Every topic.
    pub const ALL: [Topic; 4] = [
        Topic::Curves,
        Topic::Points,
        Topic::Records,
        Topic::Transforms,
    ];

    /// The topic name.
    pub fn name(self) -> &'static str {
        match self {
            Topic::Curves => "/isoline/curves",
            Topic::Points => "/isoline/points",
            Topic::Records => "/isoline/records",
            Topic::Transforms => "/isoline/tf",
        }
    }

    /// Schema and message encoding.
    pub fn schema(self) -> (foxglove::Schema, String) {
        fn of<T: Encode>() -> (foxglove::Schema, String) {
            (
                T::get_schema().expect("the well-known types have schemas"),
                T::get_message_encoding(),
            )
        }
        match self {
            Topic::Curves => of::<SceneUpdate>(),
            Topic::Points => of::<PointCloud>(),
            Topic::Transforms => of::<FrameTransforms>(),
            Topic::Records => (
                foxglove::Schema::new(
                    "isoline.Record",
                    "jsonschema",
                    br#"{"type":"object","description":"an isoline result record (docs/formats.md)"}"#
                        .as_slice(),
                ),
                "json".into(),
            ),
        }
    }
}

/// One frame as Foxglove shows it.
#[derive(Clone, Debug, Default)]
pub struct FrameView {
    /// The frame's result record.
    pub record: ResultRecord,
    /// The frame's points, in its coordinates.
    pub points: Vec<Point>,
    /// Its time stamp, seconds.
    pub t: Option<f64>,
    /// Its pose in the world.
    pub pose: Option<Pose>,
}

impl FrameView {
    /// The frame id of its coordinates: the stream's id, or `isoline`.
    pub fn frame_id(&self) -> &str {
        match self.record.stream.as_deref() {
            Some(s) if !s.is_empty() => s,
            _ => "isoline",
        }
    }

    /// Its time in nanoseconds: the time stamp, or else the frame number at 10 Hz.
    pub fn nanos(&self) -> u64 {
        let t = self
            .t
            .unwrap_or(self.record.frame.unwrap_or(0) as f64 * 0.1);
        (t.clamp(0.0, 4.0e9) * 1e9) as u64
    }
}

fn timestamp(nanos: u64) -> Timestamp {
    Timestamp::new(
        (nanos / 1_000_000_000) as u32,
        (nanos % 1_000_000_000) as u32,
    )
}

/// The encoded messages of one frame, by topic: curves, points and record always, the
/// transform when the frame has a pose.
// One function: one message a topic, each a literal of its Foxglove schema.
pub fn frame_messages(view: &FrameView) -> Vec<(Topic, Vec<u8>)> {
    let stamp = Some(timestamp(view.nanos()));
    let frame_id = view.frame_id().to_string();
    let green = Color {
        r: 0.1,
        g: 0.8,
        b: 0.3,
        a: 1.0,
    };
    let lines = view
        .record
        .polylines
        .iter()
        .flatten()
        .map(|p| LinePrimitive {
            r#type: if p.closed {
                line_primitive::Type::LineLoop
            } else {
                line_primitive::Type::LineStrip
            } as i32,
            thickness: 3.0,
            scale_invariant: true,
            points: p
                .points
                .iter()
                .map(|q| Point3 {
                    x: q[0],
                    y: q[1],
                    z: 0.0,
                })
                .collect(),
            color: Some(green),
            ..Default::default()
        })
        .collect();
    // Junctions a hundredth of the curves' extent across: visible at any zoom that
    // shows the drawing, small beside its strokes.
    let bbox = isoline_core::geom::BBox::of(
        &view
            .record
            .polylines
            .iter()
            .flatten()
            .flat_map(|p| p.points.iter().copied())
            .collect::<Vec<_>>(),
    );
    let size = bbox.map_or(0.0, |b| b.diag()) / 100.0;
    let spheres = view
        .record
        .junctions
        .iter()
        .flatten()
        .map(|j| SpherePrimitive {
            pose: Some(FoxglovePose {
                position: Some(Vector3 {
                    x: j.at[0],
                    y: j.at[1],
                    z: 0.0,
                }),
                orientation: Some(Quaternion {
                    x: 0.0,
                    y: 0.0,
                    z: 0.0,
                    w: 1.0,
                }),
            }),
            size: Some(Vector3 {
                x: size,
                y: size,
                z: size,
            }),
            color: Some(Color {
                r: 0.2,
                g: 0.3,
                b: 0.9,
                a: 1.0,
            }),
        })
        .collect();
    let scene = SceneUpdate {
        deletions: Vec::new(),
        entities: vec![SceneEntity {
            timestamp: stamp,
            frame_id: frame_id.clone(),
            id: format!("{frame_id}/curves"),
            frame_locked: true,
            lines,
            spheres,
            ..Default::default()
        }],
    };
    let mut data = Vec::with_capacity(12 * view.points.len());
    for p in &view.points {
        for v in [p[0] as f32, p[1] as f32, 0.0f32] {
            data.extend_from_slice(&v.to_le_bytes());
        }
    }
    let field = |name: &str, offset| PackedElementField {
        name: name.into(),
        offset,
        r#type: packed_element_field::NumericType::Float32 as i32,
    };
    let cloud = PointCloud {
        timestamp: stamp,
        frame_id: frame_id.clone(),
        pose: None,
        point_stride: 12,
        fields: vec![field("x", 0), field("y", 4), field("z", 8)],
        data: data.into(),
    };
    let mut out = vec![
        (Topic::Curves, encoded(&scene)),
        (Topic::Points, encoded(&cloud)),
        (
            Topic::Records,
            serde_json::to_vec(&view.record).expect("records serialize"),
        ),
    ];
    if let Some(p) = view.pose {
        let q = crate::ingest::ros::Quaternion::of_yaw(p[2]);
        let tf = FrameTransforms {
            transforms: vec![FrameTransform {
                timestamp: stamp,
                parent_frame_id: WORLD_FRAME.into(),
                child_frame_id: frame_id,
                translation: Some(Vector3 {
                    x: p[0],
                    y: p[1],
                    z: 0.0,
                }),
                rotation: Some(Quaternion {
                    x: q.x,
                    y: q.y,
                    z: q.z,
                    w: q.w,
                }),
            }],
        };
        out.push((Topic::Transforms, encoded(&tf)));
    }
    out
}

/// A message's protobuf bytes.
fn encoded<T: Encode>(msg: &T) -> Vec<u8> {
    let mut buf = Vec::new();
    // Encoding into a growable buffer cannot run out of room.
    msg.encode(&mut buf).expect("encoding into a Vec");
    buf
}

/// An MCAP file of results, zstd-compressed. It is written beside its path (a [`PartFile`])
/// and takes its name once [`McapOut::finish`]ed: a run that fails or is killed leaves
/// no half file under the name, and an earlier file there stays whole until then.
pub struct McapOut {
    writer: mcap::Writer<std::io::BufWriter<std::fs::File>>,
    channels: BTreeMap<Topic, u16>,
    sequence: u32,
    path: PathBuf,
    /// Removes the unfinished file if the run fails or is killed first.
    part: PartFile,
}

impl McapOut {
    /// Starts the file `path`.
    pub fn create(path: &Path) -> Result<McapOut> {
        let (part, file) = PartFile::create(path).map_err(|e| Error::io(path, e))?;
        let mcap_err = |e: mcap::McapError| Error::Recording {
            path: path.to_path_buf(),
            message: e.to_string(),
        };
        let mut writer = mcap::WriteOptions::new()
            .profile("")
            .library(concat!("isoline ", env!("CARGO_PKG_VERSION")))
            .create(std::io::BufWriter::new(file))
            .map_err(mcap_err)?;
        let mut channels = BTreeMap::new();
        for topic in Topic::ALL {
            let (schema, encoding) = topic.schema();
            let s = writer
                .add_schema(&schema.name, &schema.encoding, &schema.data)
                .map_err(mcap_err)?;
            let c = writer
                .add_channel(s, topic.name(), &encoding, &BTreeMap::new())
                .map_err(mcap_err)?;
            channels.insert(topic, c);
        }
        Ok(McapOut {
            writer,
            channels,
            sequence: 0,
            path: path.to_path_buf(),
            part,
        })
    }

    fn error(&self, e: impl std::fmt::Display) -> Error {
        Error::Recording {
            path: self.path.clone(),
            message: e.to_string(),
        }
    }

    /// Writes one frame's messages.
    pub fn write(&mut self, view: &FrameView) -> Result<()> {
        let ns = view.nanos();
        for (topic, data) in frame_messages(view) {
            self.sequence = self.sequence.wrapping_add(1);
            let header = mcap::records::MessageHeader {
                channel_id: self.channels[&topic],
                sequence: self.sequence,
                log_time: ns,
                publish_time: ns,
            };
            self.writer
                .write_to_known_channel(&header, &data)
                .map_err(|e| self.error(e))?;
        }
        Ok(())
    }

    /// Writes the summary, flushes the file and gives it its name.
    pub fn finish(mut self) -> Result<()> {
        self.writer.finish().map_err(|e| self.error(e))?;
        let McapOut {
            writer, part, path, ..
        } = self;
        let mut file = writer.into_inner();
        std::io::Write::flush(&mut file).map_err(|e| Error::io(&path, e))?;
        drop(file);
        part.commit().map_err(|e| Error::io(&path, e))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::format::PolylineJson;
    use foxglove::Decode;

    #[test]
    fn a_frame_becomes_curves_points_record_and_transform() {
        let view = FrameView {
            record: ResultRecord {
                stream: Some("laser".into()),
                frame: Some(3),
                polylines: Some(vec![PolylineJson {
                    closed: false,
                    points: vec![[0.0, 1.0], [2.0, 1.0], [2.0, 3.0]],
                }]),
                junctions: Some(vec![crate::format::JunctionJson {
                    at: [2.0, 1.0],
                    polylines: vec![0],
                }]),
                ..Default::default()
            },
            points: vec![[0.0, 1.1], [2.0, 0.9]],
            t: Some(1.5),
            pose: Some([1.0, 2.0, 0.5]),
        };
        let msgs = frame_messages(&view);
        assert_eq!(
            msgs.iter().map(|m| m.0).collect::<Vec<_>>(),
            Topic::ALL.to_vec()
        );
        let scene = SceneUpdate::decode(msgs[0].1.as_slice()).unwrap();
        let e = &scene.entities[0];
        assert_eq!((e.frame_id.as_str(), e.lines.len()), ("laser", 1));
        assert_eq!(e.lines[0].points.len(), 3);
        let at = e.spheres[0].pose.unwrap().position.unwrap();
        assert_eq!((e.spheres.len(), at.x, at.y), (1, 2.0, 1.0));
        assert_eq!(e.timestamp.unwrap().total_nanos(), 1_500_000_000);
        let cloud = PointCloud::decode(msgs[1].1.as_slice()).unwrap();
        assert_eq!(cloud.data.len(), 24);
        let rec: ResultRecord = serde_json::from_slice(&msgs[2].1).unwrap();
        assert_eq!(rec.frame, Some(3));
        let tf = FrameTransforms::decode(msgs[3].1.as_slice()).unwrap();
        let q = tf.transforms[0].rotation.unwrap();
        assert!((2.0 * q.z.atan2(q.w) - 0.5).abs() < 1e-12);
    }
}
