//! `isoline map`: every scan of a recording, placed by its pose, fused into one
//! world-frame curve map (docs/method.md, "A map of the whole run").

use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};
use std::time::Instant;

use anyhow::{anyhow, bail, Context, Result};
use rayon::prelude::*;
use serde_json::json;

use isoline_core::geom::{Point, Polyline, Pose};
use isoline_core::{Params, Scan};
use isoline_io::map_files::{MapFormat, MAP_EXTENSIONS};
use isoline_io::{BadFrame, Frame};
use isoline_map::{Map, MapScores, MapStats};

mod register;

/// `isoline map` options.
#[derive(clap::Args)]
pub struct Args {
    /// A ROS 2 bag (.mcap, with --odometry or --world-frame for the poses), a CARMEN log
    /// (its lines' poses) or NDJSON frames with `pose`.
    input: PathBuf,
    /// The map; the extension picks the format: .geojson .svg .ndjson .json .mcap
    /// (a scene update in the world frame). Repeat for several. Default: the
    /// configuration's [map] output.
    #[arg(short, long)]
    output: Vec<PathBuf>,
    /// TOML configuration: [map] for the lattice, [scan] [mesh] [solver] [export] for
    /// each scan's curves.
    #[arg(short, long)]
    config: Option<PathBuf>,
    /// The run's summary (scans, times, memory, tiles, scores) as JSON.
    #[arg(long)]
    stats: Option<PathBuf>,
    /// Also write the outputs every this many scans while the map grows (0: at the end).
    /// Default: the configuration's [map] every, else 0.
    #[arg(long)]
    every: Option<u64>,
    /// Where tiles beyond [map] max_tiles go. Default: the configuration's [map] spill,
    /// else the system's temporary directory.
    #[arg(long)]
    spill: Option<PathBuf>,
    /// Estimate the scans' poses before fusing them: each scan registered against the
    /// local map with the input poses' motion as a prior (odometry), loops closed, the
    /// map fused at the estimated poses (docs/method.md, "Poses"). Frames without a pose
    /// are registered from their returns alone. Without it the input poses are the truth.
    #[arg(long)]
    register: bool,
    /// Write the pose of every scan placed (the estimate with --register) as a TUM
    /// trajectory: `t x y z qx qy qz qw` a line, z = 0.
    #[arg(long)]
    trajectory: Option<PathBuf>,
    /// No progress bar.
    #[arg(long, short)]
    quiet: bool,
    #[command(flatten)]
    bag: super::BagArgs,
}

/// Scans reconstructed at once, on all cores, before they are fused in order.
const BATCH: usize = 64;

/// What the run skipped, by reason.
#[derive(Default, Debug, serde::Serialize)]
struct Skipped {
    /// Frames without a pose: they cannot be placed.
    no_pose: u64,
    /// Frames of points without beams: no free space to vote with.
    no_beams: u64,
    /// Messages that could not be read as frames.
    unreadable: u64,
    /// Scans whose reconstruction failed.
    failed: u64,
    /// Scans whose pose puts them beyond the map's lattice.
    far: u64,
}

struct Run<'a> {
    map: Map,
    params: Params,
    skipped: Skipped,
    first_errors: Vec<String>,
    poses: Vec<Point>,
    /// Each scan fused: its time (else its frame number) and pose.
    placed: Vec<(f64, Pose)>,
    /// With --register, every scan's estimated pose in reading order, and the next's.
    registered: Option<(Vec<Pose>, usize)>,
    /// With --register, the scans' reconstructions from its pass, in reading order,
    /// each taken (left `None`) when its scan is fused.
    drawn: Vec<Option<register::Drawn>>,
    reconstruct_s: f64,
    fuse_s: f64,
    /// CPU seconds (all threads) spent reconstructing and fusing.
    reconstruct_cpu_s: f64,
    fuse_cpu_s: f64,
    outputs: &'a [PathBuf],
    every: u64,
    since_write: u64,
    /// Each block of [`BLOCK`] scans: what it cost and what memory held at its end.
    blocks: Vec<Block>,
    block: Block,
    /// `--quiet`, and when the last plain progress line was printed.
    quiet: bool,
    last_line: Instant,
    /// The input's frames, once a thread of its own has counted them.
    total: Arc<OnceLock<u64>>,
}

