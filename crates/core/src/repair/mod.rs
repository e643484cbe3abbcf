//! Repair of a point cloud's curves after the export stage: the zero isoline is right
//! where the level set captured the samples, and these passes mend it where the mesh
//! could not resolve the data (loops round too few samples, pinches across narrow
//! necks, sampling gaps, clean samples it passed by, corners) and add the open strokes
//! of a drawing that encloses nothing. [`mend`] runs them in order; each pass is its own
//! module, with its contract in its doc.

pub mod between;
pub mod corners;
pub mod gaps;
pub mod invariants;
pub mod pinches;
pub mod strokes;
pub mod through;

use crate::distance::DistanceField;
use crate::geom::{Placement, Point, Polyline};
use strokes::Junction;

/// Every number the repair passes decide by, with its reason: each is dimensionless (a
/// multiple of `hmin`, a count of samples, an angle in radians or a ratio), so one set
/// serves data of any size. The defaults are the values the project's tables and the
/// glyph corpus's development range were made with; docs/method.md lists them. Work
/// bounds (vertices per arc, pairs per frame) are not tolerances: they are constants of
/// their pass, each a bound on cost that no result of the tables reaches.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Deserialize),
    serde(default, deny_unknown_fields)
)]
#[non_exhaustive]
pub struct Tolerances {
    /// Samples lying on circles to within this many `hmin` are clean: the mending
    /// through and between samples runs on them. A quarter: noise of `sigma` leaves
    /// circle fits off by about `sigma`, and the export's mesh resolves `hmin`.
    pub clean_fit: f64,
    /// How far the passes on clean samples move a vertex, in `hmin`: the level set
    /// passes clean samples by up to the capture's tolerance (`2 hmin`) and kinks round
    /// them by up to twice that.
    pub max_move: f64,
    /// Arcs across gaps: the largest turn between the ends' tangents, radians (171
    /// degrees); beyond it a bend cannot be told from a fold.
    pub arc_max_turn: f64,
    /// Arcs across gaps: how far an arc may stray from its chord, in chords.
    pub arc_max_bulge: f64,
    /// Arcs across gaps: samples an end's tangent is fitted to, at least (a quadratic
    /// needs three, and two more make it a test).
    pub arc_min_fit: usize,
    /// The turn at which two sides' curves meet at a corner rather than round a smooth
    /// arc, radians (40 degrees).
    pub corner_min_turn: f64,
    /// How far a side's fitted curve is continued to a corner across a gap, in radians
    /// of its turn over the chord: a radian round its osculating circle.
    pub corner_max_side_turn: f64,
    /// Between clean samples: consecutive samples a circle goes through, one more than a
    /// circle needs so that lying on it is a test.
    pub between_run: usize,
    /// Between clean samples: the least turn at a corner between two runs' circles,
    /// radians (11 degrees); nested osculating circles of one smooth curve do not cross.
    pub between_min_turn: f64,
    /// Between clean samples: how far a run's circle is continued to a corner, radians
    /// of its turn over the samples' distance (twice the gaps' sides: five clean samples
    /// on one circle are the curve's own).
    pub between_max_side_turn: f64,
    /// Between clean samples: the largest slope of a run's circle against its chord
    /// (steeper, the run turns by over 127 degrees and is no stretch of one wall).
    pub between_max_slope: f64,
    /// Through clean samples: the samples looked at round a vertex (several sides'
    /// worth, where the sampling thins out on one side).
    pub through_nearest: usize,
    /// Through clean samples: the nearest samples whose principal axis is a vertex's
    /// tangent.
    pub through_frame: usize,
    /// Through clean samples: samples the circle goes through on either side of a
    /// vertex (interpolated, never extrapolated past the samples' end).
    pub through_each_side: usize,
    /// Through clean samples: the largest slope of the fitted curve in a vertex's frame.
    pub through_max_slope: f64,
    /// Pinches: how far a join may turn from an end's run, radians (45 degrees: more
    /// along its wall than across).
    pub pinch_max_turn: f64,
    /// Strokes: samples a line is fitted to when thinning, at most (the nearest within
    /// the stroke scale).
    pub stroke_fit: usize,
    /// Strokes: candidate tree edges per moved sample, at most.
    pub stroke_links: usize,
    /// Strokes: a join across a gap runs within this cosine of the line at each end (30
    /// degrees).
    pub stroke_along_cos: f64,
    /// Loops through empty space: a gap this many times the median of the gaps around
    /// it may be a bridge (a random sampling's longest gap is about `ln n` means).
    pub bridge_gaps: f64,
    /// Loops through empty space: samples off the loops past a bridge's end that show
    /// the sheet running on (three, so that one in the noise's tail is not one).
    pub bridge_left_behind: usize,
    /// Loops through empty space: gaps on either side a gap is compared with.
    pub bridge_context: usize,
    /// Loops joined by strokes: the loop's samples within this many tolerances of the
    /// samples beside it are thinned.
    pub joined_window: f64,
}

