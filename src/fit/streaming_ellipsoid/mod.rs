//! 3D ellipsoid calibration: hard iron, soft iron and field magnitude from samples
//! taken in many attitudes, refusing or falling back on flat data.
//!
//! It is the live panel's fit (refitted from its power sums whenever asked), one of the
//! starts of the 3D fit with the dip ([`crate::fit::ellipsoid`]), and the ellipsoid
//! benchmark's (`benches/ellipsoid.rs`).
//!
//! ## Model
//!
//! Moafipoor et al. (2007), Eq. 2-3 and 5: a sample is `m = S·b + h`, where `b` is the
//! Earth's field in the body frame (constant magnitude `F`), `S` the soft iron and `h`
//! the hard iron. As the device turns, `b` sweeps a sphere of radius `F`, so the samples
//! lie on the ellipsoid `(m − h)ᵀ·Q·(m − h) = 1` with `Q = S⁻ᵀ·S⁻¹ / F²`. The
//! correction is `A = F·Q^½` (symmetric), so that `|A·(m − h)| = F` for every sample.
//!
//! ## Method
//!
//! 1. **One streaming pass** ([`EllipsoidAccumulator`]): the 35 power sums
//!    `Σ dx^a·dy^b·dz^c` (`a + b + c ≤ 4`) of the samples' offsets `d` from the first
//!    sample. Every entry of the 10×10 scatter matrix `D·Dᵀ` of the quadric's design
//!    vector is one of them, so no N×10 design matrix is ever built, two accumulators
//!    merge exactly (the sums of one are moved to the other's origin by the binomial
//!    theorem), and the cost is about 50 multiplications and 35 additions per sample
//!    (chunked to keep the sums in registers, two samples per SSE2 register on x86-64:
//!    about 6 ms for a million samples). Before solving, the sums are moved to the mean
//!    and scaled by the RMS radius, which keeps the normal equations well conditioned
//!    whatever the hard iron.
//! 2. **Algebraic, ellipsoid-specific fit**: Li and Griffiths (2004), *Least squares
//!    ellipsoid specific fitting*, Proc. Geometric Modeling and Processing, the
//!    algorithm of Magneto 1.2. With the scatter split into quadratic (`S11`) and
//!    linear-and-constant (`S22`) blocks, the quadratic coefficients `v1` solve the
//!    generalised eigenproblem `(S11 − S12·S22⁻¹·S21)·v1 = λ·C·v1` for its one positive
//!    eigenvalue, where `C` encodes the ellipsoid constraint `4J − I² = 1` (their
//!    constraint with k = 4), and `v2 = −S22⁻¹·S21·v1`. The constrained models write
//!    the quadric matrix as a combination of fixed matrices (their generators) and run
//!    the same solver on the reduced design; for the sphere this is Kåsa's (1976) linear
//!    fit of `|m|² = 2·hᵀm + (R² − |h|²)`.
//! 3. **Conversion**: the centre is the hard iron and `A` is the symmetric square root
//!    of the normalised quadric matrix, scaled so that `det A = 1` (the field is then
//!    the geometric mean of the semi-axes, as in NXP's application note AN4246) or so
//!    that the radius is the expected field when the caller gives one.
//! 4. **Geometric refinement** (Levenberg-Marquardt, the `levenberg-marquardt` crate):
//!    residuals `(|A·(m − h)| − R) / (det A)^⅓` with `h` (3) and the free entries of `A`
//!    (1, 3, 5 or 6) as parameters and `R` fixed, which is the same problem as
//!    `det A = 1` with `R` free. A refinement that drifts along a valley the data hardly
//!    constrain (its hard iron predicted more than twice as uncertain as at the start)
//!    is dropped in favour of the algebraic fit.
//! 5. **Model choice** (`Auto`, after MATLAB's `magcal`): the simplest model whose
//!    residual is close to the full model's (the rule is in [`fit_ellipsoid`]).
//! 6. **Observability**: data from walkers and vehicles turn through every heading but
//!    tilt only a few degrees: a narrow band of the ellipsoid. Its in-plane shape is
//!    well observed, but the scale along the band's axis cannot be told from the hard
//!    iron along it (the band hardly moves along it), so a full fit there follows the
//!    noise. When the band is narrower than [`MIN_FULL_TILT_SPAN_DEG`] and the `Band`
//!    model, which ties that scale to the in-plane ones, fits as well as the full one,
//!    the fit falls back to it and says why.
//!
//! ## Limits
//!
//! The model is linear (hard and soft iron fixed in the body frame); fields that change
//! during the recording (a passing car, a steel desk) bend the ellipsoid and no model
//! here removes them. The algebraic fit is biased by about `σ²/R²` (negligible at
//! 0.3 µT of noise on 50 µT); the refinement removes most of that. Without an expected
//! field the absolute scale of `A` is fixed by the `det A = 1` convention only, so the
//! corrected magnitude is the geometric mean of the semi-axes, not necessarily the true
//! field; with one, the expected field sets that scale and nothing else (it cannot pin
//! what the geometry leaves free unless the sensor's gain is trusted, which is not
//! assumed). The dip angle is not used. On a band (circle-only data) a 3D fit leaves
//! heading errors of 1-4° RMS even after the fallback (measured in the tests); the
//! tilt-aware plane fit ([`crate::fit::ellipse`]) is the method for such data. The geometric
//! refinement runs on at most [`MAX_REFINE_SAMPLES`] samples, evenly spaced.
//!
//! ## Files
//!
//! `moments.rs` the power sums (step 1) and `accumulator.rs` the streaming
//! [`EllipsoidAccumulator`] over them; `algebraic.rs` Li and Griffiths' fit and the
//! conversion to a calibration (steps 2-3); `refinement.rs` the geometric refinement
//! (step 4); `observability.rs` what the data's shape lets a fit see, its refusals and
//! the band fallback (step 6); this file the types, the acceptance checks and
//! [`fit_ellipsoid`] with the model choice (step 5); `tests.rs` the tests.

