//! Tagged multi-sensor line logs: the Android sensor dump and GetSensorData.
//!
//! Both formats write one sensor event per line, led by a tag that names the sensor,
//! with all sensors mixed in one file at their own rates. Both report vectors in
//! Android's *device* axes (x right of the screen, y towards its top edge, z out of the
//! screen), which become body axes here through [`PhoneMount`] and nowhere else. The
//! mount is detected from the mean accelerometer reading in device axes; without a
//! clear answer the phone is taken as held flat, and the notes say so.
//!
//! ## Android sensor dump
//!
//! The logs of the Microsoft Indoor Location Competition 2020 (GitHub
//! `location-competition/indoor-location-competition-20`, `data/site1/F1`; value order
//! and units as in Android's `SensorEvent` reference,
//! <https://developer.android.com/reference/android/hardware/SensorEvent>). Lines
//! starting with `#` are a header (`startTime:`, site, device, sensor descriptions);
//! every other line is `unix_ms<TAB>TYPE<TAB>values…` (tabs shown as `⇥`):
//!
//! ```text
//! #⇥startTime:1574562661929
//! 1574562662058⇥TYPE_ACCELEROMETER⇥-1.6145935⇥-0.5860138⇥10.276016⇥2
//! 1574562662058⇥TYPE_GYROSCOPE⇥0.759079⇥0.22821045⇥-0.5694275⇥3
//! 1574562662058⇥TYPE_MAGNETIC_FIELD⇥34.79004⇥2.0629883⇥-30.970764⇥3
//! 1574562662058⇥TYPE_MAGNETIC_FIELD_UNCALIBRATED⇥-21.505737⇥-88.80005⇥-332.47528⇥-56.295776⇥-90.86304⇥-301.50452⇥3
//! 1574562662058⇥TYPE_ROTATION_VECTOR⇥-0.059935603⇥-0.032342788⇥0.7208543⇥3
//! 1574562661937⇥TYPE_WAYPOINT⇥197.70462⇥82.66885
//! ```
//!
//! - `TYPE_ACCELEROMETER x y z [accuracy]`: specific force, m/s² (face up reads
//!   z ≈ +9.81 in device axes).
//! - `TYPE_GYROSCOPE x y z [accuracy]`: rad/s.
//! - `TYPE_MAGNETIC_FIELD x y z [accuracy]`: µT, already corrected by the OS for hard
//!   iron.
//! - `TYPE_MAGNETIC_FIELD_UNCALIBRATED mx my mz bx by bz [accuracy]`: the raw field and
//!   the OS's hard-iron estimate, µT; raw − bias is the calibrated field. The raw field
//!   is what this crate's calibration needs, so it becomes `mag_in_body_ut` whenever the
//!   file has it, and the bias becomes `mag_bias_in_body_ut`.
//! - `TYPE_ROTATION_VECTOR x y z [accuracy or w [heading accuracy]]`: the vector part
//!   of the unit quaternion that turns device axes into east-north-up, with y towards
//!   magnetic north; w = √(1 − x² − y² − z²). A fourth value is the accuracy in these
//!   logs but w in others, so only x, y, z are used (q and −q are the same rotation).
//! - `TYPE_WAYPOINT x y`: surveyed position on the floor plan, metres east and north.
//!
//! Other types (`TYPE_ACCELEROMETER_UNCALIBRATED`, `TYPE_GYROSCOPE_UNCALIBRATED`,
//! `TYPE_WIFI`, `TYPE_BEACON`, `TYPE_BLUE`, …) are counted once in the notes. Time is
//! `t_s = (unix_ms − origin) / 1000` with the `startTime` header as origin, or the
//! earliest sample when there is no header.
//!
//! ## GetSensorData
//!
//! The Android app of the IPIN indoor localisation competitions (smartphone tracks).
//! Source: the format the app writes into the header of every log and its
//! `String.format` calls, GitHub `lopsi/GetSensorData_Android`,
//! `GetSensorData20/app/src/main/java/es/csic/getsensordata/MainActivity.java`, commit
//! d86ac2dab66aaf272b01a5b9c2472e603e862b6b. Lines starting with `%` are comments; the
//! others are `;`-separated and start with a tag:
//!
//! ```text
//! ACCE;0.012;9635.412;0.07184;0.11971;9.81532;3
//! GYRO;0.013;9635.413;-0.00122;0.00244;0.00061;3
//! MAGN;0.015;9635.409;-2.04000;22.62000;-40.38000;3
//! PRES;0.020;9635.398;947.3125;0
//! TEMP;0.021;9635.400;24.5;0
//! AHRS;0.024;9635.416;0.000000;0.000000;-90.000000;0.00000000;0.00000000;-0.70710678;3
//! GNSS;0.512;1568967124.000;40.313541;-3.483176;651.200;45.000;8.0;1.2;12;9
//! POSI;0.600;1;40.31355012;-3.48318510;0;0
//! ```
//!
//! - `ACCE|GYRO|MAGN;AppTimestamp(s);SensorTimestamp(s);X;Y;Z[;Accuracy]`: m/s², rad/s,
//!   µT (`MAGN` is Android's OS-calibrated `TYPE_MAGNETIC_FIELD`). The header the app
//!   writes shows `Mag_X(uT);;Mag_Y(uT)`, but its format string has a single `;`.
//! - `PRES;AppTimestamp;SensorTimestamp;Pres(mbar)[;Accuracy]`: 1 mbar = 1 hPa.
//! - `TEMP;AppTimestamp;SensorTimestamp;temp(Celsius)[;Accuracy]`.
//! - `AHRS;AppTimestamp;SensorTimestamp;PitchX(deg);RollY(deg);YawZ(deg);RotVecX;
//!   RotVecY;RotVecZ[;Accuracy]`: Android's `TYPE_ROTATION_VECTOR`. The app's angles are
//!   `getOrientation` with azimuth and pitch negated (yaw counter-clockwise, east-north-
//!   up), so the attitude is computed from the rotation vector instead, exactly as for
//!   the Android dump.
//! - `GNSS;AppTimestamp;SensorTimeStamp;Latit(deg);Long(deg);Altitude(m);Bearing(deg);
//!   Accuracy(m);Speed(m/s);SatInView;SatInUse`, where SensorTimeStamp is the fix time in
//!   seconds since 1970 (`Location.getTime()`). Older logs lack SensorTimeStamp; a time
//!   since 1970 is never a latitude, so the third field tells the two layouts apart. The
//!   competitions' logs add `UTCTime(ms)` after Speed.
//! - `POSI;Timestamp(s);Counter;Latitude(deg);Longitude(deg);FloorID;BuildingID`: a
//!   ground-truth landmark on the app clock. The app itself writes 0, 0 when the user
//!   marks a position, and the competition fills in the coordinates, so 0, 0 is
//!   skipped.
//!
//! Other tags (`WIFI`, `BLUE`, `BLE4`, `LIGH`, `PROX`, `HUMI`, `SOUN`, `RFID`, `IMUX`,
//! `IMUL`, …) are counted once in the notes. There are two clocks: AppTimestamp, set by
//! the app as each event arrives (seconds since logging started, one clock for every
//! sensor), and SensorTimestamp, each sensor's own clock. AppTimestamp is `t_s`, so that
//! all streams share one timeline; the spread of SensorTimestamp − AppTimestamp per
//! sensor is reported in the notes.
//!
//! The log is dated (for the magnetic model) by the first fix's UTC time (UTCTime, else
//! SensorTimeStamp) minus its AppTimestamp, else by the header's `% Date of creation:`
//! (Java's `Date.toString()`, `Fri Sep 20 10:18:41 GMT+02:00 2019`).

use std::collections::BTreeMap;

use nalgebra::{Matrix3, Quaternion, Rotation3, UnitQuaternion, Vector2, Vector3};

use super::axes::PhoneMount;
use super::lines::decode_all;
use super::{
    ensure_text, shorten, Diagnostics, ImportError, ImportReport, MagUnit, SensorFrame,
    MAX_LINE_BYTES,
};
use crate::angle::wrap_to_2pi;
use crate::recording::{Attitude, GnssFix, Recording, Stream};

pub const ANDROID_DUMP: &str = "Android sensor dump";
pub const GET_SENSOR_DATA: &str = "GetSensorData log";

/// How many lines the format detectors look at.
const DETECTION_LINES: usize = 20;

/// Distinct ignored tags listed by name; past this they are only counted, so that a
/// file of garbage cannot grow the list without bound.
const MAX_IGNORED_NAMES: usize = 32;

/// How far past 1 the rotation vector's length may be before it is refused: the values
/// are single-precision, so a unit quaternion's vector part can exceed 1 by rounding.
const ROTATION_VECTOR_SLACK: f64 = 1e-3;

/// Tags that GetSensorData writes, for recognising its logs.
const GET_SENSOR_DATA_TAGS: [&str; 21] = [
    "ACCE", "GYRO", "MAGN", "PRES", "LIGH", "PROX", "HUMI", "TEMP", "AHRS", "GNSS", "WIFI", "BLUE",
    "BLE4", "SOUN", "RFID", "IMUX", "IMUL", "IMUI", "IM1P", "IM1X", "POSI",
];

/// Whether the first lines look like an Android sensor dump: a `#⇥startTime:` header
/// or a line `unix_ms<TAB>TYPE_…`.
pub fn looks_like_android_dump(sample_lines: &[&str]) -> bool {
    sample_lines.iter().take(DETECTION_LINES).any(|line| {
        let line = line.trim_start_matches('\u{feff}').trim();
        if let Some(header) = line.strip_prefix('#') {
            return header.trim_start().starts_with("startTime:");
        }
        let mut fields = line.split('\t').map(str::trim);
        match (fields.next(), fields.next()) {
            (Some(time), Some(kind)) => time.parse::<f64>().is_ok() && kind.starts_with("TYPE_"),
            _ => false,
        }
    })
}

/// Whether the first lines look like a GetSensorData log: its `%` header naming the
/// app, or a line starting with one of its tags and a number.
pub fn looks_like_get_sensor_data(sample_lines: &[&str]) -> bool {
    sample_lines.iter().take(DETECTION_LINES).any(|line| {
        let line = line.trim_start_matches('\u{feff}').trim();
        if let Some(comment) = line.strip_prefix('%') {
            return comment.contains("GetSensorData");
        }
        let mut fields = line.split(';').map(str::trim);
        match (fields.next(), fields.next()) {
            (Some(tag), Some(time)) => {
                GET_SENSOR_DATA_TAGS.contains(&tag) && time.parse::<f64>().is_ok()
            }
            _ => false,
        }
    })
}

/// Reads an Android sensor dump. Fails only when nothing can be read; every skipped
/// line becomes a diagnostic in the report.
pub fn read_android_dump(file_name: &str, bytes: &[u8]) -> Result<ImportReport, ImportError> {
    read_bytes(file_name, bytes, AndroidReader::default())
}

/// Reads a GetSensorData log. Fails only when nothing can be read; every skipped line
/// becomes a diagnostic in the report.
pub fn read_get_sensor_data(file_name: &str, bytes: &[u8]) -> Result<ImportReport, ImportError> {
    read_bytes(file_name, bytes, GetSensorDataReader::default())
}

/// A reader of one format, fed line by line, so that files and chunked input share it.
pub trait LineReader {
    fn read_line(&mut self, number: usize, text: &str, truncated: bool);
    fn finish(self, file_name: String) -> Result<ImportReport, ImportError>;
}

