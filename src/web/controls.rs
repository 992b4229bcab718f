//! The analysis controls: which calibration methods run, the train/check split, the
//! declination, the GNSS outages and the step model, as form fields, and the timeline
//! they can be brushed on.
//!
//! The fields are the state (a keyboard user types `240-840` where a mouse user drags);
//! the timeline only writes into them. A change re-runs what depends on it: the split,
//! the declination and the methods re-run the calibration and everything after it; the
//! outages and the step model re-run only the dead reckoning.

use std::rc::Rc;

use gloo::events::EventListener;
use wasm_bindgen::JsCast;
use web_sys::{Document, HtmlCanvasElement, HtmlInputElement, HtmlSelectElement, MouseEvent};

use super::page::Page;
use crate::analysis::calibration::{CalibrationOptions, DeclinationChoice, Method};
use crate::pdr::fusion::{parse_outages, Outage};
use crate::pdr::step_length::StepModelKind;
use crate::pdr::PdrOptions;
use crate::present::plot::timeline::Timeline;

const DECLINATION_ID: &str = "control-declination";
const SPLIT_ID: &str = "control-split";
const OUTAGES_ID: &str = "control-outages";
const STEP_MODEL_ID: &str = "control-step-model";
const KNOWN_DISTANCE_ID: &str = "control-known-distance";
pub const TIMELINE_ID: &str = "timeline";
const STATUS_ID: &str = "controls-status";

/// What a change re-runs.
pub use crate::pipeline::Stage;

/// The controls as read from the form.
#[derive(Debug, Clone, PartialEq)]
pub struct Controls {
    pub declination_deg: Option<f64>,
    pub train_until_s: Option<f64>,
    pub outages: Vec<Outage>,
    pub step_model: StepModelKind,
    /// The walk's length when it is known (a measured route): trains the step model.
    pub known_distance_m: Option<f64>,
    pub methods: Vec<Method>,
}

impl Controls {
    /// The options of every stage of the pipeline.
    pub fn options(&self) -> PdrOptions {
        let mut options = PdrOptions {
            step_model: self.step_model,
            known_distance_m: self.known_distance_m,
            ..PdrOptions::default()
        };
        options.gnss.outages = self.outages.clone();
        options.heading_options.calibration = CalibrationOptions {
            methods: self.methods.clone(),
            train_until_s: self.train_until_s,
            declination: self
                .declination_deg
                .map_or(DeclinationChoice::Auto, DeclinationChoice::Degrees),
            ..CalibrationOptions::default()
        };
        options
    }
}

/// Reads the form; a field that cannot be read is named in the controls' status line
/// and left at its default, so the analysis still runs.
pub fn read(document: &Document) -> Controls {
    let mut problems = Vec::new();
    let number = |id: &str, what: &str, problems: &mut Vec<String>| -> Option<f64> {
        let input = input(document, id)?;
        let text = input.value();
        if text.trim().is_empty() {
            return None;
        }
        let value = input.value_as_number();
        if value.is_finite() {
            Some(value)
        } else {
            problems.push(format!(
                "{what}: \"{text}\" is not a number; it is left out"
            ));
            None
        }
    };
    let declination_deg = number(DECLINATION_ID, "Declination", &mut problems)
        .filter(|deg| (-180.0..=180.0).contains(deg));
    let train_until_s = number(SPLIT_ID, "Train until", &mut problems).filter(|s| *s > 0.0);
    let known_distance_m =
        number(KNOWN_DISTANCE_ID, "Known distance", &mut problems).filter(|m| *m > 0.0);
    let outages = match input(document, OUTAGES_ID).map(|input| input.value()) {
        Some(text) => parse_outages(&text).unwrap_or_else(|error| {
            problems.push(format!("GNSS outages: {error}"));
            Vec::new()
        }),
        None => Vec::new(),
    };
    let step_model = document
        .get_element_by_id(STEP_MODEL_ID)
        .and_then(|element| element.dyn_into::<HtmlSelectElement>().ok())
        .and_then(|select| StepModelKind::parse(&select.value()))
        .unwrap_or(StepModelKind::Weinberg);
    let methods: Vec<Method> = Method::ALL
        .into_iter()
        .filter(|method| {
            input(document, &format!("control-method-{}", method.key()))
                .is_none_or(|checkbox| checkbox.checked())
        })
        .collect();
    if methods.is_empty() {
        problems.push("Methods: none is ticked; all run".to_string());
    }
    if let Some(status) = document.get_element_by_id(STATUS_ID) {
        status.set_text_content(Some(&problems.join(". ")));
    }
    Controls {
        declination_deg,
        train_until_s,
        outages,
        step_model,
        known_distance_m,
        methods: if methods.is_empty() {
            Method::ALL.to_vec()
        } else {
            methods
        },
    }
}

