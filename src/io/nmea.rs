//! NMEA 0183: GNSS fixes and compass headings from a receiver's or compass's serial log.
//!
//! Each line is one sentence: `$` (or `!`), an address, comma-separated fields and an
//! optional checksum, `*` and two hex digits that are the XOR of every byte between
//! the `$` and the `*`. The address is a two-letter talker (GP, GN, GL, GA, HC, II,
//! HE, …) and a three-letter type, or `P` and a maker's code for a proprietary
//! sentence. Any talker is accepted. Fields may be empty (null) when the device has no
//! value. These sentences are read (field numbers below the diagrams):
//!
//! ```text
//! $--RMC,hhmmss.ss,A,llll.ll,a,yyyyy.yy,a,x.x,x.x,ddmmyy,x.x,a,m*hh
//!        1         2 3       4 5        6 7   8   9      10  11 12
//!  1 UTC time of day          2 status: A valid, V invalid (navigation receiver warning)
//!  3-4 latitude ddmm.mmmm, N/S   5-6 longitude dddmm.mmmm, E/W
//!  7 speed over ground, knots    8 course over ground, degrees true
//!  9 date day-month-year        10-11 magnetic variation, degrees, E/W
//! 12 mode (NMEA 2.3): A autonomous, D differential, E estimated, N not valid, …
//!
//! $--GGA,hhmmss.ss,llll.ll,a,yyyyy.yy,a,q,nn,h.h,x.x,M,x.x,M,x.x,xxxx*hh
//!        1         2       3 4        5 6 7  8   9   10 11 12 13  14
//!  1 UTC time of day   2-5 latitude and longitude as in RMC
//!  6 fix quality: 0 invalid, 1 GPS, 2 DGPS, 4 RTK fixed, 5 RTK float, 6 estimated, …
//!  7 satellites used   8 horizontal dilution of precision (HDOP, no unit)
//!  9-10 antenna altitude above mean sea level, metres   11-12 geoid separation, metres
//! 13-14 age of differential data, reference station id
//!
//! $--VTG,x.x,T,x.x,M,x.x,N,x.x,K,m*hh     (NMEA 1.x: $--VTG,x.x,x.x,x.x,x.x*hh)
//!        1   2 3   4 5   6 7   8 9
//!  1 course over ground, degrees true   3 course over ground, degrees magnetic
//!  5 speed over ground, knots           7 speed over ground, km/h   9 mode, as in RMC
//!
//! $--HDG,x.x,x.x,a,x.x,a*hh
//!        1   2   3 4   5
//!  1 magnetic sensor heading, degrees   2-3 deviation, degrees, E/W
//!  4-5 variation, degrees, E/W (sensor + deviation = magnetic; magnetic + variation = true)
//!
//! $--HDM,x.x,M*hh          $--HDT,x.x,T*hh
//!        1   2                    1   2
//!  1 heading, degrees magnetic (HDM) or true (HDT)
//!
//! $PTNTHPR,x.x,a,x.x,a,x.x,a*hh     (Honeywell HMR3000 heading, pitch and roll)
//!          1   2 3   4 5   6
//!  1 heading, degrees   3 pitch, degrees   5 roll, degrees
//!  2, 4, 6 status of the magnetic field, pitch and roll: N normal, M low warning,
//!    L low alarm, O high warning, P high alarm, C tuning the analogue circuit
//! ```
//!
//! Sources: Eric S. Raymond, "NMEA Revealed" (gpsd project,
//! <https://gpsd.gitlab.io/gpsd/NMEA.html>) for the framing, the checksum, RMC, GGA,
//! VTG, HDG, HDM and HDT; Garmin, "GPS 19x HVS Technical Specifications", §4.2 (RMC,
//! VTG); Kongsberg's description of the HDG datagram (deviation and variation); and
//! Honeywell, "HMR3000 Digital Compass Module User's Guide" (900240 Rev. B), §3.10 and
//! §3.12, for PTNTHPR, its status letters and its example sentences (used as golden
//! tests below). On an alarm the HMR3000 leaves the heading and the alarmed value null.
//!
//! Units become this crate's here, once: degrees to radians, knots and km/h to m/s,
//! ddmm.mmmm to decimal degrees (south and west negative). Times of day become `t_s`,
//! seconds since the first timed sentence, counted across midnight (from the RMC date
//! where there is one). Sentences without a time (VTG, HDG, HDM, HDT, PTNTHPR) are placed
//! evenly, line by line, between the timed sentences around them; see [`NmeaReader`].

use std::borrow::Cow;
use std::fmt;

use super::lines::Line;
use super::{ensure_text, shorten, thousands, Diagnostics, ImportError, ImportReport};
use crate::angle::wrap_to_2pi;
use crate::recording::{Attitude, DeviceHeading, GnssFix, North, Recording};

#[cfg(any(not(target_arch = "wasm32"), target_feature = "atomics"))]
mod parallel;

pub const FORMAT_NAME: &str = "NMEA 0183";

/// Lines longer than this are cut and skipped. A standard sentence is at most 82
/// characters; proprietary ones run longer, but not to kilobytes.
const MAX_LINE_BYTES: usize = 4096;

/// One international knot is exactly 1852 m per hour.
const MPS_PER_KNOT: f64 = 1852.0 / 3600.0;
const SECONDS_PER_DAY: f64 = 86_400.0;

/// How many distinct unknown sentence addresses are named in the notes; the rest are
/// only counted, so that a stream of garbage addresses cannot grow memory.
const MAX_UNKNOWN_ADDRESSES_NAMED: usize = 16;

/// What this importer reads, for messages.
const READ_SENTENCES: &str = "RMC, GGA, VTG, HDG, HDM, HDT and PTNTHPR";

// ---------------------------------------------------------------------------------------
// Sentences
// ---------------------------------------------------------------------------------------

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

/// A UTC date as RMC gives it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NmeaDate {
    pub year: i32,
    pub month: u8,
    pub day: u8,
}

impl NmeaDate {
    /// Days since 1970-01-01 (proleptic Gregorian calendar), after Howard Hinnant's
    /// `days_from_civil`.
    pub fn days_since_1970(&self) -> i64 {
        crate::civil::days_from_civil(
            i64::from(self.year),
            u32::from(self.month),
            u32::from(self.day),
        )
    }
}

/// RMC, recommended minimum data.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rmc {
    /// Seconds since midnight UTC.
    pub time_of_day_s: Option<f64>,
    /// Status A; false for V (the receiver has no valid fix).
    pub status_valid: bool,
    pub lat_deg: Option<f64>,
    pub lon_deg: Option<f64>,
    pub speed_mps: Option<f64>,
    /// Course over ground, clockwise from true north.
    pub course_rad: Option<f64>,
    pub date: Option<NmeaDate>,
    /// Magnetic variation (declination), east positive.
    pub magnetic_variation_rad: Option<f64>,
    /// The NMEA 2.3 mode letter, where given.
    pub mode: Option<char>,
}

impl Rmc {
    /// Whether the receiver says the fix is usable: status A and, where a mode letter
    /// is given, not N (not valid).
    pub fn is_valid(&self) -> bool {
        self.status_valid && self.mode != Some('N')
    }
}

/// GGA, fix data.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gga {
    /// Seconds since midnight UTC.
    pub time_of_day_s: Option<f64>,
    pub lat_deg: Option<f64>,
    pub lon_deg: Option<f64>,
    /// Fix quality; 0 means the fix is invalid.
    pub quality: Option<u8>,
    pub n_satellites: Option<u32>,
    /// Horizontal dilution of precision: a geometry factor without unit, not an
    /// accuracy in metres.
    pub hdop: Option<f64>,
    /// Antenna altitude above mean sea level.
    pub alt_msl_m: Option<f64>,
    /// Height of the geoid above the ellipsoid.
    pub geoid_separation_m: Option<f64>,
}

impl Gga {
    pub fn is_valid(&self) -> bool {
        self.quality != Some(0)
    }
}

/// VTG, course and speed over ground.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Vtg {
    /// Clockwise from true north.
    pub course_true_rad: Option<f64>,
    /// Clockwise from magnetic north.
    pub course_magnetic_rad: Option<f64>,
    /// From the knots field, or from the km/h field where knots are null.
    pub speed_mps: Option<f64>,
    pub mode: Option<char>,
}

/// HDG, a magnetic sensor's heading with the deviation and variation it knows.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hdg {
    pub sensor_heading_rad: f64,
    /// East positive.
    pub deviation_rad: Option<f64>,
    /// East positive.
    pub variation_rad: Option<f64>,
}

impl Hdg {
    /// The sensor heading corrected for deviation: the heading from magnetic north.
    pub fn magnetic_heading_rad(&self) -> f64 {
        wrap_to_2pi(self.sensor_heading_rad + self.deviation_rad.unwrap_or(0.0))
    }
}

/// HDM or HDT: one heading.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeadingOnly {
    pub heading_rad: f64,
}

/// The status letter of each PTNTHPR value.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HprStatus {
    LowAlarm,
    LowWarning,
    Normal,
    HighWarning,
    HighAlarm,
    TuningAnalogCircuit,
}

impl HprStatus {
    fn from_letter(letter: &[u8]) -> Option<HprStatus> {
        match letter {
            b"L" => Some(HprStatus::LowAlarm),
            b"M" => Some(HprStatus::LowWarning),
            b"N" => Some(HprStatus::Normal),
            b"O" => Some(HprStatus::HighWarning),
            b"P" => Some(HprStatus::HighAlarm),
            b"C" => Some(HprStatus::TuningAnalogCircuit),
            _ => None,
        }
    }

    pub fn describe(self) -> &'static str {
        match self {
            HprStatus::LowAlarm => "low alarm (L)",
            HprStatus::LowWarning => "low warning (M)",
            HprStatus::Normal => "normal (N)",
            HprStatus::HighWarning => "high warning (O)",
            HprStatus::HighAlarm => "high alarm (P)",
            HprStatus::TuningAnalogCircuit => "tuning its analogue circuit (C)",
        }
    }
}

/// PTNTHPR, the Honeywell HMR3000's heading, pitch and roll. Values are null while
/// their status is an alarm.
///
/// Signs: the HMR3000 guide defines pitch from the tilt of the board's north-south
/// (forward) axis and roll from its east-west axis, but the parts of it that could be
/// consulted do not state the signs in words. The values are therefore taken as they
/// come, in the aerospace sense that this crate's body frame (x forward, y right, z
/// down) also uses: pitch positive nose up, roll positive right side down (as ARINC
/// 407 and MIL-N-81497A define them). A device found to differ needs its signs
/// flipped here, in one place.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hpr {
    pub heading_rad: Option<f64>,
    pub heading_status: HprStatus,
    pub pitch_rad: Option<f64>,
    pub pitch_status: HprStatus,
    pub roll_rad: Option<f64>,
    pub roll_status: HprStatus,
}

/// Why a line is not a usable sentence.
#[derive(Debug, Clone, PartialEq)]
pub enum SentenceError {
    /// The line does not start with `$` or `!` and an address.
    NotASentence,
    /// A `*` is not followed by exactly two hex digits.
    BadChecksumField,
    ChecksumMismatch {
        calculated: u8,
        found: u8,
    },
    /// A well-formed sentence of a type this importer does not read.
    UnknownSentence {
        address: String,
    },
    MissingField {
        sentence: &'static str,
        field: &'static str,
    },
    BadNumber {
        sentence: &'static str,
        field: &'static str,
        text: String,
    },
    /// A field that is not one of the values the format allows.
    BadValue {
        sentence: &'static str,
        field: &'static str,
        text: String,
        expected: &'static str,
    },
}

impl fmt::Display for SentenceError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SentenceError::NotASentence => write!(
                f,
                "not an NMEA sentence (one starts with $ or ! and an address such as GPRMC, \
                 then comma-separated fields)"
            ),
            SentenceError::BadChecksumField => write!(
                f,
                "the checksum after * is not two hexadecimal digits; the line was cut or \
                 joined to another in transit"
            ),
            SentenceError::ChecksumMismatch { calculated, found } => write!(
                f,
                "checksum mismatch: calculated {calculated:02X}, found {found:02X}; the line \
                 was corrupted in transit"
            ),
            SentenceError::UnknownSentence { address } => write!(
                f,
                "{address} sentences are not read by this tool (it reads {READ_SENTENCES})"
            ),
            SentenceError::MissingField { sentence, field } => {
                write!(f, "{sentence} has no {field}, so the sentence was skipped")
            }
            SentenceError::BadNumber {
                sentence,
                field,
                text,
            } => write!(f, "{sentence} {field} is not a number ({text})"),
            SentenceError::BadValue {
                sentence,
                field,
                text,
                expected,
            } => write!(f, "{sentence} {field} is \"{text}\"; expected {expected}"),
        }
    }
}

impl std::error::Error for SentenceError {}

impl SentenceError {
    #[cold]
    fn bad_number(sentence: &'static str, field: &'static str, text: &[u8]) -> SentenceError {
        SentenceError::BadNumber {
            sentence,
            field,
            text: shorten(&field_text(text)),
        }
    }

    #[cold]
    fn bad_value(
        sentence: &'static str,
        field: &'static str,
        text: &[u8],
        expected: &'static str,
    ) -> SentenceError {
        SentenceError::BadValue {
            sentence,
            field,
            text: shorten(&field_text(text)),
            expected,
        }
    }
}

