//! Causal features of a tracked marker field over time, for the learned slip detector.
//!
//! One vector of [`N_FEATURES`] values per frame, from that frame and earlier ones only. Lengths
//! are in marker pitches (the same gel motion reads the same on a 640x480 GelSight and a 320x240
//! GelSight Mini) and every feature is invariant to rotating or mirroring the image.
//!
//! Per frame, from the motion `m` of each valid marker since the first frame ([`N_FRAME`]):
//! 0-5 the field's state: median and 90th-percentile `|m|`, length of the mean motion, 90th
//! percentile residual of the least-squares affine fit, the fit's dilation and absolute rotation;
//! 6-9 and 10-13 its change over 1 and 4 frames: 90th-percentile and median length, affine
//! residual of the change, and that residual over (90th percentile + [`INCOHERENCE_FLOOR`]);
//! 14 the share of markers lost; 15 relaxation: the largest median `|m|` of the last [`LONG`]
//! frames minus the current one; 16 the median change over the last [`LONG`] frames.
//! The vector is those 17 values, their maximum and minimum over the last [`WINDOW`] frames, and
//! their change since [`LONG`] frames ago (the oldest kept while fewer have been seen); then
//! [`N_SNAP`] values of how abruptly the field changes ([`SlipFeatures::snap_values`]: a shaken
//! grasp reverses smoothly over several frames, stored shear released by a slip snaps back within
//! one or two) and their maximum over the last [`WINDOW`] frames.
//! Percentiles interpolate linearly between order statistics (numpy's default).

use std::collections::VecDeque;

use crate::error::{CoreError, Result};
use crate::still_filter::StillFilter;

/// Per-frame features.
pub const N_FRAME: usize = 17;
/// Per-frame snap-back values ([`SlipFeatures::snap_values`]).
pub const N_SNAP: usize = 6;
/// Length of the feature vector before the snap-back values were added (a scorer trained on it
/// reads this prefix of the vector).
pub const N_BASE_FEATURES: usize = 4 * N_FRAME;
/// Length of the feature vector of a frame.
pub const N_FEATURES: usize = N_BASE_FEATURES + 2 * N_SNAP;
/// Frames of the window maximum and minimum.
pub const WINDOW: usize = 8;
/// Frames of the long-term change and the relaxation.
pub const LONG: usize = 25;
/// Fits need this many valid markers; with fewer their features are 0.
pub const MIN_MARKERS: usize = 6;
/// Added to a change's 90th-percentile length (pitches) before dividing by it.
pub const INCOHERENCE_FLOOR: f64 = 0.02;
/// Snap-back values need this many markers valid in the last three frames; with fewer they are 0.
pub const SNAP_MIN_MARKERS: usize = 3;
/// Markers displaced at least this far (pitches) count in the motion back towards rest.
pub const SNAP_MIN_DISPLACEMENT: f64 = 0.2;
/// Added to the reversal cosine's denominator (pitches squared) so a still field reads 0.
const REVERSAL_FLOOR: f64 = 1e-4;

/// Linear-interpolation percentile (`q` in 0..=100) of `v`, which it sorts; 0 when empty.
pub(crate) fn percentile(v: &mut [f64], q: f64) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_unstable_by(|a, b| a.total_cmp(b));
    let pos = q / 100.0 * (v.len() - 1) as f64;
    let lo = pos.floor() as usize;
    let hi = pos.ceil() as usize;
    v[lo] + (v[hi] - v[lo]) * (pos - lo as f64)
}

/// Solves the 3x3 system `a x = b` by Gaussian elimination with partial pivoting; None when
/// singular.
fn solve3(mut a: [[f64; 3]; 3], mut b: [f64; 3]) -> Option<[f64; 3]> {
    for col in 0..3 {
        let piv = (col..3).max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))?;
        if a[piv][col].abs() < 1e-12 {
            return None;
        }
        a.swap(col, piv);
        b.swap(col, piv);
        for row in col + 1..3 {
            let f = a[row][col] / a[col][col];
            let pivot_row = a[col];
            for (v, p) in a[row].iter_mut().zip(pivot_row).skip(col) {
                *v -= f * p;
            }
            b[row] -= f * b[col];
        }
    }
    let mut x = [0.0; 3];
    for row in (0..3).rev() {
        let mut s = b[row];
        for k in row + 1..3 {
            s -= a[row][k] * x[k];
        }
        x[row] = s / a[row][row];
    }
    Some(x)
}

