//! 3D calibration that uses everything a log knows: the field's magnitude, the
//! accelerometer's tilt through the **dip-angle invariance**, and the World Magnetic
//! Model's field strength and inclination as priors; robust to disturbed samples, and
//! saying which parameters the data could not see instead of refusing.
//!
//! ## Model
//!
//! The magnetometer reads `m = S·b + h + e` (Moafipoor et al. 2007, Eq. 5): the Earth's
//! field `b` in the body frame (x forward, y right, z down; µT) through a soft-iron
//! matrix `S`, plus the hard iron `h` and noise. The correction is `c = D·(m − h)`
//! with `D ≈ S⁻¹`, a **general** 3×3 matrix: besides scale factors and cross-axis soft
//! iron it holds the small rotation between the magnetometer's axes and the
//! accelerometer's, which matters for tilt compensation. For every sample two things
//! are known without the heading:
//!
//! ```text
//! r_B = |c| − F            the field's magnitude is the Earth's, F
//! r_V = ĝ·c − V            the component along "down" is constant, V = F·sin(dip)
//! ```
//!
//! `ĝ` is the unit "down" vector in body axes from the accelerometer's specific force
//! (averaged over about a second, see [`crate::attitude::tilt`]). The second residual is the
//! dot-product (dip-angle) invariance: the angle between gravity and the field does not
//! change as the device turns. It is what Kok and Schön (2016, *Magnetometer calibration
//! using inertial sensors*, IEEE Sensors Journal 16(14)) and Li and Li (2012, *A new
//! calibration method for tri-axial field sensors in strap-down navigation systems*,
//! Meas. Sci. Technol. 23) add to the ellipsoid fit, and it is what makes a device
//! that only turns in yaw with a few degrees of tilt calibratable: the magnitude
//! alone sees a band of the ellipsoid, the vertical residual ties the band's height
//! (the vertical hard iron, the vertical scale, the mag-to-accelerometer alignment) to
//! the tilt. Without an accelerometer only `r_B` is used, and the model is the
//! classic ellipsoid fit.
//!
//! ## Priors (a maximum a posteriori fit)
//!
//! - `F` is the WMM's total intensity at the log's place and date when known (as
//!   ArduPilot scales its compass to the WMM), else the radius of the first fit: the
//!   overall scale of `D` is a convention the headings do not see.
//! - `V` has a prior `F·sin(I_WMM)` with a standard deviation of
//!   [`INCLINATION_PRIOR_STD_DEG`] of dip (local anomalies); without a model, none.
//! - `D` has a weak prior towards `s·I` ([`SOFT_IRON_PRIOR_STD`] of `s` per entry) and
//!   its rotation part (the antisymmetric part) towards zero with
//!   [`ROTATION_PRIOR_STD_RAD`]. The data overrule them wherever they see anything; where
//!   they see nothing (a level turn says nothing of the vertical scale), the posterior
//!   keeps the prior, and the fit reports the parameter as not observed, with its
//!   uncertainty.
//! - `h` has no prior worth the name ([`HARD_IRON_PRIOR_STD_UT`]).
//!
//! ## Fit
//!
//! 1. Starts: the algebraic ellipsoid of [`crate::fit::streaming_ellipsoid`] (Li and Griffiths; needs
//!    a 3D spread), a band start for yaw-only data (the samples' principal plane, a
//!    direct ellipse fit in it, the vertical hard iron from the prior's dip), and
//!    Kåsa's sphere. They are ranked by their median residuals as they stand; the
//!    first two (more while none is plausible) are solved, side by side on the
//!    machine's threads, on one evenly spaced subset of at most [`MAX_FIT_SAMPLES`], and
//!    the plausible solution with the smallest median residuals is the fit.
//! 2. Levenberg-Marquardt on the normal equations (13 parameters at most: the `N×13`
//!    Jacobian is never formed, so 10⁴ samples take milliseconds), inside iteratively
//!    reweighted least squares: Huber weights, then Cauchy weights, on residuals scaled
//!    by their median absolute deviation. Samples near moving iron become outliers with
//!    small weights, not a reason to give nothing. Each solve first probes (two
//!    reweightings, a few steps each) along every direction of the model, then
//!    decides from the probe's normal equations which directions the data see, and
//!    converges along those alone: along a direction the data do not see the cost is
//!    flat, and a solve that wanders there spends its steps moving the hard iron by tens
//!    of µT for nothing (on the TYREX phone walks, 55 steps per solve ended wherever the
//!    step budget ran out).
//! 3. The posterior covariance `(JᵀWJ + P)⁻¹`, inflated by the residuals' lag-one
//!    autocorrelation (neighbouring samples share their tilt error), gives each
//!    parameter's standard deviation and the heading's: its gradient through levelling,
//!    averaged over the samples.
//!
//! ## Bands, trust and fallbacks
//!
//! - **A band of data** (a car in its mount, a level turn: the tilt within 3° RMS of
//!   its mean and the field within 20° of a plane, or without an accelerometer the
//!   samples within 5° of a plane): what only tilt shows of a 3D distortion is then
//!   decided by the accelerometer's own errors more than by the magnetometer, so the
//!   band model is fitted instead, and what the band hardly sees stays at the priors
//!   (`FreeDirections::band` in `solve.rs`).
//! - **Trust in the tilt** ([`fit_inertial_trusting`], the trust from the estimate of
//!   down, [`crate::attitude::down`]): where the samples' mean trust is below
//!   [`TRUSTED_TILT`] (a swinging phone, a run), each sample's dip residual weighs its
//!   own trust, a dip far from the model's refuses no solution (the tilt is what is
//!   wrong), and the fit says so ([`InertialFit::tilt_untrusted`], decided once per
//!   sample set); elsewhere every dip weighs alike.
//! - **Plausibility**: a solution that mirrors the field, runs away in gain, takes a
//!   shape no material gives or a dip far from the model's is set aside
//!   (`plausibility.rs`); when no full soft iron is left, the fit falls back to hard
//!   iron, one scale and the dip ([`SoftIronModel::Isotropic`]) and says why.
//!
//! ## Limits
//!
//! A field that changes along the recording (indoors, near iron) is not one field: the
//! robust weights keep its most common value, and the residual figures say how far the
//! rest is. A rotation of the magnetometer about "down" is seen only through changes of
//! tilt; with none, it stays at its prior (zero) and a constant heading offset remains,
//! which only a reference heading (Eq. 8, the Fourier model) can remove. The tilt is the
//! accelerometer's: sustained accelerations (a car braking) bend it, and the robust
//! weights, not the model, deal with them.
//!
//! The files: here the options, result and errors, the entry points and the choice
//! among starts and models; `samples.rs` the sample sets, `starts.rs` the starts,
//! `residuals.rs` the residuals and normal equations (the samples' rank-two updates
//! added to `JᵀWJ` in blocks of 16, the same sums in the same order as sample by
//! sample), `solve.rs` the reweighted solver and the covariance, `plausibility.rs`
//! whether a solution is a calibration, `uncertainty.rs` the report of a converged one.

