//! The daemon (`isoline run`) as a user runs it: the real binary, real files, sockets and
//! signals.

use std::io::{BufRead, BufReader, Write};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::Value;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_isoline"))
}

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fixtures")
        .join(name)
}

/// Writes `toml` as `dir/daemon.toml`; relative paths in it are taken from `dir`.
fn config(dir: &Path, toml: &str) -> PathBuf {
    let path = dir.join("daemon.toml");
    std::fs::write(&path, toml).unwrap();
    path
}

/// Replays `input` as fast as the daemon takes it into `dir/out.ndjson`, with hmin 0.002,
/// `output` added to the `[output]` table and `tables` after the others; the run must
/// succeed. Returns the records and the daemon's stderr.
fn replay(dir: &Path, input: &Path, output: &str, tables: &str) -> (Vec<Value>, String) {
    let cfg = config(
        dir,
        &format!(
            "[input]\npath = {input:?}\nreplay = \"fast\"\n[output]\npath = \"out.ndjson\"\n\
             {output}\n[mesh]\nhmin = 0.002\n{tables}\n"
        ),
    );
    let out = bin()
        .args(["run", "-c", cfg.to_str().unwrap()])
        .output()
        .expect("run isoline");
    let stderr = String::from_utf8_lossy(&out.stderr).to_string();
    assert!(out.status.success(), "{stderr}");
    (records(&dir.join("out.ndjson")), stderr)
}

/// Every line of an NDJSON file, parsed; panics on a line that is not JSON (a record cut
/// short by a shutdown would be one).
fn records(path: &Path) -> Vec<Value> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("not JSON ({e}): {l}")))
        .collect()
}

fn frame_ids(recs: &[Value]) -> Vec<u64> {
    recs.iter().map(|r| r["frame"].as_u64().unwrap()).collect()
}

#[test]
fn a_replayed_stream_gets_one_record_per_frame_in_order_mostly_warm() {
    let dir = tempfile::tempdir().unwrap();
    let input = fixture("ellipse-stream-20.ndjson");
    let (recs, stderr) = replay(dir.path(), &input, "svg_dir = \"svg\"", "");
    assert!(
        stderr.contains("20 records (20 reconstructed, 0 errors, 0 skipped)"),
        "{stderr}"
    );
    assert_eq!(frame_ids(&recs), (0..20).collect::<Vec<_>>());
    for r in &recs {
        assert_eq!(r["stream"], "lidar0");
        assert_eq!(
            r["polylines"].as_array().unwrap().len(),
            1,
            "{}",
            r["stats"]
        );
        let ms = &r["stats"]["ms"];
        assert!(ms["latency"].as_f64().unwrap() >= ms["total"].as_f64().unwrap() * 0.99);
    }
    let warm = recs
        .iter()
        .filter(|r| r["stats"]["warm_start"] == true)
        .count();
    // The first frame has nothing to start from; the motion (0.003 per frame) is within
    // every later frame's warm-start reach.
    assert_eq!(recs[0]["stats"]["warm_start"], false);
    assert_eq!(warm, 19);
    assert!(dir.path().join("svg/lidar0-000019.svg").exists());
}

#[test]
fn a_malformed_line_gets_an_error_record_and_the_stream_goes_on() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(fixture("ellipse-stream-20.ndjson")).unwrap();
    let mut lines: Vec<String> = text.lines().take(4).map(str::to_string).collect();
    lines[1] = r#"{"stream":"lidar0","frame":1,"points":[[0.1,"#.to_string();
    lines[2] = r#"{"stream":"lidar0","frame":2,"points":[[0.5,0.5]]}"#.to_string();
    let input = dir.path().join("in.ndjson");
    std::fs::write(&input, lines.join("\n") + "\n").unwrap();
    let (recs, _) = replay(dir.path(), &input, "", "");
    assert_eq!(frame_ids(&recs), vec![0, 1, 2, 3]);
    let e1 = recs[1]["error"].as_str().unwrap();
    assert!(e1.contains("in.ndjson, line 2"), "{e1}");
    // A truncated line is not JSON: its stream and number are read up to the cut, and
    // its record names the line.
    assert_eq!(recs[1]["stream"], "lidar0");
    assert_eq!(recs[1]["line"], 2);
    let e2 = recs[2]["error"].as_str().unwrap();
    assert!(e2.contains("point") || e2.contains("coincide"), "{e2}");
    assert_eq!(recs[2]["stream"], "lidar0");
    assert!(recs[3]["polylines"]
        .as_array()
        .is_some_and(|p| !p.is_empty()));
    assert_eq!(recs[3]["stats"]["warm_start"], true);
}

