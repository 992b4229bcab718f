//! The live calibration panel: a serial port read through Web Serial into the core's
//! [`LiveSession`], with its figures, plots and buttons.
//!
//! The read loop hands every chunk to the session as it arrives (nothing is parsed
//! here), refits twice a second and redraws four times a second, so the page keeps
//! answering at any line rate the port can carry. When the port fails or the board is
//! unplugged, the loop ends with everything received still in the session: the
//! recording downloads whole, and "Connect" continues the same session on a new port.
//! Web Serial is feature-detected; a browser without it gets a message, not an error.
//!
//! Serial objects are typed with web-sys's bindings but taken with `unchecked_into`, so
//! any object with the Web Serial shape works (the end-to-end tests' fake port).
//!
//! This file holds the panel's element handles and state, the wiring of its buttons, a
//! new session, the expected field and the buttons' states. The rooms beside it:
//! `port.rs` (connecting, the read loop, sending a calibration back), `simulation.rs`
//! (the simulated board), `drawing.rs` (the timer that refits and redraws; the figures,
//! the verdict, the skipped lines, the board's confirmation and the plots; the 3D view,
//! turned by a drag or the arrow keys), `saved.rs`
//! (the settings and recent calibrations kept between visits, and a calibration file's
//! import) and `downloads.rs` (the recording and the calibration).

mod downloads;
mod drawing;
mod port;
mod saved;
mod simulation;

use std::cell::{Cell, RefCell};
use std::rc::Rc;

use gloo::events::EventListener;
use wasm_bindgen::closure::Closure;
use wasm_bindgen::JsCast;
use wasm_bindgen_futures::spawn_local;
use web_sys::{
    Document, Element, HtmlButtonElement, HtmlCanvasElement, HtmlInputElement, HtmlSelectElement,
    ReadableStreamDefaultReader, Serial, SerialPort,
};

use super::dom;
use super::storage::RecentCalibration;
use crate::earth::wmm::{date_of_unix_s, expected_field};
use crate::live::LiveSession;
use crate::present::plot::sphere_view::SphereView;
use simulation::Simulation;

/// An interval timer's handle and the callback it calls (dropped when it is cleared).
type Ticker = (i32, Closure<dyn FnMut()>);

pub struct LivePanel {
    document: Document,
    section: Element,
    connect: HtmlButtonElement,
    disconnect: HtmlButtonElement,
    send: HtmlButtonElement,
    download: HtmlButtonElement,
    download_calibration: HtmlButtonElement,
    download_snippet: HtmlButtonElement,
    reset: HtmlButtonElement,
    simulate: HtmlButtonElement,
    baud: HtmlSelectElement,
    lat: HtmlInputElement,
    lon: HtmlInputElement,
    clouds: HtmlCanvasElement,
    coverage: HtmlCanvasElement,
    dial: HtmlCanvasElement,
    sphere: HtmlCanvasElement,
    /// How the 3D view is turned; it turns by itself while samples arrive until the
    /// user turns it (`user_turned`).
    sphere_view: Cell<SphereView>,
    user_turned: Cell<bool>,
    /// Where the pointer was at the last move of a drag on the 3D view.
    drag_from: Cell<Option<(f64, f64)>>,
    session: RefCell<LiveSession>,
    port: RefCell<Option<SerialPort>>,
    reader: RefCell<Option<ReadableStreamDefaultReader>>,
    /// Whether a read loop is running.
    reading: Cell<bool>,
    last_refit_ms: Cell<f64>,
    /// New bytes since the last redraw.
    dirty: Cell<bool>,
    /// Bytes came in since the last refit.
    refit_pending: Cell<bool>,
    /// While connected: the interval timer that refits and redraws, and its callback.
    ticker: RefCell<Option<Ticker>>,
    /// While a simulated board plays: its timer, and what is left of its text.
    simulation: RefCell<Option<(Ticker, Simulation)>>,
    /// Why the last refit gave no fit, for the status line.
    fit_message: RefCell<Option<String>>,
    /// The longest refit and the longest redraw on this page so far (ms of its thread),
    /// on the panel for the end-to-end tests (`data-longest-refit-ms`, `-draw-ms`).
    longest_ms: Cell<(f64, f64)>,
    /// Why the last click on a Send button sent nothing, shown until a send goes out
    /// (or, for the latest fit, until it may be sent).
    refusal: RefCell<Option<Refusal>>,
    /// The recent calibrations (newest first), as stored.
    recent: RefCell<Vec<RecentCalibration>>,
    import: HtmlInputElement,
    recent_list: Element,
}

