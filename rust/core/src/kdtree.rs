//! A static 2-d tree over marker centres: nearest-neighbour and k-nearest queries in
//! `O(log N)` each, whatever the point distribution or the gate.
//!
//! Why not the uniform [`crate::geometry::CellGrid`]: a grid cell of the gate's width holds every
//! point of a dense cluster (or a million duplicates of one point), and a query then scans them
//! all: `O(N^2)` over a frame. The tree splits at the median along the wider side of each node,
//! so its depth is `log2(N / LEAF)` for any input, and [`KdTree::unique`] collapses exact
//! duplicates (keeping the lowest index) so that ties at distance zero never force a scan.
//!
//! Distances are squared Euclidean in `f64`: finite `f32` coordinates (up to `3.4e38`) never
//! overflow, so far-apart points still compare correctly.

/// Points per leaf: scanning a few points beats descending further.
const LEAF: usize = 8;

/// Squared Euclidean distance in `f64` (never overflows for finite `f32` coordinates).
#[inline]
pub fn dist2_f64(a: [f32; 2], b: [f32; 2]) -> f64 {
    let dx = f64::from(a[0]) - f64::from(b[0]);
    let dy = f64::from(a[1]) - f64::from(b[1]);
    dx * dx + dy * dy
}

/// A balanced 2-d tree; points are stored permuted into tree order with their original indices.
pub struct KdTree {
    pts: Vec<[f32; 2]>,
    ids: Vec<u32>,
    /// Split axis and value of each inner node, in heap order (root 0, children `2k + 1`,
    /// `2k + 2`): the left half holds coordinates `<=` the value, the right half `>=`.
    splits: Vec<(u8, f32)>,
}

/// Exact duplicates removed: for each distinct coordinate, the lowest index holding it.
/// `-0.0` and `0.0` count as the same coordinate. `O(N log N)`.
pub fn unique_indices(points: &[[f32; 2]]) -> Vec<u32> {
    // `+ 0.0` turns -0.0 into 0.0, so the bit patterns of equal coordinates are equal.
    let key = |i: u32| {
        let p = points[i as usize];
        ((p[0] + 0.0).to_bits(), (p[1] + 0.0).to_bits())
    };
    let mut order: Vec<u32> = (0..points.len() as u32).collect();
    // Stable on the index for equal keys, so the first of a run is the lowest index.
    order.sort_unstable_by_key(|&i| (key(i), i));
    order.dedup_by_key(|i| key(*i));
    order.sort_unstable();
    order
}

/// Orders `items` into tree order below `node`: the median along the wider side at `len / 2`,
/// the halves built recursively.
fn build(items: &mut [([f32; 2], u32)], splits: &mut [(u8, f32)], node: usize) {
    let n = items.len();
    if n <= LEAF {
        return;
    }
    let (mut min, mut max) = ([f32::INFINITY; 2], [f32::NEG_INFINITY; 2]);
    for (p, _) in items.iter() {
        for k in 0..2 {
            min[k] = min[k].min(p[k]);
            max[k] = max[k].max(p[k]);
        }
    }
    // The wider side (in f64: the spread of two huge coordinates may overflow f32).
    let spread = |k: usize| f64::from(max[k]) - f64::from(min[k]);
    let axis = usize::from(spread(1) > spread(0));
    let mid = n / 2;
    items.select_nth_unstable_by(mid, |a, b| a.0[axis].total_cmp(&b.0[axis]));
    // Stored here: building the halves reorders them, so `items[mid]` will not stay the median.
    splits[node] = (axis as u8, items[mid].0[axis]);
    let (lo, hi) = items.split_at_mut(mid);
    build(lo, splits, 2 * node + 1);
    build(hi, splits, 2 * node + 2);
}

