//! The hidden layer's activation functions, applied to whole slices.
//!
//! - Logistic `σ(z) = 1 / (1 + e^−z)`, the "logistic function (sigmoid)" of Noureldin
//!   et al. (2007), Section 3; `σ' = σ·(1 − σ)`.
//! - `tanh(z) = 1 − 2 / (e^2z + 1)`, MATLAB's `tansig` used by Chen et al. for the step
//!   length; `tanh' = 1 − tanh²`.
//!
//! Both are written on [`exp`] below instead of the standard library's, because the
//! standard library's is an opaque call that no compiler vectorises: this one is
//! straight-line arithmetic that the compiler turns into SIMD code over a slice, and it
//! gives the same bits on every target (it uses no fused multiply-add), so a native and
//! a wasm build train the same network.

/// The hidden layer's activation function.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Activation {
    /// `1 / (1 + e^−z)`, output in (0, 1).
    Logistic,
    /// `tanh z`, output in (−1, 1).
    Tanh,
}

impl Activation {
    /// Replaces each pre-activation in `values` by its activation.
    pub(crate) fn apply(self, values: &mut [f64]) {
        match self {
            Activation::Logistic => {
                for value in values.iter_mut() {
                    *value = 1.0 / (1.0 + exp(-*value));
                }
            }
            Activation::Tanh => {
                for value in values.iter_mut() {
                    *value = 1.0 - 2.0 / (exp(2.0 * *value) + 1.0);
                }
            }
        }
    }

    /// The derivative `f'(z)` written in terms of the activation `output = f(z)` (the
    /// reference for the kernels' four-lane version).
    #[cfg(test)]
    pub(crate) fn derivative(self, output: f64) -> f64 {
        match self {
            Activation::Logistic => output * (1.0 - output),
            Activation::Tanh => 1.0 - output * output,
        }
    }
}

/// `e^x` to within a few ulp for |x| ≤ 708 (clamped outside, NaN stays NaN).
///
/// Cody and Waite's reduction `x = n·ln 2 + r` with |r| ≤ ln 2 / 2 (ln 2 split into a
/// high part exact in 32 bits and a low part, so `n·ln2_hi` is exact), `e^r` by its
/// Taylor series to r¹³ (the remainder is below r¹⁴/14! ≈ 4·10⁻¹⁸ relative), and `2^n`
/// built in the exponent bits. `n` is rounded with the 1.5·2⁵² trick: adding it leaves
/// `n` in the low mantissa bits, so no float-to-integer conversion (which SSE2 lacks for
/// 64-bit lanes) is needed.
#[inline(always)]
pub(crate) fn exp(x: f64) -> f64 {
    let x = x.clamp(-EXP_LIMIT, EXP_LIMIT);
    let shifted = x * std::f64::consts::LOG2_E + ROUND;
    let n = shifted - ROUND;
    let r = (x - n * LN2_HI) - n * LN2_LO;
    // Σ r^k / k! for k = 0..=13 by Estrin's scheme (pairs, then pairs of pairs), which
    // needs 5 dependent steps instead of Horner's 13.
    let c = &EXP_COEFFICIENTS;
    let r2 = r * r;
    let r4 = r2 * r2;
    let r8 = r4 * r4;
    let s0 = (c[0] + c[1] * r) + (c[2] + c[3] * r) * r2;
    let s1 = (c[4] + c[5] * r) + (c[6] + c[7] * r) * r2;
    let s2 = (c[8] + c[9] * r) + (c[10] + c[11] * r) * r2;
    let s3 = c[12] + c[13] * r;
    let p = (s0 + s1 * r4) + (s2 + s3 * r4) * r8;
    // The low bits of `shifted` hold n (two's complement) and n + 1023 lies in [1, 2046].
    let two_to_n = f64::from_bits(shifted.to_bits().wrapping_add(1023) << 52);
    p * two_to_n
}

/// |x| beyond which [`exp`] clamps (e^±708 is still a normal number).
pub(crate) const EXP_LIMIT: f64 = 708.0;
/// ln 2 in two parts: the high part has 32 significant bits (0x3FE62E42FEE00000), so
/// `n·LN2_HI` is exact for |n| < 2²¹; the low part is ln 2 − LN2_HI (fdlibm's values).
pub(crate) const LN2_HI: f64 = 0.693_147_180_369_123_8;
pub(crate) const LN2_LO: f64 = 1.908_214_929_270_587_7e-10;
/// 1.5·2⁵²: adding it rounds to an integer and leaves that integer in the low bits.
pub(crate) const ROUND: f64 = 6_755_399_441_055_744.0;
/// 1/k! for k = 0..=13.
pub(crate) const EXP_COEFFICIENTS: [f64; 14] = [
    1.0,
    1.0,
    0.5,
    1.0 / 6.0,
    1.0 / 24.0,
    1.0 / 120.0,
    1.0 / 720.0,
    1.0 / 5_040.0,
    1.0 / 40_320.0,
    1.0 / 362_880.0,
    1.0 / 3_628_800.0,
    1.0 / 39_916_800.0,
    1.0 / 479_001_600.0,
    1.0 / 6_227_020_800.0,
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exp_matches_the_standard_library() {
        let mut worst = 0.0_f64;
        let mut x = -700.0;
        while x < 700.0 {
            let relative = (exp(x) - x.exp()).abs() / x.exp();
            worst = worst.max(relative);
            x += 0.0137;
        }
        assert!(worst < 1e-15, "worst relative error {worst:e}");
        assert_eq!(exp(0.0), 1.0);
        assert!(exp(-1000.0) > 0.0 && exp(1000.0).is_finite());
    }

    #[test]
    fn activations_and_derivatives_match_their_definitions() {
        let inputs: Vec<f64> = (-80..=80).map(|k| f64::from(k) * 0.25).collect();
        let mut logistic = inputs.clone();
        Activation::Logistic.apply(&mut logistic);
        let mut tanh = inputs.clone();
        Activation::Tanh.apply(&mut tanh);
        for ((z, s), t) in inputs.iter().zip(&logistic).zip(&tanh) {
            assert!((s - 1.0 / (1.0 + (-z).exp())).abs() < 1e-15, "{z}");
            assert!((t - z.tanh()).abs() < 1e-15, "{z}");
        }
        for ((z, s), t) in inputs.iter().zip(&logistic).zip(&tanh) {
            assert!(
                (Activation::Tanh.derivative(*t) - 1.0 / z.cosh().powi(2)).abs() < 1e-14,
                "{z}"
            );
            let logistic_derivative = (-z).exp() / (1.0 + (-z).exp()).powi(2);
            assert!(
                (Activation::Logistic.derivative(*s) - logistic_derivative).abs() < 1e-14,
                "{z}"
            );
        }
    }
}
