//! Min/max autocalibration of the levelled horizontal field.
//!
//! Source: Moafipoor et al. (2007), Eq. 6-7, after Caruso (1997). The method:
//!
//! 1. level the field with roll and pitch (Eq. 4, [`crate::attitude::tilt`]);
//! 2. take the extremes of the levelled components over a full turn and estimate, per
//!    axis, a scale factor and a bias (Eq. 7):
//!    ```text
//!    Sx = max(1, (Hy_max − Hy_min) / (Hx_max − Hx_min))
//!    Sy = max(1, (Hx_max − Hx_min) / (Hy_max − Hy_min))
//!    Bx = ((Hx_max − Hx_min)/2 − Hx_max) · Sx
//!    By = ((Hy_max − Hy_min)/2 − Hy_max) · Sy
//!    ```
//! 3. correct each sample with `H' = S·H + B` (Eq. 6), which moves the centre of the
//!    ellipse to the origin and stretches its shorter axis to the longer one;
//! 4. compute the heading from the corrected components (Eq. 1, [`crate::attitude::compass_heading`]);
//! 5. add the declination.
//!
//! ## Limits
//!
//! The model is a centre and two axis scales: an ellipse whose axes lie along x and y.
//! Soft iron that couples x into y tilts the ellipse and leaves an error of a few
//! degrees that this method cannot remove. The extremes come from single samples, so one
//! spike moves them; and without a full turn the extremes are not those of the ellipse.
//! The fit reports the largest heading gap so that a partial turn is visible.

use nalgebra::Vector2;
use serde::Serialize;

use crate::base::angle::wrap_to_2pi;
use crate::fit::CalibError;

/// Fewer samples than this cannot trace a turn.
pub const MIN_SAMPLES: usize = 20;

/// A horizontal field range below this (µT) is no turn at all: Earth's horizontal
/// field is 10-40 µT, so a full turn spans 20-80 µT.
const MIN_RANGE_UT: f64 = 1.0;

/// Nor is a range (1st to 99th percentile, so that a spike does not count) under this
/// many times the sensor's noise: a board left on the bench, or one rocked by a few
/// degrees, whose extremes are its noise (a real HMC5883L left unmoved spans 1-2 µT).
/// A full turn spans 20-80 µT, against phone and board noise of 0.05-1 µT.
const MIN_RANGE_PER_NOISE: f64 = 8.0;

/// A range above this (µT) is a turn whatever the noise estimate says: the estimate
/// takes the samples' second differences for noise, which a fast turn sampled
/// sparsely (tens of degrees per sample), or samples out of time order, inflate; and
/// a turn of half a circle spans at least the horizontal field, over 10 µT wherever
/// people live. (A magnetometer this noisy when still would need σ over 2 µT.)
const MAX_NOISE_LIMITED_RANGE_UT: f64 = 10.0;

/// Width of the heading bins that coverage is counted in.
const COVERAGE_BIN_DEG: f64 = 10.0;

/// The Eq. 7 parameters, with the extremes they came from.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct MinMaxCalibration {
    pub scale_x: f64,
    pub scale_y: f64,
    pub bias_x_ut: f64,
    pub bias_y_ut: f64,
    /// Centre of the raw ellipse, `(max + min) / 2` per axis (the hard-iron estimate in
    /// the level plane).
    pub center_x_ut: f64,
    pub center_y_ut: f64,
    /// Half the range per axis: the semi-axes of the raw ellipse.
    pub semi_axis_x_ut: f64,
    pub semi_axis_y_ut: f64,
    /// How much of the circle the corrected samples cover.
    pub coverage: Coverage,
}

/// How much of a full turn the samples cover, in heading bins.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Coverage {
    pub n_bins_covered: usize,
    pub n_bins: usize,
    /// The widest arc of magnetic heading with no sample, and where it starts.
    pub largest_gap_deg: f64,
    pub largest_gap_start_deg: f64,
}

