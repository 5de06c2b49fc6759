//! The planar serial chain of revolute links and its closed forms.
//!
//! Coordinates follow `docs/theory.md`: q₁ is the absolute angle of link 1 (from the x axis), qᵢ for
//! i > 1 the angle of link i relative to link i−1. The absolute angle of link i is therefore
//! φᵢ = q₁ + … + qᵢ, φ = S q with S the lower-triangular matrix of ones.
//!
//! # Two forms of the same closed forms
//!
//! The centre of mass of link i moves with velocity Σ_{t ≤ i} r_{it} φ̇_t e⊥(φ_t), where r_{it} is
//! the length of link t (t < i) or the centre-of-mass distance of link i (t = i). The kinetic
//! energy in link angles is therefore ½ φ̇ᵀ (K ∘ C(φ)) φ̇ with one constant symmetric matrix
//! K_{tu} = Σ_{i ≥ max(t,u)} mᵢ r_{it} r_{iu} + δ_{tu} I_t and C_{tu} = cos(φ_t − φ_u), and
//! M(q) = Sᵀ (K ∘ C) S. Every entry of M is a constant plus a sum of cos(φ_b − φ_a) over link
//! pairs a < b, and φ_b − φ_a = q_{a+1} + … + q_b is a sum of joint angles. Two evaluations of M,
//! ∂M/∂q, the Coriolis term and the Jacobians of the variational equations follow, both exact and
//! allocation-free (the geodesic integrator calls them millions of times):
//!
//! - the **pair form** (`pairs.rs`) stores one constant n × n matrix per link pair, so that
//!   M = M₀ + Σ W_{ab} cos(φ_b − φ_a): one `sin_cos` per pair and O(n⁴) arithmetic;
//! - the **link-angle form** (`link_angles.rs`) works with K itself: the Coriolis term in link
//!   angles is h^φ_s = Σ_t K_{st} sin(φ_s − φ_t) φ̇_t², h = Sᵀ h^φ, and the Jacobians are Sᵀ (·) S
//!   of n × n link-angle matrices, each a 2-D suffix sum: n − 1 `sin_cos` calls and O(n²)
//!   arithmetic besides the O(n³) Cholesky factor and Jacobi-field product.
//!
//! Chains of up to [`PAIR_FORM_MAX_JOINTS`] joints use the pair form, longer ones the link-angle
//! form. The two agree to rounding (tested), but not bit for bit, and a fit that selects a few
//! springs among hundreds can take another path on last-bit differences: the two- and three-joint
//! designs the documentation quotes were fitted with the pair form, which at those sizes is as
//! fast (two joints: the log map 30 µs a point against 37 µs). From four joints on the link-angle
//! form wins and the gap grows: the seven-link chain's region check takes 3.8 s against 8.5 s on
//! one thread (`SCALING_CHECK=1 cargo bench --bench scaling`).

mod link_angles;
mod pairs;

use nalgebra::{DMatrix, DVector};

use self::link_angles::LinkAngleForm;
use self::pairs::PairForm;
use super::Workspace;
use crate::numerics::linalg;

/// The largest chain evaluated in the pair form (see the module doc).
pub(super) const PAIR_FORM_MAX_JOINTS: usize = 3;

/// One rigid link of the chain.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Link {
    /// Mass in kg.
    pub mass: f64,
    /// Length from this joint to the next, in m.
    pub length: f64,
    /// Distance of the centre of mass from this link's joint along the link, in m.
    pub com: f64,
    /// Moment of inertia about the centre of mass, in kg·m².
    pub inertia: f64,
}

/// Which form evaluates the dynamics (see the module doc).
#[derive(Debug, Clone)]
enum Form {
    Pairs(PairForm),
    LinkAngles(LinkAngleForm),
}

/// A planar serial chain of n ≥ 1 revolute links with optional gravity.
#[derive(Debug, Clone)]
pub struct PlanarChain {
    links: Vec<Link>,
    gravity: [f64; 2],
    form: Form,
    /// G_t = Σ_{i ≥ t} m_i r_{it}: the mass-weighted lever of link t's direction in U_g.
    gravity_lever: Vec<f64>,
}

