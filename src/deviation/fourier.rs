//! The unified heading error model: a Fourier series of the raw heading, fitted by
//! least squares against a reference heading.
//!
//! Source: Chen et al., the PDR paper (`pdr-unified-heading-model.txt`), Section IV,
//! Eq. 11-12:
//!
//! ```text
//! δ = ξ − ξ' = A + B·sin ξ' + C·cos ξ' + D·sin 2ξ' + E·cos 2ξ' + ω
//! ```
//!
//! where ξ' is the raw (or already field-calibrated) heading, ξ the reference and ω the
//! noise, mostly the body's oscillation. The first harmonic (B, C) is hard iron, the
//! second (D, E) soft iron; the constant A absorbs the misalignment β between the
//! device and the walking direction, the declination λ, and any constant offset of the
//! reference. The deviation is an angle: it is unwrapped about its circular mean and,
//! after a first fit, re-wrapped about the fitted curve, so that a deviation near ±180°
//! is fitted on the right branch.
//!
//! The sine and cosine terms can be told apart only when the headings cover enough of
//! the circle. The fit measures this by the smallest eigenvalue of the normalised normal
//! matrix (0.5 for headings spread evenly over the circle) and falls back to the first
//! harmonic, then to the constant alone, saying so, rather than return coefficients the
//! data cannot support.

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::base::angle::wrap_to_pi;

/// Fewest pairs for a fit.
const MIN_PAIRS: usize = 10;
/// Smallest eigenvalue of the normalised normal matrix for a set of terms to be fitted
/// (0.5 for an even spread; a 60° arc of headings gives about 0.002 for five terms).
const MIN_EIGENVALUE: f64 = 0.02;
/// Wrap-and-refit passes.
const N_REWRAP_PASSES: usize = 3;

/// The coefficients, in degrees as the paper's Table II gives them.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct FourierDeviation {
    pub a_deg: f64,
    pub b_deg: f64,
    pub c_deg: f64,
    pub d_deg: f64,
    pub e_deg: f64,
}

impl FourierDeviation {
    /// δ(ξ') in radians.
    pub fn deviation_rad(&self, raw_heading_rad: f64) -> f64 {
        let [s1, c1, s2, c2] = harmonics(raw_heading_rad);
        (self.a_deg + self.b_deg * s1 + self.c_deg * c1 + self.d_deg * s2 + self.e_deg * c2)
            .to_radians()
    }

    /// The corrected heading ξ' + δ(ξ'), in [0, 2π).
    pub fn correct_rad(&self, raw_heading_rad: f64) -> f64 {
        crate::base::angle::wrap_to_2pi(raw_heading_rad + self.deviation_rad(raw_heading_rad))
    }

    fn from_coefficients_rad(coefficients: &[f64]) -> FourierDeviation {
        let get = |idx: usize| coefficients.get(idx).copied().unwrap_or(0.0).to_degrees();
        FourierDeviation {
            a_deg: get(0),
            b_deg: get(1),
            c_deg: get(2),
            d_deg: get(3),
            e_deg: get(4),
        }
    }
}

/// Which terms the data supported.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FourierTerms {
    /// A to E, as the paper.
    Full,
    /// A, B, C: the headings cover too little of the circle for the second harmonic.
    FirstHarmonic,
    /// A alone: the headings cover too little of the circle for any harmonic.
    ConstantOnly,
}

/// A fitted model and how well it fits its own data.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FourierFit {
    pub model: FourierDeviation,
    pub terms: FourierTerms,
    pub n_pairs: usize,
    /// The smallest eigenvalue of the normalised normal matrix of the terms fitted.
    pub min_eigenvalue: f64,
    /// Residual (reference − corrected) mean and standard deviation (deg).
    pub residual_mean_deg: f64,
    pub residual_std_deg: f64,
    /// The share of residuals within ±5°, in percent (the paper reports 78-94 %).
    pub within_5_deg_pct: f64,
    pub histogram: ResidualHistogram,
}

/// Residuals counted in 1° bins from −20° to 20°, with the tails counted apart.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ResidualHistogram {
    pub min_deg: f64,
    pub bin_width_deg: f64,
    pub counts: Vec<usize>,
    pub n_below: usize,
    pub n_above: usize,
}

impl ResidualHistogram {
    pub fn of(residuals_deg: &[f64]) -> ResidualHistogram {
        let (min_deg, bin_width_deg, n_bins) = (-20.0, 1.0, 40usize);
        let mut histogram = ResidualHistogram {
            min_deg,
            bin_width_deg,
            counts: vec![0; n_bins],
            n_below: 0,
            n_above: 0,
        };
        for &residual_deg in residuals_deg.iter().filter(|value| value.is_finite()) {
            let bin = ((residual_deg - min_deg) / bin_width_deg).floor();
            if bin < 0.0 {
                histogram.n_below += 1;
            } else if let Some(count) = histogram.counts.get_mut(bin as usize) {
                *count += 1;
            } else {
                histogram.n_above += 1;
            }
        }
        histogram
    }
}