fn read_bytes(
    file_name: &str,
    bytes: &[u8],
    mut reader: impl LineReader,
) -> Result<ImportReport, ImportError> {
    ensure_text(file_name, bytes)?;
    let file_name = file_name.to_string();
    decode_all(bytes, MAX_LINE_BYTES, |line| {
        reader.read_line(line.number, &line.text, line.truncated)
    });
    reader.finish(file_name)
}

/// Which stream a sample went to, for finding the first line whose time goes backwards.
#[derive(Debug, Clone, Copy)]
enum Slot {
    Acc,
    Gyro,
    MagCalibrated,
    MagRaw,
    Rotation,
    Pressure,
    Temp,
    Gnss,
    RefEn,
    RefLatLon,
}

const N_SLOTS: usize = 10;

/// How file times become `t_s`: `t_s = (t_file − origin) · scale`.
struct Clock {
    origin: f64,
    scale: f64,
    /// What the notes say about the clock.
    note: String,
}

/// What both formats read, in device axes and on the file's own clock, until the mount
/// and the time origin are known at the end of the file.
#[derive(Default)]
struct Collector {
    acc_in_device_mps2: Stream<Vector3<f64>>,
    gyro_in_device_radps: Stream<Vector3<f64>>,
    mag_calibrated_in_device_ut: Stream<Vector3<f64>>,
    mag_raw_in_device_ut: Stream<Vector3<f64>>,
    mag_bias_in_device_ut: Stream<Vector3<f64>>,
    device_to_enu: Stream<UnitQuaternion<f64>>,
    pressure_hpa: Stream<f64>,
    temp_c: Stream<f64>,
    gnss: Stream<GnssFix>,
    ref_position_en_m: Stream<Vector2<f64>>,
    ref_position_lat_lon_deg: Stream<Vector2<f64>>,
    diagnostics: Diagnostics,
    n_lines: usize,
    n_data_lines: usize,
    /// Samples read per tag, for the notes.
    n_read: BTreeMap<&'static str, usize>,
    /// Lines of tags this tool does not use, per tag.
    ignored: BTreeMap<String, usize>,
    n_ignored_unnamed: usize,
    first_ignored_line: Option<usize>,
    last_t: [Option<f64>; N_SLOTS],
    first_backwards_line: Option<usize>,
    /// Notes that only one format knows about, added after the common ones.
    extra_notes: Vec<String>,
}

impl Collector {
    /// Counts a sample of `tag` and remembers the first line where its stream's time
    /// goes backwards.
    fn record(&mut self, slot: Slot, tag: &'static str, line: usize, t: f64) {
        *self.n_read.entry(tag).or_insert(0) += 1;
        if let Some(last_t) = self.last_t.get_mut(slot as usize) {
            if matches!(*last_t, Some(previous) if t < previous)
                && self.first_backwards_line.is_none()
            {
                self.first_backwards_line = Some(line);
            }
            *last_t = Some(t);
        }
    }

    fn ignore(&mut self, line: usize, tag: &str) {
        self.first_ignored_line.get_or_insert(line);
        let name = shorten(tag);
        if let Some(count) = self.ignored.get_mut(&name) {
            *count += 1;
        } else if self.ignored.len() < MAX_IGNORED_NAMES {
            self.ignored.insert(name, 1);
        } else {
            self.n_ignored_unnamed += 1;
        }
    }

    fn problem(&mut self, line: usize, message: impl Into<String>) {
        self.diagnostics.push(Some(line), message);
    }

    fn is_empty(&self) -> bool {
        self.acc_in_device_mps2.is_empty()
            && self.gyro_in_device_radps.is_empty()
            && self.mag_calibrated_in_device_ut.is_empty()
            && self.mag_raw_in_device_ut.is_empty()
            && self.device_to_enu.is_empty()
            && self.pressure_hpa.is_empty()
            && self.temp_c.is_empty()
            && self.gnss.is_empty()
            && self.ref_position_en_m.is_empty()
            && self.ref_position_lat_lon_deg.is_empty()
    }

    /// The earliest sample time of any stream, on the file's clock.
    fn earliest_t(&self) -> Option<f64> {
        [
            &self.acc_in_device_mps2.t_s,
            &self.gyro_in_device_radps.t_s,
            &self.mag_calibrated_in_device_ut.t_s,
            &self.mag_raw_in_device_ut.t_s,
            &self.device_to_enu.t_s,
            &self.pressure_hpa.t_s,
            &self.temp_c.t_s,
            &self.gnss.t_s,
            &self.ref_position_en_m.t_s,
            &self.ref_position_lat_lon_deg.t_s,
        ]
        .into_iter()
        .flatten()
        .copied()
        .reduce(f64::min)
    }

    fn nothing_recognised(&self, file_name: String, format: &'static str) -> ImportError {
        let first_problem = match (self.diagnostics.kept.first(), self.first_ignored_line) {
            (Some(diagnostic), _) => match diagnostic.line {
                Some(line) => format!(" (line {line}: {})", diagnostic.message),
                None => format!(" ({})", diagnostic.message),
            },
            (None, Some(line)) => format!(
                " (line {line}: only {} that this tool does not use)",
                self.ignored_summary()
            ),
            (None, None) => String::new(),
        };
        ImportError::NothingRecognised {
            file_name,
            format,
            n_lines: self.n_lines,
            first_problem,
        }
    }

    fn ignored_summary(&self) -> String {
        let mut parts: Vec<String> = self
            .ignored
            .iter()
            .map(|(tag, count)| format!("{tag} ×{count}"))
            .collect();
        if self.n_ignored_unnamed > 0 {
            parts.push(format!(
                "{} more lines of other tags",
                self.n_ignored_unnamed
            ));
        }
        parts.join(", ")
    }

    /// Converts to body axes and seconds, sorts, and writes the notes.
    fn finish(
        mut self,
        file_name: String,
        format: &'static str,
        clock: Clock,
    ) -> Result<ImportReport, ImportError> {
        if self.is_empty() {
            return Err(self.nothing_recognised(file_name, format));
        }
        let mut notes = Vec::new();
        if !self.n_read.is_empty() {
            let counts: Vec<String> = self
                .n_read
                .iter()
                .map(|(tag, count)| format!("{count} {tag}"))
                .collect();
            notes.push(format!("read {} samples", counts.join(", ")));
        }
        notes.push(clock.note.clone());
        let mount = detect_mount(&self.acc_in_device_mps2, &mut notes);

        let to_s = |t: f64| (t - clock.origin) * clock.scale;
        let to_body = |v: &Vector3<f64>| mount.device_to_body(*v);
        let mut recording = Recording {
            acc_in_body_mps2: convert(&self.acc_in_device_mps2, to_s, to_body),
            gyro_in_body_radps: convert(&self.gyro_in_device_radps, to_s, to_body),
            temp_c: convert(&self.temp_c, to_s, |v| *v),
            pressure_hpa: convert(&self.pressure_hpa, to_s, |v| *v),
            gnss: convert(&self.gnss, to_s, |v| *v),
            attitude: convert(&self.device_to_enu, to_s, |q| {
                attitude_from_rotation_vector(q, mount)
            }),
            ref_position_en_m: convert(&self.ref_position_en_m, to_s, |v| *v),
            ref_position_lat_lon_deg: convert(&self.ref_position_lat_lon_deg, to_s, |v| *v),
            ..Recording::default()
        };
        if !self.mag_raw_in_device_ut.is_empty() {
            recording.mag_in_body_ut = convert(&self.mag_raw_in_device_ut, to_s, to_body);
            recording.mag_bias_in_body_ut = convert(&self.mag_bias_in_device_ut, to_s, to_body);
            let unused = if self.mag_calibrated_in_device_ut.is_empty() {
                String::new()
            } else {
                format!(
                    "; the {} OS-calibrated samples were not used",
                    self.mag_calibrated_in_device_ut.len()
                )
            };
            notes.push(format!(
                "magnetometer: the raw (uncalibrated) field, with the OS's own hard-iron \
                 estimate kept as the device bias{unused}"
            ));
        } else if !self.mag_calibrated_in_device_ut.is_empty() {
            recording.mag_in_body_ut = convert(&self.mag_calibrated_in_device_ut, to_s, to_body);
            notes.push(
                "magnetometer: only the OS-calibrated field, from which the OS has already \
                 removed its hard-iron estimate, so a calibration fit should find little offset"
                    .to_string(),
            );
        }
        // Both formats write the field in µT (Android's `SensorEvent` unit), device axes.
        let mag_frame = (!recording.mag_in_body_ut.is_empty())
            .then(|| SensorFrame::android_device(mount, MagUnit::MICROTESLA));
        if !recording.attitude.is_empty() {
            notes.push(
                "attitude: from the rotation vector (device to east-north-up), converted to \
                 body to north-east-down with the same mount; yaw is clockwise from magnetic \
                 north"
                    .to_string(),
            );
        }
        if self.first_ignored_line.is_some() {
            notes.push(format!(
                "ignored (not used by this tool): {}",
                self.ignored_summary()
            ));
        }
        notes.append(&mut self.extra_notes);

        // The bias shares the magnetometer's times, so only the magnetometer is counted.
        let n_out_of_order = recording.acc_in_body_mps2.sort_by_time()
            + recording.gyro_in_body_radps.sort_by_time()
            + recording.mag_in_body_ut.sort_by_time()
            + recording.temp_c.sort_by_time()
            + recording.pressure_hpa.sort_by_time()
            + recording.gnss.sort_by_time()
            + recording.attitude.sort_by_time()
            + recording.ref_position_en_m.sort_by_time()
            + recording.ref_position_lat_lon_deg.sort_by_time();
        recording.mag_bias_in_body_ut.sort_by_time();
        if n_out_of_order > 0 {
            let line = self
                .first_backwards_line
                .map_or(String::new(), |line| format!(" (first at line {line})"));
            self.diagnostics.push(
                self.first_backwards_line,
                format!(
                    "time goes backwards {n_out_of_order} times within a sensor's samples{line}; \
                     the samples were sorted by time"
                ),
            );
        }

        Ok(ImportReport {
            file_name,
            format,
            recording,
            diagnostics: self.diagnostics,
            header: None,
            n_data_lines: self.n_data_lines,
            notes,
            mag_frame,
        })
    }
}

/// A stream with its times and values converted.
fn convert<T, U>(
    stream: &Stream<T>,
    to_s: impl Fn(f64) -> f64,
    value: impl Fn(&T) -> U,
) -> Stream<U> {
    Stream {
        t_s: stream.t_s.iter().map(|&t| to_s(t)).collect(),
        values: stream.values.iter().map(value).collect(),
    }
}

/// The mount from the mean specific force in device axes, Flat when undecided; the
/// choice and its mapping go into the notes.
fn detect_mount(acc_in_device_mps2: &Stream<Vector3<f64>>, notes: &mut Vec<String>) -> PhoneMount {
    let n = acc_in_device_mps2.len();
    if n == 0 {
        let mount = PhoneMount::Flat;
        notes.push(format!(
            "phone mount: no accelerometer samples to tell it from, so assumed {mount:?}: {}",
            mount.describe()
        ));
        return mount;
    }
    let mean = acc_in_device_mps2
        .values
        .iter()
        .fold(Vector3::zeros(), |sum, v| sum + v)
        / n as f64;
    let mean_text = format!("({:.2}, {:.2}, {:.2}) m/s²", mean.x, mean.y, mean.z);
    match PhoneMount::detect(mean) {
        Some(mount) => {
            notes.push(format!(
                "phone mount: {mount:?}, detected from the mean specific force {mean_text} in \
                 device axes: {}",
                mount.describe()
            ));
            mount
        }
        None => {
            let mount = PhoneMount::Flat;
            notes.push(format!(
                "phone mount: the mean specific force {mean_text} in device axes does not show \
                 which way is up (a phone on its side?), so assumed {mount:?}: {}",
                mount.describe()
            ));
            mount
        }
    }
}

