//! A map of a whole run: scans placed by their poses and fused, as they come, into one
//! world-frame level set whose zero crossing is the map's curves.
//!
//! The world is a lattice of samples `cell` apart, cut into square tiles of `tile`
//! samples a side that exist only where some beam went. Each scan brings two kinds of
//! evidence (docs/method.md, "A map of the whole run"):
//!
//! - its curves (the scan's own reconstruction, placed by its pose): every sample within
//!   the truncation `3 sigma + 2 cell` of them takes their signed distance (positive on
//!   the free side, the curves' left) into a running average capped at `max_weight`
//!   scans (the truncated signed distance fusion of Curless & Levoy 1996, the cap
//!   KinectFusion's, so that the field follows a changed scene);
//! - its beams: every sample a beam's square crosses is *seen through* if it lies more
//!   than `hit_tolerance` before the beam's return, *hit* if within it. The votes update
//!   a clamped occupancy log-odds (OctoMap's rule, Hornung et al. 2013: +0.85 a hit,
//!   -0.4 a miss, within [-2, 3.5]): a wall seen a hundred times leaves the map after
//!   about nine scans see through it, and a person who walked by after one or two.
//!
//! A stretch of the zero crossing is in the map where `min_scans` scans' curves support
//! it and its occupancy is not negative (not seen through more than hit). Tiles least
//! recently seen leave memory for a [`TileStore`] beyond `max_tiles`, so memory is
//! bounded whatever the run's length and area; their first row and column stay, and the
//! curves they held, so the live map and the borders with their neighbours go on.

mod extract;
mod score;
mod tile;

use std::collections::HashMap;

use isoline_core::geom::{dist, to_world, Point, Polyline, Pose};
use isoline_core::Scan;
use rustc_hash::FxHashMap;

use crate::error::{Error, Result};

pub use score::{MapLayers, MapScores};
use tile::{locate, Border, Sample, Tile};

/// A tile's position in the lattice of tiles.
pub type Key = (i64, i64);

/// Where tiles go when they leave memory and come back from. The core library does no
/// I/O: `isoline-io` keeps them in files; [`MemoryStore`] keeps them in memory.
pub trait TileStore: Send + Sync {
    /// Keeps `bytes` as the tile at `key`, replacing any.
    fn put(&mut self, key: Key, bytes: Vec<u8>) -> std::result::Result<(), String>;
    /// Gives back (and forgets) the tile at `key`, if kept.
    fn take(&mut self, key: Key) -> std::result::Result<Option<Vec<u8>>, String>;
}

/// A [`TileStore`] in memory: the tiles leave the map's bound, not the process's.
#[derive(Debug, Default)]
pub struct MemoryStore {
    tiles: HashMap<Key, Vec<u8>>,
}

impl TileStore for MemoryStore {
    fn put(&mut self, key: Key, bytes: Vec<u8>) -> std::result::Result<(), String> {
        self.tiles.insert(key, bytes);
        Ok(())
    }
    fn take(&mut self, key: Key) -> std::result::Result<Option<Vec<u8>>, String> {
        Ok(self.tiles.remove(&key))
    }
}

/// What a map fuses and keeps.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(default, deny_unknown_fields))]
pub struct MapParams {
    /// Spacing of the lattice's samples, metres.
    pub cell: f64,
    /// Samples along a tile's side.
    pub tile: usize,
    /// Scans whose curves must support a stretch before it enters the map.
    pub min_scans: u16,
    /// The running average's cap, in scans: the field follows a changed scene after
    /// about this many scans.
    pub max_weight: u16,
    /// A beam whose return lies within this of a sample hit it; one that ended farther
    /// went past it, metres (at least `3 sigma + cell` of the scan's range noise); the
    /// scores' distance too.
    pub hit_tolerance: f64,
    /// Beams count up to this range (returns beyond it are left out), metres: it bounds
    /// the tiles one scan touches.
    pub max_range: f64,
    /// Tiles held in memory at most; the least recently seen go to the store.
    pub max_tiles: usize,
    /// Tiles kept in the store at most (each [`MapParams::tile_bytes`] on disk): beyond
    /// it the least recently seen stored tile is forgotten, its part of the map with it
    /// (counted in [`MapStats::tiles_dropped`]). Scans whose poses jump (a reset, robots
    /// not localised together) would otherwise grow the store without end.
    pub max_stored_tiles: usize,
    /// Lay each scan onto the map before fusing it (its pose corrected by at most
    /// `8 hit_tolerance` and 0.1 rad); off (the default), scans go where their poses put
    /// them. Scan-to-map alignment drifts as odometry does where the map ahead is
    /// new (docs/method.md): use it for poses worse than the drift.
    pub align: bool,
    /// Standard deviation of the poses' heading error, radians: a wall a scan's curve
    /// puts at range `r` is off by about `r` times it across, so the scan's signed
    /// distance there counts with weight `s^2 / (s^2 + (r heading_noise)^2)` (`s` its
    /// range noise). 0 weighs every scan alike.
    pub heading_noise: f64,
}

impl Default for MapParams {
    fn default() -> Self {
        MapParams {
            cell: 0.03,
            tile: 128,
            min_scans: 2,
            max_weight: 64,
            hit_tolerance: 0.05,
            max_range: 20.0,
            max_tiles: 512,
            // 2 GiB of 128-sample tiles: 120,000 m^2 at 3 cm, a campus.
            max_stored_tiles: 8192,
            align: false,
            // SLAM-corrected poses are off by about this much in the median frame
            // (docs/method.md, refinement); half of it gives the same maps within a
            // point of static returns.
            heading_noise: 0.5_f64.to_radians(),
        }
    }
}

