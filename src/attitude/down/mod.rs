//! Which way is down, from the gyroscope and the accelerometer together: a
//! complementary filter run forwards and backwards over the log.
//!
//! ## Why not the accelerometer alone
//!
//! The accelerometer senses gravity plus the body's own acceleration, so its direction
//! is only down on average: [`crate::attitude::tilt::smooth_specific_force`] averages it over about
//! a second, which keeps a slow tilt and loses everything faster. A hand that sways by a
//! degree or two at the step frequency is then levelled with the wrong tilt at every
//! instant, and at 65° of dip one degree of tilt is about two degrees of heading: on
//! walks simulated from the physics, the true calibration leaves 1.3-4.5° of heading
//! error with the averaged tilt and 0.5-1.6° with the true one. A device turned quickly
//! (a calibration dance) is worse: the average of a turning vector is not the vector in
//! the middle of the window.
//!
//! ## Method
//!
//! The down direction `d` (a unit vector in body axes) turns opposite to the body:
//! `ḋ = −ω × d`, with `ω` the gyroscope's rate. Between two accelerometer samples it is
//! turned by the gyroscope's rate at their midpoint (Rodrigues' formula for the rotation
//! by `−ω·Δt`), then pulled towards the accelerometer's own down, `−f/|f|`, by
//! `Δt/τ` (Mahony et al. 2008, *Nonlinear complementary filters on the special
//! orthogonal group*, IEEE TAC 53(5), the proportional term, on the direction of
//! gravity only). One pass lags by `τ` where the accelerometer leads, and a gyroscope
//! bias `b` tilts it by `b·τ`, in opposite directions in a forward and a backward
//! pass; their mean has neither at first order (a two-pass smoother, as Rauch-Tung-
//! Striebel's is for a Kalman filter). Accelerations faster than `1/τ` (steps, hand
//! sway) are left to the gyroscope; slower ones (a turn's centripetal acceleration, a
//! car braking) still tilt `d`, as they tilt any accelerometer-based down.
//!
//! ## When the gyroscope is not used
//!
//! Without a gyroscope, or when its rate does not carry the accelerometer's direction
//! along (a sign or a unit wrong in the log: its prediction of down then strays from
//! the accelerometer's by more than [`MAX_INNOVATION_DEG`] RMS over one-second blocks,
//! where a right gyroscope differs by the slow accelerations, a degree or two), the
//! averaged accelerometer is used, and [`GravityEstimate::source`] says which and why.
//!
//! ## GNSS, time scale, trust and autopilots
//!
//! Several settings are tried, each by a forward pass, and the one whose gyroscope
//! predicts the accelerometer's down best wins (another than the plain one only when
//! clearly better): with GNSS speeds, the motion's own accelerations (the change of
//! speed, a turn's centripetal acceleration) taken out of the accelerometer first (fixes
//! that state no speed take it from their positions); and the gyroscope's rates as
//! logged, twice or half as fast (a log without timestamps read at a wrongly assumed
//! rate). Each sample's tilt carries a σ ([`GravityEstimate::tilt_sigma_rad`]: half
//! the angle between the two passes, which agree where the accelerometer read gravity),
//! from which the fits tell how far to trust it. Then the gyroscope's bias is estimated
//! from how its turns carry that down along (`gyro_bias`) and removed, and down is
//! followed over ten times the time constant (`refine`), which averages a swinging
//! arm's accelerations away; kept where the passes then agree clearly better (walks and
//! swings: their median disagreement falls from 0.7° and 7° to 0.25° and 1°; a car's
//! does not). An autopilot's log is levelled with the
//! autopilot's own roll and pitch instead ([`gravity_from_attitude`]): in flight a
//! multirotor's accelerometer reads its thrust, not gravity.

use nalgebra::{Rotation3, Vector2, Vector3};
use serde::Serialize;

use crate::attitude::tilt::smooth_specific_force;
use crate::base::geodesy::LocalFrame;
use crate::io::recording::{Attitude, GnssFix, Recording, Stream};

mod gyro_bias;
mod refine;
use refine::{refine_without_gyro_bias, Smoothing, CLEARLY_BETTER, LONG_TAU_FACTOR};

/// Standard gravity (m/s²), the magnitude given to the estimated specific force
/// (CGPM 1901; only the direction matters to the tilt): `io`'s one constant.
pub use crate::io::STANDARD_GRAVITY_MPS2;

/// The gyroscope's rate is not interpolated across gaps longer than this (s).
const MAX_GYRO_GAP_S: f64 = 0.5;

/// Specific force weaker than this (m/s²) gives no direction (free fall, a broken
/// sample) and corrects nothing.
const MIN_SPECIFIC_FORCE_MPS2: f64 = 2.0;

/// A gyroscope whose prediction of down differs from the accelerometer's by more than
/// this on average over blocks of `INNOVATION_BLOCK_S` (RMS over the blocks) is not
/// trusted: a right one differs by the slow accelerations left in the accelerometer,
/// a degree or two; a wrong sign or unit by tens as soon as the device turns.
pub const MAX_INNOVATION_DEG: f64 = 10.0;

