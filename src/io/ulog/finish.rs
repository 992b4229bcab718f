//! The end of a ULog input: the unfinished last message reported, every stream sorted,
//! the compasses' calibration applied or undone ([`super::compass`]), the primary
//! compass's raw field put in the recording, and the notes written.

use nalgebra::{Matrix3, Vector3};

use super::compass::calibration;
use super::topics::{Collected, MagSeries};
use super::{looks_like, UlogReader, MAGIC, ULOG};
use crate::io::autopilot::{Autopilot, AutopilotLog, CompassLog};
use crate::io::frame::{BODY_AXES, PX4_SENSOR_MAG_AXES};
use crate::io::recording::{Attitude, GnssFix, Recording, Stream};
use crate::io::{thousands, ImportError, ImportReport, MagUnit, SensorFrame};

/// µT per gauss.
const UT_PER_GAUSS: f64 = 100.0;

/// Whether a magnetometer topic logs the raw field or the calibrated one.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Logged {
    Raw,
    /// `S·(raw − offset)` in the sensor's axes: `sensor_mag` before PX4 v1.12, whose
    /// drivers applied offset and scale and left the rotation to the sensors module.
    CalibratedInSensorAxes,
    /// `R·S·(raw − offset)`, body axes.
    Calibrated,
}

/// PX4 v1.12 (`ver_sw_release` 0x010C00TT) moved the compass calibration from the
/// drivers to `lib/sensor_calibration`, leaving `sensor_mag` raw.
const FIRST_RAW_SENSOR_MAG_RELEASE: u32 = 0x010C_0000;

/// One compass made, with the rotation of its raw values into body axes.
struct Made {
    log: CompassLog,
    device_id: Option<u32>,
    body_from_sensor: Option<Matrix3<f64>>,
}

fn scaled(
    stream: &Stream<Vector3<f64>>,
    map: impl Fn(&Vector3<f64>) -> Vector3<f64>,
) -> Stream<Vector3<f64>> {
    Stream {
        t_s: stream.t_s.clone(),
        values: stream
            .values
            .iter()
            .map(|value| map(value) * UT_PER_GAUSS)
            .collect(),
    }
}

impl UlogReader {
    /// Ends the input. Fails only when nothing at all could be read.
    pub fn finish(mut self, file_name: &str) -> Result<ImportReport, ImportError> {
        self.end_of_input(file_name)?;
        let collected = std::mem::take(&mut self.collected);
        let mut notes = Vec::new();
        let Collected {
            gyro_radps,
            acc_mps2,
            combined_mag,
            sensor_mag,
            vehicle_mag,
            attitude,
            gnss,
            first_utc,
            n_fixes_without_position,
            n_other_instances,
        } = collected;
        let motion = Motion {
            gyro_radps,
            acc_mps2,
            attitude,
            gnss,
            first_utc,
            n_fixes_without_position,
            n_other_instances,
        };
        let (mut recording, mut n_out_of_order) = motion.into_recording(&mut notes);
        let made = self.compasses(
            combined_mag,
            sensor_mag,
            vehicle_mag,
            &mut notes,
            &mut n_out_of_order,
        );
        let prime = self
            .param("CAL_MAG_PRIME")
            .filter(|&id| id > 0.0)
            .map(|id| id as u32);
        let (mag_frame, main_compass) = set_primary(&made, prime, &mut recording, &mut notes);
        self.finish_with(
            file_name,
            recording,
            (made, main_compass),
            mag_frame,
            notes,
            n_out_of_order,
        )
    }

    /// The parameter in force named `name`.
    fn param(&self, name: &str) -> Option<f64> {
        crate::io::autopilot::param_in(&self.params, name)
    }

