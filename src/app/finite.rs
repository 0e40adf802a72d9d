//! Finite results or a clear error: a solve whose solution or residual is not finite, and a grid
//! on which f overflows, are refused with the likely cause (the data's scale, the carrier's
//! magnitude) instead of writing NaN volumes, empty meshes and models that cannot be read back.
//!
//! f = f_c - U grows like the square of the distance from the data (a ball carrier) or like the
//! distance (the spline's kernel terms), so on a box its largest magnitudes are at the corners:
//! |x - c|^2 and sum_i |w_i| |x - c_i| are convex and take their maxima on a box at a vertex. The
//! grid is therefore checked at its eight corners before any slab is evaluated, and a slab's
//! values can be checked again before they are written ([`check_slab`]).
//!
//! A fitted model must also be a bounded solid: f < 0 far from the data, where the carrier's
//! sign decides ([`check_bounded`]). With the kernel r (and the compactly supported kernels) U
//! grows at most linearly there and the carrier's quadratic decay wins. With r^3 the polynomial
//! part of U is quadratic, like every quadric-based carrier, and can absorb the carrier's far
//! field: the fit can then come out inside-out (f > 0 everywhere far away, a torus's tube
//! negative). The surface is still the fitted one (curvature tests use such fits), so this is a
//! warning in the report and on standard error, not a refusal.

use std::path::Path;

use super::fit::Fitted;
use crate::contour::SectionFit;
use crate::error::{Error, Result};
use crate::grid::Grid;
use crate::par::{agree, Comm};
use crate::spline::hygiene::Prepared;
use crate::spline::{Field, Model};

/// Largest magnitude in `v` (NaN counts as infinite).
pub(super) fn reach(v: &[f64]) -> f64 {
    v.iter().fold(0.0f64, |a, &b| if b.is_nan() { f64::INFINITY } else { a.max(b.abs()) })
}

/// Refuses a fit whose solution (weights, polynomial coefficients) or residual is not finite,
/// naming the carrier's values at the data and the data's coordinates. Identical on every rank
/// (the solution and the residual are).
pub fn check_fit(fitted: &Fitted, prep: &Prepared) -> Result<()> {
    let solution_ok = std::iter::once(&fitted.spline)
        .chain(&fitted.coarse)
        .all(|s| s.weights.iter().chain(&s.poly).all(|v| v.is_finite()));
    if solution_ok && fitted.residual.is_finite() {
        return Ok(());
    }
    let what = if solution_ok { "the residual of the solve" } else { "the solution" };
    let coords = reach(&prep.box_lo).max(reach(&prep.box_hi));
    Err(Error::Numerical(format!(
        "{what} is not finite: the carrier's values at the data reach {:e} and the data's coordinates \
         {coords:e}, beyond what the solve can represent; rescale the data (or use a carrier of smaller \
         magnitude)",
        reach(&prep.values)
    )))
}

/// Whether a model is negative far from the data: f is evaluated at the 8 corners and 6 face
/// centres of the data's box grown by 4 half-diagonals beyond each side. The growth is the same
/// on every axis: the fitted ball carrier is as wide as the box's diagonal on every axis (the
/// fitted ellipsoids lie within it), so a box grown in proportion to its sides (9 times each)
/// left the far points of a long, thin scan inside the ball, where f > 0 is right. Returns a
/// warning naming the first place where f >= 0 and how many of the 14 are not negative, or None
/// for a bounded solid. The same on every rank (every rank holds the whole model).
pub fn check_bounded(model: &Model) -> Option<String> {
    let (lo, hi) = (model.provenance.box_lo, model.provenance.box_hi);
    let c: Vec<f64> = (0..3).map(|d| 0.5 * (lo[d] + hi[d])).collect();
    let half_diagonal = 0.5 * crate::spline::hygiene::diagonal(&lo, &hi);
    let h: Vec<f64> =
        (0..3).map(|d| (0.5 * (hi[d] - lo[d]) + 4.0 * half_diagonal).max(f64::MIN_POSITIVE)).collect();
    let mut far = Vec::with_capacity(14);
    for corner in 0..8 {
        far.push(
            (0..3).map(|d| c[d] + if corner >> d & 1 == 1 { h[d] } else { -h[d] }).collect::<Vec<f64>>(),
        );
    }
    for d in 0..3 {
        for s in [-1.0, 1.0] {
            let mut p = c.clone();
            p[d] += s * h[d];
            far.push(p);
        }
    }
    let values: Vec<f64> = far.iter().map(|p| model.eval(p)).collect();
    let bad = values.iter().filter(|v| !(**v < 0.0)).count();
    let first = values.iter().position(|v| !(*v < 0.0))?;
    let (p, v) = (&far[first], values[first]);
    let what = if bad == far.len() {
        "inside and outside are swapped (f > 0 in every direction far away)".to_string()
    } else {
        format!("f >= 0 in {bad} of {} directions far away", far.len())
    };
    // the carrier falls off like -|x|^2; a polynomial part of degree 2 or more can follow that
    // growth and cancel it, one of degree 1 (the kernel r's, Wendland's) cannot, nor can the
    // weights' far field, so there the cause is the size of the coefficients
    let kernel = &model.spline.kernel;
    let (kernel_name, degree) = (kernel.name(), kernel.order().saturating_sub(1));
    let why = if degree >= 2 {
        format!(
            "kernel {kernel_name}'s polynomial part (degree {degree}) absorbed the carrier's growth; \
             the kernel r (the default) keeps the carrier's sign"
        )
    } else {
        format!(
            "kernel {kernel_name}'s polynomial part is of degree {degree}, which cannot follow the \
             carrier's quadratic fall, so the spline's coefficients are large enough to outgrow it: a \
             badly conditioned fit (see the residual and the spread of the data's spacing)"
        )
    };
    Some(format!(
        "the fitted solid is not bounded: f = {v:.3e} at ({:.4e}, {:.4e}, {:.4e}), far from the data, \
         where the carrier should make it negative; {what}. The surface f = 0 is as fitted, but the \
         volume's sign is not the solid's: {why}",
        p[0], p[1], p[2]
    ))
}

