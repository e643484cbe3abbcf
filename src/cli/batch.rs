//! `isoline batch`: many inputs reconstructed in parallel, as a TOML job file says.

use std::path::{Path, PathBuf};

use anyhow::{bail, Result};

/// `isoline batch` options.
#[derive(clap::Args)]
pub struct Args {
    /// Job file: [batch] inputs, output, formats, workers; [mesh] [solver] [export];
    /// [files."GLOB".*] overrides.
    #[arg(short, long)]
    config: PathBuf,
    /// Redo inputs whose outputs are up to date.
    #[arg(long)]
    force: bool,
}

/// Runs the job: a progress bar on a terminal, a log line per file otherwise, and the
/// summary table at the end; fails when a file failed.
pub fn run(a: Args) -> Result<()> {
    use std::io::IsTerminal;
    let force = a.force;
    let job = isoline::batch::Job::load(&a.config)?;
    let n = job.tasks.len();
    let bar = std::io::stderr().is_terminal().then(|| {
        let b = indicatif::ProgressBar::new(n as u64);
        b.set_style(
            indicatif::ProgressStyle::with_template(
                "{elapsed_precise} [{bar:40}] {pos}/{len} files, {per_sec}, eta {eta} {msg}",
            )
            .expect("valid template")
            .progress_chars("=> "),
        );
        b
    });
    let done = std::sync::atomic::AtomicUsize::new(0);
    eprintln!(
        "isoline batch: {n} files, {} workers, output {}",
        job.workers,
        job.output.display()
    );
    let summary = job.run(force, |f| {
        let k = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
        match &bar {
            Some(b) => {
                b.set_message(f.file.clone());
                b.inc(1);
            }
            None => eprintln!(
                "[{k}/{n}] {} {}{} ({:.0} ms)",
                f.file,
                f.status,
                f.reason
                    .as_deref()
                    .map(|r| format!(": {r}"))
                    .unwrap_or_default(),
                f.ms
            ),
        }
    })?;
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    let mut table = format!(
        "{:<40} {:>8} {:>7} {:>9} {:>9} {:>9} {:>10} {:>9}",
        "file", "status", "points", "polylines", "vertices", "iterations", "residual", "ms"
    );
    for f in &summary.files {
        let name = Path::new(&f.file)
            .file_name()
            .map_or(f.file.clone(), |n| n.to_string_lossy().into_owned());
        table += &format!(
            "\n{:<40} {:>8} {:>7} {:>9} {:>9} {:>9} {:>10.2e} {:>9.0}",
            name, f.status, f.points, f.polylines, f.vertices, f.iterations, f.residual, f.ms
        );
        if let Some(r) = &f.reason {
            table += &format!("\n    {r}");
        }
    }
    let t = &summary.totals;
    table += &format!(
        "\ntotal: {} files, {} reconstructed, {} skipped, {} failed; {} points, {} polylines; {:.1} s, {:.2} files/s",
        t.files, t.ok, t.skipped, t.failed, t.points, t.polylines, t.ms / 1e3, t.files_per_second
    );
    table += &format!("\nsummary: {}\n", job.output.join("summary.json").display());
    super::print(&table)?;
    if t.failed > 0 {
        bail!(
            "{} of {} files failed (reasons in summary.json)",
            t.failed,
            t.files
        );
    }
    Ok(())
}