impl MapParams {
    /// Every problem with the parameters, each naming its key (`map.cell`).
    pub fn validate(&self) -> std::result::Result<(), Vec<String>> {
        let mut problems = Vec::new();
        let positive = |p: &mut Vec<String>, k: &str, v: f64| {
            if !(v.is_finite() && v > 0.0) {
                p.push(format!("map.{k} = {v}: must be a positive finite number"));
            }
        };
        positive(&mut problems, "cell", self.cell);
        positive(&mut problems, "hit_tolerance", self.hit_tolerance);
        if self.hit_tolerance.is_finite()
            && self.cell.is_finite()
            && self.hit_tolerance > self.max_tolerance()
        {
            problems.push(format!(
                "map.hit_tolerance = {}: at most {} m (a quarter of a tile's side, at least \
                 ten cells): a beam's hit band must stay within the tiles a scan may touch",
                self.hit_tolerance,
                self.max_tolerance()
            ));
        }
        positive(&mut problems, "max_range", self.max_range);
        if !(self.heading_noise.is_finite() && (0.0..=0.5).contains(&self.heading_noise)) {
            problems.push(format!(
                "map.heading_noise = {}: must be 0 to 0.5 radians",
                self.heading_noise
            ));
        }
        if !(4..=1024).contains(&self.tile) {
            problems.push(format!("map.tile = {}: must be 4 to 1024", self.tile));
        }
        if self.min_scans == 0 || self.max_weight < self.min_scans {
            problems.push(format!(
                "map.min_scans = {}, map.max_weight = {}: need 1 <= min_scans <= max_weight",
                self.min_scans, self.max_weight
            ));
        }
        // One scan must fit: its beams reach `max_range` around the sensor.
        if self.cell.is_finite() && self.cell > 0.0 && self.max_range.is_finite() {
            let need = self.tiles_per_scan();
            if self.max_tiles < need {
                problems.push(format!(
                    "map.max_tiles = {}: one scan reaching {} m touches up to {need} tiles",
                    self.max_tiles, self.max_range
                ));
            }
        }
        if self.max_range / self.cell > 1e6 {
            problems.push("map.max_range / map.cell: above a million samples".into());
        }
        if problems.is_empty() {
            Ok(())
        } else {
            Err(problems)
        }
    }

    /// The most tiles one scan touches: a disc of radius `max_range` plus the widest
    /// band a beam's hit or a curve's truncation reaches past its return
    /// ([`MapParams::max_tolerance`] and a cell).
    fn tiles_per_scan(&self) -> usize {
        let side = self.cell * self.tile as f64;
        let reach = self.max_range + self.max_tolerance() + self.cell;
        let across = (2.0 * reach / side).ceil() as usize + 1;
        across * across
    }

    /// The widest band round a return the votes and the curves' signed distances reach,
    /// metres: a quarter of a tile's side, and at least ten cells (a range noise of a
    /// little over two cells fits whatever the tiles). `hit_tolerance` is validated
    /// against it, and a scan's range noise is taken at most as wide (`3 sigma + 2 cell`
    /// within it); [`MapParams::validate`] counts it in the tiles one scan touches.
    pub fn max_tolerance(&self) -> f64 {
        (0.25 * self.tile as f64).max(10.0) * self.cell
    }

    /// The farthest a pose may put a scan's sensor from the world's origin, metres: the
    /// lattice's indices stay within 2^31 cells (64,000 km at 3 cm, more than the
    /// Earth's circumference), so that every sample's place is exact to far below a
    /// cell in floating point. Scans placed farther are refused.
    pub fn max_coordinate(&self) -> f64 {
        self.cell * f64::from(1u32 << 31) - self.max_range - self.cell * self.tile as f64
    }

    /// Bytes one tile holds, in memory or in the store.
    pub fn tile_bytes(&self) -> usize {
        Tile::bytes(self.tile)
    }

    /// Bytes the tiles in memory hold at most.
    pub fn memory_bound(&self) -> usize {
        self.max_tiles * Tile::bytes(self.tile)
    }
}

/// What a map holds and did, for its summary.
#[derive(Clone, Debug, Default, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct MapStats {
    /// Scans fused.
    pub scans: u64,
    /// Tiles in memory.
    pub tiles_resident: usize,
    /// Tiles in the store.
    pub tiles_stored: usize,
    /// Times a tile left memory.
    pub spills: u64,
    /// Bytes the tiles in memory hold.
    pub bytes: usize,
    /// Stored tiles forgotten beyond `max_stored_tiles`.
    pub tiles_dropped: u64,
    /// Scans refused because their pose put them beyond
    /// [`MapParams::max_coordinate`].
    pub scans_refused: u64,
}