/// Parses one sentence. Leading and trailing whitespace (and a byte-order mark) are
/// ignored; a `*hh` checksum is verified when present.
pub fn parse_sentence(text: &str) -> Result<Sentence, SentenceError> {
    match parse_line(text.as_bytes())? {
        Parsed::Known(sentence) => Ok(sentence),
        Parsed::Unknown { address, .. } => Err(SentenceError::UnknownSentence {
            address: shorten(address),
        }),
    }
}

/// The parser behind [`parse_sentence`], which does not allocate for the common case
/// of a sentence type this importer does not read (GSV, GSA, … are half of many logs).
enum Parsed<'a> {
    Known(Sentence),
    Unknown {
        address: &'a str,
        has_checksum: bool,
    },
}

/// The text of a field, for a message. Fields are cut at ASCII bytes from UTF-8 text,
/// so they are UTF-8 themselves; the replacement only guards against a caller's bug.
fn field_text(field: &[u8]) -> Cow<'_, str> {
    String::from_utf8_lossy(field)
}

/// Parses the bytes of one line, which must be UTF-8 (text, or ASCII bytes): bytes
/// rather than `str` so that an ASCII line needs no UTF-8 validation.
#[inline(always)]
fn parse_line(bytes: &[u8]) -> Result<Parsed<'_>, SentenceError> {
    let mut bytes = bytes;
    while let Some(rest) = bytes.strip_prefix("\u{feff}".as_bytes()) {
        bytes = rest;
    }
    let bytes = bytes.trim_ascii();
    if !matches!(bytes.first(), Some(b'$' | b'!')) {
        return Err(SentenceError::NotASentence);
    }
    // The checksum delimiter is searched from the end, where it is; `*` may not appear
    // in the data, so a line with two is corrupt either way.
    let (body, has_checksum, found) = match bytes.iter().rposition(|&byte| byte == b'*') {
        None => (bytes.get(1..).unwrap_or_default(), false, None),
        Some(star_idx) => {
            let found = match bytes.get(star_idx + 1..) {
                Some([high, low]) => hex_pair(*high, *low),
                _ => None,
            }
            .ok_or(SentenceError::BadChecksumField)?;
            (
                bytes.get(1..star_idx).unwrap_or_default(),
                true,
                Some(found),
            )
        }
    };
    // Comma positions are kept as u32 (see `BodyScan`): a body of 4 GiB or more is not
    // a sentence (NMEA allows 82 characters), and the readers cut lines at 4 KiB.
    if u32::try_from(body.len()).is_err() {
        return Err(SentenceError::NotASentence);
    }
    let scan = BodyScan::of(body);
    if let Some(found) = found {
        if found != scan.xor {
            return Err(SentenceError::ChecksumMismatch {
                calculated: scan.xor,
                found,
            });
        }
    }

    let fields = Fields { body, scan: &scan };
    let address = fields.address();
    if address.is_empty()
        || !address
            .iter()
            .all(|byte| byte.is_ascii_uppercase() || byte.is_ascii_digit())
    {
        return Err(SentenceError::NotASentence);
    }
    let unknown = || Parsed::Unknown {
        // Upper-case letters and digits only, so always UTF-8.
        address: std::str::from_utf8(address).unwrap_or_default(),
        has_checksum,
    };
    // Byte patterns rather than string comparisons: this runs once per line.
    let (talker, data) = match *address {
        [b'P', b'T', b'N', b'T', b'H', b'P', b'R'] => {
            (None, SentenceData::Hpr(parse_hpr(fields.take())?))
        }
        [b'P', ..] => return Ok(unknown()),
        [first, second, a, b, c] => {
            let data = match [a, b, c] {
                [b'R', b'M', b'C'] => SentenceData::Rmc(parse_rmc(fields.take())?),
                [b'G', b'G', b'A'] => SentenceData::Gga(parse_gga(fields.take())?),
                [b'V', b'T', b'G'] => SentenceData::Vtg(parse_vtg(fields.take())?),
                [b'H', b'D', b'G'] => SentenceData::Hdg(parse_hdg(fields.take())?),
                [b'H', b'D', b'M'] => {
                    SentenceData::Hdm(parse_heading_only(fields.take(), "HDM", b'M')?)
                }
                [b'H', b'D', b'T'] => {
                    SentenceData::Hdt(parse_heading_only(fields.take(), "HDT", b'T')?)
                }
                _ => return Ok(unknown()),
            };
            (Some([first, second]), data)
        }
        _ => return Ok(unknown()),
    };
    Ok(Parsed::Known(Sentence {
        talker,
        has_checksum,
        data,
    }))
}

#[inline(always)]
fn hex_pair(high: u8, low: u8) -> Option<u8> {
    let digit = |byte: u8| (byte as char).to_digit(16);
    let value = digit(high)? * 16 + digit(low)?;
    u8::try_from(value).ok()
}

/// How many commas [`BodyScan`] records: the address and the twelve fields of the
/// longest sentence read (RMC, GGA) need thirteen.
const MAX_COMMAS: usize = 16;

/// One pass over a sentence body, eight bytes at a time: the checksum (the XOR of all
/// bytes; XOR is associative, so the lanes of the wide XOR fold down to it) and where
/// the first [`MAX_COMMAS`] commas are. One pass instead of one for the checksum and
/// one byte by byte per field. The positions are u32 (the caller refuses longer bodies)
/// so that the scan is small enough to stay in registers and on the stack: with `usize`
/// positions it was 144 bytes, and returning it was a `memcpy` call on every line.
struct BodyScan {
    xor: u8,
    n_commas: usize,
    comma_idx: [u32; MAX_COMMAS],
}

impl BodyScan {
    #[inline(always)]
    fn of(body: &[u8]) -> BodyScan {
        let mut scan = BodyScan {
            xor: 0,
            n_commas: 0,
            comma_idx: [0; MAX_COMMAS],
        };
        let mut xor_word = 0u64;
        let mut words = body.chunks_exact(8);
        let mut word_start = 0usize;
        for word in &mut words {
            let word = u64::from_le_bytes(<[u8; 8]>::try_from(word).unwrap_or_default());
            xor_word ^= word;
            scan.note_commas(word, word_start);
            word_start += 8;
        }
        // The last bytes, padded with zeros, which change neither the XOR nor the
        // commas: read as the body's last eight bytes shifted down past those already
        // seen, where the body is that long.
        let remainder = words.remainder();
        let word = match body
            .len()
            .checked_sub(8)
            .and_then(|start| body.get(start..))
        {
            Some(last_eight) if !remainder.is_empty() => {
                let last_eight =
                    u64::from_le_bytes(<[u8; 8]>::try_from(last_eight).unwrap_or_default());
                last_eight >> (8 * (8 - remainder.len()))
            }
            _ => remainder
                .iter()
                .rev()
                .fold(0u64, |word, &byte| word << 8 | u64::from(byte)),
        };
        xor_word ^= word;
        scan.note_commas(word, word_start);
        scan.xor = xor_word
            .to_le_bytes()
            .iter()
            .fold(0u8, |acc, byte| acc ^ byte);
        scan
    }

    /// Records the commas among the eight bytes of `word` (little-endian, so byte `k`
    /// is bits `8k..8k + 8`), which start at `word_start` in the body.
    #[inline(always)]
    fn note_commas(&mut self, word: u64, word_start: usize) {
        const LOW_7_BITS: u64 = 0x7f7f_7f7f_7f7f_7f7f;
        const COMMAS: u64 = 0x2c2c_2c2c_2c2c_2c2c;
        // A byte of `diff` is zero exactly where `word` has a comma. Adding 0x7f to
        // the low seven bits of a byte sets its high bit unless they are all zero, and
        // never carries into the next byte, so the high bit of each byte of `comma_bits`
        // is set exactly where `diff` has a zero byte (the common `(x - 0x01…) & !x`
        // trick also flags a 0x01 byte above a zero one: a `-` after a comma).
        let diff = word ^ COMMAS;
        let mut comma_bits = !(((diff & LOW_7_BITS) + LOW_7_BITS) | diff | LOW_7_BITS);
        while comma_bits != 0 {
            let Some(slot) = self.comma_idx.get_mut(self.n_commas) else {
                return;
            };
            // The body is shorter than 4 GiB (checked by the caller), so this fits.
            *slot = (word_start + (comma_bits.trailing_zeros() / 8) as usize) as u32;
            self.n_commas += 1;
            comma_bits &= comma_bits - 1;
        }
    }
}

/// The comma-separated fields of a sentence body: field 0 is the address.
struct Fields<'a, 'b> {
    body: &'a [u8],
    scan: &'b BodyScan,
}

impl<'a> Fields<'a, '_> {
    /// The address: the body up to its first comma.
    #[inline(always)]
    fn address(&self) -> &'a [u8] {
        let end = match self.scan.n_commas {
            0 => self.body.len(),
            _ => self
                .scan
                .comma_idx
                .first()
                .map_or(self.body.len(), |&idx| idx as usize),
        };
        self.body.get(..end).unwrap_or_default()
    }

    /// The `N` fields after the address, trimmed; missing trailing fields are empty
    /// (null), extra ones ignored.
    #[inline(always)]
    fn take<const N: usize>(&self) -> [&'a [u8]; N] {
        let mut taken: [&'a [u8]; N] = [&[]; N];
        let commas = self
            .scan
            .comma_idx
            .get(..self.scan.n_commas)
            .unwrap_or_default();
        // Field k + 1 starts after comma k and ends at comma k + 1 or the body's end.
        for (field_idx, slot) in taken.iter_mut().enumerate() {
            let Some(&comma_idx) = commas.get(field_idx) else {
                break;
            };
            let end = commas
                .get(field_idx + 1)
                .map_or(self.body.len(), |&idx| idx as usize);
            *slot = trim_field(
                self.body
                    .get(comma_idx as usize + 1..end)
                    .unwrap_or_default(),
            );
        }
        taken
    }
}

/// A field without surrounding ASCII whitespace; a field without any, the usual one,
/// is seen as such from its two ends.
#[inline(always)]
fn trim_field(field: &[u8]) -> &[u8] {
    match (field.first(), field.last()) {
        (Some(first), Some(last)) if first.is_ascii_whitespace() || last.is_ascii_whitespace() => {
            field.trim_ascii()
        }
        _ => field,
    }
}

#[inline(always)]
fn parse_rmc(fields: [&[u8]; 12]) -> Result<Rmc, SentenceError> {
    const S: &str = "RMC";
    let [time, status, lat, lat_ns, lon, lon_ew, knots, course_deg, date, var_deg, var_ew, mode] =
        fields;
    let status_valid = match status {
        b"A" => true,
        b"V" => false,
        b"" => {
            return Err(SentenceError::MissingField {
                sentence: S,
                field: "status",
            })
        }
        other => return Err(SentenceError::bad_value(S, "status", other, "A or V")),
    };
    Ok(Rmc {
        time_of_day_s: time_of_day_s(S, time)?,
        status_valid,
        lat_deg: coordinate(S, Axis::Latitude, lat, lat_ns)?,
        lon_deg: coordinate(S, Axis::Longitude, lon, lon_ew)?,
        speed_mps: number(S, "speed over ground", knots)?.map(|knots| knots * MPS_PER_KNOT),
        course_rad: heading_rad(S, "course over ground", course_deg)?,
        date: parse_date(S, date)?,
        magnetic_variation_rad: east_positive_rad(S, "magnetic variation", var_deg, var_ew)?,
        mode: first_char(mode),
    })
}

/// The first character of a field.
#[inline(always)]
fn first_char(field: &[u8]) -> Option<char> {
    match field.first() {
        Some(&byte) if byte.is_ascii() => Some(char::from(byte)),
        Some(_) => field_text(field).chars().next(),
        None => None,
    }
}

#[inline(always)]
fn parse_gga(fields: [&[u8]; 12]) -> Result<Gga, SentenceError> {
    const S: &str = "GGA";
    let [time, lat, lat_ns, lon, lon_ew, quality, n_sats, hdop, alt, alt_unit, sep, sep_unit] =
        fields;
    for (unit, field) in [
        (alt_unit, "altitude unit"),
        (sep_unit, "geoid separation unit"),
    ] {
        if !matches!(unit, b"" | b"M") {
            return Err(SentenceError::bad_value(S, field, unit, "M (metres)"));
        }
    }
    Ok(Gga {
        time_of_day_s: time_of_day_s(S, time)?,
        lat_deg: coordinate(S, Axis::Latitude, lat, lat_ns)?,
        lon_deg: coordinate(S, Axis::Longitude, lon, lon_ew)?,
        quality: integer(S, "fix quality", quality)?,
        n_satellites: integer(S, "number of satellites", n_sats)?,
        hdop: number(S, "HDOP", hdop)?,
        alt_msl_m: number(S, "altitude", alt)?,
        geoid_separation_m: number(S, "geoid separation", sep)?,
    })
}

