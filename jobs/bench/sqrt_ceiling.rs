//! The ceiling the hardware square root puts on grid evaluation: the inner loop of the evaluator
//! (8 lanes, blocks of 512 centres, one core) with the kernel r computed three ways: the exactly
//! rounded square root of the hardware for every centre (volspline takes every third lane group's
//! roots from a multiply-add iteration instead, which runs beside it, and so passes this ceiling),
//! AVX-512's 14-bit reciprocal square root estimate refined by two Newton steps (full precision,
//! not exactly rounded) and by one (about 28 bits, too few for sums whose weights cancel). Prints
//! one CSV line per variant: name, kernel evaluations per second, largest relative difference
//! from the exact sum. Run by `jobs/bench-eval`.
//!
//!     cargo run --release --example sqrt_ceiling

use std::time::Instant;

const CENTRES: usize = 512;
const POINTS: usize = 200_000;

fn main() {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx512f") {
            // SAFETY: AVX-512F is present (checked just above).
            unsafe { x86::run() };
            return;
        }
    }
    eprintln!("sqrt_ceiling: needs x86_64 with AVX-512F; nothing measured");
}

/// Random centres and weights in [-0.5, 0.5), the same on every run.
fn data() -> [Vec<f64>; 4] {
    let mut s = 1u64;
    let mut rnd = || {
        s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    std::array::from_fn(|_| (0..CENTRES).map(|_| rnd()).collect())
}

#[cfg(target_arch = "x86_64")]
mod x86 {
    use super::*;
    use std::arch::x86_64::*;

    /// Sum over the centres of w_j g(|x - c_j|) for POINTS points along a line, with g computed
    /// by `newton` Newton steps from rsqrt14 (None: the exactly rounded square root).
    #[target_feature(enable = "avx512f")]
    unsafe fn sums(d: &[Vec<f64>; 4], newton: Option<u32>, out: &mut [f64]) {
        let [cx, cy, cz, w] = d;
        let (half, three_halves, tiny) = (_mm512_set1_pd(0.5), _mm512_set1_pd(1.5), _mm512_set1_pd(1e-300));
        for (i, o) in out.iter_mut().enumerate() {
            let x = i as f64 / POINTS as f64 - 0.5;
            let (vx, vy, vz) = (_mm512_set1_pd(x), _mm512_set1_pd(0.3), _mm512_set1_pd(-0.2));
            let mut a = _mm512_setzero_pd();
            for j in (0..CENTRES).step_by(8) {
                let dx = _mm512_sub_pd(vx, _mm512_loadu_pd(cx.as_ptr().add(j)));
                let dy = _mm512_sub_pd(vy, _mm512_loadu_pd(cy.as_ptr().add(j)));
                let dz = _mm512_sub_pd(vz, _mm512_loadu_pd(cz.as_ptr().add(j)));
                let r2 = _mm512_add_pd(
                    _mm512_add_pd(_mm512_mul_pd(dx, dx), _mm512_mul_pd(dy, dy)),
                    _mm512_mul_pd(dz, dz),
                );
                let r = match newton {
                    None => _mm512_sqrt_pd(r2),
                    Some(steps) => {
                        let mut y = _mm512_rsqrt14_pd(_mm512_max_pd(r2, tiny));
                        for _ in 0..steps {
                            let t = _mm512_mul_pd(_mm512_mul_pd(r2, y), y);
                            y = _mm512_mul_pd(y, _mm512_sub_pd(three_halves, _mm512_mul_pd(half, t)));
                        }
                        _mm512_mul_pd(r2, y)
                    }
                };
                a = _mm512_add_pd(a, _mm512_mul_pd(_mm512_loadu_pd(w.as_ptr().add(j)), r));
            }
            *o = _mm512_reduce_add_pd(a);
        }
    }

    pub unsafe fn run() {
        let d = data();
        let mut exact = vec![0.0; POINTS];
        sums(&d, None, &mut exact);
        let scale = exact.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        println!("variant,kernel_evals_per_s,max_rel_diff");
        for (name, newton) in [("sqrt", None), ("rsqrt14_newton2", Some(2)), ("rsqrt14_newton1", Some(1))] {
            let mut out = vec![0.0; POINTS];
            // best of three
            let best = (0..3)
                .map(|_| {
                    let t = Instant::now();
                    sums(&d, newton, &mut out);
                    t.elapsed().as_secs_f64()
                })
                .fold(f64::INFINITY, f64::min);
            let diff = out.iter().zip(&exact).fold(0.0f64, |m, (a, b)| m.max((a - b).abs())) / scale;
            println!("{name},{:.4e},{diff:.3e}", (CENTRES * POINTS) as f64 / best);
        }
    }
}
