//! The lanes in WebAssembly's 128-bit SIMD, which both of the page's modules are built
//! with (`.cargo/config.toml`): two `f32x4` registers, each operation the same IEEE
//! single operation as the portable lane's.
//! `min` and `max` are the pseudo-minimum and pseudo-maximum with their operands
//! swapped, which is the portable `if a < b { a } else { b }` (and `>`) exactly, NaN
//! included. Without it the page's network trained one lane at a time: 130 ms of a
//! 3 MB drive's 230 ms analysis in the page, against 5-10 ms natively.

use std::arch::wasm32::{
    f32x4_add, f32x4_div, f32x4_mul, f32x4_neg, f32x4_pmax, f32x4_pmin, f32x4_splat, f32x4_sub,
    i32x4_add, i32x4_shl, i32x4_splat, v128, v128_and, v128_load, v128_store,
};

use super::Lanes;

/// Eight lanes in two 128-bit registers: lanes 0-3 and 4-7.
#[derive(Clone, Copy)]
pub(super) struct Simd128(v128, v128);

impl Simd128 {
    #[inline(always)]
    fn map2(self, other: Self, f: impl Fn(v128, v128) -> v128) -> Self {
        Simd128(f(self.0, other.0), f(self.1, other.1))
    }
}

impl Lanes for Simd128 {
    const WIDTH: usize = super::LANES;
    /// One input per backward pass, as the portable lanes: three (as many as AVX2's
    /// registers would hold of two-register values) trained the page's networks
    /// no faster (a 3 MB drive's heading models: 14-30 ms either way, four drops
    /// each) and took 1.2 kB more of the threaded module's gzipped size.
    const MAX_GROUP: usize = 1;
    /// The two registers of a value are already two independent chains.
    const PAIRED: bool = false;

    #[inline(always)]
    fn splat(value: f32) -> Self {
        Simd128(f32x4_splat(value), f32x4_splat(value))
    }

    #[inline(always)]
    fn load(values: &[f32], start: usize) -> Self {
        let eight = &values[start..start + 8];
        // SAFETY: `eight` is eight `f32` (32 bytes) in bounds; `v128_load` reads
        // 16 unaligned bytes at each of its two halves.
        unsafe {
            Simd128(
                v128_load(eight.as_ptr().cast()),
                v128_load(eight[4..].as_ptr().cast()),
            )
        }
    }

    #[inline(always)]
    fn store(self, values: &mut [f32], start: usize) {
        let eight = &mut values[start..start + 8];
        // SAFETY: as in `load`, for writing.
        unsafe {
            v128_store(eight.as_mut_ptr().cast(), self.0);
            v128_store(eight[4..].as_mut_ptr().cast(), self.1);
        }
    }

    #[inline(always)]
    fn add(self, other: Self) -> Self {
        self.map2(other, |a, b| f32x4_add(a, b))
    }

    #[inline(always)]
    fn sub(self, other: Self) -> Self {
        self.map2(other, |a, b| f32x4_sub(a, b))
    }

    #[inline(always)]
    fn mul(self, other: Self) -> Self {
        self.map2(other, |a, b| f32x4_mul(a, b))
    }

    #[inline(always)]
    fn div(self, other: Self) -> Self {
        self.map2(other, |a, b| f32x4_div(a, b))
    }

    /// `pmin(b, a)` is `a < b ? a : b`.
    #[inline(always)]
    fn min(self, other: Self) -> Self {
        self.map2(other, |a, b| f32x4_pmin(b, a))
    }

    /// `pmax(b, a)` is `b < a ? a : b`, that is `a > b ? a : b`.
    #[inline(always)]
    fn max(self, other: Self) -> Self {
        self.map2(other, |a, b| f32x4_pmax(b, a))
    }

    #[inline(always)]
    fn neg(self) -> Self {
        Simd128(f32x4_neg(self.0), f32x4_neg(self.1))
    }

    #[inline(always)]
    fn two_to_the_rounded(shifted: Self) -> Self {
        let two_to = |bits: v128| i32x4_shl(i32x4_add(bits, i32x4_splat(127)), 23);
        Simd128(two_to(shifted.0), two_to(shifted.1))
    }

    #[inline(always)]
    fn keep_first(self, count: usize) -> Self {
        let mut mask = [0u32; 8];
        for lane in mask.iter_mut().take(count) {
            *lane = u32::MAX;
        }
        // SAFETY: `mask` is 32 bytes; each load reads 16 of them.
        let (low, high) = unsafe {
            (
                v128_load(mask.as_ptr().cast()),
                v128_load(mask[4..].as_ptr().cast()),
            )
        };
        Simd128(v128_and(self.0, low), v128_and(self.1, high))
    }
}
