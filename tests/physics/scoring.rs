//! Scoring the crate's calibrations on the independent generator's logs: every method's
//! check heading error beside the **true calibration's floor on the same samples** (the
//! generator's own `b = S⁻¹·(m − h)`, levelled with the same tilt and turned by the same
//! declination as the methods, so that the floor carries the tilt's and the reference's
//! errors and nothing of the fit's).
//!
//! Shared by the property tests (`tests/independent.rs`) and the accuracy report
//! (`benches/accuracy.rs`).

use compass_pdr::analysis::calibration::{calibrate, CalibrationAnalysis, CalibrationOptions};
use compass_pdr::analysis::headings::{compare, HeadingOptions};
use compass_pdr::attitude::compass_heading::heading_rad;
use compass_pdr::base::angle::heading_difference_rad;
use compass_pdr::base::stats::HeadingErrorStats;
use compass_pdr::fit::model::FieldCalibration;
use compass_pdr::io::import::import;

use nalgebra::{Matrix3, Vector3};

use super::GeneratedLog;

/// What one log gave.
#[derive(Debug, Clone)]
pub struct Scores {
    pub name: String,
    /// Check RMS of the true calibration (degrees), levelled with the log's own tilt
    /// estimate, and with the true tilt.
    pub floor_deg: f64,
    pub true_tilt_floor_deg: Option<f64>,
    /// Check RMS of the uncalibrated heading.
    pub raw_deg: Option<f64>,
    /// Each fitted method's check RMS, by its key, and the error of those that failed.
    pub methods: Vec<(String, Option<f64>, Option<String>)>,
    /// The field calibration the crate chose, and its check RMS.
    pub best: Option<(String, f64)>,
    /// The exported device calibration, applied as its JSON says and levelled with the
    /// true attitude ([`export_true_tilt`]); `None` when nothing is exported.
    pub export_true_tilt_deg: Option<f64>,
    /// The true calibration scored the same way ([`true_calibration_floor`]).
    pub true_calibration_floor_deg: Option<f64>,
    /// The heading method the crate chose over every row of the heading comparison
    /// (field calibrations, with the Fourier model on top, uncalibrated), and its check
    /// RMS: what a user gets.
    pub heading: Option<(String, f64)>,
}

impl Scores {
    pub fn method(&self, key: &str) -> Option<f64> {
        self.methods
            .iter()
            .find(|(method, _, _)| method == key)
            .and_then(|(_, rms, _)| *rms)
    }

    /// The chosen field calibration's check RMS over the floor.
    pub fn best_over_floor(&self) -> f64 {
        self.best
            .as_ref()
            .map_or(f64::INFINITY, |(_, rms)| rms / self.floor_deg)
    }

    /// The exported calibration's check RMS over the true calibration's, both levelled
    /// with the true attitude; infinite when nothing is exported.
    pub fn export_over_true_tilt_floor(&self) -> f64 {
        match (self.export_true_tilt_deg, self.true_calibration_floor_deg) {
            (Some(export), Some(floor)) => export / floor,
            _ => f64::INFINITY,
        }
    }

    /// The chosen heading method's check RMS over the floor.
    pub fn heading_over_floor(&self) -> f64 {
        self.heading
            .as_ref()
            .map_or(f64::INFINITY, |(_, rms)| rms / self.floor_deg)
    }
}

/// Imports the log and calibrates it with `options`.
pub fn analyse(log: &GeneratedLog, options: &CalibrationOptions) -> CalibrationAnalysis {
    let report = import(&format!("{}.csv", log.name), log.csv.as_bytes()).expect("imports");
    calibrate(report, options).expect("calibrates")
}

