//! Marker extraction: darkness relative to a local background, an image-chosen threshold,
//! 8-connected components, area/shape filters and sub-pixel centres.
//!
//! Size: ~1,540 lines of code (the rest is its tests) for one pipeline whose steps share their
//! buffers and histogram; not yet split by step as `telea/` is.
//!
//! Pipeline (one image, single thread):
//! 1. luma in fixed point (`29 B + 150 G + 77 R`, i.e. grey x 256; grey input is scaled by 256),
//!    inverted for bright markers so that markers are always darker than the gel;
//! 2. local background = box mean over `block_size x block_size` (reflect-101 border, the rule of
//!    `cv2.BORDER_REFLECT_101`), computed with running sums in `u32` — no uint8 wraparound anywhere;
//! 3. darkness `d = background - luma`; its histogram gives the background level (median), the
//!    noise (MAD) and an Otsu threshold on the darker half; the threshold is never below
//!    `median + max(NOISE_SIGMAS * sigma, MIN_CONTRAST)` so that a markerless frame yields nothing;
//!    when that floor decides, the background is recomputed without Otsu's dark class (markers
//!    pull a box mean toward them) and the median and noise come from the remaining pixels;
//! 4. run-length 8-connected labelling with union-find (same components as
//!    `cv2.connectedComponents(connectivity=8)`);
//! 5. filters on area, fill ratio (area / bounding-box area) and bounding-box aspect ratio;
//! 6. per kept marker, a local background level from a ring around its box, and a centre weighted
//!    by darkness above that level over the marker and a one-pixel margin, so soft edges count;
//! 7. the mask: every marker's pixels, markers cut by the frame border included (reported or
//!    not), then grown by fixed dilations or adaptively per marker ([`crate::mask_grow`]).

use crate::error::{CoreError, Result};
use crate::image::ImageView;
use crate::mask_grow::{grow_masks, GrowSeed, GrowWorkspace};
use crate::simd::multiversion;

/// Fixed-point luma weights (sum 256), BT.601, in B, G, R order.
const LUMA_B: u32 = 29;
const LUMA_G: u32 = 150;
const LUMA_R: u32 = 77;
/// Fixed-point scale of luma: one grey level is this many units.
const LUMA_SCALE: i32 = 256;
/// Darkness is stored as i16 in units of 1/64 grey level (luma units >> 2).
const DARK_SHIFT: i32 = 2;
const DARK_PER_LEVEL: i32 = LUMA_SCALE >> DARK_SHIFT;
/// Histogram covers darkness from -255 to +255 grey levels, one bin per level.
const HIST_OFFSET: i32 = 256;
const HIST_BINS: usize = 512;
/// The automatic threshold stays this many noise sigmas above the background level...
const NOISE_SIGMAS: f32 = 6.0;
/// ...and at least this many grey levels above it (markers are tens of levels dark).
const MIN_CONTRAST_LEVELS: f32 = 10.0;
/// MAD to sigma for a normal distribution.
const MAD_TO_SIGMA: f32 = 1.4826;
/// Weights in the sub-pixel centroid start this many noise sigmas below the local background.
const CENTROID_NOISE_SIGMAS: f32 = 2.0;
/// A marker on the image border is kept while at least this fraction of a typical interior
/// marker's area is visible. A disc cut through its centre keeps one half; thresholded blobs
/// shrink further at a cut edge, and 0.3 of a disc corresponds to a centre at most ~0.25 radius
/// outside the frame.
const BORDER_MIN_AREA_FRACTION: f32 = 0.3;
/// A border blob narrower across the border than this fraction of its extent along it is cut:
/// its centre is completed from the far edge.
const CUT_RATIO: f32 = 0.9;
/// Interior markers needed to use the area rule above.
const MIN_INTERIOR_FOR_AREA_RULE: usize = 3;
/// Without enough interior markers, a border blob is kept while its extent across the border is
/// at least this fraction of its extent along it (a disc cut through its centre has one half).
const BORDER_KEEP_RATIO: f32 = 0.5;
/// Largest background box (pixels): keeps the binned window sums within u32.
pub const MAX_BLOCK: usize = 255;
/// Pixels tested at once when scanning for marker runs (32: two SSE2 move-masks, and the
/// hits of a chunk are the low bits of a `u64`, with room for `1 << 32`).
const SCAN_CHUNK: usize = 32;
/// Width of the ring around a marker's box used for its local background (pixels).
const RING_GAP: usize = 2;
/// Default `min_area`: this fraction of the frame's pixels (at least [`MIN_AREA_FLOOR`])...
const MIN_AREA_FRAME_FRACTION: f64 = 5e-5;
/// ...but never above this fraction of the typical blob area (area-weighted median of the
/// marker-shaped components), so large frames with small markers keep them.
const MIN_AREA_TYPICAL_FRACTION: f32 = 0.25;
const MIN_AREA_FLOOR: usize = 4;
/// A border blob failing the interior shape filters is a cut marker (masked; reported only with
/// `exclude_border = false`) when the disc it is part of has a radius within these factors of a
/// typical interior marker's radius...
const CUT_RADIUS_MIN: f32 = 0.4;
const CUT_RADIUS_MAX: f32 = 2.0;
/// ...and at least this many pixels show.
const CUT_MIN_PIXELS: u32 = 2;

/// How the output mask is grown beyond the thresholded marker pixels.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MaskGrowth {
    /// This many dilations by a 3x3 cross (OpenCV's 3x3 `MORPH_ELLIPSE`), at most until the mask
    /// stops changing.
    Dilate(usize),
    /// Per marker, ring by ring until the ring just outside is consistent with the local
    /// background ([`crate::mask_grow`]).
    Adaptive,
}

/// Which way markers differ from the gel.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Polarity {
    /// Markers darker than the gel (painted dots on GelSight, GelSight Mini, GelSlim).
    Dark,
    /// Markers brighter than the gel (TacTip pins, white dots on a dark membrane).
    Bright,
}

/// Options of [`extract_markers`]. `None` fields are chosen from the image.
#[derive(Debug, Clone, PartialEq)]
pub struct ExtractParams {
    /// Marker polarity.
    pub polarity: Polarity,
    /// Side of the background box filter in pixels (odd). Default: `min(H, W) / 8`, at least 15.
    pub block_size: Option<usize>,
    /// Darkness threshold in grey levels above the local background. Default: Otsu with a noise floor.
    pub threshold: Option<f32>,
    /// Smallest marker area in pixels. Default: `5e-5 * H * W`, at least 4.
    pub min_area: Option<usize>,
    /// Largest marker area in pixels. Default: `0.02 * H * W`.
    pub max_area: Option<usize>,
    /// Smallest area / bounding-box area (a disc has 0.785).
    pub min_fill: f32,
    /// Largest bounding-box aspect ratio (long side / short side).
    pub max_aspect: f32,
    /// Growth of the output mask beyond the thresholded pixels.
    pub grow: MaskGrowth,
    /// Do not report markers whose centre lies outside the frame (cut by the border; their
    /// centre is an estimate). They are in the mask either way.
    pub exclude_border: bool,
}

impl Default for ExtractParams {
    fn default() -> Self {
        Self {
            polarity: Polarity::Dark,
            block_size: None,
            threshold: None,
            min_area: None,
            max_area: None,
            min_fill: 0.35,
            max_aspect: 3.0,
            grow: MaskGrowth::Dilate(0),
            exclude_border: true,
        }
    }
}

/// One extracted marker.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Marker {
    /// Sub-pixel centre `(x, y)`, pixels.
    pub centre: [f32; 2],
    /// Pixels above threshold.
    pub area: u32,
    /// Bounding box `(x, y, width, height)` of the thresholded pixels, as `cv2.connectedComponentsWithStats`.
    pub bbox: [u32; 4],
    /// Peak darkness relative to the local background, `1 - min / background`, in `[0, 1]`.
    pub contrast: f32,
}

/// Result of [`extract_markers`].
#[derive(Debug, Clone)]
pub struct Extraction {
    /// Markers sorted by row then column of their centre (raster order of the centres).
    pub markers: Vec<Marker>,
    /// `H x W` mask, true = marker pixel (every marker found, reported or not, after growth).
    pub mask: Vec<bool>,
    /// Rings added around each masked marker by [`MaskGrowth::Adaptive`] (empty otherwise), in
    /// label order.
    pub grow_rings: Vec<u16>,
    /// Threshold used, grey levels of darkness above the local background.
    pub threshold: f32,
    /// Background level (median darkness), grey levels.
    pub background_level: f32,
    /// Estimated noise sigma of the darkness image, grey levels.
    pub noise_sigma: f32,
    /// Box-filter size used, pixels.
    pub block_size: usize,
    /// Connected components before the area/shape filters.
    pub n_components: usize,
}

/// Reusable buffers so that a streaming caller allocates nothing per frame.
#[derive(Debug, Default, Clone)]
pub struct ExtractWorkspace {
    luma: Vec<u16>,
    /// Per background bin, the luma below which a pixel is a marker pixel ([`label_image`]).
    limits: Vec<u16>,
    boxes: BoxBuffers,
    labels: Vec<u32>,
    labeller: RunLabeller,
    ring: Vec<u16>,
    grow: GrowWorkspace,
}

#[derive(Debug, Clone, Copy)]
struct Run {
    y: u32,
    x0: u32,
    /// Exclusive end.
    x1: u32,
    label: u32,
}

/// Default box size for an image (pixels): large next to a marker, small next to lighting
/// gradients.
pub fn default_block_size(height: usize, width: usize) -> usize {
    let b = (height.min(width) / 8).max(15);
    (b | 1).min(MAX_BLOCK)
}

