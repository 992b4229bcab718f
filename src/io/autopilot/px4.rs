//! A compass calibration as PX4 stores and applies it, and its parameter file.
//!
//! PX4's `lib/sensor_calibration/Magnetometer.cpp` corrects a raw reading in the
//! sensor's axes (gauss) as `corrected = R · S · (raw − offset)`, `R` the rotation to body
//! axes (`CAL_MAGn_ROT`, or the board's for an internal compass), `offset` =
//! `CAL_MAGn_XOFF..ZOFF`, `S` symmetric with `CAL_MAGn_XSCALE..ZSCALE` on its diagonal and
//! `XODIAG` (xy), `YODIAG` (xz), `ZODIAG` (yz) off it. The fits work in body axes in
//! ArduPilot's form `M · (raw_b + o_b)` with `raw_b = R · raw`: the same correction is
//! `M = R·S·Rᵀ`, `o_b = −R·offset`, and back `S = Rᵀ·M·R`, `offset = −Rᵀ·o_b`. The file is
//! QGroundControl's `.params`: `vehicle component NAME value type` separated by tabs.

use nalgebra::{Matrix3, Vector3};

/// mG per gauss: the fits' unit.
const MG_PER_GAUSS: f64 = 1000.0;
/// MAVLink's `MAV_PARAM_TYPE_REAL32`, the type of every `CAL_MAG*` value written.
const REAL32: u8 = 9;

/// One compass's calibration in PX4's form.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Px4Compass {
    pub slot: usize,
    /// From the raw values' axes to body axes.
    pub body_from_sensor: Matrix3<f64>,
    pub scale: Matrix3<f64>,
    pub offset_ga: Vector3<f64>,
}

impl Px4Compass {
    /// The calibration in `params` for `slot` (absent values as PX4's defaults).
    pub fn from_params(
        params: &dyn Fn(&str) -> Option<f64>,
        slot: usize,
        body_from_sensor: Matrix3<f64>,
    ) -> Px4Compass {
        let get = |suffix: &str, default: f64| {
            params(&format!("CAL_MAG{slot}_{suffix}"))
                .filter(|value| value.is_finite())
                .unwrap_or(default)
        };
        let (xs, ys, zs) = (get("XSCALE", 1.0), get("YSCALE", 1.0), get("ZSCALE", 1.0));
        let (xod, yod, zod) = (get("XODIAG", 0.0), get("YODIAG", 0.0), get("ZODIAG", 0.0));
        Px4Compass {
            slot,
            body_from_sensor,
            scale: Matrix3::new(xs, xod, yod, xod, ys, zod, yod, zod, zs),
            offset_ga: Vector3::new(get("XOFF", 0.0), get("YOFF", 0.0), get("ZOFF", 0.0)),
        }
    }

    /// The same correction in body axes, ArduPilot's form: `(M, o_b)` with `o_b` in mG.
    pub fn body_form(&self) -> (Matrix3<f64>, Vector3<f64>) {
        let r = self.body_from_sensor;
        (
            r * self.scale * r.transpose(),
            -(r * self.offset_ga) * MG_PER_GAUSS,
        )
    }

    /// PX4's form of a body-axes correction `M · (raw_b + o_b)` (`o_b` in mG).
    pub fn from_body_form(
        slot: usize,
        body_from_sensor: Matrix3<f64>,
        soft_iron: Matrix3<f64>,
        offsets_mg: Vector3<f64>,
    ) -> Px4Compass {
        let r = body_from_sensor;
        Px4Compass {
            slot,
            body_from_sensor,
            scale: r.transpose() * soft_iron * r,
            offset_ga: -(r.transpose() * offsets_mg) / MG_PER_GAUSS,
        }
    }

    /// The parameters that set it.
    pub fn params(&self) -> Vec<(String, f64)> {
        let s = &self.scale;
        let values = [
            ("XOFF", self.offset_ga.x),
            ("YOFF", self.offset_ga.y),
            ("ZOFF", self.offset_ga.z),
            ("XSCALE", s[(0, 0)]),
            ("YSCALE", s[(1, 1)]),
            ("ZSCALE", s[(2, 2)]),
            ("XODIAG", s[(0, 1)]),
            ("YODIAG", s[(0, 2)]),
            ("ZODIAG", s[(1, 2)]),
        ];
        values
            .iter()
            .map(|(suffix, value)| (format!("CAL_MAG{}_{suffix}", self.slot), *value))
            .collect()
    }
}

/// A QGroundControl parameter file: comment lines, then `1 1 NAME value 9` by tabs.
pub fn params_file(comment: &[String], params: &[(String, f64)]) -> String {
    let mut text = String::new();
    for line in comment {
        text.push_str("# ");
        text.push_str(line);
        text.push('\n');
    }
    text.push_str("# Vehicle-Id Component-Id Name Value Type\n");
    for (name, value) in params {
        text.push_str(&format!("1\t1\t{name}\t{}\t{REAL32}\n", *value as f32));
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::autopilot::ardupilot::parse_param_file;

    #[test]
    fn the_body_form_and_back_give_the_same_correction_and_the_file_reads_back() {
        // A compass turned a quarter about z, with an offset and a soft iron.
        let r = Matrix3::new(0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0);
        let compass = Px4Compass {
            slot: 1,
            body_from_sensor: r,
            scale: Matrix3::new(1.02, 0.01, -0.02, 0.01, 0.97, 0.03, -0.02, 0.03, 1.01),
            offset_ga: Vector3::new(0.03, 0.55, -0.39),
        };
        let raw_ga = Vector3::new(0.2, -0.1, 0.45);
        let px4 = r * compass.scale * (raw_ga - compass.offset_ga);
        let (m, o_b) = compass.body_form();
        let ardupilot = m * (r * raw_ga * MG_PER_GAUSS + o_b) / MG_PER_GAUSS;
        assert!((px4 - ardupilot).amax() < 1e-12);
        let back = Px4Compass::from_body_form(1, r, m, o_b);
        assert!((back.scale - compass.scale).amax() < 1e-12);
        assert!((back.offset_ga - compass.offset_ga).amax() < 1e-12);
        let text = params_file(&["test".to_string()], &back.params());
        let read = parse_param_file(&text);
        let lookup = |name: &str| crate::io::autopilot::param_in(&read, name);
        let again = Px4Compass::from_params(&lookup, 1, r);
        assert!((again.offset_ga - compass.offset_ga).amax() < 1e-6);
        assert!((again.scale - compass.scale).amax() < 1e-6);
    }
}
