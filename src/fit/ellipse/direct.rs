//! The direct, ellipse-specific conic fit in the level plane (step 1 of the fit in
//! [`super`]): Fitzgibbon, Pilu and Fisher (1999, *Direct least square fitting of
//! ellipses*, IEEE PAMI 21(5)) in the numerically stable form of Halíř and Flusser (1998,
//! *Numerically stable direct least squares fitting of ellipses*, WSCG), on centred and
//! scaled coordinates; the start of the tilt-aware fit, and on its own ([`fit_ellipse`])
//! the calibration for data that are already level.

use nalgebra::{Matrix2, Matrix3, SymmetricEigen, Vector2, Vector3};

use super::{PlaneCalibration, PlaneError, MAX_AXIS_RATIO, MIN_SAMPLES};

/// Fits a general ellipse to levelled field samples (µT) and returns the correction
/// that maps it onto a circle: the calibration for data that is already level (or
/// levelled after removing a known 3D hard iron). The transform is symmetric with
/// determinant 1, so the circle's radius is the geometric mean of the semi-axes.
pub fn fit_ellipse(level_ut: &[Vector2<f64>]) -> Result<PlaneCalibration, PlaneError> {
    if level_ut.len() < MIN_SAMPLES {
        return Err(PlaneError::TooFewSamples {
            n_samples: level_ut.len(),
            min: MIN_SAMPLES,
        });
    }
    if let Some(sample_idx) = level_ut
        .iter()
        .position(|sample| !(sample.x.is_finite() && sample.y.is_finite()))
    {
        return Err(PlaneError::NonFinite { sample_idx });
    }
    direct_ellipse_fit(level_ut)?.to_plane_calibration()
}

/// An ellipse `(p − center)ᵀ·shape·(p − center) = 1`, `shape` positive definite.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Ellipse {
    center_ut: Vector2<f64>,
    shape_per_ut2: Matrix2<f64>,
}

impl Ellipse {
    /// The symmetric square root `W` of `shape` maps the ellipse onto the unit circle;
    /// `radius·W` with `radius = det(shape)^(−1/4)` (the geometric mean of the
    /// semi-axes) maps it onto a circle of the same area.
    pub(super) fn to_plane_calibration(self) -> Result<PlaneCalibration, PlaneError> {
        let eigen = SymmetricEigen::new(self.shape_per_ut2);
        let (small, large) = (eigen.eigenvalues.min(), eigen.eigenvalues.max());
        if !(small > 0.0 && large.is_finite()) {
            return Err(PlaneError::DegenerateConic {
                reason: "the fitted conic is not a real ellipse",
            });
        }
        let axis_ratio = (large / small).sqrt();
        if axis_ratio > MAX_AXIS_RATIO {
            return Err(PlaneError::TooElongated { axis_ratio });
        }
        let radius_ut = (small * large).powf(-0.25);
        let sqrt_eigenvalues = Matrix2::from_diagonal(&eigen.eigenvalues.map(f64::sqrt));
        let transform =
            eigen.eigenvectors * sqrt_eigenvalues * eigen.eigenvectors.transpose() * radius_ut;
        // Symmetrise away the rounding of the product.
        let transform = (transform + transform.transpose()) / 2.0;
        Ok(PlaneCalibration {
            center_ut: self.center_ut,
            transform,
            radius_ut,
        })
    }
}

