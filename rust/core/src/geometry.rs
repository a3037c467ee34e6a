//! Point-set geometry: nearest-neighbour search, marker-pitch estimation and 2D rigid fits.
//!
//! Points are `[x, y]` in pixels. Callers guarantee finite coordinates (the public entry points
//! check for NaN/Inf before calling in).

use crate::error::{CoreError, Result};
use crate::kdtree::dist2_f64;

/// Query points sampled (evenly, deterministically) for the pitch median.
const PITCH_SAMPLES: usize = 32;

/// Squared Euclidean distance.
#[inline]
pub fn dist2(a: [f32; 2], b: [f32; 2]) -> f32 {
    let dx = a[0] - b[0];
    let dy = a[1] - b[1];
    dx * dx + dy * dy
}

/// Checks that every coordinate is finite; names `name` in the error otherwise.
pub fn check_finite(points: &[[f32; 2]], name: &'static str) -> Result<()> {
    match points
        .iter()
        .position(|p| !p[0].is_finite() || !p[1].is_finite())
    {
        Some(i) => Err(CoreError::invalid(
            name,
            format!(
                "point {i} is not finite ({}, {})",
                points[i][0], points[i][1]
            ),
        )),
        None => Ok(()),
    }
}

/// Points bucketed in square cells at least `min_cell` wide: the 3x3 cells around a query hold
/// every point within `min_cell` of it.
pub struct CellGrid {
    min: [f32; 2],
    cell: f32,
    cols: usize,
    rows: usize,
    /// `starts[c]..starts[c + 1]` indexes `order` for cell `c`.
    starts: Vec<u32>,
    order: Vec<u32>,
}

/// Cells per side at most: bounds memory whatever the gate.
const MAX_CELLS_PER_SIDE: usize = 1024;

impl CellGrid {
    /// Buckets `points`; cells are `min_cell` wide (wider if needed to stay within
    /// `MAX_CELLS_PER_SIDE` per side).
    pub fn new(points: &[[f32; 2]], min_cell: f32) -> Self {
        let (mut min, mut max) = ([f32::MAX; 2], [f32::MIN; 2]);
        for p in points {
            for k in 0..2 {
                min[k] = min[k].min(p[k]);
                max[k] = max[k].max(p[k]);
            }
        }
        if points.is_empty() {
            (min, max) = ([0.0; 2], [0.0; 2]);
        }
        let span = (max[0] - min[0]).max(max[1] - min[1]);
        let cell = min_cell
            .max(span / MAX_CELLS_PER_SIDE as f32)
            .max(f32::MIN_POSITIVE);
        let cols = ((max[0] - min[0]) / cell) as usize + 1;
        let rows = ((max[1] - min[1]) / cell) as usize + 1;
        let mut starts = vec![0u32; cols * rows + 1];
        let cell_of = |p: &[f32; 2]| {
            let cx = (((p[0] - min[0]) / cell) as usize).min(cols - 1);
            let cy = (((p[1] - min[1]) / cell) as usize).min(rows - 1);
            cy * cols + cx
        };
        for p in points {
            starts[cell_of(p) + 1] += 1;
        }
        for c in 1..starts.len() {
            starts[c] += starts[c - 1];
        }
        let mut fill = starts.clone();
        let mut order = vec![0u32; points.len()];
        for (i, p) in points.iter().enumerate() {
            let c = cell_of(p);
            order[fill[c] as usize] = i as u32;
            fill[c] += 1;
        }
        Self {
            min,
            cell,
            cols,
            rows,
            starts,
            order,
        }
    }

    /// Cell width, pixels.
    pub fn cell(&self) -> f32 {
        self.cell
    }

    /// Most points in one cell: a query scans at most 9 times this many.
    pub fn max_occupancy(&self) -> usize {
        self.starts
            .windows(2)
            .map(|w| (w[1] - w[0]) as usize)
            .max()
            .unwrap_or(0)
    }

    /// Indices of the points in the 3x3 cells around `p` (nothing if `p` is far outside).
    pub fn candidates(&self, p: [f32; 2]) -> impl Iterator<Item = usize> + '_ {
        let fx = ((p[0] - self.min[0]) / self.cell).floor();
        let fy = ((p[1] - self.min[1]) / self.cell).floor();
        let span = |f: f32, n: usize| -> std::ops::Range<usize> {
            if f < -1.0 || f > n as f32 {
                return 0..0;
            }
            let lo = (f - 1.0).max(0.0) as usize;
            let hi = ((f + 1.0) as usize).min(n - 1);
            lo..hi + 1
        };
        let (xs, ys) = (span(fx, self.cols), span(fy, self.rows));
        ys.flat_map(move |cy| {
            let row = cy * self.cols;
            let (a, b) = (self.starts[row + xs.start], self.starts[row + xs.end]);
            // Cells of one grid row are contiguous in `order`.
            self.order[a as usize..b as usize]
                .iter()
                .map(|&j| j as usize)
        })
    }
}

