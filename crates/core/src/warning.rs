//! What is wrong with a result that has one. A warning is data (its kind and its
//! numbers); the text a record carries is its `Display`.

use std::fmt;

/// A problem with a [`crate::Reconstruction`] that is not an error: the frame has a
/// result, but a user should look at it.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[non_exhaustive]
pub enum Warning {
    /// No curve came out, although `supported` points (for a scan, the returns in runs)
    /// have support for one.
    NoCurve {
        /// The points with support.
        supported: usize,
    },
    /// Most of the data lie farther than `tolerance` from every curve.
    FewExplained {
        /// The share within `tolerance`, in `[0, 1]`.
        explained: f64,
        /// The accuracy bound `3 sigma + 2 hmin`, in data units.
        tolerance: f64,
    },
}

impl fmt::Display for Warning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Warning::NoCurve { supported } => write!(
                f,
                "no curve, although {supported} points have support (a curve through them \
                 was expected)"
            ),
            Warning::FewExplained {
                explained,
                tolerance,
            } => write!(
                f,
                "only {:.0}% of the points lie within {tolerance:.3} of a curve",
                100.0 * explained
            ),
        }
    }
}
