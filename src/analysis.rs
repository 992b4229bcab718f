//! The analysis pipeline that the CLI and the page share: bytes of a log in, a
//! calibration with its heading errors out.
//!
//! Today it runs the min/max calibration of the 2007 paper's five steps: level the field
//! with the accelerometer (Eq. 4), fit Eq. 7, correct with Eq. 6, compute the heading
//! (Eq. 1) and add the declination. Headings before and after calibration are compared
//! with the log's reference heading where it has one.

use nalgebra::Vector2;
use serde::Serialize;
use thiserror::Error;

use crate::angle::heading_difference_rad;
use crate::calib::heading::heading_rad;
use crate::calib::minmax::MinMaxCalibration;
use crate::calib::tilt::{smooth_specific_force, Tilt};
use crate::calib::CalibError;
use crate::io::import::import_files;
use crate::io::{Diagnostics, ImportError, ImportReport};
use crate::stats::HeadingErrorStats;

/// Choices that change the result.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Options {
    /// True north from magnetic north, east positive, added to every heading.
    pub declination_deg: f64,
    /// Window over which specific force is averaged to give roll and pitch (s).
    pub gravity_window_s: f64,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            declination_deg: 0.0,
            gravity_window_s: 1.0,
        }
    }
}

/// The longest gap (s) across which the accelerometer or the reference heading is
/// interpolated to a magnetometer sample's time.
const MAX_INTERPOLATION_GAP_S: f64 = 0.5;

/// How the field was levelled.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Levelling {
    /// Roll and pitch from the accelerometer, averaged over a window.
    Accelerometer { window_s: f64 },
    /// No accelerometer in the log: the device was assumed level.
    AssumedLevel,
}

/// Everything the min/max analysis of one file produced, with the per-sample series the
/// plots draw.
#[derive(Debug, Clone, PartialEq)]
pub struct MinMaxAnalysis {
    pub summary: MinMaxSummary,
    /// Time of each magnetometer sample used.
    pub t_s: Vec<f64>,
    /// Levelled raw field (Xh, Yh) and the same after Eq. 6.
    pub level_raw_ut: Vec<Vector2<f64>>,
    pub level_corrected_ut: Vec<Vector2<f64>>,
    /// Heading before and after calibration, and the reference where there is one.
    pub heading_before_deg: Vec<f64>,
    pub heading_after_deg: Vec<f64>,
    pub ref_heading_deg: Vec<Option<f64>>,
}

/// What the CLI prints as JSON and the page shows as figures.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MinMaxSummary {
    pub file_name: String,
    pub method: &'static str,
    pub options: Options,
    pub levelling: Levelling,
    pub n_mag_samples: usize,
    /// Magnetometer samples used: those with an accelerometer sample near them when the
    /// field is levelled.
    pub n_samples_used: usize,
    pub calibration: MinMaxCalibration,
    /// Heading error against the reference, before and after calibration; absent when
    /// the log has no reference heading.
    pub heading_error_before: Option<HeadingErrorStats>,
    pub heading_error_after: Option<HeadingErrorStats>,
    /// Things the user should know about the result.
    pub notes: Vec<String>,
    pub diagnostics: Diagnostics,
    pub n_data_lines: usize,
}

/// Why a file could not be analysed. Each message names the file and what to do.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum AnalysisError {
    #[error(transparent)]
    Import(#[from] ImportError),

    #[error(
        "{file_name} has no magnetometer columns: its header (line {header_line}) has {found}. \
         Name them mag_x_ut, mag_y_ut, mag_z_ut (microtesla, body axes x forward, y right, z down)."
    )]
    NoMagnetometerColumns {
        file_name: String,
        header_line: usize,
        found: String,
    },

    #[error("{file_name}: none of its {n_data_lines} data lines has a usable magnetometer sample{first_problem}. Check that the log holds numbers in mag_x_ut, mag_y_ut and mag_z_ut.")]
    NoMagnetometerSamples {
        file_name: String,
        n_data_lines: usize,
        first_problem: String,
    },

    #[error("{file_name}: the accelerometer does not overlap the magnetometer in time, so the field cannot be levelled. Check the t_s column.")]
    NoLevelledSamples { file_name: String },

    #[error("{file_name}: {source}")]
    Calibration {
        file_name: String,
        source: CalibError,
    },
}

