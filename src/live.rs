//! Live calibration: a magnetometer streaming text lines over a serial port, calibrated
//! while the user turns it.
//!
//! The page hands every chunk of bytes it reads from the port to [`LiveSession::feed`]
//! as it arrives; the session keeps all of them (the raw recording, downloadable at any
//! time and whole after an unplug), cuts them into lines with the same decoder as files
//! (CR, LF or CRLF; chunk boundaries anywhere), and reads each line with the serial-line
//! reader of [`crate::io::serial_lines`] (MotionCal `Raw:`, `Uni:`, Adafruit `Raw: `,
//! Serial Plotter pairs, tuples, CircuitPython `X: Y: Z:`, plain numbers, and the
//! `Cal1:`/`Cal2:` echoes). A line that is not a reading is counted and listed, never
//! dropped silently.
//!
//! Each magnetometer sample goes, in the **sensor's own axes** (as printed, µT: what
//! the device will apply the calibration to), into the power sums of the streaming
//! ellipsoid fit ([`EllipsoidAccumulator`], the algebraic fit of Moafipoor et al. 2007
//! Eq. 5 after Li and Griffiths 2004), so a refit costs the same after ten samples or
//! a million. [`LiveSession::refit`] solves it and measures the fit on an evenly thinned
//! copy of the samples: residual RMS of `|corrected| − B`, the spread of `|corrected|`,
//! the sphere coverage as MotionCal counts it ([`sphere_coverage`], 100 equal-area
//! regions, "gaps" under 15 %), and, when the page knows where the user is, the fitted
//! field against the World Magnetic Model's. [`LiveQuality::verdict`] says whether the
//! calibration is good enough to send, or why not.
//!
//! [`LiveSession::packet_for_device`] makes MotionCal's 68-byte calibration packet
//! ([`motioncal_packet`]) and remembers what was sent; the `Cal1:`/`Cal2:` lines the
//! device echoes afterwards confirm it (or say which value differs).
//!
//! No clock here: the page passes each chunk's arrival time.

mod attitude;

use nalgebra::Vector3;
use serde::Serialize;

use crate::calib::ellipsoid::{EllipsoidAccumulator, EllipsoidError, EllipsoidModel};
use crate::calib::export::{motioncal_packet, SensorCalibration, MOTIONCAL_PACKET_LEN};
use crate::calib::model::FieldCalibration;
use crate::calib::sphere_coverage::{sphere_coverage, SphereCoverage};
use crate::calib::tilt::Tilt;
use crate::io::lines::LineDecoder;
use crate::io::serial_lines::{sensor_to_body, EchoKind, EchoSeen, LineFormat, SerialReader};
use crate::io::{nmea, Diagnostics, MagUnit, SensorFrame};

/// Lines longer than this are cut and reported (no sensor line is near it).
const MAX_LINE_BYTES: usize = 4096;

/// At most this many samples are kept for the quality figures and the plots: every
/// sample until then, afterwards every second one, and so on (an even thinning over the
/// whole session, so a long session costs no more to assess than a short one).
pub const MAX_KEPT_SAMPLES: usize = 16_384;

/// The fewest magnetometer samples a refit is tried on.
pub const MIN_FIT_SAMPLES: usize = 50;

/// Good enough to send: fewer samples than this are not.
pub const GOOD_MIN_SAMPLES: usize = 300;
/// Good enough: MotionCal's gaps figure under this (percent of the sphere).
pub const GOOD_MAX_GAP_PCT: f64 = 15.0;
/// Good enough: the corrected field's magnitude varies by less than this (standard
/// deviation over mean, percent). A good fit of a MEMS magnetometer leaves about 1 %.
pub const GOOD_MAX_SPREAD_PCT: f64 = 3.0;
/// Good enough: the fitted field within this of the World Magnetic Model's, when the
/// position is known (percent). Further off, the sensor's scale is wrong or something
/// magnetic is near.
pub const GOOD_MAX_FIELD_DIFFERENCE_PCT: f64 = 15.0;

/// An echoed value matches the one sent within this (the sketch prints `Cal1:` with 3
/// decimals and `Cal2:` with 4; float32 adds a few 10⁻⁶ relative).
const ECHO_ABS_TOLERANCE: f64 = 6e-4;
const ECHO_REL_TOLERANCE: f64 = 1e-5;

