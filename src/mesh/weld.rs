//! Welding of per-slab [`MeshPiece`]s into one [`TriMesh`].
//!
//! Owns the rule that makes the final mesh independent of how the grid was
//! split across ranks: vertices are identified only by their global edge id
//! and emitted in edge-id order, and triangles are put in a canonical rotation
//! and sorted. Any split of the same grid therefore yields identical arrays.

use super::{MeshPiece, TriMesh};

/// Rotates a triangle so its smallest index comes first, keeping orientation.
fn canonical(t: [u32; 3]) -> [u32; 3] {
    let [a, b, c] = t;
    if a <= b && a <= c {
        [a, b, c]
    } else if b <= c {
        [b, c, a]
    } else {
        [c, a, b]
    }
}

/// Merge pieces by edge id.
///
/// - Output vertices are sorted by edge id; the position kept for an id is the
///   one from the first piece listing it (pieces computed from the same grid
///   produce bit-identical positions for a shared edge).
/// - Triangles are rotated to start at their smallest index and sorted, so the
///   output does not depend on piece order. Triangles that use a vertex twice
///   are dropped, as are exact duplicates (e.g. from overlapping slabs) and
///   triangles whose indices fall outside their piece.
/// - Vertices no remaining triangle uses are dropped.
pub fn weld(pieces: &[MeshPiece]) -> TriMesh {
    let mut entries: Vec<(u64, u32, u32)> = Vec::new();
    for (p, piece) in pieces.iter().enumerate() {
        let n = piece.edge_ids.len().min(piece.positions.len());
        entries.extend((0..n).map(|l| (piece.edge_ids[l], p as u32, l as u32)));
    }
    entries.sort_unstable();

    let mut maps: Vec<Vec<u32>> =
        pieces.iter().map(|pc| vec![u32::MAX; pc.edge_ids.len().min(pc.positions.len())]).collect();
    let mut positions: Vec<[f64; 3]> = Vec::new();
    let mut last_id = None;
    for &(id, p, l) in &entries {
        if last_id != Some(id) {
            last_id = Some(id);
            positions.push(pieces[p as usize].positions[l as usize]);
        }
        maps[p as usize][l as usize] = (positions.len() - 1) as u32;
    }

    let mut triangles: Vec<[u32; 3]> = Vec::new();
    for (piece, map) in pieces.iter().zip(&maps) {
        for t in &piece.triangles {
            let g = t.map(|v| map.get(v as usize).copied().unwrap_or(u32::MAX));
            if g.contains(&u32::MAX) || g[0] == g[1] || g[1] == g[2] || g[0] == g[2] {
                continue;
            }
            triangles.push(canonical(g));
        }
    }
    triangles.sort_unstable();
    triangles.dedup();

    // Compaction keeps the sort order, so vertices stay in edge-id order.
    let mut remap = vec![u32::MAX; positions.len()];
    for t in &triangles {
        for &v in t {
            remap[v as usize] = 0;
        }
    }
    let mut vertices = Vec::with_capacity(positions.len());
    for (r, p) in remap.iter_mut().zip(&positions) {
        if *r == 0 {
            *r = vertices.len() as u32;
            vertices.push(*p);
        }
    }
    for t in &mut triangles {
        *t = t.map(|v| remap[v as usize]);
    }
    TriMesh { vertices, triangles }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn piece(ids: &[u64], tris: &[[u32; 3]]) -> MeshPiece {
        MeshPiece {
            edge_ids: ids.to_vec(),
            positions: ids.iter().map(|&i| [i as f64, 0.0, 0.0]).collect(),
            triangles: tris.to_vec(),
        }
    }

    #[test]
    fn shared_ids_merge_and_order_is_by_id() {
        let a = piece(&[30, 10, 20], &[[0, 1, 2]]);
        let b = piece(&[20, 40, 10], &[[2, 1, 0]]);
        let m = weld(&[a.clone(), b.clone()]);
        assert_eq!(m.vertices, vec![[10.0, 0.0, 0.0], [20.0, 0.0, 0.0], [30.0, 0.0, 0.0], [40.0, 0.0, 0.0]]);
        // a: (30,10,20) -> (2,0,1) -> canonical (0,1,2); b: (10,40,20) -> (0,3,1).
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 3, 1]]);
        assert_eq!(weld(&[b, a]), m, "piece order must not matter");
    }

    #[test]
    fn drops_degenerate_duplicate_and_invalid_triangles() {
        let a = piece(&[5, 6, 7, 8], &[[0, 1, 2], [0, 0, 3], [1, 2, 9]]);
        let b = piece(&[6, 7, 5], &[[2, 0, 1], [1, 0, 2]]);
        let m = weld(&[a, b]);
        // [2,0,1] of b is the same triangle as a's first; [1,0,2] is its reverse.
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 1]]);
        assert_eq!(m.vertices.len(), 3, "vertex 8 is only used by a dropped triangle");
        // Same id twice in one piece collapses to one vertex, making a degenerate triangle.
        let c = piece(&[1, 1, 2], &[[0, 1, 2]]);
        assert!(weld(&[c]).triangles.is_empty());
        assert_eq!(weld(&[]), TriMesh::default());
    }

    #[test]
    fn mismatched_piece_lengths_do_not_panic() {
        let p = MeshPiece {
            edge_ids: vec![1, 2, 3, 4],
            positions: vec![[0.0; 3]; 3],
            triangles: vec![[0, 1, 2], [1, 2, 3]],
        };
        let m = weld(&[p]);
        assert_eq!(m.triangles, vec![[0, 1, 2]]);
    }
}
