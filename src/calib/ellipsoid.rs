//! 3D ellipsoid calibration: hard iron, soft iron and field magnitude from samples
//! taken in many attitudes.
//!
//! ## Model
//!
//! Moafipoor et al. (2007), Eq. 2-3 and 5: a sample is `m = S·b + h`, where `b` is the
//! Earth's field in the body frame (constant magnitude `F`), `S` the soft iron and `h`
//! the hard iron. As the device turns, `b` sweeps a sphere of radius `F`, so the samples
//! lie on the ellipsoid `(m − h)ᵀ·Q·(m − h) = 1` with `Q = S⁻ᵀ·S⁻¹ / F²`. The
//! correction is `A = F·Q^½` (symmetric), so that `|A·(m − h)| = F` for every sample.
//!
//! ## Method
//!
//! 1. **One streaming pass** ([`EllipsoidAccumulator`]): the 35 power sums
//!    `Σ dx^a·dy^b·dz^c` (`a + b + c ≤ 4`) of the samples' offsets `d` from the first
//!    sample. Every entry of the 10×10 scatter matrix `D·Dᵀ` of the quadric's design
//!    vector is one of them, so no N×10 design matrix is ever built, two accumulators
//!    merge exactly (the sums of one are moved to the other's origin by the binomial
//!    theorem), and the cost is about 50 multiplications and 35 additions per sample
//!    (chunked to keep the sums in registers, two samples per SSE2 register on x86-64:
//!    about 6 ms for a million samples). Before solving, the sums are moved to the mean
//!    and scaled by the RMS radius, which keeps the normal equations well conditioned
//!    whatever the hard iron.
//! 2. **Algebraic, ellipsoid-specific fit**: Li and Griffiths (2004), *Least squares
//!    ellipsoid specific fitting*, Proc. Geometric Modeling and Processing, the
//!    algorithm of Magneto 1.2. With the scatter split into quadratic (`S11`) and
//!    linear-and-constant (`S22`) blocks, the quadratic coefficients `v1` solve the
//!    generalised eigenproblem `(S11 − S12·S22⁻¹·S21)·v1 = λ·C·v1` for its one positive
//!    eigenvalue, where `C` encodes the ellipsoid constraint `4J − I² = 1` (their
//!    constraint with k = 4), and `v2 = −S22⁻¹·S21·v1`. The constrained models write
//!    the quadric matrix as a combination of fixed matrices (their generators) and run
//!    the same solver on the reduced design; for the sphere this is Kåsa's (1976) linear
//!    fit of `|m|² = 2·hᵀm + (R² − |h|²)`.
//! 3. **Conversion**: the centre is the hard iron and `A` is the symmetric square root
//!    of the normalised quadric matrix, scaled so that `det A = 1` (the field is then
//!    the geometric mean of the semi-axes, as in NXP's application note AN4246) or so
//!    that the radius is the expected field when the caller gives one.
//! 4. **Geometric refinement** (Levenberg-Marquardt, the `levenberg-marquardt` crate):
//!    residuals `(|A·(m − h)| − R) / (det A)^⅓` with `h` (3) and the free entries of `A`
//!    (1, 3, 5 or 6) as parameters and `R` fixed, which is the same problem as
//!    `det A = 1` with `R` free. A refinement that drifts along a valley the data hardly
//!    constrain (its hard iron predicted more than twice as uncertain as at the start)
//!    is dropped in favour of the algebraic fit.
//! 5. **Model choice** (`Auto`, after MATLAB's `magcal`): the simplest model whose
//!    residual is close to the full model's (the rule is in [`fit_ellipsoid`]).
//! 6. **Observability**: data from walkers and vehicles turn through every heading but
//!    tilt only a few degrees: a narrow band of the ellipsoid. Its in-plane shape is
//!    well observed, but the scale along the band's axis cannot be told from the hard
//!    iron along it (the band hardly moves along it), so a full fit there follows the
//!    noise. When the band is narrower than [`MIN_FULL_TILT_SPAN_DEG`] and the `Band`
//!    model, which ties that scale to the in-plane ones, fits as well as the full one,
//!    the fit falls back to it and says why.
//!
//! ## Limits
//!
//! The model is linear (hard and soft iron fixed in the body frame); fields that change
//! during the recording (a passing car, a steel desk) bend the ellipsoid and no model
//! here removes them. The algebraic fit is biased by about `σ²/R²` (negligible at
//! 0.3 µT of noise on 50 µT); the refinement removes most of that. Without an expected
//! field the absolute scale of `A` is fixed by the `det A = 1` convention only, so the
//! corrected magnitude is the geometric mean of the semi-axes, not necessarily the true
//! field; with one, the expected field sets that scale and nothing else (it cannot pin
//! what the geometry leaves free unless the sensor's gain is trusted, which is not
//! assumed). The dip angle is not used. On a band (circle-only data) a 3D fit leaves
//! heading errors of 1-4° RMS even after the fallback (measured in the tests); the
//! tilt-aware plane fit ([`super::plane`]) is the method for such data. The geometric
//! refinement runs on at most [`MAX_REFINE_SAMPLES`] samples, evenly spaced.

use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt};
use nalgebra::storage::Owned;
use nalgebra::{Cholesky, DMatrix, DVector, Dyn, Matrix3, SymmetricEigen, Vector3};
use serde::Serialize;
use thiserror::Error;

use super::model::FieldCalibration;

/// Fewer samples than this cannot determine the nine parameters of a full ellipsoid
/// with any redundancy.
pub const MIN_SAMPLES: usize = 10;

/// The geometric refinement uses at most this many samples, evenly spaced. Its
/// Jacobian is N×p and the library factorises it each iteration; beyond this size the
/// estimate's noise (σ·√(3/N), 0.004 µT here at σ = 0.3 µT) no longer matters.
pub const MAX_REFINE_SAMPLES: usize = 20_000;

/// Samples beyond this (µT, on any axis) are refused: magnetometers read up to a few
/// thousand µT, and 1 T keeps the fourth powers of a billion samples finite.
pub const MAX_ABS_UT: f64 = 1e6;

/// A spread below this (µT, RMS about the mean) means the device did not turn: a
/// still magnetometer spreads by its noise, well under 1 µT, and any turn by tens.
const MIN_SPREAD_UT: f64 = 2.0;

/// Samples whose second principal axis is this small a fraction of the first lie on a
/// line (a field that grows and shrinks along one direction), not on a surface.
const MIN_WIDTH_FRACTION: f64 = 0.05;

/// Samples within this tilt span (±degrees, see [`Observability::tilt_span_deg`]) of a
/// plane are refused. Such a band is mostly noise (a level ring at 0.6 µT of noise
/// already spans 3°), and just above it, at 5°, every 3D model leaves 3.5° RMS of
/// heading error (worst 5-7°): any narrower would be a confident wrong answer.
const MIN_TILT_SPAN_DEG: f64 = 4.0;

/// Below this tilt span (±degrees) the full and diagonal models fall back to the band
/// model. Measured by the `band_sweep` test over 30 random distortions (0.3 µT of
/// noise, 3000 samples, inclination 65°), the RMS heading error, mean and (worst), of
/// the full and the band model: at a span of 9.6° (roll and pitch within ±10°) 3.9°
/// (4.5°) and 1.5° (4.1°); at 17° 3.6° (4.2°) and 1.6° (3.7°); at 20° 2.7° (3.1°) and
/// 1.8° (4.4°); at 22° (±30°) 2.0° (3.1°) and 2.0° (5.1°); at 24.5° 1.2° (1.6°) and 2.2°
/// (5.7°); over a full sphere the full model reaches the noise's own 0.8°.
pub const MIN_FULL_TILT_SPAN_DEG: f64 = 22.0;

/// Auto keeps a simpler model when the systematic part it misses,
/// `√(rms_simple² − rms_full²)`, is below this fraction of the full model's RMS: the RMS
/// then grows by under 5 %, which no user could tell from noise.
const AUTO_EXCESS_OF_NOISE: f64 = 0.3;

/// ... or below this fraction of the field (0.1 %: a scale error that moves the
/// heading by under 0.06°).
const AUTO_EXCESS_OF_FIELD: f64 = 0.001;

/// A narrow band falls back to the band model only when the band model's RMS residual
/// exceeds the full model's by a systematic part under this fraction of the full
/// model's RMS (the RMS grows by under 0.5 %); see [`prefers_band`].
const BAND_EXCESS_OF_NOISE: f64 = 0.1;

/// A fit whose RMS residual exceeds this fraction of the field is refused: noise is
/// 0.1-1 µT, about 1 % of the field, and even a walk past parked cars stays within a
/// few percent, so 10 % means the samples do not lie on any one ellipsoid.
const MAX_RESIDUAL_FRACTION: f64 = 0.1;

/// A fitted ellipsoid whose longest axis is this many times its shortest is not a
/// magnetometer's distortion but a failed fit: the soft iron of phones and boards is a
/// few percent, and mismatched sensor axes differ by ±15 % at most.
const MAX_AXIS_RATIO: f64 = 2.0;

/// The refinement is rejected when it leaves the hard iron this many times less
/// certain (predicted 1σ) than the algebraic start did; see [`refine`]. Sound fits
/// change it by under 1.5×, drifting ones by 3-8× (measured on bands of ±5°).
const MAX_REFINE_STD_GROWTH: f64 = 2.0;

/// The solver stops after this many evaluations per parameter. A well-posed fit
/// converges in 10-20 evaluations in all; one that wanders (a degenerate band) would
/// otherwise spend 100 per parameter before giving up.
const REFINE_PATIENCE: usize = 10;

/// The most generators a model has (the full model's six free entries of `A`).
const MAX_GENERATORS: usize = 6;

/// The residual (µT) given to every sample for a trial step the solver must reject.
const REJECTED_STEP_UT: f64 = 1e6;

/// Relative regularisation of the reduced scatter matrix before its Cholesky factor is
/// taken: noise-free data make it exactly singular (the solution is its null vector).
const SCATTER_REGULARISATION: f64 = 1e-12;

/// Which soft-iron matrix a fit may use, as MATLAB's `magcal` offers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
pub enum EllipsoidModel {
    /// Hard iron and one scale (`A = s·I`; magcal's `eye`).
    Sphere,
    /// Hard iron and one scale per axis (`magcal`'s `diag`).
    Diagonal,
    /// Hard iron and a symmetric `A` (`magcal`'s `sym`).
    Full,
    /// For a band of data (every heading, little tilt): hard iron and a symmetric `A`
    /// whose scale along the band's axis (the data's direction of least spread) is
    /// tied to the mean of its two in-plane scales, five free entries instead of six.
    /// Not in `magcal`; the fallback of the others when the band is narrow.
    Band,
    /// The simplest of sphere, diagonal and full whose residual is close to the full
    /// model's.
    #[default]
    Auto,
}

/// What [`fit_ellipsoid`] may do.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct EllipsoidOptions {
    pub model: EllipsoidModel,
    /// The Earth's field magnitude where the data were taken (from a model such as the
    /// WMM), if known. The corrected field then has this magnitude.
    pub expected_field_ut: Option<f64>,
    /// Refine the algebraic fit by Levenberg-Marquardt on geometric residuals.
    pub refine: bool,
}

impl Default for EllipsoidOptions {
    fn default() -> Self {
        EllipsoidOptions {
            model: EllipsoidModel::Auto,
            expected_field_ut: None,
            refine: true,
        }
    }
}

/// A 3D calibration and how well the data supported it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EllipsoidFit {
    pub calibration: FieldCalibration,
    /// The model used (never `Auto`).
    pub model: EllipsoidModel,
    /// RMS of `|corrected| − field_ut` over the samples (over the refinement's evenly
    /// spaced subset when there are more than [`MAX_REFINE_SAMPLES`]).
    pub residual_rms_ut: f64,
    /// Standard deviation of `|corrected|` over its mean, in percent (MotionCal's
    /// "variance"), over the same samples.
    pub field_spread_pct: f64,
    pub n_samples: usize,
    /// Whether the geometric refinement ran and was kept.
    pub refined: bool,
    /// Why the fit used a simpler model than asked for, when it did.
    pub fallback: Option<String>,
    pub observability: Observability,
}

/// How well the samples' geometry constrains a 3D fit.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Observability {
    /// Standard deviations of the raw samples along their principal axes, largest
    /// first (µT).
    pub principal_spread_ut: [f64; 3],
    /// The unit direction (body frame) along which the samples vary least: the axis
    /// of a band of data.
    pub least_spread_axis: Vector3<f64>,
    /// The half-width (±degrees) of the band the samples form around that axis,
    /// `atan(√3·σ₃ / √(σ₁² + σ₂²))`: a band of tilts uniform within ±a degrees gives
    /// about a, a level ring gives the noise's share (`√3·σ/H`, 1.4° at 0.3 µT), a
    /// full sphere `atan √(3/2)` ≈ 51° (40-50° once distorted). Roll and pitch each
    /// uniform within ±10° give about 10°, within ±30° about 22°.
    pub tilt_span_deg: f64,
    /// Longest over shortest semi-axis of the fitted raw ellipsoid.
    pub axis_ratio: f64,
    /// The hard iron's predicted 1σ uncertainty along its worst direction (µT), from the
    /// Gauss-Newton covariance of the geometric residuals: noise and geometry, not model
    /// error. `None` from [`EllipsoidAccumulator::solve`], which has no samples.
    pub hard_iron_std_ut: Option<f64>,
}

