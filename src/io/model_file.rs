//! The model file `PREFIX.model.h5`: everything needed to evaluate f = f_c - U anywhere without
//! solving again, and how it was made. Written and read serially by one rank.
//!
//! Layout (all in the root group):
//! - attributes `format` = "volspline-model", `format_version` (1, or 2 for a compactly supported
//!   kernel), `kernel_dim` (n), `kernel_order` (m; 2 for a Wendland kernel, whose polynomial part
//!   is linear), `kernel` (name, e.g. "r" or "wendland2 (support 0.08)"), for a compactly
//!   supported kernel `kernel_compact` (`wendland0`, `wendland2` or `wendland4`) and
//!   `kernel_support` (R, normalised coordinates), for a smoothing spline `kernel_smoothing`
//!   (lambda, see `Kernel::nugget`; it shaped the weights and plays no part in evaluation), `carrier` (spec, see `carrier`),
//!   `normalisation_centre` (3 doubles), `normalisation_scale`, and the provenance:
//!   `input`, `data_box_lo`, `data_box_hi` (the input points' bounding box), `points_read`, `duplicates_merged`,
//!   `data_points` (how many of the finest level's centres, first in order, are the data points;
//!   absent in files written before it was recorded), `solver`, `residual`, `ranks`, `threads`,
//!   `volspline_version`, `timing_stages` (comma-separated), `timing_seconds`;
//! - datasets `centres` (N x n, input coordinates), `centres_normalised` (N x n, the ones the
//!   system was built from), `weights` (lambda, N), `poly_coefficients` (c, k) and
//!   `poly_exponents` (k x 3, the monomial of each c).
//!
//! A file without `kernel_compact` holds a Green's-function kernel, as every version 1 file does.
//! Models with a compactly supported kernel are written as version 2 so that a reader that knows
//! only version 1 refuses them instead of taking them for a Green's-function spline.
//!
//! Version 3 adds coarse levels (f = f_c - U_0 - ... - U_L, see [`crate::spline::model`]): the
//! attribute `coarse_levels` (L) and, for each coarse level l = 0..L-1 in order of evaluation, the
//! kernel attributes and the datasets above with the prefix `coarse{l}_` (`coarse0_kernel`,
//! `coarse0_weights`, ...). The unprefixed ones are the finest level. All levels share the
//! normalisation. A file without `coarse_levels` is a model of one level.

use std::path::Path;

use super::h5::{format_of, Attrs};
use crate::error::{Error, Result};
use crate::spline::carrier::Carrier;
use crate::spline::kernel::Kernel;
use crate::spline::model::Model;
use crate::spline::{Normalisation, Spline};

pub const FORMAT: &str = "volspline-model";

/// Writes `model` to `path` (an HDF5 file, created or truncated).
pub fn write_model(path: &Path, model: &Model) -> Result<()> {
    let h5 = |e: hdf5::Error| Error::hdf5(path, e);
    let f = super::h5::create(path)?;
    let a = Attrs { file: &f, path };
    let sp = &model.spline;
    a.put_str("format", FORMAT)?;
    let compact = model.levels().any(|s| s.kernel.is_compact().is_some());
    let version = if !model.coarse.is_empty() {
        3
    } else if compact {
        2
    } else {
        1
    };
    a.put_int("format_version", version)?;
    a.put_str("carrier", &model.carrier.to_string())?;
    a.put_f64s("normalisation_centre", &sp.norm.centre)?;
    a.put_f64s("normalisation_scale", &[sp.norm.scale])?;
    a.put_provenance(&model.provenance)?;
    if !model.coarse.is_empty() {
        a.put_int("coarse_levels", model.coarse.len() as i64)?;
    }
    for (l, s) in model.coarse.iter().enumerate() {
        if s.norm != sp.norm {
            return Err(Error::Numerical("the levels of a model must share one normalisation".into()));
        }
        write_level(&a, &format!("coarse{l}_"), s)?;
    }
    write_level(&a, "", sp)?;
    f.close().map_err(h5)
}

