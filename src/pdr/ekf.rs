//! The step-wise extended Kalman filter of PDR: state `[E, N, l, a]`.
//!
//! Chen et al., *A unified heading error model and step length estimation for PDR*,
//! Section V, Eq. 13:
//!
//! ```text
//! E_{k+1} = E_k + l_k·sin a_k        l_{k+1} = l_k + w_l,   w_l ~ N(0, σ_l²)
//! N_{k+1} = N_k + l_k·cos a_k        a_{k+1} = a_k + w_a,   w_a ~ N(0, σ_a²)
//! ```
//!
//! with the step's estimated length and compensated heading as the measurement
//! (`H` selects `l` and `a`; the heading innovation is wrapped to ±π). On top of the
//! paper, a loosely coupled GNSS position update (`H` selects `E` and `N`), so that one
//! filter runs through good GNSS, outages and recovery.
//!
//! This file is "how to fuse" only: the caller ([`super::fusion`]) decides which
//! measurements to give it and when. State and covariance are plain `[f64; 4]` and
//! `[[f64; 4]; 4]`, and each operation is written out for the structure of its
//! Jacobian (identity plus two columns), so that a step costs a few dozen
//! multiplications.
//!
//! Frames and units: `E`, `N` in metres east and north of the local origin; `l` in
//! metres; `a` in radians clockwise from true north, kept in `[0, 2π)`.

use serde::Serialize;

use crate::base::angle::{wrap_to_2pi, wrap_to_pi};

/// Noise of the model and the measurements (1 σ).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct EkfNoise {
    /// σ_l: random walk of the step length per step (m).
    pub step_length_walk_m: f64,
    /// σ_a: random walk of the heading per step (rad).
    pub heading_walk_rad: f64,
    /// Noise of a step length from the step model (m).
    pub step_length_measurement_m: f64,
    /// Noise of a compensated heading (rad).
    pub heading_measurement_rad: f64,
}

impl Default for EkfNoise {
    fn default() -> Self {
        EkfNoise {
            step_length_walk_m: 0.05,
            heading_walk_rad: 10f64.to_radians(),
            step_length_measurement_m: 0.05,
            heading_measurement_rad: 5f64.to_radians(),
        }
    }
}

/// The filter's state and covariance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PdrEkf {
    /// `[E (m), N (m), l (m), a (rad)]`.
    pub x: [f64; 4],
    pub p: [[f64; 4]; 4],
    noise: EkfNoise,
}

/// What a GNSS position update did.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PositionInnovation {
    pub east_m: f64,
    pub north_m: f64,
    /// Normalised innovation squared (χ² with 2 degrees of freedom when consistent).
    pub nis: f64,
}

impl PdrEkf {
    /// A filter at `position_en_m` with `position_sigma_m` of uncertainty, and the first
    /// step's length and heading as they were measured.
    pub fn new(
        position_en_m: [f64; 2],
        position_sigma_m: f64,
        length_m: f64,
        heading_rad: f64,
        noise: EkfNoise,
    ) -> PdrEkf {
        let mut p = [[0.0; 4]; 4];
        p[0][0] = position_sigma_m * position_sigma_m;
        p[1][1] = p[0][0];
        p[2][2] = noise.step_length_measurement_m.powi(2);
        p[3][3] = noise.heading_measurement_rad.powi(2);
        PdrEkf {
            x: [
                position_en_m[0],
                position_en_m[1],
                length_m,
                wrap_to_2pi(heading_rad),
            ],
            p,
            noise,
        }
    }

    pub fn noise(&self) -> EkfNoise {
        self.noise
    }

    /// One step: the measured length and heading update `l` and `a`, then Eq. 13
    /// moves the position by the step and lets `l` and `a` walk. The heading's 1σ is
    /// `heading_sigma_rad` where its source states one, else the noise model's.
    pub fn step(
        &mut self,
        measured_length_m: f64,
        measured_heading_rad: f64,
        heading_sigma_rad: Option<f64>,
    ) {
        self.update_length_heading(measured_length_m, measured_heading_rad, heading_sigma_rad);
        self.predict();
    }

