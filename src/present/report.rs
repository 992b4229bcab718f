//! An analysis in words and files, shared by the page and the CLI: the device
//! calibration to export ([`device_export`]: in the sensor's own axes and units, and in
//! body axes and µT), the sentences the page shows and the HTML report repeats (the
//! context, the device calibration with its axes, unit and formula, the heading models,
//! the dead reckoning), the corrected data as CSV, and a self-contained HTML report
//! (no script, no remote resource) with the figures the caller gives it: SVG from
//! [`svg_figures`] in the CLI, the page's canvases as PNG.
//!
//! Pure: each function takes the analyses and returns text. Every piece of text that
//! comes from a log (file names, messages) is escaped before it goes into HTML
//! ([`escape_html`]).

use std::fmt::Write as _;

use plotters::prelude::*;

use serde::Serialize;
use thiserror::Error;

use crate::analysis::calibration::autopilot::AutopilotCalibration;
use crate::analysis::calibration::selection::WriteBackRefused;
use crate::analysis::calibration::{CalibrationAnalysis, CalibrationReport, Method};
use crate::analysis::headings::{HeadingAnalysis, HeadingReport};
use crate::fit::export::{CalibrationExport, SensorCalibration};
use crate::io::SensorFrame;
use crate::pdr::PdrAnalysis;
use crate::present::plot::{draw_calibration_figure, draw_deviation_figure, draw_pdr_figure};

// Counts are printed as the importers' notes print them.
pub use crate::io::thousands;

/// Where the reference, declination and expected field came from, and the split.
pub fn context_lines(report: &CalibrationReport) -> Vec<String> {
    let reference = report
        .reference
        .map_or_else(|| "none in the log".to_string(), |source| source.describe());
    let field = match &report.expected_field {
        Some(expected) => format!(
            "Field: {:.1} µT measured (raw), {:.1} µT expected, inclination {:.1}° ({})",
            report.mean_raw_field_ut, expected.total_ut, expected.inclination_deg, expected.model
        ),
        None => format!(
            "Field: {:.1} µT measured (raw); no model value without a position and a date",
            report.mean_raw_field_ut
        ),
    };
    let split = match report.train_until_s {
        Some(until_s) => format!(
            "Train on the first {until_s:.1} s ({} samples), check on the rest ({} samples)",
            report.n_train, report.n_check
        ),
        None => format!(
            "All {} samples train the methods (no reference to check against)",
            report.n_train
        ),
    };
    vec![
        format!("Reference heading: {reference}"),
        format!(
            "Declination: {:.2}° ({})",
            report.declination.declination_deg, report.declination.source
        ),
        field,
        split,
    ]
}

/// What was read from the log: its format, then one line per stream (samples, rate,
/// duration, unit, gaps).
pub fn stream_lines(format: &str, streams: &[crate::io::summary::StreamSummary]) -> Vec<String> {
    let mut lines = vec![format!("Format: {format}")];
    for stream in streams.iter().filter(|stream| stream.n_samples > 0) {
        let rate = stream
            .rate_hz
            .map_or(String::new(), |hz| format!(" at {hz:.1} Hz"));
        let gaps = match stream.n_gaps {
            0 => String::new(),
            1 => format!(", 1 gap (up to {:.1} s)", stream.largest_gap_s),
            n => format!(", {n} gaps (up to {:.1} s)", stream.largest_gap_s),
        };
        lines.push(format!(
            "{}: {} samples{rate} over {:.1} s, in {}{gaps}",
            stream.stream, stream.n_samples, stream.duration_s, stream.unit
        ));
    }
    lines
}

/// The calibration to store in a device, in both forms: in the magnetometer's own axes
/// and unit (what every export writes and a device applies to its raw readings) and in
/// body axes and µT (what the analysis fitted and uses itself).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DeviceExport {
    pub method: Method,
    /// In the raw values' axes and unit, as the log writes them.
    pub sensor: CalibrationExport,
    /// In body axes (x forward, y right, z down) and µT.
    pub body_ut: CalibrationExport,
    #[serde(skip)]
    pub calibration: SensorCalibration,
}