/// One spline's kernel attributes and datasets, their names prefixed with `prefix`.
fn write_level(a: &Attrs<'_>, prefix: &str, sp: &Spline) -> Result<()> {
    let h5 = |e: hdf5::Error| Error::hdf5(a.path, e);
    let f = a.file;
    let dim = sp.kernel.dim();
    a.put_int(&format!("{prefix}kernel_dim"), dim as i64)?;
    a.put_int(&format!("{prefix}kernel_order"), sp.kernel.order() as i64)?;
    a.put_str(&format!("{prefix}kernel"), &sp.kernel.name())?;
    if let Some(w) = sp.kernel.wendland_part() {
        a.put_str(&format!("{prefix}kernel_compact"), w.kind.name())?;
        a.put_f64s(&format!("{prefix}kernel_support"), &[w.support])?;
    }
    if sp.kernel.smoothing() > 0.0 {
        a.put_f64s(&format!("{prefix}kernel_smoothing"), &[sp.kernel.smoothing()])?;
    }
    let mut caller = vec![0.0; sp.centres.len()];
    for (c, pn) in caller.chunks_exact_mut(dim).zip(sp.centres.chunks_exact(dim)) {
        for d in 0..dim {
            c[d] = pn[d] * sp.norm.scale + sp.norm.centre[d];
        }
    }
    let arr2 = |v: &[f64], cols: usize| ndarray::Array2::from_shape_vec((v.len() / cols, cols), v.to_vec());
    let name = |n: &str| format!("{prefix}{n}");
    f.new_dataset_builder()
        .with_data(&arr2(&caller, dim).expect("shape"))
        .create(&*name("centres"))
        .map_err(h5)?;
    f.new_dataset_builder()
        .with_data(&arr2(&sp.centres, dim).expect("shape"))
        .create(&*name("centres_normalised"))
        .map_err(h5)?;
    f.new_dataset_builder().with_data(&sp.weights).create(&*name("weights")).map_err(h5)?;
    f.new_dataset_builder().with_data(&sp.poly).create(&*name("poly_coefficients")).map_err(h5)?;
    let exps: Vec<i64> = sp.kernel.monomials().iter().flat_map(|e| e.map(|x| x as i64)).collect();
    f.new_dataset_builder()
        .with_data(&ndarray::Array2::from_shape_vec((exps.len() / 3, 3), exps).expect("shape"))
        .create(&*name("poly_exponents"))
        .map_err(h5)?;
    Ok(())
}

/// Most coarse levels a model file may declare (the fit writes one).
pub const MAX_COARSE_LEVELS: i64 = 16;

/// Reads a model written by [`write_model`], checking its format and consistency.
pub fn read_model(path: &Path) -> Result<Model> {
    let f = open(path)?;
    let a = Attrs { file: &f, path };
    let carrier = Carrier::parse(&a.str("carrier")?, 3).map_err(|e| a.bad(e.to_string()))?;
    if !carrier.is_resolved() {
        return Err(a.bad(format!("carrier '{carrier}': a stored ball must give its centre and radius")));
    }
    let centre = a.f64s("normalisation_centre")?;
    let scale = a.f64s("normalisation_scale")?;
    let finite = centre.iter().chain(&scale).all(|v| v.is_finite());
    if centre.len() != 3 || scale.len() != 1 || !(scale[0] > 0.0) || !finite {
        return Err(
            a.bad("malformed normalisation: a centre of 3 finite numbers and a finite positive scale")
        );
    }
    let norm = Normalisation { centre: [centre[0], centre[1], centre[2]], scale: scale[0] };
    let levels = if f.attr("coarse_levels").is_ok() { a.int("coarse_levels")? } else { 0 };
    if !(0..=MAX_COARSE_LEVELS).contains(&levels) {
        return Err(a.bad(format!("coarse_levels is {levels}, not a count from 0 to {MAX_COARSE_LEVELS}")));
    }
    let coarse =
        (0..levels).map(|l| read_level(&a, &format!("coarse{l}_"), norm)).collect::<Result<Vec<Spline>>>()?;
    let spline = read_level(&a, "", norm)?;
    let provenance = a.provenance()?;
    Ok(Model { carrier, spline, coarse, provenance })
}

/// One spline stored by [`write_level`] under `prefix`, checked.
fn read_level(a: &Attrs<'_>, prefix: &str, norm: Normalisation) -> Result<Spline> {
    let f = a.file;
    let name = |n: &str| format!("{prefix}{n}");
    let level = if prefix.is_empty() { String::new() } else { format!("level '{prefix}': ") };
    let bad = |why: String| a.bad(format!("{level}{why}"));
    let (dim, order) = (a.int(&name("kernel_dim"))?, a.int(&name("kernel_order"))?);
    let kernel = if f.attr(&name("kernel_compact")).is_ok() {
        let support = a.f64s(&name("kernel_support"))?;
        if support.len() != 1 || (dim, order) != (3, 2) {
            return Err(bad("malformed compactly supported kernel".into()));
        }
        Kernel::wendland(&a.str(&name("kernel_compact"))?, support[0])
    } else if dim == 3 && (order == 2 || order == 3) {
        Kernel::new(3, order as usize)
    } else {
        return Err(bad(format!(
            "kernel_dim {dim} and kernel_order {order} are not a kernel of this format (dimension 3, \
             order 2 for r or 3 for r3)"
        )));
    }
    .map_err(|e| bad(e.to_string()))?;
    let kernel = if f.attr(&name("kernel_smoothing")).is_ok() {
        match a.f64s(&name("kernel_smoothing"))?[..] {
            [lambda] => kernel.with_smoothing(lambda).map_err(|e| bad(e.to_string()))?,
            _ => return Err(bad("kernel_smoothing must hold one number".into())),
        }
    } else {
        kernel
    };
    let dim = kernel.dim();
    let n = a.expect_shape(&name("centres_normalised"), &[None, Some(3)])?[0];
    if n == 0 {
        return Err(bad("the model has no centres".into()));
    }
    a.expect_shape(&name("weights"), &[Some(n)])?;
    a.expect_shape(&name("poly_coefficients"), &[Some(kernel.poly_count())])?;
    let centres = a.dataset_f64(&name("centres_normalised"))?;
    let weights = a.dataset_f64(&name("weights"))?;
    let poly = a.dataset_f64(&name("poly_coefficients"))?;
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
    check_magnitudes(a, &centres, &weights, &poly)?;
    Ok(Spline { kernel, centres, weights, poly, norm })
}

