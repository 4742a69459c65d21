//! Robots from URDF: kinematic chains, forward kinematics, joint limits and the
//! geometric Jacobian.

use crate::error::{Error, Result};
use crate::geometry::{Isometry3, Pose, Vector3};
use nalgebra::{DMatrix, Translation3, Unit, UnitQuaternion};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// What a joint of a chain does.
#[derive(Clone, Debug, PartialEq)]
pub enum JointMotion {
    /// A rigid connection.
    Fixed,
    /// Rotation about `axis` (unit, joint frame) within `[lower, upper]` radians.
    Revolute {
        /// The rotation axis (unit, joint frame).
        axis: Unit<Vector3>,
        /// Lowest angle (rad).
        lower: f64,
        /// Highest angle (rad).
        upper: f64,
    },
    /// Unlimited rotation about `axis`.
    Continuous {
        /// The rotation axis (unit, joint frame).
        axis: Unit<Vector3>,
    },
    /// Translation along `axis` within `[lower, upper]` metres.
    Prismatic {
        /// The direction of travel (unit, joint frame).
        axis: Unit<Vector3>,
        /// Lowest position (m).
        lower: f64,
        /// Highest position (m).
        upper: f64,
    },
}

/// One joint of a chain: `parent_from_child(q) = origin · motion(q)`.
#[derive(Clone, Debug)]
pub struct ChainJoint {
    /// The URDF joint name.
    pub name: String,
    /// `parent_from_joint`: the joint's `<origin>`.
    pub origin: Isometry3,
    /// Its motion.
    pub motion: JointMotion,
}

impl ChainJoint {
    fn is_actuated(&self) -> bool {
        self.motion != JointMotion::Fixed
    }

    /// `joint_from_child` for the joint value `q`.
    fn motion_transform(&self, q: f64) -> Isometry3 {
        match &self.motion {
            JointMotion::Fixed => Isometry3::identity(),
            JointMotion::Revolute { axis, .. } | JointMotion::Continuous { axis } => {
                Isometry3::from_parts(
                    Translation3::identity(),
                    UnitQuaternion::from_axis_angle(axis, q),
                )
            }
            JointMotion::Prismatic { axis, .. } => Isometry3::from_parts(
                Translation3::from(axis.into_inner() * q),
                UnitQuaternion::identity(),
            ),
        }
    }
}

/// A robot model read from a URDF file.
#[derive(Clone, Debug)]
pub struct Robot {
    /// The robot's name in the URDF.
    pub name: String,
    /// The file it came from.
    pub source: PathBuf,
    links: Vec<String>,
    /// child link -> (parent link, joint)
    parent_joint: HashMap<String, (String, ChainJoint)>,
    /// What the user should know of the file that is not an error
    /// ([`Robot::notes`]).
    notes: Vec<String>,
}

/// How far a joint's limits may reach, in turns, before sigmap asks whether
/// they are degrees: real arms stop within two turns (the UR5's ±2π), a
/// limit written in degrees (±170) is 27 turns as radians.
const LIMIT_TURNS: f64 = 2.0;

/// The notes of `joint` that are not errors: an origin whose angles, or
/// limits that, turn more than a radian value would (degrees written where
/// URDF reads radians, most likely).
fn joint_notes(joint: &urdf_rs::Joint, path: &Path) -> Vec<String> {
    let what = format!("{} joint '{}'", path.display(), joint.name);
    let origin = Pose::new(joint.origin.xyz.0, joint.origin.rpy.0);
    let mut notes: Vec<String> = origin
        .degrees_note(&format!("{what} origin:"))
        .into_iter()
        .collect();
    let moving = !matches!(
        joint.joint_type,
        urdf_rs::JointType::Fixed | urdf_rs::JointType::Prismatic
    );
    let (lower, upper) = (joint.limit.lower, joint.limit.upper);
    let reach = LIMIT_TURNS * std::f64::consts::TAU;
    if moving && (lower.abs() > reach || upper.abs() > reach) {
        notes.push(format!(
            "note: {what}: limits [{lower}, {upper}] reach past {LIMIT_TURNS} turns: URDF \
             angles are radians; if these are degrees, write lower=\"{:.4}\" upper=\"{:.4}\"",
            lower.to_radians(),
            upper.to_radians()
        ));
    }
    notes
}