use nalgebra::{Matrix3, SMatrix, SVector, Vector2, Vector3};
use serde::Serialize;
use thiserror::Error;

use crate::attitude::tilt::Tilt;
use crate::fit::model::FieldCalibration;

mod starts;
use starts::{principal_plane, ranked, starts};

mod plausibility;
mod residuals;
mod samples;
mod solve;
mod uncertainty;
use plausibility::*;
use residuals::*;
use samples::*;
use solve::*;

/// Fewer samples than this cannot determine the thirteen parameters with redundancy.
pub const MIN_SAMPLES: usize = 20;

/// The standard deviation of the dip prior: the WMM's own error is under a degree, and
/// local anomalies (buildings, vehicles) move the dip by a few.
pub const INCLINATION_PRIOR_STD_DEG: f64 = 3.0;

/// Each diagonal entry of `D` may differ from the prior's `s` by about this fraction of
/// `s`: uncalibrated chips differ in gain between axes by up to a factor of two (a
/// QMC5883L's three axes span 0.7-1.5 of their mean).
pub const SOFT_IRON_PRIOR_STD: f64 = 0.5;

/// The symmetric off-diagonal part of `D` (cross-axis soft iron), as a fraction of `s`:
/// ±0.1 is already strong soft iron; a fit that needs ±1 is explaining something else
/// (a changing field, a tilt error) with a distortion no material makes.
pub const CROSS_AXIS_PRIOR_STD: f64 = 0.15;

