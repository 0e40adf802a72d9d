//! Topological and integral checks on a [`TriMesh`]: connected components,
//! closed consistently oriented edge-manifoldness, Euler characteristic and the
//! enclosed signed volume.
//!
//! Triangles with an index outside `vertices` are ignored by the counting
//! functions and make [`is_closed_manifold_edges`] false.

use super::TriMesh;

fn valid_triangles(mesh: &TriMesh) -> impl Iterator<Item = [u32; 3]> + '_ {
    let n = mesh.vertices.len();
    mesh.triangles.iter().copied().filter(move |t| t.iter().all(|&v| (v as usize) < n))
}

/// Number of connected components, two triangles being connected when they
/// share a vertex. Vertices used by no triangle are not counted.
pub fn connected_components(mesh: &TriMesh) -> usize {
    let n = mesh.vertices.len();
    let mut used = vec![false; n];
    for t in valid_triangles(mesh) {
        for &v in &t {
            used[v as usize] = true;
        }
    }
    let edges =
        valid_triangles(mesh).flat_map(|t| [(t[0] as usize, t[1] as usize), (t[0] as usize, t[2] as usize)]);
    let (label, _) = crate::graph::components(n, edges);
    let mut seen = vec![false; n];
    (0..n).filter(|&v| used[v] && !std::mem::replace(&mut seen[label[v]], true)).count()
}

/// True when every undirected edge is used by exactly two triangles, once in
/// each direction (closed, edge-manifold, consistently oriented). Degenerate
/// triangles or out-of-range indices make it false; an empty mesh is
/// (vacuously) closed.
pub fn is_closed_manifold_edges(mesh: &TriMesh) -> bool {
    let n = mesh.vertices.len();
    let mut dir: Vec<(u32, u32)> = Vec::with_capacity(3 * mesh.triangles.len());
    for &[a, b, c] in &mesh.triangles {
        if [a, b, c].iter().any(|&v| v as usize >= n) || a == b || b == c || a == c {
            return false;
        }
        dir.extend([(a, b), (b, c), (c, a)]);
    }
    dir.sort_unstable();
    if dir.windows(2).any(|w| w[0] == w[1]) {
        return false;
    }
    // No directed edge repeats, so finding each reverse once means every
    // undirected edge has exactly one use per direction.
    dir.iter().all(|&(a, b)| dir.binary_search(&(b, a)).is_ok())
}

/// `V - E + F` over the vertices used by triangles and the distinct undirected
/// edges; 2 per sphere-like closed component, 0 for a torus.
pub fn euler_characteristic(mesh: &TriMesh) -> i64 {
    let mut edges: Vec<(u32, u32)> = Vec::new();
    let mut used = vec![false; mesh.vertices.len()];
    let mut faces = 0i64;
    for t in valid_triangles(mesh) {
        faces += 1;
        for s in 0..3 {
            let (a, b) = (t[s], t[(s + 1) % 3]);
            used[a as usize] = true;
            edges.push(if a < b { (a, b) } else { (b, a) });
        }
    }
    edges.sort_unstable();
    edges.dedup();
    let v = used.iter().filter(|&&u| u).count() as i64;
    v - edges.len() as i64 + faces
}

/// Enclosed volume by the divergence theorem; positive when triangles are
/// oriented outward.
///
/// Tetrahedra are taken from the centre of the vertex bounding box rather than
/// the origin: for a closed mesh the result is the same, but a mesh far from
/// the origin does not lose its digits to cancellation.
pub fn signed_volume(mesh: &TriMesh) -> f64 {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in &mesh.vertices {
        for a in 0..3 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    let r: [f64; 3] = std::array::from_fn(|a| {
        let c = 0.5 * (lo[a] + hi[a]);
        if c.is_finite() {
            c
        } else {
            0.0
        }
    });
    let mut six_v = 0.0;
    for t in valid_triangles(mesh) {
        let [a, b, c] = t.map(|v| {
            let p = mesh.vertices[v as usize];
            [p[0] - r[0], p[1] - r[1], p[2] - r[2]]
        });
        six_v += a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
            + a[2] * (b[0] * c[1] - b[1] * c[0]);
    }
    six_v / 6.0
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Unit cube with outward triangles, shifted by `o`.
    fn cube(o: [f64; 3]) -> TriMesh {
        let vertices = (0..8)
            .map(|c| [o[0] + (c & 1) as f64, o[1] + (c >> 1 & 1) as f64, o[2] + (c >> 2 & 1) as f64])
            .collect();
        let quads = [[0, 4, 6, 2], [1, 3, 7, 5], [0, 1, 5, 4], [2, 6, 7, 3], [0, 2, 3, 1], [4, 5, 7, 6]];
        let triangles = quads.iter().flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]]).collect();
        TriMesh { vertices, triangles }
    }

    #[test]
    fn cube_is_closed_with_unit_volume() {
        let m = cube([1e6, -3e6, 2e6]);
        assert!(is_closed_manifold_edges(&m));
        assert_eq!(connected_components(&m), 1);
        assert_eq!(euler_characteristic(&m), 2);
        assert!((signed_volume(&m) - 1.0).abs() < 1e-9);
    }

    #[test]
    fn checks_detect_defects() {
        let mut open = cube([0.0; 3]);
        open.triangles.pop();
        assert!(!is_closed_manifold_edges(&open));

        let mut flipped = cube([0.0; 3]);
        flipped.triangles[3].swap(1, 2);
        assert!(!is_closed_manifold_edges(&flipped));

        let mut inverted = cube([0.0; 3]);
        inverted.triangles.iter_mut().for_each(|t| t.swap(1, 2));
        assert!(is_closed_manifold_edges(&inverted));
        assert!((signed_volume(&inverted) + 1.0).abs() < 1e-12);

        let mut doubled = cube([0.0; 3]);
        let extra = doubled.triangles.clone();
        doubled.triangles.extend(extra);
        assert!(!is_closed_manifold_edges(&doubled));

        let mut bad = cube([0.0; 3]);
        bad.triangles.push([0, 1, 99]);
        assert!(!is_closed_manifold_edges(&bad));
        assert_eq!(connected_components(&bad), 1);
        bad.triangles.push([2, 2, 3]);
        assert!(!is_closed_manifold_edges(&bad));
    }

    #[test]
    fn components_count_separate_pieces() {
        let a = cube([0.0; 3]);
        let b = cube([5.0, 0.0, 0.0]);
        let mut m = a.clone();
        let off = m.vertices.len() as u32;
        m.vertices.extend(&b.vertices);
        m.triangles.extend(b.triangles.iter().map(|t| t.map(|v| v + off)));
        m.vertices.push([9.0; 3]); // unused vertex: not a component
        assert_eq!(connected_components(&m), 2);
        assert_eq!(euler_characteristic(&m), 4);
        assert!((signed_volume(&m) - 2.0).abs() < 1e-12);
        assert_eq!(connected_components(&TriMesh::default()), 0);
        assert!(is_closed_manifold_edges(&TriMesh::default()));
    }
}
