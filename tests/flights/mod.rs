//! An independent generator of multirotor flights, written byte by byte as ArduPilot
//! DataFlash logs: not `src/sim`, and not the fit's model.
//!
//! The physics: the Earth's field is the World Magnetic Model's at a random place and
//! date, turned by a local anomaly of up to 1.5° and scaled by up to ±2 % (the model is
//! not the truth either); each compass reads `S·(R_bᵀ·B) + h + k·current + noise` with a
//! general (not symmetric) soft iron `S`, a hard iron `h`, motor interference `k` per
//! ampere and white noise, in the board's axes; the board sits on the vehicle turned by
//! `AHRS_TRIM`, and the autopilot logs the vehicle's attitude with noise and a slowly
//! wandering yaw error; each compass's field is logged after the calibration in force
//! (random: near the truth, stale, with a wrong iron, or none), in whole mG, with its
//! offsets and motor compensation beside it, as ArduPilot logs `MAG`.
//!
//! Coverage runs from one heading (±5° of yaw, a few degrees of tilt) to a hand-held
//! tumble over the whole sphere.

#![allow(dead_code)]

use nalgebra::{Matrix3, Rotation3, Vector3};

use super::physics::Rng;

/// One DataFlash message: the header, its type and payload.
pub fn message(type_id: u8, payload: &[u8]) -> Vec<u8> {
    let mut bytes = vec![0xA3, 0x95, type_id];
    bytes.extend_from_slice(payload);
    bytes
}

fn padded(text: &str, size: usize) -> Vec<u8> {
    let mut bytes = text.as_bytes().to_vec();
    bytes.resize(size, 0);
    bytes
}

/// The `FMT` message that describes a message type.
pub fn fmt(type_id: u8, length: u8, name: &str, format: &str, columns: &str) -> Vec<u8> {
    let mut payload = vec![type_id, length];
    payload.extend(padded(name, 4));
    payload.extend(padded(format, 16));
    payload.extend(padded(columns, 64));
    message(128, &payload)
}

/// A `PARM` message (type 129).
pub fn parm(name: &str, value: f32) -> Vec<u8> {
    let mut payload = padded(name, 16);
    payload.extend_from_slice(&value.to_le_bytes());
    message(129, &payload)
}

/// How much of the sphere a flight turns the vehicle through.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Coverage {
    /// One heading, ±5° of yaw and ±3° of tilt: the flight the old fit went wrong on.
    OneHeading,
    /// A part of a turn, 60-150° of yaw.
    PartTurn,
    /// One to three full turns with 5-25° of tilt.
    FullTurns,
    /// The vehicle tumbled by hand over the whole sphere.
    Tumble,
}

impl Coverage {
    pub const ALL: [Coverage; 4] = [
        Coverage::OneHeading,
        Coverage::PartTurn,
        Coverage::FullTurns,
        Coverage::Tumble,
    ];
}

/// What the calibration in force is, relative to the truth.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InForceKind {
    /// Near the truth (offsets within a few mG, the iron's symmetric part, the motor
    /// term where compensated): better than most flights can support.
    Good,
    /// Offsets 80-200 mG off, no iron.
    Stale,
    /// Offsets near, a wrong iron (diagonals 0.9-1.1).
    WrongIron,
    /// Nothing in force (zeros).
    None,
}

/// One compass of a flight, and the truth about it.
#[derive(Debug, Clone)]
pub struct CompassTruth {
    pub instance: usize,
    pub kind: InForceKind,
    /// The raw field as the log gives it back (the calibration in force undone from the
    /// whole mG logged), mG, board axes.
    pub raw_mg: Vec<Vector3<f64>>,
}

/// One flight: its log's bytes and, per sample, the truth to score against.
#[derive(Debug, Clone)]
pub struct Flight {
    pub coverage: Coverage,
    pub log: Vec<u8>,
    /// The parameters in force, as the log's PARM messages hold them.
    pub params: Vec<(String, f64)>,
    pub compasses: Vec<CompassTruth>,
    pub current_a: Vec<f64>,
    /// The board's true attitude (body → north-east-down).
    pub board_to_ned: Vec<Rotation3<f64>>,
    /// The true Earth's field, north-east-down, mG.
    pub earth_ned_mg: Vector3<f64>,
}

