//! Slip detection from a marker motion field.
//!
//! Two criteria, each optional, both relative to the first frame of the grasp (the frame after
//! [`SlipDetector::reset`]):
//! - **displacement** (the paper's rule): slip when the largest marker displacement since the
//!   first frame exceeds `threshold_px` (3.25 px at 640x480 in the paper);
//! - **rigid**: the markers that moved most (at least `active_fraction` of the largest displacement)
//!   belong to the contact; while the contact sticks they move together as a rigid body. Slip when
//!   their largest deviation from the best-fit rigid motion exceeds `rigid_threshold_px` — the
//!   signature of incipient slip spreading in from the contact edge.

use crate::error::{CoreError, Result};
use crate::geometry::fit_rigid;

/// The paper's displacement threshold, pixels, at the paper's image width.
pub const PAPER_THRESHOLD_PX: f32 = 3.25;
/// Image width at which [`PAPER_THRESHOLD_PX`] was set.
pub const PAPER_IMAGE_WIDTH: f32 = 640.0;
/// Markers with at least this fraction of the largest displacement form the rigid-fit set.
pub const DEFAULT_ACTIVE_FRACTION: f32 = 0.5;
/// The rigid criterion needs this many markers in its set.
const MIN_RIGID_MARKERS: usize = 3;

/// The paper's threshold scaled to an image width (the rule is in pixels of a 640-wide frame).
pub fn scaled_threshold(image_width: usize) -> f32 {
    PAPER_THRESHOLD_PX * image_width as f32 / PAPER_IMAGE_WIDTH
}

/// Options of [`SlipDetector`].
#[derive(Debug, Clone, PartialEq)]
pub struct SlipParams {
    /// Displacement threshold, pixels; `None` disables the displacement criterion.
    pub threshold_px: Option<f32>,
    /// Rigid-deviation threshold, pixels; `None` disables the rigid criterion.
    pub rigid_threshold_px: Option<f32>,
    /// Fraction of the largest displacement that puts a marker in the rigid-fit set.
    pub active_fraction: f32,
}

impl Default for SlipParams {
    fn default() -> Self {
        Self {
            threshold_px: Some(PAPER_THRESHOLD_PX),
            rigid_threshold_px: None,
            active_fraction: DEFAULT_ACTIVE_FRACTION,
        }
    }
}

/// What one [`SlipDetector::update`] concluded.
#[derive(Debug, Clone, PartialEq)]
pub struct SlipState {
    /// Slip in this frame by any enabled criterion.
    pub slip: bool,
    /// The displacement criterion fired.
    pub by_displacement: bool,
    /// The rigid criterion fired.
    pub by_rigid: bool,
    /// Largest displacement since the first frame, pixels (0 when no marker is comparable).
    pub max_displacement: f32,
    /// Reference index of that marker, -1 if none.
    pub marker: i64,
    /// Largest deviation from the best rigid motion, pixels; NaN when not evaluated.
    pub rigid_residual: f32,
    /// Reference index of that marker, -1 if none.
    pub rigid_marker: i64,
    /// Markers valid in this frame and in the baseline.
    pub n_compared: usize,
    /// Frame index within the grasp, 0 for the first.
    pub frame: u64,
}

/// Streaming slip detector.
#[derive(Debug, Clone)]
pub struct SlipDetector {
    params: SlipParams,
    points: Option<Vec<[f32; 2]>>,
    baseline: Vec<[f32; 2]>,
    frame: u64,
    first_slip: Option<u64>,
}

impl SlipDetector {
    /// A detector. `points` are the reference marker positions, needed by the rigid criterion.
    pub fn new(params: SlipParams, points: Option<Vec<[f32; 2]>>) -> Result<Self> {
        for (name, v) in [
            ("threshold_px", params.threshold_px),
            ("rigid_threshold_px", params.rigid_threshold_px),
        ] {
            if let Some(t) = v {
                if !t.is_finite() || t <= 0.0 {
                    return Err(CoreError::invalid(
                        name,
                        format!("must be a positive, finite number of pixels; got {t}"),
                    ));
                }
            }
        }
        if !(params.active_fraction.is_finite()
            && params.active_fraction > 0.0
            && params.active_fraction <= 1.0)
        {
            return Err(CoreError::invalid(
                "active_fraction",
                format!("must be in (0, 1]; got {}", params.active_fraction),
            ));
        }
        if params.rigid_threshold_px.is_some() && points.is_none() {
            return Err(CoreError::invalid(
                "points",
                "the rigid criterion needs the reference marker positions",
            ));
        }
        if let Some(p) = &points {
            crate::geometry::check_finite(p, "points")?;
        }
        Ok(Self {
            params,
            points,
            baseline: Vec::new(),
            frame: 0,
            first_slip: None,
        })
    }

