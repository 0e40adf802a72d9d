//! Typed access to the attributes and datasets of the model files over hdf5-metno, with errors
//! that name the file, and the provenance block that both model formats (scattered points and
//! contours) carry. Serial HDF5 only; the parallel volume output is in `vtkhdf`.
//!
//! Model files are written in HDF5's latest file format ([`create`]), whose metadata (superblock,
//! object headers, B-trees, heaps of names) carry checksums, and their texts as byte arrays
//! rather than variable-length strings (whose global heap has no checksum): a damaged file is
//! refused by the library with an error. On files written in the earliest format a damaged
//! object could make HDF5 1.10 read out of bounds and crash.

use std::path::Path;

use hdf5::types::VarLenUnicode;

use crate::error::{Error, Result};
use crate::spline::model::Provenance;

/// Creates (or truncates) the model file `path` in HDF5's latest file format (see the module doc).
pub fn create(path: &Path) -> Result<hdf5::File> {
    hdf5::File::with_options().with_fapl(|p| p.libver_latest()).create(path).map_err(|e| Error::hdf5(path, e))
}

/// The root group of one open model file.
pub struct Attrs<'a> {
    pub file: &'a hdf5::File,
    pub path: &'a Path,
}

impl Attrs<'_> {
    fn h5(&self, e: hdf5::Error) -> Error {
        Error::hdf5(self.path, e)
    }

    /// A malformed-file error naming the file.
    pub fn bad(&self, why: impl Into<String>) -> Error {
        Error::input(self.path, "", why)
    }

    /// Writes the text `v` as a one-dimensional attribute of its UTF-8 bytes (an empty text as
    /// one NUL byte). Not a variable-length string: those live in HDF5's global heap, whose
    /// objects carry no checksum, and a file damaged there made the library itself read out of
    /// bounds and crash instead of returning an error.
    pub fn put_str(&self, name: &str, v: &str) -> Result<()> {
        let bytes: Vec<u8> = if v.is_empty() { vec![0] } else { v.as_bytes().to_vec() };
        self.file.new_attr_builder().with_data(&bytes).create(name).map(|_| ()).map_err(|e| self.h5(e))
    }

    pub fn put_f64s(&self, name: &str, v: &[f64]) -> Result<()> {
        self.file.new_attr_builder().with_data(v).create(name).map(|_| ()).map_err(|e| self.h5(e))
    }

    pub fn put_int(&self, name: &str, v: i64) -> Result<()> {
        self.file.new_attr_builder().with_data(&[v]).create(name).map(|_| ()).map_err(|e| self.h5(e))
    }

    fn attr(&self, name: &str) -> Result<hdf5::Attribute> {
        self.file.attr(name).map_err(|_| self.bad(format!("attribute '{name}' is missing")))
    }

    /// The text of attribute `name`: UTF-8 bytes as [`Attrs::put_str`] writes them, or a
    /// variable-length string (files written before 2026-12-04).
    pub fn str(&self, name: &str) -> Result<String> {
        let attr = self.attr(name)?;
        if attr.dtype().map_err(|e| self.h5(e))?.is::<u8>() {
            let mut bytes = attr.read_raw::<u8>().map_err(|e| self.h5(e))?;
            while bytes.last() == Some(&0) {
                bytes.pop();
            }
            return String::from_utf8(bytes)
                .map_err(|_| self.bad(format!("attribute '{name}' is not UTF-8 text")));
        }
        let v = attr.read_scalar::<VarLenUnicode>().map_err(|e| self.h5(e))?;
        Ok(v.as_str().to_string())
    }

    pub fn f64s(&self, name: &str) -> Result<Vec<f64>> {
        self.attr(name)?.read_raw::<f64>().map_err(|e| self.h5(e))
    }

    pub fn int(&self, name: &str) -> Result<i64> {
        let v = self.attr(name)?.read_raw::<i64>().map_err(|e| self.h5(e))?;
        v.first().copied().ok_or_else(|| self.bad(format!("attribute '{name}' is empty")))
    }

    /// Three finite numbers (a point).
    pub fn point(&self, name: &str) -> Result<[f64; 3]> {
        let v = self.f64s(name)?;
        if v.len() != 3 || v.iter().any(|x| !x.is_finite()) {
            return Err(self.bad(format!("attribute '{name}' must hold 3 finite numbers")));
        }
        Ok([v[0], v[1], v[2]])
    }

    pub fn dataset_f64(&self, name: &str) -> Result<Vec<f64>> {
        let ds = self.file.dataset(name).map_err(|_| self.bad(format!("dataset '{name}' is missing")))?;
        ds.read_raw::<f64>().map_err(|e| self.h5(e))
    }

    /// The shape of dataset `name`.
    pub fn shape(&self, name: &str) -> Result<Vec<usize>> {
        let ds = self.file.dataset(name).map_err(|_| self.bad(format!("dataset '{name}' is missing")))?;
        Ok(ds.shape())
    }

    /// Refuses dataset `name` unless its shape is `want` (`None`: any length on that axis).
    pub fn expect_shape(&self, name: &str, want: &[Option<usize>]) -> Result<Vec<usize>> {
        let got = self.shape(name)?;
        let fits = got.len() == want.len() && got.iter().zip(want).all(|(g, w)| w.is_none_or(|w| w == *g));
        if fits {
            return Ok(got);
        }
        let show = |v: Vec<String>| if v.is_empty() { "scalar (no axes)".to_string() } else { v.join(" x ") };
        let want: Vec<String> = want.iter().map(|w| w.map_or("N".to_string(), |w| w.to_string())).collect();
        Err(self.bad(format!(
            "dataset '{name}' has shape {}, expected {}",
            show(got.iter().map(|g| g.to_string()).collect()),
            show(want)
        )))
    }

    pub fn dataset_i64(&self, name: &str) -> Result<Vec<i64>> {
        let ds = self.file.dataset(name).map_err(|_| self.bad(format!("dataset '{name}' is missing")))?;
        ds.read_raw::<i64>().map_err(|e| self.h5(e))
    }

    /// Writes the provenance attributes: `input`, `data_box_lo`, `data_box_hi`, `points_read`,
    /// `duplicates_merged`, `data_points` (only when known), `solver`, `residual`, `ranks`, `threads`, `volspline_version`,
    /// `timing_stages` (comma-separated) and `timing_seconds`.
    pub fn put_provenance(&self, p: &Provenance) -> Result<()> {
        self.put_str("input", &p.input)?;
        self.put_str("solver", &p.solver)?;
        self.put_str("volspline_version", &p.version)?;
        self.put_int("points_read", p.points_read as i64)?;
        self.put_int("duplicates_merged", p.duplicates_merged as i64)?;
        if p.data_points > 0 {
            self.put_int("data_points", p.data_points as i64)?;
        }
        self.put_int("ranks", p.ranks as i64)?;
        self.put_int("threads", p.threads as i64)?;
        self.put_f64s("residual", &[p.residual])?;
        self.put_f64s("data_box_lo", &p.box_lo)?;
        self.put_f64s("data_box_hi", &p.box_hi)?;
        let stages: Vec<&str> = p.timings.iter().map(|(s, _)| s.as_str()).collect();
        self.put_str("timing_stages", &stages.join(","))?;
        self.put_f64s("timing_seconds", &p.timings.iter().map(|(_, t)| *t).collect::<Vec<f64>>())
    }

    /// Reads what [`Attrs::put_provenance`] wrote; only the data box is required.
    pub fn provenance(&self) -> Result<Provenance> {
        let stages = self.str("timing_stages").unwrap_or_default();
        let secs = self.f64s("timing_seconds").unwrap_or_default();
        let (box_lo, box_hi) = (self.point("data_box_lo")?, self.point("data_box_hi")?);
        if let Some(d) = (0..3).find(|&d| box_lo[d] > box_hi[d]) {
            return Err(self.bad(format!(
                "attributes 'data_box_lo' and 'data_box_hi' are not a box: along {} the low corner {:e} lies \
                 above the high one {:e}",
                ["x", "y", "z"][d],
                box_lo[d],
                box_hi[d]
            )));
        }
        Ok(Provenance {
            input: self.str("input").unwrap_or_default(),
            box_lo,
            box_hi,
            points_read: self.int("points_read").unwrap_or(0) as usize,
            duplicates_merged: self.int("duplicates_merged").unwrap_or(0) as usize,
            data_points: self.int("data_points").unwrap_or(0).max(0) as usize,
            solver: self.str("solver").unwrap_or_default(),
            residual: self.f64s("residual").ok().and_then(|v| v.first().copied()).unwrap_or(f64::NAN),
            ranks: self.int("ranks").unwrap_or(0) as usize,
            threads: self.int("threads").unwrap_or(0) as usize,
            timings: stages.split(',').filter(|s| !s.is_empty()).map(String::from).zip(secs).collect(),
            version: self.str("volspline_version").unwrap_or_default(),
        })
    }
}

