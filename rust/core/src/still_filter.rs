//! A hysteresis on tracked marker motion that holds still markers exactly still under camera
//! noise.
//!
//! In the MPEG-4 and H.264 recordings the slip scorers learned from, a marker on a still gel is
//! tracked at exactly the same place frame after frame (the codec copies still blocks). Sensor
//! noise moves it by about 0.001 pitch a frame, and the scorers' "how still is the field"
//! features (window minima of the velocities) read that as a different gel. The filter reports a
//! marker's motion unchanged until its tracked motion is more than `h` pitches away from the
//! value reported last; `h` is [`StillFilter::K`] times the stream's own frame-to-frame jitter
//! floor (the smallest running median so far of each frame's 25th-percentile marker step, in
//! pitches), at most [`StillFilter::CAP`]. A stream with no jitter (the recordings) gets `h = 0`
//! and passes through unchanged; a noisy camera gets `h` above its noise. Repeated frames (every
//! marker exactly where it was) do not count towards the floor.

use std::collections::VecDeque;

use crate::slip_features::percentile;

/// Online hysteresis of one marker field (motions in pixels, thresholds in pitches).
#[derive(Debug, Clone)]
pub struct StillFilter {
    pitch: f64,
    steps: VecDeque<f64>,
    floor: f64,
    prev: Vec<[f32; 2]>,
    held: Vec<[f32; 2]>,
    started: bool,
    scratch: Vec<f64>,
}

impl StillFilter {
    /// Multiple of the jitter floor that a marker must move before its reported motion follows.
    pub const K: f64 = 8.0;
    /// Largest hysteresis, pitches (0.2 px at a GelSight Mini's 20 px pitch).
    pub const CAP: f64 = 0.01;
    /// Frames of the running median of the per-frame step.
    pub const WINDOW: usize = 5;
    /// Quantile of the markers' frame-to-frame steps taken as a frame's jitter (most markers of
    /// a contact do not move; a quarter of them are the stillest).
    pub const QUANTILE: f64 = 0.25;

    /// A filter for markers at `pitch` pixels.
    pub fn new(pitch: f64) -> Self {
        Self {
            pitch,
            steps: VecDeque::with_capacity(Self::WINDOW),
            floor: f64::INFINITY,
            prev: Vec::new(),
            held: Vec::new(),
            started: false,
            scratch: Vec::new(),
        }
    }

    /// Forgets the history (the next frame is treated as the first).
    pub fn reset(&mut self) {
        self.steps.clear();
        self.floor = f64::INFINITY;
        self.started = false;
    }

    /// The hysteresis now, pitches (0 until [`Self::WINDOW`] steps have been seen).
    pub fn hysteresis(&self) -> f64 {
        if self.floor.is_finite() {
            (Self::K * self.floor).min(Self::CAP)
        } else {
            0.0
        }
    }

    /// Feeds one frame's motion (`N x 2` px, NaN = lost); returns the reported motion (a lost
    /// marker is reported lost, and reported as tracked when it comes back).
    pub fn update(&mut self, motion: &[[f32; 2]]) -> &[[f32; 2]] {
        let finite = |p: &[f32; 2]| p[0].is_finite() && p[1].is_finite();
        if !self.started || self.prev.len() != motion.len() {
            self.started = true;
            self.prev = motion.to_vec();
            self.held = motion.to_vec();
            return &self.held;
        }
        self.scratch.clear();
        self.scratch.extend(
            motion
                .iter()
                .zip(&self.prev)
                .filter(|(a, b)| finite(a) && finite(b))
                .map(|(a, b)| {
                    let dx = (a[0] - b[0]) as f64;
                    let dy = (a[1] - b[1]) as f64;
                    (dx * dx + dy * dy).sqrt() / self.pitch
                }),
        );
        // A repeated frame (every marker exactly where it was: a camera or a player repeating a
        // frame, or the rest frames a recording's stale start is read as) says nothing of the
        // camera's jitter; counted, three of them in a window would set the floor to 0 for good.
        let repeated = !self.scratch.is_empty() && self.scratch.iter().all(|&s| s == 0.0);
        if !repeated {
            let step = if self.scratch.is_empty() {
                f64::INFINITY
            } else {
                percentile(&mut self.scratch, 100.0 * Self::QUANTILE)
            };
            if self.steps.len() == Self::WINDOW {
                self.steps.pop_front();
            }
            self.steps.push_back(step);
            if self.steps.len() == Self::WINDOW {
                self.scratch.clear();
                self.scratch.extend(self.steps.iter().copied());
                // A window holding infinite steps (frames without a finite marker) can give NaN
                // (inf - inf), which `min` ignores as it would ignore an infinite median.
                self.floor = self.floor.min(percentile(&mut self.scratch, 50.0));
            }
        }
        let h = self.hysteresis() * self.pitch;
        for ((held, &m), prev) in self.held.iter_mut().zip(motion).zip(self.prev.iter_mut()) {
            let dx = (m[0] - held[0]) as f64;
            let dy = (m[1] - held[1]) as f64;
            let dist = (dx * dx + dy * dy).sqrt();
            // A NaN distance (lost now, or lost when last reported) also follows.
            if dist.is_nan() || dist > h {
                *held = m;
            }
            *prev = m;
        }
        &self.held
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn noisy(n: usize, t: usize, sigma: f32, seed: u64) -> Vec<Vec<[f32; 2]>> {
        // A small deterministic generator (no dependency): uniform noise of the given spread.
        let mut s = seed.wrapping_mul(6364136223846793005).wrapping_add(1);
        let mut next = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((s >> 33) as f32 / (1u64 << 31) as f32 - 0.5) * 2.0 * sigma
        };
        (0..t)
            .map(|_| (0..n).map(|_| [next(), next()]).collect())
            .collect()
    }

