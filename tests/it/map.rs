//! `isoline map`: a simulated drive through the room, with a person walking across it,
//! fused into one world-frame map and checked against the scene's truth.

use super::common::{ok, p, scene_walls, synth_room, to_walls};

#[test]
fn a_drive_through_the_room_is_one_map_near_the_walls_without_the_person() {
    let dir = tempfile::tempdir().unwrap();
    let (frames, truth) = (dir.path().join("f.ndjson"), dir.path().join("t.json"));
    ok(&[
        "synth",
        "room",
        "--frames",
        "100",
        "--motion",
        "0.1",
        "--walker",
        "1.0",
        "--noise",
        "0.01",
        "--seed",
        "4",
        "-o",
        p(&frames),
        "--truth",
        p(&truth),
    ]);
    let (geo, rec, svg, stats) = (
        dir.path().join("m.geojson"),
        dir.path().join("m.ndjson"),
        dir.path().join("m.svg"),
        dir.path().join("s.json"),
    );
    ok(&[
        "map",
        p(&frames),
        "-o",
        p(&geo),
        "-o",
        p(&rec),
        "-o",
        p(&svg),
        "--stats",
        p(&stats),
        "-q",
    ]);
    let walls = scene_walls(&truth);
    let map: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&geo).unwrap()).unwrap();
    let pieces: Vec<Vec<[f64; 2]>> = map["features"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| serde_json::from_value(f["geometry"]["coordinates"].clone()).unwrap())
        .collect();
    // Every stretch of the map within 3 sigma + 2 cells of a wall (a scan's bound with
    // the lattice's spacing for hmin), the person included: were they in the map, a
    // curve would lie a metre from every wall.
    let bound = 3.0 * 0.01 + 2.0 * 0.03;
    let mut length = 0.0;
    for piece in &pieces {
        for s in piece.windows(2) {
            length += (s[1][0] - s[0][0]).hypot(s[1][1] - s[0][1]);
            for k in 0..=10 {
                let t = k as f64 / 10.0;
                let q = [
                    s[0][0] + t * (s[1][0] - s[0][0]),
                    s[0][1] + t * (s[1][1] - s[0][1]),
                ];
                let d = to_walls(q, &walls);
                assert!(d <= bound, "{q:?} is {d} m from every wall");
            }
        }
    }
    // The room's 28 m of walls, less its two doorways' 1.8 m, and walls outside seen
    // through them: 41.9 m measured; at most a twentieth less.
    assert!(length > 39.8, "{length} m");
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
    assert_eq!(s["scans"], 100);
    assert!(
        s["scores"]["static_within"].as_f64().unwrap() >= 0.95,
        "{s}"
    );
    assert!(s["scores"]["seen_through"].as_f64().unwrap() <= 0.01, "{s}");
    assert!(
        s["scores"]["union_length"].as_f64().unwrap() > 20.0 * length,
        "{s}"
    );
    // The NDJSON record is the map, as `isoline eval` and the other tools read records.
    let r: serde_json::Value =
        serde_json::from_str(std::fs::read_to_string(&rec).unwrap().trim()).unwrap();
    assert_eq!(r["stream"], "map");
    assert_eq!(r["polylines"].as_array().unwrap().len(), pieces.len());
    assert!(std::fs::read_to_string(&svg).unwrap().starts_with("<svg"));
    // `isoline eval --map` scores the GeoJSON (as it would another tool's) by the same
    // votes, from the poses alone, and against the scene: all of it within the bound.
    let out = ok(&[
        "eval",
        p(&geo),
        "--map",
        "--frames",
        p(&frames),
        "--truth",
        p(&truth),
    ]);
    let e: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(e["scans"], 100);
    assert!(e["static_within"].as_f64().unwrap() >= 0.95, "{e}");
    assert!(e["seen_through"].as_f64().unwrap() <= 0.01, "{e}");
    assert!(
        (e["length"].as_f64().unwrap() - length).abs() < 0.01 * length,
        "{e}"
    );
    let t = &e["truth"];
    assert_eq!(t["bound"].as_f64().unwrap(), bound, "{e}");
    assert_eq!(t["within_bound"].as_f64().unwrap(), 1.0, "{e}");
    assert!(t["to_walls_max"].as_f64().unwrap() <= bound, "{e}");
    // The room's walls were seen round the drive, and the map draws nearly all of them.
    assert!(t["walls_seen_covered"].as_f64().unwrap() >= 0.9, "{e}");
}

