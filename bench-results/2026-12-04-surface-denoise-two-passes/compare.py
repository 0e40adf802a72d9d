"""Compares an experiment folder (SAMPLING/raw.csv, default rows) set by set with the default of
bench-results/2026-12-04-surface-default-neighbours and its peers, on the quality targets.
Run from the repository root: python3 bench-results/2026-12-04-surface-denoise-two-passes/compare.py FOLDER"""
import os, sys
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "jobs", "bench"))
from surface_robust import load
from surface_report import targets, PEERS
B = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "2026-12-04-surface-default-neighbours")
root = sys.argv[1]
tot = [0, 0, 0]
for s in sorted(os.listdir(root)):
    if not os.path.exists(os.path.join(root, s, "raw.csv")):
        continue
    exp = load(os.path.join(root, s))
    base = load(os.path.join(B, s))
    peers = load(open(os.path.join(B, s, "baseline.txt")).read().strip())
    for name, by in exp.items():
        e = by.get("default")
        b = base[name].get("default") or base[name].get("neighbours")
        pe = {m: r for m, r in peers[name].items() if m in PEERS}
        def ok(row):
            bm = dict(pe); bm["default"] = row
            r = row
            ch = targets(name, r["variant"], int(r["points"]), bm, "default", time_key="-")
            return all(c[1] for c in ch), [f"{c[0]} {c[2]}" for c in ch if not c[1]]
        (ob, fb), (oe, fe) = ok(b), ok(e)
        tot[0] += 1; tot[1] += ob; tot[2] += oe
        f = lambda r: f"{float(r['t2m_rms_pct']):.3f}/{float(r['m2t_rms_pct']):.3f}/{float(r['far2_pct']):.2f}"
        bp = "/".join(f"{min(float(p[k]) for p in pe.values() if p['status']=='ok'):.3f}" for k in ("t2m_rms_pct","m2t_rms_pct"))
        mark = "" if ob == oe else (" GAINED" if oe else " LOST")
        print(f"{s:8} {name:22} base {f(b)} {'ok ' if ob else 'MISS'}  exp {f(e)} {'ok ' if oe else 'MISS'}  peer {bp}{mark}")
print(f"sets {tot[0]}: base met {tot[1]}, exp met {tot[2]}")
