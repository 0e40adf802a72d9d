//! The choice of distributed solver: the `auto` policy by system size, default panel widths, and
//! the fallback from the projected Cholesky to LU when the projected block turns out not definite
//! to working precision; the mixed-precision solve and its fallback to f64. One entry point,
//! [`solve_in`] ([`solve`] in f64), for every command.

use faer::Par;

use super::cholesky::factor_and_solve;
use super::cholesky2d;
use super::extend::Factored;
use super::{
    cholesky2d_solve, cholesky_solve, householder2d_solve, householder_solve, lu2d_solve, lu_solve,
    mixed_solve, LocalBlocks, LocalRows, ProcessGrid, Refinement,
};
use crate::error::{Error, Result};
use crate::linalg::gemm;
use crate::par::{agree, Comm};

/// The context of a distributed solve: the ranks, the panel width (0: the solver's default), the
/// parallelism of each rank's local kernels (GEMMs, triangular solves), where progress goes, and
/// whether the factorisations look ahead: overlap each panel's trailing update with the next
/// panel's collectives (on the row-cyclic layout the LU's pivot searches, the Householder
/// panel's all-reduces, the projected Cholesky's gathers of L11 and L21).
#[derive(Clone, Copy)]
pub struct Job<'a> {
    pub comm: &'a dyn Comm,
    pub panel: usize,
    pub par: Par,
    pub progress: &'a dyn Fn(usize, usize),
    pub lookahead: bool,
}

fn silent(_: usize, _: usize) {}

/// Whether a [`Job`] looks ahead unless told: no. `fit` turns it on for the row-cyclic projected
/// Cholesky: on a quiet 2-core node, 2 ranks, runs interleaved, it took 0.395-0.408 s against
/// 0.425-0.539 s at N + k = 4000 and 2.32-2.51 s against 2.49-2.57 s at 8000. The LU measured no
/// faster (N = 4000 on 2 ranks 0.61 s either way, N = 8000 4.70 s with against 4.37 s without)
/// and the Householder QR slower (4000: 1.36-1.46 s against 1.32-1.36 s; 8000: 9.35-9.53 s
/// against 8.89-9.39 s).
pub const LOOKAHEAD: bool = false;

impl<'a> Job<'a> {
    /// A solve on `comm` with the default panel, sequential local kernels, no progress and the
    /// default look-ahead ([`LOOKAHEAD`]).
    pub fn on(comm: &'a dyn Comm) -> Self {
        Job { comm, panel: 0, par: Par::Seq, progress: &silent, lookahead: LOOKAHEAD }
    }

    pub fn lookahead(self, lookahead: bool) -> Self {
        Job { lookahead, ..self }
    }

    pub fn panel(self, panel: usize) -> Self {
        Job { panel, ..self }
    }

    pub fn par(self, par: Par) -> Self {
        Job { par, ..self }
    }

    pub fn progress(self, progress: &'a dyn Fn(usize, usize)) -> Self {
        Job { progress, ..self }
    }

    /// The panel width of `kind` on `n` rows: the job's, or the solver's default for the engine
    /// of this job's products ([`SolverKind::default_panel`]) where the ranks agreed on it
    /// ([`gemm::choose_agreed`], as `fit` does), faer's otherwise, so that every rank takes the
    /// same width.
    pub fn panel_for(&self, kind: SolverKind, n: usize) -> usize {
        if self.panel > 0 {
            self.panel
        } else {
            kind.default_panel(n, gemm::by_blas_on_every_rank(self.par))
        }
    }
}

/// The distributed dense solvers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SolverKind {
    /// Householder QR in compact-WY blocks (the classical method for these systems).
    Householder,
    /// LU with partial pivoting, right-looking blocked.
    Lu,
    /// Projected Cholesky of the definite block (about a quarter of Householder's flops).
    Cholesky,
    /// The fastest for the size: Householder for tiny systems, which need no definiteness and
    /// take about a millisecond whatever the solver, Cholesky from `AUTO_CHOLESKY_FROM` rows.
    Auto,
}

/// System size from which `auto` picks the projected Cholesky. Measured on 2 ranks (best of 5,
/// a 2-core AVX-512 machine), Householder against Cholesky: 100 rows 2 against 1 ms, 200 rows 3
/// against 2, 500 rows 6 against 4, 700 rows 11 against 7, 1000 rows 20 against 10 (on one rank
/// 500 rows 9 against 6 ms, 1000 rows 32 against 13). The projected Cholesky also keeps its
/// factor, so the refits of the off-surface method (blob pins, turned patches) border it
/// instead of factoring afresh: at 400 cow samples (about 700 rows, six fits) the solve stage
/// takes 18 ms instead of 50.
pub const AUTO_CHOLESKY_FROM: usize = 100;

