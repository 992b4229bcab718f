//! The streaming NMEA importer ([`super`]): [`NmeaReader`] takes lines as they come (a
//! file, its chunks, a serial port) and applies each parsed sentence in order: RMC and
//! GGA of one epoch merged into one fix, the clock across midnight, untimed sentences
//! placed between the timed ones around them, and the counts the notes report. The end
//! of the input is in `finish.rs`.

use super::clock::{Clock, NmeaDate};
use super::framing::{for_each_line, LineEvent};
#[cfg(any(not(target_arch = "wasm32"), target_feature = "atomics"))]
use super::parallel;
use super::{Hpr, HprStatus, SentenceData, SentenceError, KIND_NAMES, MAX_LINE_BYTES};
use crate::io::lines::Line;
use crate::io::recording::{Attitude, DeviceHeading, GnssFix, North, Recording};
use crate::io::{shorten, Diagnostics};

/// How many distinct unknown sentence addresses are named in the notes; the rest are
/// only counted, so that a stream of garbage addresses cannot grow memory.
const MAX_UNKNOWN_ADDRESSES_NAMED: usize = 16;

/// What one sentence gives the recording.
#[derive(Debug, Clone, Copy)]
enum SampleValue {
    Fix(GnssFix),
    Heading(DeviceHeading),
    Hpr {
        attitude: Attitude,
        heading: DeviceHeading,
    },
}

/// Which stream of the recording a sample went to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum StreamId {
    Gnss,
    DeviceHeading,
    Attitude,
}

/// A sample pushed without a time (its `t_s` is NaN until the end of the input, when
/// the timed sentences around it are known).
#[derive(Debug, Clone, Copy)]
pub(super) struct Untimed {
    pub(super) stream: StreamId,
    /// Index in its stream.
    idx: usize,
    pub(super) line: usize,
    /// Position among the untimed sentences, from 0: the time when nothing else is.
    pub(super) number: usize,
}

/// A timed sentence: where it is in the file and when it was.
#[derive(Debug, Clone, Copy)]
pub(super) struct Anchor {
    pub(super) line: usize,
    pub(super) t_s: f64,
}

/// The streaming importer: feed it lines as they come (from a file or a serial port),
/// then [`finish`](NmeaReader::finish) for the report.
///
/// Time: RMC and GGA carry the time of day; `t_s` is seconds since the first of them,
/// counted across midnight. The other sentences carry no time: once the next timed
/// sentence is read, each is placed by its line number between the timed sentences
/// before and after it (evenly spaced, so ten HDT lines between two fixes one second
/// apart get 1/11 s steps). Before the first and after the last timed sentence they
/// are extrapolated, at the end, at the log's mean time per line; with one timed epoch
/// only, a line counts as one second; with no timed sentence at all, the sample number
/// stands in for time. Each of these assumptions is stated in the notes.
///
/// Fixes: an RMC and a GGA with the same time (one receiver epoch) become one
/// [`GnssFix`]: position from the first, altitude from GGA, speed and course from RMC.
/// A VTG becomes a fix of its own with only speed and course. HDOP is not turned into
/// an accuracy, so `hacc_m` stays `None`.
#[derive(Debug, Clone, Default)]
pub struct NmeaReader {
    /// Samples go straight into the streams, in line order, so that sorting at the end
    /// counts only real steps back in time.
    pub(super) recording: Recording,
    /// Untimed samples still without a time: first those before the first timed
    /// sentence (`..n_leading`, placed at the end, when the mean time per line is
    /// known), then those after the latest one (placed when the next one comes).
    pub(super) untimed: Vec<Untimed>,
    pub(super) n_leading: usize,
    pub(super) n_untimed_sentences: usize,
    pub(super) first_anchor: Option<Anchor>,
    pub(super) last_anchor: Option<Anchor>,
    pub(super) clock: Clock,
    /// The last fix with a time, as (index in the GNSS stream, `t_s`), to merge RMC and
    /// GGA.
    last_timed_fix: Option<(usize, f64)>,
    pub(super) diagnostics: Diagnostics,
    pub(super) n_data_lines: usize,
    pub(super) n_read: [usize; KIND_NAMES.len()],
    pub(super) n_without_checksum: usize,
    pub(super) n_merged: usize,
    pub(super) n_rmc_invalid: usize,
    pub(super) n_gga_invalid: usize,
    pub(super) n_vtg_empty: usize,
    pub(super) n_hdg_with_deviation: usize,
    pub(super) hdg_reports_variation: bool,
    /// Which sentence types carried no time (by index in `KIND_NAMES`).
    pub(super) untimed_kinds: [bool; KIND_NAMES.len()],
    pub(super) rmc_variation_rad: Option<f64>,
    /// The first sentence that was read but gave nothing, for the error message.
    pub(super) first_unused: Option<(usize, &'static str)>,
    pub(super) unknown: Vec<(String, usize)>,
    pub(super) n_unknown: usize,
    pub(super) first_unknown_line: Option<usize>,
}

impl NmeaReader {
    pub fn new() -> Self {
        Self::default()
    }

