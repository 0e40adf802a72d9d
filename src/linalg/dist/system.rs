//! The local part of a row-cyclic distributed matrix with its right-hand side as the last column,
//! so that every row operation of a factorisation reaches the right-hand side too.

use std::ops::Range;

use faer::{MatMut, MatRef};

use super::layout::RowCyclic;
use super::scalar::Scalar;
use crate::par::Comm;

/// This rank's rows of the global (n x cols) matrix, column-major with leading dimension equal to
/// the local row count. Column `cols - 1` is the right-hand side. The entries are f64, or f32 for
/// the factorisation of a mixed-precision solve.
#[derive(Debug, Clone)]
pub struct LocalRows<T = f64> {
    pub layout: RowCyclic,
    pub cols: usize,
    /// k: the last k rows and the k columns before the right-hand side are the polynomial border
    /// [P; 0] of the spline system (0 for a general matrix).
    pub border: usize,
    pub data: Vec<T>,
}

impl<T: Scalar> LocalRows<T> {
    pub fn zeros(layout: RowCyclic, cols: usize, border: usize) -> Self {
        LocalRows { layout, cols, border, data: vec![T::of(0.0); layout.local_count() * cols] }
    }

    /// [`LocalRows::zeros`], or [`crate::error::Error::Memory`] where the system refuses the
    /// allocation (see [`crate::linalg::try_zeros`]).
    pub fn try_zeros(layout: RowCyclic, cols: usize, border: usize) -> crate::error::Result<Self> {
        let data = crate::linalg::try_zeros(layout.local_count() * cols, T::of(0.0), || {
            format!("this rank's {} rows of the dense {} x {} system", layout.local_count(), layout.n, cols)
        })?;
        Ok(LocalRows { layout, cols, border, data })
    }

    /// The same rows rounded to another precision.
    pub fn convert<U: Scalar>(&self) -> LocalRows<U> {
        let data = self.data.iter().map(|v| U::of(v.f64())).collect();
        LocalRows { layout: self.layout, cols: self.cols, border: self.border, data }
    }

    /// Local row count (the leading dimension).
    #[inline]
    pub fn ld(&self) -> usize {
        self.layout.local_count()
    }

    #[inline]
    pub fn get(&self, l: usize, c: usize) -> T {
        self.data[l + c * self.ld()]
    }

    #[inline]
    pub fn set(&mut self, l: usize, c: usize, v: T) {
        let ld = self.ld();
        self.data[l + c * ld] = v;
    }

