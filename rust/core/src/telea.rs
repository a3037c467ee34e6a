//! Telea (2004) fast-marching inpainting, a drop-in for `cv2.inpaint(img, mask, r, INPAINT_TELEA)`.
//!
//! Same scheme as OpenCV's `modules/photo/src/inpaint.cpp`: a fast-marching front moves from the
//! hole boundary inwards; each pixel, when the front first reaches it, becomes the weighted mean of
//! the known pixels within `radius`, with Telea's weight `direction * level-set * geometric`:
//! `|r . grad T| * 1 / (1 + |T(q) - T(p)|) * 1 / |r|^3` (`r = p - q`; the `|r|^3` is OpenCV's
//! `1/|r|^2` distance term times its unnormalised direction term). `T` outside the hole is the
//! negated arrival time of a second front marched outwards up to `radius` (Chebyshev) pixels.
//!
//! Differences from OpenCV, all deliberate:
//! - no `+0.5` before the final cast and no normalised gradient term (OpenCV adds
//!   `(Jx + Jy) / |J|`, up to +-1.4 grey levels of noise): a flat image stays exactly flat;
//!   float input is not biased;
//! - the weighted mean is taken relative to the first contributing pixel, so identical
//!   neighbours reproduce their value bit for bit in every type;
//! - pixels outside the image are simply absent: holes touching any border (OpenCV skips the
//!   top/left rows and columns) are filled;
//! - holes are 8-connected components; holes closer than `2 * radius + 2` pixels (Chebyshev) are
//!   grouped, and each group is solved in its own window, in parallel. Groups farther apart cannot
//!   see each other's pixels or fronts, and fronts pop in a fixed `(T, y, x)` order, so the result
//!   is bit-identical to one solve over the whole image ([`inpaint_telea_global`]). OpenCV lets a
//!   hole borrow the already-filled pixels of a nearby hole; here a hole only sees known pixels
//!   and its own group.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use rayon::prelude::*;

use crate::error::{CoreError, Result};
use crate::image::ImageView;
use crate::simd::multiversion;

/// Largest accepted `radius` (OpenCV clamps to the same bound).
pub const MAX_RADIUS: usize = 100;
/// Most interleaved channels an image may have.
pub const MAX_CHANNELS: usize = 4;
/// Arrival time of pixels no front has reached (OpenCV's value, so weights agree).
const FAR_T: f32 = 1.0e6;
/// Direction terms at most this large count as perpendicular to the front ...
const MIN_DIRECTION: f32 = 0.01;
/// ... and get this small positive weight instead of zero, so every neighbour counts a little.
const DIRECTION_FLOOR: f32 = 1.0e-6;

/// Pixel flags in a solve window.
const KNOWN: u8 = 0; // known pixel (given or filled) behind the front
const BAND: u8 = 1; // known pixel on the front
const INSIDE: u8 = 2; // to fill, not reached yet
const VOID: u8 = 3; // outside the image: never read
const NEAR: u8 = 4; // known pixel within `radius` of the hole that the outward front has not reached

/// A sample type TELEA can work on: values are processed as `f32` and converted back.
pub trait Sample: Copy + Send + Sync + 'static {
    /// Whether the type can hold NaN or infinities (then known pixels are checked).
    const FLOAT: bool = false;
    /// The value as `f32` (exact for `u8` and `u16`).
    fn to_f32(self) -> f32;
    /// The nearest representable value (integers round half up and saturate).
    fn from_f32(v: f32) -> Self;
    /// False for NaN and infinities.
    fn is_finite(self) -> bool {
        true
    }
}

impl Sample for u8 {
    fn to_f32(self) -> f32 {
        f32::from(self)
    }
    fn from_f32(v: f32) -> Self {
        // Round half up of a non-negative value; `as` truncates (and maps NaN to 0).
        (v.clamp(0.0, f32::from(u8::MAX)) + 0.5) as u8
    }
}

impl Sample for u16 {
    fn to_f32(self) -> f32 {
        f32::from(self)
    }
    fn from_f32(v: f32) -> Self {
        (v.clamp(0.0, f32::from(u16::MAX)) + 0.5) as u16
    }
}

impl Sample for f32 {
    const FLOAT: bool = true;
    fn to_f32(self) -> f32 {
        self
    }
    fn from_f32(v: f32) -> Self {
        v
    }
    fn is_finite(self) -> bool {
        f32::is_finite(self)
    }
}

/// Inclusive pixel box `x0..=x1`, `y0..=y1`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct BBox {
    x0: usize,
    y0: usize,
    x1: usize,
    y1: usize,
}

impl BBox {
    fn union(self, o: BBox) -> BBox {
        BBox {
            x0: self.x0.min(o.x0),
            y0: self.y0.min(o.y0),
            x1: self.x1.max(o.x1),
            y1: self.y1.max(o.y1),
        }
    }

    /// Chebyshev distance between the boxes (1 for boxes that touch, 0 for overlapping ones).
    fn gap(self, o: BBox) -> usize {
        let dx =
            o.x0.saturating_sub(self.x1)
                .max(self.x0.saturating_sub(o.x1));
        let dy =
            o.y0.saturating_sub(self.y1)
                .max(self.y0.saturating_sub(o.y1));
        dx.max(dy)
    }
}

