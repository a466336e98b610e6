//! Depth of the image points without ground truth: where the `Z` of each [`ImagePoint`] comes from, and an online
//! estimator of each point's depth from the known camera motion and the measured image motion.
//!
//! # Depth sources
//!
//! [`DepthSource`] (a task's configuration, serde) names the choice; [`Depths`] carries the data it needs at one control
//! period, and [`assign_depths`] turns measured normalised points and a [`Depths`] into the [`ImagePoint`]s
//! `(x, y, Z)` an [`crate::feature::Observation`] needs.
//!
//! # Online estimator ([`DepthEstimator`])
//!
//! For a point at normalised coordinates `s = (x, y)` with inverse depth `ρ = 1/Z` (1/m) and a camera twist
//! `v = (υ, ω)` (m/s, rad/s, camera frame `c`), the point rows of MATH \[M28\] split into a part proportional to `ρ`
//! and a part that does not depend on it:
//!
//! ```text
//! ṡ = ρ a(s, υ) + b(s, ω)
//! a = (−υx + x υz,  −υy + y υz)                                      (m/s)
//! b = (x y ωx − (1 + x²) ωy + y ωz,  (1 + y²) ωx − x y ωy − x ωz)     (1/s)
//! ρ̇ = ρ² υz + ρ (y ωx − x ωy)                                        (from Ż = −υz − Z (y ωx − x ωy))
//! ```
//!
//! Between two frames at `t₀` and `t₁ = t₀ + Δt`, with the twist `v` applied over `[t₀, t₁]`, the image motion gives
//! one measurement of `ρ` at mid-period, `r = (s₁ − s₀)/Δt − b(s̄, ω) = ρ(t₀ + Δt/2) a(s̄, υ)`, with the midpoint
//! `s̄ = (s₀ + s₁)/2` (second-order accurate). Each point keeps an estimate `ρ̂` and its information `I` (m²/s²), a
//! recursive least-squares estimate with exponential forgetting of time constant `τ` (`memory_s`):
//!
//! ```text
//! predict to mid-period:   ρ̂ ← ρ̂ + (Δt/2) (ρ̂² υz + ρ̂ (ȳ ωx − x̄ ωy)),   I ← I e^{−Δt/τ}
//! correct:                 ρ̂ ← (I ρ̂ + aᵀ r) / (I + aᵀ a),             I ← I + aᵀ a
//! predict to t₁:           ρ̂ ← ρ̂ + (Δt/2) (ρ̂² υz + ρ̂ (y₁ ωx − x₁ ωy))
//! ```
//!
//! With `I = 0` and one update this is the least-squares `ρ̂ = aᵀ r / aᵀ a`. Before any information (`I = 0`) the
//! estimate is the initial depth.
//!
//! **Observability.** `aᵀ a = (υx − x υz)² + (υy − y υz)²` is the squared translational speed across the point's line of
//! sight: the depth is observable only when the camera translates, and not along that line of sight. A pure rotation
//! (`υ = 0`) leaves the estimate unchanged (prediction only); [`DepthEstimator::information`] tells how much has been
//! learnt about each point.
//!
//! Every update is allocation-free: the per-point state is allocated once at construction.

use crate::camera::ImagePoint;
use crate::target::TargetPlane;
use nalgebra::{Point2, Vector6};

/// Errors of the depth sources and the estimator. Each variant carries the offending values.
#[non_exhaustive]
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DepthError {
    /// A parameter is out of range.
    #[error("depth parameter `{name}` = {value} must be finite and > 0")]
    InvalidParameter {
        /// The parameter.
        name: &'static str,
        /// Its value.
        value: f64,
    },
    /// A measured point is NaN or infinite.
    #[error("measured point {index} is not finite: ({x}, {y})")]
    NonFinitePoint {
        /// Index of the point.
        index: usize,
        /// Normalised abscissa.
        x: f64,
        /// Normalised ordinate.
        y: f64,
    },
    /// The camera twist has a NaN or infinite component.
    #[error("camera twist is not finite: {twist:?}")]
    NonFiniteTwist {
        /// The twist `(υ, ω)`.
        twist: [f64; 6],
    },
    /// The time of an update is not after the previous one (or is not finite).
    #[error("time {time} s is not after the previous update at {previous} s")]
    TimeNotIncreasing {
        /// The previous update's time (s).
        previous: f64,
        /// This update's time (s).
        time: f64,
    },
    /// The number of points differs from the one the estimator or the output was built for.
    #[error("{got} points, expected {expected}")]
    PointCountMismatch {
        /// Expected count.
        expected: usize,
        /// Count given.
        got: usize,
    },
    /// A depth (estimated, constant, from the plane or from the desired image) is zero, negative or not finite: the
    /// point would be at or behind the camera. The estimator's state is left as it was before the update.
    #[error("point {index}: depth source gives 1/Z = {inverse_depth} 1/m (zero, negative or not finite)")]
    NonPositiveDepth {
        /// Index of the point.
        index: usize,
        /// The inverse depth `1/Z` it gives (1/m).
        inverse_depth: f64,
    },
}