    /// The end of the bytes: an error when the header or the log is unreadable, a
    /// diagnostic for an unfinished last message.
    fn end_of_input(&mut self, file_name: &str) -> Result<(), ImportError> {
        if self.offset == 0 && self.pending.is_empty() {
            return Err(ImportError::Empty {
                file_name: file_name.to_string(),
            });
        }
        let nothing = |problem: String, n_lines: usize| ImportError::NothingRecognised {
            file_name: file_name.to_string(),
            format: ULOG,
            n_lines,
            first_problem: format!(" ({problem})"),
        };
        if !self.header_read {
            let problem = if looks_like(&self.pending) || MAGIC.starts_with(&self.pending) {
                format!(
                    "byte 0: the file ends inside the 16-byte header ({} bytes)",
                    self.pending.len()
                )
            } else {
                "byte 0: no ULog header (magic ULog 01 12 35)".to_string()
            };
            return Err(nothing(problem, 0));
        }
        if let Some(reason) = self.stopped.take() {
            return Err(nothing(reason, self.n_data_messages));
        }
        if let Some(from) = self.resyncing_from.take() {
            self.diagnostics.push(
                None,
                format!("byte {from}: corrupt bytes to the end of the file skipped"),
            );
        } else if !self.pending.is_empty() {
            let needed = self.bytes_needed(&self.pending);
            self.diagnostics.push(
                None,
                format!(
                    "byte {}: the last message is cut short ({} of {needed} bytes); skipped",
                    self.offset,
                    self.pending.len()
                ),
            );
        }

        Ok(())
    }

    /// Every compass topic made into a compass, with its calibration in force applied
    /// or undone.
    fn compasses(
        &self,
        combined_mag: MagSeries,
        sensor_mag: std::collections::BTreeMap<u8, MagSeries>,
        vehicle_mag: std::collections::BTreeMap<u8, MagSeries>,
        notes: &mut Vec<String>,
        n_out_of_order: &mut usize,
    ) -> Vec<Made> {
        let param = |name: &str| self.param(name);
        let prime = param("CAL_MAG_PRIME")
            .filter(|&id| id > 0.0)
            .map(|id| id as u32);
        let mut sources: Vec<(String, usize, Logged, MagSeries)> = Vec::new();
        let sensor_mag_logged = match self.ver_sw_release {
            Some(release) if release < FIRST_RAW_SENSOR_MAG_RELEASE => {
                Logged::CalibratedInSensorAxes
            }
            _ => Logged::Raw,
        };
        if !sensor_mag.is_empty() {
            notes.push(match sensor_mag_logged {
                Logged::Raw => {
                    "sensor_mag taken as raw (PX4 v1.12 or later, or version unknown)".to_string()
                }
                _ => format!(
                    "sensor_mag taken as calibrated in the sensor's axes: the log's \
                     ver_sw_release {:#010x} is older than PX4 v1.12, whose drivers applied \
                     offset and scale",
                    self.ver_sw_release.unwrap_or_default()
                ),
            });
        }
        for (multi_id, series) in sensor_mag {
            sources.push((
                format!("sensor_mag {multi_id}"),
                multi_id as usize,
                sensor_mag_logged,
                series,
            ));
        }
        for (multi_id, series) in vehicle_mag {
            sources.push((
                format!("vehicle_magnetometer {multi_id}"),
                multi_id as usize,
                Logged::Calibrated,
                series,
            ));
        }
        if !combined_mag.field_ga.is_empty() {
            sources.push((
                "sensor_combined".into(),
                0,
                Logged::Calibrated,
                combined_mag,
            ));
        }
        let mut made: Vec<Made> = Vec::new();
        for (source, instance, logged, mut series) in sources {
            if series.field_ga.is_empty() {
                continue;
            }
            *n_out_of_order += series.field_ga.sort_by_time();
            made.push(make_compass(
                source, instance, logged, series, prime, &param,
            ));
        }
        for compass in &made {
            notes.push(format!(
                "{}: {} samples (gauss × 100 = µT); {}",
                compass.log.source,
                thousands(compass.log.logged_in_body_ut.len()),
                compass.log.how_raw
            ));
        }
        made
    }