/// Extracts markers from a BGR (`channels == 3`), BGRA (4) or grey (1) uint8 image.
pub fn extract_markers(image: &ImageView<'_, u8>, params: &ExtractParams) -> Result<Extraction> {
    let mut ws = ExtractWorkspace::default();
    extract_markers_with(image, params, &mut ws, true)
}

/// [`extract_markers`] with caller-owned buffers; `want_mask = false` leaves
/// [`Extraction::mask`] empty (the markers are unchanged).
pub fn extract_markers_with(
    image: &ImageView<'_, u8>,
    params: &ExtractParams,
    ws: &mut ExtractWorkspace,
    want_mask: bool,
) -> Result<Extraction> {
    validate(image, params)?;
    let (h, w) = (image.height(), image.width());
    let n = h * w;
    let block = params
        .block_size
        .unwrap_or_else(|| default_block_size(h, w));

    let bg = luma_and_background(image, params.polarity, block, &mut ws.luma, &mut ws.boxes);
    let hist = darkness_histogram(&ws.luma, &ws.boxes.mean, bg);
    let mut stats = HistStats::from_hist(&hist);
    let first_sigma = stats.sigma;
    let otsu = otsu_threshold(&hist, &stats);
    let threshold = match params.threshold {
        Some(t) => t,
        None if otsu < noise_floor(&stats) => {
            // The noise floor binds: the spread may come from the markers themselves (large or
            // many markers pull the box mean down near them, so the gel around them reads bright
            // and the markers shallow) rather than from noise. Recompute the background without
            // the pixels that Otsu puts in the dark class, then the statistics and threshold.
            let exclude = otsu.max(stats.median + MIN_CONTRAST_LEVELS);
            background_excluding(&ws.luma, bg, block, exclude, &mut ws.boxes);
            let hist = darkness_histogram(&ws.luma, &ws.boxes.mean, bg);
            // The level and noise of the gel: from the pixels left out of the dark class (the
            // markers' own darkness is not noise). Otsu still sees the whole histogram.
            let mut gel = hist;
            let cut = (exclude.floor() as i32 + HIST_OFFSET).clamp(0, HIST_BINS as i32) as usize;
            gel[cut..].fill(0);
            stats = HistStats::from_hist(&gel);
            let otsu = otsu_threshold(&hist, &stats);
            otsu.max(noise_floor(&stats)).clamp(0.0, 255.0)
        }
        None => auto_threshold(&hist, &stats),
    };
    // Strictly greater than the threshold, in the i16 darkness units.
    let t_units = (threshold * DARK_PER_LEVEL as f32)
        .floor()
        .clamp(i16::MIN as f32, i16::MAX as f32) as i16;

    let n_components = label_image(
        &ws.luma,
        &ws.boxes.mean,
        bg,
        t_units,
        &mut ws.limits,
        &mut ws.boxes.row,
        &mut ws.labeller,
    );
    let comps = component_stats(&ws.labeller.runs, n_components);

    let max_area = params
        .max_area
        .unwrap_or_else(|| ((0.02 * n as f64).round() as usize).max(MIN_AREA_FLOOR));
    let min_area = params.min_area.unwrap_or_else(|| {
        default_min_area(&comps, h, w, max_area, params.min_fill, params.max_aspect)
    });
    let max_area = max_area.max(min_area);
    // `keep`: in the mask; `report`: in the returned markers.
    let mut keep: Vec<bool> = comps
        .iter()
        .map(|c| c.passes(min_area, max_area, params.min_fill, params.max_aspect))
        .collect();
    let typical_area = typical_interior_area(&comps, &keep, h, w);
    let mut report = keep.clone();
    if params.exclude_border {
        drop_border_cut(&comps, &mut report, h, w, typical_area);
    }
    if let Some(a) = typical_area {
        let r_typ = (a / std::f32::consts::PI).sqrt();
        for (i, c) in comps.iter().enumerate() {
            if !keep[i] && c.is_cut_marker(h, w, r_typ, max_area, params.min_fill) {
                keep[i] = true;
                report[i] = !params.exclude_border;
            }
        }
    }

    // Label image (0 = background) so that centroids can tell their own pixels from a neighbour's.
    // The buffer is all zeros between calls: only the runs written here are cleared afterwards.
    if ws.labels.len() != n {
        ws.labels.clear();
        ws.labels.resize(n, 0);
    }
    for r in &ws.labeller.runs {
        let row = r.y as usize * w;
        ws.labels[row + r.x0 as usize..row + r.x1 as usize].fill(r.label + 1);
    }

    let sigma_units = stats.sigma.max(first_sigma) * LUMA_SCALE as f32;
    let mut markers = Vec::new();
    let t_luma = threshold * LUMA_SCALE as f32;
    let mut seeds = Vec::new();
    for (label, c) in comps.iter().enumerate() {
        if !keep[label] {
            continue;
        }
        let (mut marker, local_dark) = refine_marker(
            c,
            label as u32 + 1,
            &ws.luma,
            &ws.labels,
            h,
            w,
            sigma_units,
            &mut ws.ring,
        );
        complete_cut_centre(&mut marker, c, h, w, typical_area);
        // The box mean is pulled up next to bright features, so their dark-looking surroundings
        // can pass the threshold; a real marker is also darker than its own immediate ring.
        if local_dark <= t_luma {
            keep[label] = false;
            continue;
        }
        // A cut marker's completed centre can land past the frame edge: with exclude_border
        // such a marker is left out of the report (the mask keeps it).
        if report[label] && !(params.exclude_border && centre_outside(&marker.centre, h, w)) {
            markers.push(marker);
        }
        if want_mask && params.grow == MaskGrowth::Adaptive {
            let visible = (c.area as f32 / std::f32::consts::PI).sqrt();
            let radius = match typical_area {
                Some(a) if c.on_border(h, w) => (a / std::f32::consts::PI).sqrt().max(visible),
                _ => visible,
            };
            seeds.push(GrowSeed {
                label: label as u32 + 1,
                bbox: [c.x0, c.y0, c.x1, c.y1],
                centre: marker.centre,
                radius,
            });
        }
    }
    markers.sort_by(|a, b| {
        a.centre[1]
            .total_cmp(&b.centre[1])
            .then(a.centre[0].total_cmp(&b.centre[0]))
    });

    // A fresh 300 KB mask per frame costs page faults; streaming callers that only want centres
    // skip it.
    let mut mask = if want_mask {
        vec![false; n]
    } else {
        Vec::new()
    };
    for r in ws.labeller.runs.iter().filter(|_| want_mask) {
        if keep[r.label as usize] {
            let row = r.y as usize * w;
            mask[row + r.x0 as usize..row + r.x1 as usize].fill(true);
        }
    }
    let mut grow_rings = Vec::new();
    if want_mask {
        match params.grow {
            MaskGrowth::Dilate(k) => mask = dilate_cross_n(mask, h, w, k),
            MaskGrowth::Adaptive => {
                grow_rings = grow_masks(&ws.luma, &ws.labels, h, w, &seeds, &mut mask, &mut ws.grow)
            }
        }
    }
    for r in &ws.labeller.runs {
        let row = r.y as usize * w;
        ws.labels[row + r.x0 as usize..row + r.x1 as usize].fill(0);
    }

    Ok(Extraction {
        markers,
        mask,
        grow_rings,
        threshold,
        background_level: stats.median,
        noise_sigma: stats.sigma,
        block_size: block,
        n_components,
    })
}

fn validate(image: &ImageView<'_, u8>, params: &ExtractParams) -> Result<()> {
    if !matches!(image.channels(), 1 | 3 | 4) {
        return Err(CoreError::invalid(
            "img",
            format!(
                "expected a grey (H x W), BGR (H x W x 3) or BGRA image; got {} channels",
                image.channels()
            ),
        ));
    }
    if let Some(b) = params.block_size {
        if !(3..=MAX_BLOCK).contains(&b) || b % 2 == 0 {
            return Err(CoreError::invalid(
                "block_size",
                format!("must be an odd integer in [3, {MAX_BLOCK}]; got {b}"),
            ));
        }
    }
    if let Some(t) = params.threshold {
        if !t.is_finite() || !(0.0..=255.0).contains(&t) {
            return Err(CoreError::invalid(
                "threshold",
                format!("must be a finite number of grey levels in [0, 255]; got {t}"),
            ));
        }
    }
    if let (Some(lo), Some(hi)) = (params.min_area, params.max_area) {
        if lo > hi {
            return Err(CoreError::invalid(
                "max_area",
                format!("must be >= min_area ({lo}); got {hi}"),
            ));
        }
    }
    if !params.min_fill.is_finite() || !(0.0..=1.0).contains(&params.min_fill) {
        return Err(CoreError::invalid(
            "min_fill",
            format!("must be in [0, 1]; got {}", params.min_fill),
        ));
    }
    if !params.max_aspect.is_finite() || params.max_aspect < 1.0 {
        return Err(CoreError::invalid(
            "max_aspect",
            format!("must be a finite number >= 1; got {}", params.max_aspect),
        ));
    }
    Ok(())
}