impl Default for Tolerances {
    fn default() -> Tolerances {
        Tolerances {
            clean_fit: 0.25,
            max_move: 4.0,
            arc_max_turn: 0.95 * std::f64::consts::PI,
            arc_max_bulge: 0.6,
            arc_min_fit: 5,
            corner_min_turn: 0.7,
            corner_max_side_turn: 1.0,
            between_run: 5,
            between_min_turn: 0.2,
            between_max_side_turn: 2.0,
            between_max_slope: 2.0,
            through_nearest: 24,
            through_frame: 4,
            through_each_side: 2,
            through_max_slope: 1.0,
            pinch_max_turn: std::f64::consts::FRAC_PI_4,
            stroke_fit: 64,
            stroke_links: 16,
            stroke_along_cos: 0.866,
            bridge_gaps: 20.0,
            bridge_left_behind: 3,
            bridge_context: 10,
            joined_window: 8.0,
        }
    }
}

impl Tolerances {
    /// Every problem with these tolerances, keyed by their path (`export.repair.*`):
    /// ratios and angles must be positive and finite, and every count at least what its
    /// fit needs (a circle through three samples and one to test it, a frame's axis from
    /// two, one sample on each side). Settings outside make a pass's fit undefined.
    pub fn validate(&self) -> std::result::Result<(), Vec<String>> {
        let mut problems = Vec::new();
        for (key, v) in [
            ("clean_fit", self.clean_fit),
            ("max_move", self.max_move),
            ("arc_max_turn", self.arc_max_turn),
            ("arc_max_bulge", self.arc_max_bulge),
            ("corner_min_turn", self.corner_min_turn),
            ("corner_max_side_turn", self.corner_max_side_turn),
            ("between_min_turn", self.between_min_turn),
            ("between_max_side_turn", self.between_max_side_turn),
            ("between_max_slope", self.between_max_slope),
            ("through_max_slope", self.through_max_slope),
            ("pinch_max_turn", self.pinch_max_turn),
            ("stroke_along_cos", self.stroke_along_cos),
            ("bridge_gaps", self.bridge_gaps),
            ("joined_window", self.joined_window),
        ] {
            crate::error::check_positive(&mut problems, &format!("export.repair.{key}"), Some(v));
        }
        for (key, v, least) in [
            ("arc_min_fit", self.arc_min_fit, 3),
            ("between_run", self.between_run, 4),
            ("through_frame", self.through_frame, 2),
            ("through_each_side", self.through_each_side, 1),
            (
                "through_nearest",
                self.through_nearest,
                2 * self.through_each_side + 1,
            ),
            ("stroke_fit", self.stroke_fit, 3),
            ("stroke_links", self.stroke_links, 1),
            ("bridge_left_behind", self.bridge_left_behind, 1),
            ("bridge_context", self.bridge_context, 1),
        ] {
            if v < least {
                problems.push(format!(
                    "export.repair.{key} = {v}: must be at least {least}"
                ));
            }
        }
        if self.stroke_along_cos > 1.0 {
            problems.push(format!(
                "export.repair.stroke_along_cos = {}: a cosine, at most 1",
                self.stroke_along_cos
            ));
        }
        if problems.is_empty() {
            Ok(())
        } else {
            Err(problems)
        }
    }
}

/// What [`mend`] needs of the frame besides its curves (lengths in the local units of
/// the frame's placement unless said otherwise).
#[derive(Clone, Copy, Debug)]
pub struct Frame<'a> {
    /// The samples, in local coordinates.
    pub field: &'a DistanceField,
    /// The samples, in data coordinates.
    pub data: &'a [Point],
    /// Where the data sit.
    pub at: Placement,
    /// The data's noise (median local-fit residual).
    pub sigma: f64,
    /// The noise the fits over one wall's window measure (clean samples of a bend
    /// read as clean by them where the neighbours' fits span the bend).
    pub one_wall_noise: f64,
    /// The mesh's smallest size.
    pub hmin: f64,
    /// Closed loops enclosing less area are holes the noise opened.
    pub min_area: f64,
    /// Whether the level set enclosed anything (a drawing of strokes does not).
    pub enclosed: bool,
    /// The accuracy bound `3 sigma + 2 hmin`, in data units.
    pub tolerance: f64,
    /// The passes' tolerances.
    pub tolerances: &'a Tolerances,
}

