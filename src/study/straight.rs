//! The straight-feasible test: a denominator of the study that no method defines (issue 43). "The draws a baseline
//! wins" depends on the baselines; a draw is *straight-feasible* when the straight joint-space path from its start to
//! its goal configuration keeps the four corners in the image, the target within the incidence bound and every joint
//! inside its limits — a situation a planner would call easy, from which a controller worth the name should
//! converge. The `feasible` family ([`crate::study::Perturbation::Feasible`]) draws uniform starts until they pass.

use crate::scenario::{Experiment, Scenario};

/// The configurations checked along the path: its two ends and `STRAIGHT_PATH_SAMPLES − 1` evenly spaced between
/// (every 1 % of the way).
pub const STRAIGHT_PATH_SAMPLES: usize = 100;

/// `true` when every configuration `q(s) = q₀ + s (q* − q₀)`, `s = k / STRAIGHT_PATH_SAMPLES`, lies inside the joint
/// limits, sees the four corners inside the image (the scenario's `simulation.image_margin`) and the target within
/// `simulation.max_incidence_deg` of its normal. The goal is the configuration the desired view was taught at
/// (`desired.joints`); with a goal perturbation, the target moves with it.
pub fn straight_feasible<const N: usize>(scenario: &Scenario, experiment: &Experiment<N>) -> bool {
    let scene = &experiment.scene;
    let (lower, upper) = (scene.chain().lower_limits(), scene.chain().upper_limits());
    let mut workspace = crate::robot::KinematicsWorkspace::new();
    let step = experiment.desired_joints - experiment.start;
    (0..=STRAIGHT_PATH_SAMPLES).all(|k| {
        let q = experiment.start + step * (k as f64 / STRAIGHT_PATH_SAMPLES as f64);
        let inside_limits = (0..N).all(|i| lower[i] <= q[i] && q[i] <= upper[i]);
        inside_limits
            && scene.observe(&mut workspace, &q).is_ok_and(|view| {
                scene
                    .intrinsics()
                    .all_in_field_of_view(&view.points, scenario.simulation.image_margin)
                    && seen_within(scene.target_incidence_deg(&view.c_from_o), scenario)
            })
    })
}

/// The target's incidence (degrees) within the scenario's bound.
fn seen_within(incidence_deg: f64, scenario: &Scenario) -> bool {
    incidence_deg <= scenario.simulation.max_incidence_deg
}

/// The Wilson score interval's lower end for `successes` of `trials` at 95 % (z = 1.96): the share that the full method
/// reaches with 97.5 % confidence, one-sided. `0` for no trial.
pub fn wilson_lower_95(successes: usize, trials: usize) -> f64 {
    if trials == 0 {
        return 0.0;
    }
    let (n, z) = (trials as f64, 1.96f64);
    let p = successes as f64 / n;
    let centre = p + z * z / (2.0 * n);
    let spread = z * (p * (1.0 - p) / n + z * z / (4.0 * n * n)).sqrt();
    ((centre - spread) / (1.0 + z * z / n)).max(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wilson_bound_matches_hand_computed_values() {
        // 34 of 42: p = 0.8095; centre = 0.8095 + 3.8416/84 = 0.85525; spread = 1.96 √(0.8095·0.1905/42 + 3.8416/7056)
        // = 1.96 √(0.0036716 + 0.00054444) = 1.96 · 0.064930 = 0.127263; (0.85525 − 0.127263)/(1 + 3.8416/42) = 0.6669.
        assert!(
            (wilson_lower_95(34, 42) - 0.6669).abs() < 5e-4,
            "{}",
            wilson_lower_95(34, 42)
        );
        // All of 200: the bound is 200/(200 + 3.8416) = 0.98115.
        assert!((wilson_lower_95(200, 200) - 0.98115).abs() < 1e-4);
        assert_eq!(wilson_lower_95(0, 10), 0.0);
        assert_eq!(wilson_lower_95(0, 0), 0.0);
    }
}
