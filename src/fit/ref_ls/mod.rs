//! Reference-heading least squares: Eq. 8 fitted to headings known from elsewhere.
//!
//! Source: Moafipoor et al. (2007), Eq. 6 and 8. With a reference heading for every
//! levelled sample (GPS course over ground while moving straight, a calibrated gyro, a
//! map's street direction), the axis scale factors and biases of Eq. 6 can be fitted to
//! the compass deviation directly instead of to the shape of the circle. The paper
//! notes that this least squares "requires good initial values; otherwise, the
//! computation could easily lead to divergence" and points to the two-step estimators
//! of Haupt et al. (1996) and Gebre-Egziabher et al. (2001): first a linear least
//! squares on a reparametrised problem, then the physical parameters from its solution.
//! This file does that, then refines by Levenberg-Marquardt.
//!
//! ## Eq. 8 in this crate's convention
//!
//! The paper writes `α = tan⁻¹((Sy·Hy + By) / (Sx·Hx + Bx))`, with its sensor's y axis
//! the other way round. With the body y axis to the right and headings clockwise
//! (see [`crate::attitude::compass_heading`]) it reads
//!
//! ```text
//! ψ = atan2(−(Sy·Yh + By), Sx·Xh + Bx) + D
//! ```
//!
//! where `(Xh, Yh)` is the levelled field (Eq. 4), `(Sx·Xh + Bx, Sy·Yh + By)` the
//! corrected one (Eq. 6), and `D` the declination, given or estimated (below). `By`
//! therefore has the opposite sign of the paper's for the same installation.
//!
//! Headings do not depend on the overall scale: multiplying `Sx, Sy, Bx, By` by the
//! same factor changes no heading. The fit fixes that freedom with `Sx·Sy = 1`, so the
//! corrected circle has the area of the raw ellipse and `Bx, By` are in µT of that
//! circle. (Min/max, Eq. 7, fixes it differently: the smaller of `Sx, Sy` is 1.)
//!
//! ## The offset
//!
//! With [`RefLsOptions::declination_rad`] given, `D` is that declination and three
//! parameters are fitted. Without it, `D` is a fourth parameter: a constant heading
//! offset that absorbs the declination, a yaw misalignment between sensor and body,
//! and any constant bias of the reference. Reported headings then follow the
//! reference's north.
//!
//! ## Step 1: a linear problem
//!
//! A heading `ψ` means the corrected vector is parallel to `(cos(ψ − D), −sin(ψ − D))`:
//! its cross product with that direction vanishes,
//!
//! ```text
//! (Sx·Xh + Bx)·sin(ψ − D) + (Sy·Yh + By)·cos(ψ − D) = 0.
//! ```
//!
//! With `D` known this is linear and homogeneous in `(Sx, Sy, Bx, By)`, with rows
//! `(Xh·sin ψm, Yh·cos ψm, sin ψm, cos ψm)`, `ψm = ψ − D`. With `D` unknown, expanding
//! the sines makes it linear in the six products
//! `(Sx·cos D, Sx·sin D, Sy·cos D, Sy·sin D, γ1, γ2)`, with rows
//! `(Xh·sin ψ, −Xh·cos ψ, Yh·cos ψ, Yh·sin ψ, sin ψ, cos ψ)`, where
//! `γ = R(−D)·(Bx, By)` is the bias rotated by the offset (only that combination
//! appears; eight products would leave a three-dimensional null space). Either way
//! the solution is the eigenvector of the normal matrix with the smallest eigenvalue
//! (total least squares, on columns scaled to unit RMS).
//!
//! ## Step 2: the parameters, algebraically
//!
//! `(Sx, Sy)·(cos D, sin D)` is a rank-one 2×2 matrix: its dominant singular vectors
//! give `D` and `Sx, Sy`, and `(Bx, By) = R(D)·γ`. The cross product cannot tell a
//! vector from its opposite, so the sign (or, with `D` estimated, `D` against `D + π`)
//! is chosen so that the headings point along the references. `Sx` and `Sy` of
//! opposite signs mean a mirrored axis, which is refused.
//!
//! ## Step 3: the heading residual
//!
//! Levenberg-Marquardt then minimises the wrapped heading errors themselves (step 1
//! weights each sample by its field magnitude and is biased by noise), over
//! `(ln Sx, Bx, By[, D])` with `Sy = 1/Sx`.
//!
//! How much the start matters (the tests measure it): with the declination known, the
//! damped, trust-region refinement alone converges from the identity even with a 40 µT
//! hard iron, and the two-step start only saves iterations (5 evaluations instead of
//! 12). With the offset estimated and a sensor mounted a quarter turn off, the identity
//! start ends in a wrong minimum in about half of the noise draws; the two-step start,
//! which needs no guess, never does.
//!
//! ## Limits
//!
//! The model is Eq. 6: axis scale factors and biases in the level plane, no cross-axis
//! soft iron and no tilt leakage of the hard iron (see [`crate::fit::ellipse`] for both); it
//! absorbs what it can of them into the four parameters. The references must spread
//! over headings (a gap larger than [`RefLsOptions::max_heading_gap_deg`] is refused)
//! and belong to the same instants as the field samples; reference noise averages out
//! over many samples, a reference lag while turning does not.
//!
//! References over a few headings only can still be used on top of a calibration
//! already made (the analysis takes the best 3D one): the fit then starts from the
//! identity and priors ([`RefLsOptions::prior`], [`PartialPrior`]) hold what those
//! headings cannot see, so that they fix only what they can.

