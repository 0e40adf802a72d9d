//! The row-cyclic distribution of the rows of the dense system over the ranks. All global/local
//! row index arithmetic lives here.
//!
//! With p ranks, global row g (0-based, the k polynomial rows last) lives on rank g mod p as
//! local row g div p; ScaLAPACK calls this a cyclic distribution with block size 1. Rank r owns
//!
//! ```text
//!     rows_below(r, g) = #{ g' < g : g' = r mod p } = (g + p - 1 - r) div p
//! ```
//!
//! rows above global row g, so its rows g.. are the contiguous local range
//! rows_below(r, g)..local_count: every factorisation step that works on "the rows from g on"
//! touches one slice of each rank's column-major storage. The layout is chosen for balance: a
//! right-looking factorisation at step g works on the trailing rows g..n, and every rank owns
//! (n - g)/p of them to within one row at every step, where a block distribution would idle the
//! ranks holding the leading blocks. Each rank also assembles only its own rows (N kernel
//! evaluations per row), so the assembly is perfectly parallel and no matrix passes through one
//! rank.
//!
//! A collective that gathers the rows g0..g1 receives them rank by rank: rank r's rows of the
//! range are g0 + ((r - g0) mod p) + t p, t = 0, 1, ...; [`RowCyclic::to_global_order`] puts
//! them back in global order.

use super::system::RowIndex;

/// Row-cyclic distribution of `n` global rows over `p` ranks: global row g lives on rank g mod p
/// at local index g div p.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RowCyclic {
    pub n: usize,
    pub ranks: usize,
    pub rank: usize,
}

impl RowCyclic {
    pub fn new(n: usize, ranks: usize, rank: usize) -> Self {
        assert!(ranks > 0 && rank < ranks);
        RowCyclic { n, ranks, rank }
    }

    /// Rank owning global row g.
    #[inline]
    pub fn owner(&self, g: usize) -> usize {
        g % self.ranks
    }

    /// Local index of global row g on its owner.
    #[inline]
    pub fn local(&self, g: usize) -> usize {
        g / self.ranks
    }

    /// Global index of this rank's local row l.
    #[inline]
    pub fn global(&self, l: usize) -> usize {
        l * self.ranks + self.rank
    }

    /// Number of rows this rank owns.
    pub fn local_count(&self) -> usize {
        self.count_on(self.rank)
    }

    /// Number of rows rank r owns.
    pub fn count_on(&self, r: usize) -> usize {
        (self.n + self.ranks - 1 - r) / self.ranks
    }

    /// First local index whose global row is >= g (local_count() if none): this rank's rows
    /// g.. form the contiguous local range first_local_from(g)..local_count().
    #[inline]
    pub fn first_local_from(&self, g: usize) -> usize {
        self.count_below_on(self.rank, g)
    }

    /// Number of global rows < g owned by rank r.
    pub fn count_below_on(&self, r: usize, g: usize) -> usize {
        (g + self.ranks - 1 - r) / self.ranks
    }

    /// Number of rows in the global range a..b owned by rank r.
    pub fn count_in_on(&self, r: usize, a: usize, b: usize) -> usize {
        self.count_below_on(r, b) - self.count_below_on(r, a)
    }

    /// Puts the rows g0..g1, `w` values each, from rank order (rank 0's rows of the range in
    /// local order, then rank 1's, ..., as an all-gather delivers them) into global order.
    pub fn to_global_order<T: Copy>(&self, gathered: &[T], g0: usize, g1: usize, w: usize, out: &mut [T]) {
        debug_assert!(gathered.len() == (g1 - g0) * w && out.len() == gathered.len());
        let p = self.ranks;
        let mut off = 0;
        for r in 0..p {
            let first = g0 + (r + p - g0 % p) % p;
            for t in 0..self.count_in_on(r, g0, g1) {
                let g = first + t * p;
                out[(g - g0) * w..(g - g0 + 1) * w].copy_from_slice(&gathered[off..off + w]);
                off += w;
            }
        }
    }
}

impl RowIndex for RowCyclic {
    fn owner(&self, g: usize) -> usize {
        RowCyclic::owner(self, g)
    }
    fn local(&self, g: usize) -> usize {
        RowCyclic::local(self, g)
    }
    fn first_local_from(&self, g: usize) -> usize {
        RowCyclic::first_local_from(self, g)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn row_cyclic_round_trips() {
        for ranks in 1..5 {
            for n in [0, 1, 7, 10, 13] {
                let mut seen = vec![0; n];
                for rank in 0..ranks {
                    let l = RowCyclic::new(n, ranks, rank);
                    for loc in 0..l.local_count() {
                        let g = l.global(loc);
                        assert_eq!(l.owner(g), rank);
                        assert_eq!(l.local(g), loc);
                        seen[g] += 1;
                    }
                    for g in 0..=n {
                        let first = l.first_local_from(g);
                        let expect =
                            (0..l.local_count()).find(|&x| l.global(x) >= g).unwrap_or(l.local_count());
                        assert_eq!(first, expect, "n={n} ranks={ranks} rank={rank} g={g}");
                    }
                    assert_eq!(l.count_in_on(rank, 0, n), l.local_count());
                }
                assert!(seen.iter().all(|&c| c == 1));
            }
        }
    }

    #[test]
    fn gathered_rows_return_to_global_order() {
        for ranks in 1..5 {
            for (g0, g1) in [(0, 0), (0, 9), (3, 4), (5, 13), (2, 11)] {
                let (n, w) = (13, 2);
                let lay = RowCyclic::new(n, ranks, 0);
                // what an all-gather delivers: each rank's rows of the range, ascending
                let gathered: Vec<f64> = (0..ranks)
                    .flat_map(|r| (g0..g1).filter(move |g| g % ranks == r))
                    .flat_map(|g| [g as f64, -(g as f64)])
                    .collect();
                let mut out = vec![0.0; (g1 - g0) * w];
                lay.to_global_order(&gathered, g0, g1, w, &mut out);
                let expect: Vec<f64> = (g0..g1).flat_map(|g| [g as f64, -(g as f64)]).collect();
                assert_eq!(out, expect, "ranks={ranks} g0={g0} g1={g1}");
            }
        }
    }
}
