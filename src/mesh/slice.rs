//! Cutting a triangle mesh by a plane into polylines: the contours of `volspline slice`, and the
//! sections of reconstructed meshes that the tests count. Pure geometry on a [`TriMesh`].
//!
//! A vertex with signed distance >= 0 counts as in front of the plane, so every crossed edge has
//! exactly one crossing point and every crossed triangle exactly one segment; segments sharing an
//! edge are chained. On a closed manifold mesh every polyline is closed; where the mesh has holes
//! (open scans) a chain ends at the hole and is reported as open.

use std::collections::HashMap;

use super::TriMesh;

/// The polylines where a mesh meets a plane.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PlaneCut {
    /// Closed polylines (the last point joins the first), world coordinates.
    pub closed: Vec<Vec<[f64; 3]>>,
    /// Chains that end on the mesh's boundary (holes), in order.
    pub open: Vec<Vec<[f64; 3]>>,
}

/// Cuts `mesh` by the plane through `origin` with normal `normal` (any length).
pub fn cut_by_plane(mesh: &TriMesh, origin: [f64; 3], normal: [f64; 3]) -> PlaneCut {
    let s: Vec<f64> =
        mesh.vertices.iter().map(|p| (0..3).map(|d| normal[d] * (p[d] - origin[d])).sum::<f64>()).collect();
    let ahead = |v: u32| s[v as usize] >= 0.0;
    let key = |a: u32, b: u32| (a.min(b), a.max(b));
    // each crossed triangle gives one segment between two crossed edges
    let mut segments: Vec<[(u32, u32); 2]> = Vec::new();
    for t in &mesh.triangles {
        let mut ends = Vec::with_capacity(2);
        for e in 0..3 {
            let (a, b) = (t[e], t[(e + 1) % 3]);
            if ahead(a) != ahead(b) {
                ends.push(key(a, b));
            }
        }
        if ends.len() == 2 {
            segments.push([ends[0], ends[1]]);
        }
    }
    let mut at_edge: HashMap<(u32, u32), Vec<usize>> = HashMap::new();
    for (i, seg) in segments.iter().enumerate() {
        for e in seg {
            at_edge.entry(*e).or_default().push(i);
        }
    }
    let point = |(a, b): (u32, u32)| -> [f64; 3] {
        let (pa, pb) = (mesh.vertices[a as usize], mesh.vertices[b as usize]);
        let t = s[a as usize] / (s[a as usize] - s[b as usize]);
        [pa[0] + t * (pb[0] - pa[0]), pa[1] + t * (pb[1] - pa[1]), pa[2] + t * (pb[2] - pa[2])]
    };
    let mut used = vec![false; segments.len()];
    let mut cut = PlaneCut::default();
    // walks from edge `e` along unused segments; returns the edges visited after `e`
    let walk = |start: (u32, u32), used: &mut Vec<bool>| -> Vec<(u32, u32)> {
        let mut chain = Vec::new();
        let mut e = start;
        while let Some(&i) = at_edge.get(&e).and_then(|l| l.iter().find(|&&i| !used[i])) {
            used[i] = true;
            e = if segments[i][0] == e { segments[i][1] } else { segments[i][0] };
            chain.push(e);
        }
        chain
    };
    for first in 0..segments.len() {
        if used[first] {
            continue;
        }
        used[first] = true;
        let [a, b] = segments[first];
        let forward = walk(b, &mut used);
        let closed = forward.last() == Some(&a);
        let mut edges = vec![a, b];
        if closed {
            edges.extend_from_slice(&forward[..forward.len() - 1]);
        } else {
            edges.extend_from_slice(&forward);
            let mut back = walk(a, &mut used);
            back.reverse();
            back.extend(edges);
            edges = back;
        }
        let poly: Vec<[f64; 3]> = edges.into_iter().map(point).collect();
        if closed {
            cut.closed.push(poly);
        } else {
            cut.open.push(poly);
        }
    }
    cut
}

#[cfg(test)]
mod tests {
    use super::super::testutil::{mesh_in_slabs, sample};
    use super::*;

    #[test]
    fn a_sphere_cut_is_one_circle_and_two_spheres_two() {
        let g = sample(40, -1.0, 1.0, |p| 0.6f64.powi(2) - (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]));
        let m = mesh_in_slabs(&g, 0.0, 1);
        let cut = cut_by_plane(&m, [0.0, 0.0, 0.3], [0.0, 0.0, 2.0]);
        assert_eq!((cut.closed.len(), cut.open.len()), (1, 0));
        let r = (0.36f64 - 0.09).sqrt();
        for p in &cut.closed[0] {
            assert!((p[2] - 0.3).abs() < 1e-12);
            assert!(((p[0] * p[0] + p[1] * p[1]).sqrt() - r).abs() < 0.01);
        }
        assert!(cut.closed[0].len() > 20);
        assert!(cut_by_plane(&m, [0.0, 0.0, 0.7], [0.0, 0.0, 1.0]).closed.is_empty());
        let two = sample(40, -1.0, 1.0, |p| {
            let d = |c: f64| 0.3f64.powi(2) - ((p[0] - c).powi(2) + p[1] * p[1] + p[2] * p[2]);
            d(-0.5).max(d(0.5))
        });
        let m2 = mesh_in_slabs(&two, 0.0, 2);
        let tilted = cut_by_plane(&m2, [0.0, 0.0, 0.0], [0.0, 0.3, 1.0]);
        assert_eq!((tilted.closed.len(), tilted.open.len()), (2, 0));
    }

    #[test]
    fn an_open_mesh_gives_an_open_chain() {
        // a square of two triangles, cut across
        let m = TriMesh {
            vertices: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]],
            triangles: vec![[0, 1, 2], [0, 2, 3]],
        };
        let cut = cut_by_plane(&m, [0.5, 0.0, 0.0], [1.0, 0.0, 0.0]);
        assert_eq!((cut.closed.len(), cut.open.len()), (0, 1));
        assert_eq!(cut.open[0].len(), 3);
        assert!(cut.open[0].iter().all(|p| (p[0] - 0.5).abs() < 1e-15));
    }
}
