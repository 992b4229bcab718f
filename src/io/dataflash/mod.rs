//! ArduPilot DataFlash logs, binary (`.bin`) and text (`.log`).
//!
//! A log describes itself: `FMT` messages give each message type's name, length, field
//! types and column names (`format.rs`). The messages read are the compasses (`MAG`,
//! `MAG2`, `MAG3`, or `MAG` with an instance column), the first IMU, the first GPS
//! (position, course and speed; its week and time of week date the log), `ATT` (the
//! autopilot's own attitude) and `PARM` (the parameters in force), in `messages.rs`;
//! `binary.rs` and `text.rs` frame the two kinds of log.
//!
//! ArduPilot logs a compass's field **after** its calibration. `AP_Compass::correct_field`
//! applies, in body axes (the compass's orientation is applied before):
//!
//! ```text
//! corrected = M · (raw + offsets) · scale + motor,
//! M = [[DIA_X, ODI_X, ODI_Y], [ODI_X, DIA_Y, ODI_Z], [ODI_Y, ODI_Z, DIA_Z]]
//! ```
//!
//! (`M` is the identity when the diagonals are zero, and `scale` is `COMPASS_SCALE` only
//! within 0.85-1.4.) The offsets and motor compensation are logged beside each sample
//! (`OfsX..`, `MOfsX..`/`MOX..`), the rest are `PARM`s. The raw field that a new
//! calibration is fitted on is `raw = M⁻¹ · (corrected − motor) / scale − offsets`, which
//! the end of the read (`finish`) computes and says it did ([`ArduPilotCompass`] is the
//! one place that knows how ArduPilot applies a calibration). Units: mG (0.1 µT). The
//! primary compass's raw field is the recording's magnetometer; `CURR`/`BAT` give the
//! battery current for the motor term; and `ATT`, the vehicle's attitude, is turned back
//! by `AHRS_TRIM` into the attitude of the board the compasses are logged in.

mod binary;
mod format;
mod messages;
mod text;

use nalgebra::{Matrix3, Vector3};

pub use self::binary::BinaryReader;
use self::messages::{Collector, MagTrack};
pub use self::text::{looks_like as looks_like_text, TextReader};
use super::autopilot::ardupilot::ArduPilotCompass;
use super::autopilot::{Autopilot, AutopilotLog, CompassLog};
use super::frame::{MagUnit, SensorFrame};
use super::{thousands, Diagnostics, ImportError, ImportReport};
use crate::io::recording::{GyroBias, Recording, Stream};

pub const BINARY: &str = "ArduPilot DataFlash log";
pub const TEXT: &str = "ArduPilot DataFlash text log";

/// The axes ArduPilot logs a compass in.
pub const ARDUPILOT_AXES: &str =
    "ArduPilot's body axes (x forward, y right, z down; the compass's orientation applied)";

const UT_PER_MG: f64 = 0.1;

/// Whether a file starts as a binary DataFlash log: a message head, then `FMT`'s type.
pub fn looks_like_binary(prefix: &[u8]) -> bool {
    prefix.starts_with(&[0xA3, 0x95, format::FMT_TYPE])
}

/// Reads a whole binary log.
pub fn read_binary(file_name: &str, bytes: &[u8]) -> Result<ImportReport, ImportError> {
    let mut reader = BinaryReader::default();
    reader.feed(bytes);
    finish_binary(reader, file_name)
}

/// Reads a whole text log.
pub fn read_text(file_name: &str, bytes: &[u8]) -> Result<ImportReport, ImportError> {
    let mut reader = TextReader::default();
    crate::io::lines::decode_all(bytes, super::MAX_LINE_BYTES, |line| {
        reader.read_line(line.number, &line.text);
    });
    finish_text(reader, file_name)
}

