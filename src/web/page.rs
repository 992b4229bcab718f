//! The page: element handles, event wiring, and putting results into the DOM.
//!
//! Log-derived text (file names, messages) is set with `textContent`, never as HTML.
//! The body's `data-state` attribute says where the page is (`loading`, `ready`,
//! `error`), for people using assistive technology (through the status region) and for
//! the end-to-end tests.

use std::rc::Rc;

use gloo::events::{EventListener, EventListenerOptions};
use wasm_bindgen::JsCast;
use wasm_bindgen_futures::{spawn_local, JsFuture};
use web_sys::{Document, DragEvent, Element, HtmlCanvasElement, HtmlElement, HtmlInputElement};

use super::canvas::{self, HeadingPlot, PdrPlot, Plot};
use super::chunks::ChunkReader;
use super::controls::{self, Stage};
use super::dom;
use super::mapping;
use crate::analysis::AnalysisError;
use crate::calibration::{CalibrationAnalysis, CalibrationReport};
use crate::deviation::{HeadingAnalysis, HeadingReport};
use crate::io::delimited::{preview, ColumnMapping, Preview};
use crate::io::import::import_files;
use crate::io::import::{header_signature, merge, ChunkedImport, FileImport};
use crate::io::{ImportError, ImportReport};
use crate::pdr::{PdrAnalysis, PdrError};
use crate::pipeline;
use crate::plot::timeline::Timeline;
use crate::report;

/// The ids of the elements the page must have (see `www/index.html`).
const STATUS_ID: &str = "status";
const FILE_INPUT_ID: &str = "file-input";
const DROP_ZONE_ID: &str = "drop-zone";
const CIRCLE_CANVAS_ID: &str = "plot-circle";
const HEADING_CANVAS_ID: &str = "plot-heading";
const FIELD_CANVAS_ID: &str = "plot-field";
const DEVIATION_CANVAS_ID: &str = "plot-deviation";
const RESIDUALS_CANVAS_ID: &str = "plot-residuals";
const ONLINE_CANVAS_ID: &str = "plot-online";
const TRAJECTORY_CANVAS_ID: &str = "plot-trajectory";
const STEPS_CANVAS_ID: &str = "plot-steps";
const POSITION_ERROR_CANVAS_ID: &str = "plot-position-error";
const PROGRESS_ID: &str = "progress";

/// Bytes read from a file at a time: small enough that the page answers between
/// chunks, large enough that the reads cost little.
pub(super) const CHUNK_BYTES: f64 = 4.0 * 1024.0 * 1024.0;

/// While a file is read, the browser gets a turn at least this often. (A chunk read
/// ahead is often ready when it is wanted, and awaiting it then gives the browser none.)
const YIELD_EVERY_MS: f64 = 40.0;

/// How much of a file's start is kept for the mapping dialog's preview.
const PREVIEW_BYTES: usize = 64 * 1024;

/// What reading one file gave.
struct ChunkedRead {
    result: Result<FileImport, ImportError>,
    first_chunk: Vec<u8>,
    used_remembered_mapping: bool,
}

/// The preview of delimited text from its first bytes.
fn preview_of(first_chunk: &[u8]) -> Option<Preview> {
    let mut lines = Vec::new();
    crate::io::lines::decode_all(first_chunk, 4096, |line| {
        if lines.len() < 20 {
            lines.push(line.text.into_owned());
        }
    });
    let sample: Vec<&str> = lines.iter().map(String::as_str).collect();
    preview(&sample)
}

/// Diagnostics listed on the page at most; the rest are counted.
const MAX_DIAGNOSTICS_SHOWN: usize = 50;

pub struct Page {
    pub(super) document: Document,
    body: HtmlElement,
    status: Element,
    file_input: HtmlInputElement,
    drop_zone: Element,
    circle_canvas: HtmlCanvasElement,
    heading_canvas: HtmlCanvasElement,
    field_canvas: HtmlCanvasElement,
    deviation_canvas: HtmlCanvasElement,
    residuals_canvas: HtmlCanvasElement,
    online_canvas: HtmlCanvasElement,
    trajectory_canvas: HtmlCanvasElement,
    steps_canvas: HtmlCanvasElement,
    position_error_canvas: HtmlCanvasElement,
    /// The latest analysis, for the exports; `None` before the first and after an error.
    results: std::cell::RefCell<Option<Rc<Results>>>,
    /// The latest log as imported, for re-running the analysis when a control changes.
    import: std::cell::RefCell<Option<Rc<ImportReport>>>,
    /// How many times the calibration and the dead reckoning ran (on the body as
    /// `data-calibration-runs` and `data-pdr-runs`, for the tests).
    n_calibration_runs: std::cell::Cell<u32>,
    n_pdr_runs: std::cell::Cell<u32>,
}

