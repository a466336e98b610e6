//! Forward kinematics and geometric Jacobians of a [`SerialChain`], written into a preallocated workspace.

use super::{ChainLink, Joint, JointKind, MimicJoint, RobotError, SerialChain};
use crate::bounds::KINEMATIC_COORDINATE;
use crate::math::{JointVector, KinematicJacobian};
use nalgebra::{Isometry3, Point3, SMatrix, Translation3, UnitQuaternion, Vector3};

/// Everything one kinematic evaluation computes, for `N` joints, read through the reference
/// [`SerialChain::kinematics`] returns. All frames and vectors are in the base frame unless named otherwise.
#[derive(Debug, Clone, PartialEq)]
pub struct KinematicState<const N: usize> {
    q: JointVector<N>,
    base_from_segment: [Isometry3<f64>; N],
    axes: [Vector3<f64>; N],
    rotational: [bool; N],
    base_from_tip: Isometry3<f64>,
    base_jacobian: KinematicJacobian<N>,
    tip_jacobian: KinematicJacobian<N>,
}

/// Preallocated storage for [`SerialChain::kinematics`] (the `Data` of the model/data split). Holds no heap memory;
/// build it once and reuse it for every control step.
#[derive(Debug, Clone, PartialEq)]
pub struct KinematicsWorkspace<const N: usize> {
    state: KinematicState<N>,
}

impl<const N: usize> KinematicsWorkspace<N> {
    /// A workspace for chains of `N` joints (its content is meaningless until the first evaluation).
    pub fn new() -> Self {
        Self {
            state: KinematicState {
                q: JointVector::zeros(),
                base_from_segment: [Isometry3::identity(); N],
                axes: [Vector3::zeros(); N],
                rotational: [true; N],
                base_from_tip: Isometry3::identity(),
                base_jacobian: KinematicJacobian::zeros(),
                tip_jacobian: KinematicJacobian::zeros(),
            },
        }
    }
}

