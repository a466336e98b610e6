//! How a run ended: the [`Outcome`], and how a run that used its whole budget, or whose controller held, is named
//! (stalled on a task, or still converging).

use super::Record;
use crate::controller::{ControllerStatus, StackController};

/// How a run ended.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
#[serde(tag = "outcome", rename_all = "snake_case")]
pub enum Outcome {
    /// Every task stacked and achieved, with the camera at its goal pose (within
    /// [`SimulationParameters::goal_tolerance_m`](super::SimulationParameters::goal_tolerance_m) and
    /// [`SimulationParameters::goal_tolerance_deg`](super::SimulationParameters::goal_tolerance_deg)).
    Converged,
    /// Every task stacked and its error below the threshold, but the camera away from its goal pose: the features
    /// take their desired values at another pose too ([D22](crate::theory#d22)), or measurement errors bias where they
    /// settle. The loop would stay there: the run ends.
    OffGoal {
        /// The camera's distance to its goal pose (m).
        translation_m: f64,
        /// The rotation between the camera and its goal pose (degrees).
        rotation_deg: f64,
    },
    /// A joint left its limits (D11).
    JointLimit {
        /// The joint (0-based).
        joint: usize,
        /// The tasks stacked when it happened (indices into the task list).
        stacked: Vec<usize>,
    },
    /// A target point went behind the camera or out of the image.
    FeatureLost {
        /// The point (0-based).
        point: usize,
    },
    /// The iteration budget ran out with every task stacked: the errors were still above the threshold.
    MaxIterations {
        /// What the run was doing (the task errors at the end).
        reason: String,
    },
    /// The iteration budget ran out while a task was removed or waiting to be pushed, or the controller held before a
    /// hard limit and the robot came to rest (D13): the run names the task and why.
    Stalled {
        /// The task that waited (index into the task list).
        task: usize,
        /// Why it could not come in.
        reason: String,
    },
    /// The target is seen edge-on: its plane passes through the optical centre, it is seen more obliquely than
    /// [`SimulationParameters::max_incidence_deg`](super::SimulationParameters::max_incidence_deg) (D27), or a feature
    /// is undefined on the image (collinear points, vanishing area).
    ImageDegenerate {
        /// What is undefined.
        reason: String,
    },
    /// A link touched or penetrated an obstacle (signed distance `≤ 0`).
    Collision {
        /// The link.
        link: String,
        /// The obstacle.
        obstacle: String,
        /// Their signed distance (m, `≤ 0`).
        distance: f64,
        /// The tasks stacked when it happened.
        stacked: Vec<usize>,
    },
}

impl Outcome {
    /// Every [`Outcome::name`], in the order of the variants.
    pub const NAMES: [&'static str; 8] = [
        "converged",
        "off_goal",
        "joint_limit",
        "feature_lost",
        "max_iterations",
        "stalled",
        "image_degenerate",
        "collision",
    ];

    /// The short name used in summaries: `converged`, `off_goal`, `joint_limit`, `feature_lost`, `max_iterations`,
    /// `stalled`, `image_degenerate`, `collision`.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Converged => "converged",
            Self::OffGoal { .. } => "off_goal",
            Self::JointLimit { .. } => "joint_limit",
            Self::FeatureLost { .. } => "feature_lost",
            Self::MaxIterations { .. } => "max_iterations",
            Self::Stalled { .. } => "stalled",
            Self::ImageDegenerate { .. } => "image_degenerate",
            Self::Collision { .. } => "collision",
        }
    }
}

