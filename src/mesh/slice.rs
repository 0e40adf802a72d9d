//! Cutting a triangle mesh by a plane into polylines: the contours of `volspline slice`, and the
//! sections of reconstructed meshes that the tests count. Pure geometry on a [`TriMesh`].
//!
//! A vertex with signed distance >= 0 counts as in front of the plane, so every crossed edge has
//! exactly one crossing point and every crossed triangle exactly one segment; segments sharing an
//! edge are chained. On a closed manifold mesh every polyline is closed; where the mesh has holes
//! (open scans) a chain ends at the hole and is reported as open.
//!
//! A plane that passes within a hair of a vertex cuts all of that vertex's crossed edges next to
//! it, and one across a sliver triangle cuts its two long edges side by side, so consecutive
//! points of a polyline can lie a millionth of the model apart. Such a pair is one point of the
//! section but two nearly equal rows in an interpolation system, whose condition it ruins once
//! the contour is traced more finely. A point closer to the last kept one than [`NEAR_CUT`] of
//! the shorter of their two edges is therefore dropped: this moves the polyline by at most that
//! share of the mesh's local edge length, far below what linear interpolation along the edges
//! resolves.

use std::collections::HashMap;

use glam::DVec3;

use super::TriMesh;

/// The polylines where a mesh meets a plane.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PlaneCut {
    /// Closed polylines (the last point joins the first), world coordinates.
    pub closed: Vec<Vec<[f64; 3]>>,
    /// Chains that end on the mesh's boundary (holes), in order.
    pub open: Vec<Vec<[f64; 3]>>,
    /// Points dropped as one with their predecessor (closer than [`NEAR_CUT`] of their edges).
    pub merged: usize,
}

/// Consecutive cuts closer than this share of the shorter of their two edges are one point.
pub const NEAR_CUT: f64 = 1e-2;

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
    // measured from the end in front of the plane, so that the crossing depends on the edge's
    // two points alone, not on how the file numbers them (a triangle soup cuts as its surface)
    let point = |(a, b): (u32, u32)| -> [f64; 3] {
        let (a, b) = if ahead(a) { (a, b) } else { (b, a) };
        let (pa, pb) = (mesh.vertices[a as usize], mesh.vertices[b as usize]);
        let t = s[a as usize] / (s[a as usize] - s[b as usize]);
        [pa[0] + t * (pb[0] - pa[0]), pa[1] + t * (pb[1] - pa[1]), pa[2] + t * (pb[2] - pa[2])]
    };
    let length = |(a, b): (u32, u32)| -> f64 {
        let (pa, pb) = (mesh.vertices[a as usize], mesh.vertices[b as usize]);
        DVec3::from(pa).distance(pb.into())
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
        let poly = thin_out(&edges, closed, &point, &length, &mut cut.merged);
        if closed {
            cut.closed.push(poly);
        } else {
            cut.open.push(poly);
        }
    }
    cut
}

/// The polyline through the cuts of `edges`, each point closer to the last kept one than
/// [`NEAR_CUT`] of the shorter of their edges left out (for a closed one also the last against
/// the first), counting them in `merged`; a polyline is never thinned below 3 points (2 open).
fn thin_out(
    edges: &[(u32, u32)],
    closed: bool,
    point: &dyn Fn((u32, u32)) -> [f64; 3],
    length: &dyn Fn((u32, u32)) -> f64,
    merged: &mut usize,
) -> Vec<[f64; 3]> {
    let all: Vec<[f64; 3]> = edges.iter().map(|&e| point(e)).collect();
    let near = |i: usize, j: usize| {
        DVec3::from(all[i]).distance(all[j].into()) < NEAR_CUT * length(edges[i]).min(length(edges[j]))
    };
    let mut keep: Vec<usize> = Vec::with_capacity(all.len());
    for i in 0..all.len() {
        if keep.last().is_some_and(|&k| near(k, i)) {
            continue;
        }
        keep.push(i);
    }
    while closed && keep.len() > 1 && near(keep[keep.len() - 1], keep[0]) {
        keep.pop();
    }
    let least = if closed { 3 } else { 2 };
    if keep.len() < least.min(all.len()) {
        return all;
    }
    *merged += all.len() - keep.len();
    keep.into_iter().map(|i| all[i]).collect()
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

    /// A tube of 24 vertices a ring, rings 0.1 apart from z = 0 to 1, open at both ends.
    fn tube() -> TriMesh {
        let (k, rings) = (24u32, 11u32);
        let vertices = (0..rings)
            .flat_map(|r| {
                (0..k).map(move |i| {
                    let a = std::f64::consts::TAU * i as f64 / k as f64;
                    [a.cos(), a.sin(), 0.1 * r as f64]
                })
            })
            .collect();
        let triangles = (0..rings - 1)
            .flat_map(|r| {
                (0..k).flat_map(move |i| {
                    let (a, b) = (r * k + i, r * k + (i + 1) % k);
                    [[a, b, b + k], [a, b + k, a + k]]
                })
            })
            .collect();
        TriMesh { vertices, triangles }
    }

    #[test]
    fn a_plane_grazing_vertices_cuts_each_once() {
        let m = tube();
        // between two rings: a vertical and a diagonal edge cut per vertex of a ring, all kept
        let clear = cut_by_plane(&m, [0.0, 0.0, 0.55], [0.0, 0.0, 1.0]);
        assert_eq!((clear.open.len(), clear.merged), (0, 0));
        assert_eq!(clear.closed[0].len(), 48);
        // a hair above the ring at 0.5: both cuts of each vertex lie 1e-8 of their edges from it
        let cut = cut_by_plane(&m, [0.0, 0.0, 0.5 + 1e-9], [0.0, 0.0, 1.0]);
        assert_eq!((cut.closed.len(), cut.merged), (1, 24));
        let c = &cut.closed[0];
        assert_eq!(c.len(), 24);
        // one point at each vertex of the ring
        let mut hit = vec![0; 24];
        for p in c {
            let at = m.vertices[5 * 24..6 * 24]
                .iter()
                .position(|v| DVec3::from(*v).distance((*p).into()) < 1e-7)
                .expect("at a vertex");
            hit[at] += 1;
        }
        assert!(hit.iter().all(|&h| h == 1), "{hit:?}");
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
