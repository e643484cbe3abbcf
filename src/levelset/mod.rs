//! The level-set evolution (paper sections 2 and 3.4): initial signed distances, the
//! explicit and semi-implicit schemes, and the stopping test of eq. 11.

pub mod init;
pub mod solver;

pub use init::Init;
pub use solver::{LinearSolver, Scheme, SolveReport, Solver, SolverSettings, StopReason};
