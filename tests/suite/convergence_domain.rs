//! The convergence-domain study on small seeded samples: the full method reaches its goal from the perturbed starts,
//! never does worse than the stack with projected gradient on the same draw, removes few tasks, and every run that
//! does not converge says why. Outcomes over draws, not numbers copied from a run.

use servostack::controller::EventKind;
use servostack::math::JointVector;
use servostack::scenario::{RobotSpec, RunKind, Scenario, Zoo};
use servostack::sim::SummaryOnly;
use servostack::study::{
    optional_families, standard_families, Family, MethodResult, Perturbation, Study, StudyError,
    StudyResult, POSE_TOLERANCE_DEG, POSE_TOLERANCE_M,
};
use std::path::Path;

fn scenario(name: &str) -> Scenario {
    let path = format!(
        "{}/assets/scenarios/{name}.toml",
        env!("CARGO_MANIFEST_DIR")
    );
    Scenario::from_file(Path::new(&path)).unwrap()
}

fn families(names: &[&str]) -> Vec<Family> {
    standard_families()
        .into_iter()
        .filter(|f| names.contains(&f.name.as_str()))
        .collect()
}

#[test]
fn full_method_converges_from_perturbed_starts_and_never_does_worse_than_stack_gradient() {
    let scenario = scenario("paper_afma6");
    let study = Study::new(&scenario, families(&["mild", "strong"]), 8, 5).unwrap();
    let result = study.run().unwrap();
    for family in &result.families {
        let full = family
            .methods
            .iter()
            .find(|m| m.method == RunKind::FullMethod)
            .unwrap();
        assert!(full.converged >= 7, "{}: {full:?}", family.family.name);
        assert!(
            full.median_removals <= 2.0,
            "{}: {full:?}",
            family.family.name
        );
        assert_eq!(family.full_method_worse_than_stack_gradient, 0);
        // The per-task median is the median over the draws of each run's most removals of one task.
        let full_index = family
            .methods
            .iter()
            .position(|m| m.method == RunKind::FullMethod)
            .unwrap();
        let mut most: Vec<f64> = family
            .draws
            .iter()
            .map(|d| d.methods[full_index].max_removals_of_a_task as f64)
            .collect();
        most.sort_by(f64::total_cmp);
        let middle = most.len() / 2;
        let expected = if most.len().is_multiple_of(2) {
            0.5 * (most[middle - 1] + most[middle])
        } else {
            most[middle]
        };
        assert_eq!(full.median_removals_of_a_task, expected);
        assert!(full.median_removals_of_a_task <= 2.0);
        for draw in &family.draws {
            for method in &draw.methods {
                // A run that spent its budget names its reason.
                if matches!(method.outcome, "stalled" | "max_iterations") {
                    assert!(method.reason.as_deref().is_some_and(|r| !r.is_empty()));
                }
            }
        }
    }
}

/// On the UR5e with a restricted elbow, starts perturbed or the goal moved: the full method converges in at least
/// as many draws as each of the laws it switches between, and covers the draws where the stack with gradient does.
#[test]
fn on_the_ur5e_the_full_method_covers_its_baselines() {
    let scenario = scenario("ur5e_limits");
    let study = Study::new(&scenario, families(&["strong", "goal_4cm"]), 8, 9).unwrap();
    let result = study.run().unwrap();
    for family in &result.families {
        let converged = |kind| {
            family
                .methods
                .iter()
                .find(|m| m.method == kind)
                .unwrap()
                .converged
        };
        let full = converged(RunKind::FullMethod);
        for baseline in [RunKind::Classical, RunKind::Stack, RunKind::StackGradient] {
            assert!(
                full >= converged(baseline),
                "{}: {baseline:?}",
                family.family.name
            );
        }
        assert_eq!(family.full_method_worse_than_stack_gradient, 0);
    }
}

