//! The local matrix products of the dense solvers: the machine's optimised BLAS (OpenBLAS, MKL
//! or BLIS behind `libblas.so.3`) where one is loaded and the product runs on one thread, faer's
//! product otherwise.
//!
//! Almost all the flops of the distributed factorisations are the trailing updates' GEMMs, so
//! the solvers run at the rate of their local product. On an AVX2 core faer's product reaches
//! about 78 % of OpenBLAS's DGEMM at the solvers' shapes (28 against 36 GFLOP/s), which caps every
//! solver below the rate ScaLAPACK draws from the same library. The BLAS is the one the
//! executable already loads for MUMPS and ScaLAPACK; which implementation answers is told by the
//! symbols each exports (`openblas_get_config`, `MKL_Get_Version`, `bli_info_get_version_str`):
//! the reference BLAS, which answers to none of them, is left alone, since it is several times
//! slower than faer.
//!
//! [`Engine`] is chosen once per process (`fit --gemm`, `VOLSPLINE_GEMM`); `auto` takes the BLAS
//! when it is an optimised one whose kernels use the processor's widest vector unit (an OpenBLAS
//! older than the processor falls back to older kernels, slower than faer's), and only where
//! every rank of the job takes it. The choice depends on the machine alone, never on timings, so
//! a run's results do not change with the load. A product goes to the BLAS only when its
//! operands are column-major (or transposed column-major) views and it runs on one thread
//! (`Par::Seq`): with more threads a rank's product is faer's, which threads through rayon, while
//! a serial BLAS cannot and a threaded one would compete with rayon for the cores. The two engines
//! give the same products up to rounding; the solvers' tests compare them with serial oracles
//! within tolerances either way. BLAS calls are made one at a time in a process (a serial
//! OpenBLAS is not safe to call from two threads at once; see `blas_lock`).

use std::ffi::{c_char, c_int, c_void, CStr, CString};
use std::sync::atomic::{AtomicBool, AtomicU8, Ordering};
use std::sync::{Mutex, MutexGuard, OnceLock};

use faer::linalg::matmul::matmul;
use faer::reborrow::ReborrowMut;
use faer::{Accum, MatMut, MatRef, Par};

use crate::error::{Error, Result};
use crate::par::Comm;

/// Which library computes the solvers' local products.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Engine {
    /// The optimised BLAS where one is loaded, faer otherwise.
    Auto,
    /// The loaded BLAS, whichever it is (the reference BLAS too).
    Blas,
    /// faer's product.
    Faer,
}

impl Engine {
    /// The engine named on the command line.
    pub fn parse(name: &str) -> Result<Self> {
        match name {
            "auto" => Ok(Engine::Auto),
            "blas" => Ok(Engine::Blas),
            "faer" => Ok(Engine::Faer),
            other => {
                Err(Error::Usage(format!("unknown product engine '{other}' (expected auto, blas or faer)")))
            }
        }
    }

    /// The engine's name as on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Engine::Auto => "auto",
            Engine::Blas => "blas",
            Engine::Faer => "faer",
        }
    }
}

// 0: not chosen yet (auto), 1: BLAS, 2: faer
static CHOSEN: AtomicU8 = AtomicU8::new(0);
// whether the engine in effect was auto's choice
static CHOSEN_AUTO: AtomicBool = AtomicBool::new(false);
// whether the ranks agreed on the engine (choose_agreed)
static AGREED: AtomicBool = AtomicBool::new(false);

/// Sets the engine of this process's products; `Auto` resolves to the BLAS when [`blas_vendor`]
/// names an optimised one whose kernels fit the processor (`kernels_fit_processor`). Returns
/// the engine in effect (`Blas` or `Faer`). Local: [`choose_agreed`] makes the ranks of a job
/// agree.
pub fn choose(engine: Engine) -> Engine {
    CHOSEN_AUTO.store(engine == Engine::Auto, Ordering::Relaxed);
    let blas = match engine {
        Engine::Blas => true,
        Engine::Faer => false,
        Engine::Auto => blas_vendor().is_some() && kernels_fit_processor(),
    };
    set(blas);
    in_effect()
}

/// [`choose`] on every rank of `comm`, then the BLAS only where every rank chose it: the ranks
/// compute some products alike (the same panel factors on every rank), and one engine keeps
/// those the same to the last bit. Collective.
pub fn choose_agreed(comm: &dyn Comm, engine: Engine) -> Engine {
    let mut faer = [if choose(engine) == Engine::Faer { 1.0 } else { 0.0 }];
    comm.max_f64(&mut faer);
    set(faer[0] == 0.0);
    AGREED.store(true, Ordering::Relaxed);
    in_effect()
}

fn set(blas: bool) {
    if blas {
        one_thread();
    }
    CHOSEN.store(if blas { 1 } else { 2 }, Ordering::Relaxed);
}

/// Whether the BLAS's kernels use this processor's widest vector unit. OpenBLAS names the
/// kernels it chose (`openblas_get_corename`): a release older than the processor falls back to
/// older kernels (generic ones at a fifth of the rate, or AVX2 kernels on an AVX-512 processor
/// at about 60 % of it), slower than faer's, which use the widest unit the processor has. MKL
/// and BLIS are taken as they are.
fn kernels_fit_processor() -> bool {
    let corename = blas_symbol(c"openblas_get_corename");
    if corename.is_null() {
        return true;
    }
    // SAFETY: openblas_get_corename takes no arguments and returns a static string
    let core = unsafe { static_string(corename) };
    core_fits(
        &core,
        std::arch::is_x86_feature_detected!("avx512f"),
        std::arch::is_x86_feature_detected!("avx2"),
    )
}

