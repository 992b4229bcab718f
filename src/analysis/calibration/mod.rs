//! Every calibration method on one log, side by side, on a train/check split by time.
//!
//! The 2007 paper calibrates on one run and checks on another; so does this: samples up
//! to `train_until_s` (by default, half of the referenced samples on each side) train
//! each method, at most 20,000 of them evenly thinned; the rest check it against the
//! reference heading. The methods (`methods.rs`):
//!
//! - **min/max** (Eq. 6-7, [`crate::fit::minmax`]): centre and axis scales of the
//!   levelled raw field;
//! - **ellipse** ([`crate::fit::ellipse`]): the tilt-aware level-plane fit, a general
//!   conic with cross-axis soft iron, the method for flat, circle-only data;
//! - **ellipsoid** ([`crate::fit::ellipsoid`]): the 3D model of Eq. 5 with the dip and
//!   gravity, with MotionCal's sphere coverage and where to turn to fill it;
//! - **reference LS** (Eq. 8, [`crate::fit::ref_ls`]): min/max's parameters fitted to
//!   the reference heading (over the best 3D fit where it covers little of the circle).
//!
//! Every heading gets the declination (`context.rs`): the user's, the World Magnetic
//! Model's at the log's first position and date ([`crate::earth::wmm`]), else an
//! autopilot's own; the model also gives the field a wrong unit or a magnet stands out
//! against. Down and the tilted samples are computed once (`Levelled`) and reused by
//! [`calibrate_again`], the dead reckoning's refit; the report carries the import's
//! `SensorFrame`, so the device calibration is exported in the sensor's axes and units.

use std::sync::Arc;

use nalgebra::{Vector2, Vector3};
use serde::Serialize;

use crate::analysis::calibration::selection::{choose_by_reference, Choice, Scored, RAW_KEY};
use crate::analysis::levelled::{AnalysisError, Levelling, TiltedSamples};
use crate::attitude::compass_heading::heading_rad;
use crate::attitude::down::{gravity_from_attitude, gravity_of, GravityEstimate};
use crate::attitude::tilt::Tilt;
use crate::base::stats::HeadingErrorStats;
use crate::earth::wmm::ExpectedField;
use crate::fit::ellipse::PlaneFit;
use crate::fit::ellipsoid::InertialFit;
use crate::fit::minmax::MinMaxCalibration;
use crate::fit::model::FieldCalibration;
use crate::fit::ref_ls::RefLsFit;
use crate::io::autopilot::AutopilotLog;
use crate::io::recording::Recording;
use crate::io::{Diagnostics, ImportReport, SensorFrame};
use crate::reference::{choose_reference, ReferenceOptions, ReferenceSource};

mod attitude;
pub mod autopilot;
mod context;
mod methods;
pub mod selection;

pub use attitude::AttitudeHeading;
use context::{
    conditions, declination_used, field_and_reference_notes, split, turn_onto_raw_heading,
};
pub use context::{expected_field_of, inertial_options, plane_options, Split};
use methods::{fit_ellipse, fit_ellipsoid, fit_min_max, fit_ref_ls, MethodInputs, MethodOutputs};

/// A calibration method.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    MinMax,
    Ellipse,
    Ellipsoid,
    RefLs,
}

impl Method {
    pub const ALL: [Method; 4] = [
        Method::MinMax,
        Method::Ellipse,
        Method::Ellipsoid,
        Method::RefLs,
    ];

    /// The method's name in JSON and in the page's element ids.
    pub fn key(self) -> &'static str {
        match self {
            Method::MinMax => "min_max",
            Method::Ellipse => "ellipse",
            Method::Ellipsoid => "ellipsoid",
            Method::RefLs => "ref_ls",
        }
    }

    pub fn label(self) -> &'static str {
        match self {
            Method::MinMax => "min/max",
            Method::Ellipse => "ellipse (tilt-aware 2D)",
            Method::Ellipsoid => "ellipsoid (3D)",
            Method::RefLs => "reference LS (Eq. 8)",
        }
    }
}

/// Where the declination comes from.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum DeclinationChoice {
    /// The World Magnetic Model at the log's first position and date, else zero.
    Auto,
    Degrees(f64),
}

