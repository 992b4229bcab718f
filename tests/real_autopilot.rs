//! Autopilot logs from `../shared/data`: ArduPilot DataFlash (binary and text), read
//! whole and in chunks, and the `.param` file written for log171 read back and applied
//! as ArduPilot applies it. Skipped, with a message, where the folder is absent.

mod common;
mod flights;
mod physics;

use compass_pdr::analysis::calibration::{calibrate, CalibrationOptions};
use compass_pdr::io::autopilot::ardupilot::{parse_param_file, ArduPilotCompass};
use compass_pdr::io::autopilot::param_in;
use compass_pdr::io::autopilot::AutopilotLog;
use compass_pdr::io::import::{ChunkedImport, FileImport};
use compass_pdr::io::ImportReport;
use nalgebra::Vector3;

fn log171() -> Option<(String, Vec<u8>)> {
    let data = common::shared_data()?;
    let path = data.join("ardupilot-copter-log171/log171.bin");
    Some(common::read_named(&[path]).remove(0))
}

#[test]
fn log171_gives_every_stream_the_parameters_in_force_and_three_raw_compasses() {
    let Some((name, bytes)) = log171() else {
        return;
    };
    let report = compass_pdr::io::import::import(&name, &bytes).unwrap();
    let recording = &report.recording;
    // Counts as pymavlink reads them (MAG 2384, IMU 11916, ATT 2383; GPS 1199 of which
    // 161 have no 3D fix).
    assert_eq!(recording.mag_in_body_ut.len(), 2384);
    assert_eq!(recording.acc_in_body_mps2.len(), 11_916);
    assert_eq!(recording.attitude.len(), 2383);
    assert_eq!(recording.gnss.len(), 1199 - 161);
    let autopilot = report.autopilot.as_ref().unwrap();
    assert_eq!(autopilot.params.len(), 491);
    assert_eq!(autopilot.compasses.len(), 3);
    assert!(autopilot.current_a.len() > 2000);
    // Dated by the GPS week: 2015-11-21.
    let start = recording.start_unix_s.unwrap();
    assert!(
        (1_448_064_000.0..1_448_150_400.0).contains(&start),
        "{start}"
    );
    // The raw field, corrected as ArduPilot corrects it, is the field as logged.
    for compass in &autopilot.compasses {
        let lookup = |name: &str| autopilot.param(name);
        let in_force = ArduPilotCompass::from_params(&lookup, compass.instance).unwrap();
        let raw = compass.raw_in_body_ut.as_ref().unwrap();
        for (raw_ut, logged_ut) in raw.values.iter().zip(&compass.logged_in_body_ut.values) {
            let corrected_ut = in_force.apply(raw_ut * 10.0, 0.0) / 10.0;
            // Logged offsets are whole mG, the PARMs' are not: within half a mG.
            assert!(
                (corrected_ut - logged_ut).amax() < 0.06,
                "{}",
                compass.source
            );
        }
    }
    // The chunked import (the CLI's and the page's) gives the same report.
    let mut chunked = ChunkedImport::new(&name, Some(bytes.len()));
    for chunk in bytes.chunks(65_536 - 7) {
        chunked.feed(chunk).unwrap();
    }
    let Ok(FileImport::Final(chunked)) = chunked.finish() else {
        panic!("a DataFlash log is read to its end")
    };
    assert_eq!(chunked, report);
}

#[test]
fn the_text_log_gives_its_streams_and_nan_parameters() {
    let Some(data) = common::shared_data() else {
        return;
    };
    let report = common::import_paths(&[data.join("ardupilot-text-log/nan.log")]);
    assert_eq!(report.format, compass_pdr::io::dataflash::TEXT);
    let recording = &report.recording;
    // 141 MAG messages, 51 of them (0, 0, 0): the compass read nothing then.
    assert_eq!(recording.mag_in_body_ut.len(), 90);
    assert!(report
        .notes
        .iter()
        .any(|note| note.starts_with("MAG: 51 readings of exactly (0, 0, 0) left out")));
    assert_eq!(recording.acc_in_body_mps2.len(), 705);
    assert_eq!(recording.attitude.len(), 141);
    assert_eq!(recording.gnss.len(), 73);
    let autopilot = report.autopilot.as_ref().unwrap();
    assert_eq!(autopilot.params.len(), 330);
    assert!(autopilot.param("COMPASS_MOT_X").unwrap().is_nan());
    assert_eq!(autopilot.compasses.len(), 2);
    assert!(autopilot.firmware.as_deref().unwrap().contains("V3.1.1"));
    assert!(report.diagnostics.is_empty(), "{:?}", report.diagnostics);
}

