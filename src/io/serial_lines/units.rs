//! The quantities a serial line carries ([`super`]), the units they are written in and
//! their spellings (`uT`, `gauss`, `m/s^2`, `deg/s`, `dps`, …), numbers with and without
//! a unit after them, and a sample's vector set in SI units. The units without a
//! factor are the Adafruit Unified Sensor units (m/s², rad/s, µT), which are this
//! crate's; g is standard gravity.

use std::f64::consts::PI;

use nalgebra::Vector3;

use super::SensorSample;
use crate::io::{MagUnit, UnitOrigin, STANDARD_GRAVITY_MPS2};

/// The quantities a line can carry.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Quantity {
    Acc,
    Gyro,
    Mag,
    Temp,
}

impl Quantity {
    pub(super) fn name(self) -> &'static str {
        match self {
            Quantity::Acc => "accelerometer",
            Quantity::Gyro => "gyroscope",
            Quantity::Mag => "magnetometer",
            Quantity::Temp => "temperature",
        }
    }
}

/// A unit: the quantity it measures and its factor to this crate's unit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Unit {
    pub(super) quantity: Quantity,
    pub(super) to_si: f64,
    pub(super) name: &'static str,
}

pub(super) const MICROTESLA: Unit = Unit {
    quantity: Quantity::Mag,
    to_si: 1.0,
    name: "µT",
};
pub(super) const GAUSS: Unit = Unit {
    quantity: Quantity::Mag,
    to_si: 100.0,
    name: "gauss",
};
const MILLIGAUSS: Unit = Unit {
    quantity: Quantity::Mag,
    to_si: 0.1,
    name: "mG",
};
pub(super) const NANOTESLA: Unit = Unit {
    quantity: Quantity::Mag,
    to_si: 0.001,
    name: "nT",
};
pub(super) const MPS2: Unit = Unit {
    quantity: Quantity::Acc,
    to_si: 1.0,
    name: "m/s²",
};
const GRAVITY: Unit = Unit {
    quantity: Quantity::Acc,
    to_si: STANDARD_GRAVITY_MPS2,
    name: "g",
};
pub(super) const RADPS: Unit = Unit {
    quantity: Quantity::Gyro,
    to_si: 1.0,
    name: "rad/s",
};
pub(super) const DEGPS: Unit = Unit {
    quantity: Quantity::Gyro,
    to_si: PI / 180.0,
    name: "°/s",
};
pub(super) const CELSIUS: Unit = Unit {
    quantity: Quantity::Temp,
    to_si: 1.0,
    name: "°C",
};

/// Unit spellings, compared without regard to ASCII case.
const UNIT_SPELLINGS: [(&str, Unit); 31] = [
    ("uT", MICROTESLA),
    ("µT", MICROTESLA),
    ("μT", MICROTESLA),
    ("microtesla", MICROTESLA),
    ("gauss", GAUSS),
    ("nT", NANOTESLA),
    ("milligauss", MILLIGAUSS),
    ("m/s^2", MPS2),
    ("m/s²", MPS2),
    ("m/s2", MPS2),
    ("m/s/s", MPS2),
    ("mps2", MPS2),
    ("ms^-2", MPS2),
    ("rad/s", RADPS),
    ("rad/sec", RADPS),
    ("rads", RADPS),
    ("radps", RADPS),
    ("deg/s", DEGPS),
    ("deg/sec", DEGPS),
    ("degrees/s", DEGPS),
    ("degrees/sec", DEGPS),
    ("degree/s", DEGPS),
    ("°/s", DEGPS),
    ("°/sec", DEGPS),
    ("dps", DEGPS),
    ("degps", DEGPS),
    ("C", CELSIUS),
    ("°C", CELSIUS),
    ("degC", CELSIUS),
    ("celsius", CELSIUS),
    ("ºC", CELSIUS),
];

/// The unit a word names, if any; brackets around it are ignored.
pub(super) fn unit_of(word: &str) -> Option<Unit> {
    let word = word
        .trim_end_matches(':')
        .trim_matches(|c| matches!(c, '(' | ')' | '[' | ']'));
    // Case matters for these few: g is gravity, G gauss, mG milligauss.
    match word {
        "g" => return Some(GRAVITY),
        "G" | "Gs" => return Some(GAUSS),
        "mG" => return Some(MILLIGAUSS),
        _ => {}
    }
    UNIT_SPELLINGS
        .iter()
        .find(|(spelling, _)| spelling.eq_ignore_ascii_case(word))
        .map(|&(_, unit)| unit)
}

/// A finite number, or `None`.
pub(super) fn number(text: &str) -> Option<f64> {
    text.parse::<f64>().ok().filter(|value| value.is_finite())
}

/// A number with a unit written right after it (`25.000C`, `12.5uT`).
pub(super) fn number_with_unit(word: &str) -> Option<(f64, Unit)> {
    // Bounded so that a long run of garbage costs little.
    if word.len() > 40 {
        return None;
    }
    word.char_indices()
        .skip(1)
        .find_map(|(idx, _)| Some((number(word.get(..idx)?)?, unit_of(word.get(idx..)?)?)))
}

/// Whether a field is written as an integer (MotionCal counts).
pub(super) fn is_integer_text(field: &str) -> bool {
    let digits = field.strip_prefix(['-', '+']).unwrap_or(field);
    !digits.is_empty() && digits.bytes().all(|byte| byte.is_ascii_digit())
}

/// Sets the vector of `quantity` in `sample`, scaled to SI.
pub(super) fn set_vector(
    sample: &mut SensorSample,
    quantity: Quantity,
    v: Vector3<f64>,
    unit: Option<Unit>,
) {
    let scaled = v * unit.map_or(1.0, |unit| unit.to_si);
    let assumed = unit.is_none();
    match quantity {
        Quantity::Acc => {
            sample.acc_in_sensor_mps2 = Some(scaled);
            sample.acc_unit_assumed = assumed;
        }
        Quantity::Gyro => {
            sample.gyro_in_sensor_radps = Some(scaled);
            sample.gyro_unit_assumed = assumed;
        }
        Quantity::Mag => {
            sample.mag_in_sensor_ut = Some(scaled);
            sample.mag_unit_assumed = assumed;
            sample.mag_unit = match unit {
                Some(unit) => MagUnit {
                    name: unit.name,
                    ut_per_unit: Some(unit.to_si),
                    origin: UnitOrigin::Stated,
                },
                None => MagUnit::assumed_microtesla(),
            };
        }
        // Callers never pass a temperature as a vector.
        Quantity::Temp => {}
    }
}
