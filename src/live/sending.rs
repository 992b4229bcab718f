//! Sending a calibration to the board and hearing back: MotionCal's packet made only
//! when [`super::send_check`]'s rule allows it (the latest fit, or a saved calibration
//! judged on the session's samples), the calibration in force (the one the board
//! confirmed, else the one sent last, else its raw readings), and the board's
//! `Cal1:`/`Cal2:` echoes compared with what was sent.

use serde::Serialize;

use super::send_check::{HeldBack, InForce, InForceSource, SendDecision};
use super::LiveSession;
use crate::fit::export::{motioncal_packet, MOTIONCAL_PACKET_LEN};
use crate::fit::model::FieldCalibration;
use crate::io::serial_lines::{EchoKind, EchoSeen};

/// An echoed value matches the one sent within this (the sketch prints `Cal1:` with 3
/// decimals and `Cal2:` with 4; float32 adds a few 10⁻⁶ relative).
const ECHO_ABS_TOLERANCE: f64 = 6e-4;
const ECHO_REL_TOLERANCE: f64 = 1e-5;

#[derive(Debug, Clone, Copy)]
pub(super) struct Sent {
    pub(super) calibration: FieldCalibration,
    /// Echoes seen before the packet went out (those cannot confirm it).
    pub(super) n_echoes_before: usize,
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

/// What to do before anything can be sent.
const NO_FIT_YET: &str = "no calibration yet: keep turning the device";

impl LiveSession {
    /// MotionCal's calibration packet for the latest fit, remembered as sent so that
    /// the device's echoes can confirm it, when [`super::LiveQuality::send`] allows it;
    /// otherwise the reasons (nothing is sent, the calibration in force is kept).
    pub fn packet_for_device(&mut self) -> Result<[u8; MOTIONCAL_PACKET_LEN], Vec<String>> {
        let Some(quality) = self.quality.as_ref() else {
            return Err(vec![NO_FIT_YET.to_string()]);
        };
        if !quality.send.sendable {
            return Err(quality.send.reasons.clone());
        }
        Ok(self.remember_sent(quality.calibration))
    }

    /// MotionCal's packet for a saved calibration, remembered as sent, when
    /// [`decision_for`](Self::decision_for) allows it; otherwise the reasons.
    pub fn packet_for(
        &mut self,
        calibration: FieldCalibration,
    ) -> Result<[u8; MOTIONCAL_PACKET_LEN], Vec<String>> {
        let decision = self.decision_for(&calibration);
        if !decision.sendable {
            return Err(decision.reasons);
        }
        Ok(self.remember_sent(calibration))
    }

    /// Whether a saved calibration may be sent: judged on this session's samples by the
    /// live verdict's conditions, better than the calibration in force on the held-back
    /// samples, and inside the bounds.
    pub fn decision_for(&self, calibration: &FieldCalibration) -> SendDecision {
        let measured = self.measure_only(calibration);
        let held_back = HeldBack::assess(
            &self.blocks,
            calibration,
            None,
            self.in_force(),
            self.expected_field_ut,
        );
        SendDecision::of(
            &measured.verdict,
            &held_back,
            calibration,
            self.expected_field_ut,
        )
    }

    /// The calibration in force on the board: the last one it confirmed, else the last
    /// one sent, else its raw readings.
    pub fn in_force(&self) -> InForce {
        let confirmed = |calibration| InForce {
            source: InForceSource::Confirmed,
            calibration,
        };
        match (&self.sent, self.confirmation()) {
            (Some(sent), Confirmation::Confirmed { .. }) => confirmed(sent.calibration),
            (Some(sent), _) => self.confirmed_before.map_or(
                InForce {
                    source: InForceSource::Sent,
                    calibration: sent.calibration,
                },
                confirmed,
            ),
            (None, _) => InForce::raw(),
        }
    }

    /// The port did not take the packet: what was in force before it is in force again.
    pub fn send_failed(&mut self) {
        if let Some((sent, confirmed_before)) = self.before_send.take() {
            self.sent = sent;
            self.confirmed_before = confirmed_before;
            self.reassess();
        }
    }

    fn remember_sent(&mut self, calibration: FieldCalibration) -> [u8; MOTIONCAL_PACKET_LEN] {
        self.before_send = Some((self.sent, self.confirmed_before));
        // The board keeps what it confirmed until it confirms the next one.
        let in_force = self.in_force();
        if in_force.source == InForceSource::Confirmed {
            self.confirmed_before = Some(in_force.calibration);
        }
        self.sent = Some(Sent {
            calibration,
            n_echoes_before: self.reader.echoes().len(),
        });
        self.reassess();
        motioncal_packet(&calibration)
    }

    /// The latest fit's held-back check and decision again, against the calibration in
    /// force now.
    pub(super) fn reassess(&mut self) {
        let in_force = self.in_force();
        let Some(quality) = self.quality.as_mut() else {
            return;
        };
        let held_back = &quality.held_back;
        let train = match (held_back.train_calibration, &held_back.train_error) {
            (Some(calibration), _) => Some(Ok(calibration)),
            (None, Some(error)) => Some(Err(error.clone())),
            (None, None) => None,
        };
        quality.held_back = HeldBack::assess(
            &self.blocks,
            &quality.calibration,
            train,
            in_force,
            quality.expected_field_ut,
        );
        quality.send = SendDecision::of(
            &quality.verdict,
            &quality.held_back,
            &quality.calibration,
            quality.expected_field_ut,
        );
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
