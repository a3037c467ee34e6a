//! The dtype front ends: the sample types TELEA works on (`u8`, `u16`, `f32`, processed as
//! `f32`), the argument checks every inpainting method shares, and the conversion of a solved
//! window's `f32` planes back to the caller's interleaved type.

use super::*;

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

/// The argument checks every inpainting method shares: at most [`MAX_CHANNELS`] channels and
/// one mask value per pixel.
pub(crate) fn check_image_and_mask<T: Sample>(img: &ImageView<'_, T>, mask: &[u8]) -> Result<()> {
    let (h, w, c) = (img.height(), img.width(), img.channels());
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
    Ok(())
}

/// Refuses a float image with NaN or infinity in a known (unmasked) pixel, naming the first;
/// masked pixels may hold anything. Integer images pass without a scan.
pub(crate) fn check_known_finite<T: Sample>(img: &ImageView<'_, T>, mask: &[u8]) -> Result<()> {
    if !T::FLOAT {
        return Ok(());
    }
    let (w, c, data) = (img.width(), img.channels(), img.data());
    let bad = |i: &usize| mask[*i] == 0 && data[i * c..(i + 1) * c].iter().any(|v| !v.is_finite());
    match (0..mask.len()).find(bad) {
        Some(i) => Err(CoreError::invalid(
            "img",
            format!(
                "unmasked pixel (x={}, y={}) is NaN or infinite; mask it or clean it first",
                i % w,
                i / w
            ),
        )),
        None => Ok(()),
    }
}
/// Where a group's filled pixels go.
pub(super) enum Out<'a, T> {
    /// The output image (interleaved, the input's layout).
    Image(&'a mut [T]),
    /// A vector of the pixels in run order.
    Runs(&'a mut Vec<T>),
}

/// `dst` (`C` interleaved channels) from the window's planes, from window pixel `at` on: each
/// plane converted in pieces (straight loops, which vectorise), then interleaved.
#[inline(always)]
pub(super) fn convert<T: Sample, const C: usize>(ws: &Workspace, at: usize, dst: &mut [T]) {
    const PIECE: usize = 64;
    let n = ws.flag.len();
    let mut piece = [[T::from_f32(0.0); PIECE]; C];
    for (k, out) in dst.chunks_mut(PIECE * C).enumerate() {
        let m = out.len() / C;
        let from = at + k * PIECE;
        for (ch, p) in piece.iter_mut().enumerate() {
            let plane = &ws.vals[ch * n + from..ch * n + from + m];
            for (q, &v) in p.iter_mut().zip(plane) {
                *q = T::from_f32(v);
            }
        }
        for (i, o) in out.chunks_exact_mut(C).enumerate() {
            for (o, p) in o.iter_mut().zip(&piece) {
                *o = p[i];
            }
        }
    }
}
