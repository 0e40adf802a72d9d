//! A variable-depth octree over 3D points: neighbour search within a radius and an ordering of
//! the points that makes the matrix of a compactly supported kernel banded. Pure and serial (the
//! callers thread over their own queries).
//!
//! # Construction (Algorithm I of Kojekine, Savchenko, Berzin and Hagiwara, 2001)
//!
//! The root cell is the bounding cube of the points (the bounding box's lower corner and its
//! longest side). A cell holding more than K points (the leaf capacity, 10 by default) is cut
//! into its eight octants and each octant that holds a point becomes a child; a cell with at most
//! K points is a leaf. Empty octants are never created, so the tree adapts its depth to the data:
//! a surface sampled densely in one place and sparsely in another gets deep and shallow branches.
//!
//! When all the points of a cell fall into one octant the cell would get a single child. Such a
//! node answers no question its child cannot, so it is removed and replaced by the child (the
//! pruning step of the construction): here the cell simply shrinks to that octant and is cut
//! again. Long chains of single children appear where points are much closer to each other than
//! to everything else, and mostly for small K. [`OctreeStats`] reports the nodes kept, the
//! nodes removed and the number of levels, the figures by which the tree is usually described
//! (so many nodes at so many levels). Coincident points are never separated by cutting; below
//! [`MAX_LEVEL`] halvings of the root a cell is a leaf whatever it holds.
//!
//! The points of every node are contiguous in the tree's own order of the points (a node's
//! range is the concatenation of its children's), and each node keeps the tight bounding box of
//! its points, which is never larger than its cell and prunes searches better.
//!
//! # Search (Algorithm II)
//!
//! The points within distance r of a query are found by walking down from the root and
//! classifying each node's box against the r-sphere: (b) entirely outside it (skipped), (a)
//! entirely inside it (all its points are taken without looking at them), or (c) partly inside
//! (its children are classified in turn; a leaf's points are tested one by one). The nearest and
//! farthest points of a box from the query are found axis by axis, so both tests cost a few
//! operations. The same walk answers a slightly more general question that row evaluation needs:
//! the points within r of an axis-aligned box (a segment of a grid row, say): the distance from a
//! point to a box is sqrt(sum over axes of gap_d^2), gap_d = max(lo_d - p_d, p_d - hi_d, 0),
//! and a sphere is the box with lo = hi = the centre.
//!
//! Both classifications are exact in floating point: the computed distance of a point is a
//! monotone function of each of its coordinates, so the computed distances of a box's corners
//! bound those of its points. A point is reported if and only if its computed squared distance
//! is at most r^2, whichever way the walk reached it.
//!
//! # Ordering (Algorithm III)
//!
//! With a compactly supported kernel of support R, row i of the matrix has its nonzeros in the
//! columns of the points within R of point i. Numbered as they come, neighbours can be far apart
//! in the numbering and the nonzeros are scattered over the whole row. [`Octree::order`]
//! renumbers the points breadth first through the neighbour graph: take the first point not yet
//! numbered, number it, then go through the numbered points in their new order and number each
//! one's neighbours not yet numbered (in increasing input index); when the list runs dry without
//! covering everything (the graph is not connected), start again from the first point left. Each
//! point's neighbours then follow it closely, so the nonzeros of every row lie in a band next to
//! the diagonal: the envelope (for each row, the distance from its first nonzero to the diagonal)
//! becomes small, which is what an envelope (profile) Cholesky factorisation stores and works on.
//! This is the Cuthill-McKee ordering without the sort of each level by degree; reversing it (the
//! reverse Cuthill-McKee ordering) never enlarges the envelope and often shrinks it further.

/// The leaf capacity K used unless told otherwise.
pub const DEFAULT_LEAF_CAPACITY: usize = 10;

/// Halvings of the root cell after which a cell is a leaf whatever it holds: only points closer
/// than 2^-48 of the data's extent, coincident for every practical purpose, are left together.
pub const MAX_LEVEL: usize = 48;

/// An octree over a fixed set of points.
#[derive(Debug, Clone)]
pub struct Octree {
    /// The points in tree order (each node's points are contiguous).
    pts: Vec<[f64; 3]>,
    /// `index[t]` is the input index of the point at tree position t.
    index: Vec<usize>,
    /// `at[i]` is the tree position of input point i (the inverse of `index`).
    at: Vec<usize>,
    nodes: Vec<Node>,
    capacity: usize,
    stats: OctreeStats,
}

