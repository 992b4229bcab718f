//! One recording analysed: its samples levelled, every calibration fitted and compared
//! on the same split, the heading models on top, and the one choice of the best.

pub mod attitude_track;
pub mod calibration;
pub mod headings;
pub mod levelled;