#[inline(always)]
fn parse_vtg(fields: [&[u8]; 9]) -> Result<Vtg, SentenceError> {
    const S: &str = "VTG";
    let [course_true, t_letter, course_magnetic, m_letter, knots, n_letter, kmph, k_letter, mode] =
        fields;
    // NMEA 1.x receivers send the four values without their unit letters, so the
    // second field is a number and nothing follows the fourth.
    let is_legacy = !matches!(t_letter, b"T" | b"")
        && [knots, n_letter, kmph, k_letter, mode]
            .iter()
            .all(|field| field.is_empty());
    let no_mode: &[u8] = b"";
    let (course_true, course_magnetic, knots, kmph, mode) = if is_legacy {
        (course_true, t_letter, course_magnetic, m_letter, no_mode)
    } else {
        (course_true, course_magnetic, knots, kmph, mode)
    };
    let speed_mps = match number(S, "speed over ground (knots)", knots)? {
        Some(knots) => Some(knots * MPS_PER_KNOT),
        None => number(S, "speed over ground (km/h)", kmph)?.map(|kmph| kmph / 3.6),
    };
    Ok(Vtg {
        course_true_rad: heading_rad(S, "true course", course_true)?,
        course_magnetic_rad: heading_rad(S, "magnetic course", course_magnetic)?,
        speed_mps,
        mode: first_char(mode),
    })
}

fn parse_hdg(fields: [&[u8]; 5]) -> Result<Hdg, SentenceError> {
    const S: &str = "HDG";
    let [heading, deviation, deviation_direction, variation, variation_direction] = fields;
    let sensor_heading_rad =
        heading_rad(S, "heading", heading)?.ok_or(SentenceError::MissingField {
            sentence: S,
            field: "heading",
        })?;
    Ok(Hdg {
        sensor_heading_rad,
        deviation_rad: east_positive_rad(S, "deviation", deviation, deviation_direction)?,
        variation_rad: east_positive_rad(S, "variation", variation, variation_direction)?,
    })
}

#[inline(always)]
fn parse_heading_only(
    fields: [&[u8]; 2],
    sentence: &'static str,
    letter: u8,
) -> Result<HeadingOnly, SentenceError> {
    let [heading, reference] = fields;
    if !(reference.is_empty() || reference == [letter]) {
        return Err(SentenceError::bad_value(
            sentence,
            "reference letter",
            reference,
            if letter == b'M' { "M" } else { "T" },
        ));
    }
    let heading_rad =
        heading_rad(sentence, "heading", heading)?.ok_or(SentenceError::MissingField {
            sentence,
            field: "heading",
        })?;
    Ok(HeadingOnly { heading_rad })
}

fn parse_hpr(fields: [&[u8]; 6]) -> Result<Hpr, SentenceError> {
    const S: &str = "PTNTHPR";
    let [heading, heading_status, pitch, pitch_status, roll, roll_status] = fields;
    let status = |field: &'static str, letter: &[u8]| -> Result<HprStatus, SentenceError> {
        if letter.is_empty() {
            return Err(SentenceError::MissingField { sentence: S, field });
        }
        HprStatus::from_letter(letter)
            .ok_or_else(|| SentenceError::bad_value(S, field, letter, "one of N, M, L, O, P, C"))
    };
    let angle =
        |field: &'static str, text: &[u8], max_deg: f64, expected: &'static str| match number(
            S, field, text,
        )? {
            Some(value_deg) if (-max_deg..=max_deg).contains(&value_deg) => {
                Ok(Some(value_deg.to_radians()))
            }
            Some(_) => Err(SentenceError::bad_value(S, field, text, expected)),
            None => Ok(None),
        };
    let heading_rad = match number(S, "heading", heading)? {
        Some(heading_deg) if (0.0..=360.0).contains(&heading_deg) => {
            Some(heading_0_360_rad(heading_deg))
        }
        Some(_) => {
            return Err(SentenceError::bad_value(
                S,
                "heading",
                heading,
                "0 to 360 degrees (is the compass set to mils?)",
            ))
        }
        None => None,
    };
    Ok(Hpr {
        heading_rad,
        heading_status: status("magnetic field status", heading_status)?,
        pitch_rad: angle(
            "pitch",
            pitch,
            90.0,
            "-90 to 90 degrees (is the compass set to mils?)",
        )?,
        pitch_status: status("pitch status", pitch_status)?,
        roll_rad: angle(
            "roll",
            roll,
            180.0,
            "-180 to 180 degrees (is the compass set to mils?)",
        )?,
        roll_status: status("roll status", roll_status)?,
    })
}

/// A decimal number as [`super::number::parse_f64`] reads it, from bytes: Clinger's
/// fast path, else the standard library's parser.
#[inline(always)]
fn parse_f64_bytes(text: &[u8]) -> Option<f64> {
    match super::number::parse_prefix(text) {
        Some((value, consumed)) if consumed == text.len() => Some(value),
        _ => std::str::from_utf8(text).ok()?.parse::<f64>().ok(),
    }
}

/// A finite decimal number, `None` for a null field.
#[inline(always)]
fn number(
    sentence: &'static str,
    field: &'static str,
    text: &[u8],
) -> Result<Option<f64>, SentenceError> {
    if text.is_empty() {
        return Ok(None);
    }
    match parse_f64_bytes(text) {
        Some(value) if value.is_finite() => Ok(Some(value)),
        _ => Err(SentenceError::bad_number(sentence, field, text)),
    }
}

/// A whole number as `str::parse` reads it: up to nine plain digits directly, anything
/// else (a sign, more digits) through `str::parse`.
#[inline(always)]
fn integer<T: std::str::FromStr + TryFrom<u32>>(
    sentence: &'static str,
    field: &'static str,
    text: &[u8],
) -> Result<Option<T>, SentenceError> {
    if text.is_empty() {
        return Ok(None);
    }
    if text.len() <= 9 && text.iter().all(u8::is_ascii_digit) {
        let value = text
            .iter()
            .fold(0u32, |value, digit| value * 10 + u32::from(digit - b'0'));
        if let Ok(value) = T::try_from(value) {
            return Ok(Some(value));
        }
    }
    std::str::from_utf8(text)
        .ok()
        .and_then(|text| text.parse::<T>().ok())
        .map(Some)
        .ok_or_else(|| SentenceError::bad_number(sentence, field, text))
}

/// A heading or course in degrees, 0 to 360, as radians in `[0, 2π)`.
#[inline(always)]
fn heading_rad(
    sentence: &'static str,
    field: &'static str,
    text: &[u8],
) -> Result<Option<f64>, SentenceError> {
    match number(sentence, field, text)? {
        Some(value_deg) if (0.0..=360.0).contains(&value_deg) => {
            Ok(Some(heading_0_360_rad(value_deg)))
        }
        Some(_) => Err(SentenceError::bad_value(
            sentence,
            field,
            text,
            "0 to 360 degrees",
        )),
        None => Ok(None),
    }
}

/// A heading already checked to lie in 0-360°, as radians in `[0, 2π)`. Only 360
/// itself needs wrapping, which spares the hot path the remainder in `wrap_to_2pi`.
#[inline(always)]
fn heading_0_360_rad(heading_deg: f64) -> f64 {
    let heading_rad = heading_deg.to_radians();
    if heading_rad >= std::f64::consts::TAU {
        0.0
    } else {
        heading_rad
    }
}

/// An angle with an E/W letter, east positive. A value without its letter is dropped
/// rather than guessed, and does not cost the rest of the sentence.
#[inline(always)]
fn east_positive_rad(
    sentence: &'static str,
    field: &'static str,
    value: &[u8],
    direction: &[u8],
) -> Result<Option<f64>, SentenceError> {
    let Some(value_deg) = number(sentence, field, value)? else {
        return Ok(None);
    };
    match direction {
        b"E" => Ok(Some(value_deg.to_radians())),
        b"W" => Ok(Some(-value_deg.to_radians())),
        b"" => Ok(None),
        other => Err(SentenceError::bad_value(sentence, field, other, "E or W")),
    }
}

#[derive(Clone, Copy)]
enum Axis {
    Latitude,
    Longitude,
}

/// `ddmm.mmmm` (latitude) or `dddmm.mmmm` (longitude) and its hemisphere letter, as
/// decimal degrees, south and west negative.
#[inline(always)]
fn coordinate(
    sentence: &'static str,
    axis: Axis,
    value: &[u8],
    hemisphere: &[u8],
) -> Result<Option<f64>, SentenceError> {
    let (field, hemisphere_field, max_deg, positive, negative, expected_letters, expected_value) =
        match axis {
            Axis::Latitude => (
                "latitude",
                "latitude hemisphere",
                90.0,
                b"N",
                b"S",
                "N or S",
                "ddmm.mmmm, at most 90°",
            ),
            Axis::Longitude => (
                "longitude",
                "longitude hemisphere",
                180.0,
                b"E",
                b"W",
                "E or W",
                "dddmm.mmmm, at most 180°",
            ),
        };
    match (value.is_empty(), hemisphere.is_empty()) {
        (true, true) => return Ok(None),
        (true, false) => return Err(SentenceError::MissingField { sentence, field }),
        (false, true) => {
            return Err(SentenceError::MissingField {
                sentence,
                field: hemisphere_field,
            })
        }
        (false, false) => {}
    }
    let Some(ddmm) = number(sentence, field, value)? else {
        return Ok(None);
    };
    // Truncation through an integer where that is exact (`f64::trunc` is a library
    // call on baseline x86-64); negative or huge values are refused below either way.
    let degrees = if (0.0..1e15).contains(&ddmm) {
        ((ddmm / 100.0) as u64) as f64
    } else {
        (ddmm / 100.0).trunc()
    };
    let minutes = ddmm - degrees * 100.0;
    let decimal_deg = degrees + minutes / 60.0;
    if !(ddmm >= 0.0 && minutes < 60.0 && decimal_deg <= max_deg) {
        return Err(SentenceError::bad_value(
            sentence,
            field,
            value,
            expected_value,
        ));
    }
    if hemisphere == positive {
        Ok(Some(decimal_deg))
    } else if hemisphere == negative {
        Ok(Some(-decimal_deg))
    } else {
        Err(SentenceError::bad_value(
            sentence,
            hemisphere_field,
            hemisphere,
            expected_letters,
        ))
    }
}

/// Two ASCII digits at `at`, as a number.
#[inline(always)]
fn two_digits(bytes: &[u8], at: usize) -> Option<u8> {
    match bytes.get(at..at + 2)? {
        [tens @ b'0'..=b'9', ones @ b'0'..=b'9'] => Some((tens - b'0') * 10 + (ones - b'0')),
        _ => None,
    }
}

/// `hhmmss` with optional decimals, as seconds since midnight.
#[inline(always)]
fn time_of_day_s(sentence: &'static str, text: &[u8]) -> Result<Option<f64>, SentenceError> {
    if text.is_empty() {
        return Ok(None);
    }
    let bad = || SentenceError::bad_value(sentence, "time", text, "hhmmss.ss (UTC)");
    let (Some(hours), Some(minutes), Some(_)) = (
        two_digits(text, 0),
        two_digits(text, 2),
        two_digits(text, 4),
    ) else {
        return Err(bad());
    };
    // The seconds keep their decimals. A leap second (60) is allowed.
    let seconds = text.get(4..).and_then(parse_f64_bytes).ok_or_else(bad)?;
    if hours > 23 || minutes > 59 || !(0.0..61.0).contains(&seconds) {
        return Err(bad());
    }
    Ok(Some(
        f64::from(hours) * 3600.0 + f64::from(minutes) * 60.0 + seconds,
    ))
}

/// `ddmmyy`. Two-digit years 80-99 are 1980-1999 (GPS began in 1980), the rest 20xx.
#[inline(always)]
fn parse_date(sentence: &'static str, text: &[u8]) -> Result<Option<NmeaDate>, SentenceError> {
    if text.is_empty() {
        return Ok(None);
    }
    let (Some(day), Some(month), Some(year), 6) = (
        two_digits(text, 0),
        two_digits(text, 2),
        two_digits(text, 4),
        text.len(),
    ) else {
        return Err(SentenceError::bad_value(sentence, "date", text, "ddmmyy"));
    };
    if !(1..=31).contains(&day) || !(1..=12).contains(&month) {
        return Err(SentenceError::bad_value(sentence, "date", text, "ddmmyy"));
    }
    let year = if year >= 80 {
        1900 + i32::from(year)
    } else {
        2000 + i32::from(year)
    };
    Ok(Some(NmeaDate { year, month, day }))
}

/// Whether a line has the shape of a sentence: `$` or `!`, an address of a talker and
/// a type (5 characters) or a proprietary `P…` address, then fields, then optionally
/// `*hh`. The checksum's value is not checked: a corrupted sentence still shows the
/// format.
fn is_sentence_shaped(line: &str) -> bool {
    let line = line.trim_start_matches('\u{feff}').trim_ascii();
    let bytes = line.as_bytes();
    let Some((&start, rest)) = bytes.split_first() else {
        return false;
    };
    if start != b'$' && start != b'!' {
        return false;
    }
    let address_len = rest
        .iter()
        .position(|&byte| byte == b',' || byte == b'*')
        .unwrap_or(rest.len());
    let address = rest.get(..address_len).unwrap_or_default();
    let address_ok = address
        .iter()
        .all(|byte| byte.is_ascii_uppercase() || byte.is_ascii_digit())
        && (address.len() == 5
            || (start == b'$' && address.len() >= 2 && address.first() == Some(&b'P')));
    if !address_ok {
        return false;
    }
    match rest.iter().position(|&byte| byte == b'*') {
        None => true,
        Some(star_idx) => matches!(
            rest.get(star_idx + 1..),
            Some([high, low]) if high.is_ascii_hexdigit() && low.is_ascii_hexdigit()
        ),
    }
}

