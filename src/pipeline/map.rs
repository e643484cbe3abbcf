//! The map stage: every reconstructed scan with a pose, from every stream, fused into
//! one world-frame curve map ([`isoline_map::Map`]) and written as it grows
//! (`[map] output`, every `every` scans or `every_seconds`, and at the end), each file
//! whole (docs/daemon.md, "The map of the run").
//!
//! The streams' poses are taken to be in one world frame (a fleet's robots localized in
//! one building's map): their scans build one map.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crossbeam_channel::Receiver;
use serde::Serialize;

use crate::error::{Error, Result};
use isoline_core::geom::{Point, Polyline, Pose};
use isoline_core::Scan;
use isoline_map::{Map, MapParams};

/// `[map]` for the daemon, validated.
#[derive(Clone, Debug, PartialEq)]
pub struct MapOutput {
    /// The lattice and the evidence rule.
    pub params: MapParams,
    /// The files written, each in the format of its extension.
    pub paths: Vec<PathBuf>,
    /// Write every this many scans (0: only at the end).
    pub every: u64,
    /// Also write once this long has passed since the last write.
    pub every_seconds: Option<Duration>,
    /// Where tiles beyond `params.max_tiles` go (default: a temporary folder).
    pub spill: Option<PathBuf>,
}

/// Default of `map.every` for the daemon: a map a robot's operator can watch grow (a
/// 10 Hz scanner writes it every 10 s).
pub const DAEMON_MAP_EVERY: u64 = 100;

/// A reconstructed scan on its way into the map.
pub(crate) struct MapItem {
    pub(crate) scan: Box<Scan>,
    pub(crate) pose: Pose,
    /// The scan's curves, in its frame.
    pub(crate) curves: Vec<Polyline>,
    /// The scan's range noise estimate.
    pub(crate) noise: f64,
    pub(crate) stream: Option<String>,
    pub(crate) frame: u64,
}

/// Reconstructed frames the map did not take, counted by the export stage.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct MapCounts {
    pub(crate) unplaced: u64,
    pub(crate) behind: u64,
}

/// What the map stage did, in the run's summary.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct MapReport {
    /// Scans fused.
    pub scans: u64,
    /// Reconstructed frames without a pose or without beams: they cannot be placed.
    pub unplaced: u64,
    /// Frames that found the map stage behind under `pipeline.policy = "latest"` and
    /// passed it by (their records are written all the same).
    pub behind: u64,
    /// Scans whose fusion failed (a bug, logged).
    pub failed: u64,
    /// Scans whose pose put them beyond the map's lattice
    /// ([`isoline_map::MapParams::max_coordinate`]): left out, the first logged.
    pub refused: u64,
    /// Stored tiles forgotten beyond `[map] max_stored_tiles`.
    pub tiles_dropped: u64,
    /// Times the map's files were written (the last at the end).
    pub writes: u64,
    /// The final map's pieces.
    pub pieces: usize,
    /// Its length, metres.
    pub length: f64,
    /// Share of static returns within `hit_tolerance` of the map
    /// ([`isoline_map::MapScores`]).
    pub static_within: f64,
    /// Share of the map's length seen through more often than hit.
    pub seen_through: f64,
    /// Tiles in memory at the end.
    pub tiles_resident: usize,
    /// Tiles in the store at the end.
    pub tiles_stored: usize,
}

/// The map as it stands and where it goes.
struct Mapper {
    map: Map,
    out: MapOutput,
    live: Option<Arc<super::live::LiveView>>,
    /// The sensor's positions, a dot a metre, for the drawing.
    path: Vec<Point>,
    since_write: u64,
    last_write: Instant,
    report: MapReport,
}

