//! Ray casting of a solid f >= 0 inside: a pinhole camera framed on the solid's bounds, the first
//! root of f along each ray, and its shading from the gradient.
//!
//! # Finding the first root safely
//!
//! Along a ray x(t) = o + t d (|d| = 1) inside the bounds, f(x(t)) changes by at most L s over a
//! step s when L bounds |grad f| on the segment, so a step of s = |f| / L cannot pass a root. L is
//! estimated on a coarse lattice of f ([`Lattice`], about [`LATTICE_CELLS`] cells along the
//! longest side, its node values computed by the caller, possibly on several ranks): in each cell
//! the largest difference quotient of f along each axis's edges gives a slope s_x, s_y, s_z, and
//! the cell's bound is
//!
//! ```text
//! S = sqrt(s_x^2 + s_y^2 + s_z^2),   L = SAFETY * S.
//! ```
//!
//! A cell whose eight corners have the same sign and |f| > L r at every corner (r half the
//! cell's diagonal) cannot hold the surface, since every point of the cell is within r of a
//! corner. Rays cross such cells in one step, knowing the sign of f there without evaluating it.
//! In the other cells the ray advances by s = |f| / L, but at least h / [`MIN_STEP_DIVISOR`] and
//! at most h, evaluating f exactly at every sample. Here h is the length of ray that crosses a
//! cell's width along the axis it crosses soonest (min over the axes of h_a / |d_a|): a step of
//! h moves the ray by at most one cell width along every axis, and a ray across a flat box (a
//! solid of zero thickness) takes a few steps a cell, not the box's thinnest side's fraction of
//! its length. L is here the
//! largest over the cells such a step can reach (the cell and its neighbours on the side the ray
//! is heading). A sign change between two samples brackets the root; regula falsi with the
//! Illinois modification (every fourth step a bisection) narrows it to [`REFINE_TOLERANCE`] of
//! the bracket. The lower bound on the step is the one compromise: a part of the solid thinner
//! than h / 4 along the ray, in a cell that may hold the surface, can be missed. The lattice is
//! an estimate, not a proof: L is a sampled bound with the safety factor [`SAFETY`].
//!
//! # Parts thinner than a cell
//!
//! The corners of a cell see f only at the nodes: a part of the solid thinner than a cell (a
//! rod, a fin) can pass between them, every corner negative and far enough from zero for the
//! cell to count as away from the surface, and every ray crosses it in one step. A solid may
//! name points on its surface ([`Implicit::surface_points`]: a fitted model's data points, a
//! contour model's contour points).
//! Where one lies in a cell the corners class as away from the surface, the lattice missed a
//! part there ([`Lattice::look_closely`]): that cell and its neighbours are marked as cells that
//! may hold the surface, with an unbounded slope, so rays through them, or heading into them,
//! advance by the smallest step (h / [`MIN_STEP_DIVISOR`]). A part at least that thick along the
//! ray is then found wherever points mark it; cells of the usual surface, which the corners see,
//! hold the points already, and cost nothing more.
//!
//! The surface is looked for only inside the bounds; a ray that starts inside the solid (where
//! the solid reaches the bounds) is shown cut there.
//!
//! # Camera and shading
//!
//! The camera looks at the centre of the bounds from the direction given by an azimuth about the
//! up axis and an elevation above the plane normal to it, with a vertical field of view of
//! [`FIELD_OF_VIEW`] degrees; by default from the distance at which the ball around the bounds
//! just fills the view. Pixel (i, j) (j down from the top) is hit by the ray through its centre.
//! The outward normal is n = -grad f / |grad f|; shading is ambient plus Lambert from a light
//! above and to the left of the camera, plus a Blinn-Phong highlight.

use super::Implicit;

