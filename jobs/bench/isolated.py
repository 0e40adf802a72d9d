"""Isolated points in the surface benchmark's sets, as `volspline fit` finds them.

Writes every set of the eight samplings the surface benchmark is judged on (area-uniform seeds 1-7,
the scanner's vertices strided) as .xyz, fits each with the cheapest method (the plain carrier, the
compactly supported spline, an 8-node grid) and reads `isolated_points` from its timings, beside the
same count by the definition computed here with scipy (the distance to the 8th nearest other point
above 10 times the median over at most 4096 evenly spaced points, or a place in a group apart from
the rest by that distance holding at most 1 % of the points, or 8). Usage:
    python3 jobs/bench/isolated.py OUT --binary BIN
"""
import csv
import os
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
sys.dont_write_bytecode = True
sys.path.insert(0, HERE)


def by_definition(p):
    import numpy as np
    from scipy.spatial import cKDTree

    from scipy import ndimage

    d, _ = cKDTree(p).query(p, k=9)
    kth = d[:, 8]
    sampled = np.sort(kth[:: -(-len(kth) // 4096)])
    threshold = 10 * sampled[len(sampled) // 2]
    alone = kth > threshold
    # groups apart from the rest: connected parts (26-neighbourhood) of the occupied cubes of a
    # lattice as wide as the threshold, all but the largest, holding at most 1 % of the points
    # (or 8)
    cube = np.floor((p - p.min(axis=0)) / threshold).astype(np.int64)
    occupied = np.zeros(cube.max(axis=0) + 1, bool)
    occupied[tuple(cube.T)] = True
    labels, _ = ndimage.label(occupied, structure=np.ones((3, 3, 3), bool))
    part = labels[tuple(cube.T)]
    size = np.bincount(part)
    most = max(8, int(0.01 * len(p)))
    apart = (size[part] <= most) & (size[part] < size[part].max())
    return int(np.count_nonzero(alone | apart))


def main(out, binary):
    import numpy as np

    import surface

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for sampling, seed in [("area", s) for s in range(1, 8)] + [("strided", 1)]:
            args = surface.parse(["/dev/null", "--sampling", sampling, "--seed", str(seed)])
            for name, _mesh, n, variant, pts, *_ in surface.make_sets(args):
                pts = np.asarray(pts, float)
                xyz = os.path.join(tmp, "p.xyz")
                np.savetxt(xyz, pts, fmt="%.17g")
                timings = os.path.join(tmp, "t.csv")
                cmd = [binary, "fit", xyz, "--out", os.path.join(tmp, "f"), "--surface", "carrier",
                       "--method", "csrbf", "--grid", "8", "--no-preview", "--timings", timings]
                subprocess.run(cmd, check=True, capture_output=True, env={**os.environ, "RAYON_NUM_THREADS": "2"})
                figures = dict(line.strip().split(",", 1) for line in open(timings) if "," in line)
                rows.append({"sampling": f"{sampling}-seed{seed}" if sampling == "area" else sampling,
                             "set": name, "points": len(pts),
                             "isolated_volspline": int(figures["isolated_points"]),
                             "isolated_definition": by_definition(pts)})
    with open(os.path.join(out, "raw.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    flagged = [r for r in rows if r["isolated_volspline"] or r["isolated_definition"]]
    differ = [r for r in rows if r["isolated_volspline"] != r["isolated_definition"]]
    summary = (f"{len(rows)} sets; {len(flagged)} with isolated points; "
               f"{len(differ)} where volspline and the definition differ\n")
    for r in flagged:
        summary += f"  {r}\n"
    open(os.path.join(out, "summary.txt"), "w").write(summary)
    print(summary, end="")
    return 1 if differ else 0


if __name__ == "__main__":
    out = sys.argv[1]
    binary = sys.argv[sys.argv.index("--binary") + 1] if "--binary" in sys.argv else None
    sys.exit(main(out, binary))