use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt};
use nalgebra::{DMatrix, DVector, Dyn, Matrix2, Owned, SymmetricEigen, Vector2};
use serde::Serialize;
use thiserror::Error;

use crate::attitude::compass_heading;
use crate::base::angle::wrap_to_pi;
use crate::fit::minmax::Coverage;
use crate::fit::model::PlaneCalibration;

/// Fewer samples than this leave the four parameters with little redundancy.
pub const MIN_SAMPLES: usize = 10;

/// A second-smallest eigenvalue of the (scaled) normal matrix below this share of the
/// largest means the linear problem has more than one solution.
const MIN_EIGENVALUE_GAP: f64 = 1e-10;

/// Why a reference-heading fit could not be made. Messages say what the user can do.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum RefLsError {
    #[error("too few samples with a reference heading ({n_samples}; at least {min} are needed). Record longer, with reference headings over a full circle.")]
    TooFewSamples { n_samples: usize, min: usize },

    #[error("{n_level} field samples but {n_ref} reference headings: give one reference heading per levelled field sample.")]
    LengthMismatch { n_level: usize, n_ref: usize },

    #[error("sample {sample_idx} is not a finite number (field or reference heading). Remove NaN or infinite values from the input.")]
    NonFinite { sample_idx: usize },

    #[error("the declination {declination_rad} rad is not a finite number: give the local declination, or none to estimate a heading offset.")]
    InvalidDeclination { declination_rad: f64 },

    #[error("no reference heading from {gap_from_deg:.0}° clockwise to {gap_to_deg:.0}° ({width_deg:.0}° of the circle never faced): turn that way too (a full circle) and record again.", width_deg = crate::base::angle::clockwise_arc_deg(*.gap_from_deg, *.gap_to_deg))]
    NoTurn { gap_from_deg: f64, gap_to_deg: f64 },

    #[error("the field samples and reference headings do not determine a calibration ({reason}). Check that the field changes as the reference heading changes, and that both come from the same times.")]
    Degenerate { reason: &'static str },

    #[error("the field turns the opposite way to the reference headings (a mirrored axis). Check that the body y axis points right and that reference headings are clockwise from north.")]
    Mirrored,

    #[error("the least squares did not settle ({reason}). Check that the reference headings belong to the field samples at the same times.")]
    NotConverged { reason: String },
}

/// What [`fit_reference_ls`] may assume.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RefLsOptions {
    /// The declination (true north from magnetic north, east positive) when the
    /// reference headings are from true north and it is known; `None` estimates a
    /// constant heading offset instead (see the module header).
    pub declination_rad: Option<f64>,
    /// The widest arc of reference heading without samples that the full fit accepts.
    /// Beyond it, the fit is refused without a `prior`, and made with one.
    pub max_heading_gap_deg: f64,
    /// For references over a few headings only: the fit starts from the identity (the
    /// levelled field is then that of a calibration already made) and each parameter
    /// is held near it by a prior, so that the headings fix what they can see and the
    /// rest stays put. See [`PartialPrior`].
    pub prior: Option<PartialPrior>,
}

