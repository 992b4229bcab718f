//! What the page remembers in `localStorage`: the settings, the recent calibrations and
//! the column mappings, each under a key with its schema version in it
//! (`compass-pdr.<what>.v1`). An entry that cannot be read (corrupt, edited by hand, or
//! of another version) is ignored with a notice on the page, never a broken page; a
//! storage that is full or disabled only means nothing is remembered.

use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

use crate::fit::export::CalibrationExport;

pub const SETTINGS_KEY: &str = "compass-pdr.settings.v1";
pub const CALIBRATIONS_KEY: &str = "compass-pdr.calibrations.v1";
pub const MAPPINGS_KEY: &str = "compass-pdr.column-mappings.v1";

/// Recent calibrations kept at most (the oldest goes first).
pub const MAX_RECENT_CALIBRATIONS: usize = 10;

const NOTICE_ID: &str = "storage-notice";

/// The live panel's settings.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Settings {
    pub baud_rate: Option<u32>,
    pub lat_deg: Option<f64>,
    pub lon_deg: Option<f64>,
}

/// A calibration kept for later: where it came from, when, and the calibration.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RecentCalibration {
    /// "live session", or the name of the file it was imported from.
    pub source: String,
    /// ISO 8601, from the browser's clock.
    pub saved_at: String,
    pub calibration: CalibrationExport,
}

/// The stored value under `key`: `None` when nothing is stored (or storage is off);
/// a stored value that cannot be read is dropped and noticed on the page.
pub fn load<T: DeserializeOwned>(key: &str, what: &str) -> Option<T> {
    let storage = web_sys::window()?.local_storage().ok().flatten()?;
    let text = storage.get_item(key).ok().flatten()?;
    let parsed = js_sys::JSON::parse(&text)
        .map_err(|_| "it is not JSON".to_string())
        .and_then(|value| {
            serde_wasm_bindgen::from_value::<T>(value).map_err(|error| error.to_string())
        });
    match parsed {
        Ok(value) => Some(value),
        Err(reason) => {
            let _ = storage.remove_item(key);
            notice(&format!(
                "The saved {what} could not be read ({reason}) and were set aside; the page starts without them."
            ));
            None
        }
    }
}

/// Stores `value` under `key`; a full or disabled storage is ignored.
pub fn save<T: Serialize>(key: &str, value: &T) {
    let Some(storage) = web_sys::window().and_then(|window| window.local_storage().ok().flatten())
    else {
        return;
    };
    let serializer = serde_wasm_bindgen::Serializer::json_compatible();
    let text = value
        .serialize(&serializer)
        .ok()
        .and_then(|value| js_sys::JSON::stringify(&value).ok())
        .and_then(|text| text.as_string());
    if let Some(text) = text {
        let _ = storage.set_item(key, &text);
    }
}

/// Adds a notice to the page's notice line (shown only when it has text).
fn notice(message: &str) {
    web_sys::console::warn_1(&format!("compass-pdr: {message}").into());
    let Some(element) = web_sys::window()
        .and_then(|window| window.document())
        .and_then(|document| document.get_element_by_id(NOTICE_ID))
    else {
        return;
    };
    let previous = element.text_content().unwrap_or_default();
    let text = if previous.is_empty() {
        message.to_string()
    } else {
        format!("{previous} {message}")
    };
    element.set_text_content(Some(&text));
}