/// The mean trust in the tilt ([`TiltTrusted`]) below which it is mostly not trusted:
/// each sample's dip then weighs its own trust and a dip far from the model's refuses
/// nothing (the tilt is what is wrong). On the generator a swinging phone's is 0.01-0.11,
/// a walker's 0.8-0.9, a car's 0.9; over the real logs, the TYREX running and swinging
/// trials' 0.001-0.2, every other shared log's 0.35-1 (`calibrate --json`,
/// `tilt_trust_mean`).
pub const TRUSTED_TILT: f64 = 0.25;

/// The prior's standard deviation of the magnetometer-to-accelerometer rotation (rad):
/// a few degrees on a board or a phone, up to about six with cross-axis soft iron.
pub const ROTATION_PRIOR_STD_RAD: f64 = 0.1;

/// Hard iron is left to the data: this only keeps the normal equations regular.
pub const HARD_IRON_PRIOR_STD_UT: f64 = 10_000.0;

/// A parameter whose posterior standard deviation is above this share of its prior's
/// was not seen by the data.
const UNOBSERVED_SHARE: f64 = 0.5;

/// A hard-iron component known no better than this (µT, 1σ) was not seen by the data.
const UNOBSERVED_HARD_IRON_UT: f64 = 5.0;

/// Samples (µT, any axis) beyond this are refused as a unit error, not a field.
const MAX_ABS_UT: f64 = 1e6;

/// Below this spread (µT, RMS about the mean) the device did not turn.
const MIN_SPREAD_UT: f64 = 2.0;

/// The starts that fit best as they are are solved, this many of them; more only while
/// none of those led to a plausible solution. Starts that fit worse rarely end better
/// (each start's solve is most of the fit's time).
const MAX_SOLVED_STARTS: usize = 2;

/// The fit uses at most this many evenly spaced samples: neighbouring samples share
/// their tilt error and disturbance (see `autocorrelation_inflation`), so a log
/// thinned to 1,500 keeps most of its independent information, and the parameters'
/// noise from it is far below what tilt errors leave. The starts are solved on the
/// same samples, so the best of them is the fit (a second solve on another thinning
/// would only wander again along what the data hardly see).
pub const MAX_FIT_SAMPLES: usize = 1_500;

/// Huber's constant and Cauchy's (in robust standard deviations): 95 % efficiency on
/// Gaussian residuals for each.
const HUBER_K: f64 = 1.345;
const CAUCHY_C: f64 = 2.385;

/// Outer (reweighting) and inner (Levenberg-Marquardt) iterations, at most.
const N_REWEIGHTINGS: usize = 6;
const MAX_LM_ITERATIONS: usize = 25;
const MAX_LM_ITERATIONS_BEFORE_LAST: usize = 6;

/// The inner iterations stop when a step lowers the cost by less than this share of it;
/// the outer ones when a reweighting moved no parameter by more than
/// [`STEADY_PARAMETER_SHARE`] of its scale (the field for `h` and `V`, the largest entry
/// of `D` for `D`): 10⁻⁴ of a 50 µT field is 0.005 µT, a thousandth of a degree of
/// heading.
const STEADY_COST_SHARE: f64 = 1e-8;
const STEADY_PARAMETER_SHARE: f64 = 1e-4;

/// A parameter direction is fitted only where the data's information exceeds the
/// priors' by this factor (after the residuals' correlation is counted); see
/// [`observed_directions`].
const MIN_DATA_OVER_PRIOR: f64 = 4.0;

