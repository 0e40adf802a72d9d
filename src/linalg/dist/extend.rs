//! Bordering a projected Cholesky factor: the system of a fit with m centres appended after the
//! n it had, solved from the factor of the first system in O(n^2 m) flops instead of a fresh
//! O((n + m)^3) factorisation. The factor is row-cyclic; one from the 2D layout is moved here
//! first (`LocalBlocks::to_row_cyclic`: L and the first k rows of Q^T A Q, the entries read
//! below). The right-hand side of the first n rows may change too (a second
//! fit that moves no centre but changes values is the case m = 0).
//!
//! # Why the first factor survives
//!
//! The projected Cholesky (see `cholesky`) factors s B = L L^T with B = Q2^T A Q2, where
//! P = Q [R; 0] is the Householder QR of the polynomial block and Q2 its last n - k columns.
//! Appending centres appends rows P_new (m x k) to P and rows and columns to A:
//!
//! ```text
//!     A' = [A E; E^T F],   P' = [P; P_new],   E = (G(|x_i - y_j|)) (n x m), F (m x m).
//! ```
//!
//! With T = diag(Q, I_m), T^T P' = [R; 0; P_new]: only the k rows of R and the m new rows are
//! not yet zero. A second Householder QR of the small (k + m) x k matrix [R; P_new] =
//! G [R'; 0] finishes it: with H the embedding of G on those k + m coordinates (the identity on
//! the n - k others), Q' = T H is an orthogonal factor of P' = Q' [R'; 0]. H leaves the
//! coordinates k..n alone, so the null-space basis Q2' of P'^T consists of the old Q2 (padded
//! with zeros) and m new columns, and the new projected block is the old one bordered:
//!
//! ```text
//!     B' = [B C; C^T D],   C = [M_{k..n,0..k}  (Q^T E)_{k..n}] G_n,
//!                          D = G_n^T [M_{0..k,0..k} (Q^T E)_{0..k}; (Q^T E)_{0..k}^T F] G_n,
//! ```
//!
//! with M = Q^T A Q (the first solve leaves its rows 0..k and columns 0..k in place) and G_n the
//! last m columns of G. B' is definite with the same sign s (it is the projection of the same
//! kernel onto the null space of the larger P'^T). Its factor is the old one bordered:
//! s B' = [L 0; X^T L22] [L^T X; 0 L22^T] with L X = s C (a blocked forward substitution of m
//! columns through the distributed L, n^2 m flops) and L22 L22^T = s D - X^T X (m x m, on every
//! rank). When that last block is not definite to working precision the extension fails with
//! `Error::NotDefinite` and the caller factors the whole system instead.
//!
//! The right-hand side follows the same way: y' = Q'^T r' is Q^T r_old at k..n and
//! G^T [(Q^T r_old)_{0..k}; r_new] on the other k + m coordinates; mu' = [mu; mu_new] from the
//! bordered factor, lambda' = Q' [0; mu'] and R' c = y'_{0..k} - (Q'^T A' Q')_{0..k, null} mu'.
//!
//! Only the right-hand side depends on the values, so the pieces that do not (X, L22, G, R' and
//! the blocks Z G_n, Q^T E, M_{0..k}) are kept in a [`Bordered`]: another right-hand side of the
//! same n + m centres then costs a forward substitution of s y_{k..n} through L, the small solve
//! with L22 and the back substitution, O(n^2) flops in all ([`solve_bordered`]). The solution is
//! linear in the right-hand side, and the substitutions read the whole of L for each of them,
//! so several right-hand sides are solved together ([`solve_bordered_many`]): one pass over L
//! for all of them, each column adding 2 flops per entry of L read.
//!
//! # Substitutions kept per centre
//!
//! The forward substitution, n^2 m of the flops, is taken before G_n: X = Y G_n with
//! Y = s L^{-1} [M_{k..n,0..k}  (Q^T E)_{k..n}], since G_n acts on the columns and L^{-1} on the
//! rows. A column of Q^T E = E - V T^T V^T E depends on its own centre alone, and so does its
//! column of Y. The factor keeps the columns of Y it computed, by the appended centres'
//! coordinates ([`Appended::keys`]), and a later extension by some of the same centres
//! substitutes only the others. Second fits that differ in a few of hundreds of appended centres
//! (two candidate sets of constraint points, or a set and a superset of it) then cost one
//! substitution between them instead of one each. The kept columns are bounded by
//! [`kept_most`] of the factor's centres.
//!
//! X itself is never formed: X^T X = G_n^T (Y^T Y) G_n, and the solves take X^T z = G_n^T (Y^T z)
//! and X u = Y (G_n u). The Gram matrix Y^T Y of the kept columns is kept with them (summed over
//! the ranks), so an extension takes only the products of the columns it substitutes, with the
//! kept ones and among themselves: with hundreds of kept centres and a few new ones, the m^2
//! (n - k) flops of X^T X become a product of the few new columns, and the (n - k) m k flops
//! and the memory traffic that would form X are saved too (a fit of 5556 centres bordered by
//! 373, 371 of them kept, on 2 ranks: 0.043 s -> 0.028 s).
//!
//! # Diagonal blocks kept
//!
//! Both substitutions solve with L's diagonal blocks of one panel each, which every rank needs
//! whole: a gather of panel x panel entries per block and substitution. L does not change
//! between extensions, so the blocks gathered once are kept (the forward substitution's and the
//! back substitution's, whose panels are cut from opposite ends) up to [`DIAGONAL_BYTES`] a
//! rank, and later substitutions read them from there: on a fit of 514 centres bordered ten
//! times on one rank, about a third of the extensions' time went to gathering and unpacking the
//! same blocks again.
//!
//! # Memory beyond the estimate
//!
//! The memory a bordering needs is estimated with the kept columns of the share alone
//! ([`KEPT_SHARE`]). What a factor keeps beyond that (the diagonal blocks, the columns beyond
//! the share up to [`KEPT_FLOOR`]) only saves time, so it lives in the room the estimate leaves:
//! the caller gives each extension that room ([`Factored::limit_extras`]; the ranks agree on
//! it), the factor keeps no more beyond the estimate than that, and it lets go of what it kept
//! beyond the estimate where an extension leaves less room than it holds. Counted alike on every
//! rank (the rows of the rank with the most), so every rank keeps the same.

