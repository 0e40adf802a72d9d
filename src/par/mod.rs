//! Communication between ranks: the [`Comm`] interface every collective stage is written against,
//! typed collectives over it ([`Wire`] values), and the agreement on failures that keeps a job from
//! hanging when one rank fails.
//!
//! [`Comm`] has two implementations: [`Solo`] (one process, no MPI) and [`mpi::MpiComm`] (any MPI
//! communicator). `mpi.rs` is the only file of the crate that imports the MPI bindings; everything
//! else sees ranks through this trait, so the solvers and commands are the same code in unit tests,
//! on one process and under `mpirun`.
//!
//! [`Timed`] wraps any [`Comm`] and adds up the time its calls spend waiting: the "comm wait" of
//! the stage table.
//!
//! The failure protocol: a stage whose local step can fail on some ranks calls [`agree`] before the
//! next collective. Every rank then returns the same outcome: `Ok` everywhere, or the error of the
//! lowest failing rank, carried to the others as [`Error::Remote`] with the original error (its kind
//! included) inside. Callers that branch on the kind of an error (the Cholesky solver's fallback to
//! LU) look through `Remote` with [`Error::root`], so every rank takes the same branch.

pub mod mpi;
mod solo;
mod timed;
mod wire;

pub use solo::Solo;
pub use timed::{CallKind, Timed};
pub use wire::{Reader, Wire};

use std::ops::Range;

use crate::error::{Error, Result};

/// The handle a parallel file library needs to open a file on all ranks (MPI-IO).
pub type RawComm = mpi::RawComm;

/// A group of ranks. Every method is collective over all ranks unless it says otherwise, and every
/// rank must pass buffers of the same length.
pub trait Comm {
    fn rank(&self) -> usize;
    fn size(&self) -> usize;
    fn barrier(&self);
    /// Element-wise sum over ranks, in place.
    fn sum_f64(&self, buf: &mut [f64]);
    /// Element-wise maximum over ranks, in place.
    fn max_f64(&self, buf: &mut [f64]);
    /// Element-wise minimum over ranks, in place.
    fn min_f64(&self, buf: &mut [f64]);
    /// Element-wise sum over ranks of counts, in place.
    fn sum_u64(&self, buf: &mut [u64]);
    /// Copies `buf` from `root` to every rank (lengths must agree).
    fn broadcast_f64(&self, root: usize, buf: &mut [f64]);
    /// Copies `buf` from `root` to every rank; other ranks' buffers are resized.
    fn broadcast_bytes(&self, root: usize, buf: &mut Vec<u8>);
    /// Concatenation of every rank's `send` in rank order; `counts[r]` is rank r's length.
    fn all_gather_f64(&self, send: &[f64], counts: &[usize], recv: &mut [f64]);
    /// Every rank's bytes on `root` (None on the others).
    fn gather_bytes(&self, root: usize, send: &[u8]) -> Option<Vec<Vec<u8>>>;
    /// Sends `send` to rank `dest` and receives the message of rank `source` into `recv` (whose
    /// length the caller knows). Point-to-point; `dest` must at the same time receive from this
    /// rank and `source` send to it (a shift or a pairwise exchange), so nothing deadlocks.
    fn shift_f64(&self, dest: usize, source: usize, send: &[f64], recv: &mut [f64]);
    /// Personalised exchange (MPI_Alltoallv): `send` holds, in rank order, `send_counts[r]`
    /// values for each rank r, and `recv` receives, in rank order, `recv_counts[r]` values from
    /// each rank r (the caller knows both; each rank's `send_counts[r]` must equal rank r's
    /// `recv_counts` entry for it). Redistributes a matrix between layouts.
    fn all_to_all_f64(&self, send: &[f64], send_counts: &[usize], recv: &mut [f64], recv_counts: &[usize]);
    /// [`Comm::all_gather_f64`] of single-precision values (the factors of a mixed-precision
    /// solve travel at half the bytes).
    fn all_gather_f32(&self, send: &[f32], counts: &[usize], recv: &mut [f32]);
    /// [`Comm::shift_f64`] of single-precision values.
    fn shift_f32(&self, dest: usize, source: usize, send: &[f32], recv: &mut [f32]);
    /// [`Comm::all_gather_f64`] that calls `work` while the messages are in flight (a look-ahead
    /// factorisation puts its trailing update there): once before waiting, and again as long as
    /// the gather has not completed and `work` returned true (it has more to do). `work` must not
    /// communicate. Without non-blocking collectives, `work` runs once and the gather follows.
    fn all_gather_f64_while(
        &self,
        send: &[f64],
        counts: &[usize],
        recv: &mut [f64],
        work: &mut dyn FnMut() -> bool,
    ) {
        work();
        self.all_gather_f64(send, counts, recv);
    }
    /// [`Comm::broadcast_f64`] that calls `work` while the message is in flight, as
    /// [`Comm::all_gather_f64_while`] does: the 2D LU broadcasts its next panel along the process
    /// rows during the trailing update. Every rank must call this one (a blocking and a
    /// non-blocking broadcast do not match). Without non-blocking collectives, `work` runs until
    /// it has nothing more to do and the broadcast follows.
    fn broadcast_f64_while(&self, root: usize, buf: &mut [f64], work: &mut dyn FnMut() -> bool) {
        while work() {}
        self.broadcast_f64(root, buf);
    }
    /// [`Comm::sum_f64`] that calls `work` while the sums are in flight, as
    /// [`Comm::broadcast_f64_while`] does (the Householder QR forms its Y = V T^T while W is
    /// summed): `work` runs until it has nothing more to do, the rest of it after the sum where
    /// the sum completes first. Every rank must call this one (a blocking and a non-blocking
    /// reduction do not match). Without non-blocking collectives, `work` runs and the sum follows.
    fn sum_f64_while(&self, buf: &mut [f64], work: &mut dyn FnMut() -> bool) {
        while work() {}
        self.sum_f64(buf);
    }
    /// [`Comm::all_gather_f64_while`] of single-precision values.
    fn all_gather_f32_while(
        &self,
        send: &[f32],
        counts: &[usize],
        recv: &mut [f32],
        work: &mut dyn FnMut() -> bool,
    ) {
        work();
        self.all_gather_f32(send, counts, recv);
    }
    /// The ranks with the same `color` as a communicator of their own, ordered by `key` (ties by
    /// rank here), as MPI_Comm_split makes them: the rows and columns of a 2D process grid.
    /// Collective over all ranks of `self`.
    fn split(&self, color: usize, key: usize) -> Box<dyn Comm + '_>;
    /// The communicator handle for collective file access (MPI-IO), where there is one.
    fn raw(&self) -> Option<RawComm> {
        None
    }
    /// The communicator as a Fortran handle (`MPI_Comm_c2f`), for libraries with a Fortran
    /// interface (MUMPS), where there is an MPI communicator.
    fn fortran_handle(&self) -> Option<i32> {
        None
    }
}

