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
//!   scale the equations leave free), unknowns `M` (5), `u`, `B` (11).
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
}

/// Which parameters the fit frees.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum AidedModel {
    /// Offsets only, the soft iron held.
    Offsets { soft_iron: Matrix3<f64> },
    OffsetsAndSoftIron,
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
    pub n_samples: usize,
}

impl AidedFit {
    pub fn apply(&self, raw: Vector3<f64>) -> Vector3<f64> {
        self.soft_iron * (raw + self.offsets)
    }
}

/// Fits `model` to the samples; `None` with fewer samples than unknowns or when the
/// equations do not fix the unknowns (a singular normal matrix).
pub fn fit_aided(samples: &[AidedSample], model: AidedModel) -> Option<AidedFit> {
    let n_unknowns = match model {
        AidedModel::Offsets { .. } => 6,
        AidedModel::OffsetsAndSoftIron => 11,
    };
    if samples.len() * 3 < 2 * n_unknowns {
        return None;
    }
    let mut normal = DMatrix::<f64>::zeros(n_unknowns, n_unknowns);
    let mut rhs = DVector::<f64>::zeros(n_unknowns);
    let mut rows: Vec<(DVector<f64>, f64)> = Vec::with_capacity(3);
    let mut sum_squares_rhs = 0.0;
    let equations = |sample: &AidedSample, rows: &mut Vec<(DVector<f64>, f64)>| {
        rows.clear();
        let r = sample.raw;
        // R_iᵀ: rows map NED to body.
        let ned_to_body = sample.body_to_ned.matrix().transpose();
        for axis in 0..3 {
            let mut row = DVector::<f64>::zeros(n_unknowns);
            let base = n_unknowns - 6;
            row[base + axis] = 1.0;
            for col in 0..3 {
                row[base + 3 + col] = -ned_to_body[(axis, col)];
            }
            let value = match model {
                AidedModel::Offsets { soft_iron } => -(soft_iron * r)[axis],
                AidedModel::OffsetsAndSoftIron => {
                    // M = [[a, c, d], [c, b, e], [d, e, 3 − a − b]]; unknowns a, b, c, d, e.
                    match axis {
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
                    }
                }
            };
            rows.push((row, value));
        }
    };
    for sample in samples {
        equations(sample, &mut rows);
        for (row, value) in &rows {
            normal.ger(1.0, row, row, 1.0);
            rhs.axpy(*value, row, 1.0);
            sum_squares_rhs += value * value;
        }
    }
    let decomposition = normal.clone().cholesky()?;
    let x = decomposition.solve(&rhs);
    // Residual sum of squares: bᵀb − xᵀAᵀb.
    let n_equations = samples.len() * 3;
    let ssr = (sum_squares_rhs - x.dot(&rhs)).max(0.0);
    let sigma2 = ssr / (n_equations - n_unknowns).max(1) as f64;
    let covariance = decomposition.inverse() * sigma2;
    let base = n_unknowns - 6;
    let u = Vector3::new(x[base], x[base + 1], x[base + 2]);
    let earth_ned = Vector3::new(x[base + 3], x[base + 4], x[base + 5]);
    let (soft_iron, soft_iron_sigma) = match model {
        AidedModel::Offsets { soft_iron } => (soft_iron, None),
        AidedModel::OffsetsAndSoftIron => {
            let (a, b, c, d, e) = (x[0], x[1], x[2], x[3], x[4]);
            let sigma = (0..5)
                .map(|idx| covariance[(idx, idx)].max(0.0).sqrt())
                .fold(0.0, f64::max);
            (Matrix3::new(a, c, d, c, b, e, d, e, 3.0 - a - b), Some(sigma))
        }
    };
    let inverse = soft_iron.try_inverse()?;
    let offsets = inverse * u;
    let u_covariance = covariance.fixed_view::<3, 3>(base, base).into_owned();
    let offsets_covariance = inverse * u_covariance * inverse.transpose();
    let offsets_sigma = offsets_covariance.diagonal().map(|v| v.max(0.0).sqrt());
    let fit = AidedFit {
        offsets,
        soft_iron,
        earth_ned,
        offsets_sigma,
        soft_iron_sigma,
        n_samples: samples.len(),
    };
    fit.offsets
        .iter()
        .chain(fit.soft_iron.iter())
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

/// The agreement of `correct(raw)` over `samples`; `None` without samples.
pub fn agreement(
    samples: &[AidedSample],
    correct: impl Fn(Vector3<f64>) -> Vector3<f64>,
) -> Option<Agreement> {
    if samples.is_empty() {
        return None;
    }
    let corrected: Vec<Vector3<f64>> = samples.iter().map(|s| correct(s.raw)).collect();
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
    let variance = magnitudes
        .iter()
        .map(|m| (m - mean_magnitude).powi(2))
        .sum::<f64>()
        / n;
    Some(Agreement {
        heading_rms_deg: heading_ms.sqrt().to_degrees(),
        spread_pct: 100.0 * variance.sqrt() / mean_magnitude,
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
                AidedSample {
                    t_s: i as f64 * 0.1,
                    raw: inverse * corrected - offsets + noise,
                    body_to_ned,
                }
            })
            .collect();
        let full = fit_aided(&samples, AidedModel::OffsetsAndSoftIron).unwrap();
        assert!((full.offsets - offsets).amax() < 6.0, "{:?}", full.offsets);
        let only = fit_aided(&samples, AidedModel::Offsets { soft_iron }).unwrap();
        assert!((only.offsets - offsets).amax() < 2.0, "{:?}", only.offsets);
        assert!(only.offsets_sigma.amax() < 1.0);
        let good = agreement(&samples, |raw| only.apply(raw)).unwrap();
        let raw = agreement(&samples, |raw| raw).unwrap();
        assert!(good.heading_rms_deg < 1.0 && raw.heading_rms_deg > 10.0);
        assert!(good.spread_pct < raw.spread_pct);
    }

    #[test]
    fn too_few_or_degenerate_samples_give_no_fit() {
        assert!(fit_aided(&[], AidedModel::OffsetsAndSoftIron).is_none());
        let still = AidedSample {
            t_s: 0.0,
            raw: Vector3::new(100.0, 0.0, 400.0),
            body_to_ned: Rotation3::identity(),
        };
        // One attitude only: the offsets and the Earth's field cannot be told apart.
        assert!(fit_aided(&vec![still; 100], AidedModel::Offsets { soft_iron: Matrix3::identity() }).is_none());
    }
}
