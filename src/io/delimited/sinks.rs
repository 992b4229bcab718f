//! Where the delimited reader's samples go ([`super`]): a recording's streams, or (large
//! files, `parallel.rs`) one part's share of columns prepared for the whole file.

use nalgebra::{Vector2, Vector3};

use super::reader::Plan;
use crate::io::recording::{Attitude, GnssFix, Recording, Stream};

/// Where one stream's samples go.
pub(super) trait SampleSink<T> {
    fn push(&mut self, t_s: f64, value: T);
}

impl<T> SampleSink<T> for Stream<T> {
    /// [`Stream::push`], always inlined into the hot loop.
    #[inline(always)]
    fn push(&mut self, t_s: f64, value: T) {
        self.t_s.push(t_s);
        self.values.push(value);
    }
}

/// The streams one row's samples go to.
pub(super) struct Targets<'a, V, S, P> {
    pub(super) acc: &'a mut V,
    pub(super) gyro: &'a mut V,
    pub(super) mag: &'a mut V,
    pub(super) temp: &'a mut S,
    pub(super) pressure: &'a mut S,
    pub(super) ref_heading: &'a mut S,
    pub(super) ref_position: &'a mut P,
    pub(super) gnss: &'a mut Stream<GnssFix>,
    pub(super) attitude: &'a mut Stream<Attitude>,
}

/// Where a reader's samples go: a recording, or (native, large files) one part's share
/// of columns prepared for the whole file.
pub(super) trait SampleSinks {
    type Vector: SampleSink<Vector3<f64>>;
    type Scalar: SampleSink<f64>;
    type Position: SampleSink<Vector2<f64>>;

    fn targets(&mut self) -> Targets<'_, Self::Vector, Self::Scalar, Self::Position>;

    /// Makes room for `n_rows` samples in each stream the plan fills.
    fn reserve_rows(&mut self, plan: &Plan, n_rows: usize);
}

impl SampleSinks for Recording {
    type Vector = Stream<Vector3<f64>>;
    type Scalar = Stream<f64>;
    type Position = Stream<Vector2<f64>>;

    #[inline(always)]
    fn targets(&mut self) -> Targets<'_, Self::Vector, Self::Scalar, Self::Position> {
        Targets {
            acc: &mut self.acc_in_body_mps2,
            gyro: &mut self.gyro_in_body_radps,
            mag: &mut self.mag_in_body_ut,
            temp: &mut self.temp_c,
            pressure: &mut self.pressure_hpa,
            ref_heading: &mut self.ref_heading_rad,
            ref_position: &mut self.ref_position_en_m,
            gnss: &mut self.gnss,
            attitude: &mut self.attitude,
        }
    }

    fn reserve_rows(&mut self, plan: &Plan, n_rows: usize) {
        fn reserve<T>(stream: &mut Stream<T>, planned: bool, n_rows: usize) {
            if planned {
                stream.t_s.reserve_exact(n_rows);
                stream.values.reserve_exact(n_rows);
            }
        }
        let filled = plan.filled_streams();
        reserve(&mut self.acc_in_body_mps2, filled.acc, n_rows);
        reserve(&mut self.gyro_in_body_radps, filled.gyro, n_rows);
        reserve(&mut self.mag_in_body_ut, filled.mag, n_rows);
        reserve(&mut self.temp_c, filled.temp, n_rows);
        reserve(&mut self.pressure_hpa, filled.pressure, n_rows);
        reserve(&mut self.ref_heading_rad, filled.ref_heading, n_rows);
        reserve(&mut self.ref_position_en_m, filled.ref_position, n_rows);
    }
}

/// Which of the dense streams a plan fills (the ones room is made for).
#[derive(Debug, Clone, Copy)]
pub(super) struct FilledStreams {
    pub(super) acc: bool,
    pub(super) gyro: bool,
    pub(super) mag: bool,
    pub(super) temp: bool,
    pub(super) pressure: bool,
    pub(super) ref_heading: bool,
    pub(super) ref_position: bool,
}