/// A plausible full soft iron ([`implausibility`]): each axis's gain against their
/// geometric mean, the symmetric cross-axis terms, the rotation, and how far the fitted
/// dip may be from the model's (four of the prior's standard deviations).
const MIN_AXIS_GAIN: f64 = 0.5;
/// The overall gain a sensor read in µT may need: its factory gain is within tens of per
/// cent, soft iron and a mount's steel change it by less than a factor of two.
const MAX_OVERALL_GAIN: f64 = 4.0;
const MAX_AXIS_GAIN: f64 = 2.0;
const MAX_CROSS_AXIS: f64 = 0.3;
const MAX_ROTATION_RAD: f64 = 0.25;
const MAX_DIP_OFF_PRIOR_DEG: f64 = 4.0 * INCLINATION_PRIOR_STD_DEG;

/// Below this RMS tilt about the mean "down" (degrees), the band model is fitted (see
/// `SampleSet::band_axis` and `FreeDirections::band`).
const MIN_TILT_FOR_ROTATION_DEG: f64 = 3.0;

/// With the accelerometer, the band model also needs the magnetometer's samples within
/// this many degrees of a plane (see `MAX_LEVEL_BAND_DEG` for the measure): a car's
/// band is 2-6°, a sphere about 50°.
const MAX_MAG_BAND_DEG: f64 = 20.0;

/// Without an accelerometer, the band model is fitted when the samples lie within this
/// many degrees of a plane (`atan(√3·σ₃ / √(σ₁² + σ₂²))` of their principal spreads: a
/// level ring with noise gives 1-2°, a walk's sway 5-10°, a sphere about 50°).
const MAX_LEVEL_BAND_DEG: f64 = 5.0;

/// A sample whose final weight is below this counts as an outlier in the report.
const OUTLIER_WEIGHT: f64 = 0.3;

/// The band start is tried when the samples' least-spread axis is within this angle of
/// the mean "down" (cosine): the device turned about the vertical.
const BAND_AXIS_MIN_COS: f64 = 0.5;

/// Parameter indices.
const H: usize = 0;
const D0: usize = 3;
const V: usize = 12;
const N_MAX: usize = 13;

type ParamVec = SVector<f64, N_MAX>;
type ParamMat = SMatrix<f64, N_MAX, N_MAX>;

/// The Earth's field the fit may lean on (from the WMM at the log's place and date).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FieldPrior {
    pub total_ut: f64,
    /// Below the horizontal, positive down.
    pub inclination_deg: f64,
}

/// What [`fit_inertial`] may use.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct InertialOptions {
    pub field: Option<FieldPrior>,
    /// The samples are in µT as the sensor's own factory gains give them (a phone, a
    /// board read in µT or gauss), not raw counts: the correction's overall gain is
    /// then near one ([`GAIN_PRIOR_STD`]), and without a model the field is taken as
    /// [`TYPICAL_FIELD_UT`]. Without either, a few minutes of a phone in a pocket
    /// (a short arc of the sphere) fit a sphere of any size.
    pub gain_known: bool,
}

/// The prior's standard deviation of the natural log of the correction's overall gain
/// `det(D)^⅓` when the gain is known: factory-calibrated sensors are within 10-20 %,
/// and without a field model the Earth's 22-67 µT add as much again.
pub const GAIN_PRIOR_STD: f64 = 0.4;

/// The field magnitude assumed without a model, in µT (the Earth's middle value).
pub const TYPICAL_FIELD_UT: f64 = 45.0;

/// A parameter the data could not see: its value is (mostly) the prior's.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Unobserved {
    /// Which parameter, in words ("hard iron z").
    pub parameter: String,
    /// Its posterior standard deviation, in its own unit (µT, or a fraction of the
    /// scale for soft-iron entries, or degrees of dip).
    pub std: f64,
    pub unit: &'static str,
}

/// Which correction matrix the fit kept.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SoftIronModel {
    /// A general 3×3 matrix (scale factors, cross-axis soft iron, a small rotation).
    Full,
    /// One scale for every axis: the hard iron only, when the data could not carry more.
    Isotropic,
}