/// Samples per second of the generated streams.
const RATE_HZ: f64 = 10.0;

fn param_name(base: &str, instance: usize, axis: &str) -> String {
    let number = if instance == 0 {
        String::new()
    } else {
        (instance + 1).to_string()
    };
    format!("COMPASS_{base}{number}_{axis}")
}

/// ArduPilot's correction of a raw field, as `AP_Compass` applies it, from a parameter
/// lookup: `M·(raw + COMPASS_OFS)·COMPASS_SCALE + COMPASS_MOT·current` (the motor term
/// by current only with `COMPASS_MOTCT` 2; `M` the identity where the diagonals are all
/// zero; the scale only within 0.85-1.4). Written here from ArduPilot's documentation,
/// not taken from the crate.
pub fn ardupilot_correct(
    params: &dyn Fn(&str) -> Option<f64>,
    instance: usize,
    raw_mg: Vector3<f64>,
    current_a: f64,
) -> Vector3<f64> {
    let get = |base: &str, axis: &str| params(&param_name(base, instance, axis)).unwrap_or(0.0);
    let axes = ["X", "Y", "Z"];
    let offsets = Vector3::from_fn(|i, _| get("OFS", axes[i]));
    let diagonal = Vector3::from_fn(|i, _| get("DIA", axes[i]));
    let (ox, oy, oz) = (get("ODI", "X"), get("ODI", "Y"), get("ODI", "Z"));
    let m = if diagonal == Vector3::zeros() {
        Matrix3::identity()
    } else {
        Matrix3::new(diagonal.x, ox, oy, ox, diagonal.y, oz, oy, oz, diagonal.z)
    };
    let scale_name = if instance == 0 {
        "COMPASS_SCALE".to_string()
    } else {
        format!("COMPASS_SCALE{}", instance + 1)
    };
    let scale = params(&scale_name)
        .filter(|s| *s > 0.85 && *s < 1.4)
        .unwrap_or(1.0);
    let motor = if params("COMPASS_MOTCT") == Some(2.0) {
        Vector3::from_fn(|i, _| get("MOT", axes[i]))
    } else {
        Vector3::zeros()
    };
    m * (raw_mg + offsets) * scale + motor * current_a
}

/// The board's attitude at each sample for a coverage, and the seconds on the ground at
/// the start.
fn attitudes(rng: &mut Rng, coverage: Coverage, n: usize) -> Vec<Rotation3<f64>> {
    let yaw0 = rng.range(0.0, std::f64::consts::TAU);
    let ground = n / 7;
    let phase = rng.range(0.0, 6.0);
    let mut tumble = Rotation3::from_euler_angles(0.0, 0.0, yaw0);
    let (w1, w2, w3) = (
        rng.range(0.3, 0.9),
        rng.range(0.3, 0.9),
        rng.range(0.2, 0.6),
    );
    let span = rng.range(60.0, 150.0).to_radians();
    let turns = rng.range(1.0, 3.0);
    let tilt = match coverage {
        Coverage::OneHeading => rng.range(1.0, 3.0),
        Coverage::PartTurn => rng.range(5.0, 15.0),
        _ => rng.range(5.0, 25.0),
    }
    .to_radians();
    (0..n)
        .map(|i| {
            let t = i as f64 / RATE_HZ;
            if i < ground {
                return Rotation3::from_euler_angles(0.0, 0.0, yaw0);
            }
            let flying = (i - ground) as f64 / (n - ground) as f64;
            let roll = tilt * (0.31 * t + phase).sin();
            let pitch = tilt * (0.23 * t).cos();
            match coverage {
                Coverage::OneHeading => Rotation3::from_euler_angles(
                    roll,
                    pitch,
                    yaw0 + 5f64.to_radians() * (0.17 * t + phase).sin(),
                ),
                Coverage::PartTurn => Rotation3::from_euler_angles(
                    roll,
                    pitch,
                    yaw0 + 0.5 * span * (1.0 - (std::f64::consts::PI * 2.0 * flying).cos()),
                ),
                Coverage::FullTurns => Rotation3::from_euler_angles(
                    roll,
                    pitch,
                    yaw0 + std::f64::consts::TAU * turns * flying,
                ),
                Coverage::Tumble => {
                    // Body rates of about a radian per second about every axis.
                    let rate = Vector3::new(
                        w1 * (0.21 * t + phase).sin(),
                        w2 * (0.13 * t).cos(),
                        w3 * (0.07 * t + 1.0).sin() + 0.2,
                    );
                    tumble *= Rotation3::new(rate / RATE_HZ);
                    tumble
                }
            }
        })
        .collect()
}

