//! [`EllipsoidAccumulator`], the streaming half of the fit (step 1 of the method in
//! [`super`]): samples added one at a time, in slices, or merged from other accumulators
//! into the power sums of `moments.rs`; and its `solve`, the algebraic fit of Li and
//! Griffiths (2004) without the refinement, which the live panel and the 3D fit's
//! starts ([`crate::fit::ellipsoid`]) use.

use nalgebra::Vector3;

use super::*;

/// The streaming half of the fit: one pass over the samples, in any order and any
/// chunking, merged across chunks or threads.
#[derive(Debug, Clone, PartialEq)]
pub struct EllipsoidAccumulator {
    /// The first finite sample: the power sums are of offsets from it, which keeps
    /// their magnitudes near the field's rather than the hard iron's.
    pub(super) origin_ut: Option<Vector3<f64>>,
    /// `Σ d^α` over the finite samples, in the order of [`EXPONENTS`]; the first is
    /// their count.
    pub(super) moments: [f64; N_MOMENTS],
    pub(super) n_seen: usize,
    /// The first sample refused (not finite, or out of any sensor's range), as the
    /// error [`solve`](Self::solve) will return.
    pub(super) first_rejected: Option<EllipsoidError>,
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
}
