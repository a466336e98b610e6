//! What a first program needs, in one `use servostack::prelude::*;`: the servo façade, the models (robot, mount,
//! camera, target), the simulated experiment and its settings, the run's outcome and events, and the nalgebra types
//! of poses and joint vectors.
//!
//! ```
//! use servostack::prelude::*;
//!
//! let robot = builtin::afma6()?;
//! let goal = Isometry3::translation(0.0, 0.0, 0.5);
//! let q = JointVector::<6>::from([0.0, 0.0, 0.0, 0.0, 1.2, 0.0]);
//! assert!(robot.chain.lower_limits()[4] < q[4] && goal.translation.z > 0.0);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub use crate::camera::{CalibratedCamera, CameraIntrinsics, EyeInHand};
pub use crate::controller::{ControllerParameters, EventKind, StackEvent};
pub use crate::math::JointVector;
pub use crate::robot::{builtin, KinematicsWorkspace, SerialChain};
pub use crate::scenario::{Experiment, RunKind, Scenario, Settings};
pub use crate::servo::{Corners, DesiredImage, ServoConfig, VisualServo};
pub use crate::sim::{Outcome, Run};
pub use crate::target::RectangleTarget;
pub use nalgebra::{Isometry3, SVector, Translation3, UnitQuaternion, Vector3, Vector6};