impl SoftIronModel {
    /// Why `state` is no solution of this model, if it is not: the full model's shape
    /// checks ([`implausibility`]); for either, a degenerate correction ([`degeneracy`]).
    fn implausibility(
        self,
        state: &State,
        options: &InertialOptions,
        tilt_trusted: bool,
    ) -> Option<String> {
        match self {
            SoftIronModel::Full => implausibility(state, options, tilt_trusted),
            SoftIronModel::Isotropic => degeneracy(state, options),
        }
    }
}

/// A 3D calibration fitted with the tilt and priors, with how well the data supported it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct InertialFit {
    /// The correction matrix kept, and why not the full one when it is not.
    pub model: SoftIronModel,
    pub model_reason: Option<String>,
    /// `corrected = soft_iron · (raw − hard_iron)`, body axes, µT; `soft_iron` is a
    /// general matrix (it includes the magnetometer-to-accelerometer rotation).
    pub calibration: FieldCalibration,
    /// Whether the dip-angle invariance was used (the log has an accelerometer).
    pub uses_dip: bool,
    /// Whether the fitted samples' tilt was mostly not trusted ([`TRUSTED_TILT`]): each
    /// sample's dip then weighed its trust and the fitted dip refused no solution.
    pub tilt_untrusted: bool,
    /// Whether `field_ut` is the model's intensity (else the data's own scale).
    pub field_from_model: bool,
    /// The fitted dip (with the accelerometer), degrees below the horizontal, and its
    /// standard deviation.
    pub inclination_deg: Option<f64>,
    pub inclination_std_deg: Option<f64>,
    /// RMS of `|corrected| − field_ut` over the samples that were not outliers.
    pub residual_rms_ut: f64,
    /// Standard deviation of `|corrected|` over its mean, in percent, over the samples
    /// that were not outliers (MotionCal's "variance"); and over every sample.
    pub field_spread_pct: f64,
    pub field_spread_all_pct: f64,
    /// RMS of the vertical residual `ĝ·c − V` (with the accelerometer), same samples.
    pub vertical_rms_ut: Option<f64>,
    pub n_samples: usize,
    /// Samples the final fit saw (evenly spaced when there were more).
    pub n_fitted: usize,
    /// The share of those that the robust weights set aside (moving iron, accelerations).
    pub outlier_pct: f64,
    /// Posterior standard deviations of the hard iron (body axes, µT) and of each entry
    /// of `soft_iron` (as a fraction of its scale).
    pub hard_iron_std_ut: Vector3<f64>,
    pub soft_iron_std: Matrix3<f64>,
    /// The heading's standard deviation from the calibration's uncertainty, RMS over the
    /// fitted samples' own attitudes (degrees).
    pub heading_std_deg: f64,
    /// Parameters the data did not see, kept near their priors.
    pub unobserved: Vec<Unobserved>,
}

/// Why no calibration could be fitted. Messages say what the user can do.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum InertialError {
    #[error(
        "too few magnetometer samples ({n_samples}; at least {min} are needed). Record \
         longer while turning the device."
    )]
    TooFewSamples { n_samples: usize, min: usize },

    #[error(
        "magnetometer sample {sample_idx} is not a usable number (not finite, or beyond \
         ±1 T). Check the input's units (µT are expected)."
    )]
    BadSample { sample_idx: usize },

    #[error(
        "the field hardly changes (spread {spread_ut:.2} µT): the device was not turned. \
         Record while turning it through a full circle (and, for 3D, tilting it)."
    )]
    NoRotation { spread_ut: f64 },

    #[error(
        "the expected field ({total_ut} µT, inclination {inclination_deg}°) is not usable; \
         give 25-65 µT and an inclination within ±90°, or none."
    )]
    BadPrior { total_ut: f64, inclination_deg: f64 },

    #[error(
        "no calibration converged: the samples follow no single field turned around. Record \
         again away from iron that moves with respect to the sensor, turning through a full \
         circle."
    )]
    NoConvergence,
}

