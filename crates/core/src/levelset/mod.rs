//! The level-set evolution (paper sections 2 and 3.4): initial signed distances, the
//! explicit and semi-implicit schemes, the stopping test of eq. 11, warm starts from the
//! previous frame, and the median settle; [`evolve::solve`] runs them as the solve stage.

pub mod evolve;
pub mod init;
pub mod orient;
pub mod params;
pub mod settle;
pub mod solver;
pub mod warm;

pub use init::Init;
pub use params::{Settle, SolverParams, Start, MAX_STEPS};
pub use solver::{LinearSolver, Scheme, StopReason};
