//! What the phone's sensors read of the true motion: the hand's attitude (mean tilt and
//! sway), the accelerometer's specific force, the gyroscope's body rates with bias, the
//! temperature, and the magnetometer's field through hard and soft iron (or a compass
//! deviating by Eq. 12), each with its noise.

use nalgebra::{Matrix3, Rotation3, Vector3};

use super::trajectory::Sample;
use super::WalkConfig;
use crate::base::rng::SplitMix64;
use crate::io::STANDARD_GRAVITY_MPS2;

/// The sensors of one sample.
pub(super) struct Reading {
    pub(super) acc_mps2: Vector3<f64>,
    pub(super) gyro_radps: Vector3<f64>,
    pub(super) mag_ut: Vector3<f64>,
    pub(super) temp_c: f64,
    /// Where the device faces: the walking direction plus the misalignment.
    pub(super) device_heading_rad: f64,
}

/// The device's attitude at a sample and its rate (for the gyroscope).
struct Attitude {
    roll_rad: f64,
    pitch_rad: f64,
    roll_rate_radps: f64,
    pitch_rate_radps: f64,
    device_heading_rad: f64,
    body_from_ned: Rotation3<f64>,
}

/// The phone: what of the configuration stays the same from sample to sample.
pub(super) struct Sensors<'a> {
    config: &'a WalkConfig,
    earth_field_in_ned_ut: Vector3<f64>,
    hard_iron_ut: Vector3<f64>,
    scale: Vector3<f64>,
    /// The full symmetric S, where it has terms off the diagonal.
    soft_iron: Option<Matrix3<f64>>,
    gyro_bias_radps: Vector3<f64>,
    vehicle_speed_mps: Option<f64>,
}

