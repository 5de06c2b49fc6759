//! URDF input: the joints that move, the rest held, as a [`SpatialChain`].
//!
//! A URDF is a tree of links joined by joints. The design names the joints that move and get
//! springs (in order from the base) and holds every other joint at a given value (`locked`;
//! unlisted movable joints are held at 0). Everything that then moves rigidly with moving joint
//! i, through fixed or held joints, is merged into body i: masses add, centres of mass and
//! inertias are carried into body i's frame (the frame of the moving joint's child link). Links
//! that never move (before the first moving joint) do not enter the dynamics.
//!
//! What cannot be used is refused with the URDF file and element named: a chosen joint that is
//! missing, prismatic, fixed or floating; chosen joints that are not one chain in the given
//! order; a moving joint's link without inertial data; a mimic joint that follows a moving joint
//! (it would couple joints, which springfit does not model). A mimic joint that follows a held
//! joint is held too, at `multiplier · leader + offset` (a gripper's second finger), unless the
//! design locks it itself. Every held joint must sit within its `<limit>` (a pose the arm cannot
//! take is refused, naming the joint, the value and the limits). Inertial data must be physical:
//! positive mass, an inertia tensor that is positive definite and satisfies the triangle inequality of its principal moments, every
//! value finite and within the limits of `docs/limits.md`.

use std::collections::HashMap;
use std::path::Path;

use nalgebra::{Matrix3, Rotation3, Vector3};
use urdf_rs::JointType;

use super::spatial::{Body, MAX_BODIES, SpatialChain};
use crate::error::{Error, Result};
use crate::limits::{MAX_ANGLE_RAD, MAX_INERTIA_KGM2, MAX_LENGTH_M, MAX_MASS_KG, show, within};

/// A rigid placement: rotation then translation.
#[derive(Debug, Clone, Copy)]
struct Pose {
    rot: Matrix3<f64>,
    pos: Vector3<f64>,
}

impl Pose {
    fn identity() -> Self {
        Pose { rot: Matrix3::identity(), pos: Vector3::zeros() }
    }

    fn from_urdf(p: &urdf_rs::Pose) -> Self {
        let [r, pi, y] = p.rpy.0;
        Pose { rot: *Rotation3::from_euler_angles(r, pi, y).matrix(), pos: Vector3::from(p.xyz.0) }
    }

    fn then(&self, other: &Pose) -> Pose {
        Pose { rot: self.rot * other.rot, pos: self.pos + self.rot * other.pos }
    }
}

/// What a moving joint's `<limit>` allows: the region of a real arm must stay within it.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum JointRange {
    /// A revolute joint with `lower < upper` (rad).
    Limited {
        /// The lower limit, rad.
        lower: f64,
        /// The upper limit, rad.
        upper: f64,
    },
    /// A continuous joint, or a planar arm's joint: it turns without end.
    Unlimited,
    /// A revolute joint whose `<limit>` gives no range (missing, or lower = upper): springfit
    /// assumes it turns freely and says so, since a real joint almost always stops somewhere.
    Unstated,
}

impl JointRange {
    /// The range as (lower, upper), infinite where the joint has no stated stop.
    pub fn bounds(&self) -> (f64, f64) {
        match *self {
            JointRange::Limited { lower, upper } => (lower, upper),
            JointRange::Unlimited | JointRange::Unstated => (f64::NEG_INFINITY, f64::INFINITY),
        }
    }
}

/// Reads `urdf` and builds the chain of `joints` (base first) with the other joints held at
/// `locked` (name, value in rad or m for a prismatic joint) and gravity in the base frame.
pub fn load(urdf: &Path, joints: &[String], locked: &[(String, f64)], gravity: [f64; 3]) -> Result<SpatialChain> {
    load_with_ranges(urdf, joints, locked, gravity).map(|(chain, _)| chain)
}