    /// The last notes, the firmware and the report.
    fn finish_with(
        mut self,
        file_name: &str,
        recording: Recording,
        (made, main_compass): (Vec<Made>, Option<usize>),
        mag_frame: Option<SensorFrame>,
        mut notes: Vec<String>,
        n_out_of_order: usize,
    ) -> Result<ImportReport, ImportError> {
        let nothing = |problem: String, n_lines: usize| ImportError::NothingRecognised {
            file_name: file_name.to_string(),
            format: ULOG,
            n_lines,
            first_problem: format!(" ({problem})"),
        };
        if n_out_of_order > 0 {
            notes.push(format!(
                "{} samples out of time order, sorted",
                thousands(n_out_of_order)
            ));
        }
        if self.n_dropouts > 0 {
            notes.push(format!(
                "{} logging dropouts, {} ms of data lost in all",
                self.n_dropouts, self.dropout_ms
            ));
        }
        if self.n_bytes_skipped > 0 {
            notes.push(format!(
                "{} corrupt bytes skipped",
                thousands(self.n_bytes_skipped as usize)
            ));
        }
        notes.push(format!(
            "{} parameters in force (logged before the first data), {} changed during the log",
            thousands(self.params.len()),
            thousands(self.params_changed.len())
        ));

        let has_samples = !recording.gyro_in_body_radps.is_empty()
            || !recording.acc_in_body_mps2.is_empty()
            || !recording.mag_in_body_ut.is_empty()
            || !recording.attitude.is_empty()
            || !recording.gnss.is_empty();
        if !has_samples {
            let problem = match self.diagnostics.kept.first() {
                Some(first) => first.message.clone(),
                None => "no sensor_combined, sensor_mag, vehicle_magnetometer, vehicle_attitude \
                         or GNSS data in the log"
                    .to_string(),
            };
            return Err(nothing(problem, self.n_data_messages));
        }
        let info = |key: &str| {
            self.info
                .iter()
                .find(|(name, _)| name == key)
                .map(|(_, value)| value.clone())
        };
        let firmware = match (info("sys_name"), info("ver_sw"), info("ver_hw")) {
            (None, None, None) => None,
            (sys_name, ver_sw, ver_hw) => Some(format!(
                "{} {} on {}",
                sys_name.unwrap_or_else(|| "PX4".into()),
                ver_sw.unwrap_or_else(|| "(version unknown)".into()),
                ver_hw.unwrap_or_else(|| "(board unknown)".into())
            )),
        };
        let autopilot = AutopilotLog {
            autopilot: Autopilot::Px4,
            firmware,
            params: std::mem::take(&mut self.params),
            params_changed: std::mem::take(&mut self.params_changed),
            compasses: made.into_iter().map(|made| made.log).collect(),
            main_compass,
            current_a: Stream::default(),
        };
        Ok(ImportReport {
            file_name: file_name.to_string(),
            format: ULOG,
            recording,
            diagnostics: self.diagnostics,
            header: None,
            n_data_lines: self.n_data_messages,
            notes,
            mag_frame,
            autopilot: Some(autopilot),
        })
    }
}

/// The streams of a log besides its compasses, before they are sorted.
struct Motion {
    gyro_radps: Stream<Vector3<f64>>,
    acc_mps2: Stream<Vector3<f64>>,
    attitude: Stream<Attitude>,
    gnss: [Stream<GnssFix>; 2],
    first_utc: [Option<(f64, f64)>; 2],
    n_fixes_without_position: usize,
    n_other_instances: usize,
}