/// Where the estimate of down came from.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum GravitySource {
    /// The gyroscope, corrected towards the accelerometer with time constant `tau_s`
    /// (as asked); `motion_compensated` when the GNSS speed's accelerations were taken
    /// out first; `gyro_time_scale` the factor the gyroscope's rates needed to follow the
    /// accelerometer (1, or 2 or ½ when the log's sample rate was assumed wrongly).
    /// `smoothing_tau_s` is the time constant used: longer than `tau_s` where the
    /// gyroscope's bias was estimated and removed first (`gyro_bias_radps`, body axes)
    /// and the two passes then agreed better.
    GyroAided {
        tau_s: f64,
        motion_compensated: bool,
        gyro_time_scale: f64,
        smoothing_tau_s: f64,
        gyro_bias_radps: Option<[f64; 3]>,
    },
    /// The accelerometer averaged over `window_s`; `reason` says why not the gyroscope.
    Accelerometer { window_s: f64, reason: String },
    /// An autopilot's own roll and pitch (its estimator's), at its attitude samples: a
    /// multirotor's accelerometer reads its thrust along its own axis, not gravity,
    /// whatever its tilt, so in flight it cannot level anything. `tau_s` is the time
    /// constant asked for, kept to tell whether an estimate can be reused.
    Autopilot { tau_s: f64 },
}

/// The specific force that gravity alone would give (the negative of down, times
/// [`STANDARD_GRAVITY_MPS2`]) at each accelerometer sample, and how it was found.
#[derive(Debug, Clone, PartialEq)]
pub struct GravityEstimate {
    pub specific_force_mps2: Stream<Vector3<f64>>,
    pub source: GravitySource,
    /// The fixes whose speed and course were taken out of the accelerometer (the
    /// recording's GNSS when motion-compensated, else empty).
    pub gnss_used: Stream<GnssFix>,
    /// How far the tilt may be wrong (rad, 1σ) at each accelerometer sample. With the
    /// gyroscope, half the angle between the forward and the backward pass: where the
    /// accelerometer pulled them off gravity (an arm's swing, a run) each lags it the
    /// other way, where it read gravity (a bounce the gyroscope carries, a turn on the
    /// spot) they agree. With the accelerometer alone, the acceleration the average left
    /// out over g. Empty for an autopilot's attitude.
    pub tilt_sigma_rad: Stream<f64>,
}

/// [`estimate_gravity`] on a recording's accelerometer, gyroscope and GNSS: computed
/// once per analysis and shared by whatever levels with it (the magnetometer's tilt,
/// the gyro's heading, the dead reckoning's refit).
pub fn gravity_of(recording: &Recording, tau_s: f64) -> GravityEstimate {
    estimate_gravity(
        &recording.acc_in_body_mps2,
        &recording.gyro_in_body_radps,
        &recording.gnss,
        tau_s,
    )
}

/// Down from an autopilot's own attitude estimate ([`GravitySource::Autopilot`]): the
/// specific force gravity alone gives at each attitude sample, `g · (sin θ, −sin φ cos θ,
/// −cos φ cos θ)` in body axes (x forward, y right, z down) for roll φ and pitch θ;
/// `None` with fewer than two attitudes.
pub fn gravity_from_attitude(attitude: &Stream<Attitude>, tau_s: f64) -> Option<GravityEstimate> {
    if attitude.len() < 2 {
        return None;
    }
    let values = attitude
        .values
        .iter()
        .map(|attitude| {
            let (sin_roll, cos_roll) = attitude.roll_rad.sin_cos();
            let (sin_pitch, cos_pitch) = attitude.pitch_rad.sin_cos();
            STANDARD_GRAVITY_MPS2
                * Vector3::new(sin_pitch, -sin_roll * cos_pitch, -cos_roll * cos_pitch)
        })
        .collect();
    Some(GravityEstimate {
        specific_force_mps2: Stream {
            t_s: attitude.t_s.clone(),
            values,
        },
        source: GravitySource::Autopilot { tau_s },
        gnss_used: Stream::default(),
        tilt_sigma_rad: Stream::default(),
    })
}

impl GravityEstimate {
    /// The time constant it was estimated with (s).
    pub fn tau_s(&self) -> f64 {
        match self.source {
            GravitySource::GyroAided { tau_s, .. } => tau_s,
            GravitySource::Accelerometer { window_s, .. } => window_s,
            GravitySource::Autopilot { tau_s } => tau_s,
        }
    }

    /// How far each of the times `t_s` may trust this down, 0 to 1: `1 / (1 + (σ/σ½)²)`
    /// with `σ` the RMS over [`TRUST_WINDOW_S`] of [`GravityEstimate::tilt_sigma_rad`]
    /// and `σ½` = [`TRUST_HALF_DEG`]. 1 where nothing was measured (down from an
    /// autopilot, no accelerometer).
    pub fn tilt_trust_at(&self, t_s: &[f64]) -> Vec<f64> {
        let values = &self.tilt_sigma_rad;
        if values.is_empty() {
            return vec![1.0; t_s.len()];
        }
        // A running RMS over the window, on the accelerometer's own times.
        let mut rms = Stream::default();
        let (mut lo, mut hi, mut sum_sq) = (0usize, 0usize, 0.0f64);
        for (&centre_s, _) in values.t_s.iter().zip(&values.values) {
            while hi < values.len() && values.t_s[hi] <= centre_s + TRUST_WINDOW_S / 2.0 {
                sum_sq += values.values[hi] * values.values[hi];
                hi += 1;
            }
            while lo < hi && values.t_s[lo] < centre_s - TRUST_WINDOW_S / 2.0 {
                sum_sq -= values.values[lo] * values.values[lo];
                lo += 1;
            }
            let n = (hi - lo).max(1) as f64;
            rms.push(centre_s, (sum_sq.max(0.0) / n).sqrt());
        }
        t_s.iter()
            .map(|&t_s| {
                rms.interpolate_at(t_s, MAX_GYRO_GAP_S)
                    .map_or(1.0, |sigma_rad| {
                        1.0 / (1.0 + (sigma_rad / TRUST_HALF_DEG.to_radians()).powi(2))
                    })
            })
            .collect()
    }

