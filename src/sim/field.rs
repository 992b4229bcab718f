//! Magnetometer samples with known distortion, for testing fits against truth.
//!
//! Each sample is the Earth's field `F` (north-east-down, magnitude and inclination as
//! chosen, declination zero) seen by a body in some attitude, distorted as in Eq. 2-3 of
//! the 2007 paper: `m = S·(Rᵀ·F) + h + noise`, with `S` symmetric. Two kinds of motion:
//! the full-sphere "calibration dance" (attitudes spread over all directions) and the
//! circle-only motion of walkers and vehicles (every heading, tilt within a few degrees).

use nalgebra::{Matrix3, Rotation3, Vector3};

use crate::base::rng::SplitMix64;

/// The distortion and the field, all known.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FieldTruth {
    pub hard_iron_ut: Vector3<f64>,
    /// The soft-iron matrix `S` (symmetric); the ideal correction is `S⁻¹`.
    pub soft_iron: Matrix3<f64>,
    pub field_total_ut: f64,
    pub inclination_deg: f64,
    pub noise_ut: f64,
}

impl FieldTruth {
    /// A random distortion: hard iron up to `max_hard_iron_ut` per axis, soft-iron
    /// diagonal within 1 ± `max_scale_error`, off-diagonals up to `max_cross`.
    pub fn random(
        rng: &mut SplitMix64,
        max_hard_iron_ut: f64,
        max_scale_error: f64,
        max_cross: f64,
    ) -> FieldTruth {
        let mut hard = || rng.uniform_in(-max_hard_iron_ut, max_hard_iron_ut);
        let hard_iron_ut = Vector3::new(hard(), hard(), hard());
        let mut soft_iron = Matrix3::identity();
        for axis in 0..3 {
            soft_iron[(axis, axis)] = 1.0 + rng.uniform_in(-max_scale_error, max_scale_error);
        }
        for (row, col) in [(0, 1), (0, 2), (1, 2)] {
            let cross = rng.uniform_in(-max_cross, max_cross);
            soft_iron[(row, col)] = cross;
            soft_iron[(col, row)] = cross;
        }
        FieldTruth {
            hard_iron_ut,
            soft_iron,
            field_total_ut: 50.0,
            inclination_deg: 60.0,
            noise_ut: 0.3,
        }
    }

    pub fn field_in_ned_ut(&self) -> Vector3<f64> {
        let inclination_rad = self.inclination_deg.to_radians();
        Vector3::new(inclination_rad.cos(), 0.0, inclination_rad.sin()) * self.field_total_ut
    }

    /// The ideal correction `S⁻¹`, scaled so that corrected samples have the field's
    /// magnitude (which is what `FieldCalibration::soft_iron` means).
    pub fn ideal_correction(&self) -> Matrix3<f64> {
        self.soft_iron
            .try_inverse()
            .unwrap_or_else(Matrix3::identity)
    }

    /// The measured field of a body whose attitude is `ned_from_body`.
    pub fn measure(&self, ned_from_body: &Rotation3<f64>, rng: &mut SplitMix64) -> Vector3<f64> {
        let true_in_body = ned_from_body.inverse() * self.field_in_ned_ut();
        let noise = Vector3::new(rng.gaussian(), rng.gaussian(), rng.gaussian()) * self.noise_ut;
        self.soft_iron * true_in_body + self.hard_iron_ut + noise
    }
}

/// One simulated sample: the attitude (yaw = heading) and what the magnetometer read.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FieldSample {
    pub heading_rad: f64,
    pub pitch_rad: f64,
    pub roll_rad: f64,
    pub mag_ut: Vector3<f64>,
}

/// `n_samples` attitudes spread over the whole sphere (uniform random rotations).
pub fn full_sphere(truth: &FieldTruth, n_samples: usize, rng: &mut SplitMix64) -> Vec<FieldSample> {
    (0..n_samples)
        .map(|_| {
            // A uniform random rotation from a uniform random unit quaternion (Shoemake).
            let (u1, u2, u3) = (rng.uniform(), rng.uniform(), rng.uniform());
            let (a, b) = ((1.0 - u1).sqrt(), u1.sqrt());
            let tau = std::f64::consts::TAU;
            let quaternion = nalgebra::Quaternion::new(
                b * (tau * u3).cos(),
                a * (tau * u2).sin(),
                a * (tau * u2).cos(),
                b * (tau * u3).sin(),
            );
            let rotation =
                nalgebra::UnitQuaternion::from_quaternion(quaternion).to_rotation_matrix();
            let (roll_rad, pitch_rad, heading_rad) = rotation.euler_angles();
            FieldSample {
                heading_rad,
                pitch_rad,
                roll_rad,
                mag_ut: truth.measure(&rotation, rng),
            }
        })
        .collect()
}

/// `n_samples` attitudes of circle-only motion: headings evenly round the circle, roll
/// and pitch uniform within ±`max_tilt_deg`.
pub fn circle_only(
    truth: &FieldTruth,
    n_samples: usize,
    max_tilt_deg: f64,
    rng: &mut SplitMix64,
) -> Vec<FieldSample> {
    (0..n_samples)
        .map(|sample_idx| {
            let heading_rad = std::f64::consts::TAU * sample_idx as f64 / n_samples as f64;
            let max_tilt_rad = max_tilt_deg.to_radians();
            let pitch_rad = rng.uniform_in(-max_tilt_rad, max_tilt_rad);
            let roll_rad = rng.uniform_in(-max_tilt_rad, max_tilt_rad);
            let rotation = Rotation3::from_euler_angles(roll_rad, pitch_rad, heading_rad);
            FieldSample {
                heading_rad,
                pitch_rad,
                roll_rad,
                mag_ut: truth.measure(&rotation, rng),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_undistorted_noise_free_field_has_its_magnitude_everywhere() {
        let truth = FieldTruth {
            hard_iron_ut: Vector3::zeros(),
            soft_iron: Matrix3::identity(),
            field_total_ut: 48.0,
            inclination_deg: 46.0,
            noise_ut: 0.0,
        };
        let mut rng = SplitMix64::new(1);
        for sample in full_sphere(&truth, 200, &mut rng)
            .into_iter()
            .chain(circle_only(&truth, 200, 10.0, &mut rng))
        {
            assert!((sample.mag_ut.norm() - 48.0).abs() < 1e-9);
        }
    }

    #[test]
    fn the_ideal_correction_undoes_the_distortion() {
        let mut rng = SplitMix64::new(2);
        let truth = FieldTruth {
            noise_ut: 0.0,
            ..FieldTruth::random(&mut rng, 60.0, 0.1, 0.1)
        };
        let correction = truth.ideal_correction();
        for sample in full_sphere(&truth, 100, &mut rng) {
            let corrected = correction * (sample.mag_ut - truth.hard_iron_ut);
            assert!((corrected.norm() - truth.field_total_ut).abs() < 1e-9);
        }
    }

    #[test]
    fn circle_only_tilt_stays_within_its_bound() {
        let truth = FieldTruth::random(&mut SplitMix64::new(3), 30.0, 0.05, 0.05);
        let samples = circle_only(&truth, 500, 10.0, &mut SplitMix64::new(4));
        assert!(samples
            .iter()
            .all(|sample| sample.pitch_rad.abs() <= 10f64.to_radians()
                && sample.roll_rad.abs() <= 10f64.to_radians()));
    }
}
