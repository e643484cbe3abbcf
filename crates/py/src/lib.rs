//! `isoline._isoline`: the Python face of isoline (PyO3). The package `isoline`
//! (python/isoline) re-exports it; its docstrings are the Python documentation and
//! `python/isoline/__init__.pyi` its types.
//!
//! Every function takes plain numpy data, releases the GIL while the method runs, and
//! raises Python exceptions: `ValueError` (its subclass `isoline.IsolineError`) for data
//! or parameters the method refuses, `OSError` for files that cannot be read. A frame
//! goes through exactly the code the `isoline` binary runs: [`isoline_io::Frame`]
//! validates it, [`isoline_io::reconstruct_frame`] or [`isoline_core::Stream`]
//! reconstructs it, and [`isoline_io::format::ResultRecord`] is what a result holds.

use std::path::PathBuf;
use std::sync::mpsc::{sync_channel, Receiver};
use std::sync::Mutex;

use numpy::ndarray::{Array1, Array2};
use numpy::{AllowTypeChange, IntoPyArray, PyArray1, PyArray2, PyArrayLikeDyn};
use pyo3::create_exception;
use pyo3::exceptions::{PyMemoryError, PyOSError, PyStopIteration, PyTypeError, PyValueError};
use pyo3::prelude::*;

use isoline_core::Point;
use isoline_io::format::{FrameRecord, ResultRecord};
use isoline_map::WindowLimits;

create_exception!(
    isoline,
    IsolineError,
    PyValueError,
    "Data, parameters or a file that isoline refuses; the message says what and where."
);

/// Frames a reader thread may read ahead of the Python loop that takes them.
const READ_AHEAD: usize = 64;

/// The refinement window's byte budget of one stream by default: the daemon's
/// (`pipeline.max_state_bytes` 4 GiB over `pipeline.max_streams` 256).
const DEFAULT_WINDOW_BYTES: usize = (4 << 30) / 256;

/// The most frames a refinement window may hold (the daemon's `pipeline.accumulate`).
const MAX_ACCUMULATE: usize = 100;

fn io_error(e: isoline_io::Error) -> PyErr {
    match e {
        isoline_io::Error::Io { .. } => PyOSError::new_err(e.to_string()),
        e => IsolineError::new_err(e.to_string()),
    }
}

fn core_error(e: isoline_core::Error) -> PyErr {
    IsolineError::new_err(e.to_string())
}

/// Room for `n` items, or `MemoryError`: an array may be a view of a few numbers that
/// claims more rows than memory holds (`np.broadcast_to`), and copying it must fail in
/// Python, not abort the interpreter.
fn reserve<T>(n: usize, what: &str) -> PyResult<Vec<T>> {
    let mut v = Vec::new();
    v.try_reserve_exact(n)
        .map_err(|_| PyMemoryError::new_err(format!("{what}: {n} rows do not fit in memory")))?;
    Ok(v)
}

/// The rows of an (N, 2) array-like as points; anything else is a `ValueError`.
fn points_of(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<Point>> {
    let array: PyArrayLikeDyn<'_, f64, AllowTypeChange> = obj
        .extract()
        .map_err(|e| IsolineError::new_err(format!("{what}: not an array of numbers ({e})")))?;
    let view = array.as_array();
    if view.ndim() != 2 || view.shape()[1] != 2 {
        return Err(IsolineError::new_err(format!(
            "{what}: shape {:?}, expected (N, 2)",
            view.shape()
        )));
    }
    let mut points = reserve(view.shape()[0], what)?;
    points.extend(view.outer_iter().map(|row| [row[0], row[1]]));
    Ok(points)
}

/// A one-dimensional array-like of at most `max` numbers (checked before the copy).
fn vector_of(obj: &Bound<'_, PyAny>, what: &str, max: usize) -> PyResult<Vec<f64>> {
    let array: PyArrayLikeDyn<'_, f64, AllowTypeChange> = obj
        .extract()
        .map_err(|e| IsolineError::new_err(format!("{what}: not an array of numbers ({e})")))?;
    let view = array.as_array();
    if view.ndim() != 1 {
        return Err(IsolineError::new_err(format!(
            "{what}: shape {:?}, expected (N,)",
            view.shape()
        )));
    }
    if view.len() > max {
        return Err(IsolineError::new_err(format!(
            "{what}: {} values, at most {max}",
            view.len()
        )));
    }
    let mut v = reserve(view.len(), what)?;
    v.extend(view.iter().copied());
    Ok(v)
}

fn points_array<'py>(py: Python<'py>, points: &[Point]) -> Bound<'py, PyArray2<f64>> {
    let flat: Vec<f64> = points.iter().flatten().copied().collect();
    Array2::from_shape_vec((points.len(), 2), flat)
        .expect("two numbers a point")
        .into_pyarray(py)
}