/// Smallest spread of the fitted markers' positions across their main direction, as a share of
/// the spread along it (the eigenvalues of their centred covariance), for which [`affine`] fits
/// a field: markers that nearly lie on one line (a single row left valid) determine no gradient
/// across it, and a fit would turn their noise into dilation and rotation. Scale-free; a grid
/// of two rows or more passes (on real Mini recordings the valid markers' share is 0.37 or more).
const MIN_SPREAD_SHARE: f64 = 0.01;

/// The eigenvalues (smaller, larger) of the centred covariance of `pts`.
fn spread(pts: &[[f64; 2]]) -> (f64, f64) {
    let n = pts.len().max(1) as f64;
    let (mx, my) = pts
        .iter()
        .fold((0.0, 0.0), |(a, b), p| (a + p[0] / n, b + p[1] / n));
    let (mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0);
    for p in pts {
        let (dx, dy) = (p[0] - mx, p[1] - my);
        sxx += dx * dx / n;
        syy += dy * dy / n;
        sxy += dx * dy / n;
    }
    let half_trace = 0.5 * (sxx + syy);
    let root = (half_trace * half_trace - (sxx * syy - sxy * sxy))
        .max(0.0)
        .sqrt();
    (half_trace - root, half_trace + root)
}

/// 90th-percentile residual, dilation and absolute rotation of the least-squares affine field
/// through `(p, v)` pairs; zeros when the points do not determine one (nearly collinear: see
/// [`MIN_SPREAD_SHARE`]).
fn affine(pts: &[[f64; 2]], vec: &[[f64; 2]], scratch: &mut Vec<f64>) -> [f64; 3] {
    let (across, along) = spread(pts);
    if across <= MIN_SPREAD_SHARE * along {
        return [0.0; 3];
    }
    let mut s = [[0.0; 3]; 3];
    let mut bx = [0.0; 3];
    let mut by = [0.0; 3];
    for (p, v) in pts.iter().zip(vec) {
        let a = [p[0], p[1], 1.0];
        for i in 0..3 {
            for j in 0..3 {
                s[i][j] += a[i] * a[j];
            }
            bx[i] += a[i] * v[0];
            by[i] += a[i] * v[1];
        }
    }
    let (Some(cx), Some(cy)) = (solve3(s, bx), solve3(s, by)) else {
        return [0.0; 3];
    };
    scratch.clear();
    scratch.extend(pts.iter().zip(vec).map(|(p, v)| {
        let rx = cx[0] * p[0] + cx[1] * p[1] + cx[2] - v[0];
        let ry = cy[0] * p[0] + cy[1] * p[1] + cy[2] - v[1];
        (rx * rx + ry * ry).sqrt()
    }));
    let resid = percentile(scratch, 90.0);
    // Jacobian [[cx0, cx1], [cy0, cy1]]: dilation = trace, rotation = d(vy)/dx - d(vx)/dy.
    [resid, cx[0] + cy[1], (cy[0] - cx[1]).abs()]
}

/// Streaming feature extractor of one marker field.
#[derive(Debug, Clone)]
pub struct SlipFeatures {
    pts: Vec<[f64; 2]>,
    pitch: f64,
    hist: VecDeque<(Vec<[f64; 2]>, Vec<bool>)>,
    medians: VecDeque<f64>,
    recent: VecDeque<[f64; N_FRAME]>,
    long: VecDeque<[f64; N_FRAME]>,
    recent_snap: VecDeque<[f64; N_SNAP]>,
    // Scratch buffers reused every frame.
    sel_p: Vec<[f64; 2]>,
    sel_v: Vec<[f64; 2]>,
    sel_m: Vec<[f64; 2]>,
    lens: Vec<f64>,
    scratch: Vec<f64>,
    // Holds still markers still under camera noise (`with_still_filter`).
    still: Option<StillFilter>,
}