use std::cell::{Cell, RefCell};
use std::collections::HashMap;
use std::rc::Rc;

use crate::linalg::gemm::gemm;
use faer::linalg::matmul::triangular::{self, BlockStructure};
use faer::linalg::triangular_solve::{solve_lower_triangular_in_place, solve_upper_triangular_in_place};
use faer::{Accum, Mat, MatRef};

use super::cholesky::{back_substitute_many, cholesky_small, Border};
use super::solver::Job;
use super::system::{all_gather_rows, LocalRows};
use crate::error::{Error, Result};
use crate::linalg::reflector::{explicit_v, qr_in_place, wy_t};
use crate::par::Comm;

/// Most columns of Y a factor keeps (see "Substitutions kept per centre"), as a share of its
/// centres: a quarter adds at most a quarter to the memory of the factor's own rows, and holds
/// the constraint points of the blob search (at most a sixth of the centres of an off-surface
/// fit of some thousands of points). Small factors keep up to [`KEPT_FLOOR`] columns whatever
/// their share ([`kept_most`]).
pub const KEPT_SHARE: f64 = 0.25;

/// The columns of Y every factor may keep, up to its own centres, whatever its share: on small
/// fits the blob search's constraint points are more than the share holds (200 on 400 data
/// points with 114 off points, where a quarter is 128); with them kept, each later extension by
/// the same points and a few more substitutes the few (there, on 2 ranks, the extensions after
/// the first two took 1.0-1.2 ms instead of 3.0-3.3 ms). At most 512 columns of a factor's rows
/// and a 512 x 512 Gram matrix: a few megabytes.
pub const KEPT_FLOOR: usize = 512;

/// The most columns of Y a factor of `n` centres keeps: [`KEPT_SHARE`] of them, at least
/// [`KEPT_FLOOR`] (at most `n`).
pub fn kept_most(n: usize) -> usize {
    ((KEPT_SHARE * n as f64) as usize).max(KEPT_FLOOR.min(n))
}

/// Most bytes of L's diagonal blocks a factor keeps on each rank (see "Diagonal blocks kept"):
/// both substitutions' blocks of a factor of about 8000 centres at the default panel of 256.
pub const DIAGONAL_BYTES: f64 = 32e6;

/// The factor of a solved projected Cholesky kept for bordering: the rows it overwrote (L of
/// s B in rows and columns k..n, rows 0..k and columns 0..k of Q^T A Q as the projection left
/// them), the QR of the border, s and the panel width; and the substitutions of earlier
/// extensions kept for later ones.
pub struct Factored {
    rows: LocalRows,
    border: Border,
    sign: f64,
    panel: usize,
    kept: RefCell<Substituted>,
    /// The most columns of Y it keeps ([`kept_most`] unless set).
    keep: usize,
    diagonal: Diagonal,
    /// The bytes it may keep beyond the memory estimate (see "Memory beyond the estimate"), and
    /// those of the columns of Y it keeps beyond the share.
    extras_room: Cell<f64>,
    columns_beyond: Cell<f64>,
    /// The seconds this rank took to move the factor from the 2D layout (None: factored here).
    moved: Option<f64>,
}

