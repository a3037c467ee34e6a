//! Eight `f32` lanes (`Simd8`): plain arrays on any CPU, one AVX register where AVX2 + FMA are
//! detected at run time; both give the same bits. Also the branch-free selection helpers.

use super::*;

/// Whether the disk arithmetic may run on AVX2 (with FMA).
pub(super) fn detect_avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}
/// Eight `f32` lanes, the unit of the disk arithmetic. Two implementations: [`Lanes8`] (plain
/// arrays, any CPU) and `avx::Avx8` (one AVX register). Every operation is lane-wise IEEE
/// arithmetic and [`Simd8::sum`] adds in the same tree in both, so both give bit-identical results.
pub(super) trait Simd8: Copy {
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
pub(super) struct Lanes8([f32; LANES]);

impl Lanes8 {
    #[inline(always)]
    pub(super) fn zip(self, o: Lanes8, f: impl Fn(f32, f32) -> f32) -> Lanes8 {
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
pub(super) mod avx {
    //! [`Simd8`] on one AVX register. Only reached from functions compiled with AVX2 enabled
    //! and called after the CPU reported it (`march_inward_avx2`).
    use std::arch::x86_64::*;

    use super::{Simd8, LANES};

    #[derive(Clone, Copy)]
    pub(in crate::telea) struct Avx8(__m256);

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
/// All ones if `c`, else 0, hidden from the optimiser: it would otherwise turn the selections
/// built on it back into branches, mispredicted about half the time on these conditions.
#[inline(always)]
pub(super) fn mask_if(c: bool) -> u32 {
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
pub(super) fn pick(c: bool, a: f32, b: f32) -> f32 {
    let m = mask_if(c);
    f32::from_bits((a.to_bits() & m) | (b.to_bits() & !m))
}
