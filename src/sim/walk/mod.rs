//! A simulated walk with a phone held in hand, with its truth.
//!
//! The walk opens with a calibration circle (a full turn, as the 2007 paper's
//! autocalibration asks for), then alternates straight legs, turns and short stops.
//! Physics, per sample:
//!
//! - attitude: the true heading ψ, plus the hand's mean tilt and a sway at the step
//!   frequency (pitch) and half of it (roll);
//! - magnetometer: `m = S·(R_bodyᵀ·F_ned) + b_hard + noise`, Eq. 2-3 of the 2007 paper
//!   with a symmetric S (axis scale factors on its diagonal, soft iron off it: Eq. 5),
//!   the hard iron drifting with a temperature swing, and the Earth's field `F_ned` of a
//!   chosen magnitude, inclination and declination (from the World Magnetic Model at a
//!   place and date, which then also date the log: `WalkConfig::at_place`); optionally
//!   iron near the path, or instead a compass whose deviation is exactly Eq. 12 of the
//!   PDR paper;
//! - accelerometer: specific force `f = a − g` with a vertical bounce and a fore-aft
//!   surge at the step frequency while walking, rotated into the body frame;
//! - gyroscope: the exact body rates of the Euler-angle motion, plus bias and noise;
//! - GNSS (optional): fixes with noise, outages and multipath.
//!
//! The device's forward axis may be misaligned with the walking direction (the PDR
//! paper's β, Eq. 9). The truth is written as the reference columns. Besides a walk the
//! route may be a turntable's turns or a car's octagonal loop in a fixed mount
//! (`vehicle_loop`, a compass deviating by Eq. 12); `demo` is the committed demo,
//! `paper_raw_case` the 2007 paper's (12 ± 30)° raw error on a turntable and `pdr_walk`
//! the PDR scenario (varied gait, an Eq. 12 compass, GNSS with 3 m noise; 50 or 100 Hz).
//!
//! The gait is [`Gait::Steady`](crate::sim::gait::Gait::Steady) (fixed steps, the
//! committed demo's) or [`Gait::Varied`](crate::sim::gait::Gait::Varied) (steps that
//! vary, with accelerations that follow Weinberg's relation and the truth of every
//! step: `gait.rs`). [`simulate_with_truth`] returns that step truth with the log.
//!
//! The files: `config.rs` the scenario ([`WalkConfig`] and its named walks),
//! `trajectory.rs` the true motion (the route's phases, the gait, heading, position and
//! step truth), `sensors.rs` what the phone's sensors read of it, `gnss.rs` the
//! receiver's fixes; here, the sample loop that puts them together into rows.

mod config;
mod gnss;
mod sensors;
mod trajectory;

use serde::Serialize;

pub use self::config::{Disturbance, GnssSim, Multipath, Route, WalkConfig};
use super::gait::StepTruth;
use crate::base::angle::wrap_to_2pi;
use crate::base::rng::SplitMix64;
use crate::io::canonical_csv::CanonicalRow;

/// The truth of a walk beyond its reference columns.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct WalkTruth {
    /// The length of the path the truth position followed, summed sample by sample.
    pub path_length_m: f64,
    /// The steps, in order (empty for the steady gait,
    /// [`Gait::Steady`](crate::sim::gait::Gait::Steady)); their lengths add up to
    /// `path_length_m`.
    pub steps: Vec<StepTruth>,
}

/// Simulates the walk: one canonical row per sample.
pub fn simulate(config: &WalkConfig) -> Vec<CanonicalRow> {
    simulate_with_truth(config).0
}

/// Simulates the walk: one canonical row per sample, and the truth of its steps. The
/// rows are those of [`simulate`].
///
/// One random stream serves the whole walk, in a fixed order (the route's legs and
/// turns, then per sample the accelerometer's, gyroscope's and magnetometer's noise and
/// the receiver's draws), so that a seed gives the same log byte for byte.
pub fn simulate_with_truth(config: &WalkConfig) -> (Vec<CanonicalRow>, WalkTruth) {
    let mut rng = SplitMix64::new(config.seed);
    let phases = trajectory::route_phases(config, &mut rng);
    let dt_s = 1.0 / config.sample_rate_hz;
    let n_samples = (config.duration_s * config.sample_rate_hz).round() as usize;
    let t0_s = config.start_unix_s.unwrap_or(0.0);
    let sensors = sensors::Sensors::new(config);
    let mut receiver = gnss::Receiver::new(config);
    let mut trajectory = trajectory::Trajectory::new(config, phases);
    let mut rows = Vec::with_capacity(n_samples);
    for sample_idx in 0..n_samples {
        let sample = trajectory.sample(sample_idx, dt_s);
        let reading = sensors.read(&sample, &mut rng);
        let mut row = CanonicalRow {
            t_s: t0_s + sample.t_s,
            acc_mps2: Some(reading.acc_mps2),
            gyro_radps: Some(reading.gyro_radps),
            mag_ut: Some(reading.mag_ut),
            temp_c: Some(reading.temp_c),
            ref_heading_deg: Some(wrap_to_2pi(reading.device_heading_rad).to_degrees()),
            ref_en_m: Some(sample.position_en_m),
            ..CanonicalRow::default()
        };
        if let Some(receiver) = receiver.as_mut() {
            receiver.fix(&mut row, &sample, &mut rng);
        }
        rows.push(row);
        trajectory.advance(&sample);
    }
    (rows, trajectory.into_truth())
}

#[cfg(test)]
mod tests;
