//! Measurement model: what a real camera delivers to the controller, built from the true image at each control period.
//!
//! One [`MeasurementModel::measure`] call per control period, at time `t`, with the true image points (normalised
//! `x = X/Z`, `y = Y/Z` and depth `Z` in the **true** camera frame):
//!
//! 1. **Frames.** The camera captures a frame at the first control period at or after each frame time
//!    `t₀ + n / camera_rate_hz` (`n = 0, 1, …`; every period when `camera_rate_hz` is absent). A frame is the true
//!    image through the **true** camera: pixel `(u, v) = (cx + fx x_d, cy + fy y_d)` with `(x_d, y_d)` the true
//!    Brown–Conrady distortion of `(x, y)` ([`crate::camera::CalibratedCamera::pixel_of`]), plus seeded noise on each
//!    coordinate: uniform in `±pixel_noise_uniform_px` and Gaussian of standard deviation `pixel_noise_sigma_px`
//!    (Box–Muller), both in px.
//! 2. **Latency.** The frame delivered at `t` is the one captured `latency_frames` frames earlier: frame `n − d` when
//!    frame `n` is the latest (a ring buffer of `d + 1` frames allocated at construction; frame 0 until `d` more frames
//!    exist, as if the camera had been still before `t₀`).
//! 3. **Controller side.** When a new frame is delivered, its pixels go back to normalised coordinates through the
//!    **nominal** (believed) camera: `(x_d, y_d) = ((u − ĉx)/f̂x, (v − ĉy)/f̂y)`, then undistortion. The nominal
//!    intrinsics are the true ones with each of `fx, fy, cx, cy` scaled by `1 ± intrinsics_error_fraction` (sign drawn
//!    per parameter from the seed: the error magnitude is exactly the fraction); the nominal distortion is the true one.
//! 4. **Between frames**, [`BetweenFrames::Hold`] keeps the last delivered points, [`BetweenFrames::Predict`] moves
//!    them with the point interaction rows \[M28\] and the known camera twist `v` applied over the last period `Δt`:
//!    `x ← x + Δt L_x(x, y, 1/Ẑ) v`, `y ← y + Δt L_y(x, y, 1/Ẑ) v`, with the depths `Ẑ` of the caller's depth source.
//!
//! The hand-eye (camera mount) error is a perturbation of `eMc` between the true and the believed robot:
//! [`perturbed_mount`] and [`perturbed_eye_in_hand`] draw it from a seed with exact magnitudes.
//!
//! [`MeasurementParameters::default`] is the exact, noise-free, instantaneous camera: [`MeasurementParameters::is_exact`]
//! lets a simulation skip the model and keep its results bit for bit.
//!
//! [`MeasurementModel::measure`] allocates nothing.

use crate::bounds::{PIXEL_NOISE_PX, RATE_HZ};
use crate::camera::{
    BrownConrady, CalibratedCamera, CameraError, CameraIntrinsics, EyeInHand, ImagePoint,
};
use crate::depth::{assign_depths, DepthError, Depths};
use crate::feature::point_interaction;
use nalgebra::{Isometry3, Point2, Unit, UnitQuaternion, Vector3, Vector6};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};

/// Largest `latency_frames` accepted (the ring buffer holds `latency_frames + 1` frames).
pub const MAX_LATENCY_FRAMES: usize = 1000;