/// The unit "down" direction in body axes at a tilt: `(−sinθ, sinφ·cosθ, cosφ·cosθ)`,
/// the direction opposite to the specific force at rest (see [`crate::attitude::tilt`]).
pub fn down_in_body(tilt: &Tilt) -> Vector3<f64> {
    let (sin_roll, cos_roll) = tilt.roll_sin_cos();
    let (sin_pitch, cos_pitch) = tilt.pitch_sin_cos();
    Vector3::new(-sin_pitch, sin_roll * cos_pitch, cos_roll * cos_pitch)
}

/// The tilt at each sample and how far each is trusted (0 to 1, `None`: all fully):
/// a sample's dip residual weighs its trust times what the robust loss gives it, so
/// that a tilt the accelerometer got wrong (a swinging arm's acceleration) bends the fit
/// less and the field's shape decides there (issue 43).
#[derive(Debug, Clone, Copy)]
pub struct TiltTrusted<'a> {
    pub tilt: &'a [Tilt],
    pub trust: Option<&'a [f64]>,
}

/// Fits the calibration to magnetometer samples (µT, body axes) and, when the log has
/// an accelerometer, the tilt at each of them (`tilt[i]` belongs to `mag_ut[i]`), all
/// trusted alike.
pub fn fit_inertial(
    mag_ut: &[Vector3<f64>],
    tilt: Option<&[Tilt]>,
    options: &InertialOptions,
) -> Result<InertialFit, InertialError> {
    fit_inertial_trusting(
        mag_ut,
        tilt.map(|tilt| TiltTrusted { tilt, trust: None }),
        options,
    )
}

/// [`fit_inertial`] with each sample's tilt trusted as [`TiltTrusted`] says.
pub fn fit_inertial_trusting(
    mag_ut: &[Vector3<f64>],
    tilt: Option<TiltTrusted>,
    options: &InertialOptions,
) -> Result<InertialFit, InertialError> {
    if mag_ut.len() < MIN_SAMPLES {
        return Err(InertialError::TooFewSamples {
            n_samples: mag_ut.len(),
            min: MIN_SAMPLES,
        });
    }
    if let Some(sample_idx) = mag_ut
        .iter()
        .position(|m| !m.iter().all(|v| v.is_finite() && v.abs() < MAX_ABS_UT))
    {
        return Err(InertialError::BadSample { sample_idx });
    }
    if let Some(prior) = options.field {
        let usable = prior.total_ut.is_finite()
            && prior.total_ut > 0.0
            && prior.inclination_deg.is_finite()
            && prior.inclination_deg.abs() <= 90.0;
        if !usable {
            return Err(InertialError::BadPrior {
                total_ut: prior.total_ut,
                inclination_deg: prior.inclination_deg,
            });
        }
    }
    let tilt = tilt.filter(|tilt| tilt.tilt.len() == mag_ut.len());
    let down: Option<Vec<Vector3<f64>>> =
        tilt.map(|tilt| tilt.tilt.iter().map(down_in_body).collect());
    let samples = Samples {
        mag_ut,
        down_in_body: down.as_deref(),
        dip_trust: tilt
            .and_then(|tilt| tilt.trust)
            .filter(|trust| trust.len() == mag_ut.len()),
    };
    let spread_ut = spread_ut(mag_ut);
    if spread_ut.is_nan() || spread_ut < MIN_SPREAD_UT {
        return Err(InertialError::NoRotation { spread_ut });
    }

    let fit_set = samples.evenly(MAX_FIT_SAMPLES);
    let starts = ranked(&fit_set, starts(&fit_set, options));
    // The full model from the starts that fit best as they are; the plausible solution
    // that fits best wins.
    let mut first_reason = None;
    let solution = match best_solution(
        &fit_set,
        &starts,
        options,
        SoftIronModel::Full,
        &mut first_reason,
    ) {
        Some(solution) => solution,
        None => {
            // No plausible full model: the data cannot carry nine soft-iron entries (a
            // field that changes, tilt the accelerometer got wrong). Hard iron, one scale
            // and the dip, which only a changing field can spoil.
            best_solution(
                &fit_set,
                &starts,
                options,
                SoftIronModel::Isotropic,
                &mut first_reason,
            )
            .ok_or(InertialError::NoConvergence)?
        }
    };
    let reason = (solution.model == SoftIronModel::Isotropic)
        .then_some(first_reason)
        .flatten();
    let mut fit = solution.report(&fit_set, mag_ut, options);
    fit.model_reason = reason;
    Ok(fit)
}

