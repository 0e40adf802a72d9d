"""Closed sheets thinner than the sampling: the default fit, the plain carrier method and screened
Poisson on a thin ellipsoid.

The surface benchmark's meshes (the bunny, the cow) have no part thinner than their point spacing
over a large area. A closed thin sheet (a leaf, a blade, a plate) is the case where orienting
normals estimated from the points is hardest: where the sheet is thinner than the spacing of the
points along it, every neighbourhood holds points of both sides, whose normals are nearly
parallel. This job measures where the methods stand there.

The sheet: the ellipsoid with semi-axes 1, 0.5 and C (thickness 2C), as a triangle mesh of a
latitude-longitude grid (400 x 200 vertices, denser than any sampling used), from which the
points are drawn area-uniformly (jobs/bench/sample_surface.py) and 5000 held-out truth samples
as well. For each C and N: `volspline fit` with no surface option (the default) and with
`--surface carrier`, 2 ranks, grid 100 along the longest side, `--margin auto` (the grid grows
where the solid reaches it: `reached` is 1 where the run warned that the solid still reaches the
grid's faces after the growth allowed), and screened Poisson on PCA normals (pymeshlab, depth 8,
as jobs/bench/surface.py runs it). Distances in % of the ellipsoid's bounding-box diagonal, exact
point-to-triangle distances (jobs/bench/distance.py): t2m (truth samples to the mesh), m2t (the
mesh's vertices to the true mesh), far2 (% of the mesh's vertices farther than 2 %). spacing: the
mean spacing of the points, sqrt(area / N), over the thickness 2C. Usage:
    python3 jobs/bench/thin_sheet.py OUT --binary BIN [--thickness 0.02,0.03,0.05] [--sizes 1000,2000,4000]
"""
import argparse
import csv
import os
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
sys.dont_write_bytecode = True
sys.path.insert(0, HERE)

TRUTH = 5000
FAR_PCT = 2.0


def ellipsoid_mesh(c, nu=400, nv=200):
    """Vertices and triangles of the ellipsoid with semi-axes 1, 0.5, c (poles as single vertices)."""
    import numpy as np

    u = np.linspace(0, 2 * np.pi, nu, endpoint=False)
    v = np.linspace(0, np.pi, nv + 1)[1:-1]
    uu, vv = np.meshgrid(u, v)
    ring = np.stack([np.cos(uu) * np.sin(vv), 0.5 * np.sin(uu) * np.sin(vv), c * np.cos(vv)], axis=-1).reshape(-1, 3)
    verts = np.vstack([[0, 0, c], ring, [0, 0, -c]])
    idx = lambda i, j: 1 + i * nu + (j % nu)  # noqa: E731
    faces = []
    for j in range(nu):
        faces.append([0, idx(0, j), idx(0, j + 1)])
        faces.append([len(verts) - 1, idx(len(v) - 1, j + 1), idx(len(v) - 1, j)])
    for i in range(len(v) - 1):
        for j in range(nu):
            faces.append([idx(i, j), idx(i + 1, j), idx(i + 1, j + 1)])
            faces.append([idx(i, j), idx(i + 1, j + 1), idx(i, j + 1)])
    return verts, np.array(faces, dtype=np.int64)


def stats(rv, rf, truth, tv, tf, diag):
    import numpy as np

    import distance

    used = np.unique(rf)
    t2m = 100 * distance.distances(rv, rf, truth) / diag
    m2t = 100 * distance.distances(tv, tf, rv[used]) / diag
    rms = lambda d: f"{np.sqrt((d * d).mean()):.4g}"  # noqa: E731
    return {"t2m_rms_pct": rms(t2m), "m2t_rms_pct": rms(m2t), "far2_pct": f"{100 * (m2t > FAR_PCT).mean():.4g}",
            "vertices": len(used)}


