//! What every calibration needs before it fits: magnetometer samples with the tilt at
//! each ([`tilted_samples`]), and the errors ([`AnalysisError`]) whose messages name the
//! file and what to do.

use nalgebra::Vector3;
use serde::Serialize;
use thiserror::Error;

use crate::attitude::down::{GravityEstimate, GravitySource};
use crate::attitude::tilt::Tilt;
use crate::io::recording::{Recording, Stream};
use crate::io::{Diagnostics, HeaderInfo, ImportError};

/// The longest gap (s) across which the accelerometer or the reference heading is
/// interpolated to a magnetometer sample's time.
const MAX_INTERPOLATION_GAP_S: f64 = 0.5;

/// How the field was levelled.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Levelling {
    /// Roll and pitch from the accelerometer: carried by the gyroscope between its
    /// samples and pulled towards it with time constant `window_s`, or, without a
    /// usable gyroscope, averaged over `window_s` (see [`crate::attitude::down`]).
    Accelerometer { window_s: f64 },
    /// No accelerometer in the log: the device was assumed level.
    AssumedLevel,
}

impl Levelling {
    /// How samples levelled with `gravity` are levelled.
    pub fn of(gravity: &GravityEstimate) -> Levelling {
        if gravity.specific_force_mps2.is_empty() {
            Levelling::AssumedLevel
        } else {
            Levelling::Accelerometer {
                window_s: gravity.tau_s(),
            }
        }
    }
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

    #[error(
        "{file_name} holds no magnetometer samples, only {found}. To calibrate, drop it \
         together with the log that has the magnetometer (the files are merged on one \
         timeline), or choose a log with a magnetometer."
    )]
    NoMagnetometerStream { file_name: String, found: String },

    #[error("{file_name}: none of its {n_data_lines} data lines has a usable magnetometer sample{first_problem}. Check that the log holds numbers in mag_x_ut, mag_y_ut and mag_z_ut.")]
    NoMagnetometerSamples {
        file_name: String,
        n_data_lines: usize,
        first_problem: String,
    },

    #[error("{file_name}: the accelerometer does not overlap the magnetometer in time, so the field cannot be levelled. Check the t_s column.")]
    NoLevelledSamples { file_name: String },
}

/// The streams a recording holds, with their sample counts, for a message ("1,200 GNSS
/// fixes and 40 device headings"); "nothing" when it holds none.
fn streams_found(recording: &Recording) -> String {
    let counts = [
        (recording.acc_in_body_mps2.len(), "accelerometer samples"),
        (recording.gyro_in_body_radps.len(), "gyroscope samples"),
        (recording.temp_c.len(), "temperatures"),
        (recording.pressure_hpa.len(), "pressures"),
        (recording.gnss.len(), "GNSS fixes"),
        (recording.attitude.len(), "attitudes"),
        (recording.device_heading.len(), "device headings"),
        (recording.ref_heading_rad.len(), "reference headings"),
        (
            recording.ref_position_en_m.len() + recording.ref_position_lat_lon_deg.len(),
            "reference positions",
        ),
    ];
    let found: Vec<String> = counts
        .iter()
        .filter(|(count, _)| *count > 0)
        .map(|(count, what)| format!("{} {what}", crate::io::thousands(*count)))
        .collect();
    match found.as_slice() {
        [] => "notes on what it is (no samples this tool uses)".to_string(),
        [one] => one.clone(),
        [rest @ .., last] => format!("{} and {last}", rest.join(", ")),
    }
}

/// Magnetometer samples with the tilt at each, ready for any calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct TiltedSamples {
    pub t_s: Vec<f64>,
    pub mag_ut: Vec<Vector3<f64>>,
    pub tilt: Vec<Tilt>,
    /// How far each sample's tilt is trusted, 0 to 1
    /// ([`GravityEstimate::tilt_trust_at`]): what weighs its dip in a 3D fit.
    pub tilt_trust: Vec<f64>,
    pub levelling: Levelling,
    /// What the user should know (samples left out, a device assumed level).
    pub notes: Vec<String>,
}

