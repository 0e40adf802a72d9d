//! Curvature of reconstructed solids against known surfaces: a sphere reconstructed from points
//! on it (with an ellipsoid carrier, so that the spline has work to do) and a torus, through the
//! real binary: the PLY's vertex properties and the VTKHDF arrays written with `--curvature`, and
//! the analytic derivatives against the finite-difference defaults on a fitted model.

mod common;

use std::f64::consts::PI;
use std::path::Path;

use common::{run_ok, temp_dir, write_xyz};
use volspline::frep::{Implicit, ModelSolid};
use volspline::io::model_file::read_model;
use volspline::io::vtkhdf::read_image;

/// `n` points spread evenly over the sphere of radius `r` about the origin (a Fibonacci lattice).
fn sphere_points(n: usize, r: f64) -> Vec<f64> {
    let golden = PI * (3.0 - 5f64.sqrt());
    (0..n)
        .flat_map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let s = (1.0 - z * z).sqrt();
            let t = golden * i as f64;
            [r * s * t.cos(), r * s * t.sin(), r * z]
        })
        .collect()
}

const BIG: f64 = 2.0;
const SMALL: f64 = 0.7;

/// Points on the torus about the z axis with radii BIG and SMALL, on staggered rings.
fn torus_points() -> Vec<f64> {
    let mut pts = Vec::new();
    for i in 0..72 {
        for j in 0..24 {
            let u = 2.0 * PI * (i as f64 + 0.5 * (j % 2) as f64) / 72.0;
            let v = 2.0 * PI * j as f64 / 24.0;
            let rho = BIG + SMALL * v.cos();
            pts.extend([rho * u.cos(), rho * u.sin(), SMALL * v.sin()]);
        }
    }
    pts
}

