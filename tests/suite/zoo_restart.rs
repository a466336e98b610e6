//! D29 on the zoo's arms without a locked joint: a run whose stacked error has stopped falling short of its goal
//! restarts, whatever the locks. Outcomes over draws of the zoo's generated scenarios (with the zoo installed).

use crate::convergence_domain::{full_method_uniform, zoo_scenario};

/// On the zoo's Tiago Pro and xArm7, runs came to a false equilibrium with every task stacked and no joint locked:
/// the law chattering about a singular configuration at the velocity limits, its sign flipping every period, the
/// stacked error flat, until the budget ended (3 of these 80 uniform draws, measured while D29 wanted a locked
/// joint). No run of the full method ends its budget without having restarted.
#[test]
fn a_run_whose_error_stops_falling_restarts_without_a_locked_joint() {
    for arm in ["tiago_pro", "xarm7"] {
        let Some(scenario) = zoo_scenario(arm) else {
            return;
        };
        for draw in &full_method_uniform(&scenario).families[0].draws {
            let run = &draw.methods[0];
            assert!(
                run.outcome != "max_iterations" || run.restart_take_outs > 0,
                "{arm}, draw {}: {run:?}",
                draw.draw
            );
        }
    }
}
