"""Calibrated scaling model of volspline's dense solvers: time(N, P) for the row-cyclic layout the
solvers use against a 2D block-cyclic layout (ScaLAPACK's, a pr x pc grid), for Householder QR,
LU with partial pivoting and the projected Cholesky. Used by jobs/scaling-model.

Usage: python3 scaling_model.py OUT    (reads OUT/micro_blas.csv, OUT/micro_mpi.csv, OUT/machine.txt,
OUT/command.txt and the measured studies under bench-results/; writes OUT/raw.csv, OUT/model.csv,
OUT/validation.csv, OUT/summary.md and PNG plots)

The model
=========
Machine parameters. Local kernels (one thread per rank): g3(k), the DGEMM rate of an update of
inner dimension k (micro-benchmark, OpenBLAS); g2, the rate of an unblocked BLAS-2 panel (LAPACK's
dgeqr2/dgetf2 on a tall panel). Messages (Hockney): a point-to-point message of B bytes costs
a + b B; each collective has its own (a, b), fitted on 2 ranks, and on q ranks costs

    allgather(B, q) = ceil(log2 q) a + 2 (q-1)/q B b          (B: bytes every rank ends with)
    allreduce(B, q) = ceil(log2 q) a + 2 (q-1)/q B b          (Rabenseifner: reduce-scatter + allgather)
    bcast(B, q)     = ceil(log2 q) a + min(log2 q, 2 (q-1)/q) B b

(on q = 2 these are the fitted a + B b). volspline's kernels (faer) run at the local rate

    R(m) = eff g3(nb) m / (m + m0),   m = the smallest dimension of the local update, m0 = 32

(a Hockney-style (r_inf, n_1/2) law: the packing of a GEMM's operands is amortised over its
smaller dimension; m0 is assumed), and every factorisation step (column) costs a fixed c seconds
on every rank besides its flops and messages (loop and allocation overheads, which no layout
divides). eff and c are fitted per solver and per machine from the 1-rank times of that machine
only; the P > 1 times are then predictions.

Algorithms (n = N + k rows, panel width nb, a panel starting at row j has m_j = n - j rows; rows
per rank at that step: ceil(m_j / P) row-cyclic, ceil(m_j / pr) x ceil(m_j / pc) in 2D). Sums
over the panels give the times; the flops of every rank's share run one after the other with
the collectives (no overlap, as in the code: no look-ahead).

Row-cyclic (volspline, src/linalg/dist):
  Householder  per column one all-reduce of ~nb + 2 values (norm, x^T A, the pivot row); per
               panel all-reduces of V^T V (nb^2) and of W = V^T A_trail (nb x m_j) and the local
               update 4 (m_j/P) nb m_j; with, in the code now, Y = V T^T for each rank's own rows
               (2 nb^2 m_j / P flops), and in the revisions of the calibrating studies T^T W (2 nb^2
               m_j flops on every rank; from 4 ranks on a reduce-scatter of W, 2 nb^2 m_j / P flops a
               rank and an all-gather, counted as the all-reduce).
  LU           per column one all-gather of every rank's candidate with its row's leaf part
               (P (8 + 2) values: grows with P) and a row swap (point-to-point); per panel the interchange of the
               trailing rows (P - 1 shifts), the all-gather of the nb x m_j block row, and the local GEMM
               2 (m_j/P) nb m_j; the recursive panel's leaves (8 columns) are BLAS-2. With, in the
               code now (block form), W = L21 L11^-1 for each rank's own rows (nb^2 m_j / P), and in
               the revisions of the calibrating studies U12 = L11^-1 A12 solved on every rank (nb^2
               m_j; from 4 ranks on L11 all-gathered, A12 dealt in column shares, counted as an
               all-gather of 1/P of it, nb^2 m_j / P a rank and the all-gather of U12).
  The validation against the studies models their revisions; the predictions model the code now.
  Both rate a triangular solve as a GEMM of its flops, which flatters the textbook LU's U12 solve:
  on a 2-core AVX-512 machine the block form made the 1-rank LU at n = 8000 4 % faster with the
  same flops.
  Cholesky     the projection (6 n^2 k / P flops, one all-gather of n x k); per panel an all-gather
               of the diagonal block, its redundant Cholesky (nb^3 / 3), the local L21 solve, the
               all-gather of all of L21 (nb x m_j: the whole panel, not a block row) and the
               lower-triangle update nb (m_j/P) m_j; substitutions: three collectives per panel.
2D block-cyclic (ScaLAPACK-like PDGETRF / PDGEQRF / PDPOTRF, no look-ahead):
  the panel is factored by the pr ranks of one process column (per column: LU a max-loc all-reduce
  and a broadcast of the pivot row over pr, QR two all-reduces over pr); the panel is broadcast
  along the process rows (nb m_j / pr values over pc), U12 / W / L21^T along the process columns
  (nb m_j / pc values over pr); LU swaps rows of m_j / pc values one by one; the trailing update is
  (m_j / pr) x nb x (m_j / pc) per rank.
Both layouts use the same local rates, so the comparison is of the distributions alone.

Memory per rank (the rule of volspline's preflight, `panel_bytes` in src/app/preflight.rs):
its rows of the matrix (the lower triangle and a page per column for the Cholesky), the panels'
buffers, 2.5 nb n + 3 nb n / P values (every rank receives each panel's block across all
columns, the current one and the next; measured on 1-3 ranks), and 200 MB. For the 2D layout the
same rule with the rank's process row and column in place of all rows: 2.5 nb (n / pr + n / pc)
+ 3 nb n / P (not measured beyond 2 ranks).
"""
import csv
import math
import os
import sys
from collections import defaultdict

