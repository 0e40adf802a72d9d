//! Carrier solids f_c: simple solids whose defining function the volume spline interpolates at the
//! data points, r_i = f_c(P_i). f_c >= 0 inside. The reconstructed solid is f = f_c - U, with the
//! carrier first (why U - f_c would be inside-out: [`crate::spline::model`]). The carrier is the
//! solid's first approximation: near the data U pulls the surface onto the points, far from them
//! f follows f_c minus a polynomial.
//!
//! # Which carriers change the solid
//!
//! The interpolation operator r -> U is linear, and it reproduces every polynomial q of degree
//! <= m - 1: if r_i = q(P_i) then lambda = 0 with c the coefficients of q solves the bordered
//! system, and the solution is unique, so U = q. Two carriers whose difference is such a
//! polynomial therefore give the same solid: U_1 - U_2 = f_c1 - f_c2, so f_c1 - U_1 = f_c2 - U_2.
//! Two balls differ by exactly that for m = 2:
//!
//! ```text
//! (R1^2 - |x - c1|^2) - (R2^2 - |x - c2|^2) = (R1^2 - R2^2 - |c1|^2 + |c2|^2) + 2 x . (c1 - c2),
//! ```
//!
//! a constant plus a linear function (the |x|^2 terms cancel). So with the kernel r (3D) or
//! r^2 ln r (2D) any ball or disc gives the same f, whatever its centre and radius; the automatic
//! ball only has to be one. An ellipsoid with unequal semi-axes differs from a ball by a quadratic
//! and does change the solid, as do R-function carriers. For m = 3 (polynomials of degree <= 2) a
//! ball or ellipsoid is itself reproduced, U = f_c and f = 0 everywhere: `hygiene::prepare`
//! refuses that combination ([`Carrier::polynomial_degree`]).
//!
//! # The fitted ellipsoid
//!
//! Only a carrier's quadratic part shapes the solid (above), and of an ellipsoid only its shape:
//! scaled by s, 1 - Q(x) / s^2 = (1 - Q(x)) / s^2 + (1 - 1 / s^2), a multiple plus a constant, and
//! the values at the off points scale with the gradient, so the solid is the same. Where the data
//! hold the zero set the carrier hardly matters; across a hole in a scan the zero set is the
//! spline's continuation of the field around it, and the carrier's curvature is what that
//! continuation starts from. A ball curves the field alike in every direction. `ellipsoid` fits
//! one to the points: its axes are the principal directions of their scatter (the eigenvectors
//! of their covariance, each signed so that its largest component is positive), its semi-axes half the points' extent along each and its centre the middle of
//! those extents, so it turns with the points (a rotated cloud gets the rotated ellipsoid) and
//! does not depend on their order. `ellipsoid(S)` scales the spread of the semi-axes on a log
//! scale, a_j -> g (a_j / g)^S with g their geometric mean: S = 1 is the fitted ellipsoid, S = 0
//! a ball. A semi-axis is kept at least a thousandth of the largest, so flat data still give a
//! solid. Measured on holed scans of an elongated shape, the fitted
//! shape lifts a cap over a flank that the ball lets sag into the body, and flattens one over the
//! end of the long axis; with the spread scaled by 0.3 to 0.5 most of the one is kept and little
//! of the other, and `ellipsoid(0.3)` is the carrier of the off-surface fit by default
//! (`--carrier auto`).
//!
//! # R-functions
//!
//! Unions, intersections and differences of carriers are made with Rvachev's R-functions (the
//! R_0 system, as in HyperFun):
//!
//! ```text
//! intersection:  f1 & f2 = f1 + f2 - sqrt(f1^2 + f2^2)     >= 0  iff  f1 >= 0 and f2 >= 0
//! union:         f1 | f2 = f1 + f2 + sqrt(f1^2 + f2^2)     >= 0  iff  f1 >= 0 or  f2 >= 0
//! difference:    f1 \ f2 = f1 & (-f2)
//! ```
//!
//! The sign rule of the intersection: if f1, f2 >= 0 then (f1 + f2)^2 = f1^2 + f2^2 + 2 f1 f2 >=
//! f1^2 + f2^2 and f1 + f2 >= 0, so the result is >= 0. If, say, f1 < 0, either f1 + f2 <= 0 and the
//! result is negative, or f1 + f2 > 0, so f2 > 0, f1 f2 < 0 and (f1 + f2)^2 < f1^2 + f2^2: negative
//! again. The union is -((-f1) & (-f2)). The zero set of the result is the boundary of the set
//! operation, and the functions are continuous (smooth away from f1 = f2 = 0) and homogeneous of
//! degree one, so a union of balls still falls off like -|x|^2 far away, only by a smaller factor.
//!
//! Specs (also the canonical text stored in model files, see `Display`):
//! `ball` (automatic: fitted to the data's bounding box), `ball:cx,cy,cz,r` (f = r^2 - |x - c|^2,
//! the FRep sphere), `ellipsoid` and `ellipsoid(S)` (automatic: fitted to the data, above),
//! `ellipsoid:cx,cy,cz,a,b,c` (f = 1 - sum (x_j - c_j)^2 / a_j^2), the same followed by the unit
//! axes u_1, u_2, u_3 one after the other (f = 1 - sum ((x - c) . u_j / a_j)^2; they must be
//! orthonormal to 1e-6), and the R-functions `union(A,B)`, `intersection(A,B)`,
//! `difference(A,B)`. In two dimensions the same
//! specs take two centre coordinates (`ball:cx,cy,r` is a disc).

