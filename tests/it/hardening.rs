//! Bad input as a careless user or an attacker gives it, through the binary: damaged
//! and inflating recordings, poses and settings the map cannot hold, outputs that
//! cannot be written. Each run ends with records for what was read, a clean error, and
//! bounded memory.

use std::io::Write;
use std::path::Path;
use std::process::{Command, Stdio};

use serde_json::Value;

use super::common::{fails, ok, p, replay_config, synth_room};

/// Runs `isoline` with `args`; its exit status, stderr and peak resident memory (kB,
/// from /proc while it runs: VmHWM only grows).
fn run_measured(args: &[&str], dir: &Path) -> (bool, String, u64) {
    let err_path = dir.join("stderr.txt");
    let mut child = Command::new(env!("CARGO_BIN_EXE_isoline"))
        .args(args)
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(&err_path).unwrap())
        .spawn()
        .unwrap();
    let status_path = format!("/proc/{}/status", child.id());
    let mut peak = 0u64;
    let status = loop {
        if let Ok(text) = std::fs::read_to_string(&status_path) {
            if let Some(kb) = text
                .lines()
                .find_map(|l| l.strip_prefix("VmHWM:"))
                .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<u64>().ok())
            {
                peak = peak.max(kb);
            }
        }
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        std::thread::sleep(std::time::Duration::from_millis(5));
    };
    (
        status.success(),
        std::fs::read_to_string(err_path).unwrap(),
        peak,
    )
}

fn records(path: &Path) -> Vec<Value> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .filter(|l| !l.trim().is_empty())
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

/// The simulated room's frames as a CARMEN log of `ROBOTLASER1` lines (which carry
/// their beams' geometry), gzip-compressed as the public datasets publish them.
fn room_log(dir: &Path, frames: usize) -> (std::path::PathBuf, usize) {
    let nd = dir.join("room.ndjson");
    synth_room(&nd, frames, 0.1, &["--noise", "0.01", "--seed", "2"]);
    let mut text = String::from("# CARMEN Logfile\n");
    let recs = records(&nd);
    for r in &recs {
        let ranges: Vec<String> = r["ranges"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap_or(0.0).to_string())
            .collect();
        let (pose, t) = (&r["pose"], r["t"].as_f64().unwrap());
        let (x, y, th) = (
            pose[0].as_f64().unwrap(),
            pose[1].as_f64().unwrap(),
            pose[2].as_f64().unwrap(),
        );
        let inc = r["angle_increment"].as_f64().unwrap();
        text += &format!(
            "ROBOTLASER1 0 {} {} {inc} {} 0.01 0 {} {} 0 {x} {y} {th} {x} {y} {th} 0 0 0 0 0 {t} host {t}\n",
            r["angle_min"].as_f64().unwrap(),
            inc * (ranges.len() - 1) as f64,
            r["range_max"].as_f64().unwrap(),
            ranges.len(),
            ranges.join(" "),
        );
    }
    let gz = dir.join("room.log.gz");
    let mut enc = flate2::write::GzEncoder::new(
        std::fs::File::create(&gz).unwrap(),
        flate2::Compression::default(),
    );
    enc.write_all(text.as_bytes()).unwrap();
    enc.finish().unwrap();
    (gz, recs.len())
}

#[test]
fn a_damaged_log_keeps_the_scans_before_the_damage_with_one_error() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (gz, n) = room_log(d, 40);
    let bytes = std::fs::read(&gz).unwrap();
    // An interrupted download, and a member padded with zeros after its end.
    let cut = d.join("cut.log.gz");
    std::fs::write(&cut, &bytes[..bytes.len() * 6 / 10]).unwrap();
    let padded = d.join("padded.log.gz");
    std::fs::write(&padded, [bytes.clone(), vec![0u8; 4096]].concat()).unwrap();
    for (damaged, all_scans) in [(&cut, false), (&padded, true)] {
        let out = d.join("out.ndjson");
        let _ = std::fs::remove_file(&out);
        let err = fails(&["reconstruct", p(damaged), "-o", p(&out)]);
        assert!(err.contains("could not read on"), "{err}");
        let recs = records(&out);
        assert!(!recs.is_empty() && recs.iter().all(|r| r.get("error").is_none()));
        if all_scans {
            assert_eq!(recs.len(), n);
        } else {
            assert!(recs.len() < n);
        }
        let map = d.join("map.geojson");
        let _ = std::fs::remove_file(&map);
        let err = fails(&["map", p(damaged), "-o", p(&map), "--quiet"]);
        assert!(err.contains("before the damage"), "{err}");
        let geo: Value = serde_json::from_str(&std::fs::read_to_string(&map).unwrap()).unwrap();
        assert!(!geo["features"].as_array().unwrap().is_empty());
    }
}

