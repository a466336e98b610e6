//! Robot models: serial kinematic chains loaded from URDF, their forward kinematics and Jacobians, built-in arms.
//!
//! # Model and workspace
//!
//! As Pinocchio's `Model`/`Data`, a [`SerialChain<N>`] is the immutable model (joint kinds,
//! fixed transforms, axes, limits, names) and a [`KinematicsWorkspace<N>`] holds everything one evaluation writes.
//! [`SerialChain::kinematics`] fills the workspace for a joint vector `q` and returns the [`KinematicState<N>`] it
//! computed: the pose `base_from_tip` (ViSP `fMe`), the geometric Jacobian in the base frame and in the end-effector
//! frame (`eJe`, [\[M42\]](crate::theory#m42)), and the pose and axis of every joint. The computation allocates nothing.
//!
//! # Conventions
//!
//! * Frames: `base` is the frame of the URDF base link (ViSP `f`), `tip` the frame of the URDF tip link (ViSP `e`,
//!   the end effector). A *segment* is the rigid group of links moved by one joint: segment `i` has the frame of the
//!   child link of joint `i`; links attached by fixed joints are folded into it.
//! * Joint `i` moves segment `i` relative to segment `i − 1` (the base for `i = 0`). At `q = 0` the child frame of a
//!   joint is its URDF `<origin>`; a revolute or continuous joint then rotates it by `q_i` (rad) about the unit `<axis>`
//!   (expressed in the joint frame), a prismatic joint translates it by `q_i` (m) along that axis:
//!
//!   ```text
//!   base_from_segment_i = base_from_segment_{i−1} · origin_i · motion_i(q_i),     base_from_tip = base_from_segment_{N−1} · segment_from_tip
//!   ```
//! * Jacobians (twist order `(v, ω)`, [theory §0](crate::theory#s0)): with `a_i` the unit axis of joint `i` and `o_i` the origin of its frame,
//!   both in the base frame, and `p` the origin of the tip frame,
//!
//!   ```text
//!   column i of base_J = (a_i × (p − o_i), a_i)   (revolute, continuous)
//!                        (a_i, 0)                 (prismatic)
//!   eJe = diag(eRb, eRb) · base_J                  (the same tip twist, expressed in the tip frame)
//!   ```
//!   so `base_J q̇` is the linear velocity of the tip origin and the angular velocity of the tip, in base axes, and
//!   `eJe q̇` the same twist in tip axes — the `eJe` that [\[M42\]](crate::theory#m42) multiplies by `cVe` [\[M43\]](crate::theory#m43).
//!
//! # Joint limits
//!
//! Revolute and prismatic joints must carry finite limits `lower < upper` (rad or m). Continuous joints have no limit:
//! their limits are `−∞` and `+∞`, which the joint-limit cost leaves out ([D18](crate::theory#d18)).
//!
//! # Mimic joints
//!
//! A URDF `<mimic>` joint on the path is no coordinate of the chain: its position is `m · q_i + o`, `i` the
//! independent joint it follows ([`MimicJoint`]), and it adds `m` times its own column to column `i` of the
//! Jacobians ([D19](crate::theory#d19)). Mimic joints are supported after the last independent joint of the path.
//!
//! ```
//! use servostack::robot::{builtin, KinematicsWorkspace};
//! use servostack::math::JointVector;
//!
//! let robot = builtin::afma6()?;
//! let mut ws = KinematicsWorkspace::new();
//! let q = JointVector::<6>::new(0.1, -0.2, 0.05, 0.3, 0.4, -0.1);
//! let state = robot.chain.kinematics(&mut ws, &q)?;
//! let base_from_camera = robot.mount.base_from_camera(state.base_from_tip());
//! let camera_jacobian = robot.mount.camera_jacobian(state.tip_jacobian()); // cVe · eJe
//! // The camera frame moves with the end effector: fMc = fMe · eMc.
//! let e_from_c = robot.mount.e_from_c();
//! assert_eq!(base_from_camera, state.base_from_tip() * e_from_c);
//! // Joint 1 is the gantry's x slide: q̇ = (1, 0, …) moves the camera along x of the base, 1 m/s.
//! let c_from_base = base_from_camera.rotation.inverse();
//! let v_c = camera_jacobian.column(0).fixed_rows::<3>(0).into_owned();
//! assert!((c_from_base.inverse() * v_c - nalgebra::Vector3::x()).norm() < 1e-12);
//! # Ok::<(), servostack::robot::RobotError>(())
//! ```