/// One log's analysis: what the exports write.
pub struct Results {
    pub calibration: CalibrationAnalysis,
    pub heading: HeadingAnalysis,
    /// The dead reckoning, or why there is none.
    pub pdr: Result<PdrAnalysis, String>,
}

impl Page {
    /// Finds the page's elements; the message names the first one missing.
    pub fn from_document() -> Result<Rc<Page>, String> {
        let document = web_sys::window()
            .and_then(|window| window.document())
            .ok_or("no document")?;
        let body = document.body().ok_or("the page has no body")?;
        let element = |id: &str| {
            document
                .get_element_by_id(id)
                .ok_or(format!("the page has no element #{id}"))
        };
        let canvas = |id: &str| {
            element(id)?
                .dyn_into::<HtmlCanvasElement>()
                .map_err(|_| format!("#{id} is not a canvas"))
        };
        Ok(Rc::new(Page {
            status: element(STATUS_ID)?,
            file_input: element(FILE_INPUT_ID)?
                .dyn_into::<HtmlInputElement>()
                .map_err(|_| format!("#{FILE_INPUT_ID} is not an input"))?,
            drop_zone: element(DROP_ZONE_ID)?,
            circle_canvas: canvas(CIRCLE_CANVAS_ID)?,
            heading_canvas: canvas(HEADING_CANVAS_ID)?,
            field_canvas: canvas(FIELD_CANVAS_ID)?,
            deviation_canvas: canvas(DEVIATION_CANVAS_ID)?,
            residuals_canvas: canvas(RESIDUALS_CANVAS_ID)?,
            online_canvas: canvas(ONLINE_CANVAS_ID)?,
            trajectory_canvas: canvas(TRAJECTORY_CANVAS_ID)?,
            steps_canvas: canvas(STEPS_CANVAS_ID)?,
            position_error_canvas: canvas(POSITION_ERROR_CANVAS_ID)?,
            body,
            document,
            results: std::cell::RefCell::new(None),
            import: std::cell::RefCell::new(None),
            n_calibration_runs: std::cell::Cell::new(0),
            n_pdr_runs: std::cell::Cell::new(0),
        }))
    }

    /// Wires the file input and the drop zone, then analyses the demo.
    pub fn start(self: Rc<Self>) {
        let page = Rc::clone(&self);
        EventListener::new(&self.file_input, "change", move |_| {
            let Some(files) = page.file_input.files() else {
                return;
            };
            page.analyse_files(files);
            // Choosing the same file again should analyse it again.
            page.file_input.set_value("");
        })
        .forget();

        // Without preventDefault on dragover and drop, the browser opens the file.
        let prevent_default = EventListenerOptions::enable_prevent_default();
        for event_name in ["dragover", "drop"] {
            EventListener::new_with_options(&self.document, event_name, prevent_default, |event| {
                event.prevent_default()
            })
            .forget();
        }
        let drop_zone = self.drop_zone.clone();
        EventListener::new(&self.drop_zone, "dragover", move |_| {
            let _ = drop_zone.class_list().add_1("dragging");
        })
        .forget();
        let drop_zone = self.drop_zone.clone();
        EventListener::new(&self.drop_zone, "dragleave", move |_| {
            let _ = drop_zone.class_list().remove_1("dragging");
        })
        .forget();
        let page = Rc::clone(&self);
        EventListener::new_with_options(&self.drop_zone, "drop", prevent_default, move |event| {
            event.prevent_default();
            let _ = page.drop_zone.class_list().remove_1("dragging");
            let files = event
                .dyn_ref::<DragEvent>()
                .and_then(DragEvent::data_transfer)
                .and_then(|transfer| transfer.files());
            match files {
                Some(files) if files.length() > 0 => page.analyse_files(files),
                _ => page.show_error(
                    "Nothing to read in what was dropped. Drop a CSV file from your computer.",
                ),
            }
        })
        .forget();

        spawn_local(async move { self.load_demo().await });
    }

