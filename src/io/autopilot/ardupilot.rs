//! A compass calibration as ArduPilot stores and applies it, and its `.param` file.
//!
//! `AP_Compass::correct_field` (libraries/AP_Compass/AP_Compass_Backend.cpp), in body
//! axes and mG, after the compass's orientation was applied:
//!
//! ```text
//! corrected = M · (raw + COMPASS_OFS) · COMPASS_SCALE + motor
//! M = [[DIA_X, ODI_X, ODI_Y], [ODI_X, DIA_Y, ODI_Z], [ODI_Y, ODI_Z, DIA_Z]]
//! ```
//!
//! `M` is the identity when the three diagonals are zero, and `COMPASS_SCALE` is applied
//! only within 0.85-1.4 (`COMPASS_MIN/MAX_SCALE_FACTOR`). The parameters of the second
//! and third compasses carry a 2 or 3 after the name: `COMPASS_OFS2_X`, `COMPASS_DIA3_Y`.
//! A `.param` file is one `NAME,VALUE` per line, as Mission Planner saves and loads it
//! (MAVProxy's `param load` takes the same with white space; both skip `#` lines).

use nalgebra::{Matrix3, Vector3};

/// `COMPASS_MOTCT` for compensation by battery current.
pub const MOTOR_BY_CURRENT: f64 = 2.0;

/// `AP_Compass`'s sanity range for `COMPASS_SCALE`.
const SCALE_APPLIED: std::ops::Range<f64> = 0.85..1.4;

/// The name of a compass parameter: `COMPASS_OFS_X` for the first compass,
/// `COMPASS_OFS2_X` for the second; `axis` empty for one without an axis.
pub fn compass_param(base: &str, instance: usize, axis: &str) -> String {
    let number = match instance {
        0 => String::new(),
        n => (n + 1).to_string(),
    };
    if axis.is_empty() {
        format!("COMPASS_{base}{number}")
    } else {
        format!("COMPASS_{base}{number}_{axis}")
    }
}

/// One compass's calibration as ArduPilot applies it (motor compensation apart).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArduPilotCompass {
    pub instance: usize,
    /// `COMPASS_OFS*` (mG), added to the raw field.
    pub offsets_mg: Vector3<f64>,
    /// `M` from `COMPASS_DIA*` and `COMPASS_ODI*`.
    pub soft_iron: Matrix3<f64>,
    /// `COMPASS_SCALE*` where ArduPilot applies it, else 1.
    pub scale: f64,
    /// `COMPASS_MOT*` (mG per ampere) where `COMPASS_MOTCT` is 2 (current); zero
    /// otherwise (compensation by throttle, type 1, is not modelled).
    pub motor_mg_per_a: Vector3<f64>,
}

impl ArduPilotCompass {
    /// The calibration in `params` (`None` without all three offsets); `M` is the
    /// identity where the diagonals are absent or zero, as `AP_Compass` takes them.
    pub fn from_params(params: &dyn Fn(&str) -> Option<f64>, instance: usize) -> Option<Self> {
        let get = |base: &str, axis: &str| params(&compass_param(base, instance, axis));
        let offsets_mg = Vector3::new(get("OFS", "X")?, get("OFS", "Y")?, get("OFS", "Z")?);
        let diagonal = [get("DIA", "X"), get("DIA", "Y"), get("DIA", "Z")];
        let soft_iron = match diagonal {
            [Some(dx), Some(dy), Some(dz)] if !(dx == 0.0 && dy == 0.0 && dz == 0.0) => {
                let ox = get("ODI", "X").unwrap_or(0.0);
                let oy = get("ODI", "Y").unwrap_or(0.0);
                let oz = get("ODI", "Z").unwrap_or(0.0);
                Matrix3::new(dx, ox, oy, ox, dy, oz, oy, oz, dz)
            }
            _ => Matrix3::identity(),
        };
        let scale = get("SCALE", "")
            .filter(|scale| SCALE_APPLIED.contains(scale))
            .unwrap_or(1.0);
        let by_current = params("COMPASS_MOTCT") == Some(MOTOR_BY_CURRENT);
        let motor_mg_per_a = match (get("MOT", "X"), get("MOT", "Y"), get("MOT", "Z")) {
            (Some(x), Some(y), Some(z)) if by_current => Vector3::new(x, y, z),
            _ => Vector3::zeros(),
        };
        Some(ArduPilotCompass {
            instance,
            offsets_mg,
            soft_iron,
            scale,
            motor_mg_per_a: motor_mg_per_a.map(|v| if v.is_finite() { v } else { 0.0 }),
        })
    }

    /// The corrected field of a raw one (mG) at a battery current (A).
    pub fn apply(&self, raw_mg: Vector3<f64>, current_a: f64) -> Vector3<f64> {
        self.soft_iron * (raw_mg + self.offsets_mg) * self.scale + self.motor_mg_per_a * current_a
    }

