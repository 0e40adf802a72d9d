//! The cases of marching cubes: for every cell configuration, the closed loops of edge
//! crossings that bound the inside region, derived from the cell's six faces.
//!
//! The classic 256-case table is not typed in. A cell's corners are inside or outside
//! (`value >= iso`), which gives 256 corner masks; a face whose inside corners are diagonal
//! (two inside, two outside, alternating) is ambiguous, and whether its inside corners are joined
//! across it is decided from its four values by Nielson & Hamann's asymptotic decider
//! ([`face_connected`]). Given the mask and the decisions, the loops follow from the faces alone
//! ([`build_case`]); all 256 x 64 of them are built once, on first use ([`tables`]). Because a
//! face's decision depends only on its four values, the two cells sharing a face always agree,
//! which makes the surface watertight across cells and across slabs.

use std::sync::OnceLock;

/// Cube corners are numbered `c = dx + 2 * dy + 4 * dz`. Edges are grouped by
/// axis (x: 0..4, y: 4..8, z: 8..12), each listed from its lower corner so the
/// first corner is the node the global edge id is attached to.
pub(super) const EDGE_CORNERS: [[usize; 2]; 12] =
    [[0, 1], [2, 3], [4, 5], [6, 7], [0, 2], [1, 3], [4, 6], [5, 7], [0, 4], [1, 5], [2, 6], [3, 7]];

/// Corners of each face, counter-clockwise seen from outside the cell
/// (faces: x = 0, x = 1, y = 0, y = 1, z = 0, z = 1).
const FACES: [[usize; 4]; 6] =
    [[0, 4, 6, 2], [1, 3, 7, 5], [0, 1, 5, 4], [2, 6, 7, 3], [0, 2, 3, 1], [4, 5, 7, 6]];

/// Twelve crossings at most, each loop has at least three.
const MAX_LOOPS: usize = 4;

/// The closed crossing loops of one (corner signs, face decisions) case, stored
/// already oriented so that triangles following loop order face outward.
#[derive(Clone, Copy, Default)]
pub(super) struct Case {
    n_loops: u8,
    lens: [u8; MAX_LOOPS],
    edges: [u8; 12],
}

impl Case {
    /// The loops, each a cycle of cell edges (numbered as in [`EDGE_CORNERS`]).
    pub(super) fn loops(&self) -> impl Iterator<Item = &[u8]> {
        let mut off = 0;
        self.lens[..usize::from(self.n_loops)].iter().map(move |&len| {
            let lp = &self.edges[off..off + usize::from(len)];
            off += usize::from(len);
            lp
        })
    }
}

pub(super) struct Tables {
    /// Indexed by `mask << 6 | connected`, where bit `f` of `connected` says
    /// that the inside corners of ambiguous face `f` are joined across it.
    cases: Vec<Case>,
    /// Bit `f` set when face `f` is ambiguous for this corner mask.
    ambiguous: [u8; 256],
    /// Whether two cell edges lie on a common face.
    pub(super) share_face: [[bool; 12]; 12],
}

impl Tables {
    /// The case of a cell whose inside corners are the set bits of `mask`. The eight corner
    /// values are asked for only when a face is ambiguous, to decide it.
    pub(super) fn case(&self, mask: usize, iso: f64, values: impl FnOnce() -> [f64; 8]) -> &Case {
        let amb = self.ambiguous[mask];
        let mut connected = 0u8;
        if amb != 0 {
            let v = values();
            for (f, q) in FACES.iter().enumerate() {
                if amb >> f & 1 == 1 && face_connected(q.map(|k| v[k]), iso) {
                    connected |= 1 << f;
                }
            }
        }
        &self.cases[mask << 6 | usize::from(connected)]
    }

    /// Every case that can occur, with its corner mask: decisions only on ambiguous faces.
    #[cfg(test)]
    pub(super) fn each_case(&self) -> impl Iterator<Item = (usize, &Case)> {
        (0..256 * 64)
            .filter(|idx| (idx & 63) as u8 & !self.ambiguous[idx >> 6] == 0)
            .map(|idx| (idx >> 6, &self.cases[idx]))
    }
}

