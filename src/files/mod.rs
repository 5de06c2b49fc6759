//! The files springfit reads and writes beside its reports: the bill of materials (`bom.csv`)
//! and the cams' files it names.

pub mod bom;
pub mod cam;
pub mod fit_folder;
pub mod parts;
pub mod stock;
