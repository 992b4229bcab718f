//! Calibration from flat, circle-only data: a general conic in the level plane, made
//! tilt-aware so that the hard iron does not leak through the levelling.
//!
//! This is the method for the data people really have: walkers and vehicles turn
//! through every heading but tilt only a few degrees (about ±10°), which leaves a 3D
//! ellipsoid fit badly conditioned. It needs, for every magnetometer sample (µT, body
//! frame x forward, y right, z down), the roll and pitch of that moment ([`Tilt`], from
//! the accelerometer averaged over about a second, see [`crate::attitude::tilt`]). An expected
//! inclination (dip, from a field model) helps but is not needed.
//!
//! ## Why levelling the raw field is not enough
//!
//! The magnetometer reads `m = S·b + h + noise`, where `b = Tᵀ·n(ψ)` is the Earth's
//! field in the body frame, `T = Ry(θ)·Rx(φ)` the levelling rotation of Eq. 4 and
//! `n(ψ) = (H·cosψ, −H·sinψ, V)` the field in the level frame of a device facing ψ.
//! The hard iron `h` is fixed in the *body* frame, so levelling the raw field rotates
//! it with the tilt:
//!
//! ```text
//! T·m = (T·S·Tᵀ)·n(ψ) + T·h ≈ S·n(ψ) + h + (θ·h_z, −φ·h_z) + …   (horizontal part)
//! ```
//!
//! A vertical hard iron of tens of µT thus adds `h_z·sin 10° ≈ 5-10 µT` to a horizontal
//! field of about 20 µT, varying with the tilt rather than the heading: the levelled raw
//! field is not an ellipse in ψ, and neither min/max (Eq. 6-7) nor a conic fitted to it
//! can remove what is not a function of the heading. The second-order terms (`θ²·h_x/2`,
//! with a non-zero mean) also move the centre of such a fit by tenths of a µT, i.e.
//! about a degree.
//!
//! ## The model
//!
//! Let `A = S⁻¹` (symmetric, as in [`crate::fit::model`]). For every sample,
//! `l = T·A·(m − h)` must equal `n(ψ)` for some ψ, which is two scalar conditions that
//! do not involve the unknown heading:
//!
//! ```text
//! r_horizontal = |(l_x, l_y)| − H      (the corrected horizontal field is a circle)
//! r_vertical   = l_z − V               (the corrected vertical field is constant)
//! ```
//!
//! Both residuals are in µT. The unknowns are the six entries of `A`, the three of `h`
//! and `V`; `H` is held at the radius of the first fit, because headings cannot tell
//! the overall scale (it is fixed at the end, below). With the inclination given,
//! `V = H·tan(dip)` is no longer an unknown.
//!
//! What the data observes, to first order in the tilt: a level turn fixes the in-plane
//! part of `A`, the coupling `A_xz`, `A_yz` (the vertical residual must not vary with
//! the heading, and `A` is symmetric) and hence the horizontal hard iron; it leaves one
//! combination `A_zz·V − h_z − V` free. Tilt separates it: the horizontal residual
//! moves with `(θ, −φ)·(A_zz·V − h_z)` and the vertical one with
//! `A_zz·(θ·n_x − φ·n_y)`. The tilt must therefore *vary* (a constant tilt is only a
//! re-mounted sensor); when it varies by less than [`MIN_TILT_SPREAD_DEG`], `A_zz = 1`
//! and (without an inclination) `h_z = 0` are held fixed, which costs nothing at level
//! and is reported as `vertical_estimated = false`. The symmetric form of `A` is what
//! fixes the rotation about the vertical: a rotation between sensor and body axes is
//! not observable without a reference heading (see [`crate::fit::ref_ls`]).
//!
//! ## The fit, step by step
//!
//! 1. Level the raw field with Eq. 4 and fit a general conic to it: the direct,
//!    ellipse-specific least squares of Fitzgibbon, Pilu and Fisher (1999, *Direct
//!    least square fitting of ellipses*, IEEE PAMI 21(5)), in the numerically stable
//!    form of Halíř and Flusser (1998, *Numerically stable direct least squares fitting
//!    of ellipses*, WSCG), on centred and scaled coordinates. This gives the in-plane
//!    start and the gauge `H` (`direct.rs`; [`fit_ellipse`] on its own is the
//!    calibration for levelled 2D data).
//! 2. Minimise the residuals above by Levenberg-Marquardt on the normal equations
//!    (`fit::normal_lm`: one pass over the samples per step, analytic Jacobian; first
//!    on an evenly spaced subset of at most 2,000 samples, then on all of them),
//!    starting from the conic, `A_zz = 1`, no vertical coupling, `h_z = 0` (or `h_z`
//!    from the dip, when given). The model is nearly
//!    linear in `h`, so this start converges. The residuals are geometric (distances in
//!    µT in the corrected space), so this step is also the geometric refinement of the
//!    algebraic conic; it removes the conic's small noise bias as well.
//! 3. Fix the scale: `A`, `H` and `V` are multiplied by `k = √det(S_hh)` so that the
//!    level-plane correction preserves area, i.e. the corrected circle's radius is the
//!    geometric mean of the raw level ellipse's semi-axes (the "mean horizontal field").
//!
//! The fit keeps the full model: [`PlaneFit::heading_rad`] computes `T·A·(m − h)` for
//! any tilt. [`PlaneFit::plane`] is its level-plane form, `corrected = W·(p − c)` on
//! `p = level(m − h)`, with `W = S_hh⁻¹` (symmetric, determinant 1) and `c = S_hz·V`;
//! it is exact for level samples and leaves, when tilted, the second-order terms
//! `(S_zz − S_xx)·θ·V` (about 1 µT at 10° for 10 % soft iron) that only the full model
//! removes.
//!
//! ## When the full matrix is not supported
//!
//! A few degrees of tilt, a vertical hard iron of hundreds of µT (a phone's speaker
//! magnet) and a field that changes along an indoor walk let the full model trade the
//! vertical residual for the disturbances: `A_zz` shrinks towards zero, `A_xz`, `A_yz`
//! absorb the rest, and the hard iron moves by tens of µT. When the fitted `A` scales
//! one axis more than [`MAX_AXIS_RATIO`] times another (or is not positive definite),
//! the fit is replaced by the isotropic model of [`crate::fit::ellipse_isotropic`] (`A` = the
//! identity, hard iron removed in the body frame before levelling, the vertical field
//! from the given inclination), and [`PlaneFit::soft_iron_model`] says so.
//!
//! ## Limits
//!
//! The heading is only as good as the tilt: a 1° error in roll or pitch moves the
//! levelled field by `V·sin 1°`, about 0.8 µT (2° of heading) at 65° inclination. In
//! the fit such errors average out: with 1° RMS of random tilt error in the training
//! data, the level heading RMS of the simulated test below stays under 0.3°. The
//! model assumes one field (one place, no changing disturbance) and a symmetric soft
//! iron. An algebraic conic from a partial turn is poorly determined, so the fit
//! refuses a heading gap larger than [`PlaneOptions::max_heading_gap_deg`] and names
//! the missing headings.

