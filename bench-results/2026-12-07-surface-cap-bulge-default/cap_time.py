"""Fit time with and without the cap points on the same binary, the same sets, interleaved.

  python3 bench-results/2026-12-07-surface-cap-bulge-default/cap_time.py BINARY OUT.csv [RUNS]

(from the repository root). The holed sets of area sampling 1 of the surface benchmark (the
bunny and the cow at 1000 and 2000 points, `open`, `openx`, `openmy`, `openmz`), each fitted on
2 ranks, grid 100, one thread per rank, RUNS times (default 3) with `--cap-bulge 0` and with the
binary's default, alternately; the fastest run of each (the sum of the stage maxima of
`--timings`, render included) and the number of cap points the default placed."""
import csv
import os
import re
import subprocess
import sys
import tempfile
import types

sys.path.insert(0, "jobs/bench")
import surface  # noqa: E402

binary, out = sys.argv[1], sys.argv[2]
runs = int(sys.argv[3]) if len(sys.argv) > 3 else 3
args = types.SimpleNamespace(meshes=["bunny", "cow"], sizes=[], variant_sizes=[1000, 2000],
                             variants=["open", "openx", "openmy", "openmz"], sets=[], seed=1,
                             sampling="area", permute=None)
tmp = tempfile.mkdtemp()
rows = []
for name, _, _, _, pts, *_ in surface.make_sets(args):
    xyz = os.path.join(tmp, name + ".xyz")
    with open(xyz, "w") as fh:
        fh.write("".join(f"{x!r} {y!r} {z!r}\n" for x, y, z in pts.tolist()))
    best = {"unpushed": float("inf"), "pushed": float("inf")}
    caps = 0
    for _ in range(runs):
        for label, flags in (("unpushed", ["--cap-bulge", "0"]), ("pushed", [])):
            t = os.path.join(tmp, "t.csv")
            cmd = ["mpirun", "-n", "2", binary, "fit", xyz, "--out", os.path.join(tmp, "o"), "--grid", "100",
                   "--margin", "0.05", "--threads", "1", "--no-preview", "--timings", t] + flags
            text = subprocess.run(cmd, capture_output=True, text=True, check=True).stdout
            kv = dict(line.split(",", 1) for line in open(t).read().splitlines()[1:] if "," in line)
            s = sum(float(v) for k, v in kv.items()
                    if k.startswith("stage_") and k.endswith("_max_s") and k != "stage_comm_wait_max_s")
            best[label] = min(best[label], s)
            if label == "pushed":
                m = re.search(r"(\d+) cap points?", text)
                caps = int(m.group(1)) if m else 0
    rows.append({"set": name, "points": len(pts), "cap_points": caps, "unpushed_s": f"{best['unpushed']:.3f}",
                 "pushed_s": f"{best['pushed']:.3f}", "ratio": f"{best['pushed'] / best['unpushed']:.3f}"})
    print(rows[-1], flush=True)
with open(out, "w", newline="") as fh:
    w = csv.DictWriter(fh, fieldnames=list(rows[0]))
    w.writeheader()
    w.writerows(rows)
ratios = sorted(float(r["ratio"]) for r in rows)
print(f"ratio pushed / unpushed: median {ratios[len(ratios) // 2]:.3f}, range {ratios[0]:.3f}-{ratios[-1]:.3f}")
