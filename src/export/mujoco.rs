//! MJCF export: the chain and its springs as a MuJoCo model.
//!
//! A URDF arm becomes springfit's own bodies (`model::urdf`): one per moving joint, carrying
//! every link that moves rigidly with it, the held joints welded at their held values, placed by
//! the joint frames and turning about the URDF's axes, with the merged masses, centres of mass and
//! full inertia tensors. So MuJoCo integrates the dynamics springfit fits and simulates, and
//! `qpos` is the design's q. What follows describes a planar chain typed into the design file.
//!
//! The chain becomes nested bodies in the x–y plane with hinge joints about z (parallel axes), so
//! MuJoCo's `qpos` is springfit's q: qᵢ relative to the previous link, q₁ from the x axis. Each
//! body carries its link's mass, centre of mass and inertia; the joints have no damping,
//! armature or friction loss, contacts are off and the integrator is RK4 with springfit's step,
//! so the two simulators integrate the same equations with the same scheme.
//!
//! Springs map onto MuJoCo's passive forces where MuJoCo has an exact equivalent:
//!
//! | element | MJCF | exact |
//! | --- | --- | --- |
//! | linear on one joint (a = eᵢ) | joint `stiffness` + `springref` | yes |
//! | cubic on one joint | joint `stiffness="0 0 k"` (polynomial, MuJoCo ≥ 3.7) | yes |
//! | linear or cubic on a coupling | fixed tendon, `coef` = a, `stiffness`, `springlength` = x₀ | yes |
//! | linear, cubic or compression on a tendon's coupling | fixed tendon, `coef` = the pulley radii ρaᵢ (m), `stiffness` k/ρ² (cubic k/ρ⁴), `springlength` ρx₀ | yes |
//! | compression, side ± | fixed tendon with a dead band `springlength="lo hi"` | yes |
//! | crank on one joint (a = ±eᵢ) | zero-length spatial tendon between two sites | yes |
//! | crank on a coupling | passive-force callback (`mjcb_passive`) | no |
//! | cam (its coefficient rows together) | passive-force callback | no |
//!
//! The crank identity: a zero-rest-length spring of rate κ between a site at radius d on the
//! parent (at angle x₀) and one at radius r on the child has L² = r² + d² − 2 r d cos(q − x₀), so
//! ½ κ L² = const + κ r d (1 − cos(q − x₀)): a crank with k = κ r d, exactly.
//!
//! Elements without an exact equivalent are written as `<custom><numeric>` entries named
//! `springfit_callback_<name>` with data `[profile code, k, x₀, a₁ … aₙ]` (codes in
//! [`callback_code`]), so the model file alone says everything a passive-force callback needs. A
//! cam is one entry `springfit_cam_<id>` with data `[N, h, x_lo, a₁ … aₙ, c₀ … c_{N+1}]`: its
//! potential V(x) = Σⱼ cⱼ Bⱼ(x − x_lo) on N uniform knots of spacing h (the B-splines of
//! `elements::spline`, continued beyond the knots by their second-order Taylor polynomials), the
//! torque −a V′(a·q).

use std::fmt::Write as _;

use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};

use crate::design::Design;
use crate::elements::{Element, Profile, Side};
use crate::error::{Error, Result};
use crate::fit::bill::BomRow;
use crate::model::Chain;

/// Prefix of the `<numeric>` entries that describe callback elements.
pub const CALLBACK_PREFIX: &str = "springfit_callback_";

/// Prefix of the `<numeric>` entries that describe cams.
pub const CAM_PREFIX: &str = "springfit_cam_";

/// The far end of a one-sided dead band, rad: far beyond any reachable a·q, so the band is open
/// on that side in practice (MuJoCo's band needs two finite numbers).
pub const DEAD_BAND_FAR: f64 = 1e9;

/// Radius of a crank's site on the child link, m (only r·d matters: κ = k / (r d)).
pub const CRANK_CHILD_RADIUS: f64 = 0.1;

/// Radius of a crank's site on the parent link, m. It differs from [`CRANK_CHILD_RADIUS`] so the
/// tendon never reaches zero length (where its direction, and so its moment arm, is undefined).
pub const CRANK_PARENT_RADIUS: f64 = 0.05;

/// The ratio of a link's inertia about its long axis (x) to the in-plane one (z). It has no
/// effect on a planar motion (ω stays along z, a principal axis) but MuJoCo needs a valid,
/// positive inertia: a slender link has I_x ≪ I_y = I_z, and this choice meets the triangle
/// inequality I_x + I_y ≥ I_z.
pub const AXIAL_INERTIA_RATIO: f64 = 0.01;

/// How one element is represented in MuJoCo.
#[derive(Debug, Clone, PartialEq)]
pub enum Representation {
    /// Joint `stiffness`/`springref` (linear) or polynomial stiffness (cubic) on joint `joint`
    /// (0-based).
    Joint {
        /// The joint, 0-based (the MJCF's `q1` is 0).
        joint: usize,
    },
    /// A fixed tendon with `coef` = a (or −a with the length negated, so that x₀ = −1 is not
    /// read as MuJoCo's "length at qpos_spring").
    FixedTendon {
        /// True when x₀ is exactly −1 (MuJoCo's "length at qpos_spring"): written with `coef` −a
        /// and `springlength` 1, which leaves the force law unchanged.
        negated: bool,
    },
    /// A fixed tendon with a two-value `springlength` dead band.
    DeadBand,
    /// A tendon's cable (`realise::transmission`): a fixed tendon whose coefficients are its
    /// pulley radii ρ·aᵢ in m, so its length is the cable's, ρ·x; the stiffness k/ρ² (cubic
    /// k/ρ⁴) and `springlength` ρ·x₀ (a dead band ρ·x₀ and the far end) give the element's force
    /// law on x.
    PulleyTendon {
        /// The drum radius ρ, mm.
        scale_mm: f64,
        /// A dead band (a compression element).
        dead_band: bool,
        /// Written with the radii negated and the length −ρx₀ (ρx₀ exactly −1 would read as
        /// MuJoCo's "length at qpos_spring").
        negated: bool,
    },
    /// A zero-rest-length spatial tendon between two sites (a crank on one joint).
    SpatialCrank {
        /// The joint the tendon spans (a site on the link either side of it), 0-based.
        joint: usize,
    },
    /// A passive-force callback; the reason why no built-in element fits.
    Callback {
        /// Why no built-in element fits, in words (`elements.md` lists it).
        reason: String,
    },
}

