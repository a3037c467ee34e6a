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

/// A horizontal run `x0..=x1` of masked pixels on row `y`.
#[derive(Debug, Clone, Copy)]
struct Run {
    y: usize,
    x0: usize,
    x1: usize,
}

/// Bit `i` set where byte `i` of `word` (eight mask pixels, little-endian) is nonzero.
#[inline(always)]
fn nonzero_bits(word: u64) -> u64 {
    let mut t = word;
    t |= t >> 4;
    t |= t >> 2;
    t |= t >> 1;
    // The low bit of each byte, gathered into the top byte by one multiplication.
    ((t & 0x0101_0101_0101_0101).wrapping_mul(0x0102_0408_1020_4080) >> 56) & 0xFF
}

/// Runs of the mask, row by row: each row becomes a bit set (blocks of 32 zero pixels cost one
/// test), whose runs of ones are read with bit scans.
fn mask_runs(mask: &[u8], h: usize, w: usize) -> Vec<Run> {
    const BLOCK: usize = 32;
    let mut runs = Vec::new();
    let mut bits = vec![0u64; w.div_ceil(64)];
    for (y, row) in mask.chunks_exact(w).enumerate().take(h) {
        bits.fill(0);
        let mut any = false;
        let full = w - w % BLOCK;
        for (b, block) in row[..full].chunks_exact(BLOCK).enumerate() {
            let mut words = [0u64; BLOCK / 8];
            for (wd, c) in words.iter_mut().zip(block.chunks_exact(8)) {
                *wd = u64::from_le_bytes(c.try_into().unwrap_or([0; 8]));
            }
            if words.iter().fold(0, |a, &wd| a | wd) == 0 {
                continue;
            }
            let mut set = 0u64;
            for (k, &wd) in words.iter().enumerate() {
                set |= nonzero_bits(wd) << (8 * k);
            }
            let at = b * BLOCK;
            bits[at / 64] |= set << (at % 64);
            any = true;
        }
        for (x, &v) in row.iter().enumerate().skip(full) {
            if v != 0 {
                bits[x / 64] |= 1 << (x % 64);
                any = true;
            }
        }
        if !any {
            continue;
        }
        let mut x = 0;
        while x < w {
            // Next set bit at or after x.
            let mut k = x / 64;
            let mut m = bits[k] & (!0u64 << (x % 64));
            while m == 0 && k + 1 < bits.len() {
                k += 1;
                m = bits[k];
            }
            if m == 0 {
                break;
            }
            let x0 = k * 64 + m.trailing_zeros() as usize;
            // Next clear bit after x0 (bits past the row's end are clear).
            let mut k = x0 / 64;
            let mut m = !bits[k] & (!0u64 << (x0 % 64));
            while m == 0 && k + 1 < bits.len() {
                k += 1;
                m = !bits[k];
            }
            let x1 = if m == 0 {
                w
            } else {
                (k * 64 + m.trailing_zeros() as usize).min(w)
            };
            runs.push(Run { y, x0, x1: x1 - 1 });
            x = x1;
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

/// Lanes of one disk chunk: weights and sums are computed 8 disk pixels at a time.
const LANES: usize = 8;
/// Per-lane constants of a chunk: `r = p - q`, the geometric weight `g = 1 / |r|^3`, and for the
/// weights `g r` and `g` times the direction term's limit and floor; all 0 for lanes that are
/// not disk pixels (the centre among them).
#[derive(Debug, Clone, Copy, Default)]
#[repr(C, align(32))]
struct Lanes {
    rx: [f32; LANES],
    ry: [f32; LANES],
    geometric: [f32; LANES],
    g_rx: [f32; LANES],
    g_ry: [f32; LANES],
    g_limit: [f32; LANES],
    g_floor: [f32; LANES],
}

impl Lanes {
    fn set(&mut self, l: usize, dx: isize, dy: isize) {
        let len2 = (dx * dx + dy * dy) as f64;
        let g = 1.0 / (len2 * len2.sqrt());
        self.rx[l] = -dx as f32;
        self.ry[l] = -dy as f32;
        self.geometric[l] = g as f32;
        self.g_rx[l] = (-dx as f64 * g) as f32;
        self.g_ry[l] = (-dy as f64 * g) as f32;
        self.g_limit[l] = (f64::from(MIN_DIRECTION) * g) as f32;
        self.g_floor[l] = (f64::from(DIRECTION_FLOOR) * g) as f32;
    }
}

/// The disk of radius `r` without its centre, cut into 8-lane chunks: direct chunks (runs of a
/// disk row, read in place from the window) and gathered chunks (the pixels left over).
#[derive(Debug)]
struct DiskPlan {
    /// `(dx, dy)` of lane 0 of each direct chunk; lane `l` is the pixel `(dx + l, dy)`.
    direct: Vec<(isize, isize)>,
    direct_lanes: Vec<Lanes>,
    /// `(dx, dy)` of each lane of each gathered chunk; unused lanes point at the centre.
    gathered: Vec<[(isize, isize); LANES]>,
    gathered_lanes: Vec<Lanes>,
    /// Pixels taken one at a time: `(dx, dy)` and `[rx, ry, geometric]`.
    single: Vec<((isize, isize), [f32; 3])>,
    radius: usize,
    /// Window margin around a group's box: `radius + 2` (disk, outward front, its neighbours,
    /// their neighbours), or more if a direct chunk reads farther.
    margin: usize,
}

impl DiskPlan {
    /// The cheapest cut of the disk of radius `r`, by instructions per fill (measured, 3
    /// channels): about 30 for a direct chunk, 100 for a gathered one (eight scattered loads per
    /// plane), 48 for a single pixel.
    fn new(r: usize) -> DiskPlan {
        let cost = |p: &DiskPlan| 10 * p.direct.len() + 33 * p.gathered.len() + 16 * p.single.len();
        (1..=4)
            .flat_map(|min_direct| [false, true].map(|single| DiskPlan::cut(r, min_direct, single)))
            .min_by_key(cost)
            .unwrap_or_else(|| DiskPlan::cut(r, 1, false))
    }

    /// [`DiskPlan::new`], kept per thread for the last radius asked for.
    fn cached(r: usize) -> std::rc::Rc<DiskPlan> {
        thread_local! {
            static LAST: std::cell::RefCell<Option<std::rc::Rc<DiskPlan>>> =
                const { std::cell::RefCell::new(None) };
        }
        LAST.with(|last| {
            let mut last = last.borrow_mut();
            match &*last {
                Some(plan) if plan.radius == r => plan.clone(),
                _ => {
                    let plan = std::rc::Rc::new(DiskPlan::new(r));
                    *last = Some(plan.clone());
                    plan
                }
            }
        })
    }

    /// The disk of radius `r`: runs of at least `min_direct` row pixels as direct chunks, the
    /// others as single pixels (`single`) or gathered chunks.
    fn cut(r: usize, min_direct: usize, single: bool) -> DiskPlan {
        let ri = r as isize;
        // Reads may reach 2r + 1 pixels from a hole: groups are at least 2r + 2 apart, so no
        // lane ever reads another group's pixels (whose values may be anything, NaN included).
        let reach = 2 * ri + 1;
        let mut plan = DiskPlan {
            direct: Vec::new(),
            direct_lanes: Vec::new(),
            gathered: Vec::new(),
            gathered_lanes: Vec::new(),
            single: Vec::new(),
            radius: r,
            margin: r + 2,
        };
        let mut left: Vec<(isize, isize)> = Vec::new();
        for dy in -ri..=ri {
            let row: Vec<isize> = (-ri..=ri)
                .filter(|&dx| (dx, dy) != (0, 0) && dx * dx + dy * dy <= ri * ri)
                .collect();
            let mut i = 0;
            while i < row.len() {
                let x0 = row[i];
                let count = row[i..]
                    .iter()
                    .take_while(|&&dx| dx < x0 + LANES as isize)
                    .count();
                if count >= min_direct && x0 + LANES as isize - 1 <= reach {
                    let mut lanes = Lanes::default();
                    for &dx in &row[i..i + count] {
                        lanes.set((dx - x0) as usize, dx, dy);
                    }
                    plan.direct.push((x0, dy));
                    plan.direct_lanes.push(lanes);
                    let far = x0.abs().max(x0 + LANES as isize - 1).max(dy.abs());
                    plan.margin = plan.margin.max(far as usize);
                    i += count;
                } else {
                    left.push((x0, dy));
                    i += 1;
                }
            }
        }
        if single {
            for &(dx, dy) in &left {
                let mut lanes = Lanes::default();
                lanes.set(0, dx, dy);
                let consts = [lanes.rx[0], lanes.ry[0], lanes.geometric[0]];
                plan.single.push(((dx, dy), consts));
            }
            left.clear();
        }
        for chunk in left.chunks(LANES) {
            let mut at = [(0, 0); LANES];
            let mut lanes = Lanes::default();
            for (l, &(dx, dy)) in chunk.iter().enumerate() {
                at[l] = (dx, dy);
                lanes.set(l, dx, dy);
            }
            plan.gathered.push(at);
            plan.gathered_lanes.push(lanes);
        }
        plan
    }

    /// The chunks with their offsets in a window of `n` pixels, `ww` wide.
    fn place(&self, ww: usize, n: usize, disk: &mut WindowDisk) {
        let off = |(dx, dy): (isize, isize)| dy * ww as isize + dx;
        disk.direct.clear();
        disk.direct.extend(
            self.direct
                .iter()
                .zip(&self.direct_lanes)
                .map(|(&at, lanes)| (off(at), *lanes)),
        );
        disk.gathered.clear();
        disk.gathered.extend(
            self.gathered
                .iter()
                .zip(&self.gathered_lanes)
                .map(|(at, lanes)| (at.map(off), *lanes)),
        );
        disk.single.clear();
        disk.single
            .extend(self.single.iter().map(|&(at, c)| (off(at), c)));
        // Fills at `lo..=hi` read inside the window: lanes reach `first..end` around the pixel.
        let first = disk.direct.iter().map(|d| d.0);
        let first = first.chain(disk.gathered.iter().flat_map(|g| g.0));
        let first = first.chain(disk.single.iter().map(|s| s.0)).min();
        let end = disk.direct.iter().map(|d| d.0 + LANES as isize);
        let end = end.chain(disk.gathered.iter().flat_map(|g| g.0.map(|o| o + 1)));
        let end = end.chain(disk.single.iter().map(|s| s.0 + 1)).max();
        let (first, end) = (first.unwrap_or(0).min(0), end.unwrap_or(1).max(1));
        disk.lo = first.unsigned_abs();
        disk.hi = (n as isize - end).max(-1);
    }
}

/// A solve window's disk: the chunks with their window offsets.
#[derive(Default)]
struct WindowDisk {
    direct: Vec<(isize, Lanes)>,
    gathered: Vec<([isize; LANES], Lanes)>,
    single: Vec<(isize, [f32; 3])>,
    /// Every read of a fill at a window pixel in `lo..=hi` is inside the window.
    lo: usize,
    hi: isize,
}

impl WindowDisk {
    #[inline(always)]
    fn covers(&self, p: usize) -> bool {
        self.lo <= p && (p as isize) <= self.hi
    }
}

/// Queue key: arrival time in the high half (non-negative, so its bits order like the value), the
/// window index in the low half. Window raster order is image raster order, so ties pop in the
/// same order whatever the window: a group's solve does not depend on where its window lies.
fn key(t: f32, wi: usize) -> u64 {
    (u64::from(t.to_bits()) << 32) | wi as u64
}

fn key_index(k: u64) -> usize {
    (k & u64::from(u32::MAX)) as usize
}

/// Buckets of the front queue per pixel of arrival time ...
const BUCKET_SCALE: f32 = 64.0;
/// ... and buckets in its ring: 4 pixels of arrival time, while a front spans about one (a new
/// arrival time is at most 1 more than the one just popped).
const BUCKETS: usize = 256;
const RING_WORDS: usize = BUCKETS / 64;

/// The bucket of arrival time `t`: `round(t * BUCKET_SCALE)`, nondecreasing in `t`, by integer
/// operations (adding 2^23 leaves the rounded integer in the mantissa; the clamp keeps it below
/// 2^22).
#[inline(always)]
fn bucket(t: f32) -> u64 {
    let t = t * BUCKET_SCALE;
    u64::from((t.clamp(0.0, 4_194_304.0) + 8_388_608.0).to_bits() & 0x7F_FFFF)
}

/// The bucket of a [`key`].
fn key_bucket(k: u64) -> u64 {
    bucket(f32::from_bits((k >> 32) as u32))
}

/// The fast-marching fronts' queue: a bucket queue on arrival time quantised to
/// `1 / BUCKET_SCALE` pixel. Buckets pop in increasing time; within a bucket, pixels pop in the
/// order they were pushed; a pixel pushed below the current bucket (a front may, rarely, reach a
/// pixel earlier than the one just popped) pops next. O(1) per push and pop, without
/// allocation: a ring of buckets kept as linked lists threaded through the window's pixels
/// (`next`), with a bitmap of the non-empty ones; pixels beyond the ring wait in a spill list
/// (never seen: kept so that the order stays right whatever the times).
///
/// The order depends only on the pushes and their times: pixels of independent groups may
/// interleave, but each group sees its own pops in the same order whether it is solved alone or
/// with others, and wherever its window lies.
#[derive(Default)]
struct FrontQueue {
    /// `next[i]`: the pixel after window pixel `i` in its bucket; entries `n + s` head the list
    /// of ring slot `s` (for a window of `n` pixels).
    next: Vec<u32>,
    /// Last pixel of each slot's list (`n + s` when empty).
    tail: Vec<u32>,
    /// Window size: `n + s` is slot `s`'s list head.
    n: u32,
    /// Bit `s` set: ring slot `s` is not empty (the current slot's bit is clear).
    occupied: [u64; RING_WORDS],
    /// Absolute index of the current bucket.
    cur: u64,
    /// The last pixel popped from the current bucket (or its list head).
    cursor: u32,
    /// Pixels pushed below the current bucket, and how many of them have popped.
    late: Vec<u32>,
    late_head: usize,
    /// Keys ([`key`]) beyond the ring.
    spill: Vec<u64>,
}

impl FrontQueue {
    /// Empties the queue for a window of `n` pixels and pushes the pixels `seeds` at `T = 0`,
    /// in this order.
    fn reset(&mut self, n: usize, seeds: &[usize]) {
        // Window indices fit in 32 bits with room for the list heads (checked by the caller).
        self.n = n as u32;
        self.next.resize(n + BUCKETS, 0);
        self.tail.clear();
        self.tail.extend((0..BUCKETS as u32).map(|s| self.n + s));
        self.occupied = [0; RING_WORDS];
        self.cur = 0;
        self.cursor = self.n;
        self.late.clear();
        self.late_head = 0;
        self.spill.clear();
        for &wi in seeds {
            self.push(0.0, wi);
        }
    }

    #[inline(always)]
    fn push(&mut self, t: f32, wi: usize) {
        let b = bucket(t);
        let wi32 = wi as u32;
        if b.wrapping_sub(self.cur) < BUCKETS as u64 {
            let slot = (b % BUCKETS as u64) as usize;
            let last = &mut self.tail[slot];
            self.next[*last as usize] = wi32;
            *last = wi32;
            if b != self.cur {
                self.occupied[slot / 64] |= 1 << (slot % 64);
            }
        } else if b < self.cur {
            self.late.push(wi32);
        } else {
            self.spill.push(key(t, wi));
        }
    }

    #[inline(always)]
    fn pop(&mut self) -> Option<usize> {
        if self.late_head < self.late.len() {
            self.late_head += 1;
            return Some(self.late[self.late_head - 1] as usize);
        }
        loop {
            let slot = (self.cur % BUCKETS as u64) as usize;
            if self.cursor != self.tail[slot] {
                self.cursor = self.next[self.cursor as usize];
                return Some(self.cursor as usize);
            }
            self.advance()?;
        }
    }

    /// Makes the next non-empty bucket current; `None` when the queue is empty.
    #[inline(never)]
    fn advance(&mut self) -> Option<()> {
        self.late.clear();
        self.late_head = 0;
        // The current slot is exhausted: empty it (and stay empty if nothing follows).
        let slot = (self.cur % BUCKETS as u64) as usize;
        self.tail[slot] = self.n + slot as u32;
        self.cursor = self.n + slot as u32;
        if self.spill.is_empty() {
            // The first occupied slot after the current one, circularly.
            let start = ((self.cur + 1) % BUCKETS as u64) as usize;
            let (w0, b0) = (start / 64, start % 64);
            let mut found = None;
            for k in 0..=RING_WORDS {
                let w = (w0 + k) % RING_WORDS;
                let mut bits = self.occupied[w];
                if k == 0 {
                    bits &= !0u64 << b0;
                } else if k == RING_WORDS {
                    bits &= (1u64 << b0).wrapping_sub(1);
                }
                if bits != 0 {
                    found = Some(w * 64 + bits.trailing_zeros() as usize);
                    break;
                }
            }
            let slot = found?;
            self.cur += 1 + ((slot + BUCKETS - start) % BUCKETS) as u64;
            self.take(slot);
            return Some(());
        }
        // Slow path, with spilled pixels: one bucket at a time, moving spilled pixels into the
        // ring (in their push order) as it reaches them.
        loop {
            if self.occupied == [0; RING_WORDS] {
                let low = self.spill.iter().map(|&k| key_bucket(k)).min()?;
                self.cur = low.max(self.cur + 1) - 1;
            }
            self.cur += 1;
            let cur = self.cur;
            let spill = std::mem::take(&mut self.spill);
            for &k in &spill {
                let b = key_bucket(k);
                if b < cur + BUCKETS as u64 {
                    let slot = (b % BUCKETS as u64) as usize;
                    let wi = key_index(k) as u32;
                    let last = &mut self.tail[slot];
                    self.next[*last as usize] = wi;
                    *last = wi;
                    self.occupied[slot / 64] |= 1 << (slot % 64);
                } else {
                    self.spill.push(k);
                }
            }
            let slot = (self.cur % BUCKETS as u64) as usize;
            if self.occupied[slot / 64] & (1 << (slot % 64)) != 0 {
                self.take(slot);
                return Some(());
            }
        }
    }

    /// Makes ring slot `slot` the current bucket.
    fn take(&mut self, slot: usize) {
        self.occupied[slot / 64] &= !(1 << (slot % 64));
        self.cursor = self.n + slot as u32;
    }
}

/// Per-thread buffers of the window solves, reused from one group to the next.
#[derive(Default)]
struct Workspace {
    flag: Vec<u8>,
    t: Vec<f32>,
    /// The window's values, one plane per channel.
    vals: Vec<f32>,
    queue: FrontQueue,
    band: Vec<usize>,
    /// The group's runs in window coordinates `(y, x0, x1)`.
    wruns: Vec<(usize, usize, usize)>,
    /// Difference array of a window row (coverage of the grown runs).
    diff: Vec<i32>,
    /// New flags of a row.
    row_flags: Vec<u8>,
    disk: WindowDisk,
    /// Width of the current window.
    ww: usize,
}

impl Workspace {
    /// Windows of more pixels than this are not kept between calls.
    const KEEP_PIXELS: usize = 1 << 18;

    fn trim(&mut self) {
        if self.flag.capacity() > Self::KEEP_PIXELS {
            *self = Workspace::default();
        }
    }
}

thread_local! {
    static WORKSPACE: std::cell::RefCell<Workspace> = std::cell::RefCell::default();
}

/// Runs `f` with this thread's workspace (kept between calls, so that windows and queues do
/// not allocate again), or with a fresh one if it is in use.
fn with_workspace<R>(f: impl FnOnce(&mut Workspace) -> R) -> R {
    WORKSPACE.with(|cell| match cell.try_borrow_mut() {
        Ok(mut ws) => {
            let out = f(&mut ws);
            ws.trim();
            out
        }
        Err(_) => f(&mut Workspace::default()),
    })
}

struct Ctx<'a, 'b, T> {
    img: &'a ImageView<'b, T>,
    radius: usize,
    plan: &'a DiskPlan,
    /// Run the disk arithmetic on AVX2 (see [`march_inward`]).
    avx2: bool,
}

impl<T: Sample> Ctx<'_, '_, T> {
    /// Fills the holes made of `runs` (a group, in its box `bbox`) and writes their pixels to
    /// `out`.
    fn solve(&self, ws: &mut Workspace, bbox: BBox, runs: &[Run], out: Out<'_, T>) {
        match self.img.channels() {
            1 => self.solve_c::<1>(ws, bbox, runs, out),
            2 => self.solve_c::<2>(ws, bbox, runs, out),
            3 => self.solve_c::<3>(ws, bbox, runs, out),
            _ => self.solve_c::<4>(ws, bbox, runs, out),
        }
    }

    /// Solves the holes made of `runs` in their box grown by the plan's margin: at least
    /// `radius + 2`, `radius` for the disk and the outward front, one more for the front's
    /// neighbours, one more so that every read of a processed pixel's 4-neighbours stays inside
    /// the window. Masked pixels of other groups inside the window stay "known": they lie farther
    /// than any read reaches.
    fn solve_c<const C: usize>(
        &self,
        ws: &mut Workspace,
        bbox: BBox,
        runs: &[Run],
        out: Out<'_, T>,
    ) {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: `avx2` is only set after AVX2 and FMA were detected.
            return unsafe { self.solve_avx2::<C>(ws, bbox, runs, out) };
        }
        self.solve_with::<C, Lanes8>(ws, bbox, runs, out)
    }

    /// [`Self::solve_with`] compiled for AVX2 and FMA, the disk arithmetic on AVX registers.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn solve_avx2<const C: usize>(
        &self,
        ws: &mut Workspace,
        bbox: BBox,
        runs: &[Run],
        out: Out<'_, T>,
    ) {
        self.solve_with::<C, avx::Avx8>(ws, bbox, runs, out)
    }

    #[inline(always)]
    fn solve_with<const C: usize, V: Simd8>(
        &self,
        ws: &mut Workspace,
        bbox: BBox,
        runs: &[Run],
        out: Out<'_, T>,
    ) {
        self.prepare::<C, V>(ws, bbox, runs);
        while inward_step::<C, V>(ws) {}
        match out {
            Out::Image(img) => {
                let w = self.img.width();
                for (run, &(wy, wx0, _)) in runs.iter().zip(&ws.wruns) {
                    let span = (run.y * w + run.x0) * C..(run.y * w + run.x1 + 1) * C;
                    convert::<T, C>(ws, wy * ws.ww + wx0, &mut img[span]);
                }
            }
            Out::Runs(values) => {
                let pixels: usize = ws.wruns.iter().map(|r| r.2 + 1 - r.1).sum();
                values.clear();
                values.resize(pixels * C, T::from_f32(0.0));
                let mut at = 0;
                for &(wy, wx0, wx1) in &ws.wruns {
                    let len = (wx1 + 1 - wx0) * C;
                    convert::<T, C>(ws, wy * ws.ww + wx0, &mut values[at..at + len]);
                    at += len;
                }
            }
        }
    }

    /// Builds the window of the group (`bbox`, `runs`) in `ws`, marches the outward front and
    /// queues the inward one.
    #[inline(always)]
    fn prepare<const C: usize, V: Simd8>(&self, ws: &mut Workspace, bbox: BBox, runs: &[Run]) {
        let (ih, iw) = (self.img.height(), self.img.width());
        let r = self.radius;
        let margin = self.plan.margin;
        let (ox, oy) = (
            bbox.x0 as isize - margin as isize,
            bbox.y0 as isize - margin as isize,
        );
        let ww = bbox.x1 - bbox.x0 + 1 + 2 * margin;
        let wh = bbox.y1 - bbox.y0 + 1 + 2 * margin;
        let n = ww * wh;
        let data = self.img.data();

        // Pixels hold arrival time +inf until a front reaches them. A disk pixel weighs
        // 1 / (1 + |T(q) - T(p)|) times the rest, so an unusable pixel (T = +inf: not reached,
        // being filled, outside the image) weighs exactly 0 and, holding a finite value (0 where
        // not set below), adds exactly 0. Only the known pixels within `r` (Chebyshev) of the
        // hole are ever read with a nonzero weight or marched over: they are NEAR and hold their
        // values; the other pixels of the window stay VOID.
        let (flag, t, vals) = (&mut ws.flag, &mut ws.t, &mut ws.vals);
        flag.clear();
        flag.resize(n, VOID);
        t.clear();
        t.resize(n, f32::INFINITY);
        vals.clear();
        vals.resize(C * n, 0.0);
        // The image's columns `x_lo..x_hi` and rows `y_lo..y_hi` in window coordinates.
        let x_lo = (-ox).max(0) as usize;
        let x_hi = ((iw as isize - ox).max(0) as usize).min(ww);
        let y_lo = (-oy).max(0) as usize;
        let y_hi = ((ih as isize - oy).max(0) as usize).min(wh);
        let wr = &mut ws.wruns;
        wr.clear();
        wr.extend(runs.iter().map(|run| {
            let wy = (run.y as isize - oy) as usize;
            let wx0 = (run.x0 as isize - ox) as usize;
            (wy, wx0, wx0 + run.x1 - run.x0)
        }));
        // Per window row, the union of the runs of the rows within `r`, each grown by `r`: a
        // coverage count from a difference array over the row, without sorting the runs.
        let diff = &mut ws.diff;
        diff.clear();
        diff.resize(ww + 1, 0);
        let (first, last) = match (wr.first(), wr.last()) {
            (Some(f), Some(l)) => (f.0, l.0),
            _ => (0, 0),
        };
        let mut lo = 0;
        for wy in first.saturating_sub(r).max(y_lo)..(last + r + 1).min(y_hi) {
            while lo < wr.len() && wr[lo].0 + r < wy {
                lo += 1;
            }
            let (mut a_min, mut b_max) = (ww, 0);
            for run in wr[lo..].iter().take_while(|run| run.0 <= wy + r) {
                let (a, b) = (run.1.saturating_sub(r).max(x_lo), (run.2 + r + 1).min(x_hi));
                if a < b {
                    diff[a] += 1;
                    diff[b] -= 1;
                    a_min = a_min.min(a);
                    b_max = b_max.max(b);
                }
            }
            if a_min >= b_max {
                continue;
            }
            let row = wy * ww;
            let mut cover = 0i32;
            for (f, d) in flag[row + a_min..row + b_max]
                .iter_mut()
                .zip(&mut diff[a_min..b_max])
            {
                cover += *d;
                *d = 0;
                *f = if cover > 0 { NEAR } else { VOID };
            }
            diff[b_max] = 0;
            // Values over the whole covered range (gaps included: read with weight 0 at most).
            let start = (oy + wy as isize) as usize * iw + (ox + a_min as isize) as usize;
            let src = &data[start * C..(start + b_max - a_min) * C];
            for (ch, plane) in vals.chunks_exact_mut(n).enumerate() {
                for (d, px) in plane[row + a_min..row + b_max]
                    .iter_mut()
                    .zip(src.chunks_exact(C))
                {
                    *d = px[ch].to_f32();
                }
            }
        }
        // The holes.
        for &(wy, wx0, wx1) in wr.iter() {
            let (a, b) = (wy * ww + wx0, wy * ww + wx1 + 1);
            flag[a..b].fill(INSIDE);
            for plane in vals.chunks_exact_mut(n) {
                plane[a..b].fill(0.0);
            }
        }
        // The front starts on the NEAR pixels 4-adjacent to the hole, at T = 0; collected in
        // window (= image) raster order, the order they leave the queue in. Branch-free: new
        // flags a row at a time (over the columns of the runs of the row and its two
        // neighbours), then the band pixels' indices compacted.
        let mut band = std::mem::take(&mut ws.band);
        let row_flags = &mut ws.row_flags;
        band.clear();
        row_flags.resize(ww, 0);
        let mut lo = 0;
        for wy in first - 1..=last + 1 {
            while lo < wr.len() && wr[lo].0 + 1 < wy {
                lo += 1;
            }
            let (mut x0, mut x1) = (ww, 0);
            for run in wr[lo..].iter().take_while(|run| run.0 <= wy + 1) {
                x0 = x0.min(run.1 - 1);
                x1 = x1.max(run.2 + 2);
            }
            if x0 >= x1 {
                continue;
            }
            let row = wy * ww;
            let at = |d: isize| {
                let s = (row as isize + d) as usize;
                &flag[s + x0..s + x1]
            };
            let (cur, up, down) = (at(0), at(-(ww as isize)), at(ww as isize));
            let (left, right) = (at(-1), at(1));
            let nbs = up.iter().zip(down).zip(left.iter().zip(right));
            let new = &mut row_flags[..x1 - x0];
            for ((o, &c), ((&u, &d), (&l, &r))) in new.iter_mut().zip(cur).zip(nbs) {
                let inside_nb = (u == INSIDE) | (d == INSIDE) | (l == INSIDE) | (r == INSIDE);
                *o = if (c == NEAR) & inside_nb { BAND } else { c };
            }
            flag[row + x0..row + x1].copy_from_slice(new);
            let k0 = band.len();
            band.resize(k0 + new.len(), 0);
            let dst = &mut band[k0..];
            let mut k = 0;
            for (i, &f) in new.iter().enumerate() {
                if let Some(d) = dst.get_mut(k) {
                    *d = row + x0 + i;
                }
                k += usize::from(f == BAND);
            }
            band.truncate(k0 + k);
        }
        for &wi in band.iter() {
            t[wi] = 0.0;
        }
        ws.band = band;
        let band = &ws.band;

        // Outward front over those pixels; its arrival times, negated, order the known pixels
        // for the level-set weight.
        march_outward::<V>(&mut ws.queue, flag, t, band, ww);

        // Inward front: each pixel is filled when first reached.
        self.plan.place(ww, n, &mut ws.disk);
        ws.queue.reset(n, band);
        ws.ww = ww;
    }
}

/// Where a group's filled pixels go.
enum Out<'a, T> {
    /// The output image (interleaved, the input's layout).
    Image(&'a mut [T]),
    /// A vector of the pixels in run order.
    Runs(&'a mut Vec<T>),
}

/// `dst` (`C` interleaved channels) from the window's planes, from window pixel `at` on: each
/// plane converted in pieces (straight loops, which vectorise), then interleaved.
#[inline(always)]
fn convert<T: Sample, const C: usize>(ws: &Workspace, at: usize, dst: &mut [T]) {
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

/// `p` and its 4-neighbours in `s` (a window `ww` wide): `[up, left, centre, right, down]`, from
/// one bounds check (processed pixels lie inside the window).
#[inline(always)]
fn cross<X: Copy>(s: &[X], p: usize, ww: usize) -> [X; 5] {
    if p > ww && p + ww < s.len() {
        // SAFETY: `p - ww >= 1` and `p + ww < len`, so all five indices are in bounds.
        unsafe {
            [
                *s.get_unchecked(p - ww),
                *s.get_unchecked(p - 1),
                *s.get_unchecked(p),
                *s.get_unchecked(p + 1),
                *s.get_unchecked(p + ww),
            ]
        }
    } else {
        [s[p - ww], s[p - 1], s[p], s[p + 1], s[p + ww]]
    }
}

/// The 4-neighbours of `wi` (up, left, down, right) and, as bits in that order, which of them
/// hold `f` (one mask instead of four unpredictable branches).
#[inline(always)]
fn neighbours_with(flag: &[u8], wi: usize, ww: usize, f: u8) -> ([usize; 4], u32) {
    let [up, left, _, right, down] = cross(flag, wi, ww).map(|x| u32::from(x == f));
    let bits = up | (left << 1) | (down << 2) | (right << 3);
    ([wi - ww, wi - 1, wi + ww, wi + 1], bits)
}

/// Outward front from the band (`T = 0`) over the `NEAR` pixels, which become `KNOWN` with the
/// negated arrival time (the level-set weight then orders known pixels before the hole).
#[inline(always)]
fn march_outward<V: Simd8>(
    queue: &mut FrontQueue,
    flag: &mut [u8],
    t: &mut [f32],
    band: &[usize],
    ww: usize,
) {
    queue.reset(flag.len(), band);
    while let Some(wi) = queue.pop() {
        let (nbs, mut todo) = neighbours_with(flag, wi, ww, NEAR);
        while todo != 0 {
            let nb = nbs[todo.trailing_zeros() as usize & 3];
            todo &= todo - 1;
            // Reached pixels hold -T already: the neighbours' times are the magnitudes (the
            // band's 0 and the others' +inf unchanged).
            let d = V::arrival(cross(t, nb, ww).map(f32::abs));
            t[nb] = -d;
            flag[nb] = KNOWN;
            queue.push(d, nb);
        }
    }
}

/// Whether the disk arithmetic may run on AVX2 (with FMA).
fn detect_avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// One step of the inward front: pops a pixel (in arrival-time order) and fills each of its
/// `INSIDE` 4-neighbours, which then join the front. False when the front is done.
#[inline(always)]
fn inward_step<const C: usize, V: Simd8>(ws: &mut Workspace) -> bool {
    let Workspace {
        queue,
        flag,
        t,
        vals,
        disk,
        ww,
        ..
    } = ws;
    let ww = *ww;
    let Some(wi) = queue.pop() else {
        return false;
    };
    let n = flag.len();
    let sized = t.len() == n && vals.len() == C * n;
    flag[wi] = KNOWN;
    let (nbs, mut todo) = neighbours_with(flag, wi, ww, INSIDE);
    while todo != 0 {
        let nb = nbs[todo.trailing_zeros() as usize & 3];
        todo &= todo - 1;
        // `t[nb]` is set after the fill: until then it is +inf, which the fill's centre lane
        // (weight 0) reads harmlessly.
        let (tp, gx, gy) = V::arrival_grad(cross(t, nb, ww));
        let grad = (gx, gy);
        let v = if sized && disk.covers(nb) {
            // SAFETY: every read of the fill at `nb` is inside the window (`covers`), and
            // `t` and each plane of `vals` hold the window's `n` pixels.
            unsafe { fill::<C, V, false>(nb, wi, tp, grad, disk, t, vals, n) }
        } else {
            // SAFETY: checked reads (never taken: fills lie `margin` inside the window).
            unsafe { fill::<C, V, true>(nb, wi, tp, grad, disk, t, vals, n) }
        };
        for (ch, &x) in v.iter().enumerate() {
            vals[ch * n + nb] = x;
        }
        t[nb] = tp;
        flag[nb] = BAND;
        queue.push(tp, nb);
    }
    true
}

/// Eight `f32` lanes, the unit of the disk arithmetic. Two implementations: [`Lanes8`] (plain
/// arrays, any CPU) and `avx::Avx8` (one AVX register). Every operation is lane-wise IEEE
/// arithmetic and [`Simd8::sum`] adds in the same tree in both, so both give bit-identical results.
trait Simd8: Copy {
    fn splat(v: f32) -> Self;
    fn load(a: &[f32; LANES]) -> Self;
    /// # Safety
    /// `p` points at eight readable `f32`.
    unsafe fn load_ptr(p: *const f32) -> Self;
    fn add(self, o: Self) -> Self;
    fn sub(self, o: Self) -> Self;
    fn mul(self, o: Self) -> Self;
    /// `self * o + c`, rounded once.
    fn mul_add(self, o: Self, c: Self) -> Self;
    fn div(self, o: Self) -> Self;
    fn abs(self) -> Self;
    /// `floor` in the lanes where `self <= limit`, else `self`.
    fn floor_small(self, limit: Self, floor: Self) -> Self;
    /// `((l0 + l1) + (l2 + l3)) + ((l4 + l5) + (l6 + l7))`.
    fn sum(self) -> f32;
    /// The sums of four vectors, each as [`Simd8::sum`] adds.
    fn sum4(a: Self, b: Self, c: Self, d: Self) -> [f32; 4] {
        [a.sum(), b.sum(), c.sum(), d.sum()]
    }
    /// Weighted means of three channels: with `s = sum4(sums) + extra` (lane-wise),
    /// `reference[k] + s[k + 1] / s[0]`.
    #[inline(always)]
    fn mean3(sums: [Self; 4], extra: [f32; 4], reference: [f32; 3]) -> [f32; 3] {
        let s = Self::sum4(sums[0], sums[1], sums[2], sums[3]);
        let s: [f32; 4] = std::array::from_fn(|k| s[k] + extra[k]);
        std::array::from_fn(|k| reference[k] + s[k + 1] / s[0])
    }
    /// [`arrival`] from a pixel's [`cross`] of times.
    #[inline(always)]
    fn arrival(t: [f32; 5]) -> f32 {
        arrival(&t)
    }
    /// Arrival time and `T` gradient of a pixel from its [`cross`] of times: [`arrival`] and
    /// [`grad_t`] (known neighbours are those with a finite time: the band, filled pixels).
    #[inline(always)]
    fn arrival_grad(t: [f32; 5]) -> (f32, f32, f32) {
        let tp = arrival(&t);
        let known = t.map(|v| u8::from(v == f32::INFINITY) * INSIDE);
        let (gx, gy) = grad_t(&known, &t, tp);
        (tp, gx, gy)
    }
}

/// [`Simd8`] on plain arrays (the fallback for CPUs without AVX2).
#[derive(Debug, Clone, Copy)]
struct Lanes8([f32; LANES]);

impl Lanes8 {
    #[inline(always)]
    fn zip(self, o: Lanes8, f: impl Fn(f32, f32) -> f32) -> Lanes8 {
        Lanes8(std::array::from_fn(|l| f(self.0[l], o.0[l])))
    }
}

impl Simd8 for Lanes8 {
    #[inline(always)]
    fn splat(v: f32) -> Self {
        Lanes8([v; LANES])
    }
    #[inline(always)]
    fn load(a: &[f32; LANES]) -> Self {
        Lanes8(*a)
    }
    #[inline(always)]
    unsafe fn load_ptr(p: *const f32) -> Self {
        // SAFETY: the caller's contract.
        Lanes8(unsafe { p.cast::<[f32; LANES]>().read_unaligned() })
    }
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        self.zip(o, |a, b| a + b)
    }
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        self.zip(o, |a, b| a - b)
    }
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        self.zip(o, |a, b| a * b)
    }
    #[inline(always)]
    fn mul_add(self, o: Self, c: Self) -> Self {
        Lanes8(std::array::from_fn(|l| self.0[l].mul_add(o.0[l], c.0[l])))
    }
    #[inline(always)]
    fn div(self, o: Self) -> Self {
        self.zip(o, |a, b| a / b)
    }
    #[inline(always)]
    fn abs(self) -> Self {
        self.zip(self, |a, _| a.abs())
    }
    #[inline(always)]
    fn floor_small(self, limit: Self, floor: Self) -> Self {
        Lanes8(std::array::from_fn(|l| {
            let a = self.0[l];
            if a <= limit.0[l] {
                floor.0[l]
            } else {
                a
            }
        }))
    }
    #[inline(always)]
    fn sum(self) -> f32 {
        let a = self.0;
        ((a[0] + a[1]) + (a[2] + a[3])) + ((a[4] + a[5]) + (a[6] + a[7]))
    }
}

