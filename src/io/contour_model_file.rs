//! The contour model file `PREFIX.model.h5` written by `volspline contours`: everything needed to
//! evaluate the solid from contours anywhere without solving again. Written and read serially by
//! one rank. `volspline eval` tells it from a scattered-point model by the `format` attribute
//! ([`super::h5::format_of`]).
//!
//! Layout (all in the root group), S slices, N_i centres in slice i, N = sum N_i:
//! - attributes `format` = "volspline-contour-model", `format_version` = 1, `kernel_dim` (2),
//!   `kernel_order` (m), `kernel` (name), `interp` ("linear"/"cubic"/"monotone"), `orient` ("log"/"slerp"),
//!   `section_carriers` (the S carrier specs in the plane's coordinates, joined by ';'), and the
//!   provenance as in the scattered-point model (`input`, `data_box_lo`, `data_box_hi`,
//!   `points_read`, `duplicates_merged`, `solver`, `residual`, `ranks`, `threads`,
//!   `volspline_version`, `timing_stages`, `timing_seconds`);
//! - datasets `origins` (S x 3), `frames` (S x 9: the columns u, v, w of each frame), `offsets`
//!   (S + 1: slice i's centres are rows `offsets[i]..offsets[i+1]`), `centres_normalised` (N x 2),
//!   `weights` (N), `poly_coefficients` (S x k), `normalisation` (S x 3: centre a, centre b,
//!   scale).

use std::path::Path;

use glam::{DMat3, DVec3};

use super::h5::{open_model, Attrs};
use crate::contour::{ContourModel, Interp, Orient, SectionModel};
use crate::error::{Error, Result};
use crate::spline::carrier::Carrier;
use crate::spline::kernel::Kernel;
use crate::spline::{Normalisation, Spline};

pub const FORMAT: &str = "volspline-contour-model";

/// Writes `model` to `path` (created or truncated).
pub fn write_contour_model(path: &Path, model: &ContourModel) -> Result<()> {
    let h5 = |e: hdf5::Error| Error::hdf5(path, e);
    let f = super::h5::create(path)?;
    let a = Attrs { file: &f, path };
    let kernel = model.sections[0].spline.kernel;
    a.put_str("format", FORMAT)?;
    a.put_int("format_version", 1)?;
    a.put_int("kernel_dim", kernel.dim() as i64)?;
    a.put_int("kernel_order", kernel.order() as i64)?;
    a.put_str("kernel", &kernel.name())?;
    a.put_str("interp", model.interp.name())?;
    a.put_str("orient", model.orient.name())?;
    let carriers: Vec<String> = model.sections.iter().map(|s| s.carrier.to_string()).collect();
    a.put_str("section_carriers", &carriers.join(";"))?;
    a.put_provenance(&model.provenance)?;

    let s = model.sections.len();
    let k = kernel.poly_count();
    let mut origins = Vec::with_capacity(3 * s);
    let mut frames = Vec::with_capacity(9 * s);
    let mut offsets = vec![0i64];
    let (mut centres, mut weights, mut poly, mut norm) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for sec in &model.sections {
        origins.extend_from_slice(&sec.origin.to_array());
        frames.extend_from_slice(&sec.frame.to_cols_array());
        centres.extend_from_slice(&sec.spline.centres);
        weights.extend_from_slice(&sec.spline.weights);
        offsets.push(weights.len() as i64);
        poly.extend_from_slice(&sec.spline.poly);
        norm.extend_from_slice(&[
            sec.spline.norm.centre[0],
            sec.spline.norm.centre[1],
            sec.spline.norm.scale,
        ]);
    }
    let arr2 =
        |v: Vec<f64>, cols: usize| ndarray::Array2::from_shape_vec((v.len() / cols, cols), v).expect("shape");
    f.new_dataset_builder().with_data(&arr2(origins, 3)).create("origins").map_err(h5)?;
    f.new_dataset_builder().with_data(&arr2(frames, 9)).create("frames").map_err(h5)?;
    f.new_dataset_builder().with_data(&offsets).create("offsets").map_err(h5)?;
    f.new_dataset_builder().with_data(&arr2(centres, 2)).create("centres_normalised").map_err(h5)?;
    f.new_dataset_builder().with_data(&weights).create("weights").map_err(h5)?;
    f.new_dataset_builder().with_data(&arr2(poly, k)).create("poly_coefficients").map_err(h5)?;
    f.new_dataset_builder().with_data(&arr2(norm, 3)).create("normalisation").map_err(h5)?;
    f.close().map_err(h5)
}