    /// Eq. 13's prediction: `x ← f(x)`, `P ← F·P·Fᵀ + Q`, with
    /// `F = I + [0 0 sin a  l·cos a; 0 0 cos a  −l·sin a; 0 0 0 0; 0 0 0 0]`.
    pub fn predict(&mut self) {
        let [_, _, l, a] = self.x;
        let (sin_a, cos_a) = a.sin_cos();
        let p = &self.p;
        // Rows 0 and 1 of F·P (rows 2 and 3 are P's own).
        let fe = [
            p[0][0] + sin_a * p[2][0] + l * cos_a * p[3][0],
            p[0][1] + sin_a * p[2][1] + l * cos_a * p[3][1],
            p[0][2] + sin_a * p[2][2] + l * cos_a * p[3][2],
            p[0][3] + sin_a * p[2][3] + l * cos_a * p[3][3],
        ];
        let fn_ = [
            p[1][0] + cos_a * p[2][0] - l * sin_a * p[3][0],
            p[1][1] + cos_a * p[2][1] - l * sin_a * p[3][1],
            p[1][2] + cos_a * p[2][2] - l * sin_a * p[3][2],
            p[1][3] + cos_a * p[2][3] - l * sin_a * p[3][3],
        ];
        // (F·P)·Fᵀ: column j of Fᵀ is row j of F.
        let ee = fe[0] + sin_a * fe[2] + l * cos_a * fe[3];
        let en = fe[1] + cos_a * fe[2] - l * sin_a * fe[3];
        let nn = fn_[1] + cos_a * fn_[2] - l * sin_a * fn_[3];
        let mut next = self.p;
        next[0][0] = ee;
        next[0][1] = en;
        next[1][0] = en;
        next[1][1] = nn;
        for (col, (&e, &n)) in [(2usize, (&fe[2], &fn_[2])), (3, (&fe[3], &fn_[3]))] {
            next[0][col] = e;
            next[col][0] = e;
            next[1][col] = n;
            next[col][1] = n;
        }
        next[2][2] += self.noise.step_length_walk_m.powi(2);
        next[3][3] += self.noise.heading_walk_rad.powi(2);
        self.p = next;
        self.x[0] += l * sin_a;
        self.x[1] += l * cos_a;
    }

    /// The measurement update with `z = [l, a]` (heading innovation wrapped), the
    /// heading's 1σ `heading_sigma_rad` or else the noise model's.
    pub fn update_length_heading(
        &mut self,
        measured_length_m: f64,
        measured_heading_rad: f64,
        heading_sigma_rad: Option<f64>,
    ) {
        let innovation = [
            measured_length_m - self.x[2],
            wrap_to_pi(measured_heading_rad - self.x[3]),
        ];
        let heading_sigma_rad = heading_sigma_rad
            .filter(|sigma| sigma.is_finite() && *sigma > 0.0)
            .unwrap_or(self.noise.heading_measurement_rad);
        let r = [
            self.noise.step_length_measurement_m.powi(2),
            heading_sigma_rad.powi(2),
        ];
        self.update_pair(2, innovation, r);
        self.x[3] = wrap_to_2pi(self.x[3]);
    }

    /// The normalised innovation squared a position fix would have, without using it.
    pub fn position_nis(&self, position_en_m: [f64; 2], sigma_m: f64) -> f64 {
        let dy = [position_en_m[0] - self.x[0], position_en_m[1] - self.x[1]];
        let var = sigma_m * sigma_m;
        let s = [
            [self.p[0][0] + var, self.p[0][1]],
            [self.p[1][0], self.p[1][1] + var],
        ];
        let det = s[0][0] * s[1][1] - s[0][1] * s[1][0];
        (dy[0] * (s[1][1] * dy[0] - s[0][1] * dy[1]) + dy[1] * (s[0][0] * dy[1] - s[1][0] * dy[0]))
            / det
    }

    /// A loosely coupled GNSS update with `z = [E, N]` and `R = σ²·I`.
    pub fn update_position(&mut self, position_en_m: [f64; 2], sigma_m: f64) -> PositionInnovation {
        let nis = self.position_nis(position_en_m, sigma_m);
        let innovation = [position_en_m[0] - self.x[0], position_en_m[1] - self.x[1]];
        self.update_pair(0, innovation, [sigma_m * sigma_m; 2]);
        self.x[3] = wrap_to_2pi(self.x[3]);
        PositionInnovation {
            east_m: innovation[0],
            north_m: innovation[1],
            nis,
        }
    }