/// Fills the nonzero pixels of `mask` in `img` by Telea's method; returns the whole image.
///
/// `mask` is `H x W`, row-major, nonzero = fill. Unmasked pixels are copied unchanged. Masked
/// pixels of a float image may hold anything (NaN included); unmasked ones must be finite.
///
/// Errors: `radius` outside `1..=100`; `img` with more than 4 channels or a non-finite known
/// value; `mask` of the wrong length or covering every pixel.
pub fn inpaint_telea<T: Sample>(
    img: &ImageView<'_, T>,
    mask: &[u8],
    radius: usize,
) -> Result<Vec<T>> {
    inpaint_impl(img, mask, radius, true)
}

/// Reference path: the same inpainting as [`inpaint_telea`], as one sequential solve over the
/// whole image. Slower; exists to show that the per-group parallel solve changes nothing.
pub fn inpaint_telea_global<T: Sample>(
    img: &ImageView<'_, T>,
    mask: &[u8],
    radius: usize,
) -> Result<Vec<T>> {
    inpaint_impl(img, mask, radius, false)
}

fn inpaint_impl<T: Sample>(
    img: &ImageView<'_, T>,
    mask: &[u8],
    radius: usize,
    per_group: bool,
) -> Result<Vec<T>> {
    let (h, w, c) = (img.height(), img.width(), img.channels());
    if !(1..=MAX_RADIUS).contains(&radius) {
        return Err(CoreError::invalid(
            "radius",
            format!("must be between 1 and {MAX_RADIUS} pixels; got {radius}"),
        ));
    }
    if c > MAX_CHANNELS {
        return Err(CoreError::invalid(
            "img",
            format!("must have at most {MAX_CHANNELS} channels; got {c}"),
        ));
    }
    if mask.len() != h * w {
        return Err(CoreError::invalid(
            "mask",
            format!(
                "must have the image's {h}x{w} pixels; got {} values",
                mask.len()
            ),
        ));
    }
    let data = img.data();
    let n_pixels = h * w;
    // The runs also count the masked pixels (no separate pass over the mask).
    let runs = mask_runs(mask, h, w);
    let n_masked: usize = runs.iter().map(|r| r.x1 + 1 - r.x0).sum();
    if n_masked == 0 {
        return Ok(data.to_vec());
    }
    if n_masked == n_pixels {
        return Err(CoreError::invalid(
            "mask",
            "covers every pixel: nothing is known to inpaint from",
        ));
    }
    // Heap keys hold a window index in 32 bits; the largest window is the padded image.
    let margin = radius + 2;
    if (h + 2 * margin).saturating_mul(w + 2 * margin) > u32::MAX as usize {
        return Err(CoreError::invalid(
            "img",
            format!("must have fewer than 2^32 pixels; got {h}x{w}"),
        ));
    }
    let bad = |i: &usize| mask[*i] == 0 && data[i * c..(i + 1) * c].iter().any(|v| !v.is_finite());
    let first_bad = if T::FLOAT {
        (0..n_pixels).find(bad)
    } else {
        None
    };
    if let Some(i) = first_bad {
        return Err(CoreError::invalid(
            "img",
            format!(
                "unmasked pixel (x={}, y={}) is NaN or infinite; mask it or clean it first",
                i % w,
                i / w
            ),
        ));
    }

    let (comp_of, boxes) = label_runs(&runs);
    let (group_of, groups) = if per_group {
        group_holes(&boxes, 2 * radius + 1)
    } else {
        let all = boxes.iter().copied().reduce(BBox::union);
        (vec![0; boxes.len()], all.into_iter().collect())
    };
    let mut group_runs: Vec<Vec<Run>> = vec![Vec::new(); groups.len()];
    for (run, &comp) in runs.iter().zip(&comp_of) {
        group_runs[group_of[comp as usize] as usize].push(*run);
    }
    let ctx = Ctx { img, radius };
    let filled: Vec<Vec<(usize, [f32; MAX_CHANNELS])>> = if per_group {
        groups
            .par_iter()
            .zip(&group_runs)
            .map(|(&bbox, runs)| ctx.solve(bbox, runs))
            .collect()
    } else {
        groups
            .iter()
            .zip(&group_runs)
            .map(|(&bbox, runs)| ctx.solve(bbox, runs))
            .collect()
    };
    let mut out = data.to_vec();
    for (idx, v) in filled.iter().flatten() {
        for (o, &x) in out[idx * c..(idx + 1) * c].iter_mut().zip(v) {
            *o = T::from_f32(x);
        }
    }
    Ok(out)
}

/// A horizontal run `x0..=x1` of masked pixels on row `y`.
#[derive(Debug, Clone, Copy)]
struct Run {
    y: usize,
    x0: usize,
    x1: usize,
}

/// Runs of the mask, row by row; zero words of eight pixels are skipped at once.
fn mask_runs(mask: &[u8], h: usize, w: usize) -> Vec<Run> {
    const WORD: usize = 8;
    let mut runs = Vec::new();
    for y in 0..h {
        let row = &mask[y * w..(y + 1) * w];
        let mut x = 0;
        while x < w {
            let word = row
                .get(x..x + WORD)
                .and_then(|b| <[u8; WORD]>::try_from(b).ok());
            if word.is_some_and(|b| u64::from_ne_bytes(b) == 0) {
                x += WORD;
                continue;
            }
            if row[x] == 0 {
                x += 1;
                continue;
            }
            let x0 = x;
            while x < w && row[x] != 0 {
                x += 1;
            }
            runs.push(Run { y, x0, x1: x - 1 });
        }
    }
    runs
}

