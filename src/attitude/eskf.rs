//! The error-state Kalman filter on the attitude and the gyroscope's bias: *how* each
//! measurement is fused. *When* to fuse (rest, disturbed field, accelerating body) is
//! [`super::gates`]' and the driver's, as PX4's EKF2 splits `control` from `fusion`.
//!
//! ## State and frames
//!
//! The nominal state is the attitude `q` (a unit quaternion turning body vectors, x
//! forward, y right, z down, into the navigation frame, x magnetic north, y east, z down)
//! and the gyroscope's bias `b` (rad/s, body axes). The error state is six numbers: a
//! small rotation `δθ` **in the navigation frame** (`q_true = exp(δθ) ⊗ q`) and
//! `δb = b_true − b`. A navigation-frame error makes the yaw error simply `δθ_z` (a turn
//! about down), so the heading's variance is `P[2][2]` and a heading measurement touches
//! the yaw alone (Solà 2017, *Quaternion kinematics for the error-state Kalman filter*,
//! §7, "global angular error").
//!
//! ## Equations
//!
//! - **Propagation** over `Δt` with the measured rate `ω`: `q ← q ⊗ exp((ω − b)·Δt)`;
//!   `δθ ← δθ − R·δb·Δt` (a bias error turns the attitude by what it adds), so
//!   `F = [[I, −R·Δt], [0, I]]`; the process noise adds the gyroscope's angle random walk
//!   and a scale-factor term proportional to the rate (a 1 % scale error at 5 rad/s is
//!   worth more than any noise) to `δθ`, and the bias's random walk to `δb`.
//! - **Gravity**: a body at rest feels the specific force `f_n = (0, 0, −g)`. With
//!   `R_true ≈ (I + [δθ]×)·R`, the measured unit force turned by the filter's `R` is
//!   `R·f̂_b ≈ (I − [δθ]×)·(0, 0, −1) = (δθ_y, −δθ_x, −1)`: its horizontal part
//!   measures the tilt error, and gravity never corrects the yaw.
//! - **Magnetic heading**: the calibrated field turned into the navigation frame, `m_n =
//!   R·m_b`, points north where the yaw is right. Its angle from north,
//!   `atan2(m_n,y, m_n,x)`, is `−δθ_z` to first order, plus a term in the tilt error times
//!   the dip's tangent that is left out: only the yaw is corrected (`H = [0, 0, −1, 0…]`),
//!   so a dipping field cannot tilt the attitude.
//! - **Zero rate**: at rest the gyroscope reads its bias: `ω − b = δb + noise`.
//!
//! Every measurement is a few rows, each reading one error component, fused one row
//! after the other (exact for independent noises); gravity is fused with the bias as a
//! considered state, so that it never moves the bias. Each correction is injected
//! (`q ← exp(δθ) ⊗ q`, `b ← b + δb`) and the error reset to zero; the covariance is kept
//! (the reset's Jacobian is the identity to first order).

use nalgebra::{Matrix3, Matrix6, UnitQuaternion, Vector3, Vector6};

/// The filter's tuning: every noise as the physical quantity it stands for.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoiseModel {
    /// Angle random walk of the gyroscope (rad/√s).
    pub gyro_arw_rad_per_sqrt_s: f64,
    /// Scale-factor and misalignment error of the gyroscope (fraction of the rate).
    pub gyro_scale_error: f64,
    /// Random walk of the gyroscope's bias (rad/s/√s).
    pub bias_walk_radps_per_sqrt_s: f64,
}

/// The attitude and bias with their covariance.
#[derive(Debug, Clone, PartialEq)]
pub struct Eskf {
    /// Body to navigation (x magnetic north, y east, z down).
    pub nav_from_body: UnitQuaternion<f64>,
    pub gyro_bias_radps: Vector3<f64>,
    /// Covariance of `[δθ (nav frame, rad), δb (rad/s)]`.
    pub covariance: Matrix6<f64>,
    noise: NoiseModel,
}