/// The magnetometer samples of a recording with roll and pitch from `gravity` (the
/// recording's down from its accelerometer and gyroscope,
/// [`crate::attitude::down::gravity_of`]), or level when the log has no accelerometer.
/// Fails, saying why and what to do, when there is no usable magnetometer sample.
pub fn tilted_samples(
    file_name: &str,
    recording: &Recording,
    header: Option<&HeaderInfo>,
    diagnostics: &Diagnostics,
    n_data_lines: usize,
    gravity: &GravityEstimate,
) -> Result<TiltedSamples, AnalysisError> {
    let mag = &recording.mag_in_body_ut;
    if mag.is_empty() {
        return Err(no_magnetometer_error(
            file_name,
            recording,
            header,
            diagnostics,
            n_data_lines,
        ));
    }
    let levelling = Levelling::of(gravity);
    let mut samples = tilt_each_sample(mag, levelling, gravity);
    if samples.t_s.is_empty() {
        return Err(AnalysisError::NoLevelledSamples {
            file_name: file_name.to_string(),
        });
    }
    samples.tilt_trust = gravity.tilt_trust_at(&samples.t_s);
    samples
        .notes
        .extend(levelling_note(levelling, gravity, recording));
    let n_not_levelled = mag.len() - samples.t_s.len();
    if n_not_levelled > 0 {
        samples
            .notes
            .push(left_out_note(n_not_levelled, &gravity.source));
    }
    Ok(samples)
}

/// Why a recording without magnetometer samples cannot be calibrated: it holds other
/// streams only, its header has no magnetometer columns, or none of its lines was usable.
fn no_magnetometer_error(
    file_name: &str,
    recording: &Recording,
    header: Option<&HeaderInfo>,
    diagnostics: &Diagnostics,
    n_data_lines: usize,
) -> AnalysisError {
    let file_name = file_name.to_string();
    let (header_line, header_columns) = header.map_or((1, Vec::new()), |header| {
        (header.line, header.columns.clone())
    });
    let has_mag_columns = header_columns
        .iter()
        .any(|name| name.to_ascii_lowercase().starts_with("mag_"));
    if header.is_none() {
        return AnalysisError::NoMagnetometerStream {
            file_name,
            found: streams_found(recording),
        };
    }
    if has_mag_columns {
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
    }
}

/// The magnetometer samples with a tilt (level, or from the specific force interpolated
/// to the sample's time); samples without one are left out. No trust and no notes yet.
fn tilt_each_sample(
    mag: &Stream<Vector3<f64>>,
    levelling: Levelling,
    gravity: &GravityEstimate,
) -> TiltedSamples {
    let mut samples = TiltedSamples {
        t_s: Vec::with_capacity(mag.len()),
        mag_ut: Vec::with_capacity(mag.len()),
        tilt: Vec::with_capacity(mag.len()),
        tilt_trust: Vec::new(),
        levelling,
        notes: Vec::new(),
    };
    for (&sample_t_s, &mag_ut) in mag.t_s.iter().zip(&mag.values) {
        let tilt = match levelling {
            Levelling::AssumedLevel => Some(Tilt::LEVEL),
            Levelling::Accelerometer { .. } => gravity
                .specific_force_mps2
                .interpolate_at(sample_t_s, MAX_INTERPOLATION_GAP_S)
                .and_then(Tilt::from_specific_force),
        };
        if let Some(tilt) = tilt {
            samples.t_s.push(sample_t_s);
            samples.mag_ut.push(mag_ut);
            samples.tilt.push(tilt);
        }
    }
    samples
}