/// Columns of Y = s L^{-1} [M_{k..n,0..k}  (Q^T E)_{k..n}] on this rank's rows k..n (see
/// "Substitutions kept per centre"): the first k once computed, then those of appended centres,
/// found by their coordinates' bits; with their Gram matrix (summed over the ranks).
struct Substituted {
    /// The kept columns, column-major (this rank's rows k..n each): the k border columns first.
    columns: Vec<f64>,
    /// Each kept centre's column in `columns`.
    centres: HashMap<[u64; 3], usize>,
    /// The products of the kept columns over all rows k..n, in their order.
    gram: Mat<f64>,
}

/// A diagonal block of L, shared by the substitutions that read it.
type Block = Rc<Mat<f64>>;

/// L's diagonal blocks gathered by earlier substitutions (see "Diagonal blocks kept"), by their
/// first and last row: the lower triangle of each, zero above it. Every rank asks for the same
/// blocks in the same order and keeps the same ones, so a block kept on one is kept on all and
/// the gather it saves is skipped by every rank alike.
#[derive(Default)]
struct Diagonal {
    blocks: RefCell<HashMap<(usize, usize), Block>>,
    bytes: Cell<f64>,
}

impl Diagonal {
    /// The block of rows and columns q0..q1 of L in `rows`: kept, or gathered (and kept while
    /// the blocks stay within `room` bytes and [`DIAGONAL_BYTES`]). Collective where it gathers.
    fn block(&self, comm: &dyn Comm, rows: &LocalRows, (q0, q1): (usize, usize), room: f64) -> Block {
        if let Some(b) = self.blocks.borrow().get(&(q0, q1)) {
            return Rc::clone(b);
        }
        let bs = q1 - q0;
        let d = rows.gather_rows(comm, q0, q1, q0, q1);
        // the lower triangle alone: above it the first solve may have left entries of B
        let l11 = Rc::new(Mat::<f64>::from_fn(bs, bs, |i, j| if j <= i { d[i * bs + j] } else { 0.0 }));
        let bytes = self.bytes.get() + 8.0 * (bs * bs) as f64;
        if bytes <= DIAGONAL_BYTES.min(room) {
            self.bytes.set(bytes);
            self.blocks.borrow_mut().insert((q0, q1), Rc::clone(&l11));
        }
        l11
    }
}

impl Default for Substituted {
    fn default() -> Self {
        Substituted { columns: Vec::new(), centres: HashMap::new(), gram: Mat::zeros(0, 0) }
    }
}

impl Factored {
    pub(super) fn new(rows: LocalRows, border: Border, sign: f64, panel: usize) -> Self {
        let (kept, keep, diagonal) = (RefCell::default(), kept_most(border.n), Diagonal::default());
        let (extras_room, columns_beyond) = (Cell::new(f64::INFINITY), Cell::new(0.0));
        Factored { rows, border, sign, panel, kept, keep, diagonal, extras_room, columns_beyond, moved: None }
    }

    /// The factor moved from the 2D layout in `seconds` (on this rank).
    pub(super) fn moved_in(self, seconds: f64) -> Self {
        Factored { moved: Some(seconds), ..self }
    }

    /// The seconds this rank took to move the factor from the 2D layout, if it was moved.
    pub fn moved(&self) -> Option<f64> {
        self.moved
    }

    /// The factor keeping at most `columns` columns of Y for later extensions (by default
    /// [`kept_most`] of its centres). The same on every rank.
    pub fn keeping_at_most(self, columns: usize) -> Self {
        Factored { keep: columns, ..self }
    }

    /// Gives the factor `bytes` per rank beyond the memory estimate for what it keeps to save
    /// time (see "Memory beyond the estimate"; unlimited until set): where it holds more, it
    /// lets go of the diagonal blocks and the substitutions it kept. The same on every rank.
    pub fn limit_extras(&self, bytes: f64) {
        if self.extra_bytes() > bytes {
            self.diagonal.blocks.borrow_mut().clear();
            self.diagonal.bytes.set(0.0);
            *self.kept.borrow_mut() = Substituted::default();
            self.columns_beyond.set(0.0);
        }
        self.extras_room.set(bytes);
    }

    /// The bytes per rank this factor keeps beyond the memory estimate: its diagonal blocks and
    /// the columns of Y (with their rows of the Gram matrix) beyond [`KEPT_SHARE`].
    pub fn extra_bytes(&self) -> f64 {
        self.diagonal.bytes.get() + self.columns_beyond.get()
    }

    /// The bytes of `columns` kept columns of Y beyond the share, counted with the rows of the
    /// rank that has the most.
    fn beyond_share(&self, columns: usize) -> f64 {
        let share = (KEPT_SHARE * self.border.n as f64) as usize;
        let rows = self.border.n.div_ceil(self.rows.layout.ranks);
        8.0 * ((rows + columns) * columns.saturating_sub(share)) as f64
    }