#[cfg(target_arch = "x86_64")]
mod avx {
    //! [`Simd8`] on one AVX register. Only reached from functions compiled with AVX2 enabled
    //! and called after the CPU reported it (`march_inward_avx2`).
    use std::arch::x86_64::*;

    use super::{Simd8, LANES};

    #[derive(Clone, Copy)]
    pub(super) struct Avx8(__m256);

    /// [`Simd8::sum4`] into one SSE register: pairs, then pairs of pairs, per 128-bit half; then
    /// the two halves.
    ///
    /// # Safety
    /// The CPU has AVX.
    #[inline(always)]
    unsafe fn sum4_sse(v: [Avx8; 4]) -> __m128 {
        // SAFETY: the caller's contract.
        unsafe {
            let ab = _mm256_hadd_ps(v[0].0, v[1].0);
            let cd = _mm256_hadd_ps(v[2].0, v[3].0);
            let abcd = _mm256_hadd_ps(ab, cd);
            _mm_add_ps(
                _mm256_castps256_ps128(abcd),
                _mm256_extractf128_ps::<1>(abcd),
            )
        }
    }

    /// [`super::arrival`] on SSE registers: `(lo, hi, T)` with lanes (x, y) of the low
    /// neighbours (left, up) and the high ones (right, down), and the time in lane 0.
    ///
    /// # Safety
    /// The CPU has SSE4.1 (implied by AVX).
    #[inline(always)]
    unsafe fn sse_arrival(t: [f32; 5]) -> (__m128, __m128, __m128) {
        // SAFETY: the caller's contract.
        unsafe {
            let lo = _mm_setr_ps(t[1], t[0], 0.0, 0.0);
            let hi = _mm_setr_ps(t[3], t[4], 0.0, 0.0);
            // b = min(left, right), a = min(up, down) (as `min2`); solve_pair(a, b).
            let m = _mm_min_ps(hi, lo);
            let b = m;
            let a = _mm_movehdup_ps(m);
            let d = _mm_sub_ss(a, b);
            let far = _mm_add_ss(_mm_set_ss(1.0), _mm_min_ss(b, a));
            let root = _mm_sqrt_ss(_mm_sub_ss(_mm_set_ss(2.0), _mm_mul_ss(d, d)));
            let near = _mm_mul_ss(_mm_add_ss(_mm_add_ss(a, b), root), _mm_set_ss(0.5));
            let abs_d = _mm_and_ps(d, _mm_castsi128_ps(_mm_set1_epi32(i32::MAX)));
            let is_far = _mm_cmpge_ss(abs_d, _mm_set_ss(1.0));
            (lo, hi, _mm_blendv_ps(near, far, is_far))
        }
    }