/// System size from which the projected Cholesky's default panel is 384 rather than 256.
pub const CHOLESKY_WIDE_FROM: usize = 6000;

/// System size from which LU's default panel is 320 rather than 192 (with faer's products).
pub const LU_WIDE_FROM: usize = 6000;

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

    /// Panel width used when the user gives none for a system of `n` rows, measured on a 2-core
    /// AVX-512 machine, 2 ranks: Cholesky gains from wide panels (its trailing GEMMs get a longer
    /// inner dimension) as n grows: 256 is best at 2000 and 4000 rows (384 is 3-10 % slower
    /// there), 384 at 8000 (2.20-2.23 s against 2.30-2.34 s with 256); LU at 192 below 6000
    /// rows (at 2000 0.054 s against 0.056 s with 320 on 2 ranks, 0.083 against 0.087 s on one;
    /// at 4000 all of 128-320 within 1 % on 2 ranks) and 320 from there (at 8000, interleaved,
    /// best of 3: 2.05-2.08 s against 2.15-2.16 s with 192 and 2.11 s with 256 on 2 ranks,
    /// 2.06 s with 384, 2.17 s with 512; 3.75-3.81 against 3.96 s on one: since the block row
    /// is gathered as the ranks hold it, the wider trailing GEMMs win over the longer panels);
    /// Householder, whose panel is factored
    /// recursively, at 128 (at 8000 4.24-4.42 s against 4.69-4.72 s with 64, 4.28 s with 192 and
    /// 4.56 s with 256; 7 % faster than 64 at 4000, equal at 2000).
    ///
    /// Those figures are for faer's products. Where the BLAS computes them on every rank (`blas`,
    /// see [`gemm::by_blas_on_every_rank`]) LU keeps 192 at every size: its GEMM
    /// reaches its rate at a shorter inner dimension, so the shorter panels win (2-core AVX2
    /// machine, OpenBLAS, 8000 rows on 2 ranks, interleaved: best of 3 5.67 s against 6.35 s with
    /// 320, all three runs faster; in five more pairs 192 faster in four, median 6.06 against
    /// 6.20 s; on one rank equal). Householder takes 192 with the BLAS: on a 2-core AVX-512
    /// machine (OpenBLAS's Cooperlake kernels, 8000 rows, three runs each) 8.69-8.85 s against
    /// 9.01-9.57 s with 128 on 2 ranks and 16.1-16.4 s against 16.5-16.8 s on one; on the AVX2
    /// machine the two measured the same. Cholesky measured the same with 192 and its own widths,
    /// which it keeps.
    pub fn default_panel(&self, n: usize, blas: bool) -> usize {
        match self {
            SolverKind::Householder if blas => 192,
            SolverKind::Householder => 128,
            SolverKind::Lu if n >= LU_WIDE_FROM && !blas => 320,
            SolverKind::Lu => 192,
            SolverKind::Cholesky | SolverKind::Auto if n >= CHOLESKY_WIDE_FROM => 384,
            SolverKind::Cholesky | SolverKind::Auto => 256,
        }
    }

    /// The widest panel or block this solver takes by default on `n` rows, on either layout and
    /// with either engine of the products: what a memory estimate made before the engine is
    /// chosen assumes.
    pub fn widest_default_panel(&self, n: usize) -> usize {
        let kind = self.resolve(n);
        kind.default_panel(n, true).max(kind.default_panel(n, false)).max(kind.default_block_2d(n))
    }

    /// Block size of the 2D block-cyclic layout when the user gives none, for the solver this
    /// resolves to on `n` rows; measured at N+k = 8000 on 2 ranks (1x2 and 2x1 grids): LU and the
    /// projected Cholesky gain from 128 over ScaLAPACK's usual 64 (LU 3.99-4.08 s against
    /// 4.36-4.45 s, Cholesky 2.49-2.57 s against 2.55-2.66 s; 256 helps LU a little more and
    /// Cholesky not at all), and so does Householder with its recursive panel (1x2 4.22 s against
    /// 4.89 s, 2x1 4.48 against 5.07). Blocks much wider would unbalance large grids.
    pub fn default_block_2d(&self, _n: usize) -> usize {
        128
    }

    /// Runs this one solver (resolved for the size) on `rows` without any fallback; a panel of 0
    /// is the solver's default. Collective. The local outcome is not agreed on: see [`solve`].
    pub fn run(&self, job: &Job<'_>, rows: &mut LocalRows) -> Result<Vec<f64>> {
        let kind = self.resolve(rows.layout.n);
        let n = rows.layout.n;
        let job = Job { panel: job.panel_for(kind, n), ..*job };
        match kind {
            SolverKind::Householder => householder_solve(&job, rows),
            SolverKind::Lu => lu_solve(&job, rows),
            SolverKind::Cholesky | SolverKind::Auto => cholesky_solve(&job, rows),
        }
    }
}

