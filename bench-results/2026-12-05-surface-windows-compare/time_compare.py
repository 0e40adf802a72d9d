import csv, glob, statistics, sys
# Fit time of the default over the carrier method per set, run TAG (argv[1]) against the runs BASE (argv[2],
# outside-time by default); run from the repository root:
#   python3 bench-results/2026-12-05-surface-windows-compare/time_compare.py windows-time [BASE]
tag = sys.argv[1]  # e.g. windows-time
base = sys.argv[2] if len(sys.argv) > 2 else 'outside-time'
samps = [f"seed{s}" for s in range(1, 13)] + ["strided"]
rat, old, over, over_old, sp, spc = [], [], [], [], [], []
per = {}
for s in samps:
    a = f"bench-results/2026-12-05-surface-{s}-{tag}/raw.csv"
    b = f"bench-results/2026-12-05-surface-{s}-{base}/raw.csv"
    try:
        A = {(r['set'], r['method']): r for r in csv.DictReader(open(a))}
    except FileNotFoundError:
        continue
    B = {(r['set'], r['method']): r for r in csv.DictReader(open(b))}
    rs = []
    for (st, m), r in A.items():
        if m != 'default' or (st, 'carrier') not in A:
            continue
        d, c = float(r['fit_s']), float(A[(st, 'carrier')]['fit_s'])
        d0, c0 = float(B[(st, 'default')]['fit_s']), float(B[(st, 'carrier')]['fit_s'])
        rat.append(d / c); old.append(d0 / c0); sp.append(d / d0); spc.append(c / c0); rs.append(d / c)
        if d / c > 3: over.append((s, st, round(d / c, 2), round(d0 / c0, 2)))
        if d0 / c0 > 3: over_old.append((s, st, round(d0 / c0, 2), round(d / c, 2)))
    per[s] = (min(rs), max(rs), len(rs))
for s, v in per.items(): print(s, f"{v[0]:.2f}-{v[1]:.2f}x ({v[2]} sets)")
print(f"sets {len(rat)}: new ratio {min(rat):.2f}-{max(rat):.2f} median {statistics.median(rat):.2f}, over 3x {len(over)}; "
      f"old {min(old):.2f}-{max(old):.2f} median {statistics.median(old):.2f}, over 3x {len(over_old)}")
print(f"default fit new/old median {statistics.median(sp):.3f} ({min(sp):.2f}-{max(sp):.2f}); carrier new/old median {statistics.median(spc):.3f} ({min(spc):.2f}-{max(spc):.2f})")
print("over 3x now:", over)
print("over 3x before:", over_old)