#[derive(Debug, Clone)]
struct Node {
    /// The tight bounding box of the node's points.
    lo: [f64; 3],
    hi: [f64; 3],
    /// The node's points are tree positions start..end.
    start: usize,
    end: usize,
    /// Children are nodes first_child..first_child + children (none for a leaf).
    first_child: usize,
    children: usize,
}

/// The size of a tree.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct OctreeStats {
    /// Nodes in the tree (after pruning), leaves included.
    pub nodes: usize,
    pub leaves: usize,
    /// Levels of the pruned tree (1 for a tree that is a single leaf).
    pub levels: usize,
    /// Single-child nodes removed by pruning.
    pub pruned: usize,
    /// The most halvings of the root cell that any leaf's cell underwent.
    pub finest_level: usize,
    /// The most points in one leaf (more than K only for coincident points).
    pub largest_leaf: usize,
}

/// How a node's box lies with respect to the searched region.
enum Class {
    Outside,
    Inside,
    Partial,
}

impl Octree {
    /// The tree of `points` (3 coordinates per point) with leaf capacity `capacity` (K; 0 is
    /// taken as 1).
    pub fn new(points: &[f64], capacity: usize) -> Octree {
        assert_eq!(points.len() % 3, 0, "points come as x, y, z triples");
        let capacity = capacity.max(1);
        let mut pts: Vec<[f64; 3]> = points.chunks_exact(3).map(|p| [p[0], p[1], p[2]]).collect();
        let mut index: Vec<usize> = (0..pts.len()).collect();
        let mut tree = Octree {
            pts: Vec::new(),
            index: Vec::new(),
            at: Vec::new(),
            nodes: Vec::new(),
            capacity,
            stats: Default::default(),
        };
        if pts.is_empty() {
            return tree;
        }
        let (lo, hi) = bounds(&pts);
        let side = (0..3).map(|d| hi[d] - lo[d]).fold(0.0, f64::max);
        tree.nodes.push(Node { lo, hi, start: 0, end: pts.len(), first_child: 0, children: 0 });
        // (node, its cell's lower corner, the cell's side, halvings of the root, tree level)
        let mut stack = vec![(0usize, lo, side, 0usize, 1usize)];
        let mut scratch = Vec::new();
        let mut stats = OctreeStats { levels: 1, ..Default::default() };
        while let Some((id, mut corner, mut side, mut level, depth)) = stack.pop() {
            let (start, end) = (tree.nodes[id].start, tree.nodes[id].end);
            stats.levels = stats.levels.max(depth);
            let counts = loop {
                if end - start <= capacity || level >= MAX_LEVEL || !(side > 0.0) {
                    break None;
                }
                let c = split(&mut pts[start..end], &mut index[start..end], corner, side, &mut scratch);
                side *= 0.5;
                level += 1;
                let occupied: Vec<usize> = (0..8).filter(|&o| c[o + 1] > c[o]).collect();
                if occupied.len() > 1 {
                    break Some(c);
                }
                // a single occupied octant: the node is replaced by its only child
                stats.pruned += 1;
                corner = octant_corner(corner, side, occupied[0]);
            };
            let Some(c) = counts else {
                stats.leaves += 1;
                stats.finest_level = stats.finest_level.max(level);
                stats.largest_leaf = stats.largest_leaf.max(end - start);
                continue;
            };
            let first = tree.nodes.len();
            for o in 0..8 {
                let (s, e) = (start + c[o], start + c[o + 1]);
                if e > s {
                    let (blo, bhi) = bounds(&pts[s..e]);
                    stack.push((tree.nodes.len(), octant_corner(corner, side, o), side, level, depth + 1));
                    tree.nodes.push(Node { lo: blo, hi: bhi, start: s, end: e, first_child: 0, children: 0 });
                }
            }
            tree.nodes[id].first_child = first;
            tree.nodes[id].children = tree.nodes.len() - first;
        }
        stats.nodes = tree.nodes.len();
        tree.at = vec![0; pts.len()];
        for (t, &i) in index.iter().enumerate() {
            tree.at[i] = t;
        }
        tree.pts = pts;
        tree.index = index;
        tree.stats = stats;
        tree
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.pts.len()
    }

