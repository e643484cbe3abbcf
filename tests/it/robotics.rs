//! Robotics formats through the binary: ROS 2 bags (MCAP, LaserScan with Odometry and
//! `/tf_static`) and CARMEN logs in, MCAP with Foxglove scene updates out, the live
//! view over the Foxglove WebSocket protocol, and `convert` both ways. Every recording
//! is written here, from the simulator's scenes; the curves are scored against its truth.

use std::collections::{BTreeMap, BTreeSet};
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use crate::common::{fails, ok, p};
use isoline_io::format::FrameRecord;
use isoline_io::ros;
use serde_json::Value;

/// The laser sits this far ahead of the robot's base (the `/tf_static` link).
const LASER_X: f64 = 0.2;

/// A simulated scan stream: its frames and the files.
struct Sim {
    frames: Vec<FrameRecord>,
    path: PathBuf,
    truth: PathBuf,
}

/// `n` Hokuyo-like scans of the room, 1 cm range noise, driving `motion` m a frame.
fn simulate(dir: &Path, n: usize, motion: f64) -> Sim {
    let path = dir.join("frames.ndjson");
    let truth = dir.join("truth.json");
    ok(&[
        "synth",
        "room",
        "--noise",
        "0.01",
        "--frames",
        &n.to_string(),
        "--motion",
        &motion.to_string(),
        "--seed",
        "3",
        "-o",
        p(&path),
        "--truth",
        p(&truth),
    ]);
    let frames = std::fs::read_to_string(&path)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    Sim {
        frames,
        path,
        truth,
    }
}

fn compose(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    let (s, c) = a[2].sin_cos();
    [
        a[0] + c * b[0] - s * b[1],
        a[1] + s * b[0] + c * b[1],
        a[2] + b[2],
    ]
}

/// A bag as a robot records it: the scans on `/scan` in frame `laser`, the base's
/// odometry on `/odom` (written after each scan, so a scan's pose comes later in the
/// file), the laser's mount on `/tf_static`. `spoil` may replace a scan's bytes.
fn write_bag(path: &Path, sim: &Sim, spoil: impl Fn(usize, Vec<u8>) -> Vec<u8>) {
    write_bag_with(path, sim, false, false, spoil);
}

/// [`write_bag`], with the base's pose on `/tf` (`odom` to `base_link`) instead of
/// `/odom` when `tf` is set, and chunks not compressed when `plain` is.
fn write_bag_with(
    path: &Path,
    sim: &Sim,
    tf: bool,
    plain: bool,
    spoil: impl Fn(usize, Vec<u8>) -> Vec<u8>,
) {
    let file = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    // Small chunks, so that a file cut short keeps the chunks before the cut.
    let mut options = mcap::WriteOptions::new()
        .profile("ros2")
        .chunk_size(Some(8 << 10));
    if plain {
        options = options.compression(None);
    }
    let mut w = options.create(file).unwrap();
    let mut schema = |name: &str| {
        w.add_schema(name, "ros2msg", ros::schema_text(name).unwrap().as_bytes())
            .unwrap()
    };
    let (s_scan, s_odom, s_tf) = (
        schema(ros::LASER_SCAN),
        schema(ros::ODOMETRY),
        schema(ros::TF_MESSAGE),
    );
    let none = BTreeMap::new();
    let scan_ch = w.add_channel(s_scan, "/scan", "cdr", &none).unwrap();
    let odom_ch = w.add_channel(s_odom, "/odom", "cdr", &none).unwrap();
    let tf_ch = w.add_channel(s_tf, "/tf_static", "cdr", &none).unwrap();
    let tf_dyn = w.add_channel(s_tf, "/tf", "cdr", &none).unwrap();
    let mut seq = 0;
    let mut put = |w: &mut mcap::Writer<_>, ch, t: f64, data: &[u8]| {
        seq += 1;
        let ns = (t * 1e9) as u64;
        w.write_to_known_channel(
            &mcap::records::MessageHeader {
                channel_id: ch,
                sequence: seq,
                log_time: ns,
                publish_time: ns,
            },
            data,
        )
        .unwrap();
    };
    let t0 = 1_700_000_000.0;
    let mount = ros::TfMessage {
        transforms: vec![ros::TransformStamped {
            header: ros::Header {
                stamp: ros::Time::from_seconds(t0),
                frame_id: "base_link".into(),
            },
            child_frame_id: "laser".into(),
            transform: ros::Transform {
                translation: ros::Vector3 {
                    x: LASER_X,
                    y: 0.0,
                    z: 0.1,
                },
                rotation: ros::Quaternion::of_yaw(0.0),
            },
        }],
    };
    put(&mut w, tf_ch, t0, &ros::encode(&mount));
    for (k, f) in sim.frames.iter().enumerate() {
        let t = t0 + f.t.unwrap();
        let stamp = ros::Time::from_seconds(t);
        let ranges = f.ranges.as_ref().unwrap();
        let (a0, da) = (f.angle_min.unwrap(), f.angle_increment.unwrap());
        let scan = ros::LaserScan {
            header: ros::Header {
                stamp,
                frame_id: "laser".into(),
            },
            angle_min: a0 as f32,
            angle_max: (a0 + da * (ranges.len() - 1) as f64) as f32,
            angle_increment: da as f32,
            time_increment: 0.0,
            scan_time: 0.025,
            range_min: f.range_min.unwrap() as f32,
            range_max: f.range_max.unwrap() as f32,
            ranges: ranges
                .iter()
                .map(|r| r.map_or(f32::INFINITY, |r| r as f32))
                .collect(),
            intensities: Vec::new(),
        };
        put(&mut w, scan_ch, t, &spoil(k, ros::encode(&scan)));
        // The base is behind the laser: laser pose = base pose composed with the mount.
        let pose = f.pose.unwrap();
        let base = compose(pose, [-LASER_X, 0.0, 0.0]);
        let odom = ros::Odometry {
            header: ros::Header {
                stamp,
                frame_id: "odom".into(),
            },
            child_frame_id: "base_link".into(),
            pose: ros::PoseWithCovariance {
                pose: ros::Pose {
                    position: ros::Vector3 {
                        x: base[0],
                        y: base[1],
                        z: 0.0,
                    },
                    orientation: ros::Quaternion::of_yaw(base[2]),
                },
                ..Default::default()
            },
            ..Default::default()
        };
        if tf {
            let moving = ros::TfMessage {
                transforms: vec![ros::TransformStamped {
                    header: odom.header.clone(),
                    child_frame_id: "base_link".into(),
                    transform: ros::Transform {
                        translation: odom.pose.pose.position,
                        rotation: odom.pose.pose.orientation,
                    },
                }],
            };
            put(&mut w, tf_dyn, t, &ros::encode(&moving));
        } else {
            put(&mut w, odom_ch, t, &ros::encode(&odom));
        }
    }
    w.finish().unwrap();
}