/// A URDF joint as a chain joint: links that exist, a finite origin, a
/// usable axis and an interval of limits for a moving joint, a supported
/// type. Errors say what is wrong with the joint.
fn chain_joint(
    joint: &urdf_rs::Joint,
    links: &[String],
) -> std::result::Result<ChainJoint, String> {
    for end in [&joint.parent.link, &joint.child.link] {
        if !links.contains(end) {
            return Err(format!(
                "refers to link '{end}', which the URDF does not define"
            ));
        }
    }
    let origin = Pose::new(joint.origin.xyz.0, joint.origin.rpy.0);
    if !origin.is_finite() {
        return Err("origin has a non-finite value".into());
    }
    let axis = || {
        let a = Vector3::from(joint.axis.xyz.0);
        if !a.iter().all(|v| v.is_finite()) || a.norm() < 1e-9 {
            return Err(format!(
                "axis {:?} is not a usable direction",
                joint.axis.xyz.0
            ));
        }
        Ok(Unit::new_normalize(a))
    };
    let limits = || {
        let (lower, upper) = (joint.limit.lower, joint.limit.upper);
        if lower.is_nan() || upper.is_nan() || lower > upper {
            return Err(format!("limits [{lower}, {upper}] are not an interval"));
        }
        if lower == upper {
            return Err(format!(
                "has no <limit lower=.. upper=..> or a zero range [{lower}, {upper}]: \
                 a moving joint needs lower < upper (use type=\"fixed\" for a locked one)"
            ));
        }
        Ok((lower, upper))
    };
    let motion = match joint.joint_type {
        urdf_rs::JointType::Fixed => JointMotion::Fixed,
        urdf_rs::JointType::Revolute => {
            let (lower, upper) = limits()?;
            JointMotion::Revolute {
                axis: axis()?,
                lower,
                upper,
            }
        }
        urdf_rs::JointType::Continuous => JointMotion::Continuous { axis: axis()? },
        urdf_rs::JointType::Prismatic => {
            let (lower, upper) = limits()?;
            JointMotion::Prismatic {
                axis: axis()?,
                lower,
                upper,
            }
        }
        ref other => {
            return Err(format!(
                "type {other:?} is not supported (use fixed, revolute, continuous or prismatic)"
            ))
        }
    };
    Ok(ChainJoint {
        name: joint.name.clone(),
        origin: origin.to_isometry(),
        motion,
    })
}

/// What of xacro's macro language `text` still holds outside its comments
/// (an element `<xacro:…>` or a property `${…}`), if any: a URDF reader
/// would take such a file for a robot without the macros' links and with
/// their values unread. A plain URDF may declare the `xacro` namespace.
fn xacro_left_in(text: &str) -> Option<&'static str> {
    let mut rest = text;
    loop {
        let (before, after) = match rest.split_once("<!--") {
            Some((before, after)) => (before, Some(after)),
            None => (rest, None),
        };
        if before.contains("<xacro:") {
            return Some("<xacro:…> elements");
        }
        if before.contains("${") {
            return Some("${…} properties");
        }
        rest = after?.split_once("-->").map_or("", |(_, tail)| tail);
    }
}

/// A link from which the parent joints never reach a root (within as many
/// steps as there are links): the joints form a cycle through it.
fn first_in_a_cycle<'a>(
    links: &'a [String],
    parent_joint: &HashMap<String, (String, ChainJoint)>,
) -> Option<&'a String> {
    links.iter().find(|start| {
        let mut link: &String = start;
        for _ in 0..=links.len() {
            match parent_joint.get(link) {
                Some((parent, _)) => link = parent,
                None => break,
            }
        }
        parent_joint.contains_key(link)
    })
}

