//! A simulated walk with a phone held in hand, with its truth.
//!
//! The walk opens with a calibration circle (a full turn, as the 2007 paper's
//! autocalibration asks for), then alternates straight legs, turns and short stops.
//! Physics, per sample:
//!
//! - attitude: the true heading ψ, plus the hand's mean tilt and a sway at the step
//!   frequency (pitch) and half of it (roll);
//! - magnetometer: `m = S·(R_bodyᵀ·F_ned) + b_hard + noise`, Eq. 2-3 of the 2007 paper
//!   with a diagonal S (axis scale factors) and the Earth's field `F_ned` of a chosen
//!   magnitude and inclination, declination zero (so magnetic north is true north);
//! - accelerometer: specific force `f = a − g` with a vertical bounce and a fore-aft
//!   surge at the step frequency while walking, rotated into the body frame;
//! - gyroscope: the exact body rates of the Euler-angle motion, plus bias and noise.

use nalgebra::{Rotation3, Vector2, Vector3};
use serde::Serialize;

use super::rng::SplitMix64;
use crate::angle::wrap_to_2pi;
use crate::geo::{Geodetic, LocalFrame};
use crate::io::canonical_csv::CanonicalRow;

const G_MPS2: f64 = 9.81;

/// Everything that defines a simulated walk. [`WalkConfig::from_seed`] draws the
/// distortions from the seed, so the truth travels with the log.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WalkConfig {
    pub seed: u64,
    pub duration_s: f64,
    pub sample_rate_hz: f64,
    /// Earth's field: total intensity and inclination (dip, positive down).
    pub field_total_ut: f64,
    pub inclination_deg: f64,
    /// Hard iron in the body frame.
    pub hard_iron_ut: [f64; 3],
    /// Axis scale factors (the diagonal of S).
    pub scale: [f64; 3],
    pub mag_noise_ut: f64,
    pub acc_noise_mps2: f64,
    pub gyro_bias_radps: [f64; 3],
    pub gyro_noise_radps: f64,
    pub step_frequency_hz: f64,
    pub step_length_m: f64,
    /// The hand's mean tilt and the sway about it while walking.
    pub mean_pitch_deg: f64,
    pub mean_roll_deg: f64,
    pub sway_pitch_deg: f64,
    pub sway_roll_deg: f64,
    pub start_heading_deg: f64,
    /// Misalignment β: the device's forward axis is this far clockwise of the walking
    /// direction (the PDR paper, Eq. 9).
    pub misalignment_deg: f64,
    /// A compass whose raw heading deviates by exactly the unified model (the PDR
    /// paper's Eq. 12, A to E in degrees) instead of by hard and soft iron: the field it
    /// senses is turned about the vertical so that true = raw + δ(raw).
    pub deviation_deg: Option<[f64; 5]>,
    /// Temperature: the walk's temperature swings by this much (°C) about 22 °C with
    /// this period (s); zero swing keeps a slow warming from 22 to 25 °C.
    pub temp_swing_c: f64,
    pub temp_period_s: f64,
    /// Hard-iron drift with temperature (µT/°C per axis, about 22 °C).
    pub hard_iron_temp_coeff_ut_per_c: [f64; 3],
    /// A GNSS receiver, if the walk has one.
    pub gnss: Option<GnssSim>,
}

/// A simulated GNSS receiver: fixes at `rate_hz` with position noise, and a course over
/// ground with noise while moving.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct GnssSim {
    pub rate_hz: f64,
    pub origin_lat_deg: f64,
    pub origin_lon_deg: f64,
    pub position_noise_m: f64,
    pub course_noise_deg: f64,
    /// The accuracy the receiver reports (m).
    pub hacc_m: f64,
}

impl Default for GnssSim {
    fn default() -> Self {
        GnssSim {
            rate_hz: 1.0,
            origin_lat_deg: 60.1699,
            origin_lon_deg: 24.9384,
            position_noise_m: 2.0,
            course_noise_deg: 2.0,
            hacc_m: 3.0,
        }
    }
}

