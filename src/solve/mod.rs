//! Least-squares solvers that know columns, groups of columns, equalities and inequalities, and
//! nothing of springs, cams or catalogues: normal equations ([`lsq`]), non-negative least
//! squares ([`nnls`]), the same with exact equality rows on an updated factor
//! ([`lawson_hanson`]), the Clarabel QP with exact constraints ([`qp`]), the same QP on a working
//! set for many candidates ([`screen`]) and the choice of at most K items ([`selection`]).
//! The fit turns candidates into these columns.

pub mod constraint;
pub mod dense;
pub mod lawson_hanson;
pub mod lsq;
pub mod nnls;
pub mod qp;
pub mod screen;
pub mod selection;

pub use constraint::LinearGroup;
