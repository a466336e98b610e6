//! A study's files: `study.json` (every draw), `summary.json` (per family and method) and a Markdown table, written
//! the same way by a study run whole, by its shards and by their merge ([`StudyResult::merge`]).

use super::StudyResult;
use crate::scenario::RunKind;
use std::path::Path;

impl StudyResult {
    /// The per-family summary without the draws (`summary.json`): scenario, seed, draws per family, the shard when
    /// the result is one, per family its summaries, then iterations, seconds and threads.
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
        table.push_str(" covered | worse | off goal | straight-feasible |\n|---|");
        table.push_str(&"---|".repeat(first.methods.len() + 4));
        table.push('\n');
        for family in &self.families {
            table.push_str(&format!("| {} |", family.family.name));
            for m in &family.methods {
                table.push_str(&format!(" {} |", m.converged));
            }
            let off_goal = family
                .methods
                .iter()
                .find(|m| m.method == RunKind::StackController)
                .map_or("-".into(), |m| {
                    m.outcomes.get("off_goal").copied().unwrap_or(0).to_string()
                });
            table.push_str(&format!(
                " {}/{} | {} | {off_goal} | {} |\n",
                family.full_method_also_converged,
                family.any_baseline_converged,
                family.full_method_worse_than_stack_gradient,
                family.straight_feasible_text()
            ));
        }
        table
    }
}