fn records(path: &Path) -> Vec<Value> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

/// Median per-frame Hausdorff distance of `run` to the simulator's visible truth.
fn median_hausdorff(run: &Path, sim: &Sim) -> f64 {
    let out = ok(&[
        "eval",
        p(run),
        "--truth",
        p(&sim.truth),
        "--frames",
        p(&sim.path),
    ]);
    let report: Value = serde_json::from_slice(&out.stdout).unwrap();
    let mut h: Vec<f64> = report["frames"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["hausdorff"].as_f64().unwrap())
        .collect();
    h.sort_by(f64::total_cmp);
    h[h.len() / 2]
}

/// One record per scan, in order, with the scan's time stamp and the laser's pose
/// (odometry composed with the mount), and curves that fit the room.
fn check_records(recs: &[Value], sim: &Sim, stream: &str) {
    assert_eq!(recs.len(), sim.frames.len());
    for (k, (r, f)) in recs.iter().zip(&sim.frames).enumerate() {
        assert_eq!(r["stream"], stream, "record {k}");
        assert_eq!(r["frame"], k as u64);
        assert!(r.get("error").is_none(), "record {k}: {}", r["error"]);
        assert!(!r["polylines"].as_array().unwrap().is_empty(), "frame {k}");
        if stream != "robotlaser1" {
            let t = r["t"].as_f64().unwrap() - 1_700_000_000.0;
            // Time stamps travel as integer nanoseconds: exact to the nanosecond but for
            // f64 rounding of an epoch time (about 2e-7 s).
            assert!((t - f.t.unwrap()).abs() < 1e-6, "frame {k}: t {t}");
        }
        let pose: [f64; 3] = serde_json::from_value(r["pose"].clone()).unwrap();
        let want = f.pose.unwrap();
        for i in 0..3 {
            assert!(
                (pose[i] - want[i]).abs() < 1e-9,
                "frame {k}: {pose:?} {want:?}"
            );
        }
    }
}

#[test]
fn a_bag_is_reconstructed_with_its_stamps_and_poses_and_fits_the_truth() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sim = simulate(d, 12, 0.1);
    let bag = d.join("robot.mcap");
    write_bag(&bag, &sim, |_, b| b);
    let from_bag = d.join("bag.ndjson");
    ok(&[
        "reconstruct",
        p(&bag),
        "--odometry",
        "/odom",
        "-o",
        p(&from_bag),
    ]);
    check_records(&records(&from_bag), &sim, "laser");
    // The poses through /tf alone, to a frame named on the command line.
    let tf_bag = d.join("robot-tf.mcap");
    write_bag_with(&tf_bag, &sim, true, false, |_, b| b);
    let from_tf = d.join("tf.ndjson");
    ok(&[
        "reconstruct",
        p(&tf_bag),
        "--world-frame",
        "odom",
        "-o",
        p(&from_tf),
    ]);
    check_records(&records(&from_tf), &sim, "laser");
    // The same scans as NDJSON: the bag's f32 ranges change nothing that matters.
    let from_ndjson = d.join("ndjson.ndjson");
    ok(&["reconstruct", p(&sim.path), "-o", p(&from_ndjson)]);
    let (hb, hn) = (
        median_hausdorff(&from_bag, &sim),
        median_hausdorff(&from_ndjson, &sim),
    );
    eprintln!("median Hausdorff: bag {hb:.4} m, NDJSON {hn:.4} m");
    assert!(
        hb <= 0.05 && (hb - hn).abs() <= 0.1 * hn + 1e-3,
        "{hb} {hn}"
    );
}

