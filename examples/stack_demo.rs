//! A task stack on a six-joint system, without robot or camera: four joint-space tasks (2, 1, 1 and 2 rows, as the
//! paper's visual tasks) are pushed one by one when the velocity has settled, with joint-limit avoidance in the
//! remaining freedom and a continuous velocity at every push.
//!
//! `cargo run --release --example stack_demo`

use servostack::avoidance::{Cost, JointLimits};
use servostack::law::{control_step, ControlLaw, ControlWorkspace, StackChange};
use servostack::math::JointVector;
use servostack::task::{LinearTask, Task, TaskJacobian, TaskValue};

fn main() -> std::process::ExitCode {
    servostack::report::exit_code(run())
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    let target = JointVector::<6>::new(0.3, -0.2, 0.1, 0.5, -0.4, 0.2);
    let rows = [2usize, 1, 1, 2];
    let tasks: Vec<LinearTask<6>> = rows
        .iter()
        .enumerate()
        .map(|(i, &m)| {
            let matrix =
                TaskJacobian::<6>::from_fn(m, |r, c| ((7 * i + 3 * r + c) as f64 * 0.61).sin());
            LinearTask::new(&format!("e{}", i + 1), matrix, target, 1.0)
        })
        .collect::<Result<_, _>>()?;
    let mut values: Vec<TaskValue<6>> = tasks
        .iter()
        .map(TaskValue::for_task)
        .collect::<Result<_, _>>()?;
    let limits = JointLimits::new(JointVector::repeat(-0.8), JointVector::repeat(0.8), 0.1)?;
    let law = ControlLaw::with_default_transition(&values, 0.5)?;
    let mut workspace = ControlWorkspace::new(&values);
    let (dt, settled) = (0.01, 0.02);
    let mut q = JointVector::<6>::new(-0.7, 0.7, -0.6, 0.0, 0.3, -0.7);
    let mut order = Vec::with_capacity(tasks.len());
    let mut change = StackChange::Changed;
    let mut last_change_time = 0.0;
    println!(
        "μ = {} s⁻¹, κ = {} s⁻¹, dt = {dt} s",
        law.transition_gain(),
        law.avoidance_gain()
    );
    for iteration in 0..3000 {
        let time = iteration as f64 * dt;
        for (task, value) in tasks.iter().zip(values.iter_mut()) {
            task.evaluate(&q, value)?;
        }
        let velocity_before = *workspace.last_output().velocity();
        let out = control_step(
            &law,
            &mut workspace,
            &values,
            &order,
            Some(&limits as &dyn Cost<6>),
            &q,
            time,
            change,
        )?;
        if change == StackChange::Changed {
            println!(
                "it {iteration:4}  t = {time:5.2} s  stack = {:?}  jump ‖q̇(τ⁺) − q̇(τ⁻)‖ = {:.1e}  h = {:.2e}",
                order.iter().map(|&i| tasks[i].name()).collect::<Vec<_>>(),
                (out.velocity() - velocity_before).norm(),
                out.cost()
            );
        }
        let velocity = *out.velocity();
        let stack_velocity = workspace.stack_solution().velocity().norm();
        q += velocity * dt;
        change = StackChange::Unchanged;
        // Push the next task once the stack has settled and the transition has died out (theory D5).
        let transition_over = time - last_change_time >= 5.0 / law.transition_gain();
        if order.len() < tasks.len() && stack_velocity < settled && transition_over {
            order.push(order.len());
            change = StackChange::Changed;
            last_change_time = time + dt;
        }
    }
    let errors: Vec<String> = values
        .iter()
        .map(|v| format!("{:.1e}", v.error().norm()))
        .collect();
    println!(
        "final ‖e_i‖ = {errors:?}, margin to limits = {:.3} of the range",
        limits.normalized_margin(&q)
    );
    Ok(())
}
