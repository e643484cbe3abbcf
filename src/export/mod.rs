//! Export (paper section 1.1, the last stage): the zero isoline as polylines, and writers
//! for results (NDJSON, JSON, GeoJSON, CSV, SVG).

pub mod contour;
pub mod svg;
pub mod writers;