/// Roll, pitch and yaw (clockwise from north) of the body frame, from Android's rotation
/// vector, which turns device axes into east-north-up.
///
/// A body vector goes to device axes through the transpose of the mount's proper
/// rotation, to east-north-up through the rotation vector, and to north-east-down by
/// swapping east and north and negating up: `C_ned_body = P · R · Mᵀ`.
fn attitude_from_rotation_vector(
    device_to_enu: &UnitQuaternion<f64>,
    mount: PhoneMount,
) -> Attitude {
    let body_from_device = mount.body_from_device();
    let ned_from_enu = Matrix3::new(0.0, 1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, -1.0);
    let ned_from_body =
        ned_from_enu * device_to_enu.to_rotation_matrix().matrix() * body_from_device.transpose();
    let (roll_rad, pitch_rad, yaw_rad) =
        Rotation3::from_matrix_unchecked(ned_from_body).euler_angles();
    Attitude {
        roll_rad,
        pitch_rad,
        yaw_rad: Some(wrap_to_2pi(yaw_rad)),
    }
}

/// The unit quaternion whose vector part is `(x, y, z)`, with w ≥ 0.
fn quaternion_from_rotation_vector(x: f64, y: f64, z: f64) -> Result<UnitQuaternion<f64>, String> {
    let norm_squared = x * x + y * y + z * z;
    if norm_squared > (1.0 + ROTATION_VECTOR_SLACK).powi(2) {
        return Err(format!(
            "the rotation vector's length is {:.4}, more than 1, so it is not part of a unit \
             quaternion",
            norm_squared.sqrt()
        ));
    }
    let w = (1.0 - norm_squared).max(0.0).sqrt();
    Ok(UnitQuaternion::from_quaternion(Quaternion::new(w, x, y, z)))
}

/// One field as a finite number; `name` says which field in a message.
fn finite(field: Option<&&str>, name: &str) -> Result<f64, String> {
    let Some(field) = field else {
        return Err(format!("{name} is missing"));
    };
    match field.parse::<f64>() {
        Ok(value) if value.is_finite() => Ok(value),
        Ok(_) => Err(format!("{name} is {field}")),
        Err(_) => Err(format!("{name} is not a number ({})", shorten(field))),
    }
}

/// Three consecutive fields, from `first`, as a vector.
fn vector3(fields: &[&str], first: usize, names: [&str; 3]) -> Result<Vector3<f64>, String> {
    Ok(Vector3::new(
        finite(fields.get(first), names[0])?,
        finite(fields.get(first + 1), names[1])?,
        finite(fields.get(first + 2), names[2])?,
    ))
}

/// Refuses a field count outside `min..=max`, saying what the line should hold.
fn check_count(
    found: usize,
    min: usize,
    max: usize,
    what: &str,
    layout: &str,
) -> Result<(), String> {
    if (min..=max).contains(&found) {
        return Ok(());
    }
    let expected = if min == max {
        format!("{min}")
    } else if max == min + 1 {
        format!("{min} or {max}")
    } else {
        format!("{min} to {max}")
    };
    Err(format!(
        "{expected} {what} expected ({layout}), found {found}"
    ))
}

/// Splits on `separator`, trimming fields and dropping empty trailing ones (a line may
/// end with the separator).
fn split_fields(text: &str, separator: char) -> Vec<&str> {
    let mut fields: Vec<&str> = text.split(separator).map(str::trim).collect();
    while fields.last().is_some_and(|field| field.is_empty()) {
        fields.pop();
    }
    fields
}

// ---------------------------------------------------------------------------------
// Android sensor dump

#[derive(Default)]
pub struct AndroidReader {
    collector: Collector,
    start_time_ms: Option<f64>,
}

impl LineReader for AndroidReader {
    fn read_line(&mut self, number: usize, text: &str, truncated: bool) {
        self.collector.n_lines = self.collector.n_lines.max(number);
        let trimmed = text.trim_start_matches('\u{feff}').trim();
        if trimmed.is_empty() {
            return;
        }
        if let Some(header) = trimmed.strip_prefix('#') {
            self.read_header(number, header);
            return;
        }
        self.collector.n_data_lines += 1;
        if truncated {
            self.collector.problem(
                number,
                format!("line longer than {MAX_LINE_BYTES} bytes; skipped, as its end is missing"),
            );
            return;
        }
        // Tabs separate the fields; a copy whose tabs became spaces is still read.
        let fields = if trimmed.contains('\t') {
            split_fields(trimmed, '\t')
        } else {
            trimmed.split_whitespace().collect()
        };
        if let Err(message) = self.read_fields(number, &fields) {
            self.collector.problem(number, message);
        }
    }

    fn finish(self, file_name: String) -> Result<ImportReport, ImportError> {
        let clock = match (self.start_time_ms, self.collector.earliest_t()) {
            (Some(start_ms), _) => Clock {
                origin: start_ms,
                scale: 1e-3,
                note: format!(
                    "time: t_s = (unix_ms − {start_ms:.0}) / 1000, from the startTime header"
                ),
            },
            (None, Some(first_ms)) => Clock {
                origin: first_ms,
                scale: 1e-3,
                note: format!(
                    "time: t_s = (unix_ms − {first_ms:.0}) / 1000, from the earliest sample \
                     (there is no startTime header)"
                ),
            },
            (None, None) => Clock {
                origin: 0.0,
                scale: 1e-3,
                note: String::new(),
            },
        };
        let start_unix_s = (clock.origin != 0.0).then_some(clock.origin * clock.scale);
        let mut report = self.collector.finish(file_name, ANDROID_DUMP, clock)?;
        report.recording.start_unix_s = start_unix_s;
        Ok(report)
    }
}

impl AndroidReader {
    fn read_header(&mut self, number: usize, header: &str) {
        let Some(start) = header
            .split('\t')
            .map(str::trim)
            .find_map(|field| field.strip_prefix("startTime:"))
        else {
            return;
        };
        if self.start_time_ms.is_some() {
            return;
        }
        match number_of(start, "startTime") {
            Ok(start_ms) => self.start_time_ms = Some(start_ms),
            Err(message) => self.collector.problem(
                number,
                format!("{message}; times count from the earliest sample instead"),
            ),
        }
    }

    fn read_fields(&mut self, number: usize, fields: &[&str]) -> Result<(), String> {
        let (Some(time), Some(kind)) = (fields.first(), fields.get(1)) else {
            return Err(format!(
                "expected unix_ms<TAB>TYPE<TAB>values, found only {:?}",
                shorten(fields.first().copied().unwrap_or_default())
            ));
        };
        let t_ms = finite(Some(time), "the time (unix_ms)")?;
        let values = fields.get(2..).unwrap_or_default();
        let c = &mut self.collector;
        let in_type = |message: String| format!("{kind}: {message}");
        match *kind {
            "TYPE_ACCELEROMETER" => {
                check_count(values.len(), 3, 4, "values", "x y z [accuracy]").map_err(in_type)?;
                let acc = vector3(values, 0, ["x", "y", "z"]).map_err(in_type)?;
                c.record(Slot::Acc, "TYPE_ACCELEROMETER", number, t_ms);
                c.acc_in_device_mps2.push(t_ms, acc);
            }
            "TYPE_GYROSCOPE" => {
                check_count(values.len(), 3, 4, "values", "x y z [accuracy]").map_err(in_type)?;
                let gyro = vector3(values, 0, ["x", "y", "z"]).map_err(in_type)?;
                c.record(Slot::Gyro, "TYPE_GYROSCOPE", number, t_ms);
                c.gyro_in_device_radps.push(t_ms, gyro);
            }
            "TYPE_MAGNETIC_FIELD" => {
                check_count(values.len(), 3, 4, "values", "x y z [accuracy]").map_err(in_type)?;
                let mag = vector3(values, 0, ["x", "y", "z"]).map_err(in_type)?;
                c.record(Slot::MagCalibrated, "TYPE_MAGNETIC_FIELD", number, t_ms);
                c.mag_calibrated_in_device_ut.push(t_ms, mag);
            }
            "TYPE_MAGNETIC_FIELD_UNCALIBRATED" => {
                check_count(values.len(), 6, 7, "values", "mx my mz bx by bz [accuracy]")
                    .map_err(in_type)?;
                let raw = vector3(values, 0, ["mx", "my", "mz"]).map_err(in_type)?;
                let bias = vector3(values, 3, ["bx", "by", "bz"]).map_err(in_type)?;
                c.record(
                    Slot::MagRaw,
                    "TYPE_MAGNETIC_FIELD_UNCALIBRATED",
                    number,
                    t_ms,
                );
                c.mag_raw_in_device_ut.push(t_ms, raw);
                c.mag_bias_in_device_ut.push(t_ms, bias);
            }
            "TYPE_ROTATION_VECTOR" => {
                check_count(
                    values.len(),
                    3,
                    5,
                    "values",
                    "x y z [accuracy or w [accuracy]]",
                )
                .map_err(in_type)?;
                let v = vector3(values, 0, ["x", "y", "z"]).map_err(in_type)?;
                let q = quaternion_from_rotation_vector(v.x, v.y, v.z).map_err(in_type)?;
                c.record(Slot::Rotation, "TYPE_ROTATION_VECTOR", number, t_ms);
                c.device_to_enu.push(t_ms, q);
            }
            "TYPE_WAYPOINT" => {
                check_count(values.len(), 2, 2, "values", "x y").map_err(in_type)?;
                let east_m = finite(values.first(), "x").map_err(in_type)?;
                let north_m = finite(values.get(1), "y").map_err(in_type)?;
                c.record(Slot::RefEn, "TYPE_WAYPOINT", number, t_ms);
                c.ref_position_en_m
                    .push(t_ms, Vector2::new(east_m, north_m));
            }
            other => c.ignore(number, other),
        }
        Ok(())
    }
}

/// A bare string as a finite number (for header values).
fn number_of(text: &str, name: &str) -> Result<f64, String> {
    finite(Some(&text), name)
}

// ---------------------------------------------------------------------------------
// GetSensorData

#[derive(Default)]
pub struct GetSensorDataReader {
    collector: Collector,
    /// Per tag, the smallest and largest SensorTimestamp − AppTimestamp.
    clock_offsets_s: BTreeMap<&'static str, (f64, f64)>,
    /// The first GNSS fix with a UTC time: (AppTimestamp, UTC seconds since 1970, where
    /// the UTC time came from).
    first_fix_utc: Option<(f64, f64, &'static str)>,
    /// The header's `% Date of creation:` in seconds since 1970, and whether its zone
    /// was understood.
    creation_unix_s: Option<(f64, bool)>,
}

impl LineReader for GetSensorDataReader {
    fn read_line(&mut self, number: usize, text: &str, truncated: bool) {
        self.collector.n_lines = self.collector.n_lines.max(number);
        let trimmed = text.trim_start_matches('\u{feff}').trim();
        if let Some(comment) = trimmed.strip_prefix('%') {
            if let Some(date) = comment.trim().strip_prefix("Date of creation:") {
                if self.creation_unix_s.is_none() {
                    self.creation_unix_s = java_date_unix_s(date.trim());
                }
            }
            return;
        }
        if trimmed.is_empty() {
            return;
        }
        self.collector.n_data_lines += 1;
        if truncated {
            self.collector.problem(
                number,
                format!("line longer than {MAX_LINE_BYTES} bytes; skipped, as its end is missing"),
            );
            return;
        }
        let fields = split_fields(trimmed, ';');
        if let Err(message) = self.read_fields(number, &fields) {
            self.collector.problem(number, message);
        }
    }