/// Estimated marker pitch: the median nearest-neighbour distance within `points` (pixels).
///
/// Duplicated points (distance 0) are ignored so that they cannot drive the pitch to zero.
/// Returns `None` with fewer than two distinct points. Computed in `f64`, so two points further
/// apart than `f32` can represent give `f32::INFINITY` (see [`estimate_pitch_f64`]).
pub fn estimate_pitch(points: &[[f32; 2]]) -> Option<f32> {
    estimate_pitch_f64(points).map(|d| d as f32)
}

/// [`estimate_pitch`] in `f64`: exact for any finite coordinates (`3e38` apart included).
///
/// The median runs over up to [`PITCH_SAMPLES`] query points taken at an even stride (a median
/// needs no more, and the stride keeps it deterministic). Each finds its nearest distinct point
/// among the grid cells around it, or by a full scan when none lies within one cell: at most
/// `PITCH_SAMPLES * N` distance evaluations whatever the layout (duplicates included).
pub fn estimate_pitch_f64(points: &[[f32; 2]]) -> Option<f64> {
    if points.len() < 2 {
        return None;
    }
    let (mut lo, mut hi) = ([f32::MAX; 2], [f32::MIN; 2]);
    for p in points {
        for k in 0..2 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    // Cells 1.5 mean spacings wide: on a marker grid the nearest neighbour lies within one cell,
    // and a neighbour found closer than one cell is the true nearest; otherwise a full scan
    // settles it. (An extent beyond f32 gives one infinite cell: every query scans.)
    let area = ((hi[0] - lo[0]) * (hi[1] - lo[1])).max(1.0);
    let grid = CellGrid::new(points, 1.5 * (area / points.len() as f32).sqrt());
    let cell2 = f64::from(grid.cell()) * f64::from(grid.cell());
    fn nearest_distinct(
        p: [f32; 2],
        points: &[[f32; 2]],
        within: impl Iterator<Item = usize>,
    ) -> f64 {
        within
            .map(|j| dist2_f64(p, points[j]))
            .filter(|&d| d > 0.0)
            .fold(f64::INFINITY, f64::min)
    }
    let stride = points.len().div_ceil(PITCH_SAMPLES);
    let mut nn: Vec<f64> = Vec::with_capacity(PITCH_SAMPLES);
    for &p in points.iter().step_by(stride) {
        let mut d = nearest_distinct(p, points, grid.candidates(p));
        if d > cell2 {
            d = nearest_distinct(p, points, 0..points.len());
        }
        if d.is_finite() {
            nn.push(d.sqrt());
        }
    }
    if nn.is_empty() {
        return None;
    }
    let mid = nn.len() / 2;
    let (_, &mut m, _) = nn.select_nth_unstable_by(mid, f64::total_cmp);
    if nn.len() % 2 == 1 {
        Some(m)
    } else {
        let lower = nn[..mid].iter().copied().fold(f64::MIN, f64::max);
        Some(0.5 * (lower + m))
    }
}

/// Median of a slice (reorders it). `None` when empty.
pub fn median(values: &mut [f32]) -> Option<f32> {
    if values.is_empty() {
        return None;
    }
    let mid = values.len() / 2;
    let (_, &mut m, _) = values.select_nth_unstable_by(mid, |a, b| a.total_cmp(b));
    if values.len() % 2 == 1 {
        Some(m)
    } else {
        let lower = values[..mid].iter().copied().fold(f32::MIN, f32::max);
        Some(0.5 * (lower + m))
    }
}

/// A 2D rigid transform `p -> R(theta) p + t`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rigid2 {
    /// Rotation angle, radians, counter-clockwise in (x, y) image coordinates.
    pub theta: f32,
    /// Translation, pixels.
    pub t: [f32; 2],
}

impl Rigid2 {
    /// Applies the transform to a point.
    pub fn apply(&self, p: [f32; 2]) -> [f32; 2] {
        let (s, c) = self.theta.sin_cos();
        [
            c * p[0] - s * p[1] + self.t[0],
            s * p[0] + c * p[1] + self.t[1],
        ]
    }
}

