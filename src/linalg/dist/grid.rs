//! The 2D block-cyclic distribution: the ranks as a pr x pc process grid, and the dense system
//! dealt out to it in nb x nb blocks, as ScaLAPACK distributes its matrices.
//!
//! # Why a second layout
//!
//! On the row-cyclic layout every step of a factorisation all-gathers a block row to every rank:
//! each rank receives about n^2 / 2 values over the factorisation whatever the rank count, and
//! every pivot search is a collective over all p ranks. On a pr x pc grid the factored panel
//! travels only along the process rows (each rank gets its own rows of it) and the block row of U
//! only down the process columns (each rank gets its own columns of it), so each rank receives
//! about n^2 (1/pr + 1/pc) / 2 values, and the pivot searches are collectives over the pr ranks
//! of one process column. For p = 64 and a square grid that is a quarter of the traffic and
//! an eighth of the ranks per pivot search. Measured on one 16-core node, a 4x4 grid already
//! solved 1.2-2x faster than row-cyclic at n = 4000 and 8000, while 2x2 and 2x4 grids were
//! within about 15 % of it either way; hence `--layout auto` ([`Layout::resolve`]). The price:
//! the panel factorisation runs on one process column while the others wait, and the right-hand
//! side and the solution move block by block in the back substitution.
//!
//! # The maps
//!
//! Along one dimension, n indices in blocks of nb over q processes: index g is in block g div nb,
//! which lives on process (g div nb) mod q, at local index (g div (nb q)) nb + g mod nb. Process
//! r owns
//!
//! ```text
//!     numroc(g, r) = (g div (nb q)) nb + min(max(g mod (nb q) - r nb, 0), nb)
//! ```
//!
//! of the indices below g, so its indices from g on are the contiguous local range
//! numroc(g, r)..numroc(n, r), as on the row-cyclic layout (which is the case nb = 1, q = p).
//! Rank (i, j) of the grid is world rank i pc + j; it holds the rows of process row i and the
//! columns of process column j, column-major with its local row count as leading dimension.

use super::layout::RowCyclic;
use super::solver::Precision;
use super::system::{LocalRows, RowIndex};
use crate::error::{Error, Result};
use crate::par::Comm;

/// n indices dealt in blocks of `nb` to `procs` processes cyclically; `me` is this process.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BlockCyclic {
    pub n: usize,
    pub nb: usize,
    pub procs: usize,
    pub me: usize,
}

impl BlockCyclic {
    pub fn new(n: usize, nb: usize, procs: usize, me: usize) -> Self {
        assert!(nb > 0 && procs > 0 && me < procs);
        BlockCyclic { n, nb, procs, me }
    }

    /// Process owning index g.
    #[inline]
    pub fn owner(&self, g: usize) -> usize {
        (g / self.nb) % self.procs
    }

    /// Local index of g on its owner.
    #[inline]
    pub fn local(&self, g: usize) -> usize {
        (g / (self.nb * self.procs)) * self.nb + g % self.nb
    }

    /// Global index of this process's local index l.
    #[inline]
    pub fn global(&self, l: usize) -> usize {
        (l / self.nb) * self.nb * self.procs + self.me * self.nb + l % self.nb
    }

    /// Number of indices below g owned by process r.
    pub fn count_below_on(&self, r: usize, g: usize) -> usize {
        let cycle = self.nb * self.procs;
        (g / cycle) * self.nb + (g % cycle).saturating_sub(r * self.nb).min(self.nb)
    }

    /// First local index whose global index is >= g (the local count if none).
    #[inline]
    pub fn first_local_from(&self, g: usize) -> usize {
        self.count_below_on(self.me, g)
    }

    /// Number of indices this process owns.
    pub fn local_count(&self) -> usize {
        self.count_below_on(self.me, self.n)
    }

    /// The global indices of this process's local indices, in local order.
    pub fn globals(&self) -> Vec<usize> {
        (0..self.local_count()).map(|l| self.global(l)).collect()
    }
}