/// Whether OpenBLAS kernels named `core` (as `openblas_get_corename` names them) use the widest
/// vector unit of a processor with or without AVX-512 and AVX2: on an AVX-512 processor only the
/// AVX-512 kernels do; on an AVX2 one those and the AVX2 kernels (Haswell's, Zen's); a processor
/// with neither is not second-guessed.
fn core_fits(core: &str, avx512: bool, avx2: bool) -> bool {
    let core = core.to_lowercase();
    let with_avx512 = ["skylakex", "cooperlake", "sapphirerapids"].contains(&core.as_str());
    let with_avx2 = ["haswell", "zen"].contains(&core.as_str());
    if avx512 {
        with_avx512
    } else if avx2 {
        with_avx512 || with_avx2
    } else {
        true
    }
}

/// A symbol of [`blas_library`] or of the libraries it depends on; null where there is none (or
/// no BLAS library was found). Only that library is searched: an OpenBLAS loaded beside a
/// reference `libblas.so.3` does not answer the BLAS calls.
fn blas_symbol(name: &CStr) -> *mut c_void {
    // the handle, kept as an address (a raw pointer is not Sync); 0: none
    static HANDLE: OnceLock<usize> = OnceLock::new();
    let handle = *HANDLE.get_or_init(|| {
        let Some(file) = blas_library().and_then(|f| CString::new(f).ok()) else {
            return 0;
        };
        // SAFETY: RTLD_NOLOAD only returns a handle to a library already loaded (dgemm_'s),
        // which stays loaded for the process's lifetime
        unsafe { libc::dlopen(file.as_ptr(), libc::RTLD_LAZY | libc::RTLD_NOLOAD) as usize }
    });
    if handle == 0 {
        return std::ptr::null_mut();
    }
    // SAFETY: dlsym on a valid handle only looks a name up
    unsafe { libc::dlsym(handle as *mut c_void, name.as_ptr()) }
}

/// Calls `f`, a function of no arguments returning a static C string, and returns the string.
///
/// # Safety
/// `f` must be such a function (the BLAS libraries' version and kernel queries are).
unsafe fn static_string(f: *mut c_void) -> String {
    let get: extern "C" fn() -> *const c_char = std::mem::transmute(f);
    CStr::from_ptr(get()).to_string_lossy().trim().to_string()
}

/// Asks a threaded BLAS for one thread per call: its products run where the solvers already run
/// one thread per rank, and its own threads would compete with the other ranks for the cores.
fn one_thread() {
    for name in [c"openblas_set_num_threads", c"MKL_Set_Num_Threads", c"bli_thread_set_num_threads"] {
        let f = blas_symbol(name);
        if !f.is_null() {
            // SAFETY: the names are the libraries' documented thread-count setters, taking one int
            unsafe {
                let set: extern "C" fn(c_int) = std::mem::transmute(f);
                set(1);
            }
        }
    }
}

/// The engine of the products of a solve with `threads` threads per rank, in words for the run's
/// report: the BLAS and its implementation, or faer and why.
pub fn describe(threads: usize) -> String {
    match (in_effect(), blas_vendor()) {
        (Engine::Blas, _) if threads > 1 => format!("faer ({threads} threads per rank)"),
        (Engine::Blas, Some(v)) => format!("BLAS ({v}; {})", blas_library().unwrap_or("?")),
        (Engine::Blas, None) => {
            format!("BLAS (not a known optimised one; {})", blas_library().unwrap_or("?"))
        }
        (_, None) if CHOSEN_AUTO.load(Ordering::Relaxed) => "faer (no optimised BLAS loaded)".into(),
        (_, Some(v)) if CHOSEN_AUTO.load(Ordering::Relaxed) => {
            format!("faer (the BLAS, {v}, has kernels older than this processor here or on another rank)")
        }
        _ => "faer".into(),
    }
}

/// The engine's name in a run's figures: blas or faer, as the products of a solve with `threads`
/// threads per rank run.
pub fn figure(threads: usize) -> &'static str {
    if in_effect() == Engine::Blas && threads <= 1 {
        "blas"
    } else {
        "faer"
    }
}

/// The engine in effect: the one [`choose`] set, or `auto`'s choice when none was set.
pub fn in_effect() -> Engine {
    match CHOSEN.load(Ordering::Relaxed) {
        1 => Engine::Blas,
        2 => Engine::Faer,
        _ => choose(from_env()),
    }
}

/// The engine `VOLSPLINE_GEMM` names (auto, blas or faer; any other value and none mean auto).
fn from_env() -> Engine {
    std::env::var("VOLSPLINE_GEMM").ok().and_then(|v| Engine::parse(&v).ok()).unwrap_or(Engine::Auto)
}

/// The file of the library that answers the BLAS calls (where `dgemm_` resolves), as the
/// dynamic loader opened it: on Debian `libblas.so.3`, a link through the alternatives system
/// to the implementation chosen there.
pub fn blas_library() -> Option<&'static str> {
    static FILE: OnceLock<Option<String>> = OnceLock::new();
    FILE.get_or_init(|| {
        // SAFETY: dlsym and dladdr only look names and addresses up; dli_fname, when set, is a
        // string the loader keeps for the library's lifetime (the process's)
        unsafe {
            let f = libc::dlsym(libc::RTLD_DEFAULT, c"dgemm_".as_ptr());
            let mut info: libc::Dl_info = std::mem::zeroed();
            if f.is_null() || libc::dladdr(f, &mut info) == 0 || info.dli_fname.is_null() {
                return None;
            }
            Some(CStr::from_ptr(info.dli_fname).to_string_lossy().into_owned())
        }
    })
    .as_deref()
}

