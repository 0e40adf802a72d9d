//! Meshes as files hold them, made fit for cutting: [`indexed`] joins vertices written more than
//! once at the same place and leaves out faces that then repeat or collapse.
//!
//! A plane cut chains the segments of neighbouring triangles through the edges they share, and
//! an edge is shared only where both triangles name the same two vertex indices. Files often do
//! not: a triangle soup (PLY and OBJ exports that give every face its own three vertices) shares
//! no index at all, so every segment would be a chain of its own, ending on a "hole"; a surface
//! exported double-sided holds every face twice, once each way round, so each edge has four
//! segments and a walk round a section goes round it twice. Joining vertices of equal
//! coordinates (-0 and 0 alike: where a file repeats a vertex it writes the same digits) and
//! keeping one face of each set of three vertices, whichever way round, gives the mesh the
//! sharing its surface has; a face whose corners join into fewer than three vertices has no
//! area and is left out. Vertices that only nearly coincide are left apart: joining them would
//! need a tolerance, and the cut's own merging of near points handles what they leave.

use std::collections::{HashMap, HashSet};

use super::TriMesh;

/// What [`indexed`] changed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Indexing {
    /// Vertices at the same coordinates as an earlier one, joined with it.
    pub joined_vertices: usize,
    /// Faces over the same three vertices as an earlier one (either way round), left out.
    pub repeated_faces: usize,
    /// Faces with fewer than three distinct vertices after the joining, left out.
    pub collapsed_faces: usize,
}

/// `mesh` with vertices of equal coordinates joined (the first one kept, in file order) and
/// the faces that then repeat an earlier face or collapse left out; the faces kept keep their
/// order and orientation. Vertices no face uses stay (they do not meet a plane's cut).
pub fn indexed(mesh: &TriMesh) -> (TriMesh, Indexing) {
    let mut first: HashMap<[u64; 3], u32> = HashMap::with_capacity(mesh.vertices.len());
    let mut vertices = Vec::with_capacity(mesh.vertices.len());
    let remap: Vec<u32> = mesh
        .vertices
        .iter()
        .map(|p| {
            let key = p.map(|c| (c + 0.0).to_bits());
            *first.entry(key).or_insert_with(|| {
                vertices.push(*p);
                (vertices.len() - 1) as u32
            })
        })
        .collect();
    let joined = mesh.vertices.len() - vertices.len();
    let mut seen: HashSet<[u32; 3]> = HashSet::with_capacity(mesh.triangles.len());
    let mut out = Indexing { joined_vertices: joined, ..Default::default() };
    let mut triangles = Vec::with_capacity(mesh.triangles.len());
    for t in &mesh.triangles {
        let t = t.map(|v| remap.get(v as usize).copied().unwrap_or(v));
        if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
            out.collapsed_faces += 1;
            continue;
        }
        let mut key = t;
        key.sort_unstable();
        if !seen.insert(key) {
            out.repeated_faces += 1;
            continue;
        }
        triangles.push(t);
    }
    (TriMesh { vertices, triangles }, out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A tetrahedron's four vertices and faces.
    fn tetra() -> TriMesh {
        TriMesh {
            vertices: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            triangles: vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]],
        }
    }

    #[test]
    fn a_clean_mesh_is_kept_as_it_is() {
        let m = tetra();
        assert_eq!(indexed(&m), (m, Indexing::default()));
    }

    #[test]
    fn a_soup_shares_its_corners_and_double_faces_count_once() {
        let m = tetra();
        // every face its own corners, one of them written as -0
        let mut soup = TriMesh::default();
        for t in &m.triangles {
            let base = soup.vertices.len() as u32;
            soup.vertices.extend(t.map(|v| m.vertices[v as usize]));
            soup.triangles.push([base, base + 1, base + 2]);
        }
        soup.vertices[0] = [-0.0, 0.0, -0.0];
        let (got, how) = indexed(&soup);
        assert_eq!(how, Indexing { joined_vertices: 8, repeated_faces: 0, collapsed_faces: 0 });
        assert_eq!(got.vertices.len(), 4);
        assert!(super::super::is_closed_manifold_edges(&got));
        // double-sided: every face again the other way round, and one face whose corners coincide
        let mut double = m.clone();
        double.triangles.extend(m.triangles.iter().map(|t| [t[2], t[1], t[0]]));
        double.vertices.push([1.0, 0.0, 0.0]);
        double.triangles.push([1, 4, 2]);
        let (got, how) = indexed(&double);
        assert_eq!(how, Indexing { joined_vertices: 1, repeated_faces: 4, collapsed_faces: 1 });
        assert_eq!(got.triangles, m.triangles);
    }
}