use std::fmt;

use crate::error::{Error, Result};
use crate::surface::normals::Plane;

/// A carrier solid in `dim` dimensions.
#[derive(Debug, Clone, PartialEq)]
pub enum Carrier {
    /// Placeholder for "fit a ball to the data"; resolved by [`Carrier::resolve`] before use.
    AutoBall,
    Ball {
        centre: Vec<f64>,
        radius: f64,
    },
    /// Placeholder for "fit an ellipsoid to the data" with the spread of its semi-axes scaled by
    /// `spread` (1: as fitted); resolved by [`Carrier::resolve`] before use (see "The fitted
    /// ellipsoid" in the module doc).
    AutoEllipsoid {
        spread: f64,
    },
    /// f = 1 - sum_j ((x - c) . u_j / a_j)^2, with u_j the unit rows of `axes` (`dim` x `dim`, row
    /// by row) or the coordinate axes where `axes` is None.
    Ellipsoid {
        centre: Vec<f64>,
        semi_axes: Vec<f64>,
        axes: Option<Vec<f64>>,
    },
    Union(Box<Carrier>, Box<Carrier>),
    Intersection(Box<Carrier>, Box<Carrier>),
    Difference(Box<Carrier>, Box<Carrier>),
}

impl Carrier {
    /// Parses a carrier spec for `dim`-dimensional data.
    pub fn parse(spec: &str, dim: usize) -> Result<Carrier> {
        let mut p = Parser { s: spec.as_bytes(), pos: 0, spec, dim, depth: 0 };
        let c = p.carrier()?;
        p.skip_ws();
        if p.pos != p.s.len() {
            return Err(p.error("unexpected text after the carrier"));
        }
        Ok(c)
    }

    /// Replaces `AutoBall` by the ball centred on the bounding box `lo`..`hi` with radius half its
    /// diagonal, so every data point is inside (for m = 2 any ball gives the same solid: see "Which
    /// carriers change the solid" in the module doc), and `AutoEllipsoid` by the ellipsoid fitted
    /// to the data `points` (`lo.len()` coordinates per point; see "The fitted ellipsoid").
    pub fn resolve(&self, lo: &[f64], hi: &[f64], points: &[f64]) -> Carrier {
        match self {
            Carrier::AutoBall => {
                let centre: Vec<f64> = lo.iter().zip(hi).map(|(a, b)| 0.5 * a + 0.5 * b).collect();
                let diag = crate::spline::hygiene::diagonal(lo, hi);
                Carrier::Ball { centre, radius: (0.5 * diag).max(f64::MIN_POSITIVE) }
            }
            Carrier::AutoEllipsoid { spread } => fitted_ellipsoid(lo, hi, points, *spread),
            Carrier::Union(a, b) => {
                Carrier::Union(Box::new(a.resolve(lo, hi, points)), Box::new(b.resolve(lo, hi, points)))
            }
            Carrier::Intersection(a, b) => Carrier::Intersection(
                Box::new(a.resolve(lo, hi, points)),
                Box::new(b.resolve(lo, hi, points)),
            ),
            Carrier::Difference(a, b) => {
                Carrier::Difference(Box::new(a.resolve(lo, hi, points)), Box::new(b.resolve(lo, hi, points)))
            }
            other => other.clone(),
        }
    }

    /// Whether every automatic ball has been replaced by a concrete one (a stored model's carrier
    /// must be: only a resolved carrier can be evaluated).
    pub fn is_resolved(&self) -> bool {
        match self {
            Carrier::AutoBall | Carrier::AutoEllipsoid { .. } => false,
            Carrier::Ball { .. } | Carrier::Ellipsoid { .. } => true,
            Carrier::Union(a, b) | Carrier::Intersection(a, b) | Carrier::Difference(a, b) => {
                a.is_resolved() && b.is_resolved()
            }
        }
    }

    /// The degree of f_c when it is a polynomial (balls and ellipsoids: 2), None otherwise. A spline
    /// whose polynomial part reaches that degree reproduces such a carrier exactly, leaving f = 0.
    pub fn polynomial_degree(&self) -> Option<usize> {
        match self {
            Carrier::AutoBall
            | Carrier::AutoEllipsoid { .. }
            | Carrier::Ball { .. }
            | Carrier::Ellipsoid { .. } => Some(2),
            _ => None,
        }
    }

