//! The robot model: a serial chain of revolute joints.
//!
//! Everything downstream (geodesics, the log map, the region check, the fit, the controllers and
//! the simulation) sees a robot only through [`Chain`]: its mass matrix M(q), the derivatives of M,
//! the Coriolis term, the gravity potential and the right-hand sides of the geodesic and
//! Jacobi-field equations. Two kinds of chain provide them:
//!
//! - [`PlanarChain`] (`planar.rs`): links typed into the design file, all joint axes parallel;
//!   exact closed forms in cosines of joint-angle sums, the fastest evaluation.
//! - [`SpatialChain`] (`spatial.rs`): joint axes in any direction and gravity in 3-D, usually
//!   read from a URDF (`urdf.rs`); M by the composite-rigid-body algorithm, the rest by recursive
//!   Newton–Euler, derivatives exact.
//!
//! Both answer with the same units and conventions, so one enum with the same methods is all the
//! rest of the crate needs to know.

mod planar;
mod spatial;
pub mod urdf;

use nalgebra::{DMatrix, DVector};

pub use planar::{Link, PlanarChain};
pub use spatial::{Body, MAX_BODIES, SpatialChain};

use crate::numerics::linalg;

/// A mass carried by a moving link: a part of the springs' hardware (a spring, a pulley, a
/// length of cable) that moves with the link and so adds to the arm's inertia and gravity load.
/// It is a point: its own inertia about its centre is left out (for a spring or a pulley of a
/// few centimetres on links of decimetres that is below a percent of its share).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointMass {
    /// The link it rides on: 0 is the first moving link (joint 1's), n − 1 the last.
    pub link: usize,
    /// Where it sits in that link's frame, m: a planar link's frame has x along the link from its
    /// joint (only x is used); a spatial body's is its joint frame, as the URDF gives it.
    pub position: [f64; 3],
    /// Its mass, kg.
    pub mass: f64,
}

/// A serial chain of revolute joints: the robot springfit designs for.
#[derive(Debug, Clone)]
pub enum Chain {
    /// All joint axes parallel, links typed into the design file (closed forms).
    Planar(PlanarChain),
    /// Joint axes in any direction (CRBA and RNEA).
    Spatial(SpatialChain),
}

/// Scratch space for the allocation-free evaluations ([`Chain::geodesic_rhs`] and friends).
#[derive(Debug, Clone)]
pub struct Workspace {
    /// Mass matrix, then its Cholesky factor (column-major).
    pub(crate) m: Vec<f64>,
    /// The mass matrix itself after [`Chain::prepare`].
    pub(crate) m_full: Vec<f64>,
    pub(crate) sin: Vec<f64>,
    pub(crate) cos: Vec<f64>,
    pub(crate) h: Vec<f64>,
    pub(crate) a: Vec<f64>,
    pub(crate) tmp: Vec<f64>,
    pub(crate) tmp2: Vec<f64>,
    /// Link-angle rates φ̇ = S q̇ (planar chains).
    pub(crate) rate: Vec<f64>,
    /// n × n scratch matrices.
    pub(crate) da_dq: Vec<f64>,
    pub(crate) da_dqd: Vec<f64>,
}

impl Workspace {
    /// M(q) from the last [`Chain::prepare`] (symmetric, so row- and column-major agree).
    pub fn mass(&self) -> &[f64] {
        &self.m_full
    }

    /// h(q, q̇) = C(q, q̇) q̇ from the last [`Chain::prepare`].
    pub fn coriolis(&self) -> &[f64] {
        &self.h
    }

    /// Solves M x = b in place with the factor from the last [`Chain::prepare`].
    pub fn solve(&self, b: &mut [f64]) {
        linalg::cholesky_solve(&self.m, self.h.len(), b);
    }

    /// Scratch for n joints and `trig` entries of sines and cosines (n² for a planar chain).
    pub(crate) fn new(n: usize, trig: usize) -> Self {
        Workspace {
            m: vec![0.0; n * n],
            m_full: vec![0.0; n * n],
            sin: vec![0.0; trig],
            cos: vec![0.0; trig],
            h: vec![0.0; n],
            a: vec![0.0; n],
            tmp: vec![0.0; n],
            tmp2: vec![0.0; n],
            rate: vec![0.0; n],
            da_dq: vec![0.0; n * n],
            da_dqd: vec![0.0; n * n],
        }
    }
}

