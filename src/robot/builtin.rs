//! Built-in robots with their eye-in-hand cameras, each also shipped as a URDF file under `assets/urdf/`.
//!
//! The constructors embed those files (`include_str!`), so a built-in robot and its URDF file are the same model by
//! construction. The camera mount `e_from_c` is read from the URDF too: a fixed joint from the tip link to a camera
//! link (z forward, x right, y down). For your own URDF with such a camera link, the same idiom is
//! `EyeInHand::new(*SerialChain::<0>::from_urdf_str(xml, tip, camera)?.segment_from_tip())`.
//!
//! | name | `N` | base → tip (camera) | model |
//! |---|---|---|---|
//! | `"afma6"` | 6 | `afma6_base` → `afma6_end_effector` (`afma6_camera`) | Afma6-like gantry of the [peer scene](crate::theory::peer_scene), [theory §9](crate::theory#s9), [D12](crate::theory#d12) |
//! | `"afma6_coupled"` | 6 | as `"afma6"` | the same gantry with ViSP's coupling of the last two joints, a mimic joint ([D19](crate::theory#d19)) |
//! | `"ur5e"` | 6 | `base_link` → `tool0` (`camera_link`) | UR5e-class arm from its published DH parameters |
//! | `"rail7"` | 7 | `rail7_base` → `rail7_tool` (`rail7_camera`) | a mixed 7-joint test chain (not a real robot) |
//!
//! **Afma6** (ViSP `vpAfma6`): joints 1–3 prismatic (gantry x, y, z, m), 4–6 revolute (rad); wrist offset
//! [`AFMA6_WRIST_OFFSET`]; limits of ViSP 2011–2015; camera mount `eMc` of ViSP's Afma6 camera. The mechanical
//! coupling [`AFMA6_COUPLING`] between joints 5 and 6 is **ignored** (`g = 0`, [D12](crate::theory#d12)): `base_from_tip` is ViSP's
//! `fMe` and `tip_jacobian` its `eJe` with `g = 0`. **Afma6 coupled** ([`afma6_coupled`]) is the same model with the
//! coupling: a mimic joint `afma6_coupling` after joint 6, about the same axis, at `−g q5`, so the last rotation is
//! `q6 − g q5` and `base_from_tip`, `tip_jacobian` are ViSP's `fMe`, `eJe` exactly (column 5 gains `−g` in its `ω_z`
//! row).
//!
//! **UR5e** (DH frames, `d = (0.1625, 0, 0, 0.1333, 0.0997, 0.0996)` m, `a = (0, −0.425, −0.3922, 0, 0, 0)` m,
//! `α = (π/2, 0, 0, π/2, −π/2, 0)`): limits `±2π` on every joint except the elbow, `±π`. The camera looks along the
//! tool z axis, its axes parallel to `tool0`, at `(0, −0.06, 0.03)` m in `tool0`.

use super::urdf::parse_urdf;
use super::{RobotError, SerialChain};
use crate::camera::EyeInHand;

/// The Afma6 URDF (`assets/urdf/afma6.urdf`).
pub const AFMA6_URDF: &str = include_str!("../../assets/urdf/afma6.urdf");
/// The UR5e-class arm URDF (`assets/urdf/ur5e.urdf`).
pub const UR5E_URDF: &str = include_str!("../../assets/urdf/ur5e.urdf");
/// The Afma6 URDF with ViSP's coupling of joints 5 and 6 as a mimic joint (`assets/urdf/afma6_coupled.urdf`).
pub const AFMA6_COUPLED_URDF: &str = include_str!("../../assets/urdf/afma6_coupled.urdf");
/// The seven-joint test chain URDF (`assets/urdf/rail7.urdf`).
pub const RAIL7_URDF: &str = include_str!("../../assets/urdf/rail7.urdf");

/// Afma6 wrist offset `L` (m): the end-effector origin is at `(q1 + L cos q4, q2 + L sin q4, q3)` ([peer scene](crate::theory::peer_scene#fme)).
pub const AFMA6_WRIST_OFFSET: f64 = -0.06924;
/// Afma6 coupling `g` between joints 5 and 6 in ViSP's model (last rotation `q6 − g q5`); **not** modelled by the
/// built-in `"afma6"` ([D12](crate::theory#d12)), modelled by `"afma6_coupled"` ([`afma6_coupled`]).
pub const AFMA6_COUPLING: f64 = 0.009091;