#[test]
fn the_daemon_replays_a_bag_and_writes_curves_for_foxglove() {
    use foxglove::messages::SceneUpdate;
    use foxglove::Decode;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sim = simulate(d, 30, 0.1);
    let bag = d.join("robot.mcap");
    write_bag(&bag, &sim, |_, b| b);
    let run = |out: &Path| {
        let cfg = d.join("run.toml");
        std::fs::write(
            &cfg,
            format!(
                "[input]\npath = {bag:?}\nreplay = \"fast\"\nodometry = \"/odom\"\n\
                 [output]\npath = {out:?}\n"
            ),
        )
        .unwrap();
        ok(&["run", "-c", p(&cfg)]);
    };
    let ndjson = d.join("run.ndjson");
    run(&ndjson);
    let recs = records(&ndjson);
    check_records(&recs, &sim, "laser");
    // Each scan frame is built from its own scan.
    assert!(recs.iter().all(|r| r["stats"]["start"] == "scan"));
    // The MCAP output: per frame one scene update with the curves, at the scan's time,
    // beside its points, its record and its pose.
    let out = d.join("curves.mcap");
    run(&out);
    assert!(!d.join("curves.mcap.part").exists());
    let bytes = std::fs::read(&out).unwrap();
    let mut per_topic: BTreeMap<String, usize> = BTreeMap::new();
    let mut scenes = Vec::new();
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        *per_topic.entry(m.channel.topic.clone()).or_default() += 1;
        if m.channel.topic == "/isoline/curves" {
            assert_eq!(
                m.channel.schema.as_ref().unwrap().name,
                "foxglove.SceneUpdate"
            );
            scenes.push((m.log_time, SceneUpdate::decode(&m.data[..]).unwrap()));
        }
    }
    for topic in [
        "/isoline/curves",
        "/isoline/points",
        "/isoline/records",
        "/isoline/tf",
    ] {
        assert_eq!(per_topic.get(topic), Some(&30), "{topic}: {per_topic:?}");
    }
    for ((log_time, scene), (f, r)) in scenes.iter().zip(sim.frames.iter().zip(&recs)) {
        let e = &scene.entities[0];
        assert_eq!(e.frame_id, "laser");
        let want = r["polylines"].as_array().unwrap().len();
        assert_eq!(e.lines.len(), want);
        let t = (*log_time as f64) * 1e-9 - 1_700_000_000.0;
        assert!((t - f.t.unwrap()).abs() < 1e-6);
    }
}

/// Runs `isoline` expecting failure; its stderr.
#[test]
fn damaged_bags_unknown_topics_and_undecodable_messages_are_named_and_the_rest_goes_on() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sim = simulate(d, 8, 0.05);
    // Message 3 of /scan is garbage, message 5 cut in half.
    let bag = d.join("spoiled.mcap");
    write_bag(&bag, &sim, |k, b| match k {
        3 => vec![0, 1, 0, 0, 7, 7],
        5 => b[..b.len() / 2].to_vec(),
        _ => b,
    });
    let out = d.join("spoiled.ndjson");
    let err = fails(&["reconstruct", p(&bag), "-o", p(&out)]);
    assert!(err.contains("2 of 8 frames failed"), "{err}");
    let recs = records(&out);
    assert_eq!(recs.len(), 8);
    for (k, r) in recs.iter().enumerate() {
        assert_eq!(r["frame"], k as u64);
        if k == 3 || k == 5 {
            let e = r["error"].as_str().unwrap();
            assert!(
                e.contains("spoiled.mcap") && e.contains(&format!("topic /scan, message {k}")),
                "{e}"
            );
        } else {
            assert!(!r["polylines"].as_array().unwrap().is_empty(), "frame {k}");
        }
    }
    // Cut short: the scans before the cut get their records, the cut one error record.
    let good = d.join("good.mcap");
    write_bag(&good, &sim, |_, b| b);
    let bytes = std::fs::read(&good).unwrap();
    let cut = d.join("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() * 6 / 10]).unwrap();
    let out = d.join("cut.ndjson");
    let err = fails(&["reconstruct", p(&cut), "-o", p(&out)]);
    assert!(err.contains("damaged or cut short"), "{err}");
    let recs = records(&out);
    let ok_frames = recs.iter().filter(|r| r.get("error").is_none()).count();
    assert!(
        (2..8).contains(&ok_frames),
        "{ok_frames} frames before the cut"
    );
    let last = recs.last().unwrap()["error"].as_str().unwrap().to_string();
    assert!(
        last.contains("cut.mcap") && last.contains("/scan"),
        "{last}"
    );
    // The daemon: the same records, and the run reports the damage.
    let cfg = d.join("cut.toml");
    let run_out = d.join("cut-run.ndjson");
    std::fs::write(
        &cfg,
        format!("[input]\npath = {cut:?}\nreplay = \"fast\"\n[output]\npath = {run_out:?}\n"),
    )
    .unwrap();
    ok(&["run", "-c", p(&cfg)]);
    assert_eq!(records(&run_out).len(), recs.len());
    // A topic that is not there, a file that is not MCAP.
    let err = fails(&["reconstruct", p(&good), "--topic", "/front_scan"]);
    assert!(
        err.contains("good.mcap") && err.contains("/front_scan") && err.contains("\"/scan\""),
        "{err}"
    );
    let text = d.join("text.mcap");
    std::fs::write(&text, "not a bag\n").unwrap();
    let err = fails(&["reconstruct", p(&text)]);
    assert!(err.contains("text.mcap"), "{err}");
}