    pub fn is_empty(&self) -> bool {
        self.pts.is_empty()
    }

    /// The leaf capacity K.
    pub fn capacity(&self) -> usize {
        self.capacity
    }

    pub fn stats(&self) -> OctreeStats {
        self.stats
    }

    /// Point `i` (input index).
    pub fn point(&self, i: usize) -> [f64; 3] {
        self.pts[self.at[i]]
    }

    /// Replaces `out` with the input indices of all points p with |p - x| <= r (the squared
    /// distance summed over x, y, z in that order, compared with r * r), in the tree's order.
    pub fn within(&self, x: [f64; 3], r: f64, out: &mut Vec<usize>) {
        self.near_box(x, x, r, out);
    }

    /// Whether some point p has |p - x| <= r: the answer of `within(x, r, ..)` being non-empty,
    /// by the same comparisons, but without collecting the points and stopping at the first.
    pub fn any_within(&self, x: [f64; 3], r: f64) -> bool {
        !self.nodes.is_empty() && r >= 0.0 && self.any_near(0, x, r * r)
    }

    fn any_near(&self, id: usize, x: [f64; 3], r2: f64) -> bool {
        let n = &self.nodes[id];
        match classify(n, x, x, r2) {
            Class::Outside => false,
            Class::Inside => n.end > n.start,
            Class::Partial if n.children == 0 => {
                self.pts[n.start..n.end].iter().any(|p| dist2_to_box(p, x, x) <= r2)
            }
            Class::Partial => (n.first_child..n.first_child + n.children).any(|c| self.any_near(c, x, r2)),
        }
    }

    /// Replaces `out` with the input indices of all points within distance r of the box lo..hi
    /// (lo <= hi on each axis; a point inside the box is at distance 0), in the tree's order.
    pub fn near_box(&self, lo: [f64; 3], hi: [f64; 3], r: f64, out: &mut Vec<usize>) {
        out.clear();
        if self.nodes.is_empty() || !(r >= 0.0) {
            return;
        }
        let r2 = r * r;
        let mut stack = vec![0usize];
        while let Some(id) = stack.pop() {
            let n = &self.nodes[id];
            match classify(n, lo, hi, r2) {
                Class::Outside => {}
                Class::Inside => out.extend_from_slice(&self.index[n.start..n.end]),
                Class::Partial if n.children == 0 => {
                    for t in n.start..n.end {
                        if dist2_to_box(&self.pts[t], lo, hi) <= r2 {
                            out.push(self.index[t]);
                        }
                    }
                }
                // children pushed in reverse so that they are visited in tree order
                Class::Partial => stack.extend((n.first_child..n.first_child + n.children).rev()),
            }
        }
    }

    /// The `k` points nearest to x, as (squared distance, input index) in increasing order of
    /// both (ties by the index; all points where there are fewer than k), into `out`. The
    /// squared distance sums the squares of the coordinate differences in the order x, y, z. A
    /// depth-first search that visits the children nearest first and passes over a node whose
    /// box lies farther than the k-th point found: a box's distance is never more than that of
    /// a point in it, in floating point too (rounding is monotone), so nothing is passed over
    /// that could enter the list.
    pub fn nearest_k(&self, x: [f64; 3], k: usize, out: &mut Vec<(f64, usize)>) {
        out.clear();
        if k > 0 && !self.nodes.is_empty() {
            self.nearest_in(0, x, k, f64::INFINITY, out);
        }
    }

    /// [`Octree::nearest_k`] where the k-th nearest point is likely within distance `bound` of
    /// x (the k-th distance of a point nearby plus the distance between them, say): boxes and
    /// points farther than it are passed over from the start. The answer is that of
    /// `nearest_k` whatever `bound` is: where fewer than k points lie within it, the search is
    /// made again without it, and where k do, the k nearest are among them.
    pub fn nearest_k_within(&self, x: [f64; 3], k: usize, bound: f64, out: &mut Vec<(f64, usize)>) {
        out.clear();
        if k > 0 && !self.nodes.is_empty() {
            self.nearest_in(0, x, k, bound * bound, out);
            if out.len() < k.min(self.len()) {
                self.nearest_k(x, k, out);
            }
        }
    }

