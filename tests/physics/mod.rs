//! An independent generator of test logs, written from the physics.
//!
//! The crate's own simulator produces exactly what its calibration fits assume. This
//! module was written without reading it (nor the fits), from the physics of a phone
//! carried by a walker or mounted in a car, so that figures measured on its logs are
//! not flattered by shared assumptions. It uses only the crate's public API (the World
//! Magnetic Model, the WGS-84 tangent plane and the canonical CSV writer), `nalgebra`
//! and `std`; its random numbers are its own (xoshiro256** seeded through SplitMix64,
//! Gaussians by Box-Muller), one independent stream per physical piece, so every log is
//! a pure function of its seed.
//!
//! # Frames
//!
//! * Navigation frame: NED (x north, y east, z down), a tangent plane at the log's origin.
//!   Written reference positions are east and north metres (`ref_e_m`, `ref_n_m`).
//! * Body frame: x forward, y right, z down (the canonical CSV's axes).
//! * Attitude: `R = Rz(ψ)·Ry(θ)·Rx(φ)` (ZYX yaw-pitch-roll), body to NED, so a body
//!   vector `v_b` is `R·v_b` in NED. Headings are degrees clockwise from true north; the
//!   heading of the body x axis is `atan2(R₁₀, R₀₀)`, which is ψ itself.
//!
//! # Physics
//!
//! * Earth field: the WMM at the log's place and date (total intensity F, inclination I,
//!   declination D), perturbed per log as a real local anomaly would be: F·(1 ± ≤3 %),
//!   I ± ≤2°, D ± ≤1°. The perturbed field is the truth:
//!   `b_ned = F·(cos I cos D, cos I sin D, sin I)`. It is constant over a log.
//! * Magnetometer: `m = S·Rᵀ·(b_ned + d_ned) + h + n`, quantised to the sensor's step
//!   (0.01, 0.0625 or 0.15 µT). `S = I + diag(s) + cross terms`, a general (not
//!   symmetric) 3×3 soft-iron matrix; `h` the hard iron; `d_ned` the field of moving
//!   iron, an external field and therefore distorted by `S` like the Earth's; `n` white
//!   noise, σ uniform in 0.2-0.6 µT per axis. The true calibration is
//!   `b = S⁻¹·(m − h)` ([`GeneratedLog::true_correction`]).
//! * Moving iron: passes of a magnetic dipole, 1-10 s long, covering a fraction of the
//!   log. The dipole moves in a straight line past the phone, its field
//!   `(3(m·r̂)r̂ − m)/|r|³` rises and falls (and turns) as it passes; a cos² window makes
//!   it exactly zero outside the pass, and the peak is scaled to 5-50 µT.
//! * Accelerometer: specific force `f = Rᵀ·(a_ned − g_ned)` with
//!   `g_ned = (0, 0, 9.80665)`, plus a constant bias (±0.05 m/s² per axis) and white
//!   noise (σ 0.02-0.05 m/s²). A level device at rest reads `acc_z ≈ −9.81`.
//!   `a_ned` is the second derivative of the smooth path (speed changes, centripetal
//!   `v·ψ̇`, road grade) plus, when walking, the step oscillations: vertical bounce
//!   1.5-3 m/s² at the step frequency (with a second harmonic), fore-aft 0.8-1.5 m/s²,
//!   lateral 0.3-0.8 m/s² at half the step frequency, each varying ±10 % per step. The
//!   few centimetres of displacement these oscillations imply are not added to the
//!   reference position (which is the walker's mean path). In the car, road vibration
//!   adds noise growing with speed.
//! * Gyroscope: the body rate over each sample, `ω_k = log(R(t_k − Δt/2)ᵀ·R(t_k + Δt/2))/Δt`
//!   (attitudes are computed on a half-sample grid, so the rate is centred on the
//!   sample), plus a bias (±0.01 rad/s per axis at the start, then wandering as a
//!   Gauss-Markov process of σ 0.1-0.4 mrad/s and 200-600 s correlation time) and white
//!   noise (σ 0.002-0.005 rad/s).
//! * Walking: cadence 1.6-2.1 Hz (per log, ±4 % per leg, slowly wandering ±2 %); step
//!   length 0.55-0.85 m (per log, ±5 % per leg and ±5 % per step, blended smoothly from
//!   step to step). Speed = cadence × step length; the position integrates it along the
//!   walking direction, which turns smoothly (raised-cosine turn-rate ramps). The walker
//!   stands for 2-3 s at both ends. The phone is held in front: heading = walking
//!   direction + a constant hand misalignment (±3°) + a yaw sway (1-2° at half the step
//!   frequency); pitch and roll = a hand tilt wandering as a sum of three sinusoids at
//!   0.02-0.3 Hz within ± the log's tilt amplitude, plus a 1-2° sway at the step
//!   frequency.
//! * Car: speed changes as raised cosines (peak longitudinal acceleration below
//!   2 m/s²), turns as raised-cosine turn rates (lateral acceleration `v·ψ̇` below about
//!   3 m/s²), road grade wandering within ±3° along the road, body pitch under braking
//!   and roll in turns (fractions of a degree per m/s²). The phone sits in a fixed
//!   mount: body frame = car frame up to the mount's constant tilt of a few degrees.
//! * GNSS: 1 Hz fixes on whole seconds. Horizontal error = a first-order Gauss-Markov
//!   process per axis (σ 1.5-4 m, correlation time 20-60 s) + white 0.5 m. Velocity =
//!   true horizontal velocity + noise along track (σ 0.1-0.2 m/s) and across track (so
//!   that the course errs by 2-5° at 1.4 m/s); speed is its norm, course its direction
//!   (left empty below 0.5 m/s, as receivers do). `gps_hacc_m` states the true σ within
//!   a per-log factor of 0.8-1.25 and ±10 % per fix. Positions are written as latitude
//!   and longitude through the WGS-84 tangent plane at an origin near one of
//!   [`PLACES`].
//! * Time: `t_s` is absolute Unix seconds of a random instant in 2021-2027, so the log
//!   is dated; the WMM is evaluated on that day.
#![allow(dead_code)]

pub mod scoring;

use std::f64::consts::{FRAC_PI_2, PI, TAU};

use compass_pdr::base::geodesy::{Geodetic, LocalFrame};
use compass_pdr::earth::wmm;
use compass_pdr::io::canonical_csv::{self, CanonicalRow};
use nalgebra::{Matrix3, Rotation3, Vector2, Vector3};

/// Standard gravity (m/s²), down in NED.
pub const GRAVITY_MPS2: f64 = 9.80665;

// ---------------------------------------------------------------------------------------
// The generated log
// ---------------------------------------------------------------------------------------

/// One generated log and the truth behind it.
#[derive(Debug, Clone)]
pub struct GeneratedLog {
    /// Scenario, seed, place and date, e.g. `circle_walk seed 3 (Munich, 2024-05-17)`.
    pub name: String,
    /// The log as canonical CSV (body axes; empty fields where absent).
    pub csv: String,
    /// Hard iron `h` in body axes (µT): `m = S·b + h`.
    pub hard_iron_ut: Vector3<f64>,
    /// Soft iron `S` in body axes: `m = S·b + h`.
    pub soft_iron: Matrix3<f64>,
    /// The true (perturbed) Earth field in NED (µT).
    pub field_ned_ut: Vector3<f64>,
    /// The true declination (degrees east of true north).
    pub declination_deg: f64,
    pub sample_rate_hz: f64,
    /// The GNSS outage, seconds after the first sample (no fixes with `start ≤ t < end`).
    pub gnss_outage_s: Option<(f64, f64)>,
    /// Horizontal distance walked or driven (m).
    pub distance_m: f64,
    /// The true heading of the body x axis (degrees in [0, 360), true north), per sample.
    pub true_heading_deg: Vec<f64>,
    /// Seconds after the first sample, per sample.
    pub true_t_s: Vec<f64>,
    /// Per sample: moving iron is active (its field is not zero).
    pub disturbed: Vec<bool>,
    // Beyond the brief: the rest of the truth, for the self-checks and for tests that
    // want more than the headings.
    /// Where the walk or drive happened.
    pub place: &'static str,
    /// The tangent plane's origin (the first sample's position).
    pub origin: Geodetic,
    /// Unix time of the first sample.
    pub start_unix_s: f64,
    /// The true attitude (body to NED) per sample.
    pub true_attitude: Vec<Rotation3<f64>>,
    /// The true position, metres east and north of the origin, per sample.
    pub true_en_m: Vec<Vector2<f64>>,
    /// The gyro bias at the first sample (rad/s, body axes); it wanders slowly after.
    pub gyro_bias_radps: Vector3<f64>,
    /// The accelerometer bias (m/s², body axes).
    pub acc_bias_mps2: Vector3<f64>,
    /// The magnetometer's white noise σ per axis (µT).
    pub mag_noise_ut: f64,
    /// The true σ of the GNSS position error per horizontal axis (m).
    pub gnss_sigma_m: f64,
}

impl GeneratedLog {
    /// The true calibration: the hard iron and `S⁻¹`, so that `b = S⁻¹·(m − h)`.
    pub fn true_correction(&self) -> (Vector3<f64>, Matrix3<f64>) {
        let inverse = self
            .soft_iron
            .try_inverse()
            .expect("the drawn soft iron is diagonally dominant, hence invertible");
        (self.hard_iron_ut, inverse)
    }
}

// ---------------------------------------------------------------------------------------
// Scenarios
// ---------------------------------------------------------------------------------------

/// 6-10 min of walking, phone in hand, through loops and smooth random turns so that each
/// half of the log covers every heading; full soft iron, no moving iron; 50 Hz; GNSS
/// throughout; `ref_heading_deg` is the truth.
pub fn circle_walk(seed: u64) -> GeneratedLog {
    walk(seed, &WalkOptions::circle_walk())
}

/// 900 s on a grid (four walking directions, 90° turns, legs of 20-80 m); GNSS only for
/// the first 240 s and the last 60 s; reference positions once a second; no heading
/// reference.
pub fn four_direction_walk(seed: u64) -> GeneratedLog {
    walk(seed, &WalkOptions::four_direction_walk())
}

/// A 20-40 min city drive, the phone in a magnetic mount (hard iron 150-250 µT); 10 Hz;
/// GNSS with course and speed; moving iron (passing vehicles); no heading reference.
pub fn magnet_mount_drive(seed: u64) -> GeneratedLog {
    drive(seed, &DriveOptions::magnet_mount())
}

/// Like [`circle_walk`] but along only 3-5 headings (straight legs, sharp turns).
pub fn few_headings_walk(seed: u64) -> GeneratedLog {
    walk(seed, &WalkOptions::few_headings_walk())
}

/// [`circle_walk`] with moving iron during 10 % of the time (5-50 µT). The walk itself
/// (place, path, sensor errors) is the same as `circle_walk` with the same seed.
pub fn moving_iron_walk(seed: u64) -> GeneratedLog {
    walk(seed, &WalkOptions::moving_iron_walk())
}