impl WalkConfig {
    /// A walk of `duration_s` at 50 Hz whose distortions come from `seed`: hard iron up
    /// to 30 µT per axis, scale factors 0.9-1.1, noise 0.3 µT.
    pub fn from_seed(seed: u64, duration_s: f64) -> Self {
        let mut rng = SplitMix64::new(seed ^ 0x00C0_FFEE);
        let mut draw3 = |low: f64, high: f64| {
            [
                rng.uniform_in(low, high),
                rng.uniform_in(low, high),
                rng.uniform_in(low, high),
            ]
        };
        let hard_iron_ut = draw3(-30.0, 30.0);
        let scale = draw3(0.9, 1.1);
        let gyro_bias_radps = draw3(-0.01, 0.01);
        let start_heading_deg = (seed.wrapping_mul(37) % 360) as f64;
        WalkConfig {
            seed,
            duration_s,
            sample_rate_hz: 50.0,
            field_total_ut: 50.0,
            inclination_deg: 60.0,
            hard_iron_ut,
            scale,
            mag_noise_ut: 0.3,
            acc_noise_mps2: 0.05,
            gyro_bias_radps,
            gyro_noise_radps: 0.005,
            step_frequency_hz: 1.8,
            step_length_m: 0.7,
            mean_pitch_deg: 6.0,
            mean_roll_deg: -3.0,
            sway_pitch_deg: 2.0,
            sway_roll_deg: 1.5,
            start_heading_deg,
            misalignment_deg: 0.0,
            deviation_deg: None,
            temp_swing_c: 0.0,
            temp_period_s: 600.0,
            hard_iron_temp_coeff_ut_per_c: [0.0; 3],
            gnss: None,
        }
    }
}

/// One phase of the walk: how long, whether walking, and the turn rate.
#[derive(Debug, Clone, Copy)]
struct Phase {
    duration_s: f64,
    is_walking: bool,
    turn_rate_radps: f64,
}

/// The route: stand, walk a calibration circle, then legs, turns and stops.
fn plan_route(config: &WalkConfig, rng: &mut SplitMix64) -> Vec<Phase> {
    let circle_s = 24.0;
    let mut phases = vec![
        Phase {
            duration_s: 3.0,
            is_walking: false,
            turn_rate_radps: 0.0,
        },
        Phase {
            duration_s: circle_s,
            is_walking: true,
            turn_rate_radps: std::f64::consts::TAU / circle_s,
        },
    ];
    let mut planned_s: f64 = phases.iter().map(|phase| phase.duration_s).sum();
    let mut leg_idx = 0usize;
    while planned_s < config.duration_s {
        let leg_s = rng.uniform_in(10.0, 25.0);
        phases.push(Phase {
            duration_s: leg_s,
            is_walking: true,
            turn_rate_radps: 0.0,
        });
        let turn_deg: f64 =
            [90.0, -90.0, 45.0, -135.0, 180.0, -45.0][(rng.next_u64() % 6) as usize];
        let turn_s = 2.0 + turn_deg.abs() / 90.0;
        phases.push(Phase {
            duration_s: turn_s,
            is_walking: true,
            turn_rate_radps: f64::to_radians(turn_deg) / turn_s,
        });
        planned_s += leg_s + turn_s;
        leg_idx += 1;
        if leg_idx.is_multiple_of(4) {
            phases.push(Phase {
                duration_s: 4.0,
                is_walking: false,
                turn_rate_radps: 0.0,
            });
            planned_s += 4.0;
        }
    }
    phases
}

