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

/// Fields a line keeps on the stack ([`with_fields`]); the logs' longest lines have 11.
const FIELDS_ON_STACK: usize = 24;

/// `read` on `text` split on `separator`, its fields trimmed and empty trailing ones
/// dropped (a line may end with the separator). The fields are gathered on the stack,
/// in a vector only past [`FIELDS_ON_STACK`]: a vector per line cost an allocation and a
/// free for each of a log's tens of thousands of lines, which in the page's
/// WebAssembly are calls into its allocator.
pub(super) fn with_fields<'a, R>(
    text: &'a str,
    separator: char,
    read: impl FnOnce(&[&'a str]) -> R,
) -> R {
    let mut on_stack = [""; FIELDS_ON_STACK];
    let mut n_on_stack = 0;
    let mut spilled: Option<Vec<&'a str>> = None;
    for field in text.split(separator).map(str::trim) {
        match &mut spilled {
            Some(fields) => fields.push(field),
            None if n_on_stack < FIELDS_ON_STACK => {
                on_stack[n_on_stack] = field;
                n_on_stack += 1;
            }
            None => {
                let mut fields = on_stack.to_vec();
                fields.push(field);
                spilled = Some(fields);
            }
        }
    }
    let mut fields: &[&str] = spilled.as_deref().unwrap_or(&on_stack[..n_on_stack]);
    while let Some((last, rest)) = fields.split_last() {
        if !last.is_empty() {
            break;
        }
        fields = rest;
    }
    read(fields)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_are_trimmed_and_empty_trailing_ones_dropped_on_the_stack_or_past_it() {
        let owned = |text: &str| with_fields(text, ';', |fields| fields.join("|"));
        assert_eq!(owned("ACCE; 1.5 ;2;;x;;"), "ACCE|1.5|2||x");
        assert_eq!(owned(";;"), "");
        assert_eq!(owned(""), "");
        let long: Vec<String> = (0..FIELDS_ON_STACK + 5).map(|i| i.to_string()).collect();
        let line = format!("{};;", long.join(";"));
        assert_eq!(
            with_fields(&line, ';', <[&str]>::to_vec),
            long.iter().map(String::as_str).collect::<Vec<_>>()
        );
    }
}