/// Why an ellipsoid could not be fitted. Messages say what the user can do.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum EllipsoidError {
    #[error(
        "too few magnetometer samples ({n_samples}; at least {min} are needed). Record \
         longer while turning the device through many orientations."
    )]
    TooFewSamples { n_samples: usize, min: usize },

    #[error(
        "sample {sample_idx} is not a finite number. Remove NaN or infinite values from \
         the input."
    )]
    NonFinite { sample_idx: usize },

    #[error(
        "sample {sample_idx} reads {value_ut:e} µT, beyond any magnetometer's range \
         (±{max_ut:e} µT). Check the units of the input (µT are expected)."
    )]
    OutOfRange {
        sample_idx: usize,
        value_ut: f64,
        max_ut: f64,
    },

    #[error(
        "the expected field {field_ut} µT is not a positive number. Give the Earth's field \
         magnitude where the data were taken (25-65 µT), or none."
    )]
    InvalidExpectedField { field_ut: f64 },

    #[error(
        "the samples hardly change (spread {spread_ut:.2} µT): the device was not turned. \
         Record while turning it through many orientations."
    )]
    NoRotation { spread_ut: f64 },

    #[error(
        "the samples lie along a line ({length_ut:.1} µT long, {width_ut:.2} µT wide), not \
         on an ellipsoid: the field changed in one direction only, as near a moving magnet. \
         Record away from moving iron while turning the device."
    )]
    Line { length_ut: f64, width_ut: f64 },

    #[error(
        "the samples lie in a plane (±{tilt_span_deg:.1}° of tilt), so a 3D fit cannot see \
         across it. Use the level 2D calibration with the accelerometer's tilt, or record \
         again while also tilting the device."
    )]
    Plane { tilt_span_deg: f64 },

    #[error(
        "no {model:?} ellipsoid fits the samples (the best quadric is not closed, or its \
         axes differ more than {max_axis_ratio}:1). Record away from iron that moves with \
         respect to the sensor, turning the device through many orientations."
    )]
    NotAnEllipsoid {
        model: EllipsoidModel,
        max_axis_ratio: f64,
    },

    #[error(
        "the samples lie far from any ellipsoid (RMS {residual_rms_ut:.1} µT off a \
         {field_ut:.1} µT field): the field changed during the recording, as near moving \
         iron, a magnet or a passing vehicle. Record again away from them."
    )]
    PoorFit { residual_rms_ut: f64, field_ut: f64 },
}

// ---------------------------------------------------------------------------------
// Power sums
// ---------------------------------------------------------------------------------

/// The number of monomials `x^a·y^b·z^c` with `a + b + c ≤ 4`.
const N_MOMENTS: usize = 35;

/// Their exponents, by degree, then by falling power of x, then of y. [`monomials`]
/// writes them out in this order.
const EXPONENTS: [[usize; 3]; N_MOMENTS] = build_exponents();

/// The index in [`EXPONENTS`] of each `(a, b, c)`; unused where `a + b + c > 4`.
const MOMENT_INDEX: [[[usize; 5]; 5]; 5] = build_moment_index();

const fn build_exponents() -> [[usize; 3]; N_MOMENTS] {
    let mut exponents = [[0usize; 3]; N_MOMENTS];
    let mut moment_idx = 0;
    let mut degree = 0;
    while degree <= 4 {
        let mut a = degree + 1;
        while a > 0 {
            a -= 1;
            let mut b = degree - a + 1;
            while b > 0 {
                b -= 1;
                exponents[moment_idx] = [a, b, degree - a - b];
                moment_idx += 1;
            }
        }
        degree += 1;
    }
    exponents
}

const fn build_moment_index() -> [[[usize; 5]; 5]; 5] {
    let mut index = [[[usize::MAX; 5]; 5]; 5];
    let mut moment_idx = 0;
    while moment_idx < N_MOMENTS {
        let [a, b, c] = EXPONENTS[moment_idx];
        index[a][b][c] = moment_idx;
        moment_idx += 1;
    }
    index
}

/// The monomials of `d` in the order of [`EXPONENTS`], written out so that the
/// per-sample work is straight-line code (about 50 multiplications).
#[inline(always)]
fn monomials(d: Vector3<f64>) -> [f64; N_MOMENTS] {
    let (x, y, z) = (d.x, d.y, d.z);
    let (xx, xy, xz, yy, yz, zz) = (x * x, x * y, x * z, y * y, y * z, z * z);
    [
        1.0,
        x,
        y,
        z,
        xx,
        xy,
        xz,
        yy,
        yz,
        zz,
        x * xx,
        x * xy,
        x * xz,
        x * yy,
        x * yz,
        x * zz,
        y * yy,
        y * yz,
        y * zz,
        z * zz,
        xx * xx,
        xx * xy,
        xx * xz,
        xx * yy,
        xx * yz,
        xx * zz,
        xy * yy,
        xy * yz,
        xy * zz,
        xz * zz,
        yy * yy,
        yy * yz,
        yy * zz,
        yz * zz,
        zz * zz,
    ]
}

/// Samples per chunk in [`EllipsoidAccumulator::add_all`]: 6 KiB of offsets, which
/// stay in the L1 cache while they are read four times.
const CHUNK_LEN: usize = 256;

/// The power sums of one chunk's offsets from `origin_ut`, in the order of
/// [`EXPONENTS`], or `None` if a sample in it is not finite or out of range (the
/// slow path then finds and reports it).
fn chunk_moments(samples_ut: &[Vector3<f64>], origin_ut: Vector3<f64>) -> Option<[f64; N_MOMENTS]> {
    let mut offsets = [[0.0f64; 3]; CHUNK_LEN];
    // A comparison with NaN is false, so a non-finite sample also clears `in_range`.
    let mut in_range = true;
    for (offset, m_ut) in offsets.iter_mut().zip(samples_ut) {
        *offset = [
            m_ut.x - origin_ut.x,
            m_ut.y - origin_ut.y,
            m_ut.z - origin_ut.z,
        ];
        // `&` rather than `&&`: no branch per sample.
        in_range &= (m_ut.x.abs() <= MAX_ABS_UT)
            & (m_ut.y.abs() <= MAX_ABS_UT)
            & (m_ut.z.abs() <= MAX_ABS_UT);
    }
    if !in_range {
        return None;
    }
    offsets.get(..samples_ut.len()).map(offset_sums)
}

/// The power sums of at most [`CHUNK_LEN`] offsets, two at a time in SSE2 registers
/// (x86-64 only, where SSE2 is always present).
#[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
fn offset_sums(offsets: &[[f64; 3]]) -> [f64; N_MOMENTS] {
    // SAFETY: `sse2::offset_sums` needs only the SSE2 target feature, and the `cfg`
    // above compiles this call only where that feature is enabled for the whole build.
    unsafe { sse2::offset_sums(offsets) }
}

/// The power sums of at most [`CHUNK_LEN`] offsets (targets without SSE2, e.g. wasm).
#[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
fn offset_sums(offsets: &[[f64; 3]]) -> [f64; N_MOMENTS] {
    scalar_offset_sums(offsets)
}

/// The power sums of a few offsets, in the order of [`EXPONENTS`].
///
/// Adding 35 sums per sample to memory is limited by the stores (one per cycle, twice
/// the arithmetic's time), so the offsets are read four times instead, each time for at
/// most ten sums that stay in registers, and the sums are stored once per chunk.
/// Written out by hand because the crate's release profile (`opt-level = "s"`) neither
/// unrolls nor vectorises.
fn scalar_offset_sums(offsets: &[[f64; 3]]) -> [f64; N_MOMENTS] {
    // Degrees 1 and 2.
    let (mut x1, mut y1, mut z1) = (0.0, 0.0, 0.0);
    let (mut xx, mut xy, mut xz, mut yy, mut yz, mut zz) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    for &[x, y, z] in offsets {
        x1 += x;
        y1 += y;
        z1 += z;
        xx += x * x;
        xy += x * y;
        xz += x * z;
        yy += y * y;
        yz += y * z;
        zz += z * z;
    }
    // Degree 3.
    let (mut xxx, mut xxy, mut xxz, mut xyy, mut xyz) = (0.0, 0.0, 0.0, 0.0, 0.0);
    let (mut xzz, mut yyy, mut yyz, mut yzz, mut zzz) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for &[x, y, z] in offsets {
        let (x2, y2, z2) = (x * x, y * y, z * z);
        xxx += x2 * x;
        xxy += x2 * y;
        xxz += x2 * z;
        xyy += x * y2;
        xyz += x * y * z;
        xzz += x * z2;
        yyy += y2 * y;
        yyz += y2 * z;
        yzz += y * z2;
        zzz += z2 * z;
    }
    // Degree 4, with x.
    let (mut xxxx, mut xxxy, mut xxxz, mut xxyy) = (0.0, 0.0, 0.0, 0.0);
    let (mut xxyz, mut xxzz, mut xyyy, mut xyyz) = (0.0, 0.0, 0.0, 0.0);
    for &[x, y, z] in offsets {
        let (x2, y2) = (x * x, y * y);
        let x3 = x2 * x;
        xxxx += x3 * x;
        xxxy += x3 * y;
        xxxz += x3 * z;
        xxyy += x2 * y2;
        xxyz += x2 * (y * z);
        xxzz += x2 * (z * z);
        xyyy += x * y2 * y;
        xyyz += x * y2 * z;
    }
    // Degree 4, the rest.
    let (mut xyzz, mut xzzz, mut yyyy, mut yyyz) = (0.0, 0.0, 0.0, 0.0);
    let (mut yyzz, mut yzzz, mut zzzz) = (0.0, 0.0, 0.0);
    for &[x, y, z] in offsets {
        let (y2, z2) = (y * y, z * z);
        xyzz += x * y * z2;
        xzzz += x * z2 * z;
        yyyy += y2 * y2;
        yyyz += y2 * y * z;
        yyzz += y2 * z2;
        yzzz += y * z2 * z;
        zzzz += z2 * z2;
    }
    [
        offsets.len() as f64,
        x1,
        y1,
        z1,
        xx,
        xy,
        xz,
        yy,
        yz,
        zz,
        xxx,
        xxy,
        xxz,
        xyy,
        xyz,
        xzz,
        yyy,
        yyz,
        yzz,
        zzz,
        xxxx,
        xxxy,
        xxxz,
        xxyy,
        xxyz,
        xxzz,
        xyyy,
        xyyz,
        xyzz,
        xzzz,
        yyyy,
        yyyz,
        yyzz,
        yzzz,
        zzzz,
    ]
}

/// [`scalar_offset_sums`] with two samples per SSE2 register, one in each lane: 2.8
/// times faster under the release profile (4.3 against 12.3 ms for a million samples
/// on the development machine), because that profile does not vectorise by itself.
#[cfg(all(target_arch = "x86_64", target_feature = "sse2"))]
mod sse2 {
    use std::arch::x86_64::{
        __m128d, _mm_add_pd, _mm_cvtsd_f64, _mm_mul_pd, _mm_set_pd, _mm_setzero_pd, _mm_unpackhi_pd,
    };

    use super::{scalar_offset_sums, CHUNK_LEN, N_MOMENTS};

    /// `sum + a·b` in both lanes.
    #[inline]
    #[target_feature(enable = "sse2")]
    fn add_product(sum: __m128d, a: __m128d, b: __m128d) -> __m128d {
        _mm_add_pd(sum, _mm_mul_pd(a, b))
    }

    #[inline]
    #[target_feature(enable = "sse2")]
    fn mul(a: __m128d, b: __m128d) -> __m128d {
        _mm_mul_pd(a, b)
    }

    /// The sum of the two lanes.
    #[inline]
    #[target_feature(enable = "sse2")]
    fn lanes(v: __m128d) -> f64 {
        _mm_cvtsd_f64(v) + _mm_cvtsd_f64(_mm_unpackhi_pd(v, v))
    }

    #[target_feature(enable = "sse2")]
    pub(super) fn offset_sums(offsets: &[[f64; 3]]) -> [f64; N_MOMENTS] {
        let zero = _mm_setzero_pd();
        let one = _mm_set_pd(1.0, 1.0);
        let mut pairs = [[zero; 3]; CHUNK_LEN / 2];
        let mut n_pairs = 0;
        for (pair, two) in pairs.iter_mut().zip(offsets.chunks_exact(2)) {
            if let [a, b] = two {
                *pair = [
                    _mm_set_pd(b[0], a[0]),
                    _mm_set_pd(b[1], a[1]),
                    _mm_set_pd(b[2], a[2]),
                ];
                n_pairs += 1;
            }
        }
        let pairs = pairs.get(..n_pairs).unwrap_or_default();
        // Degrees 1 and 2.
        let (mut x1, mut y1, mut z1) = (zero, zero, zero);
        let (mut xx, mut xy, mut xz, mut yy, mut yz, mut zz) = (zero, zero, zero, zero, zero, zero);
        for &[x, y, z] in pairs {
            x1 = add_product(x1, x, one);
            y1 = add_product(y1, y, one);
            z1 = add_product(z1, z, one);
            xx = add_product(xx, x, x);
            xy = add_product(xy, x, y);
            xz = add_product(xz, x, z);
            yy = add_product(yy, y, y);
            yz = add_product(yz, y, z);
            zz = add_product(zz, z, z);
        }
        // Degree 3.
        let (mut xxx, mut xxy, mut xxz, mut xyy, mut xyz) = (zero, zero, zero, zero, zero);
        let (mut xzz, mut yyy, mut yyz, mut yzz, mut zzz) = (zero, zero, zero, zero, zero);
        for &[x, y, z] in pairs {
            let (x2, y2, z2) = (mul(x, x), mul(y, y), mul(z, z));
            xxx = add_product(xxx, x2, x);
            xxy = add_product(xxy, x2, y);
            xxz = add_product(xxz, x2, z);
            xyy = add_product(xyy, x, y2);
            xyz = add_product(xyz, mul(x, y), z);
            xzz = add_product(xzz, x, z2);
            yyy = add_product(yyy, y2, y);
            yyz = add_product(yyz, y2, z);
            yzz = add_product(yzz, y, z2);
            zzz = add_product(zzz, z2, z);
        }
        // Degree 4, with x.
        let (mut xxxx, mut xxxy, mut xxxz, mut xxyy) = (zero, zero, zero, zero);
        let (mut xxyz, mut xxzz, mut xyyy, mut xyyz) = (zero, zero, zero, zero);
        for &[x, y, z] in pairs {
            let (x2, y2) = (mul(x, x), mul(y, y));
            let (x3, xy2) = (mul(x2, x), mul(x, y2));
            xxxx = add_product(xxxx, x3, x);
            xxxy = add_product(xxxy, x3, y);
            xxxz = add_product(xxxz, x3, z);
            xxyy = add_product(xxyy, x2, y2);
            xxyz = add_product(xxyz, x2, mul(y, z));
            xxzz = add_product(xxzz, x2, mul(z, z));
            xyyy = add_product(xyyy, xy2, y);
            xyyz = add_product(xyyz, xy2, z);
        }
        // Degree 4, the rest.
        let (mut xyzz, mut xzzz, mut yyyy, mut yyyz) = (zero, zero, zero, zero);
        let (mut yyzz, mut yzzz, mut zzzz) = (zero, zero, zero);
        for &[x, y, z] in pairs {
            let (y2, z2) = (mul(y, y), mul(z, z));
            let (yz2, z3) = (mul(y, z2), mul(z2, z));
            xyzz = add_product(xyzz, x, yz2);
            xzzz = add_product(xzzz, x, z3);
            yyyy = add_product(yyyy, y2, y2);
            yyyz = add_product(yyyz, mul(y2, y), z);
            yyzz = add_product(yyzz, y2, z2);
            yzzz = add_product(yzzz, y, z3);
            zzzz = add_product(zzzz, z2, z2);
        }
        let mut sums = [
            2.0 * pairs.len() as f64,
            lanes(x1),
            lanes(y1),
            lanes(z1),
            lanes(xx),
            lanes(xy),
            lanes(xz),
            lanes(yy),
            lanes(yz),
            lanes(zz),
            lanes(xxx),
            lanes(xxy),
            lanes(xxz),
            lanes(xyy),
            lanes(xyz),
            lanes(xzz),
            lanes(yyy),
            lanes(yyz),
            lanes(yzz),
            lanes(zzz),
            lanes(xxxx),
            lanes(xxxy),
            lanes(xxxz),
            lanes(xxyy),
            lanes(xxyz),
            lanes(xxzz),
            lanes(xyyy),
            lanes(xyyz),
            lanes(xyzz),
            lanes(xzzz),
            lanes(yyyy),
            lanes(yyyz),
            lanes(yyzz),
            lanes(yzzz),
            lanes(zzzz),
        ];
        // An odd chunk's last sample has no partner.
        let leftover = offsets.chunks_exact(2).remainder();
        if !leftover.is_empty() {
            for (sum, term) in sums.iter_mut().zip(scalar_offset_sums(leftover)) {
                *sum += term;
            }
        }
        sums
    }
}

