//! The attitude filter's heading ([`crate::attitude`]) at each calibration sample: a
//! base of the heading comparison beside the field-domain methods (row `ahrs`), with the
//! deviation models on top of it like any other.
//!
//! The filter reads the whole recording (gyroscope, accelerometer, field) and runs once
//! per calibration; the field is corrected by the calibration the device would get
//! ([`super::selection::device_calibration`] of the field-domain choice) or the
//! device's own hard-iron estimate ([`crate::attitude::track::attitude_of`]). Its yaw is
//! magnetic; the declination the calibration used is added, as to every other heading.

use super::{selection, CalibrationReport};
use crate::attitude::track::attitude_of;
use crate::attitude::{AttitudeOptions, AttitudeTrack};
use crate::recording::{Recording, Stream};

/// Gyroscope outputs further apart than this (s) are not interpolated across.
const MAX_OUTPUT_GAP_S: f64 = 1.0;

/// The filter's track over `recording`, its field corrected as for the comparison's
/// `ahrs` row; `None` without a gyroscope and an accelerometer. The dead reckoning's
/// heading noise calls it too.
pub fn attitude_track(recording: &Recording, report: &CalibrationReport) -> Option<AttitudeTrack> {
    let device = selection::device_calibration(report).map(|(_, field)| field);
    attitude_of(
        recording,
        device.as_ref(),
        &AttitudeOptions::for_gyro(recording.gyro_bias),
    )
    .ok()
    .map(|(track, _)| track)
}

/// The filter's heading (degrees clockwise from true north, in [0, 360); NaN where it
/// has none) at each of `t_s`; `None` without a gyroscope and an accelerometer.
pub(super) fn attitude_heading_deg(
    recording: &Recording,
    report: &CalibrationReport,
    t_s: &[f64],
) -> Option<Vec<f64>> {
    let track = attitude_track(recording, report)?;
    let yaw = Stream {
        t_s: track.attitude.t_s,
        values: track
            .attitude
            .values
            .iter()
            .map(|estimate| estimate.yaw_rad)
            .collect(),
    };
    let declination_rad = report.declination.declination_deg.to_radians();
    Some(
        t_s.iter()
            .map(|&t_s| {
                yaw.interpolate_angle_at(t_s, MAX_OUTPUT_GAP_S)
                    .map_or(f64::NAN, |yaw_rad| {
                        crate::angle::wrap_to_2pi(yaw_rad + declination_rad).to_degrees()
                    })
            })
            .collect(),
    )
}
