//! The four calibration methods as [`super::calibrate`] runs them on one log: each fits
//! its train samples and gives its heading at every sample (min/max, Eq. 6-7; the
//! tilt-aware ellipse, `fit::ellipse`; the 3D fit, `fit::ellipsoid`; reference least
//! squares, Eq. 8, `fit::ref_ls`), or says why it was not fitted; [`fit_and_score`]
//! runs the chosen ones and scores them beside uncalibrated. The 3D fit's sphere
//! coverage adds advice on where to turn; reference least squares over references that
//! cover little of the circle is fitted on top of the best 3D calibration so far.

use nalgebra::{Vector2, Vector3};
use thiserror::Error;

use super::row_key::RowKey;
use super::selection::{choose_by_reference, Choice, Scored};
use super::{
    inertial_options, plane_options, FittedEllipse, Method, MethodParameters, MethodReport,
    Prepared,
};
use crate::analysis::levelled::Levelling;
use crate::attitude::compass_heading::heading_rad;
use crate::attitude::tilt::Tilt;
use crate::base::stats::HeadingErrorStats;
use crate::earth::wmm::ExpectedField;
use crate::fit::coverage::sphere_coverage;
use crate::fit::ellipse::{fit_plane, PlaneError};
use crate::fit::ellipsoid::{fit_inertial_trusting, InertialError, TiltTrusted};
use crate::fit::minmax::MinMaxCalibration;
use crate::fit::ref_ls::{fit_reference_ls, PartialPrior, RefLsError, RefLsOptions};
use crate::fit::CalibError;
use crate::io::SensorFrame;

/// What every method's fit reads: the samples, their levelled and train parts, the
/// reference and the declination.
struct MethodInputs<'a> {
    samples: &'a crate::analysis::levelled::TiltedSamples,
    level_raw_ut: &'a [Vector2<f64>],
    level_train: &'a [Vector2<f64>],
    mag_train: &'a [Vector3<f64>],
    tilt_train: &'a [Tilt],
    /// How far each train sample's tilt is trusted (0 to 1).
    tilt_trust_train: &'a [f64],
    ref_heading_rad: &'a [Option<f64>],
    is_fit: &'a [bool],
    declination_rad: f64,
    expected: Option<&'a ExpectedField>,
    mag_frame: Option<&'a SensorFrame>,
}

impl MethodInputs<'_> {
    /// `f(mag, tilt)` at every sample, on every core ([`crate::base::par::map`]).
    fn map_tilted<R: Send>(&self, f: impl Fn(Vector3<f64>, Tilt) -> R + Sync) -> Vec<R> {
        let tilt = &self.samples.tilt;
        crate::base::par::map(&self.samples.mag_ut, |idx, &mag| {
            f(mag, tilt.get(idx).copied().unwrap_or(Tilt::LEVEL))
        })
    }
}

/// What the methods' fits leave besides their parameters: the correction the circle
/// plot shows, the corrected |B|, and notes for the user.
struct MethodOutputs<'a> {
    plane_correction: Option<(Vec<Vector2<f64>>, Option<FittedEllipse>)>,
    field_corrected_ut: Option<Vec<f64>>,
    notes: &'a mut Vec<String>,
}

