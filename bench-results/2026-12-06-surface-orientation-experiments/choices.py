"""choices.csv: per set of the surface benchmark, the default's figures without the side vote
(off), with it (side, `--orient-side on`) and with the energy flips (energy, `--orient-energy
on`), each with the unsupported crossings its fit leaves (after step 8 where it ran, else after
step 7), from quality-only runs whose --timings CSVs were kept per set:

    python3 choices.py OFF SIDE ENERGY > choices.csv

OFF, SIDE, ENERGY: folders with seedS/raw.csv and kv-seedS/SET.csv (seeds 1-14, strided)."""
import csv, glob, sys

def kv(path):
    try:
        return dict(csv.reader(open(path)))
    except OSError:
        return {}

def left(d):
    for k in ("outside_unsupported_after", "turns_unsupported_after"):
        if d.get(k):
            return d[k]
    return ""

def quality(root):
    out = {}
    for f in glob.glob(root + "/*/raw.csv"):
        seed = f.split("/")[-2]
        for r in csv.DictReader(open(f)):
            if r["method"] == "default":
                out[(seed, r["set"])] = (r["t2m_rms_pct"], r["m2t_rms_pct"], r["far2_pct"])
    return out

roots = dict(zip(("off", "side", "energy"), sys.argv[1:4]))
q = {k: quality(v) for k, v in roots.items()}
w = csv.writer(sys.stdout)
w.writerow(["sampling", "set"] + [f"{k}_{c}" for k in roots for c in ("t2m", "m2t", "far2", "unsupported")])
for key in sorted(q["off"]):
    row = list(key)
    for k, root in roots.items():
        row += list(q[k].get(key, ("", "", ""))) + [left(kv(f"{root}/kv-{key[0]}/{key[1]}.csv"))]
    w.writerow(row)