/// Choices that change the result.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CalibrationOptions {
    pub methods: Vec<Method>,
    /// Samples up to this time train the methods; later ones check them. `None` splits
    /// the samples that have a reference heading in half by count (or trains on
    /// everything when there is no reference).
    pub train_until_s: Option<f64>,
    pub declination: DeclinationChoice,
    /// Window over which specific force is averaged to give roll and pitch (s).
    pub gravity_window_s: f64,
    /// Which reference heading to fit to and check against, and its gates.
    pub reference: ReferenceOptions,
    /// Where the log was recorded (latitude, longitude in degrees), for logs without a
    /// GNSS fix (indoors): the magnetic model needs a place.
    pub position_deg: Option<(f64, f64)>,
}

impl Default for CalibrationOptions {
    fn default() -> Self {
        CalibrationOptions {
            methods: Method::ALL.to_vec(),
            train_until_s: None,
            declination: DeclinationChoice::Auto,
            gravity_window_s: 1.0,
            reference: ReferenceOptions::default(),
            position_deg: None,
        }
    }
}

/// The most train samples a fit sees (evenly thinned beyond).
const MAX_FIT_SAMPLES: usize = 20_000;
/// The longest gap (s) across which a temperature or a gyro heading is interpolated.
const MAX_CONDITION_GAP_S: f64 = 2.0;
/// A measured field this many times off the expected one is a unit or a magnet problem.
const FIELD_RATIO_WARNING: f64 = 2.0;

/// The declination used, and where it came from.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DeclinationUsed {
    pub declination_deg: f64,
    pub source: String,
}

/// The source of a declination nobody knows (0° is used).
pub const NO_DECLINATION_SOURCE: &str = "none known (0°)";

impl DeclinationUsed {
    /// Whether the declination came from somewhere (the user, the magnetic model): a
    /// heading with it added is then from true north.
    pub fn is_known(&self) -> bool {
        self.source != NO_DECLINATION_SOURCE
    }
}

/// One method's result.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MethodReport {
    pub method: Method,
    pub label: &'static str,
    /// The fitted parameters, as the method reports them; absent when it failed.
    pub parameters: Option<MethodParameters>,
    /// Why the method could not be fitted, and what to do.
    pub error: Option<String>,
    /// Heading error against the reference on the train and check parts.
    pub heading_error_train: Option<HeadingErrorStats>,
    pub heading_error_check: Option<HeadingErrorStats>,
}

/// The parameters of each method, serialised as that method's own result.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(untagged)]
pub enum MethodParameters {
    MinMax(MinMaxCalibration),
    Ellipse(Box<PlaneFit>),
    Ellipsoid(Box<InertialFit>),
    RefLs(RefLsFit),
}

/// The hard iron a device estimated itself (Android's `TYPE_MAGNETIC_FIELD_UNCALIBRATED`
/// bias), body frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct DeviceHardIron {
    /// Its mean over the log.
    pub mean_ut: Vector3<f64>,
    /// How far it moved from its first value during the log (0 when the device kept
    /// one estimate throughout).
    pub max_change_ut: f64,
}

impl DeviceHardIron {
    fn of(recording: &Recording) -> Option<DeviceHardIron> {
        let values = &recording.mag_bias_in_body_ut.values;
        let first_ut = *values.first()?;
        let mean_ut = values.iter().sum::<Vector3<f64>>() / values.len() as f64;
        let max_change_ut = values
            .iter()
            .map(|value| (value - first_ut).norm())
            .fold(0.0, f64::max);
        Some(DeviceHardIron {
            mean_ut,
            max_change_ut,
        })
    }
}

/// What `compass-pdr calibrate --json` prints and the page shows.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CalibrationReport {
    pub file_name: String,
    pub format: &'static str,
    pub n_mag_samples: usize,
    /// Magnetometer samples with a tilt (an accelerometer sample near them, or none
    /// needed).
    pub n_samples_used: usize,
    pub n_train: usize,
    pub n_check: usize,
    pub train_until_s: Option<f64>,
    pub reference: Option<ReferenceSource>,
    pub declination: DeclinationUsed,
    pub expected_field: Option<ExpectedField>,
    /// Mean raw field magnitude, to set beside the expected one.
    pub mean_raw_field_ut: f64,
    /// The device's own hard-iron estimate, where the log has one, to set beside the
    /// fitted ones. No method uses it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub device_hard_iron: Option<DeviceHardIron>,
    /// The uncalibrated heading (levelled raw field plus declination) as a baseline.
    pub raw_heading_error_train: Option<HeadingErrorStats>,
    pub raw_heading_error_check: Option<HeadingErrorStats>,
    /// The samples' mean trust in their tilt, 0 to 1 ([`GravityEstimate::tilt_trust_at`]):
    /// below a half, the headings the methods are checked with are levelled with a tilt
    /// the accelerometer mostly got wrong.
    pub tilt_trust_mean: f64,
    pub methods: Vec<MethodReport>,
    /// The field-domain method of the analysis's one best heading ([`crate::analysis::calibration::selection`]):
    /// [`calibrate`] sets the best of the field-domain methods alone (the lowest check
    /// RMS, never worse than uncalibrated; without a reference, by the fits' own
    /// figures); the pipeline's heading stage ([`crate::pipeline::headings`]) replaces it
    /// with the base of the best of every heading model. `None` when uncalibrated (or a
    /// network on it) is the choice.
    pub best: Option<Method>,
    /// That choice (a row key such as `ellipsoid+fourier`), and why.
    pub choice: Option<Choice>,
    pub notes: Vec<String>,
    pub diagnostics: Diagnostics,
    /// How the log's raw magnetometer values became the body-axes µT every method is
    /// fitted in: what an exported calibration is turned back with
    /// ([`crate::fit::export::SensorCalibration`]).
    pub mag_frame: Option<SensorFrame>,
    /// An autopilot log's compasses calibrated and written back as its parameters.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub autopilot: Option<autopilot::AutopilotCalibration>,
}

