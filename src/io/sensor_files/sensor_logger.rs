//! Sensor Logger's per-sensor CSV export ([`super`]): the Android app's, whose axes and
//! units are these; an iOS recording is read the same way, and its notes say so. The
//! CSVs that are read go through the delimited reader ([`logger_reader`],
//! [`finish_logger`]); `Metadata.csv` gives notes, and the rest are not used.
//!
//! One CSV per sensor, each with `time` (nanoseconds since 1970, UTC) and
//! `seconds_elapsed` (seconds since the recording started, one clock for every file),
//! the vectors as `z, y, x` in Android device axes:
//!
//! ```text
//! time,seconds_elapsed,z,y,x
//! 1679068247375690000,0.17668994140625,9.66539192199707,-0.002394201699644327,0.12689268589019775
//! ```
//!
//! - `TotalAcceleration.csv`: the accelerometer (specific force, gravity included), m/s².
//! - `Accelerometer.csv` (gravity removed by the OS) and `Gravity.csv` (the OS's gravity
//!   estimate) are not what an accelerometer reports, and not a magnetometer: not used.
//! - `AccelerometerUncalibrated.csv`: the accelerometer, used only without
//!   `TotalAcceleration.csv`.
//! - `Gyroscope.csv`: rad/s, the OS's drift removed; `GyroscopeUncalibrated.csv` is used
//!   only without it.
//! - `MagnetometerUncalibrated.csv`: the raw field, µT: the magnetometer to calibrate.
//!   `Magnetometer.csv`: the OS-calibrated field. With both, raw − calibrated (paired
//!   sample by sample) is the OS's own hard-iron estimate (`mag_bias_in_body_ut`); alone,
//!   the calibrated one is the magnetometer.
//! - `Location.csv`: `latitude`, `longitude`, `altitude`, `speed`, `bearing` (the course,
//!   degrees from true north), `horizontalAccuracy`; `Barometer.csv`: `pressure` (hPa).
//! - `Orientation.csv`: the app's quaternion and angles, in its own conventions: not used.
//! - `Metadata.csv`: the phone, the app's version, the sensors and their sample periods,
//!   for the notes.
//!
//! Times are `seconds_elapsed`, shared by every file; the recording's start in UTC is
//! `time − seconds_elapsed` of a file's first row (every file gives the same within
//! milliseconds).

use super::{Role, SensorFile, SensorImport, SENSOR_LOGGER};
use crate::io::delimited::{self, RawImport, SensorAxes, XyzColumns};
use crate::io::number::parse_f64;
use crate::io::recording::GyroBias;
use crate::io::shorten;

/// Sensor Logger's per-sensor files.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LoggerFile {
    TotalAcceleration,
    AccelerometerUncalibrated,
    /// Gravity removed: not used.
    Accelerometer,
    /// The OS's gravity estimate: not used.
    Gravity,
    Gyroscope,
    GyroscopeUncalibrated,
    /// OS-calibrated.
    Magnetometer,
    MagnetometerUncalibrated,
    Location,
    Barometer,
    /// The app's own attitude: not used.
    Orientation,
    Metadata,
}