/// A scan the map takes: the scan, its pose, its time (else its frame number) and,
/// with --register, the reconstruction registration drew of it.
type Accepted = (Scan, Pose, f64, Option<register::Drawn>);

/// Scans a row of the summary's `blocks` covers.
const BLOCK: u64 = 1000;

/// A block of scans in the summary: whether time per scan and memory stay flat.
#[derive(Clone, Debug, Default, serde::Serialize)]
struct Block {
    /// Scans fused in the block.
    scans: u64,
    /// Milliseconds a scan: reconstruction (its batch's share of the CPU) and fusion
    /// (one thread).
    reconstruct_ms: f64,
    fuse_ms: f64,
    /// At the block's end: tiles in memory and in the store, and the process's
    /// resident memory, bytes.
    tiles_resident: usize,
    tiles_stored: usize,
    resident_bytes: Option<u64>,
}

/// Builds the map and writes it; fails when no scan could be placed.
pub fn run(mut a: Args) -> Result<()> {
    let cap = a.bag.line_cap();
    let cfg = super::load_config(a.config.as_deref())?;
    if let Some(problem) = cfg.map_noise_problem() {
        bail!("{problem}");
    }
    let (every, spill) = outputs(&mut a, &cfg)?;
    let bag = a.bag.options(&a.input)?;
    let store = isoline_io::DiskTiles::new(spill.as_deref())
        .context("creating the directory for tiles that leave memory")?;
    let map_params = cfg.map_params();
    let map = Map::new(map_params, Box::new(store))?;
    let bar = progress(a.quiet);
    let total = Arc::new(OnceLock::new());
    if !a.quiet {
        count_frames(&a.input, &bag, cap, &total);
    }
    let start = Instant::now();
    let cpu = cpu_time::ProcessTime::try_now().ok();
    let mut registration = if a.register {
        let mut params = cfg.register;
        params.max_range = params.max_range.min(map_params.max_range);
        Some(
            register::run(
                &a.input,
                &bag,
                cap,
                params,
                &cfg.params(),
                cfg.scan.time_increment,
                &bar,
            )
            .with_context(|| format!("registering {}", a.input.display()))?,
        )
    } else {
        None
    };
    let registered = registration
        .as_mut()
        .map(|r| (r.poses.clone(), std::mem::take(&mut r.curves)));
    let mut run = Run::new(
        map,
        cfg.params(),
        registered,
        &a.output,
        every,
        a.quiet,
        total,
    );
    let mut batch: Vec<Accepted> = Vec::with_capacity(BATCH);
    let mut failure: Option<anyhow::Error> = None;
    let mut deskew = isoline_io::Deskew::new(cfg.scan.time_increment);
    // Scans without a pose that registration corrected for their sweep, corrected the
    // same way here (in reading order, as registration read them).
    let velocities = registration
        .as_mut()
        .map(|r| std::mem::take(&mut r.velocities))
        .unwrap_or_default();
    let mut scans_read = 0usize;
    let read = isoline_io::for_each_item_capped(&a.input, &bag, cap, |mut item| {
        if let Ok(f) = &mut item {
            deskew.apply(f);
            if let (Some((_, sweep)), Some(Some(v)), Some(scan)) = (
                f.unposed_sweep(cfg.scan.time_increment),
                velocities.get(scans_read),
                f.scan.as_ref(),
            ) {
                let fixed = scan.deskewed(&sweep, *v);
                f.replace_scan(fixed);
            }
            scans_read += usize::from(f.scan.is_some());
        }
        if let Some(scan) = run.accept(item) {
            batch.push(scan);
        }
        if batch.len() == BATCH {
            if let Err(e) = run.fuse(&mut batch) {
                failure = Some(e);
                return false;
            }
            show(&bar, &mut run, start);
        }
        true
    });
    if let Some(e) = failure {
        return Err(e);
    }
    // A file damaged part way (a download cut short) still gives the map of the scans
    // before the damage; the run then fails with the read error.
    let read = read.with_context(|| format!("reading {}", a.input.display()));
    run.fuse(&mut batch)?;
    run.close_block();
    show(&bar, &mut run, start);
    let stats = run.map.stats();
    if stats.scans == 0 {
        read?;
        return Err(nothing_placed(&a.input, &bag, &run));
    }
    let t = Instant::now();
    let (curves, scores) = run.map.finish()?;
    let finish_s = t.elapsed().as_secs_f64();
    bar.finish_and_clear();
    let stats = run.map.stats();
    write_all(&a.output, &mut run.map, &curves, &run.poses)?;
    let wall = start.elapsed().as_secs_f64();
    let cpu_s = cpu.map(|c| c.elapsed().as_secs_f64());
    let mut summary = summary(&a.input, &run, &stats, &scores, wall, cpu_s, finish_s);
    if let Some(r) = &registration {
        summary["registration"] = serde_json::to_value(&r.summary)?;
    }
    if let Some(path) = &a.trajectory {
        super::write(path, tum(&run.placed))?;
    }
    eprintln!(
        "{}",
        done_line(&stats, &scores, wall, map_params.hit_tolerance)
    );
    if let Some(p) = &a.stats {
        super::write(p, serde_json::to_string_pretty(&summary)? + "\n")?;
    }
    read.map_err(|e| {
        e.context(format!(
            "the map of the {} scans before the damage is written",
            stats.scans
        ))
    })
}

