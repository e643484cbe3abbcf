//! isoline reconstructs smooth curves from noisy, unorganized 2D points with the
//! level-set method of Claisse & Frey (2009).
//!
//! The crate is layered: [`geom`] → [`distance`] → [`mesh`] → [`fem`], with the file
//! nothing of serde, files or threads.

pub mod distance;
pub mod error;
pub mod fem;
pub mod geom;
pub mod mesh;

pub use error::{Error, Result};
