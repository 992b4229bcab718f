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
use crate::recording::{Attitude, GnssFix, Stream};

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

/// A subscription (`A`): its topic's layout; `topic` is `None` for topics not read.
#[derive(Debug, Clone)]
pub(super) struct Subscription {
    pub topic: Option<Topic>,
    pub multi_id: u8,
    pub layout: Layout,
    timestamp: Option<FieldAt>,
}

/// One magnetometer topic instance as logged, gauss, in the topic's own axes.
#[derive(Debug, Clone, Default)]
pub(super) struct MagSeries {
    pub device_id: Option<u32>,
    /// Samples whose device id differed from the first one's, not kept.
    pub n_other_device: usize,
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

fn scalar(layout: &Layout, name: &str, data: &[u8]) -> Option<f64> {
    layout.fields.get(name)?.read(data, 0)
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
        let timestamp = layout.fields.get("timestamp").copied();
        self.subscriptions.insert(
            msg_id,
            Subscription {
                topic: Topic::from_name(name),
                multi_id,
                layout,
                timestamp,
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
        let t_s = t_us as f64 / 1e6;
        let layout = &sub.layout;
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
                if let Some(gyro) = vector3(layout.fields.get("gyro_rad"), data) {
                    collected.gyro_radps.push(t_s, gyro);
                }
                let relative = |name: &str| {
                    scalar(layout, name, data).filter(|&dt| dt != RELATIVE_TIMESTAMP_INVALID)
                };
                if let (Some(acc), Some(dt_us)) = (
                    vector3(layout.fields.get("accelerometer_m_s2"), data),
                    relative("accelerometer_timestamp_relative"),
                ) {
                    collected.acc_mps2.push(t_s + dt_us / 1e6, acc);
                }
                if let (Some(mag), Some(dt_us)) = (
                    vector3(layout.fields.get("magnetometer_ga"), data),
                    relative("magnetometer_timestamp_relative"),
                ) {
                    collected.combined_mag.field_ga.push(t_s + dt_us / 1e6, mag);
                }
            }
            Topic::SensorMag | Topic::VehicleMagnetometer => {
                let field = match topic {
                    Topic::SensorMag => (|| {
                        Some(Vector3::new(
                            scalar(layout, "x", data)?,
                            scalar(layout, "y", data)?,
                            scalar(layout, "z", data)?,
                        ))
                    })(),
                    _ => vector3(layout.fields.get("magnetometer_ga"), data),
                };
                let device_id = scalar(layout, "device_id", data).map(|id| id as u32);
                let series = match topic {
                    Topic::SensorMag => collected.sensor_mag.entry(multi_id).or_default(),
                    _ => collected.vehicle_mag.entry(multi_id).or_default(),
                };
                if let Some(field) = field {
                    if series.field_ga.is_empty() {
                        series.device_id = device_id;
                    }
                    if device_id == series.device_id {
                        series.field_ga.push(t_s, field);
                    } else {
                        series.n_other_device += 1;
                    }
                }
            }
            Topic::VehicleAttitude if single(collected) => {
                let q = layout.fields.get("q");
                let components = (0..4)
                    .map(|idx| q.and_then(|q| q.read(data, idx)))
                    .collect::<Option<Vec<f64>>>();
                if let Some(&[w, x, y, z]) = components.as_deref() {
                    let norm = (w * w + x * x + y * y + z * z).sqrt();
                    if norm.is_finite() && norm > 0.5 {
                        // q rotates body FRD into NED; Euler ZYX gives roll, pitch and
                        // yaw clockwise from north.
                        let q =
                            UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(w, x, y, z));
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
            Topic::VehicleGpsPosition | Topic::SensorGps if single(collected) => {
                let source = usize::from(topic == Topic::SensorGps);
                gnss_fix(layout, data, t_s, source, collected);
            }
            _ => {}
        }
    }
}

/// One GNSS fix (`vehicle_gps_position.msg`, `sensor_gps.msg`): lat/lon in 1e-7 deg
/// (or `latitude_deg` doubles in newer logs), alt in mm (or `altitude_msl_m`), fixes
/// below 2D (`fix_type` < 2) skipped; `time_utc_usec` is µs since 1970, 0 if unknown.
fn gnss_fix(layout: &Layout, data: &[u8], t_s: f64, source: usize, collected: &mut Collected) {
    if scalar(layout, "fix_type", data).is_some_and(|fix_type| fix_type < 2.0) {
        collected.n_fixes_without_position += 1;
        return;
    }
    let degrees = |double: &str, scaled: &str| {
        scalar(layout, double, data).or_else(|| scalar(layout, scaled, data).map(|v| v * 1e-7))
    };
    let fix = GnssFix {
        lat_deg: degrees("latitude_deg", "lat"),
        lon_deg: degrees("longitude_deg", "lon"),
        alt_m: scalar(layout, "altitude_msl_m", data)
            .or_else(|| scalar(layout, "alt", data).map(|alt_mm| alt_mm / 1e3)),
        speed_mps: scalar(layout, "vel_m_s", data),
        course_rad: scalar(layout, "cog_rad", data),
        hacc_m: scalar(layout, "eph", data),
    };
    if let Some(utc_us) = scalar(layout, "time_utc_usec", data).filter(|&utc_us| utc_us > 0.0) {
        collected.first_utc[source].get_or_insert((t_s, utc_us / 1e6));
    }
    collected.gnss[source].push(t_s, fix);
}