impl Robot {
    /// Reads and checks a URDF file: every joint of a supported type, links
    /// that exist, a tree (each link has at most one parent), finite origins.
    pub fn load(path: &Path) -> Result<Self> {
        let text = crate::error::read_text(path)?;
        if let Some(what) = xacro_left_in(&text) {
            return Err(Error::input(
                path,
                format!(
                    "an unexpanded xacro file (it holds {what}): expand it into a URDF first, \
                     e.g. `xacro {} > robot.urdf` (ROS's xacro package)",
                    path.file_name()
                        .map_or(String::new(), |n| n.to_string_lossy().into_owned())
                ),
            ));
        }
        let urdf = urdf_rs::read_from_string(&text)
            .map_err(|e| Error::input(path, format!("malformed URDF: {e}")))?;
        let links: Vec<String> = urdf.links.iter().map(|l| l.name.clone()).collect();
        let mut parent_joint = HashMap::new();
        let mut notes = Vec::new();
        for joint in &urdf.joints {
            let bad = |msg: String| Error::input(path, format!("joint '{}': {msg}", joint.name));
            let chain_joint = chain_joint(joint, &links).map_err(bad)?;
            notes.extend(joint_notes(joint, path));
            let previous = parent_joint.insert(
                joint.child.link.clone(),
                (joint.parent.link.clone(), chain_joint),
            );
            if previous.is_some() {
                return Err(bad(format!(
                    "link '{}' has two parent joints; a URDF must be a tree",
                    joint.child.link
                )));
            }
        }
        if let Some(start) = first_in_a_cycle(&links, &parent_joint) {
            return Err(Error::input(
                path,
                format!("the joints form a cycle through link '{start}'; a URDF must be a tree"),
            ));
        }
        Ok(Self {
            name: urdf.name,
            source: path.to_path_buf(),
            links,
            parent_joint,
            notes,
        })
    }

    /// What the user should know of the file that is not an error: joint
    /// angles or limits that look like degrees.
    pub fn notes(&self) -> &[String] {
        &self.notes
    }

    /// The names of all links.
    pub fn links(&self) -> &[String] {
        &self.links
    }

    /// The kinematic chain from `base` down to `tip` (`base` must be an
    /// ancestor of `tip`, or the same link).
    pub fn chain(&self, base: &str, tip: &str) -> Result<KinematicChain> {
        for link in [base, tip] {
            if !self.links.iter().any(|l| l == link) {
                return Err(Error::input(
                    &self.source,
                    format!("unknown link '{link}' (links: {})", self.links.join(", ")),
                ));
            }
        }
        let mut joints = Vec::new();
        let mut link = tip.to_string();
        while link != base {
            match self.parent_joint.get(&link) {
                Some((parent, joint)) => {
                    joints.push(joint.clone());
                    link = parent.clone();
                }
                None => {
                    return Err(Error::input(
                        &self.source,
                        format!("link '{base}' is not an ancestor of '{tip}': no chain joins them"),
                    ))
                }
            }
        }
        joints.reverse();
        Ok(KinematicChain {
            source: self.source.clone(),
            base: base.to_string(),
            tip: tip.to_string(),
            joints,
        })
    }
}

/// A serial chain of joints from a base link to a tip link.
#[derive(Clone, Debug)]
pub struct KinematicChain {
    source: PathBuf,
    /// The base link.
    pub base: String,
    /// The tip link.
    pub tip: String,
    joints: Vec<ChainJoint>,
}

impl KinematicChain {
    /// Number of actuated joints (the length of a configuration).
    pub fn dof(&self) -> usize {
        self.joints.iter().filter(|j| j.is_actuated()).count()
    }

    /// The actuated joints in chain order.
    pub fn actuated(&self) -> impl Iterator<Item = &ChainJoint> {
        self.joints.iter().filter(|j| j.is_actuated())
    }

    /// The joint limits `[lower, upper]` of the actuated joints (±∞ for a
    /// continuous joint).
    pub fn limits(&self) -> Vec<(f64, f64)> {
        self.actuated()
            .map(|j| match j.motion {
                JointMotion::Revolute { lower, upper, .. }
                | JointMotion::Prismatic { lower, upper, .. } => (lower, upper),
                _ => (f64::NEG_INFINITY, f64::INFINITY),
            })
            .collect()
    }