/// Reconstruction parameters: the `[mesh]`, `[solver]`, `[export]`, `[scan]` and
/// `[register]` tables of an isoline configuration file (every key, commented, in the
/// repository's config/example.toml; docs/formats.md). `Params()` is the defaults, which
/// derive every length from the data.
///
/// >>> isoline.Params('[export]\nsimplify = 0.01\n')
#[pyclass(module = "isoline", frozen)]
#[derive(Clone)]
struct Params {
    inner: isoline_core::Params,
    /// `[register]`: how a `Stream(register=True)` estimates poses.
    register: isoline_map::RegisterParams,
    /// `[scan] time_increment`: the beams' timing for frames that do not give theirs.
    time_increment: Option<f64>,
    text: String,
}

#[pymethods]
impl Params {
    #[new]
    #[pyo3(signature = (toml = ""))]
    fn new(toml: &str) -> PyResult<Self> {
        let cfg = isoline_io::config::Config::parse(toml, "Params").map_err(io_error)?;
        Ok(Params {
            inner: cfg.params(),
            register: cfg.register,
            time_increment: cfg.scan.time_increment,
            text: toml.to_string(),
        })
    }

    /// Reads the method's tables of a configuration file (other tables are refused:
    /// give a file of the method's tables only).
    #[staticmethod]
    fn load(path: PathBuf) -> PyResult<Self> {
        let text = std::fs::read_to_string(&path)
            .map_err(|e| PyOSError::new_err(format!("{}: {e}", path.display())))?;
        let cfg = isoline_io::config::Config::parse(&text, &path.display().to_string())
            .map_err(io_error)?;
        Ok(Params {
            inner: cfg.params(),
            register: cfg.register,
            time_increment: cfg.scan.time_increment,
            text,
        })
    }

    fn __repr__(&self) -> String {
        format!("isoline.Params({:?})", self.text)
    }
}

fn params_or_default(params: Option<&Params>) -> isoline_core::Params {
    params.map(|p| p.inner.clone()).unwrap_or_default()
}

/// One frame: points, or a laser scan's beams, with its stream, number, time and pose.
/// `read_frames` yields them; `Frame.from_points` and `Frame.from_scan` make them.
#[pyclass(module = "isoline", frozen)]
#[derive(Clone)]
struct Frame {
    inner: isoline_io::Frame,
}

/// A pose as Python gives it: any three numbers (a tuple, a list, a numpy array), `x`
/// and `y` in the data's units (metres for scans) and the heading in radians,
/// counter-clockwise: where the frame's coordinates (the sensor's, for a scan) sit in
/// the world. `None` is no pose. Not three numbers is a `TypeError`; a non-finite one
/// an `IsolineError`, as the readers refuse it; a heading beyond a turn is taken as
/// given (unwrapped odometry has them) with one warning that it may be in degrees.
fn pose_arg(py: Python<'_>, obj: Option<&Bound<'_, PyAny>>) -> PyResult<Option<[f64; 3]>> {
    let Some(obj) = obj.filter(|o| !o.is_none()) else {
        return Ok(None);
    };
    let shown = || obj.repr().map_or_else(|_| "?".into(), |r| r.to_string());
    let v: Vec<f64> = obj.extract().map_err(|_| {
        PyTypeError::new_err(format!(
            "pose: expected three numbers (x, y, heading in radians), got {}",
            shown()
        ))
    })?;
    let [x, y, th] = v[..] else {
        return Err(PyTypeError::new_err(format!(
            "pose: expected three numbers (x, y, heading in radians), got {} numbers",
            v.len()
        )));
    };
    if !(x.is_finite() && y.is_finite() && th.is_finite()) {
        return Err(IsolineError::new_err(format!(
            "invalid scan: pose ({x}, {y}, {th}) is not finite"
        )));
    }
    if th.abs() > std::f64::consts::TAU {
        warn_once(
            py,
            &HEADING_WARNED,
            &format!(
                "pose heading {th} is more than a turn: headings are in radians (degrees?); \
                 it is taken as given"
            ),
        )?;
    }
    Ok(Some([x, y, th]))
}

