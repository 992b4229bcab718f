//! The exports: every file the page offers for download, written by the core (calibration
//! JSON and C snippet, corrected CSV, the attitude filter's headings, the track as GeoJSON
//! and GPX, the HTML report) or
//! taken from a canvas (PNG), and the download itself.

use std::rc::Rc;

use gloo::events::EventListener;
use js_sys::Uint8Array;
use wasm_bindgen::closure::Closure;
use wasm_bindgen::JsCast;
use web_sys::{Document, HtmlButtonElement, HtmlCanvasElement};

use super::dom::set_text;
use super::page::{Page, Results};
use crate::fit::export::{c_snippet, CalibrationExport};
use crate::io::recording::Recording;
use crate::pdr::export::{track_text, TrackFormat};
use crate::pipeline;
use crate::present::report::{
    corrected_csv, device_export, device_export_or_why, escape_html, html_report, ReportFigure,
    ReportSection,
};

/// The analysis exports: button id, what it writes.
const ANALYSIS_EXPORTS: [(&str, Export); 8] = [
    ("export-calibration", Export::CalibrationJson),
    ("export-snippet", Export::CSnippet),
    ("export-param", Export::AutopilotParams),
    ("export-csv", Export::CorrectedCsv),
    ("export-attitude", Export::AttitudeCsv),
    ("export-geojson", Export::Track(TrackFormat::GeoJson)),
    ("export-gpx", Export::Track(TrackFormat::Gpx)),
    ("export-report", Export::HtmlReport),
];

#[derive(Debug, Clone, Copy)]
enum Export {
    CalibrationJson,
    CSnippet,
    AutopilotParams,
    CorrectedCsv,
    AttitudeCsv,
    Track(TrackFormat),
    HtmlReport,
}

/// Wires the analysis exports' buttons, and puts a "PNG" button under every plot.
pub fn wire(page: &Rc<Page>) {
    for (id, export) in ANALYSIS_EXPORTS {
        let Some(button) = page.document.get_element_by_id(id) else {
            continue;
        };
        let page = Rc::clone(page);
        EventListener::new(&button, "click", move |_| {
            let message = match page.results() {
                Some(results) => write(&page, &results, export).err(),
                None => Some("Nothing to export yet: drop a log first.".to_string()),
            };
            set_text(
                &page.document,
                "export-status",
                message.as_deref().unwrap_or(""),
            );
        })
        .forget();
    }
    enable(&page.document, None, None);
    add_png_buttons(&page.document);
}

/// Enables the analysis exports that `results` (and the `recording` it came from) can
/// give: none without results.
pub fn enable(document: &Document, results: Option<&Rc<Results>>, recording: Option<&Recording>) {
    let attitude_missing = recording.and_then(attitude_missing);
    for (id, export) in ANALYSIS_EXPORTS {
        let Some(button) = document
            .get_element_by_id(id)
            .and_then(|element| element.dyn_into::<HtmlButtonElement>().ok())
        else {
            continue;
        };
        let available = results.is_some_and(|results| match export {
            Export::CalibrationJson | Export::CSnippet => {
                device_export(&results.calibration).is_some()
            }
            Export::Track(TrackFormat::GeoJson | TrackFormat::Gpx) => {
                results.pdr.as_ref().is_ok_and(|pdr| pdr.frame.is_some())
            }
            Export::Track(TrackFormat::Csv) => results.pdr.is_ok(),
            Export::AttitudeCsv => recording.is_some() && attitude_missing.is_none(),
            Export::AutopilotParams => results
                .calibration
                .report
                .autopilot
                .as_ref()
                .is_some_and(|autopilot| autopilot.written().next().is_some()),
            Export::CorrectedCsv | Export::HtmlReport => true,
        });
        button.set_disabled(!available);
        let why_not = match (results, export) {
            (None, _) => Some("Drop a log first.".to_string()),
            (Some(results), Export::Track(_)) => match &results.pdr {
                Err(reason) => Some(reason.clone()),
                Ok(pdr) if pdr.frame.is_none() => Some(
                    "The log has no usable GNSS fix, so the track has no latitude and longitude."
                        .to_string(),
                ),
                Ok(_) => None,
            },
            (Some(results), Export::AutopilotParams) => Some(
                match results.calibration.report.autopilot.as_ref() {
                    // The same sentences as the summary's figures and the CLI's.
                    Some(autopilot) => format!(
                        "Nothing to write: {}.",
                        autopilot
                            .compasses
                            .iter()
                            .map(|compass| compass.sentence.clone())
                            .collect::<Vec<_>>()
                            .join("; ")
                    ),
                    None => "Only for an autopilot log (ArduPilot .bin or .log, PX4 .ulg) with its compasses and attitude."
                        .to_string(),
                },
            ),
            (Some(_), Export::AttitudeCsv) => Some(
                attitude_missing
                    .clone()
                    .unwrap_or_else(|| "The log this analysis came from is gone.".to_string()),
            ),
            (Some(results), Export::CalibrationJson | Export::CSnippet) => {
                device_export_or_why(&results.calibration)
                    .err()
                    .map(|error| error.to_string())
            }
            _ => None,
        };
        match why_not {
            Some(reason) if !available => {
                let _ = button.set_attribute("title", &reason);
            }
            _ => {
                let _ = button.remove_attribute("title");
            }
        }
    }
    set_text(document, "export-status", "");
}

