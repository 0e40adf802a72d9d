//! The contour model file `PREFIX.model.h5` written by `volspline contours`: everything needed to
//! evaluate the solid from contours anywhere without solving again. Written and read serially by
//! one rank. `volspline eval` tells it from a scattered-point model by the `format` attribute
//! ([`format_of`]).
//!
//! Layout (all in the root group), S slices, N_i centres in slice i, N = sum N_i:
//! - attributes `format` = "volspline-contour-model", `format_version` = 1, `kernel_dim` (2),
//!   `kernel_order` (m), `kernel` (name), `interp` ("linear"/"cubic"), `orient` ("log"/"slerp"),
//!   `section_carriers` (the S carrier specs in the plane's coordinates, joined by ';'), and the
//!   provenance as in the scattered-point model (`input`, `data_box_lo`, `data_box_hi`,
//!   `points_read`, `duplicates_merged`, `solver`, `residual`, `ranks`, `threads`,
//!   `volspline_version`, `timing_stages`, `timing_seconds`);
//! - datasets `origins` (S x 3), `frames` (S x 9: the columns u, v, w of each frame), `offsets`
//!   (S + 1: slice i's centres are rows offsets[i]..offsets[i+1]), `centres_normalised` (N x 2),
//!   `weights` (N), `poly_coefficients` (S x k), `normalisation` (S x 3: centre a, centre b,
//!   scale).

use std::path::Path;

use glam::{DMat3, DVec3};
use hdf5::types::VarLenUnicode;

use crate::carrier::Carrier;
use crate::contour::{ContourModel, Interp, Orient, SectionModel};
use crate::error::{Error, Result};
use crate::kernel::Kernel;
use crate::model::Provenance;
use crate::spline::{Normalisation, Spline};

pub const FORMAT: &str = "volspline-contour-model";

fn text(s: &str) -> VarLenUnicode {
    s.parse().unwrap_or_default()
}

/// The `format` attribute of an HDF5 model file.
pub fn format_of(path: &Path) -> Result<String> {
    if !path.exists() {
        return Err(Error::Io { path: path.into(), reason: "no such file".into() });
    }
    let f = hdf5::File::open(path).map_err(|e| Error::hdf5(path, e))?;
    let a = f
        .attr("format")
        .map_err(|_| Error::input(path, "", "not a volspline model: no 'format' attribute"))?;
    Ok(a.read_scalar::<VarLenUnicode>().map_err(|e| Error::hdf5(path, e))?.as_str().to_string())
}

