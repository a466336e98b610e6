//! Loading a [`SerialChain`] from URDF (urdf-rs): path search from tip to base, fixed-joint folding, validation.

use super::{ChainLink, Joint, JointKind, MimicJoint, RobotError, SerialChain};
use crate::bounds::{PhysicalRange, ANGLE_RAD, LENGTH_M, MIMIC_MULTIPLIER};
use crate::math::JointVector;
use nalgebra::{Isometry3, Translation3, Unit, UnitQuaternion, Vector3};
use std::collections::HashMap;
use std::path::Path;

/// Axes whose largest component (absolute value) is below this are rejected as zero.
const MIN_AXIS_COMPONENT: f64 = 1e-12;

impl<const N: usize> SerialChain<N> {
    /// Loads the chain from `base_link` to `tip_link` of a URDF document.
    ///
    /// Fixed joints on the path are folded into the transforms; revolute, continuous and prismatic joints become the
    /// `N` joints, in order from base to tip, except `<mimic>` joints, which follow one of those
    /// ([`SerialChain::mimic_joints`], [D19](crate::theory#d19)). Links and joints off the path are ignored (so any
    /// tree works, e.g. an arm whose gripper fingers mimic each other on branches off the path).
    ///
    /// # Errors
    /// [`RobotError::UrdfTooLarge`] and [`RobotError::UrdfTooDeep`] for text beyond the bounds checked before parsing
    /// ([D17](crate::theory#d17)); [`RobotError::Urdf`] for malformed XML/URDF; [`RobotError::UnknownLink`] when the base or tip link does not
    /// exist; [`RobotError::MultipleParents`], [`RobotError::TipNotReachable`] when no path leads from base to tip;
    /// [`RobotError::UnsupportedJoint`] (floating, planar, spherical) for joints on the path;
    /// [`RobotError::MimicUnknownJoint`], [`RobotError::MimicCycle`], [`RobotError::MimicLeaderNotOnPath`],
    /// [`RobotError::MimicBeforeJoint`] for mimic joints on the path; [`RobotError::JointCount`] when the path has a
    /// number of independent movable joints other than `N`;
    /// [`RobotError::MissingLimits`], [`RobotError::InvalidLimits`], [`RobotError::ZeroAxis`],
    /// [`RobotError::NonFiniteUrdf`], [`RobotError::OutOfRange`] for invalid joints on the path.
    pub fn from_urdf_str(xml: &str, base_link: &str, tip_link: &str) -> Result<Self, RobotError> {
        let robot = parse_urdf(xml)?;
        Self::from_urdf_robot(&robot, base_link, tip_link)
    }

    /// Reads a URDF file and loads the chain from `base_link` to `tip_link`, as [`SerialChain::from_urdf_str`].
    ///
    /// # Errors
    /// [`RobotError::File`] when the file cannot be read, [`RobotError::UrdfTooLarge`] for a file larger than
    /// [`super::MAX_URDF_BYTES`] (not read), then those of [`SerialChain::from_urdf_str`].
    pub fn from_urdf_file(
        path: impl AsRef<Path>,
        base_link: &str,
        tip_link: &str,
    ) -> Result<Self, RobotError> {
        let xml = super::read_urdf_file(path.as_ref())?;
        Self::from_urdf_str(&xml, base_link, tip_link)
    }

