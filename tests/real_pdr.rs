//! Replay tests of pedestrian dead reckoning on the real recordings in
//! `../shared/data`: the step count and loop closure of the hallway loop, and the error
//! at the surveyed waypoints of the two indoor walks. Skipped, with a message, when
//! `../shared/data` is absent.
#![cfg(not(target_arch = "wasm32"))]

mod common;

use compass_pdr::analysis::calibration::DeclinationChoice;
use compass_pdr::io::import::import_files;
use compass_pdr::io::recording::GyroBias;
use compass_pdr::pdr::step_length::StepLengthModel;
use compass_pdr::pdr::{PdrAnalysis, PdrOptions};
use compass_pdr::pipeline::dead_reckoning;
use std::path::{Path, PathBuf};

fn dead_reckon(paths: &[PathBuf], options: &PdrOptions) -> PdrAnalysis {
    dead_reckon_stated(paths, options, None)
}

/// [`dead_reckon`] with the gyroscope's bias stated, as `--gyro-bias` does.
fn dead_reckon_stated(
    paths: &[PathBuf],
    options: &PdrOptions,
    gyro_bias: Option<GyroBias>,
) -> PdrAnalysis {
    let contents = common::read_named(paths);
    let slices: Vec<(&str, &[u8])> = contents
        .iter()
        .map(|(name, bytes)| (name.as_str(), bytes.as_slice()))
        .collect();
    let mut import = import_files(&slices).expect("imports");
    if let Some(gyro_bias) = gyro_bias {
        import.recording.gyro_bias = gyro_bias;
    }
    dead_reckoning(&import, options).expect("dead-reckons")
}

#[test]
fn hallway_loop_has_its_168_steps_and_closes() {
    let Some(data) = common::shared_data() else {
        return;
    };
    let dir = data.join("phyphox-hallway-loop");
    let paths = common::files_in(&dir, "csv");
    // The loop's known length (116 m) fits Weinberg's K; the heading is the calibrated
    // compass. The indoor GNSS (22-669 m) is weighted by its accuracy, not refused: it
    // places the loop on the map and bends nothing (issue 42).
    let analysis = dead_reckon(
        &paths,
        &PdrOptions {
            known_distance_m: Some(116.0),
            closed_loop: true,
            ..PdrOptions::default()
        },
    );
    let report = &analysis.report;
    eprintln!(
        "phyphox loop: {} steps, heading {}, step model {:?}, closure {:?}",
        report.n_steps, report.heading_key, report.step_model.model, report.loop_closure
    );
    assert!(
        (165..=171).contains(&report.n_steps),
        "168 ± 3 steps: {}",
        report.n_steps
    );
    assert_eq!(report.step_model.trained_on, "known_distance");
    let closure = report.loop_closure.expect("a closed loop");
    assert!(closure.gap_pct < 3.0, "{closure:?}");
    assert_eq!(
        report.fixes.poor_accuracy, 0,
        "no fix is refused for its accuracy: {:?}",
        report.fixes
    );
    assert!(report.fixes.used > 0, "{:?}", report.fixes);
    assert!(analysis.frame.is_some(), "the loop is on the map");
    // The gyro aligned to the attitude filter's heading (no rotation vector) closes the
    // loop within 2 % (1.53 %; issue 18). phyphox logs a bias-removed gyroscope (Android's
    // `TYPE_GYROSCOPE`, iOS Core Motion's device-motion rate), which the import says.
    let gyro_ahrs = PdrOptions {
        known_distance_m: Some(116.0),
        closed_loop: true,
        heading: compass_pdr::pdr::HeadingChoice::parse("gyro+ahrs"),
        ..PdrOptions::default()
    };
    let filtered = dead_reckon(&paths, &gyro_ahrs);
    let closure = filtered.report.loop_closure.expect("a closed loop");
    eprintln!("gyro+ahrs: closure {closure:?}");
    assert!(closure.gap_pct < 2.0, "{closure:?}");
    // Stated raw (`--gyro-bias raw`), the filter's loose bias prior lets a disturbed leg
    // teach it a false bias: the loop then closes within 3 % (2.65 %).
    let raw = dead_reckon_stated(&paths, &gyro_ahrs, Some(GyroBias::Unknown));
    let closure = raw.report.loop_closure.expect("a closed loop");
    eprintln!("gyro+ahrs, --gyro-bias raw: closure {closure:?}");
    assert!(closure.gap_pct < 3.0, "{closure:?}");
}

