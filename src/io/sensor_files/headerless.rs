//! Headerless per-sensor text ([`super`]), as the TYREX attitude benchmark's Android
//! logger writes it, read here line by line, with the benchmark's `record.properties`.
//!
//! One whitespace-separated file per sensor, no header, `t` in seconds on the phone's
//! clock, Android device axes, m/s², rad/s, µT (Michel et al., "On Attitude Estimation
//! with Smartphones", the `datasets/android/<trial>/` files of GitHub
//! `tyrex-team/benchmarks-attitude-smartphones`):
//!
//! ```text
//! accelerometer.txt             t ax ay az
//! gyroscope.txt                 t wx wy wz bx by bz     raw rate, the OS's drift estimate
//! gyroscope-calibrated.txt      t wx wy wz
//! magnetometer.txt              t mx my mz bx by bz     raw field, the OS's bias estimate
//! magnetometer-calibrated.txt   t mx my mz
//! linear-acceleration.txt       t ax ay az              gravity removed: not used
//! rotation-vector.txt           t x y z w [accuracy]    the phone's own attitude: not used
//! record.properties             [Device] Manufacturer, Model, OSVersion; [Time] StartTime
//! ```
//!
//! `magnetometer.txt` is the magnetometer with its bias as the OS's hard-iron estimate;
//! `gyroscope-calibrated.txt` is the gyroscope, else `gyroscope.txt` with its drift
//! estimate removed (which is what Android's calibrated rate is); `StartTime` (seconds
//! since 1970) is taken as `t = 0`.

use nalgebra::Vector3;

use super::{notes_only, Role, SensorFileReader, SensorImport, HEADERLESS_TEXT};
use crate::base::calendar::utc_text;
use crate::io::delimited::{RawImport, SensorAxes};
use crate::io::number::parse_f64;
use crate::io::recording::{GyroBias, Recording, Stream};
use crate::io::{shorten, Diagnostics, ImportError, ImportReport, MagUnit};

/// The headerless per-sensor files.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HeaderlessFile {
    Accelerometer,
    /// Raw rate and the OS's drift estimate.
    Gyroscope,
    GyroscopeCalibrated,
    /// Raw field and the OS's bias estimate.
    Magnetometer,
    MagnetometerCalibrated,
    /// Gravity removed: not used.
    LinearAcceleration,
    /// The phone's own attitude: not used.
    RotationVector,
    /// The time offset to the motion capture: not used.
    TimeAlignment,
}

impl HeaderlessFile {
    pub(super) const ALL: [(HeaderlessFile, &'static str); 8] = [
        (HeaderlessFile::Accelerometer, "accelerometer.txt"),
        (HeaderlessFile::Gyroscope, "gyroscope.txt"),
        (
            HeaderlessFile::GyroscopeCalibrated,
            "gyroscope-calibrated.txt",
        ),
        (HeaderlessFile::Magnetometer, "magnetometer.txt"),
        (
            HeaderlessFile::MagnetometerCalibrated,
            "magnetometer-calibrated.txt",
        ),
        (
            HeaderlessFile::LinearAcceleration,
            "linear-acceleration.txt",
        ),
        (HeaderlessFile::RotationVector, "rotation-vector.txt"),
        (HeaderlessFile::TimeAlignment, "timeAlignment.txt"),
    ];

    /// How many numbers a line holds: (fewest, most).
    pub(super) fn n_numbers(self) -> (usize, usize) {
        match self {
            HeaderlessFile::Gyroscope | HeaderlessFile::Magnetometer => (7, 7),
            HeaderlessFile::RotationVector => (5, 6),
            HeaderlessFile::TimeAlignment => (1, 1),
            _ => (4, 4),
        }
    }

    pub(super) fn not_used(self) -> Option<&'static str> {
        match self {
            HeaderlessFile::LinearAcceleration => Some(
                "the acceleration with gravity removed by the OS, which is not what an \
                 accelerometer reports (accelerometer.txt is): not used",
            ),
            HeaderlessFile::RotationVector => Some(
                "the phone's own attitude (rotation vector x, y, z, w), neither an \
                 accelerometer nor a magnetometer: not used",
            ),
            HeaderlessFile::TimeAlignment => {
                Some("the time offset to the motion-capture truth: not used")
            }
            _ => None,
        }
    }

