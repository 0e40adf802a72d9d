"""Where the vertices beyond 2 % of the diagonal of a closed set's fit lie, with and without the
cap points: near the truth mesh's own holes (its boundary vertices) or elsewhere.

  python3 bench-results/2026-12-07-surface-cap-bulge-alpha/base_holes.py BINARY SEED MESH N

(from the repository root; the set is the surface benchmark's MESH-N-clean of area sampling SEED,
fitted with `--cap-bulge 0` and with the binary's default on 2 ranks, grid 100)"""
import os, sys, types, subprocess
sys.path.insert(0, "jobs/bench")
import numpy as np
import surface, distance
binary, seed, mesh, n = sys.argv[1], int(sys.argv[2]), sys.argv[3], int(sys.argv[4])
args = types.SimpleNamespace(meshes=[mesh], sizes=[n], variant_sizes=[], variants=["clean"], sets=[], seed=seed,
                             sampling="area", permute=None, ranks=2, grid=100, timeout=900)
sets = surface.make_sets(args)
name, m, n, variant, pts, truth, tv, tf, diag, focus = sets[0]
import tempfile
tmp = tempfile.mkdtemp()
xyz = f"{tmp}/{name}.xyz"
np.savetxt(xyz, pts)
lo = tv.min(axis=0); hi = tv.max(axis=0)
res = {}
for label, flags in (("unpushed", ["--cap-bulge", "0"]), ("pushed", [])):
    args.binary = binary

    st, why, rec, times = surface.run_volspline(args, flags, xyz, f"{tmp}/{name}.{label}")
    rv, rf = rec
    used = np.unique(rf)
    d = 100 * distance.distances(tv, tf, rv[used]) / diag
    res[label] = (rv[used], d)
    far = d > 2
    print(label, "verts", len(used), "far %", 100 * far.mean(), "m2t rms", np.sqrt((d * d).mean()))
    # where are far vertices, in the box's unit coordinates
    u = (rv[used][far] - lo) / (hi - lo)
    if len(u):
        print("  far verts box coords: mean", u.mean(axis=0).round(3), "min", u.min(axis=0).round(3), "max", u.max(axis=0).round(3))
        h, _ = np.histogram(u[:, 1], bins=10, range=(0, 1))
        print("  far per y decile", h)
# truth mesh boundary loops (its own holes)
e = np.concatenate([tf[:, [0, 1]], tf[:, [1, 2]], tf[:, [2, 0]]])
uu, c = np.unique(np.sort(e, axis=1), axis=0, return_counts=True)
b = np.unique(uu[c == 1])
bu = (tv[b] - lo) / (hi - lo)
print("truth boundary verts", len(b), "box coords mean", bu.mean(axis=0).round(3) if len(b) else None)
# far vertices near a truth boundary vertex
from scipy.spatial import cKDTree
if len(b):
    t = cKDTree(tv[b])
    for label, (v, d) in res.items():
        far = d > 2
        dd, _ = t.query(v[far])
        print(label, "far verts within 5% diag of a truth boundary:", (dd < 0.05 * diag).sum(), "of", far.sum())
if len(b):
    for label, (v, d) in res.items():
        dd, _ = t.query(v)
        near = dd < 0.05 * diag
        r = lambda x: np.sqrt((x * x).mean())
        print(label, f"m2t rms near the truth's own holes {r(d[near]):.4f} ({near.sum()} verts), elsewhere {r(d[~near]):.4f}, far% elsewhere {100*(d[~near]>2).mean():.3f}")
