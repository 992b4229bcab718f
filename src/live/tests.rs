//! The live session's tests: streaming, fitting, the packet and its echo, bounds on memory.

use super::*;
use crate::base::rng::SplitMix64;
use crate::fit::export::parse_motioncal_packet;
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
    let undone = calibration.soft_iron * board.distortion * (board.field_ut / calibration.field_ut);
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

/// A session fed only the upper half of the sweep's directions (z > 0).
fn half_sphere_session() -> LiveSession {
    let board = Board::new();
    let mut rng = SplitMix64::new(4);
    let mut session = LiveSession::new();
    let text: String = (0..1500)
        .map(|idx| board.raw_line(idx, 3000, &mut rng))
        .collect();
    session.feed(text.as_bytes(), 0.0);
    session
}

#[test]
fn half_a_sphere_is_not_good_enough_and_says_where_to_turn() {
    let mut session = half_sphere_session();
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
    let error = session.refit().expect_err("20 samples are too few");
    let &RefitError::TooFewSamples { n_samples, min: 50 } = &error else {
        panic!("{error:?}");
    };
    assert_eq!(
        error.to_string(),
        format!(
            "{n_samples} magnetometer samples so far; the first fit needs 50. Keep turning the \
             device."
        )
    );
}

#[test]
fn a_device_held_still_gets_no_fit_and_is_told_to_turn() {
    let mut session = LiveSession::new();
    session.feed("Raw:0,0,8192,0,0,0,100,2,300\n".repeat(60).as_bytes(), 0.0);
    let error = session.refit().expect_err("one direction does not fit");
    assert!(
        matches!(error, RefitError::Fit(EllipsoidError::NoRotation { .. })),
        "{error:?}"
    );
    assert_eq!(
        error.to_string(),
        "No fit yet: the samples hardly change (spread 0.00 µT): the device was not turned. \
         Record while turning it through many orientations."
    );
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

/// The `Cal1:`/`Cal2:` lines Adafruit's calibration sketch prints for a packet it
/// stored: the float32 values with 3 and 4 decimals.
fn echo_of(packet: &[u8]) -> String {
    let sent = parse_motioncal_packet(packet).expect("our own packet reads back");
    let h = sent.hard_iron_ut;
    let s = sent.soft_iron;
    format!(
        "Cal1:0.000,0.000,0.000,0.000,0.000,0.000,{:.3},{:.3},{:.3},{:.3}\n\
         Cal2:{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4}\n",
        h.x,
        h.y,
        h.z,
        sent.field_ut,
        s[(0, 0)],
        s[(0, 1)],
        s[(0, 2)],
        s[(1, 0)],
        s[(1, 1)],
        s[(1, 2)],
        s[(2, 0)],
        s[(2, 1)],
        s[(2, 2)]
    )
}

#[test]
fn the_packet_is_motioncal_s_and_the_echo_confirms_it() {
    let board = Board::new();
    let (mut session, _) = streamed(&board, 2000, 512);
    assert_eq!(session.confirmation(), Confirmation::NotSent);
    session.refit().expect("fits");
    let packet = session.packet_for_device().expect("a good fit is sent");
    assert_eq!(packet.len(), 68);
    assert_eq!(session.confirmation(), Confirmation::Waiting);
    let echo = echo_of(&packet);
    let (cal1, cal2) = echo.split_at(echo.find("Cal2").expect("two lines"));
    session.feed(cal1.as_bytes(), 30.0);
    assert_eq!(session.confirmation(), Confirmation::Waiting);
    session.feed(cal2.as_bytes(), 30.1);
    assert_eq!(
        session.confirmation(),
        Confirmation::Confirmed { line: 2002 }
    );

    // An echo of another calibration is named.
    let (mut session, _) = streamed(&board, 2000, 512);
    session.refit().expect("fits");
    session.packet_for_device().expect("a good fit is sent");
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

/// A second sweep of the same board: other noise, the spiral turned by a quarter.
fn second_sweep(board: &Board, n: usize) -> String {
    let mut rng = SplitMix64::new(11);
    (0..n)
        .map(|idx| board.raw_line((idx + n / 4) % n, n, &mut rng))
        .collect()
}

fn fitted(session: &mut LiveSession) -> LiveQuality {
    match session.refit() {
        Ok(quality) => quality.clone(),
        Err(message) => panic!("{message}"),
    }
}

fn any_reason(reasons: &[String], part: &str) -> bool {
    reasons.iter().any(|reason| reason.contains(part))
}

#[test]
fn a_good_session_beats_the_raw_readings_on_the_samples_held_back_and_is_sent() {
    let board = Board::new();
    let (mut session, _) = streamed(&board, 3000, 512);
    session.set_expected_field(Some(48.0));
    let quality = fitted(&mut session);
    let held_back = &quality.held_back;
    assert_eq!(held_back.in_force.source, InForceSource::Raw);
    // Blocks of 64 alternate: 1,472 of the 2,999 samples are held back.
    assert_eq!(held_back.n_check_samples, 1472);
    assert_eq!(held_back.n_train_samples, 2999 - 1472);
    let train = held_back.train.expect("the train blocks fit");
    assert!(train.better && held_back.candidate.better, "{held_back:?}");
    assert!(train.on_check.spread_pct < 1.0, "{train:?}");
    assert!(
        held_back.in_force_on_check.spread_pct > 20.0,
        "{held_back:?}"
    );
    // Two fits of one session differ by far less than the margin on the check samples.
    let relative =
        (train.on_check.spread_pct / held_back.candidate.on_check.spread_pct - 1.0).abs();
    assert!(relative < 0.01, "{relative}");
    assert!(quality.send.sendable, "{:?}", quality.send);
    assert!(
        held_back
            .summary()
            .starts_with("held back (1472 samples): |B| spread 0."),
        "{}",
        held_back.summary()
    );
    assert!(session.packet_for_device().is_ok());
    assert_eq!(session.in_force().source, InForceSource::Sent);
    assert!(!session
        .quality()
        .is_some_and(|quality| quality.send.sendable));
    // The port refused the packet: nothing is in force, and it may be sent again.
    session.send_failed();
    assert_eq!(session.in_force().source, InForceSource::Raw);
    assert_eq!(session.confirmation(), Confirmation::NotSent);
    assert!(session.packet_for_device().is_ok());
}

#[test]
fn a_session_that_has_not_covered_the_sphere_is_not_sent() {
    let mut session = half_sphere_session();
    let quality = fitted(&mut session);
    assert!(!quality.send.sendable);
    assert!(
        any_reason(&quality.send.reasons, "sphere of directions"),
        "{:?}",
        quality.send
    );
    let refused = session.packet_for_device().expect_err("not sent");
    assert_eq!(refused, quality.send.reasons);
    assert_eq!(session.confirmation(), Confirmation::NotSent);
    assert_eq!(session.in_force().source, InForceSource::Raw);
}

#[test]
fn after_a_confirmed_send_the_calibration_sent_is_in_force_and_a_refit_no_better_is_kept_back() {
    let board = Board::new();
    let (mut session, _) = streamed(&board, 3000, 512);
    let first = fitted(&mut session);
    let packet = session.packet_for_device().expect("a good fit is sent");
    // Sent, not yet echoed: in force as sent.
    assert_eq!(session.in_force().source, InForceSource::Sent);
    assert_eq!(session.in_force().calibration, first.calibration);
    session.feed(echo_of(&packet).as_bytes(), 30.0);
    assert!(matches!(
        session.confirmation(),
        Confirmation::Confirmed { .. }
    ));
    let in_force = session.in_force();
    assert_eq!(in_force.source, InForceSource::Confirmed);
    assert_eq!(in_force.calibration, first.calibration);
    // The decision follows the echo without a refit: the same fit is in force now.
    let quality = session.quality().expect("fitted");
    assert_eq!(quality.held_back.in_force, in_force);
    assert!(!quality.send.sendable);

    // Another sweep of the same board: a refit is as good as the one in force, no better.
    session.feed(second_sweep(&board, 3000).as_bytes(), 31.0);
    let quality = fitted(&mut session);
    assert!(quality.verdict.good_enough, "{:?}", quality.verdict);
    let held_back = &quality.held_back;
    let relative =
        held_back.candidate.on_check.spread_pct / held_back.in_force_on_check.spread_pct - 1.0;
    assert!(relative.abs() < 0.02, "{relative}");
    assert!(!quality.send.sendable);
    assert_eq!(quality.send.reasons.len(), 1, "{:?}", quality.send);
    assert!(
        any_reason(&quality.send.reasons, "not clearly less than the 0.")
            && any_reason(&quality.send.reasons, "the calibration the board confirmed")
            && any_reason(&quality.send.reasons, "Keep turning the device"),
        "{:?}",
        quality.send
    );
    assert_eq!(
        session.packet_for_device().expect_err("kept back"),
        quality.send.reasons
    );
    assert_eq!(session.in_force(), in_force, "nothing was sent");
}

#[test]
fn a_fit_better_than_a_poor_calibration_in_force_is_sent() {
    let board = Board::new();
    let (mut session, _) = streamed(&board, 3000, 512);
    let quality = fitted(&mut session);
    // A calibration 2 µT off in hard iron (good enough: |B| varies 2.3 %) was sent and
    // confirmed.
    let poor = FieldCalibration {
        hard_iron_ut: quality.calibration.hard_iron_ut + Vector3::new(2.0, 0.0, 0.0),
        ..quality.calibration
    };
    let packet = session
        .packet_for(poor)
        .expect("better than the raw readings");
    session.feed(echo_of(&packet).as_bytes(), 30.0);
    assert_eq!(session.in_force().source, InForceSource::Confirmed);
    let quality = fitted(&mut session);
    assert!(quality.send.sendable, "{:?}", quality.send);
    assert!(
        quality.held_back.in_force_on_check.spread_pct > 2.0,
        "{:?}",
        quality.held_back
    );
    session
        .packet_for_device()
        .expect("better than the one in force");
    // Until the board echoes the new one, the one it confirmed is in force.
    assert_eq!(session.in_force().source, InForceSource::Confirmed);
    assert_eq!(session.in_force().calibration, poor);
}

#[test]
fn a_saved_calibration_goes_through_the_same_check() {
    let board = Board::new();
    let (mut session, _) = streamed(&board, 3000, 512);
    session.set_expected_field(Some(48.0));
    let quality = fitted(&mut session);
    // The session's own fit, saved: better than the raw readings.
    assert!(session.decision_for(&quality.calibration).sendable);
    // No calibration at all: no better than the raw readings.
    let identity = InForce::raw().calibration;
    let decision = session.decision_for(&FieldCalibration {
        field_ut: 48.0,
        ..identity
    });
    assert!(!decision.sendable);
    assert!(
        any_reason(&decision.reasons, "the raw readings (nothing sent yet)"),
        "{decision:?}"
    );
    // An absurd soft iron: stretched 8 times along z.
    let stretched = FieldCalibration {
        soft_iron: quality.calibration.soft_iron
            * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, 8.0)),
        ..quality.calibration
    };
    let refused = session
        .packet_for(stretched)
        .expect_err("outside the bounds");
    assert!(any_reason(&refused, "stretches one axis"), "{refused:?}");
    assert_eq!(session.confirmation(), Confirmation::NotSent);
    // Without a session's samples nothing can be shown better.
    let refused = LiveSession::new()
        .packet_for(quality.calibration)
        .expect_err("no samples to check it on");
    assert!(any_reason(&refused, "held back"), "{refused:?}");
}