    /// f_c(x); `x` has at least `dim` components. Panics on an unresolved automatic carrier.
    #[inline]
    pub fn eval(&self, x: &[f64]) -> f64 {
        match self {
            Carrier::AutoBall | Carrier::AutoEllipsoid { .. } => {
                panic!("automatic carrier used before Carrier::resolve")
            }
            Carrier::Ball { centre, radius } => {
                let d2: f64 = centre.iter().zip(x).map(|(c, v)| (v - c) * (v - c)).sum();
                radius * radius - d2
            }
            // the fitted ellipsoid of a 3D fit, evaluated at every grid and lattice node: straight
            // code with the same operations in the same order as the general sum below, so the
            // same bits
            Carrier::Ellipsoid { centre, semi_axes, axes: Some(u) } if semi_axes.len() == 3 => {
                let (c, a) = (&centre[..3], &semi_axes[..3]);
                let (u, x) = (&u[..9], &x[..3]);
                let d = [x[0] - c[0], x[1] - c[1], x[2] - c[2]];
                let q = |j: usize| ((d[0] * u[3 * j] + d[1] * u[3 * j + 1]) + d[2] * u[3 * j + 2]) / a[j];
                let (q0, q1, q2) = (q(0), q(1), q(2));
                1.0 - ((q0 * q0 + q1 * q1) + q2 * q2)
            }
            Carrier::Ellipsoid { centre, semi_axes, axes } => {
                let s: f64 = (0..semi_axes.len())
                    .map(|j| (ellipsoid_coordinate(centre, axes.as_deref(), j, x) / semi_axes[j]).powi(2))
                    .sum();
                1.0 - s
            }
            Carrier::Union(a, b) => r_union(a.eval(x), b.eval(x)),
            Carrier::Intersection(a, b) => r_intersection(a.eval(x), b.eval(x)),
            Carrier::Difference(a, b) => r_intersection(a.eval(x), -b.eval(x)),
        }
    }
}

/// The coordinate (x - c) . u_j of `x` along an ellipsoid's axis j (`axes`: the unit axes row by
/// row, or None for the coordinate axes).
#[inline]
pub fn ellipsoid_coordinate(centre: &[f64], axes: Option<&[f64]>, j: usize, x: &[f64]) -> f64 {
    let dim = centre.len();
    match axes {
        Some(u) => (0..dim).map(|d| (x[d] - centre[d]) * u[j * dim + d]).sum(),
        None => x[j] - centre[j],
    }
}

/// Component `d` of an ellipsoid's unit axis `j` (see [`ellipsoid_coordinate`]).
#[inline]
pub fn ellipsoid_axis(axes: Option<&[f64]>, dim: usize, j: usize, d: usize) -> f64 {
    match axes {
        Some(u) => u[j * dim + d],
        None => f64::from(u8::from(j == d)),
    }
}

/// The ellipsoid fitted to the data `points` (`lo.len()` coordinates each, `lo`..`hi` their box;
/// see "The fitted ellipsoid" in the module doc): axes along the principal directions of the
/// points' scatter, semi-axes half the points' extent along each, centre the middle of those
/// extents (the scatter's axes are those of [`Plane::of`]). Without points, with fewer than two,
/// or in two dimensions, the ellipsoid of the box: the coordinate axes and half the box's
/// extents. A semi-axis
/// is at least a thousandth of the largest, so flat or straight data still give a solid. With
/// `spread` below 1 the semi-axes a_j become g (a_j / g)^spread, g their geometric mean: 1 keeps
/// the fitted shape, 0 gives the ball of radius g (which any ball's solid equals).
pub fn fitted_ellipsoid(lo: &[f64], hi: &[f64], points: &[f64], spread: f64) -> Carrier {
    let floor = |mut a: Vec<f64>| {
        let big = a.iter().fold(0.0f64, |m, &x| m.max(x)).max(f64::MIN_POSITIVE);
        a.iter_mut().for_each(|x| *x = x.max(1e-3 * big));
        let g = (a.iter().map(|x| x.ln()).sum::<f64>() / a.len().max(1) as f64).exp();
        if spread != 1.0 {
            a.iter_mut().for_each(|x| *x = g * (*x / g).powf(spread));
        }
        a
    };
    if lo.len() != 3 || points.len() < 6 {
        let centre = lo.iter().zip(hi).map(|(a, b)| 0.5 * a + 0.5 * b).collect();
        let semi_axes = floor(lo.iter().zip(hi).map(|(a, b)| 0.5 * (b - a)).collect());
        return Carrier::Ellipsoid { centre, semi_axes, axes: None };
    }
    // the principal directions of the scatter, the largest first, each turned so that its
    // largest component is positive (the eigenvectors' signs are the rotations' rounding); the
    // scatter is taken of the points moved to the box's middle and divided by its largest
    // half-extent, so that its squares stay of order one at any scale the data may have (taken of
    // the raw coordinates they overflow from about 1e154), and its mean is scaled back
    let mid = [0, 1, 2].map(|d| 0.5 * lo[d] + 0.5 * hi[d]);
    let unit = (0..3).map(|d| 0.5 * hi[d] - 0.5 * lo[d]).fold(0.0f64, f64::max);
    let unit = if unit.is_normal() { unit } else { 1.0 };
    let scatter =
        Plane::of(|| points.chunks_exact(3).map(move |p| [0, 1, 2].map(|d| (p[d] - mid[d]) / unit)));
    let axes: Vec<f64> = (0..3)
        .rev()
        .flat_map(|col| {
            let u = [0, 1, 2].map(|r| scatter.vectors[r][col]);
            let big = u.iter().copied().fold(0.0f64, |m, x| if x.abs() > m.abs() { x } else { m });
            u.map(|x| if big < 0.0 { -x } else { x })
        })
        .collect();
    let mean = [0, 1, 2].map(|d| mid[d] + unit * scatter.mean[d]);
    let (mut lo_u, mut hi_u) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for p in points.chunks_exact(3) {
        for j in 0..3 {
            let t = ellipsoid_coordinate(&mean, Some(&axes), j, p);
            lo_u[j] = lo_u[j].min(t);
            hi_u[j] = hi_u[j].max(t);
        }
    }
    let centre = (0..3)
        .map(|d| mean[d] + (0..3).map(|j| 0.5 * (lo_u[j] + hi_u[j]) * axes[3 * j + d]).sum::<f64>())
        .collect();
    let semi_axes = floor((0..3).map(|j| 0.5 * (hi_u[j] - lo_u[j])).collect());
    Carrier::Ellipsoid { centre, semi_axes, axes: Some(axes) }
}

