//! Studies of a design: sensitivity sweeps (parasitic springs, manufacturing tolerance, stock
//! rates), comparisons of fits and the accuracy a spring budget or a region size buys.

pub mod compare;
pub mod sweep;
