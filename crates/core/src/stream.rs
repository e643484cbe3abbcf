//! A stream of frames (one sensor's scans, one contour's digitizations): what each frame
//! leaves for the next, and the rules that decide when the next one may use it.
//!
//! Three things carry over, each kept by the stage that uses it, so that the daemon
//! (which runs each stage on its own thread) and [`Stream`] (which runs them in turn)
//! take the same decisions:
//! - the adapt stage's [`MeshMemory`]: the last frame's adapted mesh, which the next
//!   frame's mesh is adapted from, moved by the sensor's motion;
//! - the solve stage's [`LevelSetMemory`]: the last frame's renormalized level set, which
//!   the next frame's level set starts from (the warm start), moved likewise;
//! - the export stage's [`Refiner`]: the last frames of a scan stream with poses, which
//!   the refined export fuses (`docs/method.md`, "Refinement over frames"; isoline-map's
//!   `Window`).
//!
//! A frame number that does not go up means the stream restarted: the next frame then
//! starts cold.

use crate::error::Result;
use crate::field::AdaptedMesh;
use crate::geom::{to_sensor, to_world, Point, Pose};
use crate::levelset::evolve::{LevelSet, Solved};
use crate::mesh::Mesh;
use crate::reconstruct::{self, Params, Prepared, Reconstruction};
use crate::refine::Refiner;
use crate::scan::Scan;

/// What the adapt stage keeps of a stream: its last frame's mesh, in that frame's data
/// coordinates, with the frame's number and pose.
#[derive(Debug, Default)]
pub struct MeshMemory {
    last: Option<(u64, Mesh, Option<Pose>)>,
}

impl MeshMemory {
    /// Frame `frame` (seen at `pose`) adapted from the stream's last mesh when the frame
    /// number went up (moved by the motion between the two poses when both have one), else
    /// from scratch; the result becomes the stream's last mesh.
    pub fn adapt(&mut self, prepared: &Prepared, frame: u64, pose: Option<Pose>) -> AdaptedMesh {
        let previous = self.last.as_ref().filter(|(f, _, _)| *f < frame);
        let motion = previous.and_then(|(_, _, from)| from.zip(pose));
        let adapted =
            reconstruct::adapt_moving(prepared, previous.map(|(_, mesh, _)| mesh), motion);
        self.last = Some((frame, prepared.mesh_in_data(&adapted), pose));
        adapted
    }

    /// Bytes it holds, roughly.
    pub fn bytes(&self) -> usize {
        self.last.as_ref().map_or(0, |(_, mesh, _)| mesh.bytes())
    }
}

/// What the solve stage keeps of a stream: the number of the last frame it solved, and
/// the last renormalized level set it was given ([`LevelSetMemory::keep`]), in that
/// frame's data coordinates, with the frame's pose.
#[derive(Debug, Default)]
pub struct LevelSetMemory {
    last_frame: Option<u64>,
    kept: Option<(LevelSet, Option<Pose>)>,
}

impl LevelSetMemory {
    /// Frame `frame`'s level set on `adapted`, warm-started from the kept level set
    /// (moved into this frame's coordinates when both frames have a pose) unless the
    /// frame number did not go up, which means the stream restarted: then it starts cold
    /// and the kept level set is dropped. See [`reconstruct::solve`] for when a warm start
    /// is taken.
    pub fn solve(
        &mut self,
        prepared: &Prepared,
        adapted: &AdaptedMesh,
        frame: u64,
        pose: Option<Pose>,
    ) -> Solved {
        if self.last_frame.is_some_and(|f| f >= frame) {
            tracing::info!(frame, "stream restarted: cold start");
            self.kept = None;
        }
        self.last_frame = Some(frame);
        let previous = self.kept.as_mut().map(|(level_set, from)| {
            if let (Some(a), Some(b)) = (*from, pose) {
                level_set.map_coords(|p: Point| to_sensor(b, to_world(a, p)));
                *from = Some(b);
            }
            level_set.as_previous()
        });
        reconstruct::solve(prepared, adapted, previous)
    }

    /// Keeps `level_set`, a renormalized frame's ([`Prepared::level_set`]) seen at
    /// `pose`, as the next frame's start.
    pub fn keep(&mut self, level_set: LevelSet, pose: Option<Pose>) {
        self.kept = Some((level_set, pose));
    }

    /// Bytes it holds, roughly.
    pub fn bytes(&self) -> usize {
        self.kept.as_ref().map_or(0, |(l, _)| l.bytes())
    }
}

