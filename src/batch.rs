//! Batch jobs: many point files, reconstructed in parallel, with a summary.
//!
//! A job file is a configuration file (the `[mesh]`, `[solver]` and `[export]` tables the
//! other commands read) plus a `[batch]` table naming the inputs, the output folder and
//! the formats, and optional per-file overrides:
//!
//! ```toml
//! [batch]
//! inputs = ["scans/*.xy", "streams/*.ndjson", "bags/*.mcap"]  # relative to the job file
//! output = "out"                                 # relative to the job file
//! formats = ["ndjson", "svg"]                    # ndjson json geojson csv svg
//! workers = 2                                    # default: every core
//! topics = ["/scan"]                             # bags: LaserScan topics (default all)
//! odometry = "/odom"                             # bags: the poses' Odometry topic
//!
//! [solver]
//! alpha = 12.0
//!
//! [files."scans/noisy-*.xy".mesh]                # overrides for matching inputs
//! neighbours = 64
//! ```
//!
//! Everything is checked before any work starts. Files run in parallel on one rayon pool
//! of `workers` threads, and each file's own parallel loops run on that same pool, so the
//! machine is never oversubscribed. A file's failure, even a panic (a bug), is that
//! file's: the job goes on and reports it. Outputs are written through a temporary file
//! and a rename, and no output may be an input or a job summary; an input whose outputs
//! are all newer than it and than the job file, and that did not fail, is skipped, so an
//! interrupted job resumes where it stopped.

use std::path::{Path, PathBuf};
use std::time::{Instant, SystemTime};

use std::panic::{catch_unwind, AssertUnwindSafe};

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::config::Config;
use crate::error::{Error, Result};
use isoline_core::Params;
use isoline_io::reconstruct_frame;
use isoline_io::write::svg;
use isoline_io::write::{self as writers, Format};

/// The `[batch]` table.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct BatchTable {
    inputs: Vec<String>,
    output: String,
    #[serde(default)]
    formats: Option<Vec<String>>,
    #[serde(default)]
    workers: Option<usize>,
    #[serde(default)]
    topics: Vec<String>,
    #[serde(default)]
    odometry: Option<String>,
    #[serde(default)]
    world_frame: Option<String>,
}

/// One input of a job, with its parameters and outputs.
#[derive(Clone, Debug)]
pub struct Task {
    /// The input file.
    pub input: PathBuf,
    /// Its parameters (the job's, with the overrides of the patterns it matches).
    pub params: Params,
    /// Output path stem (`output/<file stem>`).
    pub stem: PathBuf,
}

/// A validated job.
#[derive(Clone, Debug)]
pub struct Job {
    /// The job file.
    pub path: PathBuf,
    /// The inputs, in a stable order.
    pub tasks: Vec<Task>,
    /// The output folder.
    pub output: PathBuf,
    /// Output formats.
    pub formats: Vec<Format>,
    /// Worker threads.
    pub workers: usize,
    /// What to read from bags (`topics`, `odometry`, `world_frame` in `[batch]`).
    pub bag: isoline_io::bag::BagOptions,
}

/// What became of one input.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct FileSummary {
    /// The input file.
    pub file: String,
    /// `ok`, `failed` or `skipped` (outputs up to date).
    pub status: String,
    /// Why it failed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
    /// Frames read.
    pub frames: usize,
    /// Points, over all frames.
    pub points: usize,
    /// Polylines, over all frames.
    pub polylines: usize,
    /// Mesh vertices (largest frame).
    pub vertices: usize,
    /// Solver iterations, over all frames.
    pub iterations: usize,
    /// Eq. 11 residual (largest frame).
    pub residual: f64,
    /// Wall time for this file, milliseconds.
    pub ms: f64,
}

/// The totals of a job.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Totals {
    /// Inputs.
    pub files: usize,
    /// Reconstructed now.
    pub ok: usize,
    /// Failed.
    pub failed: usize,
    /// Up to date, not redone.
    pub skipped: usize,
    /// Points, over the files reconstructed now.
    pub points: usize,
    /// Polylines, over the files reconstructed now.
    pub polylines: usize,
    /// Wall time of the whole job, milliseconds.
    pub ms: f64,
    /// Files reconstructed per second of wall time.
    pub files_per_second: f64,
}

