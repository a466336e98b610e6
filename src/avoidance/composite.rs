//! A sum of costs: `h(q) = Σ_k h_k(q)`, `∇h = Σ_k ∇h_k` ([theory §4](crate::theory#s4): the projected gradient of the sum pushes away from
//! every danger at once; a sum of C¹ potentials is C¹).

use super::{checked_cost, Cost, CostError};
use crate::math::JointVector;

/// The sum of several costs (joint limits, obstacles, visibility, ...), built once. Terms may be owned
/// (`Box::new(limits)`) or borrowed (`Box::new(&limits)`), for the lifetime `'a`. Evaluating it allocates nothing
/// beyond what its terms do.
///
/// ```
/// use servostack::avoidance::{CompositeCost, Cost, JointLimits};
/// use nalgebra::Vector2;
///
/// let a = JointLimits::new(Vector2::new(-1.0, -1.0), Vector2::new(1.0, 1.0), 0.1)?;
/// let b = JointLimits::new(Vector2::new(-2.0, -0.5), Vector2::new(2.0, 0.5), 0.1)?;
/// let both = CompositeCost::new().with(&a).with(&b);
/// let q = Vector2::new(0.0, 0.45);
/// assert_eq!(both.value(&q)?, a.value(&q)? + b.value(&q)?);
/// let mut values = [0.0; 2];
/// both.term_values(&q, &mut values)?;
/// assert_eq!(values, [a.value(&q)?, b.value(&q)?]);
/// # Ok::<(), servostack::avoidance::CostError>(())
/// ```
#[derive(Default)]
pub struct CompositeCost<'a, const N: usize> {
    terms: Vec<Box<dyn Cost<N> + 'a>>,
}

impl<const N: usize> std::fmt::Debug for CompositeCost<'_, N> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_list()
            .entries(self.terms.iter().map(|t| t.name()))
            .finish()
    }
}

impl<'a, const N: usize> CompositeCost<'a, N> {
    /// An empty sum (`h = 0`).
    pub fn new() -> Self {
        Self { terms: Vec::new() }
    }

    /// The sum with one more term.
    pub fn with(mut self, term: impl Cost<N> + 'a) -> Self {
        self.push(term);
        self
    }

    /// Adds a term.
    pub fn push(&mut self, term: impl Cost<N> + 'a) {
        self.terms.push(Box::new(term));
    }

    /// The number of terms.
    pub fn len(&self) -> usize {
        self.terms.len()
    }

    /// `true` without any term.
    pub fn is_empty(&self) -> bool {
        self.terms.is_empty()
    }

    /// The names of the terms, in order.
    pub fn term_names(&self) -> impl Iterator<Item = &str> {
        self.terms.iter().map(|t| t.name())
    }

    /// Each term's value `h_k(q)`, written into `values` (one per term, in order).
    ///
    /// # Errors
    /// [`CostError::LengthMismatch`] unless `values` has one entry per term; a term's error.
    pub fn term_values(&self, q: &JointVector<N>, values: &mut [f64]) -> Result<(), CostError> {
        if values.len() != self.terms.len() {
            return Err(CostError::LengthMismatch {
                what: "term values",
                expected: self.terms.len(),
                found: values.len(),
            });
        }
        for (term, value) in self.terms.iter().zip(values.iter_mut()) {
            *value = term.value(q)?;
        }
        Ok(())
    }
}