/// What a fusion did: its innovation, normalised (the squared Mahalanobis distance),
/// or why it was not applied.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Fused {
    Applied {
        nis: f64,
    },
    /// The innovation was further than the gate allows: nothing was changed.
    Gated {
        nis: f64,
    },
    /// The measurement gave no direction (a field or force near zero, a singular
    /// innovation covariance).
    Degenerate,
}

impl Eskf {
    /// A filter at `nav_from_body`, with 1σ uncertainties of the tilt, the yaw and the
    /// bias.
    pub fn new(
        nav_from_body: UnitQuaternion<f64>,
        (tilt_sigma_rad, yaw_sigma_rad, bias_sigma_radps): (f64, f64, f64),
        noise: NoiseModel,
    ) -> Eskf {
        let mut covariance = Matrix6::zeros();
        covariance[(0, 0)] = tilt_sigma_rad.powi(2);
        covariance[(1, 1)] = tilt_sigma_rad.powi(2);
        covariance[(2, 2)] = yaw_sigma_rad.powi(2);
        for idx in 3..6 {
            covariance[(idx, idx)] = bias_sigma_radps.powi(2);
        }
        Eskf {
            nav_from_body,
            gyro_bias_radps: Vector3::zeros(),
            covariance,
            noise,
        }
    }

