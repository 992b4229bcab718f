//! Per-sensor files of phone apps, told by their file name *and* their first lines (a
//! name alone never decides: phyphox also writes `Accelerometer.csv`), and the choices
//! made when several of them are merged into one recording.
//!
//! ## Sensor Logger (per-sensor CSV export; the Android app's, whose axes and units are
//! these; an iOS recording is read the same way, and its notes say so)
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
//!
//! ## Headerless per-sensor text (the TYREX attitude benchmark's Android logger)
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
//!
//! Device axes become body axes in [`super::delimited::RawImport::into_report`], through
//! [`super::axes::PhoneMount`], once all files are merged.

use nalgebra::Vector3;

use super::delimited::{self, RawImport, SensorAxes, XyzColumns};
use super::lines::Line;
use super::number::parse_f64;
use super::{shorten, Diagnostics, ImportError, ImportReport, MagUnit};
use crate::recording::{Recording, Stream};

/// The format name of Sensor Logger's per-sensor CSVs.
pub const SENSOR_LOGGER: &str = "Sensor Logger CSV";
/// The format name of headerless per-sensor text.
pub const HEADERLESS_TEXT: &str = "headerless per-sensor text";

/// A per-sensor file recognised by its name and first lines.
#[derive(Debug, Clone, PartialEq)]
pub enum SensorFile {
    /// One of Sensor Logger's CSVs, with the recording's start told by its first row.
    SensorLogger {
        kind: LoggerFile,
        start_unix_s: Option<f64>,
    },
    /// A headerless whitespace-separated sensor file.
    Headerless(HeaderlessFile),
    /// The benchmark's `record.properties`.
    RecordProperties,
}

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

