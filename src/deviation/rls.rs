//! Online adaptation of the unified heading error model: recursive least squares with a
//! forgetting factor, refitting A to E as each reference heading arrives.
//!
//! Source: the PDR paper (`pdr-unified-heading-model.txt`, Section IV and its
//! conclusion) fits Eq. 12 once by batch least squares and names real-time training as
//! future work. Recursive least squares with exponential forgetting (Ljung and
//! Söderström, *Theory and Practice of Recursive Identification*, 1983, §2.6) gives the
//! same estimate as the batch fit with weights λ^(n−k), one update at a time:
//!
//! ```text
//! k = P·φ / (λ + φᵀ·P·φ)
//! θ ← θ + k·(δ − φᵀ·θ)
//! P ← (P − k·φᵀ·P) / λ
//! ```
//!
//! with φ = [1, sin ξ', cos ξ', sin 2ξ', cos 2ξ']. The innovation δ − φᵀθ is an angle
//! and is wrapped. A forgetting factor λ < 1 lets the model follow a slow change (a
//! phone moved to another pocket); its memory is about 1/(1 − λ) updates. The trace of
//! P is bounded so that it cannot wind up while the headings stay on one course.

use nalgebra::{Matrix5, Vector5};
use serde::Serialize;

use crate::base::angle::wrap_to_pi;
use crate::deviation::fourier::FourierDeviation;

/// P starts at this multiple of the identity (rad²): a prior of about ±30° on each
/// coefficient, which keeps the early estimates sane while the headings seen so far
/// cannot tell the terms apart.
const INITIAL_COVARIANCE: f64 = 0.25;
/// The trace of P is kept below the prior's, against wind-up while the headings stay on
/// one course (forgetting would otherwise inflate the unexcited directions).
const MAX_COVARIANCE_TRACE: f64 = 5.0 * INITIAL_COVARIANCE;

/// The recursive estimator.
#[derive(Debug, Clone, PartialEq)]
pub struct FourierRls {
    theta_rad: Vector5<f64>,
    covariance: Matrix5<f64>,
    forgetting: f64,
    n_updates: usize,
}

/// The coefficients at one moment, for the convergence plot.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RlsSnapshot {
    pub t_s: f64,
    pub model: FourierDeviation,
}

impl FourierRls {
    /// A new estimator with forgetting factor `forgetting` (0 < λ ≤ 1; 1 never forgets).
    pub fn new(forgetting: f64) -> FourierRls {
        FourierRls {
            theta_rad: Vector5::zeros(),
            covariance: Matrix5::identity() * INITIAL_COVARIANCE,
            forgetting: if forgetting > 0.0 && forgetting <= 1.0 {
                forgetting
            } else {
                1.0
            },
            n_updates: 0,
        }
    }

    /// One reference: the raw heading and the reference heading (radians). Non-finite
    /// input is ignored.
    pub fn update(&mut self, raw_heading_rad: f64, reference_rad: f64) {
        if !(raw_heading_rad.is_finite() && reference_rad.is_finite()) {
            return;
        }
        let [s1, c1, s2, c2] = crate::deviation::fourier::harmonics(raw_heading_rad);
        let phi = Vector5::new(1.0, s1, c1, s2, c2);
        let p_phi = self.covariance * phi;
        let denominator = self.forgetting + phi.dot(&p_phi);
        if !(denominator.is_finite() && denominator > 0.0) {
            return;
        }
        let gain = p_phi / denominator;
        let deviation_rad = wrap_to_pi(reference_rad - raw_heading_rad);
        let innovation_rad = wrap_to_pi(deviation_rad - phi.dot(&self.theta_rad));
        self.theta_rad += gain * innovation_rad;
        self.covariance = (self.covariance - gain * p_phi.transpose()) / self.forgetting;
        // Keep P symmetric and bounded.
        self.covariance = (self.covariance + self.covariance.transpose()) * 0.5;
        let trace = self.covariance.trace();
        if trace > MAX_COVARIANCE_TRACE {
            self.covariance *= MAX_COVARIANCE_TRACE / trace;
        }
        self.n_updates += 1;
    }

