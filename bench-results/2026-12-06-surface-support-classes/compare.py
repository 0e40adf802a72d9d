"""The default's fit time against the carrier's, set by set, before (the side vote's try timed,
2026-12-06-surface-SAMPLING-side-try-time) and after the data's support was worked out once at
the lattice's nodes (2026-12-06-surface-SAMPLING-support-classes-time), with a check that every
quality figure is the same in both.

  python3 bench-results/2026-12-06-surface-support-classes/compare.py   (from the repository root)"""
import csv
import statistics as st

B = "bench-results/2026-12-06-surface-{}-{}-time/raw.csv"
QUALITY = ["t2m_rms_pct", "m2t_rms_pct", "far2_pct", "components", "vertices", "triangles"]
allratio, over = [], []
for s in ["seed6", "seed10", "seed12", "strided"]:
    load = lambda tag: {(r["set"], r["method"]): r for r in csv.DictReader(open(B.format(s, tag)))}
    before, after = load("side-try"), load("support-classes")
    same = sum(all(before[k][q] == r[q] for q in QUALITY) for k, r in after.items())
    print(f"{s}: {len(after)} runs, quality figures the same in {same}")
    own = []
    for (name, m), r in after.items():
        if m != "default":
            continue
        t = lambda d, meth: float(d[(name, meth)]["fit_s"])
        ra, rb = t(before, "default") / t(before, "carrier"), t(after, "default") / t(after, "carrier")
        own.append(t(after, "default") / t(before, "default"))
        allratio.append(rb)
        print(f"  {name:22} default {t(before, 'default'):.3f} -> {t(after, 'default'):.3f} s, "
              f"carrier {t(before, 'carrier'):.3f} -> {t(after, 'carrier'):.3f} s, ratio {ra:.2f} -> {rb:.2f}")
        if rb > 3:
            over.append(f"{s} {name} {rb:.2f}")
    print(f"  default's time after / before, median per set {st.median(own):.3f} ({min(own):.3f}-{max(own):.3f})")
print(f"{len(allratio)} sets: ratio {min(allratio):.2f}-{max(allratio):.2f}, median {st.median(allratio):.2f}; "
      f"over 3x: {', '.join(over) or 'none'}")
