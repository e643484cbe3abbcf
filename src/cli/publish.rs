//! `isoline publish`: feeds a Kafka topic with a recording's frames (NDJSON frames, a
//! ROS 2 bag, a CARMEN log), one NDJSON frame a message keyed by its stream, at the
//! recorded pace, so that daemons in a consumer group have something to read.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

use anyhow::{bail, Context, Result};

use isoline::pipeline::kafka::{KafkaTopic, KafkaWriter};
use isoline::pipeline::source::{sleep_until, Pacer};
use isoline::pipeline::source::{MAX_RATE, MIN_RATE};
use isoline::pipeline::Replay;

/// `isoline publish` options.
#[derive(clap::Args)]
pub struct Args {
    /// NDJSON frames (.ndjson/.jsonl), a ROS 2 bag (.mcap) or a CARMEN log (.log, .clf, .carmen, maybe .gz, or by its lines).
    input: PathBuf,
    /// Kafka bootstrap servers, host:port[,host:port].
    #[arg(long)]
    brokers: String,
    /// The topic to write to (--topic chooses a bag's scan topics).
    #[arg(long = "to", value_name = "TOPIC")]
    topic: String,
    /// Pace: "recorded" (the frames' time stamps), "fast", or frames per second.
    #[arg(long, default_value = "recorded", value_parser = parse_replay)]
    replay: Replay,
    /// A librdkafka producer property, KEY=VALUE (repeatable).
    #[arg(long = "kafka", value_parser = parse_setting)]
    settings: Vec<(String, String)>,
    #[command(flatten)]
    bag: super::BagArgs,
}

fn parse_replay(s: &str) -> std::result::Result<Replay, String> {
    match s {
        "recorded" => Ok(Replay::Recorded),
        "fast" => Ok(Replay::Fast),
        _ => match s.parse::<f64>() {
            Ok(r) if (MIN_RATE..=MAX_RATE).contains(&r) => Ok(Replay::Rate(r)),
            _ => Err(format!(
                "expected \"recorded\", \"fast\" or frames per second in [{MIN_RATE}, {MAX_RATE}]"
            )),
        },
    }
}

fn parse_setting(s: &str) -> std::result::Result<(String, String), String> {
    match s.split_once('=') {
        Some((k, v)) if !k.trim().is_empty() => Ok((k.trim().into(), v.trim().into())),
        _ => Err("expected KEY=VALUE, e.g. linger.ms=0".into()),
    }
}

/// Publishes every frame, then waits until the broker has them all. A frame that cannot
/// be read is reported and left out, and the command fails after publishing the others.
pub fn run(a: Args) -> Result<()> {
    let opts = a.bag.options(&a.input)?;
    let topic = KafkaTopic {
        brokers: a.brokers,
        topic: a.topic,
        settings: a.settings.into_iter().collect::<BTreeMap<_, _>>(),
        stall: std::time::Duration::from_secs_f64(isoline::pipeline::kafka::DEFAULT_STALL_SECONDS),
    };
    if let Some(why) = isoline::pipeline::kafka::without_tls(&topic.settings) {
        return Err(isoline::Error::Config {
            path: "--kafka".into(),
            problems: vec![why],
        }
        .into());
    }
    let writer = KafkaWriter::open(&topic)?;
    let mut pacer = Pacer::new(a.replay);
    let never = AtomicBool::new(false);
    let (mut sent, mut failed) = (0u64, 0u64);
    let mut error = None;
    super::convert::read_frames(&a.input, &opts, &mut |item| {
        let rec = match item {
            Ok(r) => r,
            Err(b) => {
                eprintln!("isoline: {}", b.message);
                failed += 1;
                return true;
            }
        };
        if let Some(due) = pacer.deadline(rec.t, Instant::now()) {
            sleep_until(due, &never);
        }
        let sent_one = serde_json::to_vec(&rec)
            .map_err(anyhow::Error::from)
            .and_then(|payload| {
                let key = rec.stream.as_deref().unwrap_or("");
                Ok(writer.send(key, &payload)?)
            });
        match sent_one {
            Ok(()) => {
                sent += 1;
                true
            }
            Err(e) => {
                error = Some(e);
                false
            }
        }
    })?;
    if let Some(e) = error {
        return Err(e).with_context(|| format!("publishing to {}", topic.topic));
    }
    writer
        .finish()
        .with_context(|| format!("publishing to {}", topic.topic))?;
    eprintln!(
        "isoline publish: {sent} frames to {} on {}",
        topic.topic, topic.brokers
    );
    if failed > 0 {
        bail!("{failed} frames could not be read (see above)");
    }
    Ok(())
}