/// Luma x 256 of one image row in `u16`; for bright markers inverted so markers are dark.
#[inline(always)]
fn luma_row(data: &[u8], channels: usize, polarity: Polarity, out: &mut [u16]) {
    match channels {
        1 => {
            for (o, &g) in out.iter_mut().zip(data) {
                *o = u16::from(g) << 8;
            }
        }
        // u16 arithmetic is exact: the weights sum to 256. Alpha is ignored.
        3 => {
            for (o, px) in out.iter_mut().zip(data.chunks_exact(3)) {
                *o = LUMA_B as u16 * u16::from(px[0])
                    + LUMA_G as u16 * u16::from(px[1])
                    + LUMA_R as u16 * u16::from(px[2]);
            }
        }
        _ => {
            for (o, px) in out.iter_mut().zip(data.chunks_exact(4)) {
                *o = LUMA_B as u16 * u16::from(px[0])
                    + LUMA_G as u16 * u16::from(px[1])
                    + LUMA_R as u16 * u16::from(px[2]);
            }
        }
    }
    if polarity == Polarity::Bright {
        // 255 * 256 is the largest luma; the difference cannot underflow.
        for v in out.iter_mut() {
            *v = 65280 - *v;
        }
    }
}

/// Sets `buf`'s length to `n` for a caller that overwrites every element: reused buffers of the
/// right size keep their stale contents instead of being zero-filled again.
#[inline(always)]
fn resize_for_overwrite<T: Copy + Default>(buf: &mut Vec<T>, n: usize) {
    if buf.len() != n {
        buf.clear();
        buf.resize(n, T::default());
    }
}

/// Reflect-101 index (`cv2.BORDER_REFLECT_101`): -1 -> 1, n -> n - 2. Requires `n >= 2` or `i == 0`.
#[inline]
fn reflect101(i: isize, n: usize) -> usize {
    let n = n as isize;
    if n == 1 {
        return 0;
    }
    let mut i = i;
    // Loop only matters for radius >= n, which the caller prevents; kept for safety.
    while i < 0 || i >= n {
        i = if i < 0 { -i } else { 2 * (n - 1) - i };
    }
    i as usize
}

/// Geometry of the binned background: `factor x factor` pixel bins, `bins_w` bins per row.
#[derive(Debug, Clone, Copy)]
struct Background {
    h: usize,
    w: usize,
    factor: usize,
    bins_w: usize,
}

/// Bin side used for a background box of `block` pixels: the box is what must be smooth, so a
/// 4x4 bin is fine from a 31-pixel box on (at least 7 bins across).
fn bin_factor(block: usize) -> usize {
    if block >= 31 {
        4
    } else {
        2
    }
}

multiversion! {
    /// Luma of the image into `luma` ([`luma_row`]), and the local background: the box mean of
    /// luma over about `block x block` pixels with reflect-101 borders, computed on `F x F` bin
    /// sums (a box of `2 * (block / (2 F)) + 1` bins) and left at bin resolution in `buf.mean`.
    /// The background only has to be smooth on the box scale; reading it back at each pixel's
    /// bin changes nothing that matters for the threshold. Each bin row's luma rows are summed
    /// right after they are computed, while still in cache (one pass over the image, not two).
    fn luma_and_background(
        image: &ImageView<'_, u8>,
        polarity: Polarity,
        block: usize,
        luma: &mut Vec<u16>,
        buf: &mut BoxBuffers,
    ) -> Background {
        let (h, w) = (image.height(), image.width());
        // Every element is written below: only a new size needs the buffer resized (a fresh
        // 600 KB zero fill per 640x480 frame otherwise).
        resize_for_overwrite(luma, h * w);
        let factor = bin_factor(block);
        let (bins_h, bins_w) = (h.div_ceil(factor), w.div_ceil(factor));
        // `bin_sums` assigns every bin.
        resize_for_overwrite(&mut buf.binned, bins_h * bins_w);
        if factor == 4 {
            bin_sums::<4>(image, polarity, luma, &mut buf.binned, &mut buf.bin_cols);
        } else {
            bin_sums::<2>(image, polarity, luma, &mut buf.binned, &mut buf.bin_cols);
        }
        let radius = block / (2 * factor);
        box_mean_binned(
            &buf.binned,
            bins_h,
            bins_w,
            radius,
            factor * factor,
            &mut buf.col,
            &mut buf.padded,
            &mut buf.mean,
        );
        Background { h, w, factor, bins_w }
    }
}

/// Luma rows ([`luma_row`]) and sums of `F x F` pixel bins; partial bins at the right/bottom
/// edge repeat the last pixel so that every bin sums `F * F` values. The `F` rows of a bin row
/// are computed and added column by column (vector adds), then each bin sums `F` columns: one
/// horizontal pass per bin row, not `F`.
#[inline(always)]
fn bin_sums<const F: usize>(
    image: &ImageView<'_, u8>,
    polarity: Polarity,
    luma: &mut [u16],
    out: &mut [u32],
    cols: &mut Vec<u32>,
) {
    let (h, w, ch) = (image.height(), image.width(), image.channels());
    let data = image.data();
    let bins_w = w.div_ceil(F);
    let full = w / F;
    resize_for_overwrite(cols, w);
    for (by, orow) in out.chunks_exact_mut(bins_w).enumerate() {
        for k in 0..F {
            let y = by * F + k;
            if y < h {
                luma_row(
                    &data[y * w * ch..][..w * ch],
                    ch,
                    polarity,
                    &mut luma[y * w..][..w],
                );
            }
            let row = &luma[y.min(h - 1) * w..][..w];
            if k == 0 {
                for (c, &v) in cols.iter_mut().zip(row) {
                    *c = u32::from(v);
                }
            } else {
                for (c, &v) in cols.iter_mut().zip(row) {
                    *c += u32::from(v);
                }
            }
        }
        for (o, px) in orow.iter_mut().zip(cols.chunks_exact(F)) {
            *o = px.iter().sum::<u32>();
        }
        if full < bins_w {
            let tail = &cols[full * F..];
            orow[full] = tail.iter().sum::<u32>() + cols[w - 1] * (F - tail.len()) as u32;
        }
    }
}

#[inline(always)]
fn expand<const F: usize>(src: &[u16], row: &mut [u16]) {
    let full = row.len() / F;
    for (chunk, &m) in row.chunks_exact_mut(F).zip(src) {
        for v in chunk {
            *v = m;
        }
    }
    if let Some(&m) = src.get(full) {
        for v in &mut row[full * F..] {
            *v = m;
        }
    }
}

/// Darkness of one pixel, i16 in 1/64 grey level: `(background - luma) >> 2`. Both are at
/// most 65280, so the result lies in `[-16320, 16320]`.
#[inline(always)]
fn darkness(m: u16, l: u16) -> i16 {
    ((i32::from(m) - i32::from(l)) >> DARK_SHIFT) as i16
}

/// Luma limit equivalent to `darkness(m, l) > t`: that holds exactly when `l < limit(m, t)`.
/// `(m - l) >> 2 > t` means `m - l >= 4 (t + 1)`, i.e. `l < m - 4 t - 3`; the limit is clamped
/// to `u16` (luma never exceeds 65280, so 65535 admits every pixel and 0 none).
#[inline(always)]
fn luma_limit(m: u16, t: i16) -> u16 {
    (i32::from(m) - 4 * i32::from(t) - 3).clamp(0, i32::from(u16::MAX)) as u16
}

multiversion! {
    /// Histogram of darkness on every other pixel of every 1st-4th row: tens of thousands of
    /// samples are plenty for a median, a MAD and Otsu. Darkness is computed only where it is
    /// sampled, straight from the binned background (no row at pixel resolution).
    fn darkness_histogram(luma: &[u16], mean: &[u16], bg: Background) -> [u32; HIST_BINS] {
        let mut hist = [[0u32; HIST_BINS]; 4];
        // Every 4th row on frames of 256+ rows (38k samples at 640x480), denser on small ones.
        let row_step = (bg.h / 64).clamp(1, 4);
        for y in (0..bg.h).step_by(row_step) {
            let means = &mean[(y / bg.factor) * bg.bins_w..][..bg.bins_w];
            let row = &luma[y * bg.w..][..bg.w];
            if bg.factor == 4 {
                sample_row::<4>(means, row, &mut hist);
            } else {
                sample_row::<2>(means, row, &mut hist);
            }
        }
        let mut total = [0u32; HIST_BINS];
        for sub in &hist {
            for (t, &c) in total.iter_mut().zip(sub) {
                *t += c;
            }
        }
        total
    }
}

/// Adds the darkness of the even pixels of one row (background bins of `F` pixels) to the
/// histograms, spread over four sub-histograms so that consecutive increments of the one busy
/// bin do not wait on each other.
#[inline(always)]
fn sample_row<const F: usize>(means: &[u16], row: &[u16], hist: &mut [[u32; HIST_BINS]; 4]) {
    // Two bins at a time: F even pixels, i.e. at least two sub-histograms in turn.
    let pairs = row.chunks_exact(2 * F);
    let done = row.len() - pairs.remainder().len();
    for (px, m) in pairs.zip(means.chunks_exact(2)) {
        for j in 0..F {
            let x = 2 * j;
            hist[j % 4][hist_bin(darkness(m[x / F], px[x]))] += 1;
        }
    }
    // `done` is a multiple of 2 F, so the tail starts on an even pixel; a partial last bin
    // is `means[x / F]` as in [`expand`].
    for x in (done..row.len()).step_by(2) {
        hist[0][hist_bin(darkness(means[x / F], row[x]))] += 1;
    }
}

