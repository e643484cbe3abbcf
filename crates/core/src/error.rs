//! The method's errors: one enum, with the variants a caller can fix (bad input data or
//! parameters) kept apart from internal invariant failures. Reading files has its own
//! errors, in isoline-io.

/// Errors returned by the isoline library.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// The point set is empty.
    #[error("the point set is empty")]
    EmptyPointSet,
    /// Every point is at the same place: there is no curve to find.
    #[error("all {count} points coincide: there is no curve to reconstruct")]
    CoincidentPoints {
        /// How many points there are.
        count: usize,
    },
    /// The points span less than the smallest supported extent.
    #[error("the points span {extent:e}, below the supported 1e-150")]
    TinyExtent {
        /// Their bounding-box diagonal.
        extent: f64,
    },
    /// A coordinate is NaN or infinite; `index` is the point's position in the input.
    #[error("point {index} has a non-finite coordinate ({x}, {y})")]
    NonFinitePoint {
        /// The point's position in the input, from 0.
        index: usize,
        /// Its x coordinate.
        x: f64,
        /// Its y coordinate.
        y: f64,
    },
    /// A coordinate is so large that squared distances would overflow.
    #[error(
        "point {index} has a coordinate of magnitude {magnitude:e}, above the supported 1e150"
    )]
    HugeCoordinate {
        /// The point's position in the input, from 0.
        index: usize,
        /// The largest coordinate magnitude.
        magnitude: f64,
    },
    /// A parameter is out of its allowed range.
    #[error("invalid parameter {name} = {value}: {reason}")]
    InvalidParameter {
        /// The parameter.
        name: &'static str,
        /// Its value.
        value: String,
        /// The allowed range.
        reason: String,
    },
    /// A scan frame's beams are malformed (no beams, a zero step, a bad range limit).
    #[error("invalid scan: {0}")]
    Scan(String),
    /// Parameters are invalid; every problem found is listed.
    #[error("invalid configuration {path}:\n  {}", problems.join("\n  "))]
    Config {
        /// What the parameters came from (a file, or "mesh parameters").
        path: String,
        /// Every problem found, each naming its key path.
        problems: Vec<String>,
    },
    /// An internal invariant failed: a bug in isoline, not in the input.
    #[error("internal error: {0}")]
    Internal(String),
}

/// `Result` with the library's [`Error`].
pub type Result<T> = std::result::Result<T, Error>;

/// Adds a problem to `problems` if `value` is set and is not a positive finite number;
/// `key` is its path in the configuration (`mesh.hmin`).
pub(crate) fn check_positive(problems: &mut Vec<String>, key: &str, value: Option<f64>) {
    if let Some(v) = value {
        if !(v.is_finite() && v > 0.0) {
            problems.push(format!("{key} = {v}: must be a positive finite number"));
        }
    }
}
