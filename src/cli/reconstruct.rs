//! `isoline reconstruct`: curves from a point file or from each frame of a stream.

use std::path::PathBuf;

use anyhow::{bail, Context, Result};

use isoline_io::format::ResultRecord;
use isoline_io::foxglove::{FrameView, McapOut};
use isoline_io::write::svg;

/// `isoline reconstruct` options.
#[derive(clap::Args)]
pub struct Args {
    /// Point file (`x y` per line), NDJSON frame stream (.ndjson/.jsonl), ROS 2 bag
    /// (.mcap) or CARMEN log (.log, .clf, .carmen, maybe .gz, or by its lines).
    input: PathBuf,
    /// TOML configuration ([mesh], [solver], [export] tables).
    #[arg(short, long)]
    config: Option<PathBuf>,
    /// Output; the extension picks the format: .ndjson .json .geojson .csv .svg, or
    /// .mcap (curves, points and records for Foxglove). Default: NDJSON on stdout.
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Per-frame statistics as JSON (an object, or an array for several frames).
    #[arg(long)]
    stats: Option<PathBuf>,
    /// Only this frame of an NDJSON input.
    #[arg(long)]
    frame: Option<u64>,
    /// Override the configured scheme: explicit or semi-implicit.
    #[arg(long)]
    scheme: Option<isoline_core::Scheme>,
    /// Override the configured starting curve: medial, tube, box or circle.
    #[arg(long)]
    init: Option<isoline_core::Init>,
    /// Draw the mesh in SVG output.
    #[arg(long)]
    mesh: bool,
    #[command(flatten)]
    bag: super::BagArgs,
}

/// Where the records go: written as each frame is done, so that a run holds one frame
/// at a time whatever the recording's length.
enum Sink {
    /// A text format to a file, renamed into place when complete.
    File(
        isoline_io::write::RecordWriter<std::io::BufWriter<std::fs::File>>,
        isoline_io::write::PartFile,
    ),
    /// NDJSON on standard output.
    Stdout(isoline_io::write::RecordWriter<std::io::Stdout>),
    /// A Foxglove bag.
    Mcap(Box<McapOut>),
    /// A drawing of the one frame an SVG holds: its points and reconstruction.
    Svg(std::path::PathBuf, Option<Box<Drawn>>),
}

/// A frame done: its record, the frame (when it could be read) and its reconstruction.
type Done = (
    ResultRecord,
    Option<isoline_io::Frame>,
    Option<isoline_core::Reconstruction>,
);

/// The frame an SVG draws: its points and reconstruction.
type Drawn = (Vec<isoline_core::geom::Point>, isoline_core::Reconstruction);

impl Sink {
    /// Creates the output before any frame is read: a path that cannot be written fails
    /// the run at once.
    fn open(output: Option<&std::path::Path>, format: isoline_io::write::Format) -> Result<Sink> {
        use isoline_io::write::{Format, RecordWriter};
        Ok(match output {
            None => Sink::Stdout(RecordWriter::new(Format::Ndjson, std::io::stdout())?),
            Some(p) if isoline_io::is_bag(p) => Sink::Mcap(Box::new(McapOut::create(p)?)),
            Some(p) if format == Format::Svg => {
                // Created now so that an unwritable path fails before the work.
                let (part, _) = super::create_part(p)?;
                drop(part);
                Sink::Svg(p.to_path_buf(), None)
            }
            Some(p) => {
                let (part, file) = super::create_part(p)?;
                Sink::File(
                    RecordWriter::new(format, std::io::BufWriter::new(file))?,
                    part,
                )
            }
        })
    }

    fn push(
        &mut self,
        rec: &ResultRecord,
        frame: Option<&isoline_io::Frame>,
        r: Option<isoline_core::Reconstruction>,
    ) -> Result<()> {
        match self {
            Sink::File(w, part) => w
                .push(rec)
                .with_context(|| format!("writing {}", part.part().display())),
            Sink::Stdout(w) => match w.push(rec) {
                Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
                r => r.context("writing to standard output"),
            },
            Sink::Mcap(m) => Ok(m.write(&FrameView {
                record: rec.clone(),
                points: frame.map(|f| f.points.clone()).unwrap_or_default(),
                t: frame.and_then(|f| f.t),
                pose: frame.and_then(|f| f.pose),
            })?),
            Sink::Svg(_, drawn) => {
                if let (Some(f), Some(r)) = (frame, r) {
                    *drawn = Some(Box::new((f.points.clone(), r)));
                }
                Ok(())
            }
        }
    }