use nalgebra::{Matrix2, Matrix3, SymmetricEigen, Vector2, Vector3};
use serde::Serialize;
use thiserror::Error;

use crate::attitude::compass_heading;
use crate::attitude::tilt::Tilt;
use crate::fit::ellipse_isotropic::{fit_isotropic, Vertical};
use crate::fit::minmax::Coverage;
use crate::fit::model::PlaneCalibration;
use crate::fit::normal_lm::{self, Normal};

mod direct;
use direct::direct_ellipse_fit;
pub use direct::fit_ellipse;

/// Fewer samples than this cannot determine the ten parameters of the model with any
/// redundancy, nor trace a turn.
pub const MIN_SAMPLES: usize = 30;

/// Below this spread of roll and pitch (standard deviation, combined), the vertical
/// hard iron is not estimated: its signature is the tilt times `h_z`, under the noise.
pub const MIN_TILT_SPREAD_DEG: f64 = 1.0;

/// A level ellipse whose axes differ by more than this factor is not soft iron (real
/// soft iron changes the axes by tens of per cent) but a partial turn or a changing
/// disturbance.
pub const MAX_AXIS_RATIO: f64 = 3.0;

/// A residual RMS above this share of the horizontal field means the data does not
/// follow the model: sensor noise (0.1-0.5 µT) and tilt errors of a degree or two
/// (`V·sin 2°`, about 1.5 µT) stay well below a tenth of a 20 µT horizontal field.
const MAX_RELATIVE_RESIDUAL: f64 = 0.15;

/// The residual limit of the isotropic fallback, which is meant for disturbed data: a
/// field that changes by 10-20 % along an indoor walk (steel, wiring, escalators) still
/// lets a full turn fix the hard iron's horizontal part, because the centre averages
/// the disturbance over thousands of samples and every heading. A quarter of the
/// horizontal field is beyond what a disturbance leaves of one field turned around.
const MAX_RELATIVE_RESIDUAL_ISOTROPIC: f64 = 0.25;

