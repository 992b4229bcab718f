//! [`super::Lanes`] in AVX2 registers, for x86-64 processors that have them (checked at
//! run time).

use std::arch::x86_64::{
    __m256, _mm256_add_epi32, _mm256_add_ps, _mm256_and_ps, _mm256_castps_si256,
    _mm256_castsi256_ps, _mm256_div_ps, _mm256_loadu_ps, _mm256_max_ps, _mm256_min_ps,
    _mm256_mul_ps, _mm256_set1_epi32, _mm256_set1_ps, _mm256_slli_epi32, _mm256_storeu_ps,
    _mm256_sub_ps, _mm256_xor_ps,
};

use super::{Lanes, PartInput, Scratch};

/// Whether the processor has AVX2 (the standard library caches the answer).
pub(super) fn is_available() -> bool {
    std::arch::is_x86_feature_detected!("avx2")
}

/// Eight lanes in one AVX register. A value exists only inside [`evaluate_part`],
/// which runs only when the processor has AVX2: that is what makes the intrinsics
/// below sound.
#[derive(Clone, Copy)]
pub(super) struct Avx2(__m256);

// SAFETY (every `unsafe` block in this impl): an `Avx2` value exists only inside
// `evaluate_part`, which its caller runs only after checking that the processor has
// AVX2; loads and stores go through a bounds-checked slice of eight values.
impl Lanes for Avx2 {
    const WIDTH: usize = super::LANES;
    const MAX_GROUP: usize = super::MAX_GROUP;
    const PAIRED: bool = true;

    #[inline(always)]
    fn splat(value: f32) -> Self {
        Avx2(unsafe { _mm256_set1_ps(value) })
    }

    #[inline(always)]
    fn load(values: &[f32], start: usize) -> Self {
        let eight = &values[start..start + 8];
        Avx2(unsafe { _mm256_loadu_ps(eight.as_ptr()) })
    }

    #[inline(always)]
    fn store(self, values: &mut [f32], start: usize) {
        let eight = &mut values[start..start + 8];
        unsafe { _mm256_storeu_ps(eight.as_mut_ptr(), self.0) }
    }

    #[inline(always)]
    fn add(self, other: Self) -> Self {
        Avx2(unsafe { _mm256_add_ps(self.0, other.0) })
    }

    #[inline(always)]
    fn sub(self, other: Self) -> Self {
        Avx2(unsafe { _mm256_sub_ps(self.0, other.0) })
    }

    #[inline(always)]
    fn mul(self, other: Self) -> Self {
        Avx2(unsafe { _mm256_mul_ps(self.0, other.0) })
    }

    #[inline(always)]
    fn div(self, other: Self) -> Self {
        Avx2(unsafe { _mm256_div_ps(self.0, other.0) })
    }

    #[inline(always)]
    fn min(self, other: Self) -> Self {
        Avx2(unsafe { _mm256_min_ps(self.0, other.0) })
    }

    #[inline(always)]
    fn max(self, other: Self) -> Self {
        Avx2(unsafe { _mm256_max_ps(self.0, other.0) })
    }

    #[inline(always)]
    fn neg(self) -> Self {
        Avx2(unsafe { _mm256_xor_ps(self.0, _mm256_set1_ps(-0.0)) })
    }

    #[inline(always)]
    fn two_to_the_rounded(shifted: Self) -> Self {
        Avx2(unsafe {
            _mm256_castsi256_ps(_mm256_slli_epi32::<23>(_mm256_add_epi32(
                _mm256_castps_si256(shifted.0),
                _mm256_set1_epi32(127),
            )))
        })
    }

    #[inline(always)]
    fn keep_first(self, count: usize) -> Self {
        let mut mask = [0.0; 8];
        for lane in mask.iter_mut().take(count) {
            *lane = f32::from_bits(u32::MAX);
        }
        Avx2(unsafe { _mm256_and_ps(self.0, _mm256_loadu_ps(mask.as_ptr())) })
    }
}

/// [`super::evaluate_part`] in AVX2 registers.
#[target_feature(enable = "avx2")]
pub(super) fn evaluate_part(
    input: &PartInput,
    range: std::ops::Range<usize>,
    scratch: &mut Scratch,
    sums: &mut [f64],
) {
    super::part::<Avx2>(input, range, scratch, sums);
}
