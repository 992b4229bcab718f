//! Topics to streams: which fields of which PX4 uORB topics are read, and how.
//!
//! Times are each message's `timestamp` (µs since boot) / 1e6. `sensor_combined`
//! carries the gyro at `timestamp` and the accelerometer (and, in old logs, the
//! magnetometer) at `timestamp + *_timestamp_relative`, where `i32::MAX` means "no
//! sample" (`sensor_combined.msg`: `RELATIVE_TIMESTAMP_INVALID`).

use std::collections::BTreeMap;

use nalgebra::{UnitQuaternion, Vector3};

use super::parse::{layout, FieldAt, Layout};
use super::UlogReader;
use crate::io::recording::{Attitude, GnssFix, Stream};

/// `sensor_combined.msg`: a relative timestamp with no sample behind it.
const RELATIVE_TIMESTAMP_INVALID: f64 = i32::MAX as f64;

/// The topics read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Topic {
    SensorCombined,
    SensorMag,
    VehicleMagnetometer,
    VehicleAttitude,
    VehicleGpsPosition,
    SensorGps,
}

impl Topic {
    fn from_name(name: &str) -> Option<Topic> {
        Some(match name {
            "sensor_combined" => Topic::SensorCombined,
            "sensor_mag" => Topic::SensorMag,
            "vehicle_magnetometer" => Topic::VehicleMagnetometer,
            "vehicle_attitude" => Topic::VehicleAttitude,
            "vehicle_gps_position" => Topic::VehicleGpsPosition,
            "sensor_gps" => Topic::SensorGps,
            _ => return None,
        })
    }
}

impl Topic {
    /// The fields read, in the order of the `*_AT` indices below.
    fn field_names(self) -> &'static [&'static str] {
        match self {
            Topic::SensorCombined => &[
                "gyro_rad",
                "accelerometer_m_s2",
                "accelerometer_timestamp_relative",
                "magnetometer_ga",
                "magnetometer_timestamp_relative",
            ],
            Topic::SensorMag => &["x", "y", "z", "device_id"],
            Topic::VehicleMagnetometer => &["magnetometer_ga", "device_id"],
            Topic::VehicleAttitude => &["q"],
            Topic::VehicleGpsPosition | Topic::SensorGps => &[
                "fix_type",
                "latitude_deg",
                "lat",
                "longitude_deg",
                "lon",
                "altitude_msl_m",
                "alt",
                "vel_m_s",
                "cog_rad",
                "eph",
                "time_utc_usec",
            ],
        }
    }
}

/// A subscription (`A`): its topic's layout; `topic` is `None` for topics not read.
#[derive(Debug, Clone)]
pub(super) struct Subscription {
    pub topic: Option<Topic>,
    pub multi_id: u8,
    pub layout: Layout,
    timestamp: Option<FieldAt>,
    /// Where each of the topic's [`Topic::field_names`] lies, found once.
    fields: Vec<Option<FieldAt>>,
}

impl Subscription {
    fn field(&self, idx: usize) -> Option<&FieldAt> {
        self.fields.get(idx).and_then(Option::as_ref)
    }

    fn scalar(&self, idx: usize, data: &[u8]) -> Option<f64> {
        self.field(idx)?.read(data, 0)
    }
}

/// One magnetometer topic instance as logged, gauss, in the topic's own axes.
#[derive(Debug, Clone, Default)]
pub(super) struct MagSeries {
    pub device_id: Option<u32>,
    /// Samples whose device id differed from the first one's, not kept.
    pub n_other_device: usize,
    /// Samples repeated from the message before (same sample time), not kept: old
    /// `sensor_combined` repeats its last magnetometer sample at the gyro's rate.
    pub n_repeated: usize,
    last_t_us: Option<i64>,
    pub field_ga: Stream<Vector3<f64>>,
}

/// What the data messages gave, before [`super::finish`].
#[derive(Debug, Clone, Default)]
pub(super) struct Collected {
    pub gyro_radps: Stream<Vector3<f64>>,
    pub acc_mps2: Stream<Vector3<f64>>,
    /// `sensor_combined.magnetometer_ga` (old logs): calibrated, body axes.
    pub combined_mag: MagSeries,
    pub sensor_mag: BTreeMap<u8, MagSeries>,
    pub vehicle_mag: BTreeMap<u8, MagSeries>,
    pub attitude: Stream<Attitude>,
    /// `vehicle_gps_position` [0] and `sensor_gps` [1].
    pub gnss: [Stream<GnssFix>; 2],
    /// (boot time s, Unix time s) of each source's first fix with a UTC time.
    pub first_utc: [Option<(f64, f64)>; 2],
    pub n_fixes_without_position: usize,
    /// Instances other than 0 of single-instance topics (combined, attitude, GNSS).
    pub n_other_instances: usize,
}