/// A live calibration session: everything received, what it was read as, and the fit.
#[derive(Debug, Clone)]
pub struct LiveSession {
    raw: Vec<u8>,
    decoder: LineDecoder,
    reader: SerialReader,
    /// Magnetometer samples of `reader`'s recording already added to the fit.
    n_mag_used: usize,
    accumulator: EllipsoidAccumulator,
    /// The evenly thinned samples (sensor axes, µT), and the stride between them.
    kept_ut: Vec<Vector3<f64>>,
    kept_stride: usize,
    /// The first lines, for telling an NMEA stream (no magnetometer) apart.
    first_lines: Vec<String>,
    expected_field_ut: Option<f64>,
    quality: Option<LiveQuality>,
    sent: Option<Sent>,
    /// The attitude filter, from the first fit on, for a stream with a gyroscope.
    attitude: Option<attitude::LiveAttitude>,
}

#[derive(Debug, Clone, Copy)]
struct Sent {
    calibration: FieldCalibration,
    /// Echoes seen before the packet went out (those cannot confirm it).
    n_echoes_before: usize,
}

/// How the latest fit looks, and whether it is good enough.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LiveQuality {
    /// The calibration in the sensor's axes, as the device applies it.
    pub calibration: FieldCalibration,
    pub model: EllipsoidModel,
    pub n_samples: usize,
    /// RMS of `|corrected| − field_ut` over the kept samples (µT).
    pub residual_rms_ut: f64,
    /// Standard deviation of `|corrected|` over its mean (percent).
    pub field_spread_pct: f64,
    pub coverage: SphereCoverage,
    /// The World Magnetic Model's field where the user is, when the page knows.
    pub expected_field_ut: Option<f64>,
    /// `(fitted − expected) / expected`, percent.
    pub field_difference_pct: Option<f64>,
    pub verdict: Verdict,
}

impl LiveQuality {
    /// The fit as every export writes it: in the board's own axes as printed and in µT,
    /// the readings the board applies its calibration to.
    pub fn sensor_calibration(&self) -> SensorCalibration {
        SensorCalibration::from_frame_ut(
            &self.calibration,
            &SensorFrame::serial_board(MagUnit::MICROTESLA),
        )
    }
}

/// Good enough to send, or the reasons it is not (each says what to do).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Verdict {
    pub good_enough: bool,
    pub reasons: Vec<String>,
}

/// What became of a calibration sent to the device.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "state", rename_all = "snake_case")]
pub enum Confirmation {
    /// Nothing sent yet.
    NotSent,
    /// Sent; no `Cal1:` and `Cal2:` echo yet.
    Waiting,
    /// The device echoed back the values sent.
    Confirmed { line: usize },
    /// The device echoed other values: the first that differs.
    Differs { line: usize, what: String },
}

/// Counts for the page: what came in and what it was read as.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LiveCounts {
    pub n_bytes: usize,
    /// Complete lines (a line still waiting for its ending is not counted).
    pub n_lines: usize,
    /// Magnetometer readings taken (the last one waits for the next line, which may be
    /// a `Uni:` line printing the same reading more precisely).
    pub n_mag_samples: usize,
    pub n_skipped_lines: usize,
    pub n_echoes: usize,
    /// What the stream was read as, e.g. "MotionCal Raw: counts".
    pub format: Option<&'static str>,
}

impl Default for LiveSession {
    fn default() -> Self {
        LiveSession::new()
    }
}

impl LiveSession {
    pub fn new() -> Self {
        LiveSession {
            raw: Vec::new(),
            decoder: LineDecoder::new(MAX_LINE_BYTES),
            // Lines carry their arrival time; the rate is used only for lines without.
            reader: SerialReader::new(100.0),
            n_mag_used: 0,
            accumulator: EllipsoidAccumulator::new(),
            kept_ut: Vec::new(),
            kept_stride: 1,
            first_lines: Vec::new(),
            expected_field_ut: None,
            quality: None,
            sent: None,
            attitude: None,
        }
    }

    /// Takes the next bytes from the port, which arrived at `arrival_t_s` (seconds on
    /// any clock that does not go back). Every byte is kept; every complete line is read.
    pub fn feed(&mut self, bytes: &[u8], arrival_t_s: f64) {
        self.raw.extend_from_slice(bytes);
        let reader = &mut self.reader;
        let first_lines = &mut self.first_lines;
        self.decoder.feed(bytes, |line| {
            if first_lines.len() < 20 && !line.text.trim().is_empty() {
                first_lines.push(line.text.trim().to_string());
            }
            reader.read_line(line.number, &line.text, Some(arrival_t_s));
        });
        self.take_new_samples();
    }