pub fn finish_binary(
    mut reader: BinaryReader,
    file_name: &str,
) -> Result<ImportReport, ImportError> {
    reader.finish();
    let summary = format!(
        "read {} messages ({} bytes skipped)",
        thousands(reader.n_messages),
        thousands(reader.n_bytes_skipped)
    );
    finish(
        file_name,
        BINARY,
        reader.collector,
        reader.diagnostics,
        reader.n_messages,
        summary,
    )
}

pub fn finish_text(mut reader: TextReader, file_name: &str) -> Result<ImportReport, ImportError> {
    if reader.collector.firmware.is_none() {
        reader.collector.firmware = reader.banner.take();
    }
    let summary = format!(
        "read {} message lines ({} lines of a type no FMT defines)",
        thousands(reader.n_messages),
        thousands(reader.n_undefined)
    );
    finish(
        file_name,
        TEXT,
        reader.collector,
        reader.diagnostics,
        reader.n_messages,
        summary,
    )
}

/// The compass's offsets at each sample: the logged ones, or the `PARM`'s where the
/// logged value is it rounded to whole mG (the log's columns are integers in old logs).
fn offsets_of(track: &MagTrack, in_force: Option<&ArduPilotCompass>) -> Option<Vec<Vector3<f64>>> {
    let param = in_force.map(|compass| compass.offsets_mg);
    if track.offsets_mg.len() == track.t_s.len() {
        return Some(
            track
                .offsets_mg
                .iter()
                .map(|&logged| match param {
                    Some(param) if (param - logged).amax() <= 1.0 => param,
                    _ => logged,
                })
                .collect(),
        );
    }
    param.map(|param| vec![param; track.t_s.len()])
}

/// Every compass of the log, each stream in time order (as the recording's will be:
/// the main compass's raw field becomes its magnetometer, the same samples in the same
/// order), and the main one: COMPASS_PRIMARY's, where its raw field is known. How many
/// of the main compass's raw samples were out of time order.
// A step run once per log, out of line (docs/ARCHITECTURE.md, "Build").
#[inline(never)]
fn set_compasses(autopilot: &mut AutopilotLog, mags: &[MagTrack]) -> usize {
    autopilot.compasses = mags
        .iter()
        .map(|track| compass_of(track, autopilot))
        .collect();
    let raw_out_of_order: Vec<usize> = autopilot
        .compasses
        .iter_mut()
        .map(|compass| {
            compass.logged_in_body_ut.sort_by_time();
            compass
                .raw_in_body_ut
                .as_mut()
                .map_or(0, crate::io::recording::Stream::sort_by_time)
        })
        .collect();
    let primary = autopilot
        .param("COMPASS_PRIMARY")
        .filter(|value| *value >= 0.0)
        .map_or(0, |value| value as usize);
    autopilot.main_compass = (0..autopilot.compasses.len())
        .filter(|&idx| autopilot.compasses[idx].raw_in_body_ut.is_some())
        .min_by_key(|&idx| {
            let instance = autopilot.compasses[idx].instance;
            (instance != primary, instance)
        });
    autopilot
        .main_compass
        .and_then(|idx| raw_out_of_order.get(idx))
        .copied()
        .unwrap_or(0)
}