fn vector3(field: Option<&FieldAt>, data: &[u8]) -> Option<Vector3<f64>> {
    let field = field?;
    Some(Vector3::new(
        field.read(data, 0)?,
        field.read(data, 1)?,
        field.read(data, 2)?,
    ))
}

/// µs to s.
fn seconds(t_us: i64) -> f64 {
    t_us as f64 / 1e6
}

impl UlogReader {
    /// A subscription (`A`): `u8 multi_id, u16 msg_id, topic name`.
    pub(super) fn subscribe(&mut self, payload: &[u8], at: u64) {
        let (Some(&multi_id), Some(msg_id)) = (
            payload.first(),
            payload
                .get(1..3)
                .map(|bytes| u16::from_le_bytes([bytes[0], bytes[1]])),
        ) else {
            self.diagnostics.push(
                None,
                format!("byte {at}: subscription message too short, skipped"),
            );
            return;
        };
        let name = String::from_utf8_lossy(payload.get(3..).unwrap_or_default());
        let name = name.trim_end_matches('\0');
        let Some(layout) = layout(&self.formats, name) else {
            self.diagnostics.push(
                None,
                format!("byte {at}: subscription to {name}, whose format is missing or broken"),
            );
            return;
        };
        let topic = Topic::from_name(name);
        let timestamp = layout.fields.get("timestamp").copied();
        let fields = topic
            .map(Topic::field_names)
            .unwrap_or_default()
            .iter()
            .map(|field_name| layout.fields.get(*field_name).copied())
            .collect();
        self.subscriptions.insert(
            msg_id,
            Subscription {
                topic,
                multi_id,
                layout,
                timestamp,
                fields,
            },
        );
    }

    /// A data message (`D`): `u16 msg_id`, then the topic's struct.
    pub(super) fn data(&mut self, payload: &[u8], at: u64) {
        let Some(msg_id) = payload
            .get(..2)
            .map(|bytes| u16::from_le_bytes([bytes[0], bytes[1]]))
        else {
            return;
        };
        let Some(sub) = self.subscriptions.get(&msg_id) else {
            if !self.unknown_msg_ids.contains(&msg_id) && self.unknown_msg_ids.len() < 64 {
                self.unknown_msg_ids.push(msg_id);
                self.diagnostics.push(
                    None,
                    format!("byte {at}: data for message id {msg_id}, which has no subscription"),
                );
            }
            return;
        };
        let Some(topic) = sub.topic else { return };
        let data = &payload[2..];
        if data.len() < sub.layout.min_bytes {
            self.diagnostics.push(
                None,
                format!(
                    "byte {at}: data message of {} bytes, its format needs {}; skipped",
                    data.len(),
                    sub.layout.min_bytes
                ),
            );
            return;
        }
        let Some(t_us) = sub.timestamp.and_then(|field| field.read_u64(data)) else {
            return;
        };
        let t_us = t_us as i64;
        let t_s = seconds(t_us);
        let multi_id = sub.multi_id;
        let collected = &mut self.collected;
        let single = |collected: &mut Collected| {
            if multi_id != 0 {
                collected.n_other_instances += 1;
            }
            multi_id == 0
        };
        match topic {
            Topic::SensorCombined if single(collected) => {
                sensor_combined(sub, data, t_us, collected);
            }
            Topic::SensorMag => sensor_mag(sub, data, t_us, collected),
            Topic::VehicleMagnetometer => vehicle_magnetometer(sub, data, t_us, collected),
            Topic::VehicleAttitude if single(collected) => {
                vehicle_attitude(sub, data, t_s, collected);
            }
            Topic::VehicleGpsPosition | Topic::SensorGps if single(collected) => {
                let source = usize::from(topic == Topic::SensorGps);
                gnss_fix(sub, data, t_s, source, collected);
            }
            _ => {}
        }
    }
}

/// One `sensor_combined` message (its instance 0): the gyro at its time, the
/// accelerometer and (old logs) the magnetometer at their relative timestamps.
fn sensor_combined(sub: &Subscription, data: &[u8], t_us: i64, collected: &mut Collected) {
    const GYRO_AT: usize = 0;
    const ACC_AT: usize = 1;
    const ACC_RELATIVE_AT: usize = 2;
    const MAG_AT: usize = 3;
    const MAG_RELATIVE_AT: usize = 4;
    let t_s = seconds(t_us);
    if let Some(gyro) = vector3(sub.field(GYRO_AT), data) {
        collected.gyro_radps.push(t_s, gyro);
    }
    // In whole µs, so that a sample repeated by the next message has the
    // very same time.
    let relative = |idx: usize| {
        sub.scalar(idx, data)
            .filter(|&dt| dt != RELATIVE_TIMESTAMP_INVALID)
            // A corrupt timestamp near the end of i64 has no sample time.
            .and_then(|dt_us| t_us.checked_add(dt_us as i64))
    };
    if let (Some(acc), Some(acc_t_us)) =
        (vector3(sub.field(ACC_AT), data), relative(ACC_RELATIVE_AT))
    {
        collected.acc_mps2.push(seconds(acc_t_us), acc);
    }
    if let (Some(mag), Some(mag_t_us)) =
        (vector3(sub.field(MAG_AT), data), relative(MAG_RELATIVE_AT))
    {
        collected.combined_mag.push(mag_t_us, mag, None);
    }
}

