//! The foundations every layer stands on, none of them about compasses: angles,
//! the calendar, English words, sorting by a float key, statistics, random numbers,
//! geodesy and the thread pool.

pub mod angle;
pub mod calendar;
pub mod geodesy;
pub mod par;
pub mod rng;
pub mod sort;
pub mod stats;
pub mod words;
