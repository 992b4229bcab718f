//! The heading each step takes: the analysis's one best heading model (or the one the
//! user names, or the device's own yaw), fitted again on the GNSS course outside the
//! outages, optionally carried by the gyro (Chen et al., Fig. 2: "the speed and heading
//! from GPS are utilized to … calibrate the compass" while GNSS is good).
//!
//! The choice of model is not made here: it is the heading comparison's
//! ([`crate::analysis::calibration::selection`], through [`crate::pipeline`]), so the
//! dead reckoning, the page, the CLI and the report name the same method. What is done
//! here is to fit that one model again for the track: on every GNSS-referenced sample
//! outside the outages, never on a reference-heading column (in a test log that column
//! is the truth), so that no fix inside an outage trains what bridges it. Where the
//! comparison itself was scored against the track's truth (that column, or the legs
//! between reference positions) and GNSS cannot fit its choice again, or where a GPS
//! course was too far from every model to choose ([`Basis::ReferenceTooFar`]), the
//! track takes a heading that needs no reference (`reference_free_choice`), unless the
//! user asks for one.

use crate::analysis::calibration::row_key::{OnTop, RowKey};
use crate::analysis::calibration::selection::{choose_without_reference, Basis};
use crate::analysis::calibration::{
    calibrate_again, CalibrationAnalysis, CalibrationOptions, Method,
};
use crate::analysis::headings::{HeadingAnalysis, HeadingOptions};
use crate::io::recording::{GnssFix, Stream};
use crate::io::ImportReport;
use crate::reference::gyro::gyro_heading;
use crate::reference::{ReferenceChoice, ReferenceOptions};

use super::fusion::Outage;
use super::{HeadingBase, PdrOptions};

/// A heading per sample (rad, clockwise from true north), with its row key and label,
/// and its 1σ (rad) where the heading states one (the attitude filter's).
pub struct StepHeading {
    pub heading_rad: Stream<f64>,
    pub sigma_rad: Option<Stream<f64>>,
    pub key: String,
    pub label: String,
}

/// The heading the steps take, and notes on how it was made.
pub fn step_heading(
    import: &ImportReport,
    (calibration, headings): (&CalibrationAnalysis, &HeadingAnalysis),
    options: &PdrOptions,
    notes: &mut Vec<String>,
) -> Option<StepHeading> {
    let compass = compass_heading(import, (calibration, headings), options, notes)?;
    let base = match options.heading.base {
        HeadingBase::Device => device_heading(import, headings, notes).unwrap_or(compass),
        _ => compass,
    };
    if !options.heading.gyro_aligned {
        return Some(base);
    }
    match gyro_heading(
        &import.recording,
        &calibration.gravity,
        Some(&base.heading_rad),
        false,
    ) {
        // The gyroscope aligned over the whole walk has errors of its own, not the
        // base's: no σ is stated for it.
        Some(gyro) => Some(StepHeading {
            heading_rad: gyro.heading_rad,
            sigma_rad: None,
            key: format!("gyro+{}", base.key),
            label: format!("the gyro aligned to {}", base.label),
        }),
        None => {
            notes.push(format!(
                "The log has no gyroscope: the {} heading was used without it.",
                base.key
            ));
            Some(base)
        }
    }
}

/// The compass heading: the model the comparison chose (or the one asked for by key),
/// fitted again on every GNSS-referenced sample outside the outages when GNSS can
/// reference it, else as the comparison fitted it; the uncalibrated heading when the
/// model does not exist for this log. `None` when there is no heading at all.
fn compass_heading(
    import: &ImportReport,
    (calibration, headings): (&CalibrationAnalysis, &HeadingAnalysis),
    options: &PdrOptions,
    notes: &mut Vec<String>,
) -> Option<StepHeading> {
    // A key the user names that is no row's is not there: the uncalibrated heading is
    // used, and the note below says so.
    let mut wanted = match &options.heading.base {
        HeadingBase::Model(text) => RowKey::parse(text).unwrap_or(RowKey::RAW),
        _ => headings.report.choice.key,
    };
    let asked = matches!(options.heading.base, HeadingBase::Model(_));
    let mut refit = None;
    if !asked && reference_cannot_choose(headings).is_some() {
        // A reference no model comes near chose nothing, and fits nothing again.
        wanted = reference_free_choice(calibration, headings, options, notes);
    } else {
        refit = refit_on_gnss(import, calibration, wanted, options, notes);
        let refitted = refit
            .as_ref()
            .is_some_and(|refit| series_of(refit, wanted).is_some());
        if !refitted && !asked && fitted_on_the_track_s_truth(headings, options) {
            wanted = reference_free_choice(calibration, headings, options, notes);
            refit = None;
        }
    }
    let from_refit = refit
        .as_ref()
        .and_then(|refit| series_of(refit, wanted).map(|series| (refit, series)));
    let (source, series) = from_refit
        .or_else(|| series_of(headings, wanted).map(|series| (headings, series)))
        .or_else(|| series_of(headings, RowKey::RAW).map(|s| (headings, s)))?;
    let key = series.0;
    if let HeadingBase::Model(requested) = &options.heading.base {
        if *requested != key.text() {
            notes.push(format!(
                "There is no heading model '{requested}' for this log; the {key} heading was used. The models are: {}.",
                model_keys(&headings.headings_deg)
            ));
        }
    }
    // A heading with gaps (the attitude filter's before it starts) keeps its samples:
    // NaN would poison the means and the gyro's alignment.
    let mut heading_rad = Stream::default();
    for (&t_s, &deg) in source.t_s.iter().zip(&series.1) {
        if deg.is_finite() {
            heading_rad.push(t_s, deg.to_radians());
        }
    }
    // The attitude filter states its yaw's 1σ: the dead reckoning's heading noise. (A
    // calibration fitted again keeps the first one's filter run, and so its σ.)
    let sigma_rad = (key == RowKey::ATTITUDE)
        .then_some(calibration.attitude_heading.as_ref())
        .flatten()
        .map(|attitude| {
            let mut sigma_rad = Stream::default();
            for (&t_s, &deg) in calibration.t_s.iter().zip(&attitude.sigma_deg) {
                if deg.is_finite() {
                    sigma_rad.push(t_s, deg.to_radians());
                }
            }
            sigma_rad
        });
    Some(StepHeading {
        heading_rad,
        sigma_rad,
        label: label_of(source, key),
        key: key.text(),
    })
}