/// The direct ellipse-specific fit (Fitzgibbon et al. 1999) as Halíř and Flusser (1998)
/// solve it. The conic `a·x² + b·xy + c·y² + d·x + e·y + f = 0` is split into its
/// quadratic part `a1 = (a, b, c)` and linear part `a2 = (d, e, f)`; with the scatter
/// matrices `S1 = D1ᵀD1`, `S2 = D1ᵀD2`, `S3 = D2ᵀD2` of the design rows
/// `D1 = (x², xy, y²)`, `D2 = (x, y, 1)`, minimising `|D1·a1 + D2·a2|²` under
/// `4ac − b² = 1` gives `a2 = −S3⁻¹·S2ᵀ·a1` and the 3×3 eigenproblem
/// `C1⁻¹·(S1 − S2·S3⁻¹·S2ᵀ)·a1 = λ·a1`, whose one eigenvector with `4ac − b² > 0` is
/// the ellipse. Centring and scaling the data first keeps the scatter matrices well
/// conditioned (Halíř and Flusser's remedy for the singular `S1` of the original).
pub(super) fn direct_ellipse_fit(points_ut: &[Vector2<f64>]) -> Result<Ellipse, PlaneError> {
    let n_points = points_ut.len() as f64;
    let mean_ut = points_ut.iter().sum::<Vector2<f64>>() / n_points;
    let scale_ut = (points_ut
        .iter()
        .map(|point| (point - mean_ut).norm_squared())
        .sum::<f64>()
        / n_points)
        .sqrt();
    if !(scale_ut.is_finite() && scale_ut > 0.0) {
        return Err(PlaneError::DegenerateConic {
            reason: "all samples are the same point",
        });
    }
    let (mut s1, mut s2, mut s3) = (Matrix3::zeros(), Matrix3::zeros(), Matrix3::zeros());
    for point in points_ut {
        let q = (point - mean_ut) / scale_ut;
        let quadratic = Vector3::new(q.x * q.x, q.x * q.y, q.y * q.y);
        let linear = Vector3::new(q.x, q.y, 1.0);
        s1 += quadratic * quadratic.transpose();
        s2 += quadratic * linear.transpose();
        s3 += linear * linear.transpose();
    }
    let s3_inverse = s3.try_inverse().ok_or(PlaneError::DegenerateConic {
        reason: "the samples lie on a line",
    })?;
    let linear_from_quadratic = -s3_inverse * s2.transpose();
    let reduced_scatter = s1 + s2 * linear_from_quadratic;
    // C1⁻¹ for the constraint matrix C1 = [[0, 0, 2], [0, −1, 0], [2, 0, 0]].
    let eigen_problem = Matrix3::from_rows(&[
        reduced_scatter.row(2) / 2.0,
        -reduced_scatter.row(1),
        reduced_scatter.row(0) / 2.0,
    ]);
    if !eigen_problem.iter().all(|value| value.is_finite()) {
        return Err(PlaneError::DegenerateConic {
            reason: "the scatter matrices are not finite",
        });
    }
    let eigen_problem_norm = eigen_problem.norm();
    let mut best: Option<(f64, Vector3<f64>)> = None;
    for eigenvalue in eigen_problem.complex_eigenvalues().iter() {
        let Some(eigenvector) = null_vector(&(eigen_problem - Matrix3::identity() * eigenvalue.re))
        else {
            continue;
        };
        let eigen_residual = (eigen_problem * eigenvector - eigenvector * eigenvalue.re).norm();
        let constraint = 4.0 * eigenvector.x * eigenvector.z - eigenvector.y * eigenvector.y;
        let is_eigenvector = eigen_residual <= 1e-6 * eigen_problem_norm.max(f64::MIN_POSITIVE);
        if is_eigenvector && constraint > 0.0 && best.is_none_or(|(best, _)| constraint > best) {
            best = Some((constraint, eigenvector));
        }
    }
    let (_, quadratic) = best.ok_or(PlaneError::DegenerateConic {
        reason: "no ellipse fits the samples",
    })?;
    let linear = linear_from_quadratic * quadratic;

    // The centre solves `2·Q·x0 = −(d, e)`; then `(q − x0)ᵀ·Q·(q − x0) = x0ᵀ·Q·x0 − f`.
    let q_matrix = Matrix2::new(
        quadratic.x,
        quadratic.y / 2.0,
        quadratic.y / 2.0,
        quadratic.z,
    );
    let q_inverse = q_matrix.try_inverse().ok_or(PlaneError::DegenerateConic {
        reason: "the fitted conic is singular",
    })?;
    let center = -q_inverse * Vector2::new(linear.x, linear.y) / 2.0;
    let level = center.dot(&(q_matrix * center)) - linear.z;
    let shape = q_matrix / level;
    if !(shape[(0, 0)] > 0.0 && shape.determinant() > 0.0 && shape.iter().all(|v| v.is_finite())) {
        return Err(PlaneError::DegenerateConic {
            reason: "the fitted conic is an imaginary or degenerate ellipse",
        });
    }
    Ok(Ellipse {
        center_ut: mean_ut + center * scale_ut,
        shape_per_ut2: shape / (scale_ut * scale_ut),
    })
}

/// A unit vector spanning the null space of a (nearly) rank-2 3×3 matrix: the largest
/// cross product of two of its rows, which is orthogonal to all three rows.
fn null_vector(matrix: &Matrix3<f64>) -> Option<Vector3<f64>> {
    let rows = [
        matrix.row(0).transpose(),
        matrix.row(1).transpose(),
        matrix.row(2).transpose(),
    ];
    let candidates = [
        rows[0].cross(&rows[1]),
        rows[0].cross(&rows[2]),
        rows[1].cross(&rows[2]),
    ];
    let largest = candidates
        .into_iter()
        .max_by(|a, b| a.norm_squared().total_cmp(&b.norm_squared()))?;
    let norm = largest.norm();
    (norm > 0.0 && norm.is_finite()).then(|| largest / norm)
}
