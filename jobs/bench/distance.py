"""Distances from points to a triangle mesh, for the accuracy of a reconstruction.

  python3 distance.py MESH.ply POINTS.xyz [--chunk C] [--diagonal-of XYZ]

MESH is a PLY file (ascii or binary_little_endian; the vertex element's x, y, z of any numeric
type, faces as a `list` of vertex indices, polygons split into fans), as volspline writes it, or a
Wavefront .obj. POINTS holds x y z per line. Prints `key,value` lines (the format of volspline's
--timings files): points, triangles, diagonal (of the bounding box of POINTS), the mean, 95th
percentile and maximum of the distances as a percentage of that diagonal (dist_mean_pct,
dist_p95_pct, dist_max_pct), the percentage of points farther than 2 % of it (dist_beyond2_pct),
and seconds. POINTS may also be a mesh (.ply or .obj): its vertices,
for the distance from a reconstruction to the true surface; --diagonal-of takes the diagonal from
another point file (the data's, so that spurious surface far out does not enlarge it).

The distance of each point is exact (to rounding): candidates come from a k-d tree of triangle
centroids. With d the exact distance to the nearest candidate so far, rho the largest distance of
a triangle's vertex from its centroid and c_k the k-th nearest centroid, every triangle not yet
examined lies at least c_k - rho away, so once c_k - rho >= d the search is over; the points
still open after the 8 nearest centroids examine every centroid within d + rho."""
import argparse
import itertools
import sys
import time

import numpy as np
from scipy.spatial import cKDTree

PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
             "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
             "float": "f4", "float32": "f4", "double": "f8", "float64": "f8"}


def fan(polys):
    """Triangles (m, 3) of polygons given as index lists."""
    tris = [[p[0], p[k], p[k + 1]] for p in polys for k in range(1, len(p) - 1)]
    return np.array(tris, dtype=np.int64).reshape(-1, 3)


def read_ply(path):
    data = open(path, "rb").read()
    end = data.index(b"end_header") + len(b"end_header")
    end = data.index(b"\n", end) + 1
    header = data[:end].decode("ascii").splitlines()
    fmt, elements = None, []
    for line in header:
        t = line.split()
        if not t or t[0] in ("ply", "comment", "obj_info", "end_header"):
            continue
        if t[0] == "format":
            fmt = t[1]
        elif t[0] == "element":
            elements.append((t[1], int(t[2]), []))
        elif t[0] == "property":
            elements[-1][2].append(("list", t[2], t[3], t[4]) if t[1] == "list" else ("scalar", t[1], t[2]))
    if fmt not in ("ascii", "binary_little_endian"):
        sys.exit(f"distance: PLY format {fmt} not supported (ascii, binary_little_endian)")
    body, pos = data[end:], 0
    tokens = body.split() if fmt == "ascii" else None
    verts = faces = None
    for name, count, props in elements:
        lists = [p for p in props if p[0] == "list"]
        if fmt == "ascii":
            if not lists:
                block = np.array(tokens[pos:pos + count * len(props)], dtype=float).reshape(count, len(props))
                pos += count * len(props)
                cols = {p[2]: block[:, i] for i, p in enumerate(props)}
                if name == "vertex":
                    verts = np.stack([cols["x"], cols["y"], cols["z"]], axis=1)
                continue
            polys = []
            for _ in range(count):
                for p in props:
                    if p[0] == "scalar":
                        pos += 1
                    else:
                        n = int(tokens[pos])
                        vals = [int(x) for x in tokens[pos + 1:pos + 1 + n]]
                        pos += 1 + n
                        if p[3] in ("vertex_indices", "vertex_index"):
                            polys.append(vals)
            if name == "face":
                faces = fan(polys)
            continue
        if not lists:
            dt = np.dtype([(p[2], "<" + PLY_TYPES[p[1]]) for p in props])
            rec = np.frombuffer(body, dtype=dt, count=count, offset=pos)
            pos += count * dt.itemsize
            if name == "vertex":
                verts = np.stack([rec["x"], rec["y"], rec["z"]], axis=1).astype(float)
            continue
        if name == "face" and len(props) == 1:
            # the common case: one list per face; try fixed triangles first
            _, ct, it, _ = props[0]
            dt = np.dtype([("n", "<" + PLY_TYPES[ct]), ("i", "<" + PLY_TYPES[it], 3)])
            if pos + count * dt.itemsize <= len(body):
                rec = np.frombuffer(body, dtype=dt, count=count, offset=pos)
                if np.all(rec["n"] == 3):
                    faces = rec["i"].astype(np.int64)
                    pos += count * dt.itemsize
                    continue
        polys = []
        for _ in range(count):
            for p in props:
                if p[0] == "scalar":
                    pos += np.dtype(PLY_TYPES[p[1]]).itemsize
                    continue
                ct, it = np.dtype("<" + PLY_TYPES[p[1]]), np.dtype("<" + PLY_TYPES[p[2]])
                n = int(np.frombuffer(body, dtype=ct, count=1, offset=pos)[0])
                vals = np.frombuffer(body, dtype=it, count=n, offset=pos + ct.itemsize)
                pos += ct.itemsize + n * it.itemsize
                if p[3] in ("vertex_indices", "vertex_index"):
                    polys.append(vals.tolist())
        if name == "face":
            faces = fan(polys)
    if verts is None or faces is None:
        sys.exit(f"distance: {path} has no vertex or face element")
    return verts, faces


def read_mesh(path):
    if path.lower().endswith(".obj"):
        v, polys = [], []
        for line in open(path):
            t = line.split()
            if t and t[0] == "v":
                v.append([float(x) for x in t[1:4]])
            elif t and t[0] == "f":
                idx = [int(x.split("/")[0]) for x in t[1:]]
                polys.append([i - 1 if i > 0 else len(v) + i for i in idx])
        return np.array(v, dtype=float), fan(polys)
    return read_ply(path)