impl RowIndex for BlockCyclic {
    fn owner(&self, g: usize) -> usize {
        BlockCyclic::owner(self, g)
    }
    fn local(&self, g: usize) -> usize {
        BlockCyclic::local(self, g)
    }
    fn first_local_from(&self, g: usize) -> usize {
        BlockCyclic::first_local_from(self, g)
    }
}

/// A pr x pc process grid over a communicator, with the communicators of its process row (the pc
/// ranks of this rank's row, ranked by column) and of its process column (ranked by row).
pub struct ProcessGrid<'a> {
    pub comm: &'a dyn Comm,
    pub pr: usize,
    pub pc: usize,
    pub myrow: usize,
    pub mycol: usize,
    pub row: Box<dyn Comm + 'a>,
    pub col: Box<dyn Comm + 'a>,
}

impl<'a> ProcessGrid<'a> {
    /// The grid of `shape` = (pr, pc) over `comm`; pr pc must be its size. Collective.
    pub fn new(comm: &'a dyn Comm, (pr, pc): (usize, usize)) -> Result<Self> {
        if pr == 0 || pc == 0 || pr * pc != comm.size() {
            return Err(Error::Usage(format!(
                "a {pr}x{pc} process grid needs {} ranks, the job has {}",
                pr * pc,
                comm.size()
            )));
        }
        let (myrow, mycol) = (comm.rank() / pc, comm.rank() % pc);
        let row = comm.split(myrow, mycol);
        let col = comm.split(mycol, myrow);
        Ok(ProcessGrid { comm, pr, pc, myrow, mycol, row, col })
    }

    /// World rank of grid position (i, j).
    pub fn rank_at(&self, i: usize, j: usize) -> usize {
        i * self.pc + j
    }
}

/// Fewest ranks from which `--layout auto` distributes in 2D: on one 16-core node the 4x4 grid
/// solved 1.2-2x faster than row-cyclic at 2000 to 8000 rows, while on 4 and 8 ranks the two
/// layouts were within about 15 % either way.
pub const AUTO_2D_RANKS: usize = 16;
/// Fewest process rows of the squarest grid for `--layout auto` to take it: the gain was measured
/// on the 4x4 grid, and the 1x16 and 16x1 grids were no faster than row-cyclic, so the thin
/// squarest grids of a prime rank count or twice a prime stay row-cyclic.
pub const AUTO_2D_GRID_ROWS: usize = 4;
/// Fewest rows of the system for `--layout auto` to distribute it in 2D (the smallest measured).
pub const AUTO_2D_SYSTEM: usize = 2000;

/// How the dense system is distributed over the ranks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Layout {
    /// Global row g on rank g mod p (every solver).
    RowCyclic,
    /// nb x nb blocks on a pr x pc process grid (every solver, in f64); None: the squarest grid.
    BlockCyclic(Option<(usize, usize)>),
    /// Row-cyclic or the squarest 2D grid, by the rank count and the fit ([`Layout::resolve`]);
    /// until resolved it distributes as row-cyclic.
    Auto,
}

impl Layout {
    /// `auto`, `row-cyclic`, `2d` (the squarest grid for the job's ranks) or an explicit grid
    /// `PRxPC`.
    pub fn parse(s: &str) -> Result<Self> {
        match s {
            "auto" => return Ok(Layout::Auto),
            "row-cyclic" | "rows" => return Ok(Layout::RowCyclic),
            "2d" => return Ok(Layout::BlockCyclic(None)),
            _ => {}
        }
        let shape = s.split_once('x').and_then(|(a, b)| Some((a.parse().ok()?, b.parse().ok()?)));
        match shape {
            Some((pr, pc)) if pr > 0 && pc > 0 => Ok(Layout::BlockCyclic(Some((pr, pc)))),
            _ => Err(Error::Usage(format!(
                "unknown layout '{s}' (expected row-cyclic, 2d or a process grid PRxPC such as 2x4)"
            ))),
        }
    }

    /// The process grid for `ranks` ranks (None for row-cyclic).
    pub fn shape(&self, ranks: usize) -> Option<(usize, usize)> {
        match *self {
            Layout::RowCyclic | Layout::Auto => None,
            Layout::BlockCyclic(shape) => Some(shape.unwrap_or_else(|| squarest(ranks))),
        }
    }

