//! A copy of evaluated tasks perturbed by about one control period's change, shared by the benches that alternate
//! between the two so that warm-started decompositions start from a nearby, not an identical, matrix.

use servostack::task::{TaskJacobian, TaskValue};

/// `tasks` with every Jacobian entry scaled by `1 + 1e−3·sin(·)`: the change of one control period.
pub fn perturbed<const N: usize>(tasks: &[TaskValue<N>]) -> Vec<TaskValue<N>> {
    tasks
        .iter()
        .enumerate()
        .map(|(i, task)| {
            let jacobian = TaskJacobian::<N>::from_fn(task.rows(), |r, c| {
                task.jacobian()[(r, c)] * (1.0 + 1e-3 * ((i + 3 * r + 7 * c) as f64).sin())
            });
            TaskValue::from_parts("perturbed", task.error().clone(), jacobian, task.gain()).unwrap()
        })
        .collect()
}