/// Whether a line holds nothing but whitespace and perhaps a byte-order mark.
fn is_blank(line: &str) -> bool {
    // Most lines start with `$`; they need no Unicode-aware trimming.
    match line.as_bytes().first() {
        Some(b'$' | b'!') => false,
        _ => line.trim_start_matches('\u{feff}').trim().is_empty(),
    }
}

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

// ---------------------------------------------------------------------------------------
// Import
// ---------------------------------------------------------------------------------------

/// Reads NMEA 0183 bytes. Fails only when nothing can be read; every skipped line
/// becomes a diagnostic in the report.
///
/// Parsing a line needs no state, applying it does (the clock, the epoch merge, the
/// placing of untimed sentences, the counts): on native builds a large file is parsed
/// on every core and applied in order on one thread (`parallel`), with the same
/// result as reading it line by line; so is it in the browser's threaded build
/// ([`crate::par`]), and the default browser build reads on one thread.
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

/// Calls `on_line` with the 1-based number and the content (without its terminator) of
/// every line of a whole buffer: the lines [`decode_all`](super::lines::decode_all)
/// gives (CR, LF and CRLF end a line; a last line without an ending counts), but as
/// bytes borrowed from the buffer. Returns the number of lines.
fn for_each_line<'a>(bytes: &'a [u8], mut on_line: impl FnMut(usize, &'a [u8])) -> usize {
    let mut rest = bytes;
    let mut n_lines = 0usize;
    while let Some(end_idx) = memchr::memchr2(b'\n', b'\r', rest) {
        let (content, tail) = rest.split_at(end_idx);
        n_lines += 1;
        on_line(n_lines, content);
        rest = match tail {
            [b'\r', b'\n', after @ ..] | [_, after @ ..] => after,
            [] => tail,
        };
    }
    if !rest.is_empty() {
        n_lines += 1;
        on_line(n_lines, rest);
    }
    n_lines
}

/// What one line is, parsed but not yet applied to a reader. Parsing needs no state,
/// so lines can be parsed anywhere (on another thread) and applied in order later.
#[derive(Debug, Clone, PartialEq)]
enum LineEvent<'a> {
    /// Nothing but whitespace (and perhaps a byte-order mark): not a data line.
    Blank,
    /// Longer than [`MAX_LINE_BYTES`].
    Truncated,
    Known(Sentence),
    Unknown {
        address: Cow<'a, str>,
        has_checksum: bool,
    },
    Error(SentenceError),
}

impl<'a> LineEvent<'a> {
    /// A line's content as [`for_each_line`] gives it: cut when too long (as the line
    /// decoder cuts it), replacing bytes that are not UTF-8 (as it does).
    fn of(content: &'a [u8]) -> LineEvent<'a> {
        if content.len() > MAX_LINE_BYTES {
            return LineEvent::Truncated;
        }
        // A sentence in ASCII, the usual line, is parsed from its bytes; anything else
        // is decoded first.
        if matches!(content.first(), Some(b'$' | b'!')) && content.is_ascii() {
            return LineEvent::of_sentence(content);
        }
        match std::str::from_utf8(content) {
            Ok(text) => LineEvent::parse(text),
            Err(_) => LineEvent::parse(&String::from_utf8_lossy(content)).into_owned(),
        }
    }

    fn parse(text: &'a str) -> LineEvent<'a> {
        if is_blank(text) {
            return LineEvent::Blank;
        }
        LineEvent::of_sentence(text.as_bytes())
    }

    /// A line that is not blank, as UTF-8 bytes.
    fn of_sentence(bytes: &'a [u8]) -> LineEvent<'a> {
        match parse_line(bytes) {
            Ok(Parsed::Known(sentence)) => LineEvent::Known(sentence),
            Ok(Parsed::Unknown {
                address,
                has_checksum,
            }) => LineEvent::Unknown {
                address: Cow::Borrowed(address),
                has_checksum,
            },
            Err(error) => LineEvent::Error(error),
        }
    }

    fn into_owned(self) -> LineEvent<'static> {
        match self {
            LineEvent::Blank => LineEvent::Blank,
            LineEvent::Truncated => LineEvent::Truncated,
            LineEvent::Known(sentence) => LineEvent::Known(sentence),
            LineEvent::Unknown {
                address,
                has_checksum,
            } => LineEvent::Unknown {
                address: Cow::Owned(address.into_owned()),
                has_checksum,
            },
            LineEvent::Error(error) => LineEvent::Error(error),
        }
    }
}

/// What one sentence gives the recording.
#[derive(Debug, Clone, Copy)]
enum SampleValue {
    Fix(GnssFix),
    Heading(DeviceHeading),
    Hpr {
        attitude: Attitude,
        heading: DeviceHeading,
    },
}

/// Which stream of the recording a sample went to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum StreamId {
    Gnss,
    DeviceHeading,
    Attitude,
}

/// A sample pushed without a time (its `t_s` is NaN until the end of the input, when
/// the timed sentences around it are known).
#[derive(Debug, Clone, Copy)]
struct Untimed {
    stream: StreamId,
    /// Index in its stream.
    idx: usize,
    line: usize,
    /// Position among the untimed sentences, from 0: the time when nothing else is.
    number: usize,
}

/// A timed sentence: where it is in the file and when it was.
#[derive(Debug, Clone, Copy)]
struct Anchor {
    line: usize,
    t_s: f64,
}

/// Turns times of day into seconds since the first timed sentence, counting days.
#[derive(Debug, Clone, Default)]
struct Clock {
    first_time_of_day_s: Option<f64>,
    /// Day of the last timed sentence, counted from the first one's (day 0).
    day: i64,
    last_time_of_day_s: f64,
    /// The first date seen (days since 1970) and the day count it fell on, which lets
    /// later dates set the day count directly.
    first_date: Option<(i64, i64)>,
    n_midnights: usize,
}

impl Clock {
    fn t_s(&mut self, time_of_day_s: f64, date: Option<NmeaDate>) -> f64 {
        let date_days = date.map(|date| date.days_since_1970());
        let Some(first_time_of_day_s) = self.first_time_of_day_s else {
            self.first_time_of_day_s = Some(time_of_day_s);
            self.last_time_of_day_s = time_of_day_s;
            self.first_date = date_days.map(|days| (days, 0));
            return 0.0;
        };
        let day = match (date_days, self.first_date) {
            (Some(days), Some((first_days, first_day))) => first_day + (days - first_days),
            _ => {
                // Without a date, a jump back of more than half a day is the clock
                // passing midnight, and a jump forward of as much is a late sentence
                // from before it.
                let mut day = self.day;
                if time_of_day_s < self.last_time_of_day_s - SECONDS_PER_DAY / 2.0 {
                    day += 1;
                } else if time_of_day_s > self.last_time_of_day_s + SECONDS_PER_DAY / 2.0 {
                    day -= 1;
                }
                if let (Some(days), None) = (date_days, self.first_date) {
                    self.first_date = Some((days, day));
                }
                day
            }
        };
        if day > self.day {
            self.n_midnights += usize::try_from(day - self.day).unwrap_or(0);
        }
        self.day = day;
        self.last_time_of_day_s = time_of_day_s;
        day as f64 * SECONDS_PER_DAY + time_of_day_s - first_time_of_day_s
    }
}

/// The streaming importer: feed it lines as they come (from a file or a serial port),
/// then [`finish`](NmeaReader::finish) for the report.
///
/// Time: RMC and GGA carry the time of day; `t_s` is seconds since the first of them,
/// counted across midnight. The other sentences carry no time: once the next timed
/// sentence is read, each is placed by its line number between the timed sentences
/// before and after it (evenly spaced, so ten HDT lines between two fixes one second
/// apart get 1/11 s steps). Before the first and after the last timed sentence they
/// are extrapolated, at the end, at the log's mean time per line; with one timed epoch
/// only, a line counts as one second; with no timed sentence at all, the sample number
/// stands in for time. Each of these assumptions is stated in the notes.
///
/// Fixes: an RMC and a GGA with the same time (one receiver epoch) become one
/// [`GnssFix`]: position from the first, altitude from GGA, speed and course from RMC.
/// A VTG becomes a fix of its own with only speed and course. HDOP is not turned into
/// an accuracy, so `hacc_m` stays `None`.
#[derive(Debug, Clone, Default)]
pub struct NmeaReader {
    /// Samples go straight into the streams, in line order, so that sorting at the end
    /// counts only real steps back in time.
    recording: Recording,
    /// Untimed samples still without a time: first those before the first timed
    /// sentence (`..n_leading`, placed at the end, when the mean time per line is
    /// known), then those after the latest one (placed when the next one comes).
    untimed: Vec<Untimed>,
    n_leading: usize,
    n_untimed_sentences: usize,
    first_anchor: Option<Anchor>,
    last_anchor: Option<Anchor>,
    clock: Clock,
    /// The last fix with a time, as (index in the GNSS stream, `t_s`), to merge RMC and
    /// GGA.
    last_timed_fix: Option<(usize, f64)>,
    diagnostics: Diagnostics,
    n_data_lines: usize,
    n_read: [usize; KIND_NAMES.len()],
    n_without_checksum: usize,
    n_merged: usize,
    n_rmc_invalid: usize,
    n_gga_invalid: usize,
    n_vtg_empty: usize,
    n_hdg_with_deviation: usize,
    hdg_reports_variation: bool,
    /// Which sentence types carried no time (by index in `KIND_NAMES`).
    untimed_kinds: [bool; KIND_NAMES.len()],
    rmc_variation_rad: Option<f64>,
    /// The first sentence that was read but gave nothing, for the error message.
    first_unused: Option<(usize, &'static str)>,
    unknown: Vec<(String, usize)>,
    n_unknown: usize,
    first_unknown_line: Option<usize>,
}

impl NmeaReader {
    pub fn new() -> Self {
        Self::default()
    }

    /// Reads one line. `line_number` is 1-based and should increase from line to line:
    /// untimed sentences are placed in time by it.
    pub fn read_line(&mut self, line_number: usize, text: &str) {
        self.apply(line_number, LineEvent::parse(text));
    }

    /// Reads a block of whole lines where they lie (the last may lack its ending),
    /// numbered on from `n_lines_before`, as [`read`] does for a whole file; returns how
    /// many lines there were. For a file read in chunks
    /// ([`super::import::ChunkedImport`]), which keeps an unfinished line for the next.
    pub(crate) fn read_lines_block(&mut self, bytes: &[u8], n_lines_before: usize) -> usize {
        #[cfg(any(not(target_arch = "wasm32"), target_feature = "atomics"))]
        if let Some(n_lines) = parallel::read_lines_block(self, bytes, n_lines_before) {
            return n_lines;
        }
        for_each_line(bytes, |line_number, content| {
            self.apply(n_lines_before + line_number, LineEvent::of(content));
        })
    }

    /// Reads one line from [`LineDecoder`](super::lines::LineDecoder), skipping it with
    /// a diagnostic if the decoder had to cut it.
    pub fn read_decoded(&mut self, line: &Line<'_>) {
        if line.truncated {
            self.apply(line.number, LineEvent::Truncated);
        } else {
            self.read_line(line.number, &line.text);
        }
    }

    /// Applies one parsed line: the only place lines change the reader's state.
    fn apply(&mut self, line_number: usize, event: LineEvent<'_>) {
        match event {
            LineEvent::Blank => return,
            LineEvent::Truncated => self.diagnostics.push(
                Some(line_number),
                format!(
                    "line longer than {MAX_LINE_BYTES} bytes, so not one NMEA sentence \
                     (at most 82 characters); it was skipped"
                ),
            ),
            LineEvent::Known(sentence) => {
                if !sentence.has_checksum {
                    self.n_without_checksum += 1;
                }
                self.take(line_number, sentence.data);
            }
            LineEvent::Unknown {
                address,
                has_checksum,
            } => {
                if !has_checksum {
                    self.n_without_checksum += 1;
                }
                self.count_unknown(line_number, &address);
            }
            LineEvent::Error(error) => self.diagnostics.push(Some(line_number), error.to_string()),
        }
        self.n_data_lines += 1;
    }

    /// Reserves room in each stream for the whole input, extrapolated from what the
    /// first `bytes_read` of its `bytes_total` bytes gave, so that the streams of a large
    /// file are not copied as they grow. Only the capacity changes, never the samples.
    #[cfg(any(not(target_arch = "wasm32"), target_feature = "atomics"))]
    fn reserve_for(&mut self, bytes_read: usize, bytes_total: usize) {
        if bytes_read == 0 || bytes_total <= bytes_read {
            return;
        }
        // A little more than the extrapolation, so that a slightly denser rest does not
        // need one more (doubling) copy.
        let expected = |len: usize| {
            let estimate = len as f64 * bytes_total as f64 / bytes_read as f64 * 1.05;
            (estimate as usize).saturating_sub(len)
        };
        let recording = &mut self.recording;
        let gnss_more = expected(recording.gnss.len());
        recording.gnss.t_s.reserve(gnss_more);
        recording.gnss.values.reserve(gnss_more);
        let heading_more = expected(recording.device_heading.len());
        recording.device_heading.t_s.reserve(heading_more);
        recording.device_heading.values.reserve(heading_more);
        let attitude_more = expected(recording.attitude.len());
        recording.attitude.t_s.reserve(attitude_more);
        recording.attitude.values.reserve(attitude_more);
    }