/// Whether the heading warning was given (once a process).
static HEADING_WARNED: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// A `UserWarning` with `text`, unless `flag` says it was given.
fn warn_once(py: Python<'_>, flag: &std::sync::atomic::AtomicBool, text: &str) -> PyResult<()> {
    if flag.swap(true, std::sync::atomic::Ordering::Relaxed) {
        return Ok(());
    }
    let warning = py.get_type::<pyo3::exceptions::PyUserWarning>();
    PyErr::warn(
        py,
        &warning,
        &std::ffi::CString::new(text.replace('\0', " ")).unwrap_or_default(),
        1,
    )
}

#[pymethods]
impl Frame {
    /// A frame of points: an (N, 2) array of x, y (a point cloud, a digitized contour).
    /// `origin` is the sensor's position when the points were seen from one (then the
    /// free space between it and the points is known).
    #[staticmethod]
    #[pyo3(signature = (points, *, origin = None, pose = None, t = None, frame = 0, stream = None, frame_id = None))]
    #[allow(clippy::too_many_arguments)]
    fn from_points(
        points: &Bound<'_, PyAny>,
        origin: Option<(f64, f64)>,
        pose: Option<&Bound<'_, PyAny>>,
        t: Option<f64>,
        frame: u64,
        stream: Option<String>,
        frame_id: Option<String>,
    ) -> PyResult<Self> {
        let pose = pose_arg(points.py(), pose)?;
        let points = points_of(points, "points")?;
        isoline_core::validate_points(&points).map_err(core_error)?;
        let record = FrameRecord {
            stream,
            frame_id,
            frame,
            t,
            points,
            origin: origin.map(|(x, y)| [x, y]),
            pose,
            ..Default::default()
        };
        Ok(Frame {
            inner: isoline_io::Frame::from_record(record).map_err(io_error)?,
        })
    }

    /// A laser scan as a ROS `sensor_msgs/LaserScan` gives it: beam `i` at angle
    /// `angle_min + i * angle_increment` (radians, counter-clockwise from the sensor's x
    /// axis) measured `ranges[i]`; ranges outside `[range_min, range_max]`, NaN or
    /// infinite are no returns. `origin` is the sensor's position in the frame's
    /// coordinates; `pose` (x, y, heading) places the frame in the world.
    #[staticmethod]
    #[pyo3(signature = (ranges, angle_min, angle_increment, range_min, range_max, *, origin = (0.0, 0.0), pose = None, t = None, frame = 0, stream = None, frame_id = None))]
    #[allow(clippy::too_many_arguments)]
    fn from_scan(
        ranges: &Bound<'_, PyAny>,
        angle_min: f64,
        angle_increment: f64,
        range_min: f64,
        range_max: f64,
        origin: (f64, f64),
        pose: Option<&Bound<'_, PyAny>>,
        t: Option<f64>,
        frame: u64,
        stream: Option<String>,
        frame_id: Option<String>,
    ) -> PyResult<Self> {
        let pose = pose_arg(ranges.py(), pose)?;
        let ranges = vector_of(ranges, "ranges", isoline_core::MAX_BEAMS)?
            .into_iter()
            .map(|r| (r.is_finite() && r >= range_min && r <= range_max).then_some(r))
            .collect();
        let record = FrameRecord {
            stream,
            frame_id,
            frame,
            t,
            origin: Some([origin.0, origin.1]),
            pose,
            ranges: Some(ranges),
            angle_min: Some(angle_min),
            angle_increment: Some(angle_increment),
            range_min: Some(range_min),
            range_max: Some(range_max),
            ..Default::default()
        };
        Ok(Frame {
            inner: isoline_io::Frame::from_record(record).map_err(io_error)?,
        })
    }

    /// The stream the frame belongs to, if it says.
    #[getter]
    fn stream(&self) -> Option<String> {
        self.inner.stream.clone()
    }

    /// The sensor's coordinate frame, as a ROS header's `frame_id` names it (a bag's
    /// scans carry theirs; NDJSON frames their `frame_id` field), if the input says.
    /// A bag's `stream` is this frame id too (the topic where it has none).
    #[getter]
    fn frame_id(&self) -> Option<String> {
        self.inner.frame_id.clone()
    }

    /// Its number within the stream.
    #[getter]
    fn frame(&self) -> u64 {
        self.inner.frame
    }

    /// Its time stamp, seconds.
    #[getter]
    fn t(&self) -> Option<f64> {
        self.inner.t
    }

    /// Where its coordinates sit in the world: (x, y, heading in radians).
    #[getter]
    fn pose(&self) -> Option<(f64, f64, f64)> {
        self.inner.pose.map(|[x, y, th]| (x, y, th))
    }