import numpy as np
from scipy.optimize import least_squares

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

LEAF = 8  # columns of the leaves of volspline's recursive LU panel
SHARED_MIN = 1 << 20  # U12 (LU) and T^T W (Householder) of at least this many multiply-adds were shared
SHARED_FROM = 4  # ... from this many ranks on (the revisions of the calibrating studies)
# The default panels of the revisions that measured the calibrating studies below (36fbe80,
# d92baee, a01d138; the last one's Cholesky took 384 from 6000 rows). Later revisions changed them
# (Householder 128; LU 192, 320 from 6000 rows with faer's products; Cholesky 384 from 6000 rows):
# a study measured with those should be modelled with its own panels.
NB = {"householder": 64, "lu": 128, "cholesky": 256}
BORDER = 4  # k: polynomial columns of the bordered system (linear polynomials in 3D)
SOLVERS = ["householder", "lu", "cholesky"]
PS = [1, 2, 3, 4, 6, 8, 16, 32, 64, 128, 256, 512, 1024]
NS = [400, 1000, 2000, 4000, 8000, 10_000, 20_000, 50_000, 100_000]
# Savchenko et al. 1995, Table 1: 400 x 400 system, Householder, INMOS T800 transputers
PAPER_T1 = {1: (180.2, 99.9), 2: (90.5, 99.4), 3: (62.5, 96.0), 6: (32.7, 92.0)}
# The measured studies the model is checked against: (folder, label, folder of the micro-benchmarks
# run on the study's own machine, or None where only this machine's are at hand)
NODE16 = "bench-results/2026-11-26-node16-scaling-model"
STUDIES = [
    ("bench-results/2026-11-26-table1-16cores", "16-core Xeon (table1)", None),
    ("bench-results/2026-11-26-node16-table1", "16-core Xeon, later revision (table1)", NODE16),
    ("bench-results/2026-11-23-table1", "2-core EPYC (table1)", None),
    ("bench-results/2026-11-23-bench-solve", "2-core EPYC (bench-solve)", None),
]
# Measured 2D block-cyclic times on the 16-core Xeon, checked against the model's 2D times with that
# machine's network and the eff, c of its row-cyclic study: (folder, calibrating study)
STUDIES_2D = [
    ("bench-results/2026-11-26-node16-table1-2d", "bench-results/2026-11-26-node16-table1"),
    ("bench-results/2026-11-26-node16-solve", "bench-results/2026-11-26-node16-table1"),
]
# Assumed (not measured) networks: a cluster interconnect, and the transputer links of 1995
CLUSTER = dict(a=2e-6, bw=2e9)  # 2 us per message, 2 GB/s per rank (a 200 Gb/s link shared by 12 ranks)
T800 = dict(a=50e-6, bw=1.7e6)  # 20 Mbit/s links (about 1.7 MB/s of data), 50 us per message in software


# ---------------------------------------------------------------- machine parameters
def read_csv(path):
    with open(path) as f:
        return list(csv.DictReader(f))


def fit_hockney(pts):
    """(a, b) of t = a + b B by least squares on log t (relative errors weigh every size alike)."""
    x = np.array([p[0] for p in pts], float)
    t = np.array([p[1] for p in pts], float)
    a0, b0 = max(t.min(), 1e-8), max(np.median(t[x > 1e5] / x[x > 1e5]) if (x > 1e5).any() else 1e-10, 1e-13)

    def res(v):
        return np.log(np.exp(v[0]) + np.exp(v[1]) * x) - np.log(t)

    s = least_squares(res, [math.log(a0), math.log(b0)])
    return math.exp(s.x[0]), math.exp(s.x[1])


class Machine:
    """Kernel rates and message costs; `cores` caps the ranks that compute at once."""

    def __init__(self, g3, g2, net, cores, name, m0=32.0):
        self.g3_table, self.g2, self.net, self.cores, self.name, self.m0 = g3, g2, net, cores, name, m0

    def g3(self, k):
        ks = sorted(self.g3_table)
        return float(np.interp(math.log(k), [math.log(x) for x in ks], [self.g3_table[x] for x in ks]))

    def with_net(self, net, name):
        return Machine(self.g3_table, self.g2, net, self.cores, name, self.m0)


def measured_net(mpi):
    """Per-message (a, b) of each operation from micro_mpi rows measured on q ranks: the fitted cost
    of one operation on q ranks divided by the factors with which the collectives below grow with
    q (none on 2 ranks), so that the same formulas carry it to other rank counts."""
    net = {}
    for op in ["pingpong", "allgather", "allreduce", "bcast"]:
        rows = [r for r in mpi if r["op"] == op]
        q = int(rows[0]["ranks"])
        a, b = fit_hockney([(float(r["bytes"]), float(r["seconds"])) for r in rows])
        if op != "pingpong" and q > 2:
            a /= lg(q)
            b /= min(math.log2(q), 2 * (q - 1) / q) if op == "bcast" else 2 * (q - 1) / q
        net[op] = (a, b)
    return net


def measured_machine(out):
    blas = read_csv(f"{out}/micro_blas.csv")
    g3 = {int(r["k"]): float(r["gflops"]) * 1e9 for r in blas if r["kernel"] == "dgemm"}
    # the panel rate: unblocked panels of 64 columns, tall (the rows a panel has in a large system)
    panel = [float(r["gflops"]) * 1e9 for r in blas if r["kernel"] in ("getf2", "geqr2") and int(r["k"]) == 64]
    g2 = float(np.median(panel))
    mpi = read_csv(f"{out}/micro_mpi.csv")
    net = measured_net(mpi)
    cores = int([ln for ln in open(f"{out}/machine.txt") if ln.startswith("cores:")][0].split()[1])
    return Machine(g3, g2, net, cores, "this machine (measured)"), blas, mpi


