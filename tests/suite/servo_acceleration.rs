//! Acceleration limits in the façade ([`ServoConfig::max_joint_acceleration`], theory D31): the change of the velocity
//! sent stays within `a_i Δt` through whole closed-loop runs (pushes, removals, re-insertions, bad frames), the
//! continuity of the stack changes holds for what was sent, the braking keeps a stop within reach of the limited
//! deceleration, and the runs still converge.

use crate::counting_allocator::allocations_during;
use crate::servo::{
    assert_fed_back_at_change, distorted_camera, paper, paper_config, Plant, RaisedWristLimit,
};
use proptest::prelude::*;
use servostack::avoidance::braking_speed;
use servostack::controller::{ControllerParameters, EventKind};
use servostack::math::JointVector;
use servostack::servo::{ServoConfig, ServoError, ServoMethod, ServoOutput, VisualServo};

const PERIOD: f64 = 0.01;

/// m/s² for the Afma6's three prismatic joints, rad/s² for its three revolute joints: low enough to be active on the
/// paper's run at 100 Hz.
fn tight_acceleration() -> JointVector<6> {
    JointVector::from([0.02, 0.02, 0.02, 0.1, 0.1, 0.1])
}

/// Near an industrial arm's: 1 m/s² on the gantry's axes, 3 rad/s² on the wrist.
fn industrial_acceleration() -> JointVector<6> {
    JointVector::from([1.0, 1.0, 1.0, 3.0, 3.0, 3.0])
}

/// Checks one accepted period: every `|v_i − v_prev_i| ≤ a_i Δt (1 + 1e−12)`; returns the largest ratio
/// `|Δv_i| / (a_i Δt)` (0 when `Δt = 0` and nothing changed).
fn check_step(
    previous: &JointVector<6>,
    output: &ServoOutput<6>,
    limits: &JointVector<6>,
    dt: f64,
) -> f64 {
    let mut largest: f64 = 0.0;
    for i in 0..6 {
        let change = (output.velocity[i] - previous[i]).abs();
        let allowed = limits[i] * dt;
        assert!(
            change <= allowed * (1.0 + 1e-12),
            "period {}: joint {i} changed by {change} > {allowed} (a = {}, Δt = {dt}): {output:?}, previous {previous:?}",
            output.iteration,
            limits[i]
        );
        if change > 0.0 {
            largest = largest.max(change / allowed);
        }
    }
    largest
}

/// The paper scenario with its removal (the paper's settling threshold, as in the servo tests), acceleration limits,
/// and a bad frame (a lost corner) every 37 periods during which the robot holds the last velocity sent: every
/// accepted period changes the velocity by at most `a_i Δt` from the last velocity *sent*, `Δt` since the last
/// accepted period (two periods after a bad frame); the bad frame leaves the servo's output as it was; the run removes
/// a task, puts it back, and converges at the goal.
#[test]
fn acceleration_limits_hold_through_pushes_removals_and_bad_frames() {
    let (scenario, experiment) = paper();
    let camera = distorted_camera(&experiment.scene);
    let mut config = paper_config(&scenario, &experiment, camera);
    config.controller.settle_velocity_with_removal = config.controller.settle_velocity;
    let limits = JointVector::from([0.05, 0.05, 0.05, 0.3, 0.3, 0.3]);
    config.max_joint_acceleration = limits;
    // The longest hold: a bad frame, held, doubles the period.
    config.control_period_s = Some(2.0 * PERIOD);
    let mut servo = VisualServo::new(config).unwrap();
    let mut plant = Plant::new(experiment.scene.clone(), camera, experiment.start, PERIOD);
    let (mut sent, mut last_time): (JointVector<6>, Option<f64>) = (JointVector::zeros(), None);
    let (mut limited, mut bad_frames, mut after_bad, mut largest) = (0, 0, 0, 0.0_f64);
    let mut converged = false;
    let mut previous_bad = false;
    for k in 0..20_000 {
        let time = plant.time();
        if k % 37 == 36 {
            let before = *servo.last_output();
            let mut corners = plant.pixels();
            corners[1] = None;
            let error = servo.step(time, &corners, &plant.q).unwrap_err();
            assert_eq!(error, ServoError::MissingCorner { index: 1 });
            assert_eq!(
                *servo.last_output(),
                before,
                "a bad frame changed the output"
            );
            bad_frames += 1;
            previous_bad = true;
            plant.apply(&sent); // the driver holds the last velocity
            continue;
        }
        let pixels = plant.pixels();
        let output = *servo.step(time, &pixels, &plant.q).unwrap();
        let dt = last_time.map_or(0.0, |t| time - t);
        largest = largest.max(check_step(&sent, &output, &limits, dt));
        limited += usize::from(output.acceleration_scale < 1.0);
        after_bad += usize::from(previous_bad && output.acceleration_scale < 1.0);
        previous_bad = false;
        sent = output.velocity;
        last_time = Some(time);
        if output.converged {
            converged = true;
            break;
        }
        plant.apply(&sent);
        assert!(experiment.scene.limits().violated_joint(&plant.q).is_none());
    }
    eprintln!(
        "limited at {limited} periods ({after_bad} right after a bad frame), largest change {largest} of a_i Δt"
    );
    assert!(converged, "not converged: {:?}", servo.last_output());
    let (mm, deg) = plant.pose_error(&experiment.desired_joints);
    assert!(mm < 1.0 && deg < 0.05, "pose error {mm} mm, {deg}°");
    let events = servo.controller().events();
    let removed = events.iter().any(|e| e.kind == EventKind::Remove);
    let back = events
        .iter()
        .any(|e| matches!(e.kind, EventKind::Reinsert | EventKind::Fallback));
    assert!(removed && back, "{events:?}");
    assert!(bad_frames > 10, "{bad_frames} bad frames");
    assert!(
        limited > 100 && after_bad > 0,
        "the limits were active at {limited} periods, {after_bad} right after a bad frame"
    );
    // Some period used its whole allowance: the check above is not vacuous.
    assert!(largest > 0.999, "largest change {largest} of the allowance");
}

