//! The tests through the `isoline` binary, in one test binary (one link of the
//! workspace instead of one per file): each module is one area of the contract.

mod architecture;
mod batch;
mod cli;
mod common;
mod daemon;
mod docs;
mod files;
mod fuzz_regressions;
mod hardening;
#[cfg(feature = "kafka")]
mod kafka;
#[cfg(feature = "live")]
mod listeners;
mod map;
mod moving;
mod reconstruct;
mod robotics;
mod scan;
mod soak;
