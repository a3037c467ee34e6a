//! Mutual nearest-neighbour marker matching with a distance gate.

use crate::error::{CoreError, Result};
use crate::geometry::{check_finite, estimate_pitch, CellGrid};
use crate::kdtree::{dist2_f64, KdTree};

/// Default gate as a fraction of the marker pitch: half a pitch can never reach the wrong marker
/// of an undistorted grid.
pub const DEFAULT_GATE_FRACTION: f32 = 0.5;

/// Result of [`match_markers`], aligned with the reference points.
#[derive(Debug, Clone, PartialEq)]
pub struct Matches {
    /// `(dx, dy)` = matched current point minus reference point; NaN where not matched.
    pub motion: Vec<[f32; 2]>,
    /// True where the reference point has a mutual nearest neighbour within the gate.
    pub valid: Vec<bool>,
    /// Index into the current points, `-1` where not matched.
    pub index: Vec<i64>,
    /// Gate used, pixels (infinite when no gate applied).
    pub max_dist: f32,
}

/// The gate: `max_dist` if given, else half the pitch estimated from `reference`,
/// else (fewer than two distinct reference points) no gate.
pub fn resolve_gate(reference: &[[f32; 2]], max_dist: Option<f32>) -> Result<f32> {
    match max_dist {
        Some(d) if d.is_nan() || d <= 0.0 => Err(CoreError::invalid(
            "max_dist",
            format!("must be a positive number of pixels; got {d}"),
        )),
        Some(d) => Ok(d),
        None => Ok(estimate_pitch(reference)
            .map(|p| DEFAULT_GATE_FRACTION * p)
            .unwrap_or(f32::INFINITY)),
    }
}

/// Matches `current` to `reference`: reference `i` and current `j` match when each is the other's
/// nearest neighbour and they are at most `max_dist` apart. A reference point whose nearest
/// current point prefers another reference point is left unmatched rather than given its
/// second choice, so a lost marker never borrows a neighbour's detection.
///
/// Ties are broken by the lowest index, so duplicated current points match at most once.
pub fn match_markers(
    reference: &[[f32; 2]],
    current: &[[f32; 2]],
    max_dist: Option<f32>,
) -> Result<Matches> {
    check_finite(reference, "ref_pts")?;
    check_finite(current, "cur_pts")?;
    let gate = resolve_gate(reference, max_dist)?;
    Ok(match_with_gate(reference, current, gate))
}

/// Points per grid cell above which matching switches from the cell grid to 2-d trees.
const MAX_CELL_OCCUPANCY: usize = 32;

/// [`match_markers`] for inputs already checked, with a resolved gate.
///
/// Bounded work for any input: a grid of gate-wide cells over the current points when no cell
/// holds more than [`MAX_CELL_OCCUPANCY`] of them (marker layouts: the fastest path), else 2-d
/// trees over the distinct points of each side (dense clusters, a million copies of one point,
/// no gate), `O((N + M) log(N + M))`. Both give the same matches; exact duplicates match at
/// most once (ties go to the lowest index). Distances are compared in `f64`. A pair whose motion
/// overflows `f32` (coordinates near `+-3.4e38` on opposite sides) is left unmatched rather
/// than reported with an infinite motion.
pub fn match_with_gate(reference: &[[f32; 2]], current: &[[f32; 2]], gate: f32) -> Matches {
    let n = reference.len();
    let mut out = Matches {
        motion: vec![[f32::NAN; 2]; n],
        valid: vec![false; n],
        index: vec![-1; n],
        max_dist: gate,
    };
    if n == 0 || current.is_empty() {
        return out;
    }
    let g2 = f64::from(gate) * f64::from(gate);
    let pairs = if gate.is_finite() {
        let grid = CellGrid::new(current, gate);
        (grid.max_occupancy() <= MAX_CELL_OCCUPANCY)
            .then(|| mutual_in_grid(reference, current, g2, &grid))
    } else {
        None
    };
    let pairs = pairs.unwrap_or_else(|| mutual_in_trees(reference, current, g2));
    for (i, j) in pairs {
        let (p, q) = (reference[i], current[j as usize]);
        let mv = [q[0] - p[0], q[1] - p[1]];
        if mv[0].is_finite() && mv[1].is_finite() {
            out.motion[i] = mv;
            out.valid[i] = true;
            out.index[i] = i64::from(j);
        }
    }
    out
}

