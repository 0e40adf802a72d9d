//! Dense linear algebra of the spline systems: one Householder reflector and its compact-WY
//! blocks ([`reflector`]), serial oracles on one process ([`dense`]) and the row-cyclic distributed
//! solvers ([`dist`]). The sparse symmetric positive definite systems of compactly supported
//! splines have their own format and interface ([`sparse`]) and a distributed factorisation by
//! MUMPS ([`mumps`]).
//!
//! # The system
//!
//! A volume spline through N centres x_i with values r_i is U(x) = sum_i lambda_i G(|x - x_i|) +
//! sum_j c_j p_j(x), where G is the polyharmonic kernel of order m and p_1..p_k span the
//! polynomials of degree < m. Interpolation, U(x_i) = r_i, together with the moment conditions
//! sum_i lambda_i p_j(x_i) = 0 (which make the spline the one of least energy and the system
//! square), is the symmetric bordered system of size N + k
//!
//! ```text
//!     [ A   P ] [ lambda ]   [ r ]        A_ij = G(|x_i - x_j|)   (N x N, zero diagonal)
//!     [ P^T 0 ] [   c    ] = [ 0 ],       P_ij = p_j(x_i)         (N x k).
//! ```
//!
//! It is indefinite (its trailing k x k block is zero), so plain Cholesky does not apply. It has
//! one solution when P has full column rank (the centres are unisolvent: for m = 2 in 3D, not all
//! in one plane), because A is then definite on the null space of P^T (see [`dist`]'s Cholesky).
//! Three solvers are offered:
//!
//! - Householder QR, M = Q R, x = R^-1 Q^T b: backward stable for any nonsingular M,
//!   4/3 n^3 flops;
//! - LU with partial pivoting, P M = L U: 2/3 n^3 flops, stable in practice;
//! - the projected Cholesky: B = Q2^T A Q2 of order N - k is definite, factored as L L^T,
//!   1/3 n^3 flops; it falls back to LU when rounding makes a pivot non-positive.
//!
//! The derivations are in the module documentation of the code that implements them:
//! [`reflector`] (the reflector, compact WY), `dist::lu` (LU, blocking), `dist::cholesky` (the
//! projection, its definiteness and the recovery of lambda and c), `dist::layout` (the row-cyclic
//! layout) and `dist::householder` (which sums travel between the ranks).
//!
//! # Matrices
//!
//! Serial code uses faer's `Mat`/`MatRef` (column-major); the oracles take a `MatRef` of any
//! strides. Distributed code uses [`dist::LocalRows`], a rank's rows of the global matrix with
//! the right-hand side as its last column, viewed as a faer matrix for the local kernels.
//!
//! # Parallelism
//!
//! Between ranks the solvers communicate through [`crate::par::Comm`]; within a rank the
//! distributed solvers take a `faer::Par`, the parallelism of their local GEMMs and triangular
//! solves (`Par::Seq`, or `Par::rayon(t)` for t threads). Everything in [`reflector`] and
//! [`dense`] is serial.

pub mod dense;
pub mod dist;
pub mod gemm;
pub mod mumps;
pub mod reflector;
pub mod sparse;

/// `len` zeros, or [`crate::error::Error::Memory`] naming `what` where the system refuses the allocation, in
/// place of the abort a failed allocation is: an address-space limit (`ulimit -v`, a batch
/// system's `h_vmem`) or strict overcommit accounting can refuse memory the checks before a
/// stage found. The allocation is tried first and given back, then made zeroed, so that the
/// pages a solver never writes (the upper triangle the projected Cholesky leaves alone) are
/// never touched.
pub fn try_zeros<T: Copy>(
    len: usize,
    zero: T,
    what: impl FnOnce() -> String,
) -> crate::error::Result<Vec<T>> {
    let mut probe: Vec<T> = Vec::new();
    if probe.try_reserve_exact(len).is_err() {
        let bytes = len as f64 * std::mem::size_of::<T>() as f64;
        return Err(crate::error::Error::Memory(format!(
            "the system refused {:.0} MB for {} although the memory checks found room for it: an \
             address-space limit (ulimit -v, a batch system's h_vmem) or strict overcommit accounting \
             (vm.overcommit_memory = 2) counts memory the checks cannot see; use more ranks or nodes, or \
             raise that limit",
            bytes / 1e6,
            what()
        )));
    }
    drop(probe);
    Ok(vec![zero; len])
}