    /// The diagonal block of rows and columns q0..q1 of L (see "Diagonal blocks kept").
    /// Collective where it gathers.
    fn diagonal_block(&self, comm: &dyn Comm, q0: usize, q1: usize) -> Block {
        let room = self.extras_room.get() - self.columns_beyond.get();
        self.diagonal.block(comm, &self.rows, (q0, q1), room)
    }

    /// The appended centres whose substitutions this factor keeps for later extensions.
    pub fn kept_centres(&self) -> usize {
        self.kept.borrow().centres.len()
    }

    /// Y (this rank's rows k..n, columns: the k border columns, then one per appended centre),
    /// its Gram matrix Y^T Y (summed over the ranks) and z = s L^{-1} y_{k..n} of the
    /// right-hand side, by one forward substitution of the columns not kept from earlier
    /// extensions (and of z); the products among kept columns are kept too, so only those of the
    /// new columns are taken. Keeps the new columns while there is room. `qte`: Q^T E on this
    /// rank's rows; `keys`: the appended centres' coordinates, 3 per centre (None: nothing
    /// reused or kept). Collective: every rank keeps the same centres.
    fn substitute(
        &self,
        job: &Job<'_>,
        qte: &Mat<f64>,
        y: &[f64],
        keys: Option<&[f64]>,
    ) -> (Mat<f64>, Mat<f64>, Vec<f64>) {
        let Job { comm, par, .. } = *job;
        let (k, n, s) = (self.border.k, self.border.n, self.sign);
        let lay = self.rows.layout;
        let (la, b0) = (lay.first_local_from(n), lay.first_local_from(k));
        let (h, m, w) = (la - b0, qte.ncols(), k + qte.ncols());
        let key =
            |j: usize| keys.map(|c| [c[3 * j].to_bits(), c[3 * j + 1].to_bits(), c[3 * j + 2].to_bits()]);
        let mut kept = self.kept.borrow_mut();
        let held = kept.gram.nrows();
        // each column of Y among the kept ones, if it is
        let at: Vec<Option<usize>> = (0..k)
            .map(|j| (held >= k).then_some(j))
            .chain((0..m).map(|j| key(j).and_then(|q| kept.centres.get(&q).copied())))
            .collect();
        let new: Vec<usize> = (0..w).filter(|&c| at[c].is_none()).collect();
        let mut x = LocalRows::zeros(lay, new.len() + 1, 0);
        let ld = x.ld();
        {
            let mut out = x.data.chunks_mut(ld).map(|c| &mut c[b0..la]);
            let mut fill = |f: &dyn Fn(usize) -> f64| {
                let col = out.next().expect("a column for each");
                col.iter_mut().enumerate().for_each(|(i, v)| *v = s * f(b0 + i));
            };
            for &c in &new {
                match c < k {
                    true => fill(&|l| self.rows.get(l, c)),
                    false => fill(&|l| qte[(l, c - k)]),
                }
            }
            fill(&|l| y[lay.global(l)]);
        }
        forward_substitute(job, self, &mut x);
        let fresh = x.view().submatrix(b0, 0, h, new.len());
        let stored = MatRef::from_column_major_slice(&kept.columns, h, held);
        let mut yc = Mat::<f64>::zeros(h, w);
        let mut at_new = vec![None; w];
        new.iter().enumerate().for_each(|(t, &c)| at_new[c] = Some(t));
        for c in 0..w {
            let from = match (at_new[c], at[c]) {
                (Some(t), _) => fresh.col(t),
                (None, Some(a)) => stored.col(a),
                (None, None) => unreachable!("a column not kept is substituted now"),
            };
            yc.as_mut().col_mut(c).copy_from(from);
        }
        // the products of the new columns with the kept ones and among themselves (the lower
        // triangle, mirrored), summed over the ranks in one call
        let mut products = Mat::<f64>::zeros(held + new.len(), new.len());
        if held > 0 && !new.is_empty() {
            gemm(products.as_mut().subrows_mut(0, held), Accum::Replace, stored.transpose(), fresh, 1.0, par);
        }
        let (lower, full) = (BlockStructure::TriangularLower, BlockStructure::Rectangular);
        let among = products.as_mut().subrows_mut(held, new.len());
        triangular::matmul(among, lower, Accum::Replace, fresh.transpose(), full, fresh, full, 1.0, par);
        let rows = held + new.len();
        let mut buf: Vec<f64> = (0..rows * new.len())
            .map(|q| {
                let (i, j) = (q % rows, q / rows);
                // the upper triangle of the block among the new columns from the lower
                match i >= held && i - held < j {
                    true => products[(held + j, i - held)],
                    false => products[(i, j)],
                }
            })
            .collect();
        comm.sum_f64(&mut buf);
        let product = |i: usize, j: usize| buf[j * rows + i];
        let gram = Mat::<f64>::from_fn(w, w, |i, j| match (at[i], at[j], at_new[i], at_new[j]) {
            (Some(a), Some(b), _, _) => kept.gram[(a, b)],
            (Some(a), None, _, Some(t)) => product(a, t),
            (None, Some(b), Some(t), _) => product(b, t),
            (None, None, Some(a), Some(b)) => product(held + a, b),
            _ => unreachable!("a column is either kept or new"),
        });
        // keep the border's columns, and the new centres' while there is room
        let fresh_centres = new.iter().filter(|&&c| c >= k).count();
        let total = kept.centres.len() + fresh_centres;
        let beyond = self.beyond_share(total);
        let room = self.extras_room.get() - self.diagonal.bytes.get();
        let centres_fit = keys.is_some() && total <= self.keep && (beyond == 0.0 || beyond <= room);
        let added: Vec<usize> = (0..new.len()).filter(|&t| new[t] < k || centres_fit).collect();
        if !added.is_empty() {
            let count = held + added.len();
            let previous = std::mem::replace(&mut kept.gram, Mat::zeros(0, 0));
            kept.gram = Mat::from_fn(count, count, |a, b| match (a < held, b < held) {
                (true, true) => previous[(a, b)],
                (true, false) => product(a, added[b - held]),
                (false, true) => product(b, added[a - held]),
                (false, false) => product(held + added[a - held], added[b - held]),
            });
            for (slot, &t) in added.iter().enumerate() {
                kept.columns.extend(fresh.col(t).iter());
                if new[t] >= k {
                    kept.centres.insert(key(new[t] - k).expect("keys given"), held + slot);
                }
            }
            self.columns_beyond.set(self.beyond_share(kept.centres.len()));
        }
        let z = x.view().col(new.len()).subrows(b0, h).iter().copied().collect();
        (yc, gram, z)
    }