    async fn load_demo(&self) {
        let Some(demo_url) = self.body.get_attribute("data-demo-url") else {
            self.set_state("ready", "Drop a log to analyse it.");
            return;
        };
        let file_name = demo_url.rsplit('/').next().unwrap_or(&demo_url).to_string();
        self.set_state("loading", &format!("Loading the demo log {file_name}…"));
        match fetch_bytes(&demo_url).await {
            Ok(bytes) => {
                self.analyse_and_show(&[(file_name.as_str(), bytes.as_slice())])
                    .await
            }
            Err(message) => self.show_error(&format!("Could not load the demo log {demo_url}: {message}. Drop a log to analyse it instead.")),
        }
    }

    /// Reads every file dropped or chosen, in chunks, and analyses them as one recording
    /// (phyphox writes one file per sensor). Each chunk is read asynchronously, so the
    /// page repaints and answers between chunks, and the progress bar moves.
    fn analyse_files(self: &Rc<Self>, files: web_sys::FileList) {
        let files: Vec<web_sys::File> = (0..files.length())
            .filter_map(|idx| files.get(idx))
            .collect();
        if !files.is_empty() {
            self.analyse_file_list(files, None);
        }
    }

    /// Reads the files in chunks and analyses them as one recording. `mapping` is the
    /// one the user just made in the mapping dialog; otherwise a remembered one is used
    /// for a header seen before.
    pub fn analyse_file_list(
        self: &Rc<Self>,
        files: Vec<web_sys::File>,
        mapping: Option<ColumnMapping>,
    ) {
        let page = Rc::clone(self);
        spawn_local(async move {
            let names: Vec<String> = files.iter().map(web_sys::File::name).collect();
            page.set_state("loading", &format!("Reading {}…", names.join(", ")));
            let total_bytes: f64 = files.iter().map(|file| file.size()).sum();
            let mut bytes_done = 0.0;
            let mut results = Vec::with_capacity(files.len());
            let mut first_chunks = Vec::with_capacity(files.len());
            let mut remembered_for = Vec::new();
            for (file, file_name) in files.iter().zip(&names) {
                let read = page
                    .read_in_chunks(
                        file,
                        file_name,
                        mapping.as_ref(),
                        &mut bytes_done,
                        total_bytes,
                    )
                    .await;
                match read {
                    Ok(read) => {
                        if read.used_remembered_mapping {
                            remembered_for.push(file_name.clone());
                        }
                        results.push((file_name.clone(), read.result));
                        first_chunks.push(read.first_chunk);
                    }
                    Err(message) => {
                        page.hide_progress();
                        page.show_error(&message);
                        return;
                    }
                }
            }
            page.hide_progress();
            page.set_state("loading", &format!("Analysing {}…", names.join(", ")));
            let merged = merge(results).map_err(AnalysisError::from);
            let (result, import) = page.calibrate_import(merged);
            // A single delimited file whose columns were not understood, or numbers
            // without a header line: ask the user.
            let unreadable_header = matches!(
                result,
                Err(AnalysisError::NoMagnetometerColumns { .. }
                    | AnalysisError::Import(
                        ImportError::UnknownHeader { .. } | ImportError::NoHeaderLine { .. }
                    ))
            );
            if let (true, [file], [first_chunk]) =
                (unreadable_header, files.as_slice(), first_chunks.as_slice())
            {
                if let Some(preview) = preview_of(first_chunk) {
                    let reason = result
                        .as_ref()
                        .err()
                        .map(ToString::to_string)
                        .unwrap_or_default();
                    page.show_error(&reason);
                    mapping::open_dialog(
                        &page,
                        file.clone(),
                        &preview,
                        &reason,
                        header_signature(first_chunk),
                    );
                    return;
                }
            }
            page.show_result(result, import).await;
            if !remembered_for.is_empty() {
                let status = page.status.text_content().unwrap_or_default();
                page.status.set_text_content(Some(&format!(
                    "{status} Read with your saved column mapping for {}.",
                    remembered_for.join(", ")
                )));
            }
        });
    }

