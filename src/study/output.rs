//! A study's files and tables: `study.json` (every draw), `summary.json` (per family and method), a Markdown table
//! and the printed success table, written the same way by a study run whole, by its shards and by their merge
//! ([`StudyResult::merge`]).

use super::{StudyResult, AT_LIMIT_MARGIN, POSE_TOLERANCE_DEG, POSE_TOLERANCE_M};
use crate::scenario::RunKind;
use std::path::Path;

impl StudyResult {
    /// The per-family summary without the draws (`summary.json`): scenario, seed, draws per family, budget, the shard
    /// when the result is one, per family its summaries, then iterations, seconds and threads.
    pub fn summary_json(&self) -> serde_json::Value {
        let families: Vec<_> = self
            .families
            .iter()
            .map(|f| {
                serde_json::json!({
                    "family": f.family,
                    "methods": f.methods,
                    "any_baseline_converged": f.any_baseline_converged,
                    "full_method_also_converged": f.full_method_also_converged,
                    "full_method_worse_than_stack_gradient": f.full_method_worse_than_stack_gradient,
                    "baseline_wins_at_limit": f.baseline_wins_at_limit,
                    "full_method_also_converged_at_limit": f.full_method_also_converged_at_limit,
                })
            })
            .collect();
        let mut summary = serde_json::json!({
            "scenario": self.scenario,
            "seed": self.seed,
            "draws_per_family": self.draws_per_family,
            "budget": self.budget,
            "families": families,
            "iterations": self.iterations,
            "seconds": self.seconds,
            "threads": self.threads,
        });
        if let (Some(shard), Some(map)) = (self.shard, summary.as_object_mut()) {
            map.insert("shard".into(), serde_json::json!(shard));
        }
        summary
    }

    /// Writes `study.json` (compact) and `summary.json` (pretty) into `dir`, creating it.
    ///
    /// # Errors
    /// The I/O error of a directory or file that cannot be written.
    pub fn write_files(&self, dir: &Path) -> std::io::Result<()> {
        std::fs::create_dir_all(dir)?;
        std::fs::write(dir.join("study.json"), serde_json::to_string(self)?)?;
        std::fs::write(
            dir.join("summary.json"),
            serde_json::to_string_pretty(&self.summary_json())?,
        )
    }

    /// The success table in Markdown: one row per family, the draws each method converged in, then the full method's
    /// coverage of the draws a baseline won and its *off goal* runs (the columns of the tables of `docs/convergence_domain.md`).
    pub fn markdown_table(&self) -> String {
        let Some(first) = self.families.first() else {
            return String::new();
        };
        let mut table = String::from("| family |");
        for m in &first.methods {
            table.push_str(&format!(" {} |", m.method.name()));
        }
        table.push_str(" covered | worse | off goal | straight-feasible | p95 / budget |\n|---|");
        table.push_str(&"---|".repeat(first.methods.len() + 5));
        table.push('\n');
        for family in &self.families {
            table.push_str(&format!("| {} |", family.family.name));
            for m in &family.methods {
                table.push_str(&format!(" {} |", m.converged));
            }
            let full = family
                .methods
                .iter()
                .find(|m| m.method == RunKind::FullMethod);
            let off_goal = full.map_or("-".into(), |m| {
                m.outcomes.get("off_goal").copied().unwrap_or(0).to_string()
            });
            table.push_str(&format!(
                " {}/{} | {} | {off_goal} | {} | {} |\n",
                family.full_method_also_converged,
                family.any_baseline_converged,
                family.full_method_worse_than_stack_gradient,
                family.straight_feasible_text(),
                self.p95_text(full)
            ));
        }
        table
    }

    /// The full method's 95th percentile of iterations to converge as a share of the budget (`0.62`), the count when
    /// the budget is unknown, `-` without the full method or a converged run.
    fn p95_text(&self, full: Option<&super::MethodSummary>) -> String {
        match full.and_then(|m| m.p95_iterations_to_converge) {
            Some(p95) if self.budget > 0 => format!("{:.2}", p95 as f64 / self.budget as f64),
            Some(p95) => p95.to_string(),
            None => "-".into(),
        }
    }
}

