//! The end of a serial input ([`super`]): the report and the calibration echoes, the
//! notes that say which line formats were read and in which units, the checks of the
//! units assumed where lines gave none (g, °/s, raw counts, as the module header of
//! [`super`] describes), the direction of gravity, and the magnetometer's frame.

use std::f64::consts::PI;

use super::{EchoSeen, LineFormat, SerialReader, FORMAT_NAME};
use crate::io::frame::RAW_COUNT_MAGNITUDES;
use crate::io::{
    ImportError, ImportReport, MagUnit, SensorFrame, UnitOrigin, STANDARD_GRAVITY_MPS2,
};

/// The widest common gyroscope range, 2000 °/s, in rad/s.
const MAX_PLAUSIBLE_RATE_RADPS: f64 = 35.0;

impl SerialReader {
    /// The report. Fails when no line held a sensor reading.
    pub fn finish(self, file_name: &str) -> Result<ImportReport, ImportError> {
        self.into_report(file_name, true).map(|(report, _)| report)
    }

    /// The report and the calibration echoes. Fails only when no line held a reading
    /// or an echo.
    pub fn finish_with_echoes(
        self,
        file_name: &str,
    ) -> Result<(ImportReport, Vec<EchoSeen>), ImportError> {
        self.into_report(file_name, false)
    }

    pub(super) fn into_report(
        mut self,
        file_name: &str,
        require_samples: bool,
    ) -> Result<(ImportReport, Vec<EchoSeen>), ImportError> {
        self.flush_frame();
        let has_samples = self.n_frames > 0;
        if !has_samples && (require_samples || self.echoes.is_empty()) {
            let first_problem = match (&self.first_problem, self.echoes.first()) {
                (_, Some(echo)) => format!(
                    " (line {}: only calibration echoes (Cal1:, Cal2:), no sensor readings)",
                    echo.line
                ),
                (Some((line, reason)), None) => format!(" (line {line}: {reason})"),
                (None, None) => String::new(),
            };
            return Err(ImportError::NothingRecognised {
                file_name: file_name.to_string(),
                format: FORMAT_NAME,
                n_lines: self.n_lines,
                first_problem,
            });
        }

        let mut notes = Vec::new();
        if self.n_arrival_times < self.n_frames {
            let rate_hz = self.sample_rate_hz;
            notes.push(format!(
                "no timestamps: samples are spaced at an assumed {rate_hz} Hz"
            ));
        }
        if self.rate_was_invalid {
            notes.push(
                "the sample rate given was not a positive number; 100 Hz was used".to_string(),
            );
        }
        if self.n_arrival_times > 0 {
            notes.push(format!(
                "{} samples are timed by the arrival of their first line",
                self.n_arrival_times
            ));
        }
        let seen: Vec<String> = LineFormat::ALL
            .iter()
            .zip(self.lines_per_format)
            .filter(|(_, count)| *count > 0)
            .map(|(format, count)| format!("{} ({count})", format.describe()))
            .collect();
        notes.push(format!("line formats seen: {}", seen.join(", ")));
        self.push_unit_notes(&mut notes);
        if has_samples {
            notes.push(
                "axes: the sensor's own x, y, z as printed, z up out of the board (a level \
                 sensor at rest reads z ≈ +9.8 m/s²); body axes (x forward, y right, z \
                 down) = (x, −y, −z)"
                    .to_string(),
            );
        }
        self.check_assumed_units(&mut notes);
        self.check_gravity_direction(&mut notes);
        let mag_frame = self.mag_frame(&mut notes);
        if self.n_raw_replaced_by_uni > 0 {
            notes.push(format!(
                "{} Raw: lines were each followed by a Uni: line of the same reading; the \
                 Uni: values (more digits) were used",
                self.n_raw_replaced_by_uni
            ));
        }
        if self.n_joined_frames > 0 {
            notes.push(format!(
                "{} samples were joined from consecutive lines that each brought a \
                 different sensor",
                self.n_joined_frames
            ));
        }
        if !self.ignored_labels.is_empty() {
            notes.push(format!(
                "labels ignored (no sensor axis this tool knows): {}",
                self.ignored_labels.join(", ")
            ));
        }
        if !self.echoes.is_empty() {
            notes.push(format!(
                "{} calibration echoes (Cal1:, Cal2:) were read apart from the recording",
                self.echoes.len()
            ));
        }

        if self.n_arrival_times > 0 {
            let recording = &mut self.recording;
            let n_out_of_order = recording.acc_in_body_mps2.sort_by_time()
                + recording.gyro_in_body_radps.sort_by_time()
                + recording.mag_in_body_ut.sort_by_time()
                + recording.temp_c.sort_by_time();
            if n_out_of_order > 0 {
                self.diagnostics.push(
                    None,
                    format!(
                        "arrival times go backwards {}; the samples were sorted by time",
                        crate::base::words::times(n_out_of_order)
                    ),
                );
            }
        }

        let report = ImportReport {
            autopilot: None,
            file_name: file_name.to_string(),
            format: FORMAT_NAME,
            recording: self.recording,
            diagnostics: self.diagnostics,
            header: None,
            n_data_lines: self.n_data_lines,
            notes,
            mag_frame,
        };
        Ok((report, self.echoes))
    }

