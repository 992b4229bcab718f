//! Integrated gyro heading: a reference that follows every turn, anchored where an
//! absolute reference exists.
//!
//! Source: the 2007 paper (`compass-calibration-ann-2007.txt`, Section 3) feeds a gyro
//! heading to its network; the PDR paper's Fig. 2 bridges GPS gaps with relative
//! sensors. The heading rate of a body with roll φ and pitch θ (x forward, y right,
//! z down; yaw-pitch-roll Euler angles) is
//!
//! ```text
//! ψ̇ = (q·sin φ + r·cos φ) / cos θ
//! ```
//!
//! where (p, q, r) are the body rates. Roll and pitch come from the accelerometer
//! averaged over a window, as for tilt compensation. The integral is relative; it is
//! made absolute in one of three ways, and the result says which:
//!
//! - **anchored**: an absolute reference (GPS course, a reference column, map legs)
//!   gives the offset at its first samples, and, where it spans at least a minute, a
//!   linear drift (a constant gyro bias) fitted by least squares to all its samples;
//! - **closed loop**: the user says the walk ends where it started. Dead-reckoning the
//!   walk at a constant pace while walking (the accelerometer varies) with the gyro
//!   heading, the drift is the constant rate that makes the path close on its start
//!   (searched over ±2.9°/s, then refined). A loop need not end facing as it began (one
//!   that starts at a corner ends 90° off), so the heading alone cannot say this. The
//!   offset is unknown (the start is 0°);
//! - **relative**: neither; the start is 0° and drift is not corrected.

use nalgebra::Vector3;
use serde::Serialize;

use crate::attitude::down::GravityEstimate;
use crate::attitude::tilt::Tilt;
use crate::base::angle::wrap_to_pi;
use crate::io::recording::{Recording, Stream};

/// Gyro samples further apart than this (s), or than three of the log's typical
/// intervals where that is longer (a log of per-second means), are a gap: the turn
/// across it is unknown.
const MAX_GYRO_GAP_S: f64 = 0.5;

/// How far apart (s) anchor samples must spread before a drift is fitted.
const MIN_DRIFT_SPAN_S: f64 = 60.0;
/// The largest drift searched for a closed loop (rad/s, about 2.9°/s: far beyond any
/// phone gyro's bias).
const MAX_LOOP_DRIFT_RADPS: f64 = 0.05;
/// Specific force varying more than this (m/s², standard deviation over a second)
/// means walking.
const WALKING_ACC_STD_MPS2: f64 = 0.6;

/// How the integrated heading was made absolute.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum GyroAlignment {
    Anchored {
        n_anchor_samples: usize,
        /// The drift fitted (deg/min), `None` when the anchors spanned too short a time.
        drift_deg_per_min: Option<f64>,
        /// RMS of the anchors about the aligned gyro heading (deg).
        residual_rms_deg: f64,
    },
    ClosedLoop {
        drift_deg_per_min: f64,
        /// The turn from start to end after the drift is removed (deg).
        turned_deg: f64,
        /// How far the dead-reckoned loop misses its start, in % of its length.
        closure_pct: f64,
    },
    Relative,
}

/// The integrated heading (clockwise from north where anchored) at the gyro's times.
#[derive(Debug, Clone, PartialEq)]
pub struct GyroHeading {
    pub heading_rad: Stream<f64>,
    pub alignment: GyroAlignment,
    /// Gaps in the gyro stream longer than 0.5 s (the heading after each is less sure).
    pub n_gaps: usize,
}

/// Integrates the gyro of `recording`, levelled with `gravity` (the recording's own,
/// [`crate::attitude::down::gravity_of`]); `None` without gyro samples.
pub fn gyro_heading(
    recording: &Recording,
    gravity: &GravityEstimate,
    anchor: Option<&Stream<f64>>,
    closed_loop: bool,
) -> Option<GyroHeading> {
    let gyro = &recording.gyro_in_body_radps;
    let max_gap_s = gyro.gap_limit_s(MAX_GYRO_GAP_S);
    let (relative, n_gaps) = integrate_heading_rate(gyro, &gravity.specific_force_mps2, max_gap_s);
    let (&first_t_s, &last_t_s) = (relative.t_s.first()?, relative.t_s.last()?);

    let anchored = anchor.and_then(|anchor| anchored_heading(&relative, anchor, max_gap_s));
    if let Some((heading_rad, alignment)) = anchored {
        return Some(GyroHeading {
            heading_rad,
            alignment,
            n_gaps,
        });
    }

    let span_s = last_t_s - first_t_s;
    let (drift_radps, alignment) = match closed_loop
        .then(|| loop_closing_drift(recording, &relative))
        .flatten()
    {
        Some((drift_radps, closure_pct)) => {
            let turned_rad = relative.values.last().copied().unwrap_or(0.0)
                - relative.values.first().copied().unwrap_or(0.0)
                - drift_radps * span_s;
            (
                drift_radps,
                GyroAlignment::ClosedLoop {
                    drift_deg_per_min: drift_radps.to_degrees() * 60.0,
                    turned_deg: turned_rad.to_degrees(),
                    closure_pct,
                },
            )
        }
        None => (0.0, GyroAlignment::Relative),
    };
    let mut heading = Stream::default();
    for (&t_s, &gyro_rad) in relative.t_s.iter().zip(&relative.values) {
        heading.push(
            t_s,
            crate::base::angle::wrap_to_2pi(gyro_rad - drift_radps * (t_s - first_t_s)),
        );
    }
    Some(GyroHeading {
        heading_rad: heading,
        alignment,
        n_gaps,
    })
}

