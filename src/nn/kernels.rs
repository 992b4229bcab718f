//! The inner loops of a batch evaluation, two samples at a time in SSE2 registers on
//! x86-64 and one at a time elsewhere (wasm32 here has no SIMD enabled).
//!
//! The release profile optimises for size, under which the compiler does not vectorise
//! loops by itself (the same reason `calib/ellipsoid.rs` has its SSE2 sums), so the
//! two-lane code is written out. Each lane does exactly the scalar code's operations in
//! the same order (SSE2 has no fused multiply-add, and a dot product keeps the scalar
//! code's four partial sums, two per register), so both give the same bits: a network
//! trained natively and in the browser is the same network. A test checks it.

use super::activation::Activation;

/// `out[s] = bias + Σᵢ weights[i]·base[i·stride + s]`, the sum taken in the order of `i`.
pub(crate) fn affine_rows(
    bias: f64,
    weights: &[f64],
    base: &[f64],
    stride: usize,
    out: &mut [f64],
) {
    #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
    // SAFETY: `sse2::affine_rows` needs only the SSE2 target feature, which the `cfg`
    // above guarantees for the whole build.
    unsafe {
        sse2::affine_rows(bias, weights, base, stride, out)
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
    scalar::affine_rows(bias, weights, base, stride, out)
}

/// Replaces each pre-activation by its activation ([`Activation::apply`]).
pub(crate) fn activate(activation: Activation, values: &mut [f64]) {
    #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
    // SAFETY: as in `affine_rows`.
    unsafe {
        sse2::activate(activation, values)
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
    activation.apply(values)
}

/// `hidden[s] = back[s] · f'(hidden[s])`, the derivative written in terms of the
/// activation ([`Activation::derivative`]).
pub(crate) fn back_propagate(activation: Activation, back: &[f64], hidden: &mut [f64]) {
    #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
    // SAFETY: as in `affine_rows`.
    unsafe {
        sse2::back_propagate(activation, back, hidden)
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
    scalar::back_propagate(activation, back, hidden)
}

/// `Σ xᵢ·yᵢ` with four partial sums (elements `4k + p` go to sum `p`), then
/// `(s₀ + s₁) + (s₂ + s₃)` plus the tail in order.
pub(crate) fn dot(x: &[f64], y: &[f64]) -> f64 {
    #[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
    // SAFETY: as in `affine_rows`.
    unsafe {
        sse2::dot(x, y)
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
    scalar::dot(x, y)
}

/// The scalar reference of every kernel (and the code wasm runs).
#[cfg_attr(all(target_arch = "x86_64", target_feature = "sse2"), allow(dead_code))]
mod scalar {
    use super::Activation;

    /// [`Activation::derivative`], in place.
    pub(super) fn back_propagate(activation: Activation, back: &[f64], hidden: &mut [f64]) {
        for (h, delta) in hidden.iter_mut().zip(back) {
            *h = delta * activation.derivative(*h);
        }
    }

    pub(super) fn affine_rows(
        bias: f64,
        weights: &[f64],
        base: &[f64],
        stride: usize,
        out: &mut [f64],
    ) {
        out.fill(bias);
        let m = out.len();
        for (row_idx, weight) in weights.iter().enumerate() {
            let row = &base[row_idx * stride..][..m];
            for (out, value) in out.iter_mut().zip(row) {
                *out += weight * value;
            }
        }
    }

    pub(super) fn dot(x: &[f64], y: &[f64]) -> f64 {
        let mut partial = [0.0; 4];
        let x_chunks = x.chunks_exact(4);
        let y_chunks = y.chunks_exact(4);
        let tail = x_chunks.remainder().iter().zip(y_chunks.remainder());
        for (x, y) in x_chunks.clone().zip(y_chunks.clone()) {
            partial[0] += x[0] * y[0];
            partial[1] += x[1] * y[1];
            partial[2] += x[2] * y[2];
            partial[3] += x[3] * y[3];
        }
        let mut total = (partial[0] + partial[1]) + (partial[2] + partial[3]);
        for (x, y) in tail {
            total += x * y;
        }
        total
    }
}

#[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
mod sse2 {
    use std::arch::x86_64::{
        __m128d, _mm_add_epi64, _mm_add_pd, _mm_castpd_si128, _mm_castsi128_pd, _mm_cvtsd_f64,
        _mm_div_pd, _mm_max_pd, _mm_min_pd, _mm_mul_pd, _mm_set1_epi64x, _mm_set1_pd, _mm_set_pd,
        _mm_slli_epi64, _mm_sub_pd, _mm_unpackhi_pd,
    };

    use super::super::activation::{
        Activation, EXP_COEFFICIENTS, EXP_LIMIT, LN2_HI, LN2_LO, ROUND,
    };

    #[inline]
    #[target_feature(enable = "sse2")]
    fn load(pair: &[f64]) -> __m128d {
        match pair {
            [a, b, ..] => _mm_set_pd(*b, *a),
            _ => _mm_set1_pd(0.0),
        }
    }

    #[inline]
    #[target_feature(enable = "sse2")]
    fn store(v: __m128d, pair: &mut [f64]) {
        if let [a, b, ..] = pair {
            *a = _mm_cvtsd_f64(v);
            *b = _mm_cvtsd_f64(_mm_unpackhi_pd(v, v));
        }
    }

    /// Row by row (`out += wᵢ·rowᵢ`), so that consecutive pairs do not wait for each
    /// other; each element still sums in the order of `i`.
    #[target_feature(enable = "sse2")]
    pub(super) fn affine_rows(
        bias: f64,
        weights: &[f64],
        base: &[f64],
        stride: usize,
        out: &mut [f64],
    ) {
        let m = out.len();
        out.fill(bias);
        for (row_idx, weight) in weights.iter().enumerate() {
            let row = &base[row_idx * stride..][..m];
            let weight_pair = _mm_set1_pd(*weight);
            let mut out_pairs = out.chunks_exact_mut(2);
            let mut row_pairs = row.chunks_exact(2);
            for (out_pair, row_pair) in out_pairs.by_ref().zip(row_pairs.by_ref()) {
                store(
                    _mm_add_pd(load(out_pair), _mm_mul_pd(weight_pair, load(row_pair))),
                    out_pair,
                );
            }
            if let ([last], [value]) = (out_pairs.into_remainder(), row_pairs.remainder()) {
                *last += weight * value;
            }
        }
    }

    /// Two lanes of `activation::exp`, operation for operation.
    /// (A macro, not a function: a `target_feature` function cannot be forced inline,
    /// and a call per pair costs more than the arithmetic.)
    macro_rules! exp {
        ($x:expr) => {{
            let x: __m128d = $x;
            let x = _mm_max_pd(
                _mm_min_pd(x, _mm_set1_pd(EXP_LIMIT)),
                _mm_set1_pd(-EXP_LIMIT),
            );
            let shifted = _mm_add_pd(
                _mm_mul_pd(x, _mm_set1_pd(std::f64::consts::LOG2_E)),
                _mm_set1_pd(ROUND),
            );
            let n = _mm_sub_pd(shifted, _mm_set1_pd(ROUND));
            let r = _mm_sub_pd(
                _mm_sub_pd(x, _mm_mul_pd(n, _mm_set1_pd(LN2_HI))),
                _mm_mul_pd(n, _mm_set1_pd(LN2_LO)),
            );
            // Estrin's scheme, as in `activation::exp`.
            let c = |k: usize| _mm_set1_pd(EXP_COEFFICIENTS[k]);
            let add = _mm_add_pd;
            let mul = _mm_mul_pd;
            let r2 = mul(r, r);
            let r4 = mul(r2, r2);
            let r8 = mul(r4, r4);
            let s0 = add(add(c(0), mul(c(1), r)), mul(add(c(2), mul(c(3), r)), r2));
            let s1 = add(add(c(4), mul(c(5), r)), mul(add(c(6), mul(c(7), r)), r2));
            let s2 = add(add(c(8), mul(c(9), r)), mul(add(c(10), mul(c(11), r)), r2));
            let s3 = add(c(12), mul(c(13), r));
            let p = add(add(s0, mul(s1, r4)), mul(add(s2, mul(s3, r4)), r8));
            let bits = _mm_slli_epi64::<52>(_mm_add_epi64(
                _mm_castpd_si128(shifted),
                _mm_set1_epi64x(1023),
            ));
            _mm_mul_pd(p, _mm_castsi128_pd(bits))
        }};
    }

    #[target_feature(enable = "sse2")]
    pub(super) fn activate(activation: Activation, values: &mut [f64]) {
        let one = _mm_set1_pd(1.0);
        let two = _mm_set1_pd(2.0);
        let mut pairs = values.chunks_exact_mut(2);
        for pair in pairs.by_ref() {
            let z = load(pair);
            let activated = match activation {
                Activation::Logistic => {
                    _mm_div_pd(one, _mm_add_pd(one, exp!(_mm_mul_pd(_mm_set1_pd(-1.0), z))))
                }
                Activation::Tanh => _mm_sub_pd(
                    one,
                    _mm_div_pd(two, _mm_add_pd(exp!(_mm_mul_pd(two, z)), one)),
                ),
            };
            store(activated, pair);
        }
        activation.apply(pairs.into_remainder());
    }

    #[target_feature(enable = "sse2")]
    pub(super) fn back_propagate(activation: Activation, back: &[f64], hidden: &mut [f64]) {
        let one = _mm_set1_pd(1.0);
        let mut pairs = hidden.chunks_exact_mut(2);
        let mut back_pairs = back.chunks_exact(2);
        for (pair, back_pair) in pairs.by_ref().zip(back_pairs.by_ref()) {
            let h = load(pair);
            let derivative = match activation {
                Activation::Logistic => _mm_mul_pd(h, _mm_sub_pd(one, h)),
                Activation::Tanh => _mm_sub_pd(one, _mm_mul_pd(h, h)),
            };
            store(_mm_mul_pd(load(back_pair), derivative), pair);
        }
        super::scalar::back_propagate(activation, back_pairs.remainder(), pairs.into_remainder());
    }

    #[target_feature(enable = "sse2")]
    pub(super) fn dot(x: &[f64], y: &[f64]) -> f64 {
        let mut low = _mm_set1_pd(0.0);
        let mut high = _mm_set1_pd(0.0);
        let x_chunks = x.chunks_exact(4);
        let y_chunks = y.chunks_exact(4);
        let tail = x_chunks.remainder().iter().zip(y_chunks.remainder());
        for (x, y) in x_chunks.clone().zip(y_chunks.clone()) {
            low = _mm_add_pd(low, _mm_mul_pd(load(x), load(y)));
            high = _mm_add_pd(high, _mm_mul_pd(load(&x[2..]), load(&y[2..])));
        }
        let lanes = |v: __m128d| _mm_cvtsd_f64(v) + _mm_cvtsd_f64(_mm_unpackhi_pd(v, v));
        let mut total = lanes(low) + lanes(high);
        for (x, y) in tail {
            total += x * y;
        }
        total
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::rng::SplitMix64;

    #[test]
    fn the_kernels_give_the_scalar_code_s_bits() {
        let mut rng = SplitMix64::new(1);
        for m in [0, 1, 2, 5, 127, 128] {
            let base: Vec<f64> = (0..3 * 130).map(|_| 10.0 * rng.gaussian()).collect();
            let weights = [0.3, -1.7, 2.2];
            let mut fast = vec![0.0; m];
            let mut reference = vec![0.0; m];
            affine_rows(0.25, &weights, &base, 130, &mut fast);
            scalar::affine_rows(0.25, &weights, &base, 130, &mut reference);
            assert_eq!(fast, reference);
            for activation in [Activation::Logistic, Activation::Tanh] {
                let mut fast_activated = fast.clone();
                activate(activation, &mut fast_activated);
                let mut reference_activated = reference.clone();
                activation.apply(&mut reference_activated);
                assert_eq!(fast_activated, reference_activated);
            }
            for activation in [Activation::Logistic, Activation::Tanh] {
                let mut hidden = fast.clone();
                activate(activation, &mut hidden);
                let mut reference_hidden = hidden.clone();
                back_propagate(activation, &base[260..260 + m], &mut hidden);
                scalar::back_propagate(activation, &base[260..260 + m], &mut reference_hidden);
                assert_eq!(hidden, reference_hidden);
            }
            assert_eq!(
                dot(&base[..m], &base[130..130 + m]).to_bits(),
                scalar::dot(&base[..m], &base[130..130 + m]).to_bits()
            );
        }
    }
}
