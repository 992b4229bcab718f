//! The messages a DataFlash log is read for, binary or text alike: which columns of
//! which message type become which stream ([`Plan`]), and the [`Collector`] that gathers
//! them. Column names are ArduPilot's (`libraries/AP_Logger/LogStructure.h` and the
//! older `DataFlash/LogStructure.h`): `TimeUS` (µs since boot) in logs from 2015 on,
//! `TimeMS` (ms since boot) before, except in the old `GPS` message, where `TimeMS` is
//! the GPS time of week and `T` the boot time.

use nalgebra::Vector3;

use super::format::{FieldType, MessageFormat, NumberKind};
use crate::io::recording::{Attitude, GnssFix, Recording, Stream};

/// Reads a field of one message, binary or text.
pub trait Fields {
    /// The number in column `column` (scaled as the format says); `None` when it is not
    /// a number.
    fn number(&self, column: usize) -> Option<f64>;
    /// The text in column `column`.
    fn text(&self, column: usize) -> Option<String>;
}

/// Where a message's boot time is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Time {
    column: usize,
    s_per_unit: f64,
}

impl Time {
    /// `TimeUS`, else `TimeMS` (for everything but the old GPS message).
    fn of(format: &MessageFormat) -> Option<Time> {
        if let Some(column) = format.column("TimeUS") {
            return Some(Time {
                column,
                s_per_unit: 1e-6,
            });
        }
        format.column("TimeMS").map(|column| Time {
            column,
            s_per_unit: 1e-3,
        })
    }

    fn read(self, fields: &dyn Fields) -> Option<f64> {
        fields
            .number(self.column)
            .map(|value| value * self.s_per_unit)
            .filter(|t_s| t_s.is_finite())
    }
}

fn columns3(format: &MessageFormat, names: [&str; 3]) -> Option<[usize; 3]> {
    Some([
        format.column(names[0])?,
        format.column(names[1])?,
        format.column(names[2])?,
    ])
}

fn vector(fields: &dyn Fields, columns: [usize; 3]) -> Option<Vector3<f64>> {
    let vector = Vector3::new(
        fields.number(columns[0])?,
        fields.number(columns[1])?,
        fields.number(columns[2])?,
    );
    vector
        .iter()
        .all(|value| value.is_finite())
        .then_some(vector)
}