impl<'a> Run<'a> {
    /// A run that fuses into `map`, placing scans by `registered` poses when given
    /// (with the registration's reconstructions of them).
    fn new(
        map: Map,
        params: Params,
        mut registered: Option<(Vec<Pose>, Vec<Option<register::Drawn>>)>,
        outputs: &'a [PathBuf],
        every: u64,
        quiet: bool,
        total: Arc<OnceLock<u64>>,
    ) -> Run<'a> {
        Run {
            map,
            params,
            skipped: Skipped::default(),
            first_errors: Vec::new(),
            poses: Vec::new(),
            placed: Vec::new(),
            drawn: registered
                .as_mut()
                .map(|r| std::mem::take(&mut r.1))
                .unwrap_or_default(),
            registered: registered.map(|(poses, _)| (poses, 0)),
            reconstruct_s: 0.0,
            fuse_s: 0.0,
            reconstruct_cpu_s: 0.0,
            fuse_cpu_s: 0.0,
            outputs,
            every,
            since_write: 0,
            blocks: Vec::new(),
            block: Block::default(),
            quiet,
            last_line: Instant::now(),
            total,
        }
    }
}

/// The map's outputs, `--every` and the spill folder, from the command line or else the
/// configuration's `[map]` table (its paths taken from its folder, as the daemon takes
/// them); every output checked (a known format, not the input, writable) before the
/// first scan is read.
fn outputs(a: &mut Args, cfg: &isoline::config::Config) -> Result<(u64, Option<PathBuf>)> {
    // The configuration's paths are taken from its folder, as the daemon takes them.
    let base = a
        .config
        .as_deref()
        .and_then(Path::parent)
        .unwrap_or(Path::new(""))
        .to_path_buf();
    if a.output.is_empty() {
        a.output = cfg
            .map
            .output
            .iter()
            .flat_map(|o| o.paths())
            .map(|p| base.join(p))
            .collect();
    }
    if a.output.is_empty() {
        bail!("no map to write: give -o MAP (or [map] output in the configuration)");
    }
    let every = a.every.or(cfg.map.every).unwrap_or(0);
    let spill = a
        .spill
        .clone()
        .or(cfg.map.spill.as_ref().map(|p| base.join(p)));
    let outputs: Vec<Option<&Path>> = a
        .output
        .iter()
        .map(|p| Some(p.as_path()))
        .chain([a.stats.as_deref(), a.trajectory.as_deref()])
        .collect();
    super::refuse_overwrite(&a.input, &outputs)?;
    for o in &a.output {
        if MapFormat::of(o).is_none() {
            bail!("{}: the map is written as {MAP_EXTENSIONS}", o.display());
        }
    }
    super::check_writable(&outputs)?;
    Ok((every, spill))
}

/// Why no scan was placed: the skipped counts, the first error, and what to do about
/// missing poses.
fn nothing_placed(input: &Path, bag: &isoline_io::bag::BagOptions, run: &Run<'_>) -> anyhow::Error {
    anyhow!(format!(
        "{}: no scan with a pose to place ({} without a pose, {} without beams, {} unreadable, {} beyond the map's reach{})",
        input.display(),
        run.skipped.no_pose,
        run.skipped.no_beams,
        run.skipped.unreadable,
        run.skipped.far,
        run.first_errors
            .first()
            .map(|e| format!("; first: {e}"))
            .unwrap_or_default()
    ) + &pose_hint(input, bag, run.skipped.no_pose))
}

