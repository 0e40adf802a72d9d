//! The regular evaluation grid: its geometry (origin, spacing, node counts, x fastest) and the
//! z-slab each rank evaluates and writes.

use crate::error::{Error, Result};

/// Node counts requested on the command line: `N` (nodes along the longest side, cubic cells) or
/// `NX,NY,NZ`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GridSize {
    Longest(usize),
    Each([usize; 3]),
}

impl GridSize {
    pub fn parse(s: &str) -> Result<Self> {
        let parts: Vec<&str> = s.split(',').map(str::trim).collect();
        let num = |t: &str| -> Result<usize> {
            match t.parse::<usize>() {
                Ok(v) if v >= 2 => Ok(v),
                _ => Err(Error::Usage(format!("grid '{s}': '{t}' is not a node count >= 2"))),
            }
        };
        match parts.len() {
            1 => Ok(GridSize::Longest(num(parts[0])?)),
            3 => Ok(GridSize::Each([num(parts[0])?, num(parts[1])?, num(parts[2])?])),
            _ => Err(Error::Usage(format!("grid '{s}': expected N or NX,NY,NZ"))),
        }
    }
}

/// Parses `xmin,ymin,zmin,xmax,ymax,zmax`.
pub fn parse_bounds(s: &str) -> Result<([f64; 3], [f64; 3])> {
    let v: Vec<f64> =
        s.split(',').map(|t| t.trim().parse::<f64>()).collect::<std::result::Result<_, _>>().map_err(
            |_| Error::Usage(format!("bounds '{s}': expected six numbers xmin,ymin,zmin,xmax,ymax,zmax")),
        )?;
    if v.len() != 6 || v.iter().any(|x| !x.is_finite()) {
        return Err(Error::Usage(format!("bounds '{s}': expected six finite numbers")));
    }
    let (lo, hi) = ([v[0], v[1], v[2]], [v[3], v[4], v[5]]);
    if (0..3).any(|d| hi[d] <= lo[d]) {
        return Err(Error::Usage(format!("bounds '{s}': every max must exceed its min")));
    }
    Ok((lo, hi))
}

/// A regular grid of nx x ny x nz nodes; node (i, j, k) is at origin + (i, j, k) * spacing and has
/// index i + nx (j + ny k).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Grid {
    pub dims: [usize; 3],
    pub origin: [f64; 3],
    pub spacing: [f64; 3],
}

/// The smallest grid spacing relative to the coordinates of its nodes: 16 units of double
/// precision's rounding, so that neighbouring nodes, and the surface's vertices between them, are
/// told apart.
pub const RESOLVED: f64 = 16.0 * f64::EPSILON;

impl Grid {
    /// A grid covering the box lo..hi. `Longest(n)`: cubic cells, n nodes along the longest side,
    /// the other sides rounded up to whole cells and centred on the box.
    pub fn covering(lo: [f64; 3], hi: [f64; 3], size: GridSize) -> Result<Grid> {
        let ext: Vec<f64> = (0..3).map(|d| hi[d] - lo[d]).collect();
        let longest = ext.iter().cloned().fold(0.0, f64::max);
        if !(longest > 0.0) || ext.iter().any(|e| !e.is_finite() || *e < 0.0) {
            return Err(Error::Usage("the grid box is empty or not finite".into()));
        }
        let mut g = Grid { dims: [0; 3], origin: [0.0; 3], spacing: [0.0; 3] };
        let underflow = |h: f64, d: usize| {
            Error::Usage(format!(
                "the grid box is too small: its longest side {longest:e} gives a spacing of {h:e} along {}; \
                 give a larger box (--bounds)",
                ["x", "y", "z"][d]
            ))
        };
        for d in 0..3 {
            match size {
                GridSize::Longest(n) => {
                    let h = longest / (n - 1) as f64;
                    if !(h > 0.0) {
                        return Err(underflow(h, d));
                    }
                    let cells = ((ext[d] / h) - 1e-9).ceil().max(1.0) as usize;
                    g.dims[d] = cells + 1;
                    g.spacing[d] = h;
                    g.origin[d] = 0.5 * (lo[d] + hi[d]) - 0.5 * cells as f64 * h;
                }
                GridSize::Each(n) => {
                    let e = if ext[d] > 0.0 { ext[d] } else { longest * 1e-3 };
                    g.dims[d] = n[d];
                    g.spacing[d] = e / (n[d] - 1) as f64;
                    if !(g.spacing[d] > 0.0) {
                        return Err(underflow(g.spacing[d], d));
                    }
                    g.origin[d] = 0.5 * (lo[d] + hi[d]) - 0.5 * e;
                }
            }
        }
        for d in 0..3 {
            let far = g.origin[d] + g.spacing[d] * (g.dims[d] - 1) as f64;
            let reach = g.origin[d].abs().max(far.abs());
            if !(g.spacing[d] >= RESOLVED * reach) || !reach.is_finite() {
                return Err(Error::Usage(format!(
                    "the grid's spacing along {} ({:e}) is not resolved at its coordinates (up to {reach:.3e}): \
                     a spacing below {RESOLVED:e} of them puts nodes on one another, and the surface's vertices \
                     with them; give a larger box (--bounds) or one nearer the origin (translate the solid)",
                    ["x", "y", "z"][d],
                    g.spacing[d]
                )));
            }
        }
        let nodes = g.dims.iter().map(|&n| n as u128).product::<u128>();
        if nodes > 1 << 36 {
            return Err(Error::Usage(format!("grid {:?} has {nodes} nodes, more than 2^36", g.dims)));
        }
        Ok(g)
    }