impl LoggerFile {
    pub(super) const ALL: [(LoggerFile, &'static str); 12] = [
        (LoggerFile::TotalAcceleration, "TotalAcceleration.csv"),
        (
            LoggerFile::AccelerometerUncalibrated,
            "AccelerometerUncalibrated.csv",
        ),
        (LoggerFile::Accelerometer, "Accelerometer.csv"),
        (LoggerFile::Gravity, "Gravity.csv"),
        (LoggerFile::Gyroscope, "Gyroscope.csv"),
        (
            LoggerFile::GyroscopeUncalibrated,
            "GyroscopeUncalibrated.csv",
        ),
        (LoggerFile::Magnetometer, "Magnetometer.csv"),
        (
            LoggerFile::MagnetometerUncalibrated,
            "MagnetometerUncalibrated.csv",
        ),
        (LoggerFile::Location, "Location.csv"),
        (LoggerFile::Barometer, "Barometer.csv"),
        (LoggerFile::Orientation, "Orientation.csv"),
        (LoggerFile::Metadata, "Metadata.csv"),
    ];

    /// What the file's x, y, z columns are, for the vector files that are used.
    fn xyz_columns(self) -> Option<XyzColumns> {
        match self {
            LoggerFile::TotalAcceleration | LoggerFile::AccelerometerUncalibrated => {
                Some(XyzColumns::Accelerometer)
            }
            LoggerFile::Gyroscope | LoggerFile::GyroscopeUncalibrated => {
                Some(XyzColumns::Gyroscope)
            }
            LoggerFile::Magnetometer | LoggerFile::MagnetometerUncalibrated => {
                Some(XyzColumns::Magnetometer)
            }
            _ => None,
        }
    }

    /// Why a file is not used, for those that are not.
    pub(super) fn not_used(self) -> Option<&'static str> {
        match self {
            LoggerFile::Accelerometer => Some(
                "the acceleration with gravity removed by the OS, which is not what an \
                 accelerometer reports (TotalAcceleration.csv is): not used",
            ),
            LoggerFile::Gravity => Some(
                "the OS's gravity estimate, neither the accelerometer nor a magnetometer \
                 (tilt comes from TotalAcceleration.csv and the gyroscope): not used",
            ),
            LoggerFile::Orientation => {
                Some("the app's own orientation, in its own conventions: not used")
            }
            _ => None,
        }
    }

    /// What the file gives, for the notes.
    fn describe(self) -> &'static str {
        match self {
            LoggerFile::TotalAcceleration => {
                "the accelerometer (m/s², gravity included), Android device axes"
            }
            LoggerFile::AccelerometerUncalibrated => {
                "the uncalibrated accelerometer (m/s², gravity included), Android device axes"
            }
            LoggerFile::Gyroscope => {
                "the gyroscope (rad/s, the OS's drift removed), Android device axes"
            }
            LoggerFile::GyroscopeUncalibrated => {
                "the uncalibrated gyroscope (rad/s), Android device axes"
            }
            LoggerFile::Magnetometer => {
                "the OS-calibrated magnetometer (µT, the OS's hard-iron estimate removed), \
                 Android device axes"
            }
            LoggerFile::MagnetometerUncalibrated => {
                "the raw magnetometer (µT), Android device axes"
            }
            LoggerFile::Location => {
                "GNSS fixes: latitude, longitude, altitude, speed, bearing (the course, from \
                 true north) and horizontal accuracy"
            }
            LoggerFile::Barometer => "the pressure (hPa)",
            _ => "",
        }
    }

    fn role(self) -> Role {
        match self {
            LoggerFile::TotalAcceleration => Role::Accelerometer { alternative: false },
            LoggerFile::AccelerometerUncalibrated => Role::Accelerometer { alternative: true },
            LoggerFile::Gyroscope => Role::Gyroscope { alternative: false },
            LoggerFile::GyroscopeUncalibrated => Role::Gyroscope { alternative: true },
            LoggerFile::Magnetometer => Role::CalibratedMagnetometer,
            LoggerFile::MagnetometerUncalibrated => Role::RawMagnetometer,
            _ => Role::Other,
        }
    }
}

pub(super) fn recognise_logger(kind: LoggerFile, sample_lines: &[&str]) -> Option<SensorFile> {
    let header = sample_lines.first()?;
    let columns: Vec<String> = header
        .trim_start_matches('\u{feff}')
        .split(',')
        .map(|name| name.trim().trim_matches('"').to_lowercase())
        .collect();
    let has = |name: &str| columns.iter().any(|column| column == name);
    if kind == LoggerFile::Metadata {
        let fits = has("version") && (has("device name") || has("appversion"));
        return fits.then_some(SensorFile::SensorLogger {
            kind,
            start_unix_s: None,
        });
    }
    let timed = has("time") && has("seconds_elapsed");
    let fits = timed
        && match kind {
            LoggerFile::Location => has("latitude") && has("longitude"),
            LoggerFile::Barometer => has("pressure"),
            LoggerFile::Orientation => true,
            _ => has("x") && has("y") && has("z"),
        };
    if !fits {
        return None;
    }
    // The start: time (ns since 1970) − seconds_elapsed, on the first row that has both.
    let time_idx = columns.iter().position(|column| column == "time")?;
    let elapsed_idx = columns
        .iter()
        .position(|column| column == "seconds_elapsed")?;
    let start_unix_s = sample_lines.iter().skip(1).find_map(|line| {
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        let time_ns = parse_f64(fields.get(time_idx)?)?;
        let elapsed_s = parse_f64(fields.get(elapsed_idx)?)?;
        // Nanoseconds since 1970 are beyond 1e17 from 1973 on.
        (time_ns > 1e17 && time_ns.is_finite() && elapsed_s.is_finite())
            .then_some(time_ns * 1e-9 - elapsed_s)
    });
    Some(SensorFile::SensorLogger { kind, start_unix_s })
}

