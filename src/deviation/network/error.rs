//! What can go wrong when a network is trained or used, with what the user can do.

use super::dataset::DataPart;

/// Errors of [`super::train`], [`super::Dataset::new`] and [`super::Mlp::predict`]. Bad data
/// never panics; it comes back as one of these.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum NnError {
    #[error(
        "{n_samples} samples are too few to train a network: give at least {min} (more when part is held out for validation)."
    )]
    TooFewSamples { n_samples: usize, min: usize },
    #[error(
        "the {part} value at row {row}, column {column} is {value}: every value must be a finite number; remove or repair that row."
    )]
    NonFinite {
        part: DataPart,
        row: usize,
        column: usize,
        value: f64,
    },
    #[error(
        "the {part} values hold {n_values} numbers, which is not a whole number of rows of {width}: give {width} numbers per sample."
    )]
    RaggedRows {
        part: DataPart,
        n_values: usize,
        width: usize,
    },
    #[error(
        "{n_input_rows} input rows but {n_target_rows} target rows: give one target row per input row."
    )]
    RowCountMismatch {
        n_input_rows: usize,
        n_target_rows: usize,
    },
    #[error("a network needs at least one {part} column.")]
    NoColumns { part: DataPart },
    #[error("the hidden layer has no neurons: choose a hidden size such as 10 to 16.")]
    HiddenSizeZero,
    #[error("the model takes {expected} {part} values, {found} were given.")]
    WrongWidth {
        part: DataPart,
        expected: usize,
        found: usize,
    },
    #[error("the training option {name} is {value}: {what_to_do}")]
    InvalidOption {
        name: &'static str,
        value: f64,
        what_to_do: &'static str,
    },
    #[error(
        "the saved model is inconsistent ({reason}): train it again or restore an intact copy."
    )]
    InconsistentModel { reason: String },
}
