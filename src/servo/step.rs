//! One period of the façade ([`VisualServo::step`], [`VisualServo::step_normalized`]): the checks, the depths, the
//! tasks, the controller step, the saturation and the feedback of the sent velocity (steps 1–5 of the
//! [module docs](super)).

use super::error::depth_error;
use super::{Corners, ServoError, ServoOutput, VisualServo, MAX_TASKS};
use crate::avoidance::{image_braking_scale, ShapedVelocity};
use crate::camera::ImagePoint;
use crate::depth::{assign_depths, DepthSource, Depths};
use crate::feature::Observation;
use crate::math::{first_non_finite, JointVector};
use crate::task::{Task, TaskError};
use crate::visual_task::VisualContext;
use nalgebra::{Point2, Vector6};

impl<const N: usize> VisualServo<N> {
    /// One period at `time_s` (s, any clock, strictly increasing) with the measured corners in pixels (distorted, as
    /// the camera delivers them) and the measured joint positions `q` (rad, m). Returns the velocity to send and what
    /// the servo did. Allocates nothing.
    ///
    /// # Errors
    /// [`ServoError::TimeNotIncreasing`], [`ServoError::NonFiniteJoint`], [`ServoError::MissingCorner`],
    /// [`ServoError::NonFiniteCorner`], [`ServoError::OutsideImage`], [`ServoError::Undistortion`],
    /// [`ServoError::NonPositiveDepth`], [`ServoError::Task`] (a feature undefined on this image),
    /// [`ServoError::Controller`]. On error nothing is to be sent and the servo's memory is unchanged — but for a new
    /// frame already given to the online depth estimator when a later stage fails (a feature undefined on the image, a
    /// controller failure): that update stands, and its time becomes the last accepted one.
    pub fn step(
        &mut self,
        time_s: f64,
        pixels: &Corners,
        q: &JointVector<N>,
    ) -> Result<&ServoOutput<N>, ServoError> {
        self.check_time_and_joints(time_s, q)?;
        let mut points = [Point2::origin(); 4];
        let intrinsics = &self.camera.intrinsics;
        for (index, (corner, point)) in pixels.iter().zip(points.iter_mut()).enumerate() {
            let (u, v) = corner.ok_or(ServoError::MissingCorner { index })?;
            check_pixel(index, u, v, intrinsics.width(), intrinsics.height())?;
            let (x, y) = self
                .camera
                .normalized_of(u, v)
                .map_err(|source| ServoError::Undistortion { index, source })?;
            *point = Point2::new(x, y);
        }
        self.run(time_s, &points, q)
    }

    /// As [`Self::step`] with corners already undistorted and normalised (`x = X/Z`, `y = Y/Z`); each is checked to lie
    /// in the image at its distorted pixel.
    ///
    /// # Errors
    /// As [`Self::step`] (no [`ServoError::Undistortion`]).
    pub fn step_normalized(
        &mut self,
        time_s: f64,
        normalized: &Corners,
        q: &JointVector<N>,
    ) -> Result<&ServoOutput<N>, ServoError> {
        self.check_time_and_joints(time_s, q)?;
        let mut points = [Point2::origin(); 4];
        let intrinsics = &self.camera.intrinsics;
        for (index, (corner, point)) in normalized.iter().zip(points.iter_mut()).enumerate() {
            let (x, y) = corner.ok_or(ServoError::MissingCorner { index })?;
            if !(x.is_finite() && y.is_finite()) {
                return Err(ServoError::NonFiniteCorner { index, u: x, v: y });
            }
            let (u, v) = self.camera.pixel_of(x, y);
            check_pixel(index, u, v, intrinsics.width(), intrinsics.height())?;
            *point = Point2::new(x, y);
        }
        self.run(time_s, &points, q)
    }

    fn check_time_and_joints(&self, time_s: f64, q: &JointVector<N>) -> Result<(), ServoError> {
        if !(time_s.is_finite() && time_s > self.last_time) {
            return Err(ServoError::TimeNotIncreasing {
                previous: self.last_time,
                time: time_s,
            });
        }
        if let Some((joint, value)) = first_non_finite(q) {
            return Err(ServoError::NonFiniteJoint { joint, value });
        }
        Ok(())
    }