def point_triangle_dist2(p, a, b, c):
    """Squared distances |p - T| for rows of points p and triangles (a, b, c), all (n, 3): the
    closest point by the Voronoi regions of the vertices, edges and face (Ericson, Real-Time
    Collision Detection, 5.1.5). Degenerate triangles fall back to their edges."""
    dot = lambda x, y: np.einsum("ij,ij->i", x, y)  # noqa: E731
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = dot(ab, ap), dot(ac, ap)
    bp = p - b
    d3, d4 = dot(ab, bp), dot(ac, bp)
    cp = p - c
    d5, d6 = dot(ab, cp), dot(ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        t_ab = d1 / (d1 - d3)
        t_ac = d2 / (d2 - d6)
        t_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        den = 1.0 / (va + vb + vc)
        v_in, w_in = vb * den, vc * den
        conds = [(d1 <= 0) & (d2 <= 0), (d3 >= 0) & (d4 <= d3), (vc <= 0) & (d1 >= 0) & (d3 <= 0),
                 (d6 >= 0) & (d5 <= d6), (vb <= 0) & (d2 >= 0) & (d6 <= 0),
                 (va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0)]
        q = np.empty_like(p)
        choice = np.select(conds, np.arange(6), default=6)
        for k, pick in enumerate([a, b, a + t_ab[:, None] * ab, c, a + t_ac[:, None] * ac,
                                  b + t_bc[:, None] * (c - b), a + v_in[:, None] * ab + w_in[:, None] * ac]):
            m = choice == k
            q[m] = pick[m]
    d2 = ((p - q) ** 2).sum(axis=1)
    bad = ~np.isfinite(d2)
    if bad.any():
        d2[bad] = np.minimum.reduce([seg_dist2(p[bad], x[bad], y[bad]) for x, y in [(a, b), (b, c), (c, a)]])
    return d2


def seg_dist2(p, a, b):
    ab = b - a
    L = (ab * ab).sum(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(L > 0, ((p - a) * ab).sum(axis=1) / L, 0.0)
    t = np.clip(np.nan_to_num(t), 0.0, 1.0)
    return ((p - a - t[:, None] * ab) ** 2).sum(axis=1)


def distances(verts, faces, pts, chunk=100_000):
    """Exact distance of every point to the mesh (see the module doc)."""
    a, b, c = verts[faces[:, 0]], verts[faces[:, 1]], verts[faces[:, 2]]
    cen = (a + b + c) / 3
    rho = np.sqrt(np.max([((x - cen) ** 2).sum(axis=1) for x in (a, b, c)], axis=0)).max()
    tree = cKDTree(cen)

    def pair_dist(idx, cand):
        """Distances of points idx[j] to triangles cand[j], in batches of `chunk` pairs."""
        out = np.empty(len(idx))
        for s in range(0, len(idx), chunk):
            i, t = idx[s:s + chunk], cand[s:s + chunk]
            out[s:s + chunk] = np.sqrt(point_triangle_dist2(pts[i], a[t], b[t], c[t]))
        return out

    k = min(8, len(faces))
    ck, ik = tree.query(pts, k=k)
    ck, ik = ck.reshape(len(pts), k), ik.reshape(len(pts), k)
    best = pair_dist(np.repeat(np.arange(len(pts)), k), ik.ravel()).reshape(len(pts), k).min(axis=1)
    open_ = np.flatnonzero((ck[:, -1] - rho < best) & (k < len(faces)))
    for s in range(0, len(open_), 20_000):
        idx = open_[s:s + 20_000]
        lists = tree.query_ball_point(pts[idx], best[idx] + rho, return_sorted=False)
        counts = np.fromiter((len(x) for x in lists), dtype=np.int64, count=len(idx))
        cand = np.fromiter(itertools.chain.from_iterable(lists), dtype=np.int64, count=counts.sum())
        keep = counts > 0
        d = pair_dist(np.repeat(idx, counts), cand)
        starts = np.concatenate([[0], np.cumsum(counts)[:-1]])[keep]
        best[idx[keep]] = np.minimum(best[idx[keep]], np.minimum.reduceat(d, starts))
    return best


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("mesh")
    ap.add_argument("points")
    ap.add_argument("--chunk", type=int, default=100_000, help="point-triangle pairs per numpy batch")
    ap.add_argument("--diagonal-of", help="point file whose bounding box gives the diagonal")
    args = ap.parse_args()
    t0 = time.perf_counter()
    verts, faces = read_mesh(args.mesh)
    if args.points.endswith((".ply", ".obj")):
        pts = read_mesh(args.points)[0]
    else:
        pts = np.fromfile(args.points, sep=" ").reshape(-1, 3)
    if len(faces) == 0:
        sys.exit(f"distance: {args.mesh} has no triangles")
    if len(pts) == 0:
        sys.exit(f"distance: {args.points} has no points")
    box = np.fromfile(args.diagonal_of, sep=" ").reshape(-1, 3) if args.diagonal_of else pts
    diag = float(np.linalg.norm(box.max(axis=0) - box.min(axis=0)))
    d = 100 * distances(verts, faces, pts, args.chunk) / diag
    print(f"points,{len(pts)}\ntriangles,{len(faces)}\ndiagonal,{diag:.9g}")
    print(f"dist_mean_pct,{d.mean():.6g}\ndist_p95_pct,{np.percentile(d, 95):.6g}\ndist_max_pct,{d.max():.6g}")
    print(f"dist_beyond2_pct,{100 * np.mean(d > 2):.6g}")
    print(f"seconds,{time.perf_counter() - t0:.3f}")


if __name__ == "__main__":
    main()