impl dyn Comm + '_ {
    /// `root`'s value on every rank. `root` passes `Some`, the others `None`. Collective.
    pub fn broadcast_value<T: Wire>(&self, root: usize, value: Option<T>) -> T {
        let mut bytes = Vec::new();
        if self.rank() == root {
            value.as_ref().expect("the root of a broadcast passes its value").put(&mut bytes);
        }
        self.broadcast_bytes(root, &mut bytes);
        match value {
            Some(v) if self.rank() == root => v,
            _ => T::decode(&bytes),
        }
    }

    /// Every rank's value on `root`, in rank order (None on the other ranks). Collective.
    pub fn gather_values<T: Wire>(&self, root: usize, value: &T) -> Option<Vec<T>> {
        let mut bytes = Vec::new();
        value.put(&mut bytes);
        self.gather_bytes(root, &bytes).map(|all| all.iter().map(|b| T::decode(b)).collect())
    }
}

/// Makes every rank return the same result: Ok on all ranks if all succeeded, otherwise the error
/// of the lowest failing rank, as [`Error::Remote`] (kind kept) on the others. Collective; call it
/// before any collective that a failed rank would not reach.
pub fn agree<T>(comm: &dyn Comm, local: Result<T>) -> Result<T> {
    let mut who = [if local.is_err() { comm.rank() as f64 } else { f64::INFINITY }];
    comm.min_f64(&mut who);
    if who[0].is_infinite() {
        return local;
    }
    let root = who[0] as usize;
    let mine = if root == comm.rank() { local.as_ref().err().cloned() } else { None };
    let error: Error = comm.broadcast_value(root, mine);
    match local {
        Err(e) if root == comm.rank() => Err(e),
        _ => Err(Error::Remote { rank: root, source: Box::new(error) }),
    }
}

/// Runs `f` on rank 0 only (a file write, say) and agrees on its outcome. Collective.
pub fn on_root(comm: &dyn Comm, f: impl FnOnce() -> Result<()>) -> Result<()> {
    let local = if comm.rank() == 0 { f() } else { Ok(()) };
    agree(comm, local)
}

/// The items of `0..n` that rank `rank` of `comm` takes when they are dealt over the ranks in
/// contiguous blocks, in order (the blocks' sizes differ by one at most).
pub fn block(comm: &dyn Comm, n: usize, rank: usize) -> Range<usize> {
    let size = comm.size();
    rank * n / size..(rank + 1) * n / size
}

/// Every rank's `width` values per item of its [`block`] of `n` items (`mine`, this rank's),
/// all-gathered in the order of the items: `n * width` values on every rank. Collective.
pub fn all_gather_blocks(comm: &dyn Comm, n: usize, width: usize, mine: &[f64]) -> Vec<f64> {
    let counts: Vec<usize> = (0..comm.size()).map(|r| block(comm, n, r).len() * width).collect();
    let mut all = vec![0.0; n * width];
    comm.all_gather_f64(mine, &counts, &mut all);
    all
}

/// Largest value of `x` over ranks. Collective.
pub fn max_over_ranks(comm: &dyn Comm, x: f64) -> f64 {
    let mut v = [x];
    comm.max_f64(&mut v);
    v[0]
}