    /// Turns the attitude by the measured rate over `dt_s` and grows the covariance.
    pub fn propagate(&mut self, rate_in_body_radps: Vector3<f64>, dt_s: f64) {
        let corrected_radps = rate_in_body_radps - self.gyro_bias_radps;
        let rotation = self.nav_from_body.to_rotation_matrix().into_inner();
        self.nav_from_body *= UnitQuaternion::from_scaled_axis(corrected_radps * dt_s);
        // P ← F P Fᵀ + Q with F = [[I, A], [0, I]], A = −R·Δt, written by blocks (the
        // full 6×6 products would be most of the filter's time).
        let a = -rotation * dt_s;
        let p_tt = self.covariance.fixed_view::<3, 3>(0, 0).into_owned();
        let p_tb = self.covariance.fixed_view::<3, 3>(0, 3).into_owned();
        let p_bb = self.covariance.fixed_view::<3, 3>(3, 3).into_owned();
        let a_p_bb = a * p_bb;
        let new_tb = p_tb + a_p_bb;
        let mut new_tt =
            p_tt + a * p_tb.transpose() + p_tb * a.transpose() + a_p_bb * a.transpose();
        let rate_noise_radps = self.noise.gyro_scale_error * corrected_radps.norm();
        let angle_variance =
            self.noise.gyro_arw_rad_per_sqrt_s.powi(2) * dt_s + (rate_noise_radps * dt_s).powi(2);
        for idx in 0..3 {
            new_tt[(idx, idx)] += angle_variance;
        }
        let bias_variance = self.noise.bias_walk_radps_per_sqrt_s.powi(2) * dt_s;
        let mut new_bb = p_bb;
        for idx in 0..3 {
            new_bb[(idx, idx)] += bias_variance;
        }
        self.covariance
            .fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&symmetric(new_tt));
        self.covariance
            .fixed_view_mut::<3, 3>(0, 3)
            .copy_from(&new_tb);
        self.covariance
            .fixed_view_mut::<3, 3>(3, 0)
            .copy_from(&new_tb.transpose());
        self.covariance
            .fixed_view_mut::<3, 3>(3, 3)
            .copy_from(&new_bb);
    }

    /// Adds `variance_rad2` to the yaw's variance: a turn not seen (a gap in the
    /// gyroscope's samples).
    pub fn inflate_yaw(&mut self, variance_rad2: f64) {
        self.covariance[(2, 2)] += variance_rad2;
    }

    /// Fuses the direction of the specific force as that of gravity, with a 1σ of
    /// `sigma_rad` on each tilt axis; not applied beyond `max_nis` (2 degrees of
    /// freedom).
    pub fn fuse_gravity(
        &mut self,
        specific_force_in_body: Vector3<f64>,
        sigma_rad: f64,
        max_nis: f64,
    ) -> Fused {
        let norm = specific_force_in_body.norm();
        if !(norm > 1e-6 && norm.is_finite()) {
            return Fused::Degenerate;
        }
        let in_nav = self.nav_from_body * (specific_force_in_body / norm);
        self.fuse_gravity_in_nav(
            nalgebra::Vector2::new(in_nav.x, in_nav.y),
            sigma_rad,
            max_nis,
        )
    }

    /// [`Eskf::fuse_gravity`] given the horizontal part of the unit specific force
    /// already turned into the navigation frame by this filter's attitude (or the mean of
    /// several such, as the driver fuses them). That part is `(δθ_y, −δθ_x)` to first
    /// order (`R·f̂_b = (I − [δθ]×)·(0, 0, −1)`): a two-dimensional measurement of the
    /// tilt error with an isotropic noise (a rotation keeps it isotropic), the yaw absent.
    pub fn fuse_gravity_in_nav(
        &mut self,
        horizontal_in_nav: nalgebra::Vector2<f64>,
        sigma_rad: f64,
        max_nis: f64,
    ) -> Fused {
        let variance = sigma_rad.powi(2);
        let p = &self.covariance;
        // S = H·P·Hᵀ + R for the rows (δθ_y, −δθ_x).
        let (s11, s22, s12) = (p[(1, 1)] + variance, p[(0, 0)] + variance, -p[(1, 0)]);
        let determinant = s11 * s22 - s12 * s12;
        let (y1, y2) = (horizontal_in_nav.x, horizontal_in_nav.y);
        let nis = (y1 * y1 * s22 - 2.0 * y1 * y2 * s12 + y2 * y2 * s11) / determinant;
        self.fuse_rows(
            &[(1, 1.0, y1), (0, -1.0, y2)],
            variance,
            (nis, max_nis),
            false,
        )
    }

    /// The angle of the horizontal field from the filter's north (rad): zero where the
    /// yaw agrees with the magnetometer; `None` for a field with no horizontal part.
    pub fn magnetic_heading_error(&self, field_in_body: Vector3<f64>) -> Option<f64> {
        let field_in_nav = self.nav_from_body * field_in_body;
        let horizontal = field_in_nav.xy().norm();
        (horizontal > 1e-9 * field_in_nav.norm().max(1e-300) && horizontal.is_finite())
            .then(|| field_in_nav.y.atan2(field_in_nav.x))
    }

    /// Fuses the magnetic heading (see the module header) with a 1σ of `sigma_rad`; not
    /// applied beyond `max_nis` (one degree of freedom); the bias is corrected too, or
    /// only considered.
    pub fn fuse_magnetic_heading(
        &mut self,
        field_in_body: Vector3<f64>,
        sigma_rad: f64,
        max_nis: f64,
        corrects_bias: bool,
    ) -> Fused {
        let Some(angle_rad) = self.magnetic_heading_error(field_in_body) else {
            return Fused::Degenerate;
        };
        let variance = sigma_rad.powi(2);
        let nis = angle_rad.powi(2) / (self.covariance[(2, 2)] + variance);
        self.fuse_rows(
            &[(2, -1.0, angle_rad)],
            variance,
            (nis, max_nis),
            corrects_bias,
        )
    }

    /// Fuses "the body is not turning": the rate left after the bias is removed is
    /// the bias's error, with a 1σ of `sigma_radps`.
    pub fn fuse_zero_rate(&mut self, rate_in_body_radps: Vector3<f64>, sigma_radps: f64) -> Fused {
        let innovation = rate_in_body_radps - self.gyro_bias_radps;
        let rows = [
            (3, 1.0, innovation.x),
            (4, 1.0, innovation.y),
            (5, 1.0, innovation.z),
        ];
        self.fuse_rows(&rows, sigma_radps.powi(2), (0.0, f64::INFINITY), true)
    }

    /// Re-aims the yaw at the magnetometer's and sets its variance: the recovery after
    /// the field was refused for long though it looked undisturbed (the filter, not the
    /// field, was wrong), as Fusion's recovery trigger does.
    pub fn reset_yaw_to(&mut self, field_in_body: Vector3<f64>, yaw_sigma_rad: f64) {
        if let Some(angle_rad) = self.magnetic_heading_error(field_in_body) {
            let turn = UnitQuaternion::from_scaled_axis(Vector3::new(0.0, 0.0, -angle_rad));
            self.nav_from_body = turn * self.nav_from_body;
            for idx in 0..6 {
                self.covariance[(2, idx)] = 0.0;
                self.covariance[(idx, 2)] = 0.0;
            }
            self.covariance[(2, 2)] = yaw_sigma_rad.powi(2);
        }
    }

    /// Re-levels the attitude on `specific_force_in_body` taken as gravity's direction,
    /// turning it as little as that takes: a tilt lost (a gyroscope saturated while
    /// the body tumbled) that the gate on gravity would refuse to mend forever. The tilt's
    /// variance restarts at `tilt_sigma_rad`² and its correlations at zero.
    pub fn reset_tilt_to(&mut self, specific_force_in_body: Vector3<f64>, tilt_sigma_rad: f64) {
        let norm = specific_force_in_body.norm();
        if !(norm > 1e-6 && norm.is_finite()) {
            return;
        }
        // The smallest turn of the navigation frame that points the force up: about a
        // horizontal axis, so a level body keeps its heading (a half turn about north
        // when the force points straight down).
        let up_in_nav = self.nav_from_body * (specific_force_in_body / norm);
        let turn =
            UnitQuaternion::rotation_between(&up_in_nav, &-Vector3::z()).unwrap_or_else(|| {
                UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI)
            });
        self.nav_from_body = turn * self.nav_from_body;
        for row in 0..2 {
            for idx in 0..6 {
                self.covariance[(row, idx)] = 0.0;
                self.covariance[(idx, row)] = 0.0;
            }
            self.covariance[(row, row)] = tilt_sigma_rad.powi(2);
        }
    }

    /// One Kalman update with a measurement whose rows each read one error-state
    /// component (`(index, sign, innovation)`: `innovation = sign·δx[index] + noise`),
    /// with independent noises of `variance`, processed one row after the other (exact
    /// for independent noises, and one small routine instead of a matrix update per
    /// measurement size). `nis` is the whole measurement's squared Mahalanobis distance,
    /// refused beyond `max_nis`. Without `corrects_bias` the bias is a *considered*
    /// state (Schmidt's filter): its uncertainty widens the innovation's, but the
    /// measurement does not move it. Gravity's direction is fused so: a walking body's
    /// acceleration is correlated with its attitude over a step, and a bias learnt from
    /// it turns the heading (on the shared attitude trials, a bias of 0.07 rad/s grew in
    /// two minutes of a phone in a pocket); the field, as the options say.
    fn fuse_rows(
        &mut self,
        rows: &[(usize, f64, f64)],
        variance: f64,
        (nis, max_nis): (f64, f64),
        corrects_bias: bool,
    ) -> Fused {
        if !nis.is_finite() || variance.is_nan() || variance <= 0.0 {
            return Fused::Degenerate;
        }
        if nis > max_nis {
            return Fused::Gated { nis };
        }
        let mut correction = Vector6::zeros();
        for &(index, sign, innovation) in rows {
            let p_h: Vector6<f64> = self.covariance.column(index) * sign;
            let s = sign * p_h[index] + variance;
            let mut gain = p_h / s;
            if !corrects_bias {
                gain.fixed_rows_mut::<3>(3).fill(0.0);
            }
            // The rows before this one moved the state: the innovation is taken from
            // where they left it.
            let residual = innovation - sign * correction[index];
            correction += gain * residual;
            // Joseph's form, expanded with P·hᵀ = k_opt·s: P − k·(Phᵀ)ᵀ − Phᵀ·kᵀ + s·k·kᵀ.
            // It holds for any gain (Schmidt's too). Computed on one triangle and
            // mirrored, so P stays exactly symmetric.
            for col in 0..6 {
                for row in 0..=col {
                    let change =
                        gain[row] * p_h[col] + p_h[row] * gain[col] - s * gain[row] * gain[col];
                    let value = self.covariance[(row, col)] - change;
                    self.covariance[(row, col)] = value;
                    self.covariance[(col, row)] = value;
                }
            }
        }
        let turn = Vector3::new(correction[0], correction[1], correction[2]);
        self.nav_from_body = UnitQuaternion::from_scaled_axis(turn) * self.nav_from_body;
        self.gyro_bias_radps += Vector3::new(correction[3], correction[4], correction[5]);
        Fused::Applied { nis }
    }

    /// The yaw's 1σ (rad).
    pub fn yaw_sigma_rad(&self) -> f64 {
        self.covariance[(2, 2)].max(0.0).sqrt()
    }

    /// (roll, pitch, yaw) in radians, yaw clockwise from magnetic north in (−π, π].
    pub fn roll_pitch_yaw_rad(&self) -> (f64, f64, f64) {
        self.nav_from_body.euler_angles()
    }
}

