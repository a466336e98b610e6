//! A family's summary: per method the outcomes, medians and counts over the family's draws, and how the full method
//! compares with its baselines on the same draws. Computed the same way for a study run whole, a shard and a merge of
//! shards ([`StudyResult::merge`](super::StudyResult::merge)).

use super::{
    DrawResult, Family, FamilyResult, MethodResult, MethodSummary, POSE_TOLERANCE_DEG,
    POSE_TOLERANCE_M,
};
use crate::scenario::RunKind;

/// A family's summary over its draws, for the methods of the study in their order.
pub(super) fn summarize(
    methods: &[RunKind],
    family: &Family,
    draws: Vec<DrawResult>,
) -> FamilyResult {
    let position = |kind| methods.iter().position(|&m| m == kind);
    let full = position(RunKind::FullMethod);
    let stack_gradient = position(RunKind::StackGradient);
    let converged = |d: &DrawResult, i: Option<usize>| i.is_some_and(|i| d.methods[i].converged());
    let any_baseline = |d: &DrawResult| {
        d.methods
            .iter()
            .any(|m| m.method.is_paper_baseline() && m.converged())
    };
    let only_at_limit = DrawResult::baselines_converged_only_at_limit;
    let summaries = methods
        .iter()
        .enumerate()
        .map(|(i, &method)| {
            let results: Vec<&MethodResult> = draws.iter().map(|d| &d.methods[i]).collect();
            // The iterations the converged runs took, for the median and the 95th percentile.
            let iterations_to_converge: Vec<usize> = results
                .iter()
                .filter(|r| r.converged())
                .map(|r| r.iterations)
                .collect();
            let mut outcomes = std::collections::BTreeMap::new();
            for r in &results {
                *outcomes.entry(r.outcome).or_insert(0) += 1;
            }
            MethodSummary {
                method,
                converged: iterations_to_converge.len(),
                draws: results.len(),
                outcomes,
                median_removals: median(results.iter().map(|r| r.removals as f64)),
                median_removals_of_a_task: median(
                    results.iter().map(|r| r.max_removals_of_a_task as f64),
                ),
                max_removals_of_a_task: results
                    .iter()
                    .map(|r| r.max_removals_of_a_task)
                    .max()
                    .unwrap_or(0),
                fallbacks: results.iter().filter(|r| r.fallback).count(),
                restarts: results.iter().filter(|r| r.restart_take_outs > 0).count(),
                median_take_outs_of_a_task: median(
                    results.iter().map(|r| r.max_take_outs_of_a_task as f64),
                ),
                median_max_velocity_step: median(results.iter().map(|r| r.max_velocity_step)),
                max_acceleration_ratio: results
                    .iter()
                    .map(|r| r.max_acceleration_ratio)
                    .fold(0.0, f64::max),
                converged_within_pose_tolerance: results
                    .iter()
                    .filter(|r| {
                        r.converged()
                            && r.camera_translation_error <= POSE_TOLERANCE_M
                            && r.camera_rotation_error_deg <= POSE_TOLERANCE_DEG
                    })
                    .count(),
                median_iterations_to_converge: Some(median(
                    iterations_to_converge.iter().map(|&i| i as f64),
                ))
                .filter(|m| !m.is_nan()),
                p95_iterations_to_converge: nearest_rank(0.95, iterations_to_converge),
            }
        })
        .collect();
    FamilyResult {
        family: family.clone(),
        methods: summaries,
        any_baseline_converged: draws.iter().filter(|d| any_baseline(d)).count(),
        full_method_also_converged: draws
            .iter()
            .filter(|d| any_baseline(d) && converged(d, full))
            .count(),
        full_method_worse_than_stack_gradient: draws
            .iter()
            .filter(|d| converged(d, stack_gradient) && full.is_some() && !converged(d, full))
            .count(),
        baseline_wins_at_limit: draws.iter().filter(|d| only_at_limit(d)).count(),
        full_method_also_converged_at_limit: draws
            .iter()
            .filter(|d| only_at_limit(d) && converged(d, full))
            .count(),
        straight_feasible: draws.iter().filter(|d| d.straight_feasible).count(),
        full_method_straight_feasible: draws
            .iter()
            .filter(|d| d.straight_feasible && converged(d, full))
            .count(),
        draws,
    }
}

/// The median of `values` (`NaN` when empty).
fn median(values: impl Iterator<Item = f64>) -> f64 {
    let mut values: Vec<f64> = values.collect();
    if values.is_empty() {
        return f64::NAN;
    }
    values.sort_by(f64::total_cmp);
    let mid = values.len() / 2;
    if values.len() % 2 == 1 {
        values[mid]
    } else {
        0.5 * (values[mid - 1] + values[mid])
    }
}

/// The `p`-quantile of `values` by nearest rank: the smallest value that at least a share `p` of them do not exceed
/// (the value of rank `⌈p n⌉` in increasing order, `0 < p ≤ 1`); `None` when empty.
fn nearest_rank(p: f64, mut values: Vec<usize>) -> Option<usize> {
    values.sort_unstable();
    let rank = (p * values.len() as f64).ceil() as usize;
    values.get(rank.clamp(1, values.len().max(1)) - 1).copied()
}

#[cfg(test)]
mod tests {
    use super::nearest_rank;

    #[test]
    fn the_95th_percentile_is_the_value_of_rank_ceil_of_95_percent() {
        // 20 values: rank ⌈19⌉ = 19, one value above it; 100 values: rank 95; 21 values: rank ⌈19.95⌉ = 20.
        assert_eq!(nearest_rank(0.95, (1..=20).rev().collect()), Some(19));
        assert_eq!(
            nearest_rank(0.95, (1..=100).map(|i| 10 * i).collect()),
            Some(950)
        );
        assert_eq!(nearest_rank(0.95, (1..=21).collect()), Some(20));
        // One value is its own percentile; none has none.
        assert_eq!(nearest_rank(0.95, vec![7]), Some(7));
        assert_eq!(nearest_rank(0.95, vec![]), None);
        // Ties: the value, not a position.
        assert_eq!(nearest_rank(0.95, vec![5, 5, 5, 9]), Some(9));
        assert_eq!(nearest_rank(0.5, vec![5, 5, 5, 9]), Some(5));
    }
}