fn input(document: &Document, id: &str) -> Option<HtmlInputElement> {
    document
        .get_element_by_id(id)
        .and_then(|element| element.dyn_into::<HtmlInputElement>().ok())
}

/// Wires the fields (a change re-runs its stage) and the timeline's brushing.
pub fn wire(page: &Rc<Page>) {
    let document = &page.document;
    let mut fields: Vec<(String, Stage)> = vec![
        (DECLINATION_ID.to_string(), Stage::Calibration),
        (SPLIT_ID.to_string(), Stage::Calibration),
        (OUTAGES_ID.to_string(), Stage::DeadReckoning),
        (STEP_MODEL_ID.to_string(), Stage::DeadReckoning),
        (KNOWN_DISTANCE_ID.to_string(), Stage::DeadReckoning),
    ];
    for method in Method::ALL {
        fields.push((
            format!("control-method-{}", method.key()),
            Stage::Calibration,
        ));
    }
    for (id, stage) in fields {
        let Some(element) = document.get_element_by_id(&id) else {
            continue;
        };
        let page = Rc::clone(page);
        EventListener::new(&element, "change", move |_| page.rerun(stage)).forget();
    }
    let Some(canvas) = document
        .get_element_by_id(TIMELINE_ID)
        .and_then(|element| element.dyn_into::<HtmlCanvasElement>().ok())
    else {
        return;
    };
    let pressed_at: Rc<std::cell::Cell<Option<f64>>> = Rc::new(std::cell::Cell::new(None));
    let pressed = Rc::clone(&pressed_at);
    let canvas_for_down = canvas.clone();
    EventListener::new(&canvas, "mousedown", move |event| {
        if let Some(event) = event.dyn_ref::<MouseEvent>() {
            pressed.set(Some(canvas_x(&canvas_for_down, event)));
        }
    })
    .forget();
    let page = Rc::clone(page);
    let canvas_for_up = canvas.clone();
    EventListener::new(&canvas, "mouseup", move |event| {
        let (Some(event), Some(down_x)) = (event.dyn_ref::<MouseEvent>(), pressed_at.take()) else {
            return;
        };
        let Some(timeline) = page.timeline() else {
            return;
        };
        let up_x = canvas_x(&canvas_for_up, event);
        let width = f64::from(super::canvas::logical_size(&canvas_for_up).0);
        let (t0, t1) = (
            timeline.time_at(down_x.min(up_x), width),
            timeline.time_at(down_x.max(up_x), width),
        );
        let is_click = (up_x - down_x).abs() < 4.0;
        let stage = brush(&page.document, &timeline, t0, t1, is_click);
        if let Some(stage) = stage {
            page.rerun(stage);
        }
    })
    .forget();
}

/// The pointer's x in the canvas's layout pixels (it may be shown scaled).
fn canvas_x(canvas: &HtmlCanvasElement, event: &MouseEvent) -> f64 {
    let shown_px = f64::from(canvas.client_width().max(1));
    event.offset_x() * f64::from(super::canvas::logical_size(canvas).0) / shown_px
}

/// Writes a brush into the fields: in outage mode a drag adds an outage and a click
/// removes the one under it; in split mode the train part ends where the pointer was
/// released. Returns the stage to re-run.
fn brush(
    document: &Document,
    timeline: &Timeline,
    t0: f64,
    t1: f64,
    is_click: bool,
) -> Option<Stage> {
    let split_mode = input(document, "brush-split").is_some_and(|radio| radio.checked());
    if split_mode {
        let field = input(document, SPLIT_ID)?;
        field.set_value(&format!("{t1:.1}"));
        return Some(Stage::Calibration);
    }
    let field = input(document, OUTAGES_ID)?;
    let mut outages = parse_outages(&field.value()).unwrap_or_default();
    if is_click {
        let before = outages.len();
        outages.retain(|outage| !outage.contains(t1));
        if outages.len() == before {
            return None;
        }
    } else {
        let (start_s, end_s) = (t0.max(timeline.start_s), t1.min(timeline.end_s));
        if end_s - start_s < 1.0 {
            return None;
        }
        outages.push(Outage { start_s, end_s });
    }
    let text: Vec<String> = outages
        .iter()
        .map(|outage| format!("{:.0}-{:.0}", outage.start_s, outage.end_s))
        .collect();
    field.set_value(&text.join(", "));
    Some(Stage::DeadReckoning)
}
