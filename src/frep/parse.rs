//! The text of an FRep expression, parsed into a [`Syntax`] tree without touching any file (so a
//! malformed expression is a usage error before MPI starts); [`crate::frep::expr::Expr::load`]
//! reads the model files it names.
//!
//! # Grammar
//!
//! ```text
//! expr     := number | carrier | call | path
//! carrier  := ("ball" | "sphere") ":" cx "," cy "," cz "," r
//!           | "ellipsoid" ":" cx "," cy "," cz "," a "," b "," c
//! call     := name "(" arg ("," arg)* ")"
//! arg      := expr          (numbers where the operation asks for them)
//! path     := any other text up to the next "," or ")": a model file (fit or contours)
//! ```
//!
//! The operations and their arguments:
//!
//! ```text
//! union(e1, e2, ...)  intersection(e1, e2, ...)  difference(e1, e2)  complement(e)
//! blend_union(e1, e2, a0, a1, a2)  blend_intersection(e1, e2, a0, a1, a2)
//! offset(e, d)  translate(e, dx, dy, dz)  rotate(e, ax, ay, az, degrees)  scale(e, s)
//! scale(e, sx, sy, sz)
//! carrier(MODEL, SPEC)        SPEC: any carrier spec of `fit --carrier`, e.g. union(ball:..,ball:..)
//! ```
//!
//! Names are case-insensitive; blanks between tokens are ignored. A text that names an existing
//! file is read as that model file, even when its name holds commas or parentheses. An error names
//! the expression, the 1-based character where parsing stopped and what was expected there.

use std::fmt;
use std::path::PathBuf;

use crate::error::{Error, Result};
use crate::spline::carrier::{Carrier, MAX_CARRIER_NUMBER};

/// How deeply operations may nest (the parser and the evaluation recurse once per level).
pub const MAX_DEPTH: usize = 64;

/// An operation of the expression language with its numeric parameters; its operands are the
/// expressions next to it in [`Syntax::Apply`] / [`crate::frep::expr::Expr::Apply`].
#[derive(Debug, Clone, PartialEq)]
pub enum Op {
    Union,
    Intersection,
    Difference,
    Complement,
    /// R-union (or R-intersection when `union` is false) plus the displacement
    /// a0 / (1 + (f1/a1)^2 + (f2/a2)^2).
    Blend {
        union: bool,
        a0: f64,
        a1: f64,
        a2: f64,
    },
    Offset(f64),
    Translate([f64; 3]),
    /// Rotation about an axis through the origin: the unit axis and the angle in degrees.
    Rotate {
        axis: [f64; 3],
        degrees: f64,
    },
    /// Scaling about the origin by factors along x, y and z (all equal for `scale(e, s)`).
    Scale([f64; 3]),
}

/// A parsed expression whose model files are not read yet.
#[derive(Debug, Clone, PartialEq)]
pub enum Syntax {
    /// A model file written by `fit` or `contours`.
    Model(PathBuf),
    /// `carrier(MODEL, SPEC)`: the model's spline under another carrier.
    Swap(PathBuf, Carrier),
    Carrier(Carrier),
    Number(f64),
    Apply(Op, Vec<Syntax>),
}

impl Syntax {
    /// Parses an expression (see the module doc for the grammar). A text that names an existing
    /// file is that file, whatever characters its name holds (a plain model path always works).
    pub fn parse(text: &str) -> Result<Syntax> {
        if std::path::Path::new(text).is_file() {
            return Ok(Syntax::Model(PathBuf::from(text)));
        }
        let mut p = Parser { s: text.as_bytes(), text, pos: 0, depth: 0 };
        let e = p.expr()?;
        p.skip_ws();
        if p.pos != p.s.len() {
            return Err(p.error("unexpected text after the expression"));
        }
        // nested scales multiply: each factor within range is not enough
        let (small, large) = scale_extremes(&e, 1.0, 1.0);
        if !(small >= 1e-150 && large <= 1e150) {
            let bad = if small < 1e-150 { small } else { large };
            return Err(p.error_at(
                0,
                &format!(
                    "nested scale factors multiply to {bad:e}, outside 1e-150 to 1e150 (the gradient is scaled \
                     by the inverse, and squared); rescale the models' data instead"
                ),
            ));
        }
        Ok(e)
    }