/// Why the attitude filter cannot run on `recording`, if it cannot.
pub(super) fn attitude_missing(recording: &Recording) -> Option<String> {
    let missing: Vec<&str> = [
        ("gyroscope", recording.gyro_in_body_radps.is_empty()),
        ("accelerometer", recording.acc_in_body_mps2.is_empty()),
    ]
    .into_iter()
    .filter_map(|(sensor, absent)| absent.then_some(sensor))
    .collect();
    (!missing.is_empty()).then(|| {
        format!(
            "The attitude filter needs a gyroscope and an accelerometer; this log has no {}.",
            missing.join(" and no ")
        )
    })
}

/// Writes one export of `results` and offers it for download.
fn write(page: &Page, results: &Results, export: Export) -> Result<(), String> {
    let document = &page.document;
    let stem = file_stem(&results.calibration.report.file_name);
    match export {
        Export::CalibrationJson => {
            let export =
                device_export_or_why(&results.calibration).map_err(|error| error.to_string())?;
            let text = calibration_json(&export.sensor)?;
            download_bytes(
                document,
                &format!("{stem}-calibration.json"),
                text.as_bytes(),
                "application/json",
            );
        }
        Export::CSnippet => {
            let export =
                device_export_or_why(&results.calibration).map_err(|error| error.to_string())?;
            download_bytes(
                document,
                &format!("{stem}-calibration.h"),
                c_snippet(&export.calibration).as_bytes(),
                "text/plain",
            );
        }
        Export::AutopilotParams => {
            let autopilot = results
                .calibration
                .report
                .autopilot
                .as_ref()
                .ok_or("not an autopilot log with its compasses and attitude")?;
            // QGroundControl's files end in .params, ArduPilot's in .param.
            let extension = if autopilot.autopilot == "PX4" {
                "params"
            } else {
                "param"
            };
            download_bytes(
                document,
                &format!("{stem}-compass.{extension}"),
                autopilot.param_file.as_bytes(),
                "text/plain",
            );
        }
        Export::CorrectedCsv => download_bytes(
            document,
            &format!("{stem}-corrected.csv"),
            corrected_csv(&results.calibration).as_bytes(),
            "text/csv",
        ),
        Export::AttitudeCsv => {
            let import = page
                .import()
                .ok_or("the log this analysis came from is gone: drop it again")?;
            let text = pipeline::attitude_csv(&import, &results.calibration)
                .map_err(|error| error.to_string())?;
            download_bytes(
                document,
                &format!("{stem}-attitude.csv"),
                text.as_bytes(),
                "text/csv",
            );
        }
        Export::Track(format) => {
            let pdr = results.pdr.as_ref().map_err(Clone::clone)?;
            let text = track_text(pdr, format).map_err(|error| error.to_string())?;
            let (extension, mime) = match format {
                TrackFormat::Csv => ("csv", "text/csv"),
                TrackFormat::GeoJson => ("geojson", "application/geo+json"),
                TrackFormat::Gpx => ("gpx", "application/gpx+xml"),
            };
            download_bytes(
                document,
                &format!("{stem}-track.{extension}"),
                text.as_bytes(),
                mime,
            );
        }
        Export::HtmlReport => {
            let html = html_report(
                &results.calibration,
                Some(&results.heading),
                results.pdr.as_ref().map_err(String::as_str),
                &canvas_figures(document),
            );
            download_bytes(
                document,
                &format!("{stem}-report.html"),
                html.as_bytes(),
                "text/html",
            );
        }
    }
    Ok(())
}

