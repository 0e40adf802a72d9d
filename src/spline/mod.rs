//! The mathematics of the reconstructed solid, pure (no ranks, no files): the kernels, Green's
//! functions and compactly supported Wendland functions ([`kernel`]), carrier solids and
//! R-functions ([`carrier`]), the bordered interpolation system and the spline it defines
//! ([`system`]), its sparse form for compactly supported kernels ([`compact`], with the point
//! octree of [`octree`]), fast evaluation on grid rows ([`evaluator`], [`compact_eval`]; where only
//! the sign must be exact, [`sign_eval`]), clean-up
//! of the data points before a fit ([`hygiene`]), analytic derivatives ([`derivatives`]),
//! evaluation at single points ([`point_eval`]) and the solid f = f_c - U with its record
//! ([`model`]).
//!
//! The method is that of Savchenko, Pasko, Okunev and Kunii, *Function representation of solids
//! reconstructed from scattered surface points and contours* (Computer Graphics Forum 14(4),
//! 1995), with its sign convention corrected, and, for compactly supported kernels, that of
//! Kojekine, Savchenko, Berzin and Hagiwara, *Software tools for compactly supported radial
//! basis functions* (2001). The derivations live with the code: the spline, its bordered system,
//! conditional definiteness, unisolvency and normalisation in [`system`]; Wendland functions,
//! their definiteness, the support radius and the sparse block system in [`compact`]; the
//! octree and the banded ordering in [`octree`]; the choice of carrier and the R-functions in
//! [`carrier`]; the sign of the solid in [`model`].

pub mod carrier;
pub mod compact;
pub mod compact_eval;
pub mod derivatives;
pub mod evaluator;
pub mod hygiene;
pub mod kernel;
pub mod model;
pub mod octree;
pub mod point_eval;
pub mod sign_eval;
pub mod system;

pub use carrier::Carrier;
pub use evaluator::Evaluator;
pub use kernel::{Kernel, Wendland, WendlandKind};
pub use model::{Field, Model, Provenance};
pub use octree::Octree;
pub use sign_eval::SignEvaluator;
pub use system::{
    fill_block, fill_block_lower, fill_rows, fill_rows_lower, full_system, residual_parts, system_size,
    Normalisation, Spline,
};