/// The tables, built on first use.
pub(super) fn tables() -> &'static Tables {
    static TABLES: OnceLock<Tables> = OnceLock::new();
    TABLES.get_or_init(build_tables)
}

fn edge_of(a: usize, b: usize) -> usize {
    let (lo, hi) = if a < b { (a, b) } else { (b, a) };
    EDGE_CORNERS.iter().position(|e| e[0] == lo && e[1] == hi).unwrap_or(0)
}

/// Edge `m` of a face joins its corners `m` and `m + 1`.
fn face_edges(f: usize) -> [usize; 4] {
    let q = FACES[f];
    [0, 1, 2, 3].map(|m| edge_of(q[m], q[(m + 1) % 4]))
}

fn build_tables() -> Tables {
    let mut share_face = [[false; 12]; 12];
    for f in 0..6 {
        for a in face_edges(f) {
            for b in face_edges(f) {
                share_face[a][b] = a != b;
            }
        }
    }
    let mut ambiguous = [0u8; 256];
    for (mask, amb) in ambiguous.iter_mut().enumerate() {
        for (f, q) in FACES.iter().enumerate() {
            let s = q.map(|c| mask >> c & 1 == 1);
            if s[0] == s[2] && s[1] == s[3] && s[0] != s[1] {
                *amb |= 1 << f;
            }
        }
    }
    let cases = (0..256 * 64).map(|idx| build_case(idx >> 6, (idx & 63) as u8)).collect();
    Tables { cases, ambiguous, share_face }
}

/// Builds the loops of one case from its faces.
///
/// On each face the boundary of the inside region, walked with the inside on
/// the left (seen from outside the cell), is a set of segments from an "exit"
/// crossing (inside corner followed by an outside one in counter-clockwise
/// order) to an "entry" crossing. A crossing edge lies on two faces, which walk
/// it in opposite directions, so it is an exit on one and an entry on the other:
/// following exits to entries therefore splits the crossings into disjoint
/// closed loops.
fn build_case(mask: usize, connected: u8) -> Case {
    let mut next = [usize::MAX; 12];
    for (f, q) in FACES.iter().enumerate() {
        let s = q.map(|c| mask >> c & 1 == 1);
        let e = face_edges(f);
        let crossings = (0..4).filter(|&m| s[m] != s[(m + 1) % 4]).count();
        for m in 0..4 {
            let is_exit = s[m] && !s[(m + 1) % 4];
            if !is_exit {
                continue;
            }
            let entry = if crossings == 4 {
                // Joined inside corners: the inside band turns towards the
                // next inside corner; separated: it closes around this corner.
                if connected >> f & 1 == 1 {
                    (m + 1) % 4
                } else {
                    (m + 3) % 4
                }
            } else {
                match (0..4).find(|&n| !s[n] && s[(n + 1) % 4]) {
                    Some(n) => n,
                    None => continue,
                }
            };
            next[e[m]] = e[entry];
        }
    }
    let mut case = Case::default();
    let mut seen = [false; 12];
    let mut used = 0usize;
    for start in 0..12 {
        if next[start] == usize::MAX || seen[start] || usize::from(case.n_loops) == MAX_LOOPS {
            continue;
        }
        let mut lp = Vec::with_capacity(12);
        let mut e = start;
        while e != usize::MAX && !seen[e] {
            seen[e] = true;
            lp.push(e as u8);
            e = next[e];
        }
        // Walking exits to entries circles the inside corners clockwise seen
        // from outside the solid; reversing gives outward-facing triangles.
        lp.reverse();
        case.edges[used..used + lp.len()].copy_from_slice(&lp);
        case.lens[usize::from(case.n_loops)] = lp.len() as u8;
        case.n_loops += 1;
        used += lp.len();
    }
    case
}

