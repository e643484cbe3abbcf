//! The configuration files: the method's tables are isoline-io's
//! ([`isoline_io::config`]); here, the helpers the daemon's and batch jobs' tables share.

use std::path::Path;

pub use isoline_io::config::*;

/// `v` if set and in `lo..=hi`, `default` if unset; out of range, `default` and a
/// problem naming `key`.
pub(crate) fn bounded(
    key: &str,
    v: Option<i64>,
    default: usize,
    lo: usize,
    hi: usize,
    problems: &mut Vec<String>,
) -> usize {
    match v {
        None => default,
        Some(v) if (lo as i64..=hi as i64).contains(&v) => v as usize,
        Some(v) => {
            problems.push(format!("{key} = {v}: must be in {lo}..={hi}"));
            default
        }
    }
}

/// The address a listener of table `table` binds: `bind` (or `default`), refused when it
/// is not loopback unless `allow_remote` says so.
pub(crate) fn listen_address(
    table: &str,
    bind: Option<&str>,
    allow_remote: Option<bool>,
    default: &str,
    problems: &mut Vec<String>,
) -> Option<std::net::SocketAddr> {
    let bind = bind.unwrap_or(default);
    match bind.parse::<std::net::SocketAddr>() {
        Ok(b) if !b.ip().is_loopback() && allow_remote != Some(true) => {
            problems.push(format!(
                "{table}.bind = {bind:?}: not a loopback address, so anyone on the network \
                 could connect; set {table}.allow_remote = true to mean it"
            ));
            None
        }
        Ok(b) => Some(b),
        Err(e) => {
            problems.push(format!(
                "{table}.bind = {bind:?}: {e} (expected e.g. \"{default}\")"
            ));
            None
        }
    }
}

/// A path as written in a configuration file, taken from the file's folder `base`
/// when relative.
pub(crate) fn resolve(base: &Path, p: &Path) -> std::path::PathBuf {
    if p.is_absolute() {
        p.to_path_buf()
    } else {
        base.join(p)
    }
}
