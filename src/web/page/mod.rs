//! The page: its element handles, the wiring of the file input and the drop zone, the
//! demo log, the re-runs when a control changes, and the kept import and [`Results`].
//! Reading dropped files is in `reading.rs`; putting the analysis into the DOM is in
//! `show.rs`; zooming its plots in `zoom.rs`.
//!
//! Log-derived text (file names, messages) is set with `textContent`, never as HTML.
//! The body's `data-state` attribute says where the page is (`loading`, `ready`,
//! `error`), for people using assistive technology (through the status region) and for
//! the end-to-end tests.

pub(crate) mod analysis;
mod loading;
mod reading;
mod show;
mod verdict;
mod zoom;

use std::rc::Rc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use gloo::events::{EventListener, EventListenerOptions};
use wasm_bindgen::JsCast;
use wasm_bindgen_futures::{spawn_local, JsFuture};
use web_sys::{Document, DragEvent, Element, HtmlCanvasElement, HtmlElement, HtmlInputElement};

use super::controls::{self, Stage};
use super::dom;
use crate::analysis::calibration::CalibrationAnalysis;
use crate::analysis::headings::HeadingAnalysis;
use crate::analysis::levelled::AnalysisError;
use crate::io::ImportReport;
use crate::pdr::PdrAnalysis;
use crate::present::plot::timeline::Timeline;

/// The ids of the elements the page must have (see `www/index.html`).
const STATUS_ID: &str = "status";
const FILE_INPUT_ID: &str = "file-input";
const DROP_ZONE_ID: &str = "drop-zone";
const CANCEL_ID: &str = "cancel";
const CIRCLE_CANVAS_ID: &str = "plot-circle";
const HEADING_CANVAS_ID: &str = "plot-heading";
const FIELD_CANVAS_ID: &str = "plot-field";
const DEVIATION_CANVAS_ID: &str = "plot-deviation";
const RESIDUALS_CANVAS_ID: &str = "plot-residuals";
const ONLINE_CANVAS_ID: &str = "plot-online";
const TRAJECTORY_CANVAS_ID: &str = "plot-trajectory";
const STEPS_CANVAS_ID: &str = "plot-steps";
const POSITION_ERROR_CANVAS_ID: &str = "plot-position-error";

/// The body's attribute that shows the `loading` state's Cancel button (`www/style.css`):
/// set once the job's loading display is shown (`loading.rs`).
const LOADING_SHOWN: &str = "data-loading-shown";

/// Bytes read from a file at a time: small enough that the page answers between
/// chunks, large enough that the reads cost little.
pub(super) const CHUNK_BYTES: f64 = 4.0 * 1024.0 * 1024.0;

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
    /// The latest answer, whose picture is drawn again when the window's width changes.
    answer: std::cell::RefCell<Option<crate::present::verdict::Verdict>>,
    /// The latest log as imported, for re-running the analysis when a control changes.
    import: std::cell::RefCell<Option<Arc<ImportReport>>>,
    /// The running job's cancel flag (set when a new job starts or Cancel is pressed).
    cancel: std::cell::RefCell<Arc<AtomicBool>>,
    /// Where the analysis runs when the page has the threaded module; `None` (and always
    /// in the plain module) runs it on this thread.
    #[cfg(target_feature = "atomics")]
    worker: Option<crate::web::worker::AnalysisWorker>,
    /// How many times the calibration and the dead reckoning ran (on the body as
    /// `data-calibration-runs` and `data-pdr-runs`, for the tests).
    n_calibration_runs: std::cell::Cell<u32>,
    n_pdr_runs: std::cell::Cell<u32>,
    /// Finished analyses shown so far: a job's early figures stop drawing when it moves.
    n_shown: std::cell::Cell<u64>,
    /// The calibration figures the running job drew early, which its finished analysis
    /// need not draw again (emptied when a job begins; a cancelled job draws no more).
    early_figures: std::cell::RefCell<Vec<show::Canvas>>,
    /// The zoomable plots' zooms and frames.
    zooms: zoom::Zooms,
    /// The running job's loading display, held back for its first moments.
    loading: loading::Held,
}

/// What reading and analysing a log gave: the import (when the files could be read)
/// and the analysis, or why there is none.
pub(crate) type Outcome = (Option<Arc<ImportReport>>, Result<Results, AnalysisError>);

