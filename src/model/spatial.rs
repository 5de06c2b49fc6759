//! Spatial serial chains of revolute joints: joint axes in any direction, gravity in 3-D.
//!
//! Each joint i has a fixed placement in the frame of body i−1 (the base for the first joint), a
//! unit axis, and carries body i (mass, centre of mass, inertia about the centre of mass, all in
//! body i's frame, which is the joint frame turned by qᵢ about the axis). This is what a URDF
//! describes once fixed and locked joints are merged (`urdf.rs`).
//!
//! # The algorithms (DESIGN.md §4)
//!
//! - M(q) by the composite-rigid-body algorithm, in the base frame: the composite of bodies i…n
//!   is kept as mass, first moment and inertia about the base origin (so a massless composite
//!   needs no centre of mass), and M_ji is the torque on joint j ≤ i of the momentum the
//!   composite has when joint i alone turns at unit rate.
//! - τ = RNEA(q, q̇, q̈) = M q̈ + h(q, q̇) + ∂U_g/∂q by the recursive Newton–Euler algorithm, with
//!   gravity as an upward acceleration of the base.
//! - Christoffel symbols of the first kind by polarising the velocity term c(v) = RNEA(q, v, 0)
//!   without gravity: Γ_{i,jk} = ½ [c(e_j + e_k) − c(e_j) − c(e_k)]_i, and
//!   ∂M_ij/∂q_k = Γ_{i,jk} + Γ_{j,ik}. Exact: no finite differences.
//! - The Jacobi-field right-hand side needs ∂a/∂q and ∂a/∂q̇ of a = −M⁻¹h, that is second
//!   derivatives of M. Along a geodesic RNEA(q, q̇, a) = 0 (no gravity), so for a direction
//!   (δq, δq̇): M δa = −(∂RNEA/∂q δq + ∂RNEA/∂q̇ δq̇) at fixed a. RNEA is written once over a
//!   scalar type and run on dual numbers x + ε ẋ (ε² = 0), which gives that directional
//!   derivative exactly (to rounding) in one pass per column of the Jacobi field. The gravity
//!   Hessian comes the same way from the gravity torque.
//!
//! Gravity is the physical acceleration vector in the base frame (for a z-up base
//! `[0, 0, -9.81]`), so U_g = −Σ mᵢ g·cᵢ(q).

use std::ops::{Add, Mul, Neg, Sub};

use nalgebra::{DMatrix, DVector, Matrix3, Vector3};

use super::Workspace;
use crate::numerics::linalg;

/// The longest spatial chain (the RNEA keeps its per-body state on the stack).
pub const MAX_BODIES: usize = 8;

/// One revolute joint and the rigid body it moves.
#[derive(Debug, Clone, PartialEq)]
pub struct Body {
    /// Name of the joint (from the URDF), for reports.
    pub joint: String,
    /// Orientation of the joint frame in the previous body's frame (the base for the first).
    pub rotation: Matrix3<f64>,
    /// Origin of the joint frame in the previous body's frame, m.
    pub translation: Vector3<f64>,
    /// Unit axis of rotation in the joint frame.
    pub axis: Vector3<f64>,
    /// Mass of the body, kg.
    pub mass: f64,
    /// Centre of mass in the body frame, m.
    pub com: Vector3<f64>,
    /// Inertia about the centre of mass in the body frame, kg·m².
    pub inertia: Matrix3<f64>,
}

/// A spatial serial chain of revolute joints with gravity.
#[derive(Debug, Clone)]
pub struct SpatialChain {
    bodies: Vec<Body>,
    gravity: Vector3<f64>,
    /// A point of the last body to draw as the tip (body frame), m.
    tip: Vector3<f64>,
    /// Base-frame unit vectors of the drawing plane (see [`SpatialChain::joint_positions`]).
    view: [Vector3<f64>; 2],
}

/// A number RNEA can run on: f64, or a dual number for exact directional derivatives.
trait Scalar: Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + Neg<Output = Self> {
    fn c(x: f64) -> Self;
    fn sin_cos(self) -> (Self, Self);
}

