//! A deterministic simulator: logs with known truth.
//!
//! [`walk`] simulates a pedestrian with a phone held in front of them: a calibration
//! circle, then straight legs and turns. The magnetometer sees the Earth's field through
//! hard and soft iron and noise (the model of Eq. 2-3 and 5 of the 2007 paper); the
//! accelerometer sees gravity, the tilt of the hand, and a vertical bounce at the step
//! frequency. The true heading and position are written as the reference columns.
//! [`gait`] is the varied gait of the PDR scenario (`WalkConfig::pdr_walk`): steps
//! whose frequency and length vary, accelerations that follow Weinberg's relation, and
//! the truth of every step. [`dance`] is the sphere "calibration dance" of a board on a
//! breadboard, printed as MotionCal `Raw:` lines, with the Eq. 5 distortion (hard iron,
//! a symmetric soft-iron matrix) as its truth.
//!
//! [`nmea`] writes a simulated log as NMEA 0183 and [`field`] makes magnetometer samples
//! of known distortion for the fits' tests.
//!
//! Randomness comes from [`crate::base::rng::SplitMix64`], written out in the crate
//! rather than taken from a dependency so that a seed gives the same log forever, on
//! every platform: the demo in `assets/` depends on it.

pub mod dance;
pub mod field;
pub mod gait;
pub mod nmea;
pub mod walk;