/// The optimised BLAS that answers the BLAS calls, by the version function its implementation
/// exports, looked up in [`blas_library`] and the libraries it depends on: `OpenBLAS <config>`,
/// `MKL` or `BLIS <version>`; None for any other (the reference BLAS).
pub fn blas_vendor() -> Option<&'static str> {
    static VENDOR: OnceLock<Option<String>> = OnceLock::new();
    VENDOR
        .get_or_init(|| {
            let found = |name: &CStr| Some(blas_symbol(name)).filter(|f| !f.is_null());
            if let Some(f) = found(c"openblas_get_config") {
                // SAFETY: the libraries' own version queries take no arguments and return
                // static strings
                let config = unsafe { static_string(f) };
                // "OpenBLAS 0.3.21 ... Zen SINGLE_THREADED"
                return Some(if config.starts_with("OpenBLAS") {
                    config
                } else {
                    format!("OpenBLAS {config}")
                });
            }
            if found(c"MKL_Get_Version").is_some() || found(c"mkl_get_version").is_some() {
                return Some("MKL".to_string());
            }
            // SAFETY: as above
            found(c"bli_info_get_version_str").map(|f| format!("BLIS {}", unsafe { static_string(f) }))
        })
        .as_deref()
}

/// The Fortran GEMM: C = alpha op(A) op(B) + beta C, column-major; the trailing lengths are
/// the hidden lengths of the two character arguments.
type GemmFn<T> = unsafe extern "C" fn(
    *const c_char,
    *const c_char,
    *const c_int,
    *const c_int,
    *const c_int,
    *const T,
    *const T,
    *const c_int,
    *const T,
    *const c_int,
    *const T,
    *mut T,
    *const c_int,
    usize,
    usize,
);

/// The Fortran triangular solve: op(A) X = alpha B (side 'L') or X op(A) = alpha B (side 'R'),
/// X overwriting B, column-major; the trailing lengths are those of the four character
/// arguments.
type TrsmFn<T> = unsafe extern "C" fn(
    *const c_char,
    *const c_char,
    *const c_char,
    *const c_char,
    *const c_int,
    *const c_int,
    *const T,
    *const T,
    *const c_int,
    *mut T,
    *const c_int,
    usize,
    usize,
    usize,
    usize,
);

/// A float type the BLAS multiplies: f64 (dgemm, dtrsm, dtrmm) and f32 (sgemm, strsm, strmm).
pub trait Gemm: faer::traits::RealField + Copy {
    /// The type's GEMM.
    const GEMM: GemmFn<Self>;
    /// The type's triangular solve.
    const TRSM: TrsmFn<Self>;
    /// The type's triangular product (B <- op(A) B or B op(A), the arguments of the solve).
    const TRMM: TrsmFn<Self>;
    /// 0 and 1 of the type.
    const ZERO_ONE: (Self, Self);
}

/// Declares the BLAS routines of a float type (from `libblas.so.3`, the runtime name: Debian
/// ships no unversioned link without the -dev package) and makes the type a [`Gemm`].
macro_rules! blas_routines {
    ($t:ty, $gemm:ident, $trsm:ident, $trmm:ident) => {
        blas_routines!($t, $gemm, $trsm, $trmm; triangular $trsm, $trmm);
    };
    // the triangular solve and product share one signature ([`TrsmFn`])
    ($t:ty, $gemm:ident, $trsm:ident, $trmm:ident; triangular $($tri:ident),+) => {
        #[link(name = "libblas.so.3", kind = "dylib", modifiers = "+verbatim")]
        extern "C" {
            fn $gemm(
                ta: *const c_char,
                tb: *const c_char,
                m: *const c_int,
                n: *const c_int,
                k: *const c_int,
                alpha: *const $t,
                a: *const $t,
                lda: *const c_int,
                b: *const $t,
                ldb: *const c_int,
                beta: *const $t,
                c: *mut $t,
                ldc: *const c_int,
                la: usize,
                lb: usize,
            );
            $(
                fn $tri(
                    side: *const c_char,
                    uplo: *const c_char,
                    ta: *const c_char,
                    diag: *const c_char,
                    m: *const c_int,
                    n: *const c_int,
                    alpha: *const $t,
                    a: *const $t,
                    lda: *const c_int,
                    b: *mut $t,
                    ldb: *const c_int,
                    l1: usize,
                    l2: usize,
                    l3: usize,
                    l4: usize,
                );
            )+
        }
        impl Gemm for $t {
            const GEMM: GemmFn<Self> = $gemm;
            const TRSM: TrsmFn<Self> = $trsm;
            const TRMM: TrsmFn<Self> = $trmm;
            const ZERO_ONE: (Self, Self) = (0.0, 1.0);
        }
    };
}
blas_routines!(f64, dgemm_, dtrsm_, dtrmm_);
blas_routines!(f32, sgemm_, strsm_, strmm_);

/// Calls the type's GEMM with Rust sizes (which the callers have checked fit a C int).
///
/// # Safety
/// The pointers and leading dimensions must describe column-major matrices of the given shapes.
#[allow(clippy::too_many_arguments)]
unsafe fn call_gemm<T: Gemm>(
    (ta, tb): (u8, u8),
    (m, n, k): (usize, usize, usize),
    alpha: T,
    (a, lda): (*const T, usize),
    (b, ldb): (*const T, usize),
    beta: T,
    (c, ldc): (*mut T, usize),
) {
    let (ta, tb) = (ta as c_char, tb as c_char);
    let [m, n, k, lda, ldb, ldc] = [m, n, k, lda, ldb, ldc].map(|v| v as c_int);
    T::GEMM(&ta, &tb, &m, &n, &k, &alpha, a, &lda, b, &ldb, &beta, c, &ldc, 1, 1);
}

