//! The streaming reader of serial lines ([`super`]): [`SerialReader`] takes lines as
//! they come (a file, its chunks, a serial port), parses each, keeps the calibration
//! echoes apart, times samples by their arrival or by an assumed rate, and joins lines
//! that each bring a different sensor into one sample until a sensor repeats. The end
//! of the input is in `finish.rs`.

use nalgebra::Vector3;

use super::{
    parse_line_with, sensor_to_body, EchoSeen, LineError, LineFormat, SensorSample, SerialLine,
    ASSUMED_FILE_RATE_HZ, MAX_LINE_BYTES,
};
use crate::io::recording::Recording;
use crate::io::{shorten, Diagnostics, MagUnit};

/// How many ignored label names the notes list.
const MAX_IGNORED_LABELS_LISTED: usize = 20;

/// Lines that each bring some sensors, collected until a sensor repeats.
#[derive(Debug, Clone, Copy)]
struct Frame {
    t_s: f64,
    acc: Option<(Vector3<f64>, bool)>,
    gyro: Option<(Vector3<f64>, bool)>,
    mag: Option<(Vector3<f64>, bool, MagUnit)>,
    temp_c: Option<f64>,
    /// The frame is one MotionCal `Raw:` line, so a `Uni:` line right after it is the
    /// same reading.
    is_one_motioncal_raw: bool,
    n_lines: usize,
}

impl Frame {
    fn collides(&self, sample: &SensorSample) -> bool {
        (self.acc.is_some() && sample.acc_in_sensor_mps2.is_some())
            || (self.gyro.is_some() && sample.gyro_in_sensor_radps.is_some())
            || (self.mag.is_some() && sample.mag_in_sensor_ut.is_some())
            || (self.temp_c.is_some() && sample.temp_c.is_some())
    }

    fn take(&mut self, sample: &SensorSample) {
        if let Some(acc) = sample.acc_in_sensor_mps2 {
            self.acc = Some((acc, sample.acc_unit_assumed));
        }
        if let Some(gyro) = sample.gyro_in_sensor_radps {
            self.gyro = Some((gyro, sample.gyro_unit_assumed));
        }
        if let Some(mag) = sample.mag_in_sensor_ut {
            self.mag = Some((mag, sample.mag_unit_assumed, sample.mag_unit));
        }
        if let Some(temp_c) = sample.temp_c {
            self.temp_c = Some(temp_c);
        }
    }
}

/// The streaming reader: the live page feeds it lines as they arrive, files feed it
/// every line, and [`SerialReader::finish`] makes the report.
#[derive(Debug, Clone)]
pub struct SerialReader {
    pub(super) sample_rate_hz: f64,
    pub(super) rate_was_invalid: bool,
    pub(super) recording: Recording,
    /// For each sample of each stream: whether its unit was assumed (SI) rather than
    /// given, so that `finish` can check the assumption.
    pub(super) acc_unit_assumed: Vec<bool>,
    pub(super) gyro_unit_assumed: Vec<bool>,
    pub(super) mag_unit_assumed: Vec<bool>,
    /// How many magnetometer samples came in each unit, in the order first met.
    pub(super) mag_units: Vec<(MagUnit, usize)>,
    pub(super) diagnostics: Diagnostics,
    pub(super) echoes: Vec<EchoSeen>,
    frame: Option<Frame>,
    pub(super) n_frames: usize,
    pub(super) n_joined_frames: usize,
    pub(super) n_arrival_times: usize,
    pub(super) n_data_lines: usize,
    pub(super) n_lines: usize,
    pub(super) lines_per_format: [usize; LineFormat::ALL.len()],
    pub(super) n_raw_replaced_by_uni: usize,
    pub(super) n_wide_count_lines: usize,
    pub(super) n_six_value_lines: usize,
    pub(super) ignored_labels: Vec<String>,
    pub(super) first_problem: Option<(usize, String)>,
}