impl Representation {
    /// Whether MuJoCo's own elements reproduce the element exactly (up to rounding).
    pub fn is_exact(&self) -> bool {
        !matches!(self, Representation::Callback { .. })
    }

    /// One line for `elements.md`.
    pub fn describe(&self) -> String {
        match self {
            Representation::Joint { joint } => format!("joint `q{}` stiffness and springref", joint + 1),
            Representation::FixedTendon { negated: false } => "fixed tendon, coef = a, stiffness, springlength".into(),
            Representation::FixedTendon { negated: true } => {
                "fixed tendon, coef = −a, springlength = −x₀ (x₀ = −1 would read as MuJoCo's default)".into()
            }
            Representation::DeadBand => "fixed tendon, dead band springlength=\"lo hi\"".into(),
            Representation::PulleyTendon { scale_mm, dead_band, negated } => format!(
                "tendon over pulleys: fixed tendon, coef = the pulley radii {}ρ·a (ρ = {scale_mm} mm), stiffness k/ρ{}, {}",
                if *negated { "−" } else { "" },
                if *dead_band { "²" } else { "² (cubic: ⁴)" },
                if *dead_band { "dead band springlength=\"lo hi\" at ρ·x₀" } else { "springlength = ρ·x₀" }
            ),
            Representation::SpatialCrank { joint } => {
                format!("zero-length spatial tendon between two sites across joint `q{}`", joint + 1)
            }
            Representation::Callback { reason } => format!("passive-force callback: {reason}"),
        }
    }
}

/// One exported element.
#[derive(Debug, Clone, PartialEq)]
pub struct ExportedElement {
    /// The bill of materials' id.
    pub id: String,
    /// The MJCF name of its tendon, site pair or callback entry.
    pub name: String,
    /// `profile (coupling) @ offset`.
    pub label: String,
    /// Stiffness and unit.
    pub stiffness: String,
    /// How MuJoCo represents it.
    pub representation: Representation,
}

/// The exported model.
#[derive(Debug, Clone)]
pub struct MujocoModel {
    /// The MJCF text.
    pub xml: String,
    /// Every element of the bill of materials, in its order (a cam once, at its first row).
    pub elements: Vec<ExportedElement>,
    /// The simulation step written into `<option timestep>`, s.
    pub timestep: f64,
}

impl MujocoModel {
    /// Elements MuJoCo reproduces exactly (a cam counts once).
    pub fn exact_count(&self) -> usize {
        self.elements.iter().filter(|e| e.representation.is_exact()).count()
    }

    /// Elements that need the passive-force callback.
    pub fn callback_count(&self) -> usize {
        self.elements.len() - self.exact_count()
    }
}

/// The profile code of a callback entry: 1 linear, 2 cubic, 3 crank, 4 compression +,
/// 5 compression −.
pub fn callback_code(p: Profile) -> u8 {
    match p {
        Profile::Linear => 1,
        Profile::Cubic => 2,
        Profile::Crank => 3,
        Profile::Compression(Side::Plus) => 4,
        Profile::Compression(Side::Minus) => 5,
        // A cam has its own entry (`CAM_PREFIX`), never a code.
        Profile::Spline(_) => 0,
    }
}

