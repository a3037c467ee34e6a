//! Biharmonic inpainting: each hole becomes the smoothest surface that meets the known pixels
//! around it (the discrete thin-plate energy, the sum of squared Laplacians, is minimised).
//!
//! Minimising `sum_p (L u)_p^2` over the hole's pixels, with `L` the 5-point graph Laplacian
//! (`(L u)_p = sum of (u_q - u_p)` over the 4-neighbours `q` of `p` inside the image), gives the
//! normal equations `L^T L u = ...`. Away from the image border `L^T L` is the 13-point biharmonic
//! stencil (20, -8, 2, 1) that `skimage.restoration.inpaint_biharmonic` solves, so interior holes
//! agree with scikit-image to solver precision; at the border the graph Laplacian gives natural
//! boundary conditions, so holes touching the border are filled as well.
//!
//! Why it is here: TELEA's weighted mean flattens a shading gradient across a hole; the biharmonic
//! fill continues gradients and curvature, which is what contact shading needs. Neither recovers
//! texture the hole hides.
//!
//! Solver: masked pixels that share a Laplacian row (Manhattan distance at most 2) form a group;
//! each group is one symmetric positive definite system (positive definite because every group
//! reaches a known pixel: the mask may not cover the image), factorised once in f64 by an envelope
//! (profile) Cholesky and solved for every channel. The unknowns are ordered by rows, columns or
//! diagonals, whichever gives the smallest envelope (two lines of the order: two diagonals of a
//! round hole, half the work of two rows). Groups run in parallel.

use rayon::prelude::*;

use crate::error::{CoreError, Result};
use crate::image::ImageView;
use crate::simd::multiversion;
use crate::telea::{check_image_and_mask, check_known_finite, Sample, MAX_CHANNELS};

/// Most envelope entries one group may need (128 MiB of f64): a hole of about 20 000 pixels
/// (a 160 px disc). Larger holes are refused with a clear error instead of a long solve.
pub const MAX_ENVELOPE: usize = 1 << 24;

/// Offsets (dx, dy) of the pixels coupled to a pixel through one Laplacian row.
const COUPLED: [(isize, isize); 12] = [
    (1, 0),
    (-1, 0),
    (0, 1),
    (0, -1),
    (1, 1),
    (1, -1),
    (-1, 1),
    (-1, -1),
    (2, 0),
    (-2, 0),
    (0, 2),
    (0, -2),
];
/// 4-neighbour offsets (dx, dy) of the Laplacian.
const NEIGHBOURS: [(isize, isize); 4] = [(1, 0), (-1, 0), (0, 1), (0, -1)];

/// Fills the nonzero pixels of `mask` in `img` with the biharmonic (thin-plate) surface through
/// the known pixels; returns the whole image.
///
/// `mask` is `H x W`, row-major, nonzero = fill. Unmasked pixels are copied unchanged; integer
/// outputs are rounded half up and saturated. Masked pixels of a float image may hold anything.
///
/// Errors: `img` with more than 4 channels or a non-finite known value; `mask` of the wrong
/// length, covering every pixel, or with a hole too large for the direct solver
/// ([`MAX_ENVELOPE`]).
pub fn inpaint_biharmonic<T: Sample>(img: &ImageView<'_, T>, mask: &[u8]) -> Result<Vec<T>> {
    let (h, w, c) = (img.height(), img.width(), img.channels());
    check_image_and_mask(img, mask)?;
    let mut out = img.data().to_vec();
    let n_masked = mask.iter().filter(|&&m| m != 0).count();
    if n_masked == 0 {
        return Ok(out);
    }
    if n_masked == h * w {
        return Err(CoreError::invalid(
            "mask",
            "covers every pixel: nothing is known to inpaint from",
        ));
    }
    check_known_finite(img, mask)?;
    let mut groups = coupled_groups(mask, h, w);
    let solved: Vec<Result<Vec<f64>>> = groups
        .par_iter_mut()
        .map(|g| {
            order_unknowns(g, w);
            solve_group(img, mask, g)
        })
        .collect();
    for (g, values) in groups.iter().zip(solved) {
        let values = values?;
        for (i, &p) in g.iter().enumerate() {
            for k in 0..c {
                out[p * c + k] = T::from_f32(values[k * g.len() + i] as f32);
            }
        }
    }
    Ok(out)
}