/// The instance of a sensor message: its `I` column where it has one (logs from 2019 on
/// log every instance under one name), else the digit its name ends in (`MAG2` → 1).
fn instance_of(format: &MessageFormat, base: &str) -> Option<Instance> {
    let suffix = format.name.strip_prefix(base)?;
    if let Some(column) = format.column("I") {
        return suffix.is_empty().then_some(Instance::Column(column));
    }
    match suffix {
        "" => Some(Instance::Fixed(0)),
        digit => digit
            .parse::<usize>()
            .ok()
            .filter(|n| (2..=9).contains(n))
            .map(|n| Instance::Fixed(n - 1)),
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Instance {
    Fixed(usize),
    Column(usize),
}

impl Instance {
    fn read(self, fields: &dyn Fields) -> Option<usize> {
        match self {
            Instance::Fixed(instance) => Some(instance),
            Instance::Column(column) => fields
                .number(column)
                .filter(|value| (0.0..16.0).contains(value))
                .map(|value| value as usize),
        }
    }
}

/// What a message type is read for.
#[derive(Debug, Clone, PartialEq)]
pub enum Plan {
    Mag {
        time: Time,
        instance: Instance,
        field: [usize; 3],
        offsets: Option<[usize; 3]>,
        motor: Option<[usize; 3]>,
    },
    Imu {
        time: Time,
        instance: Instance,
        gyro: [usize; 3],
        acc: [usize; 3],
    },
    Gps {
        boot: Time,
        instance: Instance,
        status: usize,
        week_ms: Option<usize>,
        week: Option<usize>,
        lat_lon: [usize; 2],
        alt: Option<usize>,
        speed: Option<usize>,
        course: Option<usize>,
    },
    Attitude {
        time: Time,
        roll_pitch_yaw: [usize; 3],
    },
    Param {
        name: usize,
        value: usize,
    },
    /// The battery current: `CURR` (centiamperes in integer columns, before 2016),
    /// `BAT` (amperes); the first battery only.
    Current {
        time: Time,
        instance: Option<usize>,
        current: usize,
        a_per_unit: f64,
    },
    Message {
        text: usize,
    },
    Ignored,
}

impl Plan {
    /// The plan for a message type, from its name and columns.
    pub fn of(format: &MessageFormat) -> Plan {
        Self::try_of(format).unwrap_or(Plan::Ignored)
    }

    fn try_of(format: &MessageFormat) -> Option<Plan> {
        let name = format.name.as_str();
        if let Some(instance) = instance_of(format, "MAG") {
            return Some(Plan::Mag {
                time: Time::of(format)?,
                instance,
                field: columns3(format, ["MagX", "MagY", "MagZ"])?,
                offsets: columns3(format, ["OfsX", "OfsY", "OfsZ"]),
                motor: columns3(format, ["MOfsX", "MOfsY", "MOfsZ"])
                    .or_else(|| columns3(format, ["MOX", "MOY", "MOZ"])),
            });
        }
        if let Some(instance) = instance_of(format, "IMU") {
            return Some(Plan::Imu {
                time: Time::of(format)?,
                instance,
                gyro: columns3(format, ["GyrX", "GyrY", "GyrZ"])?,
                acc: columns3(format, ["AccX", "AccY", "AccZ"])?,
            });
        }
        if let Some(instance) = instance_of(format, "GPS") {
            // Old logs: TimeMS is the GPS time of week, T the boot time in ms.
            let (boot, week_ms, week) = match (format.column("TimeUS"), format.column("T")) {
                (Some(_), _) => (
                    Time::of(format)?,
                    format.column("GMS"),
                    format.column("GWk"),
                ),
                (None, Some(column)) => (
                    Time {
                        column,
                        s_per_unit: 1e-3,
                    },
                    format.column("TimeMS"),
                    format.column("Week"),
                ),
                (None, None) => return None,
            };
            return Some(Plan::Gps {
                boot,
                instance,
                status: format.column("Status")?,
                week_ms,
                week,
                lat_lon: [format.column("Lat")?, format.column("Lng")?],
                alt: format.column("Alt"),
                speed: format.column("Spd"),
                course: format.column("GCrs"),
            });
        }
        match name {
            "ATT" => Some(Plan::Attitude {
                time: Time::of(format)?,
                roll_pitch_yaw: columns3(format, ["Roll", "Pitch", "Yaw"])?,
            }),
            "PARM" => Some(Plan::Param {
                name: format.column("Name")?,
                value: format.column("Value")?,
            }),
            "CURR" | "BAT" => {
                let current = format.column("Curr")?;
                let is_integer = format
                    .fields
                    .as_ref()
                    .and_then(|fields| fields.get(current))
                    .is_some_and(|(field, _)| {
                        matches!(
                            field,
                            FieldType::Number {
                                kind: NumberKind::Signed | NumberKind::Unsigned,
                                scale,
                                ..
                            } if *scale == 1.0
                        )
                    });
                Some(Plan::Current {
                    time: Time::of(format)?,
                    instance: format.column("Inst").or_else(|| format.column("I")),
                    current,
                    a_per_unit: if is_integer { 0.01 } else { 1.0 },
                })
            }
            "MSG" => Some(Plan::Message {
                text: format.column("Message")?,
            }),
            _ => None,
        }
    }
}

/// One compass's samples as logged, with the offsets logged beside them.
#[derive(Debug, Clone, Default)]
pub struct MagTrack {
    pub instance: usize,
    pub source: String,
    pub t_s: Vec<f64>,
    /// The field as logged (mG).
    pub field_mg: Vec<Vector3<f64>>,
    /// The offsets applied to it (mG), where the message logs them.
    pub offsets_mg: Vec<Vector3<f64>>,
    /// The motor compensation added to it (mG), where the message logs it.
    pub motor_mg: Vec<Vector3<f64>>,
    /// Readings of exactly (0, 0, 0), left out.
    pub n_zero_readings: usize,
}

/// What the messages of a log gave, before the end of the log.
#[derive(Debug, Default)]
pub struct Collector {
    pub recording: Recording,
    pub mags: Vec<MagTrack>,
    /// Parameters in force (the first value of each, in the log's order) and changed.
    pub params: Vec<(String, f64)>,
    pub params_changed: Vec<(String, f64)>,
    pub firmware: Option<String>,
    /// Samples read per message name, in the order first met.
    pub counts: Vec<(String, usize)>,
    /// IMU and GPS samples of other instances than the first, not used.
    pub n_other_instances: usize,
    pub n_gps_without_fix: usize,
    /// The GPS clock's Unix time minus the boot time, from the first 3D fix with a week.
    pub utc_minus_boot_s: Option<f64>,
    /// The first battery's current (A).
    pub current_a: Stream<f64>,
}

/// Seconds between the Unix and GPS epochs (1970-01-01 to 1980-01-06).
const GPS_EPOCH_UNIX_S: f64 = 315_964_800.0;
const SECONDS_PER_WEEK: f64 = 604_800.0;

/// GPS time minus UTC (leap seconds) at a GPS time given as Unix seconds: 15 s from
/// 2009, 16 from mid-2012, 17 from mid-2015, 18 from 2017 (IERS Bulletin C).
fn leap_seconds(gps_as_unix_s: f64) -> f64 {
    const STEPS: [(f64, f64); 4] = [
        (1_230_768_000.0, 15.0),
        (1_341_100_800.0, 16.0),
        (1_435_708_800.0, 17.0),
        (1_483_228_800.0, 18.0),
    ];
    STEPS
        .iter()
        .rev()
        .find(|(from_s, _)| gps_as_unix_s >= *from_s)
        .map_or(14.0, |&(_, leap)| leap)
}

impl Collector {
    fn count(&mut self, name: &str) {
        match self.counts.iter_mut().find(|(known, _)| known == name) {
            Some((_, count)) => *count += 1,
            None => self.counts.push((name.to_string(), 1)),
        }
    }

    /// Reads one message of type `name` by its plan.
    pub fn read(&mut self, name: &str, plan: &Plan, fields: &dyn Fields) {
        let used = match *plan {
            Plan::Mag {
                time,
                instance,
                field,
                offsets,
                motor,
            } => self.read_mag(name, time, instance, field, offsets, motor, fields),
            Plan::Imu {
                time,
                instance,
                gyro,
                acc,
            } => match (time.read(fields), instance.read(fields)) {
                (Some(t_s), Some(0)) => {
                    if let (Some(gyro), Some(acc)) = (vector(fields, gyro), vector(fields, acc)) {
                        self.recording.gyro_in_body_radps.push(t_s, gyro);
                        self.recording.acc_in_body_mps2.push(t_s, acc);
                        true
                    } else {
                        false
                    }
                }
                (Some(_), Some(_)) => {
                    self.n_other_instances += 1;
                    false
                }
                _ => false,
            },
            Plan::Gps { .. } => self.read_gps(plan, fields),
            Plan::Attitude {
                time,
                roll_pitch_yaw,
            } => match (time.read(fields), vector(fields, roll_pitch_yaw)) {
                (Some(t_s), Some(degrees)) => {
                    let radians = degrees.map(f64::to_radians);
                    self.recording.autopilot_heading_rad.push(t_s, radians.z);
                    self.recording.attitude.push(
                        t_s,
                        Attitude {
                            roll_rad: radians.x,
                            pitch_rad: radians.y,
                            yaw_rad: Some(radians.z),
                        },
                    );
                    true
                }
                _ => false,
            },
            Plan::Param { name, value } => match (fields.text(name), fields.number(value)) {
                (Some(param), Some(value)) if !param.is_empty() => {
                    match self.params.iter().find(|(known, _)| *known == param) {
                        None => self.params.push((param, value)),
                        Some(&(_, first)) if first.to_bits() != value.to_bits() => {
                            self.params_changed.retain(|(known, _)| *known != param);
                            self.params_changed.push((param, value));
                        }
                        Some(_) => {}
                    }
                    true
                }
                _ => false,
            },
            Plan::Current {
                time,
                instance,
                current,
                a_per_unit,
            } => {
                let first = instance.is_none_or(|column| fields.number(column) == Some(0.0));
                match (time.read(fields), fields.number(current)) {
                    (Some(t_s), Some(value)) if first && value.is_finite() => {
                        self.current_a.push(t_s, value * a_per_unit);
                        true
                    }
                    _ => false,
                }
            }
            Plan::Message { text } => {
                if let Some(text) = fields.text(text) {
                    let is_firmware = text.contains(" V") || text.starts_with('V');
                    if self.firmware.is_none() && is_firmware {
                        self.firmware = Some(text);
                    }
                }
                false
            }
            Plan::Ignored => false,
        };
        if used {
            self.count(name);
        }
    }

    #[allow(clippy::too_many_arguments)]
    fn read_mag(
        &mut self,
        name: &str,
        time: Time,
        instance: Instance,
        field: [usize; 3],
        offsets: Option<[usize; 3]>,
        motor: Option<[usize; 3]>,
        fields: &dyn Fields,
    ) -> bool {
        let (Some(t_s), Some(instance), Some(field)) = (
            time.read(fields),
            instance.read(fields),
            vector(fields, field),
        ) else {
            return false;
        };
        let track = match self
            .mags
            .iter()
            .position(|track| track.instance == instance)
        {
            Some(idx) => &mut self.mags[idx],
            None => {
                self.mags.push(MagTrack {
                    instance,
                    source: name.to_string(),
                    ..MagTrack::default()
                });
                let last = self.mags.len() - 1;
                &mut self.mags[last]
            }
        };
        let zero = Vector3::zeros();
        // ArduPilot logs a field of exactly zero while the compass reads nothing: no
        // measurement (the Earth's field is never zero), left out and counted.
        if field == zero {
            track.n_zero_readings += 1;
            return false;
        }
        track.t_s.push(t_s);
        track.field_mg.push(field);
        if let Some(columns) = offsets {
            track
                .offsets_mg
                .push(vector(fields, columns).unwrap_or(zero));
        }
        if let Some(columns) = motor {
            track.motor_mg.push(vector(fields, columns).unwrap_or(zero));
        }
        true
    }

    fn read_gps(&mut self, plan: &Plan, fields: &dyn Fields) -> bool {
        let Plan::Gps {
            boot,
            instance,
            status,
            week_ms,
            week,
            lat_lon,
            alt,
            speed,
            course,
        } = *plan
        else {
            return false;
        };
        let (Some(t_s), Some(instance)) = (boot.read(fields), instance.read(fields)) else {
            return false;
        };
        if instance != 0 {
            self.n_other_instances += 1;
            return false;
        }
        // ArduPilot's fix status: 3 is a 3D fix, 4-6 better ones.
        if fields.number(status).is_none_or(|status| status < 3.0) {
            self.n_gps_without_fix += 1;
            return false;
        }
        let number = |column: Option<usize>| column.and_then(|c| fields.number(c));
        let (Some(lat_deg), Some(lon_deg)) = (fields.number(lat_lon[0]), fields.number(lat_lon[1]))
        else {
            return false;
        };
        if self.utc_minus_boot_s.is_none() {
            if let (Some(week_ms), Some(week)) = (number(week_ms), number(week)) {
                if week > 0.0 {
                    let gps_as_unix_s = GPS_EPOCH_UNIX_S + week * SECONDS_PER_WEEK + week_ms * 1e-3;
                    let utc_s = gps_as_unix_s - leap_seconds(gps_as_unix_s);
                    self.utc_minus_boot_s = Some(utc_s - t_s);
                }
            }
        }
        self.recording.gnss.push(
            t_s,
            GnssFix {
                lat_deg: Some(lat_deg),
                lon_deg: Some(lon_deg),
                alt_m: number(alt),
                speed_mps: number(speed),
                course_rad: number(course).map(f64::to_radians),
                hacc_m: None,
            },
        );
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn leap_seconds_follow_the_bulletins() {
        // 2015-10-01 (log171's year) had 17; 2023 has 18; 2010 had 15.
        assert_eq!(leap_seconds(1_443_657_600.0), 17.0);
        assert_eq!(leap_seconds(1_700_000_000.0), 18.0);
        assert_eq!(leap_seconds(1_270_000_000.0), 15.0);
    }

    #[test]
    fn instances_from_names_and_columns() {
        let old = MessageFormat::new("MAG2", 25, "Ihhhhhhhhh", "TimeMS,MagX,MagY,MagZ");
        assert_eq!(instance_of(&old, "MAG"), Some(Instance::Fixed(1)));
        let new = MessageFormat::new("MAG", 40, "QBhhh", "TimeUS,I,MagX,MagY,MagZ");
        assert_eq!(instance_of(&new, "MAG"), Some(Instance::Column(1)));
        let other = MessageFormat::new("MAGX", 25, "I", "TimeMS");
        assert_eq!(instance_of(&other, "MAG"), None);
    }
}