    /// Steps 2–5 of the module docs, on validated points.
    fn run(
        &mut self,
        time_s: f64,
        measured: &[Point2<f64>; 4],
        q: &JointVector<N>,
    ) -> Result<&ServoOutput<N>, ServoError> {
        let first = self.start_time.is_none();
        let start = self.start_time.unwrap_or(time_s);
        let time = time_s - start;
        // The motion since the last accepted period, at the twist sent then.
        let dt = if first { 0.0 } else { time_s - self.last_time };
        let twist_sum = self.twist_sum + self.output.camera_twist * dt;
        let twist_time = self.twist_time + dt;
        let new_frame = first || *measured != self.last_points;
        let mut depth_updated = false;
        if let (Some(estimator), true) = (self.estimator.as_mut(), new_frame) {
            let mean = if twist_time > 0.0 {
                twist_sum / twist_time
            } else {
                Vector6::zeros()
            };
            // On error the estimator keeps its state: nothing of this period is committed.
            estimator
                .update(time, measured, &mean)
                .map_err(depth_error)?;
            depth_updated = true;
        }
        // The observer's estimate (D32) from the twist sent since the last period and that period's depths; the tasks
        // and the target's pose see it, the depth estimator the frames themselves.
        let observed = self.observer.as_ref().and_then(|observer| {
            observer.propose(
                time_s,
                &self.output.camera_twist,
                &self.output.depths,
                new_frame.then_some(measured),
            )
        });
        let seen = observed.as_ref().map_or(measured, |step| step.points());
        let plane = match self.depth {
            DepthSource::TargetPose => Some(self.target.plane_from_image(seen)),
            _ => None,
        };
        let depths = match (&self.estimator, self.depth, &plane) {
            (Some(estimator), _, _) => Ok(Depths::Estimated(estimator.depths())),
            (None, _, Some(Ok(plane))) => Ok(Depths::Plane(plane)),
            (None, _, Some(Err(e))) => Err(ServoError::TargetPose(e.clone())),
            (None, DepthSource::Constant { depth_m }, None) => Ok(Depths::Constant(depth_m)),
            (None, _, None) => Ok(Depths::Desired(&self.desired_points)),
        };
        let mut points = [ImagePoint::default(); 4];
        let result = depths
            .and_then(|depths| assign_depths(depths, seen, &mut points).map_err(depth_error))
            .and_then(|()| self.control(time, dt, &points, q));
        if result.is_err() && !depth_updated {
            // Nothing changed (the controller restores its own memory on error).
            return result.map(|()| &self.output);
        }
        // The frame is committed: accepted, or given to the depth estimator before a later failure (a feature undefined
        // on this image, a controller failure), whose update cannot be undone.
        if new_frame {
            self.twist_sum = Vector6::zeros();
            self.twist_time = 0.0;
        } else {
            self.twist_sum = twist_sum;
            self.twist_time = twist_time;
        }
        self.start_time = Some(start);
        self.last_time = time_s;
        self.last_points = *measured;
        if let (Some(observer), Some(step)) = (self.observer.as_mut(), &observed) {
            observer.commit(step);
        }
        result?;
        let output = &mut self.output;
        output.new_frame = new_frame;
        output.iteration = self.iteration;
        for (d, p) in output.depths.iter_mut().zip(&points) {
            *d = p.depth;
        }
        self.iteration += 1;
        Ok(&self.output)
    }

