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
//!   k0..k0+layers. The first dataset (f) also carries the string attribute `Attribute` =
//!   `Scalars`, which makes it the active scalars.
//!
//! Several point arrays may be written side by side (f and, on request, the curvatures); there
//! is no cell or field data.

use std::path::Path;

use hdf5::types::FixedAscii;
use ndarray::{s, ArrayView3};

use crate::error::{Error, Result};
use crate::grid::Grid;
use crate::par::{agree, on_root, Comm};

/// Writes `values` (this rank's layers k0..k0+layers of `grid`, x fastest) as the point array
/// `name` of a VTKHDF ImageData file at `path`. Collective. See [`write_image_arrays`].
pub fn write_image(
    comm: &dyn Comm,
    path: &Path,
    grid: &Grid,
    k0: usize,
    layers: usize,
    name: &str,
    values: &[f64],
) -> Result<()> {
    write_image_arrays(comm, path, grid, k0, layers, &[(name, values)])
}

/// Writes point arrays (name, this rank's layers k0..k0+layers of `grid`, x fastest) of a VTKHDF
/// ImageData file at `path`, one dataset each under `/VTKHDF/PointData`. Collective.
///
/// Every collective step (free space, create, metadata, slab write, close) agrees on its outcome
/// across ranks before the next, so a failure on one rank (a full disk, say) never leaves the ranks
/// in different collectives. After a failed step the file is truncated by rank 0 before it is
/// closed, which gives back the space the metadata flush of the close needs, every rank closes it
/// in the same order, and rank 0 removes it.
pub fn write_image_arrays(
    comm: &dyn Comm,
    path: &Path,
    grid: &Grid,
    k0: usize,
    layers: usize,
    arrays: &[(&str, &[f64])],
) -> Result<()> {
    let h5 = |e: hdf5::Error| Error::hdf5(path, e);
    let [nx, ny, nz] = grid.dims;
    for (_, values) in arrays {
        assert_eq!(values.len(), nx * ny * layers);
    }
    let bytes = (nx * ny * nz * 8 * arrays.len()) as u64;
    on_root(comm, || check_space(path, bytes))?;
    agree(comm, check_file_size_limit(path, bytes))?;
    let created = match comm.raw() {
        Some(world) => hdf5::File::with_options().with_fapl(|p| p.mpio(world, None)).create(path),
        None => hdf5::File::create(path),
    };
    let file = match agree(comm, created.map_err(h5)) {
        Ok(f) => f,
        Err(e) => {
            on_root(comm, || remove(path)).ok();
            return Err(e);
        }
    };
    let written = (|| {
        let names: Vec<&str> = arrays.iter().map(|(n, _)| *n).collect();
        let sets = agree(comm, metadata(&file, grid, &names).map_err(h5))?;
        for (ds, (_, values)) in sets.iter().zip(arrays) {
            let slab = if layers > 0 {
                let view = ArrayView3::from_shape((layers, ny, nx), values).expect("slab shape");
                ds.as_writer().write_slice(view, s![k0..k0 + layers, .., ..]).map_err(h5)
            } else {
                Ok(())
            };
            agree(comm, slab)?;
        }
        Ok(())
    })();
    if written.is_err() && comm.rank() == 0 {
        // frees the space of the data written so far, so that the close can flush its metadata
        let _ = std::fs::OpenOptions::new().write(true).open(path).and_then(|f| f.set_len(0));
    }
    comm.barrier();
    // every object of the file is closed by now (the dataset and groups live in the closure)
    let closed = agree(comm, file.close().map_err(h5));
    let result = written.and(closed);
    if result.is_err() {
        on_root(comm, || remove(path)).ok();
    }
    result
}