impl Default for RefLsOptions {
    fn default() -> Self {
        RefLsOptions {
            declination_rad: None,
            max_heading_gap_deg: 90.0,
            prior: None,
        }
    }
}

/// The priors of a partial-coverage fit, about the identity (`Sx = Sy = 1`, `B = 0`)
/// and the declination.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PartialPrior {
    /// Of `ln Sx` (a fraction of scale).
    pub log_scale_std: f64,
    /// Of each bias, as a fraction of the horizontal field.
    pub bias_std_of_field: f64,
    /// Of the heading offset about the declination (rad): it takes the misalignment
    /// between device and direction of travel, which few headings see best of all.
    pub offset_std_rad: f64,
}

impl Default for PartialPrior {
    fn default() -> Self {
        PartialPrior {
            log_scale_std: 0.05,
            bias_std_of_field: 0.05,
            offset_std_rad: 10f64.to_radians(),
        }
    }
}

/// The Eq. 6 parameters fitted to reference headings, in the gauge `Sx·Sy = 1`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RefLsFit {
    pub scale_x: f64,
    pub scale_y: f64,
    pub bias_x_ut: f64,
    pub bias_y_ut: f64,
    /// Added to the magnetic heading: the declination given, or the estimated offset.
    pub heading_offset_rad: f64,
    pub heading_offset_estimated: bool,
    /// Mean magnitude of the corrected horizontal field.
    pub horizontal_field_ut: f64,
    /// RMS of the heading errors against the references.
    pub residual_rms_deg: f64,
    /// Coverage of the reference headings.
    pub coverage: Coverage,
    pub n_samples: usize,
    /// Whether the references covered too little of the circle for the full fit, so
    /// that the priors of [`RefLsOptions::prior`] held what they could not see.
    pub partial: bool,
}

impl RefLsFit {
    /// Eq. 6: the corrected levelled field of a levelled sample.
    pub fn apply(&self, level_ut: Vector2<f64>) -> Vector2<f64> {
        Vector2::new(
            self.scale_x * level_ut.x + self.bias_x_ut,
            self.scale_y * level_ut.y + self.bias_y_ut,
        )
    }

    /// Eq. 8: the heading of a levelled sample, clockwise from the references' north
    /// (true north when the declination was given), in `[0, 2π)`.
    pub fn heading_rad(&self, level_ut: Vector2<f64>) -> f64 {
        compass_heading::heading_rad(self.apply(level_ut), self.heading_offset_rad)
    }

    /// The same correction as a [`PlaneCalibration`] (`corrected = diag(S)·(level −
    /// center)` with `center = −B/S`); the heading offset is not part of it.
    pub fn plane_calibration(&self) -> PlaneCalibration {
        PlaneCalibration {
            center_ut: Vector2::new(
                -self.bias_x_ut / self.scale_x,
                -self.bias_y_ut / self.scale_y,
            ),
            transform: Matrix2::new(self.scale_x, 0.0, 0.0, self.scale_y),
            radius_ut: self.horizontal_field_ut,
        }
    }
}

