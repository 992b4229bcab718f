//! The 3D fit's starts ([`super`]): the algebraic ellipsoid (Li and Griffiths), the band
//! start for yaw-only data (the samples' principal plane, a direct ellipse fit in it, the
//! vertical hard iron from the prior's dip) and Kåsa's sphere, ranked by how well they fit
//! as they stand.

use nalgebra::{Matrix3, SymmetricEigen, Vector2, Vector3};

use super::{
    robust_scales, tilt_noise_ratio, InertialOptions, SampleSet, State, BAND_AXIS_MIN_COS,
    TYPICAL_FIELD_UT,
};
use crate::fit::ellipse::fit_ellipse;
use crate::fit::streaming_ellipsoid::{EllipsoidAccumulator, EllipsoidModel};

/// `starts`, those that fit best as they are (median absolute residuals) first.
pub(super) fn ranked(set: &SampleSet, starts: Vec<State>) -> Vec<State> {
    let mut scored: Vec<(f64, State)> = starts
        .into_iter()
        .map(|start| {
            let (sigma_magnitude_ut, sigma_vertical_ut) =
                robust_scales(set, &start, tilt_noise_ratio(set, &start));
            let score = sigma_magnitude_ut
                + if set.uses_dip() {
                    sigma_vertical_ut
                } else {
                    0.0
                };
            (if score.is_nan() { f64::INFINITY } else { score }, start)
        })
        .collect();
    crate::base::sort::sort_by_key(&mut scored, |scored| scored.0);
    scored.into_iter().map(|(_, start)| start).collect()
}

/// The starts: the algebraic ellipsoid, the band start(s), the sphere.
pub(super) fn starts(set: &SampleSet, options: &InertialOptions) -> Vec<State> {
    let mut starts = Vec::new();
    let target_field = options
        .field
        .map(|prior| prior.total_ut)
        .or(options.gain_known.then_some(TYPICAL_FIELD_UT));
    let with_vertical = |state: State| finish_start(set, state, target_field);
    let band = band_starts(set, options);
    // On a band, only the band starts: a 3D start there holds what the band cannot see
    // at whatever values the noise gave it, and the band model would keep them.
    if set.band_axis().is_some() && !band.is_empty() {
        return band.into_iter().map(with_vertical).collect();
    }
    let mut accumulator = EllipsoidAccumulator::new();
    accumulator.add_all(&set.mag_ut);
    if let Ok(fit) = accumulator.solve(EllipsoidModel::Full, None) {
        let calibration = fit.calibration;
        starts.push(with_vertical(State {
            hard_iron_ut: calibration.hard_iron_ut,
            correction: calibration.soft_iron,
            vertical_ut: 0.0,
            field_ut: calibration.field_ut,
        }));
    }
    starts.extend(band.into_iter().map(with_vertical));
    if let Some((centre_ut, radius_ut)) = kasa_sphere(&set.mag_ut) {
        starts.push(with_vertical(State {
            hard_iron_ut: centre_ut,
            correction: Matrix3::identity(),
            vertical_ut: 0.0,
            field_ut: radius_ut,
        }));
    }
    starts
}

/// The samples' principal plane (the two axes of largest spread): its normal.
pub(super) struct PrincipalPlane {
    pub(super) mean_ut: Vector3<f64>,
    pub(super) normal: Vector3<f64>,
    /// Standard deviations along first, second and normal (µT).
    pub(super) spread_ut: [f64; 3],
}

pub(super) fn principal_plane(mag_ut: &[Vector3<f64>]) -> Option<PrincipalPlane> {
    let n = mag_ut.len() as f64;
    if mag_ut.is_empty() {
        return None;
    }
    let mean_ut: Vector3<f64> = mag_ut.iter().sum::<Vector3<f64>>() / n;
    let covariance = mag_ut
        .iter()
        .map(|m| (m - mean_ut) * (m - mean_ut).transpose())
        .sum::<Matrix3<f64>>()
        / n;
    let eigen = SymmetricEigen::new(covariance);
    let order = crate::base::sort::descending(eigen.eigenvalues.as_slice());
    let axis = |idx: usize| eigen.eigenvectors.column(order[idx]).into_owned();
    let (first, second) = (axis(0), axis(1));
    let spread = |idx: usize| eigen.eigenvalues[order[idx]].max(0.0).sqrt();
    Some(PrincipalPlane {
        mean_ut,
        normal: first.cross(&second),
        spread_ut: [spread(0), spread(1), spread(2)],
    })
}