/// Levenberg-Marquardt steps before the fit keeps the best parameters it found (on the
/// subset; a quarter of them on all the samples): clean data settle in 5-30; data that
/// follow no single field (a walk in a pocket, indoors) creep on for hundreds of steps
/// at a few milliseconds each, and the residual check judges where they got. 30 keeps
/// the fit under 50 ms on 10⁴ samples of every real log (docs/BENCHMARKS.md).
const MAX_LM_STEPS: usize = 30;

/// Inclinations steeper than this leave almost no horizontal field to steer by.
const MAX_INCLINATION_DEG: f64 = 85.0;

/// Why a plane calibration could not be fitted. Messages say what the user can do.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum PlaneError {
    #[error("too few magnetometer samples ({n_samples}; at least {min} are needed). Record longer, turning through a full circle.")]
    TooFewSamples { n_samples: usize, min: usize },

    #[error("{n_mag} magnetometer samples but {n_tilt} tilts: give one roll/pitch per magnetometer sample (interpolate the accelerometer onto the magnetometer's times).")]
    LengthMismatch { n_mag: usize, n_tilt: usize },

    #[error("sample {sample_idx} is not a finite number (magnetometer or tilt). Remove NaN or infinite values from the input.")]
    NonFinite { sample_idx: usize },

    #[error("the inclination {inclination_deg}° is not usable: give the dip of the local field between −{max_deg}° and {max_deg}°, or none to estimate it.", max_deg = MAX_INCLINATION_DEG)]
    InvalidInclination { inclination_deg: f64 },

    #[error("no data from {gap_from_deg:.0}° clockwise to {gap_to_deg:.0}° magnetic heading ({width_deg:.0}° of the circle never faced): turn that way too (a full circle) and record again.", width_deg = crate::base::angle::clockwise_arc_deg(*.gap_from_deg, *.gap_to_deg))]
    NoTurn { gap_from_deg: f64, gap_to_deg: f64 },

    #[error("the levelled field does not trace an ellipse ({reason}). Turn through a full circle, away from iron and electronics that move with you, and check that the magnetometer values change as you turn.")]
    DegenerateConic { reason: &'static str },

    #[error("the levelled field traces an ellipse {axis_ratio:.1} times longer than wide, which is not soft iron but a partial turn or a changing disturbance. Turn through a full circle, away from moving iron.")]
    TooElongated { axis_ratio: f64 },

    #[error("the samples do not follow one field turned through every heading (residual {residual_rms_ut:.1} µT against a horizontal field of {horizontal_field_ut:.1} µT). Turn the device rather than only tilting it, stay away from moving iron, and check that each roll/pitch belongs to the magnetometer sample at the same time.")]
    PoorFit {
        residual_rms_ut: f64,
        horizontal_field_ut: f64,
    },

    #[error("the tilt-aware fit did not settle ({reason}). Check that each roll/pitch belongs to the magnetometer sample at the same time, and that the data comes from one place.")]
    NotConverged { reason: String },
}

/// What [`fit_plane`] may assume.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PlaneOptions {
    /// The expected inclination (dip) of the Earth's field, degrees, positive when the
    /// field points down (northern hemisphere), e.g. from a field model. `None`
    /// estimates the vertical field from the tilt instead.
    pub inclination_deg: Option<f64>,
    /// The widest arc of magnetic heading without samples that the fit accepts.
    pub max_heading_gap_deg: f64,
}

impl Default for PlaneOptions {
    fn default() -> Self {
        PlaneOptions {
            inclination_deg: None,
            max_heading_gap_deg: 90.0,
        }
    }
}

/// The soft-iron model behind a [`PlaneFit`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum SoftIronModel {
    /// The full symmetric matrix `A`.
    Full,
    /// `A` = identity ([`crate::fit::ellipse_isotropic`]), because the full fit scaled one
    /// axis more than [`MAX_AXIS_RATIO`] times another (`full_axis_ratio`, the ratio of
    /// its largest to smallest eigenvalue) or was not positive definite (`None`). The
    /// vertical hard iron then rests on the given inclination when there is one.
    Isotropic { full_axis_ratio: Option<f64> },
}