#[derive(Debug, Clone, PartialEq, Error)]
pub enum FourierError {
    #[error("the deviation model needs at least {MIN_PAIRS} samples with a reference heading; there were {0}")]
    TooFewPairs(usize),
    #[error("{0} raw headings and {1} reference headings: they must pair up")]
    LengthMismatch(usize, usize),
}

/// `[sin ξ, cos ξ, sin 2ξ, cos 2ξ]`, the second pair by the double-angle formulas (one
/// `sin_cos` per heading: the models evaluate it at every sample of a recording).
pub(super) fn harmonics(heading_rad: f64) -> [f64; 4] {
    let (s1, c1) = heading_rad.sin_cos();
    [s1, c1, 2.0 * s1 * c1, (c1 - s1) * (c1 + s1)]
}

fn regressors(raw_heading_rad: f64, n_terms: usize) -> [f64; 5] {
    let [s1, c1, s2, c2] = harmonics(raw_heading_rad);
    let mut row = [1.0, s1, c1, s2, c2];
    for value in row.iter_mut().skip(n_terms) {
        *value = 0.0;
    }
    row
}

/// Solves the normal equations for the first `n_terms` terms; returns the coefficients
/// (radians) and the smallest eigenvalue of the normalised normal matrix.
fn solve(pairs: &[(f64, f64)], n_terms: usize) -> Option<(Vec<f64>, f64)> {
    let mut normal = DMatrix::<f64>::zeros(n_terms, n_terms);
    let mut rhs = DVector::<f64>::zeros(n_terms);
    for &(raw_rad, deviation_rad) in pairs {
        let row = regressors(raw_rad, n_terms);
        for i in 0..n_terms {
            rhs[i] += row[i] * deviation_rad;
            for j in 0..n_terms {
                normal[(i, j)] += row[i] * row[j];
            }
        }
    }
    let normalised = &normal / pairs.len() as f64;
    let min_eigenvalue = normalised
        .clone()
        .symmetric_eigen()
        .eigenvalues
        .iter()
        .copied()
        .fold(f64::INFINITY, f64::min);
    let solution = normal.cholesky()?.solve(&rhs);
    Some((solution.iter().copied().collect(), min_eigenvalue))
}