/// Refuses contour sections whose solution or residual is not finite, naming the first such slice
/// and the data's coordinates. Identical on every rank (every rank holds every section).
/// `lines`: the line of the contour file `path` that opens each section.
pub fn check_sections(
    path: &Path,
    lines: &[usize],
    fits: &[SectionFit],
    lo: &[f64],
    hi: &[f64],
) -> Result<()> {
    let bad = fits.iter().position(|f| {
        let s = &f.spline;
        !f.residual.is_finite() || !s.weights.iter().chain(&s.poly).all(|v| v.is_finite())
    });
    let Some(i) = bad else { return Ok(()) };
    Err(Error::input(
        path,
        format!("line {}", lines[i]),
        format!(
            "the solution of this slice's spline is not finite (residual {:e}): the data's coordinates reach \
             {:e}, beyond what the solve can represent; rescale the data",
            fits[i].residual,
            reach(lo).max(reach(hi))
        ),
    ))
}

/// Refuses a grid whose origin or spacing is not finite, or on whose corners `field` is not finite
/// (where f is largest, see the module doc). Collective: every rank agrees.
pub fn check_grid_field(comm: &dyn Comm, field: &dyn Field, grid: &Grid) -> Result<()> {
    let local = (|| {
        let far: Vec<f64> =
            (0..3).map(|d| grid.origin[d] + grid.spacing[d] * (grid.dims[d] - 1) as f64).collect();
        if grid.origin.iter().chain(&grid.spacing).chain(&far).any(|v| !v.is_finite()) {
            return Err(Error::Usage(format!(
                "the grid is not representable: origin {:?}, spacing {:?}; choose a smaller --margin, or with eval and morph --bounds nearer the data",
                grid.origin, grid.spacing
            )));
        }
        let corners = Grid {
            dims: [2, 2, 2],
            origin: grid.origin,
            spacing: [far[0] - grid.origin[0], far[1] - grid.origin[1], far[2] - grid.origin[2]],
        };
        let values = field.eval_layers(&corners, 0, 2);
        if values.iter().all(|v| v.is_finite()) {
            return Ok(());
        }
        Err(Error::Numerical(format!(
            "f is not finite at the grid's corners (the grid reaches coordinates of {:e}): the carrier's \
             magnitude overflows so far from the data; choose a smaller --margin (with eval and morph, --bounds \
             nearer the data) or rescale the data",
            reach(&grid.origin).max(reach(&far))
        )))
    })();
    agree(comm, local)
}

