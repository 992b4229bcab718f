//! The attitude-aided compass fit for autopilot logs.
//!
//! A vehicle's flight rarely turns its compass over the whole sphere, so the fits that
//! only ask the corrected field to be of one size (the ellipsoid of Eq. 5) are blind
//! along most directions. An autopilot log also holds the vehicle's attitude, estimated
//! from gyroscopes, accelerometers and GPS. In the Earth's frame the field is one
//! constant vector `B`, so each sample gives three equations, not one:
//!
//! ```text
//! M · (raw_i + offsets) = R_iᵀ · B        R_i: body → north-east-down, from the log
//! ```
//!
//! This is the fit of ArduPilot's MAGFit (WebTools, `MAGFit/MAGFit.js`), which fits
//! offsets, scale, iron and motor compensation against the World Magnetic Model with
//! the attitude source the user picks. Here `B` is fitted with the rest (three more
//! unknowns), so no magnetic model is needed: the log's own date may lie outside the
//! model's years. Written with `u = M · offsets`, both models are linear least squares:
//!
//! - offsets only, `M` held at the calibration in force: unknowns `u`, `B` (6);
//! - offsets and soft iron: `M` symmetric with its trace held at 3 (which fixes the
//!   scale the equations leave free), unknowns `M` (5), `u`, `B` (11);
//! - either with motor interference, a field `k · current` added after `M` as ArduPilot's
//!   `COMPASS_MOT` with `COMPASS_MOTCT = 2` adds it: three more unknowns `k`.
//!
//! The 1σ of each parameter is the formal one, `σ² · (AᵀA)⁻¹`, with the samples taken as
//! independent (successive samples of a log are not, so it is a lower bound).

use nalgebra::{DMatrix, DVector, Matrix3, Rotation3, Vector3};

use crate::angle::wrap_to_pi;

/// One compass sample with the vehicle's attitude at its time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AidedSample {
    pub t_s: f64,
    /// The raw field in body axes, in the compass's unit.
    pub raw: Vector3<f64>,
    pub body_to_ned: Rotation3<f64>,
    /// The battery current (A) that the motor-interference term scales; 0 where unknown.
    pub current_a: f64,
}

/// Which parameters the fit frees: the offsets always, the soft iron where it is not
/// held, and a field per ampere of battery current (motor interference, ArduPilot's
/// `COMPASS_MOT`) where `motor` is set.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AidedModel {
    pub held_soft_iron: Option<Matrix3<f64>>,
    pub motor: bool,
}

/// A fitted calibration in ArduPilot's form, `corrected = M · (raw + offsets)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AidedFit {
    /// Added to the raw field (ArduPilot's sign: minus the hard iron).
    pub offsets: Vector3<f64>,
    pub soft_iron: Matrix3<f64>,
    /// The Earth's field in north-east-down axes, in the compass's unit.
    pub earth_ned: Vector3<f64>,
    /// Formal 1σ of the offsets.
    pub offsets_sigma: Vector3<f64>,
    /// The largest formal 1σ of the soft iron's entries, where they were fitted.
    pub soft_iron_sigma: Option<f64>,
    /// The field added per ampere of battery current (zero where not fitted), with its
    /// formal 1σ.
    pub motor_per_a: Vector3<f64>,
    pub motor_sigma: Vector3<f64>,
    pub n_samples: usize,
}

impl AidedFit {
    pub fn apply(&self, raw: Vector3<f64>, current_a: f64) -> Vector3<f64> {
        self.soft_iron * (raw + self.offsets) + self.motor_per_a * current_a
    }
}