/// Closes every HDF5 object still open and shuts the library down (a later call restarts it).
/// Called before MPI is finalised, so that no HDF5 close runs through MPI-IO after it.
pub fn close_library() {
    // SAFETY: H5close under the library lock of hdf5-metno; no HDF5 handle is used after it
    hdf5::sync::sync(|| unsafe {
        hdf5_sys::h5::H5close();
    });
}

/// What a model file is, for the errors about files that are not one.
const MODEL_FILES: &str =
    "a model is the PREFIX.model.h5 that `volspline fit` or `volspline contours` writes";

/// The `format` attribute of an HDF5 model file (which of the model formats it holds).
pub fn format_of(path: &Path) -> Result<String> {
    if !path.exists() {
        return Err(Error::Io { path: path.into(), reason: "no such file".into() });
    }
    if path.is_dir() {
        return Err(Error::input(path, "", format!("a directory, not a model file ({MODEL_FILES})")));
    }
    // a pipe or a device would block HDF5's open (a pipe without a writer, forever) and cannot
    // be read at random as HDF5 reads
    if !path.metadata().is_ok_and(|m| m.is_file()) {
        return Err(Error::input(
            path,
            "",
            format!("not a regular file (a pipe or a device), so not a model: HDF5 reads models from files ({MODEL_FILES})"),
        ));
    }
    super::staging::note_input(path);
    let f = hdf5::File::open(path).map_err(|e| {
        // a file without the HDF5 signature where it starts is named so, not by HDF5's own words
        let mut head = [0u8; 8];
        let read = std::fs::File::open(path).and_then(|mut f| std::io::Read::read_exact(&mut f, &mut head));
        if read.is_err() || head != *b"\x89HDF\r\n\x1a\n" {
            Error::input(path, "", format!("not an HDF5 file, so not a model ({MODEL_FILES})"))
        } else {
            Error::hdf5(path, e)
        }
    })?;
    let a = Attrs { file: &f, path };
    if f.attr("format").is_err() {
        return Err(a.bad("not a volspline model: no 'format' attribute"));
    }
    a.str("format").map_err(|_| a.bad("not a volspline model: its 'format' attribute is not a text"))
}

/// Opens a model file for reading after checking that its `format` attribute is `format` (else
/// the file is "not a `what`") and that its `format_version` is 1, the only version written.
pub fn open_model(path: &Path, format: &str, what: &str) -> Result<hdf5::File> {
    if format_of(path)? != format {
        return Err(Error::input(path, "", format!("not a {what} (format is not '{format}')")));
    }
    let file = hdf5::File::open(path).map_err(|e| Error::hdf5(path, e))?;
    let version = Attrs { file: &file, path }.int("format_version")?;
    if version != 1 {
        let why = format!("{what} format version {version} is not supported (expected 1)");
        return Err(Error::input(path, "", why));
    }
    Ok(file)
}