/// The best-scoring plausible solution of `model` from the ranked `starts`: the first
/// [`MAX_SOLVED_STARTS`] of them, more only while none was plausible. The first reason a
/// solution was not plausible goes into `first_reason`.
///
/// The starts are solved side by side on the machine's threads ([`crate::base::par`]), a few
/// at a time, and judged in their order: the answer is the same on any number of
/// threads (a start solved ahead of need is set aside unread).
fn best_solution(
    set: &SampleSet,
    starts: &[State],
    options: &InertialOptions,
    model: SoftIronModel,
    first_reason: &mut Option<String>,
) -> Option<Solution> {
    let n_threads = crate::base::par::n_threads().max(1);
    let mut best: Option<(f64, Solution)> = None;
    let mut n_solved = 0;
    while n_solved < starts.len() && !(n_solved >= MAX_SOLVED_STARTS && best.is_some()) {
        // The starts certainly needed (the first MAX_SOLVED_STARTS, then one at a time),
        // or as many as there are threads.
        let needed = MAX_SOLVED_STARTS.saturating_sub(n_solved).max(1);
        let width = needed.max(n_threads).min(starts.len() - n_solved);
        let batch = &starts[n_solved..n_solved + width];
        let solve_one = |start: &State| solve(set, *start, options, model);
        let solutions = crate::base::par::on_each_part(batch.iter(), solve_one)
            .unwrap_or_else(|| batch.iter().map(solve_one).collect());
        for solution in solutions {
            if n_solved >= MAX_SOLVED_STARTS && best.is_some() {
                break;
            }
            n_solved += 1;
            let Some(solution) = solution else {
                continue;
            };
            let tilt_trusted = !set.tilt_untrusted();
            if let Some(reason) = model.implausibility(&solution.state, options, tilt_trusted) {
                first_reason.get_or_insert(reason);
                continue;
            }
            let score = solution.score(set);
            if best
                .as_ref()
                .is_none_or(|(best_score, _)| score < *best_score)
            {
                best = Some((score, solution));
            }
        }
    }
    best.map(|(_, solution)| solution)
}

fn spread_ut(mag_ut: &[Vector3<f64>]) -> f64 {
    let n = mag_ut.len() as f64;
    let mean: Vector3<f64> = mag_ut.iter().sum::<Vector3<f64>>() / n;
    (mag_ut
        .iter()
        .map(|m| (m - mean).norm_squared())
        .sum::<f64>()
        / n)
        .sqrt()
}

/// The parameters: hard iron, the correction matrix, the vertical field, and the
/// fixed magnitude `F` with the prior's centres.
#[derive(Debug, Clone, Copy)]
struct State {
    hard_iron_ut: Vector3<f64>,
    correction: Matrix3<f64>,
    vertical_ut: f64,
    field_ut: f64,
}

impl State {
    fn params(&self) -> ParamVec {
        let mut params = ParamVec::zeros();
        for axis in 0..3 {
            params[H + axis] = self.hard_iron_ut[axis];
        }
        for row in 0..3 {
            for col in 0..3 {
                params[D0 + 3 * row + col] = self.correction[(row, col)];
            }
        }
        params[V] = self.vertical_ut;
        params
    }

    fn with_params(&self, params: &ParamVec) -> State {
        State {
            hard_iron_ut: Vector3::new(params[H], params[H + 1], params[H + 2]),
            correction: Matrix3::from_fn(|row, col| params[D0 + 3 * row + col]),
            vertical_ut: params[V],
            ..*self
        }
    }