impl KdTree {
    /// A tree over `points[i]` for every `i` in `ids` (original indices are reported back).
    pub fn new(points: &[[f32; 2]], ids: Vec<u32>) -> Self {
        let mut items: Vec<([f32; 2], u32)> =
            ids.iter().map(|&i| (points[i as usize], i)).collect();
        let n = items.len();
        let mut splits = Vec::new();
        if n > LEAF {
            // Halving `n` until it fits a leaf: `depth` levels of inner nodes.
            let depth = usize::BITS - (n.div_ceil(LEAF) - 1).leading_zeros();
            splits = vec![(0, 0.0); (1usize << depth) - 1];
            build(&mut items, &mut splits, 0);
        }
        Self {
            pts: items.iter().map(|e| e.0).collect(),
            ids: items.iter().map(|e| e.1).collect(),
            splits,
        }
    }

    /// A tree over every point, duplicates kept.
    pub fn over_all(points: &[[f32; 2]]) -> Self {
        Self::new(points, (0..points.len() as u32).collect())
    }

    /// A tree over the distinct points (lowest index of each), see [`unique_indices`].
    pub fn unique(points: &[[f32; 2]]) -> Self {
        Self::new(points, unique_indices(points))
    }

    /// Number of points in the tree.
    pub fn len(&self) -> usize {
        self.pts.len()
    }

    /// True when the tree holds no point.
    pub fn is_empty(&self) -> bool {
        self.pts.is_empty()
    }

    /// The nearest point to `q` at squared distance at most `max_d2`, as `(index, d2)`;
    /// ties go to the lowest index. `skip_zero`: ignore points at distance 0 (the query itself
    /// and its duplicates). None when no point qualifies.
    pub fn nearest(&self, q: [f32; 2], max_d2: f64, skip_zero: bool) -> Option<(u32, f64)> {
        let mut best = (u32::MAX, max_d2);
        if !self.pts.is_empty() {
            self.nearest_in(0, 0, self.pts.len(), q, skip_zero, &mut best);
        }
        (best.0 != u32::MAX).then_some(best)
    }

    fn nearest_in(
        &self,
        node: usize,
        lo: usize,
        hi: usize,
        q: [f32; 2],
        skip_zero: bool,
        best: &mut (u32, f64),
    ) {
        if hi - lo <= LEAF {
            for (p, &id) in self.pts[lo..hi].iter().zip(&self.ids[lo..hi]) {
                let d = dist2_f64(q, *p);
                if (skip_zero && d == 0.0) || d > best.1 {
                    continue;
                }
                if d < best.1 || id < best.0 {
                    *best = (id, d);
                }
            }
            return;
        }
        let (axis, split) = self.splits[node];
        let mid = lo + (hi - lo) / 2;
        let diff = f64::from(q[usize::from(axis)]) - f64::from(split);
        let left = (2 * node + 1, lo, mid);
        let right = (2 * node + 2, mid, hi);
        let (first, second) = if diff < 0.0 {
            (left, right)
        } else {
            (right, left)
        };
        self.nearest_in(first.0, first.1, first.2, q, skip_zero, best);
        // `<=`: a point exactly as far on the other side may have a lower index.
        if diff * diff <= best.1 {
            self.nearest_in(second.0, second.1, second.2, q, skip_zero, best);
        }
    }

    /// Indices of up to `k` nearest points to `q` other than `exclude`, nearest first (ties in
    /// no particular but deterministic order). Bounded work even with many duplicates: a side is
    /// skipped once `k` points at least as close are known.
    pub fn k_nearest(&self, q: [f32; 2], k: usize, exclude: u32) -> Vec<u32> {
        let mut found: Vec<(f64, u32)> = Vec::with_capacity(k + 1);
        if k > 0 && !self.pts.is_empty() {
            self.knn_in(0, 0, self.pts.len(), q, k, exclude, &mut found);
        }
        found.into_iter().map(|(_, id)| id).collect()
    }

