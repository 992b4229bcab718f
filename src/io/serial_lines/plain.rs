//! Plain numbers ([`super`]): 3 (the magnetometer), 6 (accelerometer, magnetometer) or
//! 9 (accelerometer, gyroscope, magnetometer), separated by commas, semicolons, spaces or
//! tabs, as sketches print them without labels; 3 may be followed by a unit that names
//! their sensor. Without a unit the Adafruit Unified Sensor units are assumed.

use nalgebra::Vector3;

use super::units::{number, set_vector, unit_of, Quantity, Unit};
use super::{LineError, LineFormat, SensorSample};

/// 3, 6 or 9 numbers; 3 may be followed by a unit.
pub(super) fn parse_plain(text: &str) -> Result<SensorSample, LineError> {
    // An empty field between delimiters is a missing value, which must not shift the
    // values after it into the wrong sensor.
    if let Some(delimiter) = [',', ';'].into_iter().find(|d| text.contains(*d)) {
        let mut fields = text.split(delimiter).enumerate().peekable();
        while let Some((idx, field)) = fields.next() {
            if field.trim().is_empty() && fields.peek().is_some() {
                return Err(LineError::EmptyField { field: idx + 1 });
            }
        }
    }
    let mut values = [0.0f64; 9];
    let mut n = 0usize;
    let mut unit: Option<Unit> = None;
    let mut tokens = text
        .split([',', ';', ' ', '\t'])
        .filter(|token| !token.is_empty())
        .peekable();
    while let Some(token) = tokens.next() {
        if let Some(value) = number(token) {
            if let Some(slot) = values.get_mut(n) {
                *slot = value;
            }
            n += 1;
            continue;
        }
        if tokens.peek().is_none() && n > 0 {
            if let Some(found) = unit_of(token) {
                unit = Some(found);
                continue;
            }
        }
        return Err(LineError::Unrecognised);
    }
    let vector = |start: usize| match values.get(start..start + 3) {
        Some(&[x, y, z]) => Vector3::new(x, y, z),
        _ => Vector3::zeros(),
    };
    let mut sample = SensorSample::empty(LineFormat::PlainNumbers);
    match (n, unit) {
        (3, Some(unit)) if unit.quantity == Quantity::Temp => {
            return Err(LineError::UnitConflict {
                unit: unit.name,
                what: "x, y, z values",
            })
        }
        (3, Some(unit)) => set_vector(&mut sample, unit.quantity, vector(0), Some(unit)),
        (3, None) => set_vector(&mut sample, Quantity::Mag, vector(0), None),
        (6 | 9, Some(_)) => return Err(LineError::PlainUnit),
        (6, None) => {
            set_vector(&mut sample, Quantity::Acc, vector(0), None);
            set_vector(&mut sample, Quantity::Mag, vector(3), None);
        }
        (9, None) => {
            set_vector(&mut sample, Quantity::Acc, vector(0), None);
            set_vector(&mut sample, Quantity::Gyro, vector(3), None);
            set_vector(&mut sample, Quantity::Mag, vector(6), None);
        }
        (found, _) => return Err(LineError::PlainCount { found }),
    }
    Ok(sample)
}

#[cfg(test)]
mod tests {
    use super::super::parse_line;
    use super::super::tests::{assert_close, sample};
    use super::*;

    #[test]
    fn golden_plain_numbers() {
        for text in [
            "12.5,-3.25,40",
            "12.5 -3.25 40",
            "12.5\t-3.25\t40",
            "12.5; -3.25; 40",
        ] {
            let s = sample(text);
            assert_eq!(s.format, LineFormat::PlainNumbers, "{text}");
            assert_close(s.mag_in_sensor_ut, [12.5, -3.25, 40.0], text);
        }
        let s = sample("0.1,0.2,9.8,0.01,0.02,0.03,20,-5,40");
        assert_close(s.acc_in_sensor_mps2, [0.1, 0.2, 9.8], "acc");
        assert_close(s.gyro_in_sensor_radps, [0.01, 0.02, 0.03], "gyro");
        assert_close(s.mag_in_sensor_ut, [20.0, -5.0, 40.0], "mag");

        let s = sample("0.1 0.2 9.8 20 -5 40");
        assert_close(s.acc_in_sensor_mps2, [0.1, 0.2, 9.8], "six: acc");
        assert_close(s.mag_in_sensor_ut, [20.0, -5.0, 40.0], "six: mag");
        assert!(s.gyro_in_sensor_radps.is_none());

        let s = sample("0.1 0.2 1.0 g");
        assert_close(
            s.acc_in_sensor_mps2,
            [0.1 * 9.80665, 0.2 * 9.80665, 9.80665],
            "g",
        );

        assert_eq!(
            parse_line("1,2,3,4"),
            Err(LineError::PlainCount { found: 4 })
        );
        assert_eq!(parse_line("1,,3"), Err(LineError::EmptyField { field: 2 }));
        assert_eq!(
            parse_line("Wrote calibration"),
            Err(LineError::Unrecognised)
        );
    }
}