/// The device calibration the analysis chose
/// ([`CalibrationAnalysis::device_calibration`]), turned into the magnetometer's own axes
/// and unit with the importer's frame (body axes and µT where the import gave none),
/// where the rule every write-back follows lets it be written; `None` otherwise
/// ([`device_export_or_why`] says why).
pub fn device_export(analysis: &CalibrationAnalysis) -> Option<DeviceExport> {
    device_export_or_why(analysis).ok()
}

/// Why there is no device calibration to write back ([`device_export_or_why`]).
#[derive(Debug, Clone, PartialEq, Error)]
pub enum DeviceExportError {
    /// The rule every write-back follows refused it
    /// ([`crate::analysis::calibration::selection::device_write_back`]): an autopilot
    /// log, no 3D method fitted, not better than the readings as they are, outside a
    /// device's bounds.
    #[error(transparent)]
    NotWrittenBack(#[from] WriteBackRefused),
}

/// The device calibration to write back (JSON, C snippet, MotionCal packet) in the
/// sensor's own axes and unit, or why there is none: the rule every write-back follows,
/// [`crate::analysis::calibration::selection::device_write_back`].
pub fn device_export_or_why(
    analysis: &CalibrationAnalysis,
) -> Result<DeviceExport, DeviceExportError> {
    let (method, body_ut) = crate::analysis::calibration::selection::device_write_back(analysis)
        .map_err(DeviceExportError::NotWrittenBack)?;
    let frame = analysis
        .report
        .mag_frame
        .unwrap_or_else(SensorFrame::body_ut);
    let calibration = SensorCalibration::from_body(&body_ut, &frame);
    Ok(DeviceExport {
        method,
        sensor: CalibrationExport::from(&calibration),
        body_ut: CalibrationExport::body_ut(&body_ut),
        calibration,
    })
}

/// Decimals that show a field value in a unit of `ut_per_unit` µT to about 0.01 µT.
pub fn decimals_for_unit(ut_per_unit: f64) -> usize {
    if ut_per_unit.is_finite() && ut_per_unit > 0.0 {
        (2.0 + ut_per_unit.log10()).round().clamp(0.0, 8.0) as usize
    } else {
        2
    }
}

/// An autopilot log's compass calibration, compass by compass, against the parameters
/// in force: what `calibrate` prints, the page lists and the report holds. Each
/// compass's first line is the sentence its parameter file carries.
pub fn autopilot_calibration_lines(autopilot: &AutopilotCalibration) -> Vec<String> {
    let n_written = autopilot.written().count();
    let mut lines = vec![format!(
        "{} compass calibration, attitude-aided, judged against {}; {}",
        autopilot.autopilot,
        autopilot.earth.describe(),
        match (n_written, autopilot.autopilot) {
            (0, _) => "nothing written, the parameters in force are kept (why below)",
            (_, "PX4") => "its .params file loads in QGroundControl",
            _ => "its .param file loads in Mission Planner or MAVProxy",
        }
    )];
    for compass in &autopilot.compasses {
        lines.push(compass.sentence.clone());
        if compass.candidates.is_empty() {
            continue;
        }
        let candidates: Vec<String> = compass
            .candidates
            .iter()
            .map(|candidate| {
                let figure = candidate.check.map_or_else(
                    || "-".to_string(),
                    |score| format!("{:.1} mG", score.vector_rms_mg),
                );
                if candidate.refused.is_empty() {
                    format!("{} {figure}", candidate.model)
                } else {
                    format!(
                        "{} {figure} (refused: {})",
                        candidate.model,
                        candidate.refused.join(", ")
                    )
                }
            })
            .collect();
        lines.push(format!(
            "{}: vector error on the held-back second half of each model fitted on the first: {}; \
             parameters in force {}; the Earth's field turned in the body by {:.0}° and {:.0}° (1σ), \
             crossing {} of the sphere's 100 regions",
            compass.source,
            candidates.join(", "),
            compass
                .check
                .in_force
                .map_or_else(|| "-".to_string(), |score| format!("{:.1} mG", score.vector_rms_mg)),
            compass.turned_deg[0],
            compass.turned_deg[1],
            compass.coverage_regions
        ));
        if !compass.is_written() {
            continue;
        }
        let params: Vec<String> = compass
            .params
            .iter()
            .map(|(name, value)| format!("{name} {value:.4}"))
            .collect();
        let sigma = compass.offsets_sigma.unwrap_or([f64::NAN; 3]);
        lines.push(format!(
            "{} (formal 1σ: offsets ±{:.1}, {:.1}, {:.1} mG{}{})",
            params.join(", "),
            sigma[0],
            sigma[1],
            sigma[2],
            compass
                .soft_iron_sigma
                .map_or_else(String::new, |s| format!(", iron ±{s:.3}")),
            compass.motor_sigma.map_or_else(String::new, |s| format!(
                ", motor ±{:.2}, {:.2}, {:.2} mG/A",
                s[0], s[1], s[2]
            ))
        ));
    }
    lines.extend(autopilot.notes.iter().cloned());
    lines
}

/// The calibration to store in the device, as numbers a person can copy: in the
/// magnetometer's own axes and unit, with how to apply it, then (where they differ) the
/// MotionCal packet's µT and the analysis's own body axes.
pub fn device_calibration_lines(analysis: &CalibrationAnalysis) -> Vec<String> {
    // An autopilot's own parameters first: they are what its user loads.
    let mut lines = analysis
        .report
        .autopilot
        .as_ref()
        .map(autopilot_calibration_lines)
        .unwrap_or_default();
    lines.extend(sensor_calibration_lines(analysis));
    lines
}

/// The 3D calibration in the sensor's own axes and unit.
fn sensor_calibration_lines(analysis: &CalibrationAnalysis) -> Vec<String> {
    let export = match device_export_or_why(analysis) {
        Ok(export) => export,
        Err(why) => return vec![format!("No device calibration: {why}.")],
    };
    let calibration = &export.calibration;
    let frame = &calibration.frame;
    let unit = frame.unit.name;
    let decimals = decimals_for_unit(frame.unit.factor());
    let vector = |v: &nalgebra::Vector3<f64>, decimals: usize| {
        format!(
            "({:.decimals$}, {:.decimals$}, {:.decimals$})",
            v.x, v.y, v.z
        )
    };
    let soft = calibration.soft_iron;
    let mut lines = vec![
        format!(
            "From the {} method, in the magnetometer's own axes and unit: {}, raw values in {}",
            export.method.label(),
            frame.axes,
            frame.unit.label()
        ),
        "Apply it to every raw reading as the log writes it: corrected = S · (raw − h), S row by row"
            .to_string(),
        format!("Hard iron {} {unit}", vector(&calibration.hard_iron, decimals)),
        format!(
            "Soft iron [[{:.4}, {:.4}, {:.4}], [{:.4}, {:.4}, {:.4}], [{:.4}, {:.4}, {:.4}]]",
            soft[(0, 0)],
            soft[(0, 1)],
            soft[(0, 2)],
            soft[(1, 0)],
            soft[(1, 1)],
            soft[(1, 2)],
            soft[(2, 0)],
            soft[(2, 1)],
            soft[(2, 2)]
        ),
        format!("Field {:.decimals$} {unit} after correction", calibration.field),
    ];
    match (frame.unit.ut_per_unit, calibration.in_ut()) {
        (Some(ut_per_unit), Some(in_ut)) if ut_per_unit != 1.0 => lines.push(format!(
            "The same in µT, as MotionCal's packet carries it (same axes): hard iron {} µT, field {:.2} µT",
            vector(&in_ut.hard_iron_ut, 2),
            in_ut.field_ut
        )),
        (None, _) => lines.push(format!(
            "The log gives no µT per unit for its {unit}, so the calibration, its field strength \
             and the fits are in {unit}, and there is no MotionCal packet (its floats are µT)"
        )),
        _ => {}
    }
    if !frame.is_body_ut() {
        if let Some((_, body_ut)) = analysis.device_calibration() {
            // Raw counts of unknown sensitivity were fitted as they are.
            let fitted_unit = if frame.unit.ut_per_unit.is_some() {
                "µT"
            } else {
                unit
            };
            lines.push(format!(
                "In body axes (x forward, y right, z down) and {fitted_unit}, as the analysis fitted it: hard iron {} {fitted_unit}",
                vector(&body_ut.hard_iron_ut, 2)
            ));
        }
    }
    lines
}

/// The Fourier deviation models as the PDR paper's Table II, the networks, the online
/// model and the notes.
pub fn deviation_model_lines(report: &HeadingReport) -> Vec<String> {
    let models = report.fourier.iter().map(|fourier| {
        let model = fourier.fit.model;
        format!(
            "{}: A {:.2}°, B {:.2}°, C {:.2}°, D {:.2}°, E {:.2}°; residuals {:.2} ± {:.2}°, {:.0} % within ±5° (train)",
            fourier.base_label,
            model.a_deg,
            model.b_deg,
            model.c_deg,
            model.d_deg,
            model.e_deg,
            fourier.fit.residual_mean_deg,
            fourier.fit.residual_std_deg,
            fourier.fit.within_5_deg_pct
        )
    });
    let neural = report.neural.iter().map(|neural| {
        format!(
            "MLP on {}: inputs {}; {} one-second pairs, {} logistic neurons, {} L-BFGS iterations, train MSE {:.2} deg²",
            neural.base_label,
            neural.inputs.join(", "),
            neural.n_pairs,
            neural.n_hidden,
            neural.iterations,
            neural.train_mse_deg2
        )
    });
    let online = report.online.iter().map(|online| {
        let model = online.model;
        format!(
            "Online on {} (recursive least squares, memory {:.0} s, {} updates): A {:.2}°, B {:.2}°, C {:.2}°, D {:.2}°, E {:.2}°",
            online.base_label,
            online.memory_s,
            online.n_updates,
            model.a_deg,
            model.b_deg,
            model.c_deg,
            model.d_deg,
            model.e_deg
        )
    });
    models
        .chain(neural)
        .chain(online)
        .chain(report.notes.iter().cloned())
        .collect()
}

/// The dead reckoning as the paper reports it, a line each.
pub fn pdr_summary_lines(analysis: &PdrAnalysis) -> Vec<String> {
    let report = &analysis.report;
    let mut lines = vec![format!(
        "{} {} in {} {}{}; {:.1} m dead-reckoned over {:.0} s.",
        report.n_steps,
        crate::base::words::plural(report.n_steps, "step", "steps"),
        report.n_bouts,
        crate::base::words::plural(report.n_bouts, "bout", "bouts"),
        report
            .mean_step_frequency_hz
            .map_or(String::new(), |hz| format!(" at {hz:.2} steps/s")),
        report.pdr_distance_m,
        report.duration_s
    )];
    if let Some(not_a_walk) = crate::present::verdict::not_a_walk(report) {
        lines.insert(0, not_a_walk);
    }
    lines.push(format!("Step model: {}.", report.step_model.describe()));
    lines.push(format!("Heading: {}.", report.heading_label));
    if let Some(errors) = &report.position_error {
        lines.push(format!(
            "Position error at {} reference points: RMS {:.2} m ({:.2} % of {:.0} m), max {:.2} m; distance error {:+.1} %.",
            errors.n_points,
            errors.rms_m,
            errors.rms_pct,
            errors.distance_m,
            errors.max_m,
            errors.distance_error_pct
        ));
    }
    if let Some(fixes) = report.fixes.describe() {
        lines.push(format!("GNSS fixes: {fixes}."));
    }
    for errors in &report.outage_position_errors {
        lines.push(format!(
            "In the outage {:.0}-{:.0} s: RMS {:.2} m ({:.2} % of {:.0} m), max {:.2} m.",
            errors.start_s,
            errors.end_s,
            errors.rms_m,
            errors.rms_pct,
            errors.distance_m,
            errors.max_m
        ));
    }
    for gap in &report.gnss_gaps {
        lines.push(gap_sentence(gap));
    }
    if let Some(error) = &report.step_length_error_m {
        lines.push(format!(
            "Step length error: {:+.3} ± {:.3} m over {} steps.",
            error.mean, error.std, error.n
        ));
    }
    if let Some(error) = &report.heading_error_deg {
        lines.push(format!(
            "Heading error: {:+.2} ± {:.2}° over {} steps.",
            error.mean, error.std, error.n
        ));
    }
    lines.extend(report.notes.iter().cloned());
    lines
}

/// What the dead reckoning did across a span without GNSS, as a sentence.
pub fn gap_sentence(gap: &crate::pdr::GnssGap) -> String {
    let head = format!(
        "No GNSS fix from {:.0} to {:.0} s ({:.0} s): dead reckoning alone carried the track {:.1} m",
        gap.start_s,
        gap.end_s,
        gap.end_s - gap.start_s,
        gap.pdr_distance_m
    );
    match &gap.position_error {
        Some(errors) => format!(
            "{head}, with an error of RMS {:.2} m, max {:.2} m ({:.2} % of the {:.0} m walked).",
            errors.rms_m, errors.max_m, errors.max_pct, errors.distance_m
        ),
        None => format!("{head}."),
    }
}

/// The corrected data, one row per magnetometer sample used: time, the levelled field
/// raw and corrected, the raw heading, each method's heading, the reference heading, and
/// |B| raw and corrected. Empty cells where a value does not exist.
pub fn corrected_csv(analysis: &CalibrationAnalysis) -> String {
    let mut text = String::from(
        "t_s,level_raw_x_ut,level_raw_y_ut,level_corrected_x_ut,level_corrected_y_ut,raw_heading_deg",
    );
    for (method, _) in &analysis.headings_deg {
        let _ = write!(text, ",{}_heading_deg", method.key());
    }
    text.push_str(",ref_heading_deg,field_raw_ut,field_corrected_ut\n");
    let cell = |value: Option<&f64>, decimals: usize| -> String {
        value
            .filter(|value| value.is_finite())
            .map_or(String::new(), |value| format!("{value:.decimals$}"))
    };
    for (idx, t_s) in analysis.t_s.iter().enumerate() {
        let raw = analysis.level_raw_ut.get(idx);
        let corrected = analysis.level_corrected_ut.get(idx);
        let _ = write!(
            text,
            "{t_s:.3},{},{},{},{},{}",
            cell(raw.map(|v| &v.x), 3),
            cell(raw.map(|v| &v.y), 3),
            cell(corrected.map(|v| &v.x), 3),
            cell(corrected.map(|v| &v.y), 3),
            cell(analysis.raw_heading_deg.get(idx), 2)
        );
        for (_, headings) in &analysis.headings_deg {
            let _ = write!(text, ",{}", cell(headings.get(idx), 2));
        }
        let reference = analysis.ref_heading_deg.get(idx).and_then(Option::as_ref);
        let _ = writeln!(
            text,
            ",{},{},{}",
            cell(reference, 2),
            cell(analysis.field_raw_ut.get(idx), 3),
            cell(analysis.field_corrected_ut.get(idx), 3)
        );
    }
    text
}

/// `&`, `<`, `>`, `"` and `'` as entities, so that text from a log stays text.
pub fn escape_html(text: &str) -> String {
    let mut escaped = String::with_capacity(text.len());
    for character in text.chars() {
        match character {
            '&' => escaped.push_str("&amp;"),
            '<' => escaped.push_str("&lt;"),
            '>' => escaped.push_str("&gt;"),
            '"' => escaped.push_str("&quot;"),
            '\'' => escaped.push_str("&#39;"),
            other => escaped.push(other),
        }
    }
    escaped
}

/// A figure for the report: its HTML (an inline `<svg>`, or an `<img>` of a PNG data
/// URL, made by the caller from its own drawing) and a caption.
#[derive(Debug, Clone, PartialEq)]
pub struct ReportFigure {
    /// Which section it goes in.
    pub section: ReportSection,
    pub html: String,
}

/// The report's sections that carry figures.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ReportSection {
    /// The answer's picture, under the verdict.
    Answer,
    Calibration,
    HeadingModels,
    DeadReckoning,
}

