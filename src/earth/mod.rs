//! The Earth's field where and when a log was recorded: the World Magnetic Model.

pub mod wmm;