/// The model keyed `key` fitted on every GNSS-referenced sample outside the outages
/// (only its field-domain method, with the 3D fits a reference least squares stands
/// on); `None` when a train/check split was asked for (the comparison's fit then
/// stands), when the calibration fails (said in a note) or when GNSS references no
/// heading.
fn refit_on_gnss(
    import: &ImportReport,
    calibration: &CalibrationAnalysis,
    key: RowKey,
    options: &PdrOptions,
    notes: &mut Vec<String>,
) -> Option<HeadingAnalysis> {
    let given = &options.heading_options;
    if given.calibration.train_until_s.is_some() {
        return None;
    }
    let methods = match key.field_method().unwrap_or(Method::MinMax) {
        Method::RefLs => vec![Method::Ellipse, Method::Ellipsoid, Method::RefLs],
        method => vec![method],
    };
    let everything = HeadingOptions {
        calibration: CalibrationOptions {
            reference: ReferenceOptions {
                choice: ReferenceChoice::Gps,
                ..given.calibration.reference
            },
            train_until_s: Some(f64::INFINITY),
            methods,
            ..given.calibration.clone()
        },
        // A network trains only when it is the model: it would dominate the time.
        neural: key.on_top == OnTop::Network,
        ..given.clone()
    };
    let gnss = without_outages(&import.recording.gnss, &options.gnss.outages);
    if gnss.is_empty() {
        // Nothing to reference the heading: the comparison's fit stands.
        return None;
    }
    // The calibration's levelled samples (computed afresh if its down took speeds from
    // fixes the outages now hide).
    let mut report = import.clone();
    report.recording.gnss = gnss;
    match calibrate_again(calibration, report, &everything.calibration) {
        Ok(refit) if refit.report.reference.is_some() => {
            Some(crate::analysis::headings::compare(&refit, &everything))
        }
        Ok(_) => None,
        Err(error) => {
            notes.push(format!(
                "The heading model was not refitted on every GNSS-referenced sample ({error}); the one the comparison fitted was used."
            ));
            None
        }
    }
}

/// The closest model's RMS against the comparison's reference and its label, when the
/// reference was too far to choose ([`Basis::ReferenceTooFar`]).
fn reference_cannot_choose(headings: &HeadingAnalysis) -> Option<(f64, &str)> {
    match &headings.report.choice.basis {
        Basis::ReferenceTooFar { rms_deg, closest } => Some((*rms_deg, closest)),
        _ => None,
    }
}

/// Whether the comparison's choice has parameters fitted on what also scores the track
/// (a reference-heading column, the legs between reference positions: in a test log the
/// truth), which the user did not ask to train on (`--train-on-reference`).
fn fitted_on_the_track_s_truth(headings: &HeadingAnalysis, options: &PdrOptions) -> bool {
    headings.report.choice.key.learns_from_reference()
        && !options.train_on_reference_positions
        && headings
            .report
            .reference
            .is_some_and(|source| source.scores_the_track())
}

