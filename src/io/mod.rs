//! Files in and out: scattered points and meshes (`points`), the VTKHDF volume (`vtkhdf`, written
//! in parallel by all ranks), the model file (`model_file`) and the staging of outputs
//! under temporary names, renamed into place as a set (`staging`), and the decoding of text
//! inputs (`text`).

pub mod contour_model_file;
pub mod h5;
pub mod model_file;
pub mod points;
pub mod staging;
pub mod text;
pub mod vtkhdf;

use std::path::Path;

use crate::error::Result;

/// Writes the output `path` of this run under its temporary name (see [`staging`]); it is renamed
/// into place with the command's other outputs by [`staging::commit_all`] once every rank has
/// succeeded. On failure the temporary file is removed and `path` is untouched.
pub fn write_atomically(path: &Path, write: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
    staging::stage(path, write)
}
