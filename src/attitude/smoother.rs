//! The attitude over a whole log from two runs of the filter: one forward in time, one
//! backward (the log reversed, the gyroscope's rates negated), combined sample by sample
//! as a two-filter smoother combines them (Fraser and Potter 1969, "The optimum linear
//! smoother as a combination of two optimum linear filters", IEEE TAC 14(4)). Each yaw
//! weighs by the other's variance, so the backward run's converged heading replaces the
//! forward run's first seconds (a cold start taken from one, possibly disturbed, field
//! sample) and the forward run's replaces the backward one's last; in between, the two
//! runs' lags after a disturbance or a turn point opposite ways and half cancel. The
//! roll and pitch are the forward run's.
//!
//! The runs' errors are not independent (they read the same field), so the stated yaw σ
//! is the weighted mean of theirs, as for fully correlated errors, never below the
//! smaller one. A live session has no future to read and uses the forward filter alone
//! ([`super::AttitudeFilter`]).

use nalgebra::Vector3;

use super::{
    estimate_attitude, AttitudeError, AttitudeEstimate, AttitudeOptions, AttitudeTrack, Sensors,
};
use crate::base::angle::wrap_to_pi;
use crate::io::recording::Stream;

/// How a whole log's attitude is run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Runs {
    /// The forward filter alone: each attitude from the log up to its time, as a device
    /// would have it. The dead reckoning's `gyro+ahrs` fuses this heading with the
    /// gyroscope itself, over the whole walk, and assumes its errors are the filter's.
    Forward,
    /// Forward and backward, combined: the attitude export. Without a field (or its
    /// reference) the runs' yaws have different origins, and the forward one is kept.
    BothWays,
}

/// `forward` ([`estimate_attitude`] over `sensors`) combined with the filter run
/// backward over the same log (see the module's text); the summary stays the forward
/// run's. Without a field to share, each run's yaw counts from its own first attitude
/// (the log's start, or its end): they cannot be combined, and `forward` is returned.
pub fn with_backward_run(
    forward: AttitudeTrack,
    sensors: Sensors<'_>,
    reference: Option<super::gates::FieldReference>,
    options: &AttitudeOptions,
) -> Result<AttitudeTrack, AttitudeError> {
    if reference.is_none() || sensors.field_in_body_ut.is_empty() {
        return Ok(forward);
    }
    let (acc, gyro, field) = (
        reversed(sensors.acc_in_body_mps2, 1.0),
        reversed(sensors.gyro_in_body_radps, -1.0),
        reversed(sensors.field_in_body_ut, 1.0),
    );
    let backward = estimate_attitude(
        Sensors {
            acc_in_body_mps2: &acc,
            gyro_in_body_radps: &gyro,
            field_in_body_ut: &field,
        },
        reference,
        options,
    )?;
    // The backward run's outputs from its last (the log's earliest time) on: its times
    // are the log's negated.
    let (times_b, values_b) = (&backward.attitude.t_s, &backward.attitude.values);
    let mut next_b = times_b.len().min(values_b.len());
    let mut attitude = Stream::default();
    for (&t_s, ahead) in forward.attitude.t_s.iter().zip(&forward.attitude.values) {
        while next_b > 0 && -times_b[next_b - 1] < t_s {
            next_b -= 1;
        }
        let combined = match next_b.checked_sub(1) {
            Some(idx) if -times_b[idx] == t_s => combine(ahead, &values_b[idx]),
            _ => *ahead,
        };
        attitude.push(t_s, combined);
    }
    Ok(AttitudeTrack {
        attitude,
        summary: forward.summary,
    })
}

/// The stream in reverse order at the negated times, each value times `sign`.
fn reversed(stream: &Stream<Vector3<f64>>, sign: f64) -> Stream<Vector3<f64>> {
    let mut reversed = stream.clone();
    reversed.t_s.reverse();
    reversed.values.reverse();
    for t_s in &mut reversed.t_s {
        *t_s = -*t_s;
    }
    for value in &mut reversed.values {
        *value *= sign;
    }
    reversed
}

