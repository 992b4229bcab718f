//! # compass-pdr
//!
//! Magnetometer compass calibration, heading estimation and pedestrian dead reckoning
//! (PDR), as one pure Rust core that runs natively (the `compass-pdr` CLI) and in the
//! browser (WebAssembly, `src/web/`).
//!
//! ## A primer on the domain
//!
//! A 3-axis magnetometer measures the local magnetic field, about 25-65 µT on Earth,
//! in the axes of the device. The Earth's field points to magnetic north and dips into
//! the ground by the inclination angle. Once the horizontal part of the measured field
//! is known, the heading (the angle of the device's forward axis, clockwise from
//! north) follows from one `atan2`. Three things spoil it:
//!
//! - **tilt**: unless the device is level, its x and y axes are not horizontal, so the
//!   vertical field leaks into them. Roll and pitch from the accelerometer undo this
//!   (Moafipoor et al. 2007, Eq. 4; [`attitude::tilt`]).
//! - **hard and soft iron**: magnets and iron carried with the sensor add a constant
//!   offset and stretch the field, so that a full turn traces an off-centre ellipse
//!   instead of a centred circle (Eq. 2-3, 5). Calibration estimates and removes them
//!   ([`fit::minmax`]).
//! - **declination**: magnetic north is not true north; the angle depends on place and
//!   date.
//!
//! ## Conventions used throughout
//!
//! - **Body frame**: x forward, y right, z down (the canonical CSV uses it; importers
//!   convert other devices' axes to it at one place, and record how in an
//!   [`io::SensorFrame`], so that a calibration fitted in body axes is exported in the
//!   sensor's own axes and units: [`fit::export::SensorCalibration`]).
//! - **Navigation frame**: north-east-down for vectors; positions in a local east-north
//!   plane in metres.
//! - **Headings** are clockwise from north. Angles are radians inside the core and
//!   degrees at the edges (CSV, JSON, page); names carry the unit (`_rad`, `_deg`).
//! - **Accelerometer** values are specific force as sensors report it: a level device at
//!   rest reads `acc_z_mps2 ≈ −9.81`.
//! - Other units are in names too: `_ut` (microtesla), `_mps2`, `_radps`, `_s`, `_m`.
//!
//! ## Layers
//!
//! Folders by layer, each built only on those below it (`docs/ARCHITECTURE.md` has the
//! table, which a test holds to the imports): [`base`], [`io`] (with the central
//! [`io::recording::Recording`]), [`earth`], [`sim`], [`attitude`], [`fit`],
//! [`reference`](mod@crate::reference), [`deviation`], [`live`], [`analysis`], [`pdr`],
//! [`pipeline`], [`present`]; then the edges, the CLI (`src/main.rs`, `src/cli/`: files
//! and argv) and `web` (wasm32 only: the DOM). Everything but the edges is pure: it
//! takes bytes, text or samples and returns values, and reads no clock, file, global or
//! DOM; the one exception is [`base::par`], which asks how many threads there are and,
//! in the threaded browser build, holds the Web Worker pool (the runtime's state, not
//! the algorithms'; results never depend on it).
//!
//! ## What it does
//!
//! Field-domain calibration ([`fit`]: min/max, a tilt-aware ellipse, a 3D ellipsoid with
//! the dip and gravity, reference-heading least squares) is followed by heading models
//! learned from a reference ([`deviation`]: the PDR paper's Fourier model, online too, and
//! the 2007 paper's neural network). Tilt comes from a gyro-propagated estimate of down
//! that knows when the accelerometer is not gravity ([`attitude::down`]). Dead reckoning
//! ([`pdr`]) detects steps, takes a step-length model, and smooths the steps with every
//! GNSS fix weighted (or runs the paper's `[E, N, l, a]` EKF), stating a σ for every
//! point; it has no map matching, so indoors its heading is only as good as the compass
//! or the attitude filter.

// The threaded browser build (nightly, `-C target-feature=+atomics`) waits with
// `memory.atomic.wait32` in its workers (`base::par::pool`).
#![cfg_attr(
    all(target_arch = "wasm32", target_feature = "atomics"),
    feature(stdarch_wasm_atomic_wait)
)]

pub mod analysis;
pub mod attitude;
pub mod base;
pub mod deviation;
pub mod earth;
pub mod fit;
pub mod io;
pub mod live;
pub mod pdr;
pub mod pipeline;
pub mod present;
pub mod reference;
pub mod sim;

#[cfg(target_arch = "wasm32")]
pub mod web;