/// The continuity identity of D1 for what was sent, with the acceleration limits active: a push at every transition
/// (`ε_add` out of reach); at each stack change the controller's velocity is the velocity sent at the period before
/// (`q̇(τ⁺) = q̇_sent(τ⁻)`), although that one was held back by the acceleration limits and differs from the
/// controller's own.
#[test]
fn the_continuity_identity_holds_for_the_acceleration_limited_velocity() {
    let (scenario, experiment) = paper();
    let camera = distorted_camera(&experiment.scene);
    let mut config = paper_config(&scenario, &experiment, camera);
    config.max_joint_acceleration = tight_acceleration() * 0.5;
    config.controller = ControllerParameters {
        settle_velocity: 1e3,
        settle_velocity_with_removal: 1e3,
        ..scenario.controller
    };
    let mut servo = VisualServo::new(config).unwrap();
    let mut plant = Plant::new(experiment.scene.clone(), camera, experiment.start, PERIOD);
    let mut outputs: Vec<ServoOutput<6>> = Vec::new();
    for _ in 0..600 {
        let pixels = plant.pixels();
        let output = *servo.step(plant.time(), &pixels, &plant.q).unwrap();
        plant.apply(&output.velocity);
        outputs.push(output);
    }
    let mut changes = 0;
    let mut limited_changes = 0;
    for w in outputs.windows(2) {
        let (before, at) = (&w[0], &w[1]);
        if at.event.is_none() {
            continue;
        }
        changes += 1;
        let held_back = (before.velocity - before.unscaled_velocity).norm();
        if before.acceleration_scale < 1.0 && held_back > 1e-6 {
            limited_changes += 1;
        }
        assert_fed_back_at_change(before, at);
    }
    assert!(changes >= 3, "{changes} stack changes");
    assert!(
        limited_changes >= 2,
        "only {limited_changes} changes while the acceleration limits held the velocity back"
    );
}

