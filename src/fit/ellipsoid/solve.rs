//! The 3D fit's solver: iteratively reweighted Levenberg-Marquardt along the parameter
//! directions the data see (the rest held at the priors), and the posterior covariance
//! with the residuals' autocorrelation counted.

use super::*;

/// Iteratively reweighted Levenberg-Marquardt from `start`, moving only along the
/// directions the data see ([`observed_directions`]); `None` when it diverges or ends on
/// a mirror image (negative determinant).
pub(super) fn solve(
    set: &SampleSet,
    start: State,
    options: &InertialOptions,
    model: SoftIronModel,
) -> Option<Solution> {
    let start = match model {
        SoftIronModel::Full => start,
        SoftIronModel::Isotropic => State {
            correction: Matrix3::identity() * start.correction.determinant().abs().cbrt(),
            ..start
        },
    };
    let model_directions = match (model, set.band_axis()) {
        (SoftIronModel::Full, Some(axis)) => FreeDirections::band(axis),
        (SoftIronModel::Full, None) if set.uses_dip() => FreeDirections::all(),
        (SoftIronModel::Full, None) => FreeDirections::symmetric(),
        (SoftIronModel::Isotropic, _) => FreeDirections::isotropic(),
    };
    // First a short probe along every direction of the model; then, to convergence,
    // only those the data see at the noise the probe leaves (judged before it, a start's
    // misfit would pass for noise and hide what the data do see), the others back at
    // the start's values, which come from the priors.
    let (first, first_weights) = iterate(
        set,
        start,
        &start,
        options,
        &model_directions,
        Schedule::Probe,
    )?;
    let normal = normal_equations(set, &first, &first_weights, options, &start);
    let inflation = autocorrelation_inflation(set, &first, &first_weights);
    let observed = observed_directions(&normal, inflation, model_directions.clone());
    let (from, free) = if observed.n_free < model_directions.n_free {
        let restart = start.with_params(&observed.project(&start.params(), &first.params()));
        (restart, &observed)
    } else {
        (first, &model_directions)
    };
    let (state, weights) = iterate(set, from, &start, options, free, Schedule::Converge)?;
    let det = state.correction.determinant();
    if det.is_nan() || det <= 0.0 {
        return None;
    }
    Some(Solution {
        state,
        model,
        weights,
        prior_centre: start,
    })
}

/// Iteratively reweighted Levenberg-Marquardt from `from` along the `free` directions
/// (the priors centred as for `start`): the state and the last weights.
pub(super) fn iterate(
    set: &SampleSet,
    from: State,
    start: &State,
    options: &InertialOptions,
    free: &FreeDirections,
    schedule: Schedule,
) -> Option<(State, Weights)> {
    let mut state = from;
    let mut lambda = 1e-3;
    let mut last = None;
    for reweighting in 0..schedule.max_reweightings() {
        let before = state;
        let weights = weights(set, &state, schedule.loss());
        let mut normal = normal_equations(set, &state, &weights, options, start);
        let max_iterations = schedule.max_iterations(reweighting);
        for iteration in 0..max_iterations {
            let step = free.step(&normal.jtj, &normal.jtr, lambda)?;
            let trial = state.with_params(&(state.params() - step));
            // The cost decides; the gradients only where another step will use them.
            let trial_cost = cost(set, &trial, &weights, options, start);
            if trial_cost.is_finite() && trial_cost <= normal.cost {
                let decrease = normal.cost - trial_cost;
                state = trial;
                lambda = (lambda / 3.0).max(1e-9);
                if decrease <= STEADY_COST_SHARE * trial_cost.max(1e-300)
                    || iteration + 1 == max_iterations
                {
                    break;
                }
                normal = normal_equations(set, &state, &weights, options, start);
            } else {
                lambda *= 4.0;
                if lambda > 1e8 {
                    break;
                }
            }
        }
        last = Some(weights);
        if reweighting + 1 >= schedule.min_reweightings() && state.is_steady_from(&before) {
            break;
        }
    }
    Some((state, last?))
}

/// The parameter directions the fit may move along: a basis of columns.
#[derive(Clone)]
pub(super) struct FreeDirections {
    pub(super) basis: SMatrix<f64, N_MAX, N_MAX>,
    pub(super) n_free: usize,
}

