//! [`Comm`] over MPI (rsmpi), and the process-wide MPI life cycle: start, abort on a panic, finish.
//! The only file of the crate that imports the MPI bindings. MPI is called from the calling thread
//! only (the rayon workers never communicate).

use mpi::collective::SystemOperation;
use mpi::datatype::{Partition, PartitionMut};
use mpi::environment::Universe;
use mpi::raw::AsRaw;
use mpi::topology::{Color, SimpleCommunicator};
use mpi::traits::*;
use mpi::Count;

use super::Comm;

/// The raw communicator handle, for MPI-IO through the HDF5 library.
pub type RawComm = mpi::ffi::MPI_Comm;

/// MPI, started for the life of the process. Dropping it finalises MPI.
pub struct World {
    universe: Universe,
}

impl World {
    /// Starts MPI (None when it cannot be started) and installs a panic hook that aborts every
    /// rank, so that a panic on one rank never leaves the others waiting in a collective.
    pub fn start() -> Option<World> {
        let universe = mpi::initialize()?;
        let default_hook = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            default_hook(info);
            crate::note!("volspline: internal error (panic); aborting all ranks");
            abort_all(70);
        }));
        Some(World { universe })
    }

    /// MPI_COMM_WORLD as a [`Comm`].
    pub fn comm(&self) -> MpiComm {
        MpiComm::new(self.universe.world())
    }
}

/// Ends every rank of the job with `code` (MPI_Abort on the world communicator).
pub fn abort_all(code: i32) -> ! {
    unsafe {
        mpi::ffi::MPI_Abort(mpi::ffi::RSMPI_COMM_WORLD, code);
    }
    std::process::exit(code)
}

/// A communicator through rsmpi.
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

    fn all_reduce<T: Equivalence + Clone>(&self, buf: &mut [T], op: SystemOperation) {
        if self.size > 1 {
            let send = buf.to_vec();
            self.comm.all_reduce_into(&send[..], buf, op);
        }
    }

    fn all_gather<T: Equivalence + Copy>(&self, send: &[T], counts: &[usize], recv: &mut [T]) {
        if self.size == 1 {
            recv.copy_from_slice(send);
            return;
        }
        let (c, d) = displacements(counts);
        let mut part = PartitionMut::new(recv, c, d);
        self.comm.all_gather_varcount_into(send, &mut part);
    }

    /// The personalised exchange as MPI_Alltoallv (see [`Comm::all_to_all_f64`]).
    fn all_to_all<T: Equivalence + Copy>(
        &self,
        send: &[T],
        send_counts: &[usize],
        recv: &mut [T],
        recv_counts: &[usize],
    ) {
        if self.size == 1 {
            recv.copy_from_slice(send);
            return;
        }
        let (c, d) = displacements(send_counts);
        let out = Partition::new(send, c, d);
        let (c, d) = displacements(recv_counts);
        let mut into = PartitionMut::new(recv, c, d);
        self.comm.all_to_all_varcount_into(&out, &mut into);
    }

    /// The all-gather as MPI_Iallgatherv, with `work` run while it is in flight (see
    /// [`Comm::all_gather_f64_while`]); MPI_Test between the pieces of work drives its progress.
    fn all_gather_while<T: Equivalence + Copy>(
        &self,
        send: &[T],
        counts: &[usize],
        recv: &mut [T],
        work: &mut dyn FnMut() -> bool,
    ) {
        if self.size == 1 {
            recv.copy_from_slice(send);
            work();
            return;
        }
        let (c, d) = displacements(counts);
        let mut part = PartitionMut::new(recv, c, d);
        mpi::request::scope(|scope| {
            overlap(self.comm.immediate_all_gather_varcount_into(scope, send, &mut part), work);
        });
    }

    /// The broadcast as MPI_Ibcast, with `work` run while it is in flight (see
    /// [`Comm::broadcast_f64_while`]); work left when the broadcast completes runs after it.
    fn broadcast_while<T: Equivalence + Copy>(
        &self,
        root: usize,
        buf: &mut [T],
        work: &mut dyn FnMut() -> bool,
    ) {
        if self.size == 1 {
            while work() {}
            return;
        }
        let more = mpi::request::scope(|scope| {
            overlap(self.comm.process_at_rank(root as i32).immediate_broadcast_into(scope, buf), work)
        });
        while more && work() {}
    }

    fn shift<T: Equivalence + Copy>(&self, dest: usize, source: usize, send: &[T], recv: &mut [T]) {
        if dest == self.rank && source == self.rank {
            recv.copy_from_slice(send);
            return;
        }
        let d = self.comm.process_at_rank(dest as i32);
        let s = self.comm.process_at_rank(source as i32);
        mpi::point_to_point::send_receive_into(send, &d, recv, &s);
    }
}

