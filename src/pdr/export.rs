//! The dead-reckoned track as text: CSV (always), GeoJSON and GPX (when the track has a
//! geodetic frame, i.e. the log had GNSS).
//!
//! GeoJSON is RFC 7946 (a `FeatureCollection` with the track as a `LineString` of
//! `[lon, lat]`, WGS-84); GPX is version 1.1 (one `trk` of `trkpt lat lon`, with the log
//! time in seconds in `<extensions>` since a log need not have a date).

use std::fmt::Write as _;

use super::PdrAnalysis;
use crate::base::geodesy::LocalFrame;
use nalgebra::Vector3;
use thiserror::Error;

/// The track's formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TrackFormat {
    Csv,
    GeoJson,
    Gpx,
}

impl TrackFormat {
    /// The format a file name's extension asks for.
    pub fn from_file_name(name: &str) -> Option<TrackFormat> {
        let lower = name.to_ascii_lowercase();
        let extension = lower.rsplit_once('.')?.1;
        match extension {
            "csv" => Some(TrackFormat::Csv),
            "geojson" | "json" => Some(TrackFormat::GeoJson),
            "gpx" => Some(TrackFormat::Gpx),
            _ => None,
        }
    }
}

/// Why the track cannot be written in a format.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum TrackExportError {
    /// GeoJSON or GPX (`format`) asked of a track without a geodetic frame.
    #[error(
        "the track has no latitude and longitude (the log has no usable GNSS fix), so it can \
         only be written as CSV in local metres"
    )]
    NoLatLon { format: TrackFormat },
}

/// The track in `format`; an error saying why for GeoJSON and GPX without a frame.
pub fn track_text(analysis: &PdrAnalysis, format: TrackFormat) -> Result<String, TrackExportError> {
    match format {
        TrackFormat::Csv => Ok(csv(analysis)),
        TrackFormat::GeoJson | TrackFormat::Gpx => {
            let frame = analysis
                .frame
                .ok_or(TrackExportError::NoLatLon { format })?;
            Ok(if format == TrackFormat::GeoJson {
                geojson(analysis, &frame)
            } else {
                gpx(analysis, &frame)
            })
        }
    }
}

fn lat_lon(frame: &LocalFrame, east_m: f64, north_m: f64) -> (f64, f64) {
    let position = frame.geodetic_of(Vector3::new(east_m, north_m, 0.0));
    (position.lat_deg, position.lon_deg)
}

fn csv(analysis: &PdrAnalysis) -> String {
    let mut text = String::from(
        "t_s,east_m,north_m,lat_deg,lon_deg,step_length_m,heading_deg,position_sigma_m,gnss_used\n",
    );
    for point in &analysis.track {
        let (lat, lon) = analysis
            .frame
            .map_or((String::new(), String::new()), |frame| {
                let (lat, lon) = lat_lon(&frame, point.east_m, point.north_m);
                (format!("{lat:.8}"), format!("{lon:.8}"))
            });
        let _ = writeln!(
            text,
            "{:.3},{:.3},{:.3},{lat},{lon},{:.3},{:.2},{:.2},{}",
            point.t_s,
            point.east_m,
            point.north_m,
            point.length_m,
            point.heading_rad.to_degrees(),
            point.position_sigma_m,
            u8::from(point.gnss_used)
        );
    }
    text
}

fn geojson(analysis: &PdrAnalysis, frame: &LocalFrame) -> String {
    let coordinates: Vec<String> = analysis
        .track
        .iter()
        .map(|point| {
            let (lat, lon) = lat_lon(frame, point.east_m, point.north_m);
            format!("[{lon:.8},{lat:.8}]")
        })
        .collect();
    let times: Vec<String> = analysis
        .track
        .iter()
        .map(|point| format!("{:.3}", point.t_s))
        .collect();
    format!(
        "{{\"type\":\"FeatureCollection\",\"features\":[{{\"type\":\"Feature\",\"properties\":{{\"name\":\"compass-pdr track of {}\",\"t_s\":[{}]}},\"geometry\":{{\"type\":\"LineString\",\"coordinates\":[{}]}}}}]}}\n",
        json_escape(&analysis.report.file_name),
        times.join(","),
        coordinates.join(",")
    )
}

fn gpx(analysis: &PdrAnalysis, frame: &LocalFrame) -> String {
    let mut text = String::from(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<gpx version=\"1.1\" creator=\"compass-pdr\" xmlns=\"http://www.topografix.com/GPX/1/1\">\n<trk><name>",
    );
    text.push_str(&xml_escape(&analysis.report.file_name));
    text.push_str("</name><trkseg>\n");
    for point in &analysis.track {
        let (lat, lon) = lat_lon(frame, point.east_m, point.north_m);
        let _ = writeln!(
            text,
            "<trkpt lat=\"{lat:.8}\" lon=\"{lon:.8}\"><extensions><t_s>{:.3}</t_s></extensions></trkpt>",
            point.t_s
        );
    }
    text.push_str("</trkseg></trk>\n</gpx>\n");
    text
}

fn json_escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            c if (c as u32) < 0x20 => {
                let _ = write!(out, "\\u{:04x}", c as u32);
            }
            c => out.push(c),
        }
    }
    out
}

fn xml_escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn formats_follow_the_extension() {
        assert_eq!(
            TrackFormat::from_file_name("a/b.GPX"),
            Some(TrackFormat::Gpx)
        );
        assert_eq!(
            TrackFormat::from_file_name("t.geojson"),
            Some(TrackFormat::GeoJson)
        );
        assert_eq!(TrackFormat::from_file_name("t.csv"), Some(TrackFormat::Csv));
        assert_eq!(TrackFormat::from_file_name("t.kml"), None);
        assert_eq!(TrackFormat::from_file_name("track"), None);
        assert_eq!(xml_escape("a<&>\""), "a&lt;&amp;&gt;&quot;");
        assert_eq!(json_escape("a\"b"), "a\\\"b");
    }

    #[test]
    fn a_track_without_lat_lon_says_csv_only() {
        assert_eq!(
            TrackExportError::NoLatLon {
                format: TrackFormat::Gpx
            }
            .to_string(),
            "the track has no latitude and longitude (the log has no usable GNSS fix), so it can \
             only be written as CSV in local metres"
        );
    }
}
