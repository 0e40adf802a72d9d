/* Times ScaLAPACK's PDGESV (LU with partial pivoting + solve), PDGEQRF (Householder QR) or PDPOTRF
 * + PDPOTRS (Cholesky + solve of one right-hand side) on an n x n matrix distributed
 * block-cyclically (blocks nb x nb) over a PR x PC process grid. The default grid is P x 1 (row
 * blocks of nb: the block-cyclic relative of volspline's row-cyclic layout); a 2D grid such as
 * 2 x 2 times ScaLAPACK's usual layout. Used by jobs/bench-solve.
 *
 * Matrices: lu and qr factor a random matrix with entries uniform in [-1/2, 1/2) (a hash of the
 * global index, so every grid sees the same matrix). chol factors its symmetric part plus n I:
 * the off-diagonal entries of a row sum to at most n/2 in magnitude, so the matrix is strictly
 * diagonally dominant with a positive diagonal, hence symmetric positive definite. Cholesky does
 * not pivot, so its time depends on n only, not on the entries: this is the same work as the
 * Cholesky of the projected spline block B (n - k rows) that volspline's projected Cholesky
 * factors, without the projection (O(k n^2), k = 4) around it.
 *
 * Usage: mpirun -n P scalapack_driver N NB lu|qr|chol [PR PC]
 *   -> prints "lu|qr|chol,n,nb,PR,PC,seconds,info" (PR * PC must equal P) */
#include <mpi.h>
#include <stdio.h>
#include <stdlib.h>

extern void Cblacs_get(int, int, int *);
extern void Cblacs_gridinit(int *, const char *, int, int);
extern void Cblacs_gridinfo(int, int *, int *, int *, int *);
extern void Cblacs_gridexit(int);
extern int numroc_(int *, int *, int *, int *, int *);
extern void descinit_(int *, int *, int *, int *, int *, int *, int *, int *, int *, int *);
extern void pdgesv_(int *, int *, double *, int *, int *, int *, int *, double *, int *, int *, int *, int *);
extern void pdgeqrf_(int *, int *, double *, int *, int *, int *, double *, double *, int *, int *);
extern void pdpotrf_(char *, int *, double *, int *, int *, int *, int *);
extern void pdpotrs_(char *, int *, int *, double *, int *, int *, int *, double *, int *, int *, int *, int *);

/* entry (gi, gj) of the random matrix, uniform in [-1/2, 1/2) */
static double entry(long gi, long gj) {
    unsigned long long s = (unsigned long long)gi * 1000003ULL + (unsigned long long)gj * 7919ULL + 12345ULL;
    s ^= s >> 13;
    s *= 0x9E3779B97F4A7C15ULL;
    s ^= s >> 29;
    return (double)(s >> 11) / 9007199254740992.0 - 0.5;
}

int main(int argc, char **argv) {
    MPI_Init(&argc, &argv);
    int rank, size;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &size);
    if (argc != 4 && argc != 6) {
        if (rank == 0) fprintf(stderr, "usage: scalapack_driver N NB lu|qr|chol [PR PC]\n");
        MPI_Abort(MPI_COMM_WORLD, 2);
    }
    int n = atoi(argv[1]), nb = atoi(argv[2]);
    char op = argv[3][0];
    int nprow = argc == 6 ? atoi(argv[4]) : size, npcol = argc == 6 ? atoi(argv[5]) : 1;
    if (n < 1 || nb < 1 || (op != 'l' && op != 'q' && op != 'c') || nprow < 1 || npcol < 1 || nprow * npcol != size) {
        if (rank == 0) fprintf(stderr, "scalapack_driver: need N, NB >= 1, lu|qr|chol and PR x PC = %d ranks\n", size);
        MPI_Abort(MPI_COMM_WORLD, 2);
    }
    int ctxt, myrow, mycol, izero = 0, ione = 1, info = 0;
    Cblacs_get(-1, 0, &ctxt);
    Cblacs_gridinit(&ctxt, "Row", nprow, npcol);
    Cblacs_gridinfo(ctxt, &nprow, &npcol, &myrow, &mycol);
    int mloc = numroc_(&n, &nb, &myrow, &izero, &nprow);
    int nloc = numroc_(&n, &nb, &mycol, &izero, &npcol);
    int lld = mloc > 1 ? mloc : 1;
    int desca[9], descb[9];
    descinit_(desca, &n, &n, &nb, &nb, &izero, &izero, &ctxt, &lld, &info);
    descinit_(descb, &n, &ione, &nb, &nb, &izero, &izero, &ctxt, &lld, &info);
    double *a = malloc(sizeof(double) * (size_t)lld * (size_t)(nloc > 0 ? nloc : 1));
    double *b = malloc(sizeof(double) * (size_t)lld);
    for (int jl = 0; jl < nloc; jl++)
        for (int il = 0; il < mloc; il++) {
            long gi = ((long)(il / nb) * nprow + myrow) * nb + il % nb;
            long gj = ((long)(jl / nb) * npcol + mycol) * nb + jl % nb;
            double v = entry(gi, gj);
            if (op == 'c') v = 0.5 * (v + entry(gj, gi)) + (gi == gj ? (double)n : 0.0);
            a[il + (size_t)jl * lld] = v;
        }
    for (int il = 0; il < mloc; il++) b[il] = 1.0;
    int *ipiv = malloc(sizeof(int) * (size_t)(mloc + nb));
    double *tau = malloc(sizeof(double) * (size_t)(nloc + 1));
    double *work = NULL;
    int lwork = -1;
    char lower = 'L';
    if (op == 'q') {
        double query;
        pdgeqrf_(&n, &n, a, &ione, &ione, desca, tau, &query, &lwork, &info);
        lwork = (int)query;
        work = malloc(sizeof(double) * (size_t)lwork);
    }
    MPI_Barrier(MPI_COMM_WORLD);
    double t0 = MPI_Wtime();
    if (op == 'q')
        pdgeqrf_(&n, &n, a, &ione, &ione, desca, tau, work, &lwork, &info);
    else if (op == 'l')
        pdgesv_(&n, &ione, a, &ione, &ione, desca, ipiv, b, &ione, &ione, descb, &info);
    else {
        pdpotrf_(&lower, &n, a, &ione, &ione, desca, &info);
        if (info == 0) pdpotrs_(&lower, &n, &ione, a, &ione, &ione, desca, b, &ione, &ione, descb, &info);
    }
    MPI_Barrier(MPI_COMM_WORLD);
    double t = MPI_Wtime() - t0;
    const char *name = op == 'q' ? "qr" : op == 'l' ? "lu" : "chol";
    if (rank == 0) printf("%s,%d,%d,%d,%d,%.6f,%d\n", name, n, nb, nprow, npcol, t, info);
    Cblacs_gridexit(ctxt);
    MPI_Finalize();
    return info != 0;
}
