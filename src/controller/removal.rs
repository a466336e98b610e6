//! Removal ([theory §6](crate::theory#s6), D4, D6, D13): the decision of each iteration, the prediction it rests on,
//! the criteria that choose the task to remove, and the hold of the fallback.

use super::*;

impl<const N: usize> StackController<N> {
    /// `h_max`: the parameter, else the cost's D6 default, else no removal.
    pub(super) fn removal_threshold(&self, cost: &dyn Cost<N>) -> f64 {
        self.parameters
            .removal_threshold
            .or_else(|| cost.default_removal_threshold())
            .unwrap_or(f64::INFINITY)
    }

    /// Steps 2–4 of the module docs: a relieving re-insertion (D7), else a removal (D6), else a settled re-insertion
    /// (D7), a fallback (D13) or a push (D5), applied to the stack and logged. `result` receives the predicted cost.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn decide(
        &mut self,
        law: &ControlLaw,
        tasks: &[TaskValue<N>],
        cost: Option<&dyn Cost<N>>,
        guard: Option<&dyn Cost<N>>,
        q: &JointVector<N>,
        output: &ControlOutput<N>,
        sent_before: &JointVector<N>,
        iteration: usize,
        time: f64,
        result: &mut ControllerStep<N>,
    ) -> Result<Option<EventKind>, ControllerError> {
        self.criteria.clear();
        if matches!(self.phase, Phase::Held { .. }) {
            return Ok(None);
        }
        if let Some(kind) = self.escape_early(law, tasks, output, iteration, time) {
            return Ok(Some(kind));
        }
        let prediction = Prediction {
            q,
            sent: output.velocity(),
            sent_before,
            gradient: output.gradient(),
            transition_gain: law.transition_gain(),
            rule: self.parameters.rule,
        };
        let Some(cost) = cost else {
            return self.settle_and_add(law, tasks, None, &prediction, iteration, time, result);
        };
        let horizon = self.parameters.horizon(law.transition_gain());
        let predicted = prediction.at(output.law(), horizon);
        let mut predicted_gradient = JointVector::zeros();
        result.predicted_cost = match cost.value_and_gradient(&predicted, &mut predicted_gradient) {
            Err(CostError::PointBehindCamera { .. }) => f64::INFINITY,
            _ if self.parameters.rule == DecisionRule::Robust && cost.forbids(&predicted) => {
                f64::INFINITY
            }
            other => other?,
        };
        // The direction of the danger: ∇h(q), or ∇h(q̂) while the robot is still outside every band (robust rule). While
        // a restart recentres joints (D29) the law's gradient carries the recentring term: ∇h is evaluated apart.
        let mut gradient = *output.gradient();
        if matches!(self.phase, Phase::Recentring { .. }) {
            cost.value_and_gradient(q, &mut gradient)?;
        }
        let danger = if gradient.norm() > 0.0 || self.parameters.rule == DecisionRule::Paper {
            gradient
        } else {
            predicted_gradient
        };
        if danger.norm() > 0.0 {
            self.compute_criteria(law, tasks, &danger)?;
        }
        let threshold = self.removal_threshold(cost);
        let danger_predicted =
            result.predicted_cost > threshold && result.predicted_cost > result.cost;
        if let Some((task, predicted_back)) =
            self.choose_relieving_reinsertion(law, tasks, cost, &prediction, horizon, result, time)?
        {
            let threshold = self.parameters.reinsertion_ratio * threshold;
            self.reinsert(
                task,
                EventKind::Reinsert,
                iteration,
                time,
                predicted_back,
                threshold,
            );
            return Ok(Some(EventKind::Reinsert));
        }
        if let Some(guard) = guard {
            if let Some((task, predicted_back, predicted_without)) =
                self.choose_guard_relief(law, tasks, guard, &prediction, output, horizon, time)?
            {
                self.reinsert(
                    task,
                    EventKind::Reinsert,
                    iteration,
                    time,
                    predicted_back,
                    predicted_without,
                );
                return Ok(Some(EventKind::Reinsert));
            }
        }
        // After the fallback, only the last resort of D13: the law is about to cross a hard limit (or lose the target)
        // within the time a removal needs to act, `max(T, n_resort/μ)`. Before it, the `h_max` test of D6, and the
        // same hard-limit check (D6): the `h_max` test looks `T` ahead only.
        let far = horizon.max(LAST_RESORT_TRANSITIONS / law.transition_gain());
        let (trigger, removal_horizon, reference) = if self.fallback {
            let far_value = self.predicted_value(cost, &prediction.at(output.law(), far))?;
            let imminent = self.parameters.rule == DecisionRule::Robust && far_value.is_infinite();
            (imminent, far, f64::INFINITY)
        } else if !danger_predicted
            && self.parameters.rule == DecisionRule::Robust
            && cost.forbids(&prediction.at(output.law(), far))
        {
            (true, far, f64::INFINITY)
        } else {
            (danger_predicted, horizon, result.predicted_cost)
        };
        if trigger && danger.norm() > 0.0 && self.may_remove(law, time) {
            let choice = self.choose_removal(
                law,
                tasks,
                cost,
                guard,
                &prediction,
                removal_horizon,
                reference,
                &predicted,
            )?;
            if let Some((task, predicted_cost_without)) = choice {
                // At the prediction a target point may be behind the camera (an infinite cost, D6): the cost is
                // then named as a whole when it cannot name its term.
                let dominant = match cost.dominant_term(&predicted) {
                    Err(CostError::PointBehindCamera { .. }) => cost.name(),
                    named => named?,
                }
                .to_owned();
                self.stacked.retain(|&t| t != task);
                let at = self.removed.partition_point(|&t| t < task);
                self.removed.insert(at, task);
                self.removal_count[task] += 1;
                self.last_resort_used[task] |= self.fallback;
                self.removed_at[task] = time;
                self.last_removal_time = time;
                self.last_reinsertion_test = None;
                let report = RemovalReport {
                    predicted_cost: reference,
                    threshold,
                    predicted_cost_without,
                    horizon: removal_horizon,
                    joint: predicted_gradient.iamax(),
                    cost: dominant,
                    criteria: self.criteria.clone(),
                    swapped_for: None,
                };
                self.record(StackEvent {
                    iteration,
                    time,
                    kind: EventKind::Remove,
                    task,
                    law_jump: 0.0,
                    removal: Some(report),
                    reinsertion: None,
                });
                return Ok(Some(EventKind::Remove));
            }
            if self.fallback && self.parameters.hold_before_limit {
                return Ok(Some(self.hold(iteration, time)));
            }
        }
        self.settle_and_add(law, tasks, Some(cost), &prediction, iteration, time, result)
    }

    /// D13 hold: every stacked task is dropped (into the removed list, never to come back), so that the law is the
    /// avoidance alone. Moves indices between preallocated lists: no allocation.
    pub(super) fn hold(&mut self, iteration: usize, time: f64) -> EventKind {
        let first = self.stacked.first().copied().unwrap_or(0);
        while let Some(task) = self.stacked.pop() {
            let at = self.removed.partition_point(|&t| t < task);
            self.removed.insert(at, task);
        }
        self.phase = Phase::Held {
            task: first,
            since: time,
        };
        self.record(StackEvent {
            iteration,
            time,
            kind: EventKind::Hold,
            task: first,
            law_jump: 0.0,
            removal: None,
            reinsertion: None,
        });
        EventKind::Hold
    }

    /// Whether a removal may be made now: removals allowed, a task stacked, and (robust rule) the last removal at least
    /// `n_change/μ` old. A removal right after a push is allowed: the push is what the removal answers. After the
    /// fallback the caller asks this only for the last resort of D13.
    pub(super) fn may_remove(&self, law: &ControlLaw, time: f64) -> bool {
        let parameters = &self.parameters;
        let spaced = match parameters.rule {
            DecisionRule::Robust => {
                time - self.last_removal_time
                    >= parameters.change_transitions / law.transition_gain()
            }
            DecisionRule::Paper => true,
        };
        parameters.allow_removal && !self.stacked.is_empty() && spaced
    }

    /// D6: the task to remove and the cost predicted without it, or `None` when no candidate qualifies.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn choose_removal(
        &mut self,
        law: &ControlLaw,
        tasks: &[TaskValue<N>],
        cost: &dyn Cost<N>,
        guard: Option<&dyn Cost<N>>,
        prediction: &Prediction<'_, N>,
        horizon: f64,
        predicted_cost: f64,
        predicted: &JointVector<N>,
    ) -> Result<Option<(usize, f64)>, ControllerError> {
        let criterion = self.parameters.criterion;
        self.ranking.clear();
        self.ranking.extend_from_slice(&self.criteria);
        // Best score first; on equal scores the lowest priority (largest index) first.
        self.ranking.sort_unstable_by(|a, b| {
            b.score(criterion)
                .total_cmp(&a.score(criterion))
                .then(b.task.cmp(&a.task))
        });
        let robust = self.parameters.rule == DecisionRule::Robust;
        if robust && self.stacked.len() <= 1 {
            return Ok(None);
        }
        let guard_now = match guard {
            Some(guard) if robust => self.predicted_value(guard, predicted)?,
            _ => 0.0,
        };
        for rank in 0..self.ranking.len() {
            let task = self.ranking[rank].task;
            if robust
                && (self.protected[task]
                    || self.removal_count[task] >= self.parameters.max_removals
                    || self.last_resort_used[task])
            {
                continue;
            }
            self.set_trial_stack(None, Some(task));
            let without =
                prediction.after_change(&self.trial_law(law, tasks, prediction.gradient)?, horizon);
            let predicted_without = self.predicted_value(cost, &without)?;
            if !robust {
                return Ok(Some((task, predicted_without)));
            }
            if predicted_without >= predicted_cost {
                continue;
            }
            if let Some(guard) = guard {
                if self.predicted_value(guard, &without)? > guard_now {
                    continue;
                }
            }
            return Ok(Some((task, predicted_without)));
        }
        Ok(None)
    }

    /// Computes [`TaskCriteria`] for every stacked task ([theory §6.3](crate::theory#s6-3)) into `self.criteria`, with the danger direction
    /// `gradient`.
    ///
    /// # Errors
    /// A failed decomposition of a task Jacobian (the removal must not be chosen from an incomplete set).
    pub(super) fn compute_criteria(
        &mut self,
        law: &ControlLaw,
        tasks: &[TaskValue<N>],
        gradient: &JointVector<N>,
    ) -> Result<(), ControllerError> {
        let policy = law.stack_parameters().rank_policy;
        let gradient_norm = gradient.norm();
        for &index in &self.stacked {
            let (Some(task), Some(svd)) = (tasks.get(index), self.svds.get_mut(index)) else {
                continue;
            };
            // J_i⁺ e_i and ‖J_i⁺J_i ∇h‖: for a one- or two-row task of full, well-conditioned rank in closed form,
            // otherwise by the SVD.
            let mut direction = JointVector::zeros();
            let c2_prime = match solve_small_full_row_rank(
                task.jacobian(),
                task.error(),
                gradient,
                &policy,
                &mut direction,
            ) {
                Some(c2_prime) => c2_prime,
                None => {
                    let mut work = self.jacobian_work.rows_mut(0, task.rows());
                    work.copy_from(task.jacobian());
                    let linalg = |source| {
                        ControllerError::Law(LawError::Stack(StackError::Linalg {
                            level: index,
                            source,
                        }))
                    };
                    svd.decompose_warm(&mut work, &policy, 0.0)
                        .map_err(linalg)?;
                    svd.solve(
                        &work,
                        task.error(),
                        VelocityInverse::Truncated,
                        &mut direction,
                    )
                    .map_err(linalg)?;
                    svd.row_space_component_norm(gradient)
                }
            };
            let c1 = -direction.dot(gradient);
            let direction_norm = direction.norm();
            let c1_normalized = if direction_norm > DIRECTION_FLOOR {
                c1 / direction_norm
            } else {
                0.0
            };
            let c2 = (gradient_norm * gradient_norm - c2_prime * c2_prime)
                .max(0.0)
                .sqrt();
            self.criteria.push(TaskCriteria {
                task: index,
                c1,
                c1_normalized,
                c2,
                c2_prime,
                combined: (c1_normalized + c2_prime) / gradient_norm,
            });
        }
        Ok(())
    }
}
