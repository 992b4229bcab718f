//! The answer first ([`crate::present::verdict`]): the grade, the headline, the method,
//! the key figures and what to do, in the summary at the top of the page (`#summary`),
//! above the downloads' details.

use wasm_bindgen::JsCast;

use super::Page;
use crate::present::verdict::Verdict;

/// The summary's element ids (see `www/index.html`).
const SUMMARY_ID: &str = "summary";
const FIGURES_ID: &str = "verdict-figures";
const COVERAGE_FIGURE_ID: &str = "verdict-coverage-figure";
const COVERAGE_CANVAS_ID: &str = "verdict-coverage";

impl Page {
    /// Fills the summary with `verdict`, or empties it (`None`: an error, or no log yet).
    pub(super) fn show_verdict(&self, verdict: Option<&Verdict>) {
        if let Some(summary) = self.document.get_element_by_id(SUMMARY_ID) {
            let grade = verdict.map_or("", |verdict| verdict.grade.key());
            summary.set_attribute("data-grade", grade).ok();
            let kind = verdict.map_or("", |verdict| verdict.kind.key());
            summary.set_attribute("data-kind", kind).ok();
        }
        self.show_coverage(verdict.and_then(|verdict| verdict.coverage.as_ref()));
        let Some(verdict) = verdict else {
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

    /// A calibration-only log's coverage map under the summary; hidden for the others.
    fn show_coverage(&self, coverage: Option<&crate::fit::coverage::SphereCoverage>) {
        let Some(figure) = self.document.get_element_by_id(COVERAGE_FIGURE_ID) else {
            return;
        };
        let canvas = self
            .document
            .get_element_by_id(COVERAGE_CANVAS_ID)
            .and_then(|element| element.dyn_into::<web_sys::HtmlCanvasElement>().ok());
        match (coverage, canvas) {
            (Some(coverage), Some(canvas)) => {
                let _ = figure.remove_attribute("hidden");
                if let Err(message) = crate::web::canvas::draw_coverage(&canvas, Some(coverage)) {
                    let _ = crate::web::canvas::draw_message(
                        &canvas,
                        &format!("This plot could not be drawn: {message}"),
                    );
                }
            }
            _ => {
                let _ = figure.set_attribute("hidden", "");
            }
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
