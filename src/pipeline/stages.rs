//! The stage threads: each receives frames, calls the plain stage function of
//! [`mod@crate::reconstruct`] under a span named after the stage (with the stream, frame and
//! queue depth), and sends the frame on.

use std::collections::hash_map::Entry;
use std::collections::HashMap;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crossbeam_channel::{Receiver, RecvTimeoutError, Sender};
use hdrhistogram::Histogram;

use super::config::Policy;
use super::ledger::{Leases, Receipt};
use super::metrics::{Counted, Metrics};
use super::sink::Sink;
use super::source::Line;
use super::spawn;
use super::RunSummary;
use crate::error::Result;
use isoline_core::geom::{Point, Pose};
use isoline_core::stages::{self as reconstruct, Prepared};
use isoline_core::stages::{AdaptedMesh, LevelSet, LevelSetMemory, MeshMemory, Solved};
use isoline_core::Params;
use isoline_core::Reconstruction;
use isoline_io::format::ResultRecord;
use isoline_map::{RegisterParams, Registrar};
use isoline_map::{Window, WindowLimits};

/// A frame on its way through the stages.
pub(crate) struct Msg {
    /// Stream id as in the input (or the TCP client's).
    stream: Option<String>,
    /// `None` only for a failed line whose frame number could not be read.
    frame: Option<u64>,
    /// The input line, for error records.
    line: u64,
    /// Where the frame's coordinates sit in the world, when the frame says.
    pose: Option<Pose>,
    /// The pose registration estimated (`[pipeline] register`): where refinement and
    /// the map place the frame.
    registered: Option<Pose>,
    /// The frame's time stamp, when it has one.
    t: Option<f64>,
    arrived: Instant,
    /// A Kafka frame's claim on its offset, handed in once its record is written.
    receipt: Option<Receipt>,
    /// The frame's beams, kept past the distance stage for the map (when it is on and
    /// the frame has a pose).
    scan: Option<Box<isoline_core::Scan>>,
    /// What the reader did to the frame's readings, for the record's warnings.
    notes: Vec<String>,
    work: Work,
}

impl Msg {
    /// The key of the stream's state.
    fn key(&self) -> &str {
        self.stream.as_deref().unwrap_or("")
    }
    fn live(&self) -> bool {
        !matches!(self.work, Work::Failed(_) | Work::Skipped)
    }
    /// The frame number of a live frame (live frames always have one).
    fn number(&self) -> u64 {
        self.frame.unwrap_or(0)
    }
    /// The lease of the Kafka partition the frame came from.
    fn lease(&self) -> Option<u64> {
        self.receipt.as_ref().map(Receipt::lease)
    }
}

/// The bounds of the per-stream state every stage keeps.
#[derive(Clone, Debug)]
pub(crate) struct StreamBounds {
    /// Streams kept at most.
    pub(crate) max: usize,
    /// A stream not seen for this long is forgotten.
    pub(crate) idle: Duration,
    /// Kafka input: the partitions held. The state of a stream whose partition has
    /// been given up is forgotten.
    pub(crate) leases: Option<Arc<Leases>>,
}

/// Per-stream state of a stage, bounded in number and age: a stream not seen for
/// `idle` is forgotten, and so is the least recently seen one when a new stream would
/// make more than `max`. With Kafka input, each state is kept under the lease of its
/// partition: it is forgotten once that partition is given up, and not used for a
/// frame under another lease. A forgotten stream's next frame starts cold.
pub(crate) struct Streams<V> {
    map: HashMap<String, (Instant, Option<u64>, V)>,
    bounds: StreamBounds,
    /// Streams forgotten so far.
    pub(crate) forgotten: u64,
}

impl<V> Streams<V> {
    pub(crate) fn new(bounds: &StreamBounds) -> Self {
        Streams {
            map: HashMap::new(),
            bounds: StreamBounds {
                max: bounds.max.max(1),
                ..bounds.clone()
            },
            forgotten: 0,
        }
    }

    #[cfg(test)]
    pub(crate) fn len(&self) -> usize {
        self.map.len()
    }

    pub(crate) fn get(&self, key: &str) -> Option<&V> {
        self.map.get(key).map(|(_, _, v)| v)
    }

    /// The state without marking the stream as seen.
    pub(crate) fn peek_mut(&mut self, key: &str) -> Option<&mut V> {
        self.map.get_mut(key).map(|(_, _, v)| v)
    }

    /// The state of `key` under `lease`, seen at `now`: created with `make` if absent
    /// or kept under another lease. First forgets idle streams, those of partitions
    /// given up and, if the table is full, the least recently seen one; only states
    /// that `may_forget` allows (the solve stage keeps streams with level sets in flight).
    pub(crate) fn seen(
        &mut self,
        key: &str,
        lease: Option<u64>,
        now: Instant,
        may_forget: impl Fn(&V) -> bool,
        make: impl FnOnce() -> V,
    ) -> &mut V {
        let before = self.map.len();
        let idle = self.bounds.idle;
        let leases = self.bounds.leases.as_deref();
        let held = |l: &Option<u64>| match (l, leases) {
            (Some(l), Some(leases)) => leases.is_live(*l),
            _ => true,
        };
        self.map.retain(|k, (t, l, v)| {
            let fresh = if k == key {
                *l == lease
            } else {
                now.saturating_duration_since(*t) <= idle && held(l)
            };
            fresh || !may_forget(v)
        });
        if !self.map.contains_key(key) && self.map.len() >= self.bounds.max {
            let oldest = self
                .map
                .iter()
                .filter(|(_, (_, _, v))| may_forget(v))
                .min_by_key(|(_, (t, _, _))| *t)
                .map(|(k, _)| k.clone());
            if let Some(k) = oldest {
                self.map.remove(&k);
            }
        }
        let gone = before - self.map.len();
        if gone > 0 {
            self.forgotten += gone as u64;
            tracing::info!(forgotten = gone, kept = self.map.len(), "streams forgotten");
        }
        let entry = match self.map.entry(key.to_string()) {
            // Kept under another lease only because `may_forget` refused: start afresh.
            Entry::Occupied(mut o) if o.get().1 != lease => {
                o.insert((now, lease, make()));
                o.into_mut()
            }
            Entry::Occupied(o) => o.into_mut(),
            Entry::Vacant(v) => v.insert((now, lease, make())),
        };
        entry.0 = now;
        &mut entry.2
    }
}