impl<const N: usize> Cost<N> for CompositeCost<'_, N> {
    /// `Σ_k h_k(q)`.
    fn value(&self, q: &JointVector<N>) -> Result<f64, CostError> {
        let value = self
            .terms
            .iter()
            .try_fold(0.0, |sum, t| Ok::<_, CostError>(sum + t.value(q)?))?;
        checked_cost::<N>(self.name(), value, None)
    }

    /// `Σ_k h_k(q)` and `Σ_k ∇h_k(q)`.
    fn value_and_gradient(
        &self,
        q: &JointVector<N>,
        gradient: &mut JointVector<N>,
    ) -> Result<f64, CostError> {
        gradient.fill(0.0);
        let mut term_gradient = JointVector::<N>::zeros();
        let mut value = 0.0;
        for term in &self.terms {
            value += term.value_and_gradient(q, &mut term_gradient)?;
            *gradient += term_gradient;
        }
        checked_cost(self.name(), value, Some(gradient))
    }

    fn name(&self) -> &str {
        "composite"
    }

    /// The name of the term with the largest value at `q` (the first on ties; `"composite"` without terms). A term
    /// that cannot be evaluated at `q` because a target point would be at or behind the camera
    /// ([`CostError::PointBehindCamera`]) counts as infinite there, as the stack controller counts such a prediction:
    /// it is named, not passed on as an error.
    fn dominant_term(&self, q: &JointVector<N>) -> Result<&str, CostError> {
        let mut best: Option<(f64, &str)> = None;
        for term in &self.terms {
            let (value, name) = match term.value(q) {
                Err(CostError::PointBehindCamera { .. }) => (f64::INFINITY, term.name()),
                value => (value?, term.dominant_term(q)?),
            };
            if best.is_none_or(|(b, _)| value > b) {
                best = Some((value, name));
            }
        }
        Ok(best.map_or("composite", |(_, name)| name))
    }

    /// The smallest default threshold of the terms that have one.
    fn default_removal_threshold(&self) -> Option<f64> {
        self.terms
            .iter()
            .filter_map(|term| term.default_removal_threshold())
            .reduce(f64::min)
    }

    /// Whether any term forbids `q`.
    fn forbids(&self, q: &JointVector<N>) -> bool {
        self.terms.iter().any(|term| term.forbids(q))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::avoidance::test_support::gradient_error;
    use crate::avoidance::JointLimits;
    use nalgebra::Vector2;

    #[test]
    fn sum_gradient_and_dominant_term() {
        let a = JointLimits::new(Vector2::new(-1.0, -1.0), Vector2::new(1.0, 1.0), 0.1).unwrap();
        let b = JointLimits::new(Vector2::new(-2.0, -0.5), Vector2::new(2.0, 0.5), 0.2).unwrap();
        struct Named<'a>(&'a JointLimits<2>, &'static str);
        impl Cost<2> for Named<'_> {
            fn value(&self, q: &JointVector<2>) -> Result<f64, CostError> {
                self.0.value(q)
            }
            fn value_and_gradient(
                &self,
                q: &JointVector<2>,
                g: &mut JointVector<2>,
            ) -> Result<f64, CostError> {
                self.0.value_and_gradient(q, g)
            }
            fn name(&self) -> &str {
                self.1
            }
        }
        let sum = CompositeCost::new()
            .with(Named(&a, "wide"))
            .with(Named(&b, "narrow"));
        assert_eq!(sum.term_names().collect::<Vec<_>>(), ["wide", "narrow"]);
        // Joint 1 at 0.45: inside a's box (threshold 0.8), 0.15 into b's band (threshold 0.3).
        let q = Vector2::new(0.0, 0.45);
        assert!((sum.value(&q).unwrap() - 0.5 * 0.15f64.powi(2)).abs() < 1e-15);
        assert_eq!(sum.dominant_term(&q).unwrap(), "narrow");
        // Joint 0 at 0.95: 0.15 into a's band (range 2), inside b's box.
        let q = Vector2::new(0.95, 0.0);
        assert!((sum.value(&q).unwrap() - 0.5 * 0.15f64.powi(2) / 2.0).abs() < 1e-15);
        assert_eq!(sum.dominant_term(&q).unwrap(), "wide");
        for q in [Vector2::new(0.93, 0.41), Vector2::new(-0.97, -0.49)] {
            assert!(gradient_error(&sum, &q, 1e-6) < 1e-8);
        }
        assert_eq!(CompositeCost::<2>::new().value(&q).unwrap(), 0.0);
        assert_eq!(
            CompositeCost::<2>::new().dominant_term(&q).unwrap(),
            "composite"
        );
    }

    /// A configuration is forbidden when any term forbids it: beyond b's hard limit on joint 1 (0.5) but inside a's.
    #[test]
    fn forbidden_where_any_term_forbids() {
        let a = JointLimits::new(Vector2::new(-1.0, -1.0), Vector2::new(1.0, 1.0), 0.1).unwrap();
        let b = JointLimits::new(Vector2::new(-2.0, -0.5), Vector2::new(2.0, 0.5), 0.2).unwrap();
        let sum = CompositeCost::new().with(&a).with(&b);
        assert!(!sum.forbids(&Vector2::new(0.99, 0.5)));
        assert!(sum.forbids(&Vector2::new(0.0, 0.51)));
        assert!(sum.forbids(&Vector2::new(-1.01, 0.0)));
        assert!(!CompositeCost::<2>::new().forbids(&Vector2::new(5.0, 5.0)));
    }
}