const BINOMIAL: [[f64; 5]; 5] = [
    [1.0, 0.0, 0.0, 0.0, 0.0],
    [1.0, 1.0, 0.0, 0.0, 0.0],
    [1.0, 2.0, 1.0, 0.0, 0.0],
    [1.0, 3.0, 3.0, 1.0, 0.0],
    [1.0, 4.0, 6.0, 4.0, 1.0],
];

/// The power sums of `(d + shift) / scale` from those of `d`. By the binomial theorem,
/// `Σ (d + δ)^α = Σ_{β ≤ α} C(α, β)·δ^(α−β)·Σ d^β`, one axis at a time.
fn shift_and_scale(
    moments: &[f64; N_MOMENTS],
    shift: Vector3<f64>,
    scale: f64,
) -> [f64; N_MOMENTS] {
    let powers = |value: f64| {
        let mut powers = [1.0; 5];
        for power_idx in 1..5 {
            powers[power_idx] = powers[power_idx - 1] * value;
        }
        powers
    };
    let (shift_x, shift_y, shift_z) = (powers(shift.x), powers(shift.y), powers(shift.z));
    let inverse_scale = powers(1.0 / scale);
    let mut shifted = [0.0; N_MOMENTS];
    for (target, &[a, b, c]) in shifted.iter_mut().zip(EXPONENTS.iter()) {
        let mut sum = 0.0;
        for i in 0..=a {
            for j in 0..=b {
                for k in 0..=c {
                    sum += BINOMIAL[a][i]
                        * BINOMIAL[b][j]
                        * BINOMIAL[c][k]
                        * shift_x[a - i]
                        * shift_y[b - j]
                        * shift_z[c - k]
                        * moments[MOMENT_INDEX[i][j][k]];
                }
            }
        }
        *target = sum * inverse_scale[a + b + c];
    }
    shifted
}

/// The streaming half of the fit: one pass over the samples, in any order and any
/// chunking, merged across chunks or threads.
#[derive(Debug, Clone, PartialEq)]
pub struct EllipsoidAccumulator {
    /// The first finite sample: the power sums are of offsets from it, which keeps
    /// their magnitudes near the field's rather than the hard iron's.
    origin_ut: Option<Vector3<f64>>,
    /// `Σ d^α` over the finite samples, in the order of [`EXPONENTS`]; the first is
    /// their count.
    moments: [f64; N_MOMENTS],
    n_seen: usize,
    /// The first sample refused (not finite, or out of any sensor's range), as the
    /// error [`solve`](Self::solve) will return.
    first_rejected: Option<EllipsoidError>,
}

impl Default for EllipsoidAccumulator {
    fn default() -> Self {
        EllipsoidAccumulator::new()
    }
}

impl EllipsoidAccumulator {
    pub fn new() -> Self {
        EllipsoidAccumulator {
            origin_ut: None,
            moments: [0.0; N_MOMENTS],
            n_seen: 0,
            first_rejected: None,
        }
    }

    /// Adds one sample. One that is not finite or beyond [`MAX_ABS_UT`] is counted,
    /// remembered by its index (in the order samples were added), and makes
    /// [`solve`](Self::solve) fail.
    pub fn add(&mut self, m_ut: Vector3<f64>) {
        let sample_idx = self.n_seen;
        self.n_seen += 1;
        if !(m_ut.x.is_finite() && m_ut.y.is_finite() && m_ut.z.is_finite()) {
            self.first_rejected
                .get_or_insert(EllipsoidError::NonFinite { sample_idx });
            return;
        }
        let value_ut = m_ut.amax();
        if value_ut > MAX_ABS_UT {
            self.first_rejected
                .get_or_insert(EllipsoidError::OutOfRange {
                    sample_idx,
                    value_ut,
                    max_ut: MAX_ABS_UT,
                });
            return;
        }
        let origin_ut = *self.origin_ut.get_or_insert(m_ut);
        let terms = monomials(m_ut - origin_ut);
        for (moment, term) in self.moments.iter_mut().zip(terms) {
            *moment += term;
        }
    }

    /// Adds a slice of samples, as repeated [`add`](Self::add) would (up to rounding),
    /// several times faster: in chunks whose sums stay in registers, two samples per
    /// SSE2 register on x86-64.
    pub fn add_all(&mut self, samples_ut: &[Vector3<f64>]) {
        for chunk in samples_ut.chunks(CHUNK_LEN) {
            let sums = self
                .origin_ut
                .and_then(|origin_ut| chunk_moments(chunk, origin_ut));
            match sums {
                Some(sums) => {
                    self.n_seen += chunk.len();
                    for (moment, sum) in self.moments.iter_mut().zip(sums) {
                        *moment += sum;
                    }
                }
                // The first chunk (no origin yet) and chunks with a refused sample go
                // one sample at a time.
                None => {
                    for &m_ut in chunk {
                        self.add(m_ut);
                    }
                }
            }
        }
    }

    /// Adds the samples another accumulator has seen, as if they had been added here
    /// after this one's (indices of refused samples continue this one's count).
    pub fn merge(&mut self, other: &EllipsoidAccumulator) {
        if self.first_rejected.is_none() {
            self.first_rejected = match other.first_rejected {
                Some(EllipsoidError::NonFinite { sample_idx }) => Some(EllipsoidError::NonFinite {
                    sample_idx: sample_idx + self.n_seen,
                }),
                Some(EllipsoidError::OutOfRange {
                    sample_idx,
                    value_ut,
                    max_ut,
                }) => Some(EllipsoidError::OutOfRange {
                    sample_idx: sample_idx + self.n_seen,
                    value_ut,
                    max_ut,
                }),
                ref other_error => other_error.clone(),
            };
        }
        self.n_seen += other.n_seen;
        match (self.origin_ut, other.origin_ut) {
            (_, None) => {}
            (None, Some(_)) => {
                self.origin_ut = other.origin_ut;
                self.moments = other.moments;
            }
            (Some(origin_ut), Some(other_origin_ut)) => {
                let moved = shift_and_scale(&other.moments, other_origin_ut - origin_ut, 1.0);
                for (moment, other_moment) in self.moments.iter_mut().zip(moved) {
                    *moment += other_moment;
                }
            }
        }
    }

    /// The number of samples added, finite or not.
    pub fn n_samples(&self) -> usize {
        self.n_seen
    }

    /// The algebraic fit of `model` (no refinement). `Auto` gives the full model
    /// unless the data form a band too narrow for it, when it falls back as
    /// [`fit_ellipsoid`] does; the residual figures are first-order approximations
    /// from the power sums (`(|c|² − R²) / 2R` for `|c| − R`).
    pub fn solve(
        &self,
        model: EllipsoidModel,
        expected_field_ut: Option<f64>,
    ) -> Result<EllipsoidFit, EllipsoidError> {
        let expected_field_ut = check_expected_field(expected_field_ut)?;
        let geometry = self.geometry()?;
        let solved = |model| -> Result<(FieldCalibration, f64, f64), EllipsoidError> {
            let calibration = geometry.algebraic_fit(model, expected_field_ut)?;
            let (rms_ut, spread_pct) = geometry.approximate_residuals(&calibration);
            Ok((calibration, rms_ut, spread_pct))
        };
        let model = match model {
            EllipsoidModel::Auto => EllipsoidModel::Full,
            model => model,
        };
        let mut chosen = (model, solved(model), None);
        if matches!(model, EllipsoidModel::Full | EllipsoidModel::Diagonal) {
            let band = solved(EllipsoidModel::Band);
            let fall_back = match (&band, &chosen.1) {
                (Ok((_, band_rms_ut, _)), Ok((_, rms_ut, _))) => {
                    prefers_band(&geometry, *band_rms_ut, *rms_ut)
                }
                (Ok(_), Err(_)) => geometry.tilt_span_deg < MIN_FULL_TILT_SPAN_DEG,
                _ => false,
            };
            if fall_back {
                chosen = (
                    EllipsoidModel::Band,
                    band,
                    Some(band_fallback_sentence(&geometry)),
                );
            }
        }
        let (model, solution, fallback) = chosen;
        let (calibration, residual_rms_ut, field_spread_pct) = solution?;
        check_residual(residual_rms_ut, &calibration)?;
        Ok(EllipsoidFit {
            observability: geometry.observability(&calibration),
            calibration,
            model,
            residual_rms_ut,
            field_spread_pct,
            n_samples: self.n_seen,
            refined: false,
            fallback,
        })
    }

    /// Checks the data and moves the sums to a well-conditioned frame.
    fn geometry(&self) -> Result<Geometry, EllipsoidError> {
        if let Some(error) = &self.first_rejected {
            return Err(error.clone());
        }
        let n_finite = self.moments[0];
        let origin_ut = match self.origin_ut {
            Some(origin_ut) if self.n_seen >= MIN_SAMPLES => origin_ut,
            _ => {
                return Err(EllipsoidError::TooFewSamples {
                    n_samples: self.n_seen,
                    min: MIN_SAMPLES,
                })
            }
        };
        let mean_offset_ut =
            Vector3::new(self.moments[1], self.moments[2], self.moments[3]) / n_finite;
        let centred = shift_and_scale(&self.moments, -mean_offset_ut, 1.0);
        let second = |a: usize, b: usize, c: usize| centred[MOMENT_INDEX[a][b][c]] / n_finite;
        let covariance_ut2 = Matrix3::new(
            second(2, 0, 0),
            second(1, 1, 0),
            second(1, 0, 1),
            second(1, 1, 0),
            second(0, 2, 0),
            second(0, 1, 1),
            second(1, 0, 1),
            second(0, 1, 1),
            second(0, 0, 2),
        );
        let spread_ut = covariance_ut2.trace().max(0.0).sqrt();
        if spread_ut.is_nan() || spread_ut < MIN_SPREAD_UT {
            return Err(EllipsoidError::NoRotation { spread_ut });
        }
        let Some(eigen) = symmetric_eigen(covariance_ut2) else {
            return Err(EllipsoidError::NoRotation { spread_ut });
        };
        let mut axes: [(f64, Vector3<f64>); 3] = std::array::from_fn(|axis_idx| {
            (
                eigen.eigenvalues[axis_idx].max(0.0).sqrt(),
                eigen.eigenvectors.column(axis_idx).into_owned(),
            )
        });
        axes.sort_by(|a, b| b.0.total_cmp(&a.0));
        let principal_spread_ut = [axes[0].0, axes[1].0, axes[2].0];
        if principal_spread_ut[1] < MIN_WIDTH_FRACTION * principal_spread_ut[0] {
            return Err(EllipsoidError::Line {
                length_ut: principal_spread_ut[0],
                width_ut: principal_spread_ut[1],
            });
        }
        let in_plane_ut = principal_spread_ut[0].hypot(principal_spread_ut[1]);
        let tilt_span_deg = (3f64.sqrt() * principal_spread_ut[2] / in_plane_ut)
            .atan()
            .to_degrees();
        if tilt_span_deg < MIN_TILT_SPAN_DEG {
            return Err(EllipsoidError::Plane { tilt_span_deg });
        }
        let scale_ut = spread_ut;
        Ok(Geometry {
            n_samples: n_finite,
            mean_ut: origin_ut + mean_offset_ut,
            scale_ut,
            normalised: shift_and_scale(&centred, Vector3::zeros(), scale_ut),
            principal_spread_ut,
            principal_axes: Matrix3::from_columns(&[axes[0].1, axes[1].1, axes[2].1]),
            tilt_span_deg,
        })
    }
}

/// The power sums in the frame the fits are solved in, `u = (m − mean) / scale`, and
/// what they say about the data's shape.
#[derive(Debug, Clone)]
struct Geometry {
    n_samples: f64,
    mean_ut: Vector3<f64>,
    scale_ut: f64,
    normalised: [f64; N_MOMENTS],
    principal_spread_ut: [f64; 3],
    /// Unit principal directions of the samples, as columns, by falling spread.
    principal_axes: Matrix3<f64>,
    tilt_span_deg: f64,
}

/// The design vector of the quadric
/// `a·x² + b·y² + c·z² + 2f·yz + 2g·xz + 2h·xy + 2p·x + 2q·y + 2r·z + d` (Li and
/// Griffiths' order): each entry is a factor times a monomial, given by its exponents.
const DESIGN: [(f64, [usize; 3]); 10] = [
    (1.0, [2, 0, 0]),
    (1.0, [0, 2, 0]),
    (1.0, [0, 0, 2]),
    (2.0, [0, 1, 1]),
    (2.0, [1, 0, 1]),
    (2.0, [1, 1, 0]),
    (2.0, [1, 0, 0]),
    (2.0, [0, 1, 0]),
    (2.0, [0, 0, 1]),
    (1.0, [0, 0, 0]),
];

