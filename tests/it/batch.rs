//! `isoline batch` through the real binary.

use std::path::Path;
use std::process::Command;

use serde_json::Value;

fn batch(job: &Path, force: bool) -> std::process::Output {
    let mut c = Command::new(env!("CARGO_BIN_EXE_isoline"));
    c.args(["batch", "-c", job.to_str().unwrap()]);
    if force {
        c.arg("--force");
    }
    c.output().expect("run isoline")
}

fn summary(dir: &Path) -> Value {
    let text = std::fs::read_to_string(dir.join("out/summary.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

fn status_of<'a>(s: &'a Value, name: &str) -> &'a Value {
    s["files"]
        .as_array()
        .unwrap()
        .iter()
        .find(|f| f["file"].as_str().unwrap().ends_with(name))
        .unwrap_or_else(|| panic!("{name} not in {s}"))
}

#[test]
fn good_files_are_done_bad_ones_named_and_a_rerun_skips_what_is_done() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let fixtures = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures");
    std::fs::create_dir(d.join("in")).unwrap();
    std::fs::copy(fixtures.join("circle-500.xy"), d.join("in/circle.xy")).unwrap();
    std::fs::copy(
        fixtures.join("ellipse-500-n001.ndjson"),
        d.join("in/ellipse.ndjson"),
    )
    .unwrap();
    std::fs::write(d.join("in/bad.xy"), "0.1 0.2\n0.3 zero\n").unwrap();
    std::fs::write(d.join("in/empty.xy"), "").unwrap();
    let job = d.join("job.toml");
    std::fs::write(
        &job,
        concat!(
            "[batch]\ninputs = [\"in/*.xy\", \"in/*.ndjson\"]\noutput = \"out\"\n",
            "formats = [\"ndjson\", \"csv\", \"geojson\"]\nworkers = 2\n",
            "[files.\"in/ellipse*\".export]\nsimplify = 1e-4\n",
        ),
    )
    .unwrap();

    let out = batch(&job, false);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("2 of 4 files failed"), "{err}");
    for stem in ["circle", "ellipse"] {
        for ext in ["ndjson", "csv", "geojson"] {
            assert!(
                d.join(format!("out/{stem}.{ext}")).is_file(),
                "{stem}.{ext}"
            );
        }
    }
    assert!(!d.join("out/bad.ndjson").exists() && !d.join("out/empty.ndjson").exists());
    let s = summary(d);
    assert_eq!(s["totals"]["ok"], 2);
    assert_eq!(s["totals"]["failed"], 2);
    let bad = status_of(&s, "bad.xy");
    assert_eq!(bad["status"], "failed");
    assert!(bad["reason"].as_str().unwrap().contains("line 2"), "{bad}");
    let empty = status_of(&s, "empty.xy");
    assert!(
        empty["reason"].as_str().unwrap().contains("empty"),
        "{empty}"
    );
    let circle = status_of(&s, "circle.xy");
    assert_eq!(circle["status"], "ok");
    assert_eq!(circle["points"], 500);
    assert_eq!(circle["polylines"], 1);
    assert!(circle["vertices"].as_u64().unwrap() > 100);
    let csv = std::fs::read_to_string(d.join("out/summary.csv")).unwrap();
    assert_eq!(csv.lines().count(), 6, "{csv}");
    assert!(csv
        .lines()
        .last()
        .unwrap()
        .starts_with("TOTAL,2 ok / 2 failed / 0 skipped"));

    // A second run skips the finished files and tries the failed ones again.
    let out = batch(&job, false);
    assert!(!out.status.success());
    let s = summary(d);
    assert_eq!(s["totals"]["skipped"], 2, "{s}");
    assert_eq!(s["totals"]["failed"], 2);
    assert_eq!(status_of(&s, "circle.xy")["status"], "skipped");
    assert_eq!(
        status_of(&s, "circle.xy")["polylines"],
        1,
        "stats read back"
    );

    // --force redoes them.
    let out = batch(&job, true);
    assert!(!out.status.success());
    assert_eq!(summary(d)["totals"]["ok"], 2);

    // An invalid job is refused before any work, with the key path named.
    std::fs::write(
        &job,
        "[batch]\ninputs = [\"in/*.xy\"]\noutput = \"out2\"\nworkers = 0\n",
    )
    .unwrap();
    let out = batch(&job, false);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("batch.workers = 0"), "{err}");
    assert!(!d.join("out2").exists());
}

/// A rerun that skips a finished file reports what the run that made its outputs did,
/// whatever the formats (here no NDJSON to read the records back from).
#[test]
fn a_skipped_file_reports_the_counts_of_the_run_that_made_it() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let fixtures = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures");
    std::fs::create_dir(d.join("in")).unwrap();
    std::fs::copy(fixtures.join("circle-500.xy"), d.join("in/circle.xy")).unwrap();
    let job = d.join("job.toml");
    std::fs::write(
        &job,
        "[batch]\ninputs = [\"in/*.xy\"]\noutput = \"out\"\nformats = [\"svg\", \"csv\"]\n",
    )
    .unwrap();
    assert!(batch(&job, false).status.success());
    let first = status_of(&summary(d), "circle.xy").clone();
    assert_eq!(first["points"], 500);
    assert!(batch(&job, false).status.success());
    let s = summary(d);
    let again = status_of(&s, "circle.xy");
    assert_eq!(again["status"], "skipped");
    for key in ["frames", "points", "polylines", "vertices", "iterations"] {
        assert_eq!(again[key], first[key], "{key}: {s}");
    }
}