/// The tilt-aware calibration and how well it fits.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PlaneFit {
    /// The hard iron `h` in the body frame, subtracted before levelling.
    pub hard_iron_ut: Vector3<f64>,
    /// The correction `A = S⁻¹` (symmetric, dimensionless), applied before levelling.
    pub soft_iron: Matrix3<f64>,
    /// The level-plane form of the model, for `level(mag − hard_iron)`: exact when
    /// level (see the module header).
    pub plane: PlaneCalibration,
    /// The corrected horizontal field `H` (the radius of `plane`).
    pub horizontal_field_ut: f64,
    /// The corrected vertical field `V`, positive down.
    pub vertical_field_ut: f64,
    /// `atan(V / H)`: estimated, or the one given.
    pub inclination_deg: f64,
    /// Which soft-iron model the fit kept: the full symmetric matrix, or the isotropic
    /// one when the full fit was implausible (see [`SoftIronModel`]).
    pub soft_iron_model: SoftIronModel,
    /// Whether the tilt varied enough to estimate `A_zz` (and, without an inclination,
    /// `h_z`); when not, they are held at 1 and 0, which is exact for level use only.
    pub vertical_estimated: bool,
    /// Spread of roll and pitch in the data (standard deviations, combined).
    pub tilt_spread_deg: f64,
    /// RMS of both residuals (horizontal circle and constant vertical field).
    pub residual_rms_ut: f64,
    /// Standard deviation of the corrected horizontal magnitude.
    pub horizontal_magnitude_std_ut: f64,
    /// Heading coverage of the corrected samples (magnetic).
    pub coverage: Coverage,
    pub n_samples: usize,
}

impl PlaneFit {
    /// The corrected, levelled field `(Xh, Yh)` of a raw sample at a tilt.
    pub fn level_corrected_ut(&self, mag_ut: Vector3<f64>, tilt: Tilt) -> Vector2<f64> {
        tilt.level(self.soft_iron * (mag_ut - self.hard_iron_ut))
    }

    /// The heading of a raw sample at a tilt, clockwise from north, in `[0, 2π)`, with
    /// the declination (true north from magnetic north, east positive) added.
    pub fn heading_rad(&self, mag_ut: Vector3<f64>, tilt: Tilt, declination_rad: f64) -> f64 {
        compass_heading::heading_rad(self.level_corrected_ut(mag_ut, tilt), declination_rad)
    }
}

/// Fits the tilt-aware plane calibration to magnetometer samples (µT, body frame) and
/// the tilt at each of them.
pub fn fit_plane(
    mag_ut: &[Vector3<f64>],
    tilt: &[Tilt],
    options: &PlaneOptions,
) -> Result<PlaneFit, PlaneError> {
    let tan_inclination = checked_inputs(mag_ut, tilt, options)?;
    let levelling: Vec<Matrix3<f64>> = tilt.iter().map(levelling_rotation).collect();
    let level_raw_ut: Vec<Vector2<f64>> = mag_ut
        .iter()
        .zip(tilt)
        .map(|(&mag, tilt)| tilt.level(mag))
        .collect();

    // Step 1: the conic of the levelled raw field. Its centre and shape are blurred by
    // the hard iron's leak, but they start the refinement close enough.
    let start = direct_ellipse_fit(&level_raw_ut)?.to_plane_calibration()?;

    let tilt_spread_deg = tilt_spread_rad(tilt).to_degrees();
    let vertical_estimated = tilt_spread_deg >= MIN_TILT_SPREAD_DEG;

    // Step 2: the tilt-aware model. The start's transform has determinant 1, so it is
    // the in-plane block of a dimensionless `A`; `H` is the start's radius.
    let horizontal_field_ut = start.radius_ut;
    let (mut full, free) = tilt_aware_start(
        &start,
        mag_ut,
        &levelling,
        tan_inclination,
        vertical_estimated,
    );
    let problem = TiltAwareProblem {
        mag_ut,
        levelling: &levelling,
        horizontal_field_ut,
    };
    // Running out of steps still leaves the best parameters found; the residual check
    // below judges them like any other.
    normal_lm::minimize_thinned_then_all(
        &mut full,
        &free,
        mag_ut.len(),
        MAX_LM_STEPS,
        |full, stride| problem.normal_equations(full, stride),
    )
    .map_err(|reason| PlaneError::NotConverged {
        reason: reason.to_string(),
    })?;
    if !full.iter().all(|value| value.is_finite()) {
        return Err(PlaneError::NotConverged {
            reason: "the parameters became infinite".to_string(),
        });
    }

    // Step 3: the scale gauge. `S = A⁻¹`; scaling `A`, `H` and `V` by `k` changes no
    // heading, and `k = √det(S_hh)` makes the level-plane correction `S_hh⁻¹` preserve
    // area.
    let soft_iron = soft_iron_of(&full);
    let eigen = SymmetricEigen::new(soft_iron);
    let positive_definite = eigen
        .eigenvalues
        .iter()
        .all(|&value| value.is_finite() && value > 0.0);
    // Real soft iron changes the axes by tens of per cent; a correction that scales one
    // axis several times more than another has traded the vertical residual for field
    // disturbances. The isotropic model (see `ellipse_isotropic`) is then the honest one.
    let full_axis_ratio =
        positive_definite.then(|| eigen.eigenvalues.max() / eigen.eigenvalues.min());
    if full_axis_ratio.is_none_or(|axis_ratio| axis_ratio > MAX_AXIS_RATIO) {
        let fit = isotropic_fit(
            mag_ut,
            &levelling,
            &start,
            tan_inclination,
            vertical_estimated,
            tilt_spread_deg,
            full_axis_ratio,
        )?;
        return checked(fit, mag_ut, &levelling, options);
    }
    let fit = gauged_fit(
        soft_iron,
        &full,
        horizontal_field_ut,
        vertical_estimated,
        tilt_spread_deg,
        mag_ut.len(),
    )?;
    checked(fit, mag_ut, &levelling, options)
}

