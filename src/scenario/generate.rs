//! The paper's scenario for any arm: [`generate`] (re-exported by [`crate::scenario`]).

use super::{
    invalid, with_joint_count, ForJointCount, JointLimitsSpec, RobotSpec, RunKind, Scenario,
    ScenarioError,
};
use crate::math::JointVector;
use crate::robot::KinematicsWorkspace;
use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The scenario whose camera, target, desired pose, tasks and settings every generated scenario takes.
const TEMPLATE: &str = include_str!("../../assets/scenarios/ur5e_limits.toml");

/// The template's gains (the tasks' `λ_i` and the classical `λ`, 0.6 s⁻¹; the avoidance's `κ`, 1 s⁻¹) are multiplied by
/// this in every generated scenario: the same laws run four times faster (`λ = 2.4 s⁻¹`, `κ = 4 s⁻¹`; the transition's
/// `μ = 10 max λ_i` follows). With `κ/λ` kept, the laws without a clock (the classical law, the stack, the stack with
/// avoidance) are the template's in a time four times shorter, and converge from as many draws. The template's time
/// constant, 1.7 s, is the paper scene's; on the zoo's arms, whose uniform starts need a restart of the sequence more
/// often, it left the 80 s budget only a few time constants per task, and their wins came in its last third.
pub const GAIN_FACTOR: f64 = 4.0;

/// The angles tried for the start's turned joint (rad), in order.
const START_TURNS: [f64; 6] = [1.6, -1.6, 1.2, -1.2, 0.8, -0.8];

/// The fractions of the classical law's excursion at which the restricted limit is tried, in order.
const LIMIT_FRACTIONS: [f64; 3] = [0.7, 0.5, 0.3];

/// The restricted range, as a multiple of the limit's distance to the span of the start and goal values.
const RANGE_FACTOR: f64 = 11.0;

/// The smallest excursion (m or rad) that is restricted: below it, the classical law does not stray.
const MIN_EXCURSION: f64 = 1e-3;

/// The smallest singular value of the camera Jacobian accepted at the goal (m/s or rad/s per unit of joint velocity).
pub const MIN_GOAL_SINGULAR_VALUE: f64 = 1e-3;

/// One arm: a robot (base and tool links, camera mount) and, when the middle of its ranges is no goal, its own.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ArmSpec {
    /// A short name: the generated scenario's name.
    pub name: String,
    /// The robot, as in a scenario's `[robot]` (paths relative to the directory given to [`generate`]).
    pub robot: RobotSpec,
    /// The goal configuration (m or rad per joint); default: the middle of every joint's range.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub goal_joints: Option<Vec<f64>>,
    /// Why the arm has the links, mount or goal it has.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub note: String,
}

