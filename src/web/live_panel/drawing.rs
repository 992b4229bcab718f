//! What the panel shows while samples arrive: the timer that refits and redraws apart
//! from the read loop, the figures (counts, the fit, the verdict and its reasons, the
//! skipped lines, the board's confirmation), the three plots and the 3D view (turned by
//! a drag or the arrow keys).

use std::rc::Rc;

use gloo::events::EventListener;
use wasm_bindgen::JsCast;
use web_sys::{HtmlCanvasElement, KeyboardEvent, MouseEvent};

use super::{every, now_ms, LivePanel};
use crate::io::Diagnostics;
use crate::live::{Confirmation, LiveQuality, MIN_FIT_SAMPLES};
use crate::web::canvas;

/// Refits this often while samples arrive (ms).
const REFIT_EVERY_MS: f64 = 500.0;
/// Redraws the plots and figures this often (ms).
const DRAW_EVERY_MS: f64 = 250.0;

/// How far the 3D view turns by itself at each redraw while samples arrive (rad): a
/// turn in about 40 s.
const SPHERE_TURN_PER_DRAW_RAD: f64 = 0.04;
/// How far an arrow key turns the 3D view, as a drag of this many pixels.
const SPHERE_KEY_STEP_PX: f64 = 24.0;

/// Skipped lines listed at most (all are counted).
const MAX_SKIPPED_SHOWN: usize = 20;

impl LivePanel {
    /// Refits and redraws on a timer while connected, apart from the read loop, so that
    /// reading never waits for drawing and the last bytes are always shown.
    pub(super) fn start_ticker(self: &Rc<Self>) {
        let panel = Rc::clone(self);
        *self.ticker.borrow_mut() = every(DRAW_EVERY_MS, move || panel.tick());
    }

    pub(super) fn stop_ticker(&self) {
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
        if !self.user_turned.get() {
            let view = self.sphere_view.get();
            self.sphere_view
                .set(crate::present::plot::sphere_view::SphereView {
                    yaw_rad: (view.yaw_rad + SPHERE_TURN_PER_DRAW_RAD) % std::f64::consts::TAU,
                    ..view
                });
        }
        self.draw();
    }

