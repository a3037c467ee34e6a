//! Point-set geometry: nearest-neighbour search, marker-pitch estimation and 2D rigid fits.
//!
//! Points are `[x, y]` in pixels. Callers guarantee finite coordinates (the public entry points
//! check for NaN/Inf before calling in).

use crate::error::{CoreError, Result};

/// Below this many candidate points a linear scan beats building a grid.
const BRUTE_FORCE_MAX_POINTS: usize = 160;

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

/// A uniform bucket grid over a point set for nearest-neighbour queries.
///
/// Small sets are scanned linearly; larger ones are bucketed so that a query within radius `r`
/// touches only the cells the disc of radius `r` overlaps.
pub struct PointIndex<'a> {
    points: &'a [[f32; 2]],
    grid: Option<Grid>,
}

struct Grid {
    min: [f32; 2],
    cell: f32,
    cols: usize,
    rows: usize,
    /// `starts[c]..starts[c + 1]` indexes `order` for cell `c`.
    starts: Vec<u32>,
    order: Vec<u32>,
}

impl<'a> PointIndex<'a> {
    /// Builds an index; `cell_hint` is the typical query radius (pixels), used as the cell size.
    pub fn new(points: &'a [[f32; 2]], cell_hint: f32) -> Self {
        if points.len() <= BRUTE_FORCE_MAX_POINTS {
            return Self { points, grid: None };
        }
        let (mut min, mut max) = ([f32::MAX; 2], [f32::MIN; 2]);
        for p in points {
            for k in 0..2 {
                min[k] = min[k].min(p[k]);
                max[k] = max[k].max(p[k]);
            }
        }
        let span = (max[0] - min[0]).max(max[1] - min[1]).max(1.0);
        // At most ~4 points per cell on average whatever the hint, and never more than 2^20 cells.
        let density_cell = span / ((points.len() as f32 / 4.0).sqrt().max(1.0));
        let cell = if cell_hint.is_finite() && cell_hint > 0.0 {
            cell_hint.max(span / 1024.0)
        } else {
            density_cell
        };
        let cols = (((max[0] - min[0]) / cell) as usize + 1).min(1024);
        let rows = (((max[1] - min[1]) / cell) as usize + 1).min(1024);
        let cell = cell
            .max((max[0] - min[0]) / cols as f32)
            .max((max[1] - min[1]) / rows as f32);
        let cell_of = |p: &[f32; 2]| -> usize {
            let cx = (((p[0] - min[0]) / cell) as usize).min(cols - 1);
            let cy = (((p[1] - min[1]) / cell) as usize).min(rows - 1);
            cy * cols + cx
        };
        let mut counts = vec![0u32; cols * rows + 1];
        for p in points {
            counts[cell_of(p) + 1] += 1;
        }
        for c in 1..counts.len() {
            counts[c] += counts[c - 1];
        }
        let starts = counts.clone();
        let mut fill = counts;
        let mut order = vec![0u32; points.len()];
        for (i, p) in points.iter().enumerate() {
            let c = cell_of(p);
            order[fill[c] as usize] = i as u32;
            fill[c] += 1;
        }
        Self {
            points,
            grid: Some(Grid {
                min,
                cell,
                cols,
                rows,
                starts,
                order,
            }),
        }
    }

