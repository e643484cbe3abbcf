//! Docs that stay true: every command and every configuration or JSON snippet shown in
//! the README, ARCHITECTURE.md and docs/ is run or parsed here.
//!
//! Code blocks are found by their language: `sh` blocks are commands, run in order, one
//! temporary folder per page (with `fixtures/` and `scripts/` linked in, `config/` copied):
//! `isoline ...` and `cargo run --release -- ...` run the binary under test; scripts run
//! with `QUICK=1` (a small version of their run) and that binary. `cargo test`, `cargo
//! bench`, `cargo build`, `scripts/test.sh` and `.ci/run` are the suite and its build,
//! `scripts/cgal-peer.sh` installs a Debian package and builds a C++ peer,
//! `scripts/kiss-peer.sh` installs a Python peer (KISS-ICP),
//! `scripts/glyphs.sh` installs Debian's fonts and a Python environment, and `python`,
//! `pip` and `scripts/python.sh` are the Python package's, which scripts/python.sh tests
//! (with the `python` blocks of docs/python.md): not run here. Any
//! other command fails the test, so a page cannot show one that nothing checks. `toml`
//! blocks are parsed as the configuration they are (daemon, batch job, or the shared
//! tables), `json` blocks as the frame, result or truth they show.

use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn pages() -> Vec<PathBuf> {
    let mut pages = vec![root().join("README.md"), root().join("ARCHITECTURE.md")];
    let mut docs: Vec<PathBuf> = std::fs::read_dir(root().join("docs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    docs.sort();
    pages.extend(docs);
    pages
}

/// The fenced code blocks of a Markdown text: (language, body).
fn blocks(text: &str) -> Vec<(String, String)> {
    let mut out = Vec::new();
    let mut cur: Option<(String, String)> = None;
    for line in text.lines() {
        let trimmed = line.trim_start();
        if let Some(rest) = trimmed.strip_prefix("```") {
            match cur.take() {
                Some(b) => out.push(b),
                None => cur = Some((rest.trim().to_string(), String::new())),
            }
        } else if let Some((_, body)) = &mut cur {
            body.push_str(line);
            body.push('\n');
        }
    }
    out
}

/// Shell words of one command line: whitespace-separated, with '...' and "..." quoting.
fn words(line: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut cur = String::new();
    let mut quote = None;
    let mut any = false;
    for c in line.chars() {
        match (quote, c) {
            (None, '\'' | '"') => {
                quote = Some(c);
                any = true;
            }
            (Some(q), c) if c == q => quote = None,
            (None, c) if c.is_whitespace() => {
                if any {
                    out.push(std::mem::take(&mut cur));
                    any = false;
                }
            }
            (_, c) => {
                cur.push(c);
                any = true;
            }
        }
    }
    if any {
        out.push(cur);
    }
    out
}

/// The commands of a `sh` block: comments dropped, continuation lines joined.
fn commands(body: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut cur = String::new();
    for line in body.lines() {
        let line = line.trim();
        if cur.is_empty() && (line.is_empty() || line.starts_with('#')) {
            continue;
        }
        match line.strip_suffix('\\') {
            Some(part) => {
                cur.push_str(part);
                cur.push(' ');
            }
            None => {
                cur.push_str(line);
                out.push(std::mem::take(&mut cur));
            }
        }
    }
    out
}

fn link(dir: &Path, name: &str) {
    std::os::unix::fs::symlink(root().join(name), dir.join(name)).unwrap();
}

/// Held while a command that listens on a fixed port runs.
static FIXED_PORTS: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn run(dir: &Path, page: &Path, command: &str) {
    let bin = env!("CARGO_BIN_EXE_isoline");
    let mut w = words(command);
    // A trailing comment, as the shell drops it.
    if let Some(at) = w.iter().position(|x| x.starts_with('#')) {
        w.truncate(at);
    }
    // Leading VAR=value assignments.
    let mut env: Vec<(String, String)> = Vec::new();
    while let Some((k, v)) = w.first().and_then(|x| x.split_once('=')) {
        if k.is_empty() || !k.chars().all(|c| c.is_ascii_uppercase() || c == '_') {
            break;
        }
        env.push((k.to_string(), v.to_string()));
        w.remove(0);
    }
    let what = format!("{}: `{command}`", page.display());
    let mut cmd = match w.iter().map(String::as_str).collect::<Vec<_>>().as_slice() {
        ["cargo", "test" | "bench" | "build" | "clippy" | "fmt", ..]
        | [".ci/run"]
        | ["scripts/test.sh"]
        // The Python package: scripts/python.sh (run by scripts/test.sh) builds it into a
        // fresh virtual environment and tests it, its examples included.
        | ["python" | "pip" | "scripts/python.sh", ..]
        // Install Debian packages (and build a C++ driver, or a Python environment with
        // fontTools): measurements run by hand.
        | ["scripts/cgal-peer.sh" | "scripts/glyphs.sh" | "scripts/kiss-peer.sh", ..]
        // The glyphs' Python environment, which scripts/glyphs.sh makes.
        | [".tools/glyphs/bin/python", ..] => return,
        ["cargo", "run", "--release", "--", rest @ ..] | ["isoline", rest @ ..] => {
            let mut c = Command::new(bin);
            c.args(rest);
            c
        }
        [script, rest @ ..] if script.starts_with("scripts/") && script.ends_with(".sh") => {
            let mut c = Command::new("bash");
            c.arg(script).args(rest);
            c
        }
        ["python3", script, rest @ ..] if script.starts_with("scripts/") => {
            let mut c = Command::new("python3");
            c.arg(script).args(rest);
            c
        }
        _ => panic!("{what}: a command this test does not know how to run"),
    };
    // A configuration that binds a fixed port (the live view's 8765) is run by one
    // page at a time: two pages show the same demo, and side by side the second would
    // find the port taken.
    let binds = w
        .windows(2)
        .filter(|p| p[0] == "-c" || p[0] == "--config")
        .any(|p| {
            std::fs::read_to_string(dir.join(&p[1]))
                .is_ok_and(|t| t.lines().any(|l| l.starts_with("bind")))
        });
    let _port = binds.then(|| FIXED_PORTS.lock().unwrap_or_else(|e| e.into_inner()));
    cmd.current_dir(dir)
        .env("QUICK", "1")
        .env("ISOLINE_BIN", bin)
        .envs(env)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped());
    let mut child = cmd.spawn().unwrap_or_else(|e| panic!("{what}: {e}"));
    // A demo that serves until Ctrl-C (a lingering live view) is stopped as a user
    // would, once it says so; it must then end cleanly.
    let pid = child.id().to_string();
    let stderr = child.stderr.take().unwrap();
    let reader = std::thread::spawn(move || {
        use std::io::BufRead;
        let mut all = String::new();
        for line in std::io::BufReader::new(stderr)
            .lines()
            .map_while(Result::ok)
        {
            if line.contains("until Ctrl-C") {
                let _ = Command::new("kill").args(["-INT", &pid]).status();
            }
            all.push_str(&line);
            all.push('\n');
        }
        all
    });
    let out = child
        .wait_with_output()
        .unwrap_or_else(|e| panic!("{what}: {e}"));
    let stderr = reader.join().unwrap();
    assert!(
        out.status.success(),
        "{what} failed:\n{}\n{stderr}",
        String::from_utf8_lossy(&out.stdout),
    );
}

fn check_toml(dir: &Path, page: &Path, k: usize, body: &str) {
    let what = format!("{}, toml block {k}", page.display());
    // Written beside the shipped configurations, so that relative paths resolve alike.
    let path = dir
        .join("config-snippets")
        .join(format!("snippet-{k}.toml"));
    std::fs::write(&path, body).unwrap();
    if body.contains("[input]") {
        match isoline::pipeline::DaemonConfig::load(&path) {
            Ok(_) => {}
            // A TLS configuration is valid for a build with Kafka over TLS (the suite's,
            // scripts/test.sh); a build without it must refuse it, saying why.
            Err(e) if !cfg!(feature = "kafka-tls") && e.to_string().contains("kafka-tls") => {}
            Err(e) => panic!("{what}: {e}"),
        }
    } else if body.contains("[batch]") {
        isoline::batch::Job::load(&path).unwrap_or_else(|e| panic!("{what}: {e}"));
    } else {
        isoline::config::Config::load(&path).unwrap_or_else(|e| panic!("{what}: {e}"));
    }
}

fn check_json(page: &Path, k: usize, body: &str) {
    use isoline_io::format::{FrameRecord, ResultRecord, TruthFile};
    let what = format!("{}, json block {k}", page.display());
    let v: serde_json::Value =
        serde_json::from_str(body).unwrap_or_else(|e| panic!("{what}: not JSON: {e}"));
    if v.get("ranges").is_some() || v.get("points").is_some() {
        let rec: FrameRecord = serde_json::from_value(v).unwrap_or_else(|e| panic!("{what}: {e}"));
        isoline_io::Frame::from_record(rec).unwrap_or_else(|e| panic!("{what}: {e}"));
    } else if v.get("stats").is_some() || v.get("error").is_some() {
        let _: ResultRecord = serde_json::from_value(v).unwrap_or_else(|e| panic!("{what}: {e}"));
    } else {
        let _: TruthFile = serde_json::from_value(v).unwrap_or_else(|e| panic!("{what}: {e}"));
    }
}

/// Runs and parses one page's blocks in a folder of its own; the commands run.
fn check_page(page: &Path) -> usize {
    let mut ran = 0;
    let text = std::fs::read_to_string(page).unwrap();
    let dir = tempfile::tempdir().unwrap();
    for name in ["fixtures", "scripts"] {
        link(dir.path(), name);
    }
    // The tools the scripts make (the Kafka broker), shared with the checkout:
    // scripts/test.sh installs them before the tests run, and a page's scripts find
    // them rather than installing them again in its folder.
    if root().join(".tools").is_dir() {
        link(dir.path(), ".tools");
    }
    // Copied, not linked: a configuration's relative paths (`../scan-out`) must
    // resolve into the temporary folder, not beside the real one.
    std::fs::create_dir(dir.path().join("config")).unwrap();
    for e in std::fs::read_dir(root().join("config")).unwrap() {
        let e = e.unwrap();
        std::fs::copy(e.path(), dir.path().join("config").join(e.file_name())).unwrap();
    }
    std::fs::create_dir(dir.path().join("config-snippets")).unwrap();
    for (k, (lang, body)) in blocks(&text).into_iter().enumerate() {
        match lang.as_str() {
            "sh" => {
                for c in commands(&body) {
                    run(dir.path(), page, &c);
                    ran += 1;
                }
            }
            "toml" => check_toml(dir.path(), page, k, &body),
            "json" => check_json(page, k, &body),
            _ => {}
        }
    }
    ran
}

/// The pages run side by side, each in its own folder: most commands use one core.
#[test]
fn every_documented_command_and_snippet_works() {
    let pages = pages();
    let ran: usize = std::thread::scope(|s| {
        let runs: Vec<_> = pages
            .iter()
            .map(|page| s.spawn(move || check_page(page)))
            .collect();
        runs.into_iter()
            .map(|r| r.join().expect("a page failed; its message is above"))
            .sum()
    });
    assert!(ran >= 10, "only {ran} commands found in the docs");
}

#[test]
fn the_readme_is_a_front_door() {
    let readme = std::fs::read_to_string(root().join("README.md")).unwrap();
    assert!(
        readme.len() <= 12 * 1024,
        "README.md is {} bytes",
        readme.len()
    );
    // Every relative link points at a file that exists.
    for page in pages() {
        let text = std::fs::read_to_string(&page).unwrap();
        let base = page.parent().unwrap();
        for (i, _) in text.match_indices("](") {
            let rest = &text[i + 2..];
            let target = &rest[..rest.find(')').unwrap_or(0)];
            let target = target.split('#').next().unwrap_or("");
            if target.is_empty() || target.contains("://") {
                continue;
            }
            assert!(
                base.join(target).exists(),
                "{}: broken link {target}",
                page.display()
            );
        }
    }
}