    fn count_unknown(&mut self, line_number: usize, address: &str) {
        self.n_unknown += 1;
        self.first_unknown_line.get_or_insert(line_number);
        if let Some(entry) = self
            .unknown
            .iter_mut()
            .find(|(known, _)| known.as_str() == address)
        {
            entry.1 += 1;
        } else if self.unknown.len() < MAX_UNKNOWN_ADDRESSES_NAMED {
            self.unknown.push((shorten(address), 1));
        }
    }

    fn take(&mut self, line: usize, data: SentenceData) {
        let kind_idx = data.kind_idx();
        if let Some(count) = self.n_read.get_mut(kind_idx) {
            *count += 1;
        }
        match data {
            SentenceData::Rmc(rmc) => {
                let t_s = self.timed(line, rmc.time_of_day_s, rmc.date);
                if !rmc.is_valid() {
                    self.n_rmc_invalid += 1;
                    self.first_unused
                        .get_or_insert((line, "RMC status V: the receiver had no valid fix"));
                    return;
                }
                if self.rmc_variation_rad.is_none() {
                    self.rmc_variation_rad = rmc.magnetic_variation_rad;
                }
                let fix = GnssFix {
                    lat_deg: rmc.lat_deg,
                    lon_deg: rmc.lon_deg,
                    speed_mps: rmc.speed_mps,
                    course_rad: rmc.course_rad,
                    ..GnssFix::default()
                };
                self.push_fix(line, kind_idx, t_s, fix);
            }
            SentenceData::Gga(gga) => {
                let t_s = self.timed(line, gga.time_of_day_s, None);
                if !gga.is_valid() {
                    self.n_gga_invalid += 1;
                    self.first_unused
                        .get_or_insert((line, "GGA fix quality 0: the receiver had no valid fix"));
                    return;
                }
                let fix = GnssFix {
                    lat_deg: gga.lat_deg,
                    lon_deg: gga.lon_deg,
                    alt_m: gga.alt_msl_m,
                    ..GnssFix::default()
                };
                self.push_fix(line, kind_idx, t_s, fix);
            }
            SentenceData::Vtg(vtg) => {
                let fix = GnssFix {
                    speed_mps: vtg.speed_mps,
                    course_rad: vtg.course_true_rad,
                    ..GnssFix::default()
                };
                if vtg.mode == Some('N') || fix == GnssFix::default() {
                    self.n_vtg_empty += 1;
                    self.first_unused
                        .get_or_insert((line, "VTG without a valid true course or speed"));
                    return;
                }
                self.push_untimed(line, kind_idx, SampleValue::Fix(fix));
            }
            SentenceData::Hdg(hdg) => {
                if hdg.deviation_rad.is_some() {
                    self.n_hdg_with_deviation += 1;
                }
                if hdg.variation_rad.is_some() {
                    self.hdg_reports_variation = true;
                }
                let heading = DeviceHeading {
                    heading_rad: hdg.magnetic_heading_rad(),
                    north: North::Magnetic,
                };
                self.push_untimed(line, kind_idx, SampleValue::Heading(heading));
            }
            SentenceData::Hdm(hdm) => {
                let heading = DeviceHeading {
                    heading_rad: hdm.heading_rad,
                    north: North::Magnetic,
                };
                self.push_untimed(line, kind_idx, SampleValue::Heading(heading));
            }
            SentenceData::Hdt(hdt) => {
                let heading = DeviceHeading {
                    heading_rad: hdt.heading_rad,
                    north: North::True,
                };
                self.push_untimed(line, kind_idx, SampleValue::Heading(heading));
            }
            SentenceData::Hpr(hpr) => self.take_hpr(line, kind_idx, hpr),
        }
    }

    fn take_hpr(&mut self, line: usize, kind_idx: usize, hpr: Hpr) {
        let statuses = [
            ("magnetic field", hpr.heading_status),
            ("pitch", hpr.pitch_status),
            ("roll", hpr.roll_status),
        ];
        if statuses
            .iter()
            .any(|(_, status)| *status != HprStatus::Normal)
        {
            let described: Vec<String> = statuses
                .iter()
                .filter(|(_, status)| *status != HprStatus::Normal)
                .map(|(name, status)| format!("{name} {}", status.describe()))
                .collect();
            self.diagnostics.push(
                Some(line),
                format!(
                    "PTNTHPR reports {}; only samples with every status normal (N) are kept",
                    described.join(", ")
                ),
            );
            return;
        }
        let missing = [
            ("heading", hpr.heading_rad),
            ("pitch", hpr.pitch_rad),
            ("roll", hpr.roll_rad),
        ]
        .into_iter()
        .find(|(_, value)| value.is_none());
        let (Some(heading_rad), Some(pitch_rad), Some(roll_rad)) =
            (hpr.heading_rad, hpr.pitch_rad, hpr.roll_rad)
        else {
            let field = missing.map_or("value", |(name, _)| name);
            self.diagnostics.push(
                Some(line),
                SentenceError::MissingField {
                    sentence: "PTNTHPR",
                    field,
                }
                .to_string(),
            );
            return;
        };
        let value = SampleValue::Hpr {
            attitude: Attitude {
                roll_rad,
                pitch_rad,
                yaw_rad: Some(heading_rad),
            },
            heading: DeviceHeading {
                heading_rad,
                north: North::Magnetic,
            },
        };
        self.push_untimed(line, kind_idx, value);
    }

    /// Converts a sentence's time of day and records it as an anchor for the untimed
    /// sentences around it.
    fn timed(
        &mut self,
        line: usize,
        time_of_day_s: Option<f64>,
        date: Option<NmeaDate>,
    ) -> Option<f64> {
        let time_of_day_s = time_of_day_s?;
        let t_s = self.clock.t_s(time_of_day_s, date);
        let anchor = Anchor { line, t_s };
        match self.last_anchor {
            None => {
                self.first_anchor = Some(anchor);
                self.n_leading = self.untimed.len();
            }
            Some(before) => {
                let pending = self.untimed.get(self.n_leading..).unwrap_or_default();
                for untimed in pending {
                    set_time(
                        &mut self.recording,
                        untimed,
                        interpolate(before, anchor, untimed.line),
                    );
                }
                self.untimed.truncate(self.n_leading);
            }
        }
        self.last_anchor = Some(anchor);
        Some(t_s)
    }

    fn push_untimed(&mut self, line: usize, kind_idx: usize, value: SampleValue) {
        if let Some(untimed) = self.untimed_kinds.get_mut(kind_idx) {
            *untimed = true;
        }
        let number = self.n_untimed_sentences;
        self.n_untimed_sentences += 1;
        let recording = &mut self.recording;
        let mut note = |stream: StreamId, idx: usize| {
            self.untimed.push(Untimed {
                stream,
                idx,
                line,
                number,
            });
        };
        match value {
            SampleValue::Fix(fix) => {
                note(StreamId::Gnss, recording.gnss.len());
                recording.gnss.push(f64::NAN, fix);
            }
            SampleValue::Heading(heading) => {
                note(StreamId::DeviceHeading, recording.device_heading.len());
                recording.device_heading.push(f64::NAN, heading);
            }
            SampleValue::Hpr { attitude, heading } => {
                note(StreamId::DeviceHeading, recording.device_heading.len());
                recording.device_heading.push(f64::NAN, heading);
                note(StreamId::Attitude, recording.attitude.len());
                recording.attitude.push(f64::NAN, attitude);
            }
        }
    }

    fn push_fix(&mut self, line: usize, kind_idx: usize, t_s: Option<f64>, fix: GnssFix) {
        if fix == GnssFix::default() {
            return;
        }
        let Some(t_s) = t_s else {
            self.push_untimed(line, kind_idx, SampleValue::Fix(fix));
            return;
        };
        if let Some((fix_idx, last_t_s)) = self.last_timed_fix {
            if t_s == last_t_s {
                if let Some(merged) = self.recording.gnss.values.get_mut(fix_idx) {
                    // The first sentence of the epoch keeps what it gave; the second fills in.
                    merged.lat_deg = merged.lat_deg.or(fix.lat_deg);
                    merged.lon_deg = merged.lon_deg.or(fix.lon_deg);
                    merged.alt_m = merged.alt_m.or(fix.alt_m);
                    merged.speed_mps = merged.speed_mps.or(fix.speed_mps);
                    merged.course_rad = merged.course_rad.or(fix.course_rad);
                    self.n_merged += 1;
                    return;
                }
            }
        }
        self.last_timed_fix = Some((self.recording.gnss.len(), t_s));
        self.recording.gnss.push(t_s, fix);
    }

    /// Ends the input: places the untimed samples in time, sorts every stream and
    /// writes the notes. Fails when no line gave a sample.
    pub fn finish(mut self, file_name: &str) -> Result<ImportReport, ImportError> {
        let file_name = file_name.to_string();
        if self.n_data_lines == 0 {
            return Err(ImportError::Empty { file_name });
        }
        let mut notes = Vec::new();
        self.note_counts(&mut notes);
        let s_per_line = self.note_time(&mut notes);
        // t_s = 0 is the first timed sentence, on the day the first RMC date fixes.
        self.recording.start_unix_s = self.clock.first_date.map(|(first_days, first_day)| {
            (first_days - first_day) as f64 * SECONDS_PER_DAY
                + self.clock.first_time_of_day_s.unwrap_or(0.0)
        });
        let (leading, trailing) = self
            .untimed
            .split_at(self.n_leading.min(self.untimed.len()));
        for untimed in leading {
            let t_s = match self.first_anchor {
                Some(after) => {
                    after.t_s - after.line.saturating_sub(untimed.line) as f64 * s_per_line
                }
                None => untimed.number as f64,
            };
            set_time(&mut self.recording, untimed, t_s);
        }
        for untimed in trailing {
            let t_s = match self.last_anchor {
                Some(before) => {
                    before.t_s + untimed.line.saturating_sub(before.line) as f64 * s_per_line
                }
                None => untimed.number as f64,
            };
            set_time(&mut self.recording, untimed, t_s);
        }

        let mut recording = self.recording;
        let mut diagnostics = self.diagnostics;
        if recording.gnss.is_empty()
            && recording.device_heading.is_empty()
            && recording.attitude.is_empty()
        {
            let first_problem = if let Some(first) = diagnostics.kept.first() {
                match first.line {
                    Some(line) => format!(" (line {line}: {})", first.message),
                    None => format!(" ({})", first.message),
                }
            } else if let Some((line, reason)) = self.first_unused {
                format!(" (line {line}: {reason})")
            } else if let (Some(line), Some((address, _))) =
                (self.first_unknown_line, self.unknown.first())
            {
                format!(
                    " (line {line}: {address} sentences are not read by this tool; \
                     it reads {READ_SENTENCES})"
                )
            } else {
                String::new()
            };
            return Err(ImportError::NothingRecognised {
                file_name,
                format: FORMAT_NAME,
                n_lines: self.n_data_lines,
                first_problem,
            });
        }

        let n_out_of_order = recording.gnss.sort_by_time()
            + recording.device_heading.sort_by_time()
            + recording.attitude.sort_by_time();
        if n_out_of_order > 0 {
            diagnostics.push(
                None,
                format!(
                    "time goes backwards {n_out_of_order} times; the samples were sorted by time"
                ),
            );
        }
        Ok(ImportReport {
            file_name,
            format: FORMAT_NAME,
            recording,
            diagnostics,
            header: None,
            n_data_lines: self.n_data_lines,
            notes,
            // NMEA carries headings, never a magnetometer vector.
            mag_frame: None,
        })
    }

    fn note_counts(&self, notes: &mut Vec<String>) {
        let read: Vec<String> = KIND_NAMES
            .iter()
            .zip(self.n_read)
            .filter(|(_, count)| *count > 0)
            .map(|(name, count)| format!("{} {name}", thousands(count)))
            .collect();
        let mut summary = if read.is_empty() {
            "read no sentence of the types this tool reads".to_string()
        } else {
            format!("read {} sentences", read.join(", "))
        };
        if self.n_without_checksum > 0 {
            summary.push_str(&format!(
                "; {} lines without checksum (accepted unchecked)",
                thousands(self.n_without_checksum)
            ));
        }
        notes.push(summary);
        if self.n_unknown > 0 {
            let named: Vec<String> = self
                .unknown
                .iter()
                .map(|(address, count)| format!("{address} {}", thousands(*count)))
                .collect();
            notes.push(format!(
                "skipped {} sentences of types this tool does not read ({})",
                thousands(self.n_unknown),
                named.join(", ")
            ));
        }
        if self.n_rmc_invalid > 0 {
            notes.push(format!(
                "{} RMC sentences had status V (no valid fix): their time was kept, their \
                 position, speed and course were not used",
                thousands(self.n_rmc_invalid)
            ));
        }
        if self.n_gga_invalid > 0 {
            notes.push(format!(
                "{} GGA sentences had fix quality 0 (invalid): their time was kept, their \
                 position was not used",
                thousands(self.n_gga_invalid)
            ));
        }
        if self.n_vtg_empty > 0 {
            notes.push(format!(
                "{} VTG sentences had no valid true course or speed and were not used",
                thousands(self.n_vtg_empty)
            ));
        }
        if self.n_merged > 0 {
            notes.push(format!(
                "RMC and GGA sentences with the same time were merged into one fix ({} times)",
                thousands(self.n_merged)
            ));
        }
        if self.n_read[1] > 0 {
            notes.push(
                "GGA HDOP is a geometry factor, not an accuracy in metres, so no horizontal \
                 accuracy was set"
                    .to_string(),
            );
        }
        if let Some(variation_rad) = self.rmc_variation_rad {
            let variation_deg = variation_rad.to_degrees();
            let direction = if variation_deg < 0.0 { "W" } else { "E" };
            notes.push(format!(
                "the receiver reports a magnetic variation (declination) of {:.1}° \
                 {direction} (RMC)",
                variation_deg.abs()
            ));
        }
        if self.n_hdg_with_deviation > 0 {
            notes.push(format!(
                "HDG deviation was added to the sensor heading to give the magnetic heading \
                 ({} sentences); variation was not added",
                thousands(self.n_hdg_with_deviation)
            ));
        }
        if self.n_read[6] > 0 {
            let mut hpr_note = "PTNTHPR headings are taken as magnetic; pitch is taken as \
                                positive nose up and roll as positive right side down"
                .to_string();
            if self.hdg_reports_variation {
                hpr_note.push_str(
                    "; but this compass also reports a variation in HDG, and the HMR3000 \
                     adds a programmed variation to its PTNTHPR heading, which would make \
                     it true, not magnetic",
                );
            }
            notes.push(hpr_note);
        }
    }

