//! The `isoline` command line: one module per subcommand in `cli/`.

mod cli;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(
    name = "isoline",
    version,
    about = "Level-set curve reconstruction from noisy 2D points and laser scans",
    after_help = "Examples:
  isoline reconstruct fixtures/circle-500.xy -o circle.svg  # curves through points
  isoline reconstruct run.log.gz -o curves.ndjson   # every scan of a CARMEN log
  isoline map run.mcap --odometry /odom -o map.svg  # one map of a whole run
  isoline run -c config/scan-replay.toml            # the streaming daemon

Configuration: config/example.toml (every key, commented). Documentation: README.md and
docs/ (formats.md for the files, daemon.md for `run`, method.md for the method)."
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

/// The subcommands, in the order a new user reaches for them.
#[derive(Subcommand)]
enum Command {
    /// Reconstruct curves from a point file or from each frame of an NDJSON stream, a
    /// ROS 2 bag or a CARMEN log.
    Reconstruct(cli::reconstruct::Args),
    /// Fuse every scan of a recording, placed by its pose, into one world-frame curve
    /// map.
    Map(cli::map::Args),
    /// The streaming daemon: frames from a file, stdin, TCP or Kafka through the staged
    /// pipeline, each warm-started from the previous frame of its stream.
    Run(cli::run::Args),
    /// Reconstruct many files in parallel, as a TOML job file says.
    Batch(cli::batch::Args),
    /// Convert frames between ROS 2 bags (MCAP), CARMEN logs and NDJSON.
    Convert(cli::convert::Args),
    /// Publish a recording's frames to a Kafka topic, keyed by stream, at the recorded
    /// pace.
    #[cfg(feature = "kafka")]
    Publish(cli::publish::Args),
    /// Accuracy of a reconstruction against a truth file, as JSON.
    Eval(cli::eval::Args),
    /// Simulate a scanner: sample a shape with noise, outliers and motion.
    Synth(cli::synth::Args),
    /// Adapt an anisotropic mesh to a point set and draw it.
    Mesh(cli::mesh::Args),
}

/// The error and its causes, each cause left out when the message before it already
/// says it (an I/O error's text is in the message that names its file).
fn message(e: &anyhow::Error) -> String {
    let mut text = e.to_string();
    for cause in e.chain().skip(1) {
        let c = cause.to_string();
        if !text.contains(&c) {
            text.push_str(": ");
            text.push_str(&c);
        }
    }
    text
}

fn main() {
    let cli = Cli::parse();
    let result = match cli.command {
        // The daemon sets up its own logging, from its configuration.
        Command::Run(a) => cli::run::run(a),
        other => cli::init_tracing("warn", None).and_then(|_| match other {
            Command::Synth(a) => cli::synth::run(a),
            Command::Eval(a) => cli::eval::run(a),
            Command::Reconstruct(a) => cli::reconstruct::run(a),
            Command::Batch(a) => cli::batch::run(a),
            Command::Convert(a) => cli::convert::run(a),
            Command::Mesh(a) => cli::mesh::run(a),
            Command::Map(a) => cli::map::run(a),
            #[cfg(feature = "kafka")]
            Command::Publish(a) => cli::publish::run(a),
            Command::Run(_) => unreachable!("matched above"),
        }),
    };
    if let Err(e) = result {
        eprintln!("isoline: {}", message(&e));
        std::process::exit(1);
    }
}