#[test]
fn a_log_that_inflates_is_reconstructed_in_bounded_memory() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // 150,000 laser lines that cannot be frames: each gets its error record, none is
    // held. Held (before records were streamed), twice as many peaked at 346 MB: these
    // would take about 170 MB, nearly three times the bound below.
    let bomb = d.join("bomb.log.gz");
    let mut enc = flate2::write::GzEncoder::new(
        std::fs::File::create(&bomb).unwrap(),
        flate2::Compression::best(),
    );
    let line = "FLASER 3 1.0 x 2.0 0 0 0 0 0 0 1 host 1\n".repeat(1000);
    for _ in 0..150 {
        enc.write_all(line.as_bytes()).unwrap();
    }
    enc.finish().unwrap();
    let out = d.join("out.ndjson");
    let (success, err, peak_kb) = run_measured(&["reconstruct", p(&bomb), "-o", p(&out)], d);
    assert!(!success, "every frame failed");
    assert!(
        err.contains("150000 of 150000 frames failed"),
        "{}",
        &err[err.len().saturating_sub(300)..]
    );
    assert_eq!(records(&out).len(), 150_000);
    // The binary, its buffers and one frame: far below what the frames would hold.
    assert!(peak_kb < 60_000, "peak resident memory {peak_kb} kB");
    // A batch job over it: the same bound, the outputs written.
    let job = d.join("job.toml");
    std::fs::write(
        &job,
        "[batch]\ninputs = [\"bomb.log.gz\"]\noutput = \"out\"\nformats = [\"ndjson\", \"csv\"]\nworkers = 1\n",
    )
    .unwrap();
    let (_, err, peak_kb) = run_measured(&["batch", "-c", p(&job)], d);
    assert!(peak_kb < 60_000, "peak resident memory {peak_kb} kB");
    assert_eq!(
        records(&d.join("out/bomb.log.ndjson")).len(),
        150_000,
        "{err}"
    );
}

#[test]
fn the_carmen_reader_holds_a_bounded_count_of_readings() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // 4,000 lines of 361 readings, nearly all distinct: 1.4 million distinct readings,
    // which a map of each reading held at about 100 bytes apiece.
    let log = d.join("long.log");
    let mut text = String::with_capacity(20 << 20);
    for k in 0..4000u64 {
        text += "FLASER 361";
        for b in 0..361u64 {
            let r = 1.0 + ((k * 361 + b) * 7919 % 1_000_000) as f64 * 7.9e-5 + 1e-7 * b as f64;
            text += &format!(" {r:.7}");
        }
        text += &format!(" 0 0 0 0 0 0 {k} host {k}\n");
    }
    std::fs::write(&log, text).unwrap();
    let out = d.join("out.ndjson");
    let (success, err, peak_kb) = run_measured(&["convert", p(&log), "-o", p(&out)], d);
    assert!(success, "{err}");
    assert!(peak_kb < 40_000, "peak resident memory {peak_kb} kB");
}