pub mod builtin;
mod kinematics;
mod urdf;
mod xml_bounds;

pub use kinematics::{KinematicState, KinematicsWorkspace};
pub(crate) use urdf::parse_urdf;
pub(crate) use xml_bounds::{first_too_deep, read_urdf_file};
pub use xml_bounds::{MAX_URDF_BYTES, MAX_URDF_DEPTH};

use crate::bounds::JOINT_POSITION;
use crate::camera::CameraError;
use crate::math::JointVector;
use nalgebra::{Isometry3, Quaternion, Unit, Vector3};

/// Errors of robot loading and kinematics. Each variant names the offending joint, link or value.
#[non_exhaustive]
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RobotError {
    /// The URDF text could not be parsed (malformed XML or URDF, as reported by urdf-rs).
    #[error("cannot parse URDF: {message}")]
    Urdf {
        /// The parser's message.
        message: String,
    },
    /// The URDF text is larger than [`MAX_URDF_BYTES`] (checked before parsing, [D17](crate::theory#d17)).
    #[error("URDF of {bytes} bytes is larger than the limit of {limit} bytes")]
    UrdfTooLarge {
        /// The size of the text or file (bytes).
        bytes: u64,
        /// [`MAX_URDF_BYTES`].
        limit: usize,
    },
    /// The URDF nests elements deeper than [`MAX_URDF_DEPTH`] (checked before parsing: a recursive parser would
    /// overflow the stack, [D17](crate::theory#d17)).
    #[error("URDF nests elements {depth} deep at line {line}: the limit is {limit}")]
    UrdfTooDeep {
        /// The depth reached when the limit was passed.
        depth: usize,
        /// [`MAX_URDF_DEPTH`].
        limit: usize,
        /// The line (1-based) of the element that passed it.
        line: usize,
    },
    /// A URDF file could not be read.
    #[error("cannot read URDF file {path}: {message}")]
    File {
        /// The path given.
        path: String,
        /// The operating system's message.
        message: String,
    },
    /// The base or tip link named by the caller is not a link of the URDF.
    #[error("unknown {role} link {link:?}")]
    UnknownLink {
        /// `"base"` or `"tip"`.
        role: &'static str,
        /// The link name given.
        link: String,
    },
    /// Walking up from the tip link through parent joints never reaches the base link.
    #[error("tip link {tip:?} is not reachable from base link {base:?}")]
    TipNotReachable {
        /// Base link name.
        base: String,
        /// Tip link name.
        tip: String,
    },
    /// A link on the path is the child of several joints (the URDF is not a tree).
    #[error("link {link:?} is the child of several joints")]
    MultipleParents {
        /// The link name.
        link: String,
    },
    /// A joint on the path is of a kind a serial chain cannot hold (floating, planar, spherical).
    #[error("joint {joint:?} is {kind}: only revolute, continuous, prismatic and fixed joints are supported")]
    UnsupportedJoint {
        /// Joint name.
        joint: String,
        /// Its URDF type.
        kind: &'static str,
    },
    /// A mimic joint on the path names a joint the URDF does not have.
    #[error("joint {joint:?} mimics {leader:?}, which is not a joint of the URDF")]
    MimicUnknownJoint {
        /// The mimic joint.
        joint: String,
        /// The joint it names.
        leader: String,
    },
    /// Following `<mimic>` elements from a joint of the path comes back to a joint already met.
    #[error("mimic joints form a cycle: {}", joints.join(" → "))]
    MimicCycle {
        /// The joints met, from the joint of the path to the one met twice.
        joints: Vec<String>,
    },
    /// A mimic joint on the path follows a joint that is not an independent movable joint of the chain (off the
    /// path, or fixed): the chain has no coordinate for it.
    #[error(
        "joint {joint:?} mimics {leader:?}, which is not a movable non-mimic joint between the base and tip links"
    )]
    MimicLeaderNotOnPath {
        /// The mimic joint.
        joint: String,
        /// The joint it follows (at the end of a chain of mimics).
        leader: String,
    },
    /// A mimic joint on the path comes before an independent joint: mimic joints are supported after the chain's last
    /// independent joint (a coupled last axis, a finger as tip link), [D19](crate::theory#d19).
    #[error(
        "mimic joint {joint:?} comes before the independent joint {next:?}: mimic joints are supported only after \
         the last independent joint of the chain"
    )]
    MimicBeforeJoint {
        /// The mimic joint.
        joint: String,
        /// The independent joint after it.
        next: String,
    },
    /// The chain has a different number of movable joints than the static size `N`.
    #[error("the chain has {found} movable joints, expected {expected}")]
    JointCount {
        /// `N`.
        expected: usize,
        /// Movable joints between base and tip.
        found: usize,
    },
    /// A revolute or prismatic joint has no usable `<limit lower upper>` (absent, infinite, or `lower = upper = 0`,
    /// which is what urdf-rs reports for a missing `<limit>` element before URDF 1.2).
    #[error(
        "joint {joint:?} has no position limits (lower = {lower}, upper = {upper}): give it \
         <limit lower=\"…\" upper=\"…\" effort=\"…\" velocity=\"…\"/> in the URDF (rad or m), or make it \
         type=\"continuous\" if it turns without limit"
    )]
    MissingLimits {
        /// Joint name.
        joint: String,
        /// Lower limit read.
        lower: f64,
        /// Upper limit read.
        upper: f64,
    },
    /// A revolute or prismatic joint has `lower ≥ upper`.
    #[error("joint {joint:?} has an empty or inverted range: lower = {lower}, upper = {upper}")]
    InvalidLimits {
        /// Joint name.
        joint: String,
        /// Lower limit (rad or m).
        lower: f64,
        /// Upper limit (rad or m).
        upper: f64,
    },
    /// A movable joint has a zero axis (its largest component, in absolute value, below 1e−12).
    #[error("joint {joint:?} has a zero axis {axis:?}")]
    ZeroAxis {
        /// Joint name.
        joint: String,
        /// The axis read.
        axis: [f64; 3],
    },
    /// A number of the URDF on the path (origin, axis, limit, mimic) is NaN or infinite.
    #[error("joint {joint:?}: {field} is not finite: {values:?}")]
    NonFiniteUrdf {
        /// Joint name.
        joint: String,
        /// Which field (`"origin xyz"`, `"origin rpy"`, `"axis"`, `"limit"`, `"mimic"`).
        field: &'static str,
        /// The values read.
        values: Vec<f64>,
    },
    /// A number of the URDF on the path (origin, limit) is finite but outside its physical range
    /// ([`crate::bounds`], [D17](crate::theory#d17)).
    #[error("joint {joint:?}: {field} = {value:e} is out of range: expected {expected}")]
    OutOfRange {
        /// Joint name.
        joint: String,
        /// Which field (`"origin xyz"`, `"origin rpy"`, `"limit"`, `"mimic"`, or `"position"` for a joint position
        /// given to the kinematics).
        field: &'static str,
        /// The first value out of range.
        value: f64,
        /// The range.
        expected: &'static str,
    },
    /// A joint limit given to [`SerialChain::with_limits`] is NaN or infinite.
    #[error("joint {joint:?}: limits must be finite (lower = {lower}, upper = {upper})")]
    NonFiniteLimits {
        /// Joint name.
        joint: String,
        /// Lower limit given (rad or m).
        lower: f64,
        /// Upper limit given (rad or m).
        upper: f64,
    },
    /// A joint position given to the kinematics is NaN or infinite.
    #[error("joint {index} position is not finite: {value}")]
    NonFiniteJoint {
        /// Joint index.
        index: usize,
        /// The value given.
        value: f64,
    },
    /// A link passed to a kinematic query belongs to a chain with more joints than this state.
    #[error("link is moved by joint {index}, but the chain has {joints} joints")]
    JointIndexOutOfRange {
        /// The joint index.
        index: usize,
        /// The number of joints `N`.
        joints: usize,
    },
    /// No built-in robot has this name.
    #[error("unknown built-in robot {name:?} (known: {known:?})")]
    UnknownRobot {
        /// The name asked for.
        name: String,
        /// The names of the built-in robots.
        known: &'static [&'static str],
    },
    /// The camera mount of a robot is invalid.
    #[error(transparent)]
    Camera(#[from] CameraError),
}