impl<const N: usize> Default for KinematicsWorkspace<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> SerialChain<N> {
    /// Forward kinematics and both geometric Jacobians at joint positions `q` (rad or m), written into `workspace`
    /// (see the [module docs](super) for the equations). Allocates nothing.
    ///
    /// # Errors
    /// [`RobotError::NonFiniteJoint`] when an entry of `q` is NaN or infinite; [`RobotError::OutOfRange`] (field
    /// `"position"`) beyond [`KINEMATIC_COORDINATE`], which keeps the pose and the Jacobians finite by construction.
    /// Positions outside the joint limits are accepted (the limits are the caller's business: see
    /// [`SerialChain::within_limits`]).
    pub fn kinematics<'w>(
        &self,
        workspace: &'w mut KinematicsWorkspace<N>,
        q: &JointVector<N>,
    ) -> Result<&'w KinematicState<N>, RobotError> {
        self.poses(&mut workspace.state, q)?;
        self.jacobians(&mut workspace.state);
        Ok(&workspace.state)
    }

    /// Forward kinematics alone: `base_from_tip` (ViSP `fMe`) at joint positions `q`, without the Jacobians, for
    /// callers that need the pose only (a cost's value, most of the time). The same operations in the same order as
    /// [`SerialChain::kinematics`], so the same bits. Allocates nothing.
    ///
    /// # Errors
    /// As [`SerialChain::kinematics`].
    pub fn tip_pose(
        &self,
        workspace: &mut KinematicsWorkspace<N>,
        q: &JointVector<N>,
    ) -> Result<Isometry3<f64>, RobotError> {
        self.poses(&mut workspace.state, q)?;
        Ok(workspace.state.base_from_tip)
    }

    /// The Jacobians at the configuration of the last [`SerialChain::tip_pose`] call on `workspace`, completing its
    /// state to what [`SerialChain::kinematics`] would have written there.
    pub(crate) fn jacobians_after_tip_pose<'w>(
        &self,
        workspace: &'w mut KinematicsWorkspace<N>,
    ) -> &'w KinematicState<N> {
        self.jacobians(&mut workspace.state);
        &workspace.state
    }

    /// The validated `q` and every frame of `state`: the segments' poses and axes, and `base_from_tip`.
    fn poses(&self, state: &mut KinematicState<N>, q: &JointVector<N>) -> Result<(), RobotError> {
        if let Some((index, &value)) = q.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(RobotError::NonFiniteJoint { index, value });
        }
        if let Some((joint, &value)) = self
            .joints
            .iter()
            .zip(q.iter())
            .find(|(_, &v)| !KINEMATIC_COORDINATE.contains(v))
        {
            return Err(RobotError::OutOfRange {
                joint: joint.name.clone(),
                field: "position",
                value,
                expected: KINEMATIC_COORDINATE.text,
            });
        }
        state.q = *q;

        // Poses: base_from_segment_i = base_from_segment_{i−1} · origin_i · motion_i(q_i). The half-angle sines and
        // cosines come first, off the serial dependency chain of the poses.
        let mut half_angles = [(0.0, 1.0); N];
        for ((sc, joint), &qi) in half_angles.iter_mut().zip(self.joints.iter()).zip(q.iter()) {
            if joint.kind.is_rotational() {
                *sc = (0.5 * qi).sin_cos();
            }
        }
        let mut rotation = UnitQuaternion::identity();
        let mut translation = Vector3::zeros();
        for ((((joint, (&qi, &half)), frame), axis), rotational) in self
            .joints
            .iter()
            .zip(q.iter().zip(half_angles.iter()))
            .zip(state.base_from_segment.iter_mut())
            .zip(state.axes.iter_mut())
            .zip(state.rotational.iter_mut())
        {
            *rotational = joint.kind.is_rotational();
            *axis = joint.advance(&mut rotation, &mut translation, qi, half);
            *frame = Isometry3::from_parts(Translation3::from(translation), rotation);
        }
        // Mimic joints after the last independent joint move the frames beyond them ([D19](crate::theory#d19)).
        let mut base_from_segment =
            Isometry3::from_parts(Translation3::from(translation), rotation);
        for mimic in &self.mimic_joints {
            mimic.advance(
                &mut base_from_segment.rotation,
                &mut base_from_segment.translation.vector,
                q,
            );
        }
        state.base_from_tip = base_from_segment * self.segment_from_tip;
        Ok(())
    }

    /// Both Jacobians of `state` from its frames (written by [`SerialChain::poses`] at `state.q`).
    fn jacobians(&self, state: &mut KinematicState<N>) {
        let q = &state.q;
        // Jacobians: columns (a_i × (p − o_i), a_i) or (a_i, 0) in base axes, then rotated into tip axes.
        let tip = state.base_from_tip.translation.vector;
        let tip_from_base = state.base_from_tip.rotation.inverse().to_rotation_matrix();
        for ((((joint, frame), axis), mut base_column), mut tip_column) in self
            .joints
            .iter()
            .zip(state.base_from_segment.iter())
            .zip(state.axes.iter())
            .zip(state.base_jacobian.column_iter_mut())
            .zip(state.tip_jacobian.column_iter_mut())
        {
            let (linear, angular) = match joint.kind {
                JointKind::Revolute | JointKind::Continuous => {
                    (axis.cross(&(tip - frame.translation.vector)), *axis)
                }
                JointKind::Prismatic => (*axis, Vector3::zeros()),
            };
            base_column.fixed_rows_mut::<3>(0).copy_from(&linear);
            base_column.fixed_rows_mut::<3>(3).copy_from(&angular);
            tip_column
                .fixed_rows_mut::<3>(0)
                .copy_from(&(tip_from_base * linear));
            tip_column
                .fixed_rows_mut::<3>(3)
                .copy_from(&(tip_from_base * angular));
        }
        // Each mimic joint adds its own column, times its multiplier, to its leader's.
        if let Some(last) = N.checked_sub(1) {
            let (base_jacobian, tip_jacobian) = (&mut state.base_jacobian, &mut state.tip_jacobian);
            for_each_mimic_column(
                &self.mimic_joints,
                &state.base_from_segment[last],
                q,
                &tip,
                |leader, linear, angular| {
                    let (mut base_column, mut tip_column) = (
                        base_jacobian.column_mut(leader),
                        tip_jacobian.column_mut(leader),
                    );
                    let mut base_linear = base_column.fixed_rows_mut::<3>(0);
                    base_linear += linear;
                    let mut base_angular = base_column.fixed_rows_mut::<3>(3);
                    base_angular += angular;
                    let mut tip_linear = tip_column.fixed_rows_mut::<3>(0);
                    tip_linear += tip_from_base * linear;
                    let mut tip_angular = tip_column.fixed_rows_mut::<3>(3);
                    tip_angular += tip_from_base * angular;
                },
            );
        }
    }
}