/// Least-squares rigid transform mapping `src[i]` to `dst[i]` (2D Kabsch / Procrustes, no scale).
///
/// Returns `None` for fewer than two pairs. Computed in f64 around the centroids, so it is exact
/// for pure translations and stable for large coordinates.
pub fn fit_rigid(src: &[[f32; 2]], dst: &[[f32; 2]]) -> Option<Rigid2> {
    let n = src.len().min(dst.len());
    if n < 2 {
        return None;
    }
    let (mut cs, mut cd) = ([0f64; 2], [0f64; 2]);
    for i in 0..n {
        for k in 0..2 {
            cs[k] += f64::from(src[i][k]);
            cd[k] += f64::from(dst[i][k]);
        }
    }
    for k in 0..2 {
        cs[k] /= n as f64;
        cd[k] /= n as f64;
    }
    let (mut sxx, mut sxy) = (0f64, 0f64);
    for i in 0..n {
        let a = [f64::from(src[i][0]) - cs[0], f64::from(src[i][1]) - cs[1]];
        let b = [f64::from(dst[i][0]) - cd[0], f64::from(dst[i][1]) - cd[1]];
        sxx += a[0] * b[0] + a[1] * b[1];
        sxy += a[0] * b[1] - a[1] * b[0];
    }
    let theta = if sxx == 0.0 && sxy == 0.0 {
        0.0
    } else {
        sxy.atan2(sxx)
    };
    let (s, c) = theta.sin_cos();
    let t = [
        cd[0] - (c * cs[0] - s * cs[1]),
        cd[1] - (s * cs[0] + c * cs[1]),
    ];
    Some(Rigid2 {
        theta: theta as f32,
        t: [t[0] as f32, t[1] as f32],
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid_points(nx: usize, ny: usize, pitch: f32) -> Vec<[f32; 2]> {
        let mut v = Vec::new();
        for j in 0..ny {
            for i in 0..nx {
                v.push([10.0 + i as f32 * pitch, 12.0 + j as f32 * pitch]);
            }
        }
        v
    }

    #[test]
    fn pitch_of_regular_grid() {
        let pts = grid_points(11, 9, 30.0);
        assert!((estimate_pitch(&pts).unwrap() - 30.0).abs() < 1e-4);
        let big = grid_points(40, 30, 7.5);
        assert!((estimate_pitch(&big).unwrap() - 7.5).abs() < 1e-4);
    }

    #[test]
    fn pitch_ignores_duplicates() {
        let mut pts = grid_points(5, 5, 20.0);
        pts.push(pts[3]);
        assert!((estimate_pitch(&pts).unwrap() - 20.0).abs() < 1e-4);
        assert_eq!(estimate_pitch(&pts[..1]), None);
        assert_eq!(estimate_pitch(&[[1.0, 1.0]; 1000]), None);
    }

    #[test]
    fn pitch_of_far_apart_points_is_their_distance() {
        assert_eq!(
            estimate_pitch_f64(&[[0.0, 0.0], [1e20, 0.0]]),
            Some(1e20f32 as f64)
        );
        let d = estimate_pitch_f64(&[[3e38, 0.0], [-3e38, 0.0]]).unwrap();
        assert!((d / 6e38 - 1.0).abs() < 1e-6);
        assert_eq!(
            estimate_pitch(&[[3e38, 0.0], [-3e38, 0.0]]),
            Some(f32::INFINITY)
        );
    }

    #[test]
    fn grid_candidates_cover_the_cell_radius() {
        let pts: Vec<[f32; 2]> = (0..500)
            .map(|i| {
                let t = i as f32 * 0.618;
                [(t * 97.0) % 300.0, (t * 41.0) % 200.0]
            })
            .collect();
        let grid = CellGrid::new(&pts, 7.5);
        for q in [
            [13.0, 15.0],
            [-5.0, 3.0],
            [299.0, 199.0],
            [150.2, 50.7],
            [900.0, 10.0],
        ] {
            let mut got: Vec<usize> = grid
                .candidates(q)
                .filter(|&j| dist2(q, pts[j]) <= 7.5 * 7.5)
                .collect();
            got.sort_unstable();
            let want: Vec<usize> = (0..pts.len())
                .filter(|&j| dist2(q, pts[j]) <= 7.5 * 7.5)
                .collect();
            assert_eq!(got, want);
        }
    }

    #[test]
    fn rigid_fit_recovers_rotation_and_translation() {
        let src = grid_points(6, 5, 20.0);
        let truth = Rigid2 {
            theta: 0.05,
            t: [3.0, -2.0],
        };
        let dst: Vec<_> = src.iter().map(|&p| truth.apply(p)).collect();
        let fit = fit_rigid(&src, &dst).unwrap();
        assert!((fit.theta - truth.theta).abs() < 1e-5);
        for (s, d) in src.iter().zip(&dst) {
            let p = fit.apply(*s);
            assert!(dist2(p, *d) < 1e-6);
        }
        assert!(fit_rigid(&src[..1], &dst[..1]).is_none());
    }
}
