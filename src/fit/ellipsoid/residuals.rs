//! The residuals of the 3D fit and their normal equations: per sample, the magnitude
//! residual `|D·(m − h)| − F` and the vertical one `ĝ·D·(m − h) − V` (the dip-angle
//! invariance), each divided by its Sampson normaliser (the length of its gradient in
//! the raw reading); the robust scales and weights; `JᵀWJ`, `JᵀWr` and the cost with the
//! priors' residuals added; and the cost alone, for trial steps.

use super::*;

/// The two residuals of one sample.
pub(super) fn residuals(
    state: &State,
    m_ut: Vector3<f64>,
    down: Option<Vector3<f64>>,
) -> (f64, Option<f64>) {
    let corrected = state.correction * (m_ut - state.hard_iron_ut);
    (
        corrected.norm() - state.field_ut,
        down.map(|down| down.dot(&corrected) - state.vertical_ut),
    )
}

/// The median of absolute values (destroys the order of `values`).
pub(super) fn median_abs(values: &mut [f64]) -> f64 {
    for value in values.iter_mut() {
        *value = value.abs();
    }
    crate::base::stats::median(values).unwrap_or(0.0)
}

/// The length of each residual's gradient with respect to the measurement, `|Dᵀa|`
/// (`a` the unit corrected field for the magnitude, "down" for the vertical): a residual
/// divided by it is a distance in the raw field (µT as measured, the first-order
/// geometric or Sampson distance), whose noise is the sensor's whatever `D` is. In the
/// corrected space the noise of a residual grows and shrinks with `D`, and a fit there
/// shrinks `D` along an axis the data hardly constrain just to shrink the noise: a bias
/// of several µT in the vertical hard iron of a yaw-only turn.
pub(super) fn normalisers(
    state: &State,
    m_ut: Vector3<f64>,
    down: Option<Vector3<f64>>,
    kappa: f64,
) -> (f64, f64) {
    let d_ut = m_ut - state.hard_iron_ut;
    let magnitude = magnitude_norm(&state.correction, d_ut).unwrap_or(1.0);
    let vertical = down
        .and_then(|down| vertical_norm(&state.correction, d_ut, down, kappa))
        .unwrap_or(1.0);
    (magnitude, vertical)
}

pub(super) const NORMALISER_FLOOR: f64 = 1e-9;

/// [`magnitude_normaliser`]'s value alone (the same arithmetic, without the gradient).
pub(super) fn magnitude_norm(correction: &Matrix3<f64>, d_ut: Vector3<f64>) -> Option<f64> {
    let corrected = correction * d_ut;
    let c_norm = corrected.norm();
    let q_norm = (correction.transpose() * corrected).norm();
    if !(c_norm > 0.0 && q_norm > 0.0) {
        return None;
    }
    Some((q_norm * (1.0 / c_norm)).max(NORMALISER_FLOOR))
}

/// [`vertical_normaliser`]'s value alone (the same arithmetic, without the gradient).
pub(super) fn vertical_norm(
    correction: &Matrix3<f64>,
    d_ut: Vector3<f64>,
    down: Vector3<f64>,
    kappa: f64,
) -> Option<f64> {
    let w = correction.transpose() * down;
    let corrected = correction * d_ut;
    let perpendicular = corrected - down * down.dot(&corrected);
    let n = (w.norm_squared() + kappa * kappa * perpendicular.norm_squared()).sqrt();
    if n.is_nan() || n <= 0.0 {
        return None;
    }
    Some(n.max(NORMALISER_FLOOR))
}