fn find(parent: &mut [usize], mut i: usize) -> usize {
    while parent[i] != i {
        parent[i] = parent[parent[i]];
        i = parent[i];
    }
    i
}

fn unite(parent: &mut [usize], a: usize, b: usize) {
    let (a, b) = (find(parent, a), find(parent, b));
    parent[a.max(b)] = a.min(b);
}

/// 8-connected components of the runs: each run's component and each component's box.
fn label_runs(runs: &[Run]) -> (Vec<u32>, Vec<BBox>) {
    let mut parent: Vec<usize> = (0..runs.len()).collect();
    // Runs of consecutive rows touch (8-connectivity) when their spans, grown by one, overlap.
    let mut prev = 0..0;
    let mut start = 0;
    while start < runs.len() {
        let y = runs[start].y;
        let mut end = start;
        while end < runs.len() && runs[end].y == y {
            end += 1;
        }
        if prev.end > prev.start && runs[prev.start].y + 1 == y {
            let mut j = prev.start;
            for i in start..end {
                while j < prev.end && runs[j].x1 + 1 < runs[i].x0 {
                    j += 1;
                }
                let mut k = j;
                while k < prev.end && runs[k].x0 <= runs[i].x1 + 1 {
                    unite(&mut parent, i, k);
                    k += 1;
                }
            }
        }
        prev = start..end;
        start = end;
    }
    let mut comp_of = vec![0u32; runs.len()];
    let mut root_comp = vec![u32::MAX; runs.len()];
    let mut boxes: Vec<BBox> = Vec::new();
    for (i, run) in runs.iter().enumerate() {
        let root = find(&mut parent, i);
        let rb = BBox {
            x0: run.x0,
            y0: run.y,
            x1: run.x1,
            y1: run.y,
        };
        if root_comp[root] == u32::MAX {
            root_comp[root] = boxes.len() as u32;
            boxes.push(rb);
        }
        let c = root_comp[root];
        comp_of[i] = c;
        boxes[c as usize] = boxes[c as usize].union(rb);
    }
    (comp_of, boxes)
}

/// Unites holes whose boxes are at most `reach` apart; returns each hole's group and group boxes.
fn group_holes(boxes: &[BBox], reach: usize) -> (Vec<u32>, Vec<BBox>) {
    let n = boxes.len();
    let mut parent: Vec<usize> = (0..n).collect();
    // Sweep by top edge: a hole can only be within reach of holes starting at most `reach` below
    // its bottom edge.
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by_key(|&i| boxes[i].y0);
    for (k, &i) in order.iter().enumerate() {
        for &j in &order[k + 1..] {
            if boxes[j].y0 > boxes[i].y1 + reach {
                break;
            }
            if boxes[i].gap(boxes[j]) <= reach {
                unite(&mut parent, i, j);
            }
        }
    }
    let mut group_of = vec![u32::MAX; n];
    let mut root_group = vec![u32::MAX; n];
    let mut groups: Vec<BBox> = Vec::new();
    for i in 0..n {
        let r = find(&mut parent, i);
        if root_group[r] == u32::MAX {
            root_group[r] = groups.len() as u32;
            groups.push(boxes[i]);
        }
        let g = root_group[r];
        group_of[i] = g;
        groups[g as usize] = groups[g as usize].union(boxes[i]);
    }
    (group_of, groups)
}

/// The disk of radius `r` as flat lists: window offset of each pixel, `r = p - q` and the
/// geometric weight `1 / |r|^3`. Padded to a multiple of [`DISK_CHUNK`] with entries of weight 0
/// pointing at the centre (never usable while it is being filled), so the weight loop runs on
/// whole vectors.
struct Disk {
    lin: Vec<isize>,
    rx: Vec<f32>,
    ry: Vec<f32>,
    geometric: Vec<f32>,
    /// The unpadded entries as chunks of [`DISK_CHUNK`] entries contiguous in the window (the
    /// last of each row running past it): `(window offset, first entry)`, in entry order.
    chunks: Vec<(isize, usize)>,
}

/// Vector width the disk is padded to.
const DISK_CHUNK: usize = 8;

/// Per-fill scratch: the disk's usable flags, arrival times and weights.
struct Scratch {
    usable: Vec<f32>,
    t: Vec<f32>,
    w: Vec<f32>,
}

/// Heap key: arrival time in the high half (non-negative, so its bits order like the value), the
/// window index in the low half. Window raster order is image raster order, so ties pop in the
/// same order whatever the window: a group's solve does not depend on where its window lies.
type Key = Reverse<u64>;

fn key(t: f32, wi: usize) -> Key {
    Reverse((u64::from(t.to_bits()) << 32) | wi as u64)
}

fn key_index(k: u64) -> usize {
    (k & u64::from(u32::MAX)) as usize
}

struct Ctx<'a, 'b, T> {
    img: &'a ImageView<'b, T>,
    radius: usize,
}

