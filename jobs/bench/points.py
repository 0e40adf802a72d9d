"""Deterministic bunny point sets of a given size for the benchmarks: evenly spaced vertices of
tests/data/bunny10k.obj while N <= 5051, beyond that vertices followed by face centroids (up to
15050 points). Usage: python3 points.py N OUT.xyz"""
import sys

import numpy as np

ROOT = __file__.rsplit("/jobs/", 1)[0]


def bunny_pool():
    sys.path.insert(0, __file__.rsplit("/", 1)[0])
    from sample_surface import read_obj

    v, f = read_obj(f"{ROOT}/tests/data/bunny10k.obj")
    return v, v[f].mean(axis=1)


def subset(n):
    v, c = bunny_pool()
    pool = v if n <= len(v) else np.vstack([v, c])
    if n > len(pool):
        sys.exit(f"at most {len(pool)} bunny points available, {n} requested")
    idx = np.floor(np.arange(n) * (len(pool) / n)).astype(int)
    return pool[idx]


if __name__ == "__main__":
    np.savetxt(sys.argv[2], subset(int(sys.argv[1])), fmt="%.17g")