    /// Its points (a scan's returns), an (N, 2) array in the frame's coordinates.
    #[getter]
    fn points<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        points_array(py, &self.inner.points)
    }

    /// Whether it was seen from a sensor (a scan, or points with an origin).
    #[getter]
    fn is_scan(&self) -> bool {
        self.inner.scan.is_some()
    }

    /// A scan's ranges, one a beam in bearing order, NaN where a beam returned nothing
    /// (metres); `None` for points without a sensor.
    #[getter]
    fn ranges<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray1<f64>>> {
        let scan = self.inner.scan.as_ref()?;
        Some(PyArray1::from_slice(py, &scan.ranges))
    }

    /// A scan's beam bearings, radians, counter-clockwise from the frame's x axis, one a
    /// range; `None` for points without a sensor.
    #[getter]
    fn angles<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray1<f64>>> {
        let scan = self.inner.scan.as_ref()?;
        Some(PyArray1::from_slice(py, &scan.angles))
    }

    fn __repr__(&self) -> String {
        format!(
            "isoline.Frame(stream={}, frame={}, points={}, scan={}, pose={})",
            self.inner
                .stream
                .as_deref()
                .map_or("None".into(), |s| format!("{s:?}")),
            self.inner.frame,
            self.inner.points.len(),
            if self.inner.scan.is_some() {
                "True"
            } else {
                "False"
            },
            self.inner
                .pose
                .map_or("None".into(), |[x, y, th]| format!("({x}, {y}, {th})"))
        )
    }
}

/// The curves of one frame, as the `isoline` binary writes them in a result record.
#[pyclass(module = "isoline", frozen)]
struct Result {
    record: ResultRecord,
}

#[pymethods]
impl Result {
    /// The curves: a list of (M, 2) arrays in the frame's coordinates. A closed curve's
    /// last point is not repeated; closed loops run counter-clockwise around inside
    /// regions, and a scan's open walls keep the free side on their left.
    #[getter]
    fn polylines<'py>(&self, py: Python<'py>) -> Vec<Bound<'py, PyArray2<f64>>> {
        self.record
            .polylines
            .iter()
            .flatten()
            .map(|p| points_array(py, &p.points))
            .collect()
    }

    /// For each curve, whether it is closed.
    #[getter]
    fn closed(&self) -> Vec<bool> {
        self.record
            .polylines
            .iter()
            .flatten()
            .map(|p| p.closed)
            .collect()
    }

    /// Scans: the centres of the clusters of returns no curve explains (legs, clutter),
    /// a (K, 2) array.
    #[getter]
    fn features<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let centres: Vec<Point> = self
            .record
            .features
            .iter()
            .flatten()
            .map(|f| f.center)
            .collect();
        points_array(py, &centres)
    }

    /// The number of returns in each feature, a (K,) array.
    #[getter]
    fn feature_returns<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<u64>> {
        let n: Vec<u64> = self
            .record
            .features
            .iter()
            .flatten()
            .map(|f| f.returns as u64)
            .collect();
        Array1::from_vec(n).into_pyarray(py)
    }

    /// Point clouds: where open strokes meet, as (point, indices of the curves).
    #[getter]
    fn junctions(&self) -> Vec<((f64, f64), Vec<usize>)> {
        self.record
            .junctions
            .iter()
            .flatten()
            .map(|j| ((j.at[0], j.at[1]), j.polylines.clone()))
            .collect()
    }

    /// What is wrong with the result, if anything (docs/formats.md lists them).
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.record.warnings.clone().unwrap_or_default()
    }

    /// How the frame was reconstructed: the record's `stats` (docs/formats.md), e.g.
    /// `warm_start`, `iterations`, `explained`, `ms`.
    #[getter]
    fn stats<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let text = serde_json::to_string(&self.record.stats)
            .map_err(|e| IsolineError::new_err(e.to_string()))?;
        py.import("json")?.call_method1("loads", (text,))
    }

    /// Whether the frame was warm-started from its stream's previous one.
    #[getter]
    fn warm_start(&self) -> bool {
        self.record.stats.as_ref().is_some_and(|s| s.warm_start)
    }

    /// The frame's stream, if it had one.
    #[getter]
    fn stream(&self) -> Option<String> {
        self.record.stream.clone()
    }

    /// The frame's number.
    #[getter]
    fn frame(&self) -> Option<u64> {
        self.record.frame
    }

    /// The frame's time stamp, seconds, if it had one.
    #[getter]
    fn t(&self) -> Option<f64> {
        self.record.t
    }

    /// The frame's pose, (x, y, heading), when it had one.
    #[getter]
    fn pose(&self) -> Option<(f64, f64, f64)> {
        self.record.pose.map(|[x, y, th]| (x, y, th))
    }

    /// The pose a `Stream(register=True)` estimated for the frame, (x, y, heading) in
    /// metres and radians, in the world of the stream's first scan; `None` otherwise.
    #[getter]
    fn registered_pose(&self) -> Option<(f64, f64, f64)> {
        self.record.registered_pose.map(|[x, y, th]| (x, y, th))
    }

    /// The curves placed in the world by the frame's pose (`ValueError` without one),
    /// in the order of `polylines` and `closed`; with `close=True` a closed curve
    /// repeats its first point at its end (as GeoJSON rings do), so that it draws
    /// closed.
    #[pyo3(signature = (*, close = false))]
    fn to_world<'py>(
        &self,
        py: Python<'py>,
        close: bool,
    ) -> PyResult<Vec<Bound<'py, PyArray2<f64>>>> {
        let pose = self
            .record
            .pose
            .ok_or_else(|| PyValueError::new_err("the frame has no pose"))?;
        Ok(self
            .record
            .polylines
            .iter()
            .flatten()
            .map(|p| {
                let mut world: Vec<Point> = p
                    .points
                    .iter()
                    .map(|&q| isoline_core::geom::to_world(pose, q))
                    .collect();
                if close && p.closed && !world.is_empty() {
                    world.push(world[0]);
                }
                points_array(py, &world)
            })
            .collect())
    }

    /// The result record as the `isoline` binary writes it: one line of JSON.
    fn to_json(&self) -> PyResult<String> {
        serde_json::to_string(&self.record).map_err(|e| IsolineError::new_err(e.to_string()))
    }

    fn __repr__(&self) -> String {
        let n = self.record.polylines.as_ref().map_or(0, Vec::len);
        format!(
            "isoline.Result(frame={}, curves={n}, warnings={})",
            self.record.frame.map_or("None".into(), |f| f.to_string()),
            self.record.warnings.as_ref().map_or(0, Vec::len)
        )
    }
}

