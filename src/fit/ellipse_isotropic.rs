//! The tilt-aware hard-iron fit with an isotropic soft iron: the fallback of
//! [`crate::fit::ellipse`] when the data cannot support a full soft-iron matrix.
//!
//! ## The model
//!
//! Moafipoor et al. (2007), Eq. 5, with the soft iron `C_soft-iron·S_SF` reduced to a
//! multiple of the identity: the magnetometer reads `m = k·Tᵀ·n(ψ) + h + noise` (µT,
//! body frame x forward, y right, z down), where `T = Ry(θ)·Rx(φ)` is the levelling
//! rotation of Eq. 4, `n(ψ) = (H·cosψ, −H·sinψ, V)` the field in the level frame of a
//! device facing ψ, and `h` the hard iron, fixed in the body frame. The hard iron is
//! removed in the body frame *before* levelling, `l = T·(m − h)`, and every sample
//! gives two conditions that do not involve the unknown heading:
//!
//! ```text
//! r_horizontal = |(l_x, l_y)| − H      (the levelled horizontal field is a circle)
//! r_vertical   = l_z − V               (the levelled vertical field is constant)
//! ```
//!
//! The scale `k` is absorbed into `H` and `V` (a common scale changes no heading). The
//! unknowns are `h`, `H` and the vertical field: `V` itself ([`Vertical::Free`]),
//! `V = H·tan(dip)` with the dip of a field model ([`Vertical::ModelDip`]), or none
//! with `h_z` held ([`Vertical::Held`]).
//!
//! ## Why this and not the full matrix
//!
//! With a few degrees of tilt, a vertical hard iron of hundreds of µT (phones: the
//! speaker magnet, the battery) and a field that varies by several µT along an indoor
//! walk, the full model's `A_zz` and `A_xz`, `A_yz` can trade the vertical residual
//! for the disturbances: the fit shrinks the corrected vertical axis to nearly nothing
//! and moves the hard iron by tens of µT. Real soft iron changes the axes by tens of
//! per cent; the isotropic model keeps that prior exactly (a flat phone sees no
//! anisotropy it could fit honestly) and leaves five well-observed unknowns.
//!
//! ## What the data observes, and the limits
//!
//! A full turn fixes `h_x`, `h_y` and `H` (the circle's centre and radius). The
//! vertical hard iron and the vertical field enter only as `h_z + V` at level; tilt
//! separates them through the horizontal residual's `θ·(m_z − h_z)` term, a signal of
//! `V·sin θ` (about 2 µT at 3°) that indoor disturbances of 5 µT swamp: on such data
//! [`Vertical::Free`] gives `h_z` to tens of µT, and [`Vertical::ModelDip`] gives it
//! as well as the field model describes the *local* vertical field. Inside buildings
//! the local field departs from the model by several µT, so `h_z` then carries that
//! departure. The horizontal hard iron does not: it is set by the turn.
//!
//! The fit is Levenberg-Marquardt on the normal equations (`fit::normal_lm`) with
//! the analytic Jacobian `∂l/∂h = −T`; the model is nearly linear in `h`, so a start from the
//! conic centre of the levelled raw field converges.

use nalgebra::{Matrix3, Vector2, Vector3};

use crate::fit::ellipse::PlaneError;
use crate::fit::normal_lm::{self, Normal};

/// How the vertical field is handled.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Vertical {
    /// `V` is an unknown; `h_z` is estimated from the tilt.
    Free,
    /// `V = H·tan(dip)` with the dip of a field model; `h_z` is estimated.
    ModelDip { tan_inclination: f64 },
    /// Too little tilt and no model: `h_z` stays at its start, `V` is an unknown.
    Held,
}

/// The isotropic fit: the hard iron and the corrected level field.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IsotropicFit {
    /// The hard iron `h`, body frame.
    pub hard_iron_ut: Vector3<f64>,
    /// The horizontal field `H` (in the magnetometer's own scale).
    pub horizontal_field_ut: f64,
    /// The vertical field `V`, positive down.
    pub vertical_field_ut: f64,
}