/// A random general soft iron, `1 ± diagonal` and `± off` off the diagonal.
fn soft_iron(rng: &mut Rng, diagonal: f64, off: f64) -> Matrix3<f64> {
    Matrix3::from_fn(|row, col| {
        if row == col {
            1.0 + rng.symmetric(diagonal)
        } else {
            rng.symmetric(off)
        }
    })
}

/// A flight of the given coverage, with the Earth's field `model_ned_mg` (the World
/// Magnetic Model's at the flight's place and date, which the caller writes into the GPS
/// messages as `gps`: latitude, longitude in degrees and the GPS week and ms of week).
pub fn flight(
    rng: &mut Rng,
    coverage: Coverage,
    model_ned_mg: Vector3<f64>,
    gps: (f64, f64, u16, u32),
) -> Flight {
    flight_lasting(rng, coverage, model_ned_mg, gps, None)
}

/// [`flight`], lasting `duration_s` where given (else 50-90 s on one heading, 90-240 s
/// otherwise).
pub fn flight_lasting(
    rng: &mut Rng,
    coverage: Coverage,
    model_ned_mg: Vector3<f64>,
    gps: (f64, f64, u16, u32),
    duration_s: Option<f64>,
) -> Flight {
    // The local field: the model's turned by up to 1.5° and scaled by up to ±2 %.
    let anomaly = Rotation3::new(Vector3::new(
        rng.symmetric(1.5f64.to_radians() / 3f64.sqrt()),
        rng.symmetric(1.5f64.to_radians() / 3f64.sqrt()),
        rng.symmetric(1.5f64.to_radians() / 3f64.sqrt()),
    ));
    let earth_ned_mg = anomaly * model_ned_mg * (1.0 + rng.symmetric(0.02));
    let drawn_s = match coverage {
        Coverage::OneHeading => rng.range(50.0, 90.0),
        _ => rng.range(90.0, 240.0),
    };
    let duration_s = duration_s.unwrap_or(drawn_s);
    let n = (duration_s * RATE_HZ) as usize;
    let board_to_ned = attitudes(rng, coverage, n);
    let trim = Rotation3::from_euler_angles(
        rng.symmetric(2f64.to_radians()),
        rng.symmetric(2f64.to_radians()),
        0.0,
    );
    let (trim_x, trim_y, _) = trim.euler_angles();
    let ground = n / 7;
    let current_base = rng.range(8.0, 20.0);
    let current_a: Vec<f64> = (0..n)
        .map(|i| {
            if i < ground {
                0.5
            } else {
                let t = i as f64 / RATE_HZ;
                (current_base + 4.0 * (0.05 * t).sin() + rng.symmetric(1.0)) as f32 as f64
            }
        })
        .collect();
    // The autopilot's yaw wanders from the truth by up to 3°.
    let yaw_error_amp = rng.range(0.0, 3.0).to_radians();
    let yaw_phase = rng.range(0.0, 6.0);

    let by_current = rng.uniform() < 0.5;
    let mut params: Vec<(String, f64)> = vec![
        ("AHRS_TRIM_X".to_string(), trim_x as f32 as f64),
        ("AHRS_TRIM_Y".to_string(), trim_y as f32 as f64),
        (
            "COMPASS_MOTCT".to_string(),
            if by_current { 2.0 } else { 0.0 },
        ),
    ];
    struct Physics {
        soft: Matrix3<f64>,
        hard: Vector3<f64>,
        motor: Vector3<f64>,
        noise_mg: f64,
        in_force_m: Matrix3<f64>,
        in_force_ofs: Vector3<f64>,
        in_force_mot: Vector3<f64>,
        kind: InForceKind,
    }
    let kinds = [
        InForceKind::Good,
        InForceKind::Stale,
        InForceKind::WrongIron,
        InForceKind::None,
    ];
    let physics: Vec<Physics> = (0..2)
        .map(|instance| {
            // The first compass external (away from the power), the second on the board.
            let (iron, hard_max, motor_max) = if instance == 0 {
                ((0.06, 0.03), 250.0, 3.0)
            } else {
                ((0.1, 0.05), 500.0, 10.0)
            };
            let soft = soft_iron(rng, iron.0, iron.1);
            let hard = Vector3::from_fn(|_, _| rng.symmetric(hard_max));
            let motor = Vector3::from_fn(|_, _| rng.symmetric(motor_max));
            let kind = kinds[rng.index(kinds.len())];
            let inverse = soft.try_inverse().expect("a soft iron near the identity");
            let (in_force_m, in_force_ofs, in_force_mot) = match kind {
                InForceKind::Good => {
                    let symmetric = (inverse + inverse.transpose()) * 0.5;
                    let mot = if by_current {
                        -(symmetric * motor)
                    } else {
                        Vector3::zeros()
                    };
                    (
                        symmetric,
                        -hard + Vector3::from_fn(|_, _| 4.0 * rng.gaussian()),
                        mot,
                    )
                }
                InForceKind::Stale => (
                    Matrix3::identity(),
                    -hard + Vector3::from_fn(|_, _| rng.sign() * rng.range(80.0, 200.0)),
                    Vector3::zeros(),
                ),
                InForceKind::WrongIron => {
                    let d = Vector3::from_fn(|_, _| 1.0 + rng.symmetric(0.1));
                    let o = Vector3::from_fn(|_, _| rng.symmetric(0.05));
                    (
                        Matrix3::new(d.x, o.x, o.y, o.x, d.y, o.z, o.y, o.z, d.z),
                        -hard + Vector3::from_fn(|_, _| 20.0 * rng.gaussian()),
                        Vector3::zeros(),
                    )
                }
                InForceKind::None => (Matrix3::identity(), Vector3::zeros(), Vector3::zeros()),
            };
            Physics {
                soft,
                hard,
                motor,
                noise_mg: rng.range(1.5, 4.0),
                // As the PARMs hold them: whole mG offsets (ArduPilot logs whole mG
                // beside each sample), float32 iron.
                in_force_m: in_force_m.map(|v| v as f32 as f64),
                in_force_ofs: in_force_ofs.map(f64::round),
                in_force_mot: in_force_mot.map(|v| v as f32 as f64),
                kind,
            }
        })
        .collect();
    for (instance, compass) in physics.iter().enumerate() {
        let axes = ["X", "Y", "Z"];
        for (idx, axis) in axes.iter().enumerate() {
            params.push((param_name("OFS", instance, axis), compass.in_force_ofs[idx]));
            params.push((param_name("MOT", instance, axis), compass.in_force_mot[idx]));
        }
        if compass.kind != InForceKind::None {
            let m = &compass.in_force_m;
            for (axis, value) in axes.iter().zip([m[(0, 0)], m[(1, 1)], m[(2, 2)]]) {
                params.push((param_name("DIA", instance, axis), value));
            }
            for (axis, value) in axes.iter().zip([m[(0, 1)], m[(0, 2)], m[(1, 2)]]) {
                params.push((param_name("ODI", instance, axis), value));
            }
        }
    }

    let mut log = fmt(128, 89, "FMT", "BBnNZ", "Type,Length,Name,Format,Columns");
    log.extend(fmt(129, 23, "PARM", "Nf", "Name,Value"));
    let mag_columns = "TimeUS,MagX,MagY,MagZ,OfsX,OfsY,OfsZ,MOX,MOY,MOZ";
    log.extend(fmt(130, 29, "MAG", "Qhhhhhhhhh", mag_columns));
    log.extend(fmt(131, 29, "MAG2", "Qhhhhhhhhh", mag_columns));
    log.extend(fmt(132, 23, "ATT", "Qfff", "TimeUS,Roll,Pitch,Yaw"));
    log.extend(fmt(133, 15, "CURR", "Qf", "TimeUS,Curr"));
    log.extend(fmt(
        134,
        30,
        "GPS",
        "QBIHLLf",
        "TimeUS,Status,GMS,GWk,Lat,Lng,Alt",
    ));
    for (name, value) in &params {
        log.extend(parm(name, *value as f32));
    }
    let mut compasses: Vec<CompassTruth> = physics
        .iter()
        .enumerate()
        .map(|(instance, compass)| CompassTruth {
            instance,
            kind: compass.kind,
            raw_mg: Vec::with_capacity(n),
        })
        .collect();
    let (lat_deg, lon_deg, week, week_ms) = gps;
    for i in 0..n {
        let t_us = 5_000_000u64 + (i as f64 / RATE_HZ * 1e6) as u64;
        let board = board_to_ned[i];
        let current = current_a[i];
        let field_in_board = board.inverse() * earth_ned_mg;
        for (instance, compass) in physics.iter().enumerate() {
            let noise = Vector3::from_fn(|_, _| rng.gaussian()) * compass.noise_mg;
            let raw =
                compass.soft * field_in_board + compass.hard + compass.motor * current + noise;
            let motor_logged = (compass.in_force_mot * current).map(f64::round);
            let logged =
                (compass.in_force_m * (raw + compass.in_force_ofs)).map(f64::round) + motor_logged;
            let mut payload = t_us.to_le_bytes().to_vec();
            for value in logged
                .iter()
                .chain(compass.in_force_ofs.iter())
                .chain(motor_logged.iter())
            {
                payload.extend_from_slice(&(*value as i16).to_le_bytes());
            }
            log.extend(message(130 + instance as u8, &payload));
            // What the log gives back: the calibration in force undone.
            let inverse = compass
                .in_force_m
                .try_inverse()
                .expect("an invertible iron in force");
            compasses[instance]
                .raw_mg
                .push(inverse * (logged - motor_logged) - compass.in_force_ofs);
        }
        // The autopilot logs the vehicle's attitude, the board's turned back by the trim,
        // with noise and its yaw error.
        let vehicle = board * trim.inverse();
        let (roll, pitch, yaw) = vehicle.euler_angles();
        let t = i as f64 / RATE_HZ;
        let yaw_logged = yaw + yaw_error_amp * (0.02 * t + yaw_phase).sin();
        let mut att = t_us.to_le_bytes().to_vec();
        for degrees in [
            roll + 0.2f64.to_radians() * rng.gaussian(),
            pitch + 0.2f64.to_radians() * rng.gaussian(),
            yaw_logged.rem_euclid(std::f64::consts::TAU),
        ]
        .map(f64::to_degrees)
        {
            att.extend_from_slice(&(degrees as f32).to_le_bytes());
        }
        log.extend(message(132, &att));
        let mut curr = t_us.to_le_bytes().to_vec();
        curr.extend_from_slice(&(current as f32).to_le_bytes());
        log.extend(message(133, &curr));
        if i % 2 == 0 {
            let mut fix = t_us.to_le_bytes().to_vec();
            fix.push(3);
            fix.extend_from_slice(&(week_ms + (i as f64 / RATE_HZ * 1000.0) as u32).to_le_bytes());
            fix.extend_from_slice(&week.to_le_bytes());
            fix.extend_from_slice(&((lat_deg * 1e7) as i32).to_le_bytes());
            fix.extend_from_slice(&((lon_deg * 1e7) as i32).to_le_bytes());
            fix.extend_from_slice(&100f32.to_le_bytes());
            log.extend(message(134, &fix));
        }
    }
    Flight {
        coverage,
        log,
        params,
        compasses,
        current_a,
        board_to_ned,
        earth_ned_mg,
    }
}
