//! The row-cyclic distribution of the rows of the dense system over the ranks (global row g lives
//! on rank g mod P, as local row g div P). All global/local row index arithmetic lives here.

/// Row-cyclic distribution of `n` global rows over `p` ranks: global row g lives on rank g mod p
/// at local index g div p (the paper's transputer layout, ScaLAPACK with block size 1).
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
}