def uniform_net(a, bw):
    return {op: (a, 1.0 / bw) for op in ["pingpong", "allgather", "allreduce", "bcast"]}


# ---------------------------------------------------------------- collectives
def lg(q):
    return math.ceil(math.log2(q)) if q > 1 else 0


def allgather(net, nbytes, q):
    if q <= 1:
        return 0.0 * nbytes
    a, b = net["allgather"]
    return lg(q) * a + 2 * (q - 1) / q * nbytes * b


def allreduce(net, nbytes, q):
    if q <= 1:
        return 0.0 * nbytes
    a, b = net["allreduce"]
    return lg(q) * a + 2 * (q - 1) / q * nbytes * b


def bcast(net, nbytes, q):
    if q <= 1:
        return 0.0 * nbytes
    a, b = net["bcast"]
    return lg(q) * a + min(math.log2(q), 2 * (q - 1) / q) * nbytes * b


def p2p(net, nbytes, q):
    if q <= 1:
        return 0.0 * nbytes
    a, b = net["pingpong"]
    return a + nbytes * b


# ---------------------------------------------------------------- the algorithms
def grid2d(p):
    """The squarest pr x pc = p with pr <= pc."""
    pr = max(d for d in range(1, int(math.isqrt(p)) + 1) if p % d == 0)
    return pr, p // pr


# volspline's widest default panels at scale and its 2D block (a unit test in
# src/linalg/dist/solver.rs checks these two lines against the solvers' defaults)
MEM_NB = {"householder": 192, "lu": 320, "cholesky": 384}  # volspline's widest default panels
MEM_NB_2D = 128  # its default 2D block
MEM_FIXED = 200e6  # the preflight's fixed part a rank
PAGE = 4096


def memory_per_rank(solver, layout, n, p):
    """Bytes a rank holds at the peak of a dense solve by the preflight's rule (see the module doc),
    and the part of them that is panel buffers."""
    pr, pc = grid2d(p) if layout == "2d" else (p, 1)
    rows, cols = math.ceil(n / pr), math.ceil(n / pc)
    whole = rows * cols * 8.0
    if solver == "cholesky":
        matrix = min(whole, whole / 2 + cols * PAGE)
    else:
        matrix = whole
    if layout == "2d":
        panels = MEM_NB_2D * 8.0 * (2.5 * (n / pr + n / pc) + 3.0 * n / p)
    else:
        panels = MEM_NB[solver] * 8.0 * (2.5 * n + 3.0 * n / p)
    return matrix + panels + MEM_FIXED, panels