    /// The number of centres of the factored system.
    pub fn centres(&self) -> usize {
        self.border.n
    }

    /// The width k of the polynomial border.
    pub fn border(&self) -> usize {
        self.border.k
    }

    /// The panel width the factor was computed with (the bordering uses the same).
    pub fn panel(&self) -> usize {
        self.panel
    }

    /// This rank's rows of the factored system's centres (global indices, in local order): the
    /// rows of [`Appended::cross`].
    pub fn local_centres(&self) -> Vec<usize> {
        let lay = self.rows.layout;
        (0..lay.first_local_from(self.border.n)).map(|l| lay.global(l)).collect()
    }
}

/// What m appended centres add to a factored system of n centres and border k.
pub struct Appended<'a> {
    /// E: the kernel between this rank's centres ([`Factored::local_centres`]) and the new ones,
    /// column-major (local rows x m).
    pub cross: &'a [f64],
    /// P_new: the k polynomials at the new centres, row-major (m x k).
    pub poly: &'a [f64],
    /// F: the kernel among the new centres (m x m).
    pub block: &'a [f64],
    /// The whole right-hand side r' of the n + m centres (the first n may differ from the first
    /// system's).
    pub rhs: &'a [f64],
    /// The appended centres' coordinates (3 per centre), by which the factor keeps their
    /// substitutions for later extensions (see "Substitutions kept per centre"); None: none are
    /// kept or reused. The same on every rank.
    pub keys: Option<&'a [f64]>,
}

/// A factor of the first system bordered by m appended centres, kept so that further right-hand
/// sides of the same bordered system cost two distributed triangular solves through L and a few
/// small products ([`solve_bordered`]), instead of the n^2 m flops of bordering again: Y (with
/// G_n it gives X) and L22 of the bordered factor, the border's new QR (G and R') and the blocks
/// the solution's last steps multiply by.
pub struct Bordered {
    /// The appended centres' count m.
    m: usize,
    /// Y = s L^{-1} [M_{k..n,0..k}  (Q^T E)_{k..n}] in this rank's rows k..n (k + m columns):
    /// X = s L^{-1} C = Y G_n.
    y: Mat<f64>,
    /// L22 of the bordered factor (m x m).
    l22: Mat<f64>,
    /// G of the QR [R; P_new] = G [R'; 0] ((k + m) x (k + m)) and R' (k x k).
    g: Mat<f64>,
    r_new: Mat<f64>,
    /// Z G_n ((k + m) x m), Q^T E on this rank's rows (local rows x m) and rows 0..k of
    /// M = Q^T A Q (row-major k x n).
    zg: Mat<f64>,
    qte: Mat<f64>,
    m_top: Vec<f64>,
}

