//! The JSON shapes of the file contract (docs/formats.md): frames, polylines, truth
//! files and result records. Kept apart from the method's types, which know no serde:
//! the contract and the library change apart, and each conversion is written here.

use serde::{Deserialize, Serialize};

use isoline_core::geom::{Point, Polyline};
use isoline_core::Feature;

/// One frame of an NDJSON stream, as on the wire (see docs/formats.md): points,
/// `{"stream":..,"frame":..,"t":..,"points":[[x,y],..],"origin":[x,y]}`, or a scanner's
/// beams, `{"frame":..,"ranges":[r,..],"angle_min":a,"angle_increment":da,
/// "range_min":r0,"range_max":r1,"pose":[x,y,theta]}`. [`crate::ingest::Frame`] is the
/// validated form.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct FrameRecord {
    /// What the reader did to the frame's readings (e.g. readings taken for the
    /// scanner's no-return code and dropped); carried into the result's warnings.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub notes: Option<Vec<String>>,
    /// Stream id (optional).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stream: Option<String>,
    /// The sensor's coordinate frame, as a ROS header's `frame_id` names it (optional;
    /// a bag's scans carry theirs).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frame_id: Option<String>,
    /// Frame number.
    pub frame: u64,
    /// Time stamp in seconds (optional).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub t: Option<f64>,
    /// The points (absent in a frame of beams).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub points: Vec<Point>,
    /// The sensor's position in the frame's coordinates (optional; `[0, 0]` for beams).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub origin: Option<Point>,
    /// The pose `[x, y, theta]` of the frame's coordinates in a world frame (optional).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pose: Option<[f64; 3]>,
    /// Beams: each one's range, `null` where it returned nothing.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ranges: Option<Vec<Option<f64>>>,
    /// Beams: bearing of the first, radians counter-clockwise from the x axis.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub angle_min: Option<f64>,
    /// Beams: angle from one to the next, radians.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub angle_increment: Option<f64>,
    /// Beams: seconds from one beam to the next, as a ROS `LaserScan`'s `time_increment`
    /// (optional; absent or 0: taken at once). With the frame's time `t` and pose, and
    /// the stream's previous frame's, each return is corrected for the sensor's motion
    /// during the sweep.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time_increment: Option<f64>,
    /// Beams: nearer returns are no returns (default 0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub range_min: Option<f64>,
    /// Beams: returns at or beyond this are no returns; a beam without one is free up to
    /// it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub range_max: Option<f64>,
    /// Beams: intensities (optional, one per beam; read and not used).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub intensities: Option<Vec<Option<f64>>>,
}

/// A polyline on the wire: `{"closed":..,"points":[[x,y],..]}`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PolylineJson {
    /// Whether the last point joins the first.
    pub closed: bool,
    /// Vertices.
    pub points: Vec<Point>,
}

impl From<&Polyline> for PolylineJson {
    fn from(p: &Polyline) -> Self {
        PolylineJson {
            closed: p.closed,
            points: p.points.clone(),
        }
    }
}

impl From<PolylineJson> for Polyline {
    fn from(p: PolylineJson) -> Self {
        Polyline {
            closed: p.closed,
            points: p.points,
        }
    }
}

/// An opening in a wall (a doorway) on the wire: the segment across it, `[[x,y],[x,y]]`.
pub type OpeningJson = [Point; 2];

/// The sensor a simulated scan stream was made with (truth files of scenes).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SensorJson {
    /// The preset's name.
    pub name: String,
    /// Range noise (standard deviation).
    pub range_noise: f64,
    /// Probability that a beam returned nothing.
    pub dropout: f64,
    /// Probability that a beam returned a spurious short range.
    pub outliers: f64,
}

/// The truth of one frame of a multi-frame stream.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TruthFrame {
    /// Frame number.
    pub frame: u64,
    /// Exact curves of that frame (for a scan, what the sensor could see of each
    /// surface, in the sensor's frame).
    pub polylines: Vec<PolylineJson>,
    /// Scans: the openings in the walls (doorways), in the sensor's frame.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub openings: Option<Vec<OpeningJson>>,
    /// Scans: the sensor's pose in the scene.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pose: Option<[f64; 3]>,
    /// Scans with a walking person: where it is, `[x, y, radius]` in the scene's
    /// coordinates (its visible side is in `polylines`, not in the file's `scene`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub walker: Option<[f64; 3]>,
}

/// A truth file: `{"polylines":[..]}` (frame 0, or the only frame), plus `"frames"` with
/// each frame's curves when there are several; scans add the openings and the sensor.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TruthFile {
    /// Curves of the first frame.
    pub polylines: Vec<PolylineJson>,
    /// Scans: openings of the first frame.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub openings: Option<Vec<OpeningJson>>,
    /// Curves of every frame, when there is more than one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frames: Option<Vec<TruthFrame>>,
    /// Scans: the sensor.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sensor: Option<SensorJson>,
    /// Scans: every surface of the scene, in the scene's (world) coordinates.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scene: Option<Vec<PolylineJson>>,
    /// Scans: the sensor's pose in the scene in the first frame.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pose: Option<[f64; 3]>,
}

impl TruthFile {
    /// The truth of frame `frame`: its own entry if listed, else the top-level curves.
    pub fn for_frame(&self, frame: Option<u64>) -> Vec<Polyline> {
        self.frame(frame)
            .0
            .iter()
            .cloned()
            .map(Into::into)
            .collect()
    }

