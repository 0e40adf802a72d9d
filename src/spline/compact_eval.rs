//! Evaluation of a spline with a compactly supported kernel on rows of points: each point sums
//! only the centres within the support, found with the octree once per row.
//!
//! A row of points (x_1..x_m, y, z) can only see the centres within R of the segment from
//! (min x, y, z) to (max x, y, z): one octree search with that segment as its core
//! ([`Octree::near_box`]) gathers them. Those farther than R from the row's line are dropped;
//! the rest are sorted by their x coordinate (ties by index), so that the centres a point x can
//! see lie in the window x - R..x + R of the sorted list, found by bisection.
//!
//! # Reproducibility
//!
//! Slabs evaluated on different ranks must agree bit for bit where they overlap, whatever the
//! split of the grid, the thread count or the batching of points into rows. The value at a point
//! is the sum, over the centres whose squared distance to it (computed as
//! (dx^2 + dy^2) + dz^2, as the plain sum does) is below R^2, of lambda_i phi, taken in the order
//! of (x coordinate, index) of the centres. Both the set and the order depend on the point alone:
//! the row search and the window only ever add candidates, which the distance test then
//! rejects, so every way of reaching a point gives the same terms in the same order. The terms
//! themselves are those of [`crate::spline::Spline::eval`], which sums in index order; the two
//! agree to rounding.

use crate::spline::octree::{Octree, DEFAULT_LEAF_CAPACITY};
use crate::spline::Spline;

/// A compactly supported spline's centres, arranged for row evaluation.
#[derive(Debug, Clone)]
pub struct CompactRows {
    tree: Octree,
    support: f64,
}

/// The candidates of one row: centres near the row's line, sorted by x.
struct Candidates {
    cx: Vec<f64>,
    dy2: Vec<f64>,
    dz2: Vec<f64>,
    w: Vec<f64>,
}

impl CompactRows {
    /// None unless the spline's kernel is compactly supported (and three-dimensional).
    pub fn new(spline: &Spline) -> Option<CompactRows> {
        let support = spline.kernel.is_compact()?;
        if spline.kernel.dim() != 3 {
            return None;
        }
        Some(CompactRows { tree: Octree::new(&spline.centres, DEFAULT_LEAF_CAPACITY), support })
    }

    /// The support radius R (normalised coordinates).
    pub fn support(&self) -> f64 {
        self.support
    }

    /// The octree of the centres.
    pub fn tree(&self) -> &Octree {
        &self.tree
    }

    /// The kernel part sum_i lambda_i phi(|x - P_i| / R) at the normalised points (`xn[j]`, y, z)
    /// into `out`.
    pub fn radial_row(&self, spline: &Spline, xn: &[f64], y: f64, z: f64, out: &mut [f64]) {
        let (lo, hi) = xn.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| (a.min(x), b.max(x)));
        out.fill(0.0);
        if !(lo <= hi) {
            return;
        }
        let c = self.candidates(spline, [lo, y, z], [hi, y, z]);
        let r = self.support;
        let r2 = r * r;
        let kernel = &spline.kernel;
        for (o, &x) in out.iter_mut().zip(xn) {
            // a window a little wider than R: the distance test decides, the window only has to
            // hold every centre that can pass it
            let margin = 1e-6 * (r + x.abs());
            let first = c.cx.partition_point(|&cx| cx < x - r - margin);
            let last = c.cx.partition_point(|&cx| cx <= x + r + margin);
            let mut s = 0.0;
            for t in first..last {
                let dx = c.cx[t] - x;
                let d2 = dx * dx + c.dy2[t] + c.dz2[t];
                if d2 < r2 {
                    s += c.w[t] * kernel.eval_r2(d2);
                }
            }
            *o = s;
        }
    }

    /// The centres within R of the segment lo..hi (parallel to x), less those that cannot reach
    /// the segment's line, sorted by (x coordinate, index).
    fn candidates(&self, spline: &Spline, lo: [f64; 3], hi: [f64; 3]) -> Candidates {
        let mut found = Vec::new();
        self.tree.near_box(lo, hi, self.support, &mut found);
        let r2 = self.support * self.support;
        let (y, z) = (lo[1], lo[2]);
        let mut near: Vec<(f64, usize)> = found
            .iter()
            .filter_map(|&i| {
                let p = &spline.centres[3 * i..3 * i + 3];
                let (dy, dz) = (p[1] - y, p[2] - z);
                (dy * dy + dz * dz < r2).then_some((p[0], i))
            })
            .collect();
        near.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let mut c = Candidates {
            cx: Vec::with_capacity(near.len()),
            dy2: Vec::with_capacity(near.len()),
            dz2: Vec::with_capacity(near.len()),
            w: Vec::with_capacity(near.len()),
        };
        for &(x, i) in &near {
            let p = &spline.centres[3 * i..3 * i + 3];
            c.cx.push(x);
            c.dy2.push((p[1] - y) * (p[1] - y));
            c.dz2.push((p[2] - z) * (p[2] - z));
            c.w.push(spline.weights[i]);
        }
        c
    }

    /// The mean number of centres within the support of a centre (itself included), over up to
    /// `sample` centres spread through the list: the kernel evaluations per point near the data
    /// (points farther than R from every centre need none).
    pub fn mean_neighbours(&self, sample: usize) -> f64 {
        let n = self.tree.len();
        if n == 0 {
            return 0.0;
        }
        let stride = n.div_ceil(sample.max(1)).max(1);
        let mut found = Vec::new();
        let (mut total, mut count) = (0usize, 0usize);
        for i in (0..n).step_by(stride) {
            self.tree.within(self.tree.point(i), self.support, &mut found);
            total += found.len();
            count += 1;
        }
        total as f64 / count as f64
    }
}

