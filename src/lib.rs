//! Stacked-task visual servoing (N. Mansard and F. Chaumette): prioritised visual tasks, joint-limit avoidance, and a
//! stack controller that removes the blocking task and puts it back later ([§6](crate::theory#s6)).
//!
//! - [`prelude`]: what a first program uses (with [`nalgebra`], re-exported). [`servo`]: the method, one call a period.
//! - Models: [`robot`], [`camera`], [`target`]. Tasks: [`feature`], [`visual_task`], [`task`].
//! - The law: [`stack`], [`continuity`], [`law`], [`avoidance`]. Controller: [`controller`].
//! - Real cameras: [`depth`], [`measurement`]. Simulation, study: [`sim`], [`scenario`], [`study`], [`report`].
//! - Basics: [`math`], [`linalg`], [`bounds`]. Documentation: [`theory`], [`guide`].
//!
//! # Quick start
//!
//! Dependencies: `servostack` (it re-exports [`nalgebra`]; Rust 1.89 or later). A built-in arm, a calibration file,
//! a simulated camera:
//!
//! ```rust
//! use servostack::prelude::*;
//!
//! fn main() -> Result<(), Box<dyn std::error::Error>> {
//!     // The Afma6 gantry, its camera mount, a 0.2 × 0.1 m target seen 0.5 m ahead at the goal.
//!     let (robot, target) = (builtin::afma6()?, RectangleTarget::new(0.2, 0.1)?);
//!     let camera = CalibratedCamera::from_yaml_file("tests/data/ros_camera_info.yaml")?;
//!     let (goal, chain) = (Isometry3::translation(0.0, 0.0, 0.5), robot.chain.clone());
//!     let config = ServoConfig::new(chain, robot.mount, camera, target, DesiredImage::Pose(goal));
//!     let mut servo = VisualServo::new(config)?;
//!     // A simulated world: the target seen as `goal` from `q_goal`; the robot starts elsewhere.
//!     let q_goal = JointVector::<6>::from([0.0, 0.0, 0.0, 0.0, 1.2, 0.0]);
//!     let mut q = q_goal + JointVector::<6>::from([0.05, -0.04, 0.03, 0.05, -0.05, 0.1]);
//!     let world = Experiment::builder(robot.chain, robot.mount, camera, target);
//!     let world = world.goal(q_goal, goal).start(q).build()?;
//!     for i in 0..6000 {
//!         let t = i as f64 * 0.01; // a 100 Hz loop
//!         let output = servo.step(t, &world.corners(&q)?, &q)?; // or a detector's corners (px)
//!         if output.converged {
//!             println!("converged after {t:.1} s");
//!             return Ok(());
//!         }
//!         q += output.velocity * 0.01; // a real loop sends `output.velocity` to the drives here
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
pub mod prelude;
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

/// nalgebra, whose vectors and poses the API takes (so that a user need not depend on it, nor match its version).
pub use nalgebra;

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
