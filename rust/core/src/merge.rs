//! Tiling an image into overlapping square patches and merging them back.
//!
//! Size: ~620 lines of code and ~140 of tests, one concern (the layout and the two merge modes
//! share the patch geometry).
//!
//! The paper runs its diffusion model on 256 x 256 patches over a 640 x 480 image with about
//! 30 px of overlap, the last row and column of patches snapped to the image edge (6 patches), and
//! averages the overlapping pixels. [`tile`] reproduces that layout; [`merge_patches`] averages
//! (`Average`, the paper) or blends with raised-cosine ramps across the overlaps (`Feather`), which
//! removes the seams that patches disagreeing by a small offset leave with a plain average.
//!
//! Both modes compute `v1 + sum_k w_k (v_k - v1) / sum_k w_k`, relative to the first covering
//! patch, so unmodified patches merge back to the image bit for bit.

use std::mem::MaybeUninit;

use rayon::prelude::*;

use crate::error::{CoreError, Result};
use crate::image::ImageView;
use crate::telea::Sample;

/// How overlapping patch pixels are combined.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MergeMode {
    /// Plain mean of the covering patches (the paper).
    Average,
    /// Weighted mean with weights rising as a raised cosine over the overlap from each patch edge.
    Feather,
}

/// Start offsets of patches along one axis: stride `patch - overlap`, the last start snapped so
/// that the last patch ends on the image edge; `[0]` when the axis fits in one patch.
pub fn axis_starts(len: usize, patch: usize, overlap: usize) -> Vec<usize> {
    if len <= patch {
        return vec![0];
    }
    let stride = patch - overlap;
    let n = (len - patch).div_ceil(stride) + 1;
    let mut starts: Vec<usize> = (0..n - 1).map(|i| i * stride).collect();
    starts.push(len - patch);
    starts
}

fn check_tiling(patch: usize, overlap: usize) -> Result<()> {
    if patch == 0 {
        return Err(CoreError::invalid("patch", "must be at least 1 pixel"));
    }
    if overlap >= patch {
        return Err(CoreError::invalid(
            "overlap",
            format!("must be smaller than patch ({patch}); got {overlap}"),
        ));
    }
    Ok(())
}

/// Patch origins `(x, y)` for an image, row by row (y outer, x inner).
pub fn tile_origins(
    height: usize,
    width: usize,
    patch: usize,
    overlap: usize,
) -> Result<Vec<[usize; 2]>> {
    check_tiling(patch, overlap)?;
    let xs = axis_starts(width, patch, overlap);
    let ys = axis_starts(height, patch, overlap);
    Ok(ys
        .iter()
        .flat_map(|&y| xs.iter().map(move |&x| [x, y]))
        .collect())
}

/// Mirror index of `i` into `0..len` without repeating the edge pixel (`cv2.BORDER_REFLECT_101`).
fn reflect_101(i: usize, len: usize) -> usize {
    if len == 1 {
        return 0;
    }
    let period = 2 * (len - 1);
    let m = i % period;
    if m < len {
        m
    } else {
        period - m
    }
}

/// Most bytes [`tile`] will allocate for its patches (2 GiB): beyond this a patch/overlap choice
/// is a mistake (e.g. `overlap = patch - 1`, one patch per pixel), not a workload.
pub const MAX_TILE_BYTES: usize = 1 << 31;