impl SlipFeatures {
    /// An extractor for markers at `points` (`x, y` px) with the given pitch (px).
    pub fn new(points: &[[f32; 2]], pitch: f32) -> Result<Self> {
        if !(pitch.is_finite() && pitch > 0.0) {
            return Err(CoreError::invalid(
                "pitch",
                format!("must be > 0; got {pitch}"),
            ));
        }
        crate::geometry::check_finite(points, "points")?;
        let n = points.len().max(1) as f64;
        let cx = points.iter().map(|p| p[0] as f64).sum::<f64>() / n;
        let cy = points.iter().map(|p| p[1] as f64).sum::<f64>() / n;
        let pitch = pitch as f64;
        let pts = points
            .iter()
            .map(|p| [(p[0] as f64 - cx) / pitch, (p[1] as f64 - cy) / pitch])
            .collect();
        Ok(Self {
            pts,
            pitch,
            hist: VecDeque::with_capacity(LONG + 1),
            medians: VecDeque::with_capacity(LONG),
            recent: VecDeque::with_capacity(WINDOW),
            long: VecDeque::with_capacity(LONG + 1),
            recent_snap: VecDeque::with_capacity(WINDOW),
            sel_p: Vec::new(),
            sel_v: Vec::new(),
            sel_m: Vec::new(),
            lens: Vec::new(),
            scratch: Vec::new(),
            still: None,
        })
    }

    /// The same extractor reading the motion through a [`StillFilter`] (tracked markers from a
    /// camera whose noise moves still markers; the shipped marker scorer reads it this way).
    pub fn with_still_filter(mut self) -> Self {
        self.still = Some(StillFilter::new(self.pitch));
        self
    }

    /// Whether the motion is read through a [`StillFilter`].
    pub fn still_filter(&self) -> bool {
        self.still.is_some()
    }

    /// Number of markers.
    pub fn len(&self) -> usize {
        self.pts.len()
    }

    /// Whether there are no markers.
    pub fn is_empty(&self) -> bool {
        self.pts.is_empty()
    }

    /// Forgets the history (the next frame is treated as the first).
    pub fn reset(&mut self) {
        self.hist.clear();
        self.medians.clear();
        self.recent.clear();
        self.long.clear();
        self.recent_snap.clear();
        if let Some(f) = self.still.as_mut() {
            f.reset();
        }
    }

    /// Change statistics (p90, median, affine residual, incoherence) between now and `lag`
    /// frames ago over markers valid in both; zeros when too few.
    fn change(&mut self, lag: usize) -> [f64; 4] {
        let n_hist = self.hist.len();
        if n_hist <= lag {
            return [0.0; 4];
        }
        let (cur, cur_ok) = &self.hist[n_hist - 1];
        let (old, old_ok) = &self.hist[n_hist - 1 - lag];
        self.sel_p.clear();
        self.sel_v.clear();
        for i in 0..cur.len() {
            if cur_ok[i] && old_ok[i] {
                self.sel_p.push(self.pts[i]);
                self.sel_v
                    .push([cur[i][0] - old[i][0], cur[i][1] - old[i][1]]);
            }
        }
        if self.sel_v.len() < MIN_MARKERS {
            return [0.0; 4];
        }
        self.lens.clear();
        self.lens.extend(
            self.sel_v
                .iter()
                .map(|v| (v[0] * v[0] + v[1] * v[1]).sqrt()),
        );
        let p90 = percentile(&mut self.lens, 90.0);
        let med = percentile(&mut self.lens, 50.0);
        let resid = affine(&self.sel_p, &self.sel_v, &mut self.scratch)[0];
        [p90, med, resid, resid / (p90 + INCOHERENCE_FLOOR)]
    }

