//! Importers: bytes in, a [`Recording`] and diagnostics out.
//!
//! Partial failure is not failure. A line that cannot be used becomes a [`Diagnostic`]
//! with its line number and the reason, and the rest of the file is still read. Only a
//! file from which nothing at all can be read is an [`ImportError`].

pub mod autopilot;
pub mod axes;
pub mod canonical_csv;
pub mod dataflash;
pub mod delimited;
pub mod frame;
pub mod gpx;
pub mod import;
pub mod lines;
pub mod nmea;
pub mod number;
pub mod recording;
pub mod sensor_files;
pub mod serial_lines;
pub mod summary;
pub mod tagged_lines;
pub mod ulog;

use serde::Serialize;
use thiserror::Error;

pub use frame::{MagUnit, SensorFrame, UnitOrigin};

use crate::io::recording::Recording;

/// How many diagnostics an import keeps in full; past this only their count is kept,
/// so that a huge file of bad lines cannot exhaust memory.
pub const MAX_DIAGNOSTICS_KEPT: usize = 200;

/// Lines longer than this are cut by the line decoder, and skipped or reported by the
/// readers of delimited text, Android dumps and GetSensorData logs, and by the chunked
/// import that feeds them: a sensor line is under 200 bytes, a Wi-Fi line with a long
/// network name a few hundred. Serial sensor lines and NMEA have shorter limits of
/// their own.
const MAX_LINE_BYTES: usize = 64 * 1024;

/// Standard gravity (CGPM 1901, m/s²): for accelerometers that report in g, and the
/// crate's one value of g (the tilt's, the simulators').
pub const STANDARD_GRAVITY_MPS2: f64 = 9.806_65;

/// A line that was skipped or is suspect.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Diagnostic {
    /// 1-based line number, where the problem belongs to one line.
    pub line: Option<usize>,
    pub message: String,
    /// The file, where several files were imported together.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub file_name: Option<String>,
}

/// Diagnostics of one import, bounded in memory.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Diagnostics {
    pub kept: Vec<Diagnostic>,
    /// Diagnostics past [`MAX_DIAGNOSTICS_KEPT`], counted but not kept.
    pub n_not_kept: usize,
}

impl Diagnostics {
    /// The kept diagnostics' messages, in order (for tests that pin their wording).
    #[cfg(test)]
    pub(crate) fn messages(&self) -> Vec<&str> {
        self.kept.iter().map(|d| d.message.as_str()).collect()
    }

    pub fn push(&mut self, line: Option<usize>, message: impl Into<String>) {
        if self.kept.len() < MAX_DIAGNOSTICS_KEPT {
            self.kept.push(Diagnostic {
                line,
                message: message.into(),
                file_name: None,
            });
        } else {
            self.n_not_kept += 1;
        }
    }

    /// That `n_out_of_order` samples went back in time and were sorted (nothing when
    /// none did): one wording for every importer.
    pub fn push_sorted_by_time(&mut self, line: Option<usize>, n_out_of_order: usize) {
        if n_out_of_order > 0 {
            self.push(
                line,
                format!(
                    "time goes backwards {}; the samples were sorted by time",
                    crate::base::words::times(n_out_of_order)
                ),
            );
        }
    }

    /// Appends another file's diagnostics, marking each with its file.
    pub fn absorb(&mut self, other: Diagnostics, file_name: &str) {
        for diagnostic in other.kept {
            if self.kept.len() < MAX_DIAGNOSTICS_KEPT {
                self.kept.push(Diagnostic {
                    file_name: Some(file_name.to_string()),
                    ..diagnostic
                });
            } else {
                self.n_not_kept += 1;
            }
        }
        self.n_not_kept += other.n_not_kept;
    }

    pub fn total(&self) -> usize {
        self.kept.len() + self.n_not_kept
    }

    pub fn is_empty(&self) -> bool {
        self.total() == 0
    }
}

/// What an import read: the recording, what was skipped, and what the header held.
#[derive(Debug, Clone, PartialEq)]
pub struct ImportReport {
    pub file_name: String,
    /// The format as the user would name it ("canonical CSV", "NMEA 0183", …).
    pub format: &'static str,
    pub recording: Recording,
    pub diagnostics: Diagnostics,
    /// The header line of a delimited file, where there is one.
    pub header: Option<HeaderInfo>,
    /// Lines that were neither blank, comments nor the header.
    pub n_data_lines: usize,
    /// What the importer understood and assumed (units guessed, axes mapped), for the
    /// user to check.
    pub notes: Vec<String>,
    /// How the magnetometer's body-axes µT values were made from the log's raw values;
    /// `None` when the recording has no magnetometer.
    pub mag_frame: Option<SensorFrame>,
    /// An autopilot log's parameters and compasses ([`autopilot`]); `None` for others.
    pub autopilot: Option<autopilot::AutopilotLog>,
}

/// The header of a delimited file: its column names as written and its line number.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct HeaderInfo {
    pub line: usize,
    pub columns: Vec<String>,
}