    /// Decides how untimed samples get their times (returning the time per line for
    /// extrapolation), and says so in the notes.
    fn note_time(&self, notes: &mut Vec<String>) -> f64 {
        let (first, last) = (self.first_anchor, self.last_anchor);
        let s_per_line = match (first, last) {
            (Some(first), Some(last)) if last.line > first.line => {
                let s_per_line = (last.t_s - first.t_s) / (last.line - first.line) as f64;
                (s_per_line.is_finite() && s_per_line > 0.0).then_some(s_per_line)
            }
            _ => None,
        };
        let s_per_line_or_one = s_per_line.unwrap_or(1.0);

        if let Some(first) = first {
            let (hours, minutes, seconds) = hms(self.clock.first_time_of_day_s.unwrap_or(0.0));
            let mut time_note = format!(
                "t_s counts seconds from the first timed sentence (RMC or GGA, line {}) at \
                 {hours:02}:{minutes:02}:{seconds:05.2} UTC",
                first.line
            );
            if let Some((first_days, first_day)) = self.clock.first_date {
                let (year, month, day) = crate::civil::civil_from_days(first_days - first_day);
                time_note.push_str(&format!(" on {year:04}-{month:02}-{day:02}"));
            }
            notes.push(time_note);
        }
        if self.clock.n_midnights > 0 {
            let how = if self.clock.first_date.is_some() {
                "from the RMC date and the time of day"
            } else {
                "from the time of day wrapping round (no RMC date)"
            };
            notes.push(format!(
                "the log passes midnight UTC {} times; t_s keeps counting across it ({how})",
                self.clock.n_midnights
            ));
        }

        let untimed: Vec<&str> = KIND_NAMES
            .iter()
            .zip(self.untimed_kinds)
            .filter(|(_, untimed)| *untimed)
            .map(|(name, _)| *name)
            .collect();
        let n_untimed = self.n_untimed_sentences;
        if n_untimed == 0 {
            return s_per_line_or_one;
        }
        if first.is_none() {
            notes.push(format!(
                "no sentence carries a time (RMC or GGA with a time field), so the sample \
                 number stands in for time: t_s = 0, 1, 2, … over the {} {} samples",
                thousands(n_untimed),
                untimed.join(", ")
            ));
            return s_per_line_or_one;
        }
        // What is left unplaced lies outside the timed sentences. An HPR sentence has an
        // entry in two streams; its attitude entry is not counted.
        let n_outside = self
            .untimed
            .iter()
            .filter(|untimed| untimed.stream != StreamId::Attitude)
            .count();
        notes.push(format!(
            "{} sentences ({}) carry no time: each was placed evenly, by its line number, \
             between the timed sentences before and after it",
            thousands(n_untimed),
            untimed.join(", ")
        ));
        if n_outside > 0 {
            notes.push(match s_per_line {
                Some(s_per_line) => format!(
                    "{} of them lie before the first or after the last timed sentence; \
                     their times were extrapolated at the log's mean of {s_per_line:.4} s per line",
                    thousands(n_outside)
                ),
                None => format!(
                    "{} of them lie before the first or after the last timed sentence, and \
                     the log has a single timed epoch, so each line stands for one second there",
                    thousands(n_outside)
                ),
            });
        }
        s_per_line_or_one
    }
}

/// The time of a line between two timed sentences, evenly by line number.
fn interpolate(before: Anchor, after: Anchor, line: usize) -> f64 {
    if after.line > before.line {
        let fraction = line.saturating_sub(before.line) as f64 / (after.line - before.line) as f64;
        before.t_s + (after.t_s - before.t_s) * fraction
    } else {
        before.t_s
    }
}

/// Gives an untimed sample its time.
fn set_time(recording: &mut Recording, untimed: &Untimed, t_s: f64) {
    let slot = match untimed.stream {
        StreamId::Gnss => recording.gnss.t_s.get_mut(untimed.idx),
        StreamId::DeviceHeading => recording.device_heading.t_s.get_mut(untimed.idx),
        StreamId::Attitude => recording.attitude.t_s.get_mut(untimed.idx),
    };
    if let Some(slot) = slot {
        *slot = t_s;
    }
}

/// Hours, minutes and seconds of a time of day.
fn hms(time_of_day_s: f64) -> (u32, u32, f64) {
    let whole_minutes = (time_of_day_s / 60.0).floor();
    let seconds = time_of_day_s - whole_minutes * 60.0;
    let whole_minutes = whole_minutes as u32;
    (whole_minutes / 60, whole_minutes % 60, seconds)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::lines::LineDecoder;

    /// Appends the checksum a sentence body needs, `$` included.
    fn sentence(body: &str) -> String {
        let checksum = body.bytes().fold(0u8, |acc, byte| acc ^ byte);
        format!("${body}*{checksum:02X}")
    }

    fn read_text(text: &str) -> ImportReport {
        read("test.nmea", text.as_bytes()).expect("readable")
    }

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() < 1e-9
    }

    const GOLDEN_RMC: &str = "$GPRMC,123519,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W*6A";
    const GOLDEN_GGA: &str = "$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*47";

    #[test]
    fn golden_rmc() {
        let parsed = parse_sentence(GOLDEN_RMC).expect("valid");
        assert_eq!(parsed.talker, Some(*b"GP"));
        assert!(parsed.has_checksum);
        let SentenceData::Rmc(rmc) = parsed.data else {
            panic!("not RMC: {parsed:?}");
        };
        assert_eq!(rmc.time_of_day_s, Some(12.0 * 3600.0 + 35.0 * 60.0 + 19.0));
        assert!(rmc.is_valid());
        assert!(close(rmc.lat_deg.unwrap_or(f64::NAN), 48.0 + 7.038 / 60.0));
        assert!(close(rmc.lon_deg.unwrap_or(f64::NAN), 11.0 + 31.0 / 60.0));
        assert!(close(
            rmc.speed_mps.unwrap_or(f64::NAN),
            22.4 * 1852.0 / 3600.0
        ));
        assert!(close(
            rmc.course_rad.unwrap_or(f64::NAN),
            84.4f64.to_radians()
        ));
        assert_eq!(
            rmc.date,
            Some(NmeaDate {
                year: 1994,
                month: 3,
                day: 23
            })
        );
        assert!(close(
            rmc.magnetic_variation_rad.unwrap_or(f64::NAN),
            -3.1f64.to_radians()
        ));
        assert_eq!(rmc.mode, None);
    }

    #[test]
    fn a_dated_log_knows_when_it_started() {
        let text = format!("{GOLDEN_RMC}\r\n{GOLDEN_GGA}\r\n");
        let report = read("dated.nmea", text.as_bytes()).expect("readable");
        // 1994-03-23 12:35:19 UTC.
        assert_eq!(report.recording.start_unix_s, Some(764_426_119.0));
        let undated = read("undated.nmea", format!("{GOLDEN_GGA}\n").as_bytes()).expect("readable");
        assert_eq!(undated.recording.start_unix_s, None);
    }

    #[test]
    fn golden_gga() {
        let SentenceData::Gga(gga) = parse_sentence(GOLDEN_GGA).expect("valid").data else {
            panic!("not GGA");
        };
        assert_eq!(gga.quality, Some(1));
        assert_eq!(gga.n_satellites, Some(8));
        assert_eq!(gga.hdop, Some(0.9));
        assert_eq!(gga.alt_msl_m, Some(545.4));
        assert_eq!(gga.geoid_separation_m, Some(46.9));
        assert!(close(gga.lat_deg.unwrap_or(f64::NAN), 48.1173));
    }

    #[test]
    fn golden_hmr3000_sentences() {
        // The examples of the HMR3000 User's Guide, §3.12, with their checksums.
        let SentenceData::Hpr(normal) = parse_sentence("$PTNTHPR,59.6,N,-0.2,N,-3.0,N*0F")
            .expect("valid")
            .data
        else {
            panic!("not HPR");
        };
        assert!(close(
            normal.heading_rad.unwrap_or(f64::NAN),
            59.6f64.to_radians()
        ));
        assert!(close(
            normal.pitch_rad.unwrap_or(f64::NAN),
            -0.2f64.to_radians()
        ));
        assert!(close(
            normal.roll_rad.unwrap_or(f64::NAN),
            -3.0f64.to_radians()
        ));
        assert_eq!(normal.roll_status, HprStatus::Normal);
        let SentenceData::Hpr(warning) = parse_sentence("$PTNTHPR,72.9,N,-1.6,N,-29.6,O*33")
            .expect("valid")
            .data
        else {
            panic!("not HPR");
        };
        assert_eq!(warning.roll_status, HprStatus::HighWarning);
        let SentenceData::Hpr(alarm) = parse_sentence("$PTNTHPR,,N,-1.5,N,,P*03")
            .expect("valid")
            .data
        else {
            panic!("not HPR");
        };
        assert_eq!(
            (alarm.heading_rad, alarm.roll_rad, alarm.roll_status),
            (None, None, HprStatus::HighAlarm)
        );
        let SentenceData::Hpr(mag) = parse_sentence("$PTNTHPR,,P,0.3,N,0.1,N*06")
            .expect("valid")
            .data
        else {
            panic!("not HPR");
        };
        assert_eq!(mag.heading_status, HprStatus::HighAlarm);
    }

    #[test]
    fn every_sentence_type_and_any_talker() {
        let vtg = parse_sentence("$GPVTG,054.7,T,034.4,M,005.5,N,010.2,K*48").expect("valid");
        let SentenceData::Vtg(vtg) = vtg.data else {
            panic!("not VTG")
        };
        assert!(close(
            vtg.course_true_rad.unwrap_or(f64::NAN),
            54.7f64.to_radians()
        ));
        assert!(close(
            vtg.course_magnetic_rad.unwrap_or(f64::NAN),
            34.4f64.to_radians()
        ));
        assert!(close(vtg.speed_mps.unwrap_or(f64::NAN), 5.5 * MPS_PER_KNOT));
        // Speed from km/h where knots are null; NMEA 1.x form without unit letters.
        let SentenceData::Vtg(kmph) = parse_sentence(&sentence("GNVTG,10.0,T,,M,,N,36.0,K,A"))
            .expect("valid")
            .data
        else {
            panic!("not VTG")
        };
        assert!(close(kmph.speed_mps.unwrap_or(f64::NAN), 10.0));
        let SentenceData::Vtg(legacy) = parse_sentence(&sentence("GPVTG,054.7,034.4,005.5,010.2"))
            .expect("valid")
            .data
        else {
            panic!("not VTG")
        };
        assert!(close(
            legacy.course_magnetic_rad.unwrap_or(f64::NAN),
            34.4f64.to_radians()
        ));
        assert!(close(
            legacy.speed_mps.unwrap_or(f64::NAN),
            5.5 * MPS_PER_KNOT
        ));

        let hdg = parse_sentence("$HCHDG,101.1,,,7.1,W*3C").expect("valid");
        assert_eq!(hdg.talker, Some(*b"HC"));
        let SentenceData::Hdg(hdg) = hdg.data else {
            panic!("not HDG")
        };
        assert!(close(hdg.sensor_heading_rad, 101.1f64.to_radians()));
        assert_eq!(hdg.deviation_rad, None);
        assert!(close(
            hdg.variation_rad.unwrap_or(f64::NAN),
            -7.1f64.to_radians()
        ));
        let SentenceData::Hdg(deviated) = parse_sentence(&sentence("IIHDG,359.0,2.0,E,,"))
            .expect("valid")
            .data
        else {
            panic!("not HDG")
        };
        assert!(close(deviated.magnetic_heading_rad(), 1f64.to_radians()));

        let hdm = parse_sentence(&sentence("IIHDM,45.5,M")).expect("valid");
        assert_eq!(
            hdm.data,
            SentenceData::Hdm(HeadingOnly {
                heading_rad: 45.5f64.to_radians()
            })
        );
        let hdt = parse_sentence("$HCHDT,128.0,T*22").expect("valid");
        assert_eq!(hdt.data.type_name(), "HDT");
        for talker in ["GP", "GN", "GL", "GA", "BD", "HE", "II", "U1"] {
            let text = sentence(&format!("{talker}HDT,10.0,T"));
            let parsed = parse_sentence(&text).expect("any talker");
            assert_eq!(
                parsed.talker,
                Some([talker.as_bytes()[0], talker.as_bytes()[1]])
            );
        }
        // Southern and western hemispheres are negative.
        let SentenceData::Gga(south_west) = parse_sentence(&sentence(
            "GNGGA,000000.00,3351.000,S,15112.600,W,2,12,0.7,10.0,M,,M,,",
        ))
        .expect("valid")
        .data
        else {
            panic!("not GGA")
        };
        assert!(close(south_west.lat_deg.unwrap_or(f64::NAN), -33.85));
        assert!(close(south_west.lon_deg.unwrap_or(f64::NAN), -151.21));
    }

