//! Outputs: atomic output folders, figures, tables and the files each command writes.

pub mod contour;
pub mod output;
pub mod plot;
