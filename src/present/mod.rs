//! What a person reads and sees: the verdict (the answer first), the words, CSV and
//! HTML of the report, and the plots, drawn on any plotters backend.

pub mod plot;
pub mod report;
pub mod verdict;