/// Where the depth of each image point comes from, selectable per task (serde: `{ kind = "desired" }`,
/// `{ kind = "constant", depth_m = 0.5 }`, `{ kind = "previous_plane" }`,
/// `{ kind = "estimated", initial_depth_m = 0.5, memory_s = 0.5 }`).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum DepthSource {
    /// Each point takes its depth in the desired image (a constant per point).
    Desired,
    /// Every point takes the same depth `Z*` (m).
    Constant {
        /// The depth (m, > 0).
        depth_m: f64,
    },
    /// The plane `1/Z = A x + B y + C` of the previous pose estimate of the target.
    PreviousPlane,
    /// The online [`DepthEstimator`] (module docs).
    Estimated {
        /// The depth (m, > 0) used before the motion makes the depth observable.
        initial_depth_m: f64,
        /// The forgetting time constant `τ` (s, > 0).
        memory_s: f64,
    },
}

impl DepthSource {
    /// Checks the parameters.
    ///
    /// # Errors
    /// [`DepthError::InvalidParameter`] for a non-finite or non-positive depth or memory.
    pub fn validate(&self) -> Result<(), DepthError> {
        match *self {
            Self::Desired | Self::PreviousPlane => Ok(()),
            Self::Constant { depth_m } => positive("depth_m", depth_m).map(drop),
            Self::Estimated {
                initial_depth_m,
                memory_s,
            } => {
                positive("initial_depth_m", initial_depth_m)?;
                positive("memory_s", memory_s).map(drop)
            }
        }
    }
}

