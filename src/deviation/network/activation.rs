//! The hidden layer's activation functions, in single precision.
//!
//! - Logistic `σ(z) = 1 / (1 + e^−z)`, the "logistic function (sigmoid)" of Noureldin
//!   et al. (2007), Section 3; `σ' = σ·(1 − σ)`.
//! - `tanh(z) = 1 − 2 / (e^2z + 1)`, MATLAB's `tansig` used by Chen et al. for the step
//!   length; `tanh' = 1 − tanh²`.
//!
//! Both are written on [`exp`] below instead of the standard library's, because the
//! standard library's is an opaque call that no compiler vectorises: this one is
//! straight-line arithmetic that the kernels run on eight lanes at once, and it gives the
//! same bits on every target (it uses no fused multiply-add), so a native and a wasm
//! build train the same network. Both are computed in single precision, as the kernels
//! evaluate the network (`kernels.rs` on eight lanes, [`Activation::of`] on one value for
//! `Mlp::predict`), so a trained network predicts with the function it was trained with.

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
    /// The activation of one pre-activation, the kernels' operations on one lane.
    pub(crate) fn of(self, z: f32) -> f32 {
        match self {
            Activation::Logistic => 1.0 / (1.0 + exp(-z)),
            Activation::Tanh => 1.0 - 2.0 / (exp(2.0 * z) + 1.0),
        }
    }

    /// The derivative `f'(z)` written in terms of the activation `output = f(z)` (the
    /// reference for the kernels' four-lane version).
    #[cfg(test)]
    pub(crate) fn derivative(self, output: f32) -> f32 {
        match self {
            Activation::Logistic => output * (1.0 - output),
            Activation::Tanh => 1.0 - output * output,
        }
    }
}

/// `e^x` in single precision, to within 2 ulp for |x| ≤ 87 (clamped outside, NaN stays
/// NaN).
///
/// Cody and Waite's reduction `x = n·ln 2 + r` with |r| ≤ ln 2 / 2 (ln 2 split into a
/// high part with 9 significant bits, so `n·ln2_hi` is exact, and a low part), then
/// Cephes' `expf`: `e^r ≈ 1 + r + r²·P(r)` with `P` of degree 5, and `2^n` built in the
/// exponent bits. `n` is rounded with the 1.5·2²³ trick: adding it leaves `n` in the low
/// mantissa bits, so no float-to-integer conversion is needed.
#[inline(always)]
pub(crate) fn exp(x: f32) -> f32 {
    let x = x.clamp(-EXP_LIMIT, EXP_LIMIT);
    let shifted = x * std::f32::consts::LOG2_E + ROUND;
    let n = shifted - ROUND;
    let r = (x - n * LN2_HI) - n * LN2_LO;
    let mut p = EXP_COEFFICIENTS[0];
    for c in &EXP_COEFFICIENTS[1..] {
        p = p * r + c;
    }
    let e = (p * (r * r) + r) + 1.0;
    // The low bits of `shifted` hold n (two's complement) and n + 127 lies in [1, 253].
    let two_to_n = f32::from_bits(shifted.to_bits().wrapping_add(127) << 23);
    e * two_to_n
}

/// |x| beyond which [`exp`] clamps (e^87 is still a normal number, and so is e^−87).
pub(crate) const EXP_LIMIT: f32 = 87.0;
/// ln 2 in two parts (Cephes' `C1` and `−C2`): the high part has 9 significant bits.
pub(crate) const LN2_HI: f32 = 0.693_359_4;
pub(crate) const LN2_LO: f32 = -2.121_944_4e-4;
/// 1.5·2²³: adding it rounds to an integer and leaves that integer in the low bits.
pub(crate) const ROUND: f32 = 12_582_912.0;
/// Cephes' `expf` polynomial `P`, highest power first (its last, 0.500000012, is 0.5 in
/// `f32`).
pub(crate) const EXP_COEFFICIENTS: [f32; 6] = [
    1.987_569_2e-4,
    1.398_199_9e-3,
    8.333_452e-3,
    4.166_579_6e-2,
    1.666_666_5e-1,
    0.5,
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exp_matches_the_standard_library() {
        let mut worst = 0.0_f64;
        let mut x = -87.0_f32;
        while x < 87.0 {
            let exact = f64::from(x).exp();
            let relative = (f64::from(exp(x)) - exact).abs() / exact;
            worst = worst.max(relative);
            x += 0.00137;
        }
        // 2 ulp of f32 (an ulp is 2⁻²³ ≈ 1.2·10⁻⁷ relative at most).
        assert!(worst < 2.4e-7, "worst relative error {worst:e}");
        assert_eq!(exp(0.0), 1.0);
        assert!(exp(-1000.0) > 0.0 && exp(1000.0).is_finite());
        assert!(exp(f32::NAN).is_nan());
    }

    #[test]
    fn activations_and_derivatives_match_their_definitions() {
        let inputs: Vec<f64> = (-80..=80).map(|k| f64::from(k) * 0.25).collect();
        let of = |activation: Activation| -> Vec<f64> {
            inputs
                .iter()
                .map(|&z| f64::from(activation.of(z as f32)))
                .collect()
        };
        let (logistic, tanh) = (of(Activation::Logistic), of(Activation::Tanh));
        for ((z, s), t) in inputs.iter().zip(&logistic).zip(&tanh) {
            // Single precision: within a few ulp of 1.
            assert!((s - 1.0 / (1.0 + (-z).exp())).abs() < 3e-7, "{z}");
            assert!((t - z.tanh()).abs() < 3e-7, "{z}");
        }
        for ((z, s), t) in inputs.iter().zip(&logistic).zip(&tanh) {
            let tanh_derivative = f64::from(Activation::Tanh.derivative(*t as f32));
            assert!(
                (tanh_derivative - 1.0 / z.cosh().powi(2)).abs() < 1e-6,
                "{z}"
            );
            let logistic_derivative = (-z).exp() / (1.0 + (-z).exp()).powi(2);
            let ours = f64::from(Activation::Logistic.derivative(*s as f32));
            assert!((ours - logistic_derivative).abs() < 1e-6, "{z}");
        }
    }
}