/// Asymptotic decider: are the two inside corners of an ambiguous face joined
/// across it?
///
/// With `w = v - iso` the bilinear saddle value minus `iso` is
/// `(w0 w2 - w1 w3) / (w0 + w2 - w1 - w3)`; on an ambiguous face the
/// denominator is non-zero and has the sign of the inside diagonal, so the test
/// `saddle >= iso` reduces to "product of the inside diagonal >= product of the
/// outside diagonal" without any division by a possibly tiny denominator. The
/// products are symmetric in corner order, so both cells sharing the face get
/// the same answer bit for bit. Faces with a NaN corner count as separated.
fn face_connected(v: [f64; 4], iso: f64) -> bool {
    let w = v.map(|x| x - iso);
    if w.iter().any(|x| x.is_nan()) {
        return false;
    }
    // Scaling keeps the products away from overflow for huge values; the
    // maximum is order independent, so neighbours still agree exactly.
    let m = w.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let w = if m.is_finite() && m > 0.0 { w.map(|x| x / m) } else { w };
    let (inside, outside) = if v[0] >= iso { (w[0] * w[2], w[1] * w[3]) } else { (w[1] * w[3], w[0] * w[2]) };
    inside >= outside
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::testutil::{cross, dot, sub, Lcg};

    fn corner(c: usize) -> [f64; 3] {
        [(c & 1) as f64, (c >> 1 & 1) as f64, (c >> 2 & 1) as f64]
    }

    #[test]
    fn faces_are_counter_clockwise_from_outside() {
        for q in FACES {
            let p = q.map(corner);
            let nrm = cross(sub(p[1], p[0]), sub(p[2], p[0]));
            let centre = [0, 1, 2].map(|a| p.iter().map(|x| x[a]).sum::<f64>() / 4.0);
            let outward = sub(centre, [0.5; 3]);
            assert!(dot(nrm, outward) > 0.0, "face {q:?}");
            for m in 0..4 {
                let (a, b) = (q[m], q[(m + 1) % 4]);
                assert_eq!((a ^ b).count_ones(), 1, "face {q:?} not cyclic");
            }
        }
    }

    #[test]
    fn every_case_has_closed_loops_along_faces_through_every_crossing() {
        let t = tables();
        for (mask, case) in t.each_case() {
            let crossing: Vec<usize> = (0..12)
                .filter(|&e| {
                    let [a, b] = EDGE_CORNERS[e];
                    (mask >> a & 1) != (mask >> b & 1)
                })
                .collect();
            let mut all: Vec<usize> = Vec::new();
            for lp in case.loops() {
                let len = lp.len();
                assert!(len >= 3, "mask {mask} loop {lp:?}");
                for s in 0..len {
                    let (a, b) = (usize::from(lp[s]), usize::from(lp[(s + 1) % len]));
                    assert!(t.share_face[a][b], "mask {mask}: {a}->{b} not on a face");
                }
                all.extend(lp.iter().map(|&e| usize::from(e)));
            }
            all.sort_unstable();
            assert_eq!(all, crossing, "mask {mask} loops {:?}", case.loops().collect::<Vec<_>>());
        }
    }

    #[test]
    fn decider_matches_saddle_formula() {
        let mut rng = Lcg(7);
        for _ in 0..10_000 {
            let iso = rng.range(-0.5, 0.5);
            let mut v = [0.0; 4];
            let inside_even = rng.unit() < 0.5;
            for (m, x) in v.iter_mut().enumerate() {
                let mag = rng.range(1e-3, 2.0);
                *x = if (m % 2 == 0) == inside_even { iso + mag } else { iso - mag };
            }
            let saddle = (v[0] * v[2] - v[1] * v[3]) / (v[0] + v[2] - v[1] - v[3]);
            if (saddle - iso).abs() < 1e-9 {
                continue;
            }
            assert_eq!(face_connected(v, iso), saddle >= iso, "{v:?} iso {iso}");
            // Neighbours list the face in another order; the answer must agree.
            assert_eq!(face_connected(v, iso), face_connected([v[1], v[0], v[3], v[2]], iso));
            assert_eq!(face_connected(v, iso), face_connected([v[2], v[3], v[0], v[1]], iso));
        }
        assert!(!face_connected([1.0, f64::NAN, 1.0, -1.0], 0.0));
    }
}
