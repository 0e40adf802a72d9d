//! The choice of distributed solver: the `auto` policy by system size, default panel widths, and
//! the fallback from the projected Cholesky to LU when the projected block turns out not definite
//! to working precision. One entry point, [`solve`], for every command.

use faer::Par;

use super::{cholesky_solve, householder_solve, lu_solve, LocalRows};
use crate::error::{Error, Result};
use crate::par::{agree, Comm};

/// The distributed dense solvers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SolverKind {
    /// Householder QR in compact-WY blocks (the classical method for these systems).
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

    /// Runs this one solver (resolved for the size) on `rows` without any fallback; `panel` 0 is
    /// the solver's default, `par` the parallelism of each rank's local BLAS-3 kernels
    /// (`Par::Seq`, or `Par::rayon(t)` for t threads per rank). Collective. The local outcome is
    /// not agreed on: see [`solve`].
    pub fn run(
        &self,
        comm: &dyn Comm,
        rows: &mut LocalRows,
        panel: usize,
        par: Par,
        progress: &dyn Fn(usize, usize),
    ) -> Result<Vec<f64>> {
        let kind = self.resolve(rows.layout.n);
        let panel = if panel > 0 { panel } else { kind.default_panel() };
        match kind {
            SolverKind::Householder => householder_solve(comm, rows, panel, par, progress),
            SolverKind::Lu => lu_solve(comm, rows, panel, par, progress),
            SolverKind::Cholesky | SolverKind::Auto => cholesky_solve(comm, rows, panel, par, progress),
        }
    }
}

/// A solution and how it was obtained.
#[derive(Debug, Clone)]
pub struct Solved {
    /// The whole solution, on every rank.
    pub x: Vec<f64>,
    /// The solver that produced it (Cholesky may have fallen back to LU).
    pub used: SolverKind,
    /// The panel width it used.
    pub panel: usize,
    /// Why Cholesky fell back to LU, if it did.
    pub fallback: Option<Error>,
}

/// Solves the distributed system `rows` (right-hand side in the last column) with `kind`, and
/// returns the solution on every rank. Collective; every rank returns the same outcome. `panel`
/// and `par` as in [`SolverKind::run`].
///
/// When the projected Cholesky meets a pivot that is not positive on any rank, every rank learns
/// it (the agreed error keeps its kind), the system is assembled again by `reassemble` (the
/// factorisation overwrote it) and solved by LU.
pub fn solve(
    comm: &dyn Comm,
    kind: SolverKind,
    mut rows: LocalRows,
    panel: usize,
    par: Par,
    progress: &dyn Fn(usize, usize),
    reassemble: impl FnOnce() -> LocalRows,
) -> Result<Solved> {
    let used = kind.resolve(rows.layout.n);
    let panel_of = |k: SolverKind| if panel > 0 { panel } else { k.default_panel() };
    match agree(comm, used.run(comm, &mut rows, panel, par, progress)) {
        Ok(x) => Ok(Solved { x, used, panel: panel_of(used), fallback: None }),
        Err(e) if e.is_not_definite() => {
            drop(rows);
            let mut rows = reassemble();
            let x = agree(comm, SolverKind::Lu.run(comm, &mut rows, panel, par, progress))?;
            Ok(Solved { x, used: SolverKind::Lu, panel: panel_of(SolverKind::Lu), fallback: Some(e) })
        }
        Err(e) => Err(e),
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
