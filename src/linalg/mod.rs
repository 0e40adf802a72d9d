//! Dense linear algebra of the spline systems: serial oracles on one process ([`dense`]) and the
//! row-cyclic distributed solvers ([`dist`]).

pub mod dense;
pub mod dist;