    /// Loads the chain from an already parsed urdf-rs [`urdf_rs::Robot`], as [`SerialChain::from_urdf_str`].
    ///
    /// # Errors
    /// Those of [`SerialChain::from_urdf_str`] except [`RobotError::Urdf`].
    pub fn from_urdf_robot(
        robot: &urdf_rs::Robot,
        base_link: &str,
        tip_link: &str,
    ) -> Result<Self, RobotError> {
        for (role, link) in [("base", base_link), ("tip", tip_link)] {
            if !robot.links.iter().any(|l| l.name == link) {
                return Err(RobotError::UnknownLink {
                    role,
                    link: link.to_owned(),
                });
            }
        }
        let path = path_from_base(robot, base_link, tip_link)?;

        let mut joints = Vec::with_capacity(N);
        let mut lower = Vec::with_capacity(N);
        let mut upper = Vec::with_capacity(N);
        // The mimic joints met so far, each with the name of the joint it follows in the end, its multiplier and
        // offset (the name is resolved to an index once every independent joint is known).
        let mut mimics: Vec<(Joint, String, f64, f64)> = Vec::new();
        let mut links = vec![ChainLink {
            name: base_link.to_owned(),
            moved_by: None,
            mimics: Vec::new(),
            segment_from_link: Isometry3::identity(),
        }];
        // How many mimic joints come before each link of `links`.
        let mut mimics_before_link = vec![0];
        // Pose of the current link in the frame of the last movable joint's child (the base before the first one).
        let mut segment_from_link = Isometry3::identity();
        for urdf_joint in path {
            let origin = segment_from_link * joint_origin(urdf_joint)?;
            let kind = match urdf_joint.joint_type {
                urdf_rs::JointType::Fixed => None,
                urdf_rs::JointType::Revolute => Some(JointKind::Revolute),
                urdf_rs::JointType::Continuous => Some(JointKind::Continuous),
                urdf_rs::JointType::Prismatic => Some(JointKind::Prismatic),
                urdf_rs::JointType::Floating => return Err(unsupported(urdf_joint, "floating")),
                urdf_rs::JointType::Planar => return Err(unsupported(urdf_joint, "planar")),
                urdf_rs::JointType::Spherical => return Err(unsupported(urdf_joint, "spherical")),
            };
            match kind {
                None => segment_from_link = origin,
                Some(kind) => {
                    let joint = Joint::new(
                        urdf_joint.name.clone(),
                        kind,
                        urdf_joint.child.link.clone(),
                        origin,
                        joint_axis(urdf_joint)?,
                    );
                    if urdf_joint.mimic.is_some() {
                        let (leader, multiplier, offset) = mimic_leader(robot, urdf_joint)?;
                        let out_of_range = [
                            (multiplier, MIMIC_MULTIPLIER),
                            (offset, crate::bounds::JOINT_POSITION),
                        ]
                        .into_iter()
                        .find(|(value, range)| !range.contains(*value));
                        if let Some((value, range)) = out_of_range {
                            return Err(RobotError::OutOfRange {
                                joint: urdf_joint.name.clone(),
                                field: "mimic",
                                value,
                                expected: range.text,
                            });
                        }
                        mimics.push((joint, leader, multiplier, offset));
                    } else {
                        if let Some((mimic, ..)) = mimics.first() {
                            return Err(RobotError::MimicBeforeJoint {
                                joint: mimic.name.clone(),
                                next: urdf_joint.name.clone(),
                            });
                        }
                        let (lo, hi) = joint_limits(urdf_joint, kind)?;
                        lower.push(lo);
                        upper.push(hi);
                        joints.push(joint);
                    }
                    segment_from_link = Isometry3::identity();
                }
            }
            links.push(ChainLink {
                name: urdf_joint.child.link.clone(),
                moved_by: joints.len().checked_sub(1),
                mimics: Vec::new(), // filled below, once the mimic joints are resolved
                segment_from_link,
            });
            mimics_before_link.push(mimics.len());
        }

        let mut mimic_joints = Vec::with_capacity(mimics.len());
        for (joint, leader, multiplier, offset) in mimics {
            let leader = joints
                .iter()
                .position(|j| j.name == leader)
                .ok_or_else(|| RobotError::MimicLeaderNotOnPath {
                    joint: joint.name.clone(),
                    leader,
                })?;
            mimic_joints.push(MimicJoint {
                joint,
                leader,
                multiplier,
                offset,
            });
        }
        for (link, &before) in links.iter_mut().zip(&mimics_before_link) {
            link.mimics = mimic_joints[..before].to_vec();
        }

        let found = joints.len();
        let joints: [Joint; N] = joints
            .try_into()
            .map_err(|_| RobotError::JointCount { expected: N, found })?;
        Ok(Self {
            base_link: base_link.to_owned(),
            tip_link: tip_link.to_owned(),
            joints,
            mimic_joints,
            lower: JointVector::from_iterator(lower),
            upper: JointVector::from_iterator(upper),
            segment_from_tip: segment_from_link,
            links,
        })
    }
}

