//! Putting one log's analysis into the DOM: the calibration (context, streams, device
//! calibration, notes, diagnostics, its plots), the heading models (the comparison
//! table, the deviation models, their plots), the dead reckoning (summary and plots),
//! the timeline, and errors in the place of all of them.
//!
//! The summary goes first, then the answer's picture and the lists, then the figures,
//! one per task. Where the analysis worker runs a job, its calibration and figures can
//! be shown before the job ends: the worker sends a copy when the calibration step is
//! done, and the page shows it after `EARLY_FIGURES_AFTER_MS` unless the job has
//! finished by then (so that a quick analysis's answer does not wait behind them); the
//! finished analysis does not draw those figures again.

use std::rc::Rc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use wasm_bindgen::JsCast;
use web_sys::HtmlCanvasElement;

use super::{yield_to_browser, Page, Results};
use crate::analysis::calibration::{CalibrationAnalysis, CalibrationReport};
use crate::analysis::headings::{HeadingAnalysis, HeadingReport};
use crate::analysis::levelled::AnalysisError;
use crate::io::ImportReport;
use crate::pdr::PdrAnalysis;
use crate::pipeline::Stage;
use crate::present::report;
use crate::web::canvas::{self, HeadingPlot, PdrPlot, Plot};
use crate::web::controls;

/// Diagnostics listed on the page at most; the rest are counted.
const MAX_DIAGNOSTICS_SHOWN: usize = 50;

impl Page {
    /// Shows a finished analysis of `import` (or why there is none): the answer first
    /// (the summary), then its picture and the lists of the calibration, the heading
    /// models and the dead reckoning (1-4 ms, in folded details: after a turn, so that
    /// the headline is painted without waiting for them), then their figures one at a
    /// time, the browser getting a turn between them (to paint, to answer input), so
    /// that no part of the drawing is a long task. A job started meanwhile (`cancel`
    /// set) stops the drawing: its own outcome follows. `stage`: where the analysis started, for the run counters.
    pub(super) async fn show_outcome(
        &self,
        outcome: Result<Results, AnalysisError>,
        import: Option<Arc<ImportReport>>,
        (stage, cancel): (Stage, &AtomicBool),
    ) {
        let results = match outcome {
            Ok(results) => results,
            Err(error) => return self.show_error(&error.to_string()),
        };
        *self.import.borrow_mut() = import.clone();
        self.n_shown.set(self.n_shown.get() + 1);
        // The calibration figures this job drew early are the same; the zooms were
        // reset when they were drawn (and may since have been changed by the user).
        let drawn_early = self.early_figures.take();
        if drawn_early.is_empty() {
            self.zooms.reset();
        }
        let answer = self.show_answer(&results);
        // The answer's picture and the lists (in the folded details below it) after a
        // turn: the headline is painted first.
        yield_to_browser().await;
        if cancel.load(Ordering::Acquire) {
            return;
        }
        self.draw_picture(&answer, &results);
        let status = self.show_lists(&results, import.as_deref(), &answer);
        *self.answer.borrow_mut() = Some(answer);
        for figure in FIGURES {
            if drawn_early.contains(&figure.canvas()) {
                continue;
            }
            yield_to_browser().await;
            if cancel.load(Ordering::Acquire) {
                return;
            }
            self.draw_figure(figure, &results);
        }
        self.keep_results(results);
        self.count_runs(stage);
        self.set_state("ready", &status);
    }

    /// A job's calibration while its heading models and dead reckoning still run (the
    /// analysis worker sends it): its lists and figures, a figure per task. Stops when
    /// the job is cancelled, when it is `finished` (its answer waits for this thread:
    /// the figures left are drawn after the summary) or when a finished analysis is
    /// being shown.
    pub(super) async fn show_calibrated(
        &self,
        import: &ImportReport,
        calibration: &CalibrationAnalysis,
        (cancel, finished): (&AtomicBool, &AtomicBool),
    ) {
        let n_shown = self.n_shown.get();
        let current = || {
            !cancel.load(Ordering::Acquire)
                && !finished.load(Ordering::Acquire)
                && self.n_shown.get() == n_shown
        };
        if !current() {
            return;
        }
        // A new log's figures start unzoomed.
        self.zooms.reset();
        self.show_calibration(calibration, Some(import));
        for figure in FIGURES {
            let Figure::Calibration(canvas, plot) = figure else {
                continue;
            };
            yield_to_browser().await;
            if !current() {
                return;
            }
            self.draw_calibration_figure(canvas, plot, calibration);
            self.early_figures.borrow_mut().push(canvas);
        }
    }