/// Calls a triangular routine of the type's BLAS (its solve or its product, [`TrsmFn`]) with
/// alpha = 1 on a lower triangle, with Rust sizes.
///
/// # Safety
/// As for [`call_gemm`].
unsafe fn call_triangular<T: Gemm>(
    routine: TrsmFn<T>,
    (side, ta, diag): (u8, u8, u8),
    (m, n): (usize, usize),
    (a, lda): (*const T, usize),
    (b, ldb): (*mut T, usize),
) {
    let [side, uplo, ta, diag] = [side, b'L', ta, diag].map(|c| c as c_char);
    let [m, n, lda, ldb] = [m, n, lda, ldb].map(|v| v as c_int);
    let one = T::ZERO_ONE.1;
    routine(&side, &uplo, &ta, &diag, &m, &n, &one, a, &lda, b, &ldb, 1, 1, 1, 1);
}

/// Columns of L at which [`trsm_right`] stops halving and solves the leaf.
const TRSM_LEAF: usize = 64;

/// Rows of B from which [`trsm_right`] solves a leaf by the inverse of its triangle and a
/// triangular product instead of the BLAS's solve: on tall blocks OpenBLAS's DTRSM runs at
/// 12-14 GFLOP/s on 48-64 columns, its DTRMM at 26-39 (4000 rows, an AVX-512 core), and the
/// inverse (n^3 / 3 flops on the leaf) is paid once for all the rows.
const INVERTED_LEAF_ROWS: usize = 512;

/// X op(L) = B in place, for a lower triangular L (n x n, leading dimension `lda`) and a
/// column-major B (m x n, leading dimension `ldb`), op(L) = L^T (`ta` = b'T') or L (b'N'): L is
/// halved, L = [La 0; Lb Lc], and the halves of X are solved one after the other with the
/// coupling as a GEMM: for L^T, X1 La^T = B1, then X2 Lc^T = B2 - X1 Lb^T; for L, X2 Lc = B2,
/// then X1 La = B1 - X2 Lb. Most of the flops so run in GEMMs: OpenBLAS's DTRSM solves the tall
/// blocks of the factorisations (thousands of rows against a triangle of 192-384) at 25-29
/// GFLOP/s on an AVX-512 core, the GEMM itself runs at 50-54. The leaves of at most
/// [`TRSM_LEAF`] columns are solved by the BLAS where B is short; from [`INVERTED_LEAF_ROWS`]
/// rows on they are multiplied by the inverse of their triangle instead (DTRMM), as blocked GPU
/// solvers do with their diagonal blocks: the inverse of a triangle of at most 64 columns is
/// computed once by a solve against the identity, and every row of B is multiplied by it. Its
/// rounding errors grow with the condition number of the leaf alone, not of the whole triangle;
/// on the leaves of the factorisations' diagonal blocks the residuals of the 8000-row solves
/// stayed at 1-4e-14. With the BLAS's leaves the halving ran at 29-31 GFLOP/s (4000 and 8000
/// rows, 384 columns), with inverted leaves at 39-41.
///
/// # Safety
/// As for [`call_gemm`]; B does not overlap L, and the caller holds the BLAS lock.
unsafe fn trsm_right<T: Gemm>(
    (ta, diag): (u8, u8),
    (m, n): (usize, usize),
    (a, lda): (*const T, usize),
    (b, ldb): (*mut T, usize),
) {
    if n <= TRSM_LEAF || m == 0 {
        solve_leaf((b'R', ta, diag), (m, n), (a, lda), (b, ldb));
        return;
    }
    // a multiple of 16 below n (n > 64)
    let h = (n / 2).div_ceil(16) * 16;
    let r = n - h;
    // SAFETY (offsets): La, Lb and Lc lie in the n x n triangle, B1 and B2 in B
    let (la, lb, lc) = (a, a.add(h), a.add(h + h * lda));
    let (b1, b2) = (b, b.add(h * ldb));
    let one = T::ZERO_ONE.1;
    if ta == b'T' {
        trsm_right((ta, diag), (m, h), (la, lda), (b1, ldb));
        call_gemm((b'N', b'T'), (m, r, h), -one, (b1, ldb), (lb, lda), one, (b2, ldb));
        trsm_right((ta, diag), (m, r), (lc, lda), (b2, ldb));
    } else {
        trsm_right((ta, diag), (m, r), (lc, lda), (b2, ldb));
        call_gemm((b'N', b'N'), (m, h, r), -one, (b2, ldb), (lb, lda), one, (b1, ldb));
        trsm_right((ta, diag), (m, h), (la, lda), (b1, ldb));
    }
}