/// Checks that tiling an `h x w x c` image of `elem`-byte samples stays within
/// [`MAX_TILE_BYTES`]; the error names `patch` when one patch alone is too large, else `overlap`.
pub fn check_tile_size(
    h: usize,
    w: usize,
    c: usize,
    elem: usize,
    patch: usize,
    overlap: usize,
) -> Result<usize> {
    check_tiling(patch, overlap)?;
    let per = patch
        .checked_mul(patch)
        .and_then(|v| v.checked_mul(c))
        .and_then(|v| v.checked_mul(elem))
        .filter(|&v| v <= MAX_TILE_BYTES)
        .ok_or_else(|| {
            CoreError::invalid(
                "patch",
                format!(
                    "a {patch} x {patch} patch of a {h} x {w} x {c} image exceeds the {} GiB \
                     limit of tile()",
                    MAX_TILE_BYTES >> 30
                ),
            )
        })?;
    // Patches per axis, as `axis_starts` lays them out (without building the lists).
    let along = |len: usize| {
        if len <= patch {
            1
        } else {
            (len - patch).div_ceil(patch - overlap) + 1
        }
    };
    let count = along(w).saturating_mul(along(h));
    match count.checked_mul(per).filter(|&v| v <= MAX_TILE_BYTES) {
        Some(total) => Ok(total),
        None => Err(CoreError::invalid(
            if overlap > 0 { "overlap" } else { "patch" },
            format!(
                "{count} patches of {patch} x {patch} (overlap {overlap}) would need {:.1} GB, \
                 over the {} GiB limit of tile(); use a smaller overlap or a larger patch",
                count as f64 * per as f64 / 1e9,
                MAX_TILE_BYTES >> 30
            ),
        )),
    }
}

/// Cuts `img` into `patch x patch` patches; returns them (`N x patch x patch x C`, C-order) and
/// their origins `(x, y)`. An image side shorter than `patch` is padded by reflection
/// (`BORDER_REFLECT_101`); [`merge_patches`] crops the padding away again.
pub fn tile<T: Copy>(
    img: &ImageView<'_, T>,
    patch: usize,
    overlap: usize,
) -> Result<(Vec<T>, Vec<[usize; 2]>)> {
    let (h, w, c) = (img.height(), img.width(), img.channels());
    check_tile_size(h, w, c, std::mem::size_of::<T>(), patch, overlap)?;
    let origins = tile_origins(h, w, patch, overlap)?;
    let per = patch * patch * c;
    // Built by appending (no zero-fill pass): tiling is a copy, bound by memory traffic.
    let mut out = Vec::with_capacity(per * origins.len());
    for &[ox, oy] in &origins {
        for py in 0..patch {
            let src = img.row(reflect_101(oy + py, h));
            if ox + patch <= w {
                out.extend_from_slice(&src[ox * c..(ox + patch) * c]);
            } else {
                for px in 0..patch {
                    let sx = reflect_101(ox + px, w);
                    out.extend_from_slice(&src[sx * c..(sx + 1) * c]);
                }
            }
        }
    }
    Ok((out, origins))
}

/// Raised-cosine weights of one patch side: rising over `ramp` pixels from each edge, 1 between.
/// Strictly positive, so a pixel covered by one patch keeps that patch's value.
fn feather_weights(patch: usize, ramp: usize) -> Vec<f32> {
    let rise = |t: usize| -> f64 {
        if t >= ramp {
            1.0
        } else {
            0.5 - 0.5 * (std::f64::consts::PI * (t as f64 + 0.5) / ramp as f64).cos()
        }
    };
    (0..patch)
        .map(|t| rise(t).min(rise(patch - 1 - t)) as f32)
        .collect()
}

/// The smallest overlap between consecutive distinct starts along one axis (0 when none).
fn min_overlap(starts: &mut Vec<usize>, patch: usize) -> usize {
    starts.sort_unstable();
    starts.dedup();
    starts
        .windows(2)
        .filter_map(|s| patch.checked_sub(s[1] - s[0]).filter(|&o| o > 0))
        .min()
        .unwrap_or(0)
}

