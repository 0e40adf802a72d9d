//! The compactly supported method: Wendland functions of support R give a sparse, positive
//! definite A, so the bordered system [A P; P^T 0] is solved by one sparse Cholesky factorisation
//! of A and a block elimination of the polynomial border. The octree of the centres finds each
//! row's neighbours; each rank assembles a contiguous block of rows of the lower triangle; the
//! factorisation is faer's sparse Cholesky or the envelope Cholesky after the octree ordering on
//! one rank, and MUMPS (entered distributed, never gathered) across ranks.

use faer::{MatRef, Par};
use rayon::prelude::*;

use super::{Fitted, Run};
use crate::app::preflight::check_memory;
use crate::app::progress::Progress;
use crate::app::stages::{Stage, Stages};
use crate::cli::{FitArgs, KernelChoice, Method, SparseSolver};
use crate::error::{Error, Result};
use crate::linalg::mumps::MumpsSpd;
use crate::linalg::sparse::{bordered_solve, EnvelopeCholesky, SparseCholesky, SpdSolve, SymCsr};
use crate::par::{agree, Comm};
use crate::spline::compact::{assemble_lower, poly_block};
use crate::spline::hygiene::Prepared;
use crate::spline::octree::Octree;
use crate::spline::system::power_of_two_below_inverse;
use crate::spline::{Kernel, Spline};

/// Factor entries per stored entry of A assumed before the factorisation: the fill measured on
/// surface scans with about 30 neighbours per point stays below 10 (faer, AMD ordering).
const FILL_ALLOWANCE: f64 = 12.0;

/// The global rows of rank `r` of `p`: a contiguous block, the first n mod p ranks one more.
fn block_rows(n: usize, p: usize, r: usize) -> std::ops::Range<usize> {
    let (base, rem) = (n / p, n % p);
    let start = r * base + r.min(rem);
    start..start + base + usize::from(r < rem)
}

/// The solver a run uses: `auto` is faer's Cholesky on one rank and MUMPS on several.
fn resolve(asked: SparseSolver, ranks: usize) -> Result<SparseSolver> {
    match (asked, ranks) {
        (SparseSolver::Auto, 1) => Ok(SparseSolver::Cholesky),
        (SparseSolver::Auto, _) => Ok(SparseSolver::Mumps),
        (SparseSolver::Cholesky | SparseSolver::Envelope, p) if p > 1 => Err(Error::Usage(format!(
            "--sparse-solver {} runs on one rank; under mpirun -n {p} use mumps (or auto)",
            name(asked)
        ))),
        (s, _) => Ok(s),
    }
}

/// Refuses, before the input is read, a `--sparse-solver` of one rank under several where the
/// fit is compactly supported whatever the data (`--method csrbf`, or `auto` with a Wendland
/// kernel); otherwise [`check_before`] and [`fit`] refuse it once the method is chosen, before
/// any solve.
pub fn check_solver(a: &FitArgs, ranks: usize) -> Result<()> {
    if matches!((a.method, a.kernel), (Method::Csrbf, _) | (Method::Auto, KernelChoice::Wendland(_))) {
        resolve(a.sparse_solver, ranks)?;
    }
    Ok(())
}

fn name(s: SparseSolver) -> &'static str {
    match s {
        SparseSolver::Auto => "auto",
        SparseSolver::Cholesky => "cholesky",
        SparseSolver::Envelope => "envelope",
        SparseSolver::Mumps => "mumps",
    }
}

/// The bytes a rank needs for the sparse factor of a matrix with `nnz` stored entries of its rows
/// (the lower triangle, with [`FILL_ALLOWANCE`] for the fill).
fn factor_bytes(nnz: f64) -> f64 {
    nnz * (12.0 + 8.0 * FILL_ALLOWANCE) + 100e6
}

/// The points of `rows` with no other centre closer than `support` (where the spline is a spike,
/// useless between points), counted over all ranks, and the largest distance from such a point
/// to its nearest other one (0 where there is none). Collective.
fn lonely(
    comm: &dyn Comm,
    tree: &Octree,
    centres: &[f64],
    rows: std::ops::Range<usize>,
    support: f64,
) -> (usize, f64) {
    let (count, farthest) = rows
        .into_par_iter()
        .map(|i| tree.kth_distance([centres[3 * i], centres[3 * i + 1], centres[3 * i + 2]], 2))
        .filter(|&d| d >= support)
        .fold(|| (0u64, 0.0f64), |(c, m), d| (c + 1, m.max(d)))
        .reduce(|| (0, 0.0), |x, y| (x.0 + y.0, x.1.max(y.1)));
    let (mut count, mut farthest) = ([count], [farthest]);
    comm.sum_u64(&mut count);
    comm.max_f64(&mut farthest);
    (count[0] as usize, farthest[0])
}