/// Errors of the measurement model. Each variant carries the offending values.
#[non_exhaustive]
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MeasurementError {
    /// A parameter is out of range.
    #[error("measurement parameter `{name}` = {value} is invalid: {expected}")]
    InvalidParameter {
        /// The parameter.
        name: &'static str,
        /// Its value.
        value: f64,
        /// What is expected.
        expected: &'static str,
    },
    /// The number of points differs from the one the model was built for.
    #[error("{got} points, expected {expected}")]
    PointCountMismatch {
        /// Expected count.
        expected: usize,
        /// Count given.
        got: usize,
    },
    /// A true image point is NaN or infinite, or at or behind the camera.
    #[error("true image point {index} is invalid: ({x}, {y}), depth {depth} m")]
    InvalidPoint {
        /// Index of the point.
        index: usize,
        /// Normalised abscissa.
        x: f64,
        /// Normalised ordinate.
        y: f64,
        /// Depth (m).
        depth: f64,
    },
    /// The camera twist has a NaN or infinite component.
    #[error("camera twist is not finite: {twist:?}")]
    NonFiniteTwist {
        /// The twist `(υ, ω)`.
        twist: [f64; 6],
    },
    /// The time of a call is not after the previous one (or is not finite).
    #[error("time {time} s is not after the previous measurement at {previous} s")]
    TimeNotIncreasing {
        /// The previous call's time (s).
        previous: f64,
        /// This call's time (s).
        time: f64,
    },
    /// Undistortion of a delivered pixel through the nominal camera failed.
    #[error(transparent)]
    Camera(#[from] CameraError),
    /// The depths used for prediction are unusable.
    #[error(transparent)]
    Depth(#[from] DepthError),
}

/// What the controller sees between two delivered frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BetweenFrames {
    /// The last delivered frame's points.
    #[default]
    Hold,
    /// The last points moved by `Δt L_x v` each period (module docs).
    Predict,
}

/// The camera the controller has, compared with the true one (module docs). Units are in the names. The default is
/// the exact, noise-free, instantaneous camera.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MeasurementParameters {
    /// Half-width `a` (px, in `[0, 1000]`) of the uniform noise added to each pixel coordinate: `U(−a, a)`.
    pub pixel_noise_uniform_px: f64,
    /// Standard deviation `σ` (px, in `[0, 1000]`) of the Gaussian noise added to each pixel coordinate.
    pub pixel_noise_sigma_px: f64,
    /// Seed of every random draw of a run (noise and intrinsics error signs).
    pub seed: u64,
    /// Frame rate (Hz, > 0, at most the control rate); absent: a frame every control period.
    pub camera_rate_hz: Option<f64>,
    /// Latency in whole frames (0 to [`MAX_LATENCY_FRAMES`]).
    pub latency_frames: usize,
    /// Hold or predict the points between frames.
    pub between_frames: BetweenFrames,
    /// Relative error `ε` (in `[0, 0.5)`) of each of the nominal `fx, fy, cx, cy`: nominal = true · (1 ± ε).
    pub intrinsics_error_fraction: f64,
    /// Hand-eye translation error (m, in `[0, 1000]`) for [`perturbed_eye_in_hand`].
    pub hand_eye_translation_m: f64,
    /// Hand-eye rotation error (degrees, in `[0, 180]`) for [`perturbed_eye_in_hand`].
    pub hand_eye_rotation_deg: f64,
    /// The true lens's Brown–Conrady coefficients `(k1, k2, p1, p2, k3)` (dimensionless); the nominal camera has the
    /// same.
    pub distortion_coefficients: [f64; 5],
    /// The controller's low-pass filter of the points it gets (s, ≥ 0; 0, the default: none): each period
    /// `x_f ← x_f + (1 − e^{−Δt/τ}) (x − x_f)` on the normalised coordinates, started at the first points. It trades
    /// pixel noise for a lag of about `τ` (which the depth estimator, fed with the filtered points, also sees).
    pub filter_time_constant_s: f64,
}

impl Default for MeasurementParameters {
    fn default() -> Self {
        Self {
            pixel_noise_uniform_px: 0.0,
            pixel_noise_sigma_px: 0.0,
            seed: 0,
            camera_rate_hz: None,
            latency_frames: 0,
            between_frames: BetweenFrames::Hold,
            intrinsics_error_fraction: 0.0,
            hand_eye_translation_m: 0.0,
            hand_eye_rotation_deg: 0.0,
            distortion_coefficients: [0.0; 5],
            filter_time_constant_s: 0.0,
        }
    }
}

impl MeasurementParameters {
    /// `true` for the exact camera: no noise, a frame every period, no latency, no intrinsics or hand-eye error, no
    /// distortion (a simulation may then use the true image directly).
    pub fn is_exact(&self) -> bool {
        let exact = Self {
            seed: self.seed,
            between_frames: self.between_frames,
            ..Self::default()
        };
        *self == exact
    }

