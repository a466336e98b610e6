//! The measurement model of one run ([`MeasurementModel`]): the true and nominal cameras, the frame captures with their
//! pixel noise, the latency ring buffer, and the controller's points (held or predicted between frames, filtered).

use super::{BetweenFrames, MeasurementError, MeasurementParameters};
use crate::camera::{BrownConrady, CalibratedCamera, CameraIntrinsics, ImagePoint};
use crate::depth::{assign_depths, Depths};
use crate::feature::point_interaction;
use nalgebra::{Point2, Vector6};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};

/// What [`MeasurementModel::measure`] delivers at one control period.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Measurement<'a> {
    /// The controller's normalised points (nominal camera, undistorted), held or predicted between frames, and filtered
    /// when `filter_time_constant_s > 0`.
    pub normalized: &'a [Point2<f64>],
    /// The pixels of the delivered frame (noisy, distorted, through the true camera).
    pub pixels: &'a [Point2<f64>],
    /// `true` when a frame not delivered before arrived at this period.
    pub fresh: bool,
    /// The capture time (s) of the delivered frame.
    pub frame_time: f64,
}

/// The measurement model of one run (module docs): the true and nominal cameras, the noise generator, the frame ring
/// buffer and the controller-side points, all allocated at construction.
#[derive(Debug)]
pub struct MeasurementModel {
    parameters: MeasurementParameters,
    true_camera: CalibratedCamera,
    nominal_camera: CalibratedCamera,
    rng: StdRng,
    point_count: usize,
    /// `latency_frames + 1` frames of `point_count` pixels, frame `n` at slot `n mod (latency_frames + 1)`.
    frames: Vec<Point2<f64>>,
    frame_times: Vec<f64>,
    /// Index of the latest captured frame, `None` before the first call.
    latest_frame: Option<u64>,
    start_time: f64,
    previous_time: f64,
    delivered_frame: u64,
    normalized: Vec<Point2<f64>>,
    /// The filtered points the controller gets (`filter_time_constant_s`).
    filtered: Vec<Point2<f64>>,
    image_points: Vec<ImagePoint>,
}

impl MeasurementModel {
    /// A model for `point_count` points seen by a camera whose true intrinsics are `true_intrinsics` (px), with the
    /// control period `period` (s).
    ///
    /// # Errors
    /// [`MeasurementError::InvalidParameter`] for an invalid parameter or zero points; [`MeasurementError::Camera`]
    /// when the nominal intrinsics are invalid.
    pub fn new(
        parameters: &MeasurementParameters,
        true_intrinsics: CameraIntrinsics,
        point_count: usize,
        period: f64,
    ) -> Result<Self, MeasurementError> {
        parameters.validate(period)?;
        if point_count == 0 {
            return Err(MeasurementError::InvalidParameter {
                name: "point_count",
                value: 0.0,
                expected: "at least one point",
            });
        }
        let [k1, k2, p1, p2, k3] = parameters.distortion_coefficients;
        let distortion = BrownConrady::new(k1, k2, p1, p2, k3)?;
        let true_camera = CalibratedCamera {
            intrinsics: true_intrinsics,
            distortion,
        };
        let mut rng = StdRng::seed_from_u64(parameters.seed);
        let epsilon = parameters.intrinsics_error_fraction;
        let mut scaled = |value: f64| {
            let sign = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
            value * (1.0 + sign * epsilon)
        };
        let k = true_intrinsics;
        let nominal_intrinsics = CameraIntrinsics::new(
            scaled(k.fx()),
            scaled(k.fy()),
            scaled(k.cx()),
            scaled(k.cy()),
            k.width(),
            k.height(),
        )?;
        let slots = parameters.latency_frames + 1;
        Ok(Self {
            parameters: *parameters,
            true_camera,
            nominal_camera: CalibratedCamera {
                intrinsics: nominal_intrinsics,
                distortion,
            },
            rng,
            point_count,
            frames: vec![Point2::origin(); slots * point_count],
            frame_times: vec![0.0; slots],
            latest_frame: None,
            start_time: 0.0,
            previous_time: 0.0,
            delivered_frame: 0,
            normalized: vec![Point2::origin(); point_count],
            filtered: vec![Point2::origin(); point_count],
            image_points: vec![ImagePoint::default(); point_count],
        })
    }

    /// The true camera (intrinsics and distortion) that makes the pixels.
    pub fn true_camera(&self) -> &CalibratedCamera {
        &self.true_camera
    }

    /// The nominal (believed) camera the controller converts pixels with.
    pub fn nominal_camera(&self) -> &CalibratedCamera {
        &self.nominal_camera
    }