use nalgebra::Vector3;
use serde::Serialize;
use thiserror::Error;

use crate::fit::model::FieldCalibration;

mod accumulator;
mod algebraic;
mod moments;
mod observability;
mod refinement;

pub use accumulator::EllipsoidAccumulator;
use algebraic::*;
use moments::*;
use observability::*;
use refinement::*;

/// Fewer samples than this cannot determine the nine parameters of a full ellipsoid
/// with any redundancy.
pub const MIN_SAMPLES: usize = 10;

/// The geometric refinement uses at most this many samples, evenly spaced. Its
/// Jacobian is N×p and the library factorises it each iteration; beyond this size the
/// estimate's noise (σ·√(3/N), 0.004 µT here at σ = 0.3 µT) no longer matters.
pub const MAX_REFINE_SAMPLES: usize = 20_000;

/// Samples beyond this (µT, on any axis) are refused: magnetometers read up to a few
/// thousand µT, and 1 T keeps the fourth powers of a billion samples finite.
pub const MAX_ABS_UT: f64 = 1e6;

/// Below this tilt span (±degrees) the full and diagonal models fall back to the band
/// model. Measured by the `band_sweep` test over 30 random distortions (0.3 µT of
/// noise, 3000 samples, inclination 65°), the RMS heading error, mean and (worst), of
/// the full and the band model: at a span of 9.6° (roll and pitch within ±10°) 3.9°
/// (4.5°) and 1.5° (4.1°); at 17° 3.6° (4.2°) and 1.6° (3.7°); at 20° 2.7° (3.1°) and
/// 1.8° (4.4°); at 22° (±30°) 2.0° (3.1°) and 2.0° (5.1°); at 24.5° 1.2° (1.6°) and 2.2°
/// (5.7°); over a full sphere the full model reaches the noise's own 0.8°.
pub const MIN_FULL_TILT_SPAN_DEG: f64 = 22.0;

/// Auto keeps a simpler model when the systematic part it misses,
/// `√(rms_simple² − rms_full²)`, is below this fraction of the full model's RMS: the RMS
/// then grows by under 5 %, which no user could tell from noise.
const AUTO_EXCESS_OF_NOISE: f64 = 0.3;

/// ... or below this fraction of the field (0.1 %: a scale error that moves the
/// heading by under 0.06°).
const AUTO_EXCESS_OF_FIELD: f64 = 0.001;

/// A fit whose RMS residual exceeds this fraction of the field is refused: noise is
/// 0.1-1 µT, about 1 % of the field, and even a walk past parked cars stays within a
/// few percent, so 10 % means the samples do not lie on any one ellipsoid.
const MAX_RESIDUAL_FRACTION: f64 = 0.1;

/// A fitted ellipsoid whose longest axis is this many times its shortest is not a
/// magnetometer's distortion but a failed fit: the soft iron of phones and boards is a
/// few percent, and mismatched sensor axes differ by ±15 % at most.
const MAX_AXIS_RATIO: f64 = 2.0;

