//! What a converged solution says: [`InertialFit`]'s figures (the residuals over the
//! inliers, the field's spread, the outliers' share), the posterior standard deviation of
//! every parameter and of the heading (the covariance of step 3 of the fit in [`super`]),
//! and the parameters the data could not see, named with their uncertainty.

use super::*;

impl Solution {
    /// The fit as the caller sees it, from the solution on `set` (the evenly spaced
    /// samples of `all_ut` it was fitted on).
    pub(super) fn report(
        &self,
        set: &SampleSet,
        all_ut: &[Vector3<f64>],
        options: &InertialOptions,
    ) -> InertialFit {
        let state = &self.state;
        let uses_dip = set.uses_dip();
        let mut inlier_magnitudes = Vec::new();
        let mut all_magnitudes = Vec::with_capacity(set.mag_ut.len());
        let (mut sum_sq_b, mut sum_sq_v, mut n_in, mut n_out) = (0.0, 0.0, 0usize, 0usize);
        for (idx, &m_ut) in set.mag_ut.iter().enumerate() {
            let (r_b, r_v) = residuals(state, m_ut, set.down(idx));
            let magnitude = r_b + state.field_ut;
            all_magnitudes.push(magnitude);
            let weight = self.weights.magnitude.get(idx).copied().unwrap_or(1.0);
            let vertical_weight = if uses_dip {
                self.weights.vertical.get(idx).copied().unwrap_or(1.0)
            } else {
                1.0
            };
            if weight.min(vertical_weight) < OUTLIER_WEIGHT {
                n_out += 1;
                continue;
            }
            n_in += 1;
            inlier_magnitudes.push(magnitude);
            sum_sq_b += r_b * r_b;
            sum_sq_v += r_v.unwrap_or(0.0).powi(2);
        }
        let spread_pct = |magnitudes: &[f64]| {
            let n = magnitudes.len().max(1) as f64;
            let mean = magnitudes.iter().sum::<f64>() / n;
            let variance = magnitudes.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n;
            100.0 * variance.sqrt() / mean.max(f64::MIN_POSITIVE)
        };
        let n_in_f = n_in.max(1) as f64;
        let covariance = self.covariance(set, options).unwrap_or(ParamMat::zeros());
        let std_of = |idx: usize| covariance[(idx, idx)].max(0.0).sqrt();
        let scale = state
            .correction
            .determinant()
            .abs()
            .cbrt()
            .max(f64::MIN_POSITIVE);
        let hard_iron_std_ut = Vector3::new(std_of(H), std_of(H + 1), std_of(H + 2));
        let soft_iron_std = Matrix3::from_fn(|row, col| std_of(D0 + 3 * row + col) / scale);
        let inclination = uses_dip.then(|| {
            let ratio = (state.vertical_ut / state.field_ut).clamp(-1.0, 1.0);
            let cos_dip = (1.0 - ratio * ratio).sqrt().max(1e-6);
            (
                ratio.asin().to_degrees(),
                (std_of(V) / state.field_ut / cos_dip).to_degrees(),
            )
        });
        let unobserved = self.unobserved(
            covariance,
            scale,
            hard_iron_std_ut,
            inclination,
            uses_dip,
            options,
        );
        InertialFit {
            model: self.model,
            model_reason: None,
            calibration: FieldCalibration {
                hard_iron_ut: state.hard_iron_ut,
                soft_iron: state.correction,
                field_ut: state.field_ut,
            },
            uses_dip,
            tilt_untrusted: set.tilt_untrusted(),
            field_from_model: options.field.is_some(),
            inclination_deg: inclination.map(|(deg, _)| deg),
            inclination_std_deg: inclination.map(|(_, std)| std),
            residual_rms_ut: (sum_sq_b / n_in_f).sqrt(),
            field_spread_pct: spread_pct(&inlier_magnitudes),
            field_spread_all_pct: spread_pct(&all_magnitudes),
            vertical_rms_ut: uses_dip.then(|| (sum_sq_v / n_in_f).sqrt()),
            n_samples: all_ut.len(),
            n_fitted: set.mag_ut.len(),
            outlier_pct: 100.0 * n_out as f64 / set.mag_ut.len().max(1) as f64,
            hard_iron_std_ut,
            soft_iron_std,
            heading_std_deg: heading_std_deg(set, state, &covariance),
            unobserved,
        }
    }