/// `summary.json`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Summary {
    /// One entry per input.
    pub files: Vec<FileSummary>,
    /// Totals.
    pub totals: Totals,
}

fn config_error(path: &Path, problems: Vec<String>) -> Error {
    Error::Config {
        path: path.display().to_string(),
        problems,
    }
}

/// `a/b/../c` as `a/c`, lexically (for readable paths; the job's paths are not links).
fn normalize(p: &Path) -> PathBuf {
    use std::path::Component;
    let mut out = PathBuf::new();
    for c in p.components() {
        match c {
            Component::ParentDir
                if matches!(out.components().next_back(), Some(Component::Normal(_))) =>
            {
                out.pop();
            }
            Component::CurDir => {}
            other => out.push(other),
        }
    }
    if out.as_os_str().is_empty() {
        out.push(".");
    }
    out
}

/// Recursively lays `over` onto `base`: tables merge, other values replace.
fn merge(base: &mut toml::Table, over: &toml::Table) {
    for (k, v) in over {
        match (base.get_mut(k), v) {
            (Some(toml::Value::Table(b)), toml::Value::Table(o)) => merge(b, o),
            _ => {
                base.insert(k.clone(), v.clone());
            }
        }
    }
}

impl Job {
    /// Reads and validates a job file: the `[batch]` table, the shared tables and every
    /// override, the inputs (each glob must match a file) and the output names (two
    /// inputs may not share one). Every problem is listed at once, with its key path.
    // One function: one table after another, every problem collected before failing.
    pub fn load(path: &Path) -> Result<Job> {
        let text = std::fs::read_to_string(path).map_err(|e| isoline_io::Error::io(path, e))?;
        let mut table =
            crate::config::parse_table(&text).map_err(|e| config_error(path, vec![e]))?;
        let base_dir = path.parent().unwrap_or(Path::new(".")).to_path_buf();
        let mut problems = Vec::new();
        let batch = match table.remove("batch") {
            None => {
                return Err(config_error(
                    path,
                    vec!["missing table [batch] (inputs, output, formats, workers)".into()],
                ))
            }
            Some(v) => {
                let mut p = Vec::new();
                crate::config::read_value::<BatchTable>(v, "batch.", &mut p)
                    .ok_or_else(|| config_error(path, p))?
            }
        };
        let files = crate::config::take_table(&mut table, "files", &mut problems);
        let name = path.display().to_string();
        let base = match Config::from_table(table.clone(), &name, "").map_err(Error::from) {
            Ok(c) => Some(c),
            Err(Error::Config { problems: p, .. }) => {
                problems.extend(p);
                None
            }
            Err(e) => return Err(e),
        };
        // Overrides: each merged onto the shared tables and validated as a whole.
        let mut overrides: Vec<(glob::Pattern, Params)> = Vec::new();
        for (pat, over) in &files {
            let prefix = format!("files.\"{pat}\".");
            let full = normalize(&base_dir.join(pat));
            let pattern = match glob::Pattern::new(&full.to_string_lossy()) {
                Ok(p) => p,
                Err(e) => {
                    problems.push(format!("files.\"{pat}\": not a glob pattern: {e}"));
                    continue;
                }
            };
            let Some(over) = over.as_table() else {
                problems.push(format!("{prefix}: must be a table"));
                continue;
            };
            let mut merged = table.clone();
            merge(&mut merged, over);
            match Config::from_table(merged, &name, &prefix).map_err(Error::from) {
                Ok(c) => overrides.push((pattern, c.params())),
                Err(Error::Config { problems: p, .. }) => problems.extend(p),
                Err(e) => return Err(e),
            }
        }
        let formats: Vec<Format> = match &batch.formats {
            None => vec![Format::Ndjson, Format::Svg],
            Some(list) => list
                .iter()
                .filter_map(|f| {
                    let parsed = Format::from_path(Path::new(&format!("x.{f}")));
                    if parsed.is_none() {
                        problems.push(format!(
                            "batch.formats: unknown format {f:?} (allowed: ndjson, json, geojson, csv, svg)"
                        ));
                    }
                    parsed
                })
                .collect(),
        };
        if batch.formats.as_ref().is_some_and(|f| f.is_empty()) {
            problems.push("batch.formats: empty (allowed: ndjson, json, geojson, csv, svg)".into());
        }
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        let workers = batch.workers.unwrap_or(cores);
        if !(1..=256).contains(&workers) {
            problems.push(format!("batch.workers = {workers}: must be in 1..=256"));
        }
        if batch.inputs.is_empty() {
            problems.push("batch.inputs: empty (list globs of point or NDJSON files)".into());
        }
        let output = normalize(&base_dir.join(&batch.output));
        let mut inputs: Vec<PathBuf> = Vec::new();
        for pat in &batch.inputs {
            let full = normalize(&base_dir.join(pat));
            match glob::glob(&full.to_string_lossy()) {
                Err(e) => problems.push(format!("batch.inputs: {pat:?} is not a glob: {e}")),
                Ok(paths) => {
                    let found: Vec<PathBuf> = paths
                        .filter_map(|p| p.ok())
                        .filter(|p| p.is_file())
                        .collect();
                    if found.is_empty() {
                        problems.push(format!("batch.inputs: {pat:?} matches no file"));
                    }
                    inputs.extend(found);
                }
            }
        }
        inputs.sort();
        inputs.dedup();
        let mut tasks: Vec<Task> = Vec::new();
        let mut seen = std::collections::HashMap::new();
        for input in inputs {
            let stem = input.file_stem().unwrap_or_default().to_os_string();
            if let Some(other) = seen.insert(stem.clone(), input.clone()) {
                problems.push(format!(
                    "batch.inputs: {} and {} would write the same outputs ({})",
                    other.display(),
                    input.display(),
                    stem.to_string_lossy()
                ));
            }
            // Override patterns, like inputs, are relative to the job file.
            let mut params = base.as_ref().map(|c| c.params()).unwrap_or_default();
            for (pat, p) in &overrides {
                if pat.matches_path(&input) {
                    params = p.clone();
                }
            }
            tasks.push(Task {
                stem: output.join(&stem),
                input,
                params,
            });
        }
        let job = Job {
            path: path.to_path_buf(),
            tasks,
            output,
            formats,
            workers,
            bag: isoline_io::bag::BagOptions {
                topics: batch.topics.clone(),
                odometry: batch.odometry.clone(),
                world_frame: batch.world_frame.clone(),
            },
        };
        problems.extend(job.collisions());
        if !problems.is_empty() {
            return Err(config_error(path, problems));
        }
        Ok(job)
    }

