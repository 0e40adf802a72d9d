//! The distributed sparse Cholesky factorisation of MUMPS (the MUltifrontal Massively Parallel
//! sparse direct Solver, Amestoy, Duff, L'Excellent & Koster, SIAM J. Matrix Anal. Appl. 23, 2001),
//! for the symmetric positive definite matrices of compactly supported splines.
//!
//! # What MUMPS does here
//!
//! MUMPS factors A = L D L^T (D diagonal and positive for a positive definite A, which is a
//! Cholesky factorisation up to scaling) by the multifrontal method: an ordering of the unknowns
//! that limits fill-in, the elimination tree of the ordered matrix, and, for each node of the tree
//! from the leaves up, a small dense frontal matrix that is assembled from the entries of A and
//! the update matrices of the node's children, partially factored by dense kernels (BLAS 3), and
//! whose remaining Schur complement becomes the update matrix passed to its parent. Independent
//! subtrees go to different ranks; large fronts are shared by several ranks, and the root front by
//! all of them (ScaLAPACK). The factors stay distributed over the ranks for the whole life of the
//! factorisation.
//!
//! The matrix is given in MUMPS's distributed assembled format: each rank passes the entries it
//! holds (its rows of the lower triangle, [`SymCsr`] with global indices) as 1-based triples
//! (i, j, a_ij); entries given twice, on one rank or on several, are summed. The values are never
//! gathered on one rank; a sequential analysis (the only kind the Debian build of MUMPS offers,
//! which has neither PT-SCOTCH nor ParMETIS) gathers the pattern, the (i, j) pairs, on rank 0 to
//! order it. The right-hand sides are centralised: they are the same on every rank,
//! MUMPS reads rank 0's copy and writes the solution there, and the solution is broadcast, so
//! every rank returns the same bits. (Two solves with the same factors on several ranks may differ
//! in the last bits: MUMPS sums contributions in the order its messages arrive.)
//!
//! # Life cycle
//!
//! One MUMPS instance per factorisation, each step collective over the communicator and selected
//! by the JOB parameter of the single entry point `dmumps_c`:
//!
//! - JOB = -1, initialisation: symmetric positive definite mode (SYM = 1), rank 0 takes part in
//!   the factorisation (PAR = 1), the communicator (MUMPS duplicates it); then the controls
//!   (ICNTL) are set: no printing unless asked, distributed assembled entry (ICNTL(18) = 3),
//!   automatic choice of the ordering and of sequential or parallel analysis (ICNTL(7) = 7,
//!   ICNTL(28) = 0; the Debian build offers the sequential AMD, AMF, QAMD and PORD orderings),
//!   centralised dense right-hand sides and solution (ICNTL(20) = 0, ICNTL(21) = 0);
//! - JOB = 1, analysis: ordering, symbolic factorisation, mapping of the tree onto the ranks;
//! - JOB = 2, numerical factorisation;
//! - JOB = 3, solution, as often as needed ([`SpdSolve::solve_in_place`]);
//! - JOB = -2, the end: frees MUMPS's memory (when the [`MumpsSpd`] is dropped).
//!
//! # Errors
//!
//! MUMPS reports a failure in INFOG(1) < 0, the same value on every rank (INFOG(2) adds a detail,
//! a size or a rank). It becomes a typed error that names the code and says why in plain words:
//!
//! - -10 (a zero pivot: numerically singular) and -40 (a non-positive pivot in the root front's
//!   ScaLAPACK Cholesky) -> [`Error::NotDefinite`];
//! - -5, -7, -8, -9, -11 to -15, -17, -19, -20 (an allocation failed or a work array estimated
//!   at the analysis was too small) -> [`Error::Memory`];
//! - -2, -16 (sizes out of range) -> [`Error::Usage`]; every other code, -6 (structurally
//!   singular) included -> [`Error::Numerical`].
//!
//! In the positive definite mode MUMPS does not pivot, and a negative pivot does not stop it: a
//! symmetric matrix that is not positive definite but whose leading minors are nonzero is factored
//! as L D L^T with some negative entries in D, and MUMPS counts them in INFOG(12). A factorisation
//! with INFOG(12) > 0 is therefore refused with [`Error::NotDefinite`] as well.
//!
//! Input that MUMPS cannot take (a row or column out of range, an entry above the diagonal, a
//! non-finite value, orders that differ between ranks) is refused before MUMPS is called, with
//! [`Error::Usage`] or [`Error::Numerical`]. Every error is agreed across the ranks with
//! [`par::agree`], so a failure on one rank never leaves the others waiting in a collective.
//!
//! MUMPS needs MPI: a communicator without a Fortran handle ([`crate::par::Solo`]) is refused with
//! [`Error::Usage`]. A process started without `mpirun` still has one, since
//! [`crate::par::mpi::World::start`] initialises MPI as a singleton.
//!
//! The unsafe code of the binding is the private `Instance` of this file: a boxed, zero-initialised
//! `DMUMPS_STRUC_C` (so its address never changes between calls), the arrays it points to, owned
//! next to it and never changed while it lives, and the calls of `dmumps_c`.

