//! Standardisation of each column: the mean removed and the result divided by the
//! standard deviation (Noureldin et al. 2007, Section 5: "normalized to the same
//! numerical range with the mean removed"), so that inputs of different physical nature
//! (degrees, µT, °C) reach the hidden layer on one scale.
//!
//! A column that does not vary (its standard deviation is below 10⁻¹² of its size) keeps
//! a scale of 1: it becomes a column of zeros instead of NaN.

/// Per-column mean and scale; `normalised = (raw − mean) / scale`.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Standardiser {
    mean: Vec<f64>,
    scale: Vec<f64>,
}

impl Standardiser {
    /// The mean and population standard deviation of each of the `width` columns of the
    /// row-major `values` (two passes, so a large mean costs no precision). With no rows,
    /// every mean is 0 and every scale 1.
    pub fn fit(values: &[f64], width: usize) -> Self {
        let n_rows = values.len().checked_div(width).unwrap_or(0);
        let mut mean = vec![0.0; width];
        let mut scale = vec![1.0; width];
        if n_rows == 0 {
            return Standardiser { mean, scale };
        }
        for row in values.chunks_exact(width) {
            for (sum, value) in mean.iter_mut().zip(row) {
                *sum += value;
            }
        }
        for sum in &mut mean {
            *sum /= n_rows as f64;
        }
        let mut sum_of_squares = vec![0.0; width];
        for row in values.chunks_exact(width) {
            for ((sum, value), column_mean) in sum_of_squares.iter_mut().zip(row).zip(&mean) {
                *sum += (value - column_mean) * (value - column_mean);
            }
        }
        for ((column_scale, sum), column_mean) in scale.iter_mut().zip(&sum_of_squares).zip(&mean) {
            let std = (sum / n_rows as f64).sqrt();
            if std.is_finite() && std > 1e-12 * column_mean.abs().max(1e-300) {
                *column_scale = std;
            }
        }
        Standardiser { mean, scale }
    }

    /// A standardiser from its parts; `None` unless both have the same length and every
    /// scale is finite and positive and every mean finite.
    pub fn from_parts(mean: Vec<f64>, scale: Vec<f64>) -> Option<Self> {
        let valid = mean.len() == scale.len()
            && mean.iter().all(|value| value.is_finite())
            && scale.iter().all(|value| value.is_finite() && *value > 0.0);
        valid.then_some(Standardiser { mean, scale })
    }

    pub fn width(&self) -> usize {
        self.mean.len()
    }

    pub fn mean(&self) -> &[f64] {
        &self.mean
    }

    pub fn scale(&self) -> &[f64] {
        &self.scale
    }

    /// `(raw − mean) / scale` of column `column`.
    pub(crate) fn normalise(&self, column: usize, raw: f64) -> f64 {
        (raw - self.mean[column]) / self.scale[column]
    }

    /// `normalised · scale + mean` of column `column`.
    pub(crate) fn denormalise(&self, column: usize, normalised: f64) -> f64 {
        normalised * self.scale[column] + self.mean[column]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn columns_get_zero_mean_and_unit_deviation() {
        let values = [1.0, 100.0, 3.0, 300.0, 5.0, 200.0];
        let standardiser = Standardiser::fit(&values, 2);
        assert_eq!(standardiser.mean(), &[3.0, 200.0]);
        let normalised: Vec<f64> = values
            .chunks_exact(2)
            .map(|row| standardiser.normalise(0, row[0]))
            .collect();
        let variance = normalised.iter().map(|value| value * value).sum::<f64>() / 3.0;
        assert!((variance - 1.0).abs() < 1e-12);
        assert!(
            (standardiser.denormalise(1, standardiser.normalise(1, 250.0)) - 250.0).abs() < 1e-12
        );
    }

    #[test]
    fn a_constant_column_becomes_zeros_not_nan() {
        let values = [7.5, 1.0, 7.5, 2.0, 7.5, 3.0];
        let standardiser = Standardiser::fit(&values, 2);
        assert_eq!(standardiser.scale()[0], 1.0);
        assert_eq!(standardiser.normalise(0, 7.5), 0.0);
        let empty = Standardiser::fit(&[], 3);
        assert_eq!(empty.scale(), &[1.0, 1.0, 1.0]);
        assert!(Standardiser::from_parts(vec![0.0], vec![0.0]).is_none());
    }
}