    /// Outputs that would overwrite an input or a job summary.
    fn collisions(&self) -> Vec<String> {
        let inputs: std::collections::HashMap<PathBuf, &Path> = self
            .tasks
            .iter()
            .filter_map(|t| crate::files::identity(&t.input).map(|id| (id, t.input.as_path())))
            .collect();
        let summaries = [SUMMARY_JSON, SUMMARY_CSV].map(|n| self.output.join(n));
        let mut problems = Vec::new();
        for t in &self.tasks {
            let mut outs = self.outputs(t);
            if self.formats.contains(&Format::Svg) {
                outs.push(frames_dir(t));
            }
            for out in outs {
                if let Some(input) = crate::files::identity(&out).and_then(|id| inputs.get(&id)) {
                    problems.push(format!(
                        "batch.output: {} would overwrite the input {} (choose another output \
                         folder)",
                        out.display(),
                        input.display()
                    ));
                } else if summaries.contains(&out) {
                    problems.push(format!(
                        "batch.inputs: the results of {} would overwrite the job's {} \
                         (rename the input)",
                        t.input.display(),
                        out.display()
                    ));
                }
            }
        }
        problems
    }

    /// The output files of `task`. SVG drawings hold one frame each: `<stem>.svg` draws
    /// the first, and an input of several frames also gets one drawing per frame in
    /// `<stem>-frames/`.
    pub fn outputs(&self, task: &Task) -> Vec<PathBuf> {
        self.formats
            .iter()
            .map(|f| {
                let mut p = task.stem.clone().into_os_string();
                p.push(".");
                p.push(f.extension());
                PathBuf::from(p)
            })
            .collect()
    }

