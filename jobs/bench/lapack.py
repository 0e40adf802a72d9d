"""LAPACK side of jobs/bench-solve: builds volspline's bordered system (kernel r, automatic ball
carrier, normalised coordinates, exactly as `volspline fit` does) from a point file and times
scipy.linalg.solve on it, and LAPACK dgetrf / dgeqrf (optimal workspace) on the same matrix.
Prints raw.csv rows, each time the best of REPEAT runs (2 if not given). Usage:
python3 lapack.py POINTS.xyz THREADS [REPEAT]"""
import sys
import time

import numpy as np
import scipy.linalg as sl
import scipy.linalg.lapack as la
from scipy.spatial.distance import cdist

pts = np.loadtxt(sys.argv[1])
threads = sys.argv[2]
repeat = int(sys.argv[3]) if len(sys.argv) > 3 else 2
lo, hi = pts.min(axis=0), pts.max(axis=0)
centre, scale = 0.5 * (lo + hi), 0.5 * np.linalg.norm(hi - lo)
x = (pts - centre) / scale
n, k = len(pts), 4
m = np.zeros((n + k, n + k), order="F")
m[:n, :n] = cdist(x, x)
m[:n, n] = 1.0
m[:n, n + 1 :] = x
m[n:, :n] = m[:n, n:].T
radius = 0.5 * np.linalg.norm(hi - lo)
b = np.concatenate([radius**2 - ((pts - centre) ** 2).sum(axis=1), np.zeros(k)])
size = n + k


def timed(f):
    """Best of `repeat` runs, after a small warm-up call that starts the BLAS threads."""
    best, out = float("inf"), None
    for _ in range(repeat):
        t = time.perf_counter()
        out = f()
        best = min(best, time.perf_counter() - t)
    return best, out


w = np.asfortranarray(np.random.default_rng(0).random((256, 256)))
sl.solve(w, w[:, 0])
la.dgetrf(w)


secs, sol = timed(lambda: sl.solve(m, b, check_finite=False))
res = np.linalg.norm(m @ sol - b) / np.linalg.norm(b)
print(f"scipy,solve,{size},1,{threads},{secs:.6f},,{res:.3e},")
secs, _ = timed(lambda: la.dgetrf(m, overwrite_a=False))
print(f"lapack,dgetrf,{size},1,{threads},{secs:.6f},,,")
lwork = int(la.dgeqrf_lwork(size, size)[0])
secs, _ = timed(lambda: la.dgeqrf(m, lwork=lwork, overwrite_a=False))
print(f"lapack,dgeqrf,{size},1,{threads},{secs:.6f},,,")
