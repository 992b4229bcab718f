//! What the panel keeps between visits (through `web::storage`): the baud rate and
//! position typed in, and the recent calibrations (the latest fit kept when it is sent
//! or downloaded, and calibration files imported), with their list and its buttons.

use std::rc::Rc;

use gloo::events::EventListener;
use wasm_bindgen::JsCast;
use wasm_bindgen_futures::spawn_local;
use web_sys::{Element, HtmlInputElement};

use super::LivePanel;
use crate::fit::export::{calibration_export, CalibrationExport};
use crate::web::exports::{calibration_json, download_bytes};
use crate::web::storage::{
    self, RecentCalibration, Settings, CALIBRATIONS_KEY, MAX_RECENT_CALIBRATIONS, SETTINGS_KEY,
};

impl LivePanel {
    /// The settings and recent calibrations saved by an earlier visit.
    pub(super) fn restore(&self) {
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
    pub(super) fn wire_storage(self: &Rc<Self>) {
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
    pub(super) fn keep_latest_fit(&self) {
        let calibration = self
            .session
            .borrow()
            .quality()
            .map(crate::live::LiveQuality::sensor_calibration);
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
            let decimals =
                crate::present::report::decimals_for_unit(saved.ut_per_unit.unwrap_or(1.0));
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
}