/// D22: from starts drawn anywhere inside the limits the features also settle at poses far from the goal. Such runs
/// are `off_goal`, never `converged`: every converged run of every method ends within the goal tolerance, every
/// `off_goal` run beyond it, and the small sample holds both kinds (about half of the full method's settled runs on
/// the Afma6 end off the goal).
#[test]
fn runs_that_settle_away_from_the_goal_are_not_counted_as_converged() {
    let scenario = scenario("paper_afma6");
    let (tolerance_m, tolerance_deg) = (
        scenario.simulation.goal_tolerance_m,
        scenario.simulation.goal_tolerance_deg,
    );
    let study = Study::new(&scenario, families(&["uniform"]), 16, 2).unwrap();
    let result = study.run().unwrap();
    let (mut converged, mut off_goal) = (0, 0);
    for draw in &result.families[0].draws {
        for method in &draw.methods {
            let at_goal = method.camera_translation_error <= tolerance_m
                && method.camera_rotation_error_deg <= tolerance_deg;
            match method.outcome {
                "converged" => {
                    assert!(at_goal, "draw {}: {method:?}", draw.draw);
                    converged += 1;
                }
                "off_goal" => {
                    assert!(!at_goal, "draw {}: {method:?}", draw.draw);
                    // Far off, not a slow approach: a false equilibrium of the features.
                    assert!(method.camera_translation_error > 0.1, "{method:?}");
                    off_goal += 1;
                }
                _ => {}
            }
        }
    }
    assert!(
        converged > 0 && off_goal > 0,
        "{converged} converged, {off_goal} off the goal"
    );
}

/// The full method's outcome on each of `draws` draws of one family of a 6-joint scenario.
fn full_method_outcomes(
    scenario: &Scenario,
    family: &str,
    draws: usize,
    seed: u64,
) -> Vec<&'static str> {
    let study = Study::new(scenario, families(&[family]), draws, seed)
        .unwrap()
        .with_methods(&[RunKind::FullMethod]);
    let result = study.run().unwrap();
    result.families[0]
        .draws
        .iter()
        .map(|d| d.methods[0].outcome)
        .collect()
}

/// How many of `outcomes` are `outcome`.
fn count(outcomes: &[&str], outcome: &str) -> usize {
    outcomes.iter().filter(|&&o| o == outcome).count()
}

/// Draw by draw (same family, same seed), every draw that converges `without` a mechanism still converges `with` it.
fn assert_no_draw_lost(without: &[&str], with: &[&str], mechanism: &str) {
    assert_eq!(without.len(), with.len());
    for (draw, (a, b)) in without.iter().zip(with).enumerate() {
        assert!(
            *a != "converged" || *b == "converged",
            "draw {draw}: {a} without {mechanism}, {b} with it"
        );
    }
}

/// D23: on the Afma6 with the desired view turned by up to 10°, the paper's features settle off the goal in some
/// draws; with the image points in reserve (the default) the full method leaves those false equilibria and reaches
/// the goal, and no draw that converges without the reserve task is lost with it.
#[test]
fn the_reserve_task_leads_turned_views_off_their_false_equilibria() {
    let with_escape = scenario("paper_afma6");
    let mut without = with_escape.clone();
    without.controller.escape_error = f64::INFINITY;
    let outcomes = |scenario: &Scenario| full_method_outcomes(scenario, "view_10deg", 24, 4);
    let (with_escape, without) = (outcomes(&with_escape), outcomes(&without));
    let off_goal = count(&without, "off_goal");
    assert!(
        off_goal > 0,
        "the sample holds no false equilibrium: {without:?}"
    );
    let rescued = without
        .iter()
        .zip(&with_escape)
        .filter(|(&a, &b)| a == "off_goal" && b == "converged")
        .count();
    assert!(
        2 * rescued > off_goal,
        "{rescued} of {off_goal} rescued: {with_escape:?}"
    );
    assert_no_draw_lost(&without, &with_escape, "the reserve task");
}

/// D24: from starts anywhere inside the Afma6's limits the paper's fourth task often leads the camera towards a false
/// equilibrium next to a wrist limit, where D23's escape comes too late (the reserve's path from there meets the
/// limit). Escaping as soon as the complete stack drives the corners away from their goal converges in more draws: on
/// 200 draws, 21–28 more, and every draw a baseline wins where the late escape covers 70 % (with the lock of D26; four
/// times as many draws before it, when a run stopped at the limit).
#[test]
fn the_early_escape_keeps_uniform_starts_off_the_false_equilibria() {
    let early = scenario("paper_afma6");
    let mut late = early.clone();
    late.controller.escape_growth_rate = f64::INFINITY;
    let outcomes = |scenario: &Scenario| full_method_outcomes(scenario, "uniform", 32, 3);
    let (early, late) = (outcomes(&early), outcomes(&late));
    let only = |a: &[&str], b: &[&str]| {
        a.iter()
            .zip(b)
            .filter(|(x, y)| **x == "converged" && **y != "converged")
            .count()
    };
    let (won, lost) = (only(&early, &late), only(&late, &early));
    assert!(
        won >= 3 && won >= 3 * lost,
        "{won} draws converged only with the early escape, {lost} only without: {early:?}, {late:?}"
    );
}