/// The line a finished run ends with.
fn done_line(stats: &MapStats, scores: &MapScores, wall: f64, hit_tolerance: f64) -> String {
    format!(
        "isoline map: {} scans in {:.1} s ({:.0} scans/s), {} pieces, {:.1} m; static returns within {} m: {:.1}%, map seen through: {:.2}%",
        stats.scans,
        wall,
        stats.scans as f64 / wall,
        scores.pieces,
        scores.length,
        hit_tolerance,
        100.0 * scores.static_within,
        100.0 * scores.seen_through
    )
}

/// Every placed scan's time and pose as a TUM trajectory (`t x y z qx qy qz qw`).
fn tum(placed: &[(f64, Pose)]) -> String {
    let mut text = String::from("# t x y z qx qy qz qw\n");
    for &(t, pose) in placed {
        text += &isoline_map::trajectory::tum_line(t, pose);
        text.push('\n');
    }
    text
}

/// What to do about scans without poses: a bag's come from its odometry or its
/// transforms, which must be named; any recording's can be estimated.
fn pose_hint(input: &Path, bag: &isoline_io::bag::BagOptions, no_pose: u64) -> String {
    if no_pose == 0 {
        return String::new();
    }
    if isoline_io::is_bag(input) && bag.odometry.is_none() && bag.world_frame.is_none() {
        ". A bag's scans are placed by --odometry TOPIC (a nav_msgs/Odometry topic) or \
         --world-frame FRAME (through /tf); or estimate their poses with --register"
            .into()
    } else {
        ". Estimate the scans' poses from their returns with --register".into()
    }
}

impl Run<'_> {
    /// The frame's scan, pose and time, or why it is skipped (counted).
    fn accept(&mut self, item: Result<Frame, BadFrame>) -> Option<Accepted> {
        match item {
            Err(bad) => {
                self.skipped.unreadable += 1;
                self.note(bad.message);
                None
            }
            Ok(f) => match (f.scan, f.pose, &mut self.registered) {
                // Registration read the same frames in the same order.
                (Some(scan), _, Some((poses, next))) => {
                    let pose = poses.get(*next).copied()?;
                    // The registration's reconstruction of this scan, when it kept one.
                    let drawn = self.drawn.get_mut(*next).and_then(Option::take);
                    *next += 1;
                    Some((scan, pose, f.t.unwrap_or(f.frame as f64), drawn))
                }
                (None, _, Some(_)) => {
                    self.skipped.no_beams += 1;
                    None
                }
                (_, None, None) => {
                    self.skipped.no_pose += 1;
                    None
                }
                (None, Some(_), None) => {
                    self.skipped.no_beams += 1;
                    None
                }
                (Some(scan), Some(pose), None) => {
                    Some((scan, pose, f.t.unwrap_or(f.frame as f64), None))
                }
            },
        }
    }

    fn note(&mut self, e: String) {
        if self.first_errors.len() < 5 {
            self.first_errors.push(e);
        }
    }

    /// Reconstructs the batch's scans in parallel, fuses them in order, and writes the
    /// outputs when `every` scans have come since the last write.
    fn fuse(&mut self, batch: &mut Vec<Accepted>) -> Result<()> {
        let t = Instant::now();
        // The process's CPU over each phase: the main thread waits for the batch, and
        // fuses alone.
        let cpu = cpu_time::ProcessTime::try_now().ok();
        let params = &self.params;
        let results: Vec<_> = batch
            .par_iter_mut()
            .map(|(scan, _, _, drawn)| match drawn.take() {
                Some(d) => Ok(d),
                None => isoline_core::reconstruct_scan(scan, params)
                    .map(|r| (r.polylines, r.noise_estimate)),
            })
            .collect();
        let reconstruct = t.elapsed().as_secs_f64();
        self.reconstruct_s += reconstruct;
        let cpu_elapsed = |c: Option<cpu_time::ProcessTime>| {
            c.and_then(|c| c.try_elapsed().ok())
                .map_or(0.0, |d| d.as_secs_f64())
        };
        let batch_cpu = cpu_elapsed(cpu);
        self.reconstruct_cpu_s += batch_cpu;
        let cpu = cpu_time::ProcessTime::try_now().ok();
        let each = 1e3 * batch_cpu / batch.len().max(1) as f64;
        let t = Instant::now();
        for ((scan, pose, time, _), r) in batch.drain(..).zip(results) {
            match r {
                Ok((polylines, noise)) => {
                    let t = Instant::now();
                    // With [map] align the pose the scan was fused at is the estimate.
                    let pose = match self.map.insert(&scan, pose, &polylines, noise) {
                        Ok(p) => p,
                        Err(e @ isoline_map::Error::PoseOutOfReach { .. }) => {
                            self.skipped.far += 1;
                            self.note(e.to_string());
                            continue;
                        }
                        Err(e) => return Err(e.into()),
                    };
                    self.block.fuse_ms += 1e3 * t.elapsed().as_secs_f64();
                    self.block.reconstruct_ms += each;
                    self.block.scans += 1;
                    if self.block.scans == BLOCK {
                        self.close_block();
                    }
                    self.poses.push([pose[0], pose[1]]);
                    self.placed.push((time, pose));
                    self.since_write += 1;
                }
                Err(e) => {
                    self.skipped.failed += 1;
                    self.note(e.to_string());
                }
            }
            if self.every > 0 && self.since_write >= self.every {
                self.since_write = 0;
                let curves = self.map.curves()?;
                write_all(self.outputs, &mut self.map, &curves, &self.poses)?;
            }
        }
        self.fuse_s += t.elapsed().as_secs_f64();
        self.fuse_cpu_s += cpu_elapsed(cpu);
        Ok(())
    }
}

