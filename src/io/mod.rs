//! Files in and out: scattered points and meshes (`points`), the VTKHDF volume (`vtkhdf`, written
//! in parallel by all ranks), the model file (`model_file`) and atomic replacement of outputs.

pub mod contour_model_file;
pub mod h5;
pub mod model_file;
pub mod points;
pub mod vtkhdf;

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

/// The temporary name an output is written under before it is renamed into place, so that a
/// failed run never leaves a half-written file under the final name. The same on every rank.
pub fn partial_path(path: &Path) -> PathBuf {
    let mut s = path.as_os_str().to_owned();
    s.push(".partial");
    PathBuf::from(s)
}

/// Writes `path` atomically: `write` fills the temporary file it is given, which is then renamed to
/// `path`; on any failure the temporary file is removed and `path` is untouched.
pub fn write_atomically(path: &Path, write: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
    let tmp = partial_path(path);
    write(&tmp).and_then(|_| commit(path)).inspect_err(|_| discard(path))
}

/// Renames the finished temporary file to its final name.
pub fn commit(path: &Path) -> Result<()> {
    let tmp = partial_path(path);
    std::fs::rename(&tmp, path).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        Error::io(path, &e)
    })
}

/// Removes a temporary file after a failure (errors ignored: there may be nothing to remove).
pub fn discard(path: &Path) {
    let _ = std::fs::remove_file(partial_path(path));
}