/// `x` rounded up to three significant digits, strictly above it, as text: a support that
/// reaches a point `x` away.
fn just_above(x: f64) -> String {
    if !(x > 0.0 && x.is_finite()) {
        return format!("{x}");
    }
    let digits = x.log10().floor() as i32 - 2;
    let step = 10f64.powi(digits);
    format!("{:.*}", (-digits).max(0) as usize, ((x / step).floor() + 1.0) * step)
}

/// The refusal of a support that leaves `count` of the `n` points alone (no other point closer,
/// the farthest of them `farthest` from its nearest one), with the support that reaches them.
/// A support the user gave is a usage error; the default one is the scan's spacing varying
/// more than the default follows, which the message says, with the same fix.
fn lonely_refusal(a: &FitArgs, support: f64, n: usize, (count, farthest): (usize, f64)) -> Error {
    let alone = format!(
        "{count} of the {n} points {} no other point within it (the farthest {farthest:.3e} from its \
         nearest one), where the spline would be a spike useless between points",
        if count == 1 { "has" } else { "have" }
    );
    let fix = format!("use --support {} or larger", just_above(farthest));
    if a.support.is_some() {
        Error::Usage(format!(
            "support {support} is too small: {alone}; {fix} (the default aims at about {} neighbours)",
            crate::spline::compact::DEFAULT_NEIGHBOURS
        ))
    } else {
        Error::input(
            &a.input,
            "",
            format!(
                "the default support {support} is too small for this scan: {alone}. The default, the median \
                 distance to the {}th nearest neighbour, grows at most {} times to give every point a \
                 neighbour, and the spacing of these points varies more than that; {fix} (in the internal \
                 coordinates, where the data's box has diagonal 2: the densest parts get more neighbours, \
                 so a larger factor) or thin the densest parts of the scan",
                crate::spline::compact::DEFAULT_NEIGHBOURS,
                crate::spline::compact::MAX_SUPPORT_GROWTH
            ),
        )
    }
}

/// Rows sampled per rank by [`check_before`].
pub const SAMPLED_ROWS: usize = 4096;

/// Refuses, before any other work, a compactly supported fit of `prep`'s points with a sparse
/// solver of one rank under several, or with a support that leaves some point with no other
/// within it (as [`fit`] would after its assembly, and after level 0 of the two levels had been
/// solved), or whose sparse factor would not fit the ranks' memory, by the check [`fit`] makes
/// after its assembly, with the
/// stored entries of each rank's rows estimated from at most [`SAMPLED_ROWS`] of them evenly
/// spread (the entries of a row are its neighbours within the support that come before it in the
/// order, so they depend on the rank's place in the order). `what` names the fit in the message.
/// Returns the octree of the centres, for [`fit`] to take. Collective.
pub fn check_before(run: &Run<'_>, kernel: &Kernel, prep: &Prepared, what: &str) -> Result<Octree> {
    let Run { args: a, comm, .. } = *run;
    resolve(a.sparse_solver, comm.size())?;
    let support = kernel.is_compact().expect("a compactly supported kernel");
    let centres = &prep.centres;
    let n = centres.len() / 3;
    let tree = Octree::new(centres, a.leaf);
    let rows = block_rows(n, comm.size(), comm.rank());
    let stride = rows.len().div_ceil(SAMPLED_ROWS).max(1);
    let sampled: Vec<usize> = rows.clone().step_by(stride).collect();
    let (lower, all): (usize, usize) = sampled
        .par_iter()
        .map(|&i| {
            let mut near = Vec::new();
            tree.within([centres[3 * i], centres[3 * i + 1], centres[3 * i + 2]], support, &mut near);
            (near.iter().filter(|&&j| j <= i).count(), near.len())
        })
        .reduce(|| (0, 0), |x, y| (x.0 + y.0, x.1 + y.1));
    let per_row = lower as f64 / sampled.len().max(1) as f64;
    let mut mean = [all as f64, sampled.len() as f64];
    comm.sum_f64(&mut mean);
    check_memory(
        comm,
        factor_bytes(per_row * rows.len() as f64),
        &format!(
            "{what}: the sparse factor of {n} points with about {:.0} neighbours each (support {support})",
            mean[0] / mean[1].max(1.0)
        ),
        "use a smaller --support, more ranks (with mumps) or fewer points",
    )?;
    let alone = lonely(comm, &tree, centres, rows, support);
    if alone.0 > 0 {
        return Err(lonely_refusal(a, support, n, alone));
    }
    Ok(tree)
}