#[test]
fn frames_without_poses_make_no_map_and_say_why() {
    let dir = tempfile::tempdir().unwrap();
    let frames = dir.path().join("f.ndjson");
    ok(&["synth", "room", "--frames", "2", "-o", p(&frames)]);
    // The same frames with their poses removed.
    let text = std::fs::read_to_string(&frames).unwrap();
    let stripped: String = text
        .lines()
        .map(|l| {
            let mut v: serde_json::Value = serde_json::from_str(l).unwrap();
            v.as_object_mut().unwrap().remove("pose");
            v.to_string() + "\n"
        })
        .collect();
    std::fs::write(&frames, stripped).unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_isoline"))
        .args([
            "map",
            p(&frames),
            "-o",
            p(&dir.path().join("m.geojson")),
            "-q",
        ])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("2 without a pose"), "{err}");
    assert!(!dir.path().join("m.geojson").exists());
}

/// Without `-o`, the configuration's `[map] output` (relative to its folder) is written;
/// with neither, the command says what it lacks and writes nothing.
#[test]
fn the_configuration_names_the_map_when_the_command_line_does_not() {
    let dir = tempfile::tempdir().unwrap();
    let frames = dir.path().join("f.ndjson");
    synth_room(&frames, 6, 0.1, &[]);
    let sub = dir.path().join("cfg");
    std::fs::create_dir(&sub).unwrap();
    let cfg = sub.join("map.toml");
    std::fs::write(
        &cfg,
        "[map]\noutput = [\"m.geojson\", \"m.ndjson\"]\nevery = 2\n",
    )
    .unwrap();
    ok(&["map", p(&frames), "-c", p(&cfg), "-q"]);
    let r: serde_json::Value = serde_json::from_str(
        std::fs::read_to_string(sub.join("m.ndjson"))
            .unwrap()
            .trim(),
    )
    .unwrap();
    assert_eq!(r["frame"], 6);
    assert!(sub.join("m.geojson").exists());
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_isoline"))
        .args(["map", p(&frames), "-q"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("give -o MAP"), "{err}");
}

/// A frame record's time and pose as a line of a TUM trajectory (the simulator's poses
/// as the reference `isoline eval --reference` reads).
fn tum_line(frame: &serde_json::Value) -> String {
    let pose: [f64; 3] = serde_json::from_value(frame["pose"].clone()).unwrap();
    let t = frame["t"].as_f64().unwrap();
    let (s, c) = (pose[2] / 2.0).sin_cos();
    format!("{t} {} {} 0 0 0 {s} {c}\n", pose[0], pose[1])
}

/// `--register` on frames whose poses were removed: every scan registered from the
/// returns alone, the trajectory written as TUM and scored against the simulator's
/// poses by `isoline eval --reference`, and the map scored by the estimated poses.
#[test]
fn frames_without_poses_are_registered_from_their_returns() {
    let dir = tempfile::tempdir().unwrap();
    let frames = dir.path().join("f.ndjson");
    synth_room(&frames, 60, 0.1, &["--noise", "0.01", "--seed", "3"]);
    let text = std::fs::read_to_string(&frames).unwrap();
    let (mut stripped, mut reference) = (String::new(), String::from("# t x y z qx qy qz qw\n"));
    for l in text.lines() {
        let mut v: serde_json::Value = serde_json::from_str(l).unwrap();
        reference += &tum_line(&v);
        v.as_object_mut().unwrap().remove("pose");
        stripped += &(v.to_string() + "\n");
    }
    std::fs::write(&frames, stripped).unwrap();
    let (reference_path, est, stats) = (
        dir.path().join("ref.tum"),
        dir.path().join("est.tum"),
        dir.path().join("s.json"),
    );
    std::fs::write(&reference_path, reference).unwrap();
    ok(&[
        "map",
        p(&frames),
        "--register",
        "--trajectory",
        p(&est),
        "--stats",
        p(&stats),
        "-o",
        p(&dir.path().join("m.geojson")),
        "-q",
    ]);
    let lines = std::fs::read_to_string(&est).unwrap();
    assert_eq!(lines.lines().filter(|l| !l.starts_with('#')).count(), 60);
    let out = ok(&["eval", p(&est), "--reference", p(&reference_path)]);
    let e: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    // A 6 m room, 1 cm of range noise, 10 cm between scans: registration from the
    // returns alone lands within a few millimetres (the world frame is the first
    // scan's, which the alignment removes).
    assert_eq!(e["poses"], 60);
    assert!(e["ate_m"].as_f64().unwrap() < 0.01, "{e}");
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
    assert_eq!(s["registration"]["without_pose"], 60);
    assert!(s["scores"]["static_within"].as_f64().unwrap() > 0.9, "{s}");
}

/// `--register` on an RPLIDAR's sweeps without poses (360 degrees in the 100 ms between
/// frames, each beam cast from where the sensor is at its time): with the beams'
/// timing the scans and their curves are corrected by the motion registration gives,
/// in both passes; read as taken at once every turn bends them.
#[test]
fn sweeps_without_poses_are_corrected_in_both_passes() {
    let dir = tempfile::tempdir().unwrap();
    let frames = dir.path().join("f.ndjson");
    synth_sweeping_rplidar(&frames, 200);
    let text = std::fs::read_to_string(&frames).unwrap();
    let (mut timed, mut untimed) = (String::new(), String::new());
    let mut reference = String::from("# t x y z qx qy qz qw\n");
    for l in text.lines() {
        let mut v: serde_json::Value = serde_json::from_str(l).unwrap();
        reference += &tum_line(&v);
        let o = v.as_object_mut().unwrap();
        o.remove("pose");
        timed += &(serde_json::Value::Object(o.clone()).to_string() + "\n");
        o.remove("time_increment");
        untimed += &(serde_json::Value::Object(o.clone()).to_string() + "\n");
    }
    let reference_path = dir.path().join("ref.tum");
    std::fs::write(&reference_path, reference).unwrap();
    let run = |name: &str, text: &str| -> (f64, f64) {
        let (input, est, stats) = (
            dir.path().join(format!("{name}.ndjson")),
            dir.path().join(format!("{name}.tum")),
            dir.path().join(format!("{name}.json")),
        );
        std::fs::write(&input, text).unwrap();
        ok(&[
            "map",
            p(&input),
            "--register",
            "--trajectory",
            p(&est),
            "--stats",
            p(&stats),
            "-o",
            p(&dir.path().join(format!("{name}.geojson"))),
            "-q",
        ]);
        let out = ok(&["eval", p(&est), "--reference", p(&reference_path)]);
        let e: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        let s: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
        (
            e["rpe"][0]["heading_deg"].as_f64().unwrap(),
            s["scores"]["static_within"].as_f64().unwrap(),
        )
    };
    let ((timed_heading, timed_map), (raw_heading, raw_map)) =
        (run("timed", &timed), run("untimed", &untimed));
    eprintln!("heading over 1 m {timed_heading} / {raw_heading} deg, map {timed_map} / {raw_map}");
    // Bent by a whole frame's turn, the raw sweeps' heading is off by about half a
    // degree over 1 m; corrected, by what registration leaves of a sweep taken at once.
    assert!(
        timed_heading < 0.5 * raw_heading,
        "{timed_heading} / {raw_heading}"
    );
    // The map is fused from the scans corrected as registration corrected them: its
    // returns lie on it at least as well.
    assert!(timed_map >= raw_map, "{timed_map} / {raw_map}");
}

/// `count` frames of an RPLIDAR A1 sweeping through the clutter scene (`synth --sweep`:
/// each beam cast from where the sensor is at its time), written to `frames`.
fn synth_sweeping_rplidar(frames: &std::path::Path, count: usize) {
    ok(&[
        "synth",
        "clutter",
        "--sensor",
        "rplidar-a1",
        "--frames",
        &count.to_string(),
        "--motion",
        "0.05",
        "--seed",
        "2",
        "--sweep",
        "-o",
        p(frames),
    ]);
}

/// `isoline eval --frames` scores a frame's curves against the next scans as the
/// reconstruction read them: corrected for their sweeps, as `reconstruct` corrected the
/// frame's own.
#[test]
fn the_next_scan_is_scored_corrected_for_its_sweep() {
    let dir = tempfile::tempdir().unwrap();
    let (frames, out) = (dir.path().join("f.ndjson"), dir.path().join("r.ndjson"));
    synth_sweeping_rplidar(&frames, 40);
    ok(&["reconstruct", p(&frames), "-o", p(&out)]);
    let e: serde_json::Value =
        serde_json::from_slice(&ok(&["eval", p(&out), "--frames", p(&frames)]).stdout).unwrap();
    let d = e["next_scan_by_input_pose"].as_f64().unwrap();
    // The next scan's returns lie about the walls by the range noise (a mean of 0.8 cm
    // for its 1 cm) and the curves' own error; read bent by a whole frame's turn
    // (0.1 rad of a 360-degree sweep), twice as far.
    assert!(d < 0.015, "{e}");
}

/// Chromium from the system's packages (scripts/deps.sh browser installs it), or
/// `$ISOLINE_CHROMIUM`; `None` where neither is, unless `ISOLINE_REQUIRE_BROWSER` is set
/// (scripts/test.sh sets it, so that CI cannot pass without the browser's test).
fn chromium() -> Option<std::path::PathBuf> {
    let named = std::env::var_os("ISOLINE_CHROMIUM").map(std::path::PathBuf::from);
    let path = std::env::var_os("PATH").unwrap_or_default();
    let dirs: Vec<std::path::PathBuf> = std::env::split_paths(&path).collect();
    let found = named.or_else(|| {
        ["chromium", "chromium-browser", "google-chrome"]
            .iter()
            .flat_map(|name| dirs.iter().map(move |dir| dir.join(name)))
            .find(|p| p.is_file())
    });
    if found.is_none() {
        assert!(
            std::env::var_os("ISOLINE_REQUIRE_BROWSER").is_none(),
            "no Chromium: scripts/deps.sh browser installs it"
        );
        eprintln!("skipped: no Chromium (scripts/deps.sh browser installs it)");
    }
    found
}

#[test]
fn the_html_map_loads_in_a_browser_and_draws_every_layer() {
    let dir = tempfile::tempdir().unwrap();
    let frames = dir.path().join("f.ndjson");
    synth_room(&frames, 40, 0.1, &["--noise", "0.01", "--seed", "2"]);
    let page = dir.path().join("m.html");
    ok(&["map", p(&frames), "-o", p(&page), "-q"]);
    let text = std::fs::read_to_string(&page).unwrap();
    // Self-contained: nothing fetched, so it opens offline and can be mailed.
    for external in ["http://", "https://", "src=", "href="] {
        assert!(!text.contains(external), "the page refers to {external}");
    }
    let Some(browser) = chromium() else { return };
    // The page's script writes what it drew (and any error) on the body; the DOM after
    // the scripts ran says so. The returns' layer starts hidden: shown by its box.
    let shown = dir.path().join("shown.html");
    std::fs::write(
        &shown,
        text.replace(r#"id="show-returns">"#, r#"id="show-returns" checked>"#),
    )
    .unwrap();
    for (file, returns_drawn) in [(&page, false), (&shown, true)] {
        let out = std::process::Command::new(&browser)
            .args([
                "--headless",
                "--no-sandbox",
                "--disable-gpu",
                "--no-first-run",
                "--window-size=1000,700",
                "--virtual-time-budget=5000",
                "--dump-dom",
            ])
            .arg(format!("file://{}", file.display()))
            .env("HOME", dir.path())
            .output()
            .expect("run Chromium");
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let dom = String::from_utf8_lossy(&out.stdout);
        let body = dom
            .split("<body")
            .nth(1)
            .and_then(|b| b.split('>').next())
            .unwrap_or_else(|| panic!("no body in {dom}"));
        assert!(!body.contains("data-error"), "the page failed: {body}");
        let count = |key: &str| -> usize {
            body.split(&format!("{key}=\""))
                .nth(1)
                .and_then(|v| v.split('"').next())
                .and_then(|v| v.parse().ok())
                .unwrap_or_else(|| panic!("no {key} in {body}"))
        };
        // The room's four walls and the drive: many segments, a path.
        assert!(count("data-drawn-segments") >= 20, "{body}");
        assert!(count("data-drawn-path") >= 2, "{body}");
        assert_eq!(count("data-drawn-returns") > 0, returns_drawn, "{body}");
        assert!(
            body.contains(r#"data-scale-bar=""#) && body.contains(" m\""),
            "{body}"
        );
    }
}

#[test]
fn off_a_terminal_the_progress_is_a_plain_line_with_the_total() {
    let dir = tempfile::tempdir().unwrap();
    let frames = dir.path().join("f.ndjson");
    synth_room(&frames, 300, 0.02, &["--noise", "0.01"]);
    // stderr is a pipe here: no bar, no escape codes; a line each time the interval
    // passes (0 s: every batch), the total once the counting thread has it.
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_isoline"))
        .args(["map", p(&frames), "-o", p(&dir.path().join("m.geojson"))])
        .env("ISOLINE_PROGRESS_EVERY", "0")
        .output()
        .unwrap();
    assert!(out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    let lines: Vec<&str> = err.lines().filter(|l| l.contains("frames read")).collect();
    assert!(lines.len() >= 2, "{err}");
    assert!(
        !err.contains('\u{1b}'),
        "escape codes off a terminal: {err:?}"
    );
    assert!(
        lines.iter().any(|l| l.contains("of 300, about")),
        "no total: {err}"
    );
}