/// The kind of a movable joint. Fixed URDF joints are folded into the fixed transforms and never appear here.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JointKind {
    /// Rotation about the axis, position in rad, finite limits.
    Revolute,
    /// Rotation about the axis, position in rad, no limits (`±∞`).
    Continuous,
    /// Translation along the axis, position in m, finite limits.
    Prismatic,
}

impl JointKind {
    /// `true` for revolute and continuous joints (position in rad).
    pub fn is_rotational(self) -> bool {
        !matches!(self, JointKind::Prismatic)
    }
}

/// One movable joint of a [`SerialChain`].
#[derive(Debug, Clone, PartialEq)]
pub struct Joint {
    name: String,
    kind: JointKind,
    child_link: String,
    origin: Isometry3<f64>,
    axis: Unit<Vector3<f64>>,
    /// Cached for the kinematics: the axis in the previous segment frame, `origin.rotation · axis`.
    axis_in_parent: Vector3<f64>,
    /// Cached for the kinematics: `origin.rotation ⊗ (0, axis)`, so that the rotation `origin · Rot(axis, q)` is
    /// the quaternion `cos(q/2) origin.rotation + sin(q/2) origin_times_axis`.
    origin_times_axis: Quaternion<f64>,
}

impl Joint {
    fn new(
        name: String,
        kind: JointKind,
        child_link: String,
        origin: Isometry3<f64>,
        axis: Unit<Vector3<f64>>,
    ) -> Self {
        Self {
            name,
            kind,
            child_link,
            origin,
            axis,
            axis_in_parent: origin.rotation * axis.into_inner(),
            origin_times_axis: origin.rotation.into_inner()
                * Quaternion::from_imag(axis.into_inner()),
        }
    }

