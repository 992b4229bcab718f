//! The values in a sentence's fields ([`super`]): decimal numbers (read from the bytes
//! as [`crate::io::number`] reads text), whole numbers, headings and courses in degrees,
//! angles with an E/W letter, `ddmm.mmmm` coordinates with their hemisphere letter, and
//! mode letters, each as this crate's units (radians, decimal degrees) or a
//! [`SentenceError`] naming the field.
//!
//! Source: Eric S. Raymond, "NMEA Revealed" (gpsd project,
//! <https://gpsd.gitlab.io/gpsd/NMEA.html>), for the field formats.

use super::framing::field_text;
use super::SentenceError;

/// The first character of a field.
#[cfg_attr(not(target_arch = "wasm32"), inline(always))]
pub(super) fn first_char(field: &[u8]) -> Option<char> {
    match field.first() {
        Some(&byte) if byte.is_ascii() => Some(char::from(byte)),
        Some(_) => field_text(field).chars().next(),
        None => None,
    }
}

/// A decimal number as [`crate::io::number::parse_f64`] reads it, from bytes: Clinger's
/// fast path, else the standard library's parser.
#[cfg_attr(not(target_arch = "wasm32"), inline(always))]
pub(super) fn parse_f64_bytes(text: &[u8]) -> Option<f64> {
    match crate::io::number::parse_prefix(text) {
        Some((value, consumed)) if consumed == text.len() => Some(value),
        _ => std::str::from_utf8(text).ok()?.parse::<f64>().ok(),
    }
}

/// A finite decimal number, `None` for a null field.
#[cfg_attr(not(target_arch = "wasm32"), inline(always))]
pub(super) fn number(
    sentence: &'static str,
    field: &'static str,
    text: &[u8],
) -> Result<Option<f64>, SentenceError> {
    if text.is_empty() {
        return Ok(None);
    }
    match parse_f64_bytes(text) {
        Some(value) if value.is_finite() => Ok(Some(value)),
        _ => Err(SentenceError::bad_number(sentence, field, text)),
    }
}

/// A whole number as `str::parse` reads it: up to nine plain digits directly, anything
/// else (a sign, more digits) through `str::parse`.
#[cfg_attr(not(target_arch = "wasm32"), inline(always))]
pub(super) fn integer<T: std::str::FromStr + TryFrom<u32>>(
    sentence: &'static str,
    field: &'static str,
    text: &[u8],
) -> Result<Option<T>, SentenceError> {
    if text.is_empty() {
        return Ok(None);
    }
    if text.len() <= 9 && text.iter().all(u8::is_ascii_digit) {
        let value = text
            .iter()
            .fold(0u32, |value, digit| value * 10 + u32::from(digit - b'0'));
        if let Ok(value) = T::try_from(value) {
            return Ok(Some(value));
        }
    }
    std::str::from_utf8(text)
        .ok()
        .and_then(|text| text.parse::<T>().ok())
        .map(Some)
        .ok_or_else(|| SentenceError::bad_number(sentence, field, text))
}

/// A heading or course in degrees, 0 to 360, as radians in `[0, 2π)`.
#[cfg_attr(not(target_arch = "wasm32"), inline(always))]
pub(super) fn heading_rad(
    sentence: &'static str,
    field: &'static str,
    text: &[u8],
) -> Result<Option<f64>, SentenceError> {
    match number(sentence, field, text)? {
        Some(value_deg) if (0.0..=360.0).contains(&value_deg) => {
            Ok(Some(heading_0_360_rad(value_deg)))
        }
        Some(_) => Err(SentenceError::bad_value(
            sentence,
            field,
            text,
            "0 to 360 degrees",
        )),
        None => Ok(None),
    }
}

/// A heading already checked to lie in 0-360°, as radians in `[0, 2π)`. Only 360
/// itself needs wrapping, which spares the hot path the remainder in `wrap_to_2pi`.
#[cfg_attr(not(target_arch = "wasm32"), inline(always))]
pub(super) fn heading_0_360_rad(heading_deg: f64) -> f64 {
    let heading_rad = heading_deg.to_radians();
    if heading_rad >= std::f64::consts::TAU {
        0.0
    } else {
        heading_rad
    }
}

/// An angle with an E/W letter, east positive. A value without its letter is dropped
/// rather than guessed, and does not cost the rest of the sentence.
#[cfg_attr(not(target_arch = "wasm32"), inline(always))]
pub(super) fn east_positive_rad(
    sentence: &'static str,
    field: &'static str,
    value: &[u8],
    direction: &[u8],
) -> Result<Option<f64>, SentenceError> {
    let Some(value_deg) = number(sentence, field, value)? else {
        return Ok(None);
    };
    match direction {
        b"E" => Ok(Some(value_deg.to_radians())),
        b"W" => Ok(Some(-value_deg.to_radians())),
        b"" => Ok(None),
        other => Err(SentenceError::bad_value(sentence, field, other, "E or W")),
    }
}