/// Issue 43's motions, each with its magnetometer (symmetric soft iron, 10-60 µT of hard
/// iron) and the GNSS course as the only reference: a car on open roads (turns of up to
/// 6 m/s²), with and without a GNSS speed, and a walker with the phone held steady in
/// front, moved about by the hand, or swinging at the arm's end.
pub fn car(seed: u64) -> GeneratedLog {
    drive(seed, &DriveOptions::issue_43_car())
}

pub fn car_without_speed(seed: u64) -> GeneratedLog {
    drive(seed, &DriveOptions::issue_43_car_without_speed())
}

pub fn steady_walk(seed: u64) -> GeneratedLog {
    walk(seed, &WalkOptions::issue_43_walk())
}

pub fn hand_walk(seed: u64) -> GeneratedLog {
    walk(seed, &WalkOptions::issue_43_hand())
}

pub fn swing_walk(seed: u64) -> GeneratedLog {
    walk(seed, &WalkOptions::issue_43_swing())
}

/// A scenario: a log per seed.
pub type Scenario = fn(u64) -> GeneratedLog;

/// Every scenario by name.
pub const SCENARIOS: [(&str, Scenario); 5] = [
    ("circle_walk", circle_walk),
    ("four_direction_walk", four_direction_walk),
    ("magnet_mount_drive", magnet_mount_drive),
    ("few_headings_walk", few_headings_walk),
    ("moving_iron_walk", moving_iron_walk),
];

/// The shape of a walk.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WalkRoute {
    /// Full loops in each half of the log, between straight stretches and smooth turns.
    Loops,
    /// Four directions 90° apart, legs of 20-80 m.
    Grid,
    /// 3-5 headings at least 40° apart, straight legs of 20-80 m, sharp turns.
    FewHeadings,
}

impl WalkRoute {
    fn label(self) -> &'static str {
        match self {
            WalkRoute::Loops => "loops",
            WalkRoute::Grid => "grid",
            WalkRoute::FewHeadings => "few-headings",
        }
    }
}

/// How the magnetometer's errors are drawn.
#[derive(Debug, Clone, Copy)]
pub struct MagnetometerOptions {
    /// Each `s_i` of `S = diag(1 + s_i) + cross` is uniform in ± this.
    pub soft_diag_max: f64,
    /// Each off-diagonal entry of `S` is uniform in ± this, independently.
    pub soft_cross_max: f64,
    /// `S` symmetric (each cross term drawn once, mirrored): a soft iron that turns no
    /// field, as issue 43's generator asks; otherwise general.
    pub symmetric: bool,
    pub hard_iron: HardIronOptions,
}

/// How the hard iron is drawn.
#[derive(Debug, Clone, Copy)]
pub enum HardIronOptions {
    /// Each axis uniform in ± `max_ut`.
    PerAxis { max_ut: f64 },
    /// A random direction, magnitude uniform in `min_ut..max_ut`.
    Magnitude { min_ut: f64, max_ut: f64 },
}

/// Moving iron: dipole passes covering `time_fraction` of the log.
#[derive(Debug, Clone, Copy)]
pub struct MovingIronOptions {
    pub time_fraction: f64,
    /// Peak field of one pass, drawn uniform in this range (µT).
    pub amplitude_ut: (f64, f64),
    /// Length of one pass, drawn uniform in this range (s).
    pub duration_s: (f64, f64),
}

impl Default for MovingIronOptions {
    fn default() -> Self {
        MovingIronOptions {
            time_fraction: 0.05,
            amplitude_ut: (5.0, 50.0),
            duration_s: (1.0, 10.0),
        }
    }
}

/// A walk with the phone in hand.
#[derive(Debug, Clone)]
pub struct WalkOptions {
    pub name: &'static str,
    pub route: WalkRoute,
    /// Drawn uniform in this range (s).
    pub duration_s: (f64, f64),
    pub sample_rate_hz: f64,
    /// The hand tilt's amplitude (pitch and roll), drawn uniform in this range per log.
    pub tilt_amplitude_deg: (f64, f64),
    pub magnetometer: MagnetometerOptions,
    pub moving_iron: Option<MovingIronOptions>,
    /// No GNSS fixes with `start ≤ t < end` (seconds after the first sample).
    pub gnss_outage_s: Option<(f64, f64)>,
    pub write_ref_heading: bool,
    /// `ref_e_m`, `ref_n_m` once a second.
    pub write_ref_position: bool,
    /// The phone swings in the hand at the arm's end, by ± an amplitude drawn in this
    /// range (degrees) at half the step frequency; `None`: held in front.
    pub swing_deg: Option<(f64, f64)>,
}

const HAND_MAGNETOMETER: MagnetometerOptions = MagnetometerOptions {
    soft_diag_max: 0.1,
    soft_cross_max: 0.1,
    symmetric: false,
    hard_iron: HardIronOptions::PerAxis { max_ut: 30.0 },
};

/// Issue 43's magnetometer: symmetric soft iron (diagonal 0.85-1.15, cross terms ±0.1),
/// hard iron of 10-60 µT in a random direction.
pub const ISSUE_43_MAGNETOMETER: MagnetometerOptions = MagnetometerOptions {
    soft_diag_max: 0.15,
    soft_cross_max: 0.1,
    symmetric: true,
    hard_iron: HardIronOptions::Magnitude {
        min_ut: 10.0,
        max_ut: 60.0,
    },
};

impl WalkOptions {
    pub fn circle_walk() -> WalkOptions {
        WalkOptions {
            name: "circle_walk",
            route: WalkRoute::Loops,
            duration_s: (360.0, 600.0),
            sample_rate_hz: 50.0,
            tilt_amplitude_deg: (5.0, 10.0),
            magnetometer: HAND_MAGNETOMETER,
            moving_iron: None,
            gnss_outage_s: None,
            write_ref_heading: true,
            write_ref_position: false,
            swing_deg: None,
        }
    }

    /// Issue 43's walker, phone held in front: bounce, hand sway, a hand tilt wandering
    /// within ±3-8°; its magnetometer; the GNSS course the only reference.
    pub fn issue_43_walk() -> WalkOptions {
        WalkOptions {
            name: "walk",
            tilt_amplitude_deg: (3.0, 8.0),
            magnetometer: ISSUE_43_MAGNETOMETER,
            write_ref_heading: false,
            ..WalkOptions::circle_walk()
        }
    }

    /// [`WalkOptions::issue_43_walk`] with the hand moving the phone about: a tilt
    /// wandering within ±15-30°.
    pub fn issue_43_hand() -> WalkOptions {
        WalkOptions {
            name: "hand",
            tilt_amplitude_deg: (15.0, 30.0),
            ..WalkOptions::issue_43_walk()
        }
    }

    /// [`WalkOptions::issue_43_walk`] with the phone swinging in the hand by ±30-60°.
    pub fn issue_43_swing() -> WalkOptions {
        WalkOptions {
            name: "swing",
            swing_deg: Some((30.0, 60.0)),
            ..WalkOptions::issue_43_walk()
        }
    }

    pub fn four_direction_walk() -> WalkOptions {
        WalkOptions {
            name: "four_direction_walk",
            route: WalkRoute::Grid,
            duration_s: (900.0, 900.0),
            tilt_amplitude_deg: (3.0, 8.0),
            gnss_outage_s: Some((240.0, 840.0)),
            write_ref_heading: false,
            write_ref_position: true,
            ..WalkOptions::circle_walk()
        }
    }

    pub fn few_headings_walk() -> WalkOptions {
        WalkOptions {
            name: "few_headings_walk",
            route: WalkRoute::FewHeadings,
            ..WalkOptions::circle_walk()
        }
    }

    pub fn moving_iron_walk() -> WalkOptions {
        WalkOptions {
            name: "moving_iron_walk",
            moving_iron: Some(MovingIronOptions {
                time_fraction: 0.10,
                ..MovingIronOptions::default()
            }),
            ..WalkOptions::circle_walk()
        }
    }
}

/// A drive with the phone in a fixed mount.
#[derive(Debug, Clone)]
pub struct DriveOptions {
    pub name: &'static str,
    /// Drawn uniform in this range (s).
    pub duration_s: (f64, f64),
    pub sample_rate_hz: f64,
    pub magnetometer: MagnetometerOptions,
    pub moving_iron: Option<MovingIronOptions>,
    /// The road grade wanders within ± this.
    pub road_pitch_max_deg: f64,
    pub route: DriveRoute,
    /// Whether the fixes carry a speed (the course is written either way).
    pub gnss_speed: bool,
}

/// The shape of a drive.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DriveRoute {
    /// Cruising at 8-20 m/s, slow corners of 8-25 m radius at 3-6 m/s, stops.
    City,
    /// 5-20 m/s, turns of 10-200 m radius at up to 6 m/s² of centripetal acceleration.
    Open,
}

impl DriveOptions {
    pub fn magnet_mount() -> DriveOptions {
        DriveOptions {
            name: "magnet_mount_drive",
            duration_s: (1200.0, 2400.0),
            sample_rate_hz: 10.0,
            magnetometer: MagnetometerOptions {
                soft_diag_max: 0.15,
                soft_cross_max: 0.1,
                symmetric: false,
                hard_iron: HardIronOptions::Magnitude {
                    min_ut: 150.0,
                    max_ut: 250.0,
                },
            },
            moving_iron: Some(MovingIronOptions::default()),
            road_pitch_max_deg: 3.0,
            route: DriveRoute::City,
            gnss_speed: true,
        }
    }

    /// Issue 43's car: 10-20 min on open roads, an ordinary mount, its magnetometer.
    pub fn issue_43_car() -> DriveOptions {
        DriveOptions {
            name: "car",
            duration_s: (600.0, 1200.0),
            magnetometer: ISSUE_43_MAGNETOMETER,
            route: DriveRoute::Open,
            ..DriveOptions::magnet_mount()
        }
    }

    /// [`DriveOptions::issue_43_car`] whose fixes carry no speed.
    pub fn issue_43_car_without_speed() -> DriveOptions {
        DriveOptions {
            name: "car_without_speed",
            gnss_speed: false,
            ..DriveOptions::issue_43_car()
        }
    }
}