impl PlanarChain {
    /// Builds the chain. `gravity` is the gravity vector in the plane of the arm in m/s²
    /// (e.g. `[0.0, -9.81]`); the caller validates that masses and lengths are positive.
    pub fn new(links: Vec<Link>, gravity: [f64; 2]) -> Self {
        let pairs = links.len() <= PAIR_FORM_MAX_JOINTS;
        Self::with_form(links, gravity, pairs)
    }

    /// The chain in the pair form (`pairs`) or the link-angle form, whatever its length.
    fn with_form(links: Vec<Link>, gravity: [f64; 2], pairs: bool) -> Self {
        let n = links.len();
        let r = |i: usize, t: usize| {
            if t < i { links[t].length } else { links[i].com }
        };
        let form =
            if pairs { Form::Pairs(PairForm::new(&links, r)) } else { Form::LinkAngles(LinkAngleForm::new(&links, r)) };
        let gravity_lever = (0..n).map(|t| (t..n).map(|i| links[i].mass * r(i, t)).sum()).collect();
        PlanarChain { links, gravity, form, gravity_lever }
    }

    /// The paper's double pendulum (appendix, no gravity): m = 1 kg, l = 2 m, centre of mass at
    /// 1 m, I = 1 kg·m² for both links. M₁₁ = 8 + 4 cos q₂, M₁₂ = 2 + 2 cos q₂, M₂₂ = 2.
    pub fn paper_double_pendulum() -> Self {
        let link = Link { mass: 1.0, length: 2.0, com: 1.0, inertia: 1.0 };
        PlanarChain::new(vec![link, link], [0.0, 0.0])
    }

    /// Number of joints n.
    pub fn dof(&self) -> usize {
        self.links.len()
    }

    /// The links, base first.
    pub fn links(&self) -> &[Link] {
        &self.links
    }

    /// The chain with `masses` added to its links ([`super::Chain::with_point_masses`]), each
    /// at its distance along the link (`position[0]`): m' = m + Σ m_p, c' = (m c + Σ m_p x_p)/m',
    /// I' = I + m (c − c')² + Σ m_p (x_p − c')² (parallel-axis theorem), the closed forms
    /// rebuilt from them.
    pub fn with_point_masses(&self, masses: &[super::PointMass]) -> PlanarChain {
        let links = self
            .links
            .iter()
            .enumerate()
            .map(|(t, l)| {
                let here: Vec<(f64, f64)> =
                    masses.iter().filter(|p| p.link == t).map(|p| (p.mass, p.position[0])).collect();
                if here.is_empty() {
                    return *l;
                }
                let mass = l.mass + here.iter().map(|(m, _)| m).sum::<f64>();
                let com = (l.mass * l.com + here.iter().map(|(m, x)| m * x).sum::<f64>()) / mass;
                let inertia = l.inertia
                    + l.mass * (l.com - com).powi(2)
                    + here.iter().map(|(m, x)| m * (x - com).powi(2)).sum::<f64>();
                Link { mass, length: l.length, com, inertia }
            })
            .collect();
        PlanarChain::new(links, self.gravity)
    }

    /// The gravity vector in m/s².
    pub fn gravity(&self) -> [f64; 2] {
        self.gravity
    }

    /// Whether gravity acts (a non-zero gravity vector).
    pub fn has_gravity(&self) -> bool {
        self.gravity != [0.0, 0.0]
    }

    /// Scratch space sized for this chain.
    pub fn workspace(&self) -> Workspace {
        Workspace::new(self.dof(), self.dof() * self.dof())
    }

    /// Absolute link angles φᵢ = q₁ + … + qᵢ.
    pub fn link_angles(&self, q: &[f64]) -> Vec<f64> {
        q.iter()
            .scan(0.0, |acc, &qi| {
                *acc += qi;
                Some(*acc)
            })
            .collect()
    }

