//! The local part of a row-cyclic distributed matrix with its right-hand side as the last column,
//! so that every row operation of a factorisation reaches the right-hand side too.

use faer::{MatMut, MatRef};

use super::comm::Comm;
use super::layout::RowCyclic;

/// This rank's rows of the global (n x cols) matrix, column-major with leading dimension equal to
/// the local row count. Column `cols - 1` is the right-hand side.
#[derive(Debug, Clone)]
pub struct LocalRows {
    pub layout: RowCyclic,
    pub cols: usize,
    /// k: the last k rows and the k columns before the right-hand side are the polynomial border
    /// [P; 0] of the spline system (0 for a general matrix).
    pub border: usize,
    pub data: Vec<f64>,
}

impl LocalRows {
    pub fn zeros(layout: RowCyclic, cols: usize, border: usize) -> Self {
        LocalRows { layout, cols, border, data: vec![0.0; layout.local_count() * cols] }
    }

    /// Local row count (the leading dimension).
    #[inline]
    pub fn ld(&self) -> usize {
        self.layout.local_count()
    }

    #[inline]
    pub fn get(&self, l: usize, c: usize) -> f64 {
        self.data[l + c * self.ld()]
    }

    #[inline]
    pub fn set(&mut self, l: usize, c: usize, v: f64) {
        let ld = self.ld();
        self.data[l + c * ld] = v;
    }

    pub fn view(&self) -> MatRef<'_, f64> {
        MatRef::from_column_major_slice(&self.data, self.ld(), self.cols)
    }

    pub fn view_mut(&mut self) -> MatMut<'_, f64> {
        let ld = self.ld();
        MatMut::from_column_major_slice_mut(&mut self.data, ld, self.cols)
    }

    /// Copies local row l, columns c0..c1, into `out`.
    pub fn read_row(&self, l: usize, c0: usize, c1: usize, out: &mut [f64]) {
        let ld = self.ld();
        for (o, c) in out.iter_mut().zip(c0..c1) {
            *o = self.data[l + c * ld];
        }
    }

    /// Writes `src` into local row l, columns c0..c1.
    pub fn write_row(&mut self, l: usize, c0: usize, src: &[f64]) {
        let ld = self.ld();
        for (c, v) in (c0..).zip(src) {
            self.data[l + c * ld] = *v;
        }
    }

    /// Largest |entry| of the global matrix (all columns but the right-hand side). Collective.
    pub fn max_abs(&self, comm: &dyn Comm) -> f64 {
        let n = self.ld() * (self.cols - 1);
        let mut m = [self.data[..n].iter().fold(0.0f64, |a, v| a.max(v.abs()))];
        comm.max_f64(&mut m);
        m[0]
    }

    /// The global rows g0..g1, columns c0..c1, on every rank, row-major. Collective.
    pub fn gather_rows(&self, comm: &dyn Comm, g0: usize, g1: usize, c0: usize, c1: usize) -> Vec<f64> {
        let lay = self.layout;
        let w = c1 - c0;
        let (l0, l1) = (lay.first_local_from(g0), lay.first_local_from(g1));
        let mut send = vec![0.0; (l1 - l0) * w];
        for (t, l) in (l0..l1).enumerate() {
            self.read_row(l, c0, c1, &mut send[t * w..(t + 1) * w]);
        }
        let counts: Vec<usize> = (0..lay.ranks).map(|r| lay.count_in_on(r, g0, g1) * w).collect();
        let mut recv = vec![0.0; (g1 - g0) * w];
        comm.all_gather_f64(&send, &counts, &mut recv);
        // recv holds rank 0's rows, then rank 1's, ...; put them in global order
        let mut out = vec![0.0; (g1 - g0) * w];
        let mut off = 0;
        for r in 0..lay.ranks {
            let first = g0 + (r + lay.ranks - g0 % lay.ranks) % lay.ranks;
            for t in 0..counts[r] / w.max(1) {
                let g = first + t * lay.ranks;
                out[(g - g0) * w..(g - g0 + 1) * w].copy_from_slice(&recv[off..off + w]);
                off += w;
            }
        }
        out
    }

    /// Exchanges global rows a and b (all columns) between their owners. Collective only for the
    /// two owners; the other ranks return at once.
    pub fn swap_rows(&mut self, comm: &dyn Comm, a: usize, b: usize) {
        if a == b {
            return;
        }
        let lay = self.layout;
        let (oa, ob) = (lay.owner(a), lay.owner(b));
        let me = lay.rank;
        let ld = self.ld();
        if oa == me && ob == me {
            let (la, lb) = (lay.local(a), lay.local(b));
            for c in 0..self.cols {
                self.data.swap(la + c * ld, lb + c * ld);
            }
        } else if oa == me || ob == me {
            let (mine, partner) = if oa == me { (lay.local(a), ob) } else { (lay.local(b), oa) };
            let mut send = vec![0.0; self.cols];
            self.read_row(mine, 0, self.cols, &mut send);
            let mut recv = vec![0.0; self.cols];
            comm.exchange_f64(partner, &send, &mut recv);
            self.write_row(mine, 0, &recv);
        }
    }
}
