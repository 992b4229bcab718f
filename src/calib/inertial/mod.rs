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
//! (averaged over about a second, see [`super::tilt`]). The second residual is the
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
//! 1. Starts: the algebraic ellipsoid of [`super::ellipsoid`] (Li and Griffiths; needs
//!    a 3D spread), a band start for yaw-only data (the samples' principal plane, a
//!    direct ellipse fit in it, the vertical hard iron from the prior's dip), and
//!    Kåsa's sphere. They are ranked by their median residuals as they stand; the
//!    first [`MAX_SOLVED_STARTS`] (more while none is plausible) are refined on an
//!    evenly spaced subset of at most [`MAX_START_SAMPLES`], and the plausible one with
//!    the smallest median residuals continues, warm, on at most [`MAX_FIT_SAMPLES`].
//! 2. Levenberg-Marquardt on the normal equations (13 parameters at most: the `N×13`
//!    Jacobian is never formed, so 10⁴ samples take milliseconds), inside iteratively
//!    reweighted least squares: Huber weights, then Cauchy weights, on residuals scaled
//!    by their median absolute deviation. Samples near moving iron become outliers with
//!    small weights, not a reason to give nothing.
//! 3. The posterior covariance `(JᵀWJ + P)⁻¹`, inflated by the residuals' lag-one
//!    autocorrelation (neighbouring samples share their tilt error), gives each
//!    parameter's standard deviation and the heading's: its gradient through levelling,
//!    averaged over the samples.
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

use nalgebra::{Matrix3, SMatrix, SVector, Vector2, Vector3};
use serde::Serialize;
use thiserror::Error;

use super::model::FieldCalibration;
use super::tilt::Tilt;

mod starts;
use starts::{principal_plane, ranked, starts};

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

/// The starts are refined on at most this many evenly spaced samples.
pub const MAX_START_SAMPLES: usize = 1_500;

/// The starts that fit best as they are are solved, this many of them; more only while
/// none of those led to a plausible solution. Starts that fit worse rarely end better
/// (each start's solve is most of the fit's time).
const MAX_SOLVED_STARTS: usize = 2;