/// A number as MJCF text: Rust's shortest round-trip form, so MuJoCo reads the same f64.
fn num(x: f64) -> String {
    format!("{x:?}")
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

/// An MJCF name made of letters, digits, `_` and `-`.
fn sanitize(id: &str) -> String {
    id.chars().map(|c| if c.is_ascii_alphanumeric() || c == '_' || c == '-' { c } else { '_' }).collect()
}

/// The two sites of a crank on joint `j` with phase `phase`: (the parent's, in the parent body's
/// frame, or the world's for the first joint; the child's, in the child body's frame). Both lie in
/// the plane through the joint origin orthogonal to its axis, the parent's at angle `phase` from
/// the child's direction at q = 0, so L² = r² + d² − 2 r d cos(q − phase).
fn crank_sites(chain: &Chain, j: usize, phase: f64) -> ([f64; 3], [f64; 3]) {
    let (s, c) = phase.sin_cos();
    match chain {
        Chain::Planar(p) => {
            let base = if j == 0 { 0.0 } else { p.links()[j - 1].length };
            ([base + CRANK_PARENT_RADIUS * c, CRANK_PARENT_RADIUS * s, 0.0], [CRANK_CHILD_RADIUS, 0.0, 0.0])
        }
        Chain::Spatial(sp) => {
            let body = &sp.bodies()[j];
            let [e1, e2] = perpendicular_pair(&body.axis);
            let parent = body.translation + body.rotation * (CRANK_PARENT_RADIUS * (c * e1 + s * e2));
            (parent.into(), (CRANK_CHILD_RADIUS * e1).into())
        }
    }
}

/// Two unit vectors (e₁, e₂ = u × e₁) completing the unit axis `u` to a right-handed frame: a
/// turn by q about u takes e₁ to cos q e₁ + sin q e₂.
fn perpendicular_pair(u: &Vector3<f64>) -> [Vector3<f64>; 2] {
    // The coordinate axis least aligned with u, its part orthogonal to u.
    let helper = if u.x.abs() <= u.y.abs() && u.x.abs() <= u.z.abs() {
        Vector3::x()
    } else if u.y.abs() <= u.z.abs() {
        Vector3::y()
    } else {
        Vector3::z()
    };
    let e1 = (helper - u * u.dot(&helper)).normalize();
    [e1, u.cross(&e1)]
}

/// A site's position: planar chains keep their two-number form with z written as `0`.
fn site_pos(chain: &Chain, p: [f64; 3]) -> String {
    match chain {
        Chain::Planar(_) => format!("{} {} 0", num(p[0]), num(p[1])),
        Chain::Spatial(_) => format!("{} {} {}", num(p[0]), num(p[1]), num(p[2])),
    }
}

/// What qpos means, for the model's header comment.
fn joint_meaning(chain: &Chain) -> String {
    match chain {
        Chain::Planar(_) => "q1 from the x axis, qi relative to link i-1".into(),
        Chain::Spatial(sp) => {
            let names: Vec<String> =
                sp.bodies().iter().enumerate().map(|(i, b)| format!("q{} = {}", i + 1, b.joint)).collect();
            format!("the URDF joint angles, {}", names.join(", "))
        }
    }
}

/// Gravity in MuJoCo's world frame (the planar chain's plane is x–y; the URDF's base frame).
fn gravity(chain: &Chain) -> Vec<f64> {
    match chain {
        Chain::Planar(p) => p.gravity().to_vec(),
        Chain::Spatial(sp) => sp.gravity().to_vec(),
    }
}

/// One body's MJCF attributes and children.
struct BodyText {
    /// `pos="…"` and, when turned, `quat="…"`: the joint frame in the parent body's frame.
    placement: String,
    /// ` axis="…"` for a spatial joint (planar ones take the default z).
    axis: String,
    /// The `<inertial>` element.
    inertial: String,
    /// A capsule for viewing (massless: `inertiafromgeom="false"`).
    geom: String,
}

/// The bodies of the chain. Planar links lie along their body's x axis. A spatial chain's bodies
/// are springfit's: each is every URDF link that moves rigidly with its joint (held joints
/// welded at their held values), with the merged mass, centre of mass and full inertia tensor in
/// the frame of the joint's child link, which at q = 0 is the joint frame.
fn body_texts(chain: &Chain) -> Vec<BodyText> {
    match chain {
        Chain::Planar(p) => {
            let links = p.links();
            links
                .iter()
                .enumerate()
                .map(|(i, link)| BodyText {
                    placement: format!("pos=\"{} 0 0\"", num(if i == 0 { 0.0 } else { links[i - 1].length })),
                    axis: String::new(),
                    inertial: format!(
                        "<inertial pos=\"{} 0 0\" mass=\"{}\" diaginertia=\"{} {} {}\"/>",
                        num(link.com),
                        num(link.mass),
                        num(AXIAL_INERTIA_RATIO * link.inertia),
                        num(link.inertia),
                        num(link.inertia)
                    ),
                    geom: format!("<geom fromto=\"0 0 0 {} 0 0\"/>", num(link.length)),
                })
                .collect()
        }
        Chain::Spatial(sp) => {
            let bodies = sp.bodies();
            let v = |v: &Vector3<f64>| format!("{} {} {}", num(v.x), num(v.y), num(v.z));
            bodies
                .iter()
                .enumerate()
                .map(|(i, b)| {
                    let mut placement = format!("pos=\"{}\"", v(&b.translation));
                    if b.rotation != Matrix3::identity() {
                        let q = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(b.rotation));
                        let _ = write!(placement, " quat=\"{} {} {} {}\"", num(q.w), num(q.i), num(q.j), num(q.k));
                    }
                    let j = &b.inertia;
                    let inertial = format!(
                        "<inertial pos=\"{}\" mass=\"{}\" fullinertia=\"{} {} {} {} {} {}\"/>",
                        v(&b.com),
                        num(b.mass),
                        num(j[(0, 0)]),
                        num(j[(1, 1)]),
                        num(j[(2, 2)]),
                        num(j[(0, 1)]),
                        num(j[(0, 2)]),
                        num(j[(1, 2)])
                    );
                    // To the next joint's origin (the last body: to its centre of mass).
                    let end = bodies.get(i + 1).map_or(b.com, |next| next.translation);
                    let geom = if end.norm() > 1e-6 {
                        format!("<geom fromto=\"0 0 0 {}\"/>", v(&end))
                    } else {
                        "<geom type=\"sphere\" size=\"0.03\"/>".into()
                    };
                    BodyText { placement, axis: format!(" axis=\"{}\"", v(&b.axis)), inertial, geom }
                })
                .collect()
        }
    }
}

/// Builds the MJCF model of `design` with the springs of `rows`, integrated by RK4 with step
/// `timestep` seconds.
///
/// Each row becomes MuJoCo's own element where one reproduces it exactly (joint stiffness, a
/// fixed tendon, a dead band, a spatial tendon between two sites for a crank) and a callback
/// entry otherwise (a cam once, at its first coefficient row); then the text is written around
/// the bodies.
pub fn export(design: &Design, rows: &[BomRow], timestep: f64) -> Result<MujocoModel> {
    let n = design.dof();
    if !(timestep.is_finite() && timestep > 0.0) {
        return Err(Error::Setting { field: "timestep".into(), reason: format!("must be positive, got {timestep}") });
    }
    if let Some(r) = rows.iter().find(|r| r.element.coupling.len() != n) {
        return Err(Error::Setting {
            field: "bom".into(),
            reason: format!("element {} acts on {} joints but the design has {n}", r.id, r.element.coupling.len()),
        });
    }
    let mut parts = Parts::new(n, crate::realise::transmission::Limits::of(&design.parts));
    let mut elements = Vec::with_capacity(rows.len());
    let cams = crate::fit::bill::grouped(rows);
    let mut cams_done = vec![false; cams.len()];
    for (i, row) in rows.iter().enumerate() {
        if matches!(row.element.profile, Profile::Spline(_)) {
            // A cam: one callback entry for all its coefficient rows, at its first.
            let id = row.id.split('.').next().unwrap_or(&row.id);
            let Some(c) = cams.iter().position(|c| c.id == id) else { continue };
            if !std::mem::replace(&mut cams_done[c], true) {
                elements.push(parts.cam(c, &cams[c]));
            }
            continue;
        }
        elements.push(parts.spring(&design.chain, i, row));
    }
    let xml = parts.xml(design, &elements, timestep);
    Ok(MujocoModel { xml, elements, timestep })
}

/// The pieces of the model the elements add to, gathered before the text is written: joint
/// attributes, sites per body (index 0 is the world), tendons, callback entries, and the names
/// used so far.
struct Parts {
    joint_attrs: Vec<Option<String>>,
    sites: Vec<Vec<String>>,
    tendons: String,
    customs: String,
    used_names: std::collections::BTreeSet<String>,
    /// The design's `[parts]` tendon limits, which give a tendon coupling its pulley radii.
    limits: crate::realise::transmission::Limits,
}