/// What the user should know about where the tilt came from, if anything: a device
/// assumed level, a gyroscope left unused, the autopilot's attitude, a corrected time scale.
fn levelling_note(
    levelling: Levelling,
    gravity: &GravityEstimate,
    recording: &Recording,
) -> Option<String> {
    if levelling == Levelling::AssumedLevel {
        return Some("The log has no accelerometer, so the device was assumed level; tilt adds heading error.".to_string());
    }
    match &gravity.source {
        GravitySource::Accelerometer { reason, window_s }
            if !recording.gyro_in_body_radps.is_empty() =>
        {
            Some(format!(
                "tilt from the accelerometer alone (averaged over {window_s} s), not with the gyroscope: {reason}"
            ))
        }
        GravitySource::Autopilot { .. } => Some(
            "tilt from the autopilot's own attitude (its roll and pitch): a multirotor's accelerometer \
             reads its thrust, not gravity, in flight"
                .to_string(),
        ),
        GravitySource::GyroAided {
            gyro_time_scale, ..
        } if *gyro_time_scale != 1.0 => Some(format!(
            "the gyroscope's turns match the accelerometer's only at {gyro_time_scale}× the log's time scale: \
             the samples' times are probably wrong by that factor (a sample rate assumed, not read); \
             the tilt used the corrected rate"
        )),
        _ => None,
    }
}

/// The note that `n_not_levelled` magnetometer samples had no tilt and were left out.
fn left_out_note(n_not_levelled: usize, source: &GravitySource) -> String {
    let (sample_had, was) = if n_not_levelled == 1 {
        ("sample had", "was")
    } else {
        ("samples had", "were")
    };
    let levelled_by = match source {
        GravitySource::Autopilot { .. } => "attitude",
        _ => "accelerometer",
    };
    format!(
        "{n_not_levelled} magnetometer {sample_had} no {levelled_by} sample within {MAX_INTERPOLATION_GAP_S} s and {was} left out."
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::calibration::{CalibrationAnalysis, CalibrationOptions, Method};
    use crate::pipeline::calibrate_file as analyse_file;

    fn analyse(text: &str) -> Result<CalibrationAnalysis, AnalysisError> {
        analyse_file("log.csv", text.as_bytes(), &CalibrationOptions::default())
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
    fn a_log_without_a_magnetometer_says_what_it_holds_and_what_to_do() {
        // A GPS log: two fixes and a heading, no field.
        let text = "$GPRMC,120000.00,A,4808.000,N,01134.800,E,2.5,45.0,221126,,,A*64\r\n\
                    $GPRMC,120001.00,A,4808.001,N,01134.800,E,2.5,45.0,221126,,,A*64\r\n\
                    $HEHDT,10.0,T*1E\r\n";
        let message = analyse_file(
            "track.nmea",
            text.as_bytes(),
            &CalibrationOptions::default(),
        )
        .map(|_| ())
        .unwrap_err()
        .to_string();
        assert!(
            message.starts_with("track.nmea holds no magnetometer samples, only "),
            "{message}"
        );
        assert!(message.contains("GNSS fixes"), "{message}");
        assert!(
            message.contains("drop it together with the log"),
            "{message}"
        );
        assert!(!message.contains("header"), "{message}");
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
        // Two full turns: the first trains, the second checks.
        for sample_idx in 0..1440 {
            let heading_rad = (sample_idx as f64 / 2.0).to_radians();
            let (x_ut, y_ut) = (
                10.0 + 25.0 * heading_rad.cos(),
                -5.0 - 20.0 * heading_rad.sin(),
            );
            text.push_str(&format!(
                "{},{x_ut},{y_ut},40,{}\n",
                sample_idx as f64 / 2.0,
                (sample_idx as f64 / 2.0) % 360.0
            ));
        }
        let analysis = analyse(&text).expect("analysable");
        let report = &analysis.report;
        assert_eq!(report.n_samples_used, 1440);
        let min_max = report.method(Method::MinMax).expect("min/max ran");
        let check = min_max.heading_error_check.expect("a reference");
        assert!(check.rms_deg < 0.2, "{check:?}");
        assert!(report
            .raw_heading_error_check
            .is_some_and(|raw| raw.rms_deg > 10.0));
        assert!(report
            .notes
            .iter()
            .any(|note| note.contains("assumed level")));
    }
}
