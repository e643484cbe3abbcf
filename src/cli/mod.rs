//! The subcommands, one module each, and what they share: logging and file helpers.

pub mod batch;
pub mod convert;
pub mod eval;
pub mod map;
pub mod mesh;
#[cfg(feature = "kafka")]
pub mod publish;
pub mod reconstruct;
pub mod run;
pub mod synth;

use std::path::Path;

use anyhow::{Context, Result};

/// Logs to stderr, filtered by `RUST_LOG` or else `default`; with `chrome`, also writes
/// every span of isoline's stages (whatever the log filter) as a Chrome/Perfetto trace,
/// complete once the returned guard is dropped.
pub fn init_tracing(
    default: &str,
    chrome: Option<&Path>,
) -> Result<Option<tracing_chrome::FlushGuard>> {
    use std::io::IsTerminal;
    use tracing_subscriber::prelude::*;
    use tracing_subscriber::EnvFilter;
    let filter = EnvFilter::try_from_default_env().unwrap_or_else(|_| EnvFilter::new(default));
    let (chrome_layer, guard) = match chrome {
        Some(path) => {
            let file = create(path)?;
            let (layer, guard) = tracing_chrome::ChromeLayerBuilder::new()
                .writer(file)
                .include_args(true)
                .build();
            let spans = tracing_subscriber::filter::Targets::new()
                .with_target("isoline", tracing::Level::INFO);
            (Some(layer.with_filter(spans)), Some(guard))
        }
        None => (None, None),
    };
    tracing_subscriber::registry()
        .with(
            tracing_subscriber::fmt::layer()
                .with_writer(std::io::stderr)
                // Colours for a terminal only: a log file or a pipe gets plain text
                // (NO_COLOR turns them off on a terminal too).
                .with_ansi(ansi(std::io::stderr().is_terminal()))
                .with_filter(filter),
        )
        .with(chrome_layer)
        .try_init()
        .context("setting up tracing")?;
    Ok(guard)
}

/// Whether to colour the log: on a terminal, unless `NO_COLOR` is set (no-color.org).
fn ansi(terminal: bool) -> bool {
    terminal && std::env::var_os("NO_COLOR").is_none_or(|v| v.is_empty())
}

/// Creates (or truncates) `path`, naming it in the error.
pub fn create(path: &Path) -> Result<std::fs::File> {
    std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))
}

/// Reads `path` as text, naming it in the error.
pub fn read(path: &Path) -> Result<String> {
    std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))
}

/// Writes `text` to standard output. A reader that has gone (`| head`) is not an error:
/// the output is simply not wanted any more.
pub fn print(text: &str) -> Result<()> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    match out.write_all(text.as_bytes()).and_then(|()| out.flush()) {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        r => r.context("writing to standard output"),
    }
}

/// Refuses to run when one of `outputs` is the file `input` (it would be overwritten)
/// or two of them are one file (the second would replace the first).
pub fn refuse_overwrite(input: &Path, outputs: &[Option<&Path>]) -> Result<()> {
    let outputs: Vec<&Path> = outputs.iter().flatten().copied().collect();
    for (k, out) in outputs.iter().enumerate() {
        if isoline::same_file(input, out) {
            anyhow::bail!(
                "{} is the input file; writing there would destroy it",
                out.display()
            );
        }
        if let Some(other) = outputs[..k].iter().find(|o| isoline::same_file(o, out)) {
            anyhow::bail!(
                "{} and {} are one file: one output would replace the other",
                other.display(),
                out.display()
            );
        }
    }
    Ok(())
}

/// Fails, naming the path, unless each of `outputs` can be written: checked before the
/// work, not after it.
pub fn check_writable(outputs: &[Option<&Path>]) -> Result<()> {
    for p in outputs.iter().flatten() {
        isoline_io::write::PartFile::probe(p)
            .with_context(|| format!("{} cannot be written", p.display()))?;
    }
    Ok(())
}

/// Writes `text` to `path` through a temporary file renamed into place (a failed or
/// killed write leaves no partial file under the name), naming it in the error.
pub fn write(path: &Path, text: impl AsRef<[u8]>) -> Result<()> {
    isoline_io::write::write_atomic(path, text.as_ref())
        .with_context(|| format!("writing {}", path.display()))
}

/// A [`PartFile`](isoline_io::write::PartFile) for `path` and the file to write.
pub fn create_part(path: &Path) -> Result<(isoline_io::write::PartFile, std::fs::File)> {
    isoline_io::write::PartFile::create(path)
        .with_context(|| format!("creating {}", path.display()))
}

/// What to read from a ROS 2 bag, on the command lines that read one.
#[derive(clap::Args, Default)]
pub struct BagArgs {
    /// Bag input: read this LaserScan topic (repeat for several; default: all).
    #[arg(long = "topic")]
    topics: Vec<String>,
    /// Bag input: the nav_msgs/Odometry topic that gives the scans' poses.
    #[arg(long)]
    odometry: Option<String>,
    /// Bag input: the frame the poses are in, through /tf (default: the odometry's).
    #[arg(long)]
    world_frame: Option<String>,
    /// NDJSON input: the longest line read, bytes (default 16 MiB; a frame of a
    /// million points is a line of about 21 MB). A longer line is a bad frame.
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=1 << 34))]
    max_line_bytes: Option<u64>,
}

impl BagArgs {
    /// The options, refused unless `input` is a bag when any is given.
    pub fn options(self, input: &Path) -> Result<isoline_io::bag::BagOptions> {
        if self.max_line_bytes.is_some()
            && !(isoline_io::is_frame_stream(input)
                || isoline_io::is_compressed_frame_stream(input))
        {
            anyhow::bail!(
                "--max-line-bytes applies to an NDJSON input (.ndjson, .jsonl, maybe .gz)"
            );
        }
        let opts = isoline_io::bag::BagOptions {
            topics: self.topics,
            odometry: self.odometry,
            world_frame: self.world_frame,
        };
        if opts != Default::default() && !isoline_io::is_bag(input) {
            anyhow::bail!("--topic, --odometry and --world-frame apply to a bag input (.mcap)");
        }
        Ok(opts)
    }
}

impl BagArgs {
    /// The longest NDJSON line to read.
    pub fn line_cap(&self) -> usize {
        self.max_line_bytes
            .map_or(isoline_io::MAX_FRAME_LINE_BYTES, |n| n as usize)
    }
}

/// The configuration file, or the defaults.
pub fn load_config(path: Option<&Path>) -> Result<isoline::config::Config> {
    Ok(match path {
        Some(p) => isoline::config::Config::load(p)?,
        None => isoline::config::Config::default(),
    })
}