/// The vertices of a binary PLY written by volspline with the named float properties.
fn ply_vertices(path: &Path, names: &[&str]) -> (Vec<[f64; 3]>, Vec<Vec<f64>>) {
    let bytes = std::fs::read(path).unwrap();
    let marker = b"end_header\n";
    let end = bytes.windows(marker.len()).position(|w| w == marker).unwrap() + marker.len();
    let header = std::str::from_utf8(&bytes[..end]).unwrap();
    let n: usize = header.lines().find_map(|l| l.strip_prefix("element vertex ")).unwrap().parse().unwrap();
    let floats: Vec<&str> = header.lines().filter_map(|l| l.strip_prefix("property float ")).collect();
    let record = 24 + 4 * floats.len();
    let mut pos = Vec::with_capacity(n);
    let mut props = vec![Vec::with_capacity(n); names.len()];
    for v in 0..n {
        let rec = &bytes[end + v * record..end + (v + 1) * record];
        pos.push(std::array::from_fn(|d| f64::from_le_bytes(rec[8 * d..8 * d + 8].try_into().unwrap())));
        for (p, name) in names.iter().enumerate() {
            let k = floats.iter().position(|f| f == name).unwrap_or_else(|| panic!("no property {name}"));
            let o = 24 + 4 * k;
            props[p].push(f32::from_le_bytes(rec[o..o + 4].try_into().unwrap()) as f64);
        }
    }
    (pos, props)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

#[test]
fn a_reconstructed_sphere_has_curvature_one_over_its_radius() {
    let dir = temp_dir("curv-sphere");
    let r = 2.0;
    let input = dir.join("sphere.xyz");
    write_xyz(&input, &sphere_points(600, r));
    let out = dir.join("s");
    let out_s = out.to_str().unwrap();
    let carrier = "ellipsoid:0,0,0,3,2.5,2.2";
    run_ok(
        2,
        &[
            "fit",
            input.to_str().unwrap(),
            "--out",
            out_s,
            "--kernel",
            "r",
            "--carrier",
            carrier,
            "--grid",
            "32",
            "--curvature",
            "--no-preview",
        ],
    );
    let (pos, props) = ply_vertices(&dir.join("s.ply"), &["mean_curvature", "gaussian_curvature"]);
    assert!(pos.len() > 500);
    let mean = median(props[0].iter().map(|m| m * r).collect());
    let gauss = median(props[1].iter().map(|k| k * r * r).collect());
    assert!((mean - 1.0).abs() < 0.02, "median mean curvature * R = {mean}");
    assert!((gauss - 1.0).abs() < 0.02, "median Gaussian curvature * R^2 = {gauss}");

    // the trimmed surface keeps each kept vertex's curvatures (a small factor leaves some out: the
    // sphere's even samples leave no gap deeper than 0.6 of their spacing, so at 0.3 the surface
    // between them is one region that reaches twice as far, and goes)
    let model = dir.join("s.model.h5");
    let trim = dir.join("trim");
    let t = trim.to_str().unwrap();
    run_ok(1, &["eval", model.to_str().unwrap(), "--out", t, "--grid", "32", "--curvature", "--trim", "0.3"]);
    let names = ["mean_curvature", "gaussian_curvature"];
    let (all, all_props) = ply_vertices(&dir.join("trim.ply"), &names);
    let (kept, kept_props) = ply_vertices(&dir.join("trim.trimmed.ply"), &names);
    assert!(!kept.is_empty() && kept.len() < all.len(), "{} of {} vertices kept", kept.len(), all.len());
    let key = |p: &[f64; 3]| p.map(f64::to_bits);
    let at: std::collections::HashMap<[u64; 3], usize> =
        all.iter().enumerate().map(|(i, p)| (key(p), i)).collect();
    for (k, p) in kept.iter().enumerate() {
        let i = at[&key(p)];
        assert_eq!((kept_props[0][k], kept_props[1][k]), (all_props[0][i], all_props[1][i]), "vertex {p:?}");
    }

    // the volume arrays: near the sphere the level surfaces are nearly spheres through each node
    let (grid, m) = read_image(&dir.join("s.hdf"), "mean_curvature").unwrap();
    let (_, k) = read_image(&dir.join("s.hdf"), "gaussian_curvature").unwrap();
    let (_, f) = read_image(&dir.join("s.hdf"), "f").unwrap();
    assert_eq!((m.len(), k.len()), (f.len(), f.len()));
    let [nx, ny, _] = grid.dims;
    let mut near = Vec::new();
    for (q, (&mq, &kq)) in m.iter().zip(&k).enumerate() {
        let p = grid.node(q % nx, (q / nx) % ny, q / (nx * ny));
        let d = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
        if (d - r).abs() < 0.5 * grid.spacing[0] {
            near.push((mq * d, kq * d * d));
        }
    }
    assert!(near.len() > 100);
    let mean = median(near.iter().map(|v| v.0).collect());
    let gauss = median(near.iter().map(|v| v.1).collect());
    assert!((mean - 1.0).abs() < 0.05 && (gauss - 1.0).abs() < 0.1, "nodes: {mean}, {gauss}");
}

#[test]
fn a_reconstructed_torus_has_its_known_curvatures() {
    let dir = temp_dir("curv-torus");
    let input = dir.join("torus.xyz");
    write_xyz(&input, &torus_points());
    let out = dir.join("t");
    // r^3 is C^2 (r has a cone at every centre); the carrier must not be a quadric for m = 3
    let carrier = "union(ball:-1,0,0,2.5,ball:1,0,0,2.5)";
    run_ok(
        2,
        &[
            "fit",
            input.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--kernel",
            "r3",
            "--carrier",
            carrier,
            "--grid",
            "40",
            "--curvature",
            "--no-preview",
        ],
    );
    // which side the reconstruction calls inside decides the sign of the mean curvature
    let model = read_model(&dir.join("t.model.h5")).unwrap();
    let side = model.eval(&[BIG, 0.0, 0.0]).signum();
    let (pos, props) = ply_vertices(&dir.join("t.ply"), &["mean_curvature", "gaussian_curvature"]);
    let (mut mean_err, mut gauss_err) = (Vec::new(), Vec::new());
    for (p, (m, k)) in pos.iter().zip(props[0].iter().zip(&props[1])) {
        let rho = (p[0] * p[0] + p[1] * p[1]).sqrt();
        let v = p[2].atan2(rho - BIG);
        let ring = BIG + SMALL * v.cos();
        let want_k = v.cos() / (SMALL * ring);
        let want_m = side * (BIG + 2.0 * SMALL * v.cos()) / (2.0 * SMALL * ring);
        mean_err.push((m - want_m).abs() / want_m.abs());
        gauss_err.push((k - want_k).abs() * SMALL * (BIG - SMALL));
    }
    assert!(pos.len() > 2000);
    let (em, ek) = (median(mean_err), median(gauss_err));
    assert!(em < 0.02 && ek < 0.02, "median relative error of the mean curvature {em}, of the Gaussian {ek}");
}

#[test]
fn analytic_derivatives_of_a_fit_match_finite_differences() {
    let dir = temp_dir("curv-derivs");
    let input = dir.join("torus.xyz");
    write_xyz(&input, &torus_points());
    for (kernel, carrier) in [
        ("r", "ball"),
        ("r3", "union(ball:-1,0,0,2.5,ball:1,0,0,2.5)"),
        ("wendland2", "ellipsoid:0,0,0,3,3,1.5"),
    ] {
        let out = dir.join(kernel);
        run_ok(
            1,
            &[
                "fit",
                input.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
                "--kernel",
                kernel,
                "--carrier",
                carrier,
                "--grid",
                "12",
                "--no-preview",
                // the data alone: off-surface pairs a few thousandths apart carry large opposite
                // weights, whose cancellation the finite differences (not the analytic sums) lose
                "--surface",
                "carrier",
            ],
        );
        let model = read_model(&dir.join(format!("{kernel}.model.h5"))).unwrap();
        let fast = ModelSolid::new(model.clone());
        /// the finite-difference defaults of the trait, for comparison
        struct Plain<'a>(&'a volspline::spline::Model);
        impl Implicit for Plain<'_> {
            fn value(&self, p: [f64; 3]) -> f64 {
                self.0.eval(&p)
            }
            fn bounds(&self) -> ([f64; 3], [f64; 3]) {
                self.0.bounds()
            }
        }
        let plain = Plain(&model);
        let mut worst = (0.0f64, 0.0f64);
        for i in 0..40 {
            let a = 0.3 + i as f64 * 0.71;
            let p = [
                (BIG + 0.8 * SMALL * a.cos()) * (1.3 * a).cos(),
                (BIG + 0.8 * SMALL * a.cos()) * (1.3 * a).sin(),
                0.8 * SMALL * a.sin(),
            ];
            let (g, h) = (fast.gradient(p), fast.hessian(p));
            let (gm, hm) = (model.gradient(p), model.hessian(p));
            let (gf, hf) = (plain.gradient(p), plain.hessian(p));
            let gs = g.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let hs = h.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
            for d in 0..3 {
                assert!((g[d] - gm[d]).abs() <= 1e-9 * gs, "{kernel}: fast and plain gradients differ");
                worst.0 = worst.0.max((g[d] - gf[d]).abs() / gs);
                for e in 0..3 {
                    assert!(
                        (h[d][e] - hm[d][e]).abs() <= 1e-9 * hs,
                        "{kernel}: fast and plain Hessians differ"
                    );
                    worst.1 = worst.1.max((h[d][e] - hf[d][e]).abs() / hs);
                }
            }
        }
        assert!(
            worst.0 < 1e-6 && worst.1 < 1e-3,
            "{kernel}: relative differences to finite differences {worst:?}"
        );
    }
}