/// A map that scans with poses are fused into ([`Map::insert`]) and whose curves can
/// be drawn at any time ([`Map::curves`]).
///
/// ```
/// use isoline_core::{reconstruct_scan, LaserScan, Params, Scan};
/// use isoline_map::{Map, MapParams, MemoryStore};
/// // A wall 2 m ahead of a sensor that drives along it, scanned five times.
/// let step = 0.5f64.to_radians();
/// let ranges: Vec<Option<f64>> = (0..181)
///     .map(|i| Some(2.0 / (-0.785 + i as f64 * step).cos()).filter(|r| *r < 4.0))
///     .collect();
/// let scan = Scan::from_laser(&LaserScan {
///     origin: [0.0, 0.0], angle_min: -0.785, angle_increment: step,
///     ranges: &ranges, range_min: 0.1, range_max: 10.0,
/// })
/// .unwrap();
/// let curves = reconstruct_scan(&scan, &Params::default()).unwrap().polylines;
/// let mut map = Map::new(MapParams::default(), Box::new(MemoryStore::default())).unwrap();
/// for k in 0..5 {
///     map.insert(&scan, [0.0, 0.1 * k as f64, 0.0], &curves, 0.002).unwrap();
/// }
/// let walls = map.curves().unwrap();
/// assert_eq!(walls.len(), 1);
/// // Within 5 cm of the wall; where the support ends the crossing may hook by a cell.
/// assert!(walls[0].points.iter().all(|p| (p[0] - 2.0).abs() < 0.05), "{walls:?}");
/// ```
pub struct Map {
    params: MapParams,
    tiles: FxHashMap<Key, Tile>,
    /// Tiles in the store: their first row and column, the curve pieces they held, and
    /// the last scan that touched them.
    stored: FxHashMap<Key, (Border, Vec<extract::Piece>, u64)>,
    store: Box<dyn TileStore>,
    scans: u64,
    spills: u64,
    dropped: u64,
    refused: u64,
    /// The scan being fused: its signed distances, nearest first (reused).
    scratch: FxHashMap<(i64, i64), (f32, f32)>,
    /// The same, by tile (reused).
    cells: Vec<(Key, usize, f32, f32)>,
    score: score::Tally,
}

impl std::fmt::Debug for Map {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Map")
            .field("params", &self.params)
            .field("stats", &self.stats())
            .finish()
    }
}

/// Occupancy log-odds of a hit, a miss, and the clamp (OctoMap's defaults).
const HIT: f32 = 0.85;
const MISS: f32 = -0.4;
const OCC_MIN: f32 = -2.0;
const OCC_MAX: f32 = 3.5;

impl Map {
    /// An empty map, or the problems with `params`.
    pub fn new(params: MapParams, store: Box<dyn TileStore>) -> Result<Map> {
        params.validate().map_err(|problems| Error::Config {
            path: "map parameters".into(),
            problems,
        })?;
        Ok(Map {
            params,
            tiles: FxHashMap::default(),
            stored: FxHashMap::default(),
            store,
            scans: 0,
            spills: 0,
            dropped: 0,
            refused: 0,
            scratch: FxHashMap::default(),
            cells: Vec::new(),
            score: score::Tally::default(),
        })
    }

    /// The parameters.
    pub fn params(&self) -> &MapParams {
        &self.params
    }

    /// What the map holds.
    pub fn stats(&self) -> MapStats {
        MapStats {
            scans: self.scans,
            tiles_resident: self.tiles.len(),
            tiles_stored: self.stored.len(),
            spills: self.spills,
            bytes: self.tiles.len() * Tile::bytes(self.params.tile),
            tiles_dropped: self.dropped,
            scans_refused: self.refused,
        }
    }

    /// Fuses one scan: `scan` and `curves` in the scan's frame, `pose` the frame's place
    /// in the world, `noise` the range noise's standard deviation (metres, the scan's
    /// estimate). Returns the pose the scan was fused at (`pose`, or as the alignment
    /// corrected it). Fails when the store fails, and with [`Error::PoseOutOfReach`] for
    /// a pose that puts the sensor beyond [`MapParams::max_coordinate`]: that scan is
    /// left out (counted in [`MapStats::scans_refused`]) and the map goes on.
    pub fn insert(
        &mut self,
        scan: &Scan,
        pose: Pose,
        curves: &[Polyline],
        noise: f64,
    ) -> Result<Pose> {
        let given = pose;
        let limit = self.params.max_coordinate();
        let at = to_world(pose, scan.origin);
        if !(at[0].abs() <= limit && at[1].abs() <= limit && pose[2].is_finite()) {
            self.refused += 1;
            return Err(Error::PoseOutOfReach { pose, limit });
        }
        let pose = if self.params.align && self.scans > 0 {
            self.load_under(scan, pose)?;
            self.align(scan, pose, noise)
        } else {
            pose
        };
        let id = self.scans as u32;
        self.scans += 1;
        let origin = to_world(pose, scan.origin);
        let _span = tracing::debug_span!("map_insert", scan = self.scans - 1).entered();
        // The widest band the votes and the signed distances may reach bounds the
        // tiles a scan touches (MapParams::max_tolerance): a wider noise is taken as
        // that wide.
        let widest = (self.params.max_tolerance() - 2.0 * self.params.cell) / 3.0;
        let noise = if noise.is_finite() && noise > 0.0 {
            noise.min(widest.max(0.0))
        } else {
            0.0
        };
        // The vote cannot tell a return from a point nearer than the range noise (and
        // the lattice's spacing) allows: three standard deviations and a cell.
        let tol = self
            .params
            .hit_tolerance
            .max(3.0 * noise + self.params.cell);
        self.vote(scan, pose, origin, id, tol)?;
        let world: Vec<Polyline> = curves
            .iter()
            .map(|c| Polyline {
                closed: c.closed,
                points: c.points.iter().map(|&p| to_world(pose, p)).collect(),
            })
            .collect();
        // Only what the beams counted: a curve past `max_range` (a scanner's "no return"
        // reported as its largest range draws an arc there) is no wall the votes saw,
        // and would reach tiles beyond the ones a scan may touch.
        let reach = within(&world, origin, self.params.max_range);
        self.fuse_curves(&reach, 3.0 * noise + 2.0 * self.params.cell, origin, noise)?;
        // The scores judge the map by the returns where the scan's own pose puts them,
        // whatever the alignment made of it (a map true only to itself scores badly).
        let placed = if given == pose {
            world
        } else {
            curves
                .iter()
                .map(|c| Polyline {
                    closed: c.closed,
                    points: c.points.iter().map(|&p| to_world(given, p)).collect(),
                })
                .collect()
        };
        self.score
            .scan(scan, given, &placed, self.params.cell, self.scans);
        self.evict()?;
        Ok(pose)
    }