/// Simulates the walk: one canonical row per sample.
pub fn simulate(config: &WalkConfig) -> Vec<CanonicalRow> {
    let mut rng = SplitMix64::new(config.seed);
    let phases = plan_route(config, &mut rng);
    let dt_s = 1.0 / config.sample_rate_hz;
    let n_samples = (config.duration_s * config.sample_rate_hz).round() as usize;

    let inclination_rad = config.inclination_deg.to_radians();
    let field_in_ned_ut = Vector3::new(
        config.field_total_ut * inclination_rad.cos(),
        0.0,
        config.field_total_ut * inclination_rad.sin(),
    );
    let hard_iron_ut = Vector3::from(config.hard_iron_ut);
    let scale = Vector3::from(config.scale);
    let gyro_bias_radps = Vector3::from(config.gyro_bias_radps);
    let step_omega_radps = std::f64::consts::TAU * config.step_frequency_hz;
    let walking_speed_mps = config.step_length_m * config.step_frequency_hz;

    let mut heading_rad = config.start_heading_deg.to_radians();
    let mut position_en_m = Vector2::zeros();
    let mut phase_idx = 0usize;
    let mut phase_start_s = 0.0;
    // The sway fades in and out over a second when walking starts and stops.
    let mut gait_weight = 0.0f64;
    let mut rows = Vec::with_capacity(n_samples);
    let gnss_frame = config.gnss.map(|gnss| {
        LocalFrame::at(Geodetic {
            lat_deg: gnss.origin_lat_deg,
            lon_deg: gnss.origin_lon_deg,
            alt_m: 0.0,
        })
    });
    for sample_idx in 0..n_samples {
        let t_s = sample_idx as f64 * dt_s;
        while phase_idx + 1 < phases.len() && t_s >= phase_start_s + phases[phase_idx].duration_s {
            phase_start_s += phases[phase_idx].duration_s;
            phase_idx += 1;
        }
        let phase = phases.get(phase_idx).copied().unwrap_or(Phase {
            duration_s: 0.0,
            is_walking: false,
            turn_rate_radps: 0.0,
        });
        let target_weight = if phase.is_walking { 1.0 } else { 0.0 };
        gait_weight += (target_weight - gait_weight) * (dt_s / 0.5).min(1.0);
        let gait_phase_rad = step_omega_radps * t_s;

        // Attitude and its rate (for the gyroscope).
        let sway_pitch_rad = gait_weight * config.sway_pitch_deg.to_radians();
        let sway_roll_rad = gait_weight * config.sway_roll_deg.to_radians();
        let pitch_rad = config.mean_pitch_deg.to_radians() + sway_pitch_rad * gait_phase_rad.sin();
        let roll_rad =
            config.mean_roll_deg.to_radians() + sway_roll_rad * (gait_phase_rad / 2.0).sin();
        let pitch_rate_radps = sway_pitch_rad * step_omega_radps * gait_phase_rad.cos();
        let roll_rate_radps = sway_roll_rad * step_omega_radps / 2.0 * (gait_phase_rad / 2.0).cos();
        let yaw_rate_radps = phase.turn_rate_radps;
        // The device faces the walking direction plus the misalignment.
        let device_heading_rad = heading_rad + config.misalignment_deg.to_radians();
        let ned_from_body = Rotation3::from_euler_angles(roll_rad, pitch_rad, device_heading_rad);
        let body_from_ned = ned_from_body.inverse();

        // Specific force: body acceleration minus gravity (NED, down positive).
        let bounce_mps2 = gait_weight * 1.5 * gait_phase_rad.sin();
        let surge_mps2 = gait_weight * 0.8 * gait_phase_rad.cos();
        let acc_in_ned_mps2 = Vector3::new(
            surge_mps2 * heading_rad.cos(),
            surge_mps2 * heading_rad.sin(),
            bounce_mps2,
        );
        let f_in_ned_mps2 = acc_in_ned_mps2 - Vector3::new(0.0, 0.0, G_MPS2);
        let f_in_body_mps2 =
            body_from_ned * f_in_ned_mps2 + noise3(&mut rng, config.acc_noise_mps2);

        // Body rates of a yaw-pitch-roll motion.
        let (sin_roll, cos_roll) = roll_rad.sin_cos();
        let (sin_pitch, cos_pitch) = pitch_rad.sin_cos();
        let rate_in_body_radps = Vector3::new(
            roll_rate_radps - yaw_rate_radps * sin_pitch,
            pitch_rate_radps * cos_roll + yaw_rate_radps * sin_roll * cos_pitch,
            -pitch_rate_radps * sin_roll + yaw_rate_radps * cos_roll * cos_pitch,
        );
        let gyro_radps =
            rate_in_body_radps + gyro_bias_radps + noise3(&mut rng, config.gyro_noise_radps);

        let temp_c = if config.temp_swing_c > 0.0 {
            22.0 + config.temp_swing_c
                * (std::f64::consts::TAU * t_s / config.temp_period_s.max(1.0)).sin()
        } else {
            22.0 + 3.0 * t_s / config.duration_s.max(1.0)
        };
        let mag_ut = match config.deviation_deg {
            Some(coefficients_deg) => {
                // Turn the sensed field so that the level heading reads ψ' with
                // ψ = ψ' + δ(ψ'): the sensed field's azimuth is δ(ψ').
                let deviation_rad = deviation_of(device_heading_rad, &coefficients_deg);
                let turned =
                    Rotation3::from_axis_angle(&Vector3::z_axis(), deviation_rad) * field_in_ned_ut;
                body_from_ned * turned + noise3(&mut rng, config.mag_noise_ut)
            }
            None => {
                let drift_ut =
                    Vector3::from(config.hard_iron_temp_coeff_ut_per_c) * (temp_c - 22.0);
                (body_from_ned * field_in_ned_ut).component_mul(&scale)
                    + hard_iron_ut
                    + drift_ut
                    + noise3(&mut rng, config.mag_noise_ut)
            }
        };

        rows.push(CanonicalRow {
            t_s,
            acc_mps2: Some(f_in_body_mps2),
            gyro_radps: Some(gyro_radps),
            mag_ut: Some(mag_ut),
            temp_c: Some(temp_c),
            ref_heading_deg: Some(wrap_to_2pi(device_heading_rad).to_degrees()),
            ref_en_m: Some(position_en_m),
            ..CanonicalRow::default()
        });
        if let (Some(gnss), Some(frame), Some(row)) =
            (config.gnss, gnss_frame.as_ref(), rows.last_mut())
        {
            let every = (config.sample_rate_hz / gnss.rate_hz).round().max(1.0) as usize;
            if sample_idx % every == 0 {
                let noisy_en_m = position_en_m
                    + Vector2::new(rng.gaussian(), rng.gaussian()) * gnss.position_noise_m;
                let position = frame.geodetic_of(Vector3::new(noisy_en_m.x, noisy_en_m.y, 0.0));
                let speed_mps = gait_weight * walking_speed_mps;
                row.lat_deg = Some(position.lat_deg);
                row.lon_deg = Some(position.lon_deg);
                row.gps_hacc_m = Some(gnss.hacc_m);
                row.gps_speed_mps = Some(speed_mps + 0.05 * rng.gaussian());
                // A receiver's course follows the velocity: the walking direction.
                row.gps_course_deg = Some(
                    wrap_to_2pi(heading_rad + gnss.course_noise_deg.to_radians() * rng.gaussian())
                        .to_degrees(),
                );
            }
        }

        // Advance the truth to the next sample.
        heading_rad += yaw_rate_radps * dt_s;
        let speed_mps = gait_weight * walking_speed_mps;
        position_en_m += Vector2::new(heading_rad.sin(), heading_rad.cos()) * speed_mps * dt_s;
    }
    rows
}