/// The paper's scenario for `arm`: the limit-avoidance story of `assets/scenarios/ur5e_limits.toml` on that arm
/// ([theory §9](crate::theory#s9)), for the zoo of real arms ([`super::Zoo`]). Relative paths of its robot are
/// resolved against `base_dir` and written resolved, so the scenario runs from anywhere.
///
/// What is taken from `ur5e_limits.toml` as it is: the camera (600 px, 640 × 480), the 0.2 × 0.1 m target, the pose
/// the camera sees it from at the goal (0.45 m in front, tilted by 15° about the camera x axis), the tasks and the
/// avoidance (their gains times [`GAIN_FACTOR`]), the controller and the simulation. What is made for the arm, in this
/// order:
///
/// 1. **Limits**: the chain's own, an unlimited (continuous) joint given `[−π, π]`, one turn about its goal value 0
///    (left unlimited, or given a little more or less than a turn, the zoo's Kinova and PR2 gain in some studies and
///    lose in others: docs/theory_notes.md, D29); written out in `robot.joint_limits`.
/// 2. **Goal** `q*`: the middle of every joint's range (0 for a continuous joint), or the arm's `goal_joints`. A goal
///    where the camera Jacobian `cVe · eJe` loses rank (a stretched elbow, aligned wrist axes) is refused: the
///    classical law has no meaning there.
/// 3. **Target**: placed so that the goal camera sees it at the template's pose; the desired image is its projection at
///    the goal ([`crate::sim::Scene::with_target_seen_from`]).
/// 4. **Start**: the goal with one joint turned by 1.6 rad (or 1.2, 0.8, either sign: the first that keeps the
///    start inside the limits with the target in view), the joint whose motion turns the camera most purely about its
///    optical axis at the goal — the paper's situation, where the classical law's straight image paths back the camera
///    up.
/// 5. **A limit the classical law meets**: the classical law is run from the start with those limits. If it already
///    ends at a limit, they stay. Otherwise, the joint that strays farthest outside the span of its start and goal
///    values is restricted on that side, at 0.7 of its excursion (then 0.5, 0.3 until the classical law meets it), with
///    a range of 11 times the limit's distance to the span (as the UR5e's elbow: 0.05 rad from the goal, 0.55 rad of
///    range), within the chain's own limits.
///
/// The scenario's `description` says which joint was turned and which limit was set, and how the classical law ended.
///
/// # Errors
/// An invalid robot (unreadable URDF, unknown links, more than [`super::MAX_JOINTS`] joints), `goal_joints` of the
/// wrong size or outside the limits, a goal where the camera Jacobian's smallest singular value is below
/// [`MIN_GOAL_SINGULAR_VALUE`] (`desired.joints`), no joint that turns the camera with the target in view
/// (`start.joints`), failures of the classical run.
///
/// ```
/// use servostack::scenario::{generate, ArmSpec, RobotSpec, RunKind};
/// let arm = ArmSpec {
///     name: "ur5e_generated".into(),
///     robot: RobotSpec::Builtin { builtin: "ur5e".into(), joint_limits: None },
///     goal_joints: Some(vec![0.0, -1.9, 1.9, -1.571, -1.571, 0.0]),
///     note: String::new(),
/// };
/// let scenario = generate(&arm, None)?;
/// assert_eq!(scenario.run::<6>(RunKind::Classical)?.outcome.name(), "joint_limit");
/// # Ok::<(), servostack::scenario::ScenarioError>(())
/// ```
pub fn generate(arm: &ArmSpec, base_dir: Option<&Path>) -> Result<Scenario, ScenarioError> {
    let mut scenario = Scenario::from_toml_str(TEMPLATE, None)?;
    scenario.name = arm.name.clone();
    scenario.tasks.gains = scenario.tasks.gains.map(|gain| gain * GAIN_FACTOR);
    scenario.tasks.classical_gain *= GAIN_FACTOR;
    scenario.avoidance.gain *= GAIN_FACTOR;
    scenario.robot = resolved(&arm.robot, base_dir);
    struct Work<'a>(Scenario, &'a ArmSpec);
    impl ForJointCount for Work<'_> {
        type Output = Result<Scenario, ScenarioError>;
        fn call<const N: usize>(self) -> Self::Output {
            generate_for::<N>(self.0, self.1)
        }
    }
    with_joint_count(scenario.joint_count()?, Work(scenario, arm))?
}

/// The robot with its URDF and package paths joined to `base_dir`.
fn resolved(robot: &RobotSpec, base_dir: Option<&Path>) -> RobotSpec {
    let mut robot = robot.clone();
    if let (Some(dir), RobotSpec::Urdf { urdf, packages, .. }) = (base_dir, &mut robot) {
        *urdf = dir.join(&*urdf);
        for path in packages.values_mut() {
            *path = dir.join(&*path);
        }
    }
    robot
}

fn set_limits(robot: &mut RobotSpec, lower: &[f64], upper: &[f64]) {
    let limits = Some(JointLimitsSpec {
        lower: lower.to_vec(),
        upper: upper.to_vec(),
    });
    match robot {
        RobotSpec::Builtin { joint_limits, .. } | RobotSpec::Urdf { joint_limits, .. } => {
            *joint_limits = limits
        }
    }
}