/// The report's figures drawn as inline SVG by this crate's plots (the CLI and the
/// tests; the page passes its canvases as PNG instead, so that the browser module
/// carries one drawing backend).
pub fn svg_figures(
    calibration: &CalibrationAnalysis,
    heading: Option<&HeadingAnalysis>,
    pdr: Option<&PdrAnalysis>,
) -> Vec<ReportFigure> {
    let mut figures = Vec::new();
    if let Some(heading) = heading {
        let verdict = crate::present::verdict::verdict(
            calibration,
            &heading.report,
            pdr.map(|pdr| &pdr.report),
        );
        figures.push(ReportFigure {
            section: ReportSection::Answer,
            html: svg_figure((900, 500), |area| {
                crate::present::plot::answer::draw_answer_picture(
                    area,
                    &verdict,
                    (calibration, Some(heading)),
                    pdr,
                )
                .map(|_| ())
            }),
        });
    }
    figures.push(ReportFigure {
        section: ReportSection::Calibration,
        html: svg_figure((1500, 450), |area| {
            draw_calibration_figure(area, calibration)
        }),
    });
    if let Some(heading) = heading {
        figures.push(ReportFigure {
            section: ReportSection::HeadingModels,
            html: svg_figure((1500, 450), |area| draw_deviation_figure(area, heading)),
        });
    }
    if let Some(pdr) = pdr {
        figures.push(ReportFigure {
            section: ReportSection::DeadReckoning,
            html: svg_figure((1500, 450), |area| draw_pdr_figure(area, pdr)),
        });
    }
    figures
}