/// Runs one frame through the method with the GIL released.
fn reconstruct_one(
    py: Python<'_>,
    frame: &isoline_io::Frame,
    params: &isoline_core::Params,
) -> PyResult<Result> {
    let (record, _) = py.detach(|| isoline_io::reconstruct_frame(frame, params));
    match &record.error {
        Some(e) => Err(IsolineError::new_err(e.clone())),
        None => Ok(Result { record }),
    }
}

/// Reconstructs the curves through `points`, an (N, 2) array of x, y.
#[pyfunction]
#[pyo3(signature = (points, params = None))]
fn reconstruct(
    py: Python<'_>,
    points: &Bound<'_, PyAny>,
    params: Option<&Params>,
) -> PyResult<Result> {
    let frame = Frame::from_points(points, None, None, None, 0, None, None)?;
    reconstruct_one(py, &frame.inner, &params_or_default(params))
}

/// Reconstructs the walls a laser scan saw: open curves with the free side (the sensor's)
/// on their left. The arguments are a `sensor_msgs/LaserScan`'s (see `Frame.from_scan`);
/// `pose` is recorded in the result (`Result.to_world`).
#[pyfunction]
#[pyo3(signature = (ranges, angle_min, angle_increment, range_min, range_max, pose = None, params = None))]
#[allow(clippy::too_many_arguments)]
fn reconstruct_scan(
    py: Python<'_>,
    ranges: &Bound<'_, PyAny>,
    angle_min: f64,
    angle_increment: f64,
    range_min: f64,
    range_max: f64,
    pose: Option<&Bound<'_, PyAny>>,
    params: Option<&Params>,
) -> PyResult<Result> {
    let frame = Frame::from_scan(
        ranges,
        angle_min,
        angle_increment,
        range_min,
        range_max,
        (0.0, 0.0),
        pose,
        None,
        0,
        None,
        None,
    )?;
    reconstruct_one(py, &frame.inner, &params_or_default(params))
}

/// Reconstructs one `Frame` on its own (no warm start).
#[pyfunction]
#[pyo3(signature = (frame, params = None))]
fn reconstruct_frame(py: Python<'_>, frame: &Frame, params: Option<&Params>) -> PyResult<Result> {
    reconstruct_one(py, &frame.inner, &params_or_default(params))
}

