//! Recovery (D23, D24, D29): the reserve task's escape, its early form, and the restart of the sequence when the run
//! no longer progresses against a limit, with its recentring term.

use super::*;
use std::f64::consts::{FRAC_PI_2, PI};

/// D29: how a run with the whole sequence stacked has stopped progressing, and so whether it needs a locked joint to
/// restart and the stacked tasks' error above which the restart's goal test counts the goal as missed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Standstill {
    /// At rest, `‖q̇_n‖ < ε_add`, the error still falling: near the goal the law's velocity is proportional to the
    /// error, so a run still converging there is at rest too; the goal counts as missed above `ε_achieved`, and the
    /// run restarts only with a joint locked (slow gains leave a converging run at rest far from its goal).
    AtRest,
    /// The stacked error flat for `W_progress` ([`StackController::stopped_progressing`]) at rest: a run converging
    /// would not be flat; the goal counts as missed above the loop's convergence threshold
    /// ([`StackController::with_goal_error`]), with a joint locked (without one, a measured error is flat at the goal
    /// itself under the camera's noise).
    FlatAtRest,
    /// The stacked error flat while the robot moves (`‖q̇_n‖ ≥ ε_add`): it creeps along a limit or chatters about a
    /// singular configuration at its velocity limits; the goal counts as missed above the convergence threshold, locked
    /// joints or not.
    FlatMoving,
}

impl<const N: usize> StackController<N> {
    /// D23: the reserve task replaces the last task of the sequence when the stack has achieved its tasks and the
    /// reserve task has not (called with the sequence complete, no task out and the stack settled).
    pub(super) fn escape(
        &mut self,
        tasks: &[TaskValue<N>],
        iteration: usize,
        time: f64,
    ) -> Option<EventKind> {
        let reserve = self.waiting_reserve()?;
        let achieved = self
            .stacked
            .iter()
            .all(|&t| tasks[t].error().norm() < self.parameters.escape_achieved_error);
        if !achieved || tasks[reserve].error().norm() <= self.parameters.escape_error {
            return None;
        }
        self.swap_in_reserve(reserve, iteration, time)
    }

    /// D24: the reserve task replaces the last task of the sequence as soon as the law of the complete stack, nothing
    /// out, drives the reserve task's error away from zero (`e_rᵀ J_r u > r_escape ‖e_r‖²`) while it is above
    /// `ε_escape`; not within `n_change/μ` of the last change (the law's transient after a push is not judged).
    pub(super) fn escape_early(
        &mut self,
        law: &ControlLaw,
        tasks: &[TaskValue<N>],
        output: &ControlOutput<N>,
        iteration: usize,
        time: f64,
    ) -> Option<EventKind> {
        let reserve = self.waiting_reserve()?;
        let parameters = &self.parameters;
        if self.next_push < self.sequence_len()
            || !self.removed.is_empty()
            || time - self.last_change_time < parameters.change_transitions / law.transition_gain()
        {
            return None;
        }
        let value = &tasks[reserve];
        let error_squared = value.error().norm_squared();
        if error_squared.sqrt() <= parameters.escape_error {
            return None;
        }
        // e_rᵀ J_r u = (J_rᵀ e_r)ᵀ u, with J_rᵀ e_r a fixed-size N-vector (no allocation).
        let growth = value.jacobian().tr_mul(value.error()).dot(output.law()) / error_squared;
        if growth > parameters.escape_growth_rate {
            self.swap_in_reserve(reserve, iteration, time)
        } else {
            None
        }
    }

    /// D23, D24: the reserve task takes the place of the last stacked task, once; logged as [`EventKind::Escape`].
    pub(super) fn swap_in_reserve(
        &mut self,
        reserve: usize,
        iteration: usize,
        time: f64,
    ) -> Option<EventKind> {
        let last = *self.stacked.last()?;
        self.stacked.retain(|&t| t != last);
        self.insert_by_priority(reserve);
        self.escaped = true;
        self.record(StackEvent {
            iteration,
            time,
            kind: EventKind::Escape,
            task: reserve,
            law_jump: 0.0,
            removal: None,
            reinsertion: None,
        });
        Some(EventKind::Escape)
    }