    fn nearest_in(&self, id: usize, x: [f64; 3], k: usize, bound2: f64, out: &mut Vec<(f64, usize)>) {
        let n = &self.nodes[id];
        let before = |a: &(f64, usize), b: &(f64, usize)| a.0 < b.0 || (a.0 == b.0 && a.1 < b.1);
        if n.children == 0 {
            for t in n.start..n.end {
                let c = (dist2_to_box(&self.pts[t], x, x), self.index[t]);
                if c.0 > bound2 {
                    continue;
                }
                if out.len() == k {
                    if !before(&c, &out[k - 1]) {
                        continue;
                    }
                    out.pop();
                }
                let at = out.partition_point(|e| before(e, &c));
                out.insert(at, c);
            }
            return;
        }
        let mut kids = [(0.0, 0usize); 8];
        let m = n.children;
        for (slot, c) in kids.iter_mut().zip(n.first_child..n.first_child + m) {
            *slot = (dist2_to_box(&x, self.nodes[c].lo, self.nodes[c].hi), c);
        }
        kids[..m].sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        for &(d2, c) in &kids[..m] {
            if d2 > bound2 || (out.len() == k && d2 > out[k - 1].0) {
                break;
            }
            self.nearest_in(c, x, k, bound2, out);
        }
    }

    /// The distance from x to its k-th nearest point (k >= 1, counting a point at x itself; the
    /// farthest point's distance when there are fewer than k; infinite for an empty tree): the
    /// last of [`Octree::nearest_k`].
    pub fn kth_distance(&self, x: [f64; 3], k: usize) -> f64 {
        let mut near = Vec::new();
        self.nearest_k(x, k.max(1), &mut near);
        near.last().map_or(f64::INFINITY, |&(d2, _)| d2.sqrt())
    }

    /// The renumbering of Algorithm III for neighbourhoods of radius r (see the module doc):
    /// `perm[new] = old`, a permutation of 0..len().
    pub fn order(&self, r: f64) -> Vec<usize> {
        let n = self.len();
        let mut numbered = vec![false; n];
        let mut perm = Vec::with_capacity(n);
        let mut found = Vec::new();
        for seed in 0..n {
            if numbered[seed] {
                continue;
            }
            numbered[seed] = true;
            perm.push(seed);
            let mut head = perm.len() - 1;
            while head < perm.len() {
                self.within(self.point(perm[head]), r, &mut found);
                head += 1;
                found.sort_unstable();
                for &j in &found {
                    if !numbered[j] {
                        numbered[j] = true;
                        perm.push(j);
                    }
                }
            }
        }
        perm
    }
}

/// Squared distance from p to the box lo..hi, summed over x, y, z in that order.
#[inline]
pub(crate) fn dist2_to_box(p: &[f64; 3], lo: [f64; 3], hi: [f64; 3]) -> f64 {
    let g = |d: usize| (lo[d] - p[d]).max(p[d] - hi[d]).max(0.0);
    let (gx, gy, gz) = (g(0), g(1), g(2));
    gx * gx + gy * gy + gz * gz
}

fn classify(n: &Node, lo: [f64; 3], hi: [f64; 3], r2: f64) -> Class {
    let mut near = [0.0; 3];
    let mut far = [0.0; 3];
    for d in 0..3 {
        // the gap is convex in the coordinate: smallest over the node's extent where the
        // extents overlap (or at the closer end), largest at one of its ends
        near[d] = (lo[d] - n.hi[d]).max(n.lo[d] - hi[d]).max(0.0);
        let g = |p: f64| (lo[d] - p).max(p - hi[d]).max(0.0);
        far[d] = g(n.lo[d]).max(g(n.hi[d]));
    }
    if near[0] * near[0] + near[1] * near[1] + near[2] * near[2] > r2 {
        Class::Outside
    } else if far[0] * far[0] + far[1] * far[1] + far[2] * far[2] <= r2 {
        Class::Inside
    } else {
        Class::Partial
    }
}

fn bounds(pts: &[[f64; 3]]) -> ([f64; 3], [f64; 3]) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in pts {
        for d in 0..3 {
            lo[d] = lo[d].min(p[d]);
            hi[d] = hi[d].max(p[d]);
        }
    }
    (lo, hi)
}

