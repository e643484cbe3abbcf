//! `isoline map --register`'s first pass: every scan of the input registered and the
//! loops closed, so that the map is fused once, at the final poses (a loop closed late
//! moves scans fused early; fusing after it needs no tile fused twice).

use std::path::Path;
use std::time::Instant;

use anyhow::{anyhow, Result};
use rayon::prelude::*;

use isoline_core::Pose;
use isoline_io::bag::BagOptions;
use isoline_map::{RegisterParams, Registrar};

use super::BATCH;

/// The estimated poses, one per scan in reading order, and what it took.
pub struct Registration {
    pub poses: Vec<Pose>,
    /// The velocity each scan without an input pose was corrected for its sweep by
    /// (`Registrar::push_swept_curves`), in reading order; `None` for the others (those
    /// with a pose were corrected as read, by it). The map's pass corrects each the
    /// same way.
    pub velocities: Vec<Option<[f64; 3]>>,
    /// Each scan's curves and noise estimate as this pass reconstructed them, in reading
    /// order, for the map's pass to fuse rather than reconstruct again; `None` where
    /// the reconstruction failed or the cache was full.
    pub curves: Vec<Option<Drawn>>,
    pub summary: Summary,
}

/// A scan as read for registration: its scan, input pose, and for one without a pose
/// its time and beam timing.
type Read = (
    isoline_core::Scan,
    Option<Pose>,
    Option<(f64, isoline_core::Sweep)>,
);

/// A scan's reconstruction as the map fuses it: its curves and its noise estimate.
pub type Drawn = (Vec<isoline_core::Polyline>, f64);

/// The curve vertices kept for the map's pass at most (64 MB): a bound on memory
/// whatever the run's length. Past it the map's pass reconstructs its scans again, as
/// it did before the cache (a few thousand scans of a 2D scanner fit).
const CACHED_VERTICES: usize = 4_000_000;

/// The summary's `registration` object.
#[derive(Debug, serde::Serialize)]
pub struct Summary {
    /// Scans registered.
    pub scans: usize,
    /// Of them, without an input pose (registered from their returns alone).
    pub without_pose: usize,
    /// Keyframes in the pose graph.
    pub keyframes: usize,
    /// Loops closed.
    pub loops: usize,
    /// Scans where some direction was decided by the input's motion, not the returns.
    pub degenerate: usize,
    /// Median share of a scan's returns on the local map's walls.
    pub median_inlier_share: f64,
    /// CPU time (the process's, all threads) a scan, milliseconds.
    pub cpu_ms_per_scan: Option<f64>,
    /// Wall time, seconds.
    pub seconds: f64,
}

/// Registers every scan of `input` by its curves (reconstructed with `params_method`;
/// frames without beams are passed over, as the map passes them over), each corrected
/// for the motion during its sweep as the map's own pass corrects it.
pub fn run(
    input: &Path,
    bag: &BagOptions,
    max_line: usize,
    params: RegisterParams,
    params_method: &isoline_core::Params,
    time_increment: Option<f64>,
    bar: &indicatif::ProgressBar,
) -> Result<Registration> {
    let mut reg =
        Registrar::new(params).map_err(|p| anyhow!("registration parameters: {}", p.join("; ")))?;
    let start = Instant::now();
    let cpu = cpu_time::ProcessTime::try_now().ok();
    let (mut without_pose, mut degenerate) = (0usize, 0usize);
    let mut shares = Vec::new();
    let (mut cache, mut cached) = (Vec::new(), 0usize);
    // Scans are reconstructed in parallel batches, then registered in order by their
    // curves (Registrar::push_curves).
    let mut velocities: Vec<Option<[f64; 3]>> = Vec::new();
    let mut batch: Vec<Read> = Vec::with_capacity(BATCH);
    let mut run = |batch: &mut Vec<Read>| {
        let drawn: Vec<Option<Drawn>> = batch
            .par_iter()
            .map(|(scan, _, _)| {
                isoline_core::reconstruct_scan(scan, params_method)
                    .ok()
                    .map(|r| (r.polylines, r.noise_estimate))
            })
            .collect();
        for ((scan, pose, timing), mut drawn) in batch.drain(..).zip(drawn) {
            without_pose += usize::from(pose.is_none());
            let curves = drawn.as_ref().map_or(&[][..], |d| &d.0[..]);
            // A scan whose reconstruction drew nothing is registered by its returns; one
            // without a pose and with timing is corrected for its sweep by the motion
            // registration gives, its curves with it.
            let (r, velocity) = match timing {
                Some((t, sweep)) if curves.is_empty() => {
                    let (r, _) = reg.push_swept(&scan, &sweep, t, pose);
                    (r, None)
                }
                Some((t, sweep)) => {
                    let (r, v) = reg.push_swept_curves(&scan, curves, &sweep, t, pose);
                    (r, v.map(|v| (v, sweep)))
                }
                None if curves.is_empty() => (reg.push(&scan, pose), None),
                None => (reg.push_curves(&scan, curves, pose), None),
            };
            let vertices: usize = curves.iter().map(|c| c.points.len()).sum();
            // The map's pass fuses the curves with the scan corrected as they were.
            if let (Some((v, sweep)), Some(d)) = (velocity, drawn.as_mut()) {
                for c in &mut d.0 {
                    c.points = sweep.unbend(&c.points, scan.origin, v);
                }
            }
            velocities.push(velocity.map(|(v, _)| v));
            cache.push(drawn.filter(|_| cached + vertices <= CACHED_VERTICES));
            if cache.last().is_some_and(Option::is_some) {
                cached += vertices;
            }
            degenerate += usize::from(r.degenerate);
            shares.push(r.inlier_share);
        }
        bar.set_message(format!("registered, {} loops closed", reg.loops()));
        bar.set_position(reg.scans() as u64);
    };
    // A file damaged part way gives poses to the scans before the damage; the map's own
    // pass reads them again and reports the damage.
    let mut deskew = isoline_io::Deskew::new(time_increment);
    let _ = isoline_io::for_each_item_capped(input, bag, max_line, |item| {
        if let Ok(mut f) = item {
            deskew.apply(&mut f);
            let timing = f.unposed_sweep(time_increment);
            if let Some(scan) = f.scan {
                batch.push((scan, f.pose, timing));
                if batch.len() == BATCH {
                    run(&mut batch);
                }
            }
        }
        true
    });
    run(&mut batch);
    let poses = reg.finish();
    let seconds = start.elapsed().as_secs_f64();
    let n = poses.len();
    let median_inlier_share = if shares.is_empty() {
        0.0
    } else {
        let mid = shares.len() / 2;
        *shares.select_nth_unstable_by(mid, f64::total_cmp).1
    };
    // A scan without timing or a pose to correct it by keeps the velocity None: only
    // pose-less timed scans are corrected here.
    let velocities = if velocities.iter().any(Option::is_some) {
        velocities
    } else {
        Vec::new()
    };
    Ok(Registration {
        poses,
        velocities,
        curves: cache,
        summary: Summary {
            scans: n,
            without_pose,
            keyframes: reg.keyframes(),
            loops: reg.loops(),
            degenerate,
            median_inlier_share,
            cpu_ms_per_scan: cpu
                .and_then(|c| c.try_elapsed().ok())
                .map(|d| 1e3 * d.as_secs_f64() / n.max(1) as f64),
            seconds,
        },
    })
}
