//! The feature observer ([`FeatureObserver`]): the four image points predicted between camera frames from the camera
//! twist the controller sent, and corrected at each frame against the estimate of the frame's capture time, with a
//! gain that weighs the pixel noise against the prediction's error (a Kalman filter per coordinate). Theory:
//! [D32](crate::theory#d32).
//!
//! Each period at time `t`, with the twist `v` sent over the last period `Δt` and the points' depths `Ẑ_k`:
//!
//! 1. **Prediction** \[M28\]: `x̂_k ← x̂_k + Δt L_x(x̂_k, 1/Ẑ_k) v` (and `y`).
//! 2. **Correction**, when a new frame `z` arrives: the variance `P` of each coordinate first grows by the square of
//!    the prediction's assumed error since the previous frame, `(α · predicted motion since that frame)²` (`α`:
//!    [`ObserverParameters::prediction_error_fraction`]; a model error is systematic, so it is the whole motion's
//!    fraction, not a sum of per-period errors). The frame was captured at `t − latency`; the innovation is
//!    `z − x̂(t − latency)`, the estimate of that time taken back from the observer's own history (linear
//!    interpolation between periods), and `x̂(t) ← x̂(t) + K (z − x̂(t − latency))` with the Kalman gain
//!    `K = P / (P + R)`, `R = (σ / f)²` (`σ`: [`ObserverParameters::pixel_noise_px`], `f` the focal length in that
//!    axis), but never below `1 − e^{−T/τ}` (`T` the time since the previous frame, `τ`:
//!    [`ObserverParameters::memory_s`]): no frame older than about `τ` weighs on the estimate, whatever the model
//!    claims. The variance becomes `(1 − K)² P + K² R` (Joseph's form, right for any gain).
//!
//! The motion the robot makes is followed without lag, since the prediction carries it; the noise of the frames is
//! averaged over about `min(P/R, τ/T)` frames once the robot is still. What remains lagged is the part of the motion
//! the prediction gets wrong (calibration and depth errors), corrected at the rate `K` per frame.
//!
//! [`FeatureObserver::propose`] computes a period's estimate without changing the observer, and
//! [`FeatureObserver::commit`] keeps it, so a caller whose later stage fails (the hardware façade on a bad frame) leaves
//! the observer as it was. Neither allocates.

use super::MeasurementError;
use crate::feature::point_interaction;
use nalgebra::{Point2, Vector6};

/// The observer's points: the four corners of the target.
pub const OBSERVED_POINTS: usize = 4;

/// Periods of history kept for the latency: a latency up to this many control periods is taken back exactly; beyond,
/// the oldest estimate kept stands for the capture time.
pub const OBSERVER_HISTORY: usize = 256;

/// The observer's parameters. Units in the names.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ObserverParameters {
    /// Standard deviation of the detector's noise on each pixel coordinate (px, in `(0, 1000]`): the measurement
    /// variance `R`. Default 1.
    pub pixel_noise_px: f64,
    /// The relative error `α` of the predicted motion (in `[0, 10]`): calibration, hand-eye and depth errors make the
    /// predicted displacement of a point wrong by about this fraction of it. Default 0.1.
    pub prediction_error_fraction: f64,
    /// The longest memory `τ` (s, in `(0, 3600]`): the gain at a frame is never below `1 − e^{−T/τ}`. Default 10.
    pub memory_s: f64,
    /// The time from a frame's capture to its delivery to the controller (s, in `[0, 10]`). Default 0.
    pub latency_s: f64,
}

impl Default for ObserverParameters {
    fn default() -> Self {
        Self {
            pixel_noise_px: 1.0,
            prediction_error_fraction: 0.1,
            memory_s: 10.0,
            latency_s: 0.0,
        }
    }
}