use std::cell::RefCell;

use super::sparse::{SpdSolve, SymCsr};
use crate::error::{Error, Result};
use crate::par::{self, Comm};

#[allow(non_camel_case_types, non_snake_case, non_upper_case_globals, dead_code)]
mod ffi {
    include!(concat!(env!("OUT_DIR"), "/dmumps.rs"));
}

/// Settings of a factorisation beyond the defaults.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct MumpsOptions {
    /// Let MUMPS print its errors, warnings and statistics (on standard output); off by default.
    pub verbose: bool,
}

/// Figures of a factorisation, the same on every rank (sums over the ranks where not said).
#[derive(Debug, Clone, PartialEq)]
pub struct MumpsStats {
    /// Entries in the factors after factorisation (INFOG(29)).
    pub factor_entries: u64,
    /// Reals of storage for the factors, as estimated by the analysis (INFOG(3)).
    pub factor_reals_estimated: u64,
    /// Reals of storage for the factors after factorisation (INFOG(9)).
    pub factor_reals: u64,
    /// Working memory of the factorisation in MB: the largest over the ranks and the total
    /// (INFOG(21), INFOG(22)).
    pub memory_mb_max: u64,
    pub memory_mb_total: u64,
    /// Floating-point operations of the elimination (RINFOG(3)).
    pub flops: f64,
    /// The ordering MUMPS chose (INFOG(7), INFOG(32)), e.g. "PORD (sequential analysis)".
    pub ordering: String,
}

/// A symmetric positive definite matrix factored by MUMPS on the ranks of a communicator.
///
/// Every method is collective, and the value must be dropped on all ranks together (dropping
/// ends the MUMPS instance, JOB = -2, a collective call): keep one per rank with the same life
/// time, and drop it before MPI is finalised.
pub struct MumpsSpd<'c> {
    comm: &'c dyn Comm,
    n: usize,
    stats: MumpsStats,
    instance: RefCell<Instance>,
}

impl std::fmt::Debug for MumpsSpd<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MumpsSpd").field("n", &self.n).field("stats", &self.stats).finish_non_exhaustive()
    }
}