    /// Joint positions: the base (0, 0), each further joint, and the tip (n + 1 points).
    pub fn joint_positions(&self, q: &[f64]) -> Vec<[f64; 2]> {
        let mut p = [0.0, 0.0];
        let mut out = vec![p];
        for (link, phi) in self.links.iter().zip(self.link_angles(q)) {
            p = [p[0] + link.length * phi.cos(), p[1] + link.length * phi.sin()];
            out.push(p);
        }
        out
    }

    /// Centre-of-mass positions of the links.
    pub fn com_positions(&self, q: &[f64]) -> Vec<[f64; 2]> {
        let joints = self.joint_positions(q);
        self.links
            .iter()
            .zip(self.link_angles(q))
            .zip(joints)
            .map(|((link, phi), p)| [p[0] + link.com * phi.cos(), p[1] + link.com * phi.sin()])
            .collect()
    }

    fn fill_trig(&self, q: &[f64], ws: &mut Workspace) {
        match &self.form {
            Form::Pairs(f) => f.fill_trig(q, ws),
            Form::LinkAngles(f) => f.fill_trig(q, ws),
        }
    }

    /// M into `ws.m` (after [`Self::fill_trig`]).
    fn fill_mass(&self, ws: &mut Workspace) {
        match &self.form {
            Form::Pairs(f) => f.fill_mass(ws),
            Form::LinkAngles(f) => f.fill_mass(ws, self.dof()),
        }
    }

    /// h(q, q̇) into `ws.h` (after [`Self::fill_trig`]).
    fn coriolis_into(&self, qd: &[f64], ws: &mut Workspace) {
        match &self.form {
            Form::Pairs(f) => f.coriolis(qd, ws),
            Form::LinkAngles(f) => f.coriolis(qd, ws),
        }
    }

    /// The mass matrix M(q).
    pub fn mass_matrix(&self, q: &DVector<f64>) -> DMatrix<f64> {
        let n = self.dof();
        let mut ws = self.workspace();
        self.fill_trig(q.as_slice(), &mut ws);
        self.fill_mass(&mut ws);
        DMatrix::from_column_slice(n, n, &ws.m)
    }

    /// The partial derivatives ∂M/∂q_p, p = 1..n.
    pub fn mass_matrix_derivatives(&self, q: &DVector<f64>) -> Vec<DMatrix<f64>> {
        let mut ws = self.workspace();
        self.fill_trig(q.as_slice(), &mut ws);
        match &self.form {
            Form::Pairs(f) => f.mass_derivatives(&ws, self.dof()),
            Form::LinkAngles(f) => f.mass_derivatives(&ws, self.dof()),
        }
    }

    /// Christoffel symbols of the first kind, Γ_{ijk} = ½(∂_k M_ij + ∂_j M_ik − ∂_i M_jk),
    /// returned as `gamma[i][(j, k)]`.
    pub fn christoffel(&self, q: &DVector<f64>) -> Vec<DMatrix<f64>> {
        let n = self.dof();
        let dm = self.mass_matrix_derivatives(q);
        (0..n).map(|i| DMatrix::from_fn(n, n, |j, k| 0.5 * (dm[k][(i, j)] + dm[j][(i, k)] - dm[i][(j, k)]))).collect()
    }

    /// The Coriolis/centrifugal vector h(q, q̇) = C(q, q̇) q̇ = Ṁ q̇ − ½ ∂(q̇ᵀ M q̇)/∂q.
    pub fn coriolis(&self, q: &DVector<f64>, qd: &DVector<f64>) -> DVector<f64> {
        let mut ws = self.workspace();
        self.fill_trig(q.as_slice(), &mut ws);
        self.coriolis_into(qd.as_slice(), &mut ws);
        DVector::from_vec(ws.h)
    }

    /// |g| Σ_t |G_t|: the largest |U_g| over all configurations in J, which also bounds every entry
    /// of ∇U_g and ∇²U_g (infinite when gravity times the masses and levers overflows).
    pub fn gravity_bound(&self) -> f64 {
        let [gx, gy] = self.gravity;
        gx.hypot(gy) * self.gravity_lever.iter().map(|g| g.abs()).sum::<f64>()
    }

