/* Times ScaLAPACK's PDGESV (LU with partial pivoting + solve) or PDGEQRF (Householder QR) on an
 * n x n random matrix distributed block-cyclically over a P x 1 process grid (row blocks of nb,
 * the block-cyclic relative of volspline's row-cyclic layout). Used by jobs/bench-solve only.
 * Usage: mpirun -n P scalapack_driver N NB lu|qr   -> prints "lu|qr,n,nb,ranks,seconds,info" */
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

int main(int argc, char **argv) {
    MPI_Init(&argc, &argv);
    if (argc != 4) {
        fprintf(stderr, "usage: scalapack_driver N NB lu|qr\n");
        MPI_Abort(MPI_COMM_WORLD, 2);
    }
    int n = atoi(argv[1]), nb = atoi(argv[2]);
    int qr = argv[3][0] == 'q';
    int rank, size;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &size);
    int ctxt, nprow = size, npcol = 1, myrow, mycol, izero = 0, ione = 1, info = 0;
    Cblacs_get(-1, 0, &ctxt);
    Cblacs_gridinit(&ctxt, "Row", nprow, npcol);
    Cblacs_gridinfo(ctxt, &nprow, &npcol, &myrow, &mycol);
    int mloc = numroc_(&n, &nb, &myrow, &izero, &nprow);
    int nloc = numroc_(&n, &nb, &mycol, &izero, &npcol);
    int lld = mloc > 1 ? mloc : 1;
    int desca[9], descb[9];
    descinit_(desca, &n, &n, &nb, &nb, &izero, &izero, &ctxt, &lld, &info);
    descinit_(descb, &n, &ione, &nb, &nb, &izero, &izero, &ctxt, &lld, &info);
    double *a = malloc(sizeof(double) * (size_t)lld * (size_t)nloc);
    double *b = malloc(sizeof(double) * (size_t)lld);
    for (int jl = 0; jl < nloc; jl++)
        for (int il = 0; il < mloc; il++) {
            long gi = ((long)(il / nb) * nprow + myrow) * nb + il % nb;
            long gj = ((long)(jl / nb) * npcol + mycol) * nb + jl % nb;
            unsigned long long s = (unsigned long long)gi * 1000003ULL + (unsigned long long)gj * 7919ULL + 12345ULL;
            s ^= s >> 13;
            s *= 0x9E3779B97F4A7C15ULL;
            s ^= s >> 29;
            a[il + (size_t)jl * lld] = (double)(s >> 11) / 9007199254740992.0 - 0.5;
        }
    for (int il = 0; il < mloc; il++) b[il] = 1.0;
    int *ipiv = malloc(sizeof(int) * (size_t)(mloc + nb));
    double *tau = malloc(sizeof(double) * (size_t)(nloc + 1));
    double *work = NULL;
    int lwork = -1;
    if (qr) {
        double query;
        pdgeqrf_(&n, &n, a, &ione, &ione, desca, tau, &query, &lwork, &info);
        lwork = (int)query;
        work = malloc(sizeof(double) * (size_t)lwork);
    }
    MPI_Barrier(MPI_COMM_WORLD);
    double t0 = MPI_Wtime();
    if (qr)
        pdgeqrf_(&n, &n, a, &ione, &ione, desca, tau, work, &lwork, &info);
    else
        pdgesv_(&n, &ione, a, &ione, &ione, desca, ipiv, b, &ione, &ione, descb, &info);
    MPI_Barrier(MPI_COMM_WORLD);
    double t = MPI_Wtime() - t0;
    if (rank == 0) printf("%s,%d,%d,%d,%.6f,%d\n", qr ? "qr" : "lu", n, nb, size, t, info);
    Cblacs_gridexit(ctxt);
    MPI_Finalize();
    return info != 0;
}
