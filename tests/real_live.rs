//! The live panel's write-back rule on real boards (`../shared/data`; skipped with a
//! message when it is absent): the HMC5883L of `hmc5883l-sphere` streamed as MotionCal
//! `Raw:` lines is sent once, and not again after its echo; the QMC5883L's soft iron, as
//! its author calibrated it, is inside the bounds.
#![cfg(not(target_arch = "wasm32"))]

mod common;

use common::shared_data;
use compass_pdr::fit::export::parse_motioncal_packet;
use compass_pdr::fit::model::FieldCalibration;
use compass_pdr::fit::quality::{acceptance_reasons, MAX_SOFT_IRON_AXIS_RATIO};
use compass_pdr::live::{InForceSource, LiveSession};
use nalgebra::{Matrix3, SymmetricEigen, Vector3};

fn axis_ratio(soft_iron: &Matrix3<f64>) -> f64 {
    let eigenvalues = SymmetricEigen::new((soft_iron + soft_iron.transpose()) * 0.5).eigenvalues;
    eigenvalues.max() / eigenvalues.min()
}

/// What Adafruit's calibration sketch echoes for a packet it stored.
fn echo_of(packet: &[u8]) -> String {
    let sent = parse_motioncal_packet(packet).expect("our own packet reads back");
    let (h, s) = (sent.hard_iron_ut, sent.soft_iron);
    let soft: Vec<String> = s.transpose().iter().map(|v| format!("{v:.4}")).collect();
    format!(
        "Cal1:0,0,0,0,0,0,{:.3},{:.3},{:.3},{:.3}\nCal2:{}\n",
        h.x,
        h.y,
        h.z,
        sent.field_ut,
        soft.join(",")
    )
}

#[test]
fn a_real_hmc5883l_streamed_live_is_sent_once_and_not_again_after_its_echo() {
    let Some(data) = shared_data() else { return };
    let path = data.join("hmc5883l-sphere/full-sphere/hmc5883l_compass.csv");
    let text = std::fs::read_to_string(path).expect("readable");
    // `t_s,mag_x_gauss,mag_y_gauss,mag_z_gauss`, printed as MotionCal counts of 0.1 µT.
    let lines: Vec<String> = text
        .lines()
        .skip(1)
        .filter_map(|line| {
            let values: Vec<f64> = line.split(',').filter_map(|v| v.parse().ok()).collect();
            let [_, x, y, z] = values[..] else {
                return None;
            };
            Some(format!(
                "Raw:0,0,8192,0,0,0,{:.0},{:.0},{:.0}\n",
                x * 1000.0,
                y * 1000.0,
                z * 1000.0
            ))
        })
        .collect();
    let mut session = LiveSession::new();
    for (idx, chunk) in lines.chunks(25).enumerate() {
        session.feed(chunk.concat().as_bytes(), idx as f64 * 0.25);
    }
    let quality = session.refit().expect("the tumble fits").clone();
    let ratio = axis_ratio(&quality.calibration.soft_iron);
    let held_back = &quality.held_back;
    eprintln!(
        "HMC5883L live: soft iron axes {ratio:.3}:1; {}",
        held_back.summary()
    );
    assert!(ratio < 1.3, "{ratio}");
    assert!(quality.send.sendable, "{:?}", quality.send);
    let train = held_back.train.expect("the train blocks fit");
    let relative =
        (train.on_check.spread_pct / held_back.candidate.on_check.spread_pct - 1.0).abs();
    assert!(relative < 0.02, "train-only against full fit: {relative}");

    let packet = session.packet_for_device().expect("sent");
    session.feed(echo_of(&packet).as_bytes(), 1000.0);
    assert_eq!(session.in_force().source, InForceSource::Confirmed);
    let refused = session
        .packet_for_device()
        .expect_err("the same fit is in force");
    assert!(
        refused
            .iter()
            .any(|reason| reason.contains("the calibration the board confirmed")),
        "{refused:?}"
    );
}

#[test]
fn the_qmc5883l_s_own_calibration_is_inside_the_bounds() {
    let Some(data) = shared_data() else { return };
    let text = std::fs::read_to_string(data.join("qmc5883l-calibration/paramters_mag.csv"))
        .expect("readable");
    let numbers: Vec<f64> = text
        .split(|c: char| c == ',' || c.is_whitespace())
        .filter_map(|field| field.trim().parse().ok())
        .collect();
    // The author's correction (counts to the unit sphere), rows first.
    let author = Matrix3::from_row_slice(&numbers[..9]);
    let ratio = axis_ratio(&author);
    eprintln!("QMC5883L, its author's calibration: soft iron axes {ratio:.3}:1");
    assert!(ratio > 2.0 && ratio < MAX_SOFT_IRON_AXIS_RATIO, "{ratio}");
    // In µT (3,000 counts per gauss, the 8 G range), on a 48 µT field.
    let calibration = FieldCalibration {
        hard_iron_ut: Vector3::zeros(),
        soft_iron: author / author.determinant().cbrt(),
        field_ut: 48.0,
    };
    assert_eq!(acceptance_reasons(&calibration, None), Vec::<String>::new());
}