    fn finish(self, draw_mesh: bool) -> Result<()> {
        match self {
            Sink::File(w, part) => {
                let path = part.part().to_path_buf();
                drop(
                    w.finish()
                        .with_context(|| format!("writing {}", path.display()))?,
                );
                part.commit()
                    .with_context(|| format!("writing {}", path.display()))
            }
            Sink::Stdout(w) => match w.finish() {
                Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => {
                    Err(e).context("writing to standard output")
                }
                _ => Ok(()),
            },
            Sink::Mcap(m) => Ok(m.finish()?),
            Sink::Svg(path, drawn) => {
                let Some((points, r)) = drawn.map(|d| *d) else {
                    bail!("{}: no curves to draw (the frame failed)", path.display());
                };
                let features: Vec<_> = r.features.iter().map(|f| f.center).collect();
                let doc = svg::render(
                    &svg::of_reconstruction(&points, &r, &features, &[], draw_mesh),
                    1200.0,
                );
                super::write(&path, doc)
            }
        }
    }
}

/// The frames' statistics as JSON: one object for one frame, an array for several,
/// written as they come.
struct StatsSink {
    out: std::io::BufWriter<std::fs::File>,
    part: isoline_io::write::PartFile,
    first: Option<String>,
    written: u64,
}

impl StatsSink {
    fn open(path: &std::path::Path) -> Result<StatsSink> {
        let (part, file) = super::create_part(path)?;
        Ok(StatsSink {
            out: std::io::BufWriter::new(file),
            part,
            first: None,
            written: 0,
        })
    }

    fn push(&mut self, stats: &impl serde::Serialize) -> Result<()> {
        use std::io::Write;
        let text = format!("{:#}", serde_json::to_value(stats)?);
        match (self.written, self.first.take()) {
            (0, _) => self.first = Some(text),
            (_, Some(first)) => write!(self.out, "[\n{first},\n{text}")?,
            _ => write!(self.out, ",\n{text}")?,
        }
        self.written += 1;
        Ok(())
    }

    fn finish(mut self) -> Result<()> {
        use std::io::Write;
        match (self.written, self.first.take()) {
            (1, Some(first)) => writeln!(self.out, "{first}")?,
            _ => self.out.write_all(b"\n]\n")?,
        }
        self.out.flush()?;
        drop(self.out);
        let path = self.part.part().to_path_buf();
        self.part
            .commit()
            .with_context(|| format!("writing {}", path.display()))
    }
}

/// The configuration's parameters with the command line's overrides, and its beam
/// timing for frames that do not give theirs (`[scan] time_increment`).
fn params_of(a: &Args) -> Result<(isoline_core::Params, Option<f64>)> {
    let cfg = super::load_config(a.config.as_deref())?;
    let mut params = cfg.params();
    if let Some(s) = a.scheme {
        params.solver.scheme = s;
    }
    if let Some(i) = a.init {
        params.solver.init = i;
    }
    Ok((params, cfg.scan.time_increment))
}

/// The run's outputs: the records' sink and, with `--stats`, the statistics'.
struct Outputs {
    sink: Sink,
    stats: Option<StatsSink>,
}

impl Outputs {
    fn emit(&mut self, (rec, f, r): Done) -> Result<()> {
        self.sink.push(&rec, f.as_ref(), r)?;
        if let Some(s) = &mut self.stats {
            s.push(&rec.stats)?;
        }
        Ok(())
    }

    fn finish(self, draw_mesh: bool) -> Result<()> {
        self.sink.finish(draw_mesh)?;
        match self.stats {
            Some(s) => s.finish(),
            None => Ok(()),
        }
    }
}

/// Says on stderr why the frame of `item` failed, naming the file and, where there are
/// several, the frame.
fn say_failure(item: &isoline_io::Item, error: &str, input: &std::path::Path) {
    match item {
        Err(_) => eprintln!("isoline: {error}"),
        Ok(f) => eprintln!("isoline: {}, frame {}: {error}", input.display(), f.frame),
    }
}

/// The text format of `output` by its extension (NDJSON on standard output, and for a
/// bag, whose records are written as Foxglove messages).
fn output_format(output: Option<&std::path::Path>) -> Result<isoline_io::write::Format> {
    use isoline_io::write::Format;
    Ok(match output {
        None => Format::Ndjson,
        Some(p) if isoline_io::is_bag(p) => Format::Ndjson,
        Some(p) => Format::from_path(p).with_context(|| {
            format!(
                "{}: unknown output extension (use .ndjson, .json, .geojson, .csv, .svg or \
                 .mcap)",
                p.display()
            )
        })?,
    })
}

