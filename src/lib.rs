//! volspline: reconstruction of solids from scattered surface points as a function representation
//! f(x, y, z) >= 0, by volume splines built from the Green's function and a carrier solid
//! (Savchenko, Pasko, Okunev, Kunii 1995), solved and evaluated on distributed memory.
//!
//! Layers, top to bottom (dependencies point downward only):
//! - `cli`: argument definitions and the printed report; `pipeline`: the collective stages.
//! - `contour`: solids from planar cross-sections (paper 000, section 4).
//! - `model`, `spline`, `carrier`, `kernel`, `geometry`, `grid`: the mathematics, pure.
//! - `dist`: communicator, row-cyclic layout, distributed solvers; `dense`: serial oracles.
//! - `io`: point, mesh, model and VTKHDF files; `mesh`: marching cubes and mesh measures.
//! - `report`: stage timing and progress.

pub mod carrier;
pub mod cli;
pub mod contour;
pub mod dense;
pub mod dist;
pub mod error;
pub mod eval;
pub mod geometry;
pub mod grid;
pub mod io;
pub mod kernel;
pub mod mesh;
pub mod model;
pub mod pipeline;
pub mod report;
pub mod spline;
