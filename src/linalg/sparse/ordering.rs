//! The reverse Cuthill-McKee ordering, a purely algebraic envelope reducer (Cuthill & McKee
//! 1969; George & Liu 1981, chapter 4): a baseline for the spatial orderings of the centres and a
//! fallback when no geometry is at hand.
//!
//! The graph of A has the unknowns as vertices and an edge i - j for every a_ij != 0, i != j.
//! Cuthill-McKee numbers a start vertex first and then proceeds breadth first, numbering the
//! unnumbered neighbours of each vertex in increasing order of degree. Every vertex is thereby
//! numbered shortly after its first numbered neighbour, which bounds each row's bandwidth
//! beta_i = i - f_i by the width of the breadth-first level structure. Reversing the order leaves
//! the bandwidth as it is but never enlarges, and usually shrinks, the envelope sum_i beta_i
//! (George 1971). The start is a pseudo-peripheral vertex (one of nearly maximal eccentricity,
//! found by repeated breadth-first searches from a vertex of minimum degree in the last level),
//! which makes the level structure long and narrow. Each connected component is ordered in turn.

use std::collections::VecDeque;

use super::check::check_serial;
use super::SymCsr;
use crate::error::Result;

/// The symmetric adjacency of A without the diagonal, in compressed rows.
struct Graph {
    ptr: Vec<usize>,
    adj: Vec<usize>,
}

impl Graph {
    fn new(a: &SymCsr) -> Self {
        let n = a.n;
        let mut deg = vec![0usize; n];
        for i in 0..n {
            for (j, _) in a.row(i).filter(|&(j, _)| j != i) {
                deg[i] += 1;
                deg[j] += 1;
            }
        }
        let mut ptr = vec![0usize; n + 1];
        for i in 0..n {
            ptr[i + 1] = ptr[i] + deg[i];
        }
        let mut next = ptr[..n].to_vec();
        let mut adj = vec![0usize; ptr[n]];
        for i in 0..n {
            for (j, _) in a.row(i).filter(|&(j, _)| j != i) {
                adj[next[i]] = j;
                next[i] += 1;
                adj[next[j]] = i;
                next[j] += 1;
            }
        }
        Graph { ptr, adj }
    }

    fn neighbours(&self, v: usize) -> &[usize] {
        &self.adj[self.ptr[v]..self.ptr[v + 1]]
    }

    fn degree(&self, v: usize) -> usize {
        self.ptr[v + 1] - self.ptr[v]
    }

    /// The breadth-first level structure from `root` among the vertices not yet `numbered`: the
    /// vertices in visiting order, and where the last level starts. `stamp` marks visits.
    fn levels(
        &self,
        root: usize,
        numbered: &[bool],
        stamp: &mut [usize],
        id: usize,
    ) -> (Vec<usize>, usize, usize) {
        let mut order = vec![root];
        stamp[root] = id;
        let (mut begin, mut depth) = (0, 0);
        loop {
            let end = order.len();
            for t in begin..end {
                for &w in self.neighbours(order[t]) {
                    if !numbered[w] && stamp[w] != id {
                        stamp[w] = id;
                        order.push(w);
                    }
                }
            }
            if order.len() == end {
                return (order, begin, depth);
            }
            begin = end;
            depth += 1;
        }
    }
}

/// The reverse Cuthill-McKee ordering of `a` (the whole matrix, rows 0..n) as perm\[new\] = old,
/// ready for [`super::envelope::Envelope::new`].
pub fn reverse_cuthill_mckee(a: &SymCsr) -> Result<Vec<usize>> {
    check_serial(a, "reverse Cuthill-McKee")?;
    let n = a.n;
    let g = Graph::new(a);
    let mut numbered = vec![false; n];
    let mut stamp = vec![usize::MAX; n];
    let mut id = 0;
    let mut by_degree: Vec<usize> = (0..n).collect();
    by_degree.sort_by_key(|&v| g.degree(v));
    let mut order = Vec::with_capacity(n);
    let mut queue = VecDeque::new();
    for &seed in &by_degree {
        if numbered[seed] {
            continue;
        }
        // pseudo-peripheral root of seed's component
        let mut root = seed;
        let (mut lv, mut last, mut depth) = g.levels(root, &numbered, &mut stamp, id);
        loop {
            id += 1;
            let cand = *lv[last..].iter().min_by_key(|&&v| g.degree(v)).unwrap_or(&root);
            let (clv, clast, cdepth) = g.levels(cand, &numbered, &mut stamp, id);
            if cdepth <= depth {
                break;
            }
            (root, lv, last, depth) = (cand, clv, clast, cdepth);
        }
        // Cuthill-McKee from the root
        numbered[root] = true;
        queue.push_back(root);
        let mut fresh = Vec::new();
        while let Some(v) = queue.pop_front() {
            order.push(v);
            fresh.clear();
            fresh.extend(g.neighbours(v).iter().copied().filter(|&w| !numbered[w]));
            fresh.sort_by_key(|&w| (g.degree(w), w));
            for &w in &fresh {
                numbered[w] = true;
                queue.push_back(w);
            }
        }
        id += 1;
    }
    order.reverse();
    Ok(order)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linalg::sparse::envelope::envelope_size;
    use crate::linalg::sparse::test_support::{bunny, kernel_matrix};

    #[test]
    fn is_a_permutation_and_shrinks_the_envelope_of_a_kernel_matrix() {
        let a = kernel_matrix(&bunny(10), 0.2);
        let perm = reverse_cuthill_mckee(&a).unwrap();
        let mut sorted = perm.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, (0..a.n).collect::<Vec<_>>());
        let identity: Vec<usize> = (0..a.n).collect();
        let (rcm, file) = (envelope_size(&a, &perm).unwrap(), envelope_size(&a, &identity).unwrap());
        assert!(rcm < file, "RCM {rcm}, file order {file}");
    }

    #[test]
    fn orders_a_path_given_in_scrambled_order_as_a_band() {
        // the path 3 - 0 - 4 - 1 - 2 (edges 0-3, 0-4, 1-4, 1-2), plus an isolated vertex 5
        let edges = [(3, 0), (4, 0), (4, 1), (2, 1)];
        let n = 6;
        let mut a = SymCsr { n, rows: (0..n).collect(), row_ptr: vec![0], ..Default::default() };
        for i in 0..n {
            let mut cols: Vec<usize> = edges.iter().filter(|e| e.0 == i).map(|e| e.1).collect();
            cols.push(i);
            cols.sort_unstable();
            a.vals.extend(cols.iter().map(|&j| if i == j { 4.0 } else { -1.0 }));
            a.cols.extend(cols);
            a.row_ptr.push(a.cols.len());
        }
        let perm = reverse_cuthill_mckee(&a).unwrap();
        // a path ordered from one end: bandwidth 1, envelope 2 n - 1 minus the isolated vertex's link
        assert_eq!(envelope_size(&a, &perm).unwrap(), 2 * 5 - 1 + 1, "{perm:?}");
    }
}
