//! The geometric refinement (step 4 of the method in [`super`]): Levenberg-Marquardt (the
//! `levenberg-marquardt` crate) on the residuals `(|A·(m − h)| − R) / (det A)^⅓` of the
//! model of Moafipoor et al. (2007), Eq. 2-3 and 5, with `R` fixed; the hard iron's
//! Gauss-Newton uncertainty, by which a refinement that drifts along a valley the data
//! hardly constrain is rejected; and the exact residual figures over the samples.

use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt};
use nalgebra::storage::Owned;
use nalgebra::{Cholesky, DMatrix, DVector, Dyn, Matrix3, Vector3};

use super::*;

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
pub(super) struct GeometricProblem<'a> {
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
    /// because this runs per sample and per iteration, and the size-built first-paint
    /// module (`opt-level = "z"`) leaves nalgebra's small loops rolled.
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
pub(super) fn problem_at<'a>(
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
pub(super) fn hard_iron_std_ut(problem: &GeometricProblem) -> Option<f64> {
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
pub(super) fn refine(
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
pub(super) fn residuals(samples_ut: &[Vector3<f64>], calibration: &FieldCalibration) -> (f64, f64) {
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