impl Scalar for f64 {
    #[inline]
    fn c(x: f64) -> Self {
        x
    }
    #[inline]
    fn sin_cos(self) -> (Self, Self) {
        f64::sin_cos(self)
    }
}

/// x + ε ẋ with ε² = 0: arithmetic on it carries the derivative along exactly.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Dual {
    v: f64,
    d: f64,
}

impl Add for Dual {
    type Output = Dual;
    #[inline]
    fn add(self, o: Dual) -> Dual {
        Dual { v: self.v + o.v, d: self.d + o.d }
    }
}
impl Sub for Dual {
    type Output = Dual;
    #[inline]
    fn sub(self, o: Dual) -> Dual {
        Dual { v: self.v - o.v, d: self.d - o.d }
    }
}
impl Mul for Dual {
    type Output = Dual;
    #[inline]
    fn mul(self, o: Dual) -> Dual {
        Dual { v: self.v * o.v, d: self.d * o.v + self.v * o.d }
    }
}
impl Neg for Dual {
    type Output = Dual;
    #[inline]
    fn neg(self) -> Dual {
        Dual { v: -self.v, d: -self.d }
    }
}
impl Scalar for Dual {
    #[inline]
    fn c(x: f64) -> Self {
        Dual { v: x, d: 0.0 }
    }
    #[inline]
    fn sin_cos(self) -> (Self, Self) {
        let (s, c) = self.v.sin_cos();
        (Dual { v: s, d: c * self.d }, Dual { v: c, d: -s * self.d })
    }
}

type V3<T> = [T; 3];
/// Row-major 3 × 3.
type M3<T> = [[T; 3]; 3];

