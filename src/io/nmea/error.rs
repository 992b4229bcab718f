//! Why a line is not a usable sentence ([`super`]): [`SentenceError`], structured (a
//! checksum mismatch carries the calculated and the found checksum) and worded for the
//! user, who sees it as the line's diagnostic.

use std::fmt;

use super::framing::field_text;
use super::READ_SENTENCES;
use crate::io::shorten;

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
    pub(super) fn bad_number(
        sentence: &'static str,
        field: &'static str,
        text: &[u8],
    ) -> SentenceError {
        SentenceError::BadNumber {
            sentence,
            field,
            text: shorten(&field_text(text)),
        }
    }

    #[cold]
    pub(super) fn bad_value(
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

#[cfg(test)]
mod tests {
    use super::super::parse_sentence;
    use super::super::tests::sentence;
    use super::*;

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
}
