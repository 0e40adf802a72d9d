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

use hdf5::types::VarLenUnicode;

use crate::carrier::Carrier;
use crate::error::{Error, Result};
use crate::kernel::Kernel;
use crate::model::{Model, Provenance};
use crate::spline::{Normalisation, Spline};

const FORMAT: &str = "volspline-model";

fn text(s: &str) -> VarLenUnicode {
    s.parse().unwrap_or_default()
}

/// Writes `model` to `path` (an HDF5 file, created or truncated).
pub fn write_model(path: &Path, model: &Model) -> Result<()> {
    let h5 = |e: hdf5::Error| Error::hdf5(path, e);
    let f = hdf5::File::create(path).map_err(h5)?;
    let sp = &model.spline;
    let dim = sp.kernel.dim();
    let n = sp.len();
    let put_str = |name: &str, v: &str| -> Result<()> {
        f.new_attr::<VarLenUnicode>().create(name).map_err(h5)?.write_scalar(&text(v)).map_err(h5)
    };
    put_str("format", FORMAT)?;
    f.new_attr_builder().with_data(&[1i64]).create("format_version").map_err(h5)?;
    f.new_attr_builder().with_data(&[dim as i64]).create("kernel_dim").map_err(h5)?;
    f.new_attr_builder().with_data(&[sp.kernel.order() as i64]).create("kernel_order").map_err(h5)?;
    put_str("kernel", &sp.kernel.name())?;
    put_str("carrier", &model.carrier.to_string())?;
    f.new_attr_builder().with_data(&sp.norm.centre).create("normalisation_centre").map_err(h5)?;
    f.new_attr_builder().with_data(&[sp.norm.scale]).create("normalisation_scale").map_err(h5)?;
    let p = &model.provenance;
    put_str("input", &p.input)?;
    put_str("solver", &p.solver)?;
    put_str("volspline_version", &p.version)?;
    for (name, v) in [
        ("points_read", p.points_read as i64),
        ("duplicates_merged", p.duplicates_merged as i64),
        ("ranks", p.ranks as i64),
        ("threads", p.threads as i64),
    ] {
        f.new_attr_builder().with_data(&[v]).create(name).map_err(h5)?;
    }
    f.new_attr_builder().with_data(&[p.residual]).create("residual").map_err(h5)?;
    f.new_attr_builder().with_data(&p.box_lo).create("data_box_lo").map_err(h5)?;
    f.new_attr_builder().with_data(&p.box_hi).create("data_box_hi").map_err(h5)?;
    let stages: Vec<&str> = p.timings.iter().map(|(s, _)| s.as_str()).collect();
    put_str("timing_stages", &stages.join(","))?;
    let secs: Vec<f64> = p.timings.iter().map(|(_, t)| *t).collect();
    f.new_attr_builder().with_data(&secs).create("timing_seconds").map_err(h5)?;

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
    debug_assert_eq!(n, sp.centres.len() / dim);
    f.close().map_err(h5)
}

/// Reads a model written by [`write_model`], checking its format and consistency.
pub fn read_model(path: &Path) -> Result<Model> {
    let h5 = |e: hdf5::Error| Error::hdf5(path, e);
    let bad = |why: String| Error::input(path, "", why);
    if !path.exists() {
        return Err(Error::Io { path: path.into(), reason: "no such file".into() });
    }
    let f = hdf5::File::open(path).map_err(h5)?;
    let get_str = |name: &str| -> Result<String> {
        Ok(f.attr(name)
            .map_err(|_| bad(format!("not a volspline model: attribute '{name}' is missing")))?
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
    if get_str("format")? != FORMAT {
        return Err(bad(format!("not a volspline model (format is not '{FORMAT}')")));
    }
    let version = get_int("format_version")?;
    if version != 1 {
        return Err(bad(format!("model format version {version} is not supported (expected 1)")));
    }
    let kernel = Kernel::new(get_int("kernel_dim")? as usize, get_int("kernel_order")? as usize)
        .map_err(|e| bad(e.to_string()))?;
    let dim = kernel.dim();
    let carrier = Carrier::parse(&get_str("carrier")?, dim).map_err(|e| bad(e.to_string()))?;
    let centre = get_f64s("normalisation_centre")?;
    let scale = get_f64s("normalisation_scale")?;
    if centre.len() != 3 || scale.len() != 1 || !(scale[0] > 0.0) {
        return Err(bad("malformed normalisation".into()));
    }
    let norm = Normalisation { centre: [centre[0], centre[1], centre[2]], scale: scale[0] };
    let ds = |name: &str| -> Result<Vec<f64>> {
        f.dataset(name)
            .map_err(|_| bad(format!("dataset '{name}' is missing")))?
            .read_raw::<f64>()
            .map_err(h5)
    };
    let centres = ds("centres_normalised")?;
    let weights = ds("weights")?;
    let poly = ds("poly_coefficients")?;
    if centres.len() != weights.len() * dim || poly.len() != kernel.poly_count() {
        return Err(bad(format!(
            "inconsistent sizes: {} centre values, {} weights, {} polynomial coefficients for kernel {}",
            centres.len(),
            weights.len(),
            poly.len(),
            kernel.name()
        )));
    }
    if centres.iter().chain(&weights).chain(&poly).any(|v| !v.is_finite()) {
        return Err(bad("the model holds non-finite numbers".into()));
    }
    let box3 = |name: &str| -> Result<[f64; 3]> {
        let v = get_f64s(name)?;
        if v.len() != 3 || v.iter().any(|x| !x.is_finite()) {
            return Err(bad(format!("attribute '{name}' must hold 3 finite numbers")));
        }
        Ok([v[0], v[1], v[2]])
    };
    let (box_lo, box_hi) = (box3("data_box_lo")?, box3("data_box_hi")?);
    let stages = get_str("timing_stages").unwrap_or_default();
    let secs = get_f64s("timing_seconds").unwrap_or_default();
    let provenance = Provenance {
        input: get_str("input").unwrap_or_default(),
        box_lo,
        box_hi,
        points_read: get_int("points_read").unwrap_or(0) as usize,
        duplicates_merged: get_int("duplicates_merged").unwrap_or(0) as usize,
        solver: get_str("solver").unwrap_or_default(),
        residual: get_f64s("residual").ok().and_then(|v| v.first().copied()).unwrap_or(f64::NAN),
        ranks: get_int("ranks").unwrap_or(0) as usize,
        threads: get_int("threads").unwrap_or(0) as usize,
        timings: stages.split(',').filter(|s| !s.is_empty()).map(String::from).zip(secs).collect(),
        version: get_str("volspline_version").unwrap_or_default(),
    };
    Ok(Model { carrier, spline: Spline { kernel, centres, weights, poly, norm }, provenance })
}