/// One sample of the two runs combined: the yaw weighed by the other run's variance,
/// its σ the weighted mean of the two; roll and pitch the forward run's.
fn combine(forward: &AttitudeEstimate, backward: &AttitudeEstimate) -> AttitudeEstimate {
    let (var_f, var_b) = (
        forward.yaw_sigma_rad.powi(2),
        backward.yaw_sigma_rad.powi(2),
    );
    let weight_b = var_f / (var_f + var_b);
    // Equal weights where the variances say nothing (both zero or not finite).
    let weight_b = if weight_b.is_finite() { weight_b } else { 0.5 };
    AttitudeEstimate {
        yaw_rad: wrap_to_pi(
            forward.yaw_rad + weight_b * wrap_to_pi(backward.yaw_rad - forward.yaw_rad),
        ),
        yaw_sigma_rad: (1.0 - weight_b) * forward.yaw_sigma_rad + weight_b * backward.yaw_sigma_rad,
        field_used: forward.field_used || backward.field_used,
        ..*forward
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn estimate(yaw_deg: f64, sigma_deg: f64) -> AttitudeEstimate {
        AttitudeEstimate {
            roll_rad: 0.1,
            pitch_rad: -0.2,
            yaw_rad: yaw_deg.to_radians(),
            yaw_sigma_rad: sigma_deg.to_radians(),
            field_used: false,
        }
    }

    #[test]
    fn yaws_either_side_of_south_meet_at_south_and_the_surer_run_weighs_more() {
        let even = combine(&estimate(179.0, 2.0), &estimate(-179.0, 2.0));
        assert!(
            (even.yaw_rad.abs() - std::f64::consts::PI).abs() < 1e-9,
            "{even:?}"
        );
        assert!((even.yaw_sigma_rad.to_degrees() - 2.0).abs() < 1e-9);
        // σ 1° forward, 3° backward: the backward run weighs 1 / (1 + 9).
        let uneven = combine(&estimate(10.0, 1.0), &estimate(20.0, 3.0));
        assert!(
            (uneven.yaw_rad.to_degrees() - 11.0).abs() < 1e-9,
            "{uneven:?}"
        );
        assert!(
            (uneven.yaw_sigma_rad.to_degrees() - 1.2).abs() < 1e-9,
            "{uneven:?}"
        );
        assert_eq!((uneven.roll_rad, uneven.pitch_rad), (0.1, -0.2));
    }

    /// A gyroscope and an accelerometer alone: the forward run's yaw counts from the
    /// start, the backward one's from the end, so the export is the forward run.
    #[test]
    fn without_a_field_the_export_is_the_forward_run() {
        let (mut acc, mut gyro) = (Stream::default(), Stream::default());
        for idx in 0..500 {
            let t_s = idx as f64 * 0.02;
            acc.push(t_s, Vector3::new(0.0, 0.0, -9.81));
            gyro.push(t_s, Vector3::new(0.0, 0.0, 0.2));
        }
        let sensors = Sensors {
            acc_in_body_mps2: &acc,
            gyro_in_body_radps: &gyro,
            field_in_body_ut: &Stream::default(),
        };
        let options = AttitudeOptions::default();
        let forward = estimate_attitude(sensors, None, &options).expect("a track");
        let both = with_backward_run(forward.clone(), sensors, None, &options).expect("a track");
        assert_eq!(both, forward);
    }

    #[test]
    fn a_stream_reversed_runs_backwards_in_time_with_its_rates_negated() {
        let mut stream = Stream::default();
        stream.push(1.0, Vector3::new(1.0, 2.0, 3.0));
        stream.push(2.0, Vector3::new(4.0, 5.0, 6.0));
        let back = reversed(&stream, -1.0);
        assert_eq!(back.t_s, vec![-2.0, -1.0]);
        assert_eq!(back.values[0], Vector3::new(-4.0, -5.0, -6.0));
    }
}
