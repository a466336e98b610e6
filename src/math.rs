//! Conventions, type aliases and the small geometric helpers every module shares.
//!
//! These conventions are written once, here, and followed by the whole crate (the [theory reference](crate::theory#s0) states them with the equations):
//!
//! * **Units**: SI everywhere — metres, radians, seconds. Velocities are m/s and rad/s. Pixels appear only in
//!   [`crate::camera`]; every other module works with normalised image coordinates `x = X/Z`, `y = Y/Z`.
//! * **Twists** are 6-vectors `(v, ω)`: linear velocity **first**, then angular velocity, both expressed in one frame
//!   (as ViSP's `vpColVector` velocity screws). See [`Twist`].
//! * **Transforms**: a variable `a_from_b: Isometry3<f64>` (ViSP `aMb`) maps the coordinates of a point in frame `b` to
//!   its coordinates in frame `a`: `p_a = a_from_b * p_b`. Composition reads right to left:
//!   `a_from_c = a_from_b * b_from_c`.
//! * **Twist transforms**: `a_v_b` (ViSP `aVb`, a 6×6 [`TwistTransform`]) maps a twist of a rigid body expressed in frame
//!   `b` to the same rigid-body motion expressed in frame `a`: `v_a = a_v_b · v_b` ([\[M43\]](crate::theory#m43)).
//! * **Frames**: `f` or `base` (robot base), `e` (end effector), `c` (camera: z forward along the optical axis, x right,
//!   y down), `o` (object / target), `cd` (desired camera pose).
//! * **Joint space** is statically sized: `N` joints, [`JointVector<N>`]. Task spaces have a run-time number of rows.
//!
//! ```
//! use servostack::math::{skew, twist_transform};
//! use nalgebra::{Isometry3, Vector3};
//!
//! // The camera is 0.1 m along x of the end effector, not rotated.
//! let e_from_c = Isometry3::translation(0.1, 0.0, 0.0);
//! let c_v_e = twist_transform(&e_from_c.inverse());
//! // A pure rotation of the end effector about its z axis ...
//! let v_e = nalgebra::Vector6::new(0.0, 0.0, 0.0, 0.0, 0.0, 1.0);
//! // ... moves the camera origin sideways, by ω × (0.1, 0, 0) = (0, 0.1, 0), and turns it about its z axis.
//! let v_c = c_v_e * v_e;
//! assert!((v_c - nalgebra::Vector6::new(0.0, 0.1, 0.0, 0.0, 0.0, 1.0)).norm() < 1e-15);
//! assert_eq!(skew(&Vector3::x()) * Vector3::y(), Vector3::z());
//! ```

use nalgebra::{Isometry3, Matrix3, Matrix6, SMatrix, SVector, Vector3, Vector6};

/// A joint-space vector of `N` joints (positions in m or rad, velocities in m/s or rad/s, gradients).
///
/// nalgebra's `new(x, y, …)` exists only up to six components; for any `N`, build one from an array, a slice or a
/// function of the index:
///
/// ```
/// use servostack::math::JointVector;
/// let q = JointVector::<7>::from([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8]);
/// let same = JointVector::<7>::from_column_slice(&[0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.8]);
/// let ramp = JointVector::<7>::from_fn(|i, _| 0.1 * i as f64);
/// assert_eq!(q, same);
/// assert!((ramp[6] - 0.6).abs() < 1e-15);
/// assert_eq!(JointVector::<7>::zeros().len(), 7);
/// ```
pub type JointVector<const N: usize> = SVector<f64, N>;

/// An `N × N` joint-space matrix (projectors `P^A_i`, normal matrices).
pub type JointMatrix<const N: usize> = SMatrix<f64, N, N>;

/// A rigid-body velocity screw `(v, ω)`: linear velocity (m/s) first, then angular velocity (rad/s).
pub type Twist = Vector6<f64>;

/// A 6 × 6 twist transform `a_v_b` (ViSP `aVb`), [\[M43\]](crate::theory#m43).
pub type TwistTransform = Matrix6<f64>;

/// A 6 × `N` kinematic Jacobian: maps joint velocities to a twist `(v, ω)` in some frame.
pub type KinematicJacobian<const N: usize> = SMatrix<f64, 6, N>;

/// The skew-symmetric matrix `[t]×` such that `[t]× u = t × u`.
pub fn skew(t: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -t.z, t.y, t.z, 0.0, -t.x, -t.y, t.x, 0.0)
}

