//! Exact Euclidean distance from query points to a triangle set.
//!
//! Owns a bounding-volume hierarchy over the triangles (median splits, small
//! leaves) and the point-triangle closest-point routine. The BVH only prunes
//! with lower bounds, so results equal a brute-force minimum; queries run in
//! parallel with rayon and each one is independent, so the output does not
//! depend on the thread count.

use super::TriMesh;
use rayon::prelude::*;

type P = [f64; 3];

fn sub(a: P, b: P) -> P {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: P, b: P) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn axpy(a: P, s: f64, d: P) -> P {
    [a[0] + s * d[0], a[1] + s * d[1], a[2] + s * d[2]]
}

fn dist2(a: P, b: P) -> f64 {
    let d = sub(a, b);
    dot(d, d)
}

fn segment_dist2(p: P, a: P, b: P) -> f64 {
    let ab = sub(b, a);
    let len2 = dot(ab, ab);
    let t = if len2 > 0.0 { (dot(sub(p, a), ab) / len2).clamp(0.0, 1.0) } else { 0.0 };
    dist2(p, axpy(a, t, ab))
}

/// Squared distance from `p` to the (closed, solid) triangle `abc`.
///
/// Region classification after Ericson, *Real-Time Collision Detection* 5.1.5.
/// Its divisions are by squared edge lengths or the squared area, so they only
/// misbehave for degenerate triangles, which fall back to the three edges.
pub fn point_triangle_dist2(p: P, [a, b, c]: [P; 3]) -> f64 {
    let ab = sub(b, a);
    let ac = sub(c, a);
    let ap = sub(p, a);
    let d1 = dot(ab, ap);
    let d2 = dot(ac, ap);
    let q = 'closest: {
        if d1 <= 0.0 && d2 <= 0.0 {
            break 'closest a;
        }
        let bp = sub(p, b);
        let d3 = dot(ab, bp);
        let d4 = dot(ac, bp);
        if d3 >= 0.0 && d4 <= d3 {
            break 'closest b;
        }
        let vc = d1 * d4 - d3 * d2;
        if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
            break 'closest axpy(a, d1 / (d1 - d3), ab);
        }
        let cp = sub(p, c);
        let d5 = dot(ab, cp);
        let d6 = dot(ac, cp);
        if d6 >= 0.0 && d5 <= d6 {
            break 'closest c;
        }
        let vb = d5 * d2 - d1 * d6;
        if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
            break 'closest axpy(a, d2 / (d2 - d6), ac);
        }
        let va = d3 * d6 - d5 * d4;
        if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
            let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
            break 'closest axpy(b, w, sub(c, b));
        }
        let denom = va + vb + vc;
        axpy(axpy(a, vb / denom, ab), vc / denom, ac)
    };
    let d = dist2(p, q);
    if d.is_finite() || p.iter().any(|x| !x.is_finite()) {
        d
    } else {
        segment_dist2(p, a, b).min(segment_dist2(p, b, c)).min(segment_dist2(p, c, a))
    }
}

const LEAF: usize = 4;

struct Node {
    lo: P,
    hi: P,
    /// Leaf: first triangle in `Bvh::tris`; internal: index of the right child
    /// (the left child is the next node).
    first_or_right: u32,
    /// Number of triangles; 0 marks an internal node.
    count: u32,
}

struct Bvh {
    nodes: Vec<Node>,
    /// Triangle corners in leaf order, so a leaf reads contiguous memory.
    tris: Vec<[P; 3]>,
}

fn box_dist2(p: P, lo: P, hi: P) -> f64 {
    let mut s = 0.0;
    for a in 0..3 {
        let d = (lo[a] - p[a]).max(p[a] - hi[a]).max(0.0);
        s += d * d;
    }
    s
}

