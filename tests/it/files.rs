//! Outputs against failures: a full disk, an output named like the input's temporary
//! file, two outputs that are one file, a bad frame among good ones, a record cut short
//! by a kill. No run destroys a file or leaves a partial one under an output's name.

use std::path::Path;
use std::process::{Command, Output};

use crate::common::{ok, p};

fn fixture(name: &str) -> String {
    format!("{}/fixtures/{name}", env!("CARGO_MANIFEST_DIR"))
}

/// `isoline ARGS` in `dir` with files limited to 1 KiB (`ulimit -f` counts 512-byte
/// blocks; the `SIGXFSZ` it would send ignored), so that writes fail as on a full disk.
fn on_a_full_disk(dir: &Path, args: &[&str]) -> Output {
    Command::new("sh")
        .arg("-c")
        .arg("trap '' XFSZ; ulimit -f 2; exec \"$0\" \"$@\"")
        .arg(env!("CARGO_BIN_EXE_isoline"))
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap()
}

fn names(dir: &Path) -> Vec<String> {
    let mut n: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    n.sort();
    n
}

#[test]
fn a_full_disk_leaves_no_partial_output_and_the_previous_one_whole() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // Three frames: a few kilobytes of records in every format.
    let text = std::fs::read_to_string(fixture("ellipse-stream-20.ndjson")).unwrap();
    let first3: String = text.lines().take(3).map(|l| format!("{l}\n")).collect();
    let frames = tempfile::tempdir().unwrap();
    let input_path = frames.path().join("in.ndjson");
    std::fs::write(&input_path, first3).unwrap();
    let input = input_path.to_str().unwrap().to_string();
    for out in ["o.ndjson", "o.geojson", "o.csv", "o.mcap"] {
        let fail = on_a_full_disk(d, &["reconstruct", &input, "-o", out]);
        assert!(!fail.status.success(), "{out}");
        assert!(names(d).is_empty(), "{out}: {:?}", names(d));
        // An earlier output stays as it was.
        std::fs::write(d.join(out), "earlier").unwrap();
        let fail = on_a_full_disk(d, &["reconstruct", &input, "-o", out]);
        assert!(!fail.status.success());
        assert_eq!(names(d), [out]);
        assert_eq!(std::fs::read_to_string(d.join(out)).unwrap(), "earlier");
        std::fs::remove_file(d.join(out)).unwrap();
    }
    let fail = on_a_full_disk(
        d,
        &[
            "convert",
            &fixture("clutter-hokuyo-20.ndjson"),
            "-o",
            "c.mcap",
        ],
    );
    assert!(!fail.status.success());
    assert!(names(d).is_empty(), "{:?}", names(d));
}

#[test]
fn an_input_named_like_a_temporary_file_is_never_written() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let text = std::fs::read_to_string(fixture("ellipse-stream-20.ndjson")).unwrap();
    let first3: String = text.lines().take(3).map(|l| format!("{l}\n")).collect();
    // Inputs that happen to be named as an MCAP output's temporary file was: a point
    // file for `reconstruct`, frames for the daemon.
    let points = std::fs::read_to_string(fixture("circle-500.xy")).unwrap();
    let xy = d.join("p.mcap.part");
    std::fs::write(&xy, &points).unwrap();
    ok(&["reconstruct", p(&xy), "-o", p(&d.join("p.mcap"))]);
    assert_eq!(std::fs::read_to_string(&xy).unwrap(), points);
    let input = d.join("x.mcap.part");
    std::fs::write(&input, &first3).unwrap();
    let cfg = d.join("d.toml");
    std::fs::write(
        &cfg,
        format!(
            "[input]\npath = {input:?}\n[output]\npath = {:?}\n",
            d.join("x.mcap")
        ),
    )
    .unwrap();
    ok(&["run", "-c", p(&cfg)]);
    assert_eq!(std::fs::read_to_string(&input).unwrap(), first3);
    assert_eq!(
        names(d),
        ["d.toml", "p.mcap", "p.mcap.part", "x.mcap", "x.mcap.part"]
    );
}

#[test]
fn stats_and_results_in_one_file_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("r.json");
    let run = Command::new(env!("CARGO_BIN_EXE_isoline"))
        .args(["reconstruct", &fixture("circle-500.xy")])
        .args(["-o", p(&out), "--stats", p(&dir.path().join("./r.json"))])
        .output()
        .unwrap();
    assert!(!run.status.success());
    let e = String::from_utf8_lossy(&run.stderr);
    assert!(e.contains("are one file"), "{e}");
    assert!(!out.exists());
}

/// One bad line of five: four reconstructed records and an error record naming the
/// line, in the input's order; the exit says how many failed.
#[test]
fn a_bad_frame_costs_its_own_record_only() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let text = std::fs::read_to_string(fixture("ellipse-stream-20.ndjson")).unwrap();
    let mut lines: Vec<String> = text.lines().take(4).map(str::to_string).collect();
    lines.insert(
        2,
        "{\"stream\":\"lidar0\",\"frame\":77,\"points\":[[0,\"x\"]]}".into(),
    );
    let input = d.join("in.ndjson");
    std::fs::write(&input, lines.join("\n") + "\n").unwrap();
    let out = d.join("out.ndjson");
    let run = Command::new(env!("CARGO_BIN_EXE_isoline"))
        .args(["reconstruct", p(&input), "-o", p(&out)])
        .output()
        .unwrap();
    assert!(!run.status.success());
    let e = String::from_utf8_lossy(&run.stderr);
    assert!(e.contains("1 of 5 frames failed"), "{e}");
    let recs: Vec<serde_json::Value> = std::fs::read_to_string(&out)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(recs.len(), 5);
    assert_eq!(recs[2]["frame"], 77);
    assert!(recs[2]["error"].as_str().unwrap().contains("line 3"));
    for k in [0, 1, 3, 4] {
        assert!(recs[k]["polylines"]
            .as_array()
            .is_some_and(|p| !p.is_empty()));
    }
}

/// A record file whose writer was killed mid-record: the cut last line is skipped with
/// a warning, the whole records are read.
#[test]
fn a_record_cut_by_a_kill_is_skipped_by_readers() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let frames = d.join("frames.ndjson");
    let text = std::fs::read_to_string(fixture("clutter-hokuyo-20.ndjson")).unwrap();
    std::fs::write(&frames, &text).unwrap();
    let out = d.join("out.ndjson");
    ok(&["reconstruct", p(&frames), "-o", p(&out)]);
    let whole = std::fs::read_to_string(&out).unwrap();
    let cut = &whole[..whole.len() - 40];
    std::fs::write(&out, cut).unwrap();
    let scored = ok(&["eval", p(&out), "--frames", p(&frames)]);
    let e = String::from_utf8_lossy(&scored.stderr);
    assert!(e.contains("cut short; skipped"), "{e}");
    let v: serde_json::Value = serde_json::from_slice(&scored.stdout).unwrap();
    assert_eq!(
        v["frames"].as_array().unwrap().len(),
        whole.lines().count() - 1
    );
}
