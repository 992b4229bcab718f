//! The simulated GNSS receiver's output: at its rate, outside its outage, a fix written
//! into the sample's row (position with noise and any multipath's wandering error, the
//! accuracy it reports, speed, and the course over ground).

use nalgebra::{Vector2, Vector3};

use super::trajectory::Sample;
use super::{GnssSim, WalkConfig};
use crate::base::angle::wrap_to_2pi;
use crate::base::geodesy::{Geodetic, LocalFrame};
use crate::base::rng::SplitMix64;
use crate::io::canonical_csv::CanonicalRow;

/// A walk's receiver, with the multipath error it carries from fix to fix.
pub(super) struct Receiver {
    gnss: GnssSim,
    frame: LocalFrame,
    /// A fix every this many samples.
    every: usize,
    multipath_error_m: Vector2<f64>,
}

impl Receiver {
    /// The receiver of `config`, if the walk has one.
    pub(super) fn new(config: &WalkConfig) -> Option<Receiver> {
        config.gnss.map(|gnss| Receiver {
            gnss,
            frame: LocalFrame::at(Geodetic {
                lat_deg: gnss.origin_lat_deg,
                lon_deg: gnss.origin_lon_deg,
                alt_m: 0.0,
            }),
            every: (config.sample_rate_hz / gnss.rate_hz).round().max(1.0) as usize,
            multipath_error_m: Vector2::zeros(),
        })
    }

    /// Writes the fix of `sample` into `row`, where there is one.
    pub(super) fn fix(&mut self, row: &mut CanonicalRow, sample: &Sample, rng: &mut SplitMix64) {
        let (gnss, every, t_s) = (self.gnss, self.every, sample.t_s);
        let in_outage = gnss
            .outage_s
            .is_some_and(|(start_s, end_s)| (start_s..end_s).contains(&t_s));
        let multipath = gnss
            .multipath
            .filter(|multipath| (multipath.start_s..multipath.end_s).contains(&t_s));
        if !sample.idx.is_multiple_of(every) || in_outage {
            return;
        }
        let fix_dt_s = every as f64 * sample.dt_s;
        // The multipath error wanders (first order, 10 s), and is gone after.
        self.multipath_error_m = match multipath {
            Some(multipath) => {
                let keep = (-fix_dt_s / 10.0).exp();
                let drive = multipath.error_m * (1.0 - keep * keep).sqrt();
                self.multipath_error_m * keep + Vector2::new(rng.gaussian(), rng.gaussian()) * drive
            }
            None => Vector2::zeros(),
        };
        let noisy_en_m = sample.position_en_m
            + self.multipath_error_m
            + Vector2::new(rng.gaussian(), rng.gaussian()) * gnss.position_noise_m;
        let position = self
            .frame
            .geodetic_of(Vector3::new(noisy_en_m.x, noisy_en_m.y, 0.0));
        let speed_mps = sample.motion.speed_mps;
        row.lat_deg = Some(position.lat_deg);
        row.lon_deg = Some(position.lon_deg);
        row.gps_hacc_m = Some(multipath.map_or(gnss.hacc_m, |multipath| multipath.hacc_m));
        row.gps_speed_mps = Some(speed_mps + 0.05 * rng.gaussian());
        // A receiver's course follows the velocity: the walking direction.
        let course_noise_deg = gnss.course_noise_deg * if multipath.is_some() { 3.0 } else { 1.0 };
        row.gps_course_deg = Some(
            wrap_to_2pi(sample.heading_rad + course_noise_deg.to_radians() * rng.gaussian())
                .to_degrees(),
        );
    }
}
