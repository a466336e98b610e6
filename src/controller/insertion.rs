//! Pushes and re-insertions (D5, D7, D28): when the stack has settled, the next task or a removed one is added, and a
//! removed task is swapped back when it relieves the avoidance.

use super::*;

/// D5: the stacked tasks' squared error makes progress when it falls below this fraction of its reference (its norm
/// by about a tenth). Not a parameter: 0.5 to 0.9 change the zoo's uniform count by under 0.3 % (theory notes, D29).
const PROGRESS_FRACTION: f64 = 0.8;

impl<const N: usize> StackController<N> {
    /// Pushes the next task of the sequence, or, with [`TaskSequencing::AllAtOnce`], every task left in it: one
    /// change, each push logged at this iteration.
    pub(super) fn push_next(&mut self, iteration: usize, time: f64) {
        loop {
            let task = self.next_push;
            self.next_push += 1;
            self.insert_by_priority(task);
            self.record(StackEvent {
                iteration,
                time,
                kind: EventKind::Push,
                task,
                law_jump: 0.0,
                removal: None,
                reinsertion: None,
            });
            if self.parameters.sequencing == TaskSequencing::OneByOne
                || self.next_push >= self.sequence_len()
            {
                break;
            }
        }
    }

    pub(super) fn insert_by_priority(&mut self, task: usize) {
        let at = self.stacked.partition_point(|&t| t < task);
        self.stacked.insert(at, task);
    }

