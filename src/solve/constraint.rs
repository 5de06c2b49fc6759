//! Named groups of linear constraints: what the solvers enforce and what an infeasibility
//! message names.

use nalgebra::{DMatrix, DVector};

/// A group of linear equations or inequalities in k with a name for messages.
#[derive(Debug, Clone)]
pub struct LinearGroup {
    /// Name used in messages ("equilibrium gradient", …).
    pub name: String,
    /// What the group asks for, in words (for infeasibility messages).
    pub description: String,
    /// Coefficients (rows × columns).
    pub matrix: DMatrix<f64>,
    /// Right-hand side.
    pub rhs: DVector<f64>,
}
