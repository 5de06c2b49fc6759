//! The files springfit reads and writes beside its reports: the bill of materials (`bom.csv`)
//! and the cams' files it names, and the logs of a built arm's motion that `identify` reads.

pub mod bom;
pub mod cam;
pub mod fit_folder;
pub mod log;
pub mod parts;
pub mod stock;

/// For reading back, one line at a time, the CSV files springfit writes (`bom.csv`, `parts.csv`,
/// `compare.csv`, …): the fields unquoted as the writers quoted them.
///
pub use crate::csv::split_csv_line;
