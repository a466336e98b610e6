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
//!    The [`FeatureObserver`] (`observer`) does better: it predicts the same way and corrects at each frame against
//!    the estimate of the frame's capture time, weighing the noise against the prediction's error
//!    ([D32](crate::theory#d32)); a simulation runs it on the delivered frames.
//!
//! The hand-eye (camera mount) error is a perturbation of `eMc` between the true and the believed robot:
//! [`perturbed_mount`] and [`perturbed_eye_in_hand`] draw it from a seed with exact magnitudes.
//!
//! [`MeasurementParameters::default`] is the exact, noise-free, instantaneous camera: [`MeasurementParameters::is_exact`]
//! lets a simulation skip the model and keep its results bit for bit.
//!
//! [`MeasurementModel::measure`] allocates nothing.

mod error;
mod hand_eye;
mod model;
mod observer;
mod parameters;
#[cfg(test)]
mod tests;

pub use error::MeasurementError;
pub use hand_eye::{perturbed_eye_in_hand, perturbed_mount};
pub use model::{Measurement, MeasurementModel};
pub use observer::{
    FeatureObserver, ObserverParameters, ObserverStep, OBSERVED_POINTS, OBSERVER_HISTORY,
};
pub use parameters::{BetweenFrames, MeasurementParameters};

/// Largest `latency_frames` accepted (the ring buffer holds `latency_frames + 1` frames).
pub const MAX_LATENCY_FRAMES: usize = 1000;