    /// Reads one line. `line_number` is 1-based and should increase from line to line:
    /// untimed sentences are placed in time by it.
    pub fn read_line(&mut self, line_number: usize, text: &str) {
        self.apply(line_number, LineEvent::parse(text));
    }

    /// Reads a block of whole lines where they lie (the last may lack its ending),
    /// numbered on from `n_lines_before`, as [`read`](super::read) does for a whole file;
    /// returns how many lines there were. For a file read in chunks
    /// ([`crate::io::import::ChunkedImport`]), which keeps an unfinished line for the next.
    pub(crate) fn read_lines_block(&mut self, bytes: &[u8], n_lines_before: usize) -> usize {
        #[cfg(any(not(target_arch = "wasm32"), target_feature = "atomics"))]
        if let Some(n_lines) = parallel::read_lines_block(self, bytes, n_lines_before) {
            return n_lines;
        }
        for_each_line(bytes, |line_number, content| {
            self.apply(n_lines_before + line_number, LineEvent::of(content));
        })
    }

    /// Reads one line from [`LineDecoder`](crate::io::lines::LineDecoder), skipping it with
    /// a diagnostic if the decoder had to cut it.
    pub fn read_decoded(&mut self, line: &Line<'_>) {
        if line.truncated {
            self.apply(line.number, LineEvent::Truncated);
        } else {
            self.read_line(line.number, &line.text);
        }
    }

    /// Applies one parsed line: the only place lines change the reader's state.
    pub(super) fn apply(&mut self, line_number: usize, event: LineEvent<'_>) {
        match event {
            LineEvent::Blank => return,
            LineEvent::Truncated => self.diagnostics.push(
                Some(line_number),
                format!(
                    "line longer than {MAX_LINE_BYTES} bytes, so not one NMEA sentence \
                     (at most 82 characters); it was skipped"
                ),
            ),
            LineEvent::Known(sentence) => {
                if !sentence.has_checksum {
                    self.n_without_checksum += 1;
                }
                self.take(line_number, sentence.data);
            }
            LineEvent::Unknown {
                address,
                has_checksum,
            } => {
                if !has_checksum {
                    self.n_without_checksum += 1;
                }
                self.count_unknown(line_number, &address);
            }
            LineEvent::Error(error) => self.diagnostics.push(Some(line_number), error.to_string()),
        }
        self.n_data_lines += 1;
    }

    /// Reserves room in each stream for the whole input, extrapolated from what the
    /// first `bytes_read` of its `bytes_total` bytes gave, so that the streams of a large
    /// file are not copied as they grow. Only the capacity changes, never the samples.
    #[cfg(any(not(target_arch = "wasm32"), target_feature = "atomics"))]
    pub(super) fn reserve_for(&mut self, bytes_read: usize, bytes_total: usize) {
        if bytes_read == 0 || bytes_total <= bytes_read {
            return;
        }
        // A little more than the extrapolation, so that a slightly denser rest does not
        // need one more (doubling) copy.
        let expected = |len: usize| {
            let estimate = len as f64 * bytes_total as f64 / bytes_read as f64 * 1.05;
            (estimate as usize).saturating_sub(len)
        };
        let recording = &mut self.recording;
        let gnss_more = expected(recording.gnss.len());
        recording.gnss.t_s.reserve(gnss_more);
        recording.gnss.values.reserve(gnss_more);
        let heading_more = expected(recording.device_heading.len());
        recording.device_heading.t_s.reserve(heading_more);
        recording.device_heading.values.reserve(heading_more);
        let attitude_more = expected(recording.attitude.len());
        recording.attitude.t_s.reserve(attitude_more);
        recording.attitude.values.reserve(attitude_more);
    }

    fn count_unknown(&mut self, line_number: usize, address: &str) {
        self.n_unknown += 1;
        self.first_unknown_line.get_or_insert(line_number);
        if let Some(entry) = self
            .unknown
            .iter_mut()
            .find(|(known, _)| known.as_str() == address)
        {
            entry.1 += 1;
        } else if self.unknown.len() < MAX_UNKNOWN_ADDRESSES_NAMED {
            self.unknown.push((shorten(address), 1));
        }
    }