    /// The URDF joint name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Revolute, continuous or prismatic.
    pub fn kind(&self) -> JointKind {
        self.kind
    }

    /// The URDF child link of this joint: the link whose frame is the frame of the segment this joint moves.
    pub fn child_link(&self) -> &str {
        &self.child_link
    }

    /// `segment_{i−1}_from_joint_i`: the joint frame at `q_i = 0` in the frame of the previous segment (the base
    /// frame for the first joint), the URDF `<origin>` composed with every fixed joint before it.
    pub fn origin(&self) -> &Isometry3<f64> {
        &self.origin
    }

    /// The unit joint axis, in the joint frame (the URDF `<axis>`, normalised).
    pub fn axis(&self) -> &Unit<Vector3<f64>> {
        &self.axis
    }
}

/// A mimic joint of the chain ([D19](crate::theory#d19)): a movable joint whose position is not a coordinate of the
/// chain but follows an independent joint `i` (the *leader*),
///
/// ```text
/// θ = multiplier · q_i + offset          (rad or m, as the joint's kind; multiplier in joint unit per leader unit)
/// ```
///
/// so it adds `multiplier ×` its own geometric column to column `i` of the Jacobians. A `<mimic>` of a `<mimic>` is
/// followed to the independent joint at its end, the multipliers and offsets composed.
#[derive(Debug, Clone, PartialEq)]
pub struct MimicJoint {
    joint: Joint,
    leader: usize,
    multiplier: f64,
    offset: f64,
}