    /// The layout `auto` stands for, for a system of `rows` rows on `ranks` ranks solved in
    /// `precision`: the squarest 2D grid from `AUTO_2D_RANKS` ranks with at least
    /// `AUTO_2D_GRID_ROWS` process rows and `AUTO_2D_SYSTEM` rows, in f64; row-cyclic otherwise.
    /// (An off-surface fit, whose later fits border the first fit's factor, keeps a 2D factor
    /// moved to the row-cyclic layout.) Any other layout is returned as it is.
    pub fn resolve(self, ranks: usize, rows: usize, precision: Precision) -> Layout {
        if self != Layout::Auto {
            return self;
        }
        let wide = ranks >= AUTO_2D_RANKS && squarest(ranks).0 >= AUTO_2D_GRID_ROWS;
        if wide && rows >= AUTO_2D_SYSTEM && precision == Precision::F64 {
            Layout::BlockCyclic(None)
        } else {
            Layout::RowCyclic
        }
    }

    pub fn name(&self, ranks: usize) -> String {
        if *self == Layout::Auto {
            return "auto".into();
        }
        match self.shape(ranks) {
            None => "row-cyclic".into(),
            Some((pr, pc)) => format!("2D block-cyclic {pr}x{pc}"),
        }
    }
}

/// The squarest grid for `ranks` ranks with pr <= pc (ScaLAPACK's advice: the panel's process
/// column is the one that works alone, so it should be the taller side of the trade).
pub fn squarest(ranks: usize) -> (usize, usize) {
    let mut pr = (ranks as f64).sqrt() as usize;
    while pr > 1 && !ranks.is_multiple_of(pr) {
        pr -= 1;
    }
    let pr = pr.max(1);
    (pr, ranks / pr)
}

/// This rank's blocks of an n x (n + 1) system on a process grid, the right-hand side as global
/// column n; column-major, leading dimension the local row count.
#[derive(Debug, Clone)]
pub struct LocalBlocks {
    pub rows: BlockCyclic,
    pub cols: BlockCyclic,
    pub data: Vec<f64>,
}

impl LocalBlocks {
    /// The zero blocks of this grid position for an n x (n + 1) system in nb x nb blocks.
    pub fn zeros(grid: &ProcessGrid<'_>, n: usize, nb: usize) -> Self {
        let rows = BlockCyclic::new(n, nb, grid.pr, grid.myrow);
        let cols = BlockCyclic::new(n + 1, nb, grid.pc, grid.mycol);
        let data = vec![0.0; rows.local_count() * cols.local_count()];
        LocalBlocks { rows, cols, data }
    }

    /// [`LocalBlocks::zeros`], or [`crate::error::Error::Memory`] where the system refuses the
    /// allocation (see [`crate::linalg::try_zeros`]).
    pub fn try_zeros(grid: &ProcessGrid<'_>, n: usize, nb: usize) -> crate::error::Result<Self> {
        let rows = BlockCyclic::new(n, nb, grid.pr, grid.myrow);
        let cols = BlockCyclic::new(n + 1, nb, grid.pc, grid.mycol);
        let data = crate::linalg::try_zeros(rows.local_count() * cols.local_count(), 0.0, || {
            format!("this rank's blocks of the dense {n} x {} system", n + 1)
        })?;
        Ok(LocalBlocks { rows, cols, data })
    }

    /// Global order n of the system.
    pub fn n(&self) -> usize {
        self.rows.n
    }

    /// Leading dimension: the local row count.
    #[inline]
    pub fn ld(&self) -> usize {
        self.rows.local_count()
    }

    /// Largest |entry| of the global matrix (the right-hand side left out). Collective.
    pub fn max_abs(&self, comm: &dyn Comm) -> f64 {
        let ld = self.ld();
        let end = self.cols.first_local_from(self.n());
        let mut m = [self.data[..ld * end].iter().fold(0.0f64, |a, v| a.max(v.abs()))];
        comm.max_f64(&mut m);
        m[0]
    }