    pub fn view(&self) -> MatRef<'_, T> {
        MatRef::from_column_major_slice(&self.data, self.ld(), self.cols)
    }

    pub fn view_mut(&mut self) -> MatMut<'_, T> {
        let ld = self.ld();
        MatMut::from_column_major_slice_mut(&mut self.data, ld, self.cols)
    }

    /// Copies local row l, columns c0..c1, into `out`.
    pub fn read_row(&self, l: usize, c0: usize, c1: usize, out: &mut [T]) {
        let ld = self.ld();
        for (o, c) in out.iter_mut().zip(c0..c1) {
            *o = self.data[l + c * ld];
        }
    }

    /// Writes `src` into local row l, columns c0..c1.
    pub fn write_row(&mut self, l: usize, c0: usize, src: &[T]) {
        let ld = self.ld();
        for (c, v) in (c0..).zip(src) {
            self.data[l + c * ld] = *v;
        }
    }

    /// The size below which an elimination treats a pivot as zero: n eps max |a_ij|, eps the unit
    /// roundoff of the entries' type. Collective.
    pub fn singular_tol(&self, comm: &dyn Comm) -> f64 {
        self.max_abs(comm) * T::EPSILON * self.layout.n as f64
    }

    /// Largest |entry| of the global matrix (all columns but the right-hand side). Collective.
    pub fn max_abs(&self, comm: &dyn Comm) -> f64 {
        let n = self.ld() * (self.cols - 1);
        let mut m = [self.data[..n].iter().fold(0.0f64, |a, v| a.max(v.f64().abs()))];
        comm.max_f64(&mut m);
        m[0]
    }

    /// The global rows g0..g1, columns c0..c1, on every rank, row-major. Collective.
    pub fn gather_rows(&self, comm: &dyn Comm, g0: usize, g1: usize, c0: usize, c1: usize) -> Vec<T> {
        let mut bufs = GatherBuffers::default();
        self.gather_rows_with(comm, g0, g1, c0, c1, &mut bufs);
        bufs.out
    }

    /// As [`LocalRows::gather_rows`], into reused buffers (`bufs.out` holds the result): the
    /// factorisations gather megabytes per panel, and fresh allocations of that size cost a page
    /// fault per page.
    pub fn gather_rows_with(
        &self,
        comm: &dyn Comm,
        g0: usize,
        g1: usize,
        c0: usize,
        c1: usize,
        bufs: &mut GatherBuffers<T>,
    ) {
        gather_rows_while(comm, self.layout, &self.data, (g0, g1), (c0, c1), bufs, None);
    }

    /// The rows g0..g1 of columns c0..c1 on every rank, in rank order and column by column:
    /// rank 0's rows of the range (in local order) for column c0, then for c0 + 1, ... through
    /// c1 - 1, then rank 1's, and so on (in `bufs`, which the slice borrows). Each rank sends
    /// its rows as they lie in its columns, so packing is a copy of contiguous pieces and the
    /// receiver reads each column of each rank contiguously: for a block row of a few hundred
    /// rows across all columns, cheaper than the row-major [`LocalRows::gather_rows_with`],
    /// which transposes on both sides. Collective.
    pub fn gather_columns_by_rank<'b>(
        &self,
        comm: &dyn Comm,
        (g0, g1): (usize, usize),
        (c0, c1): (usize, usize),
        bufs: &'b mut GatherBuffers<T>,
    ) -> &'b [T] {
        let lay = self.layout;
        let ld = self.ld();
        let (l0, l1) = (lay.first_local_from(g0), lay.first_local_from(g1));
        let (mine, w) = (l1 - l0, c1 - c0);
        set_len(&mut bufs.send, mine * w);
        for (c, to) in (c0..c1).zip(bufs.send.chunks_exact_mut(mine.max(1))) {
            to.copy_from_slice(&self.data[l0 + c * ld..l1 + c * ld]);
        }
        let counts: Vec<usize> = (0..lay.ranks).map(|r| lay.count_in_on(r, g0, g1) * w).collect();
        set_len(&mut bufs.recv, (g1 - g0) * w);
        T::all_gather(comm, &bufs.send, &counts, &mut bufs.recv);
        &bufs.recv
    }

    /// Exchanges global rows a and b in columns c0..c1 between their owners. Only the two owners
    /// take part; the other ranks return at once.
    pub fn swap_rows(&mut self, comm: &dyn Comm, a: usize, b: usize, c0: usize, c1: usize) {
        if a == b {
            return;
        }
        let lay = self.layout;
        let (oa, ob) = (lay.owner(a), lay.owner(b));
        let me = lay.rank;
        let ld = self.ld();
        if oa == me && ob == me {
            let (la, lb) = (lay.local(a), lay.local(b));
            for c in c0..c1 {
                self.data.swap(la + c * ld, lb + c * ld);
            }
        } else if oa == me || ob == me {
            let (mine, partner) = if oa == me { (lay.local(a), ob) } else { (lay.local(b), oa) };
            let mut send = vec![T::of(0.0); c1 - c0];
            self.read_row(mine, c0, c1, &mut send);
            let mut recv = vec![T::of(0.0); c1 - c0];
            T::shift(comm, partner, partner, &send, &mut recv);
            self.write_row(mine, c0, &recv);
        }
    }

    /// Applies a sequence of row interchanges (a_i <-> b_i, in order, as partial pivoting records
    /// them) to columns c0..c1 at once: the net permutation moves each affected row once, local
    /// rows column by column, remote rows in one message per pair of ranks. Collective.
    pub fn permute_rows(&mut self, comm: &dyn Comm, swaps: &[(usize, usize)], c0: usize, c1: usize) {
        let lay = self.layout;
        let ld = self.ld();
        permute_local_rows(comm, &lay, swaps, &mut self.data, ld, c0..c1);
    }
}

/// Where the global rows of a distributed matrix live, seen from one rank: the rank (of the
/// communicator the rows are exchanged over) owning global row g, its local index there, and the
/// first of this rank's local rows at or below g. The row-cyclic and the 2D block-cyclic layouts
/// both have one, so the row operations written against it serve both.
pub(crate) trait RowIndex {
    fn owner(&self, g: usize) -> usize;
    fn local(&self, g: usize) -> usize;
    fn first_local_from(&self, g: usize) -> usize;
}