fn symmetric(m: Matrix3<f64>) -> Matrix3<f64> {
    (m + m.transpose()) * 0.5
}

/// The attitude of a body whose specific force is `specific_force_in_body` (at rest) and
/// whose field is `field_in_body`: roll and pitch from the force, the yaw from the
/// levelled field (magnetic north), or 0 without a field.
pub fn attitude_from(
    specific_force_in_body: Vector3<f64>,
    field_in_body: Option<Vector3<f64>>,
) -> UnitQuaternion<f64> {
    // f_b = Rᵀ·(0, 0, −g): f_x = g·sin θ, f_y = −g·sin φ·cos θ, f_z = −g·cos φ·cos θ.
    let f = specific_force_in_body;
    let pitch_rad = f.x.atan2(f.yz().norm());
    let roll_rad = (-f.y).atan2(-f.z);
    let level_from_body = UnitQuaternion::from_euler_angles(roll_rad, pitch_rad, 0.0);
    let yaw_rad = field_in_body.map_or(0.0, |field| {
        let level = level_from_body * field;
        (-level.y).atan2(level.x)
    });
    UnitQuaternion::from_euler_angles(roll_rad, pitch_rad, yaw_rad)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::FRAC_PI_2;

    const QUIET: NoiseModel = NoiseModel {
        gyro_arw_rad_per_sqrt_s: 1e-3,
        gyro_scale_error: 0.0,
        bias_walk_radps_per_sqrt_s: 1e-5,
    };

    /// The field (north, dipping 60°) and the specific force at rest, in the body of a
    /// device at `nav_from_body`.
    fn seen_by(nav_from_body: UnitQuaternion<f64>) -> (Vector3<f64>, Vector3<f64>) {
        let field_in_nav = Vector3::new(20.0, 0.0, 20.0 * 3f64.sqrt());
        let force_in_nav = Vector3::new(0.0, 0.0, -9.81);
        (
            nav_from_body.inverse() * field_in_nav,
            nav_from_body.inverse() * force_in_nav,
        )
    }

    #[test]
    fn the_first_attitude_is_read_from_the_force_and_the_field() {
        let truth = UnitQuaternion::from_euler_angles(0.3, -0.2, 2.5);
        let (field, force) = seen_by(truth);
        let found = attitude_from(force, Some(field));
        assert!(found.angle_to(&truth) < 1e-9, "{}", found.angle_to(&truth));
    }

    #[test]
    fn a_heading_error_is_corrected_by_the_magnetometer_and_not_by_gravity() {
        let truth = UnitQuaternion::from_euler_angles(0.1, 0.2, 1.0);
        let (field, force) = seen_by(truth);
        let start = UnitQuaternion::from_euler_angles(0.1, 0.2, 1.3);
        let mut filter = Eskf::new(start, (0.05, 0.5, 0.01), QUIET);
        filter.fuse_gravity(force, 0.05, f64::INFINITY);
        let (_, _, yaw_after_gravity) = filter.roll_pitch_yaw_rad();
        assert!(
            (yaw_after_gravity - 1.3).abs() < 1e-9,
            "gravity moved the yaw: {yaw_after_gravity}"
        );
        for _ in 0..50 {
            filter.fuse_magnetic_heading(field, 0.05, f64::INFINITY, false);
        }
        let (_, _, yaw) = filter.roll_pitch_yaw_rad();
        assert!((yaw - 1.0).abs() < 1e-3, "{yaw}");
        assert!(filter.yaw_sigma_rad() < 0.01);
    }

    #[test]
    fn a_tilt_error_is_corrected_by_gravity() {
        let truth = UnitQuaternion::from_euler_angles(0.4, -0.3, -2.0);
        let (_, force) = seen_by(truth);
        let start = UnitQuaternion::from_euler_angles(0.2, -0.1, -2.0);
        let mut filter = Eskf::new(start, (0.3, 0.3, 0.01), QUIET);
        for _ in 0..200 {
            filter.fuse_gravity(force, 0.05, f64::INFINITY);
        }
        let (roll, pitch, _) = filter.roll_pitch_yaw_rad();
        assert!(
            (roll - 0.4).abs() < 1e-3 && (pitch + 0.3).abs() < 1e-3,
            "{roll} {pitch}"
        );
    }

    #[test]
    fn a_biased_turn_is_held_by_the_field_and_the_bias_is_learnt_at_rest() {
        // A device turning about down at 0.5 rad/s with a gyroscope biased by 0.02 rad/s:
        // the field holds the yaw (the bias is only considered there), and at rest the
        // zero-rate update learns the bias.
        let bias = Vector3::new(0.01, -0.01, 0.02);
        let mut truth = UnitQuaternion::from_euler_angles(0.0, 0.0, 0.0);
        let mut filter = Eskf::new(truth, (0.01, 0.01, 0.05), QUIET);
        let dt_s = 0.01;
        let rate = Vector3::new(0.0, 0.0, 0.5);
        for step in 0..6000 {
            truth *= UnitQuaternion::from_scaled_axis(rate * dt_s);
            filter.propagate(rate + bias, dt_s);
            let (field, force) = seen_by(truth);
            filter.fuse_gravity(force, 0.05, f64::INFINITY);
            if step % 4 == 0 {
                filter.fuse_magnetic_heading(field, 0.05, f64::INFINITY, false);
            }
        }
        assert!(
            filter.nav_from_body.angle_to(&truth) < 0.02,
            "{}",
            filter.nav_from_body.angle_to(&truth)
        );
        assert!(
            filter.gyro_bias_radps.norm() < 1e-12,
            "moved by the field: {}",
            filter.gyro_bias_radps
        );
        for _ in 0..200 {
            filter.propagate(bias, dt_s);
            filter.fuse_zero_rate(bias, 0.01);
        }
        assert!(
            (filter.gyro_bias_radps - bias).norm() < 2e-3,
            "{}",
            filter.gyro_bias_radps
        );
    }

    #[test]
    fn without_the_field_the_yaw_sigma_grows_and_a_far_heading_is_gated() {
        let mut filter = Eskf::new(UnitQuaternion::identity(), (0.01, 0.01, 0.001), QUIET);
        let before = filter.yaw_sigma_rad();
        for _ in 0..1000 {
            filter.propagate(Vector3::zeros(), 0.01);
        }
        assert!(filter.yaw_sigma_rad() > before);
        let (field, _) = seen_by(UnitQuaternion::from_euler_angles(0.0, 0.0, FRAC_PI_2));
        assert!(matches!(
            filter.fuse_magnetic_heading(field, 0.05, 9.0, false),
            Fused::Gated { .. }
        ));
        filter.reset_yaw_to(field, 0.1);
        let (_, _, yaw) = filter.roll_pitch_yaw_rad();
        assert!((yaw - FRAC_PI_2).abs() < 1e-9, "{yaw}");
    }
}
