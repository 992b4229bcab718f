//! PX4 ULog (`.ulg`) files, read as a stream: the IMU, the compasses (as logged and with
//! the autopilot's calibration undone), the autopilot's attitude estimate, GNSS fixes and
//! the parameters in force.
//!
//! The format is PX4's "ULog File Format" (docs.px4.io, `dev_log/ulog_file_format`;
//! pyulog's `core.py` is its reference reader): a 16-byte header (magic
//! `ULog 01 12 35`, a version byte, the log's start in µs), then messages framed as
//! `u16 msg_size (LE), u8 msg_type, payload[msg_size]`. Format definitions (`F`) describe
//! each topic's struct, subscriptions (`A`) tie a message id to a format and an
//! instance, and data messages (`D`) carry one little-endian struct each. Parameters
//! (`P`) logged before the first data message are the ones in force.
//!
//! [`UlogReader`] keeps only an unfinished message between chunks, so any chunking
//! gives the same report and memory does not grow with the file. Only the fields the
//! topics below need are decoded: each field's byte offset is found once, when its
//! topic is subscribed. Corrupt message headers are reported with their byte offset
//! and skipped by scanning for the next plausible header, as pyulog does.
//!
//! Topics read (`topics.rs`): `sensor_combined` (gyro, accelerometer, and in old logs
//! the calibrated magnetometer), `sensor_mag` (raw, per instance), `vehicle_magnetometer`
//! (calibrated), `vehicle_attitude`, `vehicle_gps_position` or `sensor_gps`. How the
//! calibration in force is undone is in `compass.rs`; `parse.rs` frames the messages
//! and `finish.rs` turns them into the report.

mod compass;
mod finish;
mod parse;
mod topics;

#[cfg(test)]
mod tests;

use std::collections::HashMap;

pub use compass::px4_rotation;

use crate::io::{Diagnostics, ImportError, ImportReport};

/// The format name for [`ImportReport::format`].
pub const ULOG: &str = "PX4 ULog";

/// The first seven bytes of every ULog file (the eighth is the version).
pub const MAGIC: &[u8; 7] = b"ULog\x01\x12\x35";

/// Whether a file's first bytes are a ULog header.
pub fn looks_like(prefix: &[u8]) -> bool {
    prefix.starts_with(MAGIC)
}

/// Reads a whole ULog file held in memory.
pub fn read(file_name: &str, bytes: &[u8]) -> Result<ImportReport, ImportError> {
    let mut reader = UlogReader::new();
    reader.feed(bytes);
    reader.finish(file_name)
}

/// A streaming ULog reader: [`feed`](UlogReader::feed) it chunks of any size, then
/// [`finish`](UlogReader::finish).
#[derive(Debug, Default)]
pub struct UlogReader {
    /// The bytes of an unfinished message (or header) carried to the next chunk.
    pending: Vec<u8>,
    /// The file offset of the next byte to be framed (`pending[0]` when it is not empty).
    offset: u64,
    header_read: bool,
    /// Why reading stopped early (no magic, an unknown incompatible flag).
    stopped: Option<String>,
    /// Bytes before this file offset are skipped (appended data).
    skip_until: u64,
    /// Where appended data starts (flag bits message), ascending, not yet reached.
    appended_offsets: Vec<u64>,
    /// Where the corrupt bytes being skipped began.
    resyncing_from: Option<u64>,
    n_messages: usize,
    n_bytes_skipped: u64,
    formats: HashMap<String, parse::Format>,
    subscriptions: HashMap<u16, topics::Subscription>,
    /// Message ids of data without a subscription already reported.
    unknown_msg_ids: Vec<u16>,
    collected: topics::Collected,
    params: Vec<(String, f64)>,
    param_idx: HashMap<String, usize>,
    params_changed: Vec<(String, f64)>,
    seen_data: bool,
    info: Vec<(String, String)>,
    /// The `ver_sw_release` info: it tells whether `sensor_mag` is raw ([`finish`]).
    ver_sw_release: Option<u32>,
    n_dropouts: usize,
    dropout_ms: u64,
    n_data_messages: usize,
    diagnostics: Diagnostics,
}

impl UlogReader {
    pub fn new() -> Self {
        Self::default()
    }

    /// Reads one chunk. Complete messages are decoded at once; only an unfinished one
    /// (at most 64 KiB) is kept for the next chunk.
    pub fn feed(&mut self, chunk: &[u8]) {
        let mut chunk = chunk;
        while !self.pending.is_empty() && !chunk.is_empty() {
            let needed = self.bytes_needed(&self.pending);
            let take = needed
                .saturating_sub(self.pending.len())
                .max(1)
                .min(chunk.len());
            self.pending.extend_from_slice(&chunk[..take]);
            chunk = &chunk[take..];
            let pending = std::mem::take(&mut self.pending);
            let consumed = self.process(&pending);
            self.pending = pending;
            self.pending.drain(..consumed.min(self.pending.len()));
        }
        if self.pending.is_empty() && !chunk.is_empty() {
            let consumed = self.process(chunk).min(chunk.len());
            self.pending.extend_from_slice(&chunk[consumed..]);
        }
    }
}
