//! GGA, fix data ([`super`]): the time, position, fix quality, satellites used, HDOP,
//! the altitude above mean sea level and the geoid separation.
//!
//! ```text
//! $--GGA,hhmmss.ss,llll.ll,a,yyyyy.yy,a,q,nn,h.h,x.x,M,x.x,M,x.x,xxxx*hh
//!        1         2       3 4        5 6 7  8   9   10 11 12 13  14
//!  1 UTC time of day   2-5 latitude and longitude as in RMC
//!  6 fix quality: 0 invalid, 1 GPS, 2 DGPS, 4 RTK fixed, 5 RTK float, 6 estimated, …
//!  7 satellites used   8 horizontal dilution of precision (HDOP, no unit)
//!  9-10 antenna altitude above mean sea level, metres   11-12 geoid separation, metres
//! 13-14 age of differential data, reference station id
//! ```
//!
//! Source: Eric S. Raymond, "NMEA Revealed" (gpsd project,
//! <https://gpsd.gitlab.io/gpsd/NMEA.html>).

use super::clock::time_of_day_s;
use super::values::{coordinate, integer, number, Axis};
use super::SentenceError;

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

#[cfg_attr(not(target_arch = "wasm32"), inline(always))]
pub(super) fn parse_gga(fields: [&[u8]; 12]) -> Result<Gga, SentenceError> {
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

#[cfg(test)]
mod tests {
    use super::super::tests::{close, GOLDEN_GGA};
    use super::super::{parse_sentence, SentenceData};

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
}
