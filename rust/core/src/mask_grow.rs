//! Adaptive marker masks: each marker's mask grows ring by ring until the ring just outside it
//! is consistent with the gel around it.
//!
//! A threshold mask follows a marker's dark core. Real markers darken more than that: soft paint
//! edges, optical blur, and the ringing of lossy codecs (H.264, MJPEG) around high-contrast dots
//! leave a rim a few grey levels dark (or bright) that an inpainting fill smears inward. How wide
//! that rim is depends on the sensor, the codec and the marker, so no fixed dilation fits: on
//! crisp lossless markers one pixel is right, on compressed ones five or more.
//!
//! Per marker (one window around it, single thread):
//! 1. a chamfer (3-4) distance from the marker's thresholded pixels; ring `k` holds the pixels at
//!    distance `(k - 1, k]` (ring 1 = the 4-neighbours, i.e. one 3x3-cross dilation);
//! 2. the local noise sigma: the robust spread (MAD) of the luma around a plane fitted (least
//!    squares, two outlier-rejecting passes) to an annulus of [`ANNULUS_RINGS`] rings just
//!    beyond the largest growth allowed;
//! 3. ring `k` is part of the rim while its mean luma differs by more than [`GROW_SIGMAS`] noise
//!    sigmas from the local background just outside it: the least-squares plane through rings
//!    `k + 1 ..= k + ANNULUS_RINGS` (other markers' pixels excluded), so that contact shading (a
//!    gradient, or curvature over a few pixels) is not mistaken for darkening. The mask takes
//!    every ring up to the last one that differs, stopping after two consistent rings in a row
//!    (codec ringing alternates dark and bright, so one consistent ring does not end the rim);
//!    where the background is curved (one of the two outermost allowed rings already fails that
//!    test: contact shading, the imprint's edge), a ring must also differ from the next ring's
//!    darkness: a rim fades ring by ring, smooth shading curvature gives about the same
//!    darkness on successive rings (without this, contact markers grew to the cap);
//! 4. growth is capped at [`MAX_GROW_RADII`] marker radii and at half the gap to the nearest
//!    other marker, so neighbouring markers and contact shading cannot make it run away.

/// Rings (pixels) the local background just outside a ring is fitted on (and of the outer
/// annulus the noise is measured on).
pub const ANNULUS_RINGS: usize = 2;
/// A ring belongs to the marker while its mean luma differs from the local background just
/// outside it by more than this many local noise sigmas (per-pixel sigma of the outer annulus
/// around its plane)...
pub const GROW_SIGMAS: f32 = 0.25;
/// ...and by more than this many grey levels (noise-free synthetic frames).
pub const GROW_MIN_LEVELS: f32 = 0.5;
/// Largest growth, in marker radii (equivalent-disc radius of the thresholded blob).
pub const MAX_GROW_RADII: f32 = 1.5;
/// Growth never exceeds this many rings, whatever the marker size.
pub const MAX_GROW_RINGS: usize = 48;
/// Smallest cap (rings) for which a curved background is looked for (two outer rings tested
/// and at least one ring left to grow).
const CURVED_MIN_CAP: usize = 3;
/// Consistent rings in a row that end the growth.
const STOP_AFTER_CONSISTENT: usize = 2;
/// Chamfer 3-4 weights: an orthogonal step is 3 units (one pixel), a diagonal 4.
const STEP_ORTHO: u8 = 3;
const STEP_DIAG: u8 = 4;
// Every distance that matters (the annulus' outer edge) fits in the u8 distance map.
const _: () = assert!((MAX_GROW_RINGS + ANNULUS_RINGS + 1) * (STEP_ORTHO as usize) < 255);
/// Fewest annulus pixels for a plane fit; fewer use their median as a flat background.
const MIN_PLANE_PIXELS: usize = 12;
/// Outliers beyond this many sigmas (neighbours' soft edges, bright features) leave the fit.
const FIT_CLIP_SIGMAS: f32 = 3.0;
/// MAD to sigma for a normal distribution.
const MAD_TO_SIGMA: f32 = 1.4826;
/// Luma units per grey level (the extraction's fixed point).
const LUMA_PER_LEVEL: f32 = 256.0;