/// One compass as logged and raw.
fn compass_of(track: &MagTrack, params: &AutopilotLog) -> CompassLog {
    let logged_in_body_ut = Stream {
        t_s: track.t_s.clone(),
        values: track.field_mg.iter().map(|v| v * UT_PER_MG).collect(),
    };
    let lookup = |name: &str| params.param(name).filter(|value| value.is_finite());
    let in_force = ArduPilotCompass::from_params(&lookup, track.instance);
    let offsets = offsets_of(track, in_force.as_ref());
    // Without COMPASS_OFS in the log, the logged offsets and an identity M.
    let soft_iron = in_force.map_or_else(Matrix3::identity, |compass| compass.soft_iron);
    let scale = in_force.map_or(1.0, |compass| compass.scale);
    let inverse = soft_iron.try_inverse();
    let motor_logged = track.motor_mg.len() == track.t_s.len();
    let (raw_in_body_ut, how_raw) = match (offsets, inverse) {
        (Some(offsets), Some(inverse)) => {
            let values = track
                .field_mg
                .iter()
                .enumerate()
                .map(|(idx, &logged)| {
                    let motor = if motor_logged {
                        track.motor_mg[idx]
                    } else {
                        Vector3::zeros()
                    };
                    (inverse * (logged - motor) / scale - offsets[idx]) * UT_PER_MG
                })
                .collect();
            let m = soft_iron;
            let first = offsets.first().copied().unwrap_or_else(Vector3::zeros);
            let how = format!(
                "{}: the field as logged, with its calibration undone: raw = M⁻¹ · (logged − \
                 motor) / scale − offsets, offsets ({:.1}, {:.1}, {:.1}) mG{}, M diagonal \
                 ({:.4}, {:.4}, {:.4}) off-diagonal ({:.4}, {:.4}, {:.4}), scale {scale}, {}",
                track.source,
                first.x,
                first.y,
                first.z,
                if track.offsets_mg.is_empty() {
                    " (from PARM: the message logs none)"
                } else {
                    " (logged with each sample)"
                },
                m[(0, 0)],
                m[(1, 1)],
                m[(2, 2)],
                m[(0, 1)],
                m[(0, 2)],
                m[(1, 2)],
                if motor_logged {
                    "motor compensation as logged with each sample"
                } else {
                    "no motor compensation logged"
                }
            );
            (
                Some(Stream {
                    t_s: track.t_s.clone(),
                    values,
                }),
                how,
            )
        }
        (None, _) => (
            None,
            format!(
                "{}: neither the message nor PARM gives the offsets in force, so the raw field \
                 cannot be recovered",
                track.source
            ),
        ),
        (_, None) => (
            None,
            format!(
                "{}: COMPASS_DIA/ODI give a matrix that cannot be inverted, so the raw field \
                 cannot be recovered",
                track.source
            ),
        ),
    };
    CompassLog {
        instance: track.instance,
        source: track.source.clone(),
        logged_in_body_ut,
        raw_in_body_ut,
        how_raw,
        px4_slot: None,
    }
}

/// The notes on the whole log: what was read, the firmware, the parameters.
// A step run once per log, out of line (docs/ARCHITECTURE.md, "Build").
#[inline(never)]
fn log_notes(summary: String, counts: &[(String, usize)], autopilot: &AutopilotLog) -> Vec<String> {
    let mut notes = vec![summary];
    let read: Vec<String> = counts
        .iter()
        .map(|(name, count)| format!("{name} {}", thousands(*count)))
        .collect();
    if !read.is_empty() {
        notes.push(format!("messages used: {}", read.join(", ")));
    }
    if let Some(firmware) = &autopilot.firmware {
        notes.push(format!("firmware: {firmware}"));
    }
    if !autopilot.params.is_empty() {
        notes.push(format!(
            "{} parameters in force (PARM){}",
            autopilot.params.len(),
            if autopilot.params_changed.is_empty() {
                String::new()
            } else {
                format!(
                    "; changed during the log: {}",
                    autopilot
                        .params_changed
                        .iter()
                        .map(|(name, value)| format!("{name} → {value}"))
                        .collect::<Vec<_>>()
                        .join(", ")
                )
            }
        ));
    }
    notes
}