multiversion! {
    /// Labels the pixels with darkness above `t`. Darkness is never stored: each bin row's
    /// background becomes a luma limit ([`luma_limit`]) at pixel resolution, and the labeller
    /// compares luma with it.
    fn label_image(
        luma: &[u16],
        mean: &[u16],
        bg: Background,
        t: i16,
        limits: &mut Vec<u16>,
        limit_row: &mut Vec<u16>,
        labeller: &mut RunLabeller,
    ) -> usize {
        labeller.clear();
        resize_for_overwrite(limits, bg.bins_w);
        resize_for_overwrite(limit_row, bg.w);
        for y in 0..bg.h {
            if y % bg.factor == 0 {
                let means = &mean[(y / bg.factor) * bg.bins_w..][..bg.bins_w];
                for (l, &m) in limits.iter_mut().zip(means) {
                    *l = luma_limit(m, t);
                }
                if bg.factor == 4 {
                    expand::<4>(limits, limit_row);
                } else {
                    expand::<2>(limits, limit_row);
                }
            }
            labeller.push_row(&luma[y * bg.w..][..bg.w], limit_row, y);
        }
        labeller.finish()
    }
}

/// Histogram bin of a darkness value: d / 64 floored, shifted into [0, 512) (|d| <= 16320).
#[inline(always)]
fn hist_bin(d: i16) -> usize {
    ((i32::from(d) >> 6) + HIST_OFFSET) as usize
}

/// Buffers of [`background`].
#[derive(Debug, Default, Clone)]
struct BoxBuffers {
    binned: Vec<u32>,
    /// Column sums of one bin row's pixel rows ([`bin_sums`]).
    bin_cols: Vec<u32>,
    col: Vec<u32>,
    padded: Vec<u32>,
    mean: Vec<u16>,
    /// [`label_image`]'s luma limits of the current row at pixel resolution.
    row: Vec<u16>,
    /// [`background_excluding`]: per-bin luma sums and counts of the pixels kept, and their box
    /// sums (one pass down the columns, then along the rows).
    kept_sum: Vec<u64>,
    kept_count: Vec<u32>,
    box_sum: Vec<u64>,
    box_count: Vec<u32>,
}

/// Per bin, the luma sum and count of the pixels at most `limit` (luma units) darker than the
/// bin's background (branch-free, one bin of `F` pixels at a time).
#[inline(always)]
fn kept_sums<const F: usize>(luma: &[u16], bg: Background, limit: i32, buf: &mut BoxBuffers) {
    for y in 0..bg.h {
        let b0 = (y / F) * bg.bins_w;
        let means = &buf.mean[b0..][..bg.bins_w];
        let sums = &mut buf.kept_sum[b0..][..bg.bins_w];
        let counts = &mut buf.kept_count[b0..][..bg.bins_w];
        let bins = means.iter().zip(sums.iter_mut().zip(counts.iter_mut()));
        for (chunk, (&m, (s, c))) in luma[y * bg.w..][..bg.w].chunks(F).zip(bins) {
            let m = i32::from(m);
            let (mut ss, mut cc) = (0u32, 0u32);
            for &l in chunk {
                let k = u32::from(m - i32::from(l) <= limit);
                ss += k * u32::from(l);
                cc += k;
            }
            *s += u64::from(ss);
            *c += cc;
        }
    }
}

/// Replaces the binned background `buf.mean` by the mean over the same boxes of the pixels whose
/// darkness against it is at most `exclude` grey levels: markers no longer pull the background of
/// their surroundings (nor their own) toward them. A box with no pixel kept keeps its mean.
fn background_excluding(
    luma: &[u16],
    bg: Background,
    block: usize,
    exclude: f32,
    buf: &mut BoxBuffers,
) {
    let f = bg.factor;
    let (bins_h, bins_w) = (bg.h.div_ceil(f), bg.bins_w);
    let nb = bins_h * bins_w;
    let limit = (exclude * LUMA_SCALE as f32).floor() as i32;
    buf.kept_sum.clear();
    buf.kept_sum.resize(nb, 0);
    buf.kept_count.clear();
    buf.kept_count.resize(nb, 0);
    if f == 4 {
        kept_sums::<4>(luma, bg, limit, buf);
    } else {
        kept_sums::<2>(luma, bg, limit, buf);
    }
    // Same box as `background`: radius in bins, reflect-101 borders.
    let r = block / (2 * f);
    let ry = r.min(bins_h.saturating_sub(1)) as isize;
    let rx = r.min(bins_w.saturating_sub(1)) as isize;
    buf.box_sum.clear();
    buf.box_sum.resize(nb, 0);
    buf.box_count.clear();
    buf.box_count.resize(nb, 0);
    // Vertical pass into `box_*`, then horizontal pass back into `kept_*` via a row copy.
    for by in 0..bins_h {
        for k in -ry..=ry {
            let src = reflect101(by as isize + k, bins_h) * bins_w;
            for bx in 0..bins_w {
                buf.box_sum[by * bins_w + bx] += buf.kept_sum[src + bx];
                buf.box_count[by * bins_w + bx] += buf.kept_count[src + bx];
            }
        }
    }
    for by in 0..bins_h {
        let row = by * bins_w;
        for bx in 0..bins_w {
            let (mut s, mut c) = (0u64, 0u64);
            for k in -rx..=rx {
                let i = row + reflect101(bx as isize + k, bins_w);
                s += buf.box_sum[i];
                c += u64::from(buf.box_count[i]);
            }
            // A mean of u16 values fits in u16.
            if let Some(m) = (s + c / 2).checked_div(c) {
                buf.mean[row + bx] = m as u16;
            }
        }
    }
}

#[inline(always)]
/// Box mean (radius `r` in bins, reflect-101 borders) of bin sums of `per_bin` pixels, as luma.
#[allow(clippy::too_many_arguments)]
fn box_mean_binned(
    binned: &[u32],
    h: usize,
    w: usize,
    r: usize,
    per_bin: usize,
    col: &mut Vec<u32>,
    padded: &mut Vec<u32>,
    mean: &mut Vec<u16>,
) {
    // Radius limited so that reflect-101 never needs more than one bounce.
    let ry = r.min(h.saturating_sub(1));
    let rx = r.min(w.saturating_sub(1));
    // Fixed-point reciprocal so that mean = (sum * inv) >> 32.
    let count = (per_bin * (2 * ry + 1) * (2 * rx + 1)) as u64;
    let inv = (1u64 << 32).div_ceil(count);
    col.clear();
    col.resize(w, 0);
    for k in -(ry as isize)..=(ry as isize) {
        for (c, &v) in col.iter_mut().zip(&binned[reflect101(k, h) * w..][..w]) {
            *c += v;
        }
    }
    // Both are fully written below (`padded`: the row and both reflected margins, every row).
    resize_for_overwrite(padded, w + 2 * rx);
    resize_for_overwrite(mean, h * w);
    for y in 0..h {
        if y > 0 {
            let add = &binned[reflect101(y as isize + ry as isize, h) * w..][..w];
            let sub = &binned[reflect101(y as isize - ry as isize - 1, h) * w..][..w];
            for ((c, &a), &s) in col.iter_mut().zip(add).zip(sub) {
                // Never negative: `s` was added when its row entered the window.
                *c = *c + a - s;
            }
        }
        // Column sums padded by reflect-101 so the running sum has no branches.
        padded[rx..rx + w].copy_from_slice(col);
        for k in 0..rx {
            padded[rx - 1 - k] = col[reflect101(-1 - k as isize, w)];
            padded[rx + w + k] = col[reflect101((w + k) as isize, w)];
        }
        // u32 cannot overflow: a window covers at most ~MAX_BLOCK^2 pixels of at most 65280.
        let mut acc: u32 = padded[..2 * rx + 1].iter().sum();
        let out = &mut mean[y * w..][..w];
        out[0] = ((u64::from(acc) * inv) >> 32) as u16;
        // padded[x + 2 rx] enters the window centred on x, padded[x - 1] leaves it.
        let entering = &padded[2 * rx + 1..];
        let leaving = &padded[..w - 1];
        for ((o, &a), &s) in out[1..].iter_mut().zip(entering).zip(leaving) {
            acc = acc + a - s;
            *o = ((u64::from(acc) * inv) >> 32) as u16;
        }
    }
}

/// Robust statistics of the darkness histogram.
struct HistStats {
    /// Median darkness (background level), grey levels.
    median: f32,
    /// Noise sigma from the MAD, grey levels (at least 0.5: the histogram has 1-level bins).
    sigma: f32,
    median_bin: usize,
}

impl HistStats {
    fn from_hist(hist: &[u32; HIST_BINS]) -> Self {
        let total: u64 = hist.iter().map(|&c| u64::from(c)).sum();
        let half = total.div_ceil(2);
        let mut acc = 0u64;
        let mut median_bin = 0;
        for (i, &c) in hist.iter().enumerate() {
            acc += u64::from(c);
            if acc >= half {
                median_bin = i;
                break;
            }
        }
        // MAD: smallest radius r such that bins [m - r, m + r] hold half of the pixels.
        let mut acc = u64::from(hist[median_bin]);
        let mut r = 0usize;
        while acc < half && r < HIST_BINS {
            r += 1;
            if median_bin >= r {
                acc += u64::from(hist[median_bin - r]);
            }
            if median_bin + r < HIST_BINS {
                acc += u64::from(hist[median_bin + r]);
            }
        }
        let median = median_bin as f32 - HIST_OFFSET as f32 + 0.5;
        Self {
            median,
            sigma: (MAD_TO_SIGMA * r as f32).max(0.5),
            median_bin,
        }
    }
}

/// Otsu's threshold on the darker-than-background half of the histogram, floored above the noise.
fn auto_threshold(hist: &[u32; HIST_BINS], stats: &HistStats) -> f32 {
    otsu_threshold(hist, stats)
        .max(noise_floor(stats))
        .clamp(0.0, 255.0)
}

/// Lowest automatic threshold: [`NOISE_SIGMAS`] sigmas, at least [`MIN_CONTRAST_LEVELS`], above
/// the background level.
fn noise_floor(stats: &HistStats) -> f32 {
    stats.median + (NOISE_SIGMAS * stats.sigma).max(MIN_CONTRAST_LEVELS)
}

