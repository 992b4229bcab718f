//! PTNTHPR, the Honeywell HMR3000's proprietary heading, pitch and roll ([`super`]),
//! each with the status letter of the magnetic field, the pitch or the roll.
//!
//! ```text
//! $PTNTHPR,x.x,a,x.x,a,x.x,a*hh     (Honeywell HMR3000 heading, pitch and roll)
//!          1   2 3   4 5   6
//!  1 heading, degrees   3 pitch, degrees   5 roll, degrees
//!  2, 4, 6 status of the magnetic field, pitch and roll: N normal, M low warning,
//!    L low alarm, O high warning, P high alarm, C tuning the analogue circuit
//! ```
//!
//! Source: Honeywell, "HMR3000 Digital Compass Module User's Guide" (900240 Rev. B),
//! §3.10 and §3.12, for the sentence, its status letters and its example sentences (the
//! golden tests below). On an alarm the HMR3000 leaves the heading and the alarmed value
//! null.

use super::values::{heading_0_360_rad, number};
use super::SentenceError;

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

pub(super) fn parse_hpr(fields: [&[u8]; 6]) -> Result<Hpr, SentenceError> {
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

#[cfg(test)]
mod tests {
    use super::super::tests::close;
    use super::super::{parse_sentence, SentenceData};
    use super::*;

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
}