#[test]
fn outputs_that_cannot_be_written_fail_the_run_before_the_work() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let frames = d.join("f.ndjson");
    synth_room(&frames, 20, 0.1, &[]);
    // A folder that is a file: nothing can be written under it.
    let file = d.join("a-file");
    std::fs::write(&file, "x").unwrap();
    let blocked = file.join("stats.json");
    let err = fails(&[
        "map",
        p(&frames),
        "-o",
        p(&d.join("m.geojson")),
        "--stats",
        p(&blocked),
    ]);
    assert!(err.contains("stats.json cannot be written"), "{err}");
    assert!(!d.join("m.geojson").exists());
    // The daemon names the key at start and reads no frame.
    let out = d.join("out.ndjson");
    let map = format!("[map]\noutput = {:?}\n", p(&file.join("map.geojson")));
    let cfg = replay_config(d, &frames, &out, &map);
    let err = fails(&["run", "-c", p(&cfg)]);
    assert!(
        err.contains("map.output") && err.contains("cannot be written"),
        "{err}"
    );
    assert_eq!(records_or_none(&out), 0);
}

fn records_or_none(path: &Path) -> usize {
    std::fs::read_to_string(path).map_or(0, |t| t.lines().count())
}

#[test]
fn a_pose_the_map_cannot_hold_is_left_out_and_counted_and_the_run_goes_on() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let frames = d.join("f.ndjson");
    synth_room(&frames, 30, 0.1, &["--seed", "3"]);
    // Frames 10 and 20 jump beyond the lattice (the walk would never end at 2.8e17 m).
    let text: Vec<String> = records(&frames)
        .into_iter()
        .map(|mut r| {
            let k = r["frame"].as_u64().unwrap();
            if k == 10 || k == 20 {
                r["pose"] = serde_json::json!([3e17, -1e13, 0.5]);
            }
            r.to_string()
        })
        .collect();
    let jumpy = d.join("jumpy.ndjson");
    std::fs::write(&jumpy, text.join("\n") + "\n").unwrap();
    let (map, stats) = (d.join("m.geojson"), d.join("s.json"));
    ok(&[
        "map",
        p(&jumpy),
        "-o",
        p(&map),
        "--stats",
        p(&stats),
        "--quiet",
    ]);
    let s: Value = serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
    assert_eq!(s["skipped"]["far"], 2, "{s:#}");
    // The daemon: every frame its record, the map's report counts the two.
    let out = d.join("out.ndjson");
    let map = format!("[map]\noutput = {:?}\n", p(&d.join("daemon-map.geojson")));
    let cfg = replay_config(d, &jumpy, &out, &map);
    let o = ok(&["run", "-c", p(&cfg)]);
    assert_eq!(records(&out).len(), 30);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("2 scans beyond the map's reach left out"),
        "{err}"
    );
}

#[test]
fn map_settings_that_would_break_its_bounds_are_refused_at_load() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let frames = d.join("f.ndjson");
    synth_room(&frames, 5, 0.1, &[]);
    for (table, key) in [
        ("[map]\nhit_tolerance = 50.0\n", "map.hit_tolerance"),
        ("[map]\nhit_tolerance = 1000.0\n", "map.hit_tolerance"),
        ("[scan]\nrange_noise = 5.0\n", "scan.range_noise"),
    ] {
        let cfg = d.join("c.toml");
        std::fs::write(&cfg, table).unwrap();
        let err = fails(&[
            "map",
            p(&frames),
            "-c",
            p(&cfg),
            "-o",
            p(&d.join("m.geojson")),
        ]);
        assert!(err.contains(key), "{table}: {err}");
    }
}

#[test]
fn the_ndjson_line_cap_is_a_setting() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let frames = d.join("f.ndjson");
    synth_room(&frames, 2, 0.1, &[]);
    let longest = std::fs::read_to_string(&frames)
        .unwrap()
        .lines()
        .map(str::len)
        .max()
        .unwrap();
    let out = d.join("o.ndjson");
    let cap = (longest / 2).to_string();
    let err = fails(&[
        "reconstruct",
        p(&frames),
        "-o",
        p(&out),
        "--max-line-bytes",
        &cap,
    ]);
    assert!(err.contains("longer than"), "{err}");
    let roomy = (longest + 1).to_string();
    ok(&[
        "reconstruct",
        p(&frames),
        "-o",
        p(&out),
        "--max-line-bytes",
        &roomy,
    ]);
    assert!(records(&out).iter().all(|r| r.get("error").is_none()));
}