/// Mutual nearest pairs `(reference, current)` within `g2` by one pass over the grid's
/// candidates: each reference keeps its nearest current point, each current point its nearest
/// reference; a pair is kept when each is the other's.
fn mutual_in_grid(
    reference: &[[f32; 2]],
    current: &[[f32; 2]],
    g2: f64,
    grid: &CellGrid,
) -> Vec<(usize, u32)> {
    let mut ref_best = vec![(u32::MAX, f64::INFINITY); reference.len()];
    let mut cur_best = vec![(u32::MAX, f64::INFINITY); current.len()];
    for (i, &p) in reference.iter().enumerate() {
        for j in grid.candidates(p) {
            let d = dist2_f64(p, current[j]);
            if d > g2 {
                continue;
            }
            // Ties go to the lowest index on both sides (candidates may come in any order).
            let rb = &mut ref_best[i];
            if d < rb.1 || (d == rb.1 && (j as u32) < rb.0) {
                *rb = (j as u32, d);
            }
            let cb = &mut cur_best[j];
            if d < cb.1 || (d == cb.1 && (i as u32) < cb.0) {
                *cb = (i as u32, d);
            }
        }
    }
    ref_best
        .iter()
        .enumerate()
        .filter(|&(i, &(j, _))| j != u32::MAX && cur_best[j as usize].0 == i as u32)
        .map(|(i, &(j, _))| (i, j))
        .collect()
}