    /// Checks every parameter against the control period `period` (s).
    ///
    /// # Errors
    /// [`MeasurementError::InvalidParameter`] naming the first invalid parameter.
    pub fn validate(&self, period: f64) -> Result<(), MeasurementError> {
        let invalid = |name, value, expected| {
            Err(MeasurementError::InvalidParameter {
                name,
                value,
                expected,
            })
        };
        let non_negative = |v: f64| v.is_finite() && v >= 0.0;
        if !(period.is_finite() && period > 0.0) {
            return invalid("period", period, "finite and > 0 (s)");
        }
        for (name, value) in [
            ("pixel_noise_uniform_px", self.pixel_noise_uniform_px),
            ("pixel_noise_sigma_px", self.pixel_noise_sigma_px),
        ] {
            if !PIXEL_NOISE_PX.contains(value) {
                return invalid(name, value, PIXEL_NOISE_PX.text);
            }
        }
        if let Some(rate) = self.camera_rate_hz {
            if !(RATE_HZ.contains(rate) && rate * period <= 1.0 + 1e-9) {
                return invalid(
                    "camera_rate_hz",
                    rate,
                    "within [1/3600, 1e6] Hz and at most the control rate 1/period",
                );
            }
        }
        if self.latency_frames > MAX_LATENCY_FRAMES {
            return invalid(
                "latency_frames",
                self.latency_frames as f64,
                "at most 1000 frames",
            );
        }
        if !(non_negative(self.intrinsics_error_fraction) && self.intrinsics_error_fraction < 0.5) {
            return invalid(
                "intrinsics_error_fraction",
                self.intrinsics_error_fraction,
                "in [0, 0.5)",
            );
        }
        self.validate_hand_eye()?;
        if !(non_negative(self.filter_time_constant_s) && self.filter_time_constant_s <= 3600.0) {
            return invalid(
                "filter_time_constant_s",
                self.filter_time_constant_s,
                "in [0, 3600] s",
            );
        }
        let [k1, k2, p1, p2, k3] = self.distortion_coefficients;
        if let Err(CameraError::InvalidDistortion { value, .. }) =
            BrownConrady::new(k1, k2, p1, p2, k3)
        {
            return invalid("distortion_coefficients", value, "finite");
        }
        Ok(())
    }
}

impl MeasurementParameters {
    /// Checks `hand_eye_translation_m` and `hand_eye_rotation_deg`.
    fn validate_hand_eye(&self) -> Result<(), MeasurementError> {
        let invalid = |name, value, expected| {
            Err(MeasurementError::InvalidParameter {
                name,
                value,
                expected,
            })
        };
        let non_negative = |v: f64| v.is_finite() && v >= 0.0;
        if !(non_negative(self.hand_eye_translation_m)
            && crate::bounds::LENGTH_M.contains(self.hand_eye_translation_m))
        {
            return invalid(
                "hand_eye_translation_m",
                self.hand_eye_translation_m,
                "within [0, 1000] m",
            );
        }
        if !(non_negative(self.hand_eye_rotation_deg) && self.hand_eye_rotation_deg <= 180.0) {
            return invalid(
                "hand_eye_rotation_deg",
                self.hand_eye_rotation_deg,
                "in [0, 180] (degrees)",
            );
        }
        Ok(())
    }
}

/// The mount `e_from_c` perturbed in the camera frame by a translation of exactly `translation_m` (m) along a random
/// direction and a rotation of exactly `rotation_deg` (degrees) about a random axis, both drawn uniformly on the unit
/// sphere from `seed`: `e_from_c · (t, R)`. Deterministic for a given seed.
pub fn perturbed_mount(
    e_from_c: &Isometry3<f64>,
    translation_m: f64,
    rotation_deg: f64,
    seed: u64,
) -> Isometry3<f64> {
    let mut rng = StdRng::seed_from_u64(seed);
    let translation = unit_vector(&mut rng).into_inner() * translation_m;
    let rotation =
        UnitQuaternion::from_axis_angle(&unit_vector(&mut rng), rotation_deg.to_radians());
    e_from_c * Isometry3::from_parts(translation.into(), rotation)
}

/// The believed camera of an eye-in-hand mount with the hand-eye error of `parameters`
/// (`hand_eye_translation_m`, `hand_eye_rotation_deg`, `seed`), see [`perturbed_mount`].
///
/// # Errors
/// [`MeasurementError::InvalidParameter`] for invalid magnitudes.
pub fn perturbed_eye_in_hand(
    camera: &EyeInHand,
    parameters: &MeasurementParameters,
) -> Result<EyeInHand, MeasurementError> {
    parameters.validate_hand_eye()?;
    let mount = perturbed_mount(
        camera.e_from_c(),
        parameters.hand_eye_translation_m,
        parameters.hand_eye_rotation_deg,
        parameters.seed,
    );
    Ok(EyeInHand::new(mount)?)
}