impl Geometry {
    fn moment(&self, exponents: [usize; 3]) -> f64 {
        let [a, b, c] = exponents;
        self.normalised[MOMENT_INDEX[a][b][c]]
    }

    /// `D·Dᵀ` over the chosen design entries.
    fn scatter(&self, entries: &[usize]) -> DMatrix<f64> {
        DMatrix::from_fn(entries.len(), entries.len(), |row, col| {
            let (row_factor, row_exponents) = DESIGN[entries[row]];
            let (col_factor, col_exponents) = DESIGN[entries[col]];
            let exponents = [
                row_exponents[0] + col_exponents[0],
                row_exponents[1] + col_exponents[1],
                row_exponents[2] + col_exponents[2],
            ];
            row_factor * col_factor * self.moment(exponents)
        })
    }

    /// The algebraic fit of a model whose quadric matrix is `Q = Σ θ_k·G_k` (its
    /// generators): Li and Griffiths' method on the scatter of the reduced design
    /// `(uᵀG_k·u…, 2x, 2y, 2z, 1)`, which is `Tᵀ·(D·Dᵀ)·T` for the matrix `T` that
    /// maps the reduced coefficients to the full ones, with the constraint `Tᵀ·C·T`.
    /// For the sphere this is Kåsa's (1976) linear fit, for the full model Magneto's.
    fn algebraic_fit(
        &self,
        model: EllipsoidModel,
        expected_field_ut: Option<f64>,
    ) -> Result<FieldCalibration, EllipsoidError> {
        let generators = generators(model, self);
        let n_quadratic = generators.len();
        // Full coefficients (a, b, c, f, g, h, p, q, r, d) from reduced ones.
        let mut reduction = DMatrix::zeros(10, n_quadratic + 4);
        for (generator_idx, generator) in generators.iter().enumerate() {
            let full = [
                generator[(0, 0)],
                generator[(1, 1)],
                generator[(2, 2)],
                generator[(1, 2)],
                generator[(0, 2)],
                generator[(0, 1)],
            ];
            for (row, value) in full.into_iter().enumerate() {
                reduction[(row, generator_idx)] = value;
            }
        }
        for linear_idx in 0..4 {
            reduction[(6 + linear_idx, n_quadratic + linear_idx)] = 1.0;
        }
        let all: Vec<usize> = (0..10).collect();
        let scatter = reduction.transpose() * self.scatter(&all) * &reduction;
        let quadratic_reduction = reduction.view((0, 0), (6, n_quadratic));
        let constraint = quadratic_reduction.transpose() * full_constraint() * quadratic_reduction;
        li_griffiths(&scatter, &constraint)
            .and_then(|coefficients| {
                let quadratic = generators
                    .iter()
                    .zip(coefficients.iter())
                    .fold(Matrix3::zeros(), |sum, (generator, &theta)| {
                        sum + generator * theta
                    });
                let quadric = Quadric {
                    quadratic,
                    linear: Vector3::new(
                        coefficients[n_quadratic],
                        coefficients[n_quadratic + 1],
                        coefficients[n_quadratic + 2],
                    ),
                    constant: coefficients[n_quadratic + 3],
                };
                quadric.to_calibration(self, expected_field_ut)
            })
            .ok_or(EllipsoidError::NotAnEllipsoid {
                model,
                max_axis_ratio: MAX_AXIS_RATIO,
            })
    }

    /// RMS of `|c| − R` and the spread of `|c|` in percent, to first order in the
    /// residual: `|c| − R ≈ (|c|² − R²) / 2R`, a quadratic in `u` whose square sums are
    /// the scatter matrix's.
    fn approximate_residuals(&self, calibration: &FieldCalibration) -> (f64, f64) {
        let radius_ut = calibration.field_ut;
        // |c|² − R² = (u − u0)ᵀ G (u − u0) − R², with G = s²·AᵀA and u0 the centre.
        let gram = self.scale_ut
            * self.scale_ut
            * calibration.soft_iron.transpose()
            * calibration.soft_iron;
        let centre = (calibration.hard_iron_ut - self.mean_ut) / self.scale_ut;
        let linear = -(gram * centre);
        let coefficients = DVector::from_vec(vec![
            gram[(0, 0)],
            gram[(1, 1)],
            gram[(2, 2)],
            gram[(1, 2)],
            gram[(0, 2)],
            gram[(0, 1)],
            linear.x,
            linear.y,
            linear.z,
            centre.dot(&(gram * centre)) - radius_ut * radius_ut,
        ]);
        let all: Vec<usize> = (0..10).collect();
        let scatter = self.scatter(&all);
        let sum_of_squares = coefficients.dot(&(&scatter * &coefficients)).max(0.0);
        let sum = coefficients.dot(&scatter.column(9));
        let n = self.n_samples;
        let two_r = 2.0 * radius_ut;
        let rms_ut = (sum_of_squares / n).sqrt() / two_r;
        let mean_ut = sum / n / two_r;
        let spread_ut = (rms_ut * rms_ut - mean_ut * mean_ut).max(0.0).sqrt();
        (rms_ut, 100.0 * spread_ut / (radius_ut + mean_ut))
    }

    fn observability(&self, calibration: &FieldCalibration) -> Observability {
        Observability {
            principal_spread_ut: self.principal_spread_ut,
            least_spread_axis: self.principal_axes.column(2).into_owned(),
            tilt_span_deg: self.tilt_span_deg,
            axis_ratio: axis_ratio(&calibration.soft_iron),
            hard_iron_std_ut: None,
        }
    }
}

/// nalgebra's eigen solver iterates until it converges, which a matrix with a NaN or
/// an infinity never does; this bounds it.
const MAX_EIGEN_ITERATIONS: usize = 10_000;

/// The eigen decomposition of a finite symmetric 3×3 matrix.
fn symmetric_eigen(matrix: Matrix3<f64>) -> Option<SymmetricEigen<f64, nalgebra::U3>> {
    if matrix.iter().all(|v| v.is_finite()) {
        SymmetricEigen::try_new(matrix, f64::EPSILON, MAX_EIGEN_ITERATIONS)
    } else {
        None
    }
}

/// Longest over shortest semi-axis of the raw ellipsoid that `A` maps to a sphere.
fn axis_ratio(soft_iron: &Matrix3<f64>) -> f64 {
    let Some(eigen) = symmetric_eigen(*soft_iron) else {
        return f64::INFINITY;
    };
    let (min, max) = (eigen.eigenvalues.min(), eigen.eigenvalues.max());
    if min > 0.0 {
        max / min
    } else {
        f64::INFINITY
    }
}

/// The quadric `uᵀQu + 2·lᵀu + d = 0` in the normalised frame.
struct Quadric {
    quadratic: Matrix3<f64>,
    linear: Vector3<f64>,
    constant: f64,
}

impl Quadric {
    /// Centre, `A` and radius, or `None` when the quadric is no (plausible) ellipsoid.
    fn to_calibration(
        &self,
        geometry: &Geometry,
        expected_field_ut: Option<f64>,
    ) -> Option<FieldCalibration> {
        // The equation is defined up to sign; make Q positive.
        let sign = if self.quadratic.trace() < 0.0 {
            -1.0
        } else {
            1.0
        };
        let quadratic = self.quadratic * sign;
        let linear = self.linear * sign;
        let constant = self.constant * sign;
        let centre = -Cholesky::new(quadratic)?.solve(&linear);
        // (u − c)ᵀQ(u − c) = cᵀQc − d.
        let level = centre.dot(&(quadratic * centre)) - constant;
        if level.is_nan() || level <= 0.0 {
            return None;
        }
        let scale_ut = geometry.scale_ut;
        let hard_iron_ut = geometry.mean_ut + centre * scale_ut;
        let unit_sphere_map = symmetric_sqrt(&(quadratic / (level * scale_ut * scale_ut)))?;
        let (soft_iron, field_ut) = match expected_field_ut {
            Some(field_ut) => (unit_sphere_map * field_ut, field_ut),
            None => {
                // det A = 1: the field is the geometric mean of the semi-axes.
                let field_ut = unit_sphere_map.determinant().cbrt().recip();
                (unit_sphere_map * field_ut, field_ut)
            }
        };
        plausible(FieldCalibration {
            hard_iron_ut,
            soft_iron,
            field_ut,
        })
    }
}

/// The symmetric positive square root, or `None` if the matrix is not positive.
fn symmetric_sqrt(matrix: &Matrix3<f64>) -> Option<Matrix3<f64>> {
    let eigen = symmetric_eigen(*matrix)?;
    let smallest = eigen.eigenvalues.min();
    if smallest.is_nan() || smallest <= 0.0 {
        return None;
    }
    let roots = Matrix3::from_diagonal(&eigen.eigenvalues.map(f64::sqrt));
    let root = eigen.eigenvectors * roots * eigen.eigenvectors.transpose();
    Some((root + root.transpose()) * 0.5)
}

/// Li and Griffiths' `C`: `vᵀCv = 4J − I²` for the quadratic coefficients
/// `(a, b, c, f, g, h)`, with `I = a + b + c` and `J = ab + bc + ca − f² − g² − h²`.
fn full_constraint() -> DMatrix<f64> {
    let mut constraint = DMatrix::zeros(6, 6);
    for row in 0..3 {
        for col in 0..3 {
            constraint[(row, col)] = if row == col { -1.0 } else { 1.0 };
        }
        constraint[(row + 3, row + 3)] = -4.0;
    }
    constraint
}

/// Li and Griffiths' ellipsoid-specific fit. `scatter` is `D·Dᵀ` with the quadratic
/// entries first and `(2x, 2y, 2z, 1)` last; returns all coefficients.
///
/// The generalised eigenproblem `M·v1 = λ·C·v1` (`M` the reduced scatter) is made
/// symmetric with `M = L·Lᵀ`: `L⁻¹·C·L⁻ᵀ·w = (1/λ)·w`, `v1 = L⁻ᵀ·w`, and the one
/// positive `λ` is the largest `1/λ`.
fn li_griffiths(scatter: &DMatrix<f64>, constraint: &DMatrix<f64>) -> Option<DVector<f64>> {
    let n_quadratic = constraint.nrows();
    let s11 = scatter
        .view((0, 0), (n_quadratic, n_quadratic))
        .into_owned();
    let s12 = scatter
        .view((0, n_quadratic), (n_quadratic, 4))
        .into_owned();
    let s22 = scatter
        .view((n_quadratic, n_quadratic), (4, 4))
        .into_owned();
    let s22_cholesky = Cholesky::new(s22)?;
    let s22_inv_s21 = s22_cholesky.solve(&s12.transpose());
    let reduced = &s11 - &s12 * &s22_inv_s21;
    let mut reduced = (&reduced + reduced.transpose()) * 0.5;
    let regularisation = SCATTER_REGULARISATION * reduced.trace().abs() / n_quadratic as f64;
    for diagonal_idx in 0..n_quadratic {
        reduced[(diagonal_idx, diagonal_idx)] += regularisation;
    }
    let lower = Cholesky::new(reduced)?.l();
    let half = lower.solve_lower_triangular(constraint)?;
    let symmetric = lower.solve_lower_triangular(&half.transpose())?;
    let symmetric = (&symmetric + symmetric.transpose()) * 0.5;
    let finite = symmetric.iter().all(|v| v.is_finite());
    let eigen = finite
        .then(|| SymmetricEigen::try_new(symmetric, f64::EPSILON, MAX_EIGEN_ITERATIONS))
        .flatten()?;
    let best_idx = eigen.eigenvalues.imax();
    let best = eigen.eigenvalues[best_idx];
    if best.is_nan() || best <= 0.0 {
        return None;
    }
    let w = eigen.eigenvectors.column(best_idx).into_owned();
    let quadratic = lower.tr_solve_lower_triangular(&w)?;
    let linear = -(s22_inv_s21 * &quadratic);
    let mut coefficients = DVector::zeros(n_quadratic + 4);
    coefficients.rows_mut(0, n_quadratic).copy_from(&quadratic);
    coefficients.rows_mut(n_quadratic, 4).copy_from(&linear);
    coefficients
        .iter()
        .all(|v| v.is_finite())
        .then_some(coefficients)
}

// ---------------------------------------------------------------------------------
// Geometric refinement
// ---------------------------------------------------------------------------------

/// The free entries of a model's `A` (and of its quadric matrix, which has the same
/// form): `A = Σ θ_k·G_k`.
fn generators(model: EllipsoidModel, geometry: &Geometry) -> Vec<Matrix3<f64>> {
    let unit = |row: usize, col: usize| {
        let mut matrix = Matrix3::zeros();
        matrix[(row, col)] = 1.0;
        matrix[(col, row)] = 1.0;
        matrix
    };
    match model {
        EllipsoidModel::Sphere => vec![Matrix3::identity()],
        EllipsoidModel::Diagonal => vec![unit(0, 0), unit(1, 1), unit(2, 2)],
        EllipsoidModel::Band => {
            // In the frame of the data's principal axes (the band's plane, then its
            // axis): a free 2×2 block in the plane and free couplings between plane
            // and axis, but along the axis the mean of the in-plane scales, because
            // the band cannot tell that scale from the hard iron along the axis.
            let basis = geometry.principal_axes;
            let in_frame = |matrix: Matrix3<f64>| basis * matrix * basis.transpose();
            let mut first = unit(0, 0);
            first[(2, 2)] = 0.5;
            let mut second = unit(1, 1);
            second[(2, 2)] = 0.5;
            vec![
                in_frame(first),
                in_frame(second),
                in_frame(unit(0, 1)),
                in_frame(unit(0, 2)),
                in_frame(unit(1, 2)),
            ]
        }
        EllipsoidModel::Full | EllipsoidModel::Auto => vec![
            unit(0, 0),
            unit(1, 1),
            unit(2, 2),
            unit(0, 1),
            unit(0, 2),
            unit(1, 2),
        ],
    }
}

/// The coordinates of a symmetric `A` on the generators, by least squares in the
/// Frobenius inner product (exact when `A` lies in their span).
fn coordinates(soft_iron: &Matrix3<f64>, generators: &[Matrix3<f64>]) -> Option<DVector<f64>> {
    let n_generators = generators.len();
    let gram = DMatrix::from_fn(n_generators, n_generators, |row, col| {
        generators[row].dot(&generators[col])
    });
    let projections = DVector::from_iterator(
        n_generators,
        generators.iter().map(|generator| soft_iron.dot(generator)),
    );
    Cholesky::new(gram).map(|cholesky| cholesky.solve(&projections))
}