    /// D7 relief: while the cost is predicted to rise (`h(q̂) > h(q)` over the removal horizon `T`), a removed task whose
    /// dwell is over comes back, without waiting for the stack to settle, when the law with it back predicts a lower
    /// cost than the current stack's and one under the re-insertion threshold `r_back · h_max`: the first such task by
    /// priority, with its predicted cost. Robust rule only, never during the fallback, not within `n_change/μ` of the
    /// last change.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn choose_relieving_reinsertion(
        &mut self,
        law: &ControlLaw,
        tasks: &[TaskValue<N>],
        cost: &dyn Cost<N>,
        prediction: &Prediction<'_, N>,
        horizon: f64,
        now: &ControllerStep<N>,
        time: f64,
    ) -> Result<Option<(usize, f64)>, ControllerError> {
        if !self.may_relieve(law, time) || self.fallback || now.predicted_cost <= now.cost {
            return Ok(None);
        }
        let threshold = self.parameters.reinsertion_ratio * self.removal_threshold(cost);
        self.first_task_back(law, tasks, cost, prediction, horizon, Some(time), |back| {
            back < now.predicted_cost && back <= threshold
        })
    }

    /// D7 guard relief: while the `guard` cost (the visibility of the target, in the simulation) is predicted to rise
    /// to a positive value one transition time ahead (`g(q̂(max(T, n_resort/μ))) > max(g(q), 0)`), the first removed
    /// task by priority whose return lowers that prediction comes back at once, whatever its dwell and during the
    /// fallback too: losing the target ends the run, and the free motion a removal leaves may carry the target out of
    /// the image long after the removal's own guard test. Returns the task, the guard's prediction with it back and
    /// without it. Robust rule only, not within `n_change/μ` of the last change.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn choose_guard_relief(
        &mut self,
        law: &ControlLaw,
        tasks: &[TaskValue<N>],
        guard: &dyn Cost<N>,
        prediction: &Prediction<'_, N>,
        output: &ControlOutput<N>,
        horizon: f64,
        time: f64,
    ) -> Result<Option<(usize, f64, f64)>, ControllerError> {
        if !self.may_relieve(law, time) {
            return Ok(None);
        }
        let far = horizon.max(LAST_RESORT_TRANSITIONS / law.transition_gain());
        let now = self.predicted_value(guard, prediction.q)?;
        let without = self.predicted_value(guard, &prediction.at(output.law(), far))?;
        if without <= now.max(0.0) {
            return Ok(None);
        }
        let found = self.first_task_back(law, tasks, guard, prediction, far, None, |back| {
            back < without
        })?;
        Ok(found.map(|(task, back)| (task, back, without)))
    }

    /// Whether a relief (D7) may be considered: a task is out, robust rule, the last change at least `n_change/μ` old.
    pub(super) fn may_relieve(&self, law: &ControlLaw, time: f64) -> bool {
        !self.removed.is_empty()
            && self.parameters.rule == DecisionRule::Robust
            && time - self.last_change_time
                >= self.parameters.change_transitions / law.transition_gain()
    }

    /// The first removed task by priority whose return `accept`s the value of `cost` predicted `horizon` ahead along
    /// the law of the stack with it back, with that value. With `dwell_at = Some(t)`, tasks still within their dwell
    /// at time `t` are passed over.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn first_task_back(
        &mut self,
        law: &ControlLaw,
        tasks: &[TaskValue<N>],
        cost: &dyn Cost<N>,
        prediction: &Prediction<'_, N>,
        horizon: f64,
        dwell_at: Option<f64>,
        accept: impl Fn(f64) -> bool,
    ) -> Result<Option<(usize, f64)>, ControllerError> {
        for rank in 0..self.removed.len() {
            let task = self.removed[rank];
            if dwell_at.is_some_and(|time| time - self.removed_at[task] < self.dwell(task)) {
                continue;
            }
            self.set_trial_stack(Some(task), None);
            let back =
                prediction.after_change(&self.trial_law(law, tasks, prediction.gradient)?, horizon);
            let predicted_back = self.predicted_value(cost, &back)?;
            if accept(predicted_back) {
                return Ok(Some((task, predicted_back)));
            }
        }
        Ok(None)
    }

    /// `self.trial_order` ← the stacked tasks without `left_out`, with `added` at its priority: the stack a removal,
    /// a re-insertion or a swap would make.
    pub(super) fn set_trial_stack(&mut self, added: Option<usize>, left_out: Option<usize>) {
        self.trial_order.clear();
        self.trial_order.extend(
            self.stacked
                .iter()
                .copied()
                .filter(|&t| Some(t) != left_out),
        );
        if let Some(task) = added {
            let at = self.trial_order.partition_point(|&t| t < task);
            self.trial_order.insert(at, task);
        }
    }

    /// The law `u = q̇_n − κ P^A_n ∇h` of the stack `self.trial_order`.
    pub(super) fn trial_law(
        &mut self,
        law: &ControlLaw,
        tasks: &[TaskValue<N>],
        gradient: &JointVector<N>,
    ) -> Result<JointVector<N>, ControllerError> {
        let solution = solve_stack(
            law.stack_parameters(),
            &mut self.trial_workspace,
            tasks,
            &self.trial_order,
        )
        .map_err(LawError::from)?;
        let avoidance = law.avoidance_term(solution, tasks, &self.trial_order, gradient)?;
        Ok(solution.velocity() + avoidance)
    }

    /// D5: the stack velocity is below `epsilon_add` and the last transition has died out.
    pub(super) fn settled(
        &self,
        law: &ControlLaw,
        time: f64,
        stack_velocity_norm: f64,
        epsilon_add: f64,
    ) -> bool {
        stack_velocity_norm < epsilon_add
            && time - self.last_change_time
                >= self.parameters.settle_transitions / law.transition_gain()
    }

    /// D5 (full method): the stack has stopped progressing — the stacked tasks' squared error `E = Σ‖e_i‖²` has not
    /// fallen below `0.8 E₀` within `W_progress` of the reference `(t₀, E₀)`, taken at the first test after each change
    /// and again each time `E` falls below `0.8 E₀` — whatever its velocity: a stack that chatters or creeps along a
    /// limit has settled as much as one at rest. Once it has, the reference is taken again at the next test.
    pub(super) fn stopped_progressing(&mut self, tasks: &[TaskValue<N>], time: f64) -> bool {
        let parameters = &self.parameters;
        let window = parameters.progress_window;
        if window == f64::INFINITY
            || !parameters.allow_removal
            || parameters.rule != DecisionRule::Robust
        {
            return false;
        }
        let error: f64 = self
            .stacked
            .iter()
            .map(|&t| tasks[t].error().norm_squared())
            .sum();
        match self.progress_reference {
            // The reference holds while no change has been made since it was taken and the error has not fallen by
            // the fraction.
            Some((since, reference))
                if since >= self.last_change_time && error >= PROGRESS_FRACTION * reference =>
            {
                if time - since < window {
                    return false;
                }
                self.progress_reference = None;
                true
            }
            _ => {
                self.progress_reference = Some((time, error));
                false
            }
        }
    }

    /// D28: before the stack has settled, push the next task once the law with it, `‖u⁺‖`, has grown to `r_push`
    /// times its smallest value since the last change (full method, no task out, one transition after the change).
    pub(super) fn push_early(
        &mut self,
        law: &ControlLaw,
        tasks: &[TaskValue<N>],
        gradient: &JointVector<N>,
        iteration: usize,
        time: f64,
    ) -> Result<Option<EventKind>, ControllerError> {
        let parameters = &self.parameters;
        if !parameters.early_push_ratio.is_finite()
            || !parameters.allow_removal
            || parameters.rule != DecisionRule::Robust
            || !self.removed.is_empty()
            || self.next_push >= self.sequence_len()
            || time - self.last_change_time < parameters.change_transitions / law.transition_gain()
        {
            return Ok(None);
        }
        let ratio = parameters.early_push_ratio;
        self.set_trial_stack(Some(self.next_push), None);
        let with_next = self.trial_law(law, tasks, gradient)?.norm();
        let changes = self.events.len();
        match self.early_push_reference {
            Some((since, smallest)) if since == changes => {
                if with_next > ratio * smallest {
                    self.push_next(iteration, time);
                    return Ok(Some(EventKind::Push));
                }
                self.early_push_reference = Some((since, smallest.min(with_next)));
            }
            _ => self.early_push_reference = Some((changes, with_next)),
        }
        Ok(None)
    }

    /// D7, D13, D5: once settled, put a removed task back (with hysteresis and dwell), fall back when one cannot come
    /// back, or push the next task.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn settle_and_add(
        &mut self,
        law: &ControlLaw,
        tasks: &[TaskValue<N>],
        cost: Option<&dyn Cost<N>>,
        prediction: &Prediction<'_, N>,
        iteration: usize,
        time: f64,
        result: &ControllerStep<N>,
    ) -> Result<Option<EventKind>, ControllerError> {
        // D29: while a restart recentres joints, nothing is pushed or put back.
        if let Phase::Recentring {
            joints,
            centre,
            since,
        } = self.phase
        {
            if time - since < self.parameters.restart_timeout
                && !self.recentred(&joints, &centre, prediction.q)
            {
                return Ok(None);
            }
            self.phase = Phase::Sequencing;
        }
        // With no task out, the next push waits for the full method's threshold when tasks may be removed (robust
        // rule), the paper's otherwise; a removed task is tested for re-insertion at the paper's, once the stack has
        // nearly stopped (D5).
        let parameters = &self.parameters;
        let epsilon_add = if self.removed.is_empty()
            && parameters.allow_removal
            && parameters.rule == DecisionRule::Robust
        {
            parameters.settle_velocity_with_removal
        } else {
            parameters.settle_velocity
        };
        let stalled = self.stopped_progressing(tasks, time);
        if !(stalled || self.settled(law, time, result.stack_velocity_norm, epsilon_add)) {
            return self.push_early(law, tasks, prediction.gradient, iteration, time);
        }
        if self.removed.is_empty() {
            if self.next_push < self.sequence_len() {
                self.push_next(iteration, time);
                return Ok(Some(EventKind::Push));
            }
            if let Some(kind) = self.escape(tasks, iteration, time) {
                return Ok(Some(kind));
            }
            // D29 restarts a run whose error has stopped falling, or at rest (the paper's `ε_add`).
            let at_rest = result.stack_velocity_norm < self.parameters.settle_velocity;
            let standstill = match (stalled, at_rest) {
                (true, true) => Some(Standstill::FlatAtRest),
                (true, false) => Some(Standstill::FlatMoving),
                (false, true) => Some(Standstill::AtRest),
                (false, false) => None,
            };
            return Ok(self.restart(law, tasks, cost, standstill, prediction.q, iteration, time));
        }
        let robust = self.parameters.rule == DecisionRule::Robust;
        let h_max = cost.map_or(f64::INFINITY, |c| self.removal_threshold(c));
        let threshold = if robust {
            self.parameters.reinsertion_ratio * h_max
        } else {
            h_max
        };
        let mut tested = false;
        for rank in 0..self.removed.len() {
            let task = self.removed[rank];
            let removed_for = time - self.removed_at[task];
            if robust && removed_for < self.dwell(task) {
                continue;
            }
            let predicted_cost = match cost {
                Some(cost) if !self.fallback => {
                    self.set_trial_stack(Some(task), None);
                    // The look-ahead spans the task's own time constant 1/λ_i: for a task converging as e^{−λ_i t},
                    // q + u/λ_i is where its linearised law would take the robot.
                    let horizon = match (robust, tasks.get(task)) {
                        (true, Some(value)) => {
                            self.parameters.reinsertion_look_ahead / value.gain()
                        }
                        _ => self.parameters.prediction_horizon,
                    };
                    let back = prediction
                        .after_change(&self.trial_law(law, tasks, prediction.gradient)?, horizon);
                    self.predicted_value(cost, &back)?
                }
                _ => 0.0,
            };
            tested = true;
            self.last_reinsertion_test = Some((task, predicted_cost, threshold));
            if predicted_cost <= threshold || self.fallback {
                let kind = if self.fallback {
                    EventKind::Fallback
                } else {
                    EventKind::Reinsert
                };
                self.reinsert(task, kind, iteration, time, predicted_cost, threshold);
                return Ok(Some(kind));
            }
        }
        if !tested {
            return Ok(None);
        }
        if robust && self.next_push < self.sequence_len() {
            // No removed task can come back here: make progress with the next task instead (the paper's e4 achieved
            // while e3 is out). The removed ones are tested again once the stack has settled.
            self.push_next(iteration, time);
            return Ok(Some(EventKind::Push));
        }
        if let (true, false, Some(cost)) = (robust, self.fallback, cost) {
            if let Some((back, out, predicted_cost)) =
                self.find_swap(law, tasks, cost, prediction, threshold, time)?
            {
                self.last_swap = Some((back, out));
                // One transition: `back` returns at its priority and `out` leaves (the configuration has changed since
                // `back` was removed, and now `out` is the task in the way).
                self.reinsert(
                    back,
                    EventKind::Reinsert,
                    iteration,
                    time,
                    predicted_cost,
                    threshold,
                );
                self.stacked.retain(|&t| t != out);
                let at = self.removed.partition_point(|&t| t < out);
                self.removed.insert(at, out);
                self.removal_count[out] += 1;
                self.removed_at[out] = time;
                self.last_removal_time = time;
                self.record(StackEvent {
                    iteration,
                    time,
                    kind: EventKind::Remove,
                    task: out,
                    law_jump: 0.0,
                    removal: Some(RemovalReport {
                        predicted_cost: result.predicted_cost,
                        threshold: h_max,
                        predicted_cost_without: predicted_cost,
                        horizon: self.parameters.reinsertion_look_ahead
                            / tasks.get(back).map_or(1.0, TaskValue::gain),
                        joint: prediction.gradient.iamax(),
                        cost: cost.dominant_term(prediction.q)?.to_owned(),
                        criteria: self.criteria.clone(),
                        swapped_for: Some(back),
                    }),
                    reinsertion: None,
                });
                return Ok(Some(EventKind::Remove));
            }
        }
        let waiting_since = *self.refused_since.get_or_insert(time);
        if robust && time - waiting_since >= self.parameters.stall_timeout {
            // D13: the first removed task comes back without the test; from now on tasks are removed only as a last
            // resort.
            self.fallback = true;
            let task = self.removed[0];
            let (predicted_cost, threshold) = match self.last_reinsertion_test {
                Some((tested, predicted, threshold)) if tested == task => (predicted, threshold),
                _ => (f64::NAN, threshold),
            };
            self.reinsert(
                task,
                EventKind::Fallback,
                iteration,
                time,
                predicted_cost,
                threshold,
            );
            return Ok(Some(EventKind::Fallback));
        }
        Ok(None)
    }

    /// D7 swap: a removed task `back` (dwell over) and a stacked task `out` (removable), not the reverse of the last
    /// swap, such that the stack with `back` in and `out` out keeps the prediction over `n_back/λ_back` below the
    /// re-insertion threshold.
    pub(super) fn find_swap(
        &mut self,
        law: &ControlLaw,
        tasks: &[TaskValue<N>],
        cost: &dyn Cost<N>,
        prediction: &Prediction<'_, N>,
        threshold: f64,
        time: f64,
    ) -> Result<Option<(usize, usize, f64)>, ControllerError> {
        for back_rank in 0..self.removed.len() {
            let back = self.removed[back_rank];
            let Some(back_gain) = tasks.get(back).map(TaskValue::gain) else {
                continue;
            };
            if time - self.removed_at[back] < self.dwell(back) {
                continue;
            }
            for out_rank in 0..self.stacked.len() {
                let out = self.stacked[out_rank];
                // Never the reverse of the last swap: two tasks traded back and forth is chatter, not progress.
                if self.last_swap == Some((out, back)) {
                    continue;
                }
                if self.protected[out] || self.removal_count[out] >= self.parameters.max_removals {
                    continue;
                }
                self.set_trial_stack(Some(back), Some(out));
                let horizon = self.parameters.reinsertion_look_ahead / back_gain;
                let swapped = prediction
                    .after_change(&self.trial_law(law, tasks, prediction.gradient)?, horizon);
                let predicted_cost = self.predicted_value(cost, &swapped)?;
                if predicted_cost <= threshold {
                    return Ok(Some((back, out, predicted_cost)));
                }
            }
        }
        Ok(None)
    }

    /// The cost of a predicted configuration: [`predicted_value`], and under the robust rule `+∞` where the cost
    /// forbids it ([`Cost::forbids`], D6).
    pub(super) fn predicted_value(
        &self,
        cost: &dyn Cost<N>,
        q: &JointVector<N>,
    ) -> Result<f64, CostError> {
        if self.parameters.rule == DecisionRule::Robust && cost.forbids(q) {
            return Ok(f64::INFINITY);
        }
        predicted_value(cost, q)
    }

    /// `T_dwell · 2^{k−1}`: how long a task removed `k` times stays out at least (D7).
    pub(super) fn dwell(&self, task: usize) -> f64 {
        let doublings = self.removal_count[task].saturating_sub(1).min(30);
        self.parameters.reinsertion_dwell * f64::from(1u32 << doublings)
    }

    pub(super) fn reinsert(
        &mut self,
        task: usize,
        kind: EventKind,
        iteration: usize,
        time: f64,
        predicted_cost: f64,
        threshold: f64,
    ) {
        self.removed.retain(|&t| t != task);
        self.insert_by_priority(task);
        let removed_for = time - self.removed_at[task];
        self.record(StackEvent {
            iteration,
            time,
            kind,
            task,
            law_jump: 0.0,
            removal: None,
            reinsertion: Some(ReinsertionReport {
                predicted_cost,
                threshold,
                removed_for,
            }),
        });
    }
}
