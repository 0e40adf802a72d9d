"""Every quality figure of the default in a quality-only sweep (SWEEP/SAMPLING/raw.csv, by default this
folder's quality/) against the side vote's time sweep of each sampling, set by set.

  python3 bench-results/2026-12-06-surface-kept-columns/compare.py [SWEEP]   (from the repository root)"""
import csv, sys, os
ref = {"1": "seed1-side-try-time", "2": "seed2-side-try-time", "5": "seed5-side-try-time",
       "11": "seed11-side-try-time", "13": "seed13-held-out-side-try-time",
       "14": "seed14-held-out-side-try-time", "strided": "strided-side-try-time",
       **{str(k): f"seed{k}-side-try-time" for k in (3, 4, 6, 7, 8, 9, 10, 12)}}
sweep = sys.argv[1] if len(sys.argv) > 1 else "bench-results/2026-12-06-surface-kept-columns/quality"
keys = ["t2m_rms_pct", "m2t_rms_pct", "far2_pct", "components", "vertices", "triangles"]
same = diff = 0; sa = sb = 0.0
for s, r in ref.items():
    p = f"{sweep}/{s}/raw.csv"
    if not os.path.exists(p): continue
    A = {x["set"]: x for x in csv.DictReader(open(f"bench-results/2026-12-06-surface-{r}/raw.csv")) if x["method"] == "default"}
    for b in csv.DictReader(open(p)):
        if b["method"] != "default": continue
        a = A[b["set"]]
        fa = [a[k] for k in keys]; fb = [b[k] for k in keys]
        sa += float(a["t2m_rms_pct"]) + float(a["m2t_rms_pct"]); sb += float(b["t2m_rms_pct"]) + float(b["m2t_rms_pct"])
        if fa == fb: same += 1
        else:
            diff += 1
            print(f"{s:8} {b['set']:22} {'/'.join(fa[:3])} -> {'/'.join(fb[:3])}  comp {fa[3]}->{fb[3]} verts {fa[4]}->{fb[4]}")
print(f"same {same}, different {diff}; sum of both distances {sa:.3f} -> {sb:.3f}")