/// D13 hold (an option since the lock of D26): from uniform starts on the square marker's Afma6 most failed runs of
/// the stack with gradient the fallback leaves end past a hard limit; holding instead keeps the robot inside its limits
/// in most of them, and costs at most a draw that converged without it (0–2 of 200 in the study).
#[test]
fn holding_keeps_failed_uniform_runs_inside_the_limits() {
    let mut held = scenario("square_marker_afma6");
    held.controller.hold_before_limit = true;
    // The hold alone: without the braking of D25 and the lock of D26, which keep every run inside the limits.
    held.controller.braking_rate = f64::INFINITY;
    held.controller.lock_band = 0.0;
    let mut crossing = held.clone();
    crossing.controller.hold_before_limit = false;
    let outcomes = |scenario: &Scenario| full_method_outcomes(scenario, "uniform", 32, 3);
    let (held, crossing) = (outcomes(&held), outcomes(&crossing));
    let (crossed_with, crossed_without) =
        (count(&held, "joint_limit"), count(&crossing, "joint_limit"));
    assert!(
        crossed_without >= 4 && 2 * crossed_with <= crossed_without,
        "past a limit: {crossed_with} with the hold, {crossed_without} without"
    );
    assert!(count(&held, "stalled") >= crossed_without - crossed_with);
    assert!(count(&held, "converged") + 1 >= count(&crossing, "converged"));
}

/// D26 lock: on the UR5e, braked at a limit (D25), a run stops there with the whole robot; sliding along it (the
/// default) lets the other joints go on, so more uniform starts converge, and none that converged without the lock is
/// lost. The restart of D29 is off in both: without the lock it restarts runs whose error stays flat, and wins some
/// late (draw 18 of this sample, after three restarts at 7 471 of 8 000 iterations, measured), which are not the lock's.
#[test]
fn sliding_along_the_limits_converges_from_more_uniform_starts() {
    let mut sliding = scenario("ur5e_limits");
    assert!(sliding.controller.lock_band > 0.0);
    sliding.controller.restart_rate = 0.0;
    let mut stopping = sliding.clone();
    stopping.controller.lock_band = 0.0;
    let outcomes = |scenario: &Scenario| full_method_outcomes(scenario, "uniform", 32, 3);
    let (sliding, stopping) = (outcomes(&sliding), outcomes(&stopping));
    assert!(
        count(&sliding, "converged") >= count(&stopping, "converged") + 3,
        "converged: {sliding:?} sliding, {stopping:?} stopping"
    );
    assert!(!sliding.contains(&"joint_limit"), "{sliding:?}");
    assert_no_draw_lost(&stopping, &sliding, "the lock");
}

/// D29 beside an unlimited joint (D18): `rail7` with its continuous roll left without limits. The runs that restart
/// drive their locked joints to their targets while the unlimited joint, which has no middle, is left where it is,
/// and the study runs to its end (the recentring term's entry for that joint was `0 · NaN`: the first restart stopped
/// the study with a non-finite velocity).
#[test]
fn a_restart_beside_an_unlimited_joint_keeps_the_velocity_finite() {
    let mut scenario = scenario("rail7_limits");
    let RobotSpec::Builtin {
        joint_limits: Some(limits),
        ..
    } = &mut scenario.robot
    else {
        panic!(
            "rail7_limits.toml gives its joint limits: {:?}",
            scenario.robot
        );
    };
    (limits.lower[4], limits.upper[4]) = (f64::NEG_INFINITY, f64::INFINITY);
    let study = Study::new(&scenario, families(&["uniform"]), 12, 61)
        .unwrap()
        .with_methods(&[RunKind::FullMethod]);
    let result = study.run().unwrap();
    let restarted = result.families[0]
        .draws
        .iter()
        .filter(|d| d.methods[0].restart_take_outs > 0)
        .count();
    assert!(
        restarted > 0,
        "no draw restarted: the test does not reach D29"
    );
}