/// A walk, phone in hand.
pub fn walk(seed: u64, options: &WalkOptions) -> GeneratedLog {
    let streams = Streams::new(seed, format!("walk/{}", options.route.label()));
    let dt_s = 1.0 / options.sample_rate_hz;
    let gait = Gait::draw(&mut streams.rng("gait"));
    let duration_s = streams
        .rng("duration")
        .range(options.duration_s.0, options.duration_s.1);
    let mut route_rng = streams.rng("route");
    let speed_mps = gait.typical_speed_mps();
    let plan = match options.route {
        WalkRoute::Loops => loops_route(&mut route_rng, duration_s, speed_mps),
        WalkRoute::Grid => grid_route(&mut route_rng, duration_s, speed_mps),
        WalkRoute::FewHeadings => few_headings_route(&mut route_rng, duration_s, speed_mps),
    };
    let samples = (plan.duration_s() * options.sample_rate_hz).floor() as usize;
    let mut hand = HandPose::draw(&mut streams.rng("hand"), options.tilt_amplitude_deg);
    hand.swing = options
        .swing_deg
        .map(|range| Swing::draw(&mut streams.rng("swing"), range));
    let track = walk_track(&plan, &gait, &hand, samples, dt_s, streams.rng("steps"));
    assemble(Parts {
        scenario: options.name,
        seed,
        streams,
        track,
        sample_rate_hz: options.sample_rate_hz,
        magnetometer: options.magnetometer,
        moving_iron: options.moving_iron,
        vibration: Vibration::NONE,
        gnss_speed: true,
        gnss_outage_s: options.gnss_outage_s,
        write_ref_heading: options.write_ref_heading,
        write_ref_position: options.write_ref_position,
    })
}

/// A drive, phone in a fixed mount.
pub fn drive(seed: u64, options: &DriveOptions) -> GeneratedLog {
    let streams = Streams::new(seed, "drive".to_string());
    let dt_s = 1.0 / options.sample_rate_hz;
    let duration_s = streams
        .rng("duration")
        .range(options.duration_s.0, options.duration_s.1);
    let plan = match options.route {
        DriveRoute::City => city_route(&mut streams.rng("route"), duration_s),
        DriveRoute::Open => open_route(&mut streams.rng("route"), duration_s),
    };
    let samples = (plan.duration_s() * options.sample_rate_hz).floor() as usize;
    let car = Car::draw(&mut streams.rng("car"), options.road_pitch_max_deg);
    let track = drive_track(&plan, &car, samples, dt_s);
    assemble(Parts {
        scenario: options.name,
        seed,
        streams,
        track,
        sample_rate_hz: options.sample_rate_hz,
        magnetometer: options.magnetometer,
        moving_iron: options.moving_iron,
        vibration: Vibration::ROAD,
        gnss_speed: options.gnss_speed,
        gnss_outage_s: None,
        write_ref_heading: false,
        write_ref_position: false,
    })
}

// ---------------------------------------------------------------------------------------
// Random numbers
// ---------------------------------------------------------------------------------------

/// xoshiro256** (Blackman and Vigna), seeded through SplitMix64; Gaussians by Box-Muller.
#[derive(Debug, Clone)]
pub struct Rng {
    state: [u64; 4],
    spare_gaussian: Option<f64>,
}

fn splitmix64(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

impl Rng {
    pub fn new(seed: u64) -> Rng {
        let mut state = seed;
        Rng {
            state: [
                splitmix64(&mut state),
                splitmix64(&mut state),
                splitmix64(&mut state),
                splitmix64(&mut state),
            ],
            spare_gaussian: None,
        }
    }

    /// An independent stream for `label` under `seed`.
    pub fn stream(seed: u64, label: &str) -> Rng {
        // FNV-1a of the label, mixed with the scrambled seed.
        let mut hash = 0xCBF2_9CE4_8422_2325_u64;
        for byte in label.bytes() {
            hash ^= u64::from(byte);
            hash = hash.wrapping_mul(0x0000_0100_0000_01B3);
        }
        let mut scrambled = seed;
        Rng::new(splitmix64(&mut scrambled) ^ hash)
    }

    pub fn next_u64(&mut self) -> u64 {
        let s = &mut self.state;
        let result = s[1].wrapping_mul(5).rotate_left(7).wrapping_mul(9);
        let t = s[1] << 17;
        s[2] ^= s[0];
        s[3] ^= s[1];
        s[1] ^= s[2];
        s[0] ^= s[3];
        s[2] ^= t;
        s[3] = s[3].rotate_left(45);
        result
    }

    /// Uniform in [0, 1), 53 bits.
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1_u64 << 53) as f64)
    }

    /// Uniform in [lo, hi).
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.uniform()
    }

    /// Uniform in [−max, max).
    pub fn symmetric(&mut self, max: f64) -> f64 {
        self.range(-max, max)
    }

    /// ±1 with equal odds.
    pub fn sign(&mut self) -> f64 {
        if self.next_u64() >> 63 == 0 {
            1.0
        } else {
            -1.0
        }
    }

    /// Uniform in 0..n (n > 0).
    pub fn index(&mut self, n: usize) -> usize {
        ((self.uniform() * n as f64) as usize).min(n.saturating_sub(1))
    }

    /// Standard normal (Box-Muller; the second value is kept for the next call).
    pub fn gaussian(&mut self) -> f64 {
        if let Some(value) = self.spare_gaussian.take() {
            return value;
        }
        let u1 = 1.0 - self.uniform(); // (0, 1]: the logarithm stays finite
        let u2 = self.uniform();
        let radius = (-2.0 * u1.ln()).sqrt();
        let (sin, cos) = (TAU * u2).sin_cos();
        self.spare_gaussian = Some(radius * sin);
        radius * cos
    }

    /// Three independent standard normals.
    pub fn gaussian3(&mut self) -> Vector3<f64> {
        Vector3::new(self.gaussian(), self.gaussian(), self.gaussian())
    }

    /// Uniform on the unit sphere.
    pub fn unit_vector(&mut self) -> Vector3<f64> {
        loop {
            let v = self.gaussian3();
            let norm = v.norm();
            if norm > 1e-6 {
                return v / norm;
            }
        }
    }
}

/// The named random streams of one log.
struct Streams {
    seed: u64,
    prefix: String,
}

impl Streams {
    fn new(seed: u64, prefix: String) -> Streams {
        Streams { seed, prefix }
    }

    fn rng(&self, label: &str) -> Rng {
        Rng::stream(self.seed, &format!("{}/{label}", self.prefix))
    }
}

// ---------------------------------------------------------------------------------------
// Small smooth functions
// ---------------------------------------------------------------------------------------

/// 0 below 0, 1 above 1, `3x² − 2x³` between (continuous slope).
fn smoothstep(x: f64) -> f64 {
    let x = x.clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
}

/// Wraps an angle to (−π, π].
fn wrap_pi(angle_rad: f64) -> f64 {
    let wrapped = (angle_rad + PI).rem_euclid(TAU) - PI;
    if wrapped <= -PI {
        wrapped + TAU
    } else {
        wrapped
    }
}

/// Body-to-NED rotation `Rz(yaw)·Ry(pitch)·Rx(roll)`.
pub fn attitude_zyx(yaw_rad: f64, pitch_rad: f64, roll_rad: f64) -> Rotation3<f64> {
    Rotation3::from_axis_angle(&Vector3::z_axis(), yaw_rad)
        * Rotation3::from_axis_angle(&Vector3::y_axis(), pitch_rad)
        * Rotation3::from_axis_angle(&Vector3::x_axis(), roll_rad)
}

/// Heading of the body x axis (degrees clockwise from north, in [0, 360)).
pub fn heading_deg_of(attitude: &Rotation3<f64>) -> f64 {
    let m = attitude.matrix();
    m[(1, 0)].atan2(m[(0, 0)]).to_degrees().rem_euclid(360.0)
}

/// A slow wander: `amplitude·Σ wᵢ·sin(2π fᵢ x + φᵢ)` with weights summing to 1, so it
/// stays within ± amplitude. `x` is time (s) or distance (m); frequencies per unit of x.
#[derive(Debug, Clone, Copy)]
struct Wander {
    amplitude: f64,
    terms: [(f64, f64, f64); 3],
}

impl Wander {
    fn draw(rng: &mut Rng, amplitude: f64, frequency: (f64, f64)) -> Wander {
        let mut terms = [(0.0, 0.0, 0.0); 3];
        for term in &mut terms {
            *term = (
                rng.range(0.2, 1.0),
                rng.range(frequency.0, frequency.1),
                rng.range(0.0, TAU),
            );
        }
        let total: f64 = terms.iter().map(|term| term.0).sum();
        for term in &mut terms {
            term.0 /= total;
        }
        Wander { amplitude, terms }
    }

    fn at(&self, x: f64) -> f64 {
        self.amplitude
            * self
                .terms
                .iter()
                .map(|&(weight, frequency, phase)| weight * (TAU * frequency * x + phase).sin())
                .sum::<f64>()
    }
}

// ---------------------------------------------------------------------------------------
// Routes: a plan of phases, each with a smooth turn and (in a car) a smooth speed change
// ---------------------------------------------------------------------------------------

/// One phase of a route. The heading turns by `turn_rad` with a Tukey-shaped rate
/// (raised-cosine ramps of `ramp_s`, constant between); a car's speed goes from
/// `speed_from_mps` to `speed_to_mps` as a raised cosine; a walker's cadence and step
/// length are scaled by the two factors (per leg).
#[derive(Debug, Clone, Copy)]
struct Phase {
    duration_s: f64,
    turn_rad: f64,
    ramp_s: f64,
    speed_from_mps: f64,
    speed_to_mps: f64,
    cadence_factor: f64,
    step_length_factor: f64,
}

impl Phase {
    fn straight(duration_s: f64) -> Phase {
        Phase {
            duration_s,
            turn_rad: 0.0,
            ramp_s: 0.0,
            speed_from_mps: 0.0,
            speed_to_mps: 0.0,
            cadence_factor: 1.0,
            step_length_factor: 1.0,
        }
    }

    fn turn(duration_s: f64, turn_rad: f64, ramp_s: f64) -> Phase {
        Phase {
            turn_rad,
            ramp_s,
            ..Phase::straight(duration_s)
        }
    }

    /// A car at constant speed.
    fn cruise(duration_s: f64, speed_mps: f64) -> Phase {
        Phase {
            speed_from_mps: speed_mps,
            speed_to_mps: speed_mps,
            ..Phase::straight(duration_s)
        }
    }

    fn is_straight(&self) -> bool {
        self.turn_rad == 0.0
    }

    /// Fraction of the turn done `tau_s` into the phase (0 to 1).
    fn turn_fraction(&self, tau_s: f64) -> f64 {
        let (length, ramp) = (
            self.duration_s,
            self.ramp_s.clamp(1e-6, self.duration_s / 2.0),
        );
        let tau = tau_s.clamp(0.0, length);
        let ramp_area = |x: f64| x / 2.0 - ramp / (2.0 * PI) * (PI * x / ramp).sin();
        let area = if tau < ramp {
            ramp_area(tau)
        } else if tau <= length - ramp {
            ramp / 2.0 + (tau - ramp)
        } else {
            (length - ramp) - ramp_area(length - tau)
        };
        area / (length - ramp)
    }

    /// Turn rate as a fraction of the turn per second.
    fn turn_rate_fraction(&self, tau_s: f64) -> f64 {
        let (length, ramp) = (
            self.duration_s,
            self.ramp_s.clamp(1e-6, self.duration_s / 2.0),
        );
        if !(0.0..=length).contains(&tau_s) {
            return 0.0;
        }
        let edge = tau_s.min(length - tau_s);
        let window = if edge < ramp {
            0.5 * (1.0 - (PI * edge / ramp).cos())
        } else {
            1.0
        };
        window / (length - ramp)
    }

