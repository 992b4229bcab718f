//! The Pearson correlation matrix of a network's inputs, for the report (Noureldin et
//! al. 2007, Table 1: strongly correlated inputs suggest a subset may be enough).
//!
//! `r_ij = Σ (xᵢ − x̄ᵢ)(xⱼ − x̄ⱼ) / √(Σ (xᵢ − x̄ᵢ)² · Σ (xⱼ − x̄ⱼ)²)`, computed with the
//! means removed first (two passes). A column that does not vary has no correlation:
//! its entries are `None`, not NaN.

use super::dataset::{check_finite, rows_of, DataPart};
use super::error::NnError;

/// A symmetric matrix of correlation coefficients in [−1, 1], row-major.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CorrelationMatrix {
    pub n_columns: usize,
    /// `coefficients[i·n_columns + j]`; `None` where column i or j is constant.
    pub coefficients: Vec<Option<f64>>,
}

impl CorrelationMatrix {
    /// The coefficient of columns `i` and `j`; `None` when either is constant or out of
    /// range.
    pub fn get(&self, i: usize, j: usize) -> Option<f64> {
        if i >= self.n_columns || j >= self.n_columns {
            return None;
        }
        self.coefficients
            .get(i * self.n_columns + j)
            .copied()
            .flatten()
    }
}

/// The correlation of the `width` columns of the row-major `rows` (at least two rows,
/// every value finite).
pub fn correlation_matrix(rows: &[f64], width: usize) -> Result<CorrelationMatrix, NnError> {
    let n_rows = rows_of(rows, width, DataPart::Input)?;
    if n_rows < 2 {
        return Err(NnError::TooFewSamples {
            n_samples: n_rows,
            min: 2,
        });
    }
    check_finite(rows, width, DataPart::Input)?;
    let mut mean = vec![0.0; width];
    for row in rows.chunks_exact(width) {
        for (sum, value) in mean.iter_mut().zip(row) {
            *sum += value;
        }
    }
    for sum in &mut mean {
        *sum /= n_rows as f64;
    }
    // The scatter matrix Σ (x − x̄)(x − x̄)ᵀ.
    let mut scatter = nalgebra::DMatrix::<f64>::zeros(width, width);
    let mut centred = nalgebra::DVector::<f64>::zeros(width);
    for row in rows.chunks_exact(width) {
        for ((c, value), column_mean) in centred.iter_mut().zip(row).zip(&mean) {
            *c = value - column_mean;
        }
        scatter.ger(1.0, &centred, &centred, 1.0);
    }
    let mut coefficients = vec![None; width * width];
    for i in 0..width {
        for j in 0..width {
            let denominator = (scatter[(i, i)] * scatter[(j, j)]).sqrt();
            // A column whose spread is rounding noise of its mean counts as constant.
            let varies =
                |k: usize| scatter[(k, k)].sqrt() > 1e-12 * mean[k].abs() * (n_rows as f64).sqrt();
            if denominator > 0.0 && varies(i) && varies(j) {
                coefficients[i * width + j] =
                    Some((scatter[(i, j)] / denominator).clamp(-1.0, 1.0));
            }
        }
    }
    Ok(CorrelationMatrix {
        n_columns: width,
        coefficients,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn perfectly_related_columns_correlate_fully_and_constants_have_none() {
        // Columns: x, −2x + 1, a constant, and x² (not linear in x).
        let rows: Vec<f64> = (0..50)
            .flat_map(|k| {
                let x = f64::from(k) - 24.5;
                [x, -2.0 * x + 1.0, 3.0, x * x]
            })
            .collect();
        let matrix = correlation_matrix(&rows, 4).unwrap();
        assert!((matrix.get(0, 0).unwrap() - 1.0).abs() < 1e-12);
        assert!((matrix.get(0, 1).unwrap() + 1.0).abs() < 1e-12);
        assert_eq!(matrix.get(0, 2), None);
        assert_eq!(matrix.get(2, 2), None);
        // x is symmetric about its mean, so x and x² are (nearly) uncorrelated.
        assert!(matrix.get(0, 3).unwrap().abs() < 0.05);
        assert_eq!(matrix.get(1, 3), matrix.get(3, 1));
    }

    #[test]
    fn bad_input_is_an_error() {
        assert!(matches!(
            correlation_matrix(&[1.0, 2.0], 2),
            Err(NnError::TooFewSamples {
                n_samples: 1,
                min: 2
            })
        ));
        assert!(matches!(
            correlation_matrix(&[1.0, 2.0, f64::NAN, 4.0], 2),
            Err(NnError::NonFinite {
                row: 1,
                column: 0,
                ..
            })
        ));
    }
}