/// A built-in robot: its chain and its eye-in-hand camera mount.
#[derive(Debug, Clone, PartialEq)]
pub struct BuiltinRobot<const N: usize> {
    /// The name it is looked up by (see [`NAMES`]).
    pub name: &'static str,
    /// The kinematic chain from base to end effector.
    pub chain: SerialChain<N>,
    /// The camera mount on the end effector (`eMc`).
    pub mount: EyeInHand,
}

struct Spec {
    name: &'static str,
    urdf: &'static str,
    base: &'static str,
    tip: &'static str,
    camera: &'static str,
}

const SPECS: [Spec; 4] = [
    Spec {
        name: "afma6",
        urdf: AFMA6_URDF,
        base: "afma6_base",
        tip: "afma6_end_effector",
        camera: "afma6_camera",
    },
    Spec {
        name: "afma6_coupled",
        urdf: AFMA6_COUPLED_URDF,
        base: "afma6_base",
        tip: "afma6_end_effector",
        camera: "afma6_camera",
    },
    Spec {
        name: "ur5e",
        urdf: UR5E_URDF,
        base: "base_link",
        tip: "tool0",
        camera: "camera_link",
    },
    Spec {
        name: "rail7",
        urdf: RAIL7_URDF,
        base: "rail7_base",
        tip: "rail7_tool",
        camera: "rail7_camera",
    },
];

/// The names of the built-in robots, for [`by_name`].
pub const NAMES: &[&str] = &[SPECS[0].name, SPECS[1].name, SPECS[2].name, SPECS[3].name];

/// The built-in robot of this name, with `N` joints (for scenario files).
///
/// # Errors
/// [`RobotError::UnknownRobot`] for a name not in [`NAMES`]; [`RobotError::JointCount`] when the robot does not have
/// `N` joints (`"afma6"`, `"afma6_coupled"` and `"ur5e"` have 6, `"rail7"` has 7).
pub fn by_name<const N: usize>(name: &str) -> Result<BuiltinRobot<N>, RobotError> {
    let spec = SPECS
        .iter()
        .find(|s| s.name == name)
        .ok_or_else(|| RobotError::UnknownRobot {
            name: name.to_owned(),
            known: NAMES,
        })?;
    let robot = parse_urdf(spec.urdf)?;
    let chain = SerialChain::from_urdf_robot(&robot, spec.base, spec.tip)?;
    let mount = SerialChain::<0>::from_urdf_robot(&robot, spec.tip, spec.camera)?;
    Ok(BuiltinRobot {
        name: spec.name,
        chain,
        mount: EyeInHand::new(*mount.segment_from_tip())?,
    })
}

/// The URDF text of the built-in robot of this name (for its `<collision>` geometry, see
/// [`crate::avoidance::LinkColliders`]).
///
/// # Errors
/// [`RobotError::UnknownRobot`] for a name not in [`NAMES`].
pub fn urdf_by_name(name: &str) -> Result<&'static str, RobotError> {
    SPECS
        .iter()
        .find(|s| s.name == name)
        .map(|s| s.urdf)
        .ok_or_else(|| RobotError::UnknownRobot {
            name: name.to_owned(),
            known: NAMES,
        })
}

/// The Afma6-like gantry with its camera (see the [module docs](self)).
///
/// # Errors
/// None in practice (the model is embedded); the `Result` carries any URDF error of [`by_name`].
pub fn afma6() -> Result<BuiltinRobot<6>, RobotError> {
    by_name("afma6")
}

/// The Afma6-like gantry with ViSP's coupling of its last two joints, and its camera (see the [module docs](self)).
///
/// # Errors
/// As [`afma6`].
pub fn afma6_coupled() -> Result<BuiltinRobot<6>, RobotError> {
    by_name("afma6_coupled")
}

/// The UR5e-class arm with its flange camera (see the [module docs](self)).
///
/// # Errors
/// As [`afma6`].
pub fn ur5e() -> Result<BuiltinRobot<6>, RobotError> {
    by_name("ur5e")
}

/// The seven-joint test chain with its camera (see the [module docs](self)).
///
/// # Errors
/// As [`afma6`].
pub fn rail7() -> Result<BuiltinRobot<7>, RobotError> {
    by_name("rail7")
}