    fn role(self) -> Role {
        match self {
            HeaderlessFile::Accelerometer => Role::Accelerometer { alternative: false },
            HeaderlessFile::GyroscopeCalibrated => Role::Gyroscope { alternative: false },
            HeaderlessFile::Gyroscope => Role::Gyroscope { alternative: true },
            HeaderlessFile::Magnetometer => Role::RawMagnetometer,
            HeaderlessFile::MagnetometerCalibrated => Role::CalibratedMagnetometer,
            _ => Role::Other,
        }
    }
}

/// The numbers of a line split on white space, when it is only numbers.
pub(super) fn numbers_of(line: &str) -> Option<Vec<f64>> {
    let numbers: Option<Vec<f64>> = line.split_ascii_whitespace().map(parse_f64).collect();
    numbers.filter(|numbers| !numbers.is_empty())
}

/// The streams of a headerless file, on its own clock, in device axes.
#[derive(Default)]
pub(super) struct HeaderlessStreams {
    vector: Stream<Vector3<f64>>,
    /// The OS's estimate beside the raw values (drift, bias), where the file has one.
    estimate: Stream<Vector3<f64>>,
    diagnostics: Diagnostics,
    n_data_lines: usize,
    went_back: bool,
}

impl SensorFileReader {
    pub(super) fn read_numbers(
        &mut self,
        kind: HeaderlessFile,
        number: usize,
        text: &str,
        truncated: bool,
    ) {
        let streams = &mut self.headerless;
        streams.n_data_lines += 1;
        if truncated {
            streams.diagnostics.push(
                Some(number),
                "line too long; skipped, as its end is missing",
            );
            return;
        }
        let (fewest, most) = kind.n_numbers();
        let numbers = match numbers_of(text) {
            Some(numbers) if (fewest..=most).contains(&numbers.len()) => numbers,
            Some(numbers) => {
                streams.diagnostics.push(
                    Some(number),
                    format!(
                        "{} numbers where this file has {fewest} (t x y z{}); skipped",
                        numbers.len(),
                        if fewest == 7 { " bx by bz" } else { "" }
                    ),
                );
                return;
            }
            None => {
                streams.diagnostics.push(
                    Some(number),
                    format!("not a line of numbers ({}); skipped", shorten(text)),
                );
                return;
            }
        };
        let finite = numbers.iter().all(|value| value.is_finite());
        let (Some(&t_s), true) = (numbers.first(), finite) else {
            streams
                .diagnostics
                .push(Some(number), "a value is not finite; skipped");
            return;
        };
        let at = |idx: usize| numbers.get(idx).copied().unwrap_or(0.0);
        if streams.vector.t_s.last().is_some_and(|&last| t_s < last) {
            streams.went_back = true;
        }
        streams.vector.push(t_s, Vector3::new(at(1), at(2), at(3)));
        if numbers.len() >= 7 {
            streams
                .estimate
                .push(t_s, Vector3::new(at(4), at(5), at(6)));
        }
    }
}

/// The benchmark's `record.properties`: the phone in the notes, `StartTime` (seconds
/// since 1970) as the recording's start.
pub(super) fn properties_import(file_name: &str, lines: &[String], n_lines: usize) -> SensorImport {
    let value_of = |key: &str| {
        lines.iter().find_map(|line| {
            let (name, value) = line.split_once('=')?;
            (name.trim() == key).then(|| value.trim())
        })
    };
    let mut notes = Vec::new();
    let phone = [value_of("Manufacturer"), value_of("Model")]
        .into_iter()
        .flatten()
        .collect::<Vec<_>>()
        .join(" ");
    if !phone.is_empty() {
        let os = value_of("OSVersion").map_or(String::new(), |api| format!(", Android API {api}"));
        notes.push(format!("the phone: {}{os}", shorten(&phone)));
    }
    let start_unix_s = value_of("StartTime")
        .and_then(parse_f64)
        .filter(|start_s| start_s.is_finite() && *start_s > 1e8);
    match start_unix_s {
        Some(start_unix_s) => notes.push(format!(
            "StartTime {} taken as t = 0 of the sensor files (dates the log for the magnetic \
             model)",
            utc_text(start_unix_s)
        )),
        None => notes.push("no StartTime: the log is not dated".to_string()),
    }
    let mut import = notes_only(file_name, HEADERLESS_TEXT, notes, n_lines);
    import.raw.report.recording.start_unix_s = start_unix_s;
    import
}