    /// The port closed: a last line without its ending is read as it is, the reading
    /// waiting for a possible `Uni:` line is taken, and the next port's first line starts
    /// a line of its own (the raw recording is left as received).
    pub fn port_closed(&mut self) {
        let reader = &mut self.reader;
        self.decoder
            .finish(|line| reader.read_line(line.number, &line.text, None));
        self.decoder = LineDecoder::continuing(MAX_LINE_BYTES, self.decoder.n_lines());
        // No `Uni:` line can follow on a closed port: the last reading counts now.
        self.reader.end_of_stream();
        self.take_new_samples();
    }

    /// Every byte received, in order: the raw recording.
    pub fn raw(&self) -> &[u8] {
        &self.raw
    }

    /// The World Magnetic Model's field strength where the user is (µT), or `None`.
    pub fn set_expected_field(&mut self, expected_field_ut: Option<f64>) {
        self.expected_field_ut = expected_field_ut.filter(|ut| ut.is_finite() && *ut > 0.0);
    }

    pub fn counts(&self) -> LiveCounts {
        LiveCounts {
            n_bytes: self.raw.len(),
            n_lines: self.decoder.n_lines(),
            n_mag_samples: self.n_mag_used,
            n_skipped_lines: self.reader.diagnostics().total(),
            n_echoes: self.reader.echoes().len(),
            format: self.format_label(),
        }
    }

