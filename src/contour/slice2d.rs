//! The spline of one section: U_i through the section's points in the plane's own coordinates,
//! solved serially on one rank (the systems are small and every slice is independent), and the 2D
//! carrier: a disc round the slice, or the R-union of one disc per contour (bounded by the slice's
//! disc). F_i = f_c,i - U_i >= 0 inside the section. Also serves any dimension through
//! [`fit_values`] (the 1D line splines of the sliced accuracy test in `tests/contours.rs`).

use faer::MatRef;

use crate::error::{Error, Result};
use crate::linalg::dense;
use crate::spline::carrier::Carrier;
use crate::spline::hygiene::{
    after_merging, bounding_box, check_unisolvent, diagonal, merge_duplicates, MIN_SPREAD,
};
use crate::spline::kernel::Kernel;
use crate::spline::{full_system, Normalisation, Spline};

use super::format::Section;

/// The carrier of a section.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SectionCarrier {
    /// One disc round the slice's bounding box (with r^2 ln r any disc gives the same F_i: two discs
    /// differ by a linear function, which the spline reproduces; see `spline::carrier`).
    Disc,
    /// The R-union of one disc per contour (one carrier per contour, united, as suggested by
    /// Savchenko and Pasko, *Reconstruction from contour data and sculpting 3D objects*, 1995),
    /// R-intersected with the slice's disc. The union alone decays far away only as
    /// -(2 - sqrt 2) d^2 and left spurious lobes beyond the data (the cow's head, by half a body
    /// length); the intersection restores the disc's far field without moving anything near the
    /// contours.
    Union,
}

impl SectionCarrier {
    pub fn parse(name: &str) -> Result<Self> {
        match name {
            "disc" | "ball" => Ok(SectionCarrier::Disc),
            "union" => Ok(SectionCarrier::Union),
            other => Err(Error::Usage(format!("unknown --carrier '{other}' (expected disc or union)"))),
        }
    }

    pub fn name(&self) -> &'static str {
        match self {
            SectionCarrier::Disc => "disc",
            SectionCarrier::Union => "union",
        }
    }
}

/// A solved section and how well it interpolates.
#[derive(Debug, Clone, PartialEq)]
pub struct SectionFit {
    pub carrier: Carrier,
    pub spline: Spline,
    /// Points of the section after merging near-duplicates.
    pub points: usize,
    pub merged: usize,
    /// ||M x - b|| / ||b|| of the bordered system.
    pub residual: f64,
    /// max |F_i| at the section's points (0 for an exact interpolant).
    pub max_abs_at_points: f64,
}

/// The spline through `values` at `points` (`kernel.dim()` coordinates each): normalised, checked
/// for unisolvency, solved by faer's blocked LU with partial pivoting on this thread (the slices
/// of a rank are solved side by side on its threads). A pivot below 1e-14 n times the largest
/// entry is refused as singular, as the serial oracle does. Returns the spline and the relative
/// residual.
pub fn fit_values(kernel: &Kernel, points: &[f64], values: &[f64]) -> Result<(Spline, f64)> {
    let dim = kernel.dim();
    assert_eq!(points.len(), values.len() * dim);
    let (lo, hi) = bounding_box(points, dim);
    let norm = Normalisation::of_box(&lo, &hi);
    let mut centres = vec![0.0; points.len()];
    for (c, p) in centres.chunks_exact_mut(dim).zip(points.chunks_exact(dim)) {
        norm.apply(p, c);
    }
    check_unisolvent(kernel, &centres)?;
    let n = values.len() + kernel.poly_count();
    let (data, b) = full_system(kernel, &centres, values);
    let m = MatRef::from_column_major_slice(&data, n, n);
    let x = dense::lu_solve_blocked(m, &b)?;
    let residual = dense::relative_residual(m, &x, &b);
    Ok((Spline::from_solution(*kernel, centres, &x, norm), residual))
}