/// The magnitude residual's normaliser `n = |Dᵀĉ| = |q|/|c|` (with `c = D·d`,
/// `d = m − h`, `q = Dᵀc`) and its gradient:
/// `∂n/∂D_jk = (q̂_k·c_j + (D·q̂)_j·d_k − n·ĉ_j·d_k) / |c|`,
/// `∂n/∂h = (n·Dᵀĉ − DᵀD·q̂) / |c|`.
pub(super) fn magnitude_normaliser(
    correction: &Matrix3<f64>,
    d_ut: Vector3<f64>,
) -> Option<(f64, ParamVec)> {
    let corrected = correction * d_ut;
    let c_norm = corrected.norm();
    let q = correction.transpose() * corrected;
    let q_norm = q.norm();
    if !(c_norm > 0.0 && q_norm > 0.0) {
        return None;
    }
    // Reciprocals once: divisions cost ten times a multiplication in this loop.
    let (inv_c_norm, inv_q_norm) = (1.0 / c_norm, 1.0 / q_norm);
    let (c_unit, q_unit) = (corrected * inv_c_norm, q * inv_q_norm);
    let n = q_norm * inv_c_norm;
    let d_q_unit = correction * q_unit;
    let mut gradient = ParamVec::zeros();
    let hard = correction.transpose() * (c_unit * n - d_q_unit) * inv_c_norm;
    for axis in 0..3 {
        gradient[H + axis] = hard[axis];
    }
    for row in 0..3 {
        let (a, b) = (
            corrected[row] * inv_c_norm,
            (d_q_unit[row] - n * c_unit[row]) * inv_c_norm,
        );
        for col in 0..3 {
            gradient[D0 + 3 * row + col] = q_unit[col] * a + b * d_ut[col];
        }
    }
    Some((n.max(NORMALISER_FLOOR), gradient))
}

/// The vertical residual's normaliser. The magnetometer's noise reaches `u·c` through
/// `|Dᵀu|`; the tilt's error `δ` (radians, perpendicular to `u`) through the horizontal
/// part of the field, `δ·c⊥` with `c⊥ = c − (u·c)·u`. Both in the magnetometer noise's
/// units: `n² = |Dᵀu|² + κ²·|c⊥|²`, `κ = σ_tilt / σ_mag`. Without the second term a fit
/// would tilt the corrected field towards "down" to shrink the tilt's noise. Gradient:
/// `n·∂n = wᵀ∂w + κ²·c⊥ᵀ∂c` (`w = Dᵀu`), i.e. `∂n/∂D_jk = (w_k·u_j + κ²·c⊥_j·d_k) / n`,
/// `∂n/∂h = −κ²·Dᵀc⊥ / n`.
pub(super) fn vertical_normaliser(
    correction: &Matrix3<f64>,
    d_ut: Vector3<f64>,
    down: Vector3<f64>,
    kappa: f64,
) -> Option<(f64, ParamVec)> {
    let w = correction.transpose() * down;
    let corrected = correction * d_ut;
    let perpendicular = corrected - down * down.dot(&corrected);
    let kappa_sq = kappa * kappa;
    let n = (w.norm_squared() + kappa_sq * perpendicular.norm_squared()).sqrt();
    if n.is_nan() || n <= 0.0 {
        return None;
    }
    let inv_n = 1.0 / n;
    let mut gradient = ParamVec::zeros();
    let hard = -(correction.transpose() * perpendicular) * (kappa_sq * inv_n);
    for axis in 0..3 {
        gradient[H + axis] = hard[axis];
    }
    for row in 0..3 {
        let (a, b) = (down[row] * inv_n, kappa_sq * perpendicular[row] * inv_n);
        for col in 0..3 {
            gradient[D0 + 3 * row + col] = w[col] * a + b * d_ut[col];
        }
    }
    Some((n.max(NORMALISER_FLOOR), gradient))
}

/// The two residuals of one sample divided by their normalisers at the same state.
pub(super) fn raw_residuals(
    state: &State,
    m_ut: Vector3<f64>,
    down: Option<Vector3<f64>>,
    kappa: f64,
) -> (f64, Option<f64>) {
    let (r_b, r_v) = residuals(state, m_ut, down);
    let (n_b, n_v) = normalisers(state, m_ut, down, kappa);
    (r_b / n_b, r_v.map(|r_v| r_v / n_v))
}

/// Robust residual scales (1.4826 × MAD, raw µT), floored at a small share of the field.
pub(super) fn robust_scales(set: &SampleSet, state: &State, kappa: f64) -> (f64, f64) {
    let (mut magnitude, mut vertical): (Vec<f64>, Vec<f64>) = (Vec::new(), Vec::new());
    for (idx, &m_ut) in set.mag_ut.iter().enumerate() {
        let (r_b, r_v) = raw_residuals(state, m_ut, set.down(idx), kappa);
        magnitude.push(r_b);
        if let Some(r_v) = r_v {
            vertical.push(r_v);
        }
    }
    let floor_ut = 1e-4 * state.field_ut;
    (
        (1.4826 * median_abs(&mut magnitude)).max(floor_ut),
        (1.4826 * median_abs(&mut vertical)).max(floor_ut),
    )
}