impl<'c> MumpsSpd<'c> {
    /// Factors the matrix whose rows of the lower triangle each rank holds in `a` (global row and
    /// column indices, `a.n` the global order, the same on every rank). Collective.
    pub fn factor(comm: &'c dyn Comm, a: &SymCsr) -> Result<MumpsSpd<'c>> {
        Self::factor_with(comm, a, MumpsOptions::default())
    }

    /// [`MumpsSpd::factor`] with `options`. Collective.
    pub fn factor_with(comm: &'c dyn Comm, a: &SymCsr, options: MumpsOptions) -> Result<MumpsSpd<'c>> {
        let mut n_range = [a.n as f64, -(a.n as f64)];
        comm.min_f64(&mut n_range);
        let same_n = n_range[0] == -n_range[1];
        let checked = if same_n {
            check_local(a)
        } else {
            Err(Error::Usage(format!(
                "the ranks disagree on the order of the matrix ({} to {})",
                n_range[0], -n_range[1]
            )))
        };
        let local = checked.and_then(|triples| match comm.fortran_handle() {
            Some(handle) => Ok((handle, triples)),
            None => Err(Error::Usage("MUMPS needs an MPI communicator; start the program with MPI".into())),
        });
        let (handle, (irn, jcn, vals)) = par::agree(comm, local)?;

        // INFOG(1) is the same on every rank, but the outcome of each step is agreed all the same,
        // so that every rank surely takes the same branch (and ends the instance, a collective)
        let mut instance = Instance::init(handle, irn, jcn, vals, a.n);
        let started = par::agree(comm, instance.outcome("initialisation"));
        instance.started = started.is_ok();
        started?;
        instance.configure(options);
        instance.call(1);
        // on an error, `instance` is dropped, JOB = -2, on every rank
        par::agree(comm, instance.outcome("analysis"))?;
        // the analysis estimates the workspace; where the pivots' fronts come out larger than
        // estimated (more so on more ranks) MUMPS stops with a workspace error, and the remedy is
        // to factor again with a larger relaxation ICNTL(14) (a percentage of the estimate)
        let mut relax = WORKSPACE_RELAXATION;
        loop {
            instance.set_icntl(14, relax);
            instance.call(2);
            let short = WORKSPACE_SHORT.contains(&instance.id.infog[0]);
            if short && relax < MAX_WORKSPACE_RELAXATION {
                relax *= 2;
                continue;
            }
            par::agree(comm, instance.outcome("factorisation"))?;
            break;
        }
        let stats = instance.stats();
        Ok(MumpsSpd { comm, n: a.n, stats, instance: RefCell::new(instance) })
    }

    /// The figures of the factorisation.
    pub fn stats(&self) -> &MumpsStats {
        &self.stats
    }
}

impl SpdSolve for MumpsSpd<'_> {
    fn order(&self) -> usize {
        self.n
    }

    /// Collective; `rhs` must be the same on every rank (MUMPS reads rank 0's copy). On success
    /// every rank holds the same solution; after an error `rhs` is unspecified.
    fn solve_in_place(&self, rhs: &mut [f64], nrhs: usize) -> Result<()> {
        let checked = if self.n.checked_mul(nrhs) != Some(rhs.len()) {
            Err(Error::Usage(format!(
                "{} right-hand side values for {nrhs} right-hand side(s) of order {}",
                rhs.len(),
                self.n
            )))
        } else if nrhs > i32::MAX as usize {
            Err(Error::Usage(format!("{nrhs} right-hand sides are more than MUMPS takes at once")))
        } else {
            Ok(())
        };
        par::agree(self.comm, checked)?;
        if nrhs == 0 {
            return Ok(());
        }
        let host = self.comm.rank() == 0;
        let solved = self.instance.borrow_mut().solve(host.then_some(&mut *rhs), nrhs);
        par::agree(self.comm, solved)?;
        self.comm.broadcast_f64(0, rhs);
        Ok(())
    }
}

/// Percentage by which the factorisation's workspace exceeds the analysis's estimate at first
/// (MUMPS's own default is 20 to 35).
const WORKSPACE_RELAXATION: i32 = 50;

/// The relaxation beyond which a workspace error is reported rather than retried.
const MAX_WORKSPACE_RELAXATION: i32 = 800;

/// INFOG(1) codes of a workspace that was estimated too small (MUMPS 5.5 user guide, section 8).
const WORKSPACE_SHORT: [i32; 4] = [-8, -9, -14, -15];

/// The triples MUMPS takes (1-based row and column indices, values) of this rank's entries, or
/// why they cannot be given.
fn check_local(a: &SymCsr) -> Result<(Vec<i32>, Vec<i32>, Vec<f64>)> {
    if a.n == 0 {
        return Err(Error::Usage("the matrix has order 0".into()));
    }
    if a.n >= i32::MAX as usize {
        return Err(Error::Usage(format!("order {} exceeds MUMPS's 32-bit indices", a.n)));
    }
    let nnz = a.vals.len();
    let shape_ok = a.row_ptr.len() == a.rows.len() + 1
        && a.row_ptr.first() == Some(&0)
        && a.row_ptr.windows(2).all(|w| w[0] <= w[1])
        && a.row_ptr.last() == Some(&nnz)
        && a.cols.len() == nnz;
    if !shape_ok {
        return Err(Error::Usage(format!(
            "malformed sparse matrix: {} rows, {} row pointers, {} column indices, {} values",
            a.rows.len(),
            a.row_ptr.len(),
            a.cols.len(),
            nnz
        )));
    }
    let (mut irn, mut jcn) = (Vec::with_capacity(nnz), Vec::with_capacity(nnz));
    for (l, &i) in a.rows.iter().enumerate() {
        if i >= a.n {
            return Err(Error::Usage(format!("row {i} of a matrix of order {}", a.n)));
        }
        for (j, v) in a.row(l) {
            if j > i {
                return Err(Error::Usage(format!("entry ({i}, {j}) lies above the diagonal")));
            }
            if !v.is_finite() {
                return Err(Error::Numerical(format!("entry ({i}, {j}) of the matrix is {v}")));
            }
            irn.push(i as i32 + 1);
            jcn.push(j as i32 + 1);
        }
    }
    Ok((irn, jcn, a.vals.clone()))
}

/// A failure of MUMPS (INFOG(1) = `code` < 0, INFOG(2) = `detail`) as a typed error.
fn mumps_error(phase: &str, code: i32, detail: i32) -> Error {
    let size = || if detail < 0 { format!("{} million", -(detail as i64)) } else { detail.to_string() };
    let reason = match code {
        -10 => "the matrix is numerically singular, so not positive definite (a zero pivot)".into(),
        -40 => "the matrix is not positive definite (a non-positive pivot in the root front)".into(),
        -5 | -7 => format!("allocating {} entries of work space for the analysis failed", size()),
        -8 | -14 | -15 => "the integer work array estimated by the analysis was too small".into(),
        -9 | -11 | -12 => "the real work array estimated by the analysis was too small".into(),
        -13 => format!("allocating {} entries of work space failed", size()),
        -17 | -20 => "a communication buffer estimated by the analysis was too small".into(),
        -19 => "the working memory limit was too small".into(),
        -2 | -16 => "the order or the number of entries is out of range".into(),
        -6 => format!("the matrix is structurally singular (structural rank {detail})"),
        -23 => "MPI was not initialised".into(),
        _ => format!("see the MUMPS users' guide (INFOG(2) = {detail})"),
    };
    let msg = format!("MUMPS {phase} failed with error {code}: {reason}");
    match code {
        -10 | -40 => Error::NotDefinite(msg),
        -5 | -7 | -8 | -9 | -11 | -12 | -13 | -14 | -15 | -17 | -19 | -20 => Error::Memory(msg),
        -2 | -16 => Error::Usage(msg),
        _ => Error::Numerical(msg),
    }
}

/// A count MUMPS reports (INFOG), negative when it is in millions.
fn count(v: i32) -> u64 {
    if v < 0 {
        (-(v as i64)) as u64 * 1_000_000
    } else {
        v as u64
    }
}

/// The ordering of INFOG(7), after an analysis of kind INFOG(32).
fn ordering_name(code: i32, analysis: i32) -> String {
    let parallel = analysis == 2;
    let name = match (parallel, code) {
        (true, 1) => "PT-SCOTCH",
        (true, 2) => "ParMETIS",
        (false, 0) => "AMD",
        (false, 1) => "given by the user",
        (false, 2) => "AMF",
        (false, 3) => "SCOTCH",
        (false, 4) => "PORD",
        (false, 5) => "METIS",
        (false, 6) => "QAMD",
        _ => "unknown",
    };
    format!("{name} ({} analysis)", if parallel { "parallel" } else { "sequential" })
}

/// One MUMPS instance with the arrays its structure points to. Every call of MUMPS (`init`,
/// `call`, `solve`, drop) is collective.
struct Instance {
    id: Box<ffi::DMUMPS_STRUC_C>,
    /// JOB = -1 succeeded: there is something to end.
    started: bool,
    irn: Vec<i32>,
    jcn: Vec<i32>,
    vals: Vec<f64>,
}

impl Instance {
    /// JOB = -1 on the communicator `comm_fortran`, with this rank's entries; [`Instance::outcome`]
    /// tells whether it succeeded.
    fn init(comm_fortran: i32, irn: Vec<i32>, jcn: Vec<i32>, vals: Vec<f64>, n: usize) -> Instance {
        // SAFETY: DMUMPS_STRUC_C holds only integers, reals, pointers and char arrays, for which
        // all-zero bytes are valid values (null pointers, empty strings).
        let id: Box<ffi::DMUMPS_STRUC_C> = Box::new(unsafe { std::mem::zeroed() });
        let mut inst = Instance { id, started: false, irn, jcn, vals };
        inst.id.sym = 1;
        inst.id.par = 1;
        inst.id.comm_fortran = comm_fortran;
        inst.call(-1);
        // the matrix: global order, this rank's triples; the arrays live as long as the instance
        // (in `self`) and are never changed, so the pointers stay valid
        inst.id.n = n as i32;
        inst.id.nnz_loc = inst.vals.len() as i64;
        inst.id.nz_loc = i32::try_from(inst.vals.len()).unwrap_or(0);
        inst.id.irn_loc = inst.irn.as_mut_ptr();
        inst.id.jcn_loc = inst.jcn.as_mut_ptr();
        inst.id.a_loc = inst.vals.as_mut_ptr();
        inst
    }