/// Masked pixels grouped by coupling (Manhattan distance <= 2), each group sorted row-major.
fn coupled_groups(mask: &[u8], h: usize, w: usize) -> Vec<Vec<usize>> {
    let mut seen = vec![false; h * w];
    let mut groups = Vec::new();
    let mut stack = Vec::new();
    for start in 0..h * w {
        if mask[start] == 0 || seen[start] {
            continue;
        }
        seen[start] = true;
        stack.push(start);
        let mut group = Vec::new();
        while let Some(p) = stack.pop() {
            group.push(p);
            let (x, y) = ((p % w) as isize, (p / w) as isize);
            for (dx, dy) in COUPLED {
                let (qx, qy) = (x + dx, y + dy);
                if qx < 0 || qy < 0 || qx >= w as isize || qy >= h as isize {
                    continue;
                }
                let q = qy as usize * w + qx as usize;
                if mask[q] != 0 && !seen[q] {
                    seen[q] = true;
                    stack.push(q);
                }
            }
        }
        group.sort_unstable();
        groups.push(group);
    }
    groups
}

/// Reorders a group's pixels (row-major on entry) to whichever of four orders gives the
/// cheapest envelope Cholesky: by rows, by columns, or along either diagonal (lines of constant
/// `x + y` or `x - y`), each line in increasing `y` (`x` for columns). The cost of an order is
/// the sum over its rows of the squared envelope width, about twice the factorisation's
/// multiply-adds. Pixels couple up to Manhattan distance 2, so a row's envelope reaches two lines
/// of the order back: two rows of a round hole in row-major order, but two diagonals, each about
/// `1/sqrt(2)` as long, along a diagonal, which halves the work. The solution is the same up to
/// rounding.
fn order_unknowns(group: &mut Vec<usize>, w: usize) {
    let n = group.len();
    if n < 16 {
        return;
    }
    let (mut x0, mut y0, mut x1, mut y1) = (usize::MAX, usize::MAX, 0, 0);
    for &p in group.iter() {
        let (x, y) = (p % w, p / w);
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    let (bw, bh) = (x1 - x0 + 1, y1 - y0 + 1);
    // Local coordinates, row-major like the group.
    let local: Vec<(usize, usize)> = group.iter().map(|&p| (p % w - x0, p / w - y0)).collect();
    let mut pos = vec![u32::MAX; bw * bh];
    let mut best_cost = u64::MAX;
    let mut best: Vec<u32> = Vec::new();
    let mut order: Vec<u32> = Vec::with_capacity(n);
    let mut counts = vec![0usize; bw + bh];
    for kind in 0..4 {
        // Line of each pixel; a stable counting sort of the row-major group by line keeps
        // increasing y (x for columns) within a line.
        let line = |&(x, y): &(usize, usize)| match kind {
            0 => y,
            1 => x,
            2 => x + y,
            _ => x + bh - 1 - y,
        };
        counts.iter_mut().for_each(|c| *c = 0);
        for q in &local {
            counts[line(q) + 1] += 1;
        }
        for i in 1..counts.len() {
            counts[i] += counts[i - 1];
        }
        order.clear();
        order.resize(n, 0);
        let mut next = counts.clone();
        for (i, q) in local.iter().enumerate() {
            let l = line(q);
            order[next[l]] = i as u32;
            next[l] += 1;
        }
        for (k, &i) in order.iter().enumerate() {
            let (x, y) = local[i as usize];
            pos[y * bw + x] = k as u32;
        }
        let mut cost = 0u64;
        for (k, &i) in order.iter().enumerate() {
            let (x, y) = (local[i as usize].0 as isize, local[i as usize].1 as isize);
            let mut first = k as u32;
            for (dx, dy) in COUPLED {
                let (qx, qy) = (x + dx, y + dy);
                if qx >= 0 && qy >= 0 && (qx as usize) < bw && (qy as usize) < bh {
                    first = first.min(pos[qy as usize * bw + qx as usize]);
                }
            }
            let width = u64::from(k as u32 - first + 1);
            cost += width * width;
        }
        for &(x, y) in &local {
            pos[y * bw + x] = u32::MAX;
        }
        if cost < best_cost {
            best_cost = cost;
            best.clone_from(&order);
        }
    }
    let old = std::mem::take(group);
    *group = best.iter().map(|&i| old[i as usize]).collect();
}

/// One Laplacian row restricted to the group: up to five (unknown index, coefficient) pairs and
/// the known pixels' contribution per channel.
struct Row {
    terms: [(usize, f64); 5],
    len: usize,
    known: [f64; MAX_CHANNELS],
}

/// The biharmonic values of one group's pixels (`channels x len`: one plane per channel).
fn solve_group<T: Sample>(
    img: &ImageView<'_, T>,
    mask: &[u8],
    group: &[usize],
) -> Result<Vec<f64>> {
    let (h, w, c) = (img.height(), img.width(), img.channels());
    let data = img.data();
    let n = group.len();
    // Window around the group (2 px margin: every pixel a row can reach), with unknown indices.
    let (mut x0, mut y0, mut x1, mut y1) = (w, h, 0, 0);
    for &p in group {
        let (x, y) = (p % w, p / w);
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    let (x0, y0) = (x0.saturating_sub(2), y0.saturating_sub(2));
    let (x1, y1) = ((x1 + 2).min(w - 1), (y1 + 2).min(h - 1));
    let ww = x1 - x0 + 1;
    let mut index = vec![usize::MAX; ww * (y1 - y0 + 1)];
    for (i, &p) in group.iter().enumerate() {
        index[(p / w - y0) * ww + (p % w - x0)] = i;
    }
    let local = |x: usize, y: usize| (y - y0) * ww + (x - x0);

    // Rows: the Laplacian at every unknown and at every 4-neighbour of one.
    let mut row_of = vec![false; index.len()];
    let mut rows = Vec::with_capacity(3 * n);
    for &p in group {
        let (x, y) = (p % w, p / w);
        for (dx, dy) in [(0, 0), (1, 0), (-1, 0), (0, 1), (0, -1)] {
            let (rx, ry) = (x as isize + dx, y as isize + dy);
            if rx < 0 || ry < 0 || rx >= w as isize || ry >= h as isize {
                continue;
            }
            let (rx, ry) = (rx as usize, ry as usize);
            if std::mem::replace(&mut row_of[local(rx, ry)], true) {
                continue;
            }
            let mut row = Row {
                terms: [(0, 0.0); 5],
                len: 0,
                known: [0.0; MAX_CHANNELS],
            };
            let mut add = |qx: usize, qy: usize, coef: f64| {
                let i = index[local(qx, qy)];
                if i != usize::MAX {
                    row.terms[row.len] = (i, coef);
                    row.len += 1;
                } else {
                    // Known (in bounds because the window covers every pixel a row reaches, and
                    // not masked: a masked pixel this close would belong to the group).
                    let q = qy * w + qx;
                    debug_assert!(mask[q] == 0);
                    for k in 0..c {
                        row.known[k] += coef * f64::from(data[q * c + k].to_f32());
                    }
                }
            };
            let mut degree = 0.0;
            for (dx, dy) in NEIGHBOURS {
                let (qx, qy) = (rx as isize + dx, ry as isize + dy);
                if qx < 0 || qy < 0 || qx >= w as isize || qy >= h as isize {
                    continue;
                }
                add(qx as usize, qy as usize, 1.0);
                degree += 1.0;
            }
            add(rx, ry, -degree);
            rows.push(row);
        }
    }

    // Envelope: the first column of each row of A = sum of row^T row.
    let mut first: Vec<usize> = (0..n).collect();
    for row in &rows {
        let terms = &row.terms[..row.len];
        if let Some(lo) = terms.iter().map(|t| t.0).min() {
            for &(i, _) in terms {
                first[i] = first[i].min(lo);
            }
        }
    }
    let mut start = Vec::with_capacity(n + 1);
    let mut total = 0usize;
    for (i, &f) in first.iter().enumerate() {
        start.push(total);
        total += i - f + 1;
    }
    start.push(total);
    if total > MAX_ENVELOPE {
        return Err(CoreError::invalid(
            "mask",
            format!(
                "a hole of {n} pixels is too large for biharmonic inpainting (its system needs \
                 {total} > {MAX_ENVELOPE} envelope entries); use inpaint_telea for it"
            ),
        ));
    }
    let mut env = vec![0.0f64; total];
    // Right-hand sides, one plane per channel.
    let mut rhs = vec![0.0f64; n * c];
    for row in &rows {
        let terms = &row.terms[..row.len];
        for &(i, ci) in terms {
            for &(j, cj) in terms {
                if j <= i {
                    env[start[i] + j - first[i]] += ci * cj;
                }
            }
            for k in 0..c {
                rhs[k * n + i] -= ci * row.known[k];
            }
        }
    }
    if !cholesky_envelope(&mut env, &start, &first) {
        return Err(CoreError::Unsolvable(
            "biharmonic system is not positive definite".into(),
        ));
    }
    for plane in rhs.chunks_exact_mut(n) {
        solve_envelope(&env, &start, &first, plane);
    }
    Ok(rhs)
}

multiversion! {
    /// In-place envelope Cholesky `A = L L^T` (row `i` of the lower triangle stored densely from
    /// column `first[i]` at `env[start[i]..start[i + 1]]`; fill-in stays inside the envelope).
    /// Returns false if a pivot is not positive (impossible for a group that reaches a known
    /// pixel, see the module docs).
    fn cholesky_envelope(env: &mut [f64], start: &[usize], first: &[usize]) -> bool {
        let n = first.len();
        // Reciprocal pivots: each entry of a row depends on the one before it (through the
        // dot product), so a division's latency would sit on that chain; a product does not.
        let mut inv = vec![0.0f64; n];
        for i in 0..n {
            let (fi, si) = (first[i], start[i]);
            for j in fi..=i {
                let (fj, sj) = (first[j], start[j]);
                let lo = fi.max(fj);
                let s = dot(
                    &env[si + lo - fi..si + j - fi],
                    &env[sj + lo - fj..sj + j - fj],
                );
                let a = env[si + j - fi] - s;
                if j < i {
                    env[si + j - fi] = a * inv[j];
                } else if a > 0.0 && a.is_finite() {
                    let d = a.sqrt();
                    env[si + j - fi] = d;
                    inv[i] = 1.0 / d;
                } else {
                    return false;
                }
            }
        }
        true
    }
}

multiversion! {
    /// Solves `L L^T x = b` in place for one right-hand side (one channel, planar).
    fn solve_envelope(env: &[f64], start: &[usize], first: &[usize], b: &mut [f64]) {
        let n = first.len();
        for i in 0..n {
            let (fi, si) = (first[i], start[i]);
            let s = dot(&env[si..si + i - fi], &b[fi..i]);
            b[i] = (b[i] - s) / env[si + i - fi];
        }
        for i in (0..n).rev() {
            let (fi, si) = (first[i], start[i]);
            let xi = b[i] / env[si + i - fi];
            b[i] = xi;
            for (bj, l) in b[fi..i].iter_mut().zip(&env[si..si + i - fi]) {
                *bj -= l * xi;
            }
        }
    }
}

/// Dot product with eight independent accumulators (two AVX2 vectors; the factorisation's
/// inner loop, typically 10-60 long).
#[inline(always)]
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut acc = [0.0f64; 8];
    let (ca, cb) = (a.chunks_exact(8), b.chunks_exact(8));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for k in 0..8 {
            acc[k] += x[k] * y[k];
        }
    }
    let (ca, cb) = (ra.chunks_exact(4), rb.chunks_exact(4));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for k in 0..4 {
            acc[k] += x[k] * y[k];
        }
    }
    let mut s = ((acc[0] + acc[4]) + (acc[1] + acc[5])) + ((acc[2] + acc[6]) + (acc[3] + acc[7]));
    for (x, y) in ra.iter().zip(rb) {
        s += x * y;
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(img: &[f32], h: usize, w: usize, mask: &[u8]) -> Vec<f32> {
        let view = ImageView::new(img, h, w, 1, "img").unwrap();
        inpaint_biharmonic(&view, mask).unwrap()
    }

    #[test]
    fn reproduces_linear_and_quadratic_surfaces() {
        // Discrete biharmonic functions (planes, and x^2 - y^2) are reproduced exactly when the
        // hole is away from the border.
        let (h, w) = (24, 30);
        for f in [
            |x: f32, y: f32| 3.0 + 0.5 * x - 0.25 * y,
            |x: f32, y: f32| 0.01 * (x * x - y * y) + 40.0,
        ] {
            let img: Vec<f32> = (0..h * w)
                .map(|p| f((p % w) as f32, (p / w) as f32))
                .collect();
            let mut mask = vec![0u8; h * w];
            for y in 8..15 {
                for x in 10..19 {
                    mask[y * w + x] = 1;
                }
            }
            let mut holed = img.clone();
            for p in 0..h * w {
                if mask[p] != 0 {
                    holed[p] = f32::NAN;
                }
            }
            let out = run(&holed, h, w, &mask);
            for p in 0..h * w {
                assert!(
                    (out[p] - img[p]).abs() < 1e-3,
                    "{p}: {} vs {}",
                    out[p],
                    img[p]
                );
            }
        }
    }

    #[test]
    fn flat_images_stay_flat_and_border_holes_are_filled() {
        let (h, w) = (10, 12);
        let img = vec![100u8; h * w * 3];
        let mut mask = vec![0u8; h * w];
        for p in [0, 1, w, w + 1, h * w - 1, 5 * w + 6] {
            mask[p] = 1;
        }
        let view = ImageView::new(&img, h, w, 3, "img").unwrap();
        assert_eq!(inpaint_biharmonic(&view, &mask).unwrap(), img);
    }

    #[test]
    fn errors_name_the_argument() {
        let img = vec![0u8; 16];
        let view = ImageView::new(&img, 4, 4, 1, "img").unwrap();
        let all = inpaint_biharmonic(&view, &[1u8; 16]).unwrap_err();
        assert!(all.to_string().starts_with("mask:"));
        let short = inpaint_biharmonic(&view, &[0u8; 15]).unwrap_err();
        assert!(short.to_string().starts_with("mask:"));
        let nan = vec![f32::NAN; 16];
        let view = ImageView::new(&nan, 4, 4, 1, "img").unwrap();
        let mut mask = [0u8; 16];
        mask[5] = 1;
        assert!(inpaint_biharmonic(&view, &mask)
            .unwrap_err()
            .to_string()
            .starts_with("img:"));
    }

    #[test]
    fn unknown_order_follows_the_cheapest_envelope_and_keeps_the_solution() {
        // A round hole is ordered along a diagonal (half the work of rows); a wide flat strip
        // stays in rows (short columns would be as good, rows come first). Every order gives
        // the row-major solution up to rounding.
        let (h, w) = (48, 64);
        let img: Vec<f32> = (0..h * w)
            .map(|p| {
                let (x, y) = ((p % w) as f32, (p / w) as f32);
                100.0 + 20.0 * (0.2 * x).sin() + 0.05 * x * y
            })
            .collect();
        let view = ImageView::new(&img, h, w, 1, "img").unwrap();
        let disc: Vec<usize> = (0..h * w)
            .filter(|&p| {
                let (dx, dy) = ((p % w) as f32 - 30.0, (p / w) as f32 - 22.0);
                dx * dx + dy * dy <= 14.0 * 14.0
            })
            .collect();
        let strip: Vec<usize> = (0..h * w)
            .filter(|&p| (p / w == 40 || p / w == 41) && (4..60).contains(&(p % w)))
            .collect();
        for (group, diagonal) in [(disc, true), (strip, false)] {
            let mut mask = vec![0u8; h * w];
            group.iter().for_each(|&p| mask[p] = 1);
            let mut ordered = group.clone();
            order_unknowns(&mut ordered, w);
            let mut sorted = ordered.clone();
            sorted.sort_unstable();
            assert_eq!(sorted, group);
            let step = (ordered[1] as isize - ordered[0] as isize).unsigned_abs();
            assert_eq!(step == w - 1 || step == w + 1, diagonal, "step {step}");
            let a = solve_group(&view, &mask, &group).unwrap();
            let b = solve_group(&view, &mask, &ordered).unwrap();
            for (i, p) in ordered.iter().enumerate() {
                let j = group.binary_search(p).unwrap();
                assert!((a[j] - b[i]).abs() < 1e-9, "{p}: {} vs {}", a[j], b[i]);
            }
        }
    }

    #[test]
    fn groups_follow_the_coupling_distance() {
        let (h, w) = (5, 9);
        let mut mask = vec![0u8; h * w];
        mask[2 * w + 1] = 1;
        mask[2 * w + 3] = 1; // Manhattan 2 from the first: same group
        mask[2 * w + 6] = 1; // 3 away: its own group
        let groups = coupled_groups(&mask, h, w);
        assert_eq!(groups.len(), 2);
        assert_eq!(groups[0], vec![2 * w + 1, 2 * w + 3]);
    }
}