/// Cells of the lattice along the longest side of the bounds.
pub const LATTICE_CELLS: usize = 48;
/// The factor on the sampled gradient bound.
pub const SAFETY: f64 = 1.5;
/// The smallest step is the cell size over this.
pub const MIN_STEP_DIVISOR: f64 = 4.0;
/// The root is narrowed to this fraction of its first bracket (at most a cell wide).
pub const REFINE_TOLERANCE: f64 = 1e-3;
/// Vertical field of view in degrees.
pub const FIELD_OF_VIEW: f64 = 30.0;

/// The coordinate axis that points up in the picture.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Axis {
    X,
    Y,
    Z,
}

/// How a picture colours the surface.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Colouring {
    /// One matte colour, shaded.
    Shading,
    /// Mean curvature: red where convex, blue where concave, white where flat, shaded; the scale
    /// is the 95th percentile of |mean curvature| over the picture.
    Curvature,
}

/// The colour of the pixels whose ray misses the solid.
pub const BACKGROUND: [u8; 3] = [40, 44, 52];

/// The colour of a pixel from its light (ambient + diffuse, specular) and, for
/// [`Colouring::Curvature`], its mean curvature over the picture's scale.
pub fn pixel_colour(light: f64, specular: f64, curvature: Option<f64>) -> [u8; 3] {
    let base = match curvature {
        None => [0.85, 0.78, 0.62],
        Some(t) if t.is_nan() => [0.6, 0.6, 0.6],
        Some(t) => {
            let t = t.clamp(-1.0, 1.0);
            if t >= 0.0 {
                [1.0, 1.0 - t, 1.0 - t]
            } else {
                [1.0 + t, 1.0 + t, 1.0]
            }
        }
    };
    base.map(|b| ((b * light + specular).clamp(0.0, 1.0) * 255.0).round() as u8)
}

/// Where the camera is: angles in degrees, distance from the centre of the bounds (None: frame
/// the bounds), picture size in pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct View {
    pub azimuth: f64,
    pub elevation: f64,
    pub distance: Option<f64>,
    pub width: usize,
    pub height: usize,
    pub up: Axis,
}

/// A pinhole camera.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    pub eye: [f64; 3],
    pub forward: [f64; 3],
    pub right: [f64; 3],
    pub up: [f64; 3],
    /// tan of half the vertical field of view.
    pub tan_half: f64,
    /// The eye's distance from the centre of the box it looks at, and the radius of the ball
    /// round the box.
    pub distance: f64,
    pub radius: f64,
    pub width: usize,
    pub height: usize,
}

fn add(a: [f64; 3], b: [f64; 3], s: f64) -> [f64; 3] {
    [a[0] + s * b[0], a[1] + s * b[1], a[2] + s * b[2]]
}
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}
fn unit(a: [f64; 3]) -> [f64; 3] {
    let n = dot(a, a).sqrt();
    a.map(|v| v / n)
}

impl Camera {
    /// The camera of `view` looking at the centre of the box `bounds`.
    pub fn frame(bounds: ([f64; 3], [f64; 3]), view: &View) -> Camera {
        let (lo, hi) = bounds;
        let centre: [f64; 3] = std::array::from_fn(|d| 0.5 * lo[d] + 0.5 * hi[d]);
        let radius = 0.5 * (0..3).map(|d| (hi[d] - lo[d]).powi(2)).sum::<f64>().sqrt();
        let tan_half = (0.5 * FIELD_OF_VIEW).to_radians().tan();
        let distance = view.distance.unwrap_or(radius / (0.5 * FIELD_OF_VIEW).to_radians().sin());
        // up, then the two horizontal axes in right-handed order (a x b = up)
        let (u, a, b) = match view.up {
            Axis::X => (0, 1, 2),
            Axis::Y => (1, 2, 0),
            Axis::Z => (2, 0, 1),
        };
        let (az, el) = (view.azimuth.to_radians(), view.elevation.to_radians());
        let mut towards_eye = [0.0; 3];
        towards_eye[a] = el.cos() * az.cos();
        towards_eye[b] = el.cos() * az.sin();
        towards_eye[u] = el.sin();
        let mut world_up = [0.0; 3];
        world_up[u] = 1.0;
        let forward = towards_eye.map(|v| -v);
        let mut right = cross(forward, world_up);
        if dot(right, right) < 1e-20 {
            // looking straight up or down: the azimuth decides which way is right
            right = [0.0; 3];
            right[a] = -az.sin();
            right[b] = az.cos();
        }
        let right = unit(right);
        let up = cross(right, forward);
        Camera {
            eye: add(centre, towards_eye, distance),
            forward,
            right,
            up,
            tan_half,
            distance,
            radius,
            width: view.width,
            height: view.height,
        }
    }