/// What the repair stage makes of a point cloud's curves.
#[derive(Clone, Debug, PartialEq)]
pub struct Repaired {
    /// The curves, in data coordinates.
    pub polylines: Vec<Polyline>,
    /// Where open strokes meet (indices into `polylines`).
    pub junctions: Vec<Junction>,
    /// What the invariants had to cut.
    pub warnings: Vec<crate::Warning>,
}

/// The repair stage of a point cloud, after the export stage's contour.
///
/// Takes the zero isoline's `curves` (data coordinates), the frame they came from and
/// what the invariants need of the cloud. Mends them ([`mend`]: the passes, each
/// deciding by `frame.tolerances`) and guarantees, whatever the passes made
/// ([`invariants::enforce`]):
/// - every vertex within the support distance of a sample that is not an outlier (the
///   accuracy bound plus the neighbours' reach);
/// - no two segments crossing: curves simple and disjoint but where pieces meet at a
///   junction's shared end;
/// - no zero-length segment, no closed curve of fewer than three vertices;
/// - junctions indexing the returned curves, each with two or more ends;
///
/// with a warning for each invariant that had to cut, and one when the result looks
/// collapsed.
pub fn repair(curves: Vec<Polyline>, frame: &Frame<'_>, cloud: &invariants::Cloud<'_>) -> Repaired {
    let (polylines, junctions) = mend(curves, frame);
    let (polylines, junctions, warnings) = invariants::enforce(polylines, junctions, cloud);
    Repaired {
        polylines,
        junctions,
        warnings,
    }
}

/// Mends a point cloud's `curves` (data coordinates) and adds its open strokes: loops
/// round fewer than three samples go; two loops pinched across one neck where both
/// walls have a gap become one ([`pinches`]); arcs span the sampling gaps a loop passed
/// by ([`gaps`]); on clean samples, loops are moved onto them ([`through`]) and drawn
/// between them round corners ([`between`]); holes the arcs shrank go; and the samples
/// no loop explains become strokes with their junctions ([`strokes`]). Loops the passes
/// leave alone keep their coordinates to the bit.
pub fn mend(curves: Vec<Polyline>, frame: &Frame<'_>) -> (Vec<Polyline>, Vec<Junction>) {
    let Frame {
        field,
        at,
        sigma,
        hmin,
        tolerances: t,
        ..
    } = *frame;
    // Across sampling gaps first: a loop that passed a sparse wall by would otherwise
    // look like strokes joined through empty space. In local coordinates, where the
    // samples' tree is; only the loops changed come back.
    let local: Vec<Polyline> = curves
        .iter()
        .map(|pl| Polyline {
            closed: pl.closed,
            points: pl.points.iter().map(|&p| at.to_local(p)).collect(),
        })
        .collect();
    // Noisy samples lie on no circle to a quarter of hmin; clean ones do, by the fits
    // over one wall's window too: the k neighbours' fits span a small bay's bend (and
    // measure it as noise) where it is about their reach across. (Clean random
    // samplings of curved shapes estimate a few 1e-5 of the diagonal: the fits' own
    // error.) Where only the one-wall fits say clean, the neighbours' estimate is the
    // bend's, not noise, and the mending below holds the curve to the one wall's
    // residual: with the estimate, a loop that cuts an inlet's sharp corner by twice the
    // spacing counts as held there.
    let fit_tol = t.clean_fit * hmin;
    let clean = sigma.min(frame.one_wall_noise) <= fit_tol;
    let mend_sigma = if sigma > fit_tol && clean {
        frame.one_wall_noise
    } else {
        sigma
    };
    let mend_tol = 3.0 * mend_sigma + 2.0 * hmin;
    // Loops round fewer than three samples go first (holes the noise opened in a band's
    // interior, which hold none, among them): they hold those samples off the arcs
    // below.
    let (mut curves, mut local): (Vec<Polyline>, Vec<Polyline>) = curves
        .into_iter()
        .zip(local)
        .filter(|(_, pl)| !holds_no_curve(pl, field, mend_tol))
        .unzip();
    // Pinches before that: two loops each crossing one neck where both walls have a gap
    // become one, whose joins along the walls are arcs to span.
    let mut joined = vec![false; curves.len()];
    for (kept, removed) in
        pinches::join_pinches(&mut local, field, mend_sigma, clean, mend_tol, hmin, t)
    {
        joined[kept] = true;
        joined.remove(removed);
        curves.remove(removed);
    }
    tracing::debug!(
        loops = joined.iter().filter(|&&j| j).count(),
        "loops joined across pinches"
    );
    let mut changed = gaps::span_gaps(&mut local, field, mend_sigma, mend_tol, hmin, t);
    tracing::debug!(loops = changed.len(), "sampling gaps spanned by arcs");
    // Then onto clean samples, which the level set passes by up to the capture's
    // tolerance (the arcs go through those they skipped, not onto the others), and round
    // which it kinks by up to twice that: moves of 4 hmin at most.
    changed.extend((0..joined.len()).filter(|&k| joined[k]));
    if clean {
        let onto = through::through_samples(&mut local, field, t.max_move * hmin, fit_tol, t);
        tracing::debug!(loops = onto.len(), "loops moved onto clean samples");
        changed.extend(onto);
        // Then between them: the vertices round a corner, whose nearest samples span
        // both walls, are not moved above.
        let pieces =
            between::between_samples(&mut local, field, t.max_move * hmin, fit_tol, hmin, t);
        tracing::debug!(loops = pieces.len(), "loops drawn between clean samples");
        changed.extend(pieces);
    }
    changed.sort_unstable();
    changed.dedup();
    for &k in &changed {
        curves[k].points = local[k].points.iter().map(|&p| at.to_data(p)).collect();
    }
    // Holes the noise opened in a band's interior that the arcs shrank go.
    let mut k = 0;
    curves.retain(|_| {
        let shrunk = changed.binary_search(&k).is_ok() && is_shrunk_hole(&local[k], frame.min_area);
        k += 1;
        !shrunk
    });
    strokes::with_strokes(
        curves,
        frame.data,
        frame.enclosed,
        at.len_to_data(sigma),
        at.len_to_data(hmin),
        frame.tolerance,
        t,
    )
}