#[test]
fn a_carmen_log_is_read_line_by_line() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sim = simulate(d, 6, 0.1);
    let log = d.join("robot.clf");
    let mut text = String::from(
        "# CARMEN Logfile\nPARAM robot_front_laser_max 30.0 nohost 0\nSYNC tag 0 host 0\n",
    );
    for (k, f) in sim.frames.iter().enumerate() {
        let ranges = f.ranges.as_ref().unwrap();
        let pose = f.pose.unwrap();
        let t = f.t.unwrap();
        text += &format!(
            "ODOM {} {} {} 0 0 0 {t} host {t}\n",
            pose[0], pose[1], pose[2]
        );
        if k == 2 {
            text += "ROBOTLASER1 0 -2.3 4.7 0.0043 30 0.01 0 1080 1.0 2.0\n";
        }
        text += &format!(
            "ROBOTLASER1 0 {} {} {} {} 0.01 0 {} {} 0 {} {} {} {} {} {} 0 0 0 0 0 {t} host {t}\n",
            f.angle_min.unwrap(),
            f.angle_increment.unwrap() * (ranges.len() - 1) as f64,
            f.angle_increment.unwrap(),
            f.range_max.unwrap(),
            ranges.len(),
            ranges
                .iter()
                .map(|r| r.unwrap_or(f.range_max.unwrap()).to_string())
                .collect::<Vec<_>>()
                .join(" "),
            pose[0],
            pose[1],
            pose[2],
            pose[0],
            pose[1],
            pose[2],
        );
    }
    std::fs::write(&log, text).unwrap();
    let out = d.join("carmen.ndjson");
    let err = fails(&["reconstruct", p(&log), "-o", p(&out)]);
    assert!(err.contains("1 of 7 frames failed"), "{err}");
    let recs = records(&out);
    assert_eq!(recs.len(), 7);
    // The cut line (the 9th: three header lines, then ODOM and laser pairs) is named.
    let bad = &recs[2];
    let e = bad["error"].as_str().unwrap();
    assert!(
        e.contains("robot.clf, line 9") && e.contains("num_readings 1080"),
        "{e}"
    );
    let good: Vec<Value> = recs
        .iter()
        .filter(|r| r.get("error").is_none())
        .map(|r| {
            // Renumber as the simulator numbered them, for the evaluator.
            let mut r = r.clone();
            let k = r["frame"].as_u64().unwrap();
            r["frame"] = (k - u64::from(k > 2)).into();
            r
        })
        .collect();
    let sim_recs = d.join("carmen-good.ndjson");
    let mut f = std::fs::File::create(&sim_recs).unwrap();
    for r in &good {
        writeln!(f, "{r}").unwrap();
    }
    check_records(&good, &sim, "robotlaser1");
    let h = median_hausdorff(&sim_recs, &sim);
    assert!(h <= 0.05, "median Hausdorff {h}");

    // As the public datasets publish their logs: gzip-compressed, named `.log.gz`.
    let gz = d.join("robot.log.gz");
    let zipped = Command::new("sh")
        .arg("-c")
        .arg("gzip -c \"$0\" > \"$1\"")
        .args([p(&log), p(&gz)])
        .status()
        .unwrap();
    assert!(zipped.success());
    let out_gz = d.join("gz.ndjson");
    let err = fails(&["reconstruct", p(&gz), "-o", p(&out_gz)]);
    assert!(err.contains("robot.log.gz, line 9"), "{err}");
    let polylines =
        |rs: &[Value]| -> Vec<Value> { rs.iter().map(|r| r["polylines"].clone()).collect() };
    assert_eq!(polylines(&records(&out_gz)), polylines(&recs));
}