/// Twist transform `a_v_b` of a transform `a_from_b` ([\[M43\]](crate::theory#m43)):
///
/// ```text
/// a_v_b = [ aRb   [atb]× aRb ]
///         [  0        aRb    ]
/// ```
///
/// so that the twist `(v, ω)` of a rigid body expressed (and taken at the origin of) frame `b` becomes the same
/// motion expressed at the origin of frame `a`: `v_a = a_v_b · v_b`. With `a_from_b = c_from_e` this is the `cVe` of
/// [\[M42\]](crate::theory#m42).
pub fn twist_transform(a_from_b: &Isometry3<f64>) -> TwistTransform {
    let rotation = a_from_b.rotation.to_rotation_matrix().into_inner();
    let translation = a_from_b.translation.vector;
    let mut out = Matrix6::zeros();
    out.fixed_view_mut::<3, 3>(0, 0).copy_from(&rotation);
    out.fixed_view_mut::<3, 3>(0, 3)
        .copy_from(&(skew(&translation) * rotation));
    out.fixed_view_mut::<3, 3>(3, 3).copy_from(&rotation);
    out
}

/// Wraps an angle (rad) into `(−π, π]`, the convention for angular feature errors ([D8](crate::theory#d8)).
pub fn wrap_angle(angle: f64) -> f64 {
    let two_pi = 2.0 * std::f64::consts::PI;
    let wrapped = angle - two_pi * (angle / two_pi).round();
    if wrapped <= -std::f64::consts::PI {
        wrapped + two_pi
    } else {
        wrapped
    }
}

/// The first joint whose value is not finite, with that value, or `None` (for errors that name the offending entry).
pub fn first_non_finite<const N: usize>(q: &JointVector<N>) -> Option<(usize, f64)> {
    q.iter().copied().enumerate().find(|(_, v)| !v.is_finite())
}

/// The first entry of a matrix or vector (in column-major order) that is NaN or infinite, as `(row, column, value)`,
/// or `None`: the slow, precise companion of [`all_finite`] and [`all_finite_slice`] for error messages.
pub fn first_non_finite_entry<R, C, S>(
    m: &nalgebra::Matrix<f64, R, C, S>,
) -> Option<(usize, usize, f64)>
where
    R: nalgebra::Dim,
    C: nalgebra::Dim,
    S: nalgebra::RawStorage<f64, R, C>,
{
    let rows = m.nrows().max(1);
    m.iter()
        .enumerate()
        .find(|(_, v)| !v.is_finite())
        .map(|(k, &v)| (k % rows, k / rows, v))
}

/// `true` when every entry of a matrix or vector is finite (no NaN, no ±∞).
pub fn all_finite<R, C, S>(m: &nalgebra::Matrix<f64, R, C, S>) -> bool
where
    R: nalgebra::Dim,
    C: nalgebra::Dim,
    S: nalgebra::RawStorage<f64, R, C>,
{
    m.iter().all(|v| v.is_finite())
}

/// `true` when every value of the slice is finite: as [`all_finite`], on contiguous storage.
///
/// Entry by entry, with scalar loads, on purpose: the slices checked in the control step (interaction rows, task
/// errors and Jacobians) have just been written entry by entry, and a vector load that spans several stores still in
/// flight cannot take its data from them; it waits for them to commit, which cost up to 60 ns per check on the AVX
/// builds of the peer benchmark.
pub fn all_finite_slice(values: &[f64]) -> bool {
    values.iter().all(|v| v.is_finite())
}

/// The largest `s ∈ (0, 1]` such that `|s · v_i| ≤ max_i` for every joint: the uniform scaling of a joint velocity
/// `v` into the per-joint limits `max` (units of each joint per second; `+∞` for no limit), which keeps its direction.
/// `1` when `v` is within its limits. The limits must be `> 0`.
pub fn velocity_limit_scale<const N: usize>(
    velocity: &JointVector<N>,
    max: &JointVector<N>,
) -> f64 {
    velocity
        .iter()
        .zip(max.iter())
        .map(|(v, max)| if v.abs() > *max { max / v.abs() } else { 1.0 })
        .fold(1.0, f64::min)
}