    /// What the stream is read as; NMEA sentences are named (they are recorded, but
    /// carry no magnetometer vector to calibrate).
    fn format_label(&self) -> Option<&'static str> {
        let lines: Vec<&str> = self.first_lines.iter().map(String::as_str).collect();
        if self.n_mag_used == 0 && lines.len() >= 3 && nmea::looks_like(&lines) {
            return Some(NMEA_LABEL);
        }
        self.reader.main_format().map(LineFormat::describe)
    }

    /// The lines skipped so far, with their numbers and reasons.
    pub fn diagnostics(&self) -> &Diagnostics {
        self.reader.diagnostics()
    }

    /// The kept (evenly thinned) magnetometer samples, sensor axes, µT.
    pub fn kept_samples_ut(&self) -> &[Vector3<f64>] {
        &self.kept_ut
    }

    /// The latest magnetometer sample (sensor axes, µT).
    pub fn latest_mag_ut(&self) -> Option<Vector3<f64>> {
        self.reader
            .recording()
            .mag_in_body_ut
            .values
            .last()
            .map(|&v_in_body| sensor_to_body(v_in_body))
    }

    /// The attitude filter's heading and its 1σ (radians; magnetic north, clockwise),
    /// for a stream with a gyroscope and an accelerometer, once the field has corrected
    /// it after the first fit: the dial's second needle, which a steel tool brought
    /// near the board bends by the gyroscope's drift rather than by the tool.
    pub fn filter_heading_rad(&self) -> Option<(f64, f64)> {
        let attitude = self.attitude.as_ref()?;
        Some((attitude.heading_rad()?, attitude.heading_sigma_rad()?))
    }

    /// The heading (radians from magnetic north, clockwise) of the latest sample through
    /// the latest fit, levelled with the latest accelerometer sample when the stream has
    /// one (the PDR paper's and the compass paper's Eq. 4 tilt compensation); `None`
    /// before the first fit. The dial's needle: the calibration's direct reading.
    pub fn latest_heading_rad(&self) -> Option<f64> {
        let quality = self.quality.as_ref()?;
        let corrected_in_sensor = quality.calibration.apply(self.latest_mag_ut()?);
        let corrected_in_body = sensor_to_body(corrected_in_sensor);
        let tilt = self
            .reader
            .recording()
            .acc_in_body_mps2
            .values
            .last()
            .and_then(|&f_in_body| Tilt::from_specific_force(f_in_body))
            .unwrap_or(Tilt::LEVEL);
        let level = tilt.level(corrected_in_body);
        Some(crate::calib::heading::heading_rad(level, 0.0))
    }

    /// Refits from every sample so far and measures the fit. `Err` says why no fit is
    /// possible yet (too few samples, or all in a plane) and what to do.
    pub fn refit(&mut self) -> Result<&LiveQuality, String> {
        let n_samples = self.accumulator.n_samples();
        if n_samples < MIN_FIT_SAMPLES {
            return Err(format!(
                "{n_samples} magnetometer samples so far; the first fit needs {MIN_FIT_SAMPLES}. \
                 Keep turning the device."
            ));
        }
        let fit = self
            .accumulator
            .solve(EllipsoidModel::Auto, None)
            .map_err(|error| describe_fit_error(&error))?;
        let quality = self.measure(fit.calibration, fit.model, n_samples);
        let recording = self.reader.recording();
        match &mut self.attitude {
            Some(attitude) => attitude.recalibrate(recording, &quality.calibration),
            None => self.attitude = attitude::LiveAttitude::start(recording, &quality.calibration),
        }
        Ok(self.quality.insert(quality))
    }

    /// The latest fit's quality, if a fit was made.
    pub fn quality(&self) -> Option<&LiveQuality> {
        self.quality.as_ref()
    }

    /// MotionCal's calibration packet for the latest fit, remembered as sent so that the
    /// device's echoes can confirm it; `None` before the first fit.
    pub fn packet_for_device(&mut self) -> Option<[u8; MOTIONCAL_PACKET_LEN]> {
        let calibration = self.quality.as_ref()?.calibration;
        Some(self.packet_for(calibration))
    }

    /// MotionCal's packet for any calibration (a saved one), remembered as sent.
    pub fn packet_for(&mut self, calibration: FieldCalibration) -> [u8; MOTIONCAL_PACKET_LEN] {
        self.sent = Some(Sent {
            calibration,
            n_echoes_before: self.reader.echoes().len(),
        });
        motioncal_packet(&calibration)
    }

    /// Whether the device echoed back what was sent: the first `Cal1:` and the first
    /// `Cal2:` after the packet went out are compared with it.
    pub fn confirmation(&self) -> Confirmation {
        let Some(sent) = &self.sent else {
            return Confirmation::NotSent;
        };
        let echoes = self
            .reader
            .echoes()
            .get(sent.n_echoes_before..)
            .unwrap_or_default();
        let first = |kind: EchoKind| echoes.iter().find(|seen| seen.echo.kind == kind);
        let (Some(cal1), Some(cal2)) = (first(EchoKind::Cal1), first(EchoKind::Cal2)) else {
            return Confirmation::Waiting;
        };
        let last_line = cal1.line.max(cal2.line);
        match echo_difference(&sent.calibration, cal1, cal2) {
            None => Confirmation::Confirmed { line: last_line },
            Some(what) => Confirmation::Differs {
                line: last_line,
                what,
            },
        }
    }

    /// Adds the reader's new magnetometer samples to the fit and the kept samples.
    fn take_new_samples(&mut self) {
        let mag_in_body = &self.reader.recording().mag_in_body_ut.values;
        let new = mag_in_body.get(self.n_mag_used..).unwrap_or_default();
        for &v_in_body in new {
            let v_in_sensor = sensor_to_body(v_in_body);
            self.accumulator.add(v_in_sensor);
            if self.n_mag_used.is_multiple_of(self.kept_stride) {
                self.kept_ut.push(v_in_sensor);
                if self.kept_ut.len() >= MAX_KEPT_SAMPLES {
                    // Keep every second one; later samples are kept at the new stride,
                    // so the kept ones stay evenly spread over the session.
                    let mut idx = 0usize;
                    self.kept_ut.retain(|_| {
                        idx += 1;
                        idx % 2 == 1
                    });
                    self.kept_stride *= 2;
                }
            }
            self.n_mag_used += 1;
        }
        if let (Some(attitude), Some(quality)) = (&mut self.attitude, &self.quality) {
            attitude.take(self.reader.recording(), &quality.calibration);
        }
    }

    fn measure(
        &self,
        calibration: FieldCalibration,
        model: EllipsoidModel,
        n_samples: usize,
    ) -> LiveQuality {
        let magnitudes: Vec<f64> = self
            .kept_ut
            .iter()
            .map(|&raw_ut| calibration.apply(raw_ut).norm())
            .filter(|magnitude| magnitude.is_finite())
            .collect();
        let n = magnitudes.len().max(1) as f64;
        let residual_rms_ut = (magnitudes
            .iter()
            .map(|magnitude| (magnitude - calibration.field_ut).powi(2))
            .sum::<f64>()
            / n)
            .sqrt();
        let field_spread_pct =
            crate::stats::spread_pct(magnitudes.iter().copied()).unwrap_or(f64::NAN);
        let coverage = sphere_coverage(
            self.kept_ut
                .iter()
                .map(|&raw_ut| sensor_to_body(calibration.apply(raw_ut))),
        );
        let field_difference_pct = self
            .expected_field_ut
            .map(|expected_ut| 100.0 * (calibration.field_ut - expected_ut) / expected_ut);
        let verdict = field_verdict(
            n_samples,
            &coverage,
            field_spread_pct,
            self.expected_field_ut,
            calibration.field_ut,
        );
        LiveQuality {
            calibration,
            model,
            n_samples,
            residual_rms_ut,
            field_spread_pct,
            coverage,
            expected_field_ut: self.expected_field_ut,
            field_difference_pct,
            verdict,
        }
    }
}