    /// The magnetometer's frame: the board's axes as printed ([`sensor_to_body`](super::sensor_to_body) turned
    /// them into body axes) and the unit most of its values were written in; a note when
    /// they came in several.
    fn mag_frame(&self, notes: &mut Vec<String>) -> Option<SensorFrame> {
        let (unit, _) = self
            .mag_units
            .iter()
            .copied()
            .max_by_key(|&(_, count)| count)?;
        if self.mag_units.len() > 1 {
            let counts: Vec<String> = self
                .mag_units
                .iter()
                .map(|(unit, count)| format!("{count} in {}", unit.label()))
                .collect();
            notes.push(format!(
                "magnetometer values came in several units ({}); a calibration is exported for \
                 values in {}, the most common",
                counts.join(", "),
                unit.label()
            ));
        }
        Some(SensorFrame::serial_board(unit))
    }

    fn format_count(&self, format: LineFormat) -> usize {
        self.lines_per_format
            .get(format.index())
            .copied()
            .unwrap_or(0)
    }

    fn push_unit_notes(&self, notes: &mut Vec<String>) {
        if self.format_count(LineFormat::MotionCalRaw) > 0 {
            notes.push(
                "Raw: counts read as MotionCal reads them: accelerometer 1/8192 g (g = \
                 9.80665 m/s²), gyroscope 1/16 °/s, magnetometer 0.1 µT per count"
                    .to_string(),
            );
        }
        if self.n_wide_count_lines > 0 {
            notes.push(format!(
                "{} Raw: lines have counts beyond ±32767; MotionCal would drop them, they \
                 were kept",
                self.n_wide_count_lines
            ));
        }
        if self.format_count(LineFormat::Uni) > 0 {
            notes.push(
                "Uni: accelerometer m/s², gyroscope rad/s, magnetometer µT (Adafruit's \
                 calibration sketch)"
                    .to_string(),
            );
        }
        if self.format_count(LineFormat::AdafruitRawDecimal) > 0 {
            notes.push(
                "Raw: with decimals: accelerometer m/s², gyroscope °/s, magnetometer µT \
                 (Adafruit's calibrated_orientation sketch)"
                    .to_string(),
            );
        }
        let unitless = [
            LineFormat::SerialPlotter,
            LineFormat::Tuple,
            LineFormat::PlainNumbers,
        ];
        if unitless.iter().any(|&format| self.format_count(format) > 0) {
            notes.push(
                "values without a unit: accelerometer m/s², gyroscope rad/s, magnetometer \
                 µT (Adafruit Unified Sensor and CircuitPython units); a line of 3 numbers \
                 or a lone (x, y, z) is the magnetometer"
                    .to_string(),
            );
        }
        if self.n_six_value_lines > 0 {
            notes.push(format!(
                "{} lines of 6 numbers were read as accelerometer (m/s²) then magnetometer \
                 (µT); if the sketch prints accelerometer then gyroscope, the magnetometer \
                 stream is wrong",
                self.n_six_value_lines
            ));
        }
    }

