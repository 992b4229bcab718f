//! Tagged multi-sensor line logs: the Android sensor dump and GetSensorData.
//!
//! Both formats write one sensor event per line, led by a tag that names the sensor,
//! with all sensors mixed in one file at their own rates. Both report vectors in
//! Android's *device* axes (x right of the screen, y towards its top edge, z out of the
//! screen), which become body axes here through
//! [`PhoneMount`](super::axes::PhoneMount) and nowhere else. The mount is detected from
//! the mean accelerometer reading in device axes; without a clear answer the phone is
//! taken as held flat, and the notes say so.
//!
//! The formats, each in a file whose header shows its lines and cites its source: the
//! Android sensor dump of the Microsoft Indoor Location Competition 2020 (`android.rs`)
//! and the GetSensorData logs of the IPIN competitions (`get_sensor_data.rs`). What
//! both read is collected in device axes and on the file's clock (`collector.rs`) until
//! the end of the file, when it becomes body axes and seconds, with the notes;
//! `fields.rs` reads a line's fields; `tests.rs` tests whole logs, the real recordings
//! among them.

use super::lines::decode_all;
use super::{ensure_text, ImportError, ImportReport, MAX_LINE_BYTES};

mod android;
mod collector;
mod fields;
mod get_sensor_data;

pub use self::android::AndroidReader;
pub use self::get_sensor_data::GetSensorDataReader;

pub const ANDROID_DUMP: &str = "Android sensor dump";
pub const GET_SENSOR_DATA: &str = "GetSensorData log";

/// How many lines the format detectors look at.
const DETECTION_LINES: usize = 20;

/// Tags that GetSensorData writes, for recognising its logs.
const GET_SENSOR_DATA_TAGS: [&str; 21] = [
    "ACCE", "GYRO", "MAGN", "PRES", "LIGH", "PROX", "HUMI", "TEMP", "AHRS", "GNSS", "WIFI", "BLUE",
    "BLE4", "SOUN", "RFID", "IMUX", "IMUL", "IMUI", "IM1P", "IM1X", "POSI",
];

/// Whether the first lines look like an Android sensor dump: a `#⇥startTime:` header
/// or a line `unix_ms<TAB>TYPE_…`.
pub fn looks_like_android_dump(sample_lines: &[&str]) -> bool {
    sample_lines.iter().take(DETECTION_LINES).any(|line| {
        let line = line.trim_start_matches('\u{feff}').trim();
        if let Some(header) = line.strip_prefix('#') {
            return header.trim_start().starts_with("startTime:");
        }
        let mut fields = line.split('\t').map(str::trim);
        match (fields.next(), fields.next()) {
            (Some(time), Some(kind)) => time.parse::<f64>().is_ok() && kind.starts_with("TYPE_"),
            _ => false,
        }
    })
}

/// Whether the first lines look like a GetSensorData log: its `%` header naming the
/// app, or a line starting with one of its tags and a number.
pub fn looks_like_get_sensor_data(sample_lines: &[&str]) -> bool {
    sample_lines.iter().take(DETECTION_LINES).any(|line| {
        let line = line.trim_start_matches('\u{feff}').trim();
        if let Some(comment) = line.strip_prefix('%') {
            return comment.contains("GetSensorData");
        }
        let mut fields = line.split(';').map(str::trim);
        match (fields.next(), fields.next()) {
            (Some(tag), Some(time)) => {
                GET_SENSOR_DATA_TAGS.contains(&tag) && time.parse::<f64>().is_ok()
            }
            _ => false,
        }
    })
}

/// Reads an Android sensor dump. Fails only when nothing can be read; every skipped
/// line becomes a diagnostic in the report.
pub fn read_android_dump(file_name: &str, bytes: &[u8]) -> Result<ImportReport, ImportError> {
    read_bytes(file_name, bytes, AndroidReader::default())
}

/// Reads a GetSensorData log. Fails only when nothing can be read; every skipped line
/// becomes a diagnostic in the report.
pub fn read_get_sensor_data(file_name: &str, bytes: &[u8]) -> Result<ImportReport, ImportError> {
    read_bytes(file_name, bytes, GetSensorDataReader::default())
}

/// A reader of one format, fed line by line, so that files and chunked input share it.
pub trait LineReader {
    fn read_line(&mut self, number: usize, text: &str, truncated: bool);
    fn finish(self, file_name: String) -> Result<ImportReport, ImportError>;
}

fn read_bytes(
    file_name: &str,
    bytes: &[u8],
    mut reader: impl LineReader,
) -> Result<ImportReport, ImportError> {
    ensure_text(file_name, bytes)?;
    let file_name = file_name.to_string();
    decode_all(bytes, MAX_LINE_BYTES, |line| {
        reader.read_line(line.number, &line.text, line.truncated);
    });
    reader.finish(file_name)
}

#[cfg(test)]
mod tests;
