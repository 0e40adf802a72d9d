//! The distributed layer: the communicator interface, the row-cyclic layout of the bordered system
//! (the transputer network's distribution) and the collective solvers built on them.
//!
//! Everything that crosses ranks goes through [`Comm`]; `MpiComm` implements it over MPI and
//! `Solo` over a single process, so the solvers are the same code in tests, on one process and
//! under `mpirun`. Nothing outside this module and the collective I/O calls MPI.

mod backsub;
mod cholesky;
mod comm;
mod householder;
mod layout;
mod lu;
mod system;

pub use cholesky::cholesky_solve;
pub use comm::{agree, Comm, MpiComm, Solo};
pub use householder::householder_solve;
pub use layout::{RowCyclic, Slabs};
pub use lu::lu_solve;
pub use system::LocalRows;

use crate::error::{Error, Result};
use crate::report::Progress;

/// The distributed dense solvers, chosen by name at run time.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SolverKind {
    /// Householder QR in compact-WY blocks (the paper's method).
    Householder,
    /// LU with partial pivoting, right-looking blocked.
    Lu,
    /// Projected Cholesky of the definite block (about a quarter of Householder's flops).
    Cholesky,
    /// The fastest for the size: Householder for small systems, where every solver takes
    /// milliseconds and the fewest collectives win, Cholesky from `AUTO_CHOLESKY_FROM` rows.
    Auto,
}

/// System size from which `auto` picks the projected Cholesky (jobs/table2: at 946 rows both take
/// the same time on 2 ranks, at 2004 Cholesky takes 40 % less).
pub const AUTO_CHOLESKY_FROM: usize = 1000;

impl SolverKind {
    pub fn parse(name: &str) -> Result<Self> {
        match name {
            "householder" | "qr" => Ok(SolverKind::Householder),
            "lu" => Ok(SolverKind::Lu),
            "cholesky" => Ok(SolverKind::Cholesky),
            "auto" => Ok(SolverKind::Auto),
            other => Err(Error::Usage(format!(
                "unknown solver '{other}' (expected auto, cholesky, householder or lu)"
            ))),
        }
    }

    pub fn name(&self) -> &'static str {
        match self {
            SolverKind::Householder => "householder",
            SolverKind::Lu => "lu",
            SolverKind::Cholesky => "cholesky",
            SolverKind::Auto => "auto",
        }
    }

    /// The solver `auto` stands for on a system of `n` rows (the others stand for themselves).
    pub fn resolve(&self, n: usize) -> SolverKind {
        match self {
            SolverKind::Auto if n >= AUTO_CHOLESKY_FROM => SolverKind::Cholesky,
            SolverKind::Auto => SolverKind::Householder,
            other => *other,
        }
    }

    /// Solves the distributed system held in `rows` (its right-hand side is the last column) and
    /// returns the whole solution on every rank. Collective. `Cholesky` may return
    /// `Error::NotDefinite`, after which `rows` must be assembled again for another solver.
    /// `panel` 0 means the solver's default width.
    pub fn solve(
        &self,
        comm: &dyn Comm,
        rows: &mut LocalRows,
        panel: usize,
        progress: &Progress,
    ) -> Result<Vec<f64>> {
        let kind = self.resolve(rows.layout.n);
        let panel = if panel > 0 { panel } else { kind.default_panel() };
        match kind {
            SolverKind::Householder => householder_solve(comm, rows, panel, progress),
            SolverKind::Lu => lu_solve(comm, rows, panel, progress),
            SolverKind::Cholesky | SolverKind::Auto => cholesky_solve(comm, rows, panel, progress),
        }
    }
}

impl SolverKind {
    /// Panel width used when the user gives none, measured on a 2-core AVX-512 machine at
    /// N = 4000 and 8000, 2 ranks: Cholesky gains from wide panels (its trailing GEMMs get a
    /// longer inner dimension), LU is best at 128 (equal at 8000, 7 % faster at 4000, where the
    /// panel's collectives weigh more), Householder's per-column all-reduces favour 64.
    pub fn default_panel(&self) -> usize {
        match self {
            SolverKind::Householder => 64,
            SolverKind::Lu => 128,
            SolverKind::Cholesky | SolverKind::Auto => 256,
        }
    }
}

/// Collects an error from any rank and returns it on every rank; the error message travels from the
/// lowest failing rank. Collective; used by [`agree`].
fn first_error(comm: &dyn Comm, local: Option<&Error>) -> Option<Error> {
    let mut who = [if local.is_some() { comm.rank() as f64 } else { f64::INFINITY }];
    comm.min_f64(&mut who);
    if who[0].is_infinite() {
        return None;
    }
    let root = who[0] as usize;
    let mut msg = match local {
        Some(e) if root == comm.rank() => e.to_string().into_bytes(),
        _ => Vec::new(),
    };
    comm.broadcast_bytes(root, &mut msg);
    if root == comm.rank() {
        local.cloned()
    } else {
        Some(Error::Rank { rank: root, message: String::from_utf8_lossy(&msg).into_owned() })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn auto_picks_by_size_and_names_round_trip() {
        assert_eq!(SolverKind::parse("auto").unwrap().resolve(400), SolverKind::Householder);
        assert_eq!(SolverKind::parse("auto").unwrap().resolve(AUTO_CHOLESKY_FROM), SolverKind::Cholesky);
        for name in ["householder", "lu", "cholesky", "auto"] {
            let k = SolverKind::parse(name).unwrap();
            assert_eq!(k.name(), name);
            assert_eq!(k.resolve(5000).resolve(5), k.resolve(5000));
        }
        assert!(SolverKind::parse("gauss").is_err());
    }
}
