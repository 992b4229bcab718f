//! The end of a delimited file ([`super`]): times made seconds (from their unit, the
//! magnitude of epoch counters, or a settings line's sample rate) and relative to the
//! first sample where they are absolute; values converted once, in place, from the
//! header's units or from units guessed from the data (the field magnitude, the specific
//! force at rest, rotation rates); and the notes that say what was assumed.

use nalgebra::Vector3;

use super::header::{Header, Quantity, Setting, DEG_TO_RAD, WHITESPACE};
use super::{DelimitedReader, RawImport, SensorAxes, FORMAT_NAME};
use crate::io::frame::RAW_COUNT_MAGNITUDES;
use crate::io::recording::{GyroBias, Recording, Stream};
use crate::io::{shorten, HeaderInfo, ImportError, ImportReport, MagUnit, STANDARD_GRAVITY_MPS2};

/// How many settings lines the notes list.
const MAX_SETTINGS_NOTED: usize = 8;

/// Times beyond this many seconds (about three years) are taken as absolute (epoch).
const ABSOLUTE_TIME_S: f64 = 1e8;

/// A settings line that gives a sample rate: its line number, the setting, the rate in Hz.
type RateSetting<'a> = (usize, &'a Setting, f64);

impl DelimitedReader {
    /// Converts times and units in place and hands over the import, still in the file's
    /// axes.
    pub fn finish(mut self, file_name: &str) -> Result<RawImport, ImportError> {
        let file_name = file_name.to_string();
        let Some(header) = self.header.take() else {
            return Err(ImportError::NoHeader { file_name });
        };
        if header.columns.iter().all(Option::is_none) {
            if header.headerless {
                return Err(ImportError::NoHeaderLine {
                    file_name,
                    line: header.line,
                    n_columns: header.names.len(),
                });
            }
            return Err(ImportError::UnknownHeader {
                file_name,
                line: header.line,
                found: shorten(&header.names.join(", ")),
            });
        }
        // The first settings line that gives a sample rate times the samples when there is
        // no time column.
        let rate = self
            .settings
            .iter()
            .find_map(|(line, setting)| Some((*line, setting, setting.sample_rate_hz()?)));
        let mut notes = self.notes_on_the_file(&header, rate);
        let recording = &mut self.recording;
        times_to_seconds(
            recording,
            &header,
            rate,
            self.row_times.went_back,
            &mut notes,
        );
        let mag_unit = values_to_units(recording, &header, &mut notes);
        if !recording.gyro_in_body_radps.is_empty() && is_phyphox_gyroscope(&header) {
            recording.gyro_bias = GyroBias::RemovedByDevice;
            notes.push(PHYPHOX_GYROSCOPE_NOTE.to_string());
        }
        // Every stream's times are some of the rows' times, in the rows' order: when
        // those never go back, no stream needs sorting (or the pass that looks).
        let n_out_of_order = if self.row_times.went_back {
            recording.sort_all_by_time()
        } else {
            0
        };
        self.diagnostics
            .push_sorted_by_time(Some(header.line), n_out_of_order);
        shrink_all(recording);
        Ok(RawImport {
            report: ImportReport {
                autopilot: None,
                file_name,
                format: FORMAT_NAME,
                recording: std::mem::take(recording),
                diagnostics: self.diagnostics,
                header: Some(HeaderInfo {
                    line: header.line,
                    columns: header.names,
                }),
                n_data_lines: self.n_data_lines,
                notes,
                // Set with the axes, by `RawImport::into_report`.
                mag_frame: None,
            },
            axes: header.axes,
            mag_unit,
        })
    }

