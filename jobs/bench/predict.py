"""Time guard of jobs/scale-csrbf: the predicted wall time of a run of N points from the runs of
the same implementation and rank count already in raw.csv. The fit is extrapolated as
fit_last (N / N_last)^e, e the least-squares slope of log fit_s against log N over those runs
(at least 1; 1.5 while there is only one), and the rest of the run (wall_s - fit_s: evaluation,
surface, files) linearly in N. Prints 0 when there is no such run.
Usage: python3 predict.py RAW.csv IMPL RANKS N"""
import csv
import math
import sys

raw, impl, ranks, n = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
done = sorted((int(r["points"]), float(r["fit_s"]), float(r["wall_s"])) for r in csv.DictReader(open(raw))
              if r["impl"] == impl and r["ranks"] == ranks and r["fit_s"] and r["wall_s"])
if not done:
    print(0)
    sys.exit(0)
e = 1.5
if len({p for p, _, _ in done}) > 1:
    x = [math.log(p) for p, _, _ in done]
    y = [math.log(max(t, 1e-3)) for _, t, _ in done]
    mx, my = sum(x) / len(x), sum(y) / len(y)
    e = max(1.0, sum((a - mx) * (b - my) for a, b in zip(x, y)) / sum((a - mx) ** 2 for a in x))
p, fit, wall = done[-1]
print(f"{fit * (n / p) ** e + max(wall - fit, 0) * n / p:.1f}")
