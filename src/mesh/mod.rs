//! Surface extraction and mesh utilities for the `f = iso` level set.
//!
//! This module owns everything that happens after the implicit function has been
//! sampled on the grid: per-slab marching cubes ([`polygonise`]), welding of the
//! per-rank pieces into one deterministic mesh ([`weld()`]), PLY output
//! ([`write_ply`]), exact point-to-mesh distances ([`point_mesh_distances`]) and
//! topological checks ([`connected_components`], [`is_closed_manifold_edges`],
//! [`signed_volume`]), plane cuts into polylines ([`cut_by_plane`]) of meshes as files hold them
//! ([`clean::indexed`]) and trimming ([`trim::trim_regions`]).
//!
//! Conventions shared by all submodules:
//! - grid values are stored x fastest: `index = i + nx * (j + ny * k)`, node
//!   `(i, j, k)` sits at `origin + (i * sx, j * sy, k * sz)`;
//! - a node is inside when `value >= iso`; NaN values count as outside;
//! - triangles are oriented so that `(b - a) x (c - a)` points out of the solid
//!   (towards decreasing values), which makes [`signed_volume`] positive.

mod cases;
pub mod clean;
pub mod distance;
pub mod marching_cubes;
pub mod ply;
pub mod slice;
pub mod topology;
pub mod trim;
pub mod weld;

pub use distance::point_mesh_distances;
pub use marching_cubes::{polygonise, MeshPiece, SlabGrid};
pub use ply::{write_ply, write_ply_to, write_ply_with, VertexProperty};
pub use slice::{cut_by_plane, PlaneCut, NEAR_CUT};
pub use topology::{connected_components, euler_characteristic, is_closed_manifold_edges, signed_volume};
pub use weld::weld;

/// An indexed triangle mesh; triangles index into `vertices`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriMesh {
    pub vertices: Vec<[f64; 3]>,
    pub triangles: Vec<[u32; 3]>,
}

#[cfg(test)]
pub(crate) mod testutil {
    //! Helpers shared by the tests of the mesh submodules.

    use super::{polygonise, weld, SlabGrid, TriMesh};

    /// Tiny deterministic generator so tests do not need a dependency.
    pub struct Lcg(pub u64);

    impl Lcg {
        pub fn next_u64(&mut self) -> u64 {
            self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            self.0
        }

        /// Uniform in [0, 1).
        pub fn unit(&mut self) -> f64 {
            (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
        }

        pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
            lo + (hi - lo) * self.unit()
        }
    }

    pub struct Grid {
        pub values: Vec<f64>,
        pub n: [usize; 3],
        pub origin: [f64; 3],
        pub spacing: [f64; 3],
    }

    impl Grid {
        pub fn node(&self, i: usize, j: usize, k: usize) -> [f64; 3] {
            [
                self.origin[0] + i as f64 * self.spacing[0],
                self.origin[1] + j as f64 * self.spacing[1],
                self.origin[2] + k as f64 * self.spacing[2],
            ]
        }
    }

    /// Samples `f` on an `n^3` grid covering `[lo, hi]^3`.
    pub fn sample(n: usize, lo: f64, hi: f64, f: impl Fn([f64; 3]) -> f64) -> Grid {
        let h = (hi - lo) / (n - 1) as f64;
        let mut g =
            Grid { values: Vec::with_capacity(n * n * n), n: [n; 3], origin: [lo; 3], spacing: [h; 3] };
        for k in 0..n {
            for j in 0..n {
                for i in 0..n {
                    let p = g.node(i, j, k);
                    g.values.push(f(p));
                }
            }
        }
        g
    }

    /// Polygonises `g` split into `slabs` z-slabs (each with its ghost layer)
    /// and welds the pieces, as the MPI driver would.
    pub fn mesh_in_slabs(g: &Grid, iso: f64, slabs: usize) -> TriMesh {
        let [nx, ny, nz] = g.n;
        let plane = nx * ny;
        let pieces: Vec<_> = (0..slabs)
            .map(|r| {
                let k0 = r * nz / slabs;
                let k1 = (r + 1) * nz / slabs;
                let end = (k1 + 1).min(nz);
                polygonise(
                    &SlabGrid {
                        values: &g.values[k0 * plane..end * plane],
                        nx,
                        ny,
                        nz,
                        k0,
                        layers: k1 - k0,
                        origin: g.origin,
                        spacing: g.spacing,
                    },
                    iso,
                )
            })
            .collect();
        weld(&pieces)
    }

    pub fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
        [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
    }

    pub fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
        [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    }

    pub fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
        a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
    }

    pub fn norm(a: [f64; 3]) -> f64 {
        dot(a, a).sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::testutil::{mesh_in_slabs, sample};
    use super::*;

    /// End to end: polygonise, weld, check, measure and write one mesh.
    #[test]
    fn pipeline_end_to_end() {
        let r = 0.6;
        let g = sample(32, -1.0, 1.0, |p| r * r - (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]));
        let m = mesh_in_slabs(&g, 0.0, 4);
        assert!(!m.triangles.is_empty());
        assert!(is_closed_manifold_edges(&m));
        assert_eq!(connected_components(&m), 1);
        assert_eq!(euler_characteristic(&m), 2);
        let v = signed_volume(&m);
        let exact = 4.0 / 3.0 * std::f64::consts::PI * r * r * r;
        assert!((v - exact).abs() < 0.02 * exact, "{v} vs {exact}");
        let d = point_mesh_distances(&m, &[[0.0, 0.0, 0.0], [2.0, 0.0, 0.0]]);
        assert!((d[0] - r).abs() < 1e-2 && (d[1] - (2.0 - r)).abs() < 1e-2, "{d:?}");
        let mut buf = Vec::new();
        write_ply_to(&mut buf, &m).unwrap();
        assert!(buf.len() > m.vertices.len() * 24 + m.triangles.len() * 13);
    }
}