    /// The [`N_FRAME`] per-frame values of this frame (history updated).
    fn frame_values(&mut self, motion: &[[f32; 2]], valid: &[bool]) -> [f64; N_FRAME] {
        let m: Vec<[f64; 2]> = motion
            .iter()
            .map(|v| [v[0] as f64 / self.pitch, v[1] as f64 / self.pitch])
            .collect();
        let ok: Vec<bool> = valid
            .iter()
            .zip(&m)
            .map(|(&v, p)| v && p[0].is_finite() && p[1].is_finite())
            .collect();
        if self.hist.len() == LONG + 1 {
            self.hist.pop_front();
        }
        self.hist.push_back((m, ok));
        let mut out = [0.0; N_FRAME];
        let (m, ok) = &self.hist[self.hist.len() - 1];
        let n = m.len();
        let n_ok = ok.iter().filter(|&&v| v).count();
        out[14] = if n == 0 {
            1.0
        } else {
            1.0 - n_ok as f64 / n as f64
        };
        if self.medians.len() == LONG {
            self.medians.pop_front();
        }
        if n_ok < MIN_MARKERS {
            let last = self.medians.back().copied().unwrap_or(0.0);
            self.medians.push_back(last);
            return out;
        }
        self.sel_p.clear();
        self.sel_v.clear();
        let (mut sx, mut sy) = (0.0, 0.0);
        for i in 0..n {
            if ok[i] {
                self.sel_p.push(self.pts[i]);
                self.sel_v.push(m[i]);
                sx += m[i][0];
                sy += m[i][1];
            }
        }
        self.lens.clear();
        self.lens.extend(
            self.sel_v
                .iter()
                .map(|v| (v[0] * v[0] + v[1] * v[1]).sqrt()),
        );
        out[1] = percentile(&mut self.lens, 90.0);
        out[0] = percentile(&mut self.lens, 50.0);
        let k = n_ok as f64;
        out[2] = ((sx / k).powi(2) + (sy / k).powi(2)).sqrt();
        let aff = affine(&self.sel_p, &self.sel_v, &mut self.scratch);
        out[3..6].copy_from_slice(&aff);
        let c1 = self.change(1);
        out[6..10].copy_from_slice(&c1);
        let c4 = self.change(4);
        out[10..14].copy_from_slice(&c4);
        self.medians.push_back(out[0]);
        let peak = self.medians.iter().copied().fold(f64::MIN, f64::max);
        out[15] = peak - out[0];
        if self.hist.len() > LONG {
            let (cur, cur_ok) = &self.hist[self.hist.len() - 1];
            let (old, old_ok) = &self.hist[0];
            self.lens.clear();
            for i in 0..cur.len() {
                if cur_ok[i] && old_ok[i] {
                    let d = [cur[i][0] - old[i][0], cur[i][1] - old[i][1]];
                    self.lens.push((d[0] * d[0] + d[1] * d[1]).sqrt());
                }
            }
            out[16] = percentile(&mut self.lens, 50.0);
        }
        out
    }