/// Merges `N x patch x patch x C` patches placed at `origins` `(x, y)` into a `height x width x C`
/// image. Patch pixels outside the image are ignored; every image pixel must be covered.
#[allow(clippy::too_many_arguments)]
pub fn merge_patches<T: Sample>(
    patches: &[T],
    n: usize,
    patch: usize,
    channels: usize,
    origins: &[[usize; 2]],
    height: usize,
    width: usize,
    mode: MergeMode,
) -> Result<Vec<T>> {
    if patch == 0 || channels == 0 {
        return Err(CoreError::invalid(
            "patches",
            "patches must be at least 1 x 1 x 1",
        ));
    }
    if height == 0 || width == 0 {
        return Err(CoreError::invalid(
            "shape",
            format!("must be at least 1 x 1; got {height} x {width}"),
        ));
    }
    let per = patch * patch * channels;
    if patches.len() != n * per {
        return Err(CoreError::invalid(
            "patches",
            format!(
                "buffer holds {} values but {n} x {patch} x {patch} x {channels} needs {}",
                patches.len(),
                n * per
            ),
        ));
    }
    if origins.len() != n {
        return Err(CoreError::invalid(
            "origins",
            format!(
                "must have one (x, y) per patch ({n}); got {}",
                origins.len()
            ),
        ));
    }
    if let Some((i, o)) = origins
        .iter()
        .enumerate()
        .find(|(_, o)| o[0] >= width || o[1] >= height)
    {
        return Err(CoreError::invalid(
            "origins",
            format!(
                "patch {i} starts at ({}, {}), outside the {width} x {height} image",
                o[0], o[1]
            ),
        ));
    }
    let (wx, wy) = match mode {
        MergeMode::Average => (vec![1.0f32; patch], vec![1.0f32; patch]),
        MergeMode::Feather => {
            let ramp = |mut s: Vec<usize>| min_overlap(&mut s, patch).min(patch / 2);
            let rx = ramp(origins.iter().map(|o| o[0]).collect());
            let ry = ramp(origins.iter().map(|o| o[1]).collect());
            (feather_weights(patch, rx), feather_weights(patch, ry))
        }
    };
    // Patches sorted by x so that "the first covering patch" is well defined.
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by_key(|&i| (origins[i][0], origins[i][1]));
    let bands = plan(origins, &order, patch, height, width)?;
    // Column weights repeated per channel, so a segment's weights are one contiguous slice.
    let wxc: Vec<f32> = wx
        .iter()
        .flat_map(|&v| std::iter::repeat(v).take(channels))
        .collect();

    let row_len = width * channels;
    let len = height * row_len;
    let geom = Geometry {
        patches,
        origins,
        patch,
        channels,
        wxc: &wxc,
        wy: &wy,
        mode,
    };
    // Every value is written exactly once below, so the output is not zero-filled first (that
    // pass alone costs about a third of the merge of 6 patches).
    let mut out: Vec<T> = Vec::with_capacity(len);
    let rows = &mut out.spare_capacity_mut()[..len];
    rows.par_chunks_mut(row_len)
        .enumerate()
        .with_min_len(MIN_ROWS_PER_TASK)
        .for_each_init(
            || Scratch {
                acc: vec![0.0; row_len],
                wsum: vec![0.0; row_len],
            },
            |scratch, (y, out_row)| {
                // `plan` returns bands covering rows 0..height in order.
                let band = bands.partition_point(|b| b.y1 <= y);
                if let Some(band) = bands.get(band) {
                    geom.merge_row(band, y, out_row, scratch);
                }
            },
        );
    // SAFETY: `len <= capacity`, and every one of the `len` values has been initialised: the
    // bands of `plan` partition the rows `0..height`, each band's segments partition the columns
    // `0..width`, and `merge_row` writes every value of every segment of its row.
    unsafe { out.set_len(len) };
    Ok(out)
}

/// Rows at least this many per rayon task: a row is a few microseconds of work.
const MIN_ROWS_PER_TASK: usize = 8;

/// Columns `x0..x1` of a band covered by the same patches, listed in merge order.
struct Segment {
    x0: usize,
    x1: usize,
    cover: Vec<usize>,
}

/// Rows `y0..y1` over which the covering patches do not change, cut into segments.
struct Band {
    y0: usize,
    y1: usize,
    segments: Vec<Segment>,
}