impl<T: Sample> Ctx<'_, '_, T> {
    fn solve(&self, bbox: BBox, runs: &[Run]) -> Vec<(usize, [f32; MAX_CHANNELS])> {
        match self.img.channels() {
            1 => self.solve_c::<1>(bbox, runs),
            2 => self.solve_c::<2>(bbox, runs),
            3 => self.solve_c::<3>(bbox, runs),
            _ => self.solve_c::<4>(bbox, runs),
        }
    }

    /// Solves the holes made of `runs` in their box grown by `radius + 2`: `radius` for the disk
    /// and the outward front, one more for the front's neighbours, one more so that every read of
    /// a processed pixel's 4-neighbours stays inside the window. Masked pixels of other groups
    /// inside the window stay "known": they lie farther than any read reaches.
    /// Returns `(image index, value)` per filled pixel.
    fn solve_c<const C: usize>(
        &self,
        bbox: BBox,
        runs: &[Run],
    ) -> Vec<(usize, [f32; MAX_CHANNELS])> {
        let (ih, iw) = (self.img.height(), self.img.width());
        let r = self.radius;
        let margin = r + 2;
        let (ox, oy) = (
            bbox.x0 as isize - margin as isize,
            bbox.y0 as isize - margin as isize,
        );
        let ww = bbox.x1 - bbox.x0 + 1 + 2 * margin;
        let wh = bbox.y1 - bbox.y0 + 1 + 2 * margin;
        let n = ww * wh;
        let data = self.img.data();

        let mut flag = vec![VOID; n];
        // Unknown and void pixels hold 0 so that a zero weight times their value is exactly 0.
        // Values padded to four lanes so that one fill step is one 4-wide multiply-add.
        let mut val = vec![[0.0f32; MAX_CHANNELS]; n];
        // 1.0 where the value is usable (known or filled), else 0.0: a branch-free weight factor.
        let mut usable = vec![0.0f32; n];
        let x_lo = (-ox).max(0) as usize;
        let x_hi = ((iw as isize - ox).max(0) as usize).min(ww);
        for wy in 0..wh {
            let y = oy + wy as isize;
            if y < 0 || y >= ih as isize || x_lo >= x_hi {
                continue;
            }
            let start = y as usize * iw + (ox + x_lo as isize) as usize;
            let src = &data[start * C..(start + x_hi - x_lo) * C];
            let row = wy * ww;
            flag[row + x_lo..row + x_hi].fill(KNOWN);
            usable[row + x_lo..row + x_hi].fill(1.0);
            for (d, s) in val[row + x_lo..row + x_hi]
                .iter_mut()
                .zip(src.chunks_exact(C))
            {
                for (dc, sc) in d.iter_mut().zip(s) {
                    *dc = sc.to_f32();
                }
            }
        }
        let mut targets = Vec::new();
        for run in runs {
            let wy = (run.y as isize - oy) as usize;
            for x in run.x0..=run.x1 {
                let wi = wy * ww + (x as isize - ox) as usize;
                flag[wi] = INSIDE;
                usable[wi] = 0.0;
                val[wi] = [0.0; MAX_CHANNELS];
                targets.push((run.y * iw + x, wi));
            }
        }
        let neighbours = |wi: usize| [wi - ww, wi - 1, wi + ww, wi + 1];

        // The front starts on known pixels 4-adjacent to the hole, at T = 0.
        let mut t = vec![FAR_T; n];
        let mut band = Vec::new();
        for &(_, wi) in &targets {
            for nb in neighbours(wi) {
                if flag[nb] == KNOWN {
                    flag[nb] = BAND;
                    t[nb] = 0.0;
                    band.push(nb);
                }
            }
        }

        // Outward front over the known pixels within `r` (Chebyshev) of the hole; its arrival
        // times, negated, order the known pixels for the level-set weight.
        let near = dilate_rect(&flag, ww, wh, r);
        for (f, &nr) in flag.iter_mut().zip(&near) {
            if *f == KNOWN && nr {
                *f = NEAR;
            }
        }
        let mut heap: BinaryHeap<Key> = band.iter().map(|&wi| key(0.0, wi)).collect();
        let mut reached = Vec::new();
        while let Some(Reverse(k)) = heap.pop() {
            for nb in neighbours(key_index(k)) {
                if flag[nb] == NEAR {
                    let d = arrival(&t, nb, ww);
                    t[nb] = d;
                    flag[nb] = KNOWN;
                    reached.push(nb);
                    heap.push(key(d, nb));
                }
            }
        }
        for &wi in &reached {
            t[wi] = -t[wi];
        }
        for f in flag.iter_mut() {
            if *f == NEAR {
                *f = KNOWN;
            }
        }

        // Inward front: each pixel is filled when first reached.
        let disk = disk_offsets(r, ww);
        let n_disk = disk.lin.len();
        // Slack of one chunk for the chunked gather (the weights cover the padded disk only).
        let mut scratch = Scratch {
            usable: vec![0.0; n_disk + DISK_CHUNK],
            t: vec![0.0; n_disk + DISK_CHUNK],
            w: vec![0.0; n_disk],
        };
        heap.extend(band.iter().map(|&wi| key(0.0, wi)));
        march_inward(
            &mut heap,
            &mut flag,
            &mut t,
            &mut usable,
            &mut val,
            &disk,
            ww,
            &mut scratch,
        );

        targets
            .iter()
            .map(|&(i, wi)| {
                let mut v = [0.0f32; MAX_CHANNELS];
                v[..C].copy_from_slice(&val[wi][..C]);
                (i, v)
            })
            .collect()
    }
}