/// The vector error (RMS, mG) of compass `instance`'s raw field corrected by `params`
/// as ArduPilot corrects it (this test's own reading, [`flights::ardupilot_correct`]),
/// against the World Magnetic Model's field at the log's first fix seen through the
/// autopilot board's attitude (ATT turned by AHRS_TRIM, as imported).
fn vector_rms_mg(
    report: &ImportReport,
    log: &AutopilotLog,
    instance: usize,
    params: &dyn Fn(&str) -> Option<f64>,
) -> f64 {
    use compass_pdr::earth::wmm::{date_of_unix_s, expected_field};
    use nalgebra::Rotation3;
    let recording = &report.recording;
    let fix = &recording.gnss.values[0];
    let date = date_of_unix_s(recording.start_unix_s.unwrap()).unwrap();
    let field = expected_field(fix.lat_deg.unwrap(), fix.lon_deg.unwrap(), 0.0, date).unwrap();
    let declination = field.declination_deg.to_radians();
    let earth_ned_mg = Vector3::new(
        field.horizontal_ut * declination.cos(),
        field.horizontal_ut * declination.sin(),
        field.vertical_ut,
    ) * 10.0;
    let raw = log.compasses[instance].raw_in_body_ut.as_ref().unwrap();
    let attitude = &recording.attitude;
    let current = &log.current_a;
    let (mut sum, mut n) = (0.0, 0usize);
    for (&t_s, raw_ut) in raw.t_s.iter().zip(&raw.values) {
        let idx = attitude.t_s.partition_point(|&t| t < t_s);
        let Some(&t_att) = attitude.t_s.get(idx) else {
            continue;
        };
        if (t_att - t_s).abs() > 0.1 {
            continue;
        }
        let a = attitude.values[idx];
        let board_to_ned =
            Rotation3::from_euler_angles(a.roll_rad, a.pitch_rad, a.yaw_rad.unwrap());
        let i_current = current
            .t_s
            .partition_point(|&t| t < t_s)
            .min(current.len() - 1);
        let corrected =
            flights::ardupilot_correct(params, instance, raw_ut * 10.0, current.values[i_current]);
        sum += (corrected - board_to_ned.inverse() * earth_ned_mg).norm_squared();
        n += 1;
    }
    (sum / n as f64).sqrt()
}

/// log171's `.param` file, applied as its own lines say: every compass it writes flies
/// closer to the Earth's field than its parameters in force; every compass it keeps
/// has no line in it; each compass's comment is the sentence the console prints.
#[test]
fn log171_s_param_file_writes_only_what_beats_the_parameters_in_force() {
    let Some((name, bytes)) = log171() else {
        return;
    };
    let report: ImportReport = compass_pdr::io::import::import(&name, &bytes).unwrap();
    let log = report.autopilot.clone().unwrap();
    let analysis = calibrate(report.clone(), &CalibrationOptions::default()).unwrap();
    let calibration = analysis.report.autopilot.as_ref().unwrap();
    assert_eq!(calibration.compasses.len(), 3);
    assert!(calibration.earth.model_ned_mg().is_some());
    let written = parse_param_file(&calibration.param_file);
    let after = |name: &str| param_in(&written, name).or_else(|| log.param(name));
    let in_force = |name: &str| log.param(name);
    let console = compass_pdr::present::report::autopilot_calibration_lines(calibration);
    for compass in &calibration.compasses {
        let instance = compass.instance;
        let (before_mg, after_mg) = (
            vector_rms_mg(&report, &log, instance, &in_force),
            vector_rms_mg(&report, &log, instance, &after),
        );
        eprintln!(
            "{}: {before_mg:.1} mG in force, {after_mg:.1} mG as the file leaves it ({})",
            compass.label(),
            if compass.is_written() {
                "written"
            } else {
                "kept"
            }
        );
        let sentence = compass.sentence.clone();
        assert!(console.contains(&sentence), "{sentence}");
        assert!(calibration
            .param_file
            .lines()
            .any(|line| line == format!("# {sentence}")));
        let number = if instance == 0 {
            String::new()
        } else {
            (instance + 1).to_string()
        };
        let lines = written
            .iter()
            .filter(|(name, _)| name.starts_with(&format!("COMPASS_OFS{number}_")))
            .count();
        if compass.is_written() {
            assert_eq!(lines, 3, "{sentence}");
            assert!(after_mg < before_mg, "{sentence}");
        } else {
            assert_eq!(lines, 0, "{sentence}");
            assert_eq!(after_mg, before_mg);
        }
    }
    // Compasses 2 and 3 are far off the Earth's field in force (MAG3 has none).
    assert!(calibration.compasses[1].is_written() && calibration.compasses[2].is_written());
}