#[test]
fn convert_goes_from_ndjson_to_a_bag_and_back() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sim = simulate(d, 5, 0.1);
    let bag = d.join("frames.mcap");
    ok(&["convert", p(&sim.path), "-o", p(&bag)]);
    let back = d.join("back.ndjson");
    ok(&["convert", p(&bag), "-o", p(&back), "--odometry", "/odom"]);
    let recs: Vec<FrameRecord> = std::fs::read_to_string(&back)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(recs.len(), sim.frames.len());
    for (a, b) in sim.frames.iter().zip(&recs) {
        assert_eq!((&a.stream, a.frame), (&b.stream, b.frame));
        assert!((a.t.unwrap() - b.t.unwrap()).abs() < 1e-9);
        for (x, y) in a.pose.unwrap().iter().zip(b.pose.unwrap()) {
            assert!((x - y).abs() < 1e-9);
        }
        // Ranges travel as f32: within a micrometre at these ranges.
        for (x, y) in a
            .ranges
            .as_ref()
            .unwrap()
            .iter()
            .zip(b.ranges.as_ref().unwrap())
        {
            match (x, y) {
                (Some(x), Some(y)) => assert!((x - y).abs() < 1e-5, "{x} {y}"),
                (None, None) => {}
                other => panic!("{other:?}"),
            }
        }
    }
    // An output that exists is left alone when the conversion fails.
    std::fs::write(d.join("keep.ndjson"), "kept\n").unwrap();
    fails(&[
        "convert",
        p(&d.join("missing.mcap")),
        "-o",
        p(&d.join("keep.ndjson")),
    ]);
    assert_eq!(
        std::fs::read_to_string(d.join("keep.ndjson")).unwrap(),
        "kept\n"
    );
}

/// Subscribes to `topics` of the Foxglove WebSocket server at `addr`; every message
/// received until the server closes, as (topic, payload).
fn watch(addr: &str, topics: &[&str], deadline: Instant) -> Vec<(String, Vec<u8>)> {
    use tungstenite::client::IntoClientRequest;
    use tungstenite::Message;
    let mut req = format!("ws://{addr}").into_client_request().unwrap();
    req.headers_mut()
        .insert("Sec-WebSocket-Protocol", "foxglove.sdk.v1".parse().unwrap());
    let stream = std::net::TcpStream::connect(addr).unwrap();
    stream
        .set_read_timeout(Some(Duration::from_millis(500)))
        .unwrap();
    let (mut ws, _) = tungstenite::client(req, stream).unwrap();
    let mut channels: BTreeMap<u64, String> = BTreeMap::new();
    let mut subscribed: BTreeMap<u32, String> = BTreeMap::new();
    let mut got = Vec::new();
    while Instant::now() < deadline {
        let msg = match ws.read() {
            Ok(m) => m,
            Err(tungstenite::Error::Io(e))
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                ) =>
            {
                continue
            }
            Err(_) => break,
        };
        match msg {
            Message::Text(t) => {
                let v: Value = serde_json::from_str(&t).unwrap();
                if v["op"] == "advertise" {
                    let mut subs = Vec::new();
                    for c in v["channels"].as_array().unwrap() {
                        let (id, topic) = (c["id"].as_u64().unwrap(), c["topic"].as_str().unwrap());
                        channels.insert(id, topic.to_string());
                        if topics.contains(&topic) {
                            let sub = subscribed.len() as u32 + 1;
                            subscribed.insert(sub, topic.to_string());
                            subs.push(serde_json::json!({"id": sub, "channelId": id}));
                        }
                    }
                    let req = serde_json::json!({"op": "subscribe", "subscriptions": subs});
                    ws.send(Message::Text(req.to_string().into())).unwrap();
                }
            }
            Message::Binary(b) if b.first() == Some(&1) && b.len() >= 13 => {
                let sub = u32::from_le_bytes(b[1..5].try_into().unwrap());
                if let Some(topic) = subscribed.get(&sub) {
                    got.push((topic.clone(), b[13..].to_vec()));
                }
            }
            Message::Close(_) => break,
            _ => {}
        }
    }
    got
}

