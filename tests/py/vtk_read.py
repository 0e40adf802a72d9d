"""Reads a volspline VTKHDF file with VTK's own vtkHDFReader and prints what VTK sees, one item per
line: class, dims, origin, spacing, active scalars, the names of the point arrays, then the point array `f` in VTK point-id order
(i + nx*(j + ny*k)), 17 significant digits."""
import sys

import vtk
from vtk.util.numpy_support import vtk_to_numpy

path = sys.argv[1]
reader = vtk.vtkHDFReader()
if not reader.CanReadFile(path):
    sys.exit(f"vtkHDFReader cannot read {path}")
reader.SetFileName(path)
reader.Update()
img = reader.GetOutput()
pd = img.GetPointData()
arr = pd.GetArray("f")
if arr is None:
    sys.exit(f"{path}: VTK finds no point array 'f'")
print("version", vtk.vtkVersion.GetVTKVersion())
print("class", img.GetClassName())
print("dims", *img.GetDimensions())
print("origin", *(repr(v) for v in img.GetOrigin()))
print("spacing", *(repr(v) for v in img.GetSpacing()))
print("scalars", pd.GetScalars().GetName() if pd.GetScalars() else "none")
print("arrays", *sorted(pd.GetArrayName(i) for i in range(pd.GetNumberOfArrays())))
print("f", *(repr(float(v)) for v in vtk_to_numpy(arr)))