multiversion! {
    /// Inward front: pops the front in `(T, index)` order and fills each `INSIDE` 4-neighbour
    /// when first reached, which then joins the front.
    #[allow(clippy::too_many_arguments)]
    fn march_inward(
        heap: &mut BinaryHeap<Key>,
        flag: &mut [u8],
        t: &mut [f32],
        usable: &mut [f32],
        val: &mut [[f32; MAX_CHANNELS]],
        disk: &Disk,
        ww: usize,
        scratch: &mut Scratch,
    ) {
        while let Some(Reverse(k)) = heap.pop() {
            let wi = key_index(k);
            flag[wi] = KNOWN;
            for nb in [wi - ww, wi - 1, wi + ww, wi + 1] {
                if flag[nb] != INSIDE {
                    continue;
                }
                let tp = arrival(t, nb, ww);
                t[nb] = tp;
                val[nb] = fill(nb, wi, tp, disk, flag, usable, t, val, ww, scratch);
                flag[nb] = BAND;
                usable[nb] = 1.0;
                heap.push(key(tp, nb));
            }
        }
    }
}

/// Telea's weighted mean at window pixel `p` (arrival time `tp`) over the known disk pixels,
/// taken relative to `src`, the known pixel whose front reached `p`: equal neighbours give
/// exactly their value. Weights are `direction * level-set * geometric`, the direction term
/// floored so that no neighbour drops out; unusable pixels get weight 0 and hold finite values,
/// so they add exactly 0.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn fill(
    p: usize,
    src: usize,
    tp: f32,
    disk: &Disk,
    flag: &[u8],
    usable: &[f32],
    t: &[f32],
    val: &[[f32; MAX_CHANNELS]],
    ww: usize,
    scratch: &mut Scratch,
) -> [f32; MAX_CHANNELS] {
    let (gx, gy) = grad_t(flag, t, p, ww);
    // Gather by contiguous runs, then compute the weights in straight vectorisable passes.
    // In bounds: p lies `radius + 2` inside the window and the disk reaches `radius`. Padding
    // entries of the scratch stay 0 (unusable), as for the centre they stand for.
    // Whole chunks of [`DISK_CHUNK`] values are copied (a fixed-size copy is a vector move, a
    // short variable one a call): the tail of a chunk past its run is overwritten by the next
    // run, or lands in padding entries, whose weight is 0 whatever they hold (finite values
    // of the window), or in the scratch's slack.
    for &(off, start) in &disk.chunks {
        let q = (p as isize + off) as usize;
        let (s, d) = (q..q + DISK_CHUNK, start..start + DISK_CHUNK);
        scratch.usable[d.clone()].copy_from_slice(&usable[s.clone()]);
        scratch.t[d].copy_from_slice(&t[s]);
    }
    let terms = disk.rx.iter().zip(&disk.ry).zip(&disk.geometric);
    let known = scratch.usable.iter().zip(&scratch.t);
    for (w, ((&u, &tq), ((&rx, &ry), &g))) in scratch.w.iter_mut().zip(known.zip(terms)) {
        let level = 1.0 / (1.0 + (tq - tp).abs());
        let dir = rx * gx + ry * gy;
        let dir = if dir.abs() <= MIN_DIRECTION {
            DIRECTION_FLOOR
        } else {
            dir
        };
        *w = u * (g * level * dir).abs();
    }
    // Two independent sums (even and odd entries) so that consecutive additions do not wait on
    // each other; held side by side in 8 lanes, so one wide multiply-add serves both.
    let reference = val[src];
    let mut acc = [0.0f32; 2 * MAX_CHANNELS];
    let (mut sum0, mut sum1) = (0.0f32, 0.0f32);
    let mut refs = [0.0f32; 2 * MAX_CHANNELS];
    refs[..MAX_CHANNELS].copy_from_slice(&reference);
    refs[MAX_CHANNELS..].copy_from_slice(&reference);
    for (offs, ws) in disk.lin.chunks_exact(2).zip(scratch.w.chunks_exact(2)) {
        let mut v = [0.0f32; 2 * MAX_CHANNELS];
        v[..MAX_CHANNELS].copy_from_slice(&val[(p as isize + offs[0]) as usize]);
        v[MAX_CHANNELS..].copy_from_slice(&val[(p as isize + offs[1]) as usize]);
        let mut wv = [ws[0]; 2 * MAX_CHANNELS];
        wv[MAX_CHANNELS..].fill(ws[1]);
        for l in 0..2 * MAX_CHANNELS {
            acc[l] += wv[l] * (v[l] - refs[l]);
        }
        sum0 += ws[0];
        sum1 += ws[1];
    }
    // The sum is > 0: `src` is a known 4-neighbour of p, inside the disk since radius >= 1.
    let sum_w = sum0 + sum1;
    let mut out = reference;
    for ch in 0..MAX_CHANNELS {
        out[ch] += (acc[ch] + acc[MAX_CHANNELS + ch]) / sum_w;
    }
    out
}