/// D29 restart: from uniform starts on the square marker's Afma6, the sequence often comes to rest with the wrist
/// locked at its lower limit, short of the goal (a false equilibrium against the limit that sliding cannot leave).
/// Restarting the sequence there, with the locked joint recentred first (the default), converges from more
/// draws, and loses none that converged without it.
#[test]
fn restarting_from_rest_at_a_limit_converges_from_more_uniform_starts() {
    let scenario = scenario("square_marker_afma6");
    assert!(scenario.controller.restart_rate > 0.0);
    let mut without_restart = scenario.clone();
    without_restart.controller.restart_rate = 0.0;
    let outcomes = |scenario: &Scenario| full_method_outcomes(scenario, "uniform", 24, 3);
    let (restarting, without) = (outcomes(&scenario), outcomes(&without_restart));
    assert!(
        count(&restarting, "converged") >= count(&without, "converged") + 3,
        "converged: {restarting:?} restarting, {without:?} without"
    );
    assert_no_draw_lost(&without, &restarting, "the restart");
    // One of the draws only the restart brings to the goal, run again: every task but the first is taken out in
    // one change, which the transition of D1 keeps continuous, and the sequence is complete at the end.
    let study = Study::new(&scenario, families(&["uniform"]), 24, 3)
        .unwrap()
        .with_methods(&[RunKind::FullMethod]);
    let result = study.run().unwrap();
    let family = &result.families[0];
    let draws = &family.draws;
    // The study says when each run restarted, and how the wins' iterations spread against the budget.
    for draw in draws {
        let run = &draw.methods[0];
        assert_eq!(
            run.restart_iteration.is_some(),
            run.restart_take_outs > 0,
            "{run:?}"
        );
        assert!(run.restart_iteration.is_none_or(|at| at < run.iterations));
    }
    let mut wins: Vec<usize> = draws
        .iter()
        .filter(|d| d.methods[0].converged())
        .map(|d| d.methods[0].iterations)
        .collect();
    wins.sort_unstable();
    let summary = &family.methods[0];
    let p95 = summary.p95_iterations_to_converge.unwrap();
    assert_eq!(result.budget, scenario.simulation.max_iterations);
    assert!(wins.iter().filter(|&&w| w <= p95).count() * 20 >= wins.len() * 19);
    assert!(wins.iter().filter(|&&w| w < p95).count() * 20 < wins.len() * 19);
    assert!(summary.median_iterations_to_converge.unwrap() <= p95 as f64 && p95 <= result.budget);
    let rescued = draws
        .iter()
        .zip(&without)
        .find(|(d, without)| d.methods[0].outcome == "converged" && **without != "converged")
        .map(|(d, _)| d)
        .unwrap();
    let mut experiment = scenario.experiment::<6>().unwrap();
    experiment.start = JointVector::<6>::from_column_slice(&rescued.start);
    let run = experiment
        .run_with(&scenario.settings(), RunKind::FullMethod, &mut SummaryOnly)
        .unwrap();
    assert_eq!(run.outcome.name(), "converged");
    assert_eq!(run.iterations(), rescued.methods[0].iterations);
    let restarts: Vec<_> = run
        .event_continuity()
        .into_iter()
        .filter(|e| e.kind == EventKind::Restart)
        .collect();
    let taken_out: Vec<_> = restarts.iter().map(|e| e.task).collect();
    assert!(
        taken_out.len() == 3 && taken_out[..2] == [1, 2],
        "the angle, the area and the fourth task (or the points in its place) taken out: {taken_out:?}"
    );
    assert!(restarts
        .iter()
        .all(|e| e.iteration == restarts[0].iteration));
    assert_eq!(
        rescued.methods[0].restart_iteration,
        Some(restarts[0].iteration)
    );
    let restart = restarts.last().unwrap();
    assert!(
        restart.jump < 0.1 * restart.law_jump,
        "velocity step {} at the restart, law jump {}",
        restart.jump,
        restart.law_jump
    );
    assert_eq!(run.stacked_at_end().len(), 4);
}