/// Which soft-iron matrix a fit may use, as MATLAB's `magcal` offers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
pub enum EllipsoidModel {
    /// Hard iron and one scale (`A = s·I`; magcal's `eye`).
    Sphere,
    /// Hard iron and one scale per axis (`magcal`'s `diag`).
    Diagonal,
    /// Hard iron and a symmetric `A` (`magcal`'s `sym`).
    Full,
    /// For a band of data (every heading, little tilt): hard iron and a symmetric `A`
    /// whose scale along the band's axis (the data's direction of least spread) is
    /// tied to the mean of its two in-plane scales, five free entries instead of six.
    /// Not in `magcal`; the fallback of the others when the band is narrow.
    Band,
    /// The simplest of sphere, diagonal and full whose residual is close to the full
    /// model's.
    #[default]
    Auto,
}

/// What [`fit_ellipsoid`] may do.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct EllipsoidOptions {
    pub model: EllipsoidModel,
    /// The Earth's field magnitude where the data were taken (from a model such as the
    /// WMM), if known. The corrected field then has this magnitude.
    pub expected_field_ut: Option<f64>,
    /// Refine the algebraic fit by Levenberg-Marquardt on geometric residuals.
    pub refine: bool,
}

impl Default for EllipsoidOptions {
    fn default() -> Self {
        EllipsoidOptions {
            model: EllipsoidModel::Auto,
            expected_field_ut: None,
            refine: true,
        }
    }
}

/// A 3D calibration and how well the data supported it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EllipsoidFit {
    pub calibration: FieldCalibration,
    /// The model used (never `Auto`).
    pub model: EllipsoidModel,
    /// RMS of `|corrected| − field_ut` over the samples (over the refinement's evenly
    /// spaced subset when there are more than [`MAX_REFINE_SAMPLES`]).
    pub residual_rms_ut: f64,
    /// Standard deviation of `|corrected|` over its mean, in percent (MotionCal's
    /// "variance"), over the same samples.
    pub field_spread_pct: f64,
    pub n_samples: usize,
    /// Whether the geometric refinement ran and was kept.
    pub refined: bool,
    /// Why the fit used a simpler model than asked for, when it did.
    pub fallback: Option<String>,
    pub observability: Observability,
}

/// How well the samples' geometry constrains a 3D fit.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Observability {
    /// Standard deviations of the raw samples along their principal axes, largest
    /// first (µT).
    pub principal_spread_ut: [f64; 3],
    /// The unit direction (body frame) along which the samples vary least: the axis
    /// of a band of data.
    pub least_spread_axis: Vector3<f64>,
    /// The half-width (±degrees) of the band the samples form around that axis,
    /// `atan(√3·σ₃ / √(σ₁² + σ₂²))`: a band of tilts uniform within ±a degrees gives
    /// about a, a level ring gives the noise's share (`√3·σ/H`, 1.4° at 0.3 µT), a
    /// full sphere `atan √(3/2)` ≈ 51° (40-50° once distorted). Roll and pitch each
    /// uniform within ±10° give about 10°, within ±30° about 22°.
    pub tilt_span_deg: f64,
    /// Longest over shortest semi-axis of the fitted raw ellipsoid.
    pub axis_ratio: f64,
    /// The hard iron's predicted 1σ uncertainty along its worst direction (µT), from the
    /// Gauss-Newton covariance of the geometric residuals: noise and geometry, not model
    /// error. `None` from [`EllipsoidAccumulator::solve`], which has no samples.
    pub hard_iron_std_ut: Option<f64>,
}

/// Why an ellipsoid could not be fitted. Messages say what the user can do.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum EllipsoidError {
    #[error(
        "too few magnetometer samples ({n_samples}; at least {min} are needed). Record \
         longer while turning the device through many orientations."
    )]
    TooFewSamples { n_samples: usize, min: usize },

    #[error(
        "sample {sample_idx} is not a finite number. Remove NaN or infinite values from \
         the input."
    )]
    NonFinite { sample_idx: usize },

    #[error(
        "sample {sample_idx} reads {value_ut:e} µT, beyond any magnetometer's range \
         (±{max_ut:e} µT). Check the units of the input (µT are expected)."
    )]
    OutOfRange {
        sample_idx: usize,
        value_ut: f64,
        max_ut: f64,
    },

    #[error(
        "the expected field {field_ut} µT is not a positive number. Give the Earth's field \
         magnitude where the data were taken (25-65 µT), or none."
    )]
    InvalidExpectedField { field_ut: f64 },

    #[error(
        "the samples hardly change (spread {spread_ut:.2} µT): the device was not turned. \
         Record while turning it through many orientations."
    )]
    NoRotation { spread_ut: f64 },

    #[error(
        "the samples lie along a line ({length_ut:.1} µT long, {width_ut:.2} µT wide), not \
         on an ellipsoid: the field changed in one direction only, as near a moving magnet. \
         Record away from moving iron while turning the device."
    )]
    Line { length_ut: f64, width_ut: f64 },

    #[error(
        "the samples lie in a plane (±{tilt_span_deg:.1}° of tilt), so a 3D fit cannot see \
         across it. Use the level 2D calibration with the accelerometer's tilt, or record \
         again while also tilting the device."
    )]
    Plane { tilt_span_deg: f64 },

    #[error(
        "no {model:?} ellipsoid fits the samples (the best quadric is not closed, or its \
         axes differ more than {max_axis_ratio}:1). Record away from iron that moves with \
         respect to the sensor, turning the device through many orientations."
    )]
    NotAnEllipsoid {
        model: EllipsoidModel,
        max_axis_ratio: f64,
    },

    #[error(
        "the samples lie far from any ellipsoid (RMS {residual_rms_ut:.1} µT off a \
         {field_ut:.1} µT field): the field changed during the recording, as near moving \
         iron, a magnet or a passing vehicle. Record again away from them."
    )]
    PoorFit { residual_rms_ut: f64, field_ut: f64 },
}

