//! Tilt compensation: roll and pitch from the accelerometer, and the levelled field.
//!
//! Source: Moafipoor, Grejner-Brzezinska and Toth (2007), *Adaptive Calibration of a
//! Magnetometer Compass for a Personal Navigation System*, Eq. 4.
//!
//! ## Derivation in this crate's frames
//!
//! The body frame is x forward, y right, z down, and the attitude is the usual
//! yaw-pitch-roll sequence, so a vector in north-east-down is
//! `v_ned = Rz(ψ) · Ry(θ) · Rx(φ) · v_body`. Levelling removes roll and pitch only:
//! `v_level = Ry(θ) · Rx(φ) · v_body`, which gives
//!
//! ```text
//! Xh = mx·cosθ + my·sinφ·sinθ + mz·cosφ·sinθ
//! Yh = my·cosφ − mz·sinφ
//! ```
//!
//! This is the paper's Eq. 4 with its z axis pointing up (its `Hz` is our `−mz`) and
//! its θ, φ named roll and pitch. At rest the accelerometer reads the specific force
//! `f_body = (g·sinθ, −g·sinφ·cosθ, −g·cosφ·cosθ)`, hence
//! `φ = atan2(−fy, −fz)` and `θ = atan2(fx, √(fy² + fz²))`.
//!
//! ## Limits
//!
//! While walking, the accelerometer also senses the body's own acceleration. Roll and
//! pitch are therefore taken from specific force averaged over a window (about one
//! second, a couple of steps), which keeps the slow tilt and drops the step bounce.
//! Near ±90° pitch the roll is undefined (gimbal lock); the levelled field is still
//! correct there because `Yh` only needs φ up to the sign that `Xh` absorbs.

use nalgebra::{Vector2, Vector3};

use crate::io::recording::Stream;

/// Specific force smaller than this (m/s²) cannot give a direction: free fall or a
/// broken sensor.
const MIN_SPECIFIC_FORCE_MPS2: f64 = 2.0;

/// Roll and pitch of the body frame against the local level, kept as their sines and
/// cosines: a sample is levelled by every method, and by a fit at each of its
/// iterations, and the accelerometer gives them without an angle in between.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tilt {
    /// `(sin φ, cos φ)` and `(sin θ, cos θ)`, each a unit vector.
    roll_sin_cos: (f64, f64),
    pitch_sin_cos: (f64, f64),
}

impl Tilt {
    pub const LEVEL: Tilt = Tilt {
        roll_sin_cos: (0.0, 1.0),
        pitch_sin_cos: (0.0, 1.0),
    };

    pub fn new(roll_rad: f64, pitch_rad: f64) -> Tilt {
        Tilt {
            roll_sin_cos: roll_rad.sin_cos(),
            pitch_sin_cos: pitch_rad.sin_cos(),
        }
    }

    /// Roll φ (rad, in (−π, π]), right side down positive.
    pub fn roll_rad(&self) -> f64 {
        self.roll_sin_cos.0.atan2(self.roll_sin_cos.1)
    }

    /// Pitch θ (rad, in [−π/2, π/2] from the accelerometer), nose up positive.
    pub fn pitch_rad(&self) -> f64 {
        self.pitch_sin_cos.0.atan2(self.pitch_sin_cos.1)
    }

    /// `(sin φ, cos φ)`.
    pub fn roll_sin_cos(&self) -> (f64, f64) {
        self.roll_sin_cos
    }

    /// `(sin θ, cos θ)`.
    pub fn pitch_sin_cos(&self) -> (f64, f64) {
        self.pitch_sin_cos
    }