/// An ellipse as (centre, the matrix mapping a circle of the radius onto it, radius).
pub type FittedEllipse = (Vector2<f64>, nalgebra::Matrix2<f64>, f64);

/// The report with the per-sample series the plots draw.
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrationAnalysis {
    pub report: CalibrationReport,
    pub t_s: Vec<f64>,
    /// The raw magnetometer samples (body axes, µT) and the tilt at each: what every
    /// method corrects, for anyone who wants to score another calibration on them.
    pub mag_ut: Vec<Vector3<f64>>,
    pub tilt: Vec<Tilt>,
    /// Levelled raw field, and the same after the best level-plane correction (the
    /// ellipse method, else min/max).
    pub level_raw_ut: Vec<Vector2<f64>>,
    pub level_corrected_ut: Vec<Vector2<f64>>,
    /// The ellipse that correction undoes, as centre, the matrix mapping the circle of
    /// radius `radius_ut` onto it, and the radius.
    pub fitted_ellipse: Option<FittedEllipse>,
    pub ref_heading_deg: Vec<Option<f64>>,
    pub raw_heading_deg: Vec<f64>,
    /// Each fitted method's heading per sample.
    pub headings_deg: Vec<(Method, Vec<f64>)>,
    /// An autopilot log's heading per sample with its calibration in force, as the
    /// autopilot applies it ([`autopilot::InForce`]): the heading the vehicle flies
    /// with, beside the new calibrations. With the autopilot's name.
    pub in_force_heading_deg: Option<(&'static str, Vec<f64>)>,
    /// |B| raw and after the best 3D correction available (the ellipsoid's, else the
    /// ellipse method's).
    pub field_raw_ut: Vec<f64>,
    pub field_corrected_ut: Vec<f64>,
    /// Conditions at each sample, for the heading models that learn from them: the
    /// temperature, and the integrated gyro heading (relative to its start).
    pub temp_c: Vec<Option<f64>>,
    pub gyro_heading_deg: Vec<Option<f64>>,
    /// The attitude filter's heading and its 1σ at each sample, `None` without a
    /// gyroscope and an accelerometer: a base of the heading comparison, the network's
    /// gyro heading and the dead reckoning's heading noise (`attitude.rs`).
    pub attitude_heading: Option<AttitudeHeading>,
    /// Down at each accelerometer sample, which levelled the samples and the gyro:
    /// estimated once, shared by the stages after (shared, not copied, by a clone).
    pub gravity: Arc<GravityEstimate>,
    /// The train/check split every heading figure of the analysis is on.
    pub split: Split,
}

impl CalibrationReport {
    /// The report of `method`, if it was run.
    pub fn method(&self, method: Method) -> Option<&MethodReport> {
        self.methods.iter().find(|report| report.method == method)
    }

    /// Why no method could be fitted (each method's reason, which says what to record),
    /// when none was; `None` when one was.
    pub fn why_no_method_fitted(&self) -> Option<String> {
        if self.methods.iter().any(|report| report.error.is_none()) {
            return None;
        }
        let reasons: Vec<String> = self
            .methods
            .iter()
            .filter_map(|report| Some(format!("{}: {}", report.label, report.error.as_deref()?)))
            .collect();
        Some(reasons.join(" "))
    }
}

impl CalibrationAnalysis {
    /// The 3D calibration to store in a device (C snippet, MotionCal packet), chosen by
    /// [`crate::analysis::calibration::selection::device_calibration`].
    pub fn device_calibration(&self) -> Option<(Method, FieldCalibration)> {
        crate::analysis::calibration::selection::device_calibration(&self.report)
    }
}

/// What every method of one log stands on: the tilted samples, the reference at each,
/// the declination, the expected field, the split and the levelled field.
struct Prepared {
    samples: crate::analysis::levelled::TiltedSamples,
    reference: Option<crate::reference::Reference>,
    ref_heading_rad: Vec<Option<f64>>,
    expected: Option<ExpectedField>,
    declination: DeclinationUsed,
    split: Split,
    level_raw_ut: Vec<Vector2<f64>>,
    raw_heading_rad: Vec<f64>,
}

impl Prepared {
    /// The heading error statistics on the train part and on the check part.
    fn both_stats(
        &self,
        headings_rad: &[f64],
    ) -> (Option<HeadingErrorStats>, Option<HeadingErrorStats>) {
        HeadingErrorStats::on_both_parts(headings_rad, &self.ref_heading_rad, &self.split.is_train)
    }
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

/// Where down comes from when a log is levelled.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum DownFrom {
    /// The autopilot's own attitude estimate where it logged one (its accelerometer
    /// reads the thrust in flight), else the accelerometer.
    AutopilotAttitude,
    /// The accelerometer averaged over the gravity window.
    Accelerometer,
}

/// The samples levelled and the conditions at each: what a calibration takes from the
/// magnetometer, the accelerometer and the gyroscope alone, so a second calibration of
/// the same sensors with other options (or fewer fixes) can take it from the first.
struct Levelled {
    gravity: Arc<GravityEstimate>,
    samples: TiltedSamples,
    temp_c: Vec<Option<f64>>,
    gyro_heading_deg: Vec<Option<f64>>,
    /// The attitude filter's heading when it was computed already (a calibration run
    /// again on the same sensors keeps it).
    attitude_heading: Option<Option<AttitudeHeading>>,
}

impl Levelled {
    /// Down, the tilted samples and the conditions of `recording`. Down is an
    /// autopilot's own attitude estimate's where the log is an autopilot's (its
    /// accelerometer reads the thrust in flight), else from the accelerometer.
    fn of(
        file_name: &str,
        recording: &Recording,
        import: (Option<&crate::io::HeaderInfo>, &Diagnostics, usize),
        options: &CalibrationOptions,
        down: DownFrom,
    ) -> Result<Levelled, AnalysisError> {
        let (header, diagnostics, n_data_lines) = import;
        let tau_s = options.gravity_window_s;
        let from_attitude = match down {
            DownFrom::AutopilotAttitude => gravity_from_attitude(&recording.attitude, tau_s),
            DownFrom::Accelerometer => None,
        };
        let gravity = Arc::new(from_attitude.unwrap_or_else(|| gravity_of(recording, tau_s)));
        let samples = crate::analysis::levelled::tilted_samples(
            file_name,
            recording,
            header,
            diagnostics,
            n_data_lines,
            &gravity,
        )?;
        let (temp_c, gyro_heading_deg) = conditions(recording, &samples.t_s, &gravity);
        Ok(Levelled {
            gravity,
            samples,
            temp_c,
            gyro_heading_deg,
            attitude_heading: None,
        })
    }

    /// What `previous` levelled (its notes on the levelling are in its report).
    fn of_analysis(previous: &CalibrationAnalysis) -> Levelled {
        let levelling = Levelling::of(&previous.gravity);
        Levelled {
            gravity: previous.gravity.clone(),
            samples: TiltedSamples {
                t_s: previous.t_s.clone(),
                mag_ut: previous.mag_ut.clone(),
                tilt: previous.tilt.clone(),
                tilt_trust: previous.gravity.tilt_trust_at(&previous.t_s),
                levelling,
                notes: Vec::new(),
            },
            temp_c: previous.temp_c.clone(),
            gyro_heading_deg: previous.gyro_heading_deg.clone(),
            attitude_heading: Some(previous.attitude_heading.clone()),
        }
    }
}

/// Finds the reference and the declination, splits the log and levels the field.
fn prepare(
    recording: &Recording,
    (samples, gravity): (TiltedSamples, &GravityEstimate),
    (options, autopilot_declination): (&CalibrationOptions, Option<(f64, &str)>),
    notes: &mut Vec<String>,
) -> Prepared {
    notes.extend(samples.notes.iter().cloned());
    let reference = choose_reference(recording, gravity, &options.reference);
    let mut ref_heading_rad: Vec<Option<f64>> = samples
        .t_s
        .iter()
        .map(|&t_s| {
            reference.as_ref().and_then(|reference| {
                reference
                    .heading_rad
                    .interpolate_angle_at(t_s, reference.max_gap_s)
            })
        })
        .collect();
    let expected = expected_field_of(recording, options.position_deg, notes);
    let declination = declination_used(
        (options.declination, autopilot_declination),
        expected.as_ref(),
        reference.as_ref().map(|reference| reference.source),
        notes,
    );
    let split = split(&samples.t_s, &ref_heading_rad, options.train_until_s, notes);
    let level_raw_ut: Vec<Vector2<f64>> = samples
        .mag_ut
        .iter()
        .zip(&samples.tilt)
        .map(|(&mag, tilt)| tilt.level(mag))
        .collect();
    let declination_rad = declination.declination_deg.to_radians();
    let raw_heading_rad: Vec<f64> = level_raw_ut
        .iter()
        .map(|&level| heading_rad(level, declination_rad))
        .collect();
    if let Some(reference) = reference
        .as_ref()
        .filter(|reference| !reference.source.is_absolute())
    {
        notes.push(turn_onto_raw_heading(
            reference.source,
            &raw_heading_rad,
            &mut ref_heading_rad,
        ));
    }
    Prepared {
        samples,
        reference,
        ref_heading_rad,
        expected,
        declination,
        split,
        level_raw_ut,
        raw_heading_rad,
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

/// Runs the chosen methods on an imported log.
pub fn calibrate(
    report: ImportReport,
    options: &CalibrationOptions,
) -> Result<CalibrationAnalysis, AnalysisError> {
    calibrate_levelled(report, options, None)
}

/// [`calibrate`] again on the recording `previous` was calibrated from, with other
/// options (another reference, split or methods) or fewer GNSS fixes, taking the
/// levelled samples and the conditions from `previous` rather than computing them
/// again. The caller vouches that the magnetometer, accelerometer and gyroscope are
/// `previous`'s. Everything is computed afresh when that cannot hold: another gravity
/// window, another number of magnetometer samples, or other fixes where `previous`'s
/// down took speeds from its fixes ([`GravityEstimate::holds_with_gnss`]).
pub fn calibrate_again(
    previous: &CalibrationAnalysis,
    report: ImportReport,
    options: &CalibrationOptions,
) -> Result<CalibrationAnalysis, AnalysisError> {
    let same_sensors = previous.gravity.tau_s() == options.gravity_window_s
        && previous.report.n_mag_samples == report.recording.mag_in_body_ut.len()
        && previous.gravity.holds_with_gnss(&report.recording.gnss);
    let levelled = same_sensors.then(|| Levelled::of_analysis(previous));
    calibrate_levelled(report, options, levelled)
}

/// [`calibrate`] with the levelling given, or computed when it is `None`.
fn calibrate_levelled(
    report: ImportReport,
    options: &CalibrationOptions,
    levelled: Option<Levelled>,
) -> Result<CalibrationAnalysis, AnalysisError> {
    let ImportReport {
        file_name,
        format,
        recording,
        diagnostics,
        header,
        n_data_lines,
        mut notes,
        mag_frame,
        autopilot,
    } = report;
    let Levelled {
        gravity,
        samples,
        temp_c,
        gyro_heading_deg,
        attitude_heading,
    } = match levelled {
        Some(levelled) => levelled,
        None => Levelled::of(
            &file_name,
            &recording,
            (header.as_ref(), &diagnostics, n_data_lines),
            options,
            if autopilot.is_some() {
                DownFrom::AutopilotAttitude
            } else {
                DownFrom::Accelerometer
            },
        )?,
    };
    let declination = autopilot.as_ref().and_then(AutopilotLog::declination_deg);
    let prepared = prepare(
        &recording,
        (samples, &gravity),
        (options, declination),
        &mut notes,
    );
    let autopilot_calibration = autopilot.as_ref().and_then(|log| {
        let truth = autopilot::Truth::of(prepared.expected.as_ref(), &prepared.declination);
        autopilot::autopilot_calibration(log, &recording.attitude, &truth)
    });
    let mut outputs = MethodOutputs {
        plane_correction: None,
        field_corrected_ut: None,
        notes: &mut notes,
    };
    let (method_reports, headings_deg) = run_methods(
        &options.methods,
        &prepared,
        mag_frame.as_ref(),
        &mut outputs,
    );
    let MethodOutputs {
        plane_correction,
        field_corrected_ut,
        ..
    } = outputs;
    let in_force_heading_deg = in_force_headings_deg(autopilot.as_ref(), &recording, &prepared);
    let (raw_train, raw_check) = prepared.both_stats(&prepared.raw_heading_rad);
    let scored = scored_methods(raw_train, raw_check, &method_reports);
    let by_reference = choose_by_reference(&scored);
    let Prepared {
        samples,
        reference,
        ref_heading_rad,
        expected,
        declination,
        split,
        level_raw_ut,
        raw_heading_rad,
    } = prepared;
    let field_raw_ut: Vec<f64> = samples.mag_ut.iter().map(Vector3::norm).collect();
    let mean_raw_field_ut = field_raw_ut.iter().sum::<f64>() / field_raw_ut.len().max(1) as f64;
    notes.extend(field_and_reference_notes(
        mean_raw_field_ut,
        expected.as_ref(),
        reference.is_some(),
    ));
    let (level_corrected_ut, fitted_ellipse) =
        plane_correction.unwrap_or_else(|| (level_raw_ut.clone(), None));
    let mut analysis = CalibrationAnalysis {
        report: CalibrationReport {
            file_name,
            format,
            n_mag_samples: recording.mag_in_body_ut.len(),
            n_samples_used: samples.t_s.len(),
            n_train: split.n_train,
            n_check: split.n_check,
            train_until_s: split.train_until_s,
            reference: reference.map(|reference| reference.source),
            declination,
            expected_field: expected,
            mean_raw_field_ut,
            device_hard_iron: DeviceHardIron::of(&recording),
            raw_heading_error_train: raw_train,
            raw_heading_error_check: raw_check,
            tilt_trust_mean: samples.tilt_trust.iter().sum::<f64>()
                / samples.tilt_trust.len().max(1) as f64,
            methods: method_reports,
            best: None,
            choice: by_reference,
            notes,
            diagnostics,
            mag_frame,
            autopilot: autopilot_calibration,
        },
        t_s: samples.t_s,
        mag_ut: samples.mag_ut,
        tilt: samples.tilt,
        level_raw_ut,
        level_corrected_ut,
        fitted_ellipse,
        ref_heading_deg: ref_heading_rad
            .iter()
            .map(|reference| reference.map(f64::to_degrees))
            .collect(),
        raw_heading_deg: raw_heading_rad
            .iter()
            .map(|heading| heading.to_degrees())
            .collect(),
        headings_deg,
        in_force_heading_deg,
        field_corrected_ut: field_corrected_ut.unwrap_or_default(),
        temp_c,
        gyro_heading_deg,
        attitude_heading: None,
        field_raw_ut,
        gravity,
        split,
    };
    settle_choice(&mut analysis.report);
    analysis.attitude_heading = attitude_heading
        .unwrap_or_else(|| attitude::attitude_heading(&recording, &analysis.report, &analysis.t_s));
    Ok(analysis)
}

/// The calibration's own choice of best (by the reference where it scored the methods,
/// else by the fits' own figures; the heading stage may replace it), and a note when no
/// method could be fitted.
fn settle_choice(report: &mut CalibrationReport) {
    let by_reference = report.choice.take();
    let choice = selection::settle(by_reference, report);
    report.best = Method::ALL
        .into_iter()
        .find(|method| method.key() == choice.key);
    report.choice = Some(choice);
    if report.why_no_method_fitted().is_some() {
        // Nothing to calibrate with: the analysis goes on uncalibrated (the headings, the
        // in-force calibration's judgement, the dead reckoning) and says so; each
        // method's report says why it failed and what to record. `compass-pdr
        // calibrate` refuses (it has nothing to give).
        report.notes.push(
            "No calibration could be fitted, so the headings are the uncalibrated ones: each \
             method says why and what to record."
                .to_string(),
        );
    }
}

/// The heading at every sample with an autopilot's calibration in force, levelled and
/// turned by the declination as every method's heading is, with the autopilot's name;
/// `None` unless the recording's magnetometer is the autopilot's main compass.
fn in_force_headings_deg(
    log: Option<&crate::io::autopilot::AutopilotLog>,
    recording: &Recording,
    prepared: &Prepared,
) -> Option<(&'static str, Vec<f64>)> {
    let in_force = autopilot::InForce::of(log?, &recording.mag_in_body_ut)?;
    let samples = &prepared.samples;
    let declination_rad = prepared.declination.declination_deg.to_radians();
    let headings_deg = crate::base::par::map(&samples.mag_ut, |idx, &raw_ut| {
        let tilt = samples.tilt.get(idx).copied().unwrap_or(Tilt::LEVEL);
        let corrected_ut = in_force.corrected_ut(samples.t_s[idx], raw_ut);
        heading_rad(tilt.level(corrected_ut), declination_rad).to_degrees()
    });
    Some((in_force.autopilot(), headings_deg))
}

/// Uncalibrated and every method, as the selection scores them.
fn scored_methods(
    raw_train: Option<HeadingErrorStats>,
    raw_check: Option<HeadingErrorStats>,
    method_reports: &[MethodReport],
) -> Vec<Scored<'_>> {
    let mut scored = vec![Scored {
        key: RAW_KEY,
        label: "uncalibrated",
        train_rms_deg: raw_train.map(|stats| stats.rms_deg),
        check_rms_deg: raw_check.map(|stats| stats.rms_deg),
    }];
    scored.extend(method_reports.iter().map(|report| Scored {
        key: report.method.key(),
        label: report.label,
        train_rms_deg: report.heading_error_train.map(|stats| stats.rms_deg),
        check_rms_deg: report.heading_error_check.map(|stats| stats.rms_deg),
    }));
    scored
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::canonical_csv;
    use crate::io::import::import;
    use crate::sim::walk::{simulate, WalkConfig};

    fn demo_like(seed: u64) -> ImportReport {
        let text = canonical_csv::write(&simulate(&WalkConfig::from_seed(seed, 120.0)));
        import("walk.csv", text.as_bytes()).expect("readable")
    }

    fn check_rms(analysis: &CalibrationAnalysis, method: Method) -> f64 {
        analysis
            .report
            .method(method)
            .and_then(|report| report.heading_error_check)
            .map_or(f64::INFINITY, |stats| stats.rms_deg)
    }

    #[test]
    fn a_calibration_run_again_gives_what_a_fresh_one_gives() {
        let report = demo_like(23);
        let first = calibrate(report.clone(), &CalibrationOptions::default()).expect("calibrates");
        let other = CalibrationOptions {
            train_until_s: Some(f64::INFINITY),
            methods: vec![Method::MinMax, Method::Ellipse],
            ..CalibrationOptions::default()
        };
        let fresh = calibrate(report.clone(), &other).expect("calibrates");
        let again = calibrate_again(&first, report, &other).expect("calibrates");
        assert!(std::sync::Arc::ptr_eq(&again.gravity, &first.gravity));
        assert_eq!(again.t_s, fresh.t_s);
        assert_eq!(again.tilt, fresh.tilt);
        assert_eq!(again.gyro_heading_deg, fresh.gyro_heading_deg);
        assert_eq!(again.headings_deg, fresh.headings_deg);
        assert_eq!(again.report.methods, fresh.report.methods);
        // Another gravity window is levelled afresh.
        let wider = CalibrationOptions {
            gravity_window_s: 2.0,
            ..other
        };
        let rewound = calibrate_again(&first, demo_like(23), &wider).expect("calibrates");
        assert!(!std::sync::Arc::ptr_eq(&rewound.gravity, &first.gravity));
        assert_eq!(rewound.gravity.tau_s(), 2.0);
    }

    #[test]
    fn a_walk_is_split_in_half_and_every_level_method_beats_no_calibration() {
        let analysis =
            calibrate(demo_like(21), &CalibrationOptions::default()).expect("calibrates");
        let report = &analysis.report;
        assert_eq!(report.reference, Some(ReferenceSource::Column));
        assert_eq!(report.n_train + report.n_check, report.n_samples_used);
        assert!(
            report
                .train_until_s
                .is_some_and(|until_s| (until_s - 60.0).abs() < 1.0),
            "{:?}",
            report.train_until_s
        );
        let raw_rms = report
            .raw_heading_error_check
            .map_or(0.0, |stats| stats.rms_deg);
        for method in Method::ALL {
            let rms = check_rms(&analysis, method);
            assert!(
                rms < 3.0 && rms < raw_rms / 5.0,
                "{method:?}: {rms}° against {raw_rms}° uncalibrated"
            );
        }
        // A walk held nearly level: the 3D fit leans on the accelerometer's tilt and the
        // model's field, and says what it could not see instead of refusing.
        let Some(MethodParameters::Ellipsoid(fit)) =
            &report.method(Method::Ellipsoid).expect("ran").parameters
        else {
            panic!("the ellipsoid fitted")
        };
        assert!(fit.uses_dip, "{fit:?}");
        let device = analysis.device_calibration().map(|(method, _)| method);
        let lower =
            if check_rms(&analysis, Method::Ellipse) < check_rms(&analysis, Method::Ellipsoid) {
                Method::Ellipse
            } else {
                Method::Ellipsoid
            };
        assert_eq!(device, Some(lower));
        assert_eq!(analysis.field_corrected_ut.len(), analysis.t_s.len());
    }

    #[test]
    fn a_sphere_with_a_hole_says_which_way_to_turn() {
        use crate::base::rng::SplitMix64;
        use crate::sim::field::{full_sphere, FieldTruth};
        let mut rng = SplitMix64::new(5);
        let truth = FieldTruth::random(&mut rng, 30.0, 0.05, 0.05);
        let mut recording = Recording::default();
        let field_in_ned = truth.field_in_ned_ut();
        // Leave out every attitude whose body x axis points along the field.
        let samples = full_sphere(&truth, 4000, &mut rng)
            .into_iter()
            .filter(|sample| {
                let ned_from_body = nalgebra::Rotation3::from_euler_angles(
                    sample.roll_rad,
                    sample.pitch_rad,
                    sample.heading_rad,
                );
                (ned_from_body.inverse() * field_in_ned).normalize().x < 0.5
            });
        for (idx, sample) in samples.enumerate() {
            recording
                .mag_in_body_ut
                .push(idx as f64 * 0.01, sample.mag_ut);
        }
        let report = ImportReport {
            autopilot: None,
            file_name: "cap.csv".to_string(),
            format: "test",
            recording,
            diagnostics: Diagnostics::default(),
            header: None,
            n_data_lines: 0,
            notes: Vec::new(),
            mag_frame: None,
        };
        let options = CalibrationOptions {
            methods: vec![Method::Ellipsoid],
            ..CalibrationOptions::default()
        };
        let analysis =
            calibrate(report, &options).expect("the ellipsoid fits a sphere with a hole");
        let note = analysis
            .report
            .notes
            .iter()
            .find(|note| note.contains("of the sphere is uncovered"));
        assert!(
            note.is_some_and(|note| note.contains("+x axis")),
            "{:?}",
            analysis.report.notes
        );
    }

    #[test]
    fn a_given_declination_turns_every_heading_by_it() {
        let options = |declination| CalibrationOptions {
            methods: vec![Method::MinMax],
            declination,
            ..CalibrationOptions::default()
        };
        let plain = calibrate(demo_like(22), &options(DeclinationChoice::Degrees(0.0)))
            .expect("calibrates");
        let turned = calibrate(demo_like(22), &options(DeclinationChoice::Degrees(10.0)))
            .expect("calibrates");
        let (plain_deg, turned_deg) = (&plain.headings_deg[0].1, &turned.headings_deg[0].1);
        for (a_deg, b_deg) in plain_deg.iter().zip(turned_deg) {
            let difference_deg =
                crate::base::angle::heading_difference_rad(b_deg.to_radians(), a_deg.to_radians())
                    .to_degrees();
            assert!((difference_deg - 10.0).abs() < 1e-9);
        }
        assert_eq!(turned.report.declination.source, "given by the user");
    }

    #[test]
    fn without_a_position_an_autopilot_s_own_declination_is_used() {
        let decl = |choice, expected, autopilot| {
            context::declination_used(
                (choice, autopilot),
                expected,
                Some(crate::reference::ReferenceSource::Column),
                &mut Vec::new(),
            )
        };
        let own = decl(DeclinationChoice::Auto, None, Some((3.99, "EKF2_MAG_DECL")));
        assert_eq!(own.declination_deg, 3.99);
        assert!(
            own.source.contains("EKF2_MAG_DECL") && own.is_known(),
            "{own:?}"
        );
        // The user's, and the magnetic model's where the log has a position, come first.
        let users = decl(
            DeclinationChoice::Degrees(-2.0),
            None,
            Some((3.99, "EKF2_MAG_DECL")),
        );
        assert_eq!(users.declination_deg, -2.0);
        let model =
            crate::earth::wmm::expected_field(47.4, 8.5, 0.0, "2023-03-17".parse().unwrap())
                .unwrap();
        let wmm = decl(
            DeclinationChoice::Auto,
            Some(&model),
            Some((3.99, "EKF2_MAG_DECL")),
        );
        assert_eq!(wmm.declination_deg, model.declination_deg);
        assert!(!decl(DeclinationChoice::Auto, None, None).is_known());
    }
}