/// Whether the closed loop `pl` holds fewer than three samples of `field` (within `tol`
/// of a vertex): two samples show a segment, not a curve round anything. The level set
/// leaves such a loop round a few samples of a wall it passed by, and in the way of the
/// arc that spans the wall's gap ([`gaps::span_gaps`]) through them. Open polylines
/// are none.
pub fn holds_no_curve(pl: &Polyline, field: &DistanceField, tol: f64) -> bool {
    if !pl.closed {
        return false;
    }
    let (mut held, mut near) = (Vec::<u32>::new(), Vec::new());
    for &p in &pl.points {
        field.within(p, tol, &mut near);
        for &j in &near {
            if !held.contains(&j) {
                held.push(j);
                if held.len() >= 3 {
                    return false;
                }
            }
        }
    }
    true
}

/// Whether the closed loop `pl`, which the mending changed, is a hole that the noise
/// opened in a noisy band's interior: it encloses less than `min_area` (its whole run
/// lay off the samples round it, and one short arc spanned it). Open polylines are
/// none. (A hole that holds no sample at all goes before the mending, by
/// [`holds_no_curve`].)
pub fn is_shrunk_hole(pl: &Polyline, min_area: f64) -> bool {
    pl.closed && pl.signed_area().abs() < min_area
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ring(c: Point, r: f64, n: usize) -> Vec<Point> {
        (0..n)
            .map(|i| {
                let a = std::f64::consts::TAU * i as f64 / n as f64;
                [c[0] + r * a.cos(), c[1] + r * a.sin()]
            })
            .collect()
    }

    /// The defaults are valid; a count below what its fit needs and a non-finite ratio
    /// are each named.
    #[test]
    fn tolerances_outside_their_range_are_named() {
        assert_eq!(Tolerances::default().validate(), Ok(()));
        let t = Tolerances {
            through_frame: 0,
            clean_fit: f64::NAN,
            ..Default::default()
        };
        let problems = t.validate().unwrap_err();
        assert_eq!(problems.len(), 2, "{problems:?}");
        assert!(problems
            .iter()
            .any(|p| p.contains("export.repair.through_frame = 0")));
        assert!(problems
            .iter()
            .any(|p| p.contains("export.repair.clean_fit = NaN")));
    }

    /// A loop of radius 0.008 whose side lies on two samples of a wall 0.006 apart (as
    /// the level set leaves one beside a wall it passed by) holds no curve; the same
    /// loop through three samples does, and an open polyline is never dropped.
    #[test]
    fn a_loop_round_two_samples_holds_no_curve() {
        let loop_ = Polyline {
            closed: true,
            points: ring([0.008, 0.0], 0.008, 64),
        };
        let two = DistanceField::new(&[[0.0, -0.003], [0.0, 0.003]]).unwrap();
        let tol = 0.0023;
        assert!(holds_no_curve(&loop_, &two, tol));
        let three = DistanceField::new(&[[0.0, -0.003], [0.0, 0.003], [0.016, 0.0]]).unwrap();
        assert!(!holds_no_curve(&loop_, &three, tol));
        let open = Polyline {
            closed: false,
            ..loop_
        };
        assert!(!holds_no_curve(&open, &two, tol));
    }
}