#[derive(Clone, Copy)]
pub(super) enum Axis {
    Latitude,
    Longitude,
}

/// `ddmm.mmmm` (latitude) or `dddmm.mmmm` (longitude) and its hemisphere letter, as
/// decimal degrees, south and west negative.
#[cfg_attr(not(target_arch = "wasm32"), inline(always))]
pub(super) fn coordinate(
    sentence: &'static str,
    axis: Axis,
    value: &[u8],
    hemisphere: &[u8],
) -> Result<Option<f64>, SentenceError> {
    let (field, hemisphere_field, max_deg, positive, negative, expected_letters, expected_value) =
        match axis {
            Axis::Latitude => (
                "latitude",
                "latitude hemisphere",
                90.0,
                b"N",
                b"S",
                "N or S",
                "ddmm.mmmm, at most 90°",
            ),
            Axis::Longitude => (
                "longitude",
                "longitude hemisphere",
                180.0,
                b"E",
                b"W",
                "E or W",
                "dddmm.mmmm, at most 180°",
            ),
        };
    match (value.is_empty(), hemisphere.is_empty()) {
        (true, true) => return Ok(None),
        (true, false) => return Err(SentenceError::MissingField { sentence, field }),
        (false, true) => {
            return Err(SentenceError::MissingField {
                sentence,
                field: hemisphere_field,
            })
        }
        (false, false) => {}
    }
    let Some(ddmm) = number(sentence, field, value)? else {
        return Ok(None);
    };
    // Truncation through an integer where that is exact (`f64::trunc` is a library
    // call on baseline x86-64); negative or huge values are refused below either way.
    let degrees = if (0.0..1e15).contains(&ddmm) {
        ((ddmm / 100.0) as u64) as f64
    } else {
        (ddmm / 100.0).trunc()
    };
    let minutes = ddmm - degrees * 100.0;
    let decimal_deg = degrees + minutes / 60.0;
    if !(ddmm >= 0.0 && minutes < 60.0 && decimal_deg <= max_deg) {
        return Err(SentenceError::bad_value(
            sentence,
            field,
            value,
            expected_value,
        ));
    }
    if hemisphere == positive {
        Ok(Some(decimal_deg))
    } else if hemisphere == negative {
        Ok(Some(-decimal_deg))
    } else {
        Err(SentenceError::bad_value(
            sentence,
            hemisphere_field,
            hemisphere,
            expected_letters,
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::lcg;
    use super::*;

    #[test]
    fn numbers_from_bytes_read_as_from_text() {
        let mut texts: Vec<String> = [
            "12345678901234567890123",
            "0",
            "-0",
            "5",
            "5.",
            ".5",
            "-.5",
            ".",
            "-",
            "",
            "1.2.3",
            "12a",
            "+5",
            "1e3",
            "4808.22924",
            "01134.56746",
            "00.00",
            "99999999",
            "123456789",
            "1234567890123456",
            "12345678901234567",
            "1234567890123456789",
            "12345678901234567890",
            "9007199254740993",
            "9007199254740992",
            "0.1234567890123456",
            "-84.00",
            "0.00000000000000001",
            "1 2",
            " 1",
            "1 ",
        ]
        .iter()
        .map(std::string::ToString::to_string)
        .collect();
        let mut state = 11u64;
        for _ in 0..20_000 {
            state = lcg(state);
            let n_integer = (state >> 33) as usize % 12;
            state = lcg(state);
            let n_fraction = (state >> 33) as usize % 12;
            let mut text = String::new();
            if state.is_multiple_of(3) {
                text.push('-');
            }
            for _ in 0..n_integer {
                state = lcg(state);
                text.push(char::from(b'0' + (state >> 40) as u8 % 10));
            }
            if n_fraction > 0 || state.is_multiple_of(5) {
                text.push('.');
            }
            for _ in 0..n_fraction {
                state = lcg(state);
                text.push(char::from(b'0' + (state >> 40) as u8 % 10));
            }
            texts.push(text);
        }
        for text in &texts {
            let general = crate::io::number::parse_f64(text).map(f64::to_bits);
            assert_eq!(
                parse_f64_bytes(text.as_bytes()).map(f64::to_bits),
                general,
                "{text:?}"
            );
        }
    }
}