    /// Speed (m/s) and its rate (m/s²) `tau_s` into the phase.
    fn speed(&self, tau_s: f64) -> (f64, f64) {
        let change = self.speed_to_mps - self.speed_from_mps;
        let x = (tau_s / self.duration_s).clamp(0.0, 1.0);
        let speed = self.speed_from_mps + change * 0.5 * (1.0 - (PI * x).cos());
        let rate = if (0.0..1.0).contains(&x) {
            change * PI / (2.0 * self.duration_s) * (PI * x).sin()
        } else {
            0.0
        };
        (speed, rate)
    }
}

/// A route: phases one after another from a start heading.
#[derive(Debug, Clone)]
struct Plan {
    phases: Vec<Phase>,
    start_s: Vec<f64>,
    heading_before_rad: Vec<f64>,
}

impl Plan {
    fn new(start_heading_rad: f64, phases: Vec<Phase>) -> Plan {
        assert!(!phases.is_empty(), "a route has at least one phase");
        let mut start_s = Vec::with_capacity(phases.len());
        let mut heading_before_rad = Vec::with_capacity(phases.len());
        let (mut t, mut heading) = (0.0, start_heading_rad);
        for phase in &phases {
            start_s.push(t);
            heading_before_rad.push(heading);
            t += phase.duration_s;
            heading += phase.turn_rad;
        }
        Plan {
            phases,
            start_s,
            heading_before_rad,
        }
    }

    fn duration_s(&self) -> f64 {
        self.start_s.last().copied().unwrap_or(0.0)
            + self.phases.last().map_or(0.0, |phase| phase.duration_s)
    }

    /// The phase at `t_s` (clamped to the route) and the time into it.
    fn locate(&self, t_s: f64) -> (usize, f64) {
        let index = self.start_s.partition_point(|&start| start <= t_s).max(1) - 1;
        (index, t_s - self.start_s[index])
    }

    /// Direction of travel (rad clockwise from north, not wrapped).
    fn heading_rad(&self, t_s: f64) -> f64 {
        let (index, tau) = self.locate(t_s);
        let phase = &self.phases[index];
        let turned = if phase.is_straight() {
            0.0
        } else {
            phase.turn_rad * phase.turn_fraction(tau)
        };
        self.heading_before_rad[index] + turned
    }

    fn turn_rate_radps(&self, t_s: f64) -> f64 {
        let (index, tau) = self.locate(t_s);
        let phase = &self.phases[index];
        if phase.is_straight() {
            0.0
        } else {
            phase.turn_rad * phase.turn_rate_fraction(tau)
        }
    }

    /// A car's speed (m/s) and its rate (m/s²).
    fn speed(&self, t_s: f64) -> (f64, f64) {
        let (index, tau) = self.locate(t_s);
        self.phases[index].speed(tau)
    }

    /// A per-leg factor, blended from the previous leg's over the first 2 s of a leg.
    fn blended(&self, t_s: f64, factor: impl Fn(&Phase) -> f64) -> f64 {
        let (index, tau) = self.locate(t_s);
        let current = factor(&self.phases[index]);
        if index == 0 {
            return current;
        }
        let previous = factor(&self.phases[index - 1]);
        previous + (current - previous) * smoothstep(tau / 2.0)
    }
}

/// Draws the per-leg gait factors of every phase: cadence ±4 %, step length ±5 %.
fn with_leg_gait(rng: &mut Rng, mut phases: Vec<Phase>) -> Vec<Phase> {
    for phase in &mut phases {
        phase.cadence_factor = 1.0 + rng.symmetric(0.04);
        phase.step_length_factor = 1.0 + rng.symmetric(0.05);
    }
    phases
}

/// Trims or extends the route so that it lasts exactly `total_s`, changing only straight
/// phases at its end.
fn fit_to_duration(phases: &mut Vec<Phase>, total_s: f64) {
    loop {
        let excess = phases.iter().map(|phase| phase.duration_s).sum::<f64>() - total_s;
        if let Some(last) = phases.last_mut() {
            if last.is_straight() && last.duration_s - excess >= 5.0 {
                last.duration_s -= excess;
                return;
            }
        }
        if excess <= 0.0 || phases.is_empty() {
            phases.push(Phase::straight(-excess));
            return;
        }
        phases.pop();
    }
}

/// Seconds for the walker to stand, start and settle into the first leg.
const WALK_LEAD_IN_S: f64 = 8.0;
/// Seconds of straight walking, slowing and standing at the end.
const WALK_LEAD_OUT_S: f64 = 6.0;

/// Loops (360° or 720°, radius 6-15 m) in each half of the walk, between straight
/// stretches of 5-25 s and smooth turns of 30-180° over 3-10 s.
fn loops_route(rng: &mut Rng, total_s: f64, speed_mps: f64) -> Plan {
    let start_heading = rng.range(0.0, TAU);
    let half_s = total_s / 2.0;
    let mut phases = Vec::new();
    for half in 0..2 {
        let lead_in = if half == 0 { WALK_LEAD_IN_S } else { 0.0 };
        let lead_out = if half == 1 { WALK_LEAD_OUT_S } else { 0.0 };
        let mut loops: Vec<Phase> = (0..=rng.index(2))
            .map(|_| {
                let radius_m = rng.range(6.0, 15.0);
                let turns = if rng.uniform() < 0.25 { 2.0 } else { 1.0 };
                let turn_rad = rng.sign() * turns * TAU;
                Phase::turn(turn_rad.abs() * radius_m / speed_mps, turn_rad, 2.0)
            })
            .collect();
        // Loops fill at most 60 % of a half (tighter circles when the walk is short).
        let loops_s: f64 = loops.iter().map(|phase| phase.duration_s).sum();
        let scale = (0.6 * (half_s - lead_in - lead_out) / loops_s).min(1.0);
        for phase in &mut loops {
            phase.duration_s *= scale;
        }
        let budget_s = half_s - lead_in - lead_out - loops_s * scale;
        let mut fill = Vec::new();
        let mut used_s = 0.0;
        while used_s < budget_s {
            let phase = if fill.len() % 2 == 0 {
                Phase::straight(rng.range(5.0, 25.0))
            } else {
                let duration_s = rng.range(3.0, 10.0);
                let turn_rad = rng.sign() * rng.range(30.0, 180.0).to_radians();
                Phase::turn(duration_s, turn_rad, duration_s / 2.0)
            };
            used_s += phase.duration_s;
            fill.push(phase);
        }
        fit_to_duration(&mut fill, budget_s);
        for phase in loops {
            let at = rng.index(fill.len() + 1);
            fill.insert(at, phase);
        }
        if half == 0 {
            phases.push(Phase::straight(lead_in));
        }
        phases.extend(fill);
        if half == 1 {
            phases.push(Phase::straight(lead_out));
        }
    }
    Plan::new(start_heading, with_leg_gait(rng, phases))
}

/// Four directions 90° apart (a random grid orientation), legs of 20-80 m, 90° turns
/// over 1.5-3 s; turns favour the least walked direction so that all four occur.
fn grid_route(rng: &mut Rng, total_s: f64, speed_mps: f64) -> Plan {
    let grid_rad = rng.range(0.0, TAU);
    let first_direction = rng.index(4);
    let mut direction = first_direction;
    let mut walked = [0_usize; 4];
    walked[direction] += 1;
    let leg_s = |rng: &mut Rng| rng.range(20.0, 80.0) / speed_mps;
    let mut phases = vec![Phase::straight(WALK_LEAD_IN_S + leg_s(rng))];
    let mut elapsed_s = phases[0].duration_s;
    while elapsed_s < total_s {
        let right = (direction + 1) % 4;
        let left = (direction + 3) % 4;
        let go_right = if rng.uniform() < 0.7 && walked[right] != walked[left] {
            walked[right] < walked[left]
        } else {
            rng.sign() > 0.0
        };
        let (next, turn_rad) = if go_right {
            (right, FRAC_PI_2)
        } else {
            (left, -FRAC_PI_2)
        };
        direction = next;
        walked[direction] += 1;
        let turn_s = rng.range(1.5, 3.0);
        let leg = leg_s(rng);
        phases.push(Phase::turn(turn_s, turn_rad, turn_s / 2.0));
        phases.push(Phase::straight(leg));
        elapsed_s += turn_s + leg;
    }
    fit_to_duration(&mut phases, total_s);
    let start_heading = grid_rad + first_direction as f64 * FRAC_PI_2;
    Plan::new(start_heading, with_leg_gait(rng, phases))
}

/// 3-5 headings at least 40° apart; straight legs of 20-80 m, each to a different heading
/// than the last, with sharp turns (1 s plus 1 s per 90°).
fn few_headings_route(rng: &mut Rng, total_s: f64, speed_mps: f64) -> Plan {
    let count = 3 + rng.index(3);
    let min_gap_rad = 40_f64.to_radians();
    let headings: Vec<f64> = (0..1000)
        .map(|_| {
            (0..count)
                .map(|_| rng.range(0.0, TAU))
                .collect::<Vec<f64>>()
        })
        .find(|candidate| {
            candidate.iter().enumerate().all(|(i, a)| {
                candidate[i + 1..]
                    .iter()
                    .all(|b| wrap_pi(a - b).abs() >= min_gap_rad)
            })
        })
        .unwrap_or_else(|| (0..count).map(|i| i as f64 * TAU / count as f64).collect());
    let first = rng.index(count);
    let mut current = first;
    let leg_s = |rng: &mut Rng| rng.range(20.0, 80.0) / speed_mps;
    let mut phases = vec![Phase::straight(WALK_LEAD_IN_S + leg_s(rng))];
    let mut elapsed_s = phases[0].duration_s;
    while elapsed_s < total_s {
        let next = (current + 1 + rng.index(count - 1)) % count;
        let turn_rad = wrap_pi(headings[next] - headings[current]);
        let turn_s = 1.0 + turn_rad.abs() / FRAC_PI_2;
        let leg = leg_s(rng);
        phases.push(Phase::turn(turn_s, turn_rad, turn_s / 2.0));
        phases.push(Phase::straight(leg));
        elapsed_s += turn_s + leg;
        current = next;
    }
    fit_to_duration(&mut phases, total_s);
    Plan::new(headings[first], with_leg_gait(rng, phases))
}

/// A speed change from `from` to `to` at a mean 0.8-1.25 m/s² (peak ≤ 1.96 m/s²).
fn speed_change(rng: &mut Rng, from_mps: f64, to_mps: f64) -> Phase {
    let duration_s = ((to_mps - from_mps).abs() / rng.range(0.8, 1.25)).max(0.5);
    Phase {
        speed_from_mps: from_mps,
        speed_to_mps: to_mps,
        ..Phase::straight(duration_s)
    }
}

