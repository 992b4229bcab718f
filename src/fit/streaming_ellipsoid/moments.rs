//! The power sums behind the streaming fit (step 1 of the method in [`super`]): the 35
//! sums `Σ dx^a·dy^b·dz^c` (`a + b + c ≤ 4`) of the samples' offsets from an origin, from
//! which every entry of Li and Griffiths' (2004) 10×10 scatter matrix `D·Dᵀ` is read.
//! They are computed in chunks that keep the sums in registers (two samples per SSE2
//! register on x86-64), and moved to another origin and scale exactly by the binomial
//! theorem.

use nalgebra::Vector3;

use super::*;

/// The number of monomials `x^a·y^b·z^c` with `a + b + c ≤ 4`.
pub(super) const N_MOMENTS: usize = 35;

/// Their exponents, by degree, then by falling power of x, then of y. [`monomials`]
/// writes them out in this order.
pub(super) const EXPONENTS: [[usize; 3]; N_MOMENTS] = build_exponents();

/// The index in [`EXPONENTS`] of each `(a, b, c)`; unused where `a + b + c > 4`.
pub(super) const MOMENT_INDEX: [[[usize; 5]; 5]; 5] = build_moment_index();

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
pub(super) fn monomials(d: Vector3<f64>) -> [f64; N_MOMENTS] {
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
pub(super) const CHUNK_LEN: usize = 256;

/// The power sums of one chunk's offsets from `origin_ut`, in the order of
/// [`EXPONENTS`], or `None` if a sample in it is not finite or out of range (the
/// slow path then finds and reports it).
pub(super) fn chunk_moments(
    samples_ut: &[Vector3<f64>],
    origin_ut: Vector3<f64>,
) -> Option<[f64; N_MOMENTS]> {
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
pub(super) fn offset_sums(offsets: &[[f64; 3]]) -> [f64; N_MOMENTS] {
    // SAFETY: `sse2::offset_sums` needs only the SSE2 target feature, and the `cfg`
    // above compiles this call only where that feature is enabled for the whole build.
    unsafe { sse2::offset_sums(offsets) }
}

/// The power sums of at most [`CHUNK_LEN`] offsets (targets without SSE2, e.g. wasm).
#[cfg(not(all(target_arch = "x86_64", target_feature = "sse2")))]
pub(super) fn offset_sums(offsets: &[[f64; 3]]) -> [f64; N_MOMENTS] {
    scalar_offset_sums(offsets)
}

/// The power sums of a few offsets, in the order of [`EXPONENTS`].
///
/// Adding 35 sums per sample to memory is limited by the stores (one per cycle, twice
/// the arithmetic's time), so the offsets are read four times instead, each time for at
/// most ten sums that stay in registers, and the sums are stored once per chunk.
/// Written out by hand because the size-built first-paint module (`opt-level = "z"`)
/// neither unrolls nor vectorises.
pub(super) fn scalar_offset_sums(offsets: &[[f64; 3]]) -> [f64; N_MOMENTS] {
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
pub(super) fn shift_and_scale(
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
