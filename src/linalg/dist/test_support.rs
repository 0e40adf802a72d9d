//! Test systems from real data for the solver tests of this module.

use super::layout::RowCyclic;
use super::system::LocalRows;
use crate::io::points::read_points;
use crate::spline::hygiene::prepare;
use crate::spline::{fill_rows, Carrier, Kernel};

/// The bordered spline system of every `step`-th vertex of the test bunny for the kernel r with
/// the default carrier, all rows on one rank, the spline's own right-hand side [r; 0] as the
/// last column.
pub(super) fn bunny_rows(step: usize) -> LocalRows {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/bunny10k.obj");
    let set = read_points(&path).expect("the test bunny reads");
    let raw: Vec<f64> = set.points.iter().step_by(step).flatten().copied().collect();
    let kernel = Kernel::new(3, 2).unwrap();
    let prep = prepare(&raw, &kernel, &Carrier::AutoBall, 1e-12).unwrap();
    let n = prep.values.len() + kernel.poly_count();
    let mut m = LocalRows::zeros(RowCyclic::new(n, 1, 0), n + 1, kernel.poly_count());
    let globals: Vec<usize> = (0..n).collect();
    fill_rows(&kernel, &prep.centres, &prep.values, &globals, &mut m.data);
    m
}
