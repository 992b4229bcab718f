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

use std::cell::{Cell, RefCell};
use std::rc::Rc;

use gloo::events::EventListener;
use js_sys::Uint8Array;
use wasm_bindgen::closure::Closure;
use wasm_bindgen::JsCast;
use wasm_bindgen_futures::{spawn_local, JsFuture};
use web_sys::{
    Document, Element, HtmlButtonElement, HtmlCanvasElement, HtmlInputElement, HtmlSelectElement,
    ReadableStreamDefaultReader, Serial, SerialOptions, SerialPort,
};

use super::canvas;
use super::dom;
use super::exports::{calibration_json, download_bytes};
use super::page::describe_js_error;
use super::storage::{
    self, RecentCalibration, Settings, CALIBRATIONS_KEY, MAX_RECENT_CALIBRATIONS, SETTINGS_KEY,
};
use crate::calib::export::{c_snippet, calibration_export, CalibrationExport};
use crate::calib::model::FieldCalibration;
use crate::calib::wmm::{date_of_unix_s, expected_field};
use crate::live::{Confirmation, LiveSession, MIN_FIT_SAMPLES};
use crate::sim::dance::{motioncal_raw_lines, DanceConfig, DanceTruth};

/// Refits this often while samples arrive (ms).
const REFIT_EVERY_MS: f64 = 500.0;
/// Redraws the plots and figures this often (ms).
const DRAW_EVERY_MS: f64 = 250.0;
/// Skipped lines listed at most (all are counted).
const MAX_SKIPPED_SHOWN: usize = 20;

/// An interval timer's handle and the callback it calls (dropped when it is cleared).
type Ticker = (i32, Closure<dyn FnMut()>);

/// How long the simulated board's dance is (s of the board's time).
const SIMULATED_DANCE_S: f64 = 60.0;
/// How much faster than the board the simulated dance plays.
const SIMULATION_SPEED_UP: f64 = 10.0;
/// How often the simulated board delivers a piece (ms).
const SIMULATION_TICK_MS: f64 = 50.0;