impl ObserverParameters {
    /// Checks every parameter against its range.
    ///
    /// # Errors
    /// [`MeasurementError::InvalidParameter`] naming the first invalid parameter.
    pub fn validate(&self) -> Result<(), MeasurementError> {
        let checks: [(&'static str, f64, bool, &'static str); 4] = [
            (
                "observer.pixel_noise_px",
                self.pixel_noise_px,
                self.pixel_noise_px > 0.0 && self.pixel_noise_px <= 1000.0,
                "in (0, 1000] px",
            ),
            (
                "observer.prediction_error_fraction",
                self.prediction_error_fraction,
                (0.0..=10.0).contains(&self.prediction_error_fraction),
                "in [0, 10]",
            ),
            (
                "observer.memory_s",
                self.memory_s,
                self.memory_s > 0.0 && self.memory_s <= 3600.0,
                "in (0, 3600] s",
            ),
            (
                "observer.latency_s",
                self.latency_s,
                (0.0..=10.0).contains(&self.latency_s),
                "in [0, 10] s",
            ),
        ];
        match checks.into_iter().find(|(_, _, ok, _)| !ok) {
            Some((name, value, _, expected)) => Err(MeasurementError::InvalidParameter {
                name,
                value,
                expected,
            }),
            None => Ok(()),
        }
    }
}

/// One period's estimate, from [`FeatureObserver::propose`], kept by [`FeatureObserver::commit`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ObserverStep {
    time: f64,
    frame: bool,
    points: [Point2<f64>; OBSERVED_POINTS],
    variance: [[f64; 2]; OBSERVED_POINTS],
    /// The predicted motion of each coordinate since the last frame.
    moved: [[f64; 2]; OBSERVED_POINTS],
}

impl ObserverStep {
    /// The estimated points (normalised).
    pub fn points(&self) -> &[Point2<f64>; OBSERVED_POINTS] {
        &self.points
    }
}

/// The feature observer (module docs). Built once; allocation-free afterwards.
#[derive(Debug, Clone)]
pub struct FeatureObserver {
    parameters: ObserverParameters,
    /// `R` per axis: `(σ / fx)²`, `(σ / fy)²`.
    noise_variance: [f64; 2],
    /// The last committed period: `None` before the first frame.
    last: Option<ObserverStep>,
    /// Time of the last committed frame (s).
    last_frame_time: f64,
    /// Committed estimates, oldest overwritten first: `(time, points)`.
    history: Vec<(f64, [Point2<f64>; OBSERVED_POINTS])>,
    /// Next slot of `history` to write.
    next: usize,
}