    /// Whether `task` can be skipped: every output is newer than its input and the job
    /// file, and the last run did not fail on it (by the last `summary.json`, and by
    /// the error records of its NDJSON output).
    pub fn up_to_date(&self, task: &Task) -> bool {
        self.outputs_newer(task) && !self.failed_before(task)
    }

    fn failed_before(&self, task: &Task) -> bool {
        let file = task.input.display().to_string();
        let summary = std::fs::read_to_string(self.output.join(SUMMARY_JSON))
            .ok()
            .and_then(|t| serde_json::from_str::<Summary>(&t).ok());
        if let Some(s) = summary {
            if s.files
                .iter()
                .any(|f| f.file == file && f.status == "failed")
            {
                return true;
            }
        }
        self.previous_records(task)
            .is_some_and(|recs| recs.iter().any(|r| r.error.is_some()))
    }

    /// The records of the NDJSON output of `task`, if it has one.
    fn previous_records(&self, task: &Task) -> Option<Vec<isoline_io::format::ResultRecord>> {
        let ndjson = self
            .outputs(task)
            .into_iter()
            .find(|p| p.extension().is_some_and(|e| e == "ndjson"))?;
        let text = std::fs::read_to_string(ndjson).ok()?;
        Some(
            text.lines()
                .filter_map(|l| serde_json::from_str(l).ok())
                .collect(),
        )
    }

    fn outputs_newer(&self, task: &Task) -> bool {
        let mtime = |p: &Path| std::fs::metadata(p).and_then(|m| m.modified()).ok();
        let Some(newest_source) = [mtime(&task.input), mtime(&self.path)]
            .into_iter()
            .collect::<Option<Vec<SystemTime>>>()
            .and_then(|v| v.into_iter().max())
        else {
            return false;
        };
        self.outputs(task)
            .iter()
            .all(|o| mtime(o).is_some_and(|t| t >= newest_source))
    }

    /// Runs the job: every input in parallel on a pool of `workers` threads (the inputs
    /// that are up to date are skipped unless `force`), calling `progress` once per input
    /// as it finishes. Writes `summary.json` and `summary.csv` into the output folder.
    pub fn run(&self, force: bool, progress: impl Fn(&FileSummary) + Sync) -> Result<Summary> {
        self.run_with(force, progress, |task| self.process(task))
    }

    /// [`Job::run`] with `process` making each file's summary; a panic in it fails that
    /// file only.
    fn run_with(
        &self,
        force: bool,
        progress: impl Fn(&FileSummary) + Sync,
        process: impl Fn(&Task) -> FileSummary + Sync,
    ) -> Result<Summary> {
        std::fs::create_dir_all(&self.output)
            .map_err(|e| isoline_io::Error::io(&self.output, e))?;
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(self.workers)
            .build()
            .map_err(|e| Error::Internal(format!("thread pool: {e}")))?;
        let t0 = Instant::now();
        let files: Vec<FileSummary> = pool.install(|| {
            self.tasks
                .par_iter()
                .map(|task| {
                    let s = if !force && self.up_to_date(task) {
                        self.skipped(task)
                    } else {
                        let t0 = Instant::now();
                        catch_unwind(AssertUnwindSafe(|| process(task))).unwrap_or_else(|p| {
                            let what = p
                                .downcast_ref::<&str>()
                                .map(|s| s.to_string())
                                .or_else(|| p.downcast_ref::<String>().cloned())
                                .unwrap_or_else(|| "unknown panic".into());
                            tracing::error!(file = %task.input.display(), %what, "panicked");
                            FileSummary {
                                file: task.input.display().to_string(),
                                status: "failed".into(),
                                reason: Some(format!("internal error (a bug in isoline): {what}")),
                                ms: t0.elapsed().as_secs_f64() * 1e3,
                                ..Default::default()
                            }
                        })
                    };
                    progress(&s);
                    s
                })
                .collect()
        });
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        let count = |st: &str| files.iter().filter(|f| f.status == st).count();
        let done: Vec<&FileSummary> = files.iter().filter(|f| f.status == "ok").collect();
        let totals = Totals {
            files: files.len(),
            ok: done.len(),
            failed: count("failed"),
            skipped: count("skipped"),
            points: done.iter().map(|f| f.points).sum(),
            polylines: done.iter().map(|f| f.polylines).sum(),
            ms,
            files_per_second: if ms > 0.0 {
                done.len() as f64 / (ms / 1e3)
            } else {
                0.0
            },
        };
        let summary = Summary { files, totals };
        let json = serde_json::to_string_pretty(&summary).expect("summary serialises") + "\n";
        let path = self.output.join(SUMMARY_JSON);
        writers::write_atomic(&path, json.as_bytes())
            .map_err(|e| isoline_io::Error::io(&path, e))?;
        let path = self.output.join(SUMMARY_CSV);
        writers::write_atomic(&path, summary_csv(&summary).as_bytes())
            .map_err(|e| isoline_io::Error::io(&path, e))?;
        Ok(summary)
    }