impl Bvh {
    fn build(mesh: &TriMesh) -> Bvh {
        let n = mesh.vertices.len();
        let mut items: Vec<([P; 3], P)> = mesh
            .triangles
            .iter()
            .filter(|t| t.iter().all(|&v| (v as usize) < n))
            .map(|t| {
                let c = t.map(|v| mesh.vertices[v as usize]);
                let centre = std::array::from_fn(|a| (c[0][a] + c[1][a] + c[2][a]) / 3.0);
                (c, centre)
            })
            .collect();
        let mut bvh = Bvh {
            nodes: Vec::with_capacity(2 * items.len() / LEAF + 1),
            tris: Vec::with_capacity(items.len()),
        };
        if !items.is_empty() {
            bvh.build_node(&mut items);
        }
        bvh
    }

    fn build_node(&mut self, items: &mut [([P; 3], P)]) -> u32 {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        let mut clo = [f64::INFINITY; 3];
        let mut chi = [f64::NEG_INFINITY; 3];
        for (t, c) in items.iter() {
            for a in 0..3 {
                for v in t {
                    lo[a] = lo[a].min(v[a]);
                    hi[a] = hi[a].max(v[a]);
                }
                clo[a] = clo[a].min(c[a]);
                chi[a] = chi[a].max(c[a]);
            }
        }
        let me = self.nodes.len();
        self.nodes.push(Node { lo, hi, first_or_right: self.tris.len() as u32, count: items.len() as u32 });
        if items.len() <= LEAF {
            self.tris.extend(items.iter().map(|(t, _)| *t));
            return me as u32;
        }
        let ext = [0, 1, 2].map(|a| chi[a] - clo[a]);
        let axis = if ext[0] >= ext[1] && ext[0] >= ext[2] {
            0
        } else if ext[1] >= ext[2] {
            1
        } else {
            2
        };
        // Median split keeps the depth logarithmic whatever the geometry.
        let mid = items.len() / 2;
        items.select_nth_unstable_by(mid, |x, y| x.1[axis].total_cmp(&y.1[axis]));
        let (left, right) = items.split_at_mut(mid);
        self.build_node(left);
        let r = self.build_node(right);
        self.nodes[me].first_or_right = r;
        self.nodes[me].count = 0;
        me as u32
    }

    fn distance(&self, p: P) -> f64 {
        if p.iter().any(|x| x.is_nan()) {
            return f64::NAN;
        }
        if self.nodes.is_empty() {
            return f64::INFINITY;
        }
        let mut best = f64::INFINITY;
        let mut stack: Vec<(u32, f64)> = Vec::with_capacity(64);
        stack.push((0, box_dist2(p, self.nodes[0].lo, self.nodes[0].hi)));
        while let Some((ni, bound)) = stack.pop() {
            if bound > best {
                continue;
            }
            let node = &self.nodes[ni as usize];
            if node.count > 0 {
                let first = node.first_or_right as usize;
                for t in &self.tris[first..first + node.count as usize] {
                    let d = point_triangle_dist2(p, *t);
                    if d < best {
                        best = d;
                    }
                }
            } else {
                let (l, r) = (ni + 1, node.first_or_right);
                let dl = box_dist2(p, self.nodes[l as usize].lo, self.nodes[l as usize].hi);
                let dr = box_dist2(p, self.nodes[r as usize].lo, self.nodes[r as usize].hi);
                // Nearer child on top of the stack: it tightens `best` first.
                if dl <= dr {
                    stack.push((r, dr));
                    stack.push((l, dl));
                } else {
                    stack.push((l, dl));
                    stack.push((r, dr));
                }
            }
        }
        best.sqrt()
    }
}