    pub fn model(&self) -> FourierDeviation {
        FourierDeviation {
            a_deg: self.theta_rad[0].to_degrees(),
            b_deg: self.theta_rad[1].to_degrees(),
            c_deg: self.theta_rad[2].to_degrees(),
            d_deg: self.theta_rad[3].to_degrees(),
            e_deg: self.theta_rad[4].to_degrees(),
        }
    }

    pub fn n_updates(&self) -> usize {
        self.n_updates
    }
}

/// Runs the estimator over time-ordered (t, raw, reference) triples and returns the
/// final model with a snapshot every `every_s` seconds.
pub fn adapt_online(
    samples: impl IntoIterator<Item = (f64, f64, f64)>,
    forgetting: f64,
    every_s: f64,
) -> (FourierDeviation, Vec<RlsSnapshot>) {
    let mut rls = FourierRls::new(forgetting);
    let mut snapshots: Vec<RlsSnapshot> = Vec::new();
    let mut last_t_s = f64::NEG_INFINITY;
    for (t_s, raw_rad, reference_rad) in samples {
        rls.update(raw_rad, reference_rad);
        if t_s - last_t_s >= every_s && rls.n_updates() > 0 {
            snapshots.push(RlsSnapshot {
                t_s,
                model: rls.model(),
            });
            last_t_s = t_s;
        }
    }
    (rls.model(), snapshots)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::base::rng::SplitMix64;

    #[test]
    fn rls_without_forgetting_converges_to_the_batch_fit() {
        let truth = FourierDeviation {
            a_deg: -6.2,
            b_deg: 26.3,
            c_deg: 0.1,
            d_deg: 2.6,
            e_deg: -4.5,
        };
        let mut rng = SplitMix64::new(9);
        let mut samples = Vec::new();
        let mut heading_rad = 0.0f64;
        for idx in 0..4000 {
            // A walker turning slowly through every heading.
            heading_rad += 0.01 + 0.02 * rng.gaussian();
            let raw_rad = crate::base::angle::wrap_to_2pi(heading_rad);
            let reference_rad =
                raw_rad + truth.deviation_rad(raw_rad) + 2f64.to_radians() * rng.gaussian();
            samples.push((idx as f64, raw_rad, reference_rad));
        }
        let (model, snapshots) = adapt_online(samples.iter().copied(), 1.0, 100.0);
        let (raw, reference): (Vec<f64>, Vec<f64>) = samples
            .iter()
            .map(|&(_, raw, reference)| (raw, reference))
            .unzip();
        let batch = super::super::fourier::fit_fourier(&raw, &reference)
            .expect("fits")
            .model;
        for (online, batch) in [
            (model.a_deg, batch.a_deg),
            (model.b_deg, batch.b_deg),
            (model.c_deg, batch.c_deg),
            (model.d_deg, batch.d_deg),
            (model.e_deg, batch.e_deg),
        ] {
            // Equal up to the prior, a ridge of 4 against sums of about 2000 (0.2 %).
            assert!((online - batch).abs() < 0.1, "{model:?} vs {batch:?}");
        }
        assert_eq!(snapshots.len(), 40);
    }

    #[test]
    fn forgetting_follows_a_change() {
        let (before, after) = (
            FourierDeviation {
                a_deg: 5.0,
                b_deg: 20.0,
                ..FourierDeviation::default()
            },
            FourierDeviation {
                a_deg: -5.0,
                b_deg: 10.0,
                ..FourierDeviation::default()
            },
        );
        let mut rls = FourierRls::new(0.995);
        for idx in 0..6000 {
            let raw_rad = (idx as f64 * 0.05) % std::f64::consts::TAU;
            let truth = if idx < 3000 { before } else { after };
            rls.update(raw_rad, raw_rad + truth.deviation_rad(raw_rad));
        }
        let model = rls.model();
        assert!(
            (model.a_deg + 5.0).abs() < 0.1 && (model.b_deg - 10.0).abs() < 0.1,
            "{model:?}"
        );
        rls.update(f64::NAN, 1.0);
        assert_eq!(rls.n_updates(), 6000);
    }
}
