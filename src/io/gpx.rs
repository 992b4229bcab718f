//! GPX and KML tracks: positions with their UTC times, the reference a sensor log
//! dropped with them is given (GNSS fixes, so the course between them is the reference
//! heading and the positions train and check the dead reckoning).
//!
//! Read: GPX 1.0/1.1 `<trkpt lat=".." lon="..">` (and `<rtept>`) with `<time>`, `<ele>`,
//! and GPX 1.0's `<speed>` (m/s) and `<course>` (degrees); KML's `<gx:Track>` (`<when>`
//! then `<gx:coord>lon lat alt</gx:coord>`, paired in order) and placemarks with a
//! `<TimeStamp><when>` and a `<Point><coordinates>lon,lat,alt`. Points without a time
//! cannot be placed beside a sensor log and are counted, not used. The reader is a tag
//! scanner, not an XML parser: it reads what these files hold and skips the rest.

use super::delimited::parse_datetime_s;
use super::{ensure_text, shorten, thousands, Diagnostics, ImportError, ImportReport};
use crate::io::recording::{GnssFix, Recording};

pub const GPX: &str = "GPX track";
pub const KML: &str = "KML track";

/// Whether the first lines are a GPX or KML document.
pub fn looks_like(sample: &[&str]) -> bool {
    sample
        .iter()
        .take(10)
        .any(|line| line.contains("<gpx") || line.contains("<kml"))
}

/// A point as read, before the times are made relative.
#[derive(Clone)]
struct Point {
    unix_s: f64,
    fix: GnssFix,
}

/// The text between `<tag>` (or `<tag attributes>`) and `</tag>` in `element`.
fn inner<'a>(element: &'a str, tag: &str) -> Option<&'a str> {
    let open = element.find(&format!("<{tag}"))?;
    let after = open + element[open..].find('>')? + 1;
    let close = after + element[after..].find(&format!("</{tag}>"))?;
    Some(element[after..close].trim())
}

/// The value of `name="…"` in a start tag.
fn attribute(start_tag: &str, name: &str) -> Option<f64> {
    let at = start_tag.find(&format!("{name}="))? + name.len() + 1;
    let quote = start_tag.get(at..)?.chars().next()?;
    let rest = start_tag.get(at + quote.len_utf8()..)?;
    rest[..rest.find(quote)?].trim().parse().ok()
}

fn number(element: &str, tag: &str) -> Option<f64> {
    inner(element, tag)?
        .parse()
        .ok()
        .filter(|v: &f64| v.is_finite())
}

/// GPX points: every `<trkpt …>…</trkpt>` and `<rtept …>…</rtept>`.
fn gpx_points(text: &str, untimed: &mut usize) -> Vec<Point> {
    let mut points = Vec::new();
    for tag in ["trkpt", "rtept"] {
        let open = format!("<{tag}");
        let close = format!("</{tag}>");
        let mut rest = text;
        while let Some(start) = rest.find(&open) {
            let element_text = &rest[start..];
            let end = element_text
                .find(&close)
                .map_or(element_text.len(), |end| end + close.len());
            let element = &element_text[..end];
            rest = &element_text[end..];
            let start_tag = &element[..element.find('>').unwrap_or(element.len())];
            let (Some(lat_deg), Some(lon_deg)) =
                (attribute(start_tag, "lat"), attribute(start_tag, "lon"))
            else {
                continue;
            };
            let Some(unix_s) = inner(element, "time").and_then(parse_datetime_s) else {
                *untimed += 1;
                continue;
            };
            points.push(Point {
                unix_s,
                fix: GnssFix {
                    lat_deg: Some(lat_deg),
                    lon_deg: Some(lon_deg),
                    alt_m: number(element, "ele"),
                    speed_mps: number(element, "speed"),
                    course_rad: number(element, "course").map(f64::to_radians),
                    hacc_m: None,
                },
            });
        }
    }
    points
}

/// `lon lat alt` or `lon,lat,alt` as a fix.
fn kml_coordinates(text: &str) -> Option<GnssFix> {
    let mut values = text
        .split(|c: char| c == ',' || c.is_whitespace())
        .filter(|part| !part.is_empty())
        .map(|part| part.parse::<f64>().ok());
    let lon_deg = values.next()??;
    let lat_deg = values.next()??;
    Some(GnssFix {
        lat_deg: Some(lat_deg),
        lon_deg: Some(lon_deg),
        alt_m: values.next().flatten(),
        ..GnssFix::default()
    })
}

/// KML points: `<when>`/`<gx:coord>` pairs in order, and timed placemarks.
fn kml_points(text: &str, untimed: &mut usize) -> Vec<Point> {
    let mut points = Vec::new();
    let elements = |tag: &str| -> Vec<&str> {
        let open = format!("<{tag}>");
        let close = format!("</{tag}>");
        text.match_indices(&open)
            .filter_map(|(at, _)| {
                let from = at + open.len();
                let end = text[from..].find(&close)?;
                Some(text[from..from + end].trim())
            })
            .collect()
    };
    let coords = elements("gx:coord");
    if !coords.is_empty() {
        let whens = elements("when");
        for (when, coord) in whens.iter().zip(&coords) {
            match (parse_datetime_s(when), kml_coordinates(coord)) {
                (Some(unix_s), Some(fix)) => points.push(Point { unix_s, fix }),
                _ => *untimed += 1,
            }
        }
        *untimed += coords.len().saturating_sub(whens.len());
        return points;
    }
    for placemark in text.split("<Placemark").skip(1) {
        let time = inner(placemark, "when").and_then(parse_datetime_s);
        let fix = inner(placemark, "coordinates").and_then(kml_coordinates);
        match (time, fix) {
            (Some(unix_s), Some(fix)) => points.push(Point { unix_s, fix }),
            (None, Some(_)) => *untimed += 1,
            _ => {}
        }
    }
    points
}