/// A leaf of [`trsm_right`] (`side` b'R': X op(L) = B, L n x n) or [`trsm_left`] (b'L':
/// L X = B, L m x m), B m x n: by the BLAS's solve where B has fewer than
/// [`INVERTED_LEAF_ROWS`] rows (from the right) or columns (from the left), else as the product
/// with L^-1, the solve of L Y = I (with `diag` b'U' its unit diagonal is neither read nor
/// needed), by the BLAS's triangular product.
///
/// # Safety
/// As for [`call_gemm`]; B does not overlap L, and the caller holds the BLAS lock.
unsafe fn solve_leaf<T: Gemm>(
    (side, ta, diag): (u8, u8, u8),
    (m, n): (usize, usize),
    (a, lda): (*const T, usize),
    (b, ldb): (*mut T, usize),
) {
    let (order, across) = if side == b'R' { (n, m) } else { (m, n) };
    if across < INVERTED_LEAF_ROWS {
        call_triangular(T::TRSM, (side, ta, diag), (m, n), (a, lda), (b, ldb));
        return;
    }
    let mut inv = vec![T::ZERO_ONE.0; order * order];
    (0..order).for_each(|i| inv[i * order + i] = T::ZERO_ONE.1);
    call_triangular(T::TRSM, (b'L', b'N', diag), (order, order), (a, lda), (inv.as_mut_ptr(), order));
    call_triangular(T::TRMM, (side, ta, diag), (m, n), (inv.as_ptr(), order), (b, ldb));
}

/// L X = B in place, for a lower triangular L (m x m, leading dimension `lda`) and a column-major
/// B (m x n, leading dimension `ldb`): the solve from the left, halved as [`trsm_right`] halves
/// the solve from the right (L = [La 0; Lb Lc]: La X1 = B1, then Lc X2 = B2 - Lb X1). Its leaves
/// of at most [`TRSM_LEAF`] rows are solved by the BLAS where B is narrow, and from
/// [`INVERTED_LEAF_ROWS`] columns on multiplied by the inverse of their triangle: OpenBLAS's
/// DTRSM solves 64 rows against 4000 columns at 5-6 GFLOP/s on an AVX-512 core, its DTRMM
/// multiplies them at 18-23 (128 rows: 9 and 28). These are the 2D layout's panel solves
/// (U12 = L11^-1 A12 of the LU, the Cholesky's L21^T = L11^-1 B21^T).
///
/// # Safety
/// As for [`call_gemm`]; B does not overlap L, and the caller holds the BLAS lock.
unsafe fn trsm_left<T: Gemm>(
    diag: u8,
    (m, n): (usize, usize),
    (a, lda): (*const T, usize),
    (b, ldb): (*mut T, usize),
) {
    if m <= TRSM_LEAF || n == 0 {
        solve_leaf((b'L', b'N', diag), (m, n), (a, lda), (b, ldb));
        return;
    }
    // a multiple of 16 below m (m > 64)
    let h = (m / 2).div_ceil(16) * 16;
    let r = m - h;
    // SAFETY (offsets): La, Lb and Lc lie in the m x m triangle, B1 and B2 in B
    let (la, lb, lc) = (a, a.add(h), a.add(h + h * lda));
    let (b1, b2) = (b, b.add(h));
    let one = T::ZERO_ONE.1;
    trsm_left(diag, (h, n), (la, lda), (b1, ldb));
    call_gemm((b'N', b'N'), (r, n, h), -one, (lb, lda), (b1, ldb), one, (b2, ldb));
    trsm_left(diag, (r, n), (lc, lda), (b2, ldb));
}

/// A view as the BLAS takes it: ('N', pointer, leading dimension) for a column-major view,
/// ('T', ...) for the transpose of one; None for other strides.
fn as_blas<T>(m: MatRef<'_, T>) -> Option<(u8, *const T, usize)> {
    let (rs, cs) = (m.row_stride(), m.col_stride());
    if rs == 1 && cs >= m.nrows().max(1) as isize {
        Some((b'N', m.as_ptr(), cs as usize))
    } else if cs == 1 && rs >= m.ncols().max(1) as isize {
        Some((b'T', m.as_ptr(), rs as usize))
    } else if m.ncols() <= 1 && rs == 1 {
        Some((b'N', m.as_ptr(), m.nrows().max(1)))
    } else {
        None
    }
}

/// dst = alpha lhs rhs (`Accum::Replace`) or dst += alpha lhs rhs (`Accum::Add`): faer's
/// `matmul` with the same arguments, computed by the BLAS where [`in_effect`] says so, `par` is
/// one thread and the views' strides allow (see the module documentation).
pub fn gemm<T: Gemm>(
    mut dst: MatMut<'_, T>,
    accum: Accum,
    lhs: MatRef<'_, T>,
    rhs: MatRef<'_, T>,
    alpha: T,
    par: Par,
) {
    let (m, n, k) = (dst.nrows(), dst.ncols(), lhs.ncols());
    if to_blas(par, &[m, n, k]) && blas_product(dst.rb_mut(), accum, lhs, rhs, alpha) {
        return;
    }
    matmul(dst, accum, lhs, rhs, alpha, par);
}

/// The product of [`gemm`] by the BLAS; false (nothing done) where a view's strides or a size
/// do not fit its interface.
fn blas_product<T: Gemm>(
    dst: MatMut<'_, T>,
    accum: Accum,
    lhs: MatRef<'_, T>,
    rhs: MatRef<'_, T>,
    alpha: T,
) -> bool {
    let (m, n, k) = (dst.nrows(), dst.ncols(), lhs.ncols());
    let fits = |v: usize| v <= c_int::MAX as usize;
    if m == 0 || n == 0 || k == 0 || !(fits(m) && fits(n) && fits(k)) {
        return false;
    }
    let out_ok =
        dst.row_stride() == 1 && dst.col_stride() >= m.max(1) as isize || n == 1 && dst.row_stride() == 1;
    let (true, Some((ta, a, lda)), Some((tb, b, ldb))) = (out_ok, as_blas(lhs), as_blas(rhs)) else {
        return false;
    };
    let ldc = if n == 1 { m.max(dst.col_stride().max(1) as usize) } else { dst.col_stride() as usize };
    if !(fits(lda) && fits(ldb) && fits(ldc)) {
        return false;
    }
    let (zero, one) = T::ZERO_ONE;
    let beta = if accum == Accum::Add { one } else { zero };
    let _one_at_a_time = blas_lock();
    // SAFETY: the views describe column-major matrices of the shapes passed, checked above; dst
    // is borrowed mutably and does not alias lhs or rhs (faer's rule too)
    unsafe { call_gemm((ta, tb), (m, n, k), alpha, (a, lda), (b, ldb), beta, (dst.as_ptr_mut(), ldc)) };
    true
}