    /// −g: the potential energy of a mass m at p is m (−g)·p (its weight times its height), so an
    /// arm in gravity g = (0, −9.81) hangs down.
    fn lift(&self) -> [f64; 2] {
        [-self.gravity[0], -self.gravity[1]]
    }

    /// Gravity potential U_g(q) = −Σ mᵢ g·cᵢ(q) in J.
    pub fn gravity_potential(&self, q: &[f64]) -> f64 {
        let [gx, gy] = self.lift();
        if gx == 0.0 && gy == 0.0 {
            return 0.0;
        }
        let mut phi = 0.0;
        let mut u = 0.0;
        for (qi, lever) in q.iter().zip(&self.gravity_lever) {
            phi += qi;
            u += lever * (gx * phi.cos() + gy * phi.sin());
        }
        u
    }

    /// ∂U_g/∂q in N·m.
    pub fn gravity_gradient(&self, q: &[f64]) -> DVector<f64> {
        let n = self.dof();
        let [gx, gy] = self.lift();
        let phi = self.link_angles(q);
        // ∂U_g/∂q_p = Σ_{t ≥ p} G_t g·(−sin φ_t, cos φ_t): a suffix sum.
        let mut out = DVector::zeros(n);
        let mut acc = 0.0;
        for t in (0..n).rev() {
            acc += self.gravity_lever[t] * (-gx * phi[t].sin() + gy * phi[t].cos());
            out[t] = acc;
        }
        out
    }

    /// ∂²U_g/∂q² in N·m/rad.
    pub fn gravity_hessian(&self, q: &[f64]) -> DMatrix<f64> {
        let n = self.dof();
        let [gx, gy] = self.lift();
        let phi = self.link_angles(q);
        let mut suffix = vec![0.0; n + 1];
        for t in (0..n).rev() {
            suffix[t] = suffix[t + 1] - self.gravity_lever[t] * (gx * phi[t].cos() + gy * phi[t].sin());
        }
        DMatrix::from_fn(n, n, |p, r| suffix[p.max(r)])
    }

    /// Kinetic energy ½ q̇ᵀ M q̇.
    pub fn kinetic_energy(&self, q: &DVector<f64>, qd: &DVector<f64>) -> f64 {
        0.5 * qd.dot(&(self.mass_matrix(q) * qd))
    }

    /// Right-hand side of the geodesic equation as a first-order system, y = (q, q̇):
    /// ẏ = (q̇, −M⁻¹ h(q, q̇)). Allocation-free; fails only if M is not positive definite.
    pub fn geodesic_rhs(&self, ws: &mut Workspace, y: &[f64], dy: &mut [f64]) -> bool {
        let n = self.dof();
        let (q, qd) = y[..2 * n].split_at(n);
        self.fill_trig(q, ws);
        self.fill_mass(ws);
        self.coriolis_into(qd, ws);
        linalg::geodesic_accel(&mut ws.m, &ws.h, n, qd, dy)
    }

    /// Right-hand side of the geodesic equation with its variational (Jacobi-field) equations:
    /// y = (q, q̇, Φ_q, Φ_q̇) where Φ = ∂(q, q̇)/∂(initial velocity) is stored column-major
    /// (n × n each). Φ̇_q = Φ_q̇, Φ̇_q̇ = ∂a/∂q Φ_q + ∂a/∂q̇ Φ_q̇ with a = −M⁻¹h.
    pub fn variational_rhs(&self, ws: &mut Workspace, y: &[f64], dy: &mut [f64]) -> bool {
        let n = self.dof();
        if !self.geodesic_rhs(ws, y, dy) {
            return false;
        }
        match &self.form {
            Form::Pairs(f) => f.variational(ws, y, dy, n),
            Form::LinkAngles(f) => f.variational(ws, y, dy, n),
        }
        true
    }