#[cfg(test)]
mod tests {
    use crate::grid::{Grid, GridSize};
    use crate::spline::compact::{default_support, DEFAULT_NEIGHBOURS};
    use crate::spline::kernel::Kernel;
    use crate::spline::model::{Field, Model, Provenance};
    use crate::spline::octree::tests::bunny;
    use crate::spline::{Carrier, Evaluator, Normalisation, Spline};

    /// A Wendland spline on the bunny's vertices with pseudo-random weights, in coordinates that
    /// are not the normalised ones (so that the evaluator's normalisation is exercised).
    fn bunny_spline(name: &str, support: f64) -> Spline {
        let mut s = 17u64;
        let mut rnd = || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let centres = bunny();
        let weights: Vec<f64> = (0..centres.len() / 3).map(|_| rnd()).collect();
        let poly = vec![0.3, -0.2, 0.5, 0.1];
        let norm = Normalisation { centre: [0.1, -0.2, 0.3], scale: 2.0 };
        Spline { kernel: Kernel::wendland(name, support).unwrap(), centres, weights, poly, norm }
    }

    #[test]
    fn compact_rows_agree_with_the_plain_sum() {
        let support = default_support(&bunny(), DEFAULT_NEIGHBOURS);
        for (name, r) in [("wendland0", support), ("wendland2", 2.0 * support), ("wendland4", 0.5 * support)]
        {
            let sp = bunny_spline(name, r);
            let ev = Evaluator::new(&sp);
            assert!(ev.compact_rows().is_some());
            // rows through the data: y and z of some centres, x across the whole box and beyond
            let xs: Vec<f64> = (0..161).map(|i| -2.2 + i as f64 * 0.0275).collect();
            let mut out = vec![0.0; xs.len()];
            let mut hit = 0;
            for q in (0..sp.len()).step_by(211) {
                let (y, z) = (sp.centres[3 * q + 1] * 2.0 - 0.2, sp.centres[3 * q + 2] * 2.0 + 0.3);
                ev.eval_row(&xs, y, z, &mut out);
                for (o, &x) in out.iter().zip(&xs) {
                    let plain = sp.eval(&[x, y, z]);
                    assert!((o - plain).abs() <= 1e-12 * (1.0 + plain.abs()), "{name}: {o} vs {plain}");
                    let poly_only =
                        0.3 - 0.2 * (x - 0.1) / 2.0 + 0.5 * (y + 0.2) / 2.0 + 0.1 * (z - 0.3) / 2.0;
                    hit += usize::from((plain - poly_only).abs() > 1e-9);
                }
                // a single point, as the fit's check evaluates the data points
                let mut one = [0.0];
                let p = [sp.centres[3 * q] * 2.0 + 0.1, y, z];
                ev.eval_row(&p[..1], p[1], p[2], &mut one);
                assert!((one[0] - sp.eval(&p)).abs() <= 1e-12 * (1.0 + one[0].abs()));
            }
            // the rows do pass through the support of many centres
            assert!(hit > 100, "{name}: {hit}");
        }
    }

    #[test]
    fn compact_rows_do_not_depend_on_how_points_are_batched() {
        let sp = bunny_spline("wendland2", 0.1);
        let ev = Evaluator::new(&sp);
        let xs: Vec<f64> = (0..90).map(|i| -1.5 + i as f64 * 0.033).collect();
        let (y, z) = (sp.centres[301] * 2.0 - 0.2, sp.centres[302] * 2.0 + 0.3);
        let mut whole = vec![0.0; xs.len()];
        ev.eval_row(&xs, y, z, &mut whole);
        let mut parts = vec![0.0; xs.len()];
        for (a, b) in [(0, 7), (7, 8), (8, 50), (50, 90)] {
            ev.eval_row(&xs[a..b], y, z, &mut parts[a..b]);
        }
        assert_eq!(whole, parts);
        // and in reverse order, one point at a time
        for i in (0..xs.len()).rev() {
            ev.eval_row(&xs[i..i + 1], y, z, &mut parts[i..i + 1]);
        }
        assert_eq!(whole, parts);
    }

    #[test]
    fn slabs_agree_bit_for_bit_whatever_the_split_and_the_threads() {
        let sp = bunny_spline("wendland2", 0.08);
        let model = Model {
            carrier: Carrier::parse("ball:0,0,0,2", 3).unwrap(),
            spline: sp,
            coarse: Vec::new(),
            provenance: Provenance::default(),
        };
        let grid = Grid::covering([-2.0, -2.2, -1.7], [2.2, 1.8, 2.3], GridSize::Longest(24)).unwrap();
        let nz = grid.dims[2];
        let pool = |t: usize| rayon::ThreadPoolBuilder::new().num_threads(t).build().unwrap();
        let whole = pool(1).install(|| model.eval_layers(&grid, 0, nz));
        let layer = grid.dims[0] * grid.dims[1];
        for (threads, cuts) in [(3, vec![0, 5, 6, 17, nz]), (2, vec![0, nz / 2, nz])] {
            let mut joined = Vec::new();
            for w in cuts.windows(2) {
                joined.extend(pool(threads).install(|| model.eval_layers(&grid, w[0], w[1] - w[0])));
            }
            assert_eq!(joined.len(), whole.len());
            assert!(joined.iter().zip(&whole).all(|(a, b)| a.to_bits() == b.to_bits()), "{cuts:?}");
        }
        // a slab overlapping the others by one layer
        let ghost = model.eval_layers(&grid, 4, 3);
        assert!(ghost.iter().zip(&whole[4 * layer..7 * layer]).all(|(a, b)| a.to_bits() == b.to_bits()));
        assert!(model.kernel_evals_per_node() > 10 && model.kernel_evals_per_node() < 200);
    }
}