/// `(|A·(m − h)| − R) / g` over the samples, with `g = (det A)^⅓`, for the
/// Levenberg-Marquardt solver.
///
/// Dividing by the mean gain `g` measures the residual in raw µT (it is the residual
/// of `A/g`, whose determinant is 1, against the radius `R/g`). Without it the solver
/// could shrink every residual by shrinking `A` while moving `h` far away, which a
/// narrow band of data allows at almost no cost.
struct GeometricProblem<'a> {
    samples_ut: &'a [Vector3<f64>],
    generators: &'a [Matrix3<f64>],
    radius_ut: f64,
    /// `h` (3) then the coordinates of `A`.
    params: DVector<f64>,
}

impl GeometricProblem<'_> {
    fn hard_iron_ut(&self) -> Vector3<f64> {
        Vector3::new(self.params[0], self.params[1], self.params[2])
    }

    fn soft_iron(&self) -> Matrix3<f64> {
        self.generators
            .iter()
            .zip(self.params.iter().skip(3))
            .fold(Matrix3::zeros(), |sum, (generator, &theta)| {
                sum + generator * theta
            })
    }

    /// `g = (det A)^⅓`, or `None` when `A` is singular or reflects.
    fn gain(soft_iron: &Matrix3<f64>) -> Option<f64> {
        let determinant = soft_iron.determinant();
        (determinant > 0.0 && determinant.is_finite()).then(|| determinant.cbrt())
    }
}

impl LeastSquaresProblem<f64, Dyn, Dyn> for GeometricProblem<'_> {
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, Dyn>;
    type ParameterStorage = Owned<f64, Dyn>;

    fn set_params(&mut self, params: &DVector<f64>) {
        self.params.copy_from(params);
    }

    fn params(&self) -> DVector<f64> {
        self.params.clone()
    }

    fn residuals(&self) -> Option<DVector<f64>> {
        let (hard_iron_ut, soft_iron) = (self.hard_iron_ut(), self.soft_iron());
        let Some(gain) = Self::gain(&soft_iron) else {
            // A trial step that makes A singular or reflecting is rejected through a
            // huge cost rather than an error, which would end the whole minimisation.
            return Some(DVector::from_element(
                self.samples_ut.len(),
                REJECTED_STEP_UT,
            ));
        };
        let calibration = FieldCalibration {
            hard_iron_ut,
            soft_iron,
            field_ut: self.radius_ut,
        };
        Some(DVector::from_iterator(
            self.samples_ut.len(),
            corrected_magnitudes(self.samples_ut, &calibration)
                .map(|magnitude_ut| (magnitude_ut - self.radius_ut) / gain),
        ))
    }

    fn jacobian(&self) -> Option<DMatrix<f64>> {
        // Filled one sample per column (contiguous), then transposed once.
        let n_params = self.params.len();
        let mut transposed = DMatrix::zeros(n_params, self.samples_ut.len());
        let mut columns = transposed.column_iter_mut();
        self.for_each_row(|_, row| {
            if let Some(mut column) = columns.next() {
                column.copy_from_slice(row);
            }
        })?;
        Some(transposed.transpose())
    }
}

impl GeometricProblem<'_> {
    /// Calls `visit(residual, jacobian_row)` for every sample; `None` when `A` is
    /// singular or a sample maps to zero. The arithmetic is written out on arrays
    /// because this runs per sample and per iteration, and the crate's release
    /// profile (`opt-level = "s"`) leaves nalgebra's small loops rolled.
    fn for_each_row(&self, mut visit: impl FnMut(f64, &[f64])) -> Option<()> {
        let (hard_iron_ut, soft_iron) = (self.hard_iron_ut(), self.soft_iron());
        let gain = Self::gain(&soft_iron)?;
        let inverse = soft_iron.try_inverse()?;
        let inverse_gain = gain.recip();
        // ∂g/∂θ_k = (g/3)·tr(A⁻¹·G_k), so ∂(1/g)/∂θ_k = −tr(A⁻¹·G_k) / (3g); and for a
        // symmetric G, uᵀ·G·d = Σ_i G_ii·u_i·d_i + Σ_{i<j} G_ij·(u_i·d_j + u_j·d_i).
        let mut log_gain_rates = [0.0; MAX_GENERATORS];
        let mut generator_entries = [[0.0; 6]; MAX_GENERATORS];
        for ((rate, entries), generator) in log_gain_rates
            .iter_mut()
            .zip(generator_entries.iter_mut())
            .zip(self.generators)
        {
            *rate = (inverse * generator).trace() / 3.0;
            *entries = [
                generator[(0, 0)],
                generator[(1, 1)],
                generator[(2, 2)],
                generator[(0, 1)],
                generator[(0, 2)],
                generator[(1, 2)],
            ];
        }
        let n_generators = self.generators.len();
        let a = [
            [soft_iron[(0, 0)], soft_iron[(0, 1)], soft_iron[(0, 2)]],
            [soft_iron[(1, 0)], soft_iron[(1, 1)], soft_iron[(1, 2)]],
            [soft_iron[(2, 0)], soft_iron[(2, 1)], soft_iron[(2, 2)]],
        ];
        let mut row = [0.0; 3 + MAX_GENERATORS];
        let n_params = 3 + n_generators;
        for m_ut in self.samples_ut {
            let d = [
                m_ut.x - hard_iron_ut.x,
                m_ut.y - hard_iron_ut.y,
                m_ut.z - hard_iron_ut.z,
            ];
            let c = [
                a[0][0] * d[0] + a[0][1] * d[1] + a[0][2] * d[2],
                a[1][0] * d[0] + a[1][1] * d[1] + a[1][2] * d[2],
                a[2][0] * d[0] + a[2][1] * d[1] + a[2][2] * d[2],
            ];
            let magnitude_ut = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
            if magnitude_ut.is_nan() || magnitude_ut <= 0.0 {
                return None;
            }
            let u = [
                c[0] / magnitude_ut,
                c[1] / magnitude_ut,
                c[2] / magnitude_ut,
            ];
            let residual_ut = (magnitude_ut - self.radius_ut) * inverse_gain;
            // ∂|A·d|/∂h = −Aᵀ·u, and ∂|A·d|/∂θ_k = uᵀ·G_k·d.
            row[0] = -(a[0][0] * u[0] + a[1][0] * u[1] + a[2][0] * u[2]) * inverse_gain;
            row[1] = -(a[0][1] * u[0] + a[1][1] * u[1] + a[2][1] * u[2]) * inverse_gain;
            row[2] = -(a[0][2] * u[0] + a[1][2] * u[1] + a[2][2] * u[2]) * inverse_gain;
            let q = [
                u[0] * d[0],
                u[1] * d[1],
                u[2] * d[2],
                u[0] * d[1] + u[1] * d[0],
                u[0] * d[2] + u[2] * d[0],
                u[1] * d[2] + u[2] * d[1],
            ];
            for ((entry, g), rate) in row[3..]
                .iter_mut()
                .zip(&generator_entries[..n_generators])
                .zip(&log_gain_rates)
            {
                let along = g[0] * q[0]
                    + g[1] * q[1]
                    + g[2] * q[2]
                    + g[3] * q[3]
                    + g[4] * q[4]
                    + g[5] * q[5];
                *entry = along * inverse_gain - residual_ut * rate;
            }
            visit(residual_ut, row.get(..n_params)?);
        }
        Some(())
    }
}

/// The refinement problem at a calibration, with `R` fixed at its field.
fn problem_at<'a>(
    samples_ut: &'a [Vector3<f64>],
    generators: &'a [Matrix3<f64>],
    calibration: &FieldCalibration,
) -> Option<GeometricProblem<'a>> {
    let hard_iron_ut = calibration.hard_iron_ut;
    let mut params = vec![hard_iron_ut.x, hard_iron_ut.y, hard_iron_ut.z];
    params.extend(coordinates(&calibration.soft_iron, generators)?.iter());
    Some(GeometricProblem {
        samples_ut,
        generators,
        radius_ut: calibration.field_ut,
        params: DVector::from_vec(params),
    })
}

/// The hard iron's predicted 1σ uncertainty (µT, along its worst direction), from the
/// Gauss-Newton covariance `σ²·(JᵀJ)⁻¹` with σ the residual RMS. It reflects noise
/// and geometry only, not model error.
fn hard_iron_std_ut(problem: &GeometricProblem) -> Option<f64> {
    const MAX_PARAMS: usize = 3 + MAX_GENERATORS;
    let n_params = problem.params.len();
    let mut sums = [[0.0; MAX_PARAMS]; MAX_PARAMS];
    let mut sum_squares_ut2 = 0.0;
    problem.for_each_row(|residual_ut, row| {
        sum_squares_ut2 += residual_ut * residual_ut;
        for (sums_row, &row_value) in sums.iter_mut().zip(row) {
            for (sum, &col_value) in sums_row.iter_mut().zip(row) {
                *sum += row_value * col_value;
            }
        }
    })?;
    let normal = DMatrix::from_fn(n_params, n_params, |row, col| sums[row][col]);
    let dof = problem
        .samples_ut
        .len()
        .checked_sub(n_params)
        .filter(|&dof| dof > 0)? as f64;
    let covariance = Cholesky::new(normal)?.inverse() * (sum_squares_ut2 / dof);
    let hard_iron_covariance = Matrix3::from_fn(|row, col| covariance[(row, col)]);
    let worst_ut2 = symmetric_eigen(hard_iron_covariance)?.eigenvalues.max();
    (worst_ut2 >= 0.0 && worst_ut2.is_finite()).then(|| worst_ut2.sqrt())
}

/// Levenberg-Marquardt from `start`, with `R` fixed at its field. `None` when the
/// solver fails, the result is not a plausible ellipsoid, or the solver has drifted
/// along a valley the data hardly constrain: the hard iron there is predicted to be
/// more than [`MAX_REFINE_STD_GROWTH`] times less certain than at the start. On a
/// narrow band the noise-driven cost slopes gently towards flattened, shifted
/// ellipsoids, and the solver follows that slope tens of µT away.
fn refine(
    samples_ut: &[Vector3<f64>],
    model: EllipsoidModel,
    geometry: &Geometry,
    start: &FieldCalibration,
    expected_field_ut: Option<f64>,
) -> Option<FieldCalibration> {
    let generators = generators(model, geometry);
    let problem = problem_at(samples_ut, &generators, start)?;
    let start_std_ut = hard_iron_std_ut(&problem)?;
    let (problem, report) = LevenbergMarquardt::new()
        .with_patience(REFINE_PATIENCE)
        .minimize(problem);
    if report.termination.was_usage_issue() || !report.objective_function.is_finite() {
        return None;
    }
    let end_std_ut = hard_iron_std_ut(&problem)?;
    if end_std_ut > MAX_REFINE_STD_GROWTH * start_std_ut {
        return None;
    }
    let (hard_iron_ut, soft_iron) = (problem.hard_iron_ut(), problem.soft_iron());
    let gain = GeometricProblem::gain(&soft_iron)?;
    let calibration = match expected_field_ut {
        Some(field_ut) => FieldCalibration {
            hard_iron_ut,
            soft_iron: soft_iron * (field_ut / problem.radius_ut),
            field_ut,
        },
        None => FieldCalibration {
            hard_iron_ut,
            soft_iron: soft_iron / gain,
            field_ut: problem.radius_ut / gain,
        },
    };
    plausible(calibration)
}

/// The calibration if it is finite and its axes differ by at most [`MAX_AXIS_RATIO`].
fn plausible(calibration: FieldCalibration) -> Option<FieldCalibration> {
    let finite = calibration.hard_iron_ut.iter().all(|v| v.is_finite())
        && calibration.soft_iron.iter().all(|v| v.is_finite())
        && calibration.field_ut.is_finite();
    (finite && axis_ratio(&calibration.soft_iron) <= MAX_AXIS_RATIO).then_some(calibration)
}

/// `|A·(m − h)|` for every sample, written out on arrays as in
/// [`GeometricProblem::for_each_row`].
fn corrected_magnitudes<'a>(
    samples_ut: &'a [Vector3<f64>],
    calibration: &FieldCalibration,
) -> impl Iterator<Item = f64> + 'a {
    let (h, s) = (calibration.hard_iron_ut, calibration.soft_iron);
    let a = [
        [s[(0, 0)], s[(0, 1)], s[(0, 2)]],
        [s[(1, 0)], s[(1, 1)], s[(1, 2)]],
        [s[(2, 0)], s[(2, 1)], s[(2, 2)]],
    ];
    samples_ut.iter().map(move |m_ut| {
        let d = [m_ut.x - h.x, m_ut.y - h.y, m_ut.z - h.z];
        let c = [
            a[0][0] * d[0] + a[0][1] * d[1] + a[0][2] * d[2],
            a[1][0] * d[0] + a[1][1] * d[1] + a[1][2] * d[2],
            a[2][0] * d[0] + a[2][1] * d[1] + a[2][2] * d[2],
        ];
        (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt()
    })
}

/// Exact residual figures over the samples: RMS of `|c| − R` and the spread of `|c|`.
fn residuals(samples_ut: &[Vector3<f64>], calibration: &FieldCalibration) -> (f64, f64) {
    let (mut sum, mut sum_squares, mut sum_residual_squares) = (0.0, 0.0, 0.0);
    for magnitude_ut in corrected_magnitudes(samples_ut, calibration) {
        sum += magnitude_ut;
        sum_squares += magnitude_ut * magnitude_ut;
        let residual_ut = magnitude_ut - calibration.field_ut;
        sum_residual_squares += residual_ut * residual_ut;
    }
    let n = samples_ut.len().max(1) as f64;
    let mean_ut = sum / n;
    let variance_ut2 = (sum_squares / n - mean_ut * mean_ut).max(0.0);
    (
        (sum_residual_squares / n).sqrt(),
        100.0 * variance_ut2.sqrt() / mean_ut,
    )
}

fn check_residual(
    residual_rms_ut: f64,
    calibration: &FieldCalibration,
) -> Result<(), EllipsoidError> {
    if residual_rms_ut <= MAX_RESIDUAL_FRACTION * calibration.field_ut {
        Ok(())
    } else {
        Err(EllipsoidError::PoorFit {
            residual_rms_ut,
            field_ut: calibration.field_ut,
        })
    }
}