/// The import report of a whole log from what its messages gave: the main compass's
/// raw field as the magnetometer, the other compasses kept apart, and the notes.
fn finish(
    file_name: &str,
    format: &'static str,
    collector: Collector,
    mut diagnostics: Diagnostics,
    n_messages: usize,
    summary: String,
) -> Result<ImportReport, ImportError> {
    let Collector {
        mut recording,
        mut mags,
        params,
        params_changed,
        firmware,
        counts,
        n_other_instances,
        n_gps_without_fix,
        utc_minus_boot_s,
        current_a,
    } = collector;
    if n_messages == 0 {
        return Err(ImportError::NothingRecognised {
            file_name: file_name.to_string(),
            format,
            n_lines: 0,
            first_problem: diagnostics
                .kept
                .first()
                .map(|first| format!(" ({})", first.message))
                .unwrap_or_default(),
        });
    }
    mags.sort_by_key(|track| track.instance);
    let zero_notes = zero_reading_notes(&mags);
    let mut autopilot = AutopilotLog {
        autopilot: Autopilot::ArduPilot,
        firmware,
        params,
        params_changed,
        compasses: Vec::new(),
        main_compass: None,
        current_a,
    };
    let n_main_out_of_order = set_compasses(&mut autopilot, &mags);
    let mut notes = log_notes(summary, &counts, &autopilot);
    notes.extend(zero_notes);
    let mag_frame = take_main_compass(&mut recording, &autopilot, &mut notes);
    imu_notes(&mut recording, n_other_instances, &mut notes);
    attitude_notes(&mut recording, &autopilot, &mut notes);
    if n_gps_without_fix > 0 {
        notes.push(format!(
            "GPS: {} messages without a 3D fix skipped",
            thousands(n_gps_without_fix)
        ));
    }
    recording.start_unix_s = utc_minus_boot_s;
    if let Some(start) = utc_minus_boot_s {
        notes.push(format!(
            "times are seconds since boot; the GPS week and time of week date the boot at {}",
            crate::base::calendar::utc_text(start)
        ));
    }
    // The magnetometer was sorted with its compass.
    let n_out_of_order = recording.sort_all_by_time() + n_main_out_of_order;
    diagnostics.push_sorted_by_time(None, n_out_of_order);
    Ok(ImportReport {
        file_name: file_name.to_string(),
        format,
        recording,
        diagnostics,
        header: None,
        n_data_lines: n_messages,
        notes,
        mag_frame,
        autopilot: Some(autopilot),
    })
}

/// A note for each compass that logged readings of exactly zero, which were left out.
// A step run once per log, out of line (docs/ARCHITECTURE.md, "Build").
#[inline(never)]
fn zero_reading_notes(mags: &[MagTrack]) -> Vec<String> {
    mags.iter()
        .filter(|track| track.n_zero_readings > 0)
        .map(|track| {
            format!(
                "{}: {} {} of exactly (0, 0, 0) left out: ArduPilot logs zeros while the \
                 compass reads nothing",
                track.source,
                thousands(track.n_zero_readings),
                crate::base::words::plural(track.n_zero_readings, "reading", "readings")
            )
        })
        .collect()
}

/// The main compass's raw field as the recording's magnetometer, with its frame; notes
/// say which compass it is and that the others are kept apart. `None` without one.
// A step run once per log, out of line (docs/ARCHITECTURE.md, "Build").
#[inline(never)]
fn take_main_compass(
    recording: &mut Recording,
    autopilot: &AutopilotLog,
    notes: &mut Vec<String>,
) -> Option<SensorFrame> {
    let chosen = autopilot
        .main_compass
        .and_then(|idx| autopilot.compasses.get(idx));
    let mut mag_frame = None;
    if let Some(compass) = chosen {
        recording.mag_in_body_ut = compass.raw_in_body_ut.clone().unwrap_or_default();
        mag_frame = Some(SensorFrame {
            body_from_sensor: Matrix3::identity(),
            unit: MagUnit::MILLIGAUSS,
            axes: ARDUPILOT_AXES,
        });
        notes.push(format!(
            "magnetometer: compass {} of {} ({}), raw. ArduPilot logs the field after its \
             calibration; it was undone to fit a new one: {}",
            compass.instance + 1,
            autopilot.compasses.len(),
            compass.source,
            compass.how_raw
        ));
    }
    for compass in &autopilot.compasses {
        if Some(compass.instance) != chosen.map(|chosen| chosen.instance) {
            notes.push(format!(
                "compass {} ({}): kept apart for its own calibration; {}",
                compass.instance + 1,
                compass.source,
                compass.how_raw
            ));
        }
    }
    mag_frame
}

