//! A tagged line's fields as values ([`super`]): finite numbers and vectors with
//! messages that name the field, the field count a line should have, and Android's
//! rotation vector as the unit quaternion whose vector part it is.

use nalgebra::{Quaternion, UnitQuaternion, Vector3};
use thiserror::Error;

use crate::io::shorten;

/// Why a tagged line's field, or its field count, is not usable; the message names the
/// field and says what it holds.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum TaggedFieldError {
    /// The line ends before the field.
    #[error("{name} is missing")]
    Missing { name: String },
    /// The field is a number, but NaN or infinite.
    #[error("{name} is {text}")]
    NotFinite { name: String, text: String },
    #[error("{name} is not a number ({})", shorten(.text))]
    NotANumber { name: String, text: String },
    /// The line has `found` values (or fields), outside `min..=max`; `layout` shows
    /// what it should hold.
    #[error("{} {what} expected ({layout}), found {found}", expected_count(*.min, *.max))]
    Count {
        found: usize,
        min: usize,
        max: usize,
        what: &'static str,
        layout: String,
    },
    /// A rotation vector longer than 1 (beyond the rounding slack).
    #[error(
        "the rotation vector's length is {length:.4}, more than 1, so it is not part of a unit \
         quaternion"
    )]
    RotationVectorTooLong { length: f64 },
}

/// `min..=max` as a count the user reads: "3", "3 or 4", "3 to 5".
fn expected_count(min: usize, max: usize) -> String {
    if min == max {
        format!("{min}")
    } else if max == min + 1 {
        format!("{min} or {max}")
    } else {
        format!("{min} to {max}")
    }
}

/// How far past 1 the rotation vector's length may be before it is refused: the values
/// are single-precision, so a unit quaternion's vector part can exceed 1 by rounding.
const ROTATION_VECTOR_SLACK: f64 = 1e-3;

/// The unit quaternion whose vector part is `(x, y, z)`, with w ≥ 0.
pub(super) fn quaternion_from_rotation_vector(
    x: f64,
    y: f64,
    z: f64,
) -> Result<UnitQuaternion<f64>, TaggedFieldError> {
    let norm_squared = x * x + y * y + z * z;
    if norm_squared > (1.0 + ROTATION_VECTOR_SLACK).powi(2) {
        return Err(TaggedFieldError::RotationVectorTooLong {
            length: norm_squared.sqrt(),
        });
    }
    let w = (1.0 - norm_squared).max(0.0).sqrt();
    Ok(UnitQuaternion::from_quaternion(Quaternion::new(w, x, y, z)))
}

/// One field as a finite number; `name` says which field in a message.
pub(super) fn finite(field: Option<&&str>, name: &str) -> Result<f64, TaggedFieldError> {
    let Some(field) = field else {
        return Err(TaggedFieldError::Missing {
            name: name.to_string(),
        });
    };
    match field.parse::<f64>() {
        Ok(value) if value.is_finite() => Ok(value),
        Ok(_) => Err(TaggedFieldError::NotFinite {
            name: name.to_string(),
            text: (*field).to_string(),
        }),
        Err(_) => Err(TaggedFieldError::NotANumber {
            name: name.to_string(),
            text: (*field).to_string(),
        }),
    }
}

/// Three consecutive fields, from `first`, as a vector.
pub(super) fn vector3(
    fields: &[&str],
    first: usize,
    names: [&str; 3],
) -> Result<Vector3<f64>, TaggedFieldError> {
    Ok(Vector3::new(
        finite(fields.get(first), names[0])?,
        finite(fields.get(first + 1), names[1])?,
        finite(fields.get(first + 2), names[2])?,
    ))
}

/// Refuses a field count outside `min..=max`, saying what the line should hold.
pub(super) fn check_count(
    found: usize,
    min: usize,
    max: usize,
    what: &'static str,
    layout: &str,
) -> Result<(), TaggedFieldError> {
    if (min..=max).contains(&found) {
        return Ok(());
    }
    Err(TaggedFieldError::Count {
        found,
        min,
        max,
        what,
        layout: layout.to_string(),
    })
}

/// Splits on `separator`, trimming fields and dropping empty trailing ones (a line may
/// end with the separator).
pub(super) fn split_fields(text: &str, separator: char) -> Vec<&str> {
    let mut fields: Vec<&str> = text.split(separator).map(str::trim).collect();
    while fields.last().is_some_and(|field| field.is_empty()) {
        fields.pop();
    }
    fields
}
