//! Time in NMEA sentences ([`super`]): the `hhmmss.ss` UTC time of day of RMC and GGA,
//! RMC's `ddmmyy` date, and the [`Clock`] that turns times of day into seconds since the
//! first timed sentence, counting days across midnight (from the dates where there are
//! any). Days since 1970 follow Howard Hinnant's `days_from_civil` ([`crate::base::calendar`]).
//!
//! Source: Eric S. Raymond, "NMEA Revealed" (gpsd project,
//! <https://gpsd.gitlab.io/gpsd/NMEA.html>), for the time and date fields.

use super::values::parse_f64_bytes;
use super::SentenceError;

pub(super) const SECONDS_PER_DAY: f64 = 86_400.0;

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
        crate::base::calendar::days_from_civil(
            i64::from(self.year),
            u32::from(self.month),
            u32::from(self.day),
        )
    }
}

/// Two ASCII digits at `at`, as a number.
#[cfg_attr(not(target_arch = "wasm32"), inline(always))]
fn two_digits(bytes: &[u8], at: usize) -> Option<u8> {
    match bytes.get(at..at + 2)? {
        [tens @ b'0'..=b'9', ones @ b'0'..=b'9'] => Some((tens - b'0') * 10 + (ones - b'0')),
        _ => None,
    }
}

/// `hhmmss` with optional decimals, as seconds since midnight.
#[cfg_attr(not(target_arch = "wasm32"), inline(always))]
pub(super) fn time_of_day_s(
    sentence: &'static str,
    text: &[u8],
) -> Result<Option<f64>, SentenceError> {
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
#[cfg_attr(not(target_arch = "wasm32"), inline(always))]
pub(super) fn parse_date(
    sentence: &'static str,
    text: &[u8],
) -> Result<Option<NmeaDate>, SentenceError> {
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

/// Turns times of day into seconds since the first timed sentence, counting days.
#[derive(Debug, Clone, Default)]
pub(super) struct Clock {
    pub(super) first_time_of_day_s: Option<f64>,
    /// Day of the last timed sentence, counted from the first one's (day 0).
    day: i64,
    last_time_of_day_s: f64,
    /// The first date seen (days since 1970) and the day count it fell on, which lets
    /// later dates set the day count directly.
    pub(super) first_date: Option<(i64, i64)>,
    pub(super) n_midnights: usize,
}

impl Clock {
    pub(super) fn t_s(&mut self, time_of_day_s: f64, date: Option<NmeaDate>) -> f64 {
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

/// Hours, minutes and seconds of a time of day.
pub(super) fn hms(time_of_day_s: f64) -> (u32, u32, f64) {
    let whole_minutes = (time_of_day_s / 60.0).floor();
    let seconds = time_of_day_s - whole_minutes * 60.0;
    let whole_minutes = whole_minutes as u32;
    (whole_minutes / 60, whole_minutes % 60, seconds)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::thousands;

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
        assert_eq!(crate::base::calendar::civil_from_days(11_017), (2000, 3, 1));
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
}