def run_volspline(binary, xyz, prefix, flags):
    import distance

    cmd = ["mpirun", "-n", "2", binary, "fit", xyz, "--out", prefix, "--grid", "100", "--threads", "1",
           "--no-preview"] + flags
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    text = out.stdout + out.stderr
    if out.returncode != 0:
        return None, f"exit {out.returncode}", 0
    reached = int("stopped at its limit" in text)
    return distance.read_mesh(prefix + ".ply"), "", reached


def run_poisson(pts):
    import numpy as np
    import pymeshlab

    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=np.ascontiguousarray(pts, dtype=np.float64)))
    ms.compute_normal_for_point_clouds(k=10)
    ms.generate_surface_reconstruction_screened_poisson(depth=8, threads=1)
    m = ms.current_mesh()
    return m.vertex_matrix().astype(float), m.face_matrix().astype(np.int64)


def main(argv):
    import numpy as np

    import sample_surface

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("out")
    ap.add_argument("--binary", required=True)
    ap.add_argument("--thickness", default="0.02,0.03,0.05", help="semi-axes C")
    ap.add_argument("--sizes", default="1000,2000,4000")
    ap.add_argument("--seed", type=int, default=7)
    a = ap.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for c in [float(x) for x in a.thickness.split(",")]:
            tv, tf = ellipsoid_mesh(c)
            diag = float(np.linalg.norm(tv.max(axis=0) - tv.min(axis=0)))
            ta, tb, tc = tv[tf[:, 0]], tv[tf[:, 1]], tv[tf[:, 2]]
            area = 0.5 * np.linalg.norm(np.cross(tb - ta, tc - ta), axis=1).sum()
            truth = sample_surface.sample(tv, tf, TRUTH, np.random.default_rng([a.seed, 1]))
            for n in [int(x) for x in a.sizes.split(",")]:
                pts = sample_surface.sample(tv, tf, n, np.random.default_rng([a.seed, 0, n]))
                xyz = os.path.join(tmp, "p.xyz")
                sample_surface.write_xyz(xyz, pts)
                base = {"c": c, "n": n, "spacing_over_thickness": f"{np.sqrt(area / n) / (2 * c):.3g}"}
                for method, flags in (("default", []), ("carrier", ["--surface", "carrier"])):
                    mesh, why, reached = run_volspline(a.binary, xyz, os.path.join(tmp, method), flags)
                    row = dict(base, method=method, reached=reached, note=why)
                    if mesh is not None:
                        row.update(stats(*mesh, truth, tv, tf, diag))
                    rows.append(row)
                    print(row, flush=True)
                row = dict(base, method="poisson", reached="", note="")
                row.update(stats(*run_poisson(pts), truth, tv, tf, diag))
                rows.append(row)
                print(row, flush=True)
    keys = ["c", "n", "spacing_over_thickness", "method", "t2m_rms_pct", "m2t_rms_pct", "far2_pct", "vertices",
            "reached", "note"]
    with open(os.path.join(a.out, "raw.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys, extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)
    with open(os.path.join(a.out, "summary.md"), "w") as f:
        f.write("# Closed thin sheets: an ellipsoid 1 x 0.5 x C\n\n")
        f.write("Cells: truth -> mesh rms / mesh -> truth rms / % of vertices beyond 2 % (of the diagonal); "
                "`reached`: the solid still reached the grid's faces after the growth allowed.\n\n")
        f.write("| C | N | spacing / thickness | default | carrier | poisson |\n|---|---|---|---|---|---|\n")
        by = {(r["c"], r["n"], r["method"]): r for r in rows}
        for c, n in sorted({(r["c"], r["n"]) for r in rows}):
            cell = lambda m: (lambda r: f"{r.get('t2m_rms_pct', '-')} / {r.get('m2t_rms_pct', '-')} / "  # noqa: E731
                              f"{r.get('far2_pct', '-')}" + (" reached" if r.get("reached") == 1 else ""))(by[(c, n, m)])
            f.write(f"| {c} | {n} | {by[(c, n, 'default')]['spacing_over_thickness']} | {cell('default')} | "
                    f"{cell('carrier')} | {cell('poisson')} |\n")


if __name__ == "__main__":
    main(sys.argv[1:])
