//! A [`Comm`] that measures the time this rank spends inside communication calls: waiting for the
//! other ranks to arrive at a collective plus moving the data. Work that an overlapped all-gather
//! runs while its messages are in flight ([`Comm::all_gather_f64_while`]) is not counted, so the
//! figure is what the overlap failed to hide.

use std::cell::Cell;
use std::rc::Rc;
use std::time::Instant;

use super::{Comm, RawComm};

/// The kinds of communication call [`Timed`] tells apart.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CallKind {
    /// Reductions, broadcasts, gathers to one rank, barriers.
    Reduce,
    /// All-gathers of at most `SMALL` values in all (the pivot searches of LU).
    SmallGather,
    /// Larger all-gathers (the block rows of the factorisations) and all-to-all exchanges.
    LargeGather,
    /// Point-to-point exchanges (row interchanges).
    Shift,
}

impl CallKind {
    pub const ALL: [CallKind; 4] =
        [CallKind::Reduce, CallKind::SmallGather, CallKind::LargeGather, CallKind::Shift];

    pub fn name(self) -> &'static str {
        match self {
            CallKind::Reduce => "reduce",
            CallKind::SmallGather => "small_gather",
            CallKind::LargeGather => "large_gather",
            CallKind::Shift => "shift",
        }
    }
}

/// All-gathers of at most this many values count as [`CallKind::SmallGather`].
pub const SMALL: usize = 1024;

fn gather_kind(len: usize) -> CallKind {
    if len <= SMALL {
        CallKind::SmallGather
    } else {
        CallKind::LargeGather
    }
}

/// `inner` with a stopwatch around every call. Not thread-safe (MPI is called from one thread).
/// The communicators split from it ([`Comm::split`]) are timed too, into the same counters, so
/// the figures of a solver on a 2D process grid include its row and column communicators.
pub struct Timed<'a> {
    inner: Inner<'a>,
    counters: Rc<Counters>,
}

#[derive(Default)]
struct Counters {
    seconds: [Cell<f64>; 4],
    calls: Cell<u64>,
}

