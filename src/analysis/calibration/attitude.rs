//! The attitude filter's heading ([`crate::attitude`]) at each calibration sample: a
//! base of the heading comparison beside the field-domain methods (row `ahrs`), with the
//! deviation models on top of it like any other.
//!
//! The filter reads the whole recording (gyroscope, accelerometer, field) and runs once
//! per calibration; the field is corrected by the calibration the device would get
//! ([`super::selection::device_calibration`] of the field-domain choice) or the
//! device's own hard-iron estimate ([`crate::analysis::attitude_track::attitude_of`]). Its yaw is
//! magnetic; the declination the calibration used is added, as to every other heading.

use super::{selection, CalibrationReport};
use crate::analysis::attitude_track::attitude_of;
use crate::attitude::smoother::Runs;
use crate::attitude::AttitudeOptions;
use crate::io::recording::{Recording, Stream};

/// Gyroscope outputs further apart than this (s) are not interpolated across.
const MAX_OUTPUT_GAP_S: f64 = 1.0;

/// The attitude filter's heading at each calibration sample, with its 1σ.
#[derive(Debug, Clone, PartialEq)]
pub struct AttitudeHeading {
    /// Degrees clockwise from true north, in [0, 360); NaN where the filter has none.
    pub heading_deg: Vec<f64>,
    /// The yaw's 1σ (degrees); NaN where the filter has none.
    pub sigma_deg: Vec<f64>,
}

/// The filter's heading and its 1σ at each of `t_s`, its field corrected as the device
/// would correct it; `None` without a gyroscope and an accelerometer.
pub(super) fn attitude_heading(
    recording: &Recording,
    report: &CalibrationReport,
    t_s: &[f64],
) -> Option<AttitudeHeading> {
    let device = selection::device_calibration(report).map(|(_, field)| field);
    let (track, _) = attitude_of(
        recording,
        device.as_ref(),
        &AttitudeOptions::for_gyro(recording.gyro_bias),
        Runs::Forward,
    )
    .ok()?;
    let (yaw, sigma) = {
        let (mut yaw, mut sigma) = (Stream::default(), Stream::default());
        for (&t_s, estimate) in track.attitude.t_s.iter().zip(&track.attitude.values) {
            yaw.push(t_s, estimate.yaw_rad);
            sigma.push(t_s, estimate.yaw_sigma_rad);
        }
        (yaw, sigma)
    };
    let declination_rad = report.declination.declination_deg.to_radians();
    let heading_deg = t_s
        .iter()
        .map(|&t_s| {
            yaw.interpolate_angle_at(t_s, MAX_OUTPUT_GAP_S)
                .map_or(f64::NAN, |yaw_rad| {
                    crate::base::angle::wrap_to_2pi(yaw_rad + declination_rad).to_degrees()
                })
        })
        .collect();
    let sigma_deg = t_s
        .iter()
        .map(|&t_s| {
            sigma
                .interpolate_at(t_s, MAX_OUTPUT_GAP_S)
                .map_or(f64::NAN, f64::to_degrees)
        })
        .collect();
    Some(AttitudeHeading {
        heading_deg,
        sigma_deg,
    })
}