    /// Whether no parameter moved by more than [`STEADY_PARAMETER_SHARE`] of its scale
    /// between `self` and `other`.
    fn is_steady_from(&self, other: &State) -> bool {
        let field_scale = self.field_ut.abs().max(NORMALISER_FLOOR);
        let correction_scale = self.correction.amax().max(NORMALISER_FLOOR);
        (self.hard_iron_ut - other.hard_iron_ut).amax() <= STEADY_PARAMETER_SHARE * field_scale
            && (self.vertical_ut - other.vertical_ut).abs() <= STEADY_PARAMETER_SHARE * field_scale
            && (self.correction - other.correction).amax()
                <= STEADY_PARAMETER_SHARE * correction_scale
    }

    /// Rescales so that the corrected field's magnitude is `field_ut`.
    fn scaled_to(mut self, field_ut: f64) -> State {
        let factor = field_ut / self.field_ut;
        self.correction *= factor;
        self.vertical_ut *= factor;
        self.field_ut = field_ut;
        self
    }
}

/// Residual scales and per-sample weights of one reweighting.
struct Weights {
    sigma_magnitude_ut: f64,
    sigma_vertical_ut: f64,
    /// The tilt's noise over the magnetometer's, see [`vertical_normaliser`].
    kappa: f64,
    magnitude: Vec<f64>,
    vertical: Vec<f64>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Loss {
    Huber,
    Cauchy,
}

/// How a solve reweights.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Schedule {
    /// From a start, to see which directions the data see: Huber weights twice (a
    /// start's misfit is not yet noise, and Cauchy's would set good samples aside), a
    /// few steps under each.
    Probe,
    /// From the probe, along the directions the data see: Cauchy's weights until the
    /// parameters hold still.
    Converge,
}

impl Schedule {
    fn loss(self) -> Loss {
        match self {
            Schedule::Probe => Loss::Huber,
            Schedule::Converge => Loss::Cauchy,
        }
    }

    fn max_reweightings(self) -> usize {
        match self {
            Schedule::Probe => 2,
            Schedule::Converge => N_REWEIGHTINGS,
        }
    }

    /// Reweightings before the outer loop may stop.
    fn min_reweightings(self) -> usize {
        match self {
            Schedule::Probe => 2,
            Schedule::Converge => 1,
        }
    }

    /// Levenberg-Marquardt iterations under the reweighting `reweighting`: weights that
    /// will change again need no exact minimum under them.
    fn max_iterations(self, reweighting: usize) -> usize {
        match self {
            Schedule::Converge if reweighting + 1 == self.max_reweightings() => MAX_LM_ITERATIONS,
            _ => MAX_LM_ITERATIONS_BEFORE_LAST,
        }
    }
}

impl Loss {
    fn weight(self, normalised: f64) -> f64 {
        let a = normalised.abs();
        match self {
            Loss::Huber => {
                if a <= HUBER_K {
                    1.0
                } else {
                    HUBER_K / a
                }
            }
            Loss::Cauchy => 1.0 / (1.0 + (a / CAUCHY_C).powi(2)),
        }
    }
}

/// A converged fit with its last weights.
struct Solution {
    state: State,
    model: SoftIronModel,
    weights: Weights,
    /// Where the priors were centred (the start it was solved from).
    prior_centre: State,
}

impl Solution {
    /// The posterior covariance on `set` with the final weights (the frozen directions
    /// keep their priors' uncertainty): only the solution that is reported needs it.
    fn covariance(&self, set: &SampleSet, options: &InertialOptions) -> Option<ParamMat> {
        let normal = normal_equations(set, &self.state, &self.weights, options, &self.prior_centre);
        posterior_covariance(
            &normal,
            autocorrelation_inflation(set, &self.state, &self.weights),
        )
    }

    /// Median absolute residuals, magnitude plus vertical (µT): comparable across starts.
    fn score(&self, set: &SampleSet) -> f64 {
        let (sigma_magnitude_ut, sigma_vertical_ut) =
            robust_scales(set, &self.state, self.weights.kappa);
        sigma_magnitude_ut
            + if set.uses_dip() {
                sigma_vertical_ut
            } else {
                0.0
            }
    }
}
#[cfg(test)]
mod tests;
