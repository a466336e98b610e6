//! The parameters of the measurement model ([`MeasurementParameters`]: noise, frame rate, latency, what to do between
//! frames, intrinsics, hand-eye and lens errors, filter), their exact default and their validation.

use super::{MeasurementError, ObserverParameters, MAX_LATENCY_FRAMES};
use crate::bounds::{PIXEL_NOISE_PX, RATE_HZ};
use crate::camera::{BrownConrady, CameraError};

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
    ///
    /// [`perturbed_eye_in_hand`]: super::perturbed_eye_in_hand
    pub hand_eye_translation_m: f64,
    /// Hand-eye rotation error (degrees, in `[0, 180]`) for [`perturbed_eye_in_hand`].
    ///
    /// [`perturbed_eye_in_hand`]: super::perturbed_eye_in_hand
    pub hand_eye_rotation_deg: f64,
    /// The true lens's Brown–Conrady coefficients `(k1, k2, p1, p2, k3)` (dimensionless); the nominal camera has the
    /// same.
    pub distortion_coefficients: [f64; 5],
    /// The controller's low-pass filter of the points it gets (s, ≥ 0; 0, the default: none): each period
    /// `x_f ← x_f + (1 − e^{−Δt/τ}) (x − x_f)` on the normalised coordinates, started at the first points. It trades
    /// pixel noise for a lag of about `τ` (which the depth estimator, fed with the filtered points, also sees).
    pub filter_time_constant_s: f64,
    /// The controller's feature observer ([`super::FeatureObserver`], [D32](crate::theory#d32)): the points predicted
    /// from the sent twist and corrected at each frame by a Kalman gain. It replaces `between_frames` and the filter
    /// (both must keep their defaults). `None`, the default: no observer.
    pub observer: Option<ObserverParameters>,
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
            observer: None,
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
        if let Some(observer) = &self.observer {
            observer.validate()?;
            if self.filter_time_constant_s > 0.0 || self.between_frames != BetweenFrames::Hold {
                return invalid(
                    "observer",
                    self.filter_time_constant_s,
                    "alone: the observer replaces between_frames = \"predict\" and filter_time_constant_s",
                );
            }
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
    pub(super) fn validate_hand_eye(&self) -> Result<(), MeasurementError> {
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

#[cfg(test)]
mod tests {
    use super::*;

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

    /// The observer reads from `[observer]`, is checked, and refuses the filter and the prediction it replaces.
    #[test]
    fn observer_is_read_checked_and_alone() {
        let parsed: MeasurementParameters =
            toml::from_str("[observer]\npixel_noise_px = 1.5\nlatency_s = 0.03\n").unwrap();
        let observer = parsed.observer.unwrap();
        assert_eq!((observer.pixel_noise_px, observer.latency_s), (1.5, 0.03));
        assert_eq!(observer.memory_s, ObserverParameters::default().memory_s);
        assert!(!parsed.is_exact());
        assert!(parsed.validate(0.002).is_ok());
        let name = |p: MeasurementParameters| match p.validate(0.002) {
            Err(MeasurementError::InvalidParameter { name, .. }) => name,
            other => panic!("{other:?}"),
        };
        let filtered = MeasurementParameters {
            filter_time_constant_s: 0.2,
            ..parsed
        };
        assert_eq!(name(filtered), "observer");
        let predicted = MeasurementParameters {
            between_frames: BetweenFrames::Predict,
            ..parsed
        };
        assert_eq!(name(predicted), "observer");
        let negative = MeasurementParameters {
            observer: Some(ObserverParameters {
                latency_s: -0.1,
                ..observer
            }),
            ..parsed
        };
        assert_eq!(name(negative), "observer.latency_s");
    }
}