    /// Brings into memory the tiles under the scan's returns (placed by `pose`) that the
    /// store holds, so that the alignment sees the map whatever has been spilled: the
    /// votes load them anyway, and a map must not depend on its memory bound.
    fn load_under(&mut self, scan: &Scan, pose: Pose) -> Result<()> {
        let (cell, side) = (self.params.cell, self.params.tile);
        let origin = to_world(pose, scan.origin);
        // The four samples round each return, as the field's bilinear lookup takes them.
        let mut keys: Vec<Key> = scan
            .returns()
            .into_iter()
            .map(|p| to_world(pose, p))
            .filter(|&p| dist(p, origin) <= self.params.max_range)
            .flat_map(|p| {
                let (i, j) = ((p[0] / cell).floor() as i64, (p[1] / cell).floor() as i64);
                [(0, 0), (1, 0), (0, 1), (1, 1)].map(|(di, dj)| locate(i + di, j + dj, side).0)
            })
            .filter(|k| self.stored.contains_key(k))
            .collect();
        keys.sort_unstable();
        keys.dedup();
        for k in keys {
            self.load(k)?;
        }
        Ok(())
    }

    /// The fused signed distance and its gradient at `q` (bilinear in the lattice), where
    /// the four samples round it are in memory and supported by `min_scans` scans.
    fn field_at(&self, q: Point) -> Option<(f64, Point)> {
        let (cell, side, min) = (self.params.cell, self.params.tile, self.params.min_scans);
        let (x, y) = (q[0] / cell, q[1] / cell);
        let (i, j) = (x.floor() as i64, y.floor() as i64);
        let (fx, fy) = (x - i as f64, y - j as f64);
        let mut v = [0.0f64; 4];
        for (n, (di, dj)) in [(0, 0), (1, 0), (0, 1), (1, 1)].into_iter().enumerate() {
            let (key, k) = locate(i + di, j + dj, side);
            let t = self.tiles.get(&key)?;
            if t.weight[k] < min {
                return None;
            }
            v[n] = f64::from(t.sdf[k]);
        }
        let value = v[0] * (1.0 - fx) * (1.0 - fy)
            + v[1] * fx * (1.0 - fy)
            + v[2] * (1.0 - fx) * fy
            + v[3] * fx * fy;
        let gx = ((v[1] - v[0]) * (1.0 - fy) + (v[3] - v[2]) * fy) / cell;
        let gy = ((v[2] - v[0]) * (1.0 - fx) + (v[3] - v[1]) * fx) / cell;
        Some((value, [gx, gy]))
    }

    /// The pose that lays the scan's returns on the map's zero level: Gauss-Newton on
    /// the fused signed distance at the returns (signed-distance tracking, as Bylow et
    /// al. 2013 register depth images to a fused field), residuals weighted by Tukey's
    /// biweight with a cutoff of three noise widths of the field and the return; `pose`
    /// itself when too few returns fall where the map is, or the correction reaches
    /// past the gate.
    fn align(&self, scan: &Scan, pose: Pose, noise: f64) -> Pose {
        use nalgebra::{Matrix3, Vector3};
        const STEPS: usize = 10;
        let origin = to_world(pose, scan.origin);
        let world: Vec<Point> = scan
            .returns()
            .into_iter()
            .map(|p| to_world(pose, p))
            .filter(|&p| dist(p, origin) <= self.params.max_range)
            .collect();
        if world.len() < 20 {
            return pose;
        }
        let n = world.len() as f64;
        let c = world
            .iter()
            .fold([0.0, 0.0], |a, p| [a[0] + p[0] / n, a[1] + p[1] / n]);
        let gate = 8.0 * self.params.hit_tolerance;
        let cutoff = 3.0 * std::f64::consts::SQRT_2 * noise.max(self.params.cell / 3.0);
        let (mut t, mut theta) = ([0.0f64, 0.0f64], 0.0f64);
        for _ in 0..STEPS {
            let (s, co) = theta.sin_cos();
            let (mut a, mut b) = (Matrix3::<f64>::zeros(), Vector3::<f64>::zeros());
            let mut used = 0usize;
            for &w in &world {
                let d = [w[0] - c[0], w[1] - c[1]];
                let r = [co * d[0] - s * d[1], s * d[0] + co * d[1]];
                let q = [c[0] + r[0] + t[0], c[1] + r[1] + t[1]];
                let Some((v, g)) = self.field_at(q) else {
                    continue;
                };
                if v.abs() >= cutoff {
                    continue;
                }
                let u = 1.0 - (v / cutoff).powi(2);
                let wt = u * u;
                let j = Vector3::new(g[0], g[1], g[0] * -r[1] + g[1] * r[0]);
                a += wt * j * j.transpose();
                b -= wt * v * j;
                used += 1;
            }
            if used < 20 {
                return pose;
            }
            // A direction the returns do not constrain (a straight corridor) stays put.
            a += Matrix3::identity() * (1e-6 * a.trace().max(1e-12));
            let Some(step) = a.try_inverse().map(|inv| inv * b) else {
                return pose;
            };
            t = [t[0] + step[0], t[1] + step[1]];
            theta += step[2];
            if step.norm() < 1e-6 {
                break;
            }
        }
        if t[0].hypot(t[1]) > gate || theta.abs() > 0.1 || !(t[0].is_finite() && theta.is_finite())
        {
            return pose;
        }
        let (s, co) = theta.sin_cos();
        let d = [pose[0] - c[0], pose[1] - c[1]];
        [
            c[0] + co * d[0] - s * d[1] + t[0],
            c[1] + s * d[0] + co * d[1] + t[1],
            pose[2] + theta,
        ]
    }