/// The merge plan: the image cut at every patch edge into bands of rows and, within each band,
/// segments of columns, each with its covering patches in `order`. Errors when a pixel is
/// covered by no patch (naming the first such pixel in raster order).
fn plan(
    origins: &[[usize; 2]],
    order: &[usize],
    patch: usize,
    height: usize,
    width: usize,
) -> Result<Vec<Band>> {
    let edges = |axis: usize, len: usize| -> Vec<usize> {
        let mut e: Vec<usize> = vec![0, len];
        for o in origins {
            e.push(o[axis]);
            e.push((o[axis] + patch).min(len));
        }
        e.sort_unstable();
        e.dedup();
        e
    };
    let covers =
        |k: usize, axis: usize, v: usize| (origins[k][axis]..origins[k][axis] + patch).contains(&v);
    let mut bands = Vec::new();
    for ys in edges(1, height).windows(2) {
        let (y0, y1) = (ys[0], ys[1]);
        let rows: Vec<usize> = order
            .iter()
            .copied()
            .filter(|&k| covers(k, 1, y0))
            .collect();
        let mut xe: Vec<usize> = vec![0, width];
        for &k in &rows {
            xe.push(origins[k][0]);
            xe.push((origins[k][0] + patch).min(width));
        }
        xe.sort_unstable();
        xe.dedup();
        let mut segments = Vec::with_capacity(xe.len() - 1);
        for xs in xe.windows(2) {
            let (x0, x1) = (xs[0], xs[1]);
            let cover: Vec<usize> = rows.iter().copied().filter(|&k| covers(k, 0, x0)).collect();
            if cover.is_empty() {
                return Err(CoreError::invalid(
                    "origins",
                    format!("image pixel (x={x0}, y={y0}) is covered by no patch"),
                ));
            }
            segments.push(Segment { x0, x1, cover });
        }
        bands.push(Band { y0, y1, segments });
    }
    Ok(bands)
}

/// Per-task buffers for segments covered by more than [`MAX_FUSED`] patches.
struct Scratch {
    acc: Vec<f64>,
    wsum: Vec<f64>,
}

/// Segments covered by at most this many patches are blended in one fused pass with the
/// patch count a compile-time constant; more take a buffered path.
const MAX_FUSED: usize = 4;

/// Everything a row of the merge needs.
struct Geometry<'a, T> {
    patches: &'a [T],
    origins: &'a [[usize; 2]],
    patch: usize,
    channels: usize,
    /// Column weights, each repeated `channels` times.
    wxc: &'a [f32],
    wy: &'a [f32],
    mode: MergeMode,
}