/// Octant o (bit d set: upper half along axis d) of the cell at `corner` whose octants have
/// side `half`.
fn octant_corner(corner: [f64; 3], half: f64, o: usize) -> [f64; 3] {
    let mut c = corner;
    for (d, v) in c.iter_mut().enumerate() {
        if o >> d & 1 == 1 {
            *v += half;
        }
    }
    c
}

/// Sorts the points of a cell (and their input indices) by octant, stably; returns the octant
/// offsets (octant o holds positions `c[o]..c[o + 1]`).
fn split(
    pts: &mut [[f64; 3]],
    index: &mut [usize],
    corner: [f64; 3],
    side: f64,
    scratch: &mut Vec<([f64; 3], usize)>,
) -> [usize; 9] {
    let half = 0.5 * side;
    let mid = [corner[0] + half, corner[1] + half, corner[2] + half];
    let octant = |p: &[f64; 3]| (0..3).map(|d| usize::from(p[d] >= mid[d]) << d).sum::<usize>();
    let mut c = [0usize; 9];
    for p in pts.iter() {
        c[octant(p) + 1] += 1;
    }
    for o in 0..8 {
        c[o + 1] += c[o];
    }
    scratch.clear();
    scratch.extend(pts.iter().copied().zip(index.iter().copied()));
    let mut next = c;
    for &(p, i) in scratch.iter() {
        let o = octant(&p);
        pts[next[o]] = p;
        index[next[o]] = i;
        next[o] += 1;
    }
    c
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// Random points in the cube [-1, 1]^3 with a fixed seed, 3 coordinates per point.
    pub(crate) fn random_points(n: usize, seed: u64) -> Vec<f64> {
        let mut s = seed;
        (0..3 * n)
            .map(|_| {
                s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                2.0 * ((s >> 11) as f64 / (1u64 << 53) as f64) - 1.0
            })
            .collect()
    }

    /// The vertices of the test bunny, normalised as the spline normalises its centres (centre of
    /// the bounding box, half its diagonal), 3 coordinates per point.
    pub(crate) fn bunny() -> Vec<f64> {
        let set = crate::io::points::read_points(std::path::Path::new("tests/data/bunny10k.obj")).unwrap();
        let (lo, hi) = bounds(&set.points);
        let norm = crate::spline::Normalisation::of_box(&lo, &hi);
        let mut out = vec![0.0; 3 * set.points.len()];
        for (o, p) in out.chunks_exact_mut(3).zip(&set.points) {
            norm.apply(p, o);
        }
        out
    }

    fn brute(points: &[f64], lo: [f64; 3], hi: [f64; 3], r: f64) -> Vec<usize> {
        let r2 = r * r;
        (0..points.len() / 3)
            .filter(|&i| {
                let p = &points[3 * i..3 * i + 3];
                let g = |d: usize| {
                    if p[d] < lo[d] {
                        lo[d] - p[d]
                    } else if p[d] > hi[d] {
                        p[d] - hi[d]
                    } else {
                        0.0
                    }
                };
                g(0) * g(0) + g(1) * g(1) + g(2) * g(2) <= r2
            })
            .collect()
    }

    /// Every point as (squared distance to x, index), in increasing order of both: the oracle of
    /// [`Octree::nearest_k`].
    fn by_distance(points: &[f64], x: [f64; 3]) -> Vec<(f64, usize)> {
        let mut all: Vec<(f64, usize)> = points
            .chunks_exact(3)
            .enumerate()
            .map(|(i, p)| ((x[0] - p[0]).powi(2) + (x[1] - p[1]).powi(2) + (x[2] - p[2]).powi(2), i))
            .collect();
        all.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        all
    }

    fn check_searches(points: &[f64], capacity: usize, radii: &[f64]) {
        let tree = Octree::new(points, capacity);
        let n = points.len() / 3;
        let mut got = Vec::new();
        for (q, r) in (0..n).step_by(n / 40 + 1).zip(radii.iter().cycle()) {
            // a data point, and a point between data points
            let x = [points[3 * q], points[3 * q + 1], points[3 * q + 2]];
            let y = [x[0] + 0.013, x[1] - 0.021, x[2] + 0.007];
            for c in [x, y] {
                tree.within(c, *r, &mut got);
                got.sort_unstable();
                let want = brute(points, c, c, *r);
                assert_eq!(got, want, "K = {capacity}, r = {r}, at {c:?}");
                assert_eq!(tree.any_within(c, *r), !want.is_empty(), "K = {capacity}, r = {r}, at {c:?}");
                // the k nearest by (squared distance, index), against sorting all points
                let all = by_distance(points, c);
                let mut near = Vec::new();
                for k in [1, 10, 33] {
                    tree.nearest_k(c, k, &mut near);
                    assert_eq!(near, all[..k.min(n)], "K = {capacity}, k = {k}, at {c:?}");
                    // with a bound on the k-th distance too short, exact, or loose
                    let kth = all[k.min(n) - 1].0.sqrt();
                    for bound in [0.0, 0.5 * kth, kth, 1.1 * kth, 3.0 * kth] {
                        tree.nearest_k_within(c, k, bound, &mut near);
                        assert_eq!(near, all[..k.min(n)], "K = {capacity}, k = {k}, bound {bound}, at {c:?}");
                    }
                }
                // just beyond the nearest point, and just short of it
                let nearest =
                    (0..n).map(|i| dist2_to_box(&tree.point(i), c, c)).fold(f64::INFINITY, f64::min).sqrt();
                assert!(
                    tree.any_within(c, nearest * (1.0 + 1e-12)) && !tree.any_within(c, 0.999 * nearest)
                        || nearest == 0.0
                );
                // the sphere through a point at exactly distance r still holds it
                if let Some(&far) = want.last() {
                    let p = tree.point(far);
                    let exact = dist2_to_box(&p, c, c).sqrt();
                    tree.within(c, exact, &mut got);
                    assert!(got.contains(&far) || dist2_to_box(&p, c, c) > exact * exact);
                }
            }
            // a segment of a grid row
            let (lo, hi) = ([y[0] - 0.3, y[1], y[2]], [y[0] + 0.2, y[1], y[2]]);
            tree.near_box(lo, hi, *r, &mut got);
            got.sort_unstable();
            assert_eq!(got, brute(points, lo, hi, *r), "K = {capacity}, r = {r}, segment");
        }
    }

    #[test]
    fn nearest_points_break_ties_by_index_on_a_grid() {
        // a 10 x 10 x 10 grid: a cell centre has 8 corners at one distance, a node 6 neighbours
        let pts: Vec<f64> = (0..1000)
            .flat_map(|i| [0.1 * (i % 10) as f64, 0.1 * ((i / 10) % 10) as f64, 0.1 * (i / 100) as f64])
            .collect();
        for capacity in [1, 4, 32] {
            let tree = Octree::new(&pts, capacity);
            let mut near = Vec::new();
            for x in [[0.45, 0.45, 0.45], [0.4, 0.4, 0.4], [0.05, 0.95, 0.55], [2.0, -1.0, 0.3]] {
                let all = by_distance(&pts, x);
                for k in [1, 3, 7, 8, 10, 27, 1000, 1200] {
                    tree.nearest_k(x, k, &mut near);
                    assert_eq!(near, all[..k.min(1000)], "K = {capacity}, k = {k}, at {x:?}");
                }
            }
        }
    }

    #[test]
    fn searches_equal_brute_force_on_random_points() {
        let pts = random_points(3000, 7);
        for k in [1, 4, 10, 50] {
            check_searches(&pts, k, &[0.0, 0.05, 0.1, 0.3, 1.0, 4.0]);
        }
    }

    #[test]
    fn searches_equal_brute_force_on_the_bunny() {
        let pts = bunny();
        for k in [1, 10, 32] {
            check_searches(&pts, k, &[0.02, 0.05, 0.1, 0.2, 0.5]);
        }
    }

    #[test]
    fn the_tree_partitions_the_points_into_leaves_of_at_most_k() {
        let pts = bunny();
        for k in [1, 10, 100] {
            let tree = Octree::new(&pts, k);
            let s = tree.stats();
            crate::note!("bunny, K = {k}: {s:?}");
            assert!(s.largest_leaf <= k, "{s:?}");
            let leaves: Vec<&Node> = tree.nodes.iter().filter(|n| n.children == 0).collect();
            assert_eq!(leaves.len(), s.leaves);
            assert_eq!(leaves.iter().map(|n| n.end - n.start).sum::<usize>(), pts.len() / 3);
            assert_eq!(s.nodes, tree.nodes.len());
            // pruning leaves no node with a single child, and every child lies inside its parent
            for n in &tree.nodes {
                assert_ne!(n.children, 1);
                for c in &tree.nodes[n.first_child..n.first_child + n.children] {
                    assert!(c.start >= n.start && c.end <= n.end);
                    assert!((0..3).all(|d| c.lo[d] >= n.lo[d] && c.hi[d] <= n.hi[d]));
                }
            }
            let mut seen = tree.index.clone();
            seen.sort_unstable();
            assert_eq!(seen, (0..pts.len() / 3).collect::<Vec<_>>());
            assert!(s.levels >= 2 && s.levels <= s.finest_level + 1, "{s:?}");
        }
    }

    #[test]
    fn coincident_points_end_in_one_leaf() {
        let mut pts = vec![0.5; 3 * 30];
        pts.extend_from_slice(&[0.0, 0.0, 0.0, 1.0, 1.0, 1.0]);
        let tree = Octree::new(&pts, 4);
        assert_eq!(tree.stats().largest_leaf, 30);
        let mut got = Vec::new();
        tree.within([0.5; 3], 0.0, &mut got);
        assert_eq!(got.len(), 30);
        assert!(Octree::new(&[], 10).is_empty());
        Octree::new(&[], 10).within([0.0; 3], 1.0, &mut got);
        assert!(got.is_empty());
    }

    #[test]
    fn kth_distances_equal_brute_force() {
        let pts = bunny();
        let tree = Octree::new(&pts, 10);
        for q in (0..pts.len() / 3).step_by(97) {
            let x = tree.point(q);
            let mut d: Vec<f64> =
                pts.chunks_exact(3).map(|p| dist2_to_box(&[p[0], p[1], p[2]], x, x)).collect();
            d.sort_by(f64::total_cmp);
            for k in [1, 10, 30] {
                assert_eq!(tree.kth_distance(x, k), d[k - 1].sqrt());
            }
        }
    }

    /// Sum over rows of (row - first column within r), the entries of the lower triangle of a
    /// profile (envelope) storage, for the numbering `perm` (perm[new] = old).
    fn envelope(tree: &Octree, r: f64, perm: &[usize]) -> usize {
        let mut new_of = vec![0; perm.len()];
        for (new, &old) in perm.iter().enumerate() {
            new_of[old] = new;
        }
        let mut found = Vec::new();
        perm.iter()
            .enumerate()
            .map(|(i, &old)| {
                tree.within(tree.point(old), r, &mut found);
                i - found.iter().map(|&j| new_of[j]).min().unwrap()
            })
            .sum()
    }

    #[test]
    fn the_ordering_is_a_permutation_that_shrinks_the_envelope() {
        let pts = bunny();
        let tree = Octree::new(&pts, 10);
        let n = pts.len() / 3;
        let input: Vec<usize> = (0..n).collect();
        for r in [0.03, 0.06, 0.1] {
            let perm = tree.order(r);
            let mut sorted = perm.clone();
            sorted.sort_unstable();
            assert_eq!(sorted, input);
            let (before, after) = (envelope(&tree, r, &input), envelope(&tree, r, &perm));
            let rev: Vec<usize> = perm.iter().rev().copied().collect();
            let reversed = envelope(&tree, r, &rev);
            crate::note!("r = {r}: envelope {before} in input order, {after} ordered, {reversed} reversed");
            assert!(2 * after < before, "r = {r}: {after} vs {before}");
        }
        // random points in input order have no locality at all
        let pts = random_points(2000, 3);
        let tree = Octree::new(&pts, 10);
        let input: Vec<usize> = (0..2000).collect();
        let (before, after) = (envelope(&tree, 0.2, &input), envelope(&tree, 0.2, &tree.order(0.2)));
        crate::note!("random points, r = 0.2: envelope {before} in input order, {after} ordered");
        assert!(2 * after < before, "{after} vs {before}");
    }
}
