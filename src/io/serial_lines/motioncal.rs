//! The tagged lines of MotionCal and Adafruit's sketches ([`super`]): `Raw:` (nine
//! integer counts, or nine decimals in m/s², °/s and µT), `Uni:` (nine SI values) and the
//! calibration echoes `Cal1:` and `Cal2:`. Layouts and units as MotionCal reads them
//! (PaulStoffregen/MotionCal `serialdata.c`, `ascii_parse`; `imuread.h` for the counts'
//! scale) and as adafruit/Adafruit_AHRS `examples/calibration/calibration.ino` and
//! `examples/calibrated_orientation/calibrated_orientation.ino` print them; the echoes
//! as adafruit/Adafruit_Sensor_Calibration `Adafruit_Sensor_Calibration.cpp` applies
//! them. The module header of [`super`] gives the details.

use std::f64::consts::PI;

use nalgebra::{Matrix3, Vector3};

use super::units::{is_integer_text, number};
use super::{
    CalibrationEcho, EchoKind, LineError, LineFormat, SensorSample, SerialLine, MAX_FIELDS,
};
use crate::io::frame::MOTIONCAL_UT_PER_COUNT;
use crate::io::{MagUnit, STANDARD_GRAVITY_MPS2};

/// MotionCal's scale factors (`imuread.h`).
const MOTIONCAL_G_PER_COUNT: f64 = 1.0 / 8192.0;
const MOTIONCAL_DPS_PER_COUNT: f64 = 1.0 / 16.0;

/// The tags of MotionCal and Adafruit's sketches.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Tag {
    Raw,
    Uni,
    Cal1,
    Cal2,
}

const TAGS: [(&str, Tag); 4] = [
    ("Raw:", Tag::Raw),
    ("Uni:", Tag::Uni),
    ("Cal1:", Tag::Cal1),
    ("Cal2:", Tag::Cal2),
];

/// The tag at the start of the line and the text after it. Digits before the tag are
/// skipped: some sketches print `millis()` right before `Raw:` (SensESP's copy of the
/// Adafruit sketch does), and MotionCal skips text before the tag too.
pub(super) fn split_tag(text: &str) -> Option<(Tag, &str)> {
    let rest = text
        .trim_start_matches(|c: char| c.is_ascii_digit())
        .trim_start();
    TAGS.iter().find_map(|&(tag_text, tag)| {
        let head = rest.get(..tag_text.len())?;
        if head.eq_ignore_ascii_case(tag_text) {
            Some((tag, rest.get(tag_text.len()..).unwrap_or("")))
        } else {
            None
        }
    })
}

/// The comma-separated numbers after a tag.
struct Fields {
    values: [f64; MAX_FIELDS],
    n: usize,
    all_integers: bool,
    beyond_16_bits: bool,
}

impl Fields {
    fn vector(&self, start: usize, scale: f64) -> Option<Vector3<f64>> {
        match self.values.get(start..start + 3)? {
            &[x, y, z] => Some(Vector3::new(x, y, z) * scale),
            _ => None,
        }
    }

    fn value(&self, idx: usize) -> Option<f64> {
        self.values.get(idx).copied()
    }
}

fn comma_numbers(body: &str, context: &'static str) -> Result<Fields, LineError> {
    let mut fields = Fields {
        values: [0.0; MAX_FIELDS],
        n: 0,
        all_integers: true,
        beyond_16_bits: false,
    };
    let mut parts = body.split(',').enumerate().peekable();
    while let Some((idx, part)) = parts.next() {
        let part = part.trim();
        if part.is_empty() {
            // A comma after the last value (some sketches print one) adds no value.
            if parts.peek().is_none() && idx > 0 {
                continue;
            }
            return Err(LineError::EmptyField { field: idx + 1 });
        }
        let value = number(part).ok_or(LineError::NotANumber {
            context,
            field: idx + 1,
        })?;
        let Some(slot) = fields.values.get_mut(fields.n) else {
            return Err(LineError::TooManyFields { max: MAX_FIELDS });
        };
        *slot = value;
        fields.n += 1;
        fields.all_integers &= is_integer_text(part);
        fields.beyond_16_bits |= !(-32768.0..=32767.0).contains(&value);
    }
    Ok(fields)
}

const NINE_LAYOUT: &str = "ax,ay,az,gx,gy,gz,mx,my,mz";

fn expect_count(
    fields: &Fields,
    tag: &'static str,
    expected: usize,
    layout: &'static str,
) -> Result<(), LineError> {
    if fields.n == expected {
        Ok(())
    } else {
        Err(LineError::FieldCount {
            tag,
            found: fields.n,
            expected,
            layout,
        })
    }
}