/// Fits the compactly supported spline of `kernel` to the prepared points; `tree`: the octree of
/// their centres where the caller built it ([`check_before`]). Collective.
pub fn fit(
    run: &Run<'_>,
    kernel: Kernel,
    prep: &Prepared,
    tree: Option<Octree>,
    stages: &mut Stages,
) -> Result<Fitted> {
    let Run { args: a, comm, threads, .. } = *run;
    let support = kernel.is_compact().expect("a compactly supported kernel");
    let solver = resolve(a.sparse_solver, comm.size())?;
    let (centres, values) = (&prep.centres, &prep.values);
    let n = values.len();
    let tree = match tree {
        Some(t) => t,
        None => stages.time(Stage::Tree, || Octree::new(centres, a.leaf)),
    };
    let tree_stats = tree.stats();
    let rows: Vec<usize> = block_rows(n, comm.size(), comm.rank()).collect();
    let (lower, row_stats) =
        stages.time(Stage::Assemble, || assemble_lower(&kernel, centres, &tree, &rows))?;
    let mut whole = [row_stats.mean * row_stats.rows as f64, lower.nnz() as f64];
    comm.sum_f64(&mut whole);
    let mut most = [row_stats.max as f64];
    comm.max_f64(&mut most);
    let (nnz_row_mean, lower_nnz) = (whole[0] / n as f64, whole[1]);
    check_memory(
        comm,
        factor_bytes(lower.nnz() as f64),
        &format!(
            "the sparse factor of {n} points with {nnz_row_mean:.0} neighbours each (support {support})"
        ),
        "use a smaller --support, more ranks (with mumps) or fewer points",
    )?;
    // a point alone in its support is interpolated by a spike: the spline is useless between points
    let mut any = [f64::from(u8::from(row_stats.rows > 0 && row_stats.min <= 1 && n > 1))];
    comm.max_f64(&mut any);
    if any[0] > 0.0 {
        let range = block_rows(n, comm.size(), comm.rank());
        return Err(lonely_refusal(a, support, n, lonely(comm, &tree, centres, range, support)));
    }

    // MUMPS and faer do not report their progress: a line ticks while they work
    let ticking = Progress::ticking(
        "factor",
        format!("the sparse factor of {n} rows ({}, {nnz_row_mean:.0} neighbours per row)", name(solver)),
        comm,
    );
    let factored = stages.time(Stage::Factor, || factor(comm, solver, &lower, &tree, support, threads))?;
    ticking.done();
    drop(lower);
    let k = kernel.poly_count();
    let all: Vec<usize> = (0..n).collect();
    let p = poly_block(&kernel, centres, &all);
    let (lambda, c) = stages.time(Stage::Solve, || {
        let local =
            bordered_solve(factored.solver.as_ref(), MatRef::from_column_major_slice(&p, n, k), values);
        agree(comm, local)
    })?;
    let x: Vec<f64> = lambda.iter().chain(&c).copied().collect();
    let residual =
        stages.time(Stage::Check, || residual(comm, &kernel, centres, values, &tree, &rows, &p, &x));
    drop(factored.solver);
    let spline = Spline::from_solution(kernel, centres.clone(), &x, prep.norm);
    let full = (n as f64) * (n as f64);
    Ok(Fitted {
        spline,
        coarse: Vec::new(),
        solver: format!("csrbf {}", name(solver)),
        residual,
        line: format!(
            "sparse solver {} ({}), support {support:.4}, octree {} nodes at {} levels (K = {}), {:.1} neighbours per row (max {}), factor {} entries ({:.2} % of full storage, fill {:.2})",
            name(solver),
            factored.detail,
            tree_stats.nodes,
            tree_stats.levels,
            a.leaf,
            nnz_row_mean,
            most[0],
            factored.stored,
            100.0 * factored.stored as f64 / full,
            factored.stored as f64 / lower_nnz.max(1.0)
        ),
        figures: vec![
            ("sparse_solver".into(), name(solver).into()),
            ("support".into(), format!("{support}")),
            ("leaf".into(), a.leaf.to_string()),
            ("tree_nodes".into(), tree_stats.nodes.to_string()),
            ("tree_levels".into(), tree_stats.levels.to_string()),
            ("nnz_row_mean".into(), format!("{nnz_row_mean:.3}")),
            ("nnz_row_max".into(), format!("{}", most[0])),
            ("lower_nnz".into(), format!("{lower_nnz}")),
            ("stored_entries".into(), factored.stored.to_string()),
            ("full_entries".into(), format!("{full}")),
            ("fill".into(), format!("{:.4}", factored.stored as f64 / lower_nnz.max(1.0))),
            ("system_size".into(), (n + k).to_string()),
        ],
        factor: None,
    })
}

