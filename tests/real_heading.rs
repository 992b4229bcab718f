//! Replay tests of the heading models on the real recordings in
//! `../shared/data`: the GPS-course comparison on the car log, the map-leg reference on
//! the indoor walks, the closed-loop gyro reference on the hallway loop. Skipped, with a
//! message, when `../shared/data` is absent.
#![cfg(not(target_arch = "wasm32"))]

mod common;

use compass_pdr::analysis::calibration::CalibrationOptions;
use compass_pdr::analysis::headings::{HeadingAnalysis, HeadingOptions, HeadingRow};
use compass_pdr::io::import::import_files;
use compass_pdr::reference::gyro::GyroAlignment;
use compass_pdr::reference::{ReferenceChoice, ReferenceOptions, ReferenceSource};
use std::path::PathBuf;

fn analyse(
    paths: &[PathBuf],
    reference: ReferenceOptions,
    position_deg: Option<(f64, f64)>,
) -> HeadingAnalysis {
    let contents = common::read_named(paths);
    let slices: Vec<(&str, &[u8])> = contents
        .iter()
        .map(|(name, bytes)| (name.as_str(), bytes.as_slice()))
        .collect();
    let report = import_files(&slices).expect("imports");
    let options = HeadingOptions {
        calibration: CalibrationOptions {
            reference,
            position_deg,
            ..CalibrationOptions::default()
        },
        ..HeadingOptions::default()
    };
    compass_pdr::pipeline::headings(&report, &options)
        .expect("analyses")
        .1
}

fn row<'a>(analysis: &'a HeadingAnalysis, key: &str) -> &'a HeadingRow {
    analysis
        .report
        .row_written(key)
        .unwrap_or_else(|| panic!("no row {key}: {:?}", analysis.report.rows))
}

fn check_rms(analysis: &HeadingAnalysis, key: &str) -> f64 {
    row(analysis, key)
        .check
        .map_or(f64::INFINITY, |stats| stats.rms_deg)
}

#[test]
fn vehicle_deviation_model_recovers_what_min_max_leaves_on_the_check_half() {
    let Some(data) = common::shared_data() else {
        return;
    };
    let analysis = analyse(
        &[data.join("vehicle-pixel6a/2023-08-09_12-47-42.csv")],
        ReferenceOptions::default(),
        None,
    );
    let report = &analysis.report;
    assert!(
        matches!(report.reference, Some(ReferenceSource::GpsCourse { min_speed_mps, .. }) if min_speed_mps == 5.0)
    );
    // Half of the referenced samples train, half check.
    assert!(
        report
            .n_train_referenced
            .abs_diff(report.n_check_referenced)
            <= 1
    );
    let (min_max, min_max_fourier) = (
        check_rms(&analysis, "min_max"),
        check_rms(&analysis, "min_max+fourier"),
    );
    let (ellipse, ellipse_fourier) = (
        check_rms(&analysis, "ellipse"),
        check_rms(&analysis, "ellipse+fourier"),
    );
    eprintln!(
        "vehicle check RMS: min/max {min_max:.2}° (+ Fourier {min_max_fourier:.2}°), ellipse {ellipse:.2}° (+ Fourier \
         {ellipse_fourier:.2}°)"
    );
    // The deviation model learns the heading-dependent error that the centre-and-scale
    // fit leaves, and does no harm where the ellipse already removed it.
    assert!(
        min_max_fourier < min_max - 1.0,
        "{min_max_fourier} vs {min_max}"
    );
    assert!(
        ellipse_fourier < ellipse + 0.5,
        "{ellipse_fourier} vs {ellipse}"
    );
    // The data README expects about 14° after a centre-only fit.
    let best = &report.choice.key.text();
    assert!(
        check_rms(&analysis, best) < 14.0,
        "{best}: {}",
        check_rms(&analysis, best)
    );
    assert!(check_rms(&analysis, "raw") > 40.0);
}