/// One marker to grow: its label in the label image and its geometry.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GrowSeed {
    /// Label of the marker's pixels in the label image (non-zero).
    pub label: u32,
    /// Inclusive bounding box `(x0, y0, x1, y1)` of the thresholded pixels.
    pub bbox: [u32; 4],
    /// Centre `(x, y)`, pixels (may lie outside the frame for a marker cut by the border).
    pub centre: [f32; 2],
    /// Radius of the full marker, pixels (equivalent disc of the thresholded blob).
    pub radius: f32,
}

/// Reusable buffers of [`grow_masks`].
#[derive(Debug, Default, Clone)]
pub struct GrowWorkspace {
    dist: Vec<u8>,
    annulus: Vec<[f32; 3]>,
    scratch: Vec<f32>,
    sums_int: Vec<RingSumsInt>,
    sums: Vec<RingSums>,
}

/// Grows every seed's mask into `mask` (`h x w`, row-major; pixels are only ever set).
///
/// `luma` is the extraction's luma (grey x 256, markers dark), `labels` its label image (0 =
/// no component). Returns the rings added around each seed (0 = the thresholded pixels only).
pub fn grow_masks(
    luma: &[u16],
    labels: &[u32],
    h: usize,
    w: usize,
    seeds: &[GrowSeed],
    mask: &mut [bool],
    ws: &mut GrowWorkspace,
) -> Vec<u16> {
    let gaps = nearest_gaps(seeds);
    seeds
        .iter()
        .zip(gaps)
        .map(|(s, gap)| {
            let by_size = (MAX_GROW_RADII * s.radius).ceil().max(1.0) as usize;
            // Half the free gap to the nearest marker's edge: two markers' rims never overlap
            // and neither annulus reaches into the other's thresholded pixels.
            let by_gap = (0.5 * gap).floor().max(1.0) as usize;
            let cap = by_size.min(by_gap).min(MAX_GROW_RINGS);
            grow_one(luma, labels, h, w, s, cap, mask, ws) as u16
        })
        .collect()
}

/// Free distance from each seed's edge to the nearest other seed's edge (pixels; infinite when
/// alone), by a sweep over seeds sorted by x in both directions from each seed.
fn nearest_gaps(seeds: &[GrowSeed]) -> Vec<f32> {
    let mut order: Vec<usize> = (0..seeds.len()).collect();
    order.sort_by(|&a, &b| seeds[a].centre[0].total_cmp(&seeds[b].centre[0]));
    let mut out = vec![f32::INFINITY; seeds.len()];
    for (k, &i) in order.iter().enumerate() {
        let a = seeds[i].centre;
        let mut best = f32::INFINITY;
        let mut visit = |j: usize| {
            let b = seeds[j].centre;
            let dx = b[0] - a[0];
            // Sorted by x: once dx alone is as far as the best, nothing further can be nearer.
            if dx * dx >= best {
                return false;
            }
            best = best.min(dx * dx + (b[1] - a[1]) * (b[1] - a[1]));
            true
        };
        for &j in &order[k + 1..] {
            if !visit(j) {
                break;
            }
        }
        for &j in order[..k].iter().rev() {
            if !visit(j) {
                break;
            }
        }
        if best.is_finite() {
            out[i] = (best.sqrt() - 2.0 * seeds[i].radius).max(0.0);
        }
    }
    out
}

/// Per-ring moments over free pixels (not part of any component), in window coordinates `x`,
/// `y` and luma `z`: enough for a least-squares plane through any run of rings, and for a
/// plane's mean over a ring, without another pass over the pixels.
#[derive(Debug, Default, Clone, Copy)]
struct RingSums {
    n: f64,
    x: f64,
    y: f64,
    z: f64,
    xx: f64,
    xy: f64,
    yy: f64,
    xz: f64,
    yz: f64,
}

/// [`RingSums`] accumulated per pixel in integers (exact and cheaper than floats): window
/// coordinates are below 2^16 and luma below 2^16, so every sum of a window fits in u64.
#[derive(Debug, Default, Clone, Copy)]
struct RingSumsInt {
    n: u64,
    x: u64,
    y: u64,
    z: u64,
    xx: u64,
    xy: u64,
    yy: u64,
    xz: u64,
    yz: u64,
}

impl RingSumsInt {
    fn to_f64(self) -> RingSums {
        RingSums {
            n: self.n as f64,
            x: self.x as f64,
            y: self.y as f64,
            z: self.z as f64,
            xx: self.xx as f64,
            xy: self.xy as f64,
            yy: self.yy as f64,
            xz: self.xz as f64,
            yz: self.yz as f64,
        }
    }
}