impl Run<'_> {
    /// Ends the block of scans under way (sums become means a scan).
    fn close_block(&mut self) {
        let mut b = std::mem::take(&mut self.block);
        if b.scans == 0 {
            return;
        }
        b.reconstruct_ms /= b.scans as f64;
        b.fuse_ms /= b.scans as f64;
        let s = self.map.stats();
        (b.tiles_resident, b.tiles_stored) = (s.tiles_resident, s.tiles_stored);
        b.resident_bytes = memory("VmRSS:");
        self.blocks.push(b);
    }
}

fn progress(quiet: bool) -> indicatif::ProgressBar {
    use std::io::IsTerminal;
    // Off a terminal (a log file, a pipe) the bar draws nothing: `show` prints a plain
    // line now and then instead.
    if quiet || !std::io::stderr().is_terminal() {
        return indicatif::ProgressBar::hidden();
    }
    let b = indicatif::ProgressBar::new_spinner();
    b.set_style(
        indicatif::ProgressStyle::with_template("{spinner} {elapsed} {pos} frames {msg}")
            .expect("a valid template"),
    );
    b
}

/// Counts the frames of `input` on a thread of its own into `total`, so that the
/// progress shows a total and the time left without holding the run up (reading is a
/// small part of a frame's cost, and the thread uses a core the map leaves idle between
/// batches). A file it cannot read leaves the total unknown; the run reports why.
fn count_frames(
    input: &Path,
    bag: &isoline_io::bag::BagOptions,
    cap: usize,
    total: &Arc<OnceLock<u64>>,
) {
    let (input, bag, total) = (input.to_path_buf(), bag.clone(), Arc::clone(total));
    // Without the thread the progress shows no total, as before.
    let _ = std::thread::Builder::new()
        .name("count-frames".into())
        .spawn(move || {
            let mut n = 0u64;
            if isoline_io::for_each_item_capped(&input, &bag, cap, |_| {
                n += 1;
                true
            })
            .is_ok()
            {
                let _ = total.set(n);
            }
        });
}