/// A stream of frames from one sensor: each frame is warm-started from the one before
/// (moved by the change of pose), and with `accumulate` > 1 each scan with a pose is
/// refined over the stream's last `accumulate` frames. With `register=True` each scan's
/// pose is estimated against the stream's local map, the given pose taken as odometry
/// (none: from the returns alone; `Params`' `[register]` table sets how), and the
/// result's `registered_pose` places it, as the daemon's `register = true` does. It takes the decisions the daemon
/// takes for one stream with the same `[pipeline]` settings: a frame number that does
/// not go up restarts the stream cold.
#[pyclass(module = "isoline")]
struct Stream {
    inner: isoline_core::Stream,
    next: u64,
    /// With `register=True`: the stream's pose stage (isoline-map).
    registrar: Option<isoline_map::Registrar>,
    /// `[scan] time_increment` of the stream's parameters: the beams' timing of frames
    /// that give none.
    time_increment: Option<f64>,
    /// The refinement window's frames (`accumulate`).
    accumulate: usize,
    /// Whether the warning that a scan without a pose is not refined was given.
    warned_no_pose: std::sync::atomic::AtomicBool,
}

#[pymethods]
impl Stream {
    #[new]
    #[pyo3(signature = (params = None, *, warm_start = true, accumulate = 0, accumulate_seconds = None, max_state_bytes = DEFAULT_WINDOW_BYTES, register = false))]
    fn new(
        params: Option<&Params>,
        warm_start: bool,
        accumulate: usize,
        accumulate_seconds: Option<f64>,
        max_state_bytes: usize,
        register: bool,
    ) -> PyResult<Self> {
        if accumulate > MAX_ACCUMULATE {
            return Err(PyValueError::new_err(format!(
                "accumulate = {accumulate}: must be in 0..={MAX_ACCUMULATE}"
            )));
        }
        if let Some(s) = accumulate_seconds {
            if !(0.001..=1e6).contains(&s) {
                return Err(PyValueError::new_err(format!(
                    "accumulate_seconds = {s}: must be in [0.001, 1e6] seconds"
                )));
            }
        }
        let mut inner = isoline_core::Stream::new(params_or_default(params), warm_start);
        if accumulate > 1 {
            inner = inner.refining(Box::new(isoline_map::Window::new(WindowLimits {
                frames: accumulate,
                seconds: accumulate_seconds,
                max_bytes: Some(max_state_bytes),
            })));
        }
        let registrar = if register {
            let params = params.map_or_else(Default::default, |p| p.register);
            Some(isoline_map::Registrar::streaming(params).map_err(|p| {
                PyValueError::new_err(format!("register parameters: {}", p.join("; ")))
            })?)
        } else {
            None
        };
        Ok(Stream {
            inner,
            next: 0,
            registrar,
            time_increment: params.and_then(|p| p.time_increment),
            accumulate,
            warned_no_pose: std::sync::atomic::AtomicBool::new(false),
        })
    }

    /// Reconstructs the stream's next frame: a `Frame` (its own number, time and pose
    /// unless given here), or an (N, 2) array of points. Frames without a number are
    /// numbered on from the last one.
    #[pyo3(signature = (data, pose = None, t = None, frame = None))]
    fn push(
        &mut self,
        py: Python<'_>,
        data: &Bound<'_, PyAny>,
        pose: Option<&Bound<'_, PyAny>>,
        t: Option<f64>,
        frame: Option<u64>,
    ) -> PyResult<Result> {
        let pose = pose_arg(py, pose)?;
        let mut f = match data.cast::<Frame>() {
            Ok(f) => f.get().inner.clone(),
            Err(_) => {
                let number = frame.unwrap_or(self.next);
                Frame::from_points(data, None, None, None, number, None, None)?.inner
            }
        };
        if let Some(n) = frame {
            f.frame = n;
        }
        // What every constructor and reader refuses, refused here too (the pose by
        // pose_arg).
        if let Some(t) = t.filter(|t| !t.is_finite()) {
            return Err(IsolineError::new_err(format!(
                "invalid scan: t = {t} is not finite"
            )));
        }
        if pose.is_some() {
            f.pose = pose;
        }
        // Refinement places each scan by its pose: a scan without one is built from
        // itself alone, which is said once.
        if self.accumulate > 1 && f.scan.is_some() && f.pose.is_none() && self.registrar.is_none() {
            warn_once(
                py,
                &self.warned_no_pose,
                "Stream(accumulate=...) refines scans over frames placed by their poses: this \
                 scan has none, so it is built from itself alone (give pose=, or \
                 register=True to estimate poses)",
            )?;
        }
        if t.is_some() {
            f.t = t;
        }
        self.next = f.frame.saturating_add(1);
        let (inner, registrar, time_increment) =
            (&mut self.inner, &mut self.registrar, self.time_increment);
        let outcome = py.detach(|| {
            // Registered scans are placed by the estimate, as the daemon places them; one
            // without a pose is corrected for its sweep by the motion registration gives,
            // as the daemon's register stage corrects it.
            let registered = match (registrar.as_mut(), f.scan.as_ref()) {
                (Some(r), Some(scan)) => match f.unposed_sweep(time_increment) {
                    Some((t, sweep)) => {
                        let (reg, fixed) = r.push_swept(scan, &sweep, t, None);
                        f.replace_scan(fixed);
                        Some(reg.pose)
                    }
                    None => Some(r.push(scan, f.pose).pose),
                },
                _ => None,
            };
            inner
                .push(&isoline_core::StreamFrame {
                    frame: f.frame,
                    points: &f.points,
                    scan: f.scan.as_ref(),
                    t: f.t,
                    pose: registered.or(f.pose),
                })
                .map(|r| (r, registered))
        });
        let (r, registered) = outcome.map_err(core_error)?;
        Ok(Result {
            record: ResultRecord {
                t: f.t,
                pose: f.pose,
                registered_pose: registered,
                ..ResultRecord::of(f.stream.clone(), f.frame, &r)
            },
        })
    }