impl RingSums {
    fn add(&mut self, o: &RingSums) {
        self.n += o.n;
        self.x += o.x;
        self.y += o.y;
        self.z += o.z;
        self.xx += o.xx;
        self.xy += o.xy;
        self.yy += o.yy;
        self.xz += o.xz;
        self.yz += o.yz;
    }

    /// Least-squares plane `z = a + b x + c y`; flat (the mean) when the pixels do not span a
    /// plane (few, or on one line as an annulus cut down to a strip by the frame border).
    fn plane(&self) -> [f64; 3] {
        let flat = [self.z / self.n, 0.0, 0.0];
        if self.n < MIN_PLANE_PIXELS as f64 {
            return flat;
        }
        let m = [
            [self.n, self.x, self.y],
            [self.x, self.xx, self.xy],
            [self.y, self.xy, self.yy],
        ];
        solve3(m, [self.z, self.xz, self.yz]).unwrap_or(flat)
    }

    /// Mean of `plane - z` over these pixels: how much darker than the plane they are.
    fn darkness_below(&self, p: [f64; 3]) -> f64 {
        (p[0] * self.n + p[1] * self.x + p[2] * self.y - self.z) / self.n
    }
}

/// Grows one marker; returns the number of rings added.
#[allow(clippy::too_many_arguments)]
fn grow_one(
    luma: &[u16],
    labels: &[u32],
    h: usize,
    w: usize,
    s: &GrowSeed,
    cap: usize,
    mask: &mut [bool],
    ws: &mut GrowWorkspace,
) -> usize {
    // One ring more than the last background: the curved-background test compares ring `cap`
    // with ring `cap + 1`.
    let margin = cap + ANNULUS_RINGS + 1;
    let x0 = (s.bbox[0] as usize).saturating_sub(margin);
    let y0 = (s.bbox[1] as usize).saturating_sub(margin);
    let x1 = (s.bbox[2] as usize + margin).min(w - 1);
    let y1 = (s.bbox[3] as usize + margin).min(h - 1);
    let (ww, wh) = (x1 - x0 + 1, y1 - y0 + 1);
    chamfer(labels, w, s.label, x0, y0, ww, wh, &mut ws.dist);
    let pw = ww + 2;

    // Ring of each distance, ceil(d / 3); 0 for the marker itself and for anything beyond the
    // outermost annulus (nothing to add there).
    let max_d = margin * usize::from(STEP_ORTHO);
    let mut ring_of = [0u8; 256];
    for (d, r) in ring_of.iter_mut().enumerate().take(max_d + 1) {
        *r = d.div_ceil(usize::from(STEP_ORTHO)) as u8;
    }

    // One pass: per-ring moments, and the pixels of the annulus just beyond the cap for the
    // noise.
    ws.annulus.clear();
    ws.sums_int.clear();
    ws.sums_int.resize(margin + 1, RingSumsInt::default());
    for wy in 0..wh {
        let y = y0 + wy;
        let drow = &ws.dist[(wy + 1) * pw + 1..][..ww];
        let lrow = &luma[y * w + x0..][..ww];
        let labrow = &labels[y * w + x0..][..ww];
        let iy = wy as u64;
        for (wx, ((&d, &z), &l)) in drow.iter().zip(lrow).zip(labrow).enumerate() {
            let r = usize::from(ring_of[usize::from(d)]);
            if r == 0 || l != 0 {
                continue;
            }
            let (ix, iz) = (wx as u64, u64::from(z));
            let e = &mut ws.sums_int[r];
            e.n += 1;
            e.x += ix;
            e.y += iy;
            e.z += iz;
            e.xx += ix * ix;
            e.xy += ix * iy;
            e.yy += iy * iy;
            e.xz += ix * iz;
            e.yz += iy * iz;
            if r > cap && r <= cap + ANNULUS_RINGS {
                ws.annulus.push([wx as f32, wy as f32, z as f32]);
            }
        }
    }
    ws.sums.clear();
    ws.sums.extend(ws.sums_int.iter().map(|e| e.to_f64()));
    // The local noise: robust spread of the outermost annulus around its own plane.
    let Some((_, sigma)) = fit_background(&ws.annulus, &mut ws.scratch) else {
        return 0;
    };
    let tau = f64::from((GROW_SIGMAS * sigma).max(GROW_MIN_LEVELS * LUMA_PER_LEVEL));
    // Mean darkness of ring k below the local background just outside it: the plane through
    // the next ANNULUS_RINGS rings, so contact shading (a gradient) is no darkening. `None`
    // when the ring or its background has no free pixel (other markers, or outside the frame).
    let dark = |k: usize| -> Option<f64> {
        let ring = ws.sums[k];
        let mut beyond = RingSums::default();
        for e in &ws.sums[k + 1..=k + ANNULUS_RINGS] {
            beyond.add(e);
        }
        (ring.n > 0.0 && beyond.n > 0.0).then(|| ring.darkness_below(beyond.plane()))
    };
    // Curved background: one of the two outermost rings the marker may take already fails the
    // plane test, far out where no rim reaches. Contact shading does that (curvature, the
    // imprint's edge over a few pixels): every ring then differs from its plane by about the
    // same amount and growth would run to the cap. There a ring is rim only if it also differs
    // from the next ring's darkness: a rim fades ring by ring, smooth curvature does not.
    let curved =
        cap >= CURVED_MIN_CAP && (cap - 1..=cap).any(|k| dark(k).is_some_and(|d| d.abs() > tau));
    let mut rings = 0;
    let mut consistent = 0;
    for k in 1..=cap {
        let deviates = dark(k).is_some_and(|d| {
            d.abs() > tau && (!curved || (d - dark(k + 1).unwrap_or(0.0)).abs() > tau)
        });
        if deviates {
            rings = k;
            consistent = 0;
        } else {
            consistent += 1;
            if consistent >= STOP_AFTER_CONSISTENT {
                break;
            }
        }
    }

    let limit = rings as u8 * STEP_ORTHO;
    for wy in 0..wh {
        let drow = &ws.dist[(wy + 1) * pw + 1..][..ww];
        let mrow = &mut mask[(y0 + wy) * w + x0..][..ww];
        for (m, &d) in mrow.iter_mut().zip(drow) {
            *m |= d <= limit;
        }
    }
    rings
}

