//! DataFlash `FMT` definitions and the decoding of one field.
//!
//! Every message type a log uses is described by a `FMT` message before its first
//! message: type id, length (with the 3-byte header), name, one format character per
//! field and the field names. The characters and their sizes are ArduPilot's
//! `libraries/AP_Logger/LogStructure.h`; the scale factors of `c`, `C`, `e`, `E` (×0.01)
//! and `L` (×1e-7, degrees) are those pymavlink's `DFReader.py` applies.

/// The type id and length of `FMT` itself, fixed so that it can be read before any `FMT`.
pub const FMT_TYPE: u8 = 128;
pub const FMT_LENGTH: usize = 89;
/// Every binary message starts with these two bytes, then its type id.
pub const HEAD: [u8; 2] = [0xA3, 0x95];
pub const HEADER_LEN: usize = 3;

/// How one field is stored.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FieldType {
    /// A number of `size` bytes, little-endian, times `scale`.
    Number {
        kind: NumberKind,
        size: usize,
        scale: f64,
    },
    /// NUL-padded text of `size` bytes.
    Text { size: usize },
    /// Bytes that are neither (`a`, an array of 32 int16): skipped.
    Skip { size: usize },
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NumberKind {
    Signed,
    Unsigned,
    Float,
    /// IEEE half precision (`g`).
    Half,
}

impl FieldType {
    /// The type of a format character; `None` for one ArduPilot does not define.
    pub fn of(character: u8) -> Option<FieldType> {
        use NumberKind::{Float, Half, Signed, Unsigned};
        let number = |kind, size, scale| FieldType::Number { kind, size, scale };
        Some(match character {
            b'b' => number(Signed, 1, 1.0),
            b'B' | b'M' => number(Unsigned, 1, 1.0),
            b'h' => number(Signed, 2, 1.0),
            b'H' => number(Unsigned, 2, 1.0),
            b'i' => number(Signed, 4, 1.0),
            b'I' => number(Unsigned, 4, 1.0),
            b'q' => number(Signed, 8, 1.0),
            b'Q' => number(Unsigned, 8, 1.0),
            b'f' => number(Float, 4, 1.0),
            b'd' => number(Float, 8, 1.0),
            b'g' => number(Half, 2, 1.0),
            b'c' => number(Signed, 2, 0.01),
            b'C' => number(Unsigned, 2, 0.01),
            b'e' => number(Signed, 4, 0.01),
            b'E' => number(Unsigned, 4, 0.01),
            b'L' => number(Signed, 4, 1e-7),
            b'n' => FieldType::Text { size: 4 },
            b'N' => FieldType::Text { size: 16 },
            b'Z' => FieldType::Text { size: 64 },
            b'a' => FieldType::Skip { size: 64 },
            _ => return None,
        })
    }

    pub fn size(self) -> usize {
        match self {
            FieldType::Number { size, .. }
            | FieldType::Text { size }
            | FieldType::Skip { size } => size,
        }
    }
}

/// One message type as its `FMT` defines it.
#[derive(Debug, Clone, PartialEq)]
pub struct MessageFormat {
    pub name: String,
    /// The whole message's length in bytes, header included.
    pub length: usize,
    pub columns: Vec<String>,
    /// Each field's type and byte offset in the payload (after the header); `None` for
    /// a binary format whose characters are unknown or overrun its length.
    pub fields: Option<Vec<(FieldType, usize)>>,
}

impl MessageFormat {
    /// A format from its `FMT` fields. The field layout is kept only where every
    /// character is known and the fields fit in the stated length.
    pub fn new(name: &str, length: usize, format: &str, columns: &str) -> MessageFormat {
        let columns: Vec<String> = columns
            .split(',')
            .map(|column| column.trim().to_string())
            .filter(|column| !column.is_empty())
            .collect();
        let mut fields = Vec::with_capacity(format.len());
        let mut offset = 0;
        let mut known = true;
        for character in format.bytes() {
            match FieldType::of(character) {
                Some(field) => {
                    fields.push((field, offset));
                    offset += field.size();
                }
                None => known = false,
            }
        }
        let fits = offset + HEADER_LEN <= length;
        MessageFormat {
            name: name.trim().to_string(),
            length,
            columns,
            fields: (known && fits).then_some(fields),
        }
    }

