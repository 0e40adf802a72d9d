//! Connected components of undirected graphs, by union-find with path halving.

/// Union-find root of `i`, halving the path on the way.
fn root(parent: &mut [usize], mut i: usize) -> usize {
    while parent[i] != i {
        parent[i] = parent[parent[i]];
        i = parent[i];
    }
    i
}

/// Labels 0..count of the connected components of `edges` over `n` vertices, numbered in the
/// order of their smallest vertex, and the count. Deterministic whatever the order of the edges.
pub fn components(n: usize, edges: impl Iterator<Item = (usize, usize)>) -> (Vec<usize>, usize) {
    let mut parent: Vec<usize> = (0..n).collect();
    for (a, b) in edges {
        let (ra, rb) = (root(&mut parent, a), root(&mut parent, b));
        if ra != rb {
            parent[ra.max(rb)] = ra.min(rb);
        }
    }
    let mut label = vec![usize::MAX; n];
    let mut count = 0;
    for i in 0..n {
        let r = root(&mut parent, i);
        if label[r] == usize::MAX {
            label[r] = count;
            count += 1;
        }
        label[i] = label[r];
    }
    (label, count)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn components_are_numbered_by_their_smallest_vertex() {
        // 0-3-4, 1, 2-5, in any order of the edges
        let edges = [(4, 3), (5, 2), (0, 3)];
        assert_eq!(components(6, edges.iter().copied()), (vec![0, 1, 2, 0, 0, 2], 3));
        assert_eq!(components(6, edges.iter().rev().copied()), (vec![0, 1, 2, 0, 0, 2], 3));
        assert_eq!(components(0, std::iter::empty()), (vec![], 0));
    }
}