    /// Whether the estimate is the same with `gnss` as the recording's fixes (with the
    /// same accelerometer and gyroscope): it used no fixes, or exactly these. A
    /// calibration run again with fixes left out (the dead reckoning's outages) must
    /// not level with speeds from the fixes it left out.
    pub fn holds_with_gnss(&self, gnss: &Stream<GnssFix>) -> bool {
        self.gnss_used.is_empty() || self.gnss_used == *gnss
    }
}

/// Estimates down at every accelerometer sample: gyro-aided with time constant
/// `tau_s` when the log has a consistent gyroscope, else the accelerometer averaged
/// over a window of the same length.
pub fn estimate_gravity(
    acc_in_body_mps2: &Stream<Vector3<f64>>,
    gyro_in_body_radps: &Stream<Vector3<f64>>,
    gnss: &Stream<GnssFix>,
    tau_s: f64,
) -> GravityEstimate {
    let fallback = |reason: String| accelerometer_only(acc_in_body_mps2, tau_s, reason);
    if gyro_in_body_radps.len() < 2 {
        return fallback("the log has no gyroscope".to_string());
    }
    // The settings tried, each by a forward pass: with a speed (GNSS), the motion's own
    // acceleration taken out of the accelerometer first; and the gyroscope's rate as
    // logged, or twice or half as fast, which is what a log without timestamps read at
    // an assumed rate gives (50 lines/s read as 100 Hz). The one whose gyroscope
    // predicts the accelerometer's down best wins; another than the plain one only when
    // clearly better.
    let derived = with_speeds_from_positions(gnss);
    let gnss_moving = derived.as_ref().unwrap_or(gnss);
    let speed_mps = speed_of(gnss_moving);
    let moving = Motion::Forward {
        speed_mps: &speed_mps,
        yaw_rate_bias_radps: yaw_rate_bias_radps(gnss_moving, gyro_in_body_radps),
    };
    let mut motions = vec![Motion::None];
    if speed_mps.len() >= 2 {
        motions.push(moving);
    }
    let best = best_setting(acc_in_body_mps2, gyro_in_body_radps, tau_s, &motions);
    let Some(Setting {
        forward,
        motion_idx,
        gyro_scale,
        innovation_rad,
        ..
    }) = best
    else {
        return fallback("the gyroscope does not overlap the accelerometer in time".to_string());
    };
    let innovation_deg = innovation_rad.to_degrees();
    if innovation_deg > MAX_INNOVATION_DEG {
        return fallback(format!(
            "the gyroscope's turns do not carry the accelerometer's down along (they differ by {innovation_deg:.0}° on average over {INNOVATION_BLOCK_S} s; a sign or unit of the gyroscope columns may be wrong)"
        ));
    }
    let motion = motions.get(motion_idx).unwrap_or(&Motion::None);
    let (backward, _) = pass(
        acc_in_body_mps2,
        gyro_in_body_radps,
        (gyro_scale, Vector3::zeros(), tau_s),
        Direction::Backward,
        motion,
        f64::INFINITY,
    )
    .unwrap_or_default();
    let (mut fused, mut tilt_sigma_rad) = fuse_passes(&acc_in_body_mps2.t_s, (&forward, &backward));
    // With the gyroscope's bias estimated and removed, down can follow the gyroscope
    // for longer, which averages a swinging arm's or a walker's accelerations away; kept
    // where the two passes then agree clearly better (their median disagreement under
    // half: a walk's 0.7° becomes 0.25-0.28°, a swinging arm's 7.4° 0.9-1.0°; a car's,
    // whose accelerations the GNSS speed already took out, moves by ±40 % either way, and
    // its calibration was no better for it).
    let mut smoothing = Smoothing {
        tau_s,
        gyro_bias_radps: None,
    };
    if let Some(refined) = refine_without_gyro_bias(
        (acc_in_body_mps2, gyro_in_body_radps),
        (gyro_scale, tau_s * LONG_TAU_FACTOR),
        motion,
        &fused,
    ) {
        if median_finite(&refined.tilt_sigma_rad.values) * CLEARLY_BETTER
            < median_finite(&tilt_sigma_rad.values)
        {
            smoothing = refined.smoothing;
            fused = refined.specific_force_mps2;
            tilt_sigma_rad = refined.tilt_sigma_rad;
        }
    }
    if fused.is_empty() {
        return fallback("the gyroscope does not overlap the accelerometer in time".to_string());
    }
    for sigma_rad in &mut tilt_sigma_rad.values {
        *sigma_rad = sigma_rad.hypot(ACCELEROMETER_OFFSET_TILT_RAD);
    }
    let motion_compensated = matches!(motion, Motion::Forward { .. });
    GravityEstimate {
        specific_force_mps2: fused,
        source: GravitySource::GyroAided {
            tau_s,
            motion_compensated,
            gyro_time_scale: gyro_scale,
            smoothing_tau_s: smoothing.tau_s,
            gyro_bias_radps: smoothing.gyro_bias_radps,
        },
        gnss_used: if motion_compensated {
            gnss.clone()
        } else {
            Stream::default()
        },
        tilt_sigma_rad,
    }
}

/// The median of the finite values; infinite without any.
fn median_finite(values: &[f64]) -> f64 {
    let mut finite: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
    crate::base::stats::median(&mut finite).unwrap_or(f64::INFINITY)
}

