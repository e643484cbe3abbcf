//! Scores of a map that need no ground truth, by the vote an occupancy grid takes: a
//! point is hit by a scan whose beam returned within `hit_tolerance` of it and seen
//! through by one whose beam went past it; a return is static when its place was hit at
//! least as often as seen through (people and opened doors are not).

use isoline_core::geom::{dist, to_world, Point, Polyline, Pose};
use isoline_core::{Scan, SegmentIndex};

use super::Map;
use crate::error::Result;

/// Points kept for the scores, at most, each of returns and of scans' curves: a uniform
/// sample of the run (reservoir sampling), so the scores cost the same on any run.
const KEEP: usize = 200_000;

/// The map's scores ([`Map::finish`]).
#[derive(Clone, Debug, Default, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct MapScores {
    /// Returns scored (a uniform sample of the run's, placed by their scans' poses).
    pub returns_scored: usize,
    /// Share of the scored returns that are static.
    pub static_share: f64,
    /// Share of the static returns within `hit_tolerance` of the map.
    pub static_within: f64,
    /// The map's length, metres.
    pub length: f64,
    /// The map's polylines.
    pub pieces: usize,
    /// Share of the map's length seen through more often than hit.
    pub seen_through: f64,
    /// Length of every scan's curves placed by its pose, metres: what the map replaces.
    pub union_length: f64,
    /// Share of that length seen through more often than hit.
    pub union_seen_through: f64,
}

/// What the scans brought, for the scores at the end.
#[derive(Debug, Default)]
pub(crate) struct Tally {
    returns: Reservoir,
    curve_points: Reservoir,
    union_length: f64,
}

impl Tally {
    /// Notes scan `n`'s returns and its curves (world coordinates).
    pub fn scan(&mut self, scan: &Scan, pose: Pose, curves: &[Polyline], cell: f64, n: u64) {
        for p in scan.returns() {
            self.returns.offer(to_world(pose, p), n);
        }
        for c in curves {
            self.union_length += c.length();
            for (a, b) in c.segments() {
                let steps = (dist(a, b) / cell).ceil().max(1.0) as usize;
                for s in 0..steps {
                    let t = s as f64 / steps as f64;
                    self.curve_points
                        .offer([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])], n);
                }
            }
        }
    }
}

/// A uniform sample of at most [`KEEP`] points of a stream (Vitter's algorithm R, with
/// a fixed-seed generator so a run's scores repeat).
#[derive(Debug)]
struct Reservoir {
    points: Vec<Point>,
    seen: u64,
    state: u64,
}

impl Default for Reservoir {
    fn default() -> Self {
        Reservoir {
            points: Vec::new(),
            seen: 0,
            state: 0x9E37_79B9_7F4A_7C15,
        }
    }
}

impl Reservoir {
    fn offer(&mut self, p: Point, _scan: u64) {
        self.seen += 1;
        if self.points.len() < KEEP {
            self.points.push(p);
            return;
        }
        // xorshift64*: enough for choosing slots uniformly.
        self.state ^= self.state >> 12;
        self.state ^= self.state << 25;
        self.state ^= self.state >> 27;
        let r = self.state.wrapping_mul(0x2545_F491_4F6C_DD1D) % self.seen;
        if (r as usize) < KEEP {
            self.points[r as usize] = p;
        }
    }
}

/// The scores of `curves`, `map`'s final curves.
pub(crate) fn scores(map: &mut Map, curves: &[Polyline]) -> Result<MapScores> {
    let tol = map.params.hit_tolerance;
    let cell = map.params.cell;
    let returns = std::mem::take(&mut map.score.returns.points);
    let mut is_static = vec![false; returns.len()];
    map.visit_samples(&returns, |n, s| {
        is_static[n] = s.is_some_and(|s| s.hits >= s.through);
    })?;
    let index = SegmentIndex::new(curves);
    let statics: Vec<Point> = returns
        .iter()
        .zip(&is_static)
        .filter(|(_, s)| **s)
        .map(|(p, _)| *p)
        .collect();
    let within = if index.is_empty() {
        0
    } else {
        statics
            .iter()
            .filter(|&&p| index.distance(p) <= tol)
            .count()
    };
    let along = along(curves, cell);
    let through_share = |map: &mut Map, pts: &[Point]| -> Result<f64> {
        let mut through = 0usize;
        map.visit_samples(pts, |_, s| {
            through += usize::from(s.is_some_and(|s| s.through > s.hits));
        })?;
        Ok(share(through, pts.len()))
    };
    let seen_through = through_share(map, &along)?;
    let union_points = std::mem::take(&mut map.score.curve_points.points);
    let union_seen_through = through_share(map, &union_points)?;
    let length = curves.iter().map(Polyline::length).sum();
    let out = MapScores {
        returns_scored: returns.len(),
        static_share: share(statics.len(), returns.len()),
        static_within: share(within, statics.len()),
        length,
        pieces: curves.len(),
        seen_through,
        union_length: map.score.union_length,
        union_seen_through,
    };
    map.score.returns.points = returns;
    map.score.curve_points.points = union_points;
    Ok(out)
}

/// Points along `curves`, `cell` apart (at the middles of equal steps).
fn along(curves: &[Polyline], cell: f64) -> Vec<Point> {
    let mut out = Vec::new();
    for c in curves {
        for (a, b) in c.segments() {
            let steps = (dist(a, b) / cell).ceil().max(1.0) as usize;
            for s in 0..steps {
                let t = (s as f64 + 0.5) / steps as f64;
                out.push([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]);
            }
        }
    }
    out
}

/// What a drawing of the map shows beside its curves.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MapLayers {
    /// A uniform sample of the run's returns, placed by their scans' poses.
    pub returns: Vec<Point>,
    /// Points along the curves, a cell apart, that the scans saw through more often
    /// than they hit: where the map is wrong by the scans' own evidence.
    pub seen_through: Vec<Point>,
}

/// The layers of `curves` on `map`, at most `max_returns` of the returns.
pub(crate) fn layers(map: &mut Map, curves: &[Polyline], max_returns: usize) -> Result<MapLayers> {
    let kept = &map.score.returns.points;
    let every = kept.len().div_ceil(max_returns.max(1)).max(1);
    let returns: Vec<Point> = kept.iter().step_by(every).copied().collect();
    let along = along(curves, map.params.cell);
    let mut seen_through = Vec::new();
    map.visit_samples(&along, |n, s| {
        if s.is_some_and(|s| s.through > s.hits) {
            seen_through.push(along[n]);
        }
    })?;
    Ok(MapLayers {
        returns,
        seen_through,
    })
}

fn share(part: usize, whole: usize) -> f64 {
    if whole == 0 {
        0.0
    } else {
        part as f64 / whole as f64
    }
}