/// The largest relative residual ||M x - b|| / ||b|| a slice's solve may leave: a well-posed slice
/// solves to 1e-15..1e-12, and a system whose pivots pass the singularity test but whose
/// residual is far above this (two points 1e-11 of the diagonal apart, left unmerged with
/// --merge-tol 0, left 4e4) has a solution that interpolates nothing.
pub const MAX_RESIDUAL: f64 = 1e-6;

/// Consecutive points of a contour a median step apart shorter than this fraction of the slice's
/// diagonal, or a shortest step shorter than [`CLOSE_STEP`] of it, are the likely cause of a
/// singular slice system.
const DENSE_STEP: f64 = 1.0 / 300.0;
const CLOSE_STEP: f64 = 1e-4;

/// Why a slice's system may be singular when its contours hold points very close together: the
/// median and the shortest step between consecutive points as fractions of the slice's diagonal
/// `diag`, and what to do (the --merge-tol that merges the closest); empty where the steps are
/// not that short.
fn dense_hint(section: &Section, diag: f64) -> String {
    let mut steps: Vec<f64> = section
        .contours
        .iter()
        .flat_map(|c| (0..c.len()).map(move |i| (c[i], c[(i + 1) % c.len()])))
        .map(|(p, q)| ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)).sqrt() / diag)
        .filter(|d| *d > 0.0)
        .collect();
    if steps.is_empty() || !diag.is_finite() {
        return String::new();
    }
    steps.sort_by(f64::total_cmp);
    let (median, shortest) = (steps[steps.len() / 2], steps[0]);
    if median >= DENSE_STEP && shortest >= CLOSE_STEP {
        return String::new();
    }
    // the power of ten at or above twice the shortest step
    let tol = 10f64.powf((2.0 * shortest).log10().ceil());
    format!(
        "; its contours hold points closer together than the spline's system can tell apart in double \
         precision (consecutive points a median 1/{:.0} of the slice's diagonal apart, the closest two \
         1/{:.0}): merge close points with --merge-tol {tol:e} or more, or thin the contours (every k-th \
         point)",
        1.0 / median,
        1.0 / shortest
    )
}

/// The disc round a 2D point set: centre of the bounding box, radius half its diagonal.
fn disc_around(points: &[f64]) -> Carrier {
    let (lo, hi) = bounding_box(points, 2);
    Carrier::AutoBall.resolve(&lo, &hi, &[])
}