/// `κ = σ_tilt / σ_mag` of [`vertical_normaliser`], from the robust spreads of the
/// corrected-space residuals: the magnitude's is the magnetometer's noise (times its
/// normaliser), and what the vertical one has beyond that noise is the tilt's error
/// times the horizontal field.
pub(super) fn tilt_noise_ratio(set: &SampleSet, state: &State) -> f64 {
    if !set.uses_dip() {
        return 0.0;
    }
    let (mut magnitude, mut vertical) = (Vec::new(), Vec::new());
    let (mut mag_gain_sq, mut vertical_gain_sq, mut horizontal_sq) =
        (Vec::new(), Vec::new(), Vec::new());
    for (idx, &m_ut) in set.mag_ut.iter().enumerate() {
        let Some(down) = set.down(idx) else {
            continue;
        };
        let d_ut = m_ut - state.hard_iron_ut;
        let (r_b, r_v) = residuals(state, m_ut, Some(down));
        magnitude.push(r_b);
        vertical.push(r_v.unwrap_or(0.0));
        if let Some(n) = magnitude_norm(&state.correction, d_ut) {
            mag_gain_sq.push(n * n);
        }
        vertical_gain_sq.push((state.correction.transpose() * down).norm_squared());
        let corrected = state.correction * d_ut;
        horizontal_sq.push((corrected - down * down.dot(&corrected)).norm_squared());
    }
    let median = |values: &mut Vec<f64>| median_abs(values);
    let sigma_mag_ut =
        1.4826 * median(&mut magnitude) / median(&mut mag_gain_sq).sqrt().max(NORMALISER_FLOOR);
    let sigma_vertical_ut = 1.4826 * median(&mut vertical);
    let excess_sq =
        sigma_vertical_ut.powi(2) - sigma_mag_ut.powi(2) * median(&mut vertical_gain_sq);
    let horizontal_sq = median(&mut horizontal_sq);
    if !(excess_sq > 0.0 && horizontal_sq > 0.0 && sigma_mag_ut > 0.0) {
        return 0.0;
    }
    (excess_sq / horizontal_sq).sqrt() / sigma_mag_ut
}

pub(super) fn weights(set: &SampleSet, state: &State, loss: Loss) -> Weights {
    let kappa = tilt_noise_ratio(set, state);
    let (sigma_magnitude_ut, sigma_vertical_ut) = robust_scales(set, state, kappa);
    let mut weights = Weights {
        sigma_magnitude_ut,
        sigma_vertical_ut,
        kappa,
        magnitude: Vec::with_capacity(set.mag_ut.len()),
        vertical: Vec::with_capacity(set.mag_ut.len()),
    };
    // Where the tilt is mostly not trusted, each sample's dip weighs its own trust (a
    // swinging arm's tilt is good only at moments); elsewhere every dip weighs alike, as
    // the trust would otherwise reshuffle a walk's dip for nothing it shows (msft F1's
    // hard iron moved by 45 µT, its track's error from 4.8 to 6.7 %).
    let untrusted = set.tilt_untrusted();
    let dip_weight = |idx: usize| if untrusted { set.dip_trust(idx) } else { 1.0 };
    for (idx, &m_ut) in set.mag_ut.iter().enumerate() {
        let (r_b, r_v) = raw_residuals(state, m_ut, set.down(idx), kappa);
        weights
            .magnitude
            .push(loss.weight(r_b / sigma_magnitude_ut));
        weights.vertical.push(r_v.map_or(0.0, |r_v| {
            dip_weight(idx) * loss.weight(r_v / sigma_vertical_ut)
        }));
    }
    weights
}

/// The normal equations `JᵀWJ`, `JᵀWr` and the cost `rᵀWr` of the weighted, scaled
/// residuals plus the priors', at `state`.
pub(super) struct Normal {
    pub(super) jtj: ParamMat,
    pub(super) jtr: ParamVec,
    pub(super) cost: f64,
    /// The priors' share of `jtj`: what is known without the data.
    pub(super) prior_information: ParamMat,
}