/// What has been made of a frame so far.
enum Work {
    Input(Box<isoline_io::Frame>),
    Prepared(Box<Prepared>),
    Adapted(Box<(Prepared, AdaptedMesh)>),
    Solved(Box<(Prepared, AdaptedMesh, Solved)>),
    /// In the export stage only: the reconstruction and the frame's points (for drawing).
    Exported(Box<isoline_core::Reconstruction>, Vec<Point>),
    Failed(String),
    Skipped,
}

/// The renormalized level set of a stream's last frame, sent back to the solve stage.
pub(crate) struct Feedback {
    key: String,
    level_set: Option<(LevelSet, Option<Pose>)>,
}

/// Under [`Policy::Latest`], takes everything waiting in `rx` behind `first` and marks
/// every live frame that has a newer live frame of its stream behind it as skipped; the
/// order is kept. Under [`Policy::Block`], just `first`.
pub(crate) fn take_batch(first: Msg, rx: &Receiver<Msg>, policy: Policy) -> Vec<Msg> {
    let mut batch = vec![first];
    if policy == Policy::Latest {
        batch.extend(rx.try_iter());
        mark_stale(&mut batch);
    }
    batch
}

/// Marks as skipped every live frame followed by a newer live frame of its stream.
fn mark_stale(batch: &mut [Msg]) {
    let mut newest: HashMap<&str, usize> = HashMap::new();
    for (i, m) in batch.iter().enumerate() {
        if m.live() {
            newest.insert(m.key(), i);
        }
    }
    let stale: Vec<usize> = batch
        .iter()
        .enumerate()
        .filter(|(i, m)| m.live() && newest[m.key()] != *i)
        .map(|(i, _)| i)
        .collect();
    for i in stale {
        batch[i].work = Work::Skipped;
    }
}

macro_rules! stage_span {
    ($name:literal, $m:expr, $depth:expr) => {
        tracing::info_span!($name, stream = $m.key(), frame = $m.frame, queue = $depth)
    };
}

/// Makes the calling stage thread the only worker of its own rayon pool, so that the
/// stage's parallel loops run on it: with as many busy stages as cores, per-stage
/// parallelism only adds hand-offs and spinning between stages that compete for them.
fn own_pool() {
    let built = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .use_current_thread()
        .build();
    match built {
        // The pool lives as long as the thread.
        Ok(pool) => std::mem::forget(pool),
        Err(e) => tracing::warn!(error = %e, "no per-stage pool: using the global one"),
    }
}

/// Runs `f` on every live frame of `rx` (under `policy`) and sends the results to `tx`;
/// failed and skipped frames pass through. A panic in `f` (a bug, not bad input) fails
/// that frame only: it gets an error record and the stream goes on. Ends when `rx`
/// closes or `tx` does.
fn run_stage(
    name: &str,
    rx: Receiver<Msg>,
    tx: Sender<Msg>,
    policy: Policy,
    metrics: &Metrics,
    span: impl Fn(&Msg, usize) -> tracing::Span,
    mut f: impl FnMut(&mut Msg),
) {
    own_pool();
    let depth = metrics.queue_depth.with_label_values(&[name]);
    let seconds = metrics.stage_seconds.with_label_values(&[name]);
    while let Ok(first) = rx.recv() {
        depth.set(rx.len() as i64);
        for mut m in take_batch(first, &rx, policy) {
            if m.live() {
                let s = span(&m, rx.len());
                let _e = s.enter();
                let t0 = Instant::now();
                if let Err(panic) = catch_unwind(AssertUnwindSafe(|| f(&mut m))) {
                    m.work = Work::Failed(internal_error(name, panic.as_ref()));
                }
                seconds.observe(t0.elapsed().as_secs_f64());
            }
            if tx.send(m).is_err() {
                return;
            }
        }
    }
}

/// The record text of a frame whose stage panicked.
fn internal_error(stage: &str, panic: &(dyn std::any::Any + Send)) -> String {
    let what = panic
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| panic.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown panic".into());
    tracing::error!(stage, %what, "a stage panicked on a frame");
    format!("internal error in the {stage} stage (a bug in isoline): {what}")
}

/// Ingest: parses lines into frames; a line that is not a frame becomes a failed frame
/// carrying the error. On `stop`, it takes what the sources have already read and ends,
/// which closes the pipeline behind it.
pub(crate) fn spawn_ingest(
    rx: Receiver<Line>,
    tx: Sender<Msg>,
    stop: Arc<AtomicBool>,
    poll: Duration,
    time_increment: Option<f64>,
    metrics: Arc<Metrics>,
) -> Result<JoinHandle<()>> {
    spawn("ingest", move || {
        let depth = metrics.queue_depth.with_label_values(&["ingest"]);
        let mut deskew = isoline_io::Deskew::new(time_increment);
        let mut handle = |line: Line| -> bool {
            metrics.frames_in.inc();
            depth.set(rx.len() as i64);
            // The span covers the parsing, not the wait for room downstream.
            let m = tracing::info_span!(
                "ingest",
                origin = %line.origin,
                line = line.line,
                queue = rx.len()
            )
            .in_scope(|| parse_line(line, &mut deskew));
            tx.send(m).is_ok()
        };
        loop {
            if stop.load(Ordering::Relaxed) {
                // Lines already read get their records; the sources see the flag and
                // read no more.
                while let Ok(line) = rx.recv_timeout(poll) {
                    if !handle(line) {
                        return;
                    }
                }
                return;
            }
            match rx.recv_timeout(poll) {
                Ok(line) => {
                    if !handle(line) {
                        return;
                    }
                }
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => return,
            }
        }
    })
}

