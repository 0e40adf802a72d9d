//! Trimming: the part of a mesh whose triangles pass a test at their centroids, with the vertices
//! no kept triangle uses left out and the rest renumbered in their order. Used to open a
//! reconstructed solid where no data supports its surface (see `crate::surface::support`).

use rayon::prelude::*;

use super::TriMesh;

/// The triangles of `mesh` whose centroid `keep` accepts, and their vertices.
pub fn keep_triangles(mesh: &TriMesh, keep: impl Fn(&[f64; 3]) -> bool + Sync) -> TriMesh {
    keep_triangles_indexed(mesh, keep).0
}

/// [`keep_triangles`], and for each vertex kept its index in `mesh` (to carry vertex properties
/// over).
pub fn keep_triangles_indexed(
    mesh: &TriMesh,
    keep: impl Fn(&[f64; 3]) -> bool + Sync,
) -> (TriMesh, Vec<usize>) {
    let kept: Vec<[u32; 3]> =
        mesh.triangles.par_iter().filter(|t| keep(&centroid(mesh, t))).copied().collect();
    let mut new_index = vec![u32::MAX; mesh.vertices.len()];
    for t in &kept {
        for &v in t {
            new_index[v as usize] = 0;
        }
    }
    let (mut vertices, mut from) = (Vec::new(), Vec::new());
    for (v, slot) in new_index.iter_mut().enumerate() {
        if *slot == 0 {
            *slot = vertices.len() as u32;
            vertices.push(mesh.vertices[v]);
            from.push(v);
        }
    }
    let triangles = kept.iter().map(|t| t.map(|v| new_index[v as usize])).collect();
    (TriMesh { vertices, triangles }, from)
}

/// The centroid of triangle `t` of `mesh`.
pub fn centroid(mesh: &TriMesh, t: &[u32; 3]) -> [f64; 3] {
    let [a, b, c] = t.map(|v| mesh.vertices[v as usize]);
    [0, 1, 2].map(|d| (a[d] + b[d] + c[d]) / 3.0)
}

/// The total area of the triangles of `mesh`.
pub fn area(mesh: &TriMesh) -> f64 {
    mesh.triangles
        .par_iter()
        .map(|t| {
            let [a, b, c] = t.map(|v| mesh.vertices[v as usize]);
            let (u, w) = ([0, 1, 2].map(|d| b[d] - a[d]), [0, 1, 2].map(|d| c[d] - a[d]));
            let x = [u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]];
            0.5 * (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt()
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two unit right triangles side by side in the plane z = 0, sharing the edge (1,0)-(0,1),
    /// and a third far away at x = 10.
    fn three() -> TriMesh {
        TriMesh {
            vertices: vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [1.0, 1.0, 0.0],
                [10.0, 0.0, 0.0],
                [11.0, 0.0, 0.0],
                [10.0, 1.0, 0.0],
            ],
            triangles: vec![[0, 1, 2], [1, 3, 2], [4, 5, 6]],
        }
    }

    #[test]
    fn triangles_left_out_take_only_their_own_vertices_with_them() {
        let m = three();
        assert!((area(&m) - 1.5).abs() < 1e-15);
        let near = keep_triangles(&m, |c| c[0] < 5.0);
        assert_eq!(near.vertices, m.vertices[..4].to_vec());
        assert_eq!(near.triangles, vec![[0, 1, 2], [1, 3, 2]]);
        // the second triangle alone: vertex 0 goes, the others are renumbered in order
        let one = keep_triangles(&m, |c| c[0] > 0.5 && c[0] < 5.0);
        assert_eq!(one.vertices, vec![[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]]);
        assert_eq!(one.triangles, vec![[0, 2, 1]]);
        assert_eq!(keep_triangles_indexed(&m, |c| c[0] > 0.5 && c[0] < 5.0).1, vec![1, 2, 3]);
        assert!((area(&one) - 0.5).abs() < 1e-15);
        assert_eq!(keep_triangles(&m, |_| false), TriMesh::default());
        assert_eq!(keep_triangles(&m, |_| true), m);
    }
}