    /// The index of the column named `name`.
    pub fn column(&self, name: &str) -> Option<usize> {
        self.columns.iter().position(|column| column == name)
    }
}

/// The number in field `field` of a binary payload, scaled; `None` for text, or when
/// the payload is too short.
pub fn number(payload: &[u8], (field, offset): (FieldType, usize)) -> Option<f64> {
    let FieldType::Number { kind, size, scale } = field else {
        return None;
    };
    let bytes = payload.get(offset..offset + size)?;
    let mut buffer = [0u8; 8];
    buffer[..size].copy_from_slice(bytes);
    let raw = u64::from_le_bytes(buffer);
    let value = match kind {
        NumberKind::Unsigned => raw as f64,
        NumberKind::Signed => {
            let shift = 64 - 8 * size as u32;
            (((raw << shift) as i64) >> shift) as f64
        }
        NumberKind::Float if size == 4 => f32::from_bits(raw as u32) as f64,
        NumberKind::Float => f64::from_bits(raw),
        NumberKind::Half => half_to_f64(raw as u16),
    };
    Some(value * scale)
}

/// The text in a text field of a binary payload, up to its first NUL.
pub fn text(payload: &[u8], (field, offset): (FieldType, usize)) -> Option<String> {
    let FieldType::Text { size } = field else {
        return None;
    };
    let bytes = payload.get(offset..offset + size)?;
    let end = bytes.iter().position(|&byte| byte == 0).unwrap_or(size);
    Some(String::from_utf8_lossy(&bytes[..end]).trim().to_string())
}

/// An IEEE 754 half-precision number.
fn half_to_f64(bits: u16) -> f64 {
    let sign = if bits & 0x8000 != 0 { -1.0 } else { 1.0 };
    let exponent = i32::from((bits >> 10) & 0x1f);
    let mantissa = f64::from(bits & 0x3ff);
    sign * match exponent {
        0 => mantissa * 2f64.powi(-24),
        0x1f if mantissa == 0.0 => f64::INFINITY,
        0x1f => f64::NAN,
        _ => (1.0 + mantissa / 1024.0) * 2f64.powi(exponent - 15),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_field_decodes_with_its_size_sign_and_scale() {
        let format = MessageFormat::new("T", 3 + 2 + 2 + 4 + 4 + 4 + 2, "hcLfnH", "A,B,C,D,E,F");
        let fields = format.fields.clone().unwrap();
        let mut payload = Vec::new();
        payload.extend_from_slice(&(-2i16).to_le_bytes());
        payload.extend_from_slice(&(-12345i16).to_le_bytes());
        payload.extend_from_slice(&(-353_640_332i32).to_le_bytes());
        payload.extend_from_slice(&1.5f32.to_le_bytes());
        payload.extend_from_slice(b"MAG\0");
        payload.extend_from_slice(&65535u16.to_le_bytes());
        assert_eq!(number(&payload, fields[0]), Some(-2.0));
        assert!((number(&payload, fields[1]).unwrap() + 123.45).abs() < 1e-9);
        assert!((number(&payload, fields[2]).unwrap() + 35.364_033_2).abs() < 1e-9);
        assert_eq!(number(&payload, fields[3]), Some(1.5));
        assert_eq!(text(&payload, fields[4]).as_deref(), Some("MAG"));
        assert_eq!(number(&payload, fields[5]), Some(65535.0));
        // A payload cut short gives nothing rather than a panic.
        assert_eq!(number(&payload[..3], fields[1]), None);
    }

    #[test]
    fn a_format_that_overruns_its_length_or_has_unknown_characters_has_no_layout() {
        assert!(MessageFormat::new("X", 5, "I", "A").fields.is_none());
        assert!(MessageFormat::new("X", 20, "Iy", "A,B").fields.is_none());
        assert!(MessageFormat::new("X", 7, "I", "A").fields.is_some());
    }

    #[test]
    fn half_floats() {
        assert_eq!(half_to_f64(0x3c00), 1.0);
        assert_eq!(half_to_f64(0xc000), -2.0);
        assert_eq!(half_to_f64(0x7c00), f64::INFINITY);
    }
}