impl FeatureObserver {
    /// An observer for a camera of focal lengths `fx`, `fy` (px).
    ///
    /// # Errors
    /// [`MeasurementError::InvalidParameter`]: a parameter out of range, a focal length not finite and positive.
    pub fn new(parameters: ObserverParameters, fx: f64, fy: f64) -> Result<Self, MeasurementError> {
        parameters.validate()?;
        for (name, value) in [
            ("observer focal length fx", fx),
            ("observer focal length fy", fy),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(MeasurementError::InvalidParameter {
                    name,
                    value,
                    expected: "finite and > 0 px",
                });
            }
        }
        let sigma = parameters.pixel_noise_px;
        Ok(Self {
            parameters,
            noise_variance: [(sigma / fx).powi(2), (sigma / fy).powi(2)],
            last: None,
            last_frame_time: 0.0,
            history: Vec::with_capacity(OBSERVER_HISTORY),
            next: 0,
        })
    }

    /// The parameters.
    pub fn parameters(&self) -> &ObserverParameters {
        &self.parameters
    }

    /// The last committed estimate, `None` before the first frame.
    pub fn points(&self) -> Option<&[Point2<f64>; OBSERVED_POINTS]> {
        self.last.as_ref().map(|step| &step.points)
    }

    /// The estimate at `time` (s, after the last committed period), from the camera twist `twist` `(υ, ω)` (m/s,
    /// rad/s) sent since the last committed period, the points' depths `depths` (m) and, when a new frame arrived,
    /// its points `frame` (normalised). Before the first frame the estimate is the frame itself; without a frame and
    /// without a committed period there is nothing to estimate (`None`). A twist or a depth that is not finite (or a
    /// depth not positive) leaves that point unpredicted for the period. Changes nothing: [`Self::commit`] keeps it.
    pub fn propose(
        &self,
        time: f64,
        twist: &Vector6<f64>,
        depths: &[f64; OBSERVED_POINTS],
        frame: Option<&[Point2<f64>; OBSERVED_POINTS]>,
    ) -> Option<ObserverStep> {
        let Some(last) = &self.last else {
            return frame.map(|frame| ObserverStep {
                time,
                frame: true,
                points: *frame,
                variance: [self.noise_variance; OBSERVED_POINTS],
                moved: [[0.0; 2]; OBSERVED_POINTS],
            });
        };
        let dt = time - last.time;
        let mut step = ObserverStep {
            time,
            frame: frame.is_some(),
            ..*last
        };
        let twist_usable = twist.iter().all(|v| v.is_finite());
        for ((point, moved), &depth) in step.points.iter_mut().zip(&mut step.moved).zip(depths) {
            if !(twist_usable && depth.is_finite() && depth > 0.0 && dt > 0.0) {
                continue;
            }
            let (lx, ly) = point_interaction(point.x, point.y, 1.0 / depth);
            let motion = [
                dt * lx.transpose().dot(twist),
                dt * ly.transpose().dot(twist),
            ];
            point.x += motion[0];
            point.y += motion[1];
            moved[0] += motion[0];
            moved[1] += motion[1];
        }
        if let Some(frame) = frame {
            let captured = self.estimate_at(time - self.parameters.latency_s, &step);
            let since = time - self.last_frame_time;
            let floor = -(-since / self.parameters.memory_s).exp_m1();
            // A model error is systematic: the prediction's error since the last frame is `α` times the whole
            // predicted motion since then (not the sum of per-period errors).
            let alpha = self.parameters.prediction_error_fraction;
            for (k, ((point, variance), moved)) in step
                .points
                .iter_mut()
                .zip(&mut step.variance)
                .zip(&mut step.moved)
                .enumerate()
            {
                let innovation = [frame[k].x - captured[k].x, frame[k].y - captured[k].y];
                for axis in 0..2 {
                    let p = variance[axis] + (alpha * moved[axis]).powi(2);
                    let r = self.noise_variance[axis];
                    let gain = (p / (p + r)).max(floor);
                    point[axis] += gain * innovation[axis];
                    variance[axis] = (1.0 - gain).powi(2) * p + gain * gain * r;
                    moved[axis] = 0.0;
                }
            }
        }
        Some(step)
    }

    /// Keeps `step` (from [`Self::propose`] on this observer) as the current estimate.
    pub fn commit(&mut self, step: &ObserverStep) {
        if step.frame {
            self.last_frame_time = step.time;
        }
        let entry = (step.time, step.points);
        if self.history.len() < OBSERVER_HISTORY {
            self.history.push(entry);
        } else {
            self.history[self.next] = entry;
        }
        self.next = (self.next + 1) % OBSERVER_HISTORY;
        self.last = Some(*step);
    }

    /// The estimate at `time`: `current` (the period being proposed) at or after its time, else interpolated linearly
    /// between the committed estimates around it, or the oldest kept.
    fn estimate_at(&self, time: f64, current: &ObserverStep) -> [Point2<f64>; OBSERVED_POINTS] {
        if time >= current.time {
            return current.points;
        }
        let mut later = (current.time, current.points);
        let count = self.history.len();
        for back in 1..=count {
            let entry = self.history[(self.next + OBSERVER_HISTORY - back) % OBSERVER_HISTORY];
            if entry.0 <= time {
                let w = (time - entry.0) / (later.0 - entry.0);
                return std::array::from_fn(|k| entry.1[k] + (later.1[k] - entry.1[k]) * w);
            }
            later = entry;
        }
        later.1
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{rngs::StdRng, RngExt, SeedableRng};

    const F: f64 = 600.0;
    const DEPTH: f64 = 0.5;
    const PERIOD: f64 = 0.002;
    /// A frame every 16 periods (31.25 Hz).
    const FRAME_EVERY: usize = 16;

    /// The true points at time `t` of a camera translating along x at `speed` (m/s) in front of a fronto-parallel
    /// target at `DEPTH`: every point moves by `ẋ = −υx/Z`.
    fn truth(t: f64, speed: f64) -> [Point2<f64>; 4] {
        let shift = -speed * t / DEPTH;
        [(-0.1, -0.05), (0.1, -0.05), (0.1, 0.05), (-0.1, 0.05)]
            .map(|(x, y)| Point2::new(x + shift, y))
    }

    /// Runs an observer over `periods` periods of the translating camera; frames carry uniform noise of `±noise_px`
    /// and arrive `latency_frames` frames after their capture. Returns the RMS error (normalised) against the true
    /// points of the current period, of the observer's estimate and of the last delivered frame (held).
    fn run(
        parameters: ObserverParameters,
        speed: f64,
        noise_px: f64,
        latency_frames: usize,
        periods: usize,
        seed: u64,
    ) -> (f64, f64) {
        let mut rng = StdRng::seed_from_u64(seed);
        let mut observer = FeatureObserver::new(parameters, F, F).unwrap();
        let twist = Vector6::new(speed, 0.0, 0.0, 0.0, 0.0, 0.0);
        let mut captured: Vec<[Point2<f64>; 4]> = Vec::new();
        let mut held = [Point2::origin(); 4];
        let (mut observed_sq, mut held_sq, mut count) = (0.0, 0.0, 0.0);
        for k in 0..periods {
            let t = k as f64 * PERIOD;
            let frame = (k.is_multiple_of(FRAME_EVERY)).then(|| {
                captured.push(truth(t, speed).map(|p| {
                    let mut noisy = p;
                    for axis in 0..2 {
                        if noise_px > 0.0 {
                            noisy[axis] += rng.random_range(-noise_px..=noise_px) / F;
                        }
                    }
                    noisy
                }));
                captured[captured.len().saturating_sub(1 + latency_frames)]
            });
            if let Some(frame) = frame {
                held = frame;
            }
            let step = observer
                .propose(t, &twist, &[DEPTH; 4], frame.as_ref())
                .unwrap();
            observer.commit(&step);
            if t >= 1.0 {
                let now = truth(t, speed);
                for i in 0..4 {
                    observed_sq += (step.points()[i] - now[i]).norm_squared();
                    held_sq += (held[i] - now[i]).norm_squared();
                    count += 1.0;
                }
            }
        }
        ((observed_sq / count).sqrt(), (held_sq / count).sqrt())
    }

    /// Without noise or latency the prediction carries the motion between frames: the estimate is exact to the
    /// rounding (the motion is linear in time here), where the held frame is up to one frame's motion behind.
    #[test]
    fn prediction_follows_the_motion_between_frames() {
        let (observed, held) = run(ObserverParameters::default(), 0.05, 0.0, 0, 1000, 1);
        assert!(held > 1e-3, "{held}");
        assert!(observed < 1e-12, "{observed}");
    }

    /// With a frame delivered one or three frames late, the observer compares it with its own estimate of the capture
    /// time: with the latency given, the estimate stays exact; with the latency ignored (0), it lags by the motion of
    /// the latency, as the held frame does.
    #[test]
    fn latency_is_taken_back_from_the_history() {
        for latency_frames in [1, 3] {
            let latency_s = (latency_frames * FRAME_EVERY) as f64 * PERIOD;
            let known = ObserverParameters {
                latency_s,
                ..ObserverParameters::default()
            };
            let (observed, held) = run(known, 0.05, 0.0, latency_frames, 1000, 1);
            assert!(observed < 1e-12, "{latency_frames} frames late: {observed}");
            let (ignored, _) = run(
                ObserverParameters::default(),
                0.05,
                0.0,
                latency_frames,
                1000,
                1,
            );
            assert!(ignored > 0.2 * held, "{ignored} vs held {held}");
        }
    }

    /// A still camera and ±2 px of noise: the observer averages the frames (its error falls as frames accumulate, to a
    /// small fraction of one frame's), over twenty draws; a short memory averages fewer.
    #[test]
    fn noise_of_a_still_camera_is_averaged() {
        let noisy = |memory_s, seed| {
            let parameters = ObserverParameters {
                pixel_noise_px: 2.0 / 3f64.sqrt(),
                memory_s,
                ..ObserverParameters::default()
            };
            run(parameters, 0.0, 2.0, 0, 3000, seed)
        };
        for seed in 0..20 {
            let (long, frame) = noisy(30.0, seed);
            let (short, _) = noisy(0.2, seed);
            // One frame's RMS error is 2/√3 px per axis; about 190 frames in all, 125 of them after 1 s.
            assert!(frame > 1.3 / F && frame < 2.0 / F, "seed {seed}: {frame}");
            assert!(long < 0.25 * frame, "seed {seed}: {long} vs {frame}");
            assert!(
                short > 1.5 * long,
                "seed {seed}: short memory {short}, long {long}"
            );
        }
    }

    /// `propose` changes nothing; only `commit` moves the observer on.
    #[test]
    fn propose_changes_nothing_until_commit() {
        let mut observer = FeatureObserver::new(ObserverParameters::default(), F, F).unwrap();
        let twist = Vector6::new(0.05, 0.0, 0.0, 0.0, 0.0, 0.0);
        assert!(observer.propose(0.0, &twist, &[DEPTH; 4], None).is_none());
        let first = observer
            .propose(0.0, &twist, &[DEPTH; 4], Some(&truth(0.0, 0.05)))
            .unwrap();
        assert!(observer.points().is_none());
        observer.commit(&first);
        let before = observer.clone();
        let next = observer.propose(PERIOD, &twist, &[DEPTH; 4], None).unwrap();
        assert_eq!(observer.points(), before.points());
        assert!((next.points()[0].x - truth(PERIOD, 0.05)[0].x).abs() < 1e-15);
        // A depth or a twist that is not usable leaves the point where it was, never NaN.
        for (depths, twist) in [
            ([f64::NAN, 0.0, -1.0, DEPTH], twist),
            ([DEPTH; 4], Vector6::repeat(f64::INFINITY)),
        ] {
            let step = observer.propose(PERIOD, &twist, &depths, None).unwrap();
            assert!(step
                .points()
                .iter()
                .all(|p| p.x.is_finite() && p.y.is_finite()));
        }
    }

    /// Every parameter out of its range is named.
    #[test]
    fn parameters_out_of_range_are_named() {
        let base = ObserverParameters::default();
        for (name, bad) in [
            (
                "observer.pixel_noise_px",
                ObserverParameters {
                    pixel_noise_px: 0.0,
                    ..base
                },
            ),
            (
                "observer.pixel_noise_px",
                ObserverParameters {
                    pixel_noise_px: f64::NAN,
                    ..base
                },
            ),
            (
                "observer.prediction_error_fraction",
                ObserverParameters {
                    prediction_error_fraction: -0.1,
                    ..base
                },
            ),
            (
                "observer.memory_s",
                ObserverParameters {
                    memory_s: f64::INFINITY,
                    ..base
                },
            ),
            (
                "observer.latency_s",
                ObserverParameters {
                    latency_s: -1e-3,
                    ..base
                },
            ),
        ] {
            match FeatureObserver::new(bad, F, F) {
                Err(MeasurementError::InvalidParameter { name: got, .. }) => assert_eq!(got, name),
                other => panic!("{name}: {other:?}"),
            }
        }
        assert!(FeatureObserver::new(base, 0.0, F).is_err());
        assert!(FeatureObserver::new(base, F, f64::NAN).is_err());
    }
}