pub(super) fn parse_tagged(tag: Tag, body: &str) -> Result<SerialLine, LineError> {
    match tag {
        Tag::Raw => {
            let fields = comma_numbers(body, "Raw:")?;
            expect_count(&fields, "Raw:", 9, NINE_LAYOUT)?;
            let sample = if fields.all_integers {
                SensorSample {
                    acc_in_sensor_mps2: fields
                        .vector(0, MOTIONCAL_G_PER_COUNT * STANDARD_GRAVITY_MPS2),
                    gyro_in_sensor_radps: fields.vector(3, MOTIONCAL_DPS_PER_COUNT.to_radians()),
                    mag_in_sensor_ut: fields.vector(6, MOTIONCAL_UT_PER_COUNT),
                    mag_unit: MagUnit::MOTIONCAL_COUNT,
                    counts_beyond_16_bits: fields.beyond_16_bits,
                    ..SensorSample::empty(LineFormat::MotionCalRaw)
                }
            } else {
                SensorSample {
                    acc_in_sensor_mps2: fields.vector(0, 1.0),
                    gyro_in_sensor_radps: fields.vector(3, PI / 180.0),
                    mag_in_sensor_ut: fields.vector(6, 1.0),
                    ..SensorSample::empty(LineFormat::AdafruitRawDecimal)
                }
            };
            Ok(SerialLine::Sample(sample))
        }
        Tag::Uni => {
            let fields = comma_numbers(body, "Uni:")?;
            expect_count(&fields, "Uni:", 9, NINE_LAYOUT)?;
            Ok(SerialLine::Sample(SensorSample {
                acc_in_sensor_mps2: fields.vector(0, 1.0),
                gyro_in_sensor_radps: fields.vector(3, 1.0),
                mag_in_sensor_ut: fields.vector(6, 1.0),
                ..SensorSample::empty(LineFormat::Uni)
            }))
        }
        Tag::Cal1 => {
            let fields = comma_numbers(body, "Cal1:")?;
            expect_count(
                &fields,
                "Cal1:",
                10,
                "3 accelerometer offsets, 3 gyroscope offsets, 3 hard-iron offsets, field strength",
            )?;
            Ok(SerialLine::Echo(CalibrationEcho {
                kind: EchoKind::Cal1,
                accel_zero_g_in_sensor_mps2: fields.vector(0, 1.0),
                gyro_zero_rate_in_sensor_radps: fields.vector(3, 1.0),
                mag_hard_iron_in_sensor_ut: fields.vector(6, 1.0),
                mag_field_ut: fields.value(9),
                mag_soft_iron: None,
            }))
        }
        Tag::Cal2 => {
            let fields = comma_numbers(body, "Cal2:")?;
            expect_count(&fields, "Cal2:", 9, "the soft-iron matrix, row by row")?;
            let soft_iron = fields.values.get(..9).map(Matrix3::from_row_slice);
            Ok(SerialLine::Echo(CalibrationEcho {
                kind: EchoKind::Cal2,
                accel_zero_g_in_sensor_mps2: None,
                gyro_zero_rate_in_sensor_radps: None,
                mag_hard_iron_in_sensor_ut: None,
                mag_field_ut: None,
                mag_soft_iron: soft_iron,
            }))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::{assert_close, read_text, sample};
    use super::super::{parse_line, read, read_with_echoes};
    use super::*;
    use crate::io::ImportError;

    #[test]
    fn golden_motioncal_raw_counts() {
        let s = sample("Raw:8192,0,-8192,16,-32,0,300,-150,450");
        assert_eq!(s.format, LineFormat::MotionCalRaw);
        assert_close(s.acc_in_sensor_mps2, [9.80665, 0.0, -9.80665], "acc");
        assert_close(
            s.gyro_in_sensor_radps,
            [1f64.to_radians(), -2f64.to_radians(), 0.0],
            "gyro",
        );
        assert_close(s.mag_in_sensor_ut, [30.0, -15.0, 45.0], "mag");
        assert!(!s.counts_beyond_16_bits);
        // The millis() some sketches print before the tag is skipped.
        assert_eq!(
            sample("123456Raw:0,0,8192,0,0,0,1,2,3").format,
            LineFormat::MotionCalRaw
        );
    }

    #[test]
    fn motioncal_raw_beyond_16_bits_is_kept() {
        let s = sample("Raw:0,0,8192,0,0,0,40000,-40000,100");
        assert!(s.counts_beyond_16_bits);
        assert_close(s.mag_in_sensor_ut, [4000.0, -4000.0, 10.0], "mag");

        let report = read_text("Raw:0,0,8192,0,0,0,40000,-40000,100\n").expect("readable");
        assert_eq!(report.recording.mag_in_body_ut.len(), 1);
        assert_close(
            report.recording.mag_in_body_ut.values.first().copied(),
            [4000.0, 40000.0 * 0.1, -10.0],
            "mag in body axes",
        );
        assert!(
            report
                .notes
                .iter()
                .any(|note| note.contains("beyond ±32767")),
            "{:?}",
            report.notes
        );
    }

    #[test]
    fn golden_uni_line() {
        let s = sample("Uni:0.12,-0.25,9.81,0.0100,-0.0200,0.0000,25.50,-3.25,40.00");
        assert_eq!(s.format, LineFormat::Uni);
        assert_close(s.acc_in_sensor_mps2, [0.12, -0.25, 9.81], "acc");
        assert_close(s.gyro_in_sensor_radps, [0.01, -0.02, 0.0], "gyro rad/s");
        assert_close(s.mag_in_sensor_ut, [25.5, -3.25, 40.0], "mag");
    }

    #[test]
    fn golden_adafruit_raw_with_decimals() {
        let s = sample(
            "Raw: 0.1200, -0.2500, 9.8100, 57.2958, 0.0000, -5.0000, 25.5000, -3.2500, 40.0000",
        );
        assert_eq!(s.format, LineFormat::AdafruitRawDecimal);
        assert_close(s.acc_in_sensor_mps2, [0.12, -0.25, 9.81], "acc");
        assert_close(
            s.gyro_in_sensor_radps,
            [57.2958f64.to_radians(), 0.0, -5f64.to_radians()],
            "gyro °/s",
        );
        assert_close(s.mag_in_sensor_ut, [25.5, -3.25, 40.0], "mag");
    }

    #[test]
    fn calibration_echoes_are_parsed_and_kept_apart() {
        let Ok(SerialLine::Echo(cal1)) =
            parse_line("Cal1:0.100,-0.200,0.300,0.010,-0.020,0.030,12.345,-6.789,30.125,48.500")
        else {
            panic!("Cal1 not read");
        };
        assert_eq!(cal1.kind, EchoKind::Cal1);
        assert_close(
            cal1.accel_zero_g_in_sensor_mps2,
            [0.1, -0.2, 0.3],
            "accel offsets",
        );
        assert_close(
            cal1.gyro_zero_rate_in_sensor_radps,
            [0.01, -0.02, 0.03],
            "gyro offsets",
        );
        assert_close(
            cal1.mag_hard_iron_in_sensor_ut,
            [12.345, -6.789, 30.125],
            "hard iron",
        );
        assert_eq!(cal1.mag_field_ut, Some(48.5));
        assert_eq!(cal1.mag_soft_iron, None);

        let Ok(SerialLine::Echo(cal2)) =
            parse_line("Cal2:0.9900,0.0100,-0.0200,0.0100,1.0100,0.0300,-0.0200,0.0300,0.9800")
        else {
            panic!("Cal2 not read");
        };
        assert_eq!(cal2.kind, EchoKind::Cal2);
        let soft_iron = cal2.mag_soft_iron.expect("soft iron");
        assert_eq!(soft_iron[(0, 1)], 0.01);
        assert_eq!(soft_iron[(1, 2)], 0.03);
        assert_eq!(soft_iron[(2, 0)], -0.02);
        assert_eq!(soft_iron[(2, 2)], 0.98);

        assert!(matches!(
            parse_line("Cal2:1,0,0,0,1,0,0,0"),
            Err(LineError::FieldCount {
                found: 8,
                expected: 9,
                ..
            })
        ));

        let text = "Raw:0,0,8192,0,0,0,200,0,-400\n\
                    Cal1:0.000,0.000,0.000,0.000,0.000,0.000,1.000,2.000,3.000,45.000\n\
                    Cal2:1.0000,0.0000,0.0000,0.0000,1.0000,0.0000,0.0000,0.0000,1.0000\n";
        let (report, echoes) = read_with_echoes("cal.txt", text.as_bytes()).expect("readable");
        assert_eq!(report.recording.mag_in_body_ut.len(), 1);
        let lines: Vec<usize> = echoes.iter().map(|echo| echo.line).collect();
        assert_eq!(lines, vec![2, 3]);
        assert!(report.diagnostics.is_empty(), "{:?}", report.diagnostics);

        // Echoes alone are a result for read_with_echoes, but no recording for read.
        let only_echoes = "Cal1:0,0,0,0,0,0,1,2,3,45\n";
        assert!(read_with_echoes("cal.txt", only_echoes.as_bytes()).is_ok());
        assert!(matches!(
            read("cal.txt", only_echoes.as_bytes()),
            Err(ImportError::NothingRecognised { .. })
        ));
    }
}