impl Normal {
    /// Nothing accumulated yet.
    fn zeros() -> Normal {
        Normal {
            jtj: ParamMat::zeros(),
            jtr: ParamVec::zeros(),
            cost: 0.0,
            prior_information: ParamMat::zeros(),
        }
    }
}

/// One prior residual `(aᵀθ − b) / σ` added to the normal equations.
pub(super) fn add_prior(normal: &mut Normal, gradient: &ParamVec, residual: f64, sigma: f64) {
    let scaled = gradient / sigma;
    let information = scaled * scaled.transpose();
    normal.jtj += information;
    normal.prior_information += information;
    normal.jtr += scaled * (residual / sigma);
    normal.cost += (residual / sigma).powi(2);
}

pub(super) fn normal_equations(
    set: &SampleSet,
    state: &State,
    weights: &Weights,
    options: &InertialOptions,
    start: &State,
) -> Normal {
    let uses_dip = set.uses_dip();
    let mut normal = Normal::zeros();
    // The upper triangle is accumulated in blocks of samples' rank-two updates.
    let inv_var_magnitude = 1.0 / weights.sigma_magnitude_ut.powi(2);
    let inv_var_vertical = 1.0 / weights.sigma_vertical_ut.powi(2);
    let mut block = Block::new();
    for (idx, &m_ut) in set.mag_ut.iter().enumerate() {
        let down = set.down(idx).filter(|_| uses_dip);
        let (magnitude, vertical) = sample_rows(state, m_ut, down, weights.kappa);
        let weighted = |row: Row, weights: &[f64], inv_var: f64| {
            row.map(|(rho, gradient)| {
                (
                    rho,
                    gradient,
                    weights.get(idx).copied().unwrap_or(0.0) * inv_var,
                )
            })
        };
        block.push(
            &mut normal,
            weighted(magnitude, &weights.magnitude, inv_var_magnitude),
            weighted(vertical, &weights.vertical, inv_var_vertical),
        );
    }
    block.flush(&mut normal);
    add_priors(&mut normal, state, options, start, uses_dip);
    normal
}

/// [`normal_equations`]'s cost alone (the same arithmetic, without the gradients): what
/// a trial step needs to be accepted or refused.
pub(super) fn cost(
    set: &SampleSet,
    state: &State,
    weights: &Weights,
    options: &InertialOptions,
    start: &State,
) -> f64 {
    let uses_dip = set.uses_dip();
    let inv_var_magnitude = 1.0 / weights.sigma_magnitude_ut.powi(2);
    let inv_var_vertical = 1.0 / weights.sigma_vertical_ut.powi(2);
    let mut normal = Normal::zeros();
    for (idx, &m_ut) in set.mag_ut.iter().enumerate() {
        let d_ut = m_ut - state.hard_iron_ut;
        let corrected = state.correction * d_ut;
        let term = |rho: Option<f64>, weights: &[f64], inv_var: f64| {
            let weight = weights.get(idx).copied().unwrap_or(0.0) * inv_var;
            match rho {
                Some(rho) if weight > 0.0 => weight * rho * rho,
                _ => 0.0,
            }
        };
        let magnitude = magnitude_norm(&state.correction, d_ut)
            .map(|n| (corrected.norm() - state.field_ut) * (1.0 / n));
        let vertical = set.down(idx).filter(|_| uses_dip).and_then(|down| {
            let n = vertical_norm(&state.correction, d_ut, down, weights.kappa)?;
            Some((down.dot(&corrected) - state.vertical_ut) * (1.0 / n))
        });
        normal.cost += term(magnitude, &weights.magnitude, inv_var_magnitude)
            + term(vertical, &weights.vertical, inv_var_vertical);
    }
    add_priors(&mut normal, state, options, start, uses_dip);
    normal.cost
}