/// The page's plots as PNG images for the report, section by section.
fn canvas_figures(document: &Document) -> Vec<ReportFigure> {
    const SECTIONS: [(ReportSection, &[&str]); 4] = [
        (ReportSection::Answer, &["answer-canvas"]),
        (
            ReportSection::Calibration,
            &["plot-circle", "plot-heading", "plot-field"],
        ),
        (
            ReportSection::HeadingModels,
            &["plot-deviation", "plot-residuals", "plot-online"],
        ),
        (
            ReportSection::DeadReckoning,
            &["plot-trajectory", "plot-steps", "plot-position-error"],
        ),
    ];
    let mut figures = Vec::new();
    for (section, ids) in SECTIONS {
        for id in ids {
            let Some(canvas) = document
                .get_element_by_id(id)
                .and_then(|element| element.dyn_into::<HtmlCanvasElement>().ok())
            else {
                continue;
            };
            let (Ok(url), Some(label)) = (canvas.to_data_url(), canvas.get_attribute("aria-label"))
            else {
                continue;
            };
            let (width, _) = super::canvas::logical_size(&canvas);
            figures.push(ReportFigure {
                section,
                html: format!(
                    "<img src=\"{url}\" width=\"{width}\" alt=\"{}\">",
                    escape_html(&label)
                ),
            });
        }
    }
    figures
}

/// A calibration as indented JSON (the browser's serializer).
pub fn calibration_json(export: &CalibrationExport) -> Result<String, String> {
    let serializer = serde_wasm_bindgen::Serializer::json_compatible();
    let value = serde::Serialize::serialize(export, &serializer)
        .map_err(|error| format!("the calibration could not be written: {error}"))?;
    js_sys::JSON::stringify_with_replacer_and_space(
        &value,
        &wasm_bindgen::JsValue::NULL,
        &wasm_bindgen::JsValue::from(2),
    )
    .ok()
    .and_then(|text| text.as_string())
    .ok_or_else(|| "the calibration could not be written as JSON".to_string())
}

/// The log's name without its extension, for the names of its exports.
fn file_stem(file_name: &str) -> String {
    let first = file_name.split(" + ").next().unwrap_or(file_name);
    let stem = first.rsplit_once('.').map_or(first, |(stem, _)| stem);
    let cleaned: String = stem
        .chars()
        .map(|c| {
            if c.is_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '-'
            }
        })
        .collect();
    if cleaned.is_empty() {
        "compass-pdr".to_string()
    } else {
        cleaned
    }
}

/// A "PNG" button in the caption of every figure with a canvas.
fn add_png_buttons(document: &Document) {
    let Ok(canvases) = document.query_selector_all("figure canvas") else {
        return;
    };
    for idx in 0..canvases.length() {
        let Some(canvas) = canvases
            .get(idx)
            .and_then(|node| node.dyn_into::<HtmlCanvasElement>().ok())
        else {
            continue;
        };
        let Some(caption) = canvas
            .parent_element()
            .and_then(|figure| figure.query_selector("figcaption").ok().flatten())
        else {
            continue;
        };
        let Ok(button) = document.create_element("button") else {
            continue;
        };
        let id = canvas.id();
        let _ = button.set_attribute("type", "button");
        let _ = button.set_attribute("id", &format!("png-{id}"));
        let _ = button.set_attribute("class", "png");
        let _ = button.set_attribute("aria-label", &format!("Save the plot {id} as PNG"));
        button.set_text_content(Some("PNG"));
        let document_for_click = document.clone();
        EventListener::new(&button, "click", move |_| {
            if let Ok(url) = canvas.to_data_url() {
                download_url(&document_for_click, &format!("{id}.png"), &url);
            }
        })
        .forget();
        let _ = caption.append_child(&button);
    }
}

/// Offers `bytes` as a download named `name`.
pub fn download_bytes(document: &Document, name: &str, bytes: &[u8], mime: &str) {
    let parts = js_sys::Array::of1(&Uint8Array::from(bytes));
    let options = web_sys::BlobPropertyBag::new();
    options.set_type(mime);
    let Ok(blob) = web_sys::Blob::new_with_u8_array_sequence_and_options(&parts, &options) else {
        return;
    };
    let Ok(url) = web_sys::Url::create_object_url_with_blob(&blob) else {
        return;
    };
    download_url(document, name, &url);
    // The download starts after this returns: the URL is given back a minute later.
    let revoke = Closure::once_into_js(move || {
        let _ = web_sys::Url::revoke_object_url(&url);
    });
    if let Some(window) = web_sys::window() {
        let _ = window
            .set_timeout_with_callback_and_timeout_and_arguments_0(revoke.unchecked_ref(), 60_000);
    }
}

fn download_url(document: &Document, name: &str, url: &str) {
    if let Ok(anchor) = document.create_element("a") {
        let _ = anchor.set_attribute("href", url);
        let _ = anchor.set_attribute("download", name);
        if let Some(anchor) = anchor.dyn_ref::<web_sys::HtmlElement>() {
            anchor.click();
        }
    }
}
