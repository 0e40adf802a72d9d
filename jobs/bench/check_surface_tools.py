"""Checks of sample_surface.py and distance.py; exits non-zero on the first failure.

  python3 check_surface_tools.py [MESH.ply]

- distance.py against brute force with a different method (projection onto the plane of every
  triangle, inside test by barycentric coordinates, else the nearest of the three edges) on a
  mesh: the given PLY (e.g. a volspline output) or tests/data/cow.obj, for points near the
  surface, far from it and on it, and on a mesh with degenerate triangles;
- the PLY reader: the same mesh written as ascii and as binary little-endian (float and double
  vertices, uchar/int and int/uint face lists) reads back identically;
- sample_surface.py: samples lie on the mesh (distance at rounding level), are the same for the
  same seed, and fall on the triangles in proportion to their areas (chi-square test)."""
import os
import subprocess
import sys
import tempfile

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
sys.dont_write_bytecode = True  # no __pycache__ beside the scripts
sys.path.insert(0, HERE)
import distance  # noqa: E402
import sample_surface  # noqa: E402


def brute(pts, v, f):
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    n = np.cross(b - a, c - a)
    nn = (n * n).sum(axis=1)
    out = np.empty(len(pts))
    for i, p in enumerate(pts):
        # nearest of the three edges (segments), every triangle
        best = np.minimum.reduce([distance.seg_dist2(np.broadcast_to(p, x.shape), x, y) for x, y in [(a, b), (b, c), (c, a)]])
        ok = nn > 1e-300
        # projection onto each plane, kept where it falls inside the triangle
        s = ((p - a[ok]) * n[ok]).sum(axis=1) / nn[ok]
        q = p - s[:, None] * n[ok]
        e0, e1, e2 = b[ok] - a[ok], c[ok] - a[ok], q - a[ok]
        d00, d01, d11 = (e0 * e0).sum(1), (e0 * e1).sum(1), (e1 * e1).sum(1)
        d20, d21 = (e2 * e0).sum(1), (e2 * e1).sum(1)
        den = d00 * d11 - d01 * d01
        bv = (d11 * d20 - d01 * d21) / den
        bw = (d00 * d21 - d01 * d20) / den
        inside = (bv >= 0) & (bw >= 0) & (bv + bw <= 1)
        plane = (s * s * nn[ok])[inside]
        out[i] = np.sqrt(min(best.min(), plane.min() if len(plane) else np.inf))
    return out


def check(name, cond, detail):
    print(f"{'ok  ' if cond else 'FAIL'} {name}: {detail}")
    if not cond:
        sys.exit(1)


def write_ply(path, v, f, fmt, vtype="double", ctype="uchar", itype="int"):
    head = (f"ply\nformat {fmt} 1.0\ncomment check\nelement vertex {len(v)}\n"
            + "".join(f"property {vtype} {a}\n" for a in "xyz")
            + f"element face {len(f)}\nproperty list {ctype} {itype} vertex_indices\nend_header\n")
    with open(path, "wb") as out:
        out.write(head.encode())
        if fmt == "ascii":
            out.write("".join(f"{x!r} {y!r} {z!r}\n" for x, y, z in v.tolist()).encode())
            out.write("".join(f"3 {i} {j} {k}\n" for i, j, k in f.tolist()).encode())
            return
        vt = "<f8" if vtype == "double" else "<f4"
        out.write(v.astype(vt).tobytes())
        ct, it = distance.PLY_TYPES[ctype], distance.PLY_TYPES[itype]
        rec = np.zeros(len(f), dtype=[("n", "<" + ct), ("i", "<" + it, 3)])
        rec["n"], rec["i"] = 3, f
        out.write(rec.tobytes())