/// Fits Eq. 8 to levelled field samples (µT) and the reference heading of each (rad,
/// clockwise from true north, or from whatever north the references use when the
/// offset is estimated).
pub fn fit_reference_ls(
    level_ut: &[Vector2<f64>],
    ref_heading_rad: &[f64],
    options: &RefLsOptions,
) -> Result<RefLsFit, RefLsError> {
    if level_ut.len() != ref_heading_rad.len() {
        return Err(RefLsError::LengthMismatch {
            n_level: level_ut.len(),
            n_ref: ref_heading_rad.len(),
        });
    }
    if level_ut.len() < MIN_SAMPLES {
        return Err(RefLsError::TooFewSamples {
            n_samples: level_ut.len(),
            min: MIN_SAMPLES,
        });
    }
    if let Some(sample_idx) = level_ut
        .iter()
        .zip(ref_heading_rad)
        .position(|(level, heading)| {
            !(level.x.is_finite() && level.y.is_finite() && heading.is_finite())
        })
    {
        return Err(RefLsError::NonFinite { sample_idx });
    }
    if let Some(declination_rad) = options.declination_rad {
        if !declination_rad.is_finite() {
            return Err(RefLsError::InvalidDeclination { declination_rad });
        }
    }
    let coverage =
        Coverage::of_headings(ref_heading_rad.iter().map(|heading| heading.to_degrees()));
    let partial = coverage.largest_gap_deg > options.max_heading_gap_deg;
    let (params, report) = match (partial, options.prior) {
        (true, None) => {
            return Err(RefLsError::NoTurn {
                gap_from_deg: coverage.largest_gap_start_deg,
                gap_to_deg: (coverage.largest_gap_start_deg + coverage.largest_gap_deg)
                    .rem_euclid(360.0),
            })
        }
        (true, Some(prior)) => refine_partial(level_ut, ref_heading_rad, options, prior),
        (false, _) => {
            let start = two_step_start(level_ut, ref_heading_rad, options.declination_rad)?;
            refine(level_ut, ref_heading_rad, options.declination_rad, start)
        }
    };
    if !(report.termination.was_successful()
        || report.termination == levenberg_marquardt::TerminationReason::LostPatience)
    {
        return Err(RefLsError::NotConverged {
            reason: format!("{:?}", report.termination),
        });
    }
    if !params.is_finite() {
        return Err(RefLsError::NotConverged {
            reason: "the parameters became infinite".to_string(),
        });
    }

    let mut fit = RefLsFit {
        scale_x: params.scale_x(),
        scale_y: params.scale_y(),
        bias_x_ut: params.bias_ut.x,
        bias_y_ut: params.bias_ut.y,
        heading_offset_rad: params.offset_rad,
        heading_offset_estimated: options.declination_rad.is_none() || partial,
        horizontal_field_ut: 0.0,
        residual_rms_deg: 0.0,
        coverage,
        n_samples: level_ut.len(),
        partial,
    };
    let n_samples = level_ut.len() as f64;
    fit.horizontal_field_ut = level_ut
        .iter()
        .map(|&level| fit.apply(level).norm())
        .sum::<f64>()
        / n_samples;
    fit.residual_rms_deg = (level_ut
        .iter()
        .zip(ref_heading_rad)
        .map(|(&level, &reference)| wrap_to_pi(fit.heading_rad(level) - reference).powi(2))
        .sum::<f64>()
        / n_samples)
        .sqrt()
        .to_degrees();
    Ok(fit)
}

/// The parameters of the refinement: `Sx = exp(log_scale_x)`, `Sy = 1/Sx`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Params {
    log_scale_x: f64,
    bias_ut: Vector2<f64>,
    offset_rad: f64,
}

impl Params {
    fn scale_x(&self) -> f64 {
        self.log_scale_x.exp()
    }

    fn scale_y(&self) -> f64 {
        (-self.log_scale_x).exp()
    }

    fn is_finite(&self) -> bool {
        self.log_scale_x.is_finite()
            && self.bias_ut.x.is_finite()
            && self.bias_ut.y.is_finite()
            && self.offset_rad.is_finite()
    }

    /// The corrected levelled field (Eq. 6).
    fn corrected(&self, level_ut: &Vector2<f64>) -> Vector2<f64> {
        Vector2::new(
            self.scale_x() * level_ut.x + self.bias_ut.x,
            self.scale_y() * level_ut.y + self.bias_ut.y,
        )
    }

    /// Eq. 8 in this crate's convention, unwrapped.
    fn heading_rad(&self, level_ut: &Vector2<f64>) -> f64 {
        let corrected = self.corrected(level_ut);
        (-corrected.y).atan2(corrected.x) + self.offset_rad
    }

    /// From `(Sx, Sy, Bx, By)` in any scale, into the gauge `Sx·Sy = 1`; `None` when the
    /// scales are not both positive.
    fn from_scales(scale: Vector2<f64>, bias_ut: Vector2<f64>, offset_rad: f64) -> Option<Params> {
        if !(scale.x > 0.0 && scale.y > 0.0) {
            return None;
        }
        let gauge = (scale.x * scale.y).sqrt();
        let params = Params {
            log_scale_x: (scale.x / gauge).ln(),
            bias_ut: bias_ut / gauge,
            offset_rad,
        };
        params.is_finite().then_some(params)
    }
}

