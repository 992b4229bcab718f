//! `compass-pdr heading`: every heading method and model on one split, and the best.

use std::fmt::Write as _;
use std::path::Path;

use super::args::ImportArgs;
use super::inspect::{import_paths, print_import_diagnostics};
use super::print_report;
use compass_pdr::analysis::headings::{HeadingOptions, HeadingReport};
use compass_pdr::base::stats::HeadingErrorStats;
use compass_pdr::pipeline;
use compass_pdr::present::plot::draw_deviation_figure;
use plotters::prelude::{IntoDrawingArea, SVGBackend};

/// Where `heading` writes, besides its report.
pub(super) struct HeadingOutputs<'a> {
    pub json: bool,
    pub plot: Option<&'a Path>,
    pub attitude_out: Option<&'a Path>,
}

pub(super) fn run_heading(
    input: &ImportArgs,
    options: &HeadingOptions,
    outputs: &HeadingOutputs<'_>,
) -> Result<(), String> {
    let import = import_paths(input)?;
    let (calibration, analysis) =
        pipeline::headings(&import, options).map_err(|error| error.to_string())?;
    let report = &analysis.report;
    print_import_diagnostics(&report.file_name, &report.calibration.diagnostics);
    if let Some(path) = outputs.attitude_out {
        let text =
            pipeline::attitude_csv(&import, &calibration).map_err(|error| error.to_string())?;
        std::fs::write(path, text)
            .map_err(|error| format!("cannot write {}: {error}", path.display()))?;
    }
    let (json, plot) = (outputs.json, outputs.plot);
    if let Some(plot) = plot {
        let root = SVGBackend::new(plot, (1400, 1000)).into_drawing_area();
        draw_deviation_figure(&root, &analysis)
            .map_err(|error| format!("{error} ({})", plot.display()))?;
    }
    print_report(report, json, heading_text)
}

/// The heading comparison as a table, then each Fourier model as the paper's Table II.
pub(super) fn heading_text(report: &HeadingReport) -> String {
    let mut text = String::new();
    write_split_and_references(&mut text, report);
    write_method_table(&mut text, report);
    write_fourier_table(&mut text, report);
    write_learned_models(&mut text, report);
    for note in report.notes.iter().chain(&report.calibration.notes) {
        let _ = writeln!(text, "  note: {note}");
    }
    text
}

/// The report's first lines: the samples on each side of the split, the reference
/// heading and the declination.
fn write_split_and_references(text: &mut String, report: &HeadingReport) {
    let _ = writeln!(
        text,
        "{}: {} samples with a reference on train, {} on check{}",
        report.file_name,
        report.n_train_referenced,
        report.n_check_referenced,
        report
            .train_until_s
            .map_or(String::new(), |until_s| format!(
                ", split at {until_s:.1} s"
            ))
    );
    let _ = writeln!(
        text,
        "  reference heading: {}",
        report.reference_description.as_deref().unwrap_or("none")
    );
    let _ = writeln!(
        text,
        "  declination: {:.2}° ({})",
        report.calibration.declination.declination_deg, report.calibration.declination.source
    );
}

/// Each heading method's errors on train and check, a row each, and the best.
fn write_method_table(text: &mut String, report: &HeadingReport) {
    // The label column as wide as its longest label, so that the numbers line up.
    let width = report
        .rows
        .iter()
        .map(|row| row.label.chars().count())
        .max()
        .unwrap_or(0)
        .max(36);
    let _ = writeln!(
        text,
        "  {:<width$} {:>9} {:>16} {:>9} {:>9} {:>8}",
        "heading method", "train RMS", "check mean±std", "check RMS", "check p95", "±5°"
    );
    let cell = |stats: Option<HeadingErrorStats>, pick: fn(&HeadingErrorStats) -> String| {
        stats.as_ref().map_or("—".to_string(), pick)
    };
    for row in &report.rows {
        if let Some(error) = &row.error {
            let _ = writeln!(text, "  {:<width$} not fitted: {error}", row.label);
            continue;
        }
        let best = if report.choice.key == row.key {
            " ← best"
        } else {
            ""
        };
        let _ = writeln!(
            text,
            "  {:<width$} {:>9} {:>16} {:>9} {:>9} {:>8}{best}",
            row.label,
            cell(row.train, |stats| format!("{:.2}°", stats.rms_deg)),
            cell(row.check, |stats| format!(
                "{:.2}±{:.2}°",
                stats.mean_deg, stats.std_deg
            )),
            cell(row.check, |stats| format!("{:.2}°", stats.rms_deg)),
            cell(row.check, |stats| format!("{:.2}°", stats.p95_abs_deg)),
            cell(row.check, |stats| format!(
                "{:.0} %",
                stats.within_5_deg_pct
            )),
        );
    }
    let _ = writeln!(text, "  best: {}", report.choice.sentence());
}

/// The Fourier model fitted on each base, as the PDR paper's Table II (nothing without one).
fn write_fourier_table(text: &mut String, report: &HeadingReport) {
    if report.fourier.is_empty() {
        return;
    }
    let _ = writeln!(
        text,
        "  Fourier model on each base (train), as the PDR paper's Table II:\n  {:<36} {:>7} {:>7} {:>7} {:>7} {:>7} {:>14} {:>6}",
        "base", "A °", "B °", "C °", "D °", "E °", "resid mean±std", "±5°"
    );
    for fourier in &report.fourier {
        let model = fourier.fit.model;
        let _ = writeln!(
            text,
            "  {:<36} {:>7.2} {:>7.2} {:>7.2} {:>7.2} {:>7.2} {:>14} {:>5.0}%",
            fourier.base_label,
            model.a_deg,
            model.b_deg,
            model.c_deg,
            model.d_deg,
            model.e_deg,
            format!(
                "{:.2}±{:.2}°",
                fourier.fit.residual_mean_deg, fourier.fit.residual_std_deg
            ),
            fourier.fit.within_5_deg_pct
        );
    }
}

/// The neural networks' training, a line each, and the online (RLS) model's terms.
fn write_learned_models(text: &mut String, report: &HeadingReport) {
    for neural in &report.neural {
        let _ = writeln!(
            text,
            "  MLP on {}: inputs {}; {} pairs, {} hidden neurons, {} L-BFGS iterations ({:?}), train MSE {:.2} deg², \
             validation MSE {}",
            neural.base_label,
            neural.inputs.join(", "),
            neural.n_pairs,
            neural.n_hidden,
            neural.iterations,
            neural.stop,
            neural.train_mse_deg2,
            neural
                .validation_mse_deg2
                .map_or("—".to_string(), |mse| format!("{mse:.2} deg²"))
        );
    }
    if let Some(online) = &report.online {
        let model = online.model;
        let _ = writeln!(
            text,
            "  online on {} (RLS, memory {:.0} s, {} updates): A {:.2}° B {:.2}° C {:.2}° D {:.2}° E {:.2}°",
            online.base_label,
            online.memory_s, online.n_updates, model.a_deg, model.b_deg, model.c_deg, model.d_deg, model.e_deg
        );
    }
}
