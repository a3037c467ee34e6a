//! Telea's weights: the disk of radius `r` cut into 8-lane chunks (`DiskPlan`), placed in a
//! window (`WindowDisk`), and the fill of one pixel as the weighted mean over it (`fill`).

use super::*;

/// Lanes of one disk chunk: weights and sums are computed 8 disk pixels at a time.
pub(super) const LANES: usize = 8;
/// Per-lane constants of a chunk: `r = p - q`, the geometric weight `g = 1 / |r|^3`, and for the
/// weights `g r` and `g` times the direction term's limit and floor; all 0 for lanes that are
/// not disk pixels (the centre among them).
#[derive(Debug, Clone, Copy, Default)]
#[repr(C, align(32))]
pub(super) struct Lanes {
    pub(super) rx: [f32; LANES],
    pub(super) ry: [f32; LANES],
    pub(super) geometric: [f32; LANES],
    pub(super) g_rx: [f32; LANES],
    pub(super) g_ry: [f32; LANES],
    pub(super) g_limit: [f32; LANES],
    pub(super) g_floor: [f32; LANES],
}

impl Lanes {
    pub(super) fn set(&mut self, l: usize, dx: isize, dy: isize) {
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
pub(super) struct DiskPlan {
    /// `(dx, dy)` of lane 0 of each direct chunk; lane `l` is the pixel `(dx + l, dy)`.
    pub(super) direct: Vec<(isize, isize)>,
    pub(super) direct_lanes: Vec<Lanes>,
    /// `(dx, dy)` of each lane of each gathered chunk; unused lanes point at the centre.
    pub(super) gathered: Vec<[(isize, isize); LANES]>,
    pub(super) gathered_lanes: Vec<Lanes>,
    /// Pixels taken one at a time: `(dx, dy)` and `[rx, ry, geometric]`.
    pub(super) single: Vec<((isize, isize), [f32; 3])>,
    pub(super) radius: usize,
    /// Window margin around a group's box: `radius + 2` (disk, outward front, its neighbours,
    /// their neighbours), or more if a direct chunk reads farther.
    pub(super) margin: usize,
}

impl DiskPlan {
    /// The cheapest cut of the disk of radius `r`, by instructions per fill (measured, 3
    /// channels): about 30 for a direct chunk, 100 for a gathered one (eight scattered loads per
    /// plane), 48 for a single pixel.
    pub(super) fn new(r: usize) -> DiskPlan {
        let cost = |p: &DiskPlan| 10 * p.direct.len() + 33 * p.gathered.len() + 16 * p.single.len();
        (1..=4)
            .flat_map(|min_direct| [false, true].map(|single| DiskPlan::cut(r, min_direct, single)))
            .min_by_key(cost)
            .unwrap_or_else(|| DiskPlan::cut(r, 1, false))
    }

    /// [`DiskPlan::new`], kept per thread for the last radius asked for.
    pub(super) fn cached(r: usize) -> std::rc::Rc<DiskPlan> {
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
    pub(super) fn cut(r: usize, min_direct: usize, single: bool) -> DiskPlan {
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
    pub(super) fn place(&self, ww: usize, n: usize, disk: &mut WindowDisk) {
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
pub(super) struct WindowDisk {
    pub(super) direct: Vec<(isize, Lanes)>,
    pub(super) gathered: Vec<([isize; LANES], Lanes)>,
    pub(super) single: Vec<(isize, [f32; 3])>,
    /// Every read of a fill at a window pixel in `lo..=hi` is inside the window.
    pub(super) lo: usize,
    pub(super) hi: isize,
}

impl WindowDisk {
    #[inline(always)]
    pub(super) fn covers(&self, p: usize) -> bool {
        self.lo <= p && (p as isize) <= self.hi
    }
}
/// The eight values of `s` from `at` (in bounds by construction; zeros otherwise, never seen).
#[inline(always)]
pub(super) fn lanes_at(s: &[f32], at: usize) -> &[f32; LANES] {
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
pub(super) fn chunk_weights<V: Simd8>(tq: V, tp: V, gx: V, gy: V, lanes: &Lanes) -> V {
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
pub(super) unsafe fn load8<V: Simd8, const CHECKED: bool>(s: &[f32], at: usize) -> V {
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
pub(super) unsafe fn load1<const CHECKED: bool>(s: &[f32], at: usize) -> f32 {
    if CHECKED {
        s.get(at).copied().unwrap_or(0.0)
    } else {
        debug_assert!(at < s.len());
        // SAFETY: the caller's contract.
        unsafe { *s.get_unchecked(at) }
    }
}

/// What one fill's chunks share.
pub(super) struct Chunk<'a, const C: usize, V> {
    pub(super) p: usize,
    pub(super) tp: V,
    pub(super) gx: V,
    pub(super) gy: V,
    pub(super) refs: [V; C],
    pub(super) t: &'a [f32],
    pub(super) vals: &'a [f32],
    pub(super) n: usize,
}

impl<const C: usize, V: Simd8> Chunk<'_, C, V> {
    /// Adds the weights of one direct chunk (window offset `off`) to `acc_w` and the weighted
    /// differences from the reference values to `acc`.
    ///
    /// # Safety
    /// As [`fill`]: unless `CHECKED`, every read of the chunk lies inside `t` and each plane.
    #[inline(always)]
    pub(super) unsafe fn direct<const CHECKED: bool>(
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
pub(super) unsafe fn fill<const C: usize, V: Simd8, const CHECKED: bool>(
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