impl std::fmt::Display for StudyResult {
    /// The success table: per family, the draws each method converged in; then the full method's removals and how it
    /// compares with its baselines on the same draws.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(
            f,
            "convergence domain of {} ({} draws per family, seed {})",
            self.scenario, self.draws_per_family, self.seed
        )?;
        let Some(first) = self.families.first() else {
            return Ok(());
        };
        write!(f, "{:<12}", "family")?;
        for m in &first.methods {
            write!(f, " {:>17}", m.method.name())?;
        }
        writeln!(
            f,
            " {:>10} {:>9} {:>9} {:>9} {:>8} {:>9} {:>9} {:>9} {:>9} {:>16} {:>8}",
            "removals",
            "per task",
            "fallback",
            "restarts",
            "covered",
            "at limit",
            "worse",
            "off goal",
            "pose",
            "straight",
            "p95 iter"
        )?;
        for family in &self.families {
            write!(f, "{:<12}", family.family.name)?;
            for m in &family.methods {
                write!(f, " {:>17}", format!("{}/{}", m.converged, m.draws))?;
            }
            let full = family
                .methods
                .iter()
                .find(|m| m.method == RunKind::FullMethod);
            writeln!(
                f,
                " {:>10} {:>9} {:>9} {:>9} {:>8} {:>9} {:>9} {:>9} {:>9} {:>16} {:>8}",
                full.map_or("-".into(), |m| format!("{}", m.median_removals)),
                full.map_or("-".into(), |m| format!("{}", m.median_removals_of_a_task)),
                full.map_or("-".into(), |m| m.fallbacks.to_string()),
                full.map_or("-".into(), |m| format!(
                    "{} ({})",
                    m.restarts, m.median_take_outs_of_a_task
                )),
                format!(
                    "{}/{}",
                    family.full_method_also_converged, family.any_baseline_converged
                ),
                format!(
                    "{}/{}",
                    family.full_method_also_converged_at_limit, family.baseline_wins_at_limit
                ),
                family.full_method_worse_than_stack_gradient,
                full.map_or("-".into(), |m| m
                    .outcomes
                    .get("off_goal")
                    .copied()
                    .unwrap_or(0)
                    .to_string()),
                full.map_or("-".into(), |m| m
                    .converged_within_pose_tolerance
                    .to_string()),
                family.straight_feasible_text(),
                self.p95_text(full)
            )?;
        }
        writeln!(
            f,
            "removals: median per run of the full method; per task: median over runs of the most removals of one task; \
             restarts: runs of the full method that restarted their sequence (in brackets, per task counting a restart's \
             taking a task out as a removal); \
             covered: draws where the full method converged among those \
             where a baseline did; at limit: of those, the draws where every baseline that converged came within \
             {} of a joint's range of a hard limit on the way (covered/of them); worse: draws where stack_gradient converged and the full method did not; off goal: \
             runs of the full method whose task errors settled with the camera away from its goal pose (not \
             converged); pose: converged runs of the full method whose camera ended within {} mm / {}° of its goal; \
             straight: draws the full method converged in among the straight-feasible ones (the straight joint path to \
             the goal keeps the target in view and the joints in their limits), with the 95 % lower confidence bound \
             of that share; p95 iter: the 95th percentile of the iterations the full method's converged runs took, as a \
             share of the budget of {} iterations",
            AT_LIMIT_MARGIN,
            POSE_TOLERANCE_M * 1e3,
            POSE_TOLERANCE_DEG,
            self.budget
        )?;
        let rate = self.iterations as f64 / self.seconds.max(1e-9);
        writeln!(
            f,
            "{} control iterations in {:.1} s on {} threads ({:.0} iterations/s)",
            self.iterations, self.seconds, self.threads, rate
        )
    }
}