    /// One file through a [`ChunkedImport`]; `Err` only when the browser cannot read it.
    /// The next chunk is read while this one is parsed ([`ChunkReader`]); the browser
    /// gets a turn (to paint the progress bar, to answer input) at least every
    /// [`YIELD_EVERY_MS`].
    async fn read_in_chunks(
        &self,
        file: &web_sys::File,
        file_name: &str,
        mapping: Option<&ColumnMapping>,
        bytes_done: &mut f64,
        total_bytes: f64,
    ) -> Result<ChunkedRead, String> {
        let mut reader = ChunkReader::new(file.clone().into(), CHUNK_BYTES);
        let size = reader.size();
        let mut import: Option<ChunkedImport> = None;
        let mut first_chunk = Vec::new();
        let mut used_remembered_mapping = false;
        let mut bytes = Vec::new();
        let mut last_turn_ms = now_ms();
        while let Some(read) = reader.next_into(&mut bytes).await {
            read.map_err(|error| {
                format!("Could not read {file_name}: {error}. Try choosing it again.")
            })?;
            let chunked = import.get_or_insert_with(|| {
                // The header is in the first chunk: it picks a remembered mapping.
                let signature = header_signature(&bytes);
                let remembered = match (mapping, &signature) {
                    (None, Some(signature)) => mapping::remembered(signature),
                    _ => None,
                };
                used_remembered_mapping = remembered.is_some();
                first_chunk = bytes
                    .get(..bytes.len().min(PREVIEW_BYTES))
                    .unwrap_or_default()
                    .to_vec();
                ChunkedImport::new(file_name, Some(size as usize))
                    .with_mapping(mapping.cloned().or(remembered))
            });
            if let Err(error) = chunked.feed(&bytes) {
                return Ok(ChunkedRead {
                    result: Err(error),
                    first_chunk,
                    used_remembered_mapping,
                });
            }
            *bytes_done += bytes.len() as f64;
            self.show_progress(*bytes_done / total_bytes.max(1.0), file_name);
            if now_ms() - last_turn_ms >= YIELD_EVERY_MS {
                yield_to_browser().await;
                last_turn_ms = now_ms();
            }
        }
        let result = match import {
            Some(import) => import.finish(),
            None => Err(ImportError::Empty {
                file_name: file_name.to_string(),
            }),
        };
        Ok(ChunkedRead {
            result,
            first_chunk,
            used_remembered_mapping,
        })
    }

    /// Shows the calibration, lets the browser breathe (paint, answer input), then
    /// learns and shows the heading models: two shorter blocks instead of one long one.
    /// Then, with the log's own import, dead-reckons the walk.
    async fn show_result(
        &self,
        result: Result<CalibrationAnalysis, AnalysisError>,
        import: Option<Rc<ImportReport>>,
    ) {
        match result {
            Ok(mut analysis) => {
                self.show_calibration(&analysis);
                yield_to_browser().await;
                let (summary, heading) = self.show_heading_models(&mut analysis);
                yield_to_browser().await;
                let (pdr_summary, pdr) = self.show_dead_reckoning(import.as_deref(), &heading);
                self.keep_results(Results {
                    calibration: analysis,
                    heading,
                    pdr,
                });
                self.set_state("ready", &format!("{summary}{pdr_summary}"));
            }
            Err(error) => self.show_error(&error.to_string()),
        }
    }

    /// Keeps the analysis for the exports and enables their buttons.
    fn keep_results(&self, results: Results) {
        let results = Rc::new(results);
        super::exports::enable(&self.document, Some(&results));
        *self.results.borrow_mut() = Some(results);
        self.show_timeline();
    }

    /// The latest analysis, if there is one.
    pub fn results(&self) -> Option<Rc<Results>> {
        self.results.borrow().clone()
    }

    fn show_progress(&self, fraction: f64, file_name: &str) {
        if let Some(progress) = self.document.get_element_by_id(PROGRESS_ID) {
            let _ = progress.set_attribute("value", &format!("{:.4}", fraction.clamp(0.0, 1.0)));
            let _ = progress.remove_attribute("hidden");
        }
        self.status.set_text_content(Some(&format!(
            "Reading {file_name}… {:.0} %",
            100.0 * fraction.clamp(0.0, 1.0)
        )));
    }

    fn hide_progress(&self) {
        if let Some(progress) = self.document.get_element_by_id(PROGRESS_ID) {
            let _ = progress.set_attribute("hidden", "");
        }
    }

    async fn analyse_and_show(&self, files: &[(&str, &[u8])]) {
        let imported = import_files(files).map_err(AnalysisError::from);
        let (result, import) = self.calibrate_import(imported);
        self.show_result(result, import).await;
    }