    fn finish(mut self, file_name: String) -> Result<ImportReport, ImportError> {
        if !self.clock_offsets_s.is_empty() {
            let spreads: Vec<String> = self
                .clock_offsets_s
                .iter()
                .map(|(tag, (min_s, max_s))| {
                    format!(
                        "{tag} {min_s:.3} to {max_s:.3} s (spread {:.0} ms)",
                        (max_s - min_s) * 1e3
                    )
                })
                .collect();
            self.collector.extra_notes.push(format!(
                "SensorTimestamp − AppTimestamp per sensor: {}",
                spreads.join("; ")
            ));
        }
        let clock = Clock {
            origin: 0.0,
            scale: 1.0,
            note: "time: t_s = AppTimestamp, the app's clock shared by all sensors (seconds \
                   since logging started); the sensors' own SensorTimestamp clocks are not used"
                .to_string(),
        };
        // The start in UTC: a fix's UTC time minus its AppTimestamp, else the header's
        // date of creation.
        let start_unix_s = match (self.first_fix_utc, self.creation_unix_s) {
            (Some((app_s, utc_s, source)), _) => {
                self.collector.extra_notes.push(format!(
                    "dated by the GNSS fixes' UTC time ({source} − AppTimestamp of the first \
                     fix): logging started {} s after 1970",
                    (utc_s - app_s).round()
                ));
                Some(utc_s - app_s)
            }
            (None, Some((creation_s, zone_known))) => {
                self.collector.extra_notes.push(format!(
                    "dated by the header's date of creation ({} s after 1970{}); no GNSS fix \
                     gives a UTC time",
                    creation_s.round(),
                    if zone_known {
                        ""
                    } else {
                        ", its time zone taken as UTC"
                    }
                ));
                Some(creation_s)
            }
            (None, None) => None,
        };
        let mut report = self.collector.finish(file_name, GET_SENSOR_DATA, clock)?;
        report.recording.start_unix_s = start_unix_s;
        Ok(report)
    }
}

impl GetSensorDataReader {
    fn read_fields(&mut self, number: usize, fields: &[&str]) -> Result<(), String> {
        let tag = fields.first().copied().unwrap_or_default();
        if !is_tag(tag) {
            return Err(format!(
                "not a GetSensorData line: it should start with a tag such as ACCE; (found {:?})",
                shorten(tag)
            ));
        }
        let in_tag = |message: String| format!("{tag}: {message}");
        let n_values = fields.len().saturating_sub(1);
        match tag {
            "ACCE" => self
                .read_vector(number, fields, "ACCE", Slot::Acc, "Acc")
                .map_err(in_tag),
            "GYRO" => self
                .read_vector(number, fields, "GYRO", Slot::Gyro, "Gyr")
                .map_err(in_tag),
            "MAGN" => self
                .read_vector(number, fields, "MAGN", Slot::MagCalibrated, "Mag")
                .map_err(in_tag),
            "PRES" => {
                check_count(
                    n_values,
                    3,
                    4,
                    "fields after the tag",
                    "AppTimestamp;SensorTimestamp;Pres(mbar)[;Accuracy]",
                )
                .map_err(in_tag)?;
                let (t, pressure) = self.read_scalar(fields, "PRES", "Pres").map_err(in_tag)?;
                let c = &mut self.collector;
                c.record(Slot::Pressure, "PRES", number, t);
                c.pressure_hpa.push(t, pressure);
                Ok(())
            }
            "TEMP" => {
                check_count(
                    n_values,
                    3,
                    4,
                    "fields after the tag",
                    "AppTimestamp;SensorTimestamp;temp(Celsius)[;Accuracy]",
                )
                .map_err(in_tag)?;
                let (t, temp_c) = self.read_scalar(fields, "TEMP", "temp").map_err(in_tag)?;
                let c = &mut self.collector;
                c.record(Slot::Temp, "TEMP", number, t);
                c.temp_c.push(t, temp_c);
                Ok(())
            }
            "AHRS" => self.read_ahrs(number, fields).map_err(in_tag),
            "GNSS" => self.read_gnss(number, fields).map_err(in_tag),
            "POSI" => self.read_posi(number, fields).map_err(in_tag),
            other => {
                self.collector.ignore(number, other);
                Ok(())
            }
        }
    }

    /// AppTimestamp, and SensorTimestamp − AppTimestamp kept for the notes.
    fn read_times(&mut self, fields: &[&str], tag: &'static str) -> Result<f64, String> {
        let app_s = finite(fields.get(1), "AppTimestamp")?;
        let sensor_s = finite(fields.get(2), "SensorTimestamp")?;
        let offset_s = sensor_s - app_s;
        let range = self
            .clock_offsets_s
            .entry(tag)
            .or_insert((offset_s, offset_s));
        range.0 = range.0.min(offset_s);
        range.1 = range.1.max(offset_s);
        Ok(app_s)
    }

    fn read_vector(
        &mut self,
        number: usize,
        fields: &[&str],
        tag: &'static str,
        slot: Slot,
        name: &str,
    ) -> Result<(), String> {
        let unit = match slot {
            Slot::Acc => "m/s^2",
            Slot::Gyro => "rad/s",
            _ => "uT",
        };
        check_count(
            fields.len().saturating_sub(1),
            5,
            6,
            "fields after the tag",
            &format!("AppTimestamp;SensorTimestamp;{name}_X({unit});{name}_Y;{name}_Z[;Accuracy]"),
        )?;
        let names = ["X", "Y", "Z"].map(|axis| format!("{name}_{axis}"));
        let v = vector3(
            fields,
            3,
            [&names[0], &names[1], &names[2]].map(String::as_str),
        )?;
        let t = self.read_times(fields, tag)?;
        let c = &mut self.collector;
        c.record(slot, tag, number, t);
        match slot {
            Slot::Acc => c.acc_in_device_mps2.push(t, v),
            Slot::Gyro => c.gyro_in_device_radps.push(t, v),
            _ => c.mag_calibrated_in_device_ut.push(t, v),
        }
        Ok(())
    }

    fn read_scalar(
        &mut self,
        fields: &[&str],
        tag: &'static str,
        name: &str,
    ) -> Result<(f64, f64), String> {
        let value = finite(fields.get(3), name)?;
        let t = self.read_times(fields, tag)?;
        Ok((t, value))
    }

    fn read_ahrs(&mut self, number: usize, fields: &[&str]) -> Result<(), String> {
        check_count(
            fields.len().saturating_sub(1),
            8,
            9,
            "fields after the tag",
            "AppTimestamp;SensorTimestamp;PitchX;RollY;YawZ;RotVecX;RotVecY;RotVecZ[;Accuracy]",
        )?;
        let v = vector3(fields, 6, ["RotVecX", "RotVecY", "RotVecZ"])?;
        let q = quaternion_from_rotation_vector(v.x, v.y, v.z)?;
        let t = self.read_times(fields, "AHRS")?;
        let c = &mut self.collector;
        c.record(Slot::Rotation, "AHRS", number, t);
        c.device_to_enu.push(t, q);
        Ok(())
    }

    fn read_gnss(&mut self, number: usize, fields: &[&str]) -> Result<(), String> {
        let t = number_at(fields, 1, "AppTimestamp")?;
        let third = number_at(fields, 2, "the third field")?;
        // The current app writes the fix time (seconds since 1970) before the latitude,
        // older versions do not; such a time is never within ±90, a latitude always is.
        let lat_idx = if third.abs() > 90.0 { 3 } else { 2 };
        let n_needed = lat_idx + 6;
        if fields.len() < n_needed {
            return Err(format!(
                "{} fields after the tag expected \
                 (AppTimestamp;[SensorTimeStamp;]Latit;Long;Altitude;Bearing;Accuracy;Speed;…), \
                 found {}",
                n_needed - 1,
                fields.len().saturating_sub(1)
            ));
        }
        let lat_deg = number_at(fields, lat_idx, "Latit")?;
        let lon_deg = number_at(fields, lat_idx + 1, "Long")?;
        check_lat_lon(lat_deg, lon_deg)?;
        // The fix's UTC time: UTCTime(ms) after Speed (the competitions' layout), else
        // SensorTimeStamp, the app's `Location.getTime()` in seconds.
        let utc_ms = fields
            .get(lat_idx + 6)
            .and_then(|field| field.parse::<f64>().ok())
            .filter(|ms| ms.is_finite() && *ms > 1e11);
        let utc = match utc_ms {
            Some(ms) => Some((ms * 1e-3, "UTCTime")),
            None => (lat_idx == 3 && third > 1e8 && third.is_finite())
                .then_some((third, "SensorTimeStamp")),
        };
        if let (None, Some((utc_s, source))) = (self.first_fix_utc, utc) {
            self.first_fix_utc = Some((t, utc_s, source));
        }
        let alt_m = number_at(fields, lat_idx + 2, "Altitude")?;
        let bearing_deg = number_at(fields, lat_idx + 3, "Bearing")?;
        let accuracy_m = number_at(fields, lat_idx + 4, "Accuracy")?;
        let speed_mps = number_at(fields, lat_idx + 5, "Speed")?;
        // Android reports 0 for an accuracy or bearing it does not have; a course of
        // exactly 0 while standing still is that, not north.
        let fix = GnssFix {
            lat_deg: Some(lat_deg),
            lon_deg: Some(lon_deg),
            alt_m: Some(alt_m),
            speed_mps: Some(speed_mps),
            course_rad: (bearing_deg != 0.0 || speed_mps != 0.0)
                .then(|| wrap_to_2pi(bearing_deg.to_radians())),
            hacc_m: (accuracy_m > 0.0).then_some(accuracy_m),
        };
        let c = &mut self.collector;
        c.record(Slot::Gnss, "GNSS", number, t);
        c.gnss.push(t, fix);
        Ok(())
    }

