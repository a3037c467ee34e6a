//! A profiling harness (ignored test), run by hand.

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
        *v = (120.0 + 40.0 * ((x as f32) * 0.05).sin() + 30.0 * ((y as f32) * 0.07).cos()) as u8;
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