/// [`load`], and the `<limit>` of each moving joint in the order of `joints`.
pub fn load_with_ranges(
    urdf: &Path,
    joints: &[String],
    locked: &[(String, f64)],
    gravity: [f64; 3],
) -> Result<(SpatialChain, Vec<JointRange>)> {
    if urdf.is_dir() {
        return Err(Error::io(urdf, std::io::Error::other("is a folder: robot.urdf names the robot's .urdf file")));
    }
    let text = std::fs::read_to_string(urdf).map_err(|e| Error::io(urdf, e))?;
    parse_with_ranges(urdf, &text, joints, locked, gravity)
}

/// [`load`] on the text of a URDF; `urdf` names it in errors.
///
/// The steps, each refusing what it cannot use: the tree of links and joints, the joints chosen
/// to move, the values the others are held at (and their limits), the walk from the base that
/// places every link on the moving body it rides on, then each body's mass and inertia.
pub fn parse(
    urdf: &Path,
    text: &str,
    joints: &[String],
    locked: &[(String, f64)],
    gravity: [f64; 3],
) -> Result<SpatialChain> {
    parse_with_ranges(urdf, text, joints, locked, gravity).map(|(chain, _)| chain)
}

/// [`parse`], and the `<limit>` of each moving joint in the order of `joints`.
pub fn parse_with_ranges(
    urdf: &Path,
    text: &str,
    joints: &[String],
    locked: &[(String, f64)],
    gravity: [f64; 3],
) -> Result<(SpatialChain, Vec<JointRange>)> {
    let robot = urdf_rs::read_from_string(text).map_err(|e| Error::Parse {
        path: urdf.to_path_buf(),
        line: 0,
        column: 0,
        message: format!(
            "cannot be read as a URDF ({e}): the file must be one complete <robot> element of well-formed XML; a file cut short, or saved from a xacro without expanding it, reads like this"
        ),
    })?;
    let bad = Bad(urdf);
    let tree = Tree::new(&robot, bad)?;
    let chosen = chosen(&robot, &tree, joints, bad)?;
    let held = held(&robot, &tree, &chosen, locked, bad)?;
    check_limits(&robot, &chosen, &held, locked, bad)?;
    let walk = walk(&robot, &tree, &chosen, &held, joints, bad)?;
    let merged = merge(&robot, &tree, &walk.placed, joints, bad)?;
    // A chosen joint the walk never reached sits in a loop of links cut off from the base.
    let Some(placements) = walk.bodies.iter().copied().collect::<Option<Vec<_>>>() else {
        let k = walk.bodies.iter().position(Option::is_none).unwrap_or(0);
        return Err(bad.joint(
            &joints[k],
            format!("cannot be reached from the base link `{}`: its links form a loop", robot.links[tree.root].name),
        ));
    };
    // `chosen` found every name in the file.
    let ranges = joints
        .iter()
        .map(|name| tree.joint_index.get(name.as_str()).map_or(JointRange::Unlimited, |&j| range(&robot.joints[j])))
        .collect();
    Ok((merged.chain(&placements, joints, gravity), ranges))
}

/// A moving joint's range: continuous joints turn freely; a revolute joint's `<limit>` reads
/// lower = upper = 0 when it is missing (urdf-rs's default), which is no range at all.
fn range(joint: &urdf_rs::Joint) -> JointRange {
    let (lower, upper) = (joint.limit.lower, joint.limit.upper);
    match joint.joint_type {
        JointType::Revolute if lower < upper && lower.is_finite() && upper.is_finite() => {
            JointRange::Limited { lower, upper }
        }
        JointType::Revolute => JointRange::Unstated,
        _ => JointRange::Unlimited,
    }
}

/// Errors on the URDF file, naming the element (`<joint name="…">`, `<link name="…">`,
/// `<robot>`) as its author would search for it.
#[derive(Clone, Copy)]
struct Bad<'a>(&'a Path);