    fn draw_calibration_figure(
        &self,
        canvas: Canvas,
        plot: Plot,
        calibration: &CalibrationAnalysis,
    ) {
        let zoom = self.zooms.zoom_of(canvas);
        match canvas::draw(self.canvas(canvas), plot, calibration, zoom) {
            Ok(frame) => self.zooms.keep_frame(canvas, frame),
            Err(message) => {
                let _ = canvas::draw_message(
                    self.canvas(canvas),
                    &format!("This plot could not be drawn: {message}"),
                );
            }
        }
        self.mark_time("data-first-plot-ms");
    }

    /// The answer of `results` in the summary; returns it, for its picture and lists.
    fn show_answer(&self, results: &Results) -> crate::present::verdict::Verdict {
        let verdict = crate::present::verdict::verdict(
            &results.calibration,
            &results.heading.report,
            results.pdr.as_ref().ok().map(|pdr| &pdr.report),
        );
        self.show_verdict(Some(&verdict));
        self.mark_time("data-summary-ms");
        verdict
    }

    /// Every list of `results` below the summary; returns the status line.
    fn show_lists(
        &self,
        results: &Results,
        import: Option<&ImportReport>,
        verdict: &crate::present::verdict::Verdict,
    ) -> String {
        self.show_calibration(&results.calibration, import);
        let summary = self.show_heading_models(&results.calibration, &results.heading);
        self.show_dead_reckoning(&results.pdr);
        // The walk's steps as the summary counts them (none for a vehicle).
        match &verdict.steps {
            Some(steps) => format!("{summary} {steps}"),
            None => summary,
        }
    }

    /// Draws one figure of `results` on its canvas (a figure that cannot be drawn says
    /// why in its place; the dead reckoning's say why there is none).
    pub(super) fn draw_figure(&self, figure: Figure, results: &Results) {
        let drawn = match figure {
            Figure::Calibration(canvas, plot) => {
                return self.draw_calibration_figure(canvas, plot, &results.calibration)
            }
            Figure::Heading(canvas, plot) => {
                canvas::draw_heading(self.canvas(canvas), plot, &results.heading)
            }
            Figure::Pdr(canvas, plot) => match &results.pdr {
                Ok(pdr) => {
                    let zoom = self.zooms.zoom_of(canvas);
                    canvas::draw_pdr(self.canvas(canvas), plot, pdr, zoom)
                        .map(|frame| self.zooms.keep_frame(canvas, frame))
                }
                // Its message is drawn with the list (`show_dead_reckoning`).
                Err(_) => Ok(()),
            },
        };
        if let Err(message) = drawn {
            let canvas = self.canvas(figure.canvas());
            let _ =
                canvas::draw_message(canvas, &format!("This plot could not be drawn: {message}"));
        }
    }

    pub(super) fn canvas(&self, canvas: Canvas) -> &HtmlCanvasElement {
        match canvas {
            Canvas::Circle => &self.circle_canvas,
            Canvas::Heading => &self.heading_canvas,
            Canvas::Field => &self.field_canvas,
            Canvas::Deviation => &self.deviation_canvas,
            Canvas::Residuals => &self.residuals_canvas,
            Canvas::Online => &self.online_canvas,
            Canvas::Trajectory => &self.trajectory_canvas,
            Canvas::Steps => &self.steps_canvas,
            Canvas::PositionError => &self.position_error_canvas,
        }
    }

    /// Keeps the analysis for the exports and enables their buttons.
    pub(super) fn keep_results(&self, results: Results) {
        let results = Rc::new(results);
        let import = self.import();
        crate::web::exports::enable(
            &self.document,
            Some(&results),
            import.as_ref().map(|import| &import.recording),
        );
        *self.results.borrow_mut() = Some(results);
        self.show_timeline();
    }

    fn show_timeline(&self) {
        let Some(canvas) = self
            .document
            .get_element_by_id(controls::TIMELINE_ID)
            .and_then(|element| element.dyn_into::<HtmlCanvasElement>().ok())
        else {
            return;
        };
        let drawn = match self.timeline() {
            Some(timeline) => canvas::draw_timeline(&canvas, &timeline),
            None => canvas::draw_message(&canvas, "No log yet."),
        };
        if let Err(message) = drawn {
            let _ = canvas::draw_message(
                &canvas,
                &format!("The timeline could not be drawn: {message}"),
            );
        }
    }

    /// The calibration's context, device calibration, notes, diagnostics and plots.
    fn show_calibration(&self, analysis: &CalibrationAnalysis, import: Option<&ImportReport>) {
        let report = &analysis.report;
        self.body.set_attribute("data-file", &report.file_name).ok();
        self.set_text("result-file", &report.file_name);
        self.show_context(report);
        if let Some(import) = import {
            self.fill_list(
                "streams",
                report::stream_lines(
                    import.format,
                    &crate::io::summary::summarize(&import.recording),
                )
                .into_iter()
                .chain(import.mag_frame.map(|frame| frame.describe())),
            );
        }
        self.show_device_calibration(analysis);
        self.fill_list("notes", or_none(report.notes.iter().cloned()));
        self.show_diagnostics(report);
    }

