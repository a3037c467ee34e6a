//! The holes: the mask's runs, labelled into 8-connected holes, and the holes grouped so that
//! groups farther apart than the reach of a fill can be solved apart (in parallel).

/// Inclusive pixel box `x0..=x1`, `y0..=y1`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct BBox {
    pub(super) x0: usize,
    pub(super) y0: usize,
    pub(super) x1: usize,
    pub(super) y1: usize,
}

impl BBox {
    pub(super) fn union(self, o: BBox) -> BBox {
        BBox {
            x0: self.x0.min(o.x0),
            y0: self.y0.min(o.y0),
            x1: self.x1.max(o.x1),
            y1: self.y1.max(o.y1),
        }
    }

    /// Chebyshev distance between the boxes (1 for boxes that touch, 0 for overlapping ones).
    pub(super) fn gap(self, o: BBox) -> usize {
        let dx =
            o.x0.saturating_sub(self.x1)
                .max(self.x0.saturating_sub(o.x1));
        let dy =
            o.y0.saturating_sub(self.y1)
                .max(self.y0.saturating_sub(o.y1));
        dx.max(dy)
    }
}
/// A horizontal run `x0..=x1` of masked pixels on row `y`.
#[derive(Debug, Clone, Copy)]
pub(super) struct Run {
    pub(super) y: usize,
    pub(super) x0: usize,
    pub(super) x1: usize,
}

/// Bit `i` set where byte `i` of `word` (eight mask pixels, little-endian) is nonzero.
#[inline(always)]
pub(super) fn nonzero_bits(word: u64) -> u64 {
    let mut t = word;
    t |= t >> 4;
    t |= t >> 2;
    t |= t >> 1;
    // The low bit of each byte, gathered into the top byte by one multiplication.
    ((t & 0x0101_0101_0101_0101).wrapping_mul(0x0102_0408_1020_4080) >> 56) & 0xFF
}

/// Runs of the mask, row by row: each row becomes a bit set (blocks of 32 zero pixels cost one
/// test), whose runs of ones are read with bit scans.
pub(super) fn mask_runs(mask: &[u8], h: usize, w: usize) -> Vec<Run> {
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

pub(super) fn find(parent: &mut [usize], mut i: usize) -> usize {
    while parent[i] != i {
        parent[i] = parent[parent[i]];
        i = parent[i];
    }
    i
}

pub(super) fn unite(parent: &mut [usize], a: usize, b: usize) {
    let (a, b) = (find(parent, a), find(parent, b));
    parent[a.max(b)] = a.min(b);
}

/// 8-connected components of the runs: each run's component and each component's box.
pub(super) fn label_runs(runs: &[Run]) -> (Vec<u32>, Vec<BBox>) {
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
pub(super) fn group_holes(boxes: &[BBox], reach: usize) -> (Vec<u32>, Vec<BBox>) {
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