/// Fits `h`, `H` and the vertical field to magnetometer samples (µT, body frame) and
/// the levelling rotation `T = Ry(θ)·Rx(φ)` of each, starting from a hard iron and a
/// horizontal field.
pub fn fit_isotropic(
    mag_ut: &[Vector3<f64>],
    levelling: &[Matrix3<f64>],
    start_hard_iron_ut: Vector3<f64>,
    start_horizontal_field_ut: f64,
    vertical: Vertical,
) -> Result<IsotropicFit, PlaneError> {
    if mag_ut.len() != levelling.len() {
        return Err(PlaneError::LengthMismatch {
            n_mag: mag_ut.len(),
            n_tilt: levelling.len(),
        });
    }
    let mut params = [
        start_hard_iron_ut.x,
        start_hard_iron_ut.y,
        start_hard_iron_ut.z,
        start_horizontal_field_ut,
        0.0,
    ];
    // The start of `V` (or of `h_z` with the dip given): the mean levelled vertical.
    let n_samples = mag_ut.len().max(1) as f64;
    let mean_level_z_ut = mag_ut
        .iter()
        .zip(levelling)
        .map(|(&mag, levelling)| (levelling * (mag - start_hard_iron_ut)).z)
        .sum::<f64>()
        / n_samples;
    let free: Vec<usize> = match vertical {
        Vertical::Free => {
            params[V_OR_UNUSED] = mean_level_z_ut;
            vec![H_X, H_Y, H_Z, H, V_OR_UNUSED]
        }
        Vertical::ModelDip { tan_inclination } => {
            params[H_Z] += mean_level_z_ut - start_horizontal_field_ut * tan_inclination;
            vec![H_X, H_Y, H_Z, H]
        }
        Vertical::Held => {
            params[V_OR_UNUSED] = mean_level_z_ut;
            vec![H_X, H_Y, H, V_OR_UNUSED]
        }
    };
    let problem = IsotropicProblem {
        mag_ut,
        levelling,
        vertical,
    };
    // Running out of steps still leaves the best parameters found.
    normal_lm::minimize_thinned_then_all(
        &mut params,
        &free,
        mag_ut.len(),
        MAX_LM_STEPS,
        |params, stride| problem.normal_equations(params, stride),
    )
    .map_err(|reason| PlaneError::NotConverged {
        reason: reason.to_string(),
    })?;
    if !params.iter().all(|value| value.is_finite()) {
        return Err(PlaneError::NotConverged {
            reason: "the parameters became infinite".to_string(),
        });
    }
    Ok(IsotropicFit {
        hard_iron_ut: Vector3::new(params[H_X], params[H_Y], params[H_Z]),
        horizontal_field_ut: params[H],
        vertical_field_ut: vertical_field_ut(vertical, &params),
    })
}

// The parameters, in this order: the hard iron, `H`, and `V` (unused with the dip).
const H_X: usize = 0;
const H_Y: usize = 1;
const H_Z: usize = 2;
const H: usize = 3;
const V_OR_UNUSED: usize = 4;
const N_PARAMS: usize = 5;

/// Levenberg-Marquardt steps before the fit keeps the best parameters it found (see
/// `fit::ellipse`'s `MAX_LM_STEPS`).
const MAX_LM_STEPS: usize = 30;

/// `V` for the parameters.
fn vertical_field_ut(vertical: Vertical, params: &[f64; N_PARAMS]) -> f64 {
    match vertical {
        Vertical::ModelDip { tan_inclination } => params[H] * tan_inclination,
        Vertical::Free | Vertical::Held => params[V_OR_UNUSED],
    }
}

/// The residuals of the module header, two per sample.
struct IsotropicProblem<'a> {
    mag_ut: &'a [Vector3<f64>],
    levelling: &'a [Matrix3<f64>],
    vertical: Vertical,
}