    /// The notes on the file as a whole: no header line, the settings lines before the
    /// header (and which gives the sample rate), the columns ignored, and a missing time
    /// column.
    fn notes_on_the_file(&self, header: &Header, rate: Option<RateSetting<'_>>) -> Vec<String> {
        let mut notes = Vec::new();
        if header.headerless {
            notes.push(format!(
                "no header line: the {} columns{} are named column 1 to column {} and read \
                 as the mapping says",
                header.names.len(),
                if header.delimiter == WHITESPACE {
                    ", split on white space,"
                } else {
                    ""
                },
                header.names.len()
            ));
        }
        if !self.settings.is_empty() {
            let described: Vec<String> = self
                .settings
                .iter()
                .map(|(line, setting)| {
                    let role = match rate {
                        Some((rate_line, _, _)) if rate_line == *line => {
                            if header.time_field.is_none() {
                                "the sample rate in Hz, used for the times"
                            } else {
                                "a sample rate; the time column is used instead"
                            }
                        }
                        _ => "not used",
                    };
                    format!(
                        "{} = {} (line {line}: {role})",
                        shorten(&setting.key),
                        setting.value
                    )
                })
                .take(MAX_SETTINGS_NOTED)
                .collect();
            let more = self.settings.len().saturating_sub(MAX_SETTINGS_NOTED);
            notes.push(format!(
                "settings lines before the header: {}{}",
                described.join("; "),
                if more > 0 {
                    format!("; and {more} more")
                } else {
                    String::new()
                }
            ));
        }
        // Ignored columns and a missing time are facts about the file, not problems of a
        // line: they are notes.
        let unknown: Vec<&str> = header
            .names
            .iter()
            .zip(&header.columns)
            .filter(|(_, column)| column.is_none())
            .map(|(name, _)| name.as_str())
            .collect();
        if !unknown.is_empty() {
            notes.push(format!(
                "columns ignored (not recognised): {}",
                shorten(&unknown.join(", "))
            ));
        }
        for name in &self.plan.incomplete {
            notes.push(format!(
                "{name} columns ignored: the header lacks one of x, y, z"
            ));
        }
        if header.time_field.is_none() {
            notes.push(match rate {
                Some((line, setting, rate_hz)) => format!(
                    "no time column: the samples are spaced at {rate_hz} Hz, the rate on line \
                     {line} ({})",
                    shorten(&setting.text)
                ),
                None => "no time column: the sample number is used as time".to_string(),
            });
        }
        notes
    }
}

/// What [`is_phyphox_gyroscope`] means for the filter, said in the import's notes.
const PHYPHOX_GYROSCOPE_NOTE: &str = "gyroscope: phyphox's rotation rate, with the OS's bias \
     estimate removed (Android's TYPE_GYROSCOPE; on iOS Core Motion's device-motion rate)";

/// Whether the header is phyphox's export of its gyroscope, named as phyphox writes
/// it: `"Time (s)"` then `"X (rad/s)"`… (one sensor's experiment) or
/// `"Gyroscope x (rad/s)"`… (several sensors'). phyphox reads Android's `TYPE_GYROSCOPE` (`SensorInput.java`) and on iOS
/// Core Motion's `CMDeviceMotion.rotationRate` (`ExperimentSensorInput.swift`), which
/// Apple documents as the rate "whose bias has been removed by Core Motion
/// algorithms": both are bias-removed. Other apps' names say nothing of the bias.
#[inline(never)]
fn is_phyphox_gyroscope(header: &Header) -> bool {
    const NAMES: [&str; 7] = [
        "Time (s)",
        "X (rad/s)",
        "Y (rad/s)",
        "Z (rad/s)",
        "Gyroscope x (rad/s)",
        "Gyroscope y (rad/s)",
        "Gyroscope z (rad/s)",
    ];
    let has = |idx: usize| header.names.iter().any(|name| name == NAMES[idx]);
    has(0) && ((1..4).all(has) || (4..7).all(has))
}

/// The factor to this crate's unit of a quantity's column, where the header gives it.
fn scale_of(header: &Header, quantity: Quantity) -> Option<f64> {
    // The time column used, where a file has several (`time` and
    // `seconds_elapsed`); the first of its quantity for the others.
    let time_column = header
        .time_field
        .and_then(|idx| header.columns.get(idx).copied().flatten())
        .filter(|_| quantity == Quantity::Time);
    time_column
        .or_else(|| {
            header
                .columns
                .iter()
                .flatten()
                .find(|column| column.quantity == quantity)
                .copied()
        })
        .and_then(|column| column.scale)
}

/// Turns every time into seconds (by the time column's unit, stated or guessed, or by
/// the settings' sample rate where there is no time column) and makes absolute times
/// relative to the first sample, with notes saying so. `went_back`: whether the rows'
/// times ever went back (else every stream is sorted already).
fn times_to_seconds(
    recording: &mut Recording,
    header: &Header,
    rate: Option<RateSetting<'_>>,
    went_back: bool,
    notes: &mut Vec<String>,
) {
    let time_scale = match (header.time_field, scale_of(header, Quantity::Time)) {
        // Sample numbers, at the rate the settings give.
        (None, _) => rate.map_or(1.0, |(_, _, rate_hz)| 1.0 / rate_hz),
        (Some(_), Some(scale)) => scale,
        (Some(_), None) => {
            let (scale, guess) = guess_time_scale(recording);
            if header.time_field.is_some() {
                notes.push(format!("time unit guessed from the values: {guess}"));
            }
            scale
        }
    };
    // Absolute times (epoch seconds, from date-times or epoch counters) are made
    // relative to the first sample; times that already count from a start are kept,
    // so that times the user quotes from the file still mean the same.
    let first_raw = if went_back {
        first_time(recording)
    } else {
        first_time_of_sorted(recording)
    };
    let t0_raw = if first_raw.is_finite() && first_raw * time_scale > ABSOLUTE_TIME_S {
        first_raw
    } else {
        0.0
    };
    if t0_raw != 0.0 {
        notes.push(format!(
            "absolute times made relative to the first sample ({:.3} s after 1970)",
            t0_raw * time_scale
        ));
    }
    // (t − 0) · 1 is t: the pass is skipped when it would change nothing.
    if t0_raw != 0.0 || time_scale != 1.0 {
        for_each_time(recording, |t| *t = (*t - t0_raw) * time_scale);
    }
    if t0_raw != 0.0 {
        recording.start_unix_s = Some(t0_raw * time_scale);
    }
}