impl LivePanel {
    /// Finds the panel's elements; `Err` names the first one missing.
    pub fn from_document(document: &Document) -> Result<Rc<LivePanel>, String> {
        let element = |id: &str| {
            document
                .get_element_by_id(id)
                .ok_or(format!("the page has no element #{id}"))
        };
        fn cast<T: JsCast>(element: Element, id: &str) -> Result<T, String> {
            element
                .dyn_into::<T>()
                .map_err(|_| format!("#{id} is not the element expected"))
        }
        let typed = |id: &str| element(id);
        Ok(Rc::new(LivePanel {
            document: document.clone(),
            section: element("live")?,
            connect: cast(typed("live-connect")?, "live-connect")?,
            disconnect: cast(typed("live-disconnect")?, "live-disconnect")?,
            send: cast(typed("live-send")?, "live-send")?,
            download: cast(typed("live-download")?, "live-download")?,
            download_calibration: cast(
                typed("live-download-calibration")?,
                "live-download-calibration",
            )?,
            download_snippet: cast(typed("live-download-snippet")?, "live-download-snippet")?,
            reset: cast(typed("live-reset")?, "live-reset")?,
            simulate: cast(typed("live-simulate")?, "live-simulate")?,
            baud: cast(typed("live-baud")?, "live-baud")?,
            lat: cast(typed("live-lat")?, "live-lat")?,
            lon: cast(typed("live-lon")?, "live-lon")?,
            clouds: cast(typed("live-clouds")?, "live-clouds")?,
            coverage: cast(typed("live-coverage")?, "live-coverage")?,
            dial: cast(typed("live-dial")?, "live-dial")?,
            sphere: cast(typed("live-sphere")?, "live-sphere")?,
            sphere_view: Cell::new(SphereView::default()),
            user_turned: Cell::new(false),
            drag_from: Cell::new(None),
            session: RefCell::new(LiveSession::new()),
            port: RefCell::new(None),
            reader: RefCell::new(None),
            reading: Cell::new(false),
            last_refit_ms: Cell::new(f64::NEG_INFINITY),
            dirty: Cell::new(false),
            refit_pending: Cell::new(false),
            ticker: RefCell::new(None),
            simulation: RefCell::new(None),
            fit_message: RefCell::new(None),
            longest_ms: Cell::new((0.0, 0.0)),
            refusal: RefCell::new(None),
            recent: RefCell::new(Vec::new()),
            import: cast(typed("live-import")?, "live-import")?,
            recent_list: element("live-recent")?,
        }))
    }

    /// Wires the buttons, or says that this browser has no Web Serial.
    pub fn start(self: Rc<Self>) {
        self.restore();
        self.wire_storage();
        self.update_buttons();
        self.draw();
        let on = |button: &HtmlButtonElement, action: fn(&Rc<LivePanel>)| {
            let panel = Rc::clone(&self);
            EventListener::new(button, "click", move |_| action(&panel)).forget();
        };
        // A simulated board, its downloads and a new session need no Web Serial.
        on(&self.simulate, LivePanel::start_simulation);
        on(&self.disconnect, |panel| panel.stop_simulation());
        on(&self.download, |panel| panel.download_recording());
        on(&self.download_calibration, |panel| {
            panel.download_calibration_json();
        });
        on(&self.download_snippet, |panel| panel.download_c_snippet());
        on(&self.reset, |panel| panel.new_session());
        self.wire_sphere();
        for input in [&self.lat, &self.lon] {
            let panel = Rc::clone(&self);
            EventListener::new(input, "change", move |_| {
                panel.update_expected_field();
                panel.refit_and_draw();
            })
            .forget();
        }
        let Some(_) = serial() else {
            self.set_state(
                "unsupported",
                "This browser has no Web Serial: live calibration needs Chromium, Chrome, Edge or \
                 Opera on a desktop computer. You can still record the board's output with any serial \
                 terminal and drop the file above, or try a simulated board here.",
            );
            self.connect.set_disabled(true);
            return;
        };
        self.set_state(
            "idle",
            "Connect a board that prints magnetometer lines (MotionCal Raw:, Adafruit, Serial Plotter, \
             CircuitPython or plain numbers), then turn it slowly through every direction.",
        );
        on(&self.connect, |panel| {
            let panel = Rc::clone(panel);
            spawn_local(async move { panel.connect_and_read().await });
        });
        on(&self.disconnect, |panel| panel.stop_reading());
        on(&self.send, |panel| {
            let panel = Rc::clone(panel);
            spawn_local(async move { panel.send_to_device(None).await });
        });
    }