#[test]
fn the_live_view_serves_the_curves_to_a_foxglove_client() {
    use foxglove::messages::SceneUpdate;
    use foxglove::Decode;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sim = simulate(d, 24, 0.1);
    let bag = d.join("robot.mcap");
    write_bag(&bag, &sim, |_, b| b);
    let cfg = d.join("live.toml");
    let out = d.join("live.ndjson");
    // 8 frames a second: three seconds of frames to watch.
    std::fs::write(
        &cfg,
        format!(
            "[input]\npath = {bag:?}\nreplay = 8\nodometry = \"/odom\"\n\
             [output]\npath = {out:?}\n[live]\nbind = \"127.0.0.1:0\"\n"
        ),
    )
    .unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_isoline"))
        .args(["run", "-c", p(&cfg)])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stderr = BufReader::new(child.stderr.take().unwrap());
    let mut line = String::new();
    let addr = loop {
        line.clear();
        assert!(
            stderr.read_line(&mut line).unwrap() > 0,
            "no live view address"
        );
        if let Some(rest) = line.split("live view on ws://").nth(1) {
            break rest.split_whitespace().next().unwrap().to_string();
        }
    };
    // A viewer that subscribes to everything and never reads: it must cost the run
    // nothing but its own messages.
    let stalled = std::thread::spawn({
        let addr = addr.clone();
        move || {
            use tungstenite::client::IntoClientRequest;
            let mut req = format!("ws://{addr}").into_client_request().unwrap();
            req.headers_mut()
                .insert("Sec-WebSocket-Protocol", "foxglove.sdk.v1".parse().unwrap());
            let stream = std::net::TcpStream::connect(&addr).unwrap();
            let (mut ws, _) = tungstenite::client(req, stream).unwrap();
            loop {
                let Ok(tungstenite::Message::Text(t)) = ws.read() else {
                    continue;
                };
                let v: Value = serde_json::from_str(&t).unwrap();
                if v["op"] == "advertise" {
                    let subs: Vec<Value> = v["channels"]
                        .as_array()
                        .unwrap()
                        .iter()
                        .enumerate()
                        .map(|(i, c)| serde_json::json!({"id": i + 1, "channelId": c["id"]}))
                        .collect();
                    let req = serde_json::json!({"op": "subscribe", "subscriptions": subs});
                    ws.send(tungstenite::Message::Text(req.to_string().into()))
                        .unwrap();
                    return ws;
                }
            }
        }
    });
    let got = watch(
        &addr,
        &["/isoline/curves", "/isoline/records"],
        Instant::now() + Duration::from_secs(60),
    );
    drop(stalled.join().unwrap());
    assert!(child.wait().unwrap().success());
    // Every frame still has its record in the output, whatever the viewer saw.
    assert_eq!(records(&out).len(), 24);
    let mut frames_with_curves = BTreeSet::new();
    let mut scenes = 0;
    for (topic, data) in &got {
        if topic == "/isoline/records" {
            let r: Value = serde_json::from_slice(data).unwrap();
            if !r["polylines"].as_array().unwrap().is_empty() {
                frames_with_curves.insert(r["frame"].as_u64().unwrap());
            }
        } else {
            let s = SceneUpdate::decode(data.as_slice()).unwrap();
            assert!(!s.entities[0].lines.is_empty());
            scenes += 1;
        }
    }
    eprintln!(
        "live view: {} frames with curves, {scenes} scene updates of 24 frames",
        frames_with_curves.len()
    );
    // The client connects while the first frames are made: most of them, not all.
    assert!(frames_with_curves.len() >= 16 && scenes >= 16, "{got:?}");
}

#[test]
fn a_batch_job_reads_bags_with_their_poses() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sim = simulate(d, 5, 0.1);
    write_bag(&d.join("robot.mcap"), &sim, |_, b| b);
    let job = d.join("job.toml");
    std::fs::write(
        &job,
        "[batch]\ninputs = [\"*.mcap\"]\noutput = \"out\"\nformats = [\"ndjson\"]\n\
         odometry = \"/odom\"\n",
    )
    .unwrap();
    ok(&["batch", "-c", p(&job)]);
    check_records(&records(&d.join("out/robot.ndjson")), &sim, "laser");
}

/// A LaserScan message of `beams` beams over a little less than a turn.
fn huge_scan(beams: usize) -> Vec<u8> {
    let da = 6.0 / beams as f32;
    ros::encode(&ros::LaserScan {
        header: ros::Header {
            stamp: ros::Time::from_seconds(1_700_000_000.05),
            frame_id: "laser".into(),
        },
        angle_min: -3.0,
        angle_max: -3.0 + da * (beams - 1) as f32,
        angle_increment: da,
        time_increment: 0.0,
        scan_time: 0.025,
        range_min: 0.05,
        range_max: 30.0,
        ranges: vec![2.0; beams],
        intensities: Vec::new(),
    })
}