const NMEA_LABEL: &str = "NMEA 0183 sentences (headings and fixes, no magnetometer vector to \
                          calibrate: the stream is recorded; download it and drop it on the \
                          page to analyse it)";

/// The verdict on a fit: each unmet condition is a reason that says what to do. A
/// dropped file without a reference heading is judged by it too ([`crate::verdict`]).
pub fn field_verdict(
    n_samples: usize,
    coverage: &SphereCoverage,
    field_spread_pct: f64,
    expected_field_ut: Option<f64>,
    field_ut: f64,
) -> Verdict {
    let mut reasons = Vec::new();
    if n_samples < GOOD_MIN_SAMPLES {
        reasons.push(format!(
            "only {n_samples} samples; at least {GOOD_MIN_SAMPLES} are needed. Keep turning the device."
        ));
    }
    if coverage.gap_pct >= GOOD_MAX_GAP_PCT {
        let advice = coverage
            .largest_gap
            .map_or(String::new(), |gap| format!(": {}", gap.advice()));
        reasons.push(format!(
            "{:.0} % of the sphere of directions is still missing (under {GOOD_MAX_GAP_PCT:.0} % is needed){advice}",
            coverage.gap_pct
        ));
    }
    // NaN (no spread measured) is not good enough either.
    if field_spread_pct.is_nan() || field_spread_pct >= GOOD_MAX_SPREAD_PCT {
        reasons.push(format!(
            "the corrected field still varies by {field_spread_pct:.1} % (under {GOOD_MAX_SPREAD_PCT:.0} % is needed): \
             move away from metal and magnets, and turn the device slowly"
        ));
    }
    if let Some(expected_ut) = expected_field_ut {
        let difference_pct = 100.0 * (field_ut - expected_ut) / expected_ut;
        if difference_pct.is_nan() || difference_pct.abs() >= GOOD_MAX_FIELD_DIFFERENCE_PCT {
            reasons.push(format!(
                "the fitted field is {field_ut:.1} µT, {difference_pct:+.0} % from the {expected_ut:.1} µT the World \
                 Magnetic Model gives here: check the sensor's range and units, and move away from magnetic objects"
            ));
        }
    }
    Verdict {
        good_enough: reasons.is_empty(),
        reasons,
    }
}

fn describe_fit_error(error: &EllipsoidError) -> String {
    format!("No fit yet: {error}")
}

/// The first echoed value that differs from the calibration sent, named for the user;
/// `None` when all match.
fn echo_difference(sent: &FieldCalibration, cal1: &EchoSeen, cal2: &EchoSeen) -> Option<String> {
    let close = |echoed: f64, sent: f64| {
        (echoed - sent).abs() <= ECHO_ABS_TOLERANCE + ECHO_REL_TOLERANCE * sent.abs()
    };
    let Some(hard_iron_ut) = cal1.echo.mag_hard_iron_in_sensor_ut else {
        return Some(format!("line {}: Cal1 has no hard iron", cal1.line));
    };
    for (axis, (echoed, expected)) in ["x", "y", "z"]
        .iter()
        .zip(hard_iron_ut.iter().zip(sent.hard_iron_ut.iter()))
    {
        if !close(*echoed, *expected) {
            return Some(format!(
                "line {}: hard iron {axis} is {echoed:.3} µT, {expected:.3} µT was sent",
                cal1.line
            ));
        }
    }
    match cal1.echo.mag_field_ut {
        Some(field_ut) if close(field_ut, sent.field_ut) => {}
        other => {
            return Some(format!(
                "line {}: field strength is {}, {:.3} µT was sent",
                cal1.line,
                other.map_or("missing".to_string(), |ut| format!("{ut:.3} µT")),
                sent.field_ut
            ))
        }
    }
    let Some(soft_iron) = cal2.echo.mag_soft_iron else {
        return Some(format!("line {}: Cal2 has no soft-iron matrix", cal2.line));
    };
    // The packet carries the symmetric part; the device echoes the full matrix.
    let sent_symmetric = (sent.soft_iron + sent.soft_iron.transpose()) * 0.5;
    for row in 0..3 {
        for column in 0..3 {
            let (echoed, expected) = (soft_iron[(row, column)], sent_symmetric[(row, column)]);
            if !close(echoed, expected) {
                return Some(format!(
                    "line {}: soft iron [{row}][{column}] is {echoed:.4}, {expected:.4} was sent",
                    cal2.line
                ));
            }
        }
    }
    None
}