/// The disk of radius `r` without its centre, for a window `ww` pixels wide.
fn disk_offsets(r: usize, ww: usize) -> Disk {
    let r = r as isize;
    let mut disk = Disk {
        lin: Vec::new(),
        rx: Vec::new(),
        ry: Vec::new(),
        geometric: Vec::new(),
        chunks: Vec::new(),
    };
    // Runs of entries contiguous in the window: (offset of the first, first entry, length).
    let mut runs: Vec<(isize, usize, usize)> = Vec::new();
    for dy in -r..=r {
        for dx in -r..=r {
            let d2 = dx * dx + dy * dy;
            if d2 == 0 || d2 > r * r {
                continue;
            }
            let len2 = d2 as f64;
            let off = dy * ww as isize + dx;
            match runs.last_mut() {
                Some((first, _, len)) if *first + *len as isize == off => *len += 1,
                _ => runs.push((off, disk.lin.len(), 1)),
            }
            disk.lin.push(off);
            disk.rx.push(-dx as f32);
            disk.ry.push(-dy as f32);
            disk.geometric.push((1.0 / (len2 * len2.sqrt())) as f32);
        }
    }
    for (off, start, len) in runs {
        for c in (0..len).step_by(DISK_CHUNK) {
            disk.chunks.push((off + c as isize, start + c));
        }
    }
    while disk.lin.len() % DISK_CHUNK != 0 {
        disk.lin.push(0);
        disk.rx.push(0.0);
        disk.ry.push(0.0);
        disk.geometric.push(0.0);
    }
    disk
}

/// Gradient of `T` at `p` from its known 4-neighbours (central, one-sided, or 0).
#[inline(always)]
fn grad_t(flag: &[u8], t: &[f32], p: usize, ww: usize) -> (f32, f32) {
    let axis = |lo: usize, hi: usize| -> f32 {
        match (flag[lo] <= BAND, flag[hi] <= BAND) {
            (true, true) => (t[hi] - t[lo]) * 0.5,
            (false, true) => t[hi] - t[p],
            (true, false) => t[p] - t[lo],
            (false, false) => 0.0,
        }
    };
    (axis(p - 1, p + 1), axis(p - ww, p + ww))
}

/// First-order upwind arrival time at `p` from its 4-neighbours (unreached ones hold `FAR_T`).
/// OpenCV takes the least of the four (vertical, horizontal) pairings; [`solve_pair`] is
/// nondecreasing in both arguments, so that least is the pairing of the two smaller neighbours.
#[inline(always)]
fn arrival(t: &[f32], p: usize, ww: usize) -> f32 {
    solve_pair(t[p - ww].min(t[p + ww]), t[p - 1].min(t[p + 1]))
}

/// Solution of `|grad T| = 1` from one vertical and one horizontal neighbour (in `f32`: OpenCV
/// uses `f64` here, which changes arrival times by about 1e-7 relative and costs latency).
#[inline(always)]
fn solve_pair(a: f32, b: f32) -> f32 {
    let d = a - b;
    if d.abs() >= 1.0 {
        1.0 + a.min(b)
    } else {
        (a + b + (2.0 - d * d).sqrt()) * 0.5
    }
}