/// Applies the row interchanges `swaps` (in order) to the local columns `cols` of a column-major
/// local matrix (leading dimension `ld`) whose rows are distributed over `comm` as `rows` says:
/// the net permutation moves each affected row once, one message per pair of ranks (always sent,
/// possibly empty, so every rank takes part in every step). Collective over `comm`.
pub(crate) fn permute_local_rows<T: Scalar>(
    comm: &dyn Comm,
    rows: &dyn RowIndex,
    swaps: &[(usize, usize)],
    data: &mut [T],
    ld: usize,
    cols: Range<usize>,
) {
    let (c0, c1) = (cols.start, cols.end);
    if c0 >= c1 || swaps.is_empty() {
        return;
    }
    // net permutation: new content of row g is the old row src[g]
    let mut src: std::collections::BTreeMap<usize, usize> = std::collections::BTreeMap::new();
    for &(a, b) in swaps {
        let sa = *src.get(&a).unwrap_or(&a);
        let sb = *src.get(&b).unwrap_or(&b);
        src.insert(a, sb);
        src.insert(b, sa);
    }
    let moves: Vec<(usize, usize)> = src.into_iter().filter(|(d, s)| d != s).collect();
    let (me, p) = (comm.rank(), comm.size());
    let (owner, local) = (|g| rows.owner(g), |g| rows.local(g));
    let w = c1 - c0;
    // read every source first (rows may be both source and destination), column by column
    let pack = |data: &[T], list: &[(usize, usize)]| -> Vec<T> {
        let mut buf = vec![T::of(0.0); list.len() * w];
        for c in c0..c1 {
            for (t, &(_, s)) in list.iter().enumerate() {
                buf[(c - c0) * list.len() + t] = data[local(s) + c * ld];
            }
        }
        buf
    };
    let to = |r: usize| -> Vec<(usize, usize)> {
        moves.iter().copied().filter(|&(d, s)| owner(s) == me && owner(d) == r).collect()
    };
    let from = |r: usize| -> Vec<(usize, usize)> {
        moves.iter().copied().filter(|&(d, s)| owner(d) == me && owner(s) == r).collect()
    };
    let local_moves = to(me);
    let local_buf = pack(data, &local_moves);
    // (moves received, their values column-major)
    type Batch<T> = (Vec<(usize, usize)>, Vec<T>);
    let mut incoming: Vec<Batch<T>> = Vec::new();
    for step in 1..p {
        let (dest, source) = ((me + step) % p, (me + p - step) % p);
        let out = to(dest);
        let inn = from(source);
        let send = pack(data, &out);
        let mut recv = vec![T::of(0.0); inn.len() * w];
        T::shift(comm, dest, source, &send, &mut recv);
        incoming.push((inn, recv));
    }
    incoming.push((local_moves, local_buf));
    for (list, buf) in incoming {
        for c in c0..c1 {
            for (t, &(d, _)) in list.iter().enumerate() {
                data[local(d) + c * ld] = buf[(c - c0) * list.len() + t];
            }
        }
    }
}