    #[allow(clippy::too_many_arguments)]
    fn knn_in(
        &self,
        node: usize,
        lo: usize,
        hi: usize,
        q: [f32; 2],
        k: usize,
        exclude: u32,
        found: &mut Vec<(f64, u32)>,
    ) {
        if hi - lo <= LEAF {
            for (p, &id) in self.pts[lo..hi].iter().zip(&self.ids[lo..hi]) {
                if id == exclude {
                    continue;
                }
                let d = dist2_f64(q, *p);
                if found.len() == k && d >= found[k - 1].0 {
                    continue;
                }
                // Insertion into a sorted list of at most k + 1 entries (k is small).
                let at = found.partition_point(|e| e.0 <= d);
                found.insert(at, (d, id));
                found.truncate(k);
            }
            return;
        }
        let (axis, split) = self.splits[node];
        let mid = lo + (hi - lo) / 2;
        let diff = f64::from(q[usize::from(axis)]) - f64::from(split);
        let left = (2 * node + 1, lo, mid);
        let right = (2 * node + 2, mid, hi);
        let (first, second) = if diff < 0.0 {
            (left, right)
        } else {
            (right, left)
        };
        self.knn_in(first.0, first.1, first.2, q, k, exclude, found);
        if found.len() < k || diff * diff < found[k - 1].0 {
            self.knn_in(second.0, second.1, second.2, q, k, exclude, found);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scatter(n: usize) -> Vec<[f32; 2]> {
        (0..n)
            .map(|i| {
                let t = i as f32 * 0.618_034;
                [(t * 97.0) % 300.0, (t * 41.0) % 200.0]
            })
            .collect()
    }

    fn brute_nearest(pts: &[[f32; 2]], q: [f32; 2], skip_zero: bool) -> Option<(u32, f64)> {
        let mut best: Option<(u32, f64)> = None;
        for (j, &p) in pts.iter().enumerate() {
            let d = dist2_f64(q, p);
            if skip_zero && d == 0.0 {
                continue;
            }
            if best.map_or(true, |b| d < b.1) {
                best = Some((j as u32, d));
            }
        }
        best
    }

    #[test]
    fn nearest_matches_brute_force_with_lowest_index_ties() {
        let mut pts = scatter(700);
        pts.extend_from_slice(&pts.clone()[..50]); // duplicates with higher indices
        pts.extend((0..20).map(|i| [i as f32 * 10.0, 0.0])); // an exact lattice: ties
        let tree = KdTree::unique(&pts);
        for q in [
            [13.0, 15.0],
            [-5.0, 3.0],
            [299.0, 199.0],
            [150.2, 50.7],
            [5.0, 0.0],
        ] {
            for skip in [false, true] {
                let got = tree.nearest(q, f64::INFINITY, skip);
                assert_eq!(got, brute_nearest(&pts, q, skip), "{q:?} {skip}");
            }
        }
        assert_eq!(tree.nearest([0.0, 0.0], 0.0, true), None);
    }

    #[test]
    fn k_nearest_matches_brute_force_distances() {
        let pts = scatter(500);
        let tree = KdTree::over_all(&pts);
        for (i, &q) in pts.iter().enumerate().step_by(37) {
            let got = tree.k_nearest(q, 6, i as u32);
            let mut want: Vec<f64> = (0..pts.len())
                .filter(|&j| j != i)
                .map(|j| dist2_f64(q, pts[j]))
                .collect();
            want.sort_by(f64::total_cmp);
            let got_d: Vec<f64> = got.iter().map(|&j| dist2_f64(q, pts[j as usize])).collect();
            assert_eq!(got_d, want[..6].to_vec());
        }
    }

    #[test]
    fn duplicates_and_huge_coordinates_stay_cheap_and_exact() {
        let pts = vec![[1.0f32, 2.0]; 100_000];
        assert_eq!(unique_indices(&pts), vec![0]);
        let tree = KdTree::over_all(&pts);
        assert_eq!(tree.k_nearest([1.0, 2.0], 6, 0).len(), 6);
        let far = [[3e38f32, 0.0], [-3e38, 0.0]];
        let tree = KdTree::unique(&far);
        let (j, d) = tree.nearest([-3e38, 0.0], f64::INFINITY, true).unwrap();
        assert_eq!(j, 0);
        assert!(d.is_finite() && d > 3.5e77);
    }
}