/// The heading rate of each gyro sample, levelled with the specific force `gravity_mps2`
/// (level without one), integrated from 0 by trapezoids: the relative heading (rad) at
/// the samples kept, and how many gaps longer than `max_gap_s` it crossed.
fn integrate_heading_rate(
    gyro: &Stream<Vector3<f64>>,
    gravity_mps2: &Stream<Vector3<f64>>,
    max_gap_s: f64,
) -> (Stream<f64>, usize) {
    let mut relative = Stream::default();
    let mut heading_rad = 0.0;
    let mut previous: Option<(f64, f64)> = None;
    let mut n_gaps = 0usize;
    for (&t_s, rate) in gyro.t_s.iter().zip(&gyro.values) {
        let tilt = if gravity_mps2.is_empty() {
            Some(Tilt::LEVEL)
        } else {
            gravity_mps2
                .interpolate_at(t_s, max_gap_s)
                .and_then(Tilt::from_specific_force)
        };
        let Some(tilt) = tilt else { continue };
        let (_, cos_pitch) = tilt.pitch_sin_cos();
        if cos_pitch.abs() < 0.1 || !rate.iter().all(|value| value.is_finite()) {
            // Near ±90° pitch the heading rate is undefined.
            continue;
        }
        let (sin_roll, cos_roll) = tilt.roll_sin_cos();
        let heading_rate_radps = (rate.y * sin_roll + rate.z * cos_roll) / cos_pitch;
        if let Some((previous_t_s, previous_rate_radps)) = previous {
            let dt_s = t_s - previous_t_s;
            if dt_s > max_gap_s {
                n_gaps += 1;
            } else if dt_s > 0.0 {
                heading_rad += 0.5 * (heading_rate_radps + previous_rate_radps) * dt_s;
            }
        }
        previous = Some((t_s, heading_rate_radps));
        relative.push(t_s, heading_rad);
    }
    (relative, n_gaps)
}

/// The relative heading made absolute by `anchor`: its offset, and its drift where the
/// anchor spans at least [`MIN_DRIFT_SPAN_S`]; `None` when no anchor sample meets the gyro.
fn anchored_heading(
    relative: &Stream<f64>,
    anchor: &Stream<f64>,
    max_gap_s: f64,
) -> Option<(Stream<f64>, GyroAlignment)> {
    // Offsets anchor − gyro, unwrapped along time.
    let mut offsets: Vec<(f64, f64)> = Vec::new();
    for (&t_s, &reference_rad) in anchor.t_s.iter().zip(&anchor.values) {
        let Some(gyro_rad) = relative.interpolate_at(t_s, max_gap_s) else {
            continue;
        };
        let offset_rad = wrap_to_pi(reference_rad - gyro_rad);
        let unwrapped = offsets.last().map_or(offset_rad, |&(_, previous_rad)| {
            previous_rad + wrap_to_pi(offset_rad - previous_rad)
        });
        offsets.push((t_s, unwrapped));
    }
    let n = offsets.len();
    let (&(t0_s, _), &(t1_s, _)) = (offsets.first()?, offsets.last()?);
    let mean_t_s = offsets.iter().map(|(t_s, _)| t_s).sum::<f64>() / n as f64;
    let mean_offset_rad = offsets.iter().map(|(_, offset)| offset).sum::<f64>() / n as f64;
    let drift_radps = if t1_s - t0_s >= MIN_DRIFT_SPAN_S {
        let (mut sxy, mut sxx) = (0.0, 0.0);
        for &(t_s, offset_rad) in &offsets {
            sxy += (t_s - mean_t_s) * (offset_rad - mean_offset_rad);
            sxx += (t_s - mean_t_s).powi(2);
        }
        (sxx > 0.0).then(|| sxy / sxx)
    } else {
        None
    };
    let correction = |t_s: f64| mean_offset_rad + drift_radps.unwrap_or(0.0) * (t_s - mean_t_s);
    let residual_rms_deg = (offsets
        .iter()
        .map(|&(t_s, offset_rad)| (offset_rad - correction(t_s)).powi(2))
        .sum::<f64>()
        / n as f64)
        .sqrt()
        .to_degrees();
    let mut heading = Stream::default();
    for (&t_s, &gyro_rad) in relative.t_s.iter().zip(&relative.values) {
        heading.push(
            t_s,
            crate::base::angle::wrap_to_2pi(gyro_rad + correction(t_s)),
        );
    }
    let alignment = GyroAlignment::Anchored {
        n_anchor_samples: n,
        drift_deg_per_min: drift_radps.map(|drift| drift.to_degrees() * 60.0),
        residual_rms_deg,
    };
    Some((heading, alignment))
}