/// Down from the accelerometer alone, averaged over `tau_s`
/// ([`GravitySource::Accelerometer`], for `reason`), its σ what the average left out.
fn accelerometer_only(
    acc_in_body_mps2: &Stream<Vector3<f64>>,
    tau_s: f64,
    reason: String,
) -> GravityEstimate {
    let smoothed = smooth_specific_force(acc_in_body_mps2, tau_s);
    let mut tilt_sigma_rad = Stream::default();
    for (&t_s, &f) in acc_in_body_mps2.t_s.iter().zip(&acc_in_body_mps2.values) {
        if let Some(gravity) = smoothed.interpolate_at(t_s, MAX_GYRO_GAP_S) {
            let sigma_rad = ((f - gravity).norm() / STANDARD_GRAVITY_MPS2).atan();
            if sigma_rad.is_finite() {
                tilt_sigma_rad.push(t_s, sigma_rad);
            }
        }
    }
    GravityEstimate {
        specific_force_mps2: smoothed,
        source: GravitySource::Accelerometer {
            window_s: tau_s,
            reason,
        },
        gnss_used: Stream::default(),
        tilt_sigma_rad,
    }
}

/// The setting (motion and gyroscope time scale) whose forward pass predicts the
/// accelerometer's down best, with that pass; `None` when no pass overlapped.
fn best_setting(
    acc_in_body_mps2: &Stream<Vector3<f64>>,
    gyro_in_body_radps: &Stream<Vector3<f64>>,
    tau_s: f64,
    motions: &[Motion],
) -> Option<Setting> {
    // Each motion at the log's own time scale first, side by side (nothing to compare
    // them with yet, so each is a whole pass), then the other time scales, each given
    // up once it cannot win. The winner is the lowest score, ties going to the earlier
    // trial in the order motion by motion, scale by scale.
    let run = |motion: &Motion, gyro_scale: f64, losing_rad: f64| {
        pass(
            acc_in_body_mps2,
            gyro_in_body_radps,
            (gyro_scale, Vector3::zeros(), tau_s),
            Direction::Forward,
            motion,
            losing_rad,
        )
    };
    let own_scale = |(_, motion): (usize, &Motion)| run(motion, 1.0, f64::INFINITY);
    let first = crate::base::par::on_each_small_part(motions.iter().enumerate(), own_scale)
        .unwrap_or_else(|| motions.iter().enumerate().map(own_scale).collect());
    let mut best: Option<Setting> = None;
    for (motion_idx, result) in first.into_iter().enumerate() {
        let trial = (motion_idx * GYRO_TIME_SCALES.len(), motion_idx, 1.0);
        Setting::keep_better(&mut best, trial, result);
    }
    for (motion_idx, motion) in motions.iter().enumerate() {
        for (scale_idx, gyro_scale) in GYRO_TIME_SCALES.into_iter().enumerate().skip(1) {
            let losing_rad = best.as_ref().map_or(f64::INFINITY, |best| best.score / 2.0);
            let result = run(motion, gyro_scale, losing_rad);
            let trial = (
                motion_idx * GYRO_TIME_SCALES.len() + scale_idx,
                motion_idx,
                gyro_scale,
            );
            Setting::keep_better(&mut best, trial, result);
        }
    }
    best
}

/// One pass's down at an accelerometer sample (a unit vector in body axes), if any.
type Down = Option<Vector3<f64>>;

/// What the two passes cannot see of the tilt's error (rad, 1σ of the angle): an
/// accelerometer's offset, which both follow alike. About 0.05 m/s² on each horizontal
/// axis, a phone's after its factory calibration (5 mg); the independent generator
/// draws up to that. Without it, the σ of a walk's down once the gyroscope's bias is
/// removed (0.16° at the median) covered 31 % of its errors within 1σ
/// (`tests/attitude_sigma.rs`).
const ACCELEROMETER_OFFSET_TILT_RAD: f64 = std::f64::consts::SQRT_2 * 0.05 / STANDARD_GRAVITY_MPS2;

/// Down from the two passes (their mean direction) at each accelerometer sample, as the
/// specific force gravity alone gives, and half the angle between them (the part of
/// [`GravityEstimate::tilt_sigma_rad`] the passes show).
fn fuse_passes(
    t_s: &[f64],
    (forward, backward): (&[Down], &[Down]),
) -> (Stream<Vector3<f64>>, Stream<f64>) {
    let mut fused = Stream::default();
    let mut tilt_sigma_rad = Stream::default();
    for (&t_s, (a, b)) in t_s.iter().zip(forward.iter().zip(backward)) {
        let down = match (a, b) {
            (Some(a), Some(b)) => {
                let sigma_rad = 0.5 * a.angle(b);
                if sigma_rad.is_finite() {
                    tilt_sigma_rad.push(t_s, sigma_rad);
                }
                (a + b).try_normalize(1e-9)
            }
            (Some(one), None) | (None, Some(one)) => Some(*one),
            (None, None) => None,
        };
        if let Some(down) = down {
            fused.push(t_s, -down * STANDARD_GRAVITY_MPS2);
        }
    }
    (fused, tilt_sigma_rad)
}

/// What the accelerometer senses besides gravity, when known.
enum Motion<'a> {
    None,
    /// The body moves along its x axis (a phone held or mounted facing the way it
    /// goes) at the GNSS speed: `a = (dv/dt, ω_z·v, −ω_y·v)` in body axes, the change of
    /// speed and the turn's centripetal acceleration.
    Forward {
        speed_mps: &'a Stream<f64>,
        /// The gyroscope's z bias against the GNSS course's rate of turn: left in, it is
        /// a centripetal acceleration on every straight (0.7° of roll at 12 m/s for
        /// 0.01 rad/s).
        yaw_rate_bias_radps: f64,
    },
}

