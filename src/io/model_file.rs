//! The model file `PREFIX.model.h5`: everything needed to evaluate f = f_c - U anywhere without
//! solving again, and how it was made. Written and read serially by one rank.
//!
//! Layout (all in the root group):
//! - attributes `format` = "volspline-model", `format_version` = 1, `kernel_dim` (n),
//!   `kernel_order` (m), `kernel` (name, e.g. "r"), `carrier` (spec, see `carrier`),
//!   `normalisation_centre` (3 doubles), `normalisation_scale`, and the provenance:
//!   `input`, `data_box_lo`, `data_box_hi` (the input points' bounding box), `points_read`, `duplicates_merged`, `solver`, `residual`, `ranks`, `threads`,
//!   `volspline_version`, `timing_stages` (comma-separated), `timing_seconds`;
//! - datasets `centres` (N x n, input coordinates), `centres_normalised` (N x n, the ones the
//!   system was built from), `weights` (lambda, N), `poly_coefficients` (c, k) and
//!   `poly_exponents` (k x 3, the monomial of each c).

use std::path::Path;

use super::h5::{open_model, Attrs};
use crate::error::{Error, Result};
use crate::spline::carrier::Carrier;
use crate::spline::kernel::Kernel;
use crate::spline::model::Model;
use crate::spline::{Normalisation, Spline};

pub const FORMAT: &str = "volspline-model";

/// Writes `model` to `path` (an HDF5 file, created or truncated).
pub fn write_model(path: &Path, model: &Model) -> Result<()> {
    let h5 = |e: hdf5::Error| Error::hdf5(path, e);
    let f = hdf5::File::create(path).map_err(h5)?;
    let a = Attrs { file: &f, path };
    let sp = &model.spline;
    let dim = sp.kernel.dim();
    a.put_str("format", FORMAT)?;
    a.put_int("format_version", 1)?;
    a.put_int("kernel_dim", dim as i64)?;
    a.put_int("kernel_order", sp.kernel.order() as i64)?;
    a.put_str("kernel", &sp.kernel.name())?;
    a.put_str("carrier", &model.carrier.to_string())?;
    a.put_f64s("normalisation_centre", &sp.norm.centre)?;
    a.put_f64s("normalisation_scale", &[sp.norm.scale])?;
    a.put_provenance(&model.provenance)?;

    let mut caller = vec![0.0; sp.centres.len()];
    for (c, pn) in caller.chunks_exact_mut(dim).zip(sp.centres.chunks_exact(dim)) {
        for d in 0..dim {
            c[d] = pn[d] * sp.norm.scale + sp.norm.centre[d];
        }
    }
    let arr2 = |v: &[f64], cols: usize| ndarray::Array2::from_shape_vec((v.len() / cols, cols), v.to_vec());
    f.new_dataset_builder().with_data(&arr2(&caller, dim).expect("shape")).create("centres").map_err(h5)?;
    f.new_dataset_builder()
        .with_data(&arr2(&sp.centres, dim).expect("shape"))
        .create("centres_normalised")
        .map_err(h5)?;
    f.new_dataset_builder().with_data(&sp.weights).create("weights").map_err(h5)?;
    f.new_dataset_builder().with_data(&sp.poly).create("poly_coefficients").map_err(h5)?;
    let exps: Vec<i64> = sp.kernel.monomials().iter().flat_map(|e| e.map(|x| x as i64)).collect();
    f.new_dataset_builder()
        .with_data(&ndarray::Array2::from_shape_vec((exps.len() / 3, 3), exps).expect("shape"))
        .create("poly_exponents")
        .map_err(h5)?;
    f.close().map_err(h5)
}

/// Reads a model written by [`write_model`], checking its format and consistency.
pub fn read_model(path: &Path) -> Result<Model> {
    let f = open_model(path, FORMAT, "volspline model")?;
    let a = Attrs { file: &f, path };
    let kernel = Kernel::new(a.int("kernel_dim")? as usize, a.int("kernel_order")? as usize)
        .map_err(|e| a.bad(e.to_string()))?;
    let dim = kernel.dim();
    let carrier = Carrier::parse(&a.str("carrier")?, dim).map_err(|e| a.bad(e.to_string()))?;
    let centre = a.f64s("normalisation_centre")?;
    let scale = a.f64s("normalisation_scale")?;
    if centre.len() != 3 || scale.len() != 1 || !(scale[0] > 0.0) {
        return Err(a.bad("malformed normalisation"));
    }
    let norm = Normalisation { centre: [centre[0], centre[1], centre[2]], scale: scale[0] };
    let centres = a.dataset_f64("centres_normalised")?;
    let weights = a.dataset_f64("weights")?;
    let poly = a.dataset_f64("poly_coefficients")?;
    if centres.len() != weights.len() * dim || poly.len() != kernel.poly_count() {
        return Err(a.bad(format!(
            "inconsistent sizes: {} centre values, {} weights, {} polynomial coefficients for kernel {}",
            centres.len(),
            weights.len(),
            poly.len(),
            kernel.name()
        )));
    }
    if centres.iter().chain(&weights).chain(&poly).any(|v| !v.is_finite()) {
        return Err(a.bad("the model holds non-finite numbers"));
    }
    let provenance = a.provenance()?;
    Ok(Model { carrier, spline: Spline { kernel, centres, weights, poly, norm }, provenance })
}