    /// The unit direction of the ray through the centre of pixel (i, j), j down from the top.
    pub fn ray(&self, i: usize, j: usize) -> [f64; 3] {
        let scale = 2.0 * self.tan_half / self.height as f64;
        let x = (i as f64 + 0.5 - 0.5 * self.width as f64) * scale;
        let y = (0.5 * self.height as f64 - j as f64 - 0.5) * scale;
        unit(add(add(self.forward, self.right, x), self.up, y))
    }
}

/// f on a coarse lattice over the bounds, with a gradient bound and a may-hold-the-surface flag
/// per cell (see the module doc).
#[derive(Debug, Clone)]
pub struct Lattice {
    pub lo: [f64; 3],
    pub hi: [f64; 3],
    /// Cells per axis.
    pub cells: [usize; 3],
    pub h: [f64; 3],
    /// The sampled gradient bound of each cell, without the safety factor.
    slope: Vec<f64>,
    surface: Vec<bool>,
    inside: Vec<bool>,
}

impl Lattice {
    /// Cells per axis for `bounds`: [`LATTICE_CELLS`] along the longest side, at least one.
    pub fn cells_for(bounds: ([f64; 3], [f64; 3])) -> [usize; 3] {
        let ext: [f64; 3] = std::array::from_fn(|d| (bounds.1[d] - bounds.0[d]).abs());
        let longest = ext.iter().fold(0.0f64, |m, &v| m.max(v));
        ext.map(|e| ((LATTICE_CELLS as f64 * e / longest).round() as usize).max(1))
    }

    /// The position of node q (x fastest) of the lattice with `cells` over `bounds`.
    pub fn node(bounds: ([f64; 3], [f64; 3]), cells: [usize; 3], q: usize) -> [f64; 3] {
        let n = cells.map(|c| c + 1);
        let idx = [q % n[0], (q / n[0]) % n[1], q / (n[0] * n[1])];
        std::array::from_fn(|d| bounds.0[d] + (bounds.1[d] - bounds.0[d]) * idx[d] as f64 / cells[d] as f64)
    }