fn generate_for<const N: usize>(
    mut scenario: Scenario,
    arm: &ArmSpec,
) -> Result<Scenario, ScenarioError> {
    // 1. Finite limits.
    let (chain, _) = scenario.robot_model::<N>()?;
    let pi = std::f64::consts::PI;
    let finite = |value: f64, default: f64| if value.is_finite() { value } else { default };
    let mut lower: Vec<f64> = chain
        .lower_limits()
        .iter()
        .map(|&l| finite(l, -pi))
        .collect();
    let mut upper: Vec<f64> = chain
        .upper_limits()
        .iter()
        .map(|&u| finite(u, pi))
        .collect();
    set_limits(&mut scenario.robot, &lower, &upper);
    // 2. The goal, and its rank.
    let goal: Vec<f64> = match &arm.goal_joints {
        Some(goal) => goal.clone(),
        None => (0..N).map(|i| 0.5 * (lower[i] + upper[i])).collect(),
    };
    scenario.desired.joints = goal.clone();
    scenario.start.joints = goal.clone();
    let experiment = scenario.experiment::<N>()?;
    let mut workspace = KinematicsWorkspace::new();
    let q_goal = JointVector::<N>::from_column_slice(&goal);
    let view = experiment.scene.observe(&mut workspace, &q_goal)?;
    let jacobian = DMatrix::from_column_slice(6, N, view.camera_jacobian.as_slice());
    let singular_values = jacobian.singular_values();
    let smallest = singular_values
        .iter()
        .copied()
        .fold(f64::INFINITY, f64::min);
    // A non-finite singular value (a Jacobian the kinematics should never give) is refused too.
    if singular_values.iter().any(|s| !s.is_finite()) || smallest < MIN_GOAL_SINGULAR_VALUE {
        return Err(invalid(
            "desired.joints",
            format!(
                "the camera Jacobian at the goal {goal:?} is singular (smallest singular value {smallest:e}, below \
                 {MIN_GOAL_SINGULAR_VALUE:e}): give the arm a goal_joints"
            ),
        ));
    }
    // 4. The start: the joint that turns the camera most purely about its optical axis.
    let depth = experiment.desired_camera_from_target.translation.z;
    let purity = |i: usize| {
        let column = view.camera_jacobian.column(i);
        let lateral = (column[0] / depth).powi(2)
            + (column[1] / depth).powi(2)
            + (column[2] / depth).powi(2)
            + column[3].powi(2)
            + column[4].powi(2);
        column[5].abs() / (lateral + column[5].powi(2)).sqrt().max(f64::MIN_POSITIVE)
    };
    let mut candidates: Vec<usize> = (0..N)
        .filter(|&i| chain.joints()[i].kind().is_rotational())
        .collect();
    candidates.sort_by(|&a, &b| purity(b).total_cmp(&purity(a)));
    let (turned, turn) = candidates
        .iter()
        .flat_map(|&i| START_TURNS.iter().map(move |&turn| (i, turn)))
        .find(|&(i, turn)| {
            let mut start = goal.clone();
            start[i] += turn;
            let mut trial = scenario.clone();
            trial.start.joints = start;
            trial.experiment::<N>().is_ok()
        })
        .ok_or_else(|| {
            invalid(
                "start.joints",
                "no joint turns the camera by 0.8 rad or more with the start inside the limits and the target in view",
            )
        })?;
    scenario.start.joints[turned] += turn;
    // 5. A limit the classical law meets.
    let run = scenario.run::<N>(RunKind::Classical)?;
    let mut story = format!(
        "Generated by servostack::scenario::generate for the arm `{}`: the camera, target, desired pose, tasks and \
         settings of ur5e_limits.toml, the gains times {GAIN_FACTOR}; the goal [{}] ({}); the start turns joint {turned} ({}) by {turn} rad, the joint \
         that turns the camera most purely about its optical axis at the goal.",
        arm.name,
        goal.iter().map(|q| format!("{q:.4}")).collect::<Vec<_>>().join(", "),
        if arm.goal_joints.is_some() {
            "the arm's own"
        } else {
            "the middle of the ranges"
        },
        chain.joints()[turned].name(),
    );
    if run.outcome.name() == "joint_limit" {
        story.push_str(" With the arm's own limits, the classical law already ends at a limit.");
        scenario.description = story;
        return Ok(scenario);
    }
    let (start, goal_q) = (&scenario.start.joints, &goal);
    let span = |j: usize| (start[j].min(goal_q[j]), start[j].max(goal_q[j]));
    // (joint, excursion, upper side?)
    let mut stray: Option<(usize, f64, bool)> = None;
    for record in &run.records {
        for j in 0..N {
            let (low, high) = span(j);
            for (excursion, up) in [(record.q[j] - high, true), (low - record.q[j], false)] {
                if excursion > stray.map_or(MIN_EXCURSION, |s| s.1) {
                    stray = Some((j, excursion, up));
                }
            }
        }
    }
    let Some((joint, excursion, up)) = stray else {
        story.push_str(&format!(
            " The classical law ends as `{}` without straying from the span of its start and goal: no limit is set.",
            run.outcome.name()
        ));
        scenario.description = story;
        return Ok(scenario);
    };
    let (low, high) = span(joint);
    let (own_lower, own_upper) = (lower[joint], upper[joint]);
    for fraction in LIMIT_FRACTIONS {
        let distance = fraction * excursion;
        if up {
            upper[joint] = high + distance;
            lower[joint] =
                own_lower.max((upper[joint] - RANGE_FACTOR * distance).min(low - distance));
        } else {
            lower[joint] = low - distance;
            upper[joint] =
                own_upper.min((lower[joint] + RANGE_FACTOR * distance).max(high + distance));
        }
        set_limits(&mut scenario.robot, &lower, &upper);
        let outcome = scenario.run::<N>(RunKind::Classical)?.outcome;
        if outcome.name() == "joint_limit" || fraction == LIMIT_FRACTIONS[LIMIT_FRACTIONS.len() - 1]
        {
            story.push_str(&format!(
                " With the arm's own limits the classical law ends as `{}` after taking joint {joint} ({}) {excursion:.3} \
                 outside the span of its start and goal values; that joint is restricted to [{:.4}, {:.4}] (the limit \
                 at {fraction} of the excursion), where the classical law ends as `{}`.",
                run.outcome.name(),
                chain.joints()[joint].name(),
                lower[joint],
                upper[joint],
                outcome.name()
            ));
            break;
        }
    }
    scenario.description = story;
    Ok(scenario)
}