    /// The model files the expression reads, in the order they appear (each once).
    pub fn models(&self) -> Vec<PathBuf> {
        fn walk(e: &Syntax, out: &mut Vec<PathBuf>) {
            match e {
                Syntax::Model(p) | Syntax::Swap(p, _) => {
                    if !out.contains(p) {
                        out.push(p.clone());
                    }
                }
                Syntax::Apply(_, args) => args.iter().for_each(|a| walk(a, out)),
                Syntax::Carrier(_) | Syntax::Number(_) => {}
            }
        }
        let mut out = Vec::new();
        walk(self, &mut out);
        out
    }

    /// The model file when the expression is nothing but one.
    pub fn as_model(&self) -> Option<&PathBuf> {
        match self {
            Syntax::Model(p) => Some(p),
            _ => None,
        }
    }
}

/// The smallest and largest product of scale factors along any path from `e` to a leaf, given
/// the products `small` and `large` above it.
fn scale_extremes(e: &Syntax, small: f64, large: f64) -> (f64, f64) {
    match e {
        Syntax::Apply(op, args) => {
            let (small, large) = match op {
                Op::Scale(f) => {
                    let (lo, hi) = f.iter().fold((f64::INFINITY, 0.0f64), |(a, b), &x| (a.min(x), b.max(x)));
                    (small * lo, large * hi)
                }
                _ => (small, large),
            };
            args.iter()
                .map(|a| scale_extremes(a, small, large))
                .fold((small, large), |(a, b), (c, d)| (a.min(c), b.max(d)))
        }
        _ => (small, large),
    }
}

fn nums(v: &[f64]) -> String {
    v.iter().map(|x| format!("{x:?}")).collect::<Vec<_>>().join(",")
}

impl fmt::Display for Syntax {
    /// The canonical text, which parses back to the same tree.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Syntax::Model(p) => write!(f, "{}", p.display()),
            Syntax::Swap(p, c) => write!(f, "carrier({},{c})", p.display()),
            Syntax::Carrier(c) => write!(f, "{c}"),
            Syntax::Number(v) => write!(f, "{v:?}"),
            Syntax::Apply(op, args) => {
                let list = args.iter().map(|a| a.to_string()).collect::<Vec<_>>().join(",");
                match op {
                    Op::Union => write!(f, "union({list})"),
                    Op::Intersection => write!(f, "intersection({list})"),
                    Op::Difference => write!(f, "difference({list})"),
                    Op::Complement => write!(f, "complement({list})"),
                    Op::Blend { union, a0, a1, a2 } => {
                        let name = if *union { "blend_union" } else { "blend_intersection" };
                        write!(f, "{name}({list},{})", nums(&[*a0, *a1, *a2]))
                    }
                    Op::Offset(d) => write!(f, "offset({list},{d:?})"),
                    Op::Translate(t) => write!(f, "translate({list},{})", nums(t)),
                    Op::Rotate { axis, degrees } => write!(f, "rotate({list},{},{degrees:?})", nums(axis)),
                    Op::Scale(s) if s[0] == s[1] && s[1] == s[2] => write!(f, "scale({list},{:?})", s[0]),
                    Op::Scale(s) => write!(f, "scale({list},{})", nums(s)),
                }
            }
        }
    }
}

/// The operation names, for the messages.
const OPERATIONS: &str = "union, intersection, difference, complement, blend_union, blend_intersection, \
                          offset, translate, rotate, scale or carrier";

struct Parser<'a> {
    s: &'a [u8],
    text: &'a str,
    pos: usize,
    depth: usize,
}

/// What an argument of a call is, with the character it starts at.
type Arg = (Syntax, usize);

