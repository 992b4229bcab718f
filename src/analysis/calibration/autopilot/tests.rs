use nalgebra::{Rotation3, Vector3};

use super::samples::UT_PER_MG;
use super::*;
use crate::io::autopilot::ardupilot::parse_param_file;
use crate::io::autopilot::param_in;
use crate::io::recording::{Attitude, Stream};

/// The Earth's field of these tests, north-east-down, mG.
const EARTH_NED_MG: Vector3<f64> = Vector3::new(230.0, 50.0, -530.0);

/// A flight of `n` samples at 10 Hz whose yaw turns through `yaw_span_rad` with ±15° of
/// tilt, and a compass with hard iron `hard_mg` and no soft iron, logged raw (µT).
fn log(
    n: usize,
    yaw_span_rad: f64,
    hard_mg: Vector3<f64>,
    in_force_offsets_mg: [f64; 3],
) -> (AutopilotLog, Stream<Attitude>) {
    let mut attitude = Stream::default();
    let mut raw_ut = Stream::default();
    for i in 0..n {
        let t_s = i as f64 * 0.1;
        let progress = i as f64 / n as f64;
        let (roll, pitch) = (
            0.26 * (0.7 * t_s).sin() * yaw_span_rad.min(1.0),
            0.26 * (0.43 * t_s).cos() * yaw_span_rad.min(1.0),
        );
        let yaw = 1.0 + yaw_span_rad * progress;
        let body_to_ned = Rotation3::from_euler_angles(roll, pitch, yaw);
        let noise = Vector3::new((i as f64 * 1.7).sin(), (i as f64 * 2.3).cos(), 0.0) * 2.0;
        let raw_mg = body_to_ned.inverse() * EARTH_NED_MG + hard_mg + noise;
        raw_ut.push(t_s, raw_mg * UT_PER_MG);
        attitude.push(
            t_s,
            Attitude {
                roll_rad: roll,
                pitch_rad: pitch,
                yaw_rad: Some(yaw.rem_euclid(std::f64::consts::TAU)),
            },
        );
    }
    let params = ["X", "Y", "Z"]
        .iter()
        .zip(in_force_offsets_mg)
        .map(|(axis, value)| (format!("COMPASS_OFS_{axis}"), value))
        .collect();
    let log = AutopilotLog {
        autopilot: Autopilot::ArduPilot,
        firmware: None,
        params,
        params_changed: Vec::new(),
        compasses: vec![CompassLog {
            instance: 0,
            source: "MAG".to_string(),
            logged_in_body_ut: raw_ut.clone(),
            raw_in_body_ut: Some(raw_ut),
            how_raw: String::new(),
            px4_slot: None,
        }],
        main_compass: Some(0),
        current_a: Stream::default(),
    };
    (log, attitude)
}

fn model_truth() -> Truth {
    Truth {
        earth: EarthField::Model {
            ned_mg: EARTH_NED_MG.into(),
            source: "a test field".to_string(),
        },
        declination_rad: Some(EARTH_NED_MG.y.atan2(EARTH_NED_MG.x)),
    }
}

#[test]
fn stale_offsets_are_replaced_and_the_file_says_what_the_console_says() {
    let hard = Vector3::new(120.0, -80.0, 40.0);
    // In force: 150 mG off along x.
    let (log, attitude) = log(1500, 6.3, hard, [-hard.x + 150.0, -hard.y, -hard.z]);
    let calibration = autopilot_calibration(&log, &attitude, &model_truth()).unwrap();
    let compass = &calibration.compasses[0];
    assert!(compass.is_written(), "{}", compass.sentence.clone());
    assert!(compass.turned_deg[1] > 8.0, "{:?}", compass.turned_deg);
    let written = parse_param_file(&calibration.param_file);
    let offsets: Vec<f64> = ["X", "Y", "Z"]
        .iter()
        .map(|axis| param_in(&written, &format!("COMPASS_OFS_{axis}")).unwrap())
        .collect();
    for (offset, truth) in offsets.iter().zip((-hard).iter()) {
        assert!((offset - truth).abs() < 3.0, "{offsets:?}");
    }
    // The file's comment for the compass is the sentence the console and page show.
    assert!(calibration
        .param_file
        .lines()
        .any(|line| line == format!("# {}", compass.sentence.clone())));
    let (check, whole) = (compass.check, compass.whole);
    assert!(check.new.unwrap().vector_rms_mg < 0.2 * check.in_force.unwrap().vector_rms_mg);
    assert!(whole.new.unwrap().heading_rms_deg.unwrap() < 1.0);
    assert!(whole.in_force.unwrap().heading_rms_deg.unwrap() > 5.0);
}

#[test]
fn a_good_calibration_in_force_is_kept_and_nothing_is_written() {
    let hard = Vector3::new(120.0, -80.0, 40.0);
    // In force within a mG of the truth: nothing the flight shows beats it.
    let (log, attitude) = log(1500, 6.3, hard, [-hard.x + 1.0, -hard.y, -hard.z]);
    let calibration = autopilot_calibration(&log, &attitude, &model_truth()).unwrap();
    let compass = &calibration.compasses[0];
    assert!(!compass.is_written(), "{}", compass.sentence.clone());
    assert!(compass.params.is_empty() && calibration.param_file.is_empty());
    assert!(compass
        .sentence
        .clone()
        .contains("parameters in force kept"));
}