impl Joint {
    /// Moves the frame `base_from_parent = (rotation, translation)` — the child frame of the previous movable joint,
    /// in the base frame — to `base_from_child = base_from_parent · origin · motion(θ)`, the motion a rotation by `θ`
    /// (rad) about the axis or a translation by `θ` (m) along it; `half` is `(sin θ/2, cos θ/2)` for a rotational
    /// joint (unused otherwise). Returns the joint axis in the base frame; the joint's origin `o` is the new
    /// translation of a rotational joint.
    #[inline]
    fn advance(
        &self,
        rotation: &mut UnitQuaternion<f64>,
        translation: &mut Vector3<f64>,
        theta: f64,
        (s, c): (f64, f64),
    ) -> Vector3<f64> {
        let matrix = rotation.to_rotation_matrix();
        let joint_origin = *translation + matrix * self.origin.translation.vector;
        let axis = matrix * self.axis_in_parent;
        if self.kind.is_rotational() {
            // origin.rotation ⊗ (cos(θ/2), sin(θ/2) axis), unit by construction.
            let local = self.origin.rotation.into_inner() * c + self.origin_times_axis * s;
            *rotation *= UnitQuaternion::new_unchecked(local);
            *translation = joint_origin;
        } else {
            *rotation *= self.origin.rotation;
            *translation = joint_origin + axis * theta;
        }
        axis
    }
}

/// Walks `mimics` (consecutive mimic joints) from the frame `base_from_segment` at chain coordinates `q`, and gives
/// for each its leader `i` and its contribution to column `i` of the Jacobian of the point `p` (base frame):
/// `m_k (a_k × (p − o_k), a_k)` for a rotational joint, `(m_k a_k, 0)` for a prismatic one ([D19](crate::theory#d19)).
fn for_each_mimic_column<const N: usize>(
    mimics: &[MimicJoint],
    base_from_segment: &Isometry3<f64>,
    q: &JointVector<N>,
    p: &Vector3<f64>,
    mut add: impl FnMut(usize, Vector3<f64>, Vector3<f64>),
) {
    let (mut rotation, mut translation) = (
        base_from_segment.rotation,
        base_from_segment.translation.vector,
    );
    for mimic in mimics {
        let axis = mimic.multiplier * mimic.advance(&mut rotation, &mut translation, q);
        if mimic.joint.kind.is_rotational() {
            add(mimic.leader, axis.cross(&(p - translation)), axis);
        } else {
            add(mimic.leader, axis, Vector3::zeros());
        }
    }
}

impl MimicJoint {
    /// [`Joint::advance`] at this mimic joint's position for the chain coordinates `q`.
    fn advance<const N: usize>(
        &self,
        rotation: &mut UnitQuaternion<f64>,
        translation: &mut Vector3<f64>,
        q: &JointVector<N>,
    ) -> Vector3<f64> {
        let theta = self.position(q);
        let half = if self.joint.kind.is_rotational() {
            (0.5 * theta).sin_cos()
        } else {
            (0.0, 1.0)
        };
        self.joint.advance(rotation, translation, theta, half)
    }
}

impl<const N: usize> KinematicState<N> {
    /// The joint positions this state was computed at (rad or m).
    pub fn q(&self) -> &JointVector<N> {
        &self.q
    }

    /// `base_from_tip` (ViSP `fMe`): the pose of the tip (end-effector) frame in the base frame.
    pub fn base_from_tip(&self) -> &Isometry3<f64> {
        &self.base_from_tip
    }