/// Why a method was not fitted: its fit's own error, or no reference heading for the
/// reference least squares. The method table shows the message.
#[derive(Debug, Clone, PartialEq, Error)]
pub(super) enum MethodFitError {
    #[error(transparent)]
    MinMax(#[from] CalibError),
    #[error(transparent)]
    Ellipse(#[from] PlaneError),
    #[error(transparent)]
    Ellipsoid(#[from] InertialError),
    #[error(transparent)]
    RefLs(#[from] RefLsError),
    /// The reference least squares (Eq. 8) without a reference heading in the train part.
    #[error("needs a reference heading (a ref_heading_deg column, or GPS course while moving)")]
    NoReference,
}

/// A method's parameters and its heading at every sample, or why it was not fitted.
type Fitted = Result<(MethodParameters, Vec<f64>), MethodFitError>;

/// What [`fit_and_score`] gives: each method's report and heading (degrees) where it
/// was fitted, the corrections the plots draw, and uncalibrated's scores with the best by
/// the reference.
pub(super) struct Scores {
    pub(super) method_reports: Vec<MethodReport>,
    pub(super) headings_deg: Vec<(Method, Vec<f64>)>,
    pub(super) plane_correction: Option<(Vec<Vector2<f64>>, Option<FittedEllipse>)>,
    pub(super) field_corrected_ut: Option<Vec<f64>>,
    pub(super) raw_train: Option<HeadingErrorStats>,
    pub(super) raw_check: Option<HeadingErrorStats>,
    pub(super) by_reference: Option<Choice>,
}

/// Every method of `methods` fitted and scored beside uncalibrated, with the best by the
/// reference; the fits' notes go to `notes`.
pub(super) fn fit_and_score(
    methods: &[Method],
    prepared: &Prepared,
    mag_frame: Option<&SensorFrame>,
    notes: &mut Vec<String>,
) -> Scores {
    let mut outputs = MethodOutputs {
        plane_correction: None,
        field_corrected_ut: None,
        notes,
    };
    let (method_reports, headings_deg) = run_methods(methods, prepared, mag_frame, &mut outputs);
    let MethodOutputs {
        plane_correction,
        field_corrected_ut,
        ..
    } = outputs;
    let (raw_train, raw_check) = prepared.both_stats(&prepared.raw_heading_rad);
    let scored = scored_methods(raw_train, raw_check, &method_reports);
    let by_reference = choose_by_reference(&scored);
    Scores {
        method_reports,
        headings_deg,
        plane_correction,
        field_corrected_ut,
        raw_train,
        raw_check,
        by_reference,
    }
}

/// Each method fitted on the train part and scored on both: its report, and its heading
/// at every sample (degrees) where it was fitted.
fn run_methods(
    methods: &[Method],
    prepared: &Prepared,
    mag_frame: Option<&SensorFrame>,
    outputs: &mut MethodOutputs,
) -> (Vec<MethodReport>, Vec<(Method, Vec<f64>)>) {
    let is_fit = &prepared.split.is_fit;
    let (samples, level_raw_ut) = (&prepared.samples, &prepared.level_raw_ut);
    let (mag_train, tilt_train, level_train) = (
        kept(&samples.mag_ut, is_fit),
        kept(&samples.tilt, is_fit),
        kept(level_raw_ut, is_fit),
    );
    let tilt_trust_train = kept(&samples.tilt_trust, is_fit);
    let inputs = MethodInputs {
        samples,
        level_raw_ut,
        level_train: &level_train,
        mag_train: &mag_train,
        tilt_train: &tilt_train,
        tilt_trust_train: &tilt_trust_train,
        ref_heading_rad: &prepared.ref_heading_rad,
        is_fit,
        declination_rad: prepared.declination.declination_deg.to_radians(),
        expected: prepared.expected.as_ref(),
        mag_frame,
    };
    let mut method_reports = Vec::new();
    let mut headings_deg = Vec::new();
    for &method in methods {
        let fitted = match method {
            Method::MinMax => fit_min_max(&inputs, outputs),
            Method::Ellipse => fit_ellipse(&inputs, outputs),
            Method::Ellipsoid => fit_ellipsoid(&inputs, outputs),
            Method::RefLs => fit_ref_ls(&inputs, outputs, &method_reports),
        };
        let (parameters, error, train, check) = match fitted {
            Ok((parameters, headings_rad)) => {
                let scores = prepared.both_stats(&headings_rad);
                headings_deg.push((
                    method,
                    headings_rad.iter().map(|h| h.to_degrees()).collect(),
                ));
                (Some(parameters), None, scores.0, scores.1)
            }
            Err(reason) => (None, Some(reason.to_string()), None, None),
        };
        method_reports.push(MethodReport {
            method,
            label: method.label(),
            parameters,
            error,
            heading_error_train: train,
            heading_error_check: check,
        });
    }
    (method_reports, headings_deg)
}

/// The values at the samples `keep` marks.
fn kept<T: Copy>(values: &[T], keep: &[bool]) -> Vec<T> {
    values
        .iter()
        .zip(keep)
        .filter(|(_, &keep)| keep)
        .map(|(value, _)| *value)
        .collect()
}

/// Uncalibrated and every method, as the selection scores them.
fn scored_methods(
    raw_train: Option<HeadingErrorStats>,
    raw_check: Option<HeadingErrorStats>,
    method_reports: &[MethodReport],
) -> Vec<Scored<'_>> {
    let mut scored = vec![Scored {
        key: RowKey::RAW,
        label: "uncalibrated",
        train_rms_deg: raw_train.map(|stats| stats.rms_deg),
        check_rms_deg: raw_check.map(|stats| stats.rms_deg),
    }];
    scored.extend(method_reports.iter().map(|report| Scored {
        key: RowKey::method(report.method),
        label: report.label,
        train_rms_deg: report.heading_error_train.map(|stats| stats.rms_deg),
        check_rms_deg: report.heading_error_check.map(|stats| stats.rms_deg),
    }));
    scored
}

/// Min/max (Eq. 6-7) on the levelled train samples.
fn fit_min_max(inputs: &MethodInputs, outputs: &mut MethodOutputs) -> Fitted {
    MinMaxCalibration::fit(inputs.level_train)
        .map_err(MethodFitError::MinMax)
        .map(|calibration| {
            let headings = crate::base::par::map(inputs.level_raw_ut, |_, &level| {
                heading_rad(calibration.apply(level), inputs.declination_rad)
            });
            if outputs.plane_correction.is_none() {
                let corrected = inputs
                    .level_raw_ut
                    .iter()
                    .map(|&level| calibration.apply(level))
                    .collect();
                let ellipse = (
                    Vector2::new(calibration.center_x_ut, calibration.center_y_ut),
                    nalgebra::Matrix2::new(
                        calibration.semi_axis_x_ut,
                        0.0,
                        0.0,
                        calibration.semi_axis_y_ut,
                    ) / calibration.corrected_radius_ut(),
                    calibration.corrected_radius_ut(),
                );
                outputs.plane_correction = Some((corrected, Some(ellipse)));
            }
            (MethodParameters::MinMax(calibration), headings)
        })
}

/// The tilt-aware level-plane ellipse (`fit::ellipse`).
fn fit_ellipse(inputs: &MethodInputs, outputs: &mut MethodOutputs) -> Fitted {
    fit_plane(
        inputs.mag_train,
        inputs.tilt_train,
        &plane_options(inputs.expected),
    )
    .map_err(MethodFitError::Ellipse)
    .map(|fit| {
        let headings =
            inputs.map_tilted(|mag, tilt| fit.heading_rad(mag, tilt, inputs.declination_rad));
        let corrected: Vec<Vector2<f64>> = inputs
            .samples
            .mag_ut
            .iter()
            .zip(&inputs.samples.tilt)
            .map(|(&mag, &tilt)| fit.level_corrected_ut(mag, tilt))
            .collect();
        // `fit.plane` applies to level(mag − hard iron); over levelled raw
        // points the same ellipse sits at its centre plus the level hard iron
        // (exact for a level device, close for small tilts).
        let center_ut = fit.plane.center_ut + Vector2::new(fit.hard_iron_ut.x, fit.hard_iron_ut.y);
        let ellipse = fit
            .plane
            .transform
            .try_inverse()
            .map(|inverse| (center_ut, inverse, fit.plane.radius_ut));
        // The ellipse method's correction is the one the circle plot shows.
        outputs.plane_correction = Some((corrected, ellipse));
        // The plane fit's 3D correction gives |B| too, until an ellipsoid
        // fit (which sees the field in 3D) replaces it.
        outputs.field_corrected_ut = Some(
            inputs
                .samples
                .mag_ut
                .iter()
                .map(|&mag| (fit.soft_iron * (mag - fit.hard_iron_ut)).norm())
                .collect(),
        );
        (MethodParameters::Ellipse(Box::new(fit)), headings)
    })
}

/// What the user should know when the 3D fit found its samples' tilt mostly not
/// trusted: how much of it, why, and what the fit and the device's calibration did.
fn untrusted_tilt_note(trust: &[f64]) -> String {
    let n_low = trust.iter().filter(|&&trust| trust < 0.5).count();
    let share_pct = 100.0 * n_low as f64 / trust.len().max(1) as f64;
    format!(
        "ellipsoid (3D): the gyroscope's and the accelerometer's down disagree by more than {}° on {share_pct:.0} % of the fitted samples (a swinging arm, a run), so each sample's dip weighed as far as its tilt is trusted, the fitted dip refused no solution, and a device calibration, where one is written, comes from this fit rather than from the ellipse fitted on that tilt",
        2.0 * crate::attitude::down::TRUST_HALF_DEG
    )
}

/// The 3D fit (`fit::ellipsoid`), with the accelerometer's tilt when the log has one.
fn fit_ellipsoid(inputs: &MethodInputs, outputs: &mut MethodOutputs) -> Fitted {
    let inertial_options = inertial_options(inputs.expected, inputs.mag_frame);
    // The dip-angle invariance needs the accelerometer's tilt; a log without
    // one was only assumed level.
    let tilt = matches!(inputs.samples.levelling, Levelling::Accelerometer { .. }).then_some(
        TiltTrusted {
            tilt: inputs.tilt_train,
            trust: Some(inputs.tilt_trust_train),
        },
    );
    fit_inertial_trusting(inputs.mag_train, tilt, &inertial_options)
        .map_err(MethodFitError::Ellipsoid)
        .map(|fit| {
            if fit.tilt_untrusted {
                outputs
                    .notes
                    .push(untrusted_tilt_note(inputs.tilt_trust_train));
            }
            let calibration = fit.calibration;
            let headings = inputs.map_tilted(|mag, tilt| {
                heading_rad(tilt.level(calibration.apply(mag)), inputs.declination_rad)
            });
            outputs.field_corrected_ut = Some(
                inputs
                    .samples
                    .mag_ut
                    .iter()
                    .map(|&mag| calibration.apply(mag).norm())
                    .collect(),
            );
            // Where the sphere of corrected directions is still empty, as
            // MotionCal counts it, and which way to turn to fill it.
            let coverage =
                sphere_coverage(inputs.mag_train.iter().map(|&mag| calibration.apply(mag)));
            if let Some(gap) = coverage.largest_gap.filter(|_| coverage.gaps_too_large()) {
                outputs.notes.push(format!(
                    "ellipsoid: {:.0} % of the sphere is uncovered (MotionCal's gaps); {}",
                    coverage.gap_pct,
                    gap.advice()
                ));
            }
            (MethodParameters::Ellipsoid(Box::new(fit)), headings)
        })
}

/// Reference least squares (Eq. 8), on top of the best 3D calibration so far when the
/// references cover too little of the circle.
fn fit_ref_ls(
    inputs: &MethodInputs,
    outputs: &mut MethodOutputs,
    method_reports: &[MethodReport],
) -> Fitted {
    let pairs: (Vec<Vector2<f64>>, Vec<f64>) = inputs
        .level_raw_ut
        .iter()
        .zip(inputs.ref_heading_rad)
        .zip(inputs.is_fit)
        .filter_map(|((&level, &reference), &train)| train.then_some((level, reference?)))
        .unzip();
    let coverage = crate::fit::minmax::Coverage::of_headings(
        pairs.1.iter().map(|reference| reference.to_degrees()),
    );
    let refls_options = RefLsOptions {
        declination_rad: Some(inputs.declination_rad),
        ..RefLsOptions::default()
    };
    // References over a few headings only: Eq. 8 on top of the best 3D
    // calibration so far (by its train error), its parameters held near the
    // identity where the headings cannot see them.
    let base = (coverage.largest_gap_deg > refls_options.max_heading_gap_deg)
        .then(|| {
            method_reports
                .iter()
                .filter_map(|report: &MethodReport| {
                    let calibration =
                        crate::analysis::calibration::selection::field_calibration_of(report)?;
                    Some((
                        report.method,
                        calibration,
                        report.heading_error_train?.rms_deg,
                    ))
                })
                .min_by(|a, b| a.2.total_cmp(&b.2))
        })
        .flatten();
    if pairs.0.is_empty() {
        Err(MethodFitError::NoReference)
    } else if let Some((base_method, calibration, _)) = base {
        let level_base_ut: Vec<Vector2<f64>> = inputs
            .samples
            .mag_ut
            .iter()
            .zip(&inputs.samples.tilt)
            .map(|(&mag, tilt)| tilt.level(calibration.apply(mag)))
            .collect();
        let base_pairs: Vec<Vector2<f64>> = level_base_ut
            .iter()
            .zip(inputs.ref_heading_rad)
            .zip(inputs.is_fit)
            .filter_map(|((&level, reference), &fit)| (fit && reference.is_some()).then_some(level))
            .collect();
        let partial_options = RefLsOptions {
            prior: Some(PartialPrior::default()),
            ..refls_options
        };
        fit_reference_ls(&base_pairs, &pairs.1, &partial_options)
                .map_err(MethodFitError::RefLs)
                .map(|fit| {
                    outputs.notes.push(format!(
                        "reference LS: the reference headings cover too little of the circle for Eq. 8 alone \
                         (none from {:.0}° clockwise to {:.0}°, {:.0}° of it), so it was fitted on top of the {} \
                         calibration, held near it where those headings cannot see",
                        coverage.largest_gap_start_deg,
                        (coverage.largest_gap_start_deg + coverage.largest_gap_deg).rem_euclid(360.0),
                        coverage.largest_gap_deg,
                        base_method.label()
                    ));
                    let headings: Vec<f64> =
                        level_base_ut.iter().map(|&level| fit.heading_rad(level)).collect();
                    (MethodParameters::RefLs(fit), headings)
                })
    } else {
        fit_reference_ls(&pairs.0, &pairs.1, &refls_options)
            .map_err(MethodFitError::RefLs)
            .map(|fit| {
                let headings =
                    crate::base::par::map(inputs.level_raw_ut, |_, &level| fit.heading_rad(level));
                (MethodParameters::RefLs(fit), headings)
            })
    }
}