/// A city drive: stretches at 8-20 m/s (some with a gentle bend), turns at 3-6 m/s
/// (mostly 90°, also 30-150°, U-turns and roundabouts), stops at lights.
fn city_route(rng: &mut Rng, total_s: f64) -> Plan {
    let start_heading = rng.range(0.0, TAU);
    let mut phases = vec![Phase::straight(rng.range(3.0, 8.0))];
    let elapsed_s = |phases: &[Phase]| phases.iter().map(|phase| phase.duration_s).sum::<f64>();
    let mut speed_mps = 0.0;
    while elapsed_s(&phases) < total_s - 60.0 {
        let cruise_mps = if rng.uniform() < 0.6 {
            rng.range(8.0, 14.0)
        } else {
            rng.range(14.0, 20.0)
        };
        phases.push(speed_change(rng, speed_mps, cruise_mps));
        let cruise_s = if rng.uniform() < 0.15 {
            rng.range(60.0, 120.0)
        } else {
            rng.range(8.0, 40.0)
        };
        let mut stretch = Phase::cruise(cruise_s, cruise_mps);
        if rng.uniform() < 0.3 {
            stretch.turn_rad = rng.sign() * rng.range(15.0, 60.0).to_radians();
            stretch.ramp_s = cruise_s / 2.0;
        }
        phases.push(stretch);
        let turn_mps = rng.range(3.0, 6.0);
        if rng.uniform() < 0.3 {
            phases.push(speed_change(rng, cruise_mps, 0.0));
            phases.push(Phase::straight(rng.range(5.0, 40.0)));
            phases.push(speed_change(rng, 0.0, turn_mps));
        } else {
            phases.push(speed_change(rng, cruise_mps, turn_mps));
        }
        let pick = rng.uniform();
        let turn_rad = rng.sign()
            * if pick < 0.65 {
                FRAC_PI_2
            } else if pick < 0.9 {
                rng.range(30.0, 150.0).to_radians()
            } else if pick < 0.95 {
                PI
            } else {
                1.5 * PI
            };
        let radius_m = rng.range(8.0, 25.0);
        // Long enough for the radius, and for a lateral acceleration of at most 3 m/s²
        // (a Hann-shaped rate peaks at twice its mean).
        let turn_s =
            (1.5 * turn_rad.abs() * radius_m / turn_mps).max(2.0 * turn_mps * turn_rad.abs() / 3.0);
        phases.push(Phase {
            speed_from_mps: turn_mps,
            speed_to_mps: turn_mps,
            ..Phase::turn(turn_s, turn_rad, turn_s / 2.0)
        });
        speed_mps = turn_mps;
    }
    phases.push(speed_change(rng, speed_mps, 0.0));
    phases.push(Phase::straight(rng.range(3.0, 6.0)));
    Plan::new(start_heading, phases)
}

/// Open roads: cruising at 5-20 m/s, then a turn of 30-180° with a radius of 10-200 m
/// (log-uniform), taken at a speed whose peak centripetal acceleration (twice the mean
/// under the raised-cosine rate) is at most 6 m/s².
fn open_route(rng: &mut Rng, total_s: f64) -> Plan {
    let start_heading = rng.range(0.0, TAU);
    let mut phases = vec![Phase::straight(rng.range(3.0, 8.0))];
    let elapsed_s = |phases: &[Phase]| phases.iter().map(|phase| phase.duration_s).sum::<f64>();
    let mut speed_mps = 0.0;
    while elapsed_s(&phases) < total_s - 60.0 {
        let cruise_mps = rng.range(5.0, 20.0);
        phases.push(speed_change(rng, speed_mps, cruise_mps));
        phases.push(Phase::cruise(rng.range(5.0, 30.0), cruise_mps));
        let radius_m = 10.0 * 20f64.powf(rng.uniform());
        let turn_mps = cruise_mps.min((3.0 * radius_m).sqrt());
        if turn_mps < cruise_mps {
            phases.push(speed_change(rng, cruise_mps, turn_mps));
        }
        let turn_rad = rng.sign() * rng.range(30.0, 180.0).to_radians();
        let turn_s = turn_rad.abs() * radius_m / turn_mps;
        phases.push(Phase {
            speed_from_mps: turn_mps,
            speed_to_mps: turn_mps,
            ..Phase::turn(turn_s, turn_rad, turn_s / 2.0)
        });
        speed_mps = turn_mps;
    }
    phases.push(speed_change(rng, speed_mps, 0.0));
    phases.push(Phase::straight(rng.range(3.0, 6.0)));
    Plan::new(start_heading, phases)
}

// ---------------------------------------------------------------------------------------
// Motion: the walker and the car, on a half-sample grid
// ---------------------------------------------------------------------------------------

/// The true motion. Attitudes are kept on a half-sample grid (index `2k + 1` is sample k,
/// `2k` and `2k + 2` the instants half a sample before and after) so that gyro rates
/// are centred on their samples; the rest is per sample.
struct Track {
    attitude_fine: Vec<Rotation3<f64>>,
    position_ned_m: Vec<Vector3<f64>>,
    velocity_ned_mps: Vec<Vector3<f64>>,
    acceleration_ned_mps2: Vec<Vector3<f64>>,
    distance_m: f64,
}

impl Track {
    fn samples(&self) -> usize {
        self.position_ned_m.len()
    }

    fn attitude(&self, sample: usize) -> Rotation3<f64> {
        self.attitude_fine[2 * sample + 1]
    }

    /// The body rate over the sample (rad/s, body axes).
    fn body_rate_radps(&self, sample: usize, dt_s: f64) -> Vector3<f64> {
        let before = self.attitude_fine[2 * sample];
        let after = self.attitude_fine[2 * sample + 2];
        (before.inverse() * after).scaled_axis() / dt_s
    }

    /// The track from attitudes and velocities on the half-sample grid: positions by the
    /// trapezoid rule, from 0 at sample 0; accelerations by central differences of the
    /// velocity, plus `extra_acceleration` (the step oscillations; one per sample).
    fn from_motion(
        attitude_fine: Vec<Rotation3<f64>>,
        velocity_fine: &[Vector3<f64>],
        extra_acceleration: &[Vector3<f64>],
        dt_s: f64,
    ) -> Track {
        let h = dt_s / 2.0;
        let samples = extra_acceleration.len();
        let mut position = Vector3::zeros();
        let mut distance_m = 0.0;
        let mut position_ned_m = Vec::with_capacity(samples);
        let mut velocity_ned_mps = Vec::with_capacity(samples);
        let mut acceleration_ned_mps2 = Vec::with_capacity(samples);
        for (k, extra) in extra_acceleration.iter().enumerate() {
            let j = 2 * k + 1;
            if k > 0 {
                for i in j - 2..j {
                    let step = h * (velocity_fine[i] + velocity_fine[i + 1]) / 2.0;
                    position += step;
                    distance_m += step.xy().norm();
                }
            }
            position_ned_m.push(position);
            velocity_ned_mps.push(velocity_fine[j]);
            acceleration_ned_mps2
                .push((velocity_fine[j + 1] - velocity_fine[j - 1]) / dt_s + extra);
        }
        Track {
            attitude_fine,
            position_ned_m,
            velocity_ned_mps,
            acceleration_ned_mps2,
            distance_m,
        }
    }
}

/// Time of half-sample grid point `j` (`t = (j − 1)·Δt/2`).
fn fine_time_s(j: usize, dt_s: f64) -> f64 {
    (j as f64 - 1.0) * dt_s / 2.0
}

/// North-east-down unit vectors along and to the right of a horizontal heading.
fn along_and_right(heading_rad: f64) -> (Vector3<f64>, Vector3<f64>) {
    let (sin, cos) = heading_rad.sin_cos();
    (Vector3::new(cos, sin, 0.0), Vector3::new(-sin, cos, 0.0))
}

/// One walker's gait, drawn per log.
#[derive(Debug, Clone, Copy)]
struct Gait {
    cadence_hz: f64,
    cadence_wander: Wander,
    step_length_m: f64,
    stand_start_s: f64,
    stand_end_s: f64,
    bounce_mps2: f64,
    fore_aft_mps2: f64,
    lateral_mps2: f64,
    /// Phases of the bounce's second harmonic, the fore-aft and the lateral sway (rad).
    phases_rad: [f64; 3],
}

impl Gait {
    fn draw(rng: &mut Rng) -> Gait {
        Gait {
            cadence_hz: rng.range(1.7, 2.0),
            cadence_wander: Wander::draw(rng, 0.02, (1.0 / 180.0, 1.0 / 60.0)),
            step_length_m: rng.range(0.6, 0.8),
            stand_start_s: rng.range(2.0, 3.0),
            stand_end_s: rng.range(2.0, 3.0),
            bounce_mps2: rng.range(1.5, 3.0),
            fore_aft_mps2: rng.range(0.8, 1.5),
            lateral_mps2: rng.range(0.3, 0.8),
            phases_rad: [
                rng.range(0.0, TAU),
                rng.range(0.0, TAU),
                rng.range(0.0, TAU),
            ],
        }
    }

    fn typical_speed_mps(&self) -> f64 {
        self.cadence_hz * self.step_length_m
    }

    /// 0 while standing, 1 while walking, smooth over 1.5 s between.
    fn envelope(&self, t_s: f64, total_s: f64) -> f64 {
        const RAMP_S: f64 = 1.5;
        smoothstep((t_s - self.stand_start_s) / RAMP_S)
            * smoothstep((total_s - self.stand_end_s - t_s) / RAMP_S)
    }

    fn cadence_at(&self, plan: &Plan, t_s: f64) -> f64 {
        let leg = plan.blended(t_s, |phase| phase.cadence_factor);
        (self.cadence_hz * leg * (1.0 + self.cadence_wander.at(t_s))).clamp(1.6, 2.1)
    }

    /// This step's length: per log, per leg and per step, within 0.55-0.85 m.
    fn step_length_m(&self, plan: &Plan, t_s: f64, step: &StepVariation) -> f64 {
        (self.step_length_m * plan.blended(t_s, |phase| phase.step_length_factor) * step.length)
            .clamp(0.55, 0.85)
    }

    /// The step oscillations in NED at step phase `steps` (in steps) and per-step
    /// variation `step`, scaled by the walking envelope.
    fn oscillation_ned_mps2(
        &self,
        steps: f64,
        envelope: f64,
        heading_rad: f64,
        step: &StepVariation,
    ) -> Vector3<f64> {
        let angle = TAU * steps;
        let [second_harmonic, fore_aft, lateral] = self.phases_rad;
        let vertical = self.bounce_mps2
            * step.bounce
            * (0.8 * angle.cos() + 0.2 * (2.0 * angle + second_harmonic).cos());
        let forward = self.fore_aft_mps2
            * step.fore_aft
            * (0.8 * (angle + fore_aft).sin() + 0.2 * (2.0 * angle + fore_aft).sin());
        let sideways = self.lateral_mps2 * step.lateral * (angle / 2.0 + lateral).sin();
        let (along, right) = along_and_right(heading_rad);
        envelope * (forward * along + sideways * right + Vector3::new(0.0, 0.0, vertical))
    }
}