    /// An upper bound of how far (m) the tip's origin can stand from the
    /// base's: the lengths of the joints' offsets plus each prismatic
    /// joint's longest travel (the triangle inequality along the chain).
    pub fn reach(&self) -> f64 {
        self.joints
            .iter()
            .map(|j| {
                let travel = match j.motion {
                    JointMotion::Prismatic { lower, upper, .. } => lower.abs().max(upper.abs()),
                    _ => 0.0,
                };
                j.origin.translation.vector.norm() + travel
            })
            .sum()
    }

    /// Checks a configuration: right length, finite, within every joint limit.
    pub fn check(&self, q: &[f64]) -> Result<()> {
        if q.len() != self.dof() {
            return Err(Error::input(
                &self.source,
                format!(
                    "chain {} -> {} has {} actuated joints, the configuration gives {} values",
                    self.base,
                    self.tip,
                    self.dof(),
                    q.len()
                ),
            ));
        }
        for ((joint, &value), (lower, upper)) in self.actuated().zip(q).zip(self.limits()) {
            if !value.is_finite() {
                return Err(Error::input(
                    &self.source,
                    format!("joint '{}' value {value} is not finite", joint.name),
                ));
            }
            if value < lower || value > upper {
                return Err(Error::input(
                    &self.source,
                    format!(
                        "joint '{}' = {value:.6} is outside its limits [{lower:.6}, {upper:.6}]",
                        joint.name
                    ),
                ));
            }
        }
        Ok(())
    }

    /// `base_from_tip(q)`, checking the limits first.
    pub fn forward(&self, q: &[f64]) -> Result<Isometry3> {
        self.check(q)?;
        Ok(self.forward_unchecked(q))
    }

    /// `base_from_tip(q)` without any check (`q` must have [`Self::dof`] values).
    pub fn forward_unchecked(&self, q: &[f64]) -> Isometry3 {
        let mut values = q.iter();
        self.joints
            .iter()
            .fold(Isometry3::identity(), |acc, joint| {
                let value = if joint.is_actuated() {
                    *values.next().unwrap_or(&0.0)
                } else {
                    0.0
                };
                acc * joint.origin * joint.motion_transform(value)
            })
    }

    /// `base_from_tip(q)` and the geometric Jacobian (6 x dof): rows 0-2 the
    /// linear velocity of the tip origin, rows 3-5 the angular velocity, both
    /// in the base frame.
    pub fn jacobian(&self, q: &[f64]) -> (Isometry3, DMatrix<f64>) {
        let mut frames = Vec::with_capacity(self.dof());
        let mut values = q.iter();
        let mut acc = Isometry3::identity();
        for joint in &self.joints {
            acc *= joint.origin;
            let value = if joint.is_actuated() {
                *values.next().unwrap_or(&0.0)
            } else {
                0.0
            };
            match &joint.motion {
                JointMotion::Fixed => {}
                JointMotion::Revolute { axis, .. } | JointMotion::Continuous { axis } => {
                    frames.push((
                        acc.translation.vector,
                        acc.rotation * axis.into_inner(),
                        true,
                    ));
                }
                JointMotion::Prismatic { axis, .. } => {
                    frames.push((
                        acc.translation.vector,
                        acc.rotation * axis.into_inner(),
                        false,
                    ));
                }
            }
            acc *= joint.motion_transform(value);
        }
        let tip = acc.translation.vector;
        let mut jac = DMatrix::zeros(6, frames.len());
        for (k, (origin, axis, revolute)) in frames.into_iter().enumerate() {
            if revolute {
                jac.fixed_view_mut::<3, 1>(0, k)
                    .copy_from(&axis.cross(&(tip - origin)));
                jac.fixed_view_mut::<3, 1>(3, k).copy_from(&axis);
            } else {
                jac.fixed_view_mut::<3, 1>(0, k).copy_from(&axis);
            }
        }
        (acc, jac)
    }
}

#[cfg(test)]
mod tests;
