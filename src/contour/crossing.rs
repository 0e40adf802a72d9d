//! Contours that cross: a contour crossing itself (a figure eight, a loop traced twice round) or
//! two contours of one slice crossing each other. The slice's spline is zero at every contour
//! point and takes its sign from the carrier, so it still fits, but the section's inside is not
//! what any reading of the drawing means: near a crossing the surface pinches, or fills a lobe
//! that should be empty. Hand-traced and segmented contours cross by mistake, so the run names
//! the places for the user to mend, and goes on.
//!
//! Two edges cross when each one's endpoints lie strictly on opposite sides of the other's line
//! (orientation tests, exact in their sign up to rounding of the products). Edges that share a
//! point, or only touch, do not count: the contours `volspline slice` cuts from a closed mesh
//! touch where the plane passes through a vertex, and that is no mistake. The edges are swept in
//! order of their smallest a coordinate, so only edges whose a-ranges overlap are compared.

use super::format::Section;

/// The most crossings counted in one slice: enough to tell a slip from a drawing that crosses
/// everywhere, without sweeping on through a pathological one.
pub const COUNTED_PER_SLICE: usize = 1000;

/// Where two edges of one slice's contours cross.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Crossing {
    /// The contours (indices in the slice, from 0; the same twice when a contour crosses itself).
    pub contours: [usize; 2],
    /// The crossing point in the slice's own coordinates (a, b).
    pub at: [f64; 2],
}

/// An edge: contour, index of its first point, endpoints.
struct Edge {
    contour: usize,
    index: usize,
    p: [f64; 2],
    q: [f64; 2],
}

impl Edge {
    fn lo(&self) -> f64 {
        self.p[0].min(self.q[0])
    }
    fn hi(&self) -> f64 {
        self.p[0].max(self.q[0])
    }
}

/// Twice the signed area of the triangle (o, a, b).
fn orient(o: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
}

/// The crossings of the contours of `section`, at most `limit` of them (ordered by the sweep),
/// and how many were found in all when that is more (counting stops at `count_up_to`).
pub fn crossings(section: &Section, limit: usize, count_up_to: usize) -> (Vec<Crossing>, usize) {
    let mut edges: Vec<Edge> = section
        .contours
        .iter()
        .enumerate()
        .flat_map(|(c, pts)| {
            (0..pts.len()).map(move |i| Edge { contour: c, index: i, p: pts[i], q: pts[(i + 1) % pts.len()] })
        })
        .collect();
    edges.sort_by(|x, y| x.lo().total_cmp(&y.lo()));
    let mut found = Vec::new();
    let mut count = 0;
    for (i, e) in edges.iter().enumerate() {
        for f in edges[i + 1..].iter().take_while(|f| f.lo() <= e.hi()) {
            if e.contour == f.contour && adjacent(e.index, f.index, section.contours[e.contour].len()) {
                continue;
            }
            if e.p[1].max(e.q[1]) < f.p[1].min(f.q[1]) || f.p[1].max(f.q[1]) < e.p[1].min(e.q[1]) {
                continue;
            }
            let (d1, d2) = (orient(f.p, f.q, e.p), orient(f.p, f.q, e.q));
            let (d3, d4) = (orient(e.p, e.q, f.p), orient(e.p, e.q, f.q));
            if d1 * d2 < 0.0 && d3 * d4 < 0.0 {
                count += 1;
                if found.len() < limit {
                    let t = d1 / (d1 - d2);
                    let at = [e.p[0] + t * (e.q[0] - e.p[0]), e.p[1] + t * (e.q[1] - e.p[1])];
                    found.push(Crossing { contours: [e.contour, f.contour], at });
                }
                if count >= count_up_to {
                    return (found, count);
                }
            }
        }
    }
    (found, count)
}

/// Whether edges i and j of a closed contour of n points share a point.
fn adjacent(i: usize, j: usize, n: usize) -> bool {
    i == j || (i + 1) % n == j || (j + 1) % n == i
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{DMat3, DVec3};

    fn slice(contours: Vec<Vec<[f64; 2]>>) -> Section {
        Section { line: 3, origin: DVec3::ZERO, frame: DMat3::IDENTITY, kind: "z", contours }
    }

    fn square(x: f64, y: f64, s: f64) -> Vec<[f64; 2]> {
        vec![[x, y], [x + s, y], [x + s, y + s], [x, y + s]]
    }

    #[test]
    fn figure_eights_and_overlapping_contours_cross_and_nested_or_touching_ones_do_not() {
        // a bow tie: edges (0,0)-(1,1) and (1,0)-(0,1) cross at the centre
        let (c, n) = crossings(&slice(vec![vec![[0.0, 0.0], [1.0, 1.0], [1.0, 0.0], [0.0, 1.0]]]), 8, 100);
        assert_eq!(n, 1);
        assert_eq!(c[0].contours, [0, 0]);
        assert!((c[0].at[0] - 0.5).abs() < 1e-15 && (c[0].at[1] - 0.5).abs() < 1e-15, "{c:?}");
        // two overlapping squares cross twice
        let (c, n) = crossings(&slice(vec![square(0.0, 0.0, 2.0), square(1.0, 1.0, 2.0)]), 8, 100);
        assert_eq!(n, 2);
        assert!(c.iter().all(|x| x.contours == [0, 1] || x.contours == [1, 0]), "{c:?}");
        // a ring (one square inside another), squares side by side sharing an edge's stretch,
        // and a square touching another at a corner: no crossing
        for contours in [
            vec![square(0.0, 0.0, 4.0), square(1.0, 1.0, 2.0)],
            vec![square(0.0, 0.0, 1.0), square(1.0, 0.0, 1.0)],
            vec![square(0.0, 0.0, 1.0), square(1.0, 1.0, 1.0)],
            vec![vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]],
        ] {
            assert_eq!(crossings(&slice(contours.clone()), 8, 100).1, 0, "{contours:?}");
        }
        // a star polygon {5/2} traced through every second point crosses itself five times;
        // the list stops at the limit and the count at its bound
        let star: Vec<[f64; 2]> = (0..5)
            .map(|k| {
                let a = std::f64::consts::TAU * (2 * k) as f64 / 5.0;
                [a.cos(), a.sin()]
            })
            .collect();
        assert_eq!(crossings(&slice(vec![star.clone()]), 8, 100).1, 5);
        let (c, n) = crossings(&slice(vec![star]), 2, 4);
        assert_eq!((c.len(), n), (2, 4));
    }
}