/// The heading the track takes when the comparison's choice is set aside (its reference
/// could not choose, or it was fitted on the track's own truth and GNSS could not fit it
/// again): the choice's part that needs no reference (`ahrs` for `ahrs+fourier`), else
/// the attitude filter, else the calibration chosen without a reference. Says why.
fn reference_free_choice(
    calibration: &CalibrationAnalysis,
    headings: &HeadingAnalysis,
    options: &PdrOptions,
    notes: &mut Vec<String>,
) -> RowKey {
    let chosen = &headings.report.choice;
    let base = RowKey::of(chosen.key.base);
    let (key, label) = if !base.learns_from_reference()
        && base != RowKey::RAW
        && series_of(headings, base).is_some()
        && reference_cannot_choose(headings).is_none()
    {
        (base, label_of(headings, base))
    } else if series_of(headings, RowKey::ATTITUDE).is_some() {
        (RowKey::ATTITUDE, label_of(headings, RowKey::ATTITUDE))
    } else {
        let choice = choose_without_reference(&calibration.report);
        (choice.key, choice.label)
    };
    let reference = headings
        .report
        .reference
        .map_or_else(|| "the reference".to_string(), |source| source.describe());
    let why = match reference_cannot_choose(headings) {
        Some((rms_deg, closest)) => format!(
            "the heading comparison's reference, {reference}, is {rms_deg:.0}° RMS from even its closest model ({closest}), too far to choose one"
        ),
        None => format!(
            "the heading comparison was scored against {reference}, which also scores the track, and GNSS could not fit its choice ({}) again{}",
            chosen.label,
            if options.train_on_reference_positions { "" } else { " (--train-on-reference would take it)" }
        ),
    };
    notes.push(format!(
        "The track's heading is the {label}, which needs no reference: {why}."
    ));
    key
}

/// The device's own fused yaw turned to true north, if the log has one.
fn device_heading(
    import: &ImportReport,
    headings: &HeadingAnalysis,
    notes: &mut Vec<String>,
) -> Option<StepHeading> {
    let declination_rad = headings
        .report
        .calibration
        .declination
        .declination_deg
        .to_radians();
    let attitude = &import.recording.attitude;
    let mut device = Stream::default();
    for (&t_s, attitude) in attitude.t_s.iter().zip(&attitude.values) {
        if let Some(yaw_rad) = attitude.yaw_rad.filter(|yaw| yaw.is_finite()) {
            device.push(
                t_s,
                crate::base::angle::wrap_to_2pi(yaw_rad + declination_rad),
            );
        }
    }
    if device.is_empty() {
        notes.push(
            "The log has no device yaw (rotation vector): the compass heading was used."
                .to_string(),
        );
        return None;
    }
    Some(StepHeading {
        heading_rad: device,
        sigma_rad: None,
        key: "device".to_string(),
        label: "the device's own yaw (rotation vector) with the declination".to_string(),
    })
}

fn series_of(headings: &HeadingAnalysis, key: RowKey) -> Option<&(RowKey, Vec<f64>)> {
    headings.headings_deg.iter().find(|(row, _)| *row == key)
}

/// The GNSS fixes outside the outages.
pub fn without_outages(gnss: &Stream<GnssFix>, outages: &[Outage]) -> Stream<GnssFix> {
    let mut kept = Stream::default();
    for (&t_s, fix) in gnss.t_s.iter().zip(&gnss.values) {
        if !outages.iter().any(|outage| outage.contains(t_s)) {
            kept.push(t_s, *fix);
        }
    }
    kept
}

fn label_of(headings: &HeadingAnalysis, key: RowKey) -> String {
    headings
        .report
        .row(key)
        .map_or_else(|| key.text(), |row| row.label.clone())
}

fn model_keys(series: &[(RowKey, Vec<f64>)]) -> String {
    series
        .iter()
        .map(|(key, _)| key.text())
        .collect::<Vec<_>>()
        .join(", ")
}

/// The circular mean of the heading samples within a step, else the heading
/// interpolated at its middle (within a second); NaN when there is none.
pub fn mean_heading(heading: &Stream<f64>, start_s: f64, end_s: f64) -> f64 {
    let first = heading.t_s.partition_point(|&t| t < start_s);
    let last = heading.t_s.partition_point(|&t| t < end_s);
    let (mut sin_sum, mut cos_sum) = (0.0, 0.0);
    for value in heading.values.get(first..last).unwrap_or(&[]) {
        sin_sum += value.sin();
        cos_sum += value.cos();
    }
    if sin_sum != 0.0 || cos_sum != 0.0 {
        return crate::base::angle::wrap_to_2pi(sin_sum.atan2(cos_sum));
    }
    heading
        .interpolate_angle_at(0.5 * (start_s + end_s), 1.0)
        .unwrap_or(f64::NAN)
}

/// Each NaN replaced by the last finite value before it (the first finite one at the
/// start; 0 when there is none).
pub fn fill_forward(values: Vec<f64>) -> Vec<f64> {
    let first_finite = values
        .iter()
        .copied()
        .find(|v| v.is_finite())
        .unwrap_or(0.0);
    let mut last = first_finite;
    values
        .into_iter()
        .map(|value| {
            if value.is_finite() {
                last = value;
            }
            last
        })
        .collect()
}