/// δ(ψ') for a true heading ψ: solves ψ = ψ' + δ(ψ') by Newton's method (δ' > −1 for
/// any deviation a compass can have, so the root is unique).
fn deviation_of(true_heading_rad: f64, coefficients_deg: &[f64; 5]) -> f64 {
    let [a, b, c, d, e] = coefficients_deg.map(f64::to_radians);
    let delta = |raw: f64| {
        a + b * raw.sin() + c * raw.cos() + d * (2.0 * raw).sin() + e * (2.0 * raw).cos()
    };
    let slope = |raw: f64| {
        b * raw.cos() - c * raw.sin() + 2.0 * d * (2.0 * raw).cos() - 2.0 * e * (2.0 * raw).sin()
    };
    let mut raw_rad = true_heading_rad - a;
    for _ in 0..30 {
        let residual = raw_rad + delta(raw_rad) - true_heading_rad;
        let derivative = 1.0 + slope(raw_rad);
        if derivative.abs() < 1e-6 {
            break;
        }
        raw_rad -= residual / derivative;
        if residual.abs() < 1e-13 {
            break;
        }
    }
    delta(raw_rad)
}

fn noise3(rng: &mut SplitMix64, sigma: f64) -> Vector3<f64> {
    Vector3::new(rng.gaussian(), rng.gaussian(), rng.gaussian()) * sigma
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::analyse_file;
    use crate::calibration::{CalibrationOptions, Method, MethodParameters};
    use crate::io::canonical_csv;

    #[test]
    fn the_same_seed_gives_the_same_log() {
        let config = WalkConfig::from_seed(3, 20.0);
        assert_eq!(simulate(&config), simulate(&config));
        assert_ne!(simulate(&config), simulate(&WalkConfig::from_seed(4, 20.0)));
    }

    #[test]
    fn the_walk_has_the_requested_length_and_a_level_rest_reading() {
        let config = WalkConfig::from_seed(1, 60.0);
        let rows = simulate(&config);
        assert_eq!(rows.len(), 3000);
        let first_acc = rows[0].acc_mps2.unwrap_or_default();
        assert!((first_acc.norm() - G_MPS2).abs() < 0.3, "{first_acc:?}");
        assert!(
            first_acc.z < -9.0,
            "a nearly level device reads z ≈ −g: {first_acc:?}"
        );
    }

    #[test]
    fn minmax_recovers_the_simulated_heading() {
        let config = WalkConfig::from_seed(11, 120.0);
        let text = canonical_csv::write(&simulate(&config));
        let analysis = analyse_file("sim.csv", text.as_bytes(), &CalibrationOptions::default())
            .expect("analysable");
        let report = &analysis.report;
        let raw = report.raw_heading_error_check.expect("reference present");
        let min_max = report
            .methods
            .iter()
            .find(|method| method.method == Method::MinMax)
            .expect("min/max ran");
        let after = min_max.heading_error_check.expect("reference present");
        assert!(raw.rms_deg > 10.0, "{raw:?}");
        assert!(after.rms_deg < 3.0, "{after:?}");
        // The level-plane centre is the hard iron's horizontal part, tilted slightly.
        let Some(MethodParameters::MinMax(calibration)) = &min_max.parameters else {
            panic!("min/max parameters: {min_max:?}");
        };
        let hard_iron_ut = config.hard_iron_ut;
        assert!(
            (calibration.center_x_ut - hard_iron_ut[0]).abs() < 6.0,
            "{calibration:?} vs {hard_iron_ut:?}"
        );
        assert!(
            (calibration.center_y_ut - hard_iron_ut[1]).abs() < 6.0,
            "{calibration:?} vs {hard_iron_ut:?}"
        );
    }
}