/// The working precision of a dense solve.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Precision {
    /// Factor and solve in f64 with the chosen solver.
    F64,
    /// Factor in f32 (the projected Cholesky where the f64 choice is Cholesky, LU otherwise),
    /// refine in f64 (classical, then GMRES-IR) to the accuracy of an f64 solve; when that fails,
    /// solve again in f64 with the chosen solver.
    Mixed,
}

impl Precision {
    pub fn parse(name: &str) -> Result<Self> {
        match name {
            "f64" | "double" => Ok(Precision::F64),
            "mixed" => Ok(Precision::Mixed),
            other => Err(Error::Usage(format!("unknown precision '{other}' (expected f64 or mixed)"))),
        }
    }

    pub fn name(&self) -> &'static str {
        match self {
            Precision::F64 => "f64",
            Precision::Mixed => "mixed",
        }
    }
}

/// A solution and how it was obtained.
#[derive(Debug, Clone)]
pub struct Solved {
    /// The whole solution, on every rank.
    pub x: Vec<f64>,
    /// The solver that produced it (Cholesky may have fallen back to LU); in mixed precision
    /// without fallback, the f32 factorisation (Cholesky or LU).
    pub used: SolverKind,
    /// The panel width it used.
    pub panel: usize,
    /// Why Cholesky fell back to LU, if it did.
    pub fallback: Option<Error>,
    /// The refinement of a mixed-precision solve (None in f64 or when the f32 factorisation
    /// failed).
    pub refinement: Option<Refinement>,
    /// Why a mixed-precision solve fell back to f64, if it did.
    pub mixed_fallback: Option<String>,
}

/// Solves the distributed system `rows` in `precision`: [`solve`] with `kind` in f64; in mixed
/// precision by an f32 factorisation and refinement in f64 (`rows` is kept for the residuals):
/// the projected Cholesky where `kind` resolves to it for the size, LU otherwise. When the f32
/// factorisation fails (a projected block not definite in f32, a singular LU) or the refinement
/// does not reach the accuracy of an f64 solve, by [`solve`] with `kind` on the same rows, with
/// the reason in `mixed_fallback`. Collective; every rank returns the same outcome.
pub fn solve_in(
    job: &Job<'_>,
    kind: SolverKind,
    precision: Precision,
    rows: LocalRows,
    reassemble: impl FnOnce() -> Result<LocalRows>,
) -> Result<Solved> {
    if precision == Precision::F64 {
        return solve(job, kind, rows, reassemble);
    }
    let factor = match kind.resolve(rows.layout.n) {
        SolverKind::Cholesky if rows.border > 0 => SolverKind::Cholesky,
        _ => SolverKind::Lu,
    };
    let panel = job.panel_for(factor, rows.layout.n);
    let (refinement, why) = match agree(job.comm, mixed_solve(&Job { panel, ..*job }, &rows, factor)) {
        Ok((x, r)) if r.converged => {
            let used = factor;
            return Ok(Solved { x, used, panel, fallback: None, refinement: Some(r), mixed_fallback: None });
        }
        Ok((_, r)) => {
            let why = format!("the refinement did not converge ({})", r.describe());
            (Some(r), why)
        }
        Err(e) if e.is_not_definite() => {
            (None, format!("the single-precision projected Cholesky failed: {}", e.root()))
        }
        Err(e) => (None, format!("the single-precision factorisation failed: {}", e.root())),
    };
    let solved = solve(job, kind, rows, reassemble)?;
    Ok(Solved { refinement, mixed_fallback: Some(why), ..solved })
}