/// The solution [lambda (n); lambda_new (m); c (k)] of the first system bordered by `new`, from
/// its factor, on every rank, with the bordered factor for further right-hand sides
/// ([`solve_bordered`]); `first` is left as it is, so it can be bordered again. Collective;
/// `Error::NotDefinite` on every rank when the new block's Schur complement is not definite,
/// `Error::Numerical` when the extended points are not unisolvent.
pub fn extend_solve(job: &Job<'_>, first: &Factored, new: &Appended<'_>) -> Result<(Vec<f64>, Bordered)> {
    let comm = job.comm;
    let (k, n) = (first.border.k, first.border.n);
    let m = new.rhs.len() - n;
    let lay = first.rows.layout;
    let la = lay.first_local_from(n);
    let b0 = lay.first_local_from(k);
    let s = first.sign;
    assert_eq!(new.cross.len(), la * m, "the cross block has this rank's rows and m columns");
    assert_eq!(new.poly.len(), m * k, "the new polynomial rows are m x k");
    assert_eq!(new.block.len(), m * m, "the new block is m x m");

    // Q^T E on this rank's rows (Q^T = I - V T^T V^T), and its rows 0..k on every rank
    let (v, t) = first.border.wy();
    let e = MatRef::from_column_major_slice(new.cross, la, m);
    let v_loc = Mat::<f64>::from_fn(la, k, |l, j| v[(lay.global(l), j)]);
    let mut vte = v_loc.transpose() * e;
    let mut buf: Vec<f64> = (0..k * m).map(|x| vte[(x / m, x % m)]).collect();
    comm.sum_f64(&mut buf);
    vte = Mat::from_fn(k, m, |i, j| buf[i * m + j]);
    let qte = e - &v_loc * (t.transpose() * &vte);
    let mut qte_top = vec![0.0; k * m];
    for i in (0..k).filter(|&i| lay.owner(i) == lay.rank) {
        (0..m).for_each(|j| qte_top[i * m + j] = qte[(lay.local(i), j)]);
    }
    comm.sum_f64(&mut qte_top);
    // rows 0..k of M = Q^T A Q, row-major k x n
    let m_top = first.rows.gather_rows(comm, 0, k, 0, n);

    // G: the QR of [R; P_new], with G^T itself computed alongside (columns k.. of the same matrix
    // receive it)
    let w = k + m;
    let mut a = vec![0.0; w * (k + w)];
    let r = first.border.r();
    for j in 0..k {
        (0..=j).for_each(|i| a[j * w + i] = r[(i, j)]);
        (0..m).for_each(|i| a[j * w + k + i] = new.poly[i * k + j]);
    }
    (0..w).for_each(|j| a[(k + j) * w + j] = 1.0);
    let taus = qr_in_place(&mut a, w, k);
    let r_new = Mat::<f64>::from_fn(k, k, |i, j| if i <= j { a[j * w + i] } else { 0.0 });
    if (0..k).any(|j| !(r_new[(j, j)].abs() > 0.0)) {
        return Err(Error::Numerical(format!(
            "the polynomial block of the extended system has rank < {k}: points not unisolvent"
        )));
    }
    let g = MatRef::from_column_major_slice(&a[k * w..(k + w) * w], w, w).transpose().to_owned();
    // G = I - V T V^T (its k reflectors in compact WY form), so that products with G_n, the last
    // m columns of G, cost O(k) per entry instead of O(m): x G_n = x_{.., k..} - (x V) T V_n^T
    // and G_n^T y = y_{k.., ..} - V_n T^T (V^T y), V_n the last m rows of V
    let gv = explicit_v(MatRef::from_column_major_slice(&a[..k * w], w, k), k);
    let tvn = wy_t(&taus, (gv.transpose() * &gv).as_ref()) * gv.as_ref().subrows(k, m).transpose();
    let times_g_null = |x: MatRef<'_, f64>| -> Mat<f64> { x.subcols(k, m) - (x * &gv) * &tvn };
    let g_null_t_times =
        |y: MatRef<'_, f64>| -> Mat<f64> { y.subrows(k, m) - tvn.transpose() * (gv.transpose() * y) };

    // D = G_n^T Z G_n with Z the (k + m) x (k + m) block of T^T A' T on R's and the new rows
    let z = Mat::<f64>::from_fn(w, w, |i, j| match (i < k, j < k) {
        (true, true) => m_top[i * n + j],
        (true, false) => qte_top[i * m + j - k],
        (false, true) => qte_top[j * m + i - k],
        (false, false) => new.block[(j - k) * m + i - k],
    });
    let zg = times_g_null(z.as_ref());
    let d = g_null_t_times(zg.as_ref());

    // Y = s L^{-1} [M_{k..n,0..k}  (Q^T E)_{k..n}] and Y^T Y from the substitutions kept and
    // one forward substitution of the others through L, the right-hand side riding along; X =
    // Y G_n is never formed: X^T X = G_n^T (Y^T Y) G_n, and the solves take Y and G_n apart
    let (y, y_s) = projected_rhs(first, &g, new.rhs);
    let (yc, gram, z) = first.substitute(job, &qte, &y, new.keys);

    // L22 L22^T = s D - X^T X
    let xtx = g_null_t_times(times_g_null(gram.as_ref()).as_ref());
    let schur: Vec<f64> = (0..m * m).map(|q| s * d[(q / m, q % m)] - xtx[(q / m, q % m)]).collect();
    let l22 = cholesky_small(&schur, m).ok_or_else(|| {
        Error::NotDefinite(format!(
            "the block of the {m} appended centres is not definite to working precision"
        ))
    })?;
    let bordered = Bordered { m, y: yc, l22, g, r_new, zg, qte, m_top };
    let z1 = MatRef::from_column_major_slice(&z, la - b0, 1);
    let lambda = bordered.finish(job, first, z1, &[y_s]).pop().expect("one right-hand side");
    Ok((lambda, bordered))
}