/// Per-step factors (each near 1).
#[derive(Debug, Clone, Copy)]
struct StepVariation {
    length: f64,
    bounce: f64,
    fore_aft: f64,
    lateral: f64,
}

impl StepVariation {
    fn draw(rng: &mut Rng) -> StepVariation {
        StepVariation {
            length: 1.0 + rng.symmetric(0.05),
            bounce: 1.0 + rng.symmetric(0.1),
            fore_aft: 1.0 + rng.symmetric(0.1),
            lateral: 1.0 + rng.symmetric(0.1),
        }
    }

    fn blend(&self, next: &StepVariation, x: f64) -> StepVariation {
        let mix = |a: f64, b: f64| a + (b - a) * smoothstep(x);
        StepVariation {
            length: mix(self.length, next.length),
            bounce: mix(self.bounce, next.bounce),
            fore_aft: mix(self.fore_aft, next.fore_aft),
            lateral: mix(self.lateral, next.lateral),
        }
    }
}

/// The per-step variations, drawn as the walk reaches them.
struct Steps {
    table: Vec<StepVariation>,
    rng: Rng,
}

impl Steps {
    /// The variation at step phase `steps`, blended smoothly from one step to the next.
    fn at(&mut self, steps: f64) -> StepVariation {
        let index = steps.max(0.0).floor() as usize;
        while self.table.len() < index + 2 {
            self.table.push(StepVariation::draw(&mut self.rng));
        }
        self.table[index].blend(&self.table[index + 1], steps - index as f64)
    }
}

/// How the phone is held, drawn per log.
#[derive(Debug, Clone, Copy)]
struct HandPose {
    misalignment_rad: f64,
    pitch_tilt: Wander,
    roll_tilt: Wander,
    /// Sway amplitudes (rad) and phases (rad): yaw at half the step frequency, pitch and
    /// roll at the step frequency.
    sway_rad: [f64; 3],
    sway_phase_rad: [f64; 3],
    swing: Option<Swing>,
}

/// A phone swinging in the hand at the end of the arm, pivoting at the shoulder in the
/// walking plane: the arm's angle from the vertical is `θ = A·sin(π·steps + φ)` (half the
/// step frequency), the phone pitches with it, and sits `L·(sin θ along + cos θ down)`
/// from the shoulder, whose second derivative (the arm's tangential and centripetal
/// accelerations) the accelerometer feels.
#[derive(Debug, Clone, Copy)]
struct Swing {
    amplitude_rad: f64,
    arm_m: f64,
    phase_rad: f64,
}

impl Swing {
    fn draw(rng: &mut Rng, amplitude_deg: (f64, f64)) -> Swing {
        Swing {
            amplitude_rad: rng.range(amplitude_deg.0, amplitude_deg.1).to_radians(),
            arm_m: rng.range(0.55, 0.75),
            phase_rad: rng.range(0.0, TAU),
        }
    }

    /// The arm's angle from the vertical (rad), forward positive.
    fn angle_rad(&self, steps: f64, envelope: f64) -> f64 {
        envelope * self.amplitude_rad * (PI * steps + self.phase_rad).sin()
    }

    /// The phone from the shoulder (NED metres).
    fn offset_ned_m(&self, steps: f64, envelope: f64, heading_rad: f64) -> Vector3<f64> {
        let angle = self.angle_rad(steps, envelope);
        let (along, _) = along_and_right(heading_rad);
        self.arm_m * (angle.sin() * along + Vector3::new(0.0, 0.0, angle.cos()))
    }
}

impl HandPose {
    fn draw(rng: &mut Rng, tilt_amplitude_deg: (f64, f64)) -> HandPose {
        let tilt_rad = rng
            .range(tilt_amplitude_deg.0, tilt_amplitude_deg.1)
            .to_radians();
        let mut sway = || rng.range(1.0, 2.0).to_radians();
        let sway_rad = [sway(), sway(), sway()];
        HandPose {
            misalignment_rad: rng.symmetric(3.0).to_radians(),
            pitch_tilt: Wander::draw(rng, tilt_rad, (0.02, 0.3)),
            roll_tilt: Wander::draw(rng, tilt_rad, (0.02, 0.3)),
            sway_rad,
            sway_phase_rad: [
                rng.range(0.0, TAU),
                rng.range(0.0, TAU),
                rng.range(0.0, TAU),
            ],
            swing: None,
        }
    }

    fn attitude(
        &self,
        t_s: f64,
        walk_heading_rad: f64,
        steps: f64,
        envelope: f64,
    ) -> Rotation3<f64> {
        let [yaw_sway, pitch_sway, roll_sway] = self.sway_rad;
        let [yaw_phase, pitch_phase, roll_phase] = self.sway_phase_rad;
        let angle = TAU * steps;
        let yaw = walk_heading_rad
            + self.misalignment_rad
            + envelope * yaw_sway * (angle / 2.0 + yaw_phase).sin();
        let swing = self
            .swing
            .map_or(0.0, |swing| swing.angle_rad(steps, envelope));
        let pitch =
            self.pitch_tilt.at(t_s) + envelope * pitch_sway * (angle + pitch_phase).sin() + swing;
        let roll = self.roll_tilt.at(t_s) + envelope * roll_sway * (angle + roll_phase).sin();
        attitude_zyx(yaw, pitch, roll)
    }
}

/// The walker: speed = cadence × step length along the plan's heading, step phase
/// integrated from the cadence, the phone's attitude from the hand pose.
fn walk_track(
    plan: &Plan,
    gait: &Gait,
    hand: &HandPose,
    samples: usize,
    dt_s: f64,
    steps_rng: Rng,
) -> Track {
    let h = dt_s / 2.0;
    let total_s = plan.duration_s();
    let fine = 2 * samples + 1;
    let mut steps = Steps {
        table: Vec::new(),
        rng: steps_rng,
    };
    let mut step_phase = 0.0;
    let mut attitude_fine = Vec::with_capacity(fine);
    let mut velocity_fine = Vec::with_capacity(fine);
    let mut oscillation = Vec::with_capacity(samples);
    let mut swing_offset_fine = Vec::with_capacity(if hand.swing.is_some() { fine } else { 0 });
    for j in 0..fine {
        let t = fine_time_s(j, dt_s);
        let envelope = gait.envelope(t, total_s);
        let cadence_hz = gait.cadence_at(plan, t);
        let step = steps.at(step_phase);
        let speed_mps = envelope * cadence_hz * gait.step_length_m(plan, t, &step);
        let heading = plan.heading_rad(t);
        velocity_fine.push(along_and_right(heading).0 * speed_mps);
        attitude_fine.push(hand.attitude(t, heading, step_phase, envelope));
        if let Some(swing) = &hand.swing {
            swing_offset_fine.push(swing.offset_ned_m(step_phase, envelope, heading));
        }
        if j % 2 == 1 {
            oscillation.push(gait.oscillation_ned_mps2(step_phase, envelope, heading, &step));
        }
        step_phase += envelope * cadence_hz * h;
    }
    // The swinging phone's acceleration about the shoulder, by second differences on the
    // half-sample grid (the same angles that turn it).
    if !swing_offset_fine.is_empty() {
        for (k, extra) in oscillation.iter_mut().enumerate() {
            let j = 2 * k + 1;
            *extra += (swing_offset_fine[j + 1] - 2.0 * swing_offset_fine[j]
                + swing_offset_fine[j - 1])
                / (h * h);
        }
    }
    Track::from_motion(attitude_fine, &velocity_fine, &oscillation, dt_s)
}

/// The car and its mount, drawn per log.
#[derive(Debug, Clone, Copy)]
struct Car {
    /// Road grade (rad) as a function of distance along the road (m).
    road_pitch: Wander,
    /// Body pitch per m/s² of longitudinal acceleration (rad; braking dips the nose).
    dive_rad_per_mps2: f64,
    /// Body roll per m/s² of lateral acceleration (rad; the car leans out of turns).
    roll_rad_per_mps2: f64,
    /// Phone in the mount relative to the car.
    mount: Rotation3<f64>,
    upright: bool,
}

impl Car {
    fn draw(rng: &mut Rng, road_pitch_max_deg: f64) -> Car {
        let amplitude_rad = rng.range(0.5, 1.0) * road_pitch_max_deg.to_radians();
        let road_pitch = Wander::draw(rng, amplitude_rad, (1.0 / 1500.0, 1.0 / 150.0));
        // Upright (vent or dashboard) mounts lean more than flat ones.
        let upright = rng.sign() > 0.0;
        let lean_deg = if upright { 8.0 } else { 3.0 };
        let mount = attitude_zyx(
            rng.symmetric(2.0).to_radians(),
            rng.symmetric(lean_deg).to_radians(),
            rng.symmetric(3.0).to_radians(),
        );
        Car {
            road_pitch,
            dive_rad_per_mps2: rng.range(0.3, 0.6).to_radians(),
            roll_rad_per_mps2: rng.range(0.4, 0.8).to_radians(),
            mount,
            upright,
        }
    }
}

/// The car: speed and heading from the plan, grade from the road, body pitch and roll
/// from the accelerations, the phone fixed in its mount.
fn drive_track(plan: &Plan, car: &Car, samples: usize, dt_s: f64) -> Track {
    let h = dt_s / 2.0;
    let fine = 2 * samples + 1;
    let mut attitude_fine = Vec::with_capacity(fine);
    let mut velocity_fine = Vec::with_capacity(fine);
    let mut road_m = 0.0;
    let mut previous_speed = 0.0;
    for j in 0..fine {
        let t = fine_time_s(j, dt_s);
        let (speed_mps, speed_rate_mps2) = plan.speed(t);
        if j > 0 {
            road_m += h * (speed_mps + previous_speed) / 2.0;
        }
        previous_speed = speed_mps;
        let heading = plan.heading_rad(t);
        let lateral_mps2 = speed_mps * plan.turn_rate_radps(t);
        let grade = car.road_pitch.at(road_m);
        let (sin_grade, cos_grade) = grade.sin_cos();
        let (along, _) = along_and_right(heading);
        velocity_fine.push(speed_mps * (cos_grade * along + Vector3::new(0.0, 0.0, -sin_grade)));
        let body = attitude_zyx(
            heading,
            grade + car.dive_rad_per_mps2 * speed_rate_mps2,
            -car.roll_rad_per_mps2 * lateral_mps2,
        );
        attitude_fine.push(body * car.mount);
    }
    let no_oscillation = vec![Vector3::zeros(); samples];
    Track::from_motion(attitude_fine, &velocity_fine, &no_oscillation, dt_s)
}

// ---------------------------------------------------------------------------------------
// Place, date and the Earth's field
// ---------------------------------------------------------------------------------------