/// Converts every value to this crate's units (by the header's units, else by units
/// guessed from the data, with notes saying so) and returns the unit the magnetometer
/// was written in (`None` without magnetometer samples).
fn values_to_units(
    recording: &mut Recording,
    header: &Header,
    notes: &mut Vec<String>,
) -> Option<MagUnit> {
    let (acc_scale, acc_note) = unit_or_guess(
        scale_of(header, Quantity::Acc),
        &recording.acc_in_body_mps2.values,
        guess_acc_scale,
    );
    let (gyro_scale, gyro_note) = unit_or_guess(
        scale_of(header, Quantity::Gyro),
        &recording.gyro_in_body_radps.values,
        guess_gyro_scale,
    );
    // The unit the field was written in, for calibrations exported in it.
    let mag_values = &recording.mag_in_body_ut.values;
    let (mag_unit, mag_note) = match scale_of(header, Quantity::Mag) {
        Some(scale) => (Some(mag_unit_of_scale(scale)), None),
        None if mag_values.is_empty() => (None, None),
        None => {
            let median = median_norm(mag_values);
            let (unit, description) = guess_mag_unit(median);
            (
                Some(unit),
                Some(format!(
                    "{description} (median magnitude {median:.3}); override the unit if \
                     this is wrong"
                )),
            )
        }
    };
    let mag_scale = mag_unit.map_or(1.0, |unit| unit.factor());
    notes.extend([acc_note, gyro_note, mag_note].into_iter().flatten());
    for (stream, scale) in [
        (&mut recording.acc_in_body_mps2, acc_scale),
        (&mut recording.gyro_in_body_radps, gyro_scale),
        (&mut recording.mag_in_body_ut, mag_scale),
    ] {
        if scale != 1.0 {
            stream.values.iter_mut().for_each(|value| *value *= scale);
        }
    }
    for (stream, scale) in [
        (
            &mut recording.temp_c,
            scale_of(header, Quantity::Temp).unwrap_or(1.0),
        ),
        (
            &mut recording.pressure_hpa,
            scale_of(header, Quantity::Pressure).unwrap_or(1.0),
        ),
        (&mut recording.ref_heading_rad, DEG_TO_RAD),
    ] {
        if scale != 1.0 {
            stream.values.iter_mut().for_each(|value| *value *= scale);
        }
    }
    let course_scale = scale_of(header, Quantity::Course).unwrap_or(DEG_TO_RAD);
    for fix in &mut recording.gnss.values {
        fix.course_rad = fix.course_rad.map(|course| course * course_scale);
    }
    let angle_scale = scale_of(header, Quantity::Roll).unwrap_or(1.0);
    for attitude in &mut recording.attitude.values {
        attitude.roll_rad *= angle_scale;
        attitude.pitch_rad *= angle_scale;
        attitude.yaw_rad = attitude.yaw_rad.map(|yaw| yaw * angle_scale);
    }
    if !recording.attitude.is_empty() && header.axes == SensorAxes::AndroidDevice {
        // The app's orientation angles are in its own conventions, which are not
        // converted yet; they are kept out rather than passed on wrong.
        recording.attitude = Stream::default();
        notes.push(
            "the app's roll/pitch/yaw columns were not used (their axis convention is the app's)"
                .to_string(),
        );
    }
    mag_unit
}

/// Calls `f` on every sample time of every stream.
fn for_each_time(recording: &mut Recording, mut f: impl FnMut(&mut f64)) {
    for t_s in [
        &mut recording.acc_in_body_mps2.t_s,
        &mut recording.gyro_in_body_radps.t_s,
        &mut recording.mag_in_body_ut.t_s,
        &mut recording.temp_c.t_s,
        &mut recording.pressure_hpa.t_s,
        &mut recording.gnss.t_s,
        &mut recording.attitude.t_s,
        &mut recording.ref_heading_rad.t_s,
        &mut recording.ref_position_en_m.t_s,
    ] {
        t_s.iter_mut().for_each(&mut f);
    }
}