/// A figure drawn to an SVG string, or a sentence saying why it could not be.
fn svg_figure(
    size: (u32, u32),
    draw: impl FnOnce(
        &DrawingArea<SVGBackend<'_>, plotters::coord::Shift>,
    ) -> Result<(), crate::present::plot::PlotError>,
) -> String {
    let mut svg = String::new();
    let result = {
        let area = SVGBackend::with_string(&mut svg, size).into_drawing_area();
        let drawn = draw(&area);
        drawn.and_then(|()| {
            area.present()
                .map_err(|error| crate::present::plot::PlotError {
                    plot: "report",
                    reason: error.to_string(),
                })
        })
    };
    match result {
        Ok(()) => svg,
        Err(error) => format!("<p>{}</p>", escape_html(&error.to_string())),
    }
}

fn list(items: &[String]) -> String {
    let mut html = String::from("<ul>\n");
    for item in items {
        let _ = writeln!(html, "<li>{}</li>", escape_html(item));
    }
    html.push_str("</ul>\n");
    html
}

/// The verdict ([`crate::present::verdict`]) as the report's opening section.
pub fn verdict_html(verdict: &crate::present::verdict::Verdict) -> String {
    let mut html = format!(
        "<section class=\"verdict\" data-grade=\"{}\">\n<p><strong>{}</strong></p>\n<h2>{}</h2>\n<p>{}</p>\n<dl>\n",
        verdict.grade.key(),
        escape_html(verdict.grade.word()),
        escape_html(&verdict.headline),
        escape_html(&verdict.method)
    );
    for figure in &verdict.figures {
        let _ = writeln!(
            html,
            "<dt>{}</dt><dd>{}</dd>",
            escape_html(&figure.label),
            escape_html(&figure.value)
        );
    }
    html.push_str("</dl>\n");
    if !verdict.to_do.is_empty() {
        html.push_str(&list(&verdict.to_do));
    }
    let _ = writeln!(html, "<p>{}</p>\n</section>", escape_html(&verdict.read));
    html
}

