//! Zoom, pan and the value under the pointer on the page's time plots (heading error,
//! |B|) and the dead-reckoned trajectory: Ctrl + wheel (a trackpad's pinch) or the `+`
//! and `-` keys zoom about the pointer, a drag pans, a double click or `0` shows the
//! whole plot again, and the values under the pointer are written under the figure. The
//! plots apply the zoom and say where they drew (`present::plot::zoom`); this room
//! keeps each canvas's zoom and last frame, and redraws that one figure from the kept
//! results. A new analysis starts unzoomed.

use std::cell::{Cell, RefCell};
use std::rc::Rc;

use gloo::events::{EventListener, EventListenerOptions};
use wasm_bindgen::JsCast;
use web_sys::{Event, KeyboardEvent, MouseEvent, WheelEvent};

use super::show::{Canvas, FIGURES};
use super::Page;
use crate::present::plot::zoom::{PlotFrame, Zoom};
use crate::web::dom;

/// The canvases that zoom.
const ZOOMABLE: [Canvas; 3] = [Canvas::Heading, Canvas::Field, Canvas::Trajectory];
/// One wheel notch (100 px) or key press zooms by this factor.
const ZOOM_PER_STEP: f64 = 1.25;
/// What the readout says while the pointer is elsewhere.
const HINT: &str = "Ctrl + wheel (or pinch, or + and −) zooms, a drag pans, a double click \
                    (or 0) shows the whole plot.";

/// Each zoomable canvas's zoom and the frame it was last drawn in, in [`ZOOMABLE`]'s
/// order, and the drag under way (which canvas, and where the pointer was).
#[derive(Default)]
pub(super) struct Zooms {
    views: [(Cell<Zoom>, RefCell<Option<PlotFrame>>); 3],
    drag: Cell<Option<(usize, (f64, f64))>>,
}

impl Zooms {
    pub(super) fn zoom_of(&self, canvas: Canvas) -> Zoom {
        slot(canvas)
            .and_then(|idx| self.views.get(idx))
            .map_or(Zoom::WHOLE, |(zoom, _)| zoom.get())
    }

    pub(super) fn keep_frame(&self, canvas: Canvas, frame: Option<PlotFrame>) {
        if let Some((_, kept)) = slot(canvas).and_then(|idx| self.views.get(idx)) {
            *kept.borrow_mut() = frame;
        }
    }

    /// Every plot unzoomed (a new analysis).
    pub(super) fn reset(&self) {
        for (zoom, frame) in &self.views {
            zoom.set(Zoom::WHOLE);
            frame.borrow_mut().take();
        }
    }
}

fn slot(canvas: Canvas) -> Option<usize> {
    ZOOMABLE.iter().position(|&zoomable| zoomable == canvas)
}

