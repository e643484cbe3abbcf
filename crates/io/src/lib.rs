//! isoline-io reads and writes isoline's files: point files, NDJSON frames (points, or a
//! scanner's beams shaped like a ROS `LaserScan`), ROS 2 bags (MCAP), CARMEN logs, and
//! the results as NDJSON records, JSON, GeoJSON, CSV, SVG drawings and MCAP for
//! Foxglove. The JSON shapes of the contract are [`mod@format`]; readers give validated
//! [`Frame`]s, which [`reconstruct_frame`] turns into result records.
//!
//! ```
//! use isoline_core::Params;
//! use isoline_io::{parse_frame, reconstruct_frame, write};
//! // A frame of 200 points round a circle, as an NDJSON line.
//! let points: Vec<String> = (0..200)
//!     .map(|i| {
//!         let a = i as f64 * std::f64::consts::TAU / 200.0;
//!         format!("[{},{}]", a.cos(), a.sin())
//!     })
//!     .collect();
//! let line = format!(r#"{{"stream":"demo","frame":0,"points":[{}]}}"#, points.join(","));
//! let frame = parse_frame(&line, "example", 1).unwrap();
//! let (record, _) = reconstruct_frame(&frame, &Params::default());
//! let curves = record.polylines.as_ref().unwrap();
//! assert_eq!(curves.len(), 1);
//! assert!(curves[0].closed);
//! let mut out = Vec::new();
//! write::write_ndjson(&mut out, &record).unwrap();
//! assert!(out.starts_with(br#"{"stream":"demo","frame":0,"polylines":[{"closed":true"#));
//! ```

#![forbid(unsafe_code)]
#![warn(missing_docs)]
#![deny(rustdoc::broken_intra_doc_links)]

pub mod config;
mod error;
pub mod format;
pub mod foxglove;
mod ingest;
pub mod map_files;
mod record;
mod tiles;
pub mod write;

pub use error::{Error, Result};
pub use ingest::{
    bag, carmen, for_each_item, for_each_item_capped, is_bag, is_compressed_frame_stream,
    is_frame_stream, is_recording, parse_frame, parse_points, read_frames, read_input, read_items,
    read_points, ros, BadFrame, Deskew, Frame, Item, MAX_FRAME_LINE_BYTES,
};
pub use record::reconstruct_frame;
pub use tiles::DiskTiles;