/// The inputs' checks: as many tilts as samples, enough samples, all finite, a usable
/// inclination; the inclination's tangent when the model's dip is given.
fn checked_inputs(
    mag_ut: &[Vector3<f64>],
    tilt: &[Tilt],
    options: &PlaneOptions,
) -> Result<Option<f64>, PlaneError> {
    if mag_ut.len() != tilt.len() {
        return Err(PlaneError::LengthMismatch {
            n_mag: mag_ut.len(),
            n_tilt: tilt.len(),
        });
    }
    if mag_ut.len() < MIN_SAMPLES {
        return Err(PlaneError::TooFewSamples {
            n_samples: mag_ut.len(),
            min: MIN_SAMPLES,
        });
    }
    if let Some(sample_idx) = mag_ut.iter().zip(tilt).position(|(mag, tilt)| {
        !(mag.iter().all(|value| value.is_finite())
            && tilt.roll_rad().is_finite()
            && tilt.pitch_rad().is_finite())
    }) {
        return Err(PlaneError::NonFinite { sample_idx });
    }
    match options.inclination_deg {
        None => Ok(None),
        Some(inclination_deg)
            if inclination_deg.is_finite() && inclination_deg.abs() <= MAX_INCLINATION_DEG =>
        {
            Ok(Some(inclination_deg.to_radians().tan()))
        }
        Some(inclination_deg) => Err(PlaneError::InvalidInclination { inclination_deg }),
    }
}

/// Step 2's start and free parameters: the conic's in-plane shape and centre, `A_zz = 1`,
/// and the vertical from the model's dip when it is given (then `h_z` from the mean
/// levelled vertical field), else from the samples.
fn tilt_aware_start(
    start: &PlaneCalibration,
    mag_ut: &[Vector3<f64>],
    levelling: &[Matrix3<f64>],
    tan_inclination: Option<f64>,
    vertical_estimated: bool,
) -> ([f64; N_PARAMS], Vec<usize>) {
    let horizontal_field_ut = start.radius_ut;
    let mut full = [0.0; N_PARAMS];
    full[A_XX] = start.transform[(0, 0)];
    full[A_YY] = start.transform[(1, 1)];
    full[A_XY] = start.transform[(0, 1)];
    full[A_ZZ] = 1.0;
    full[H_X] = start.center_ut.x;
    full[H_Y] = start.center_ut.y;
    let mut free: Vec<usize> = vec![A_XX, A_YY, A_XY, A_XZ, A_YZ, H_X, H_Y];
    match tan_inclination {
        Some(tan_inclination) => {
            // With the dip known, the level part of the vertical residual fixes `h_z`
            // from the mean levelled vertical field.
            full[V] = horizontal_field_ut * tan_inclination;
            let mean_level_z_ut = mag_ut
                .iter()
                .zip(levelling)
                .map(|(mag, levelling)| (levelling * mag).z)
                .sum::<f64>()
                / mag_ut.len() as f64;
            full[H_Z] = mean_level_z_ut - full[V];
            free.push(H_Z);
        }
        None => {
            full[V] = mean_vertical_ut(mag_ut, levelling, &full);
            free.push(V);
            if vertical_estimated {
                free.push(H_Z);
            }
        }
    }
    if vertical_estimated {
        free.push(A_ZZ);
    }
    (full, free)
}