/// A delimited reader for a Sensor Logger CSV that is read (vectors, location,
/// pressure); `None` for the files read otherwise.
pub fn logger_reader(
    kind: LoggerFile,
    size_hint_bytes: Option<usize>,
) -> Option<delimited::DelimitedReader> {
    match kind {
        LoggerFile::Accelerometer
        | LoggerFile::Gravity
        | LoggerFile::Orientation
        | LoggerFile::Metadata => None,
        _ => Some(
            delimited::DelimitedReader::new(size_hint_bytes).with_xyz_columns(kind.xyz_columns()),
        ),
    }
}

/// A Sensor Logger CSV read by the delimited reader, with what it gives and its start.
pub fn finish_logger(
    kind: LoggerFile,
    start_unix_s: Option<f64>,
    mut raw: RawImport,
) -> SensorImport {
    let report = &mut raw.report;
    report.format = SENSOR_LOGGER;
    // (The clock is noted once for all the files, by `choose`.)
    report.recording.start_unix_s = start_unix_s;
    let mut notes = vec![format!("Sensor Logger: {}", kind.describe())];
    notes.append(&mut report.notes);
    report.notes = notes;
    if kind.xyz_columns().is_some() {
        raw.axes = SensorAxes::AndroidDevice;
    }
    if kind == LoggerFile::Gyroscope {
        report.recording.gyro_bias = GyroBias::RemovedByDevice;
    }
    SensorImport {
        raw,
        role: kind.role(),
    }
}

/// How many sensors of `Metadata.csv` the notes list.
const MAX_SENSORS_LISTED: usize = 32;

/// Sensor Logger's `Metadata.csv`: a header and one row.
pub(super) fn metadata_notes(lines: &[String]) -> Vec<String> {
    let (Some(header), Some(row)) = (lines.first(), lines.get(1)) else {
        return vec!["Sensor Logger metadata: no row under the header".to_string()];
    };
    let names: Vec<&str> = header.split(',').map(str::trim).collect();
    let values: Vec<&str> = row.split(',').map(str::trim).collect();
    let value_of = |name: &str| {
        names
            .iter()
            .position(|column| column.eq_ignore_ascii_case(name))
            .and_then(|idx| values.get(idx))
            .copied()
            .unwrap_or("?")
    };
    let mut notes = vec![format!(
        "Sensor Logger {} ({}) on {}, recording {}",
        shorten(value_of("appVersion")),
        shorten(value_of("platform")),
        shorten(value_of("device name")),
        shorten(value_of("recording time")),
    )];
    if value_of("platform").eq_ignore_ascii_case("ios") {
        notes.push(
            "Sensor Logger on iOS: its files were read with Android's device axes and units, \
             which this tool has only checked on Android recordings"
                .to_string(),
        );
    }
    let sensors: Vec<&str> = value_of("sensors").split('|').collect();
    let periods: Vec<&str> = value_of("sampleRateMs").split('|').collect();
    if sensors.len() == periods.len() && sensors.len() > 1 {
        let listed: Vec<String> = sensors
            .iter()
            .zip(&periods)
            .take(MAX_SENSORS_LISTED)
            .map(|(sensor, period)| match period.trim() {
                "" => format!("{} (no period)", shorten(sensor)),
                period => format!("{} {} ms", shorten(sensor), shorten(period)),
            })
            .collect();
        notes.push(format!(
            "Sensor Logger sample periods: {}",
            listed.join(", ")
        ));
    }
    notes
}