    /// The lattice from f at its nodes (x fastest, (cells + 1) per axis).
    pub fn new(bounds: ([f64; 3], [f64; 3]), cells: [usize; 3], values: &[f64]) -> Lattice {
        let (lo, hi) = bounds;
        let n = cells.map(|c| c + 1);
        assert_eq!(values.len(), n[0] * n[1] * n[2]);
        let h: [f64; 3] = std::array::from_fn(|d| ((hi[d] - lo[d]) / cells[d] as f64).max(f64::MIN_POSITIVE));
        let at = |i: usize, j: usize, k: usize| values[i + n[0] * (j + n[1] * k)];
        let ncell = cells[0] * cells[1] * cells[2];
        let mut slope = vec![0.0; ncell];
        let mut surface = vec![false; ncell];
        let mut inside = vec![false; ncell];
        let mut min_abs = vec![0.0; ncell];
        for k in 0..cells[2] {
            for j in 0..cells[1] {
                for i in 0..cells[0] {
                    let c = i + cells[0] * (j + cells[1] * k);
                    let corner = |o: usize| at(i + (o & 1), j + ((o >> 1) & 1), k + (o >> 2));
                    let mut s = [0.0f64; 3];
                    for o in 0..8 {
                        for (d, sd) in s.iter_mut().enumerate() {
                            if o & (1 << d) == 0 {
                                *sd = sd.max((corner(o | (1 << d)) - corner(o)).abs() / h[d]);
                            }
                        }
                    }
                    slope[c] = (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]).sqrt();
                    let first = corner(0) >= 0.0;
                    let same = (1..8).all(|o| (corner(o) >= 0.0) == first);
                    // a non-finite corner marks the cell for exact evaluation
                    let all_finite = (0..8).all(|o| corner(o).is_finite());
                    surface[c] = !same || !all_finite;
                    inside[c] = first;
                    min_abs[c] = (0..8).map(|o| corner(o).abs()).fold(f64::INFINITY, f64::min);
                }
            }
        }
        let half_diag = 0.5 * (h[0] * h[0] + h[1] * h[1] + h[2] * h[2]).sqrt();
        for c in 0..ncell {
            surface[c] = surface[c] || !(min_abs[c] > SAFETY * slope[c] * half_diag);
        }
        Lattice { lo, hi, cells, h, slope, surface, inside }
    }

    fn cell_of(&self, x: [f64; 3]) -> ([usize; 3], usize) {
        let ijk: [usize; 3] = std::array::from_fn(|d| {
            let v = ((x[d] - self.lo[d]) / self.h[d]).floor();
            if v > 0.0 {
                (v as usize).min(self.cells[d] - 1)
            } else {
                0
            }
        });
        (ijk, ijk[0] + self.cells[0] * (ijk[1] + self.cells[1] * ijk[2]))
    }

    /// Takes a close look around `points`, points on or near the surface
    /// ([`Implicit::surface_points`]), where the corners missed it (see the module doc, "Parts
    /// thinner than a cell"): each cell holding one of them that the corners class as away from
    /// the surface is marked, with its neighbours, as one that may hold it, with an unbounded
    /// slope. Rays through those cells, and rays heading into them, then advance by the
    /// smallest step and evaluate f at every sample. Points outside the bounds are passed over.
    /// Returns the number of cells the corners had missed.
    pub fn look_closely(&mut self, points: &[[f64; 3]]) -> usize {
        let mut missed: Vec<usize> = points
            .iter()
            .filter(|p| (0..3).all(|d| p[d] >= self.lo[d] && p[d] <= self.hi[d]))
            .map(|&p| self.cell_of(p).1)
            .filter(|&c| !self.surface[c])
            .collect();
        missed.sort_unstable();
        missed.dedup();
        let [cx, cy, cz] = self.cells;
        let around = |i: usize, n: usize| i.saturating_sub(1)..(i + 2).min(n);
        for &c in &missed {
            let (i, j, k) = (c % cx, (c / cx) % cy, c / (cx * cy));
            for kk in around(k, cz) {
                for jj in around(j, cy) {
                    for ii in around(i, cx) {
                        let n = ii + cx * (jj + cy * kk);
                        self.surface[n] = true;
                        self.slope[n] = f64::INFINITY;
                    }
                }
            }
        }
        missed.len()
    }

    /// How many cells may hold the surface.
    pub fn surface_cells(&self) -> usize {
        self.surface.iter().filter(|&&b| b).count()
    }

    /// SAFETY times the largest slope of the cells a step of at most one cell width from cell
    /// `ijk` along `d` can reach: the cell and its neighbours on the side `d` points to.
    fn lipschitz(&self, ijk: [usize; 3], d: [f64; 3]) -> f64 {
        let span = |a: usize| {
            let i = ijk[a];
            if d[a] > 0.0 {
                i..(i + 2).min(self.cells[a])
            } else if d[a] < 0.0 {
                i.saturating_sub(1)..i + 1
            } else {
                i..i + 1
            }
        };
        let mut m = 0.0f64;
        for k in span(2) {
            for j in span(1) {
                for i in span(0) {
                    m = m.max(self.slope[i + self.cells[0] * (j + self.cells[1] * k)]);
                }
            }
        }
        SAFETY * m
    }

    /// The length of the ray along `d` that crosses one cell width along the axis it crosses
    /// soonest: at least the shortest side of a cell (for a unit `d`).
    fn ray_h(&self, d: [f64; 3]) -> f64 {
        (0..3).filter(|&a| d[a] != 0.0).map(|a| self.h[a] / d[a].abs()).fold(f64::INFINITY, f64::min)
    }
}