/// The braking under acceleration limits (D31): the classical task drives the last wrist joint into a raised limit.
/// With acceleration limits, every joint still keeps `|q̇_i| ≤ ξ d_i` (D25), no limit is crossed, and the velocity
/// never changes by more than `a_i Δt`: the stopping distance keeps the braking feasible. The braking acts (the
/// velocity is scaled), and the lock (D26) still slides.
#[test]
fn the_braking_stays_within_the_acceleration_limits() {
    let setup = RaisedWristLimit::new();
    for limits in [
        JointVector::from([0.05, 0.05, 0.05, 0.3, 0.3, 0.3]),
        JointVector::from([1.0, 1.0, 1.0, 0.3, 0.3, 0.05]),
        JointVector::repeat(0.02),
    ] {
        let mut config = setup.config.clone();
        config.max_joint_acceleration = limits;
        let (mut sent, mut first) = (JointVector::<6>::zeros(), true);
        let (mut braked, mut locked, mut clamped, mut largest) = (0, 0, 0, 0.0_f64);
        let (crossed, _) = setup.run(config, &mut |_, output, q, _| {
            let dt = if first { 0.0 } else { PERIOD };
            first = false;
            largest = largest.max(check_step(&sent, output, &limits, dt));
            clamped += usize::from(output.stopping_clamp);
            setup.assert_braked(output, q);
            braked += usize::from(output.scaled);
            locked += usize::from(output.locked[5]);
            sent = output.velocity;
        });
        assert!(!crossed, "{limits:?}: a limit was crossed");
        assert!(braked > 10, "{limits:?}: braked at {braked} periods only");
        assert!(locked > 10, "{limits:?}: locked at {locked} periods only");
        assert!(largest > 0.999, "{limits:?}: largest change {largest}");
        eprintln!("{limits:?}: braked {braked}, locked {locked}, clamped alone {clamped} periods");
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]
    /// `braking_speed` is invariant under the limited deceleration: from any speed within `B(d)` held for a period,
    /// the speed `aΔt` lower is within `B` at the new distance, and the distance never becomes negative. Driven as
    /// hard as allowed (accelerating towards the limit by `aΔt` while `B` allows it, else at `B`), a joint needs at
    /// most `aΔt` of deceleration per period, all the way to rest at the limit.
    #[test]
    fn the_braking_speed_keeps_a_stop_within_reach(
        rate in 0.5..50.0f64,
        deceleration in 0.01..50.0f64,
        period_fraction in 0.001..=1.0f64,
        distance in 0.0..3.0f64,
        start in 0.0..=1.0f64,
    ) {
        let period = period_fraction / rate; // ξ Δt ≤ 1
        let (a, h) = (deceleration, deceleration * period);
        let mut d = distance;
        let mut v = start * braking_speed(d, rate, a, period);
        for _ in 0..5000 {
            d -= v * period;
            prop_assert!(d >= -1e-15, "crossed: d = {d}");
            let bound = braking_speed(d, rate, a, period);
            prop_assert!(v - bound <= h * (1.0 + 1e-9) + 1e-15 * v, "v {v} > B {bound} + aΔt {h}");
            v = bound.min(v + h);
        }
    }
}

/// `braking_speed` against its closed forms: `ξ d` with no acceleration limit or close to the limit (`ξ² d ≤ a`);
/// beyond, as `Δt → 0`, `√(2 a d − a²/ξ²)`, the speed from which slowing at `a` to `a/ξ`, then approaching
/// exponentially at the rate `ξ`, stops at the limit; at `ξ = +∞` (no braking) the stopping speed of a held velocity
/// alone, and no bound without an acceleration limit either.
#[test]
fn the_braking_speed_matches_its_closed_forms() {
    let (rate, a) = (5.0, 2.0);
    assert_eq!(braking_speed(0.3, rate, f64::INFINITY, 0.01), 1.5);
    assert_eq!(
        braking_speed(0.3, f64::INFINITY, f64::INFINITY, 0.01),
        f64::INFINITY
    );
    // No braking (SNS, the QP cascade) but a limited deceleration: the stopping speed of a held velocity alone. From
    // 0.3 with aΔt = 0.02: 54 whole decrements fit (0.02 · 0.01 · 54 · 55 / 2 = 0.297 ≤ 0.3 < 0.308), so
    // V = 0.3 / (55 · 0.01) + 54 · 0.02 / 2, a little under √(2 a d) = √1.2.
    let stopping = braking_speed(0.3, f64::INFINITY, a, 0.01);
    assert!((stopping - (0.3 / 0.55 + 0.54)).abs() < 1e-12, "{stopping}");
    assert!(stopping < 1.2f64.sqrt() && stopping > 1.2f64.sqrt() - a * 0.01);
    assert_eq!(braking_speed(-0.1, rate, a, 0.01), 0.0);
    assert_eq!(braking_speed(0.05, rate, a, 0.01), 0.25); // ξ² d = 1.25 ≤ 2
    for d in [0.1, 0.2, 0.5, 1.0, 3.0] {
        let expected = (2.0 * a * d - a * a / (rate * rate)).sqrt();
        let continuous = braking_speed(d, rate, a, 0.0);
        assert!(
            (continuous - expected).abs() <= 1e-12 * expected,
            "d = {d}: {continuous} vs {expected}"
        );
        // A finite period asks for a little more room (the speed is held for a period before it can change).
        let discrete = braking_speed(d, rate, a, 0.01);
        assert!(discrete < continuous && discrete > 0.95 * continuous);
    }
}