/// Runs `work` while `req` is in flight, testing the request between its pieces (which drives
/// MPI's progress), and waits for it once `work` has nothing more to do. Returns whether `work`
/// has more to do (the request completed first).
fn overlap<'a, D: ?Sized, S: mpi::request::Scope<'a>>(
    mut req: mpi::request::Request<'a, D, S>,
    work: &mut dyn FnMut() -> bool,
) -> bool {
    while work() {
        match req.test() {
            Ok(_) => return true,
            Err(pending) => req = pending,
        }
    }
    req.wait_without_status();
    false
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
        self.all_reduce(buf, SystemOperation::sum());
    }
    fn max_f64(&self, buf: &mut [f64]) {
        self.all_reduce(buf, SystemOperation::max());
    }
    fn min_f64(&self, buf: &mut [f64]) {
        self.all_reduce(buf, SystemOperation::min());
    }
    fn sum_u64(&self, buf: &mut [u64]) {
        self.all_reduce(buf, SystemOperation::sum());
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
        self.all_gather(send, counts, recv);
    }
    fn all_to_all_f64(&self, send: &[f64], send_counts: &[usize], recv: &mut [f64], recv_counts: &[usize]) {
        self.all_to_all(send, send_counts, recv, recv_counts);
    }
    fn all_gather_f32(&self, send: &[f32], counts: &[usize], recv: &mut [f32]) {
        self.all_gather(send, counts, recv);
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
        self.shift(dest, source, send, recv);
    }
    fn shift_f32(&self, dest: usize, source: usize, send: &[f32], recv: &mut [f32]) {
        self.shift(dest, source, send, recv);
    }
    fn all_gather_f64_while(
        &self,
        send: &[f64],
        counts: &[usize],
        recv: &mut [f64],
        work: &mut dyn FnMut() -> bool,
    ) {
        self.all_gather_while(send, counts, recv, work);
    }
    fn all_gather_f32_while(
        &self,
        send: &[f32],
        counts: &[usize],
        recv: &mut [f32],
        work: &mut dyn FnMut() -> bool,
    ) {
        self.all_gather_while(send, counts, recv, work);
    }
    fn broadcast_f64_while(&self, root: usize, buf: &mut [f64], work: &mut dyn FnMut() -> bool) {
        self.broadcast_while(root, buf, work);
    }
    fn sum_f64_while(&self, buf: &mut [f64], work: &mut dyn FnMut() -> bool) {
        if self.size == 1 {
            while work() {}
            return;
        }
        let send = buf.to_vec();
        let more = mpi::request::scope(|scope| {
            overlap(self.comm.immediate_all_reduce_into(scope, &send[..], buf, SystemOperation::sum()), work)
        });
        while more && work() {}
    }
    fn split(&self, color: usize, key: usize) -> Box<dyn Comm + '_> {
        let sub = self
            .comm
            .split_by_color_with_key(Color::with_value(color as i32), key as i32)
            .expect("every rank passes a defined colour");
        Box::new(MpiComm::new(sub))
    }
    fn raw(&self) -> Option<RawComm> {
        Some(self.comm.as_raw())
    }
    fn fortran_handle(&self) -> Option<i32> {
        // SAFETY: the handle is a valid communicator for as long as `self` lives; the conversion
        // only reads it.
        Some(unsafe { mpi::ffi::MPI_Comm_c2f(self.comm.as_raw()) })
    }
}