    fn take(&mut self, line: usize, data: SentenceData) {
        let kind_idx = data.kind_idx();
        if let Some(count) = self.n_read.get_mut(kind_idx) {
            *count += 1;
        }
        match data {
            SentenceData::Rmc(rmc) => {
                let t_s = self.timed(line, rmc.time_of_day_s, rmc.date);
                if !rmc.is_valid() {
                    self.n_rmc_invalid += 1;
                    self.first_unused
                        .get_or_insert((line, "RMC status V: the receiver had no valid fix"));
                    return;
                }
                if self.rmc_variation_rad.is_none() {
                    self.rmc_variation_rad = rmc.magnetic_variation_rad;
                }
                let fix = GnssFix {
                    lat_deg: rmc.lat_deg,
                    lon_deg: rmc.lon_deg,
                    speed_mps: rmc.speed_mps,
                    course_rad: rmc.course_rad,
                    ..GnssFix::default()
                };
                self.push_fix(line, kind_idx, t_s, fix);
            }
            SentenceData::Gga(gga) => {
                let t_s = self.timed(line, gga.time_of_day_s, None);
                if !gga.is_valid() {
                    self.n_gga_invalid += 1;
                    self.first_unused
                        .get_or_insert((line, "GGA fix quality 0: the receiver had no valid fix"));
                    return;
                }
                let fix = GnssFix {
                    lat_deg: gga.lat_deg,
                    lon_deg: gga.lon_deg,
                    alt_m: gga.alt_msl_m,
                    ..GnssFix::default()
                };
                self.push_fix(line, kind_idx, t_s, fix);
            }
            SentenceData::Vtg(vtg) => {
                let fix = GnssFix {
                    speed_mps: vtg.speed_mps,
                    course_rad: vtg.course_true_rad,
                    ..GnssFix::default()
                };
                if vtg.mode == Some('N') || fix == GnssFix::default() {
                    self.n_vtg_empty += 1;
                    self.first_unused
                        .get_or_insert((line, "VTG without a valid true course or speed"));
                    return;
                }
                self.push_untimed(line, kind_idx, SampleValue::Fix(fix));
            }
            SentenceData::Hdg(hdg) => {
                if hdg.deviation_rad.is_some() {
                    self.n_hdg_with_deviation += 1;
                }
                if hdg.variation_rad.is_some() {
                    self.hdg_reports_variation = true;
                }
                let heading = DeviceHeading {
                    heading_rad: hdg.magnetic_heading_rad(),
                    north: North::Magnetic,
                };
                self.push_untimed(line, kind_idx, SampleValue::Heading(heading));
            }
            SentenceData::Hdm(hdm) => {
                let heading = DeviceHeading {
                    heading_rad: hdm.heading_rad,
                    north: North::Magnetic,
                };
                self.push_untimed(line, kind_idx, SampleValue::Heading(heading));
            }
            SentenceData::Hdt(hdt) => {
                let heading = DeviceHeading {
                    heading_rad: hdt.heading_rad,
                    north: North::True,
                };
                self.push_untimed(line, kind_idx, SampleValue::Heading(heading));
            }
            SentenceData::Hpr(hpr) => self.take_hpr(line, kind_idx, hpr),
        }
    }

    fn take_hpr(&mut self, line: usize, kind_idx: usize, hpr: Hpr) {
        let statuses = [
            ("magnetic field", hpr.heading_status),
            ("pitch", hpr.pitch_status),
            ("roll", hpr.roll_status),
        ];
        if statuses
            .iter()
            .any(|(_, status)| *status != HprStatus::Normal)
        {
            let described: Vec<String> = statuses
                .iter()
                .filter(|(_, status)| *status != HprStatus::Normal)
                .map(|(name, status)| format!("{name} {}", status.describe()))
                .collect();
            self.diagnostics.push(
                Some(line),
                format!(
                    "PTNTHPR reports {}; only samples with every status normal (N) are kept",
                    described.join(", ")
                ),
            );
            return;
        }
        let missing = [
            ("heading", hpr.heading_rad),
            ("pitch", hpr.pitch_rad),
            ("roll", hpr.roll_rad),
        ]
        .into_iter()
        .find(|(_, value)| value.is_none());
        let (Some(heading_rad), Some(pitch_rad), Some(roll_rad)) =
            (hpr.heading_rad, hpr.pitch_rad, hpr.roll_rad)
        else {
            let field = missing.map_or("value", |(name, _)| name);
            self.diagnostics.push(
                Some(line),
                SentenceError::MissingField {
                    sentence: "PTNTHPR",
                    field,
                }
                .to_string(),
            );
            return;
        };
        let value = SampleValue::Hpr {
            attitude: Attitude {
                roll_rad,
                pitch_rad,
                yaw_rad: Some(heading_rad),
            },
            heading: DeviceHeading {
                heading_rad,
                north: North::Magnetic,
            },
        };
        self.push_untimed(line, kind_idx, value);
    }

