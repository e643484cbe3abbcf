//! What the integration tests share: running the real binary.

use std::path::Path;
use std::process::{Command, Output};

/// Runs `isoline` with `args` and checks that it succeeded (its stderr in the message).
pub fn ok(args: &[&str]) -> Output {
    let out = Command::new(env!("CARGO_BIN_EXE_isoline"))
        .args(args)
        .output()
        .expect("run isoline");
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// A path as an argument.
#[allow(dead_code)] // Not every test file passes paths.
pub fn p(path: &Path) -> &str {
    path.to_str().expect("a UTF-8 path")
}
