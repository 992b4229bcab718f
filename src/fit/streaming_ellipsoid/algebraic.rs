//! The algebraic, ellipsoid-specific fit (steps 2-3 of the method in [`super`]): Li and
//! Griffiths (2004), *Least squares ellipsoid specific fitting*, Proc. Geometric Modeling
//! and Processing, the algorithm of Magneto 1.2, solved on the scatter matrix read from
//! the power sums; the constrained models (Kåsa's (1976) sphere, the diagonal and the
//! band model) as combinations of fixed generator matrices; and the conversion of the
//! quadric to the hard iron and a symmetric `A`, scaled so that `det A = 1` (NXP's
//! AN4246) or to the expected field.

use nalgebra::{Cholesky, DMatrix, DVector, Matrix3, SymmetricEigen, Vector3};

use super::*;

/// Relative regularisation of the reduced scatter matrix before its Cholesky factor is
/// taken: noise-free data make it exactly singular (the solution is its null vector).
const SCATTER_REGULARISATION: f64 = 1e-12;

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
    pub(super) fn algebraic_fit(
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
    pub(super) fn approximate_residuals(&self, calibration: &FieldCalibration) -> (f64, f64) {
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
}

/// nalgebra's eigen solver iterates until it converges, which a matrix with a NaN or
/// an infinity never does; this bounds it.
const MAX_EIGEN_ITERATIONS: usize = 10_000;

/// The eigen decomposition of a finite symmetric 3×3 matrix.
pub(super) fn symmetric_eigen(matrix: Matrix3<f64>) -> Option<SymmetricEigen<f64, nalgebra::U3>> {
    if matrix.iter().all(|v| v.is_finite()) {
        SymmetricEigen::try_new(matrix, f64::EPSILON, MAX_EIGEN_ITERATIONS)
    } else {
        None
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

/// The free entries of a model's `A` (and of its quadric matrix, which has the same
/// form): `A = Σ θ_k·G_k`.
pub(super) fn generators(model: EllipsoidModel, geometry: &Geometry) -> Vec<Matrix3<f64>> {
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
