//! The sphere "calibration dance": a board turned slowly through every direction, as
//! MotionCal asks, printed as MotionCal `Raw:` lines (what Adafruit's and PJRC's
//! calibration sketches send over the serial port), with its truth.
//!
//! The attitude is continuous: the field's direction in the board's frame spirals from
//! one pole of the board to the other (`turns` turns), so it covers the sphere as a
//! careful dancer does, while the board spins about it so that gravity's direction
//! varies too. The magnetometer sees
//! the Earth's field through the 2007 paper's Eq. 5 error model in the **sensor's own
//! axes** (x forward, y left, z up, as printed): `m = S·b + h + noise`, `S` symmetric
//! (axis scales on the diagonal, soft iron off it), `h` the hard iron; the accelerometer
//! sees gravity (specific force, up when level) and the gyroscope the rate of turn, each
//! in MotionCal's counts (1/8192 g, 1/16 °/s, 0.1 µT).

use nalgebra::{Matrix3, Rotation3, Vector3};
use serde::Serialize;

use super::field::FieldTruth;
use crate::base::rng::SplitMix64;
// Standard gravity, as the importer reads MotionCal counts.
use crate::io::STANDARD_GRAVITY_MPS2;

/// A dance and the board that dances it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DanceConfig {
    pub seed: u64,
    pub duration_s: f64,
    pub rate_hz: f64,
    /// Turns about the vertical over the dance.
    pub turns: f64,
    pub truth: FieldTruth,
}

impl DanceConfig {
    /// A 60 s dance at 50 lines/s with a random distortion (hard iron up to 40 µT per
    /// axis, scales within ±10 %, cross terms up to 0.05), a 48 µT field at 60° dip and
    /// 0.3 µT of noise.
    pub fn from_seed(seed: u64, duration_s: f64) -> DanceConfig {
        let mut rng = SplitMix64::new(seed ^ 0xda7c_e5ee_d000_0000);
        let truth = FieldTruth {
            field_total_ut: 48.0,
            ..FieldTruth::random(&mut rng, 40.0, 0.1, 0.05)
        };
        DanceConfig {
            seed,
            duration_s,
            rate_hz: 50.0,
            turns: 20.0,
            truth,
        }
    }
}

/// What the dance was made with: what a calibration should recover, in the sensor's axes.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct DanceTruth {
    pub hard_iron_ut: [f64; 3],
    /// `S`, row by row; the ideal correction is its inverse.
    pub soft_iron: [[f64; 3]; 3],
    pub field_total_ut: f64,
    pub inclination_deg: f64,
    pub noise_ut: f64,
    pub n_lines: usize,
}

/// The board's attitude (north-east-down from sensor) at time `t_s` of the dance: the
/// one that puts the field's direction, in the sensor's axes, on a spiral from the
/// sensor's +z pole to its −z pole (`turns` turns round it), spun about that direction
/// twice over the dance so that gravity takes every direction too.
pub fn board_attitude(config: &DanceConfig, t_s: f64) -> Rotation3<f64> {
    let phase = (t_s / config.duration_s.max(f64::MIN_POSITIVE)).clamp(0.0, 1.0);
    let z = 1.0 - 2.0 * phase;
    let azimuth = std::f64::consts::TAU * config.turns * phase;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let field_in_sensor = Vector3::new(r * azimuth.cos(), r * azimuth.sin(), z);
    let field_in_ned = config.truth.field_in_ned_ut().normalize();
    let sensor_from_ned = Rotation3::rotation_between(&field_in_ned, &field_in_sensor)
        .unwrap_or_else(|| Rotation3::from_axis_angle(&Vector3::y_axis(), std::f64::consts::PI));
    let spin = Rotation3::from_axis_angle(
        &nalgebra::Unit::new_normalize(field_in_sensor),
        std::f64::consts::TAU * 2.0 * phase,
    );
    (spin * sensor_from_ned).inverse()
}

/// The dance as MotionCal `Raw:` lines (CRLF) and its truth.
pub fn motioncal_raw_lines(config: &DanceConfig) -> (String, DanceTruth) {
    let mut rng = SplitMix64::new(config.seed);
    let n_lines = (config.duration_s * config.rate_hz).round().max(0.0) as usize;
    let dt_s = 1.0 / config.rate_hz;
    let truth = &config.truth;
    let mut text = String::with_capacity(n_lines * 48);
    for line_idx in 0..n_lines {
        let t_s = line_idx as f64 * dt_s;
        let ned_from_sensor = board_attitude(config, t_s);
        let sensor_from_ned = ned_from_sensor.inverse();
        // The Earth's field in the sensor's axes, distorted (Eq. 5).
        let field = sensor_from_ned * truth.field_in_ned_ut();
        let noise = Vector3::new(rng.gaussian(), rng.gaussian(), rng.gaussian()) * truth.noise_ut;
        let mag_ut = truth.soft_iron * field + truth.hard_iron_ut + noise;
        // Specific force: up (−g in NED's down axis) in the sensor's axes.
        let acc_mps2 = sensor_from_ned * Vector3::new(0.0, 0.0, -STANDARD_GRAVITY_MPS2);
        // Rate of turn at the line's time: the change of attitude over one line centred
        // on it (a gyroscope samples the rate when the accelerometer samples gravity).
        let before = board_attitude(config, t_s - dt_s / 2.0);
        let after = board_attitude(config, t_s + dt_s / 2.0);
        let delta = before.inverse() * after;
        let rate_dps = delta.scaled_axis() / dt_s * (180.0 / std::f64::consts::PI);
        let counts = |value: f64, per_unit: f64| (value * per_unit).round() as i64;
        let _ = std::fmt::Write::write_fmt(
            &mut text,
            format_args!(
                "Raw:{},{},{},{},{},{},{},{},{}\r\n",
                counts(acc_mps2.x, 8192.0 / STANDARD_GRAVITY_MPS2),
                counts(acc_mps2.y, 8192.0 / STANDARD_GRAVITY_MPS2),
                counts(acc_mps2.z, 8192.0 / STANDARD_GRAVITY_MPS2),
                counts(rate_dps.x, 16.0),
                counts(rate_dps.y, 16.0),
                counts(rate_dps.z, 16.0),
                counts(mag_ut.x, 10.0),
                counts(mag_ut.y, 10.0),
                counts(mag_ut.z, 10.0),
            ),
        );
    }
    let soft = |row: usize| {
        [
            truth.soft_iron[(row, 0)],
            truth.soft_iron[(row, 1)],
            truth.soft_iron[(row, 2)],
        ]
    };
    let truth = DanceTruth {
        hard_iron_ut: [
            truth.hard_iron_ut.x,
            truth.hard_iron_ut.y,
            truth.hard_iron_ut.z,
        ],
        soft_iron: [soft(0), soft(1), soft(2)],
        field_total_ut: truth.field_total_ut,
        inclination_deg: truth.inclination_deg,
        noise_ut: truth.noise_ut,
        n_lines,
    };
    (text, truth)
}