def main(tmp):
    rng = np.random.default_rng(7)
    if len(sys.argv) > 1:
        v, f = distance.read_mesh(sys.argv[1])
        name = os.path.basename(sys.argv[1])
    else:
        v, f = sample_surface.read_obj(f"{ROOT}/tests/data/cow.obj")
        name = "cow.obj"
    lo, hi = v.min(axis=0), v.max(axis=0)
    diag = np.linalg.norm(hi - lo)

    # 1. against brute force: near (within 2 % of the diagonal), far (the box grown by half) and on
    near = v[rng.integers(len(v), size=150)] + rng.normal(scale=0.02 * diag, size=(150, 3))
    far = lo - 0.5 * (hi - lo) + rng.random((50, 3)) * 2 * (hi - lo)
    on = sample_surface.sample(v, f, 50, rng)
    pts = np.vstack([near, far, on])
    got, want = distance.distances(v, f, pts), brute(pts, v, f)
    err = np.abs(got - want).max() / diag
    check(f"distance = brute force on {name} ({len(f)} triangles, {len(pts)} points)", err < 1e-12, f"max |diff| / diagonal = {err:.2e}")
    check("points sampled on the surface are at distance 0", got[-50:].max() / diag < 1e-12, f"max {got[-50:].max() / diag:.2e} of the diagonal")

    # degenerate triangles: a repeated vertex and three collinear vertices
    vd = np.vstack([v, [[0, 0, 0], [1, 1, 1], [2, 2, 2]]])
    k = len(v)
    fd = np.vstack([f[:200], [[0, 0, 1], [k, k + 1, k + 2], [k + 2, k + 1, k + 1]]])
    pts = np.vstack([pts[:100], [[0.5, 0.5, 0.6], [3, 3, 3], [-1, 0, 0]]])
    got, want = distance.distances(vd, fd, pts), brute(pts, vd, fd)
    err = np.abs(got - want).max() / diag
    check("distance = brute force with degenerate triangles", np.isfinite(got).all() and err < 1e-12, f"max |diff| / diagonal = {err:.2e}")

    # 2. PLY reader, four encodings of one mesh
    for fmt, vt, ct, it in [("ascii", "double", "uchar", "int"), ("binary_little_endian", "double", "uchar", "int"),
                            ("binary_little_endian", "float", "uchar", "uint"), ("binary_little_endian", "double", "int", "int")]:
        path = f"{tmp}/m.ply"
        write_ply(path, v, f, fmt, vt, ct, it)
        rv, rf = distance.read_ply(path)
        same_v = np.array_equal(rv, v) if vt == "double" else np.allclose(rv, v, rtol=1e-6, atol=1e-6 * diag)
        check(f"PLY {fmt} {vt} list {ct} {it} reads back", same_v and np.array_equal(rf, f), f"{len(rv)} vertices, {len(rf)} faces")

    # 3. sample_surface.py: determinism, on the surface, area-proportional
    bunny = f"{ROOT}/tests/data/bunny10k.obj"
    script = f"{HERE}/sample_surface.py"
    for name, seed in [("a", 1), ("b", 1), ("c", 2)]:
        subprocess.run([sys.executable, script, bunny, "20000", f"{tmp}/s{name}.xyz", "--seed", str(seed),
                        "--held-out", "3000", f"{tmp}/h{name}.xyz"], check=True)
    sa, sb, sc = (np.loadtxt(f"{tmp}/s{x}.xyz") for x in "abc")
    ha, hb = np.loadtxt(f"{tmp}/ha.xyz"), np.loadtxt(f"{tmp}/hb.xyz")
    check("same seed, same points; another seed, other points",
          np.array_equal(sa, sb) and np.array_equal(ha, hb) and not np.array_equal(sa, sc) and not np.array_equal(sa[:3000], ha),
          "seed 1 twice: identical data and held-out sets; seed 2: other data; held-out differs from data")
    bv, bf = sample_surface.read_obj(bunny)
    bd = np.linalg.norm(bv.max(axis=0) - bv.min(axis=0))
    d = distance.distances(bv, bf, np.vstack([sa, ha]))
    check("samples lie on the bunny", d.max() / bd < 1e-12, f"max distance / diagonal = {d.max() / bd:.2e}")
    # area-proportional: 100 bins of triangles of about equal total area, chi-square with 99 dof
    a, b, c = bv[bf[:, 0]], bv[bf[:, 1]], bv[bf[:, 2]]
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    n = 200_000
    tri, p = sample_surface.sample_faces(bv, bf, n, np.random.default_rng([5, 0]))
    inside = distance.point_triangle_dist2(p, a[tri], b[tri], c[tri]) < (1e-12 * bd) ** 2
    check("each sample lies in its triangle", inside.all(), f"{inside.sum()} of {n}")
    bins = np.minimum((np.cumsum(area) / area.sum() * 100).astype(int), 99)
    obs = np.bincount(bins[tri], minlength=100)
    exp = np.bincount(bins, weights=area, minlength=100) / area.sum() * n
    chi2 = ((obs - exp) ** 2 / exp).sum()
    check("samples fall on triangles in proportion to area", chi2 < 148, f"chi-square {chi2:.1f} on 99 dof (99.9 % point 148)")
    # uniform inside a triangle: the barycentric weight of vertex a has CDF 1 - (1 - x)^2
    e0, e1, e2 = b[tri] - a[tri], c[tri] - a[tri], p - a[tri]
    d00, d01, d11 = (e0 * e0).sum(1), (e0 * e1).sum(1), (e1 * e1).sum(1)
    d20, d21 = (e2 * e0).sum(1), (e2 * e1).sum(1)
    den = d00 * d11 - d01 * d01
    lam = 1 - (d11 * d20 - d01 * d21) / den - (d00 * d21 - d01 * d20) / den
    x = np.sort(lam)
    ks = np.abs(np.arange(1, n + 1) / n - (1 - (1 - np.clip(x, 0, 1)) ** 2)).max()
    check("uniform within the triangle", ks < 1.95 / np.sqrt(n), f"Kolmogorov-Smirnov {ks:.2e} (0.1 % point {1.95 / np.sqrt(n):.2e})")
    print("all checks passed")


if __name__ == "__main__":
    with tempfile.TemporaryDirectory() as tmp:
        main(tmp)
