//! `(x, y, z)` tuples ([`super`]), as CircuitPython prints a vector such as
//! `sensor.magnetic`, perhaps after a sensor name and a unit, as in
//! adafruit/Adafruit_CircuitPython_LSM9DS1 `examples/lsm9ds1_simpletest.py`
//! (`Magnetometer (gauss): (…)`). A tuple with no words before it is the magnetometer.

use nalgebra::Vector3;

use super::names::{quantity_of_name, Normalized, SUMMARY_WORDS};
use super::units::{number, set_vector, unit_of, Quantity, Unit};
use super::{LineError, LineFormat, SensorSample};

/// Whether the line ends with a parenthesised list that starts with a number.
pub(super) fn looks_like_tuple(text: &str) -> bool {
    let Some(body) = text.strip_suffix(')') else {
        return false;
    };
    let Some(open) = body.rfind('(') else {
        return false;
    };
    let inner = body.get(open + 1..).unwrap_or("");
    inner
        .split(',')
        .next()
        .is_some_and(|first| number(first.trim()).is_some())
}

/// `(x, y, z)`, perhaps after a name and a unit (`Magnetometer (gauss): (…)`).
pub(super) fn parse_tuple(text: &str) -> Result<SensorSample, LineError> {
    let body = text.strip_suffix(')').unwrap_or(text);
    let open = body.rfind('(').ok_or(LineError::Unrecognised)?;
    let inner = body.get(open + 1..).unwrap_or("");
    let prefix = body.get(..open).unwrap_or("");
    let mut v = [0.0f64; 3];
    let mut n = 0usize;
    for (idx, field) in inner.split(',').enumerate() {
        let value = number(field.trim()).ok_or(LineError::NotANumber {
            context: "(x, y, z)",
            field: idx + 1,
        })?;
        if let Some(slot) = v.get_mut(n) {
            *slot = value;
        }
        n += 1;
    }
    if n != 3 {
        return Err(LineError::TupleCount { found: n });
    }

    let mut quantity: Option<Quantity> = None;
    let mut unit: Option<Unit> = None;
    let mut has_words = false;
    for word in prefix.split(|c: char| c.is_whitespace() || c == ',') {
        if word.trim_matches(|c: char| !c.is_alphanumeric()).is_empty() {
            continue;
        }
        has_words = true;
        if let Some(found) = unit_of(word) {
            unit = Some(found);
            continue;
        }
        let Some(normalized) = Normalized::new(word) else {
            continue;
        };
        let name = normalized.as_str();
        if SUMMARY_WORDS.contains(&name) {
            return Err(LineError::Summary);
        }
        if let Some(found) = quantity_of_name(name, false) {
            quantity.get_or_insert(found);
        }
    }
    let (quantity, unit) = match (quantity, unit) {
        (Some(quantity), Some(unit)) if unit.quantity == quantity => (quantity, Some(unit)),
        (Some(quantity), Some(unit)) => {
            return Err(LineError::UnitConflict {
                unit: unit.name,
                what: quantity.name(),
            })
        }
        (None, Some(unit)) => (unit.quantity, Some(unit)),
        (Some(quantity), None) => (quantity, None),
        (None, None) if has_words => return Err(LineError::TupleLabel),
        (None, None) => (Quantity::Mag, None),
    };
    if quantity == Quantity::Temp {
        return Err(LineError::TupleLabel);
    }
    let mut sample = SensorSample::empty(LineFormat::Tuple);
    set_vector(&mut sample, quantity, Vector3::new(v[0], v[1], v[2]), unit);
    Ok(sample)
}

#[cfg(test)]
mod tests {
    use std::f64::consts::PI;

    use super::super::parse_line;
    use super::super::tests::{assert_close, sample};
    use super::*;

    #[test]
    fn golden_tuples() {
        let s = sample("(12.5, -3.25, 40.0)");
        assert_eq!(s.format, LineFormat::Tuple);
        assert_close(s.mag_in_sensor_ut, [12.5, -3.25, 40.0], "mag");

        let s = sample("Acceleration (m/s^2): (0.100,0.200,9.800)");
        assert_close(s.acc_in_sensor_mps2, [0.1, 0.2, 9.8], "acc");
        let s = sample("Magnetometer (gauss): (0.250,-0.100,0.400)");
        assert_close(s.mag_in_sensor_ut, [25.0, -10.0, 40.0], "mag in gauss");
        let s = sample("Gyroscope (degrees/sec): (180.000,0.000,-90.000)");
        assert_close(s.gyro_in_sensor_radps, [PI, 0.0, -PI / 2.0], "gyro");

        assert_eq!(
            parse_line("(1, 2)"),
            Err(LineError::TupleCount { found: 2 })
        );
        assert_eq!(
            parse_line("Orientation: (1, 2, 3)"),
            Err(LineError::TupleLabel)
        );
    }
}