/// The data a [`DepthSource`] reads at one control period.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Depths<'a> {
    /// [`DepthSource::Desired`]: the desired image, one point per measured point, in the same order.
    Desired(&'a [ImagePoint]),
    /// [`DepthSource::Constant`]: the depth (m).
    Constant(f64),
    /// [`DepthSource::PreviousPlane`]: the plane of the previous pose estimate (camera frame, 1/m).
    Plane(&'a TargetPlane),
    /// [`DepthSource::Estimated`]: the estimator's depths ([`DepthEstimator::depths`]), one per point (m).
    Estimated(&'a [f64]),
}

/// Writes into `out[k]` the image point `(x_k, y_k, Z_k)` of each measured normalised point with the depth that
/// `depths` gives it. Allocates nothing.
///
/// # Errors
/// [`DepthError::PointCountMismatch`] when `out`, or the desired image / estimated depths, do not have one entry per
/// measured point; [`DepthError::NonFinitePoint`]; [`DepthError::NonPositiveDepth`] when a depth is not a finite
/// positive number (for the plane: `A x + B y + C ≤ 0`).
pub fn assign_depths(
    depths: Depths<'_>,
    measured: &[Point2<f64>],
    out: &mut [ImagePoint],
) -> Result<(), DepthError> {
    let expected = measured.len();
    let per_point_len = match depths {
        Depths::Desired(points) => Some(points.len()),
        Depths::Estimated(values) => Some(values.len()),
        Depths::Constant(_) | Depths::Plane(_) => None,
    };
    for got in [Some(out.len()), per_point_len].into_iter().flatten() {
        if got != expected {
            return Err(DepthError::PointCountMismatch { expected, got });
        }
    }
    for (index, (p, o)) in measured.iter().zip(out.iter_mut()).enumerate() {
        if !(p.x.is_finite() && p.y.is_finite()) {
            return Err(DepthError::NonFinitePoint {
                index,
                x: p.x,
                y: p.y,
            });
        }
        let depth = match depths {
            Depths::Desired(points) => points.get(index).map_or(f64::NAN, |d| d.depth),
            Depths::Constant(depth) => depth,
            Depths::Plane(plane) => 1.0 / plane.inverse_depth(p.x, p.y),
            Depths::Estimated(values) => values.get(index).copied().unwrap_or(f64::NAN),
        };
        if !(depth.is_finite() && depth > 0.0) {
            return Err(DepthError::NonPositiveDepth {
                index,
                inverse_depth: 1.0 / depth,
            });
        }
        *o = ImagePoint::new(p.x, p.y, depth);
    }
    Ok(())
}

fn positive(name: &'static str, value: f64) -> Result<f64, DepthError> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(DepthError::InvalidParameter { name, value })
    }
}

/// The estimator's state for one point.
#[derive(Debug, Clone, Copy, PartialEq)]
struct PointState {
    /// The last measured normalised point.
    previous: Point2<f64>,
    /// `ρ̂` (1/m).
    inverse_depth: f64,
    /// `I` (m²/s²).
    information: f64,
}

/// Online estimator of the depth of each tracked point from the camera twist and the image motion (module docs:
/// recursive least squares on `ṡ = ρ a + b`, with prediction by `ρ̇ = ρ² υz + ρ (y ωx − x ωy)`).
#[derive(Debug, Clone, PartialEq)]
pub struct DepthEstimator {
    memory: f64,
    initial_inverse_depth: f64,
    /// Time of the last update (s); `None` before the first.
    time: Option<f64>,
    points: Vec<PointState>,
    depths: Vec<f64>,
}

impl DepthEstimator {
    /// An estimator for `point_count` points, starting from `initial_depth_m` (m) for every point, forgetting with
    /// time constant `memory_s` (s).
    ///
    /// # Errors
    /// [`DepthError::InvalidParameter`] for a non-finite or non-positive depth or memory, or zero points.
    pub fn new(
        point_count: usize,
        initial_depth_m: f64,
        memory_s: f64,
    ) -> Result<Self, DepthError> {
        positive("initial_depth_m", initial_depth_m)?;
        positive("memory_s", memory_s)?;
        if point_count == 0 {
            return Err(DepthError::InvalidParameter {
                name: "point_count",
                value: 0.0,
            });
        }
        let initial_inverse_depth = 1.0 / initial_depth_m;
        Ok(Self {
            memory: memory_s,
            initial_inverse_depth,
            time: None,
            points: vec![
                PointState {
                    previous: Point2::origin(),
                    inverse_depth: initial_inverse_depth,
                    information: 0.0,
                };
                point_count
            ],
            depths: vec![initial_depth_m; point_count],
        })
    }

    /// Starts again from the initial depth, forgetting every measurement (for instance after the target was lost).
    pub fn reset(&mut self) {
        self.time = None;
        for p in &mut self.points {
            p.inverse_depth = self.initial_inverse_depth;
            p.information = 0.0;
        }
        self.depths.fill(1.0 / self.initial_inverse_depth);
    }

    /// One update with the points measured at `time` (s) and the camera twist `(υ, ω)` (m/s, rad/s, camera frame)
    /// applied since the previous update (ignored at the first update, which only stores the points). Returns the
    /// estimated depth of each point (m). Allocates nothing.
    ///
    /// # Errors
    /// [`DepthError::PointCountMismatch`], [`DepthError::NonFinitePoint`], [`DepthError::NonFiniteTwist`],
    /// [`DepthError::TimeNotIncreasing`] (the state is unchanged); [`DepthError::NonPositiveDepth`] when an estimate
    /// would become zero, negative or non-finite (noise larger than the motion): the state is then left as it was
    /// before this update, so the caller may go on with the previous depths.
    pub fn update(
        &mut self,
        time: f64,
        measured: &[Point2<f64>],
        twist: &Vector6<f64>,
    ) -> Result<&[f64], DepthError> {
        if measured.len() != self.points.len() {
            return Err(DepthError::PointCountMismatch {
                expected: self.points.len(),
                got: measured.len(),
            });
        }
        if let Some((index, p)) = measured
            .iter()
            .enumerate()
            .find(|(_, p)| !(p.x.is_finite() && p.y.is_finite()))
        {
            return Err(DepthError::NonFinitePoint {
                index,
                x: p.x,
                y: p.y,
            });
        }
        if !twist.iter().all(|v| v.is_finite()) {
            return Err(DepthError::NonFiniteTwist {
                twist: (*twist).into(),
            });
        }
        let Some(previous_time) = self.time else {
            if !time.is_finite() {
                return Err(DepthError::TimeNotIncreasing {
                    previous: f64::NEG_INFINITY,
                    time,
                });
            }
            for (state, p) in self.points.iter_mut().zip(measured) {
                state.previous = *p;
            }
            self.time = Some(time);
            return Ok(&self.depths);
        };
        let dt = time - previous_time;
        if !(dt.is_finite() && dt > 0.0) {
            return Err(DepthError::TimeNotIncreasing {
                previous: previous_time,
                time,
            });
        }
        // Compute every new state first, commit only when all are valid.
        let forgetting = (-dt / self.memory).exp();
        for (index, (state, p)) in self.points.iter().zip(measured).enumerate() {
            let next = Self::step(state, p, twist, dt, forgetting);
            if !(next.inverse_depth.is_finite() && next.inverse_depth > 0.0) {
                return Err(DepthError::NonPositiveDepth {
                    index,
                    inverse_depth: next.inverse_depth,
                });
            }
        }
        for ((state, depth), p) in self.points.iter_mut().zip(&mut self.depths).zip(measured) {
            *state = Self::step(state, p, twist, dt, forgetting);
            *depth = 1.0 / state.inverse_depth;
        }
        self.time = Some(time);
        Ok(&self.depths)
    }

    /// Predict to mid-period, correct with the image motion, predict to the end (module docs).
    fn step(
        state: &PointState,
        current: &Point2<f64>,
        twist: &Vector6<f64>,
        dt: f64,
        forgetting: f64,
    ) -> PointState {
        let [vx, vy, vz, wx, wy, wz] = [twist[0], twist[1], twist[2], twist[3], twist[4], twist[5]];
        let rate = |rho: f64, x: f64, y: f64| rho * rho * vz + rho * (y * wx - x * wy);
        let (x0, y0) = (state.previous.x, state.previous.y);
        let (x1, y1) = (current.x, current.y);
        let (x, y) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
        let mut rho = state.inverse_depth + 0.5 * dt * rate(state.inverse_depth, x0, y0);
        let a = [-vx + x * vz, -vy + y * vz];
        let b = [
            x * y * wx - (1.0 + x * x) * wy + y * wz,
            (1.0 + y * y) * wx - x * y * wy - x * wz,
        ];
        let r = [(x1 - x0) / dt - b[0], (y1 - y0) / dt - b[1]];
        let aa = a[0] * a[0] + a[1] * a[1];
        let ar = a[0] * r[0] + a[1] * r[1];
        let information = state.information * forgetting;
        let total = information + aa;
        if total > 0.0 {
            rho = (information * rho + ar) / total;
        }
        rho += 0.5 * dt * rate(rho, x1, y1);
        PointState {
            previous: *current,
            inverse_depth: rho,
            information: total,
        }
    }

    /// The current depth estimates (m), one per point.
    pub fn depths(&self) -> &[f64] {
        &self.depths
    }

    /// The information `I` (m²/s², module docs) gathered about point `index`: 0 before any translation across its line
    /// of sight; `None` for an index out of range.
    pub fn information(&self, index: usize) -> Option<f64> {
        self.points.get(index).map(|p| p.information)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn points(xy: &[(f64, f64)]) -> Vec<Point2<f64>> {
        xy.iter().map(|&(x, y)| Point2::new(x, y)).collect()
    }

    /// One translation step along x, by hand: a point at (0, 0), Z = 2 m, camera moving at υx = 0.1 m/s for 0.1 s
    /// moves to x = −0.1·0.1/2 = −0.005 (exact: the point's X becomes −0.01 m at the same Z). The estimate is then
    /// ρ = aᵀr/aᵀa with a = (−0.1, 0), r = (−0.05, 0): ρ = 0.5, Z = 2.
    #[test]
    fn one_translation_step_gives_the_least_squares_depth() {
        let mut estimator = DepthEstimator::new(1, 1.0, 1.0).unwrap();
        let twist = Vector6::new(0.1, 0.0, 0.0, 0.0, 0.0, 0.0);
        estimator
            .update(0.0, &points(&[(0.0, 0.0)]), &twist)
            .unwrap();
        let depths = estimator
            .update(0.1, &points(&[(-0.005, 0.0)]), &twist)
            .unwrap();
        assert!((depths[0] - 2.0).abs() < 1e-12, "{}", depths[0]);
        assert!((estimator.information(0).unwrap() - 0.01).abs() < 1e-15);
    }

    /// A pure rotation carries no depth information: the estimate only follows the known depth dynamics
    /// `Ż = −Z (y ωx − x ωy)`, here `Ż = 0.2 x Z` with a mean x of 0.099 over 0.01 s.
    #[test]
    fn pure_rotation_is_not_observable() {
        let mut estimator = DepthEstimator::new(1, 0.7, 1.0).unwrap();
        let twist = Vector6::new(0.0, 0.0, 0.0, 0.0, 0.2, 0.0);
        estimator
            .update(0.0, &points(&[(0.1, 0.0)]), &twist)
            .unwrap();
        // ẋ = −(1 + x²) ωy.
        let depths = estimator
            .update(0.01, &points(&[(0.1 - 0.01 * 1.01 * 0.2, 0.0)]), &twist)
            .unwrap();
        let x_mean: f64 = 0.1 - 0.005 * 1.01 * 0.2;
        // Exact: Z = 0.7 exp(0.2 · 0.01 · x̄); two explicit half steps are within 2e−8 of it (change 1.4e−4).
        let exact = 0.7 * (0.01 * 0.2 * x_mean).exp();
        assert!((depths[0] - exact).abs() < 2e-8, "{} vs {exact}", depths[0]);
        assert_eq!(estimator.information(0), Some(0.0));
    }

    #[test]
    fn bad_inputs_are_named_errors() {
        assert!(matches!(
            DepthEstimator::new(4, 0.0, 1.0),
            Err(DepthError::InvalidParameter {
                name: "initial_depth_m",
                ..
            })
        ));
        assert!(matches!(
            DepthEstimator::new(4, 0.5, f64::NAN),
            Err(DepthError::InvalidParameter {
                name: "memory_s",
                ..
            })
        ));
        assert!(matches!(
            DepthEstimator::new(0, 0.5, 1.0),
            Err(DepthError::InvalidParameter {
                name: "point_count",
                ..
            })
        ));
        let mut estimator = DepthEstimator::new(1, 0.5, 1.0).unwrap();
        let still = Vector6::zeros();
        assert_eq!(
            estimator
                .update(0.0, &points(&[(0.0, 0.0), (0.1, 0.0)]), &still)
                .err(),
            Some(DepthError::PointCountMismatch {
                expected: 1,
                got: 2
            })
        );
        assert!(matches!(
            estimator.update(0.0, &points(&[(f64::NAN, 0.0)]), &still),
            Err(DepthError::NonFinitePoint { index: 0, .. })
        ));
        assert!(matches!(
            estimator.update(f64::NAN, &points(&[(0.0, 0.0)]), &still),
            Err(DepthError::TimeNotIncreasing { .. })
        ));
        estimator
            .update(1.0, &points(&[(0.0, 0.0)]), &still)
            .unwrap();
        let mut nan_twist = still;
        nan_twist[4] = f64::INFINITY;
        assert!(matches!(
            estimator.update(1.1, &points(&[(0.0, 0.0)]), &nan_twist),
            Err(DepthError::NonFiniteTwist { .. })
        ));
        for time in [1.0, 0.9] {
            assert_eq!(
                estimator.update(time, &points(&[(0.0, 0.0)]), &still).err(),
                Some(DepthError::TimeNotIncreasing {
                    previous: 1.0,
                    time
                })
            );
        }
        // The image moves the wrong way for the translation: the estimate would be negative. Rejected, state kept.
        let forward = Vector6::new(0.1, 0.0, 0.0, 0.0, 0.0, 0.0);
        assert!(matches!(
            estimator.update(1.1, &points(&[(0.01, 0.0)]), &forward),
            Err(DepthError::NonPositiveDepth { index: 0, .. })
        ));
        assert_eq!(estimator.depths(), [0.5]);
        assert_eq!(estimator.information(0), Some(0.0));
        // The next valid update still refers to the last accepted time and points.
        let depths = estimator
            .update(1.1, &points(&[(-0.005, 0.0)]), &forward)
            .unwrap();
        assert!((depths[0] - 2.0).abs() < 1e-12);
    }

    #[test]
    fn depths_are_assigned_from_each_source() {
        let measured = points(&[(0.1, -0.2), (-0.3, 0.05)]);
        let mut out = [ImagePoint::default(); 2];
        assign_depths(Depths::Constant(0.5), &measured, &mut out).unwrap();
        assert_eq!(
            out,
            [
                ImagePoint::new(0.1, -0.2, 0.5),
                ImagePoint::new(-0.3, 0.05, 0.5)
            ]
        );
        // 1/Z = 1·x + 2·y + 2.5: 2.2 and 2.3.
        let plane = TargetPlane {
            a: 1.0,
            b: 2.0,
            c: 2.5,
        };
        assign_depths(Depths::Plane(&plane), &measured, &mut out).unwrap();
        assert!(
            (out[0].depth - 1.0 / 2.2).abs() < 1e-15 && (out[1].depth - 1.0 / 2.3).abs() < 1e-15
        );
        let desired = [
            ImagePoint::new(0.0, 0.0, 0.4),
            ImagePoint::new(0.0, 0.0, 0.6),
        ];
        assign_depths(Depths::Desired(&desired), &measured, &mut out).unwrap();
        assert_eq!((out[0].depth, out[1].depth), (0.4, 0.6));
        assign_depths(Depths::Estimated(&[0.7, 0.8]), &measured, &mut out).unwrap();
        assert_eq!((out[0].x, out[0].depth, out[1].depth), (0.1, 0.7, 0.8));
    }

    #[test]
    fn bad_depths_are_named_errors() {
        let measured = points(&[(0.1, -0.2), (-0.3, 0.05)]);
        let mut out = [ImagePoint::default(); 2];
        assert_eq!(
            assign_depths(Depths::Constant(0.5), &measured, &mut out[..1]),
            Err(DepthError::PointCountMismatch {
                expected: 2,
                got: 1
            })
        );
        assert_eq!(
            assign_depths(Depths::Estimated(&[0.5]), &measured, &mut out),
            Err(DepthError::PointCountMismatch {
                expected: 2,
                got: 1
            })
        );
        assert!(matches!(
            assign_depths(Depths::Constant(-0.5), &measured, &mut out),
            Err(DepthError::NonPositiveDepth { index: 0, .. })
        ));
        assert!(matches!(
            assign_depths(Depths::Estimated(&[0.5, 0.0]), &measured, &mut out),
            Err(DepthError::NonPositiveDepth { index: 1, .. })
        ));
        // 1/Z = 10 x + 0.5 is negative at x = −0.3.
        let behind = TargetPlane {
            a: 10.0,
            b: 0.0,
            c: 0.5,
        };
        assert!(matches!(
            assign_depths(Depths::Plane(&behind), &measured, &mut out),
            Err(DepthError::NonPositiveDepth { index: 1, .. })
        ));
        let nan = points(&[(0.1, f64::NAN), (0.0, 0.0)]);
        assert!(matches!(
            assign_depths(Depths::Constant(0.5), &nan, &mut out),
            Err(DepthError::NonFinitePoint { index: 0, .. })
        ));
        assert!(DepthSource::Constant { depth_m: 0.0 }.validate().is_err());
        assert!(DepthSource::Estimated {
            initial_depth_m: 0.5,
            memory_s: -1.0
        }
        .validate()
        .is_err());
        assert!(DepthSource::Estimated {
            initial_depth_m: 0.5,
            memory_s: 1.0
        }
        .validate()
        .is_ok());
    }

    #[test]
    fn depth_sources_read_from_toml() {
        #[derive(serde::Deserialize)]
        struct Wrapper {
            depth: DepthSource,
        }
        let parsed: Wrapper =
            toml::from_str("depth = { kind = \"constant\", depth_m = 0.5 }").unwrap();
        assert_eq!(parsed.depth, DepthSource::Constant { depth_m: 0.5 });
        let parsed: Wrapper = toml::from_str(
            "depth = { kind = \"estimated\", initial_depth_m = 0.6, memory_s = 0.3 }",
        )
        .unwrap();
        assert_eq!(
            parsed.depth,
            DepthSource::Estimated {
                initial_depth_m: 0.6,
                memory_s: 0.3
            }
        );
        assert!(toml::from_str::<Wrapper>("depth = { kind = \"constant\", depth = 0.5 }").is_err());
    }
}
