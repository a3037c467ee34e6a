//! The narrow-band march: a group's window (`Workspace`), its outward front (negated arrival
//! times of the known pixels near the hole) and its inward front (each hole pixel filled when
//! first reached), with the upwind arrival-time and gradient updates.

use super::*;

/// Per-thread buffers of the window solves, reused from one group to the next.
#[derive(Default)]
pub(super) struct Workspace {
    pub(super) flag: Vec<u8>,
    pub(super) t: Vec<f32>,
    /// The window's values, one plane per channel.
    pub(super) vals: Vec<f32>,
    pub(super) queue: FrontQueue,
    pub(super) band: Vec<usize>,
    /// The group's runs in window coordinates `(y, x0, x1)`.
    pub(super) wruns: Vec<(usize, usize, usize)>,
    /// Difference array of a window row (coverage of the grown runs).
    pub(super) diff: Vec<i32>,
    /// New flags of a row.
    pub(super) row_flags: Vec<u8>,
    pub(super) disk: WindowDisk,
    /// Width of the current window.
    pub(super) ww: usize,
}

impl Workspace {
    /// Windows of more pixels than this are not kept between calls.
    pub(super) const KEEP_PIXELS: usize = 1 << 18;

    pub(super) fn trim(&mut self) {
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
pub(super) fn with_workspace<R>(f: impl FnOnce(&mut Workspace) -> R) -> R {
    WORKSPACE.with(|cell| match cell.try_borrow_mut() {
        Ok(mut ws) => {
            let out = f(&mut ws);
            ws.trim();
            out
        }
        Err(_) => f(&mut Workspace::default()),
    })
}

pub(super) struct Ctx<'a, 'b, T> {
    pub(super) img: &'a ImageView<'b, T>,
    pub(super) radius: usize,
    pub(super) plan: &'a DiskPlan,
    /// Run the disk arithmetic on AVX2 (see [`march_inward`]).
    pub(super) avx2: bool,
}

impl<T: Sample> Ctx<'_, '_, T> {
    /// Fills the holes made of `runs` (a group, in its box `bbox`) and writes their pixels to
    /// `out`.
    pub(super) fn solve(&self, ws: &mut Workspace, bbox: BBox, runs: &[Run], out: Out<'_, T>) {
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
    pub(super) fn solve_c<const C: usize>(
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
    pub(super) unsafe fn solve_avx2<const C: usize>(
        &self,
        ws: &mut Workspace,
        bbox: BBox,
        runs: &[Run],
        out: Out<'_, T>,
    ) {
        self.solve_with::<C, avx::Avx8>(ws, bbox, runs, out)
    }

    #[inline(always)]
    pub(super) fn solve_with<const C: usize, V: Simd8>(
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
    pub(super) fn prepare<const C: usize, V: Simd8>(
        &self,
        ws: &mut Workspace,
        bbox: BBox,
        runs: &[Run],
    ) {
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
/// `p` and its 4-neighbours in `s` (a window `ww` wide): `[up, left, centre, right, down]`, from
/// one bounds check (processed pixels lie inside the window).
#[inline(always)]
pub(super) fn cross<X: Copy>(s: &[X], p: usize, ww: usize) -> [X; 5] {
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
pub(super) fn neighbours_with(flag: &[u8], wi: usize, ww: usize, f: u8) -> ([usize; 4], u32) {
    let [up, left, _, right, down] = cross(flag, wi, ww).map(|x| u32::from(x == f));
    let bits = up | (left << 1) | (down << 2) | (right << 3);
    ([wi - ww, wi - 1, wi + ww, wi + 1], bits)
}

/// Outward front from the band (`T = 0`) over the `NEAR` pixels, which become `KNOWN` with the
/// negated arrival time (the level-set weight then orders known pixels before the hole).
#[inline(always)]
pub(super) fn march_outward<V: Simd8>(
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
/// One step of the inward front: pops a pixel (in arrival-time order) and fills each of its
/// `INSIDE` 4-neighbours, which then join the front. False when the front is done.
#[inline(always)]
pub(super) fn inward_step<const C: usize, V: Simd8>(ws: &mut Workspace) -> bool {
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
/// Gradient of `T` at a pixel (arrival time `tp`) from its known 4-neighbours (flags `f` and
/// times `t` of the pixel's [`cross`]): central, one-sided, or 0.
#[inline(always)]
pub(super) fn grad_t(f: &[u8; 5], t: &[f32; 5], tp: f32) -> (f32, f32) {
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
pub(super) fn min2(a: f32, b: f32) -> f32 {
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
pub(super) fn arrival(t: &[f32; 5]) -> f32 {
    solve_pair(min2(t[0], t[4]), min2(t[1], t[3]))
}

/// Solution of `|grad T| = 1` from one vertical and one horizontal neighbour (in `f32`: OpenCV
/// uses `f64` here, which changes arrival times by about 1e-7 relative and costs latency).
/// Branch-free: both candidates are computed (the square root of a negative number, NaN, is
/// dropped).
#[inline(always)]
pub(super) fn solve_pair(a: f32, b: f32) -> f32 {
    let d = a - b;
    let far = 1.0 + min2(a, b);
    let near = (a + b + (2.0 - d * d).sqrt()) * 0.5;
    pick(d.abs() >= 1.0, far, near)
}