/// The earliest sample time of any stream, in the file's units.
fn first_time(recording: &mut Recording) -> f64 {
    let mut first = f64::INFINITY;
    for_each_time(recording, |t| first = first.min(*t));
    first
}

/// [`first_time`] of a recording whose streams are sorted by time: the earliest of their
/// first samples' times.
fn first_time_of_sorted(recording: &Recording) -> f64 {
    [
        recording.acc_in_body_mps2.t_s.first(),
        recording.gyro_in_body_radps.t_s.first(),
        recording.mag_in_body_ut.t_s.first(),
        recording.temp_c.t_s.first(),
        recording.pressure_hpa.t_s.first(),
        recording.gnss.t_s.first(),
        recording.attitude.t_s.first(),
        recording.ref_heading_rad.t_s.first(),
        recording.ref_position_en_m.t_s.first(),
    ]
    .into_iter()
    .flatten()
    .fold(f64::INFINITY, |first, &t| first.min(t))
}

/// Gives back the room reserved for rows the file did not have.
fn shrink_all(recording: &mut Recording) {
    fn shrink<T>(stream: &mut Stream<T>) {
        stream.t_s.shrink_to_fit();
        stream.values.shrink_to_fit();
    }
    shrink(&mut recording.acc_in_body_mps2);
    shrink(&mut recording.gyro_in_body_radps);
    shrink(&mut recording.mag_in_body_ut);
    shrink(&mut recording.temp_c);
    shrink(&mut recording.pressure_hpa);
    shrink(&mut recording.ref_heading_rad);
    shrink(&mut recording.ref_position_en_m);
}