    /// The heading models on top of the calibration: every method and every stack on
    /// the same split, the deviation curve and the residuals. Returns the status line.
    fn show_heading_models(
        &self,
        analysis: &CalibrationAnalysis,
        headings: &HeadingAnalysis,
    ) -> String {
        let report = &analysis.report;
        self.show_methods(&headings.report);
        self.show_deviation_model(&headings.report);
        let problems = match report.diagnostics.total() {
            0 => String::new(),
            1 => " 1 line had a problem; see below.".to_string(),
            n => format!(" {n} lines had problems; see below."),
        };
        // The answer (and the method, the CLI's `best:` sentence word for word) is in the
        // summary below; the status says what was done.
        // As the report says it: the samples used of those read (a sample without an
        // accelerometer sample near it cannot be levelled).
        let thousands = crate::io::thousands;
        let used = if report.n_samples_used == report.n_mag_samples {
            format!("{} magnetometer samples", thousands(report.n_samples_used))
        } else {
            format!(
                "{} of {} magnetometer samples used",
                thousands(report.n_samples_used),
                thousands(report.n_mag_samples)
            )
        };
        format!("Analysed {}: {used}.{problems}", report.file_name)
    }

    /// The dead reckoning's list; a log that cannot be dead-reckoned says why in its
    /// place and on its canvases (its figures are drawn with the others).
    fn show_dead_reckoning(&self, result: &Result<PdrAnalysis, String>) {
        match result {
            Ok(analysis) => self.fill_list(
                "pdr-summary",
                report::pdr_summary_lines(analysis).into_iter(),
            ),
            Err(message) => {
                let message = format!("No dead reckoning: {message}.");
                self.fill_list("pdr-summary", std::iter::once(message.clone()));
                for canvas in [Canvas::Trajectory, Canvas::Steps, Canvas::PositionError] {
                    let _ = canvas::draw_message(self.canvas(canvas), &message);
                }
            }
        }
    }

    /// Shows an error in the status area and on the canvases, and clears the figures of
    /// the previous file so that none of them is taken for this one's.
    pub(crate) fn show_error(&self, message: &str) {
        self.results.borrow_mut().take();
        crate::web::exports::enable(&self.document, None, None);
        self.show_verdict(None);
        self.body.remove_attribute("data-file").ok();
        self.set_text("result-file", "—");
        for id in [
            "streams",
            "context",
            "methods-body",
            "deviation-model",
            "pdr-summary",
            "calibration",
            "notes",
            "diagnostics",
        ] {
            self.fill_list(id, std::iter::empty());
        }
        for canvas in [
            &self.circle_canvas,
            &self.heading_canvas,
            &self.field_canvas,
            &self.deviation_canvas,
            &self.residuals_canvas,
            &self.online_canvas,
            &self.trajectory_canvas,
            &self.steps_canvas,
            &self.position_error_canvas,
        ] {
            let _ = canvas::draw_message(canvas, &format!("No plot: {message}"));
        }
        self.set_state("error", message);
    }

    /// Where the reference, declination and expected field came from, and the split.
    fn show_context(&self, report: &CalibrationReport) {
        self.fill_list("context", report::context_lines(report).into_iter());
    }

    /// The comparison table: one row per method, train and check heading errors.
    fn show_methods(&self, report: &HeadingReport) {
        let Some(body) = self.document.get_element_by_id("methods-body") else {
            return;
        };
        body.set_text_content(None);
        let rows = report.rows.iter().map(|row| {
            (
                row.key.text().replace('+', "-"),
                row.label.clone(),
                row.train,
                row.check,
                row.error.clone(),
            )
        });
        for (key, label, train, check, error) in rows {
            let Ok(row) = self.document.create_element("tr") else {
                continue;
            };
            row.set_id(&format!("row-{key}"));
            if report.choice.key.text().replace('+', "-") == key {
                let _ = row.class_list().add_1("best");
            }
            let Ok(header) = self.document.create_element("th") else {
                continue;
            };
            let _ = header.set_attribute("scope", "row");
            header.set_text_content(Some(&label));
            let _ = row.append_child(&header);
            match error {
                Some(error) => {
                    if let Ok(cell) = self.document.create_element("td") {
                        let _ = cell.set_attribute("colspan", "6");
                        let _ = cell.class_list().add_1("method-error");
                        cell.set_id(&format!("error-{key}"));
                        cell.set_text_content(Some(&crate::web::wording::for_page(&error)));
                        let _ = row.append_child(&cell);
                    }
                }
                None => {
                    let format = |value: Option<f64>, unit: &str| {
                        value.map_or("—".to_string(), |value| format!("{value:.2}{unit}"))
                    };
                    let cells = [
                        ("train-rms", format(train.map(|stats| stats.rms_deg), "°")),
                        ("check-rms", format(check.map(|stats| stats.rms_deg), "°")),
                        ("check-mean", format(check.map(|stats| stats.mean_deg), "°")),
                        ("check-std", format(check.map(|stats| stats.std_deg), "°")),
                        (
                            "check-p95",
                            format(check.map(|stats| stats.p95_abs_deg), "°"),
                        ),
                        (
                            "check-within5",
                            format(check.map(|stats| stats.within_5_deg_pct), " %"),
                        ),
                    ];
                    for (name, text) in cells {
                        if let Ok(cell) = self.document.create_element("td") {
                            cell.set_id(&format!("stat-{key}-{name}"));
                            cell.set_text_content(Some(&text));
                            let _ = row.append_child(&cell);
                        }
                    }
                }
            }
            let _ = body.append_child(&row);
        }
    }