enum Inner<'a> {
    Borrowed(&'a dyn Comm),
    Split(Box<dyn Comm + 'a>),
}

impl<'a> Timed<'a> {
    pub fn new(inner: &'a dyn Comm) -> Self {
        Timed { inner: Inner::Borrowed(inner), counters: Rc::default() }
    }

    fn comm(&self) -> &dyn Comm {
        match &self.inner {
            Inner::Borrowed(c) => *c,
            Inner::Split(c) => c.as_ref(),
        }
    }

    /// Seconds spent in communication calls so far on this rank.
    pub fn seconds(&self) -> f64 {
        self.counters.seconds.iter().map(Cell::get).sum()
    }

    /// Seconds spent in calls of `kind` so far on this rank.
    pub fn seconds_in(&self, kind: CallKind) -> f64 {
        self.counters.seconds[kind as usize].get()
    }

    /// Communication calls so far on this rank.
    pub fn calls(&self) -> u64 {
        self.counters.calls.get()
    }

    fn add(&self, kind: CallKind, seconds: f64) {
        let c = &self.counters.seconds[kind as usize];
        c.set(c.get() + seconds);
        self.counters.calls.set(self.counters.calls.get() + 1);
    }

    fn timed<R>(&self, kind: CallKind, f: impl FnOnce() -> R) -> R {
        let t = Instant::now();
        let out = f();
        self.add(kind, t.elapsed().as_secs_f64());
        out
    }

    /// Runs an overlapped call, counting its time less the time of the work it ran.
    fn overlapped(
        &self,
        kind: CallKind,
        call: impl FnOnce(&mut dyn FnMut() -> bool),
        work: &mut dyn FnMut() -> bool,
    ) {
        let mut busy = 0.0;
        let mut counted = || {
            let t = Instant::now();
            let more = work();
            busy += t.elapsed().as_secs_f64();
            more
        };
        let t = Instant::now();
        call(&mut counted);
        self.add(kind, (t.elapsed().as_secs_f64() - busy).max(0.0));
    }
}

impl Comm for Timed<'_> {
    fn rank(&self) -> usize {
        self.comm().rank()
    }
    fn size(&self) -> usize {
        self.comm().size()
    }
    fn barrier(&self) {
        self.timed(CallKind::Reduce, || self.comm().barrier())
    }
    fn sum_f64(&self, buf: &mut [f64]) {
        self.timed(CallKind::Reduce, || self.comm().sum_f64(buf))
    }
    fn max_f64(&self, buf: &mut [f64]) {
        self.timed(CallKind::Reduce, || self.comm().max_f64(buf))
    }
    fn min_f64(&self, buf: &mut [f64]) {
        self.timed(CallKind::Reduce, || self.comm().min_f64(buf))
    }
    fn sum_u64(&self, buf: &mut [u64]) {
        self.timed(CallKind::Reduce, || self.comm().sum_u64(buf))
    }
    fn broadcast_f64(&self, root: usize, buf: &mut [f64]) {
        self.timed(CallKind::Reduce, || self.comm().broadcast_f64(root, buf))
    }
    fn broadcast_bytes(&self, root: usize, buf: &mut Vec<u8>) {
        self.timed(CallKind::Reduce, || self.comm().broadcast_bytes(root, buf))
    }
    fn all_gather_f64(&self, send: &[f64], counts: &[usize], recv: &mut [f64]) {
        self.timed(gather_kind(recv.len()), || self.comm().all_gather_f64(send, counts, recv))
    }
    fn gather_bytes(&self, root: usize, send: &[u8]) -> Option<Vec<Vec<u8>>> {
        self.timed(CallKind::Reduce, || self.comm().gather_bytes(root, send))
    }
    fn shift_f64(&self, dest: usize, source: usize, send: &[f64], recv: &mut [f64]) {
        self.timed(CallKind::Shift, || self.comm().shift_f64(dest, source, send, recv))
    }
    fn all_to_all_f64(&self, send: &[f64], send_counts: &[usize], recv: &mut [f64], recv_counts: &[usize]) {
        self.timed(gather_kind(recv.len()), || {
            self.comm().all_to_all_f64(send, send_counts, recv, recv_counts)
        })
    }
    fn all_gather_f32(&self, send: &[f32], counts: &[usize], recv: &mut [f32]) {
        self.timed(gather_kind(recv.len()), || self.comm().all_gather_f32(send, counts, recv))
    }
    fn shift_f32(&self, dest: usize, source: usize, send: &[f32], recv: &mut [f32]) {
        self.timed(CallKind::Shift, || self.comm().shift_f32(dest, source, send, recv))
    }
    fn all_gather_f64_while(
        &self,
        send: &[f64],
        counts: &[usize],
        recv: &mut [f64],
        work: &mut dyn FnMut() -> bool,
    ) {
        let kind = gather_kind(recv.len());
        self.overlapped(kind, |w| self.comm().all_gather_f64_while(send, counts, recv, w), work)
    }
    fn all_gather_f32_while(
        &self,
        send: &[f32],
        counts: &[usize],
        recv: &mut [f32],
        work: &mut dyn FnMut() -> bool,
    ) {
        let kind = gather_kind(recv.len());
        self.overlapped(kind, |w| self.comm().all_gather_f32_while(send, counts, recv, w), work)
    }
    fn broadcast_f64_while(&self, root: usize, buf: &mut [f64], work: &mut dyn FnMut() -> bool) {
        self.overlapped(CallKind::Reduce, |w| self.comm().broadcast_f64_while(root, buf, w), work)
    }
    fn sum_f64_while(&self, buf: &mut [f64], work: &mut dyn FnMut() -> bool) {
        self.overlapped(CallKind::Reduce, |w| self.comm().sum_f64_while(buf, w), work)
    }
    fn split(&self, color: usize, key: usize) -> Box<dyn Comm + '_> {
        let sub = self.timed(CallKind::Reduce, || self.comm().split(color, key));
        Box::new(Timed { inner: Inner::Split(sub), counters: Rc::clone(&self.counters) })
    }
    fn raw(&self) -> Option<RawComm> {
        self.comm().raw()
    }
    fn fortran_handle(&self) -> Option<i32> {
        self.comm().fortran_handle()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::par::Solo;

    #[test]
    fn counts_calls_and_leaves_out_the_overlapped_work() {
        let timed = Timed::new(&Solo);
        let mut v = [1.0, 2.0];
        timed.sum_f64(&mut v);
        let mut recv = [0.0; 2];
        let mut runs = 0;
        let mut work = || {
            runs += 1;
            std::thread::sleep(std::time::Duration::from_millis(200));
            false
        };
        timed.all_gather_f64_while(&[3.0, 4.0], &[2], &mut recv, &mut work);
        assert_eq!(recv, [3.0, 4.0]);
        assert_eq!(runs, 1);
        assert_eq!(timed.calls(), 2);
        assert_eq!(
            timed.seconds(),
            timed.seconds_in(CallKind::Reduce) + timed.seconds_in(CallKind::SmallGather)
        );
        // the 200 ms of work are not waiting (counted, they would make at least 0.2 s)
        assert!(timed.seconds() < 0.2, "{}", timed.seconds());
    }
}