/// A real place on land.
#[derive(Debug, Clone, Copy)]
pub struct Place {
    pub name: &'static str,
    pub lat_deg: f64,
    pub lon_deg: f64,
    pub alt_m: f64,
}

/// Cities on five continents, both hemispheres, fields from about 23 µT (Buenos Aires,
/// in the South Atlantic Anomaly) to about 52 µT (Reykjavik, inclination near 77°).
pub const PLACES: [Place; 12] = [
    Place {
        name: "London",
        lat_deg: 51.5072,
        lon_deg: -0.1276,
        alt_m: 15.0,
    },
    Place {
        name: "Munich",
        lat_deg: 48.1372,
        lon_deg: 11.5755,
        alt_m: 520.0,
    },
    Place {
        name: "Reykjavik",
        lat_deg: 64.1355,
        lon_deg: -21.8954,
        alt_m: 30.0,
    },
    Place {
        name: "New York",
        lat_deg: 40.7831,
        lon_deg: -73.9712,
        alt_m: 20.0,
    },
    Place {
        name: "Denver",
        lat_deg: 39.7392,
        lon_deg: -104.9903,
        alt_m: 1609.0,
    },
    Place {
        name: "Mexico City",
        lat_deg: 19.4326,
        lon_deg: -99.1332,
        alt_m: 2240.0,
    },
    Place {
        name: "Buenos Aires",
        lat_deg: -34.6037,
        lon_deg: -58.4316,
        alt_m: 25.0,
    },
    Place {
        name: "Johannesburg",
        lat_deg: -26.2041,
        lon_deg: 28.0473,
        alt_m: 1750.0,
    },
    Place {
        name: "Nairobi",
        lat_deg: -1.2921,
        lon_deg: 36.8219,
        alt_m: 1795.0,
    },
    Place {
        name: "Delhi",
        lat_deg: 28.6139,
        lon_deg: 77.2090,
        alt_m: 215.0,
    },
    Place {
        name: "Tokyo",
        lat_deg: 35.6895,
        lon_deg: 139.6917,
        alt_m: 40.0,
    },
    Place {
        name: "Parramatta (Sydney)",
        lat_deg: -33.8150,
        lon_deg: 151.0011,
        alt_m: 20.0,
    },
];

/// 2021-01-01T00:00:00Z and 2028-01-01T00:00:00Z.
const FIRST_UNIX_S: f64 = 1_609_459_200.0;
const END_UNIX_S: f64 = 1_830_297_600.0;

/// Where and when, and the field there.
struct Setting {
    place: &'static Place,
    origin: Geodetic,
    frame: LocalFrame,
    start_unix_s: f64,
    date: wmm::CalendarDate,
    field_ned_ut: Vector3<f64>,
    declination_deg: f64,
}

impl Setting {
    fn draw(rng: &mut Rng) -> Setting {
        let place = &PLACES[rng.index(PLACES.len())];
        // Within about 300 m of the city's point.
        let origin = Geodetic {
            lat_deg: place.lat_deg + rng.symmetric(0.0027),
            lon_deg: place.lon_deg + rng.symmetric(0.0027) / place.lat_deg.to_radians().cos(),
            alt_m: place.alt_m,
        };
        let start_unix_s =
            (rng.range(FIRST_UNIX_S, END_UNIX_S - 86_400.0) * 1000.0).round() / 1000.0;
        let date = wmm::date_of_unix_s(start_unix_s).expect("a date in 2021-2027");
        let model = wmm::expected_field(origin.lat_deg, origin.lon_deg, origin.alt_m, date)
            .expect("the WMM covers every place and date drawn here");
        // A local anomaly: the true field differs from the model's.
        let total_ut = model.total_ut * (1.0 + rng.symmetric(0.03));
        let inclination = (model.inclination_deg + rng.symmetric(2.0)).to_radians();
        let declination_deg = model.declination_deg + rng.symmetric(1.0);
        let declination = declination_deg.to_radians();
        let field_ned_ut = total_ut
            * Vector3::new(
                inclination.cos() * declination.cos(),
                inclination.cos() * declination.sin(),
                inclination.sin(),
            );
        Setting {
            place,
            origin,
            frame: LocalFrame::at(origin),
            start_unix_s,
            date,
            field_ned_ut,
            declination_deg,
        }
    }
}

// ---------------------------------------------------------------------------------------
// Sensors
// ---------------------------------------------------------------------------------------

/// The magnetometer with its hard and soft iron.
#[derive(Debug, Clone, Copy)]
struct Magnetometer {
    soft_iron: Matrix3<f64>,
    hard_iron_ut: Vector3<f64>,
    noise_ut: f64,
    step_ut: f64,
}

impl Magnetometer {
    fn draw(options: &MagnetometerOptions, rng: &mut Rng) -> Magnetometer {
        let mut soft_iron = Matrix3::identity();
        for row in 0..3 {
            for column in 0..3 {
                if options.symmetric && column < row {
                    soft_iron[(row, column)] = soft_iron[(column, row)];
                    continue;
                }
                soft_iron[(row, column)] += if row == column {
                    rng.symmetric(options.soft_diag_max)
                } else {
                    rng.symmetric(options.soft_cross_max)
                };
            }
        }
        let hard_iron_ut = match options.hard_iron {
            HardIronOptions::PerAxis { max_ut } => Vector3::new(
                rng.symmetric(max_ut),
                rng.symmetric(max_ut),
                rng.symmetric(max_ut),
            ),
            HardIronOptions::Magnitude { min_ut, max_ut } => {
                rng.unit_vector() * rng.range(min_ut, max_ut)
            }
        };
        // Output steps of real parts: 0.01 µT (fine), 1/16 µT, 0.15 µT (AK0991x-like).
        let step_ut = [0.01, 0.0625, 0.15][rng.index(3)];
        Magnetometer {
            soft_iron,
            hard_iron_ut,
            noise_ut: rng.range(0.2, 0.6),
            step_ut,
        }
    }

    /// The reading for an external field in body axes.
    fn measure(&self, field_body_ut: Vector3<f64>, rng: &mut Rng) -> Vector3<f64> {
        let raw =
            self.soft_iron * field_body_ut + self.hard_iron_ut + rng.gaussian3() * self.noise_ut;
        raw.map(|value| (value / self.step_ut).round() * self.step_ut)
    }
}

/// Accelerometer and gyroscope errors.
#[derive(Debug, Clone, Copy)]
struct Imu {
    acc_bias_mps2: Vector3<f64>,
    acc_noise_mps2: f64,
    gyro_bias_radps: Vector3<f64>,
    gyro_wander_radps: f64,
    gyro_wander_s: f64,
    gyro_noise_radps: f64,
}

impl Imu {
    fn draw(rng: &mut Rng) -> Imu {
        let mut symmetric3 =
            |max: f64| Vector3::new(rng.symmetric(max), rng.symmetric(max), rng.symmetric(max));
        let acc_bias_mps2 = symmetric3(0.05);
        let gyro_bias_radps = symmetric3(0.01);
        Imu {
            acc_bias_mps2,
            acc_noise_mps2: rng.range(0.02, 0.05),
            gyro_bias_radps,
            gyro_wander_radps: rng.range(0.0001, 0.0004),
            gyro_wander_s: rng.range(200.0, 600.0),
            gyro_noise_radps: rng.range(0.002, 0.005),
        }
    }
}

/// Road vibration: extra accelerometer and gyro noise growing with speed, first-order
/// low-passed (coefficient 0.6 from sample to sample).
#[derive(Debug, Clone, Copy)]
struct Vibration {
    acc_mps2: f64,
    acc_per_mps: f64,
    gyro_radps: f64,
    gyro_per_mps: f64,
}

impl Vibration {
    const NONE: Vibration = Vibration {
        acc_mps2: 0.0,
        acc_per_mps: 0.0,
        gyro_radps: 0.0,
        gyro_per_mps: 0.0,
    };
    /// Idling engine 0.02 m/s²; 0.26 m/s² at 20 m/s (×1.5 vertically).
    const ROAD: Vibration = Vibration {
        acc_mps2: 0.02,
        acc_per_mps: 0.012,
        gyro_radps: 0.001,
        gyro_per_mps: 0.0002,
    };
}

/// One pass of a magnetic dipole (a car, a bag, a door) past the phone.
#[derive(Debug, Clone, Copy)]
struct DipolePass {
    center_s: f64,
    duration_s: f64,
    /// Unit vectors in NED: the closest approach, the direction of motion (normal to it)
    /// and the moment.
    closest: Vector3<f64>,
    motion: Vector3<f64>,
    moment: Vector3<f64>,
    scale_ut: f64,
}

impl DipolePass {
    fn draw(rng: &mut Rng, center_s: f64, duration_s: f64, amplitude_ut: f64) -> DipolePass {
        let closest = rng.unit_vector();
        let motion = (rng.unit_vector().cross(&closest)).normalize();
        let mut pass = DipolePass {
            center_s,
            duration_s,
            closest,
            motion,
            moment: rng.unit_vector(),
            scale_ut: 1.0,
        };
        let peak = (0..=80)
            .map(|i| {
                let t = center_s + duration_s * (i as f64 / 80.0 - 0.5);
                pass.field_ned_ut(t).norm()
            })
            .fold(0.0, f64::max);
        pass.scale_ut = amplitude_ut / peak.max(1e-12);
        pass
    }

    /// The field in NED (µT), zero outside the pass.
    fn field_ned_ut(&self, t_s: f64) -> Vector3<f64> {
        let tau = (t_s - self.center_s) / self.duration_s;
        if tau.abs() >= 0.5 {
            return Vector3::zeros();
        }
        // From −2 to +2 closest distances along the track over the pass.
        let offset = self.closest + self.motion * (4.0 * tau);
        let distance = offset.norm();
        let direction = offset / distance;
        let dipole =
            (3.0 * self.moment.dot(&direction) * direction - self.moment) / distance.powi(3);
        let window = (PI * tau).cos().powi(2);
        self.scale_ut * window * dipole
    }
}

/// Non-overlapping dipole passes covering a fraction of the log (none in its first 10 s).
fn draw_moving_iron(
    options: Option<MovingIronOptions>,
    total_s: f64,
    rng: &mut Rng,
) -> Vec<DipolePass> {
    let Some(options) = options else {
        return Vec::new();
    };
    const CLEAR_START_S: f64 = 10.0;
    let target_s = options.time_fraction * total_s;
    let mut passes: Vec<DipolePass> = Vec::new();
    let mut covered_s = 0.0;
    for _ in 0..10_000 {
        if covered_s >= target_s {
            break;
        }
        let duration_s = rng
            .range(options.duration_s.0, options.duration_s.1)
            .min(target_s - covered_s + options.duration_s.0);
        let center_s = rng.range(CLEAR_START_S + duration_s / 2.0, total_s - duration_s / 2.0);
        let overlaps = passes.iter().any(|pass| {
            (pass.center_s - center_s).abs() < (pass.duration_s + duration_s) / 2.0 + 1.0
        });
        if !overlaps {
            let amplitude_ut = rng.range(options.amplitude_ut.0, options.amplitude_ut.1);
            passes.push(DipolePass::draw(rng, center_s, duration_s, amplitude_ut));
            covered_s += duration_s;
        }
    }
    passes.sort_by(|a, b| a.center_s.total_cmp(&b.center_s));
    passes
}