/// A line as a frame, or as a failed frame. A failed frame's stream and number are
/// read from the line if it is JSON with them; none is made up, so an error record never
/// claims a frame number that another record has. Its record names the line instead.
fn parse_line(mut line: Line, deskew: &mut isoline_io::Deskew) -> Msg {
    let default_stream = line.default_stream.as_deref().map(str::to_string);
    let parsed = match (line.decoded.take(), &line.text) {
        (Some(item), _) => (*item).map_err(|b| (b.message, (b.stream, b.frame))),
        (None, Err(e)) => Err((
            format!("{}, line {}: {e}", line.origin, line.line),
            (None, None),
        )),
        (None, Ok(text)) => {
            let n = usize::try_from(line.line).unwrap_or(usize::MAX);
            isoline_io::parse_frame(text, &line.origin, n)
                .map_err(|e| (e.to_string(), guess_ids(text)))
        }
    };
    let (stream, frame, pose, t, notes, work) = match parsed {
        Ok(mut f) => {
            // Keyed by the stream the record will carry.
            if f.stream.is_none() {
                f.stream.clone_from(&default_stream);
            }
            deskew.apply(&mut f);
            (
                f.stream.take().or(default_stream),
                Some(f.frame),
                f.pose,
                f.t,
                std::mem::take(&mut f.notes),
                Work::Input(Box::new(f)),
            )
        }
        Err((message, (stream, frame))) => {
            tracing::warn!(error = %message, "bad input line");
            (
                stream.or(default_stream),
                frame,
                None,
                None,
                Vec::new(),
                Work::Failed(message),
            )
        }
    };
    Msg {
        stream,
        frame,
        line: line.line,
        pose,
        registered: None,
        t,
        arrived: line.arrived,
        receipt: line.receipt,
        scan: None,
        notes,
        work,
    }
}

/// The stream and frame of a line that is JSON but not a valid frame.
/// A line cut short (a client that died mid-frame) is read up to the cut, so the ids
/// written before it still count.
fn guess_ids(text: &str) -> (Option<String>, Option<u64>) {
    match serde_json::from_str::<serde_json::Value>(text) {
        Ok(v) => (
            v.get("stream").and_then(|s| s.as_str()).map(str::to_string),
            v.get("frame").and_then(|f| f.as_u64()),
        ),
        Err(_) => {
            let stream = value_after(text, "\"stream\"").and_then(|rest| {
                serde_json::Deserializer::from_str(rest)
                    .into_iter::<String>()
                    .next()?
                    .ok()
            });
            let frame = value_after(text, "\"frame\"").and_then(|rest| {
                let digits =
                    rest.len() - rest.trim_start_matches(|c: char| c.is_ascii_digit()).len();
                // A number cut by the end of the line is not the frame's.
                (digits > 0 && digits < rest.len())
                    .then(|| rest[..digits].parse().ok())
                    .flatten()
            });
            (stream, frame)
        }
    }
}

/// The text after the first `key:` of `text`.
fn value_after<'a>(text: &'a str, key: &str) -> Option<&'a str> {
    let at = text.find(key)? + key.len();
    let rest = text[at..].trim_start().strip_prefix(':')?;
    Some(rest.trim_start())
}

/// Distance: validates and centres the points, builds their kd-tree and metric frames.
pub(crate) fn spawn_distance(
    rx: Receiver<Msg>,
    tx: Sender<Msg>,
    policy: Policy,
    params: Arc<Params>,
    keep_scans: bool,
    metrics: Arc<Metrics>,
) -> Result<JoinHandle<()>> {
    spawn("distance", move || {
        run_stage(
            "distance",
            rx,
            tx,
            policy,
            &metrics,
            |m, d| stage_span!("distance", m, d),
            |m| {
                let Work::Input(f) = std::mem::replace(&mut m.work, Work::Skipped) else {
                    unreachable!("distance takes input frames")
                };
                m.work = match reconstruct::prepare(&f.points, f.scan.as_ref(), &params) {
                    Ok(p) => Work::Prepared(Box::new(p)),
                    Err(e) => Work::Failed(e.to_string()),
                };
                if keep_scans && (m.pose.is_some() || m.registered.is_some()) {
                    m.scan = f.scan.map(Box::new);
                }
            },
        )
    })
}

/// Register (`[pipeline] register`): each stream's scans registered against its local
/// map by its own [`Registrar`] (isoline-map), the frame's pose taken as odometry
/// (none: from the returns alone). Frames without beams pass as they came.
pub(crate) fn spawn_register(
    rx: Receiver<Msg>,
    tx: Sender<Msg>,
    policy: Policy,
    params: RegisterParams,
    time_increment: Option<f64>,
    streams: StreamBounds,
    metrics: Arc<Metrics>,
) -> Result<JoinHandle<()>> {
    spawn("register", move || {
        let mut state: Streams<Registrar> = Streams::new(&streams);
        run_stage(
            "register",
            rx,
            tx,
            policy,
            &metrics,
            |m, d| stage_span!("register", m, d),
            |m| {
                let key = m.key().to_string();
                let (lease, pose) = (m.lease(), m.pose);
                let Work::Input(f) = &mut m.work else {
                    return;
                };
                let Some(scan) = f.scan.as_ref() else {
                    return;
                };
                let registrar = state.seen(
                    &key,
                    lease,
                    Instant::now(),
                    |_| true,
                    || Registrar::streaming(params).expect("validated with the configuration"),
                );
                // A scan with a pose was corrected for its sweep by ingest; one without is
                // corrected here, by the motion registration gives.
                let registered = match f.unposed_sweep(time_increment) {
                    Some((t, sweep)) => {
                        let (r, fixed) = registrar.push_swept(scan, &sweep, t, None);
                        f.replace_scan(fixed);
                        r.pose
                    }
                    None => registrar.push(scan, pose).pose,
                };
                m.registered = Some(registered);
            },
        )
    })
}