    fn read_posi(&mut self, number: usize, fields: &[&str]) -> Result<(), String> {
        check_count(
            fields.len().saturating_sub(1),
            4,
            6,
            "fields after the tag",
            "Timestamp;Counter;Latitude;Longitude[;FloorID;BuildingID]",
        )?;
        let t = number_at(fields, 1, "Timestamp")?;
        let lat_deg = number_at(fields, 3, "Latitude")?;
        let lon_deg = number_at(fields, 4, "Longitude")?;
        if lat_deg == 0.0 && lon_deg == 0.0 {
            return Err(
                "a position mark without coordinates (0, 0), as the app writes before the \
                 ground truth is filled in; skipped"
                    .to_string(),
            );
        }
        check_lat_lon(lat_deg, lon_deg)?;
        let c = &mut self.collector;
        c.record(Slot::RefLatLon, "POSI", number, t);
        c.ref_position_lat_lon_deg
            .push(t, Vector2::new(lat_deg, lon_deg));
        Ok(())
    }
}

fn number_at(fields: &[&str], idx: usize, name: &str) -> Result<f64, String> {
    finite(fields.get(idx), name)
}

fn check_lat_lon(lat_deg: f64, lon_deg: f64) -> Result<(), String> {
    if lat_deg.abs() > 90.0 || lon_deg.abs() > 180.0 {
        return Err(format!(
            "latitude {lat_deg} or longitude {lon_deg} is out of range"
        ));
    }
    Ok(())
}

/// Seconds since 1970 of a Java `Date.toString()`, `Fri Sep 20 10:18:41 GMT+02:00 2019`
/// (the GetSensorData header's date of creation), and whether its zone was understood
/// (`GMT`, `UTC`, `GMT±hh:mm`); another zone name is taken as UTC, hours off at most,
/// which does not matter for the magnetic model's date.
fn java_date_unix_s(text: &str) -> Option<(f64, bool)> {
    let parts: Vec<&str> = text.split_whitespace().collect();
    let [_, month, day, clock, zone, year] = parts.as_slice() else {
        return None;
    };
    const MONTHS: [&str; 12] = [
        "Jan", "Feb", "Mar", "Apr", "May", "Jun", "Jul", "Aug", "Sep", "Oct", "Nov", "Dec",
    ];
    let month = MONTHS.iter().position(|name| name == month)? as u32 + 1;
    let day: u32 = day.parse().ok().filter(|day| (1..=31).contains(day))?;
    let year: i64 = year.parse().ok()?;
    let mut clock_parts = clock.split(':').map(|part| part.parse::<f64>().ok());
    let (Some(Some(hours)), Some(Some(minutes)), Some(Some(seconds))) =
        (clock_parts.next(), clock_parts.next(), clock_parts.next())
    else {
        return None;
    };
    let offset_s = match zone
        .strip_prefix("GMT")
        .or_else(|| zone.strip_prefix("UTC"))
    {
        Some("") => Some(0.0),
        Some(offset) => {
            let sign = if offset.starts_with('-') { -1.0 } else { 1.0 };
            let (h, m) = offset
                .get(1..)?
                .split_once(':')
                .unwrap_or((offset.get(1..)?, "0"));
            Some(sign * (h.parse::<f64>().ok()? * 3600.0 + m.parse::<f64>().ok()? * 60.0))
        }
        None => None,
    };
    let days = crate::civil::days_from_civil(year, month, day) as f64;
    let local_s = days * 86_400.0 + hours * 3600.0 + minutes * 60.0 + seconds;
    Some((local_s - offset_s.unwrap_or(0.0), offset_s.is_some()))
}

/// A GetSensorData tag: a few capitals or digits, starting with a capital.
fn is_tag(text: &str) -> bool {
    (2..=8).contains(&text.len())
        && text.starts_with(|c: char| c.is_ascii_uppercase())
        && text
            .chars()
            .all(|c| c.is_ascii_uppercase() || c.is_ascii_digit())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::lines::LineDecoder;

    const ANDROID_SAMPLE: &str = "#\tstartTime:1574562661929\n\
#\tSiteID:5dd3d7732a57a34356595932\tFloorName:F1\n\
#\tBrand:OPPO\tModel:PBCM10\tAndroidName:8.1.0\tAPILevel:27\t\n\
1574562661934\tTYPE_DIST1\t6.5834045\t-20.037842\t-10.961151\n\
1574562661937\tTYPE_WAYPOINT\t197.70462\t82.66885\n\
1574562662058\tTYPE_ACCELEROMETER\t-1.6145935\t-0.5860138\t10.276016\t2\n\
1574562662058\tTYPE_MAGNETIC_FIELD\t34.79004\t2.0629883\t-30.970764\t3\n\
1574562662058\tTYPE_GYROSCOPE\t0.759079\t0.22821045\t-0.5694275\t3\n\
1574562662058\tTYPE_ROTATION_VECTOR\t-0.059935603\t-0.032342788\t0.7208543\t3\n\
1574562662058\tTYPE_MAGNETIC_FIELD_UNCALIBRATED\t-21.505737\t-88.80005\t-332.47528\t-56.295776\t-90.86304\t-301.50452\t3\n\
1574562662058\tTYPE_GYROSCOPE_UNCALIBRATED\t0.7575226\t0.22758484\t-0.5695648\t-0.0015563965\t-6.2561035E-4\t-1.373291E-4\t3\n\
1574562662058\tTYPE_ACCELEROMETER_UNCALIBRATED\t-1.1854248\t-0.9481354\t10.3598175\t0.0\t0.0\t0.0\t3\n\
1574562662078\tTYPE_ACCELEROMETER\t-1.1279755\t-0.15145874\t10.395737\t2\n\
1574562662451\tTYPE_WIFI\tintime_free\t0e:74:9c:2e:98:9f\t-41\t5825\t1574562661435\n\
1574562662451\tTYPE_WIFI\tintime_lease\t12:74:9c:2e:98:9f\t-41\t5825\t1574562661435\n\
1574562662564\tTYPE_BLUE\tSMG\t03:2F:22:41:3E:13\t-100\n\
#\tendTime:1574562776515\n";

    /// A GetSensorData log written from the app's own format strings: a phone lying
    /// flat, top edge pointing east, every tag once or twice.
    const GET_SENSOR_DATA_SAMPLE: &str = "% LogFile created by the 'GetSensorData' App for Android.\n\
% Date of creation: Fri Sep 20 10:12:03 GMT+02:00 2019\n\
% Version 2.1 January 2018\n\
% LogFile Data format:\n\
% Accelerometer data: \t'ACCE;AppTimestamp(s);SensorTimestamp(s);Acc_X(m/s^2);Acc_Y(m/s^2);Acc_Z(m/s^2);Accuracy(integer)'\n\
% POSI Reference:    \t\t'POSI;Timestamp(s);Counter;Latitude(degrees); Longitude(degrees);floor ID(0,1,2..4);Building ID(0,1,2..3);'\n\
% \n\
\n\
ACCE;0.012;9635.412;0.07184;0.11971;9.81532;3\n\
GYRO;0.013;9635.413;-0.00122;0.00244;0.00061;3\n\
MAGN;0.015;9635.409;-2.04000;22.62000;-40.38000;3\n\
PRES;0.020;9635.398;947.3125;0\n\
TEMP;0.021;9635.400;24.5;0\n\
AHRS;0.024;9635.416;0.000000;0.000000;-90.000000;0.00000000;0.00000000;-0.70710678;3\n\
ACCE;0.032;9635.432;0.06945;0.12210;9.80814;3\n\
WIFI;0.405;9634.100;eduroam;00:0b:86:27:36:c1;2412;-67\n\
BLE4;0.410;iBeacon;D9:1B:36:39:C3:7F;-83;-74;18479;42247;b9407f30-f5f8-466e-aff9-25556b57fe6d\n\
LIGH;0.420;9635.818;112.0;0\n\
PROX;0.430;9635.829;5.0;0\n\
HUMI;0.440;9635.838;40.5;0\n\
SOUN;0.450;0.0123;0.0008;32.1\n\
RFID;0.460;1;3457;-61;-63\n\
BLUE;0.470;JBL Flip;00:1A:7D:DA:71:13;-79\n\
GNSS;0.512;1568967124.000;40.313541;-3.483176;651.200;45.000;8.0;1.2;12;9\n\
POSI;0.600;1;40.31355012;-3.48318510;0;0\n";

    fn android(text: &str) -> Result<ImportReport, ImportError> {
        read_android_dump("walk.txt", text.as_bytes())
    }

    fn gsd(text: &str) -> Result<ImportReport, ImportError> {
        read_get_sensor_data("logfile.txt", text.as_bytes())
    }

    fn assert_close(got: f64, expect: f64, tolerance: f64, what: &str) {
        assert!(
            (got - expect).abs() <= tolerance,
            "{what}: got {got}, expected {expect} ± {tolerance}"
        );
    }

    fn assert_vector_close(got: Vector3<f64>, expect: Vector3<f64>, what: &str) {
        assert!(
            (got - expect).norm() < 1e-9,
            "{what}: got {got:?}, expected {expect:?}"
        );
    }

    fn yaw_deg(attitude: &Attitude) -> f64 {
        attitude.yaw_rad.unwrap_or(f64::NAN).to_degrees()
    }

    #[test]
    fn the_magnetometer_frame_is_android_device_axes_in_microtesla_with_the_mount() {
        let dump = "1000\tTYPE_ACCELEROMETER\t0.1\t9.8\t0.2\t3\n\
                    1000\tTYPE_MAGNETIC_FIELD\t10\t-20\t30\t3\n";
        let report = read_android_dump("dump.txt", dump.as_bytes()).expect("readable");
        let frame = report.mag_frame.expect("a magnetometer frame");
        assert_eq!(
            frame,
            SensorFrame::android_device(PhoneMount::Upright, MagUnit::MICROTESLA)
        );
        assert_eq!(
            frame.body_from_sensor * Vector3::new(10.0, -20.0, 30.0),
            report.recording.mag_in_body_ut.values[0]
        );
        let gsd = "ACCE;0.01;1.0;0.0;0.1;9.8;3\nMAGN;0.02;1.0;-2.0;22.6;-40.4;3\n";
        let report = read_get_sensor_data("gsd.txt", gsd.as_bytes()).expect("readable");
        assert_eq!(
            report.mag_frame,
            Some(SensorFrame::android_device(
                PhoneMount::Flat,
                MagUnit::MICROTESLA
            ))
        );
        let no_mag = "ACCE;0.01;1.0;0.0;0.1;9.8;3\n";
        let report = read_get_sensor_data("gsd.txt", no_mag.as_bytes()).expect("readable");
        assert_eq!(report.mag_frame, None);
    }

    #[test]
    fn android_golden_lines_of_every_type() {
        let report = android(ANDROID_SAMPLE).expect("readable");
        assert!(report.diagnostics.is_empty(), "{:?}", report.diagnostics);
        assert_eq!(report.format, ANDROID_DUMP);
        assert_eq!(report.header, None);
        assert_eq!(report.n_data_lines, 13);
        let r = &report.recording;

        // Times count from the startTime header, in seconds.
        assert_eq!(r.acc_in_body_mps2.len(), 2);
        assert_close(
            r.acc_in_body_mps2.t_s[0],
            0.129,
            1e-9,
            "first accelerometer time",
        );
        assert_close(
            r.acc_in_body_mps2.t_s[1],
            0.149,
            1e-9,
            "second accelerometer time",
        );
        // Flat mount: body = (device y, device x, −device z).
        assert_vector_close(
            r.acc_in_body_mps2.values[0],
            Vector3::new(-0.5860138, -1.6145935, -10.276016),
            "accelerometer",
        );
        assert_vector_close(
            r.gyro_in_body_radps.values[0],
            Vector3::new(0.22821045, 0.759079, 0.5694275),
            "gyroscope",
        );
        // The raw field wins over the OS-calibrated one; the bias comes along.
        assert_eq!(r.mag_in_body_ut.len(), 1);
        assert_vector_close(
            r.mag_in_body_ut.values[0],
            Vector3::new(-88.80005, -21.505737, 332.47528),
            "raw field",
        );
        assert_vector_close(
            r.mag_bias_in_body_ut.values[0],
            Vector3::new(-90.86304, -56.295776, 301.50452),
            "OS bias",
        );
        assert_eq!(r.mag_bias_in_body_ut.t_s, r.mag_in_body_ut.t_s);
        // Raw − bias is the OS-calibrated field of the same instant, in body axes.
        let calibrated = r.mag_in_body_ut.values[0] - r.mag_bias_in_body_ut.values[0];
        let os_calibrated =
            PhoneMount::Flat.device_to_body(Vector3::new(34.79004, 2.0629883, -30.970764));
        assert!((calibrated - os_calibrated).norm() < 1e-4, "{calibrated:?}");

        assert_eq!(r.attitude.len(), 1);
        let attitude = r.attitude.values[0];
        assert!(attitude.roll_rad.is_finite() && attitude.pitch_rad.is_finite());
        // The vector part (−0.060, −0.032, 0.721) turns the top edge about 92° counter-
        // clockwise from north: west-north-west, a heading of about 268°.
        assert_close(yaw_deg(&attitude), 267.8, 1.0, "yaw");

        assert_eq!(
            r.ref_position_en_m.values,
            vec![Vector2::new(197.70462, 82.66885)]
        );
        assert_close(r.ref_position_en_m.t_s[0], 0.008, 1e-9, "waypoint time");

        let notes = report.notes.join("\n");
        assert!(notes.contains("from the startTime header"), "{notes}");
        assert!(notes.contains(PhoneMount::Flat.describe()), "{notes}");
        assert!(notes.contains("detected"), "{notes}");
        assert!(notes.contains("TYPE_WIFI ×2"), "{notes}");
        assert!(
            notes.contains("TYPE_ACCELEROMETER_UNCALIBRATED ×1"),
            "{notes}"
        );
        assert!(
            notes.contains("1 OS-calibrated samples were not used"),
            "{notes}"
        );
    }

    fn flat_phone_line(yaw_vector_z: f64) -> String {
        format!(
            "1000\tTYPE_ACCELEROMETER\t0.0\t0.0\t9.81\t3\n1000\tTYPE_ROTATION_VECTOR\t0.0\t0.0\t{yaw_vector_z}\t3\n"
        )
    }

    #[test]
    fn a_flat_phone_pointing_north_has_yaw_0_and_east_yaw_90() {
        let north = android(&flat_phone_line(0.0)).expect("readable");
        let attitude = north.recording.attitude.values[0];
        assert_close(yaw_deg(&attitude), 0.0, 1e-9, "north");
        assert_close(attitude.roll_rad, 0.0, 1e-12, "roll");
        assert_close(attitude.pitch_rad, 0.0, 1e-12, "pitch");
        // A −90° turn about up (clockwise seen from above) takes the top edge from north
        // to east: vector part z = sin(−45°).
        let east = android(&flat_phone_line(-std::f64::consts::FRAC_1_SQRT_2)).expect("readable");
        assert_close(
            yaw_deg(&east.recording.attitude.values[0]),
            90.0,
            1e-6,
            "east",
        );
        let west = android(&flat_phone_line(std::f64::consts::FRAC_1_SQRT_2)).expect("readable");
        assert_close(
            yaw_deg(&west.recording.attitude.values[0]),
            270.0,
            1e-6,
            "west",
        );
        // A level phone at rest reads z ≈ −9.81 in body axes.
        assert_close(
            east.recording.acc_in_body_mps2.values[0].z,
            -9.81,
            1e-12,
            "gravity",
        );
    }

    #[test]
    fn the_rotation_vector_becomes_roll_pitch_yaw_for_both_mounts() {
        let about = |axis: Vector3<f64>, angle_deg: f64| {
            UnitQuaternion::from_axis_angle(
                &nalgebra::Unit::new_normalize(axis),
                angle_deg.to_radians(),
            )
        };
        // Flat, top edge north, top edge raised 10° (about east): nose up is positive pitch.
        let raised = attitude_from_rotation_vector(&about(Vector3::x(), 10.0), PhoneMount::Flat);
        assert_close(raised.pitch_rad.to_degrees(), 10.0, 1e-9, "pitch");
        assert_close(raised.roll_rad, 0.0, 1e-12, "roll while pitched");
        // Flat, top edge north, right edge lowered 15° (about north): right side down is
        // positive roll.
        let rolled = attitude_from_rotation_vector(&about(Vector3::y(), 15.0), PhoneMount::Flat);
        assert_close(rolled.roll_rad.to_degrees(), 15.0, 1e-9, "roll");
        assert_close(rolled.pitch_rad, 0.0, 1e-12, "pitch while rolled");
        // Upright, screen towards the user, back towards north: device x east, y up,
        // z south. That is the flat phone turned 90° about east.
        let upright_north = about(Vector3::x(), 90.0);
        let upright = attitude_from_rotation_vector(&upright_north, PhoneMount::Upright);
        assert_close(yaw_deg(&upright), 0.0, 1e-9, "upright facing north");
        assert_close(upright.pitch_rad, 0.0, 1e-9, "upright pitch");
        assert_close(upright.roll_rad, 0.0, 1e-9, "upright roll");
        // The same holder turned to face east.
        let upright_east = about(Vector3::z(), -90.0) * upright_north;
        let east = attitude_from_rotation_vector(&upright_east, PhoneMount::Upright);
        assert_close(yaw_deg(&east), 90.0, 1e-9, "upright facing east");
    }

    #[test]
    fn android_bad_lines_become_diagnostics_and_the_rest_is_read() {
        let text = "1000\tTYPE_ACCELEROMETER\t0\t0\t9.8\t3\n\
                    1020\tTYPE_ACCELEROMETER\t0\tabc\t9.8\t3\n\
                    1040\tTYPE_ACCELEROMETER\t0\tNaN\t9.8\t3\n\
                    1060\tTYPE_ACCELEROMETER\t0\t9.8\n\
                    1080\tTYPE_ACCELEROMETER\t0\t0\t9.8\t3\t7\n\
                    x1100\tTYPE_GYROSCOPE\t0\t0\t0\n\
                    1120\n\
                    1140\tTYPE_ROTATION_VECTOR\t0.9\t0.9\t0.0\t3\n\
                    1160\tTYPE_MAGNETIC_FIELD_UNCALIBRATED\t1\t2\t3\t4\t5\n\
                    1180\tTYPE_WAYPOINT\t1\n\
                    1200\tTYPE_ACCELEROMETER\t0\t0\t9.8\t3\n";
        let report = android(text).expect("readable");
        assert_eq!(report.recording.acc_in_body_mps2.t_s, vec![0.0, 0.2]);
        let lines: Vec<Option<usize>> = report.diagnostics.kept.iter().map(|d| d.line).collect();
        assert_eq!(
            lines,
            [2, 3, 4, 5, 6, 7, 8, 9, 10].map(Some).to_vec(),
            "{:?}",
            report.diagnostics
        );
        let messages: Vec<&str> = report
            .diagnostics
            .kept
            .iter()
            .map(|d| d.message.as_str())
            .collect();
        assert!(
            messages[0].contains("TYPE_ACCELEROMETER: y is not a number (abc)"),
            "{messages:?}"
        );
        assert!(messages[1].contains("y is NaN"), "{messages:?}");
        assert!(
            messages[2].contains("3 or 4 values expected"),
            "{messages:?}"
        );
        assert!(messages[3].contains("found 5"), "{messages:?}");
        assert!(messages[4].contains("unix_ms"), "{messages:?}");
        assert!(
            messages[5].contains("expected unix_ms<TAB>TYPE"),
            "{messages:?}"
        );
        assert!(
            messages[6].contains("not part of a unit quaternion"),
            "{messages:?}"
        );
        assert!(messages[7].contains("6 or 7 values"), "{messages:?}");
        assert!(messages[8].contains("TYPE_WAYPOINT"), "{messages:?}");
        assert_eq!(report.n_data_lines, 11);
    }

    #[test]
    fn android_without_start_time_counts_from_the_earliest_sample() {
        let text = "2000\tTYPE_MAGNETIC_FIELD\t20\t0\t-40\t3\n\
                    1500\tTYPE_WAYPOINT\t1\t2\n\
                    2020\tTYPE_MAGNETIC_FIELD\t20\t0\t-40\t3\n";
        let report = android(text).expect("readable");
        assert_eq!(report.recording.ref_position_en_m.t_s, vec![0.0]);
        assert_close(
            report.recording.mag_in_body_ut.t_s[0],
            0.5,
            1e-12,
            "magnetometer time",
        );
        assert!(report.recording.mag_bias_in_body_ut.is_empty());
        let notes = report.notes.join("\n");
        assert!(notes.contains("earliest sample"), "{notes}");
        assert!(notes.contains("only the OS-calibrated field"), "{notes}");
        assert!(notes.contains("no accelerometer samples"), "{notes}");
        assert!(notes.contains("assumed Flat"), "{notes}");
    }

    #[test]
    fn out_of_order_samples_are_sorted_and_reported_once() {
        let text = "#\tstartTime:1000\n\
                    1000\tTYPE_WAYPOINT\t0\t0\n\
                    3000\tTYPE_WAYPOINT\t2\t2\n\
                    1020\tTYPE_ACCELEROMETER\t0\t0\t9.8\n\
                    2000\tTYPE_WAYPOINT\t1\t1\n\
                    1010\tTYPE_ACCELEROMETER\t0\t0\t9.8\n";
        let report = android(text).expect("readable");
        assert_eq!(report.recording.ref_position_en_m.t_s, vec![0.0, 1.0, 2.0]);
        assert_eq!(report.recording.acc_in_body_mps2.t_s.len(), 2);
        assert!(
            report.recording.acc_in_body_mps2.t_s[0] < report.recording.acc_in_body_mps2.t_s[1]
        );
        assert_eq!(report.diagnostics.total(), 1, "{:?}", report.diagnostics);
        let diagnostic = &report.diagnostics.kept[0];
        assert_eq!(diagnostic.line, Some(5));
        assert!(
            diagnostic.message.contains("time goes backwards 2 times"),
            "{diagnostic:?}"
        );
    }

    #[test]
    fn an_upright_phone_is_detected_and_mapped() {
        let text = "ACCE;0.010;5.000;0.05;9.79;-0.10;3\n\
                    MAGN;0.012;5.002;1.0;2.0;3.0;3\n\
                    ACCE;0.030;5.020;-0.05;9.83;0.10;3\n";
        let report = gsd(text).expect("readable");
        let notes = report.notes.join("\n");
        assert!(notes.contains(PhoneMount::Upright.describe()), "{notes}");
        assert_vector_close(
            report.recording.mag_in_body_ut.values[0],
            Vector3::new(-3.0, 1.0, -2.0),
            "upright magnetometer",
        );
        assert_close(
            report.recording.acc_in_body_mps2.values[0].z,
            -9.79,
            1e-12,
            "gravity",
        );
    }

    #[test]
    fn get_sensor_data_golden_lines_of_every_tag() {
        let report = gsd(GET_SENSOR_DATA_SAMPLE).expect("readable");
        assert!(report.diagnostics.is_empty(), "{:?}", report.diagnostics);
        assert_eq!(report.format, GET_SENSOR_DATA);
        assert_eq!(report.n_data_lines, 17);
        let r = &report.recording;

        // AppTimestamp is the time, unchanged.
        assert_eq!(r.acc_in_body_mps2.t_s, vec![0.012, 0.032]);
        assert_vector_close(
            r.acc_in_body_mps2.values[0],
            Vector3::new(0.11971, 0.07184, -9.81532),
            "accelerometer",
        );
        assert_eq!(r.gyro_in_body_radps.t_s, vec![0.013]);
        assert_vector_close(
            r.gyro_in_body_radps.values[0],
            Vector3::new(0.00244, -0.00122, -0.00061),
            "gyroscope",
        );
        assert_eq!(r.mag_in_body_ut.t_s, vec![0.015]);
        assert_vector_close(
            r.mag_in_body_ut.values[0],
            Vector3::new(22.62, -2.04, 40.38),
            "magnetometer",
        );
        assert!(r.mag_bias_in_body_ut.is_empty());
        assert_eq!(r.pressure_hpa.values, vec![947.3125]);
        assert_eq!(r.temp_c.values, vec![24.5]);
        assert_eq!(r.temp_c.t_s, vec![0.021]);

        // The app's YawZ is −90 (counter-clockwise); the heading is 90°, east.
        assert_eq!(r.attitude.t_s, vec![0.024]);
        assert_close(yaw_deg(&r.attitude.values[0]), 90.0, 1e-5, "AHRS yaw");
        assert_close(r.attitude.values[0].pitch_rad, 0.0, 1e-9, "AHRS pitch");

        assert_eq!(r.gnss.t_s, vec![0.512]);
        let fix = r.gnss.values[0];
        assert_eq!(fix.lat_deg, Some(40.313541));
        assert_eq!(fix.lon_deg, Some(-3.483176));
        assert_eq!(fix.alt_m, Some(651.2));
        assert_eq!(fix.hacc_m, Some(8.0));
        assert_eq!(fix.speed_mps, Some(1.2));
        assert_close(
            fix.course_rad.unwrap_or(f64::NAN).to_degrees(),
            45.0,
            1e-9,
            "course",
        );

        assert_eq!(r.ref_position_lat_lon_deg.t_s, vec![0.6]);
        assert_eq!(
            r.ref_position_lat_lon_deg.values,
            vec![Vector2::new(40.31355012, -3.4831851)]
        );

        let notes = report.notes.join("\n");
        assert!(notes.contains("t_s = AppTimestamp"), "{notes}");
        assert!(notes.contains(PhoneMount::Flat.describe()), "{notes}");
        for tag in [
            "WIFI ×1", "BLE4 ×1", "LIGH ×1", "PROX ×1", "HUMI ×1", "SOUN ×1", "RFID ×1", "BLUE ×1",
        ] {
            assert!(notes.contains(tag), "{tag} missing from {notes}");
        }
        assert!(
            notes.contains("ACCE 9635.400 to 9635.400 s (spread 0 ms)"),
            "{notes}"
        );
        assert!(notes.contains("PRES 9635.378"), "{notes}");
        assert!(notes.contains("only the OS-calibrated field"), "{notes}");
    }

    #[test]
    fn get_sensor_data_bad_lines_become_diagnostics_and_the_rest_is_read() {
        let text = "ACCE;0.010;5.000;0.0;0.0;9.8;3\n\
                    ACCE;0.020;5.010;0.0;oops;9.8;3\n\
                    GYRO;0.030;5.020;0.0;0.0\n\
                    MAGN;0.040;5.030;inf;0.0;1.0;3\n\
                    hello world\n\
                    PRES;0.050;5.040\n\
                    AHRS;0.060;5.050;0;0;0;0.9;0.9;0.9;3\n\
                    GNSS;0.070;1568967124.000;95.0;-3.48;651.2;45.0;8.0;1.2;12;9\n\
                    GNSS;0.080;1568967125.000;40.3\n\
                    POSI;0.090;1;0.00000000;0.00000000;0;0\n\
                    ACCE;0.100;5.090;0.0;0.0;9.8;3\n";
        let report = gsd(text).expect("readable");
        assert_eq!(report.recording.acc_in_body_mps2.t_s, vec![0.01, 0.1]);
        let lines: Vec<Option<usize>> = report.diagnostics.kept.iter().map(|d| d.line).collect();
        assert_eq!(
            lines,
            (2..=10).map(Some).collect::<Vec<_>>(),
            "{:?}",
            report.diagnostics
        );
        let messages: Vec<&str> = report
            .diagnostics
            .kept
            .iter()
            .map(|d| d.message.as_str())
            .collect();
        assert!(
            messages[0].contains("ACCE: Acc_Y is not a number (oops)"),
            "{messages:?}"
        );
        assert!(
            messages[1].contains("GYRO: 5 or 6 fields after the tag expected"),
            "{messages:?}"
        );
        assert!(messages[2].contains("Mag_X is inf"), "{messages:?}");
        assert!(
            messages[3].contains("not a GetSensorData line"),
            "{messages:?}"
        );
        assert!(messages[4].contains("PRES"), "{messages:?}");
        assert!(messages[5].contains("unit quaternion"), "{messages:?}");
        assert!(messages[6].contains("out of range"), "{messages:?}");
        assert!(
            messages[7].contains("GNSS: 8 fields after the tag expected"),
            "{messages:?}"
        );
        assert!(messages[8].contains("without coordinates"), "{messages:?}");
    }

    #[test]
    fn get_sensor_data_logs_are_dated_by_fixes_else_by_the_header() {
        // The competitions' layout: UTCTime(ms) after Speed wins over SensorTimeStamp.
        let with_utc = "% Date of creation: Fri Sep 20 10:18:41 GMT+02:00 2019\n\
                        ACCE;0.010;9635.4;0.07;0.11;9.81;3\n\
                        GNSS;2.500;9700.0;40.3135;-3.4831;651.2;45.0;8.0;1.2;1568967124500;12;9\n";
        let report = gsd(with_utc).expect("readable");
        assert_eq!(report.recording.start_unix_s, Some(1_568_967_122.0));
        assert!(report.notes.iter().any(|note| note.contains("UTCTime")));
        // The app's own layout: SensorTimeStamp is the fix's UTC time in seconds.
        let app = "GNSS;0.512;1568967124.000;40.313541;-3.483176;651.200;45.000;8.0;1.2;12;9\n";
        let start = gsd(app).expect("readable").recording.start_unix_s;
        assert!(start.is_some_and(|start| (start - 1_568_967_123.488).abs() < 1e-6));
        // No fix: the header's date of creation, in its zone.
        let header_only = "% Date of creation: Fri Sep 20 10:18:41 GMT+02:00 2019\n\
                           ACCE;0.010;9635.4;0.07;0.11;9.81;3\n\
                           POSI;0.600;1;40.31355012;-3.48318510;0;0\n";
        let report = gsd(header_only).expect("readable");
        // 2019-09-20 08:18:41 UTC.
        assert_eq!(report.recording.start_unix_s, Some(1_568_967_521.0));
        assert_eq!(
            java_date_unix_s("Fri Sep 20 10:18:41 CEST 2019"),
            Some((1_568_974_721.0, false))
        );
        assert_eq!(java_date_unix_s("yesterday"), None);
    }

    #[test]
    fn get_sensor_data_gnss_without_sensor_timestamp_is_read() {
        // The older layout: no SensorTimeStamp; a standing receiver without bearing or
        // accuracy reports zeros for them.
        let report =
            gsd("GNSS;3.250;40.313541;-3.483176;651.2;0.0;0.0;0.0;10;7\n").expect("readable");
        let fix = report.recording.gnss.values[0];
        assert_eq!(report.recording.gnss.t_s, vec![3.25]);
        assert_eq!(fix.lat_deg, Some(40.313541));
        assert_eq!(fix.lon_deg, Some(-3.483176));
        assert_eq!(fix.course_rad, None);
        assert_eq!(fix.hacc_m, None);
        assert_eq!(fix.speed_mps, Some(0.0));
    }

    #[test]
    fn the_formats_are_told_apart() {
        let android_lines: Vec<&str> = ANDROID_SAMPLE.lines().collect();
        let gsd_lines: Vec<&str> = GET_SENSOR_DATA_SAMPLE.lines().collect();
        assert!(looks_like_android_dump(&android_lines));
        assert!(!looks_like_get_sensor_data(&android_lines));
        assert!(looks_like_get_sensor_data(&gsd_lines));
        assert!(!looks_like_android_dump(&gsd_lines));
        // Without its header, a GetSensorData log is still recognised by its tags.
        assert!(looks_like_get_sensor_data(&gsd_lines[8..]));
        let csv = ["t_s,mag_x_ut,mag_y_ut,mag_z_ut", "0,1,2,3"];
        assert!(!looks_like_android_dump(&csv));
        assert!(!looks_like_get_sensor_data(&csv));
        let nmea = ["$GPRMC,123519,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W*6A"];
        assert!(!looks_like_android_dump(&nmea));
        assert!(!looks_like_get_sensor_data(&nmea));
        assert!(!looks_like_android_dump(&[]));
        assert!(!looks_like_get_sensor_data(&[]));
    }

    #[test]
    fn files_with_nothing_readable_are_errors() {
        for read in [read_android_dump, read_get_sensor_data] {
            assert!(matches!(read("x.txt", b""), Err(ImportError::Empty { .. })));
            assert!(matches!(
                read("x.txt", b" \r\n\n"),
                Err(ImportError::Empty { .. })
            ));
            assert!(matches!(
                read("x.bin", b"\x00\x01\x02garbage"),
                Err(ImportError::NotText { byte_offset: 0, .. })
            ));
        }
        let error = android("hello world\nthis is not a log\n")
            .map(|_| ())
            .unwrap_err();
        let ImportError::NothingRecognised {
            format,
            n_lines,
            first_problem,
            ..
        } = &error
        else {
            panic!("unexpected {error:?}");
        };
        assert_eq!((*format, *n_lines), (ANDROID_DUMP, 2));
        assert!(first_problem.starts_with(" (line 1: "), "{first_problem}");
        let message = error.to_string();
        assert!(
            message.starts_with("walk.txt: none of its 2 lines"),
            "{message}"
        );

        let error = gsd("% GetSensorData\nhello;world\n")
            .map(|_| ())
            .unwrap_err();
        assert!(
            matches!(&error, ImportError::NothingRecognised { first_problem, .. }
                if first_problem.starts_with(" (line 2: ")),
            "{error:?}"
        );
        // Only tags this tool ignores: still nothing, and the message says why.
        let error = gsd("WIFI;0.4;9634.1;eduroam;00:0b:86:27:36:c1;2412;-67\n")
            .map(|_| ())
            .unwrap_err();
        assert!(
            matches!(&error, ImportError::NothingRecognised { first_problem, .. }
                if first_problem.contains("line 1: only WIFI ×1")),
            "{error:?}"
        );
        let error = android("# only a comment\n").map(|_| ()).unwrap_err();
        assert!(
            matches!(&error, ImportError::NothingRecognised { first_problem, .. } if first_problem.is_empty()),
            "{error:?}"
        );
    }

    fn read_chunks(reader: impl LineReader, chunks: &[&[u8]]) -> Result<ImportReport, ImportError> {
        let mut reader = reader;
        let mut decoder = LineDecoder::new(MAX_LINE_BYTES);
        for chunk in chunks {
            decoder.feed(chunk, |line| {
                reader.read_line(line.number, &line.text, line.truncated)
            });
        }
        decoder.finish(|line| reader.read_line(line.number, &line.text, line.truncated));
        reader.finish("walk.txt".to_string())
    }

    #[test]
    fn every_chunking_gives_the_same_report() {
        let android_text = "#\tstartTime:1000\r\n1000\tTYPE_ACCELEROMETER\t0\t0\t9.8\t3\r\n\
                            1020\tTYPE_WAYPOINT\t1\t2\r1040\tTYPE_ROTATION_VECTOR\t0\t0\t0.5\n\
                            1060\tTYPE_ACCELEROMETER\t0\tx\t9.8";
        let whole = read_android_dump("walk.txt", android_text.as_bytes()).expect("readable");
        let bytes = android_text.as_bytes();
        for split in 0..=bytes.len() {
            let chunks = [&bytes[..split], &bytes[split..]];
            let got = read_chunks(AndroidReader::default(), &chunks).expect("readable");
            assert_eq!(got, whole, "split at {split}");
        }

        let gsd_text = "% GetSensorData\r\nACCE;0.01;5.0;0;0;9.8;3\r\nPOSI;0.5;1;40.3;-3.4;0;0\r\
                        AHRS;0.02;5.01;0;0;0;0;0;0.5;3\nACCE;0.03;5.02;0;y;9.8;3";
        let whole = read_get_sensor_data("walk.txt", gsd_text.as_bytes()).expect("readable");
        let bytes = gsd_text.as_bytes();
        for split in 0..=bytes.len() {
            let chunks = [&bytes[..split], &bytes[split..]];
            let got = read_chunks(GetSensorDataReader::default(), &chunks).expect("readable");
            assert_eq!(got, whole, "split at {split}");
        }
    }

    #[test]
    fn pseudo_random_bytes_never_panic() {
        // Bytes drawn mostly from the formats' own alphabet, so that the parsers get far.
        let alphabet: &[u8] = b"0123456789.-eE;\t\n\r #%TYPE_ACCELROMTGYSNWIFHUDKVQ";
        let words: [&[u8]; 10] = [
            b"TYPE_ACCELEROMETER\t",
            b"TYPE_MAGNETIC_FIELD_UNCALIBRATED\t",
            b"TYPE_ROTATION_VECTOR\t",
            b"TYPE_WAYPOINT\t",
            b"ACCE;",
            b"AHRS;",
            b"GNSS;",
            b"POSI;",
            b"NaN",
            b"#\tstartTime:",
        ];
        let mut state: u64 = 0x2545_f491_4f6c_dd1d;
        let mut next = move || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (state >> 33) as usize
        };
        for _ in 0..400 {
            let len = next() % 600;
            let mut bytes = Vec::with_capacity(len + 64);
            while bytes.len() < len {
                match next() % 10 {
                    0 => bytes.extend_from_slice(words[next() % words.len()]),
                    1 => bytes.push((next() % 256) as u8),
                    _ => bytes.push(alphabet[next() % alphabet.len()]),
                }
            }
            let _ = read_android_dump("random.txt", &bytes);
            let _ = read_get_sensor_data("random.txt", &bytes);
            let text = String::from_utf8_lossy(&bytes);
            let lines: Vec<&str> = text.lines().collect();
            let _ = looks_like_android_dump(&lines);
            let _ = looks_like_get_sensor_data(&lines);
        }
    }

