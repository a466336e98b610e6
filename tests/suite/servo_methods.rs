//! Saturation in the null space and the QP cascade through the façade ([`ServoMethod`]), with the paper's sequence
//! and with the whole stack at once ([`TaskSequencing::AllAtOnce`]).

use crate::servo::{distorted_camera, paper, paper_config, run_loop, Plant, RaisedWristLimit};
use servostack::controller::{EventKind, TaskSequencing};
use servostack::servo::{ServoMethod, VisualServo};

const PERIOD: f64 = 0.01;
const BOXED: [ServoMethod; 2] = [
    ServoMethod::SaturationInNullSpace,
    ServoMethod::HierarchicalQp,
];

/// The classical task drives the last wrist joint into a raised limit (the braking test shows it crosses it without
/// a rule). With SNS or the QP cascade in the façade, every velocity sent keeps `q + q̇ Δt` inside the limits (with
/// the façade's braking and lock off) and no limit is crossed. The two then differ as theory §14 says: the cascade
/// gives up the task's direction and goes on reducing its error with the five other joints, well below where the
/// braking alone stops the robot (as the lock does, D26); SNS keeps the direction and scales it down, and a six-row
/// task with a joint saturated has no direction left to keep: it stops where the braking does.
#[test]
fn the_boxed_laws_keep_every_joint_inside_its_limits_through_the_facade() {
    let setup = RaisedWristLimit::new();
    let (lower, upper) = (*setup.limits.lower(), *setup.limits.upper());
    let mut braked_only = setup.config.clone();
    braked_only.controller.lock_band = 0.0;
    let (crossed, stopped) = setup.run(braked_only, &mut |_, _, _, _| {});
    assert!(!crossed);
    for method in BOXED {
        let mut config = setup.config.clone();
        config.method = method;
        config.control_period_s = Some(PERIOD);
        let mut pinned = 0;
        let (crossed, last) = setup.run(config, &mut |_, output, q, _| {
            for i in 0..6 {
                let next = q[i] + output.velocity[i] * PERIOD;
                assert!(
                    lower[i] <= next && next <= upper[i],
                    "{method:?}: joint {i} sent to {next} outside [{}, {}]",
                    lower[i],
                    upper[i]
                );
            }
            pinned += usize::from(q[5] - lower[5] < 1e-3);
            assert!(output.locked.iter().all(|l| !l), "the lock is off");
        });
        assert!(!crossed, "{method:?}: a limit was crossed");
        assert!(
            pinned > 100,
            "{method:?}: at the raised limit {pinned} periods only"
        );
        let (error, stopped) = (last.error_norm, stopped.error_norm);
        match method {
            ServoMethod::HierarchicalQp => assert!(
                error < 0.5 * stopped,
                "QP cascade: error {error}, {stopped} stopped by the braking"
            ),
            _ => assert!(
                (error - stopped).abs() < 0.05 * stopped,
                "SNS: error {error}, {stopped} stopped by the braking"
            ),
        }
    }
}

/// On the paper scenario (distorted camera), each boxed law reaches the goal pose, with the tasks pushed in sequence
/// or all at the first period; all at once, every task of the sequence is stacked by the first output, each push
/// logged at iteration 0.
#[test]
fn the_boxed_laws_reach_the_paper_goal_in_sequence_and_all_at_once() {
    let (scenario, experiment) = paper();
    let camera = distorted_camera(&experiment.scene);
    for method in BOXED {
        for sequencing in [TaskSequencing::OneByOne, TaskSequencing::AllAtOnce] {
            let mut config = paper_config(&scenario, &experiment, camera);
            config.method = method;
            config.control_period_s = Some(PERIOD);
            config.controller.sequencing = sequencing;
            let mut servo = VisualServo::new(config).unwrap();
            let mut plant = Plant::new(experiment.scene.clone(), camera, experiment.start, PERIOD);
            let outputs = run_loop(&mut servo, &mut plant, 20_000, |output, _| {
                assert!(output.velocity.iter().all(|v| v.is_finite()));
            });
            let expected_first = match sequencing {
                TaskSequencing::OneByOne => 1,
                TaskSequencing::AllAtOnce => 4,
            };
            assert_eq!(
                outputs[0].stack_len, expected_first,
                "{method:?} {sequencing:?}"
            );
            let pushes_at_start = servo
                .controller()
                .events()
                .iter()
                .filter(|e| e.iteration == 0 && e.kind == EventKind::Push)
                .count();
            assert_eq!(pushes_at_start, expected_first, "{method:?} {sequencing:?}");
            assert!(
                servo
                    .controller()
                    .events()
                    .iter()
                    .all(|e| e.kind == EventKind::Push),
                "{method:?} {sequencing:?}: a boxed law removes nothing"
            );
            let last = outputs.last().unwrap();
            assert!(
                last.converged,
                "{method:?} {sequencing:?}: not converged: {last:?}"
            );
            assert_eq!(last.stacked(), &[0, 1, 2, 3], "no reserve task");
            let (mm, deg) = plant.pose_error(&experiment.desired_joints);
            assert!(
                mm < 1.0 && deg < 0.05,
                "{method:?} {sequencing:?}: pose error {mm} mm, {deg}°"
            );
        }
    }
}