/// Starts the daemon with piped stderr; returns it and its stderr lines.
fn spawn(cfg: &Path) -> (Child, std::sync::mpsc::Receiver<String>) {
    let mut child = bin()
        .args(["run", "-c", cfg.to_str().unwrap()])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start isoline");
    let stderr = child.stderr.take().unwrap();
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            let _ = tx.send(line);
        }
    });
    (child, rx)
}

fn signal(child: &Child, sig: &str) {
    let ok = Command::new("kill")
        .args([sig, &child.id().to_string()])
        .status()
        .unwrap()
        .success();
    assert!(ok, "kill {sig}");
}

fn wait(child: &mut Child, limit: Duration) -> std::process::ExitStatus {
    let t0 = Instant::now();
    loop {
        if let Some(s) = child.try_wait().unwrap() {
            return s;
        }
        assert!(
            t0.elapsed() < limit,
            "the daemon did not exit within {limit:?}"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn frames_from_two_tcp_clients_are_kept_apart() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = config(
        dir.path(),
        "[input]\nkind = \"tcp\"\nbind = \"127.0.0.1:0\"\n[output]\npath = \"out.ndjson\"\n\
         [mesh]\nhmin = 0.002\n",
    );
    let (mut child, stderr) = spawn(&cfg);
    let addr = loop {
        let line = stderr
            .recv_timeout(Duration::from_secs(30))
            .expect("the daemon says where it listens");
        if let Some(a) = line.strip_prefix("isoline run: listening on ") {
            break a.to_string();
        }
    };
    let frames: Vec<String> = std::fs::read_to_string(fixture("ellipse-stream-20.ndjson"))
        .unwrap()
        .lines()
        .take(3)
        .map(str::to_string)
        .collect();
    // Client A names its stream; client B sends frames without one, which get the
    // stream "tcp:PEER".
    let clients: Vec<_> = (0..2)
        .map(|c| {
            let (addr, frames) = (addr.clone(), frames.clone());
            std::thread::spawn(move || {
                let mut s = TcpStream::connect(&addr).unwrap();
                for f in &frames {
                    let mut v: Value = serde_json::from_str(f).unwrap();
                    if c == 0 {
                        v["stream"] = "a".into();
                    } else {
                        v.as_object_mut().unwrap().remove("stream");
                    }
                    writeln!(s, "{v}").unwrap();
                }
                s.local_addr().unwrap().to_string()
            })
        })
        .collect();
    let peers: Vec<String> = clients.into_iter().map(|c| c.join().unwrap()).collect();
    // The listener never ends by itself: wait for the six records, then stop it.
    let out = dir.path().join("out.ndjson");
    let t0 = Instant::now();
    while std::fs::read_to_string(&out).map_or(0, |s| s.lines().count()) < 6 {
        assert!(
            t0.elapsed() < Duration::from_secs(60),
            "records did not arrive"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    signal(&child, "-TERM");
    assert!(wait(&mut child, Duration::from_secs(30)).success());
    let recs = records(&out);
    assert_eq!(recs.len(), 6);
    let b = format!("tcp:{}", peers[1]);
    for stream in ["a", b.as_str()] {
        let mine: Vec<&Value> = recs.iter().filter(|r| r["stream"] == stream).collect();
        assert_eq!(
            frame_ids(&mine.iter().map(|r| (*r).clone()).collect::<Vec<_>>()),
            vec![0, 1, 2],
            "{stream}"
        );
        // Each stream has its own warm-start state: its first frame starts cold.
        let warm: Vec<bool> = mine
            .iter()
            .map(|r| r["stats"]["warm_start"] == true)
            .collect();
        assert_eq!(warm, vec![false, true, true], "{stream}");
    }
}

#[test]
fn sigterm_mid_stream_finishes_the_frames_read_and_exits_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let trace = dir.path().join("trace.json");
    let cfg = config(
        dir.path(),
        &format!(
            "[input]\npath = {:?}\nreplay = 8\n[output]\npath = \"out.ndjson\"\n\
             [tracing]\nchrome_trace = \"trace.json\"\n[mesh]\nhmin = 0.002\n",
            fixture("ellipse-stream-20.ndjson")
        ),
    );
    let (mut child, _stderr) = spawn(&cfg);
    // At 8 frames per second, 20 frames take 2.5 s: stop after about half of them.
    let out = dir.path().join("out.ndjson");
    let t0 = Instant::now();
    while std::fs::read_to_string(&out).map_or(0, |s| s.lines().count()) < 4 {
        assert!(
            t0.elapsed() < Duration::from_secs(60),
            "records did not arrive"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    signal(&child, "-TERM");
    let status = wait(&mut child, Duration::from_secs(30));
    assert!(status.success(), "{status:?}");
    let recs = records(&out);
    let n = recs.len() as u64;
    assert!((4..20).contains(&n), "{n} records");
    // No gap: every frame read before the signal has its record.
    assert_eq!(frame_ids(&recs), (0..n).collect::<Vec<_>>());
    assert!(recs.iter().all(|r| r["polylines"].is_array()));

    // The trace: one span per stage per frame, each with the frame's id.
    let events: Vec<Value> =
        serde_json::from_str(&std::fs::read_to_string(&trace).unwrap()).expect("the trace is JSON");
    for stage in ["distance", "adapt", "solve", "renormalize", "export"] {
        let mut frames: Vec<u64> = events
            .iter()
            .filter(|e| e["name"] == stage && e["ph"] == "B")
            .map(|e| {
                let id = e["args"]["frame"].as_str().expect("frame id in the span");
                id.parse::<u64>().unwrap()
            })
            .collect();
        frames.sort_unstable();
        assert_eq!(frames, (0..n).collect::<Vec<_>>(), "{stage}");
        // tracing-chrome writes field values in their Debug form: "\"lidar0\"".
        assert!(events.iter().any(|e| e["name"] == stage
            && e["args"]["stream"].as_str().map(|s| s.trim_matches('"')) == Some("lidar0")));
    }
}

/// Accuracy under streaming: each frame of a moving stream, warm-started, within the
/// bound the one-shot reconstruction meets (3 sigma + 2 hmin, issue 3).
#[test]
fn every_streamed_frame_is_as_accurate_as_a_one_shot_reconstruction() {
    let dir = tempfile::tempdir().unwrap();
    let frames = dir.path().join("frames.ndjson");
    let truth = dir.path().join("truth.json");
    let (sigma, hmin) = (0.003, 0.002);
    let out = bin()
        .args([
            "synth", "ellipse", "--points", "1000", "--noise", "0.003", "--frames", "8",
        ])
        .args(["--motion", "0.003", "--seed", "11", "-o"])
        .arg(&frames)
        .arg("--truth")
        .arg(&truth)
        .output()
        .unwrap();
    assert!(out.status.success());
    let (recs, _) = replay(dir.path(), &frames, "", "");
    let truth: isoline_io::format::TruthFile =
        serde_json::from_str(&std::fs::read_to_string(&truth).unwrap()).unwrap();
    assert_eq!(recs.len(), 8);
    let bound = 3.0 * sigma + 2.0 * hmin;
    for r in &recs {
        let rec: isoline_io::format::ResultRecord = serde_json::from_value(r.clone()).unwrap();
        let polylines: Vec<isoline_core::geom::Polyline> =
            rec.polylines.unwrap().into_iter().map(Into::into).collect();
        let acc = isoline_sim::compare(&polylines, &truth.for_frame(rec.frame), None);
        let h = acc.hausdorff.unwrap();
        assert!(
            h <= bound,
            "frame {}: Hausdorff {h} > {bound}",
            rec.frame.unwrap()
        );
        assert_eq!(acc.components_recon, 1);
    }
}

#[test]
fn latest_skips_stale_frames_and_records_each_one() {
    let dir = tempfile::tempdir().unwrap();
    // Replayed as fast as it reads, the stream outruns the stages by far: with one-frame
    // queues and the `latest` policy they drop the frames that went stale meanwhile.
    // The fixture's frames five times over (100, numbered on), so that the reader, even
    // when a loaded machine holds it back for a while, still outruns the stages.
    let text = std::fs::read_to_string(fixture("ellipse-stream-20.ndjson")).unwrap();
    let mut frames = String::new();
    for (k, line) in text.lines().cycle().take(100).enumerate() {
        let mut v: Value = serde_json::from_str(line).unwrap();
        v["frame"] = k.into();
        v["t"] = (0.1 * k as f64).into();
        frames.push_str(&format!("{v}\n"));
    }
    let input = dir.path().join("frames.ndjson");
    std::fs::write(&input, frames).unwrap();
    let (recs, stderr) = replay(
        dir.path(),
        &input,
        "",
        "[pipeline]\nqueue = 1\npolicy = \"latest\"",
    );
    assert_eq!(frame_ids(&recs), (0..100).collect::<Vec<_>>());
    let skipped: Vec<&Value> = recs.iter().filter(|r| r["skipped"] == true).collect();
    assert!(!skipped.is_empty(), "nothing skipped: {stderr}");
    for r in &skipped {
        assert!(r["error"].as_str().unwrap().contains("skipped"));
        assert!(r.get("polylines").is_none());
    }
    // The newest frame is never stale.
    assert!(recs[99]["polylines"].is_array());
    assert!(
        stderr.contains(&format!("{} skipped", skipped.len())),
        "{stderr}"
    );
}

#[test]
fn frames_on_stdin_give_records_on_stdout() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = config(
        dir.path(),
        "[input]\nkind = \"stdin\"\n[mesh]\nhmin = 0.002\n",
    );
    let text = std::fs::read_to_string(fixture("ellipse-stream-20.ndjson")).unwrap();
    let input: String = text.lines().take(3).map(|l| format!("{l}\n")).collect();
    let mut child = bin()
        .args(["run", "-c", cfg.to_str().unwrap()])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Closing stdin is the end of input.
    child
        .stdin
        .take()
        .unwrap()
        .write_all(input.as_bytes())
        .unwrap();
    let out = child.wait_with_output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let recs: Vec<Value> = String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(frame_ids(&recs), vec![0, 1, 2]);
    assert!(recs.iter().all(|r| r["polylines"].is_array()));
}

#[test]
fn a_recorded_replay_keeps_the_time_stamps() {
    let dir = tempfile::tempdir().unwrap();
    // Six frames stamped 0.2 s apart: a recorded replay takes at least 1 s, where the
    // same frames as fast as possible take about a third of that here.
    let text = std::fs::read_to_string(fixture("ellipse-stream-20.ndjson")).unwrap();
    let input = dir.path().join("in.ndjson");
    let six: String = text
        .lines()
        .take(6)
        .enumerate()
        .map(|(k, l)| {
            let mut v: Value = serde_json::from_str(l).unwrap();
            v["t"] = (0.2 * k as f64).into();
            format!("{v}\n")
        })
        .collect();
    std::fs::write(&input, six).unwrap();
    let cfg = config(
        dir.path(),
        "[input]\npath = \"in.ndjson\"\nreplay = \"recorded\"\n[output]\npath = \"out.ndjson\"\n\
         [mesh]\nhmin = 0.002\n",
    );
    let t0 = Instant::now();
    let out = bin()
        .args(["run", "-c", cfg.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(out.status.success());
    // A lower bound only: how much longer the run takes depends on the machine.
    assert!(
        t0.elapsed() >= Duration::from_millis(1000),
        "{:?}",
        t0.elapsed()
    );
    assert_eq!(records(&dir.path().join("out.ndjson")).len(), 6);
}

#[test]
fn configurations_that_would_destroy_data_or_hang_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let text: String = std::fs::read_to_string(fixture("ellipse-stream-20.ndjson"))
        .unwrap()
        .lines()
        .take(3)
        .map(|l| format!("{l}\n"))
        .collect();
    std::fs::write(d.join("in.ndjson"), &text).unwrap();
    let run = |toml: &str| {
        let out = bin()
            .args(["run", "-c", config(d, toml).to_str().unwrap()])
            .output()
            .unwrap();
        (
            out.status.success(),
            String::from_utf8_lossy(&out.stderr).to_string(),
        )
    };
    for (toml, needle) in [
        (
            "[input]\npath = \"in.ndjson\"\n[output]\npath = \"./in.ndjson\"\n",
            "is the input file",
        ),
        (
            "[input]\npath = \"in.ndjson\"\n[tracing]\nchrome_trace = \"in.ndjson\"\n",
            "is the input file",
        ),
        ("[input]\npath = \".\"\n", "a folder"),
        (
            "[input]\npath = \"in.ndjson\"\nreplay = 1e-19\n",
            "input.replay",
        ),
        (
            "[input]\nkind = \"tcp\"\nbind = \"0.0.0.0:0\"\n",
            "input.allow_remote = true",
        ),
        (
            "[input]\nkind = \"stdin\"\nmax_line_bytes = 10\n",
            "input.max_line_bytes",
        ),
        ("[pipeline]\nmax_streams = 0\n", "pipeline.max_streams"),
    ] {
        let (ok, stderr) = run(toml);
        assert!(!ok && stderr.contains(needle), "{toml}: {stderr}");
    }
    assert_eq!(std::fs::read_to_string(d.join("in.ndjson")).unwrap(), text);

    // A full disk ends the run with an error that names the output.
    let (ok, stderr) =
        run("[input]\npath = \"in.ndjson\"\nreplay = \"fast\"\n[output]\npath = \"/dev/full\"\n");
    assert!(!ok && stderr.contains("/dev/full"), "{stderr}");

    // Wild time stamps neither panic nor stall a recorded replay.
    let stamps: String = text
        .lines()
        .zip([1e19, 0.0, -1e300])
        .map(|(l, t)| {
            let mut v: Value = serde_json::from_str(l).unwrap();
            v["t"] = t.into();
            format!("{v}\n")
        })
        .collect();
    std::fs::write(d.join("stamps.ndjson"), stamps).unwrap();
    let t0 = Instant::now();
    let (ok, stderr) = run(
        "[input]\npath = \"stamps.ndjson\"\n[output]\npath = \"out.ndjson\"\n[mesh]\nhmin = 0.002\n",
    );
    assert!(ok, "{stderr}");
    assert!(t0.elapsed() < Duration::from_secs(20));
    assert_eq!(records(&d.join("out.ndjson")).len(), 3);
}

/// `GET path` from the HTTP server at `addr`: (status code, body).
fn http_get(addr: &str, path: &str) -> (u16, String) {
    use std::io::Read;
    let mut s = TcpStream::connect(addr).unwrap();
    write!(s, "GET {path} HTTP/1.0\r\nHost: {addr}\r\n\r\n").unwrap();
    let mut text = String::new();
    s.read_to_string(&mut text).unwrap();
    let code = text.split_whitespace().nth(1).unwrap().parse().unwrap();
    let body = text.split_once("\r\n\r\n").map_or("", |b| b.1).to_string();
    (code, body)
}

/// The value of the Prometheus sample `name` (with its labels) in `text`.
fn sample(text: &str, name: &str) -> f64 {
    text.lines()
        .find_map(|l| l.strip_prefix(name).and_then(|v| v.strip_prefix(' ')))
        .unwrap_or_else(|| panic!("{name} not in\n{text}"))
        .trim()
        .parse()
        .unwrap()
}

/// The metrics endpoint, scraped during a TCP stream and once every record is written:
/// frames in, records by outcome, warm starts and the latency histogram's count add up
/// to the records written; the health check says the daemon keeps up.
#[test]
fn the_metrics_add_up_to_the_records_written() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = config(
        dir.path(),
        "[input]\nkind = \"tcp\"\nbind = \"127.0.0.1:0\"\n[output]\npath = \"out.ndjson\"\n\
         [metrics]\nbind = \"127.0.0.1:0\"\n[mesh]\nhmin = 0.002\n",
    );
    let (mut child, stderr) = spawn(&cfg);
    let (mut tcp, mut metrics) = (None, None);
    while tcp.is_none() || metrics.is_none() {
        let line = stderr
            .recv_timeout(Duration::from_secs(30))
            .expect("the daemon says where it listens");
        if let Some(a) = line.strip_prefix("isoline run: listening on ") {
            tcp = Some(a.to_string());
        }
        if let Some(a) = line.strip_prefix("isoline run: metrics on http://") {
            metrics = Some(a.split('/').next().unwrap().to_string());
        }
    }
    let (tcp, metrics) = (tcp.unwrap(), metrics.unwrap());
    let frames: Vec<String> = std::fs::read_to_string(fixture("ellipse-stream-20.ndjson"))
        .unwrap()
        .lines()
        .take(12)
        .map(str::to_string)
        .collect();
    let mut s = TcpStream::connect(&tcp).unwrap();
    for (k, f) in frames.iter().enumerate() {
        writeln!(s, "{f}").unwrap();
        if k == 5 {
            writeln!(s, "{{\"frame\":99,\"points\":[[0,\"x\"]]}}").unwrap();
        }
    }
    drop(s);
    let out = dir.path().join("out.ndjson");
    let written = |text: &str| -> f64 {
        ["reconstructed", "error", "skipped"]
            .iter()
            .map(|o| sample(text, &format!("isoline_records_total{{outcome=\"{o}\"}}")))
            .sum()
    };
    // Scraped while the frames go through: never more out than in, and never a record
    // counted before it is in the file (a record is counted once written).
    let t0 = Instant::now();
    let text = loop {
        assert!(
            t0.elapsed() < Duration::from_secs(60),
            "records did not arrive"
        );
        let (code, text) = http_get(&metrics, "/metrics");
        assert_eq!(code, 200);
        let n = written(&text);
        assert!(n <= sample(&text, "isoline_frames_in_total"));
        // Whole lines only: the newest may be half read while it is written.
        let lines = std::fs::read(&out).map_or(0, |b| b.iter().filter(|&&c| c == b'\n').count());
        assert!(n <= lines as f64);
        if n == 13.0 {
            break text;
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let recs = records(&out);
    assert_eq!(recs.len(), 13);
    let count = |f: &dyn Fn(&Value) -> bool| recs.iter().filter(|r| f(r)).count() as f64;
    assert_eq!(sample(&text, "isoline_frames_in_total"), 13.0);
    assert_eq!(
        sample(&text, "isoline_records_total{outcome=\"reconstructed\"}"),
        count(&|r| r.get("polylines").is_some())
    );
    assert_eq!(
        sample(&text, "isoline_records_total{outcome=\"error\"}"),
        count(&|r| r.get("error").is_some())
    );
    assert_eq!(
        sample(&text, "isoline_records_total{outcome=\"error\"}"),
        1.0
    );
    assert_eq!(
        sample(&text, "isoline_warm_starts_total"),
        count(&|r| r["stats"]["warm_start"] == true)
    );
    assert_eq!(sample(&text, "isoline_frame_latency_seconds_count"), 12.0);
    assert_eq!(
        sample(&text, "isoline_stage_seconds_count{stage=\"solve\"}"),
        12.0
    );
    assert_eq!(http_get(&metrics, "/health"), (200, "ok\n".to_string()));
    assert_eq!(http_get(&metrics, "/nothing").0, 404);
    signal(&child, "-TERM");
    assert!(wait(&mut child, Duration::from_secs(30)).success());
}

/// Refinement state has a byte budget: with `max_state_bytes` shared by `max_streams`,
/// every stream's window stays within its share (the oldest frames leave first), what
/// the frame count would allow notwithstanding, and the record says how much it held.
#[test]
fn refinement_windows_hold_their_byte_budget() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut text = String::new();
    for (k, s) in ["a", "b"].iter().enumerate() {
        let path = d.join(format!("{s}.ndjson"));
        let seed = (k + 1).to_string();
        crate::common::synth_room(&path, 5, 0.05, &["--seed", &seed, "--stream", s]);
        text.push_str(&std::fs::read_to_string(&path).unwrap());
    }
    let input = d.join("in.ndjson");
    std::fs::write(&input, text).unwrap();
    // 2 MiB for 4 streams: 512 KiB a window, about three frames of a 1,080-beam scan
    // (its curves, subdivided, and its returns).
    let (recs, _) = replay(
        d,
        &input,
        "",
        "[pipeline]\naccumulate = 10\nmax_streams = 4\nmax_state_bytes = 2097152\n",
    );
    assert_eq!(recs.len(), 10);
    let windows: Vec<&Value> = recs
        .iter()
        .filter_map(|r| {
            r["stats"]["window"]
                .as_object()
                .map(|_| &r["stats"]["window"])
        })
        .collect();
    assert_eq!(windows.len(), 10);
    for w in &windows {
        assert!(w["bytes"].as_u64().unwrap() <= 512 << 10, "{w}");
    }
    let most = windows
        .iter()
        .map(|w| w["frames"].as_u64().unwrap())
        .max()
        .unwrap();
    // Without the budget each stream's window would hold all its 5 frames.
    assert!((2..5).contains(&most), "{most} frames at most");
}

/// `register = true`: each stream registered on its own. Stream `a` comes with poses
/// 10% too long a step (odometry's scale error), stream `b` with none; every record
/// carries its `registered_pose`, which lies near the simulator's pose where the input
/// drifted away from it.
#[test]
fn registration_gives_each_stream_poses_of_its_own() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut truth: Vec<Vec<[f64; 3]>> = Vec::new();
    let mut lines: Vec<Vec<String>> = Vec::new();
    for (k, s) in ["a", "b"].iter().enumerate() {
        let path = d.join(format!("{s}.ndjson"));
        let seed = (k + 1).to_string();
        crate::common::synth_room(
            &path,
            30,
            0.1,
            &["--noise", "0.01", "--seed", &seed, "--stream", s],
        );
        let (mut t, mut l) = (Vec::new(), Vec::new());
        let mut prev: Option<[f64; 3]> = None;
        let mut odom = [0.0; 3];
        for line in std::fs::read_to_string(&path).unwrap().lines() {
            let mut v: Value = serde_json::from_str(line).unwrap();
            let pose: [f64; 3] = serde_json::from_value(v["pose"].clone()).unwrap();
            odom = match prev {
                None => pose,
                Some(p) => {
                    // The step in the previous pose's frame, 10% too long.
                    let (s, c) = p[2].sin_cos();
                    let (dx, dy) = (pose[0] - p[0], pose[1] - p[1]);
                    let (fx, fy) = (1.1 * (c * dx + s * dy), 1.1 * (-s * dx + c * dy));
                    let (so, co) = odom[2].sin_cos();
                    [
                        odom[0] + co * fx - so * fy,
                        odom[1] + so * fx + co * fy,
                        odom[2] + pose[2] - p[2],
                    ]
                }
            };
            prev = Some(pose);
            if *s == "a" {
                v["pose"] = serde_json::json!(odom);
            } else {
                v.as_object_mut().unwrap().remove("pose");
            }
            t.push(pose);
            l.push(v.to_string());
        }
        truth.push(t);
        lines.push(l);
    }
    // The streams interleaved, frame by frame.
    let text: String = (0..30)
        .flat_map(|k| [&lines[0][k], &lines[1][k]])
        .map(|l| format!("{l}\n"))
        .collect();
    let input = d.join("in.ndjson");
    std::fs::write(&input, text).unwrap();
    let (recs, _) = replay(d, &input, "", "[pipeline]\nregister = true\n");
    assert_eq!(recs.len(), 60);
    let worst = |stream: &str, key: &str| -> f64 {
        recs.iter()
            .filter(|r| r["stream"] == stream)
            .map(|r| {
                let k = r["frame"].as_u64().unwrap() as usize;
                let t = truth[usize::from(stream == "b")][k];
                let p: [f64; 3] = serde_json::from_value(r[key].clone()).unwrap();
                // Stream b's world is its first scan's frame: compare from there.
                let (t0, p0) = if stream == "b" {
                    let t0 = truth[1][0];
                    (t0, [0.0, 0.0, 0.0])
                } else {
                    (truth[0][0], truth[0][0])
                };
                let rel = |a: [f64; 3], o: [f64; 3]| {
                    let (s, c) = o[2].sin_cos();
                    let (dx, dy) = (a[0] - o[0], a[1] - o[1]);
                    [c * dx + s * dy, -s * dx + c * dy]
                };
                let (a, b) = (rel(p, p0), rel(t, t0));
                (a[0] - b[0]).hypot(a[1] - b[1])
            })
            .fold(0.0, f64::max)
    };
    // The input drifts by a tenth of the path (2.9 m of it: some 30 cm); the estimate
    // stays within 2 cm of the truth (1 cm noise, returns several metres away).
    assert!(worst("a", "pose") > 0.2);
    assert!(
        worst("a", "registered_pose") < 0.02,
        "{}",
        worst("a", "registered_pose")
    );
    assert!(recs
        .iter()
        .filter(|r| r["stream"] == "b")
        .all(|r| r.get("pose").is_none()));
    assert!(
        worst("b", "registered_pose") < 0.02,
        "{}",
        worst("b", "registered_pose")
    );
}