/// Pixels within Chebyshev distance `r` of an `INSIDE` pixel: a horizontal pass by prefix
/// counts, then a vertical pass by running column counts (contiguous rows, so it vectorises).
fn dilate_rect(flag: &[u8], ww: usize, wh: usize, r: usize) -> Vec<bool> {
    let mut rows = vec![0u8; ww * wh];
    let mut prefix = vec![0u32; ww + 1];
    for (frow, drow) in flag.chunks_exact(ww).zip(rows.chunks_exact_mut(ww)) {
        for (x, &f) in frow.iter().enumerate() {
            prefix[x + 1] = prefix[x] + u32::from(f == INSIDE);
        }
        for (x, d) in drow.iter_mut().enumerate() {
            let (lo, hi) = (x.saturating_sub(r), (x + r + 1).min(ww));
            *d = u8::from(prefix[hi] > prefix[lo]);
        }
    }
    // Vertical pass as a running count per column of the marked rows within `r`: each row
    // enters and leaves the window once.
    let mut out = vec![false; ww * wh];
    let mut count = vec![0u16; ww];
    for src in rows.chunks_exact(ww).take(r.min(wh)) {
        for (a, &s) in count.iter_mut().zip(src) {
            *a += u16::from(s);
        }
    }
    for (y, orow) in out.chunks_exact_mut(ww).enumerate() {
        if let Some(src) = rows.chunks_exact(ww).nth(y + r) {
            for (a, &s) in count.iter_mut().zip(src) {
                *a += u16::from(s);
            }
        }
        if let Some(src) = y
            .checked_sub(r + 1)
            .and_then(|k| rows.chunks_exact(ww).nth(k))
        {
            for (a, &s) in count.iter_mut().zip(src) {
                *a -= u16::from(s);
            }
        }
        for (o, &a) in orow.iter_mut().zip(&count) {
            *o = a != 0;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn view<T: Copy>(data: &[T], h: usize, w: usize, c: usize) -> ImageView<'_, T> {
        ImageView::new(data, h, w, c, "img").unwrap()
    }

    fn disc_mask(h: usize, w: usize, centres: &[(f32, f32)], radius: f32) -> Vec<u8> {
        let mut m = vec![0u8; h * w];
        for y in 0..h {
            for x in 0..w {
                for &(cx, cy) in centres {
                    let (dx, dy) = (x as f32 - cx, y as f32 - cy);
                    if dx * dx + dy * dy <= radius * radius {
                        m[y * w + x] = 1;
                    }
                }
            }
        }
        m
    }

    /// Smooth shading plus a fine texture, with garbage under the mask.
    fn textured(h: usize, w: usize, c: usize, mask: &[u8]) -> Vec<f32> {
        let mut img = vec![0.0f32; h * w * c];
        for y in 0..h {
            for x in 0..w {
                for ch in 0..c {
                    let v = 100.0
                        + 40.0 * ((x as f32) / 37.0).sin() * ((y as f32) / 23.0).cos()
                        + 10.0 * ((x + 2 * y + 5 * ch) as f32 * 0.9).sin();
                    img[(y * w + x) * c + ch] = if mask[y * w + x] != 0 { 3.0 } else { v };
                }
            }
        }
        img
    }

    #[test]
    fn flat_images_stay_exactly_flat() {
        let (h, w) = (40, 50);
        let mask = disc_mask(
            h,
            w,
            &[(0.0, 0.0), (25.0, 20.0), (49.0, 39.0), (10.0, 30.0)],
            5.0,
        );
        for c in [1, 3, 4] {
            let mut img = vec![100u8; h * w * c];
            let mut img16 = vec![40_000u16; h * w * c];
            let mut imgf = vec![0.123_456_7f32; h * w * c];
            for i in 0..h * w {
                if mask[i] != 0 {
                    img[i * c..(i + 1) * c].fill(0);
                    img16[i * c..(i + 1) * c].fill(7);
                    imgf[i * c..(i + 1) * c].fill(f32::NAN);
                }
            }
            for r in [1, 3, 5, 12] {
                let out = inpaint_telea(&view(&img, h, w, c), &mask, r).unwrap();
                assert!(out.iter().all(|&v| v == 100), "u8 c={c} r={r}");
                let out = inpaint_telea(&view(&img16, h, w, c), &mask, r).unwrap();
                assert!(out.iter().all(|&v| v == 40_000), "u16 c={c} r={r}");
                let out = inpaint_telea(&view(&imgf, h, w, c), &mask, r).unwrap();
                assert!(out.iter().all(|&v| v == 0.123_456_7), "f32 c={c} r={r}");
            }
        }
    }

    #[test]
    fn linear_ramp_error_is_bounded() {
        let (h, w) = (60, 80);
        let mask = disc_mask(h, w, &[(30.0, 30.0), (0.0, 59.0), (79.0, 10.0)], 6.0);
        let truth: Vec<f32> = (0..h * w)
            .map(|i| 20.0 + 0.5 * (i % w) as f32 + 0.25 * (i / w) as f32)
            .collect();
        let out = inpaint_telea(&view(&truth, h, w, 1), &mask, 3).unwrap();
        for i in 0..h * w {
            // A zero-order fill of a slope-0.56 ramp errs by at most the slope times the hole radius.
            assert!(
                (out[i] - truth[i]).abs() <= 0.56 * 6.0,
                "pixel {i}: {} vs {}",
                out[i],
                truth[i]
            );
            if mask[i] == 0 {
                assert_eq!(out[i], truth[i]);
            }
        }
    }

    #[test]
    fn border_holes_are_filled() {
        let (h, w) = (30, 30);
        let mut mask = vec![0u8; h * w];
        mask[..w].fill(1); // whole top row
        for y in 0..h {
            mask[y * w] = 1; // whole left column
        }
        mask[(h - 1) * w + w - 1] = 1;
        let img: Vec<u8> = (0..h * w)
            .map(|i| if mask[i] != 0 { 0 } else { 50 + (i % 7) as u8 })
            .collect();
        let out = inpaint_telea(&view(&img, h, w, 1), &mask, 3).unwrap();
        for i in 0..h * w {
            if mask[i] != 0 {
                assert!((50..=56).contains(&out[i]), "pixel {i} = {}", out[i]);
            } else {
                assert_eq!(out[i], img[i]);
            }
        }
    }

    #[test]
    fn per_group_parallel_equals_global_solve() {
        let (h, w, c) = (90, 120, 3);
        // Holes at several spacings: isolated, grouped (closer than 2r + 2), touching the borders.
        let centres = [
            (10.0, 10.0),
            (30.0, 12.0),
            (38.0, 14.0),
            (60.0, 45.0),
            (67.0, 52.0),
            (119.0, 0.0),
            (0.0, 89.0),
            (100.0, 70.0),
        ];
        let mask = disc_mask(h, w, &centres, 4.0);
        let img = textured(h, w, c, &mask);
        let img8: Vec<u8> = img.iter().map(|&v| v as u8).collect();
        for r in [1, 3, 5, 9] {
            let a = inpaint_telea(&view(&img, h, w, c), &mask, r).unwrap();
            let b = inpaint_telea_global(&view(&img, h, w, c), &mask, r).unwrap();
            assert!(
                a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()),
                "f32 r={r}"
            );
            let a = inpaint_telea(&view(&img8, h, w, c), &mask, r).unwrap();
            let b = inpaint_telea_global(&view(&img8, h, w, c), &mask, r).unwrap();
            assert_eq!(a, b, "u8 r={r}");
        }
    }

    #[test]
    fn fills_textured_holes_plausibly() {
        let (h, w) = (64, 64);
        let mask = disc_mask(h, w, &[(32.0, 32.0)], 4.0);
        let img = textured(h, w, 1, &mask);
        let truth = textured(h, w, 1, &vec![0; h * w]);
        let out = inpaint_telea(&view(&img, h, w, 1), &mask, 3).unwrap();
        let (mut err, mut n) = (0.0, 0);
        for i in 0..h * w {
            if mask[i] != 0 {
                err += (out[i] - truth[i]).abs();
                n += 1;
            }
        }
        assert!(err / n as f32 <= 12.0, "mean error {}", err / n as f32);
    }

    #[test]
    fn empty_mask_returns_a_copy() {
        let img: Vec<u16> = (0..12).collect();
        let out = inpaint_telea(&view(&img, 3, 4, 1), &[0; 12], 3).unwrap();
        assert_eq!(out, img);
    }

    #[test]
    fn errors_name_the_argument() {
        let img = vec![1.0f32; 12];
        let v = view(&img, 3, 4, 1);
        let name = |e: CoreError| match e {
            CoreError::InvalidArgument { name, .. } => name,
            CoreError::Unsolvable(_) => "",
        };
        assert_eq!(name(inpaint_telea(&v, &[1; 12], 3).unwrap_err()), "mask");
        assert_eq!(name(inpaint_telea(&v, &[1; 11], 3).unwrap_err()), "mask");
        assert_eq!(name(inpaint_telea(&v, &[0; 12], 0).unwrap_err()), "radius");
        assert_eq!(
            name(inpaint_telea(&v, &[0; 12], 101).unwrap_err()),
            "radius"
        );
        let mut bad = img.clone();
        bad[5] = f32::INFINITY;
        let mut mask = vec![0u8; 12];
        mask[0] = 1;
        assert_eq!(
            name(inpaint_telea(&view(&bad, 3, 4, 1), &mask, 3).unwrap_err()),
            "img"
        );
        // A NaN under the mask is fine: it gets replaced.
        mask[5] = 1;
        let out = inpaint_telea(&view(&bad, 3, 4, 1), &mask, 3).unwrap();
        assert!(out.iter().all(|v| *v == 1.0));
        let five = vec![0u8; 60];
        assert_eq!(
            name(inpaint_telea(&view(&five, 3, 4, 5), &mask, 3).unwrap_err()),
            "img"
        );
    }

    #[test]
    fn single_pixel_known_fills_everything() {
        let (h, w) = (5, 7);
        let mut mask = vec![1u8; h * w];
        mask[17] = 0;
        let img = vec![42u8; h * w];
        let out = inpaint_telea(&view(&img, h, w, 1), &mask, 1).unwrap();
        assert!(out.iter().all(|&v| v == 42));
    }
}