/// Chamfer 3-4 distance (two raster passes) from the pixels labelled `label`, inside the window
/// `(x0, y0, ww, wh)`, into `dist`: `(ww + 2) x (wh + 2)` with a one-pixel frame of `u8::MAX`
/// so the passes need no edge tests. Distances saturate at 255 (85 rings, beyond any window).
#[allow(clippy::too_many_arguments)]
fn chamfer(
    labels: &[u32],
    w: usize,
    label: u32,
    x0: usize,
    y0: usize,
    ww: usize,
    wh: usize,
    dist: &mut Vec<u8>,
) {
    let pw = ww + 2;
    dist.clear();
    dist.resize(pw * (wh + 2), u8::MAX);
    for wy in 0..wh {
        let lrow = &labels[(y0 + wy) * w + x0..][..ww];
        let drow = &mut dist[(wy + 1) * pw + 1..][..ww];
        for (d, &l) in drow.iter_mut().zip(lrow) {
            *d = if l == label { 0 } else { u8::MAX };
        }
    }
    for wy in 1..=wh {
        let (above, rest) = dist.split_at_mut(wy * pw);
        relax_row(&above[(wy - 1) * pw..][..pw], &mut rest[..pw]);
        // The running value stays in a register (no store-to-load round trip per pixel).
        let mut run = u8::MAX;
        for v in rest[1..=ww].iter_mut() {
            run = (*v).min(run.saturating_add(STEP_ORTHO));
            *v = run;
        }
    }
    for wy in (1..=wh).rev() {
        let (head, below) = dist.split_at_mut((wy + 1) * pw);
        let row = &mut head[wy * pw..][..pw];
        relax_row(&below[..pw], row);
        let mut run = u8::MAX;
        for v in row[1..=ww].iter_mut().rev() {
            run = (*v).min(run.saturating_add(STEP_ORTHO));
            *v = run;
        }
    }
}

/// `row[x] = min(row[x], nb[x] + 3, nb[x - 1] + 4, nb[x + 1] + 4)` for the inner pixels, from
/// the neighbouring row `nb` (independent per pixel: vectorises).
#[inline(always)]
fn relax_row(nb: &[u8], row: &mut [u8]) {
    let n = row.len() - 2;
    let inner = &mut row[1..=n];
    for (((r, &c), &l), &rt) in inner.iter_mut().zip(&nb[1..=n]).zip(&nb[..n]).zip(&nb[2..]) {
        let v = c
            .saturating_add(STEP_ORTHO)
            .min(l.saturating_add(STEP_DIAG))
            .min(rt.saturating_add(STEP_DIAG));
        *r = (*r).min(v);
    }
}