/// A direction drawn uniformly on the unit sphere (`z` uniform in `[−1, 1]`, azimuth uniform).
fn unit_vector(rng: &mut StdRng) -> Unit<Vector3<f64>> {
    let z: f64 = rng.random_range(-1.0..=1.0);
    let azimuth: f64 = rng.random_range(0.0..std::f64::consts::TAU);
    let radius = (1.0 - z * z).max(0.0).sqrt();
    Unit::new_normalize(Vector3::new(
        radius * azimuth.cos(),
        radius * azimuth.sin(),
        z,
    ))
}

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

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    fn intrinsics() -> CameraIntrinsics {
        CameraIntrinsics::new(600.0, 610.0, 320.0, 240.0, 640.0, 480.0).unwrap()
    }

    /// A square of four points whose image slides along x at 0.1 /s: x_k(t) = x_k(0) + 0.1 t.
    fn sliding(t: f64) -> [ImagePoint; 4] {
        [(-0.1, -0.1), (0.1, -0.1), (0.1, 0.1), (-0.1, 0.1)]
            .map(|(x, y)| ImagePoint::new(x + 0.1 * t, y, 0.5))
    }

    const STILL: Vector6<f64> = Vector6::new(0.0, 0.0, 0.0, 0.0, 0.0, 0.0);

    #[test]
    fn default_is_the_exact_instantaneous_camera() {
        let parameters = MeasurementParameters::default();
        assert!(parameters.is_exact());
        let mut model = MeasurementModel::new(&parameters, intrinsics(), 4, 0.01).unwrap();
        for step in 0..5 {
            let t = 0.01 * step as f64;
            let truth = sliding(t);
            let m = model
                .measure(t, &truth, &STILL, Depths::Constant(0.5))
                .unwrap();
            assert!(m.fresh);
            assert_eq!(m.frame_time, t);
            for (n, p) in m.normalized.iter().zip(&truth) {
                assert!((n.x - p.x).abs() < 1e-15 && (n.y - p.y).abs() < 1e-15);
            }
            // Pixels by hand: u = 320 + 600 x, v = 240 + 610 y.
            assert_relative_eq!(
                m.pixels[2].x,
                320.0 + 600.0 * (0.1 + 0.1 * t),
                epsilon = 1e-12
            );
            assert_relative_eq!(m.pixels[2].y, 240.0 + 61.0, epsilon = 1e-12);
        }
        let noisy = MeasurementParameters {
            pixel_noise_sigma_px: 0.1,
            ..parameters
        };
        assert!(!noisy.is_exact());
    }

    /// Noise statistics over 20 000 coordinates: uniform stays in ±a with variance a²/3; Gaussian has variance σ².
    /// The same seed gives the same noise, another seed another.
    #[test]
    fn pixel_noise_has_its_distribution_and_is_seeded() {
        let deviations = |parameters: &MeasurementParameters| -> Vec<f64> {
            let mut model = MeasurementModel::new(parameters, intrinsics(), 4, 0.01).unwrap();
            let truth = sliding(0.0);
            let exact: Vec<(f64, f64)> = truth
                .iter()
                .map(|p| model.true_camera().pixel_of(p.x, p.y))
                .collect();
            let mut out = Vec::new();
            for step in 0..2500 {
                let m = model
                    .measure(0.01 * step as f64, &truth, &STILL, Depths::Constant(0.5))
                    .unwrap();
                for (p, e) in m.pixels.iter().zip(&exact) {
                    out.extend([p.x - e.0, p.y - e.1]);
                }
            }
            out
        };
        let moments = |d: &[f64]| {
            let mean = d.iter().sum::<f64>() / d.len() as f64;
            (
                mean,
                d.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / d.len() as f64,
            )
        };
        let uniform = MeasurementParameters {
            pixel_noise_uniform_px: 2.0,
            seed: 11,
            ..Default::default()
        };
        let d = deviations(&uniform);
        assert!(d.iter().all(|v| v.abs() <= 2.0 + 1e-9));
        let (mean, variance) = moments(&d);
        // Standard error of the mean: √(4/3 / 20000) ≈ 0.008.
        assert!(mean.abs() < 0.04, "{mean}");
        assert!((variance - 4.0 / 3.0).abs() < 0.05, "{variance}");
        assert_eq!(d, deviations(&uniform));
        assert_ne!(
            d,
            deviations(&MeasurementParameters {
                seed: 12,
                ..uniform
            })
        );
        let gaussian = MeasurementParameters {
            pixel_noise_sigma_px: 1.5,
            seed: 3,
            ..Default::default()
        };
        let (mean, variance) = moments(&deviations(&gaussian));
        assert!(mean.abs() < 0.05, "{mean}");
        assert!((variance.sqrt() - 1.5).abs() < 0.03, "{}", variance.sqrt());
    }

    /// A 30 Hz camera under 500 Hz control: 30 frames in the first second, each at the first control period at or
    /// after n/30 s; points held in between.
    #[test]
    fn slower_camera_delivers_frames_at_its_rate_and_holds_between() {
        let parameters = MeasurementParameters {
            camera_rate_hz: Some(30.0),
            ..Default::default()
        };
        let dt = 0.002;
        let mut model = MeasurementModel::new(&parameters, intrinsics(), 4, dt).unwrap();
        let mut frame_times = Vec::new();
        for step in 0..500 {
            let t = step as f64 * dt;
            let m = model
                .measure(t, &sliding(t), &STILL, Depths::Constant(0.5))
                .unwrap();
            if m.fresh {
                frame_times.push(t);
            }
            assert_relative_eq!(
                m.normalized[0].x,
                sliding(m.frame_time)[0].x,
                epsilon = 1e-12
            );
        }
        assert_eq!(frame_times.len(), 30);
        for (n, t) in frame_times.iter().enumerate() {
            let due = n as f64 / 30.0;
            assert!(*t >= due - 1e-9 && *t < due + dt, "frame {n} at {t}");
        }
    }

    /// Latency of two frames: what is delivered was captured two frames earlier (the first frame until then).
    #[test]
    fn latency_delivers_older_frames() {
        let parameters = MeasurementParameters {
            camera_rate_hz: Some(25.0),
            latency_frames: 2,
            ..Default::default()
        };
        let dt = 0.01;
        let mut model = MeasurementModel::new(&parameters, intrinsics(), 4, dt).unwrap();
        let mut captures = Vec::new();
        for step in 0..100 {
            let t = step as f64 * dt;
            let m = model
                .measure(t, &sliding(t), &STILL, Depths::Constant(0.5))
                .unwrap();
            if step % 4 == 0 {
                captures.push(t);
            }
            let expected_frame = captures.len().saturating_sub(3);
            assert_relative_eq!(m.frame_time, captures[expected_frame], epsilon = 1e-12);
            assert_relative_eq!(
                m.normalized[1].x,
                sliding(m.frame_time)[1].x,
                epsilon = 1e-12
            );
        }
    }

    /// Prediction between frames follows a camera translating along x (every point moves by ẋ = −υx/Z): the predicted
    /// points stay on the truth, the held ones lag.
    #[test]
    fn prediction_follows_the_known_twist() {
        let twist = Vector6::new(0.05, 0.0, 0.0, 0.0, 0.0, 0.0);
        // x(t) = x(0) − υx t / Z with Z = 0.5.
        let truth = |t: f64| sliding(0.0).map(|p| ImagePoint::new(p.x - 0.1 * t, p.y, 0.5));
        let run = |between_frames| {
            let parameters = MeasurementParameters {
                camera_rate_hz: Some(10.0),
                between_frames,
                ..Default::default()
            };
            let mut model = MeasurementModel::new(&parameters, intrinsics(), 4, 0.01).unwrap();
            let mut worst = 0.0_f64;
            for step in 0..50 {
                let t = step as f64 * 0.01;
                let m = model
                    .measure(t, &truth(t), &twist, Depths::Constant(0.5))
                    .unwrap();
                worst = worst.max((m.normalized[3].x - truth(t)[3].x).abs());
            }
            worst
        };
        let (held, predicted) = (run(BetweenFrames::Hold), run(BetweenFrames::Predict));
        // Held: up to 9 periods behind, 9 · 0.01 · 0.1 = 0.009.
        assert_relative_eq!(held, 0.009, epsilon = 1e-9);
        assert!(predicted < 1e-12, "{predicted}");
    }

    /// With distortion and exact intrinsics the controller gets the true points back; with an intrinsics error each
    /// nominal parameter is off by exactly ±ε.
    #[test]
    fn distortion_and_intrinsics_error() {
        let distorted = MeasurementParameters {
            distortion_coefficients: [-0.3, 0.1, 0.001, -0.002, 0.01],
            ..Default::default()
        };
        let mut model = MeasurementModel::new(&distorted, intrinsics(), 4, 0.01).unwrap();
        let truth = sliding(1.0);
        let m = model
            .measure(0.0, &truth, &STILL, Depths::Constant(0.5))
            .unwrap();
        // The pixel is displaced by the lens: x = 0.2 gives x_d ≠ x.
        assert!((m.pixels[1].x - (320.0 + 600.0 * 0.2)).abs() > 1.0);
        for (n, p) in m.normalized.iter().zip(&truth) {
            assert!((n.x - p.x).abs() < 1e-11 && (n.y - p.y).abs() < 1e-11);
        }
        let wrong = MeasurementParameters {
            intrinsics_error_fraction: 0.05,
            seed: 5,
            ..Default::default()
        };
        let model = MeasurementModel::new(&wrong, intrinsics(), 4, 0.01).unwrap();
        let (t, n) = (
            model.true_camera().intrinsics,
            model.nominal_camera().intrinsics,
        );
        for (true_value, nominal) in [
            (t.fx(), n.fx()),
            (t.fy(), n.fy()),
            (t.cx(), n.cx()),
            (t.cy(), n.cy()),
        ] {
            assert_relative_eq!((nominal / true_value - 1.0).abs(), 0.05, epsilon = 1e-12);
        }
    }

    /// The perturbed mount is off by exactly the given translation and rotation, deterministically per seed.
    #[test]
    fn hand_eye_perturbation_has_exact_magnitudes() {
        let mount = Isometry3::new(Vector3::new(0.01, 0.0, 0.2), Vector3::new(0.1, 1.5, -0.3));
        for seed in 0..20 {
            let perturbed = perturbed_mount(&mount, 0.01, 2.0, seed);
            let delta = mount.inverse() * perturbed;
            assert_relative_eq!(delta.translation.vector.norm(), 0.01, epsilon = 1e-12);
            assert_relative_eq!(delta.rotation.angle(), 2f64.to_radians(), epsilon = 1e-12);
            assert_eq!(perturbed, perturbed_mount(&mount, 0.01, 2.0, seed));
        }
        assert_ne!(
            perturbed_mount(&mount, 0.01, 2.0, 1),
            perturbed_mount(&mount, 0.01, 2.0, 2)
        );
        let camera = EyeInHand::new(mount).unwrap();
        // The other parameters (here a camera rate) do not matter to the mount.
        let parameters = MeasurementParameters {
            hand_eye_translation_m: 0.01,
            hand_eye_rotation_deg: 2.0,
            seed: 4,
            camera_rate_hz: Some(30.0),
            ..Default::default()
        };
        let believed = perturbed_eye_in_hand(&camera, &parameters).unwrap();
        assert_eq!(*believed.e_from_c(), perturbed_mount(&mount, 0.01, 2.0, 4));
        let bad = MeasurementParameters {
            hand_eye_rotation_deg: 200.0,
            ..parameters
        };
        assert!(matches!(
            perturbed_eye_in_hand(&camera, &bad),
            Err(MeasurementError::InvalidParameter {
                name: "hand_eye_rotation_deg",
                ..
            })
        ));
    }

    #[test]
    fn invalid_parameters_are_named() {
        let cases: [(&str, MeasurementParameters); 9] = [
            (
                "filter_time_constant_s",
                MeasurementParameters {
                    filter_time_constant_s: -0.1,
                    ..Default::default()
                },
            ),
            (
                "pixel_noise_uniform_px",
                MeasurementParameters {
                    pixel_noise_uniform_px: -1.0,
                    ..Default::default()
                },
            ),
            (
                "pixel_noise_sigma_px",
                MeasurementParameters {
                    pixel_noise_sigma_px: f64::NAN,
                    ..Default::default()
                },
            ),
            (
                "camera_rate_hz",
                MeasurementParameters {
                    camera_rate_hz: Some(0.0),
                    ..Default::default()
                },
            ),
            (
                "camera_rate_hz",
                MeasurementParameters {
                    camera_rate_hz: Some(200.0),
                    ..Default::default()
                },
            ),
            (
                "latency_frames",
                MeasurementParameters {
                    latency_frames: 5000,
                    ..Default::default()
                },
            ),
            (
                "intrinsics_error_fraction",
                MeasurementParameters {
                    intrinsics_error_fraction: 0.5,
                    ..Default::default()
                },
            ),
            (
                "hand_eye_translation_m",
                MeasurementParameters {
                    hand_eye_translation_m: f64::INFINITY,
                    ..Default::default()
                },
            ),
            (
                "distortion_coefficients",
                MeasurementParameters {
                    distortion_coefficients: [0.0, f64::NAN, 0.0, 0.0, 0.0],
                    ..Default::default()
                },
            ),
        ];
        for (name, parameters) in cases {
            match MeasurementModel::new(&parameters, intrinsics(), 4, 0.01) {
                Err(MeasurementError::InvalidParameter { name: found, .. }) => {
                    assert_eq!(found, name)
                }
                other => panic!("{name}: {other:?}"),
            }
        }
        assert!(matches!(
            MeasurementModel::new(&MeasurementParameters::default(), intrinsics(), 4, 0.0),
            Err(MeasurementError::InvalidParameter { name: "period", .. })
        ));
        assert!(matches!(
            MeasurementModel::new(&MeasurementParameters::default(), intrinsics(), 0, 0.01),
            Err(MeasurementError::InvalidParameter {
                name: "point_count",
                ..
            })
        ));
    }

    #[test]
    fn bad_measurements_are_named() {
        let predict = MeasurementParameters {
            camera_rate_hz: Some(10.0),
            between_frames: BetweenFrames::Predict,
            ..Default::default()
        };
        let mut model = MeasurementModel::new(&predict, intrinsics(), 4, 0.01).unwrap();
        let truth = sliding(0.0);
        let depths = Depths::Constant(0.5);
        assert_eq!(
            model.measure(0.0, &truth[..3], &STILL, depths).err(),
            Some(MeasurementError::PointCountMismatch {
                expected: 4,
                got: 3
            })
        );
        let mut nan = truth;
        nan[2].x = f64::NAN;
        assert!(matches!(
            model.measure(0.0, &nan, &STILL, depths),
            Err(MeasurementError::InvalidPoint { index: 2, .. })
        ));
        let mut behind = truth;
        behind[1].depth = -0.1;
        assert!(matches!(
            model.measure(0.0, &behind, &STILL, depths),
            Err(MeasurementError::InvalidPoint { index: 1, .. })
        ));
        let mut bad_twist = STILL;
        bad_twist[0] = f64::NAN;
        assert!(matches!(
            model.measure(0.0, &truth, &bad_twist, depths),
            Err(MeasurementError::NonFiniteTwist { .. })
        ));
        model.measure(0.0, &truth, &STILL, depths).unwrap();
        for time in [0.0, -0.01, f64::NAN] {
            assert!(matches!(
                model.measure(time, &truth, &STILL, depths),
                Err(MeasurementError::TimeNotIncreasing { .. })
            ));
        }
        // Between frames, prediction needs usable depths.
        assert!(matches!(
            model.measure(0.01, &truth, &STILL, Depths::Constant(-1.0)),
            Err(MeasurementError::Depth(DepthError::NonPositiveDepth { .. }))
        ));
    }

    #[test]
    fn parameters_read_from_toml_with_units_in_names() {
        let parsed: MeasurementParameters = toml::from_str(
            "pixel_noise_uniform_px = 2.0\ncamera_rate_hz = 30.0\nlatency_frames = 1\nbetween_frames = \"predict\"\n\
             intrinsics_error_fraction = 0.05\nhand_eye_translation_m = 0.01\nhand_eye_rotation_deg = 2.0\nseed = 9\n",
        )
        .unwrap();
        assert_eq!(parsed.camera_rate_hz, Some(30.0));
        assert_eq!(parsed.between_frames, BetweenFrames::Predict);
        assert_eq!(parsed.pixel_noise_sigma_px, 0.0);
        let empty: MeasurementParameters = toml::from_str("").unwrap();
        assert!(empty.is_exact());
        assert!(toml::from_str::<MeasurementParameters>("pixel_noise = 2.0").is_err());
    }
}
