//! A [`Comm`] that measures the time this rank spends inside communication calls: waiting for the
//! other ranks to arrive at a collective plus moving the data. Work that an overlapped all-gather
//! runs while its messages are in flight ([`Comm::all_gather_f64_while`]) is not counted, so the
//! figure is what the overlap failed to hide.

use std::cell::Cell;
use std::time::Instant;

use super::{Comm, RawComm};

/// `inner` with a stopwatch around every call. Not thread-safe (MPI is called from one thread).
pub struct Timed<'a> {
    inner: &'a dyn Comm,
    seconds: Cell<f64>,
    calls: Cell<u64>,
}

impl<'a> Timed<'a> {
    pub fn new(inner: &'a dyn Comm) -> Self {
        Timed { inner, seconds: Cell::new(0.0), calls: Cell::new(0) }
    }

    /// Seconds spent in communication calls so far on this rank.
    pub fn seconds(&self) -> f64 {
        self.seconds.get()
    }

    /// Communication calls so far on this rank.
    pub fn calls(&self) -> u64 {
        self.calls.get()
    }

    fn timed<R>(&self, f: impl FnOnce() -> R) -> R {
        let t = Instant::now();
        let out = f();
        self.seconds.set(self.seconds.get() + t.elapsed().as_secs_f64());
        self.calls.set(self.calls.get() + 1);
        out
    }

    /// Runs an overlapped call, counting its time less the time of the work it ran.
    fn overlapped(&self, call: impl FnOnce(&mut dyn FnMut() -> bool), work: &mut dyn FnMut() -> bool) {
        let mut busy = 0.0;
        let mut counted = || {
            let t = Instant::now();
            let more = work();
            busy += t.elapsed().as_secs_f64();
            more
        };
        let t = Instant::now();
        call(&mut counted);
        let waited = (t.elapsed().as_secs_f64() - busy).max(0.0);
        self.seconds.set(self.seconds.get() + waited);
        self.calls.set(self.calls.get() + 1);
    }
}

impl Comm for Timed<'_> {
    fn rank(&self) -> usize {
        self.inner.rank()
    }
    fn size(&self) -> usize {
        self.inner.size()
    }
    fn barrier(&self) {
        self.timed(|| self.inner.barrier())
    }
    fn sum_f64(&self, buf: &mut [f64]) {
        self.timed(|| self.inner.sum_f64(buf))
    }
    fn max_f64(&self, buf: &mut [f64]) {
        self.timed(|| self.inner.max_f64(buf))
    }
    fn min_f64(&self, buf: &mut [f64]) {
        self.timed(|| self.inner.min_f64(buf))
    }
    fn sum_u64(&self, buf: &mut [u64]) {
        self.timed(|| self.inner.sum_u64(buf))
    }
    fn broadcast_f64(&self, root: usize, buf: &mut [f64]) {
        self.timed(|| self.inner.broadcast_f64(root, buf))
    }
    fn broadcast_bytes(&self, root: usize, buf: &mut Vec<u8>) {
        self.timed(|| self.inner.broadcast_bytes(root, buf))
    }
    fn all_gather_f64(&self, send: &[f64], counts: &[usize], recv: &mut [f64]) {
        self.timed(|| self.inner.all_gather_f64(send, counts, recv))
    }
    fn gather_bytes(&self, root: usize, send: &[u8]) -> Option<Vec<Vec<u8>>> {
        self.timed(|| self.inner.gather_bytes(root, send))
    }
    fn shift_f64(&self, dest: usize, source: usize, send: &[f64], recv: &mut [f64]) {
        self.timed(|| self.inner.shift_f64(dest, source, send, recv))
    }
    fn all_gather_f32(&self, send: &[f32], counts: &[usize], recv: &mut [f32]) {
        self.timed(|| self.inner.all_gather_f32(send, counts, recv))
    }
    fn shift_f32(&self, dest: usize, source: usize, send: &[f32], recv: &mut [f32]) {
        self.timed(|| self.inner.shift_f32(dest, source, send, recv))
    }
    fn all_gather_f64_while(
        &self,
        send: &[f64],
        counts: &[usize],
        recv: &mut [f64],
        work: &mut dyn FnMut() -> bool,
    ) {
        self.overlapped(|w| self.inner.all_gather_f64_while(send, counts, recv, w), work)
    }
    fn all_gather_f32_while(
        &self,
        send: &[f32],
        counts: &[usize],
        recv: &mut [f32],
        work: &mut dyn FnMut() -> bool,
    ) {
        self.overlapped(|w| self.inner.all_gather_f32_while(send, counts, recv, w), work)
    }
    fn raw(&self) -> Option<RawComm> {
        self.inner.raw()
    }
    fn fortran_handle(&self) -> Option<i32> {
        self.inner.fortran_handle()
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
        // the 200 ms of work are not waiting (counted, they would make at least 0.2 s)
        assert!(timed.seconds() < 0.2, "{}", timed.seconds());
    }
}