/// Robust plane `z = a + b u + c v` through annulus samples `[u, v, z]`, and the per-pixel sigma
/// of its residuals (luma units, at least half a grey level). `None` without samples.
fn fit_background(samples: &[[f32; 3]], scratch: &mut Vec<f32>) -> Option<([f32; 3], f32)> {
    if samples.is_empty() {
        return None;
    }
    let floor = 0.5 * LUMA_PER_LEVEL;
    // Start flat at the median, with the MAD as the spread: robust to a minority of outliers.
    let mut plane = [median_of(samples.iter().map(|s| s[2]), scratch), 0.0, 0.0];
    let mut sigma = residual_sigma(samples, plane, scratch).max(floor);
    if samples.len() < MIN_PLANE_PIXELS {
        return Some((plane, sigma));
    }
    for _ in 0..2 {
        let clip = FIT_CLIP_SIGMAS * sigma;
        match least_squares_plane(samples, plane, clip) {
            Some(p) => plane = p,
            None => break,
        }
        sigma = residual_sigma(samples, plane, scratch).max(floor);
    }
    Some((plane, sigma))
}

fn residual(s: &[f32; 3], p: [f32; 3]) -> f32 {
    s[2] - (p[0] + p[1] * s[0] + p[2] * s[1])
}

fn residual_sigma(samples: &[[f32; 3]], plane: [f32; 3], scratch: &mut Vec<f32>) -> f32 {
    MAD_TO_SIGMA * median_of(samples.iter().map(|s| residual(s, plane).abs()), scratch)
}

fn median_of(values: impl Iterator<Item = f32>, scratch: &mut Vec<f32>) -> f32 {
    scratch.clear();
    scratch.extend(values);
    if scratch.is_empty() {
        return 0.0;
    }
    let mid = scratch.len() / 2;
    *scratch.select_nth_unstable_by(mid, f32::total_cmp).1
}

/// Least-squares plane over the samples within `clip` of `prev`; `None` when they do not span
/// a plane (too few, or on one line, e.g. an annulus reduced to a strip by the frame border).
fn least_squares_plane(samples: &[[f32; 3]], prev: [f32; 3], clip: f32) -> Option<[f32; 3]> {
    let mut m = [[0f64; 3]; 3];
    let mut rhs = [0f64; 3];
    let mut n = 0usize;
    for s in samples.iter().filter(|s| residual(s, prev).abs() <= clip) {
        let row = [1.0, f64::from(s[0]), f64::from(s[1])];
        for i in 0..3 {
            for j in 0..3 {
                m[i][j] += row[i] * row[j];
            }
            rhs[i] += row[i] * f64::from(s[2]);
        }
        n += 1;
    }
    if n < MIN_PLANE_PIXELS {
        return None;
    }
    let sol = solve3(m, rhs)?;
    Some([sol[0] as f32, sol[1] as f32, sol[2] as f32])
}

