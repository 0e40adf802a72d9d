//! Compactly supported volume splines on real data (a bunny vertex subset), through the library:
//! the default support, the octree ordering, the sparse assembly of A and P, which together make
//! exactly the dense bordered system; its solution interpolates (f = f_c - U vanishes at the data
//! points, evaluated by the octree evaluator) and is negative far away; and the renumbered system
//! defines the same spline as the one in input order.

mod common;

use volspline::linalg::dense::lu_solve;
use volspline::linalg::sparse::SymCsr;
use volspline::spline::compact::{
    assemble_lower, default_support, envelope, permuted, poly_block, DEFAULT_NEIGHBOURS,
};
use volspline::spline::hygiene::prepare;
use volspline::spline::octree::DEFAULT_LEAF_CAPACITY;
use volspline::spline::{full_system, Carrier, Evaluator, Kernel, Model, Octree, Provenance, Spline};

/// The bordered matrix [A P; P^T 0] (column-major) from the lower triangle of A and P.
fn bordered(a: &SymCsr, p: &[f64]) -> Vec<f64> {
    let n = a.n;
    let nk = n + 4;
    let mut m = vec![0.0; nk * nk];
    for l in 0..a.rows.len() {
        let i = a.rows[l];
        for (j, v) in a.row(l) {
            m[j * nk + i] = v;
            m[i * nk + j] = v;
        }
    }
    for c in 0..4 {
        for i in 0..n {
            m[(n + c) * nk + i] = p[c * n + i];
            m[i * nk + n + c] = p[c * n + i];
        }
    }
    m
}

fn solve(kernel: &Kernel, centres: &[f64], values: &[f64]) -> Vec<f64> {
    let nk = values.len() + 4;
    let (m, b) = full_system(kernel, centres, values);
    lu_solve(faer::MatRef::from_column_major_slice(&m, nk, nk), &b).unwrap()
}

#[test]
fn the_sparse_system_is_the_dense_system_and_its_spline_interpolates() {
    let raw = common::bunny_subset(4, 0);
    // the kernel's support does not matter to the preparation: it only checks the linear part
    let prep = prepare(&raw, &Kernel::wendland("wendland2", 1.0).unwrap(), &Carrier::AutoBall, 1e-6).unwrap();
    let n = prep.values.len();
    let support = default_support(&prep.centres, DEFAULT_NEIGHBOURS);
    for name in ["wendland0", "wendland2", "wendland4"] {
        let kernel = Kernel::wendland(name, support).unwrap();
        let perm = Octree::new(&prep.centres, DEFAULT_LEAF_CAPACITY).order(support);
        let centres = permuted(&prep.centres, 3, &perm);
        let values = permuted(&prep.values, 1, &perm);
        let tree = Octree::new(&centres, DEFAULT_LEAF_CAPACITY);
        let rows: Vec<usize> = (0..n).collect();
        let (a, stats) = assemble_lower(&kernel, &centres, &tree, &rows).unwrap();
        let p = poly_block(&kernel, &centres, &rows);
        assert!(stats.mean > 0.5 * DEFAULT_NEIGHBOURS as f64 && stats.mean < 2.0 * DEFAULT_NEIGHBOURS as f64);
        let (dense, _) = full_system(&kernel, &centres, &values);
        assert!(bordered(&a, &p) == dense, "{name}: the sparse blocks differ from the dense system");
        let (a_input, _) =
            assemble_lower(&kernel, &prep.centres, &Octree::new(&prep.centres, 10), &rows).unwrap();
        assert!(envelope(&a) < envelope(&a_input) / 2);

        let x = solve(&kernel, &centres, &values);
        let model = Model {
            carrier: prep.carrier.clone(),
            spline: Spline::from_solution(kernel, centres.clone(), &x, prep.norm),
            coarse: Vec::new(),
            provenance: Provenance::default(),
        };
        let scale = values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let ev = Evaluator::new(&model.spline);
        for (q, pt) in prep.points.chunks_exact(3).enumerate() {
            let mut u = [0.0];
            ev.eval_row(&pt[..1], pt[1], pt[2], &mut u);
            let f = model.carrier.eval(pt) - u[0];
            assert!(f.abs() < 1e-8 * scale, "{name}: f = {f} at point {q}");
        }
        // far from the data U is its linear part and the ball carrier wins
        let (lo, hi) = (&prep.box_lo, &prep.box_hi);
        for c in 0..8 {
            let far: Vec<f64> = (0..3)
                .map(|d| if c >> d & 1 == 1 { 2.0 * hi[d] - lo[d] } else { 2.0 * lo[d] - hi[d] })
                .collect();
            assert!(model.eval(&far) < 0.0, "{name}: f >= 0 at {far:?}");
        }

        // the same spline, solved in input order
        let y = solve(&kernel, &prep.centres, &prep.values);
        let other = Spline::from_solution(kernel, prep.centres.clone(), &y, prep.norm);
        for pt in prep.points.chunks_exact(3).step_by(7) {
            let q = [pt[0] + 0.3, pt[1] - 0.2, pt[2] + 0.1];
            let (u, v) = (model.spline.eval(&q), other.eval(&q));
            assert!((u - v).abs() < 1e-8 * scale, "{name}: {u} vs {v}");
        }
    }
}