/// A self-contained HTML page of the analysis: the context, the comparison table, the
/// device calibration, the heading models, the dead reckoning, the notes and the
/// figures. No script, no remote resource. `pdr` is the dead reckoning or the sentence
/// saying why there is none.
pub fn html_report(
    calibration: &CalibrationAnalysis,
    heading: Option<&HeadingAnalysis>,
    pdr: Result<&PdrAnalysis, &str>,
    figures: &[ReportFigure],
) -> String {
    let figures_of = |section: ReportSection| -> String {
        figures
            .iter()
            .filter(|figure| figure.section == section)
            .map(|figure| format!("<figure>{}</figure>\n", figure.html))
            .collect()
    };
    let report = &calibration.report;
    let file_name = escape_html(&report.file_name);
    let mut html = format!(
        "<!doctype html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n\
         <meta http-equiv=\"Content-Security-Policy\" content=\"default-src 'none'; style-src 'unsafe-inline'; img-src data:\">\n\
         <title>compass-pdr report: {file_name}</title>\n<style>\n\
         body {{ font-family: system-ui, sans-serif; max-width: 1500px; margin: 0 auto; padding: 1rem; color: #1d2430; }}\n\
         table {{ border-collapse: collapse; }} th, td {{ padding: 0.2rem 0.7rem; border-bottom: 1px solid #dde2ea; text-align: right; }}\n\
         th[scope=row] {{ text-align: left; }} svg, img {{ max-width: 100%; height: auto; }} figure {{ margin: 0.5rem 0; }}\n\
         </style>\n</head>\n<body>\n<h1>compass-pdr report: {file_name}</h1>\n\
         <p>{} ({} magnetometer samples used of {}).</p>\n",
        escape_html(report.format),
        report.n_samples_used,
        report.n_mag_samples
    );
    if let Some(heading) = heading {
        // The answer first, as the page's summary gives it.
        let verdict = crate::present::verdict::verdict(
            calibration,
            &heading.report,
            pdr.ok().map(|pdr| &pdr.report),
        );
        html.push_str(&verdict_html(&verdict));
        html.push_str(&figures_of(ReportSection::Answer));
    }
    if let Some(choice) = &report.choice {
        // The analysis's one best (the page's status line and the CLI's `best:`).
        let _ = writeln!(
            html,
            "<p><strong>Best: {}.</strong></p>",
            escape_html(&choice.sentence())
        );
    }
    html.push_str("<h2>Context</h2>\n");
    html.push_str(&list(&context_lines(report)));
    if let Some(heading) = heading {
        html.push_str(
            "<h2>Heading error against the reference</h2>\n<table>\n<thead><tr><th scope=\"col\">method</th>\
             <th scope=\"col\">train RMS</th><th scope=\"col\">check RMS</th><th scope=\"col\">check mean</th>\
             <th scope=\"col\">check std</th><th scope=\"col\">check 95th pct |error|</th>\
             <th scope=\"col\">check within ±5°</th></tr></thead>\n<tbody>\n",
        );
        let format = |value: Option<f64>, unit: &str| {
            value.map_or("—".to_string(), |value| format!("{value:.2}{unit}"))
        };
        for row in &heading.report.rows {
            let _ = write!(
                html,
                "<tr><th scope=\"row\">{}</th>",
                escape_html(&row.label)
            );
            match &row.error {
                Some(error) => {
                    let _ = write!(html, "<td colspan=\"6\">{}</td>", escape_html(error));
                }
                None => {
                    let (train, check) = (row.train, row.check);
                    for cell in [
                        format(train.map(|stats| stats.rms_deg), "°"),
                        format(check.map(|stats| stats.rms_deg), "°"),
                        format(check.map(|stats| stats.mean_deg), "°"),
                        format(check.map(|stats| stats.std_deg), "°"),
                        format(check.map(|stats| stats.p95_abs_deg), "°"),
                        format(check.map(|stats| stats.within_5_deg_pct), " %"),
                    ] {
                        let _ = write!(html, "<td>{cell}</td>");
                    }
                }
            }
            html.push_str("</tr>\n");
        }
        html.push_str("</tbody>\n</table>\n");
    }
    html.push_str("<h2>Device calibration</h2>\n");
    html.push_str(&list(&device_calibration_lines(calibration)));
    html.push_str(&figures_of(ReportSection::Calibration));
    if let Some(heading) = heading {
        html.push_str("<h2>Heading error models</h2>\n");
        html.push_str(&list(&deviation_model_lines(&heading.report)));
        html.push_str(&figures_of(ReportSection::HeadingModels));
    }
    html.push_str("<h2>Dead reckoning</h2>\n");
    match pdr {
        Ok(pdr) => {
            html.push_str(&list(&pdr_summary_lines(pdr)));
            html.push_str(&figures_of(ReportSection::DeadReckoning));
        }
        Err(reason) => {
            let _ = writeln!(html, "<p>{}</p>", escape_html(reason));
        }
    }
    html.push_str("<h2>Notes</h2>\n");
    html.push_str(&list(&report.notes));
    let _ = writeln!(
        html,
        "<p>{} {} of the log {} skipped or suspect; the page and <code>compass-pdr inspect</code> list them.</p>",
        report.diagnostics.total(),
        crate::base::words::plural(report.diagnostics.total(), "line", "lines"),
        crate::base::words::plural(report.diagnostics.total(), "was", "were")
    );
    html.push_str("</body>\n</html>\n");
    html
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::calibration::CalibrationOptions;
    use crate::analysis::headings::{compare, HeadingOptions};
    use crate::pipeline::calibrate_file;
    use crate::sim::walk::{simulate, WalkConfig};

    #[test]
    fn the_device_calibration_is_shown_in_the_board_s_axes_and_unit_with_the_formula() {
        use crate::sim::dance::{motioncal_raw_lines, DanceConfig};
        let (text, truth) = motioncal_raw_lines(&DanceConfig::from_seed(5, 60.0));
        let analysis = calibrate_file("dance.txt", text.as_bytes(), &CalibrationOptions::default())
            .expect("the dance calibrates");
        let lines = device_calibration_lines(&analysis);
        assert!(
            lines[0].contains("the sensor's own x, y, z as printed")
                && lines[0].contains("raw values in MotionCal count (0.1 µT)"),
            "{lines:?}"
        );
        assert!(lines[1].contains("corrected = S · (raw − h)"), "{lines:?}");
        // The hard iron in counts along the board's axes: ten times the truth's µT.
        let shown: Vec<f64> = lines[2]
            .trim_start_matches("Hard iron (")
            .trim_end_matches(") MotionCal count")
            .split(", ")
            .filter_map(|value| value.parse().ok())
            .collect();
        assert_eq!(shown.len(), 3, "{}", lines[2]);
        for (shown, truth_ut) in shown.iter().zip(truth.hard_iron_ut) {
            assert!(
                (shown - 10.0 * truth_ut).abs() < 2.0,
                "{} vs {truth_ut} µT",
                lines[2]
            );
        }
        assert!(
            lines.iter().any(|line| line.starts_with("The same in µT")),
            "{lines:?}"
        );
        assert!(
            lines.iter().any(|line| line.starts_with("In body axes")),
            "{lines:?}"
        );
        let export = device_export(&analysis).expect("a device calibration");
        assert_eq!(export.sensor.unit, "MotionCal count");
        assert!((export.sensor.hard_iron[1] * 0.1 - truth.hard_iron_ut[1]).abs() < 0.2);
        assert!((export.body_ut.hard_iron[1] + truth.hard_iron_ut[1]).abs() < 0.2);
    }

    #[test]
    fn escaping_keeps_markup_from_a_log_as_text() {
        assert_eq!(
            escape_html("<script>alert('x')</script> & \"q\""),
            "&lt;script&gt;alert(&#39;x&#39;)&lt;/script&gt; &amp; &quot;q&quot;"
        );
    }

    #[test]
    fn the_csv_and_the_report_hold_the_analysis() {
        let csv = crate::io::canonical_csv::write(&simulate(&WalkConfig::from_seed(3, 120.0)));
        let analysis = calibrate_file(
            "<b>walk</b>.csv",
            csv.as_bytes(),
            &CalibrationOptions::default(),
        )
        .expect("a simulated walk calibrates");
        let corrected = corrected_csv(&analysis);
        let mut lines = corrected.lines();
        let header = lines.next().expect("a header");
        assert!(header.starts_with("t_s,level_raw_x_ut"), "{header}");
        assert!(header.contains("ellipse_heading_deg"), "{header}");
        let n_columns = header.split(',').count();
        let rows: Vec<&str> = lines.collect();
        assert_eq!(rows.len(), analysis.t_s.len());
        assert!(rows.iter().all(|row| row.split(',').count() == n_columns));

        let heading = compare(&analysis, &HeadingOptions::default());
        let figures = svg_figures(&analysis, Some(&heading), None);
        let html = html_report(
            &analysis,
            Some(&heading),
            Err("no steps in this log"),
            &figures,
        );
        assert!(html.contains("compass-pdr report: &lt;b&gt;walk&lt;/b&gt;.csv"));
        assert!(!html.contains("<b>walk"));
        assert!(!html.contains("<script"));
        assert!(html.matches("<svg").count() >= 3, "the figures are inline");
        // The answer's picture (here the heading error against the reference) comes
        // right under the verdict, before the context.
        let answer = html
            .find("Heading error against the reference heading")
            .expect("the picture");
        let verdict_end = html.find("</section>").expect("the verdict");
        let context = html.find("<h2>Context</h2>").expect("the context");
        assert!(
            verdict_end < answer && answer < context,
            "{verdict_end} {answer} {context}"
        );
        assert!(html.contains("<p>no steps in this log</p>"));
        for row in &heading.report.rows {
            assert!(html.contains(&escape_html(&row.label)), "{}", row.label);
        }
    }
}
