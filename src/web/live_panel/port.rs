//! The serial port: asking for one and opening it, the read loop that hands every chunk
//! to the session until the stream ends or fails (an unplug), closing it, and sending a
//! calibration back to the board as MotionCal's packet.

use std::rc::Rc;

use js_sys::Uint8Array;
use wasm_bindgen::JsCast;
use wasm_bindgen_futures::JsFuture;
use web_sys::{ReadableStreamDefaultReader, SerialOptions, SerialPort};

use super::{now_ms, refusal_text, serial, LivePanel, Refusal};
use crate::fit::model::FieldCalibration;
use crate::web::page::describe_js_error;

impl LivePanel {
    /// Asks for a port, opens it and reads it until it ends.
    pub(super) async fn connect_and_read(self: Rc<Self>) {
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

    pub(super) fn stop_reading(&self) {
        if let Some(reader) = self.reader.borrow().as_ref() {
            // The read loop then sees the stream end and closes the port.
            let _ = reader.cancel();
        }
    }

    /// Sends the latest fit (`saved` `None`) or a saved calibration to the board, and
    /// keeps the latest fit among the recent calibrations, when the core's decision
    /// allows it (good enough, better than the calibration in force on the samples held
    /// back, inside the bounds); otherwise sends nothing and says why.
    pub(super) async fn send_to_device(self: Rc<Self>, saved: Option<FieldCalibration>) {
        let port = self.port.borrow().clone();
        let Some(port) = port else {
            self.set_text(
                "live-confirmation",
                "Connect the board first: the calibration is sent over its port.",
            );
            return;
        };
        let packet = match saved {
            Some(calibration) => self.session.borrow_mut().packet_for(calibration),
            None => {
                self.refit_if_behind();
                let packet = self.session.borrow_mut().packet_for_device();
                if packet.is_ok() {
                    self.keep_latest_fit();
                }
                packet
            }
        };
        let packet = match packet {
            Ok(packet) => {
                self.refusal.borrow_mut().take();
                packet
            }
            Err(reasons) => {
                *self.refusal.borrow_mut() = Some(Refusal {
                    of_latest_fit: saved.is_none(),
                    text: refusal_text(&reasons),
                });
                self.show_confirmation();
                // A click that got through a disabled button (a race with a redraw).
                self.update_buttons();
                return;
            }
        };
        let writer = match port.writable().get_writer() {
            Ok(writer) => writer,
            Err(error) => {
                // Nothing reached the board: the calibration in force is what it was.
                self.session.borrow_mut().send_failed();
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
            Err(error) => {
                self.session.borrow_mut().send_failed();
                self.set_text(
                    "live-confirmation",
                    &format!(
                        "The calibration could not be sent: {}. Connect again and retry.",
                        describe_js_error(error)
                    ),
                );
            }
        }
    }
}