fn show(bar: &indicatif::ProgressBar, run: &mut Run<'_>, start: Instant) {
    let s = run.map.stats();
    let k = &run.skipped;
    let read = s.scans + k.no_pose + k.no_beams + k.unreadable + k.failed + k.far;
    let total = run.total.get().copied();
    let message = format!(
        "({:.0}/s), {} tiles in memory ({:.0} MB), {} stored",
        s.scans as f64 / start.elapsed().as_secs_f64().max(1e-9),
        s.tiles_resident,
        s.bytes as f64 / 1e6,
        s.tiles_stored
    );
    if !bar.is_hidden() {
        if let (Some(n), None) = (total, bar.length()) {
            bar.set_length(n);
            bar.set_style(
                indicatif::ProgressStyle::with_template(
                    "{elapsed} {pos}/{len} frames, {eta} left {msg}",
                )
                .expect("a valid template"),
            );
        }
        bar.set_position(read);
        bar.set_message(message);
    } else if !run.quiet && run.last_line.elapsed() >= plain_every() {
        run.last_line = Instant::now();
        let elapsed = start.elapsed().as_secs_f64();
        let of = total.map_or(String::new(), |n| {
            let left = elapsed / read.max(1) as f64 * n.saturating_sub(read) as f64;
            format!(" of {n}, about {left:.0} s left")
        });
        eprintln!(
            "isoline map: {elapsed:.0} s, {read} frames read{of}, {} scans fused {message}",
            s.scans
        );
    }
}

/// How often `isoline map` says how far it is when stderr is not a terminal:
/// Ten seconds, or `$ISOLINE_PROGRESS_EVERY` seconds.
fn plain_every() -> std::time::Duration {
    let secs = std::env::var("ISOLINE_PROGRESS_EVERY")
        .ok()
        .and_then(|v| v.parse::<f64>().ok())
        .filter(|s| s.is_finite() && *s >= 0.0 && *s <= 1e6)
        .unwrap_or(10.0);
    std::time::Duration::from_secs_f64(secs)
}

/// Writes the map to every output, each atomically (a reader never sees half a map).
fn write_all(
    outputs: &[PathBuf],
    map: &mut Map,
    curves: &[Polyline],
    poses: &[Point],
) -> Result<()> {
    isoline_io::map_files::write_maps(outputs, map, curves, poses).context("writing the map")
}

/// The process's peak resident memory, bytes, where the system says (Linux).
fn peak_memory() -> Option<u64> {
    memory("VmHWM:")
}

/// A memory figure of `/proc/self/status` (`VmHWM:` the peak, `VmRSS:` now), bytes.
fn memory(field: &str) -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with(field))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

fn summary(
    input: &Path,
    run: &Run<'_>,
    stats: &MapStats,
    scores: &MapScores,
    wall: f64,
    cpu_s: Option<f64>,
    finish_s: f64,
) -> serde_json::Value {
    let n = stats.scans.max(1) as f64;
    let p = run.map.params();
    json!({
        "input": input.display().to_string(),
        "scans": stats.scans,
        "skipped": run.skipped,
        "errors": run.first_errors,
        "seconds": wall,
        "scans_per_s": stats.scans as f64 / wall,
        "cpu_ms_per_scan": cpu_s.map(|c| 1e3 * c / n),
        "ms_per_scan": {
            "reconstruct": 1e3 * run.reconstruct_s / n,
            "fuse": 1e3 * run.fuse_s / n,
            "finish": 1e3 * finish_s / n,
        },
        "cpu_ms_per_scan_by_phase": {
            "reconstruct": 1e3 * run.reconstruct_cpu_s / n,
            "fuse": 1e3 * run.fuse_cpu_s / n,
        },
        "peak_memory_bytes": peak_memory(),
        "blocks": run.blocks,
        "tiles": {
            "resident": stats.tiles_resident,
            "stored": stats.tiles_stored,
            "spills": stats.spills,
            "dropped": stats.tiles_dropped,
            "bytes_bound": p.memory_bound(),
        },
        "map": {
            "cell": p.cell, "tile": p.tile, "min_scans": p.min_scans,
            "max_weight": p.max_weight, "hit_tolerance": p.hit_tolerance,
            "max_range": p.max_range, "max_tiles": p.max_tiles,
            "max_stored_tiles": p.max_stored_tiles,
        },
        "scores": {
            "returns_scored": scores.returns_scored,
            "static_share": scores.static_share,
            "static_within": scores.static_within,
            "length": scores.length,
            "pieces": scores.pieces,
            "seen_through": scores.seen_through,
            "union_length": scores.union_length,
            "union_seen_through": scores.union_seen_through,
        },
    })
}