/// One BLAS call at a time in the process. A single-threaded OpenBLAS (Debian's
/// `libopenblas0-serial` 0.3.21) shares one work buffer between all calls: two threads calling
/// it at once can corrupt each other's products (seen as wrong weights, now and then, when the
/// solvers of `tests/invariants.rs` ran side by side in one process). A rank of the binary calls
/// from one thread, so the lock is never contended there.
fn blas_lock() -> MutexGuard<'static, ()> {
    static LOCK: Mutex<()> = Mutex::new(());
    LOCK.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// Whether the products of a solver running with parallelism `par` go to the BLAS (those whose
/// views fit its interface).
fn by_blas(par: Par) -> bool {
    par.degree() == 1 && in_effect() == Engine::Blas
}

/// Whether the products of a solver running with parallelism `par` go to the BLAS, where every
/// rank is known to have the same engine ([`choose_agreed`] ran); false otherwise: what may
/// decide a choice the ranks must share, such as a solver's panel width (without the agreement
/// a job spread over unlike nodes could pick two widths and deadlock).
pub fn by_blas_on_every_rank(par: Par) -> bool {
    AGREED.load(Ordering::Relaxed) && by_blas(par)
}

/// Whether a product or solve of these sizes and parallelism goes to the BLAS.
fn to_blas(par: Par, dims: &[usize]) -> bool {
    dims.iter().all(|&d| d > 0 && d <= c_int::MAX as usize) && by_blas(par)
}

/// B <- L^-1 B for a lower triangular L (`unit`: with unit diagonal, not read), B of any
/// orientation: faer's `solve_lower_triangular_in_place` (or its unit variant), computed by the
/// BLAS where [`gemm`] would be.
pub fn solve_lower<T: Gemm>(l: MatRef<'_, T>, unit: bool, b: MatMut<'_, T>, par: Par) {
    let (m, n) = (b.nrows(), b.ncols());
    if to_blas(par, &[m, n]) {
        if let Some((b'N', a, lda)) = as_blas(l) {
            let diag = if unit { b'U' } else { b'N' };
            let (rs, cs) = (b.row_stride(), b.col_stride());
            let _one_at_a_time = blas_lock();
            // SAFETY: as in gemm; B is column-major (L X = B) or the transpose of a column-major
            // matrix (X^T L^T = B^T, solved from the right)
            unsafe {
                if rs == 1 && (cs >= m as isize || n == 1) {
                    let ldb = if n == 1 { m } else { cs as usize };
                    if lda <= c_int::MAX as usize && ldb <= c_int::MAX as usize {
                        trsm_left(diag, (m, n), (a, lda), (b.as_ptr_mut(), ldb));
                        return;
                    }
                } else if cs == 1
                    && rs >= n as isize
                    && lda <= c_int::MAX as usize
                    && rs <= c_int::MAX as isize
                {
                    trsm_right((b'T', diag), (n, m), (a, lda), (b.as_ptr_mut(), rs as usize));
                    return;
                }
            }
        }
    }
    if unit {
        faer::linalg::triangular_solve::solve_unit_lower_triangular_in_place(l, b, par);
    } else {
        faer::linalg::triangular_solve::solve_lower_triangular_in_place(l, b, par);
    }
}