/// The zoo's arm `name` with its generated scenario, when the zoo is installed (`SERVOSTACK_ZOO_DIR`, as `.ci/run` sets
/// it); otherwise `None`, after saying so.
pub(crate) fn zoo_scenario(name: &str) -> Option<Scenario> {
    let Some(dir) = std::env::var_os("SERVOSTACK_ZOO_DIR") else {
        eprintln!("SERVOSTACK_ZOO_DIR is not set (scripts/install_zoo.sh prints it): the zoo's {name} is not loaded");
        return None;
    };
    let zoo =
        Zoo::from_file(Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/zoo.toml")).unwrap();
    Some(Zoo::scenario(zoo.arm(name).unwrap(), Path::new(&dir)).unwrap())
}

/// D29 is made each time a run rests against a limit short of the goal, not once: on the zoo's UR3 (its generated
/// scenario, with the zoo installed) the replay after a first restart often rests again, at one pose with the shoulder
/// lift locked at the limit the generator set, and restarting from there converges. Some of its `feasible` draws
/// converge after two restarts or more (made once per run, none could). Without `SERVOSTACK_ZOO_DIR` the test says so
/// and checks nothing more.
#[test]
fn a_replay_that_rests_against_a_limit_again_restarts_again() {
    let Some(scenario) = zoo_scenario("ur3") else {
        return;
    };
    let study = Study::new(&scenario, optional_families(), 40, 75)
        .unwrap()
        .with_methods(&[RunKind::FullMethod]);
    let result = study.run().unwrap();
    let mut experiment = scenario.experiment::<6>().unwrap();
    let mut restarted_twice = 0;
    for draw in &result.families[0].draws {
        let method = &draw.methods[0];
        if !(method.converged() && method.restart_take_outs > 0) {
            continue;
        }
        experiment.start = JointVector::<6>::from_column_slice(&draw.start);
        let run = experiment
            .run_with(&scenario.settings(), RunKind::FullMethod, &mut SummaryOnly)
            .unwrap();
        assert_eq!(run.outcome.name(), "converged");
        let mut restarts: Vec<usize> = run
            .event_continuity()
            .into_iter()
            .filter(|e| e.kind == EventKind::Restart)
            .map(|e| e.iteration)
            .collect();
        restarts.dedup();
        if restarts.len() >= 2 {
            restarted_twice += 1;
        }
    }
    assert!(
        restarted_twice >= 3,
        "{restarted_twice} of 40 draws converged after two restarts or more"
    );
}

/// D29 without rest: on the zoo's Panda (uniform starts), runs that end at the budget with every task stacked and a joint
/// locked creep along the limit, never at rest, so the restart at rest never fires. With the restart also made once the
/// stacked tasks' error has stopped falling for `progress_window` (the default), some of them converge, each after a
/// restart, and no draw that converged without it is lost (measured at K = 40 on seeds 3, 5, 7: 9, 7 and 4 gained,
/// none lost). Without `SERVOSTACK_ZOO_DIR` the test says so and checks nothing more.
#[test]
fn a_run_that_creeps_along_a_limit_restarts_without_resting() {
    let Some(with_window) = zoo_scenario("panda") else {
        return;
    };
    assert!(with_window.controller.progress_window.is_finite());
    let mut at_rest_only = with_window.clone();
    at_rest_only.controller.progress_window = f64::INFINITY;
    let gained = uniform_draws_gained(&with_window, &at_rest_only, "the restart without rest");
    for (with, without) in &gained {
        assert!(with.restart_take_outs > 0, "{with:?}");
        assert_eq!(without.outcome, "max_iterations", "{without:?}");
    }
    assert!(
        gained.len() >= 4,
        "{} of 40 draws converged only with the restart without rest",
        gained.len()
    );
}

/// The full method's runs on 40 uniform draws of `scenario`, seed 5 (the zoo's tests of the controller's rules).
pub(crate) fn full_method_uniform(scenario: &Scenario) -> StudyResult {
    Study::new(scenario, families(&["uniform"]), 40, 5)
        .unwrap()
        .with_methods(&[RunKind::FullMethod])
        .run()
        .unwrap()
}

/// The full method's uniform runs on `with` and on `without` (a rule switched off), 40 draws of seed 5: asserts that
/// no draw converges without the rule only, and returns the results of the draws that converge with it only,
/// `(with, without)`.
fn uniform_draws_gained(
    with: &Scenario,
    without: &Scenario,
    rule: &str,
) -> Vec<(MethodResult, MethodResult)> {
    let (with, without) = (full_method_uniform(with), full_method_uniform(without));
    let mut gained = Vec::new();
    for (draw, other) in with.families[0]
        .draws
        .iter()
        .zip(&without.families[0].draws)
    {
        let (with, without) = (&draw.methods[0], &other.methods[0]);
        assert!(
            with.converged() || !without.converged(),
            "draw {}: converged only without {rule}: {without:?}, {with:?}",
            draw.draw
        );
        if with.converged() && !without.converged() {
            gained.push((with.clone(), without.clone()));
        }
    }
    gained
}

/// D29, a repeated restart: on the Kinova, whose base joint the generator restricts to a narrow range, the restart
/// that recentres the locked joint alone replays into the same rest, restart after restart, until the budget ends.
/// Recentring every limited joint once the same locks come back converges in draws the locked joint alone does not
/// (6 of 40 on this seed, 8 on seed 6, measured), and loses none. Without `SERVOSTACK_ZOO_DIR` the test says so
/// and checks nothing more.
#[test]
fn a_restart_that_finds_the_same_locks_again_recentres_every_joint() {
    let Some(every_joint) = zoo_scenario("kinova") else {
        return;
    };
    assert!(every_joint.controller.recentre_all_on_repeat);
    let mut locked_only = every_joint.clone();
    locked_only.controller.recentre_all_on_repeat = false;
    let gained = uniform_draws_gained(
        &every_joint,
        &locked_only,
        "recentring every joint at a repeat",
    );
    for (_, without) in &gained {
        // Restarted at least twice (two take-outs of each task but the first, of the 4 in the sequence).
        assert!(without.restart_take_outs >= 6, "{without:?}");
    }
    assert!(
        gained.len() >= 4,
        "{} of 40 draws converged only recentring every joint at a repeated restart",
        gained.len()
    );
}

/// D29's goal test: on the zoo's Tiago, runs came to rest 1 cm from the goal pose with a joint locked, the reserve
/// task's corners within `ε_escape` of their goal but a stacked task not achieved, and stayed there until the budget
/// ended without a restart (4 of these 40 draws, measured before the test counted the stacked tasks). On the Kinova
/// and the Tiago Pro, runs stalled near the goal with a stacked error flat between the convergence threshold and
/// `ε_achieved` (2 and 1 of these draws, measured before a flat error was judged against the convergence threshold).
/// No run of the full method ends its budget within 5 cm of the goal without having restarted.
#[test]
fn a_run_resting_near_the_goal_against_a_limit_restarts() {
    for arm in ["tiago", "tiago_pro", "kinova"] {
        let Some(scenario) = zoo_scenario(arm) else {
            return;
        };
        for draw in &full_method_uniform(&scenario).families[0].draws {
            let run = &draw.methods[0];
            assert!(
                run.converged()
                    || run.restart_take_outs > 0
                    || run.outcome != "max_iterations"
                    || run.camera_translation_error > 0.05,
                "{arm}, draw {}: {run:?}",
                draw.draw
            );
        }
    }
}

/// D29's goal test at rest: near the goal the law's velocity is proportional to the error, so a run still converging
/// there is at rest by the paper's `ε_add`. At rest, the goal counts as missed only above `ε_achieved`; judged against
/// the convergence threshold instead, a restart took a converging UR3 run (of these 40 draws) away from its goal
/// (measured). The restart takes no draw that converges without it, and gains some (9 measured).
#[test]
fn the_restart_takes_no_run_that_converges_without_it() {
    let Some(with_restart) = zoo_scenario("ur3") else {
        return;
    };
    let mut without = with_restart.clone();
    without.controller.restart_rate = 0.0;
    let gained = uniform_draws_gained(&with_restart, &without, "the restart");
    assert!(
        gained.len() >= 4,
        "{} of 40 draws converged only with the restart",
        gained.len()
    );
}

/// D25 at the border of the image: on the zoo's Kinova, runs lost the target while the camera, moving at the joints'
/// velocity limits, approached it (the image spread out of the frame faster than the visibility cost's band could
/// act). Braked before the border (the default), 6 of these 40 draws converge that were lost (measured), none is lost.
#[test]
fn braking_before_the_image_border_keeps_the_target_in_view() {
    let Some(braked) = zoo_scenario("kinova") else {
        return;
    };
    assert!(braked.controller.brake_at_image_border);
    let mut unbraked = braked.clone();
    unbraked.controller.brake_at_image_border = false;
    let gained = uniform_draws_gained(&braked, &unbraked, "the braking at the image border");
    for (_, without) in &gained {
        assert_eq!(without.outcome, "feature_lost", "{without:?}");
    }
    assert!(
        gained.len() >= 4,
        "{} of 40 draws converged only braked at the image border",
        gained.len()
    );
}

/// D25 braking: on the UR5e, whose elbow is fast for its 0.55 rad range, a third of the full method's uniform runs
/// reach a hard limit before the changes decided from predictions (removals, fallback, hold) take effect. Braked as
/// it nears a limit (the default), no run crosses one, and none that converged unbraked is lost.
#[test]
fn braking_keeps_every_uniform_run_inside_the_limits() {
    let braked = scenario("ur5e_limits");
    assert!(braked.controller.braking_rate.is_finite());
    let mut unbraked = braked.clone();
    unbraked.controller.braking_rate = f64::INFINITY;
    let outcomes = |scenario: &Scenario| full_method_outcomes(scenario, "uniform", 32, 3);
    let (braked, unbraked) = (outcomes(&braked), outcomes(&unbraked));
    let crossed_without = count(&unbraked, "joint_limit");
    assert!(
        crossed_without >= 3,
        "the sample holds too few crossings to say anything: {unbraked:?}"
    );
    assert!(
        !braked.contains(&"joint_limit"),
        "past a limit with the braking: {braked:?}"
    );
    assert_no_draw_lost(&unbraked, &braked, "the braking");
}

/// The same seed gives the same draws and outcomes (whatever thread runs a draw); another seed other draws.
#[test]
fn a_study_is_reproducible_from_its_seed() {
    let scenario = scenario("paper_afma6");
    let run = |seed| {
        Study::new(&scenario, families(&["mild"]), 3, seed)
            .unwrap()
            .with_methods(&[RunKind::Classical])
            .run()
            .unwrap()
    };
    let (a, b, c) = (run(3), run(3), run(4));
    assert_eq!(a.families[0].draws, b.families[0].draws);
    assert_ne!(a.families[0].draws[0].start, c.families[0].draws[0].start);
    // A mild draw moves every joint of the start by at most 2 cm or 3°.
    let start = &scenario.start.joints;
    for draw in &a.families[0].draws {
        for (k, (drawn, nominal)) in draw.start.iter().zip(start).enumerate() {
            let half = if k < 3 { 0.02 } else { 3f64.to_radians() };
            assert!((drawn - nominal).abs() <= half + 1e-12, "joint {k}");
        }
    }
}

/// A slice of starts: every cell is run, and a start below the lower limit of joint 2 is reported invalid.
#[test]
fn a_slice_marks_invalid_starts_and_runs_the_others() {
    let scenario = scenario("paper_afma6");
    let study = Study::new(&scenario, Vec::new(), 1, 1)
        .unwrap()
        .with_methods(&[RunKind::Classical, RunKind::FullMethod]);
    let slice = study.slice((0, 2), (0.02, 0.04), 3).unwrap();
    let lower = -0.5001; // joint 2's lower limit (the Afma6 built-in)
    for (method, outcomes) in &slice.methods {
        assert_eq!(outcomes.len(), 9, "{method:?}");
        for (k, outcome) in outcomes.iter().enumerate() {
            let q2 = slice.y_values[k / 3];
            assert_eq!(
                *outcome == "invalid",
                q2 < lower,
                "{method:?} cell {k} (q2 = {q2})"
            );
        }
    }
}

#[test]
fn invalid_study_parameters_are_named() {
    let scenario = scenario("paper_afma6");
    assert!(matches!(
        Study::new(&scenario, standard_families(), 0, 1),
        Err(StudyError::InvalidParameter { name: "draws", .. })
    ));
    let negative = Family::new(
        "bad",
        Perturbation::Start {
            translation_m: -0.01,
            rotation_deg: 1.0,
        },
    );
    assert!(matches!(
        Study::new(&scenario, vec![negative], 1, 1),
        Err(StudyError::InvalidParameter {
            name: "translation_m",
            ..
        })
    ));
    let study = Study::new(&scenario, families(&["mild"]), 1, 1).unwrap();
    assert!(matches!(
        study.situation::<6>("nowhere", 0),
        Err(StudyError::UnknownFamily { name }) if name == "nowhere"
    ));
    assert!(matches!(
        study.slice((0, 6), (0.01, 0.01), 3),
        Err(StudyError::InvalidParameter {
            name: "slice joints",
            ..
        })
    ));
    assert!(matches!(
        study.slice((0, 1), (f64::NAN, 0.01), 3),
        Err(StudyError::InvalidParameter {
            name: "slice half-width",
            ..
        })
    ));
}

/// D7 anti-cycling: on the 7-joint chain, where `a_n` and the third-order task block each other in turn, a swap is
/// never undone by the next one, so tasks are not traded back and forth until their removal budgets run out: the
/// median run removes at most two tasks, no task is removed more than twice, and every draw still converges. With the
/// paper's settling threshold for the pushes (the full method's earlier pushes avoid most of these conflicts, and the
/// test would not see the rule at work): without the rule the median run removes five tasks.
#[test]
fn on_the_seven_joint_chain_swaps_do_not_cycle() {
    let mut scenario = scenario("rail7_limits");
    scenario.controller.settle_velocity_with_removal = scenario.controller.settle_velocity;
    let study = Study::new(&scenario, families(&["mild", "view_10deg"]), 20, 3)
        .unwrap()
        .with_methods(&[RunKind::FullMethod]);
    let result = study.run().unwrap();
    for family in &result.families {
        let full = &family.methods[0];
        assert_eq!(
            full.converged, full.draws,
            "{}: {full:?}",
            family.family.name
        );
        assert!(
            full.median_removals <= 2.0 && full.max_removals_of_a_task <= 2,
            "{}: {full:?}",
            family.family.name
        );
    }
}

/// The noise family of the study on `paper_afma6_pixel_noise.toml`: ±2 px of pixel noise and a 5 % intrinsics error
/// (the example's `--noise 2 --calib 0.05`). With the scenario's filter, side ratios, gain of 0.03 s⁻¹ at the goal and
/// convergence held for 45 s, the full method settles in every mild draw, within 5 mm / 0.5° of the goal pose, and
/// all but at most one of twelve draws end within the 2 mm / 0.2° aimed at. With the earlier gain of 0.1 s⁻¹ held 5 s
/// about 70 % of the draws did, and eleven of twelve would be a 9 % chance.
#[test]
fn under_pixel_noise_the_full_method_settles_within_two_millimetres() {
    let mut scenario = scenario("paper_afma6_pixel_noise");
    scenario.measurement.pixel_noise_uniform_px = 2.0;
    scenario.measurement.intrinsics_error_fraction = 0.05;
    let study = Study::new(&scenario, families(&["mild"]), 12, 21)
        .unwrap()
        .with_methods(&[RunKind::FullMethod]);
    let mut within_aim = 0;
    for draw in &study.run().unwrap().families[0].draws {
        let full = &draw.methods[0];
        assert!(full.converged(), "draw {}: {full:?}", draw.draw);
        assert!(
            full.camera_translation_error < 5e-3 && full.camera_rotation_error_deg < 0.5,
            "draw {}: {full:?}",
            draw.draw
        );
        if full.camera_translation_error <= POSE_TOLERANCE_M
            && full.camera_rotation_error_deg <= POSE_TOLERANCE_DEG
        {
            within_aim += 1;
        }
    }
    assert!(within_aim >= 11, "{within_aim} of 12 within 2 mm / 0.2°");
}

/// D27: with the target's incidence bounded (80°), runs from uniform starts on the UR5e lose the target by obliquity on
/// the way; the full method's visibility cost rising from 65° (the default facing margin) keeps it facing the camera,
/// so more draws converge and fewer end `image_degenerate` than with the term only at the bound (margin 0). On 32
/// draws, seeds 3–6: 21 / 25 / 28 / 28 converged against 18 / 23 / 21 / 25, and 7 / 3 / 2 / 4 lost by obliquity
/// against 10 / 7 / 9 / 6.
#[test]
fn keeping_the_target_facing_converges_from_more_uniform_starts() {
    let facing = scenario("ur5e_limits");
    assert!(facing.simulation.facing_margin_deg > 0.0);
    let mut at_the_bound = facing.clone();
    at_the_bound.simulation.facing_margin_deg = 0.0;
    let outcomes = |scenario: &Scenario| full_method_outcomes(scenario, "uniform", 32, 3);
    let (facing, at_the_bound) = (outcomes(&facing), outcomes(&at_the_bound));
    assert!(
        count(&facing, "converged") >= count(&at_the_bound, "converged") + 2,
        "converged: {facing:?} facing, {at_the_bound:?} at the bound"
    );
    assert!(count(&facing, "image_degenerate") < count(&at_the_bound, "image_degenerate"));
}