/// Adapt: adapts each stream's frame from the stream's last mesh (when warm starts are
/// on and the frame number went up; a lower one means the stream restarted).
pub(crate) fn spawn_adapt(
    rx: Receiver<Msg>,
    tx: Sender<Msg>,
    policy: Policy,
    warm: bool,
    streams: StreamBounds,
    metrics: Arc<Metrics>,
) -> Result<JoinHandle<()>> {
    spawn("adapt", move || {
        let mut last: Streams<MeshMemory> = Streams::new(&streams);
        run_stage(
            "adapt",
            rx,
            tx,
            policy,
            &metrics,
            |m, d| stage_span!("adapt", m, d),
            |m| {
                let Work::Prepared(p) = std::mem::replace(&mut m.work, Work::Skipped) else {
                    unreachable!("adapt takes prepared frames")
                };
                let adapted = if warm {
                    let memory =
                        last.seen(m.key(), m.lease(), Instant::now(), |_| true, <_>::default);
                    memory.adapt(&p, m.number(), m.pose)
                } else {
                    reconstruct::adapt(&p, None)
                };
                m.work = Work::Adapted(Box::new((*p, adapted)));
            },
        )
    })
}

/// Per-stream state of the solve stage.
#[derive(Default)]
struct SolveState {
    /// Frames sent to renormalization whose level set has not come back.
    pending: usize,
    memory: LevelSetMemory,
}

/// Solve: the level set of each frame, warm-started from the stream's last renormalized
/// one. Before solving a frame it waits until the renormalize stage has sent back the
/// level set of every earlier frame of the stream.
pub(crate) fn spawn_solve(
    rx: Receiver<Msg>,
    tx: Sender<Msg>,
    feedback: Receiver<Feedback>,
    policy: Policy,
    warm: bool,
    streams: StreamBounds,
    metrics: Arc<Metrics>,
) -> Result<JoinHandle<()>> {
    spawn("solve", move || {
        let mut state: Streams<SolveState> = Streams::new(&streams);
        // A stream with a level set in flight is never forgotten, so its feedback finds it.
        let apply = |state: &mut Streams<SolveState>, fb: Feedback| {
            if let Some(s) = state.peek_mut(&fb.key) {
                s.pending = s.pending.saturating_sub(1);
                if let Some((level_set, pose)) = fb.level_set {
                    s.memory.keep(level_set, pose);
                }
            }
        };
        run_stage(
            "solve",
            rx,
            tx,
            policy,
            &metrics,
            |m, d| stage_span!("solve", m, d),
            |m| {
                let Work::Adapted(b) = std::mem::replace(&mut m.work, Work::Skipped) else {
                    unreachable!("solve takes adapted frames")
                };
                let (p, adapted) = *b;
                if warm {
                    for fb in feedback.try_iter() {
                        apply(&mut state, fb);
                    }
                    while state.get(m.key()).is_some_and(|s| s.pending > 0) {
                        match feedback.recv() {
                            Ok(fb) => apply(&mut state, fb),
                            Err(_) => break,
                        }
                    }
                }
                let solved = if warm {
                    let s = state.seen(
                        m.key(),
                        m.lease(),
                        Instant::now(),
                        |s| s.pending == 0,
                        SolveState::default,
                    );
                    s.pending += 1;
                    s.memory.solve(&p, &adapted, m.number(), m.pose)
                } else {
                    reconstruct::solve(&p, &adapted, None)
                };
                m.work = Work::Solved(Box::new((p, adapted, solved)));
            },
        )
    })
}

/// Renormalize: the final fast marching over the whole mesh; the result goes on to
/// export and, as the stream's new warm-start state, back to the solve stage.
pub(crate) fn spawn_renormalize(
    rx: Receiver<Msg>,
    tx: Sender<Msg>,
    feedback: Option<Sender<Feedback>>,
    metrics: Arc<Metrics>,
) -> Result<JoinHandle<()>> {
    spawn("renormalize", move || {
        run_stage(
            "renormalize",
            rx,
            tx,
            Policy::Block,
            &metrics,
            |m, d| stage_span!("renormalize", m, d),
            |m| {
                let key = m.key().to_string();
                let pose = m.pose;
                let Work::Solved(b) = &mut m.work else {
                    unreachable!("renormalize takes solved frames")
                };
                // The solve stage waits for this frame's level set: it must get an answer
                // even if renormalizing fails.
                let level_set = catch_unwind(AssertUnwindSafe(|| {
                    let (p, adapted, solved) = &mut **b;
                    reconstruct::renormalize(&adapted.mesh, solved);
                    // Kept in data coordinates and units: the next frame is placed
                    // differently.
                    feedback
                        .as_ref()
                        .map(|_| (p.level_set(adapted, solved), pose))
                }));
                let level_set = match level_set {
                    Ok(l) => l,
                    Err(panic) => {
                        m.work = Work::Failed(internal_error("renormalize", panic.as_ref()));
                        None
                    }
                };
                if let Some(fb) = &feedback {
                    // The solve stage outlives this one unless the pipeline is being torn
                    // down; then nobody needs the level set.
                    let _ = fb.send(Feedback { key, level_set });
                }
            },
        )
    })
}

/// Where the export stage puts what it makes.
pub(crate) struct Outputs {
    /// The records (NDJSON or MCAP).
    pub(crate) sink: Sink,
    /// The live view, if on.
    pub(crate) live: Option<Arc<crate::pipeline::live::LiveView>>,
    /// A folder for one drawing per frame.
    pub(crate) svg_dir: Option<PathBuf>,
    /// The map stage, when the map is on.
    pub(crate) map: Option<Sender<super::map::MapItem>>,
    /// Whether a frame that finds the map stage's queue full passes it by (counted)
    /// rather than waiting (`pipeline.policy = "latest"`).
    pub(crate) map_lossy: bool,
    /// The counters of what is written.
    pub(crate) metrics: Arc<Metrics>,
}