/// ArduPilot reports the vehicle's attitude, the board's turned back by AHRS_TRIM; the
/// compasses are in the board's axes. Golden values: each log's first `ATT` turned by its
/// trim, `R_ATT · R(AHRS_TRIM_X, AHRS_TRIM_Y, 0)`, computed apart with numpy from the
/// values pymavlink reads (log171: ATT −0.38°, −0.27°, 359.05°, trim 1.18°, 0.30°;
/// nan.log: ATT −0.25°, 0.26°, 189.54°, trim −2.19°, 0.04°).
#[test]
fn ahrs_trim_turns_att_into_the_board_s_attitude() {
    let Some(data) = common::shared_data() else {
        return;
    };
    for (path, expected_deg) in [
        (
            "ardupilot-copter-log171/log171.bin",
            [0.795_701_8, 0.032_605_3, 359.047_993],
        ),
        (
            "ardupilot-text-log/nan.log",
            [-2.437_849_5, 0.304_234_2, 189.539_807],
        ),
    ] {
        let report = common::import_paths(&[data.join(path)]);
        let first = report.recording.attitude.values[0];
        let got = [
            first.roll_rad.to_degrees(),
            first.pitch_rad.to_degrees(),
            first.yaw_rad.unwrap().to_degrees(),
        ];
        for (got, expected) in got.iter().zip(expected_deg) {
            assert!(
                (got - expected).abs() < 2e-4,
                "{path}: {got:?} against {expected_deg:?}"
            );
        }
        assert!(
            report
                .notes
                .iter()
                .any(|note| note.starts_with("ATT turned by AHRS_TRIM")),
            "{path}: {:?}",
            report.notes
        );
    }
    // On log171, the parameters in force agree better with the Earth's field through the
    // board's attitude than through the vehicle's (MAGFit's score.py: 82.8 against 85.2
    // mG with --no-trim).
    let report = common::import_paths(&[data.join("ardupilot-copter-log171/log171.bin")]);
    let log = report.autopilot.clone().unwrap();
    let in_force = |name: &str| log.param(name);
    let trimmed = vector_rms_mg(&report, &log, 0, &in_force);
    let mut untrimmed_report = report.clone();
    let (trim_x, trim_y) = (
        log.param("AHRS_TRIM_X").unwrap(),
        log.param("AHRS_TRIM_Y").unwrap(),
    );
    let undo = nalgebra::Rotation3::from_euler_angles(trim_x, trim_y, 0.0).inverse();
    for value in &mut untrimmed_report.recording.attitude.values {
        let board = nalgebra::Rotation3::from_euler_angles(
            value.roll_rad,
            value.pitch_rad,
            value.yaw_rad.unwrap(),
        );
        let (roll, pitch, yaw) = (board * undo).euler_angles();
        (value.roll_rad, value.pitch_rad, value.yaw_rad) = (roll, pitch, Some(yaw));
    }
    let untrimmed = vector_rms_mg(&untrimmed_report, &log, 0, &in_force);
    eprintln!(
        "log171 compass 1 in force: {trimmed:.1} mG with AHRS_TRIM, {untrimmed:.1} mG without"
    );
    assert!(trimmed < untrimmed - 1.0, "{trimmed} against {untrimmed}");
}

