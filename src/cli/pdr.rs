//! `compass-pdr pdr` (the track, its figures and exports) and `compass-pdr report` (the
//! page's analysis as one HTML file).

use std::fmt::Write as _;
use std::path::Path;

use super::args::ImportArgs;
use super::inspect::{import_paths, print_import_diagnostics};
use super::{print_out, print_report};
use compass_pdr::pdr::export::{track_text, TrackFormat};
use compass_pdr::pdr::metrics::PositionErrors;
use compass_pdr::pdr::{PdrOptions, PdrReport};
use compass_pdr::pipeline;
use compass_pdr::present::plot::draw_pdr_figure;
use compass_pdr::present::report::{html_report, svg_figures};
use plotters::prelude::{IntoDrawingArea, SVGBackend};

pub(super) fn run_report(
    input: &ImportArgs,
    options: &PdrOptions,
    out: &Path,
) -> Result<(), String> {
    let report = import_paths(input)?;
    let file_name = report.file_name.clone();
    let analysis = pipeline::analyse(&report, options).map_err(|error| error.to_string())?;
    print_import_diagnostics(&file_name, &analysis.calibration.report.diagnostics);
    let pdr = match analysis.pdr {
        Some(Ok(pdr)) => Ok(pdr),
        Some(Err(error)) => Err(error.to_string()),
        None => Err("no dead reckoning was asked for".to_string()),
    };
    let (calibration, heading) = (&analysis.calibration, &analysis.headings);
    let figures = svg_figures(calibration, Some(heading), pdr.as_ref().ok());
    let html = html_report(
        calibration,
        Some(heading),
        pdr.as_ref().map_err(String::as_str),
        &figures,
    );
    std::fs::write(out, html).map_err(|error| format!("{}: {error}", out.display()))?;
    print_out(&format!(
        "{file_name}: report written to {}\n",
        out.display()
    ))
}

pub(super) fn run_pdr(
    input: &ImportArgs,
    options: &PdrOptions,
    json: bool,
    out: Option<&Path>,
    plot: Option<&Path>,
) -> Result<(), String> {
    let report = import_paths(input)?;
    print_import_diagnostics(&report.file_name, &report.diagnostics);
    let analysis = pipeline::dead_reckoning(&report, options).map_err(|error| error.to_string())?;
    if let Some(out) = out {
        let name = out.to_string_lossy();
        let format = TrackFormat::from_file_name(&name).ok_or_else(|| {
            format!("--out {name}: end the file name with .csv, .geojson or .gpx")
        })?;
        let text =
            track_text(&analysis, format).map_err(|error| format!("--out {name}: {error}"))?;
        std::fs::write(out, text).map_err(|error| format!("cannot write {name}: {error}"))?;
    }
    if let Some(plot) = plot {
        let root = SVGBackend::new(plot, (1400, 1000)).into_drawing_area();
        draw_pdr_figure(&root, &analysis)
            .map_err(|error| format!("{error} ({})", plot.display()))?;
    }
    print_report(&analysis.report, json, pdr_text)
}

/// The PDR result as the paper's tables: steps, the step model, and the errors.
pub(super) fn pdr_text(report: &PdrReport) -> String {
    let mut text = String::new();
    write_walk_summary(&mut text, report);
    write_position_errors(&mut text, report);
    for gap in report
        .gnss_gaps
        .iter()
        .filter(|gap| gap.position_error.is_none())
    {
        let _ = writeln!(
            text,
            "  {}",
            compass_pdr::present::report::gap_sentence(gap)
        );
    }
    write_step_errors(&mut text, report);
    for note in &report.notes {
        let _ = writeln!(text, "  note: {note}");
    }
    text
}

/// The report's first lines: the steps and distance, whether it was a walk, the step
/// model, the heading and the GNSS fixes.
fn write_walk_summary(text: &mut String, report: &PdrReport) {
    let _ = writeln!(
        text,
        "{}: {} steps in {} bouts over {:.0} s{}, {:.1} m dead-reckoned",
        report.file_name,
        report.n_steps,
        report.n_bouts,
        report.duration_s,
        report
            .mean_step_frequency_hz
            .map_or(String::new(), |hz| format!(" ({hz:.2} steps/s)")),
        report.pdr_distance_m
    );
    if let Some(not_a_walk) = compass_pdr::present::verdict::not_a_walk(report) {
        let _ = writeln!(text, "  note: {not_a_walk}");
    }
    let _ = writeln!(text, "  step model: {}", report.step_model.describe());
    let _ = writeln!(
        text,
        "  heading: {} ({})",
        report.heading_label, report.heading_key
    );
    match report.fixes.describe() {
        Some(fixes) => {
            let _ = writeln!(text, "  GNSS fixes: {fixes}");
        }
        None => {
            let _ = writeln!(text, "  GNSS: none in the log");
        }
    }
}

/// The position errors as a table: the whole walk, each simulated outage and each
/// stretch without GNSS that has a reference (no header without a row).
fn write_position_errors(text: &mut String, report: &PdrReport) {
    let gap_errors: Vec<&PositionErrors> = report
        .gnss_gaps
        .iter()
        .filter_map(|gap| gap.position_error.as_ref())
        .collect();
    if report.position_error.is_some()
        || !report.outage_position_errors.is_empty()
        || !gap_errors.is_empty()
    {
        let _ = writeln!(
            text,
            "  {:<26} {:>9} {:>10} {:>9} {:>8} {:>9} {:>8} {:>9} {:>9} {:>7}",
            "position error",
            "points",
            "distance",
            "RMS",
            "RMS",
            "max",
            "max",
            "distance",
            "P75",
            "in 2σ"
        );
    }
    if let Some(errors) = &report.position_error {
        write_position_row(text, "whole walk", errors);
    }
    for errors in &report.outage_position_errors {
        write_position_row(
            text,
            &format!("outage {:.0}-{:.0} s", errors.start_s, errors.end_s),
            errors,
        );
    }
    for errors in gap_errors {
        write_position_row(
            text,
            &format!("no GNSS {:.0}-{:.0} s", errors.start_s, errors.end_s),
            errors,
        );
    }
}

/// One row of the position error table.
fn write_position_row(text: &mut String, name: &str, errors: &PositionErrors) {
    let _ = writeln!(
        text,
        "  {name:<26} {:>5} pts {:>8.1} m {:>7.2} m {:>6.2} % {:>7.2} m {:>6.2} % {:>+7.2} % {:>7.2} m {:>5.0} %",
        errors.n_points,
        errors.distance_m,
        errors.rms_m,
        errors.rms_pct,
        errors.max_m,
        errors.max_pct,
        errors.distance_error_pct,
        errors.p75_m,
        errors.within_2_sigma_pct
    );
}

/// The step length and heading errors against the reference, and the loop closure.
fn write_step_errors(text: &mut String, report: &PdrReport) {
    if let Some(error) = &report.step_length_error_m {
        let _ = writeln!(
            text,
            "  step length error: {:+.3} ± {:.3} m over {} steps",
            error.mean, error.std, error.n
        );
    }
    if let Some(error) = &report.heading_error_deg {
        let _ = writeln!(
            text,
            "  heading error: {:+.2} ± {:.2}° over {} steps",
            error.mean, error.std, error.n
        );
    }
    if let Some(closure) = &report.loop_closure {
        let _ = writeln!(
            text,
            "  loop closure: {:.2} m, {:.2} % of {:.1} m",
            closure.gap_m, closure.gap_pct, closure.length_m
        );
    }
}