/// The final fit uses at most this many evenly spaced samples: neighbouring samples
/// share their tilt error and disturbance (see [`autocorrelation_inflation`]), so a log
/// thinned to 2,000 keeps most of its independent information, and the parameters'
/// noise from it is far below what tilt errors leave.
pub const MAX_FIT_SAMPLES: usize = 2_000;

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
    fn implausibility(self, state: &State, options: &InertialOptions) -> Option<String> {
        match self {
            SoftIronModel::Full => implausibility(state, options),
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
/// the direction opposite to the specific force at rest (see [`super::tilt`]).
pub fn down_in_body(tilt: &Tilt) -> Vector3<f64> {
    let (sin_roll, cos_roll) = tilt.roll_rad.sin_cos();
    let (sin_pitch, cos_pitch) = tilt.pitch_rad.sin_cos();
    Vector3::new(-sin_pitch, sin_roll * cos_pitch, cos_roll * cos_pitch)
}

/// Fits the calibration to magnetometer samples (µT, body axes) and, when the log has
/// an accelerometer, the tilt at each of them (`tilt[i]` belongs to `mag_ut[i]`).
pub fn fit_inertial(
    mag_ut: &[Vector3<f64>],
    tilt: Option<&[Tilt]>,
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
    let down: Option<Vec<Vector3<f64>>> = tilt
        .filter(|tilt| tilt.len() == mag_ut.len())
        .map(|tilt| tilt.iter().map(down_in_body).collect());
    let samples = Samples {
        mag_ut,
        down_in_body: down.as_deref(),
    };
    let spread_ut = spread_ut(mag_ut);
    if spread_ut.is_nan() || spread_ut < MIN_SPREAD_UT {
        return Err(InertialError::NoRotation { spread_ut });
    }

    let start_set = samples.evenly(MAX_START_SAMPLES);
    let fit_set = samples.evenly(MAX_FIT_SAMPLES);
    let starts = ranked(&start_set, starts(&start_set, options));
    // The full model from the starts that fit best as they are; the plausible solution
    // that fits best wins.
    let mut first_reason = None;
    let (model, start) = match best_solution(
        &start_set,
        &starts,
        options,
        SoftIronModel::Full,
        &mut first_reason,
    ) {
        Some(solution) => (SoftIronModel::Full, solution.state),
        None => {
            // No plausible full model: the data cannot carry nine soft-iron entries (a
            // field that changes, tilt the accelerometer got wrong). Hard iron, one scale
            // and the dip, which only a changing field can spoil.
            let solution = best_solution(
                &start_set,
                &starts,
                options,
                SoftIronModel::Isotropic,
                &mut first_reason,
            )
            .ok_or(InertialError::NoConvergence)?;
            (SoftIronModel::Isotropic, solution.state)
        }
    };
    let mut solution = solve(&fit_set, start, options, model, Schedule::Warm)
        .ok_or(InertialError::NoConvergence)?;
    let reason = (model == SoftIronModel::Isotropic)
        .then_some(first_reason)
        .flatten();
    // More samples can carry a full model further than the subset did, into a shape no
    // material gives (weakly seen directions following a disturbance): then the
    // subset's plausible solution stands, with the full set's weights and covariance.
    if model.implausibility(&solution.state, options).is_some() {
        solution = settle(&fit_set, start, options, model).ok_or(InertialError::NoConvergence)?;
    }
    let mut fit = solution.report(&fit_set, mag_ut, options);
    fit.model_reason = reason;
    Ok(fit)
}

/// The best-scoring plausible solution of `model` from the ranked `starts`: the first
/// [`MAX_SOLVED_STARTS`] of them, more only while none was plausible. The first reason a
/// solution was not plausible goes into `first_reason`.
///
/// The starts are solved side by side on the machine's threads ([`crate::par`]), a few
/// at a time, and judged in their order: the answer is the same on any number of
/// threads (a start solved ahead of need is set aside unread).
fn best_solution(
    set: &SampleSet,
    starts: &[State],
    options: &InertialOptions,
    model: SoftIronModel,
    first_reason: &mut Option<String>,
) -> Option<Solution> {
    let n_threads = crate::par::n_threads().max(1);
    let mut best: Option<(f64, Solution)> = None;
    let mut n_solved = 0;
    while n_solved < starts.len() && !(n_solved >= MAX_SOLVED_STARTS && best.is_some()) {
        // The starts certainly needed (the first MAX_SOLVED_STARTS, then one at a time),
        // or as many as there are threads.
        let needed = MAX_SOLVED_STARTS.saturating_sub(n_solved).max(1);
        let width = needed.max(n_threads).min(starts.len() - n_solved);
        let batch = &starts[n_solved..n_solved + width];
        let solve_one = |start: &State| solve(set, *start, options, model, Schedule::Cold);
        let solutions = crate::par::on_each_part(batch.iter(), solve_one)
            .unwrap_or_else(|| batch.iter().map(solve_one).collect());
        for solution in solutions {
            if n_solved >= MAX_SOLVED_STARTS && best.is_some() {
                break;
            }
            n_solved += 1;
            let Some(solution) = solution else {
                continue;
            };
            if let Some(reason) = model.implausibility(&solution.state, options) {
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

/// `state` as it is, with the weights and covariance of `set` (no step taken).
fn settle(
    set: &SampleSet,
    state: State,
    options: &InertialOptions,
    model: SoftIronModel,
) -> Option<Solution> {
    let weights = weights(set, &state, Schedule::Warm.loss(0));
    let normal = normal_equations(set, &state, &weights, options, &state);
    let covariance =
        posterior_covariance(&normal, autocorrelation_inflation(set, &state, &weights));
    Some(Solution {
        state,
        model,
        weights,
        covariance,
    })
}

/// Why a solution of either model is no calibration at all, if it is not: a correction
/// that mirrors the field, or, for a sensor read in µT (whose factory gain is known), an
/// overall gain beyond [`MAX_OVERALL_GAIN`] either way: the fit shrank a sphere onto a
/// patch of the samples (a hard iron among them and a gain of hundreds), which a band of
/// data with a changing field allows.
fn degeneracy(state: &State, options: &InertialOptions) -> Option<String> {
    let det = state.correction.determinant();
    if det.is_nan() || det <= 0.0 {
        return Some("the fitted correction mirrors the field".to_string());
    }
    let gain = det.cbrt();
    if options.gain_known && !(1.0 / MAX_OVERALL_GAIN..=MAX_OVERALL_GAIN).contains(&gain) {
        return Some(format!(
            "the fit would scale the sensor's µT by {gain:.2}, a sphere shrunk onto part of the samples"
        ));
    }
    None
}

/// Why a full-model solution is not a magnetometer's distortion, if it is not: a shape
/// no material gives (axis gains beyond 0.5-2× their mean, cross-axis terms beyond
/// ±[`MAX_CROSS_AXIS`], a rotation beyond [`MAX_ROTATION_RAD`]), or a dip far from the
/// model's. Such solutions come from fitting a changing field or a wrong tilt with the
/// soft iron, typically on a band of data (a car's drive).
fn implausibility(state: &State, options: &InertialOptions) -> Option<String> {
    if let Some(reason) = degeneracy(state, options) {
        return Some(reason);
    }
    let det = state.correction.determinant();
    let shape = state.correction / det.cbrt();
    for axis in 0..3 {
        let gain = shape[(axis, axis)];
        if !(MIN_AXIS_GAIN..=MAX_AXIS_GAIN).contains(&gain) {
            return Some(format!(
                "a full soft iron would scale one axis by {gain:.2} of the mean"
            ));
        }
    }
    for (a, b) in [(0, 1), (0, 2), (1, 2)] {
        let symmetric = 0.5 * (shape[(a, b)] + shape[(b, a)]);
        let antisymmetric = 0.5 * (shape[(a, b)] - shape[(b, a)]);
        if symmetric.abs() > MAX_CROSS_AXIS {
            return Some(format!(
                "a full soft iron would couple two axes by {symmetric:.2}"
            ));
        }
        if antisymmetric.abs() > MAX_ROTATION_RAD {
            return Some(format!(
                "a full soft iron would turn the axes by {:.0}°",
                antisymmetric.abs().to_degrees()
            ));
        }
    }
    if let Some(prior) = options.field {
        let dip_deg = (state.vertical_ut / state.field_ut)
            .clamp(-1.0, 1.0)
            .asin()
            .to_degrees();
        if (dip_deg - prior.inclination_deg).abs() > MAX_DIP_OFF_PRIOR_DEG
            && state.vertical_ut != 0.0
        {
            return Some(format!(
                "a full soft iron would put the dip at {dip_deg:.0}° where the model has {:.0}°",
                prior.inclination_deg
            ));
        }
    }
    None
}

/// Samples, with the down vectors when the dip is used.
#[derive(Clone, Copy)]
struct Samples<'a> {
    mag_ut: &'a [Vector3<f64>],
    down_in_body: Option<&'a [Vector3<f64>]>,
}

/// An owned, evenly thinned copy.
struct SampleSet {
    mag_ut: Vec<Vector3<f64>>,
    down_in_body: Option<Vec<Vector3<f64>>>,
}

impl Samples<'_> {
    fn evenly(&self, max_samples: usize) -> SampleSet {
        let stride = self.mag_ut.len().div_ceil(max_samples).max(1);
        SampleSet {
            mag_ut: self.mag_ut.iter().step_by(stride).copied().collect(),
            down_in_body: self
                .down_in_body
                .map(|down| down.iter().step_by(stride).copied().collect()),
        }
    }
}

impl SampleSet {
    fn uses_dip(&self) -> bool {
        self.down_in_body.is_some()
    }

    fn down(&self, idx: usize) -> Option<Vector3<f64>> {
        self.down_in_body
            .as_ref()
            .and_then(|down| down.get(idx).copied())
    }

    /// The axis of a band of data, when the samples form one: with the accelerometer,
    /// the mean down when the tilt stays within [`MIN_TILT_FOR_ROTATION_DEG`] (RMS) of
    /// it (a car in its mount, a level turn); without, the samples' own axis when they
    /// lie within [`MAX_LEVEL_BAND_DEG`] of a plane (a level turn assumed level). On a
    /// band, what only tilt shows of a 3D distortion (the band's lean and height, a
    /// rotation about its axis) is decided by the accelerometer's own errors (what is
    /// left of a car's accelerations, vibration, passing vehicles) more than by the
    /// magnetometer: the band model is fitted instead ([`FreeDirections::band`]). A
    /// hand's tilt while walking (3-10°) does show them.
    fn band_axis(&self) -> Option<Vector3<f64>> {
        match &self.down_in_body {
            Some(down) => {
                let mean_down = self.mean_down()?;
                let mean_square = down
                    .iter()
                    .map(|u| u.cross(&mean_down).norm_squared())
                    .sum::<f64>()
                    / down.len().max(1) as f64;
                // The magnetometer must agree: a field that sweeps the sphere while the
                // accelerometer stays put is no band (the two are not on one body).
                let plane = principal_plane(&self.mag_ut)?;
                let mag_span_deg = (3f64.sqrt() * plane.spread_ut[2])
                    .atan2(plane.spread_ut[0].hypot(plane.spread_ut[1]))
                    .to_degrees();
                (mean_square.sqrt().asin().to_degrees() < MIN_TILT_FOR_ROTATION_DEG
                    && mag_span_deg < MAX_MAG_BAND_DEG)
                    .then_some(mean_down)
            }
            None => {
                let plane = principal_plane(&self.mag_ut)?;
                let span_deg = (3f64.sqrt() * plane.spread_ut[2])
                    .atan2(plane.spread_ut[0].hypot(plane.spread_ut[1]))
                    .to_degrees();
                // The field points down north of the magnetic equator: +z of a level
                // device.
                let normal = if plane.normal.z < 0.0 {
                    -plane.normal
                } else {
                    plane.normal
                };
                (span_deg < MAX_LEVEL_BAND_DEG).then_some(normal)
            }
        }
    }

    /// The mean down direction (unit), if the dip is used.
    fn mean_down(&self) -> Option<Vector3<f64>> {
        let sum: Vector3<f64> = self.down_in_body.as_ref()?.iter().sum();
        (sum.norm() > 0.0).then(|| sum.normalize())
    }
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
    /// From a start: Huber weights twice (a start's misfit is not yet noise, and
    /// Cauchy's would set good samples aside), then Cauchy's.
    Cold,
    /// From a solution of the same model (on a subset, or with more directions free):
    /// Cauchy's weights from the first reweighting.
    Warm,
}

impl Schedule {
    fn loss(self, reweighting: usize) -> Loss {
        match self {
            Schedule::Cold if reweighting < 2 => Loss::Huber,
            _ => Loss::Cauchy,
        }
    }

    /// Reweightings before the outer loop may stop: at least one with Cauchy's weights.
    fn max_reweightings(self) -> usize {
        N_REWEIGHTINGS
    }

    fn min_reweightings(self) -> usize {
        match self {
            Schedule::Cold => 3,
            Schedule::Warm => 1,
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

/// The two residuals of one sample.
fn residuals(state: &State, m_ut: Vector3<f64>, down: Option<Vector3<f64>>) -> (f64, Option<f64>) {
    let corrected = state.correction * (m_ut - state.hard_iron_ut);
    (
        corrected.norm() - state.field_ut,
        down.map(|down| down.dot(&corrected) - state.vertical_ut),
    )
}

/// The median of absolute values (destroys the order of `values`).
fn median_abs(values: &mut [f64]) -> f64 {
    for value in values.iter_mut() {
        *value = value.abs();
    }
    if values.is_empty() {
        return 0.0;
    }
    let middle = values.len() / 2;
    let (_, median, _) = values.select_nth_unstable_by(middle, f64::total_cmp);
    *median
}

/// The length of each residual's gradient with respect to the measurement, `|Dᵀa|`
/// (`a` the unit corrected field for the magnitude, "down" for the vertical): a residual
/// divided by it is a distance in the raw field (µT as measured, the first-order
/// geometric or Sampson distance), whose noise is the sensor's whatever `D` is. In the
/// corrected space the noise of a residual grows and shrinks with `D`, and a fit there
/// shrinks `D` along an axis the data hardly constrain just to shrink the noise: a bias
/// of several µT in the vertical hard iron of a yaw-only turn.
fn normalisers(
    state: &State,
    m_ut: Vector3<f64>,
    down: Option<Vector3<f64>>,
    kappa: f64,
) -> (f64, f64) {
    let d_ut = m_ut - state.hard_iron_ut;
    let magnitude = magnitude_norm(&state.correction, d_ut).unwrap_or(1.0);
    let vertical = down
        .and_then(|down| vertical_norm(&state.correction, d_ut, down, kappa))
        .unwrap_or(1.0);
    (magnitude, vertical)
}

const NORMALISER_FLOOR: f64 = 1e-9;

/// [`magnitude_normaliser`]'s value alone (the same arithmetic, without the gradient).
fn magnitude_norm(correction: &Matrix3<f64>, d_ut: Vector3<f64>) -> Option<f64> {
    let corrected = correction * d_ut;
    let c_norm = corrected.norm();
    let q_norm = (correction.transpose() * corrected).norm();
    if !(c_norm > 0.0 && q_norm > 0.0) {
        return None;
    }
    Some((q_norm * (1.0 / c_norm)).max(NORMALISER_FLOOR))
}

/// [`vertical_normaliser`]'s value alone (the same arithmetic, without the gradient).
fn vertical_norm(
    correction: &Matrix3<f64>,
    d_ut: Vector3<f64>,
    down: Vector3<f64>,
    kappa: f64,
) -> Option<f64> {
    let w = correction.transpose() * down;
    let corrected = correction * d_ut;
    let perpendicular = corrected - down * down.dot(&corrected);
    let n = (w.norm_squared() + kappa * kappa * perpendicular.norm_squared()).sqrt();
    if n.is_nan() || n <= 0.0 {
        return None;
    }
    Some(n.max(NORMALISER_FLOOR))
}

/// The magnitude residual's normaliser `n = |Dᵀĉ| = |q|/|c|` (with `c = D·d`,
/// `d = m − h`, `q = Dᵀc`) and its gradient:
/// `∂n/∂D_jk = (q̂_k·c_j + (D·q̂)_j·d_k − n·ĉ_j·d_k) / |c|`,
/// `∂n/∂h = (n·Dᵀĉ − DᵀD·q̂) / |c|`.
fn magnitude_normaliser(correction: &Matrix3<f64>, d_ut: Vector3<f64>) -> Option<(f64, ParamVec)> {
    let corrected = correction * d_ut;
    let c_norm = corrected.norm();
    let q = correction.transpose() * corrected;
    let q_norm = q.norm();
    if !(c_norm > 0.0 && q_norm > 0.0) {
        return None;
    }
    // Reciprocals once: divisions cost ten times a multiplication in this loop.
    let (inv_c_norm, inv_q_norm) = (1.0 / c_norm, 1.0 / q_norm);
    let (c_unit, q_unit) = (corrected * inv_c_norm, q * inv_q_norm);
    let n = q_norm * inv_c_norm;
    let d_q_unit = correction * q_unit;
    let mut gradient = ParamVec::zeros();
    let hard = correction.transpose() * (c_unit * n - d_q_unit) * inv_c_norm;
    for axis in 0..3 {
        gradient[H + axis] = hard[axis];
    }
    for row in 0..3 {
        let (a, b) = (
            corrected[row] * inv_c_norm,
            (d_q_unit[row] - n * c_unit[row]) * inv_c_norm,
        );
        for col in 0..3 {
            gradient[D0 + 3 * row + col] = q_unit[col] * a + b * d_ut[col];
        }
    }
    Some((n.max(NORMALISER_FLOOR), gradient))
}

/// The vertical residual's normaliser. The magnetometer's noise reaches `u·c` through
/// `|Dᵀu|`; the tilt's error `δ` (radians, perpendicular to `u`) through the horizontal
/// part of the field, `δ·c⊥` with `c⊥ = c − (u·c)·u`. Both in the magnetometer noise's
/// units: `n² = |Dᵀu|² + κ²·|c⊥|²`, `κ = σ_tilt / σ_mag`. Without the second term a fit
/// would tilt the corrected field towards "down" to shrink the tilt's noise. Gradient:
/// `n·∂n = wᵀ∂w + κ²·c⊥ᵀ∂c` (`w = Dᵀu`), i.e. `∂n/∂D_jk = (w_k·u_j + κ²·c⊥_j·d_k) / n`,
/// `∂n/∂h = −κ²·Dᵀc⊥ / n`.
fn vertical_normaliser(
    correction: &Matrix3<f64>,
    d_ut: Vector3<f64>,
    down: Vector3<f64>,
    kappa: f64,
) -> Option<(f64, ParamVec)> {
    let w = correction.transpose() * down;
    let corrected = correction * d_ut;
    let perpendicular = corrected - down * down.dot(&corrected);
    let kappa_sq = kappa * kappa;
    let n = (w.norm_squared() + kappa_sq * perpendicular.norm_squared()).sqrt();
    if n.is_nan() || n <= 0.0 {
        return None;
    }
    let inv_n = 1.0 / n;
    let mut gradient = ParamVec::zeros();
    let hard = -(correction.transpose() * perpendicular) * (kappa_sq * inv_n);
    for axis in 0..3 {
        gradient[H + axis] = hard[axis];
    }
    for row in 0..3 {
        let (a, b) = (down[row] * inv_n, kappa_sq * perpendicular[row] * inv_n);
        for col in 0..3 {
            gradient[D0 + 3 * row + col] = w[col] * a + b * d_ut[col];
        }
    }
    Some((n.max(NORMALISER_FLOOR), gradient))
}

/// The two residuals of one sample divided by their normalisers at the same state.
fn raw_residuals(
    state: &State,
    m_ut: Vector3<f64>,
    down: Option<Vector3<f64>>,
    kappa: f64,
) -> (f64, Option<f64>) {
    let (r_b, r_v) = residuals(state, m_ut, down);
    let (n_b, n_v) = normalisers(state, m_ut, down, kappa);
    (r_b / n_b, r_v.map(|r_v| r_v / n_v))
}

/// Robust residual scales (1.4826 × MAD, raw µT), floored at a small share of the field.
fn robust_scales(set: &SampleSet, state: &State, kappa: f64) -> (f64, f64) {
    let (mut magnitude, mut vertical): (Vec<f64>, Vec<f64>) = (Vec::new(), Vec::new());
    for (idx, &m_ut) in set.mag_ut.iter().enumerate() {
        let (r_b, r_v) = raw_residuals(state, m_ut, set.down(idx), kappa);
        magnitude.push(r_b);
        if let Some(r_v) = r_v {
            vertical.push(r_v);
        }
    }
    let floor_ut = 1e-4 * state.field_ut;
    (
        (1.4826 * median_abs(&mut magnitude)).max(floor_ut),
        (1.4826 * median_abs(&mut vertical)).max(floor_ut),
    )
}

/// `κ = σ_tilt / σ_mag` of [`vertical_normaliser`], from the robust spreads of the
/// corrected-space residuals: the magnitude's is the magnetometer's noise (times its
/// normaliser), and what the vertical one has beyond that noise is the tilt's error
/// times the horizontal field.
fn tilt_noise_ratio(set: &SampleSet, state: &State) -> f64 {
    if !set.uses_dip() {
        return 0.0;
    }
    let (mut magnitude, mut vertical) = (Vec::new(), Vec::new());
    let (mut mag_gain_sq, mut vertical_gain_sq, mut horizontal_sq) =
        (Vec::new(), Vec::new(), Vec::new());
    for (idx, &m_ut) in set.mag_ut.iter().enumerate() {
        let Some(down) = set.down(idx) else {
            continue;
        };
        let d_ut = m_ut - state.hard_iron_ut;
        let (r_b, r_v) = residuals(state, m_ut, Some(down));
        magnitude.push(r_b);
        vertical.push(r_v.unwrap_or(0.0));
        if let Some(n) = magnitude_norm(&state.correction, d_ut) {
            mag_gain_sq.push(n * n);
        }
        vertical_gain_sq.push((state.correction.transpose() * down).norm_squared());
        let corrected = state.correction * d_ut;
        horizontal_sq.push((corrected - down * down.dot(&corrected)).norm_squared());
    }
    let median = |values: &mut Vec<f64>| median_abs(values);
    let sigma_mag_ut =
        1.4826 * median(&mut magnitude) / median(&mut mag_gain_sq).sqrt().max(NORMALISER_FLOOR);
    let sigma_vertical_ut = 1.4826 * median(&mut vertical);
    let excess_sq =
        sigma_vertical_ut.powi(2) - sigma_mag_ut.powi(2) * median(&mut vertical_gain_sq);
    let horizontal_sq = median(&mut horizontal_sq);
    if !(excess_sq > 0.0 && horizontal_sq > 0.0 && sigma_mag_ut > 0.0) {
        return 0.0;
    }
    (excess_sq / horizontal_sq).sqrt() / sigma_mag_ut
}

fn weights(set: &SampleSet, state: &State, loss: Loss) -> Weights {
    let kappa = tilt_noise_ratio(set, state);
    let (sigma_magnitude_ut, sigma_vertical_ut) = robust_scales(set, state, kappa);
    let mut weights = Weights {
        sigma_magnitude_ut,
        sigma_vertical_ut,
        kappa,
        magnitude: Vec::with_capacity(set.mag_ut.len()),
        vertical: Vec::with_capacity(set.mag_ut.len()),
    };
    for (idx, &m_ut) in set.mag_ut.iter().enumerate() {
        let (r_b, r_v) = raw_residuals(state, m_ut, set.down(idx), kappa);
        weights
            .magnitude
            .push(loss.weight(r_b / sigma_magnitude_ut));
        weights
            .vertical
            .push(r_v.map_or(0.0, |r_v| loss.weight(r_v / sigma_vertical_ut)));
    }
    weights
}

/// The normal equations `JᵀWJ`, `JᵀWr` and the cost `rᵀWr` of the weighted, scaled
/// residuals plus the priors', at `state`.
struct Normal {
    jtj: ParamMat,
    jtr: ParamVec,
    cost: f64,
    /// The priors' share of `jtj`: what is known without the data.
    prior_information: ParamMat,
}

/// One prior residual `(aᵀθ − b) / σ` added to the normal equations.
fn add_prior(normal: &mut Normal, gradient: &ParamVec, residual: f64, sigma: f64) {
    let scaled = gradient / sigma;
    let information = scaled * scaled.transpose();
    normal.jtj += information;
    normal.prior_information += information;
    normal.jtr += scaled * (residual / sigma);
    normal.cost += (residual / sigma).powi(2);
}

fn normal_equations(
    set: &SampleSet,
    state: &State,
    weights: &Weights,
    options: &InertialOptions,
    start: &State,
) -> Normal {
    let uses_dip = set.uses_dip();
    let mut normal = Normal {
        jtj: ParamMat::zeros(),
        jtr: ParamVec::zeros(),
        cost: 0.0,
        prior_information: ParamMat::zeros(),
    };
    // The upper triangle is accumulated per sample in 13×13 blocks of rank two.
    let inv_var_magnitude = 1.0 / weights.sigma_magnitude_ut.powi(2);
    let inv_var_vertical = 1.0 / weights.sigma_vertical_ut.powi(2);
    for (idx, &m_ut) in set.mag_ut.iter().enumerate() {
        let down = set.down(idx).filter(|_| uses_dip);
        let (magnitude, vertical) = sample_rows(state, m_ut, down, weights.kappa);
        let weighted = |row: Row, weights: &[f64], inv_var: f64| {
            row.map(|(rho, gradient)| {
                (
                    rho,
                    gradient,
                    weights.get(idx).copied().unwrap_or(0.0) * inv_var,
                )
            })
        };
        accumulate(
            &mut normal,
            weighted(magnitude, &weights.magnitude, inv_var_magnitude),
            weighted(vertical, &weights.vertical, inv_var_vertical),
        );
    }
    add_priors(&mut normal, state, options, start, uses_dip);
    normal
}

/// [`normal_equations`]'s cost alone (the same arithmetic, without the gradients): what
/// a trial step needs to be accepted or refused.
fn cost(
    set: &SampleSet,
    state: &State,
    weights: &Weights,
    options: &InertialOptions,
    start: &State,
) -> f64 {
    let uses_dip = set.uses_dip();
    let inv_var_magnitude = 1.0 / weights.sigma_magnitude_ut.powi(2);
    let inv_var_vertical = 1.0 / weights.sigma_vertical_ut.powi(2);
    let mut normal = Normal {
        jtj: ParamMat::zeros(),
        jtr: ParamVec::zeros(),
        cost: 0.0,
        prior_information: ParamMat::zeros(),
    };
    for (idx, &m_ut) in set.mag_ut.iter().enumerate() {
        let d_ut = m_ut - state.hard_iron_ut;
        let corrected = state.correction * d_ut;
        let term = |rho: Option<f64>, weights: &[f64], inv_var: f64| {
            let weight = weights.get(idx).copied().unwrap_or(0.0) * inv_var;
            match rho {
                Some(rho) if weight > 0.0 => weight * rho * rho,
                _ => 0.0,
            }
        };
        let magnitude = magnitude_norm(&state.correction, d_ut)
            .map(|n| (corrected.norm() - state.field_ut) * (1.0 / n));
        let vertical = set.down(idx).filter(|_| uses_dip).and_then(|down| {
            let n = vertical_norm(&state.correction, d_ut, down, weights.kappa)?;
            Some((down.dot(&corrected) - state.vertical_ut) * (1.0 / n))
        });
        normal.cost += term(magnitude, &weights.magnitude, inv_var_magnitude)
            + term(vertical, &weights.vertical, inv_var_vertical);
    }
    add_priors(&mut normal, state, options, start, uses_dip);
    normal.cost
}

/// One sample's two normalised residuals `ρ = r / n` (see [`normalisers`]) and their
/// gradients, `∂ρ = (∂r − ρ·∂n) / n`; the vertical one only with a down vector.
type Row = Option<(f64, ParamVec)>;
fn sample_rows(
    state: &State,
    m_ut: Vector3<f64>,
    down: Option<Vector3<f64>>,
    kappa: f64,
) -> (Row, Row) {
    let correction = state.correction;
    let d_ut = m_ut - state.hard_iron_ut;
    let corrected = correction * d_ut;
    let magnitude = corrected.norm();
    let magnitude_row = magnitude_normaliser(&correction, d_ut).map(|(n, n_gradient)| {
        let unit = corrected * (1.0 / magnitude);
        let inv_n = 1.0 / n;
        let rho = (magnitude - state.field_ut) * inv_n;
        (
            rho,
            (row_gradient(&correction, unit, d_ut, 0.0) - n_gradient * rho) * inv_n,
        )
    });
    let vertical_row = down.and_then(|down| {
        let (n, n_gradient) = vertical_normaliser(&correction, d_ut, down, kappa)?;
        let inv_n = 1.0 / n;
        let rho = (down.dot(&corrected) - state.vertical_ut) * inv_n;
        Some((
            rho,
            (row_gradient(&correction, down, d_ut, -1.0) - n_gradient * rho) * inv_n,
        ))
    });
    (magnitude_row, vertical_row)
}

/// The gradient of `aᵀ·D·(m − h) − v·V` (for a fixed direction `a`): `−Dᵀa` for `h`,
/// `a_j·d_k` for `D_jk`, `v_coefficient` for `V`.
fn row_gradient(
    correction: &Matrix3<f64>,
    direction: Vector3<f64>,
    d_ut: Vector3<f64>,
    v_coefficient: f64,
) -> ParamVec {
    let mut gradient = ParamVec::zeros();
    let hard = -(correction.transpose() * direction);
    for axis in 0..3 {
        gradient[H + axis] = hard[axis];
    }
    for row in 0..3 {
        for col in 0..3 {
            gradient[D0 + 3 * row + col] = direction[row] * d_ut[col];
        }
    }
    gradient[V] = v_coefficient;
    gradient
}

fn accumulate(
    normal: &mut Normal,
    first: Option<(f64, ParamVec, f64)>,
    second: Option<(f64, ParamVec, f64)>,
) {
    // A row with no usable weight adds nothing (not even a NaN from its gradient).
    let usable = |row: Option<(f64, ParamVec, f64)>| {
        row.filter(|&(_, _, weight)| weight > 0.0)
            .unwrap_or((0.0, ParamVec::zeros(), 0.0))
    };
    let (rho_a, g_a, w_a) = usable(first);
    let (rho_b, g_b, w_b) = usable(second);
    for row in 0..N_MAX {
        let (a, b) = (g_a[row] * w_a, g_b[row] * w_b);
        for col in row..N_MAX {
            normal.jtj[(row, col)] += a * g_a[col] + b * g_b[col];
        }
        normal.jtr[row] += a * rho_a + b * rho_b;
    }
    normal.cost += w_a * rho_a * rho_a + w_b * rho_b * rho_b;
}

/// The priors' residuals: the vertical field, the soft iron towards `s·I`, its rotation
/// part towards zero, and the hard iron (barely). Without the dip, `V` is pinned where
/// it is (it does not enter any residual).
fn add_priors(
    normal: &mut Normal,
    state: &State,
    options: &InertialOptions,
    start: &State,
    uses_dip: bool,
) {
    // Mirror the accumulated upper triangle first: the priors add full matrices.
    for row in 0..N_MAX {
        for col in 0..row {
            normal.jtj[(row, col)] = normal.jtj[(col, row)];
        }
    }
    let params = state.params();
    let unit = |idx: usize| {
        let mut gradient = ParamVec::zeros();
        gradient[idx] = 1.0;
        gradient
    };
    // The soft-iron priors are on the shape of `D`, `D/g` with `g = det(D)^⅓`, not on
    // its scale (which `F` sets): a prior residual `p = L(D)/g − c` for a linear `L`
    // has the gradient `(∂L − (p + c)·g·G) / g`, with `∂g/∂D = g·G`, `G = D⁻ᵀ/3`.
    let det = state.correction.determinant();
    if let (true, Some(inverse)) = (det > 0.0, state.correction.try_inverse()) {
        let g = det.cbrt();
        let mut g_gradient = ParamVec::zeros();
        for row in 0..3 {
            for col in 0..3 {
                g_gradient[D0 + 3 * row + col] = inverse[(col, row)] / 3.0 * g;
            }
        }
        if options.gain_known {
            // ln g, with ∂(ln g)/∂D = G = D⁻ᵀ/3.
            add_prior(normal, &(g_gradient / g), g.ln(), GAIN_PRIOR_STD);
        }
        let mut shape_prior = |linear: ParamVec, centre: f64, std: f64| {
            let value = linear.dot(&params) / g;
            let gradient = (linear - g_gradient * value) / g;
            add_prior(normal, &gradient, value - centre, std);
        };
        for axis in 0..3 {
            shape_prior(unit(D0 + 4 * axis), 1.0, SOFT_IRON_PRIOR_STD);
        }
        // Each off-diagonal pair as its symmetric part (cross-axis soft iron) and its
        // antisymmetric part (a small rotation).
        // Without the accelerometer nothing sees a rotation of the magnetometer's axes:
        // it is held at zero (the symmetric correction of the classic ellipsoid fit).
        let rotation_std = if uses_dip {
            ROTATION_PRIOR_STD_RAD
        } else {
            1e-9
        };
        for (a, b) in [(0, 1), (0, 2), (1, 2)] {
            let (ab, ba) = (D0 + 3 * a + b, D0 + 3 * b + a);
            for (sign, std) in [(1.0, CROSS_AXIS_PRIOR_STD), (-1.0, rotation_std)] {
                let mut linear = ParamVec::zeros();
                linear[ab] = 0.5;
                linear[ba] = 0.5 * sign;
                shape_prior(linear, 0.0, std);
            }
        }
    } else {
        normal.cost = f64::INFINITY;
    }
    for axis in 0..3 {
        add_prior(
            normal,
            &unit(H + axis),
            params[H + axis] - start.hard_iron_ut[axis],
            HARD_IRON_PRIOR_STD_UT,
        );
    }
    match (uses_dip, options.field) {
        (true, Some(prior)) => {
            let (sin_dip, cos_dip) = prior.inclination_deg.to_radians().sin_cos();
            let sigma_ut =
                (state.field_ut * cos_dip.abs().max(0.05) * INCLINATION_PRIOR_STD_DEG.to_radians())
                    .max(1e-6);
            add_prior(
                normal,
                &unit(V),
                params[V] - state.field_ut * sin_dip,
                sigma_ut,
            );
        }
        (true, None) => add_prior(normal, &unit(V), params[V], 1e3 * state.field_ut),
        (false, _) => add_prior(normal, &unit(V), params[V] - start.vertical_ut, 1e-9),
    }
}

/// A converged fit with its last weights.
struct Solution {
    state: State,
    model: SoftIronModel,
    weights: Weights,
    covariance: Option<ParamMat>,
}

impl Solution {
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

    fn report(
        &self,
        set: &SampleSet,
        all_ut: &[Vector3<f64>],
        options: &InertialOptions,
    ) -> InertialFit {
        let state = &self.state;
        let uses_dip = set.uses_dip();
        let mut inlier_magnitudes = Vec::new();
        let mut all_magnitudes = Vec::with_capacity(set.mag_ut.len());
        let (mut sum_sq_b, mut sum_sq_v, mut n_in, mut n_out) = (0.0, 0.0, 0usize, 0usize);
        for (idx, &m_ut) in set.mag_ut.iter().enumerate() {
            let (r_b, r_v) = residuals(state, m_ut, set.down(idx));
            let magnitude = r_b + state.field_ut;
            all_magnitudes.push(magnitude);
            let weight = self.weights.magnitude.get(idx).copied().unwrap_or(1.0);
            let vertical_weight = if uses_dip {
                self.weights.vertical.get(idx).copied().unwrap_or(1.0)
            } else {
                1.0
            };
            if weight.min(vertical_weight) < OUTLIER_WEIGHT {
                n_out += 1;
                continue;
            }
            n_in += 1;
            inlier_magnitudes.push(magnitude);
            sum_sq_b += r_b * r_b;
            sum_sq_v += r_v.unwrap_or(0.0).powi(2);
        }
        let spread_pct = |magnitudes: &[f64]| {
            let n = magnitudes.len().max(1) as f64;
            let mean = magnitudes.iter().sum::<f64>() / n;
            let variance = magnitudes.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n;
            100.0 * variance.sqrt() / mean.max(f64::MIN_POSITIVE)
        };
        let n_in_f = n_in.max(1) as f64;
        let covariance = self.covariance.unwrap_or(ParamMat::zeros());
        let std_of = |idx: usize| covariance[(idx, idx)].max(0.0).sqrt();
        let scale = state
            .correction
            .determinant()
            .abs()
            .cbrt()
            .max(f64::MIN_POSITIVE);
        let hard_iron_std_ut = Vector3::new(std_of(H), std_of(H + 1), std_of(H + 2));
        let soft_iron_std = Matrix3::from_fn(|row, col| std_of(D0 + 3 * row + col) / scale);
        let inclination = uses_dip.then(|| {
            let ratio = (state.vertical_ut / state.field_ut).clamp(-1.0, 1.0);
            let cos_dip = (1.0 - ratio * ratio).sqrt().max(1e-6);
            (
                ratio.asin().to_degrees(),
                (std_of(V) / state.field_ut / cos_dip).to_degrees(),
            )
        });
        let mut unobserved = Vec::new();
        const AXES: [&str; 3] = ["x", "y", "z"];
        for axis in 0..3 {
            if hard_iron_std_ut[axis] > UNOBSERVED_HARD_IRON_UT {
                unobserved.push(Unobserved {
                    parameter: format!("hard iron {}", AXES[axis]),
                    std: hard_iron_std_ut[axis],
                    unit: "µT",
                });
            }
        }
        // The soft iron in the terms its priors use: each axis's gain, each pair's
        // cross-axis coupling (symmetric part) and rotation (antisymmetric part, fitted
        // only with the accelerometer), each as a fraction of the scale.
        let std_of_combination = |entries: &[((usize, usize), f64)]| {
            let mut gradient = ParamVec::zeros();
            for &((row, col), weight) in entries {
                gradient[D0 + 3 * row + col] = weight / scale;
            }
            (gradient.transpose() * covariance * gradient)[(0, 0)]
                .max(0.0)
                .sqrt()
        };
        for (axis, name) in AXES.iter().enumerate() {
            let std = std_of_combination(&[((axis, axis), 1.0)]);
            if self.model == SoftIronModel::Full && std > UNOBSERVED_SHARE * SOFT_IRON_PRIOR_STD {
                unobserved.push(Unobserved {
                    parameter: format!("soft iron gain {name}"),
                    std,
                    unit: "of the scale",
                });
            }
        }
        for (a, b) in [(0, 1), (0, 2), (1, 2)] {
            let name = format!("{}{}", AXES[a], AXES[b]);
            let cross = std_of_combination(&[((a, b), 0.5), ((b, a), 0.5)]);
            if self.model == SoftIronModel::Full && cross > UNOBSERVED_SHARE * CROSS_AXIS_PRIOR_STD
            {
                unobserved.push(Unobserved {
                    parameter: format!("cross-axis soft iron {name}"),
                    std: cross,
                    unit: "of the scale",
                });
            }
            let rotation_deg = std_of_combination(&[((a, b), 0.5), ((b, a), -0.5)]).to_degrees();
            let axis = AXES[3 - a - b];
            if self.model == SoftIronModel::Full
                && uses_dip
                && rotation_deg > UNOBSERVED_SHARE * ROTATION_PRIOR_STD_RAD.to_degrees()
            {
                unobserved.push(Unobserved {
                    parameter: format!("rotation about {axis} (magnetometer to accelerometer)"),
                    std: rotation_deg,
                    unit: "°",
                });
            }
        }
        if let (Some((_, std_deg)), Some(_)) = (inclination, options.field) {
            if std_deg > UNOBSERVED_SHARE * INCLINATION_PRIOR_STD_DEG {
                unobserved.push(Unobserved {
                    parameter: "dip".to_string(),
                    std: std_deg,
                    unit: "°",
                });
            }
        }
        InertialFit {
            model: self.model,
            model_reason: None,
            calibration: FieldCalibration {
                hard_iron_ut: state.hard_iron_ut,
                soft_iron: state.correction,
                field_ut: state.field_ut,
            },
            uses_dip,
            field_from_model: options.field.is_some(),
            inclination_deg: inclination.map(|(deg, _)| deg),
            inclination_std_deg: inclination.map(|(_, std)| std),
            residual_rms_ut: (sum_sq_b / n_in_f).sqrt(),
            field_spread_pct: spread_pct(&inlier_magnitudes),
            field_spread_all_pct: spread_pct(&all_magnitudes),
            vertical_rms_ut: uses_dip.then(|| (sum_sq_v / n_in_f).sqrt()),
            n_samples: all_ut.len(),
            n_fitted: set.mag_ut.len(),
            outlier_pct: 100.0 * n_out as f64 / set.mag_ut.len().max(1) as f64,
            hard_iron_std_ut,
            soft_iron_std,
            heading_std_deg: heading_std_deg(set, state, &covariance),
            unobserved,
        }
    }
}

/// RMS over the samples of the heading's standard deviation that the parameters'
/// covariance gives, through `ψ = atan2(−l_y, l_x)` of the levelled correction.
fn heading_std_deg(set: &SampleSet, state: &State, covariance: &ParamMat) -> f64 {
    let stride = set.mag_ut.len().div_ceil(500).max(1);
    let (mut sum_variance, mut n) = (0.0, 0usize);
    for (idx, &m_ut) in set.mag_ut.iter().enumerate().step_by(stride) {
        let down = set.down(idx).unwrap_or(Vector3::z());
        // The two horizontal axes of the level frame, expressed in body axes: the
        // forward axis projected on the horizontal, and down × forward.
        let forward = (Vector3::x() - down * down.x).try_normalize(1e-9);
        let Some(forward) = forward else {
            continue;
        };
        let right = down.cross(&forward);
        let d_ut = m_ut - state.hard_iron_ut;
        let corrected = state.correction * d_ut;
        let level = Vector2::new(forward.dot(&corrected), right.dot(&corrected));
        let norm_sq = level.norm_squared();
        if norm_sq <= 0.0 {
            continue;
        }
        // dψ = (l_y·dl_x − l_x·dl_y) / |l|², with dl = (forwardᵀ, rightᵀ)·dc.
        let direction = (forward * level.y - right * level.x) / norm_sq;
        let gradient = row_gradient(&state.correction, direction, d_ut, 0.0);
        sum_variance += (gradient.transpose() * covariance * gradient)[(0, 0)].max(0.0);
        n += 1;
    }
    (sum_variance / n.max(1) as f64).sqrt().to_degrees()
}

/// Iteratively reweighted Levenberg-Marquardt from `start`, moving only along the
/// directions the data see ([`observed_directions`]); `None` when it diverges or ends on
/// a mirror image (negative determinant).
fn solve(
    set: &SampleSet,
    start: State,
    options: &InertialOptions,
    model: SoftIronModel,
    schedule: Schedule,
) -> Option<Solution> {
    let start = match model {
        SoftIronModel::Full => start,
        SoftIronModel::Isotropic => State {
            correction: Matrix3::identity() * start.correction.determinant().abs().cbrt(),
            ..start
        },
    };
    let model_directions = match (model, set.band_axis()) {
        (SoftIronModel::Full, Some(axis)) => FreeDirections::band(axis),
        (SoftIronModel::Full, None) if set.uses_dip() => FreeDirections::all(),
        (SoftIronModel::Full, None) => FreeDirections::symmetric(),
        (SoftIronModel::Isotropic, _) => FreeDirections::isotropic(),
    };
    // First every direction of the model; then only those the data see at the noise
    // that fit leaves (judged before it, a start's misfit would pass for noise and hide
    // what the data do see), the others back at the start's values, which come from
    // the priors.
    let (first, first_weights) = iterate(set, start, &start, options, &model_directions, schedule)?;
    let normal = normal_equations(set, &first, &first_weights, options, &start);
    let inflation = autocorrelation_inflation(set, &first, &first_weights);
    let observed = observed_directions(&normal, inflation, model_directions.clone());
    let (state, weights) = if observed.n_free < model_directions.n_free {
        let restart = start.with_params(&observed.project(&start.params(), &first.params()));
        iterate(set, restart, &start, options, &observed, Schedule::Warm)?
    } else {
        (first, first_weights)
    };
    let det = state.correction.determinant();
    if det.is_nan() || det <= 0.0 {
        return None;
    }
    // The covariance at the end, with the final weights: the frozen directions keep
    // their priors' uncertainty.
    let normal = normal_equations(set, &state, &weights, options, &start);
    let covariance =
        posterior_covariance(&normal, autocorrelation_inflation(set, &state, &weights));
    Some(Solution {
        state,
        model,
        weights,
        covariance,
    })
}

/// Iteratively reweighted Levenberg-Marquardt from `from` along the `free` directions
/// (the priors centred as for `start`): the state and the last weights.
fn iterate(
    set: &SampleSet,
    from: State,
    start: &State,
    options: &InertialOptions,
    free: &FreeDirections,
    schedule: Schedule,
) -> Option<(State, Weights)> {
    let mut state = from;
    let mut lambda = 1e-3;
    let mut last = None;
    for reweighting in 0..schedule.max_reweightings() {
        let before = state;
        let weights = weights(set, &state, schedule.loss(reweighting));
        let mut normal = normal_equations(set, &state, &weights, options, start);
        // Weights that will change again need no exact minimum under them.
        let max_iterations = if reweighting + 1 == schedule.max_reweightings() {
            MAX_LM_ITERATIONS
        } else {
            MAX_LM_ITERATIONS_BEFORE_LAST
        };
        for iteration in 0..max_iterations {
            let step = free.step(&normal.jtj, &normal.jtr, lambda)?;
            let trial = state.with_params(&(state.params() - step));
            // The cost decides; the gradients only where another step will use them.
            let trial_cost = cost(set, &trial, &weights, options, start);
            if trial_cost.is_finite() && trial_cost <= normal.cost {
                let decrease = normal.cost - trial_cost;
                state = trial;
                lambda = (lambda / 3.0).max(1e-9);
                if decrease <= STEADY_COST_SHARE * trial_cost.max(1e-300)
                    || iteration + 1 == max_iterations
                {
                    break;
                }
                normal = normal_equations(set, &state, &weights, options, start);
            } else {
                lambda *= 4.0;
                if lambda > 1e8 {
                    break;
                }
            }
        }
        last = Some(weights);
        if reweighting + 1 >= schedule.min_reweightings() && state.is_steady_from(&before) {
            break;
        }
    }
    Some((state, last?))
}

/// The parameter directions the fit may move along: a basis of columns.
#[derive(Clone)]
struct FreeDirections {
    basis: SMatrix<f64, N_MAX, N_MAX>,
    n_free: usize,
}

impl FreeDirections {
    /// `from` moved towards `to` along the free directions only: `from + B·α` with
    /// `α` the least-squares coordinates of `to − from` in the basis `B`.
    fn project(&self, from: &ParamVec, to: &ParamVec) -> ParamVec {
        let basis = self.basis.columns(0, self.n_free);
        let gram = basis.transpose() * basis;
        let coordinates = gram
            .cholesky()
            .map(|cholesky| cholesky.solve(&(basis.transpose() * (to - from))));
        match coordinates {
            Some(coordinates) => from + basis * coordinates,
            None => *from,
        }
    }

    fn all() -> FreeDirections {
        FreeDirections {
            basis: ParamMat::identity(),
            n_free: N_MAX,
        }
    }

    /// The band model, for a device that turns about `axis` (unit, body axes: the mean
    /// down) with little tilt: the hard iron, the vertical field, and five directions
    /// of `D`: its in-plane shape (the difference of the two in-plane gains, and their
    /// cross term), one gain for all axes, and the leak of the in-plane field into the
    /// corrected vertical. What the band hardly sees (the axis's own gain, the leak of
    /// the axis into the plane, which a level turn cannot tell from hard iron, and a
    /// rotation about the axis: an ellipsoid through a flat ring can stretch, lean and
    /// turn almost freely) stays at the start's, which takes it from the priors, and the
    /// covariance reports the priors' uncertainty there.
    fn band(axis: Vector3<f64>) -> FreeDirections {
        let helper = if axis.x.abs() < 0.9 {
            Vector3::x()
        } else {
            Vector3::y()
        };
        let first = axis.cross(&helper).normalize();
        let second = axis.cross(&first);
        let as_params = |matrix: Matrix3<f64>| {
            let mut params = ParamVec::zeros();
            for row in 0..3 {
                for col in 0..3 {
                    params[D0 + 3 * row + col] = matrix[(row, col)];
                }
            }
            params.normalize()
        };
        let mut free = FreeDirections {
            basis: ParamMat::zeros(),
            n_free: 0,
        };
        let mut add = |vector: ParamVec| {
            free.basis.set_column(free.n_free, &vector);
            free.n_free += 1;
        };
        for axis_idx in 0..3 {
            let mut unit = ParamVec::zeros();
            unit[H + axis_idx] = 1.0;
            add(unit);
        }
        let mut vertical = ParamVec::zeros();
        vertical[V] = 1.0;
        add(vertical);
        add(as_params(
            first * first.transpose() - second * second.transpose(),
        ));
        add(as_params(
            first * second.transpose() + second * first.transpose(),
        ));
        add(as_params(Matrix3::identity()));
        // How the in-plane field leaks into the corrected vertical: a level turn sees
        // it (the vertical must not swing with the heading).
        add(as_params(axis * first.transpose()));
        add(as_params(axis * second.transpose()));
        free
    }

    /// Without the accelerometer: the hard iron and a symmetric `D` (the classic
    /// ellipsoid; nothing sees a rotation, nor the vertical field). Held by a pinning
    /// prior instead, those directions would also freeze their symmetric neighbours
    /// through Marquardt's scaling of the damping.
    fn symmetric() -> FreeDirections {
        let mut free = FreeDirections {
            basis: ParamMat::zeros(),
            n_free: 0,
        };
        let mut add = |entries: &[(usize, f64)]| {
            for &(idx, value) in entries {
                free.basis[(idx, free.n_free)] = value;
            }
            free.n_free += 1;
        };
        for axis in 0..3 {
            add(&[(H + axis, 1.0)]);
            add(&[(D0 + 4 * axis, 1.0)]);
        }
        let half = std::f64::consts::FRAC_1_SQRT_2;
        for (a, b) in [(0, 1), (0, 2), (1, 2)] {
            add(&[(D0 + 3 * a + b, half), (D0 + 3 * b + a, half)]);
        }
        free
    }

    /// The hard iron, one scale for every axis, and the vertical field.
    fn isotropic() -> FreeDirections {
        let mut basis = ParamMat::zeros();
        for axis in 0..3 {
            basis[(H + axis, axis)] = 1.0;
            basis[(D0 + 4 * axis, 3)] = 1.0;
        }
        basis[(V, 4)] = 1.0;
        FreeDirections { basis, n_free: 5 }
    }

    /// The damped Gauss-Newton step restricted to the free directions.
    /// The Levenberg-Marquardt step restricted to the free directions: the normal
    /// equations reduced to them, damped by `lambda` times their own diagonal (so that a
    /// frozen direction's prior cannot damp the free ones that share its entries).
    fn step(&self, jtj: &ParamMat, jtr: &ParamVec, lambda: f64) -> Option<ParamVec> {
        let basis = self.basis.columns(0, self.n_free);
        let mut reduced = basis.transpose() * jtj * basis;
        for idx in 0..self.n_free {
            reduced[(idx, idx)] += lambda * reduced[(idx, idx)].max(1e-12);
        }
        let rhs = basis.transpose() * jtr;
        let solution = reduced.cholesky()?.solve(&rhs);
        Some(basis * solution)
    }
}

/// Directions of the parameters along which the data say at least
/// [`MIN_DATA_OVER_PRIOR`] times more than the priors, once the residuals' correlation
/// (`inflation`) is counted: the generalised eigenvectors of the data's information
/// against the priors'. Along the others (a level turn's vertical hard iron and scale,
/// whose family of ellipsoids through one circle includes flat caps that fit any plane
/// of samples, disturbances and all) the fit stays at its start, which the starts set
/// from the priors, and the covariance reports the prior's uncertainty there.
fn observed_directions(normal: &Normal, inflation: f64, model: FreeDirections) -> FreeDirections {
    // Within the model's subspace (columns B): the reduced information matrices.
    let basis = model.basis.columns(0, model.n_free).into_owned();
    let prior = basis.transpose() * normal.prior_information * &basis;
    let data = basis.transpose() * (normal.jtj - normal.prior_information) * &basis;
    let Some(cholesky) = prior.clone().cholesky() else {
        return model;
    };
    // M = L⁻¹·data·L⁻ᵀ; an eigenvector y of M is the direction v = B·L⁻ᵀ·y.
    let Some(lower_inverse) = cholesky.l().try_inverse() else {
        return model;
    };
    let whitened = &lower_inverse * data * lower_inverse.transpose();
    let whitened = (&whitened + whitened.transpose()) / 2.0;
    let eigen = whitened.symmetric_eigen();
    let threshold = MIN_DATA_OVER_PRIOR * inflation;
    let mut free = FreeDirections {
        basis: ParamMat::zeros(),
        n_free: 0,
    };
    for (idx, &value) in eigen.eigenvalues.iter().enumerate() {
        if value >= threshold {
            let direction = &basis * (lower_inverse.transpose() * eigen.eigenvectors.column(idx));
            free.basis.set_column(free.n_free, &direction);
            free.n_free += 1;
        }
    }
    if free.n_free == 0 {
        return model;
    }
    free
}

/// The posterior covariance `(J_dᵀWJ_d / inflation + P)⁻¹`: the data's information
/// counted for its correlated samples, the priors' as they are.
fn posterior_covariance(normal: &Normal, inflation: f64) -> Option<ParamMat> {
    let data = normal.jtj - normal.prior_information;
    (data / inflation.max(1.0) + normal.prior_information)
        .try_inverse()
        .filter(|covariance| covariance.iter().all(|v| v.is_finite()))
}

/// `(1 + ρ) / (1 − ρ)` for the lag-one autocorrelation `ρ` of the residuals in sample
/// order (the larger of the two kinds, weighted): neighbouring samples share their tilt error and
/// their disturbance, so they count for less than independent ones.
fn autocorrelation_inflation(set: &SampleSet, state: &State, weights: &Weights) -> f64 {
    let mut magnitude = Vec::with_capacity(set.mag_ut.len());
    let mut vertical = Vec::with_capacity(set.mag_ut.len());
    // The weighted residuals: a burst of moving iron, set aside by its weights, is not
    // a correlation of the rest.
    for (idx, &m_ut) in set.mag_ut.iter().enumerate() {
        let (r_b, r_v) = raw_residuals(state, m_ut, set.down(idx), weights.kappa);
        let weight = |weights: &[f64]| weights.get(idx).copied().unwrap_or(0.0).sqrt();
        magnitude.push(r_b * weight(&weights.magnitude));
        if let Some(r_v) = r_v {
            vertical.push(r_v * weight(&weights.vertical));
        }
    }
    let lag_one = |values: &[f64]| {
        if values.len() < 3 {
            return 0.0;
        }
        let mean = values.iter().sum::<f64>() / values.len() as f64;
        let variance: f64 = values.iter().map(|v| (v - mean).powi(2)).sum();
        let covariance: f64 = values
            .windows(2)
            .map(|pair| (pair[0] - mean) * (pair[1] - mean))
            .sum();
        if variance > 0.0 {
            (covariance / variance).clamp(0.0, 0.99)
        } else {
            0.0
        }
    };
    let rho = lag_one(&magnitude).max(lag_one(&vertical));
    (1.0 + rho) / (1.0 - rho)
}

#[cfg(test)]
mod tests;