/// Calls the same method on whichever chain this is.
macro_rules! each {
    ($self:ident, $c:ident => $e:expr) => {
        match $self {
            Chain::Planar($c) => $e,
            Chain::Spatial($c) => $e,
        }
    };
}

impl Chain {
    /// A planar chain (see [`PlanarChain::new`]).
    pub fn new(links: Vec<Link>, gravity: [f64; 2]) -> Self {
        Chain::Planar(PlanarChain::new(links, gravity))
    }

    /// The paper's double pendulum (see [`PlanarChain::paper_double_pendulum`]).
    pub fn paper_double_pendulum() -> Self {
        Chain::Planar(PlanarChain::paper_double_pendulum())
    }

    /// The planar chain, if this is one.
    pub fn planar(&self) -> Option<&PlanarChain> {
        match self {
            Chain::Planar(c) => Some(c),
            Chain::Spatial(_) => None,
        }
    }

    /// The spatial chain, if this is one.
    pub fn spatial(&self) -> Option<&SpatialChain> {
        match self {
            Chain::Spatial(c) => Some(c),
            Chain::Planar(_) => None,
        }
    }

    /// Joint names: the URDF's for a spatial chain, `q1` … `qn` for a planar one.
    pub fn joint_names(&self) -> Vec<String> {
        match self {
            Chain::Planar(c) => (1..=c.dof()).map(|i| format!("q{i}")).collect(),
            Chain::Spatial(c) => c.bodies().iter().map(|b| b.joint.clone()).collect(),
        }
    }

    /// Number of joints n.
    pub fn dof(&self) -> usize {
        each!(self, c => c.dof())
    }

    /// Where joint `i` (0-based) sits: on the link before it (its index) at that link's frame's
    /// point (m), or None for joint 1, which sits on the base. What a part mounted on a joint's
    /// axis rides on: every joint before it moves it, the joint itself does not.
    pub fn joint_mount(&self, i: usize) -> Option<(usize, [f64; 3])> {
        if i == 0 || i >= self.dof() {
            return None;
        }
        Some((
            i - 1,
            match self {
                Chain::Planar(c) => [c.links()[i - 1].length, 0.0, 0.0],
                Chain::Spatial(c) => c.bodies()[i].translation.into(),
            },
        ))
    }

    /// The point where link `t` ends (the next joint's mount, or for the last link its length
    /// or the drawn tip), in its frame, m: what a cable along the link runs to.
    pub fn link_end(&self, t: usize) -> [f64; 3] {
        match (self.joint_mount(t + 1), self) {
            (Some((_, p)), _) => p,
            (None, Chain::Planar(c)) => [c.links().get(t).map_or(0.0, |l| l.length), 0.0, 0.0],
            (None, Chain::Spatial(c)) => c.tip(),
        }
    }

    /// The same chain with `masses` added to its links: each link's mass, centre of mass and
    /// inertia (parallel-axis theorem) updated, so that M(q), its derivatives and gravity are
    /// those of the arm carrying them. A mass on a link beyond the chain is ignored (the caller
    /// places on links `0..dof`); masses on the base are not passed at all.
    pub fn with_point_masses(&self, masses: &[PointMass]) -> Chain {
        match self {
            Chain::Planar(c) => Chain::Planar(c.with_point_masses(masses)),
            Chain::Spatial(c) => Chain::Spatial(c.with_point_masses(masses)),
        }
    }

    /// Whether gravity acts.
    pub fn has_gravity(&self) -> bool {
        each!(self, c => c.has_gravity())
    }

    /// Scratch space sized for this chain.
    pub fn workspace(&self) -> Workspace {
        each!(self, c => c.workspace())
    }

    /// Points to draw the arm in a plane: the base, each further joint and the tip, in m. A
    /// planar chain draws in its own plane, a spatial one in a plane it chooses
    /// ([`SpatialChain::joint_positions`]).
    pub fn joint_positions(&self, q: &[f64]) -> Vec<[f64; 2]> {
        each!(self, c => c.joint_positions(q))
    }

    /// The mass matrix M(q).
    pub fn mass_matrix(&self, q: &DVector<f64>) -> DMatrix<f64> {
        each!(self, c => c.mass_matrix(q))
    }

