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
//! Eq. 5 after Li and Griffiths 2004), so a refit costs the same after ten samples or a
//! million. [`LiveSession::refit`] solves it and measures the fit on an evenly thinned
//! copy of the samples (at most [`MAX_KEPT_SAMPLES`]): the residual RMS of
//! `|corrected| − B`, the spread of `|corrected|`, the sphere coverage as MotionCal
//! counts it ([`sphere_coverage`], 100 equal-area regions, "gaps" under 15 %), and,
//! when the page knows where the user is, the fitted field against the World Magnetic
//! Model's. [`LiveQuality::verdict`] says whether the calibration is good enough to
//! send, or why not.
//!
//! Before anything is sent, [`send_check`] applies the project's rule for every
//! write-back: the samples are split into train and check blocks, and the fit (and a
//! fit of the train blocks alone) must leave |B| varying clearly less on the check
//! samples than the calibration in force (the one the board confirmed, else the one
//! sent last, else the raw readings), and lie inside a device's acceptance bounds.
//! [`LiveQuality::send`] is the decision with its reasons.
//!
//! [`LiveSession::packet_for_device`] makes MotionCal's 68-byte calibration packet
//! ([`crate::fit::export::motioncal_packet`]) when the decision allows it, and
//! remembers what was sent; the `Cal1:`/`Cal2:` lines the device echoes afterwards
//! confirm it (or say which value differs). A saved calibration
//! ([`LiveSession::packet_for`]) goes through the same check on the session's samples.
//! Both live in `live/sending.rs`.
//!
//! [`LiveSession::port_closed`] ends a line cut by an unplug, so that the next port's
//! first line is its own, and takes the reading that was waiting for a possible `Uni:`
//! line. A board that also prints a gyroscope and an accelerometer gets the attitude
//! filter's heading as the dial's second needle (`live/attitude.rs`).
//!
//! No clock here: the page passes each chunk's arrival time.

mod attitude;
pub mod send_check;
mod sending;

use nalgebra::Vector3;
use serde::Serialize;
use thiserror::Error;

use crate::attitude::tilt::Tilt;
use crate::fit::coverage::{sphere_coverage, SphereCoverage};
use crate::fit::export::SensorCalibration;
use crate::fit::model::FieldCalibration;
use crate::fit::quality::{field_verdict, FieldVerdict};
use crate::fit::streaming_ellipsoid::{EllipsoidAccumulator, EllipsoidError, EllipsoidModel};
use crate::io::lines::LineDecoder;
use crate::io::serial_lines::{sensor_to_body, LineFormat, SerialReader};
use crate::io::{nmea, Diagnostics, MagUnit, SensorFrame};
pub use send_check::{HeldBack, InForce, InForceSource, SendDecision};
pub use sending::Confirmation;

/// Lines longer than this are cut and reported (no sensor line is near it).
const MAX_LINE_BYTES: usize = 4096;

/// At most this many samples are kept for the quality figures and the plots: every
/// sample until then, afterwards every second one, and so on (an even thinning over the
/// whole session, so a long session costs no more to assess than a short one).
pub const MAX_KEPT_SAMPLES: usize = 16_384;

/// The fewest magnetometer samples a refit is tried on.
pub const MIN_FIT_SAMPLES: usize = 50;