/// The isotropic model's fit (see `ellipse_isotropic`), for when the full one scales one
/// axis far more than another.
fn isotropic_fit(
    mag_ut: &[Vector3<f64>],
    levelling: &[Matrix3<f64>],
    start: &PlaneCalibration,
    tan_inclination: Option<f64>,
    vertical_estimated: bool,
    tilt_spread_deg: f64,
    full_axis_ratio: Option<f64>,
) -> Result<PlaneFit, PlaneError> {
    let vertical = match (tan_inclination, vertical_estimated) {
        (Some(tan_inclination), _) => Vertical::ModelDip { tan_inclination },
        (None, true) => Vertical::Free,
        (None, false) => Vertical::Held,
    };
    let isotropic = fit_isotropic(
        mag_ut,
        levelling,
        Vector3::new(start.center_ut.x, start.center_ut.y, 0.0),
        start.radius_ut,
        vertical,
    )?;
    Ok(PlaneFit {
        hard_iron_ut: isotropic.hard_iron_ut,
        soft_iron: Matrix3::identity(),
        plane: PlaneCalibration {
            center_ut: Vector2::zeros(),
            transform: Matrix2::identity(),
            radius_ut: isotropic.horizontal_field_ut,
        },
        horizontal_field_ut: isotropic.horizontal_field_ut,
        vertical_field_ut: isotropic.vertical_field_ut,
        inclination_deg: isotropic
            .vertical_field_ut
            .atan2(isotropic.horizontal_field_ut)
            .to_degrees(),
        soft_iron_model: SoftIronModel::Isotropic { full_axis_ratio },
        vertical_estimated,
        tilt_spread_deg,
        residual_rms_ut: 0.0,
        horizontal_magnitude_std_ut: 0.0,
        coverage: Coverage::of_headings(std::iter::empty()),
        n_samples: mag_ut.len(),
    })
}

/// Step 3's result: the soft iron scaled so that the level-plane correction preserves
/// area (`k = √det(S_hh)`), with the fields and the plane's calibration in that gauge.
fn gauged_fit(
    soft_iron: Matrix3<f64>,
    full: &[f64; N_PARAMS],
    horizontal_field_ut: f64,
    vertical_estimated: bool,
    tilt_spread_deg: f64,
    n_samples: usize,
) -> Result<PlaneFit, PlaneError> {
    let distortion = soft_iron.try_inverse().ok_or(PlaneError::DegenerateConic {
        reason: "the fitted soft iron is singular",
    })?;
    let distortion_hh: Matrix2<f64> = distortion.fixed_view::<2, 2>(0, 0).into_owned();
    let scale = distortion_hh.determinant().sqrt();
    if !(scale.is_finite() && scale > 0.0) {
        return Err(PlaneError::DegenerateConic {
            reason: "the fitted horizontal distortion is singular",
        });
    }
    let soft_iron = soft_iron * scale;
    let horizontal_field_ut = horizontal_field_ut * scale;
    let vertical_field_ut = full[V] * scale;
    let distortion_hh = distortion_hh / scale;
    let transform = distortion_hh
        .try_inverse()
        .ok_or(PlaneError::DegenerateConic {
            reason: "the fitted horizontal distortion is singular",
        })?;
    let distortion_hz = Vector2::new(distortion[(0, 2)], distortion[(1, 2)]) / scale;
    let hard_iron_ut = Vector3::new(full[H_X], full[H_Y], full[H_Z]);

    Ok(PlaneFit {
        hard_iron_ut,
        soft_iron,
        plane: PlaneCalibration {
            center_ut: distortion_hz * vertical_field_ut,
            transform,
            radius_ut: horizontal_field_ut,
        },
        horizontal_field_ut,
        vertical_field_ut,
        inclination_deg: vertical_field_ut.atan2(horizontal_field_ut).to_degrees(),
        soft_iron_model: SoftIronModel::Full,
        vertical_estimated,
        tilt_spread_deg,
        residual_rms_ut: 0.0,
        horizontal_magnitude_std_ut: 0.0,
        coverage: Coverage::of_headings(std::iter::empty()),
        n_samples,
    })
}