/// Writes `model` to `path` (created or truncated).
pub fn write_contour_model(path: &Path, model: &ContourModel) -> Result<()> {
    let h5 = |e: hdf5::Error| Error::hdf5(path, e);
    let f = hdf5::File::create(path).map_err(h5)?;
    let put_str = |name: &str, v: &str| -> Result<()> {
        f.new_attr::<VarLenUnicode>().create(name).map_err(h5)?.write_scalar(&text(v)).map_err(h5)
    };
    let put_f64s = |name: &str, v: &[f64]| -> Result<()> {
        f.new_attr_builder().with_data(v).create(name).map(|_| ()).map_err(h5)
    };
    let put_int = |name: &str, v: i64| -> Result<()> {
        f.new_attr_builder().with_data(&[v]).create(name).map(|_| ()).map_err(h5)
    };
    let kernel = model.sections[0].spline.kernel;
    put_str("format", FORMAT)?;
    put_int("format_version", 1)?;
    put_int("kernel_dim", kernel.dim() as i64)?;
    put_int("kernel_order", kernel.order() as i64)?;
    put_str("kernel", &kernel.name())?;
    put_str("interp", model.interp.name())?;
    put_str("orient", model.orient.name())?;
    let carriers: Vec<String> = model.sections.iter().map(|s| s.carrier.to_string()).collect();
    put_str("section_carriers", &carriers.join(";"))?;
    let p = &model.provenance;
    put_str("input", &p.input)?;
    put_str("solver", &p.solver)?;
    put_str("volspline_version", &p.version)?;
    put_int("points_read", p.points_read as i64)?;
    put_int("duplicates_merged", p.duplicates_merged as i64)?;
    put_int("ranks", p.ranks as i64)?;
    put_int("threads", p.threads as i64)?;
    put_f64s("residual", &[p.residual])?;
    put_f64s("data_box_lo", &p.box_lo)?;
    put_f64s("data_box_hi", &p.box_hi)?;
    let stages: Vec<&str> = p.timings.iter().map(|(s, _)| s.as_str()).collect();
    put_str("timing_stages", &stages.join(","))?;
    put_f64s("timing_seconds", &p.timings.iter().map(|(_, t)| *t).collect::<Vec<f64>>())?;

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
    let h5 = |e: hdf5::Error| Error::hdf5(path, e);
    let bad = |why: String| Error::input(path, "", why);
    if format_of(path)? != FORMAT {
        return Err(bad(format!("not a contour model (format is not '{FORMAT}')")));
    }
    let f = hdf5::File::open(path).map_err(h5)?;
    let get_str = |name: &str| -> Result<String> {
        Ok(f.attr(name)
            .map_err(|_| bad(format!("attribute '{name}' is missing")))?
            .read_scalar::<VarLenUnicode>()
            .map_err(h5)?
            .as_str()
            .to_string())
    };
    let get_f64s = |name: &str| -> Result<Vec<f64>> {
        f.attr(name).map_err(|_| bad(format!("attribute '{name}' is missing")))?.read_raw::<f64>().map_err(h5)
    };
    let get_int = |name: &str| -> Result<i64> {
        let v = f
            .attr(name)
            .map_err(|_| bad(format!("attribute '{name}' is missing")))?
            .read_raw::<i64>()
            .map_err(h5)?;
        v.first().copied().ok_or_else(|| bad(format!("attribute '{name}' is empty")))
    };
    let ds = |name: &str| -> Result<Vec<f64>> {
        f.dataset(name)
            .map_err(|_| bad(format!("dataset '{name}' is missing")))?
            .read_raw::<f64>()
            .map_err(h5)
    };
    let version = get_int("format_version")?;
    if version != 1 {
        return Err(bad(format!("contour model format version {version} is not supported (expected 1)")));
    }
    let kernel = Kernel::new(get_int("kernel_dim")? as usize, get_int("kernel_order")? as usize)
        .map_err(|e| bad(e.to_string()))?;
    if kernel.dim() != 2 {
        return Err(bad(format!("section kernels are two-dimensional, this one has n = {}", kernel.dim())));
    }
    let interp = Interp::parse(&get_str("interp")?).map_err(|e| bad(e.to_string()))?;
    let orient = Orient::parse(&get_str("orient")?).map_err(|e| bad(e.to_string()))?;
    let carriers: Vec<Carrier> = get_str("section_carriers")?
        .split(';')
        .map(|c| Carrier::parse(c, 2))
        .collect::<Result<_>>()
        .map_err(|e| bad(e.to_string()))?;
    let origins = ds("origins")?;
    let frames = ds("frames")?;
    let offsets: Vec<i64> = f
        .dataset("offsets")
        .map_err(|_| bad("dataset 'offsets' is missing".into()))?
        .read_raw::<i64>()
        .map_err(h5)?;
    let centres = ds("centres_normalised")?;
    let weights = ds("weights")?;
    let poly = ds("poly_coefficients")?;
    let norm = ds("normalisation")?;
    let s = carriers.len();
    let k = kernel.poly_count();
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
    let box3 = |name: &str| -> Result<[f64; 3]> {
        let v = get_f64s(name)?;
        if v.len() != 3 || v.iter().any(|x| !x.is_finite()) {
            return Err(bad(format!("attribute '{name}' must hold 3 finite numbers")));
        }
        Ok([v[0], v[1], v[2]])
    };
    let stages = get_str("timing_stages").unwrap_or_default();
    let secs = get_f64s("timing_seconds").unwrap_or_default();
    let provenance = Provenance {
        input: get_str("input").unwrap_or_default(),
        box_lo: box3("data_box_lo")?,
        box_hi: box3("data_box_hi")?,
        points_read: get_int("points_read").unwrap_or(0) as usize,
        duplicates_merged: get_int("duplicates_merged").unwrap_or(0) as usize,
        solver: get_str("solver").unwrap_or_default(),
        residual: get_f64s("residual").ok().and_then(|v| v.first().copied()).unwrap_or(f64::NAN),
        ranks: get_int("ranks").unwrap_or(0) as usize,
        threads: get_int("threads").unwrap_or(0) as usize,
        timings: stages.split(',').filter(|s| !s.is_empty()).map(String::from).zip(secs).collect(),
        version: get_str("volspline_version").unwrap_or_default(),
    };
    Ok(ContourModel::new(sections, interp, orient, provenance))
}