    /// D29: with the whole sequence stacked, nothing out and no escape due (called after the escape of D23 declined),
    /// a run that no longer progresses ([`Standstill`]: at rest with a joint locked at a limit, or with its error flat
    /// while it moves) and the goal not reached (a stacked task's error above the standstill's threshold, or the
    /// reserve task's above `ε_escape`): every task but the first is taken out in one change, each time, and the
    /// locked joints, if any (every limited joint at a repeat,
    /// [`Self::recentred_joints`]) are driven to their targets — the middle of their ranges, past it for ranges wider
    /// than a half turn ([`Self::recentring_targets`], [`Self::recentring_cost`]) — before the sequence goes on.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn restart(
        &mut self,
        law: &ControlLaw,
        tasks: &[TaskValue<N>],
        cost: Option<&dyn Cost<N>>,
        standstill: Option<Standstill>,
        q: &JointVector<N>,
        iteration: usize,
        time: f64,
    ) -> Option<EventKind> {
        let parameters = &self.parameters;
        if parameters.restart_rate <= 0.0
            || !parameters.allow_removal
            || parameters.rule != DecisionRule::Robust
            || self.limits.is_none()
            || cost.is_none()
            || law.avoidance_gain() <= 0.0
        {
            return None;
        }
        // At rest, a run is held against a limit only with a joint locked there; a flat error while moving is a false
        // equilibrium whatever the locks (the law chattering about a singular configuration, at its velocity limits).
        let locked = *self.law_workspace.locked_joints();
        let goal_error = match standstill? {
            Standstill::AtRest | Standstill::FlatAtRest if !locked.contains(&true) => return None,
            Standstill::AtRest => parameters.escape_achieved_error,
            Standstill::FlatAtRest | Standstill::FlatMoving => self.goal_error,
        };
        // Short of the goal: a stacked task above the threshold, or the reserve task's corners off their goal. With a
        // joint locked, the corners can rest within `ε_escape` of their goal while a stacked task is not converged.
        let goal_missed = self
            .stacked
            .iter()
            .any(|&t| tasks[t].error().norm() > goal_error)
            || self
                .reserve
                .is_some_and(|reserve| tasks[reserve].error().norm() > parameters.escape_error);
        if !goal_missed {
            return None;
        }
        let first = *self.stacked.first()?;
        let centre = self.recentring_targets(q)?;
        let joints = self.recentred_joints(locked, q)?;
        self.phase = Phase::Recentring {
            joints,
            centre,
            since: time,
        };
        self.escaped = false;
        self.next_push = first + 1;
        // One change: every task taken out is logged at this iteration, in priority order.
        let stacked = std::mem::take(&mut self.stacked);
        for &task in &stacked[1..] {
            self.record(StackEvent {
                iteration,
                time,
                kind: EventKind::Restart,
                task,
                law_jump: 0.0,
                removal: None,
                reinsertion: None,
            });
        }
        self.stacked = stacked;
        self.stacked.truncate(1);
        Some(EventKind::Restart)
    }

    /// D29: the joints a restart recentres: the `locked` ones; every joint with finite limits when the same joints
    /// are locked at the same limits as at the previous restart and [`ControllerParameters::recentre_all_on_repeat`]
    /// is set (the replay from the same recentring came back to the same rest). Remembers this restart's locks.
    fn recentred_joints(&mut self, locked: [bool; N], q: &JointVector<N>) -> Option<[bool; N]> {
        let limits = self.limits.as_ref()?;
        let locks: [LockedAt; N] = std::array::from_fn(|i| {
            if !locked[i] {
                LockedAt::Free
            } else if q[i] > 0.5 * (limits.lower()[i] + limits.upper()[i]) {
                LockedAt::Upper
            } else {
                LockedAt::Lower
            }
        });
        let repeated = self.last_restart_locks == Some(locks);
        self.last_restart_locks = Some(locks);
        if !(repeated && self.parameters.recentre_all_on_repeat) {
            return Some(locked);
        }
        Some(std::array::from_fn(|i| {
            limits.lower()[i].is_finite() && limits.upper()[i].is_finite()
        }))
    }

    /// D29: each joint's recentring target: the middle of its range `q̄_i`, past it for a joint whose range exceeds a
    /// half turn, `q̂_i = q̄_i − s_restart · sign(q_i − q̄_i) · π/2` (away from the side it is on; a joint at its
    /// middle stays there). An unlimited joint (D18) is never locked and has no middle: its entry is `q_i`, so that
    /// the recentring term's unweighted entries stay finite.
    fn recentring_targets(&self, q: &JointVector<N>) -> Option<JointVector<N>> {
        let limits = self.limits.as_ref()?;
        let offset = self.parameters.restart_offset;
        Some(JointVector::from_fn(|i, _| {
            let (lower, upper) = (limits.lower()[i], limits.upper()[i]);
            if !(lower.is_finite() && upper.is_finite()) {
                return q[i];
            }
            let middle = 0.5 * (lower + upper);
            let side = q[i] - middle;
            if upper - lower <= PI || side == 0.0 {
                return middle;
            }
            middle - offset * side.signum() * FRAC_PI_2
        }))
    }

    /// D29: every recentred joint within `b_restart Δq_i` of its target.
    pub(super) fn recentred(
        &self,
        joints: &[bool; N],
        centre: &JointVector<N>,
        q: &JointVector<N>,
    ) -> bool {
        let Some(limits) = &self.limits else {
            return true;
        };
        let band = self.parameters.restart_centre_band;
        (0..N).all(|i| {
            let (lower, upper) = (limits.lower()[i], limits.upper()[i]);
            !joints[i] || (q[i] - centre[i]).abs() <= band * (upper - lower)
        })
    }

    /// D29: while a restart recentres joints, the cost whose gradient the law descends.
    pub(super) fn recentring_cost<'a>(
        &self,
        law: &ControlLaw,
        cost: Option<&'a dyn Cost<N>>,
    ) -> Option<RecentringCost<'a, N>> {
        let Phase::Recentring { joints, centre, .. } = self.phase else {
            return None;
        };
        let avoidance = cost?;
        let kappa = law.avoidance_gain();
        if kappa <= 0.0 {
            return None;
        }
        let weight = self.parameters.restart_rate / kappa;
        Some(RecentringCost {
            avoidance,
            centre,
            weights: JointVector::from_fn(|i, _| if joints[i] { weight } else { 0.0 }),
        })
    }
}