#[inline]
fn vadd<T: Scalar>(a: V3<T>, b: V3<T>) -> V3<T> {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
#[inline]
fn vsub<T: Scalar>(a: V3<T>, b: V3<T>) -> V3<T> {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
#[inline]
fn vscale<T: Scalar>(a: V3<T>, s: T) -> V3<T> {
    [a[0] * s, a[1] * s, a[2] * s]
}
#[inline]
fn cross<T: Scalar>(a: V3<T>, b: V3<T>) -> V3<T> {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}
#[inline]
fn dot<T: Scalar>(a: V3<T>, b: V3<T>) -> T {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
/// R v.
#[inline]
fn mv<T: Scalar>(r: &M3<T>, v: V3<T>) -> V3<T> {
    [dot(r[0], v), dot(r[1], v), dot(r[2], v)]
}
/// Rᵀ v.
#[inline]
fn mtv<T: Scalar>(r: &M3<T>, v: V3<T>) -> V3<T> {
    [
        r[0][0] * v[0] + r[1][0] * v[1] + r[2][0] * v[2],
        r[0][1] * v[0] + r[1][1] * v[1] + r[2][1] * v[2],
        r[0][2] * v[0] + r[1][2] * v[1] + r[2][2] * v[2],
    ]
}
/// A B.
#[inline]
fn mm<T: Scalar>(a: &M3<T>, b: &M3<T>) -> M3<T> {
    let mut out = [[T::c(0.0); 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            out[i][j] = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
        }
    }
    out
}
fn lift_v<T: Scalar>(v: &Vector3<f64>) -> V3<T> {
    [T::c(v[0]), T::c(v[1]), T::c(v[2])]
}
fn lift_m<T: Scalar>(m: &Matrix3<f64>) -> M3<T> {
    let mut out = [[T::c(0.0); 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            out[i][j] = T::c(m[(i, j)]);
        }
    }
    out
}
/// Rotation by angle q about the unit axis a (Rodrigues).
#[inline]
fn axis_rotation<T: Scalar>(a: &Vector3<f64>, q: T) -> M3<T> {
    let (s, c) = q.sin_cos();
    let t = T::c(1.0) - c;
    let [x, y, z] = [T::c(a[0]), T::c(a[1]), T::c(a[2])];
    [
        [c + t * x * x, t * x * y - s * z, t * x * z + s * y],
        [t * x * y + s * z, c + t * y * y, t * y * z - s * x],
        [t * x * z - s * y, t * y * z + s * x, c + t * z * z],
    ]
}

/// Base-frame placement of every body at one configuration.
struct Kinematics<T> {
    /// Orientation of body i.
    rot: [M3<T>; MAX_BODIES],
    /// Origin of joint i (on its axis).
    origin: [V3<T>; MAX_BODIES],
    /// Axis of joint i.
    axis: [V3<T>; MAX_BODIES],
}

impl SpatialChain {
    /// Builds the chain from its bodies (base first, at most [`MAX_BODIES`]) and the gravity
    /// acceleration in the base frame, m/s². `tip` is a point of the last body (its frame) drawn
    /// as the end of the arm. The caller validates masses and inertias.
    pub fn new(bodies: Vec<Body>, gravity: [f64; 3], tip: [f64; 3]) -> Self {
        assert!(!bodies.is_empty() && bodies.len() <= MAX_BODIES, "1 to {MAX_BODIES} bodies");
        let gravity = Vector3::from(gravity);
        let mut chain = SpatialChain { bodies, gravity, tip: Vector3::from(tip), view: [Vector3::x(), Vector3::y()] };
        chain.view = chain.drawing_plane();
        chain
    }

    /// The drawing plane: "up" is against gravity (or the last joint's axis at q = 0 is the
    /// normal when there is none); across is up × (the axis of the last joint at q = 0 that is
    /// not vertical). A planar chain with z axes is drawn in its own x–y plane.
    fn drawing_plane(&self) -> [Vector3<f64>; 2] {
        let kin = self.kinematics::<f64>(&vec![0.0; self.dof()]);
        let axes: Vec<Vector3<f64>> = (0..self.dof()).map(|i| Vector3::from(kin.axis[i])).collect();
        let last = axes[axes.len() - 1];
        let g = self.gravity.norm();
        if g > 0.0 {
            let up = -self.gravity / g;
            if let Some(a) = axes.iter().rev().find(|a| a.cross(&up).norm() > 1e-6) {
                let across = up.cross(a).normalize();
                return [across, up];
            }
        }
        // No gravity (or every axis vertical): the plane orthogonal to the last axis.
        let helper = if last.x.abs() < 0.9 { Vector3::x() } else { Vector3::y() };
        let e1 = (helper - last * last.dot(&helper)).normalize();
        [e1, last.cross(&e1)]
    }

    /// Number of joints n.
    pub fn dof(&self) -> usize {
        self.bodies.len()
    }

    /// The bodies, base first.
    pub fn bodies(&self) -> &[Body] {
        &self.bodies
    }

    /// The point of the last body drawn as the arm's tip (its frame), m.
    pub fn tip(&self) -> [f64; 3] {
        self.tip.into()
    }

    /// The chain with `masses` added to its bodies ([`super::Chain::with_point_masses`]): each
    /// body's mass, centre of mass and inertia about it (parallel-axis theorem,
    /// I' = I + m S(c − c') + Σ m_p S(p − c'), S(d) = |d|² 1 − d dᵀ) updated.
    pub fn with_point_masses(&self, masses: &[super::PointMass]) -> SpatialChain {
        let mut chain = self.clone();
        for (t, body) in chain.bodies.iter_mut().enumerate() {
            let here: Vec<(f64, Vector3<f64>)> =
                masses.iter().filter(|p| p.link == t).map(|p| (p.mass, Vector3::from(p.position))).collect();
            if here.is_empty() {
                continue;
            }
            let total = body.mass + here.iter().map(|(m, _)| m).sum::<f64>();
            let com = (body.com * body.mass + here.iter().map(|(m, p)| p * *m).sum::<Vector3<f64>>()) / total;
            let shift = |d: Vector3<f64>| Matrix3::identity() * d.norm_squared() - d * d.transpose();
            let mut inertia = body.inertia + shift(body.com - com) * body.mass;
            for (m, p) in &here {
                inertia += shift(p - com) * *m;
            }
            body.mass = total;
            body.com = com;
            body.inertia = inertia;
        }
        chain
    }

    /// The gravity acceleration in the base frame, m/s².
    pub fn gravity(&self) -> [f64; 3] {
        self.gravity.into()
    }

    /// Whether gravity acts.
    pub fn has_gravity(&self) -> bool {
        self.gravity != Vector3::zeros()
    }

    /// Scratch space sized for this chain.
    pub fn workspace(&self) -> Workspace {
        Workspace::new(self.dof(), 0)
    }

    fn kinematics<T: Scalar>(&self, q: &[T]) -> Kinematics<T> {
        let zero = T::c(0.0);
        let mut kin = Kinematics {
            rot: [[[zero; 3]; 3]; MAX_BODIES],
            origin: [[zero; 3]; MAX_BODIES],
            axis: [[zero; 3]; MAX_BODIES],
        };
        let mut rot = lift_m::<T>(&Matrix3::identity());
        let mut origin = [zero; 3];
        for (i, b) in self.bodies.iter().enumerate() {
            origin = vadd(origin, mv(&rot, lift_v(&b.translation)));
            let joint = mm(&rot, &lift_m(&b.rotation));
            kin.axis[i] = mv(&joint, lift_v(&b.axis));
            rot = mm(&joint, &axis_rotation(&b.axis, q[i]));
            kin.rot[i] = rot;
            kin.origin[i] = origin;
        }
        kin
    }

    /// Recursive Newton–Euler: τ = M(q) q̈ + h(q, q̇) (+ ∂U_g/∂q when `with_gravity`).
    fn rnea<T: Scalar>(&self, q: &[T], qd: &[T], qdd: &[T], with_gravity: bool, tau: &mut [T]) {
        let n = self.dof();
        let zero = T::c(0.0);
        let kin = self.kinematics(q);
        let mut force = [[zero; 3]; MAX_BODIES];
        let mut moment = [[zero; 3]; MAX_BODIES];
        let mut com = [[zero; 3]; MAX_BODIES];
        // Velocity and acceleration of the previous body; acceleration of its joint's origin.
        let mut w = [zero; 3];
        let mut wd = [zero; 3];
        let mut acc = if with_gravity { lift_v::<T>(&-self.gravity) } else { [zero; 3] };
        let mut prev_origin = [zero; 3];
        for (i, b) in self.bodies.iter().enumerate() {
            let d = vsub(kin.origin[i], prev_origin);
            acc = vadd(acc, vadd(cross(wd, d), cross(w, cross(w, d))));
            let z = kin.axis[i];
            wd = vadd(wd, vadd(vscale(z, qdd[i]), vscale(cross(w, z), qd[i])));
            w = vadd(w, vscale(z, qd[i]));
            let rot = &kin.rot[i];
            let c = mv(rot, lift_v(&b.com));
            let acc_com = vadd(acc, vadd(cross(wd, c), cross(w, cross(w, c))));
            force[i] = vscale(acc_com, T::c(b.mass));
            let inertia = lift_m::<T>(&b.inertia);
            let iw = mv(rot, mv(&inertia, mtv(rot, w)));
            let iwd = mv(rot, mv(&inertia, mtv(rot, wd)));
            moment[i] = vadd(iwd, cross(w, iw));
            com[i] = c;
            prev_origin = kin.origin[i];
        }
        // Backward: f and n (about the joint origin) transmitted through joint i.
        let mut f = [zero; 3];
        let mut nm = [zero; 3];
        for i in (0..n).rev() {
            if i + 1 < n {
                let lever = vsub(kin.origin[i + 1], kin.origin[i]);
                nm = vadd(nm, cross(lever, f));
            }
            nm = vadd(nm, vadd(moment[i], cross(com[i], force[i])));
            f = vadd(f, force[i]);
            tau[i] = dot(kin.axis[i], nm);
        }
    }

    /// M(q) by the composite-rigid-body algorithm, column-major into `m`.
    fn crba(&self, q: &[f64], m: &mut [f64]) {
        let n = self.dof();
        let kin = self.kinematics::<f64>(q);
        let mut mass = 0.0;
        let mut first = Vector3::zeros();
        let mut inertia = Matrix3::zeros();
        for i in (0..n).rev() {
            let b = &self.bodies[i];
            let rot = Matrix3::from_fn(|r, c| kin.rot[i][r][c]);
            let origin = Vector3::from(kin.origin[i]);
            let c = origin + rot * b.com;
            mass += b.mass;
            first += c * b.mass;
            inertia +=
                rot * b.inertia * rot.transpose() + (Matrix3::identity() * c.dot(&c) - c * c.transpose()) * b.mass;
            // Momentum of the composite when joint i turns at unit rate.
            let z = Vector3::from(kin.axis[i]);
            let linear = z.cross(&(first - origin * mass));
            let angular = inertia * z + first.cross(&origin.cross(&z));
            for j in 0..=i {
                let zj = Vector3::from(kin.axis[j]);
                let pj = Vector3::from(kin.origin[j]);
                let mji = zj.dot(&(angular - pj.cross(&linear)));
                m[j + n * i] = mji;
                m[i + n * j] = mji;
            }
        }
    }

    /// The mass matrix M(q).
    pub fn mass_matrix(&self, q: &DVector<f64>) -> DMatrix<f64> {
        let n = self.dof();
        let mut m = vec![0.0; n * n];
        self.crba(q.as_slice(), &mut m);
        DMatrix::from_column_slice(n, n, &m)
    }

    /// τ = RNEA(q, q̇, q̈) with or without gravity: M q̈ + h (+ ∂U_g/∂q).
    pub fn inverse_dynamics(&self, q: &[f64], qd: &[f64], qdd: &[f64], with_gravity: bool) -> DVector<f64> {
        let mut tau = vec![0.0; self.dof()];
        self.rnea(q, qd, qdd, with_gravity, &mut tau);
        DVector::from_vec(tau)
    }

    /// Christoffel symbols of the first kind Γ_{i,jk}, as `gamma[i][(j, k)]`, by polarising the
    /// velocity term of RNEA.
    pub fn christoffel(&self, q: &DVector<f64>) -> Vec<DMatrix<f64>> {
        let n = self.dof();
        let zero = vec![0.0; n];
        let c = |v: &[f64]| {
            let mut t = vec![0.0; n];
            self.rnea(q.as_slice(), v, &zero, false, &mut t);
            t
        };
        let unit = |j: usize| (0..n).map(|k| if k == j { 1.0 } else { 0.0 }).collect::<Vec<_>>();
        let single: Vec<Vec<f64>> = (0..n).map(|j| c(&unit(j))).collect();
        let mut gamma = vec![DMatrix::zeros(n, n); n];
        for j in 0..n {
            for i in 0..n {
                gamma[i][(j, j)] = single[j][i];
            }
            for k in j + 1..n {
                let mut v = unit(j);
                v[k] = 1.0;
                let both = c(&v);
                for i in 0..n {
                    let g = 0.5 * (both[i] - single[j][i] - single[k][i]);
                    gamma[i][(j, k)] = g;
                    gamma[i][(k, j)] = g;
                }
            }
        }
        gamma
    }

    /// ∂M/∂q_k from the Christoffel symbols: ∂M_ij/∂q_k = Γ_{i,jk} + Γ_{j,ik}.
    pub fn mass_matrix_derivatives(&self, q: &DVector<f64>) -> Vec<DMatrix<f64>> {
        let n = self.dof();
        let gamma = self.christoffel(q);
        (0..n).map(|k| DMatrix::from_fn(n, n, |i, j| gamma[i][(j, k)] + gamma[j][(i, k)])).collect()
    }

    /// The Coriolis/centrifugal vector h(q, q̇) = RNEA(q, q̇, 0) without gravity.
    pub fn coriolis(&self, q: &DVector<f64>, qd: &DVector<f64>) -> DVector<f64> {
        self.inverse_dynamics(q.as_slice(), qd.as_slice(), &vec![0.0; self.dof()], false)
    }

    /// |g| Σᵢ mᵢ (Σ_{k ≤ i} |r_k| + |cᵢ|): no centre of mass is farther from the base origin, so
    /// this bounds |U_g| and (with the same levers) every entry of ∇U_g and ∇²U_g.
    pub fn gravity_bound(&self) -> f64 {
        let mut reach = 0.0;
        let mut bound = 0.0;
        for b in &self.bodies {
            reach += b.translation.norm();
            bound += b.mass * (reach + b.com.norm());
        }
        self.gravity.norm() * bound
    }

    /// Centres of mass of the bodies in the base frame, m.
    pub fn com_positions(&self, q: &[f64]) -> Vec<[f64; 3]> {
        let kin = self.kinematics::<f64>(q);
        self.bodies.iter().enumerate().map(|(i, b)| vadd(kin.origin[i], mv(&kin.rot[i], lift_v(&b.com)))).collect()
    }

    /// Gravity potential U_g = −Σ mᵢ g·cᵢ(q) in J.
    pub fn gravity_potential(&self, q: &[f64]) -> f64 {
        if !self.has_gravity() {
            return 0.0;
        }
        let g: V3<f64> = self.gravity.into();
        -self.com_positions(q).iter().zip(&self.bodies).map(|(c, b)| b.mass * dot(g, *c)).sum::<f64>()
    }

    /// ∂U_g/∂q in N·m: RNEA at rest with gravity.
    pub fn gravity_gradient(&self, q: &[f64]) -> DVector<f64> {
        let mut out = DVector::zeros(self.dof());
        self.gravity_gradient_into(q, out.as_mut_slice());
        out
    }

    /// ∂U_g/∂q into `out` without allocating.
    pub fn gravity_gradient_into(&self, q: &[f64], out: &mut [f64]) {
        if !self.has_gravity() {
            out.fill(0.0);
            return;
        }
        let zero = [0.0; MAX_BODIES];
        let n = self.dof();
        self.rnea(q, &zero[..n], &zero[..n], true, out);
    }

    /// ∂²U_g/∂q² in N·m/rad: the gravity torque differentiated exactly with dual numbers.
    pub fn gravity_hessian(&self, q: &[f64]) -> DMatrix<f64> {
        let n = self.dof();
        let mut out = DMatrix::zeros(n, n);
        if !self.has_gravity() {
            return out;
        }
        let zero = [Dual::c(0.0); MAX_BODIES];
        let mut tau = [Dual::c(0.0); MAX_BODIES];
        for p in 0..n {
            let qd: Vec<Dual> = (0..n).map(|k| Dual { v: q[k], d: if k == p { 1.0 } else { 0.0 } }).collect();
            self.rnea(&qd, &zero[..n], &zero[..n], true, &mut tau[..n]);
            for r in 0..n {
                out[(r, p)] = tau[r].d;
            }
        }
        // Symmetric in exact arithmetic; average away the rounding.
        (&out + out.transpose()) * 0.5
    }

    /// Right-hand side of the geodesic equation, y = (q, q̇): ẏ = (q̇, −M⁻¹ h(q, q̇)).
    pub fn geodesic_rhs(&self, ws: &mut Workspace, y: &[f64], dy: &mut [f64]) -> bool {
        let n = self.dof();
        let (q, qd) = y[..2 * n].split_at(n);
        self.crba(q, &mut ws.m);
        let zero = [0.0; MAX_BODIES];
        self.rnea(q, qd, &zero[..n], false, &mut ws.h);
        linalg::geodesic_accel(&mut ws.m, &ws.h, n, qd, dy)
    }

    /// The geodesic equation with its Jacobi fields, y = (q, q̇, Φ_q, Φ_q̇) (column-major):
    /// Φ̇_q = Φ_q̇ and, column by column, M Φ̇_q̇ = −(∂RNEA/∂q Φ_q + ∂RNEA/∂q̇ Φ_q̇) at q̈ = a,
    /// by one dual-number RNEA pass per column.
    pub fn variational_rhs(&self, ws: &mut Workspace, y: &[f64], dy: &mut [f64]) -> bool {
        let n = self.dof();
        if !self.geodesic_rhs(ws, y, dy) {
            return false;
        }
        let off_q = 2 * n;
        let off_qd = 2 * n + n * n;
        dy[off_q..off_qd].copy_from_slice(&y[off_qd..off_qd + n * n]);
        let mut q = [Dual::c(0.0); MAX_BODIES];
        let mut qd = [Dual::c(0.0); MAX_BODIES];
        let mut a = [Dual::c(0.0); MAX_BODIES];
        let mut tau = [Dual::c(0.0); MAX_BODIES];
        for k in 0..n {
            a[k] = Dual::c(dy[n + k]);
        }
        for col in 0..n {
            for k in 0..n {
                q[k] = Dual { v: y[k], d: y[off_q + k + n * col] };
                qd[k] = Dual { v: y[n + k], d: y[off_qd + k + n * col] };
            }
            self.rnea(&q[..n], &qd[..n], &a[..n], false, &mut tau[..n]);
            let out = &mut dy[off_qd + n * col..off_qd + n * (col + 1)];
            for k in 0..n {
                out[k] = -tau[k].d;
            }
            linalg::cholesky_solve(&ws.m, n, out);
        }
        true
    }

    /// Evaluates M(q) and h(q, q̇) into the workspace and factors M.
    pub fn prepare(&self, ws: &mut Workspace, q: &[f64], qd: &[f64]) -> bool {
        let n = self.dof();
        self.crba(q, &mut ws.m);
        ws.m_full.copy_from_slice(&ws.m);
        let zero = [0.0; MAX_BODIES];
        self.rnea(q, qd, &zero[..n], false, &mut ws.h);
        linalg::cholesky_in_place(&mut ws.m, n)
    }

    /// Evaluates and factors M(q) into the workspace (no Coriolis term).
    pub fn factor_mass(&self, ws: &mut Workspace, q: &[f64]) -> bool {
        let n = self.dof();
        self.crba(q, &mut ws.m);
        ws.m_full.copy_from_slice(&ws.m);
        linalg::cholesky_in_place(&mut ws.m, n)
    }

    /// Joint accelerations of M q̈ + h(q, q̇) = τ.
    pub fn acceleration(&self, ws: &mut Workspace, q: &[f64], qd: &[f64], tau: &[f64], qdd: &mut [f64]) -> bool {
        if !self.prepare(ws, q, qd) {
            return false;
        }
        for ((a, t), h) in qdd.iter_mut().zip(tau).zip(&ws.h) {
            *a = t - h;
        }
        ws.solve(qdd);
        true
    }

    /// Joint origins and the tip in the base frame, m (n + 2 points: the base origin first).
    pub fn joint_positions_3d(&self, q: &[f64]) -> Vec<[f64; 3]> {
        let n = self.dof();
        let kin = self.kinematics::<f64>(q);
        let mut out = vec![[0.0; 3]];
        out.extend((0..n).map(|i| kin.origin[i]));
        out.push(vadd(kin.origin[n - 1], mv(&kin.rot[n - 1], lift_v(&self.tip))));
        out
    }

    /// The base, the joint origins and the tip projected on the drawing plane: the vertical
    /// plane across the last non-vertical joint axis at q = 0 when gravity acts (x across, y up),
    /// else the plane orthogonal to the last joint's axis at q = 0.
    pub fn joint_positions(&self, q: &[f64]) -> Vec<[f64; 2]> {
        let [e1, e2] = self.view;
        self.joint_positions_3d(q)
            .into_iter()
            .map(|p| {
                let p = Vector3::from(p);
                [e1.dot(&p), e2.dot(&p)]
            })
            .collect()
    }
}

#[cfg(test)]
mod tests;
