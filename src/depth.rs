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
//! `v = (υ, ω)` (m/s, rad/s, camera frame `c`), the point rows of [\[M28\]](crate::theory#m28) split into a part proportional to `ρ`
//! and a part that does not depend on it, and the depth itself moves with the camera:
//!
//! ```text
//! ṡ = ρ a(s, υ) + b(s, ω)
//! a = (−υx + x υz,  −υy + y υz)                                      (m/s)
//! b = (x y ωx − (1 + x²) ωy + y ωz,  (1 + y²) ωx − x y ωy − x ωz)     (1/s)
//! ρ̇ / ρ = ρ υz + (y ωx − x ωy)                                       (from Ż = −υz − Z (y ωx − x ωy))
//! ```
//!
//! Frame `j` arrives at `t_j` with the twist `v_j` applied over `[t_{j−1}, t_j]` (`Δt_j = t_j − t_{j−1}`); with the
//! midpoint `s̄_j = (s_{j−1} + s_j)/2` (second-order accurate), each frame contributes `A_j = a(s̄_j, υ_j) Δt_j` (m),
//! `B_j = b(s̄_j, ω_j) Δt_j` and the log-depth step `δ_j = Δt_j (ρ̂ υz + ȳ_j ωx − x̄_j ωy)`, so that
//! `ρ(t_j) = ρ(t_{j−1}) e^{δ_j}`. Over a **baseline** of the last `m = min(n, window_frames)` frames ending at frame
//! `n`, integrating `ṡ` gives one measurement of the current `ρ(t_n)`:
//!
//! ```text
//! r = s_n − s_{n−m} − Σ_j B_j  =  ρ(t_n) Ã,     Ã = Σ_j A_j e^{−(δ_{j+1} + … + δ_n) − δ_j/2}      (j = n−m+1 … n)
//! ```
//!
//! The baseline matters with pixel noise: the noise of `s_n − s_{n−m}` stays the same while the motion grows with the
//! baseline. Each point keeps an estimate `ρ̂` and its information `I` (m²): a recursive least-squares estimate with
//! exponential forgetting of time constant `τ` (`memory_s`):
//!
//! ```text
//! predict:   ρ̂ ← ρ̂ e^{δ_n},   I ← I e^{−Δt_n/τ}
//! correct:   ρ̂ ← (I ρ̂ + Ãᵀ r) / (I + Ãᵀ Ã),   I ← I + Ãᵀ Ã
//! ```
//!
//! With `I = 0` and one frame this is the least-squares `ρ̂ = Ãᵀ r / Ãᵀ Ã`. Before any information (`I = 0`) the
//! estimate is the initial depth.
//!
//! **Observability.** `|A_j|² = Δt² ((υx − x υz)² + (υy − y υz)²)`: the depth is observable only when the camera
//! translates, and not along the point's line of sight. A pure rotation (`υ = 0`) leaves the estimate unchanged but for
//! the prediction; [`DepthEstimator::information`] tells how much has been learnt about each point.
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
/// `{ kind = "constant", depth_m = 0.5 }`, `{ kind = "previous_plane" }`, `{ kind = "target_pose" }`,
/// `{ kind = "estimated", initial_depth_m = 0.5, memory_s = 1.0, window_frames = 10 }`).
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
    /// The plane of the target's pose estimated at each frame from the four measured corners and the known target
    /// model ([`crate::target::RectangleTarget::plane_from_image`]: a planar homography). Needs no motion, unlike
    /// [`DepthSource::Estimated`]; its error is that of the measured points (about 2 % RMS per frame at ±2 px on the
    /// paper's target, less once the points are filtered).
    TargetPose,
    /// The online [`DepthEstimator`] (module docs).
    Estimated {
        /// The depth (m, > 0) used before the motion makes the depth observable.
        initial_depth_m: f64,
        /// The forgetting time constant `τ` (s, > 0).
        memory_s: f64,
        /// The longest baseline, in frames (1 to [`MAX_WINDOW_FRAMES`]).
        window_frames: usize,
    },
}

impl DepthSource {
    /// Checks the parameters.
    ///
    /// # Errors
    /// [`DepthError::InvalidParameter`] for a non-finite or non-positive depth or memory, or a window out of range.
    pub fn validate(&self) -> Result<(), DepthError> {
        match *self {
            Self::Desired | Self::PreviousPlane | Self::TargetPose => Ok(()),
            Self::Constant { depth_m } => positive("depth_m", depth_m).map(drop),
            Self::Estimated {
                initial_depth_m,
                memory_s,
                window_frames,
            } => DepthEstimator::new(1, initial_depth_m, memory_s, window_frames).map(drop),
        }
    }

