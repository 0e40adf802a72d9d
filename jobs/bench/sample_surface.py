"""Point sets on the surface of a triangle mesh for the benchmarks.

  python3 sample_surface.py MESH.obj N OUT.xyz [--held-out M HELD.xyz] [--seed S]
      N points uniformly distributed over the surface area: a triangle is chosen with probability
      proportional to its area, then a point uniform in it (barycentric coordinates (u, v) uniform
      in the unit square, folded into the triangle). The same MESH, N and S give the same points.
      --held-out writes M further samples drawn from an independent stream of the same seed (the
      same M points whatever N is), for measuring the accuracy of a reconstruction away from the
      data it was fitted to.
  python3 sample_surface.py MESH.obj N OUT.xyz --strided
      N of the mesh's vertices, evenly strided through the file order (vertex floor(i V / N) for
      i = 0..N-1), as jobs/bench/points.py picks the bunny subsets.

MESH is a Wavefront .obj: `v x y z` and `f i j k ...` records (polygons are split into fans;
`i/t/n` and negative indices are understood). Writes x y z per line, full double precision."""
import argparse
import sys

import numpy as np


def read_obj(path):
    v, f = [], []
    for line in open(path):
        t = line.split()
        if not t:
            continue
        if t[0] == "v":
            v.append([float(x) for x in t[1:4]])
        elif t[0] == "f":
            idx = [int(x.split("/")[0]) for x in t[1:]]
            idx = [i - 1 if i > 0 else len(v) + i for i in idx]
            f.extend([idx[0], idx[k], idx[k + 1]] for k in range(1, len(idx) - 1))
    return np.array(v, dtype=float), np.array(f, dtype=np.int64).reshape(-1, 3)


def sample_faces(v, f, n, rng):
    """n points uniform on the surface and the triangle each lies in."""
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    cdf = np.cumsum(area)
    if not cdf[-1] > 0:
        sys.exit("sample_surface: the mesh has no area")
    tri = np.searchsorted(cdf, rng.random(n) * cdf[-1], side="right")
    tri = np.minimum(tri, len(f) - 1)
    u, w = rng.random(n), rng.random(n)
    fold = u + w > 1
    u[fold], w[fold] = 1 - u[fold], 1 - w[fold]
    a, b, c = a[tri], b[tri], c[tri]
    return tri, a + u[:, None] * (b - a) + w[:, None] * (c - a)


def sample(v, f, n, rng):
    return sample_faces(v, f, n, rng)[1]


def write_xyz(path, p):
    np.savetxt(path, p, fmt="%.17g")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("mesh")
    ap.add_argument("n", type=int)
    ap.add_argument("out")
    ap.add_argument("--held-out", nargs=2, metavar=("M", "HELD.xyz"))
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--strided", action="store_true", help="evenly strided vertices instead of samples")
    args = ap.parse_args()
    v, f = read_obj(args.mesh)
    if args.strided:
        if args.n > len(v):
            sys.exit(f"sample_surface: {args.mesh} has {len(v)} vertices, {args.n} requested")
        write_xyz(args.out, v[np.floor(np.arange(args.n) * (len(v) / args.n)).astype(int)])
        return
    if len(f) == 0:
        sys.exit(f"sample_surface: {args.mesh} has no faces")
    # two independent streams of one seed: the data, and the held-out samples
    write_xyz(args.out, sample(v, f, args.n, np.random.default_rng([args.seed, 0])))
    if args.held_out:
        m, path = int(args.held_out[0]), args.held_out[1]
        write_xyz(path, sample(v, f, m, np.random.default_rng([args.seed, 1])))


if __name__ == "__main__":
    main()