    /// Bytes of state the stream holds between frames, roughly.
    #[getter]
    fn state_bytes(&self) -> usize {
        self.inner.bytes()
    }
}

/// What a reader thread sends: a frame, or why one could not be read, or why the
/// file could not be read at all (the last message then).
enum Read {
    Item(Box<isoline_io::Item>),
    Failed(isoline_io::Error),
}

/// The messages of skipped frames a reader keeps (the rest it counts).
const MAX_SKIPPED_KEPT: usize = 100;

/// The frames of a recording (an MCAP bag, a CARMEN log), an NDJSON frame stream or a
/// point file, read ahead on a thread while Python takes them. With `errors="warn"`,
/// frames that cannot be read are skipped and counted (`skipped`, the first hundred
/// messages in `skipped_messages`), with one warning when the reader reaches the end.
#[pyclass(module = "isoline")]
struct FrameReader {
    rx: Mutex<Receiver<Read>>,
    errors: String,
    /// Frames skipped so far, and the first messages.
    skipped: Mutex<(u64, Vec<String>)>,
    /// Whether the end's warning was given.
    warned: std::sync::atomic::AtomicBool,
}

#[pymethods]
impl FrameReader {
    fn __iter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    fn __next__(&self, py: Python<'_>) -> PyResult<Frame> {
        loop {
            let next = py.detach(|| self.rx.lock().ok().and_then(|rx| rx.recv().ok()));
            match next {
                None => {
                    self.warn_once(py)?;
                    return Err(PyStopIteration::new_err(()));
                }
                Some(Read::Failed(e)) => {
                    self.warn_once(py)?;
                    return Err(io_error(e));
                }
                Some(Read::Item(item)) => match *item {
                    Ok(frame) => return Ok(Frame { inner: frame }),
                    Err(bad) => match self.errors.as_str() {
                        "raise" => return Err(IsolineError::new_err(bad.message)),
                        "warn" => {
                            if let Ok(mut s) = self.skipped.lock() {
                                s.0 += 1;
                                if s.1.len() < MAX_SKIPPED_KEPT {
                                    s.1.push(bad.message);
                                }
                            }
                        }
                        _ => {}
                    },
                },
            }
        }
    }

    /// Frames skipped as unreadable so far (with `errors="warn"`).
    #[getter]
    fn skipped(&self) -> u64 {
        self.skipped.lock().map_or(0, |s| s.0)
    }

    /// Why the first (at most 100) skipped frames could not be read.
    #[getter]
    fn skipped_messages(&self) -> Vec<String> {
        self.skipped.lock().map(|s| s.1.clone()).unwrap_or_default()
    }
}

impl FrameReader {
    /// One warning for the whole reader, with the count and the first message: Python
    /// keeps every distinct warning it is given, so one a bad line would grow without
    /// bound.
    fn warn_once(&self, py: Python<'_>) -> PyResult<()> {
        let (n, first) = match self.skipped.lock() {
            Ok(s) => (s.0, s.1.first().cloned().unwrap_or_default()),
            Err(_) => return Ok(()),
        };
        if n == 0 || self.warned.swap(true, std::sync::atomic::Ordering::Relaxed) {
            return Ok(());
        }
        let text = format!(
            "{n} frame(s) could not be read and were skipped (the reader's skipped_messages \
             says why); first: {first}"
        );
        let warning = py.get_type::<pyo3::exceptions::PyUserWarning>();
        PyErr::warn(
            py,
            &warning,
            &std::ffi::CString::new(text.replace('\0', " ")).unwrap_or_default(),
            1,
        )
    }
}

