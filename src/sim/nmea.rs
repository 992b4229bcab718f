//! A simulated log written as NMEA 0183, as a marine or vehicle compass with a GNSS
//! receiver would send it over a serial line.
//!
//! At each GNSS fix (the rows with a latitude and longitude): `$GPRMC` (time, status,
//! position, speed, course, date), `$GPGGA` (time, position, quality, satellites, HDOP,
//! altitude 0 m) and `$GPVTG` (course and speed). Between them, at `heading_rate_hz`:
//! `$HCHDG`, the compass's own magnetic heading — the level heading of the raw
//! magnetometer, `atan2(−m_y, m_x)`, with its tilt, hard iron and all, as a simple
//! compass module reports it — and `$HEHDT`, the true heading (the log's reference).
//! The heading sentences carry no time, as in NMEA; the importer places them between
//! the timed sentences around them. Sentences follow "NMEA Revealed" (the formats the
//! importer documents in `io/nmea/`), with `*hh` checksums and CRLF endings.
//!
//! Times are UTC: the rows' own when the config has a start, else from 2026-01-01 00:00.

use std::fmt::Write as _;

use crate::base::calendar::civil_from_days;
use crate::io::canonical_csv::CanonicalRow;

/// The day a log without a start time is written on: 2026-01-01 00:00 UTC.
pub const DEFAULT_START_UNIX_S: f64 = 1_767_225_600.0;

const KNOTS_PER_MPS: f64 = 3600.0 / 1852.0;

/// The rows as NMEA text, with heading sentences at `heading_rate_hz`. `origin_unix_s`
/// is added to each row's `t_s` to make its UTC time: 0 for rows whose times are
/// already absolute (a config with a start), a date such as [`DEFAULT_START_UNIX_S`]
/// for rows timed from 0.
pub fn write(rows: &[CanonicalRow], origin_unix_s: f64, heading_rate_hz: f64) -> String {
    let mut text = String::with_capacity(rows.len() * 40 + 1024);
    let mut next_heading_s = f64::NEG_INFINITY;
    let heading_interval_s = 1.0 / heading_rate_hz.max(1e-3);
    for row in rows {
        let unix_s = origin_unix_s + row.t_s;
        if let (Some(lat_deg), Some(lon_deg)) = (row.lat_deg, row.lon_deg) {
            let (time, date) = time_and_date(unix_s);
            let lat = ddmm(lat_deg, 2, 'N', 'S');
            let lon = ddmm(lon_deg, 3, 'E', 'W');
            let speed_mps = row.gps_speed_mps.unwrap_or(0.0).max(0.0);
            let speed_knots = speed_mps * KNOTS_PER_MPS;
            let course = row
                .gps_course_deg
                .map_or(String::new(), |course_deg| format!("{course_deg:.2}"));
            push_sentence(
                &mut text,
                &format!("GPRMC,{time},A,{lat},{lon},{speed_knots:.3},{course},{date},,,A"),
            );
            let hdop = row.gps_hacc_m.map_or(1.0, |hacc_m| (hacc_m / 3.0).max(0.5));
            push_sentence(
                &mut text,
                &format!("GPGGA,{time},{lat},{lon},1,09,{hdop:.1},0.0,M,0.0,M,,"),
            );
            push_sentence(
                &mut text,
                &format!(
                    "GPVTG,{course},T,,M,{speed_knots:.3},N,{:.3},K,A",
                    speed_mps * 3.6
                ),
            );
        }
        if row.t_s >= next_heading_s {
            next_heading_s = row.t_s + heading_interval_s;
            if let Some(mag) = row.mag_ut {
                let heading_deg = (-mag.y).atan2(mag.x).to_degrees().rem_euclid(360.0);
                push_sentence(&mut text, &format!("HCHDG,{heading_deg:.1},,,,"));
            }
            if let Some(true_deg) = row.ref_heading_deg {
                push_sentence(
                    &mut text,
                    &format!("HEHDT,{:.2},T", true_deg.rem_euclid(360.0)),
                );
            }
        }
    }
    text
}

/// `hhmmss.ss` and `ddmmyy` of a UTC time.
fn time_and_date(unix_s: f64) -> (String, String) {
    let centiseconds = (unix_s * 100.0).round() as i64;
    let days = centiseconds.div_euclid(8_640_000);
    let of_day = centiseconds.rem_euclid(8_640_000);
    let (year, month, day) = civil_from_days(days);
    let time = format!(
        "{:02}{:02}{:02}.{:02}",
        of_day / 360_000,
        of_day / 6_000 % 60,
        of_day / 100 % 60,
        of_day % 100
    );
    let date = format!("{day:02}{month:02}{:02}", year.rem_euclid(100));
    (time, date)
}

