//! Writers for results: SVG drawings of meshes, points and curves.

pub mod svg;