    #[test]
    fn checksums_are_verified_in_either_case_or_may_be_absent() {
        let lower = "$HCHDG,101.1,,,7.1,W*3c";
        assert!(parse_sentence(lower).expect("lowercase hex").has_checksum);
        let without = parse_sentence("$HCHDT,128.0,T").expect("no checksum");
        assert!(!without.has_checksum);
        assert_eq!(
            parse_sentence("$HCHDT,128.0,T*23"),
            Err(SentenceError::ChecksumMismatch {
                calculated: 0x22,
                found: 0x23
            })
        );
        let message = SentenceError::ChecksumMismatch {
            calculated: 0x4A,
            found: 0x4B,
        }
        .to_string();
        assert_eq!(
            message,
            "checksum mismatch: calculated 4A, found 4B; the line was corrupted in transit"
        );
        for bad in [
            "$HCHDT,128.0,T*2",
            "$HCHDT,128.0,T*2G",
            "$HCHDT,128.0,T*222",
            "$HCHDT,128.0,T*",
        ] {
            assert_eq!(
                parse_sentence(bad),
                Err(SentenceError::BadChecksumField),
                "{bad}"
            );
        }
    }

    #[test]
    fn structured_errors() {
        assert_eq!(parse_sentence("hello"), Err(SentenceError::NotASentence));
        assert_eq!(parse_sentence("$"), Err(SentenceError::NotASentence));
        assert_eq!(parse_sentence("$gprmc,1"), Err(SentenceError::NotASentence));
        assert_eq!(
            parse_sentence(&sentence("GPGSV,3,1,11")),
            Err(SentenceError::UnknownSentence {
                address: "GPGSV".to_string()
            })
        );
        assert_eq!(
            parse_sentence(&sentence("HCHDT,,T")),
            Err(SentenceError::MissingField {
                sentence: "HDT",
                field: "heading"
            })
        );
        assert_eq!(
            parse_sentence(&sentence("HCHDT,12x,T")),
            Err(SentenceError::BadNumber {
                sentence: "HDT",
                field: "heading",
                text: "12x".to_string()
            })
        );
        assert!(matches!(
            parse_sentence(&sentence("GPRMC,123519,A,4807.038,X,01131.000,E,,,,,")),
            Err(SentenceError::BadValue {
                field: "latitude hemisphere",
                ..
            })
        ));
        assert!(matches!(
            parse_sentence(&sentence("GPRMC,126519,A,,,,,,,,,")),
            Err(SentenceError::BadValue { field: "time", .. })
        ));
        assert!(matches!(
            parse_sentence(&sentence("GPRMC,123519,A,4867.000,N,,,,,,,")),
            Err(SentenceError::BadValue {
                field: "latitude",
                ..
            })
        ));
        assert!(matches!(
            parse_sentence(&sentence("GPRMC,123519,A,4807.000,N,,E,,,,,")),
            Err(SentenceError::MissingField {
                field: "longitude",
                ..
            })
        ));
        assert!(matches!(
            parse_sentence(&sentence("PTNTHPR,4000,N,0,N,0,N")),
            Err(SentenceError::BadValue {
                field: "heading",
                ..
            })
        ));
        assert!(matches!(
            parse_sentence(&sentence("HCHDT,NaN,T")),
            Err(SentenceError::BadNumber { .. })
        ));
        let message = parse_sentence(&sentence("GPGSV,1"))
            .map(|_| ())
            .unwrap_err()
            .to_string();
        assert!(
            message.starts_with("GPGSV sentences are not read"),
            "{message}"
        );
    }

    #[test]
    fn numbers_from_bytes_read_as_from_text() {
        let mut texts: Vec<String> = [
            "12345678901234567890123",
            "0",
            "-0",
            "5",
            "5.",
            ".5",
            "-.5",
            ".",
            "-",
            "",
            "1.2.3",
            "12a",
            "+5",
            "1e3",
            "4808.22924",
            "01134.56746",
            "00.00",
            "99999999",
            "123456789",
            "1234567890123456",
            "12345678901234567",
            "1234567890123456789",
            "12345678901234567890",
            "9007199254740993",
            "9007199254740992",
            "0.1234567890123456",
            "-84.00",
            "0.00000000000000001",
            "1 2",
            " 1",
            "1 ",
        ]
        .iter()
        .map(|text| text.to_string())
        .collect();
        let mut state = 11u64;
        for _ in 0..20_000 {
            state = lcg(state);
            let n_integer = (state >> 33) as usize % 12;
            state = lcg(state);
            let n_fraction = (state >> 33) as usize % 12;
            let mut text = String::new();
            if state.is_multiple_of(3) {
                text.push('-');
            }
            for _ in 0..n_integer {
                state = lcg(state);
                text.push(char::from(b'0' + (state >> 40) as u8 % 10));
            }
            if n_fraction > 0 || state.is_multiple_of(5) {
                text.push('.');
            }
            for _ in 0..n_fraction {
                state = lcg(state);
                text.push(char::from(b'0' + (state >> 40) as u8 % 10));
            }
            texts.push(text);
        }
        for text in &texts {
            let general = crate::io::number::parse_f64(text).map(f64::to_bits);
            assert_eq!(
                parse_f64_bytes(text.as_bytes()).map(f64::to_bits),
                general,
                "{text:?}"
            );
        }
    }

    #[test]
    fn fractional_seconds_and_dates() {
        assert_eq!(time_of_day_s("T", b"000000"), Ok(Some(0.0)));
        assert_eq!(time_of_day_s("T", b"235959.75"), Ok(Some(86_399.75)));
        assert_eq!(time_of_day_s("T", b"120000."), Ok(Some(43_200.0)));
        assert!(time_of_day_s("T", b"1200").is_err());
        assert!(time_of_day_s("T", b"240000").is_err());
        assert!(time_of_day_s("T", b"12000a").is_err());
        assert_eq!(
            NmeaDate {
                year: 1970,
                month: 1,
                day: 1
            }
            .days_since_1970(),
            0
        );
        assert_eq!(
            NmeaDate {
                year: 2000,
                month: 3,
                day: 1
            }
            .days_since_1970(),
            11_017
        );
        assert_eq!(crate::civil::civil_from_days(11_017), (2000, 3, 1));
        assert_eq!(
            parse_date("T", b"010180"),
            Ok(Some(NmeaDate {
                year: 1980,
                month: 1,
                day: 1
            }))
        );
        assert_eq!(
            parse_date("T", b"311279"),
            Ok(Some(NmeaDate {
                year: 2079,
                month: 12,
                day: 31
            }))
        );
        assert!(parse_date("T", b"320194").is_err());
        assert!(parse_date("T", b"0101944").is_err());
        assert_eq!(thousands(24_000), "24,000");
        assert_eq!(thousands(1_204), "1,204");
        assert_eq!(thousands(999), "999");
    }

    #[test]
    fn a_log_becomes_fixes_headings_and_attitude() {
        let text = [
            GOLDEN_RMC.to_string(),
            GOLDEN_GGA.to_string(),
            sentence("GPVTG,084.4,T,087.5,M,022.4,N,041.5,K,A"),
            sentence("HCHDG,90.0,1.0,E,3.1,W"),
            sentence("HCHDM,91.0,M"),
            sentence("HEHDT,88.0,T"),
            "$PTNTHPR,85.9,N,-0.9,N,0.8,N*2C".to_string(),
            sentence("GPGSV,3,1,11,03,03,111,00"),
            sentence("GPRMC,123520,A,4807.040,N,01131.002,E,022.0,084.0,230394,003.1,W"),
        ]
        .join("\r\n");
        let report = read_text(&text);
        assert!(report.diagnostics.is_empty(), "{:?}", report.diagnostics);
        assert_eq!(report.format, FORMAT_NAME);
        assert_eq!(report.header, None);
        assert_eq!(report.n_data_lines, 9);
        let recording = &report.recording;
        // One merged RMC+GGA fix, one VTG fix, one more RMC fix.
        assert_eq!(recording.gnss.len(), 3, "{:?}", recording.gnss);
        let merged = recording.gnss.values[0];
        assert_eq!(recording.gnss.t_s[0], 0.0);
        assert_eq!(merged.alt_m, Some(545.4));
        assert!(merged.speed_mps.is_some() && merged.course_rad.is_some());
        assert_eq!(merged.hacc_m, None);
        assert_eq!(recording.gnss.t_s[2], 1.0);
        let norths: Vec<North> = recording
            .device_heading
            .values
            .iter()
            .map(|h| h.north)
            .collect();
        assert_eq!(
            norths,
            vec![
                North::Magnetic,
                North::Magnetic,
                North::True,
                North::Magnetic
            ]
        );
        assert!(close(
            recording.device_heading.values[0].heading_rad,
            91f64.to_radians()
        ));
        assert_eq!(recording.attitude.len(), 1);
        let attitude = recording.attitude.values[0];
        assert!(close(attitude.pitch_rad, -0.9f64.to_radians()));
        assert!(close(attitude.roll_rad, 0.8f64.to_radians()));
        assert!(close(
            attitude.yaw_rad.unwrap_or(f64::NAN),
            85.9f64.to_radians()
        ));
        let notes = report.notes.join("\n");
        assert!(
            notes.contains("read 2 RMC, 1 GGA, 1 VTG, 1 HDG, 1 HDM, 1 HDT, 1 PTNTHPR sentences"),
            "{notes}"
        );
        assert!(notes.contains("GPGSV 1"), "{notes}");
        assert!(notes.contains("merged into one fix (1 times)"), "{notes}");
        assert!(notes.contains("3.1° W"), "{notes}");
        assert!(notes.contains("12:35:19.00 UTC on 1994-03-23"), "{notes}");
    }

    #[test]
    fn untimed_sentences_are_interpolated_between_timed_ones() {
        let mut lines = vec![sentence(
            "GPGGA,120000.00,4807.038,N,01131.000,E,1,08,0.9,545.4,M,,M,,",
        )];
        for heading in 0..4 {
            lines.push(sentence(&format!("HEHDT,{heading}.0,T")));
        }
        lines.push(sentence("PTNTHPR,10.0,N,1.0,N,2.0,N"));
        lines.push(sentence(
            "GPGGA,120001.00,4807.038,N,01131.000,E,1,08,0.9,545.4,M,,M,,",
        ));
        let report = read_text(&lines.join("\n"));
        let headings = &report.recording.device_heading;
        let expected: Vec<f64> = (1..=5).map(|k| f64::from(k) / 6.0).collect();
        assert_eq!(headings.len(), 5);
        for (got, want) in headings.t_s.iter().zip(&expected) {
            assert!(close(*got, *want), "{:?} vs {expected:?}", headings.t_s);
        }
        assert!(close(report.recording.attitude.t_s[0], 5.0 / 6.0));
        let notes = report.notes.join("\n");
        assert!(
            notes.contains("5 sentences (HDT, PTNTHPR) carry no time"),
            "{notes}"
        );
    }

    #[test]
    fn untimed_sentences_outside_the_timed_ones_are_extrapolated() {
        let lines = [
            sentence("HEHDT,1.0,T"),
            sentence("GPGGA,120000.00,4807.038,N,01131.000,E,1,08,0.9,,,,,,"),
            sentence("HEHDT,2.0,T"),
            sentence("GPGGA,120001.00,4807.038,N,01131.000,E,1,08,0.9,,,,,,"),
            sentence("HEHDT,3.0,T"),
            sentence("HEHDT,4.0,T"),
        ];
        let report = read_text(&lines.join("\n"));
        // Two lines per second between the timed sentences: 0.5 s per line.
        assert_eq!(
            report.recording.device_heading.t_s,
            vec![-0.5, 0.5, 1.5, 2.0]
        );
        assert!(
            report.notes.join("\n").contains("0.5000 s per line"),
            "{:?}",
            report.notes
        );

        // A single timed epoch: a line stands for a second.
        let single = [
            sentence("HEHDT,1.0,T"),
            sentence("GPGGA,120000.00,,,,,1,,,,,,,,"),
            sentence("HEHDT,2.0,T"),
        ];
        let report = read_text(&single.join("\n"));
        assert_eq!(report.recording.device_heading.t_s, vec![-1.0, 1.0]);
        assert!(
            report.notes.join("\n").contains("single timed epoch"),
            "{:?}",
            report.notes
        );
    }

    #[test]
    fn without_any_time_the_sample_number_stands_in() {
        let lines = [
            sentence("HEHDT,1.0,T"),
            sentence("PTNTHPR,10.0,N,1.0,N,2.0,N"),
            sentence("HEHDT,3.0,T"),
        ];
        let report = read_text(&lines.join("\n"));
        assert_eq!(report.recording.device_heading.t_s, vec![0.0, 1.0, 2.0]);
        assert_eq!(report.recording.attitude.t_s, vec![1.0]);
        assert!(
            report
                .notes
                .join("\n")
                .contains("sample number stands in for time"),
            "{:?}",
            report.notes
        );
    }