#[test]
fn px4_logs_keep_their_parameters_where_the_flight_cannot_judge_them() {
    let Some(data) = common::shared_data() else {
        return;
    };
    // sample.ulg: no GPS (no model field) and the vehicle barely turns: nothing written.
    // sample_log_small.ulg: 6.5 s, too short to judge.
    for (path, why) in [
        ("px4-ulog/sample.ulg", "turn in the body"),
        ("px4-ulog/sample_log_small.ulg", "too few to judge"),
    ] {
        let report = common::import_paths(&[data.join(path)]);
        let analysis = calibrate(report, &CalibrationOptions::default()).unwrap();
        let calibration = analysis.report.autopilot.as_ref().unwrap();
        assert_eq!(calibration.autopilot, "PX4");
        assert!(calibration.written().next().is_none() && calibration.param_file.is_empty());
        assert!(
            calibration
                .compasses
                .iter()
                .any(|compass| compass.sentence.clone().contains(why)),
            "{path}: {:?}",
            calibration
                .compasses
                .iter()
                .map(|c| c.sentence.clone())
                .collect::<Vec<_>>()
        );
        for compass in &calibration.compasses {
            assert!(
                compass.sentence.clone().contains("Record a flight"),
                "{}",
                compass.sentence.clone()
            );
        }
    }
}

/// The heading comparison of an autopilot log has a row for the calibration the vehicle
/// flies with, its own heading at each sample through the parameters in force, as the
/// autopilot applies them: on log171 (Canberra, 2015, declination from the World
/// Magnetic Model extrapolated 4 years back) it is far closer to the autopilot's heading
/// than the raw field, the calibration undone; on PX4's sample log it is within 2°.
#[test]
fn an_autopilot_log_s_heading_comparison_has_the_parameters_in_force() {
    use compass_pdr::analysis::headings::HeadingOptions;
    let Some(data) = common::shared_data() else {
        return;
    };
    for (path, max_in_force_deg) in [
        ("ardupilot-copter-log171/log171.bin", 15.0),
        ("px4-ulog/sample.ulg", 3.0),
    ] {
        let report = common::import_paths(&[data.join(path)]);
        let (calibration, headings) =
            compass_pdr::pipeline::headings(&report, &HeadingOptions::default()).unwrap();
        let check_rms = |key: &str| {
            let row = headings.report.row_written(key);
            row.and_then(|row| row.check).map(|stats| stats.rms_deg)
        };
        let (in_force, raw) = (check_rms("in_force").unwrap(), check_rms("raw").unwrap());
        eprintln!(
            "{path}: declination {:.2}° ({}); check RMS in force {in_force:.2}°, raw {raw:.2}°",
            calibration.report.declination.declination_deg, calibration.report.declination.source
        );
        assert!(in_force < max_in_force_deg, "{path}: {in_force:.2}°");
        assert!(in_force < raw, "{path}: {in_force:.2}° against {raw:.2}°");
        let label = &headings
            .report
            .rows
            .iter()
            .find(|row| row.key.text() == "in_force")
            .unwrap()
            .label;
        assert!(label.ends_with("'s parameters in force"), "{label}");
    }
    // A multirotor's accelerometer reads its thrust: log171's fields are levelled with
    // the autopilot's roll and pitch, and then the 3D fit agrees with its heading as
    // well as the parameters in force do (52.7° check RMS when levelled with the
    // accelerometer, with no declination; 23.4° with the extrapolated one).
    let report = common::import_paths(&[data.join("ardupilot-copter-log171/log171.bin")]);
    let (calibration, headings) =
        compass_pdr::pipeline::headings(&report, &HeadingOptions::default()).unwrap();
    let row = headings
        .report
        .rows
        .iter()
        .find(|row| row.key.text() == "ellipsoid")
        .unwrap();
    let ellipsoid_deg = row.check.unwrap().rms_deg;
    eprintln!("log171: ellipsoid (3D) check RMS {ellipsoid_deg:.2}°");
    assert!(ellipsoid_deg < 15.0, "{ellipsoid_deg:.2}°");
    assert!(
        calibration
            .report
            .notes
            .iter()
            .any(|note| note.contains("the autopilot's own attitude")),
        "{:?}",
        calibration.report.notes
    );
    // IGRF-14 gives 12.40° at log171's first fix on its day.
    let report = common::import_paths(&[data.join("ardupilot-copter-log171/log171.bin")]);
    let analysis = calibrate(report, &CalibrationOptions::default()).unwrap();
    let declination = &analysis.report.declination;
    assert!(
        (declination.declination_deg - 12.40).abs() < 0.6,
        "{declination:?}"
    );
    assert!(
        declination.source.contains("extrapolated"),
        "{declination:?}"
    );
}