/// How a run that used its whole budget ended — stalled on a task that could not come in (D13), or still converging —
/// or one whose controller held (D13) once the robot is at rest.
pub(super) fn budget_outcome<const N: usize>(
    controller: &StackController<N>,
    task_names: &[String],
    last: Option<&Record<N>>,
) -> Outcome {
    let errors = last.map(|r| r.task_errors.as_slice()).unwrap_or_default();
    let error_list = task_names
        .iter()
        .zip(errors)
        .map(|(name, e)| format!("{name} {e:.1e}"))
        .collect::<Vec<_>>()
        .join(", ");
    match controller.status() {
        ControllerStatus::Reinserting {
            task,
            last_test: Some(test),
            ..
        } => Outcome::Stalled {
            task,
            reason: format!(
                "{} was removed and its re-insertion was refused to the end: the cost predicted with it back is \
                 {:.2e} > {:.2e} (task errors: {error_list})",
                task_names[task], test.predicted_cost, test.threshold
            ),
        },
        ControllerStatus::Reinserting {
            task,
            last_test: None,
            stack_velocity_norm,
        } => Outcome::Stalled {
            task,
            reason: format!(
                "{} was removed and its re-insertion was never tested (a test waits for the stack to settle and for \
                 the task's dwell): ‖q̇_n‖ = {stack_velocity_norm:.2e} at the end (task errors: {error_list})",
                task_names[task]
            ),
        },
        ControllerStatus::Pushing {
            next,
            stack_velocity_norm,
        } => Outcome::Stalled {
            task: next,
            reason: format!(
                "{} was never pushed: the stack did not settle (‖q̇_n‖ = {stack_velocity_norm:.2e} at the end; task \
                 errors: {error_list})",
                task_names[next]
            ),
        },
        ControllerStatus::Held { task, time } => Outcome::Stalled {
            task,
            reason: format!(
                "held at t = {time:.2} s: after the fallback the law was predicted past a hard limit (or to lose the \
                 target) one transition ahead and no task could be removed, so every task was dropped from {} on and \
                 the robot kept inside its limits (task errors: {error_list})",
                task_names[task]
            ),
        },
        ControllerStatus::Complete => {
            // The joints held at a limit at the end (D26): the tasks were pressing them into it.
            let locked = controller.law_workspace().locked_joints();
            let locked_list = (0..N)
                .filter(|&joint| locked[joint])
                .map(|joint| joint.to_string())
                .collect::<Vec<_>>();
            let locked_note = if locked_list.is_empty() {
                String::new()
            } else {
                format!(
                    "; locked at a hard limit, the tasks pressing them in: joint {}",
                    locked_list.join(", ")
                )
            };
            Outcome::MaxIterations {
                reason: format!(
                    "every task stacked; task errors at the end: {error_list}{locked_note}"
                ),
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::avoidance::JointLimits;
    use crate::controller::ControllerParameters;
    use crate::law::ControlLaw;
    use crate::math::JointVector;
    use crate::task::TaskJacobian;
    use crate::task::TaskValue;
    use nalgebra::DVector;

    /// D26: a run whose budget ends with every task stacked names the joints its tasks hold locked at a limit, and
    /// only those.
    #[test]
    fn a_budget_that_ends_with_a_locked_joint_names_it() {
        // One task driving joint 1 down (e = 1, J = [0, 1]: q̇ = −λ J⁺ e = (0, −1)).
        let jacobian = TaskJacobian::<2>::from_row_slice(&[0.0, 1.0]);
        let tasks = [
            TaskValue::from_parts("reach", DVector::from_element(1, 1.0), jacobian, 1.0).unwrap(),
        ];
        let limits = JointLimits::new(
            JointVector::<2>::new(-1.0, -1.0),
            JointVector::<2>::new(1.0, 1.0),
            0.1,
        )
        .unwrap();
        let law = ControlLaw::new(10.0, 0.0).unwrap();
        let reason_at = |q: JointVector<2>| {
            let mut controller = StackController::new(ControllerParameters::default(), &tasks)
                .unwrap()
                .with_joint_limits(limits.clone())
                .unwrap();
            controller.step(&law, &tasks, None, &q, 0, 0.01).unwrap();
            assert!(controller.is_complete());
            match budget_outcome(&controller, &["reach".to_string()], None) {
                Outcome::MaxIterations { reason } => reason,
                other => panic!("{other:?}"),
            }
        };
        let at_limit = reason_at(JointVector::<2>::new(0.0, -1.0));
        assert!(
            at_limit.ends_with("locked at a hard limit, the tasks pressing them in: joint 1"),
            "{at_limit}"
        );
        let inside = reason_at(JointVector::<2>::new(0.0, -0.5));
        assert!(!inside.contains("locked"), "{inside}");
    }
}
