//! The mapping crate's errors.

/// What can go wrong while building a map.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// Parameters are invalid; every problem found is listed.
    #[error("invalid configuration {path}:\n  {}", problems.join("\n  "))]
    Config {
        /// What the parameters came from (a file, or "map parameters").
        path: String,
        /// Every problem found, each naming its key path.
        problems: Vec<String>,
    },
    /// A map's tile store could not keep or give back a tile (a full disk, a removed
    /// spill directory).
    #[error("map tile store: {0}")]
    TileStore(String),
    /// A map was given a pose beyond the farthest its lattice holds.
    #[error(
        "pose ({}, {}, {}) is beyond the map's reach: sensors within {limit:e} m of the \
         origin are placed",
        pose[0], pose[1], pose[2]
    )]
    PoseOutOfReach {
        /// The pose given.
        pose: [f64; 3],
        /// [`MapParams::max_coordinate`](crate::MapParams::max_coordinate), metres.
        limit: f64,
    },
}

/// `Result` with the mapping crate's [`Error`].
pub type Result<T> = std::result::Result<T, Error>;