/// The calibration if it is finite and its axes differ by at most [`MAX_AXIS_RATIO`].
fn plausible(calibration: FieldCalibration) -> Option<FieldCalibration> {
    let finite = calibration.hard_iron_ut.iter().all(|v| v.is_finite())
        && calibration.soft_iron.iter().all(|v| v.is_finite())
        && calibration.field_ut.is_finite();
    (finite && axis_ratio(&calibration.soft_iron) <= MAX_AXIS_RATIO).then_some(calibration)
}

fn check_residual(
    residual_rms_ut: f64,
    calibration: &FieldCalibration,
) -> Result<(), EllipsoidError> {
    if residual_rms_ut <= MAX_RESIDUAL_FRACTION * calibration.field_ut {
        Ok(())
    } else {
        Err(EllipsoidError::PoorFit {
            residual_rms_ut,
            field_ut: calibration.field_ut,
        })
    }
}

fn check_expected_field(expected_field_ut: Option<f64>) -> Result<Option<f64>, EllipsoidError> {
    match expected_field_ut {
        Some(field_ut) if field_ut.is_nan() || field_ut <= 0.0 || field_ut.is_infinite() => {
            Err(EllipsoidError::InvalidExpectedField { field_ut })
        }
        other => Ok(other),
    }
}

/// One model's fit: algebraic, then refined when asked and when the refinement holds.
#[derive(Debug, Clone, Copy)]
struct Candidate {
    model: EllipsoidModel,
    calibration: FieldCalibration,
    refined: bool,
    rms_ut: f64,
}

fn fit_candidate(
    geometry: &Geometry,
    model: EllipsoidModel,
    samples_ut: &[Vector3<f64>],
    options: &EllipsoidOptions,
) -> Result<Candidate, EllipsoidError> {
    let algebraic = geometry.algebraic_fit(model, options.expected_field_ut)?;
    let refined = if options.refine {
        refine(
            samples_ut,
            model,
            geometry,
            &algebraic,
            options.expected_field_ut,
        )
    } else {
        None
    };
    let (calibration, refined) = match refined {
        Some(refined) => (refined, true),
        None => (algebraic, false),
    };
    let (rms_ut, _) = residuals(samples_ut, &calibration);
    Ok(Candidate {
        model,
        calibration,
        refined,
        rms_ut,
    })
}