fn check_expected_field(expected_field_ut: Option<f64>) -> Result<Option<f64>, EllipsoidError> {
    match expected_field_ut {
        Some(field_ut) if field_ut.is_nan() || field_ut <= 0.0 || field_ut.is_infinite() => {
            Err(EllipsoidError::InvalidExpectedField { field_ut })
        }
        other => Ok(other),
    }
}

/// The body axis nearest a direction, for messages.
fn nearest_axis_name(direction: &Vector3<f64>) -> &'static str {
    let abs = direction.abs();
    if abs.x >= abs.y && abs.x >= abs.z {
        "x"
    } else if abs.y >= abs.z {
        "y"
    } else {
        "z"
    }
}

/// Whether a narrow band of data should fall back to the band model: when the band
/// model fits as well as the full one, the data cannot tell the scale along the
/// band's axis from the hard iron along it. Rings give no excess at all (the full fit
/// there is often worse, its refinement rejected as drifting); caps of the sphere,
/// which look narrow to the tilt span but do see that scale, give 0.2-0.7 of the
/// noise where the band model would cost degrees of heading.
fn prefers_band(geometry: &Geometry, band_rms_ut: f64, full_rms_ut: f64) -> bool {
    let excess_ut = (band_rms_ut.powi(2) - full_rms_ut.powi(2)).max(0.0).sqrt();
    geometry.tilt_span_deg < MIN_FULL_TILT_SPAN_DEG
        && excess_ut <= BAND_EXCESS_OF_NOISE * full_rms_ut
}

/// The sentence that says why a fit fell back to the band model.
fn band_fallback_sentence(geometry: &Geometry) -> String {
    format!(
        "the data span only ±{:.0}° of tilt about the body {} axis (a full or diagonal \
         fit needs ±{:.0}°), so the scale along that axis cannot be told from the hard \
         iron along it; fell back to the band model (that scale tied to the other two), \
         whose hard iron along that axis is a guess from the band's curvature. Tilt the \
         device through more orientations for a full fit.",
        geometry.tilt_span_deg,
        nearest_axis_name(&geometry.principal_axes.column(2).into_owned()),
        MIN_FULL_TILT_SPAN_DEG,
    )
}

/// One model's fit: algebraic, then refined when asked and when the refinement holds.
struct Candidate {
    model: EllipsoidModel,
    calibration: FieldCalibration,
    refined: bool,
    rms_ut: f64,
}

fn fit_candidate(
    geometry: &Geometry,
    model: EllipsoidModel,
    samples_ut: &[Vector3<f64>],
    options: &EllipsoidOptions,
) -> Result<Candidate, EllipsoidError> {
    let algebraic = geometry.algebraic_fit(model, options.expected_field_ut)?;
    let refined = if options.refine {
        refine(
            samples_ut,
            model,
            geometry,
            &algebraic,
            options.expected_field_ut,
        )
    } else {
        None
    };
    let (calibration, refined) = match refined {
        Some(refined) => (refined, true),
        None => (algebraic, false),
    };
    let (rms_ut, _) = residuals(samples_ut, &calibration);
    Ok(Candidate {
        model,
        calibration,
        refined,
        rms_ut,
    })
}

/// Fits a 3D calibration to magnetometer samples (µT, body frame).
///
/// The steps are in the module header. The model is chosen in two stages:
///
/// - **Observability.** Data within ±4° of a plane, on a line or at one point are
///   refused. If the samples form a band narrower than ±[`MIN_FULL_TILT_SPAN_DEG`]
///   (walking or driving: every heading, little tilt) and the band model fits them as
///   well as the full one (its RMS residual exceeds the full model's by under 0.5 %),
///   the full, diagonal and auto models become the band model, and `fallback` says
///   so.
/// - **Auto.** Among sphere, diagonal and full, the simplest whose RMS residual is
///   close to the full model's: a simpler model is kept when the systematic part it
///   misses, `√(rms² − rms_full²)`, is under 0.3 of `rms_full` (the RMS grows by under
///   5 %, which is indistinguishable from noise) or under 0.1 % of the field (a scale
///   error worth under 0.06° of heading). MATLAB's `magcal` picks "the best fit"
///   without saying how; this rule prefers fewer parameters unless the data show they
///   are needed.
pub fn fit_ellipsoid(
    mag_ut: &[Vector3<f64>],
    options: &EllipsoidOptions,
) -> Result<EllipsoidFit, EllipsoidError> {
    check_expected_field(options.expected_field_ut)?;
    let mut accumulator = EllipsoidAccumulator::new();
    accumulator.add_all(mag_ut);
    let geometry = accumulator.geometry()?;
    let strided: Vec<Vector3<f64>>;
    let refine_set: &[Vector3<f64>] = if mag_ut.len() > MAX_REFINE_SAMPLES {
        let stride = mag_ut.len().div_ceil(MAX_REFINE_SAMPLES);
        strided = mag_ut.iter().step_by(stride).copied().collect();
        &strided
    } else {
        mag_ut
    };
    let fit = |model| fit_candidate(&geometry, model, refine_set, options);
    let may_fall_back = matches!(
        options.model,
        EllipsoidModel::Full | EllipsoidModel::Diagonal | EllipsoidModel::Auto
    );
    let mut full = None;
    if may_fall_back && geometry.tilt_span_deg < MIN_FULL_TILT_SPAN_DEG {
        let (band, full_fit) = (fit(EllipsoidModel::Band), fit(EllipsoidModel::Full));
        let fall_back = match (&band, &full_fit) {
            (Ok(band), Ok(full)) => prefers_band(&geometry, band.rms_ut, full.rms_ut),
            (Ok(_), Err(_)) => true,
            _ => false,
        };
        if let (true, Ok(band)) = (fall_back, band) {
            let sentence = band_fallback_sentence(&geometry);
            return finish(&geometry, mag_ut.len(), refine_set, band, Some(sentence));
        }
        full = full_fit.ok();
    }
    let candidates: &[EllipsoidModel] = match options.model {
        EllipsoidModel::Auto => &[
            EllipsoidModel::Full,
            EllipsoidModel::Diagonal,
            EllipsoidModel::Sphere,
        ],
        EllipsoidModel::Full => &[EllipsoidModel::Full],
        EllipsoidModel::Diagonal => &[EllipsoidModel::Diagonal],
        EllipsoidModel::Sphere => &[EllipsoidModel::Sphere],
        EllipsoidModel::Band => &[EllipsoidModel::Band],
    };
    let mut fitted: Vec<Candidate> = Vec::new();
    let mut first_error = None;
    for &model in candidates {
        let candidate = match (model, full.take()) {
            (EllipsoidModel::Full, Some(full)) => Ok(full),
            _ => fit(model),
        };
        match candidate {
            Ok(candidate) => fitted.push(candidate),
            Err(error) => {
                first_error.get_or_insert(error);
            }
        }
    }
    // The candidates run from most to fewest parameters: take the last that passes.
    let Some(full_rms_ut) = fitted.first().map(|candidate| candidate.rms_ut) else {
        return Err(first_error.unwrap_or(EllipsoidError::NotAnEllipsoid {
            model: options.model,
            max_axis_ratio: MAX_AXIS_RATIO,
        }));
    };
    let simplest_idx = fitted
        .iter()
        .rposition(|candidate| {
            let excess_ut = (candidate.rms_ut.powi(2) - full_rms_ut.powi(2))
                .max(0.0)
                .sqrt();
            excess_ut <= AUTO_EXCESS_OF_NOISE * full_rms_ut
                || excess_ut <= AUTO_EXCESS_OF_FIELD * candidate.calibration.field_ut
        })
        .unwrap_or(0);
    let chosen = fitted.swap_remove(simplest_idx);
    finish(&geometry, mag_ut.len(), refine_set, chosen, None)
}