/// Fits the model to pairs of raw heading and reference heading (radians); non-finite
/// pairs are left out.
pub fn fit_fourier(
    raw_heading_rad: &[f64],
    reference_rad: &[f64],
) -> Result<FourierFit, FourierError> {
    if raw_heading_rad.len() != reference_rad.len() {
        return Err(FourierError::LengthMismatch(
            raw_heading_rad.len(),
            reference_rad.len(),
        ));
    }
    let mut pairs: Vec<(f64, f64)> = raw_heading_rad
        .iter()
        .zip(reference_rad)
        .filter(|(raw, reference)| raw.is_finite() && reference.is_finite())
        .map(|(&raw, &reference)| (raw, wrap_to_pi(reference - raw)))
        .collect();
    if pairs.len() < MIN_PAIRS {
        return Err(FourierError::TooFewPairs(pairs.len()));
    }
    // Unwrap about the circular mean first, so that a deviation near ±180° is one
    // branch before the first fit.
    let (sum_sin, sum_cos) =
        pairs
            .iter()
            .fold((0.0, 0.0), |(sum_sin, sum_cos), &(_, deviation_rad)| {
                (sum_sin + deviation_rad.sin(), sum_cos + deviation_rad.cos())
            });
    let mean_rad = sum_sin.atan2(sum_cos);
    for pair in &mut pairs {
        pair.1 = mean_rad + wrap_to_pi(pair.1 - mean_rad);
    }
    let mut fitted: Option<(Vec<f64>, f64, FourierTerms)> = None;
    for (n_terms, terms) in [
        (5, FourierTerms::Full),
        (3, FourierTerms::FirstHarmonic),
        (1, FourierTerms::ConstantOnly),
    ] {
        if let Some((coefficients, min_eigenvalue)) = solve(&pairs, n_terms) {
            if min_eigenvalue >= MIN_EIGENVALUE || n_terms == 1 {
                fitted = Some((coefficients, min_eigenvalue, terms));
                break;
            }
        }
    }
    let Some((mut coefficients, min_eigenvalue, terms)) = fitted else {
        return Err(FourierError::TooFewPairs(pairs.len()));
    };
    let n_terms = coefficients.len();
    for _ in 0..N_REWRAP_PASSES {
        let model = FourierDeviation::from_coefficients_rad(&coefficients);
        let mut changed = false;
        for pair in &mut pairs {
            let predicted_rad = model.deviation_rad(pair.0);
            let rewrapped = predicted_rad + wrap_to_pi(pair.1 - predicted_rad);
            changed |= (rewrapped - pair.1).abs() > 1e-9;
            pair.1 = rewrapped;
        }
        if !changed {
            break;
        }
        if let Some((refitted, _)) = solve(&pairs, n_terms) {
            coefficients = refitted;
        }
    }
    let model = FourierDeviation::from_coefficients_rad(&coefficients);
    let residuals_deg: Vec<f64> = pairs
        .iter()
        .map(|&(raw_rad, deviation_rad)| {
            wrap_to_pi(deviation_rad - model.deviation_rad(raw_rad)).to_degrees()
        })
        .collect();
    let n = residuals_deg.len() as f64;
    let residual_mean_deg = residuals_deg.iter().sum::<f64>() / n;
    let residual_std_deg = (residuals_deg
        .iter()
        .map(|residual| (residual - residual_mean_deg).powi(2))
        .sum::<f64>()
        / (n - 1.0).max(1.0))
    .sqrt();
    let within_5_deg_pct = 100.0
        * residuals_deg
            .iter()
            .filter(|residual| residual.abs() <= 5.0)
            .count() as f64
        / n;
    Ok(FourierFit {
        model,
        terms,
        n_pairs: pairs.len(),
        min_eigenvalue,
        residual_mean_deg,
        residual_std_deg,
        within_5_deg_pct,
        histogram: ResidualHistogram::of(&residuals_deg),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::base::rng::SplitMix64;

    const TRUTH: FourierDeviation = FourierDeviation {
        a_deg: 9.0,
        b_deg: 31.4,
        c_deg: 0.9,
        d_deg: 0.6,
        e_deg: 1.8,
    };

    /// Raw headings over `arc_deg` of the circle and their references with noise.
    fn pairs(n: usize, arc_deg: f64, noise_deg: f64, seed: u64) -> (Vec<f64>, Vec<f64>) {
        let mut rng = SplitMix64::new(seed);
        (0..n)
            .map(|_| {
                let raw_rad = rng.uniform_in(0.0, arc_deg).to_radians();
                let reference_rad = raw_rad
                    + TRUTH.deviation_rad(raw_rad)
                    + noise_deg.to_radians() * rng.gaussian();
                (raw_rad, crate::base::angle::wrap_to_2pi(reference_rad))
            })
            .unzip()
    }

    #[test]
    fn table_ii_coefficients_come_back_from_noisy_pairs() {
        let (raw, reference) = pairs(3000, 360.0, 3.0, 1);
        let fit = fit_fourier(&raw, &reference).expect("fits");
        assert_eq!(fit.terms, FourierTerms::Full);
        let model = fit.model;
        for (got, want) in [
            (model.a_deg, TRUTH.a_deg),
            (model.b_deg, TRUTH.b_deg),
            (model.c_deg, TRUTH.c_deg),
            (model.d_deg, TRUTH.d_deg),
            (model.e_deg, TRUTH.e_deg),
        ] {
            assert!((got - want).abs() < 0.3, "{model:?}");
        }
        assert!((fit.residual_std_deg - 3.0).abs() < 0.2, "{fit:?}");
        assert!(fit.within_5_deg_pct > 85.0);
        let counted: usize = fit.histogram.counts.iter().sum::<usize>()
            + fit.histogram.n_below
            + fit.histogram.n_above;
        assert_eq!(counted, 3000);
    }

    #[test]
    fn deviations_across_180_degrees_are_fitted_on_the_right_branch() {
        let model = FourierDeviation {
            a_deg: 175.0,
            b_deg: 10.0,
            ..FourierDeviation::default()
        };
        let raw: Vec<f64> = (0..360).map(|deg| f64::from(deg).to_radians()).collect();
        let reference: Vec<f64> = raw.iter().map(|&raw| model.correct_rad(raw)).collect();
        let fit = fit_fourier(&raw, &reference).expect("fits");
        assert!(
            (fit.model.a_deg - 175.0).abs() < 1e-6 && (fit.model.b_deg - 10.0).abs() < 1e-6,
            "{:?}",
            fit.model
        );
    }

    #[test]
    fn a_narrow_arc_falls_back_to_fewer_terms() {
        let (raw, reference) = pairs(500, 20.0, 1.0, 2);
        let fit = fit_fourier(&raw, &reference).expect("fits");
        assert_eq!(fit.terms, FourierTerms::ConstantOnly);
        assert_eq!((fit.model.b_deg, fit.model.d_deg), (0.0, 0.0));
        let (raw, reference) = pairs(500, 200.0, 1.0, 3);
        assert_ne!(
            fit_fourier(&raw, &reference).expect("fits").terms,
            FourierTerms::ConstantOnly
        );
    }

    #[test]
    fn bad_input_is_an_error_not_a_panic() {
        assert_eq!(
            fit_fourier(&[1.0; 3], &[1.0; 3]),
            Err(FourierError::TooFewPairs(3))
        );
        assert_eq!(
            fit_fourier(&[1.0; 3], &[1.0; 4]),
            Err(FourierError::LengthMismatch(3, 4))
        );
        let nan = vec![f64::NAN; 50];
        assert_eq!(fit_fourier(&nan, &nan), Err(FourierError::TooFewPairs(0)));
        // All headings identical: constant only, no NaN.
        let fit = fit_fourier(&[0.5; 50], &[0.7; 50]).expect("constant");
        assert_eq!(fit.terms, FourierTerms::ConstantOnly);
        assert!((fit.model.a_deg - 0.2f64.to_degrees()).abs() < 1e-9);
    }
}