impl DanceTruth {
    pub fn soft_iron_matrix(&self) -> Matrix3<f64> {
        Matrix3::from_fn(|row, col| self.soft_iron[row][col])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::calibration::{calibrate, CalibrationOptions, Method, MethodParameters};
    use crate::io::import::import;
    use crate::io::serial_lines::sensor_to_body;
    use crate::live::LiveSession;

    /// The truth round-trips: the live session (sensor axes) and the file analysis (body
    /// axes) both recover the hard iron and undo the soft iron.
    #[test]
    fn the_dance_s_distortion_is_recovered_live_and_from_the_file() {
        let config = DanceConfig::from_seed(5, 60.0);
        let (text, truth) = motioncal_raw_lines(&config);
        assert_eq!(text.lines().count(), 3000);
        let hard_iron_ut = Vector3::from(truth.hard_iron_ut);
        let soft_iron = truth.soft_iron_matrix();

        let mut session = LiveSession::new();
        for chunk in text.as_bytes().chunks(700) {
            session.feed(chunk, 0.0);
        }
        let quality = session.refit().expect("the dance fits").clone();
        assert!(quality.verdict.good_enough, "{:?}", quality.verdict);
        let found = quality.calibration;
        // Counts of 0.1 µT and 0.3 µT of noise: the centre to a few hundredths.
        assert!(
            (found.hard_iron_ut - hard_iron_ut).norm() < 0.15,
            "{} vs {hard_iron_ut}",
            found.hard_iron_ut
        );
        let undone = found.soft_iron * soft_iron * (truth.field_total_ut / found.field_ut);
        assert!((undone - Matrix3::identity()).amax() < 0.01, "{undone}");

        let report = import("dance.txt", text.as_bytes()).expect("the lines import");
        assert_eq!(report.format, crate::io::serial_lines::FORMAT_NAME);
        let analysis = calibrate(
            report,
            &CalibrationOptions {
                methods: vec![Method::Ellipsoid],
                ..CalibrationOptions::default()
            },
        )
        .expect("calibrates");
        let Some(MethodParameters::Ellipsoid(fit)) = &analysis.report.methods[0].parameters else {
            panic!("{:?}", analysis.report.methods[0].error);
        };
        let in_body = sensor_to_body(hard_iron_ut);
        assert!(
            (fit.calibration.hard_iron_ut - in_body).norm() < 0.15,
            "{} vs {in_body}",
            fit.calibration.hard_iron_ut
        );
        assert!(fit.field_spread_pct < 1.0, "{}", fit.field_spread_pct);
    }

    #[test]
    fn the_lines_read_the_field_and_gravity_in_motioncal_counts() {
        let mut config = DanceConfig::from_seed(1, 10.0);
        config.truth.hard_iron_ut = Vector3::zeros();
        config.truth.soft_iron = Matrix3::identity();
        config.truth.noise_ut = 0.0;
        // At the start the field points along the board's +z axis.
        let start = board_attitude(&config, 0.0);
        let field_in_sensor = start.inverse() * config.truth.field_in_ned_ut().normalize();
        assert!(
            (field_in_sensor - Vector3::z()).norm() < 1e-9,
            "{field_in_sensor}"
        );
        let (text, _) = motioncal_raw_lines(&config);
        let first = text.lines().next().expect("a line");
        assert!(first.starts_with("Raw:"), "{first}");
        let values: Vec<i64> = first[4..]
            .split(',')
            .map(|v| v.parse().expect("an integer"))
            .collect();
        assert_eq!(values.len(), 9);
        let mag = Vector3::new(values[6] as f64, values[7] as f64, values[8] as f64) / 10.0;
        assert!((mag.norm() - 48.0).abs() < 0.2, "{mag}");
        let acc = Vector3::new(values[0] as f64, values[1] as f64, values[2] as f64) / 8192.0;
        assert!((acc.norm() - 1.0).abs() < 0.001, "{acc}");
    }
}