    /// The geometric Jacobian in the base frame: `base_J q̇ = (v, ω)`, the linear velocity (m/s) of the tip origin and
    /// the angular velocity (rad/s) of the tip, both in base axes.
    pub fn base_jacobian(&self) -> &KinematicJacobian<N> {
        &self.base_jacobian
    }

    /// The geometric Jacobian in the end-effector frame, `eJe` ([\[M42\]](crate::theory#m42)): `eJe q̇` is the tip twist `(v, ω)`
    /// expressed in tip axes, taken at the tip origin.
    pub fn tip_jacobian(&self) -> &KinematicJacobian<N> {
        &self.tip_jacobian
    }

    /// `base_from_segment_i` for every joint `i`: the pose of the child link frame of joint `i` in the base frame.
    pub fn segment_poses(&self) -> &[Isometry3<f64>; N] {
        &self.base_from_segment
    }

    /// The unit axis of every joint, in the base frame. Revolute axes pass through the origin of the corresponding
    /// [`Self::segment_poses`] frame.
    pub fn joint_axes(&self) -> &[Vector3<f64>; N] {
        &self.axes
    }

    /// The pose of a link of the chain in the base frame.
    ///
    /// # Errors
    /// [`RobotError::JointIndexOutOfRange`] when `link` comes from a chain with more joints than `N`.
    pub fn base_from_link(&self, link: &ChainLink) -> Result<Isometry3<f64>, RobotError> {
        let mut base_from_frame = match link.moved_by {
            None => Isometry3::identity(),
            Some(index) => *self.segment(index)?,
        };
        for mimic in &link.mimics {
            self.mimic_leader(mimic)?;
            mimic.advance(
                &mut base_from_frame.rotation,
                &mut base_from_frame.translation.vector,
                &self.q,
            );
        }
        Ok(base_from_frame * link.segment_from_link)
    }

    /// The point Jacobian of a point rigidly attached to `link`, at `point_in_base` (its current position, base
    /// frame): `out · q̇` is the point's linear velocity (m/s) in base axes. Column `i` is `a_i × (p − o_i)` for a
    /// rotational joint, `a_i` for a prismatic one, and zero for joints after the link (and for all joints when the
    /// link is attached to the base); a mimic joint before the link adds its own such column, times its multiplier, to
    /// its leader's ([D19](crate::theory#d19)). Allocates nothing.
    ///
    /// # Errors
    /// [`RobotError::JointIndexOutOfRange`] when `link` comes from a chain with more joints than `N`.
    pub fn point_jacobian(
        &self,
        link: &ChainLink,
        point_in_base: &Point3<f64>,
        out: &mut SMatrix<f64, 3, N>,
    ) -> Result<(), RobotError> {
        if let Some(index) = link.moved_by {
            self.segment(index)?;
        }
        let moving = link.moved_by.map_or(0, |i| i + 1);
        for (i, ((frame, axis), rotational)) in self
            .base_from_segment
            .iter()
            .zip(self.axes.iter())
            .zip(self.rotational.iter())
            .enumerate()
        {
            let column = if i >= moving {
                Vector3::zeros()
            } else if *rotational {
                axis.cross(&(point_in_base.coords - frame.translation.vector))
            } else {
                *axis
            };
            out.column_mut(i).copy_from(&column);
        }
        if let (Some(index), false) = (link.moved_by, link.mimics.is_empty()) {
            for mimic in &link.mimics {
                self.mimic_leader(mimic)?;
            }
            for_each_mimic_column(
                &link.mimics,
                self.segment(index)?,
                &self.q,
                &point_in_base.coords,
                |leader, linear, _| {
                    let mut column = out.column_mut(leader);
                    column += linear;
                },
            );
        }
        Ok(())
    }

    fn segment(&self, index: usize) -> Result<&Isometry3<f64>, RobotError> {
        self.base_from_segment
            .get(index)
            .ok_or(RobotError::JointIndexOutOfRange { index, joints: N })
    }

    /// The leader of a mimic joint, checked against `N`.
    fn mimic_leader(&self, mimic: &MimicJoint) -> Result<usize, RobotError> {
        let index = mimic.leader;
        (index < N)
            .then_some(index)
            .ok_or(RobotError::JointIndexOutOfRange { index, joints: N })
    }
}