/// Reads the frames of `path`: an MCAP bag of `sensor_msgs/LaserScan` (`topics`, and
/// `odometry` or `world_frame` to give each scan a pose), a CARMEN log (`.log`, `.clf`,
/// gzip-compressed or not; poses from the log), an NDJSON frame stream or a point file.
/// Every format streams: a few dozen frames are read ahead, whatever the file's size.
/// A message that cannot be a frame is skipped and counted, with one warning at the end
/// (`errors="warn"`), raises `IsolineError` (`"raise"`), or is skipped silently
/// (`"ignore"`). An NDJSON line longer than `max_line_bytes` (default 16 MiB) is such a
/// message. Scanner frames with beam timing (a bag's `time_increment`, or
/// `time_increment` seconds between beams for those that give none), a time and a pose
/// are corrected for the sensor's motion during the sweep, as `isoline map` corrects
/// them.
#[pyfunction]
#[pyo3(signature = (path, *, topics = None, odometry = None, world_frame = None, errors = "warn", max_line_bytes = isoline_io::MAX_FRAME_LINE_BYTES, time_increment = None))]
#[allow(clippy::too_many_arguments)]
fn read_frames(
    path: PathBuf,
    topics: Option<Vec<String>>,
    odometry: Option<String>,
    world_frame: Option<String>,
    errors: &str,
    max_line_bytes: usize,
    time_increment: Option<f64>,
) -> PyResult<FrameReader> {
    if let Some(t) = time_increment.filter(|t| !(t.is_finite() && (0.0..=1.0).contains(t))) {
        return Err(PyValueError::new_err(format!(
            "time_increment = {t}: must be 0 to 1 second"
        )));
    }
    if !["warn", "raise", "ignore"].contains(&errors) {
        return Err(PyValueError::new_err(format!(
            "errors = {errors:?}: expected \"warn\", \"raise\" or \"ignore\""
        )));
    }
    if max_line_bytes == 0 {
        return Err(PyValueError::new_err(
            "max_line_bytes = 0: must be positive",
        ));
    }
    if !path.exists() {
        return Err(PyOSError::new_err(format!(
            "{}: No such file or directory",
            path.display()
        )));
    }
    let opts = isoline_io::bag::BagOptions {
        topics: topics.unwrap_or_default(),
        odometry,
        world_frame,
    };
    let (tx, rx) = sync_channel(READ_AHEAD);
    std::thread::Builder::new()
        .name("isoline-read".into())
        .spawn(move || {
            // The Python side dropping the reader ends the thread at its next frame.
            let mut deskew = isoline_io::Deskew::new(time_increment);
            let each = |mut item: isoline_io::Item| {
                if let Ok(f) = &mut item {
                    deskew.apply(f);
                }
                tx.send(Read::Item(Box::new(item))).is_ok()
            };
            let outcome = isoline_io::for_each_item_capped(&path, &opts, max_line_bytes, each);
            if let Err(e) = outcome {
                let _ = tx.send(Read::Failed(e));
            }
        })
        .map_err(|e| PyOSError::new_err(format!("cannot start a reader thread: {e}")))?;
    Ok(FrameReader {
        rx: Mutex::new(rx),
        errors: errors.to_string(),
        skipped: Mutex::new((0, Vec::new())),
        warned: std::sync::atomic::AtomicBool::new(false),
    })
}

/// The isoline module: level-set curve reconstruction from noisy 2D points and laser
/// scans.
#[pymodule]
fn _isoline(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("IsolineError", m.py().get_type::<IsolineError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_class::<Params>()?;
    m.add_class::<Frame>()?;
    m.add_class::<Result>()?;
    m.add_class::<Stream>()?;
    m.add_class::<FrameReader>()?;
    m.add_function(wrap_pyfunction!(reconstruct, m)?)?;
    m.add_function(wrap_pyfunction!(reconstruct_scan, m)?)?;
    m.add_function(wrap_pyfunction!(reconstruct_frame, m)?)?;
    m.add_function(wrap_pyfunction!(read_frames, m)?)?;
    Ok(())
}
