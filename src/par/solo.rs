//! One process, no MPI: every collective is the identity.

use super::Comm;

/// The communicator of a single process.
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
    fn sum_u64(&self, _: &mut [u64]) {}
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
    fn all_to_all_f64(&self, send: &[f64], _: &[usize], recv: &mut [f64], _: &[usize]) {
        recv.copy_from_slice(send);
    }
    fn all_gather_f32(&self, send: &[f32], _: &[usize], recv: &mut [f32]) {
        recv.copy_from_slice(send);
    }
    fn shift_f32(&self, _: usize, _: usize, send: &[f32], recv: &mut [f32]) {
        recv.copy_from_slice(send);
    }
    fn split(&self, _: usize, _: usize) -> Box<dyn Comm + '_> {
        Box::new(Solo)
    }
}
