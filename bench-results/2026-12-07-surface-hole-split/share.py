"""The share of truth -> mesh (squared) that lies within an open set's removed ball, per variant and
method: with T, H and R the rms over all truth samples, those within the ball and the others, the
fraction of samples within it is f = (T^2 - R^2) / (H^2 - R^2) and its share of the squared
distance f H^2 / T^2. Medians (and ranges) over the sets of SWEEP/S/raw.csv.

  python3 bench-results/2026-12-07-surface-hole-split/share.py SWEEP
(from the repository root)"""
import csv,os,sys,statistics as st
d=sys.argv[1]
out={}
for s in sorted(os.listdir(d)):
    p=f"{d}/{s}/raw.csv"
    if not os.path.exists(p): continue
    for r in csv.DictReader(open(p)):
        if r["status"]!="ok" or not r["t2m_hole_rms_pct"]: continue
        T,H,R=(float(r[k]) for k in ("t2m_rms_pct","t2m_hole_rms_pct","t2m_rest_rms_pct"))
        f=(T*T-R*R)/(H*H-R*R)
        out.setdefault((r["variant"],r["method"]),[]).append((f,f*H*H/(T*T)))
for k,v in sorted(out.items()):
    print(k, len(v), "truth in ball %.3f" % st.median(x[0] for x in v), "share of t2m^2 in ball %.2f (%.2f-%.2f)" % (st.median(x[1] for x in v), min(x[1] for x in v), max(x[1] for x in v)))