/// The solution of the system `bordered` (the first system bordered by the centres it appended)
/// for the right-hand side `rhs` of its n + m centres, on every rank, as [`extend_solve`] gave it
/// for the first one: a forward and a back substitution through the first factor and small
/// products. Collective.
pub fn solve_bordered(job: &Job<'_>, first: &Factored, bordered: &Bordered, rhs: &[f64]) -> Vec<f64> {
    solve_bordered_many(job, first, bordered, &[rhs]).pop().expect("one right-hand side")
}

/// [`solve_bordered`] for several right-hand sides at once: the forward and the back
/// substitution each read the distributed factor once for all of them, so a few more right-hand
/// sides cost little more than one where the substitutions are bound by the memory they read
/// (the factor's rows, n^2 / 2 entries over the ranks) rather than by their flops. Collective.
pub fn solve_bordered_many(
    job: &Job<'_>,
    first: &Factored,
    bordered: &Bordered,
    rhs: &[&[f64]],
) -> Vec<Vec<f64>> {
    let (k, n) = (first.border.k, first.border.n);
    let lay = first.rows.layout;
    let (la, b0) = (lay.first_local_from(n), lay.first_local_from(k));
    let mut z = LocalRows::zeros(lay, rhs.len(), 0);
    let mut y_s = Vec::with_capacity(rhs.len());
    for (j, rhs) in rhs.iter().enumerate() {
        assert_eq!(rhs.len(), n + bordered.m, "the right-hand side has the bordered system's centres");
        let (y, ys) = projected_rhs(first, &bordered.g, rhs);
        (b0..la).for_each(|l| z.set(l, j, first.sign * y[lay.global(l)]));
        y_s.push(ys);
    }
    forward_substitute(job, first, &mut z);
    let z1 = z.view().submatrix(b0, 0, la - b0, rhs.len());
    bordered.finish(job, first, z1, &y_s)
}

/// y = Q^T r_old (n) and y' = G^T [y_{0..k}; r_new] (k + m) of the right-hand side `rhs` of the
/// n + m centres, on every rank.
fn projected_rhs(first: &Factored, g: &Mat<f64>, rhs: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let (k, n) = (first.border.k, first.border.n);
    let mut y = rhs[..n].to_vec();
    first.border.q_transpose(&mut y);
    let top: Vec<f64> = y[..k].iter().chain(&rhs[n..]).copied().collect();
    let y_s = g.transpose() * MatRef::from_column_major_slice(&top, top.len(), 1);
    (y, (0..top.len()).map(|i| y_s[(i, 0)]).collect())
}

/// Blocked forward substitution of `x`'s columns (this rank's rows k..n) through L of the first
/// factor, in place. Collective.
fn forward_substitute(job: &Job<'_>, first: &Factored, x: &mut LocalRows) {
    let Job { comm, par, .. } = *job;
    let (k, n) = (first.border.k, first.border.n);
    let lay = first.rows.layout;
    let la = lay.first_local_from(n);
    let cols = x.cols;
    let nb = first.panel.max(1);
    let mut q0 = k;
    while q0 < n {
        let q1 = (q0 + nb).min(n);
        let bs = q1 - q0;
        let l11 = first.diagonal_block(comm, q0, q1);
        let rhs = x.gather_rows(comm, q0, q1, 0, cols);
        let mut zb = Mat::<f64>::from_fn(bs, cols, |i, j| rhs[i * cols + j]);
        solve_lower_triangular_in_place(Mat::as_ref(&l11), zb.as_mut(), faer::Par::Seq);
        for l in lay.first_local_from(q0)..lay.first_local_from(q1) {
            let i = lay.global(l) - q0;
            (0..cols).for_each(|j| x.set(l, j, zb[(i, j)]));
        }
        let u0 = lay.first_local_from(q1);
        if u0 < la {
            let below = first.rows.view().submatrix(u0, q0, la - u0, bs);
            let out = x.view_mut().submatrix_mut(u0, 0, la - u0, cols);
            gemm(out, Accum::Add, below, zb.as_ref(), -1.0, par);
        }
        q0 = q1;
    }
}