impl LoggerFile {
    const ALL: [(LoggerFile, &'static str); 12] = [
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
    fn not_used(self) -> Option<&'static str> {
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

impl HeaderlessFile {
    const ALL: [(HeaderlessFile, &'static str); 8] = [
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
    fn n_numbers(self) -> (usize, usize) {
        match self {
            HeaderlessFile::Gyroscope | HeaderlessFile::Magnetometer => (7, 7),
            HeaderlessFile::RotationVector => (5, 6),
            HeaderlessFile::TimeAlignment => (1, 1),
            _ => (4, 4),
        }
    }

    fn not_used(self) -> Option<&'static str> {
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

/// What a per-sensor file gives the recording, for the choices of the merge.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Role {
    /// Specific force, gravity included; an alternative is used only without the other.
    Accelerometer {
        alternative: bool,
    },
    /// An alternative is used only without the other.
    Gyroscope {
        alternative: bool,
    },
    /// The raw field: the magnetometer to calibrate.
    RawMagnetometer,
    /// The OS-calibrated field: the magnetometer only when there is no raw one.
    CalibratedMagnetometer,
    Other,
}

/// A per-sensor file as read, in Android device axes, with what it gives.
#[derive(Debug, Clone, PartialEq)]
pub struct SensorImport {
    pub raw: RawImport,
    pub role: Role,
}

/// The file's name without its folders.
fn base_name(file_name: &str) -> &str {
    file_name.rsplit(['/', '\\']).next().unwrap_or(file_name)
}

/// The per-sensor file `file_name` is, judged from its name and its first non-blank
/// lines (trimmed); `None` when either does not fit.
pub fn recognise(file_name: &str, sample_lines: &[&str]) -> Option<SensorFile> {
    let name = base_name(file_name);
    if let Some(kind) = LoggerFile::ALL
        .iter()
        .find(|(_, known)| known.eq_ignore_ascii_case(name))
        .map(|(kind, _)| *kind)
    {
        return recognise_logger(kind, sample_lines);
    }
    if let Some(kind) = HeaderlessFile::ALL
        .iter()
        .find(|(_, known)| known.eq_ignore_ascii_case(name))
        .map(|(kind, _)| *kind)
    {
        let first = sample_lines.first()?;
        let n_numbers = numbers_of(first)?.len();
        let (fewest, most) = kind.n_numbers();
        return (fewest..=most)
            .contains(&n_numbers)
            .then_some(SensorFile::Headerless(kind));
    }
    let is_properties = name.eq_ignore_ascii_case("record.properties")
        && sample_lines.iter().any(|line| {
            line.starts_with("[Device]") || line.starts_with("[Time]") || line.contains("StartTime")
        });
    is_properties.then_some(SensorFile::RecordProperties)
}

fn recognise_logger(kind: LoggerFile, sample_lines: &[&str]) -> Option<SensorFile> {
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

/// The numbers of a line split on white space, when it is only numbers.
fn numbers_of(line: &str) -> Option<Vec<f64>> {
    let numbers: Option<Vec<f64>> = line.split_ascii_whitespace().map(parse_f64).collect();
    numbers.filter(|numbers| !numbers.is_empty())
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
    SensorImport {
        raw,
        role: kind.role(),
    }
}

/// A date and time for people, `2023-03-17 14:50:47.2 UTC`.
fn utc_text(unix_s: f64) -> String {
    // Within a million years of 1970, where the calendar is meaningful.
    const MAX_ABS_DAYS: f64 = 365.25 * 1e6;
    let days = (unix_s / 86_400.0).floor();
    if !days.is_finite() || days.abs() > MAX_ABS_DAYS {
        return format!("{unix_s:.1} s after 1970");
    }
    let seconds_of_day = unix_s - days * 86_400.0;
    let (year, month, day) = crate::civil::civil_from_days(days as i64);
    let hours = (seconds_of_day / 3600.0).floor();
    let minutes = ((seconds_of_day - hours * 3600.0) / 60.0).floor();
    let seconds = seconds_of_day - hours * 3600.0 - minutes * 60.0;
    format!("{year:04}-{month:02}-{day:02} {hours:02.0}:{minutes:02.0}:{seconds:04.1} UTC")
}

/// An import that gives only notes (a file that is recognised and not used, or one of
/// metadata).
fn notes_only(
    file_name: &str,
    format: &'static str,
    notes: Vec<String>,
    n_lines: usize,
) -> SensorImport {
    SensorImport {
        raw: RawImport {
            report: ImportReport {
                file_name: file_name.to_string(),
                format,
                recording: Recording::default(),
                diagnostics: Diagnostics::default(),
                header: None,
                n_data_lines: n_lines,
                notes,
                mag_frame: None,
            },
            axes: SensorAxes::AndroidDevice,
            mag_unit: None,
        },
        role: Role::Other,
    }
}

/// The reader of a per-sensor file that the delimited reader does not read: lines are
/// counted (a file that is not used), kept (metadata, properties) or read as numbers
/// (headerless files).
pub struct SensorFileReader {
    file: SensorFile,
    n_lines: usize,
    /// The first lines, for the files read as metadata.
    kept_lines: Vec<String>,
    headerless: HeaderlessStreams,
}

/// How many sensors of `Metadata.csv` the notes list.
const MAX_SENSORS_LISTED: usize = 32;

/// How many lines of a metadata file are kept.
const MAX_KEPT_LINES: usize = 64;

/// The streams of a headerless file, on its own clock, in device axes.
#[derive(Default)]
struct HeaderlessStreams {
    vector: Stream<Vector3<f64>>,
    /// The OS's estimate beside the raw values (drift, bias), where the file has one.
    estimate: Stream<Vector3<f64>>,
    diagnostics: Diagnostics,
    n_data_lines: usize,
    went_back: bool,
}

impl SensorFileReader {
    pub fn new(file: SensorFile) -> SensorFileReader {
        SensorFileReader {
            file,
            n_lines: 0,
            kept_lines: Vec::new(),
            headerless: HeaderlessStreams::default(),
        }
    }

    pub fn read_line(&mut self, line: &Line<'_>) {
        self.n_lines = self.n_lines.max(line.number);
        let text = line.text.trim_start_matches('\u{feff}').trim();
        if text.is_empty() {
            return;
        }
        match self.file {
            SensorFile::Headerless(kind) if kind.not_used().is_none() => {
                self.read_numbers(kind, line.number, text, line.truncated)
            }
            SensorFile::SensorLogger {
                kind: LoggerFile::Metadata,
                ..
            }
            | SensorFile::RecordProperties
                if self.kept_lines.len() < MAX_KEPT_LINES =>
            {
                self.kept_lines.push(text.to_string());
            }
            _ => {}
        }
    }

    fn read_numbers(&mut self, kind: HeaderlessFile, number: usize, text: &str, truncated: bool) {
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

    pub fn finish(self, file_name: &str) -> Result<SensorImport, ImportError> {
        match self.file {
            SensorFile::SensorLogger { kind, .. } => {
                let notes = match kind.not_used() {
                    Some(reason) => vec![format!("Sensor Logger: {reason}")],
                    None => metadata_notes(&self.kept_lines),
                };
                Ok(notes_only(file_name, SENSOR_LOGGER, notes, self.n_lines))
            }
            SensorFile::RecordProperties => {
                Ok(properties_import(file_name, &self.kept_lines, self.n_lines))
            }
            SensorFile::Headerless(kind) => match kind.not_used() {
                Some(reason) => Ok(notes_only(
                    file_name,
                    HEADERLESS_TEXT,
                    vec![reason.to_string()],
                    self.n_lines,
                )),
                None => headerless_import(file_name, kind, self.headerless, self.n_lines),
            },
        }
    }
}

/// Sensor Logger's `Metadata.csv`: a header and one row.
fn metadata_notes(lines: &[String]) -> Vec<String> {
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

/// The benchmark's `record.properties`: the phone in the notes, `StartTime` (seconds
/// since 1970) as the recording's start.
fn properties_import(file_name: &str, lines: &[String], n_lines: usize) -> SensorImport {
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

fn headerless_import(
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
        streams.diagnostics.push(
            None,
            format!("time goes backwards {n_out_of_order} times; the samples were sorted by time"),
        );
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

/// The merge's choices among per-sensor files, in file order: an alternative
/// accelerometer or gyroscope is used only without the other; a raw magnetometer is the
/// magnetometer, and an OS-calibrated one beside it gives the OS's hard-iron estimate
/// (raw − calibrated, paired sample by sample) where the raw one has none; alone, the
/// calibrated one is the magnetometer. Hands back the imports, and notes on the choices.
pub fn choose(files: Vec<(String, SensorImport)>) -> (Vec<(String, RawImport)>, Vec<String>) {
    let mut notes = clock_notes(&files);
    let name_of = |role: Role| {
        files
            .iter()
            .find(|(_, import)| import.role == role && has_stream(&import.raw, role))
            .map(|(name, _)| base_name(name).to_string())
    };
    let main_acc = name_of(Role::Accelerometer { alternative: false });
    let main_gyro = name_of(Role::Gyroscope { alternative: false });
    let raw_mag_idx = files.iter().position(|(_, import)| {
        import.role == Role::RawMagnetometer && has_stream(&import.raw, import.role)
    });
    // The calibrated field, to pair with the raw one.
    let calibrated: Option<(String, Stream<Vector3<f64>>)> = files
        .iter()
        .find(|(_, import)| {
            import.role == Role::CalibratedMagnetometer && has_stream(&import.raw, import.role)
        })
        .map(|(name, import)| {
            (
                base_name(name).to_string(),
                import.raw.report.recording.mag_in_body_ut.clone(),
            )
        });
    let raw_mag_name = raw_mag_idx
        .and_then(|idx| files.get(idx))
        .map(|(name, _)| base_name(name).to_string());
    // Whether the raw magnetometer's file has the OS's bias beside it already (then the
    // calibrated file gives nothing).
    let raw_has_bias = raw_mag_idx
        .and_then(|idx| files.get(idx))
        .is_some_and(|(_, import)| !import.raw.report.recording.mag_bias_in_body_ut.is_empty());

    let mut chosen = Vec::with_capacity(files.len());
    for (idx, (name, mut import)) in files.into_iter().enumerate() {
        let recording = &mut import.raw.report.recording;
        match import.role {
            Role::Accelerometer { alternative: true } if main_acc.is_some() => {
                recording.acc_in_body_mps2 = Stream::default();
                notes.push(format!(
                    "{}: not used, {} is the accelerometer",
                    base_name(&name),
                    main_acc.as_deref().unwrap_or_default()
                ));
            }
            Role::Gyroscope { alternative: true } if main_gyro.is_some() => {
                recording.gyro_in_body_radps = Stream::default();
                notes.push(format!(
                    "{}: not used, {} is the gyroscope",
                    base_name(&name),
                    main_gyro.as_deref().unwrap_or_default()
                ));
            }
            Role::RawMagnetometer if Some(idx) == raw_mag_idx => {
                if let (true, Some((calibrated_name, calibrated))) =
                    (recording.mag_bias_in_body_ut.is_empty(), &calibrated)
                {
                    let (bias, n_paired) = paired_difference(&recording.mag_in_body_ut, calibrated);
                    notes.push(bias_note(
                        base_name(&name),
                        calibrated_name,
                        &bias,
                        n_paired,
                        recording.mag_in_body_ut.len(),
                    ));
                    recording.mag_bias_in_body_ut = bias;
                }
            }
            Role::RawMagnetometer => {
                recording.mag_in_body_ut = Stream::default();
                recording.mag_bias_in_body_ut = Stream::default();
                import.raw.mag_unit = None;
                notes.push(format!(
                    "{}: not used, {} is the magnetometer",
                    base_name(&name),
                    raw_mag_name.as_deref().unwrap_or_default()
                ));
            }
            Role::CalibratedMagnetometer if raw_mag_idx.is_some() => {
                recording.mag_in_body_ut = Stream::default();
                import.raw.mag_unit = None;
                if raw_has_bias {
                    notes.push(format!(
                        "{}: not used, {} is the magnetometer and has the OS's bias beside it",
                        base_name(&name),
                        raw_mag_name.as_deref().unwrap_or_default()
                    ));
                }
            }
            Role::CalibratedMagnetometer => notes.push(format!(
                "{}: the OS-calibrated field is the magnetometer (there is no raw one); the OS \
                 has already removed its hard-iron estimate, so a fit should find little offset",
                base_name(&name)
            )),
            _ => {}
        }
        chosen.push((name, import.raw));
    }
    (chosen, notes)
}

/// The files' clocks, said once for all the files of each kind.
fn clock_notes(files: &[(String, SensorImport)]) -> Vec<String> {
    let mut notes = Vec::new();
    let of_format = |format: &'static str| {
        files
            .iter()
            .filter(move |(_, import)| import.raw.report.format == format)
            .map(|(_, import)| &import.raw.report.recording)
    };
    if of_format(SENSOR_LOGGER).any(has_samples) {
        let start = of_format(SENSOR_LOGGER).find_map(|recording| recording.start_unix_s);
        notes.push(format!(
            "Sensor Logger: times are seconds_elapsed, the clock the app's files share{}",
            start.map_or(String::new(), |start_unix_s| format!(
                "; the recording started at {} (time − seconds_elapsed of a file's first row)",
                utc_text(start_unix_s)
            ))
        ));
    }
    if of_format(HEADERLESS_TEXT).any(has_samples) {
        notes.push(
            "headerless sensor files: t in seconds on the phone's clock, which the files \
             share"
                .to_string(),
        );
    }
    notes
}

/// Whether a recording holds any vector or GNSS sample (a file that gives more than
/// notes).
fn has_samples(recording: &Recording) -> bool {
    !(recording.acc_in_body_mps2.is_empty()
        && recording.gyro_in_body_radps.is_empty()
        && recording.mag_in_body_ut.is_empty()
        && recording.gnss.is_empty()
        && recording.pressure_hpa.is_empty())
}

/// Whether an import has the stream its role is about.
fn has_stream(raw: &RawImport, role: Role) -> bool {
    let recording = &raw.report.recording;
    match role {
        Role::Accelerometer { .. } => !recording.acc_in_body_mps2.is_empty(),
        Role::Gyroscope { .. } => !recording.gyro_in_body_radps.is_empty(),
        Role::RawMagnetometer | Role::CalibratedMagnetometer => {
            !recording.mag_in_body_ut.is_empty()
        }
        Role::Other => false,
    }
}

/// `raw − calibrated` at the raw samples' times, each raw sample paired with the
/// calibrated sample nearest in time when that is within half the raw stream's median
/// sample interval (both streams sorted by time). The OS's hard-iron estimate is
/// piecewise constant, and the two files hold the same sensor events with timestamps a
/// fraction of a millisecond apart, so pairing (not interpolating, which would mix in
/// the field's own change between samples) gives it exactly. Returns the difference and
/// how many samples were paired.
fn paired_difference(
    raw: &Stream<Vector3<f64>>,
    calibrated: &Stream<Vector3<f64>>,
) -> (Stream<Vector3<f64>>, usize) {
    let mut intervals: Vec<f64> = raw
        .t_s
        .windows(2)
        .map(|pair| pair[1] - pair[0])
        .filter(|interval| *interval > 0.0)
        .collect();
    intervals.sort_by(f64::total_cmp);
    let tolerance_s = intervals
        .get(intervals.len() / 2)
        .map_or(0.0, |median| 0.5 * median);
    let mut bias = Stream::default();
    let mut next_idx = 0usize;
    for (&t_s, raw_value) in raw.t_s.iter().zip(&raw.values) {
        while calibrated.t_s.get(next_idx).is_some_and(|&t| t < t_s) {
            next_idx += 1;
        }
        let nearest = [next_idx.checked_sub(1), Some(next_idx)]
            .into_iter()
            .flatten()
            .filter_map(|idx| Some((calibrated.t_s.get(idx)?, calibrated.values.get(idx)?)))
            .min_by(|(a, _), (b, _)| (*a - t_s).abs().total_cmp(&(*b - t_s).abs()));
        if let Some((&t, calibrated_value)) = nearest {
            if (t - t_s).abs() <= tolerance_s {
                bias.push(t_s, raw_value - calibrated_value);
            }
        }
    }
    let n_paired = bias.len();
    (bias, n_paired)
}

fn bias_note(
    raw_name: &str,
    calibrated_name: &str,
    bias: &Stream<Vector3<f64>>,
    n_paired: usize,
    n_raw: usize,
) -> String {
    let median = |axis: usize| {
        let mut values: Vec<f64> = bias.values.iter().map(|value| value[axis]).collect();
        values.sort_by(f64::total_cmp);
        values.get(values.len() / 2).copied().unwrap_or(f64::NAN)
    };
    format!(
        "{raw_name} is the magnetometer (the raw field); the OS's own hard-iron estimate is \
         {raw_name} − {calibrated_name}, paired sample by sample ({n_paired} of {n_raw} raw \
         samples within half a sample interval; median ({:.2}, {:.2}, {:.2}) µT in device \
         axes x, y, z), kept as the device bias",
        median(0),
        median(1),
        median(2)
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::import::import_files;

    fn lines(text: &str) -> Vec<&str> {
        text.lines()
            .map(str::trim)
            .filter(|line| !line.is_empty())
            .collect()
    }

    #[test]
    fn files_are_recognised_by_name_and_content_together() {
        let logger =
            "time,seconds_elapsed,z,y,x\n1679068247375690000,0.17668994140625,9.6,0.1,0.2\n";
        let phyphox = "\"Time (s)\",\"X (m/s^2)\",\"Y (m/s^2)\",\"Z (m/s^2)\"\n0.01,0.1,0.2,9.8\n";
        assert_eq!(
            recognise("some/dir/TotalAcceleration.csv", &lines(logger)),
            Some(SensorFile::SensorLogger {
                kind: LoggerFile::TotalAcceleration,
                start_unix_s: Some(1_679_068_247.375_69 - 0.176_689_941_406_25),
            })
        );
        // The same name with phyphox's content, or the content under another name: no.
        assert_eq!(recognise("Accelerometer.csv", &lines(phyphox)), None);
        assert_eq!(recognise("walk.csv", &lines(logger)), None);
        assert_eq!(
            recognise(
                "C:\\trial\\magnetometer.txt",
                &["0.5 35.7 -71.3 375.9 59.9 -74.6 412.0"]
            ),
            Some(SensorFile::Headerless(HeaderlessFile::Magnetometer))
        );
        // A rotation vector has its own layout; a 4-number line is not a magnetometer.txt.
        assert_eq!(
            recognise("rotation-vector.txt", &["0.51 0.07 -0.02 -0.58 0.80 0.17"]),
            Some(SensorFile::Headerless(HeaderlessFile::RotationVector))
        );
        assert_eq!(
            recognise("magnetometer.txt", &["0.5 35.7 -71.3 375.9"]),
            None
        );
        assert_eq!(
            recognise("record.properties", &["[Device]", "Model = Nexus 5"]),
            Some(SensorFile::RecordProperties)
        );
    }

    const TOTAL: &str = "time,seconds_elapsed,z,y,x\n\
        1679068247375690000,0.17668994140625,9.7,0.1,0.2\n\
        1679068247395690000,0.19668994140625,9.7,0.1,0.2\n\
        1679068247415690000,0.21668994140625,9.7,0.1,0.3\n";
    const GRAVITY: &str =
        "time,seconds_elapsed,z,y,x\n1679068247375690000,0.17668994140625,9.8,0.0,0.1\n";
    const CALIBRATED: &str = "time,seconds_elapsed,z,y,x\n\
        1679068247375990000,0.17699,7.0,10.0,-7.0\n\
        1679068247395990000,0.19699,7.5,10.5,-7.0\n\
        1679068247415990000,0.21699,8.0,11.0,-7.0\n";
    const UNCALIBRATED: &str = "time,seconds_elapsed,z,y,x\n\
        1679068247375690000,0.17669,29.0,70.0,8.0\n\
        1679068247395690000,0.19669,29.5,70.5,8.0\n\
        1679068247415690000,0.21669,30.0,bad,8.0\n";
    const LOCATION: &str =
        "time,seconds_elapsed,horizontalAccuracy,speed,bearing,altitude,longitude,latitude\n\
        1679068248793000000,1.594,24.3,0,0,586.5,8.5104485,47.4072629\n";
    const METADATA: &str =
        "version,device name,recording time,platform,appVersion,device id,sensors,sampleRateMs\n\
        3,SM-A520F,2023-03-17_15-50-47,android,1.12.0,8ea4,Accelerometer|Location,20|0\n";

    #[test]
    fn a_sensor_logger_folder_gives_each_file_its_meaning() {
        let files: Vec<(&str, &[u8])> = vec![
            ("Metadata.csv", METADATA.as_bytes()),
            ("Gravity.csv", GRAVITY.as_bytes()),
            ("Magnetometer.csv", CALIBRATED.as_bytes()),
            ("MagnetometerUncalibrated.csv", UNCALIBRATED.as_bytes()),
            ("TotalAcceleration.csv", TOTAL.as_bytes()),
            ("Location.csv", LOCATION.as_bytes()),
        ];
        let report = import_files(&files).expect("imports");
        let r = &report.recording;
        assert_eq!(
            r.acc_in_body_mps2.len(),
            3,
            "TotalAcceleration, not Gravity"
        );
        assert_eq!(r.mag_in_body_ut.len(), 2, "the raw field (one bad line)");
        assert_eq!(r.mag_bias_in_body_ut.len(), 2);
        assert_eq!(r.gnss.len(), 1);
        let start = r.start_unix_s.expect("dated");
        assert!((start - 1_679_068_247.199).abs() < 1e-3, "{start}");
        // Flat (gravity along device z): body = (y, x, −z); bias = raw − calibrated.
        let bias = r.mag_bias_in_body_ut.values[0];
        assert!(
            (bias - Vector3::new(60.0, 15.0, -22.0)).norm() < 1e-9,
            "{bias}"
        );
        assert!((r.mag_in_body_ut.values[0] - Vector3::new(70.0, 8.0, -29.0)).norm() < 1e-9);
        let frame = report.mag_frame.expect("a magnetometer frame");
        assert_eq!(frame.unit, MagUnit::MICROTESLA);
        let notes = report.notes.join("\n");
        for expected in [
            "Gravity.csv: Sensor Logger: the OS's gravity estimate",
            "MagnetometerUncalibrated.csv is the magnetometer",
            "Metadata.csv: Sensor Logger 1.12.0 (android) on SM-A520F",
            "Android device axes, phone held flat",
        ] {
            assert!(notes.contains(expected), "{expected}\n{notes}");
        }
        assert!(!notes.contains("guessed"), "{notes}");
        let bad = &report.diagnostics.kept;
        assert!(
            bad.iter().any(|d| d.line == Some(4)
                && d.file_name.as_deref() == Some("MagnetometerUncalibrated.csv")),
            "{bad:?}"
        );
    }

    #[test]
    fn the_calibrated_magnetometer_alone_is_the_magnetometer() {
        let files: Vec<(&str, &[u8])> = vec![
            ("Magnetometer.csv", CALIBRATED.as_bytes()),
            ("TotalAcceleration.csv", TOTAL.as_bytes()),
        ];
        let report = import_files(&files).expect("imports");
        assert_eq!(report.recording.mag_in_body_ut.len(), 3);
        assert!(report.recording.mag_bias_in_body_ut.is_empty());
        assert!(report
            .notes
            .iter()
            .any(|note| note.contains("OS-calibrated field is the magnetometer")));
    }

    const TYREX_MAG: &str =
        "0.511100381 35.72998 -71.380615 375.9079 59.978516 -74.679565 412.08496\n\
        0.531241983 35.809326 -71.43402 375.88348 59.978516 -74.679565 412.08496\n\
        0.55 oops\n";
    const TYREX_ACC: &str =
        "0.153586954 -0.74057007 1.3436584 9.141418\n0.158622354 -0.7410126 1.2962494 9.170898\n";
    const TYREX_GYRO: &str =
        "0.566489786 -0.2216034 0.032287598 0.46340942 0.008499147 -0.003982544 0.068847656\n";
    const TYREX_ROTATION: &str =
        "0.514793008 0.076385796 -0.022159554 -0.5843173 0.8076184 0.17453292\n";

    #[test]
    fn a_headerless_trial_folder_gives_acc_gyro_mag_and_the_os_bias() {
        let files: Vec<(&str, &[u8])> = vec![
            ("magnetometer.txt", TYREX_MAG.as_bytes()),
            ("accelerometer.txt", TYREX_ACC.as_bytes()),
            ("gyroscope.txt", TYREX_GYRO.as_bytes()),
            ("rotation-vector.txt", TYREX_ROTATION.as_bytes()),
            (
                "magnetometer-calibrated.txt",
                b"0.511100381 -24.249268 3.2989502 -36.177063\n",
            ),
            (
                "record.properties",
                b"[Device]\nManufacturer = LGE\nModel = Nexus 5\nOSVersion = 23\n\n[Time]\nStartTime = 1464686052",
            ),
        ];
        let report = import_files(&files).expect("imports");
        let r = &report.recording;
        assert_eq!(r.acc_in_body_mps2.len(), 2);
        assert_eq!(r.gyro_in_body_radps.len(), 1);
        assert_eq!(r.mag_in_body_ut.len(), 2, "not the rotation vector's");
        assert_eq!(r.mag_bias_in_body_ut.len(), 2);
        assert_eq!(r.start_unix_s, Some(1_464_686_052.0));
        // The raw rate minus the drift, flat: body = (y, x, −z).
        let gyro = r.gyro_in_body_radps.values[0];
        let expected = Vector3::new(
            0.032287598 + 0.003982544,
            -0.2216034 - 0.008499147,
            -(0.46340942 - 0.068847656),
        );
        assert!((gyro - expected).norm() < 1e-9, "{gyro}");
        assert!(report
            .diagnostics
            .kept
            .iter()
            .any(|d| d.line == Some(3) && d.file_name.as_deref() == Some("magnetometer.txt")));
        let notes = report.notes.join("\n");
        assert!(
            notes.contains("rotation-vector.txt: the phone's own attitude"),
            "{notes}"
        );
        assert!(
            notes.contains(
                "magnetometer-calibrated.txt: not used, magnetometer.txt is the magnetometer"
            ),
            "{notes}"
        );
        assert!(
            notes.contains("the phone: LGE Nexus 5, Android API 23"),
            "{notes}"
        );
    }

    #[test]
    fn a_headerless_file_alone_is_read() {
        let report = import_files(&[("magnetometer.txt", TYREX_MAG.as_bytes())]).expect("imports");
        assert_eq!(report.recording.mag_in_body_ut.len(), 2);
        assert_eq!(report.format, HEADERLESS_TEXT);
        assert!(report.mag_frame.is_some());
    }
}