    /// Roll and pitch from specific force in the body frame; `None` when the force is
    /// too small or not finite to tell which way is down. With `h = √(fy² + fz²)`,
    /// `φ = atan2(−fy, −fz)` and `θ = atan2(fx, h)` (see the module's derivation), so
    /// `(sin φ, cos φ) = (−fy, −fz)/h` and `(sin θ, cos θ) = (fx, h)/|f|`. At ±90° pitch
    /// (`h = 0`) the roll is undefined and taken as zero.
    pub fn from_specific_force(f_in_body_mps2: Vector3<f64>) -> Option<Tilt> {
        let norm_mps2 = f_in_body_mps2.norm();
        if !norm_mps2.is_finite() || norm_mps2 < MIN_SPECIFIC_FORCE_MPS2 {
            return None;
        }
        let (fx, fy, fz) = (f_in_body_mps2.x, f_in_body_mps2.y, f_in_body_mps2.z);
        let h = f_in_body_mps2.yz().norm();
        let roll_sin_cos = if h > 0.0 {
            (-fy / h, -fz / h)
        } else {
            (0.0, 1.0)
        };
        Some(Tilt {
            roll_sin_cos,
            pitch_sin_cos: (fx / norm_mps2, h / norm_mps2),
        })
    }

    /// The horizontal components (Xh along the heading, Yh to its right) of a body
    /// vector: Eq. 4 in this crate's frames.
    pub fn level(&self, v_in_body: Vector3<f64>) -> Vector2<f64> {
        let (sin_roll, cos_roll) = self.roll_sin_cos;
        let (sin_pitch, cos_pitch) = self.pitch_sin_cos;
        Vector2::new(
            v_in_body.x * cos_pitch
                + v_in_body.y * sin_roll * sin_pitch
                + v_in_body.z * cos_roll * sin_pitch,
            v_in_body.y * cos_roll - v_in_body.z * sin_roll,
        )
    }
}