    #[test]
    fn midnight_rollover_counts_on() {
        // Without a date: the time of day wraps.
        let lines = [
            sentence("GPGGA,235959.00,4807.038,N,01131.000,E,1,08,0.9,1.0,M,,M,,"),
            sentence("HEHDT,5.0,T"),
            sentence("GPGGA,000001.00,4807.038,N,01131.000,E,1,08,0.9,1.0,M,,M,,"),
        ];
        let report = read_text(&lines.join("\n"));
        assert_eq!(report.recording.gnss.t_s, vec![0.0, 2.0]);
        assert_eq!(report.recording.device_heading.t_s, vec![1.0]);
        assert!(
            report
                .notes
                .join("\n")
                .contains("passes midnight UTC 1 times"),
            "{:?}",
            report.notes
        );

        // With RMC dates, including a gap of more than a day that the time of day alone
        // could not show.
        let lines = [
            sentence("GPRMC,235959.00,A,4807.038,N,01131.000,E,0.0,0.0,311299,,"),
            sentence("GPRMC,000000.00,A,4807.038,N,01131.000,E,0.0,0.0,010100,,"),
            sentence("GPRMC,000000.00,A,4807.038,N,01131.000,E,0.0,0.0,030100,,"),
        ];
        let report = read_text(&lines.join("\n"));
        assert_eq!(
            report.recording.gnss.t_s,
            vec![0.0, 1.0, 1.0 + 2.0 * 86_400.0]
        );
        assert!(
            report.notes.join("\n").contains("1999-12-31"),
            "{:?}",
            report.notes
        );
    }

    #[test]
    fn invalid_fixes_keep_their_time_but_not_their_position() {
        let lines = [
            sentence("GPRMC,120000,A,4807.038,N,01131.000,E,0.0,0.0,230394,,"),
            sentence("GPRMC,120001,V,4807.038,N,01131.000,E,0.0,0.0,230394,,"),
            sentence("HEHDT,5.0,T"),
            sentence("GPGGA,120002,4807.038,N,01131.000,E,0,08,0.9,1.0,M,,M,,"),
            sentence("GPRMC,,V,,,,,,,,,,N"),
        ];
        let report = read_text(&lines.join("\n"));
        assert_eq!(report.recording.gnss.t_s, vec![0.0]);
        // The HDT lies between the invalid RMC and GGA, whose times were kept.
        assert_eq!(report.recording.device_heading.t_s, vec![1.5]);
        let notes = report.notes.join("\n");
        assert!(notes.contains("2 RMC sentences had status V"), "{notes}");
        assert!(
            notes.contains("1 GGA sentences had fix quality 0"),
            "{notes}"
        );
        assert!(report.diagnostics.is_empty());
    }

    #[test]
    fn bad_lines_become_diagnostics_and_the_rest_is_read() {
        let text = [
            GOLDEN_RMC.to_string(),
            "$GPRMC,123519,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W*6B".to_string(),
            "$HCHDT,128.0,T".to_string(),
            "$hchdt,128.0,t*22".to_string(),
            "# a comment from the logger".to_string(),
            String::new(),
            "$PTNTHPR,72.9,N,-1.6,N,-29.6,O*33".to_string(),
            "$PTNTHPR,,P,0.3,N,0.1,N*06".to_string(),
            "$PTNTHPR,85.9,N,-0.9,N,0.8,N*2c".to_string(),
        ]
        .join("\n");
        let report = read_text(&text);
        let lines: Vec<Option<usize>> = report.diagnostics.kept.iter().map(|d| d.line).collect();
        assert_eq!(lines, vec![Some(2), Some(4), Some(5), Some(7), Some(8)]);
        assert!(report.diagnostics.kept[0]
            .message
            .contains("calculated 6A, found 6B"));
        assert!(report.diagnostics.kept[3]
            .message
            .contains("roll high warning (O)"));
        assert!(report.diagnostics.kept[4]
            .message
            .contains("magnetic field high alarm (P)"));
        assert_eq!(report.n_data_lines, 8);
        assert_eq!(report.recording.gnss.len(), 1);
        assert_eq!(
            report.recording.device_heading.len(),
            2,
            "HDT without checksum and the normal HPR"
        );
        assert_eq!(report.recording.attitude.len(), 1);
        assert!(
            report.notes[0].ends_with("; 1 lines without checksum (accepted unchecked)"),
            "{:?}",
            report.notes
        );
    }

    #[test]
    fn files_with_nothing_readable_are_errors() {
        assert!(matches!(
            read("x.nmea", b""),
            Err(ImportError::Empty { .. })
        ));
        assert!(matches!(
            read("x.nmea", b" \r\n\n"),
            Err(ImportError::Empty { .. })
        ));
        assert!(matches!(
            read("x.nmea", b"\x00\x01\x02$GPRMC"),
            Err(ImportError::NotText { .. })
        ));
        let garbage = read("x.nmea", b"hello world\nthis is, not NMEA\n");
        let Err(ImportError::NothingRecognised {
            n_lines,
            first_problem,
            format,
            ..
        }) = garbage
        else {
            panic!("{garbage:?}");
        };
        assert_eq!((n_lines, format), (2, FORMAT_NAME));
        assert!(
            first_problem.starts_with(" (line 1: not an NMEA sentence"),
            "{first_problem}"
        );
        let only_gsv = read("x.nmea", sentence("GPGSV,3,1,11").as_bytes());
        let Err(ImportError::NothingRecognised { first_problem, .. }) = only_gsv else {
            panic!("{only_gsv:?}");
        };
        assert!(
            first_problem.contains("GPGSV sentences are not read"),
            "{first_problem}"
        );
        let no_fix = read(
            "x.nmea",
            b"$GPRMC,,V,,,,,,,,,,N*53\n$GPGGA,,,,,,0,,,,,,,,*66\n",
        );
        let Err(ImportError::NothingRecognised { first_problem, .. }) = no_fix else {
            panic!("{no_fix:?}");
        };
        assert!(
            first_problem.contains("line 1: RMC status V"),
            "{first_problem}"
        );
        let message = read("walk.nmea", b"nonsense\n")
            .map(|_| ())
            .unwrap_err()
            .to_string();
        assert!(
            message.starts_with("walk.nmea: none of its 1 lines could be read as NMEA 0183"),
            "{message}"
        );
    }

    #[test]
    fn overlong_lines_are_skipped_with_a_diagnostic() {
        let long = format!("$GPRMC,{}", "1".repeat(MAX_LINE_BYTES + 10));
        let text = format!("{long}\n$HCHDT,128.0,T*22\n");
        let report = read_text(&text);
        assert_eq!(report.n_data_lines, 2);
        assert_eq!(report.diagnostics.kept.len(), 1);
        assert_eq!(report.diagnostics.kept[0].line, Some(1));
        assert!(report.diagnostics.kept[0]
            .message
            .contains("longer than 4096 bytes"));
        assert_eq!(report.recording.device_heading.len(), 1);
    }

    #[test]
    fn out_of_order_times_are_sorted_and_reported() {
        let lines = [
            sentence("GPGGA,120005,4807.038,N,01131.000,E,1,08,0.9,,,,,,"),
            sentence("GPGGA,120001,4807.038,N,01131.000,E,1,08,0.9,,,,,,"),
        ];
        let report = read_text(&lines.join("\n"));
        assert_eq!(report.recording.gnss.t_s, vec![-4.0, 0.0]);
        assert!(report.diagnostics.kept[0]
            .message
            .contains("time goes backwards 1 times"));
    }

    #[test]
    fn looks_like_nmea_and_not_like_csv() {
        assert!(looks_like(&[
            GOLDEN_RMC,
            GOLDEN_GGA,
            "",
            "$HCHDT,128.0,T",
            "!AIVDM,1,1,,A,13aG?P0P00PD;88MD5MTDww@2D7k,0*46"
        ]));
        assert!(looks_like(&[
            "\u{feff}$PTNTHPR,85.9,N,-0.9,N,0.8,N*2C",
            "garbled line",
            "$PTNTHPR,,P,0.3,N,0.1,N*06"
        ]));
        assert!(!looks_like(&["t_s,mag_x_ut,mag_y_ut,mag_z_ut", "0,1,2,3"]));
        assert!(!looks_like(&["$GPRMC,1*6A", "x", "y"]));
        assert!(!looks_like(&["$gprmc,1", "$GPRMC,1*6", "$TOOLONG,1"]));
        assert!(!looks_like(&[]));
        assert!(!looks_like(&["", "  "]));
    }

    fn recording_through_chunks(
        bytes: &[u8],
        splits: &[usize],
    ) -> (Recording, Diagnostics, Vec<String>) {
        let mut reader = NmeaReader::new();
        let mut decoder = LineDecoder::new(MAX_LINE_BYTES);
        let mut start = 0;
        for &split in splits.iter().chain([bytes.len()].iter()) {
            let end = split.clamp(start, bytes.len());
            decoder.feed(&bytes[start..end], |line| reader.read_decoded(&line));
            start = end;
        }
        decoder.finish(|line| reader.read_decoded(&line));
        let report = reader.finish("chunks.nmea").expect("readable");
        (report.recording, report.diagnostics, report.notes)
    }

    #[test]
    fn every_chunking_gives_the_same_recording() {
        let text = [
            sentence("HEHDT,1.0,T"),
            GOLDEN_RMC.to_string(),
            GOLDEN_GGA.to_string(),
            sentence("HCHDG,90.0,1.0,E,3.1,W"),
            "$GPRMC,bad*00".to_string(),
            sentence("PTNTHPR,85.9,N,-0.9,N,0.8,N"),
            sentence("GPRMC,123520,A,4807.040,N,01131.002,E,022.0,084.0,230394,003.1,W"),
            sentence("HEHDT,2.0,T"),
        ];
        let mut bytes = Vec::new();
        for (idx, line) in text.iter().enumerate() {
            bytes.extend_from_slice(line.as_bytes());
            bytes.extend_from_slice([&b"\r\n"[..], b"\n", b"\r"][idx % 3]);
        }
        let whole = recording_through_chunks(&bytes, &[]);
        assert_eq!(whole, {
            let report = read("chunks.nmea", &bytes).expect("readable");
            (report.recording, report.diagnostics, report.notes)
        });
        for split in 0..=bytes.len() {
            assert_eq!(
                recording_through_chunks(&bytes, &[split]),
                whole,
                "split at {split}"
            );
        }
        let mut state = 7u64;
        for _ in 0..200 {
            let mut splits: Vec<usize> = (0..6)
                .map(|_| {
                    state = lcg(state);
                    (state >> 33) as usize % (bytes.len() + 1)
                })
                .collect();
            splits.sort_unstable();
            assert_eq!(
                recording_through_chunks(&bytes, &splits),
                whole,
                "splits {splits:?}"
            );
        }
    }

    fn lcg(state: u64) -> u64 {
        state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407)
    }

    #[test]
    fn arbitrary_bytes_never_panic() {
        const ALPHABET: &[u8] = b"$!*,.-0123456789ABCDEFGHMNOPRSTVWEgn \r\n";
        let mut state = 1u64;
        for round in 0..3000 {
            state = lcg(state);
            let len = (state >> 40) as usize % 160;
            let bytes: Vec<u8> = (0..len)
                .map(|_| {
                    state = lcg(state);
                    let byte = (state >> 33) as u8;
                    if round % 2 == 0 {
                        ALPHABET[usize::from(byte) % ALPHABET.len()]
                    } else {
                        byte
                    }
                })
                .collect();
            let _ = read("fuzz.nmea", &bytes);
            let text = String::from_utf8_lossy(&bytes);
            let _ = parse_sentence(&text);
            let _ = looks_like(&[&text]);
        }
    }

    #[test]
    fn mutated_sentences_with_valid_checksums_never_panic() {
        // Recomputing the checksum lets mutations reach the field parsers.
        let bodies = [
            "GPRMC,123519.00,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W,A",
            "GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,",
            "GPVTG,054.7,T,034.4,M,005.5,N,010.2,K,A",
            "HCHDG,101.1,1.0,E,7.1,W",
            "HCHDM,45.5,M",
            "HEHDT,128.0,T",
            "PTNTHPR,85.9,N,-0.9,N,0.8,N",
        ];
        const REPLACEMENTS: &[u8] = b",.-+*$0123456789NSEWAVTMPeE \xff";
        let mut state = 3u64;
        for round in 0..20_000 {
            let body = bodies[round % bodies.len()];
            let mut bytes = body.as_bytes().to_vec();
            for _ in 0..3 {
                state = lcg(state);
                let at = (state >> 33) as usize % bytes.len();
                state = lcg(state);
                let replacement = REPLACEMENTS[(state >> 33) as usize % REPLACEMENTS.len()];
                match (state >> 20) % 3 {
                    0 => bytes[at] = replacement,
                    1 => bytes.insert(at, replacement),
                    _ => {
                        bytes.remove(at);
                    }
                }
                if bytes.is_empty() {
                    bytes.push(b'G');
                }
            }
            let text = sentence(&String::from_utf8_lossy(&bytes));
            let _ = parse_sentence(&text);
            let mut reader = NmeaReader::new();
            reader.read_line(1, &text);
            reader.read_line(2, GOLDEN_RMC);
            let _ = reader.finish("mutated.nmea");
        }
    }
}