impl MimicJoint {
    /// The joint's geometry: name, kind, child link, origin (in the frame of the previous movable joint's child
    /// link), axis.
    pub fn joint(&self) -> &Joint {
        &self.joint
    }

    /// The index `i` of the independent joint it follows.
    pub fn leader(&self) -> usize {
        self.leader
    }

    /// The multiplier (joint unit per leader unit).
    pub fn multiplier(&self) -> f64 {
        self.multiplier
    }

    /// The offset (rad or m).
    pub fn offset(&self) -> f64 {
        self.offset
    }

    /// Its position `multiplier · q_leader + offset` at the chain coordinates `q`.
    pub fn position<const N: usize>(&self, q: &JointVector<N>) -> f64 {
        self.multiplier * q[self.leader] + self.offset
    }
}

/// One URDF link on the path from base to tip, with the segment that carries it (for collision geometry).
#[derive(Debug, Clone, PartialEq)]
pub struct ChainLink {
    name: String,
    moved_by: Option<usize>,
    mimics: Vec<MimicJoint>,
    segment_from_link: Isometry3<f64>,
}

impl ChainLink {
    /// The URDF link name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The index of the last independent joint that moves this link (the link belongs to segment `i`), or `None` for
    /// links rigidly attached to the base.
    pub fn moved_by(&self) -> Option<usize> {
        self.moved_by
    }

    /// The mimic joints between the segment frame and this link, in order (empty unless the link lies beyond a
    /// mimic joint of the chain).
    pub fn mimics(&self) -> &[MimicJoint] {
        &self.mimics
    }

    /// The fixed pose of the link frame in the frame of the last movable joint before it: its segment frame (the
    /// base frame when [`Self::moved_by`] is `None`), or the child frame of the last of [`Self::mimics`].
    pub fn segment_from_link(&self) -> &Isometry3<f64> {
        &self.segment_from_link
    }
}

/// A serial kinematic chain of `N` movable joints between a base link and a tip link (the model; immutable).
///
/// Built from URDF with [`SerialChain::from_urdf_str`] / [`SerialChain::from_urdf_file`], or taken from
/// [`builtin`]. Evaluated with [`SerialChain::kinematics`] into a [`KinematicsWorkspace`].
#[derive(Debug, Clone, PartialEq)]
pub struct SerialChain<const N: usize> {
    base_link: String,
    tip_link: String,
    joints: [Joint; N],
    mimic_joints: Vec<MimicJoint>,
    lower: JointVector<N>,
    upper: JointVector<N>,
    segment_from_tip: Isometry3<f64>,
    links: Vec<ChainLink>,
}

impl<const N: usize> SerialChain<N> {
    /// The URDF base link name (frame `base`, ViSP `f`).
    pub fn base_link(&self) -> &str {
        &self.base_link
    }

    /// The URDF tip link name (frame `tip`, ViSP `e`).
    pub fn tip_link(&self) -> &str {
        &self.tip_link
    }

    /// The independent movable joints, from base to tip: the chain's coordinates `q`.
    pub fn joints(&self) -> &[Joint; N] {
        &self.joints
    }

    /// The names of [`Self::joints`], in the order of `q` (the URDF's joint names for a loaded chain).
    pub fn joint_names(&self) -> [&str; N] {
        self.joints.each_ref().map(Joint::name)
    }

    /// The mimic joints of the path, from base to tip, all after the last of [`Self::joints`] (see [`MimicJoint`]).
    pub fn mimic_joints(&self) -> &[MimicJoint] {
        &self.mimic_joints
    }

    /// Lower joint limits (rad or m); `−∞` for continuous joints (unless set by [`Self::with_limits`]).
    pub fn lower_limits(&self) -> &JointVector<N> {
        &self.lower
    }

    /// Upper joint limits (rad or m); `+∞` for continuous joints (unless set by [`Self::with_limits`]).
    pub fn upper_limits(&self) -> &JointVector<N> {
        &self.upper
    }

    /// The fixed pose of the tip frame in the frame of the last movable joint's child link (the last segment, the
    /// last mimic joint's child, or the base when the chain has no movable joint): the fixed joints after the last
    /// movable joint, composed.
    pub fn segment_from_tip(&self) -> &Isometry3<f64> {
        &self.segment_from_tip
    }