def model_time(solver, layout, n, p, mach, eff, col_s, nb=None, grid=None, now=True):
    """Predicted solve time (s) of `solver` on an n x n system over p ranks (2D: on `grid`, the
    squarest one by default). `now`: the row-cyclic LU and Householder as the code runs them now
    (products of each rank's own rows), else as the revisions that measured the calibrating
    studies ran them (U12 and T^T W formed whole, or in shares from 4 ranks)."""
    nb = nb or NB[solver]
    net = mach.net
    share = max(1.0, p / mach.cores)  # ranks beyond the cores share them
    g3 = eff * mach.g3(nb)
    g2 = eff * mach.g2  # volspline's kernels at eff of OpenBLAS's, panels and updates alike

    def rate(m):
        return g3 * m / (m + mach.m0)

    size = n - BORDER if solver == "cholesky" else n
    j = np.arange(0, size, nb, dtype=float)
    kb = np.minimum(nb, size - j)
    mj = size - j  # rows (and columns) left at the panel
    rest = np.maximum(mj - kb, 0.0)  # trailing columns
    cols = rest + 1  # with the right-hand side
    if layout == "row":
        loc = np.ceil(mj / p)
        locr = np.ceil(rest / p)
        if solver == "householder":
            flops = 2 * loc * kb**2 / g2 + 4 * loc * kb * cols / rate(loc)
            if now:
                # Y = V T^T for this rank's rows
                redundant = 2 * loc * kb**2 / rate(loc) + kb**3 / 3 / g2
            else:
                # shared: a reduce-scatter of W and an all-gather of T^T W, the traffic of the all-reduce
                shared = (kb**2 * cols >= SHARED_MIN) & (p >= SHARED_FROM)
                redundant = 2 * kb**2 * cols / np.where(shared, p, 1) / g3 + kb**3 / 3 / g2
            comm = (kb * allreduce(net, 8 * (kb + 2), p) + allreduce(net, 8 * kb**2, p) + allreduce(net, 8 * kb * cols, p))
        elif solver == "lu":
            leaf = loc * kb * LEAF
            flops = leaf / g2 + np.maximum(loc * kb**2 - leaf, 0) / rate(loc) + 2 * locr * kb * cols / rate(np.maximum(locr, 1))
            inner = np.maximum(kb / LEAF - 1, 0)
            comm = (kb * (allgather(net, 8 * p * (LEAF + 2), p) + p2p(net, 8 * kb, p))
                    + inner * allgather(net, 0, p) + allgather(net, 8 * kb**2 * np.log2(np.maximum(kb / LEAF, 1)) / 2, p)
                    + (p - 1) * p2p(net, 0, p) + (2 * 8 * kb * cols / p * net["pingpong"][1] if p > 1 else 0))
            if now:
                # W = L21 L11^-1 for this rank's rows; the block row all-gathered whole
                redundant = loc * kb**2 / rate(loc)
                comm = comm + allgather(net, 8 * kb * (cols + kb), p)
            else:
                shared = (kb**2 * cols >= SHARED_MIN) & (p >= SHARED_FROM)
                redundant = kb**2 * cols / np.where(shared, p, 1) / g3
                comm = comm + np.where(shared, allgather(net, 8 * kb * kb, p) + allgather(net, 8 * kb * cols / p, p)
                                       + allgather(net, 8 * kb * cols, p), allgather(net, 8 * kb * (cols + kb), p))
        else:
            flops = loc * kb**2 / rate(loc) + kb * locr * rest / rate(np.maximum(locr, 1))
            redundant = kb**3 / 3 / g3
            comm = allgather(net, 8 * kb**2, p) + allgather(net, 8 * kb * rest, p)
        per_panel = share * (flops.sum() + redundant.sum() + size * col_s) + comm.sum()
        if solver == "cholesky":
            m = math.ceil(n / p)
            proj = share * 6 * m * n * BORDER / rate(m) + allgather(net, 8 * n * BORDER, p) + allgather(net, 8 * n, p)
            subst = share * 2 * n * n / p / g2 + len(j) * (3 * allgather(net, 8 * nb**2, p) + allreduce(net, 8 * nb, p))
            return proj + per_panel + subst
        subst = share * n * n / p / g2 + len(j) * allgather(net, 8 * nb * (nb + 1), p)
        return per_panel + subst
    pr, pc = grid or grid2d(p)
    locr = np.ceil(mj / pr)
    locc = np.ceil(cols / pc)
    m = np.maximum(np.minimum(np.ceil(rest / pr), locc), 1)
    if solver == "householder":
        flops = 2 * locr * kb**2 / g2 + 2 * kb**2 * locc / g3 + kb**3 / 3 / g2 + 4 * np.ceil(rest / pr) * kb * locc / rate(m)
        comm = (2 * kb * allreduce(net, 8 * (kb + 2), pr) + bcast(net, 8 * kb * locr, pc)
                + allreduce(net, 8 * kb * locc, pr) + bcast(net, 8 * kb * locc, pr))
    elif solver == "lu":
        leaf = locr * kb * LEAF
        flops = (leaf / g2 + np.maximum(locr * kb**2 - leaf, 0) / rate(np.maximum(locr, 1)) + kb**2 * locc / g3
                 + 2 * np.ceil(rest / pr) * kb * locc / rate(m))
        comm = (kb * (allreduce(net, 16, pr) + bcast(net, 8 * kb, pr) + p2p(net, 8 * kb, pr))
                + bcast(net, 8 * kb * locr, pc) + kb * p2p(net, 8 * locc, pr) + bcast(net, 8 * kb * locc, pr))
    else:
        flops = kb**3 / 3 / g3 + locr * kb**2 / rate(np.maximum(locr, 1)) + kb * np.ceil(rest / pr) * locc / rate(m)
        comm = bcast(net, 8 * kb**2, pr) + bcast(net, 8 * kb * locr, pc) + bcast(net, 8 * kb * locc, pr)
    subst = share * 2 * n * n / pr / g2 + len(j) * 2 * (allreduce(net, 8 * nb, pr) + bcast(net, 8 * nb, pc))
    extra = 0.0
    if solver == "cholesky":
        extra = share * 6 * math.ceil(n / p) * n * BORDER / rate(math.ceil(n / p)) + allgather(net, 8 * n * BORDER, p)
    return share * (flops.sum() + size * col_s) + comm.sum() + subst + extra


# ---------------------------------------------------------------- measured studies
def load_study(folder):
    """{(solver, n, p): best time}, the machine's cores, and what the folder says about itself."""
    rows = read_csv(f"{folder}/raw.csv")
    best = {}
    for r in rows:
        if "impl" in r:
            if r["impl"] != "volspline":
                continue
            key, t = (r["operation"], int(r["n"]), int(r["ranks"])), float(r["seconds"])
        else:
            # jobs/table1 with LAYOUT=2d: not the row-cyclic layout the validation models
            if not r.get("layout", "row-cyclic").startswith("row"):
                continue
            key, t = (r["solver"], int(r["system_size"]), int(r["ranks"])), float(r["solve_s"])
        best[key] = min(best.get(key, 1e30), t)
    cores = int([ln for ln in open(f"{folder}/machine.txt") if ln.startswith("cores:")][0].split()[1])
    return best, cores


def calibrate(best, solver, mach):
    """eff and the per-column overhead c of `solver` from the 1-rank times (least squares of log
    time)."""
    pts = [(n, t) for (s, n, p), t in best.items() if s == solver and p == 1]
    if len(pts) < 2:
        return None

    def res(v):
        eff, c = math.exp(v[0]), math.exp(v[1])
        return [math.log(model_time(solver, "row", n, 1, mach, eff, c, now=False)) - math.log(t) for n, t in pts]

    s = least_squares(res, [math.log(0.5), math.log(1e-6)], bounds=([-5, -25], [4, -5]))
    return math.exp(s.x[0]), math.exp(s.x[1]), float(np.sqrt(np.mean(np.square(s.fun))))