/// Scales a start to the target field and sets its vertical field to the samples'
/// median (unless the band start set it).
fn finish_start(set: &SampleSet, state: State, target_field_ut: Option<f64>) -> State {
    let mut state = match target_field_ut {
        Some(field_ut) => state.scaled_to(field_ut),
        None => state,
    };
    if state.vertical_ut == 0.0 {
        let mut verticals: Vec<f64> = set
            .mag_ut
            .iter()
            .enumerate()
            .filter_map(|(idx, &m_ut)| {
                Some(
                    set.down(idx)?
                        .dot(&(state.correction * (m_ut - state.hard_iron_ut))),
                )
            })
            .collect();
        if !verticals.is_empty() {
            let middle = verticals.len() / 2;
            let (_, median, _) = verticals.select_nth_unstable_by(middle, f64::total_cmp);
            state.vertical_ut = *median;
        }
    }
    state
}

/// For a device turned about the vertical: the samples' principal plane, a direct
/// ellipse fit in it, the same scale across it, and the vertical hard iron from the
/// dip (the prior's, or a few guesses without one).
fn band_starts(set: &SampleSet, options: &InertialOptions) -> Vec<State> {
    let Some(principal) = principal_plane(&set.mag_ut) else {
        return Vec::new();
    };
    let mean_ut = principal.mean_ut;
    // The band's axis: the mean down on a band (so that the start is already of the
    // band model), else the samples' own normal; without the accelerometer the normal
    // is taken as the vertical (a level turn; the field points down north of the
    // magnetic equator).
    let (normal, mean_down) = match (set.band_axis(), set.mean_down()) {
        (Some(axis), _) => (axis, axis),
        (None, Some(mean_down)) => (principal.normal, mean_down),
        (None, None) => (principal.normal, principal.normal),
    };
    let normal = if normal.dot(&mean_down) < 0.0 {
        -normal
    } else {
        normal
    };
    let cos_normal_down = normal.dot(&mean_down);
    if cos_normal_down < BAND_AXIS_MIN_COS {
        return Vec::new();
    }
    let helper = if normal.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let first = normal.cross(&helper).normalize();
    let second = normal.cross(&first);
    let projected: Vec<Vector2<f64>> = set
        .mag_ut
        .iter()
        .map(|m| Vector2::new(first.dot(&(m - mean_ut)), second.dot(&(m - mean_ut))))
        .collect();
    let Ok(plane) = fit_ellipse(&projected) else {
        return Vec::new();
    };
    let basis = Matrix3::from_columns(&[first, second, normal]);
    let block = Matrix3::new(
        plane.transform[(0, 0)],
        plane.transform[(0, 1)],
        0.0,
        plane.transform[(1, 0)],
        plane.transform[(1, 1)],
        0.0,
        0.0,
        0.0,
        plane.transform.determinant().abs().sqrt(),
    );
    let shape = basis * block * basis.transpose();
    let in_plane_centre_ut = mean_ut + first * plane.center_ut.x + second * plane.center_ut.y;
    let inclinations_deg: Vec<f64> = match options.field {
        Some(prior) => vec![prior.inclination_deg],
        None => vec![60.0, -60.0, 20.0, -20.0],
    };
    inclinations_deg
        .into_iter()
        .map(|inclination_deg| {
            let (sin_dip, cos_dip) = inclination_deg.to_radians().sin_cos();
            let horizontal_ut = plane.radius_ut;
            // With the in-plane radius as the horizontal field, the field and the
            // vertical follow from the dip; the band's height above the hard iron is
            // the vertical field seen along the normal.
            let field_ut = horizontal_ut / cos_dip.max(0.05);
            let vertical_ut = field_ut * sin_dip;
            let w_normal = block[(2, 2)];
            let height_ut = vertical_ut / (w_normal * cos_normal_down);
            State {
                hard_iron_ut: in_plane_centre_ut - normal * height_ut,
                correction: shape,
                vertical_ut,
                field_ut,
            }
        })
        .collect()
}

/// Kåsa's (1976) linear sphere fit: `|m|² = 2·cᵀm + k`.
fn kasa_sphere(mag_ut: &[Vector3<f64>]) -> Option<(Vector3<f64>, f64)> {
    let n = mag_ut.len() as f64;
    let mean_ut: Vector3<f64> = mag_ut.iter().sum::<Vector3<f64>>() / n;
    let mut ata = nalgebra::Matrix4::<f64>::zeros();
    let mut atb = nalgebra::Vector4::<f64>::zeros();
    for m in mag_ut {
        let d = m - mean_ut;
        let row = nalgebra::Vector4::new(2.0 * d.x, 2.0 * d.y, 2.0 * d.z, 1.0);
        ata += row * row.transpose();
        atb += row * d.norm_squared();
    }
    let solution = ata.cholesky()?.solve(&atb);
    let centre = Vector3::new(solution[0], solution[1], solution[2]);
    let radius_sq = solution[3] + centre.norm_squared();
    (radius_sq > 0.0).then(|| (mean_ut + centre, radius_sq.sqrt()))
}