    /// The curves, openings and sensor pose of frame `frame`: its own entry if listed,
    /// else the top-level ones.
    pub fn frame(&self, frame: Option<u64>) -> (&[PolylineJson], &[OpeningJson], Option<[f64; 3]>) {
        let listed = frame.and_then(|f| {
            self.frames
                .as_ref()
                .and_then(|fs| fs.iter().find(|x| x.frame == f))
        });
        match listed {
            Some(f) => (&f.polylines, f.openings.as_deref().unwrap_or(&[]), f.pose),
            None => (
                &self.polylines,
                self.openings.as_deref().unwrap_or(&[]),
                self.pose,
            ),
        }
    }

    /// Every surface of the scene in frame `frame`'s sensor coordinates, with the
    /// walking person where the frame has one (a 64-gon); empty without a scene or a
    /// pose.
    pub fn surfaces(&self, frame: Option<u64>) -> Vec<Polyline> {
        let (_, _, pose) = self.frame(frame);
        let (Some(scene), Some(pose)) = (&self.scene, pose) else {
            return Vec::new();
        };
        let walker = frame.and_then(|f| {
            self.frames
                .as_ref()
                .and_then(|fs| fs.iter().find(|x| x.frame == f))
                .and_then(|x| x.walker)
        });
        let person = walker.map(|[x, y, r]| PolylineJson {
            closed: true,
            points: (0..64)
                .map(|i| {
                    let a = std::f64::consts::TAU * i as f64 / 64.0;
                    [x + r * a.cos(), y + r * a.sin()]
                })
                .collect(),
        });
        scene
            .iter()
            .chain(person.as_ref())
            .map(|pl| Polyline {
                closed: pl.closed,
                points: pl
                    .points
                    .iter()
                    .map(|&p| isoline_core::geom::to_sensor(pose, p))
                    .collect(),
            })
            .collect()
    }
}

/// A cluster of returns that no curve explains, on the wire:
/// `{"center":[x,y],"returns":n}`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FeatureJson {
    /// The returns' centroid.
    pub center: Point,
    /// How many returns.
    pub returns: usize,
}

/// Where open strokes meet, on the wire: `{"at":[x,y],"polylines":[i,j,k]}`, the
/// indices into the record's `polylines`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct JunctionJson {
    /// The meeting point.
    pub at: Point,
    /// The polylines ending there.
    pub polylines: Vec<usize>,
}

impl From<&isoline_core::Junction> for JunctionJson {
    fn from(j: &isoline_core::Junction) -> Self {
        JunctionJson {
            at: j.at,
            polylines: j.polylines.clone(),
        }
    }
}

impl From<&Feature> for FeatureJson {
    fn from(f: &Feature) -> Self {
        FeatureJson {
            center: f.center,
            returns: f.returns,
        }
    }
}

/// One line of a result stream: curves and stats, or an error, for one input frame.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ResultRecord {
    /// Stream id, as in the input.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stream: Option<String>,
    /// Frame number, as in the input; absent on the error record of a line whose frame
    /// number could not be read (see `line`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frame: Option<u64>,
    /// Daemon error records: the input line (1-based, within its file or TCP client)
    /// that the record answers.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub line: Option<u64>,
    /// The frame's time stamp, as in the input (a bag's header stamp, a log's time).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub t: Option<f64>,
    /// The frame's pose in the world, as in the input (or found in a bag's odometry or
    /// transforms): the curves are in the frame's coordinates, and this places them.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pose: Option<[f64; 3]>,
    /// The pose registration estimated for the frame (`[pipeline] register = true`),
    /// `[x, y, theta]` in the world frame of the stream's first scan (its input pose
    /// when it had one): where refinement and the map placed it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub registered_pose: Option<[f64; 3]>,
    /// The curves.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub polylines: Option<Vec<PolylineJson>>,
    /// Scan frames: clusters of returns that no curve explains (legs, clutter, spurious
    /// returns).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub features: Option<Vec<FeatureJson>>,
    /// Point clouds: where open strokes meet.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub junctions: Option<Vec<JunctionJson>>,
    /// How they were made.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stats: Option<isoline_core::Stats>,
    /// Why the frame has no curves.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
    /// Daemon only: `true` when the frame was skipped for a newer one of its stream.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub skipped: Option<bool>,
    /// What is wrong with a result that has one: no curve where the data have support,
    /// or most of the data unexplained.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub warnings: Option<Vec<String>>,
}

impl ResultRecord {
    /// Adds `notes` to the record's warnings.
    pub fn add_warnings(&mut self, notes: &[String]) {
        if !notes.is_empty() {
            self.warnings
                .get_or_insert_with(Vec::new)
                .extend(notes.iter().cloned());
        }
    }

    /// The record of a reconstructed frame: its curves, features (scan frames) and stats.
    pub fn of(
        stream: Option<String>,
        frame: u64,
        r: &isoline_core::Reconstruction,
    ) -> ResultRecord {
        ResultRecord {
            stream,
            frame: Some(frame),
            polylines: Some(r.polylines.iter().map(PolylineJson::from).collect()),
            features: r
                .stats
                .unexplained
                .map(|_| r.features.iter().map(FeatureJson::from).collect()),
            junctions: (!r.junctions().is_empty())
                .then(|| r.junctions().iter().map(JunctionJson::from).collect()),
            stats: Some(r.stats.clone()),
            warnings: (!r.warnings.is_empty())
                .then(|| r.warnings.iter().map(ToString::to_string).collect()),
            ..Default::default()
        }
    }
}