/// The independent joint a mimic joint follows in the end, with the composed multiplier and offset: following
/// `θ_j = m_j θ_k + o_j` through mimics of mimics, `θ = (Π m) θ_leader + o` ([D19](crate::theory#d19)).
///
/// # Errors
/// [`RobotError::MimicUnknownJoint`], [`RobotError::MimicCycle`], [`RobotError::NonFiniteUrdf`] (`"mimic"`).
fn mimic_leader(
    robot: &urdf_rs::Robot,
    joint: &urdf_rs::Joint,
) -> Result<(String, f64, f64), RobotError> {
    let (mut multiplier, mut offset) = (1.0, 0.0);
    let mut met = vec![joint.name.clone()];
    let mut current = joint;
    while let Some(mimic) = &current.mimic {
        let (m, o) = (mimic.multiplier.unwrap_or(1.0), mimic.offset.unwrap_or(0.0));
        if !(m.is_finite() && o.is_finite()) {
            return Err(RobotError::NonFiniteUrdf {
                joint: current.name.clone(),
                field: "mimic",
                values: vec![m, o],
            });
        }
        // θ = multiplier · θ_current + offset, θ_current = m · θ_next + o.
        offset += multiplier * o;
        multiplier *= m;
        let next = robot
            .joints
            .iter()
            .find(|j| j.name == mimic.joint)
            .ok_or_else(|| RobotError::MimicUnknownJoint {
                joint: current.name.clone(),
                leader: mimic.joint.clone(),
            })?;
        let seen = met.contains(&next.name);
        met.push(next.name.clone());
        if seen {
            return Err(RobotError::MimicCycle { joints: met });
        }
        current = next;
    }
    Ok((current.name.clone(), multiplier, offset))
}

/// Parses URDF text with urdf-rs, once its size and nesting depth are checked.
///
/// # Errors
/// [`RobotError::UrdfTooLarge`], [`RobotError::UrdfTooDeep`], [`RobotError::Urdf`] with urdf-rs's message.
pub(crate) fn parse_urdf(xml: &str) -> Result<urdf_rs::Robot, RobotError> {
    super::xml_bounds::check_urdf_text(xml)?;
    // urdf-rs and its XML parsers return errors on the inputs we tried (see the fuzz test), but they are third-party
    // code: a panic inside them must not escape a loading function that promises an error instead.
    std::panic::catch_unwind(|| urdf_rs::read_from_string(xml))
        .map_err(|_| RobotError::Urdf {
            message: "the URDF parser panicked on this input".to_owned(),
        })?
        .map_err(|e| RobotError::Urdf {
            message: e.to_string(),
        })
}

/// The URDF joints from `base` to `tip`, in that order, found by walking up from the tip through parent joints.
fn path_from_base<'r>(
    robot: &'r urdf_rs::Robot,
    base: &str,
    tip: &str,
) -> Result<Vec<&'r urdf_rs::Joint>, RobotError> {
    let mut parent_joint: HashMap<&str, &urdf_rs::Joint> = HashMap::new();
    let mut several_parents = Vec::new();
    for joint in &robot.joints {
        if parent_joint.insert(&joint.child.link, joint).is_some() {
            several_parents.push(joint.child.link.as_str());
        }
    }
    let mut path = Vec::new();
    let mut link = tip;
    while link != base {
        if several_parents.contains(&link) {
            return Err(RobotError::MultipleParents {
                link: link.to_owned(),
            });
        }
        // A path longer than the number of joints has gone round a cycle.
        let joint = parent_joint
            .get(link)
            .filter(|_| path.len() < robot.joints.len())
            .ok_or_else(|| RobotError::TipNotReachable {
                base: base.to_owned(),
                tip: tip.to_owned(),
            })?;
        path.push(*joint);
        link = &joint.parent.link;
    }
    path.reverse();
    Ok(path)
}