/// Reads a model written by [`write_contour_model`], checking its format and consistency.
pub fn read_contour_model(path: &Path) -> Result<ContourModel> {
    let f = open_model(path, FORMAT, "contour model")?;
    let a = Attrs { file: &f, path };
    let bad = |why: String| a.bad(why);
    let (dim, order) = (a.int("kernel_dim")?, a.int("kernel_order")?);
    if dim != 2 || !(order == 2 || order == 3) {
        return Err(bad(format!(
            "kernel_dim {dim} and kernel_order {order} are not a section kernel (dimension 2, order 2 for \
             r2log or 3 for r4log)"
        )));
    }
    let kernel = Kernel::new(2, order as usize).map_err(|e| bad(e.to_string()))?;
    let interp = Interp::parse(&a.str("interp")?).map_err(|e| bad(e.to_string()))?;
    let orient = Orient::parse(&a.str("orient")?).map_err(|e| bad(e.to_string()))?;
    let carriers: Vec<Carrier> = a
        .str("section_carriers")?
        .split(';')
        .map(|c| Carrier::parse(c, 2))
        .collect::<Result<_>>()
        .map_err(|e| bad(e.to_string()))?;
    if let Some(c) = carriers.iter().find(|c| !c.is_resolved()) {
        return Err(bad(format!("section carrier '{c}': a stored disc must give its centre and radius")));
    }
    let s = carriers.len();
    let k = kernel.poly_count();
    a.expect_shape("origins", &[Some(s), Some(3)])?;
    a.expect_shape("frames", &[Some(s), Some(9)])?;
    a.expect_shape("offsets", &[Some(s + 1)])?;
    let n = a.expect_shape("centres_normalised", &[None, Some(2)])?[0];
    a.expect_shape("weights", &[Some(n)])?;
    a.expect_shape("poly_coefficients", &[Some(s), Some(k)])?;
    a.expect_shape("normalisation", &[Some(s), Some(3)])?;
    let origins = a.dataset_f64("origins")?;
    let frames = a.dataset_f64("frames")?;
    let offsets = a.dataset_i64("offsets")?;
    let centres = a.dataset_f64("centres_normalised")?;
    let weights = a.dataset_f64("weights")?;
    let poly = a.dataset_f64("poly_coefficients")?;
    let norm = a.dataset_f64("normalisation")?;
    let consistent = s >= 2
        && origins.len() == 3 * s
        && frames.len() == 9 * s
        && offsets.len() == s + 1
        && offsets[0] == 0
        && offsets.windows(2).all(|w| w[1] > w[0])
        && offsets[s] as usize == weights.len()
        && centres.len() == 2 * weights.len()
        && poly.len() == k * s
        && norm.len() == 3 * s;
    if !consistent {
        return Err(bad("inconsistent sizes of the slice datasets".into()));
    }
    if [&origins, &frames, &centres, &weights, &poly, &norm].iter().any(|v| v.iter().any(|x| !x.is_finite()))
    {
        return Err(bad("the model holds non-finite numbers".into()));
    }
    super::model_file::check_magnitudes(&a, &centres, &weights, &poly)?;
    if origins.iter().chain(&norm).any(|v| v.abs() > crate::spline::carrier::MAX_CARRIER_NUMBER) {
        return Err(bad("the slices' origins or normalisations are too large to evaluate".into()));
    }
    let mut sections = Vec::with_capacity(s);
    for (i, carrier) in carriers.into_iter().enumerate() {
        let (a, b) = (offsets[i] as usize, offsets[i + 1] as usize);
        let frame = DMat3::from_cols_slice(&frames[9 * i..9 * i + 9]);
        if (frame.transpose() * frame - DMat3::IDENTITY).to_cols_array().iter().any(|v| v.abs() > 1e-9) {
            return Err(bad(format!("the frame of slice {i} is not a rotation")));
        }
        if !(norm[3 * i + 2] > 0.0) {
            return Err(bad(format!("the normalisation of slice {i} has a non-positive scale")));
        }
        sections.push(SectionModel {
            origin: DVec3::from_slice(&origins[3 * i..3 * i + 3]),
            frame,
            carrier,
            spline: Spline {
                kernel,
                centres: centres[2 * a..2 * b].to_vec(),
                weights: weights[a..b].to_vec(),
                poly: poly[k * i..k * (i + 1)].to_vec(),
                norm: Normalisation { centre: [norm[3 * i], norm[3 * i + 1], 0.0], scale: norm[3 * i + 2] },
            },
        });
    }
    let planes: Vec<(DVec3, DMat3)> = sections.iter().map(|s| (s.origin, s.frame)).collect();
    if !crate::contour::knots_of(&planes).windows(2).all(|w| w[1] > w[0]) {
        return Err(bad("the slices are not ordered along their normals".into()));
    }
    let provenance = a.provenance()?;
    Ok(ContourModel::new(sections, interp, orient, provenance))
}