impl<T: Sample> Geometry<'_, T> {
    /// Values of patch `k` on image row `y` for image columns `a..b` (all channels).
    fn span(&self, k: usize, y: usize, a: usize, b: usize) -> &[T] {
        let [ox, oy] = self.origins[k];
        let (p, c) = (self.patch, self.channels);
        let start = k * p * p * c + ((y - oy) * p + (a - ox)) * c;
        &self.patches[start..start + (b - a) * c]
    }

    /// Column weights of patch `k` for image columns `a..b`, per value.
    fn col_weights(&self, k: usize, a: usize, b: usize) -> &[f32] {
        let (ox, c) = (self.origins[k][0], self.channels);
        &self.wxc[(a - ox) * c..(b - ox) * c]
    }

    /// Merges image row `y` of `band`, writing every value of `out_row`.
    fn merge_row(
        &self,
        band: &Band,
        y: usize,
        out_row: &mut [MaybeUninit<T>],
        scratch: &mut Scratch,
    ) {
        debug_assert!((band.y0..band.y1).contains(&y));
        let c = self.channels;
        for seg in &band.segments {
            let (a, b) = (seg.x0, seg.x1);
            let out = &mut out_row[a * c..b * c];
            let span = |i: usize| self.span(seg.cover[i], y, a, b);
            let weights = |i: usize| {
                let k = seg.cover[i];
                (self.col_weights(k, a, b), self.wy[y - self.origins[k][1]])
            };
            match (self.mode, seg.cover.len()) {
                (_, 1) => {
                    for (o, &v) in out.iter_mut().zip(span(0)) {
                        o.write(v);
                    }
                }
                (MergeMode::Average, 2) => average(out, span(0), [span(1)]),
                (MergeMode::Average, 3) => average(out, span(0), [span(1), span(2)]),
                (MergeMode::Average, 4) => average(out, span(0), [span(1), span(2), span(3)]),
                (MergeMode::Feather, 2) => {
                    feather(out, [span(0), span(1)], [weights(0), weights(1)])
                }
                (MergeMode::Feather, 3) => feather(
                    out,
                    [span(0), span(1), span(2)],
                    [weights(0), weights(1), weights(2)],
                ),
                (MergeMode::Feather, 4) => feather(
                    out,
                    [span(0), span(1), span(2), span(3)],
                    [weights(0), weights(1), weights(2), weights(3)],
                ),
                (mode, count) => {
                    debug_assert!(count > MAX_FUSED);
                    let n = out.len();
                    let (acc, wsum) = (&mut scratch.acc[..n], &mut scratch.wsum[..n]);
                    acc.fill(0.0);
                    wsum.fill(0.0);
                    let v1 = span(0);
                    for i in 0..count {
                        let vals = span(i);
                        let (wxs, row_w) = match mode {
                            MergeMode::Average if i == 0 => continue,
                            MergeMode::Average => (None, 1.0),
                            MergeMode::Feather => {
                                let (wxs, row_w) = weights(i);
                                (Some(wxs), row_w)
                            }
                        };
                        for (e, ((s, ws), (&v, &r))) in acc
                            .iter_mut()
                            .zip(wsum.iter_mut())
                            .zip(vals.iter().zip(v1))
                            .enumerate()
                        {
                            let d = wide(v) - wide(r);
                            match wxs {
                                None => *s += d,
                                Some(wxs) => {
                                    let wgt = f64::from(row_w * wxs[e]);
                                    *ws += wgt;
                                    *s += wgt * d;
                                }
                            }
                        }
                    }
                    let count = count as f64;
                    for (((o, &s), &ws), &r) in out.iter_mut().zip(&*acc).zip(&*wsum).zip(v1) {
                        let div = if mode == MergeMode::Average {
                            count
                        } else {
                            ws
                        };
                        o.write(narrow64(r, wide(r), s / div));
                    }
                }
            }
            if T::FLOAT && (2..=MAX_FUSED).contains(&seg.cover.len()) {
                self.redo_overflow(seg, y, out);
            }
        }
    }

    /// Recomputes in `f64` the values of a fused segment that came out non-finite: the `f32`
    /// differences of samples near `+-3.4e38` overflow although their weighted mean is finite.
    /// A pass over the segment just written (in cache); taken only for float samples.
    #[cold]
    #[inline(never)]
    fn redo_overflow_at(&self, seg: &Segment, y: usize, e: usize) -> T {
        let (a, b) = (seg.x0, seg.x1);
        let r = self.span(seg.cover[0], y, a, b)[e];
        let rv = wide(r);
        let (mut s, mut ws) = (0.0f64, 0.0f64);
        for &k in &seg.cover {
            let wgt = match self.mode {
                MergeMode::Average => 1.0,
                MergeMode::Feather => {
                    f64::from(self.wy[y - self.origins[k][1]] * self.col_weights(k, a, b)[e])
                }
            };
            ws += wgt;
            s += wgt * (wide(self.span(k, y, a, b)[e]) - rv);
        }
        narrow64(r, rv, s / ws)
    }

    fn redo_overflow(&self, seg: &Segment, y: usize, out: &mut [MaybeUninit<T>]) {
        for (e, o) in out.iter_mut().enumerate() {
            // SAFETY: every value of the segment was written by the fused kernel just before.
            let v = unsafe { o.assume_init_ref() };
            if !v.is_finite() {
                o.write(self.redo_overflow_at(seg, y, e));
            }
        }
    }
}

/// `r + sum_k (v_k - r) / (K + 1)` per value, in one pass (`r` the first covering patch).
/// A power-of-two count divides by multiplying with its reciprocal, which is exact.
/// In `f32` (fast); a value that overflows is redone in `f64` by [`Geometry::redo_overflow`].
#[inline(always)]
fn average<T: Sample, const K: usize>(out: &mut [MaybeUninit<T>], r: &[T], rest: [&[T]; K]) {
    let n = out.len();
    let r = &r[..n];
    let rest = rest.map(|v| &v[..n]);
    let count = (K + 1) as f32;
    if (K + 1).is_power_of_two() {
        let inv = 1.0 / count;
        for (e, o) in out.iter_mut().enumerate() {
            let rv = r[e].to_f32();
            let mut s = 0.0f32;
            for v in &rest {
                s += v[e].to_f32() - rv;
            }
            o.write(narrow(r[e], rv, s * inv));
        }
    } else {
        for (e, o) in out.iter_mut().enumerate() {
            let rv = r[e].to_f32();
            let mut s = 0.0f32;
            for v in &rest {
                s += v[e].to_f32() - rv;
            }
            o.write(narrow(r[e], rv, s / count));
        }
    }
}

