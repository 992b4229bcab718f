//! The answer first ([`crate::present::verdict`]): the grade, the headline, the method,
//! the answer's picture, the key figures and what to do, in the summary at the top of
//! the page (`#summary`), above the downloads' details.

use wasm_bindgen::JsCast;

use std::rc::Rc;

use gloo::events::EventListener;

use super::{Page, Results};
use crate::present::verdict::Verdict;
use crate::web::canvas;

/// The summary's element ids (see `www/index.html`).
const SUMMARY_ID: &str = "summary";
const FIGURES_ID: &str = "verdict-figures";
const PICTURE_FIGURE_ID: &str = "answer-figure";
const PICTURE_CANVAS_ID: &str = "answer-canvas";
const PICTURE_CAPTION_ID: &str = "answer-caption";
/// The picture's widest and narrowest layouts (CSS pixels): narrower than the least, the
/// plots' captions and labels no longer fit, and the picture is drawn at it and scaled
/// down to the figure.
const PICTURE_MAX_WIDTH_PX: f64 = 560.0;
const PICTURE_MIN_WIDTH_PX: f64 = 400.0;
/// Its height over its width: lower on a phone, where the picture shares the first
/// screen with the headline and the downloads.
const PICTURE_ASPECT: f64 = 0.56;
const PICTURE_NARROW_ASPECT: f64 = 0.5;

impl Page {
    /// Fills the summary with `verdict`, or empties it (`None`: an error, or no log yet).
    pub(super) fn show_verdict(&self, verdict: Option<&Verdict>) {
        if let Some(summary) = self.document.get_element_by_id(SUMMARY_ID) {
            let grade = verdict.map_or("", |verdict| verdict.grade.key());
            summary.set_attribute("data-grade", grade).ok();
            let kind = verdict.map_or("", |verdict| verdict.kind.key());
            summary.set_attribute("data-kind", kind).ok();
        }
        let Some(verdict) = verdict else {
            self.hide_picture();
            for id in ["verdict-grade", "verdict-method", "verdict-read"] {
                self.set_text(id, "");
            }
            self.set_text("verdict-headline", "No answer: see the message above.");
            self.fill_list("verdict-to-do", std::iter::empty());
            self.fill_figures(&[]);
            return;
        };
        self.set_text("verdict-grade", verdict.grade.word());
        self.set_text("verdict-headline", &verdict.headline);
        self.set_text("verdict-method", &verdict.method);
        self.set_text("verdict-read", &verdict.read);
        self.fill_list("verdict-to-do", verdict.to_do.iter().cloned());
        self.fill_figures(&verdict.figures);
    }

    /// Draws the answer's picture, laid out for the figure's width (a phone's is
    /// narrower than a desktop's), with its caption; a picture that cannot be drawn says
    /// why in its place.
    pub(super) fn draw_picture(&self, verdict: &Verdict, results: &Results) {
        let Some(figure) = self.document.get_element_by_id(PICTURE_FIGURE_ID) else {
            return;
        };
        let Some(canvas) = self
            .document
            .get_element_by_id(PICTURE_CANVAS_ID)
            .and_then(|element| element.dyn_into::<web_sys::HtmlCanvasElement>().ok())
        else {
            return;
        };
        let _ = figure.remove_attribute("hidden");
        let picture = verdict.picture;
        let _ = figure.set_attribute("data-picture", picture.key());
        self.set_text(PICTURE_CAPTION_ID, picture.caption());
        let width_px = picture_width_px(f64::from(figure.client_width()));
        let aspect = if width_px < PICTURE_MAX_WIDTH_PX {
            PICTURE_NARROW_ASPECT
        } else {
            PICTURE_ASPECT
        };
        let height_px = (width_px * aspect).round();
        let _ = canvas.set_attribute("data-width", &format!("{width_px}"));
        let _ = canvas.set_attribute("data-height", &format!("{height_px}"));
        let drawn = canvas::draw_answer_picture(
            &canvas,
            verdict,
            (&results.calibration, Some(&results.heading)),
            results.pdr.as_ref().ok(),
        );
        match drawn {
            // The heading drawn as "after", for the page's tests to hold to the headline.
            Ok(Some(label)) => {
                let _ = figure.set_attribute("data-shows", &label);
            }
            Ok(None) => {
                let _ = figure.remove_attribute("data-shows");
            }
            Err(message) => {
                let _ = figure.remove_attribute("data-shows");
                let _ = canvas::draw_message(
                    &canvas,
                    &format!("This plot could not be drawn: {message}"),
                );
            }
        }
        self.mark_time("data-picture-ms");
        // When this picture was drawn, on the page's clock (bench/drop_costs.mjs).
        if let Some(performance) = web_sys::window().and_then(|window| window.performance()) {
            let _ = figure.set_attribute("data-drawn-at", &format!("{:.1}", performance.now()));
        }
    }

    /// Draws the kept answer's picture again when the window's width changes the
    /// figure's (a phone turned, a window resized), so that its text stays legible.
    pub(super) fn wire_picture_resize(self: &Rc<Self>) {
        let Some(window) = web_sys::window() else {
            return;
        };
        let page = Rc::clone(self);
        EventListener::new(&window, "resize", move |_| {
            let Some(results) = page.results.borrow().clone() else {
                return;
            };
            let (Some(figure), Some(canvas)) = (
                page.document.get_element_by_id(PICTURE_FIGURE_ID),
                page.document.get_element_by_id(PICTURE_CANVAS_ID),
            ) else {
                return;
            };
            let drawn_px = canvas
                .get_attribute("data-width")
                .and_then(|width| width.parse::<f64>().ok());
            let wanted_px = picture_width_px(f64::from(figure.client_width()));
            if drawn_px.is_some_and(|drawn_px| (drawn_px - wanted_px).abs() < 8.0) {
                return;
            }
            if let Some(verdict) = page.answer.borrow().as_ref() {
                page.draw_picture(verdict, &results);
            }
        })
        .forget();
    }

    /// No answer, no picture.
    fn hide_picture(&self) {
        *self.answer.borrow_mut() = None;
        if let Some(figure) = self.document.get_element_by_id(PICTURE_FIGURE_ID) {
            let _ = figure.set_attribute("hidden", "");
            let _ = figure.remove_attribute("data-picture");
        }
    }

    /// The key figures as a description list: label, then value.
    fn fill_figures(&self, figures: &[crate::present::verdict::Figure]) {
        let Some(list) = self.document.get_element_by_id(FIGURES_ID) else {
            return;
        };
        list.set_text_content(None);
        for figure in figures {
            for (tag, text) in [("dt", &figure.label), ("dd", &figure.value)] {
                if let Ok(element) = self.document.create_element(tag) {
                    element.set_text_content(Some(&crate::web::wording::for_page(text)));
                    let _ = list.append_child(&element);
                }
            }
        }
    }
}

/// The width (CSS pixels) the picture is laid out for in a figure `client_px` wide.
fn picture_width_px(client_px: f64) -> f64 {
    client_px
        .clamp(PICTURE_MIN_WIDTH_PX, PICTURE_MAX_WIDTH_PX)
        .round()
}