/// Reads a log (any format [`crate::io::import`] knows) and runs the min/max analysis.
pub fn analyse_minmax_file(
    file_name: &str,
    bytes: &[u8],
    options: Options,
) -> Result<MinMaxAnalysis, AnalysisError> {
    analyse_minmax_files(&[(file_name, bytes)], options)
}

/// Reads the files of one recording together (phyphox writes one file per sensor),
/// merges them, and runs the min/max analysis.
pub fn analyse_minmax_files(
    files: &[(&str, &[u8])],
    options: Options,
) -> Result<MinMaxAnalysis, AnalysisError> {
    analyse_minmax(import_files(files)?, options)
}

/// Runs the min/max analysis on an imported recording.
pub fn analyse_minmax(
    report: ImportReport,
    options: Options,
) -> Result<MinMaxAnalysis, AnalysisError> {
    let ImportReport {
        file_name,
        recording,
        diagnostics,
        header,
        n_data_lines,
        ..
    } = report;
    let (header_line, header_columns) =
        header.map_or((1, Vec::new()), |header| (header.line, header.columns));
    let mag = &recording.mag_in_body_ut;
    if mag.is_empty() {
        let has_mag_columns = header_columns
            .iter()
            .any(|name| name.to_ascii_lowercase().starts_with("mag_"));
        return Err(if has_mag_columns {
            let first_problem = diagnostics
                .kept
                .first()
                .map(|diagnostic| {
                    format!(
                        " (line {}: {})",
                        diagnostic.line.unwrap_or(header_line),
                        diagnostic.message
                    )
                })
                .unwrap_or_default();
            AnalysisError::NoMagnetometerSamples {
                file_name,
                n_data_lines,
                first_problem,
            }
        } else {
            AnalysisError::NoMagnetometerColumns {
                file_name,
                header_line,
                found: header_columns.join(", "),
            }
        });
    }

    // Step 1: level. Without an accelerometer the device is taken as level.
    let gravity = smooth_specific_force(&recording.acc_in_body_mps2, options.gravity_window_s);
    let levelling = if gravity.is_empty() {
        Levelling::AssumedLevel
    } else {
        Levelling::Accelerometer {
            window_s: options.gravity_window_s,
        }
    };
    let mut t_s = Vec::with_capacity(mag.len());
    let mut level_raw_ut = Vec::with_capacity(mag.len());
    for (&sample_t_s, &mag_ut) in mag.t_s.iter().zip(&mag.values) {
        let tilt = match levelling {
            Levelling::AssumedLevel => Some(Tilt::LEVEL),
            Levelling::Accelerometer { .. } => gravity
                .interpolate_at(sample_t_s, MAX_INTERPOLATION_GAP_S)
                .and_then(Tilt::from_specific_force),
        };
        if let Some(tilt) = tilt {
            t_s.push(sample_t_s);
            level_raw_ut.push(tilt.level(mag_ut));
        }
    }
    if level_raw_ut.is_empty() {
        return Err(AnalysisError::NoLevelledSamples { file_name });
    }

    // Steps 2-3: fit Eq. 7 and correct with Eq. 6.
    let calibration =
        MinMaxCalibration::fit(&level_raw_ut).map_err(|source| AnalysisError::Calibration {
            file_name: file_name.clone(),
            source,
        })?;
    let level_corrected_ut: Vec<Vector2<f64>> = level_raw_ut
        .iter()
        .map(|&sample| calibration.apply(sample))
        .collect();

    // Steps 4-5: heading and declination.
    let declination_rad = options.declination_deg.to_radians();
    let heading_before_rad: Vec<f64> = level_raw_ut
        .iter()
        .map(|&sample| heading_rad(sample, declination_rad))
        .collect();
    let heading_after_rad: Vec<f64> = level_corrected_ut
        .iter()
        .map(|&sample| heading_rad(sample, declination_rad))
        .collect();
    let ref_heading_rad: Vec<Option<f64>> = t_s
        .iter()
        .map(|&sample_t_s| {
            recording
                .ref_heading_rad
                .interpolate_angle_at(sample_t_s, MAX_INTERPOLATION_GAP_S)
        })
        .collect();
    let errors_against_reference = |headings_rad: &[f64]| {
        HeadingErrorStats::from_errors_rad(headings_rad.iter().zip(&ref_heading_rad).filter_map(
            |(&heading_rad, &reference_rad)| {
                Some(heading_difference_rad(heading_rad, reference_rad?))
            },
        ))
    };
    let heading_error_before = errors_against_reference(&heading_before_rad);
    let heading_error_after = errors_against_reference(&heading_after_rad);

    let mut notes = Vec::new();
    if levelling == Levelling::AssumedLevel {
        notes.push("The log has no accelerometer, so the device was assumed level; tilt adds heading error.".to_string());
    }
    let n_not_levelled = mag.len() - level_raw_ut.len();
    if n_not_levelled > 0 {
        notes.push(format!("{n_not_levelled} magnetometer samples had no accelerometer sample within {MAX_INTERPOLATION_GAP_S} s and were left out."));
    }
    let coverage = calibration.coverage;
    if coverage.largest_gap_deg >= 30.0 {
        notes.push(format!(
            "No data between {:.0}° and {:.0}° magnetic heading: min/max needs a full turn. Turn that way and record again.",
            coverage.largest_gap_start_deg,
            (coverage.largest_gap_start_deg + coverage.largest_gap_deg) % 360.0
        ));
    }
    if heading_error_before.is_none() {
        notes.push("The log has no reference heading (ref_heading_deg), so heading errors cannot be computed.".to_string());
    }

    Ok(MinMaxAnalysis {
        summary: MinMaxSummary {
            file_name,
            method: "minmax",
            options,
            levelling,
            n_mag_samples: mag.len(),
            n_samples_used: level_raw_ut.len(),
            calibration,
            heading_error_before,
            heading_error_after,
            notes,
            diagnostics,
            n_data_lines,
        },
        t_s,
        level_raw_ut,
        level_corrected_ut,
        heading_before_deg: heading_before_rad
            .iter()
            .map(|heading_rad| heading_rad.to_degrees())
            .collect(),
        heading_after_deg: heading_after_rad
            .iter()
            .map(|heading_rad| heading_rad.to_degrees())
            .collect(),
        ref_heading_deg: ref_heading_rad
            .iter()
            .map(|reference_rad| reference_rad.map(f64::to_degrees))
            .collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn analyse(text: &str) -> Result<MinMaxAnalysis, AnalysisError> {
        analyse_minmax_file("log.csv", text.as_bytes(), Options::default())
    }

    #[test]
    fn a_csv_without_magnetometer_columns_says_which_columns_it_has() {
        let message = analyse("t_s,acc_x_mps2,acc_y_mps2,acc_z_mps2\n0,0,0,-9.8\n")
            .map(|_| ())
            .unwrap_err()
            .to_string();
        assert!(
            message.contains("log.csv has no magnetometer columns"),
            "{message}"
        );
        assert!(message.contains("t_s, acc_x_mps2"), "{message}");
    }

    #[test]
    fn a_csv_of_nans_names_the_first_bad_line() {
        let message = analyse("t_s,mag_x_ut,mag_y_ut,mag_z_ut\n0,NaN,NaN,NaN\n1,NaN,NaN,NaN\n")
            .map(|_| ())
            .unwrap_err()
            .to_string();
        assert!(message.contains("none of its 2 data lines"), "{message}");
        assert!(message.contains("line 2: mag_x_ut is NaN"), "{message}");
    }

    #[test]
    fn a_level_turn_without_accelerometer_is_calibrated_and_says_so() {
        let mut text = String::from("t_s,mag_x_ut,mag_y_ut,mag_z_ut,ref_heading_deg\n");
        for sample_idx in 0..360 {
            let heading_rad = (sample_idx as f64).to_radians();
            let (x_ut, y_ut) = (
                10.0 + 25.0 * heading_rad.cos(),
                -5.0 - 20.0 * heading_rad.sin(),
            );
            text.push_str(&format!("{sample_idx},{x_ut},{y_ut},40,{sample_idx}\n"));
        }
        let analysis = analyse(&text).expect("analysable");
        let summary = &analysis.summary;
        assert_eq!(summary.levelling, Levelling::AssumedLevel);
        assert_eq!(summary.n_samples_used, 360);
        let after = summary.heading_error_after.expect("has a reference");
        let before = summary.heading_error_before.expect("has a reference");
        assert!(after.rms_deg < 0.1, "{after:?}");
        assert!(before.rms_deg > 10.0, "{before:?}");
        assert!(summary
            .notes
            .iter()
            .any(|note| note.contains("assumed level")));
    }
}