    /// The controls of this module (see the module documentation).
    fn configure(&mut self, options: MumpsOptions) {
        let print = if options.verbose { 6 } else { -1 };
        for (k, v) in [(1, print), (2, print), (3, print), (4, if options.verbose { 2 } else { 0 })] {
            self.set_icntl(k, v);
        }
        for (k, v) in [(5, 0), (7, 7), (18, 3), (20, 0), (21, 0), (28, 0)] {
            self.set_icntl(k, v);
        }
    }

    /// The outcome of the last call, from INFOG(1) and INFOG(2), and after the factorisation
    /// the count of negative pivots, INFOG(12).
    fn outcome(&self, phase: &str) -> Result<()> {
        match self.infog(1) {
            code if code < 0 => Err(mumps_error(phase, code, self.infog(2))),
            _ if self.id.job == 2 && self.infog(12) > 0 => Err(Error::NotDefinite(format!(
                "MUMPS factorisation met {} negative pivot(s) of {}: the matrix is not positive definite",
                self.infog(12),
                self.id.n
            ))),
            _ => Ok(()),
        }
    }

    /// JOB = 3 with the right-hand sides on the host (Some on rank 0, None elsewhere): `nrhs`
    /// columns of the order n, overwritten by the solution.
    fn solve(&mut self, rhs: Option<&mut [f64]>, nrhs: usize) -> Result<()> {
        self.id.nrhs = nrhs as i32;
        self.id.lrhs = self.id.n;
        self.id.rhs = match rhs {
            Some(b) => {
                debug_assert_eq!(b.len(), self.id.n as usize * nrhs);
                b.as_mut_ptr()
            }
            None => std::ptr::null_mut(),
        };
        self.call(3);
        // the caller's buffer is only borrowed for this call
        self.id.rhs = std::ptr::null_mut();
        self.outcome("solution")
    }