/// Export: the curves and statistics of each frame as a record (an NDJSON line flushed
/// per frame, or MCAP messages for Foxglove), shown in the live view if on, and
/// optionally an SVG drawing; failed and skipped frames get their record too. A sink
/// that cannot be written ends the run with an error and sets `stop`.
pub(crate) fn spawn_export(
    rx: Receiver<Msg>,
    outputs: Outputs,
    stop: Arc<AtomicBool>,
    warm: bool,
    accumulate: Option<WindowLimits>,
    streams: StreamBounds,
) -> Result<JoinHandle<Result<RunSummary>>> {
    spawn("export", move || {
        let depth = outputs.metrics.queue_depth.with_label_values(&["export"]);
        let seconds = outputs.metrics.stage_seconds.with_label_values(&["export"]);
        let map_on = outputs.map.is_some();
        let mut ex = Exporter {
            wants_frames: outputs.sink.wants_frames() || outputs.live.is_some(),
            outputs,
            warm,
            accumulate,
            windows: Streams::new(&streams),
            summary: RunSummary::default(),
            map_counts: map_on.then(Default::default),
            tally: Tally::new(),
            first: None,
        };
        while let Ok(m) = rx.recv() {
            let s = stage_span!("export", m, rx.len());
            let _e = s.enter();
            let t0 = Instant::now();
            depth.set(rx.len() as i64);
            if let Err(e) = ex.frame(m) {
                // Whatever is still queued behind a failed sink is dropped with the
                // pipeline.
                stop.store(true, Ordering::Relaxed);
                return Err(e);
            }
            seconds.observe(t0.elapsed().as_secs_f64());
        }
        ex.finish()
    })
}

/// The export stage's state: where records go, the streams' refinement windows, and
/// the run's tallies.
struct Exporter {
    outputs: Outputs,
    /// Whether the sink or the live view show each frame's points.
    wants_frames: bool,
    warm: bool,
    accumulate: Option<WindowLimits>,
    windows: Streams<Window>,
    summary: RunSummary,
    /// Reconstructed frames the map could not take, when the map is on.
    map_counts: Option<super::map::MapCounts>,
    tally: Tally,
    /// When the first frame was read.
    first: Option<Instant>,
}

impl Exporter {
    /// One frame: its curves (refined over its stream's window when asked), its
    /// record written, shown and drawn.
    fn frame(&mut self, m: Msg) -> Result<()> {
        self.first = Some(self.first.map_or(m.arrived, |f| f.min(m.arrived)));
        let frame = m.number();
        let lease = m.lease();
        // Registered frames are placed by the estimate; the record keeps both.
        let placed = m.registered.or(m.pose);
        let work = match m.work {
            Work::Solved(b) => self.export(*b, &m.stream, frame, m.t, placed, lease),
            other => other,
        };
        let mut rec = ResultRecord {
            stream: m.stream.clone(),
            frame: m.frame,
            t: m.t,
            pose: m.pose,
            registered_pose: m.registered,
            ..Default::default()
        };
        let mut shown = Vec::new();
        let mut drawing = None;
        match work {
            Work::Exported(r, points) => {
                rec = ResultRecord {
                    t: m.t,
                    pose: m.pose,
                    registered_pose: m.registered,
                    ..ResultRecord::of(m.stream.clone(), frame, &r)
                };
                rec.add_warnings(&m.notes);
                self.tally_frame(&mut rec, &r, m.arrived);
                self.send_to_map(m.scan, placed, &r, &m.stream, frame);
                if self.wants_frames {
                    shown.clone_from(&points);
                }
                if self.outputs.svg_dir.is_some() {
                    drawing = Some((points, r));
                }
            }
            Work::Failed(e) => {
                self.summary.errors += 1;
                rec.error = Some(e);
                rec.line = Some(m.line);
            }
            Work::Skipped => {
                self.summary.skipped += 1;
                rec.error = Some(
                    "skipped: a newer frame of the stream was waiting (pipeline.policy = \"latest\")"
                        .into(),
                );
                rec.skipped = Some(true);
            }
            Work::Input(_) | Work::Prepared(_) | Work::Adapted(_) | Work::Solved(_) => {
                unreachable!("export takes frames that went through every stage")
            }
        }
        let view = isoline_io::foxglove::FrameView {
            record: rec,
            points: shown,
            t: m.t,
            pose: placed,
        };
        let counted = Counted::of(&view.record, m.arrived);
        self.outputs
            .sink
            .write_frame(&view, m.receipt, counted, &self.outputs.metrics)?;
        self.summary.records += 1;
        if let Some(l) = &self.outputs.live {
            if !l.show(view) {
                self.summary.live_dropped += 1;
                self.outputs.metrics.live_dropped.inc();
            }
        }
        if let (Some(dir), Some((points, r))) = (&self.outputs.svg_dir, drawing) {
            draw(
                &super::svg_path(dir, m.stream.as_deref(), frame),
                &points,
                &r,
            );
        }
        Ok(())
    }

    /// The export kernel on a solved frame (refined over its stream's window when the
    /// frame is a scan with a pose and refinement is on), with the frame's points in
    /// data coordinates when something shows them. A panic (a bug) fails this frame
    /// only.
    fn export(
        &mut self,
        (p, adapted, solved): (Prepared, AdaptedMesh, Solved),
        stream: &Option<String>,
        frame: u64,
        t: Option<f64>,
        pose: Option<Pose>,
        lease: Option<u64>,
    ) -> Work {
        let points: Vec<Point> = if self.outputs.svg_dir.is_some() || self.wants_frames {
            p.data()
        } else {
            Vec::new()
        };
        let refine = self.accumulate.as_ref().zip(pose).filter(|_| p.is_scan());
        let key = stream.as_deref().unwrap_or("");
        let windows = &mut self.windows;
        catch_unwind(AssertUnwindSafe(|| match refine {
            Some((limits, pose)) => {
                let window = windows.seen(
                    key,
                    lease,
                    Instant::now(),
                    |_| true,
                    || Window::new(*limits),
                );
                reconstruct::export_refined(&p, adapted, solved, frame, t, pose, window)
            }
            None => reconstruct::export(&p, adapted, solved),
        }))
        .map(|r| Work::Exported(Box::new(r), points))
        .unwrap_or_else(|panic| Work::Failed(internal_error("export", panic.as_ref())))
    }