    /// Evaluates M(q) and h(q, q̇) into the workspace and factors M, for the closed-loop
    /// dynamics, which need M itself (controllers), solves with it and the Coriolis term. Returns
    /// false if M is not positive definite.
    pub fn prepare(&self, ws: &mut Workspace, q: &[f64], qd: &[f64]) -> bool {
        let n = self.dof();
        self.fill_trig(q, ws);
        self.fill_mass(ws);
        ws.m_full.copy_from_slice(&ws.m);
        self.coriolis_into(qd, ws);
        linalg::cholesky_in_place(&mut ws.m, n)
    }

    /// Evaluates and factors M(q) into the workspace (no Coriolis term): for repeated solves
    /// M x = b at one configuration ([`Workspace::solve`]).
    pub fn factor_mass(&self, ws: &mut Workspace, q: &[f64]) -> bool {
        let n = self.dof();
        self.fill_trig(q, ws);
        self.fill_mass(ws);
        ws.m_full.copy_from_slice(&ws.m);
        linalg::cholesky_in_place(&mut ws.m, n)
    }

    /// ∂U_g/∂q into `out` without allocating.
    pub fn gravity_gradient_into(&self, q: &[f64], out: &mut [f64]) {
        let [gx, gy] = self.lift();
        if gx == 0.0 && gy == 0.0 {
            out.fill(0.0);
            return;
        }
        let n = self.dof();
        let total: f64 = q.iter().sum();
        // φ_t from the top: φ_{n−1} = Σq, φ_{t−1} = φ_t − q_t.
        let mut phi = total;
        let mut acc = 0.0;
        for t in (0..n).rev() {
            acc += self.gravity_lever[t] * (-gx * phi.sin() + gy * phi.cos());
            out[t] = acc;
            phi -= q[t];
        }
    }

