//! Autopilot logs from `../shared/data`: ArduPilot DataFlash (binary and text), read
//! whole and in chunks, and the `.param` file written for log171 read back and applied
//! as ArduPilot applies it. Skipped, with a message, where the folder is absent.

mod common;

use compass_pdr::calibration::{calibrate, CalibrationOptions};
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
    assert_eq!(recording.mag_in_body_ut.len(), 141);
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

/// The spread of |B| (standard deviation over mean, %) of `raw` corrected by `compass`
/// at the battery current nearest in time.
fn spread_pct(
    compass: &ArduPilotCompass,
    raw_mg: &[(f64, Vector3<f64>)],
    log: &AutopilotLog,
) -> f64 {
    let current = &log.current_a;
    let magnitudes: Vec<f64> = raw_mg
        .iter()
        .map(|&(t_s, raw)| {
            let idx = current
                .t_s
                .partition_point(|&t| t < t_s)
                .min(current.len() - 1);
            compass.apply(raw, current.values[idx]).norm()
        })
        .collect();
    compass_pdr::stats::spread_pct(magnitudes.into_iter()).expect("samples with a field")
}

#[test]
fn log171_s_param_file_applied_as_ardupilot_applies_it_narrows_the_field() {
    let Some((name, bytes)) = log171() else {
        return;
    };
    let report: ImportReport = compass_pdr::io::import::import(&name, &bytes).unwrap();
    let log = report.autopilot.clone().unwrap();
    let analysis = calibrate(report, &CalibrationOptions::default()).unwrap();
    let calibration = analysis.report.autopilot.as_ref().unwrap();
    assert_eq!(calibration.compasses.len(), 3);
    // The file as the user gets it, read back; parameters it does not set stay as in
    // the log.
    let written = parse_param_file(&calibration.param_file);
    let lookup = |name: &str| param_in(&written, name).or_else(|| log.param(name));
    for compass in &log.compasses {
        let raw = compass.raw_in_body_ut.as_ref().unwrap();
        let raw_mg: Vec<(f64, Vector3<f64>)> = raw
            .t_s
            .iter()
            .zip(&raw.values)
            .map(|(&t, &v)| (t, v * 10.0))
            .collect();
        let in_force_lookup = |name: &str| log.param(name);
        let in_force = ArduPilotCompass::from_params(&in_force_lookup, compass.instance).unwrap();
        let new = ArduPilotCompass::from_params(&lookup, compass.instance).unwrap();
        let (before, after) = (
            spread_pct(&in_force, &raw_mg, &log),
            spread_pct(&new, &raw_mg, &log),
        );
        eprintln!(
            "{}: |B| spread {before:.2} % in force, {after:.2} % written",
            compass.source
        );
        assert!(
            after <= before,
            "{}: {after:.2} % against {before:.2} %",
            compass.source
        );
        let result = &calibration.compasses[compass.instance];
        assert!((result.fitted.spread_pct - after).abs() < 0.05);
    }
    // The primary compass's heading agrees better with the autopilot's attitude.
    let primary = &calibration.compasses[0];
    assert!(primary.fitted.heading_rms_deg < primary.in_force.unwrap().heading_rms_deg);
}

#[test]
fn a_px4_log_s_params_file_applied_as_px4_applies_it_narrows_the_field() {
    use compass_pdr::io::autopilot::px4::Px4Compass;
    let Some(data) = common::shared_data() else {
        return;
    };
    let report = common::import_paths(&[data.join("px4-ulog/sample.ulg")]);
    let log = report.autopilot.clone().unwrap();
    let analysis = calibrate(report, &CalibrationOptions::default()).unwrap();
    let calibration = analysis.report.autopilot.as_ref().unwrap();
    assert_eq!(calibration.autopilot, "PX4");
    assert!(calibration.param_file.contains("1\t1\tCAL_MAG0_XOFF\t"));
    let written = parse_param_file(&calibration.param_file);
    let lookup = |name: &str| param_in(&written, name).or_else(|| log.param(name));
    let compass = log
        .compasses
        .iter()
        .find(|compass| compass.source == calibration.compasses[0].source)
        .unwrap();
    let (slot, rotation) = compass.px4_slot.unwrap();
    let in_force_lookup = |name: &str| log.param(name);
    let spread = |px4: &Px4Compass| {
        // PX4's correction of the raw values in the sensor's axes, in gauss.
        let raw = compass.raw_in_body_ut.as_ref().unwrap();
        let magnitudes: Vec<f64> = raw
            .values
            .iter()
            .map(|raw_ut| {
                let raw_sensor_ga = rotation.transpose() * raw_ut / 100.0;
                (rotation * (px4.scale * (raw_sensor_ga - px4.offset_ga))).norm()
            })
            .collect();
        let n = magnitudes.len() as f64;
        let mean = magnitudes.iter().sum::<f64>() / n;
        (magnitudes.iter().map(|m| (m - mean).powi(2)).sum::<f64>() / n).sqrt() / mean * 100.0
    };
    let before = spread(&Px4Compass::from_params(&in_force_lookup, slot, rotation));
    let after = spread(&Px4Compass::from_params(&lookup, slot, rotation));
    eprintln!(
        "{}: |B| spread {before:.2} % in force, {after:.2} % written",
        compass.source
    );
    assert!(after <= before, "{after:.2} % against {before:.2} %");
    assert!((calibration.compasses[0].fitted.spread_pct - after).abs() < 0.05);

    // 6.5 s barely turning: nothing is written, and the notes say what to record.
    let report = common::import_paths(&[data.join("px4-ulog/sample_log_small.ulg")]);
    let analysis = calibrate(report, &CalibrationOptions::default()).unwrap();
    let calibration = analysis.report.autopilot.as_ref().unwrap();
    assert!(calibration.compasses.is_empty() && calibration.param_file.is_empty());
    assert!(
        calibration
            .notes
            .iter()
            .any(|note| note.contains("full circles")),
        "{:?}",
        calibration.notes
    );
    // The parameters in force are judged on the log instead. The field as logged
    // (vehicle_magnetometer, calibrated by them) agrees with the autopilot's heading
    // within a few degrees; the raw field, the calibration undone, is 43° off, which
    // says nothing of the vehicle's heading.
    let kept = calibration
        .kept
        .first()
        .expect("the compass in force judged");
    eprintln!(
        "{}: in force {:.1}° RMS, |B| spread {:.2} % on {} samples",
        kept.source, kept.in_force.heading_rms_deg, kept.in_force.spread_pct, kept.n_samples
    );
    assert!(kept.in_force.heading_rms_deg < 5.0, "{kept:?}");
}

/// The heading comparison of an autopilot log has a row for the calibration the vehicle
/// flies with, its own heading at each sample through the parameters in force, as the
/// autopilot applies them: on log171 (Canberra, 2015, declination from the World
/// Magnetic Model extrapolated 4 years back) it is far closer to the autopilot's heading
/// than the raw field, the calibration undone; on PX4's sample log it is within 2°.
#[test]
fn an_autopilot_log_s_heading_comparison_has_the_parameters_in_force() {
    use compass_pdr::heading::HeadingOptions;
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
            let row = headings.report.rows.iter().find(|row| row.key == key);
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
            .find(|row| row.key == "in_force")
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
        .find(|row| row.key == "ellipsoid")
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
