"""Caps over holes continued by a quadric of their collar (a prototype, quality only).

  CAP=collar=6,resid=0.12 python3 bench-results/2026-12-07-surface-quadric-caps/cap.py OUT [surface.py options]

(from the repository root, with a release binary given by --binary). Every set that
jobs/bench/surface.py makes is first fitted by the default (`volspline fit`, 2 ranks, grid 100);
the vertices of its mesh farther than `sup` (2) median spacings from every data point are the
unsupported surface, split into connected pieces. For each piece larger than `minarea` (3) discs
of radius 2 spacings, the data points within `collar` spacings of it are its collar; a quadric
height field z(u, v) (6 coefficients, least squares) is fitted to the collar in the frame of the
principal axes of the collar and the piece together. Where its rms residual is at most `resid`
times the frame's largest standard deviation, the piece's vertices are moved onto the quadric
along the frame's normal, thinned to one per cell of a median spacing, those within a spacing of
the data dropped, and the rest added to the points as data: the benchmark then runs on the
enlarged set as usual (the truth is unchanged). Options as KEY=VALUE in CAP."""
import os, sys, subprocess, tempfile
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "jobs", "bench"))
import numpy as np
from scipy.spatial import cKDTree
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
import surface, distance

P = dict(sup=2.0, minarea=3.0, collar=3.0, resid=0.08, density=1.0, keep=1.0)
for kv in os.environ.get("CAP", "").split(","):
    if kv:
        a, b = kv.split("="); P[a] = float(b)

def augment(pts, binary):
    tree = cKDTree(pts)
    d, _ = tree.query(pts, 2); h = np.median(d[:, 1])
    with tempfile.TemporaryDirectory() as tmp:
        xyz = os.path.join(tmp, "a.xyz")
        np.savetxt(xyz, pts)
        subprocess.run(["mpirun", "-n", "2", binary, "fit", xyz, "--out", tmp + "/a", "--grid", "100", "--margin", "0.05",
                        "--threads", "1", "--no-preview"], check=True, capture_output=True)  # noqa: E501
        v, f = distance.read_mesh(tmp + "/a.ply")
    dv, _ = tree.query(v)
    un = dv > P["sup"] * h
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    e = e[un[e[:, 0]] & un[e[:, 1]]]
    g = coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(len(v), len(v)))
    _, lab = connected_components(g, directed=False)
    extra, info = [], []
    cell = np.linalg.norm(v.max(0) - v.min(0)) / 150
    for L in np.unique(lab[un]):
        C = v[(lab == L) & un]
        # area proxy: vertices x cell^2
        if len(C) * cell * cell < P["minarea"] * np.pi * (2 * h) ** 2 or len(C) < 20:
            continue
        ci = np.unique(np.concatenate([np.asarray(x, dtype=np.int64) for x in tree.query_ball_point(C[::max(1, len(C) // 400)], P["collar"] * h)]))
        if len(ci) < 12:
            continue
        Q = pts[ci]; c = Q.mean(0)
        # frame from the cap's vertices and collar together
        X = np.concatenate([Q, C]); cx = X.mean(0)
        w, V = np.linalg.eigh(np.cov((X - cx).T)); n, e1, e2 = V[:, 0], V[:, 2], V[:, 1]
        q = Q - cx
        u, vv, z = q @ e1, q @ e2, q @ n
        A = np.stack([np.ones_like(u), u, vv, u * u, u * vv, vv * vv], 1)
        coef, *_ = np.linalg.lstsq(A, z, rcond=None)
        ext = np.sqrt(w[2])
        res = np.sqrt(np.mean((A @ coef - z) ** 2)) / ext
        cc = C - cx
        cu, cv, cz = cc @ e1, cc @ e2, cc @ n
        zq = np.stack([np.ones_like(cu), cu, cv, cu * cu, cu * cv, cv * cv], 1) @ coef
        shift = np.sqrt(np.mean((zq - cz) ** 2))
        if res > P["resid"]:
            info.append(f"cap {len(C)} collar {len(ci)} resid {res:.3f} skip"); continue
        Y = cx + cu[:, None] * e1 + cv[:, None] * e2 + zq[:, None] * n
        # thin to ~h spacing
        s = h * P["density"]
        key = np.floor(Y / s).astype(np.int64)
        _, first = np.unique(key, axis=0, return_index=True)
        Y = Y[first]
        dy, _ = tree.query(Y)
        Y = Y[dy > P["keep"] * h]
        extra.append(Y)
        info.append(f"cap {len(C)} collar {len(ci)} resid {res:.3f} shift/h {shift / h:.2f} added {len(Y)}")
    if extra:
        pts = np.concatenate([pts] + extra)
    return pts, info

orig = surface.make_sets
def make_sets(args):
    out = []
    for s in orig(args):
        s = list(s)
        p, info = augment(s[4], args.binary)
        print(f"# {s[0]}: {len(s[4])} -> {len(p)}: {'; '.join(info)}", flush=True)
        s[4] = p
        out.append(tuple(s))
    return out
surface.make_sets = make_sets
surface.main(sys.argv[1:])