/// Steps 1 and 2 of the module header: the start of the refinement, from the data alone.
fn two_step_start(
    level_ut: &[Vector2<f64>],
    ref_heading_rad: &[f64],
    declination_rad: Option<f64>,
) -> Result<Params, RefLsError> {
    let candidate = match declination_rad {
        Some(declination_rad) => {
            let design = DMatrix::from_row_iterator(
                level_ut.len(),
                4,
                level_ut
                    .iter()
                    .zip(ref_heading_rad)
                    .flat_map(|(level, &reference)| {
                        let (sin_heading, cos_heading) = (reference - declination_rad).sin_cos();
                        [
                            level.x * sin_heading,
                            level.y * cos_heading,
                            sin_heading,
                            cos_heading,
                        ]
                    }),
            );
            let solution = null_vector(design)?;
            let value = |idx: usize| solution.get(idx).copied().unwrap_or(0.0);
            let (mut scale, mut bias_ut) = (
                Vector2::new(value(0), value(1)),
                Vector2::new(value(2), value(3)),
            );
            // The cross product cannot tell the corrected vector from its opposite.
            if mean_alignment(level_ut, ref_heading_rad, |level| {
                let corrected = scale.component_mul(level) + bias_ut;
                (-corrected.y).atan2(corrected.x) + declination_rad
            }) < 0.0
            {
                scale = -scale;
                bias_ut = -bias_ut;
            }
            Params::from_scales(scale, bias_ut, declination_rad)
        }
        None => {
            let design = DMatrix::from_row_iterator(
                level_ut.len(),
                6,
                level_ut
                    .iter()
                    .zip(ref_heading_rad)
                    .flat_map(|(level, &reference)| {
                        let (sin_heading, cos_heading) = reference.sin_cos();
                        [
                            level.x * sin_heading,
                            -level.x * cos_heading,
                            level.y * cos_heading,
                            level.y * sin_heading,
                            sin_heading,
                            cos_heading,
                        ]
                    }),
            );
            let solution = null_vector(design)?;
            let value = |idx: usize| solution.get(idx).copied().unwrap_or(0.0);
            // (Sx, Sy)ᵀ·(cos D, sin D) is rank one: its dominant right singular vector
            // is the offset's direction, up to sign.
            let products = Matrix2::new(value(0), value(1), value(2), value(3));
            let eigen = SymmetricEigen::new(products.transpose() * products);
            let dominant_idx = eigen.eigenvalues.imax();
            let mut direction: Vector2<f64> = eigen.eigenvectors.column(dominant_idx).into_owned();
            let mut scale = products * direction;
            if scale.x + scale.y < 0.0 {
                direction = -direction;
                scale = -scale;
            }
            let mut offset_rad = direction.y.atan2(direction.x);
            let (sin_offset, cos_offset) = offset_rad.sin_cos();
            let rotated_bias = Vector2::new(value(4), value(5));
            let bias_ut =
                Matrix2::new(cos_offset, -sin_offset, sin_offset, cos_offset) * rotated_bias;
            // The solution's sign is free; flipping it turns every heading by π.
            if mean_alignment(level_ut, ref_heading_rad, |level| {
                let corrected = scale.component_mul(level) + bias_ut;
                (-corrected.y).atan2(corrected.x) + offset_rad
            }) < 0.0
            {
                offset_rad += std::f64::consts::PI;
            }
            Params::from_scales(scale, bias_ut, wrap_to_pi(offset_rad))
        }
    };
    candidate.ok_or(RefLsError::Mirrored)
}

/// The mean cosine of the heading errors: positive when the headings point along the
/// references rather than against them.
fn mean_alignment(
    level_ut: &[Vector2<f64>],
    ref_heading_rad: &[f64],
    heading_of: impl Fn(&Vector2<f64>) -> f64,
) -> f64 {
    level_ut
        .iter()
        .zip(ref_heading_rad)
        .map(|(level, reference)| (heading_of(level) - reference).cos())
        .sum::<f64>()
        / level_ut.len().max(1) as f64
}