    // ---- the real recordings in ../shared/data -------------------------------------

    /// The bytes of a file under `../shared/data`, or `None` (with a message) where the
    /// folder is absent, as in a user's clone.
    fn shared_data(path: &str) -> Option<Vec<u8>> {
        let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data");
        let full = format!("{root}/{path}");
        match std::fs::read(&full) {
            Ok(bytes) => Some(bytes),
            Err(error) => {
                eprintln!("skipped: ../shared/data not found ({full}: {error})");
                None
            }
        }
    }

    struct Expected {
        n_samples: usize,
        n_waypoints: usize,
    }

    fn check_msft_walk(path: &str, expected: Expected) {
        let Some(bytes) = shared_data(path) else {
            return;
        };
        let report = read_android_dump(path, &bytes).expect("readable");
        let r = &report.recording;
        for (name, n) in [
            ("accelerometer", r.acc_in_body_mps2.len()),
            ("gyroscope", r.gyro_in_body_radps.len()),
            ("magnetometer", r.mag_in_body_ut.len()),
            ("OS bias", r.mag_bias_in_body_ut.len()),
            ("rotation vector", r.attitude.len()),
        ] {
            assert_eq!(n, expected.n_samples, "{path}: {name}");
        }
        assert_eq!(
            r.ref_position_en_m.len(),
            expected.n_waypoints,
            "{path}: waypoints"
        );
        // The last waypoint comes after later sensor lines, but each stream is in order.
        assert!(
            report.diagnostics.is_empty(),
            "{path}: {:?}",
            report.diagnostics
        );

        let duration_s = r.acc_in_body_mps2.duration_s();
        let rate_hz = (r.acc_in_body_mps2.len() - 1) as f64 / duration_s;
        assert!(
            (113.0..=120.0).contains(&duration_s),
            "{path}: {duration_s} s"
        );
        assert!((48.0..=52.0).contains(&rate_hz), "{path}: {rate_hz} Hz");

        let notes = report.notes.join("\n");
        assert!(
            notes.contains("phone mount: Flat, detected"),
            "{path}: {notes}"
        );
        assert!(
            notes.contains("from the startTime header"),
            "{path}: {notes}"
        );
        let n = r.acc_in_body_mps2.len() as f64;
        let mean_acc = r.acc_in_body_mps2.values.iter().sum::<Vector3<f64>>() / n;
        assert!(
            mean_acc.z < -9.0,
            "{path}: mean specific force {mean_acc:?}"
        );

        // The OS bias is on every magnetometer sample, and raw − bias is the Earth's field
        // there (about 48 µT).
        assert_eq!(r.mag_bias_in_body_ut.t_s, r.mag_in_body_ut.t_s);
        let n_mag = r.mag_in_body_ut.len() as f64;
        let calibrated: Vec<Vector3<f64>> = r
            .mag_in_body_ut
            .values
            .iter()
            .zip(&r.mag_bias_in_body_ut.values)
            .map(|(raw, bias)| raw - bias)
            .collect();
        let mean_calibrated_ut = calibrated.iter().map(|m| m.norm()).sum::<f64>() / n_mag;
        let mean_raw_ut = r
            .mag_in_body_ut
            .values
            .iter()
            .map(|m| m.norm())
            .sum::<f64>()
            / n_mag;
        assert!(
            (33.0..=63.0).contains(&mean_calibrated_ut),
            "{path}: {mean_calibrated_ut} µT"
        );

        assert!(r.attitude.values.iter().all(|a| a.roll_rad.is_finite()
            && a.pitch_rad.is_finite()
            && a.yaw_rad.is_some_and(f64::is_finite)));

        // The attitude agrees with the other sensors: it turns specific force to about
        // 9.8 m/s² up, and the calibrated field to magnetic north, dipping down.
        let mut gravity_ned = Vector3::zeros();
        let mut field_ned = Vector3::zeros();
        let mut n_pairs = 0usize;
        for (idx, attitude) in r.attitude.values.iter().enumerate() {
            let (Some(&t_att), Some(&t_acc), Some(&t_mag)) = (
                r.attitude.t_s.get(idx),
                r.acc_in_body_mps2.t_s.get(idx),
                r.mag_in_body_ut.t_s.get(idx),
            ) else {
                continue;
            };
            if t_att != t_acc || t_att != t_mag {
                continue;
            }
            let ned_from_body = Rotation3::from_euler_angles(
                attitude.roll_rad,
                attitude.pitch_rad,
                attitude.yaw_rad.unwrap_or(0.0),
            );
            gravity_ned += ned_from_body * r.acc_in_body_mps2.values[idx];
            field_ned += (ned_from_body * calibrated[idx]).normalize();
            n_pairs += 1;
        }
        assert!(
            n_pairs as f64 > 0.9 * n,
            "{path}: only {n_pairs} samples share a time"
        );
        let gravity_ned = gravity_ned / n_pairs as f64;
        let field_ned = field_ned / n_pairs as f64;
        let field_azimuth_deg = field_ned.y.atan2(field_ned.x).to_degrees();
        let field_dip_deg = field_ned.z.atan2(field_ned.xy().norm()).to_degrees();
        assert_close(gravity_ned.z, -9.8, 0.5, "vertical specific force in NED");
        assert!(gravity_ned.xy().norm() < 0.5, "{path}: {gravity_ned:?}");
        assert!(
            field_azimuth_deg.abs() < 15.0,
            "{path}: field azimuth {field_azimuth_deg}°"
        );
        assert!(
            (30.0..=60.0).contains(&field_dip_deg),
            "{path}: field dip {field_dip_deg}°"
        );

        // Its roll and pitch follow the accelerometer's tilt: one-second means of both
        // rise and fall together (a sign error would make them move oppositely).
        let (pitch_correlation, roll_correlation) = tilt_correlations(r);
        assert!(
            pitch_correlation > 0.3,
            "{path}: pitch correlation {pitch_correlation}"
        );
        assert!(
            roll_correlation > 0.3,
            "{path}: roll correlation {roll_correlation}"
        );

        eprintln!(
            "{path}: {} samples per sensor, {} waypoints, {duration_s:.2} s, {rate_hz:.2} Hz, \
             mean |raw − bias| {mean_calibrated_ut:.1} µT, mean |raw| {mean_raw_ut:.1} µT, \
             mean specific force (body) {mean_acc:?}, field azimuth {field_azimuth_deg:.1}°, \
             dip {field_dip_deg:.1}°, gravity in NED {gravity_ned:?}, tilt correlations \
             {pitch_correlation:.2} (pitch), {roll_correlation:.2} (roll), diagnostics {:?}",
            expected.n_samples, expected.n_waypoints, report.diagnostics.kept
        );
    }