/// B <- B L^-1 for a lower triangular L (`unit`: with unit diagonal, not read): the solve from
/// the right, X L = B, computed by the BLAS where [`gemm`] would be and B is column-major, by
/// faer otherwise (as L^T X^T = B^T).
pub fn solve_lower_right<T: Gemm>(l: MatRef<'_, T>, unit: bool, mut b: MatMut<'_, T>, par: Par) {
    let (m, n) = (b.nrows(), b.ncols());
    if to_blas(par, &[m, n]) {
        let (rs, cs) = (b.row_stride(), b.col_stride());
        if let (Some((b'N', a, lda)), true) = (as_blas(l), rs == 1 && (cs >= m as isize || n == 1)) {
            let ldb = if n == 1 { m } else { cs as usize };
            if lda <= c_int::MAX as usize && ldb <= c_int::MAX as usize {
                let diag = if unit { b'U' } else { b'N' };
                let _one_at_a_time = blas_lock();
                // SAFETY: as in gemm; B is column-major m x n, L is n x n
                unsafe { trsm_right((b'N', diag), (m, n), (a, lda), (b.as_ptr_mut(), ldb)) };
                return;
            }
        }
    }
    let (lt, bt) = (l.transpose(), b.rb_mut().transpose_mut());
    if unit {
        faer::linalg::triangular_solve::solve_unit_upper_triangular_in_place(lt, bt, par);
    } else {
        faer::linalg::triangular_solve::solve_upper_triangular_in_place(lt, bt, par);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kernels_fit_the_widest_vector_unit() {
        // an AVX-512 processor: only AVX-512 kernels
        assert!(core_fits("SkylakeX", true, true));
        assert!(core_fits("cooperlake", true, true));
        assert!(!core_fits("Haswell", true, true));
        assert!(!core_fits("Zen", true, true));
        // an AVX2 processor: AVX2 and AVX-512 kernels (the latter cannot be chosen there)
        assert!(core_fits("Haswell", false, true));
        assert!(core_fits("Zen", false, true));
        assert!(core_fits("SkylakeX", false, true));
        // generic or SSE kernels never fit a processor with AVX2
        assert!(!core_fits("Prescott", false, true));
        assert!(!core_fits("Sandybridge", false, true));
        assert!(!core_fits("Prescott", true, true));
        // a processor with neither is not second-guessed
        assert!(core_fits("Prescott", false, false));
    }

    #[test]
    fn the_vendor_is_that_of_the_library_answering_dgemm() {
        let file = blas_library().expect("dgemm_ is linked");
        // Debian's alternatives: the link resolves to the implementation's own folder
        let real = std::fs::canonicalize(file).unwrap().to_string_lossy().into_owned();
        let vendor = blas_vendor();
        if real.contains("openblas") {
            assert!(vendor.is_some_and(|v| v.starts_with("OpenBLAS ")), "{real}: {vendor:?}");
        } else if real.ends_with("/blas/libblas.so.3") {
            // the reference BLAS: auto keeps faer's products
            assert_eq!(vendor, None, "{real}");
        } else {
            assert!(vendor.is_none_or(|v| ["OpenBLAS", "MKL", "BLIS"].iter().any(|n| v.starts_with(n))));
        }
    }

    fn filled(r: usize, c: usize, seed: u64) -> faer::Mat<f64> {
        let mut s = seed;
        faer::Mat::from_fn(r, c, |_, _| {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        })
    }

    #[test]
    fn the_blas_and_faer_products_agree_for_every_operand_form() {
        // the BLAS path is forced whatever was chosen, so that the test exercises it
        choose(Engine::Blas);
        let a = filled(37, 23, 1);
        let b = filled(23, 19, 2);
        let bt = filled(19, 23, 3);
        let c0 = filled(37, 19, 4);
        for accum in [Accum::Replace, Accum::Add] {
            let cases: [(MatRef<'_, f64>, MatRef<'_, f64>); 3] =
                [(a.as_ref(), b.as_ref()), (a.as_ref(), bt.as_ref().transpose()), (a.as_ref(), b.as_ref())];
            for (i, (l, r)) in cases.into_iter().enumerate() {
                let mut want = c0.clone();
                matmul(want.as_mut(), accum, l, r, -0.75, Par::Seq);
                let mut got = c0.clone();
                if i == 2 {
                    // a sub-view: leading dimension larger than the rows
                    let mut big = filled(50, 30, 5);
                    big.as_mut().submatrix_mut(3, 4, 37, 19).copy_from(c0.as_ref());
                    gemm(big.as_mut().submatrix_mut(3, 4, 37, 19), accum, l, r, -0.75, Par::Seq);
                    got.copy_from(big.as_ref().submatrix(3, 4, 37, 19));
                } else {
                    gemm(got.as_mut(), accum, l, r, -0.75, Par::Seq);
                }
                let err = (0..37)
                    .flat_map(|i| (0..19).map(move |j| (i, j)))
                    .map(|(i, j)| (want[(i, j)] - got[(i, j)]).abs())
                    .fold(0.0, f64::max);
                assert!(err < 1e-13, "case {i}: {err:e}");
            }
        }
        // the transposed left operand (V^T A in the Householder)
        let v = filled(41, 7, 6);
        let mut want = faer::Mat::<f64>::zeros(7, 23);
        let a2 = filled(41, 23, 7);
        matmul(want.as_mut(), Accum::Replace, v.as_ref().transpose(), a2.as_ref(), 1.0, Par::Seq);
        let mut got = faer::Mat::<f64>::zeros(7, 23);
        gemm(got.as_mut(), Accum::Replace, v.as_ref().transpose(), a2.as_ref(), 1.0, Par::Seq);
        assert!((&want - &got).norm_max() < 1e-13);

        // triangular solves, unit and not, right-hand sides column-major and transposed
        let mut l = filled(29, 29, 8);
        for i in 0..29 {
            l[(i, i)] = 2.0 + i as f64 * 0.1;
        }
        let b = filled(29, 11, 9);
        for unit in [false, true] {
            let mut want = b.clone();
            if unit {
                faer::linalg::triangular_solve::solve_unit_lower_triangular_in_place(
                    l.as_ref(),
                    want.as_mut(),
                    Par::Seq,
                );
            } else {
                faer::linalg::triangular_solve::solve_lower_triangular_in_place(
                    l.as_ref(),
                    want.as_mut(),
                    Par::Seq,
                );
            }
            let mut got = b.clone();
            solve_lower(l.as_ref(), unit, got.as_mut(), Par::Seq);
            assert!((&want - &got).norm_max() < 1e-12, "unit {unit}");
            let mut bt = faer::Mat::<f64>::zeros(11, 29);
            bt.copy_from(b.as_ref().transpose());
            solve_lower(l.as_ref(), unit, bt.as_mut().transpose_mut(), Par::Seq);
            assert!((&want - bt.as_ref().transpose()).norm_max() < 1e-12, "unit {unit}, transposed");
        }
        // solves from the right, X L = B: B column-major (the BLAS) and transposed (faer)
        let b = filled(13, 29, 10);
        for unit in [false, true] {
            // the lower triangle that the solve reads, with the unit diagonal where it assumes one
            let lower = faer::Mat::<f64>::from_fn(29, 29, |i, j| match i.cmp(&j) {
                std::cmp::Ordering::Less => 0.0,
                std::cmp::Ordering::Equal if unit => 1.0,
                _ => l[(i, j)],
            });
            let mut got = b.clone();
            solve_lower_right(l.as_ref(), unit, got.as_mut(), Par::Seq);
            let mut back = faer::Mat::<f64>::zeros(13, 29);
            matmul(back.as_mut(), Accum::Replace, got.as_ref(), lower.as_ref(), 1.0, Par::Seq);
            assert!((&back - &b).norm_max() < 1e-12, "right, unit {unit}");
            let mut bt = faer::Mat::<f64>::zeros(29, 13);
            bt.copy_from(b.as_ref().transpose());
            solve_lower_right(l.as_ref(), unit, bt.as_mut().transpose_mut(), Par::Seq);
            assert!((&got - bt.as_ref().transpose()).norm_max() < 1e-12, "right, unit {unit}, transposed");
        }
        // solves from the right wider than a leaf of their halving (trsm_right): X L = B and
        // X L^T = B (solve_lower on a transposed B), unit and not, f64 and f32, against faer
        let n = 2 * TRSM_LEAF + 22;
        let big = faer::Mat::<f64>::from_fn(n, n, |i, j| match i.cmp(&j) {
            std::cmp::Ordering::Less => 0.0,
            std::cmp::Ordering::Equal => 1.5 + (i % 7) as f64 * 0.1,
            std::cmp::Ordering::Greater => 0.05 * l[(i % 29, j % 29)],
        });
        // (41 rows: the leaves solved by the BLAS; more: by their inverses)
        for (rows, unit) in
            [(41, false), (41, true), (INVERTED_LEAF_ROWS + 37, false), (INVERTED_LEAF_ROWS + 37, true)]
        {
            let rhs = filled(rows, n, 11);
            let lower =
                faer::Mat::<f64>::from_fn(n, n, |i, j| if i == j && unit { 1.0 } else { big[(i, j)] });
            // X L = B: from L^T X^T = B^T
            let mut want = faer::Mat::<f64>::zeros(n, rows);
            want.copy_from(rhs.as_ref().transpose());
            faer::linalg::triangular_solve::solve_upper_triangular_in_place(
                lower.as_ref().transpose(),
                want.as_mut(),
                Par::Seq,
            );
            let mut got = rhs.clone();
            solve_lower_right(big.as_ref(), unit, got.as_mut(), Par::Seq);
            let err = (&got - want.as_ref().transpose()).norm_max();
            assert!(err < 1e-12, "right, {rows} x {n}, unit {unit}: {err:e}");
            // X L^T = B: L X^T = B^T
            let mut want = faer::Mat::<f64>::zeros(n, rows);
            want.copy_from(rhs.as_ref().transpose());
            faer::linalg::triangular_solve::solve_lower_triangular_in_place(
                lower.as_ref(),
                want.as_mut(),
                Par::Seq,
            );
            let mut got = rhs.clone();
            solve_lower(big.as_ref(), unit, got.as_mut().transpose_mut(), Par::Seq);
            let err = (&got - want.as_ref().transpose()).norm_max();
            assert!(err < 1e-12, "transposed, {rows} x {n}, unit {unit}: {err:e}");
            // L X = B from the left (trsm_left), B column-major n x rows: the same X^T
            let mut got = faer::Mat::<f64>::zeros(n, rows);
            got.copy_from(rhs.as_ref().transpose());
            solve_lower(big.as_ref(), unit, got.as_mut(), Par::Seq);
            let err = (&got - &want).norm_max();
            assert!(err < 1e-12, "left, {n} x {rows}, unit {unit}: {err:e}");
            // single precision (strsm, sgemm)
            let (big32, rhs32) = (big.as_ref().map(|&x| x as f32), rhs.as_ref().map(|&x| x as f32));
            let mut got32 = rhs32.clone();
            solve_lower_right(big32.as_ref(), unit, got32.as_mut(), Par::Seq);
            let mut back = faer::Mat::<f32>::zeros(rows, n);
            let lower32 = lower.as_ref().map(|&x| x as f32);
            matmul(back.as_mut(), Accum::Replace, got32.as_ref(), lower32.as_ref(), 1.0, Par::Seq);
            let err = (&back - &rhs32).norm_max();
            assert!(err < 1e-5, "right, f32, {rows} x {n}, unit {unit}: {err:e}");
        }
        // single precision (sgemm, strsm)
        let (a32, b32) = (a.as_ref().map(|&x| x as f32), filled(23, 19, 2).as_ref().map(|&x| x as f32));
        let mut want = faer::Mat::<f32>::zeros(37, 19);
        matmul(want.as_mut(), Accum::Replace, a32.as_ref(), b32.as_ref(), 2.0, Par::Seq);
        let mut got = faer::Mat::<f32>::zeros(37, 19);
        gemm(got.as_mut(), Accum::Replace, a32.as_ref(), b32.as_ref(), 2.0, Par::Seq);
        assert!((&want - &got).norm_max() < 1e-5);
        let l32 = l.as_ref().map(|&x| x as f32);
        let rhs32 = faer::Mat::<f32>::from_fn(29, 3, |i, j| (i + j) as f32 * 0.1);
        let mut want = rhs32.clone();
        faer::linalg::triangular_solve::solve_lower_triangular_in_place(
            l32.as_ref(),
            want.as_mut(),
            Par::Seq,
        );
        let mut got = rhs32.clone();
        solve_lower(l32.as_ref(), false, got.as_mut(), Par::Seq);
        assert!((&want - &got).norm_max() < 1e-4);
        choose(Engine::Auto);
    }
}