/// `rv + delta` as a sample; a zero `delta` returns `r` itself, bit for bit (so `-0.0` stays
/// `-0.0`: `-0.0 + 0.0` would be `+0.0`).
#[inline(always)]
fn narrow<T: Sample>(r: T, rv: f32, delta: f32) -> T {
    if delta == 0.0 {
        r
    } else {
        T::from_f32(rv + delta)
    }
}

/// [`narrow`] from `f64`.
#[inline(always)]
fn narrow64<T: Sample>(r: T, rv: f64, delta: f64) -> T {
    if delta == 0.0 {
        r
    } else {
        T::from_f32((rv + delta) as f32)
    }
}

/// A sample widened to `f64` (exact for every sample type).
#[inline(always)]
fn wide<T: Sample>(v: T) -> f64 {
    f64::from(v.to_f32())
}

/// `r + sum_k w_k (v_k - r) / sum_k w_k` per value, in one pass; `w_k` is the patch's row
/// weight times its column weight, `r = v_0`. In `f32`; overflow as in [`average`].
#[inline(always)]
fn feather<T: Sample, const K: usize>(
    out: &mut [MaybeUninit<T>],
    vals: [&[T]; K],
    weights: [(&[f32], f32); K],
) {
    let n = out.len();
    let vals = vals.map(|v| &v[..n]);
    let cols = weights.map(|(w, _)| &w[..n]);
    let rows = weights.map(|(_, w)| w);
    for (e, o) in out.iter_mut().enumerate() {
        let rv = vals[0][e].to_f32();
        let (mut s, mut ws) = (0.0f32, 0.0f32);
        for k in 0..K {
            let wgt = rows[k] * cols[k][e];
            ws += wgt;
            s += wgt * (vals[k][e].to_f32() - rv);
        }
        o.write(narrow(vals[0][e], rv, s / ws));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp_image(h: usize, w: usize, c: usize) -> Vec<f32> {
        (0..h * w * c)
            .map(|i| {
                let (p, ch) = (i / c, i % c);
                0.1 * (p % w) as f32 + 0.37 * (p / w) as f32 + 7.0 * ch as f32 + 0.001_234
            })
            .collect()
    }

    #[test]
    fn paper_layout_has_six_patches() {
        let o = tile_origins(480, 640, 256, 30).unwrap();
        assert_eq!(o.len(), 6);
        assert_eq!(axis_starts(640, 256, 30), vec![0, 226, 384]);
        assert_eq!(axis_starts(480, 256, 30), vec![0, 224]);
    }

    #[test]
    fn average_merge_of_unmodified_patches_is_exact() {
        for (h, w, c, p, ov) in [
            (480, 640, 3, 256, 30),
            (100, 70, 1, 32, 9),
            (20, 10, 4, 32, 4),
            (1, 1, 2, 3, 1),
        ] {
            let img = ramp_image(h, w, c);
            let v = ImageView::new(&img, h, w, c, "img").unwrap();
            let (patches, origins) = tile(&v, p, ov).unwrap();
            for mode in [MergeMode::Average, MergeMode::Feather] {
                let out =
                    merge_patches(&patches, origins.len(), p, c, &origins, h, w, mode).unwrap();
                assert!(
                    out.iter()
                        .zip(&img)
                        .all(|(a, b)| a.to_bits() == b.to_bits()),
                    "{h}x{w} {mode:?}"
                );
            }
        }
    }

    #[test]
    fn small_images_are_reflect_padded() {
        let img: Vec<u8> = (0..12).collect();
        let v = ImageView::new(&img, 3, 4, 1, "img").unwrap();
        let (patches, origins) = tile(&v, 6, 2).unwrap();
        assert_eq!(origins, vec![[0, 0]]);
        // First patch row: 0 1 2 3 | 2 1 (reflect-101).
        assert_eq!(&patches[..6], &[0, 1, 2, 3, 2, 1]);
        // Row 3 mirrors row 1.
        assert_eq!(&patches[18..22], &[4, 5, 6, 7]);
    }

    #[test]
    fn feather_removes_the_seam_of_offset_patches() {
        let (h, w) = (480, 640);
        let img = ramp_image(h, w, 1);
        let v = ImageView::new(&img, h, w, 1, "img").unwrap();
        let (mut patches, origins) = tile(&v, 256, 30).unwrap();
        for (k, p) in patches.chunks_exact_mut(256 * 256).enumerate() {
            p.iter_mut().for_each(|x| *x += k as f32); // each patch biased differently
        }
        let max_second_diff = |out: &[f32]| {
            let mut m = 0.0f32;
            for y in 0..h {
                for x in 1..w - 1 {
                    let i = y * w + x;
                    m = m.max((out[i - 1] - 2.0 * out[i] + out[i + 1]).abs());
                }
            }
            m
        };
        let avg = merge_patches(&patches, 6, 256, 1, &origins, h, w, MergeMode::Average).unwrap();
        let fea = merge_patches(&patches, 6, 256, 1, &origins, h, w, MergeMode::Feather).unwrap();
        assert!(max_second_diff(&avg) >= 0.4);
        assert!(max_second_diff(&fea) < 0.02, "{}", max_second_diff(&fea));
    }

    #[test]
    fn tile_refuses_layouts_beyond_the_memory_limit() {
        let img = vec![0u8; 640 * 480 * 3];
        let view = ImageView::new(&img, 480, 640, 3, "img").unwrap();
        // One patch per pixel column: 86 625 patches, 17 GB.
        let err = tile(&view, 256, 255).unwrap_err().to_string();
        assert!(err.starts_with("overlap:"), "{err}");
        for patch in [100_000usize, 1 << 20, 1 << 31, usize::MAX] {
            let err = tile(&view, patch, 0).unwrap_err().to_string();
            assert!(err.starts_with("patch:"), "{err}");
        }
        let one = [0u8; 1];
        let view = ImageView::new(&one, 1, 1, 1, "img").unwrap();
        assert!(tile(&view, 1 << 20, 0)
            .unwrap_err()
            .to_string()
            .starts_with("patch:"));
        assert_eq!(tile(&view, 256, 30).unwrap().0.len(), 256 * 256);
    }

    #[test]
    fn merge_keeps_negative_zero_and_huge_floats() {
        let img = vec![-0.0f32, 3e38, -3e38, 1.0, -0.0, 2.5];
        let view = ImageView::new(&img, 1, 6, 1, "img").unwrap();
        let (p, o) = tile(&view, 4, 2).unwrap();
        for mode in [MergeMode::Average, MergeMode::Feather] {
            let out = merge_patches(&p, o.len(), 4, 1, &o, 1, 6, mode).unwrap();
            let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&out), bits(&img), "{mode:?}");
        }
        // Two patches of +-3e38 over one pixel: the mean is 0, not -inf.
        let p = vec![3e38f32, -3e38];
        let out = merge_patches(&p, 2, 1, 1, &[[0, 0], [0, 0]], 1, 1, MergeMode::Average).unwrap();
        assert_eq!(out, vec![0.0]);
    }

    #[test]
    fn errors_name_the_argument() {
        let img = vec![0.0f32; 16];
        let v = ImageView::new(&img, 4, 4, 1, "img").unwrap();
        let name = |e: CoreError| match e {
            CoreError::InvalidArgument { name, .. } => name,
            CoreError::Unsolvable(_) => "",
        };
        assert_eq!(name(tile(&v, 4, 4).unwrap_err()), "overlap");
        assert_eq!(name(tile(&v, 0, 0).unwrap_err()), "patch");
        let p = vec![0.0f32; 4];
        assert_eq!(
            name(merge_patches(&p, 1, 2, 1, &[[0, 0]], 4, 4, MergeMode::Average).unwrap_err()),
            "origins"
        );
        assert_eq!(
            name(merge_patches(&p, 1, 2, 1, &[[9, 0]], 4, 4, MergeMode::Average).unwrap_err()),
            "origins"
        );
        assert_eq!(
            name(merge_patches(&p, 2, 2, 1, &[[0, 0]], 2, 2, MergeMode::Average).unwrap_err()),
            "patches"
        );
    }
}
