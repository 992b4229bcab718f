//! GetSensorData logs ([`super`]), read line by line by [`GetSensorDataReader`].
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

use nalgebra::Vector2;
use thiserror::Error;

use super::collector::{Clock, Collector, Slot};
use super::fields::{
    check_count, finite, quaternion_from_rotation_vector, split_fields, vector3, TaggedFieldError,
};
use super::{LineReader, GET_SENSOR_DATA, MAX_LINE_BYTES};
use crate::base::angle::wrap_to_2pi;
use crate::io::recording::GnssFix;
use crate::io::{shorten, ImportError, ImportReport};

/// Why a GetSensorData line was not read; the line's diagnostic.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum GetSensorDataLineError {
    /// The line does not start with a tag; `found` is its first field.
    #[error(
        "not a GetSensorData line: it should start with a tag such as ACCE; (found {:?})",
        shorten(.found)
    )]
    NoTag { found: String },
    /// A line led by `tag` (`ACCE`, `GNSS`, …) whose values are not usable.
    #[error("{tag}: {error}")]
    InTag {
        tag: String,
        #[source]
        error: GetSensorDataValueError,
    },
}

/// Why the values of a tagged GetSensorData line are not usable.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum GetSensorDataValueError {
    #[error(transparent)]
    Field(#[from] TaggedFieldError),
    /// A `GNSS` line with `found` fields after the tag, fewer than its layout's `min`.
    #[error(
        "{min} fields after the tag expected \
         (AppTimestamp;[SensorTimeStamp;]Latit;Long;Altitude;Bearing;Accuracy;Speed;…), \
         found {found}"
    )]
    TooFewGnssFields { found: usize, min: usize },
    /// A `POSI` line at 0, 0, which the app writes before the ground truth is known.
    #[error(
        "a position mark without coordinates (0, 0), as the app writes before the \
         ground truth is filled in; skipped"
    )]
    PositionNotFilledIn,
    #[error("latitude {lat_deg} or longitude {lon_deg} is out of range")]
    LatLonOutOfRange { lat_deg: f64, lon_deg: f64 },
}

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
        if let Err(error) = self.read_fields(number, &fields) {
            self.collector.problem(number, error.to_string());
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
    fn read_fields(
        &mut self,
        number: usize,
        fields: &[&str],
    ) -> Result<(), GetSensorDataLineError> {
        let tag = fields.first().copied().unwrap_or_default();
        if !is_tag(tag) {
            return Err(GetSensorDataLineError::NoTag {
                found: tag.to_string(),
            });
        }
        self.read_tagged(number, tag, fields)
            .map_err(|error| GetSensorDataLineError::InTag {
                tag: tag.to_string(),
                error,
            })
    }

    /// A line led by `tag`.
    fn read_tagged(
        &mut self,
        number: usize,
        tag: &str,
        fields: &[&str],
    ) -> Result<(), GetSensorDataValueError> {
        let n_values = fields.len().saturating_sub(1);
        match tag {
            "ACCE" => self.read_vector(number, fields, "ACCE", Slot::Acc, "Acc")?,
            "GYRO" => self.read_vector(number, fields, "GYRO", Slot::Gyro, "Gyr")?,
            "MAGN" => self.read_vector(number, fields, "MAGN", Slot::MagCalibrated, "Mag")?,
            "PRES" => {
                check_count(
                    n_values,
                    3,
                    4,
                    "fields after the tag",
                    "AppTimestamp;SensorTimestamp;Pres(mbar)[;Accuracy]",
                )?;
                let (t, pressure) = self.read_scalar(fields, "PRES", "Pres")?;
                let c = &mut self.collector;
                c.record(Slot::Pressure, "PRES", number, t);
                c.pressure_hpa.push(t, pressure);
            }
            "TEMP" => {
                check_count(
                    n_values,
                    3,
                    4,
                    "fields after the tag",
                    "AppTimestamp;SensorTimestamp;temp(Celsius)[;Accuracy]",
                )?;
                let (t, temp_c) = self.read_scalar(fields, "TEMP", "temp")?;
                let c = &mut self.collector;
                c.record(Slot::Temp, "TEMP", number, t);
                c.temp_c.push(t, temp_c);
            }
            "AHRS" => self.read_ahrs(number, fields)?,
            "GNSS" => self.read_gnss(number, fields)?,
            "POSI" => self.read_posi(number, fields)?,
            other => self.collector.ignore(number, other),
        }
        Ok(())
    }

    /// AppTimestamp, and SensorTimestamp − AppTimestamp kept for the notes.
    fn read_times(&mut self, fields: &[&str], tag: &'static str) -> Result<f64, TaggedFieldError> {
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
    ) -> Result<(), TaggedFieldError> {
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
    ) -> Result<(f64, f64), TaggedFieldError> {
        let value = finite(fields.get(3), name)?;
        let t = self.read_times(fields, tag)?;
        Ok((t, value))
    }

    fn read_ahrs(&mut self, number: usize, fields: &[&str]) -> Result<(), TaggedFieldError> {
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

    fn read_gnss(&mut self, number: usize, fields: &[&str]) -> Result<(), GetSensorDataValueError> {
        let t = number_at(fields, 1, "AppTimestamp")?;
        let third = number_at(fields, 2, "the third field")?;
        // The current app writes the fix time (seconds since 1970) before the latitude,
        // older versions do not; such a time is never within ±90, a latitude always is.
        let lat_idx = if third.abs() > 90.0 { 3 } else { 2 };
        let n_needed = lat_idx + 6;
        if fields.len() < n_needed {
            return Err(GetSensorDataValueError::TooFewGnssFields {
                found: fields.len().saturating_sub(1),
                min: n_needed - 1,
            });
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

    fn read_posi(&mut self, number: usize, fields: &[&str]) -> Result<(), GetSensorDataValueError> {
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
            return Err(GetSensorDataValueError::PositionNotFilledIn);
        }
        check_lat_lon(lat_deg, lon_deg)?;
        let c = &mut self.collector;
        c.record(Slot::RefLatLon, "POSI", number, t);
        c.ref_position_lat_lon_deg
            .push(t, Vector2::new(lat_deg, lon_deg));
        Ok(())
    }
}

fn number_at(fields: &[&str], idx: usize, name: &str) -> Result<f64, TaggedFieldError> {
    finite(fields.get(idx), name)
}

fn check_lat_lon(lat_deg: f64, lon_deg: f64) -> Result<(), GetSensorDataValueError> {
    if lat_deg.abs() > 90.0 || lon_deg.abs() > 180.0 {
        return Err(GetSensorDataValueError::LatLonOutOfRange { lat_deg, lon_deg });
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
    // A four-digit year, as `Date.toString()` writes one (a corrupt header has others).
    let year: i64 = year.parse().ok().filter(|year| (0..=9999).contains(year))?;
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
    let days = crate::base::calendar::days_from_civil(year, month, day) as f64;
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
    use nalgebra::Vector3;

    use super::super::tests::{
        assert_close, assert_vector_close, gsd, yaw_deg, GET_SENSOR_DATA_SAMPLE,
    };
    use super::*;
    use crate::io::axes::PhoneMount;

    #[test]
    fn get_sensor_data_golden_lines_of_every_tag() {
        let report = gsd(GET_SENSOR_DATA_SAMPLE).expect("readable");
        assert!(report.diagnostics.is_empty(), "{:?}", report.diagnostics);
        assert_eq!(report.format, GET_SENSOR_DATA);
        assert_eq!(report.n_data_lines, 17);
        let r = &report.recording;
        // GYRO is Android's TYPE_GYROSCOPE.
        assert_eq!(r.gyro_bias, crate::io::recording::GyroBias::RemovedByDevice);

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
        let messages = report.diagnostics.messages();
        // Word for word (the wording users see).
        assert_eq!(
            messages,
            [
                "ACCE: Acc_Y is not a number (oops)",
                "GYRO: 5 or 6 fields after the tag expected \
                 (AppTimestamp;SensorTimestamp;Gyr_X(rad/s);Gyr_Y;Gyr_Z[;Accuracy]), found 4",
                "MAGN: Mag_X is inf",
                "not a GetSensorData line: it should start with a tag such as ACCE; (found \
                 \"hello world\")",
                "PRES: 3 or 4 fields after the tag expected \
                 (AppTimestamp;SensorTimestamp;Pres(mbar)[;Accuracy]), found 2",
                "AHRS: the rotation vector's length is 1.5588, more than 1, so it is not part of \
                 a unit quaternion",
                "GNSS: latitude 95 or longitude -3.48 is out of range",
                "GNSS: 8 fields after the tag expected \
                 (AppTimestamp;[SensorTimeStamp;]Latit;Long;Altitude;Bearing;Accuracy;Speed;…), \
                 found 3",
                "POSI: a position mark without coordinates (0, 0), as the app writes before the \
                 ground truth is filled in; skipped",
            ]
        );
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
}