    /// The [`N_SNAP`] snap-back values of the newest frame, in pitches, over the markers valid in
    /// it and the two frames before (zeros with fewer than [`SNAP_MIN_MARKERS`] or before the
    /// third frame), with `v1` / `v0` the last two one-frame changes and `a = v1 - v0`:
    /// 0 the 90th-percentile `|a|`; 1 that over the sum of the 90th-percentile `|v1|` and `|v0|`
    /// plus [`INCOHERENCE_FLOOR`] (abruptness); 2 `sum(v1 . v0) / sum(|v1| |v0|)` (-1: the field
    /// reverses); 3-5 over the markers displaced at least [`SNAP_MIN_DISPLACEMENT`] a frame ago,
    /// the motion back towards rest `-(v1 . m) / |m|`: its 90th percentile, its median, and the
    /// median of it over `|m|` (the share of the displacement released in one frame).
    fn snap_values(&mut self) -> [f64; N_SNAP] {
        let n_hist = self.hist.len();
        if n_hist < 3 {
            return [0.0; N_SNAP];
        }
        let (m2, ok2) = &self.hist[n_hist - 1];
        let (m1, ok1) = &self.hist[n_hist - 2];
        let (m0, ok0) = &self.hist[n_hist - 3];
        // Reused buffers: sel_v = v1, sel_p = v0, sel_m = the displacement a frame ago.
        self.sel_v.clear();
        self.sel_p.clear();
        self.sel_m.clear();
        for i in 0..m2.len() {
            if ok2[i] && ok1[i] && ok0[i] {
                self.sel_v.push([m2[i][0] - m1[i][0], m2[i][1] - m1[i][1]]);
                self.sel_p.push([m1[i][0] - m0[i][0], m1[i][1] - m0[i][1]]);
                self.sel_m.push(m1[i]);
            }
        }
        if self.sel_v.len() < SNAP_MIN_MARKERS {
            return [0.0; N_SNAP];
        }
        let norm = |v: &[f64; 2]| (v[0] * v[0] + v[1] * v[1]).sqrt();
        let (mut dot, mut mag) = (0.0, 0.0);
        self.lens.clear();
        for (v1, v0) in self.sel_v.iter().zip(&self.sel_p) {
            self.lens.push(norm(&[v1[0] - v0[0], v1[1] - v0[1]]));
            dot += v1[0] * v0[0] + v1[1] * v0[1];
            mag += norm(v1) * norm(v0);
        }
        let p_acc = percentile(&mut self.lens, 90.0);
        self.lens.clear();
        self.lens.extend(self.sel_v.iter().map(norm));
        let p_v1 = percentile(&mut self.lens, 90.0);
        self.lens.clear();
        self.lens.extend(self.sel_p.iter().map(norm));
        let p_v0 = percentile(&mut self.lens, 90.0);
        let mut out = [0.0; N_SNAP];
        out[0] = p_acc;
        out[1] = p_acc / (p_v1 + p_v0 + INCOHERENCE_FLOOR);
        out[2] = dot / (mag + REVERSAL_FLOOR);
        self.lens.clear();
        self.scratch.clear();
        for (v1, m) in self.sel_v.iter().zip(&self.sel_m) {
            let d = norm(m);
            if d > SNAP_MIN_DISPLACEMENT {
                let back = -(v1[0] * m[0] + v1[1] * m[1]) / d;
                self.lens.push(back);
                self.scratch.push(back / d);
            }
        }
        if self.lens.len() >= SNAP_MIN_MARKERS {
            out[3] = percentile(&mut self.lens, 90.0);
            out[4] = percentile(&mut self.lens, 50.0);
            out[5] = percentile(&mut self.scratch, 50.0);
        }
        out
    }