def validate_2d(root, calib, machines):
    """Lines of the summary: the measured 2D block-cyclic times of STUDIES_2D against the model's
    2D times (and the measured and predicted ratio row-cyclic / 2D where both were measured)."""
    L = ["\n## Validation of the 2D layout: the 16-core Xeon\n",
         "volspline's solvers on the 2D block-cyclic layout (look-ahead off where the study has both) against the "
         "model's 2D times on the same grid, with the eff and c fitted to the 1-rank row-cyclic times of the "
         "calibrating study and the Xeon's own 16-rank network. Not one of these points was used to fit.\n",
         "| study | solver | N+k | grid | panel | measured 2D (s) | predicted 2D (s) | error | measured row-cyclic (s) | measured row / 2D | predicted row / 2D |",
         "|---|---|---:|---|---:|---:|---:|---:|---:|---:|---:|"]
    errs = []
    for folder, cal in STUDIES_2D:
        path = os.path.join(root, folder)
        if not os.path.exists(f"{path}/raw.csv") or cal not in machines:
            L.append(f"| {folder} | (missing) | | | | | | | | | |")
            continue
        mach = machines[cal]
        row_best, _ = load_study(os.path.join(root, cal))
        pts = {}
        for r in read_csv(f"{path}/raw.csv"):
            if "impl" in r:
                if r["impl"] != "volspline-2d":
                    continue
                solver, n, grid, t = r["operation"], int(r["n"]), r["grid"], float(r["seconds"])
                nb = 64  # jobs/bench-solve passes --panel NB (64)
            else:
                solver, n, t = r["solver"], int(r["system_size"]), float(r["solve_s"])
                grid = r["layout"].split()[-1]
                nb = 64 if solver == "householder" else 128  # the 2D defaults
            key = (solver, n, grid, nb)
            pts[key] = min(pts.get(key, 1e30), t)
        for (solver, n, grid, nb), t in sorted(pts.items()):
            if (cal, solver) not in calib:
                continue
            eff, c = calib[(cal, solver)]
            pr, pc = (int(v) for v in grid.split("x"))
            p = pr * pc
            tp = model_time(solver, "2d", n, p, mach, eff, c, nb=nb, grid=(pr, pc))
            trow = row_best.get((solver, n, p))
            prow = model_time(solver, "row", n, p, mach, eff, c, now=False)
            errs.append(abs(relerr(tp, t)))
            L.append(f"| {os.path.basename(folder)} | {solver} | {n} | {grid} | {nb} | {t:.3f} | {tp:.3f} | "
                     f"{100 * relerr(tp, t):+.0f} % | {f'{trow:.3f}' if trow else ''} | "
                     f"{f'{trow / t:.2f}' if trow else ''} | {prow / tp:.2f} |")
    if errs:
        L.append(f"\nMedian absolute error of the 2D predictions: {100 * np.median(errs):.0f} % "
                 f"(max {100 * max(errs):.0f} %, {len(errs)} points).")
    return L


def relerr(pred, meas):
    return pred / meas - 1.0


def fmt_t(t):
    return f"{t:.3g}" if t < 1000 else f"{t:.0f}"


