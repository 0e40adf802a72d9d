//! Reconstruction quality on real data: fit a quarter of the bunny's vertices on 2 ranks and
//! measure, relative to the bounding-box diagonal, (1) the distance from the held-out vertices to
//! the reconstructed mesh (completeness) and (2) the distance from the mesh to the true bunny
//! surface (spurious surface: with a ball carrier the zero set can bulge into extra sheets and
//! blobs away from the data where the scan is open or deeply concave). The bounds are the measured
//! figures with a small allowance; README.md reports them.

mod common;

use std::path::Path;

use volspline::mesh::{connected_components, is_closed_manifold_edges, point_mesh_distances};

#[test]
fn held_out_bunny_vertices_lie_on_the_reconstruction() {
    let dir = common::temp_dir("quality");
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
    common::run_ok(2, &["fit", input.to_str().unwrap(), "--out", prefix.to_str().unwrap(), "--grid", "96"]);
    let mesh = common::load_mesh(&dir.join("q.ply"));
    let truth = common::load_mesh(Path::new(common::BUNNY));
    let (lo, hi) = volspline::spline::hygiene::bounding_box(&all, 3);
    let diag = volspline::spline::hygiene::diagonal(&lo, &hi);

    let (c_mean, c_p95, c_max) = common::distance_stats(point_mesh_distances(&mesh, &held), diag);
    let (s_mean, s_p95, s_max) = common::distance_stats(point_mesh_distances(&truth, &mesh.vertices), diag);
    println!(
        "bunny, {} of {} vertices fitted, grid 96: held-out -> mesh mean {c_mean:.5} p95 {c_p95:.5} max {c_max:.5}; \
         mesh -> bunny mean {s_mean:.5} p95 {s_p95:.5} max {s_max:.5} (fractions of the diagonal {diag:.3}); \
         {} triangles, {} components",
        fit.len() / 3,
        all.len() / 3,
        mesh.triangles.len(),
        connected_components(&mesh)
    );
    assert!(is_closed_manifold_edges(&mesh), "the mesh must be closed and consistently oriented");
    // measured (2 ranks, grid 96, householder): completeness mean 0.0037, p95 0.0126, max 0.0349;
    // mesh -> bunny mean 0.0201, p95 0.104, max 0.188 (the open base of the scan is closed by
    // sheets away from the data, and small spurious blobs appear: the known weakness of a ball
    // carrier, which decides inside and outside wherever no data point does)
    assert!(c_mean < 0.0045 && c_p95 < 0.015 && c_max < 0.045, "completeness {c_mean} {c_p95} {c_max}");
    assert!(s_mean < 0.025 && s_p95 < 0.12, "spurious surface {s_mean} {s_p95} {s_max}");
}
