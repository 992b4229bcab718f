//! Training samples, checked once: row-major inputs and targets of fixed widths, the same
//! number of rows, every value finite. Code after [`Dataset::new`] trusts them.

use std::fmt;

use super::error::NnError;

/// Which side of a sample a value belongs to, for error messages.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DataPart {
    Input,
    Target,
}

impl fmt::Display for DataPart {
    fn fmt(&self, formatter: &mut fmt::Formatter<'_>) -> fmt::Result {
        formatter.write_str(match self {
            DataPart::Input => "input",
            DataPart::Target => "target",
        })
    }
}

/// Samples for training or scoring a network: `n_samples` rows of `n_inputs` inputs and
/// `n_outputs` targets, row-major, all finite.
#[derive(Debug, Clone, PartialEq)]
pub struct Dataset {
    n_inputs: usize,
    n_outputs: usize,
    inputs: Vec<f64>,
    targets: Vec<f64>,
}

impl Dataset {
    /// Checks and copies row-major `inputs` (`n_inputs` per row) and `targets`
    /// (`n_outputs` per row). A non-finite value is reported with its row and column.
    pub fn new(
        inputs: &[f64],
        n_inputs: usize,
        targets: &[f64],
        n_outputs: usize,
    ) -> Result<Self, NnError> {
        let n_input_rows = rows_of(inputs, n_inputs, DataPart::Input)?;
        let n_target_rows = rows_of(targets, n_outputs, DataPart::Target)?;
        if n_input_rows != n_target_rows {
            return Err(NnError::RowCountMismatch {
                n_input_rows,
                n_target_rows,
            });
        }
        check_finite(inputs, n_inputs, DataPart::Input)?;
        check_finite(targets, n_outputs, DataPart::Target)?;
        Ok(Dataset {
            n_inputs,
            n_outputs,
            inputs: inputs.to_vec(),
            targets: targets.to_vec(),
        })
    }

    pub fn n_samples(&self) -> usize {
        self.inputs.len() / self.n_inputs
    }

    pub fn n_inputs(&self) -> usize {
        self.n_inputs
    }

    pub fn n_outputs(&self) -> usize {
        self.n_outputs
    }

    /// All inputs, row-major.
    pub fn inputs(&self) -> &[f64] {
        &self.inputs
    }

    /// All targets, row-major.
    pub fn targets(&self) -> &[f64] {
        &self.targets
    }

    /// The samples at `indices` (in that order), as a new set. Indices come from the
    /// caller's own shuffling of `0..n_samples`, so each is in range.
    pub(crate) fn select(&self, indices: &[usize]) -> Dataset {
        let mut inputs = Vec::with_capacity(indices.len() * self.n_inputs);
        let mut targets = Vec::with_capacity(indices.len() * self.n_outputs);
        for &row in indices {
            inputs.extend_from_slice(&self.inputs[row * self.n_inputs..][..self.n_inputs]);
            targets.extend_from_slice(&self.targets[row * self.n_outputs..][..self.n_outputs]);
        }
        Dataset {
            n_inputs: self.n_inputs,
            n_outputs: self.n_outputs,
            inputs,
            targets,
        }
    }
}

/// The number of rows of `width` values in `values`, or why they do not make rows.
pub(super) fn rows_of(values: &[f64], width: usize, part: DataPart) -> Result<usize, NnError> {
    if width == 0 {
        return Err(NnError::NoColumns { part });
    }
    if !values.len().is_multiple_of(width) {
        return Err(NnError::RaggedRows {
            part,
            n_values: values.len(),
            width,
        });
    }
    Ok(values.len() / width)
}

/// The first value that is not finite, by row and column, as an error.
pub(super) fn check_finite(values: &[f64], width: usize, part: DataPart) -> Result<(), NnError> {
    match values.iter().position(|value| !value.is_finite()) {
        None => Ok(()),
        Some(idx) => Err(NnError::NonFinite {
            part,
            row: idx / width,
            column: idx % width,
            value: values[idx],
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_non_finite_value_is_named_by_row_and_column() {
        let inputs = [1.0, 2.0, 3.0, f64::NAN, 5.0, 6.0];
        let error = Dataset::new(&inputs, 2, &[0.0, 1.0, 2.0], 1).unwrap_err();
        assert!(
            matches!(
                error,
                NnError::NonFinite {
                    part: DataPart::Input,
                    row: 1,
                    column: 1,
                    ..
                }
            ),
            "{error:?}"
        );
        let error = Dataset::new(&[1.0, 2.0], 1, &[0.0, f64::INFINITY], 1).unwrap_err();
        assert!(
            matches!(
                error,
                NnError::NonFinite {
                    part: DataPart::Target,
                    row: 1,
                    column: 0,
                    ..
                }
            ),
            "{error:?}"
        );
    }

    #[test]
    fn shapes_are_checked() {
        assert_eq!(
            Dataset::new(&[1.0, 2.0, 3.0], 2, &[0.0], 1),
            Err(NnError::RaggedRows {
                part: DataPart::Input,
                n_values: 3,
                width: 2
            })
        );
        assert_eq!(
            Dataset::new(&[1.0, 2.0], 1, &[0.0], 1),
            Err(NnError::RowCountMismatch {
                n_input_rows: 2,
                n_target_rows: 1
            })
        );
        assert_eq!(
            Dataset::new(&[], 0, &[], 1),
            Err(NnError::NoColumns {
                part: DataPart::Input
            })
        );
    }
}