    /// The indexed points.
    pub fn points(&self) -> &'a [[f32; 2]] {
        self.points
    }

    /// Index and squared distance of the nearest point to `q` within `radius` (inclusive),
    /// skipping index `exclude`. Ties go to the lowest index, so results are deterministic.
    pub fn nearest_within(
        &self,
        q: [f32; 2],
        radius: f32,
        exclude: Option<usize>,
    ) -> Option<(usize, f32)> {
        let r2 = if radius.is_finite() {
            radius * radius
        } else {
            f32::INFINITY
        };
        let mut best: Option<(usize, f32)> = None;
        let consider = |i: usize, best: &mut Option<(usize, f32)>| {
            if Some(i) == exclude {
                return;
            }
            let d = dist2(q, self.points[i]);
            if d > r2 {
                return;
            }
            match *best {
                Some((bi, bd)) if d > bd || (d == bd && i > bi) => {}
                _ => *best = Some((i, d)),
            }
        };
        match &self.grid {
            None => {
                for i in 0..self.points.len() {
                    consider(i, &mut best);
                }
            }
            Some(g) => {
                if !radius.is_finite() {
                    return self.nearest_unbounded(q, exclude);
                }
                let lo_x = ((q[0] - radius - g.min[0]) / g.cell).floor().max(0.0) as usize;
                let lo_y = ((q[1] - radius - g.min[1]) / g.cell).floor().max(0.0) as usize;
                let hi_x = ((q[0] + radius - g.min[0]) / g.cell).floor();
                let hi_y = ((q[1] + radius - g.min[1]) / g.cell).floor();
                if hi_x < 0.0 || hi_y < 0.0 {
                    return None;
                }
                let hi_x = (hi_x as usize).min(g.cols - 1);
                let hi_y = (hi_y as usize).min(g.rows - 1);
                for cy in lo_y..=hi_y {
                    for cx in lo_x..=hi_x {
                        let c = cy * g.cols + cx;
                        for &i in &g.order[g.starts[c] as usize..g.starts[c + 1] as usize] {
                            consider(i as usize, &mut best);
                        }
                    }
                }
            }
        }
        best
    }

    /// Nearest point with no radius limit: grows the search ring by ring.
    fn nearest_unbounded(&self, q: [f32; 2], exclude: Option<usize>) -> Option<(usize, f32)> {
        let n_others = self.points.len() - usize::from(exclude.is_some());
        if n_others == 0 {
            return None;
        }
        let Some(g) = &self.grid else {
            return self.nearest_within(q, f32::INFINITY, exclude);
        };
        let mut radius = g.cell;
        loop {
            if let Some(hit) = self.nearest_within(q, radius, exclude) {
                return Some(hit);
            }
            radius *= 2.0;
        }
    }

    /// Nearest neighbour with no radius limit.
    pub fn nearest(&self, q: [f32; 2], exclude: Option<usize>) -> Option<(usize, f32)> {
        self.nearest_unbounded(q, exclude)
    }
}

/// Estimated marker pitch: the median nearest-neighbour distance within `points` (pixels).
///
/// Duplicated points (distance 0) are ignored so that they cannot drive the pitch to zero.
/// Returns `None` with fewer than two distinct points.
pub fn estimate_pitch(points: &[[f32; 2]]) -> Option<f32> {
    if points.len() < 2 {
        return None;
    }
    let index = PointIndex::new(points, f32::NAN);
    let mut nn: Vec<f32> = Vec::with_capacity(points.len());
    for (i, &p) in points.iter().enumerate() {
        if let Some((j, d2)) = index.nearest(p, Some(i)) {
            if d2 > 0.0 {
                nn.push(d2.sqrt());
            } else {
                // A duplicate: look past it for the nearest distinct neighbour.
                let mut best = f32::INFINITY;
                for (k, &o) in points.iter().enumerate() {
                    let d = dist2(p, o);
                    if k != i && k != j && d > 0.0 && d < best {
                        best = d;
                    }
                }
                if best.is_finite() {
                    nn.push(best.sqrt());
                }
            }
        }
    }
    median(&mut nn)
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
    }

    #[test]
    fn grid_and_brute_force_agree() {
        let pts = grid_points(30, 20, 9.0);
        let idx = PointIndex::new(&pts, 4.5);
        assert!(idx.grid.is_some());
        for q in [[13.0, 15.0], [-40.0, 3.0], [400.0, 400.0], [100.2, 50.7]] {
            let grid_hit = idx.nearest_within(q, 4.5, None);
            let brute = (0..pts.len())
                .map(|i| (i, dist2(q, pts[i])))
                .filter(|&(_, d)| d <= 4.5 * 4.5)
                .min_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
            assert_eq!(grid_hit, brute);
            let unb = idx.nearest(q, None).unwrap();
            let brute_unb = (0..pts.len())
                .map(|i| (i, dist2(q, pts[i])))
                .min_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)))
                .unwrap();
            assert_eq!(unb.1, brute_unb.1);
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