    /// Keeps the import for re-runs and runs the pipeline's calibration stage on it
    /// with the controls' options; also returns the kept import.
    fn calibrate_import(
        &self,
        imported: Result<ImportReport, AnalysisError>,
    ) -> (
        Result<CalibrationAnalysis, AnalysisError>,
        Option<Rc<ImportReport>>,
    ) {
        let import = match imported {
            Ok(report) => Rc::new(report),
            Err(error) => {
                *self.import.borrow_mut() = None;
                return (Err(error), None);
            }
        };
        *self.import.borrow_mut() = Some(Rc::clone(&import));
        let options = controls::read(&self.document).options();
        self.count_run(&self.n_calibration_runs, "data-calibration-runs");
        let result = pipeline::calibration(&import, &options.heading_options);
        (result, Some(import))
    }

    fn count_run(&self, counter: &std::cell::Cell<u32>, attribute: &str) {
        counter.set(counter.get() + 1);
        self.body
            .set_attribute(attribute, &counter.get().to_string())
            .ok();
    }

    /// Re-runs `stage` (and what follows it) on the kept import with the controls'
    /// current values.
    pub fn rerun(self: &Rc<Self>, stage: Stage) {
        let Some(import) = self.import.borrow().clone() else {
            return;
        };
        let page = Rc::clone(self);
        spawn_local(async move {
            let file_name = import.file_name.clone();
            page.set_state("loading", &format!("Analysing {file_name} again…"));
            yield_to_browser().await;
            let previous = page.results.borrow_mut().take();
            match (stage, previous.map(Rc::try_unwrap)) {
                (Stage::DeadReckoning, Some(Ok(results))) => {
                    let (pdr_summary, pdr) =
                        page.show_dead_reckoning(Some(&import), &results.heading);
                    let summary = format!(
                        "Dead-reckoned {file_name} again with the new settings.{pdr_summary}"
                    );
                    page.keep_results(Results { pdr, ..results });
                    page.set_state("ready", &summary);
                }
                _ => {
                    let options = controls::read(&page.document).options();
                    page.count_run(&page.n_calibration_runs, "data-calibration-runs");
                    let result = pipeline::calibration(&import, &options.heading_options);
                    page.show_result(result, Some(import)).await;
                }
            }
        });
    }