impl Parts {
    fn new(n: usize, limits: crate::realise::transmission::Limits) -> Parts {
        Parts {
            limits,
            joint_attrs: vec![None; n],
            sites: vec![Vec::new(); n + 1],
            tendons: String::new(),
            customs: String::new(),
            used_names: std::collections::BTreeSet::new(),
        }
    }

    /// The MJCF name of element `id`: the id made a name, or `fallback` when that is empty or
    /// taken.
    fn name(&mut self, id: &str, fallback: String) -> String {
        let mut name = sanitize(id);
        if name.is_empty() || !self.used_names.insert(name.clone()) {
            name = fallback;
            self.used_names.insert(name.clone());
        }
        name
    }

    /// Cam `c` of the bill: a callback entry with its knots, coupling and coefficients.
    fn cam(&mut self, c: usize, cam: &crate::realise::cam::FittedCam) -> ExportedElement {
        let name = self.name(&cam.id, format!("cam_{}", c + 1));
        let mut data = vec![f64::from(cam.knots.count), cam.knots.width, cam.knots.lo];
        data.extend_from_slice(&cam.coupling);
        data.extend_from_slice(&cam.coefficients);
        let data: Vec<String> = data.into_iter().map(num).collect();
        let _ = writeln!(self.customs, "    <numeric name=\"{CAM_PREFIX}{name}\" data=\"{}\"/>", data.join(" "));
        ExportedElement {
            id: cam.id.clone(),
            name,
            label: format!(
                "cam ({}) on {} knots from {:.3}",
                cam.coupling.iter().map(|a| crate::elements::fmt_number(*a)).collect::<Vec<_>>().join(";"),
                cam.knots.count,
                cam.knots.lo
            ),
            stiffness: format!("{} coefficients (J)", cam.coefficients.len()),
            representation: Representation::Callback {
                reason: "a cam: MuJoCo has no element for an arbitrary profile".into(),
            },
        }
    }

    /// Row i, a spring: MuJoCo's own element where one reproduces its profile on its coupling,
    /// a callback entry otherwise.
    fn spring(&mut self, chain: &Chain, i: usize, row: &BomRow) -> ExportedElement {
        let e = &row.element;
        let k = row.stiffness;
        let name = self.name(&row.id, format!("spring_{}", i + 1));
        let nonzero: Vec<usize> = (0..e.coupling.len()).filter(|&j| e.coupling[j] != 0.0).collect();
        let single = if nonzero.len() == 1 { Some(nonzero[0]) } else { None };
        // A coupling a tendon makes: its cable's length ρ·x is the tendon's (no transmission: the
        // coupling as it is, as for a differential).
        use crate::realise::transmission::{Kind, kind, scale};
        let tendon = if kind(&e.coupling) == Kind::Tendon { scale(&e.coupling, &self.limits).ok() } else { None };
        let representation = match (e.profile, single, tendon) {
            (Profile::Linear | Profile::Cubic | Profile::Compression(_), _, Some(rho)) => {
                self.pulley_tendon(&name, e, k, &nonzero, rho)
            }
            (Profile::Linear | Profile::Cubic, _, _) => self.linear_or_cubic(&name, e, k, &nonzero, single),
            (Profile::Compression(side), _, _) if !nonzero.is_empty() => self.dead_band(&name, e, k, side, &nonzero),
            (Profile::Crank, Some(j), _) if e.coupling[j].abs() == 1.0 => self.crank(chain, &name, e, k, j),
            _ => self.callback(&name, e, k, nonzero.is_empty()),
        };
        ExportedElement {
            id: row.id.clone(),
            name,
            label: e.label(),
            stiffness: format!("{} {}", k, e.profile.unit()),
            representation,
        }
    }

    /// A linear or cubic spring: joint stiffness on a joint of its own at ratio 1 (the first
    /// there), a fixed tendon otherwise.
    fn linear_or_cubic(
        &mut self,
        name: &str,
        e: &Element,
        k: f64,
        nonzero: &[usize],
        single: Option<usize>,
    ) -> Representation {
        let stiffness = if e.profile == Profile::Linear { num(k) } else { format!("0 0 {}", num(k)) };
        match single {
            Some(j) if e.coupling[j] == 1.0 && self.joint_attrs[j].is_none() => {
                self.joint_attrs[j] = Some(format!(" stiffness=\"{stiffness}\" springref=\"{}\"", num(e.offset)));
                Representation::Joint { joint: j }
            }
            _ if nonzero.is_empty() => Representation::Callback { reason: "the coupling is zero".into() },
            _ => {
                // A single springlength of exactly −1 means "the length at qpos_spring" to
                // MuJoCo: negate the tendon (L' = −L, L₀' = 1), which leaves the odd
                // force laws of linear and cubic springs unchanged.
                let negated = e.offset == -1.0;
                let sign = if negated { -1.0 } else { 1.0 };
                let _ = write!(
                    self.tendons,
                    "    <fixed name=\"{name}\" stiffness=\"{stiffness}\" springlength=\"{}\">\n{}    </fixed>\n",
                    num(sign * e.offset),
                    coefs(e, nonzero, sign)
                );
                Representation::FixedTendon { negated }
            }
        }
    }