/// The GNSS speeds over ground (m/s).
fn speed_of(gnss: &Stream<GnssFix>) -> Stream<f64> {
    let mut speed = Stream::default();
    for (&t_s, fix) in gnss.t_s.iter().zip(&gnss.values) {
        if let Some(speed_mps) = fix.speed_mps.filter(|speed| speed.is_finite()) {
            speed.push(t_s, speed_mps);
        }
    }
    speed
}

/// The fixes as the motion sees them where none states a speed (a receiver without a
/// Doppler speed, NMEA's GGA alone, a log that kept only positions): each fix between
/// two others takes the speed between their positions, `|p₊ − p₋| / (t₊ − t₋)`, when
/// they are at most 2 × [`MAX_SPEED_GAP_S`] apart. Without it a car's turns tilt "down"
/// by their centripetal acceleration, `v·ω/g` (17° at 3 m/s²), always towards the
/// turn's centre, and the calibration's dip takes it for iron (issue 43: on the
/// independent generator's drives without a speed the exported calibration was 1.4 ×
/// the true one's heading error at the median, 4.3 × at worst). `None` when a fix states
/// a speed or no two fixes give one.
fn with_speeds_from_positions(gnss: &Stream<GnssFix>) -> Option<Stream<GnssFix>> {
    if gnss
        .values
        .iter()
        .any(|fix| fix.speed_mps.is_some_and(f64::is_finite))
    {
        return None;
    }
    let frame = LocalFrame::at(gnss.values.iter().find_map(GnssFix::position)?);
    let en_m: Vec<Option<Vector2<f64>>> = gnss
        .values
        .iter()
        .map(|fix| {
            let position = fix.position()?;
            Some(frame.en_of(position.lat_deg, position.lon_deg))
        })
        .collect();
    let mut filled = gnss.clone();
    let mut any = false;
    for i in 1..gnss.len().saturating_sub(1) {
        let (Some(before), Some(after)) = (en_m[i - 1], en_m[i + 1]) else {
            continue;
        };
        let dt_s = gnss.t_s[i + 1] - gnss.t_s[i - 1];
        if dt_s > 0.0 && dt_s <= 2.0 * MAX_SPEED_GAP_S {
            filled.values[i].speed_mps = Some((after - before).norm() / dt_s);
            any = true;
        }
    }
    any.then_some(filled)
}

/// The median, over consecutive fixes at [`MIN_COURSE_SPEED_MPS`] or faster, of the
/// gyroscope's mean z rate between them minus the course's rate of turn; zero with
/// fewer than [`MIN_BIAS_PAIRS`] such pairs.
fn yaw_rate_bias_radps(gnss: &Stream<GnssFix>, gyro: &Stream<Vector3<f64>>) -> f64 {
    let mut differences = Vec::new();
    let fixes: Vec<(f64, f64)> = gnss
        .t_s
        .iter()
        .zip(&gnss.values)
        .filter_map(|(&t_s, fix)| {
            let course_rad = fix.course_rad?;
            (fix.speed_mps? >= MIN_COURSE_SPEED_MPS).then_some((t_s, course_rad))
        })
        .collect();
    for pair in fixes.windows(2) {
        let [(t0, c0), (t1, c1)] = [pair[0], pair[1]];
        let dt_s = t1 - t0;
        if dt_s.is_nan() || dt_s <= 0.0 || dt_s > MAX_SPEED_GAP_S {
            continue;
        }
        let lo = gyro.t_s.partition_point(|&t| t < t0);
        let hi = gyro.t_s.partition_point(|&t| t <= t1);
        let rates = gyro.values.get(lo..hi).unwrap_or(&[]);
        if rates.is_empty() {
            continue;
        }
        let mean_rate = rates.iter().map(|rate| rate.z).sum::<f64>() / rates.len() as f64;
        let course_rate = crate::base::angle::wrap_to_pi(c1 - c0) / dt_s;
        differences.push(mean_rate - course_rate);
    }
    if differences.len() < MIN_BIAS_PAIRS {
        return 0.0;
    }
    let middle = differences.len() / 2;
    let (_, median, _) = differences.select_nth_unstable_by(middle, f64::total_cmp);
    *median
}

/// The course's rate of turn is trusted at this speed or faster (m/s), and a yaw-rate
/// bias needs this many pairs of fixes.
const MIN_COURSE_SPEED_MPS: f64 = 2.0;
const MIN_BIAS_PAIRS: usize = 20;

/// The window of [`GravityEstimate::tilt_trust_at`]'s RMS (s): a stride, so that a
/// walker's bounce and an arm's swing count as what they are on average.
pub const TRUST_WINDOW_S: f64 = 1.0;
/// The tilt's σ (degrees) at which it is trusted half ([`GravityEstimate::tilt_trust_at`]).
pub const TRUST_HALF_DEG: f64 = 2.0;

/// The factors tried on the gyroscope's rates (see [`estimate_gravity`]).
const GYRO_TIME_SCALES: [f64; 3] = [1.0, 2.0, 0.5];

/// The blocks over which innovations are averaged (s): a few steps.
const INNOVATION_BLOCK_S: f64 = 1.0;

/// Speeds are not interpolated across gaps longer than this (s); their derivative is
/// taken over this span either side.
const MAX_SPEED_GAP_S: f64 = 2.5;
const SPEED_DERIVATIVE_HALF_SPAN_S: f64 = 2.0;