/// The direction of specific force averaged over a centred window of `window_s`
/// seconds, scaled to the window's mean magnitude, at each sample's time: the gravity
/// estimate that tilt is taken from.
///
/// Directions are averaged rather than the vectors themselves: while walking, the
/// vertical bounce scales the whole vector in step with the sway of the hand, and the
/// mean of their product is a tilt bias (about 0.15° for a 1.5 m/s² bounce and a 2°
/// sway, which the steep field at high inclination turns into 0.3° of heading); the
/// direction is free of it.
pub fn smooth_specific_force(
    acc_in_body_mps2: &Stream<Vector3<f64>>,
    window_s: f64,
) -> Stream<Vector3<f64>> {
    let half_window_s = window_s / 2.0;
    let times_s = &acc_in_body_mps2.t_s;
    // Each sample as (unit direction, magnitude); a zero or broken sample adds nothing.
    let directions: Vec<(Vector3<f64>, f64)> = acc_in_body_mps2
        .values
        .iter()
        .map(|value| {
            let norm = value.norm();
            if norm.is_finite() && norm > 0.0 {
                (value / norm, norm)
            } else {
                (Vector3::zeros(), 0.0)
            }
        })
        .collect();
    let mut smoothed = Stream::default();
    let (mut start_idx, mut end_idx) = (0usize, 0usize);
    let (mut sum_direction, mut sum_norm) = (Vector3::zeros(), 0.0);
    for &t_s in times_s.iter().take(directions.len()) {
        while let (Some(&end_t_s), Some(&(direction, norm))) =
            (times_s.get(end_idx), directions.get(end_idx))
        {
            if end_t_s > t_s + half_window_s {
                break;
            }
            sum_direction += direction;
            sum_norm += norm;
            end_idx += 1;
        }
        while let (Some(&start_t_s), Some(&(direction, norm))) =
            (times_s.get(start_idx), directions.get(start_idx))
        {
            if start_idx >= end_idx || start_t_s >= t_s - half_window_s {
                break;
            }
            sum_direction -= direction;
            sum_norm -= norm;
            start_idx += 1;
        }
        let n_in_window = (end_idx - start_idx).max(1) as f64;
        let direction_norm = sum_direction.norm();
        let mean = if direction_norm > 0.0 {
            sum_direction / direction_norm * (sum_norm / n_in_window)
        } else {
            Vector3::zeros()
        };
        smoothed.push(t_s, mean);
    }
    smoothed
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Rotation3;

    use crate::io::STANDARD_GRAVITY_MPS2;

    /// The body-to-NED rotation for yaw, pitch, roll.
    fn ned_from_body(yaw_rad: f64, pitch_rad: f64, roll_rad: f64) -> Rotation3<f64> {
        Rotation3::from_euler_angles(roll_rad, pitch_rad, yaw_rad)
    }

    #[test]
    fn tilt_is_recovered_from_specific_force_at_rest() {
        for &(roll_deg, pitch_deg) in &[
            (0.0, 0.0),
            (10.0, -5.0),
            (-30.0, 20.0),
            (80.0, 45.0),
            (170.0, 10.0),
        ] {
            let (roll_rad, pitch_rad) = (f64::to_radians(roll_deg), f64::to_radians(pitch_deg));
            let body_from_ned = ned_from_body(1.0, pitch_rad, roll_rad).inverse();
            let f_in_body = body_from_ned * Vector3::new(0.0, 0.0, -STANDARD_GRAVITY_MPS2);
            let tilt = Tilt::from_specific_force(f_in_body).expect("gravity is large enough");
            assert!((tilt.roll_rad() - roll_rad).abs() < 1e-9, "roll {roll_deg}");
            assert!(
                (tilt.pitch_rad() - pitch_rad).abs() < 1e-9,
                "pitch {pitch_deg}"
            );
        }
    }

    #[test]
    fn levelling_recovers_the_horizontal_field_at_any_tilt() {
        // Earth field 50 µT with 60° inclination; the device faces 30° east of north.
        let field_in_ned_ut = Vector3::new(25.0, 0.0, 43.30);
        let yaw_rad = 30f64.to_radians();
        let expect = Vector2::new(25.0 * yaw_rad.cos(), -25.0 * yaw_rad.sin());
        for &(roll_deg, pitch_deg) in &[(0.0, 0.0), (15.0, -10.0), (-40.0, 25.0)] {
            let (roll_rad, pitch_rad) = (f64::to_radians(roll_deg), f64::to_radians(pitch_deg));
            let body_from_ned = ned_from_body(yaw_rad, pitch_rad, roll_rad).inverse();
            let tilt = Tilt::from_specific_force(
                body_from_ned * Vector3::new(0.0, 0.0, -STANDARD_GRAVITY_MPS2),
            )
            .expect("tilt");
            let level_ut = tilt.level(body_from_ned * field_in_ned_ut);
            assert!(
                (level_ut - expect).norm() < 1e-9,
                "roll {roll_deg}, pitch {pitch_deg}: {level_ut:?}"
            );
        }
    }

    #[test]
    fn no_direction_from_free_fall_or_nan() {
        assert_eq!(Tilt::from_specific_force(Vector3::new(0.1, 0.0, 0.2)), None);
        assert_eq!(
            Tilt::from_specific_force(Vector3::new(f64::NAN, 0.0, -9.8)),
            None
        );
    }

    #[test]
    fn smoothing_removes_a_zero_mean_bounce() {
        let mut acc = Stream::default();
        for sample_idx in 0..500 {
            let t_s = sample_idx as f64 * 0.01;
            // A 2 Hz bounce: a 1 s window holds whole periods.
            let bounce_mps2 = 2.0 * (std::f64::consts::TAU * 2.0 * t_s).sin();
            acc.push(
                t_s,
                Vector3::new(0.0, 0.0, -STANDARD_GRAVITY_MPS2 + bounce_mps2),
            );
        }
        let smoothed = smooth_specific_force(&acc, 1.0);
        assert_eq!(smoothed.len(), acc.len());
        let middle = smoothed.values[250];
        assert!(
            (middle.z + STANDARD_GRAVITY_MPS2).abs() < 0.05,
            "{middle:?}"
        );
    }
}
