//! The samples a fit runs on: the magnetometer's, with down and the trust in it at each
//! when the dip is used, evenly thinned to what a fit needs, and what they show before
//! any fit (a band's axis, the mean down).

use super::*;

/// Samples, with the down vectors when the dip is used.
#[derive(Clone, Copy)]
pub(super) struct Samples<'a> {
    pub(super) mag_ut: &'a [Vector3<f64>],
    pub(super) down_in_body: Option<&'a [Vector3<f64>]>,
    /// Each sample's trust in its tilt, 0 to 1 ([`TiltTrusted`]).
    pub(super) dip_trust: Option<&'a [f64]>,
}

/// An owned, evenly thinned copy.
pub(super) struct SampleSet {
    pub(super) mag_ut: Vec<Vector3<f64>>,
    pub(super) down_in_body: Option<Vec<Vector3<f64>>>,
    pub(super) dip_trust: Option<Vec<f64>>,
}

impl Samples<'_> {
    pub(super) fn evenly(&self, max_samples: usize) -> SampleSet {
        let stride = self.mag_ut.len().div_ceil(max_samples).max(1);
        SampleSet {
            mag_ut: self.mag_ut.iter().step_by(stride).copied().collect(),
            down_in_body: self
                .down_in_body
                .map(|down| down.iter().step_by(stride).copied().collect()),
            dip_trust: self
                .dip_trust
                .map(|trust| trust.iter().step_by(stride).copied().collect()),
        }
    }
}

impl SampleSet {
    pub(super) fn uses_dip(&self) -> bool {
        self.down_in_body.is_some()
    }

    pub(super) fn down(&self, idx: usize) -> Option<Vector3<f64>> {
        self.down_in_body
            .as_ref()
            .and_then(|down| down.get(idx).copied())
    }

    /// Whether the samples' tilt is mostly not trusted (their mean trust under
    /// [`TRUSTED_TILT`]): the one decision the fit, its plausibility check and its report
    /// share.
    pub(super) fn tilt_untrusted(&self) -> bool {
        let n = self.mag_ut.len().max(1) as f64;
        let mean = (0..self.mag_ut.len())
            .map(|idx| self.dip_trust(idx))
            .sum::<f64>()
            / n;
        self.uses_dip() && mean < TRUSTED_TILT
    }

    /// How far sample `idx`'s tilt is trusted (1 when nothing says otherwise).
    pub(super) fn dip_trust(&self, idx: usize) -> f64 {
        self.dip_trust
            .as_ref()
            .and_then(|trust| trust.get(idx).copied())
            .filter(|trust| trust.is_finite())
            .map_or(1.0, |trust| trust.clamp(0.0, 1.0))
    }

    /// The axis of a band of data, when the samples form one: with the accelerometer,
    /// the mean down when the tilt stays within [`MIN_TILT_FOR_ROTATION_DEG`] (RMS) of
    /// it (a car in its mount, a level turn); without, the samples' own axis when they
    /// lie within [`MAX_LEVEL_BAND_DEG`] of a plane (a level turn assumed level). On a
    /// band, what only tilt shows of a 3D distortion (the band's lean and height, a
    /// rotation about its axis) is decided by the accelerometer's own errors (what is
    /// left of a car's accelerations, vibration, passing vehicles) more than by the
    /// magnetometer: the band model is fitted instead ([`FreeDirections::band`]). A
    /// hand's tilt while walking (3-10°) does show them.
    pub(super) fn band_axis(&self) -> Option<Vector3<f64>> {
        match &self.down_in_body {
            Some(down) => {
                let mean_down = self.mean_down()?;
                let mean_square = down
                    .iter()
                    .map(|u| u.cross(&mean_down).norm_squared())
                    .sum::<f64>()
                    / down.len().max(1) as f64;
                // The magnetometer must agree: a field that sweeps the sphere while the
                // accelerometer stays put is no band (the two are not on one body).
                let plane = principal_plane(&self.mag_ut)?;
                let mag_span_deg = (3f64.sqrt() * plane.spread_ut[2])
                    .atan2(plane.spread_ut[0].hypot(plane.spread_ut[1]))
                    .to_degrees();
                (mean_square.sqrt().asin().to_degrees() < MIN_TILT_FOR_ROTATION_DEG
                    && mag_span_deg < MAX_MAG_BAND_DEG)
                    .then_some(mean_down)
            }
            None => {
                let plane = principal_plane(&self.mag_ut)?;
                let span_deg = (3f64.sqrt() * plane.spread_ut[2])
                    .atan2(plane.spread_ut[0].hypot(plane.spread_ut[1]))
                    .to_degrees();
                // The field points down north of the magnetic equator: +z of a level
                // device.
                let normal = if plane.normal.z < 0.0 {
                    -plane.normal
                } else {
                    plane.normal
                };
                (span_deg < MAX_LEVEL_BAND_DEG).then_some(normal)
            }
        }
    }

    /// The mean down direction (unit), if the dip is used.
    pub(super) fn mean_down(&self) -> Option<Vector3<f64>> {
        let sum: Vector3<f64> = self.down_in_body.as_ref()?.iter().sum();
        (sum.norm() > 0.0).then(|| sum.normalize())
    }
}