impl SerialReader {
    /// A reader that spaces samples without an arrival time at `sample_rate_hz` (100 Hz
    /// if the rate given is not a positive number).
    pub fn new(sample_rate_hz: f64) -> Self {
        let rate_is_valid = sample_rate_hz.is_finite() && sample_rate_hz > 0.0;
        Self {
            sample_rate_hz: if rate_is_valid {
                sample_rate_hz
            } else {
                ASSUMED_FILE_RATE_HZ
            },
            rate_was_invalid: !rate_is_valid,
            recording: Recording::default(),
            acc_unit_assumed: Vec::new(),
            gyro_unit_assumed: Vec::new(),
            mag_unit_assumed: Vec::new(),
            mag_units: Vec::new(),
            diagnostics: Diagnostics::default(),
            echoes: Vec::new(),
            frame: None,
            n_frames: 0,
            n_joined_frames: 0,
            n_arrival_times: 0,
            n_data_lines: 0,
            n_lines: 0,
            lines_per_format: [0; LineFormat::ALL.len()],
            n_raw_replaced_by_uni: 0,
            n_wide_count_lines: 0,
            n_six_value_lines: 0,
            ignored_labels: Vec::new(),
            first_problem: None,
        }
    }

    /// Reads one line (1-based `line_number`). The live page passes the arrival time of
    /// the line; files pass `None`. A line of [`MAX_LINE_BYTES`] or more is skipped.
    pub fn read_line(&mut self, line_number: usize, text: &str, arrival_t_s: Option<f64>) {
        let truncated = text.len() >= MAX_LINE_BYTES;
        self.read_line_inner(line_number, text, arrival_t_s, truncated);
    }

    /// The samples read so far (the last one may still be waiting for the rest of its
    /// lines), in body axes and SI units, before the unit checks of `finish`.
    pub fn recording(&self) -> &Recording {
        &self.recording
    }

    /// The calibration echoes read so far.
    pub fn echoes(&self) -> &[EchoSeen] {
        &self.echoes
    }

    /// The stream ended (a serial port closed): the reading still waiting for the rest of
    /// its lines is taken as it is, as `finish` would take it.
    pub fn end_of_stream(&mut self) {
        self.flush_frame();
    }

    /// The lines skipped so far, with their line numbers and reasons.
    pub fn diagnostics(&self) -> &Diagnostics {
        &self.diagnostics
    }

    /// The line format read most often so far (echo lines aside), for telling the user
    /// what the stream was taken for; `None` before the first reading.
    pub fn main_format(&self) -> Option<LineFormat> {
        LineFormat::ALL
            .iter()
            .copied()
            .filter(|format| *format != LineFormat::CalibrationEcho)
            .map(|format| (format, self.lines_per_format[format.index()]))
            .filter(|(_, n_lines)| *n_lines > 0)
            .max_by_key(|(_, n_lines)| *n_lines)
            .map(|(format, _)| format)
    }

    pub(super) fn read_line_inner(
        &mut self,
        line_number: usize,
        text: &str,
        arrival_t_s: Option<f64>,
        truncated: bool,
    ) {
        self.n_lines = self.n_lines.max(line_number);
        let trimmed = text.trim_start_matches('\u{feff}').trim();
        if trimmed.is_empty() {
            return;
        }
        self.n_data_lines += 1;
        if truncated {
            self.skip(
                line_number,
                trimmed,
                LineError::TooLong {
                    max_bytes: MAX_LINE_BYTES,
                },
            );
            return;
        }
        let arrival_t_s = arrival_t_s.filter(|t_s| t_s.is_finite());
        let mut ignored: [&str; 8] = [""; 8];
        let mut n_ignored = 0usize;
        let parsed = parse_line_with(trimmed, &mut |label| {
            if let Some(slot) = ignored.get_mut(n_ignored) {
                *slot = label;
                n_ignored += 1;
            }
        });
        match parsed {
            Ok(SerialLine::Sample(sample)) => {
                for label in ignored.iter().take(n_ignored) {
                    self.note_ignored_label(label);
                }
                self.add_sample(sample, arrival_t_s);
            }
            Ok(SerialLine::Echo(echo)) => {
                self.count_format(LineFormat::CalibrationEcho);
                self.echoes.push(EchoSeen {
                    line: line_number,
                    arrival_t_s,
                    echo,
                });
            }
            Err(LineError::Blank) => {}
            Err(error) => self.skip(line_number, trimmed, error),
        }
    }

