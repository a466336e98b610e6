//! The hand-eye (camera mount) error: the believed mount `eMc`, the true one perturbed by a translation and a rotation
//! of exact magnitudes along seeded random directions.

use super::{MeasurementError, MeasurementParameters};
use crate::camera::EyeInHand;
use nalgebra::{Isometry3, Unit, UnitQuaternion, Vector3};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};

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

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

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
}
