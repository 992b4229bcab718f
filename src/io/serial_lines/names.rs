//! Sensor names in labels and in the words before values ([`super`]): `acc`, `gyro`,
//! `mag`, `temp` and their longer spellings, compared lower-cased without punctuation
//! (`Acc_X`, `acc-x` and `accx` are one name), and the words that mark a summary (a
//! calibration result, a min/max) rather than a reading.

use super::units::Quantity;

/// Label and prefix words, lower-cased with punctuation dropped, on the stack.
pub(super) struct Normalized {
    bytes: [u8; 32],
    len: usize,
}

impl Normalized {
    /// `None` for non-ASCII text or names longer than 32 letters and digits.
    pub(super) fn new(text: &str) -> Option<Self> {
        let mut normalized = Normalized {
            bytes: [0; 32],
            len: 0,
        };
        for c in text.chars() {
            if c.is_ascii_alphanumeric() {
                *normalized.bytes.get_mut(normalized.len)? = c.to_ascii_lowercase() as u8;
                normalized.len += 1;
            } else if !c.is_ascii() {
                return None;
            }
        }
        Some(normalized)
    }

    pub(super) fn as_str(&self) -> &str {
        std::str::from_utf8(self.bytes.get(..self.len).unwrap_or_default()).unwrap_or("")
    }
}

const ACC_NAMES: [&str; 4] = ["acc", "accel", "acceleration", "accelerometer"];
const GYRO_NAMES: [&str; 4] = ["gyr", "gyro", "gyroscope", "omega"];
const MAG_NAMES: [&str; 6] = [
    "mag",
    "magn",
    "magnet",
    "magnetic",
    "magnetometer",
    "magneticfield",
];
pub(super) const TEMP_NAMES: [&str; 4] = ["t", "temp", "temperature", "tmp"];
/// Words that mark a summary (a calibration result, a min/max), not a reading.
pub(super) const SUMMARY_WORDS: [&str; 9] = [
    "calibration",
    "offset",
    "offsets",
    "bias",
    "min",
    "max",
    "minimum",
    "maximum",
    "range",
];

/// The quantity a (normalized) name gives; one-letter names only for labels.
pub(super) fn quantity_of_name(name: &str, allow_one_letter: bool) -> Option<Quantity> {
    if allow_one_letter {
        match name {
            "a" => return Some(Quantity::Acc),
            "g" | "w" => return Some(Quantity::Gyro),
            "m" | "b" => return Some(Quantity::Mag),
            _ => {}
        }
    }
    if ACC_NAMES.contains(&name) {
        Some(Quantity::Acc)
    } else if GYRO_NAMES.contains(&name) {
        Some(Quantity::Gyro)
    } else if MAG_NAMES.contains(&name) {
        Some(Quantity::Mag)
    } else if TEMP_NAMES.contains(&name) && name.len() > 1 {
        Some(Quantity::Temp)
    } else {
        None
    }
}
