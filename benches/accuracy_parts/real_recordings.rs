//! docs/ACCURACY.md's section on every real recording in `../shared/data`: what each gives,
//! beside the truth it carries (its README lists them).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use compass_pdr::analysis::calibration::row_key::{OnTop, RowKey};
use compass_pdr::analysis::calibration::selection::field_calibration_of;
use compass_pdr::analysis::calibration::{
    CalibrationAnalysis, CalibrationOptions, Method, MethodParameters,
};
use compass_pdr::analysis::headings::{compare, HeadingOptions};
use compass_pdr::base::angle::wrap_to_pi;
use compass_pdr::reference::{ReferenceChoice, ReferenceOptions};
use nalgebra::{Matrix3, Vector3};

use super::common;

fn analyse(paths: &[PathBuf], options: &CalibrationOptions) -> Option<CalibrationAnalysis> {
    let contents = common::read_named(paths);
    let slices: Vec<(&str, &[u8])> = contents
        .iter()
        .map(|(name, bytes)| (name.as_str(), bytes.as_slice()))
        .collect();
    compass_pdr::pipeline::calibrate_files(&slices, options).ok()
}

/// The chosen heading method over the whole heading comparison, and the uncalibrated
/// heading's check RMS.
fn heading_cells(analysis: &CalibrationAnalysis) -> (String, String) {
    let headings = compare(
        analysis,
        &HeadingOptions {
            calibration: CalibrationOptions::default(),
            ..HeadingOptions::default()
        },
    );
    let report = &headings.report;
    let rms_of = |key: &str| {
        report
            .row_written(key)
            .and_then(|row| row.check.or(row.train))
            .map(|stats| stats.rms_deg)
    };
    let raw = rms_of("raw").map_or("—".to_string(), |rms| format!("{rms:.1}°"));
    let chosen = match (report.reference, rms_of(&report.choice.key.text())) {
        (Some(_), Some(rms)) => format!("{}: **{rms:.1}°**", report.choice.label),
        _ => format!("{} (no reference to score it)", report.choice.label),
    };
    (raw, chosen)
}

/// The 3D fit's own figures: |B| spread after it, its model, and what it could not see.
fn fit_cell(analysis: &CalibrationAnalysis) -> String {
    let Some(method) = analysis.report.method(Method::Ellipsoid) else {
        return "—".to_string();
    };
    match &method.parameters {
        Some(MethodParameters::Ellipsoid(fit)) => {
            let unobserved: Vec<&str> = fit
                .unobserved
                .iter()
                .map(|item| item.parameter.as_str())
                .collect();
            format!(
                "3D fit ({:?}, {}): |B| spread {:.2} %, heading ±{:.1}° from its own uncertainty{}",
                fit.model,
                if fit.uses_dip {
                    "with the dip"
                } else {
                    "magnitude only"
                },
                fit.field_spread_all_pct,
                fit.heading_std_deg,
                if unobserved.is_empty() {
                    String::new()
                } else {
                    format!("; not seen: {}", unobserved.join(", "))
                }
            )
        }
        _ => format!(
            "3D fit refused: {}",
            method.error.as_deref().unwrap_or("no reason given")
        ),
    }
}

/// The chosen device calibration's hard iron against the device's own estimate.
fn device_cell(analysis: &CalibrationAnalysis) -> String {
    let (Some(device), Some((method, calibration))) = (
        analysis.report.device_hard_iron,
        analysis.device_calibration(),
    ) else {
        return String::new();
    };
    format!(
        "; hard iron ({}) {:.1} µT from the OS's own estimate",
        method.label(),
        (calibration.hard_iron_ut - device.mean_ut).norm()
    )
}

fn row(text: &mut String, name: &str, what: &str, truth: &str, analysis: &CalibrationAnalysis) {
    let (raw, chosen) = heading_cells(analysis);
    let _ = writeln!(
        text,
        "| {} | {} | {} | {} | {} | {}{} |",
        cell(name),
        cell(what),
        cell(truth),
        cell(&raw),
        cell(&chosen),
        cell(&fit_cell(analysis)),
        cell(&device_cell(analysis))
    );
}

/// A table cell's text with its bars escaped, so that `|B|` stays inside its cell.
fn cell(text: &str) -> String {
    text.replace('|', "\\|")
}

