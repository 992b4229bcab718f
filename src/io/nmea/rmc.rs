//! RMC, recommended minimum data ([`super`]): the time, the receiver's status, position,
//! speed and course over ground, the date, the magnetic variation and the mode.
//!
//! ```text
//! $--RMC,hhmmss.ss,A,llll.ll,a,yyyyy.yy,a,x.x,x.x,ddmmyy,x.x,a,m*hh
//!        1         2 3       4 5        6 7   8   9      10  11 12
//!  1 UTC time of day          2 status: A valid, V invalid (navigation receiver warning)
//!  3-4 latitude ddmm.mmmm, N/S   5-6 longitude dddmm.mmmm, E/W
//!  7 speed over ground, knots    8 course over ground, degrees true
//!  9 date day-month-year        10-11 magnetic variation, degrees, E/W
//! 12 mode (NMEA 2.3): A autonomous, D differential, E estimated, N not valid, …
//! ```
//!
//! Sources: Eric S. Raymond, "NMEA Revealed" (gpsd project,
//! <https://gpsd.gitlab.io/gpsd/NMEA.html>); Garmin, "GPS 19x HVS Technical
//! Specifications", §4.2.

use super::clock::{parse_date, time_of_day_s};
use super::values::{coordinate, east_positive_rad, first_char, heading_rad, number, Axis};
use super::{NmeaDate, SentenceError, MPS_PER_KNOT};

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

#[cfg_attr(not(target_arch = "wasm32"), inline(always))]
pub(super) fn parse_rmc(fields: [&[u8]; 12]) -> Result<Rmc, SentenceError> {
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

#[cfg(test)]
mod tests {
    use super::super::tests::{close, GOLDEN_RMC};
    use super::super::{parse_sentence, SentenceData};
    use super::*;

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
}