/// Fills in how well `fit` follows the samples, and refuses it when it does not (the
/// residual, the heading coverage).
fn checked(
    mut fit: PlaneFit,
    mag_ut: &[Vector3<f64>],
    levelling: &[Matrix3<f64>],
    options: &PlaneOptions,
) -> Result<PlaneFit, PlaneError> {
    let horizontal_field_ut = fit.horizontal_field_ut;
    let vertical_field_ut = fit.vertical_field_ut;
    let level_corrected_ut: Vec<Vector3<f64>> = mag_ut
        .iter()
        .zip(levelling)
        .map(|(&mag, levelling)| levelling * (fit.soft_iron * (mag - fit.hard_iron_ut)))
        .collect();
    let n_samples = mag_ut.len() as f64;
    let magnitudes_ut: Vec<f64> = level_corrected_ut
        .iter()
        .map(|level| level.xy().norm())
        .collect();
    let mean_magnitude_ut = magnitudes_ut.iter().sum::<f64>() / n_samples;
    fit.horizontal_magnitude_std_ut = (magnitudes_ut
        .iter()
        .map(|magnitude| (magnitude - mean_magnitude_ut).powi(2))
        .sum::<f64>()
        / n_samples)
        .sqrt();
    fit.residual_rms_ut = (level_corrected_ut
        .iter()
        .zip(&magnitudes_ut)
        .map(|(level, magnitude)| {
            (magnitude - horizontal_field_ut).powi(2) + (level.z - vertical_field_ut).powi(2)
        })
        .sum::<f64>()
        / (2.0 * n_samples))
        .sqrt();
    fit.coverage = Coverage::of_headings(
        level_corrected_ut
            .iter()
            .map(|level| compass_heading::heading_rad(level.xy(), 0.0).to_degrees()),
    );
    let relative_limit = match fit.soft_iron_model {
        SoftIronModel::Full => MAX_RELATIVE_RESIDUAL,
        SoftIronModel::Isotropic { .. } => MAX_RELATIVE_RESIDUAL_ISOTROPIC,
    };
    let residual_limit_ut = relative_limit * horizontal_field_ut;
    if fit.residual_rms_ut.is_nan() || fit.residual_rms_ut > residual_limit_ut {
        return Err(PlaneError::PoorFit {
            residual_rms_ut: fit.residual_rms_ut,
            horizontal_field_ut,
        });
    }
    if fit.coverage.largest_gap_deg > options.max_heading_gap_deg {
        return Err(PlaneError::NoTurn {
            gap_from_deg: fit.coverage.largest_gap_start_deg,
            gap_to_deg: (fit.coverage.largest_gap_start_deg + fit.coverage.largest_gap_deg)
                .rem_euclid(360.0),
        });
    }
    Ok(fit)
}

/// The levelling rotation `T = Ry(θ)·Rx(φ)`: its first two rows are Eq. 4 as
/// [`Tilt::level`] computes it, the third the vertical component.
fn levelling_rotation(tilt: &Tilt) -> Matrix3<f64> {
    let (sin_roll, cos_roll) = tilt.roll_sin_cos();
    let (sin_pitch, cos_pitch) = tilt.pitch_sin_cos();
    Matrix3::new(
        cos_pitch,
        sin_roll * sin_pitch,
        cos_roll * sin_pitch,
        0.0,
        cos_roll,
        -sin_roll,
        -sin_pitch,
        sin_roll * cos_pitch,
        cos_roll * cos_pitch,
    )
}

/// The combined standard deviation of roll and pitch: what separates the vertical hard
/// iron from the vertical field.
fn tilt_spread_rad(tilt: &[Tilt]) -> f64 {
    let n_samples = tilt.len().max(1) as f64;
    let mean_roll_rad = tilt.iter().map(Tilt::roll_rad).sum::<f64>() / n_samples;
    let mean_pitch_rad = tilt.iter().map(Tilt::pitch_rad).sum::<f64>() / n_samples;
    (tilt
        .iter()
        .map(|tilt| {
            (tilt.roll_rad() - mean_roll_rad).powi(2) + (tilt.pitch_rad() - mean_pitch_rad).powi(2)
        })
        .sum::<f64>()
        / n_samples)
        .sqrt()
}