    /// The 3D view turns with a drag (mouse, pen or finger) and with the arrow keys
    /// once focused; then it no longer turns by itself.
    pub(super) fn wire_sphere(self: &Rc<Self>) {
        let listen = |event: &'static str, action: fn(&LivePanel, &web_sys::Event)| {
            let panel = Rc::clone(self);
            EventListener::new(&self.sphere, event, move |event| action(&panel, event)).forget();
        };
        listen("pointerdown", |panel, event| {
            if let Some(event) = event.dyn_ref::<MouseEvent>() {
                panel.user_turned.set(true);
                let at = (event.client_x(), event.client_y());
                panel.drag_from.set(Some(at));
            }
        });
        listen("pointermove", |panel, event| {
            if let (Some(from), Some(event)) =
                (panel.drag_from.get(), event.dyn_ref::<MouseEvent>())
            {
                let at = (event.client_x(), event.client_y());
                panel.drag_from.set(Some(at));
                panel.turn_sphere(at.0 - from.0, at.1 - from.1);
            }
        });
        for end in ["pointerup", "pointercancel", "pointerleave"] {
            listen(end, |panel, _| panel.drag_from.set(None));
        }
        listen("keydown", |panel, event| {
            let Some(event) = event.dyn_ref::<KeyboardEvent>() else {
                return;
            };
            let (dx, dy) = match event.key().as_str() {
                "ArrowLeft" => (-SPHERE_KEY_STEP_PX, 0.0),
                "ArrowRight" => (SPHERE_KEY_STEP_PX, 0.0),
                "ArrowUp" => (0.0, -SPHERE_KEY_STEP_PX),
                "ArrowDown" => (0.0, SPHERE_KEY_STEP_PX),
                _ => return,
            };
            event.prevent_default();
            panel.user_turned.set(true);
            panel.turn_sphere(dx, dy);
        });
    }

    /// Turns the 3D view by a drag of `(dx, dy)` CSS pixels and redraws it alone.
    fn turn_sphere(&self, dx_px: f64, dy_px: f64) {
        let size_px = f64::from(self.sphere.client_width());
        self.sphere_view
            .set(self.sphere_view.get().dragged(dx_px, dy_px, size_px));
        let session = self.session.borrow();
        self.draw_sphere(session.kept_samples_ut(), session.quality());
    }

    fn draw_sphere(&self, samples_ut: &[nalgebra::Vector3<f64>], quality: Option<&LiveQuality>) {
        drop_errors(
            &self.sphere,
            canvas::draw_sphere(&self.sphere, samples_ut, quality, self.sphere_view.get()),
        );
    }

    /// Refits now when samples came in since the last refit (the ticker refits at most
    /// every [`REFIT_EVERY_MS`]), so that what is downloaded or sent is the fit of
    /// everything received, and the same fit for each of them.
    pub(super) fn refit_if_behind(&self) {
        if self.dirty.replace(false) || self.refit_pending.replace(false) {
            self.last_refit_ms.set(now_ms());
            self.refit();
            self.draw();
        }
    }

    pub(super) fn refit_and_draw(&self) {
        self.refit();
        self.draw();
    }

    fn refit(&self) {
        let started_ms = now_ms();
        let mut session = self.session.borrow_mut();
        let message = session.refit().err().map(|error| error.to_string());
        *self.fit_message.borrow_mut() = message;
        drop(session);
        self.note_time(now_ms() - started_ms, false);
    }

    /// Keeps the longest refit (or redraw) on the panel: the page's thread does both, and
    /// the end-to-end tests hold them under the main-thread bound.
    fn note_time(&self, took_ms: f64, draw: bool) {
        let (refit_ms, draw_ms) = self.longest_ms.get();
        let longest = if draw {
            (refit_ms, draw_ms.max(took_ms))
        } else {
            (refit_ms.max(took_ms), draw_ms)
        };
        if longest != (refit_ms, draw_ms) {
            self.longest_ms.set(longest);
            let (name, value) = if draw {
                ("data-longest-draw-ms", longest.1)
            } else {
                ("data-longest-refit-ms", longest.0)
            };
            self.section
                .set_attribute(name, &format!("{value:.1}"))
                .ok();
        }
    }

    /// The figures, the verdict and the plots.
    pub(super) fn draw(&self) {
        let started_ms = now_ms();
        self.draw_figures();
        self.note_time(now_ms() - started_ms, true);
    }

    fn draw_figures(&self) {
        let session = self.session.borrow();
        let counts = session.counts();
        self.set_text("live-lines", &counts.n_lines.to_string());
        self.set_text("live-samples", &counts.n_mag_samples.to_string());
        self.set_text("live-skipped-count", &counts.n_skipped_lines.to_string());
        self.set_text("live-bytes", &counts.n_bytes.to_string());
        self.set_text("live-format", counts.format.unwrap_or("not known yet"));
        let quality = session.quality();
        self.show_fit_and_verdict(quality);
        self.show_skipped(session.diagnostics());
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
        drop_errors(
            &self.dial,
            canvas::draw_dial(&self.dial, heading, session.filter_heading_rad()),
        );
        self.draw_sphere(samples, quality);
        drop(session);
        self.update_buttons();
    }

    /// The fit's figures and whether it is good enough (with the reasons when it is
    /// not), or why there is no fit yet.
    fn show_fit_and_verdict(&self, quality: Option<&LiveQuality>) {
        match quality {
            Some(quality) => {
                let cal = &quality.calibration;
                self.set_text(
                    "live-fit",
                    &format!(
                        "hard iron ({:.2}, {:.2}, {:.2}) µT, field {:.2} µT, residual RMS {:.2} µT, \
                         |B| spread {:.2} %, gaps {:.1} % ({} of {} regions covered){}; {}",
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
                        },
                        quality.held_back.summary()
                    ),
                );
                let (verdict, send) = (&quality.verdict, &quality.send);
                let yes_no = |yes: bool| if yes { "yes" } else { "no" };
                self.section
                    .set_attribute("data-good-enough", yes_no(verdict.good_enough))
                    .ok();
                self.section
                    .set_attribute("data-sendable", yes_no(send.sendable))
                    .ok();
                self.set_text(
                    "live-verdict",
                    match (verdict.good_enough, send.sendable) {
                        (_, true) => {
                            "Good enough, and better than the calibration in force on the samples \
                             held back: send it to the board, or download it."
                        }
                        (true, false) => {
                            "Good enough, but it will not be sent: the calibration in force is \
                             kept, because"
                        }
                        (false, false) => "Not good enough yet:",
                    },
                );
                // The decision's reasons: the verdict's first, then the held-back check's
                // and the bounds'.
                self.fill_list("live-reasons", send.reasons.iter().cloned());
                if send.sendable {
                    let mut refusal = self.refusal.borrow_mut();
                    if refusal
                        .as_ref()
                        .is_some_and(|refusal| refusal.of_latest_fit)
                    {
                        refusal.take();
                    }
                }
            }
            None => {
                self.section.set_attribute("data-good-enough", "no").ok();
                self.section.set_attribute("data-sendable", "no").ok();
                let message = self.fit_message.borrow().clone().unwrap_or_else(|| {
                    format!("No fit yet: it needs {MIN_FIT_SAMPLES} magnetometer samples.")
                });
                self.set_text("live-fit", &message);
                self.set_text("live-verdict", "");
                self.fill_list("live-reasons", std::iter::empty());
            }
        }
    }

    /// The lines skipped (the first [`MAX_SKIPPED_SHOWN`], the rest counted).
    fn show_skipped(&self, skipped: &Diagnostics) {
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
    }

    pub(super) fn show_confirmation(&self) {
        let confirmation = self.session.borrow().confirmation();
        self.show_confirmation_of(&confirmation);
    }

    fn show_confirmation_of(&self, confirmation: &Confirmation) {
        if let Some(refusal) = self.refusal.borrow().as_ref() {
            self.section
                .set_attribute("data-confirmation", "refused")
                .ok();
            self.set_text("live-confirmation", &refusal.text);
            return;
        }
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
}

fn drop_errors(canvas_element: &HtmlCanvasElement, result: Result<(), String>) {
    if let Err(message) = result {
        let _ = canvas::draw_message(
            canvas_element,
            &format!("This plot could not be drawn: {message}"),
        );
    }
}