/// Fits a 3D calibration to magnetometer samples (µT, body frame).
///
/// The steps are in the module header. The model is chosen in two stages:
///
/// - **Observability.** Data within ±4° of a plane, on a line or at one point are
///   refused. If the samples form a band narrower than ±[`MIN_FULL_TILT_SPAN_DEG`]
///   (walking or driving: every heading, little tilt) and the band model fits them as
///   well as the full one (its RMS residual exceeds the full model's by under 0.5 %),
///   the full, diagonal and auto models become the band model, and `fallback` says
///   so.
/// - **Auto.** Among sphere, diagonal and full, the simplest whose RMS residual is
///   close to the full model's: a simpler model is kept when the systematic part it
///   misses, `√(rms² − rms_full²)`, is under 0.3 of `rms_full` (the RMS grows by under
///   5 %, which is indistinguishable from noise) or under 0.1 % of the field (a scale
///   error worth under 0.06° of heading). MATLAB's `magcal` picks "the best fit"
///   without saying how; this rule prefers fewer parameters unless the data show they
///   are needed.
pub fn fit_ellipsoid(
    mag_ut: &[Vector3<f64>],
    options: &EllipsoidOptions,
) -> Result<EllipsoidFit, EllipsoidError> {
    check_expected_field(options.expected_field_ut)?;
    let mut accumulator = EllipsoidAccumulator::new();
    accumulator.add_all(mag_ut);
    let geometry = accumulator.geometry()?;
    let strided: Vec<Vector3<f64>>;
    let refine_set: &[Vector3<f64>] = if mag_ut.len() > MAX_REFINE_SAMPLES {
        let stride = mag_ut.len().div_ceil(MAX_REFINE_SAMPLES);
        strided = mag_ut.iter().step_by(stride).copied().collect();
        &strided
    } else {
        mag_ut
    };
    let fit = |model| fit_candidate(&geometry, model, refine_set, options);
    let may_fall_back = matches!(
        options.model,
        EllipsoidModel::Full | EllipsoidModel::Diagonal | EllipsoidModel::Auto
    );
    let mut full = None;
    if may_fall_back && geometry.tilt_span_deg < MIN_FULL_TILT_SPAN_DEG {
        let (band, full_fit) = (fit(EllipsoidModel::Band), fit(EllipsoidModel::Full));
        let fall_back = match (&band, &full_fit) {
            (Ok(band), Ok(full)) => prefers_band(&geometry, band.rms_ut, full.rms_ut),
            (Ok(_), Err(_)) => true,
            _ => false,
        };
        if let (true, Ok(band)) = (fall_back, band) {
            let sentence = band_fallback_sentence(&geometry);
            return finish(&geometry, mag_ut.len(), refine_set, band, Some(sentence));
        }
        full = full_fit.ok();
    }
    let candidates: &[EllipsoidModel] = match options.model {
        EllipsoidModel::Auto => &[
            EllipsoidModel::Full,
            EllipsoidModel::Diagonal,
            EllipsoidModel::Sphere,
        ],
        EllipsoidModel::Full => &[EllipsoidModel::Full],
        EllipsoidModel::Diagonal => &[EllipsoidModel::Diagonal],
        EllipsoidModel::Sphere => &[EllipsoidModel::Sphere],
        EllipsoidModel::Band => &[EllipsoidModel::Band],
    };
    let mut fitted: Vec<Candidate> = Vec::new();
    let mut first_error = None;
    for &model in candidates {
        let candidate = match (model, full.take()) {
            (EllipsoidModel::Full, Some(full)) => Ok(full),
            _ => fit(model),
        };
        match candidate {
            Ok(candidate) => fitted.push(candidate),
            Err(error) => {
                first_error.get_or_insert(error);
            }
        }
    }
    // The candidates run from most to fewest parameters: take the last that passes.
    let Some(full_rms_ut) = fitted.first().map(|candidate| candidate.rms_ut) else {
        return Err(first_error.unwrap_or(EllipsoidError::NotAnEllipsoid {
            model: options.model,
            max_axis_ratio: MAX_AXIS_RATIO,
        }));
    };
    let simplest_idx = fitted
        .iter()
        .rposition(|candidate| {
            let excess_ut = (candidate.rms_ut.powi(2) - full_rms_ut.powi(2))
                .max(0.0)
                .sqrt();
            excess_ut <= AUTO_EXCESS_OF_NOISE * full_rms_ut
                || excess_ut <= AUTO_EXCESS_OF_FIELD * candidate.calibration.field_ut
        })
        .unwrap_or(0);
    let chosen = fitted.swap_remove(simplest_idx);
    finish(&geometry, mag_ut.len(), refine_set, chosen, None)
}

/// The result of the chosen candidate, with its figures.
fn finish(
    geometry: &Geometry,
    n_samples: usize,
    refine_set: &[Vector3<f64>],
    chosen: Candidate,
    fallback: Option<String>,
) -> Result<EllipsoidFit, EllipsoidError> {
    // Over the evenly spaced subset when there is one: the figures' own noise there
    // is under 1 %, and a pass over millions of samples would double the time.
    let (residual_rms_ut, field_spread_pct) = residuals(refine_set, &chosen.calibration);
    check_residual(residual_rms_ut, &chosen.calibration)?;
    let generators = generators(chosen.model, geometry);
    let hard_iron_std_ut = problem_at(refine_set, &generators, &chosen.calibration)
        .and_then(|problem| hard_iron_std_ut(&problem));
    Ok(EllipsoidFit {
        observability: Observability {
            hard_iron_std_ut,
            ..geometry.observability(&chosen.calibration)
        },
        calibration: chosen.calibration,
        model: chosen.model,
        residual_rms_ut,
        field_spread_pct,
        n_samples,
        refined: chosen.refined,
        fallback,
    })
}

#[cfg(test)]
mod tests;
