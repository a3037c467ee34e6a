//! Tiling an image into overlapping square patches and merging them back.
//!
//! The paper runs its diffusion model on 256 x 256 patches over a 640 x 480 image with about
//! 30 px of overlap, the last row and column of patches snapped to the image edge (6 patches), and
//! averages the overlapping pixels. [`tile`] reproduces that layout; [`merge_patches`] averages
//! (`Average`, the paper) or blends with raised-cosine ramps across the overlaps (`Feather`), which
//! removes the seams that patches disagreeing by a small offset leave with a plain average.
//!
//! Both modes compute `v1 + sum_k w_k (v_k - v1) / sum_k w_k`, relative to the first covering
//! patch, so unmodified patches merge back to the image bit for bit.

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

/// Cuts `img` into `patch x patch` patches; returns them (`N x patch x patch x C`, C-order) and
/// their origins `(x, y)`. An image side shorter than `patch` is padded by reflection
/// (`BORDER_REFLECT_101`); [`merge_patches`] crops the padding away again.
pub fn tile<T: Copy>(
    img: &ImageView<'_, T>,
    patch: usize,
    overlap: usize,
) -> Result<(Vec<T>, Vec<[usize; 2]>)> {
    let (h, w, c) = (img.height(), img.width(), img.channels());
    let origins = tile_origins(h, w, patch, overlap)?;
    let per = patch
        .checked_mul(patch)
        .and_then(|v| v.checked_mul(c))
        .ok_or_else(|| CoreError::invalid("patch", format!("{patch} is too large")))?;
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
    // Patches sorted by x so that "the first covering patch" is well defined and cheap to find.
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by_key(|&i| (origins[i][0], origins[i][1]));

    let row_len = width * channels;
    let mut out = vec![T::from_f32(0.0); height * row_len];
    let geom = Geometry {
        patches,
        origins,
        order: &order,
        patch,
        channels,
        width,
        wx: &wx,
        wy: &wy,
        mode,
    };
    out.par_chunks_mut(row_len).enumerate().try_for_each_init(
        || (vec![0.0f32; row_len], vec![0.0f32; row_len]),
        |(acc, wsum), (y, out_row)| geom.merge_row(y, out_row, acc, wsum),
    )?;
    Ok(out)
}

/// Everything a row of the merge needs.
struct Geometry<'a, T> {
    patches: &'a [T],
    origins: &'a [[usize; 2]],
    order: &'a [usize],
    patch: usize,
    channels: usize,
    width: usize,
    wx: &'a [f32],
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

    /// Merges one image row. Between consecutive patch edges the set of covering patches is
    /// constant, so each such segment is a few contiguous, vectorisable passes.
    fn merge_row(
        &self,
        y: usize,
        out_row: &mut [T],
        acc: &mut [f32],
        wsum: &mut [f32],
    ) -> Result<()> {
        let (p, c, w) = (self.patch, self.channels, self.width);
        let cover: Vec<usize> = self
            .order
            .iter()
            .copied()
            .filter(|&k| (self.origins[k][1]..self.origins[k][1] + p).contains(&y))
            .collect();
        let mut edges: Vec<usize> = vec![0, w];
        for &k in &cover {
            let ox = self.origins[k][0];
            edges.push(ox);
            edges.push((ox + p).min(w));
        }
        edges.sort_unstable();
        edges.dedup();
        let mut here = Vec::with_capacity(cover.len());
        for seg in edges.windows(2) {
            let (a, b) = (seg[0], seg[1]);
            here.clear();
            here.extend(
                cover
                    .iter()
                    .copied()
                    .filter(|&k| (self.origins[k][0]..self.origins[k][0] + p).contains(&a)),
            );
            let Some((&first, rest)) = here.split_first() else {
                return Err(CoreError::invalid(
                    "origins",
                    format!("image pixel (x={a}, y={y}) is covered by no patch"),
                ));
            };
            let v1 = self.span(first, y, a, b);
            let out = &mut out_row[a * c..b * c];
            if rest.is_empty() {
                out.copy_from_slice(v1);
                continue;
            }
            let n = (b - a) * c;
            let (acc, wsum) = (&mut acc[..n], &mut wsum[..n]);
            acc.fill(0.0);
            match self.mode {
                MergeMode::Average => {
                    for &k in rest {
                        for ((s, &v), &r) in acc.iter_mut().zip(self.span(k, y, a, b)).zip(v1) {
                            *s += v.to_f32() - r.to_f32();
                        }
                    }
                    let count = here.len() as f32;
                    for ((o, &s), &r) in out.iter_mut().zip(acc.iter()).zip(v1) {
                        *o = T::from_f32(r.to_f32() + s / count);
                    }
                }
                MergeMode::Feather => {
                    wsum.fill(0.0);
                    for &k in &here {
                        let [ox, oy] = self.origins[k];
                        let row_w = self.wy[y - oy];
                        let wxs = &self.wx[a - ox..b - ox];
                        let vals = self.span(k, y, a, b);
                        let per_pixel = acc
                            .chunks_exact_mut(c)
                            .zip(wsum.chunks_exact_mut(c))
                            .zip(vals.chunks_exact(c).zip(v1.chunks_exact(c)))
                            .zip(wxs);
                        for (((s, ws), (v, r)), &wq) in per_pixel {
                            let wgt = row_w * wq;
                            for ch in 0..c {
                                ws[ch] += wgt;
                                s[ch] += wgt * (v[ch].to_f32() - r[ch].to_f32());
                            }
                        }
                    }
                    for (((o, &s), &ws), &r) in
                        out.iter_mut().zip(acc.iter()).zip(wsum.iter()).zip(v1)
                    {
                        *o = T::from_f32(r.to_f32() + s / ws);
                    }
                }
            }
        }
        Ok(())
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
