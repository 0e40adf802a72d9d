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
//! the FRep sphere), `ellipsoid:cx,cy,cz,a,b,c` (f = 1 - sum (x_j - c_j)^2 / a_j^2), and the
//! R-functions `union(A,B)`, `intersection(A,B)`, `difference(A,B)`. In two dimensions the same
//! specs take two centre coordinates (`ball:cx,cy,r` is a disc).

use std::fmt;

use crate::error::{Error, Result};

/// A carrier solid in `dim` dimensions.
#[derive(Debug, Clone, PartialEq)]
pub enum Carrier {
    /// Placeholder for "fit a ball to the data"; resolved by [`Carrier::resolve`] before use.
    AutoBall,
    Ball {
        centre: Vec<f64>,
        radius: f64,
    },
    Ellipsoid {
        centre: Vec<f64>,
        semi_axes: Vec<f64>,
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

    /// Replaces `AutoBall` by the ball centred on the bounding box with radius half its diagonal,
    /// so every data point is inside. For m = 2 any ball gives the same solid (see "Which carriers
    /// change the solid" in the module doc).
    pub fn resolve(&self, lo: &[f64], hi: &[f64]) -> Carrier {
        match self {
            Carrier::AutoBall => {
                let centre: Vec<f64> = lo.iter().zip(hi).map(|(a, b)| 0.5 * a + 0.5 * b).collect();
                let diag = crate::spline::hygiene::diagonal(lo, hi);
                Carrier::Ball { centre, radius: (0.5 * diag).max(f64::MIN_POSITIVE) }
            }
            Carrier::Union(a, b) => Carrier::Union(Box::new(a.resolve(lo, hi)), Box::new(b.resolve(lo, hi))),
            Carrier::Intersection(a, b) => {
                Carrier::Intersection(Box::new(a.resolve(lo, hi)), Box::new(b.resolve(lo, hi)))
            }
            Carrier::Difference(a, b) => {
                Carrier::Difference(Box::new(a.resolve(lo, hi)), Box::new(b.resolve(lo, hi)))
            }
            other => other.clone(),
        }
    }

    /// Whether every automatic ball has been replaced by a concrete one (a stored model's carrier
    /// must be: only a resolved carrier can be evaluated).
    pub fn is_resolved(&self) -> bool {
        match self {
            Carrier::AutoBall => false,
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
            Carrier::AutoBall | Carrier::Ball { .. } | Carrier::Ellipsoid { .. } => Some(2),
            _ => None,
        }
    }

    /// f_c(x); `x` has at least `dim` components. Panics on an unresolved `AutoBall`.
    #[inline]
    pub fn eval(&self, x: &[f64]) -> f64 {
        match self {
            Carrier::AutoBall => panic!("automatic ball carrier used before Carrier::resolve"),
            Carrier::Ball { centre, radius } => {
                let d2: f64 = centre.iter().zip(x).map(|(c, v)| (v - c) * (v - c)).sum();
                radius * radius - d2
            }
            Carrier::Ellipsoid { centre, semi_axes } => {
                let s: f64 =
                    centre.iter().zip(semi_axes).zip(x).map(|((c, a), v)| ((v - c) / a).powi(2)).sum();
                1.0 - s
            }
            Carrier::Union(a, b) => r_union(a.eval(x), b.eval(x)),
            Carrier::Intersection(a, b) => r_intersection(a.eval(x), b.eval(x)),
            Carrier::Difference(a, b) => r_intersection(a.eval(x), -b.eval(x)),
        }
    }
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
            Carrier::Ball { centre, radius } => write!(f, "ball:{},{radius:?}", list(centre)),
            Carrier::Ellipsoid { centre, semi_axes } => {
                write!(f, "ellipsoid:{},{}", list(centre), list(semi_axes))
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
                Ok(v) if v.is_finite() && v.abs() <= MAX_CARRIER_NUMBER => out.push(v),
                Ok(v) if v.is_finite() => {
                    self.pos = start;
                    return Err(self.error(&format!(
                        "{tok} is larger in magnitude than {MAX_CARRIER_NUMBER:e}, the largest carrier \
                         number whose square is representable; rescale the data"
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
                self.expect(b':')?;
                let v = self.numbers()?;
                if v.len() != 2 * d {
                    return Err(self.error(&format!(
                        "ellipsoid needs {} numbers (centre, semi-axes), got {}",
                        2 * d,
                        v.len()
                    )));
                }
                if v[d..].iter().any(|&a| a <= 0.0) {
                    return Err(self.error("ellipsoid semi-axes must be positive"));
                }
                if let Some(a) = v[d..].iter().find(|&&a| a < MIN_CARRIER_LENGTH) {
                    return Err(self.error(&format!(
                        "ellipsoid semi-axis {a:e} is below {MIN_CARRIER_LENGTH:e}, the smallest whose square is \
                         representable; rescale the data"
                    )));
                }
                Ok(Carrier::Ellipsoid { centre: v[..d].to_vec(), semi_axes: v[d..].to_vec() })
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
    fn auto_ball_contains_the_box() {
        let c = Carrier::AutoBall.resolve(&[0.0, 0.0, 0.0], &[2.0, 2.0, 1.0]);
        for corner in [[0.0, 0.0, 0.0], [2.0, 2.0, 1.0], [2.0, 0.0, 1.0]] {
            assert!(c.eval(&corner) >= -1e-12);
        }
    }
}
