//! The mathematics of the reconstructed solid, pure (no ranks, no files): the Green's functions
//! ([`kernel`]), carrier solids and R-functions ([`carrier`]), the bordered interpolation system and
//! the spline it defines ([`system`]), fast evaluation on grid rows ([`evaluator`]), clean-up of the data
//! points before a fit ([`hygiene`]) and the solid f = f_c - U with its record ([`model`]).
//!
//! The method is that of Savchenko, Pasko, Okunev and Kunii, *Function representation of solids
//! reconstructed from scattered surface points and contours* (Computer Graphics Forum 14(4),
//! 1995), with its sign convention corrected. The derivations live with the code: the spline,
//! its bordered system, conditional definiteness, unisolvency and normalisation in [`system`];
//! the choice of carrier and the R-functions in [`carrier`]; the sign of the solid in [`model`].

pub mod carrier;
pub mod evaluator;
pub mod hygiene;
pub mod kernel;
pub mod model;
pub mod system;

pub use carrier::Carrier;
pub use evaluator::Evaluator;
pub use kernel::Kernel;
pub use model::{Field, Model, Provenance};
pub use system::{fill_rows, full_system, residual_parts, system_size, Normalisation, Spline};