/// Limits near an industrial arm's (1 m/s², 3 rad/s²) with each method: SNS and the QP cascade get them in their box,
/// and the façade's own limit on top; the change of the velocity sent stays within `a_i Δt` on the paper scenario,
/// which still converges at the goal.
#[test]
fn the_boxed_laws_take_the_acceleration_limits() {
    let (scenario, experiment) = paper();
    let camera = distorted_camera(&experiment.scene);
    let limits = industrial_acceleration();
    for method in [
        ServoMethod::FullMethod,
        ServoMethod::SaturationInNullSpace,
        ServoMethod::HierarchicalQp,
    ] {
        let mut config = paper_config(&scenario, &experiment, camera);
        config.method = method;
        config.control_period_s = Some(PERIOD);
        config.max_joint_acceleration = limits;
        let mut servo = VisualServo::new(config).unwrap();
        let mut plant = Plant::new(experiment.scene.clone(), camera, experiment.start, PERIOD);
        let mut sent = JointVector::<6>::zeros();
        let mut converged = false;
        for k in 0..20_000 {
            let pixels = plant.pixels();
            let output = *servo.step(plant.time(), &pixels, &plant.q).unwrap();
            check_step(&sent, &output, &limits, if k == 0 { 0.0 } else { PERIOD });
            sent = output.velocity;
            if output.converged {
                converged = true;
                break;
            }
            plant.apply(&sent);
        }
        assert!(converged, "{method:?}: {:?}", servo.last_output());
        let (mm, deg) = plant.pose_error(&experiment.desired_joints);
        assert!(
            mm < 1.0 && deg < 0.05,
            "{method:?}: pose error {mm} mm, {deg}°"
        );
    }
}

/// The knob is validated: NaN, zero and negative limits are named errors; `+∞` (no limit) is accepted. A period with
/// the limits active allocates nothing.
#[test]
fn invalid_acceleration_limits_are_named_errors_and_limited_periods_allocate_nothing() {
    let (scenario, experiment) = paper();
    let camera = distorted_camera(&experiment.scene);
    let base: ServoConfig<6> = paper_config(&scenario, &experiment, camera);
    for value in [f64::NAN, 0.0, -1.0, f64::NEG_INFINITY] {
        let mut config = base.clone();
        config.max_joint_acceleration[2] = value;
        let error = VisualServo::new(config).unwrap_err();
        assert!(
            matches!(
                error,
                ServoError::InvalidParameter {
                    name: "max_joint_acceleration",
                    ..
                }
            ),
            "{value}: {error}"
        );
    }
    let mut config = base;
    config.max_joint_acceleration = tight_acceleration();
    config.max_joint_acceleration[0] = f64::INFINITY;
    let mut servo = VisualServo::new(config).unwrap();
    let mut plant = Plant::new(experiment.scene.clone(), camera, experiment.start, PERIOD);
    let step = |servo: &mut VisualServo<6>, plant: &mut Plant| {
        let pixels = plant.pixels();
        let output = *servo.step(plant.time(), &pixels, &plant.q).unwrap();
        plant.apply(&output.velocity);
        output
    };
    for _ in 0..50 {
        step(&mut servo, &mut plant);
    }
    let mut limited = 0;
    let allocations = allocations_during(|| {
        for _ in 0..300 {
            limited += usize::from(step(&mut servo, &mut plant).acceleration_scale < 1.0);
        }
    });
    assert_eq!(allocations, 0);
    assert!(limited > 0, "the limits were never active");
}