/// [`mutual_in_grid`] with nearest neighbours from 2-d trees over the distinct points of each
/// side (a duplicate is never nearer, nor a lower index, than the first copy of its point).
fn mutual_in_trees(reference: &[[f32; 2]], current: &[[f32; 2]], g2: f64) -> Vec<(usize, u32)> {
    let cur_tree = KdTree::unique(current);
    let ref_tree = KdTree::unique(reference);
    // Nearest reference of each current point, computed once per current point that is some
    // reference's nearest.
    const UNKNOWN: u32 = u32::MAX - 1;
    let mut cur_best = vec![UNKNOWN; current.len()];
    let mut pairs = Vec::new();
    for (i, &p) in reference.iter().enumerate() {
        let Some((j, _)) = cur_tree.nearest(p, g2, false) else {
            continue;
        };
        let ju = j as usize;
        if cur_best[ju] == UNKNOWN {
            cur_best[ju] = ref_tree
                .nearest(current[ju], g2, false)
                .map_or(u32::MAX, |(r, _)| r);
        }
        if cur_best[ju] == i as u32 {
            pairs.push((i, j));
        }
    }
    pairs
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::dist2;

    fn grid(nx: usize, ny: usize, pitch: f32) -> Vec<[f32; 2]> {
        (0..ny)
            .flat_map(|j| (0..nx).map(move |i| [i as f32 * pitch, j as f32 * pitch]))
            .collect()
    }

    #[test]
    fn recovers_small_shift() {
        let r = grid(10, 10, 20.0);
        let c: Vec<_> = r.iter().rev().map(|p| [p[0] + 3.0, p[1] - 2.0]).collect();
        let m = match_markers(&r, &c, None).unwrap();
        assert!(m.valid.iter().all(|&v| v));
        assert!((m.max_dist - 10.0).abs() < 1e-5);
        for mv in &m.motion {
            assert!((mv[0] - 3.0).abs() < 1e-5 && (mv[1] + 2.0).abs() < 1e-5);
        }
    }

    #[test]
    fn motion_beyond_the_gate_is_unmatched_not_mismatched() {
        let r = grid(5, 5, 20.0);
        // 11 px diagonally: beyond the 10 px gate for its own marker and for every neighbour.
        let c: Vec<_> = r.iter().map(|p| [p[0] + 7.8, p[1] + 7.8]).collect();
        let m = match_markers(&r, &c, None).unwrap();
        assert!(m.valid.iter().all(|&v| !v));
        assert!(m.motion.iter().all(|p| p[0].is_nan() && p[1].is_nan()));
        let m = match_markers(&r, &c, Some(12.0)).unwrap();
        assert!(m.valid.iter().all(|&v| v));
    }

    #[test]
    fn lost_marker_is_nan_and_never_borrows() {
        let r = grid(4, 4, 20.0);
        let mut c = r.clone();
        c.remove(5);
        let m = match_markers(&r, &c, None).unwrap();
        assert!(!m.valid[5]);
        assert!(m.motion[5][0].is_nan());
        assert_eq!(m.valid.iter().filter(|&&v| v).count(), 15);
    }

    #[test]
    fn duplicates_match_once_and_bad_input_is_named() {
        let r = grid(3, 3, 20.0);
        let c = vec![r[0], r[0]];
        let m = match_markers(&r, &c, Some(5.0)).unwrap();
        assert_eq!(m.index[0], 0);
        let err = match_markers(&[[f32::NAN, 0.0]], &r, None).unwrap_err();
        assert!(err.to_string().starts_with("ref_pts"));
        let err = match_markers(&r, &r, Some(-1.0)).unwrap_err();
        assert!(err.to_string().starts_with("max_dist"));
        assert!(match_markers(&[], &r, None).unwrap().valid.is_empty());
    }

    #[test]
    fn a_million_duplicates_match_once_in_bounded_time() {
        let z = vec![[0.0f32, 0.0]; 1_000_000];
        let t = std::time::Instant::now();
        let m = match_markers(&z, &z, Some(1.0)).unwrap();
        assert!(t.elapsed().as_secs_f64() < 20.0);
        assert_eq!(m.valid.iter().filter(|&&v| v).count(), 1);
        assert!(m.valid[0] && m.index[0] == 0);
    }

    #[test]
    fn overflowing_motion_is_unmatched_not_infinite() {
        let m = match_markers(&[[3e38, 0.0]], &[[-3e38, 0.0]], None).unwrap();
        assert!(!m.valid[0] && m.motion[0][0].is_nan());
        // Far apart but representable: matched, exact.
        let m = match_markers(&[[1e30, 0.0]], &[[-1e30, 0.0]], None).unwrap();
        assert!(m.valid[0] && m.motion[0][0] == -2e30);
    }

    #[test]
    fn agrees_with_brute_force_mutual_nearest() {
        let pts = |n: usize, s: f32| -> Vec<[f32; 2]> {
            (0..n)
                .map(|i| {
                    let t = i as f32 * 0.618_034 + s;
                    [((t * 97.0) % 60.0).floor(), ((t * 41.0) % 40.0).floor()]
                })
                .collect()
        };
        let (r, c) = (pts(300, 0.0), pts(280, 0.3));
        // 1.5 and 4 px take the grid, 40 px (cells of 40+ points) and no gate the trees.
        for gate in [1.5f32, 4.0, 40.0, f32::INFINITY] {
            let m = match_with_gate(&r, &c, gate);
            let best = |a: &[[f32; 2]], b: &[[f32; 2]], i: usize| {
                let mut best: Option<(usize, f32)> = None;
                for (j, &q) in b.iter().enumerate() {
                    let d = dist2(a[i], q);
                    if d <= gate * gate && best.map_or(true, |x| d < x.1) {
                        best = Some((j, d));
                    }
                }
                best.map(|x| x.0)
            };
            for i in 0..r.len() {
                let want = best(&r, &c, i).filter(|&j| best(&c, &r, j) == Some(i));
                assert_eq!(
                    m.index[i],
                    want.map_or(-1, |j| j as i64),
                    "gate {gate}, ref {i}"
                );
            }
        }
    }
}

#[cfg(test)]
mod profile {
    use super::*;
    use std::time::Instant;

    /// `cargo test --release -p tacswitch-core profile_matching -- --ignored --nocapture`
    #[test]
    #[ignore]
    fn profile_matching() {
        for (nx, ny) in [(8, 6), (10, 10), (19, 14)] {
            let r: Vec<[f32; 2]> = (0..ny)
                .flat_map(|j| (0..nx).map(move |i| [i as f32 * 30.0, j as f32 * 30.0]))
                .collect();
            let c: Vec<[f32; 2]> = r.iter().rev().map(|p| [p[0] + 1.5, p[1] - 2.0]).collect();
            let reps = 2000;
            let t = Instant::now();
            for _ in 0..reps {
                std::hint::black_box(match_markers(&r, &c, None).unwrap());
            }
            let all = t.elapsed().as_secs_f64() * 1e6 / reps as f64;
            let t = Instant::now();
            for _ in 0..reps {
                std::hint::black_box(crate::geometry::estimate_pitch(&r));
            }
            let pitch = t.elapsed().as_secs_f64() * 1e6 / reps as f64;
            println!(
                "{} markers: match {all:.2} us (pitch {pitch:.2} us)",
                r.len()
            );
        }
    }
}