#[test]
fn morph_frames_carry_the_curvature_arrays() {
    // the first frame of a metamorphosis of two balls is the first ball, f = r^2 - |x - c|^2,
    // whose level surface through a node at distance d from c is the sphere of radius d: mean
    // curvature 1/d and Gaussian 1/d^2 at every node, and on the mesh's vertices (d = r)
    let dir = temp_dir("curv-morph");
    let out = dir.join("m");
    for ranks in [1, 2] {
        run_ok(
            ranks,
            &[
                "morph",
                "ball:-2,10,0,8",
                "ball:4,12,0,8",
                "--out",
                out.to_str().unwrap(),
                "--frames",
                "2",
                "--grid",
                "24",
                "--curvature",
            ],
        );
        let frame = dir.join("m_000.hdf");
        let (grid, m) = read_image(&frame, "mean_curvature").unwrap();
        let (_, k) = read_image(&frame, "gaussian_curvature").unwrap();
        let [nx, ny, _] = grid.dims;
        let mut checked = 0;
        for (q, (&mq, &kq)) in m.iter().zip(&k).enumerate() {
            let p = grid.node(q % nx, (q / nx) % ny, q / (nx * ny));
            let d = ((p[0] + 2.0).powi(2) + (p[1] - 10.0).powi(2) + p[2] * p[2]).sqrt();
            if d > 1.0 {
                assert!((mq * d - 1.0).abs() < 1e-6 && (kq * d * d - 1.0).abs() < 1e-6, "{p:?}: {mq}, {kq}");
                checked += 1;
            }
        }
        assert!(checked > 5_000, "{checked}");
        let (pos, props) = ply_vertices(&dir.join("m_000.ply"), &["mean_curvature", "gaussian_curvature"]);
        assert!(pos.len() > 100, "{ranks} ranks");
        for (p, m) in pos.iter().zip(&props[0]) {
            let d = ((p[0] + 2.0).powi(2) + (p[1] - 10.0).powi(2) + p[2] * p[2]).sqrt();
            assert!((m * d - 1.0).abs() < 1e-6, "{ranks} ranks, vertex {p:?}: {m}");
        }
    }
}