#[test]
fn one_heading_tries_the_offsets_only_and_without_a_model_field_nothing() {
    let hard = Vector3::new(120.0, -80.0, 40.0);
    let (log, attitude) = log(600, 0.08, hard, [0.0; 3]);
    let calibration = autopilot_calibration(&log, &attitude, &model_truth()).unwrap();
    let compass = &calibration.compasses[0];
    let models: Vec<&str> = compass
        .candidates
        .iter()
        .map(|c| c.model.as_str())
        .collect();
    assert_eq!(models, ["offsets"], "{:?}", compass.turned_deg);
    assert!(compass.is_written(), "{}", compass.sentence.clone());
    // No position for the model's field: the offsets cannot be told from the field.
    let fitted = Truth {
        earth: EarthField::Fitted,
        declination_rad: None,
    };
    let calibration = autopilot_calibration(&log, &attitude, &fitted).unwrap();
    let compass = &calibration.compasses[0];
    assert!(compass.candidates.is_empty() && !compass.is_written());
    assert!(
        compass.sentence.clone().contains("turn in the body"),
        "{}",
        compass.sentence.clone()
    );
}

#[test]
fn an_iron_outside_the_autopilot_s_bounds_is_never_held_nor_written() {
    let hard = Vector3::new(120.0, -80.0, 40.0);
    let (mut log, attitude) = log(1500, 6.3, hard, [0.0; 3]);
    // In force: DIA 0.35/0.56/2.09, the degenerate parameters.
    for (axis, value) in ["X", "Y", "Z"].iter().zip([0.35, 0.56, 2.09]) {
        log.params.push((format!("COMPASS_DIA_{axis}"), value));
    }
    let calibration = autopilot_calibration(&log, &attitude, &model_truth()).unwrap();
    let compass = &calibration.compasses[0];
    assert!(compass.is_written(), "{}", compass.sentence.clone());
    let written = parse_param_file(&calibration.param_file);
    for axis in ["X", "Y", "Z"] {
        let diagonal = param_in(&written, &format!("COMPASS_DIA_{axis}")).unwrap();
        assert!((0.8..1.2).contains(&diagonal), "{diagonal}");
    }
}

#[test]
fn a_px4_compass_is_written_as_qgroundcontrol_params_with_the_same_sentence() {
    let hard = Vector3::new(120.0, -80.0, 40.0);
    let (mut log, attitude) = log(1500, 6.3, hard, [0.0; 3]);
    log.autopilot = Autopilot::Px4;
    log.compasses[0].px4_slot = Some((1, nalgebra::Matrix3::identity()));
    log.compasses[0].source = "sensor_mag 1".to_string();
    // In force: the offsets 150 mG off along x, in PX4's sign and gauss.
    log.params = vec![
        ("CAL_MAG1_XOFF".to_string(), (hard.x + 150.0) / 1000.0),
        ("CAL_MAG1_YOFF".to_string(), hard.y / 1000.0),
        ("CAL_MAG1_ZOFF".to_string(), hard.z / 1000.0),
    ];
    let calibration = autopilot_calibration(&log, &attitude, &model_truth()).unwrap();
    let compass = &calibration.compasses[0];
    assert!(compass.is_written(), "{}", compass.sentence);
    assert!(compass
        .sentence
        .starts_with("CAL_MAG1 (sensor_mag 1): written"));
    assert!(calibration
        .param_file
        .lines()
        .any(|line| line == format!("# {}", compass.sentence)));
    // QGroundControl's lines, read back: the offsets within 3 mG of the truth.
    assert!(calibration.param_file.contains("1\t1\tCAL_MAG1_XOFF\t"));
    let written = parse_param_file(&calibration.param_file);
    for (axis, truth_mg) in ["X", "Y", "Z"].iter().zip(hard.iter()) {
        let offset_ga = param_in(&written, &format!("CAL_MAG1_{axis}OFF")).unwrap();
        assert!(
            (offset_ga * 1000.0 - truth_mg).abs() < 3.0,
            "{axis}: {offset_ga}"
        );
    }
    assert_eq!(written.len(), compass.params.len());
}

#[test]
fn compensation_by_throttle_in_force_is_left_as_it_is() {
    let hard = Vector3::new(120.0, -80.0, 40.0);
    let (mut log, attitude) = log(1500, 6.3, hard, [-hard.x + 150.0, -hard.y, -hard.z]);
    log.params.push(("COMPASS_MOTCT".to_string(), 1.0));
    log.params.push(("COMPASS_MOT_X".to_string(), 0.5));
    let calibration = autopilot_calibration(&log, &attitude, &model_truth()).unwrap();
    let compass = &calibration.compasses[0];
    assert!(compass.is_written(), "{}", compass.sentence);
    assert!(compass
        .params
        .iter()
        .all(|(name, _)| !name.starts_with("COMPASS_MOT")));
    let written = parse_param_file(&calibration.param_file);
    assert!(written
        .iter()
        .all(|(name, _)| !name.starts_with("COMPASS_MOT")));
}