/// A factorisation and what it stores.
struct Factored<'c> {
    solver: Box<dyn SpdSolve + 'c>,
    /// Entries of the factor (or of the envelope).
    stored: u64,
    detail: String,
}

fn factor<'c>(
    comm: &'c dyn Comm,
    solver: SparseSolver,
    lower: &SymCsr,
    tree: &Octree,
    support: f64,
    threads: usize,
) -> Result<Factored<'c>> {
    let local = match solver {
        SparseSolver::Cholesky => SparseCholesky::factor(lower, Par::rayon(threads)).map(|f| {
            let s = *f.stats();
            Factored {
                stored: s.factor_nnz as u64,
                detail: match s.supernodes {
                    Some(k) => format!("supernodal, {k} supernodes, AMD ordering"),
                    None => "simplicial, AMD ordering".into(),
                },
                solver: Box::new(f),
            }
        }),
        SparseSolver::Envelope => EnvelopeCholesky::new(lower, &tree.order(support)).map(|f| {
            let s = f.stats();
            Factored {
                stored: (s.envelope + s.order) as u64,
                detail: format!("octree ordering, bandwidth {}", s.bandwidth),
                solver: Box::new(f),
            }
        }),
        SparseSolver::Mumps => {
            // collective, and agreed inside
            let f = MumpsSpd::factor(comm, lower)?;
            let s = f.stats().clone();
            return Ok(Factored {
                stored: s.factor_entries,
                detail: format!("multifrontal, {} ordering", s.ordering),
                solver: Box::new(f),
            });
        }
        SparseSolver::Auto => unreachable!("resolved before"),
    };
    agree(comm, local)
}

/// ||M x - b|| / ||b|| of the whole bordered system, each rank taking its rows of [A P] (found
/// again through the octree, so no copy of the whole rows is kept) and rank 0 the border rows
/// P^T lambda. Collective.
#[allow(clippy::too_many_arguments)]
fn residual(
    comm: &dyn Comm,
    kernel: &Kernel,
    centres: &[f64],
    values: &[f64],
    tree: &Octree,
    rows: &[usize],
    p: &[f64],
    x: &[f64],
) -> f64 {
    let n = values.len();
    let k = kernel.poly_count();
    let support = kernel.is_compact().expect("compact");
    // exact power-of-two scaling keeps the squares finite for carrier values near 1e200
    let scale = power_of_two_below_inverse(values.iter().fold(0.0f64, |m, v| m.max(v.abs())));
    let [sq, bb] = rows
        .par_iter()
        .map_init(Vec::new, |found, &i| {
            let pi = [centres[3 * i], centres[3 * i + 1], centres[3 * i + 2]];
            tree.within(pi, support, found);
            let mut s: f64 = found
                .iter()
                .map(|&j| {
                    let d2: f64 = (0..3).map(|d| (pi[d] - centres[3 * j + d]).powi(2)).sum();
                    kernel.eval_r2(d2) * x[j]
                })
                .sum();
            s += kernel.nugget() * x[i];
            s += (0..k).map(|l| p[i + l * n] * x[n + l]).sum::<f64>();
            let (d, b) = ((s - values[i]) * scale, values[i] * scale);
            [d * d, b * b]
        })
        .reduce(|| [0.0, 0.0], |a, b| [a[0] + b[0], a[1] + b[1]]);
    let mut parts = [sq, bb];
    if comm.rank() == 0 {
        for l in 0..k {
            let t: f64 = (0..n).map(|i| p[i + l * n] * x[i]).sum::<f64>() * scale;
            parts[0] += t * t;
        }
    }
    comm.sum_f64(&mut parts);
    if parts[1] > 0.0 {
        (parts[0] / parts[1]).sqrt()
    } else {
        parts[0].sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blocks_cover_the_rows_and_solvers_resolve() {
        for p in 1..5 {
            let mut next = 0;
            for r in 0..p {
                let b = block_rows(10, p, r);
                assert_eq!(b.start, next);
                next = b.end;
            }
            assert_eq!(next, 10);
        }
        assert_eq!(resolve(SparseSolver::Auto, 1).unwrap(), SparseSolver::Cholesky);
        assert_eq!(resolve(SparseSolver::Auto, 3).unwrap(), SparseSolver::Mumps);
        assert!(resolve(SparseSolver::Envelope, 2).is_err());
        assert_eq!(resolve(SparseSolver::Envelope, 1).unwrap(), SparseSolver::Envelope);
    }
}