    fn new_session(&self) {
        if self.reading.get() {
            self.set_text(
                "live-confirmation",
                "Disconnect first: a new session starts empty.",
            );
            return;
        }
        *self.session.borrow_mut() = LiveSession::new();
        self.fit_message.borrow_mut().take();
        self.refusal.borrow_mut().take();
        self.set_text("live-confirmation", "");
        self.refit_and_draw();
        self.set_state("idle", "New session: connect a board.");
        self.update_buttons();
    }

    /// The World Magnetic Model's field at the position typed in, today.
    fn update_expected_field(&self) {
        let (lat, lon) = (self.lat.value_as_number(), self.lon.value_as_number());
        let expected = if lat.is_finite() && lon.is_finite() {
            date_of_unix_s(js_sys::Date::now() / 1e3)
                .and_then(|date| expected_field(lat, lon, 0.0, date).ok())
                .map(|field| field.total_ut)
        } else {
            None
        };
        self.session.borrow_mut().set_expected_field(expected);
    }

    fn update_buttons(&self) {
        let session = self.session.borrow();
        let quality = session.quality();
        let has_fit = quality.is_some();
        let reading = self.reading.get();
        let has_port = self.port.borrow().is_some();
        self.connect.set_disabled(reading || serial().is_none());
        self.disconnect.set_disabled(!reading);
        // Sent only when the core's decision allows it; the title says why not.
        let why_not = if !(reading && has_port) {
            Some("Connect the board first: the calibration is sent over its port.".to_string())
        } else {
            match quality {
                None => Some("No calibration yet: keep turning the board.".to_string()),
                Some(quality) if !quality.send.sendable => {
                    Some(refusal_text(&quality.send.reasons))
                }
                Some(_) => None,
            }
        };
        self.send.set_disabled(why_not.is_some());
        let title = why_not.unwrap_or_else(|| {
            "Sends MotionCal's 68-byte calibration packet to the board: better than the \
             calibration in force on the samples held back."
                .to_string()
        });
        self.send
            .set_attribute("title", &super::wording::for_page(&title))
            .ok();
        self.simulate.set_disabled(reading);
        self.download.set_disabled(session.raw().is_empty());
        self.download_calibration.set_disabled(!has_fit);
        self.download_snippet.set_disabled(!has_fit);
        self.reset.set_disabled(reading);
    }

    fn set_text(&self, id: &str, text: &str) {
        dom::set_text(&self.document, id, text);
    }

    fn fill_list(&self, id: &str, items: impl Iterator<Item = String>) {
        dom::fill_list(&self.document, id, items);
    }

    fn set_state(&self, state: &str, message: &str) {
        self.section.set_attribute("data-live-state", state).ok();
        self.set_text("live-status", message);
    }
}

/// A click on a Send button that sent nothing.
struct Refusal {
    /// Of the latest fit (forgotten once the fit may be sent), or of a saved calibration.
    of_latest_fit: bool,
    text: String,
}

/// The core's reasons for sending nothing, as one sentence for the page.
fn refusal_text(reasons: &[String]) -> String {
    let reasons: Vec<&str> = reasons
        .iter()
        .map(|reason| reason.trim().trim_end_matches('.'))
        .collect();
    format!(
        "Not sent, the calibration in force is kept: {}.",
        reasons.join("; ")
    )
}

/// Calls `callback` every `interval_ms` until the returned ticker is cleared; `None`
/// when the page has no window to set a timer on.
fn every(interval_ms: f64, callback: impl FnMut() + 'static) -> Option<Ticker> {
    let callback = Closure::<dyn FnMut()>::new(callback);
    let id = web_sys::window()?
        .set_interval_with_callback_and_timeout_and_arguments_0(
            callback.as_ref().unchecked_ref(),
            interval_ms as i32,
        )
        .ok()?;
    Some((id, callback))
}

/// `navigator.serial`, when this browser has Web Serial.
fn serial() -> Option<Serial> {
    let navigator = web_sys::window()?.navigator();
    let serial = js_sys::Reflect::get(&navigator, &"serial".into()).ok()?;
    (!serial.is_undefined() && !serial.is_null()).then(|| serial.unchecked_into::<Serial>())
}

fn now_ms() -> f64 {
    web_sys::window()
        .and_then(|window| window.performance())
        .map_or_else(js_sys::Date::now, |performance| performance.now())
}