/// A known unit's scale, or a guess from the data with a note saying so.
fn unit_or_guess(
    known: Option<f64>,
    values: &[Vector3<f64>],
    guess: fn(f64) -> (f64, &'static str),
) -> (f64, Option<String>) {
    if let Some(scale) = known {
        return (scale, None);
    }
    if values.is_empty() {
        return (1.0, None);
    }
    let median = median_norm(values);
    let (scale, description) = guess(median);
    (
        scale,
        Some(format!(
            "{description} (median magnitude {median:.3}); override the unit if this is wrong"
        )),
    )
}

/// The median magnitude of finite vectors (0 without any).
fn median_norm(values: &[Vector3<f64>]) -> f64 {
    let mut norms: Vec<f64> = values
        .iter()
        .map(Vector3::norm)
        .filter(|norm| norm.is_finite())
        .collect();
    norms.sort_by(f64::total_cmp);
    norms.get(norms.len() / 2).copied().unwrap_or(0.0)
}

/// Magnetometer unit from the median field magnitude. Earth's field is 25-65 µT; hard
/// iron can multiply a raw reading several times, so the bands are wide; between µT and
/// nT lie raw counts ([`RAW_COUNT_MAGNITUDES`]).
fn guess_mag_unit(median: f64) -> (MagUnit, &'static str) {
    if median < 1e-3 {
        (
            MagUnit::TESLA.guessed(),
            "magnetometer unit guessed as tesla",
        )
    } else if median < 5.0 {
        (
            MagUnit::GAUSS.guessed(),
            "magnetometer unit guessed as gauss",
        )
    } else if median < RAW_COUNT_MAGNITUDES.start {
        (
            MagUnit::MICROTESLA.guessed(),
            "magnetometer unit guessed as µT",
        )
    } else if RAW_COUNT_MAGNITUDES.contains(&median) {
        (
            MagUnit::COUNTS,
            "magnetometer values without a unit, far from the Earth's field in µT, gauss or \
             nT: read as raw counts, kept as they are (the µT per count is unknown, so field \
             strengths are in counts)",
        )
    } else {
        (
            MagUnit::NANOTESLA.guessed(),
            "magnetometer unit guessed as nT",
        )
    }
}

/// The magnetometer unit whose factor to µT is `scale` (one of `unit_scale`'s, in
/// `header.rs`).
fn mag_unit_of_scale(scale: f64) -> MagUnit {
    [
        MagUnit::MICROTESLA,
        MagUnit::GAUSS,
        MagUnit::MILLIGAUSS,
        MagUnit::NANOTESLA,
        MagUnit::TESLA,
    ]
    .into_iter()
    .find(|unit| unit.ut_per_unit == Some(scale))
    .unwrap_or(MagUnit {
        name: "the log's unit",
        ut_per_unit: Some(scale),
        origin: crate::io::UnitOrigin::Stated,
    })
}

/// Accelerometer unit from the median specific force: about 1 in g, 9.8 in m/s².
fn guess_acc_scale(median: f64) -> (f64, &'static str) {
    if median < 3.0 {
        (STANDARD_GRAVITY_MPS2, "accelerometer unit guessed as g")
    } else {
        (1.0, "accelerometer unit guessed as m/s²")
    }
}

/// Gyroscope unit from the median rate: a median above 1.5 would be 86°/s in rad/s,
/// more than a walk or a drive turns for most of the time.
fn guess_gyro_scale(median: f64) -> (f64, &'static str) {
    if median > 1.5 {
        (DEG_TO_RAD, "gyroscope unit guessed as deg/s")
    } else {
        (1.0, "gyroscope unit guessed as rad/s")
    }
}

/// Time unit from the values: epoch nanoseconds, microseconds, milliseconds or
/// seconds, told apart by magnitude.
fn guess_time_scale(recording: &mut Recording) -> (f64, &'static str) {
    let mut largest = 0.0f64;
    for_each_time(recording, |t| {
        if t.is_finite() {
            largest = largest.max(t.abs());
        }
    });
    if largest > 1e17 {
        (1e-9, "nanoseconds")
    } else if largest > 1e14 {
        (1e-6, "microseconds")
    } else if largest > 1e11 {
        (1e-3, "milliseconds")
    } else {
        (1.0, "seconds")
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::read_text;
    use super::super::{header_columns, looks_like};
    use super::*;
    use crate::io::recording::GnssFix;
    use crate::io::SensorFrame;

    #[test]
    fn the_first_time_of_sorted_streams_is_the_earliest_first_sample() {
        let mut recording = Recording::default();
        recording.mag_in_body_ut.push(5.0, Vector3::zeros());
        recording.mag_in_body_ut.push(9.0, Vector3::zeros());
        recording.ref_heading_rad.push(3.5, 0.0);
        recording.gnss.push(4.0, GnssFix::default());
        assert_eq!(first_time_of_sorted(&recording), 3.5);
        assert_eq!(first_time(&mut recording), 3.5);
        assert_eq!(first_time_of_sorted(&Recording::default()), f64::INFINITY);
    }

    #[test]
    fn settings_lines_before_the_header_give_the_rate_and_raw_counts_are_counts() {
        let text = "Fs,50.00\nInitialization time,60\nmx,my,mz\n6202,682,4812\n6177,682,4827\n6190,690,4800\n";
        let report = read_text(text);
        assert!(report.diagnostics.is_empty(), "{:?}", report.diagnostics);
        let mag = &report.recording.mag_in_body_ut;
        assert_eq!(mag.t_s, vec![0.0, 0.02, 0.04]);
        // Kept as they are, in counts.
        assert_eq!(mag.values[0], Vector3::new(6202.0, 682.0, 4812.0));
        assert_eq!(
            report.mag_frame,
            Some(SensorFrame::columns_as_body(MagUnit::COUNTS))
        );
        let notes = report.notes.join("\n");
        for expected in [
            "Fs = 50 (line 1: the sample rate in Hz, used for the times)",
            "Initialization time = 60 (line 2: not used)",
            "no time column: the samples are spaced at 50 Hz, the rate on line 1 (Fs,50.00)",
            "read as raw counts",
        ] {
            assert!(notes.contains(expected), "{expected}\n{notes}");
        }
        assert!(looks_like(&[
            "Fs,50.00",
            "Initialization time,60",
            "mx,my,mz",
            "1,2,3"
        ]));
        assert_eq!(
            header_columns(&["Fs,50.00", "mx,my,mz"]),
            Some(vec!["mx".to_string(), "my".to_string(), "mz".to_string()])
        );
        // With a time column, the rate is only noted.
        let timed = read_text("rate,100\nt_s,mx,my,mz\n0,20,0,-40\n0.5,21,0,-40\n");
        assert_eq!(timed.recording.mag_in_body_ut.t_s, vec![0.0, 0.5]);
        assert!(timed
            .notes
            .iter()
            .any(|note| note.contains("the time column is used instead")));
        // The guess's bands: µT below 1000, counts to 20,000, nT above.
        assert_eq!(guess_mag_unit(600.0).0, MagUnit::MICROTESLA.guessed());
        assert_eq!(guess_mag_unit(7000.0).0, MagUnit::COUNTS);
        assert_eq!(guess_mag_unit(48_000.0).0, MagUnit::NANOTESLA.guessed());
    }
}