    /// Converts a sentence's time of day and records it as an anchor for the untimed
    /// sentences around it.
    fn timed(
        &mut self,
        line: usize,
        time_of_day_s: Option<f64>,
        date: Option<NmeaDate>,
    ) -> Option<f64> {
        let time_of_day_s = time_of_day_s?;
        let t_s = self.clock.t_s(time_of_day_s, date);
        let anchor = Anchor { line, t_s };
        match self.last_anchor {
            None => {
                self.first_anchor = Some(anchor);
                self.n_leading = self.untimed.len();
            }
            Some(before) => {
                let pending = self.untimed.get(self.n_leading..).unwrap_or_default();
                for untimed in pending {
                    set_time(
                        &mut self.recording,
                        untimed,
                        interpolate(before, anchor, untimed.line),
                    );
                }
                self.untimed.truncate(self.n_leading);
            }
        }
        self.last_anchor = Some(anchor);
        Some(t_s)
    }

    fn push_untimed(&mut self, line: usize, kind_idx: usize, value: SampleValue) {
        if let Some(untimed) = self.untimed_kinds.get_mut(kind_idx) {
            *untimed = true;
        }
        let number = self.n_untimed_sentences;
        self.n_untimed_sentences += 1;
        let recording = &mut self.recording;
        let mut note = |stream: StreamId, idx: usize| {
            self.untimed.push(Untimed {
                stream,
                idx,
                line,
                number,
            });
        };
        match value {
            SampleValue::Fix(fix) => {
                note(StreamId::Gnss, recording.gnss.len());
                recording.gnss.push(f64::NAN, fix);
            }
            SampleValue::Heading(heading) => {
                note(StreamId::DeviceHeading, recording.device_heading.len());
                recording.device_heading.push(f64::NAN, heading);
            }
            SampleValue::Hpr { attitude, heading } => {
                note(StreamId::DeviceHeading, recording.device_heading.len());
                recording.device_heading.push(f64::NAN, heading);
                note(StreamId::Attitude, recording.attitude.len());
                recording.attitude.push(f64::NAN, attitude);
            }
        }
    }

    fn push_fix(&mut self, line: usize, kind_idx: usize, t_s: Option<f64>, fix: GnssFix) {
        if fix == GnssFix::default() {
            return;
        }
        let Some(t_s) = t_s else {
            self.push_untimed(line, kind_idx, SampleValue::Fix(fix));
            return;
        };
        if let Some((fix_idx, last_t_s)) = self.last_timed_fix {
            if t_s == last_t_s {
                if let Some(merged) = self.recording.gnss.values.get_mut(fix_idx) {
                    // The first sentence of the epoch keeps what it gave; the second fills in.
                    merged.lat_deg = merged.lat_deg.or(fix.lat_deg);
                    merged.lon_deg = merged.lon_deg.or(fix.lon_deg);
                    merged.alt_m = merged.alt_m.or(fix.alt_m);
                    merged.speed_mps = merged.speed_mps.or(fix.speed_mps);
                    merged.course_rad = merged.course_rad.or(fix.course_rad);
                    self.n_merged += 1;
                    return;
                }
            }
        }
        self.last_timed_fix = Some((self.recording.gnss.len(), t_s));
        self.recording.gnss.push(t_s, fix);
    }
}

/// The time of a line between two timed sentences, evenly by line number.
fn interpolate(before: Anchor, after: Anchor, line: usize) -> f64 {
    if after.line > before.line {
        let fraction = line.saturating_sub(before.line) as f64 / (after.line - before.line) as f64;
        before.t_s + (after.t_s - before.t_s) * fraction
    } else {
        before.t_s
    }
}

/// Gives an untimed sample its time.
pub(super) fn set_time(recording: &mut Recording, untimed: &Untimed, t_s: f64) {
    let slot = match untimed.stream {
        StreamId::Gnss => recording.gnss.t_s.get_mut(untimed.idx),
        StreamId::DeviceHeading => recording.device_heading.t_s.get_mut(untimed.idx),
        StreamId::Attitude => recording.attitude.t_s.get_mut(untimed.idx),
    };
    if let Some(slot) = slot {
        *slot = t_s;
    }
}
