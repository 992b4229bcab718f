//! From bytes to sentences ([`super`]): lines cut at CR, LF or CRLF, the `$` or `!`, the
//! address (a talker and a type, or a proprietary `P…`), the `*hh` checksum (the XOR of
//! every byte between the `$` and the `*`) and the comma-separated fields, found in one
//! pass; the address then picks the sentence's parser. A line is parsed without state
//! into a [`LineEvent`], to be applied in order by the reader.
//!
//! Source: Eric S. Raymond, "NMEA Revealed" (gpsd project,
//! <https://gpsd.gitlab.io/gpsd/NMEA.html>), for the framing and the checksum.

use std::borrow::Cow;

use super::gga::parse_gga;
use super::heading::{parse_hdg, parse_heading_only};
use super::hpr::parse_hpr;
use super::rmc::parse_rmc;
use super::vtg::parse_vtg;
use super::{Sentence, SentenceData, SentenceError, MAX_LINE_BYTES};
use crate::io::shorten;

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
pub(super) fn field_text(field: &[u8]) -> Cow<'_, str> {
    String::from_utf8_lossy(field)
}

/// Parses the bytes of one line, which must be UTF-8 (text, or ASCII bytes): bytes
/// rather than `str` so that an ASCII line needs no UTF-8 validation.
// Always inlined natively (the import benchmark's speed); in wasm the compiler decides,
// which keeps the page's module within its size budget (docs/development.md).
#[cfg_attr(not(target_arch = "wasm32"), inline(always))]
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

#[cfg_attr(not(target_arch = "wasm32"), inline(always))]
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
    #[cfg_attr(not(target_arch = "wasm32"), inline(always))]
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
    #[cfg_attr(not(target_arch = "wasm32"), inline(always))]
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
    #[cfg_attr(not(target_arch = "wasm32"), inline(always))]
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
    #[cfg_attr(not(target_arch = "wasm32"), inline(always))]
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
#[cfg_attr(not(target_arch = "wasm32"), inline(always))]
fn trim_field(field: &[u8]) -> &[u8] {
    match (field.first(), field.last()) {
        (Some(first), Some(last)) if first.is_ascii_whitespace() || last.is_ascii_whitespace() => {
            field.trim_ascii()
        }
        _ => field,
    }
}

/// Whether a line has the shape of a sentence: `$` or `!`, an address of a talker and
/// a type (5 characters) or a proprietary `P…` address, then fields, then optionally
/// `*hh`. The checksum's value is not checked: a corrupted sentence still shows the
/// format.
pub(super) fn is_sentence_shaped(line: &str) -> bool {
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
pub(super) fn is_blank(line: &str) -> bool {
    // Most lines start with `$`; they need no Unicode-aware trimming.
    match line.as_bytes().first() {
        Some(b'$' | b'!') => false,
        _ => line.trim_start_matches('\u{feff}').trim().is_empty(),
    }
}

/// Calls `on_line` with the 1-based number and the content (without its terminator) of
/// every line of a whole buffer: the lines [`decode_all`](crate::io::lines::decode_all)
/// gives (CR, LF and CRLF end a line; a last line without an ending counts), but as
/// bytes borrowed from the buffer. Returns the number of lines.
pub(super) fn for_each_line<'a>(
    bytes: &'a [u8],
    mut on_line: impl FnMut(usize, &'a [u8]),
) -> usize {
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
pub(super) enum LineEvent<'a> {
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
    pub(super) fn of(content: &'a [u8]) -> LineEvent<'a> {
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

    pub(super) fn parse(text: &'a str) -> LineEvent<'a> {
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

#[cfg(test)]
mod tests {
    use super::super::tests::{close, sentence};
    use super::super::{HeadingOnly, MPS_PER_KNOT};
    use super::*;

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
}