impl Bordered {
    /// The solutions from the columns of z1 = s L^{-1} y_{k..n} (this rank's rows k..n, one
    /// column per right-hand side) and the y' of each right-hand side: one pass of the back
    /// substitution through L for all of them. Collective.
    fn finish(
        &self,
        job: &Job<'_>,
        first: &Factored,
        z1: MatRef<'_, f64>,
        y_s: &[Vec<f64>],
    ) -> Vec<Vec<f64>> {
        let comm = job.comm;
        let (k, n, m) = (first.border.k, first.border.n, self.m);
        let lay = first.rows.layout;
        let (la, b0) = (lay.first_local_from(n), lay.first_local_from(k));
        let s = first.sign;
        let w = k + m;
        let nb = first.panel.max(1);
        let c = z1.ncols();

        // L22 mu_new = s y'_{k..} - X^T z1, through L22 L22^T; X^T z1 = G_n^T (Y^T z1)
        let (g_first, g_null) = (self.g.as_ref().subcols(0, k), self.g.as_ref().subcols(k, m));
        let ytz = self.y.transpose() * z1;
        let mut buf: Vec<f64> = (0..w * c).map(|q| ytz[(q % w, q / w)]).collect();
        comm.sum_f64(&mut buf);
        let xtz = g_null.transpose() * MatRef::from_column_major_slice(&buf, w, c);
        let mut mu_new = Mat::<f64>::from_fn(m, c, |i, j| s * y_s[j][k + i] - xtz[(i, j)]);
        solve_lower_triangular_in_place(self.l22.as_ref(), mu_new.as_mut(), faer::Par::Seq);
        solve_upper_triangular_in_place(self.l22.transpose(), mu_new.as_mut(), faer::Par::Seq);

        // L^T mu = z1 - X mu_new, X mu_new = Y (G_n mu_new)
        let u = g_null * &mu_new;
        let xm = &self.y * &u;
        let send: Vec<f64> = (0..(la - b0) * c).map(|q| z1[(q / c, q % c)] - xm[(q / c, q % c)]).collect();
        let gathered = all_gather_rows(comm, lay, &send, k..n, c);
        let zz = Mat::<f64>::from_fn(n, c, |i, j| if i < k { 0.0 } else { gathered[(i - k) * c + j] });
        let diagonal = |q0: usize, q1: usize| first.diagonal_block(comm, q0, q1);
        let mu = back_substitute_many(job, &first.rows, (k, n), (nb, &diagonal), zz.as_ref());

        // lambda' = Q' [0; mu; 0; mu_new]: H puts G [0; mu_new] on R's and the new coordinates
        let zgm = &self.zg * &mu_new;
        // R' c = y'_{0..k} - G_first^T [M_{0..k,k..n} mu + (Z G_n mu_new)_{0..k};
        //                               (Q^T E)_{k..n}^T mu + (Z G_n mu_new)_{k..}]
        let mut h = vec![0.0; w * c];
        for j in 0..c {
            let h = &mut h[j * w..(j + 1) * w];
            for l in b0..la {
                let mu_l = mu[(lay.global(l), j)];
                (0..m).for_each(|t| h[k + t] += self.qte[(l, t)] * mu_l);
            }
        }
        comm.sum_f64(&mut h);
        (0..c)
            .map(|j| {
                let mut lambda: Vec<f64> = (0..n).map(|i| mu[(i, j)]).collect();
                (0..k).for_each(|i| lambda[i] = u[(i, j)]);
                first.border.q(&mut lambda);
                let h = &mut h[j * w..(j + 1) * w];
                for i in 0..k {
                    h[i] = (k..n).map(|t| self.m_top[i * n + t] * mu[(t, j)]).sum::<f64>();
                }
                (0..w).for_each(|i| h[i] += zgm[(i, j)]);
                let hm = MatRef::from_column_major_slice(h, w, 1);
                let mut cc = Mat::<f64>::from_fn(k, 1, |i, _| y_s[j][i]) - g_first.transpose() * hm;
                solve_upper_triangular_in_place(self.r_new.as_ref(), cc.as_mut(), faer::Par::Seq);
                lambda.extend((0..m).map(|t| u[(k + t, j)]));
                lambda.extend((0..k).map(|i| cc[(i, 0)]));
                lambda
            })
            .collect()
    }
}