/// The GNSS receiver's errors.
#[derive(Debug, Clone, Copy)]
struct Gnss {
    markov_sigma_m: f64,
    correlation_s: f64,
    white_sigma_m: f64,
    along_sigma_mps: f64,
    across_sigma_mps: f64,
    stated_scale: f64,
}

/// One fix, on a sample's row.
#[derive(Debug, Clone, Copy)]
struct Fix {
    sample: usize,
    lat_deg: f64,
    lon_deg: f64,
    speed_mps: f64,
    course_deg: Option<f64>,
    hacc_m: f64,
}

impl Gnss {
    fn draw(rng: &mut Rng) -> Gnss {
        let course_sigma_at_walking_rad = rng.range(2.0, 5.0).to_radians();
        Gnss {
            markov_sigma_m: rng.range(1.5, 4.0),
            correlation_s: rng.range(20.0, 60.0),
            white_sigma_m: 0.5,
            along_sigma_mps: rng.range(0.1, 0.2),
            across_sigma_mps: 1.4 * course_sigma_at_walking_rad.tan(),
            stated_scale: rng.range(0.8, 1.25),
        }
    }

    fn sigma_m(&self) -> f64 {
        self.markov_sigma_m.hypot(self.white_sigma_m)
    }

    /// Fixes on every whole second; the error process runs through outages too.
    fn fixes(
        &self,
        track: &Track,
        frame: &LocalFrame,
        sample_rate_hz: f64,
        outage_s: Option<(f64, f64)>,
        rng: &mut Rng,
    ) -> Vec<Fix> {
        let per_second = sample_rate_hz.round() as usize;
        let decay = (-1.0 / self.correlation_s).exp();
        let innovation = self.markov_sigma_m * (1.0 - decay * decay).sqrt();
        let mut markov_m = Vector2::new(rng.gaussian(), rng.gaussian()) * self.markov_sigma_m;
        let mut fixes = Vec::new();
        for (second, sample) in (0..track.samples()).step_by(per_second).enumerate() {
            if second > 0 {
                markov_m =
                    markov_m * decay + Vector2::new(rng.gaussian(), rng.gaussian()) * innovation;
            }
            let error_en_m =
                markov_m + Vector2::new(rng.gaussian(), rng.gaussian()) * self.white_sigma_m;
            let position = track.position_ned_m[sample];
            let velocity = track.velocity_ned_mps[sample];
            let true_en_mps = Vector2::new(velocity.y, velocity.x);
            let along = if true_en_mps.norm() > 1e-6 {
                true_en_mps.normalize()
            } else {
                Vector2::new(0.0, 1.0)
            };
            let right = Vector2::new(along.y, -along.x);
            let measured_en_mps = true_en_mps
                + along * (rng.gaussian() * self.along_sigma_mps)
                + right * (rng.gaussian() * self.across_sigma_mps);
            let hacc_m = self.sigma_m() * self.stated_scale * (1.0 + rng.symmetric(0.1));
            let t_s = second as f64;
            if outage_s.is_some_and(|(start, end)| (start..end).contains(&t_s)) {
                continue;
            }
            let geodetic = frame.geodetic_of(Vector3::new(
                position.y + error_en_m.x,
                position.x + error_en_m.y,
                -position.z,
            ));
            let speed_mps = measured_en_mps.norm();
            fixes.push(Fix {
                sample,
                lat_deg: geodetic.lat_deg,
                lon_deg: geodetic.lon_deg,
                speed_mps,
                course_deg: (speed_mps >= 0.5).then(|| {
                    measured_en_mps
                        .x
                        .atan2(measured_en_mps.y)
                        .to_degrees()
                        .rem_euclid(360.0)
                }),
                hacc_m,
            });
        }
        fixes
    }
}

// ---------------------------------------------------------------------------------------
// Assembly: sensors on the track, rows, CSV
// ---------------------------------------------------------------------------------------

struct Parts {
    scenario: &'static str,
    seed: u64,
    streams: Streams,
    track: Track,
    sample_rate_hz: f64,
    magnetometer: MagnetometerOptions,
    moving_iron: Option<MovingIronOptions>,
    vibration: Vibration,
    /// Whether the fixes carry their speed.
    gnss_speed: bool,
    gnss_outage_s: Option<(f64, f64)>,
    write_ref_heading: bool,
    write_ref_position: bool,
}

fn assemble(parts: Parts) -> GeneratedLog {
    let Parts {
        scenario,
        seed,
        streams,
        track,
        sample_rate_hz,
        ..
    } = parts;
    let dt_s = 1.0 / sample_rate_hz;
    let samples = track.samples();
    let total_s = samples as f64 * dt_s;
    let setting = Setting::draw(&mut streams.rng("setting"));
    let magnetometer = Magnetometer::draw(&parts.magnetometer, &mut streams.rng("magnetometer"));
    let imu = Imu::draw(&mut streams.rng("imu"));
    let gnss = Gnss::draw(&mut streams.rng("gnss"));
    let passes = draw_moving_iron(parts.moving_iron, total_s, &mut streams.rng("moving-iron"));
    let fixes = gnss.fixes(
        &track,
        &setting.frame,
        sample_rate_hz,
        parts.gnss_outage_s,
        &mut streams.rng("gnss-noise"),
    );

    let mut mag_rng = streams.rng("magnetometer-noise");
    let mut acc_rng = streams.rng("accelerometer-noise");
    let mut gyro_rng = streams.rng("gyroscope-noise");
    let gyro_decay = (-dt_s / imu.gyro_wander_s).exp();
    let gyro_innovation = imu.gyro_wander_radps * (1.0 - gyro_decay * gyro_decay).sqrt();
    let mut gyro_wander = Vector3::zeros();
    let mut acc_vibration = Vector3::zeros();
    let mut gyro_vibration = Vector3::zeros();
    const VIBRATION_MEMORY: f64 = 0.6;
    let vibration_gain = (1.0 - VIBRATION_MEMORY * VIBRATION_MEMORY).sqrt();
    let gravity_ned = Vector3::new(0.0, 0.0, GRAVITY_MPS2);

    let mut rows = Vec::with_capacity(samples);
    let mut true_heading_deg = Vec::with_capacity(samples);
    let mut true_t_s = Vec::with_capacity(samples);
    let mut disturbed = Vec::with_capacity(samples);
    let mut true_attitude = Vec::with_capacity(samples);
    let mut true_en_m = Vec::with_capacity(samples);
    let mut next_pass = 0;
    let mut fix_iter = fixes.iter().peekable();
    let per_second = sample_rate_hz.round() as usize;
    for k in 0..samples {
        let t_s = k as f64 * dt_s;
        let attitude = track.attitude(k);
        let to_body = attitude.inverse();
        let speed_mps = track.velocity_ned_mps[k].norm();

        // Moving iron.
        while next_pass < passes.len()
            && passes[next_pass].center_s + passes[next_pass].duration_s / 2.0 <= t_s
        {
            next_pass += 1;
        }
        let disturbance_ned_ut = passes
            .get(next_pass)
            .map_or_else(Vector3::zeros, |pass| pass.field_ned_ut(t_s));
        disturbed.push(disturbance_ned_ut != Vector3::zeros());
        let mag_ut = magnetometer.measure(
            to_body * (setting.field_ned_ut + disturbance_ned_ut),
            &mut mag_rng,
        );

        // Accelerometer.
        let vibration = &parts.vibration;
        acc_vibration = acc_vibration * VIBRATION_MEMORY
            + acc_rng
                .gaussian3()
                .component_mul(&Vector3::new(1.0, 1.0, 1.5))
                * ((vibration.acc_mps2 + vibration.acc_per_mps * speed_mps) * vibration_gain);
        let acc_mps2 = to_body * (track.acceleration_ned_mps2[k] - gravity_ned)
            + imu.acc_bias_mps2
            + acc_rng.gaussian3() * imu.acc_noise_mps2
            + acc_vibration;

        // Gyroscope.
        if k > 0 {
            gyro_wander = gyro_wander * gyro_decay + gyro_rng.gaussian3() * gyro_innovation;
        }
        gyro_vibration = gyro_vibration * VIBRATION_MEMORY
            + gyro_rng.gaussian3()
                * ((vibration.gyro_radps + vibration.gyro_per_mps * speed_mps) * vibration_gain);
        let gyro_radps = track.body_rate_radps(k, dt_s)
            + imu.gyro_bias_radps
            + gyro_wander
            + gyro_rng.gaussian3() * imu.gyro_noise_radps
            + gyro_vibration;

        let heading_deg = heading_deg_of(&attitude);
        let position = track.position_ned_m[k];
        let en_m = Vector2::new(position.y, position.x);
        let mut row = CanonicalRow {
            t_s: setting.start_unix_s + t_s,
            acc_mps2: Some(acc_mps2),
            gyro_radps: Some(gyro_radps),
            mag_ut: Some(mag_ut),
            ref_heading_deg: parts.write_ref_heading.then_some(heading_deg),
            ref_en_m: (parts.write_ref_position && k % per_second == 0).then_some(en_m),
            ..CanonicalRow::default()
        };
        if let Some(fix) = fix_iter.next_if(|fix| fix.sample == k) {
            row.lat_deg = Some(fix.lat_deg);
            row.lon_deg = Some(fix.lon_deg);
            row.gps_speed_mps = parts.gnss_speed.then_some(fix.speed_mps);
            row.gps_course_deg = fix.course_deg;
            row.gps_hacc_m = Some(fix.hacc_m);
        }
        rows.push(row);
        true_heading_deg.push(heading_deg);
        true_t_s.push(t_s);
        true_attitude.push(attitude);
        true_en_m.push(en_m);
    }

    GeneratedLog {
        name: format!(
            "{scenario} seed {seed} ({}, {})",
            setting.place.name, setting.date
        ),
        csv: canonical_csv::write(&rows),
        hard_iron_ut: magnetometer.hard_iron_ut,
        soft_iron: magnetometer.soft_iron,
        field_ned_ut: setting.field_ned_ut,
        declination_deg: setting.declination_deg,
        sample_rate_hz,
        gnss_outage_s: parts.gnss_outage_s,
        distance_m: track.distance_m,
        true_heading_deg,
        true_t_s,
        disturbed,
        place: setting.place.name,
        origin: setting.origin,
        start_unix_s: setting.start_unix_s,
        true_attitude,
        true_en_m,
        gyro_bias_radps: imu.gyro_bias_radps,
        acc_bias_mps2: imu.acc_bias_mps2,
        mag_noise_ut: magnetometer.noise_ut,
        gnss_sigma_m: gnss.sigma_m(),
    }
}