/// Solves the distributed system `rows` (right-hand side in the last column) with `kind`, and
/// returns the solution on every rank. Collective; every rank returns the same outcome. `panel`
/// and `par` as in [`SolverKind::run`].
///
/// When the projected Cholesky meets a pivot that is not positive on any rank, every rank learns
/// it (the agreed error keeps its kind), the system is assembled again by `reassemble` (the
/// factorisation overwrote it, and may have been given the lower triangle alone) and solved by
/// LU. `reassemble` is collective and agrees on its outcome; its error (the whole matrix does not
/// fit) is returned.
pub fn solve(
    job: &Job<'_>,
    kind: SolverKind,
    rows: LocalRows,
    reassemble: impl FnOnce() -> Result<LocalRows>,
) -> Result<Solved> {
    solve_keeping(job, kind, rows, reassemble, false).map(|(solved, _)| solved)
}

/// [`solve`], which with `keep` also returns the factor when the projected Cholesky solved the
/// system (see `extend`): a second fit with centres appended can then border it.
pub fn solve_keeping(
    job: &Job<'_>,
    kind: SolverKind,
    mut rows: LocalRows,
    reassemble: impl FnOnce() -> Result<LocalRows>,
    keep: bool,
) -> Result<(Solved, Option<Factored>)> {
    let comm = job.comm;
    let used = kind.resolve(rows.layout.n);
    let n = rows.layout.n;
    let panel_of = |k: SolverKind| job.panel_for(k, n);
    let keeps = keep && used == SolverKind::Cholesky && rows.border > 0;
    let outcome = if keeps {
        let panel = panel_of(used);
        factor_and_solve(&Job { panel, ..*job }, &mut rows).map(|(x, border, sign)| (x, Some((border, sign))))
    } else {
        used.run(job, &mut rows).map(|x| (x, None))
    };
    match agree(comm, outcome) {
        Ok((x, kept)) => Ok((
            Solved { x, used, panel: panel_of(used), fallback: None, refinement: None, mixed_fallback: None },
            kept.map(|(border, sign)| Factored::new(rows, border, sign, panel_of(used))),
        )),
        Err(e) if e.is_not_definite() => {
            drop(rows);
            let mut rows = reassemble()?;
            let x = agree(comm, SolverKind::Lu.run(job, &mut rows))?;
            let panel = panel_of(SolverKind::Lu);
            let solved = Solved {
                x,
                used: SolverKind::Lu,
                panel,
                fallback: Some(e),
                refinement: None,
                mixed_fallback: None,
            };
            Ok((solved, None))
        }
        Err(e) => Err(e),
    }
}

/// Solves the bordered system `a` (k polynomial rows) on the 2D block-cyclic layout of `grid`,
/// in f64, with `kind` resolved for the size as on the row-cyclic layout; the projected Cholesky
/// falls back to LU on the assembly of `reassemble` when a pivot is not positive (the projected
/// Cholesky reads the lower triangle of A and its first k rows alone, LU the whole matrix; an
/// error of `reassemble`, such as a refusal for memory, is returned). The panel width is the
/// block size of the assembly. Collective; every rank returns the same outcome.
pub fn solve_2d(
    job: &Job<'_>,
    grid: &ProcessGrid<'_>,
    kind: SolverKind,
    k: usize,
    a: LocalBlocks,
    reassemble: impl FnOnce() -> Result<LocalBlocks>,
) -> Result<Solved> {
    solve_2d_keeping(job, grid, kind, k, a, reassemble, false).map(|(solved, _)| solved)
}

