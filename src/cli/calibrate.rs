//! `compass-pdr calibrate`: every field-domain method, the one best, the device
//! calibration and its exports (C snippet, MotionCal packet).

use std::fmt::Write as _;
use std::path::Path;

use super::args::ImportArgs;
use super::inspect::{import_paths, print_import_diagnostics};
use super::{print_out, print_report};
use compass_pdr::analysis::calibration::{
    CalibrationOptions, CalibrationReport, DeviceHardIron, MethodParameters,
};
use compass_pdr::analysis::headings::HeadingOptions;
use compass_pdr::base::stats::HeadingErrorStats;
use compass_pdr::fit::ellipse::SoftIronModel;
use compass_pdr::fit::export::{c_snippet, motioncal_packet};
use compass_pdr::pipeline;
use compass_pdr::present::plot::draw_calibration_figure;
use compass_pdr::present::report::{
    device_calibration_lines, device_export_or_why, DeviceExport, DeviceExportError,
};
use plotters::prelude::{IntoDrawingArea, SVGBackend};

/// What `calibrate` writes besides its summary.
pub(super) struct Outputs<'a> {
    pub(super) json: bool,
    pub(super) plot: Option<&'a Path>,
    pub(super) export_c: Option<&'a Path>,
    pub(super) export_packet: Option<&'a Path>,
    pub(super) param_out: Option<&'a Path>,
}

pub(super) fn run_calibrate(
    input: &ImportArgs,
    options: &CalibrationOptions,
    outputs: &Outputs<'_>,
) -> Result<(), String> {
    let report = import_paths(input)?;
    // The heading stage too: the best and the device calibration are the analysis's one
    // choice, the same as `heading`, `report` and the page give.
    let heading_options = HeadingOptions {
        calibration: options.clone(),
        ..HeadingOptions::default()
    };
    let (analysis, _) =
        pipeline::headings(&report, &heading_options).map_err(|error| error.to_string())?;
    let report = &analysis.report;
    print_import_diagnostics(&report.file_name, &report.diagnostics);
    // The other commands go on uncalibrated; this one has nothing to give, but for an
    // autopilot log's compasses, which are assessed on their own.
    if let (Some(reasons), None) = (report.why_no_method_fitted(), &report.autopilot) {
        return Err(format!(
            "{}: no calibration could be fitted. {reasons}{}",
            report.file_name,
            kept_parameters(report)
        ));
    }
    if let Some(plot) = outputs.plot {
        let root = SVGBackend::new(plot, (1800, 540)).into_drawing_area();
        draw_calibration_figure(&root, &analysis)
            .map_err(|error| format!("{error} ({})", plot.display()))?;
    }
    let export = device_export_or_why(&analysis);
    let mut written = write_device_exports(outputs, &report.file_name, export.as_ref())?;
    if let Some(path) = outputs.param_out {
        written.push(write_param_file(path, report)?);
    }
    if outputs.json {
        let output = CalibrateOutput {
            report,
            device_calibration: export.as_ref().ok(),
            written: &written,
        };
        return print_report(&output, true, |_| String::new());
    }
    let mut text = calibration_text(report);
    text.push_str("  device calibration:\n");
    for line in device_calibration_lines(&analysis) {
        text.push_str(&format!("    {line}\n"));
    }
    for line in &written {
        text.push_str(&format!("  {line}\n"));
    }
    print_out(&text)
}