/// R-function union (R_0 system, as in HyperFun): positive where either argument is.
#[inline]
pub fn r_union(f1: f64, f2: f64) -> f64 {
    f1 + f2 + (f1 * f1 + f2 * f2).sqrt()
}

/// R-function intersection: positive where both arguments are.
#[inline]
pub fn r_intersection(f1: f64, f2: f64) -> f64 {
    f1 + f2 - (f1 * f1 + f2 * f2).sqrt()
}

impl fmt::Display for Carrier {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let list = |v: &[f64]| v.iter().map(|x| format!("{x:?}")).collect::<Vec<_>>().join(",");
        match self {
            Carrier::AutoBall => write!(f, "ball"),
            Carrier::AutoEllipsoid { spread } if *spread == 1.0 => write!(f, "ellipsoid"),
            Carrier::AutoEllipsoid { spread } => write!(f, "ellipsoid({spread:?})"),
            Carrier::Ball { centre, radius } => write!(f, "ball:{},{radius:?}", list(centre)),
            Carrier::Ellipsoid { centre, semi_axes, axes: None } => {
                write!(f, "ellipsoid:{},{}", list(centre), list(semi_axes))
            }
            Carrier::Ellipsoid { centre, semi_axes, axes: Some(u) } => {
                write!(f, "ellipsoid:{},{},{}", list(centre), list(semi_axes), list(u))
            }
            Carrier::Union(a, b) => write!(f, "union({a},{b})"),
            Carrier::Intersection(a, b) => write!(f, "intersection({a},{b})"),
            Carrier::Difference(a, b) => write!(f, "difference({a},{b})"),
        }
    }
}

/// The largest magnitude of a number in a carrier spec: f_c squares centres, radii and semi-axes,
/// and the square of 1e150 (1e300) is still below the largest double (about 1.8e308).
pub const MAX_CARRIER_NUMBER: f64 = 1e150;

/// The largest magnitude of a number in an ellipsoid's spec: f_c = 1 - sum_j (t_j / a_j)^2 squares
/// only the ratios t_j / a_j of a coordinate along an axis to the semi-axis, so the centre and the
/// semi-axes may be as large as the data (a fit's ellipsoid is as large as its points), short of
/// the differences x - c overflowing.
pub const MAX_ELLIPSOID_NUMBER: f64 = 1e300;

/// The smallest radius or semi-axis of a carrier: f_c divides by their squares (an ellipsoid) or
/// subtracts a coordinate's square from theirs (a ball), and below 1e-150 the square underflows
/// (a ball of radius 1e-300 would be f_c = -|x - c|^2 to the last bit, zero at its centre only,
/// and an ellipsoid's 1 / a^2 overflows).
pub const MIN_CARRIER_LENGTH: f64 = 1e-150;

/// How deeply R-functions may nest in a carrier spec (the parser, the evaluation and the printing
/// recurse once per level).
pub const MAX_CARRIER_DEPTH: usize = 64;

/// The words that start a carrier spec.
const CARRIER_WORDS: [&str; 8] =
    ["ball", "sphere", "disc", "ellipsoid", "ellipse", "union", "intersection", "difference"];

struct Parser<'a> {
    s: &'a [u8],
    pos: usize,
    spec: &'a str,
    dim: usize,
    depth: usize,
}