/// D29: where a joint was at a restart: free, or locked at its lower or upper limit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum LockedAt {
    Free,
    Lower,
    Upper,
}

/// D29: the avoidance cost `h` with the restart's recentring term in its gradient only,
/// `∇h + W (q − q̂)` with `W = diag(k_restart/κ)` over the recentred joints and `q̂` their targets: the law's
/// term `−κ P^A_n (∇h + W (q − q̂))` moves each recentred joint towards `q̂_i` at the rate `k_restart`, within the stack's
/// null space. Its value is `h` alone: the controller's decisions (removal, re-insertion, prediction) see the
/// avoidance cost, not the recentring.
pub(super) struct RecentringCost<'a, const N: usize> {
    pub(super) avoidance: &'a dyn Cost<N>,
    pub(super) centre: JointVector<N>,
    pub(super) weights: JointVector<N>,
}

impl<const N: usize> Cost<N> for RecentringCost<'_, N> {
    fn value(&self, q: &JointVector<N>) -> Result<f64, CostError> {
        self.avoidance.value(q)
    }

    fn value_and_gradient(
        &self,
        q: &JointVector<N>,
        gradient: &mut JointVector<N>,
    ) -> Result<f64, CostError> {
        let value = self.avoidance.value_and_gradient(q, gradient)?;
        *gradient += self.weights.component_mul(&(q - self.centre));
        Ok(value)
    }

    fn name(&self) -> &str {
        self.avoidance.name()
    }

    fn dominant_term(&self, q: &JointVector<N>) -> Result<&str, CostError> {
        self.avoidance.dominant_term(q)
    }

    fn default_removal_threshold(&self) -> Option<f64> {
        self.avoidance.default_removal_threshold()
    }

    fn forbids(&self, q: &JointVector<N>) -> bool {
        self.avoidance.forbids(q)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::{FRAC_PI_4, TAU};

    /// Joint 0 spans 2 rad (less than a half turn), joint 1 two turns, joint 2 4 rad (more than a half turn).
    fn controller(offset: f64) -> StackController<3> {
        let parameters = ControllerParameters {
            restart_offset: offset,
            ..ControllerParameters::default()
        };
        let limits = JointLimits::new(
            JointVector::<3>::new(-1.0, -TAU, 0.0),
            JointVector::<3>::new(1.0, TAU, 4.0),
            0.1,
        )
        .unwrap();
        StackController::new(parameters, &[])
            .unwrap()
            .with_joint_limits(limits)
            .unwrap()
    }

    #[test]
    fn joints_wider_than_a_half_turn_are_sent_past_the_middle_the_others_to_it() {
        // Joint 0 near its upper limit, joint 1 on its lower side, joint 2 on its upper side.
        let q = JointVector::<3>::new(0.9, -5.0, 3.9);
        let targets = controller(0.5).recentring_targets(&q).unwrap();
        // The narrow joint to its middle 0; the wide ones half a quarter turn (π/4) past their middles 0 and 2.
        assert!(targets[0].abs() < 1e-12, "{targets}");
        assert!((targets[1] - FRAC_PI_4).abs() < 1e-12, "{targets}");
        assert!((targets[2] - (2.0 - FRAC_PI_4)).abs() < 1e-12, "{targets}");
        // A wide joint exactly at its middle stays there; offset 0 gives the middles, as the restart first specified.
        let at_middle = JointVector::<3>::new(0.9, 0.0, 2.0);
        assert_eq!(
            controller(0.5).recentring_targets(&at_middle).unwrap(),
            JointVector::<3>::new(0.0, 0.0, 2.0)
        );
        let middles = controller(0.0).recentring_targets(&q).unwrap();
        assert_eq!(middles, JointVector::<3>::new(0.0, 0.0, 2.0));
    }

    #[test]
    fn a_restart_that_finds_the_same_locks_again_recentres_every_limited_joint() {
        let mut controller = controller(0.5);
        let locked = [true, false, false];
        let at_upper = JointVector::<3>::new(1.0, -5.0, 3.9);
        let at_lower = JointVector::<3>::new(-1.0, -5.0, 3.9);
        // The first restart recentres the locked joint alone; so does the next, the same joint at its other limit.
        assert_eq!(controller.recentred_joints(locked, &at_upper), Some(locked));
        assert_eq!(controller.recentred_joints(locked, &at_lower), Some(locked));
        // The same joint at the same limit again: every joint.
        assert_eq!(
            controller.recentred_joints(locked, &at_lower),
            Some([true; 3])
        );
        // Other joints locked: the locked ones alone again.
        let other = [true, false, true];
        assert_eq!(controller.recentred_joints(other, &at_lower), Some(other));
        // Switched off, a repeated restart recentres the locked joints alone.
        let mut off = controller.clone();
        off.parameters.recentre_all_on_repeat = false;
        assert_eq!(off.recentred_joints(other, &at_lower), Some(other));
        // A joint without limits (D18) is never recentred.
        let limits = JointLimits::new(
            JointVector::<2>::new(-1.0, f64::NEG_INFINITY),
            JointVector::<2>::new(1.0, f64::INFINITY),
            0.1,
        )
        .unwrap();
        let mut unlimited = StackController::new(ControllerParameters::default(), &[])
            .unwrap()
            .with_joint_limits(limits)
            .unwrap();
        let q = JointVector::<2>::new(1.0, 12.0);
        assert_eq!(
            unlimited.recentred_joints([true, false], &q),
            Some([true, false])
        );
        assert_eq!(
            unlimited.recentred_joints([true, false], &q),
            Some([true, false])
        );
    }

    #[test]
    fn the_goal_error_is_a_finite_positive_threshold() {
        for bad in [0.0, -1e-4, f64::NAN, f64::INFINITY] {
            let result = controller(0.5).with_goal_error(bad);
            assert!(
                matches!(
                    result,
                    Err(ControllerError::InvalidParameter {
                        name: "goal error",
                        ..
                    })
                ),
                "{bad}"
            );
        }
        assert_eq!(
            controller(0.5).with_goal_error(1e-3).unwrap().goal_error,
            1e-3
        );
    }

    #[test]
    fn a_joint_counts_as_recentred_at_its_target_not_at_the_middle() {
        let controller = controller(0.5);
        let joints = [true, false, false];
        let target = JointVector::<3>::new(-0.5, 0.0, 0.0);
        // The band is 0.05 of joint 0's 2 rad range: 0.1 rad around the target.
        let near = JointVector::<3>::new(-0.45, 3.0, 3.9);
        let middle = JointVector::<3>::new(0.0, 0.0, 2.0);
        assert!(controller.recentred(&joints, &target, &near));
        assert!(!controller.recentred(&joints, &target, &middle));
    }

    #[test]
    fn an_unlimited_joint_leaves_the_recentring_term_finite() {
        // Joint 1 is a continuous joint without limits (D18); joint 0 is the locked one.
        let limits = JointLimits::new(
            JointVector::<2>::new(-1.0, f64::NEG_INFINITY),
            JointVector::<2>::new(1.0, f64::INFINITY),
            0.1,
        )
        .unwrap();
        let controller = StackController::new(ControllerParameters::default(), &[])
            .unwrap()
            .with_joint_limits(limits.clone())
            .unwrap();
        let q = JointVector::<2>::new(0.95, 12.0);
        let centre = controller.recentring_targets(&q).unwrap();
        assert_eq!(centre, JointVector::<2>::new(0.0, 12.0));
        let cost = RecentringCost {
            avoidance: &limits,
            centre,
            weights: JointVector::<2>::new(1.0, 0.0),
        };
        let mut gradient = JointVector::<2>::zeros();
        cost.value_and_gradient(&q, &mut gradient).unwrap();
        assert!(gradient.iter().all(|g| g.is_finite()), "{gradient}");
        // The locked joint is pulled towards its middle: the recentring adds 1 · (0.95 − 0) to the limit term.
        let mut alone = JointVector::<2>::zeros();
        limits.value_and_gradient(&q, &mut alone).unwrap();
        assert!((gradient[0] - alone[0] - 0.95).abs() < 1e-12);
    }
}