impl Motion {
    /// The recording's motion streams, sorted, with their notes; and how many samples
    /// were out of order.
    fn into_recording(self, notes: &mut Vec<String>) -> (Recording, usize) {
        let mut recording = Recording::default();
        let mut n_out_of_order = 0;
        recording.gyro_in_body_radps = self.gyro_radps;
        recording.acc_in_body_mps2 = self.acc_mps2;
        n_out_of_order += recording.gyro_in_body_radps.sort_by_time();
        n_out_of_order += recording.acc_in_body_mps2.sort_by_time();
        if !recording.gyro_in_body_radps.is_empty() || !recording.acc_in_body_mps2.is_empty() {
            notes.push(format!(
                "sensor_combined: {} gyro samples (gyro_rad, rad/s) at timestamp and {} \
                 accelerometer samples (accelerometer_m_s2) at timestamp + \
                 accelerometer_timestamp_relative, body axes (PX4's FRD)",
                thousands(recording.gyro_in_body_radps.len()),
                thousands(recording.acc_in_body_mps2.len())
            ));
        }
        recording.attitude = self.attitude;
        n_out_of_order += recording.attitude.sort_by_time();
        // The autopilot's own heading: the reference of a vehicle that flies sideways.
        recording.autopilot_heading_rad = crate::io::recording::Stream {
            t_s: recording.attitude.t_s.clone(),
            values: recording
                .attitude
                .values
                .iter()
                .map(|attitude| attitude.yaw_rad.unwrap_or(f64::NAN))
                .collect(),
        };
        if !recording.attitude.is_empty() {
            notes.push(format!(
                "vehicle_attitude: {} attitudes, the autopilot's own estimate (q, body FRD to \
                 NED, as Euler ZYX roll, pitch, yaw from north), not an independent reference",
                thousands(recording.attitude.len())
            ));
        }
        let source = usize::from(self.gnss[0].is_empty());
        let [vehicle_gps, sensor_gps] = self.gnss;
        recording.gnss = if source == 0 { vehicle_gps } else { sensor_gps };
        n_out_of_order += recording.gnss.sort_by_time();
        recording.start_unix_s = self.first_utc[source].map(|(boot_s, utc_s)| utc_s - boot_s);
        if !recording.gnss.is_empty() || self.n_fixes_without_position > 0 {
            let topic = ["vehicle_gps_position", "sensor_gps"][source];
            notes.push(format!(
                "{topic}: {} fixes; {} with fix_type below 2 (no position) skipped; {}",
                thousands(recording.gnss.len()),
                thousands(self.n_fixes_without_position),
                match recording.start_unix_s {
                    Some(_) => "the start time comes from the first fix's time_utc_usec",
                    None => "no fix has a UTC time, so the log is not dated",
                }
            ));
        }
        if self.n_other_instances > 0 {
            notes.push(format!(
                "{} messages of second instances of sensor_combined, vehicle_attitude or GNSS \
                 not used (instance 0 is read)",
                thousands(self.n_other_instances)
            ));
        }

        (recording, n_out_of_order)
    }
}