fn unsupported(joint: &urdf_rs::Joint, kind: &'static str) -> RobotError {
    RobotError::UnsupportedJoint {
        joint: joint.name.clone(),
        kind,
    }
}

fn finite3(
    joint: &urdf_rs::Joint,
    field: &'static str,
    v: &[f64; 3],
) -> Result<Vector3<f64>, RobotError> {
    if v.iter().all(|x| x.is_finite()) {
        Ok(Vector3::from(*v))
    } else {
        Err(RobotError::NonFiniteUrdf {
            joint: joint.name.clone(),
            field,
            values: v.to_vec(),
        })
    }
}

/// The URDF `<origin>`: translation `xyz` then rotation `rpy` (fixed axes x, y, z: `R = Rz(yaw) Ry(pitch) Rx(roll)`).
fn joint_origin(joint: &urdf_rs::Joint) -> Result<Isometry3<f64>, RobotError> {
    let xyz = in_range(joint, "origin xyz", &LENGTH_M, &joint.origin.xyz)?;
    let rpy = in_range(joint, "origin rpy", &ANGLE_RAD, &joint.origin.rpy)?;
    Ok(Isometry3::from_parts(
        Translation3::from(xyz),
        UnitQuaternion::from_euler_angles(rpy.x, rpy.y, rpy.z),
    ))
}

/// The unit axis. Scaled by its largest component first, so that no square overflows (an axis of `1e200 1e200
/// 1e200` is the diagonal) or underflows.
fn joint_axis(joint: &urdf_rs::Joint) -> Result<Unit<Vector3<f64>>, RobotError> {
    let axis = finite3(joint, "axis", &joint.axis.xyz)?;
    let largest = axis.amax();
    if largest < MIN_AXIS_COMPONENT {
        return Err(RobotError::ZeroAxis {
            joint: joint.name.clone(),
            axis: *joint.axis.xyz,
        });
    }
    Ok(Unit::new_normalize(axis / largest))
}

/// The values of `field`, finite and within `range`.
fn in_range(
    joint: &urdf_rs::Joint,
    field: &'static str,
    range: &PhysicalRange,
    v: &[f64; 3],
) -> Result<Vector3<f64>, RobotError> {
    let values = finite3(joint, field, v)?;
    match values.iter().find(|&&x| !range.contains(x)) {
        Some(&value) => Err(RobotError::OutOfRange {
            joint: joint.name.clone(),
            field,
            value,
            expected: range.text,
        }),
        None => Ok(values),
    }
}

/// Position limits (rad or m): `±∞` for continuous joints, `lower < upper` within [`ANGLE_RAD`] (revolute) or
/// [`LENGTH_M`] (prismatic) otherwise.
fn joint_limits(joint: &urdf_rs::Joint, kind: JointKind) -> Result<(f64, f64), RobotError> {
    if kind == JointKind::Continuous {
        return Ok((f64::NEG_INFINITY, f64::INFINITY));
    }
    let (lower, upper) = (joint.limit.lower, joint.limit.upper);
    let range = match kind {
        JointKind::Prismatic => LENGTH_M,
        _ => ANGLE_RAD,
    };
    if lower.is_nan() || upper.is_nan() {
        return Err(RobotError::NonFiniteUrdf {
            joint: joint.name.clone(),
            field: "limit",
            values: vec![lower, upper],
        });
    }
    let joint = joint.name.clone();
    if lower.is_infinite() || upper.is_infinite() || (lower == 0.0 && upper == 0.0) {
        Err(RobotError::MissingLimits {
            joint,
            lower,
            upper,
        })
    } else if lower >= upper {
        Err(RobotError::InvalidLimits {
            joint,
            lower,
            upper,
        })
    } else if let Some(value) = [lower, upper].into_iter().find(|&v| !range.contains(v)) {
        Err(RobotError::OutOfRange {
            joint,
            field: "limit",
            value,
            expected: range.text,
        })
    } else {
        Ok((lower, upper))
    }
}