    fn count_format(&mut self, format: LineFormat) {
        if let Some(count) = self.lines_per_format.get_mut(format.index()) {
            *count += 1;
        }
    }

    fn skip(&mut self, line_number: usize, text: &str, error: LineError) {
        let reason = error.to_string();
        self.diagnostics.push(
            Some(line_number),
            format!("\"{}\": {reason}", shorten(text)),
        );
        if self.first_problem.is_none() {
            self.first_problem = Some((line_number, reason));
        }
    }

    fn note_ignored_label(&mut self, label: &str) {
        let label = if label.is_empty() { "(empty)" } else { label };
        let is_known = self
            .ignored_labels
            .iter()
            .any(|known| known.eq_ignore_ascii_case(label));
        if !is_known && self.ignored_labels.len() < MAX_IGNORED_LABELS_LISTED {
            self.ignored_labels.push(shorten(label));
        }
    }

    fn add_sample(&mut self, sample: SensorSample, arrival_t_s: Option<f64>) {
        self.count_format(sample.format);
        if sample.counts_beyond_16_bits {
            self.n_wide_count_lines += 1;
        }
        let is_six_values = sample.format == LineFormat::PlainNumbers
            && sample.acc_in_sensor_mps2.is_some()
            && sample.mag_in_sensor_ut.is_some();
        if is_six_values {
            self.n_six_value_lines += 1;
        }
        if let Some(frame) = self.frame.as_mut() {
            if sample.format == LineFormat::Uni && frame.is_one_motioncal_raw {
                // The same reading as the Raw: line before it, with more digits.
                frame.take(&sample);
                frame.is_one_motioncal_raw = false;
                self.n_raw_replaced_by_uni += 1;
                return;
            }
            if frame.collides(&sample) {
                self.flush_frame();
            }
        }
        if self.frame.is_none() {
            let t_s = match arrival_t_s {
                Some(t_s) => {
                    self.n_arrival_times += 1;
                    t_s
                }
                None => self.n_frames as f64 / self.sample_rate_hz,
            };
            self.frame = Some(Frame {
                t_s,
                acc: None,
                gyro: None,
                mag: None,
                temp_c: None,
                is_one_motioncal_raw: sample.format == LineFormat::MotionCalRaw,
                n_lines: 0,
            });
        } else if let Some(frame) = self.frame.as_mut() {
            frame.is_one_motioncal_raw = false;
        }
        if let Some(frame) = self.frame.as_mut() {
            frame.take(&sample);
            frame.n_lines += 1;
        }
    }

    pub(super) fn flush_frame(&mut self) {
        let Some(frame) = self.frame.take() else {
            return;
        };
        let t_s = frame.t_s;
        let recording = &mut self.recording;
        if let Some((acc, assumed)) = frame.acc {
            recording.acc_in_body_mps2.push(t_s, sensor_to_body(acc));
            self.acc_unit_assumed.push(assumed);
        }
        if let Some((gyro, assumed)) = frame.gyro {
            recording.gyro_in_body_radps.push(t_s, sensor_to_body(gyro));
            self.gyro_unit_assumed.push(assumed);
        }
        if let Some((mag, assumed, unit)) = frame.mag {
            recording.mag_in_body_ut.push(t_s, sensor_to_body(mag));
            self.mag_unit_assumed.push(assumed);
            match self.mag_units.iter_mut().find(|(seen, _)| *seen == unit) {
                Some((_, count)) => *count += 1,
                None => self.mag_units.push((unit, 1)),
            }
        }
        if let Some(temp_c) = frame.temp_c {
            recording.temp_c.push(t_s, temp_c);
        }
        self.n_frames += 1;
        if frame.n_lines > 1 {
            self.n_joined_frames += 1;
        }
    }
}