    /// The summary of an up-to-date input: the counts of the run that made its outputs
    /// (from the last `summary.json`, else from its NDJSON records), its status
    /// `skipped`, its time this run's (none).
    fn skipped(&self, task: &Task) -> FileSummary {
        let file = task.input.display().to_string();
        let before = std::fs::read_to_string(self.output.join(SUMMARY_JSON))
            .ok()
            .and_then(|t| serde_json::from_str::<Summary>(&t).ok())
            .and_then(|s| {
                s.files
                    .into_iter()
                    .find(|f| f.file == file && f.status != "failed")
            });
        let mut s = match before {
            Some(f) => FileSummary {
                status: "skipped".into(),
                reason: None,
                ms: 0.0,
                ..f
            },
            None => {
                let mut s = FileSummary {
                    file,
                    status: "skipped".into(),
                    ..Default::default()
                };
                for r in self.previous_records(task).iter().flatten() {
                    tally(&mut s, r);
                }
                s
            }
        };
        s.ms = 0.0;
        s
    }

    /// Reconstructs every frame of one input and writes its outputs, each record as its
    /// frame is done (one frame held at a time); a file that cannot be read to its end
    /// keeps the outputs of the frames before the damage and fails.
    // One function: one input's frames through one read, reconstruct and write loop.
    fn process(&self, task: &Task) -> FileSummary {
        let t0 = Instant::now();
        let _span = tracing::info_span!("file", file = %task.input.display()).entered();
        let mut s = FileSummary {
            file: task.input.display().to_string(),
            status: "ok".into(),
            ..Default::default()
        };
        let fail = |mut s: FileSummary, reason: String| {
            s.status = "failed".into();
            s.reason = Some(reason);
            s.ms = t0.elapsed().as_secs_f64() * 1e3;
            s
        };
        let mut outputs = match Outputs::create(&self.formats, self.outputs(task), frames_dir(task))
        {
            Ok(o) => o,
            Err(e) => return fail(s, e),
        };
        let numbered = isoline_io::is_frame_stream(&task.input)
            || isoline_io::is_recording(&task.input)
            || isoline_io::is_compressed_frame_stream(&task.input);
        let (mut errors, mut failed) = (Vec::new(), 0usize);
        let mut stopped = None;
        let read = isoline_io::for_each_item(&task.input, &self.bag, |item| {
            let (rec, drawing) = match &item {
                Ok(f) => {
                    let (rec, r) = reconstruct_frame(f, &task.params);
                    let drawing = r.filter(|_| self.formats.contains(&Format::Svg)).map(|r| {
                        let features: Vec<_> = r.features.iter().map(|f| f.center).collect();
                        svg::render(
                            &svg::of_reconstruction(&f.points, &r, &features, &[], false),
                            1200.0,
                        )
                    });
                    (rec, drawing.map(|d| (f.frame, d)))
                }
                Err(b) => (
                    isoline_io::format::ResultRecord {
                        stream: b.stream.clone(),
                        frame: b.frame,
                        error: Some(b.message.clone()),
                        ..Default::default()
                    },
                    None,
                ),
            };
            tally(&mut s, &rec);
            if let Some(e) = &rec.error {
                failed += 1;
                // The first few say what went wrong; the count says how often.
                if errors.len() < MAX_REASONS {
                    errors.push(match rec.frame {
                        Some(k) if numbered => format!("frame {k}: {e}"),
                        _ => e.clone(),
                    });
                }
            }
            match outputs.push(&rec, drawing) {
                Ok(()) => true,
                Err(e) => {
                    stopped = Some(e);
                    false
                }
            }
        });
        if let Some(e) = stopped {
            return fail(s, e);
        }
        if s.frames == 0 {
            return fail(
                s,
                match read {
                    Err(e) => e.to_string(),
                    Ok(()) => "empty: no points and no frames".into(),
                },
            );
        }
        if let Err(e) = outputs.finish() {
            return fail(s, e);
        }
        if let Err(e) = read {
            let n = s.frames;
            return fail(
                s,
                format!("read {n} frames (their outputs are written), then: {e}"),
            );
        }
        if failed > 0 {
            let more = failed - errors.len();
            let mut reason = errors.join("; ");
            if more > 0 {
                reason += &format!("; and {more} more");
            }
            if failed < s.frames {
                reason = format!("{failed} of {} frames failed: {reason}", s.frames);
            }
            return fail(s, reason);
        }
        s.ms = t0.elapsed().as_secs_f64() * 1e3;
        s
    }
}