impl Bad<'_> {
    fn joint(self, name: &str, reason: impl Into<String>) -> Error {
        Error::invalid(self.0, format!("<joint name=\"{name}\">"), reason)
    }

    fn link(self, name: &str, reason: impl Into<String>) -> Error {
        Error::invalid(self.0, format!("<link name=\"{name}\">"), reason)
    }

    fn robot(self, reason: impl Into<String>) -> Error {
        Error::invalid(self.0, "<robot>", reason)
    }
}

/// The tree: links and joints by name, the joint above each link, the joints below each link,
/// the one root link.
struct Tree<'r> {
    link_index: HashMap<&'r str, usize>,
    joint_index: HashMap<&'r str, usize>,
    above: Vec<Option<usize>>,
    below: Vec<Vec<usize>>,
    root: usize,
}

impl<'r> Tree<'r> {
    /// The tree of `robot`: names unique, every joint's links in the file, every link the child
    /// of at most one joint, one root.
    fn new(robot: &'r urdf_rs::Robot, bad: Bad) -> Result<Tree<'r>> {
        let mut link_index: HashMap<&str, usize> = HashMap::new();
        for (i, l) in robot.links.iter().enumerate() {
            if link_index.insert(l.name.as_str(), i).is_some() {
                return Err(bad.link(&l.name, "is defined twice: every link needs its own name"));
            }
        }
        let mut joint_index: HashMap<&str, usize> = HashMap::new();
        for (i, j) in robot.joints.iter().enumerate() {
            if joint_index.insert(j.name.as_str(), i).is_some() {
                return Err(bad.joint(&j.name, "is defined twice: every joint needs its own name"));
            }
        }
        let mut above: Vec<Option<usize>> = vec![None; robot.links.len()];
        let mut below: Vec<Vec<usize>> = vec![Vec::new(); robot.links.len()];
        for (j, joint) in robot.joints.iter().enumerate() {
            let parent = *link_index.get(joint.parent.link.as_str()).ok_or_else(|| {
                bad.joint(&joint.name, format!("its parent link `{}` is not in the file", joint.parent.link))
            })?;
            let child = *link_index.get(joint.child.link.as_str()).ok_or_else(|| {
                bad.joint(&joint.name, format!("its child link `{}` is not in the file", joint.child.link))
            })?;
            if let Some(other) = above[child] {
                return Err(bad.link(
                    &joint.child.link,
                    format!(
                        "is the child of two joints (`{}` and `{}`): a URDF is a tree",
                        robot.joints[other].name, joint.name
                    ),
                ));
            }
            above[child] = Some(j);
            below[parent].push(j);
        }
        let roots: Vec<usize> = (0..robot.links.len()).filter(|&l| above[l].is_none()).collect();
        let [root] = roots[..] else {
            let names: Vec<&str> = roots.iter().map(|&l| robot.links[l].name.as_str()).collect();
            return Err(bad.robot(format!(
                "has {} root links ({}): springfit needs one tree with one base",
                roots.len(),
                names.join(", ")
            )));
        };
        Ok(Tree { link_index, joint_index, above, below, root })
    }

    /// Whether joint `j` lies above joint `c` in the tree (so `c` moves with whatever `j` does).
    fn descends(&self, robot: &urdf_rs::Robot, c: usize, j: usize) -> bool {
        let mut link = self.link_index[robot.joints[c].parent.link.as_str()];
        while let Some(up) = self.above[link] {
            if up == j {
                return true;
            }
            link = self.link_index[robot.joints[up].parent.link.as_str()];
        }
        false
    }
}

/// The chosen joints, as the file's joint index → the position in `joints`: 1 to MAX_BODIES
/// revolute or continuous joints, each once, none a mimic joint, and no mimic joint following
/// one of them.
fn chosen(robot: &urdf_rs::Robot, tree: &Tree, joints: &[String], bad: Bad) -> Result<HashMap<usize, usize>> {
    if joints.is_empty() || joints.len() > MAX_BODIES {
        return Err(
            bad.robot(format!("{} joints chosen: springfit moves 1 to {MAX_BODIES} revolute joints", joints.len()))
        );
    }
    let movable = || {
        robot
            .joints
            .iter()
            .filter(|j| matches!(j.joint_type, JointType::Revolute | JointType::Continuous))
            .map(|j| j.name.as_str())
            .collect::<Vec<_>>()
            .join(", ")
    };
    let mut chosen: HashMap<usize, usize> = HashMap::new();
    for (k, name) in joints.iter().enumerate() {
        let j = *tree.joint_index.get(name.as_str()).ok_or_else(|| {
            bad.joint(name, format!("no such joint in the file; its revolute joints are: {}", movable()))
        })?;
        let joint = &robot.joints[j];
        match joint.joint_type {
            JointType::Revolute | JointType::Continuous => {}
            JointType::Prismatic => {
                return Err(
                    bad.joint(name, "is prismatic: springfit moves revolute joints only (hold it with `locked`)")
                );
            }
            ref other => {
                return Err(bad.joint(
                    name,
                    format!("is {other:?} (lower-case in the file): only revolute and continuous joints can move"),
                ));
            }
        }
        if joint.mimic.is_some() {
            return Err(
                bad.joint(name, "is a mimic joint: it follows another joint, which springfit does not model (refused)")
            );
        }
        if chosen.insert(j, k).is_some() {
            return Err(bad.joint(name, "is chosen twice"));
        }
    }
    let leaders: Vec<&str> = joints.iter().map(String::as_str).collect();
    for joint in &robot.joints {
        let Some(m) = &joint.mimic else { continue };
        if leaders.contains(&m.joint.as_str()) {
            return Err(bad.joint(
                &joint.name,
                format!(
                    "is a mimic joint that follows the moving joint `{}`: coupled joints are not modelled (refused)",
                    m.joint
                ),
            ));
        }
    }
    Ok(chosen)
}

/// The values the joints that do not move are held at, by the file's joint index: `locked`
/// (revolute, continuous or prismatic joints that are not chosen), then each mimic joint of a
/// held joint where its leader puts it (unless locked itself). A joint in neither is held at 0.
fn held(
    robot: &urdf_rs::Robot,
    tree: &Tree,
    chosen: &HashMap<usize, usize>,
    locked: &[(String, f64)],
    bad: Bad,
) -> Result<HashMap<usize, f64>> {
    let mut held: HashMap<usize, f64> = HashMap::new();
    for (name, value) in locked {
        let j = *tree
            .joint_index
            .get(name.as_str())
            .ok_or_else(|| bad.joint(name, "is locked but there is no such joint in the file"))?;
        if chosen.contains_key(&j) {
            return Err(bad.joint(name, "is both chosen to move and locked"));
        }
        let joint = &robot.joints[j];
        if !matches!(joint.joint_type, JointType::Revolute | JointType::Continuous | JointType::Prismatic) {
            return Err(bad.joint(
                name,
                format!("is {:?}: only revolute, continuous and prismatic joints can be locked", joint.joint_type),
            ));
        }
        within(*value, MAX_ANGLE_RAD, "").map_err(|e| bad.joint(name, format!("locked at a value that {e}")))?;
        held.insert(j, *value);
    }
    for (j, joint) in robot.joints.iter().enumerate() {
        let Some(m) = &joint.mimic else { continue };
        if held.contains_key(&j) || chosen.contains_key(&j) {
            continue;
        }
        let leader = *tree.joint_index.get(m.joint.as_str()).ok_or_else(|| {
            bad.joint(&joint.name, format!("mimics the joint `{}`, which is not in the file", m.joint))
        })?;
        let value = m.multiplier.unwrap_or(1.0) * held.get(&leader).copied().unwrap_or(0.0) + m.offset.unwrap_or(0.0);
        held.insert(j, value);
    }
    Ok(held)
}

/// Every held joint within its limits: a hold outside them is a pose the arm cannot take.
/// Continuous joints have none; a revolute or prismatic joint without `<limit>` reads as
/// lower = upper = 0 and is not checked (only lower < upper is a range).
fn check_limits(
    robot: &urdf_rs::Robot,
    chosen: &HashMap<usize, usize>,
    held: &HashMap<usize, f64>,
    locked: &[(String, f64)],
    bad: Bad,
) -> Result<()> {
    for (j, joint) in robot.joints.iter().enumerate() {
        if chosen.contains_key(&j) || !matches!(joint.joint_type, JointType::Revolute | JointType::Prismatic) {
            continue;
        }
        let (lower, upper) = (joint.limit.lower, joint.limit.upper);
        let value = held.get(&j).copied().unwrap_or(0.0);
        if lower < upper && !(lower..=upper).contains(&value) {
            let unit = if joint.joint_type == JointType::Prismatic { "m" } else { "rad" };
            let how = match (&joint.mimic, locked.iter().any(|(n, _)| n == &joint.name)) {
                (_, true) => "robot.locked holds it".to_string(),
                (Some(m), false) => format!("it mimics `{}`, which holds it", m.joint),
                (None, false) => "it is neither moving nor in robot.locked, so it is held".to_string(),
            };
            return Err(bad.joint(
                &joint.name,
                format!(
                    "{how} at {} {unit}, outside its <limit> [{}, {}] {unit}: hold it within its limits (robot.locked)",
                    show(value),
                    show(lower),
                    show(upper)
                ),
            ));
        }
    }
    Ok(())
}

/// Where a link sits: the moving body it rides on (None before the first moving joint), its
/// pose in that body's frame (the base frame for None) and its depth in the tree.
#[derive(Clone, Copy)]
struct Placed {
    owner: Option<usize>,
    pose: Pose,
    depth: usize,
}

/// The walk from the base: every link placed (None: not reached), and each moving body's
/// placement in its parent body's frame with its unit axis (None: not reached).
struct Walk {
    placed: Vec<Option<Placed>>,
    bodies: Vec<Option<(Pose, Vector3<f64>)>>,
}

/// Walks the tree from the base: which moving body each link rides on, and where. The chosen
/// joints must be met in their order, each below the previous one.
fn walk(
    robot: &urdf_rs::Robot,
    tree: &Tree,
    chosen: &HashMap<usize, usize>,
    held: &HashMap<usize, f64>,
    joints: &[String],
    bad: Bad,
) -> Result<Walk> {
    let mut placed: Vec<Option<Placed>> = vec![None; robot.links.len()];
    let mut bodies: Vec<Option<(Pose, Vector3<f64>)>> = vec![None; joints.len()];
    let mut stack = vec![tree.root];
    placed[tree.root] = Some(Placed { owner: None, pose: Pose::identity(), depth: 0 });
    while let Some(link) = stack.pop() {
        // Every link on the stack was placed before it was pushed.
        let Some(Placed { owner, pose, depth }) = placed[link] else { continue };
        for &j in &tree.below[link] {
            let joint = &robot.joints[j];
            let child = tree.link_index[joint.child.link.as_str()];
            let origin = Pose::from_urdf(&joint.origin);
            let axis = Vector3::from(joint.axis.xyz.0);
            let unit = (axis.norm() > 0.0 && axis.iter().all(|x| x.is_finite())).then(|| axis.normalize());
            let zero_axis = || bad.joint(&joint.name, "has a zero or non-finite axis");
            let (child_owner, child_pose) = if let Some(&k) = chosen.get(&j) {
                let expected = k.checked_sub(1);
                if owner != expected {
                    return Err(bad.joint(&joint.name, out_of_order(expected, owner, joints, &joint.parent.link)));
                }
                bodies[k] = Some((pose.then(&origin), unit.ok_or_else(zero_axis)?));
                (Some(k), Pose::identity())
            } else {
                let value = held.get(&j).copied().unwrap_or(0.0);
                let motion = match joint.joint_type {
                    JointType::Fixed => Pose::identity(),
                    JointType::Revolute | JointType::Continuous => {
                        let u = nalgebra::Unit::new_unchecked(unit.ok_or_else(zero_axis)?);
                        Pose { rot: *Rotation3::from_axis_angle(&u, value).matrix(), pos: Vector3::zeros() }
                    }
                    JointType::Prismatic => Pose { rot: Matrix3::identity(), pos: unit.ok_or_else(zero_axis)? * value },
                    ref other => {
                        if owner.is_some() || chosen.keys().any(|&c| tree.descends(robot, c, j)) {
                            return Err(bad.joint(
                                &joint.name,
                                format!(
                                    "is {other:?}: springfit needs a fixed base and rigid links between the moving joints"
                                ),
                            ));
                        }
                        Pose::identity()
                    }
                };
                (owner, pose.then(&origin).then(&motion))
            };
            placed[child] = Some(Placed { owner: child_owner, pose: child_pose, depth: depth + 1 });
            stack.push(child);
        }
    }
    Ok(Walk { placed, bodies })
}

/// Why a chosen joint met on the walk is out of order: it should ride on body `expected` (None:
/// on nothing, the first) but rides on `owner`; `parent` is its parent link.
fn out_of_order(expected: Option<usize>, owner: Option<usize>, joints: &[String], parent: &str) -> String {
    match (expected, owner) {
        (None, Some(o)) => format!(
            "is the first joint in robot.joints but moves with `{}`: list the joints from the base outwards",
            joints[o]
        ),
        (Some(e), None) => format!(
            "does not hang below `{}` (its parent link `{parent}` does not move with it): the chosen joints are not one chain",
            joints[e]
        ),
        (Some(e), Some(o)) => format!(
            "hangs below `{}`, not below `{}` as robot.joints lists it: the chosen joints are not one chain in this order",
            joints[o], joints[e]
        ),
        // The walk asks only when the two differ.
        (None, None) => String::new(),
    }
}

/// The links riding on each moving body merged into it: mass, first moment and inertia about
/// the body's origin, and its tip (the deepest link's origin, with its depth).
struct Merged {
    mass: Vec<f64>,
    first: Vec<Vector3<f64>>,
    about_origin: Vec<Matrix3<f64>>,
    tip: Vec<(usize, Vector3<f64>)>,
}

/// Merges every link riding on body k into it, each link's inertial data checked, the link
/// right below a moving joint required to have some.
fn merge(
    robot: &urdf_rs::Robot,
    tree: &Tree,
    placed: &[Option<Placed>],
    joints: &[String],
    bad: Bad,
) -> Result<Merged> {
    let n = joints.len();
    let mut mass = vec![0.0; n];
    let mut first = vec![Vector3::zeros(); n];
    let mut about_origin = vec![Matrix3::zeros(); n];
    let mut tip: Vec<(usize, Vector3<f64>)> = vec![(0, Vector3::zeros()); n];
    for (l, link) in robot.links.iter().enumerate() {
        let Some(Placed { owner: Some(k), pose, depth }) = placed[l] else { continue };
        let inertial = &link.inertial;
        let i = &inertial.inertia;
        let local = Matrix3::new(i.ixx, i.ixy, i.ixz, i.ixy, i.iyy, i.iyz, i.ixz, i.iyz, i.izz);
        physical(inertial.mass.value, &local, &inertial.origin).map_err(|r| bad.link(&link.name, r))?;
        // A link riding on a body hangs below some joint.
        let is_body_link = tree.above[l].is_some_and(|j| robot.joints[j].name == joints[k]);
        if is_body_link && inertial.mass.value == 0.0 && local == Matrix3::zeros() {
            return Err(bad.link(
                &link.name,
                format!(
                    "moves with `{}` but has no inertial data (no <inertial>, or zero mass and inertia): springfit needs the mass, centre of mass and inertia of every link that moves",
                    joints[k]
                ),
            ));
        }
        let frame = pose.then(&Pose::from_urdf(&inertial.origin));
        let m = inertial.mass.value;
        let c = frame.pos;
        mass[k] += m;
        first[k] += c * m;
        about_origin[k] +=
            frame.rot * local * frame.rot.transpose() + (Matrix3::identity() * c.dot(&c) - c * c.transpose()) * m;
        if depth > tip[k].0 || (depth == tip[k].0 && pose.pos.norm() > tip[k].1.norm()) {
            tip[k] = (depth, pose.pos);
        }
    }
    Ok(Merged { mass, first, about_origin, tip })
}

impl Merged {
    /// The chain: each body at its placement about its axis, with its mass, centre of mass and
    /// inertia about the centre of mass.
    fn chain(&self, placements: &[(Pose, Vector3<f64>)], joints: &[String], gravity: [f64; 3]) -> SpatialChain {
        let (mass, first, about_origin) = (&self.mass, &self.first, &self.about_origin);
        let chain_bodies: Vec<Body> = placements
            .iter()
            .enumerate()
            .map(|(k, &(placement, axis))| {
                let com = if mass[k] > 0.0 { first[k] / mass[k] } else { Vector3::zeros() };
                let inertia = about_origin[k] - (Matrix3::identity() * com.dot(&com) - com * com.transpose()) * mass[k];
                Body {
                    joint: joints[k].clone(),
                    rotation: placement.rot,
                    translation: placement.pos,
                    axis,
                    mass: mass[k],
                    com,
                    inertia: (inertia + inertia.transpose()) * 0.5,
                }
            })
            .collect();
        let n = joints.len();
        let last = &chain_bodies[n - 1];
        // The tip: the origin of the deepest link riding on the last body, the farthest of equally
        // deep ones (its centre of mass when nothing hangs below it).
        let tip_point = if self.tip[n - 1].1 == Vector3::zeros() { last.com } else { self.tip[n - 1].1 };
        SpatialChain::new(chain_bodies, gravity, tip_point.into())
    }
}

/// Checks a link's inertial data: a finite mass in [0, MAX_MASS_KG] (0 only with no inertia: a
/// link without inertial data), an inertia tensor with finite entries within MAX_INERTIA_KGM2
/// that is positive semi-definite with principal moments obeying the triangle inequality
/// (Iₐ + I_b ≥ I_c, what any distribution of mass gives), positive definite when the link has
/// mass spread in space, and an origin within MAX_LENGTH_M.
fn physical(mass: f64, inertia: &Matrix3<f64>, origin: &urdf_rs::Pose) -> std::result::Result<(), String> {
    within(mass, MAX_MASS_KG, " kg").map_err(|e| format!("<inertial><mass value> {e}"))?;
    if mass < 0.0 {
        return Err(format!("has a negative mass {}: a mass must be positive (kg)", show(mass)));
    }
    for v in inertia.iter() {
        within(*v, MAX_INERTIA_KGM2, " kg·m²").map_err(|e| format!("<inertial><inertia> {e}"))?;
    }
    for v in origin.xyz.0.iter().chain(origin.rpy.0.iter()) {
        within(*v, MAX_LENGTH_M, "").map_err(|e| format!("<inertial><origin> {e}"))?;
    }
    if mass == 0.0 && *inertia != Matrix3::zeros() {
        return Err("has an inertia but zero mass: a body with inertia has mass".into());
    }
    let moments = inertia.symmetric_eigen().eigenvalues;
    let scale = moments.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let tol = 1e-9 * scale;
    let [a, b, c] = [moments[0], moments[1], moments[2]];
    if a.min(b).min(c) < -tol {
        return Err(format!(
            "has an inertia tensor that is not positive semi-definite (principal moments {}, {}, {} kg·m²): a body's moments of inertia are ≥ 0",
            show(a),
            show(b),
            show(c)
        ));
    }
    if a + b < c - tol || b + c < a - tol || a + c < b - tol {
        return Err(format!(
            "has principal moments of inertia {}, {}, {} kg·m² that break the triangle inequality (each is at most the sum of the other two for any body)",
            show(a),
            show(b),
            show(c)
        ));
    }
    Ok(())
}
