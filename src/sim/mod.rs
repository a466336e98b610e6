//! Kinematic simulation: a robot with an eye-in-hand camera looking at a planar target, driven by the stack controller
//! ([theory §9](crate::theory#s9), [D11](crate::theory#d11)).
//!
//! Each iteration at time `t = k·Δt`:
//!
//! 1. forward kinematics and `eJe(q)`; the camera pose `base_from_camera = base_from_tip · e_from_c` and the object
//!    pose in the camera `c_from_o = base_from_camera⁻¹ · base_from_object`;
//! 2. projection of the four target points (normalised `x, y` and depth `Z`), the target plane `(A, B, C)`, the
//!    camera Jacobian `cVe · eJe`; a point behind the camera or outside the image (with a margin in pixels) ends the
//!    run as **feature lost**;
//! 3. every visual task is evaluated (`e_i`, `L_i`, `J_i`, [\[M42\]](crate::theory#m42)); when the stack is complete and the error of
//!    every task is below the convergence threshold, the run has **converged**;
//! 4. one controller iteration ([`StackController::step`](crate::controller::StackController::step), given the
//!    scene's limits: for the full method, a joint braked onto a limit that the law drives in is locked, D26) gives
//!    `q̇`, scaled uniformly into the robot's velocity limits and, for the full method, braked before the hard
//!    limits and the border of the image (D25,
//!    [`ControllerParameters::braking_rate`](crate::controller::ControllerParameters::braking_rate));
//!    the controller is told what was sent; explicit Euler `q ← q + Δt q̇`;
//! 5. a joint outside `[q^min, q^max]` ends the run as **joint limit** (D11: a real robot stops at its limit), with the
//!    joint, the iteration and the tasks stacked; when the scene has obstacles, a link–obstacle signed distance `≤ 0`
//!    ends it as **collision**.
//!
//! The avoidance cost given to the law and the controller is the sum
//! ([`CompositeCost`](crate::avoidance::CompositeCost)) of the joint-limit cost and, when the scene has them, the
//! obstacle cost ([`Scene::with_obstacles`]) and the visibility cost ([`Scene::with_visibility_margin`]).
//!
//! Each iteration makes a [`Record`]: `q`, `q̇`, each task's error norm, the stack, the cost and its prediction, the
//! criteria, and the image points. The records go to a [`RunLog`] the caller chooses, so that a run of any length uses
//! bounded memory: every record (`Vec<Record<N>>`, what [`simulate`] keeps for the figures), an evenly spaced subset
//! of bounded size ([`Decimated`]), none ([`SummaryOnly`]) or a stream of JSON lines to a file ([`JsonLines`]). The
//! [`Run`] that [`simulate_with`] returns holds the outcome, the controller's event log (bounded: each task is pushed
//! once and removed at most `max_removals` times before the fallback of D13) and the summary of the run, accumulated
//! iteration by iteration and exact whatever the log kept: iterations, the last record (final errors, stack),
//! largest velocity step, continuity at every stack change, smallest joint-limit margin and obstacle distance.

mod drive;
mod log;
mod outcome;
mod parameters;
mod run;
mod scene;
mod sensing;

pub use drive::{simulate, simulate_with, Drive};
pub use log::{Decimated, JsonLines, RunLog, SummaryOnly};
pub use outcome::Outcome;
pub(crate) use parameters::incidence_reason;
pub use parameters::SimulationParameters;
pub use run::{EventContinuity, Record, Run};
pub use scene::{Scene, View};
pub use sensing::Sensing;

use crate::avoidance::CostError;
use crate::camera::CameraError;
use crate::controller::ControllerError;
use crate::feature::FeatureError;
use crate::measurement::MeasurementError;
use crate::robot::RobotError;
use crate::target::TargetError;
use crate::task::TaskError;

/// Errors of the simulation (distinct from the run's outcome: a joint limit or a lost feature is an outcome, not an
/// error).
#[non_exhaustive]
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SimError {
    /// A simulation parameter is out of range.
    #[error("simulation parameter `{name}` = {value} is invalid: {expected}")]
    InvalidParameter {
        /// The parameter.
        name: &'static str,
        /// Its value.
        value: f64,
        /// What is expected.
        expected: &'static str,
    },
    /// The start configuration is outside the joint limits.
    #[error("start configuration: joint {joint} = {value} is outside [{lower}, {upper}]")]
    StartOutsideLimits {
        /// The joint (0-based).
        joint: usize,
        /// Its value.
        value: f64,
        /// Lower limit.
        lower: f64,
        /// Upper limit.
        upper: f64,
    },
    /// The robot model failed (non-finite configuration).
    #[error(transparent)]
    Robot(#[from] RobotError),
    /// The camera model failed.
    #[error(transparent)]
    Camera(#[from] CameraError),
    /// The target model failed.
    #[error(transparent)]
    Target(#[from] TargetError),
    /// A feature is undefined on the desired or current image.
    #[error(transparent)]
    Feature(#[from] FeatureError),
    /// A task failed.
    #[error(transparent)]
    Task(#[from] TaskError),
    /// The controller failed.
    #[error(transparent)]
    Controller(#[from] ControllerError),
    /// The joint-limit cost failed.
    #[error(transparent)]
    Cost(#[from] CostError),
    /// The measurement model or the depth source has invalid parameters.
    #[error(transparent)]
    Measurement(#[from] MeasurementError),
    /// The run log could not keep a record (an I/O error of a [`JsonLines`] log).
    #[error("run log, iteration {iteration}: {message}")]
    Log {
        /// The iteration whose record was refused.
        iteration: usize,
        /// The log's message.
        message: String,
    },
}
