"""A second-order treecode for the level-0 sum of a two-level model, against the exact sum at 4000
random nodes of its box (errors and work measured on the first 400). Usage: python3 treecode.py MODEL.h5"""
import sys
import h5py, numpy as np, time
h = h5py.File(sys.argv[1])
C = h['coarse0_centres_normalised'][()]; W = h['coarse0_weights'][()]
print("centres", len(C), "sum|w|", np.abs(W).sum(), "sum w", W.sum(), "|sum w c|", np.abs(W @ C).max(), "max|w|", np.abs(W).max())
rng = np.random.default_rng(0)
lo, hi = C.min(0) - 0.05, C.max(0) + 0.05
X = lo + (hi - lo) * rng.random((4000, 3))
def exact(X):
    return np.array([W @ np.linalg.norm(C - x, axis=1) for x in X])
t = time.time(); F = exact(X); print("exact", time.time() - t, "f range", F.min(), F.max(), "median |f|", np.median(np.abs(F)))
# octree
class Node: pass
def build(idx, lo, hi, leaf=32):
    n = Node(); n.idx = idx
    P = C[idx]; w = W[idx]
    n.c = (lo + hi) / 2
    d = P - n.c
    n.a = np.sqrt((d * d).sum(1)).max() if len(idx) else 0
    n.M0 = w.sum(); n.M1 = w @ d; n.M2 = (w[:, None, None] * d[:, :, None] * d[:, None, :]).sum(0)
    n.A = np.abs(w).sum()
    # third-order moment for an error estimate
    n.kids = []
    if len(idx) > leaf:
        mid = n.c
        for o in range(8):
            m = np.ones(len(idx), bool); l2 = lo.copy(); h2 = hi.copy()
            for k in range(3):
                if o >> k & 1: m &= P[:, k] >= mid[k]; l2[k] = mid[k]
                else: m &= P[:, k] < mid[k]; h2[k] = mid[k]
            if m.any(): n.kids.append(build(idx[m], l2, h2, leaf))
    return n
root = build(np.arange(len(C)), C.min(0) - 1e-9, C.max(0) + 1e-9)
def tree_eval(x, n, theta, stats):
    R = x - n.c; r = np.sqrt(R @ R)
    if n.kids and r > n.a / theta:
        u = R / r
        stats[0] += 1
        return n.M0 * r - u @ n.M1 + (np.trace(n.M2) - u @ n.M2 @ u) / (2 * r)
    if not n.kids or r <= n.a / theta and not n.kids:
        stats[1] += len(n.idx)
        return W[n.idx] @ np.linalg.norm(C[n.idx] - x, axis=1)
    return sum(tree_eval(x, k, theta, stats) for k in n.kids)
for theta in (0.5, 0.3, 0.2, 0.1):
    stats = [0, 0]; sub = X[:400]
    T = np.array([tree_eval(x, root, theta, stats) for x in sub])
    err = np.abs(T - F[:400])
    print(f"theta {theta}: work per node {(stats[0] + stats[1]) / len(sub):.0f} of {len(C)} (expansions {stats[0]/len(sub):.0f}, direct {stats[1]/len(sub):.0f}); err max {err.max():.2e} median {np.median(err):.2e}; rel to median|f| {err.max()/np.median(np.abs(F)):.1e}")