    /// A linear, cubic or compression element on a tendon's coupling with drum radius `rho_mm`:
    /// a fixed tendon whose coefficients are the pulley radii ρ·aᵢ (m), so its length is ρ·x,
    /// with the stiffness scaled so that the force law on x is the element's: ½ k (x − x₀)² =
    /// ½ (k/ρ²) (L − ρx₀)², ¼ k (x − x₀)⁴ = ¼ (k/ρ⁴) (L − ρx₀)⁴.
    fn pulley_tendon(&mut self, name: &str, e: &Element, k: f64, nonzero: &[usize], rho_mm: f64) -> Representation {
        let rho = rho_mm * 1e-3;
        let x0 = rho * e.offset;
        let (stiffness, length, dead_band) = match e.profile {
            Profile::Cubic => (format!("0 0 {}", num(k / rho.powi(4))), num(x0), false),
            Profile::Compression(Side::Plus) => {
                (num(k / (rho * rho)), format!("{} {}", num(-DEAD_BAND_FAR), num(x0)), true)
            }
            Profile::Compression(Side::Minus) => {
                (num(k / (rho * rho)), format!("{} {}", num(x0), num(DEAD_BAND_FAR)), true)
            }
            _ => (num(k / (rho * rho)), num(x0), false),
        };
        // A single springlength of exactly −1 is MuJoCo's "length at qpos_spring": negate the
        // tendon (L' = −L, L₀' = 1), which leaves the odd force laws of linear and cubic springs
        // unchanged.
        let negated = !dead_band && x0 == -1.0;
        let (sign, length) = if negated { (-1.0, num(1.0)) } else { (1.0, length) };
        let _ = write!(
            self.tendons,
            "    <fixed name=\"{name}\" stiffness=\"{stiffness}\" springlength=\"{length}\">\n{}    </fixed>\n",
            coefs(e, nonzero, sign * rho)
        );
        Representation::PulleyTendon { scale_mm: rho_mm, dead_band, negated }
    }

    /// A compression spring: a fixed tendon with no force inside its dead band.
    fn dead_band(&mut self, name: &str, e: &Element, k: f64, side: Side, nonzero: &[usize]) -> Representation {
        // No force inside [lo, hi]: side + engages above x₀, side − below.
        let (lo, hi) = match side {
            Side::Plus => (-DEAD_BAND_FAR, e.offset),
            Side::Minus => (e.offset, DEAD_BAND_FAR),
        };
        let _ = write!(
            self.tendons,
            "    <fixed name=\"{name}\" stiffness=\"{}\" springlength=\"{} {}\">\n{}    </fixed>\n",
            num(k),
            num(lo),
            num(hi),
            coefs(e, nonzero, 1.0)
        );
        Representation::DeadBand
    }

    /// A crank on joint j alone at ratio ±1: a zero-length spatial tendon between a site on
    /// each of the joint's links.
    fn crank(&mut self, chain: &Chain, name: &str, e: &Element, k: f64, j: usize) -> Representation {
        // 1 − cos(a q − x₀) = 1 − cos(q − a x₀) for a = ±1.
        let phase = e.coupling[j] * e.offset;
        let kappa = k / (CRANK_CHILD_RADIUS * CRANK_PARENT_RADIUS);
        let (parent, child) = crank_sites(chain, j, phase);
        self.sites[j].push(format!("<site name=\"{name}_parent\" pos=\"{}\" size=\"0.01\"/>", site_pos(chain, parent)));
        self.sites[j + 1]
            .push(format!("<site name=\"{name}_child\" pos=\"{}\" size=\"0.01\"/>", site_pos(chain, child)));
        let _ = write!(
            self.tendons,
            "    <spatial name=\"{name}\" stiffness=\"{}\" springlength=\"0\" width=\"0.003\">\n      <site site=\"{name}_parent\"/>\n      <site site=\"{name}_child\"/>\n    </spatial>\n",
            num(kappa)
        );
        Representation::SpatialCrank { joint: j }
    }

    /// Any other spring: a callback entry with its profile code, rate, offset and coupling.
    fn callback(&mut self, name: &str, e: &Element, k: f64, zero_coupling: bool) -> Representation {
        let mut data = vec![f64::from(callback_code(e.profile)), k, e.offset];
        data.extend_from_slice(&e.coupling);
        let data: Vec<String> = data.into_iter().map(num).collect();
        let _ = writeln!(self.customs, "    <numeric name=\"{CALLBACK_PREFIX}{name}\" data=\"{}\"/>", data.join(" "));
        Representation::Callback {
            reason: if zero_coupling {
                "the coupling is zero".into()
            } else {
                "a crank on a coupling (or with a gear ratio) has no built-in MuJoCo equivalent".into()
            },
        }
    }

    /// The MJCF text: the header and options, the bodies with their joints and sites, the
    /// tendons and the callback entries.
    fn xml(&self, design: &Design, elements: &[ExportedElement], timestep: f64) -> String {
        let chain = &design.chain;
        let mut x = String::new();
        let _ = writeln!(
            x,
            "<mujoco model=\"{}\">\n  <!-- Exported by springfit from {}: {} links, {} springs ({} exact, {} by passive-force callback).\n       Angles in radians; q = qpos ({}). See elements.md. -->",
            escape(&design.name),
            escape(&design.path.display().to_string().replace("--", "-")),
            design.dof(),
            elements.len(),
            elements.iter().filter(|e| e.representation.is_exact()).count(),
            elements.iter().filter(|e| !e.representation.is_exact()).count(),
            escape(&joint_meaning(chain).replace("--", "-"))
        );
        x.push_str("  <compiler angle=\"radian\" inertiafromgeom=\"false\" autolimits=\"true\"/>\n");
        let g: Vec<String> = gravity(chain).into_iter().map(num).collect();
        let _ = writeln!(
            x,
            "  <option timestep=\"{}\" integrator=\"RK4\" gravity=\"{}\">\n    <flag contact=\"disable\" energy=\"enable\"/>\n  </option>",
            num(timestep),
            match chain {
                Chain::Planar(_) => format!("{} {} 0", g[0], g[1]),
                Chain::Spatial(_) => g.join(" "),
            }
        );
        x.push_str(
            "  <default>\n    <joint type=\"hinge\" axis=\"0 0 1\" damping=\"0\" armature=\"0\" frictionloss=\"0\" limited=\"false\"/>\n    <geom type=\"capsule\" size=\"0.02\" contype=\"0\" conaffinity=\"0\" rgba=\"0.4 0.5 0.7 1\"/>\n  </default>\n",
        );
        self.write_worldbody(&mut x, chain);
        if !self.tendons.is_empty() {
            let _ = write!(x, "  <tendon>\n{}  </tendon>\n", self.tendons);
        }
        if !self.customs.is_empty() {
            let _ = write!(x, "  <custom>\n{}  </custom>\n", self.customs);
        }
        x.push_str("</mujoco>\n");
        x
    }