    /// Hands a reconstructed frame to the map stage, when the map is on: a frame without
    /// a pose or beams cannot be placed, and under the `latest` policy a frame that
    /// finds the map behind passes it by; both are counted.
    fn send_to_map(
        &mut self,
        scan: Option<Box<isoline_core::Scan>>,
        pose: Option<Pose>,
        r: &Reconstruction,
        stream: &Option<String>,
        frame: u64,
    ) {
        let (Some(tx), Some(counts)) = (&self.outputs.map, &mut self.map_counts) else {
            return;
        };
        let (Some(scan), Some(pose)) = (scan, pose) else {
            counts.unplaced += 1;
            return;
        };
        let item = super::map::MapItem {
            scan,
            pose,
            curves: r.polylines.clone(),
            noise: r.noise_estimate,
            stream: stream.clone(),
            frame,
        };
        let sent = if self.outputs.map_lossy {
            match tx.try_send(item) {
                Ok(()) => true,
                Err(crossbeam_channel::TrySendError::Full(_)) => {
                    counts.behind += 1;
                    true
                }
                Err(crossbeam_channel::TrySendError::Disconnected(_)) => false,
            }
        } else {
            tx.send(item).is_ok()
        };
        if !sent {
            // The map stage has ended on an error, which the run reports.
            self.outputs.map = None;
        }
    }

    /// Counts a reconstructed frame in the run's summary and puts its latency in its
    /// record.
    fn tally_frame(&mut self, rec: &mut ResultRecord, r: &Reconstruction, arrived: Instant) {
        let summary = &mut self.summary;
        let stats = rec.stats.as_mut().expect("a reconstruction has stats");
        let latency = arrived.elapsed();
        stats.ms.latency = Some(latency.as_secs_f64() * 1e3);
        self.tally.latency(latency);
        if stats.warm_start {
            summary.warm += 1;
        }
        summary.cold_fallbacks += usize::from(stats.cold_fallback);
        *summary.starts.entry(stats.start.name().into()).or_default() += 1;
        summary.warnings += usize::from(rec.warnings.is_some());
        summary.empty += usize::from(r.polylines.is_empty());
        if self.warm {
            let window = stats.window.map_or(0, |w| w.bytes);
            let state = 2 * r.mesh.bytes() + r.u.len() * 8 + window;
            summary.state_bytes_max = summary.state_bytes_max.max(state);
        }
        self.tally.iterations(stats.warm_start, stats.iterations);
        self.tally.stages(&stats.ms);
        self.tally
            .wait(latency.as_secs_f64() * 1e3 - stats.ms.total);
        summary.reconstructed += 1;
    }

    /// The run's summary, once the sink is complete.
    fn finish(self) -> Result<RunSummary> {
        let Exporter {
            outputs,
            mut summary,
            tally,
            first,
            map_counts,
            ..
        } = self;
        summary.map = map_counts.map(|c| super::map::MapReport {
            unplaced: c.unplaced,
            behind: c.behind,
            ..Default::default()
        });
        outputs.sink.finish()?;
        summary.seconds = first.map_or(0.0, |f| f.elapsed().as_secs_f64());
        if summary.seconds > 0.0 {
            summary.frames_per_second = summary.records as f64 / summary.seconds;
        }
        tally.summarize(&mut summary);
        Ok(summary)
    }
}

/// Draws a frame to `path`; a drawing that cannot be written is logged, not fatal.
fn draw(path: &std::path::Path, points: &[Point], r: &Reconstruction) {
    let features: Vec<Point> = r.features.iter().map(|f| f.center).collect();
    let doc = isoline_io::write::svg::render(
        &isoline_io::write::svg::of_reconstruction(points, r, &features, &[], false),
        800.0,
    );
    if let Err(e) = isoline_io::write::write_atomic(path, doc.as_bytes()) {
        tracing::warn!(path = %path.display(), error = %e, "SVG not written");
    }
}

/// Run statistics in constant memory: histograms with three significant digits, so a
/// daemon that runs for months keeps the same few hundred kilobytes.
struct Tally {
    /// Microseconds, up to an hour (longer ones count as an hour).
    latency_us: Histogram<u64>,
    warm_its: Histogram<u64>,
    cold_its: Histogram<u64>,
    /// Microseconds in the compute stages, per frame.
    stages_us: Histogram<u64>,
    /// Microseconds a frame waited (its latency less its time in the stages): queues,
    /// and a stage busy with other streams' frames.
    wait_us: Histogram<u64>,
    /// Milliseconds per stage, summed over the frames.
    stage_sums: [f64; 5],
}

impl Tally {
    fn new() -> Self {
        let h = |max| Histogram::new_with_bounds(1, max, 3).expect("valid histogram bounds");
        Tally {
            latency_us: h(3_600_000_000),
            warm_its: h(isoline_core::stages::MAX_STEPS as u64),
            cold_its: h(isoline_core::stages::MAX_STEPS as u64),
            stages_us: h(3_600_000_000),
            wait_us: h(3_600_000_000),
            stage_sums: [0.0; 5],
        }
    }

    fn stages(&mut self, ms: &isoline_core::StageMs) {
        self.stages_us
            .saturating_record((ms.total.max(0.0) * 1e3).round() as u64);
        let parts = [ms.distance, ms.adapt, ms.solve, ms.renormalize, ms.export];
        for (sum, x) in self.stage_sums.iter_mut().zip(parts) {
            *sum += x;
        }
    }

    fn wait(&mut self, ms: f64) {
        self.wait_us
            .saturating_record((ms.max(0.0) * 1e3).round() as u64);
    }

    fn latency(&mut self, d: Duration) {
        self.latency_us
            .saturating_record(u64::try_from(d.as_micros()).unwrap_or(u64::MAX));
    }

    fn iterations(&mut self, warm: bool, n: usize) {
        let h = if warm {
            &mut self.warm_its
        } else {
            &mut self.cold_its
        };
        h.saturating_record(n as u64);
    }