    /// The partial derivatives ∂M/∂q_p, p = 1..n.
    pub fn mass_matrix_derivatives(&self, q: &DVector<f64>) -> Vec<DMatrix<f64>> {
        each!(self, c => c.mass_matrix_derivatives(q))
    }

    /// Christoffel symbols of the first kind, Γ_{ijk} = ½(∂_k M_ij + ∂_j M_ik − ∂_i M_jk),
    /// returned as `gamma[i][(j, k)]`.
    pub fn christoffel(&self, q: &DVector<f64>) -> Vec<DMatrix<f64>> {
        each!(self, c => c.christoffel(q))
    }

    /// The Coriolis/centrifugal vector h(q, q̇) = C(q, q̇) q̇.
    pub fn coriolis(&self, q: &DVector<f64>, qd: &DVector<f64>) -> DVector<f64> {
        each!(self, c => c.coriolis(q, qd))
    }

    /// A bound on |U_g|, ∇U_g and ∇²U_g over all configurations (infinite on overflow).
    pub fn gravity_bound(&self) -> f64 {
        each!(self, c => c.gravity_bound())
    }

    /// Gravity potential U_g(q) in J.
    pub fn gravity_potential(&self, q: &[f64]) -> f64 {
        each!(self, c => c.gravity_potential(q))
    }

    /// ∂U_g/∂q in N·m.
    pub fn gravity_gradient(&self, q: &[f64]) -> DVector<f64> {
        each!(self, c => c.gravity_gradient(q))
    }

    /// ∂U_g/∂q into `out` without allocating.
    pub fn gravity_gradient_into(&self, q: &[f64], out: &mut [f64]) {
        each!(self, c => c.gravity_gradient_into(q, out))
    }

    /// ∂²U_g/∂q² in N·m/rad.
    pub fn gravity_hessian(&self, q: &[f64]) -> DMatrix<f64> {
        each!(self, c => c.gravity_hessian(q))
    }

    /// Kinetic energy ½ q̇ᵀ M q̇.
    pub fn kinetic_energy(&self, q: &DVector<f64>, qd: &DVector<f64>) -> f64 {
        0.5 * qd.dot(&(self.mass_matrix(q) * qd))
    }

    /// Right-hand side of the geodesic equation as a first-order system, y = (q, q̇):
    /// ẏ = (q̇, −M⁻¹ h(q, q̇)). Allocation-free; fails only if M is not positive definite.
    pub fn geodesic_rhs(&self, ws: &mut Workspace, y: &[f64], dy: &mut [f64]) -> bool {
        each!(self, c => c.geodesic_rhs(ws, y, dy))
    }

    /// Right-hand side of the geodesic equation with its variational (Jacobi-field) equations:
    /// y = (q, q̇, Φ_q, Φ_q̇) where Φ = ∂(q, q̇)/∂(initial velocity) is stored column-major
    /// (n × n each). Φ̇_q = Φ_q̇, Φ̇_q̇ = ∂a/∂q Φ_q + ∂a/∂q̇ Φ_q̇ with a = −M⁻¹h.
    pub fn variational_rhs(&self, ws: &mut Workspace, y: &[f64], dy: &mut [f64]) -> bool {
        each!(self, c => c.variational_rhs(ws, y, dy))
    }

    /// Evaluates M(q) and h(q, q̇) into the workspace and factors M. Returns false if M is not
    /// positive definite.
    pub fn prepare(&self, ws: &mut Workspace, q: &[f64], qd: &[f64]) -> bool {
        each!(self, c => c.prepare(ws, q, qd))
    }

    /// Evaluates and factors M(q) into the workspace (no Coriolis term): for repeated solves
    /// M x = b at one configuration ([`Workspace::solve`]).
    pub fn factor_mass(&self, ws: &mut Workspace, q: &[f64]) -> bool {
        each!(self, c => c.factor_mass(ws, q))
    }

    /// Joint accelerations of the full dynamics M q̈ + h(q, q̇) = τ for a given total torque τ.
    pub fn acceleration(&self, ws: &mut Workspace, q: &[f64], qd: &[f64], tau: &[f64], qdd: &mut [f64]) -> bool {
        each!(self, c => c.acceleration(ws, q, qd, tau, qdd))
    }
}