/// The unit vector `v` minimising `|design·v|²`, on columns scaled to unit RMS so that
/// µT-sized and unit-sized columns weigh alike; `Degenerate` when it is not unique.
fn null_vector(design: DMatrix<f64>) -> Result<DVector<f64>, RefLsError> {
    let n_rows = design.nrows().max(1) as f64;
    let column_scale = DVector::from_iterator(
        design.ncols(),
        design
            .column_iter()
            .map(|column| (column.norm_squared() / n_rows).sqrt()),
    );
    if column_scale
        .iter()
        .any(|&scale| !(scale > 0.0 && scale.is_finite()))
    {
        return Err(RefLsError::Degenerate {
            reason: "a column of the linear problem is zero or not finite",
        });
    }
    let mut scaled = design;
    for (mut column, &scale) in scaled.column_iter_mut().zip(column_scale.iter()) {
        column /= scale;
    }
    let normal = scaled.transpose() * &scaled;
    if !normal.iter().all(|value| value.is_finite()) {
        return Err(RefLsError::Degenerate {
            reason: "the linear problem is not finite",
        });
    }
    let eigen = SymmetricEigen::new(normal);
    let order = crate::base::sort::ascending(eigen.eigenvalues.as_slice());
    let (smallest_idx, second_idx, largest_idx) = match order.as_slice() {
        [smallest, second, .., largest] => (*smallest, *second, *largest),
        _ => {
            return Err(RefLsError::Degenerate {
                reason: "too few unknowns",
            })
        }
    };
    let second_eigenvalue = eigen.eigenvalues[second_idx];
    if second_eigenvalue.is_nan()
        || second_eigenvalue <= MIN_EIGENVALUE_GAP * eigen.eigenvalues[largest_idx]
    {
        return Err(RefLsError::Degenerate {
            reason: "the linear problem has more than one solution",
        });
    }
    let solution = eigen
        .eigenvectors
        .column(smallest_idx)
        .component_div(&column_scale);
    let norm = solution.norm();
    if !(norm > 0.0 && norm.is_finite()) {
        return Err(RefLsError::Degenerate {
            reason: "the linear problem has no finite solution",
        });
    }
    Ok(solution / norm)
}

/// Step 3: Levenberg-Marquardt on the wrapped heading errors, from `start`. The offset
/// is a parameter only when no declination is given.
fn refine(
    level_ut: &[Vector2<f64>],
    ref_heading_rad: &[f64],
    declination_rad: Option<f64>,
    start: Params,
) -> (Params, levenberg_marquardt::MinimizationReport<f64>) {
    let problem = HeadingProblem {
        level_ut,
        ref_heading_rad,
        params: Params {
            offset_rad: declination_rad.unwrap_or(start.offset_rad),
            ..start
        },
        estimate_offset: declination_rad.is_none(),
        priors: None,
    };
    let (problem, report) = LevenbergMarquardt::new().minimize(problem);
    let mut params = problem.params;
    params.offset_rad = wrap_to_pi(params.offset_rad);
    (params, report)
}

/// A partial-coverage fit: from the identity and the declination (or no offset), the
/// heading residuals with one prior row per parameter, `σ_ψ·(θ − θ₀)/σ_θ` (the heading
/// rows are in radians; `σ_ψ`, their RMS at the start, puts the priors on their scale:
/// the whole is the posterior's negative log, up to σ_ψ²). The offset is estimated.
fn refine_partial(
    level_ut: &[Vector2<f64>],
    ref_heading_rad: &[f64],
    options: &RefLsOptions,
    prior: PartialPrior,
) -> (Params, levenberg_marquardt::MinimizationReport<f64>) {
    let start = Params {
        log_scale_x: 0.0,
        bias_ut: Vector2::zeros(),
        offset_rad: options.declination_rad.unwrap_or(0.0),
    };
    let n = level_ut.len().max(1) as f64;
    let heading_rms_rad = (level_ut
        .iter()
        .zip(ref_heading_rad)
        .map(|(level, &reference)| wrap_to_pi(start.heading_rad(level) - reference).powi(2))
        .sum::<f64>()
        / n)
        .sqrt()
        .max(1e-3);
    let field_ut = level_ut.iter().map(nalgebra::Matrix::norm).sum::<f64>() / n;
    let priors = Priors {
        centre: start,
        weight_log_scale: heading_rms_rad / prior.log_scale_std,
        weight_bias: heading_rms_rad / (prior.bias_std_of_field * field_ut).max(1e-9),
        weight_offset: heading_rms_rad / prior.offset_std_rad,
    };
    let problem = HeadingProblem {
        level_ut,
        ref_heading_rad,
        params: start,
        estimate_offset: true,
        priors: Some(priors),
    };
    let (problem, report) = LevenbergMarquardt::new().minimize(problem);
    let mut params = problem.params;
    params.offset_rad = wrap_to_pi(params.offset_rad);
    (params, report)
}

