"""scipy side of jobs/bench-eval.
  python3 eval.py carrier POINTS.xyz            -> the ball carrier spec volspline's `ball` picks
  python3 eval.py compare POINTS.xyz SPEC F.hdf THREADS
      -> reads volspline's grid with VTK, evaluates scipy's RBFInterpolator(kernel='linear',
         degree=1) interpolating the same carrier values at the same nodes, prints a raw.csv row
         with its time (the best of three) and the largest difference of the spline U relative to max |U|."""
import sys
import time

import numpy as np

pts = np.loadtxt(sys.argv[2])
lo, hi = pts.min(axis=0), pts.max(axis=0)
if sys.argv[1] == "carrier":
    c = 0.5 * (lo + hi)
    print("ball:" + ",".join(repr(float(v)) for v in [*c, 0.5 * np.linalg.norm(hi - lo)]))
    sys.exit(0)

import vtk  # noqa: E402
from scipy.interpolate import RBFInterpolator  # noqa: E402
from vtk.util.numpy_support import vtk_to_numpy  # noqa: E402

spec, hdf, threads = sys.argv[3], sys.argv[4], sys.argv[5]
v = [float(t) for t in spec.split(":")[1].split(",")]
centre, radius = np.array(v[:3]), v[3]
carrier = lambda p: radius**2 - ((p - centre) ** 2).sum(axis=1)  # noqa: E731
r = vtk.vtkHDFReader()
r.SetFileName(hdf)
r.Update()
img = r.GetOutput()
nx, ny, nz = img.GetDimensions()
o, h = np.array(img.GetOrigin()), np.array(img.GetSpacing())
f = vtk_to_numpy(img.GetPointData().GetArray("f"))
k, j, i = np.meshgrid(np.arange(nz), np.arange(ny), np.arange(nx), indexing="ij")
nodes = o + np.stack([i.ravel(), j.ravel(), k.ravel()], axis=1) * h
u_ours = carrier(nodes) - f
interp = RBFInterpolator(pts, carrier(pts), kernel="linear", degree=1)
secs = float("inf")
for _ in range(3):  # the best of three, as volspline's side
    t = time.perf_counter()
    u_scipy = interp(nodes)
    secs = min(secs, time.perf_counter() - t)
diff = np.abs(u_ours - u_scipy).max() / np.abs(u_scipy).max()
print(f"scipy,{len(pts)},{len(nodes)},{threads},{secs:.6f},{float(len(nodes)) * len(pts):.6e},{diff:.3e}")
