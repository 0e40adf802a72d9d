/* MPI costs for jobs/scaling-model, on the ranks it is started with (2 on a small machine):
 *   pingpong   rank 0 <-> rank 1, half the round trip: the point-to-point time alpha + m beta
 *   allgather  MPI_Allgather, m doubles in total (m / P from each rank), as volspline gathers rows
 *   allreduce  MPI_Allreduce (sum) of m doubles, as Householder's column and W sums
 *   bcast      MPI_Bcast of m doubles from rank 0, as a 2D code's panel broadcasts
 * For each size: best of a few rounds of repetitions (the figure least disturbed by the other
 * processes of the machine), 9 rounds of about 5 ms each, so the whole run takes seconds.
 * Usage: mpirun -n P micro_mpi   -> CSV on rank 0: op,ranks,bytes,seconds */
#include <mpi.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static double round_time(int op, double *buf, double *out, int m, int reps, int rank, int size) {
    MPI_Barrier(MPI_COMM_WORLD);
    double t0 = MPI_Wtime();
    for (int r = 0; r < reps; r++) {
        switch (op) {
        case 0:
            if (rank == 0) {
                MPI_Send(buf, m, MPI_DOUBLE, 1, 0, MPI_COMM_WORLD);
                MPI_Recv(out, m, MPI_DOUBLE, 1, 0, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
            } else if (rank == 1) {
                MPI_Recv(out, m, MPI_DOUBLE, 0, 0, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
                MPI_Send(buf, m, MPI_DOUBLE, 0, 0, MPI_COMM_WORLD);
            }
            break;
        case 1:
            MPI_Allgather(buf, m / size, MPI_DOUBLE, out, m / size, MPI_DOUBLE, MPI_COMM_WORLD);
            break;
        case 2:
            MPI_Allreduce(buf, out, m, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
            break;
        case 3:
            MPI_Bcast(rank == 0 ? buf : out, m, MPI_DOUBLE, 0, MPI_COMM_WORLD);
            break;
        }
    }
    double t = (MPI_Wtime() - t0) / reps;
    MPI_Allreduce(MPI_IN_PLACE, &t, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
    return op == 0 ? t / 2 : t;
}

int main(int argc, char **argv) {
    MPI_Init(&argc, &argv);
    int rank, size;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &size);
    const int maxm = 1 << 20; /* 8 MiB of doubles */
    double *buf = malloc(sizeof(double) * maxm), *out = malloc(sizeof(double) * maxm);
    for (int i = 0; i < maxm; i++) buf[i] = i;
    memset(out, 0, sizeof(double) * maxm);
    const char *names[] = {"pingpong", "allgather", "allreduce", "bcast"};
    if (rank == 0) printf("op,ranks,bytes,seconds\n");
    for (int op = 0; op < 4; op++) {
        if (op == 0 && size < 2) continue;
        for (int m = size; m <= maxm; m *= 4) {
            int mm = op == 1 ? m / size * size : m;
            /* repetitions per round: about 5 ms at an assumed 1 GB/s + 2 us per call */
            double guess = 2e-6 + 8.0 * mm / 1e9;
            int reps = (int)(0.005 / guess);
            reps = reps < 2 ? 2 : reps > 2000 ? 2000 : reps;
            round_time(op, buf, out, mm, 2, rank, size); /* warm-up */
            double best = 1e30;
            for (int round = 0; round < 9; round++) {
                double t = round_time(op, buf, out, mm, reps, rank, size);
                if (t < best) best = t;
            }
            if (rank == 0) printf("%s,%d,%ld,%.6e\n", names[op], size, 8L * mm, best);
            fflush(stdout);
        }
    }
    free(buf);
    free(out);
    MPI_Finalize();
    return 0;
}
