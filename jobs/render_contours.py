#!/usr/bin/env python3
"""Helpers of jobs/contours_figure.sh.

block-sections OUT.txt   writes the contour file of the bent and twisted block (the case of
                         Figure 4 of Savchenko et al. 1995):
                         50 sections of a 2 x 1 rectangle along a quarter circle of radius 4, the
                         section turning by 90 degrees about the path (the same case as
                         tests/contours.rs).
render PNG (PLY CONTOURS UP TITLE)...   draws each mesh shaded, with its contours as thin lines;
                         UP (x, y or z) is the axis drawn upwards.
"""
import math
import sys

import numpy as np


def block_frame(s):
    phi = psi = 0.5 * math.pi * s
    centre = np.array([4.0 * (1 - math.cos(phi)), 0.0, 4.0 * math.sin(phi)])
    ry = np.array([[math.cos(phi), 0, math.sin(phi)], [0, 1, 0], [-math.sin(phi), 0, math.cos(phi)]])
    rz = np.array([[math.cos(psi), -math.sin(psi), 0], [math.sin(psi), math.cos(psi), 0], [0, 0, 1]])
    return centre, ry @ rz


def rectangle(per_side=10, a=1.0, b=0.5):
    corners = [(-a, -b), (a, -b), (a, b), (-a, b)]
    pts = []
    for c in range(4):
        p, q = corners[c], corners[(c + 1) % 4]
        for k in range(per_side):
            t = k / per_side
            pts.append((p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])))
    return pts


def block_sections(path, count=50):
    with open(path, "w") as f:
        f.write("# bent and twisted block: 50 non-parallel sections of a 2 x 1 rectangle\n")
        for i in range(count):
            o, m = block_frame(i / (count - 1))
            u, v = m[:, 0], m[:, 1]
            f.write("slice plane %.17g %.17g %.17g  %.17g %.17g %.17g  %.17g %.17g %.17g\ncontour\n" % (*o, *u, *v))
            for a, b in rectangle():
                f.write("%.17g %.17g\n" % (a, b))


def read_ply(path):
    data = open(path, "rb").read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode()
    nv = int(header.split("element vertex ")[1].split()[0])
    nf = int(header.split("element face ")[1].split()[0])
    v = np.frombuffer(data[end : end + 24 * nv], dtype="<f8").reshape(nv, 3)
    f = np.frombuffer(data[end + 24 * nv :], dtype=np.dtype([("n", "u1"), ("i", "<i4", 3)]), count=nf)["i"]
    return v, f


def read_contours(path):
    """World-space polylines of a contour file written with `slice plane` or `slice z` lines."""
    lines, frame = [], None
    for raw in open(path):
        t = raw.split("#")[0].replace(",", " ").split()
        if not t:
            continue
        if t[0] == "slice":
            x = [float(s) for s in t[2:]]
            if t[1] == "z":
                frame = (np.array([0, 0, x[0]]), np.array([1.0, 0, 0]), np.array([0, 1.0, 0]))
            else:
                frame = (np.array(x[0:3]), np.array(x[3:6]), np.array(x[6:9]))
        elif t[0] == "contour":
            lines.append([])
        else:
            o, u, v = frame
            lines[-1].append(o + float(t[0]) * u + float(t[1]) * v)
    return [np.array(l + l[:1]) for l in lines]


def render(png, panels):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    fig = plt.figure(figsize=(5 * len(panels), 5))
    light = np.array([0.4, 0.8, 0.6]) / np.linalg.norm([0.4, 0.8, 0.6])
    for k, (ply, contours, up, title) in enumerate(panels):
        # a right-handed permutation that puts UP last (matplotlib draws z upwards)
        perm = {"x": [1, 2, 0], "y": [2, 0, 1], "z": [0, 1, 2]}[up]
        v, f = read_ply(ply)
        v = v[:, perm]
        ax = fig.add_subplot(1, len(panels), k + 1, projection="3d")
        tri = v[f]
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        n /= np.linalg.norm(n, axis=1, keepdims=True) + 1e-300
        shade = 0.35 + 0.65 * np.clip(n @ light, 0, 1)
        colours = np.outer(shade, [0.85, 0.62, 0.35])
        ax.add_collection3d(Poly3DCollection(tri, facecolors=colours, edgecolors="none", alpha=0.8))
        for line in read_contours(contours):
            line = line[:, perm]
            ax.plot(line[:, 0], line[:, 1], line[:, 2], color="navy", linewidth=0.35, alpha=0.7)
        lo, hi = v.min(0), v.max(0)
        c, r = 0.5 * (lo + hi), 0.5 * (hi - lo).max()
        ax.set_xlim(c[0] - r, c[0] + r)
        ax.set_ylim(c[1] - r, c[1] + r)
        ax.set_zlim(c[2] - r, c[2] + r)
        ax.set_box_aspect((1, 1, 1))
        ax.view_init(elev=20, azim=-60)
        ax.set_axis_off()
        ax.set_title(title)
    fig.tight_layout()
    fig.savefig(png, dpi=100, bbox_inches="tight")


if __name__ == "__main__":
    if sys.argv[1] == "block-sections":
        block_sections(sys.argv[2])
    elif sys.argv[1] == "render":
        args = sys.argv[3:]
        render(sys.argv[2], [tuple(args[i : i + 4]) for i in range(0, len(args), 4)])
    else:
        sys.exit(__doc__)