/// Unwrapped change of a heading series (degrees).
fn turned_deg(headings_deg: &[f64]) -> f64 {
    headings_deg
        .windows(2)
        .map(|pair| wrap_to_pi((pair[1] - pair[0]).to_radians()).to_degrees())
        .sum()
}

/// The QMC5883L author's calibration (`calibrated = A·raw + B`), as hard iron and `A`.
fn qmc_author(data: &Path) -> Option<(Vector3<f64>, Matrix3<f64>)> {
    let text = std::fs::read_to_string(data.join("qmc5883l-calibration/paramters_mag.csv")).ok()?;
    let numbers: Vec<f64> = text
        .split(|c: char| c == ',' || c.is_whitespace())
        .filter_map(|field| field.trim().parse().ok())
        .collect();
    let a = Matrix3::from_row_slice(numbers.get(..9)?);
    let b = Vector3::from_row_slice(numbers.get(9..12)?);
    Some((-(a.try_inverse()? * b), a))
}

fn spread_pct(raw: &[Vector3<f64>], correct: impl Fn(Vector3<f64>) -> f64) -> f64 {
    let norms: Vec<f64> = raw.iter().map(|&m| correct(m)).collect();
    let n = norms.len().max(1) as f64;
    let mean = norms.iter().sum::<f64>() / n;
    let variance = norms.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n;
    100.0 * variance.sqrt() / mean
}

