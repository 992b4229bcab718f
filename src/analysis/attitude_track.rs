//! The filter on a whole recording: its streams calibrated and referenced, and its
//! output as the CSV any tool can read (`heading --attitude-out`): the filter run
//! forward and backward and combined (`attitude::smoother`).
//!
//! The field is corrected by the analysis's calibration or by the device's own
//! hard-iron estimate, whichever lets the gates pass more field ([`attitude_of`]). The
//! forward run alone is a base of the heading comparison (row `ahrs`,
//! `analysis/calibration/attitude.rs`), the network's gyro-heading input, and a heading
//! dead reckoning can take (`--heading-model ahrs`, `gyro+ahrs`, with the yaw's σ as the
//! heading noise: `gyro+ahrs` fuses it with the gyroscope over the whole walk itself,
//! and given the combined runs its loop on the phyphox hallway closed to 2.3 % rather
//! than 1.5 %); the live panel runs the same filter for its dial's second needle
//! (`live/attitude.rs`).

use nalgebra::Vector3;

use crate::attitude::gates::FieldReference;
use crate::attitude::smoother::{with_backward_run, Runs};
use crate::attitude::tilt::smooth_specific_force;
use crate::attitude::{
    estimate_attitude, AttitudeError, AttitudeOptions, AttitudeTrack, Sensors, RECOVERY_S,
};
use crate::base::angle::wrap_to_2pi;
use crate::fit::model::FieldCalibration;
use crate::io::recording::{Recording, Stream};

/// The window (s) over which the specific force is averaged to level the field for the
/// reference dip (a median over the log: only its centre matters).
const DOWN_WINDOW_S: f64 = 1.0;

/// Which correction the filter's field had.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FieldSource {
    /// The analysis's calibration (the one exported).
    Calibration,
    /// The device's own hard-iron estimate, logged beside the raw field (Android's
    /// uncalibrated magnetometer's bias).
    DeviceEstimate,
    /// The field as logged.
    AsLogged,
}

/// The filter over a recording whose raw field (body axes, µT) `calibration` corrects.
/// Where the log also carries the device's own hard-iron estimate, the filter runs with
/// each and keeps the run whose gates let more field samples through: under the right
/// correction the field looks like the Earth's (its magnitude, dip and direction hold)
/// more often. A heading filter is only as good as its field, and on a phone walked with
/// (too few orientations for a fit) the device's running estimate can be the better
/// one: on the shared attitude trials our fit's hard iron is 8-130 µT from the phone's.
/// The gate's reference is the calibrated sphere's radius (or the median magnitude) and
/// the median dip of the samples of that magnitude. `runs`: forward alone, or forward
/// and backward combined.
pub fn attitude_of(
    recording: &Recording,
    calibration: Option<&FieldCalibration>,
    options: &AttitudeOptions,
    runs: Runs,
) -> Result<(AttitudeTrack, FieldSource), AttitudeError> {
    let smoothed = smooth_specific_force(&recording.acc_in_body_mps2, DOWN_WINDOW_S);
    let down = Stream {
        t_s: smoothed.t_s,
        values: smoothed
            .values
            .iter()
            .map(|force| -force.try_normalize(1e-9).unwrap_or_else(Vector3::zeros))
            .collect(),
    };
    let raw = &recording.mag_in_body_ut;
    let mut candidates: Vec<(FieldSource, Stream<Vector3<f64>>, Option<f64>)> = Vec::new();
    if let Some(calibration) = calibration {
        let field = map_stream(raw, |_, value| Some(calibration.apply(value)));
        candidates.push((FieldSource::Calibration, field, Some(calibration.field_ut)));
    }
    let bias = &recording.mag_bias_in_body_ut;
    if !bias.is_empty() {
        let field = map_stream(raw, |t_s, value| {
            bias.interpolate_at(t_s, f64::INFINITY).map(|b| value - b)
        });
        candidates.push((FieldSource::DeviceEstimate, field, None));
    }
    if candidates.is_empty() {
        candidates.push((FieldSource::AsLogged, raw.clone(), None));
    }
    // The candidates are judged by their forward runs; only the one kept is run
    // backward too.
    let sensors = |field| Sensors {
        acc_in_body_mps2: &recording.acc_in_body_mps2,
        gyro_in_body_radps: &recording.gyro_in_body_radps,
        field_in_body_ut: field,
    };
    let mut best: Option<(AttitudeTrack, FieldSource, &Stream<Vector3<f64>>, _)> = None;
    for (source, field, field_ut) in &candidates {
        let reference = FieldReference::of_log(field, &down, (*field_ut, None));
        let track = estimate_attitude(sensors(field), reference, options)?;
        if best
            .as_ref()
            .is_none_or(|(kept, ..)| track.summary.n_field_fused > kept.summary.n_field_fused)
        {
            best = Some((track, *source, field, reference));
        }
    }
    // `candidates` is never empty, so neither is `best`; the error is unreachable.
    let (track, source, field, reference) = best.ok_or(AttitudeError::NoGyroscope)?;
    let track = match runs {
        Runs::Forward => track,
        Runs::BothWays => with_backward_run(track, sensors(field), reference, options)?,
    };
    Ok((track, source))
}