/// The gyroscope's bias marked as removed by ArduPilot, with notes on the IMU and the
/// samples of other instances left unused.
// A step run once per log, out of line (docs/ARCHITECTURE.md, "Build").
#[inline(never)]
fn imu_notes(recording: &mut Recording, n_other_instances: usize, notes: &mut Vec<String>) {
    if !recording.gyro_in_body_radps.is_empty() {
        recording.gyro_bias = GyroBias::RemovedByDevice;
        notes.push(
            "IMU: the first IMU's gyroscope (rad/s) and accelerometer (m/s²), body axes; \
             ArduPilot removes the gyroscope offsets it measured at boot"
                .to_string(),
        );
    }
    if n_other_instances > 0 {
        notes.push(format!(
            "{} IMU and GPS samples of second and third instances not used",
            thousands(n_other_instances)
        ));
    }
}

/// The note on `ATT`, whose attitude is turned into the board's ([`board_attitude`]).
// A step run once per log, out of line (docs/ARCHITECTURE.md, "Build").
#[inline(never)]
fn attitude_notes(recording: &mut Recording, autopilot: &AutopilotLog, notes: &mut Vec<String>) {
    if !recording.attitude.is_empty() {
        notes.push(
            "ATT: the autopilot's own attitude estimate (roll, pitch, yaw from true north), \
             which used the compass calibration in force"
                .to_string(),
        );
        if let Some(note) = board_attitude(&mut recording.attitude, autopilot) {
            notes.push(note);
        }
    }
}

/// Turns `ATT` into the attitude of the autopilot board, whose axes the compasses are
/// logged in: ArduPilot's AHRS estimates the board's attitude and reports the vehicle's,
/// the board's turned back by `AHRS_TRIM` (`AP_AHRS`'s
/// `_rotation_autopilot_body_to_vehicle_body`, from `AHRS_TRIM_X` roll and `AHRS_TRIM_Y`
/// pitch), so the board's is `R_vehicle · R_trim`. A note says so where the trim is not
/// zero.
fn board_attitude(
    attitude: &mut Stream<crate::io::recording::Attitude>,
    autopilot: &AutopilotLog,
) -> Option<String> {
    use nalgebra::Rotation3;
    let trim = |name: &str| autopilot.param(name).filter(|v| v.is_finite() && *v != 0.0);
    let (trim_x_rad, trim_y_rad) = (trim("AHRS_TRIM_X"), trim("AHRS_TRIM_Y"));
    if trim_x_rad.is_none() && trim_y_rad.is_none() {
        return None;
    }
    let (trim_x_rad, trim_y_rad) = (trim_x_rad.unwrap_or(0.0), trim_y_rad.unwrap_or(0.0));
    let vehicle_to_board = Rotation3::from_euler_angles(trim_x_rad, trim_y_rad, 0.0);
    for value in &mut attitude.values {
        let yaw_rad = value.yaw_rad.unwrap_or(0.0);
        let board = Rotation3::from_euler_angles(value.roll_rad, value.pitch_rad, yaw_rad)
            * vehicle_to_board;
        let (roll_rad, pitch_rad, board_yaw_rad) = board.euler_angles();
        value.roll_rad = roll_rad;
        value.pitch_rad = pitch_rad;
        if value.yaw_rad.is_some() {
            value.yaw_rad = Some(board_yaw_rad.rem_euclid(std::f64::consts::TAU));
        }
    }
    Some(format!(
        "ATT turned by AHRS_TRIM (roll {:.2}°, pitch {:.2}°) into the attitude of the \
         autopilot board, whose axes the compasses are logged in",
        trim_x_rad.to_degrees(),
        trim_y_rad.to_degrees()
    ))
}

#[cfg(test)]
mod tests;