/// Prior rows of [`refine_partial`]: each parameter's distance from its centre, times
/// its weight.
#[derive(Debug, Clone, Copy)]
struct Priors {
    centre: Params,
    weight_log_scale: f64,
    weight_bias: f64,
    weight_offset: f64,
}

const N_PRIOR_ROWS: usize = 4;

struct HeadingProblem<'a> {
    level_ut: &'a [Vector2<f64>],
    ref_heading_rad: &'a [f64],
    params: Params,
    estimate_offset: bool,
    priors: Option<Priors>,
}

impl LeastSquaresProblem<f64, Dyn, Dyn> for HeadingProblem<'_> {
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, Dyn>;
    type ParameterStorage = Owned<f64, Dyn>;

    fn set_params(&mut self, params: &DVector<f64>) {
        let value = |idx: usize| params.get(idx).copied().unwrap_or(0.0);
        self.params.log_scale_x = value(0);
        self.params.bias_ut = Vector2::new(value(1), value(2));
        if self.estimate_offset {
            self.params.offset_rad = value(3);
        }
    }

    fn params(&self) -> DVector<f64> {
        let mut params = vec![
            self.params.log_scale_x,
            self.params.bias_ut.x,
            self.params.bias_ut.y,
        ];
        if self.estimate_offset {
            params.push(self.params.offset_rad);
        }
        DVector::from_vec(params)
    }

    fn residuals(&self) -> Option<DVector<f64>> {
        let headings = self
            .level_ut
            .iter()
            .zip(self.ref_heading_rad)
            .map(|(level, &reference)| wrap_to_pi(self.params.heading_rad(level) - reference));
        let prior_rows = self.priors.map(|priors| {
            let (params, centre) = (&self.params, &priors.centre);
            [
                priors.weight_log_scale * (params.log_scale_x - centre.log_scale_x),
                priors.weight_bias * (params.bias_ut.x - centre.bias_ut.x),
                priors.weight_bias * (params.bias_ut.y - centre.bias_ut.y),
                priors.weight_offset * wrap_to_pi(params.offset_rad - centre.offset_rad),
            ]
        });
        let n_rows = self.level_ut.len() + prior_rows.map_or(0, |rows| rows.len());
        Some(DVector::from_iterator(
            n_rows,
            headings.chain(prior_rows.into_iter().flatten()),
        ))
    }

    fn jacobian(&self) -> Option<DMatrix<f64>> {
        let n_params = if self.estimate_offset { 4 } else { 3 };
        let (scale_x, scale_y) = (self.params.scale_x(), self.params.scale_y());
        let n_rows = self.level_ut.len() + self.priors.map_or(0, |_| N_PRIOR_ROWS);
        let mut jacobian = DMatrix::zeros(n_rows, n_params);
        if let Some(priors) = self.priors {
            let first = self.level_ut.len();
            jacobian[(first, 0)] = priors.weight_log_scale;
            jacobian[(first + 1, 1)] = priors.weight_bias;
            jacobian[(first + 2, 2)] = priors.weight_bias;
            if self.estimate_offset {
                jacobian[(first + 3, 3)] = priors.weight_offset;
            }
        }
        for (sample_idx, level) in self.level_ut.iter().enumerate() {
            // ψ = atan2(−Y', X'): ∂ψ/∂X' = Y'/r², ∂ψ/∂Y' = −X'/r²; at the origin the
            // heading has no derivative.
            let corrected = self.params.corrected(level);
            let radius_squared = corrected.norm_squared();
            let (by_x, by_y) = if radius_squared > 0.0 {
                (corrected.y / radius_squared, -corrected.x / radius_squared)
            } else {
                (0.0, 0.0)
            };
            // ∂X'/∂ln Sx = Sx·Xh and ∂Y'/∂ln Sx = −Sy·Yh, because Sy = 1/Sx.
            jacobian[(sample_idx, 0)] = by_x * scale_x * level.x - by_y * scale_y * level.y;
            jacobian[(sample_idx, 1)] = by_x;
            jacobian[(sample_idx, 2)] = by_y;
            if self.estimate_offset {
                jacobian[(sample_idx, 3)] = 1.0;
            }
        }
        Some(jacobian)
    }
}

#[cfg(test)]
mod tests;
