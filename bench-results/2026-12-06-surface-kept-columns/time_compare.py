"""Default and carrier fit times of a timed run (AFTER raw.csv) against earlier runs (BEFORE raw.csv ...), set by
set, with whether every quality figure of the default is the same.

  python3 bench-results/2026-12-06-surface-kept-columns/time_compare.py AFTER/raw.csv BEFORE/raw.csv ..."""
import csv, sys, statistics
def load(p):
    d={}
    for r in csv.DictReader(open(p)):
        d.setdefault(r['set'],{})[r['method']]=r
    return d
new=load(sys.argv[1])
for ref in sys.argv[2:]:
    old=load(ref); rs=[]; over=[]
    for s in new:
        if s not in old: continue
        a=float(old[s]['default']['fit_s']); b=float(new[s]['default']['fit_s'])
        ca=float(old[s]['carrier']['fit_s']); cb=float(new[s]['carrier']['fit_s'])
        rs.append(b/a)
        q=[old[s]['default'][k]==new[s]['default'][k] for k in ('t2m_rms_pct','m2t_rms_pct','far2_pct','components','vertices','triangles')]
        print(f"{s:22} default {a:.3f}->{b:.3f} ({b/a:.3f}) carrier {ca:.3f}->{cb:.3f} ratio {a/ca:.2f}->{b/cb:.2f} quality {'same' if all(q) else 'DIFF'}")
    print(ref, 'median after/before', round(statistics.median(rs),3))
    r=[float(new[s]['default']['fit_s'])/float(new[s]['carrier']['fit_s']) for s in new]
    print('after: ratio range', round(min(r),2), round(max(r),2), 'median', round(statistics.median(r),2))