/// The mean corrected vertical field for the parameters `full`: the start of `V`.
fn mean_vertical_ut(
    mag_ut: &[Vector3<f64>],
    levelling: &[Matrix3<f64>],
    full: &[f64; N_PARAMS],
) -> f64 {
    let soft_iron = soft_iron_of(full);
    let hard_iron_ut = Vector3::new(full[H_X], full[H_Y], full[H_Z]);
    mag_ut
        .iter()
        .zip(levelling)
        .map(|(&mag, levelling)| (levelling * (soft_iron * (mag - hard_iron_ut))).z)
        .sum::<f64>()
        / mag_ut.len().max(1) as f64
}

// The parameters of the tilt-aware model, in this order: the six entries of the
// symmetric `A`, the hard iron, and the vertical field.
const A_XX: usize = 0;
const A_YY: usize = 1;
const A_ZZ: usize = 2;
const A_XY: usize = 3;
const A_XZ: usize = 4;
const A_YZ: usize = 5;
const H_X: usize = 6;
const H_Y: usize = 7;
const H_Z: usize = 8;
const V: usize = 9;
const N_PARAMS: usize = 10;

fn soft_iron_of(full: &[f64; N_PARAMS]) -> Matrix3<f64> {
    Matrix3::new(
        full[A_XX], full[A_XY], full[A_XZ], //
        full[A_XY], full[A_YY], full[A_YZ], //
        full[A_XZ], full[A_YZ], full[A_ZZ],
    )
}

/// The residuals of the module header, two per sample.
struct TiltAwareProblem<'a> {
    mag_ut: &'a [Vector3<f64>],
    levelling: &'a [Matrix3<f64>],
    horizontal_field_ut: f64,
}

impl TiltAwareProblem<'_> {
    /// One sample's two residuals (horizontal, vertical) and their gradients with
    /// respect to every parameter, for the soft and hard iron of `full`.
    fn sample_rows(
        &self,
        full: &[f64; N_PARAMS],
        soft_iron: &Matrix3<f64>,
        mag_ut: &Vector3<f64>,
        levelling: &Matrix3<f64>,
    ) -> [(f64, [f64; N_PARAMS]); 2] {
        let hard_iron_ut = Vector3::new(full[H_X], full[H_Y], full[H_Z]);
        // `d = m − h` and the levelled corrected field `l = T·A·d`.
        let d = mag_ut - hard_iron_ut;
        let level = levelling * (soft_iron * d);
        // The horizontal residual moves along the unit horizontal direction `u` of `l`;
        // at the origin it has no direction and no derivative.
        let horizontal_norm = level.xy().norm();
        let direction = if horizontal_norm > 0.0 {
            level.xy() / horizontal_norm
        } else {
            Vector2::zeros()
        };
        // A residual `uᵀ·l` (`u` = the horizontal direction, or the vertical `e_z`) has,
        // with `a = Tᵀ·u` in body axes, `∂/∂A_jk = aᵀ·E_jk·d` (E_jk the symmetric basis
        // matrix) and `∂/∂h = −A·a`.
        let row = |a: Vector3<f64>| {
            let minus_soft_iron_a = -(soft_iron * a);
            let mut gradient = [0.0; N_PARAMS];
            gradient[A_XX] = a.x * d.x;
            gradient[A_YY] = a.y * d.y;
            gradient[A_ZZ] = a.z * d.z;
            gradient[A_XY] = a.x * d.y + a.y * d.x;
            gradient[A_XZ] = a.x * d.z + a.z * d.x;
            gradient[A_YZ] = a.y * d.z + a.z * d.y;
            gradient[H_X] = minus_soft_iron_a.x;
            gradient[H_Y] = minus_soft_iron_a.y;
            gradient[H_Z] = minus_soft_iron_a.z;
            gradient
        };
        let horizontal =
            row(levelling.row(0).transpose() * direction.x
                + levelling.row(1).transpose() * direction.y);
        let mut vertical = row(levelling.row(2).transpose());
        vertical[V] = -1.0;
        [
            (horizontal_norm - self.horizontal_field_ut, horizontal),
            (level.z - full[V], vertical),
        ]
    }

    /// The normal equations of every `stride`-th sample's residuals at `full`, in one
    /// pass over the samples.
    fn normal_equations(&self, full: &[f64; N_PARAMS], stride: usize) -> Option<Normal<N_PARAMS>> {
        let soft_iron = soft_iron_of(full);
        let mut normal = Normal::zeros();
        for (mag_ut, levelling) in self.mag_ut.iter().zip(self.levelling).step_by(stride) {
            normal.add_pair(&self.sample_rows(full, &soft_iron, mag_ut, levelling));
        }
        normal.finished()
    }
}

#[cfg(test)]
mod tests;