/// The largest `σ ∈ [0, 1]` such that `|σ (target_i − previous_i)| ≤ a_i Δt` for every joint: the uniform scaling of
/// the change from the velocity sent last, `previous`, to `target` into the per-joint acceleration limits
/// `max_acceleration` (`a_i`, units of each joint per second squared, `> 0`; `+∞` for no limit) over the period
/// `period` (`Δt`, s, `≥ 0`). Sent as `previous + σ (target − previous)`, the change keeps its direction
/// ([D31](crate::theory#d31)). `1` when every change is within its limit; `0` when `Δt = 0` and a limited joint's
/// velocity changes.
pub fn acceleration_limit_scale<const N: usize>(
    previous: &JointVector<N>,
    target: &JointVector<N>,
    max_acceleration: &JointVector<N>,
    period: f64,
) -> f64 {
    let mut scale: f64 = 1.0;
    for ((p, t), a) in previous
        .iter()
        .zip(target.iter())
        .zip(max_acceleration.iter())
    {
        let change = (t - p).abs();
        if a.is_finite() && change > 0.0 {
            let allowed = a * period;
            if allowed < change {
                scale = scale.min(allowed / change);
            }
        }
    }
    scale.max(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use nalgebra::{Point3, UnitQuaternion};

    #[test]
    fn all_finite_slice_finds_every_non_finite_entry() {
        for len in 0..10 {
            let finite: Vec<f64> = (0..len)
                .map(|k| [f64::MAX, -0.0, -1.5e300, 3.0][k % 4])
                .collect();
            assert!(all_finite_slice(&finite), "{finite:?}");
            for at in 0..len {
                for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
                    let mut values = finite.clone();
                    values[at] = bad;
                    assert!(!all_finite_slice(&values), "{values:?}");
                }
            }
        }
    }

    /// The first non-finite entry is located in column-major order, with its row, column and value.
    #[test]
    fn first_non_finite_entry_names_row_column_and_value() {
        let mut m = nalgebra::Matrix3x2::<f64>::from_fn(|i, j| (i + 3 * j) as f64 - 2.5);
        assert_eq!(first_non_finite_entry(&m), None);
        m[(2, 1)] = f64::NEG_INFINITY;
        assert_eq!(first_non_finite_entry(&m), Some((2, 1, f64::NEG_INFINITY)));
        m[(1, 1)] = f64::INFINITY;
        m[(2, 0)] = f64::INFINITY;
        assert_eq!(first_non_finite_entry(&m), Some((2, 0, f64::INFINITY)));
    }

    #[test]
    fn skew_is_the_cross_product() {
        let t = Vector3::new(0.3, -1.2, 2.5);
        let u = Vector3::new(-0.7, 0.4, 1.1);
        assert_relative_eq!(skew(&t) * u, t.cross(&u), epsilon = 1e-15);
        assert_relative_eq!(skew(&t).transpose(), -skew(&t), epsilon = 0.0);
    }

    /// The twist transform must agree with moving rigid-body points: for a body moving with twist `v_b` (at the origin
    /// of b, in b), the velocity of a point p is `v + ω × p` in either frame.
    #[test]
    fn twist_transform_matches_point_velocities() {
        let a_from_b = Isometry3::from_parts(
            Vector3::new(0.2, -0.5, 1.3).into(),
            UnitQuaternion::from_euler_angles(0.4, -0.9, 2.1),
        );
        let v_b = Vector6::new(0.1, -0.2, 0.3, 0.7, -0.4, 0.25);
        let v_a = twist_transform(&a_from_b) * v_b;
        let p_b = Point3::new(0.3, 0.8, -0.6);
        let p_a = a_from_b * p_b;
        let vel_b = v_b.fixed_rows::<3>(0) + v_b.fixed_rows::<3>(3).cross(&p_b.coords);
        let vel_a = v_a.fixed_rows::<3>(0) + v_a.fixed_rows::<3>(3).cross(&p_a.coords);
        assert_relative_eq!(a_from_b.rotation * vel_b, vel_a, epsilon = 1e-14);
    }

    #[test]
    fn twist_transform_composes_and_inverts() {
        let a_from_b = Isometry3::new(Vector3::new(0.1, 0.2, 0.3), Vector3::new(0.3, -0.2, 0.9));
        let b_from_c = Isometry3::new(Vector3::new(-0.4, 0.6, 0.1), Vector3::new(-1.1, 0.5, 0.2));
        assert_relative_eq!(
            twist_transform(&(a_from_b * b_from_c)),
            twist_transform(&a_from_b) * twist_transform(&b_from_c),
            epsilon = 1e-14
        );
        assert_relative_eq!(
            twist_transform(&a_from_b.inverse()) * twist_transform(&a_from_b),
            Matrix6::identity(),
            epsilon = 1e-14
        );
    }

    #[test]
    fn wrap_angle_lands_in_half_open_interval() {
        use std::f64::consts::PI;
        assert_relative_eq!(wrap_angle(3.0 * PI), PI, epsilon = 1e-12);
        assert_relative_eq!(wrap_angle(-PI), PI, epsilon = 1e-12);
        assert_relative_eq!(wrap_angle(0.5 - 4.0 * PI), 0.5, epsilon = 1e-12);
        assert_relative_eq!(wrap_angle(-0.5), -0.5, epsilon = 0.0);
    }
}