/// The C snippet and the MotionCal packet the user asked for, written to their files; what
/// was written, one line each.
fn write_device_exports(
    outputs: &Outputs<'_>,
    file_name: &str,
    export: Result<&DeviceExport, &DeviceExportError>,
) -> Result<Vec<String>, String> {
    let mut written = Vec::new();
    if outputs.export_c.is_none() && outputs.export_packet.is_none() {
        return Ok(written);
    }
    let export = export.map_err(|why| format!("{file_name}: nothing to export: {why}"))?;
    let frame = &export.calibration.frame;
    if let Some(path) = outputs.export_c {
        let text = format!(
            "// {} calibration of {}\n{}",
            export.method.label(),
            file_name,
            c_snippet(&export.calibration)
        );
        std::fs::write(path, text)
            .map_err(|error| format!("cannot write {}: {error}", path.display()))?;
        written.push(format!(
            "C snippet written to {}: {}, raw values in {}",
            path.display(),
            frame.axes,
            frame.unit.label()
        ));
    }
    if let Some(path) = outputs.export_packet {
        // MotionCal's floats are µT by definition: the raw axes, in µT.
        let Some(in_ut) = export.calibration.in_ut() else {
            return Err(format!(
                    "no MotionCal packet: its floats are µT, but the magnetometer's raw values \
                     are in {}; export the JSON or the C snippet, which are in the raw values' unit",
                    frame.unit.label()
                ));
        };
        std::fs::write(path, motioncal_packet(&in_ut))
            .map_err(|error| format!("cannot write {}: {error}", path.display()))?;
        written.push(format!(
            "MotionCal packet written to {}: in µT along {}",
            path.display(),
            frame.axes
        ));
    }
    Ok(written)
}

/// An autopilot log's parameter file, written to `path` (`--param-out`), or why there is
/// none; the line that says it was written.
fn write_param_file(path: &Path, report: &CalibrationReport) -> Result<String, String> {
    let Some(autopilot) = report
        .autopilot
        .as_ref()
        .filter(|a| a.written().next().is_some())
    else {
        return Err(format!(
            "--param-out {}: no autopilot parameters to write for {}: {}",
            path.display(),
            report.file_name,
            report.autopilot.as_ref().map_or_else(
                || "it is not an autopilot log with its compasses' raw fields and attitude"
                    .to_string(),
                |autopilot| autopilot
                    .compasses
                    .iter()
                    .map(|compass| compass.sentence.clone())
                    .chain(autopilot.notes.iter().cloned())
                    .collect::<Vec<_>>()
                    .join("; ")
            )
        ));
    };
    std::fs::write(path, &autopilot.param_file)
        .map_err(|error| format!("cannot write {}: {error}", path.display()))?;
    Ok(format!(
        "{} parameters written to {}",
        autopilot.autopilot,
        path.display()
    ))
}

/// What `calibrate --json` prints: the report, the device calibration in the sensor's
/// own axes and unit (and in body axes and µT), and the files written.
#[derive(serde::Serialize)]
pub(super) struct CalibrateOutput<'a> {
    #[serde(flatten)]
    pub(super) report: &'a CalibrationReport,
    pub(super) device_calibration: Option<&'a DeviceExport>,
    #[serde(skip_serializing_if = "<[String]>::is_empty")]
    pub(super) written: &'a [String],
}

/// The calibration as text: the samples and the field, the hard irons beside the device's
/// own, each method's heading errors and the best.
pub(super) fn calibration_text(report: &CalibrationReport) -> String {
    let mut text = String::new();
    write_samples_and_field(&mut text, report);
    // Where the device estimated its own hard iron, the fitted ones go beside it.
    if let Some(device) = &report.device_hard_iron {
        write_hard_irons(&mut text, report, device);
    }
    write_heading_errors(&mut text, report);
    for note in &report.notes {
        let _ = writeln!(text, "  note: {note}");
    }
    text
}

/// The report's first lines: the samples and their split, the reference heading, the
/// declination, and the field measured beside the model's.
fn write_samples_and_field(text: &mut String, report: &CalibrationReport) {
    let _ = writeln!(
        text,
        "{}: {} magnetometer samples ({} train, {} check{})",
        report.file_name,
        report.n_samples_used,
        report.n_train,
        report.n_check,
        report
            .train_until_s
            .map_or(String::new(), |until_s| format!(
                ", split at {until_s:.1} s"
            ))
    );
    let reference = report
        .reference
        .map_or_else(|| "none".to_string(), |source| source.describe());
    let _ = writeln!(text, "  reference heading: {reference}");
    let _ = writeln!(
        text,
        "  declination: {:.2}° ({})",
        report.declination.declination_deg, report.declination.source
    );
    // Raw counts of unknown sensitivity were kept as they are: the measured field is in
    // counts.
    let raw_unit = report
        .mag_frame
        .map(|frame| frame.unit)
        .filter(|unit| unit.ut_per_unit.is_none())
        .map_or("µT", |unit| unit.name);
    match &report.expected_field {
        Some(expected) => {
            let _ = writeln!(
                text,
                "  field: measured {:.1} {raw_unit} raw, expected {:.1} µT (inclination {:.1}°)",
                report.mean_raw_field_ut, expected.total_ut, expected.inclination_deg
            );
        }
        None => {
            let _ = writeln!(
                text,
                "  field: measured {:.1} {raw_unit} raw (no model value: no position or date)",
                report.mean_raw_field_ut
            );
        }
    }
}