/// Refuses a slab of evaluated values that holds a non-finite one. Collective: every rank agrees,
/// so that no rank writes while another refuses.
pub fn check_slab(comm: &dyn Comm, values: &[f64]) -> Result<()> {
    let local = match values.iter().position(|v| !v.is_finite()) {
        None => Ok(()),
        Some(i) => Err(Error::Numerical(format!(
            "the evaluated volume holds a non-finite value ({} at node {i} of rank {}'s slab): the \
             data's scale or the carrier's magnitude overflows on this grid; rescale the data or choose \
             --bounds nearer it",
            values[i],
            comm.rank()
        ))),
    };
    agree(comm, local)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::par::Solo;
    use crate::spline::{Carrier, Kernel, Model, Normalisation, Provenance, Spline};

    fn ball_model() -> Model {
        Model {
            carrier: Carrier::parse("ball:0,0,0,1", 3).unwrap(),
            spline: Spline {
                kernel: Kernel::new(3, 2).unwrap(),
                centres: vec![0.0; 3],
                weights: vec![0.0],
                poly: vec![0.0; 4],
                norm: Normalisation { centre: [0.0; 3], scale: 1.0 },
            },
            coarse: Vec::new(),
            provenance: Provenance::default(),
        }
    }

    #[test]
    fn the_unbounded_warning_names_the_cause_the_kernel_allows() {
        // kernel r, a ball of radius 1 and a linear part 100 x: positive far along +x
        let mut m = ball_model();
        m.provenance.box_lo = [-1.0; 3];
        m.provenance.box_hi = [1.0; 3];
        assert_eq!(check_bounded(&m), None);
        m.spline.poly[1] = 100.0;
        let w = check_bounded(&m).expect("positive far along +x");
        assert!(w.contains("f >= 0 in"), "{w}");
        assert!(w.contains("degree 1, which cannot follow"), "{w}");
        assert!(!w.contains("absorbed"), "{w}");
        // kernel r3 (polynomial part of degree 2) with a quadratic part (f = f_c - U) that
        // outgrows the ball: positive everywhere far away
        let mut m = ball_model();
        m.provenance.box_lo = [-1.0; 3];
        m.provenance.box_hi = [1.0; 3];
        m.spline.kernel = Kernel::new(3, 3).unwrap();
        m.spline.poly = vec![0.0; m.spline.kernel.poly_count()];
        for (i, e) in m.spline.kernel.monomials().iter().enumerate() {
            if e.contains(&2) {
                m.spline.poly[i] = -2.0;
            }
        }
        let w = check_bounded(&m).expect("the quadratic part outgrows the ball");
        assert!(w.contains("inside and outside are swapped"), "{w}");
        assert!(w.contains("kernel r3's polynomial part (degree 2) absorbed"), "{w}");
    }

    #[test]
    fn far_grids_are_refused_near_ones_accepted() {
        let m = ball_model();
        let near = Grid { dims: [5, 5, 5], origin: [-2.0; 3], spacing: [1.0; 3] };
        check_grid_field(&Solo, &m, &near).unwrap();
        let far = Grid { dims: [5, 5, 5], origin: [-1e300; 3], spacing: [5e299; 3] };
        let e = check_grid_field(&Solo, &m, &far).unwrap_err().to_string();
        assert!(e.contains("not finite at the grid's corners"), "{e}");
        let huge = Grid { dims: [5, 5, 5], origin: [-1e308; 3], spacing: [1e308; 3] };
        let e = check_grid_field(&Solo, &m, &huge).unwrap_err().to_string();
        assert!(e.contains("not representable"), "{e}");
    }

    #[test]
    fn sections_with_nan_are_refused() {
        let fit = |residual: f64, w: f64| SectionFit {
            carrier: Carrier::parse("ball:0,0,1", 2).unwrap(),
            spline: Spline {
                kernel: Kernel::new(2, 2).unwrap(),
                centres: vec![0.0; 2],
                weights: vec![w],
                poly: vec![0.0; 3],
                norm: Normalisation { centre: [0.0; 3], scale: 1.0 },
            },
            points: 1,
            merged: 0,
            residual,
            max_abs_at_points: 0.0,
        };
        let (path, lines) = (Path::new("c.txt"), [1, 7]);
        check_sections(path, &lines, &[fit(1e-16, 1.0), fit(0.0, 2.0)], &[0.0; 3], &[1.0; 3]).unwrap();
        let e = check_sections(path, &lines, &[fit(1e-16, 1.0), fit(f64::NAN, 2.0)], &[0.0; 3], &[1.0; 3])
            .unwrap_err();
        assert!(e.to_string().contains("c.txt: line 7: the solution of this slice"), "{e}");
        assert!(check_sections(path, &lines, &[fit(0.0, f64::INFINITY)], &[0.0; 3], &[1.0; 3]).is_err());
    }

    #[test]
    fn slabs_with_nan_are_refused() {
        check_slab(&Solo, &[0.0, 1.0]).unwrap();
        let e = check_slab(&Solo, &[0.0, f64::NAN]).unwrap_err().to_string();
        assert!(e.contains("node 1"), "{e}");
    }
}
