//! VTKHDF ImageData output, written by every rank into one file through MPI-IO, each rank its own
//! z-slab. All metadata calls are collective: every rank makes them with the same values.
//!
//! VTKHDF is VTK's HDF5-based format; VTK and ParaView read an image (a uniform grid) from this
//! layout:
//! - a root group `/VTKHDF` with the attributes `Version` (two integers, major and minor: 1, 0),
//!   `Type` (the fixed-length ASCII string `ImageData`), `WholeExtent` (six integers: the first
//!   and last node index along x, y and z, here 0..nx-1, 0..ny-1, 0..nz-1), `Origin` and
//!   `Spacing` (three doubles each: the position of node (0, 0, 0) and the node distance along
//!   each axis) and `Direction` (nine doubles, the axes as a row-major 3 x 3 matrix; the
//!   identity here);
//! - a group `/VTKHDF/PointData` holding one dataset per array of node values. HDF5 lists
//!   dimensions slowest first, so a scalar array over the grid has shape [nz, ny, nx]: x varies
//!   fastest, the node order of [`Grid`]. Each rank writes the hyperslab of its layers
//!   k0..k0+layers. The dataset also carries the string attribute `Attribute` = `Scalars`.
//!
//! Only point data is written; there is no cell or field data.

use std::path::Path;

use hdf5::types::FixedAscii;
use ndarray::{s, ArrayView3};

use crate::error::{Error, Result};
use crate::grid::Grid;
use crate::par::Comm;

/// Writes `values` (this rank's layers k0..k0+layers of `grid`, x fastest) as the point array
/// `name` of a VTKHDF ImageData file at `path`. Collective.
pub fn write_image(
    comm: &dyn Comm,
    path: &Path,
    grid: &Grid,
    k0: usize,
    layers: usize,
    name: &str,
    values: &[f64],
) -> Result<()> {
    let h5 = |e: hdf5::Error| Error::hdf5(path, e);
    let [nx, ny, nz] = grid.dims;
    assert_eq!(values.len(), nx * ny * layers);
    let file = match comm.raw() {
        Some(world) => hdf5::File::with_options().with_fapl(|p| p.mpio(world, None)).create(path),
        None => hdf5::File::create(path),
    }
    .map_err(h5)?;
    let root = file.create_group("VTKHDF").map_err(h5)?;
    root.new_attr_builder().with_data(&[1i64, 0]).create("Version").map_err(h5)?;
    let ty = FixedAscii::<9>::from_ascii(b"ImageData").expect("ASCII literal");
    root.new_attr::<FixedAscii<9>>().create("Type").map_err(h5)?.write_scalar(&ty).map_err(h5)?;
    let ext = [0i64, nx as i64 - 1, 0, ny as i64 - 1, 0, nz as i64 - 1];
    root.new_attr_builder().with_data(&ext).create("WholeExtent").map_err(h5)?;
    root.new_attr_builder().with_data(&grid.origin).create("Origin").map_err(h5)?;
    root.new_attr_builder().with_data(&grid.spacing).create("Spacing").map_err(h5)?;
    let dir = [1.0f64, 0., 0., 0., 1., 0., 0., 0., 1.];
    root.new_attr_builder().with_data(&dir).create("Direction").map_err(h5)?;
    let pd = root.create_group("PointData").map_err(h5)?;
    let ds = pd.new_dataset::<f64>().shape([nz, ny, nx]).create(name).map_err(h5)?;
    let sc = FixedAscii::<7>::from_ascii(b"Scalars").expect("ASCII literal");
    ds.new_attr::<FixedAscii<7>>().create("Attribute").map_err(h5)?.write_scalar(&sc).map_err(h5)?;
    if layers > 0 {
        let view = ArrayView3::from_shape((layers, ny, nx), values).expect("slab shape");
        ds.as_writer().write_slice(view, s![k0..k0 + layers, .., ..]).map_err(h5)?;
    }
    drop(ds);
    drop(pd);
    drop(root);
    file.close().map_err(h5)
}

/// Reads a whole VTKHDF ImageData point array back (serially): grid and values, x fastest.
pub fn read_image(path: &Path, name: &str) -> Result<(Grid, Vec<f64>)> {
    let h5 = |e: hdf5::Error| Error::hdf5(path, e);
    let file = hdf5::File::open(path).map_err(h5)?;
    let root = file.group("VTKHDF").map_err(h5)?;
    let ext: Vec<i64> = root.attr("WholeExtent").map_err(h5)?.read_raw().map_err(h5)?;
    let origin: Vec<f64> = root.attr("Origin").map_err(h5)?.read_raw().map_err(h5)?;
    let spacing: Vec<f64> = root.attr("Spacing").map_err(h5)?.read_raw().map_err(h5)?;
    if ext.len() != 6 || origin.len() != 3 || spacing.len() != 3 {
        return Err(Error::hdf5(path, "malformed VTKHDF ImageData attributes"));
    }
    let dims = [ext[1] as usize + 1, ext[3] as usize + 1, ext[5] as usize + 1];
    let values: Vec<f64> = root.dataset(&format!("PointData/{name}")).map_err(h5)?.read_raw().map_err(h5)?;
    let grid = Grid {
        dims,
        origin: [origin[0], origin[1], origin[2]],
        spacing: [spacing[0], spacing[1], spacing[2]],
    };
    Ok((grid, values))
}