/// One log's analysis: what the exports write.
pub struct Results {
    pub calibration: CalibrationAnalysis,
    pub heading: HeadingAnalysis,
    /// The dead reckoning, or why there is none.
    pub pdr: Result<PdrAnalysis, String>,
}

impl Page {
    /// Finds the page's elements; the message names the first one missing.
    /// `analysis_worker` is the worker the threaded module's page started
    /// (`www/bootstrap.js`); the plain module ignores it.
    pub fn from_document(analysis_worker: Option<web_sys::Worker>) -> Result<Rc<Page>, String> {
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
        #[cfg(not(target_feature = "atomics"))]
        drop(analysis_worker);
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
            answer: std::cell::RefCell::new(None),
            import: std::cell::RefCell::new(None),
            cancel: std::cell::RefCell::new(Arc::default()),
            #[cfg(target_feature = "atomics")]
            worker: analysis_worker.map(crate::web::worker::AnalysisWorker::new),
            n_calibration_runs: std::cell::Cell::new(0),
            n_pdr_runs: std::cell::Cell::new(0),
            n_shown: std::cell::Cell::new(0),
            early_figures: std::cell::RefCell::default(),
            zooms: zoom::Zooms::default(),
            loading: loading::Held::default(),
        }))
    }

    /// Wires the file input and the drop zone, then analyses the demo.
    pub fn start(self: Rc<Self>) {
        let page = Rc::clone(&self);
        EventListener::new(&self.file_input, "change", move |_| {
            let Some(files) = page.file_input.files() else {
                return;
            };
            page.analyse_files(&files);
            // Choosing the same file again should analyse it again.
            page.file_input.set_value("");
        })
        .forget();

        // Without preventDefault on dragover and drop, the browser opens the file.
        let prevent_default = EventListenerOptions::enable_prevent_default();
        for event_name in ["dragover", "drop"] {
            EventListener::new_with_options(&self.document, event_name, prevent_default, |event| {
                event.prevent_default();
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
                Some(files) if files.length() > 0 => page.analyse_files(&files),
                _ => page.show_error(
                    "Nothing to read in what was dropped. Drop a CSV file from your computer.",
                ),
            }
        })
        .forget();

        self.wire_zoom();
        self.wire_picture_resize();
        if let Some(cancel) = self.document.get_element_by_id(CANCEL_ID) {
            let page = Rc::clone(&self);
            EventListener::new(&cancel, "click", move |_| page.cancel_job()).forget();
        }

        spawn_local(async move { self.load_demo().await });
    }

    async fn load_demo(self: Rc<Self>) {
        let Some(demo_url) = self.body.get_attribute("data-demo-url") else {
            self.set_state("ready", "Drop a log to analyse it.");
            return;
        };
        let file_name = demo_url.rsplit('/').next().unwrap_or(&demo_url).to_string();
        self.set_state("loading", &format!("Loading the demo log {file_name}…"));
        match fetch_file(&demo_url, &file_name).await {
            Ok(file) => self.analyse_file_list(vec![file], None),
            Err(message) => self.show_error(&format!("Could not load the demo log {demo_url}: {message}. Drop a log to analyse it instead.")),
        }
    }

    /// Starts a job: the one running (if any) is cancelled; returns the new one's
    /// cancel flag. Its loading display is held back for a while if `hold`
    /// (`loading.rs`).
    fn begin_job(self: &Rc<Self>, hold: bool) -> Arc<AtomicBool> {
        let job = self.loading.begin(hold);
        let page = Rc::clone(self);
        spawn_local(async move {
            pause(loading::SHOWN_AFTER_MS).await;
            if let Some((status, progress)) = page.loading.release(job) {
                page.body.set_attribute(LOADING_SHOWN, "").ok();
                if let Some(status) = status {
                    page.set_state("loading", &status);
                }
                if let Some((fraction, file_name)) = progress {
                    page.show_progress(fraction, &file_name);
                }
            }
        });
        let cancel = Arc::new(AtomicBool::new(false));
        // A job's early figures do not count for the next.
        self.early_figures.take();
        let previous = std::mem::replace(&mut *self.cancel.borrow_mut(), Arc::clone(&cancel));
        previous.store(true, Ordering::Release);
        cancel
    }

    /// Cancels the running job (the Cancel button): the page keeps what it showed.
    pub(crate) fn cancel_job(&self) {
        self.cancel.borrow().store(true, Ordering::Release);
        self.hide_progress();
        let message = match self.results.borrow().as_ref() {
            Some(results) => format!(
                "Cancelled. The page still shows {}.",
                results.calibration.report.file_name
            ),
            None => "Cancelled. Drop a log to analyse it.".to_string(),
        };
        self.set_state(
            if self.results.borrow().is_some() {
                "ready"
            } else {
                "error"
            },
            &message,
        );
    }

    /// Counts the runs a job from `stage` made, once it is shown (for the tests: a
    /// change of the step model must not calibrate again).
    pub(super) fn count_runs(&self, stage: Stage) {
        if stage == Stage::Calibration {
            self.count_run(&self.n_calibration_runs, "data-calibration-runs");
        }
        self.count_run(&self.n_pdr_runs, "data-pdr-runs");
    }

    /// The analysis worker, when the page has one that works.
    #[cfg(target_feature = "atomics")]
    fn worker(&self) -> Option<&crate::web::worker::AnalysisWorker> {
        self.worker.as_ref().filter(|worker| worker.works())
    }

    /// Where the worker's updates on `job` go: the progress bar, the status line and
    /// the calibration's figures.
    #[cfg(target_feature = "atomics")]
    fn on_update(
        self: &Rc<Self>,
        job: &crate::web::worker::Job,
    ) -> impl Fn(crate::web::worker::Update) + 'static {
        let page = Rc::clone(self);
        let (cancel, finished) = (Arc::clone(&job.cancel), Arc::clone(&job.finished));
        move |update| match update {
            crate::web::worker::Update::Calibrated(early) => {
                let page = Rc::clone(&page);
                let (cancel, finished) = (Arc::clone(&cancel), Arc::clone(&finished));
                spawn_local(async move {
                    // Most logs' heading models and dead reckoning take a few
                    // milliseconds after the calibration: its lists and figures drawn
                    // meanwhile (tens of milliseconds of this thread) would only hold
                    // up the answer. They are shown early when the rest takes longer.
                    pause(EARLY_FIGURES_AFTER_MS).await;
                    let (import, calibration) = &*early;
                    page.show_calibrated(import, calibration, (&cancel, &finished))
                        .await;
                });
            }
            crate::web::worker::Update::Progress {
                fraction,
                file_name,
            } => page.show_progress(fraction, &file_name),
            crate::web::worker::Update::Step(status) => {
                page.hide_progress();
                page.set_state("loading", &status);
            }
        }
    }

    /// The import the latest analysis came from, if there is one.
    pub fn import(&self) -> Option<Arc<ImportReport>> {
        self.import.borrow().clone()
    }

    /// The latest analysis, if there is one.
    pub fn results(&self) -> Option<Rc<Results>> {
        self.results.borrow().clone()
    }

    fn count_run(&self, counter: &std::cell::Cell<u32>, attribute: &str) {
        counter.set(counter.get() + 1);
        self.body
            .set_attribute(attribute, &counter.get().to_string())
            .ok();
    }

    /// Re-runs `stage` (and what follows it) on the kept import with the controls'
    /// current values, on the analysis worker where there is one.
    pub fn rerun(self: &Rc<Self>, stage: Stage) {
        let Some(import) = self.import.borrow().clone() else {
            return;
        };
        let page = Rc::clone(self);
        let cancel = self.begin_job(true);
        spawn_local(async move {
            let file_name = import.file_name.clone();
            page.set_state("loading", &format!("Analysing {file_name} again…"));
            // The dead reckoning alone re-uses the calibration and the heading models.
            let previous = match stage {
                Stage::DeadReckoning => page
                    .results
                    .borrow_mut()
                    .take()
                    .and_then(|results| Rc::try_unwrap(results).ok()),
                Stage::Calibration => None,
            };
            let request = analysis::Request {
                import: Arc::clone(&import),
                stage,
                previous,
                options: controls::read(&page.document).options(),
            };
            let Some(result) = page.run_request(request, &cancel).await else {
                return;
            };
            if !cancel.load(Ordering::Acquire) {
                page.show_outcome(result, Some(import), (stage, &cancel))
                    .await;
            }
        });
    }

    /// Runs `request` on the analysis worker where there is one, else here; `None`
    /// when it was cancelled or the worker failed (which the page then says).
    async fn run_request(
        self: &Rc<Self>,
        request: analysis::Request,
        cancel: &Arc<AtomicBool>,
    ) -> Option<Result<Results, AnalysisError>> {
        #[cfg(target_feature = "atomics")]
        let request = match self.worker() {
            Some(worker) => {
                use crate::web::worker::{Job, Work};
                let job = Job::new(Work::Again(Box::new(request)), cancel);
                let on_update = self.on_update(&job);
                match worker.run(job, &[], on_update).await {
                    Ok(job) => return job.outcome.map(|(_, result)| result),
                    // The worker never took the job: run it here.
                    Err(Some(job)) => match job.work {
                        Work::Again(request) => *request,
                        Work::Files { .. } => return None,
                    },
                    Err(None) => {
                        // The worker failed, and the page says so: nothing held back is
                        // shown.
                        self.loading.end();
                        return None;
                    }
                }
            }
            None => request,
        };
        self.analyse_here(request, cancel).await
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

    fn set_text(&self, id: &str, text: &str) {
        dom::set_text(&self.document, id, text);
    }

    fn fill_list(&self, id: &str, items: impl Iterator<Item = String>) {
        dom::fill_list(&self.document, id, items);
    }

    /// Puts the page in `state` with `message` in the status line. A job's `loading`
    /// display (the message, the Cancel button) is held back for its first moments
    /// (`loading.rs`), its state is not; any other state ends the holding.
    fn set_state(&self, state: &str, message: &str) {
        self.body.set_attribute("data-state", state).ok();
        if state == "loading" {
            if self.loading.hold_status(message) {
                return;
            }
            self.body.set_attribute(LOADING_SHOWN, "").ok();
        } else {
            self.loading.end();
            self.body.remove_attribute(LOADING_SHOWN).ok();
        }
        self.status
            .set_text_content(Some(&super::wording::for_page(message)));
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

/// Milliseconds on the page's clock (`performance.now()`), 0 where there is none.
fn now_ms() -> f64 {
    web_sys::window()
        .and_then(|window| window.performance())
        .map_or(0.0, |performance| performance.now())
}

/// Lets the browser run its queued work (painting, input) before the next step: a
/// zero-delay timeout, awaited.
async fn yield_to_browser() {
    pause(0).await;
}

/// How long after a job's calibration (on the analysis worker) its lists and figures
/// wait for the rest of the analysis before they are shown on their own: drawn while the
/// worker and its pool still run, they take a core from them (on a 2-core machine, after
/// 20 ms, the Pixel 6a drive's answer came 7 ms later in the median of five first drops,
/// bench/drop_costs.mjs, 2026-12-06), so only an analysis that still has a while to go
/// shows them first (the 50 MB log of tests/e2e/page.test.mjs, seconds).
#[cfg(target_feature = "atomics")]
const EARLY_FIGURES_AFTER_MS: i32 = 250;

/// Lets the browser run for at least `ms` milliseconds (a timer's turn) before going on.
async fn pause(ms: i32) {
    let promise = js_sys::Promise::new(&mut |resolve, _reject| {
        let scheduled = web_sys::window().is_some_and(|window| {
            window
                .set_timeout_with_callback_and_timeout_and_arguments_0(&resolve, ms)
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
        status.set_text_content(Some(&super::wording::for_page(message)));
    }
}

/// The file at a URL of the page's own origin, named `file_name`.
async fn fetch_file(url: &str, file_name: &str) -> Result<web_sys::File, String> {
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
    let blob = JsFuture::from(response.blob().map_err(describe_js_error)?)
        .await
        .map_err(describe_js_error)?;
    web_sys::File::new_with_blob_sequence(&js_sys::Array::of1(&blob), file_name)
        .map_err(describe_js_error)
}

/// The message of a JavaScript error, without a final full stop (the page's sentences
/// go on after it).
#[expect(
    clippy::needless_pass_by_value,
    reason = "map_err and the JS promises hand their errors over by value"
)]
pub(super) fn describe_js_error(value: wasm_bindgen::JsValue) -> String {
    let message = value
        .dyn_ref::<js_sys::Error>()
        .map(|error| String::from(error.message()))
        .or_else(|| value.as_string())
        .unwrap_or_else(|| "unknown error".to_string());
    message.trim_end().trim_end_matches('.').to_string()
}