    /// Options in force.
    pub fn params(&self) -> &SlipParams {
        &self.params
    }

    /// First frame (within the grasp) where slip fired, if any.
    pub fn first_slip(&self) -> Option<u64> {
        self.first_slip
    }

    /// Starts a new grasp: the next update becomes the first frame.
    pub fn reset(&mut self) {
        self.baseline.clear();
        self.frame = 0;
        self.first_slip = None;
    }

    /// Feeds one frame's motion field (`(dx, dy)` per reference marker, NaN/invalid when lost).
    pub fn update(&mut self, motion: &[[f32; 2]], valid: &[bool]) -> Result<SlipState> {
        if motion.len() != valid.len() {
            return Err(CoreError::invalid(
                "valid",
                format!(
                    "must have one flag per motion row ({}); got {}",
                    motion.len(),
                    valid.len()
                ),
            ));
        }
        if let Some(p) = &self.points {
            if p.len() != motion.len() {
                return Err(CoreError::invalid(
                    "motion",
                    format!(
                        "has {} rows but the detector was built for {} markers",
                        motion.len(),
                        p.len()
                    ),
                ));
            }
        }
        if !self.baseline.is_empty() && self.baseline.len() != motion.len() {
            return Err(CoreError::invalid(
                "motion",
                format!(
                    "has {} rows but earlier frames of this grasp had {}; call reset() for a new grasp",
                    motion.len(),
                    self.baseline.len()
                ),
            ));
        }
        let usable = |i: usize| valid[i] && motion[i][0].is_finite() && motion[i][1].is_finite();
        if self.baseline.is_empty() {
            self.baseline = vec![[f32::NAN; 2]; motion.len()];
        }
        // A marker first seen later in the grasp gets its baseline then.
        for (i, base) in self.baseline.iter_mut().enumerate() {
            if usable(i) && base[0].is_nan() {
                *base = motion[i];
            }
        }

        let mut disp = vec![f32::NAN; motion.len()];
        let (mut max_d, mut marker, mut n_compared) = (0f32, -1i64, 0usize);
        for i in 0..motion.len() {
            if usable(i) && !self.baseline[i][0].is_nan() {
                let d =
                    (motion[i][0] - self.baseline[i][0]).hypot(motion[i][1] - self.baseline[i][1]);
                disp[i] = d;
                n_compared += 1;
                if d > max_d || marker < 0 {
                    max_d = d;
                    marker = i as i64;
                }
            }
        }
        let by_displacement = self.params.threshold_px.is_some_and(|t| max_d > t);

        let (mut rigid_residual, mut rigid_marker) = (f32::NAN, -1i64);
        if let (Some(points), Some(_)) = (&self.points, self.params.rigid_threshold_px) {
            let cut = self.params.active_fraction * max_d;
            let active: Vec<usize> = (0..motion.len())
                .filter(|&i| disp[i].is_finite() && disp[i] >= cut && max_d > 0.0)
                .collect();
            if active.len() >= MIN_RIGID_MARKERS {
                let src: Vec<[f32; 2]> = active
                    .iter()
                    .map(|&i| {
                        [
                            points[i][0] + self.baseline[i][0],
                            points[i][1] + self.baseline[i][1],
                        ]
                    })
                    .collect();
                let dst: Vec<[f32; 2]> = active
                    .iter()
                    .map(|&i| [points[i][0] + motion[i][0], points[i][1] + motion[i][1]])
                    .collect();
                if let Some(fit) = fit_rigid(&src, &dst) {
                    rigid_residual = 0.0;
                    for (k, &i) in active.iter().enumerate() {
                        let r = crate::geometry::dist2(fit.apply(src[k]), dst[k]).sqrt();
                        if r > rigid_residual || rigid_marker < 0 {
                            rigid_residual = r;
                            rigid_marker = i as i64;
                        }
                    }
                }
            }
        }
        let by_rigid = self
            .params
            .rigid_threshold_px
            .is_some_and(|t| rigid_residual > t);

        let slip = by_displacement || by_rigid;
        let frame = self.frame;
        if slip && self.first_slip.is_none() {
            self.first_slip = Some(frame);
        }
        self.frame += 1;
        Ok(SlipState {
            slip,
            by_displacement,
            by_rigid,
            max_displacement: max_d,
            marker,
            rigid_residual,
            rigid_marker,
            n_compared,
            frame,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid() -> Vec<[f32; 2]> {
        (0..6)
            .flat_map(|j| (0..8).map(move |i| [40.0 + 80.0 * i as f32, 40.0 + 80.0 * j as f32]))
            .collect()
    }

    #[test]
    fn paper_rule_fires_above_threshold_relative_to_first_frame() {
        let n = 48;
        let mut det = SlipDetector::new(SlipParams::default(), None).unwrap();
        let valid = vec![true; n];
        // A large press offset in the first frame is the baseline, not slip.
        let base = vec![[10.0f32, 0.0]; n];
        assert!(!det.update(&base, &valid).unwrap().slip);
        let mut m = base.clone();
        m[7] = [13.0, 0.0];
        let st = det.update(&m, &valid).unwrap();
        assert!(!st.slip && (st.max_displacement - 3.0).abs() < 1e-5);
        m[7] = [13.5, 0.0];
        let st = det.update(&m, &valid).unwrap();
        assert!(st.slip && st.by_displacement && st.marker == 7 && st.frame == 2);
        assert_eq!(det.first_slip(), Some(2));
    }

    #[test]
    fn rigid_criterion_ignores_rigid_shear_and_flags_edge_lag() {
        let pts = grid();
        let params = SlipParams {
            threshold_px: None,
            rigid_threshold_px: Some(1.0),
            ..Default::default()
        };
        let mut det = SlipDetector::new(params, Some(pts.clone())).unwrap();
        let valid = vec![true; pts.len()];
        let zero = vec![[0f32; 2]; pts.len()];
        det.update(&zero, &valid).unwrap();
        // A 3x3 patch of contact markers shears rigidly (translation + twist about its centre);
        // markers outside the contact follow at a fifth of that: no slip whatever the size.
        let contact = [9usize, 10, 11, 17, 18, 19, 25, 26, 27];
        let centre = pts[18];
        let rot = crate::geometry::Rigid2 {
            theta: 0.02,
            t: [6.0, -4.0],
        };
        let rigid: Vec<[f32; 2]> = pts
            .iter()
            .enumerate()
            .map(|(i, &p)| {
                let rel = [p[0] - centre[0], p[1] - centre[1]];
                let q = rot.apply(rel);
                let m = [q[0] - rel[0], q[1] - rel[1]];
                if contact.contains(&i) {
                    m
                } else {
                    [0.2 * m[0], 0.2 * m[1]]
                }
            })
            .collect();
        let st = det.update(&rigid, &valid).unwrap();
        assert!(!st.slip && st.rigid_residual < 1e-3);
        // One contact marker lags by 3 px: incipient slip.
        let mut lag = rigid.clone();
        lag[10][0] -= 3.0;
        let st = det.update(&lag, &valid).unwrap();
        assert!(st.slip && st.by_rigid && !st.by_displacement);
    }

    #[test]
    fn invalid_markers_are_skipped_and_errors_named() {
        let mut det = SlipDetector::new(SlipParams::default(), None).unwrap();
        let st = det
            .update(&[[f32::NAN, f32::NAN], [1.0, 1.0]], &[false, true])
            .unwrap();
        assert_eq!(st.n_compared, 1);
        let err = det.update(&[[0.0, 0.0]], &[true, true]).unwrap_err();
        assert!(err.to_string().starts_with("valid"));
        let err = det.update(&[[0.0, 0.0]], &[true]).unwrap_err();
        assert!(err.to_string().starts_with("motion"));
        assert!(SlipDetector::new(
            SlipParams {
                threshold_px: Some(-1.0),
                ..Default::default()
            },
            None
        )
        .is_err());
    }
}