    /// The raw field of a corrected one; `None` when `M` cannot be inverted.
    pub fn undo(&self, corrected_mg: Vector3<f64>) -> Option<Vector3<f64>> {
        let inverse = self.soft_iron.try_inverse()?;
        Some(inverse * corrected_mg / self.scale - self.offsets_mg)
    }

    /// The parameters that set it: offsets, diagonals, off-diagonals and the motor
    /// compensation per ampere (`COMPASS_MOTCT` is one for all compasses: the caller
    /// writes it).
    pub fn params(&self) -> Vec<(String, f64)> {
        let m = &self.soft_iron;
        let mot = &self.motor_mg_per_a;
        let mut params = Vec::with_capacity(12);
        for (base, values) in [
            (
                "OFS",
                [self.offsets_mg.x, self.offsets_mg.y, self.offsets_mg.z],
            ),
            ("DIA", [m[(0, 0)], m[(1, 1)], m[(2, 2)]]),
            ("ODI", [m[(0, 1)], m[(0, 2)], m[(1, 2)]]),
            ("MOT", [mot.x, mot.y, mot.z]),
        ] {
            for (axis, value) in ["X", "Y", "Z"].iter().zip(values) {
                params.push((compass_param(base, self.instance, axis), value));
            }
        }
        params
    }
}

/// A `.param` file: a comment header, then one `NAME,VALUE` per line.
pub fn param_file(comment: &[String], params: &[(String, f64)]) -> String {
    let mut text = String::new();
    for line in comment {
        text.push_str("# ");
        text.push_str(line);
        text.push('\n');
    }
    for (name, value) in params {
        text.push_str(&format!("{name},{}\n", param_value(*value)));
    }
    text
}

/// A value as a `.param` file holds it: a float32's digits, no exponent.
fn param_value(value: f64) -> String {
    let text = format!("{:.7}", value as f32);
    let text = text.trim_end_matches('0');
    text.strip_suffix('.').unwrap_or(text).to_string()
}

/// The parameters of a parameter file: ArduPilot's `NAME,VALUE` or `NAME VALUE`, and
/// QGroundControl's `vehicle component NAME value type`; `#` lines and lines that are
/// not a name and a number skipped.
pub fn parse_param_file(text: &str) -> Vec<(String, f64)> {
    text.lines()
        .map(str::trim)
        .filter(|line| !line.is_empty() && !line.starts_with('#'))
        .filter_map(|line| {
            let parts: Vec<&str> = line
                .split(|c: char| c == ',' || c.is_whitespace())
                .filter(|part| !part.is_empty())
                .collect();
            let is_integer = |part: &&str| part.parse::<u32>().is_ok();
            let (name, value) = match parts.as_slice() {
                [vehicle, component, name, value, ..]
                    if is_integer(vehicle) && is_integer(component) =>
                {
                    (name, value)
                }
                [name, value, ..] => (name, value),
                _ => return None,
            };
            Some((name.to_string(), value.parse::<f64>().ok()?))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_param_file_reads_back_to_the_same_correction() {
        let compass = ArduPilotCompass {
            instance: 1,
            offsets_mg: Vector3::new(-97.79, 118.1, 213.18),
            soft_iron: Matrix3::new(
                0.99, 0.018, -0.0027, 0.018, 1.008, -0.0042, -0.0027, -0.0042, 1.0027,
            ),
            scale: 1.0,
            motor_mg_per_a: Vector3::new(1.5, -2.0, 4.0),
        };
        let mut params = compass.params();
        params.push(("COMPASS_MOTCT".to_string(), MOTOR_BY_CURRENT));
        let text = param_file(&["a test".to_string()], &params);
        assert!(text.starts_with("# a test\nCOMPASS_OFS2_X,-97.79"));
        let params = parse_param_file(&text);
        let lookup = |name: &str| crate::io::autopilot::param_in(&params, name);
        let back = ArduPilotCompass::from_params(&lookup, 1).unwrap();
        let raw = Vector3::new(300.0, -120.0, -800.0);
        assert!((back.apply(raw, 12.0) - compass.apply(raw, 12.0)).amax() < 1e-3);
        assert!((back.undo(back.apply(raw, 0.0)).unwrap() - raw).amax() < 1e-9);
    }

    #[test]
    fn zero_diagonals_are_the_identity_and_an_odd_scale_is_not_applied() {
        let params = [
            ("COMPASS_OFS_X", 1.0),
            ("COMPASS_OFS_Y", 2.0),
            ("COMPASS_OFS_Z", 3.0),
            ("COMPASS_DIA_X", 0.0),
            ("COMPASS_DIA_Y", 0.0),
            ("COMPASS_DIA_Z", 0.0),
            ("COMPASS_SCALE", 2.0),
        ];
        let lookup = |name: &str| params.iter().find(|(n, _)| *n == name).map(|&(_, v)| v);
        let compass = ArduPilotCompass::from_params(&lookup, 0).unwrap();
        assert_eq!(compass.soft_iron, Matrix3::identity());
        assert_eq!(compass.scale, 1.0);
        assert_eq!(
            compass.apply(Vector3::zeros(), 10.0),
            Vector3::new(1.0, 2.0, 3.0)
        );
    }
}