    /// One control period at `time` (s): captures a frame when one is due, delivers the frame `latency_frames`
    /// older, and gives the controller's normalised points (module docs). `true_points` are the true normalised
    /// points and depths (m) in the true camera frame; `camera_twist` is the twist `(υ, ω)` (m/s, rad/s) the
    /// controller believes the camera had over `[previous time, time]`; `depths` gives the depths for
    /// [`BetweenFrames::Predict`] (unused with `Hold`). Allocates nothing.
    ///
    /// # Errors
    /// [`MeasurementError::PointCountMismatch`], [`MeasurementError::InvalidPoint`],
    /// [`MeasurementError::NonFiniteTwist`], [`MeasurementError::TimeNotIncreasing`]; [`MeasurementError::Camera`]
    /// when a delivered pixel cannot be undistorted; [`MeasurementError::Depth`] when the prediction depths are
    /// unusable.
    pub fn measure(
        &mut self,
        time: f64,
        true_points: &[ImagePoint],
        camera_twist: &Vector6<f64>,
        depths: Depths<'_>,
    ) -> Result<Measurement<'_>, MeasurementError> {
        self.check_inputs(time, true_points, camera_twist)?;
        let frame_due = match (self.latest_frame, self.parameters.camera_rate_hz) {
            (None, _) => Some(0),
            (Some(latest), None) => Some(latest + 1),
            (Some(latest), Some(rate)) => {
                // Frame n is due at the first period at or after t₀ + n / rate (1e−9 guards rounding of k·Δt).
                let due = ((time - self.start_time) * rate + 1e-9).floor() as u64;
                (due > latest).then_some(due)
            }
        };
        let first = self.latest_frame.is_none();
        if first {
            self.start_time = time;
        }
        if let Some(frame) = frame_due {
            self.capture(frame, time, true_points);
        }
        // Frame 0 stays in its slot until frame d + 1 overwrites it, when frame 1 is delivered.
        let latest = self.latest_frame.unwrap_or(0);
        let delivered = latest.saturating_sub(self.parameters.latency_frames as u64);
        let fresh = first || (frame_due.is_some() && delivered != self.delivered_frame);
        if fresh {
            self.delivered_frame = delivered;
            let slot = self.slot(delivered);
            for (n, p) in self
                .normalized
                .iter_mut()
                .zip(&self.frames[slot..slot + self.point_count])
            {
                let (x, y) = self.nominal_camera.normalized_of(p.x, p.y)?;
                *n = Point2::new(x, y);
            }
        } else if self.parameters.between_frames == BetweenFrames::Predict {
            self.predict(time - self.previous_time, camera_twist, depths)?;
        }
        let tau = self.parameters.filter_time_constant_s;
        let gain = if first || tau == 0.0 {
            1.0
        } else {
            -(-(time - self.previous_time) / tau).exp_m1()
        };
        for (f, n) in self.filtered.iter_mut().zip(&self.normalized) {
            *f += (n - *f) * gain;
        }
        self.previous_time = time;
        let slot = self.slot(self.delivered_frame);
        Ok(Measurement {
            normalized: &self.filtered,
            pixels: &self.frames[slot..slot + self.point_count],
            fresh,
            frame_time: self.frame_times[slot / self.point_count],
        })
    }

    fn check_inputs(
        &self,
        time: f64,
        true_points: &[ImagePoint],
        camera_twist: &Vector6<f64>,
    ) -> Result<(), MeasurementError> {
        if true_points.len() != self.point_count {
            return Err(MeasurementError::PointCountMismatch {
                expected: self.point_count,
                got: true_points.len(),
            });
        }
        if let Some((index, p)) = true_points.iter().enumerate().find(|(_, p)| {
            !(p.x.is_finite() && p.y.is_finite() && p.depth.is_finite() && p.depth > 0.0)
        }) {
            return Err(MeasurementError::InvalidPoint {
                index,
                x: p.x,
                y: p.y,
                depth: p.depth,
            });
        }
        if !camera_twist.iter().all(|v| v.is_finite()) {
            return Err(MeasurementError::NonFiniteTwist {
                twist: (*camera_twist).into(),
            });
        }
        let previous = if self.latest_frame.is_some() {
            self.previous_time
        } else {
            f64::NEG_INFINITY
        };
        if !(time.is_finite() && time > previous) {
            return Err(MeasurementError::TimeNotIncreasing { previous, time });
        }
        Ok(())
    }

    /// First entry of frame `frame` in the ring buffer.
    fn slot(&self, frame: u64) -> usize {
        (frame % (self.parameters.latency_frames as u64 + 1)) as usize * self.point_count
    }

    /// Stores frame `frame` captured at `time`: true pixels plus noise.
    fn capture(&mut self, frame: u64, time: f64, true_points: &[ImagePoint]) {
        let slot = self.slot(frame);
        let (uniform, sigma) = (
            self.parameters.pixel_noise_uniform_px,
            self.parameters.pixel_noise_sigma_px,
        );
        for (pixel, p) in self.frames[slot..slot + self.point_count]
            .iter_mut()
            .zip(true_points)
        {
            let (mut u, mut v) = self.true_camera.pixel_of(p.x, p.y);
            for coordinate in [&mut u, &mut v] {
                if uniform > 0.0 {
                    *coordinate += self.rng.random_range(-uniform..=uniform);
                }
                if sigma > 0.0 {
                    *coordinate += sigma * standard_normal(&mut self.rng);
                }
            }
            *pixel = Point2::new(u, v);
        }
        self.frame_times[slot / self.point_count] = time;
        self.latest_frame = Some(frame);
    }

    /// `x ← x + Δt L_x v` for every point, with the depths of `depths`.
    fn predict(
        &mut self,
        dt: f64,
        twist: &Vector6<f64>,
        depths: Depths<'_>,
    ) -> Result<(), MeasurementError> {
        assign_depths(depths, &self.normalized, &mut self.image_points)?;
        for (n, p) in self.normalized.iter_mut().zip(&self.image_points) {
            let (lx, ly) = point_interaction(p.x, p.y, 1.0 / p.depth);
            *n = Point2::new(
                p.x + dt * lx.transpose().dot(twist),
                p.y + dt * ly.transpose().dot(twist),
            );
        }
        Ok(())
    }
}

/// A standard normal draw by the Box–Muller transform: `√(−2 ln u₁) cos(2π u₂)` with `u₁ ∈ (0, 1]`, `u₂ ∈ [0, 1)`.
fn standard_normal(rng: &mut StdRng) -> f64 {
    let u1: f64 = 1.0 - rng.random::<f64>();
    let u2: f64 = rng.random();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}