/// The record of one item read: the frame's reconstruction, or the error record of a
/// frame that could not be read.
fn record_of(
    item: &isoline_io::Item,
    params: &isoline_core::Params,
) -> (ResultRecord, Option<isoline_core::Reconstruction>) {
    match item {
        Ok(f) => isoline_io::reconstruct_frame(f, params),
        Err(b) => (
            ResultRecord {
                stream: b.stream.clone(),
                frame: b.frame,
                error: Some(b.message.clone()),
                ..Default::default()
            },
            None,
        ),
    }
}

/// Reconstructs every frame (or `--frame`) and writes one record per frame in the
/// output's format, each as it is done; fails when a frame failed, after writing the
/// others, and when the input could not be read to its end (a download cut short), after
/// writing the records of the frames before the damage.
pub fn run(a: Args) -> Result<()> {
    use isoline_io::write::Format;

    let (params, time_increment) = params_of(&a)?;
    let params = &params;
    let mut deskew = isoline_io::Deskew::new(time_increment);
    let (input, output, stats, only) = (
        a.input.as_path(),
        a.output.as_deref(),
        a.stats.as_deref(),
        a.frame,
    );
    let format = output_format(output)?;
    super::refuse_overwrite(input, &[output, stats])?;
    let cap = a.bag.line_cap();
    let bag = a.bag.options(input)?;
    let mut outputs = Outputs {
        sink: Sink::open(output, format)?,
        stats: stats.map(StatsSink::open).transpose()?,
    };
    // The first record waits for a second frame: one frame of points that fails has its
    // error as the answer, and no output.
    let mut held: Option<Done> = None;
    let (mut seen, mut failed) = (0u64, 0u64);
    let mut stop: Option<anyhow::Error> = None;
    let read = isoline_io::for_each_item_capped(input, &bag, cap, |mut item| {
        // Every frame, also those --frame passes over: its pose is the next one's motion.
        if let Ok(f) = &mut item {
            deskew.apply(f);
        }
        let number = match &item {
            Ok(f) => Some(f.frame),
            Err(b) => b.frame,
        };
        if only.is_some() && number != only {
            return true;
        }
        seen += 1;
        if format == Format::Svg && seen > 1 {
            stop = Some(anyhow::anyhow!(
                "{} has more than one frame and an SVG holds one: pick one with --frame",
                input.display()
            ));
            return false;
        }
        let (rec, r) = record_of(&item, params);
        if let Some(e) = &rec.error {
            failed += 1;
            // The first frame of a file of points waits: its error may be the answer.
            if seen > 1 || isoline_io::is_recording(input) {
                say_failure(&item, e, input);
            }
        }
        let next = (rec, item.ok(), r);
        let out = match held.take() {
            Some(first) => {
                if let (Some(e), false) = (&first.0.error, isoline_io::is_recording(input)) {
                    eprintln!(
                        "isoline: {}, frame {}: {e}",
                        input.display(),
                        first.0.frame.unwrap_or(0)
                    );
                }
                outputs.emit(first)
            }
            .and_then(|()| outputs.emit(next)),
            None if seen == 1 => {
                held = Some(next);
                Ok(())
            }
            None => outputs.emit(next),
        };
        if let Err(e) = out {
            stop = Some(e);
            return false;
        }
        true
    });
    if let Some(e) = stop {
        return Err(e);
    }
    if seen == 0 {
        read?;
        bail!(
            "{}: no frame {}",
            input.display(),
            only.map_or("at all".into(), |f| f.to_string())
        );
    }
    if let Some((rec, f, r)) = held.take() {
        // One frame of points: the error is the answer. A recording's frames all get
        // records, whatever their number.
        if let (Some(e), false) = (&rec.error, isoline_io::is_recording(input)) {
            read?;
            match f.filter(|f| f.stream.is_some()) {
                Some(f) => bail!("{}, frame {}: {e}", input.display(), f.frame),
                None => bail!("{}: {e}", input.display()),
            }
        }
        outputs.emit((rec, f, r))?;
    }
    outputs.finish(a.mesh)?;
    outcome(read, seen, failed, input)
}

/// How a run whose records are all written ends: the read error that stopped it (a
/// file damaged part way), or the count of frames that failed, or success.
fn outcome(
    read: isoline_io::Result<()>,
    seen: u64,
    failed: u64,
    input: &std::path::Path,
) -> Result<()> {
    if let Err(e) = read {
        return Err(anyhow::Error::new(e).context(format!(
            "{}: read {seen} frames, then could not read on (their records are written)",
            input.display()
        )));
    }
    if failed > 0 {
        bail!("{failed} of {seen} frames failed (error records written)");
    }
    Ok(())
}