/// Fits the section: merges points of the section closer than `merge_tol` times its diagonal,
/// builds the carrier and solves for U_i with the values r = f_c,i at the points.
pub fn fit_section(
    section: &Section,
    kernel: &Kernel,
    carrier: SectionCarrier,
    merge_tol: f64,
) -> Result<SectionFit> {
    assert_eq!(kernel.dim(), 2, "sections are two-dimensional");
    let where_ = || format!("the slice of line {}", section.line);
    let raw: Vec<f64> = section.contours.iter().flatten().flat_map(|p| [p[0], p[1]]).collect();
    let (lo, hi) = bounding_box(&raw, 2);
    let diag = diagonal(&lo, &hi);
    if !diag.is_finite() || (diag > 0.0 && diag < MIN_SPREAD) {
        return Err(Error::Numerical(format!(
            "{}: the section's spread is not representable (its diagonal is {diag:e}; squared distances \
             must neither overflow nor fall below {:e}); rescale the data",
            where_(),
            MIN_SPREAD * MIN_SPREAD
        )));
    }
    let (points, merged) = merge_duplicates(&raw, 2, merge_tol * diag);
    let carrier = match carrier {
        SectionCarrier::Disc => disc_around(&points),
        SectionCarrier::Union => {
            let discs: Vec<Carrier> = section
                .contours
                .iter()
                .map(|c| disc_around(&c.iter().flat_map(|p| [p[0], p[1]]).collect::<Vec<f64>>()))
                .collect();
            let union =
                discs.into_iter().reduce(|a, b| Carrier::Union(Box::new(a), Box::new(b))).expect("a contour");
            Carrier::Intersection(Box::new(union), Box::new(disc_around(&points)))
        }
    };
    if let Some(deg) = carrier.polynomial_degree() {
        if deg < kernel.order() {
            return Err(Error::Usage(format!(
                "{}: a single disc is a polynomial of degree {deg}, which kernel {} reproduces exactly \
                 (F would vanish); use the kernel r2log or --carrier union with several contours",
                where_(),
                kernel.name()
            )));
        }
    }
    let values: Vec<f64> = points.chunks_exact(2).map(|p| carrier.eval(p)).collect();
    if let Some(bad) = values.iter().find(|v| !v.is_finite()) {
        return Err(Error::Numerical(format!(
            "{}: the carrier '{carrier}' is not finite at the section's points (a value is {bad}): its \
             squares overflow at this scale; rescale the data",
            where_()
        )));
    }
    let total = raw.len() / 2;
    let (spline, residual) = fit_values(kernel, &points, &values).map_err(|e| {
        match after_merging(e, merged, total, merge_tol) {
            Error::Numerical(m) => {
                Error::Numerical(format!("{}: {m}{}", where_(), dense_hint(section, diag)))
            }
            other => other,
        }
    })?;
    if !(residual <= MAX_RESIDUAL) {
        return Err(Error::Numerical(format!(
            "{}: the slice's system solved to a relative residual of {residual:.3e}, above {MAX_RESIDUAL:e}: it \
             is too close to singular for its solution to be trusted{}",
            where_(),
            dense_hint(section, diag)
        )));
    }
    let max_abs_at_points =
        points.chunks_exact(2).map(|p| (carrier.eval(p) - spline.eval(p)).abs()).fold(0.0, f64::max);
    Ok(SectionFit { carrier, spline, points: values.len(), merged, residual, max_abs_at_points })
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{DMat3, DVec3};

    fn section(contours: Vec<Vec<[f64; 2]>>) -> Section {
        Section { line: 7, origin: DVec3::ZERO, frame: DMat3::IDENTITY, kind: "z", contours }
    }

    fn circle(cx: f64, cy: f64, r: f64, n: usize) -> Vec<[f64; 2]> {
        (0..n)
            .map(|k| {
                let a = std::f64::consts::TAU * k as f64 / n as f64;
                [cx + r * a.cos(), cy + r * a.sin()]
            })
            .collect()
    }

    #[test]
    fn a_slice_solved_to_a_large_residual_is_refused_with_the_cure() {
        let k = Kernel::new(2, 2).unwrap();
        let square = vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
        let fit = fit_section(&section(vec![square.clone()]), &k, SectionCarrier::Disc, 0.0).unwrap();
        assert!(fit.residual < 1e-12, "{}", fit.residual);
        // a fifth point 1e-11 from a corner, kept apart by --merge-tol 0
        let near = [square, vec![[1e-11, 0.0]]].concat();
        let e =
            fit_section(&section(vec![near.clone()]), &k, SectionCarrier::Disc, 0.0).unwrap_err().to_string();
        assert!(
            e.contains("the slice of line 7: the slice's system solved to a relative residual of"),
            "{e}"
        );
        assert!(e.contains("--merge-tol 1e-10 or more"), "{e}");
        // merged, as by default, it fits
        assert!(fit_section(&section(vec![near]), &k, SectionCarrier::Disc, 1e-6).is_ok());
    }

    #[test]
    fn the_blocked_lu_solves_as_the_oracle_and_refuses_singular_systems() {
        // the bordered r^2 ln r system of 300 points on a wavy closed curve, unevenly spaced
        let k = Kernel::new(2, 2).unwrap();
        let pts: Vec<f64> = (0..300)
            .flat_map(|i| {
                let a = std::f64::consts::TAU * (i as f64 / 300.0).powf(1.3);
                let r = 1.0 + 0.2 * (5.0 * a).sin();
                [r * a.cos(), 0.7 * r * a.sin()]
            })
            .collect();
        let values: Vec<f64> = pts.chunks_exact(2).map(|p| 1.0 - p[0] * p[0] - p[1] * p[1]).collect();
        let (data, b) = full_system(&k, &pts, &values);
        let n = b.len();
        let m = MatRef::from_column_major_slice(&data, n, n);
        let (got, want) = (dense::lu_solve_blocked(m, &b).unwrap(), dense::lu_solve(m, &b).unwrap());
        let scale = want.iter().fold(0.0f64, |s, v| s.max(v.abs()));
        let diff = got.iter().zip(&want).fold(0.0f64, |s, (g, w)| s.max((g - w).abs()));
        assert!(diff < 1e-9 * scale, "{diff} of {scale}");
        assert!(dense::relative_residual(m, &got, &b) < 1e-12);
        // a point given twice: two equal rows and columns
        let mut twice = pts.clone();
        twice.extend_from_slice(&pts[..2]);
        let values: Vec<f64> = twice.chunks_exact(2).map(|p| p[0]).collect();
        let (data, b) = full_system(&k, &twice, &values);
        let m = MatRef::from_column_major_slice(&data, b.len(), b.len());
        let e = dense::lu_solve_blocked(m, &b).unwrap_err().to_string();
        assert!(e.contains("matrix is singular: no pivot in column"), "{e}");
    }

    #[test]
    fn a_circle_is_reproduced_inside_positive() {
        let k = Kernel::new(2, 2).unwrap();
        let fit =
            fit_section(&section(vec![circle(1.0, 2.0, 0.5, 40)]), &k, SectionCarrier::Disc, 1e-6).unwrap();
        assert!(fit.residual < 1e-12 && fit.max_abs_at_points < 1e-10, "{fit:?}");
        let f = |x: f64, y: f64| fit.carrier.eval(&[x, y]) - fit.spline.eval(&[x, y]);
        assert!(f(1.0, 2.0) > 0.0 && f(1.0, 2.6) < 0.0 && f(2.0, 2.0) < 0.0);
        // between the points the zero set stays on the circle
        let a = 0.5 * std::f64::consts::TAU / 40.0;
        assert!(f(1.0 + 0.5 * a.cos(), 2.0 + 0.5 * a.sin()).abs() < 1e-4);
    }

    #[test]
    fn disc_and_union_carriers_and_their_failures() {
        let k = Kernel::new(2, 2).unwrap();
        let two = section(vec![circle(-1.0, 0.0, 0.5, 20), circle(1.0, 0.0, 0.5, 20)]);
        for c in [SectionCarrier::Disc, SectionCarrier::Union] {
            let fit = fit_section(&two, &k, c, 1e-6).unwrap();
            let f = |x: f64| fit.carrier.eval(&[x, 0.0]) - fit.spline.eval(&[x, 0.0]);
            assert!(f(-1.0) > 0.0 && f(1.0) > 0.0 && f(0.0) < 0.0, "{c:?}");
        }
        // r4log reproduces a disc, so a single disc is refused; the union is not a polynomial
        let k3 = Kernel::new(2, 3).unwrap();
        assert!(matches!(fit_section(&two, &k3, SectionCarrier::Disc, 1e-6), Err(Error::Usage(_))));
        assert!(fit_section(&two, &k3, SectionCarrier::Union, 1e-6).is_ok());
        let line = section(vec![vec![[0.0, 0.0], [1.0, 1.0], [2.0, 2.0], [3.0, 3.0]]]);
        let e = fit_section(&line, &k, SectionCarrier::Disc, 1e-6).unwrap_err();
        assert!(e.to_string().contains("line 7") && e.to_string().contains("line"), "{e}");
    }
}
