//! Reconstruction quality on real data: fit a quarter of the bunny's vertices on 2 ranks and
//! measure, relative to the bounding-box diagonal, (1) the distance from the held-out vertices to
//! the reconstructed mesh (completeness) and (2) the distance from the mesh to the true bunny
//! surface (spurious surface: with a ball carrier the zero set can bulge into extra sheets and
//! blobs away from the data where the scan is open or deeply concave), for the plain carrier method
//! and for the default off-surface constraints. The bounds are the measured figures with a small
//! allowance; README.md reports them.

mod common;

use std::path::Path;

use volspline::mesh::{connected_components, is_closed_manifold_edges, point_mesh_distances, TriMesh};

/// (mean, 95th percentile, maximum) of distances.
type Stats = (f64, f64, f64);

/// Fits every fourth bunny vertex on 2 ranks, grid 96, with `extra` arguments; returns the
/// (mean, p95, max) distances held-out -> mesh and mesh -> bunny as fractions of the diagonal, the
/// fraction of mesh vertices farther than 2 % of the diagonal from the bunny, and the mesh.
fn quarter_bunny(name: &str, extra: &[&str]) -> (Stats, Stats, f64, TriMesh) {
    let dir = common::temp_dir(name);
    let all = common::bunny();
    let fit: Vec<f64> = all.chunks_exact(3).step_by(4).flatten().copied().collect();
    let held: Vec<[f64; 3]> = all
        .chunks_exact(3)
        .enumerate()
        .filter(|(i, _)| i % 4 != 0)
        .map(|(_, p)| [p[0], p[1], p[2]])
        .collect();
    let input = dir.join("quarter.xyz");
    common::write_xyz(&input, &fit);
    let prefix = dir.join("q");
    let mut args = vec!["fit", input.to_str().unwrap(), "--out", prefix.to_str().unwrap(), "--grid", "96"];
    args.extend_from_slice(extra);
    common::run_ok(2, &args);
    let mesh = common::load_mesh(&dir.join("q.ply"));
    let truth = common::load_mesh(Path::new(common::BUNNY));
    let (lo, hi) = volspline::spline::hygiene::bounding_box(&all, 3);
    let diag = volspline::spline::hygiene::diagonal(&lo, &hi);
    let to_truth = point_mesh_distances(&truth, &mesh.vertices);
    let beyond = to_truth.iter().filter(|&&d| d > 0.02 * diag).count() as f64 / to_truth.len() as f64;
    let c = common::distance_stats(point_mesh_distances(&mesh, &held), diag);
    let s = common::distance_stats(to_truth, diag);
    println!(
        "bunny {name}, {} of {} vertices fitted, grid 96: held-out -> mesh mean {:.5} p95 {:.5} max {:.5}; \
         mesh -> bunny mean {:.5} p95 {:.5} max {:.5} (fractions of the diagonal {diag:.3}), {:.4} of the \
         vertices beyond 2 %; {} triangles, {} components",
        fit.len() / 3,
        all.len() / 3,
        c.0,
        c.1,
        c.2,
        s.0,
        s.1,
        s.2,
        beyond,
        mesh.triangles.len(),
        connected_components(&mesh)
    );
    assert!(is_closed_manifold_edges(&mesh), "the mesh must be closed and consistently oriented");
    (c, s, beyond, mesh)
}

#[test]
fn held_out_bunny_vertices_lie_on_the_reconstruction() {
    let ((c_mean, c_p95, c_max), (s_mean, s_p95, s_max), _, _) =
        quarter_bunny("quality", &["--surface", "carrier"]);
    // measured (2 ranks, grid 96, householder): completeness mean 0.0037, p95 0.0126, max 0.0349;
    // mesh -> bunny mean 0.0201, p95 0.104, max 0.188 (the open base of the scan is closed by
    // sheets away from the data, and small spurious blobs appear: the known weakness of a ball
    // carrier, which decides inside and outside wherever no data point does)
    assert!(c_mean < 0.0045 && c_p95 < 0.015 && c_max < 0.045, "completeness {c_mean} {c_p95} {c_max}");
    assert!(s_mean < 0.025 && s_p95 < 0.12, "spurious surface {s_mean} {s_p95} {s_max}");
}

#[test]
fn off_surface_constraints_remove_the_spurious_surface() {
    let ((c_mean, c_p95, c_max), (s_mean, s_p95, s_max), beyond, mesh) = quarter_bunny("quality-off", &[]);
    // measured (2 ranks, grid 96, the default --surface auto = offsurface, with the former default
    // of 0.4 off points for every point): completeness mean 0.00242, p95 0.0069, max 0.0269; mesh
    // -> bunny mean 0.00219, p95 0.0072, max 0.035, 1.2 % of the vertices beyond 2 % of the
    // diagonal, one component (the plain method: 0.020, 0.104, 0.188, 26 %, 3 components)
    assert_eq!(connected_components(&mesh), 1, "extra components");
    assert!(c_mean < 0.003 && c_p95 < 0.009 && c_max < 0.035, "completeness {c_mean} {c_p95} {c_max}");
    assert!(
        s_mean < 0.003 && s_p95 < 0.01 && beyond < 0.02,
        "spurious surface {s_mean} {s_p95} {s_max} {beyond}"
    );
}
