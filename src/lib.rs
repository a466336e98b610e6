//! Stacked-task visual servoing (N. Mansard and F. Chaumette): prioritised visual tasks, joint-limit avoidance, and a
//! stack controller that removes the blocking task and puts it back later ([§6](crate::theory#s6)).
//!
//! - [`servo`]: the method behind one call per control period.
//! - Models: [`robot`], [`camera`], [`target`]. Tasks: [`feature`], [`visual_task`], [`task`].
//! - The law: [`stack`], [`continuity`], [`law`], [`avoidance`]. Controller: [`controller`].
//! - Real cameras: [`depth`], [`measurement`]. Simulation, study: [`sim`], [`scenario`], [`study`], [`report`].
//! - Basics: [`math`], [`linalg`], [`bounds`]. Documentation: [`theory`], [`guide`].
//!
//! # Quick start
//!
//! Dependencies: `servostack`, `nalgebra = "0.35"` (Rust 1.89 or later). A built-in arm, a simulated camera:
//!
//! ```rust
//! use nalgebra::{Isometry3, Vector6};
//! use servostack::camera::{CalibratedCamera, CameraIntrinsics};
//! use servostack::robot::{builtin, KinematicsWorkspace};
//! use servostack::servo::{Corners, DesiredImage, ServoConfig, VisualServo};
//! use servostack::target::RectangleTarget;
//!
//! fn main() -> Result<(), Box<dyn std::error::Error>> {
//!     // The Afma6 gantry and its camera; the goal: a 0.2 × 0.1 m target 0.5 m ahead (`cdMo`).
//!     let robot = builtin::afma6()?;
//!     let intrinsics = CameraIntrinsics::new(600.0, 600.0, 320.0, 240.0, 640.0, 480.0)?;
//!     let camera = CalibratedCamera::pinhole(intrinsics);
//!     let target = RectangleTarget::new(0.2, 0.1)?;
//!     let goal = Isometry3::translation(0.0, 0.0, 0.5);
//!     let chain = robot.chain.clone();
//!     let config = ServoConfig::new(chain, robot.mount, camera, target, DesiredImage::Pose(goal));
//!     let mut servo = VisualServo::new(config)?;
//!
//!     // Simulated world: the target seen as `goal` from `q_goal`; the robot starts elsewhere.
//!     let mut workspace = KinematicsWorkspace::new();
//!     let mut camera_pose = |q: &Vector6<f64>| {
//!         let kinematics = robot.chain.kinematics(&mut workspace, q);
//!         kinematics.map(|k| robot.mount.base_from_camera(k.base_from_tip()))
//!     };
//!     let q_goal = Vector6::new(0.0, 0.0, 0.0, 0.0, 1.2, 0.0);
//!     let base_from_target = camera_pose(&q_goal)? * goal;
//!     let mut q = q_goal + Vector6::new(0.05, -0.04, 0.03, 0.05, -0.05, 0.1);
//!
//!     for i in 0..6000 {
//!         let t = i as f64 * 0.01; // a 100 Hz loop
//!         // Simulated camera. A real loop reads the corners (px) from its detector here.
//!         let camera_from_target = camera_pose(&q)?.inverse() * base_from_target;
//!         let corners: Corners = target.points().map(|corner| {
//!             let p = camera_from_target * corner;
//!             Some(camera.pixel_of(p.x / p.z, p.y / p.z))
//!         });
//!         let output = servo.step(t, &corners, &q)?;
//!         if output.converged {
//!             println!("converged after {t:.1} s");
//!             return Ok(());
//!         }
//!         // Simulated robot. A real loop sends `output.velocity` to the drives here.
//!         q += output.velocity * 0.01;
//!     }
//!     Err("not converged".into())
//! }
//! ```
//!
//! Further: the [guides](guide) (your robot, reading results, a camera loop, tuning); [`theory`] defines every
//! number the docs cite; results (study, performance, reliability) in [`docs/`][docs], with the paper's
//! [figure][figure].
//!
//! [docs]: https://github.com/servostack/servostack/tree/main/docs
//! [figure]: https://github.com/servostack/servostack/blob/main/docs/paper_stack_controller_joints.png

#![warn(missing_docs)]
#![deny(unsafe_code)]
#![cfg_attr(docsrs, feature(doc_cfg))]

pub mod avoidance;
pub mod bounds;
pub mod camera;
pub mod continuity;
pub mod controller;
pub mod depth;
pub mod feature;
#[doc(hidden)]
pub mod fuzz;
pub mod law;
pub mod linalg;
pub mod math;
pub mod measurement;
#[cfg(feature = "plot")]
pub mod plot;
pub mod report;
pub mod robot;
pub mod scenario;
pub mod servo;
pub mod sim;
pub mod stack;
pub mod study;
pub mod target;
pub mod task;
pub mod visual_task;

#[doc = include_str!("../docs/theory.md")]
pub mod theory {
    #[doc = include_str!("../docs/peer_scene.md")]
    pub mod peer_scene {}
}

/// Guides: the tasks a user meets first, each with code that compiles.
pub mod guide {
    #[doc = include_str!("../docs/guide/your_robot.md")]
    pub mod your_robot {}
    #[doc = include_str!("../docs/guide/reading_results.md")]
    pub mod reading_results {}
    #[doc = include_str!("../docs/guide/camera_loop.md")]
    pub mod camera_loop {}
    #[doc = include_str!("../docs/guide/tuning.md")]
    pub mod tuning {}
}