/// The parameter interval where the ray o + t d is inside the box, if any (t >= 0).
fn clip(lo: [f64; 3], hi: [f64; 3], o: [f64; 3], d: [f64; 3]) -> Option<(f64, f64)> {
    let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
    for a in 0..3 {
        if d[a] == 0.0 {
            if o[a] < lo[a] || o[a] > hi[a] {
                return None;
            }
            continue;
        }
        let (ta, tb) = ((lo[a] - o[a]) / d[a], (hi[a] - o[a]) / d[a]);
        t0 = t0.max(ta.min(tb));
        t1 = t1.min(ta.max(tb));
    }
    (t0 <= t1).then_some((t0, t1))
}

/// The first point where the ray from `o` along the unit `d` meets f = 0 inside the lattice's
/// box: its parameter t (None if the ray misses).
pub fn first_root(solid: &dyn Implicit, lattice: &Lattice, o: [f64; 3], d: [f64; 3]) -> Option<f64> {
    march(solid, lattice, o, d).0
}

/// [`first_root`] with the number of samples the ray took.
fn march(solid: &dyn Implicit, lattice: &Lattice, o: [f64; 3], d: [f64; 3]) -> (Option<f64>, usize) {
    let Some((t0, t1)) = clip(lattice.lo, lattice.hi, o, d) else { return (None, 0) };
    let h = lattice.ray_h(d);
    let at = |t: f64| add(o, d, t);
    // the last sample: its parameter, whether it is inside, and f there if evaluated
    let mut prev: Option<(f64, bool, Option<f64>)> = None;
    let mut t = t0;
    let mut samples = 0;
    // each step is at least a quarter of h, and the ray crosses at most `cells` widths of the
    // soonest axis: this bound is never reached, and ends the loop however the steps round
    let limit = 16 * (lattice.cells.iter().sum::<usize>() + 1);
    while t <= t1 && samples < limit {
        samples += 1;
        let x = at(t);
        let (ijk, c) = lattice.cell_of(x);
        let (inside, f, next) = if lattice.surface[c] {
            let f = solid.value(x);
            let step = (f.abs() / lattice.lipschitz(ijk, d)).clamp(h / MIN_STEP_DIVISOR, h);
            (f >= 0.0, Some(f), t + if step.is_finite() { step } else { h / MIN_STEP_DIVISOR })
        } else {
            // across the cell in one step: to the nearest face it leaves through, and past it by
            // a few units in the last place of the coordinate it crosses, so that the next
            // sample lies in the next cell however far from the origin the solid is
            let (exit, axis) = (0..3)
                .filter(|&a| d[a] != 0.0)
                .map(|a| {
                    let face = lattice.lo[a] + lattice.h[a] * (ijk[a] + usize::from(d[a] > 0.0)) as f64;
                    ((face - o[a]) / d[a], a)
                })
                .fold((f64::INFINITY, 0), |best, e| if e.0 < best.0 { e } else { best });
            let nudge = (1e-9 * h).max(4.0 * f64::EPSILON * x[axis].abs() / d[axis].abs());
            (lattice.inside[c], None, exit.max(t) + nudge)
        };
        match prev {
            None if inside => return (Some(t), samples),
            Some((tp, was_inside, fp)) if was_inside != inside => {
                if let Some(root) = refine(solid, at, (tp, fp), (t, f)) {
                    return (Some(root), samples);
                }
            }
            _ => {}
        }
        prev = Some((t, inside, f));
        // a step below the last place of t (a box thinner than that along the ray) still moves on
        t = next.max(t.next_up());
    }
    (None, samples)
}