/// [`solve_2d`], which with `keep` also returns the factor when the projected Cholesky solved the
/// system, moved to the row-cyclic layout ([`LocalBlocks::to_row_cyclic`]: the lower triangle
/// and the first k rows of the centres' block, about half of the matrix, travel once by
/// all-to-all exchanges): a second fit with centres appended borders it there (see `extend`) as
/// it borders a factor of the row-cyclic solver. The factor is the 2D one, so its panel width
/// for the bordering is the row-cyclic default for the size unless `job.panel` names one.
pub fn solve_2d_keeping(
    job: &Job<'_>,
    grid: &ProcessGrid<'_>,
    kind: SolverKind,
    k: usize,
    mut a: LocalBlocks,
    reassemble: impl FnOnce() -> Result<LocalBlocks>,
    keep: bool,
) -> Result<(Solved, Option<Factored>)> {
    let comm = job.comm;
    let (n, panel) = (a.n(), a.rows.nb);
    let used = match kind.resolve(n) {
        SolverKind::Cholesky if k == 0 => SolverKind::Lu,
        other => other,
    };
    let done =
        |x, used, fallback| Solved { x, used, panel, fallback, refinement: None, mixed_fallback: None };
    let outcome = match used {
        SolverKind::Householder => householder2d_solve(job, grid, &mut a).map(|x| (x, None)),
        SolverKind::Lu | SolverKind::Auto => lu2d_solve(job, grid, &mut a).map(|x| (x, None)),
        SolverKind::Cholesky if keep => cholesky2d::factor_and_solve(job, grid, &mut a, k)
            .map(|(x, border, sign)| (x, Some((border, sign)))),
        SolverKind::Cholesky => cholesky2d_solve(job, grid, &mut a, k).map(|x| (x, None)),
    };
    match agree(comm, outcome) {
        Ok((x, kept)) => {
            let factor = kept.map(|(border, sign)| {
                let t0 = std::time::Instant::now();
                let rows = a.to_row_cyclic(grid, k, (n - k, k));
                let panel = job.panel_for(SolverKind::Cholesky, n);
                Factored::new(rows, border, sign, panel).moved_in(t0.elapsed().as_secs_f64())
            });
            Ok((done(x, used, None), factor))
        }
        Err(e) if e.is_not_definite() => {
            drop(a);
            let mut a = reassemble()?;
            let x = agree(comm, lu2d_solve(job, grid, &mut a))?;
            Ok((done(x, SolverKind::Lu, Some(e)), None))
        }
        Err(e) => Err(e),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_scaling_models_memory_panels_are_the_solvers_defaults() {
        // jobs/bench/scaling_model.py repeats the widest default panels of the row-cyclic
        // solvers at scale and the 2D block for its memory per rank: they must follow these
        let script = include_str!("../../../jobs/bench/scaling_model.py");
        let n = 100_000;
        let widest = |kind: SolverKind| kind.default_panel(n, true).max(kind.default_panel(n, false));
        let line = script.lines().find(|l| l.starts_with("MEM_NB =")).expect("the MEM_NB line");
        for (name, kind) in [
            ("householder", SolverKind::Householder),
            ("lu", SolverKind::Lu),
            ("cholesky", SolverKind::Cholesky),
        ] {
            let at = line.find(&format!("\"{name}\": ")).unwrap_or_else(|| panic!("no {name} in {line}"));
            let rest = &line[at + name.len() + 4..];
            let panel: usize = rest.split([',', '}']).next().unwrap().trim().parse().unwrap();
            assert_eq!(panel, widest(kind), "{name}: {line}");
        }
        let line = script.lines().find(|l| l.starts_with("MEM_NB_2D =")).expect("the MEM_NB_2D line");
        let block: usize = line.split('#').next().unwrap().split('=').nth(1).unwrap().trim().parse().unwrap();
        assert_eq!(block, SolverKind::Cholesky.default_block_2d(n), "{line}");
    }

    #[test]
    fn auto_picks_by_size_and_names_round_trip() {
        assert_eq!(
            SolverKind::parse("auto").unwrap().resolve(AUTO_CHOLESKY_FROM - 1),
            SolverKind::Householder
        );
        assert_eq!(SolverKind::parse("auto").unwrap().resolve(AUTO_CHOLESKY_FROM), SolverKind::Cholesky);
        for name in ["householder", "lu", "cholesky", "auto"] {
            let k = SolverKind::parse(name).unwrap();
            assert_eq!(k.name(), name);
            assert_eq!(k.resolve(5000).resolve(5), k.resolve(5000));
        }
        assert!(SolverKind::parse("gauss").is_err());
    }

    #[test]
    fn default_panels_follow_the_size_and_the_engine_of_the_products() {
        assert_eq!(SolverKind::Householder.default_panel(8000, false), 128);
        assert_eq!(SolverKind::Householder.default_panel(8000, true), 192);
        for blas in [false, true] {
            assert_eq!(SolverKind::Lu.default_panel(LU_WIDE_FROM - 1, blas), 192);
            assert_eq!(SolverKind::Cholesky.default_panel(CHOLESKY_WIDE_FROM - 1, blas), 256);
            assert_eq!(SolverKind::Cholesky.default_panel(CHOLESKY_WIDE_FROM, blas), 384);
        }
        // wide LU panels pay with faer's products only
        assert_eq!(SolverKind::Lu.default_panel(LU_WIDE_FROM, false), 320);
        assert_eq!(SolverKind::Lu.default_panel(LU_WIDE_FROM, true), 192);
        // the job's own panel wins over any default
        let job = Job::on(&crate::par::Solo).panel(48);
        assert_eq!(job.panel_for(SolverKind::Lu, 8000), 48);
    }
}