    /// Widens the position uncertainty to `sigma_m` (a reset when fixes disagree with the
    /// dead-reckoned position for too long: the filter then trusts the next fix).
    pub fn widen_position(&mut self, sigma_m: f64) {
        let var = sigma_m * sigma_m;
        for row in 0..2 {
            for col in 0..4 {
                if row != col {
                    self.p[row][col] = 0.0;
                    self.p[col][row] = 0.0;
                }
            }
            self.p[row][row] = self.p[row][row].max(var);
        }
    }

    /// The Kalman update for a measurement of the two states `first`, `first + 1` with
    /// diagonal noise `r`: `K = P·Hᵀ·S⁻¹`, `x ← x + K·y`, `P ← P − K·S·Kᵀ` (symmetrised).
    fn update_pair(&mut self, first: usize, innovation: [f64; 2], r: [f64; 2]) {
        let (i, j) = (first, first + 1);
        let p = &self.p;
        let s = [[p[i][i] + r[0], p[i][j]], [p[j][i], p[j][j] + r[1]]];
        let det = s[0][0] * s[1][1] - s[0][1] * s[1][0];
        if !(det.is_finite() && det > 0.0) {
            return;
        }
        let s_inv = [
            [s[1][1] / det, -s[0][1] / det],
            [-s[1][0] / det, s[0][0] / det],
        ];
        // K (4×2) = P[:, i..=j] · S⁻¹.
        let mut k = [[0.0; 2]; 4];
        for (row, k_row) in k.iter_mut().enumerate() {
            let (pi, pj) = (p[row][i], p[row][j]);
            k_row[0] = pi * s_inv[0][0] + pj * s_inv[1][0];
            k_row[1] = pi * s_inv[0][1] + pj * s_inv[1][1];
        }
        for (row, k_row) in k.iter().enumerate() {
            self.x[row] += k_row[0] * innovation[0] + k_row[1] * innovation[1];
        }
        // P ← P − K·(P[i..=j, :]) (= P − K·S·Kᵀ), then symmetrised.
        let rows = [self.p[i], self.p[j]];
        for (p_row, k_row) in self.p.iter_mut().zip(&k) {
            for ((p, first), second) in p_row.iter_mut().zip(&rows[0]).zip(&rows[1]) {
                *p -= k_row[0] * first + k_row[1] * second;
            }
        }
        for row in 0..4 {
            for col in row + 1..4 {
                let mean = 0.5 * (self.p[row][col] + self.p[col][row]);
                self.p[row][col] = mean;
                self.p[col][row] = mean;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix2, Matrix2x4, Matrix4, Vector2, Vector4};

    fn dense(p: &[[f64; 4]; 4]) -> Matrix4<f64> {
        Matrix4::from_fn(|r, c| p[r][c])
    }

    #[test]
    fn predict_matches_the_dense_jacobian_form() {
        let noise = EkfNoise::default();
        let mut ekf = PdrEkf::new([3.0, -2.0], 2.0, 0.72, 1.1, noise);
        ekf.p[0][2] = 0.001;
        ekf.p[2][0] = 0.001;
        ekf.p[1][3] = -0.002;
        ekf.p[3][1] = -0.002;
        let before = ekf;
        ekf.predict();
        let [_, _, l, a] = before.x;
        let f = Matrix4::new(
            1.0,
            0.0,
            a.sin(),
            l * a.cos(),
            0.0,
            1.0,
            a.cos(),
            -l * a.sin(),
            0.0,
            0.0,
            1.0,
            0.0,
            0.0,
            0.0,
            0.0,
            1.0,
        );
        let q = Matrix4::from_diagonal(&Vector4::new(
            0.0,
            0.0,
            noise.step_length_walk_m.powi(2),
            noise.heading_walk_rad.powi(2),
        ));
        let expected = f * dense(&before.p) * f.transpose() + q;
        assert!(
            (dense(&ekf.p) - expected).abs().max() < 1e-15,
            "{}",
            dense(&ekf.p) - expected
        );
        assert!((ekf.x[0] - (3.0 + l * a.sin())).abs() < 1e-15);
        assert!((ekf.x[1] - (-2.0 + l * a.cos())).abs() < 1e-15);
    }

    #[test]
    fn updates_match_the_dense_kalman_form() {
        let mut ekf = PdrEkf::new([0.0, 0.0], 3.0, 0.7, 0.2, EkfNoise::default());
        for _ in 0..5 {
            ekf.step(0.7, 0.25, None);
        }
        let before = ekf;
        let z = [4.0, 1.0];
        ekf.update_position(z, 2.5);
        let h = Matrix2x4::new(1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0);
        let p = dense(&before.p);
        let s = h * p * h.transpose() + Matrix2::identity() * 6.25;
        let k = p * h.transpose() * s.try_inverse().expect("invertible");
        let x = Vector4::from(before.x) + k * (Vector2::from(z) - h * Vector4::from(before.x));
        let p_next = (Matrix4::identity() - k * h) * p;
        assert!((Vector4::from(ekf.x) - x).abs().max() < 1e-12);
        assert!((dense(&ekf.p) - p_next).abs().max() < 1e-12);
    }

    #[test]
    fn the_heading_innovation_is_wrapped() {
        let mut ekf = PdrEkf::new(
            [0.0, 0.0],
            1.0,
            0.7,
            359f64.to_radians(),
            EkfNoise::default(),
        );
        ekf.update_length_heading(0.7, 1f64.to_radians(), None);
        // Pulled towards 1° through north, not back through 180°.
        let heading_deg = ekf.x[3].to_degrees();
        assert!(!(10.0..350.0).contains(&heading_deg), "{heading_deg}");
    }

    #[test]
    fn a_stated_heading_sigma_weighs_the_heading_and_a_missing_one_falls_back() {
        let noise = EkfNoise::default();
        let updated = |sigma: Option<f64>| {
            let mut ekf = PdrEkf::new([0.0, 0.0], 1.0, 0.7, 0.0, noise);
            ekf.update_length_heading(0.7, 10f64.to_radians(), sigma);
            (ekf.x[3].to_degrees(), ekf.p[3][3].sqrt().to_degrees())
        };
        // The prior's 1σ is the noise model's (5°): an equal σ meets it halfway, a
        // tenfold smaller one is nearly all of the answer.
        let (halfway_deg, halfway_sigma_deg) = updated(Some(noise.heading_measurement_rad));
        assert!((halfway_deg - 5.0).abs() < 1e-9, "{halfway_deg}");
        assert!((halfway_sigma_deg - 5.0 / 2f64.sqrt()).abs() < 1e-9);
        let (tight_deg, tight_sigma_deg) = updated(Some(0.5f64.to_radians()));
        assert!(
            (tight_deg - 10.0 * 25.0 / 25.25).abs() < 1e-9,
            "{tight_deg}"
        );
        assert!(tight_sigma_deg < 0.5);
        // None, NaN and zero use the noise model's.
        for sigma in [None, Some(f64::NAN), Some(0.0)] {
            assert_eq!(
                updated(sigma),
                (halfway_deg, halfway_sigma_deg),
                "{sigma:?}"
            );
        }
    }

    #[test]
    fn straight_steps_walk_straight_and_fixes_pull_back() {
        let mut ekf = PdrEkf::new([0.0, 0.0], 0.1, 0.7, 0.0, EkfNoise::default());
        for _ in 0..100 {
            ekf.step(0.7, 0.0, None);
        }
        assert!(ekf.x[0].abs() < 1e-9);
        assert!((ekf.x[1] - 70.0).abs() < 1e-6, "{:?}", ekf.x);
        let nis = ekf.position_nis([0.0, 60.0], 3.0);
        let innovation = ekf.update_position([0.0, 60.0], 3.0);
        assert!((innovation.nis - nis).abs() < 1e-12 && nis > 1.0);
        assert!(ekf.x[1] < 70.0 && ekf.x[1] > 60.0, "{:?}", ekf.x);
    }
}