/// One compass topic made into a compass: its field as logged and raw, in body axes.
fn make_compass(
    source: String,
    instance: usize,
    logged: Logged,
    mut series: MagSeries,
    prime: Option<u32>,
    param: &dyn Fn(&str) -> Option<f64>,
) -> Made {
    let mut how_device = String::new();
    let device_id = series.device_id.or_else(|| {
        how_device = match prime {
            Some(id) => {
                format!("no device_id: taken as the primary compass CAL_MAG_PRIME {id}; ")
            }
            None => "no device_id and no CAL_MAG_PRIME; ".to_string(),
        };
        prime
    });
    if series.n_repeated > 0 {
        how_device += &format!(
            "{} repeats of the sample before (same sample time) skipped; ",
            thousands(series.n_repeated)
        );
    }
    if series.n_other_device > 0 {
        how_device += &format!(
            "{} samples from another device_id than the first skipped; ",
            series.n_other_device
        );
    }
    let cal = device_id.and_then(|id| calibration(&param, id));
    let rotation = cal.as_ref().and_then(|cal| cal.body_from_sensor);
    let (logged_in_body_ut, raw_in_body_ut, how) = match (logged, &cal, rotation) {
        (Logged::Raw, Some(cal), Some(r)) => (
            scaled(&series.field_ga, |raw| cal.apply(&r, raw)),
            Some(scaled(&series.field_ga, |raw| r * raw)),
            format!(
                "raw = R·(x, y, z) of the driver's gauss; logged = R·S·(raw − offset) \
                 with CAL_MAG{}_* in force; R: {}",
                cal.slot, cal.rotation_source
            ),
        ),
        (Logged::Calibrated | Logged::CalibratedInSensorAxes, Some(cal), Some(r)) => {
            if logged == Logged::CalibratedInSensorAxes {
                series
                    .field_ga
                    .values
                    .iter_mut()
                    .for_each(|value| *value = r * *value);
            }
            let undo = cal.undo_into_body(&r);
            let how = match undo {
                Some(_) => format!(
                    "{}; raw = R·(S⁻¹·Rᵀ·logged + offset) with CAL_MAG{}_* in force; R: {}",
                    match logged {
                        Logged::CalibratedInSensorAxes => {
                            "logged S·(raw − offset) in the sensor's axes, turned by R"
                        }
                        _ => "logged calibrated, R·S·(raw − offset)",
                    },
                    cal.slot,
                    cal.rotation_source
                ),
                None => format!("CAL_MAG{}_*SCALE is singular: raw not made", cal.slot),
            };
            let raw = undo.map(|undo| scaled(&series.field_ga, undo));
            (scaled(&series.field_ga, |value| *value), raw, how)
        }
        (_, Some(cal), None) => (
            scaled(&series.field_ga, |value| *value),
            None,
            format!(
                "rotation unknown ({}): raw not made; values as logged",
                cal.rotation_source
            ),
        ),
        (_, None, _) => (
            scaled(&series.field_ga, |value| *value),
            None,
            match device_id {
                Some(id) => format!(
                    "no CAL_MAGn_ID is {id}: calibration unknown, raw not made; values as logged"
                ),
                None => "device unknown: raw not made; values as logged".to_string(),
            },
        ),
    };
    Made {
        log: CompassLog {
            instance,
            source,
            logged_in_body_ut,
            raw_in_body_ut,
            how_raw: format!("{how_device}{how}"),
            px4_slot: cal.as_ref().and_then(|cal| Some((cal.slot, rotation?))),
        },
        device_id,
        body_from_sensor: rotation,
    }
}

/// The primary compass (`CAL_MAG_PRIME`'s, the one with a raw field and the most samples)
/// into the recording; its frame, and its index when its raw field is the one put in.
fn set_primary(
    made: &[Made],
    prime: Option<u32>,
    recording: &mut Recording,
    notes: &mut Vec<String>,
) -> (Option<SensorFrame>, Option<usize>) {
    let primary_idx = prime
        .and_then(|prime| {
            (0..made.len())
                .filter(|&idx| made[idx].device_id == Some(prime))
                .max_by_key(|&idx| {
                    (
                        made[idx].log.raw_in_body_ut.is_some(),
                        made[idx].log.logged_in_body_ut.len(),
                    )
                })
        })
        .or(if made.is_empty() { None } else { Some(0) });
    let mut mag_frame = None;
    let mut main_compass = None;
    if let Some(primary) = primary_idx.and_then(|idx| made.get(idx)) {
        match (&primary.log.raw_in_body_ut, primary.body_from_sensor) {
            (Some(raw), Some(rotation)) => {
                recording.mag_in_body_ut = raw.clone();
                main_compass = primary_idx;
                mag_frame = Some(SensorFrame {
                    body_from_sensor: rotation,
                    unit: MagUnit::GAUSS,
                    axes: PX4_SENSOR_MAG_AXES,
                });
                notes.push(format!(
                    "magnetometer: {}'s raw field (its calibration undone), body axes",
                    primary.log.source
                ));
            }
            _ => {
                recording.mag_in_body_ut = primary.log.logged_in_body_ut.clone();
                mag_frame = Some(SensorFrame {
                    body_from_sensor: Matrix3::identity(),
                    unit: MagUnit::GAUSS,
                    axes: BODY_AXES,
                });
                notes.push(format!(
                    "magnetometer: {}'s field as logged (the autopilot's calibration could \
                     not be undone), read as body axes",
                    primary.log.source
                ));
            }
        }
    }
    (mag_frame, main_compass)
}