#[test]
fn indoor_walks_at_the_waypoints() {
    let Some(data) = common::shared_data() else {
        return;
    };
    // The paper's protocol for the step model: train it on one walk, use it on another.
    // Here each walk's K is fitted to its own waypoint path (the steps between its first
    // and last waypoint) and given to the other walk.
    let (k_f1, k_f4) = (common::fitted_k(&data, "F1"), common::fitted_k(&data, "F4"));
    eprintln!("Weinberg K fitted to the waypoint path: F1 {k_f1:.4}, F4 {k_f4:.4}");
    eprintln!("| walk | heading | north | step model | steps | path (m) | RMS (m) | RMS (%) | max (m) | distance error (%) |");
    let mut best = std::collections::HashMap::new();
    let mut chosen = std::collections::HashMap::new();
    let mut filtered = std::collections::HashMap::new();
    for (floor, other_k) in [("F1", k_f4), ("F4", k_f1)] {
        for heading in ["auto", "device", "gyro+device", "ahrs", "gyro+ahrs"] {
            for (k_label, k) in [("default K", None), ("K of the other walk", Some(other_k))] {
                for (north, declination) in [
                    ("true (WMM −5.7°)", DeclinationChoice::Auto),
                    ("magnetic", DeclinationChoice::Degrees(0.0)),
                ] {
                    let analysis = common::indoor_walk(&data, floor, heading, k, declination);
                    let report = &analysis.report;
                    let errors = report.position_error.expect("waypoints score the walk");
                    let k_value = match report.step_model.model {
                        StepLengthModel::Weinberg { k } => k,
                        _ => f64::NAN,
                    };
                    eprintln!(
                    "| {floor} | {} | {north} | Weinberg, {k_label} ({k_value:.3}) | {} | {:.1} | {:.2} | {:.2} | {:.2} | {:+.1} |",
                    report.heading_key,
                    report.n_steps,
                    errors.distance_m,
                    errors.rms_m,
                    errors.rms_pct,
                    errors.max_m,
                    errors.distance_error_pct
                );
                    let entry = best.entry(floor).or_insert(f64::INFINITY);
                    *entry = f64::min(*entry, errors.rms_pct);
                    if k.is_some() && matches!(declination, DeclinationChoice::Degrees(_)) {
                        match heading {
                            "gyro+device" => chosen.insert(floor, errors.rms_pct),
                            "ahrs" | "gyro+ahrs" => {
                                filtered.insert((floor, heading), errors.rms_pct)
                            }
                            _ => None,
                        };
                    }
                }
            }
        }
    }
    eprintln!("best RMS: {best:?}; gyro+device, K of the other walk, magnetic north: {chosen:?}");
    // Under 3 % of the path. One configuration does it on both walks: the gyro
    // aligned to the phone's yaw, K from the other walk, and the plan's north taken as
    // magnetic (the README says why). The bounds hold what it reaches today.
    assert!(chosen["F1"] < 2.7, "{chosen:?}");
    assert!(chosen["F4"] < 2.5, "{chosen:?}");
    assert!(best["F1"] < 2.7 && best["F4"] < 2.5, "{best:?}");
    // Without the phone's rotation vector: the attitude filter's causal heading, and the
    // gyro aligned to it over the walk. Issue 18 asks for 2.5 % on both walks: the gyro
    // aligned to the filter reaches it (2.42 % on both, the logs' `TYPE_GYROSCOPE` read as
    // bias-free); the filter alone does not on F1 (4.8 %; F4 2.8 %).
    eprintln!("attitude filter, K of the other walk, magnetic north: {filtered:?}");
    for floor in ["F1", "F4"] {
        assert!(filtered[&(floor, "ahrs")] < 5.0, "{filtered:?}");
        assert!(filtered[&(floor, "gyro+ahrs")] < 2.5, "{filtered:?}");
    }
}

