/* Local kernel rates for jobs/scaling-model, one thread (run with OPENBLAS_NUM_THREADS=1):
 *   dgemm  C(m x n) -= A(m x k) B(k x n): the trailing update of a factorisation with panel width
 *          k (m local rows, n trailing columns); flops 2 m n k.
 *   getf2  LAPACK's unblocked LU of an m x k panel (partial pivoting, BLAS-2): the panel on the
 *          critical path; flops m k^2 - k^3 / 3.
 *   geqr2  LAPACK's unblocked Householder QR of an m x k panel (BLAS-2); flops 2 m k^2 - 2 k^3 / 3.
 *   trsm   X L^T = B for a k x k lower triangle L and m x k B (the Cholesky panel's L21); flops m k^2.
 *   trmm   B <- B L^T, the same shapes: the product a solve by the inverse of L takes.
 * Each case is timed SECONDS-long at most (repeats, best of them), so the whole run is seconds.
 * Usage: micro_blas [SCALE]  (SCALE multiplies m and n, default 1)
 * Prints CSV: kernel,m,n,k,seconds,gflops */
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

extern void dgemm_(const char *, const char *, const int *, const int *, const int *, const double *,
                   const double *, const int *, const double *, const int *, const double *, double *,
                   const int *);
extern void dtrsm_(const char *, const char *, const char *, const char *, const int *, const int *,
                   const double *, const double *, const int *, double *, const int *);
extern void dtrmm_(const char *, const char *, const char *, const char *, const int *, const int *,
                   const double *, const double *, const int *, double *, const int *);
extern void dgetf2_(const int *, const int *, double *, const int *, int *, int *);
extern void dgeqr2_(const int *, const int *, double *, const int *, double *, double *, int *);

static double now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

static void fill(double *a, size_t len, unsigned seed) {
    unsigned long long s = seed * 2654435761ULL + 1;
    for (size_t i = 0; i < len; i++) {
        s = s * 6364136223846793005ULL + 1442695040888963407ULL;
        a[i] = (double)(s >> 11) / 9007199254740992.0 - 0.5;
    }
}

/* best time of up to 5 repetitions, stopping once 0.5 s are spent */
#define BEST(setup, call)                                          \
    ({                                                             \
        double best_ = 1e30, spent_ = 0;                           \
        for (int rep_ = 0; rep_ < 5 && spent_ < 0.5; rep_++) {     \
            setup;                                                 \
            double t0_ = now();                                    \
            call;                                                  \
            double dt_ = now() - t0_;                              \
            spent_ += dt_;                                         \
            if (dt_ < best_) best_ = dt_;                          \
        }                                                          \
        best_;                                                     \
    })

int main(int argc, char **argv) {
    double scale = argc > 1 ? atof(argv[1]) : 1.0;
    int big = (int)(2000 * scale);
    int ks[] = {16, 32, 64, 128, 256};
    size_t cap = (size_t)big * 2 * big;
    double *a = malloc(sizeof(double) * cap), *b = malloc(sizeof(double) * cap), *c = malloc(sizeof(double) * cap);
    double *tau = malloc(sizeof(double) * 512), *work = malloc(sizeof(double) * 512);
    int *ipiv = malloc(sizeof(int) * 512);
    fill(a, cap, 1);
    fill(b, cap, 2);
    fill(c, cap, 3);
    double one = 1.0, mone = -1.0;
    printf("kernel,m,n,k,seconds,gflops\n");
    for (unsigned i = 0; i < sizeof ks / sizeof *ks; i++) {
        int k = ks[i], m = big, n = 2 * big;
        double t = BEST((void)0, dgemm_("N", "N", &m, &n, &k, &mone, a, &m, b, &k, &one, c, &m));
        printf("dgemm,%d,%d,%d,%.6e,%.3f\n", m, n, k, t, 2.0 * m * n * k / t / 1e9);
        fflush(stdout);
    }
    int ms[] = {big / 4, big, 4 * big};
    for (unsigned i = 0; i < sizeof ms / sizeof *ms; i++) {
        int m = ms[i], info;
        for (unsigned j = 0; j < 3; j++) {
            int k = ks[j + 1];
            if ((size_t)m * k > cap) continue;
            double t = BEST(fill(a, (size_t)m * k, 7), dgetf2_(&m, &k, a, &m, ipiv, &info));
            printf("getf2,%d,%d,%d,%.6e,%.3f\n", m, k, k, t, ((double)m * k * k - (double)k * k * k / 3) / t / 1e9);
            t = BEST(fill(a, (size_t)m * k, 7), dgeqr2_(&m, &k, a, &m, tau, work, &info));
            printf("geqr2,%d,%d,%d,%.6e,%.3f\n", m, k, k, t, (2.0 * m * k * k - 2.0 * k * k * k / 3) / t / 1e9);
            fflush(stdout);
        }
    }
    int tk[] = {48, 64, 192, 384};
    for (unsigned j = 0; j < sizeof tk / sizeof *tk; j++) {
        int m = 2 * big, k = tk[j];
        if ((size_t)m * k > cap) continue;
        /* a well-conditioned lower triangle in b: the diagonal 2, the rest small */
        fill(b, (size_t)k * k, 5);
        for (int q = 0; q < k; q++) {
            for (int p = 0; p < k; p++) b[p + (size_t)q * k] = p < q ? 0.0 : (p == q ? 2.0 : 0.1 * b[p + (size_t)q * k]);
        }
        double t = BEST(fill(a, (size_t)m * k, 7), dtrsm_("R", "L", "T", "N", &m, &k, &one, b, &k, a, &m));
        printf("trsm,%d,%d,%d,%.6e,%.3f\n", m, k, k, t, (double)m * k * k / t / 1e9);
        t = BEST(fill(a, (size_t)m * k, 7), dtrmm_("R", "L", "T", "N", &m, &k, &one, b, &k, a, &m));
        printf("trmm,%d,%d,%d,%.6e,%.3f\n", m, k, k, t, (double)m * k * k / t / 1e9);
        fflush(stdout);
    }
    return 0;
}