    /// The world's sites and the bodies nested one in the next, each with its joint (and the
    /// joint's spring attributes), inertia, geometry and sites.
    fn write_worldbody(&self, x: &mut String, chain: &Chain) {
        x.push_str("  <worldbody>\n");
        for s in &self.sites[0] {
            let _ = writeln!(x, "    {s}");
        }
        let mut indent = String::from("    ");
        for (i, body) in body_texts(chain).iter().enumerate() {
            let _ = writeln!(x, "{indent}<body name=\"link{}\" {}>", i + 1, body.placement);
            indent.push_str("  ");
            let attrs = self.joint_attrs[i].as_deref().unwrap_or("");
            let _ = writeln!(x, "{indent}<joint name=\"q{}\"{}{attrs}/>", i + 1, body.axis);
            let _ = writeln!(x, "{indent}{}", body.inertial);
            let _ = writeln!(x, "{indent}{}", body.geom);
            for s in &self.sites[i + 1] {
                let _ = writeln!(x, "{indent}{s}");
            }
        }
        for _ in 0..self.joint_attrs.len() {
            indent.truncate(indent.len() - 2);
            let _ = writeln!(x, "{indent}</body>");
        }
        x.push_str("  </worldbody>\n");
    }
}

/// A fixed tendon's joints and coefficients: `factor` × the coupling's non-zero entries (±1, or a
/// tendon's drum radius in m, which makes them its pulley radii).
fn coefs(e: &Element, nonzero: &[usize], factor: f64) -> String {
    let mut s = String::new();
    for &j in nonzero {
        let _ = writeln!(s, "      <joint joint=\"q{}\" coef=\"{}\"/>", j + 1, num(factor * e.coupling[j]));
    }
    s
}

/// The names `springfit export --mujoco` may write for `design` (see
/// [`crate::report::output::Plan`]).
pub fn files(design: &Design) -> Vec<String> {
    vec![format!("{}.xml", design.name), "elements.md".into(), "bom.csv".into(), "cams/*".into()]
}

/// Writes the export of `rows` into the folder `target` under `plan` ([`files`]): the model
/// `<design name>.xml` (RK4 at the design's `[simulate] rate`), `elements.md` saying where the
/// springs came from (`from`), and the bill of materials exported. The command and the Python
/// package's `export_mujoco` both go through here.
pub fn write_folder(
    claim: crate::report::output::Claim,
    design: &Design,
    rows: &[BomRow],
    from: &str,
) -> Result<(MujocoModel, std::path::PathBuf)> {
    let model = export(design, rows, 1.0 / design.simulate.rate)?;
    let xml_name = format!("{}.xml", design.name);
    let dir = claim.open()?;
    dir.write(&xml_name, &model.xml)?;
    dir.write("elements.md", elements_md(design, &model, from, &xml_name))?;
    crate::files::bom::write(&dir, "bom.csv", rows)?;
    let written = dir.commit()?;
    Ok((model, written))
}