/// A file from which nothing could be read. Each message names the file and says what
/// the user can do.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ImportError {
    #[error("{file_name} is empty. Choose a log with a header line and samples.")]
    Empty { file_name: String },

    /// The browser could not hand over the file's bytes (moved or deleted since it was
    /// chosen, a drive gone, no permission).
    #[error("Could not read {file_name}: {reason}. Choose it again (a copy on this computer if it is on a removable or network drive).")]
    Unreadable { file_name: String, reason: String },

    #[error(
        "{file_name} is not a text log (binary data near byte {byte_offset}). \
         Export the log as CSV text with a header line such as \
         t_s,mag_x_ut,mag_y_ut,mag_z_ut."
    )]
    NotText {
        file_name: String,
        byte_offset: usize,
    },

    /// JSON, such as the map or the track some loggers keep beside their logs: no
    /// format this tool reads starts with `{`.
    #[error("{file_name} is JSON, not a sensor log (a GeoJSON map or track is not read; GPX and KML tracks are). Drop the log itself: CSV or text with a header line such as t_s,mag_x_ut,mag_y_ut,mag_z_ut, NMEA, or an autopilot log.")]
    Json { file_name: String },

    #[error("{file_name} has no header line, only blank or comment lines. Add a header such as t_s,mag_x_ut,mag_y_ut,mag_z_ut.")]
    NoHeader { file_name: String },

    #[error(
        "{file_name} has no header line: line {line} is already {n_columns} numbers. Say \
         which column is which: in the page's column dialog, or with --map, for example \
         --map 'column 1=t_s,column 2=mag_x_ut,column 3=mag_y_ut,column 4=mag_z_ut'."
    )]
    NoHeaderLine {
        file_name: String,
        line: usize,
        n_columns: usize,
    },

    #[error(
        "{file_name}, line {line}: the header names no column this tool knows \
         (found: {found}). Use the canonical names, such as t_s, acc_x_mps2, \
         mag_x_ut, mag_y_ut, mag_z_ut, ref_heading_deg."
    )]
    UnknownHeader {
        file_name: String,
        line: usize,
        found: String,
    },

    #[error(
        "{file_name}: none of its {n_lines} lines could be read as {format}{first_problem}. \
         Check that the file is a {format} log, or export it as CSV with a header line."
    )]
    NothingRecognised {
        file_name: String,
        format: &'static str,
        n_lines: usize,
        /// The first problem met, as " (line N: reason)", or empty.
        first_problem: String,
    },
}

/// Refuses a file that is empty (or only white space) or not text, with the message
/// that names it; every importer starts here.
pub fn ensure_text(file_name: &str, bytes: &[u8]) -> Result<(), ImportError> {
    if bytes.iter().all(u8::is_ascii_whitespace) {
        return Err(ImportError::Empty {
            file_name: file_name.to_string(),
        });
    }
    if let Some(byte_offset) = first_binary_offset(bytes) {
        return Err(ImportError::NotText {
            file_name: file_name.to_string(),
            byte_offset,
        });
    }
    Ok(())
}

/// Cuts text quoted in a message (a field, a line, a header) to a readable length.
pub fn shorten(text: &str) -> String {
    const MAX_CHARS: usize = 80;
    if text.chars().count() <= MAX_CHARS {
        text.to_string()
    } else {
        let head: String = text.chars().take(MAX_CHARS).collect();
        format!("{head}…")
    }
}

/// A count with thousands separators ("12,000"), as notes and messages print it.
pub fn thousands(count: usize) -> String {
    let digits = count.to_string();
    let mut grouped = String::with_capacity(digits.len() + digits.len() / 3);
    for (idx, digit) in digits.chars().enumerate() {
        if idx > 0 && (digits.len() - idx).is_multiple_of(3) {
            grouped.push(',');
        }
        grouped.push(digit);
    }
    grouped
}

/// Whether `bytes` look like text, judged from their start. Returns the offset of the
/// first byte that shows they are not: a NUL, or the point where more than 10% of the
/// characters so far are control characters or invalid UTF-8.
pub fn first_binary_offset(bytes: &[u8]) -> Option<usize> {
    const PROBE_BYTES: usize = 8192;
    let probe = &bytes[..bytes.len().min(PROBE_BYTES)];
    if let Some(nul_offset) = probe.iter().position(|&byte| byte == 0) {
        return Some(nul_offset);
    }
    let text = String::from_utf8_lossy(probe);
    let mut n_chars = 0usize;
    let mut n_suspect = 0usize;
    let mut byte_offset = 0usize;
    for character in text.chars() {
        n_chars += 1;
        let is_suspect = character == char::REPLACEMENT_CHARACTER
            || (character.is_control() && !matches!(character, '\n' | '\r' | '\t'));
        if is_suspect {
            n_suspect += 1;
        }
        // Judge only once a few dozen characters have been seen.
        if n_chars >= 32 && n_suspect * 10 > n_chars {
            return Some(byte_offset.min(probe.len()));
        }
        byte_offset += character.len_utf8();
    }
    if n_chars > 0 && n_chars < 32 && n_suspect * 10 > n_chars {
        return Some(0);
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_is_not_binary() {
        assert_eq!(first_binary_offset(b"t_s,mag_x_ut\n0.0,1.5\n"), None);
        assert_eq!(first_binary_offset("t_s,X (µT)\r\n".as_bytes()), None);
        assert_eq!(first_binary_offset(b""), None);
    }

    #[test]
    fn nul_bytes_and_noise_are_binary() {
        assert_eq!(first_binary_offset(b"abc\0def"), Some(3));
        let noise: Vec<u8> = (0..4096u32)
            .map(|i| (i.wrapping_mul(2654435761) >> 13) as u8 | 0x80)
            .collect();
        assert!(first_binary_offset(&noise).is_some());
    }

    #[test]
    fn diagnostics_are_bounded() {
        let mut diagnostics = Diagnostics::default();
        for line in 0..(MAX_DIAGNOSTICS_KEPT + 5) {
            diagnostics.push(Some(line), "bad");
        }
        assert_eq!(diagnostics.kept.len(), MAX_DIAGNOSTICS_KEPT);
        assert_eq!(diagnostics.total(), MAX_DIAGNOSTICS_KEPT + 5);
    }
}