/// The failed frames a summary names by their error; the others it counts.
const MAX_REASONS: usize = 20;

/// One input's outputs, written as its frames are done.
struct Outputs {
    /// The text formats' writers, each to a temporary file renamed into place at the end.
    records: Vec<(
        writers::RecordWriter<std::io::BufWriter<std::fs::File>>,
        writers::PartFile,
        PathBuf,
    )>,
    /// Where the first frame's drawing goes, with SVG among the formats.
    svg: Option<PathBuf>,
    /// The folder of each frame's drawing, for an input of several frames.
    dir: PathBuf,
    /// The first frame's drawing, until a second frame says there are several.
    first: Option<(u64, String)>,
    frames: usize,
}

impl Outputs {
    /// Creates every output before the first frame: an unwritable path fails the input
    /// before the work.
    fn create(
        formats: &[Format],
        paths: Vec<PathBuf>,
        dir: PathBuf,
    ) -> std::result::Result<Outputs, String> {
        let mut o = Outputs {
            records: Vec::new(),
            svg: None,
            dir,
            first: None,
            frames: 0,
        };
        for (format, out) in formats.iter().zip(paths) {
            let writing = |e: std::io::Error| format!("writing {}: {e}", out.display());
            if *format == Format::Svg {
                o.svg = Some(out);
                continue;
            }
            let (part, file) = writers::PartFile::create(&out).map_err(writing)?;
            let w = writers::RecordWriter::new(*format, std::io::BufWriter::new(file))
                .map_err(writing)?;
            o.records.push((w, part, out));
        }
        Ok(o)
    }

    fn push(
        &mut self,
        rec: &isoline_io::format::ResultRecord,
        drawing: Option<(u64, String)>,
    ) -> std::result::Result<(), String> {
        self.frames += 1;
        for (w, _, out) in &mut self.records {
            w.push(rec)
                .map_err(|e| format!("writing {}: {e}", out.display()))?;
        }
        let in_dir = |k: u64, doc: &str| -> std::result::Result<(), String> {
            let path = self.dir.join(format!("frame-{k:06}.svg"));
            std::fs::create_dir_all(&self.dir)
                .and_then(|()| writers::write_atomic(&path, doc.as_bytes()))
                .map_err(|e| format!("writing {}: {e}", path.display()))
        };
        // A second frame says there are several: the first one's drawing joins the
        // folder.
        if self.frames == 2 {
            if let Some((k0, first)) = &self.first {
                in_dir(*k0, first)?;
            }
        }
        let Some((k, doc)) = drawing else {
            return Ok(());
        };
        if self.frames > 1 {
            in_dir(k, &doc)?;
        }
        // The first drawing is also the input's own.
        if self.first.is_none() {
            self.first = Some((k, doc));
        }
        Ok(())
    }

    fn finish(self) -> std::result::Result<(), String> {
        for (w, part, out) in self.records {
            let writing = |e: std::io::Error| format!("writing {}: {e}", out.display());
            drop(w.finish().map_err(writing)?);
            part.commit().map_err(writing)?;
        }
        if let (Some(path), Some((_, doc))) = (self.svg, self.first) {
            writers::write_atomic(&path, doc.as_bytes())
                .map_err(|e| format!("writing {}: {e}", path.display()))?;
        }
        Ok(())
    }
}