/// The normalised centres lie in the unit ball (the data's box is scaled to half-diagonal 1):
/// anything much beyond it was not written by volspline.
const MAX_NORMALISED: f64 = 1e3;

/// Refuses weights and coefficients whose sum overflows (U(x) adds them up, times kernel values
/// of order one near the data) and centres far outside the unit ball. Shared with the contour
/// model reader.
pub(crate) fn check_magnitudes(a: &Attrs<'_>, centres: &[f64], weights: &[f64], poly: &[f64]) -> Result<()> {
    if centres.iter().any(|c| c.abs() > MAX_NORMALISED) {
        return Err(a.bad(format!(
            "normalised centres beyond {MAX_NORMALISED:e}: the model was edited or is corrupt"
        )));
    }
    let sum = |v: &[f64]| v.iter().map(|x| x.abs()).sum::<f64>();
    // the factor leaves room for the kernel's values across the normalised box
    if !(1e6 * (sum(weights) + sum(poly))).is_finite() {
        return Err(a.bad(
            "the weights or polynomial coefficients are so large that evaluating the spline overflows",
        ));
    }
    Ok(())
}

/// Opens a model file after checking its `format` and that its `format_version` is 1, 2 or 3.
fn open(path: &Path) -> Result<hdf5::File> {
    if format_of(path)? != FORMAT {
        return Err(Error::input(path, "", format!("not a volspline model (format is not '{FORMAT}')")));
    }
    let file = hdf5::File::open(path).map_err(|e| Error::hdf5(path, e))?;
    let version = Attrs { file: &file, path }.int("format_version")?;
    if !(1..=3).contains(&version) {
        let why = format!("volspline model format version {version} is not supported (expected 1, 2 or 3)");
        return Err(Error::input(path, "", why));
    }
    Ok(file)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spline::model::Provenance;

    fn model(kernel: Kernel) -> Model {
        let centres = vec![0.1, 0.2, 0.3, -0.4, 0.5, 0.6, 0.7, -0.8, 0.9, 0.0, 0.1, -0.5];
        Model {
            carrier: Carrier::parse("ball:0,0,0,2", 3).unwrap(),
            spline: Spline {
                kernel,
                centres,
                weights: vec![1.5, -2.0, 0.25, 3.0],
                poly: (0..kernel.poly_count()).map(|i| 0.1 * (i + 1) as f64).collect(),
                norm: Normalisation { centre: [1.0, 2.0, 3.0], scale: 4.5 },
            },
            coarse: Vec::new(),
            provenance: Provenance { box_lo: [-1.0; 3], box_hi: [1.0; 3], ..Default::default() },
        }
    }

    fn temp(name: &str) -> std::path::PathBuf {
        std::env::temp_dir().join(format!("volspline-model-file-{}-{name}.h5", std::process::id()))
    }

    #[test]
    fn kernels_round_trip_through_the_model_file() {
        let kernels = [
            Kernel::new(3, 2).unwrap(),
            Kernel::new(3, 3).unwrap(),
            Kernel::wendland("wendland0", 0.3).unwrap(),
            Kernel::wendland("wendland2", 0.0800622707907602).unwrap(),
            Kernel::wendland("wendland4", 1.25).unwrap(),
            // a smoothing spline keeps its lambda
            Kernel::new(3, 2).unwrap().with_smoothing(0.25).unwrap(),
            Kernel::wendland("wendland2", 0.2).unwrap().with_smoothing(1e-3).unwrap(),
        ];
        for (i, k) in kernels.into_iter().enumerate() {
            let path = temp(&format!("round-trip-{i}"));
            let mut m = model(k);
            m.provenance.data_points = i % 2;
            write_model(&path, &m).unwrap();
            let back = read_model(&path).unwrap();
            let f = hdf5::File::open(&path).unwrap();
            let version = Attrs { file: &f, path: &path }.int("format_version").unwrap();
            // Green's-function models keep the version 1 layout, without the new attributes
            assert_eq!(version, if k.is_compact().is_some() { 2 } else { 1 });
            assert_eq!(f.attr("kernel_compact").is_ok(), k.is_compact().is_some());
            drop(f);
            std::fs::remove_file(&path).unwrap();
            assert_eq!(back.spline.kernel, k, "{}", k.name());
            assert_eq!(back.spline, m.spline);
            assert_eq!(back.carrier, m.carrier);
            assert_eq!(back.provenance.data_points, m.provenance.data_points);
        }
    }

    #[test]
    fn texts_are_byte_arrays_and_variable_length_strings_of_earlier_files_still_read() {
        let path = temp("texts");
        let mut m = model(Kernel::new(3, 2).unwrap());
        m.provenance.input = "scan \u{fc}.xyz".into();
        write_model(&path, &m).unwrap();
        let names = ["format", "carrier", "kernel", "input", "solver", "volspline_version"];
        {
            let f = hdf5::File::open_rw(&path).unwrap();
            let a = Attrs { file: &f, path: &path };
            for name in names {
                // written as UTF-8 bytes (the empty solver as one NUL byte), read back as written
                assert!(f.attr(name).unwrap().dtype().unwrap().is::<u8>(), "{name}");
                let text = a.str(name).unwrap();
                f.delete_attr(name).unwrap();
                let v: hdf5::types::VarLenUnicode = text.parse().unwrap();
                f.new_attr::<hdf5::types::VarLenUnicode>().create(name).unwrap().write_scalar(&v).unwrap();
            }
        }
        let back = read_model(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        assert_eq!(back, m);
    }

    #[test]
    fn malformed_compact_kernels_are_reported() {
        let path = temp("malformed");
        write_model(&path, &model(Kernel::wendland("wendland2", 0.2).unwrap())).unwrap();
        {
            let f = hdf5::File::open_rw(&path).unwrap();
            f.delete_attr("kernel_compact").unwrap();
            Attrs { file: &f, path: &path }.put_str("kernel_compact", "wendland9").unwrap();
        }
        let err = read_model(&path).unwrap_err().to_string();
        assert!(err.contains("wendland9"), "{err}");
        {
            let f = hdf5::File::open_rw(&path).unwrap();
            f.delete_attr("format_version").unwrap();
            Attrs { file: &f, path: &path }.put_int("format_version", 4).unwrap();
        }
        let err = read_model(&path).unwrap_err().to_string();
        assert!(err.contains("version 4"), "{err}");
        std::fs::remove_file(&path).unwrap();
    }

    #[test]
    fn levels_round_trip_and_a_bad_level_shape_is_refused() {
        let path = temp("levels");
        let mut m = model(Kernel::wendland("wendland2", 0.2).unwrap());
        let mut coarse = model(Kernel::new(3, 2).unwrap()).spline;
        coarse.weights.push(0.5);
        coarse.centres.extend_from_slice(&[0.3, 0.3, 0.3]);
        m.coarse = vec![coarse];
        write_model(&path, &m).unwrap();
        assert_eq!(read_model(&path).unwrap(), m);
        {
            let f = hdf5::File::open(&path).unwrap();
            assert_eq!(Attrs { file: &f, path: &path }.int("format_version").unwrap(), 3);
        }
        // one weight fewer than centres in the coarse level
        {
            let f = hdf5::File::open_rw(&path).unwrap();
            f.unlink("coarse0_weights").unwrap();
            f.new_dataset_builder().with_data(&[1.0, 2.0, 3.0, 4.0]).create("coarse0_weights").unwrap();
        }
        let err = read_model(&path).unwrap_err().to_string();
        assert!(err.contains("coarse0_weights"), "{err}");
        // a level count beyond the levels stored
        {
            let f = hdf5::File::open_rw(&path).unwrap();
            f.unlink("coarse0_weights").unwrap();
            f.new_dataset_builder()
                .with_data(&[1.5, -2.0, 0.25, 3.0, 0.5])
                .create("coarse0_weights")
                .unwrap();
            f.delete_attr("coarse_levels").unwrap();
            Attrs { file: &f, path: &path }.put_int("coarse_levels", 2).unwrap();
        }
        let err = read_model(&path).unwrap_err().to_string();
        assert!(err.contains("coarse1_"), "{err}");
        {
            let f = hdf5::File::open_rw(&path).unwrap();
            f.delete_attr("coarse_levels").unwrap();
            Attrs { file: &f, path: &path }.put_int("coarse_levels", -1).unwrap();
        }
        let err = read_model(&path).unwrap_err().to_string();
        assert!(err.contains("coarse_levels is -1"), "{err}");
        std::fs::remove_file(&path).unwrap();
    }
}