    fn call(&mut self, job: i32) {
        self.id.job = job;
        // SAFETY: `id` was zero-initialised and then set up by JOB = -1 on every rank of the
        // communicator; the pointers it holds are null or point into arrays that outlive the call
        // with the lengths given next to them (n, nnz_loc, lrhs * nrhs on the host).
        unsafe { ffi::dmumps_c(&mut *self.id) };
    }

    fn set_icntl(&mut self, k: usize, value: i32) {
        self.id.icntl[k - 1] = value;
    }

    fn infog(&self, k: usize) -> i32 {
        self.id.infog[k - 1]
    }

    fn stats(&self) -> MumpsStats {
        MumpsStats {
            factor_entries: count(self.infog(29)),
            factor_reals_estimated: count(self.infog(3)),
            factor_reals: count(self.infog(9)),
            memory_mb_max: count(self.infog(21)),
            memory_mb_total: count(self.infog(22)),
            flops: self.id.rinfog[2],
            ordering: ordering_name(self.infog(7), self.infog(32)),
        }
    }
}

impl Drop for Instance {
    /// JOB = -2: frees MUMPS's memory; collective.
    fn drop(&mut self) {
        if self.started {
            self.call(-2);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::par::Solo;

    fn small() -> SymCsr {
        // [[4, 1, 0], [1, 3, 0], [0, 0, 2]], lower triangle
        SymCsr {
            n: 3,
            rows: vec![0, 1, 2],
            row_ptr: vec![0, 1, 3, 4],
            cols: vec![0, 0, 1, 2],
            vals: vec![4.0, 1.0, 3.0, 2.0],
        }
    }

    #[test]
    fn triples_are_one_based_and_keep_the_values() {
        let (irn, jcn, vals) = check_local(&small()).unwrap();
        assert_eq!(irn, [1, 2, 2, 3]);
        assert_eq!(jcn, [1, 1, 2, 3]);
        assert_eq!(vals, [4.0, 1.0, 3.0, 2.0]);
    }

    #[test]
    fn malformed_input_is_refused_before_mumps() {
        let mut upper = small();
        upper.cols[1] = 2;
        assert!(matches!(check_local(&upper), Err(Error::Usage(m)) if m.contains("above the diagonal")));
        let mut out_of_range = small();
        out_of_range.rows[2] = 3;
        assert!(matches!(check_local(&out_of_range), Err(Error::Usage(m)) if m.contains("row 3")));
        let mut nan = small();
        nan.vals[2] = f64::NAN;
        assert!(matches!(check_local(&nan), Err(Error::Numerical(_))));
        let mut short = small();
        short.row_ptr.pop();
        assert!(matches!(check_local(&short), Err(Error::Usage(m)) if m.contains("malformed")));
        assert!(matches!(check_local(&SymCsr::default()), Err(Error::Usage(m)) if m.contains("order 0")));
    }

    #[test]
    fn a_communicator_without_mpi_is_refused() {
        let err = MumpsSpd::factor(&Solo, &small()).unwrap_err();
        assert!(matches!(&err, Error::Usage(m) if m.contains("MPI")), "{err:?}");
    }

    #[test]
    fn mumps_codes_become_typed_errors() {
        assert!(mumps_error("factorisation", -10, 0).is_not_definite());
        assert!(mumps_error("factorisation", -40, 0).is_not_definite());
        for code in [-5, -7, -8, -9, -11, -12, -13, -14, -15, -17, -19, -20] {
            assert!(matches!(mumps_error("factorisation", code, -3), Error::Memory(_)), "{code}");
        }
        let e = mumps_error("analysis", -13, -3);
        assert!(e.to_string().contains("error -13") && e.to_string().contains("3 million"), "{e}");
        assert!(matches!(mumps_error("analysis", -16, 0), Error::Usage(_)));
        assert!(matches!(mumps_error("analysis", -6, 7), Error::Numerical(m) if m.contains("rank 7")));
        assert!(matches!(mumps_error("solution", -999, 0), Error::Numerical(m) if m.contains("-999")));
    }

    #[test]
    fn counts_in_millions_and_ordering_names() {
        assert_eq!(count(12), 12);
        assert_eq!(count(-3), 3_000_000);
        assert_eq!(ordering_name(4, 1), "PORD (sequential analysis)");
        assert_eq!(ordering_name(1, 2), "PT-SCOTCH (parallel analysis)");
    }
}