    /// Feeds one frame's motion since the first frame (`N x 2` px, NaN = lost) and validity;
    /// returns its [`N_FEATURES`] features.
    pub fn update(&mut self, motion: &[[f32; 2]], valid: &[bool]) -> Result<[f32; N_FEATURES]> {
        if motion.len() != self.pts.len() {
            return Err(CoreError::invalid(
                "motion",
                format!(
                    "expected {} rows (one per reference marker); got {}",
                    self.pts.len(),
                    motion.len()
                ),
            ));
        }
        if valid.len() != motion.len() {
            return Err(CoreError::invalid(
                "valid",
                format!("expected {} flags; got {}", motion.len(), valid.len()),
            ));
        }
        // The filter is taken out while its output is borrowed (no copy of the field a frame).
        let mut still = self.still.take();
        let motion = match still.as_mut() {
            Some(filter) => filter.update(motion),
            None => motion,
        };
        let f = self.frame_values(motion, valid);
        self.still = still;
        let snap = self.snap_values();
        if self.recent_snap.len() == WINDOW {
            self.recent_snap.pop_front();
        }
        self.recent_snap.push_back(snap);
        if self.recent.len() == WINDOW {
            self.recent.pop_front();
        }
        self.recent.push_back(f);
        if self.long.len() == LONG + 1 {
            self.long.pop_front();
        }
        self.long.push_back(f);
        let oldest = self.long.front().copied().unwrap_or(f);
        let mut out = [0.0f32; N_FEATURES];
        for j in 0..N_FRAME {
            let mut hi = f64::MIN;
            let mut lo = f64::MAX;
            for r in &self.recent {
                hi = hi.max(r[j]);
                lo = lo.min(r[j]);
            }
            out[j] = f[j] as f32;
            out[N_FRAME + j] = hi as f32;
            out[2 * N_FRAME + j] = lo as f32;
            out[3 * N_FRAME + j] = (f[j] - oldest[j]) as f32;
        }
        for (j, &v) in snap.iter().enumerate() {
            let hi = self
                .recent_snap
                .iter()
                .fold(f64::MIN, |acc, r| acc.max(r[j]));
            out[N_BASE_FEATURES + j] = v as f32;
            out[N_BASE_FEATURES + N_SNAP + j] = hi as f32;
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid() -> Vec<[f32; 2]> {
        let mut p = Vec::new();
        for y in 0..7 {
            for x in 0..9 {
                p.push([20.0 + 30.0 * x as f32, 15.0 + 30.0 * y as f32]);
            }
        }
        p
    }

    #[test]
    fn a_nearly_collinear_selection_fits_no_affine_field() {
        // One row of markers (in pitches) with noise across it: no gradient across the row.
        let pts: Vec<[f64; 2]> = (0..9)
            .map(|i| [i as f64 - 4.0, if i % 2 == 0 { 0.01 } else { -0.01 }])
            .collect();
        let vec: Vec<[f64; 2]> = (0..9)
            .map(|i| {
                [
                    0.002 * (i % 3) as f64,
                    if i % 2 == 0 { 0.003 } else { -0.002 },
                ]
            })
            .collect();
        assert_eq!(affine(&pts, &vec, &mut Vec::new()), [0.0; 3]);
        // The full grid still fits: a pure dilation is read as one.
        let grid: Vec<[f64; 2]> = (0..25)
            .map(|i| [(i % 5) as f64 - 2.0, (i / 5) as f64 - 2.0])
            .collect();
        let dil: Vec<[f64; 2]> = grid.iter().map(|p| [0.1 * p[0], 0.1 * p[1]]).collect();
        let [resid, dilation, rotation] = affine(&grid, &dil, &mut Vec::new());
        assert!(resid < 1e-9 && (dilation - 0.2).abs() < 1e-9 && rotation < 1e-9);
    }

    #[test]
    fn percentile_matches_numpy_linear() {
        let mut v = vec![4.0, 1.0, 3.0, 2.0];
        assert!((percentile(&mut v, 90.0) - 3.7).abs() < 1e-12);
        assert!((percentile(&mut v, 50.0) - 2.5).abs() < 1e-12);
        assert_eq!(percentile(&mut [], 50.0), 0.0);
    }

    #[test]
    fn the_still_filter_leaves_a_stream_without_jitter_unchanged() {
        let pts = grid();
        let mut plain = SlipFeatures::new(&pts, 30.0).unwrap();
        let mut still = SlipFeatures::new(&pts, 30.0).unwrap().with_still_filter();
        assert!(still.still_filter() && !plain.still_filter());
        let valid = vec![true; pts.len()];
        for t in 0..30 {
            // Half the markers exactly still, half sliding: no frame-to-frame jitter.
            let m: Vec<[f32; 2]> = (0..pts.len())
                .map(|i| {
                    if i % 2 == 0 {
                        [0.0, 0.0]
                    } else {
                        [0.2 * t as f32, 0.0]
                    }
                })
                .collect();
            assert_eq!(
                plain.update(&m, &valid).unwrap(),
                still.update(&m, &valid).unwrap()
            );
        }
    }

    #[test]
    fn rigid_translation_has_no_residual_and_scales_with_pitch() {
        let pts = grid();
        let mut f = SlipFeatures::new(&pts, 30.0).unwrap();
        let valid = vec![true; pts.len()];
        f.update(&vec![[0.0, 0.0]; pts.len()], &valid).unwrap();
        let out = f.update(&vec![[6.0, 8.0]; pts.len()], &valid).unwrap();
        assert!((out[0] - 10.0 / 30.0).abs() < 1e-5);
        assert!((out[2] - 10.0 / 30.0).abs() < 1e-5);
        assert!(out[3].abs() < 1e-5, "affine residual {}", out[3]);
        assert!(
            (out[6] - 10.0 / 30.0).abs() < 1e-5,
            "one-frame change {}",
            out[6]
        );
        assert!(out[8].abs() < 1e-5);
    }

    #[test]
    fn rotation_and_dilation_are_measured() {
        let pts = grid();
        let mut f = SlipFeatures::new(&pts, 30.0).unwrap();
        let (cx, cy) = (140.0f32, 105.0f32);
        let a = 0.02f32;
        let rot: Vec<[f32; 2]> = pts
            .iter()
            .map(|p| {
                let (x, y) = (p[0] - cx, p[1] - cy);
                [x * a.cos() - y * a.sin() - x, x * a.sin() + y * a.cos() - y]
            })
            .collect();
        let out = f.update(&rot, &vec![true; pts.len()]).unwrap();
        assert!((out[5] - 2.0 * a.sin()).abs() < 1e-3, "rotation {}", out[5]);
        assert!(out[4].abs() < 1e-3, "dilation {}", out[4]);
    }

    #[test]
    fn relaxation_follows_a_drop() {
        let pts = grid();
        let mut f = SlipFeatures::new(&pts, 30.0).unwrap();
        let valid = vec![true; pts.len()];
        f.update(&vec![[9.0, 0.0]; pts.len()], &valid).unwrap();
        let out = f.update(&vec![[3.0, 0.0]; pts.len()], &valid).unwrap();
        assert!((out[15] - 0.2).abs() < 1e-5, "relaxation {}", out[15]);
    }

    #[test]
    fn too_few_markers_and_bad_arguments() {
        let pts = grid();
        let mut f = SlipFeatures::new(&pts, 30.0).unwrap();
        let mut valid = vec![false; pts.len()];
        valid[0] = true;
        let out = f.update(&vec![[1.0, 0.0]; pts.len()], &valid).unwrap();
        assert!((out[14] - (1.0 - 1.0 / 63.0)).abs() < 1e-5);
        assert_eq!(out[0], 0.0);
        assert!(f.update(&[[0.0, 0.0]], &[true]).is_err());
        assert!(f.update(&vec![[0.0, 0.0]; pts.len()], &[true]).is_err());
        assert!(SlipFeatures::new(&pts, 0.0).is_err());
        assert!(SlipFeatures::new(&pts, f32::NAN).is_err());
    }

    #[test]
    fn nan_rows_count_as_lost() {
        let pts = grid();
        let mut f = SlipFeatures::new(&pts, 30.0).unwrap();
        let mut m = vec![[1.0f32, 0.0]; pts.len()];
        m[3] = [f32::NAN, 0.0];
        let out = f.update(&m, &vec![true; pts.len()]).unwrap();
        assert!((out[14] - 1.0 / 63.0).abs() < 1e-5);
        assert!(out.iter().all(|v| v.is_finite()));
    }

    #[test]
    fn snap_back_reads_a_reversal_and_not_a_steady_drift() {
        let pts = grid();
        let valid = vec![true; pts.len()];
        let base = N_BASE_FEATURES;
        // Steady drift: no acceleration, the velocity keeps its direction.
        let mut f = SlipFeatures::new(&pts, 30.0).unwrap();
        let mut out = [0.0f32; N_FEATURES];
        for t in 0..4 {
            out = f
                .update(&vec![[4.0 * t as f32, 0.0]; pts.len()], &valid)
                .unwrap();
        }
        assert!(out[base].abs() < 1e-6, "acceleration {}", out[base]);
        assert!(
            (out[base + 2] - 1.0).abs() < 1e-3,
            "reversal {}",
            out[base + 2]
        );
        assert!(out[base + 3] < 0.0, "a drift moves away from rest");
        // Loaded, then released in one frame: the field reverses and moves back towards rest.
        let mut f = SlipFeatures::new(&pts, 30.0).unwrap();
        for m in [0.0f32, 6.0, 12.0] {
            out = f.update(&vec![[m, 0.0]; pts.len()], &valid).unwrap();
        }
        let snap = f.update(&vec![[3.0, 0.0]; pts.len()], &valid).unwrap();
        assert!(
            (snap[base] - 15.0 / 30.0).abs() < 1e-5,
            "acceleration {}",
            snap[base]
        );
        assert!(
            (snap[base + 2] + 1.0).abs() < 1e-3,
            "reversal {}",
            snap[base + 2]
        );
        assert!(
            (snap[base + 3] - 9.0 / 30.0).abs() < 1e-5,
            "back p90 {}",
            snap[base + 3]
        );
        assert!(
            (snap[base + 5] - 0.75).abs() < 1e-5,
            "share released {}",
            snap[base + 5]
        );
        // The window maximum keeps the snap for the next frames.
        let later = f.update(&vec![[3.0, 0.0]; pts.len()], &valid).unwrap();
        assert!((later[base + N_SNAP] - 15.0 / 30.0).abs() < 1e-5);
        assert!(out.iter().chain(&later).all(|v| v.is_finite()));
    }
}
