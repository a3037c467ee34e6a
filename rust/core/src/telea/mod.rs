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
//! - the fronts pop in order of arrival time quantised to 1/64 pixel, pixels of equal quantised
//!   time in the order they were reached (OpenCV: a binary heap on the exact time, ties in heap
//!   order);
//! - holes are 8-connected components; holes closer than `2 * radius + 2` pixels (Chebyshev) are
//!   grouped, and each group is solved in its own window, in parallel. Groups farther apart cannot
//!   see each other's pixels or fronts, and a group's pops depend only on its own pixels, so the
//!   result is bit-identical to one solve over the whole image ([`inpaint_telea_global`]).
//!   OpenCV lets a hole borrow the already-filled pixels of a nearby hole; here a hole only sees
//!   known pixels and its own group.
//!
//! Implementation: a group's window holds one `f32` plane per channel, the arrival times (`+inf`
//! where a pixel is unknown, unreached or outside the image, which gives it weight exactly 0) and
//! flags. The disk is cut into 8-pixel chunks read in place from window rows (`DiskPlan`);
//! the weights and sums of a chunk are one AVX register each (AVX2 + FMA, detected at run time),
//! or plain arrays elsewhere: the same IEEE operations in the same order, so both give the same
//! bits. The fronts use a bucket queue threaded through the window (`FrontQueue`).

use rayon::prelude::*;

use crate::error::{CoreError, Result};
use crate::image::ImageView;

mod dtypes;
mod holes;
mod march;
mod queue;
mod simd8;
mod weights;

#[cfg(test)]
mod profile;
#[cfg(test)]
mod tests;

pub use dtypes::Sample;
use dtypes::*;
pub(crate) use dtypes::{check_image_and_mask, check_known_finite};
use holes::*;
use march::*;
use queue::*;
use simd8::*;
use weights::*;

/// Largest accepted `radius` (OpenCV clamps to the same bound).
pub const MAX_RADIUS: usize = 100;
/// Most interleaved channels an image may have.
pub const MAX_CHANNELS: usize = 4;
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
    inpaint_impl(img, mask, radius, true, true)
}

/// Reference path: the same inpainting as [`inpaint_telea`], as one sequential solve over the
/// whole image. Slower; exists to show that the per-group parallel solve changes nothing.
pub fn inpaint_telea_global<T: Sample>(
    img: &ImageView<'_, T>,
    mask: &[u8],
    radius: usize,
) -> Result<Vec<T>> {
    inpaint_impl(img, mask, radius, false, true)
}

/// `simd`: run the disk arithmetic on AVX2 where the CPU has it (false: the portable code,
/// which gives the same bits; tests compare the two).
fn inpaint_impl<T: Sample>(
    img: &ImageView<'_, T>,
    mask: &[u8],
    radius: usize,
    per_group: bool,
    simd: bool,
) -> Result<Vec<T>> {
    let (h, w, c) = (img.height(), img.width(), img.channels());
    if !(1..=MAX_RADIUS).contains(&radius) {
        return Err(CoreError::invalid(
            "radius",
            format!("must be between 1 and {MAX_RADIUS} pixels; got {radius}"),
        ));
    }
    check_image_and_mask(img, mask)?;
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
    // The front queue links window pixels by 32-bit indices, with a list head per bucket after
    // them; the largest window is the padded image.
    let plan = DiskPlan::cached(radius);
    let margin = plan.margin;
    if (h + 2 * margin).saturating_mul(w + 2 * margin) > u32::MAX as usize - BUCKETS {
        return Err(CoreError::invalid(
            "img",
            format!("must have fewer than 2^32 pixels; got {h}x{w}"),
        ));
    }
    check_known_finite(img, mask)?;

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
    let ctx = Ctx {
        img,
        radius,
        plan: &plan,
        avx2: simd && detect_avx2(),
    };
    // With one thread, solve here: handing the groups to the pool's thread costs wake-ups.
    let parallel = per_group && rayon::current_num_threads() > 1;
    if parallel {
        let filled: Vec<Vec<T>> = groups
            .par_iter()
            .zip(&group_runs)
            .map(|(&bbox, runs)| {
                let mut values = Vec::new();
                with_workspace(|ws| ctx.solve(ws, bbox, runs, Out::Runs(&mut values)));
                values
            })
            .collect();
        let mut out = data.to_vec();
        for (values, runs) in filled.iter().zip(&group_runs) {
            let mut values = values.iter();
            for run in runs {
                let span = (run.y * w + run.x0) * c..(run.y * w + run.x1 + 1) * c;
                for (o, v) in out[span].iter_mut().zip(values.by_ref()) {
                    *o = *v;
                }
            }
        }
        return Ok(out);
    }
    let mut out = data.to_vec();
    for (&bbox, runs) in groups.iter().zip(&group_runs) {
        with_workspace(|ws| ctx.solve(ws, bbox, runs, Out::Image(&mut out)));
    }
    Ok(out)
}