    /// The beams' votes: the samples each beam's square crosses before its return are
    /// seen through, those within `tol` of the return hit; a sample votes once a scan,
    /// a hit first.
    fn vote(&mut self, scan: &Scan, pose: Pose, origin: Point, id: u32, tol: f64) -> Result<()> {
        let (cell, cap) = (self.params.cell, self.params.max_weight);
        let reach = self.params.max_range.min(scan.range_max);
        let incidence = incidence_cosines(scan);
        let beams: Vec<(Point, f64, f64)> = scan
            .angles
            .iter()
            .zip(&scan.ranges)
            .zip(&incidence)
            .filter_map(|((&a, &r), &cos)| {
                let (s, c) = (a + pose[2]).sin_cos();
                // A beam without a return votes nothing: scanners report none both for
                // nothing in range and for errors (dark or shiny surfaces, the
                // URG-04LX's error codes), and a wall swept by an error is still there.
                // One whose return lies beyond `max_range` went past everything nearer.
                let r = if r.is_finite() && r <= reach {
                    r
                } else if r.is_finite() {
                    f64::INFINITY
                } else {
                    return None;
                };
                Some(([c, s], r, cos))
            })
            .collect();
        // Hits first: a sample a beam returned at and another passed is hit.
        for &(dir, r, _) in &beams {
            if r.is_finite() {
                self.walk(
                    origin,
                    dir,
                    (r - tol - cell).max(0.0),
                    r + tol + cell,
                    |t, k, along| {
                        if (along - r).abs() <= tol && t.stamp[k] != id {
                            t.stamp[k] = id;
                            t.occ[k] = (t.occ[k] + HIT).min(OCC_MAX);
                            t.hits[k] = t.hits[k].saturating_add(1);
                            forget(t, k, cap);
                        }
                    },
                )?;
            }
        }
        for &(dir, r, cos) in &beams {
            // A beam that meets its surface at incidence phi passes a point at range d
            // (r - d) cos phi in front of it: the point is seen through once that
            // clears the tolerance, not once r - d does (at grazing incidence a beam
            // runs along the wall it ends on).
            let end = if r.is_finite() {
                r - tol / cos.max(0.05)
            } else {
                reach
            };
            self.walk(origin, dir, 0.0, end, |t, k, along| {
                if along < end && t.stamp[k] != id {
                    t.stamp[k] = id;
                    t.occ[k] = (t.occ[k] + MISS).max(OCC_MIN);
                    t.through[k] = t.through[k].saturating_add(1);
                    forget(t, k, cap);
                }
            })?;
        }
        Ok(())
    }

    /// Calls `f` on every sample whose square the ray `origin + t dir`, `t` in
    /// `[t0, t1]`, crosses (Amanatides & Woo's traversal), with the sample's index in
    /// its tile and its centre's distance along the ray; creates or loads tiles.
    fn walk(
        &mut self,
        origin: Point,
        dir: Point,
        t0: f64,
        t1: f64,
        mut f: impl FnMut(&mut Tile, usize, f64),
    ) -> Result<()> {
        if t1.is_nan() || t0.is_nan() || t1 <= t0 {
            return Ok(());
        }
        let (cell, side) = (self.params.cell, self.params.tile);
        // Lattice units: sample (i, j) owns [i - 1/2, i + 1/2) x [j - 1/2, j + 1/2).
        let u = [
            (origin[0] + t0 * dir[0]) / cell + 0.5,
            (origin[1] + t0 * dir[1]) / cell + 0.5,
        ];
        let mut ij = [u[0].floor() as i64, u[1].floor() as i64];
        let steps = [
            if dir[0] >= 0.0 { 1i64 } else { -1 },
            if dir[1] >= 0.0 { 1i64 } else { -1 },
        ];
        let mut next = [0.0f64; 2];
        let mut delta = [f64::INFINITY; 2];
        for a in 0..2 {
            if dir[a] != 0.0 {
                let boundary = if steps[a] > 0 {
                    ij[a] as f64 + 1.0
                } else {
                    ij[a] as f64
                };
                next[a] = t0 + (boundary - u[a]) * cell / dir[a];
                delta[a] = cell / dir[a].abs();
            } else {
                next[a] = f64::INFINITY;
            }
        }
        // A sample's centre along the ray, and what a step on each axis adds to it.
        let along_of = |ij: [i64; 2]| {
            (ij[0] as f64 * cell - origin[0]) * dir[0] + (ij[1] as f64 * cell - origin[1]) * dir[1]
        };
        let step_along = [
            steps[0] as f64 * cell * dir[0],
            steps[1] as f64 * cell * dir[1],
        ];
        let s = side as i64;
        let mut t = t0;
        while t <= t1 {
            // The tile is looked up once for the run of samples the ray crosses in it;
            // within it the sample's place and distance along the ray are stepped.
            let (key, _) = locate(ij[0], ij[1], side);
            self.load(key)?;
            let tile = self.tiles.get_mut(&key).expect("loaded above");
            tile.seen = self.scans;
            let mut local = [ij[0] - key.0 * s, ij[1] - key.1 * s];
            let mut along = along_of(ij);
            while t <= t1 {
                f(tile, (local[1] * s + local[0]) as usize, along);
                let a = if next[0] < next[1] { 0 } else { 1 };
                t = next[a];
                next[a] += delta[a];
                ij[a] += steps[a];
                local[a] += steps[a];
                along += step_along[a];
                if local[a] < 0 || local[a] >= s {
                    break;
                }
            }
        }
        Ok(())
    }

