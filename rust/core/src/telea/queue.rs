//! The fast-marching fronts' queue: a bucket queue on quantised arrival time (`FrontQueue`).

/// Queue key: arrival time in the high half (non-negative, so its bits order like the value), the
/// window index in the low half. Window raster order is image raster order, so ties pop in the
/// same order whatever the window: a group's solve does not depend on where its window lies.
pub(super) fn key(t: f32, wi: usize) -> u64 {
    (u64::from(t.to_bits()) << 32) | wi as u64
}

pub(super) fn key_index(k: u64) -> usize {
    (k & u64::from(u32::MAX)) as usize
}

/// Buckets of the front queue per pixel of arrival time ...
pub(super) const BUCKET_SCALE: f32 = 64.0;
/// ... and buckets in its ring: 4 pixels of arrival time, while a front spans about one (a new
/// arrival time is at most 1 more than the one just popped).
pub(super) const BUCKETS: usize = 256;
pub(super) const RING_WORDS: usize = BUCKETS / 64;

/// The bucket of arrival time `t`: `round(t * BUCKET_SCALE)`, nondecreasing in `t`, by integer
/// operations (adding 2^23 leaves the rounded integer in the mantissa; the clamp keeps it below
/// 2^22).
#[inline(always)]
pub(super) fn bucket(t: f32) -> u64 {
    let t = t * BUCKET_SCALE;
    u64::from((t.clamp(0.0, 4_194_304.0) + 8_388_608.0).to_bits() & 0x7F_FFFF)
}

/// The bucket of a [`key`].
pub(super) fn key_bucket(k: u64) -> u64 {
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
pub(super) struct FrontQueue {
    /// `next[i]`: the pixel after window pixel `i` in its bucket; entries `n + s` head the list
    /// of ring slot `s` (for a window of `n` pixels).
    pub(super) next: Vec<u32>,
    /// Last pixel of each slot's list (`n + s` when empty).
    pub(super) tail: Vec<u32>,
    /// Window size: `n + s` is slot `s`'s list head.
    pub(super) n: u32,
    /// Bit `s` set: ring slot `s` is not empty (the current slot's bit is clear).
    pub(super) occupied: [u64; RING_WORDS],
    /// Absolute index of the current bucket.
    pub(super) cur: u64,
    /// The last pixel popped from the current bucket (or its list head).
    pub(super) cursor: u32,
    /// Pixels pushed below the current bucket, and how many of them have popped.
    pub(super) late: Vec<u32>,
    pub(super) late_head: usize,
    /// Keys ([`key`]) beyond the ring.
    pub(super) spill: Vec<u64>,
}

impl FrontQueue {
    /// Empties the queue for a window of `n` pixels and pushes the pixels `seeds` at `T = 0`,
    /// in this order.
    pub(super) fn reset(&mut self, n: usize, seeds: &[usize]) {
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
    pub(super) fn push(&mut self, t: f32, wi: usize) {
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
    pub(super) fn pop(&mut self) -> Option<usize> {
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
    pub(super) fn advance(&mut self) -> Option<()> {
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
    pub(super) fn take(&mut self, slot: usize) {
        self.occupied[slot / 64] &= !(1 << (slot % 64));
        self.cursor = self.n + slot as u32;
    }
}