/// One frame of a stream, as [`Stream::push`] takes it.
#[derive(Clone, Copy, Debug)]
pub struct StreamFrame<'a> {
    /// The frame's number: the stream restarts (cold) when it does not go up.
    pub frame: u64,
    /// Its points (for a scan, its returns).
    pub points: &'a [Point],
    /// The beams that saw them, for a scan frame.
    pub scan: Option<&'a Scan>,
    /// Its time stamp, seconds (refinement drops frames older than its window allows).
    pub t: Option<f64>,
    /// Where its coordinates sit in the world: moves the warm start and places the frame
    /// in the refinement window.
    pub pose: Option<Pose>,
}

/// A stream of frames reconstructed one after the other, each warm-started from the one
/// before and, when refinement is on, its scans fused over a window of the last frames:
/// the daemon's per-stream state and decisions, in one value.
///
/// ```
/// use isoline_core::{Params, Stream, StreamFrame};
/// let ring = |r: f64| -> Vec<[f64; 2]> {
///     (0..240)
///         .map(|i| {
///             let a = i as f64 * std::f64::consts::TAU / 240.0;
///             [r * a.cos(), r * a.sin()]
///         })
///         .collect()
/// };
/// let mut stream = Stream::new(Params::default(), true);
/// for (frame, r) in [1.0, 1.01, 1.02].into_iter().enumerate() {
///     let points = ring(r);
///     let f = StreamFrame { frame: frame as u64, points: &points, scan: None, t: None, pose: None };
///     let result = stream.push(&f).unwrap();
///     assert_eq!(result.polylines.len(), 1);
///     assert_eq!(result.stats.warm_start, frame > 0);
/// }
/// ```
#[derive(Debug)]
pub struct Stream {
    params: Params,
    warm: bool,
    mesh: MeshMemory,
    level_set: LevelSetMemory,
    refiner: Option<Box<dyn Refiner>>,
}

impl Stream {
    /// A stream reconstructed with `params`, each frame warm-started from the last when
    /// `warm`.
    pub fn new(params: Params, warm: bool) -> Stream {
        Stream {
            params,
            warm,
            mesh: MeshMemory::default(),
            level_set: LevelSetMemory::default(),
            refiner: None,
        }
    }

    /// The same stream with refinement on: each scan frame with a pose is fused with the
    /// stream's last frames by `refiner` (isoline-map's `Window`).
    pub fn refining(mut self, refiner: Box<dyn Refiner>) -> Stream {
        self.params.scan.refine = true;
        self.refiner = Some(refiner);
        self
    }

    /// The parameters it reconstructs with.
    pub fn params(&self) -> &Params {
        &self.params
    }

    /// What its refinement window holds, when refinement is on.
    pub fn window(&self) -> Option<crate::stats::WindowStats> {
        self.refiner.as_ref().map(|r| r.stats())
    }

    /// Reconstructs the stream's next frame. A frame that fails (bad points) leaves the
    /// stream's state as it was.
    pub fn push(&mut self, f: &StreamFrame<'_>) -> Result<Reconstruction> {
        let _span = tracing::info_span!("frame", frame = f.frame).entered();
        let prepared = reconstruct::prepare(f.points, f.scan, &self.params)?;
        let adapted = if self.warm {
            self.mesh.adapt(&prepared, f.frame, f.pose)
        } else {
            reconstruct::adapt(&prepared, None)
        };
        let mut solved = if self.warm {
            self.level_set.solve(&prepared, &adapted, f.frame, f.pose)
        } else {
            reconstruct::solve(&prepared, &adapted, None)
        };
        reconstruct::renormalize(&adapted.mesh, &mut solved);
        if self.warm {
            // The frame's own level set: refinement moves the curves, not the level set.
            let kept = prepared.level_set(&adapted, &solved);
            self.level_set.keep(kept, f.pose);
        }
        Ok(match (self.refiner.as_deref_mut(), f.pose) {
            (Some(refiner), Some(pose)) if prepared.is_scan() => {
                reconstruct::export_refined(&prepared, adapted, solved, f.frame, f.t, pose, refiner)
            }
            _ => reconstruct::export(&prepared, adapted, solved),
        })
    }

    /// Bytes of state it holds between frames, roughly.
    pub fn bytes(&self) -> usize {
        self.mesh.bytes()
            + self.level_set.bytes()
            + self.refiner.as_ref().map_or(0, |r| r.stats().bytes)
    }
}