    /// The estimator this source needs for `point_count` points: `Some` for [`DepthSource::Estimated`] (built with its
    /// parameters), `None` for the others. Build it once per run, before the control loop.
    ///
    /// # Errors
    /// [`DepthError::InvalidParameter`] as [`DepthSource::validate`] and [`DepthEstimator::new`].
    pub fn estimator(&self, point_count: usize) -> Result<Option<DepthEstimator>, DepthError> {
        self.validate()?;
        match *self {
            Self::Estimated {
                initial_depth_m,
                memory_s,
                window_frames,
            } => {
                DepthEstimator::new(point_count, initial_depth_m, memory_s, window_frames).map(Some)
            }
            Self::Desired | Self::Constant { .. } | Self::PreviousPlane | Self::TargetPose => {
                Ok(None)
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
    /// [`DepthSource::PreviousPlane`] and [`DepthSource::TargetPose`]: the plane of the pose estimate (camera frame,
    /// 1/m).
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

/// One frame of one point in the estimator's window: the measured point and the frame's increments (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
struct FrameEntry {
    /// `s_j`.
    point: Point2<f64>,
    /// `A_j = a(s̄_j, υ_j) Δt_j` (m).
    a: [f64; 2],
    /// `B_j = b(s̄_j, ω_j) Δt_j` (dimensionless).
    b: [f64; 2],
    /// `δ_j` (dimensionless).
    delta: f64,
    /// `e^{−δ_j/2}`, so that the window's weights are products, not exponentials.
    half_decay: f64,
}

/// The estimate and information of one point.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Estimate {
    /// `ρ̂` (1/m).
    inverse_depth: f64,
    /// `I` (m²).
    information: f64,
}

/// Largest `window_frames` accepted.
pub const MAX_WINDOW_FRAMES: usize = 1000;

/// Online estimator of the depth of each tracked point from the camera twist and the image motion over a baseline of
/// frames (module docs: recursive least squares on the integral of `ṡ = ρ a + b`, with prediction by the depth
/// dynamics).
#[derive(Debug, Clone, PartialEq)]
pub struct DepthEstimator {
    memory: f64,
    window: usize,
    initial_inverse_depth: f64,
    /// Time of the last frame (s); `None` before the first.
    time: Option<f64>,
    /// Number of frames received.
    frames: u64,
    /// `window + 1` entries per point, frame `j` of point `k` at `k (window + 1) + j mod (window + 1)`.
    entries: Vec<FrameEntry>,
    estimates: Vec<Estimate>,
    /// The new entry and estimate of each point during an update, committed once all are valid.
    proposals: Vec<(FrameEntry, Estimate)>,
    depths: Vec<f64>,
}

impl DepthEstimator {
    /// An estimator for `point_count` points, starting from `initial_depth_m` (m) for every point, forgetting with
    /// time constant `memory_s` (s), measuring the image motion over baselines of up to `window_frames` frames.
    ///
    /// # Errors
    /// [`DepthError::InvalidParameter`] for a non-finite or non-positive depth or memory, zero points, or a window of
    /// 0 or more than [`MAX_WINDOW_FRAMES`] frames.
    pub fn new(
        point_count: usize,
        initial_depth_m: f64,
        memory_s: f64,
        window_frames: usize,
    ) -> Result<Self, DepthError> {
        positive("initial_depth_m", initial_depth_m)?;
        positive("memory_s", memory_s)?;
        if point_count == 0 {
            return Err(DepthError::InvalidParameter {
                name: "point_count",
                value: 0.0,
            });
        }
        if !(1..=MAX_WINDOW_FRAMES).contains(&window_frames) {
            return Err(DepthError::InvalidParameter {
                name: "window_frames",
                value: window_frames as f64,
            });
        }
        let initial_inverse_depth = 1.0 / initial_depth_m;
        let initial = Estimate {
            inverse_depth: initial_inverse_depth,
            information: 0.0,
        };
        Ok(Self {
            memory: memory_s,
            window: window_frames,
            initial_inverse_depth,
            time: None,
            frames: 0,
            entries: vec![FrameEntry::default(); point_count * (window_frames + 1)],
            estimates: vec![initial; point_count],
            proposals: vec![(FrameEntry::default(), initial); point_count],
            depths: vec![initial_depth_m; point_count],
        })
    }

    /// Starts again from the initial depth, forgetting every measurement (for instance after the target was lost).
    pub fn reset(&mut self) {
        self.time = None;
        self.frames = 0;
        for e in &mut self.estimates {
            e.inverse_depth = self.initial_inverse_depth;
            e.information = 0.0;
        }
        self.depths.fill(1.0 / self.initial_inverse_depth);
    }

    /// One update with the points measured at `time` (s) and the camera twist `(υ, ω)` (m/s, rad/s, camera frame)
    /// applied since the previous frame (ignored at the first frame, which only stores the points). Returns the
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
        if measured.len() != self.estimates.len() {
            return Err(DepthError::PointCountMismatch {
                expected: self.estimates.len(),
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
        let previous = self.time.unwrap_or(f64::NEG_INFINITY);
        if !(time.is_finite() && time > previous) {
            return Err(DepthError::TimeNotIncreasing { previous, time });
        }
        let slots = self.window + 1;
        let slot = (self.frames % slots as u64) as usize;
        if self.time.is_none() {
            for (k, p) in measured.iter().enumerate() {
                self.entries[k * slots + slot] = FrameEntry {
                    point: *p,
                    ..FrameEntry::default()
                };
            }
        } else {
            let dt = time - previous;
            let forgetting = (-dt / self.memory).exp();
            // Compute and check every new estimate first, commit only when all are valid.
            for (index, p) in measured.iter().enumerate() {
                let proposal = self.propose(index, p, twist, dt, forgetting);
                let inverse_depth = proposal.1.inverse_depth;
                if !(inverse_depth.is_finite() && inverse_depth > 0.0) {
                    return Err(DepthError::NonPositiveDepth {
                        index,
                        inverse_depth,
                    });
                }
                self.proposals[index] = proposal;
            }
            for (index, &(entry, estimate)) in self.proposals.iter().enumerate() {
                self.entries[index * slots + slot] = entry;
                self.estimates[index] = estimate;
                self.depths[index] = 1.0 / estimate.inverse_depth;
            }
        }
        self.frames += 1;
        self.time = Some(time);
        Ok(&self.depths)
    }

    /// The new frame entry of point `index` and its predicted and corrected estimate (module docs), without changing
    /// the state.
    fn propose(
        &self,
        index: usize,
        current: &Point2<f64>,
        twist: &Vector6<f64>,
        dt: f64,
        forgetting: f64,
    ) -> (FrameEntry, Estimate) {
        let [vx, vy, vz, wx, wy, wz] = [twist[0], twist[1], twist[2], twist[3], twist[4], twist[5]];
        let slots = self.window + 1;
        let ring = &self.entries[index * slots..(index + 1) * slots];
        let at = |frame: u64| &ring[(frame % slots as u64) as usize];
        let n = self.frames;
        let previous = at(n - 1).point;
        let (x, y) = (
            0.5 * (previous.x + current.x),
            0.5 * (previous.y + current.y),
        );
        let old = self.estimates[index];
        let delta = (old.inverse_depth * vz + y * wx - x * wy) * dt;
        let entry = FrameEntry {
            point: *current,
            a: [(-vx + x * vz) * dt, (-vy + y * vz) * dt],
            b: [
                (x * y * wx - (1.0 + x * x) * wy + y * wz) * dt,
                ((1.0 + y * y) * wx - x * y * wy - x * wz) * dt,
            ],
            delta,
            half_decay: (-0.5 * delta).exp(),
        };
        // Ã and Σ B over the last m frames, newest first; `later_decay` = e^{−(δ_{j+1} + … + δ_n)}.
        let m = n.min(self.window as u64);
        let (mut a_tilde, mut b_sum, mut later_decay) = ([0.0; 2], [0.0; 2], 1.0);
        for back in 0..m {
            let e = if back == 0 { &entry } else { at(n - back) };
            let weight = later_decay * e.half_decay;
            for i in 0..2 {
                a_tilde[i] += e.a[i] * weight;
                b_sum[i] += e.b[i];
            }
            later_decay *= e.half_decay * e.half_decay;
        }
        let start = at(n - m).point;
        let r = [
            current.x - start.x - b_sum[0],
            current.y - start.y - b_sum[1],
        ];
        let aa = a_tilde[0] * a_tilde[0] + a_tilde[1] * a_tilde[1];
        let ar = a_tilde[0] * r[0] + a_tilde[1] * r[1];
        let mut rho = old.inverse_depth * entry.delta.exp();
        let information = old.information * forgetting;
        let total = information + aa;
        if total > 0.0 {
            rho = (information * rho + ar) / total;
        }
        (
            entry,
            Estimate {
                inverse_depth: rho,
                information: total,
            },
        )
    }

    /// The current depth estimates (m), one per point.
    pub fn depths(&self) -> &[f64] {
        &self.depths
    }

    /// The information `I` (m², module docs) gathered about point `index`: 0 before any translation across its line of
    /// sight; `None` for an index out of range.
    pub fn information(&self, index: usize) -> Option<f64> {
        self.estimates.get(index).map(|e| e.information)
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
    /// ρ = Ãᵀr/ÃᵀÃ with Ã = a Δt = (−0.01, 0) m, r = (−0.005, 0): ρ = 0.5, Z = 2, and I = ÃᵀÃ = 1e−4 m².
    #[test]
    fn one_translation_step_gives_the_least_squares_depth() {
        let mut estimator = DepthEstimator::new(1, 1.0, 1.0, 1).unwrap();
        let twist = Vector6::new(0.1, 0.0, 0.0, 0.0, 0.0, 0.0);
        estimator
            .update(0.0, &points(&[(0.0, 0.0)]), &twist)
            .unwrap();
        let depths = estimator
            .update(0.1, &points(&[(-0.005, 0.0)]), &twist)
            .unwrap();
        assert!((depths[0] - 2.0).abs() < 1e-12, "{}", depths[0]);
        assert!((estimator.information(0).unwrap() - 1e-4).abs() < 1e-18);
    }

    /// A pure rotation carries no depth information: the estimate only follows the known depth dynamics
    /// `Ż = −Z (y ωx − x ωy)`, here `Ż = 0.2 x Z` with a mean x of 0.099 over 0.01 s.
    #[test]
    fn pure_rotation_is_not_observable() {
        let mut estimator = DepthEstimator::new(1, 0.7, 1.0, 1).unwrap();
        let twist = Vector6::new(0.0, 0.0, 0.0, 0.0, 0.2, 0.0);
        estimator
            .update(0.0, &points(&[(0.1, 0.0)]), &twist)
            .unwrap();
        // ẋ = −(1 + x²) ωy.
        let depths = estimator
            .update(0.01, &points(&[(0.1 - 0.01 * 1.01 * 0.2, 0.0)]), &twist)
            .unwrap();
        let x_mean: f64 = 0.1 - 0.005 * 1.01 * 0.2;
        // Exact for x varying linearly: Z = 0.7 exp(0.2 · 0.01 · x̄) (change 1.4e−4).
        let exact = 0.7 * (0.01 * 0.2 * x_mean).exp();
        assert!((depths[0] - exact).abs() < 2e-8, "{} vs {exact}", depths[0]);
        assert_eq!(estimator.information(0), Some(0.0));
    }

    #[test]
    fn bad_inputs_are_named_errors() {
        assert!(matches!(
            DepthEstimator::new(4, 0.0, 1.0, 1),
            Err(DepthError::InvalidParameter {
                name: "initial_depth_m",
                ..
            })
        ));
        assert!(matches!(
            DepthEstimator::new(4, 0.5, f64::NAN, 1),
            Err(DepthError::InvalidParameter {
                name: "memory_s",
                ..
            })
        ));
        assert!(matches!(
            DepthEstimator::new(0, 0.5, 1.0, 1),
            Err(DepthError::InvalidParameter {
                name: "point_count",
                ..
            })
        ));
        let mut estimator = DepthEstimator::new(1, 0.5, 1.0, 3).unwrap();
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
        let estimated = |memory_s, window_frames| DepthSource::Estimated {
            initial_depth_m: 0.5,
            memory_s,
            window_frames,
        };
        assert!(matches!(
            estimated(-1.0, 5).validate(),
            Err(DepthError::InvalidParameter {
                name: "memory_s",
                ..
            })
        ));
        for window in [0, MAX_WINDOW_FRAMES + 1] {
            assert!(matches!(
                estimated(1.0, window).validate(),
                Err(DepthError::InvalidParameter {
                    name: "window_frames",
                    ..
                })
            ));
        }
        assert!(estimated(1.0, 5).validate().is_ok());
        let estimator = estimated(1.0, 5).estimator(4).unwrap().unwrap();
        assert_eq!(estimator.depths(), [0.5; 4]);
        assert_eq!(DepthSource::PreviousPlane.estimator(4), Ok(None));
        assert!(matches!(
            estimated(1.0, 5).estimator(0),
            Err(DepthError::InvalidParameter {
                name: "point_count",
                ..
            })
        ));
        assert!(matches!(
            DepthSource::Constant { depth_m: f64::NAN }.estimator(4),
            Err(DepthError::InvalidParameter {
                name: "depth_m",
                ..
            })
        ));
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
            "depth = { kind = \"estimated\", initial_depth_m = 0.6, memory_s = 0.3, window_frames = 8 }",
        )
        .unwrap();
        assert_eq!(
            parsed.depth,
            DepthSource::Estimated {
                initial_depth_m: 0.6,
                memory_s: 0.3,
                window_frames: 8
            }
        );
        assert!(toml::from_str::<Wrapper>("depth = { kind = \"constant\", depth = 0.5 }").is_err());
    }
}