    /// Every URDF link on the path, from the base link to the tip link, with the segment carrying it.
    pub fn links(&self) -> &[ChainLink] {
        &self.links
    }

    /// The link of the path with this name, if any.
    pub fn link(&self, name: &str) -> Option<&ChainLink> {
        self.links.iter().find(|l| l.name == name)
    }

    /// The same chain with other joint limits `lower < upper` (rad for revolute and continuous joints, m for
    /// prismatic joints), e.g. the narrower ranges of a controller's safety configuration. Limits must be finite,
    /// except that a continuous joint may keep `(−∞, +∞)` (unlimited); a continuous joint given finite limits is
    /// limited from then on — soft limits the joint-limit cost keeps it within ([D18](crate::theory#d18)) — and its
    /// [`JointKind`] is unchanged. Nothing else of the chain changes.
    ///
    /// ```
    /// use servostack::math::JointVector;
    /// let chain = servostack::robot::builtin::ur5e()?.chain;
    /// let wrist = JointVector::<6>::from_element(1.0);
    /// let narrower = chain.with_limits(-wrist, wrist)?;
    /// assert_eq!(narrower.upper_limits()[5], 1.0);
    /// # Ok::<(), servostack::robot::RobotError>(())
    /// ```
    ///
    /// # Errors
    /// [`RobotError::NonFiniteLimits`] for a NaN or infinite limit (other than `(−∞, +∞)` on a continuous joint),
    /// [`RobotError::OutOfRange`] for one beyond [`crate::bounds::JOINT_POSITION`], [`RobotError::InvalidLimits`] for
    /// `lower ≥ upper`; both name the first joint at fault.
    pub fn with_limits(
        mut self,
        lower: JointVector<N>,
        upper: JointVector<N>,
    ) -> Result<Self, RobotError> {
        for (i, joint) in self.joints.iter().enumerate() {
            let (lo, hi) = (lower[i], upper[i]);
            let unlimited = joint.kind == JointKind::Continuous
                && lo == f64::NEG_INFINITY
                && hi == f64::INFINITY;
            if unlimited {
                continue;
            }
            if !(lo.is_finite() && hi.is_finite()) {
                return Err(RobotError::NonFiniteLimits {
                    joint: joint.name.clone(),
                    lower: lo,
                    upper: hi,
                });
            }
            if let Some(value) = [lo, hi].into_iter().find(|&v| !JOINT_POSITION.contains(v)) {
                return Err(RobotError::OutOfRange {
                    joint: joint.name.clone(),
                    field: "limit",
                    value,
                    expected: JOINT_POSITION.text,
                });
            }
            if lo >= hi {
                return Err(RobotError::InvalidLimits {
                    joint: joint.name.clone(),
                    lower: lo,
                    upper: hi,
                });
            }
        }
        self.lower = lower;
        self.upper = upper;
        Ok(self)
    }

    /// `true` when every joint of `q` lies in `[lower, upper]` (limits included).
    pub fn within_limits(&self, q: &JointVector<N>) -> bool {
        q.iter()
            .zip(self.lower.iter().zip(self.upper.iter()))
            .all(|(q, (lo, hi))| *lo <= *q && *q <= *hi)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// The pose-only pass and the completion of its Jacobians write what the full evaluation writes, bit for
        /// bit, from a workspace last used at another configuration: on the Afma6 and on the coupled Afma6, whose
        /// mimic joint adds its column to its leader's.
        #[test]
        fn tip_pose_then_its_jacobians_equal_the_full_kinematics(
            u in proptest::collection::vec(-1.0..1.0f64, 6),
        ) {
            for chain in [builtin::afma6().unwrap().chain, builtin::afma6_coupled().unwrap().chain] {
                let (lower, upper) = (chain.lower_limits(), chain.upper_limits());
                let q = JointVector::<6>::from_fn(|i, _| {
                    0.5 * (lower[i] + upper[i]) + 0.5 * (upper[i] - lower[i]) * u[i]
                });
                let mut full = KinematicsWorkspace::new();
                let expected = chain.kinematics(&mut full, &q).unwrap().clone();
                let mut split = KinematicsWorkspace::new();
                chain.kinematics(&mut split, &JointVector::zeros()).unwrap();
                prop_assert_eq!(chain.tip_pose(&mut split, &q).unwrap(), *expected.base_from_tip());
                prop_assert_eq!(chain.jacobians_after_tip_pose(&mut split), &expected);
            }
        }
    }