    /// Tasks, adaptive gains, controller step, saturation and feedback; `dt` (s) is the time since the last accepted
    /// period (0 at the first).
    fn control(
        &mut self,
        time: f64,
        dt: f64,
        points: &[ImagePoint; 4],
        q: &JointVector<N>,
    ) -> Result<(), ServoError> {
        let state = self.chain.kinematics(&mut self.kinematics, q)?;
        let camera_jacobian = self.mount.camera_jacobian(state.tip_jacobian());
        let observation = Observation::new(points, None).map_err(|source| {
            ServoError::Task(TaskError::Feature {
                name: "observation".into(),
                source,
            })
        })?;
        let context = VisualContext {
            observation: &observation,
            camera_jacobian: &camera_jacobian,
        };
        let mut task_errors = [0.0; MAX_TASKS];
        let mut task_gains = [0.0; MAX_TASKS];
        for (i, (task, value)) in self.tasks.iter().zip(self.values.iter_mut()).enumerate() {
            task.evaluate(&context, value)?;
            task_errors[i] = value.error().norm();
            if let Some(adaptive) = &self.adaptive {
                adaptive.apply(Task::<N, VisualContext<'_, N>>::name(task), value)?;
            }
            task_gains[i] = value.gain();
        }
        let cost: &dyn crate::avoidance::Cost<N> = &self.limits;
        let step =
            self.controller
                .step(&self.law, &self.values, Some(cost), q, self.iteration, time)?;
        // The braking before the border of the (undistorted) image (D25), the velocity limits, the braking before a
        // hard limit (D25) with the stopping distance the acceleration limits need, and the change from the velocity
        // sent last within them (D31): the path the simulation takes.
        let unscaled = step.velocity;
        let braking_rate = self.controller.parameters().braking_rate;
        let image_scale = if self.controller.parameters().brake_at_image_border {
            image_braking_scale(
                &self.camera.intrinsics,
                0.0,
                points,
                &(camera_jacobian * unscaled),
                braking_rate,
            )
        } else {
            1.0
        };
        let shaped = self.motion.shape(
            &self.limits,
            q,
            &(unscaled * image_scale),
            &self.output.velocity,
            braking_rate,
            dt,
        );
        let ShapedVelocity {
            velocity,
            scale,
            acceleration_scale: fraction,
            stopping_clamp: clamped,
        } = shaped;
        self.controller.set_sent_velocity(&velocity)?;
        let output = &mut self.output;
        output.velocity = velocity;
        output.unscaled_velocity = unscaled;
        output.scale = image_scale * scale;
        output.scaled = output.scale < 1.0;
        output.acceleration_scale = fraction;
        output.stopping_clamp = clamped;
        output.task_errors = task_errors;
        output.task_gains = task_gains;
        output.error_norm = task_errors.iter().map(|e| e * e).sum::<f64>().sqrt();
        output.event = step.event;
        output.held = self.controller.is_held();
        output.locked = *self.controller.law_workspace().locked_joints();
        output.stack_velocity_norm = step.stack_velocity_norm;
        let stacked = self.controller.stacked();
        output.stack_len = stacked.len().min(MAX_TASKS);
        output.stack[..output.stack_len].copy_from_slice(&stacked[..output.stack_len]);
        // A reserve task not stacked yet (D23) counts only as a check that the corners are where they should be.
        let waiting_reserve = self.controller.waiting_reserve();
        let escape_error = self.controller.parameters().escape_error;
        output.converged = self.controller.is_complete()
            && task_errors[..output.task_count]
                .iter()
                .enumerate()
                .all(|(i, &e)| match waiting_reserve {
                    Some(reserve) if i == reserve => e <= escape_error,
                    _ => e < self.convergence_error,
                });
        output.camera_twist = camera_jacobian * velocity;
        Ok(())
    }
}

/// `Ok` when `(u, v)` is finite and inside `[0, width] × [0, height]` (px).
pub(super) fn check_pixel(
    index: usize,
    u: f64,
    v: f64,
    width: f64,
    height: f64,
) -> Result<(), ServoError> {
    if !(u.is_finite() && v.is_finite()) {
        return Err(ServoError::NonFiniteCorner { index, u, v });
    }
    if !((0.0..=width).contains(&u) && (0.0..=height).contains(&v)) {
        return Err(ServoError::OutsideImage {
            index,
            u,
            v,
            width,
            height,
        });
    }
    Ok(())
}
