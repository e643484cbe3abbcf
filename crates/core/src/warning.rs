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
    /// Curve stretches farther than `reach` from every sample were cut: no data
    /// support them (the invariant `repair::invariants::supported` keeps).
    OffData {
        /// The length cut, in data units.
        length: f64,
        /// The support distance: the accuracy bound plus the neighbours' reach.
        reach: f64,
    },
    /// Curves crossed: a curve crossing itself was split into its loops, and curves
    /// crossing each other were split where they cross, meeting there at a junction
    /// (or, for a crossing that dropping a repeated point made, lost a segment).
    /// Curves are simple and meet only at shared ends
    /// (the invariant `repair::invariants::uncrossed` keeps).
    Crossings {
        /// The crossings undone.
        removed: usize,
    },
    /// The curves look collapsed: one junction holds most of the strokes' ends (a star
    /// of spokes across the drawing), or they are far shorter than the data's extent.
    Collapsed {
        /// Ends at the busiest junction, of all the open curves' ends.
        ends: (usize, usize),
        /// The curves' length against the data's extent (its bounding box's longer
        /// side).
        length: (f64, f64),
    },
    /// The points fill an area rather than sample a curve: at every scale up to a
    /// sixteenth of their extent, fewer than [`crate::AREA_SHARE`] of the noise
    /// measurement's windows see one, and fewer than that share of the samples' own
    /// windows (strokes hatched closer than the sampling resolves, scattered points).
    /// No curve is drawn; the points are features.
    Area {
        /// The share of the windows that see a curve, in `[0, 1]`.
        curve_share: f64,
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
            Warning::OffData { length, reach } => write!(
                f,
                "cut {length:.3} of curve lying farther than {reach:.3} from every sample"
            ),
            Warning::Crossings { removed } => {
                write!(f, "split curves at {removed} crossings")
            }
            Warning::Collapsed { ends, length } => write!(
                f,
                "the curves look collapsed: {} of {} ends meet at one junction, length {:.3} \
                 against the data's extent {:.3}",
                ends.0, ends.1, length.0, length.1
            ),
            Warning::Area { curve_share } => write!(
                f,
                "the points fill an area: {:.1}% of the windows they were measured in see a \
                 curve; no curve drawn, the points are features",
                100.0 * curve_share
            ),
        }
    }
}