/// The root of f(at(t)) in [a, b] from a sign change (values evaluated where missing), or None
/// when the exact values do not change sign after all (a bracket from the lattice's estimate).
fn refine(
    solid: &dyn Implicit,
    at: impl Fn(f64) -> [f64; 3],
    a: (f64, Option<f64>),
    b: (f64, Option<f64>),
) -> Option<f64> {
    let (mut ta, mut tb) = (a.0, b.0);
    let mut fa = a.1.unwrap_or_else(|| solid.value(at(ta)));
    let mut fb = b.1.unwrap_or_else(|| solid.value(at(tb)));
    if (fa >= 0.0) == (fb >= 0.0) {
        return None;
    }
    let tol = REFINE_TOLERANCE * (tb - ta).abs().max(f64::MIN_POSITIVE) + 1e-12 * ta.abs();
    let mut side = 0i8;
    for it in 0..100 {
        if (tb - ta).abs() <= tol {
            break;
        }
        let mut tc = (ta * fb - tb * fa) / (fb - fa);
        if it % 4 == 3 || !(tc > ta.min(tb) && tc < ta.max(tb)) {
            tc = 0.5 * (ta + tb);
        }
        let fc = solid.value(at(tc));
        if fc == 0.0 {
            return Some(tc);
        }
        if (fc >= 0.0) == (fa >= 0.0) {
            ta = tc;
            fa = fc;
            if side == -1 {
                fb *= 0.5;
            }
            side = -1;
        } else {
            tb = tc;
            fb = fc;
            if side == 1 {
                fa *= 0.5;
            }
            side = 1;
        }
    }
    Some((ta * fb - tb * fa) / (fb - fa)).filter(|t| t.is_finite()).or(Some(0.5 * (ta + tb)))
}

