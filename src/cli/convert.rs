//! `isoline convert`: frames from one format to another (ROS 2 bag, CARMEN log, NDJSON
//! frames in; NDJSON frames or a ROS 2 bag out), so that a recording can be looked at,
//! edited or fed as the user likes.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};

use isoline_io::bag::{self, BagOptions, BagWriter};
use isoline_io::format::FrameRecord;
use isoline_io::{carmen, BadFrame};

/// `isoline convert` options.
#[derive(clap::Args)]
pub struct Args {
    /// ROS 2 bag (.mcap), CARMEN log (.log, .clf, .carmen, maybe .gz, or by its lines) or NDJSON frames (.ndjson/.jsonl).
    input: PathBuf,
    /// NDJSON frames (.ndjson/.jsonl) or a ROS 2 bag (.mcap: LaserScan and Odometry).
    #[arg(short, long)]
    output: PathBuf,
    #[command(flatten)]
    bag: super::BagArgs,
    /// Bag output: the LaserScan topic.
    #[arg(long, default_value = "/scan")]
    scan_topic: String,
    /// Bag output: the Odometry topic for the frames' poses.
    #[arg(long, default_value = "/odom")]
    odometry_topic: String,
    /// Bag output: the poses' frame.
    #[arg(long, default_value = "odom")]
    pose_frame: String,
}

/// Where converted frames go.
enum Out {
    Ndjson(std::io::BufWriter<std::fs::File>),
    Bag(Box<BagWriter<std::io::BufWriter<std::fs::File>>>),
}

/// Converts every frame; a frame that cannot be read or written is reported on stderr
/// and left out, and the command fails after writing the others. The output appears
/// only when complete (written beside it, then renamed).
pub fn run(a: Args) -> Result<()> {
    let (input, output) = (a.input.as_path(), a.output.as_path());
    super::refuse_overwrite(input, &[Some(output)])?;
    let out_bag = isoline_io::is_bag(output);
    if !out_bag && !isoline_io::is_frame_stream(output) {
        bail!(
            "{}: unknown output extension (use .ndjson, .jsonl or .mcap)",
            output.display()
        );
    }
    let opts = a.bag.options(input)?;
    let (guard, file) = isoline_io::write::PartFile::create(output)
        .with_context(|| format!("creating {}", output.display()))?;
    let part = guard.part().to_path_buf();
    let mut out = if out_bag {
        Out::Bag(Box::new(
            BagWriter::new(
                std::io::BufWriter::new(file),
                &a.scan_topic,
                &a.odometry_topic,
                &a.pose_frame,
            )
            .with_context(|| format!("writing {}", part.display()))?,
        ))
    } else {
        Out::Ndjson(std::io::BufWriter::new(file))
    };
    let result = convert(input, &part, &opts, &mut out);
    let finished = result.and_then(|counts| {
        match out {
            Out::Ndjson(mut w) => w.flush().context("flushing the output")?,
            Out::Bag(b) => b.finish().context("finishing the bag")?,
        }
        guard
            .commit()
            .with_context(|| format!("renaming {} to {}", part.display(), output.display()))?;
        Ok(counts)
    });
    let (written, failed) = finished?;
    eprintln!(
        "isoline convert: {written} frames written to {}{}",
        output.display(),
        if failed > 0 {
            format!(", {failed} left out")
        } else {
            String::new()
        }
    );
    if failed > 0 {
        bail!("{failed} frames could not be converted (see above)");
    }
    Ok(())
}

/// Reads `input` frame by frame into `out`; (frames written, frames left out).
fn convert(input: &Path, part: &Path, opts: &BagOptions, out: &mut Out) -> Result<(u64, u64)> {
    let (mut written, mut failed) = (0u64, 0u64);
    let mut write_error: Option<anyhow::Error> = None;
    let mut each = |item: std::result::Result<FrameRecord, BadFrame>| -> bool {
        let rec = match item {
            Ok(r) => r,
            Err(b) => {
                eprintln!("isoline: {}", b.message);
                failed += 1;
                return true;
            }
        };
        let done = match out {
            Out::Ndjson(w) => serde_json::to_writer(&mut *w, &rec)
                .map_err(std::io::Error::from)
                .and_then(|()| w.write_all(b"\n"))
                .map_err(|e| anyhow::anyhow!("writing {}: {e}", part.display())),
            Out::Bag(b) => match b.write(&rec) {
                Ok(()) => Ok(()),
                // A frame the bag cannot hold (points without beams) is left out.
                Err(e) => {
                    eprintln!("isoline: {}, frame {}: {e}", input.display(), rec.frame);
                    failed += 1;
                    return true;
                }
            },
        };
        match done {
            Ok(()) => {
                written += 1;
                true
            }
            Err(e) => {
                write_error = Some(e);
                false
            }
        }
    };
    read_frames(input, opts, &mut each)?;
    if let Some(e) = write_error {
        return Err(e);
    }
    Ok((written, failed))
}

/// Reads every frame of `input` (a bag, a CARMEN log or NDJSON frames) in order into
/// `each`, until it returns false. Each frame is checked as the pipeline would read it;
/// one that fails is a [`BadFrame`] in its place.
pub fn read_frames(
    input: &Path,
    opts: &BagOptions,
    each: &mut dyn FnMut(std::result::Result<FrameRecord, BadFrame>) -> bool,
) -> Result<()> {
    // Each frame is checked as the pipeline would read it; the record is what is kept.
    let check = |rec: FrameRecord| {
        isoline_io::Frame::from_record(rec.clone())
            .map(|_| rec)
            .map_err(|e| e.to_string())
    };
    if isoline_io::is_bag(input) {
        bag::read_bag_with(input, opts, check, &mut *each)?;
    } else if carmen::is_carmen(input) {
        carmen::read_carmen_with(input, check, &mut *each)?;
    } else if isoline_io::is_frame_stream(input) || isoline_io::is_compressed_frame_stream(input) {
        let text = if isoline_io::is_compressed_frame_stream(input) {
            let mut text = String::new();
            let f = std::fs::File::open(input)
                .with_context(|| format!("reading {}", input.display()))?;
            std::io::Read::read_to_string(&mut flate2::read::MultiGzDecoder::new(f), &mut text)
                .with_context(|| format!("reading {}", input.display()))?;
            text
        } else {
            super::read(input)?
        };
        let name = input.display().to_string();
        for (i, line) in text.lines().enumerate() {
            if line.trim().is_empty() {
                continue;
            }
            let item = serde_json::from_str::<FrameRecord>(line)
                .map_err(|e| e.to_string())
                .and_then(check)
                .map_err(|e| BadFrame {
                    stream: None,
                    frame: None,
                    message: format!("{name}, line {}: {e}", i + 1),
                });
            if !each(item) {
                break;
            }
        }
    } else {
        bail!(
            "{}: unknown input: not a bag (.mcap), NDJSON frames (.ndjson, .jsonl, gzipped .ndjson.gz) or a CARMEN log (.log, .clf, .carmen, or lines that start with PARAM, FLASER, ...)",
            input.display()
        );
    }
    Ok(())
}