impl FreeDirections {
    /// `from` moved towards `to` along the free directions only: `from + B·α` with
    /// `α` the least-squares coordinates of `to − from` in the basis `B`.
    pub(super) fn project(&self, from: &ParamVec, to: &ParamVec) -> ParamVec {
        let basis = self.basis.columns(0, self.n_free);
        let gram = basis.transpose() * basis;
        let coordinates = gram
            .cholesky()
            .map(|cholesky| cholesky.solve(&(basis.transpose() * (to - from))));
        match coordinates {
            Some(coordinates) => from + basis * coordinates,
            None => *from,
        }
    }

    pub(super) fn all() -> FreeDirections {
        FreeDirections {
            basis: ParamMat::identity(),
            n_free: N_MAX,
        }
    }

    /// The band model, for a device that turns about `axis` (unit, body axes: the mean
    /// down) with little tilt: the hard iron, the vertical field, and five directions
    /// of `D`: its in-plane shape (the difference of the two in-plane gains, and their
    /// cross term), one gain for all axes, and the leak of the in-plane field into the
    /// corrected vertical. What the band hardly sees (the axis's own gain, the leak of
    /// the axis into the plane, which a level turn cannot tell from hard iron, and a
    /// rotation about the axis: an ellipsoid through a flat ring can stretch, lean and
    /// turn almost freely) stays at the start's, which takes it from the priors, and the
    /// covariance reports the priors' uncertainty there.
    pub(super) fn band(axis: Vector3<f64>) -> FreeDirections {
        let helper = if axis.x.abs() < 0.9 {
            Vector3::x()
        } else {
            Vector3::y()
        };
        let first = axis.cross(&helper).normalize();
        let second = axis.cross(&first);
        let as_params = |matrix: Matrix3<f64>| {
            let mut params = ParamVec::zeros();
            for row in 0..3 {
                for col in 0..3 {
                    params[D0 + 3 * row + col] = matrix[(row, col)];
                }
            }
            params.normalize()
        };
        let mut free = FreeDirections {
            basis: ParamMat::zeros(),
            n_free: 0,
        };
        let mut add = |vector: ParamVec| {
            free.basis.set_column(free.n_free, &vector);
            free.n_free += 1;
        };
        for axis_idx in 0..3 {
            let mut unit = ParamVec::zeros();
            unit[H + axis_idx] = 1.0;
            add(unit);
        }
        let mut vertical = ParamVec::zeros();
        vertical[V] = 1.0;
        add(vertical);
        add(as_params(
            first * first.transpose() - second * second.transpose(),
        ));
        add(as_params(
            first * second.transpose() + second * first.transpose(),
        ));
        add(as_params(Matrix3::identity()));
        // How the in-plane field leaks into the corrected vertical: a level turn sees
        // it (the vertical must not swing with the heading).
        add(as_params(axis * first.transpose()));
        add(as_params(axis * second.transpose()));
        free
    }

    /// Without the accelerometer: the hard iron and a symmetric `D` (the classic
    /// ellipsoid; nothing sees a rotation, nor the vertical field). Held by a pinning
    /// prior instead, those directions would also freeze their symmetric neighbours
    /// through Marquardt's scaling of the damping.
    pub(super) fn symmetric() -> FreeDirections {
        let mut free = FreeDirections {
            basis: ParamMat::zeros(),
            n_free: 0,
        };
        let mut add = |entries: &[(usize, f64)]| {
            for &(idx, value) in entries {
                free.basis[(idx, free.n_free)] = value;
            }
            free.n_free += 1;
        };
        for axis in 0..3 {
            add(&[(H + axis, 1.0)]);
            add(&[(D0 + 4 * axis, 1.0)]);
        }
        let half = std::f64::consts::FRAC_1_SQRT_2;
        for (a, b) in [(0, 1), (0, 2), (1, 2)] {
            add(&[(D0 + 3 * a + b, half), (D0 + 3 * b + a, half)]);
        }
        free
    }

    /// The hard iron, one scale for every axis, and the vertical field.
    pub(super) fn isotropic() -> FreeDirections {
        let mut basis = ParamMat::zeros();
        for axis in 0..3 {
            basis[(H + axis, axis)] = 1.0;
            basis[(D0 + 4 * axis, 3)] = 1.0;
        }
        basis[(V, 4)] = 1.0;
        FreeDirections { basis, n_free: 5 }
    }

    /// The damped Gauss-Newton step restricted to the free directions.
    /// The Levenberg-Marquardt step restricted to the free directions: the normal
    /// equations reduced to them, damped by `lambda` times their own diagonal (so that a
    /// frozen direction's prior cannot damp the free ones that share its entries).
    pub(super) fn step(&self, jtj: &ParamMat, jtr: &ParamVec, lambda: f64) -> Option<ParamVec> {
        let basis = self.basis.columns(0, self.n_free);
        let mut reduced = basis.transpose() * jtj * basis;
        for idx in 0..self.n_free {
            reduced[(idx, idx)] += lambda * reduced[(idx, idx)].max(1e-12);
        }
        let rhs = basis.transpose() * jtr;
        let solution = reduced.cholesky()?.solve(&rhs);
        Some(basis * solution)
    }
}

