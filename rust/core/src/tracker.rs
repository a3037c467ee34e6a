//! Frame-to-frame marker tracking against a fixed reference.
//!
//! Matching each frame directly to the reference fails once markers move more than half a pitch
//! (real presses reach a whole pitch). The tracker instead matches each frame to where every marker
//! is *predicted* to be: its last tracked position, or — for a marker lost earlier — its reference
//! position moved by the median motion of its tracked neighbours. Predicted positions are matched
//! mutually with a gate of half the pitch, in two rounds: markers seen last frame first, then the
//! re-predicted lost ones against the detections left over.

use crate::error::{CoreError, Result};
use crate::geometry::{check_finite, estimate_pitch, median};
use crate::kdtree::KdTree;
use crate::matching::{match_with_gate, DEFAULT_GATE_FRACTION};

/// Neighbours used to predict a lost marker's motion.
const NEIGHBOURS: usize = 6;

/// A marker tracker holding the reference grid and the last tracked positions.
#[derive(Debug, Clone)]
pub struct Tracker {
    reference: Vec<[f32; 2]>,
    last: Vec<[f32; 2]>,
    seen: Vec<bool>,
    /// [`NEIGHBOURS`] slots per marker, `u32::MAX` where unused.
    neighbours: Vec<u32>,
    gate: f32,
    frame: u64,
}

/// Output of one [`Tracker::update`].
#[derive(Debug, Clone, PartialEq)]
pub struct TrackState {
    /// `(dx, dy)` from the reference, NaN for markers not found in this frame.
    pub motion: Vec<[f32; 2]>,
    /// Whether each reference marker was found in this frame.
    pub valid: Vec<bool>,
    /// Frames processed so far, this one included.
    pub frame: u64,
}

impl Tracker {
    /// A tracker for `reference` markers. `max_dist`: per-frame gate (pixels); default half the
    /// reference pitch.
    pub fn new(reference: Vec<[f32; 2]>, max_dist: Option<f32>) -> Result<Self> {
        check_finite(&reference, "ref")?;
        let gate = match max_dist {
            Some(d) if d.is_nan() || d <= 0.0 => {
                return Err(CoreError::invalid(
                    "max_dist",
                    format!("must be a positive number of pixels; got {d}"),
                ))
            }
            Some(d) => d,
            None => estimate_pitch(&reference)
                .map(|p| DEFAULT_GATE_FRACTION * p)
                .unwrap_or(f32::INFINITY),
        };
        let neighbours = nearest_neighbours(&reference, NEIGHBOURS);
        let n = reference.len();
        Ok(Self {
            last: reference.clone(),
            reference,
            seen: vec![true; n],
            neighbours,
            gate,
            frame: 0,
        })
    }

    /// Reference marker positions.
    pub fn reference(&self) -> &[[f32; 2]] {
        &self.reference
    }

    /// Per-frame gate, pixels.
    pub fn gate(&self) -> f32 {
        self.gate
    }

    /// Frames processed.
    pub fn frame(&self) -> u64 {
        self.frame
    }

    /// Last tracked positions (for lost markers, the last position where they were seen).
    pub fn positions(&self) -> &[[f32; 2]] {
        &self.last
    }

    /// Forgets the motion history: every marker is expected back at its reference position.
    pub fn reset(&mut self) {
        self.last.clone_from(&self.reference);
        self.seen.fill(true);
        self.frame = 0;
    }

    /// Tracks the markers detected in a new frame.
    pub fn update(&mut self, detections: &[[f32; 2]]) -> Result<TrackState> {
        check_finite(detections, "detections")?;
        let n = self.reference.len();
        let mut found = vec![false; n];
        let mut pos = vec![[f32::NAN; 2]; n];
        let mut used = vec![false; detections.len()];

        // Round 1: markers seen in the previous frame, predicted where they were.
        let round1: Vec<usize> = (0..n).filter(|&i| self.seen[i]).collect();
        let predicted: Vec<[f32; 2]> = round1.iter().map(|&i| self.last[i]).collect();
        self.match_round(
            &round1, &predicted, detections, &mut found, &mut pos, &mut used,
        );

        // Round 2: the rest, predicted from the motion of their neighbours found this frame.
        let round2: Vec<usize> = (0..n).filter(|&i| !found[i]).collect();
        if !round2.is_empty() && used.iter().any(|&u| !u) {
            let predicted: Vec<[f32; 2]> = round2
                .iter()
                .map(|&i| self.predict_from_neighbours(i, &found, &pos))
                .collect();
            self.match_round(
                &round2, &predicted, detections, &mut found, &mut pos, &mut used,
            );
        }

        let mut motion = vec![[f32::NAN; 2]; n];
        for i in 0..n {
            if found[i] {
                self.last[i] = pos[i];
                motion[i] = [
                    pos[i][0] - self.reference[i][0],
                    pos[i][1] - self.reference[i][1],
                ];
            }
        }
        self.seen.copy_from_slice(&found);
        self.frame += 1;
        Ok(TrackState {
            motion,
            valid: found,
            frame: self.frame,
        })
    }