/// The job summaries in the output folder.
const SUMMARY_JSON: &str = "summary.json";
/// See [`SUMMARY_JSON`].
const SUMMARY_CSV: &str = "summary.csv";

/// The folder of per-frame drawings of a multi-frame input: `<stem>-frames`.
fn frames_dir(task: &Task) -> PathBuf {
    let mut p = task.stem.clone().into_os_string();
    p.push("-frames");
    PathBuf::from(p)
}

/// Adds one record's stats to `s`.
fn tally(s: &mut FileSummary, r: &isoline_io::format::ResultRecord) {
    s.frames += 1;
    s.polylines += r.polylines.as_ref().map_or(0, |p| p.len());
    if let Some(st) = &r.stats {
        s.points += st.points;
        s.vertices = s.vertices.max(st.vertices);
        s.iterations += st.iterations;
        s.residual = s.residual.max(st.residual);
    }
}

/// `summary.csv`: one row per input, then a `TOTAL` row.
pub fn summary_csv(s: &Summary) -> String {
    let mut out = String::from(
        "file,status,frames,points,polylines,vertices,iterations,residual,ms,reason\n",
    );
    let quote = |t: &str| format!("\"{}\"", t.replace('"', "\"\""));
    for f in &s.files {
        out += &format!(
            "{},{},{},{},{},{},{},{},{:.1},{}\n",
            quote(&f.file),
            f.status,
            f.frames,
            f.points,
            f.polylines,
            f.vertices,
            f.iterations,
            f.residual,
            f.ms,
            quote(f.reason.as_deref().unwrap_or(""))
        );
    }
    let t = &s.totals;
    out += &format!(
        "TOTAL,{} ok / {} failed / {} skipped,,{},{},,,,{:.1},\n",
        t.ok, t.failed, t.skipped, t.points, t.polylines, t.ms
    );
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn job_files_are_validated_with_key_paths_before_any_work() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("a.xy"), "0 0\n1 0\n0 1\n").unwrap();
        let job = dir.path().join("job.toml");
        std::fs::write(
            &job,
            concat!(
                "[batch]\ninputs = [\"*.xy\", \"nothing/*.xy\"]\noutput = \"out\"\n",
                "formats = [\"ndjson\", \"pdf\"]\nworkers = 0\n",
                "[mesh]\nhmin = -1\n",
                "[files.\"a*\".solver]\ncfl = 3\n",
            ),
        )
        .unwrap();
        let e = Job::load(&job).unwrap_err().to_string();
        for needle in [
            "nothing/*.xy\" matches no file",
            "unknown format \"pdf\"",
            "batch.workers = 0: must be in 1..=256",
            "mesh.hmin = -1",
            "files.\"a*\".solver.cfl = 3: must be in (0, 1]",
        ] {
            assert!(e.contains(needle), "{needle:?} not in {e}");
        }
        let head = "[batch]\ninputs = [\"*.xy\"]\noutput = \"out\"\n";
        for (tail, needle) in [
            ("workrs = 2\n", "workrs"),
            ("workers = \"two\"\n", "batch.workers: invalid type"),
            (
                "[files.\"*.xy\".mesh]\nhmin = \"x\"\n",
                "files.\"*.xy\".mesh.hmin: invalid type",
            ),
        ] {
            std::fs::write(&job, format!("{head}{tail}")).unwrap();
            let e = Job::load(&job).unwrap_err().to_string();
            assert!(e.contains(needle), "{needle:?} not in {e}");
        }
        std::fs::write(
            &job,
            "[batch]\ninputs = [\"*.xy\"]\noutput = \"out\"\n[files.\"a*\".solver]\nalpha = 5.0\n",
        )
        .unwrap();
        let j = Job::load(&job).unwrap();
        assert_eq!(j.tasks.len(), 1);
        assert_eq!(j.tasks[0].params.solver.alpha, Some(5.0));
        assert_eq!(j.formats, vec![Format::Ndjson, Format::Svg]);
    }

    fn job_in(dir: &Path, text: &str) -> Result<Job> {
        let job = dir.join("job.toml");
        std::fs::write(&job, text).unwrap();
        Job::load(&job)
    }

    #[test]
    fn no_output_may_overwrite_an_input_or_a_summary() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let frame = r#"{"frame":1,"points":[[0,0],[1,0],[0,1]]}"#;
        std::fs::write(d.join("a.ndjson"), format!("{frame}\n")).unwrap();
        // Results into the input folder: a.ndjson would be replaced by its own results.
        let e = job_in(d, "[batch]\ninputs = [\"*.ndjson\"]\noutput = \".\"\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("would overwrite the input"), "{e}");
        assert_eq!(
            std::fs::read_to_string(d.join("a.ndjson")).unwrap(),
            format!("{frame}\n")
        );
        // Through another spelling of the same folder, too.
        std::fs::create_dir(d.join("sub")).unwrap();
        let e = job_in(d, "[batch]\ninputs = [\"*.ndjson\"]\noutput = \"sub/..\"\n");
        assert!(e.is_err());
        // An input called summary would write over the job summary.
        std::fs::write(d.join("sub/summary.xy"), "0 0\n1 0\n0 1\n").unwrap();
        let e = job_in(
            d,
            "[batch]\ninputs = [\"sub/*.xy\"]\noutput = \"out\"\nformats = [\"json\"]\n",
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("summary.json") && e.contains("rename the input"),
            "{e}"
        );
        // A multi-frame drawing folder and another input's drawing do not meet.
        std::fs::write(d.join("sub/a-1.xy"), "0 0\n1 0\n0 1\n").unwrap();
        std::fs::remove_file(d.join("sub/summary.xy")).unwrap();
        let j = job_in(
            d,
            "[batch]\ninputs = [\"*.ndjson\", \"sub/*.xy\"]\noutput = \"out\"\n",
        )
        .unwrap();
        assert_eq!(j.tasks.len(), 2);
    }

    #[test]
    fn a_panicking_file_fails_alone() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        for name in ["a", "b", "c"] {
            std::fs::write(d.join(format!("{name}.xy")), "0 0\n1 0\n0 1\n").unwrap();
        }
        let j = job_in(
            d,
            "[batch]\ninputs = [\"*.xy\"]\noutput = \"out\"\nworkers = 2\n",
        )
        .unwrap();
        let hook = std::panic::take_hook();
        std::panic::set_hook(Box::new(|_| {}));
        let s = j.run_with(
            true,
            |_| {},
            |t| {
                assert!(!t.input.ends_with("b.xy"), "b is cursed");
                FileSummary {
                    file: t.input.display().to_string(),
                    status: "ok".into(),
                    ..Default::default()
                }
            },
        );
        std::panic::set_hook(hook);
        let s = s.unwrap();
        assert_eq!((s.totals.ok, s.totals.failed), (2, 1));
        let b = s.files.iter().find(|f| f.file.ends_with("b.xy")).unwrap();
        assert!(
            b.reason.as_deref().unwrap().contains("b is cursed"),
            "{b:?}"
        );
        assert!(d.join("out/summary.json").is_file());
    }

    #[test]
    fn a_rerun_retries_a_file_whose_frame_failed() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let good = (0..40)
            .map(|i| {
                let a = f64::from(i) * std::f64::consts::TAU / 40.0;
                format!("[{},{}]", a.cos(), a.sin())
            })
            .collect::<Vec<_>>()
            .join(",");
        std::fs::write(
            d.join("s.ndjson"),
            format!("{{\"frame\":1,\"points\":[{good}]}}\n{{\"frame\":2,\"points\":[[0,0]]}}\n"),
        )
        .unwrap();
        let j = job_in(d, "[batch]\ninputs = [\"*.ndjson\"]\noutput = \"out\"\n").unwrap();
        let first = j.run(false, |_| {}).unwrap();
        assert_eq!(first.totals.failed, 1, "{first:?}");
        // Its outputs are newer than the input, but they hold a failure: not skipped.
        assert!(!j.up_to_date(&j.tasks[0]));
        let again = j.run(false, |_| {}).unwrap();
        assert_eq!((again.totals.failed, again.totals.skipped), (1, 0));
        assert!(d.join("out/s-frames/frame-000001.svg").is_file());
    }
}