/// Reads a GPX or KML file.
pub fn read(file_name: &str, bytes: &[u8]) -> Result<ImportReport, ImportError> {
    ensure_text(file_name, bytes)?;
    let text = String::from_utf8_lossy(bytes);
    let is_kml = text.contains("<kml");
    let format = if is_kml { KML } else { GPX };
    let mut untimed = 0;
    let mut points = if is_kml {
        kml_points(&text, &mut untimed)
    } else {
        gpx_points(&text, &mut untimed)
    };
    crate::base::sort::sort_by_key(&mut points, |point| point.unix_s);
    let Some(first) = points.first().map(|point| point.unix_s) else {
        return Err(ImportError::NothingRecognised {
            file_name: file_name.to_string(),
            format,
            n_lines: text.lines().count(),
            first_problem: if untimed > 0 {
                format!(" ({untimed} points without a time: a track needs times to be placed beside a sensor log)")
            } else {
                format!(" (no track point in {})", shorten(file_name))
            },
        });
    };
    let mut recording = Recording {
        start_unix_s: Some(first),
        ..Recording::default()
    };
    for point in &points {
        recording.gnss.push(point.unix_s - first, point.fix);
    }
    let n_with_course = points.iter().filter(|p| p.fix.course_rad.is_some()).count();
    let mut notes = vec![format!(
        "{format}: {} points over {:.0} s from {}, positions{}; the course between points is \
         the reference heading where the track has no course of its own",
        thousands(points.len()),
        recording.gnss.duration_s(),
        crate::base::calendar::utc_text(first),
        if n_with_course > 0 {
            format!(", with speed and course at {}", thousands(n_with_course))
        } else {
            String::new()
        }
    )];
    let mut diagnostics = Diagnostics::default();
    if untimed > 0 {
        diagnostics.push(
            None,
            format!(
                "{} points without a time skipped: they cannot be placed beside a sensor log",
                thousands(untimed)
            ),
        );
        notes.push(format!(
            "{} points without a time not used",
            thousands(untimed)
        ));
    }
    Ok(ImportReport {
        file_name: file_name.to_string(),
        format,
        recording,
        diagnostics,
        header: None,
        n_data_lines: points.len(),
        notes,
        mag_frame: None,
        autopilot: None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn iso_times_with_and_without_zones() {
        let base = parse_datetime_s("2023-03-17T15:50:47Z").unwrap();
        assert_eq!(base, 1_679_068_247.0);
        assert_eq!(
            parse_datetime_s("2023-03-17T16:50:47.5+01:00"),
            Some(base + 0.5)
        );
        assert_eq!(parse_datetime_s("2023-03-17T15:50:47"), Some(base));
        assert_eq!(parse_datetime_s("2023-13-17T15:50:47Z"), None);
        assert_eq!(parse_datetime_s("yesterday"), None);
        assert_eq!(parse_datetime_s("99999999999999999-01-01T00:00:00Z"), None);
    }

    #[test]
    fn a_gpx_track_gives_timed_fixes() {
        let gpx = r#"<?xml version="1.0"?>
<gpx version="1.0" creator="test"><trk><trkseg>
<trkpt lat="47.408" lon="8.507"><ele>550.2</ele><time>2023-03-17T15:50:47Z</time><speed>1.4</speed><course>90</course></trkpt>
<trkpt lon="8.5071" lat="47.4081"><time>2023-03-17T15:50:48Z</time></trkpt>
<trkpt lat="47.4082" lon="8.5072"></trkpt>
</trkseg></trk></gpx>"#;
        assert!(looks_like(&gpx.lines().collect::<Vec<_>>()));
        let report = read("walk.gpx", gpx.as_bytes()).unwrap();
        let gnss = &report.recording.gnss;
        assert_eq!(gnss.len(), 2);
        assert_eq!(gnss.t_s, vec![0.0, 1.0]);
        assert_eq!(gnss.values[0].alt_m, Some(550.2));
        assert!((gnss.values[0].course_rad.unwrap() - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        assert_eq!(gnss.values[1].lon_deg, Some(8.5071));
        assert_eq!(report.recording.start_unix_s, Some(1_679_068_247.0));
        assert_eq!(report.diagnostics.total(), 1, "the untimed point");
    }

    #[test]
    fn a_kml_track_pairs_whens_and_coordinates() {
        let kml =
            "<kml xmlns:gx=\"http://www.google.com/kml/ext/2.2\"><Document><Placemark><gx:Track>\n\
            <when>2023-03-17T15:50:47Z</when><when>2023-03-17T15:50:49Z</when>\n\
            <gx:coord>8.507 47.408 550</gx:coord><gx:coord>8.508 47.409 551</gx:coord>\n\
            </gx:Track></Placemark></Document></kml>";
        let report = read("walk.kml", kml.as_bytes()).unwrap();
        assert_eq!(report.format, KML);
        let gnss = &report.recording.gnss;
        assert_eq!(gnss.t_s, vec![0.0, 2.0]);
        assert_eq!(gnss.values[1].lat_deg, Some(47.409));
    }

    #[test]
    fn a_track_without_times_says_why_it_cannot_be_used() {
        let gpx = "<gpx><trk><trkseg><trkpt lat=\"1\" lon=\"2\"></trkpt></trkseg></trk></gpx>";
        let error = read("route.gpx", gpx.as_bytes()).unwrap_err().to_string();
        assert!(error.contains("without a time"), "{error}");
        // Cut or garbled input never panics.
        for cut in 0..gpx.len() {
            let _ = read("cut.gpx", &gpx.as_bytes()[..cut]);
        }
    }
}