impl MinMaxCalibration {
    /// Fits Eq. 7 to levelled field samples (µT).
    pub fn fit(level_ut: &[Vector2<f64>]) -> Result<Self, CalibError> {
        if level_ut.len() < MIN_SAMPLES {
            return Err(CalibError::TooFewSamples {
                n_samples: level_ut.len(),
                min: MIN_SAMPLES,
            });
        }
        if let Some(sample_idx) = level_ut
            .iter()
            .position(|sample| !(sample.x.is_finite() && sample.y.is_finite()))
        {
            return Err(CalibError::NonFinite { sample_idx });
        }
        let (mut min, mut max) = (
            Vector2::repeat(f64::INFINITY),
            Vector2::repeat(f64::NEG_INFINITY),
        );
        for sample in level_ut {
            min = min.inf(sample);
            max = max.sup(sample);
        }
        let range_ut = max - min;
        for (axis, axis_range_ut) in [("x", range_ut.x), ("y", range_ut.y)] {
            if axis_range_ut < MIN_RANGE_UT {
                return Err(CalibError::NoTurn {
                    axis,
                    range_ut: axis_range_ut,
                });
            }
        }
        for (axis, component) in [("x", 0), ("y", 1)] {
            let values: Vec<f64> = level_ut.iter().map(|sample| sample[component]).collect();
            let (robust_range_ut, noise_ut) = (robust_range(&values), noise_of(&values));
            if robust_range_ut < MIN_RANGE_PER_NOISE * noise_ut
                && robust_range_ut < MAX_NOISE_LIMITED_RANGE_UT
            {
                return Err(CalibError::NoTurnAboveNoise {
                    axis,
                    range_ut: robust_range_ut,
                    noise_ut,
                    min_noise_multiple: MIN_RANGE_PER_NOISE,
                });
            }
        }
        let scale_x = (range_ut.y / range_ut.x).max(1.0);
        let scale_y = (range_ut.x / range_ut.y).max(1.0);
        let mut calibration = MinMaxCalibration {
            scale_x,
            scale_y,
            bias_x_ut: (range_ut.x / 2.0 - max.x) * scale_x,
            bias_y_ut: (range_ut.y / 2.0 - max.y) * scale_y,
            center_x_ut: (max.x + min.x) / 2.0,
            center_y_ut: (max.y + min.y) / 2.0,
            semi_axis_x_ut: range_ut.x / 2.0,
            semi_axis_y_ut: range_ut.y / 2.0,
            coverage: Coverage {
                n_bins_covered: 0,
                n_bins: 0,
                largest_gap_deg: 0.0,
                largest_gap_start_deg: 0.0,
            },
        };
        calibration.coverage = Coverage::of_headings(level_ut.iter().map(|&sample| {
            let corrected_ut = calibration.apply(sample);
            wrap_to_2pi((-corrected_ut.y).atan2(corrected_ut.x)).to_degrees()
        }));
        Ok(calibration)
    }

    /// Eq. 6: the corrected levelled components of a raw levelled sample.
    pub fn apply(&self, level_ut: Vector2<f64>) -> Vector2<f64> {
        Vector2::new(
            self.scale_x * level_ut.x + self.bias_x_ut,
            self.scale_y * level_ut.y + self.bias_y_ut,
        )
    }

    /// Radius of the corrected circle: the longer semi-axis, which Eq. 7 keeps.
    pub fn corrected_radius_ut(&self) -> f64 {
        self.semi_axis_x_ut.max(self.semi_axis_y_ut)
    }
}

impl Coverage {
    /// Coverage of a set of headings in degrees, `[0, 360)`.
    pub fn of_headings(headings_deg: impl IntoIterator<Item = f64>) -> Coverage {
        let n_bins = (360.0 / COVERAGE_BIN_DEG).round() as usize;
        let mut covered = vec![false; n_bins];
        for heading_deg in headings_deg {
            if heading_deg.is_finite() {
                let bin_idx =
                    ((heading_deg.rem_euclid(360.0) / COVERAGE_BIN_DEG) as usize).min(n_bins - 1);
                covered[bin_idx] = true;
            }
        }
        let n_bins_covered = covered.iter().filter(|&&is_covered| is_covered).count();
        // The longest run of empty bins, going round the circle (so twice over).
        let (mut largest_run, mut largest_run_start, mut run) = (0usize, 0usize, 0usize);
        for step in 0..(2 * n_bins) {
            if covered[step % n_bins] {
                run = 0;
            } else {
                run += 1;
                if run > largest_run && run <= n_bins {
                    largest_run = run;
                    largest_run_start = (step + 1 - run) % n_bins;
                }
            }
        }
        Coverage {
            n_bins_covered,
            n_bins,
            largest_gap_deg: largest_run as f64 * COVERAGE_BIN_DEG,
            largest_gap_start_deg: largest_run_start as f64 * COVERAGE_BIN_DEG,
        }
    }
}