#[test]
fn indoor_walks_are_referenced_by_the_waypoint_legs() {
    let Some(data) = common::shared_data() else {
        return;
    };
    for (floor, min_legs) in [("F1", 10), ("F4", 15)] {
        let paths = common::files_in(&data.join("msft-indoor-2020/site1").join(floor), "txt");
        let legs = ReferenceOptions {
            choice: ReferenceChoice::Legs,
            ..ReferenceOptions::default()
        };
        let analysis = analyse(&paths, legs, Some((30.3, 120.1)));
        let Some(ReferenceSource::Legs {
            n_legs,
            total_length_m,
        }) = analysis.report.reference
        else {
            panic!("{floor}: {:?}", analysis.report.reference);
        };
        eprintln!("{floor}: {n_legs} legs, {total_length_m:.0} m");
        // The README: walks of about 123 m between surveyed waypoints.
        assert!(
            n_legs >= min_legs && (100.0..140.0).contains(&total_length_m),
            "{floor}: {n_legs} legs, {total_length_m} m"
        );
        assert!(
            analysis.report.n_train_referenced > 1000 && analysis.report.n_check_referenced > 1000
        );
        assert!(row(&analysis, "raw").check.is_some() && row(&analysis, "min_max").check.is_some());
    }
}

#[test]
fn the_hallway_loop_gyro_reference_closes_and_the_compass_follows_it() {
    let Some(data) = common::shared_data() else {
        return;
    };
    let paths = common::files_in(&data.join("phyphox-hallway-loop"), "csv");
    let gyro = ReferenceOptions {
        choice: ReferenceChoice::Gyro,
        closed_loop: true,
        ..ReferenceOptions::default()
    };
    let analysis = analyse(&paths, gyro, None);
    let Some(ReferenceSource::Gyro {
        alignment:
            GyroAlignment::ClosedLoop {
                drift_deg_per_min,
                turned_deg,
                closure_pct,
            },
        ..
    }) = analysis.report.reference
    else {
        panic!("{:?}", analysis.report.reference);
    };
    eprintln!("hallway loop: drift {drift_deg_per_min:.2}°/min, turned {turned_deg:.0}°, closes to {closure_pct:.1} %");
    assert!(drift_deg_per_min.abs() < 10.0 && closure_pct < 10.0);
    // A loop started at a corner turns three right angles, not four.
    assert!((turned_deg.abs() - 270.0).abs() < 20.0, "{turned_deg}");
    // Against the gyro's shape, the compass is within about 10° on the check half.
    let best = &analysis.report.choice.key.text();
    assert!(
        check_rms(&analysis, best) < 10.0,
        "{best}: {}",
        check_rms(&analysis, best)
    );
}

/// On every recording with a reference, the chosen heading is never worse than the
/// uncalibrated one, the 3D fit gives a heading (it no longer refuses the drive's magnet
/// mount or the indoor walks), and the drive's chosen heading is within the 15° of its
/// own scatter.
#[test]
fn no_recording_gets_a_best_worse_than_uncalibrated_and_the_3d_fit_answers() {
    let Some(data) = common::shared_data() else {
        return;
    };
    let indoor =
        |floor: &str| common::files_in(&data.join("msft-indoor-2020/site1").join(floor), "txt");
    let legs = ReferenceOptions {
        choice: ReferenceChoice::Legs,
        ..ReferenceOptions::default()
    };
    let gyro_loop = ReferenceOptions {
        choice: ReferenceChoice::Gyro,
        ..ReferenceOptions::default()
    };
    let cases = [
        (
            "vehicle-pixel6a",
            vec![data.join("vehicle-pixel6a/2023-08-09_12-47-42.csv")],
            ReferenceOptions::default(),
            None,
        ),
        ("msft F1", indoor("F1"), legs, Some((30.3, 120.1))),
        ("msft F4", indoor("F4"), legs, Some((30.3, 120.1))),
        (
            "phyphox loop",
            common::files_in(&data.join("phyphox-hallway-loop"), "csv"),
            gyro_loop,
            None,
        ),
        (
            "sensorlogger",
            common::files_in(&data.join("sensorlogger-walk-ethz"), "csv"),
            ReferenceOptions::default(),
            None,
        ),
    ];
    for (name, paths, reference, position_deg) in cases {
        let analysis = analyse(&paths, reference, position_deg);
        let report = &analysis.report;
        let chosen = check_rms(&analysis, &report.choice.key.text());
        let raw = check_rms(&analysis, "raw");
        eprintln!(
            "{name}: chosen {} at {chosen:.1}°, uncalibrated {raw:.1}°, 3D fit {:.1}°",
            report.choice.key,
            check_rms(&analysis, "ellipsoid")
        );
        assert!(chosen <= raw, "{name}: {chosen}° against {raw}°");
        assert!(
            row(&analysis, "ellipsoid").error.is_none(),
            "{name}: {:?}",
            row(&analysis, "ellipsoid").error
        );
        if name == "vehicle-pixel6a" {
            assert!(chosen <= 15.0, "{name}: {chosen}°");
        }
    }
}