/// [`LocalRows::gather_rows_with`] on the column-major local rows `data` (the leading dimension
/// is the layout's local row count; `data` may end after column c1). With `work`, the gather is
/// non-blocking and `work` runs while it is in flight ([`Comm::all_gather_f64_while`]); every
/// rank must pass `work` or none alike. Collective.
pub(crate) fn gather_rows_while<T: Scalar>(
    comm: &dyn Comm,
    lay: RowCyclic,
    data: &[T],
    (g0, g1): (usize, usize),
    (c0, c1): (usize, usize),
    bufs: &mut GatherBuffers<T>,
    work: Option<&mut (dyn FnMut() -> bool + '_)>,
) {
    let w = c1 - c0;
    let (l0, l1) = (lay.first_local_from(g0), lay.first_local_from(g1));
    let ld = lay.local_count();
    let send = &mut bufs.send;
    set_len(send, (l1 - l0) * w);
    // row-major into the buffer, a block of rows at a time: the block's lines of the buffer stay
    // in the first-level cache while every column of the block is read (contiguous) and spread
    for t0 in (0..l1 - l0).step_by(PACK_ROWS) {
        let t1 = (t0 + PACK_ROWS).min(l1 - l0);
        for c in c0..c1 {
            let col = &data[l0 + c * ld..l1 + c * ld];
            for (t, v) in col[t0..t1].iter().enumerate() {
                send[(t0 + t) * w + (c - c0)] = *v;
            }
        }
    }
    all_gather_packed_while(comm, lay, (g0, g1, w), bufs, true, work);
}

/// Rows packed per block when local rows are copied row-major into a gather's buffer.
const PACK_ROWS: usize = 32;

/// [`gather_rows_while`] for a caller that has written this rank's rows g0..g1, row-major, `w`
/// values each, into [`GatherBuffers::send_buffer`] itself. With `ordered`, the rows end in
/// global order in `out`; without, they stay in rank order ([`GatherBuffers::by_rank`]), which
/// spares a copy of all of them for a caller that can read them so.
pub(crate) fn all_gather_packed_while<T: Scalar>(
    comm: &dyn Comm,
    lay: RowCyclic,
    (g0, g1, w): (usize, usize, usize),
    bufs: &mut GatherBuffers<T>,
    ordered: bool,
    work: Option<&mut (dyn FnMut() -> bool + '_)>,
) {
    let out = if ordered { Some(&mut bufs.out) } else { None };
    all_gather_rows_into(comm, lay, &bufs.send, (g0, g1, w), (&mut bufs.recv, out), work);
}

/// Gives a reused buffer the length `len`, for a caller that then writes every entry: only where
/// it grows are entries filled (with zeros). A panel factorisation's gathers shrink from panel to
/// panel, so after the first one nothing is filled twice.
fn set_len<T: Scalar>(buf: &mut Vec<T>, len: usize) {
    if buf.len() >= len {
        buf.truncate(len);
    } else {
        buf.resize(len, T::of(0.0));
    }
}

/// Buffers reused by [`LocalRows::gather_rows_with`].
#[derive(Debug)]
pub struct GatherBuffers<T = f64> {
    send: Vec<T>,
    recv: Vec<T>,
    /// The gathered rows, row-major in global order.
    pub out: Vec<T>,
}

impl<T: Scalar> GatherBuffers<T> {
    /// The rows of the last gather without `ordered`, in rank order: rank 0's rows of the range
    /// in local order, then rank 1's, and so on.
    pub(crate) fn by_rank(&self) -> &[T] {
        &self.recv
    }

    /// The send buffer with `len` entries, for [`all_gather_packed_while`]; its contents are
    /// whatever the last gather left.
    pub(crate) fn send_buffer(&mut self, len: usize) -> &mut [T] {
        set_len(&mut self.send, len);
        &mut self.send
    }
}

impl<T> Default for GatherBuffers<T> {
    fn default() -> Self {
        GatherBuffers { send: Vec::new(), recv: Vec::new(), out: Vec::new() }
    }
}

/// Every rank's rows g0..g1 of a row-cyclic block, `w` values per row: `send` holds this rank's
/// rows of the range in local order, row-major; the result holds all of them in global order on
/// every rank. Collective.
pub fn all_gather_rows<T: Scalar>(
    comm: &dyn Comm,
    lay: RowCyclic,
    send: &[T],
    rows: Range<usize>,
    w: usize,
) -> Vec<T> {
    let (mut recv, mut out) = (Vec::new(), Vec::new());
    all_gather_rows_into(comm, lay, send, (rows.start, rows.end, w), (&mut recv, Some(&mut out)), None);
    out
}

/// [`all_gather_rows`] of rows g0..g1 of width w, into reused buffers (`out` in global order
/// where given, else only `recv` in rank order), with `work` run while the gather is in flight
/// where there is some.
fn all_gather_rows_into<T: Scalar>(
    comm: &dyn Comm,
    lay: RowCyclic,
    send: &[T],
    (g0, g1, w): (usize, usize, usize),
    (recv, out): (&mut Vec<T>, Option<&mut Vec<T>>),
    work: Option<&mut (dyn FnMut() -> bool + '_)>,
) {
    let counts: Vec<usize> = (0..lay.ranks).map(|r| lay.count_in_on(r, g0, g1) * w).collect();
    set_len(recv, (g1 - g0) * w);
    match work {
        None => T::all_gather(comm, send, &counts, recv),
        Some(work) => T::all_gather_while(comm, send, &counts, recv, work),
    }
    if let Some(out) = out {
        set_len(out, (g1 - g0) * w);
        lay.to_global_order(recv, g0, g1, w, out);
    }
}