pub fn section(text: &mut String, data: &Path) {
    text.push_str(
        "## Every real recording\n\n\
         Each recording in `../shared/data` as a user would drop it, with the truth it carries (its\n\
         README). Heading errors are RMS on the check part (the second half of the referenced samples);\n\
         \"chosen\" is the method the analysis recommends over the whole heading comparison (the lowest\n\
         check RMS, never worse than uncalibrated; without a reference, the fits' own figures). The 3D fit\n\
         is the tilt-aided ellipsoid (`fit::ellipsoid`).\n\n\
         | recording | what | truth / reference | uncalibrated | chosen | calibration |\n\
         |---|---|---|---|---|---|\n",
    );
    let default = CalibrationOptions::default();
    if let Some(analysis) = analyse(
        &[data.join("vehicle-pixel6a/2023-08-09_12-47-42.csv")],
        &default,
    ) {
        row(
            text,
            "`vehicle-pixel6a`",
            "87 min drive, phone in a mount (|B| 93 µT in it), 1 Hz",
            "GPS course above 5 m/s",
            &analysis,
        );
    }
    for floor in ["F1", "F4"] {
        let paths = common::files_in(&data.join("msft-indoor-2020/site1").join(floor), "txt");
        let options = CalibrationOptions {
            reference: ReferenceOptions {
                choice: ReferenceChoice::Legs,
                ..ReferenceOptions::default()
            },
            position_deg: Some((30.3, 120.1)),
            ..CalibrationOptions::default()
        };
        if let Some(analysis) = analyse(&paths, &options) {
            row(
                text,
                &format!("`msft-indoor-2020` {floor}"),
                "indoor walk in a mall, phone flat, raw field 300-400 µT",
                "waypoint legs (map direction)",
                &analysis,
            );
        }
    }
    let loop_paths = common::files_in(&data.join("phyphox-hallway-loop"), "csv");
    let closed_loop = CalibrationOptions {
        reference: ReferenceOptions {
            choice: ReferenceChoice::Gyro,
            ..ReferenceOptions::default()
        },
        ..CalibrationOptions::default()
    };
    if let Some(analysis) = analyse(&loop_paths, &closed_loop) {
        row(
            text,
            "`phyphox-hallway-loop`",
            "116 m indoor loop, phone in hand (the OS-calibrated field)",
            "the gyro over the closed loop",
            &analysis,
        );
    }
    let sensor_logger = common::files_in(&data.join("sensorlogger-walk-ethz"), "csv");
    if let Some(analysis) = analyse(&sensor_logger, &default) {
        row(
            text,
            "`sensorlogger-walk-ethz`",
            "700 s outdoor walk, the app's folder dropped whole",
            "GNSS course (Location.csv); the OS's hard iron",
            &analysis,
        );
    }
    let hmc = |run: &str| {
        let dir = data.join("hmc5883l-sphere").join(run);
        [
            dir.join("hmc5883l_compass.csv"),
            dir.join("mpu6050_accelerometer.csv"),
        ]
    };
    if let Some(analysis) = analyse(&hmc("full-sphere"), &default) {
        row(
            text,
            "`hmc5883l-sphere` full-sphere",
            "breadboard HMC5883L turned over the sphere",
            "a constant field",
            &analysis,
        );
    }
    if let Some(analysis) = analyse(&hmc("rotate-ccw-around-z-pointing-up"), &default) {
        let chosen = analysis
            .report
            .choice
            .as_ref()
            .map(|choice| choice.key)
            .filter(|key| key.on_top == OnTop::Nothing)
            .and_then(RowKey::field_method);
        let turned = analysis
            .headings_deg
            .iter()
            .find(|(method, _)| Some(*method) == chosen)
            .map_or("—".to_string(), |(method, headings)| {
                format!("{}: {:+.1}°", method.label(), turned_deg(headings))
            });
        let _ = writeln!(
            text,
            "| `hmc5883l-sphere` rotate-ccw | two turns about z, level | +720° of heading in all (the sign: this log's z points up) | — | {turned} over the log | {} |",
            fit_cell(&analysis)
        );
    }
    if let Some(analysis) = analyse(&hmc("unmoved-with-x-pointing-forward"), &default) {
        let note = analysis
            .report
            .methods
            .iter()
            .find(|method| method.method == Method::Ellipsoid)
            .and_then(|method| method.error.clone())
            .unwrap_or_else(|| fit_cell(&analysis));
        let _ = writeln!(
            text,
            "| `hmc5883l-sphere` unmoved | the board at rest | nothing to calibrate | — | — | {note} |"
        );
    }
    if let Some((author_hard_iron, author)) = qmc_author(data) {
        let radius = author.determinant().abs().cbrt().recip();
        for file in ["noisy_raw_data", "filtered_raw_data"] {
            let path = data.join(format!("qmc5883l-calibration/{file}.csv"));
            let Some(analysis) = analyse(&[path], &default) else {
                continue;
            };
            let Some(ours) = analysis
                .report
                .method(Method::Ellipsoid)
                .and_then(field_calibration_of)
            else {
                continue;
            };
            let raw = &analysis.mag_ut;
            let (ours_pct, theirs_pct) = (
                spread_pct(raw, |m| ours.apply(m).norm()),
                spread_pct(raw, |m| (author * (m - author_hard_iron)).norm()),
            );
            let _ = writeln!(
                text,
                "| `qmc5883l-calibration` {file} | a QMC5883L turned by hand, raw counts, 50 Hz (`Fs,50.00`) | the author's result: hard iron ({:.0}, {:.0}, {:.0}) counts, \\|B\\| spread {theirs_pct:.2} % here | — | — | hard iron ({:.0}, {:.0}, {:.0}), {:.1} % of the field's radius ({radius:.0} counts) from the author's; \\|B\\| spread {ours_pct:.2} % |",
                author_hard_iron.x,
                author_hard_iron.y,
                author_hard_iron.z,
                ours.hard_iron_ut.x,
                ours.hard_iron_ut.y,
                ours.hard_iron_ut.z,
                100.0 * (ours.hard_iron_ut - author_hard_iron).norm() / radius
            );
        }
    }
    for (name, paths) in common::tyrex_trials(data) {
        if let Some(analysis) = analyse(&paths, &default) {
            row(
                text,
                &format!("`tyrex-attitude` {name}"),
                "Nexus 5, one person, ~2 min (the motion-capture heading: \"Attitude against motion capture\" below)",
                "the OS's hard iron (the Qualisys attitude is the heading filter's benchmark)",
                &analysis,
            );
        }
    }
    for (name, what) in [
        ("`ardupilot-copter-log171`", "ArduPilot DataFlash binary"),
        ("`ardupilot-text-log`", "ArduPilot DataFlash text"),
        ("`px4-ulog`", "PX4 ULog"),
    ] {
        let _ = writeln!(
            text,
            "| {name} | {what} | the autopilot's parameters and attitude | — | — | each compass against the autopilot's heading, in force and as written: \"Autopilot compasses beside MAGFit\" below |"
        );
    }
    text.push('\n');
}
