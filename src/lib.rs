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
//!   (Moafipoor et al. 2007, Eq. 4; [`calib::tilt`]).
//! - **hard and soft iron**: magnets and iron carried with the sensor add a constant
//!   offset and stretch the field, so that a full turn traces an off-centre ellipse
//!   instead of a centred circle (Eq. 2-3, 5). Calibration estimates and removes them
//!   ([`calib::minmax`]).
//! - **declination**: magnetic north is not true north; the angle depends on place and
//!   date.
//!
//! ## Conventions used throughout
//!
//! - **Body frame**: x forward, y right, z down (the canonical CSV uses it; importers
//!   convert other devices' axes to it at one place, and record how in an
//!   [`io::SensorFrame`], so that a calibration fitted in body axes is exported in the
//!   sensor's own axes and units: [`calib::export::SensorCalibration`]).
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
//! Everything in this crate except `web` is pure: it takes bytes, text or samples and
//! returns values. It reads no clock, file, global or DOM; the one exception is
//! [`par`], which asks how many threads there are and, in the threaded browser build,
//! holds the Web Worker pool (the runtime's state, not the algorithms'; results never
//! depend on it). The CLI (`src/main.rs`, `src/cli/`) owns files and argv; `web`
//! (wasm32 only) owns the DOM. See `docs/ARCHITECTURE.md`.
//!
//! ## Limits (today)
//!
//! Field-domain calibration (min/max, a tilt-aware ellipse, a 3D ellipsoid,
//! reference-heading least squares) is followed by heading models learned from a
//! reference ([`heading`]: the PDR paper's Fourier model, online too, and the 2007
//! paper's neural network). Tilt comes from the direction of specific force averaged over
//! a second, so fast sway is not compensated (a gyro-aided attitude would). Dead
//! reckoning ([`pdr`]) detects steps, fits a step-length model to GNSS or a known
//! distance, and runs the paper's `[E, N, l, a]` EKF through GNSS outages; it has no
//! map matching, so indoors its heading is only as good as the compass or the device's
//! own yaw.

// The threaded browser build (nightly, `-C target-feature=+atomics`) waits with
// `memory.atomic.wait32` in its workers (`par::pool`).
#![cfg_attr(
    all(target_arch = "wasm32", target_feature = "atomics"),
    feature(stdarch_wasm_atomic_wait)
)]

pub mod analysis;
pub mod angle;
pub mod attitude;
pub mod calib;
pub mod calibration;
pub mod civil;
pub mod english;
pub mod geo;
pub mod heading;
pub mod io;
pub mod live;
pub mod nn;
pub mod order;
pub mod par;
pub mod pdr;
pub mod pipeline;
pub mod plot;
pub mod recording;
pub mod reference;
pub mod report;
pub mod sim;
pub mod stats;
pub mod verdict;

#[cfg(target_arch = "wasm32")]
pub mod web;