    /// The lower triangle and the first `top` rows of the leading `count` x `count` block of the
    /// global matrix on the row-cyclic layout of the same system (row g on rank g mod p, every
    /// column and the right-hand side's, polynomial border `border`): the entries (g, c) with
    /// g, c < count and c <= g or g < top. The other entries are zero, and their pages are never
    /// written. Each rank sends those entries of its blocks to the owners of their rows, by
    /// all-to-all exchanges of a band of global columns at a time (about `EXCHANGE_VALUES` per
    /// rank), so the buffers stay small beside the two copies of the matrix. Both sides walk a
    /// band in the same order (columns ascending, rows ascending within a column), which
    /// block-cyclic local order preserves, so no indices travel. Collective over the grid.
    pub fn to_row_cyclic(
        &self,
        grid: &ProcessGrid<'_>,
        border: usize,
        (count, top): (usize, usize),
    ) -> LocalRows {
        self.to_row_cyclic_in_bands(grid, border, (count, top), self.band(grid.comm.size()))
    }

    /// The columns per exchange of [`LocalBlocks::to_row_cyclic`] on `ranks` ranks: about
    /// `EXCHANGE_VALUES` values on the rank with the most rows of either layout. The same on
    /// every rank (the exchanges must match), so it depends on global sizes alone.
    fn band(&self, ranks: usize) -> usize {
        let most_rows = self.rows.count_below_on(0, self.n()).max(self.n().div_ceil(ranks)).max(1);
        (EXCHANGE_VALUES / most_rows).max(1)
    }

    /// [`LocalBlocks::to_row_cyclic`] in bands of `band` global columns (at least one).
    pub fn to_row_cyclic_in_bands(
        &self,
        grid: &ProcessGrid<'_>,
        border: usize,
        (count, top): (usize, usize),
        band: usize,
    ) -> LocalRows {
        let comm = grid.comm;
        let (p, n, ld) = (comm.size(), self.n(), self.ld());
        let count = count.min(n);
        let top = top.min(count);
        let lay = RowCyclic::new(n, p, comm.rank());
        let mut out = LocalRows::zeros(lay, n + 1, border);
        // the rank each local row goes to, and the process row each of this rank's rows comes from
        let dest: Vec<usize> = (0..ld).map(|lr| lay.owner(self.rows.global(lr))).collect();
        let from_row: Vec<usize> = (0..lay.local_count()).map(|l| self.rows.owner(lay.global(l))).collect();
        // the local rows of column c that move: the first `top` rows, then the rows from the
        // diagonal down to `count` (as two ranges that do not overlap)
        let ranges = |first_local_from: &dyn Fn(usize) -> usize, c: usize| {
            let (t, d, e) = (first_local_from(top), first_local_from(c.max(top)), first_local_from(count));
            [0..t, d..e]
        };
        let band = band.max(1);
        // the exchange buffers, kept across the bands: fresh ones would fault in their pages
        // for every band
        let (mut send, mut recv) = (Vec::new(), Vec::new());
        let mut c0 = 0;
        while c0 < count {
            let c1 = c0.saturating_add(band).min(count);
            let local_cols = self.cols.first_local_from(c0)..self.cols.first_local_from(c1);
            // what this rank sends: those entries of its columns c0..c1, by row owner
            let mut send_counts = vec![0; p];
            for lc in local_cols.clone() {
                for part in ranges(&|g| self.rows.first_local_from(g), self.cols.global(lc)) {
                    dest[part].iter().for_each(|&to| send_counts[to] += 1);
                }
            }
            let mut at = offsets(&send_counts);
            send.clear();
            send.resize(at[p], 0.0);
            for lc in local_cols {
                let column = &self.data[lc * ld..(lc + 1) * ld];
                for part in ranges(&|g| self.rows.first_local_from(g), self.cols.global(lc)) {
                    for (&to, &v) in dest[part.clone()].iter().zip(&column[part]) {
                        send[at[to]] = v;
                        at[to] += 1;
                    }
                }
            }
            // what it receives: those entries of its rows in columns c0..c1, by block owner
            let mut recv_counts = vec![0; p];
            for c in c0..c1 {
                let j = self.cols.owner(c);
                for part in ranges(&|g| lay.first_local_from(g), c) {
                    from_row[part].iter().for_each(|&i| recv_counts[grid.rank_at(i, j)] += 1);
                }
            }
            let mut at = offsets(&recv_counts);
            recv.clear();
            recv.resize(at[p], 0.0);
            comm.all_to_all_f64(&send, &send_counts, &mut recv, &recv_counts);
            let ldo = out.ld();
            for c in c0..c1 {
                let j = self.cols.owner(c);
                let column = &mut out.data[c * ldo..(c + 1) * ldo];
                for part in ranges(&|g| lay.first_local_from(g), c) {
                    for (v, &i) in column[part.clone()].iter_mut().zip(&from_row[part]) {
                        let from = &mut at[grid.rank_at(i, j)];
                        *v = recv[*from];
                        *from += 1;
                    }
                }
            }
            c0 = c1;
        }
        out
    }
}