/// One sample's two normalised residuals `ρ = r / n` (see [`normalisers`]) and their
/// gradients, `∂ρ = (∂r − ρ·∂n) / n`; the vertical one only with a down vector.
pub(super) type Row = Option<(f64, ParamVec)>;
pub(super) fn sample_rows(
    state: &State,
    m_ut: Vector3<f64>,
    down: Option<Vector3<f64>>,
    kappa: f64,
) -> (Row, Row) {
    let correction = state.correction;
    let d_ut = m_ut - state.hard_iron_ut;
    let corrected = correction * d_ut;
    let magnitude = corrected.norm();
    let magnitude_row = magnitude_normaliser(&correction, d_ut).map(|(n, n_gradient)| {
        let unit = corrected * (1.0 / magnitude);
        let inv_n = 1.0 / n;
        let rho = (magnitude - state.field_ut) * inv_n;
        (
            rho,
            (row_gradient(&correction, unit, d_ut, 0.0) - n_gradient * rho) * inv_n,
        )
    });
    let vertical_row = down.and_then(|down| {
        let (n, n_gradient) = vertical_normaliser(&correction, d_ut, down, kappa)?;
        let inv_n = 1.0 / n;
        let rho = (down.dot(&corrected) - state.vertical_ut) * inv_n;
        Some((
            rho,
            (row_gradient(&correction, down, d_ut, -1.0) - n_gradient * rho) * inv_n,
        ))
    });
    (magnitude_row, vertical_row)
}

/// The gradient of `aᵀ·D·(m − h) − v·V` (for a fixed direction `a`): `−Dᵀa` for `h`,
/// `a_j·d_k` for `D_jk`, `v_coefficient` for `V`.
pub(super) fn row_gradient(
    correction: &Matrix3<f64>,
    direction: Vector3<f64>,
    d_ut: Vector3<f64>,
    v_coefficient: f64,
) -> ParamVec {
    let mut gradient = ParamVec::zeros();
    let hard = -(correction.transpose() * direction);
    for axis in 0..3 {
        gradient[H + axis] = hard[axis];
    }
    for row in 0..3 {
        for col in 0..3 {
            gradient[D0 + 3 * row + col] = direction[row] * d_ut[col];
        }
    }
    gradient[V] = v_coefficient;
    gradient
}

/// One residual's row as the normal equations take it: `(ρ, ∂ρ, weight)`.
type WeightedRow = Option<(f64, ParamVec, f64)>;

/// Samples whose rank-two updates of `JᵀWJ` wait in a [`Block`].
const BLOCK_SAMPLES: usize = 16;

/// A block of samples' weighted gradients, by parameter (`a[p][k]`: parameter `p` of
/// sample `k`), added to `JᵀWJ` together ([`Block::flush`]): each entry is loaded and
/// stored once per block, not once per sample, and gets the same sum in the same
/// order as sample by sample (`entry + (a·g_a + b·g_b)` for each sample in turn).
struct Block {
    /// The magnitude row's gradient times its weight, and the gradient.
    a: [[f64; BLOCK_SAMPLES]; N_MAX],
    g_a: [[f64; BLOCK_SAMPLES]; N_MAX],
    /// The vertical row's.
    b: [[f64; BLOCK_SAMPLES]; N_MAX],
    g_b: [[f64; BLOCK_SAMPLES]; N_MAX],
    n_samples: usize,
}

impl Block {
    fn new() -> Block {
        let zeros = [[0.0; BLOCK_SAMPLES]; N_MAX];
        Block {
            a: zeros,
            g_a: zeros,
            b: zeros,
            g_b: zeros,
            n_samples: 0,
        }
    }

    /// One sample's two rows `(ρ, ∂ρ, weight)`: `JᵀWr` and the cost now, `JᵀWJ` when the
    /// block is full.
    fn push(&mut self, normal: &mut Normal, first: WeightedRow, second: WeightedRow) {
        // A row with no usable weight adds nothing (not even a NaN from its gradient).
        let usable = |row: WeightedRow| {
            row.filter(|&(_, _, weight)| weight > 0.0)
                .unwrap_or((0.0, ParamVec::zeros(), 0.0))
        };
        let (rho_a, g_a, w_a) = usable(first);
        let (rho_b, g_b, w_b) = usable(second);
        let k = self.n_samples;
        for param in 0..N_MAX {
            let (a, b) = (g_a[param] * w_a, g_b[param] * w_b);
            self.a[param][k] = a;
            self.g_a[param][k] = g_a[param];
            self.b[param][k] = b;
            self.g_b[param][k] = g_b[param];
            normal.jtr[param] += a * rho_a + b * rho_b;
        }
        normal.cost += w_a * rho_a * rho_a + w_b * rho_b * rho_b;
        self.n_samples += 1;
        if self.n_samples == BLOCK_SAMPLES {
            self.flush(normal);
        }
    }