    /// Brings the tile at `key` into memory: from the store, or new.
    fn load(&mut self, key: Key) -> Result<()> {
        if self.tiles.contains_key(&key) {
            return Ok(());
        }
        let side = self.params.tile;
        let tile = if self.stored.remove(&key).is_some() {
            let bytes = self
                .store
                .take(key)
                .map_err(Error::TileStore)?
                .ok_or_else(|| Error::TileStore(format!("tile {key:?} is not in the store")))?;
            Tile::from_bytes(&bytes, side)
                .ok_or_else(|| Error::TileStore(format!("tile {key:?} came back damaged")))?
        } else {
            Tile::new(side)
        };
        self.tiles.insert(key, tile);
        Ok(())
    }

    /// The signed distance to the scan's `curves` (world coordinates) fused into every
    /// sample within `trunc` of them, weighed by how far the scan's heading error moves
    /// a curve at that range from the sensor at `origin` against the scan's range
    /// `noise` (`MapParams::heading_noise`): a weighted average, so that the walls lie
    /// where the scans that saw them from near put them. Near an open curve's end the
    /// distance has no sign to give (the wall may go on unseen): samples nearest an end
    /// are left alone.
    fn fuse_curves(
        &mut self,
        curves: &[Polyline],
        trunc: f64,
        origin: Point,
        noise: f64,
    ) -> Result<()> {
        let heading = self.params.heading_noise;
        // A curve is no sharper than the lattice that holds it.
        let spread = noise.max(0.25 * self.params.cell);
        let cell = self.params.cell;
        let mut scratch = std::mem::take(&mut self.scratch);
        scratch.clear();
        for c in curves {
            let n = c.points.len();
            let segs = if c.closed { n } else { n.saturating_sub(1) };
            for s in 0..segs {
                let (a, b) = (c.points[s], c.points[(s + 1) % n]);
                let first = !c.closed && s == 0;
                let last = !c.closed && s + 1 == segs;
                let d = [b[0] - a[0], b[1] - a[1]];
                let len2 = d[0] * d[0] + d[1] * d[1];
                if len2 <= 0.0 {
                    continue;
                }
                let lo = [a[0].min(b[0]) - trunc, a[1].min(b[1]) - trunc];
                let hi = [a[0].max(b[0]) + trunc, a[1].max(b[1]) + trunc];
                let (i0, i1) = ((lo[0] / cell).ceil() as i64, (hi[0] / cell).floor() as i64);
                let (j0, j1) = ((lo[1] / cell).ceil() as i64, (hi[1] / cell).floor() as i64);
                // Each row only where it crosses the band within `trunc` of the segment's
                // line (a long slanted wall's box is mostly far from it).
                let reach = trunc * len2.sqrt();
                for j in j0..=j1 {
                    let (mut r0, mut r1) = (i0, i1);
                    if d[1].abs() > 1e-12 * len2.sqrt() {
                        let y = j as f64 * cell - a[1];
                        let (x0, x1) = (
                            a[0] + (d[0] * y - reach) / d[1],
                            a[0] + (d[0] * y + reach) / d[1],
                        );
                        let (x0, x1) = (x0.min(x1), x0.max(x1));
                        r0 = r0.max((x0 / cell).floor() as i64);
                        r1 = r1.min((x1 / cell).ceil() as i64);
                    }
                    for i in r0..=r1 {
                        let p = [i as f64 * cell, j as f64 * cell];
                        let w = [p[0] - a[0], p[1] - a[1]];
                        let t = (w[0] * d[0] + w[1] * d[1]) / len2;
                        if (first && t < 0.0) || (last && t > 1.0) {
                            continue;
                        }
                        let t = t.clamp(0.0, 1.0);
                        let q = [a[0] + t * d[0] - p[0], a[1] + t * d[1] - p[1]];
                        let off = (q[0] * q[0] + q[1] * q[1]).sqrt();
                        if off > trunc {
                            continue;
                        }
                        let side = d[0] * w[1] - d[1] * w[0];
                        let sd = if side > 0.0 { off } else { -off } as f32;
                        let across = dist(p, origin) * heading;
                        let weight = (1.0 / (1.0 + (across / spread).powi(2))) as f32;
                        scratch
                            .entry((i, j))
                            .and_modify(|v: &mut (f32, f32)| {
                                if sd.abs() < v.0.abs() {
                                    *v = (sd, weight);
                                }
                            })
                            .or_insert((sd, weight));
                    }
                }
            }
        }
        let (side, cap) = (self.params.tile, self.params.max_weight);
        // Tile by tile, so each tile is looked up once.
        let mut cells = std::mem::take(&mut self.cells);
        cells.clear();
        cells.extend(scratch.drain().map(|((i, j), (sd, weight))| {
            let (key, k) = locate(i, j, side);
            (key, k, sd, weight)
        }));
        cells.sort_unstable_by_key(|c| c.0);
        for run in cells.chunk_by(|a, b| a.0 == b.0) {
            let key = run[0].0;
            self.load(key)?;
            let t = self.tiles.get_mut(&key).expect("loaded above");
            t.seen = self.scans;
            for &(_, k, sd, weight) in run {
                let w = t.weight[k];
                let total = t.evidence[k].min(f32::from(cap));
                t.sdf[k] += weight * (sd - t.sdf[k]) / (total + weight);
                t.evidence[k] = total + weight;
                t.weight[k] = w.saturating_add(1).min(cap);
            }
        }
        self.scratch = scratch;
        self.cells = cells;
        Ok(())
    }