/// The 1st to the 99th percentile of `values`.
fn robust_range(values: &[f64]) -> f64 {
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    let at = |fraction: f64| {
        let idx = ((sorted.len() - 1) as f64 * fraction).round() as usize;
        sorted.get(idx).copied().unwrap_or(0.0)
    };
    at(0.99) - at(0.01)
}

/// The white noise of a series in time order, from its second differences: a slow turn
/// hardly bends them, and for noise of standard deviation σ, `x[i+1] − 2x[i] + x[i−1]`
/// has standard deviation √6·σ and mean absolute value √6·σ·√(2/π).
fn noise_of(values: &[f64]) -> f64 {
    let second_differences = values
        .windows(3)
        .map(|window| (window[2] - 2.0 * window[1] + window[0]).abs());
    let n = values.len().saturating_sub(2).max(1) as f64;
    second_differences.sum::<f64>() / n / (6.0f64.sqrt() * (2.0 / std::f64::consts::PI).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::attitude::compass_heading::heading_rad;
    use crate::base::angle::heading_difference_rad;

    /// A level full turn seen through hard iron and axis scale factors.
    fn distorted_turn(
        n_samples: usize,
        hard_iron_ut: Vector2<f64>,
        scale: Vector2<f64>,
    ) -> Vec<(f64, Vector2<f64>)> {
        let horizontal_field_ut = 22.0;
        (0..n_samples)
            .map(|sample_idx| {
                let heading_rad = std::f64::consts::TAU * sample_idx as f64 / n_samples as f64;
                let true_level_ut = Vector2::new(
                    horizontal_field_ut * heading_rad.cos(),
                    -horizontal_field_ut * heading_rad.sin(),
                );
                (
                    heading_rad,
                    true_level_ut.component_mul(&scale) + hard_iron_ut,
                )
            })
            .collect()
    }

    #[test]
    fn hard_iron_and_axis_scale_are_removed() {
        let turn = distorted_turn(3600, Vector2::new(15.0, -30.0), Vector2::new(1.2, 0.9));
        let samples: Vec<Vector2<f64>> = turn.iter().map(|&(_, sample)| sample).collect();
        let calibration = MinMaxCalibration::fit(&samples).expect("a full turn fits");
        assert!((calibration.center_x_ut - 15.0).abs() < 1e-3);
        assert!((calibration.center_y_ut + 30.0).abs() < 1e-3);
        assert!((calibration.scale_y - 1.2 / 0.9).abs() < 1e-3);
        assert_eq!(calibration.scale_x, 1.0);
        let worst_error_deg = turn
            .iter()
            .map(|&(true_heading_rad, sample)| {
                heading_difference_rad(
                    heading_rad(calibration.apply(sample), 0.0),
                    true_heading_rad,
                )
                .abs()
                .to_degrees()
            })
            .fold(0.0, f64::max);
        assert!(
            worst_error_deg < 0.05,
            "worst heading error {worst_error_deg}°"
        );
        assert_eq!(calibration.coverage.n_bins_covered, 36);
        assert_eq!(calibration.coverage.largest_gap_deg, 0.0);
    }

    #[test]
    fn a_half_turn_shows_its_gap() {
        let turn = distorted_turn(360, Vector2::zeros(), Vector2::new(1.0, 1.0));
        let half: Vec<Vector2<f64>> = turn.iter().take(180).map(|&(_, sample)| sample).collect();
        let calibration = MinMaxCalibration::fit(&half).expect("fits, with a gap");
        // Min/max stretches a half circle, so the corrected headings spread, but the gap
        // stays wide enough to be reported.
        assert!(
            calibration.coverage.largest_gap_deg >= 60.0,
            "{:?}",
            calibration.coverage
        );
    }

    #[test]
    fn degenerate_inputs_are_errors_not_panics() {
        let point = vec![Vector2::new(3.0, 4.0); 100];
        assert!(matches!(
            MinMaxCalibration::fit(&point),
            Err(CalibError::NoTurn { axis: "x", .. })
        ));
        let line: Vec<Vector2<f64>> = (0..100).map(|idx| Vector2::new(idx as f64, 5.0)).collect();
        assert!(matches!(
            MinMaxCalibration::fit(&line),
            Err(CalibError::NoTurn { axis: "y", .. })
        ));
        assert!(matches!(
            MinMaxCalibration::fit(&point[..3]),
            Err(CalibError::TooFewSamples { n_samples: 3, .. })
        ));
        let mut with_nan = point.clone();
        with_nan[7].x = f64::NAN;
        assert!(matches!(
            MinMaxCalibration::fit(&with_nan),
            Err(CalibError::NonFinite { sample_idx: 7 })
        ));
        assert!(matches!(
            MinMaxCalibration::fit(&[]),
            Err(CalibError::TooFewSamples { .. })
        ));
    }

    /// A xorshift generator: the test's own draws, not the simulator's.
    struct Draws(u64);

    impl Draws {
        fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            lo + (hi - lo) * (self.0 >> 11) as f64 / (1u64 << 53) as f64
        }

        /// Box-Muller from two uniforms.
        fn gaussian(&mut self) -> f64 {
            let (u1, u2) = (self.uniform(1e-12, 1.0), self.uniform(0.0, 1.0));
            (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
        }
    }

    /// Random boards: a full turn at any field, hard iron, scale and noise whose turn
    /// spans at least ten times the noise is fitted, in time order or shuffled; the
    /// same board left still, or rocked by under a degree, is refused, up to a noise
    /// of 2 µT (beyond any magnetometer's when still).
    #[test]
    fn a_turn_is_told_from_noise_on_random_boards() {
        let mut draws = Draws(0x2545_f491_4f6c_dd1d);
        for _ in 0..300 {
            let field_ut = draws.uniform(8.0, 40.0);
            let noise_ut = draws.uniform(0.02, (2.0 * field_ut / 10.0).min(6.0));
            let hard_iron = Vector2::new(draws.uniform(-60.0, 60.0), draws.uniform(-60.0, 60.0));
            let scale = Vector2::new(draws.uniform(0.8, 1.25), draws.uniform(0.8, 1.25));
            let n_samples = draws.uniform(100.0, 4000.0) as usize;
            let start_rad = draws.uniform(0.0, std::f64::consts::TAU);
            let board = |turn_rad: f64, draws: &mut Draws| -> Vec<Vector2<f64>> {
                (0..n_samples)
                    .map(|idx| {
                        let heading = start_rad + turn_rad * idx as f64 / n_samples as f64;
                        let level =
                            Vector2::new(field_ut * heading.cos(), -field_ut * heading.sin());
                        let noise = Vector2::new(draws.gaussian(), draws.gaussian()) * noise_ut;
                        level.component_mul(&scale) + hard_iron + noise
                    })
                    .collect()
            };
            let mut turn = board(std::f64::consts::TAU, &mut draws);
            for shuffled in [false, true] {
                if shuffled {
                    for idx in (1..turn.len()).rev() {
                        turn.swap(idx, draws.uniform(0.0, idx as f64 + 1.0) as usize);
                    }
                }
                let fitted = MinMaxCalibration::fit(&turn);
                assert!(
                    fitted.is_ok(),
                    "a full turn of {field_ut:.1} µT with noise {noise_ut:.2} µT (shuffled: \
                     {shuffled}) was refused: {fitted:?}"
                );
            }
            if noise_ut > 2.0 {
                continue;
            }
            let rock_rad = draws.uniform(0.0, 1.0f64.to_radians());
            for still in [board(0.0, &mut draws), board(rock_rad, &mut draws)] {
                assert!(
                    matches!(
                        MinMaxCalibration::fit(&still),
                        Err(CalibError::NoTurn { .. } | CalibError::NoTurnAboveNoise { .. })
                    ),
                    "a still board with noise {noise_ut:.2} µT was fitted"
                );
            }
        }
    }
}