/// A fitted session of a board turned through `share` of the sphere from its top (a
/// Fibonacci spiral of `n_samples` MotionCal `Raw:` lines, hard iron (100, −50, 300)
/// counts), for the plots' tests.
#[cfg(test)]
pub(crate) fn turned_session(n_samples: usize, share: f64) -> (LiveSession, LiveQuality) {
    let mut session = LiveSession::new();
    let mut text = String::new();
    for idx in 0..n_samples {
        let z = 1.0 - 2.0 * share * (idx as f64 + 0.5) / n_samples as f64;
        let azimuth = idx as f64 * 2.399_963;
        let r = (1.0 - z * z).sqrt();
        text.push_str(&format!(
            "Raw:0,0,8192,0,0,0,{:.0},{:.0},{:.0}\n",
            480.0 * r * azimuth.cos() + 100.0,
            480.0 * r * azimuth.sin() - 50.0,
            480.0 * z + 300.0
        ));
    }
    session.feed(text.as_bytes(), 0.0);
    let quality = session.refit().expect("a sphere fits").clone();
    (session, quality)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calib::export::parse_motioncal_packet;
    use crate::sim::rng::SplitMix64;
    use nalgebra::Matrix3;

    /// A distorted sensor (sensor axes, µT) and MotionCal `Raw:` lines of it turned
    /// over the whole sphere.
    struct Board {
        hard_iron_ut: Vector3<f64>,
        distortion: Matrix3<f64>,
        field_ut: f64,
    }

    impl Board {
        fn new() -> Self {
            Board {
                hard_iron_ut: Vector3::new(12.0, -7.5, 30.0),
                distortion: Matrix3::new(1.08, 0.03, -0.02, 0.03, 0.95, 0.01, -0.02, 0.01, 1.02),
                field_ut: 48.0,
            }
        }

        /// Line `idx` of a sweep: directions spread over the sphere (a spiral), with
        /// 0.2 µT of noise, as MotionCal counts (0.1 µT) and gravity along z.
        fn raw_line(&self, idx: usize, n: usize, rng: &mut SplitMix64) -> String {
            let z = 1.0 - 2.0 * (idx as f64 + 0.5) / n as f64;
            let azimuth = idx as f64 * 2.399_963;
            let r = (1.0 - z * z).sqrt();
            let true_ut = self.field_ut * Vector3::new(r * azimuth.cos(), r * azimuth.sin(), z);
            let noise = Vector3::new(rng.gaussian(), rng.gaussian(), rng.gaussian()) * 0.2;
            let measured = self.distortion * true_ut + self.hard_iron_ut + noise;
            format!(
                "Raw:0,0,8192,0,0,0,{},{},{}\r\n",
                (measured.x * 10.0).round(),
                (measured.y * 10.0).round(),
                (measured.z * 10.0).round()
            )
        }
    }

    fn streamed(board: &Board, n: usize, chunk_len: usize) -> (LiveSession, Vec<u8>) {
        let mut rng = SplitMix64::new(3);
        let text: String = (0..n).map(|idx| board.raw_line(idx, n, &mut rng)).collect();
        let bytes = text.into_bytes();
        let mut session = LiveSession::new();
        for (chunk_idx, chunk) in bytes.chunks(chunk_len).enumerate() {
            session.feed(chunk, chunk_idx as f64 * 0.01);
        }
        (session, bytes)
    }

    #[test]
    fn a_sweep_streamed_in_odd_chunks_is_kept_whole_and_calibrates_the_board() {
        let board = Board::new();
        let (mut session, bytes) = streamed(&board, 3000, 37);
        assert_eq!(session.raw(), bytes.as_slice());
        let counts = session.counts();
        assert_eq!(counts.n_lines, 3000);
        // The last reading waits for the next line (a `Uni:` line may replace it).
        assert_eq!(counts.n_mag_samples, 2999);
        assert_eq!(counts.n_skipped_lines, 0);
        assert_eq!(counts.format, Some("MotionCal Raw: counts"));
        session.set_expected_field(Some(48.0));
        let quality = session
            .refit()
            .expect("3000 samples over the sphere fit")
            .clone();
        let calibration = quality.calibration;
        assert!(
            (calibration.hard_iron_ut - board.hard_iron_ut).norm() < 0.2,
            "{:?}",
            calibration.hard_iron_ut
        );
        // The correction undoes the distortion up to the field's scale.
        let undone =
            calibration.soft_iron * board.distortion * (board.field_ut / calibration.field_ut);
        assert!((undone - Matrix3::identity()).amax() < 0.01, "{undone}");
        assert!(
            quality.field_spread_pct < 1.0,
            "{}",
            quality.field_spread_pct
        );
        assert!(
            quality.coverage.gap_pct < 1.0,
            "{}",
            quality.coverage.gap_pct
        );
        assert!(quality.verdict.good_enough, "{:?}", quality.verdict);
        // Exported as fitted: the board's axes as printed, µT.
        let exported = quality.sensor_calibration();
        assert_eq!(exported.hard_iron, calibration.hard_iron_ut);
        assert_eq!(exported.frame.unit, MagUnit::MICROTESLA);
        assert_eq!(
            exported.frame.axes,
            crate::io::frame::SENSOR_AXES_AS_PRINTED
        );
        // The fitted field is the distorted ellipsoid's mean radius: within a few
        // percent of the true 48 µT (the distortion's determinant is 1.047).
        let difference_pct = quality
            .field_difference_pct
            .expect("an expected field was given");
        assert!(difference_pct.abs() < 3.0, "{difference_pct}");
    }

    #[test]
    fn half_a_sphere_is_not_good_enough_and_says_where_to_turn() {
        let board = Board::new();
        let mut rng = SplitMix64::new(4);
        let mut session = LiveSession::new();
        // Only the upper half of the sweep's directions (z > 0).
        let text: String = (0..1500)
            .map(|idx| board.raw_line(idx, 3000, &mut rng))
            .collect();
        session.feed(text.as_bytes(), 0.0);
        let verdict = match session.refit() {
            Ok(quality) => quality.verdict.clone(),
            Err(message) => panic!("{message}"),
        };
        assert!(!verdict.good_enough);
        assert!(
            verdict
                .reasons
                .iter()
                .any(|reason| reason.contains("sphere of directions")),
            "{verdict:?}"
        );
    }

    #[test]
    fn too_few_samples_say_how_many_are_needed() {
        let board = Board::new();
        let (mut session, _) = streamed(&board, 20, 64);
        let message = session.refit().expect_err("20 samples are too few");
        assert!(message.contains("needs 50"), "{message}");
    }

    #[test]
    fn bad_lines_are_counted_and_listed_not_lost() {
        let mut session = LiveSession::new();
        session.feed(b"hello\nRaw:1,2,3\nRaw:0,0,8192,0,0,0,100,2", 0.0);
        session.feed(b"00,300\nRaw:0,0,8192,0,0,0,1,2,3\n", 0.1);
        let counts = session.counts();
        assert_eq!(counts.n_lines, 4);
        assert_eq!(counts.n_mag_samples, 1);
        assert_eq!(counts.n_skipped_lines, 2);
        let lines: Vec<Option<usize>> = session.diagnostics().kept.iter().map(|d| d.line).collect();
        assert_eq!(lines, vec![Some(1), Some(2)]);
        let latest = session.latest_mag_ut().expect("one reading");
        assert!(
            (latest - Vector3::new(10.0, 20.0, 30.0)).norm() < 1e-9,
            "{latest}"
        );
    }

    #[test]
    fn the_packet_is_motioncal_s_and_the_echo_confirms_it() {
        let board = Board::new();
        let (mut session, _) = streamed(&board, 2000, 512);
        assert_eq!(session.confirmation(), Confirmation::NotSent);
        session.refit().expect("fits");
        let packet = session.packet_for_device().expect("a fit was made");
        assert_eq!(packet.len(), 68);
        let sent = parse_motioncal_packet(&packet).expect("our own packet reads back");
        assert_eq!(session.confirmation(), Confirmation::Waiting);
        // The device echoes the float32 values it stored, as the Adafruit sketch prints.
        let h = sent.hard_iron_ut;
        let s = sent.soft_iron;
        let cal1 = format!(
            "Cal1:0.000,0.000,0.000,0.000,0.000,0.000,{:.3},{:.3},{:.3},{:.3}\n",
            h.x, h.y, h.z, sent.field_ut
        );
        let cal2 = format!(
            "Cal2:{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4}\n",
            s[(0, 0)],
            s[(0, 1)],
            s[(0, 2)],
            s[(1, 0)],
            s[(1, 1)],
            s[(1, 2)],
            s[(2, 0)],
            s[(2, 1)],
            s[(2, 2)]
        );
        session.feed(cal1.as_bytes(), 30.0);
        assert_eq!(session.confirmation(), Confirmation::Waiting);
        session.feed(cal2.as_bytes(), 30.1);
        assert_eq!(
            session.confirmation(),
            Confirmation::Confirmed { line: 2002 }
        );
        // An echo of another calibration is named.
        session.packet_for_device();
        session.feed(b"Cal1:0,0,0,0,0,0,1.000,2.000,3.000,50.000\n", 31.0);
        session.feed(cal2.as_bytes(), 31.1);
        match session.confirmation() {
            Confirmation::Differs { what, .. } => assert!(what.contains("hard iron x"), "{what}"),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn a_line_cut_by_an_unplug_does_not_join_the_next_port_s_first_line() {
        let mut session = LiveSession::new();
        let (first_port, second_port): (&[u8], &[u8]) = (
            b"Raw:0,0,8192,0,0,0,100,200,300\nRaw:0,0,81",
            b"Raw:0,0,8192,0,0,0,1,2,3\nRaw:0,0,8192,0,0,0,4,5,6\n",
        );
        session.feed(first_port, 0.0);
        session.port_closed();
        session.feed(second_port, 1.0);
        let counts = session.counts();
        assert_eq!(counts.n_lines, 4);
        assert_eq!(counts.n_skipped_lines, 1);
        assert_eq!(
            counts.n_mag_samples, 2,
            "the last reading waits for the next line"
        );
        assert_eq!(
            session.diagnostics().kept.first().and_then(|d| d.line),
            Some(2)
        );
        session.port_closed();
        assert_eq!(
            session.counts().n_mag_samples,
            3,
            "a closed port's last reading is taken"
        );
        assert_eq!(session.raw(), [first_port, second_port].concat().as_slice());
    }

    #[test]
    fn an_nmea_stream_is_named_and_recorded() {
        let mut session = LiveSession::new();
        let lines = "$HCHDG,98.3,0.0,E,12.6,W*57\r\n$HCHDG,99.1,0.0,E,12.6,W*54\r\n$HCHDG,100.0,0.0,E,12.6,W*64\r\n";
        session.feed(lines.as_bytes(), 0.0);
        let counts = session.counts();
        assert_eq!(counts.n_lines, 3);
        assert!(
            counts
                .format
                .is_some_and(|format| format.starts_with("NMEA 0183")),
            "{counts:?}"
        );
        assert_eq!(session.raw(), lines.as_bytes());
    }

    /// Ten minutes at 1,000 lines/s, in the chunks a port delivers every 10 ms: every
    /// line counted, memory for the fit bounded, refits as cheap as at the start.
    #[test]
    fn ten_minutes_at_a_thousand_lines_a_second_stay_bounded() {
        let board = Board::new();
        let mut rng = SplitMix64::new(9);
        let mut session = LiveSession::new();
        let n_lines = 600_000;
        let mut n_bytes = 0;
        for tick in 0..n_lines / 10 {
            let chunk: String = (0..10)
                .map(|k| board.raw_line((tick * 10 + k) % 20_000, 20_000, &mut rng))
                .collect();
            n_bytes += chunk.len();
            session.feed(chunk.as_bytes(), tick as f64 * 0.01);
            if tick % 50 == 0 {
                // The page refits every 500 ms.
                let _ = session.refit();
            }
        }
        let counts = session.counts();
        assert_eq!(counts.n_lines, n_lines);
        assert_eq!(counts.n_bytes, n_bytes);
        assert_eq!(counts.n_mag_samples, n_lines - 1);
        assert!(session.kept_samples_ut().len() < MAX_KEPT_SAMPLES);
        let quality = session.refit().expect("fits");
        assert!(quality.verdict.good_enough, "{:?}", quality.verdict);
        assert!((quality.calibration.hard_iron_ut - board.hard_iron_ut).norm() < 0.1);
    }

    #[test]
    fn thinning_keeps_the_session_evenly() {
        let board = Board::new();
        let (session, _) = streamed(&board, 40_000, 4096);
        let kept = session.kept_samples_ut().len();
        assert!(
            (MAX_KEPT_SAMPLES / 2..MAX_KEPT_SAMPLES).contains(&kept),
            "{kept}"
        );
        assert_eq!(session.counts().n_mag_samples, 39_999);
    }
}