    /// Sends the least recently seen tiles to the store until `max_tiles` remain,
    /// keeping their borders and curves.
    fn evict(&mut self) -> Result<()> {
        while self.tiles.len() > self.params.max_tiles {
            let Some((&key, _)) = self
                .tiles
                .iter()
                .filter(|(_, t)| t.seen < self.scans)
                .min_by_key(|(k, t)| (t.seen, **k))
            else {
                break;
            };
            self.put_away(key)?;
            self.spills += 1;
        }
        self.forget_beyond_store_bound()
    }

    /// Forgets the least recently seen stored tiles beyond `max_stored_tiles`: the store
    /// is bounded whatever the poses do.
    fn forget_beyond_store_bound(&mut self) -> Result<()> {
        let excess = self
            .stored
            .len()
            .saturating_sub(self.params.max_stored_tiles);
        if excess == 0 {
            return Ok(());
        }
        let mut oldest: Vec<(u64, Key)> = self.stored.iter().map(|(k, v)| (v.2, *k)).collect();
        oldest.select_nth_unstable(excess - 1);
        for &(_, key) in &oldest[..excess] {
            self.stored.remove(&key);
            self.store.take(key).map_err(Error::TileStore)?;
            self.dropped += 1;
        }
        if self.dropped == excess as u64 {
            tracing::warn!(
                max_stored_tiles = self.params.max_stored_tiles,
                "the map's store is full: the least recently seen tiles are forgotten"
            );
        }
        Ok(())
    }

    /// What the lattice knows at sample `(i, j)`, from memory or a stored tile's border;
    /// `None` where no scan reached, or inside a stored tile.
    fn sample(&self, i: i64, j: i64) -> Option<Sample> {
        let side = self.params.tile;
        let (key, k) = locate(i, j, side);
        if let Some(t) = self.tiles.get(&key) {
            return Some(t.sample(k));
        }
        let (border, _, _) = self.stored.get(&key)?;
        let (li, lj) = (k % side, k / side);
        if lj == 0 {
            Some(border.row[li])
        } else if li == 0 {
            Some(border.column[lj])
        } else {
            None
        }
    }

    /// The map's curves now: pieces of tiles in memory drawn afresh, those of stored
    /// tiles as they were when they left, joined across tiles, the free side on the
    /// left.
    pub fn curves(&self) -> Result<Vec<Polyline>> {
        Ok(extract::curves(self))
    }

    /// The map's curves drawn from every tile afresh (stored ones brought back one at a
    /// time, memory's bound kept), and the scores of [`MapScores`]: what a run's end
    /// writes.
    pub fn finish(&mut self) -> Result<(Vec<Polyline>, MapScores)> {
        let stored: Vec<Key> = {
            let mut k: Vec<Key> = self.stored.keys().copied().collect();
            k.sort_unstable();
            k
        };
        // Each stored tile's pieces drawn again with its neighbours as they are now.
        for key in stored {
            if self.tiles.len() >= self.params.max_tiles {
                self.evict_one_other_than(key)?;
            }
            self.load(key)?;
            self.put_away(key)?;
        }
        let curves = extract::curves(self);
        let scores = score::scores(self, &curves)?;
        Ok((curves, scores))
    }

    /// The scores of [`MapScores`] for any `curves` in the world frame, by the votes
    /// this map's scans cast: how a map drawn elsewhere (another tool, an earlier run)
    /// fares on this run's evidence. Insert the scans with no curves to gather the
    /// votes alone. The union's scores are those of the curves inserted.
    pub fn score(&mut self, curves: &[Polyline]) -> Result<MapScores> {
        score::scores(self, curves)
    }

    /// What a drawing of `curves` (this map's) shows beside them: a uniform sample of
    /// at most `max_returns` of the run's returns, and the points along the curves that
    /// the scans saw through more often than they hit.
    pub fn layers(&mut self, curves: &[Polyline], max_returns: usize) -> Result<MapLayers> {
        score::layers(self, curves, max_returns)
    }

    fn evict_one_other_than(&mut self, keep: Key) -> Result<()> {
        let Some((&key, _)) = self
            .tiles
            .iter()
            .filter(|(k, _)| **k != keep)
            .min_by_key(|(k, t)| (t.seen, **k))
        else {
            return Ok(());
        };
        self.put_away(key)?;
        self.spills += 1;
        Ok(())
    }

    /// Sends the tile at `key` (in memory) to the store, keeping its first row and
    /// column and the curve pieces it holds.
    fn put_away(&mut self, key: Key) -> Result<()> {
        let pieces = extract::tile_pieces(self, key);
        let Some(tile) = self.tiles.remove(&key) else {
            return Ok(());
        };
        let border = Border::of(&tile, self.params.tile);
        self.store
            .put(key, tile.to_bytes())
            .map_err(Error::TileStore)?;
        self.stored.insert(key, (border, pieces, tile.seen));
        Ok(())
    }