impl Parser<'_> {
    fn error(&self, why: &str) -> Error {
        Error::Usage(format!("carrier '{}' at character {}: {why}", self.spec, self.pos + 1))
    }

    fn skip_ws(&mut self) {
        while self.pos < self.s.len() && self.s[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
    }

    fn word(&mut self) -> String {
        self.skip_ws();
        let start = self.pos;
        // non-ASCII letters belong to the word too, so that a misspelt name is reported whole
        while self.pos < self.s.len()
            && (self.s[self.pos].is_ascii_alphanumeric() || self.s[self.pos] >= 0x80)
        {
            self.pos += 1;
        }
        String::from_utf8_lossy(&self.s[start..self.pos]).to_lowercase()
    }

    fn expect(&mut self, c: u8) -> Result<()> {
        self.skip_ws();
        if self.s.get(self.pos) == Some(&c) {
            self.pos += 1;
            Ok(())
        } else {
            Err(self.error(&format!("expected '{}'", c as char)))
        }
    }

    fn numbers(&mut self) -> Result<Vec<f64>> {
        self.numbers_within(MAX_CARRIER_NUMBER, "carrier number whose square is representable")
    }

    /// The numbers of a spec up to the next carrier or ')', each finite and at most `limit` in
    /// magnitude (`largest` says what the limit is, for the message).
    fn numbers_within(&mut self, limit: f64, largest: &str) -> Result<Vec<f64>> {
        let start = self.pos;
        while self.pos < self.s.len() && !matches!(self.s[self.pos], b')') {
            if self.s[self.pos] == b',' && self.carrier_follows(self.pos + 1) {
                break;
            }
            self.pos += 1;
        }
        let text = std::str::from_utf8(&self.s[start..self.pos]).unwrap_or("");
        let mut out = Vec::new();
        for tok in text.split(',') {
            let tok = tok.trim();
            match tok.parse::<f64>() {
                Ok(v) if v.is_finite() && v.abs() <= limit => out.push(v),
                Ok(v) if v.is_finite() => {
                    self.pos = start;
                    return Err(self.error(&format!(
                        "{tok} is larger in magnitude than {limit:e}, the largest {largest}; rescale the data"
                    )));
                }
                _ => {
                    self.pos = start;
                    return Err(self.error(&format!("'{tok}' is not a finite number")));
                }
            }
        }
        Ok(out)
    }

    /// Whether a carrier name starts at byte `at` (after blanks): what ends a list of numbers.
    fn carrier_follows(&self, at: usize) -> bool {
        let rest = &self.s[at.min(self.s.len())..];
        let rest = &rest[rest.iter().take_while(|b| b.is_ascii_whitespace()).count()..];
        let len = rest.iter().take_while(|b| b.is_ascii_alphabetic()).count();
        let word = String::from_utf8_lossy(&rest[..len]).to_ascii_lowercase();
        CARRIER_WORDS.contains(&word.as_str())
    }

    fn carrier(&mut self) -> Result<Carrier> {
        self.depth += 1;
        if self.depth > MAX_CARRIER_DEPTH {
            return Err(self.error(&format!("R-functions nest deeper than {MAX_CARRIER_DEPTH} levels")));
        }
        let c = self.carrier_inner();
        self.depth -= 1;
        c
    }

    fn carrier_inner(&mut self) -> Result<Carrier> {
        let start = self.pos;
        let name = self.word();
        let d = self.dim;
        match name.as_str() {
            "ball" | "sphere" | "disc" => {
                self.skip_ws();
                if self.s.get(self.pos) != Some(&b':') {
                    return Ok(Carrier::AutoBall);
                }
                self.pos += 1;
                let v = self.numbers()?;
                if v.len() != d + 1 {
                    return Err(self.error(&format!(
                        "ball needs {} numbers (centre, radius), got {}",
                        d + 1,
                        v.len()
                    )));
                }
                if v[d] <= 0.0 {
                    return Err(self.error("ball radius must be positive"));
                }
                if v[d] < MIN_CARRIER_LENGTH {
                    return Err(self.error(&format!(
                        "ball radius {:e} is below {MIN_CARRIER_LENGTH:e}, the smallest whose square is \
                         representable; rescale the data",
                        v[d]
                    )));
                }
                Ok(Carrier::Ball { centre: v[..d].to_vec(), radius: v[d] })
            }
            "ellipsoid" | "ellipse" => {
                self.skip_ws();
                if self.s.get(self.pos) == Some(&b'(') {
                    self.pos += 1;
                    let at = self.pos;
                    let v = self.numbers()?;
                    self.expect(b')')?;
                    if v.len() != 1 || !(0.0..=1.0).contains(&v[0]) {
                        self.pos = at;
                        return Err(self.error("a fitted ellipsoid's spread is one number from 0 to 1"));
                    }
                    return Ok(Carrier::AutoEllipsoid { spread: v[0] });
                }
                if self.s.get(self.pos) != Some(&b':') {
                    return Ok(Carrier::AutoEllipsoid { spread: 1.0 });
                }
                self.pos += 1;
                let v = self.numbers_within(
                    MAX_ELLIPSOID_NUMBER,
                    "ellipsoid number whose differences are representable",
                )?;
                if v.len() != 2 * d && v.len() != 2 * d + d * d {
                    return Err(self.error(&format!(
                        "ellipsoid needs {} numbers (centre, semi-axes) or {} (centre, semi-axes, then the \
                         unit axes one after the other), got {}",
                        2 * d,
                        2 * d + d * d,
                        v.len()
                    )));
                }
                if v[d..2 * d].iter().any(|&a| a <= 0.0) {
                    return Err(self.error("ellipsoid semi-axes must be positive"));
                }
                if let Some(a) = v[d..2 * d].iter().find(|&&a| a < MIN_CARRIER_LENGTH) {
                    return Err(self.error(&format!(
                        "ellipsoid semi-axis {a:e} is below {MIN_CARRIER_LENGTH:e}, the smallest whose square is \
                         representable; rescale the data"
                    )));
                }
                let axes = (v.len() > 2 * d).then(|| v[2 * d..].to_vec());
                if let Some(u) = &axes {
                    for (i, j) in (0..d).flat_map(|i| (0..d).map(move |j| (i, j))) {
                        let dot: f64 = (0..d).map(|k| u[i * d + k] * u[j * d + k]).sum();
                        if (dot - f64::from(u8::from(i == j))).abs() > 1e-6 {
                            return Err(self.error(&format!(
                                "ellipsoid axes must be orthonormal: axes {} and {} have dot product {dot}",
                                i + 1,
                                j + 1
                            )));
                        }
                    }
                }
                Ok(Carrier::Ellipsoid { centre: v[..d].to_vec(), semi_axes: v[d..2 * d].to_vec(), axes })
            }
            "union" | "intersection" | "difference" => {
                self.expect(b'(')?;
                let a = self.carrier()?;
                self.expect(b',')?;
                let b = self.carrier()?;
                self.expect(b')')?;
                let (a, b) = (Box::new(a), Box::new(b));
                Ok(match name.as_str() {
                    "union" => Carrier::Union(a, b),
                    "intersection" => Carrier::Intersection(a, b),
                    _ => Carrier::Difference(a, b),
                })
            }
            "" => Err(self.error("expected a carrier (ball, ellipsoid, union, intersection, difference)")),
            other => {
                self.pos = start;
                Err(self.error(&format!(
                    "unknown carrier '{other}' (expected ball, ellipsoid, union, intersection, difference)"
                )))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn specs_parse_and_round_trip() {
        for spec in [
            "ball",
            "ball:1.0,2.0,3.0,4.0",
            "ellipsoid:0.0,0.0,0.0,1.0,2.0,3.0",
            "union(ball:-1.0,0.0,0.0,1.5,ball:1.0,0.0,0.0,1.5)",
            "difference(intersection(ball,ball:0.0,0.0,0.0,1.0),ellipsoid:0.0,0.0,0.0,1.0,1.0,0.5)",
        ] {
            let c = Carrier::parse(spec, 3).unwrap();
            assert_eq!(c.to_string(), spec);
            assert_eq!(Carrier::parse(&c.to_string(), 3).unwrap(), c);
        }
        let disc = Carrier::parse("ball: 0, 0, 2", 2).unwrap();
        assert_eq!(disc.eval(&[1.0, 1.0]), 2.0);
    }

    #[test]
    fn bad_specs_are_rejected_with_position() {
        for spec in [
            "ball:1,2,3",
            "ball:0,0,0,-1",
            "cube",
            "union(ball,ball",
            "ellipsoid:0,0,0,1,0,1",
            "ball:a,b,c,d",
            "ball x",
            "ball:0,0,0,1e-300",
            "ellipsoid:0,0,0,1,1e-160,1",
        ] {
            let e = Carrier::parse(spec, 3).unwrap_err();
            assert!(matches!(e, Error::Usage(ref m) if m.contains(spec)), "{spec}: {e}");
        }
        let e = Carrier::parse("ball:0,0,0,1e-300", 3).unwrap_err().to_string();
        assert!(e.contains("radius 1e-300 is below 1e-150"), "{e}");
        assert!(Carrier::parse("ball:0,0,0,1e-150", 3).is_ok());
    }

    #[test]
    fn messages_name_the_real_fault() {
        let msg = |spec: &str| Carrier::parse(spec, 3).unwrap_err().to_string();
        assert!(msg("ball:0,0,0,inf").contains("'inf' is not a finite number"), "{}", msg("ball:0,0,0,inf"));
        assert!(msg("ball:0,0,0,nan").contains("'nan' is not a finite number"));
        assert!(msg("bäll").contains("unknown carrier 'bäll'"), "{}", msg("bäll"));
        let big = msg("ball:0,0,0,1e160");
        assert!(big.contains("1e160") && big.contains("1e150"), "{big}");
        // a number list still ends where the next carrier begins
        Carrier::parse("union(ball:0,0,0,1, ellipsoid:0,0,0,1,2,3)", 3).unwrap();
    }

    #[test]
    fn nesting_is_limited() {
        let nest = |d: usize| "union(".repeat(d) + "ball:0,0,0,1" + &",ball:0,0,0,1)".repeat(d);
        Carrier::parse(&nest(MAX_CARRIER_DEPTH - 1), 3).unwrap();
        let e = Carrier::parse(&nest(200_000), 3).unwrap_err().to_string();
        assert!(e.contains("deeper than 64"), "{}", &e[e.len() - 80..]);
    }

    #[test]
    fn only_concrete_carriers_are_resolved() {
        assert!(!Carrier::parse("union(ball:0,0,0,1,ball)", 3).unwrap().is_resolved());
        assert!(Carrier::parse("union(ball:0,0,0,1,ball:1,0,0,1)", 3).unwrap().is_resolved());
    }

    #[test]
    fn sign_convention_inside_positive() {
        let b = Carrier::parse("ball:1,2,3,2", 3).unwrap();
        assert_eq!(b.eval(&[1.0, 2.0, 3.0]), 4.0);
        assert_eq!(b.eval(&[3.0, 2.0, 3.0]), 0.0);
        assert!(b.eval(&[4.0, 2.0, 3.0]) < 0.0);
        let e = Carrier::parse("ellipsoid:0,0,0,2,1,1", 3).unwrap();
        assert_eq!(e.eval(&[2.0, 0.0, 0.0]), 0.0);
        assert!(e.eval(&[0.0, 1.5, 0.0]) < 0.0);
    }

    #[test]
    fn r_functions_are_set_operations() {
        // two unit balls at x = -1 and x = +1
        let u = Carrier::parse("union(ball:-1,0,0,1,ball:1,0,0,1)", 3).unwrap();
        let i = Carrier::parse("intersection(ball:-0.5,0,0,1,ball:0.5,0,0,1)", 3).unwrap();
        let d = Carrier::parse("difference(ball:0,0,0,2,ball:0,0,0,1)", 3).unwrap();
        assert!(u.eval(&[-1.5, 0.0, 0.0]) > 0.0 && u.eval(&[1.5, 0.0, 0.0]) > 0.0);
        assert!(u.eval(&[0.0, 0.5, 0.0]) < 0.0);
        assert!(i.eval(&[0.0, 0.0, 0.0]) > 0.0 && i.eval(&[1.2, 0.0, 0.0]) < 0.0);
        assert!(d.eval(&[1.5, 0.0, 0.0]) > 0.0 && d.eval(&[0.5, 0.0, 0.0]) < 0.0);
        // the zero sets are exactly the boundary of the set operation
        assert!(u.eval(&[2.0, 0.0, 0.0]).abs() < 1e-12);
    }

    #[test]
    fn ellipsoid_numbers_may_reach_1e300_where_a_balls_stop_at_1e150() {
        let big = "ellipsoid:1e299,0,0,2e299,1e299,5e298";
        let c = Carrier::parse(big, 3).unwrap();
        assert_eq!(Carrier::parse(&c.to_string(), 3).unwrap(), c);
        assert!((c.eval(&[3e299, 0.0, 0.0])).abs() < 1e-12, "{}", c.eval(&[3e299, 0.0, 0.0]));
        let e = Carrier::parse("ellipsoid:2e300,0,0,1,1,1", 3).unwrap_err().to_string();
        assert!(e.contains("larger in magnitude than 1e300"), "{e}");
        let e = Carrier::parse("ball:0,0,0,1e160", 3).unwrap_err().to_string();
        assert!(e.contains("larger in magnitude than 1e150"), "{e}");
    }

    #[test]
    fn a_turned_ellipsoid_in_3d_gives_the_bits_of_the_general_sum() {
        // the fitted ellipsoid of scattered points, whose axes are turned every which way
        let pts: Vec<f64> = (0..200)
            .flat_map(|i| {
                let t = i as f64 * 0.37;
                [3.0 * t.cos() + 0.1 * t, 1.5 * t.sin() - 0.2 * t.cos(), 0.7 * (2.0 * t).sin() + 0.05 * t]
            })
            .collect();
        let c = fitted_ellipsoid(&[-4.0, -2.0, -1.0], &[5.0, 2.0, 1.0], &pts, 0.3);
        let Carrier::Ellipsoid { centre, semi_axes, axes } = &c else { panic!("{c:?}") };
        assert!(axes.is_some());
        let general = |x: &[f64]| {
            let s: f64 = (0..3)
                .map(|j| (ellipsoid_coordinate(centre, axes.as_deref(), j, x) / semi_axes[j]).powi(2))
                .sum();
            1.0 - s
        };
        for x in pts.chunks_exact(3).chain([[0.0; 3].as_slice(), &[-0.0, 1e-300, 7e5]]) {
            assert_eq!(c.eval(x).to_bits(), general(x).to_bits(), "{x:?}");
        }
    }

    #[test]
    fn turned_ellipsoids_parse_round_trip_and_are_checked() {
        let h = std::f64::consts::FRAC_1_SQRT_2;
        let spec =
            format!("ellipsoid:0.0,0.0,0.0,2.0,1.0,0.5,{h:?},{h:?},0.0,{:?},{h:?},0.0,0.0,0.0,1.0", -h);
        let c = Carrier::parse(&spec, 3).unwrap();
        assert_eq!(c.to_string(), spec);
        assert_eq!(Carrier::parse(&c.to_string(), 3).unwrap(), c);
        // on the long axis, along (1, 1, 0) / sqrt 2, at 2: the surface
        assert!(c.eval(&[2.0 * h, 2.0 * h, 0.0]).abs() < 1e-15);
        assert!(c.eval(&[2.0 * h, -2.0 * h, 0.0]) < -1.0);
        assert_eq!(Carrier::parse("ellipsoid", 3).unwrap(), Carrier::AutoEllipsoid { spread: 1.0 });
        assert_eq!(Carrier::AutoEllipsoid { spread: 1.0 }.to_string(), "ellipsoid");
        let half = Carrier::parse("ellipsoid(0.5)", 3).unwrap();
        assert_eq!((half.to_string(), half.is_resolved()), ("ellipsoid(0.5)".to_string(), false));
        for bad in ["ellipsoid(1.5)", "ellipsoid(0.5,1)", "ellipsoid(-1)", "ellipsoid(0.5"] {
            assert!(Carrier::parse(bad, 3).is_err(), "{bad}");
        }
        let e = Carrier::parse("ellipsoid:0,0,0,1,1,1,1,0,0,1,0,0,0,0,1", 3).unwrap_err().to_string();
        assert!(e.contains("orthonormal") && e.contains("axes 1 and 2"), "{e}");
        let e = Carrier::parse("ellipsoid:0,0,0,1,1,1,1,0,0", 3).unwrap_err().to_string();
        assert!(e.contains("needs 6 numbers") && e.contains("or 15"), "{e}");
    }

    /// Points on the surface of the ellipsoid with semi-axes `a` along the rows of `axes` about
    /// `centre`, on a grid of angles.
    fn on_ellipsoid(centre: [f64; 3], a: [f64; 3], axes: [[f64; 3]; 3]) -> Vec<f64> {
        let mut out = Vec::new();
        for i in 0..24 {
            for j in 1..12 {
                let (th, ph) =
                    (i as f64 * std::f64::consts::TAU / 24.0, j as f64 * std::f64::consts::PI / 12.0);
                let t = [a[0] * ph.sin() * th.cos(), a[1] * ph.sin() * th.sin(), a[2] * ph.cos()];
                out.extend((0..3).map(|d| centre[d] + (0..3).map(|k| t[k] * axes[k][d]).sum::<f64>()));
            }
        }
        // the two poles, so the extents along the third axis are reached
        for s in [-1.0, 1.0] {
            out.extend((0..3).map(|d| centre[d] + s * a[2] * axes[2][d]));
        }
        out
    }

    #[test]
    fn the_fitted_ellipsoid_follows_a_turned_cloud() {
        // a rotation by 0.5 rad about (1, 2, 2) / 3
        let (k, t) = ([1.0 / 3.0, 2.0 / 3.0, 2.0 / 3.0], 0.5f64);
        let r: [[f64; 3]; 3] = std::array::from_fn(|i| {
            std::array::from_fn(|j| {
                let delta = f64::from(u8::from(i == j));
                let cross = match (i, j) {
                    (0, 1) => -k[2],
                    (1, 0) => k[2],
                    (0, 2) => k[1],
                    (2, 0) => -k[1],
                    (1, 2) => -k[0],
                    (2, 1) => k[0],
                    _ => 0.0,
                };
                t.cos() * delta + t.sin() * cross + (1.0 - t.cos()) * k[i] * k[j]
            })
        });
        let (centre, a) = ([1.0, -2.0, 0.5], [3.0, 2.0, 1.0]);
        let pts = on_ellipsoid(centre, a, r);
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for p in pts.chunks_exact(3) {
            for d in 0..3 {
                lo[d] = lo[d].min(p[d]);
                hi[d] = hi[d].max(p[d]);
            }
        }
        let c = Carrier::AutoEllipsoid { spread: 1.0 }.resolve(&lo, &hi, &pts);
        let Carrier::Ellipsoid { centre: got_c, semi_axes, axes: Some(axes) } = &c else { panic!("{c}") };
        for j in 0..3 {
            let along: f64 = (0..3).map(|d| axes[3 * j + d] * r[j][d]).sum();
            assert!(along.abs() > 1.0 - 1e-9, "axis {j}: {axes:?} against {:?}", r[j]);
            assert!((semi_axes[j] - a[j]).abs() < 1e-9, "{semi_axes:?}");
            assert!((got_c[j] - centre[j]).abs() < 1e-9, "{got_c:?}");
        }
        // every point lies on the fitted surface
        assert!(pts.chunks_exact(3).all(|p| c.eval(p).abs() < 1e-9));
        // without the points: the box's ellipsoid; flat data keep a solid
        let boxed = Carrier::AutoEllipsoid { spread: 1.0 }.resolve(&[0.0, 0.0, 0.0], &[4.0, 2.0, 0.0], &[]);
        assert_eq!(boxed.to_string(), "ellipsoid:2.0,1.0,0.0,2.0,1.0,0.002");
        // the spread halved: semi-axes g (a / g)^0.5 with g the geometric mean, here 1
        let c = Carrier::AutoEllipsoid { spread: 0.5 }.resolve(&lo, &hi, &pts);
        let Carrier::Ellipsoid { semi_axes, .. } = &c else { panic!("{c}") };
        let g = (3.0f64 * 2.0 * 1.0).cbrt();
        for (got, a) in semi_axes.iter().zip(a) {
            assert!((got - g * (a / g).sqrt()).abs() < 1e-9, "{semi_axes:?}");
        }
        let ball = Carrier::AutoEllipsoid { spread: 0.0 }.resolve(&lo, &hi, &pts);
        let Carrier::Ellipsoid { semi_axes, .. } = &ball else { panic!("{ball}") };
        assert!(semi_axes.iter().all(|s| (s - g).abs() < 1e-9), "{semi_axes:?}");
        // the same points at 1e200, where their squares overflow: the same ellipsoid, scaled
        let big = 1e200;
        let scaled: Vec<f64> = pts.iter().map(|v| v * big).collect();
        let (lo_b, hi_b) = (lo.map(|v| v * big), hi.map(|v| v * big));
        let c = Carrier::AutoEllipsoid { spread: 1.0 }.resolve(&lo_b, &hi_b, &scaled);
        let Carrier::Ellipsoid { centre: got_c, semi_axes, .. } = &c else { panic!("{c}") };
        for j in 0..3 {
            assert!((semi_axes[j] / big - a[j]).abs() < 1e-9, "{c}");
            assert!((got_c[j] / big - centre[j]).abs() < 1e-9, "{c}");
        }
        assert!(scaled.chunks_exact(3).all(|p| c.eval(p).abs() < 1e-9), "{c}");
    }

    #[test]
    fn auto_ball_contains_the_box() {
        let c = Carrier::AutoBall.resolve(&[0.0, 0.0, 0.0], &[2.0, 2.0, 1.0], &[]);
        for corner in [[0.0, 0.0, 0.0], [2.0, 2.0, 1.0], [2.0, 0.0, 1.0]] {
            assert!(c.eval(&corner) >= -1e-12);
        }
    }
}
