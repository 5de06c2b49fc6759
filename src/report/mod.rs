//! Outputs: atomic output folders, figures, tables and the files each command writes.

pub mod compare;
pub mod contour;
pub mod figures;
pub mod fit;
pub mod geodesics;
pub mod html;
pub mod identify;
pub mod mass;
pub mod output;
pub mod parts;
pub mod plot;
pub mod simulate;
pub mod sweep;
pub mod tune;

/// Numbers as springfit's tables, legends and messages write them.
///
pub use crate::units::{deg, sci};