impl Motion<'_> {
    /// The motion's acceleration at `t_s` (m/s², body axes) from the gyroscope's rate as
    /// read (`rate_radps`, before any bias is removed) and the bias found from down
    /// (`gyro_bias_radps`, zero in the first passes): the turn's rate is the z rate less
    /// its bias against the GNSS course (which the z rate is not corrected for twice),
    /// the pitch rate the y rate less the bias from down. Both biases taken from the z
    /// rate counted it twice: on the simulated vehicle loop (0.0038 rad/s at 12 m/s) a
    /// false centripetal 0.05 m/s² on every straight, and down without the gyroscope's
    /// bias was tilted by 0.35° at the median against 0.17° with it counted once.
    fn acceleration_in_body_mps2(
        &self,
        t_s: f64,
        rate_radps: Option<Vector3<f64>>,
        gyro_bias_radps: Vector3<f64>,
    ) -> Vector3<f64> {
        let Motion::Forward {
            speed_mps,
            yaw_rate_bias_radps,
        } = self
        else {
            return Vector3::zeros();
        };
        let Some(speed) = speed_mps.interpolate_at(t_s, MAX_SPEED_GAP_S) else {
            return Vector3::zeros();
        };
        let along = match (
            speed_mps.interpolate_at(t_s + SPEED_DERIVATIVE_HALF_SPAN_S, MAX_SPEED_GAP_S),
            speed_mps.interpolate_at(t_s - SPEED_DERIVATIVE_HALF_SPAN_S, MAX_SPEED_GAP_S),
        ) {
            (Some(later), Some(earlier)) => {
                (later - earlier) / (2.0 * SPEED_DERIVATIVE_HALF_SPAN_S)
            }
            _ => 0.0,
        };
        let rate = rate_radps.unwrap_or_else(Vector3::zeros);
        Vector3::new(
            along,
            (rate.z - yaw_rate_bias_radps) * speed,
            -(rate.y - gyro_bias_radps.y) * speed,
        )
    }
}

/// One setting of the filter tried by [`estimate_gravity`], with its forward pass.
struct Setting {
    forward: Vec<Option<Vector3<f64>>>,
    /// The innovation, handicapped when the time scale is not the log's.
    score: f64,
    /// Its place in the order of the trials (ties go to the earlier).
    order: usize,
    motion_idx: usize,
    gyro_scale: f64,
    innovation_rad: f64,
}

impl Setting {
    /// Keeps the trial `(order, motion_idx, gyro_scale)`'s pass in `best` when it scores
    /// lower, or as low and earlier in the order. Motion compensation is its own
    /// evidence; a changed time scale must halve the innovation.
    fn keep_better(
        best: &mut Option<Setting>,
        (order, motion_idx, gyro_scale): (usize, usize, f64),
        pass: Option<(Vec<Option<Vector3<f64>>>, f64)>,
    ) {
        let Some((forward, innovation_rad)) = pass else {
            return;
        };
        let score = innovation_rad * if gyro_scale == 1.0 { 1.0 } else { 2.0 };
        if best
            .as_ref()
            .is_none_or(|best| (score, order) < (best.score, best.order))
        {
            *best = Some(Setting {
                forward,
                score,
                order,
                motion_idx,
                gyro_scale,
                innovation_rad,
            });
        }
    }
}

#[derive(Clone, Copy, PartialEq)]
enum Direction {
    Forward,
    Backward,
}