impl<'a> Sensors<'a> {
    pub(super) fn new(config: &'a WalkConfig) -> Sensors<'a> {
        let inclination_rad = config.inclination_deg.to_radians();
        let declination_rad = config.declination_deg.to_radians();
        let horizontal_ut = config.field_total_ut * inclination_rad.cos();
        let earth_field_in_ned_ut = Vector3::new(
            horizontal_ut * declination_rad.cos(),
            horizontal_ut * declination_rad.sin(),
            config.field_total_ut * inclination_rad.sin(),
        );
        let scale = Vector3::from(config.scale);
        let [xy, xz, yz] = config.soft_iron_offdiag;
        let soft_iron = (config.soft_iron_offdiag != [0.0; 3]).then(|| {
            Matrix3::new(
                scale.x, xy, xz, //
                xy, scale.y, yz, //
                xz, yz, scale.z,
            )
        });
        Sensors {
            config,
            earth_field_in_ned_ut,
            hard_iron_ut: Vector3::from(config.hard_iron_ut),
            scale,
            soft_iron,
            gyro_bias_radps: Vector3::from(config.gyro_bias_radps),
            vehicle_speed_mps: config.route.vehicle_speed_mps(),
        }
    }

    /// Every sensor at `sample`. The noise is drawn from `rng` in a fixed order:
    /// accelerometer, gyroscope, magnetometer.
    pub(super) fn read(&self, sample: &Sample, rng: &mut SplitMix64) -> Reading {
        let attitude = self.attitude(sample);
        let acc_mps2 = self.specific_force(sample, &attitude, rng);
        let gyro_radps = self.gyroscope(sample, &attitude, rng);
        let temp_c = self.temperature(sample.t_s);
        let mag_ut = self.magnetometer(sample.t_s, temp_c, &attitude, rng);
        Reading {
            acc_mps2,
            gyro_radps,
            mag_ut,
            temp_c,
            device_heading_rad: attitude.device_heading_rad,
        }
    }

    /// The hand's mean tilt with its sway at the gait's phase, and the heading the
    /// device faces.
    fn attitude(&self, sample: &Sample) -> Attitude {
        let config = self.config;
        let motion = &sample.motion;
        let gait_phase_rad = motion.phase_rad;
        let sway_pitch_rad = motion.weight * config.sway_pitch_deg.to_radians();
        let sway_roll_rad = motion.weight * config.sway_roll_deg.to_radians();
        let pitch_rad = config.mean_pitch_deg.to_radians() + sway_pitch_rad * gait_phase_rad.sin();
        let roll_rad =
            config.mean_roll_deg.to_radians() + sway_roll_rad * (gait_phase_rad / 2.0).sin();
        let pitch_rate_radps = sway_pitch_rad * motion.phase_rate_radps * gait_phase_rad.cos();
        let roll_rate_radps =
            sway_roll_rad * motion.phase_rate_radps / 2.0 * (gait_phase_rad / 2.0).cos();
        // The device faces the walking direction plus the misalignment.
        let device_heading_rad = sample.heading_rad + config.misalignment_deg.to_radians();
        let ned_from_body = Rotation3::from_euler_angles(roll_rad, pitch_rad, device_heading_rad);
        Attitude {
            roll_rad,
            pitch_rad,
            roll_rate_radps,
            pitch_rate_radps,
            device_heading_rad,
            body_from_ned: ned_from_body.inverse(),
        }
    }

    /// Specific force: body acceleration minus gravity (NED, down positive), in the
    /// body frame, with noise.
    fn specific_force(
        &self,
        sample: &Sample,
        attitude: &Attitude,
        rng: &mut SplitMix64,
    ) -> Vector3<f64> {
        let heading_rad = sample.heading_rad;
        let bounce_mps2 = sample.motion.down_mps2;
        let surge_mps2 = sample.motion.forward_mps2;
        // A vehicle in a turn feels v·ω towards the turn's centre (to the right when
        // turning clockwise); a walker's is too small to matter and is left out.
        let centripetal_mps2 = match self.vehicle_speed_mps {
            Some(speed_mps) => speed_mps * sample.phase.turn_rate_radps,
            None => 0.0,
        };
        let acc_in_ned_mps2 = Vector3::new(
            surge_mps2 * heading_rad.cos() - centripetal_mps2 * heading_rad.sin(),
            surge_mps2 * heading_rad.sin() + centripetal_mps2 * heading_rad.cos(),
            bounce_mps2,
        );
        let f_in_ned_mps2 = acc_in_ned_mps2 - Vector3::new(0.0, 0.0, STANDARD_GRAVITY_MPS2);
        attitude.body_from_ned * f_in_ned_mps2 + noise3(rng, self.config.acc_noise_mps2)
    }

    /// The body rates of a yaw-pitch-roll motion, plus bias and noise.
    fn gyroscope(
        &self,
        sample: &Sample,
        attitude: &Attitude,
        rng: &mut SplitMix64,
    ) -> Vector3<f64> {
        let yaw_rate_radps = sample.phase.turn_rate_radps;
        let (roll_rate_radps, pitch_rate_radps) =
            (attitude.roll_rate_radps, attitude.pitch_rate_radps);
        let (sin_roll, cos_roll) = attitude.roll_rad.sin_cos();
        let (sin_pitch, cos_pitch) = attitude.pitch_rad.sin_cos();
        let rate_in_body_radps = Vector3::new(
            roll_rate_radps - yaw_rate_radps * sin_pitch,
            pitch_rate_radps * cos_roll + yaw_rate_radps * sin_roll * cos_pitch,
            -pitch_rate_radps * sin_roll + yaw_rate_radps * cos_roll * cos_pitch,
        );
        rate_in_body_radps + self.gyro_bias_radps + noise3(rng, self.config.gyro_noise_radps)
    }

    /// The temperature: a swing about 22 °C, or a slow warming from 22 to 25 °C.
    fn temperature(&self, t_s: f64) -> f64 {
        let config = self.config;
        if config.temp_swing_c > 0.0 {
            22.0 + config.temp_swing_c
                * (std::f64::consts::TAU * t_s / config.temp_period_s.max(1.0)).sin()
        } else {
            22.0 + 3.0 * t_s / config.duration_s.max(1.0)
        }
    }

    /// The magnetometer: the Earth's field (and any iron passed) through hard iron
    /// drifting with temperature and scale factors or soft iron, or through a compass
    /// that deviates by exactly Eq. 12; with noise.
    fn magnetometer(
        &self,
        t_s: f64,
        temp_c: f64,
        attitude: &Attitude,
        rng: &mut SplitMix64,
    ) -> Vector3<f64> {
        let config = self.config;
        let body_from_ned = attitude.body_from_ned;
        let field_in_ned_ut = self.earth_field_in_ned_ut
            + config
                .disturbance
                .map_or_else(Vector3::zeros, |disturbance| disturbance.field_ned_ut(t_s));
        match config.deviation_deg {
            Some(coefficients_deg) => {
                // Turn the sensed field so that the level heading reads ψ' with
                // ψ = ψ' + δ(ψ'): the sensed field's azimuth is δ(ψ').
                let deviation_rad = deviation_of(attitude.device_heading_rad, &coefficients_deg);
                let turned =
                    Rotation3::from_axis_angle(&Vector3::z_axis(), deviation_rad) * field_in_ned_ut;
                body_from_ned * turned + noise3(rng, config.mag_noise_ut)
            }
            None => {
                let drift_ut =
                    Vector3::from(config.hard_iron_temp_coeff_ut_per_c) * (temp_c - 22.0);
                let field_in_body_ut = body_from_ned * field_in_ned_ut;
                // A diagonal S is applied axis by axis (the committed logs' arithmetic).
                self.soft_iron.map_or_else(
                    || field_in_body_ut.component_mul(&self.scale),
                    |soft_iron| soft_iron * field_in_body_ut,
                ) + self.hard_iron_ut
                    + drift_ut
                    + noise3(rng, config.mag_noise_ut)
            }
        }
    }
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