    /// The Fourier deviation models as the PDR paper's Table II, and the online one.
    fn show_deviation_model(&self, report: &HeadingReport) {
        self.fill_list(
            "deviation-model",
            or_none(report::deviation_model_lines(report).into_iter()),
        );
    }

    /// The calibration to store in the device, as numbers a person can copy.
    fn show_device_calibration(&self, analysis: &CalibrationAnalysis) {
        self.fill_list(
            "calibration",
            report::device_calibration_lines(analysis).into_iter(),
        );
    }

    fn show_diagnostics(&self, report: &CalibrationReport) {
        let diagnostics = &report.diagnostics;
        let shown = diagnostics
            .kept
            .iter()
            .take(MAX_DIAGNOSTICS_SHOWN)
            .map(|diagnostic| {
                let file_name = diagnostic.file_name.as_deref().unwrap_or(&report.file_name);
                match diagnostic.line {
                    Some(line) => format!("{file_name}, line {line}: {}", diagnostic.message),
                    None => format!("{file_name}: {}", diagnostic.message),
                }
            });
        let n_not_shown = diagnostics.total().saturating_sub(MAX_DIAGNOSTICS_SHOWN);
        let more = (n_not_shown > 0)
            .then(|| format!("… and {n_not_shown} more (the CLI lists them all)."));
        self.fill_list("diagnostics", or_none(shown.chain(more)));
    }
}

/// The items, or a single "None." when there are none, so that an empty list reads as
/// checked rather than missing.
fn or_none(items: impl Iterator<Item = String>) -> impl Iterator<Item = String> {
    let mut items = items.peekable();
    let none = items.peek().is_none().then(|| "None.".to_string());
    items.chain(none)
}

/// The page's canvases.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Canvas {
    Circle,
    Heading,
    Field,
    Deviation,
    Residuals,
    Online,
    Trajectory,
    Steps,
    PositionError,
}

/// One figure: what is drawn on which canvas.
#[derive(Debug, Clone, Copy)]
pub(super) enum Figure {
    Calibration(Canvas, Plot),
    Heading(Canvas, HeadingPlot),
    Pdr(Canvas, PdrPlot),
}

impl Figure {
    pub(super) fn canvas(self) -> Canvas {
        match self {
            Figure::Calibration(canvas, _)
            | Figure::Heading(canvas, _)
            | Figure::Pdr(canvas, _) => canvas,
        }
    }
}

/// Every figure, in the page's order.
pub(super) const FIGURES: [Figure; 9] = [
    Figure::Calibration(Canvas::Circle, Plot::CircleFit),
    Figure::Calibration(Canvas::Heading, Plot::HeadingError),
    Figure::Calibration(Canvas::Field, Plot::FieldMagnitude),
    Figure::Heading(Canvas::Deviation, HeadingPlot::DeviationCurve),
    Figure::Heading(Canvas::Residuals, HeadingPlot::ResidualHistogram),
    Figure::Heading(Canvas::Online, HeadingPlot::OnlineConvergence),
    Figure::Pdr(Canvas::Trajectory, PdrPlot::Trajectory),
    Figure::Pdr(Canvas::Steps, PdrPlot::StepLengths),
    Figure::Pdr(Canvas::PositionError, PdrPlot::PositionError),
];

#[cfg(test)]
impl Page {
    /// The whole analysis at once (the browser tests use it).
    pub(crate) fn show_analysis(&self, results: &Results, import: Option<&ImportReport>) {
        let answer = self.show_answer(results);
        self.draw_picture(&answer, results);
        let status = self.show_lists(results, import, &answer);
        for figure in FIGURES {
            self.draw_figure(figure, results);
        }
        self.set_state("ready", &status);
    }
}