    /// Checks the SI units assumed where lines gave none against the data's size, and
    /// rescales where the data leaves no doubt.
    fn check_assumed_units(&mut self, notes: &mut Vec<String>) {
        let acc = &mut self.recording.acc_in_body_mps2.values;
        let acc_norms: Vec<f64> = acc
            .iter()
            .zip(&self.acc_unit_assumed)
            .filter(|(_, assumed)| **assumed)
            .map(|(value, _)| value.norm())
            .collect();
        if let Some(median) = median(acc_norms) {
            if (0.3..3.0).contains(&median) {
                // At rest or walking, specific force is about 1 g; near 1 the unit is g.
                for (value, _) in acc
                    .iter_mut()
                    .zip(&self.acc_unit_assumed)
                    .filter(|(_, assumed)| **assumed)
                {
                    *value *= STANDARD_GRAVITY_MPS2;
                }
                notes.push(format!(
                    "accelerometer values without a unit have a median magnitude of \
                     {median:.2}: read as g, not m/s²"
                ));
            } else if !(5.0..30.0).contains(&median) {
                notes.push(format!(
                    "accelerometer values without a unit have a median magnitude of \
                     {median:.2}, neither about 1 g nor 9.8 m/s²: check the unit"
                ));
            }
        }

        let gyro = &mut self.recording.gyro_in_body_radps.values;
        let max_rate = gyro
            .iter()
            .zip(&self.gyro_unit_assumed)
            .filter(|(_, assumed)| **assumed)
            .map(|(value, _)| value.norm())
            .fold(None, |max: Option<f64>, norm| {
                Some(max.map_or(norm, |max| max.max(norm)))
            });
        if let Some(max_rate) = max_rate {
            if max_rate > MAX_PLAUSIBLE_RATE_RADPS {
                for (value, _) in gyro
                    .iter_mut()
                    .zip(&self.gyro_unit_assumed)
                    .filter(|(_, assumed)| **assumed)
                {
                    *value *= PI / 180.0;
                }
                notes.push(format!(
                    "gyroscope values without a unit reach {max_rate:.0}, beyond any \
                     gyroscope's range in rad/s: read as °/s"
                ));
            }
        }

        let mag_norms: Vec<f64> = self
            .recording
            .mag_in_body_ut
            .values
            .iter()
            .zip(&self.mag_unit_assumed)
            .filter(|(_, assumed)| **assumed)
            .map(|value| value.0.norm())
            .collect();
        if let Some(median) = median(mag_norms) {
            if RAW_COUNT_MAGNITUDES.contains(&median) {
                // Far from the Earth's field in any unit: raw counts, kept as they are.
                for (unit, _) in &mut self.mag_units {
                    if unit.origin == UnitOrigin::Assumed {
                        *unit = MagUnit::COUNTS;
                    }
                }
                notes.push(format!(
                    "magnetometer values without a unit have a median magnitude of \
                     {median:.0}, far from the Earth's field in µT, gauss or nT: read as raw \
                     counts, kept as they are (the µT per count is unknown, so field strengths \
                     are in counts)"
                ));
            } else if !(10.0..=200.0).contains(&median) {
                notes.push(format!(
                    "magnetometer values without a unit have a median magnitude of \
                     {median:.3} µT, far from the Earth's 25-65 µT: check the unit (gauss \
                     would be 100× larger) or whether these are magnetometer values"
                ));
            }
        }
    }

    /// A level device at rest reads z ≈ −9.8 m/s² in body axes; a clearly positive mean
    /// means it was upside down or its firmware already prints z down.
    fn check_gravity_direction(&self, notes: &mut Vec<String>) {
        let acc = &self.recording.acc_in_body_mps2.values;
        if acc.is_empty() {
            return;
        }
        let mean_z = acc.iter().map(|value| value.z).sum::<f64>() / acc.len() as f64;
        if mean_z > 3.0 {
            notes.push(format!(
                "the mean body z specific force is +{mean_z:.1} m/s² (a level device at \
                 rest reads −9.8): the sensor was mostly upside down, or its firmware \
                 already prints z down"
            ));
        }
    }
}

fn median(mut values: Vec<f64>) -> Option<f64> {
    values.retain(|value| value.is_finite());
    crate::base::stats::median(&mut values)
}
