//! NMEA 0183: GNSS fixes and compass headings from a receiver's or compass's serial log.
//!
//! Each line is one sentence: `$` (or `!`), an address, comma-separated fields and an
//! optional checksum, `*` and two hex digits that are the XOR of every byte between
//! the `$` and the `*`. The address is a two-letter talker (GP, GN, GL, GA, HC, II,
//! HE, …) and a three-letter type, or `P` and a maker's code for a proprietary
//! sentence. Any talker is accepted. Fields may be empty (null) when the device has no
//! value. These sentences are read, each in a file of its own whose header draws its
//! fields: RMC (`rmc.rs`), GGA (`gga.rs`), VTG (`vtg.rs`), HDG, HDM and HDT
//! (`heading.rs`), and the Honeywell HMR3000's proprietary PTNTHPR (`hpr.rs`).
//!
//! Sources: Eric S. Raymond, "NMEA Revealed" (gpsd project,
//! <https://gpsd.gitlab.io/gpsd/NMEA.html>) for the framing, the checksum, RMC, GGA,
//! VTG, HDG, HDM and HDT; Garmin, "GPS 19x HVS Technical Specifications", §4.2 (RMC,
//! VTG); Kongsberg's description of the HDG datagram (deviation and variation); and
//! Honeywell, "HMR3000 Digital Compass Module User's Guide" (900240 Rev. B), §3.10 and
//! §3.12, for PTNTHPR, its status letters and its example sentences (used as golden
//! tests in `hpr.rs`). On an alarm the HMR3000 leaves the heading and the alarmed value
//! null.
//!
//! Units become this crate's here, once: degrees to radians, knots and km/h to m/s,
//! ddmm.mmmm to decimal degrees (south and west negative). Times of day become `t_s`,
//! seconds since the first timed sentence, counted across midnight (from the RMC date
//! where there is one). Sentences without a time (VTG, HDG, HDM, HDT, PTNTHPR) are placed
//! evenly, line by line, between the timed sentences around them; see [`NmeaReader`].
//!
//! The other files: `framing.rs` cuts lines into sentences (the `$`, the address, the
//! checksum, the fields), `values.rs` reads the fields' numbers, angles and coordinates,
//! `clock.rs` the times of day and dates and the clock across midnight, `error.rs` says
//! why a line is not a usable sentence, `reader.rs` applies the sentences in order
//! ([`NmeaReader`]), `finish.rs` ends the input with its notes, and `parallel.rs` parses
//! large files on every thread.

use self::framing::{for_each_line, is_blank, is_sentence_shaped, LineEvent};
use super::{ensure_text, ImportError, ImportReport};

mod clock;
mod error;
mod finish;
mod framing;
mod gga;
mod heading;
mod hpr;
#[cfg(any(not(target_arch = "wasm32"), target_feature = "atomics"))]
mod parallel;
mod reader;
mod rmc;
#[cfg(test)]
mod tests;
mod values;
mod vtg;

pub use self::clock::NmeaDate;
pub use self::error::SentenceError;
pub use self::framing::parse_sentence;
pub use self::gga::Gga;
pub use self::heading::{Hdg, HeadingOnly};
pub use self::hpr::{Hpr, HprStatus};
pub use self::reader::NmeaReader;
pub use self::rmc::Rmc;
pub use self::vtg::Vtg;

pub const FORMAT_NAME: &str = "NMEA 0183";

/// Lines longer than this are cut and skipped. A standard sentence is at most 82
/// characters; proprietary ones run longer, but not to kilobytes.
const MAX_LINE_BYTES: usize = 4096;

/// One international knot is exactly 1852 m per hour.
const MPS_PER_KNOT: f64 = 1852.0 / 3600.0;

/// What this importer reads, for messages.
const READ_SENTENCES: &str = "RMC, GGA, VTG, HDG, HDM, HDT and PTNTHPR";

/// One parsed sentence, in this crate's units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sentence {
    /// The two-letter talker (`*b"GP"`, `*b"HC"`, …); `None` for a proprietary sentence.
    pub talker: Option<[u8; 2]>,
    /// The line carried a `*hh` checksum (and it matched).
    pub has_checksum: bool,
    pub data: SentenceData,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SentenceData {
    Rmc(Rmc),
    Gga(Gga),
    Vtg(Vtg),
    Hdg(Hdg),
    Hdm(HeadingOnly),
    Hdt(HeadingOnly),
    Hpr(Hpr),
}

impl SentenceData {
    /// The sentence type as the user sees it in the log.
    pub fn type_name(&self) -> &'static str {
        KIND_NAMES[self.kind_idx()]
    }

    fn kind_idx(&self) -> usize {
        match self {
            SentenceData::Rmc(_) => 0,
            SentenceData::Gga(_) => 1,
            SentenceData::Vtg(_) => 2,
            SentenceData::Hdg(_) => 3,
            SentenceData::Hdm(_) => 4,
            SentenceData::Hdt(_) => 5,
            SentenceData::Hpr(_) => 6,
        }
    }
}

const KIND_NAMES: [&str; 7] = ["RMC", "GGA", "VTG", "HDG", "HDM", "HDT", "PTNTHPR"];

/// Whether most non-blank lines of a sample (the first twenty or so lines of a file or
/// a serial stream) are NMEA sentences.
pub fn looks_like(sample_lines: &[&str]) -> bool {
    let mut n_lines = 0usize;
    let mut n_sentences = 0usize;
    for line in sample_lines {
        if is_blank(line) {
            continue;
        }
        n_lines += 1;
        if is_sentence_shaped(line) {
            n_sentences += 1;
        }
    }
    n_sentences > 0 && n_sentences * 2 > n_lines
}

/// Reads NMEA 0183 bytes. Fails only when nothing can be read; every skipped line
/// becomes a diagnostic in the report.
///
/// Parsing a line needs no state, applying it does (the clock, the epoch merge, the
/// placing of untimed sentences, the counts): on native builds a large file is parsed
/// on every core and applied in order on one thread (`parallel`), with the same
/// result as reading it line by line; so is it in the browser's threaded build
/// ([`crate::base::par`]), and the default browser build reads on one thread.
pub fn read(file_name: &str, bytes: &[u8]) -> Result<ImportReport, ImportError> {
    ensure_text(file_name, bytes)?;
    #[cfg(any(not(target_arch = "wasm32"), target_feature = "atomics"))]
    if let Some(report) = parallel::read(file_name, bytes) {
        return report;
    }
    let mut reader = NmeaReader::new();
    for_each_line(bytes, |line_number, content| {
        reader.apply(line_number, LineEvent::of(content));
    });
    reader.finish(file_name)
}