/// Why [`LiveSession::refit`] made no fit; the message says what to do.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum RefitError {
    /// Fewer than `min` ([`MIN_FIT_SAMPLES`]) magnetometer samples so far.
    #[error(
        "{n_samples} magnetometer samples so far; the first fit needs {min}. Keep turning the \
         device."
    )]
    TooFewSamples { n_samples: usize, min: usize },
    /// The ellipsoid could not be fitted (all samples in a plane, …).
    #[error("No fit yet: {0}")]
    Fit(#[from] EllipsoidError),
}

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
    sent: Option<sending::Sent>,
    /// The last calibration the board confirmed before the one in `sent` went out.
    confirmed_before: Option<FieldCalibration>,
    /// `sent` and `confirmed_before` before the last packet, for a write that failed.
    before_send: Option<(Option<sending::Sent>, Option<FieldCalibration>)>,
    /// The samples split into train and check blocks, for the held-back check.
    blocks: send_check::Blocks,
    /// The attitude filter, from the first fit on, for a stream with a gyroscope.
    attitude: Option<attitude::LiveAttitude>,
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
    pub verdict: FieldVerdict,
    /// The fit against the calibration in force on the held-back samples.
    pub held_back: HeldBack,
    /// Whether it may be sent: good enough, better than the calibration in force on the
    /// held-back samples, inside the bounds.
    pub send: SendDecision,
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
            confirmed_before: None,
            before_send: None,
            blocks: send_check::Blocks::new(),
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
        // An echo may have confirmed what was sent: the calibration in force changed.
        if self
            .quality
            .as_ref()
            .is_some_and(|quality| quality.held_back.in_force != self.in_force())
        {
            self.reassess();
        }
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
        Some(crate::attitude::compass_heading::heading_rad(level, 0.0))
    }

    /// Refits from every sample so far and measures the fit. `Err` says why no fit is
    /// possible yet (too few samples, or all in a plane) and what to do.
    pub fn refit(&mut self) -> Result<&LiveQuality, RefitError> {
        let n_samples = self.accumulator.n_samples();
        if n_samples < MIN_FIT_SAMPLES {
            return Err(RefitError::TooFewSamples {
                n_samples,
                min: MIN_FIT_SAMPLES,
            });
        }
        let fit = self.accumulator.solve(EllipsoidModel::Auto, None)?;
        // The train blocks alone, with the full fit's model, for the held-back check.
        let train = self
            .blocks
            .train()
            .solve(fit.model, None)
            .map(|train| train.calibration);
        let quality = self.measure(fit.calibration, fit.model, n_samples, train);
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

    /// Adds the reader's new magnetometer samples to the fit and the kept samples.
    fn take_new_samples(&mut self) {
        let mag_in_body = &self.reader.recording().mag_in_body_ut.values;
        let new = mag_in_body.get(self.n_mag_used..).unwrap_or_default();
        for &v_in_body in new {
            let v_in_sensor = sensor_to_body(v_in_body);
            self.accumulator.add(v_in_sensor);
            self.blocks.add(v_in_sensor);
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
        train: Result<FieldCalibration, EllipsoidError>,
    ) -> LiveQuality {
        let measured = self.measure_only(&calibration);
        let held_back = HeldBack::assess(
            &self.blocks,
            &calibration,
            Some(train),
            self.in_force(),
            self.expected_field_ut,
        );
        let send = SendDecision::of(
            &measured.verdict,
            &held_back,
            &calibration,
            self.expected_field_ut,
        );
        LiveQuality {
            calibration,
            model,
            n_samples,
            residual_rms_ut: measured.residual_rms_ut,
            field_spread_pct: measured.field_spread_pct,
            coverage: measured.coverage,
            expected_field_ut: self.expected_field_ut,
            field_difference_pct: measured.field_difference_pct,
            verdict: measured.verdict,
            held_back,
            send,
        }
    }

    /// A calibration on the kept samples, judged by the live verdict.
    fn measure_only(&self, calibration: &FieldCalibration) -> Measured {
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
            crate::base::stats::spread_pct(magnitudes.iter().copied()).unwrap_or(f64::NAN);
        let coverage = sphere_coverage(
            self.kept_ut
                .iter()
                .map(|&raw_ut| sensor_to_body(calibration.apply(raw_ut))),
        );
        let field_difference_pct = self
            .expected_field_ut
            .map(|expected_ut| 100.0 * (calibration.field_ut - expected_ut) / expected_ut);
        let verdict = field_verdict(
            self.accumulator.n_samples(),
            &coverage,
            field_spread_pct,
            self.expected_field_ut,
            calibration.field_ut,
        );
        Measured {
            residual_rms_ut,
            field_spread_pct,
            coverage,
            field_difference_pct,
            verdict,
        }
    }
}

/// A calibration's figures on the kept samples (see [`LiveQuality`]).
struct Measured {
    residual_rms_ut: f64,
    field_spread_pct: f64,
    coverage: SphereCoverage,
    field_difference_pct: Option<f64>,
    verdict: FieldVerdict,
}

const NMEA_LABEL: &str = "NMEA 0183 sentences (headings and fixes, no magnetometer vector to \
                          calibrate: the stream is recorded; download it and drop it on the \
                          page to analyse it)";

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
mod tests;
