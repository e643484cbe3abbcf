//! One input frame to its result record: the reconstruction, or the error, answered
//! with the frame's ids.

use isoline_core::stages::reconstruct_with;
use isoline_core::{Params, Reconstruction};

use crate::format::ResultRecord;
use crate::ingest::Frame;

/// Reconstructs one input frame into its result record (curves and stats, or the error),
/// with a tracing span carrying the stream and frame ids. The reconstruction itself is
/// returned too, for drawing.
pub fn reconstruct_frame(frame: &Frame, params: &Params) -> (ResultRecord, Option<Reconstruction>) {
    let span = tracing::info_span!(
        "frame",
        stream = frame.stream.as_deref().unwrap_or(""),
        frame = frame.frame
    );
    let _e = span.enter();
    match reconstruct_with(&frame.points, frame.scan.as_ref(), params, None) {
        Ok(r) => {
            let mut rec = ResultRecord {
                t: frame.t,
                pose: frame.pose,
                ..ResultRecord::of(frame.stream.clone(), frame.frame, &r)
            };
            rec.add_warnings(&frame.notes);
            (rec, Some(r))
        }
        Err(e) => (
            ResultRecord {
                stream: frame.stream.clone(),
                frame: Some(frame.frame),
                t: frame.t,
                pose: frame.pose,
                error: Some(e.to_string()),
                ..Default::default()
            },
            None,
        ),
    }
}
