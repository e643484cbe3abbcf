//! The JSON shapes of the file contract (DESIGN.md section 4): frames, polylines, truth
//! files and result records. Kept apart from the numerical types, which know no serde.

use serde::{Deserialize, Serialize};

use crate::geom::{Point, Polyline};

/// One frame of an NDJSON stream: `{"stream":..,"frame":..,"t":..,"points":[[x,y],..],"origin":[x,y]}`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FrameRecord {
    /// Stream id (optional).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stream: Option<String>,
    /// Frame number.
    pub frame: u64,
    /// Time stamp in seconds (optional).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub t: Option<f64>,
    /// The points.
    pub points: Vec<Point>,
    /// Sensor origin (optional).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub origin: Option<Point>,
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

/// The truth of one frame of a multi-frame stream.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TruthFrame {
    /// Frame number.
    pub frame: u64,
    /// Exact curves of that frame.
    pub polylines: Vec<PolylineJson>,
}

/// A truth file: `{"polylines":[..]}` (frame 0, or the only frame), plus `"frames"` with
/// each frame's curves when the shape moves.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TruthFile {
    /// Curves of the first frame.
    pub polylines: Vec<PolylineJson>,
    /// Curves of every frame, when there is more than one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frames: Option<Vec<TruthFrame>>,
}

impl TruthFile {
    /// The truth of frame `frame`: its own entry if listed, else the top-level curves.
    pub fn for_frame(&self, frame: Option<u64>) -> Vec<Polyline> {
        let listed = frame.and_then(|f| {
            self.frames
                .as_ref()
                .and_then(|fs| fs.iter().find(|x| x.frame == f))
        });
        match listed {
            Some(f) => f.polylines.iter().cloned().map(Into::into).collect(),
            None => self.polylines.iter().cloned().map(Into::into).collect(),
        }
    }
}

/// Milliseconds per stage of one frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct StageMs {
    /// kd-tree and distances at the mesh vertices.
    pub distance: f64,
    /// Metric and mesh adaptation.
    pub adapt: f64,
    /// Time stepping and stopping tests.
    pub solve: f64,
    /// Fast-marching renormalization.
    pub renormalize: f64,
    /// Isoline extraction and simplification.
    pub export: f64,
    /// The whole frame: the sum of the stages.
    pub total: f64,
    /// Daemon only: from the frame's arrival to its record, queueing included.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub latency: Option<f64>,
}

/// The `stats` of a result record (DESIGN.md section 4), plus what a user tuning the
/// solver wants to see.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct FrameStats {
    /// Data points.
    pub points: usize,
    /// Mesh vertices.
    pub vertices: usize,
    /// Mesh triangles.
    pub triangles: usize,
    /// Solver time steps.
    pub iterations: usize,
    /// Eq. 11 residual: the largest `|u|` at a data point.
    pub residual: f64,
    /// Whether the residual got below `eps`.
    pub converged: bool,
    /// Whether the frame started from the previous frame's level set.
    pub warm_start: bool,
    /// Time per stage.
    pub ms: StageMs,
    /// Why the solver stopped: `converged`, `stagnated` or `max_iterations`.
    #[serde(default)]
    pub stop: String,
    /// `explicit` or `semi-implicit`.
    #[serde(default)]
    pub scheme: String,
    /// Conjugate-gradient iterations (semi-implicit).
    #[serde(default)]
    pub linear_iterations: usize,
    /// Renormalizations.
    #[serde(default)]
    pub renormalizations: usize,
    /// Smallest element size used.
    #[serde(default)]
    pub hmin: f64,
    /// Stopping tolerance used.
    #[serde(default)]
    pub eps: f64,
}

/// One line of a result stream: curves and stats, or an error, for one input frame.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ResultRecord {
    /// Stream id, as in the input.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stream: Option<String>,
    /// Frame number, as in the input.
    pub frame: u64,
    /// The curves.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub polylines: Option<Vec<PolylineJson>>,
    /// How they were made.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stats: Option<FrameStats>,
    /// Why the frame has no curves.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
    /// Daemon only: `true` when the frame was skipped for a newer one of its stream.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub skipped: Option<bool>,
}