/// A simulated board's text, how much of it was delivered, and its truth.
struct Simulation {
    text: Vec<u8>,
    sent: usize,
    bytes_per_tick: usize,
    truth: DanceTruth,
}

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
        on(&self.simulate, |panel| panel.start_simulation());
        on(&self.disconnect, |panel| panel.stop_simulation());
        on(&self.download, |panel| panel.download_recording());
        on(&self.download_calibration, |panel| {
            panel.download_calibration_json()
        });
        on(&self.download_snippet, |panel| panel.download_c_snippet());
        on(&self.reset, |panel| panel.new_session());
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

    /// The settings and recent calibrations saved by an earlier visit.
    fn restore(&self) {
        let settings: Settings = storage::load(SETTINGS_KEY, "settings").unwrap_or_default();
        if let Some(baud_rate) = settings.baud_rate {
            self.baud.set_value(&baud_rate.to_string());
        }
        for (input, value) in [(&self.lat, settings.lat_deg), (&self.lon, settings.lon_deg)] {
            if let Some(value) = value.filter(|value| value.is_finite()) {
                input.set_value(&value.to_string());
            }
        }
        let recent: Vec<RecentCalibration> =
            storage::load(CALIBRATIONS_KEY, "recent calibrations").unwrap_or_default();
        // Entries whose numbers do not make a calibration are dropped like corrupt ones.
        *self.recent.borrow_mut() = recent
            .into_iter()
            .filter(|entry| entry.calibration.to_calibration().is_ok())
            .take(MAX_RECENT_CALIBRATIONS)
            .collect();
        self.render_recent();
    }

    /// Saves the settings when they change; wires the recent list and the import.
    fn wire_storage(self: &Rc<Self>) {
        for element in [
            self.baud.clone().unchecked_into::<Element>(),
            self.lat.clone().unchecked_into::<Element>(),
            self.lon.clone().unchecked_into::<Element>(),
        ] {
            let panel = Rc::clone(self);
            EventListener::new(&element, "change", move |_| panel.save_settings()).forget();
        }
        let panel = Rc::clone(self);
        EventListener::new(&self.recent_list, "click", move |event| {
            let Some(target) = event
                .target()
                .and_then(|target| target.dyn_into::<Element>().ok())
            else {
                return;
            };
            let action = target.get_attribute("data-action");
            let index = target
                .get_attribute("data-index")
                .and_then(|index| index.parse::<usize>().ok());
            let (Some(action), Some(index)) = (action, index) else {
                return;
            };
            let entry = panel.recent.borrow().get(index).cloned();
            let Some(entry) = entry else {
                return;
            };
            let Ok(calibration) = entry.calibration.to_calibration() else {
                return;
            };
            match action.as_str() {
                "send" => {
                    let panel = Rc::clone(&panel);
                    spawn_local(async move { panel.send_to_device(Some(calibration)).await });
                }
                "download" => {
                    if let Ok(text) = calibration_json(&entry.calibration) {
                        download_bytes(
                            &panel.document,
                            "compass-pdr-calibration.json",
                            text.as_bytes(),
                            "application/json",
                        );
                    }
                }
                _ => {}
            }
        })
        .forget();
        let panel = Rc::clone(self);
        EventListener::new(&self.import, "change", move |_| {
            let Some(file) = panel.import.files().and_then(|files| files.get(0)) else {
                return;
            };
            panel.import.set_value("");
            let panel = Rc::clone(&panel);
            spawn_local(async move { panel.import_calibration(file).await });
        })
        .forget();
    }

    fn save_settings(&self) {
        let number =
            |input: &HtmlInputElement| Some(input.value_as_number()).filter(|v| v.is_finite());
        let settings = Settings {
            baud_rate: self.baud.value().parse().ok(),
            lat_deg: number(&self.lat),
            lon_deg: number(&self.lon),
        };
        storage::save(SETTINGS_KEY, &settings);
    }

    /// Keeps the latest fit among the recent calibrations (once).
    fn keep_latest_fit(&self) {
        let calibration = self
            .session
            .borrow()
            .quality()
            .map(|quality| quality.sensor_calibration());
        if let Some(calibration) = calibration {
            self.keep(RecentCalibration {
                source: "live session".to_string(),
                saved_at: String::from(js_sys::Date::new_0().to_iso_string()),
                calibration: calibration_export(&calibration),
            });
        }
    }

    fn keep(&self, entry: RecentCalibration) {
        {
            let mut recent = self.recent.borrow_mut();
            if recent
                .first()
                .is_some_and(|newest| newest.calibration == entry.calibration)
            {
                return;
            }
            recent.insert(0, entry);
            recent.truncate(MAX_RECENT_CALIBRATIONS);
            storage::save(CALIBRATIONS_KEY, &*recent);
        }
        self.render_recent();
    }

    /// Reads a calibration JSON the user chose and keeps it among the recent ones.
    async fn import_calibration(self: Rc<Self>, file: web_sys::File) {
        let name = file.name();
        let text = match gloo_file::futures::read_as_text(&gloo::file::Blob::from(file)).await {
            Ok(text) => text,
            Err(error) => {
                self.set_text(
                    "live-import-status",
                    &format!("Could not read {name}: {error}."),
                );
                return;
            }
        };
        let parsed = js_sys::JSON::parse(&text)
            .map_err(|_| "it is not JSON".to_string())
            .and_then(|value| {
                serde_wasm_bindgen::from_value::<CalibrationExport>(value)
                    .map_err(|error| error.to_string())
            })
            .and_then(|export| {
                export
                    .to_calibration()
                    .map(|_| export)
                    .map_err(|error| error.to_string())
            });
        match parsed {
            Ok(export) => {
                let conversion = if export.ut_per_unit == Some(1.0) {
                    String::new()
                } else {
                    format!(
                        " It is in {}; sending it converts it to µT, the unit of MotionCal's packet.",
                        export.unit
                    )
                };
                let message = format!(
                    "Loaded the calibration in {name}: it is first in the list below. Its axes: {}.{conversion}",
                    export.axes_description
                );
                self.keep(RecentCalibration {
                    source: name.clone(),
                    saved_at: String::from(js_sys::Date::new_0().to_iso_string()),
                    calibration: export,
                });
                self.set_text("live-import-status", &message);
            }
            Err(reason) => self.set_text(
                "live-import-status",
                &format!(
                    "{name} is not a calibration compass-pdr can read: {reason}. Choose a file saved with \
                     \"Download calibration (JSON)\"."
                ),
            ),
        }
    }

    fn render_recent(&self) {
        let list = &self.recent_list;
        list.set_text_content(None);
        let recent = self.recent.borrow();
        if recent.is_empty() {
            if let Ok(item) = self.document.create_element("li") {
                item.set_text_content(Some(
                    "None yet: a calibration you send or download is kept here.",
                ));
                let _ = list.append_child(&item);
            }
            return;
        }
        for (index, entry) in recent.iter().enumerate() {
            let Ok(item) = self.document.create_element("li") else {
                continue;
            };
            let saved = &entry.calibration;
            let hard = saved.hard_iron;
            let when = entry
                .saved_at
                .get(..16)
                .unwrap_or(&entry.saved_at)
                .replace('T', " ");
            let decimals = crate::report::decimals_for_unit(saved.ut_per_unit.unwrap_or(1.0));
            let unit = &saved.unit;
            let description = format!(
                "{when} UTC, {}: hard iron ({:.decimals$}, {:.decimals$}, {:.decimals$}) {unit}, field \
                 {:.decimals$} {unit}; axes: {} ",
                entry.source, hard[0], hard[1], hard[2], saved.field, saved.axes_description
            );
            if let Ok(span) = self.document.create_element("span") {
                span.set_text_content(Some(&description));
                let _ = item.append_child(&span);
            }
            for (action, label) in [("send", "Send to device"), ("download", "Download JSON")] {
                if let Ok(button) = self.document.create_element("button") {
                    let _ = button.set_attribute("type", "button");
                    let _ = button.set_attribute("data-action", action);
                    let _ = button.set_attribute("data-index", &index.to_string());
                    let _ = button.set_attribute("id", &format!("recent-{action}-{index}"));
                    button.set_text_content(Some(label));
                    let _ = item.append_child(&button);
                }
            }
            let _ = list.append_child(&item);
        }
    }

    /// Asks for a port, opens it and reads it until it ends.
    async fn connect_and_read(self: Rc<Self>) {
        if self.reading.get() {
            return;
        }
        let Some(serial) = serial() else {
            return;
        };
        let baud_rate = self.baud.value().parse::<u32>().unwrap_or(115_200);
        self.set_state(
            "connecting",
            "Choose the board's port in the browser's list…",
        );
        let port = match JsFuture::from(serial.request_port()).await {
            Ok(port) => port.unchecked_into::<SerialPort>(),
            Err(error) => {
                self.set_state(
                    "idle",
                    &format!(
                        "No port chosen ({}). Click Connect to try again.",
                        describe_js_error(error)
                    ),
                );
                return;
            }
        };
        let options = SerialOptions::new(baud_rate);
        if let Err(error) = JsFuture::from(port.open(&options)).await {
            self.set_state(
                "error",
                &format!(
                    "The port could not be opened at {baud_rate} baud: {}. Close any other program \
                     using it (the Arduino IDE's monitor, MotionCal) and connect again.",
                    describe_js_error(error)
                ),
            );
            return;
        }
        self.update_expected_field();
        *self.port.borrow_mut() = Some(port.clone());
        self.reading.set(true);
        self.update_buttons();
        self.set_state(
            "connected",
            &format!("Connected at {baud_rate} baud; reading. Turn the board slowly through every direction."),
        );
        self.start_ticker();
        let ending = self.read_until_end(&port).await;
        self.stop_ticker();
        self.reading.set(false);
        self.reader.borrow_mut().take();
        // Closing may fail on a port that is gone; there is nothing more to do then.
        let _ = JsFuture::from(port.close()).await;
        self.port.borrow_mut().take();
        self.session.borrow_mut().port_closed();
        self.refit_and_draw();
        let n_lines = self.session.borrow().counts().n_lines;
        match ending {
            Ok(()) => self.set_state(
                "disconnected",
                &format!(
                    "Disconnected. All {n_lines} lines received are kept: download the recording, send \
                     the calibration, or connect again to continue this session."
                ),
            ),
            Err(message) => self.set_state(
                "disconnected",
                &format!(
                    "The connection ended: {message}. All {n_lines} lines received are kept: download \
                     the recording, or plug the board back in and connect again to continue."
                ),
            ),
        }
        self.update_buttons();
    }

    /// The read loop: `Ok` when the stream ended or was cancelled, `Err` with the
    /// browser's reason when it failed (an unplug).
    async fn read_until_end(&self, port: &SerialPort) -> Result<(), String> {
        let reader = port
            .readable()
            .get_reader()
            .unchecked_into::<ReadableStreamDefaultReader>();
        *self.reader.borrow_mut() = Some(reader.clone());
        let result = loop {
            let chunk = match JsFuture::from(reader.read()).await {
                Ok(chunk) => chunk,
                Err(error) => break Err(describe_js_error(error)),
            };
            let done = js_sys::Reflect::get(&chunk, &"done".into())
                .ok()
                .is_some_and(|done| done.is_truthy());
            if done {
                break Ok(());
            }
            if let Ok(value) = js_sys::Reflect::get(&chunk, &"value".into()) {
                if let Some(bytes) = value.dyn_ref::<Uint8Array>() {
                    self.session
                        .borrow_mut()
                        .feed(&bytes.to_vec(), now_ms() / 1e3);
                    self.dirty.set(true);
                }
            }
        };
        reader.release_lock();
        result
    }

    /// Plays the simulator's calibration dance (`sim::dance`: MotionCal `Raw:` lines of
    /// a board with a random hard and soft iron) into the session as a board's port
    /// would deliver it, ten times as fast as the board would, in pieces cut anywhere,
    /// so that the panel can be tried without a board. The truth is said at the end.
    fn start_simulation(self: &Rc<Self>) {
        if self.reading.get() {
            return;
        }
        let seed = (now_ms() as u64) % 1000 + 1;
        let config = DanceConfig::from_seed(seed, SIMULATED_DANCE_S);
        let (text, truth) = motioncal_raw_lines(&config);
        let bytes_per_tick = (text.len() as f64 / SIMULATED_DANCE_S
            * SIMULATION_SPEED_UP
            * SIMULATION_TICK_MS
            / 1e3)
            .ceil() as usize;
        self.update_expected_field();
        self.reading.set(true);
        self.update_buttons();
        self.set_state(
            "connected",
            &format!(
                "A simulated board (seed {seed}) is turned through every direction, printing \
                 MotionCal Raw: lines; it plays ten times as fast as a board would."
            ),
        );
        self.start_ticker();
        let panel = Rc::clone(self);
        let Some(ticker) = every(SIMULATION_TICK_MS, move || panel.play_simulation()) else {
            self.reading.set(false);
            self.stop_ticker();
            self.update_buttons();
            return;
        };
        *self.simulation.borrow_mut() = Some((
            ticker,
            Simulation {
                text: text.into_bytes(),
                sent: 0,
                bytes_per_tick: bytes_per_tick.max(1),
                truth,
            },
        ));
    }

    /// The simulated board's next piece; at the end of its text, the end of the session.
    fn play_simulation(&self) {
        let piece = {
            let mut simulation = self.simulation.borrow_mut();
            let Some((_, playing)) = simulation.as_mut() else {
                return;
            };
            let start = playing.sent;
            let end = (start + playing.bytes_per_tick).min(playing.text.len());
            playing.sent = end;
            playing.text.get(start..end).map(<[u8]>::to_vec)
        };
        match piece {
            Some(piece) if !piece.is_empty() => {
                self.session.borrow_mut().feed(&piece, now_ms() / 1e3);
                self.dirty.set(true);
            }
            _ => self.stop_simulation(),
        }
    }

    /// Ends the simulated board (at the end of its text, or on Disconnect).
    fn stop_simulation(&self) {
        let Some(((id, _tick), simulation)) = self.simulation.borrow_mut().take() else {
            return;
        };
        if let Some(window) = web_sys::window() {
            window.clear_interval_with_handle(id);
        }
        self.stop_ticker();
        self.reading.set(false);
        self.session.borrow_mut().port_closed();
        self.refit_and_draw();
        let n_lines = self.session.borrow().counts().n_lines;
        let [x, y, z] = simulation.truth.hard_iron_ut;
        self.set_state(
            "disconnected",
            &format!(
                "The simulated board stopped after {n_lines} lines. Its true hard iron was \
                 ({x:.2}, {y:.2}, {z:.2}) µT: compare the fit. Download the recording, or connect \
                 a real board."
            ),
        );
        self.update_buttons();
    }

    fn stop_reading(&self) {
        if let Some(reader) = self.reader.borrow().as_ref() {
            // The read loop then sees the stream end and closes the port.
            let _ = reader.cancel();
        }
    }

    /// Sends the latest fit (`saved` `None`) or a saved calibration to the board, and
    /// keeps the latest fit among the recent calibrations.
    async fn send_to_device(self: Rc<Self>, saved: Option<FieldCalibration>) {
        let port = self.port.borrow().clone();
        let Some(port) = port else {
            self.set_text(
                "live-confirmation",
                "Connect the board first: the calibration is sent over its port.",
            );
            return;
        };
        let packet = match saved {
            Some(calibration) => Some(self.session.borrow_mut().packet_for(calibration)),
            None => {
                self.refit_if_behind();
                let packet = self.session.borrow_mut().packet_for_device();
                self.keep_latest_fit();
                packet
            }
        };
        let Some(packet) = packet else {
            self.set_text(
                "live-confirmation",
                "No calibration yet: keep turning the board.",
            );
            return;
        };
        let writer = match port.writable().get_writer() {
            Ok(writer) => writer,
            Err(error) => {
                self.set_text(
                    "live-confirmation",
                    &format!(
                        "The port cannot be written to: {}.",
                        describe_js_error(error)
                    ),
                );
                return;
            }
        };
        let bytes = Uint8Array::from(packet.as_slice());
        let written = JsFuture::from(writer.write_with_chunk(&bytes)).await;
        writer.release_lock();
        match written {
            Ok(_) => self.show_confirmation(),
            Err(error) => self.set_text(
                "live-confirmation",
                &format!(
                    "The calibration could not be sent: {}. Connect again and retry.",
                    describe_js_error(error)
                ),
            ),
        }
    }

    fn download_recording(&self) {
        let session = self.session.borrow();
        let name = format!("compass-pdr-live-{}.txt", timestamp_for_file_name());
        download_bytes(&self.document, &name, session.raw(), "text/plain");
    }

    fn download_calibration_json(&self) {
        self.refit_if_behind();
        let session = self.session.borrow();
        let Some(quality) = session.quality() else {
            return;
        };
        let export = calibration_export(&quality.sensor_calibration());
        drop(session);
        self.keep_latest_fit();
        match calibration_json(&export) {
            Ok(text) => download_bytes(
                &self.document,
                "compass-pdr-calibration.json",
                text.as_bytes(),
                "application/json",
            ),
            Err(message) => self.set_text("live-confirmation", &message),
        }
    }

    fn download_c_snippet(&self) {
        self.refit_if_behind();
        let session = self.session.borrow();
        if let Some(quality) = session.quality() {
            let text = c_snippet(&quality.sensor_calibration());
            download_bytes(
                &self.document,
                "compass-pdr-calibration.h",
                text.as_bytes(),
                "text/plain",
            );
        }
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

    /// Refits and redraws on a timer while connected, apart from the read loop, so that
    /// reading never waits for drawing and the last bytes are always shown.
    fn start_ticker(self: &Rc<Self>) {
        let panel = Rc::clone(self);
        *self.ticker.borrow_mut() = every(DRAW_EVERY_MS, move || panel.tick());
    }

    fn stop_ticker(&self) {
        if let Some((id, _tick)) = self.ticker.borrow_mut().take() {
            if let Some(window) = web_sys::window() {
                window.clear_interval_with_handle(id);
            }
        }
    }

    /// Redraws when bytes came in; refits at most every [`REFIT_EVERY_MS`], and once
    /// more after the last bytes, so that the fit shown is always of everything received.
    fn tick(&self) {
        let now = now_ms();
        if self.dirty.replace(false) {
            self.refit_pending.set(true);
        } else if !self.refit_pending.get() {
            return;
        }
        if now - self.last_refit_ms.get() >= REFIT_EVERY_MS {
            self.last_refit_ms.set(now);
            self.refit_pending.set(false);
            self.refit();
        }
        self.draw();
    }

    /// Refits now when samples came in since the last refit (the ticker refits at most
    /// every [`REFIT_EVERY_MS`]), so that what is downloaded or sent is the fit of
    /// everything received, and the same fit for each of them.
    fn refit_if_behind(&self) {
        if self.dirty.replace(false) || self.refit_pending.replace(false) {
            self.last_refit_ms.set(now_ms());
            self.refit();
            self.draw();
        }
    }

    fn refit_and_draw(&self) {
        self.refit();
        self.draw();
    }

    fn refit(&self) {
        let mut session = self.session.borrow_mut();
        let message = session.refit().err();
        *self.fit_message.borrow_mut() = message;
    }

    /// The figures, the verdict and the plots.
    fn draw(&self) {
        let session = self.session.borrow();
        let counts = session.counts();
        self.set_text("live-lines", &counts.n_lines.to_string());
        self.set_text("live-samples", &counts.n_mag_samples.to_string());
        self.set_text("live-skipped-count", &counts.n_skipped_lines.to_string());
        self.set_text("live-bytes", &counts.n_bytes.to_string());
        self.set_text("live-format", counts.format.unwrap_or("not known yet"));
        let quality = session.quality();
        match quality {
            Some(quality) => {
                let cal = &quality.calibration;
                self.set_text(
                    "live-fit",
                    &format!(
                        "hard iron ({:.2}, {:.2}, {:.2}) µT, field {:.2} µT, residual RMS {:.2} µT, \
                         |B| spread {:.2} %, gaps {:.1} % ({} of {} regions covered){}",
                        cal.hard_iron_ut.x,
                        cal.hard_iron_ut.y,
                        cal.hard_iron_ut.z,
                        cal.field_ut,
                        quality.residual_rms_ut,
                        quality.field_spread_pct,
                        quality.coverage.gap_pct,
                        quality.coverage.n_covered,
                        quality.coverage.n_regions,
                        match (quality.expected_field_ut, quality.field_difference_pct) {
                            (Some(expected), Some(pct)) =>
                                format!(", {pct:+.1} % from the WMM's {expected:.1} µT"),
                            _ => ", no WMM comparison (type your latitude and longitude)".to_string(),
                        }
                    ),
                );
                let verdict = &quality.verdict;
                self.section
                    .set_attribute(
                        "data-good-enough",
                        if verdict.good_enough { "yes" } else { "no" },
                    )
                    .ok();
                self.set_text(
                    "live-verdict",
                    if verdict.good_enough {
                        "Good enough: send it to the board, or download it."
                    } else {
                        "Not good enough yet:"
                    },
                );
                self.fill_list("live-reasons", verdict.reasons.iter().cloned());
            }
            None => {
                self.section.set_attribute("data-good-enough", "no").ok();
                let message = self.fit_message.borrow().clone().unwrap_or_else(|| {
                    format!("No fit yet: it needs {MIN_FIT_SAMPLES} magnetometer samples.")
                });
                self.set_text("live-fit", &message);
                self.set_text("live-verdict", "");
                self.fill_list("live-reasons", std::iter::empty());
            }
        }
        let skipped = session.diagnostics();
        let shown = skipped
            .kept
            .iter()
            .take(MAX_SKIPPED_SHOWN)
            .map(|diagnostic| match diagnostic.line {
                Some(line) => format!("line {line}: {}", diagnostic.message),
                None => diagnostic.message.clone(),
            });
        let more = skipped
            .total()
            .checked_sub(MAX_SKIPPED_SHOWN)
            .filter(|&n| n > 0)
            .map(|n| format!("… and {n} more (all are in the recording)."));
        let mut items = shown.chain(more).peekable();
        let none = items.peek().is_none().then(|| "None.".to_string());
        self.fill_list("live-skipped", items.chain(none));
        self.show_confirmation_of(&session.confirmation());
        let samples = session.kept_samples_ut();
        let heading = session.latest_heading_rad();
        drop_errors(
            &self.clouds,
            canvas::draw_live_clouds(&self.clouds, samples, quality),
        );
        drop_errors(
            &self.coverage,
            canvas::draw_coverage(&self.coverage, quality.map(|quality| &quality.coverage)),
        );
        drop_errors(&self.dial, canvas::draw_dial(&self.dial, heading));
        drop(session);
        self.update_buttons();
    }

    fn show_confirmation(&self) {
        let confirmation = self.session.borrow().confirmation();
        self.show_confirmation_of(&confirmation);
    }

    fn show_confirmation_of(&self, confirmation: &Confirmation) {
        let (state, text) = match confirmation {
            Confirmation::NotSent => ("not-sent", String::new()),
            Confirmation::Waiting => (
                "waiting",
                "Sent the 68-byte MotionCal packet; waiting for the board to echo it (Cal1:/Cal2: lines)…"
                    .to_string(),
            ),
            Confirmation::Confirmed { line } => (
                "confirmed",
                format!("Confirmed: the board echoed the calibration sent (line {line})."),
            ),
            Confirmation::Differs { line, what } => (
                "differs",
                format!(
                    "The board echoed a different calibration (line {line}: {what}). Send it again; if \
                     it persists, the sketch does not store what it receives."
                ),
            ),
        };
        self.section.set_attribute("data-confirmation", state).ok();
        self.set_text("live-confirmation", &text);
    }

    fn update_buttons(&self) {
        let session = self.session.borrow();
        let has_fit = session.quality().is_some();
        let reading = self.reading.get();
        let has_port = self.port.borrow().is_some();
        self.connect.set_disabled(reading || serial().is_none());
        self.disconnect.set_disabled(!reading);
        self.send.set_disabled(!(reading && has_port && has_fit));
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

/// `navigator.serial`, when this browser has Web Serial.
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

/// `2026-11-21T22-05-09`, local time, for file names.
fn timestamp_for_file_name() -> String {
    let date = js_sys::Date::new_0();
    format!(
        "{:04}-{:02}-{:02}T{:02}-{:02}-{:02}",
        date.get_full_year(),
        date.get_month() + 1,
        date.get_date(),
        date.get_hours(),
        date.get_minutes(),
        date.get_seconds()
    )
}

fn drop_errors(canvas_element: &HtmlCanvasElement, result: Result<(), String>) {
    if let Err(message) = result {
        let _ = canvas::draw_message(
            canvas_element,
            &format!("This plot could not be drawn: {message}"),
        );
    }
}
