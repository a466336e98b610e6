//! One field of a scenario changed by its dotted path, as a sweep or an ablation of the study needs it: a value set
//! (`controller.restart_rate = 0` switches the restart off) or a number scaled (`controller.braking_rate × 1.3`), the
//! field's default used when the file leaves it out. The changed scenario goes through the same parser, so a value
//! of the wrong type or an unknown field is the same named error as in a file.

use super::{invalid, Scenario, ScenarioError};

impl Scenario {
    /// The scenario with the field at `path` (dotted, `controller.early_push_ratio`) set to `value`, a TOML value
    /// (`inf`, `0`, `false`, `"paper"`, `[0.5, 0.5]`).
    ///
    /// # Errors
    /// [`ScenarioError::Invalid`] for a value that is not TOML or a path through a field that is not a table;
    /// [`ScenarioError::Syntax`] for a field the scenario does not have or a value of the wrong type.
    pub fn with_field(&self, path: &str, value: &str) -> Result<Self, ScenarioError> {
        let parsed: toml::Table = toml::from_str(&format!("value = {value}"))
            .map_err(|e| invalid(path, format!("`{value}` is not a TOML value: {e}")))?;
        let value = parsed
            .get("value")
            .cloned()
            .ok_or_else(|| invalid(path, "no value"))?;
        self.changed(path, |_| Ok(value))
    }

    /// The scenario with the number at `path` (its value in the file, else its default) multiplied by `factor`. An
    /// integer field stays an integer (rounded).
    ///
    /// # Errors
    /// [`ScenarioError::Invalid`] for a path that leads to no number, or a non-finite factor; then as
    /// [`Self::with_field`].
    pub fn with_field_scaled(&self, path: &str, factor: f64) -> Result<Self, ScenarioError> {
        if !factor.is_finite() {
            return Err(invalid(
                path,
                format!("scale factor {factor} is not finite"),
            ));
        }
        self.changed(path, |current| match current {
            Some(toml::Value::Float(x)) => Ok(toml::Value::Float(x * factor)),
            Some(toml::Value::Integer(i)) => {
                let scaled = (*i as f64 * factor).round();
                if scaled.abs() < 9e15 {
                    Ok(toml::Value::Integer(scaled as i64))
                } else {
                    Err(invalid(path, format!("{i} × {factor} is too large")))
                }
            }
            Some(other) => Err(invalid(path, format!("{other} is not a number"))),
            None => Err(invalid(path, "no such field (or no default to scale)")),
        })
    }

    /// The scenario as TOML with every default filled in, the field at `path` replaced by `change(current value)`,
    /// parsed again.
    fn changed(
        &self,
        path: &str,
        change: impl FnOnce(Option<&toml::Value>) -> Result<toml::Value, ScenarioError>,
    ) -> Result<Self, ScenarioError> {
        let mut root = toml::Table::try_from(self)
            .map_err(|e| invalid(path, format!("the scenario cannot be written as TOML: {e}")))?;
        let (parents, leaf) = match path.rsplit_once('.') {
            Some((parents, leaf)) => (Some(parents), leaf),
            None => (None, path),
        };
        let mut table = &mut root;
        for key in parents.into_iter().flat_map(|p| p.split('.')) {
            table = match table
                .entry(key)
                .or_insert_with(|| toml::Value::Table(toml::Table::new()))
            {
                toml::Value::Table(inner) => inner,
                _ => return Err(invalid(path, format!("`{key}` is not a table"))),
            };
        }
        let value = change(table.get(leaf))?;
        table.insert(leaf.to_owned(), value);
        let mut scenario: Self = toml::Value::Table(root).try_into()?;
        scenario.base_dir.clone_from(&self.base_dir);
        Ok(scenario)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::controller::ControllerParameters;

    const PAPER: &str = include_str!("../../assets/scenarios/paper_afma6.toml");

    #[test]
    fn a_field_is_set_or_scaled_from_its_value_or_its_default() {
        let scenario = Scenario::from_toml_str(PAPER, None).unwrap();
        // In the file: settle_velocity = 0.01.
        let scaled = scenario
            .with_field_scaled("controller.settle_velocity", 1.3)
            .unwrap();
        assert!((scaled.controller.settle_velocity - 0.013).abs() < 1e-15);
        // Not in the file: the default, scaled.
        let braking = ControllerParameters::default().braking_rate;
        let scaled = scenario
            .with_field_scaled("controller.braking_rate", 0.7)
            .unwrap();
        assert_eq!(scaled.controller.braking_rate, braking * 0.7);
        let set = scenario
            .with_field("controller.early_push_ratio", "inf")
            .unwrap();
        assert_eq!(set.controller.early_push_ratio, f64::INFINITY);
        // Everything else is unchanged.
        let mut back = set.clone();
        back.controller.early_push_ratio = scenario.controller.early_push_ratio;
        assert_eq!(
            toml::to_string(&back).unwrap(),
            toml::to_string(&scenario).unwrap()
        );
        let budget = scenario
            .with_field_scaled("simulation.max_iterations", 0.5)
            .unwrap();
        assert_eq!(budget.simulation.max_iterations, 5000);
    }

    #[test]
    fn unknown_fields_and_wrong_types_are_named() {
        let scenario = Scenario::from_toml_str(PAPER, None).unwrap();
        assert!(matches!(
            scenario.with_field("controller.no_such_rule", "1"),
            Err(ScenarioError::Syntax(_))
        ));
        assert!(matches!(
            scenario.with_field("controller.restart_rate", "\"fast\""),
            Err(ScenarioError::Syntax(_))
        ));
        assert!(matches!(
            scenario.with_field("controller.restart_rate", "1 2"),
            Err(ScenarioError::Invalid { .. })
        ));
        assert!(matches!(
            scenario.with_field_scaled("controller.criterion", 2.0),
            Err(ScenarioError::Invalid { .. })
        ));
        assert!(matches!(
            scenario.with_field_scaled("controller.nothing", 2.0),
            Err(ScenarioError::Invalid { .. })
        ));
        assert!(matches!(
            scenario.with_field_scaled("controller.braking_rate", f64::NAN),
            Err(ScenarioError::Invalid { .. })
        ));
        assert!(matches!(
            scenario.with_field("name.inner", "1"),
            Err(ScenarioError::Invalid { .. })
        ));
    }
}
