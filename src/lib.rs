//! volspline: reconstruction of solids from scattered surface points and planar contours as a
//! function representation f(x, y, z) >= 0, by volume splines built from the Green's function and
//! a carrier solid, solved and evaluated on distributed memory.
//!
//! Rooms, top to bottom (dependencies point downward only):
//! - [`cli`]: the command line, parsed into typed options; [`app`]: one file per command, the
//!   shared volume outputs, the run report and what crosses ranks.
//! - [`contour`]: solids from planar cross-sections (section splines, interpolation between
//!   slices, orientation of non-parallel slices, plane families).
//! - [`surface`]: surface points without normals -> oriented off-surface constraints.
//! - [`spline`]: the mathematics (kernels, carriers, the bordered system, evaluation, hygiene,
//!   the model); [`grid`]: the evaluation grid and its z-slabs.
//! - [`linalg`]: serial dense oracles and the row-cyclic distributed solvers.
//! - [`par`]: the communicator, typed collectives and the agreement on failures (the only room
//!   that talks to MPI); [`simd`]: hand-written loops dispatched to the widest vector unit.
//! - [`io`]: point, mesh, model and VTKHDF files; [`mesh`]: marching cubes and mesh measures.
//! - [`frep`]: reconstructed solids as function-representation objects (evaluation at points,
//!   derivatives, bounds) for modelling and pictures.

/// `eprintln!` that never panics: a line for a standard error whose reader has gone (`2>&1 | head
/// -1`, a launcher tearing the job down) is lost, not the run (`eprintln!` panics there, and the
/// panic aborts the job with its outputs unwritten). Every message of the crate goes through it.
#[macro_export]
macro_rules! note {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr(), $($arg)*);
    }};
}

pub mod app;
pub mod cli;
pub mod contour;
pub mod error;
pub mod frep;
pub mod graph;
pub mod grid;
pub mod io;
pub mod linalg;
pub mod mesh;
pub mod par;
pub mod simd;
pub mod spline;
pub mod surface;