    /// Joint accelerations of the full dynamics M q̈ + h(q, q̇) = τ for a given total torque τ
    /// (spring, gravity, damping and control torques already summed by the caller).
    pub fn acceleration(&self, ws: &mut Workspace, q: &[f64], qd: &[f64], tau: &[f64], qdd: &mut [f64]) -> bool {
        let n = self.dof();
        self.fill_trig(q, ws);
        self.fill_mass(ws);
        self.coriolis_into(qd, ws);
        if !linalg::cholesky_in_place(&mut ws.m, n) {
            return false;
        }
        for ((a, t), h) in qdd.iter_mut().zip(tau).zip(&ws.h) {
            *a = t - h;
        }
        linalg::cholesky_solve(&ws.m, n, qdd);
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    fn three_link() -> PlanarChain {
        PlanarChain::new(
            vec![
                Link { mass: 1.3, length: 1.1, com: 0.4, inertia: 0.2 },
                Link { mass: 0.7, length: 0.9, com: 0.5, inertia: 0.05 },
                Link { mass: 0.4, length: 0.6, com: 0.35, inertia: 0.02 },
            ],
            [0.3, -9.81],
        )
    }

    /// Five unequal links: long enough that the angles between links compose over four joints.
    fn five_link() -> PlanarChain {
        let links = (0..5)
            .map(|i| {
                let f = 1.0 + 0.37 * i as f64;
                Link { mass: 1.6 / f, length: 0.9 / f.sqrt(), com: 0.3 + 0.05 * i as f64, inertia: 0.07 / f }
            })
            .collect();
        PlanarChain::new(links, [0.0, -9.81])
    }

    /// Deterministic pseudo-random numbers in [-1, 1] for test points (no RNG crate needed).
    fn points(n: usize, count: usize) -> Vec<DVector<f64>> {
        let mut state = 0x9E37_79B9_7F4A_7C15_u64;
        (0..count)
            .map(|_| {
                DVector::from_fn(n, |_, _| {
                    state ^= state << 13;
                    state ^= state >> 7;
                    state ^= state << 17;
                    (state as f64 / u64::MAX as f64) * 2.0 - 1.0
                })
            })
            .collect()
    }

    /// M from its definition Σ mᵢ JᵢᵀJᵢ + Iᵢ J_ωᵢᵀJ_ωᵢ with finite-difference Jacobians of the
    /// centre-of-mass positions: an independent check of the link-angle construction.
    fn mass_matrix_by_definition(chain: &PlanarChain, q: &DVector<f64>) -> DMatrix<f64> {
        let n = chain.dof();
        let h = 1e-6;
        let mut m = DMatrix::zeros(n, n);
        for (i, link) in chain.links().iter().enumerate() {
            let mut j = DMatrix::zeros(2, n);
            for p in 0..n {
                let mut qp = q.clone();
                let mut qm = q.clone();
                qp[p] += h;
                qm[p] -= h;
                let cp = chain.com_positions(qp.as_slice())[i];
                let cm = chain.com_positions(qm.as_slice())[i];
                j[(0, p)] = (cp[0] - cm[0]) / (2.0 * h);
                j[(1, p)] = (cp[1] - cm[1]) / (2.0 * h);
            }
            let jw = DMatrix::from_fn(1, n, |_, p| if p <= i { 1.0 } else { 0.0 });
            m += j.transpose() * &j * link.mass + jw.transpose() * &jw * link.inertia;
        }
        m
    }

    /// The pair form and the link-angle form are the same closed forms: on a chain of four
    /// links (either form could serve) M, ∂M/∂q, h and both right-hand sides agree to rounding.
    #[test]
    fn pair_and_link_angle_forms_agree() {
        let links = five_link().links()[..4].to_vec();
        let pairs = PlanarChain::with_form(links.clone(), [0.0, -9.81], true);
        let angles = PlanarChain::with_form(links, [0.0, -9.81], false);
        assert!(matches!(pairs.form, Form::Pairs(_)) && matches!(angles.form, Form::LinkAngles(_)));
        let n = 4;
        let pts = points(n, 12);
        for pair in pts.chunks(3) {
            let (q, qd) = (&pair[0] * 3.0, &pair[1] * 2.0);
            assert!((pairs.mass_matrix(&q) - angles.mass_matrix(&q)).amax() < 1e-13);
            for (a, b) in pairs.mass_matrix_derivatives(&q).iter().zip(angles.mass_matrix_derivatives(&q)) {
                assert!((a - b).amax() < 1e-13);
            }
            assert!((pairs.coriolis(&q, &qd) - angles.coriolis(&q, &qd)).amax() < 1e-12);
            let mut y: Vec<f64> = q.iter().chain(qd.iter()).copied().collect();
            y.extend(pair[2].iter().cycle().take(2 * n * n));
            let (mut da, mut db) = (vec![0.0; y.len()], vec![0.0; y.len()]);
            assert!(pairs.variational_rhs(&mut pairs.workspace(), &y, &mut da));
            assert!(angles.variational_rhs(&mut angles.workspace(), &y, &mut db));
            let scale = da.iter().fold(1.0f64, |m, v| m.max(v.abs()));
            for (a, b) in da.iter().zip(&db) {
                assert!((a - b).abs() < 1e-12 * scale, "{a} vs {b}");
            }
        }
    }

    #[test]
    fn paper_mass_matrix_closed_form() {
        let chain = PlanarChain::paper_double_pendulum();
        for q in points(2, 20) {
            let q = q * PI;
            let m = chain.mass_matrix(&q);
            let c = q[1].cos();
            assert!((m[(0, 0)] - (8.0 + 4.0 * c)).abs() < 1e-12);
            assert!((m[(0, 1)] - (2.0 + 2.0 * c)).abs() < 1e-12);
            assert!((m[(1, 0)] - (2.0 + 2.0 * c)).abs() < 1e-12);
            assert!((m[(1, 1)] - 2.0).abs() < 1e-12);
        }
    }

    #[test]
    fn mass_matrix_matches_definition_and_is_spd() {
        for chain in [PlanarChain::paper_double_pendulum(), three_link(), five_link()] {
            let n = chain.dof();
            for q in points(n, 30) {
                let q = q * 3.0;
                let m = chain.mass_matrix(&q);
                let reference = mass_matrix_by_definition(&chain, &q);
                assert!((&m - &reference).amax() < 1e-7, "{m} vs {reference}");
                assert!((&m - m.transpose()).amax() < 1e-14);
                let eig = m.clone().symmetric_eigen();
                assert!(eig.eigenvalues.min() > 0.0, "not positive definite at {q}");
            }
        }
    }

    #[test]
    fn mass_matrix_derivatives_match_finite_differences() {
        for chain in [three_link(), five_link()] {
            let n = chain.dof();
            let h = 1e-6;
            for q in points(n, 10) {
                let q = q * 2.0;
                let dm = chain.mass_matrix_derivatives(&q);
                for p in 0..n {
                    let mut qp = q.clone();
                    let mut qm = q.clone();
                    qp[p] += h;
                    qm[p] -= h;
                    let fd = (chain.mass_matrix(&qp) - chain.mass_matrix(&qm)) / (2.0 * h);
                    assert!((&dm[p] - fd).amax() < 1e-8);
                }
            }
        }
    }

    #[test]
    fn christoffel_symbols_match_finite_differences_of_m() {
        let chain = three_link();
        let h = 1e-6;
        for q in points(3, 10) {
            let gamma = chain.christoffel(&q);
            // Finite-difference ∂M/∂q, then the textbook formula.
            let dm: Vec<DMatrix<f64>> = (0..3)
                .map(|p| {
                    let mut qp = q.clone();
                    let mut qm = q.clone();
                    qp[p] += h;
                    qm[p] -= h;
                    (chain.mass_matrix(&qp) - chain.mass_matrix(&qm)) / (2.0 * h)
                })
                .collect();
            for i in 0..3 {
                for j in 0..3 {
                    for k in 0..3 {
                        let fd = 0.5 * (dm[k][(i, j)] + dm[j][(i, k)] - dm[i][(j, k)]);
                        assert!((gamma[i][(j, k)] - fd).abs() < 1e-8);
                    }
                }
            }
        }
    }

    #[test]
    fn coriolis_equals_christoffel_contraction_and_skew_property() {
        for chain in [three_link(), five_link()] {
            let n = chain.dof();
            let pts = points(n, 20);
            for pair in pts.chunks(2) {
                let (q, qd) = (&pair[0], &pair[1]);
                let gamma = chain.christoffel(q);
                let h = chain.coriolis(q, qd);
                for i in 0..n {
                    let expected = qd.dot(&(&gamma[i] * qd));
                    assert!((h[i] - expected).abs() < 1e-12);
                }
                // Energy identity: q̇ᵀ h = ½ q̇ᵀ Ṁ q̇ (Ṁ − 2C skew-symmetric along q̇).
                let dm = chain.mass_matrix_derivatives(q);
                let mdot = (0..n).fold(DMatrix::zeros(n, n), |acc, p| acc + &dm[p] * qd[p]);
                assert!((qd.dot(&h) - 0.5 * qd.dot(&(mdot * qd))).abs() < 1e-12);
            }
        }
    }

    /// A single link in gravity (0, −9.81) rests hanging straight down, q = −π/2: there the
    /// gravity torque vanishes and the potential is at its minimum; pointing up is a maximum.
    #[test]
    fn a_link_in_gravity_hangs_down() {
        let link = Link { mass: 2.0, length: 1.0, com: 0.5, inertia: 0.1 };
        let chain = PlanarChain::new(vec![link], [0.0, -9.81]);
        let down = [-std::f64::consts::FRAC_PI_2];
        let up = [std::f64::consts::FRAC_PI_2];
        assert!(chain.gravity_gradient(&down)[0].abs() < 1e-12);
        assert!(chain.gravity_hessian(&down)[(0, 0)] > 0.0);
        assert!(chain.gravity_hessian(&up)[(0, 0)] < 0.0);
        assert!((chain.gravity_potential(&down) + 2.0 * 9.81 * 0.5).abs() < 1e-12);
        // Horizontal (q = 0): gravity pulls the link down, a negative torque −∂U/∂q.
        assert!(-chain.gravity_gradient(&[0.0])[0] < 0.0);
    }

    #[test]
    fn gravity_gradient_and_hessian_match_finite_differences() {
        let chain = three_link();
        let h = 1e-6;
        for q in points(3, 10) {
            let g = chain.gravity_gradient(q.as_slice());
            let mut g2 = [0.0; 3];
            chain.gravity_gradient_into(q.as_slice(), &mut g2);
            assert!((g.iter().zip(&g2).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max)) < 1e-13);
            let hess = chain.gravity_hessian(q.as_slice());
            for p in 0..3 {
                let mut qp = q.clone();
                let mut qm = q.clone();
                qp[p] += h;
                qm[p] -= h;
                let fd = (chain.gravity_potential(qp.as_slice()) - chain.gravity_potential(qm.as_slice())) / (2.0 * h);
                assert!((g[p] - fd).abs() < 1e-7);
                let fdg = (chain.gravity_gradient(qp.as_slice()) - chain.gravity_gradient(qm.as_slice())) / (2.0 * h);
                for r in 0..3 {
                    assert!((hess[(r, p)] - fdg[r]).abs() < 1e-7);
                }
            }
        }
        // Potential against the definition −Σ mᵢ g·cᵢ (weight times height).
        let q = [0.3, -0.7, 1.1];
        let direct: f64 =
            chain.links().iter().zip(chain.com_positions(&q)).map(|(l, c)| -l.mass * (0.3 * c[0] - 9.81 * c[1])).sum();
        assert!((chain.gravity_potential(&q) - direct).abs() < 1e-12);
    }