/// One `sensor_mag` message: a compass's field (`x`, `y`, `z`) and its device id, in
/// the series of its instance.
fn sensor_mag(sub: &Subscription, data: &[u8], t_us: i64, collected: &mut Collected) {
    let field = (|| {
        Some(Vector3::new(
            sub.scalar(0, data)?,
            sub.scalar(1, data)?,
            sub.scalar(2, data)?,
        ))
    })();
    let device_id = sub.scalar(3, data).map(|id| id as u32);
    if let Some(field) = field {
        let series = collected.sensor_mag.entry(sub.multi_id).or_default();
        series.push(t_us, field, device_id);
    }
}

/// One `vehicle_magnetometer` message: the calibrated field and its device id, in the
/// series of its instance.
fn vehicle_magnetometer(sub: &Subscription, data: &[u8], t_us: i64, collected: &mut Collected) {
    let device_id = sub.scalar(1, data).map(|id| id as u32);
    if let Some(field) = vector3(sub.field(0), data) {
        let series = collected.vehicle_mag.entry(sub.multi_id).or_default();
        series.push(t_us, field, device_id);
    }
}

/// One `vehicle_attitude` message (its instance 0): roll, pitch and yaw from its
/// quaternion, unless the quaternion is far from unit length.
fn vehicle_attitude(sub: &Subscription, data: &[u8], t_s: f64, collected: &mut Collected) {
    let q = sub.field(0);
    let components = (0..4)
        .map(|idx| q.and_then(|q| q.read(data, idx)))
        .collect::<Option<Vec<f64>>>();
    if let Some(&[w, x, y, z]) = components.as_deref() {
        let norm = (w * w + x * x + y * y + z * z).sqrt();
        if norm.is_finite() && norm > 0.5 {
            // q rotates body FRD into NED; Euler ZYX gives roll, pitch and
            // yaw clockwise from north.
            let q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(w, x, y, z));
            let (roll_rad, pitch_rad, yaw_rad) = q.euler_angles();
            collected.attitude.push(
                t_s,
                Attitude {
                    roll_rad,
                    pitch_rad,
                    yaw_rad: Some(yaw_rad),
                },
            );
        }
    }
}

impl MagSeries {
    /// Adds a sample unless it repeats the last one's time, or comes from another
    /// device than the first sample.
    fn push(&mut self, t_us: i64, field_ga: Vector3<f64>, device_id: Option<u32>) {
        if self.field_ga.is_empty() {
            self.device_id = device_id;
        }
        if device_id != self.device_id {
            self.n_other_device += 1;
        } else if self.last_t_us == Some(t_us) {
            self.n_repeated += 1;
        } else {
            self.last_t_us = Some(t_us);
            self.field_ga.push(seconds(t_us), field_ga);
        }
    }
}

/// One GNSS fix (`vehicle_gps_position.msg`, `sensor_gps.msg`): lat/lon in 1e-7 deg
/// (or `latitude_deg` doubles in newer logs), alt in mm (or `altitude_msl_m`), fixes
/// below 2D (`fix_type` < 2) skipped; `time_utc_usec` is µs since 1970, 0 if unknown.
fn gnss_fix(sub: &Subscription, data: &[u8], t_s: f64, source: usize, collected: &mut Collected) {
    let value = |idx: usize| sub.scalar(idx, data);
    if value(0).is_some_and(|fix_type| fix_type < 2.0) {
        collected.n_fixes_without_position += 1;
        return;
    }
    let degrees = |double: usize, scaled: usize| {
        value(double).or_else(|| value(scaled).map(|deg_e7| deg_e7 * 1e-7))
    };
    let fix = GnssFix {
        lat_deg: degrees(1, 2),
        lon_deg: degrees(3, 4),
        alt_m: value(5).or_else(|| value(6).map(|alt_mm| alt_mm / 1e3)),
        speed_mps: value(7),
        course_rad: value(8),
        hacc_m: value(9),
    };
    if let Some(utc_us) = value(10).filter(|&utc_us| utc_us > 0.0) {
        collected.first_utc[source].get_or_insert((t_s, utc_us / 1e6));
    }
    collected.gnss[source].push(t_s, fix);
}