/// Values per rank moved by one exchange of [`LocalBlocks::to_row_cyclic`] (32 MB).
pub const EXCHANGE_VALUES: usize = 1 << 22;

/// The start of each rank's part of a buffer of parts of `counts` values in rank order, and the
/// total as the last entry.
fn offsets(counts: &[usize]) -> Vec<usize> {
    let mut at = Vec::with_capacity(counts.len() + 1);
    let mut sum = 0;
    for &c in counts {
        at.push(sum);
        sum += c;
    }
    at.push(sum);
    at
}

/// The narrowest piece of a trailing update run between two tests of a panel broadcast.
const MIN_PIECE: usize = 256;

/// One step of a right-looking 2D factorisation after the panel's own work: the trailing update
/// of this rank's columns `cols` (by `update(a, c0, c1)` on local column ranges) and the next
/// panel, factored by `factor` on its process column `pk1` (whose first `kb1` columns of `cols`
/// are that panel) and broadcast along the process rows; returns the packed next panel (`len`
/// values) on every rank. Without look-ahead: the whole update, then the panel, then a blocking
/// broadcast. With it: the process column of the next panel updates that panel's columns first
/// and factors it at once, and every rank runs the rest of its update in pieces while the
/// non-blocking broadcast is in flight. The factors are the same either way: the next panel's
/// factorisation reads and writes only its own columns, which are updated before it runs.
/// Collective over the grid.
#[allow(clippy::too_many_arguments)]
pub(super) fn update_and_next_panel(
    grid: &ProcessGrid<'_>,
    a: &mut LocalBlocks,
    lookahead: bool,
    cols: std::ops::Range<usize>,
    (pk1, kb1): (usize, usize),
    len: usize,
    update: &dyn Fn(&mut LocalBlocks, usize, usize),
    factor: &dyn Fn(&mut LocalBlocks) -> Vec<f64>,
) -> Vec<f64> {
    let (c1, end) = (cols.start, cols.end);
    if !lookahead {
        update(a, c1, end);
        let mut next = if grid.mycol == pk1 { factor(a) } else { vec![0.0; len] };
        grid.row.broadcast_f64(pk1, &mut next);
        return next;
    }
    let early = grid.mycol == pk1;
    let mut next = if early {
        update(a, c1, c1 + kb1);
        factor(a)
    } else {
        vec![0.0; len]
    };
    let mut from = if early { c1 + kb1 } else { c1 };
    let piece = (end - from).div_ceil(4).max(MIN_PIECE);
    let mut work = || {
        let to = (from + piece).min(end);
        update(a, from, to);
        from = to;
        from < end
    };
    grid.row.broadcast_f64_while(pk1, &mut next, &mut work);
    next
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn block_cyclic_maps_round_trip() {
        for procs in 1..5 {
            for nb in [1, 2, 3, 8] {
                for n in [0, 1, 7, 10, 13, 33] {
                    let mut seen = vec![0; n];
                    for me in 0..procs {
                        let m = BlockCyclic::new(n, nb, procs, me);
                        for l in 0..m.local_count() {
                            let g = m.global(l);
                            assert!(g < n);
                            assert_eq!((m.owner(g), m.local(g)), (me, l), "n={n} nb={nb} q={procs}");
                            seen[g] += 1;
                        }
                        for g in 0..=n {
                            let expect = (0..m.local_count()).find(|&l| m.global(l) >= g);
                            assert_eq!(m.first_local_from(g), expect.unwrap_or(m.local_count()));
                        }
                    }
                    assert!(seen.iter().all(|&c| c == 1), "n={n} nb={nb} q={procs}");
                }
            }
        }
    }

    #[test]
    fn layouts_parse() {
        assert_eq!(Layout::parse("row-cyclic").unwrap(), Layout::RowCyclic);
        assert_eq!(Layout::parse("2d").unwrap().shape(6), Some((2, 3)));
        assert_eq!(Layout::parse("3x1").unwrap().shape(6), Some((3, 1)));
        assert_eq!(Layout::parse("2x2").unwrap().name(4), "2D block-cyclic 2x2");
        for bad in ["", "x", "0x2", "2x", "2x-1", "square", "2*2"] {
            assert!(Layout::parse(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn auto_takes_the_squarest_grid_from_sixteen_ranks_for_large_f64_systems() {
        let f64 = Precision::F64;
        let auto = |ranks, rows, precision| Layout::Auto.resolve(ranks, rows, precision);
        assert_eq!(auto(16, 2000, f64), Layout::BlockCyclic(None));
        assert_eq!(Layout::BlockCyclic(None).shape(16), Some((4, 4)));
        assert_eq!(auto(64, 100_000, f64), Layout::BlockCyclic(None));
        assert_eq!(auto(24, 8000, f64), Layout::BlockCyclic(None), "4x6");
        for (ranks, rows, precision, why) in [
            (15, 8000, f64, "too few ranks"),
            (17, 8000, f64, "a prime: 1x17"),
            (22, 8000, f64, "2x11"),
            (16, 1999, f64, "too few rows"),
            (16, 8000, Precision::Mixed, "mixed precision runs row-cyclic"),
        ] {
            assert_eq!(auto(ranks, rows, precision), Layout::RowCyclic, "{why}");
        }
        // an explicit layout stays as asked
        for asked in [Layout::RowCyclic, Layout::BlockCyclic(Some((1, 2)))] {
            assert_eq!(asked.resolve(16, 8000, f64), asked);
        }
        assert_eq!(Layout::parse("auto").unwrap(), Layout::Auto);
        assert_eq!(Layout::Auto.shape(16), None);
    }

    #[test]
    fn the_exchange_band_is_the_same_on_every_rank() {
        // the process rows of a grid own different row counts; the band must not follow them
        for (pr, pc) in [(1, 1), (2, 1), (1, 2), (3, 2), (4, 4)] {
            for (n, nb) in [(7, 2), (3001, 64), (100_003, 128)] {
                let band = |i: usize, j: usize| {
                    let rows = BlockCyclic::new(n, nb, pr, i);
                    let cols = BlockCyclic::new(n + 1, nb, pc, j);
                    LocalBlocks { rows, cols, data: Vec::new() }.band(pr * pc)
                };
                let first = band(0, 0);
                for (i, j) in (0..pr).flat_map(|i| (0..pc).map(move |j| (i, j))) {
                    assert_eq!(band(i, j), first, "{pr}x{pc}, n {n}, nb {nb}: rank ({i}, {j})");
                }
            }
        }
    }

    #[test]
    fn squarest_grids() {
        assert_eq!(squarest(1), (1, 1));
        assert_eq!(squarest(2), (1, 2));
        assert_eq!(squarest(3), (1, 3));
        assert_eq!(squarest(4), (2, 2));
        assert_eq!(squarest(12), (3, 4));
        assert_eq!(squarest(16), (4, 4));
        assert_eq!(squarest(1024), (32, 32));
    }
}