    /// Adds the block's samples to the upper triangle of `JᵀWJ`, column by column.
    fn flush(&mut self, normal: &mut Normal) {
        let n = self.n_samples;
        for (col, column) in normal
            .jtj
            .as_mut_slice()
            .chunks_exact_mut(N_MAX)
            .enumerate()
        {
            let (ga_col, gb_col) = (&self.g_a[col][..n], &self.g_b[col][..n]);
            for ((entry, a_row), b_row) in column[..=col].iter_mut().zip(&self.a).zip(&self.b) {
                let samples = a_row[..n].iter().zip(ga_col).zip(&b_row[..n]).zip(gb_col);
                *entry = samples.fold(*entry, |sum, (((&a, &ga), &b), &gb)| {
                    sum + (a * ga + b * gb)
                });
            }
        }
        self.n_samples = 0;
    }
}

/// The priors' residuals: the vertical field, the soft iron towards `s·I`, its rotation
/// part towards zero, and the hard iron (barely). Without the dip, `V` is pinned where
/// it is (it does not enter any residual).
pub(super) fn add_priors(
    normal: &mut Normal,
    state: &State,
    options: &InertialOptions,
    start: &State,
    uses_dip: bool,
) {
    // Mirror the accumulated upper triangle first: the priors add full matrices.
    for row in 0..N_MAX {
        for col in 0..row {
            normal.jtj[(row, col)] = normal.jtj[(col, row)];
        }
    }
    let params = state.params();
    let unit = |idx: usize| {
        let mut gradient = ParamVec::zeros();
        gradient[idx] = 1.0;
        gradient
    };
    // The soft-iron priors are on the shape of `D`, `D/g` with `g = det(D)^⅓`, not on
    // its scale (which `F` sets): a prior residual `p = L(D)/g − c` for a linear `L`
    // has the gradient `(∂L − (p + c)·g·G) / g`, with `∂g/∂D = g·G`, `G = D⁻ᵀ/3`.
    let det = state.correction.determinant();
    if let (true, Some(inverse)) = (det > 0.0, state.correction.try_inverse()) {
        let g = det.cbrt();
        let mut g_gradient = ParamVec::zeros();
        for row in 0..3 {
            for col in 0..3 {
                g_gradient[D0 + 3 * row + col] = inverse[(col, row)] / 3.0 * g;
            }
        }
        if options.gain_known {
            // ln g, with ∂(ln g)/∂D = G = D⁻ᵀ/3.
            add_prior(normal, &(g_gradient / g), g.ln(), GAIN_PRIOR_STD);
        }
        let mut shape_prior = |linear: ParamVec, centre: f64, std: f64| {
            let value = linear.dot(&params) / g;
            let gradient = (linear - g_gradient * value) / g;
            add_prior(normal, &gradient, value - centre, std);
        };
        for axis in 0..3 {
            shape_prior(unit(D0 + 4 * axis), 1.0, SOFT_IRON_PRIOR_STD);
        }
        // Each off-diagonal pair as its symmetric part (cross-axis soft iron) and its
        // antisymmetric part (a small rotation).
        // Without the accelerometer nothing sees a rotation of the magnetometer's axes:
        // it is held at zero (the symmetric correction of the classic ellipsoid fit).
        // With a tilt mostly not trusted it is not held: on the generator's swinging arm
        // (symmetric soft iron by construction) holding it met issue 43's bar, but the
        // TYREX swinging trial's heading against motion capture went from 2.4° to 3.4°
        // (a real phone's magnetometer is turned against its accelerometer).
        let rotation_std = if uses_dip {
            ROTATION_PRIOR_STD_RAD
        } else {
            1e-9
        };
        for (a, b) in [(0, 1), (0, 2), (1, 2)] {
            let (ab, ba) = (D0 + 3 * a + b, D0 + 3 * b + a);
            for (sign, std) in [(1.0, CROSS_AXIS_PRIOR_STD), (-1.0, rotation_std)] {
                let mut linear = ParamVec::zeros();
                linear[ab] = 0.5;
                linear[ba] = 0.5 * sign;
                shape_prior(linear, 0.0, std);
            }
        }
    } else {
        normal.cost = f64::INFINITY;
    }
    for axis in 0..3 {
        add_prior(
            normal,
            &unit(H + axis),
            params[H + axis] - start.hard_iron_ut[axis],
            HARD_IRON_PRIOR_STD_UT,
        );
    }
    match (uses_dip, options.field) {
        (true, Some(prior)) => {
            let (sin_dip, cos_dip) = prior.inclination_deg.to_radians().sin_cos();
            let sigma_ut =
                (state.field_ut * cos_dip.abs().max(0.05) * INCLINATION_PRIOR_STD_DEG.to_radians())
                    .max(1e-6);
            add_prior(
                normal,
                &unit(V),
                params[V] - state.field_ut * sin_dip,
                sigma_ut,
            );
        }
        (true, None) => add_prior(normal, &unit(V), params[V], 1e3 * state.field_ut),
        (false, _) => add_prior(normal, &unit(V), params[V] - start.vertical_ut, 1e-9),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The per-sample rank-two update the blocks replace: `JᵀWJ`'s upper triangle,
    /// `JᵀWr` and the cost, one sample after the other.
    fn sample_by_sample(rows: &[(WeightedRow, WeightedRow)]) -> Normal {
        let mut normal = Normal::zeros();
        let usable = |row: WeightedRow| {
            row.filter(|&(_, _, weight)| weight > 0.0)
                .unwrap_or((0.0, ParamVec::zeros(), 0.0))
        };
        for &(first, second) in rows {
            let (rho_a, g_a, w_a) = usable(first);
            let (rho_b, g_b, w_b) = usable(second);
            for col in 0..N_MAX {
                for row in 0..=col {
                    normal.jtj[(row, col)] += g_a[row] * w_a * g_a[col] + g_b[row] * w_b * g_b[col];
                }
            }
            for row in 0..N_MAX {
                normal.jtr[row] += g_a[row] * w_a * rho_a + g_b[row] * w_b * rho_b;
            }
            normal.cost += w_a * rho_a * rho_a + w_b * rho_b * rho_b;
        }
        normal
    }

    /// Blocks of samples give `JᵀWJ`, `JᵀWr` and the cost bit for bit as one sample
    /// after the other, for partial and whole blocks, missing rows, and rows of zero
    /// weight whose gradient is NaN.
    #[test]
    fn blocks_sum_as_sample_by_sample() {
        let mut state = 0x9e37_79b9_7f4a_7c15_u64;
        let mut uniform = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 * 4.0 - 2.0
        };
        for n_samples in [0, 1, 15, 16, 17, 40, 333] {
            let rows: Vec<_> = (0..n_samples)
                .map(|idx| {
                    let mut row = || {
                        let gradient = ParamVec::from_fn(|_, _| uniform());
                        (uniform(), gradient, uniform().abs())
                    };
                    let first = row();
                    let second = match idx % 5 {
                        0 => None,
                        1 => Some((f64::NAN, ParamVec::repeat(f64::NAN), 0.0)),
                        _ => Some(row()),
                    };
                    (Some(first), second)
                })
                .collect();
            let expected = sample_by_sample(&rows);
            let mut normal = Normal::zeros();
            let mut block = Block::new();
            for &(first, second) in &rows {
                block.push(&mut normal, first, second);
            }
            block.flush(&mut normal);
            let bits = |values: &[f64]| {
                values
                    .iter()
                    .map(|value| value.to_bits())
                    .collect::<Vec<_>>()
            };
            assert_eq!(
                bits(normal.jtj.as_slice()),
                bits(expected.jtj.as_slice()),
                "{n_samples} samples: JᵀWJ"
            );
            assert_eq!(
                bits(normal.jtr.as_slice()),
                bits(expected.jtr.as_slice()),
                "{n_samples} samples: JᵀWr"
            );
            assert_eq!(
                normal.cost.to_bits(),
                expected.cost.to_bits(),
                "{n_samples} samples: cost"
            );
        }
    }
}