    fn summarize(&self, s: &mut RunSummary) {
        let q = |h: &Histogram<u64>, q: f64| (!h.is_empty()).then(|| h.value_at_quantile(q));
        s.latency_p50 = q(&self.latency_us, 0.5).map_or(0.0, |us| us as f64 / 1e3);
        s.latency_p99 = q(&self.latency_us, 0.99).map_or(0.0, |us| us as f64 / 1e3);
        s.iterations_warm = q(&self.warm_its, 0.5).map(|n| n as f64);
        s.iterations_cold = q(&self.cold_its, 0.5).map(|n| n as f64);
        s.stage_ms_p50 = q(&self.stages_us, 0.5).map(|us| us as f64 / 1e3);
        s.wait_ms_p50 = q(&self.wait_us, 0.5).map(|us| us as f64 / 1e3);
        let frames = self.stages_us.len();
        s.stage_ms_mean = (frames > 0).then(|| self.stage_sums.map(|sum| sum / frames as f64));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn msg(stream: &str, frame: u64, live: bool) -> Msg {
        Msg {
            stream: Some(stream.into()),
            frame: Some(frame),
            line: frame,
            pose: None,
            registered: None,
            t: None,
            arrived: Instant::now(),
            receipt: None,
            scan: None,
            notes: Vec::new(),
            work: if live {
                Work::Input(Default::default())
            } else {
                Work::Failed("bad".into())
            },
        }
    }

    #[test]
    fn latest_keeps_the_newest_live_frame_of_each_stream_in_order() {
        let mut batch = vec![
            msg("a", 1, true),
            msg("b", 1, true),
            msg("a", 2, false),
            msg("a", 3, true),
            msg("a", 4, true),
        ];
        mark_stale(&mut batch);
        let kept: Vec<(String, u64, bool)> = batch
            .iter()
            .map(|m| {
                (
                    m.key().to_string(),
                    m.number(),
                    matches!(m.work, Work::Skipped),
                )
            })
            .collect();
        assert_eq!(
            kept,
            vec![
                ("a".into(), 1, true),
                ("b".into(), 1, false),
                ("a".into(), 2, false),
                ("a".into(), 3, true),
                ("a".into(), 4, false),
            ]
        );
    }

    #[test]
    fn block_takes_one_frame_at_a_time() {
        let (tx, rx) = crossbeam_channel::unbounded();
        tx.send(msg("a", 2, true)).unwrap();
        let batch = take_batch(msg("a", 1, true), &rx, Policy::Block);
        assert_eq!(batch.len(), 1);
        assert_eq!(rx.len(), 1);
        let batch = take_batch(msg("a", 1, true), &rx, Policy::Latest);
        assert_eq!(batch.len(), 2);
        assert!(matches!(batch[0].work, Work::Skipped));
    }

    #[test]
    fn ingest_corrects_each_clients_sweeps_by_its_own_motion() {
        // A sensor at the origin turning at 1 rad/s before a wall at x = 3, its 201
        // beams 1 ms apart; two TCP clients' frames interleaved, neither naming its
        // stream: each is corrected by its own client's previous frame.
        let line = |t: f64, client: &str, n| {
            let (a0, inc) = (-50f64.to_radians(), 0.5f64.to_radians());
            let ranges: Vec<f64> = (0..201)
                .map(|i| 3.0 / (t + 1e-3 * f64::from(i) + a0 + f64::from(i) * inc).cos())
                .collect();
            let text = serde_json::json!({"frame": n, "t": t, "pose": [0.0, 0.0, t],
                "ranges": ranges, "angle_min": a0, "angle_increment": inc,
                "time_increment": 1e-3, "range_max": 20.0})
            .to_string();
            Line {
                origin: "tcp".into(),
                default_stream: Some(client.into()),
                line: n,
                text: Ok(text),
                decoded: None,
                arrived: Instant::now(),
                receipt: None,
            }
        };
        let off_wall = |m: &Msg| {
            let Work::Input(f) = &m.work else { panic!() };
            f.points
                .iter()
                .map(|&p| (isoline_core::geom::to_world(f.pose.unwrap(), p)[0] - 3.0).abs())
                .fold(0.0, f64::max)
        };
        let mut deskew = isoline_io::Deskew::new(None);
        let a0 = parse_line(line(0.0, "a", 1), &mut deskew);
        let b0 = parse_line(line(0.05, "b", 1), &mut deskew);
        let a1 = parse_line(line(0.1, "a", 2), &mut deskew);
        let b1 = parse_line(line(0.15, "b", 2), &mut deskew);
        // The first frame of each has no motion before it: as it came, 0.2 rad bent.
        assert!(off_wall(&a0) > 0.1 && off_wall(&b0) > 0.1);
        assert!(off_wall(&a1) < 1e-9 && off_wall(&b1) < 1e-9);
        assert_eq!(a1.stream.as_deref(), Some("a"));
    }

    #[test]
    fn bad_lines_become_failed_frames_with_the_best_ids_available() {
        let line = |text: &str, n| Line {
            origin: "in.ndjson".into(),
            default_stream: None,
            line: n,
            text: Ok(text.into()),
            decoded: None,
            arrived: Instant::now(),
            receipt: None,
        };
        let ok = parse_line(
            line(r#"{"stream":"s","frame":7,"points":[[0,0]]}"#, 1),
            &mut isoline_io::Deskew::new(None),
        );
        assert!(matches!(ok.work, Work::Input(_)) && ok.frame == Some(7));
        let bad = parse_line(
            line(r#"{"stream":"s","frame":8,"points":[[0]]}"#, 2),
            &mut isoline_io::Deskew::new(None),
        );
        assert_eq!((bad.stream.as_deref(), bad.frame), (Some("s"), Some(8)));
        let Work::Failed(e) = &bad.work else { panic!() };
        assert!(e.contains("in.ndjson, line 2"), "{e}");
        // No frame number is made up: a guess could be a real frame's. What a cut line
        // says before its cut counts.
        let cut = parse_line(
            line(r#"{"stream":"s","fra"#, 3),
            &mut isoline_io::Deskew::new(None),
        );
        assert_eq!(
            (cut.stream.as_deref(), cut.frame, cut.line),
            (Some("s"), None, 3)
        );
        let cut = parse_line(
            line(r#"{"stream":"s\"t","frame":12,"points":[[0.1,"#, 3),
            &mut isoline_io::Deskew::new(None),
        );
        assert_eq!((cut.stream.as_deref(), cut.frame), (Some("s\"t"), Some(12)));
        let cut = parse_line(
            line(r#"{"frame":12"#, 3),
            &mut isoline_io::Deskew::new(None),
        );
        assert_eq!(cut.frame, None);
        let Work::Failed(e) = &cut.work else { panic!() };
        assert!(e.contains("line 3"), "{e}");
        let huge = parse_line(
            line(r#"{"frame":18446744073709551615,"points":7}"#, 4),
            &mut isoline_io::Deskew::new(None),
        );
        assert_eq!(huge.frame, Some(u64::MAX));
        let invalid = Line {
            text: Err("the line is not valid UTF-8".into()),
            ..line("", 4)
        };
        let m = parse_line(invalid, &mut isoline_io::Deskew::new(None));
        let Work::Failed(e) = &m.work else { panic!() };
        assert!(e.contains("line 4") && e.contains("UTF-8"), "{e}");
    }

    #[test]
    fn a_panic_fails_its_frame_only() {
        let (in_tx, in_rx) = crossbeam_channel::unbounded();
        let (out_tx, out_rx) = crossbeam_channel::unbounded();
        for f in 0..3 {
            in_tx.send(msg("a", f, true)).unwrap();
        }
        drop(in_tx);
        // The default hook would print the expected panic among the test output.
        let hook = std::panic::take_hook();
        std::panic::set_hook(Box::new(|_| {}));
        run_stage(
            "test",
            in_rx,
            out_tx,
            Policy::Block,
            &Metrics::new(4),
            |_, _| tracing::Span::none(),
            |m| assert!(m.frame != Some(1), "frame one is cursed"),
        );
        std::panic::set_hook(hook);
        let out: Vec<Msg> = out_rx.iter().collect();
        assert_eq!(
            out.iter().map(|m| m.number()).collect::<Vec<_>>(),
            vec![0, 1, 2]
        );
        assert!(matches!(out[0].work, Work::Input(_)));
        let Work::Failed(e) = &out[1].work else {
            panic!("frame 1 not failed")
        };
        assert!(
            e.contains("internal error in the test stage") && e.contains("cursed"),
            "{e}"
        );
        assert!(matches!(out[2].work, Work::Input(_)));
    }

    #[test]
    fn run_statistics_are_bounded_and_within_a_thousandth() {
        let mut t = Tally::new();
        for ms in 1..=1000u64 {
            t.latency(Duration::from_millis(ms));
        }
        // A stuck frame and a pathological one stay countable.
        t.latency(Duration::from_secs(100_000));
        t.iterations(true, 3);
        t.iterations(false, usize::MAX);
        let mut s = RunSummary::default();
        t.summarize(&mut s);
        // Three significant digits: each quantile within 0.1% of the exact one.
        assert!(
            (s.latency_p50 - 501.0).abs() <= 0.001 * 501.0,
            "{}",
            s.latency_p50
        );
        assert!(
            (s.latency_p99 - 991.0).abs() <= 0.001 * 991.0,
            "{}",
            s.latency_p99
        );
        assert_eq!(s.iterations_warm, Some(3.0));
        assert!(s.iterations_cold.is_some());
        // No frame, no stage times; then three frames whose stages add up.
        assert_eq!((s.stage_ms_p50, s.stage_ms_mean), (None, None));
        for k in 1..=3 {
            let k = k as f64;
            t.stages(&isoline_core::StageMs {
                distance: k,
                adapt: 2.0 * k,
                solve: 0.5,
                renormalize: 0.0,
                export: 1.5,
                total: 3.0 * k + 2.0,
                latency: None,
            });
        }
        t.summarize(&mut s);
        let p50 = s.stage_ms_p50.expect("three frames");
        assert!((p50 - 8.0).abs() <= 0.001 * 8.0, "{p50}");
        let mean = s.stage_ms_mean.expect("three frames");
        assert_eq!(mean, [2.0, 4.0, 0.5, 0.0, 1.5]);
        assert_eq!(mean.iter().sum::<f64>(), 8.0);
        let bytes = [
            &t.latency_us,
            &t.warm_its,
            &t.cold_its,
            &t.stages_us,
            &t.wait_us,
        ]
        .iter()
        .map(|h| h.distinct_values() * 8)
        .sum::<usize>();
        assert!(bytes < 1 << 20, "{bytes}");
    }

    #[test]
    fn stream_state_is_bounded_in_number_and_age() {
        let t0 = Instant::now();
        let bounds = StreamBounds {
            max: 3,
            idle: Duration::from_secs(10),
            leases: None,
        };
        let mut s: Streams<u32> = Streams::new(&bounds);
        for (i, k) in ["a", "b", "c"].iter().enumerate() {
            *s.seen(k, None, t0 + Duration::from_secs(i as u64), |_| true, || 0) += 1;
        }
        // A fourth stream forgets the least recently seen, "a".
        s.seen("d", None, t0 + Duration::from_secs(3), |_| true, || 0);
        assert_eq!(s.len(), 3);
        assert!(s.get("a").is_none() && s.get("b").is_some());
        // A busy stream is never forgotten: "b" stays, so the table goes over its size
        // rather than lose a level set in flight.
        s.seen("e", None, t0 + Duration::from_secs(4), |v| *v == 0, || 0);
        assert!(s.get("b").is_some() && s.get("c").is_some());
        // Idle ones go, whatever the count.
        s.seen("f", None, t0 + Duration::from_secs(60), |_| true, || 0);
        assert_eq!(s.len(), 1);
        assert_eq!(s.forgotten, 5);
    }

    #[test]
    fn a_partition_given_up_takes_its_streams_state_with_it() {
        let leases = Arc::new(Leases::default());
        let (p0, p1) = (leases.grant(0), leases.grant(1));
        let bounds = StreamBounds {
            max: 10,
            idle: Duration::from_secs(10),
            leases: Some(leases.clone()),
        };
        let mut s: Streams<u32> = Streams::new(&bounds);
        let now = Instant::now();
        *s.seen("a", Some(p0), now, |_| true, || 0) = 1;
        *s.seen("b", Some(p1), now, |_| true, || 0) = 1;
        leases.revoke(1);
        // Any frame drops the state of the partition given up; the other stays warm.
        assert_eq!(*s.seen("a", Some(p0), now, |_| true, || 0), 1);
        assert!(s.get("b").is_none());
        // Partition 0 moves away and back: the stream's old state is not reused.
        leases.revoke(0);
        let again = leases.grant(0);
        assert_eq!(*s.seen("a", Some(again), now, |_| true, || 0), 0);
        assert_eq!(s.forgotten, 2);
    }
}