    /// The parameters the data could not see, kept near their priors: a hard-iron axis
    /// whose standard deviation exceeds [`UNOBSERVED_HARD_IRON_UT`]; a soft-iron gain,
    /// cross-axis term or rotation (the full model only, the rotation only with the
    /// accelerometer) or the dip (with a field model) whose standard deviation exceeds
    /// [`UNOBSERVED_SHARE`] of its prior's.
    fn unobserved(
        &self,
        covariance: ParamMat,
        scale: f64,
        hard_iron_std_ut: Vector3<f64>,
        inclination: Option<(f64, f64)>,
        uses_dip: bool,
        options: &InertialOptions,
    ) -> Vec<Unobserved> {
        let mut unobserved = Vec::new();
        const AXES: [&str; 3] = ["x", "y", "z"];
        for axis in 0..3 {
            if hard_iron_std_ut[axis] > UNOBSERVED_HARD_IRON_UT {
                unobserved.push(Unobserved {
                    parameter: format!("hard iron {}", AXES[axis]),
                    std: hard_iron_std_ut[axis],
                    unit: "µT",
                });
            }
        }
        // The soft iron in the terms its priors use: each axis's gain, each pair's
        // cross-axis coupling (symmetric part) and rotation (antisymmetric part, fitted
        // only with the accelerometer), each as a fraction of the scale.
        let std_of_combination = |entries: &[((usize, usize), f64)]| {
            let mut gradient = ParamVec::zeros();
            for &((row, col), weight) in entries {
                gradient[D0 + 3 * row + col] = weight / scale;
            }
            (gradient.transpose() * covariance * gradient)[(0, 0)]
                .max(0.0)
                .sqrt()
        };
        for (axis, name) in AXES.iter().enumerate() {
            let std = std_of_combination(&[((axis, axis), 1.0)]);
            if self.model == SoftIronModel::Full && std > UNOBSERVED_SHARE * SOFT_IRON_PRIOR_STD {
                unobserved.push(Unobserved {
                    parameter: format!("soft iron gain {name}"),
                    std,
                    unit: "of the scale",
                });
            }
        }
        for (a, b) in [(0, 1), (0, 2), (1, 2)] {
            let name = format!("{}{}", AXES[a], AXES[b]);
            let cross = std_of_combination(&[((a, b), 0.5), ((b, a), 0.5)]);
            if self.model == SoftIronModel::Full && cross > UNOBSERVED_SHARE * CROSS_AXIS_PRIOR_STD
            {
                unobserved.push(Unobserved {
                    parameter: format!("cross-axis soft iron {name}"),
                    std: cross,
                    unit: "of the scale",
                });
            }
            let rotation_deg = std_of_combination(&[((a, b), 0.5), ((b, a), -0.5)]).to_degrees();
            let axis = AXES[3 - a - b];
            if self.model == SoftIronModel::Full
                && uses_dip
                && rotation_deg > UNOBSERVED_SHARE * ROTATION_PRIOR_STD_RAD.to_degrees()
            {
                unobserved.push(Unobserved {
                    parameter: format!("rotation about {axis} (magnetometer to accelerometer)"),
                    std: rotation_deg,
                    unit: "°",
                });
            }
        }
        if let (Some((_, std_deg)), Some(_)) = (inclination, options.field) {
            if std_deg > UNOBSERVED_SHARE * INCLINATION_PRIOR_STD_DEG {
                unobserved.push(Unobserved {
                    parameter: "dip".to_string(),
                    std: std_deg,
                    unit: "°",
                });
            }
        }
        unobserved
    }
}

/// RMS over the samples of the heading's standard deviation that the parameters'
/// covariance gives, through `ψ = atan2(−l_y, l_x)` of the levelled correction.
fn heading_std_deg(set: &SampleSet, state: &State, covariance: &ParamMat) -> f64 {
    let stride = set.mag_ut.len().div_ceil(500).max(1);
    let (mut sum_variance, mut n) = (0.0, 0usize);
    for (idx, &m_ut) in set.mag_ut.iter().enumerate().step_by(stride) {
        let down = set.down(idx).unwrap_or(Vector3::z());
        // The two horizontal axes of the level frame, expressed in body axes: the
        // forward axis projected on the horizontal, and down × forward.
        let forward = (Vector3::x() - down * down.x).try_normalize(1e-9);
        let Some(forward) = forward else {
            continue;
        };
        let right = down.cross(&forward);
        let d_ut = m_ut - state.hard_iron_ut;
        let corrected = state.correction * d_ut;
        let level = Vector2::new(forward.dot(&corrected), right.dot(&corrected));
        let norm_sq = level.norm_squared();
        if norm_sq <= 0.0 {
            continue;
        }
        // dψ = (l_y·dl_x − l_x·dl_y) / |l|², with dl = (forwardᵀ, rightᵀ)·dc.
        let direction = (forward * level.y - right * level.x) / norm_sq;
        let gradient = row_gradient(&state.correction, direction, d_ut, 0.0);
        sum_variance += (gradient.transpose() * covariance * gradient)[(0, 0)].max(0.0);
        n += 1;
    }
    (sum_variance / n.max(1) as f64).sqrt().to_degrees()
}