    /// Correlations of one-second means of the attitude's pitch and roll with those
    /// seen in the specific force, sample by sample (the streams share their times).
    fn tilt_correlations(r: &Recording) -> (f64, f64) {
        const WINDOW: usize = 50;
        let n_windows = r.attitude.len().min(r.acc_in_body_mps2.len()) / WINDOW;
        let mut series: [Vec<f64>; 4] = Default::default();
        for window in 0..n_windows {
            let range = window * WINDOW..(window + 1) * WINDOW;
            let attitude = &r.attitude.values[range.clone()];
            let force = r.acc_in_body_mps2.values[range]
                .iter()
                .sum::<Vector3<f64>>();
            series[0].push(attitude.iter().map(|a| a.pitch_rad).sum::<f64>());
            series[1].push(force.x.atan2(force.yz().norm()));
            series[2].push(attitude.iter().map(|a| a.roll_rad).sum::<f64>());
            series[3].push((-force.y).atan2(-force.z));
        }
        let correlation = |a: &[f64], b: &[f64]| {
            let n = a.len() as f64;
            let (mean_a, mean_b) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
            let covariance: f64 = a
                .iter()
                .zip(b)
                .map(|(x, y)| (x - mean_a) * (y - mean_b))
                .sum();
            let var_a: f64 = a.iter().map(|x| (x - mean_a).powi(2)).sum();
            let var_b: f64 = b.iter().map(|y| (y - mean_b).powi(2)).sum();
            covariance / (var_a * var_b).sqrt()
        };
        (
            correlation(&series[0], &series[1]),
            correlation(&series[2], &series[3]),
        )
    }

    #[test]
    fn the_msft_f1_walk_is_read() {
        check_msft_walk(
            "msft-indoor-2020/site1/F1/5dd9ef979191710006b57086.txt",
            Expected {
                n_samples: 5755,
                n_waypoints: 17,
            },
        );
    }

    #[test]
    fn the_msft_f4_walk_is_read() {
        check_msft_walk(
            "msft-indoor-2020/site1/F4/5ddb6573c5b77e0006b17932.txt",
            Expected {
                n_samples: 5971,
                n_waypoints: 25,
            },
        );
    }
}