/// Light reaching the eye from a surface point with gradient `g` seen along the ray `d`:
/// (ambient + diffuse, specular), each in [0, 1].
pub fn shade(camera: &Camera, g: [f64; 3], d: [f64; 3]) -> (f64, f64) {
    const AMBIENT: f64 = 0.25;
    let norm = dot(g, g).sqrt();
    if !(norm > 0.0) || !norm.is_finite() {
        return (AMBIENT, 0.0);
    }
    let mut n = g.map(|v| -v / norm);
    if dot(n, d) > 0.0 {
        // the back of the surface (a cut at the bounds, or the camera inside): lit as the front
        n = n.map(|v| -v);
    }
    let light = unit(add(add(camera.forward.map(|v| -v), camera.up, 0.6), camera.right, -0.4));
    let diffuse = dot(n, light).max(0.0);
    let half = unit(add(light, d, -1.0));
    let specular = dot(n, half).max(0.0).powi(40);
    (AMBIENT + (1.0 - AMBIENT) * diffuse, 0.3 * specular)
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Ball(f64);
    impl Implicit for Ball {
        fn value(&self, p: [f64; 3]) -> f64 {
            self.0 * self.0 - dot(p, p)
        }
        fn bounds(&self) -> ([f64; 3], [f64; 3]) {
            ([-1.2 * self.0; 3], [1.2 * self.0; 3])
        }
    }

    fn lattice_of(s: &dyn Implicit) -> Lattice {
        let b = s.bounds();
        let cells = Lattice::cells_for(b);
        let n = (cells[0] + 1) * (cells[1] + 1) * (cells[2] + 1);
        let values: Vec<f64> = (0..n).map(|q| s.value(Lattice::node(b, cells, q))).collect();
        Lattice::new(b, cells, &values)
    }

    #[test]
    fn rays_find_the_near_side_of_a_ball() {
        let ball = Ball(2.0);
        let lat = lattice_of(&ball);
        // from 10 units out along x, towards the centre and offset
        for off in [0.0, 0.5, 1.2, 1.9] {
            let o = [10.0, off, 0.0];
            let t = first_root(&ball, &lat, o, [-1.0, 0.0, 0.0]).unwrap();
            let want = 10.0 - (4.0f64 - off * off).sqrt();
            assert!((t - want).abs() < 1e-6, "offset {off}: {t} vs {want}");
        }
        assert!(first_root(&ball, &lat, [10.0, 2.05, 0.0], [-1.0, 0.0, 0.0]).is_none());
        // a ray starting inside the solid is cut at its start
        assert_eq!(first_root(&ball, &lat, [0.0, 0.0, 0.0], [1.0, 0.0, 0.0]), Some(0.0));
    }

    /// A ball: its centre, then its radius.
    struct Away([f64; 3], f64);
    impl Implicit for Away {
        fn value(&self, p: [f64; 3]) -> f64 {
            let q = add(p, self.0, -1.0);
            self.1 * self.1 - dot(q, q)
        }
        fn bounds(&self) -> ([f64; 3], [f64; 3]) {
            (self.0.map(|c| c - 1.2 * self.1), self.0.map(|c| c + 1.2 * self.1))
        }
    }

    #[test]
    fn rays_cross_a_solid_far_from_the_origin_in_a_few_steps_a_cell() {
        // at 1e12 a coordinate's last place is 1.2e-4, a millionth of the cell: a nudge of 1e-9
        // cells past a face left the sample in the cell it leaves about half the time, for
        // about a million steps each (a picture of such a solid took minutes a row)
        for c in [[0.0; 3], [1e12, -3e11, 0.0]] {
            let ball = Away(c, 2.0);
            let lat = lattice_of(&ball);
            let cells = Lattice::cells_for(ball.bounds()).iter().sum::<usize>();
            let o = add(c, [10.0, 0.5, 0.0], 1.0);
            let (t, samples) = march(&ball, &lat, o, [-1.0, 0.0, 0.0]);
            let want = 10.0 - (4.0f64 - 0.25).sqrt();
            assert!((t.unwrap() - want).abs() < 1e-3, "{t:?} vs {want}");
            assert!(samples <= 2 * cells, "{samples} samples, {cells} cells along the axes");
            // a ray passing by, across empty cells from side to side
            let (t, samples) = march(&ball, &lat, add(c, [10.0, 0.3, 2.3], 1.0), unit([-1.0, 0.01, 0.0]));
            assert!(t.is_none() && samples > 5 && samples <= 2 * cells, "{t:?}, {samples} samples");
        }
    }

    /// The rod y^2 + z^2 <= 0.01 along x in the box [-5.5, 5.5] x [-0.6, 0.6]^2, with points
    /// on its surface.
    struct Rod;
    impl Implicit for Rod {
        fn value(&self, p: [f64; 3]) -> f64 {
            0.01 - p[1] * p[1] - p[2] * p[2]
        }
        fn bounds(&self) -> ([f64; 3], [f64; 3]) {
            ([-5.5, -0.6, -0.6], [5.5, 0.6, 0.6])
        }
        fn surface_points(&self) -> Vec<[f64; 3]> {
            (0..200)
                .map(|i| (i as f64 * 2.4, -5.0 + 0.05 * i as f64))
                .map(|(a, x)| [x, 0.1 * a.cos(), 0.1 * a.sin()])
                .collect()
        }
    }

    #[test]
    fn a_rod_between_the_nodes_is_found_where_its_points_mark_it() {
        let mut lat = lattice_of(&Rod);
        // 48 cells along x, 5 across (0.24 wide): the nodes nearest the axis lie 0.17 from it,
        // every corner of the middle column of cells is negative, and no ray down across the
        // rod samples f there
        assert_eq!(lat.cells, [48, 5, 5]);
        let down = |lat: &Lattice, x: f64| first_root(&Rod, lat, [x, 0.0, 10.0], [0.0, 0.0, -1.0]);
        for x in [-4.95, -2.0, 0.0, 1.3, 4.9] {
            assert!(down(&lat, x).is_none(), "x = {x}");
        }
        // the points lie in that column's cells from x = -5 to 4.95: 44 of the 48
        assert_eq!(lat.look_closely(&Rod.surface_points()), 44);
        for x in [-4.95, -2.0, 0.0, 1.3, 4.9] {
            let t = down(&lat, x).unwrap_or_else(|| panic!("x = {x}: the ray misses the rod"));
            assert!((t - 9.9).abs() < 1e-6 * 10.0, "x = {x}: t = {t}");
        }
        // a ball's points lie in cells the corners see already: nothing changes
        let ball = Ball(2.0);
        let mut lat = lattice_of(&ball);
        let before = lat.surface_cells();
        let on: Vec<[f64; 3]> = (0..500)
            .map(|i| {
                let (z, a) = (1.0 - 2.0 * (i as f64 + 0.5) / 500.0, 2.4 * i as f64);
                let r = (1.0 - z * z).sqrt();
                [2.0 * r * a.cos(), 2.0 * r * a.sin(), 2.0 * z]
            })
            .collect();
        assert_eq!(lat.look_closely(&on), 0);
        assert_eq!(lat.surface_cells(), before);
    }

    /// The disc x^2 + y^2 <= 1 of the box [-2, 2]^2 x [0, thickness].
    struct Flat(f64);
    impl Implicit for Flat {
        fn value(&self, p: [f64; 3]) -> f64 {
            1.0 - p[0] * p[0] - p[1] * p[1]
        }
        fn bounds(&self) -> ([f64; 3], [f64; 3]) {
            ([-2.0, -2.0, 0.0], [2.0, 2.0, self.0])
        }
    }

    #[test]
    fn rays_cross_a_box_of_next_to_no_thickness_in_a_few_steps() {
        // a box 1e-300 thick (contour slices that close) made steps of a quarter of its thickness,
        // below the last place of t, so the ray stood still; 1e-6 made billions of steps
        for thickness in [1e-300, 1e-6, 0.5] {
            let flat = Flat(thickness);
            let lat = lattice_of(&flat);
            let cells = Lattice::cells_for(flat.bounds()).iter().sum::<usize>();
            for (o, d) in [
                ([-8.0, 0.3, 0.5 * thickness], [1.0, 0.0, 0.0]),
                ([-8.0, 0.3, 8.0], unit([1.0, 0.01, -1.0])),
                ([-8.0, 1.5, 0.5 * thickness], unit([1.0, 0.1, 0.0])),
            ] {
                let (t, samples) = march(&flat, &lat, o, d);
                assert!(samples <= 8 * cells, "{thickness:e}, {d:?}: {samples} samples for {cells} cells");
                if d[2] == 0.0 && o[1] < 1.0 {
                    let want = 8.0 - (1.0f64 - 0.09).sqrt();
                    assert!((t.unwrap() - want).abs() < 1e-3, "{thickness:e}: {t:?} vs {want}");
                }
            }
        }
    }

    #[test]
    fn the_default_camera_frames_the_bounds() {
        let view = View { azimuth: 0.0, elevation: 0.0, distance: None, width: 64, height: 48, up: Axis::Z };
        let cam = Camera::frame(([-1.0; 3], [1.0; 3]), &view);
        // looking from +x at the origin, z up, the centre pixel's ray points along -x
        assert!((cam.eye[0] - 3f64.sqrt() / (15f64.to_radians().sin())).abs() < 1e-12);
        assert!(cam.eye[1].abs() < 1e-12 && cam.eye[2].abs() < 1e-12);
        assert!((cam.up[2] - 1.0).abs() < 1e-12 && (cam.right[1] - 1.0).abs() < 1e-12);
        let top = cam.ray(32, 0);
        assert!(top[2] > 0.0);
    }
}