/// Starts the map stage. It ends when the export stage does (its sender dropped), after
/// the final map is written; a file that cannot be written ends the run with the error
/// and sets `stop`.
pub(crate) fn spawn_map(
    rx: Receiver<MapItem>,
    out: MapOutput,
    live: Option<Arc<super::live::LiveView>>,
    stop: Arc<AtomicBool>,
) -> Result<JoinHandle<Result<MapReport>>> {
    let spill = out.spill.clone().unwrap_or_else(std::env::temp_dir);
    let store =
        isoline_io::DiskTiles::new(Some(&spill)).map_err(|e| isoline_io::Error::io(&spill, e))?;
    let map = Map::new(out.params, Box::new(store))?;
    let mut m = Mapper {
        map,
        out,
        live,
        path: Vec::new(),
        since_write: 0,
        last_write: Instant::now(),
        report: MapReport::default(),
    };
    std::thread::Builder::new()
        .name("map".into())
        .spawn(move || {
            let run = || -> Result<MapReport> {
                while let Ok(item) = rx.recv() {
                    m.fuse(item)?;
                }
                m.finish()
            };
            run().inspect_err(|_| stop.store(true, Ordering::Relaxed))
        })
        .map_err(|e| Error::Internal(format!("cannot start thread map: {e}")))
}

impl Mapper {
    /// One scan into the map, and the files written when it is their time.
    fn fuse(&mut self, item: MapItem) -> Result<()> {
        let span = tracing::info_span!(
            "map",
            stream = item.stream.as_deref().unwrap_or(""),
            frame = item.frame
        );
        let _e = span.enter();
        let MapItem {
            scan,
            pose,
            curves,
            noise,
            ..
        } = item;
        let map = &mut self.map;
        let fused = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            map.insert(&scan, pose, &curves, noise)
        }));
        match fused {
            Ok(Ok(placed)) => {
                self.report.scans += 1;
                self.since_write += 1;
                let p = [placed[0], placed[1]];
                if self
                    .path
                    .last()
                    .is_none_or(|&q| isoline_core::geom::dist(p, q) >= 1.0)
                {
                    self.path.push(p);
                }
            }
            Ok(Err(e @ isoline_map::Error::PoseOutOfReach { .. })) => {
                self.report.refused += 1;
                if self.report.refused == 1 {
                    tracing::warn!("{e}; such scans are left out of the map (counted)");
                }
            }
            // The store failed: the map cannot go on holding its bound.
            Ok(Err(e)) => return Err(e.into()),
            Err(_) => {
                self.report.failed += 1;
                tracing::error!("fusing the scan into the map panicked; the scan is left out");
            }
        }
        let due_scans = self.out.every > 0 && self.since_write >= self.out.every;
        let due_time = self
            .out
            .every_seconds
            .is_some_and(|d| self.since_write > 0 && self.last_write.elapsed() >= d);
        if due_scans || due_time {
            let curves = self.map.curves()?;
            self.write(&curves)?;
        }
        Ok(())
    }

    /// Writes every file and shows the map in the live view.
    fn write(&mut self, curves: &[Polyline]) -> Result<()> {
        let scans = self.report.scans;
        isoline_io::map_files::write_maps(&self.out.paths, &mut self.map, curves, &self.path)?;
        if let Some(l) = &self.live {
            // A viewer that is behind sees the next write.
            l.show(isoline_io::map_files::map_view(curves, scans));
        }
        self.report.writes += 1;
        self.since_write = 0;
        self.last_write = Instant::now();
        tracing::info!(scans, pieces = curves.len(), "map written");
        Ok(())
    }

    /// The final map, written, and the report.
    fn finish(mut self) -> Result<MapReport> {
        let (curves, scores) = self.map.finish()?;
        self.write(&curves)?;
        let stats = self.map.stats();
        Ok(MapReport {
            pieces: scores.pieces,
            length: scores.length,
            static_within: scores.static_within,
            seen_through: scores.seen_through,
            tiles_resident: stats.tiles_resident,
            tiles_stored: stats.tiles_stored,
            tiles_dropped: stats.tiles_dropped,
            ..self.report
        })
    }
}