/// Solves a 3x3 symmetric system by Cramer's rule; `None` when nearly singular.
fn solve3(m: [[f64; 3]; 3], r: [f64; 3]) -> Option<[f64; 3]> {
    let det = |a: &[[f64; 3]; 3]| {
        a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1])
            - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
            + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0])
    };
    let d = det(&m);
    // Relative to the diagonal's scale: samples on one line give a (near) zero determinant.
    let scale = m[0][0] * m[1][1] * m[2][2];
    // NaN (degenerate sums) fails the comparison too.
    if d.abs().partial_cmp(&(1e-9 * scale.abs())) != Some(std::cmp::Ordering::Greater) {
        return None;
    }
    let mut out = [0f64; 3];
    for (k, o) in out.iter_mut().enumerate() {
        let mut a = m;
        for i in 0..3 {
            a[i][k] = r[i];
        }
        *o = det(&a) / d;
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chamfer_rings_start_with_the_cross() {
        // One pixel at (3, 3) of a 7x7 window.
        let mut labels = vec![0u32; 49];
        labels[3 * 7 + 3] = 5;
        let mut dist = Vec::new();
        chamfer(&labels, 7, 5, 0, 0, 7, 7, &mut dist);
        let at = |x: usize, y: usize| dist[(y + 1) * 9 + x + 1];
        assert_eq!(at(3, 3), 0);
        assert_eq!(at(4, 3), 3);
        assert_eq!(at(4, 2), 4);
        assert_eq!(at(6, 3), 9);
        assert_eq!(at(0, 0), 12);
        assert_eq!(at(6, 6), 12);
    }

    #[test]
    fn plane_fit_recovers_a_gradient_despite_outliers() {
        let mut samples = Vec::new();
        for y in -10..=10 {
            for x in -10..=10 {
                let z = 1000.0 + 30.0 * x as f32 - 12.0 * y as f32;
                // A dark blob in one corner, as a neighbour's soft edge would be.
                let z = if x > 6 && y > 6 { z - 5000.0 } else { z };
                samples.push([x as f32, y as f32, z]);
            }
        }
        let mut scratch = Vec::new();
        let (p, sigma) = fit_background(&samples, &mut scratch).unwrap();
        assert!((p[0] - 1000.0).abs() < 1.0, "{p:?}");
        assert!(
            (p[1] - 30.0).abs() < 0.1 && (p[2] + 12.0).abs() < 0.1,
            "{p:?}"
        );
        assert!(sigma <= 0.5 * LUMA_PER_LEVEL + 1.0);
    }

    #[test]
    fn collinear_samples_fall_back_to_flat() {
        let samples: Vec<[f32; 3]> = (0..30).map(|i| [i as f32, 0.0, 500.0]).collect();
        let mut scratch = Vec::new();
        let (p, _) = fit_background(&samples, &mut scratch).unwrap();
        assert!((p[0] - 500.0).abs() < 1e-3 && p[2] == 0.0);
    }

    /// One marker (radius 4 px, grey 40) with a rim fading by 0.35 per pixel, at the centre of
    /// a 61x61 frame whose background is a cone `150 - q r` (grey levels, `r` px from the
    /// centre, as on the flank of an imprint): each ring is about `1.5 q` grey levels off the
    /// plane of the next two rings (as contact shading is), the same on every ring. Returns the
    /// rings grown and the cap.
    fn grow_on_cone(q: f32) -> (usize, usize) {
        let (n, c, r0) = (61usize, 30.0f32, 4.0f32);
        let mut luma = vec![0u16; n * n];
        let mut labels = vec![0u32; n * n];
        let mut area = 0u32;
        for y in 0..n {
            for x in 0..n {
                let r = ((x as f32 - c).powi(2) + (y as f32 - c).powi(2)).sqrt();
                let bg = 150.0 - q * r;
                let g = if r <= r0 {
                    labels[y * n + x] = 1;
                    area += 1;
                    40.0
                } else {
                    bg - 20.0 * 0.35f32.powf(r - r0)
                };
                luma[y * n + x] = (g * LUMA_PER_LEVEL).round() as u16;
            }
        }
        let seed = GrowSeed {
            label: 1,
            bbox: [26, 26, 34, 34],
            centre: [c, c],
            radius: (area as f32 / std::f32::consts::PI).sqrt(),
        };
        let mut mask = vec![false; n * n];
        let rings = grow_masks(
            &luma,
            &labels,
            n,
            n,
            &[seed],
            &mut mask,
            &mut GrowWorkspace::default(),
        );
        let cap = (MAX_GROW_RADII * seed.radius).ceil() as usize;
        (usize::from(rings[0]), cap)
    }

    #[test]
    fn rim_on_a_flat_background_is_grown() {
        let (rings, cap) = grow_on_cone(0.0);
        // The rim is above half a grey level for 3 px.
        assert!((2..cap).contains(&rings), "{rings} of {cap}");
    }

    #[test]
    fn curved_background_does_not_run_to_the_cap() {
        // q = 2: the background alone is ~3 grey levels off its plane on every ring.
        let (flat, _) = grow_on_cone(0.0);
        let (rings, cap) = grow_on_cone(2.0);
        assert!(
            rings < cap && rings >= 1 && rings <= flat + 1,
            "{rings} of {cap}, flat {flat}"
        );
    }

    #[test]
    fn gaps_between_seeds() {
        let seed = |x: f32| GrowSeed {
            label: 1,
            bbox: [0, 0, 0, 0],
            centre: [x, 0.0],
            radius: 2.0,
        };
        let gaps = nearest_gaps(&[seed(0.0), seed(10.0), seed(30.0)]);
        assert_eq!(gaps, vec![6.0, 6.0, 16.0]);
        assert!(nearest_gaps(&[seed(0.0)])[0].is_infinite());
    }
}
