"""Slices of jobs/bench/surface.py: three axis planes through the centre of the evaluation grid, or
through the grid node nearest a given point (the removed region of an open scan).

Each panel shows, in the plane, the field f of the first volspline method of the set (read from
its VTKHDF volume with h5py; drawn as tanh(f / s), red where f > 0 inside) as the background, the zero contour of every
volspline method's own volume, the cut of Poisson's mesh by the plane, the cut of the true mesh
(black, thick), and the data points within 0.75 % of the diagonal of the plane (grey dots)."""
import h5py
import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.collections import LineCollection  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402

COLOURS = {"default": "tab:blue", "carrier": "tab:orange", "offsurface": "tab:purple", "poisson": "tab:green",
           "trimmed": "tab:cyan", "choice": "tab:red", "wide": "tab:olive"}
AXES = "xyz"


def read_volume(path):
    """(f indexed [x, y, z], origin, spacing) of a VTKHDF image volume written by volspline."""
    with h5py.File(path, "r") as h:
        g = h["VTKHDF"]
        origin = np.asarray(g.attrs["Origin"], dtype=float)
        spacing = np.asarray(g.attrs["Spacing"], dtype=float)
        f = np.asarray(g["PointData"]["f"])  # stored z slowest: (nz, ny, nx)
    return f.transpose(2, 1, 0), origin, spacing


def plane_of(f, origin, spacing, axis, index):
    """The nodes of the plane `index` across `axis`: (values [u, v], u coordinates, v coordinates)."""
    keep = [a for a in range(3) if a != axis]
    vals = np.take(f, index, axis=axis)
    coords = [origin[a] + spacing[a] * np.arange(f.shape[a]) for a in keep]
    return vals, coords[0], coords[1]


def mesh_cut(v, f, axis, c):
    """Segments (m, 2, 2) where the plane x[axis] = c cuts the triangles (v, f), in the other axes."""
    keep = [a for a in range(3) if a != axis]
    s = v[:, axis] - c
    pos = s > 0
    cross, ends = [], []
    for i, j in ((0, 1), (1, 2), (2, 0)):
        a, b = f[:, i], f[:, j]
        x = pos[a] != pos[b]
        t = np.where(x, s[a] / np.where(x, s[a] - s[b], 1.0), 0.0)
        cross.append(x)
        ends.append(v[a] + t[:, None] * (v[b] - v[a]))
    cross, ends = np.stack(cross, axis=1), np.stack(ends, axis=1)
    two = cross.sum(axis=1) == 2
    # a cut triangle has exactly two crossed edges: their points, in order, are one segment
    return ends[two][cross[two]].reshape(-1, 2, 3)[:, :, keep]


def slices(png, name, pts, tv, tf, diag, results, focus=None):
    """Writes the figure of one set; results maps a method to (kind, prefix, (verts, faces)); the
    planes go through the grid node nearest `focus`, or through the centre of the grid."""
    vols = {m: read_volume(prefix + ".hdf") for m, (kind, prefix, _) in results.items() if kind == "volspline"}
    if vols:
        base = next(iter(vols))
        f0, origin, spacing = vols[base]
        shape = np.array(f0.shape)
    else:
        base, lo, hi = None, tv.min(axis=0), tv.max(axis=0)
        spacing = (hi - lo) / 99
        origin, shape = lo, np.full(3, 100)
    fig, axes = plt.subplots(1, 3, figsize=(16, 5.6))
    for axis, ax in enumerate(axes):
        index = int(shape[axis] // 2)
        if focus is not None:
            index = int(np.clip(np.rint((focus[axis] - origin[axis]) / spacing[axis]), 0, shape[axis] - 1))
        c = origin[axis] + spacing[axis] * index
        keep = [a for a in range(3) if a != axis]
        if base is not None:
            vals, u, w = plane_of(f0, origin, spacing, axis, index)
            # tanh(f / s) with s the lower quartile of |f|: the sign shows, far values saturate
            lim = np.percentile(np.abs(vals), 25) or 1.0
            ax.imshow(np.tanh(vals / lim).T, origin="lower", extent=(u[0], u[-1], w[0], w[-1]), cmap="RdBu_r",
                      vmin=-1, vmax=1, alpha=0.35, interpolation="bilinear")
        handles = []
        for m, (kind, _, rec) in results.items():
            col = COLOURS.get(m, "tab:gray")
            if kind == "volspline":
                f, o, sp = vols[m]
                vals, u, w = plane_of(f, o, sp, axis, index)
                if vals.min() < 0 < vals.max():
                    ax.contour(u, w, vals.T, levels=[0.0], colors=[col], linewidths=1.3)
            else:
                ax.add_collection(LineCollection(mesh_cut(rec[0], rec[1], axis, c), colors=col, linewidths=1.3))
            handles.append(Line2D([], [], color=col, linewidth=1.3, label=m))
        ax.add_collection(LineCollection(mesh_cut(tv, tf, axis, c), colors="black", linewidths=2.2, alpha=0.8))
        handles.append(Line2D([], [], color="black", linewidth=2.2, label="true surface"))
        near = np.abs(pts[:, axis] - c) < 0.0075 * diag
        ax.plot(pts[near, keep[0]], pts[near, keep[1]], ".", color="0.35", markersize=3)
        handles.append(Line2D([], [], color="0.35", marker=".", linestyle="", label="data near the plane"))
        lo = origin[keep] if base is not None else tv.min(axis=0)[keep]
        hi = (origin + spacing * (shape - 1))[keep] if base is not None else tv.max(axis=0)[keep]
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        ax.set_aspect("equal")
        ax.set_xlabel(AXES[keep[0]])
        ax.set_ylabel(AXES[keep[1]])
        ax.set_title(f"{AXES[axis]} = {c:.4g}")
    axes[-1].legend(handles=handles, loc="upper right", fontsize=8, framealpha=0.85)
    back = f"; background: f of {base} (red inside)" if base else ""
    where = "through the removed region" if focus is not None else "through the centre"
    fig.suptitle(f"{name}: {len(pts)} points, zero sets in three planes {where}{back}")
    fig.tight_layout()
    fig.savefig(png, dpi=90)
    plt.close(fig)