#[cfg(test)]
mod profile {
    use super::*;
    use std::time::Instant;

    /// `cargo test --release -p tacswitch-core profile_telea -- --ignored --nocapture`; under
    /// `perf record` (with `CARGO_PROFILE_RELEASE_DEBUG=line-tables-only`) it showed `fill` at
    /// ~48 % (a third of it the scalar disk gather), the rest of the solve ~34 %, `dilate_rect` ~7 %.
    #[test]
    #[ignore]
    fn profile_telea() {
        let (h, w) = (480usize, 640usize);
        let mut img = vec![0u8; h * w * 3];
        for (i, v) in img.iter_mut().enumerate() {
            let (y, x) = ((i / 3) / w, (i / 3) % w);
            *v =
                (120.0 + 40.0 * ((x as f32) * 0.05).sin() + 30.0 * ((y as f32) * 0.07).cos()) as u8;
        }
        let mut mask = vec![0u8; h * w];
        for j in 0..6 {
            for i in 0..8 {
                let (cx, cy) = (40 + 80 * i, 40 + 80 * j);
                for y in cy - 13..=cy + 13 {
                    for x in cx - 13..=cx + 13 {
                        if (x - cx) * (x - cx) + (y - cy) * (y - cy) <= 169 {
                            mask[y * w + x] = 1;
                        }
                    }
                }
            }
        }
        let view = ImageView::new(&img, h, w, 3, "img").unwrap();
        // `TELEA_PROFILE=global` profiles the one-window reference solve; by default the
        // per-group solve the library runs (pin `RAYON_NUM_THREADS=1` for one thread).
        let global = std::env::var("TELEA_PROFILE").is_ok_and(|v| v == "global");
        for r in [3usize, 5] {
            let mut times: Vec<f64> = (0..60)
                .map(|_| {
                    let t = Instant::now();
                    let out = if global {
                        inpaint_telea_global(&view, &mask, r)
                    } else {
                        inpaint_telea(&view, &mask, r)
                    };
                    std::hint::black_box(out.unwrap());
                    t.elapsed().as_secs_f64() * 1e3
                })
                .collect();
            times.sort_by(f64::total_cmp);
            println!("r={r}: median {:.3} ms, min {:.3} ms", times[30], times[0]);
        }
    }
}