/// The result of the chosen candidate, with its figures.
fn finish(
    geometry: &Geometry,
    n_samples: usize,
    refine_set: &[Vector3<f64>],
    chosen: Candidate,
    fallback: Option<String>,
) -> Result<EllipsoidFit, EllipsoidError> {
    // Over the evenly spaced subset when there is one: the figures' own noise there
    // is under 1 %, and a pass over millions of samples would double the time.
    let (residual_rms_ut, field_spread_pct) = residuals(refine_set, &chosen.calibration);
    check_residual(residual_rms_ut, &chosen.calibration)?;
    let generators = generators(chosen.model, geometry);
    let hard_iron_std_ut = problem_at(refine_set, &generators, &chosen.calibration)
        .and_then(|problem| hard_iron_std_ut(&problem));
    Ok(EllipsoidFit {
        observability: Observability {
            hard_iron_std_ut,
            ..geometry.observability(&chosen.calibration)
        },
        calibration: chosen.calibration,
        model: chosen.model,
        residual_rms_ut,
        field_spread_pct,
        n_samples,
        refined: chosen.refined,
        fallback,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::angle::heading_difference_rad;
    use crate::calib::heading::heading_rad;
    use crate::calib::tilt::Tilt;
    use crate::sim::field::{circle_only, full_sphere, FieldSample, FieldTruth};
    use crate::sim::rng::SplitMix64;

    /// The issue's distortions: hard iron up to 60 µT, soft iron 1 ± 0.1 on the
    /// diagonal and up to 0.1 off it, 0.3 µT of noise, a 50 µT field.
    fn random_truth(seed: u64, inclination_deg: f64) -> (FieldTruth, SplitMix64) {
        let mut rng = SplitMix64::new(seed);
        let truth = FieldTruth {
            inclination_deg,
            ..FieldTruth::random(&mut rng, 60.0, 0.1, 0.1)
        };
        (truth, rng)
    }

    fn mags(samples: &[FieldSample]) -> Vec<Vector3<f64>> {
        samples.iter().map(|sample| sample.mag_ut).collect()
    }

    /// ‖A − S⁻¹‖_F / ‖S⁻¹‖_F, with `A` scaled to the truth's corrected radius first.
    fn soft_iron_error(calibration: &FieldCalibration, truth: &FieldTruth) -> f64 {
        let ideal = truth.ideal_correction();
        let scaled = calibration.soft_iron * (truth.field_total_ut / calibration.field_ut);
        (scaled - ideal).norm() / ideal.norm()
    }

    /// RMS of the heading error after levelling the corrected field with the true tilt.
    fn heading_rms_deg(samples: &[FieldSample], calibration: &FieldCalibration) -> f64 {
        let sum_squares: f64 = samples
            .iter()
            .map(|sample| {
                let tilt = Tilt {
                    roll_rad: sample.roll_rad,
                    pitch_rad: sample.pitch_rad,
                };
                let level_ut = tilt.level(calibration.apply(sample.mag_ut));
                heading_difference_rad(heading_rad(level_ut, 0.0), sample.heading_rad).powi(2)
            })
            .sum();
        (sum_squares / samples.len() as f64).sqrt().to_degrees()
    }

    /// A model's fit without the observability fallback: what a plain 3D fit gives.
    fn forced_fit(mag_ut: &[Vector3<f64>], model: EllipsoidModel) -> FieldCalibration {
        let mut accumulator = EllipsoidAccumulator::new();
        accumulator.add_all(mag_ut);
        let geometry = accumulator.geometry().expect("geometry");
        let algebraic = geometry.algebraic_fit(model, None).expect("algebraic fit");
        refine(mag_ut, model, &geometry, &algebraic, None).unwrap_or(algebraic)
    }

    #[test]
    fn monomials_follow_the_exponent_table() {
        let d = Vector3::new(1.3, -0.7, 2.1);
        for (term, [a, b, c]) in monomials(d).iter().zip(EXPONENTS) {
            let expect = d.x.powi(a as i32) * d.y.powi(b as i32) * d.z.powi(c as i32);
            assert!((term - expect).abs() < 1e-12, "{a} {b} {c}");
        }
        for (moment_idx, [a, b, c]) in EXPONENTS.iter().enumerate() {
            assert_eq!(MOMENT_INDEX[*a][*b][*c], moment_idx);
        }
    }

    #[test]
    fn chunked_sums_equal_per_sample_sums() {
        let samples: Vec<Vector3<f64>> = (0..1000)
            .map(|idx| {
                let t = idx as f64 * 0.37;
                Vector3::new(
                    30.0 * t.cos() + 5.0,
                    -20.0 * t.sin(),
                    10.0 * (0.3 * t).sin() - 40.0,
                )
            })
            .collect();
        let (mut one_by_one, mut chunked) =
            (EllipsoidAccumulator::new(), EllipsoidAccumulator::new());
        for &m_ut in &samples {
            one_by_one.add(m_ut);
        }
        chunked.add_all(&samples);
        assert_eq!(one_by_one.n_samples(), chunked.n_samples());
        for (a, b) in one_by_one.moments.iter().zip(chunked.moments) {
            assert!((a - b).abs() <= 1e-9 * a.abs().max(1.0), "{a} {b}");
        }
    }

    #[test]
    fn the_sums_of_offsets_agree_on_every_path() {
        // On x86-64 `offset_sums` is the SSE2 code: it must give the scalar sums, for
        // odd and even lengths.
        for n_offsets in [1, 2, 3, 100, 255, CHUNK_LEN] {
            let offsets: Vec<[f64; 3]> = (0..n_offsets)
                .map(|idx| {
                    let t = idx as f64 * 0.61;
                    [
                        25.0 * t.cos() - 3.0,
                        18.0 * t.sin() + 2.0,
                        30.0 * (0.2 * t).cos(),
                    ]
                })
                .collect();
            let mut expect = [0.0; N_MOMENTS];
            for &[x, y, z] in &offsets {
                for (sum, term) in expect.iter_mut().zip(monomials(Vector3::new(x, y, z))) {
                    *sum += term;
                }
            }
            for sums in [offset_sums(&offsets), scalar_offset_sums(&offsets)] {
                for (got, want) in sums.iter().zip(expect) {
                    assert!(
                        (got - want).abs() <= 1e-12 * want.abs().max(1.0),
                        "{n_offsets}: {got} {want}"
                    );
                }
            }
        }
    }

    #[test]
    fn moving_the_origin_is_exact() {
        let samples = [
            Vector3::new(1.0, 2.0, 3.0),
            Vector3::new(-4.0, 0.5, 2.0),
            Vector3::new(0.3, -1.0, -2.5),
        ];
        let shift = Vector3::new(0.7, -1.3, 2.2);
        let sums = |offset: Vector3<f64>, scale: f64| {
            let mut sums = [0.0; N_MOMENTS];
            for &m in &samples {
                for (sum, term) in sums.iter_mut().zip(monomials((m + offset) / scale)) {
                    *sum += term;
                }
            }
            sums
        };
        let moved = shift_and_scale(&sums(Vector3::zeros(), 1.0), shift, 2.5);
        for (a, b) in moved.iter().zip(sums(shift, 2.5)) {
            assert!((a - b).abs() < 1e-12 * b.abs().max(1.0), "{a} {b}");
        }
    }

    #[test]
    fn the_jacobian_matches_numerical_derivatives() {
        let (truth, mut rng) = random_truth(5, 60.0);
        let samples = mags(&full_sphere(&truth, 50, &mut rng));
        let mut accumulator = EllipsoidAccumulator::new();
        accumulator.add_all(&samples);
        let geometry = accumulator.geometry().expect("geometry");
        for model in [
            EllipsoidModel::Sphere,
            EllipsoidModel::Diagonal,
            EllipsoidModel::Full,
            EllipsoidModel::Band,
        ] {
            let generators = generators(model, &geometry);
            let start = geometry.algebraic_fit(model, None).expect("fit");
            // Away from the optimum, so that the residual terms of the derivative count.
            let perturbed = FieldCalibration {
                hard_iron_ut: start.hard_iron_ut + Vector3::new(1.0, -2.0, 0.5),
                field_ut: start.field_ut * 1.1,
                ..start
            };
            let mut problem = problem_at(&samples, &generators, &perturbed).expect("problem");
            let analytic = problem.jacobian().expect("jacobian");
            let numeric = levenberg_marquardt::differentiate_numerically(&mut problem)
                .expect("numerical jacobian");
            let error = (&analytic - &numeric).amax() / numeric.amax();
            assert!(error < 1e-6, "{model:?}: relative error {error}");
        }
    }

    #[test]
    fn full_sphere_data_recover_random_distortions() {
        // Acceptance test of the issue. Over 3000 samples the noise leaves about
        // 0.3·√(3/3000) ≈ 0.01 µT of hard-iron error per axis, well inside 0.1 µT; 300
        // samples (0.03 µT per axis) would still pass, 30 would not.
        let n_seeds = 100;
        let (mut worst_hard_iron_ut, mut worst_soft_iron, mut worst_rms_ut) =
            (0.0f64, 0.0f64, 0.0f64);
        for seed in 0..n_seeds {
            let (truth, mut rng) = random_truth(seed, 60.0);
            let samples = mags(&full_sphere(&truth, 3000, &mut rng));
            let fit = fit_ellipsoid(&samples, &EllipsoidOptions::default()).expect("fits");
            let hard_iron_error_ut = (fit.calibration.hard_iron_ut - truth.hard_iron_ut).norm();
            let soft_iron_error = soft_iron_error(&fit.calibration, &truth);
            assert!(
                hard_iron_error_ut < 0.1,
                "seed {seed}: hard iron off by {hard_iron_error_ut} µT"
            );
            assert!(
                soft_iron_error < 0.005,
                "seed {seed}: soft iron off by {soft_iron_error}"
            );
            assert_eq!(fit.model, EllipsoidModel::Full, "seed {seed}");
            assert_eq!(fit.fallback, None, "seed {seed}");
            assert!(fit.refined, "seed {seed}");
            assert!(
                fit.observability.tilt_span_deg > 35.0,
                "{:?}",
                fit.observability
            );
            worst_hard_iron_ut = worst_hard_iron_ut.max(hard_iron_error_ut);
            worst_soft_iron = worst_soft_iron.max(soft_iron_error);
            worst_rms_ut = worst_rms_ut.max(fit.residual_rms_ut);
        }
        // The residual is the noise along the radius (0.3 µT), no more.
        assert!(worst_rms_ut < 0.33, "{worst_rms_ut}");
        println!(
            "full sphere, {n_seeds} seeds, 3000 samples: worst hard-iron error \
             {worst_hard_iron_ut:.4} µT, worst soft-iron error {:.3} %, worst RMS \
             {worst_rms_ut:.3} µT",
            100.0 * worst_soft_iron
        );
    }

    #[test]
    fn full_sphere_accuracy_by_sample_count() {
        for (n_samples, max_hard_iron_ut) in [(300, 0.15), (1000, 0.1), (10_000, 0.03)] {
            let mut worst_ut = 0.0f64;
            for seed in 0..30 {
                let (truth, mut rng) = random_truth(1000 + seed, 60.0);
                let samples = mags(&full_sphere(&truth, n_samples, &mut rng));
                let fit = fit_ellipsoid(&samples, &EllipsoidOptions::default()).expect("fits");
                worst_ut = worst_ut.max((fit.calibration.hard_iron_ut - truth.hard_iron_ut).norm());
            }
            println!("full sphere, {n_samples} samples: worst hard-iron error {worst_ut:.4} µT");
            assert!(worst_ut < max_hard_iron_ut, "{n_samples}: {worst_ut}");
        }
    }

    #[test]
    fn the_expected_field_sets_the_corrected_magnitude() {
        for seed in 0..20 {
            let (truth, mut rng) = random_truth(200 + seed, 60.0);
            let samples = mags(&full_sphere(&truth, 3000, &mut rng));
            let options = EllipsoidOptions {
                expected_field_ut: Some(truth.field_total_ut),
                ..EllipsoidOptions::default()
            };
            let fit = fit_ellipsoid(&samples, &options).expect("fits");
            assert_eq!(fit.calibration.field_ut, truth.field_total_ut);
            // No rescaling needed: A is the truth's S⁻¹ itself.
            let error = (fit.calibration.soft_iron - truth.ideal_correction()).norm()
                / truth.ideal_correction().norm();
            assert!(error < 0.005, "seed {seed}: {error}");
            assert!((fit.calibration.hard_iron_ut - truth.hard_iron_ut).norm() < 0.1);
        }
    }

    #[test]
    fn noise_free_data_are_fitted_exactly() {
        let (truth, mut rng) = random_truth(9, 60.0);
        let truth = FieldTruth {
            noise_ut: 0.0,
            ..truth
        };
        let samples = mags(&full_sphere(&truth, 500, &mut rng));
        for refine in [false, true] {
            let options = EllipsoidOptions {
                refine,
                ..EllipsoidOptions::default()
            };
            let fit = fit_ellipsoid(&samples, &options).expect("fits");
            assert!((fit.calibration.hard_iron_ut - truth.hard_iron_ut).norm() < 1e-6);
            assert!(soft_iron_error(&fit.calibration, &truth) < 1e-8);
            assert!(fit.residual_rms_ut < 1e-6, "{}", fit.residual_rms_ut);
        }
    }

    #[test]
    fn a_hard_iron_far_larger_than_the_field_is_well_conditioned() {
        // Raw counts of some sensors, or a magnet glued next to the sensor.
        let (truth, mut rng) = random_truth(11, 60.0);
        let truth = FieldTruth {
            hard_iron_ut: Vector3::new(5000.0, -3000.0, 8000.0),
            ..truth
        };
        let samples = mags(&full_sphere(&truth, 3000, &mut rng));
        let fit = fit_ellipsoid(&samples, &EllipsoidOptions::default()).expect("fits");
        assert!((fit.calibration.hard_iron_ut - truth.hard_iron_ut).norm() < 0.1);
        assert!(soft_iron_error(&fit.calibration, &truth) < 0.005);
    }

    #[test]
    fn auto_prefers_the_simplest_model_the_data_support() {
        let cases = [
            (Matrix3::identity(), EllipsoidModel::Sphere),
            (
                Matrix3::from_diagonal(&Vector3::new(1.08, 0.93, 1.0)),
                EllipsoidModel::Diagonal,
            ),
            (
                Matrix3::new(1.05, 0.06, -0.04, 0.06, 0.95, 0.03, -0.04, 0.03, 1.0),
                EllipsoidModel::Full,
            ),
        ];
        for (soft_iron, expect) in cases {
            let (truth, mut rng) = random_truth(21, 60.0);
            let truth = FieldTruth { soft_iron, ..truth };
            let samples = mags(&full_sphere(&truth, 3000, &mut rng));
            let fit = fit_ellipsoid(&samples, &EllipsoidOptions::default()).expect("fits");
            assert_eq!(fit.model, expect, "{soft_iron}");
            assert!((fit.calibration.hard_iron_ut - truth.hard_iron_ut).norm() < 0.1);
        }
    }

    #[test]
    fn each_model_can_be_asked_for() {
        let (truth, mut rng) = random_truth(23, 60.0);
        let samples = mags(&full_sphere(&truth, 2000, &mut rng));
        for model in [
            EllipsoidModel::Sphere,
            EllipsoidModel::Diagonal,
            EllipsoidModel::Full,
            EllipsoidModel::Band,
        ] {
            let options = EllipsoidOptions {
                model,
                ..EllipsoidOptions::default()
            };
            let fit = fit_ellipsoid(&samples, &options).expect("fits");
            assert_eq!(fit.model, model);
            let soft_iron = fit.calibration.soft_iron;
            assert!((soft_iron - soft_iron.transpose()).amax() < 1e-12);
            match model {
                EllipsoidModel::Sphere => {
                    assert!(
                        (soft_iron - Matrix3::identity()).amax() < 1e-9,
                        "{soft_iron}"
                    )
                }
                EllipsoidModel::Diagonal => {
                    assert!(
                        (soft_iron - Matrix3::from_diagonal(&soft_iron.diagonal())).amax() == 0.0
                    )
                }
                _ => {}
            }
            // det A = 1 without an expected field.
            assert!((soft_iron.determinant() - 1.0).abs() < 1e-9, "{model:?}");
        }
    }

    #[test]
    fn circle_only_data_fall_back_and_keep_the_horizontal_hard_iron() {
        // Acceptance test of the issue: every heading, roll and pitch within ±10°,
        // inclination 65°. A plain 3D fit leaves the scale along z free against the
        // hard iron along z; the fallback ties it and says so.
        let n_seeds = 50;
        let (mut worst_horizontal_ut, mut worst_heading_deg, mut mean_heading_deg) =
            (0.0f64, 0.0f64, 0.0);
        let (mut worst_full_heading_deg, mut mean_full_heading_deg, mut worst_full_hard_iron_ut) =
            (0.0f64, 0.0, 0.0f64);
        let mut worst_vertical_ut = 0.0f64;
        for seed in 0..n_seeds {
            let (truth, mut rng) = random_truth(300 + seed, 65.0);
            let samples = circle_only(&truth, 3000, 10.0, &mut rng);
            let mag_ut = mags(&samples);
            let fit = fit_ellipsoid(&mag_ut, &EllipsoidOptions::default()).expect("fits");
            assert_eq!(fit.model, EllipsoidModel::Band, "seed {seed}");
            let fallback = fit.fallback.as_deref().unwrap_or_default();
            assert!(
                fallback.contains("about the body z axis") && fallback.contains("fell back"),
                "{fallback}"
            );
            let tilt_span_deg = fit.observability.tilt_span_deg;
            assert!(
                (6.0..15.0).contains(&tilt_span_deg),
                "seed {seed}: {tilt_span_deg}"
            );
            let error_ut = fit.calibration.hard_iron_ut - truth.hard_iron_ut;
            let heading_deg = heading_rms_deg(&samples, &fit.calibration);
            assert!(error_ut.xy().norm() < 6.0, "seed {seed}: {error_ut:?}");
            assert!(heading_deg < 5.0, "seed {seed}: {heading_deg}°");
            worst_horizontal_ut = worst_horizontal_ut.max(error_ut.xy().norm());
            worst_vertical_ut = worst_vertical_ut.max(error_ut.z.abs());
            worst_heading_deg = worst_heading_deg.max(heading_deg);
            mean_heading_deg += heading_deg / n_seeds as f64;

            let full = forced_fit(&mag_ut, EllipsoidModel::Full);
            let full_heading_deg = heading_rms_deg(&samples, &full);
            worst_full_heading_deg = worst_full_heading_deg.max(full_heading_deg);
            mean_full_heading_deg += full_heading_deg / n_seeds as f64;
            worst_full_hard_iron_ut =
                worst_full_hard_iron_ut.max((full.hard_iron_ut - truth.hard_iron_ut).norm());
        }
        println!(
            "circle only ±10°, {n_seeds} seeds, 3000 samples: band fallback heading RMS mean \
             {mean_heading_deg:.2}°, worst {worst_heading_deg:.2}°; hard-iron error worst \
             {worst_horizontal_ut:.2} µT horizontal, {worst_vertical_ut:.1} µT vertical. Full \
             3D fit without fallback: heading RMS mean {mean_full_heading_deg:.2}°, worst \
             {worst_full_heading_deg:.2}°, hard-iron error worst {worst_full_hard_iron_ut:.1} µT"
        );
    }

    #[test]
    fn caps_of_the_sphere_do_not_blow_up() {
        // A device never turned upside down (a hemisphere of field directions), and one
        // kept within about 60° of one attitude.
        // The cap is a hard case: it looks narrow to the tilt span, and either model
        // leaves degrees of heading error on some distortions; the fit chooses per
        // distortion (see `prefers_band`) and stays within 3.2° RMS.
        for (label, min_cos, max_hard_iron_ut, max_heading_deg) in [
            ("hemisphere", 0.0, 0.3, 1.0),
            ("cap of ±60°", 0.5, 8.0, 4.0),
        ] {
            let (mut worst_ut, mut worst_soft_iron, mut worst_heading_deg) =
                (0.0f64, 0.0f64, 0.0f64);
            let mut models = Vec::new();
            for seed in 0..20 {
                let (truth, mut rng) = random_truth(400 + seed, 60.0);
                let samples: Vec<FieldSample> = full_sphere(&truth, 6000, &mut rng)
                    .into_iter()
                    .filter(|sample| {
                        let offset_ut =
                            truth.ideal_correction() * (sample.mag_ut - truth.hard_iron_ut);
                        offset_ut.z / offset_ut.norm() >= min_cos
                    })
                    .collect();
                let fit =
                    fit_ellipsoid(&mags(&samples), &EllipsoidOptions::default()).expect("fits");
                worst_ut = worst_ut.max((fit.calibration.hard_iron_ut - truth.hard_iron_ut).norm());
                worst_soft_iron = worst_soft_iron.max(soft_iron_error(&fit.calibration, &truth));
                worst_heading_deg =
                    worst_heading_deg.max(heading_rms_deg(&samples, &fit.calibration));
                models.push(fit.model);
            }
            println!(
                "{label}: models {models:?}; worst hard-iron error {worst_ut:.2} µT, soft iron \
                 {:.2} %, heading RMS {worst_heading_deg:.2}°",
                100.0 * worst_soft_iron
            );
            assert!(
                worst_ut < max_hard_iron_ut && worst_heading_deg < max_heading_deg,
                "{label}"
            );
        }
    }

    #[test]
    fn a_sphere_asked_for_on_circle_only_data_is_kept() {
        let (truth, mut rng) = random_truth(40, 65.0);
        let samples = mags(&circle_only(&truth, 2000, 10.0, &mut rng));
        let options = EllipsoidOptions {
            model: EllipsoidModel::Sphere,
            ..EllipsoidOptions::default()
        };
        let fit = fit_ellipsoid(&samples, &options).expect("fits");
        assert_eq!((fit.model, fit.fallback), (EllipsoidModel::Sphere, None));
    }

    #[test]
    fn degenerate_inputs_are_errors_not_panics() {
        let options = EllipsoidOptions::default();
        let point = vec![Vector3::new(20.0, -5.0, 40.0); 100];
        assert!(matches!(
            fit_ellipsoid(&point, &options),
            Err(EllipsoidError::NoRotation { .. })
        ));
        let line: Vec<Vector3<f64>> = (0..100)
            .map(|idx| {
                Vector3::new(1.0, 2.0, -1.0) * (idx as f64 - 50.0) + Vector3::new(3.0, 0.0, 9.0)
            })
            .collect();
        assert!(matches!(
            fit_ellipsoid(&line, &options),
            Err(EllipsoidError::Line { .. })
        ));
        // A ring in a tilted plane: a turn about one axis and nothing else.
        let (e1, e2) = (
            Vector3::new(1.0, 1.0, 0.0).normalize(),
            Vector3::new(0.0, 0.3, 1.0).normalize(),
        );
        let plane: Vec<Vector3<f64>> = (0..360)
            .map(|idx| {
                let angle = (idx as f64).to_radians();
                Vector3::new(10.0, 20.0, -30.0) + (e1 * angle.cos() + e2 * angle.sin()) * 25.0
            })
            .collect();
        assert!(matches!(
            fit_ellipsoid(&plane, &options),
            Err(EllipsoidError::Plane { .. })
        ));
        let (truth, mut rng) = random_truth(50, 60.0);
        let good = mags(&full_sphere(&truth, 100, &mut rng));
        for bad_value in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let mut with_bad = good.clone();
            with_bad[7].y = bad_value;
            assert_eq!(
                fit_ellipsoid(&with_bad, &options).map(|fit| fit.model),
                Err(EllipsoidError::NonFinite { sample_idx: 7 })
            );
        }
        let mut with_huge = good.clone();
        with_huge[40].z = 1e200;
        assert!(matches!(
            fit_ellipsoid(&with_huge, &options),
            Err(EllipsoidError::OutOfRange { sample_idx: 40, .. })
        ));
        let huge: Vec<Vector3<f64>> = good.iter().map(|&m_ut| m_ut * 1e150).collect();
        assert!(matches!(
            fit_ellipsoid(&huge, &options),
            Err(EllipsoidError::OutOfRange { sample_idx: 0, .. })
        ));
        assert_eq!(
            fit_ellipsoid(&good[..5], &options).map(|fit| fit.model),
            Err(EllipsoidError::TooFewSamples {
                n_samples: 5,
                min: MIN_SAMPLES
            })
        );
        assert!(matches!(
            fit_ellipsoid(&[], &options),
            Err(EllipsoidError::TooFewSamples { n_samples: 0, .. })
        ));
        for field_ut in [0.0, -50.0, f64::NAN, f64::INFINITY] {
            let options = EllipsoidOptions {
                expected_field_ut: Some(field_ut),
                ..EllipsoidOptions::default()
            };
            assert!(matches!(
                fit_ellipsoid(&good, &options),
                Err(EllipsoidError::InvalidExpectedField { .. })
            ));
        }
        // A hyperboloid is no ellipsoid.
        let hyperboloid: Vec<Vector3<f64>> = (0..400)
            .map(|idx| {
                let (angle, height) = (
                    (idx as f64 * 17.0).to_radians(),
                    (idx % 20) as f64 * 3.0 - 30.0,
                );
                let radius = (400.0 + height * height).sqrt();
                Vector3::new(radius * angle.cos(), radius * angle.sin(), height)
            })
            .collect();
        let result = fit_ellipsoid(&hyperboloid, &options);
        assert!(
            matches!(
                result,
                Err(EllipsoidError::NotAnEllipsoid { .. } | EllipsoidError::PoorFit { .. })
            ),
            "{result:?}"
        );
        // The messages are sentences that say what to do.
        let message = EllipsoidError::Plane { tilt_span_deg: 1.2 }.to_string();
        assert!(
            message.contains("±1.2°") && message.contains("tilting"),
            "{message}"
        );
    }

    #[test]
    fn random_clouds_never_panic() {
        let mut rng = SplitMix64::new(77);
        for n_samples in [10, 11, 12, 15, 20, 50, 200] {
            for _ in 0..50 {
                let cloud: Vec<Vector3<f64>> = (0..n_samples)
                    .map(|_| {
                        Vector3::new(
                            rng.uniform_in(-60.0, 60.0),
                            rng.uniform_in(-60.0, 60.0),
                            rng.uniform_in(-60.0, 60.0),
                        )
                    })
                    .collect();
                for model in [EllipsoidModel::Auto, EllipsoidModel::Band] {
                    let options = EllipsoidOptions {
                        model,
                        ..EllipsoidOptions::default()
                    };
                    if let Ok(fit) = fit_ellipsoid(&cloud, &options) {
                        assert!(fit.calibration.soft_iron.iter().all(|v| v.is_finite()));
                        assert!(fit.calibration.hard_iron_ut.iter().all(|v| v.is_finite()));
                        assert!(fit.observability.axis_ratio <= MAX_AXIS_RATIO);
                    }
                }
            }
        }
    }

    #[test]
    fn order_and_chunking_do_not_change_the_streaming_fit() {
        let (truth, mut rng) = random_truth(60, 60.0);
        let samples = mags(&full_sphere(&truth, 2000, &mut rng));
        let mut one_pass = EllipsoidAccumulator::new();
        for &m_ut in &samples {
            one_pass.add(m_ut);
        }
        let reference = one_pass.solve(EllipsoidModel::Full, None).expect("solves");
        let check = |accumulator: &EllipsoidAccumulator, label: &str| {
            let fit = accumulator
                .solve(EllipsoidModel::Full, None)
                .expect("solves");
            assert_eq!(fit.n_samples, samples.len(), "{label}");
            let hard_iron_ut =
                (fit.calibration.hard_iron_ut - reference.calibration.hard_iron_ut).norm();
            let soft_iron = (fit.calibration.soft_iron - reference.calibration.soft_iron).amax();
            let field_ut = (fit.calibration.field_ut - reference.calibration.field_ut).abs();
            assert!(
                hard_iron_ut < 1e-9 && soft_iron < 1e-11 && field_ut < 1e-9,
                "{label}: {hard_iron_ut} {soft_iron} {field_ut}"
            );
        };
        let mut reversed = EllipsoidAccumulator::new();
        samples.iter().rev().for_each(|&m_ut| reversed.add(m_ut));
        check(&reversed, "reversed");
        let mut slice = EllipsoidAccumulator::new();
        slice.add_all(&samples);
        check(&slice, "add_all");
        let (first_half, second_half) = samples.split_at(samples.len() / 2);
        let (mut first, mut second) = (EllipsoidAccumulator::new(), EllipsoidAccumulator::new());
        first.add_all(first_half);
        second.add_all(second_half);
        let mut merged = first.clone();
        merged.merge(&second);
        check(&merged, "merge of two halves");
        let mut merged_the_other_way = second.clone();
        merged_the_other_way.merge(&first);
        check(&merged_the_other_way, "halves merged in the other order");
        for chunk_len in [1, 7, 256, 999] {
            let mut total = EllipsoidAccumulator::new();
            total.merge(&EllipsoidAccumulator::new());
            for chunk in samples.chunks(chunk_len) {
                let mut part = EllipsoidAccumulator::new();
                part.add_all(chunk);
                total.merge(&part);
                total.merge(&EllipsoidAccumulator::new());
            }
            check(&total, &format!("chunks of {chunk_len}"));
        }
        // A non-finite sample keeps its place in the merged order.
        let mut with_nan = EllipsoidAccumulator::new();
        with_nan.add_all(&samples[..5]);
        with_nan.add(Vector3::new(f64::NAN, 0.0, 0.0));
        let mut merged = first.clone();
        merged.merge(&with_nan);
        assert_eq!(
            merged
                .solve(EllipsoidModel::Full, None)
                .map(|fit| fit.n_samples),
            Err(EllipsoidError::NonFinite {
                sample_idx: first_half.len() + 5
            })
        );
    }

    #[test]
    fn the_streaming_solve_is_the_algebraic_fit() {
        let (truth, mut rng) = random_truth(70, 60.0);
        let samples = mags(&full_sphere(&truth, 3000, &mut rng));
        let mut accumulator = EllipsoidAccumulator::new();
        accumulator.add_all(&samples);
        let streamed = accumulator
            .solve(EllipsoidModel::Auto, None)
            .expect("solves");
        let options = EllipsoidOptions {
            model: EllipsoidModel::Full,
            refine: false,
            ..EllipsoidOptions::default()
        };
        let sliced = fit_ellipsoid(&samples, &options).expect("fits");
        assert_eq!(streamed.model, EllipsoidModel::Full);
        assert_eq!(streamed.calibration, sliced.calibration);
        assert!(!sliced.refined && !streamed.refined);
        // The first-order residual figures from the power sums are close to the exact ones.
        let relative =
            (streamed.residual_rms_ut - sliced.residual_rms_ut).abs() / sliced.residual_rms_ut;
        assert!(
            relative < 0.02,
            "{} vs {}",
            streamed.residual_rms_ut,
            sliced.residual_rms_ut
        );
        assert!(
            (streamed.field_spread_pct - sliced.field_spread_pct).abs()
                < 0.02 * sliced.field_spread_pct
        );
        assert!((sliced.calibration.hard_iron_ut - truth.hard_iron_ut).norm() < 0.1);
        // And on circle-only data the streaming solve falls back too.
        let (truth, mut rng) = random_truth(71, 65.0);
        let mut accumulator = EllipsoidAccumulator::new();
        accumulator.add_all(&mags(&circle_only(&truth, 3000, 10.0, &mut rng)));
        let streamed = accumulator
            .solve(EllipsoidModel::Auto, None)
            .expect("solves");
        assert_eq!(streamed.model, EllipsoidModel::Band);
        assert!(streamed.fallback.is_some());
    }

    // serde_json is a native-only dependency.
    #[cfg(not(target_arch = "wasm32"))]
    #[test]
    fn the_fit_serialises_with_units_in_its_names() {
        let (truth, mut rng) = random_truth(80, 60.0);
        let samples = mags(&full_sphere(&truth, 500, &mut rng));
        let fit = fit_ellipsoid(&samples, &EllipsoidOptions::default()).expect("fits");
        let json = serde_json::to_value(&fit).expect("serialisable");
        for key in [
            "calibration",
            "model",
            "residual_rms_ut",
            "field_spread_pct",
            "fallback",
            "observability",
        ] {
            assert!(json.get(key).is_some(), "{key} in {json}");
        }
        assert!(json["observability"]["tilt_span_deg"].is_number());
        assert_eq!(json["model"], "Full");
    }

    /// The table behind [`MIN_FULL_TILT_SPAN_DEG`] and [`MIN_TILT_SPAN_DEG`]: heading
    /// and hard-iron errors of each model on bands of growing tilt. Slow; run with
    /// `cargo test --release --lib band_sweep -- --ignored --nocapture`.
    #[test]
    #[ignore]
    fn band_sweep() {
        let cases = [
            (3.0, 3000),
            (5.0, 3000),
            (10.0, 3000),
            (15.0, 3000),
            (20.0, 3000),
            (25.0, 3000),
            (30.0, 3000),
            (35.0, 3000),
            (45.0, 3000),
            (90.0, 3000),
            (10.0, 300),
            (10.0, 20_000),
        ];
        for (max_tilt_deg, n_samples) in cases {
            for model in [
                EllipsoidModel::Full,
                EllipsoidModel::Band,
                EllipsoidModel::Sphere,
            ] {
                let n_seeds = 30;
                let (mut worst_ut, mut worst_horizontal_ut, mut worst_heading_deg) =
                    (0.0f64, 0.0f64, 0.0f64);
                let (mut mean_heading_deg, mut mean_span_deg) = (0.0, 0.0);
                let mut n_refused = 0;
                for seed in 0..n_seeds {
                    let (truth, mut rng) = random_truth(1000 + seed, 65.0);
                    let samples = if max_tilt_deg >= 90.0 {
                        full_sphere(&truth, n_samples, &mut rng)
                    } else {
                        circle_only(&truth, n_samples, max_tilt_deg, &mut rng)
                    };
                    let mag_ut = mags(&samples);
                    let mut accumulator = EllipsoidAccumulator::new();
                    accumulator.add_all(&mag_ut);
                    let Ok(geometry) = accumulator.geometry() else {
                        n_refused += 1;
                        continue;
                    };
                    mean_span_deg += geometry.tilt_span_deg / n_seeds as f64;
                    let calibration = forced_fit(&mag_ut, model);
                    let error_ut = calibration.hard_iron_ut - truth.hard_iron_ut;
                    let heading_deg = heading_rms_deg(&samples, &calibration);
                    worst_ut = worst_ut.max(error_ut.norm());
                    worst_horizontal_ut = worst_horizontal_ut.max(error_ut.xy().norm());
                    worst_heading_deg = worst_heading_deg.max(heading_deg);
                    mean_heading_deg += heading_deg / n_seeds as f64;
                }
                println!(
                    "tilt ±{max_tilt_deg:>2} (span {mean_span_deg:4.1}°) N {n_samples:>5} {model:?}: \
                     hard iron worst {worst_ut:6.2} µT ({worst_horizontal_ut:5.2} horizontal), \
                     heading RMS mean {mean_heading_deg:5.2}° worst {worst_heading_deg:5.2}°, \
                     {n_refused} refused"
                );
            }
        }
    }
}