    /// The timeline of the kept import, with the controls' split and outages.
    pub fn timeline(&self) -> Option<Timeline> {
        let import = self.import.borrow().clone()?;
        let recording = &import.recording;
        let times = &recording.mag_in_body_ut.t_s;
        let (start_s, end_s) = (*times.first()?, *times.last()?);
        let controls = controls::read(&self.document);
        let train_until_s = self
            .results
            .borrow()
            .as_ref()
            .and_then(|results| results.calibration.report.train_until_s)
            .or(controls.train_until_s);
        Some(Timeline {
            start_s,
            end_s: end_s.max(start_s + 1.0),
            train_until_s,
            outages: controls.outages,
            gnss_times_s: recording.gnss.t_s.clone(),
        })
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

    /// The whole analysis at once (the browser tests use it).
    #[cfg(test)]
    pub fn show_analysis(&self, analysis: &mut CalibrationAnalysis, import: Option<&ImportReport>) {
        self.show_calibration(analysis);
        let (summary, heading) = self.show_heading_models(analysis);
        let (pdr_summary, _) = self.show_dead_reckoning(import, &heading);
        self.set_state("ready", &format!("{summary}{pdr_summary}"));
    }

    /// The calibration's context, device calibration, notes, diagnostics and plots.
    fn show_calibration(&self, analysis: &CalibrationAnalysis) {
        let report = &analysis.report;
        self.body.set_attribute("data-file", &report.file_name).ok();
        self.set_text("result-file", &report.file_name);
        self.show_context(report);
        if let Some(import) = self.import.borrow().as_ref() {
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
        // The table waits for the heading models; no stale rows meanwhile.
        self.fill_list("methods-body", std::iter::empty());
        self.fill_list("deviation-model", std::iter::empty());
        self.show_device_calibration(analysis);
        self.fill_list("notes", or_none(report.notes.iter().cloned()));
        self.show_diagnostics(report);
        for (canvas, plot) in [
            (&self.circle_canvas, Plot::CircleFit),
            (&self.heading_canvas, Plot::HeadingError),
            (&self.field_canvas, Plot::FieldMagnitude),
        ] {
            if let Err(message) = canvas::draw(canvas, plot, analysis) {
                let _ = canvas::draw_message(
                    canvas,
                    &format!("This plot could not be drawn: {message}"),
                );
            }
        }
        self.mark_time("data-first-plot-ms");
        self.set_state(
            "loading",
            &format!(
                "Calibrated {}; learning the heading models…",
                report.file_name
            ),
        );
    }

    /// The heading models on top of the calibration: every method and every stack on
    /// the same split, the deviation curve and the residuals. Returns the status line
    /// and the analysis.
    fn show_heading_models(&self, analysis: &mut CalibrationAnalysis) -> (String, HeadingAnalysis) {
        let options = controls::read(&self.document).options();
        let headings = pipeline::heading_models(analysis, &options.heading_options);
        // The choice is made: the device calibration and the heading plot follow it.
        self.show_device_calibration(analysis);
        if let Err(message) = canvas::draw(&self.heading_canvas, Plot::HeadingError, analysis) {
            let _ = canvas::draw_message(
                &self.heading_canvas,
                &format!("This plot could not be drawn: {message}"),
            );
        }
        let report = &analysis.report;
        self.show_methods(&headings.report);
        self.show_deviation_model(&headings.report);
        for (canvas, plot) in [
            (&self.deviation_canvas, HeadingPlot::DeviationCurve),
            (&self.residuals_canvas, HeadingPlot::ResidualHistogram),
            (&self.online_canvas, HeadingPlot::OnlineConvergence),
        ] {
            if let Err(message) = canvas::draw_heading(canvas, plot, &headings) {
                let _ = canvas::draw_message(
                    canvas,
                    &format!("This plot could not be drawn: {message}"),
                );
            }
        }
        let problems = match report.diagnostics.total() {
            0 => String::new(),
            1 => " 1 line had a problem; see below.".to_string(),
            n => format!(" {n} lines had problems; see below."),
        };
        // The CLI's `best:` line, word for word (crate::selection makes the choice once).
        let best = format!(" Best: {}.", headings.report.choice.sentence());
        self.set_state(
            "loading",
            &format!("Calibrated {}; dead-reckoning the walk…", report.file_name),
        );
        let summary = format!(
            "Analysed {}: {} magnetometer samples.{best}{problems}",
            report.file_name, report.n_samples_used
        );
        (summary, headings)
    }

    /// Dead-reckons the walk (steps, step model, the EKF) and shows its summary and
    /// plots; a log that cannot be dead-reckoned says why in their place. Returns a
    /// sentence for the status line, and the analysis or why there is none.
    fn show_dead_reckoning(
        &self,
        import: Option<&ImportReport>,
        headings: &HeadingAnalysis,
    ) -> (String, Result<PdrAnalysis, String>) {
        self.count_run(&self.n_pdr_runs, "data-pdr-runs");
        let options = controls::read(&self.document).options();
        let result = import
            .filter(|import| !import.recording.acc_in_body_mps2.is_empty())
            .ok_or_else(|| "the log has no accelerometer, so no steps can be detected".to_string())
            .and_then(|import| {
                crate::pdr::dead_reckon(import, headings, &options).map_err(|error| match error {
                    PdrError::Analysis(error) => error.to_string(),
                    other => other.to_string(),
                })
            });
        let canvases = [
            (&self.trajectory_canvas, PdrPlot::Trajectory),
            (&self.steps_canvas, PdrPlot::StepLengths),
            (&self.position_error_canvas, PdrPlot::PositionError),
        ];
        match result {
            Ok(analysis) => {
                self.fill_list(
                    "pdr-summary",
                    report::pdr_summary_lines(&analysis).into_iter(),
                );
                for (canvas, plot) in canvases {
                    if let Err(message) = canvas::draw_pdr(canvas, plot, &analysis) {
                        let _ = canvas::draw_message(
                            canvas,
                            &format!("This plot could not be drawn: {message}"),
                        );
                    }
                }
                let sentence = format!(
                    " {} steps dead-reckoned over {:.0} m.",
                    analysis.report.n_steps, analysis.report.pdr_distance_m
                );
                (sentence, Ok(analysis))
            }
            Err(message) => {
                let message = format!("No dead reckoning: {message}.");
                self.fill_list("pdr-summary", std::iter::once(message.clone()));
                for (canvas, _) in canvases {
                    let _ = canvas::draw_message(canvas, &message);
                }
                (String::new(), Err(message))
            }
        }
    }

    /// Shows an error in the status area and on the canvases, and clears the figures of
    /// the previous file so that none of them is taken for this one's.
    pub fn show_error(&self, message: &str) {
        self.results.borrow_mut().take();
        super::exports::enable(&self.document, None);
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
                row.key.replace('+', "-"),
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
            if report
                .best
                .as_deref()
                .is_some_and(|best| best.replace('+', "-") == key)
            {
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
                        cell.set_text_content(Some(&error));
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

    fn set_text(&self, id: &str, text: &str) {
        dom::set_text(&self.document, id, text);
    }

    fn fill_list(&self, id: &str, items: impl Iterator<Item = String>) {
        dom::fill_list(&self.document, id, items);
    }

    fn set_state(&self, state: &str, message: &str) {
        self.body.set_attribute("data-state", state).ok();
        self.status.set_text_content(Some(message));
        if state == "ready" {
            self.mark_time("data-ready-ms");
        }
    }

    /// Milliseconds from the page's navigation to now, on the body the first time (the
    /// time to the first plots and to the whole demo, which the README reports).
    fn mark_time(&self, attribute: &str) {
        if self.body.has_attribute(attribute) {
            return;
        }
        if let Some(performance) = web_sys::window().and_then(|window| window.performance()) {
            let _ = self
                .body
                .set_attribute(attribute, &format!("{:.0}", performance.now()));
        }
    }
}

/// The items, or a single "None." when there are none, so that an empty list reads as
/// checked rather than missing.
fn or_none(items: impl Iterator<Item = String>) -> impl Iterator<Item = String> {
    let mut items = items.peekable();
    let none = items.peek().is_none().then(|| "None.".to_string());
    items.chain(none)
}

/// Milliseconds on the page's clock (`performance.now()`), 0 where there is none.
fn now_ms() -> f64 {
    web_sys::window()
        .and_then(|window| window.performance())
        .map_or(0.0, |performance| performance.now())
}

/// Lets the browser run its queued work (painting, input) before the next step: a
/// zero-delay timeout, awaited.
async fn yield_to_browser() {
    let promise = js_sys::Promise::new(&mut |resolve, _reject| {
        let scheduled = web_sys::window().is_some_and(|window| {
            window
                .set_timeout_with_callback_and_timeout_and_arguments_0(&resolve, 0)
                .is_ok()
        });
        if !scheduled {
            let _ = resolve.call0(&wasm_bindgen::JsValue::NULL);
        }
    });
    let _ = JsFuture::from(promise).await;
}

/// Puts a bug report into the status area, whatever state the page is in.
pub fn show_bug(message: &str) {
    let Some(document) = web_sys::window().and_then(|window| window.document()) else {
        return;
    };
    if let Some(body) = document.body() {
        body.set_attribute("data-state", "error").ok();
    }
    if let Some(status) = document.get_element_by_id(STATUS_ID) {
        status.set_text_content(Some(message));
    }
}

/// The bytes at a URL of the page's own origin.
async fn fetch_bytes(url: &str) -> Result<Vec<u8>, String> {
    let window = web_sys::window().ok_or("no window")?;
    let response = JsFuture::from(window.fetch_with_str(url))
        .await
        .map_err(describe_js_error)?;
    let response: web_sys::Response = response
        .dyn_into()
        .map_err(|_| "the answer was not an HTTP response".to_string())?;
    if !response.ok() {
        return Err(format!("HTTP {}", response.status()));
    }
    let buffer = JsFuture::from(response.array_buffer().map_err(describe_js_error)?)
        .await
        .map_err(describe_js_error)?;
    Ok(js_sys::Uint8Array::new(&buffer).to_vec())
}

/// The message of a JavaScript error, without a final full stop (the page's sentences
/// go on after it).
pub(super) fn describe_js_error(value: wasm_bindgen::JsValue) -> String {
    let message = value
        .dyn_ref::<js_sys::Error>()
        .map(|error| String::from(error.message()))
        .or_else(|| value.as_string())
        .unwrap_or_else(|| "unknown error".to_string());
    message.trim_end().trim_end_matches('.').to_string()
}