    pub fn node_count(&self) -> usize {
        self.dims.iter().product()
    }

    /// Position of node (i, j, k).
    #[inline]
    pub fn node(&self, i: usize, j: usize, k: usize) -> [f64; 3] {
        [
            self.origin[0] + i as f64 * self.spacing[0],
            self.origin[1] + j as f64 * self.spacing[1],
            self.origin[2] + k as f64 * self.spacing[2],
        ]
    }

    /// The z-layers of every rank.
    pub fn slabs(&self, ranks: usize) -> Slabs {
        Slabs { n: self.dims[2], ranks }
    }
}

/// `--margin`: the padding of the data's box on every side, as a fraction of its longest side,
/// and whether the grid may grow where the solid reaches its faces (`auto`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Margin {
    pub fraction: f64,
    pub grow: bool,
}

impl Margin {
    /// The padding `auto` starts from.
    pub const AUTO_START: f64 = 0.05;

    /// `auto` or a fraction in [0, 10].
    pub fn parse(s: &str) -> Result<Margin> {
        if s.trim().eq_ignore_ascii_case("auto") {
            return Ok(Margin { fraction: Margin::AUTO_START, grow: true });
        }
        match s.trim().parse::<f64>() {
            Ok(v) if (0.0..=10.0).contains(&v) => Ok(Margin { fraction: v, grow: false }),
            Ok(v) => Err(Error::Usage(format!("margin {v}: expected auto or a number in [0, 10]"))),
            Err(_) => Err(Error::Usage(format!("margin '{s}': expected auto or a number in [0, 10]"))),
        }
    }
}

/// Cells added at a face of the grid at the first step of growth, as a fraction of the cells
/// along the grid's longest side (at least one cell); each further step adds twice the cells of
/// the step before.
pub const GROW_STEP: f64 = 0.05;

/// Most steps of growth, and most nodes after them as a multiple of the grid's first count: a
/// solid that still reaches the faces then is left cut open (with a warning), since it is
/// unbounded or reaches far from its data.
pub const GROW_STEPS: usize = 6;
pub const GROW_NODES: usize = 8;

/// The six faces of a grid, in the order of [`Grid::grown`]: -x, +x, -y, +y, -z, +z.
pub const FACE_NAMES: [&str; 6] = ["-x", "+x", "-y", "+y", "-z", "+z"];

impl Grid {
    /// This grid with `cells` more cells beyond each face in `faces` (-x, +x, -y, +y, -z, +z), at
    /// the same spacing: the nodes it had keep their positions (to the rounding of origin + i h).
    pub fn grown(&self, faces: [bool; 6], cells: usize) -> Grid {
        let mut g = *self;
        for d in 0..3 {
            if faces[2 * d] {
                g.origin[d] -= cells as f64 * g.spacing[d];
                g.dims[d] += cells;
            }
            if faces[2 * d + 1] {
                g.dims[d] += cells;
            }
        }
        g
    }

