//! A tagged line's fields as values ([`super`]): finite numbers and vectors with
//! messages that name the field, the field count a line should have, and Android's
//! rotation vector as the unit quaternion whose vector part it is.

use nalgebra::{Quaternion, UnitQuaternion, Vector3};

use crate::io::shorten;

/// How far past 1 the rotation vector's length may be before it is refused: the values
/// are single-precision, so a unit quaternion's vector part can exceed 1 by rounding.
const ROTATION_VECTOR_SLACK: f64 = 1e-3;

/// The unit quaternion whose vector part is `(x, y, z)`, with w ≥ 0.
pub(super) fn quaternion_from_rotation_vector(
    x: f64,
    y: f64,
    z: f64,
) -> Result<UnitQuaternion<f64>, String> {
    let norm_squared = x * x + y * y + z * z;
    if norm_squared > (1.0 + ROTATION_VECTOR_SLACK).powi(2) {
        return Err(format!(
            "the rotation vector's length is {:.4}, more than 1, so it is not part of a unit \
             quaternion",
            norm_squared.sqrt()
        ));
    }
    let w = (1.0 - norm_squared).max(0.0).sqrt();
    Ok(UnitQuaternion::from_quaternion(Quaternion::new(w, x, y, z)))
}

/// One field as a finite number; `name` says which field in a message.
pub(super) fn finite(field: Option<&&str>, name: &str) -> Result<f64, String> {
    let Some(field) = field else {
        return Err(format!("{name} is missing"));
    };
    match field.parse::<f64>() {
        Ok(value) if value.is_finite() => Ok(value),
        Ok(_) => Err(format!("{name} is {field}")),
        Err(_) => Err(format!("{name} is not a number ({})", shorten(field))),
    }
}

/// Three consecutive fields, from `first`, as a vector.
pub(super) fn vector3(
    fields: &[&str],
    first: usize,
    names: [&str; 3],
) -> Result<Vector3<f64>, String> {
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
    what: &str,
    layout: &str,
) -> Result<(), String> {
    if (min..=max).contains(&found) {
        return Ok(());
    }
    let expected = if min == max {
        format!("{min}")
    } else if max == min + 1 {
        format!("{min} or {max}")
    } else {
        format!("{min} to {max}")
    };
    Err(format!(
        "{expected} {what} expected ({layout}), found {found}"
    ))
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