/// The device's own hard iron, then each fitted one and its difference from the device's.
fn write_hard_irons(text: &mut String, report: &CalibrationReport, device: &DeviceHardIron) {
    let vector =
        |v_ut: &nalgebra::Vector3<f64>| format!("({:.1}, {:.1}, {:.1})", v_ut.x, v_ut.y, v_ut.z);
    let _ = writeln!(
        text,
        "  hard iron (µT, body x forward, y right, z down): device's own {} (moved {:.1} µT during the log)",
        vector(&device.mean_ut),
        device.max_change_ut
    );
    for method in &report.methods {
        let fitted = match &method.parameters {
            Some(MethodParameters::Ellipse(fit)) => Some((
                fit.hard_iron_ut,
                match fit.soft_iron_model {
                    SoftIronModel::Full => "full soft iron",
                    SoftIronModel::Isotropic { .. } => "isotropic soft iron",
                },
            )),
            Some(MethodParameters::Ellipsoid(fit)) => {
                Some((fit.calibration.hard_iron_ut, "ellipsoid"))
            }
            _ => None,
        };
        if let Some((hard_iron_ut, model)) = fitted {
            let _ = writeln!(
                text,
                "    {}: {} ({model}), minus the device's {}",
                method.label,
                vector(&hard_iron_ut),
                vector(&(hard_iron_ut - device.mean_ut))
            );
        }
    }
}

/// The heading error table: uncalibrated, then each method (or why it was not fitted),
/// then the best.
fn write_heading_errors(text: &mut String, report: &CalibrationReport) {
    let _ = writeln!(
        text,
        "  {:<26} {:>17} {:>17} {:>10}",
        "heading error (RMS)", "train", "check", "check p95"
    );
    text.push_str(&heading_error_row(
        "uncalibrated",
        report.raw_heading_error_train,
        report.raw_heading_error_check,
    ));
    for method in &report.methods {
        match &method.error {
            None => text.push_str(&heading_error_row(
                method.label,
                method.heading_error_train,
                method.heading_error_check,
            )),
            Some(error) => {
                let _ = writeln!(text, "  {:<26} not fitted: {error}", method.label);
            }
        }
    }
    if let Some(choice) = &report.choice {
        let _ = writeln!(text, "  best: {}", choice.sentence());
    }
}

/// One row of the heading error table: RMS (mean) on train and check, and the check's P95.
fn heading_error_row(
    label: &str,
    train: Option<HeadingErrorStats>,
    check: Option<HeadingErrorStats>,
) -> String {
    let cell = |stats: Option<HeadingErrorStats>| {
        stats.map_or("—".to_string(), |stats| {
            format!("{:.2}° ({:+.2}°)", stats.rms_deg, stats.mean_deg)
        })
    };
    format!(
        "  {label:<26} {:>17} {:>17} {:>10}\n",
        cell(train),
        cell(check),
        check.map_or("—".to_string(), |stats| format!(
            "{:.2}°",
            stats.p95_abs_deg
        ))
    )
}

/// An autopilot log's compasses whose parameters in force are kept, as a sentence for
/// the refusal: what the vehicle flies with is the answer then.
fn kept_parameters(report: &CalibrationReport) -> String {
    let Some(autopilot) = report.autopilot.as_ref() else {
        return String::new();
    };
    let kept: Vec<String> = autopilot
        .compasses
        .iter()
        .filter(|compass| !compass.is_written())
        .map(|compass| compass.sentence.clone())
        .collect();
    if kept.is_empty() {
        return String::new();
    }
    format!(" {}.", kept.join("; "))
}
