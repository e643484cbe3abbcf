//! The `isoline` binary's library: the streaming daemon ([`pipeline`]), batch jobs
//! ([`batch`]) and the TOML configuration they share ([`config`]). The method is
//! `isoline-core`, the file formats `isoline-io`, the simulators and scores
//! `isoline-sim`; this crate only moves frames between them.

#![forbid(unsafe_code)]
#![warn(missing_docs)]
#![deny(rustdoc::broken_intra_doc_links)]

pub mod batch;
pub mod config;
mod error;
mod files;
pub mod pipeline;

pub use error::{Error, Result};
pub use files::same_file;
