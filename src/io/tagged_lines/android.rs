//! The Android sensor dump ([`super`]), read line by line by [`AndroidReader`].
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

use nalgebra::Vector2;
use thiserror::Error;

use super::collector::{Clock, Collector, Slot};
use super::fields::{
    check_count, finite, quaternion_from_rotation_vector, split_fields, vector3, TaggedFieldError,
};
use super::{LineReader, ANDROID_DUMP, MAX_LINE_BYTES};
use crate::io::{shorten, ImportError, ImportReport};

/// Why a line of an Android sensor dump was not read; the line's diagnostic.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum AndroidLineError {
    /// The line has no type after its time; `found` is its first field.
    #[error("expected unix_ms<TAB>TYPE<TAB>values, found only {:?}", shorten(.found))]
    NoType { found: String },
    /// The time (unix_ms) is not a finite number.
    #[error(transparent)]
    Time(#[from] TaggedFieldError),
    /// A value of a line of type `kind` (`TYPE_ACCELEROMETER`, …), or their count.
    #[error("{kind}: {error}")]
    InType {
        kind: String,
        #[source]
        error: TaggedFieldError,
    },
}

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
        if let Err(error) = self.read_fields(number, &fields) {
            self.collector.problem(number, error.to_string());
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
            Err(error) => self.collector.problem(
                number,
                format!("{error}; times count from the earliest sample instead"),
            ),
        }
    }

    fn read_fields(&mut self, number: usize, fields: &[&str]) -> Result<(), AndroidLineError> {
        let (Some(time), Some(kind)) = (fields.first(), fields.get(1)) else {
            return Err(AndroidLineError::NoType {
                found: fields.first().copied().unwrap_or_default().to_string(),
            });
        };
        let t_ms = finite(Some(time), "the time (unix_ms)")?;
        let values = fields.get(2..).unwrap_or_default();
        self.read_values(number, kind, t_ms, values)
            .map_err(|error| AndroidLineError::InType {
                kind: (*kind).to_string(),
                error,
            })
    }

    /// The values of a line of type `kind` at `t_ms`.
    fn read_values(
        &mut self,
        number: usize,
        kind: &str,
        t_ms: f64,
        values: &[&str],
    ) -> Result<(), TaggedFieldError> {
        let c = &mut self.collector;
        match kind {
            "TYPE_ACCELEROMETER" => {
                check_count(values.len(), 3, 4, "values", "x y z [accuracy]")?;
                let acc = vector3(values, 0, ["x", "y", "z"])?;
                c.record(Slot::Acc, "TYPE_ACCELEROMETER", number, t_ms);
                c.acc_in_device_mps2.push(t_ms, acc);
            }
            "TYPE_GYROSCOPE" => {
                check_count(values.len(), 3, 4, "values", "x y z [accuracy]")?;
                let gyro = vector3(values, 0, ["x", "y", "z"])?;
                c.record(Slot::Gyro, "TYPE_GYROSCOPE", number, t_ms);
                c.gyro_in_device_radps.push(t_ms, gyro);
            }
            "TYPE_MAGNETIC_FIELD" => {
                check_count(values.len(), 3, 4, "values", "x y z [accuracy]")?;
                let mag = vector3(values, 0, ["x", "y", "z"])?;
                c.record(Slot::MagCalibrated, "TYPE_MAGNETIC_FIELD", number, t_ms);
                c.mag_calibrated_in_device_ut.push(t_ms, mag);
            }
            "TYPE_MAGNETIC_FIELD_UNCALIBRATED" => {
                check_count(values.len(), 6, 7, "values", "mx my mz bx by bz [accuracy]")?;
                let raw = vector3(values, 0, ["mx", "my", "mz"])?;
                let bias = vector3(values, 3, ["bx", "by", "bz"])?;
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
                )?;
                let v = vector3(values, 0, ["x", "y", "z"])?;
                let q = quaternion_from_rotation_vector(v.x, v.y, v.z)?;
                c.record(Slot::Rotation, "TYPE_ROTATION_VECTOR", number, t_ms);
                c.device_to_enu.push(t_ms, q);
            }
            "TYPE_WAYPOINT" => {
                check_count(values.len(), 2, 2, "values", "x y")?;
                let east_m = finite(values.first(), "x")?;
                let north_m = finite(values.get(1), "y")?;
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
fn number_of(text: &str, name: &str) -> Result<f64, TaggedFieldError> {
    finite(Some(&text), name)
}

#[cfg(test)]
mod tests {
    use nalgebra::Vector3;

    use super::super::tests::{
        android, assert_close, assert_vector_close, yaw_deg, ANDROID_SAMPLE,
    };
    use super::*;
    use crate::io::axes::PhoneMount;

    #[test]
    fn android_golden_lines_of_every_type() {
        let report = android(ANDROID_SAMPLE).expect("readable");
        assert!(report.diagnostics.is_empty(), "{:?}", report.diagnostics);
        assert_eq!(report.format, ANDROID_DUMP);
        assert_eq!(report.header, None);
        assert_eq!(report.n_data_lines, 13);
        let r = &report.recording;
        // TYPE_GYROSCOPE is the rate with the OS's drift estimate removed.
        assert_eq!(r.gyro_bias, crate::io::recording::GyroBias::RemovedByDevice);
        assert!(
            report
                .notes
                .iter()
                .any(|note| note.contains("the OS's bias estimate removed")),
            "{:?}",
            report.notes
        );

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
        let messages = report.diagnostics.messages();
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

    /// Every line diagnostic, word for word (the wording users see).
    #[test]
    fn android_diagnostics_are_worded_exactly() {
        let text = "#\tstartTime:abc\n\
                    1000\tTYPE_ACCELEROMETER\t0\tabc\t9.8\t3\n\
                    1020\tTYPE_ACCELEROMETER\t0\tNaN\t9.8\t3\n\
                    1040\tTYPE_ACCELEROMETER\t0\t9.8\n\
                    x1060\tTYPE_GYROSCOPE\t0\t0\t0\n\
                    1080\n\
                    1100\tTYPE_ROTATION_VECTOR\t0.9\t0.9\t0.0\t3\n\
                    1120\tTYPE_ROTATION_VECTOR\t0\t0\t0\t1\t3\t7\n\
                    1140\tTYPE_MAGNETIC_FIELD_UNCALIBRATED\t1\t2\t3\t4\t5\n\
                    1160\tTYPE_WAYPOINT\t1\n\
                    1180\tTYPE_MAGNETIC_FIELD\t20\t0\t-40\t3\n";
        let report = android(text).expect("readable");
        let messages = report.diagnostics.messages();
        assert_eq!(
            messages,
            [
                "startTime is not a number (abc); times count from the earliest sample instead",
                "TYPE_ACCELEROMETER: y is not a number (abc)",
                "TYPE_ACCELEROMETER: y is NaN",
                "TYPE_ACCELEROMETER: 3 or 4 values expected (x y z [accuracy]), found 2",
                "the time (unix_ms) is not a number (x1060)",
                "expected unix_ms<TAB>TYPE<TAB>values, found only \"1080\"",
                "TYPE_ROTATION_VECTOR: the rotation vector's length is 1.2728, more than 1, so it \
                 is not part of a unit quaternion",
                "TYPE_ROTATION_VECTOR: 3 to 5 values expected (x y z [accuracy or w [accuracy]]), \
                 found 6",
                "TYPE_MAGNETIC_FIELD_UNCALIBRATED: 6 or 7 values expected (mx my mz bx by bz \
                 [accuracy]), found 5",
                "TYPE_WAYPOINT: 2 values expected (x y), found 1",
            ]
        );
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
}