    #[test]
    fn variational_rhs_matches_finite_differences_of_geodesic_rhs() {
        for chain in [three_link(), five_link()] {
            let n = chain.dof();
            let mut ws = chain.workspace();
            let pts = points(n, 8);
            for pair in pts.chunks(2) {
                let (q, qd) = (&pair[0], &pair[1]);
                // Φ = random but fixed.
                let phi: Vec<f64> = (0..2 * n * n).map(|i| ((i * 7 % 11) as f64 - 5.0) / 5.0).collect();
                let mut y: Vec<f64> = q.iter().chain(qd.iter()).copied().collect();
                y.extend_from_slice(&phi);
                let mut dy = vec![0.0; y.len()];
                assert!(chain.variational_rhs(&mut ws, &y, &mut dy));
                // Directional derivative of a(q, q̇) along each column of Φ by finite differences.
                let h = 1e-6;
                for col in 0..n {
                    let dq: Vec<f64> = (0..n).map(|r| phi[r + n * col]).collect();
                    let dqd: Vec<f64> = (0..n).map(|r| phi[n * n + r + n * col]).collect();
                    let shifted = |sign: f64| {
                        let mut ys = vec![0.0; 2 * n];
                        for r in 0..n {
                            ys[r] = q[r] + sign * h * dq[r];
                            ys[n + r] = qd[r] + sign * h * dqd[r];
                        }
                        let mut d = vec![0.0; 2 * n];
                        let mut ws2 = chain.workspace();
                        assert!(chain.geodesic_rhs(&mut ws2, &ys, &mut d));
                        d
                    };
                    let (dp, dm) = (shifted(1.0), shifted(-1.0));
                    for r in 0..n {
                        let fd = (dp[n + r] - dm[n + r]) / (2.0 * h);
                        let an = dy[2 * n + n * n + r + n * col];
                        assert!((fd - an).abs() < 1e-6, "row {r} col {col}: {fd} vs {an}");
                        assert_eq!(dy[2 * n + r + n * col], dqd[r]);
                    }
                }
            }
        }
    }

    #[test]
    fn forward_kinematics_of_the_paper_arm() {
        let chain = PlanarChain::paper_double_pendulum();
        let p = chain.joint_positions(&[0.0, PI / 2.0]);
        assert!((p[1][0] - 2.0).abs() < 1e-12 && p[1][1].abs() < 1e-12);
        assert!((p[2][0] - 2.0).abs() < 1e-12 && (p[2][1] - 2.0).abs() < 1e-12);
        let c = chain.com_positions(&[0.0, PI / 2.0]);
        assert!((c[1][0] - 2.0).abs() < 1e-12 && (c[1][1] - 1.0).abs() < 1e-12);
    }
}