/// Fits `model` to the samples; `None` with fewer samples than unknowns or when the
/// equations do not fix the unknowns (a singular normal matrix).
pub fn fit_aided(samples: &[AidedSample], model: AidedModel) -> Option<AidedFit> {
    // Unknowns: M's five (where fitted), the motor term's three (where fitted), u, B.
    let n_m = if model.held_soft_iron.is_some() { 0 } else { 5 };
    let base_u = n_m + if model.motor { 3 } else { 0 };
    let base_b = base_u + 3;
    let n_unknowns = base_b + 3;
    if samples.len() * 3 < 2 * n_unknowns {
        return None;
    }
    let mut normal = DMatrix::<f64>::zeros(n_unknowns, n_unknowns);
    let mut rhs = DVector::<f64>::zeros(n_unknowns);
    let mut row = DVector::<f64>::zeros(n_unknowns);
    let mut sum_squares_rhs = 0.0;
    for sample in samples {
        let r = sample.raw;
        // R_iᵀ: rows map NED to body.
        let ned_to_body = sample.body_to_ned.matrix().transpose();
        for axis in 0..3 {
            row.fill(0.0);
            row[base_u + axis] = 1.0;
            for col in 0..3 {
                row[base_b + col] = -ned_to_body[(axis, col)];
            }
            if model.motor {
                row[n_m + axis] = sample.current_a;
            }
            let value = match model.held_soft_iron {
                Some(soft_iron) => -(soft_iron * r)[axis],
                // M = [[a, c, d], [c, b, e], [d, e, 3 − a − b]]; unknowns a, b, c, d, e.
                None => match axis {
                    0 => {
                        row[0] = r.x;
                        row[2] = r.y;
                        row[3] = r.z;
                        0.0
                    }
                    1 => {
                        row[1] = r.y;
                        row[2] = r.x;
                        row[4] = r.z;
                        0.0
                    }
                    _ => {
                        row[0] = -r.z;
                        row[1] = -r.z;
                        row[3] = r.x;
                        row[4] = r.y;
                        -3.0 * r.z
                    }
                },
            };
            normal.ger(1.0, &row, &row, 1.0);
            rhs.axpy(value, &row, 1.0);
            sum_squares_rhs += value * value;
        }
    }
    let decomposition = normal.cholesky()?;
    let x = decomposition.solve(&rhs);
    // Residual sum of squares: bᵀb − xᵀAᵀb.
    let n_equations = samples.len() * 3;
    let ssr = (sum_squares_rhs - x.dot(&rhs)).max(0.0);
    let sigma2 = ssr / (n_equations - n_unknowns).max(1) as f64;
    let covariance = decomposition.inverse() * sigma2;
    let sigma_of = |idx: usize| covariance[(idx, idx)].max(0.0).sqrt();
    let u = Vector3::new(x[base_u], x[base_u + 1], x[base_u + 2]);
    let earth_ned = Vector3::new(x[base_b], x[base_b + 1], x[base_b + 2]);
    let (soft_iron, soft_iron_sigma) = match model.held_soft_iron {
        Some(soft_iron) => (soft_iron, None),
        None => {
            let (a, b, c, d, e) = (x[0], x[1], x[2], x[3], x[4]);
            let sigma = (0..5).map(sigma_of).fold(0.0, f64::max);
            (
                Matrix3::new(a, c, d, c, b, e, d, e, 3.0 - a - b),
                Some(sigma),
            )
        }
    };
    let (motor_per_a, motor_sigma) = if model.motor {
        (
            Vector3::new(x[n_m], x[n_m + 1], x[n_m + 2]),
            Vector3::new(sigma_of(n_m), sigma_of(n_m + 1), sigma_of(n_m + 2)),
        )
    } else {
        (Vector3::zeros(), Vector3::zeros())
    };
    let inverse = soft_iron.try_inverse()?;
    let offsets = inverse * u;
    let u_covariance = covariance.fixed_view::<3, 3>(base_u, base_u).into_owned();
    let offsets_covariance = inverse * u_covariance * inverse.transpose();
    let offsets_sigma = offsets_covariance.diagonal().map(|v| v.max(0.0).sqrt());
    let fit = AidedFit {
        offsets,
        soft_iron,
        earth_ned,
        offsets_sigma,
        soft_iron_sigma,
        motor_per_a,
        motor_sigma,
        n_samples: samples.len(),
    };
    fit.offsets
        .iter()
        .chain(fit.soft_iron.iter())
        .chain(fit.motor_per_a.iter())
        .all(|v| v.is_finite())
        .then_some(fit)
}

/// How well a corrected field agrees with one Earth field seen through the attitude.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Agreement {
    /// RMS of the heading error: the corrected field's azimuth in the Earth's frame
    /// against the mean field's (degrees).
    pub heading_rms_deg: f64,
    /// The corrected field's magnitude: its standard deviation over its mean (%).
    pub spread_pct: f64,
    pub mean_magnitude: f64,
    pub n_samples: usize,
}