/// Otsu's threshold on the darker-than-background half of the histogram, grey levels.
fn otsu_threshold(hist: &[u32; HIST_BINS], stats: &HistStats) -> f32 {
    let lo = stats.median_bin;
    let (mut total, mut sum) = (0f64, 0f64);
    for (i, &c) in hist.iter().enumerate().skip(lo) {
        total += f64::from(c);
        sum += f64::from(c) * i as f64;
    }
    let (mut w0, mut sum0) = (0f64, 0f64);
    let (mut best_var, mut best_bin) = (-1f64, lo);
    for (i, &c) in hist.iter().enumerate().skip(lo) {
        w0 += f64::from(c);
        sum0 += f64::from(c) * i as f64;
        let w1 = total - w0;
        if w0 == 0.0 || w1 == 0.0 {
            continue;
        }
        let diff = sum0 / w0 - (sum - sum0) / w1;
        let var = w0 * w1 * diff * diff;
        if var > best_var {
            best_var = var;
            best_bin = i;
        }
    }
    // Otsu's class boundary is the upper edge of `best_bin`.
    (best_bin as f32 + 1.0) - HIST_OFFSET as f32
}

/// Run-length 8-connected labelling, fed one row of darkness at a time.
#[derive(Debug, Default, Clone)]
struct RunLabeller {
    runs: Vec<Run>,
    parent: Vec<u32>,
    prev: std::ops::Range<usize>,
}

impl RunLabeller {
    fn clear(&mut self) {
        self.runs.clear();
        self.parent.clear();
        self.prev = 0..0;
    }

    /// Adds the runs of `luma[x] < limit[x]` (marker pixels, [`luma_limit`]) of row `y` and
    /// unions them with touching runs above.
    #[inline(always)]
    fn push_row(&mut self, luma: &[u16], limit: &[u16], y: usize) {
        let w = luma.len();
        let limit = &limit[..w];
        let start = self.runs.len();
        // Start of a run still open at the current chunk's first pixel.
        let mut open: Option<usize> = None;
        let mut x = 0;
        while x < w {
            if open.is_none() {
                // Background: a tight loop over whole chunks until one holds a marker pixel.
                while x + SCAN_CHUNK <= w
                    && hit_bits(&luma[x..][..SCAN_CHUNK], &limit[x..][..SCAN_CHUNK]) == 0
                {
                    x += SCAN_CHUNK;
                }
                if x == w {
                    break;
                }
            }
            let n = SCAN_CHUNK.min(w - x);
            let bits = hit_bits(&luma[x..x + n], &limit[x..x + n]);
            let all = (1u64 << n) - 1;
            // Background, or the inside of a run: nothing starts or ends in this chunk.
            if (bits == 0 && open.is_none()) || (bits == all && open.is_some()) {
                x += n;
                continue;
            }
            // A run starts at a set bit and ends at the next clear one (`pos` <= 32 < 64).
            let mut pos = 0u32;
            loop {
                let from = u64::MAX << pos;
                match open {
                    Some(x0) => {
                        let ends = !bits & all & from;
                        if ends == 0 {
                            break;
                        }
                        pos = ends.trailing_zeros();
                        self.push_run(y, x0, x + pos as usize);
                        open = None;
                    }
                    None => {
                        let starts = bits & from;
                        if starts == 0 {
                            break;
                        }
                        pos = starts.trailing_zeros();
                        open = Some(x + pos as usize);
                    }
                }
            }
            x += n;
        }
        if let Some(x0) = open {
            self.push_run(y, x0, w);
        }
        let cur = start..self.runs.len();
        // Two-pointer sweep: runs in a row are sorted and disjoint.
        let mut p = self.prev.start;
        for c in cur.clone() {
            let (cx0, cx1) = (self.runs[c].x0, self.runs[c].x1);
            while p < self.prev.end && self.runs[p].x1 < cx0 {
                p += 1;
            }
            let mut q = p;
            // 8-connectivity: runs touch, diagonals included, when prev.x0 <= cx1 and prev.x1 >= cx0.
            while q < self.prev.end && self.runs[q].x0 <= cx1 {
                union(&mut self.parent, c as u32, q as u32);
                q += 1;
            }
        }
        self.prev = cur;
    }

    #[inline(always)]
    fn push_run(&mut self, y: usize, x0: usize, x1: usize) {
        let id = self.runs.len() as u32;
        self.runs.push(Run {
            y: y as u32,
            x0: x0 as u32,
            x1: x1 as u32,
            label: id,
        });
        self.parent.push(id);
    }

    /// Compacts labels in order of first appearance; returns the number of components.
    fn finish(&mut self) -> usize {
        let mut compact = vec![u32::MAX; self.runs.len()];
        let mut n = 0u32;
        for (i, run) in self.runs.iter_mut().enumerate() {
            let root = find(&mut self.parent, i as u32) as usize;
            if compact[root] == u32::MAX {
                compact[root] = n;
                n += 1;
            }
            run.label = compact[root];
        }
        n as usize
    }
}

/// Bit `i` set where `luma[i] < limit[i]`, for at most [`SCAN_CHUNK`] pixels.
#[inline(always)]
fn hit_bits(luma: &[u16], limit: &[u16]) -> u64 {
    #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
    if let (Ok(l), Ok(m)) = (
        <&[u16; SCAN_CHUNK]>::try_from(luma),
        <&[u16; SCAN_CHUNK]>::try_from(limit),
    ) {
        return hit_bits_sse2(l, m);
    }
    let mut bits = 0u64;
    for (i, (&l, &m)) in luma.iter().zip(limit).enumerate() {
        bits |= u64::from(l < m) << i;
    }
    bits
}

/// [`hit_bits`] of a full chunk in SSE2 (part of the x86-64 baseline): unsigned 16-bit
/// compares (signed after flipping the sign bits), packed to bytes, one move-mask. LLVM does
/// not form the move-mask from the portable loop.
#[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
#[inline(always)]
fn hit_bits_sse2(luma: &[u16; SCAN_CHUNK], limit: &[u16; SCAN_CHUNK]) -> u64 {
    use std::arch::x86_64::{
        _mm_cmplt_epi16, _mm_loadu_si128, _mm_movemask_epi8, _mm_packs_epi16, _mm_set1_epi16,
        _mm_xor_si128,
    };
    // SAFETY: SSE2 is enabled for this build (the cfg above); each load reads 8 u16 (16 bytes)
    // at `v[8 k..]`, inside a 32-element array for k in 0..4, and unaligned loads have no
    // alignment requirement.
    unsafe {
        let flip = _mm_set1_epi16(i16::MIN);
        let lt = |k: usize| {
            let l = _mm_loadu_si128(luma.as_ptr().add(8 * k).cast());
            let m = _mm_loadu_si128(limit.as_ptr().add(8 * k).cast());
            _mm_cmplt_epi16(_mm_xor_si128(l, flip), _mm_xor_si128(m, flip))
        };
        // Each 16-bit lane is all ones or all zeros: the signed pack keeps it as one byte.
        let lo = _mm_movemask_epi8(_mm_packs_epi16(lt(0), lt(1))) as u32;
        let hi = _mm_movemask_epi8(_mm_packs_epi16(lt(2), lt(3))) as u32;
        u64::from(lo) | (u64::from(hi) << 16)
    }
}

fn find(parent: &mut [u32], mut i: u32) -> u32 {
    while parent[i as usize] != i {
        let gp = parent[parent[i as usize] as usize];
        parent[i as usize] = gp;
        i = gp;
    }
    i
}

fn union(parent: &mut [u32], a: u32, b: u32) {
    let (ra, rb) = (find(parent, a), find(parent, b));
    if ra != rb {
        // Keep the smaller index as root so labels follow raster order.
        let (lo, hi) = if ra < rb { (ra, rb) } else { (rb, ra) };
        parent[hi as usize] = lo;
    }
}

#[derive(Debug, Clone, Copy)]
struct Component {
    area: u32,
    x0: u32,
    y0: u32,
    x1: u32,
    y1: u32,
}

impl Component {
    /// A blob on the border whose extent across it is clearly shorter than along it: a marker
    /// cut by the frame edge, whose centre would be biased. Grazing markers are kept.
    fn cut_by_border(&self, h: usize, w: usize) -> bool {
        let (bw, bh) = (
            (self.x1 - self.x0 + 1) as f32,
            (self.y1 - self.y0 + 1) as f32,
        );
        let on_x = self.x0 == 0 || self.x1 as usize + 1 == w;
        let on_y = self.y0 == 0 || self.y1 as usize + 1 == h;
        (on_x && bw < BORDER_KEEP_RATIO * bh) || (on_y && bh < BORDER_KEEP_RATIO * bw)
    }

    fn on_border(&self, h: usize, w: usize) -> bool {
        self.x0 == 0 || self.y0 == 0 || self.x1 as usize + 1 == w || self.y1 as usize + 1 == h
    }

