//! Unit tests of TELEA: fills against known answers, OpenCV's semantics, per-group against
//! global solves, portable against AVX2 arithmetic, every dtype.

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