/// The drift (rad/s) that closes the dead-reckoned loop, and how far it then misses
/// (% of the path length); `None` without walking.
fn loop_closing_drift(recording: &Recording, relative: &Stream<f64>) -> Option<(f64, f64)> {
    // Walking where the specific force varies over a one-second window.
    let acc = &recording.acc_in_body_mps2;
    let magnitudes: Vec<f64> = acc.values.iter().map(nalgebra::Matrix::norm).collect();
    let mut walking = Stream::default();
    let (mut start, mut end) = (0usize, 0usize);
    let (mut sum, mut sum_sq) = (0.0, 0.0);
    for &t_s in &acc.t_s {
        while let (Some(&end_t_s), Some(&value)) = (acc.t_s.get(end), magnitudes.get(end)) {
            if end_t_s > t_s + 0.5 {
                break;
            }
            sum += value;
            sum_sq += value * value;
            end += 1;
        }
        while let (Some(&start_t_s), Some(&value)) = (acc.t_s.get(start), magnitudes.get(start)) {
            if start >= end || start_t_s >= t_s - 0.5 {
                break;
            }
            sum -= value;
            sum_sq -= value * value;
            start += 1;
        }
        let n = (end - start).max(1) as f64;
        let variance = (sum_sq / n - (sum / n).powi(2)).max(0.0);
        walking.push(
            t_s,
            if variance.sqrt() > WALKING_ACC_STD_MPS2 {
                1.0
            } else {
                0.0
            },
        );
    }
    // Each gyro step: (dt, heading, walking).
    let first_t_s = *relative.t_s.first()?;
    let max_gap_s = relative.gap_limit_s(MAX_GYRO_GAP_S);
    let steps: Vec<(f64, f64, f64)> = relative
        .t_s
        .windows(2)
        .zip(relative.values.iter().skip(1))
        .filter_map(|(pair, &heading_rad)| {
            let [t0_s, t1_s] = pair else { return None };
            let dt_s = t1_s - t0_s;
            let is_walking = walking.interpolate_at(*t1_s, 0.5).unwrap_or(0.0);
            (dt_s > 0.0 && dt_s <= max_gap_s && is_walking > 0.5).then_some((
                dt_s,
                heading_rad,
                t1_s - first_t_s,
            ))
        })
        .collect();
    let path_length: f64 = steps.iter().map(|step| step.0).sum();
    if path_length <= 0.0 {
        return None;
    }
    let miss = |drift_radps: f64| {
        let (mut east, mut north) = (0.0, 0.0);
        for &(dt_s, heading_rad, elapsed_s) in &steps {
            let (sin, cos) = (heading_rad - drift_radps * elapsed_s).sin_cos();
            east += sin * dt_s;
            north += cos * dt_s;
        }
        nalgebra::Vector2::new(east, north).norm()
    };
    // A grid, then golden-section refinement around the best point.
    let n_grid = 400;
    let step_radps = 2.0 * MAX_LOOP_DRIFT_RADPS / n_grid as f64;
    let mut best = (0.0, miss(0.0));
    for idx in 0..=n_grid {
        let drift_radps = -MAX_LOOP_DRIFT_RADPS + idx as f64 * step_radps;
        let value = miss(drift_radps);
        if value < best.1 {
            best = (drift_radps, value);
        }
    }
    let (mut low, mut high) = (best.0 - step_radps, best.0 + step_radps);
    let ratio = (5f64.sqrt() - 1.0) / 2.0;
    for _ in 0..40 {
        let a = high - ratio * (high - low);
        let b = low + ratio * (high - low);
        if miss(a) < miss(b) {
            high = b;
        } else {
            low = a;
        }
    }
    let drift_radps = (low + high) / 2.0;
    Some((drift_radps, 100.0 * miss(drift_radps) / path_length))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    use crate::attitude::down::gravity_of;
    use crate::io::STANDARD_GRAVITY_MPS2;

    /// A level device turning at `rate_radps` about the vertical, with a gyro bias.
    fn turning(duration_s: f64, rate_radps: f64, bias_radps: f64) -> Recording {
        let mut recording = Recording::default();
        let n = (duration_s * 50.0) as usize;
        for idx in 0..=n {
            let t_s = idx as f64 / 50.0;
            recording
                .gyro_in_body_radps
                .push(t_s, Vector3::new(0.0, 0.0, rate_radps + bias_radps));
            recording
                .acc_in_body_mps2
                .push(t_s, Vector3::new(0.0, 0.0, -STANDARD_GRAVITY_MPS2));
        }
        recording
    }

    #[test]
    fn anchors_give_the_offset_and_the_drift() {
        let recording = turning(300.0, 0.05, 0.002);
        // The true heading is 1.0 + 0.05 t; anchors every 10 s.
        let mut anchor = Stream::default();
        for idx in 0..30 {
            let t_s = idx as f64 * 10.0;
            anchor.push(t_s, crate::base::angle::wrap_to_2pi(1.0 + 0.05 * t_s));
        }
        let gyro = gyro_heading(
            &recording,
            &gravity_of(&recording, 1.0),
            Some(&anchor),
            false,
        )
        .expect("gyro");
        let GyroAlignment::Anchored {
            drift_deg_per_min: Some(drift_deg_per_min),
            ..
        } = gyro.alignment
        else {
            panic!("{:?}", gyro.alignment)
        };
        assert!((drift_deg_per_min + 0.002f64.to_degrees() * 60.0).abs() < 1e-6);
        for (&t_s, &heading_rad) in gyro.heading_rad.t_s.iter().zip(&gyro.heading_rad.values) {
            let truth = 1.0 + 0.05 * t_s;
            assert!(wrap_to_pi(heading_rad - truth).abs() < 1e-6, "{t_s}");
        }
    }

    #[test]
    fn a_closed_loop_gives_the_drift_that_closes_it() {
        // A square with rounded corners walked from the middle of a side: 10 s, then
        // three 20 s sides and 10 s, with four 90° right turns walked in 2 s between
        // them, a 0.003 rad/s gyro bias, and the step bounce that says "walking".
        let bias_radps = 0.003;
        let mut recording = Recording::default();
        let (leg_s, turn_s) = (20.0, 2.0);
        let total_s = 4.0 * leg_s + 4.0 * turn_s;
        let n = (total_s * 50.0) as usize;
        for idx in 0..=n {
            let t_s = idx as f64 / 50.0;
            let in_cycle_s = (t_s + leg_s / 2.0) % (leg_s + turn_s);
            let turning = in_cycle_s >= leg_s;
            let rate_radps = if turning {
                std::f64::consts::FRAC_PI_2 / turn_s
            } else {
                0.0
            };
            recording
                .gyro_in_body_radps
                .push(t_s, Vector3::new(0.0, 0.0, rate_radps + bias_radps));
            let bounce = 2.0 * (std::f64::consts::TAU * 2.0 * t_s).sin();
            recording
                .acc_in_body_mps2
                .push(t_s, Vector3::new(0.0, 0.0, -STANDARD_GRAVITY_MPS2 + bounce));
        }
        let gyro =
            gyro_heading(&recording, &gravity_of(&recording, 1.0), None, true).expect("gyro");
        let GyroAlignment::ClosedLoop {
            drift_deg_per_min,
            turned_deg,
            closure_pct,
        } = gyro.alignment
        else {
            panic!("{:?}", gyro.alignment)
        };
        let expected = bias_radps.to_degrees() * 60.0;
        assert!(
            (drift_deg_per_min - expected).abs() < 0.05 * expected,
            "{drift_deg_per_min} vs {expected}"
        );
        assert!((turned_deg - 360.0).abs() < 3.0, "{turned_deg}");
        assert!(closure_pct < 1.0, "{closure_pct}");
        // Without the loop, nothing is corrected.
        let relative =
            gyro_heading(&recording, &gravity_of(&recording, 1.0), None, false).expect("gyro");
        assert_eq!(relative.alignment, GyroAlignment::Relative);
        assert!(gyro_heading(
            &Recording::default(),
            &gravity_of(&Recording::default(), 1.0),
            None,
            false
        )
        .is_none());
    }
}