/// The figure-eight check (`pdr/turning_over.rs`) on real carrying: every step of the
/// nine TYREX trials (in hand, texting, phoning, swinging, front and back pocket,
/// running in hand and in a pocket) is kept, and every IPIN 2023 walk loses the 30-56
/// "steps" of the compass calibration it begins with (at most three lone steps of its
/// first 26 s are left).
#[test]
fn a_compass_calibration_s_figure_eight_is_left_out_and_no_real_walk_or_run_is() {
    let Some(data) = common::shared_data() else {
        return;
    };
    let mut trials = common::tyrex_trials(&data);
    trials.extend(common::tyrex_trials_in(&data, "tyrex-attitude-more"));
    assert_eq!(trials.len(), 9, "{trials:?}");
    for (name, paths) in &trials {
        let analysis = dead_reckon(paths, &PdrOptions::default());
        let left_out = analysis
            .report
            .notes
            .iter()
            .find(|note| note.contains("turned over"));
        eprintln!("{name}: {} steps", analysis.report.n_steps);
        assert!(left_out.is_none(), "{name}: {left_out:?}");
        assert!(analysis.report.n_steps >= 100, "{name}");
    }
    let walks = common::files_in(&data.join("ipin2023-track3-walks"), "txt");
    assert_eq!(walks.len(), 12);
    for walk in &walks {
        let analysis = dead_reckon(std::slice::from_ref(walk), &PdrOptions::default());
        let note = analysis
            .report
            .notes
            .iter()
            .find(|note| note.contains("turned over"))
            .unwrap_or_else(|| panic!("{}: no figure eight left out", walk.display()));
        let n_left_out: usize = note
            .split_whitespace()
            .next()
            .and_then(|n| n.parse().ok())
            .unwrap_or(0);
        assert!(
            (30..=56).contains(&n_left_out),
            "{}: {note}",
            walk.display()
        );
        // At most a lone step or two at the ends of the figure eight are left.
        let n_left = analysis
            .steps
            .iter()
            .filter(|step| step.t_start_s < 26.0)
            .count();
        assert!(
            n_left <= 3,
            "{}: {n_left} steps before 26 s",
            walk.display()
        );
    }
}

/// A phone's fixes move less than its walker (they lag and cut corners): on IPIN route 01
/// (fixes of 4-7 m, legs of 8 m between turns) a filter that learnt the step scale from
/// them shrank reps. 3 and 4 by 15 and 13 % and was sure of it. The fixes must not shrink a
/// walk that nothing proves a step length for: the distance walked between the first and
/// last landmark is within ±10 % of the landmarks' polyline on each of the four walks.
#[test]
fn the_fixes_do_not_shrink_route_01_s_walks() {
    let Some(data) = common::shared_data() else {
        return;
    };
    let walks: Vec<PathBuf> = common::files_in(&data.join("ipin2023-track3-walks"), "txt")
        .into_iter()
        .filter(|walk| walk.to_string_lossy().contains("Trial01"))
        .collect();
    assert_eq!(walks.len(), 4);
    for walk in &walks {
        let distance_error_pct = walked_distance_error_pct(walk);
        assert!(
            distance_error_pct.abs() <= 10.0,
            "{}: {distance_error_pct:+.1} %",
            walk.display()
        );
    }
}

/// A walk's distance between its first and last landmark, dead-reckoned with the
/// defaults, against the landmarks' polyline (%), printed.
fn walked_distance_error_pct(walk: &Path) -> f64 {
    let analysis = dead_reckon(&[walk.to_path_buf()], &PdrOptions::default());
    let errors = analysis
        .report
        .position_error
        .as_ref()
        .unwrap_or_else(|| panic!("{}: no landmarks scored", walk.display()));
    eprintln!(
        "{}: walked {:+.1} % of the landmarks' {:.1} m",
        walk.display(),
        errors.distance_error_pct,
        errors.distance_m
    );
    errors.distance_error_pct
}

/// Issue 42's distance bar on all twelve IPIN walks: the walked distance between the first
/// and last landmark within ±10 % of the landmarks' polyline on at least ten, the median
/// within ±5 %. Without `pdr/lone_steps.rs` (the feet shifted at the turn-about landmark
/// walked as steps) the median was +5.2 %.
#[test]
fn the_twelve_ipin_walks_walk_the_landmarks_distance() {
    let Some(data) = common::shared_data() else {
        return;
    };
    let walks = common::files_in(&data.join("ipin2023-track3-walks"), "txt");
    assert_eq!(walks.len(), 12);
    let mut distance_errors_pct: Vec<f64> = walks
        .iter()
        .map(|walk| walked_distance_error_pct(walk))
        .collect();
    let within = distance_errors_pct
        .iter()
        .filter(|e| e.abs() <= 10.0)
        .count();
    distance_errors_pct.sort_by(f64::total_cmp);
    let median = 0.5 * (distance_errors_pct[5] + distance_errors_pct[6]);
    eprintln!("within ±10 %: {within} of 12, median {median:+.1} %");
    assert!(within >= 10, "{distance_errors_pct:?}");
    assert!(median.abs() <= 5.0, "{distance_errors_pct:?}");
}
