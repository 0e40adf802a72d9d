"""The peer of jobs/scale-csrbf: ferreus_rbf (fast multipole, iterative solver with a domain
decomposition preconditioner) fitting the same spline as volspline's dense method, the linear
kernel |r| with a linear drift, to the carrier values of the same points (the ball carrier of
volspline's `ball`: centre the middle of the bounding box, radius half its diagonal,
f_c(x) = R^2 - |x - c|^2), then evaluating it on a grid of GRID nodes along the longest side of
the box grown by 5 % of that side on every side (volspline's --margin default), cubic cells, or
on NX x NY x NZ nodes spanning that box, as volspline's --grid N or NX,NY,NZ places them.

  python3 ferreus.py POINTS.xyz GRID|NX,NY,NZ [F.hdf]

With F.hdf (a volspline fit of the same points with the same GRID and the default ball carrier),
also prints max_rel_diff: the largest difference between ferreus_rbf's spline and volspline's
U = f_c - f on the grid, relative to max |U|; both are the same interpolant.

Threads: ferreus_rbf runs on rayon; set RAYON_NUM_THREADS. Prints `key,value` lines: points,
fit_s, evaluate_s, grid_nodes, max_at_points (largest |s(x_i) - f_c(x_i)| relative to
max |f_c(x_i)|), peak_rss_bytes (of this process), version."""
import resource
import sys
import time
from importlib.metadata import version

import numpy as np
from ferreus_rbf import RBFInterpolator
from ferreus_rbf.interpolant_config import Drift, InterpolantSettings, RBFKernelType


def main():
    path, grid = sys.argv[1], sys.argv[2]
    hdf = sys.argv[3] if len(sys.argv) > 3 else None
    pts = np.fromfile(path, sep=" ").reshape(-1, 3)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    centre, radius = 0.5 * (lo + hi), 0.5 * np.linalg.norm(hi - lo)
    values = radius**2 - ((pts - centre) ** 2).sum(axis=1)

    t = time.perf_counter()
    settings = InterpolantSettings(RBFKernelType.Linear, drift=Drift.Linear)
    rbf = RBFInterpolator(pts, values, settings)
    fit_s = time.perf_counter() - t

    # volspline's grid: GRID nodes on the longest side, cubic cells, the other sides rounded up
    # to whole cells and centred on the box; or NX, NY, NZ nodes spanning the box. The upper
    # bounds lie half a cell beyond the last node, so that ferreus_rbf counts the same nodes.
    margin = 0.05 * (hi - lo).max()
    glo, ghi = lo - margin, hi + margin
    ext = ghi - glo
    if "," in grid:
        n = np.array([int(x) for x in grid.split(",")])
        ext = np.where(ext > 0, ext, ext.max() * 1e-3)
        glo = 0.5 * (glo + ghi) - 0.5 * ext
        h = ext / (n - 1)
        cells = n - 1
    else:
        h = np.full(3, ext.max() / (int(grid) - 1))
        cells = np.maximum(np.ceil(ext / h - 1e-9), 1)
        glo = glo - 0.5 * (cells * h - ext)
    ghi = glo + (cells + 0.5) * h
    t = time.perf_counter()
    f = rbf.evaluate_grid([*glo, *ghi], [*h])
    evaluate_s = time.perf_counter() - t

    at = rbf.evaluate_at_source(add_nugget=True)
    rel = np.abs(at.ravel() - values).max() / np.abs(values).max()
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    print(f"points,{len(pts)}\nfit_s,{fit_s:.6f}\nevaluate_s,{evaluate_s:.6f}\ngrid_nodes,{f.size}")
    print(f"grid_shape,{'x'.join(str(n) for n in f.shape)}\nmax_at_points,{rel:.3e}\npeak_rss_bytes,{rss}")
    print(f"version,{version('ferreus-rbf')}")
    if hdf:
        import vtk
        from vtk.util.numpy_support import vtk_to_numpy

        r = vtk.vtkHDFReader()
        r.SetFileName(hdf)
        r.Update()
        img = r.GetOutput()
        nx, ny, nz = img.GetDimensions()
        if (nx, ny, nz) != f.shape:
            sys.exit(f"ferreus: grid {f.shape} differs from {hdf}'s {(nx, ny, nz)}")
        o = np.array(img.GetOrigin())
        if np.abs(o - glo).max() > 1e-9 * np.abs(ext).max():
            sys.exit(f"ferreus: grid origin {glo} differs from {hdf}'s {o}")
        fv = vtk_to_numpy(img.GetPointData().GetArray("f")).reshape(nz, ny, nx).transpose(2, 1, 0)
        k, j, i = np.meshgrid(np.arange(nz), np.arange(ny), np.arange(nx), indexing="ij")
        nodes = glo + np.stack([i, j, k], axis=-1).transpose(2, 1, 0, 3) * h
        u = radius**2 - ((nodes - centre) ** 2).sum(axis=-1) - fv
        print(f"max_rel_diff,{np.abs(u - f).max() / np.abs(u).max():.3e}")


if __name__ == "__main__":
    main()