/// A bag whose second scan has 100,000 beams, more than any scanner: that message gets
/// an error record naming the file, the topic and the message, in `reconstruct`,
/// `run` and `batch` alike, and the other scans are reconstructed.
#[test]
fn a_scan_with_more_beams_than_any_scanner_is_one_error_record() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sim = simulate(d, 4, 0.1);
    let bag = d.join("big.mcap");
    write_bag(
        &bag,
        &sim,
        |k, b| if k == 1 { huge_scan(100_000) } else { b },
    );
    let check = |recs: &[Value]| {
        assert_eq!(recs.len(), 4);
        let e = recs[1]["error"]
            .as_str()
            .unwrap_or_else(|| panic!("{}", recs[1]));
        for part in ["big.mcap", "topic /scan", "message 1", "100000 beams"] {
            assert!(e.contains(part), "{part} not in {e}");
        }
        for k in [0, 2, 3] {
            assert!(
                recs[k]["error"].is_null() && !recs[k]["polylines"].as_array().unwrap().is_empty()
            );
        }
    };
    let out = d.join("r.ndjson");
    let run = Command::new(env!("CARGO_BIN_EXE_isoline"))
        .args(["reconstruct", p(&bag), "-o", p(&out)])
        .output()
        .unwrap();
    assert!(!run.status.success());
    check(&records(&out));

    let cfg = d.join("d.toml");
    let daemon_out = d.join("d.ndjson");
    std::fs::write(
        &cfg,
        format!("[input]\npath = {bag:?}\n[output]\npath = {daemon_out:?}\n"),
    )
    .unwrap();
    let run = Command::new(env!("CARGO_BIN_EXE_isoline"))
        .args(["run", "-c", p(&cfg)])
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    check(&records(&daemon_out));

    let job = d.join("job.toml");
    std::fs::write(
        &job,
        format!(
            "[batch]\ninputs = [{bag:?}]\noutput = {:?}\nformats = [\"ndjson\"]\n",
            d.join("batch")
        ),
    )
    .unwrap();
    let run = Command::new(env!("CARGO_BIN_EXE_isoline"))
        .args(["batch", "-c", p(&job)])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr);
    let written: Vec<PathBuf> = std::fs::read_dir(d.join("batch"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.to_string_lossy().ends_with(".ndjson"))
        .collect();
    assert_eq!(written.len(), 1, "{written:?} {stderr}");
    check(&records(&written[0]));
}

/// Damage inside a chunk (one byte of a scan's ranges) is found by the chunk's CRC: an
/// error record and a failed exit, never a scan read with altered returns.
#[test]
fn damage_inside_a_bag_chunk_is_an_error_record() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sim = simulate(d, 4, 0.1);
    let bag = d.join("plain.mcap");
    write_bag_with(&bag, &sim, false, true, |_, b| b);
    let mut bytes = std::fs::read(&bag).unwrap();
    // The first scan's ranges: its 2nd beam's f32, found by value.
    let r = sim.frames[0].ranges.as_ref().unwrap()[1].unwrap() as f32;
    let at = bytes
        .windows(4)
        .position(|w| w == r.to_le_bytes())
        .expect("the range is in the plain chunk");
    bytes[at + 2] ^= 0x10;
    std::fs::write(&bag, &bytes).unwrap();
    let out = d.join("r.ndjson");
    let run = Command::new(env!("CARGO_BIN_EXE_isoline"))
        .args(["reconstruct", p(&bag), "-o", p(&out)])
        .output()
        .unwrap();
    assert!(!run.status.success());
    let recs = records(&out);
    let errors: Vec<&str> = recs.iter().filter_map(|r| r["error"].as_str()).collect();
    assert!(errors.iter().any(|e| e.contains("CRC")), "{errors:?}");
}

/// A demo that stays up: with `[live] linger`, the live view keeps serving after the
/// recording has ended, and a viewer that connects then (10 s after the start) is sent
/// each stream's last frame; SIGTERM ends it cleanly.
#[test]
fn a_lingering_live_view_shows_the_last_frame_after_the_recording_ends() {
    use foxglove::messages::SceneUpdate;
    use foxglove::Decode;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let started = Instant::now();
    let (_, mut child) = lingering_on_a_bag(d, 4, "", "[output]\npath = \"out.mcap\"\n");
    let mut stderr = BufReader::new(child.stderr.take().unwrap());
    let mut line = String::new();
    let mut addr = None;
    loop {
        line.clear();
        assert!(stderr.read_line(&mut line).unwrap() > 0, "the run ended");
        if let Some(rest) = line.split("live view on ws://").nth(1) {
            addr = Some(rest.split_whitespace().next().unwrap().to_string());
        }
        if line.contains("the input has ended") {
            break;
        }
    }
    // The run is over (its summary printed, its MCAP complete); the view still serves
    // a viewer that connects 10 s after the start.
    assert!(d.join("out.mcap").exists());
    std::thread::sleep(Duration::from_secs(10).saturating_sub(started.elapsed()));
    let got = watch(
        &addr.unwrap(),
        &["/isoline/curves"],
        Instant::now() + Duration::from_millis(1500),
    );
    let scene = got
        .iter()
        .find(|(t, _)| t == "/isoline/curves")
        .expect("the last frame's curves");
    let s = SceneUpdate::decode(scene.1.as_slice()).unwrap();
    assert!(!s.entities[0].lines.is_empty());
    terminate(&mut child);
}