def main(out):
    root = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
    here, blas, mpi = measured_machine(out)
    machine_txt = open(f"{out}/machine.txt").read().strip()
    command = open(f"{out}/command.txt").read().strip()
    with open(f"{out}/raw.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["benchmark", "op", "ranks", "m", "n", "k", "bytes", "seconds", "gflops"])
        for r in blas:
            w.writerow(["micro_blas", r["kernel"], 1, r["m"], r["n"], r["k"], "", r["seconds"], r["gflops"]])
        for r in mpi:
            w.writerow(["micro_mpi", r["op"], r["ranks"], "", "", "", r["bytes"], r["seconds"], ""])
    L = [f"# Scaling model of the dense solvers: row-cyclic against 2D block-cyclic\n", f"Command: `{command}`\n",
         "```", machine_txt, "```\n"]
    L.append("## Parameters measured on this machine (micro-benchmarks, one thread per rank)\n")
    L.append("| parameter | value |")
    L.append("|---|---:|")
    for k, g in sorted(here.g3_table.items()):
        L.append(f"| DGEMM rate g3, inner dimension {k} (GFLOP/s) | {g / 1e9:.1f} |")
    L.append(f"| unblocked panel rate g2, dgetf2/dgeqr2 of 64 columns, median (GFLOP/s) | {here.g2 / 1e9:.2f} |")
    for op, (a, b) in here.net.items():
        L.append(f"| {op} on 2 ranks: latency a (us) / bandwidth 1/b (GB/s) | {a * 1e6:.2f} / {1 / b / 1e9:.2f} |")
    L.append(f"\nRaw micro-benchmark figures: raw.csv (micro_blas.csv, micro_mpi.csv as written by the programs).")

    # ------------------------------------------------ validation against the measured studies
    val_rows, calib = [], {}
    L.append("\n## Validation: the measured studies\n")
    L.append("For each study, eff and c of each solver are fitted to that study's 1-rank times only; the other "
             "ranks are predictions. The 16-core Xeon's flop rates come only from its own 1-rank points; its "
             "g2/g3 ratio is assumed to be this machine's, and so is its network in the first Xeon study (one "
             "shared-memory node, the same OpenMPI 4.1.4 shared-memory transport); the later one uses the network "
             "measured on the Xeon itself (16 ranks). Ranks beyond a machine's cores share them (compute x P/cores): "
             "those points are marked oversubscribed and left out of the error statistics.\n")
    L.append("| study | solver | eff (of OpenBLAS DGEMM here) | local rate eff g3(nb) (GFLOP/s) | c per column (us) | fit rms (log) at 1 rank | points P > 1 | median abs error | max abs error |")
    L.append("|---|---|---:|---:|---:|---:|---:|---:|---:|")
    figv, axv = plt.subplots(len(STUDIES), 3, figsize=(14, 3.6 * len(STUDIES)), squeeze=False)
    machines = {}
    for si, (folder, label, micro) in enumerate(STUDIES):
        path = os.path.join(root, folder)
        if not os.path.exists(f"{path}/raw.csv"):
            L.append(f"| {label} | (missing: {folder}) | | | | | | | |")
            continue
        best, cores = load_study(path)
        net = here.net
        if micro and os.path.exists(os.path.join(root, micro, "micro_mpi.csv")):
            net = measured_net(read_csv(os.path.join(root, micro, "micro_mpi.csv")))
        mach = Machine(here.g3_table, here.g2, net, cores, label)
        machines[folder] = mach
        for ci, solver in enumerate(SOLVERS):
            ax = axv[si][ci]
            c = calibrate(best, solver, mach)
            if c is None:
                ax.set_visible(False)
                continue
            eff, mh, rms = c
            calib[(folder, solver)] = (eff, mh)
            errs = []
            for n in sorted({n for (s, n, p) in best if s == solver}):
                ps = sorted(p for (s, nn, p) in best if s == solver and nn == n)
                meas = [best[(solver, n, p)] for p in ps]
                pgrid = sorted(set(ps) | {1, 2, 4, 8, 16})
                pgrid = [p for p in pgrid if p <= max(ps)]
                pred = [model_time(solver, "row", n, p, mach, eff, mh, now=False) for p in pgrid]
                line = ax.loglog(pgrid, pred, "-")
                ax.loglog(ps, meas, "o", color=line[0].get_color(), label=f"N+k={n}")
                for p, t in zip(ps, meas):
                    tp = model_time(solver, "row", n, p, mach, eff, mh, now=False)
                    over = p > cores
                    val_rows.append([label, solver, n, p, t, tp, relerr(tp, t), "yes" if over else "no"])
                    if p > 1 and not over:
                        errs.append(abs(relerr(tp, t)))
            ax.set(title=f"{label}: {solver}", xlabel="ranks P", ylabel="solve time (s)")
            ax.legend(fontsize=7)
            med = f"{100 * np.median(errs):.0f} %" if errs else "—"
            mx = f"{100 * max(errs):.0f} %" if errs else "—"
            L.append(f"| {label} | {solver} | {eff:.3f} | {eff * mach.g3(NB[solver]) / 1e9:.1f} | {mh * 1e6:.2f} | {rms:.3f} | {len(errs)} | {med} | {mx} |")
    figv.suptitle("Measured (points) against the model (lines), row-cyclic; 1-rank points calibrate")
    figv.tight_layout()
    figv.savefig(f"{out}/validation.png", dpi=100)
    with open(f"{out}/validation.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["study", "solver", "n", "ranks", "measured_s", "predicted_s", "relative_error", "oversubscribed"])
        w.writerows(val_rows)
    L.append("\nEvery point: validation.csv (relative error = predicted / measured - 1); plot: validation.png.\n")
    L.extend(validate_2d(root, calib, machines))
    L.append("| study | solver | N+k | P | measured (s) | predicted (s) | error |")
    L.append("|---|---|---:|---:|---:|---:|---:|")
    for r in val_rows:
        if r[3] > 1:
            L.append(f"| {r[0]} | {r[1]} | {r[2]} | {r[3]}{' (oversubscribed)' if r[7] == 'yes' else ''} | {r[4]:.4f} | {r[5]:.4f} | {100 * r[6]:+.0f} % |")

    # ------------------------------------------------ the paper's Table 1 on transputers
    t800 = Machine({1: 1.0, 2: 1.0}, 1.0, uniform_net(T800["a"], T800["bw"]), 10**9, "T800", m0=0.0)
    unit = model_time("householder", "row", 400, 1, t800, 1.0, 0.0, nb=1)
    eff800 = unit / PAPER_T1[1][0]  # flop rate of one transputer (flop/s) from the paper's 1-processor time
    L.append("\n## Table 1 of Savchenko et al. 1995 (400 x 400 Householder, INMOS T800)\n")
    L.append(f"One transputer's rate from the paper's 1-processor time: {eff800 / 1e6:.2f} MFLOP/s (unblocked, nb = 1). "
             f"Assumed, not measured: links of {T800['bw'] / 1e6:.1f} MB/s and {T800['a'] * 1e6:.0f} us per message, "
             "tree collectives, row-cyclic rows.\n")
    L.append("| processors | paper time (s) | paper use (%) | model time (s) | model use (%) |")
    L.append("|---:|---:|---:|---:|---:|")
    for p in [1, 2, 3, 4, 6, 8, 16, 32, 64, 128, 256, 512, 1024]:
        t = model_time("householder", "row", 400, p, t800, eff800, 0.0, nb=1)
        pt = PAPER_T1.get(p)
        L.append(f"| {p} | {pt[0] if pt else ''} | {pt[1] if pt else ''} | {t:.2f} | {100 * PAPER_T1[1][0] / (p * t):.1f} |")

    # ------------------------------------------------ predictions P = 1..1024, N = 400..1e5
    ref = "bench-results/2026-11-23-bench-solve"
    scen = {"shared memory (measured here)": here.with_net(here.net, "here"),
            f"cluster (assumed: {CLUSTER['a'] * 1e6:.0f} us, {CLUSTER['bw'] / 1e9:.0f} GB/s per rank)":
                here.with_net(uniform_net(CLUSTER["a"], CLUSTER["bw"]), "cluster")}
    for m in scen.values():
        m.cores = 10**9  # predictions: every rank on its own core
    model_rows = []
    for sname, mach in scen.items():
        for solver in SOLVERS:
            eff, mh = calib.get((ref, solver), (0.5, 0.0))
            for n in NS:
                t1 = model_time(solver, "row", n, 1, mach, eff, mh)
                for p in PS:
                    for layout in ["row", "2d"]:
                        t = model_time(solver, layout, n, p, mach, eff, mh)
                        pr, pc = grid2d(p) if layout == "2d" else (p, 1)
                        model_rows.append([sname, solver, layout, f"{pr}x{pc}", n, p, t, 100 * t1 / (p * t)])
    with open(f"{out}/model.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["scenario", "solver", "layout", "grid", "n", "ranks", "predicted_s", "processor_use_pct"])
        w.writerows(model_rows)
    T = {(r[0], r[1], r[2], r[4], r[5]): r[6] for r in model_rows}
    L.append("\n## Predictions, P = 1..1024, N+k = 400..10^5\n")
    L.append(f"Local rates: this machine's micro-benchmarks with eff and c of each solver from the 1-rank points of "
             f"{ref} (this machine); every rank on a core of its own; no memory limit (N = 10^5 needs 80 GB in all). "
             "Two networks: the shared-memory costs measured here (an idealised machine of many such cores), "
             "and an assumed cluster network. All of it: model.csv.\n")
    for sname in scen:
        L.append(f"\n### Householder, {sname}: time (s) row-cyclic / 2D, processor use of row-cyclic\n")
        L.append("| N+k | " + " | ".join(f"P={p}" for p in PS) + " |")
        L.append("|---:|" + "---|" * len(PS))
        for n in NS:
            t1 = T[(sname, "householder", "row", n, 1)]
            cells = [f"{fmt_t(T[(sname, 'householder', 'row', n, p)])} / {fmt_t(T[(sname, 'householder', '2d', n, p)])} "
                     f"({100 * t1 / (p * T[(sname, 'householder', 'row', n, p)]):.0f} %)" for p in PS]
            L.append(f"| {n} | " + " | ".join(cells) + " |")

    # crossover: the first P at which row-cyclic is slower than 2D
    L.append("\n## Where row-cyclic loses to 2D\n")
    L.append("The first P (of " + ", ".join(map(str, PS)) + ") at which the row-cyclic time exceeds the 2D one "
             "(\"—\": not up to 1024), and the ratio row-cyclic / 2D at P = 64 and P = 1024.\n")
    L.append("| network | solver | " + " | ".join(f"N+k={n}" for n in NS) + " |")
    L.append("|---|---|" + "---|" * len(NS))
    decision = {}
    for sname in scen:
        for solver in SOLVERS:
            cells = []
            for n in NS:
                cross = next((p for p in PS if p > 1 and T[(sname, solver, "row", n, p)] > T[(sname, solver, "2d", n, p)]), None)
                r64 = T[(sname, solver, "row", n, 64)] / T[(sname, solver, "2d", n, 64)]
                r1k = T[(sname, solver, "row", n, 1024)] / T[(sname, solver, "2d", n, 1024)]
                cells.append(f"{cross or '—'} ({r64:.2f}, {r1k:.2f})")
                if n >= 10_000:
                    for p in PS:
                        if p >= 64:
                            decision.setdefault((sname, solver), []).append(
                                T[(sname, solver, "row", n, p)] / T[(sname, solver, "2d", n, p)])
            L.append(f"| {sname} | {solver} | " + " | ".join(cells) + " |")
    L.append("\n## Does 2D matter at P >= 64 for N >= 10^4?\n")
    L.append("Read as: over the points N+k >= 10^4, P >= 64 of the grid above, the median of row-cyclic time / 2D time "
             "is at least 1.1 (2D at least 10 % faster) for every solver.\n")
    answers = []
    for (sname, solver), ratios in decision.items():
        med = float(np.median(ratios))
        answers.append(med >= 1.1)
        L.append(f"- {sname}, {solver}: row-cyclic / 2D from {min(ratios):.2f} to {max(ratios):.2f}, median {med:.2f}; "
                 f"2D faster at {100 * np.mean([r > 1 for r in ratios]):.0f} % of the points, at least 10 % faster at "
                 f"{100 * np.mean([r >= 1.1 for r in ratios]):.0f} %")
    if all(answers):
        verdict = "yes: by the model, a 2D block-cyclic layout matters at P >= 64 for N >= 10^4, for all three solvers and both networks"
    elif not any(answers):
        verdict = "no: by the model, the row-cyclic layout stays within 10 % of 2D at P >= 64 for N >= 10^4"
    else:
        verdict = "for some solvers and networks only (the lines above say which)"
    L.append(f"\n**Answer: {verdict}.** The gain shrinks as N grows at fixed P (the flops, which both layouts divide "
             "alike, outgrow the messages) and grows with P: row-cyclic pays ceil(log2 P) latencies per column for "
             "Householder's all-reduces and LU's pivot all-gathers (2D: log2 sqrt(P) in one process column) and "
             "receives the n^2/2 values of every block row or panel on every rank (2D: about n^2/sqrt(P)).")

    # ------------------------------------------------ memory per rank
    L.append("\n## Memory per rank\n")
    L.append("The preflight's rule (src/app/preflight.rs): the rank's rows of the matrix, the panels' buffers "
             "(2.5 nb n + 3 nb n / P values: each panel's block across all columns reaches every rank) and 200 MB; "
             "for 2D the same with the rank's process row and column, 2.5 nb (n/pr + n/pc) + 3 nb n / P (a bound, "
             "measured only on 2 ranks). Panels: volspline's widest defaults, " +
             ", ".join(f"{s} {MEM_NB[s]}" for s in SOLVERS) + "; 2D blocks " + str(MEM_NB_2D) + ". "
             "GB per rank, row-cyclic / 2D, and the share of the row-cyclic figure that is panel buffers.\n")
    mem_ps = [p for p in PS if p >= 16]
    L.append("| solver | N+k | " + " | ".join(f"P={p}" for p in mem_ps) + " |")
    L.append("|---|---:|" + "---|" * len(mem_ps))
    for solver in SOLVERS:
        for n in [n for n in NS if n >= 20_000]:
            cells = []
            for p in mem_ps:
                row, panels = memory_per_rank(solver, "row", n, p)
                two, _ = memory_per_rank(solver, "2d", n, p)
                cells.append(f"{row / 1e9:.2f} / {two / 1e9:.2f} ({100 * panels / row:.0f} %)")
            L.append(f"| {solver} | {n} | " + " | ".join(cells) + " |")
    L.append("\nOn the row-cyclic layout the panels' buffers do not shrink with P, so from about "
             "P = n / (2.5 nb) on (half that for the Cholesky's lower triangle; at N+k = 10^5 about 210 for the "
             "Householder's panels of 192, 125 for the LU's 320, 52 for the Cholesky's 384) they hold more than the "
             "matrix rows: the memory side of the case for 2D at scale.")

    # ------------------------------------------------ plots of the predictions
    fig, ax = plt.subplots(1, 3, figsize=(16, 4.6))
    sname = next(iter(scen))
    for n in NS:
        tr = [T[(sname, "householder", "row", n, p)] for p in PS]
        line = ax[0].loglog(PS, tr, "-", label=f"N+k={n}")
        ax[0].loglog(PS, [T[(sname, "householder", "2d", n, p)] for p in PS], "--", color=line[0].get_color())
        ax[1].semilogx(PS, [100 * tr[0] / (p * t) for p, t in zip(PS, tr)], "-", color=line[0].get_color(), label=f"N+k={n}")
    for folder, label, _ in STUDIES[2:]:
        path = os.path.join(root, folder)
        if os.path.exists(f"{path}/raw.csv"):
            best, cores = load_study(path)
            pts = [(p, t) for (s, n, p), t in best.items() if s == "householder" and p <= cores]
            ax[0].loglog([p for p, _ in pts], [t for _, t in pts], "k^", ms=5, label=f"measured: {label}" if folder == STUDIES[2][0] else None)
    ax[0].set(xlabel="ranks P", ylabel="time (s)", title=f"Householder, {sname}: row-cyclic (-), 2D (--)")
    ax[1].set(xlabel="ranks P", ylabel="processor use (%)", title="Processor use T1 / (P TP), row-cyclic")
    ps800 = PS
    t800s = [model_time("householder", "row", 400, p, t800, eff800, 0.0, nb=1) for p in ps800]
    ax[2].loglog(ps800, t800s, "-", label="model, row-cyclic (T800)")
    ax[2].loglog(ps800, [model_time("householder", "2d", 400, p, t800, eff800, 0.0, nb=1) for p in ps800], "--", label="model, 2D (T800)")
    ax[2].loglog(list(PAPER_T1), [v[0] for v in PAPER_T1.values()], "ko", label="Savchenko et al. 1995, Table 1")
    ax[2].set(xlabel="processors", ylabel="time (s)", title="Table 1: 400 x 400 Householder on transputers")
    for a in ax:
        a.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(f"{out}/table1_prediction.png", dpi=100)
    fig, ax = plt.subplots(len(scen), 3, figsize=(15, 4.2 * len(scen)), squeeze=False)
    for i, sname in enumerate(scen):
        for j, solver in enumerate(SOLVERS):
            for n in NS:
                ax[i][j].semilogx(PS, [T[(sname, solver, "row", n, p)] / T[(sname, solver, "2d", n, p)] for p in PS], label=f"N+k={n}")
            ax[i][j].axhline(1.0, color="k", lw=0.8)
            ax[i][j].axvline(64, color="grey", ls=":")
            ax[i][j].set(xlabel="ranks P", ylabel="time row-cyclic / time 2D", title=f"{solver}, {sname}")
            ax[i][j].legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(f"{out}/crossover.png", dpi=100)
    load = [ln.split(":", 1)[1].strip() for ln in machine_txt.splitlines() if ln.startswith("load_average_at_start")]
    L.append("\n## Caveats\n")
    L.append(f"- The micro-benchmarks share this machine's cores with whatever else runs (load average at the start: "
             f"{load[0] if load else '?'}): where eff > 1, OpenBLAS's DGEMM ran slower here and now than volspline's "
             "kernels ran in the study. The model uses only the product eff g3 (the local rate column), fitted to each "
             "study's own 1-rank times, so the load moves eff, not the predictions; the message costs are the best of "
             "9 short rounds, the figure least disturbed by the load.")
    L.append("- The 2D column of every table is the model's, not a measurement: ScaLAPACK's 2D times on 2 ranks "
             "(jobs/bench-solve, GRIDS) are the only measured 2D points so far. At P = 2 and 3 the squarest grid is "
             "1 x P (a column-cyclic layout: the panel on one rank, no collective per column).")
    L.append("- The first 16-core Xeon study's network is assumed to be this machine's shared memory; the later one "
             f"uses the Xeon's own MPI micro-benchmark on 16 ranks ({NODE16}). Both take this machine's g2/g3 ratio: "
             "on the Xeon, Debian 12's OpenBLAS 0.3.21 did not recognise the processor and ran generic kernels "
             "(DGEMM 7-14 GFLOP/s against faer's 56-62 on the same core), so its micro_blas.csv is not that "
             "machine's rate. Ranks are assumed to have a core each; memory bandwidth shared by 16 ranks is not in "
             "the model.")
    L.append("\nPlots: validation.png (measured against predicted), table1_prediction.png (Householder predictions "
             "P = 1..1024 with the measured points, and the transputer Table 1), crossover.png (row-cyclic / 2D).")
    L.append("\nThe model (equations and what each term stands for): the module doc of jobs/bench/scaling_model.py.")
    open(f"{out}/summary.md", "w").write("\n".join(L) + "\n")
    print("\n".join(L))


if __name__ == "__main__":
    main(sys.argv[1])
