//! The collective operations the solvers and the pipeline need, over MPI or over one process.

use mpi::collective::SystemOperation;
use mpi::datatype::PartitionMut;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use mpi::Count;

use crate::error::Result;

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
    /// The MPI communicator, where there is one (for MPI-IO).
    fn mpi(&self) -> Option<&SimpleCommunicator> {
        None
    }
}

/// Makes every rank return the same result: Ok on all ranks if all succeeded, otherwise the error
/// of the lowest failing rank (as [`crate::error::Error::Rank`] on the others). Collective; call it
/// before any collective that a failed rank would not reach.
pub fn agree<T>(comm: &dyn Comm, local: Result<T>) -> Result<T> {
    match super::first_error(comm, local.as_ref().err()) {
        None => local,
        Some(e) => Err(e),
    }
}

/// One process, no MPI.
#[derive(Debug, Default, Clone, Copy)]
pub struct Solo;

impl Comm for Solo {
    fn rank(&self) -> usize {
        0
    }
    fn size(&self) -> usize {
        1
    }
    fn barrier(&self) {}
    fn sum_f64(&self, _: &mut [f64]) {}
    fn max_f64(&self, _: &mut [f64]) {}
    fn min_f64(&self, _: &mut [f64]) {}
    fn broadcast_f64(&self, _: usize, _: &mut [f64]) {}
    fn broadcast_bytes(&self, _: usize, _: &mut Vec<u8>) {}
    fn all_gather_f64(&self, send: &[f64], _: &[usize], recv: &mut [f64]) {
        recv.copy_from_slice(send);
    }
    fn gather_bytes(&self, _: usize, send: &[u8]) -> Option<Vec<Vec<u8>>> {
        Some(vec![send.to_vec()])
    }
    fn shift_f64(&self, _: usize, _: usize, send: &[f64], recv: &mut [f64]) {
        recv.copy_from_slice(send);
    }
}

/// MPI_COMM_WORLD (or any communicator) through rsmpi. MPI is called from the calling thread only.
pub struct MpiComm {
    comm: SimpleCommunicator,
    rank: usize,
    size: usize,
}

impl MpiComm {
    pub fn new(comm: SimpleCommunicator) -> Self {
        let (rank, size) = (comm.rank() as usize, comm.size() as usize);
        MpiComm { comm, rank, size }
    }
}

fn displacements(counts: &[usize]) -> (Vec<Count>, Vec<Count>) {
    let c: Vec<Count> = counts.iter().map(|&x| x as Count).collect();
    let mut d = Vec::with_capacity(c.len());
    let mut acc: Count = 0;
    for &x in &c {
        d.push(acc);
        acc += x;
    }
    (c, d)
}

impl Comm for MpiComm {
    fn rank(&self) -> usize {
        self.rank
    }
    fn size(&self) -> usize {
        self.size
    }
    fn barrier(&self) {
        self.comm.barrier();
    }
    fn sum_f64(&self, buf: &mut [f64]) {
        if self.size > 1 {
            let send = buf.to_vec();
            self.comm.all_reduce_into(&send[..], buf, SystemOperation::sum());
        }
    }
    fn max_f64(&self, buf: &mut [f64]) {
        if self.size > 1 {
            let send = buf.to_vec();
            self.comm.all_reduce_into(&send[..], buf, SystemOperation::max());
        }
    }
    fn min_f64(&self, buf: &mut [f64]) {
        if self.size > 1 {
            let send = buf.to_vec();
            self.comm.all_reduce_into(&send[..], buf, SystemOperation::min());
        }
    }
    fn broadcast_f64(&self, root: usize, buf: &mut [f64]) {
        if self.size > 1 {
            self.comm.process_at_rank(root as i32).broadcast_into(buf);
        }
    }
    fn broadcast_bytes(&self, root: usize, buf: &mut Vec<u8>) {
        if self.size > 1 {
            let p = self.comm.process_at_rank(root as i32);
            let mut len = [buf.len() as u64];
            p.broadcast_into(&mut len[..]);
            buf.resize(len[0] as usize, 0);
            p.broadcast_into(&mut buf[..]);
        }
    }
    fn all_gather_f64(&self, send: &[f64], counts: &[usize], recv: &mut [f64]) {
        if self.size == 1 {
            recv.copy_from_slice(send);
            return;
        }
        let (c, d) = displacements(counts);
        let mut part = PartitionMut::new(recv, c, d);
        self.comm.all_gather_varcount_into(send, &mut part);
    }
    fn gather_bytes(&self, root: usize, send: &[u8]) -> Option<Vec<Vec<u8>>> {
        if self.size == 1 {
            return Some(vec![send.to_vec()]);
        }
        let p = self.comm.process_at_rank(root as i32);
        if self.rank == root {
            let mut counts = vec![0u64; self.size];
            p.gather_into_root(&(send.len() as u64), &mut counts[..]);
            let counts: Vec<usize> = counts.into_iter().map(|c| c as usize).collect();
            let (c, d) = displacements(&counts);
            let mut all = vec![0u8; counts.iter().sum()];
            let mut part = PartitionMut::new(&mut all[..], c, d.clone());
            p.gather_varcount_into_root(send, &mut part);
            Some(
                counts
                    .iter()
                    .zip(&d)
                    .map(|(&n, &off)| all[off as usize..off as usize + n].to_vec())
                    .collect(),
            )
        } else {
            p.gather_into(&(send.len() as u64));
            p.gather_varcount_into(send);
            None
        }
    }
    fn shift_f64(&self, dest: usize, source: usize, send: &[f64], recv: &mut [f64]) {
        if dest == self.rank && source == self.rank {
            recv.copy_from_slice(send);
            return;
        }
        let d = self.comm.process_at_rank(dest as i32);
        let s = self.comm.process_at_rank(source as i32);
        mpi::point_to_point::send_receive_into(send, &d, recv, &s);
    }
    fn mpi(&self) -> Option<&SimpleCommunicator> {
        Some(&self.comm)
    }
}