/// One pass of the complementary filter over the accelerometer's samples, in time order
/// or reversed: the down direction at each sample (`None` before the first usable one),
/// and the RMS over blocks of [`INNOVATION_BLOCK_S`] of the mean difference between the
/// accelerometer's down and the gyroscope's prediction (rad): how far the accelerometer
/// leans on average, which a right motion compensation reduces.
///
/// A pass whose innovation is sure to come out above `losing_rad` (another setting
/// already does better) is abandoned: `None`. The blocks start at least
/// [`INNOVATION_BLOCK_S`] apart, so the log's span bounds their number, and the RMS over
/// the blocks so far divided by that bound can only grow. The answer is the same as
/// running every pass to the end; a wrong time scale is given up within seconds of
/// the log.
fn pass(
    acc: &Stream<Vector3<f64>>,
    gyro: &Stream<Vector3<f64>>,
    (gyro_scale, gyro_bias_radps, tau_s): (f64, Vector3<f64>, f64),
    direction: Direction,
    motion: &Motion,
    losing_rad: f64,
) -> Option<(Vec<Option<Vector3<f64>>>, f64)> {
    let n = acc.len().min(acc.t_s.len());
    let max_blocks = (acc.duration_s().abs() / INNOVATION_BLOCK_S).floor() + 1.0;
    let losing_sum_sq = if max_blocks.is_finite() {
        losing_rad * losing_rad * max_blocks
    } else {
        f64::INFINITY
    };
    let mut downs = vec![None; n];
    let order: Box<dyn Iterator<Item = usize>> = match direction {
        Direction::Forward => Box::new(0..n),
        Direction::Backward => Box::new((0..n).rev()),
    };
    let mut state: Option<(f64, Vector3<f64>)> = None;
    // The innovations (accelerometer minus prediction) summed over blocks of
    // INNOVATION_BLOCK_S: the steps' swings cancel within a block, a systematic tilt of
    // the accelerometer (an acceleration left in it) does not.
    let (mut sum_sq_innovation, mut n_blocks) = (0.0, 0usize);
    let mut block: Option<(f64, Vector3<f64>, usize)> = None;
    for idx in order {
        let (Some(&t_s), Some(&f)) = (acc.t_s.get(idx), acc.values.get(idx)) else {
            continue;
        };
        let f = match motion {
            Motion::None => f,
            Motion::Forward { .. } => {
                let rate_now = gyro
                    .interpolate_at(t_s, MAX_GYRO_GAP_S)
                    .map(|rate| rate * gyro_scale);
                f - motion.acceleration_in_body_mps2(t_s, rate_now, gyro_bias_radps)
            }
        };
        let measured = (f.norm() >= MIN_SPECIFIC_FORCE_MPS2 && f.iter().all(|v| v.is_finite()))
            .then(|| -f.normalize());
        let down = match (state, measured) {
            (None, None) => continue,
            (None, Some(measured)) => measured,
            (Some((last_t_s, last_down)), measured) => {
                // Time runs backwards in the backward pass: the rotation is undone.
                let dt_s = t_s - last_t_s;
                let midpoint_s = 0.5 * (t_s + last_t_s);
                let rate = gyro
                    .interpolate_at(midpoint_s, MAX_GYRO_GAP_S)
                    .map(|rate| rate * gyro_scale - gyro_bias_radps);
                let turned = match rate {
                    Some(rate) if dt_s.abs() <= MAX_GYRO_GAP_S => {
                        Rotation3::new(-rate * dt_s) * last_down
                    }
                    _ => last_down,
                };
                match measured {
                    Some(measured) => {
                        let innovation = measured - turned;
                        match &mut block {
                            Some((start_s, sum, count))
                                if (t_s - *start_s).abs() < INNOVATION_BLOCK_S =>
                            {
                                *sum += innovation;
                                *count += 1;
                            }
                            _ => {
                                if let Some((_, sum, count)) = block {
                                    sum_sq_innovation += (sum / count as f64).norm_squared();
                                    n_blocks += 1;
                                    if sum_sq_innovation > losing_sum_sq {
                                        return None;
                                    }
                                }
                                block = Some((t_s, innovation, 1));
                            }
                        }
                        let gain = (dt_s.abs() / tau_s).min(1.0);
                        (turned + (measured - turned) * gain)
                            .try_normalize(1e-12)
                            .unwrap_or(measured)
                    }
                    None => turned,
                }
            }
        };
        downs[idx] = Some(down);
        state = Some((t_s, down));
    }
    let rms = (sum_sq_innovation / n_blocks.max(1) as f64).sqrt();
    Some((downs, rms))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::attitude::tilt::Tilt;

    /// Speeds between fixes' positions: 10 m/s eastward along the equator, and a fix whose
    /// latitude is out of range (a corrupt line) gives no speed to its neighbours rather
    /// than a NaN.
    #[test]
    fn speeds_from_positions_skip_a_fix_without_a_usable_position() {
        let metres_per_deg = 111_319.49;
        let mut gnss = Stream::default();
        for idx in 0..5 {
            let lat_deg = if idx == 2 { 95.0 } else { 0.0 };
            gnss.push(
                idx as f64,
                GnssFix {
                    lat_deg: Some(lat_deg),
                    lon_deg: Some(10.0 * idx as f64 / metres_per_deg),
                    alt_m: None,
                    speed_mps: None,
                    course_rad: None,
                    hacc_m: Some(3.0),
                },
            );
        }
        let filled = with_speeds_from_positions(&gnss).expect("speeds");
        let speeds: Vec<Option<f64>> = filled.values.iter().map(|fix| fix.speed_mps).collect();
        assert_eq!(speeds[0], None);
        assert_eq!(speeds[1], None, "its neighbour after has no position");
        assert!(
            (speeds[2].expect("a speed") - 10.0).abs() < 0.01,
            "{speeds:?}"
        );
        assert_eq!(speeds[3], None, "its neighbour before has no position");
        assert_eq!(speeds[4], None);
    }

    #[test]
    fn an_autopilot_s_roll_and_pitch_level_as_the_accelerometer_would_at_rest() {
        use crate::io::recording::Attitude;
        let angles = [
            (0.0, 0.0),
            (0.3, -0.2),
            (-1.2, 0.7),
            (2.9, 0.1),
            (0.5, -1.5),
        ];
        let attitude = Stream {
            t_s: (0..angles.len()).map(|idx| idx as f64 * 0.1).collect(),
            values: angles
                .iter()
                .map(|&(roll_rad, pitch_rad)| Attitude {
                    roll_rad,
                    pitch_rad,
                    yaw_rad: Some(1.0),
                })
                .collect(),
        };
        let estimate = gravity_from_attitude(&attitude, 2.0).expect("five attitudes");
        assert_eq!(estimate.source, GravitySource::Autopilot { tau_s: 2.0 });
        assert_eq!(estimate.tau_s(), 2.0);
        for (&(roll_rad, pitch_rad), &force) in
            angles.iter().zip(&estimate.specific_force_mps2.values)
        {
            let tilt = Tilt::from_specific_force(force).expect("a specific force");
            assert!(
                (tilt.roll_rad() - roll_rad).abs() < 1e-12,
                "{roll_rad} {pitch_rad}"
            );
            assert!(
                (tilt.pitch_rad() - pitch_rad).abs() < 1e-12,
                "{roll_rad} {pitch_rad}"
            );
            assert!((force.norm() - STANDARD_GRAVITY_MPS2).abs() < 1e-12);
        }
        let one = Stream {
            t_s: vec![0.0],
            values: vec![attitude.values[0]],
        };
        assert!(gravity_from_attitude(&one, 2.0).is_none());
    }

    /// A body swaying in roll and pitch at `sway_hz` by `sway_deg` while turning in
    /// yaw, with a walking bounce and fore-aft acceleration in the accelerometer: the
    /// gyro-aided down follows the sway, the averaged one does not.
    fn swaying(
        sway_deg: f64,
        sway_hz: f64,
        gyro_bias_radps: Vector3<f64>,
        gyro_sign: f64,
    ) -> (Stream<Vector3<f64>>, Stream<Vector3<f64>>, Vec<Tilt>) {
        let rate_hz = 100.0;
        let n = 6000;
        let (mut acc, mut gyro, mut truth) = (Stream::default(), Stream::default(), Vec::new());
        let attitude = |t_s: f64| {
            let roll = sway_deg.to_radians() * (std::f64::consts::TAU * sway_hz * t_s).sin();
            let pitch =
                0.7 * sway_deg.to_radians() * (std::f64::consts::TAU * sway_hz * 0.5 * t_s).cos();
            let yaw = 0.3 * t_s;
            Rotation3::from_euler_angles(roll, pitch, yaw)
        };
        for idx in 0..n {
            let t_s = idx as f64 / rate_hz;
            let ned_from_body = attitude(t_s);
            // Steps: 2 m/s² bounce and 1 m/s² fore-aft at 2 Hz, in the navigation frame.
            let step = std::f64::consts::TAU * 2.0 * t_s;
            let a_ned = Vector3::new(1.0 * step.sin(), 0.0, 2.0 * step.cos());
            let f_body =
                ned_from_body.inverse() * (a_ned - Vector3::new(0.0, 0.0, STANDARD_GRAVITY_MPS2));
            acc.push(t_s, f_body);
            let dt = 1e-4;
            let delta = attitude(t_s - dt).inverse() * attitude(t_s + dt);
            let rate = delta.scaled_axis() / (2.0 * dt);
            gyro.push(
                t_s,
                Vector3::new(gyro_sign * rate.x, rate.y, rate.z) + gyro_bias_radps,
            );
            let (roll, pitch, _) = ned_from_body.euler_angles();
            truth.push(Tilt::new(roll, pitch));
        }
        (acc, gyro, truth)
    }

    fn rms_tilt_error_deg(estimate: &Stream<Vector3<f64>>, truth: &[Tilt]) -> f64 {
        let errors: Vec<f64> = estimate
            .values
            .iter()
            .zip(truth)
            .skip(500)
            .take(5000)
            .filter_map(|(f, truth)| {
                let tilt = Tilt::from_specific_force(*f)?;
                Some(
                    (tilt.roll_rad() - truth.roll_rad()).powi(2)
                        + (tilt.pitch_rad() - truth.pitch_rad()).powi(2),
                )
            })
            .collect();
        (errors.iter().sum::<f64>() / errors.len() as f64)
            .sqrt()
            .to_degrees()
    }

    #[test]
    fn the_gyro_follows_a_sway_the_averaged_accelerometer_misses() {
        let (acc, gyro, truth) = swaying(3.0, 1.0, Vector3::new(0.01, -0.008, 0.005), 1.0);
        let fused = estimate_gravity(&acc, &gyro, &Stream::default(), 1.0);
        assert!(
            matches!(
                fused.source,
                GravitySource::GyroAided {
                    tau_s: 1.0,
                    motion_compensated: false,
                    gyro_time_scale: 1.0,
                    ..
                }
            ),
            "{:?}",
            fused.source
        );
        let averaged = smooth_specific_force(&acc, 1.0);
        let (fused_deg, averaged_deg) = (
            rms_tilt_error_deg(&fused.specific_force_mps2, &truth),
            rms_tilt_error_deg(&averaged, &truth),
        );
        assert!(fused_deg < 0.3, "{fused_deg}° (averaged {averaged_deg}°)");
        assert!(averaged_deg > 1.5, "{averaged_deg}°");
    }

    #[test]
    fn a_gyro_axis_of_the_wrong_sign_is_noticed_and_not_used() {
        let (acc, gyro, _) = swaying(25.0, 0.5, Vector3::zeros(), -1.0);
        let estimate = estimate_gravity(&acc, &gyro, &Stream::default(), 1.0);
        assert!(
            matches!(&estimate.source, GravitySource::Accelerometer { reason, .. } if reason.contains("sign")),
            "{:?}",
            estimate.source
        );
    }

    #[test]
    fn an_estimate_holds_with_other_fixes_only_if_it_used_none() {
        let (acc, gyro, _) = swaying(3.0, 1.0, Vector3::zeros(), 1.0);
        let without = estimate_gravity(&acc, &gyro, &Stream::default(), 1.0);
        let mut fixes = Stream::default();
        fixes.push(0.0, GnssFix::default());
        assert!(without.holds_with_gnss(&fixes));
        let with = GravityEstimate {
            gnss_used: fixes.clone(),
            ..without
        };
        assert!(with.holds_with_gnss(&fixes));
        assert!(!with.holds_with_gnss(&Stream::default()));
    }

    #[test]
    fn without_a_gyro_the_accelerometer_is_averaged() {
        let (acc, _, _) = swaying(3.0, 1.0, Vector3::zeros(), 1.0);
        let estimate = estimate_gravity(&acc, &Stream::default(), &Stream::default(), 1.0);
        assert_eq!(
            estimate.specific_force_mps2,
            smooth_specific_force(&acc, 1.0)
        );
        assert!(matches!(
            estimate.source,
            GravitySource::Accelerometer { .. }
        ));
    }
}