/// `ddmm.mmmmm,H` (two or three degree digits), as NMEA writes latitude and longitude.
pub fn ddmm(value_deg: f64, degree_digits: usize, positive: char, negative: char) -> String {
    let hemisphere = if value_deg < 0.0 { negative } else { positive };
    let value_deg = value_deg.abs();
    let mut degrees = value_deg.trunc();
    let mut minutes = (value_deg - degrees) * 60.0;
    // Rounding to five decimals must not write 60.00000 minutes.
    if (minutes * 100_000.0).round() >= 6_000_000.0 {
        degrees += 1.0;
        minutes = 0.0;
    }
    format!(
        "{:0width$}{:08.5},{hemisphere}",
        degrees as u32,
        minutes,
        width = degree_digits
    )
}

/// `$`, the body, `*`, the XOR of the body's bytes in two hex digits, CRLF.
pub fn push_sentence(text: &mut String, body: &str) {
    let checksum = body.bytes().fold(0u8, |acc, byte| acc ^ byte);
    let _ = write!(text, "${body}*{checksum:02X}\r\n");
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::import::import;
    use crate::io::recording::North;
    use crate::sim::walk::{simulate, WalkConfig};

    #[test]
    fn the_demo_walk_as_nmea_reads_back_with_its_fixes_courses_and_headings() {
        let config = WalkConfig::demo(3, 120.0, 50.0);
        let rows = simulate(&config);
        // The demo's rows carry absolute times already.
        let text = write(&rows, 0.0, 10.0);
        let report = import("demo.nmea", text.as_bytes()).expect("NMEA reads back");
        assert_eq!(report.format, crate::io::nmea::FORMAT_NAME);
        assert!(
            report.diagnostics.kept.is_empty(),
            "{:?}",
            report.diagnostics
        );
        let written: Vec<&CanonicalRow> = rows.iter().filter(|row| row.lat_deg.is_some()).collect();
        // The importer merges RMC and GGA of one time into a fix with a position; the
        // untimed VTG after them is a sample of its own (course and speed only).
        let gnss = &report.recording.gnss;
        let from_rmc: Vec<(f64, crate::io::recording::GnssFix)> = gnss
            .t_s
            .iter()
            .zip(&gnss.values)
            .filter(|(_, fix)| fix.lat_deg.is_some())
            .map(|(&t_s, &fix)| (t_s, fix))
            .collect();
        assert_eq!(from_rmc.len(), written.len());
        assert_eq!(gnss.len(), 2 * written.len());
        assert_eq!(report.recording.start_unix_s, config.start_unix_s);
        for ((t_s, fix), row) in from_rmc.iter().zip(&written) {
            // Times to the centisecond, positions to ddmm.mmmmm (2 cm), speeds to the
            // thousandth of a knot, courses to the hundredth of a degree.
            let t0_s = config.start_unix_s.unwrap_or(0.0);
            assert!(
                (t_s - (row.t_s - t0_s)).abs() < 0.006,
                "{t_s} vs {}",
                row.t_s
            );
            assert!((fix.lat_deg.unwrap_or(f64::NAN) - row.lat_deg.unwrap_or(0.0)).abs() < 2e-7);
            assert!((fix.lon_deg.unwrap_or(f64::NAN) - row.lon_deg.unwrap_or(0.0)).abs() < 2e-7);
            let speed_mps = row.gps_speed_mps.unwrap_or(0.0).max(0.0);
            assert!((fix.speed_mps.unwrap_or(f64::NAN) - speed_mps).abs() < 1e-3);
            let course_deg = fix.course_rad.unwrap_or(f64::NAN).to_degrees();
            let written_deg = row.gps_course_deg.unwrap_or(0.0);
            let difference = (course_deg - written_deg + 540.0).rem_euclid(360.0) - 180.0;
            assert!(difference.abs() < 0.006, "{course_deg} vs {written_deg}");
        }
        // Headings: HDG magnetic and HDT true, 10 a second.
        let headings = &report.recording.device_heading;
        let n_true = headings
            .values
            .iter()
            .filter(|heading| heading.north == North::True)
            .count();
        let n_magnetic = headings.len() - n_true;
        assert!((1190..=1210).contains(&n_true), "{n_true}");
        assert_eq!(n_magnetic, n_true);
    }

    #[test]
    fn times_dates_and_coordinates_are_written_as_nmea_writes_them() {
        // 2026-05-14 23:59:59.995 rounds to the next day's midnight.
        assert_eq!(
            time_and_date(1_778_803_199.995),
            ("000000.00".to_string(), "150526".to_string())
        );
        assert_eq!(ddmm(47.606_2, 2, 'N', 'S'), "4736.37200,N");
        assert_eq!(ddmm(-122.332_1, 3, 'E', 'W'), "12219.92600,W");
        assert_eq!(ddmm(10.999_999_999, 2, 'N', 'S'), "1100.00000,N");
    }
}