/// Directions of the parameters along which the data say at least
/// [`MIN_DATA_OVER_PRIOR`] times more than the priors, once the residuals' correlation
/// (`inflation`) is counted: the generalised eigenvectors of the data's information
/// against the priors'. Along the others (a level turn's vertical hard iron and scale,
/// whose family of ellipsoids through one circle includes flat caps that fit any plane
/// of samples, disturbances and all) the fit stays at its start, which the starts set
/// from the priors, and the covariance reports the prior's uncertainty there.
pub(super) fn observed_directions(
    normal: &Normal,
    inflation: f64,
    model: FreeDirections,
) -> FreeDirections {
    // Within the model's subspace (columns B): the reduced information matrices.
    let basis = model.basis.columns(0, model.n_free).into_owned();
    let prior = basis.transpose() * normal.prior_information * &basis;
    let data = basis.transpose() * (normal.jtj - normal.prior_information) * &basis;
    let Some(cholesky) = prior.clone().cholesky() else {
        return model;
    };
    // M = L⁻¹·data·L⁻ᵀ; an eigenvector y of M is the direction v = B·L⁻ᵀ·y.
    let Some(lower_inverse) = cholesky.l().try_inverse() else {
        return model;
    };
    let whitened = &lower_inverse * data * lower_inverse.transpose();
    let whitened = (&whitened + whitened.transpose()) / 2.0;
    let eigen = whitened.symmetric_eigen();
    let threshold = MIN_DATA_OVER_PRIOR * inflation;
    let mut free = FreeDirections {
        basis: ParamMat::zeros(),
        n_free: 0,
    };
    for (idx, &value) in eigen.eigenvalues.iter().enumerate() {
        if value >= threshold {
            let direction = &basis * (lower_inverse.transpose() * eigen.eigenvectors.column(idx));
            free.basis.set_column(free.n_free, &direction);
            free.n_free += 1;
        }
    }
    if free.n_free == 0 {
        return model;
    }
    free
}

/// The posterior covariance `(J_dᵀWJ_d / inflation + P)⁻¹`: the data's information
/// counted for its correlated samples, the priors' as they are.
pub(super) fn posterior_covariance(normal: &Normal, inflation: f64) -> Option<ParamMat> {
    let data = normal.jtj - normal.prior_information;
    (data / inflation.max(1.0) + normal.prior_information)
        .try_inverse()
        .filter(|covariance| covariance.iter().all(|v| v.is_finite()))
}

/// `(1 + ρ) / (1 − ρ)` for the lag-one autocorrelation `ρ` of the residuals in sample
/// order (the larger of the two kinds, weighted): neighbouring samples share their tilt error and
/// their disturbance, so they count for less than independent ones.
pub(super) fn autocorrelation_inflation(set: &SampleSet, state: &State, weights: &Weights) -> f64 {
    let mut magnitude = Vec::with_capacity(set.mag_ut.len());
    let mut vertical = Vec::with_capacity(set.mag_ut.len());
    // The weighted residuals: a burst of moving iron, set aside by its weights, is not
    // a correlation of the rest.
    for (idx, &m_ut) in set.mag_ut.iter().enumerate() {
        let (r_b, r_v) = raw_residuals(state, m_ut, set.down(idx), weights.kappa);
        let weight = |weights: &[f64]| weights.get(idx).copied().unwrap_or(0.0).sqrt();
        magnitude.push(r_b * weight(&weights.magnitude));
        if let Some(r_v) = r_v {
            vertical.push(r_v * weight(&weights.vertical));
        }
    }
    let lag_one = |values: &[f64]| {
        if values.len() < 3 {
            return 0.0;
        }
        let mean = values.iter().sum::<f64>() / values.len() as f64;
        let variance: f64 = values.iter().map(|v| (v - mean).powi(2)).sum();
        let covariance: f64 = values
            .windows(2)
            .map(|pair| (pair[0] - mean) * (pair[1] - mean))
            .sum();
        if variance > 0.0 {
            (covariance / variance).clamp(0.0, 0.99)
        } else {
            0.0
        }
    };
    let rho = lag_one(&magnitude).max(lag_one(&vertical));
    (1.0 + rho) / (1.0 - rho)
}