    /// Runs `f` on the sample nearest each of `points` (world), tile by tile, bringing
    /// stored tiles back one at a time; `f` gets `None` where no scan reached.
    fn visit_samples(
        &mut self,
        points: &[Point],
        mut f: impl FnMut(usize, Option<Sample>),
    ) -> Result<()> {
        let (cell, side) = (self.params.cell, self.params.tile);
        let mut order: Vec<(Key, usize, usize)> = points
            .iter()
            .enumerate()
            .map(|(n, p)| {
                let (key, k) = locate(
                    (p[0] / cell).round() as i64,
                    (p[1] / cell).round() as i64,
                    side,
                );
                (key, k, n)
            })
            .collect();
        order.sort_unstable();
        let mut start = 0;
        while start < order.len() {
            let key = order[start].0;
            let end = start + order[start..].partition_point(|o| o.0 == key);
            let was_stored = self.stored.contains_key(&key);
            if was_stored {
                if self.tiles.len() >= self.params.max_tiles {
                    self.evict_one_other_than(key)?;
                }
                self.load(key)?;
            }
            let tile = self.tiles.get(&key);
            for &(_, k, n) in &order[start..end] {
                f(n, tile.map(|t| t.sample(k)));
            }
            if was_stored {
                self.put_away(key)?;
            }
            start = end;
        }
        Ok(())
    }
}

/// Halves a sample's votes once they reach `cap` scans: the vote is the recent scans'
/// (about the last `cap`), as the signed distance's average is.
fn forget(t: &mut Tile, k: usize, cap: u16) {
    if u32::from(t.hits[k]) + u32::from(t.through[k]) >= u32::from(cap) {
        t.hits[k] = t.hits[k].div_ceil(2);
        t.through[k] = t.through[k].div_ceil(2);
    }
}

/// Each beam's cosine of incidence on the surface it returned from, from the chord of
/// the returns three beams either side (about the noise's scale on the scanners of
/// interest); 1 where the neighbours do not lie on one surface with it, or are missing.
fn incidence_cosines(scan: &Scan) -> Vec<f64> {
    const SIDE: usize = 3;
    let n = scan.ranges.len();
    let point = |k: usize| -> Option<Point> {
        let r = scan.ranges[k];
        r.is_finite().then(|| {
            let (s, c) = scan.angles[k].sin_cos();
            [r * c, r * s]
        })
    };
    (0..n)
        .map(|k| {
            let Some(p) = point(k) else {
                return 1.0;
            };
            let r = scan.ranges[k];
            let (lo, hi) = (k.saturating_sub(SIDE), (k + SIDE).min(n - 1));
            let (Some(a), Some(b)) = (point(lo), point(hi)) else {
                return 1.0;
            };
            // One surface: the chord no longer than the beams' spread at a grazing
            // incidence of about 80 degrees would make it.
            let spread = r * scan.step * (hi - lo) as f64;
            let chord = [b[0] - a[0], b[1] - a[1]];
            let len = chord[0].hypot(chord[1]);
            if len <= 0.0 || len > 6.0 * spread + 0.05 || lo == hi {
                return 1.0;
            }
            let dir = [p[0] / r, p[1] / r];
            ((dir[0] * chord[1] - dir[1] * chord[0]) / len).abs()
        })
        .collect()
}

/// The stretches of `curves` within `r` of `o`, each cut where it crosses the circle;
/// a closed curve that leaves the disc comes out as open pieces.
fn within(curves: &[Polyline], o: Point, r: f64) -> Vec<Polyline> {
    let inside = |p: Point| dist(p, o) <= r;
    // Where the segment from `a` (inside) to `b` (outside) leaves the disc.
    let exit = |a: Point, b: Point| -> Point {
        let (d, f) = ([b[0] - a[0], b[1] - a[1]], [a[0] - o[0], a[1] - o[1]]);
        let (qa, qb, qc) = (
            d[0] * d[0] + d[1] * d[1],
            2.0 * (f[0] * d[0] + f[1] * d[1]),
            f[0] * f[0] + f[1] * f[1] - r * r,
        );
        let t = if qa > 0.0 {
            ((-qb + (qb * qb - 4.0 * qa * qc).max(0.0).sqrt()) / (2.0 * qa)).clamp(0.0, 1.0)
        } else {
            0.0
        };
        [a[0] + t * d[0], a[1] + t * d[1]]
    };
    let mut out = Vec::new();
    for c in curves {
        if c.points.iter().all(|&p| inside(p)) {
            out.push(c.clone());
            continue;
        }
        let n = c.points.len();
        // A closed curve is walked from a point outside, so that no stretch wraps round.
        let start = if c.closed {
            c.points.iter().position(|&p| !inside(p)).unwrap_or(0)
        } else {
            0
        };
        let steps = if c.closed { n + 1 } else { n };
        let mut piece: Vec<Point> = Vec::new();
        let mut prev: Option<Point> = None;
        for k in 0..steps {
            let p = c.points[(start + k) % n];
            match (prev, inside(p)) {
                (Some(q), true) if !inside(q) => piece.push(exit(p, q)),
                (Some(q), false) if inside(q) => {
                    piece.push(exit(q, p));
                    out.push(Polyline {
                        closed: false,
                        points: std::mem::take(&mut piece),
                    });
                }
                _ => {}
            }
            if inside(p) {
                piece.push(p);
            }
            prev = Some(p);
        }
        if piece.len() >= 2 {
            out.push(Polyline {
                closed: false,
                points: piece,
            });
        }
    }
    out.retain(|pl| pl.points.len() >= 2);
    out
}

#[cfg(test)]
mod tests;
