"""Deterministic bunny point sets of a given size for the benchmarks: evenly spaced vertices of
tests/data/bunny10k.obj while N <= 5051, beyond that vertices followed by face centroids (up to
15050 points). Usage: python3 points.py N OUT.xyz"""
import sys

import numpy as np

ROOT = __file__.rsplit("/jobs/", 1)[0]


def bunny_pool():
    v, f = [], []
    for line in open(f"{ROOT}/tests/data/bunny10k.obj"):
        t = line.split()
        if not t:
            continue
        if t[0] == "v":
            v.append([float(x) for x in t[1:4]])
        elif t[0] == "f":
            idx = [int(x.split("/")[0]) for x in t[1:]]
            f.append([i - 1 if i > 0 else len(v) + i for i in idx])
    v = np.array(v)
    return v, np.array([v[i].mean(axis=0) for i in f])


def subset(n):
    v, c = bunny_pool()
    pool = v if n <= len(v) else np.vstack([v, c])
    if n > len(pool):
        sys.exit(f"at most {len(pool)} bunny points available, {n} requested")
    idx = np.floor(np.arange(n) * (len(pool) / n)).astype(int)
    return pool[idx]


if __name__ == "__main__":
    np.savetxt(sys.argv[2], subset(int(sys.argv[1])), fmt="%.17g")