/// The check RMS (degrees) of `calibration` on the analysis's own samples, tilt,
/// declination, reference and split.
pub fn check_rms_of(analysis: &CalibrationAnalysis, calibration: &FieldCalibration) -> Option<f64> {
    let declination_rad = analysis.report.declination.declination_deg.to_radians();
    let train_until_s = analysis.report.train_until_s;
    let errors = analysis
        .t_s
        .iter()
        .zip(&analysis.mag_ut)
        .zip(&analysis.tilt)
        .zip(&analysis.ref_heading_deg)
        .filter(|(((&t_s, _), _), _)| train_until_s.is_some_and(|until_s| t_s > until_s))
        .filter_map(|(((_, &mag_ut), tilt), reference_deg)| {
            let heading = heading_rad(tilt.level(calibration.apply(mag_ut)), declination_rad);
            Some(heading_difference_rad(
                heading,
                (*reference_deg)?.to_radians(),
            ))
        });
    HeadingErrorStats::from_errors_rad(errors).map(|stats| stats.rms_deg)
}

/// The check RMS (degrees) of the true calibration levelled with the *true* attitude
/// (and the true declination): what a perfect tilt would leave, the reference's own
/// error and the hand's sway in heading.
pub fn true_tilt_floor(log: &GeneratedLog, analysis: &CalibrationAnalysis) -> Option<f64> {
    let (hard_iron_ut, correction) = log.true_correction();
    true_tilt_rms(log, analysis, Against::Reference, |mag_ut| {
        correction * (mag_ut - hard_iron_ut)
    })
}

/// The check RMS (degrees) of the true calibration levelled with the true attitude,
/// against the true heading: what the sensor's noise and the moving iron leave, the
/// floor [`export_true_tilt`] is judged against.
pub fn true_calibration_floor(log: &GeneratedLog, analysis: &CalibrationAnalysis) -> Option<f64> {
    let (hard_iron_ut, correction) = log.true_correction();
    true_tilt_rms(log, analysis, Against::TrueHeading, |mag_ut| {
        correction * (mag_ut - hard_iron_ut)
    })
}

/// The calibration the analysis exports for the device, written as its JSON and read
/// back from that text alone, applied as the text says (`corrected = S · (raw − h)`, in
/// the raw values' unit, times `ut_per_unit`) to the samples as the log writes them
/// (the generator's CSV is in body axes and µT), and levelled with the *true* attitude:
/// the calibration alone is judged, against the true heading, beside
/// [`true_calibration_floor`]. `None` when nothing is exported.
pub fn export_true_tilt(log: &GeneratedLog, analysis: &CalibrationAnalysis) -> Option<f64> {
    let export = compass_pdr::present::report::device_export(analysis)?;
    let text = serde_json::to_string(&export.sensor).expect("the export serialises");
    // Read back from the text alone, by its own keys, not by the crate's reader.
    let read: ExportText = serde_json::from_str(&text).expect("its text is the export's");
    // The generator writes body axes in µT: the sensor's own axes are the body's.
    assert!(read.axes == "body" || read.axes == "sensor", "{text}");
    let hard_iron = Vector3::from(read.hard_iron);
    let soft_iron = Matrix3::from_fn(|row, column| read.soft_iron[row][column]);
    let ut_per_unit = read.ut_per_unit.expect("the generator's unit is µT");
    true_tilt_rms(log, analysis, Against::TrueHeading, |mag_ut| {
        soft_iron * (mag_ut / ut_per_unit - hard_iron) * ut_per_unit
    })
}

/// The keys of an exported calibration's JSON that say how to apply it.
#[derive(serde::Deserialize)]
struct ExportText {
    axes: String,
    hard_iron: [f64; 3],
    soft_iron: [[f64; 3]; 3],
    ut_per_unit: Option<f64>,
}

/// `calibration` levelled with the true attitude, against the true heading, on the
/// check part (as [`export_true_tilt`] judges the exported one).
pub fn calibration_true_tilt(
    log: &GeneratedLog,
    analysis: &CalibrationAnalysis,
    calibration: &FieldCalibration,
) -> Option<f64> {
    true_tilt_rms(log, analysis, Against::TrueHeading, |mag_ut| {
        calibration.apply(mag_ut)
    })
}