/// The daemon's map (`[map] output`) from a bag replayed at 40 scans a second: written
/// whole every 15 scans while the run goes on (a reader polling the file sees it grow
/// and never half a file), and at the end near the room's walls; the live view shows
/// it to a viewer in frame `map`.
#[test]
fn the_daemon_writes_the_map_as_it_grows_and_shows_it_live() {
    use foxglove::messages::SceneUpdate;
    use foxglove::Decode;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let n = 120;
    let (sim, mut child) = lingering_on_a_bag(
        d,
        n,
        "replay = 40\n",
        "[output]\npath = \"out.ndjson\"\n[map]\noutput = [\"map.ndjson\", \"map.geojson\", \
         \"map.html\"]\nevery = 15\n",
    );
    let stderr = BufReader::new(child.stderr.take().unwrap());
    let (tx, lines) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for l in stderr.lines().map_while(Result::ok) {
            let _ = tx.send(l);
        }
    });
    // Poll the map while the scans come in: every read is one whole record.
    let mut seen = BTreeSet::new();
    let (mut addr, mut summary) = (None, String::new());
    let deadline = Instant::now() + Duration::from_secs(120);
    while summary.is_empty() {
        assert!(Instant::now() < deadline, "the run did not end");
        if let Ok(text) = std::fs::read_to_string(d.join("map.ndjson")) {
            let r: Value = serde_json::from_str(text.trim()).expect("a whole record");
            seen.insert(r["frame"].as_u64().unwrap());
        }
        for l in lines.try_iter() {
            if let Some(rest) = l.split("live view on ws://").nth(1) {
                addr = Some(rest.split_whitespace().next().unwrap().to_string());
            }
            if l.contains("map of") {
                summary = l;
            }
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let last: Value = serde_json::from_str(
        std::fs::read_to_string(d.join("map.ndjson"))
            .unwrap()
            .trim(),
    )
    .unwrap();
    assert_eq!(last["frame"], n as u64, "{summary}");
    assert!(
        seen.iter().filter(|&&s| s < n as u64).count() >= 3,
        "the map was seen growing: {seen:?}"
    );
    assert!(
        summary.contains(&format!("map of {n} scans (0 unplaced, 0 passed by)")),
        "{summary}"
    );
    // The page, written with the others: the whole run's map, its layers computed.
    let page = std::fs::read_to_string(d.join("map.html")).unwrap();
    let data: Value = serde_json::from_str(
        page.split(r#"id="map-data">"#)
            .nth(1)
            .and_then(|t| t.split("</script>").next())
            .expect("the page's data"),
    )
    .unwrap();
    assert_eq!(data["scans"], n as u64);
    assert!(!data["curves"].as_array().unwrap().is_empty());
    assert!(
        data["returns"].as_array().unwrap().len() >= 2,
        "no returns to draw"
    );
    // Near the walls: 3 sigma + 2 cells.
    let walls = crate::common::scene_walls(&sim.truth);
    let geo: Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("map.geojson")).unwrap()).unwrap();
    let mut length = 0.0;
    for f in geo["features"].as_array().unwrap() {
        let piece: Vec<[f64; 2]> =
            serde_json::from_value(f["geometry"]["coordinates"].clone()).unwrap();
        for q in &piece {
            let d = crate::common::to_walls(*q, &walls);
            assert!(
                d <= 3.0 * 0.01 + 2.0 * 0.03,
                "{q:?} is {d} m from every wall"
            );
        }
        length += f["properties"]["length"].as_f64().unwrap();
    }
    // The room's walls and those seen through its doorways: 42.2 m measured; at most a
    // twentieth less.
    assert!(length > 40.0, "{length} m of map");
    // The live view kept the map for a viewer that connects after the run.
    let got = watch(
        &addr.expect("the live view's address"),
        &["/isoline/curves"],
        Instant::now() + Duration::from_millis(1500),
    );
    let map = got
        .iter()
        .filter(|(t, _)| t == "/isoline/curves")
        .map(|(_, b)| SceneUpdate::decode(b.as_slice()).unwrap())
        .find(|s| s.entities.iter().any(|e| e.frame_id == "map"))
        .expect("the map in the live view");
    assert!(!map.entities[0].lines.is_empty());
    terminate(&mut child);
}

/// Ends a lingering daemon as its user would, with SIGTERM; it must exit cleanly.
fn terminate(child: &mut std::process::Child) {
    let ok = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(ok.success());
    assert!(child.wait().unwrap().success());
}

/// `isoline run` on a bag of `n` simulated scans of the room (poses on `/odom`) in `d`,
/// with `input` added to `[input]`, `tables` after it, and a live view on a free port
/// that lingers after the input ends; its stderr piped.
fn lingering_on_a_bag(d: &Path, n: usize, input: &str, tables: &str) -> (Sim, std::process::Child) {
    let sim = simulate(d, n, 0.1);
    let bag = d.join("robot.mcap");
    write_bag(&bag, &sim, |_, b| b);
    let cfg = d.join("daemon.toml");
    std::fs::write(
        &cfg,
        format!(
            "[input]\npath = {bag:?}\nodometry = \"/odom\"\n{input}{tables}\
             [live]\nbind = \"127.0.0.1:0\"\nlinger = true\n"
        ),
    )
    .unwrap();
    let child = Command::new(env!("CARGO_BIN_EXE_isoline"))
        .args(["run", "-c", p(&cfg)])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    (sim, child)
}