impl Parser<'_> {
    fn error(&self, why: &str) -> Error {
        self.error_at(self.pos, why)
    }

    fn error_at(&self, pos: usize, why: &str) -> Error {
        Error::Usage(format!("expression '{}' at {}: {why}", self.text, pos + 1))
    }

    fn skip_ws(&mut self) {
        while self.pos < self.s.len() && self.s[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
    }

    fn peek(&self) -> Option<u8> {
        self.s.get(self.pos).copied()
    }

    /// The letters, digits and underscores from `pos` on (not consumed).
    fn name_at(&self, pos: usize) -> &str {
        let end = (pos..self.s.len())
            .find(|&i| !(self.s[i].is_ascii_alphanumeric() || self.s[i] == b'_'))
            .unwrap_or(self.s.len());
        &self.text[pos..end]
    }

    /// The first non-blank byte at or after `pos`.
    fn next_non_ws(&self, pos: usize) -> Option<u8> {
        self.s[pos.min(self.s.len())..].iter().copied().find(|c| !c.is_ascii_whitespace())
    }

    fn expr(&mut self) -> Result<Syntax> {
        self.skip_ws();
        let start = self.pos;
        let Some(c) = self.peek() else {
            return Err(self.error(&format!(
                "expected an operand (a model file, a carrier or a number) or {OPERATIONS}"
            )));
        };
        if c == b',' || c == b')' || c == b'(' {
            return Err(self.error(&format!(
                "expected an operand (a model file, a carrier or a number) or {OPERATIONS}"
            )));
        }
        if c.is_ascii_digit() || matches!(c, b'-' | b'+' | b'.') {
            // a token that does not read as a number is a file name (./a.model.h5, 2024/b.model.h5)
            if self.text[start..self.token_end(start)].parse::<f64>().is_ok() {
                return self.number().map(Syntax::Number);
            }
            return self.path().map(Syntax::Model);
        }
        let name = self.name_at(start).to_ascii_lowercase();
        let after = start + name.len();
        if !name.is_empty() && self.next_non_ws(after) == Some(b'(') {
            return self.call(&name, start);
        }
        if matches!(name.as_str(), "ball" | "sphere" | "ellipsoid") && self.s.get(after) == Some(&b':') {
            return self.carrier_leaf(&name, after + 1);
        }
        self.path().map(Syntax::Model)
    }

    /// Where a number token starting at `pos` ends: at the next ',', parenthesis or blank.
    fn token_end(&self, pos: usize) -> usize {
        (pos..self.s.len())
            .find(|&i| matches!(self.s[i], b',' | b')' | b'(') || self.s[i].is_ascii_whitespace())
            .unwrap_or(self.s.len())
    }

    /// A number token.
    fn number(&mut self) -> Result<f64> {
        self.skip_ws();
        let start = self.pos;
        self.pos = self.token_end(start);
        let tok = &self.text[start..self.pos];
        match tok.parse::<f64>() {
            Ok(v) if v.is_finite() && v.abs() <= MAX_CARRIER_NUMBER => Ok(v),
            Ok(_) => {
                Err(self
                    .error_at(start, &format!("{tok} is not finite or larger than {MAX_CARRIER_NUMBER:e}")))
            }
            Err(_) if tok.is_empty() => Err(self.error_at(start, "expected a number")),
            Err(_) => Err(self.error_at(start, &format!("'{tok}' is not a number"))),
        }
    }

    /// `ball:cx,cy,cz,r` or `ellipsoid:cx,cy,cz,a,b,c` with `pos` just after the colon.
    fn carrier_leaf(&mut self, name: &str, pos: usize) -> Result<Syntax> {
        let start = self.pos;
        self.pos = pos;
        let count = if name == "ellipsoid" { 6 } else { 4 };
        let mut v = Vec::with_capacity(count);
        for i in 0..count {
            if i > 0 {
                self.expect(b',', &format!("a {name} takes {count} numbers"))?;
            }
            v.push(self.number()?);
        }
        let spec = format!("{name}:{}", nums(&v));
        Carrier::parse(&spec, 3).map(Syntax::Carrier).map_err(|e| self.wrap(start, &e))
    }

    /// A carrier error as an error of this expression at `pos`.
    fn wrap(&self, pos: usize, e: &Error) -> Error {
        let why = match e {
            Error::Usage(m) => m.clone(),
            other => other.to_string(),
        };
        self.error_at(pos, &why)
    }

    fn expect(&mut self, c: u8, context: &str) -> Result<()> {
        self.skip_ws();
        if self.peek() == Some(c) {
            self.pos += 1;
            Ok(())
        } else {
            Err(self.error(&format!("expected '{}' ({context})", c as char)))
        }
    }

    /// A model file's name: the text up to the next ',' or ')', trimmed.
    fn path(&mut self) -> Result<PathBuf> {
        let start = self.pos;
        while self.pos < self.s.len() && !matches!(self.s[self.pos], b',' | b')' | b'(') {
            self.pos += 1;
        }
        let p = self.text[start..self.pos].trim();
        if p.is_empty() {
            return Err(self.error_at(start, "expected a model file"));
        }
        if self.peek() == Some(b'(') {
            return Err(self.error(&format!("unknown operation '{p}' (expected {OPERATIONS})")));
        }
        Ok(PathBuf::from(p))
    }

    fn call(&mut self, name: &str, start: usize) -> Result<Syntax> {
        if self.depth >= MAX_DEPTH {
            return Err(self.error_at(start, &format!("operations nested deeper than {MAX_DEPTH}")));
        }
        self.pos = start + name.len();
        self.expect(b'(', "after the operation's name")?;
        if name == "carrier" {
            return self.swap(start);
        }
        self.depth += 1;
        let mut args: Vec<Arg> = Vec::new();
        loop {
            self.skip_ws();
            let at = self.pos;
            args.push((self.expr()?, at));
            self.skip_ws();
            match self.peek() {
                Some(b',') => self.pos += 1,
                Some(b')') => {
                    self.pos += 1;
                    break;
                }
                _ => return Err(self.error(&format!("expected ',' or ')' in the arguments of {name}"))),
            }
        }
        self.depth -= 1;
        self.operation(name, start, args)
    }

    /// `carrier(MODEL, SPEC)` after its opening parenthesis: SPEC is the text up to the matching
    /// closing one, read by the carrier parser.
    fn swap(&mut self, start: usize) -> Result<Syntax> {
        self.skip_ws();
        let at = self.pos;
        let model = match self.expr()? {
            Syntax::Model(p) => p,
            _ => {
                return Err(
                    self.error_at(at, "the first argument of carrier(MODEL, SPEC) must be a model file")
                )
            }
        };
        self.expect(b',', "carrier(MODEL, SPEC) takes a model file and a carrier spec")?;
        self.skip_ws();
        let spec_start = self.pos;
        let mut depth = 0usize;
        while self.pos < self.s.len() {
            match self.s[self.pos] {
                b'(' => depth += 1,
                b')' if depth == 0 => break,
                b')' => depth -= 1,
                _ => {}
            }
            self.pos += 1;
        }
        if self.pos == self.s.len() {
            return Err(self.error_at(start, "carrier( is never closed: expected ')'"));
        }
        let spec = self.text[spec_start..self.pos].trim();
        let carrier = Carrier::parse(spec, 3).map_err(|e| self.wrap(spec_start, &e))?;
        self.pos += 1;
        Ok(Syntax::Swap(model, carrier))
    }

    /// Checks the arguments of operation `name` and builds it.
    fn operation(&self, name: &str, start: usize, args: Vec<Arg>) -> Result<Syntax> {
        let n = args.len();
        let arity = |want: usize, what: &str| -> Result<()> {
            if n == want {
                Ok(())
            } else {
                Err(self.error_at(start, &format!("{name} takes {what}, got {n} argument(s)")))
            }
        };
        // the numeric parameters after `first` expressions
        let numbers = |first: usize| -> Result<Vec<f64>> {
            args[first..]
                .iter()
                .map(|(a, at)| match a {
                    Syntax::Number(v) => Ok(*v),
                    _ => Err(self.error_at(*at, &format!("expected a number (an argument of {name})"))),
                })
                .collect()
        };
        let exprs = |count: usize| -> Vec<Syntax> { args.iter().take(count).map(|a| a.0.clone()).collect() };
        let op = match name {
            "union" | "intersection" => {
                if n < 2 {
                    return Err(
                        self.error_at(start, &format!("{name} takes two or more expressions, got {n}"))
                    );
                }
                let op = if name == "union" { Op::Union } else { Op::Intersection };
                return Ok(Syntax::Apply(op, exprs(n)));
            }
            "difference" => {
                arity(2, "two expressions")?;
                Op::Difference
            }
            "complement" => {
                arity(1, "one expression")?;
                Op::Complement
            }
            "blend_union" | "blend_intersection" => {
                arity(5, "two expressions and a0, a1, a2")?;
                let v = numbers(2)?;
                if v[1] == 0.0 || v[2] == 0.0 {
                    return Err(self.error_at(args[3].1, "a1 and a2 of a blend must not be zero"));
                }
                Op::Blend { union: name == "blend_union", a0: v[0], a1: v[1], a2: v[2] }
            }
            "offset" => {
                arity(2, "an expression and a distance")?;
                Op::Offset(numbers(1)?[0])
            }
            "translate" => {
                arity(4, "an expression and dx, dy, dz")?;
                let v = numbers(1)?;
                Op::Translate([v[0], v[1], v[2]])
            }
            "rotate" => {
                arity(5, "an expression, an axis ax, ay, az and an angle in degrees")?;
                let v = numbers(1)?;
                let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
                if !(len > 0.0 && len.is_finite()) {
                    return Err(self.error_at(args[1].1, "the rotation axis must not be zero"));
                }
                Op::Rotate { axis: [v[0] / len, v[1] / len, v[2] / len], degrees: v[3] }
            }
            "scale" => {
                if n != 4 {
                    arity(2, "an expression and a factor s, or factors sx, sy, sz")?;
                }
                let v = numbers(1)?;
                if let Some(i) = v.iter().position(|s| !(*s > 0.0)) {
                    return Err(self.error_at(args[1 + i].1, "a scale factor must be positive"));
                }
                // the gradient scales by 1/s and its square must stay finite (the pictures' shading
                // and the curvature square it), the factor's too
                if let Some(i) = v.iter().position(|s| !(*s >= 1e-150 && *s <= 1e150)) {
                    return Err(self.error_at(
                        args[1 + i].1,
                        &format!(
                            "a scale factor must lie within 1e-150 to 1e150 (the gradient is scaled by its \
                             inverse, and squared), not {:e}; rescale the models' data instead",
                            v[i]
                        ),
                    ));
                }
                Op::Scale(if n == 2 { [v[0]; 3] } else { [v[0], v[1], v[2]] })
            }
            _ => {
                return Err(
                    self.error_at(start, &format!("unknown operation '{name}' (expected {OPERATIONS})"))
                )
            }
        };
        let count = match op {
            Op::Difference | Op::Blend { .. } => 2,
            _ => 1,
        };
        Ok(Syntax::Apply(op, exprs(count)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn err(text: &str) -> String {
        match Syntax::parse(text) {
            Err(Error::Usage(m)) => m,
            other => panic!("{text}: expected a usage error, got {other:?}"),
        }
    }

    #[test]
    fn expressions_parse_and_print_back() {
        for text in [
            "a.model.h5",
            "union(a.model.h5,b.model.h5,ball:0.0,0.0,0.0,1.0)",
            "blend_union(a.model.h5,complement(b.model.h5),0.1,0.5,0.5)",
            "offset(translate(scale(a.model.h5,2.0),1.0,-2.0,3.0),0.25)",
            "scale(a.model.h5,1.0,2.0,0.5)",
            "carrier(dir/a.model.h5,union(ball:0.0,0.0,0.0,1.0,ball:2.0,0.0,0.0,1.0))",
            "difference(ellipsoid:0.0,0.0,0.0,1.0,2.0,3.0,-1.5)",
        ] {
            let s = Syntax::parse(text).unwrap();
            assert_eq!(s.to_string(), text);
        }
        let s = Syntax::parse(" UNION ( a.model.h5 , rotate(b.model.h5, 0,0,2, 90) ) ").unwrap();
        let Syntax::Apply(Op::Union, args) = s else { panic!("{s:?}") };
        assert_eq!(
            args[1],
            Syntax::Apply(
                Op::Rotate { axis: [0.0, 0.0, 1.0], degrees: 90.0 },
                vec![Syntax::Model("b.model.h5".into())]
            )
        );
    }

    #[test]
    fn malformed_expressions_name_the_place_and_the_reason() {
        let cases = [
            ("union(a.model.h5,", 18, "expected an operand"),
            ("union(a.model.h5)", 1, "two or more"),
            ("unoin(a.model.h5,b)", 1, "unknown operation 'unoin'"),
            ("offset(a.model.h5,x)", 19, "expected a number"),
            ("offset(a.model.h5,1", 20, "expected ',' or ')'"),
            ("scale(a.model.h5,-1)", 18, "positive"),
            ("scale(a.model.h5,1,0,2)", 20, "positive"),
            ("scale(a.model.h5,1e-170)", 18, "within 1e-150 to 1e150"),
            ("scale(a.model.h5,1,1,1e-200)", 22, "within 1e-150 to 1e150"),
            ("scale(scale(a.model.h5,1e-100),1e-100)", 1, "nested scale factors multiply to 1e-200"),
            ("scale(a.model.h5,1,2)", 1, "factors sx, sy, sz"),
            ("ball:0,0,1", 11, "expected ','"),
            ("ball:0,0,0,-1", 1, "radius"),
            ("carrier(a.model.h5,cube)", 20, "cube"),
            ("carrier(union(a,b),ball)", 9, "must be a model file"),
            ("union(a.model.h5,b.model.h5) x", 30, "unexpected text"),
            ("", 1, "expected an operand"),
        ];
        for (text, at, why) in cases {
            let m = err(text);
            assert!(m.starts_with(&format!("expression '{text}' at {at}: ")), "{text}: {m}");
            assert!(m.contains(why), "{text}: {m}");
        }
        let deep = format!("{}a{}", "complement(".repeat(MAX_DEPTH + 1), ")".repeat(MAX_DEPTH + 1));
        assert!(err(&deep).contains("nested deeper"));
    }
}
