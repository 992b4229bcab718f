//! What both tagged formats read ([`super`]), collected in Android's device axes and on
//! the file's own clock ([`Collector`]) until the end of the file, when the phone's
//! mount is detected from the mean specific force ([`PhoneMount`]), vectors become
//! body axes, times become seconds ([`Clock`]), the rotation vector becomes roll, pitch
//! and yaw, streams are sorted, and the notes are written.

use std::collections::BTreeMap;

use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector2, Vector3};

use crate::base::angle::wrap_to_2pi;
use crate::io::axes::PhoneMount;
use crate::io::recording::{Attitude, GnssFix, GyroBias, Recording, Stream};
use crate::io::{shorten, Diagnostics, ImportError, ImportReport, MagUnit, SensorFrame};

/// Distinct ignored tags listed by name; past this they are only counted, so that a
/// file of garbage cannot grow the list without bound.
const MAX_IGNORED_NAMES: usize = 32;

/// Which stream a sample went to, for finding the first line whose time goes backwards.
#[derive(Debug, Clone, Copy)]
pub(super) enum Slot {
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
pub(super) struct Clock {
    pub(super) origin: f64,
    pub(super) scale: f64,
    /// What the notes say about the clock.
    pub(super) note: String,
}

/// What both formats read, in device axes and on the file's own clock, until the mount
/// and the time origin are known at the end of the file.
#[derive(Default)]
pub(super) struct Collector {
    pub(super) acc_in_device_mps2: Stream<Vector3<f64>>,
    pub(super) gyro_in_device_radps: Stream<Vector3<f64>>,
    pub(super) mag_calibrated_in_device_ut: Stream<Vector3<f64>>,
    pub(super) mag_raw_in_device_ut: Stream<Vector3<f64>>,
    pub(super) mag_bias_in_device_ut: Stream<Vector3<f64>>,
    pub(super) device_to_enu: Stream<UnitQuaternion<f64>>,
    pub(super) pressure_hpa: Stream<f64>,
    pub(super) temp_c: Stream<f64>,
    pub(super) gnss: Stream<GnssFix>,
    pub(super) ref_position_en_m: Stream<Vector2<f64>>,
    pub(super) ref_position_lat_lon_deg: Stream<Vector2<f64>>,
    diagnostics: Diagnostics,
    pub(super) n_lines: usize,
    pub(super) n_data_lines: usize,
    /// Samples read per tag, for the notes.
    n_read: BTreeMap<&'static str, usize>,
    /// Lines of tags this tool does not use, per tag.
    ignored: BTreeMap<String, usize>,
    n_ignored_unnamed: usize,
    first_ignored_line: Option<usize>,
    last_t: [Option<f64>; N_SLOTS],
    first_backwards_line: Option<usize>,
    /// Notes that only one format knows about, added after the common ones.
    pub(super) extra_notes: Vec<String>,
}

impl Collector {
    /// Counts a sample of `tag` and remembers the first line where its stream's time
    /// goes backwards.
    pub(super) fn record(&mut self, slot: Slot, tag: &'static str, line: usize, t: f64) {
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

    pub(super) fn ignore(&mut self, line: usize, tag: &str) {
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

    pub(super) fn problem(&mut self, line: usize, message: impl Into<String>) {
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
    pub(super) fn earliest_t(&self) -> Option<f64> {
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
    pub(super) fn finish(
        mut self,
        file_name: String,
        format: &'static str,
        clock: Clock,
    ) -> Result<ImportReport, ImportError> {
        if self.is_empty() {
            return Err(self.nothing_recognised(file_name, format));
        }
        let mut notes = self.read_notes();
        let Clock {
            origin,
            scale,
            note,
        } = clock;
        notes.push(note);
        let mount = detect_mount(&self.acc_in_device_mps2, &mut notes);

        let to_s = |t: f64| (t - origin) * scale;
        let mut recording = self.recording_in_body(to_s, mount);
        notes.extend(self.take_magnetometer(&mut recording, to_s, mount));
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
        self.sort_by_time(&mut recording);

        Ok(ImportReport {
            autopilot: None,
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

    /// The first notes: the samples read per tag, and the gyroscope's kind.
    // A step run once per log, out of line (docs/ARCHITECTURE.md, "Build").
    #[inline(never)]
    fn read_notes(&self) -> Vec<String> {
        let mut notes = Vec::new();
        if !self.n_read.is_empty() {
            let counts: Vec<String> = self
                .n_read
                .iter()
                .map(|(tag, count)| format!("{count} {tag}"))
                .collect();
            notes.push(format!("read {} samples", counts.join(", ")));
        }
        if !self.gyro_in_device_radps.is_empty() {
            notes.push(
                "gyroscope: Android's TYPE_GYROSCOPE, the rate with the OS's bias estimate removed"
                    .to_string(),
            );
        }
        notes
    }

    /// Every stream but the magnetometer in body axes (by `mount`) and seconds (by
    /// `to_s`), the rotation vector as an attitude.
    // A step run once per log, out of line (docs/ARCHITECTURE.md, "Build").
    #[inline(never)]
    fn recording_in_body(&self, to_s: impl Fn(f64) -> f64 + Copy, mount: PhoneMount) -> Recording {
        let to_body = |v: &Vector3<f64>| mount.device_to_body(*v);
        Recording {
            acc_in_body_mps2: convert(&self.acc_in_device_mps2, to_s, to_body),
            gyro_in_body_radps: convert(&self.gyro_in_device_radps, to_s, to_body),
            // Both dialects log Android's `TYPE_GYROSCOPE`, the OS's drift removed.
            gyro_bias: GyroBias::RemovedByDevice,
            temp_c: convert(&self.temp_c, to_s, |v| *v),
            pressure_hpa: convert(&self.pressure_hpa, to_s, |v| *v),
            gnss: convert(&self.gnss, to_s, |v| *v),
            attitude: convert(&self.device_to_enu, to_s, |q| {
                attitude_from_rotation_vector(q, mount)
            }),
            ref_position_en_m: convert(&self.ref_position_en_m, to_s, |v| *v),
            ref_position_lat_lon_deg: convert(&self.ref_position_lat_lon_deg, to_s, |v| *v),
            ..Recording::default()
        }
    }

    /// The raw field (with the OS's bias estimate) as the recording's magnetometer, else
    /// the OS-calibrated one, in body axes and seconds; a note says which.
    // A step run once per log, out of line (docs/ARCHITECTURE.md, "Build").
    #[inline(never)]
    fn take_magnetometer(
        &self,
        recording: &mut Recording,
        to_s: impl Fn(f64) -> f64 + Copy,
        mount: PhoneMount,
    ) -> Option<String> {
        let to_body = |v: &Vector3<f64>| mount.device_to_body(*v);
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
            Some(format!(
                "magnetometer: the raw (uncalibrated) field, with the OS's own hard-iron \
                 estimate kept as the device bias{unused}"
            ))
        } else if !self.mag_calibrated_in_device_ut.is_empty() {
            recording.mag_in_body_ut = convert(&self.mag_calibrated_in_device_ut, to_s, to_body);
            Some(
                "magnetometer: only the OS-calibrated field, from which the OS has already \
                 removed its hard-iron estimate, so a calibration fit should find little offset"
                    .to_string(),
            )
        } else {
            None
        }
    }

    /// Sorts every stream of `recording` by time, with a diagnostic when time went
    /// backwards.
    // A step run once per log, out of line (docs/ARCHITECTURE.md, "Build").
    #[inline(never)]
    fn sort_by_time(&mut self, recording: &mut Recording) {
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
// A step run once per log, out of line (docs/ARCHITECTURE.md, "Build").
#[inline(never)]
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

#[cfg(test)]
mod tests {
    use super::super::tests::{android, assert_close, assert_vector_close, gsd, yaw_deg};
    use super::super::{read_android_dump, read_get_sensor_data};
    use super::*;

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
}