    /// A blob on the border that fails the interior shape filters but is the visible part of a
    /// marker-sized disc: judged on the disc it is part of (its radius from the blob's extent
    /// along and across the border), so slivers pass while shading and edges along the border
    /// (long and thin: a huge disc) or large dark corners do not.
    fn is_cut_marker(
        &self,
        h: usize,
        w: usize,
        r_typ: f32,
        max_area: usize,
        min_fill: f32,
    ) -> bool {
        let on_x = self.x0 == 0 || self.x1 as usize + 1 == w;
        let on_y = self.y0 == 0 || self.y1 as usize + 1 == h;
        let spans = (self.x0 == 0 && self.x1 as usize + 1 == w)
            || (self.y0 == 0 && self.y1 as usize + 1 == h);
        if !(on_x || on_y) || spans || self.area < CUT_MIN_PIXELS || self.area as usize > max_area {
            return false;
        }
        let (bw, bh) = (
            (self.x1 - self.x0 + 1) as f32,
            (self.y1 - self.y0 + 1) as f32,
        );
        // Disc through a chord of length `along` at depth `across` (the sagitta); a blob at
        // least half as deep as it is long shows the whole diameter along the border.
        let disc_radius = |along: f32, across: f32| {
            if across >= 0.5 * along {
                0.5 * along
            } else {
                (across * across + 0.25 * along * along) / (2.0 * across)
            }
        };
        let radius = match (on_x, on_y) {
            (true, false) => disc_radius(bh, bw),
            (false, true) => disc_radius(bw, bh),
            // In a corner both extents are at most a diameter.
            _ => 0.5 * bw.max(bh),
        };
        let fill = self.area as f32 / (bw * bh);
        (CUT_RADIUS_MIN * r_typ..=CUT_RADIUS_MAX * r_typ).contains(&radius) && fill >= min_fill
    }

    fn passes(&self, min_area: usize, max_area: usize, min_fill: f32, max_aspect: f32) -> bool {
        let area = self.area as usize;
        if area < min_area || area > max_area {
            return false;
        }
        let (bw, bh) = (
            (self.x1 - self.x0 + 1) as f32,
            (self.y1 - self.y0 + 1) as f32,
        );
        let fill = self.area as f32 / (bw * bh);
        fill >= min_fill && bw.max(bh) / bw.min(bh) <= max_aspect
    }
}

/// Default smallest marker area: [`MIN_AREA_FRAME_FRACTION`] of the frame, capped at
/// [`MIN_AREA_TYPICAL_FRACTION`] of the typical marker-shaped blob (area-weighted median over
/// interior blobs of at least [`MIN_AREA_FLOOR`] pixels passing the fill and aspect filters,
/// so a few large markers outweigh many specks).
fn default_min_area(
    comps: &[Component],
    h: usize,
    w: usize,
    max_area: usize,
    min_fill: f32,
    max_aspect: f32,
) -> usize {
    let by_frame =
        ((MIN_AREA_FRAME_FRACTION * (h * w) as f64).round() as usize).max(MIN_AREA_FLOOR);
    let mut areas: Vec<u32> = comps
        .iter()
        .filter(|c| !c.on_border(h, w) && c.passes(MIN_AREA_FLOOR, max_area, min_fill, max_aspect))
        .map(|c| c.area)
        .collect();
    if areas.is_empty() {
        return by_frame;
    }
    areas.sort_unstable();
    let total: u64 = areas.iter().map(|&a| u64::from(a)).sum();
    let mut acc = 0u64;
    let mut typical = areas[areas.len() - 1];
    for &a in &areas {
        acc += u64::from(a);
        if 2 * acc >= total {
            typical = a;
            break;
        }
    }
    let by_blobs = (MIN_AREA_TYPICAL_FRACTION * typical as f32).round() as usize;
    by_frame.min(by_blobs.max(MIN_AREA_FLOOR))
}

/// Median area of the kept markers that do not touch the border, if there are enough of them.
fn typical_interior_area(comps: &[Component], keep: &[bool], h: usize, w: usize) -> Option<f32> {
    let mut interior: Vec<f32> = comps
        .iter()
        .zip(keep.iter())
        .filter(|(c, &k)| k && !c.on_border(h, w))
        .map(|(c, _)| c.area as f32)
        .collect();
    if interior.len() >= MIN_INTERIOR_FOR_AREA_RULE {
        crate::geometry::median(&mut interior)
    } else {
        None
    }
}

/// Drops markers whose centre lies outside the frame: on the border with less than
/// [`BORDER_MIN_AREA_FRACTION`] of the typical interior marker area visible, or — with too few
/// interior markers to compare against — visibly cut across the border.
fn drop_border_cut(
    comps: &[Component],
    keep: &mut [bool],
    h: usize,
    w: usize,
    typical_area: Option<f32>,
) {
    for (c, k) in comps.iter().zip(keep.iter_mut()) {
        if !*k || !c.on_border(h, w) {
            continue;
        }
        *k = match typical_area {
            Some(a) => c.area as f32 >= BORDER_MIN_AREA_FRACTION * a,
            None => !c.cut_by_border(h, w),
        };
    }
}

/// Whether a centre `(x, y)` lies outside the pixel-centre span of the frame, `[0, w - 1] x
/// [0, h - 1]` (a marker centred there is at least half cut off).
fn centre_outside(centre: &[f32; 2], h: usize, w: usize) -> bool {
    let (x, y) = (centre[0], centre[1]);
    !(x >= 0.0 && y >= 0.0 && x <= (w - 1) as f32 && y <= (h - 1) as f32)
}

/// A marker cut by the border has its visible part's centroid pulled inward. Along each cut axis,
/// place the centre one marker radius in from the far (uncut) edge instead; the radius is that of
/// a typical interior marker, or half the blob's extent along the border.
fn complete_cut_centre(
    marker: &mut Marker,
    c: &Component,
    h: usize,
    w: usize,
    typical_area: Option<f32>,
) {
    let (bw, bh) = ((c.x1 - c.x0 + 1) as f32, (c.y1 - c.y0 + 1) as f32);
    let radius = |along: f32| match typical_area {
        Some(a) => (a / std::f32::consts::PI).sqrt(),
        None => 0.5 * along,
    };
    let (left, right) = (c.x0 == 0, c.x1 as usize + 1 == w);
    if (left != right) && bw < CUT_RATIO * bh {
        let r = radius(bh);
        marker.centre[0] = if left {
            c.x1 as f32 + 0.5 - r
        } else {
            c.x0 as f32 - 0.5 + r
        };
    }
    let (top, bottom) = (c.y0 == 0, c.y1 as usize + 1 == h);
    if (top != bottom) && bh < CUT_RATIO * bw {
        let r = radius(bw);
        marker.centre[1] = if top {
            c.y1 as f32 + 0.5 - r
        } else {
            c.y0 as f32 - 0.5 + r
        };
    }
}

fn component_stats(runs: &[Run], n: usize) -> Vec<Component> {
    let mut comps = vec![
        Component {
            area: 0,
            x0: u32::MAX,
            y0: u32::MAX,
            x1: 0,
            y1: 0,
        };
        n
    ];
    for r in runs {
        let c = &mut comps[r.label as usize];
        c.area += r.x1 - r.x0;
        c.x0 = c.x0.min(r.x0);
        c.x1 = c.x1.max(r.x1 - 1);
        c.y0 = c.y0.min(r.y);
        c.y1 = c.y1.max(r.y);
    }
    comps
}