/// `elements.md`: how each element is represented, and what the export chose where the design
/// says nothing (inertias about the other axes, the plane, the step).
pub fn elements_md(design: &Design, model: &MujocoModel, springs_from: &str, xml_name: &str) -> String {
    let mut s = format!("# MuJoCo export: {}\n\n", design.name);
    let _ = writeln!(
        s,
        "Model: [{xml_name}]({xml_name}); springs from {springs_from} ([bom.csv](bom.csv)). {} elements: **{} exact**, **{} by passive-force callback**.\n",
        model.elements.len(),
        model.exact_count(),
        model.callback_count()
    );
    s.push_str("| id | element | stiffness | MuJoCo | exact |\n| --- | --- | --- | --- | --- |\n");
    for e in &model.elements {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} (`{}`) | {} |",
            e.id,
            e.label,
            e.stiffness,
            e.representation.describe(),
            e.name,
            if e.representation.is_exact() { "exact" } else { "callback" }
        );
    }
    s.push_str("\n## What the model contains\n\n");
    match &design.chain {
        Chain::Planar(p) => {
            let [gx, gy] = p.gravity();
            let _ = write!(
                s,
                "- Bodies `link1` … `link{n}` in the x–y plane, hinge joints `q1` … `q{n}` about z (parallel axes);
  `qpos` is springfit's q (q1 from the x axis, qi relative to the previous link), angles in radians
  (`<compiler angle=\"radian\"/>`).
- Each body: the link's mass, its centre of mass on the link's x axis, and `diaginertia` =
  ({r} I, I, I) with I the link's inertia about its centre of mass. Only I (about z, the joint
  axis) acts in a planar motion; the others are a slender link's (small about its long axis x,
  equal to I about y) so that MuJoCo gets a valid inertia.
- Gravity ({gx}, {gy}, 0) m/s² as in the design; ",
                n = design.dof(),
                r = AXIAL_INERTIA_RATIO,
            );
        }
        Chain::Spatial(sp) => {
            let [gx, gy, gz] = sp.gravity();
            let joints: Vec<String> =
                sp.bodies().iter().enumerate().map(|(i, b)| format!("`q{}` = `{}`", i + 1, b.joint)).collect();
            let _ = write!(
                s,
                "- Bodies `link1` … `link{n}`, hinge joints {joints} about the URDF's axes; `qpos` is springfit's
  q (the URDF joint angles), angles in radians (`<compiler angle=\"radian\"/>`). The world is the
  URDF's base frame; links before the first moving joint do not move and are left out.
- Each body is everything that moves rigidly with its joint: the joint's child link and every link
  hanging below it through fixed or held joints, the held joints welded at their held values
  (`robot.locked`; others at 0). Its `pos` and `quat` are the joint frame in the previous body's
  frame, its `<inertial>` the merged mass, centre of mass and full inertia tensor in the body frame
  (the frame of the joint's child link), exactly what springfit integrates.
- Gravity ({gx}, {gy}, {gz}) m/s² in the base frame, as in the design; ",
                n = design.dof(),
                joints = joints.join(", "),
            );
        }
    }
    let _ = write!(
        s,
        "no damping, armature or friction loss; contacts
  off (the capsules are for viewing only); `integrator=\"RK4\"`, `timestep` = {dt} s (springfit's step,
  1 / `simulate.rate`).
- Cranks on one joint: a zero-rest-length spatial tendon from a site at {d} m from the joint axis
  on the parent (at the crank's phase) to a site at {r2} m on the child, both in the plane through
  the joint orthogonal to its axis, stiffness κ = k / ({r2} · {d}): ½κL² = const + k (1 − cos(q − x₀)),
  exactly.
- Dead bands: compression side + is `springlength=\"-{far} x₀\"` (force only for x > x₀), side − is
  `\"x₀ {far}\"`.
- Callback elements are listed as `<custom><numeric name=\"{prefix}<name>\">` with data
  [code, k, x₀, a₁ … aₙ] (code 1 linear, 2 cubic, 3 crank, 4 compression +, 5 compression −). Add
  −a · k u′(a·q − x₀) to `qfrc_passive` in `mjcb_passive`, which MuJoCo calls at every RK4 stage;
  `scripts/verify_mujoco.py` in the springfit repository does this.
- Cams are listed as `<custom><numeric name=\"{cam_prefix}<name>\">` with data
  [N, h, x_lo, a₁ … aₙ, c₀ … c_(N+1)]: V(x) = Σⱼ cⱼ Bⱼ(x − x_lo), cubic B-splines on N uniform
  knots of spacing h (continued beyond the knots by their second-order Taylor polynomials); add
  −a V′(a·q) in the same callback.
",
        dt = model.timestep,
        d = CRANK_PARENT_RADIUS,
        r2 = CRANK_CHILD_RADIUS,
        far = DEAD_BAND_FAR,
        prefix = CALLBACK_PREFIX,
        cam_prefix = CAM_PREFIX,
    );
    if design.simulate.integrator != crate::design::simulate::Integrator::Rk4 {
        s.push_str("\nNote: this design simulates with the adaptive integrator; MuJoCo uses RK4 at the step above, so trajectories agree only to that step's accuracy.\n");
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::elements::Element;

    fn design() -> Design {
        Design::load(&std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("designs/double_pendulum.toml"))
            .unwrap()
    }

    fn row(id: &str, profile: Profile, coupling: &[f64], offset: f64, k: f64) -> BomRow {
        BomRow {
            id: id.into(),
            family: "f".into(),
            element: Element { profile, coupling: coupling.to_vec(), offset },
            stiffness: k,
            max_torque_nm: 0.0,
            max_deflection_rad: 0.0,
            stock_rate: None,
            tolerance: 0.0,
            preload_nm: None,
            adjust: crate::fit::bill::Adjustment::default(),
            cam: None,
            pulleys_mm: None,
        }
    }

    #[test]
    fn each_profile_gets_its_representation() {
        let rows = vec![
            row("S01", Profile::Linear, &[1.0, 0.0], 0.25, 3.0),
            row("S02", Profile::Linear, &[1.0, 0.0], 0.5, 2.0),
            row("S03", Profile::Cubic, &[0.0, 1.0], 1.5, 0.7),
            row("S04", Profile::Linear, &[1.0, -2.0], -1.0, 1.0),
            row("S05", Profile::Compression(Side::Plus), &[1.0, 1.0], 0.3, 4.0),
            row("S06", Profile::Compression(Side::Minus), &[0.0, 1.0], -0.2, 5.0),
            row("S07", Profile::Crank, &[0.0, -1.0], 0.4, 6.0),
            row("S08", Profile::Crank, &[1.0, 2.0], 0.1, 7.0),
        ];
        let m = export(&design(), &rows, 0.001).unwrap();
        let reps: Vec<_> = m.elements.iter().map(|e| e.representation.clone()).collect();
        assert_eq!(reps[0], Representation::Joint { joint: 0 });
        // The joint already holds S01: the second linear spring on q1 becomes a tendon.
        assert_eq!(reps[1], Representation::FixedTendon { negated: false });
        assert_eq!(reps[2], Representation::Joint { joint: 1 });
        assert_eq!(reps[3], Representation::FixedTendon { negated: true });
        assert_eq!(reps[4], Representation::DeadBand);
        assert_eq!(reps[5], Representation::DeadBand);
        assert_eq!(reps[6], Representation::SpatialCrank { joint: 1 });
        assert!(matches!(reps[7], Representation::Callback { .. }));
        assert_eq!((m.exact_count(), m.callback_count()), (7, 1));
        let x = &m.xml;
        assert!(x.contains("<compiler angle=\"radian\""), "angles must be radians");
        assert!(x.contains("integrator=\"RK4\"") && x.contains("timestep=\"0.001\""));
        assert!(x.contains("<joint name=\"q1\" stiffness=\"3.0\" springref=\"0.25\"/>"), "{x}");
        assert!(x.contains("<joint name=\"q2\" stiffness=\"0 0 0.7\" springref=\"1.5\"/>"), "{x}");
        // x₀ = −1 is written negated: springlength 1 with coefficients −a.
        assert!(x.contains("<fixed name=\"S04\" stiffness=\"1.0\" springlength=\"1.0\">"), "{x}");
        assert!(x.contains("<joint joint=\"q1\" coef=\"-1.0\"/>") && x.contains("coef=\"2.0\""), "{x}");
        assert!(!x.contains("springlength=\"-1.0\""), "{x}");
        assert!(x.contains("springlength=\"-1000000000.0 0.3\""), "side + engages above x₀: {x}");
        assert!(x.contains("springlength=\"-0.2 1000000000.0\""), "side − engages below x₀: {x}");
        // Crank on −q₂ at 0.4: the parent site sits at phase −0.4 around joint 2 (at x = l₁ = 2).
        let (s, c) = (-0.4f64).sin_cos();
        assert!(
            x.contains(&format!("pos=\"{:?} {:?} 0\"", 2.0 + CRANK_PARENT_RADIUS * c, CRANK_PARENT_RADIUS * s)),
            "{x}"
        );
        assert!(x.contains(&format!(
            "stiffness=\"{:?}\" springlength=\"0\"",
            6.0 / (CRANK_CHILD_RADIUS * CRANK_PARENT_RADIUS)
        )));
        assert!(x.contains("<numeric name=\"springfit_callback_S08\" data=\"3.0 7.0 0.1 1.0 2.0\"/>"), "{x}");
        let md = elements_md(&design(), &m, "a test", "t.xml");
        assert!(md.contains("| S08 |") && md.contains("callback |") && md.contains("7 exact"), "{md}");
    }

    /// A coupling only a tendon makes (1 : 0.7 is no bevel ratio) becomes a fixed tendon whose
    /// coefficients are its pulley radii in m (ρ = 40 mm at the default `[parts]` limits), its
    /// stiffness scaled so that the torque on every joint is the element's.
    #[test]
    fn a_tendon_coupling_is_a_fixed_tendon_on_its_pulley_radii() {
        let rows = vec![
            row("T1", Profile::Linear, &[1.0, 0.7], 0.3, 2.0),
            row("T2", Profile::Compression(Side::Minus), &[0.3, -1.0], 0.1, 3.0),
            row("T3", Profile::Crank, &[1.0, 0.7], 0.3, 2.0),
        ];
        let m = export(&design(), &rows, 0.001).unwrap();
        let reps: Vec<_> = m.elements.iter().map(|e| e.representation.clone()).collect();
        assert_eq!(reps[0], Representation::PulleyTendon { scale_mm: 40.0, dead_band: false, negated: false });
        assert_eq!(reps[1], Representation::PulleyTendon { scale_mm: 40.0, dead_band: true, negated: false });
        assert!(matches!(reps[2], Representation::Callback { .. }), "{:?}", reps[2]);
        let x = &m.xml;
        let (rho, k) = (0.04, 2.0);
        assert!(
            x.contains(&format!(
                "<fixed name=\"T1\" stiffness=\"{:?}\" springlength=\"{:?}\">",
                k / (rho * rho),
                rho * 0.3
            )),
            "{x}"
        );
        assert!(x.contains(&format!("coef=\"{:?}\"", rho * 0.7)), "{x}");
        // The torque on joint j: coefⱼ · (−k/ρ²)(L − ρx₀) with L = Σ coefᵢ qᵢ is −k aⱼ (a·q − x₀).
        let q = [0.4, -0.9];
        let l: f64 = rho * q[0] + rho * 0.7 * q[1];
        let tau = rho * 0.7 * (-k / (rho * rho)) * (l - rho * 0.3);
        assert!((tau - (-k * 0.7 * (q[0] + 0.7 * q[1] - 0.3))).abs() < 1e-12);
    }

    #[test]
    fn the_crank_sites_reproduce_k_sin() {
        // The geometry behind the spatial-tendon crank: ½κL² − const = k (1 − cos(q − x₀)).
        let (k, x0): (f64, f64) = (2.5, 0.7);
        let kappa = k / (CRANK_CHILD_RADIUS * CRANK_PARENT_RADIUS);
        let half_l2 = |q: f64| {
            let p = [CRANK_PARENT_RADIUS * x0.cos(), CRANK_PARENT_RADIUS * x0.sin()];
            let c = [CRANK_CHILD_RADIUS * q.cos(), CRANK_CHILD_RADIUS * q.sin()];
            0.5 * kappa * ((c[0] - p[0]).powi(2) + (c[1] - p[1]).powi(2))
        };
        let offset = half_l2(x0);
        for q in [-2.0, -0.3, 0.7, 1.9, 3.0] {
            let want = k * (1.0 - (q - x0).cos());
            assert!((half_l2(q) - offset - want).abs() < 1e-12, "q = {q}");
        }
    }

    #[test]
    fn spatial_crank_sites_reproduce_k_sin_about_a_tilted_axis() {
        // A joint frame turned and moved in its parent, its axis tilted: the child site, carried
        // by the turn about the axis, and the parent site, brought into the joint frame, keep
        // ½κL² − const = k (1 − cos(q − x₀)).
        use crate::model::{Body, SpatialChain};
        let rotation = *Rotation3::from_euler_angles(0.3, -0.7, 1.1).matrix();
        let translation = Vector3::new(0.2, -0.1, 0.4);
        let axis = Vector3::new(0.3, -0.5, 0.8).normalize();
        let body = Body {
            joint: "j".into(),
            rotation,
            translation,
            axis,
            mass: 1.0,
            com: Vector3::zeros(),
            inertia: Matrix3::identity(),
        };
        let chain = Chain::Spatial(SpatialChain::new(vec![body], [0.0, 0.0, -9.81], [0.0, 0.0, 0.0]));
        let (k, x0): (f64, f64) = (2.5, 0.7);
        let kappa = k / (CRANK_CHILD_RADIUS * CRANK_PARENT_RADIUS);
        let (parent, child) = crank_sites(&chain, 0, x0);
        let parent = rotation.transpose() * (Vector3::from(parent) - translation);
        let half_l2 = |q: f64| {
            let turn = Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(axis), q);
            0.5 * kappa * (turn * Vector3::from(child) - parent).norm_squared()
        };
        let offset = half_l2(x0);
        for q in [-2.0, -0.3, 0.7, 1.9, 3.0] {
            let want = k * (1.0 - (q - x0).cos());
            assert!((half_l2(q) - offset - want).abs() < 1e-12, "q = {q}: {} vs {want}", half_l2(q) - offset);
        }
    }

    #[test]
    fn bodies_nest_with_masses_and_inertias() {
        let m = export(&design(), &[], 0.002).unwrap();
        let x = &m.xml;
        assert!(x.contains("<body name=\"link1\" pos=\"0.0 0 0\">"));
        assert!(x.contains("<body name=\"link2\" pos=\"2.0 0 0\">"));
        assert!(x.contains("<inertial pos=\"1.0 0 0\" mass=\"1.0\" diaginertia=\"0.01 1.0 1.0\"/>"), "{x}");
        assert_eq!(x.matches("<body ").count(), 2);
        assert_eq!(x.matches("</body>").count(), 2);
        assert!(x.contains("damping=\"0\" armature=\"0\" frictionloss=\"0\""));
        assert!(!x.contains("<tendon>") && !x.contains("<custom>"));
    }

    #[test]
    fn a_bill_for_another_arm_is_refused() {
        let rows = vec![row("S01", Profile::Linear, &[1.0, 0.0, 0.0], 0.0, 1.0)];
        let err = export(&design(), &rows, 0.001).unwrap_err().to_string();
        assert!(err.contains("S01") && err.contains("3 joints"), "{err}");
    }
}