    #[test]
    fn a_stream_without_jitter_passes_unchanged() {
        let mut f = StillFilter::new(20.0);
        for t in 0..40 {
            let m: Vec<[f32; 2]> = (0..30)
                .map(|i| {
                    if i < 10 {
                        [0.0, 0.0] // still markers: no jitter at all
                    } else {
                        [0.01 * t as f32, -0.003 * t as f32]
                    }
                })
                .collect();
            assert_eq!(f.update(&m), &m[..], "frame {t}");
        }
        assert_eq!(f.hysteresis(), 0.0);
    }

    #[test]
    fn still_markers_under_noise_read_still_and_moving_ones_follow() {
        let pitch = 20.0;
        let mut f = StillFilter::new(pitch);
        let noise = noisy(40, 60, 0.02, 7); // 0.001 pitch of jitter
        let mut last = Vec::new();
        for (t, nm) in noise.iter().enumerate() {
            let m: Vec<[f32; 2]> = nm
                .iter()
                .enumerate()
                .map(|(i, p)| {
                    let drift = if i < 5 { 0.5 * t as f32 } else { 0.0 };
                    [p[0] + drift, p[1]]
                })
                .collect();
            last = f.update(&m).to_vec();
            if t > 10 {
                let h = f.hysteresis() * pitch;
                assert!(h > 0.0 && h <= StillFilter::CAP * pitch);
                for (i, (r, mm)) in last.iter().zip(&m).enumerate() {
                    let d = ((r[0] - mm[0]).powi(2) + (r[1] - mm[1]).powi(2)).sqrt() as f64;
                    assert!(d <= h + 1e-6, "marker {i} lags by {d} > {h}");
                }
            }
        }
        // The moving markers keep up (within the hysteresis); the still ones froze.
        assert!((last[0][0] - 0.5 * 59.0).abs() < 0.3);
        let frozen = noise[59]
            .iter()
            .zip(&last)
            .skip(5)
            .filter(|(n, r)| n != r)
            .count();
        assert!(frozen > 25, "{frozen} of 35 still markers were held");
    }

    #[test]
    fn lost_markers_stay_lost_and_come_back_tracked() {
        let mut f = StillFilter::new(20.0);
        let noise = noisy(12, 20, 0.02, 3);
        for (t, nm) in noise.iter().enumerate() {
            let mut m = nm.clone();
            if (8..12).contains(&t) {
                m[0] = [f32::NAN, f32::NAN];
            }
            let out = f.update(&m).to_vec();
            if (8..12).contains(&t) {
                assert!(out[0][0].is_nan());
            } else if t == 12 {
                assert_eq!(out[0], m[0]);
            }
        }
        // Frames with every marker lost (infinite steps) leave the floor where it was.
        let h = f.hysteresis();
        for _ in 0..8 {
            let lost = vec![[f32::NAN, f32::NAN]; 12];
            assert!(f.update(&lost).iter().all(|p| p[0].is_nan()));
            assert_eq!(f.hysteresis(), h);
        }
        // Reset starts over: the next frame is reported as given.
        f.reset();
        assert_eq!(f.hysteresis(), 0.0);
        let m = vec![[1.0, 2.0]; 12];
        assert_eq!(f.update(&m), &m[..]);
    }

    #[test]
    fn repeated_frames_do_not_switch_the_filter_off() {
        // A noisy stream whose first frames repeat (a stale start read as rest, or a camera
        // repeating frames): the repeats must not set the jitter floor to zero.
        let pitch = 20.0;
        let noise = noisy(40, 40, 0.02, 11);
        let mut f = StillFilter::new(pitch);
        for _ in 0..6 {
            f.update(&vec![[0.0, 0.0]; 40]);
        }
        for nm in &noise {
            f.update(nm);
        }
        let h = f.hysteresis();
        assert!(h > 0.0, "floor set to zero by repeated frames");
        // A freeze in the middle of the stream leaves the threshold where it was.
        for _ in 0..8 {
            f.update(&noise[39]);
        }
        assert_eq!(f.hysteresis(), h);
    }
}