impl Page {
    /// Listens on the zoomable canvases.
    pub(super) fn wire_zoom(self: &Rc<Self>) {
        for (idx, canvas) in ZOOMABLE.into_iter().enumerate() {
            let element = self.canvas(canvas).clone();
            let _ = element.set_attribute("tabindex", "0");
            let listen = |name: &'static str, action: fn(&Page, usize, &Event)| {
                let page = Rc::clone(self);
                let options = EventListenerOptions::enable_prevent_default();
                EventListener::new_with_options(&element, name, options, move |event| {
                    action(&page, idx, event);
                })
                .forget();
            };
            listen("wheel", |page, idx, event| {
                let Some(wheel) = event.dyn_ref::<WheelEvent>() else {
                    return;
                };
                // A plain wheel scrolls the page; Ctrl + wheel (a pinch) zooms.
                if wheel.ctrl_key() || wheel.meta_key() {
                    event.prevent_default();
                    let notches =
                        wheel.delta_y() / if wheel.delta_mode() == 0 { 100.0 } else { 3.0 };
                    page.zoom_at(idx, wheel, ZOOM_PER_STEP.powf(-notches));
                }
            });
            listen("pointerdown", |page, idx, event| {
                if let Some(at) = page.pointer(idx, event) {
                    page.zooms.drag.set(Some((idx, at)));
                }
            });
            listen("pointermove", |page, idx, event| {
                let Some(at) = page.pointer(idx, event) else {
                    return;
                };
                match page.zooms.drag.get() {
                    Some((dragged, from)) if dragged == idx => {
                        page.zooms.drag.set(Some((idx, at)));
                        page.change_zoom(idx, |zoom, frame| {
                            let by = frame.fraction_of_move((at.0 - from.0, at.1 - from.1));
                            zoom.panned(by, frame.both_axes)
                        });
                    }
                    _ => page.show_readout(idx, Some(at)),
                }
            });
            for end in ["pointerup", "pointercancel", "pointerleave"] {
                listen(end, |page, idx, event| {
                    page.zooms.drag.set(None);
                    if event.type_() == "pointerleave" {
                        page.show_readout(idx, None);
                    }
                });
            }
            listen("dblclick", |page, idx, _| {
                page.change_zoom(idx, |_, _| Zoom::WHOLE);
            });
            listen("keydown", |page, idx, event| {
                let Some(key) = event.dyn_ref::<KeyboardEvent>().map(KeyboardEvent::key) else {
                    return;
                };
                let factor = match key.as_str() {
                    "+" | "=" => ZOOM_PER_STEP,
                    "-" | "_" => 1.0 / ZOOM_PER_STEP,
                    "0" => return page.change_zoom(idx, |_, _| Zoom::WHOLE),
                    _ => return,
                };
                event.prevent_default();
                page.change_zoom(idx, |zoom, frame| {
                    zoom.zoomed((0.5, 0.5), factor, frame.both_axes)
                });
            });
            self.show_readout(idx, None);
        }
    }

    /// The pointer's position on canvas `idx` in the plot's own pixels (the canvas is
    /// drawn at its `data-width` and shown at whatever width the page gives it).
    fn pointer(&self, idx: usize, event: &Event) -> Option<(f64, f64)> {
        let event = event.dyn_ref::<MouseEvent>()?;
        let canvas = self.canvas(*ZOOMABLE.get(idx)?);
        let (width, height) = crate::web::canvas::logical_size(canvas);
        let scale = |logical: u32, shown: i32| f64::from(logical) / f64::from(shown.max(1));
        Some((
            event.offset_x() * scale(width, canvas.client_width()),
            event.offset_y() * scale(height, canvas.client_height()),
        ))
    }

    fn zoom_at(&self, idx: usize, event: &MouseEvent, factor: f64) {
        let Some(at) = self.pointer(idx, event) else {
            return;
        };
        self.change_zoom(idx, |zoom, frame| {
            let fraction = frame.fraction_at(at).unwrap_or((0.5, 0.5));
            zoom.zoomed(fraction, factor, frame.both_axes)
        });
    }

    /// Applies `change` to canvas `idx`'s zoom (given its last frame) and redraws it;
    /// nothing before the canvas has been drawn with the kept results.
    fn change_zoom(&self, idx: usize, change: impl FnOnce(Zoom, &PlotFrame) -> Zoom) {
        let (Some(canvas), Some((zoom, frame))) = (ZOOMABLE.get(idx), self.zooms.views.get(idx))
        else {
            return;
        };
        let Some(new_zoom) = frame
            .borrow()
            .as_ref()
            .map(|frame| change(zoom.get(), frame))
        else {
            return;
        };
        if new_zoom == zoom.get() {
            return;
        }
        zoom.set(new_zoom);
        let results = self.results.borrow().clone();
        let figure = FIGURES
            .into_iter()
            .find(|figure| figure.canvas() == *canvas);
        if let (Some(results), Some(figure)) = (results, figure) {
            self.draw_figure(figure, &results);
        }
    }

    /// The values under the pointer under canvas `idx`, or how to zoom.
    fn show_readout(&self, idx: usize, at: Option<(f64, f64)>) {
        let (Some(canvas), Some((_, frame))) = (ZOOMABLE.get(idx), self.zooms.views.get(idx))
        else {
            return;
        };
        let readout = at.and_then(|at| frame.borrow().as_ref()?.readout(at));
        let id = format!("{}-readout", self.canvas(*canvas).id());
        dom::set_text(&self.document, &id, readout.as_deref().unwrap_or(HINT));
    }
}