/// The check RMS (degrees) of the heading of `correct`ed samples levelled with the true
/// attitude and turned by the true declination, against the analysis's reference.
fn true_tilt_rms(
    log: &GeneratedLog,
    analysis: &CalibrationAnalysis,
    against: Against,
    correct: impl Fn(Vector3<f64>) -> Vector3<f64>,
) -> Option<f64> {
    let train_until_s = analysis.report.train_until_s?;
    let start_s = analysis.t_s.first().copied()? - log.true_t_s.first().copied()?;
    let errors = analysis
        .t_s
        .iter()
        .zip(&analysis.mag_ut)
        .zip(&analysis.ref_heading_deg)
        .filter(|((&t_s, _), _)| t_s > train_until_s)
        .filter_map(|((&t_s, &mag_ut), reference_deg)| {
            let idx = log
                .true_t_s
                .partition_point(|&true_t_s| true_t_s + start_s < t_s - 1e-6);
            let attitude = log.true_attitude.get(idx)?;
            let (roll, pitch, _) = attitude.euler_angles();
            let tilt = compass_pdr::attitude::tilt::Tilt::new(roll, pitch);
            let heading = heading_rad(
                tilt.level(correct(mag_ut)),
                log.declination_deg.to_radians(),
            );
            let truth_deg = match against {
                Against::Reference => (*reference_deg)?,
                Against::TrueHeading => *log.true_heading_deg.get(idx)?,
            };
            Some(heading_difference_rad(heading, truth_deg.to_radians()))
        });
    HeadingErrorStats::from_errors_rad(errors).map(|stats| stats.rms_deg)
}

/// What a heading is scored against.
#[derive(Debug, Clone, Copy)]
enum Against {
    /// The analysis's own reference (a GNSS course, a heading column): its errors are
    /// in the floor.
    Reference,
    /// The generator's true heading of the body's x axis: only the sensor's noise and the
    /// moving iron are in the floor.
    TrueHeading,
}

/// Scores every method on one log against the true calibration's floor.
pub fn score(log: &GeneratedLog, options: &CalibrationOptions) -> Scores {
    let analysis = analyse(log, options);
    let (hard_iron_ut, correction) = log.true_correction();
    let truth = FieldCalibration {
        hard_iron_ut,
        soft_iron: correction,
        field_ut: log.field_ned_ut.norm(),
    };
    let floor_deg = check_rms_of(&analysis, &truth).expect("the log has a reference on check");
    let report = &analysis.report;
    let methods = report
        .methods
        .iter()
        .map(|method| {
            (
                method.method.key().to_string(),
                method.heading_error_check.map(|stats| stats.rms_deg),
                method.error.clone(),
            )
        })
        .collect();
    let best = report.best().and_then(|best| {
        let rms = report.method(best)?.heading_error_check?.rms_deg;
        Some((best.key().to_string(), rms))
    });
    let headings = compare(
        &analysis,
        &HeadingOptions {
            calibration: options.clone(),
            neural: false,
            ..HeadingOptions::default()
        },
    );
    let key = headings.report.choice.key;
    let heading = headings
        .report
        .row(key)
        .and_then(|row| Some((key.text(), row.check?.rms_deg)));
    Scores {
        name: log.name.clone(),
        floor_deg,
        true_tilt_floor_deg: true_tilt_floor(log, &analysis),
        export_true_tilt_deg: export_true_tilt(log, &analysis),
        true_calibration_floor_deg: true_calibration_floor(log, &analysis),
        raw_deg: report.raw_heading_error_check.map(|stats| stats.rms_deg),
        methods,
        best,
        heading,
    }
}

/// The `q`-quantile (0..1) of `values` (nearest rank).
pub fn quantile(values: &[f64], q: f64) -> f64 {
    let mut sorted: Vec<f64> = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    if sorted.is_empty() {
        return f64::NAN;
    }
    let rank = ((q * sorted.len() as f64).ceil() as usize).clamp(1, sorted.len());
    sorted[rank - 1]
}