impl IsotropicProblem<'_> {
    /// One sample's two residuals (horizontal, vertical) and their gradients with
    /// respect to every parameter.
    fn sample_rows(
        &self,
        params: &[f64; N_PARAMS],
        mag_ut: &Vector3<f64>,
        levelling: &Matrix3<f64>,
    ) -> [(f64, [f64; N_PARAMS]); 2] {
        let hard_iron_ut = Vector3::new(params[H_X], params[H_Y], params[H_Z]);
        let level = levelling * (mag_ut - hard_iron_ut);
        // The horizontal residual moves along the unit horizontal direction; at the
        // origin it has no direction and no derivative.
        let horizontal_norm = level.xy().norm();
        let direction = if horizontal_norm > 0.0 {
            level.xy() / horizontal_norm
        } else {
            Vector2::zeros()
        };
        let mut horizontal = [0.0; N_PARAMS];
        let mut vertical = [0.0; N_PARAMS];
        // ∂l/∂h_j = −T·e_j, the j-th column of −T.
        for axis in [H_X, H_Y, H_Z] {
            let column_of_t = levelling.column(axis);
            horizontal[axis] = -direction.dot(&Vector2::new(column_of_t[0], column_of_t[1]));
            vertical[axis] = -column_of_t[2];
        }
        horizontal[H] = -1.0;
        match self.vertical {
            Vertical::ModelDip { tan_inclination } => vertical[H] = -tan_inclination,
            Vertical::Free | Vertical::Held => vertical[V_OR_UNUSED] = -1.0,
        }
        [
            (horizontal_norm - params[H], horizontal),
            (level.z - vertical_field_ut(self.vertical, params), vertical),
        ]
    }

    /// The normal equations of every `stride`-th sample's residuals at `params`, in one
    /// pass over the samples.
    fn normal_equations(
        &self,
        params: &[f64; N_PARAMS],
        stride: usize,
    ) -> Option<Normal<N_PARAMS>> {
        let mut normal = Normal::zeros();
        for (mag_ut, levelling) in self.mag_ut.iter().zip(self.levelling).step_by(stride) {
            normal.add_pair(&self.sample_rows(params, mag_ut, levelling));
        }
        normal.finished()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::base::rng::SplitMix64;
    use nalgebra::Rotation3;

    /// Samples of a field `(H, 0, V)` in NED seen through the hard iron at every
    /// heading and a few degrees of tilt, with the levelling rotation of each.
    fn flat_walk(
        hard_iron_ut: Vector3<f64>,
        horizontal_ut: f64,
        vertical_ut: f64,
        tilt_deg: f64,
        rng: &mut SplitMix64,
    ) -> (Vec<Vector3<f64>>, Vec<Matrix3<f64>>) {
        let field_in_ned_ut = Vector3::new(horizontal_ut, 0.0, vertical_ut);
        (0..720)
            .map(|sample_idx| {
                let yaw_rad = (sample_idx as f64 * 1.5).to_radians();
                let roll_rad = rng.uniform_in(-tilt_deg, tilt_deg).to_radians();
                let pitch_rad = rng.uniform_in(-tilt_deg, tilt_deg).to_radians();
                let ned_from_body = Rotation3::from_euler_angles(roll_rad, pitch_rad, yaw_rad);
                let mag = ned_from_body.inverse() * field_in_ned_ut + hard_iron_ut;
                let levelling = Rotation3::from_euler_angles(roll_rad, pitch_rad, 0.0);
                (mag, *levelling.matrix())
            })
            .unzip()
    }

    #[test]
    fn a_large_vertical_hard_iron_is_recovered_in_every_vertical_mode() {
        let mut rng = SplitMix64::new(3);
        let truth_ut = Vector3::new(-90.0, -56.0, 300.0);
        let (mag, levelling) = flat_walk(truth_ut, 34.0, 35.0, 4.0, &mut rng);
        let start_ut = Vector3::new(-80.0, -50.0, 0.0);
        for vertical in [
            Vertical::Free,
            Vertical::ModelDip {
                tan_inclination: 35.0 / 34.0,
            },
        ] {
            let fit = fit_isotropic(&mag, &levelling, start_ut, 30.0, vertical).expect("fits");
            assert!(
                (fit.hard_iron_ut - truth_ut).norm() < 1e-6,
                "{vertical:?}: {:?}",
                fit.hard_iron_ut
            );
            assert!((fit.horizontal_field_ut - 34.0).abs() < 1e-6);
            assert!((fit.vertical_field_ut - 35.0).abs() < 1e-6);
        }
        // Held: the horizontal part is still exact at level, h_z stays where it started.
        let (mag, levelling) = flat_walk(truth_ut, 34.0, 35.0, 0.0, &mut rng);
        let fit = fit_isotropic(&mag, &levelling, start_ut, 30.0, Vertical::Held).expect("fits");
        assert!((fit.hard_iron_ut.xy() - truth_ut.xy()).norm() < 1e-6);
        assert_eq!(fit.hard_iron_ut.z, 0.0);
        assert!((fit.vertical_field_ut - 335.0).abs() < 1e-6);
    }

    #[test]
    fn a_wrong_model_dip_moves_only_the_vertical_hard_iron() {
        // The local vertical field is 7 µT below the model's: h_z takes it, h_x and h_y
        // stay within a small fraction of a µT.
        let mut rng = SplitMix64::new(4);
        let truth_ut = Vector3::new(-40.0, -52.0, 270.0);
        let (mag, levelling) = flat_walk(truth_ut, 33.0, 28.0, 4.0, &mut rng);
        let fit = fit_isotropic(
            &mag,
            &levelling,
            Vector3::new(-30.0, -40.0, 0.0),
            30.0,
            Vertical::ModelDip {
                tan_inclination: 35.0 / 33.0,
            },
        )
        .expect("fits");
        let error_ut = fit.hard_iron_ut - truth_ut;
        assert!(error_ut.xy().norm() < 0.5, "{error_ut:?}");
        assert!((error_ut.z + 7.0).abs() < 0.5, "{error_ut:?}");
    }

    #[test]
    fn mismatched_lengths_are_an_error() {
        let result = fit_isotropic(
            &[Vector3::zeros(); 3],
            &[Matrix3::identity(); 2],
            Vector3::zeros(),
            30.0,
            Vertical::Free,
        );
        assert!(matches!(result, Err(PlaneError::LengthMismatch { .. })));
    }

    #[test]
    fn the_jacobian_matches_numerical_differentiation() {
        let mut rng = SplitMix64::new(6);
        let (mag, levelling) = flat_walk(Vector3::new(5.0, -3.0, 40.0), 20.0, 40.0, 8.0, &mut rng);
        for vertical in [
            Vertical::Free,
            Vertical::ModelDip {
                tan_inclination: 1.7,
            },
        ] {
            let problem = IsotropicProblem {
                mag_ut: &mag,
                levelling: &levelling,
                vertical,
            };
            let params = [4.0, -2.0, 30.0, 22.0, 35.0];
            let step = 1e-6;
            for (mag_ut, levelling) in mag.iter().zip(&levelling) {
                let analytic = problem.sample_rows(&params, mag_ut, levelling);
                for param_idx in 0..N_PARAMS {
                    let (mut plus, mut minus) = (params, params);
                    plus[param_idx] += step;
                    minus[param_idx] -= step;
                    let plus = problem.sample_rows(&plus, mag_ut, levelling);
                    let minus = problem.sample_rows(&minus, mag_ut, levelling);
                    for residual_idx in 0..2 {
                        let numeric = (plus[residual_idx].0 - minus[residual_idx].0) / (2.0 * step);
                        let difference = (numeric - analytic[residual_idx].1[param_idx]).abs();
                        assert!(
                            difference < 1e-5,
                            "{vertical:?} parameter {param_idx}: {difference}"
                        );
                    }
                }
            }
        }
    }
}