    fn match_round(
        &self,
        which: &[usize],
        predicted: &[[f32; 2]],
        detections: &[[f32; 2]],
        found: &mut [bool],
        pos: &mut [[f32; 2]],
        used: &mut [bool],
    ) {
        if which.is_empty() {
            return;
        }
        let free: Vec<usize> = (0..detections.len()).filter(|&j| !used[j]).collect();
        let free_pts: Vec<[f32; 2]> = free.iter().map(|&j| detections[j]).collect();
        let m = match_with_gate(predicted, &free_pts, self.gate);
        for (k, &i) in which.iter().enumerate() {
            if m.valid[k] {
                let j = free[m.index[k] as usize];
                found[i] = true;
                pos[i] = detections[j];
                used[j] = true;
            }
        }
    }

    fn predict_from_neighbours(&self, i: usize, found: &[bool], pos: &[[f32; 2]]) -> [f32; 2] {
        let slots = &self.neighbours[i * NEIGHBOURS..(i + 1) * NEIGHBOURS];
        let (mut dx, mut dy): (Vec<f32>, Vec<f32>) = slots
            .iter()
            .filter(|&&k| k != u32::MAX)
            .map(|&k| k as usize)
            .filter(|&k| found[k])
            .map(|k| {
                (
                    pos[k][0] - self.reference[k][0],
                    pos[k][1] - self.reference[k][1],
                )
            })
            .unzip();
        match (median(&mut dx), median(&mut dy)) {
            (Some(mx), Some(my)) => [self.reference[i][0] + mx, self.reference[i][1] + my],
            _ => self.last[i],
        }
    }
}

/// The `k` nearest other points of every point, `k` slots per point (unused slots hold
/// `u32::MAX`). One 2-d tree query each: `O(N log N)` time, `O(N k)` memory.
fn nearest_neighbours(points: &[[f32; 2]], k: usize) -> Vec<u32> {
    let tree = KdTree::over_all(points);
    let mut out = vec![u32::MAX; points.len() * k];
    for (i, (&p, slots)) in points
        .iter()
        .zip(out.chunks_exact_mut(k.max(1)))
        .enumerate()
    {
        for (s, j) in slots.iter_mut().zip(tree.k_nearest(p, k, i as u32)) {
            *s = j;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(nx: usize, ny: usize, pitch: f32) -> Vec<[f32; 2]> {
        (0..ny)
            .flat_map(|j| (0..nx).map(move |i| [20.0 + i as f32 * pitch, 20.0 + j as f32 * pitch]))
            .collect()
    }

    #[test]
    fn follows_a_shift_of_more_than_one_pitch() {
        let r = grid(8, 6, 30.0);
        let mut t = Tracker::new(r.clone(), None).unwrap();
        let mut last = None;
        for step in 1..=20 {
            let s = step as f32 * 2.0; // up to 40 px, more than a pitch
            let cur: Vec<_> = r.iter().map(|p| [p[0] + s, p[1] + 0.5 * s]).collect();
            last = Some(t.update(&cur).unwrap());
        }
        let st = last.unwrap();
        assert!(st.valid.iter().all(|&v| v));
        assert!(st.motion.iter().all(|m| (m[0] - 40.0).abs() < 1e-4));
    }

    #[test]
    fn reacquires_a_lost_marker_after_motion() {
        let r = grid(6, 6, 30.0);
        let mut t = Tracker::new(r.clone(), None).unwrap();
        let shifted = |s: f32| -> Vec<[f32; 2]> { r.iter().map(|p| [p[0] + s, p[1]]).collect() };
        t.update(&shifted(2.0)).unwrap();
        // Marker 14 disappears for several frames while everything moves 20 px.
        for step in 2..=10 {
            let mut cur = shifted(step as f32 * 2.0);
            cur.remove(14);
            let st = t.update(&cur).unwrap();
            assert!(!st.valid[14] && st.motion[14][0].is_nan());
        }
        let st = t.update(&shifted(22.0)).unwrap();
        assert!(st.valid[14]);
        assert!((st.motion[14][0] - 22.0).abs() < 1e-4);
    }

    #[test]
    fn all_lost_then_back() {
        let r = grid(4, 4, 25.0);
        let mut t = Tracker::new(r.clone(), None).unwrap();
        let st = t.update(&[]).unwrap();
        assert!(st.valid.iter().all(|&v| !v));
        let st = t.update(&r).unwrap();
        assert!(st.valid.iter().all(|&v| v));
    }

    #[test]
    fn neighbours_are_the_nearest_and_memory_is_linear() {
        let r = grid(7, 5, 10.0);
        let nb = nearest_neighbours(&r, NEIGHBOURS);
        assert_eq!(nb.len(), r.len() * NEIGHBOURS);
        // Marker 8 (x=1, y=1): its 4 axis neighbours at 10 px come first.
        let mut first4: Vec<u32> = nb[8 * NEIGHBOURS..8 * NEIGHBOURS + 4].to_vec();
        first4.sort_unstable();
        assert_eq!(first4, vec![1, 7, 9, 15]);
        let two = nearest_neighbours(&r[..2], NEIGHBOURS);
        assert_eq!(&two[..2], &[1, u32::MAX]);
    }

    #[test]
    fn a_large_grid_builds_and_tracks_quickly() {
        let r = grid(320, 320, 10.0); // 102 400 markers
        let t0 = std::time::Instant::now();
        let mut t = Tracker::new(r.clone(), None).unwrap();
        let cur: Vec<_> = r.iter().map(|p| [p[0] + 1.0, p[1]]).collect();
        let st = t.update(&cur).unwrap();
        assert!(st.valid.iter().all(|&v| v));
        assert!(t0.elapsed().as_secs_f64() < 30.0);
    }
}