    /// The cells of one step of growth of this grid ([`GROW_STEP`] of its longest side).
    pub fn grow_cells(&self) -> usize {
        let longest = self.dims.iter().max().copied().unwrap_or(2).saturating_sub(1);
        ((GROW_STEP * longest as f64).ceil() as usize).max(1)
    }
}

/// Box lo..hi of points grown by `margin` times its longest side on every side.
pub fn padded_box(lo: &[f64], hi: &[f64], margin: f64) -> ([f64; 3], [f64; 3]) {
    let longest = (0..3).map(|d| hi[d] - lo[d]).fold(0.0, f64::max);
    let pad = margin * longest;
    let mut l = [0.0; 3];
    let mut h = [0.0; 3];
    for d in 0..3 {
        l[d] = lo[d] - pad;
        h[d] = hi[d] + pad;
    }
    (l, h)
}

/// Contiguous block distribution of `n` grid layers over `ranks`: rank r gets layers
/// start(r)..start(r)+count(r), the first n mod ranks ranks one more.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Slabs {
    pub n: usize,
    pub ranks: usize,
}

impl Slabs {
    pub fn start(&self, r: usize) -> usize {
        let (base, rem) = (self.n / self.ranks, self.n % self.ranks);
        r * base + r.min(rem)
    }

    pub fn count(&self, r: usize) -> usize {
        self.n / self.ranks + usize::from(r < self.n % self.ranks)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn longest_side_gives_cubic_cells_covering_the_box() {
        let g = Grid::covering([0.0, 0.0, 0.0], [2.0, 1.0, 0.5], GridSize::Longest(21)).unwrap();
        assert_eq!(g.dims, [21, 11, 6]);
        assert!(g.spacing.iter().all(|&h| (h - 0.1).abs() < 1e-15));
        let far = g.node(20, 10, 5);
        assert!(g.origin[0] <= 0.0 && far[0] >= 2.0 - 1e-12);
        assert!(g.origin[2] <= 0.0 && far[2] >= 0.5 - 1e-12);
    }

    #[test]
    fn grids_whose_nodes_coordinates_cannot_tell_apart_are_refused() {
        let err = |lo: [f64; 3], hi: [f64; 3], size: GridSize| {
            Grid::covering(lo, hi, size).unwrap_err().to_string()
        };
        // a box of the smallest subnormal: the spacing underflows to 0
        let e = err([0.0; 3], [5e-324; 3], GridSize::Longest(10));
        assert!(e.contains("the grid box is too small") && e.contains("spacing of 0e0 along x"), "{e}");
        let e = err([0.0; 3], [5e-324; 3], GridSize::Each([10, 10, 10]));
        assert!(e.contains("the grid box is too small"), "{e}");
        // a unit box at 1e16: a spacing of 0.1 is below the coordinates' rounding
        let e = err([1e16, 0.0, 0.0], [1e16 + 1.0, 1.0, 1.0], GridSize::Longest(11));
        assert!(e.contains("spacing along x") && e.contains("not resolved"), "{e}");
        // at 1e12 the same box is resolved (0.1 is 800 roundings there)
        assert!(Grid::covering([1e12, 0.0, 0.0], [1e12 + 1.0, 1.0, 1.0], GridSize::Longest(11)).is_ok());
    }

    #[test]
    fn explicit_dims_and_bad_sizes() {
        let g = Grid::covering([0.0; 3], [1.0, 2.0, 3.0], GridSize::parse("5,6,7").unwrap()).unwrap();
        assert_eq!(g.dims, [5, 6, 7]);
        assert_eq!(g.node(4, 5, 6), [1.0, 2.0, 3.0]);
        for bad in ["1", "a", "4,4", "0,4,4", ""] {
            assert!(GridSize::parse(bad).is_err(), "{bad}");
        }
        assert!(parse_bounds("0,0,0,1,1").is_err());
        assert!(parse_bounds("0,0,0,1,1,0").is_err());
        assert_eq!(parse_bounds("0,0,0,1,1,1").unwrap().1, [1.0; 3]);
    }

    #[test]
    fn slabs_cover_the_grid() {
        for ranks in 1..6 {
            let s = Slabs { n: 11, ranks };
            let mut next = 0;
            for r in 0..ranks {
                assert_eq!(s.start(r), next);
                next += s.count(r);
            }
            assert_eq!(next, 11);
        }
    }
}
