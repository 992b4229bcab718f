//! Heading deviation models learnt from a reference heading on top of a field
//! calibration: the PDR paper's Fourier series (Eq. 12, batch and recursive) and the
//! 2007 paper's five-input network.

pub mod fourier;
pub mod network;
pub mod neural;
pub mod rls;