    #[test]
    fn with_limits_replaces_the_limits_and_nothing_else() {
        let chain = builtin::rail7().unwrap().chain;
        let lower = JointVector::<7>::from_element(-0.5);
        let upper = JointVector::<7>::from_element(0.25);
        let limited = chain.clone().with_limits(lower, upper).unwrap();
        assert_eq!(limited.lower_limits(), &lower);
        assert_eq!(limited.upper_limits(), &upper);
        // The continuous roll joint keeps its kind, now with finite limits.
        assert_eq!(limited.joints()[4].kind(), JointKind::Continuous);
        assert!(chain.upper_limits()[4].is_infinite());
        assert_eq!(limited.joints(), chain.joints());
        assert_eq!(limited.links(), chain.links());
        assert!(!limited.within_limits(&JointVector::<7>::from_element(0.3)));
    }

    #[test]
    fn with_limits_rejects_unordered_and_non_finite_limits() {
        let chain = builtin::ur5e().unwrap().chain;
        let lower = JointVector::<6>::from_element(-1.0);
        let upper = JointVector::<6>::from_element(1.0);
        let mut bad = upper;
        bad[2] = -1.0; // lower = upper
        match chain.clone().with_limits(lower, bad) {
            Err(RobotError::InvalidLimits {
                joint,
                lower,
                upper,
            }) => {
                assert_eq!(joint, chain.joints()[2].name());
                assert_eq!((lower, upper), (-1.0, -1.0));
            }
            other => panic!("expected InvalidLimits, got {other:?}"),
        }
        bad[2] = -2.0; // lower > upper
        assert!(matches!(
            chain.clone().with_limits(lower, bad),
            Err(RobotError::InvalidLimits { .. })
        ));
        for value in [f64::NAN, f64::INFINITY] {
            let mut bad = upper;
            bad[4] = value;
            match chain.clone().with_limits(lower, bad) {
                Err(RobotError::NonFiniteLimits { joint, .. }) => {
                    assert_eq!(joint, chain.joints()[4].name());
                }
                other => panic!("expected NonFiniteLimits, got {other:?}"),
            }
        }
        let mut bad = lower;
        bad[0] = f64::NEG_INFINITY;
        assert!(matches!(
            chain.clone().with_limits(bad, upper),
            Err(RobotError::NonFiniteLimits { .. })
        ));
        // (−∞, +∞) is refused on a revolute joint (joint 0)...
        let mut up = upper;
        up[0] = f64::INFINITY;
        assert!(matches!(
            chain.with_limits(bad, up),
            Err(RobotError::NonFiniteLimits { .. })
        ));
    }

    /// A continuous joint may be left unlimited next to soft limits on the others, or given soft limits itself.
    #[test]
    fn with_limits_keeps_a_continuous_joint_unlimited() {
        let chain = builtin::rail7().unwrap().chain;
        let mut lower = JointVector::<7>::from_element(-0.5);
        let mut upper = JointVector::<7>::from_element(0.5);
        lower[4] = f64::NEG_INFINITY;
        upper[4] = f64::INFINITY;
        let limited = chain.clone().with_limits(lower, upper).unwrap();
        assert!(limited.lower_limits()[4].is_infinite() && limited.upper_limits()[4].is_infinite());
        assert_eq!(limited.upper_limits()[3], 0.5);
        lower[4] = -1.0;
        assert!(matches!(
            chain.with_limits(lower, upper),
            Err(RobotError::NonFiniteLimits { .. })
        ));
    }
}
