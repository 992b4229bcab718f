//! Calendar dates as day counts: the one place the proleptic Gregorian calendar is
//! computed (NMEA dates, ISO date-times, the magnetic model's dates, the benchmark's
//! generated logs).
//!
//! Howard Hinnant, "chrono-Compatible Low-Level Date Algorithms" (2013): days are
//! counted from 1970-01-01. Shifting the year to start on 1 March puts the leap day
//! last, so the day of the year is `(153·m + 2)/5 + d − 1` with m = 0 for March; an era
//! is the 400-year cycle of 146 097 days.

/// Days from 1970-01-01 to a date (month 1-12, day 1-31; not checked: callers validate).
/// Total: computed in `i128`, so that a corrupt year from a log (the fuzzers found
/// several) gives a far-off day, saturated at the ends of `i64`, never an overflow.
pub fn days_from_civil(year: i64, month: u32, day: u32) -> i64 {
    let days = days_from_civil_wide(i128::from(year), i128::from(month), i128::from(day));
    i64::try_from(days).unwrap_or(if days < 0 { i64::MIN } else { i64::MAX })
}

fn days_from_civil_wide(year: i128, month: i128, day: i128) -> i128 {
    let year = if month <= 2 { year - 1 } else { year };
    let era = year.div_euclid(400);
    let year_of_era = year - era * 400; // [0, 399]
    let month_from_march = (month + 9) % 12; // March = 0, ..., February = 11
    let day_of_year = (153 * month_from_march + 2) / 5 + day - 1; // [0, 365]
    let day_of_era = year_of_era * 365 + year_of_era / 4 - year_of_era / 100 + day_of_year;
    era * 146_097 + day_of_era - 719_468
}

/// The date `days` after 1970-01-01, as (year, month 1-12, day 1-31).
/// Total like [`days_from_civil`]: any `days` gives a date (years saturated at the ends
/// of `i64`).
pub fn civil_from_days(days: i64) -> (i64, u32, u32) {
    let (year, month, day) = civil_from_days_wide(i128::from(days));
    let year = i64::try_from(year).unwrap_or(if year < 0 { i64::MIN } else { i64::MAX });
    (year, month, day)
}

fn civil_from_days_wide(days: i128) -> (i128, u32, u32) {
    let days = days + 719_468; // days since 0000-03-01
    let era = days.div_euclid(146_097);
    let day_of_era = days - era * 146_097; // [0, 146096]
    let year_of_era =
        (day_of_era - day_of_era / 1460 + day_of_era / 36_524 - day_of_era / 146_096) / 365;
    let day_of_year = day_of_era - (365 * year_of_era + year_of_era / 4 - year_of_era / 100);
    let month_from_march = (5 * day_of_year + 2) / 153; // [0, 11]
    let day = day_of_year - (153 * month_from_march + 2) / 5 + 1; // [1, 31]
    let month = if month_from_march < 10 {
        month_from_march + 3
    } else {
        month_from_march - 9
    };
    let year = year_of_era + era * 400 + i128::from(month <= 2);
    // In range by construction: month in [1, 12], day in [1, 31].
    (year, month as u32, day as u32)
}

/// The UTC date of a Unix time in seconds, as (year, month 1-12, day 1-31); `None` when
/// the time is not finite or absurdly far (more than a million years) from 1970.
pub fn civil_from_unix_s(unix_s: f64) -> Option<(i64, u32, u32)> {
    const SECONDS_PER_DAY: f64 = 86_400.0;
    const MAX_ABS_DAYS: f64 = 365.25 * 1e6;
    let days = (unix_s / SECONDS_PER_DAY).floor();
    if !days.is_finite() || days.abs() > MAX_ABS_DAYS {
        return None;
    }
    Some(civil_from_days(days as i64))
}

/// A date and time for people, `2023-03-17 14:50:47.2 UTC`.
pub fn utc_text(unix_s: f64) -> String {
    let Some((year, month, day)) = civil_from_unix_s(unix_s) else {
        return format!("{unix_s:.1} s after 1970");
    };
    let seconds_of_day = unix_s - (unix_s / 86_400.0).floor() * 86_400.0;
    let hours = (seconds_of_day / 3600.0).floor();
    let minutes = ((seconds_of_day - hours * 3600.0) / 60.0).floor();
    let seconds = seconds_of_day - hours * 3600.0 - minutes * 60.0;
    format!("{year:04}-{month:02}-{day:02} {hours:02.0}:{minutes:02.0}:{seconds:04.1} UTC")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_dates() {
        assert_eq!(days_from_civil(1970, 1, 1), 0);
        assert_eq!(days_from_civil(2000, 3, 1), 11_017);
        assert_eq!(civil_from_days(11_017), (2000, 3, 1));
        assert_eq!(days_from_civil(2023, 8, 9), 19_578);
        assert_eq!(civil_from_days(-1), (1969, 12, 31));
    }

    #[test]
    fn any_year_or_day_count_gives_an_answer_not_an_overflow() {
        for year in [
            i64::MIN,
            -1_000_000_000_000_000,
            99_999_999_999_999_999,
            i64::MAX,
        ] {
            for month in [1, 2, 3, 12] {
                let days = days_from_civil(year, month, 1);
                let _ = civil_from_days(days);
            }
        }
        assert_eq!(days_from_civil(i64::MAX, 12, 31), i64::MAX);
        assert_eq!(days_from_civil(i64::MIN, 1, 1), i64::MIN);
        let (year, _, _) = civil_from_days(i64::MAX);
        assert!(year > 25_000_000_000_000_000);
    }

    #[test]
    fn days_round_trip_over_four_centuries() {
        for days in -146_097..146_097 + 400 {
            let (year, month, day) = civil_from_days(days);
            assert_eq!(days_from_civil(year, month, day), days);
        }
    }
}