    // SAFETY (every block below): the intrinsics need AVX, which the CPU has (these methods are
    // only called from `march_inward_avx2`, entered after AVX2 was detected); loads read the
    // eight floats of an `&[f32; 8]`.
    impl Simd8 for Avx8 {
        #[inline(always)]
        fn splat(v: f32) -> Self {
            Avx8(unsafe { _mm256_set1_ps(v) })
        }
        #[inline(always)]
        fn load(a: &[f32; LANES]) -> Self {
            Avx8(unsafe { _mm256_loadu_ps(a.as_ptr()) })
        }
        #[inline(always)]
        unsafe fn load_ptr(p: *const f32) -> Self {
            Avx8(unsafe { _mm256_loadu_ps(p) })
        }
        #[inline(always)]
        fn add(self, o: Self) -> Self {
            Avx8(unsafe { _mm256_add_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn sub(self, o: Self) -> Self {
            Avx8(unsafe { _mm256_sub_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn mul(self, o: Self) -> Self {
            Avx8(unsafe { _mm256_mul_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn mul_add(self, o: Self, c: Self) -> Self {
            Avx8(unsafe { _mm256_fmadd_ps(self.0, o.0, c.0) })
        }
        #[inline(always)]
        fn div(self, o: Self) -> Self {
            Avx8(unsafe { _mm256_div_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn abs(self) -> Self {
            Avx8(unsafe { _mm256_and_ps(self.0, _mm256_castsi256_ps(_mm256_set1_epi32(i32::MAX))) })
        }
        #[inline(always)]
        fn floor_small(self, limit: Self, floor: Self) -> Self {
            unsafe {
                let small = _mm256_cmp_ps::<_CMP_LE_OQ>(self.0, limit.0);
                Avx8(_mm256_blendv_ps(self.0, floor.0, small))
            }
        }
        #[inline(always)]
        fn sum(self) -> f32 {
            Self::sum4(self, self, self, self)[0]
        }
        #[inline(always)]
        fn arrival(t: [f32; 5]) -> f32 {
            unsafe { _mm_cvtss_f32(sse_arrival(t).2) }
        }
        #[inline(always)]
        fn mean3(sums: [Self; 4], extra: [f32; 4], reference: [f32; 3]) -> [f32; 3] {
            unsafe {
                let s = _mm_add_ps(sum4_sse(sums), _mm_loadu_ps(extra.as_ptr()));
                let num = _mm_shuffle_ps::<0b11_11_10_01>(s, s);
                let den = _mm_shuffle_ps::<0>(s, s);
                let r = _mm_setr_ps(reference[0], reference[1], reference[2], 0.0);
                let m = _mm_add_ps(r, _mm_div_ps(num, den));
                let mut out = [0.0f32; 4];
                _mm_storeu_ps(out.as_mut_ptr(), m);
                [out[0], out[1], out[2]]
            }
        }
        #[inline(always)]
        fn arrival_grad(t: [f32; 5]) -> (f32, f32, f32) {
            unsafe {
                let (lo, hi, tp) = sse_arrival(t);
                // gradient: unknown sides stand in with T(p).
                let tpv = _mm_shuffle_ps::<0>(tp, tp);
                let inf = _mm_set1_ps(f32::INFINITY);
                let (lo_ok, hi_ok) = (_mm_cmplt_ps(lo, inf), _mm_cmplt_ps(hi, inf));
                let hi_v = _mm_blendv_ps(tpv, hi, hi_ok);
                let lo_v = _mm_blendv_ps(tpv, lo, lo_ok);
                let half =
                    _mm_blendv_ps(_mm_set1_ps(1.0), _mm_set1_ps(0.5), _mm_and_ps(lo_ok, hi_ok));
                let g = _mm_mul_ps(_mm_sub_ps(hi_v, lo_v), half);
                let mut out = [0.0f32; 4];
                _mm_storeu_ps(out.as_mut_ptr(), g);
                (_mm_cvtss_f32(tp), out[0], out[1])
            }
        }
        #[inline(always)]
        fn sum4(a: Self, b: Self, c: Self, d: Self) -> [f32; 4] {
            unsafe {
                let mut out = [0.0f32; 4];
                _mm_storeu_ps(out.as_mut_ptr(), sum4_sse([a, b, c, d]));
                out
            }
        }
    }
}

/// The eight values of `s` from `at` (in bounds by construction; zeros otherwise, never seen).
#[inline(always)]
fn lanes_at(s: &[f32], at: usize) -> &[f32; LANES] {
    const ZEROS: [f32; LANES] = [0.0; LANES];
    s.get(at..)
        .and_then(|s| s.first_chunk::<LANES>())
        .unwrap_or(&ZEROS)
}

/// Telea's weights of one chunk of disk pixels (arrival times `tq`) for the pixel being filled
/// (arrival time `tp`, gradient `(gx, gy)`): `direction * level-set * geometric`, the direction
/// term floored so that no neighbour drops out; `geometric * direction` as one term,
/// `|g r . grad T|` (floored at `g` times the floor where at most `g` times the limit).
#[inline(always)]
fn chunk_weights<V: Simd8>(tq: V, tp: V, gx: V, gy: V, lanes: &Lanes) -> V {
    let one = V::splat(1.0);
    let level = one.div(one.add(tq.sub(tp).abs()));
    let g_dir = V::load(&lanes.g_rx)
        .mul_add(gx, V::load(&lanes.g_ry).mul(gy))
        .abs()
        .floor_small(V::load(&lanes.g_limit), V::load(&lanes.g_floor));
    level.mul(g_dir)
}

/// Eight values of `s` from `at`.
///
/// # Safety
/// Unless `CHECKED`, `at + 8 <= s.len()`.
#[inline(always)]
unsafe fn load8<V: Simd8, const CHECKED: bool>(s: &[f32], at: usize) -> V {
    if CHECKED {
        V::load(lanes_at(s, at))
    } else {
        debug_assert!(at + LANES <= s.len());
        // SAFETY: the caller's contract.
        unsafe { V::load_ptr(s.as_ptr().add(at)) }
    }
}

/// The value of `s` at `at`.
///
/// # Safety
/// Unless `CHECKED`, `at < s.len()`.
#[inline(always)]
unsafe fn load1<const CHECKED: bool>(s: &[f32], at: usize) -> f32 {
    if CHECKED {
        s.get(at).copied().unwrap_or(0.0)
    } else {
        debug_assert!(at < s.len());
        // SAFETY: the caller's contract.
        unsafe { *s.get_unchecked(at) }
    }
}

/// What one fill's chunks share.
struct Chunk<'a, const C: usize, V> {
    p: usize,
    tp: V,
    gx: V,
    gy: V,
    refs: [V; C],
    t: &'a [f32],
    vals: &'a [f32],
    n: usize,
}

impl<const C: usize, V: Simd8> Chunk<'_, C, V> {
    /// Adds the weights of one direct chunk (window offset `off`) to `acc_w` and the weighted
    /// differences from the reference values to `acc`.
    ///
    /// # Safety
    /// As [`fill`]: unless `CHECKED`, every read of the chunk lies inside `t` and each plane.
    #[inline(always)]
    unsafe fn direct<const CHECKED: bool>(
        &self,
        (off, lanes): &(isize, Lanes),
        acc_w: &mut V,
        acc: &mut [V; C],
    ) {
        let q = self.p.wrapping_add_signed(*off);
        // SAFETY: the caller's contract.
        let tq = unsafe { load8::<V, CHECKED>(self.t, q) };
        let w = chunk_weights(tq, self.tp, self.gx, self.gy, lanes);
        for (ch, a) in acc.iter_mut().enumerate() {
            // SAFETY: the caller's contract.
            let v = unsafe { load8::<V, CHECKED>(self.vals, ch * self.n + q) };
            *a = w.mul_add(v.sub(self.refs[ch]), *a);
        }
        *acc_w = acc_w.add(w);
    }
}

/// Telea's weighted mean at window pixel `p` (arrival time `tp`, gradient `grad`) over the usable
/// disk pixels, taken relative to `src`, the known pixel whose front reached `p`: equal
/// neighbours give exactly their value. `vals` holds one plane of `n` values per channel.
///
/// # Safety
/// Unless `CHECKED`: `disk.covers(p)`, `t.len() == n` and `vals.len() == C * n`.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
unsafe fn fill<const C: usize, V: Simd8, const CHECKED: bool>(
    p: usize,
    src: usize,
    tp: f32,
    (gx, gy): (f32, f32),
    disk: &WindowDisk,
    t: &[f32],
    vals: &[f32],
    n: usize,
) -> [f32; C] {
    let mut reference = [0.0f32; C];
    for (ch, v) in reference.iter_mut().enumerate() {
        *v = vals[ch * n + src];
    }
    let refs = reference.map(V::splat);
    let (tp_s, gx_s, gy_s) = (tp, gx, gy);
    let (tp, gx, gy) = (V::splat(tp), V::splat(gx), V::splat(gy));
    let zero = V::splat(0.0);
    let (mut acc_w, mut acc) = (zero, [zero; C]);
    let at = Chunk {
        p,
        tp,
        gx,
        gy,
        refs,
        t,
        vals,
        n,
    };
    for chunk in &disk.direct {
        // SAFETY: the caller's contract: `covers(p)` puts every read of a direct chunk inside
        // the window (unless CHECKED).
        unsafe { at.direct::<CHECKED>(chunk, &mut acc_w, &mut acc) };
    }
    for (offs, lanes) in &disk.gathered {
        let q = offs.map(|o| p.wrapping_add_signed(o));
        // SAFETY: as above, for every gathered lane.
        let tq = q.map(|q| unsafe { load1::<CHECKED>(t, q) });
        let w = chunk_weights(V::load(&tq), tp, gx, gy, lanes);
        for (ch, a) in acc.iter_mut().enumerate() {
            // SAFETY: as above.
            let v = q.map(|q| unsafe { load1::<CHECKED>(vals, ch * n + q) });
            *a = w.mul_add(V::load(&v).sub(refs[ch]), *a);
        }
        acc_w = acc_w.add(w);
    }
    // Single pixels, in scalar arithmetic (the same on every CPU).
    let (mut single_w, mut single) = (0.0f32, [0.0f32; C]);
    for &(off, [rx, ry, g]) in &disk.single {
        let q = p.wrapping_add_signed(off);
        // SAFETY: as above.
        let tq = unsafe { load1::<CHECKED>(t, q) };
        let level = 1.0 / (1.0 + (tq - tp_s).abs());
        let dir = (rx * gx_s + ry * gy_s).abs();
        let w = g * level * pick(dir <= MIN_DIRECTION, DIRECTION_FLOOR, dir);
        single_w += w;
        for (ch, a) in single.iter_mut().enumerate() {
            // SAFETY: as above.
            *a += w * (unsafe { load1::<CHECKED>(vals, ch * n + q) } - reference[ch]);
        }
    }
    // The sum is > 0: `src` is a known 4-neighbour of p, inside the disk since radius >= 1.
    // Channels 0..3 in one go (one vector division); a fourth one alone.
    let ch = |k: usize| if k < C { acc[k % C] } else { zero };
    let at = |a: &[f32; C], k: usize| if k < C { a[k % C] } else { 0.0 };
    let mean = V::mean3(
        [acc_w, ch(0), ch(1), ch(2)],
        [single_w, at(&single, 0), at(&single, 1), at(&single, 2)],
        [at(&reference, 0), at(&reference, 1), at(&reference, 2)],
    );
    let mut out = reference;
    for (o, m) in out.iter_mut().zip(mean) {
        *o = m;
    }
    if C > 3 {
        let sum_w = acc_w.sum() + single_w;
        out[3 % C] = reference[3 % C] + (acc[3 % C].sum() + single[3 % C]) / sum_w;
    }
    out
}

/// All ones if `c`, else 0, hidden from the optimiser: it would otherwise turn the selections
/// built on it back into branches, mispredicted about half the time on these conditions.
#[inline(always)]
fn mask_if(c: bool) -> u32 {
    #[allow(unused_mut)]
    let mut m = 0u32.wrapping_sub(u32::from(c));
    #[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
    // SAFETY: an empty instruction sequence; it only makes `m` opaque to the compiler.
    unsafe {
        std::arch::asm!("/* {0:e} */", inout(reg) m, options(pure, nomem, nostack, preserves_flags));
    }
    m
}

/// `a` if `c`, else `b`, without a branch.
#[inline(always)]
fn pick(c: bool, a: f32, b: f32) -> f32 {
    let m = mask_if(c);
    f32::from_bits((a.to_bits() & m) | (b.to_bits() & !m))
}

/// Gradient of `T` at a pixel (arrival time `tp`) from its known 4-neighbours (flags `f` and
/// times `t` of the pixel's [`cross`]): central, one-sided, or 0.
#[inline(always)]
fn grad_t(f: &[u8; 5], t: &[f32; 5], tp: f32) -> (f32, f32) {
    let axis = |lo: usize, hi: usize| -> f32 {
        let (lo_ok, hi_ok) = (f[lo] <= BAND, f[hi] <= BAND);
        // An unknown side stands in with T(p): one-sided differences, or 0 with neither.
        let (a, b) = (pick(hi_ok, t[hi], tp), pick(lo_ok, t[lo], tp));
        (a - b) * pick(lo_ok & hi_ok, 0.5, 1.0)
    };
    (axis(1, 3), axis(0, 4))
}

/// The lesser of `a` and `b` (no NaN handling: times are never NaN).
#[inline(always)]
fn min2(a: f32, b: f32) -> f32 {
    if b < a {
        b
    } else {
        a
    }
}

/// First-order upwind arrival time at a pixel from its 4-neighbours (times `t` of its
/// [`cross`]; unreached ones hold `+inf`). OpenCV takes the least of the four (vertical,
/// horizontal) pairings; [`solve_pair`] is nondecreasing in both arguments, so that least is the
/// pairing of the two smaller neighbours.
#[inline(always)]
fn arrival(t: &[f32; 5]) -> f32 {
    solve_pair(min2(t[0], t[4]), min2(t[1], t[3]))
}

/// Solution of `|grad T| = 1` from one vertical and one horizontal neighbour (in `f32`: OpenCV
/// uses `f64` here, which changes arrival times by about 1e-7 relative and costs latency).
/// Branch-free: both candidates are computed (the square root of a negative number, NaN, is
/// dropped).
#[inline(always)]
fn solve_pair(a: f32, b: f32) -> f32 {
    let d = a - b;
    let far = 1.0 + min2(a, b);
    let near = (a + b + (2.0 - d * d).sqrt()) * 0.5;
    pick(d.abs() >= 1.0, far, near)
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

    /// A small deterministic generator for the randomised tests.
    struct Lcg(u64);

    impl Lcg {
        fn next(&mut self) -> u64 {
            self.0 = self
                .0
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            self.0 >> 33
        }
        fn below(&mut self, n: u64) -> u64 {
            self.next() % n
        }
    }

    #[test]
    fn simd_and_portable_paths_agree_bit_for_bit() {
        let mut rng = Lcg(7);
        for case in 0..40 {
            let (h, w) = (8 + rng.below(40) as usize, 8 + rng.below(50) as usize);
            let c = [1, 2, 3, 4][case % 4];
            let density = 1 + rng.below(40);
            let mask: Vec<u8> = (0..h * w)
                .map(|_| u8::from(rng.below(100) < density))
                .collect();
            if mask.iter().all(|&m| m != 0) {
                continue;
            }
            let img: Vec<f32> = (0..h * w * c)
                .map(|_| rng.below(1000) as f32 * 0.37)
                .collect();
            let img8: Vec<u8> = img.iter().map(|&v| v as u8).collect();
            for r in [1, 2, 3, 5, 8] {
                let v = view(&img, h, w, c);
                let a = inpaint_impl(&v, &mask, r, true, true).unwrap();
                let b = inpaint_impl(&v, &mask, r, true, false).unwrap();
                assert!(
                    a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()),
                    "f32 case {case} r={r}"
                );
                let v = view(&img8, h, w, c);
                let a = inpaint_impl(&v, &mask, r, true, true).unwrap();
                let b = inpaint_impl(&v, &mask, r, true, false).unwrap();
                assert_eq!(a, b, "u8 case {case} r={r}");
            }
        }
    }

    #[test]
    fn mask_runs_match_a_plain_scan() {
        let mut rng = Lcg(3);
        for _ in 0..300 {
            let (h, w) = (1 + rng.below(5) as usize, 1 + rng.below(200) as usize);
            let density = rng.below(100);
            let mask: Vec<u8> = (0..h * w)
                .map(|_| match rng.below(100) < density {
                    true => [1, 7, 255][rng.below(3) as usize],
                    false => 0,
                })
                .collect();
            let mut expected = Vec::new();
            for y in 0..h {
                let mut x = 0;
                while x < w {
                    if mask[y * w + x] != 0 {
                        let x0 = x;
                        while x < w && mask[y * w + x] != 0 {
                            x += 1;
                        }
                        expected.push((y, x0, x - 1));
                    } else {
                        x += 1;
                    }
                }
            }
            let got: Vec<_> = mask_runs(&mask, h, w)
                .iter()
                .map(|r| (r.y, r.x0, r.x1))
                .collect();
            assert_eq!(got, expected, "{h}x{w}");
        }
    }

    #[test]
    fn front_queue_pops_by_bucket_then_push_order() {
        use std::collections::{BTreeMap, VecDeque};
        let mut rng = Lcg(11);
        for round in 0..200 {
            let n = 4000;
            let mut q = FrontQueue::default();
            let seeds: Vec<usize> = (0..1 + rng.below(20) as usize).collect();
            q.reset(n, &seeds);
            // Reference: buckets in order, first in first out; pushes below the current bucket
            // pop next.
            let mut buckets: BTreeMap<u64, VecDeque<usize>> = BTreeMap::new();
            buckets.insert(0, seeds.iter().copied().collect());
            let (mut cur, mut late) = (0u64, VecDeque::new());
            let mut next_id = seeds.len();
            let mut t_now = 0.0f32;
            loop {
                let expected = late.pop_front().or_else(|| loop {
                    if let Some(v) = buckets.get_mut(&cur).and_then(|d| d.pop_front()) {
                        break Some(v);
                    }
                    buckets.retain(|_, d| !d.is_empty());
                    match buckets.range(cur + 1..).next() {
                        Some((&b, _)) => cur = b,
                        None => break None,
                    }
                });
                let got = q.pop();
                assert_eq!(got, expected, "round {round}");
                let Some(_) = got else { break };
                if round % 7 == 0 && next_id > 3000 {
                    continue;
                }
                // A few pushes, mostly just ahead, sometimes far ahead (past the ring) or
                // behind the current bucket.
                for _ in 0..rng.below(3) {
                    if next_id >= n {
                        break;
                    }
                    let t = match rng.below(20) {
                        0 => t_now + 20.0 + rng.below(2000) as f32 * 0.37,
                        1 => (t_now - rng.below(100) as f32 * 0.01).max(0.0),
                        _ => t_now + rng.below(100) as f32 * 0.011,
                    };
                    q.push(t, next_id);
                    let b = bucket(t);
                    if b < cur {
                        late.push_back(next_id);
                    } else {
                        buckets.entry(b).or_default().push_back(next_id);
                    }
                    next_id += 1;
                }
                t_now = cur as f32 / BUCKET_SCALE;
            }
            assert_eq!(q.pop(), None);
        }
    }

    #[test]
    fn disk_plans_cover_each_disk_pixel_once() {
        for r in 1..=20usize {
            let plan = DiskPlan::new(r);
            let mut seen = std::collections::HashMap::new();
            let mut add = |dx: isize, dy: isize, g: f32| {
                if g != 0.0 {
                    *seen.entry((dx, dy)).or_insert(0) += 1;
                }
            };
            for (&(x0, dy), lanes) in plan.direct.iter().zip(&plan.direct_lanes) {
                for l in 0..LANES {
                    add(x0 + l as isize, dy, lanes.geometric[l]);
                }
            }
            for (at, lanes) in plan.gathered.iter().zip(&plan.gathered_lanes) {
                for (&(dx, dy), &g) in at.iter().zip(&lanes.geometric) {
                    add(dx, dy, g);
                }
            }
            for &((dx, dy), [_, _, g]) in &plan.single {
                add(dx, dy, g);
            }
            let ri = r as isize;
            for dy in -ri..=ri {
                for dx in -ri..=ri {
                    let inside = (dx, dy) != (0, 0) && dx * dx + dy * dy <= ri * ri;
                    let count = seen.get(&(dx, dy)).copied().unwrap_or(0);
                    assert_eq!(count, usize::from(inside), "r={r} ({dx}, {dy})");
                }
            }
            assert_eq!(seen.len(), seen.values().filter(|&&c| c == 1).count());
            assert!(plan.margin >= r + 2 && plan.margin <= 2 * r + 2, "r={r}");
        }
    }

    #[test]
    fn many_groups_equal_global_solve() {
        // A grid of separate holes: groups are solved two at a time, interleaved.
        let (h, w, c) = (150, 210, 3);
        let centres: Vec<(f32, f32)> = (0..5)
            .flat_map(|j| (0..7).map(move |i| (15.0 + 30.0 * i as f32, 15.0 + 30.0 * j as f32)))
            .collect();
        let mask = disc_mask(h, w, &centres, 6.3);
        let img = textured(h, w, c, &mask);
        let img8: Vec<u8> = img.iter().map(|&v| v as u8).collect();
        for r in [1, 3, 5] {
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

    /// `RAYON_NUM_THREADS=1 cargo test --release -p tacswitch-core profile_telea -- --ignored
    /// --nocapture`: median and least time per call, 48 holes in a 640x480 BGR frame. Under
    /// `perf record` (with `CARGO_PROFILE_RELEASE_DEBUG=line-tables-only`), or `valgrind
    /// --tool=callgrind` for instruction counts that a busy machine does not disturb. Settings:
    /// `TELEA_PROFILE_R=3` (radii, comma-separated), `TELEA_PROFILE_N=200` (calls per radius),
    /// `TELEA_PROFILE_FRAME=/tmp/f` (frame and mask from `/tmp/f_img.raw`, `/tmp/f_mask.raw`),
    /// `TELEA_PROFILE=global` (the one-window reference solve).
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
                let (cx, cy): (usize, usize) = (40 + 80 * i, 40 + 80 * j);
                for y in cy - 13..=cy + 13 {
                    for x in cx - 13..=cx + 13 {
                        let (dx, dy) = (x.abs_diff(cx), y.abs_diff(cy));
                        if dx * dx + dy * dy <= 169 {
                            mask[y * w + x] = 1;
                        }
                    }
                }
            }
        }
        // Raw bytes, e.g. numpy's `tofile`.
        if let Ok(prefix) = std::env::var("TELEA_PROFILE_FRAME") {
            img = std::fs::read(format!("{prefix}_img.raw")).unwrap();
            mask = std::fs::read(format!("{prefix}_mask.raw")).unwrap();
        }
        let view = ImageView::new(&img, h, w, 3, "img").unwrap();
        let global = std::env::var("TELEA_PROFILE").is_ok_and(|v| v == "global");
        let radii: Vec<usize> = match std::env::var("TELEA_PROFILE_R") {
            Ok(v) => v.split(',').filter_map(|s| s.trim().parse().ok()).collect(),
            Err(_) => vec![3, 5],
        };
        let runs: usize = std::env::var("TELEA_PROFILE_N")
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(60);
        for r in radii {
            let mut times: Vec<f64> = (0..runs)
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
            println!(
                "r={r}: median {:.3} ms, min {:.3} ms",
                times[runs / 2],
                times[0]
            );
        }
    }
}
