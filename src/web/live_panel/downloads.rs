//! The panel's downloads: the recording (every byte received, as received), and the
//! latest fit as calibration JSON or as a C header.

use super::LivePanel;
use crate::fit::export::{c_snippet, calibration_export};
use crate::web::exports::{calibration_json, download_bytes};

impl LivePanel {
    pub(super) fn download_recording(&self) {
        let session = self.session.borrow();
        let name = format!("compass-pdr-live-{}.txt", timestamp_for_file_name());
        download_bytes(&self.document, &name, session.raw(), "text/plain");
    }

    pub(super) fn download_calibration_json(&self) {
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

    pub(super) fn download_c_snippet(&self) {
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