/// The agreement of `correct(raw, current_a)` over `samples`; `None` without samples.
pub fn agreement(
    samples: &[AidedSample],
    correct: impl Fn(Vector3<f64>, f64) -> Vector3<f64>,
) -> Option<Agreement> {
    if samples.is_empty() {
        return None;
    }
    let corrected: Vec<Vector3<f64>> = samples
        .iter()
        .map(|s| correct(s.raw, s.current_a))
        .collect();
    let in_ned: Vec<Vector3<f64>> = samples
        .iter()
        .zip(&corrected)
        .map(|(sample, c)| sample.body_to_ned * c)
        .collect();
    let n = samples.len() as f64;
    let mean_ned = in_ned.iter().sum::<Vector3<f64>>() / n;
    let mean_azimuth = mean_ned.y.atan2(mean_ned.x);
    let heading_ms = in_ned
        .iter()
        .map(|v| wrap_to_pi(v.y.atan2(v.x) - mean_azimuth).powi(2))
        .sum::<f64>()
        / n;
    let magnitudes: Vec<f64> = corrected.iter().map(|c| c.norm()).collect();
    let mean_magnitude = magnitudes.iter().sum::<f64>() / n;
    Some(Agreement {
        heading_rms_deg: heading_ms.sqrt().to_degrees(),
        spread_pct: crate::stats::spread_pct(magnitudes.iter().copied()).unwrap_or(f64::NAN),
        mean_magnitude,
        n_samples: samples.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A flight-like attitude history: yaw swinging over 120°, ±20° of tilt.
    fn attitudes(n: usize) -> Vec<Rotation3<f64>> {
        (0..n)
            .map(|i| {
                let t = i as f64 * 0.1;
                Rotation3::from_euler_angles(
                    0.35 * (0.7 * t).sin(),
                    0.3 * (0.43 * t + 1.0).sin(),
                    1.0 * (0.05 * t).sin(),
                )
            })
            .collect()
    }

    #[test]
    fn a_flight_that_covers_little_of_the_sphere_still_gives_the_offsets() {
        let earth_ned = Vector3::new(250.0, 40.0, -520.0);
        let soft_iron = Matrix3::new(1.05, 0.02, -0.01, 0.02, 0.97, 0.03, -0.01, 0.03, 0.98);
        let offsets = Vector3::new(-97.0, 118.0, 213.0);
        let inverse = soft_iron.try_inverse().unwrap();
        let samples: Vec<AidedSample> = attitudes(2000)
            .into_iter()
            .enumerate()
            .map(|(i, body_to_ned)| {
                let noise = Vector3::new((i as f64 * 1.3).sin(), (i as f64 * 2.1).cos(), 0.5) * 2.0;
                let corrected = body_to_ned.inverse() * earth_ned;
                // A motor term of (2, −1, 3) per A, with the current stepping up in flight.
                let current_a = if i < 600 {
                    0.5
                } else {
                    14.0 + (i as f64 * 0.01).sin()
                };
                let motor = Vector3::new(2.0, -1.0, 3.0) * current_a;
                AidedSample {
                    t_s: i as f64 * 0.1,
                    raw: inverse * (corrected - motor) - offsets + noise,
                    body_to_ned,
                    current_a,
                }
            })
            .collect();
        let model = |held_soft_iron, motor| AidedModel {
            held_soft_iron,
            motor,
        };
        let full = fit_aided(&samples, model(None, true)).unwrap();
        assert!((full.offsets - offsets).amax() < 6.0, "{:?}", full.offsets);
        let only = fit_aided(&samples, model(Some(soft_iron), true)).unwrap();
        assert!((only.offsets - offsets).amax() < 2.0, "{:?}", only.offsets);
        assert!((only.motor_per_a - Vector3::new(2.0, -1.0, 3.0)).amax() < 0.1);
        assert!(only.offsets_sigma.amax() < 1.0);
        let good = agreement(&samples, |raw, current| only.apply(raw, current)).unwrap();
        let raw = agreement(&samples, |raw, _| raw).unwrap();
        assert!(good.heading_rms_deg < 1.0 && raw.heading_rms_deg > 10.0);
        assert!(good.spread_pct < raw.spread_pct);
        // Without the motor term the same flight is fitted worse.
        let no_motor = fit_aided(&samples, model(Some(soft_iron), false)).unwrap();
        let worse = agreement(&samples, |raw, current| no_motor.apply(raw, current)).unwrap();
        assert!(worse.heading_rms_deg > 2.0 * good.heading_rms_deg);
    }

    #[test]
    fn too_few_or_degenerate_samples_give_no_fit() {
        let free = AidedModel {
            held_soft_iron: None,
            motor: false,
        };
        assert!(fit_aided(&[], free).is_none());
        let still = AidedSample {
            t_s: 0.0,
            raw: Vector3::new(100.0, 0.0, 400.0),
            body_to_ned: Rotation3::identity(),
            current_a: 0.0,
        };
        // One attitude only: the offsets and the Earth's field cannot be told apart.
        let model = AidedModel {
            held_soft_iron: Some(Matrix3::identity()),
            motor: false,
        };
        assert!(fit_aided(&vec![still; 100], model).is_none());
    }
}