/// The groups, attributes and (empty) datasets of the layout described above.
fn metadata(file: &hdf5::File, grid: &Grid, names: &[&str]) -> hdf5::Result<Vec<hdf5::Dataset>> {
    let [nx, ny, nz] = grid.dims;
    let root = file.create_group("VTKHDF")?;
    root.new_attr_builder().with_data(&[1i64, 0]).create("Version")?;
    let ty = FixedAscii::<9>::from_ascii(b"ImageData").expect("ASCII literal");
    root.new_attr::<FixedAscii<9>>().create("Type")?.write_scalar(&ty)?;
    let ext = [0i64, nx as i64 - 1, 0, ny as i64 - 1, 0, nz as i64 - 1];
    root.new_attr_builder().with_data(&ext).create("WholeExtent")?;
    root.new_attr_builder().with_data(&grid.origin).create("Origin")?;
    root.new_attr_builder().with_data(&grid.spacing).create("Spacing")?;
    let dir = [1.0f64, 0., 0., 0., 1., 0., 0., 0., 1.];
    root.new_attr_builder().with_data(&dir).create("Direction")?;
    let pd = root.create_group("PointData")?;
    let mut sets = Vec::with_capacity(names.len());
    for (i, name) in names.iter().enumerate() {
        let ds = pd.new_dataset::<f64>().shape([nz, ny, nx]).create(*name)?;
        // only the first array is the active scalars: VTK drops an array marked Scalars when a
        // later one takes that role
        if i == 0 {
            let sc = FixedAscii::<7>::from_ascii(b"Scalars").expect("ASCII literal");
            ds.new_attr::<FixedAscii<7>>().create("Attribute")?.write_scalar(&sc)?;
        }
        sets.push(ds);
    }
    Ok(sets)
}

/// Refuses to start a write of `bytes` of data (plus 1 MiB of metadata) into the directory of
/// `path` when its file system has less space free, before any collective write can fail. The
/// fault-injection tests set `VOLSPLINE_TEST_SKIP_SPACE_CHECK` to reach the failing write itself.
fn check_space(path: &Path, bytes: u64) -> Result<()> {
    if std::env::var_os("VOLSPLINE_TEST_SKIP_SPACE_CHECK").is_some() {
        return Ok(());
    }
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let Ok(c) = std::ffi::CString::new(dir.as_os_str().as_encoded_bytes()) else { return Ok(()) };
    // SAFETY: statvfs fills the zeroed struct it is given from a NUL-terminated path
    let mut st: libc::statvfs = unsafe { std::mem::zeroed() };
    if unsafe { libc::statvfs(c.as_ptr(), &mut st) } != 0 {
        return Ok(()); // no figure: the write itself reports a full disk
    }
    let free = st.f_bavail as u64 * st.f_frsize as u64;
    let need = bytes + (1 << 20);
    if free < need {
        let mb = |b: u64| b as f64 / 1048576.0;
        return Err(Error::Io {
            path: dir.into(),
            reason: format!(
                "not enough free space for the volume: it needs {:.1} MB, {:.1} MB are free (use a coarser --grid or another --out directory)",
                mb(need),
                mb(free)
            ),
        });
    }
    Ok(())
}

/// Refuses to start a write of a file of `bytes` of data (plus 1 MiB of metadata) at `path` when
/// this process may not write a file that large (`ulimit -f`, a batch system's file-size limit),
/// before any collective write can fail: a file past the limit fails its metadata flush at the
/// close too, however it is truncated, and HDF5's shutdown then crashes on the file left half
/// closed. Checked on every rank: the launcher may give the ranks different limits.
fn check_file_size_limit(path: &Path, bytes: u64) -> Result<()> {
    // SAFETY: getrlimit fills the zeroed struct it is given
    let mut lim: libc::rlimit = unsafe { std::mem::zeroed() };
    if unsafe { libc::getrlimit(libc::RLIMIT_FSIZE, &mut lim) } != 0 || lim.rlim_cur == libc::RLIM_INFINITY {
        return Ok(());
    }
    let (limit, need) = (lim.rlim_cur as u64, bytes + (1 << 20));
    if need > limit {
        let mb = |b: u64| b as f64 / 1048576.0;
        return Err(Error::Io {
            path: path.into(),
            reason: format!(
                "the volume needs {:.1} MB, but this process may write files of at most {:.1} MB (the file-size limit, `ulimit -f`); use a coarser --grid or a larger limit",
                mb(need),
                mb(limit)
            ),
        });
    }
    Ok(())
}

fn remove(path: &Path) -> Result<()> {
    let _ = std::fs::remove_file(path);
    Ok(())
}

/// Reads a whole VTKHDF ImageData point array back (serially): grid and values, x fastest.
pub fn read_image(path: &Path, name: &str) -> Result<(Grid, Vec<f64>)> {
    super::staging::note_input(path);
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