/// Exact Euclidean distance from each query to the nearest point of any
/// triangle of `mesh`.
///
/// Returns `+inf` for every query when the mesh has no (valid) triangle and NaN
/// for a query with a NaN coordinate. Triangles with out-of-range indices are
/// ignored.
pub fn point_mesh_distances(mesh: &TriMesh, queries: &[[f64; 3]]) -> Vec<f64> {
    let bvh = Bvh::build(mesh);
    queries.par_iter().map(|&q| bvh.distance(q)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::testutil::{mesh_in_slabs, sample, Lcg};

    fn brute(mesh: &TriMesh, p: P) -> f64 {
        mesh.triangles
            .iter()
            .map(|t| point_triangle_dist2(p, t.map(|v| mesh.vertices[v as usize])))
            .fold(f64::INFINITY, f64::min)
            .sqrt()
    }

    #[test]
    fn known_values() {
        let t = [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0]];
        let d = |p: P| point_triangle_dist2(p, t).sqrt();
        // Above the interior.
        assert!((d([0.5, 0.5, 3.0]) - 3.0).abs() < 1e-15);
        assert!((d([0.5, 0.5, -0.25]) - 0.25).abs() < 1e-15);
        // Beside edge a-b (below y = 0), beside the hypotenuse, and beside vertices.
        assert!((d([1.0, -3.0, 4.0]) - 5.0).abs() < 1e-15);
        assert!((d([2.0, 2.0, 0.0]) - 2f64.sqrt()).abs() < 1e-15);
        assert!((d([-1.0, -1.0, 1.0]) - 3f64.sqrt()).abs() < 1e-15);
        assert!((d([5.0, 0.0, 4.0]) - 5.0).abs() < 1e-15);
        assert!((d([0.0, 3.0, 0.0]) - 1.0).abs() < 1e-15);
        // On the triangle.
        assert_eq!(d([0.5, 0.5, 0.0]), 0.0);
        // Degenerate triangles: collinear and a single point.
        let line = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]];
        assert!((point_triangle_dist2([1.5, 3.0, 4.0], line).sqrt() - 5.0).abs() < 1e-15);
        let dot_tri = [[1.0, 1.0, 1.0]; 3];
        assert!((point_triangle_dist2([1.0, 4.0, 5.0], dot_tri).sqrt() - 5.0).abs() < 1e-15);

        let mesh = TriMesh { vertices: t.to_vec(), triangles: vec![[0, 1, 2]] };
        let got = point_mesh_distances(&mesh, &[[0.5, 0.5, 3.0], [1.0, -3.0, 4.0]]);
        assert_eq!(got, vec![3.0, 5.0]);
    }

    #[test]
    fn bvh_matches_brute_force() {
        let g = sample(24, -1.0, 1.0, |p| {
            let q = (p[0] * p[0] + p[1] * p[1]).sqrt() - 0.55;
            0.2 * 0.2 - (q * q + p[2] * p[2])
        });
        let mesh = mesh_in_slabs(&g, 0.0, 2);
        assert!(mesh.triangles.len() > 1000);
        let mut rng = Lcg(2024);
        let queries: Vec<P> = (0..400)
            .map(|i| {
                let s = if i % 4 == 0 { 5.0 } else { 1.2 };
                [rng.range(-s, s), rng.range(-s, s), rng.range(-s, s)]
            })
            .chain(mesh.vertices.iter().take(20).copied())
            .collect();
        let fast = point_mesh_distances(&mesh, &queries);
        for (q, f) in queries.iter().zip(&fast) {
            assert_eq!(*f, brute(&mesh, *q), "query {q:?}");
        }
        // A query exactly on a vertex is at distance zero.
        assert!(fast[400..].iter().all(|&d| d == 0.0));
    }

    #[test]
    fn empty_and_nan() {
        let empty = TriMesh::default();
        assert_eq!(point_mesh_distances(&empty, &[[0.0; 3]]), vec![f64::INFINITY]);
        let mesh = TriMesh {
            vertices: vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            triangles: vec![[0, 1, 2], [0, 1, 7]],
        };
        let d = point_mesh_distances(&mesh, &[[f64::NAN, 0.0, 0.0], [0.0, 0.0, 2.0]]);
        assert!(d[0].is_nan());
        assert_eq!(d[1], 2.0);
    }
}