/// Local background from a ring around the box, then a darkness-weighted centre over the marker
/// and a one-pixel margin (soft edges below the threshold still pull the centre). Also returns
/// the marker's peak darkness below that ring, in luma units.
#[allow(clippy::too_many_arguments)]
fn refine_marker(
    c: &Component,
    label: u32,
    luma: &[u16],
    labels: &[u32],
    h: usize,
    w: usize,
    sigma_units: f32,
    ring: &mut Vec<u16>,
) -> (Marker, f32) {
    // The median of the ring: robust to neighbouring markers' soft edges and to bright features
    // the ring happens to cross.
    let gap = RING_GAP as i64;
    let (rx0, ry0) = (c.x0 as i64 - gap, c.y0 as i64 - gap);
    let (rx1, ry1) = (c.x1 as i64 + gap, c.y1 as i64 + gap);
    ring.clear();
    let mut add_ring = |x: i64, y: i64| {
        if x >= 0 && y >= 0 && (x as usize) < w && (y as usize) < h {
            let i = y as usize * w + x as usize;
            if labels[i] == 0 {
                ring.push(luma[i]);
            }
        }
    };
    for x in rx0..=rx1 {
        add_ring(x, ry0);
        add_ring(x, ry1);
    }
    for y in ry0 + 1..ry1 {
        add_ring(rx0, y);
        add_ring(rx1, y);
    }
    let ring_median = if ring.is_empty() {
        None
    } else {
        let mid = ring.len() / 2;
        Some(i32::from(*ring.select_nth_unstable(mid).1))
    };

    // One pass over the box grown by a pixel: own minimum and sum, and the darkness-weighted
    // centroid in exact integers. Pixels of other markers weigh nothing.
    let x_lo = c.x0.saturating_sub(1) as usize;
    let y_lo = c.y0.saturating_sub(1) as usize;
    let x_hi = (c.x1 as usize + 1).min(w - 1);
    let y_hi = (c.y1 as usize + 1).min(h - 1);
    // Fully surrounded by other markers or the border: the box's brightest pixel stands in.
    let background = ring_median.unwrap_or_else(|| {
        (y_lo..=y_hi)
            .flat_map(|y| luma[y * w + x_lo..=y * w + x_hi].iter())
            .map(|&v| i32::from(v))
            .max()
            .unwrap_or(0)
    });
    let cut = background - (CENTROID_NOISE_SIGMAS * sigma_units) as i32;
    let (mut sw, mut sx, mut sy) = (0i64, 0i64, 0i64);
    let mut min_luma = u16::MAX;
    for y in y_lo..=y_hi {
        let lrow = &luma[y * w + x_lo..=y * w + x_hi];
        let labrow = &labels[y * w + x_lo..=y * w + x_hi];
        let (rw, rx, row_min) = centroid_row(lrow, labrow, label, cut);
        min_luma = min_luma.min(row_min);
        sw += rw;
        sx += rx + rw * x_lo as i64;
        sy += rw * y as i64;
    }
    let centre = if sw > 0 {
        [
            (sx as f64 / sw as f64) as f32,
            (sy as f64 / sw as f64) as f32,
        ]
    } else {
        [0.5 * (c.x0 + c.x1) as f32, 0.5 * (c.y0 + c.y1) as f32]
    };
    let background = background as f32;
    let contrast = if background > 0.0 {
        (1.0 - f32::from(min_luma) / background).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let marker = Marker {
        centre,
        area: c.area,
        bbox: [c.x0, c.y0, c.x1 - c.x0 + 1, c.y1 - c.y0 + 1],
        contrast,
    };
    (marker, background - f32::from(min_luma))
}

/// Rows up to this wide accumulate in i32 (weights < 2^12, sum of offsets < 2^17).
const CENTROID_I32_MAX_WIDTH: usize = 512;

multiversion! {
    /// One row of the centroid: sum of weights, sum of weight x offset (from the row start), and
    /// the row's minimum over the marker's own pixels. Weights are darkness below `cut` in
    /// 1/16 grey level, on own and unlabelled pixels only.
    fn centroid_row(lrow: &[u16], labrow: &[u32], label: u32, cut: i32) -> (i64, i64, u16) {
        let mut row_min = u16::MAX;
        if lrow.len() <= CENTROID_I32_MAX_WIDTH {
            let (mut rw, mut rx) = (0i32, 0i32);
            for (k, (&l, &v)) in labrow.iter().zip(lrow).enumerate() {
                let own = l == label;
                row_min = row_min.min(if own { v } else { u16::MAX });
                let wgt = ((cut - i32::from(v)).max(0) >> 4) * i32::from(own || l == 0);
                rw += wgt;
                rx += wgt * k as i32;
            }
            return (i64::from(rw), i64::from(rx), row_min);
        }
        let (mut rw, mut rx) = (0i64, 0i64);
        for (k, (&l, &v)) in labrow.iter().zip(lrow).enumerate() {
            let own = l == label;
            row_min = row_min.min(if own { v } else { u16::MAX });
            let wgt = i64::from(((cut - i32::from(v)).max(0) >> 4) * i32::from(own || l == 0));
            rw += wgt;
            rx += wgt * k as i64;
        }
        (rw, rx, row_min)
    }
}

/// `iterations` dilations by a 3x3 cross, stopping early once the mask no longer changes (empty,
/// full, or grown over every pixel it can reach): at most `H + W` passes whatever is asked.
pub fn dilate_cross_n(mut mask: Vec<bool>, h: usize, w: usize, iterations: usize) -> Vec<bool> {
    for _ in 0..iterations.min(h + w) {
        let next = dilate_cross(&mask, h, w);
        if next == mask {
            break;
        }
        mask = next;
    }
    mask
}

/// One dilation by a 3x3 cross (`cv2.dilate` with the 3x3 `MORPH_ELLIPSE` kernel, border ignored).
pub fn dilate_cross(mask: &[bool], h: usize, w: usize) -> Vec<bool> {
    let mut out = mask.to_vec();
    for y in 0..h {
        let row = &mask[y * w..][..w];
        let orow = &mut out[y * w..][..w];
        for x in 0..w {
            let mut v = row[x];
            if x > 0 {
                v |= row[x - 1];
            }
            if x + 1 < w {
                v |= row[x + 1];
            }
            orow[x] = v;
        }
        if y > 0 {
            let up = &mask[(y - 1) * w..][..w];
            for (o, &u) in orow.iter_mut().zip(up) {
                *o |= u;
            }
        }
        if y + 1 < h {
            let down = &mask[(y + 1) * w..][..w];
            for (o, &d) in orow.iter_mut().zip(down) {
                *o |= d;
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Renders anti-aliased dark discs (supersampled 8x8) on a flat background, grey.
    fn render(h: usize, w: usize, centres: &[[f32; 2]], radius: f32, bg: f32, fg: f32) -> Vec<u8> {
        let mut img = vec![bg.round() as u8; h * w];
        for c in centres {
            let x0 = (c[0] - radius - 1.0).floor().max(0.0) as usize;
            let x1 = ((c[0] + radius + 1.0).ceil() as usize).min(w - 1);
            let y0 = (c[1] - radius - 1.0).floor().max(0.0) as usize;
            let y1 = ((c[1] + radius + 1.0).ceil() as usize).min(h - 1);
            for y in y0..=y1 {
                for x in x0..=x1 {
                    let mut cover = 0.0;
                    for sy in 0..8 {
                        for sx in 0..8 {
                            let px = x as f32 - 0.5 + (sx as f32 + 0.5) / 8.0;
                            let py = y as f32 - 0.5 + (sy as f32 + 0.5) / 8.0;
                            if (px - c[0]).powi(2) + (py - c[1]).powi(2) <= radius * radius {
                                cover += 1.0 / 64.0;
                            }
                        }
                    }
                    let v = bg + (fg - bg) * cover;
                    img[y * w + x] = v.round() as u8;
                }
            }
        }
        img
    }

    #[test]
    fn finds_discs_with_subpixel_centres() {
        let mut centres = Vec::new();
        for j in 0..6 {
            for i in 0..8 {
                centres.push([
                    40.0 + i as f32 * 80.0 + 0.37 * j as f32,
                    40.0 + j as f32 * 80.0 + 0.21 * i as f32,
                ]);
            }
        }
        let img = render(480, 640, &centres, 11.5, 180.0, 40.0);
        let view = ImageView::new(&img, 480, 640, 1, "img").unwrap();
        let ex = extract_markers(&view, &ExtractParams::default()).unwrap();
        assert_eq!(ex.markers.len(), 48);
        for c in &centres {
            let best = ex
                .markers
                .iter()
                .map(|m| crate::geometry::dist2(m.centre, *c).sqrt())
                .fold(f32::MAX, f32::min);
            assert!(best < 0.1, "centre error {best}");
        }
    }

    #[test]
    fn flat_and_markerless_images_give_nothing() {
        for v in [0u8, 128, 255] {
            let img = vec![v; 120 * 160];
            let view = ImageView::new(&img, 120, 160, 1, "img").unwrap();
            let ex = extract_markers(&view, &ExtractParams::default()).unwrap();
            assert!(ex.markers.is_empty());
            assert!(ex.mask.iter().all(|&m| !m));
        }
    }

    #[test]
    fn bright_polarity_finds_bright_dots() {
        let img = render(200, 200, &[[50.0, 50.0], [150.3, 120.6]], 6.0, 40.0, 220.0);
        let view = ImageView::new(&img, 200, 200, 1, "img").unwrap();
        let dark = extract_markers(&view, &ExtractParams::default()).unwrap();
        assert!(dark.markers.is_empty());
        let params = ExtractParams {
            polarity: Polarity::Bright,
            ..Default::default()
        };
        let bright = extract_markers(&view, &params).unwrap();
        assert_eq!(bright.markers.len(), 2);
        assert!((bright.markers[1].centre[0] - 150.3).abs() < 0.1);
    }

    #[test]
    fn border_cut_markers_dropped_grazing_kept() {
        // Left: centre 2 px outside the image (cut in half). Right: grazes the border by 1 px.
        let img = render(
            100,
            100,
            &[[-2.0, 30.0], [93.5, 60.0], [50.0, 50.0]],
            6.0,
            200.0,
            40.0,
        );
        let view = ImageView::new(&img, 100, 100, 1, "img").unwrap();
        let ex = extract_markers(&view, &ExtractParams::default()).unwrap();
        assert_eq!(ex.markers.len(), 2);
        assert!(ex.markers.iter().all(|m| m.centre[0] > 40.0));
        let keep_all = ExtractParams {
            exclude_border: false,
            ..Default::default()
        };
        assert_eq!(extract_markers(&view, &keep_all).unwrap().markers.len(), 3);
    }

    #[test]
    fn slivers_on_every_border_are_masked_not_reported() {
        // Centres outside the frame on each border (deep cuts: slivers), plus an interior grid.
        let mut centres = vec![[-3.0, 60.0], [163.0, 100.0], [100.0, -3.5], [60.0, 163.0]];
        for j in 0..3 {
            for i in 0..3 {
                centres.push([40.0 + 40.0 * i as f32, 40.0 + 40.0 * j as f32]);
            }
        }
        let img = render(160, 160, &centres, 5.0, 200.0, 30.0);
        let view = ImageView::new(&img, 160, 160, 1, "img").unwrap();
        for grow in [MaskGrowth::Dilate(0), MaskGrowth::Adaptive] {
            let params = ExtractParams {
                grow,
                ..Default::default()
            };
            let ex = extract_markers(&view, &params).unwrap();
            assert_eq!(ex.markers.len(), 9);
            for (i, &v) in img.iter().enumerate() {
                assert!(
                    v > 100 || ex.mask[i],
                    "dark pixel {i} outside the mask, {grow:?}"
                );
            }
        }
        let all = ExtractParams {
            exclude_border: false,
            ..Default::default()
        };
        assert_eq!(extract_markers(&view, &all).unwrap().markers.len(), 13);
    }

    #[test]
    fn adaptive_growth_on_crisp_discs_is_one_ring() {
        let centres: Vec<[f32; 2]> = (0..4)
            .flat_map(|j| (0..5).map(move |i| [30.3 + 35.0 * i as f32, 30.6 + 35.0 * j as f32]))
            .collect();
        let img = render(160, 200, &centres, 5.0, 180.0, 40.0);
        let view = ImageView::new(&img, 160, 200, 1, "img").unwrap();
        let params = ExtractParams {
            grow: MaskGrowth::Adaptive,
            ..Default::default()
        };
        let ex = extract_markers(&view, &params).unwrap();
        assert_eq!(ex.markers.len(), 20);
        assert!(ex.grow_rings.iter().all(|&r| r <= 1), "{:?}", ex.grow_rings);
        // Every pixel a disc touches is inside.
        assert!(img.iter().zip(&ex.mask).all(|(&v, &m)| v >= 180 || m));
    }

    #[test]
    fn dilation_stops_once_the_mask_is_full() {
        let mut mask = vec![false; 6 * 9];
        mask[0] = true;
        let full = dilate_cross_n(mask.clone(), 6, 9, usize::MAX);
        assert!(full.iter().all(|&m| m));
        assert!(!dilate_cross_n(mask, 6, 9, 12).iter().all(|&m| m));
        assert!(dilate_cross_n(vec![false; 54], 6, 9, usize::MAX)
            .iter()
            .all(|&m| !m));
    }

    #[test]
    fn a_reused_workspace_gives_what_a_fresh_one_gives() {
        // Buffers are resized without zero-filling when the size is unchanged: stale contents
        // of an earlier frame (other size, channels, polarity, content) must not leak.
        let mut ws = ExtractWorkspace::default();
        let cases: [(usize, usize, f32, f32, usize, Polarity); 6] = [
            (120, 160, 5.0, 30.0, 3, Polarity::Dark),
            (120, 160, 4.0, 60.0, 3, Polarity::Dark),
            (97, 131, 3.5, 40.0, 1, Polarity::Dark),
            (120, 160, 6.0, 220.0, 4, Polarity::Bright),
            (5, 3, 1.0, 20.0, 1, Polarity::Dark),
            (120, 160, 5.0, 30.0, 3, Polarity::Dark),
        ];
        for (k, &(h, w, radius, fg, channels, polarity)) in cases.iter().enumerate() {
            let centres: Vec<[f32; 2]> = (0..4)
                .flat_map(|j| {
                    (0..5).map(move |i| [15.3 + 30.0 * i as f32 + k as f32, 14.6 + 28.0 * j as f32])
                })
                .collect();
            let grey = render(h, w, &centres, radius, 128.0 + 10.0 * k as f32, fg);
            let img: Vec<u8> = grey
                .iter()
                .flat_map(|&v| std::iter::repeat(v).take(channels))
                .collect();
            let view = ImageView::new(&img, h, w, channels, "img").unwrap();
            for grow in [MaskGrowth::Dilate(1), MaskGrowth::Adaptive] {
                let params = ExtractParams {
                    polarity,
                    grow,
                    ..Default::default()
                };
                let fresh = extract_markers(&view, &params).unwrap();
                for want_mask in [true, false] {
                    let reused = extract_markers_with(&view, &params, &mut ws, want_mask).unwrap();
                    assert_eq!(reused.markers, fresh.markers, "case {k}");
                    assert_eq!(reused.threshold, fresh.threshold, "case {k}");
                    assert_eq!(reused.n_components, fresh.n_components, "case {k}");
                    if want_mask {
                        assert_eq!(reused.mask, fresh.mask, "case {k}");
                        assert_eq!(reused.grow_rings, fresh.grow_rings, "case {k}");
                    }
                }
            }
        }
    }

    #[test]
    fn tiny_images_do_not_panic() {
        for (h, w) in [(1, 1), (1, 7), (5, 1), (2, 2), (3, 40)] {
            let img = vec![7u8; h * w * 3];
            let view = ImageView::new(&img, h, w, 3, "img").unwrap();
            let ex = extract_markers(&view, &ExtractParams::default()).unwrap();
            assert_eq!(ex.mask.len(), h * w);
        }
    }

    #[test]
    fn luma_limit_is_the_darkness_test() {
        // `l < luma_limit(m, t)` exactly when `darkness(m, l) > t`, near the boundary and at
        // the extremes of luma, background and threshold.
        let ts = [
            -16320i16, -5, -1, 0, 1, 2, 3, 63, 64, 640, 8000, 16319, 16320,
        ];
        for m in (0..=65280u16).step_by(251).chain([65279, 65280]) {
            for &t in &ts {
                let edge = i32::from(m) - 4 * i32::from(t) - 3;
                let near = (edge - 9..=edge + 9).filter(|l| (0..=65280).contains(l));
                for l in near.chain([0, 1, 65279, 65280]) {
                    let l = l as u16;
                    assert_eq!(
                        l < luma_limit(m, t),
                        darkness(m, l) > t,
                        "m {m} t {t} l {l}"
                    );
                }
            }
        }
    }

    #[test]
    fn run_scan_matches_a_pixel_by_pixel_scan() {
        // Runs that start, end or continue at chunk edges, whole chunks inside a run, rows
        // narrower than a chunk and a partial last chunk: the runs are those of a plain scan.
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        for w in [1usize, 5, 15, 16, 17, 31, 32, 33, 47, 63, 64, 65, 640] {
            for density in [0u64, 1, 4, 8, 12, 15, 16] {
                let luma: Vec<u16> = (0..w).map(|_| (next() % 16 < density) as u16).collect();
                let limit = vec![1u16; w];
                let mut l = RunLabeller::default();
                l.push_row(&luma, &limit, 0);
                let got: Vec<(u32, u32)> = l.runs.iter().map(|r| (r.x0, r.x1)).collect();
                let mut want = Vec::new();
                let mut x = 0;
                while x < w {
                    if luma[x] < 1 {
                        let x0 = x;
                        while x < w && luma[x] < 1 {
                            x += 1;
                        }
                        want.push((x0 as u32, x as u32));
                    } else {
                        x += 1;
                    }
                }
                assert_eq!(got, want, "w {w} density {density}");
            }
        }
    }

    #[test]
    fn labelling_is_8_connected() {
        // Two pixels touching diagonally form one component.
        let mut dark = vec![0i16; 9];
        dark[0] = 100;
        dark[4] = 100;
        dark[8] = 100;
        // Darkness as luma under a flat background of 200 grey levels.
        let count = |dark: &[i16]| {
            let (m, t) = (200 * 256, 10);
            let luma: Vec<u16> = dark.iter().map(|&d| m - 4 * d as u16).collect();
            let limit = vec![luma_limit(m, t); 3];
            let mut l = RunLabeller::default();
            for (y, row) in luma.chunks_exact(3).enumerate() {
                l.push_row(row, &limit, y);
            }
            l.finish()
        };
        assert_eq!(count(&dark), 1);
        dark[4] = 0;
        assert_eq!(count(&dark), 2);
    }

    #[test]
    fn reflect101_matches_opencv_rule() {
        assert_eq!(reflect101(-1, 5), 1);
        assert_eq!(reflect101(-2, 5), 2);
        assert_eq!(reflect101(5, 5), 3);
        assert_eq!(reflect101(6, 5), 2);
        assert_eq!(reflect101(0, 1), 0);
    }

    #[test]
    fn rejects_bad_parameters() {
        let img = vec![0u8; 100];
        let view = ImageView::new(&img, 10, 10, 1, "img").unwrap();
        let bad = ExtractParams {
            block_size: Some(4),
            ..Default::default()
        };
        let err = extract_markers(&view, &bad).unwrap_err();
        assert!(err.to_string().contains("block_size"));
        let view2 = ImageView::new(&img, 10, 5, 2, "img").unwrap();
        assert!(extract_markers(&view2, &ExtractParams::default()).is_err());
    }
}

#[cfg(test)]
mod profile {
    use super::*;
    use std::time::Instant;

    /// `cargo test --release -p tacswitch-core profile_stages -- --ignored --nocapture`
    #[test]
    #[ignore]
    fn profile_stages() {
        let (h, w) = (480usize, 640usize);
        let mut img = vec![180u8; h * w * 3];
        for j in 0..6 {
            for i in 0..8 {
                let (cx, cy) = (40 + 80 * i, 40 + 80 * j);
                for y in cy - 11..=cy + 11 {
                    for x in cx - 11..=cx + 11 {
                        if (x - cx) * (x - cx) + (y - cy) * (y - cy) <= 121 {
                            img[(y * w + x) * 3..][..3].fill(40);
                        }
                    }
                }
            }
        }
        let view = ImageView::new(&img, h, w, 3, "img").unwrap();
        let mut ws = ExtractWorkspace::default();
        let p = ExtractParams::default();
        let reps = 200;
        let time = |name: &str, f: &mut dyn FnMut()| {
            f();
            let t = Instant::now();
            for _ in 0..reps {
                f();
            }
            println!(
                "{name}: {:.1} us",
                t.elapsed().as_secs_f64() * 1e6 / reps as f64
            );
        };
        let mut bg = luma_and_background(&view, Polarity::Dark, 61, &mut ws.luma, &mut ws.boxes);
        time("luma and background", &mut || {
            bg = luma_and_background(&view, Polarity::Dark, 61, &mut ws.luma, &mut ws.boxes);
        });
        let mut hist = [0u32; HIST_BINS];
        time("histogram", &mut || {
            hist = darkness_histogram(&ws.luma, &ws.boxes.mean, bg);
        });
        let st = HistStats::from_hist(&hist);
        let tu = (auto_threshold(&hist, &st) * 64.0) as i16;
        time("label", &mut || {
            label_image(
                &ws.luma,
                &ws.boxes.mean,
                bg,
                tu,
                &mut ws.limits,
                &mut ws.boxes.row,
                &mut ws.labeller,
            );
        });
        time("all", &mut || {
            extract_markers_with(&view, &p, &mut ws, false).unwrap();
        });
    }
}