pub(super) fn headerless_import(
    file_name: &str,
    kind: HeaderlessFile,
    mut streams: HeaderlessStreams,
    n_lines: usize,
) -> Result<SensorImport, ImportError> {
    if streams.vector.is_empty() {
        let first_problem = streams
            .diagnostics
            .kept
            .first()
            .map(|diagnostic| match diagnostic.line {
                Some(line) => format!(" (line {line}: {})", diagnostic.message),
                None => format!(" ({})", diagnostic.message),
            })
            .unwrap_or_default();
        return Err(ImportError::NothingRecognised {
            file_name: file_name.to_string(),
            format: HEADERLESS_TEXT,
            n_lines,
            first_problem,
        });
    }
    if streams.went_back {
        let n_out_of_order = streams.vector.sort_by_time();
        streams.estimate.sort_by_time();
        streams
            .diagnostics
            .push_sorted_by_time(None, n_out_of_order);
    }
    let mut recording = Recording::default();
    let mut notes = Vec::new();
    let mut mag_unit = None;
    let n = streams.vector.len();
    match kind {
        HeaderlessFile::Accelerometer => {
            recording.acc_in_body_mps2 = streams.vector;
            notes.push(format!(
                "{n} accelerometer samples (t x y z: s, m/s², gravity included), Android device axes"
            ));
        }
        HeaderlessFile::GyroscopeCalibrated => {
            recording.gyro_in_body_radps = streams.vector;
            recording.gyro_bias = GyroBias::RemovedByDevice;
            notes.push(format!(
                "{n} gyroscope samples (t x y z: s, rad/s, the OS's drift removed), Android device axes"
            ));
        }
        HeaderlessFile::Gyroscope => {
            // Android's calibrated rate is the raw rate minus its drift estimate.
            let mut gyro = streams.vector;
            for (rate, drift) in gyro.values.iter_mut().zip(&streams.estimate.values) {
                *rate -= drift;
            }
            recording.gyro_in_body_radps = gyro;
            recording.gyro_bias = GyroBias::RemovedByDevice;
            notes.push(format!(
                "{n} gyroscope samples (t x y z bx by bz: s, rad/s): the raw rate minus the OS's \
                 drift estimate, Android device axes"
            ));
        }
        HeaderlessFile::Magnetometer => {
            recording.mag_in_body_ut = streams.vector;
            recording.mag_bias_in_body_ut = streams.estimate;
            mag_unit = Some(MagUnit::MICROTESLA);
            notes.push(format!(
                "{n} magnetometer samples (t x y z bx by bz: s, µT): the raw field, with the \
                 OS's hard-iron estimate kept as the device bias, Android device axes"
            ));
        }
        HeaderlessFile::MagnetometerCalibrated => {
            recording.mag_in_body_ut = streams.vector;
            mag_unit = Some(MagUnit::MICROTESLA);
            notes.push(format!(
                "{n} magnetometer samples (t x y z: s, µT), OS-calibrated (its hard-iron \
                 estimate removed), Android device axes"
            ));
        }
        HeaderlessFile::LinearAcceleration
        | HeaderlessFile::RotationVector
        | HeaderlessFile::TimeAlignment => {}
    }
    Ok(SensorImport {
        raw: RawImport {
            report: ImportReport {
                autopilot: None,
                file_name: file_name.to_string(),
                format: HEADERLESS_TEXT,
                recording,
                diagnostics: streams.diagnostics,
                header: None,
                n_data_lines: streams.n_data_lines,
                notes,
                mag_frame: None,
            },
            axes: SensorAxes::AndroidDevice,
            mag_unit,
        },
        role: kind.role(),
    })
}