/// The samples of `stream` mapped by `map` (given each time), those it drops left out.
fn map_stream(
    stream: &Stream<Vector3<f64>>,
    map: impl Fn(f64, Vector3<f64>) -> Option<Vector3<f64>>,
) -> Stream<Vector3<f64>> {
    let mut mapped = Stream::default();
    for (&t_s, &value) in stream.t_s.iter().zip(&stream.values) {
        if let Some(value) = map(t_s, value) {
            mapped.push(t_s, value);
        }
    }
    mapped
}

/// The track as `t_s,yaw_deg,pitch_deg,roll_deg,yaw_sigma_deg`, after `#` lines that
/// say what the columns are: t_s in the log's time (its epoch said where known), yaw of the body x axis
/// clockwise from true north where `declination_deg` is given (else magnetic north),
/// in [0, 360); `body_axes` says which way the body x axis points on the device.
pub fn attitude_csv(
    track: &AttitudeTrack,
    declination_deg: Option<f64>,
    body_axes: &str,
    start_unix_s: Option<f64>,
) -> String {
    use std::fmt::Write as _;
    let mut text = String::with_capacity(64 * (track.attitude.len() + 8));
    let north = match declination_deg {
        Some(declination_deg) => {
            format!("true north (magnetic yaw plus a declination of {declination_deg:.2}°)")
        }
        None => "magnetic north (no declination known)".to_string(),
    };
    let _ = writeln!(
        text,
        "# compass-pdr attitude: a gyroscope + accelerometer + magnetometer filter run forward and backward, the yaws weighed by their sigma"
    );
    let _ = writeln!(
        text,
        "# yaw_deg: heading of the body x axis, clockwise from {north}"
    );
    let _ = writeln!(text, "# body axes: {body_axes}");
    let _ = writeln!(text, "# pitch_deg, roll_deg: body x forward, y right, z down relative to north-east-down (ZYX Euler angles)");
    let _ = writeln!(text, "# yaw_sigma_deg: 1-sigma of the yaw (the runs' own, with the error a field that passes the gates still carries)");
    let summary = &track.summary;
    let deg = |radps: f64| radps.to_degrees();
    let [bx, by, bz] = summary.final_gyro_bias_radps.map(deg);
    let [sx, sy, sz] = summary.final_gyro_bias_sigma_radps.map(deg);
    let _ = writeln!(
        text,
        "# gyroscope bias (deg/s, body x y z): prior 1-sigma {:.2}; at the end ({bx:.3}, {by:.3}, {bz:.3}) +- ({sx:.3}, {sy:.3}, {sz:.3})",
        deg(summary.initial_gyro_bias_sigma_radps)
    );
    let field_samples = summary.n_field_fused
        + summary.n_field_disturbed
        + summary.n_field_turning
        + summary.n_field_contradicting;
    if field_samples > 0 {
        let pct = |n: usize| 100.0 * n as f64 / field_samples as f64;
        let _ = writeln!(
            text,
            "# magnetometer: {field_samples} samples after the filter started: {:.1} % corrected the yaw, {:.1} % refused as disturbed by their magnitude or dip, {:.1} % as turning in the navigation frame, {:.1} % refused as contradicting the gyroscope; {} yaw resets after {RECOVERY_S} s of contradiction",
            pct(summary.n_field_fused),
            pct(summary.n_field_disturbed),
            pct(summary.n_field_turning),
            pct(summary.n_field_contradicting),
            summary.n_recoveries,
        );
    }
    let gravity_samples = summary.n_gravity_fused + summary.n_gravity_refused;
    if gravity_samples > 0 {
        let _ = writeln!(
            text,
            "# accelerometer: {gravity_samples} samples after the filter started: {:.1} % corrected the tilt as gravity, {:.1} % refused (the body accelerating, or contradicting the tilt); {} tilts re-levelled after {RECOVERY_S} s of contradiction",
            100.0 * summary.n_gravity_fused as f64 / gravity_samples as f64,
            100.0 * summary.n_gravity_refused as f64 / gravity_samples as f64,
            summary.n_tilt_recoveries,
        );
    }
    match start_unix_s {
        Some(start_s) => {
            let _ = writeln!(
                text,
                "# t_s: seconds of the log's time, whose 0 is {start_s:.3} s after 1970-01-01 UTC"
            );
        }
        None => {
            let _ = writeln!(text, "# t_s: seconds of the log's own time stamps");
        }
    }
    let _ = writeln!(text, "t_s,yaw_deg,pitch_deg,roll_deg,yaw_sigma_deg");
    let declination_rad = declination_deg.unwrap_or(0.0).to_radians();
    for (t_s, estimate) in track.attitude.t_s.iter().zip(&track.attitude.values) {
        let _ = writeln!(
            text,
            "{t_s:.6},{:.3},{:.3},{:.3},{:.3}",
            wrap_to_2pi(estimate.yaw_rad + declination_rad).to_degrees(),
            estimate.pitch_rad.to_degrees(),
            estimate.roll_rad.to_degrees(),
            estimate.yaw_sigma_rad.to_degrees()
        );
    }
    text
}
