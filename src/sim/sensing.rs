//! What the controller sees when the camera is not exact ([`Sensing`]): the measurement model, the believed camera
//! mount and where the depths come from, with the per-run state that turns the true view into the measured points.

use super::{Scene, SimError, View};
use crate::camera::{EyeInHand, ImagePoint};
use crate::depth::{assign_depths, DepthError, DepthEstimator, DepthSource, Depths};
use crate::math::{JointVector, KinematicJacobian};
use crate::measurement::{
    perturbed_eye_in_hand, FeatureObserver, MeasurementError, MeasurementModel,
    MeasurementParameters,
};
use crate::target::{RectangleTarget, TargetPlane};
use crate::visual_task::VisualTask;
use nalgebra::{Point2, Vector6};

/// What the controller sees of the target when the camera is not exact (a real camera): the measurement model
/// (pixel noise, intrinsics and hand-eye errors, distortion, a slower camera, latency), where the depths come from,
/// and the desired image as taught through that camera. Without it the controller sees the true image with the true
/// depths.
#[derive(Debug, Clone, Copy)]
pub struct Sensing<'a> {
    /// The camera the controller has, against the true one.
    pub measurement: MeasurementParameters,
    /// Where the points' depths come from; `None`: the true depths (a simulation-only oracle).
    pub depth: Option<DepthSource>,
    /// The desired image points as the nominal camera reads them, with their desired depths (for
    /// [`DepthSource::Desired`]).
    pub desired_points: [ImagePoint; 4],
    /// The run's tasks with their desired values from the true desired image: the noise-free errors of the run (its
    /// records and its convergence) are theirs on the true image. Empty: the controller's own tasks.
    pub true_tasks: &'a [VisualTask],
}

impl Sensing<'_> {
    /// The same sensing with `true_tasks`.
    pub fn with_true_tasks(self, true_tasks: &[VisualTask]) -> Sensing<'_> {
        Sensing {
            measurement: self.measurement,
            depth: self.depth,
            desired_points: self.desired_points,
            true_tasks,
        }
    }
}

/// The per-run state of [`Sensing`]: the measurement model, the believed camera mount, the depth estimator and the
/// believed camera twist (which the estimator and the prediction between frames use).
pub(super) struct SensingState<'a> {
    pub(super) sensing: &'a Sensing<'a>,
    model: MeasurementModel,
    pub(super) believed: EyeInHand,
    estimator: Option<DepthEstimator>,
    believed_twist: Vector6<f64>,
    twist_sum: Vector6<f64>,
    twist_time: f64,
    /// The plane of the pose estimate the depth source uses: the perfect one of the previous period
    /// ([`DepthSource::PreviousPlane`]) or the one estimated from the last measured corners and the target model
    /// ([`DepthSource::TargetPose`]).
    plane: Option<TargetPlane>,
    target: RectangleTarget,
    measured: [Point2<f64>; 4],
    /// The controller's feature observer, when the measurement has one (D32).
    observer: Option<FeatureObserver>,
    pub(super) points: [ImagePoint; 4],
}

impl<'a> SensingState<'a> {
    pub(super) fn new<const N: usize>(
        sensing: &'a Sensing<'a>,
        scene: &Scene<N>,
        period: f64,
    ) -> Result<Self, SimError> {
        let depth_error = |e: DepthError| SimError::Measurement(MeasurementError::Depth(e));
        let model = MeasurementModel::new(&sensing.measurement, scene.intrinsics, 4, period)?;
        Ok(Self {
            sensing,
            believed: perturbed_eye_in_hand(&scene.mount, &sensing.measurement)?,
            estimator: match sensing.depth {
                Some(source) => source.estimator(4).map_err(depth_error)?,
                None => None,
            },
            believed_twist: Vector6::zeros(),
            twist_sum: Vector6::zeros(),
            twist_time: 0.0,
            plane: None,
            target: scene.target,
            measured: [Point2::origin(); 4],
            observer: sensing
                .measurement
                .observer
                .map(|parameters| {
                    let nominal = model.nominal_camera().intrinsics;
                    FeatureObserver::new(parameters, nominal.fx(), nominal.fy())
                })
                .transpose()?,
            model,
            points: [ImagePoint::default(); 4],
        })
    }

    /// The points the controller sees at `time` for the true `view` (normalised through the nominal camera, with the
    /// depths of the source), or why the image is unusable.
    pub(super) fn measure<const N: usize>(
        &mut self,
        time: f64,
        view: &View<N>,
    ) -> Result<(), String> {
        let depths = depths_of(
            self.sensing,
            self.estimator.as_ref(),
            self.plane.as_ref(),
            view,
        );
        let measurement = self
            .model
            .measure(time, &view.points, &self.believed_twist, depths)
            .map_err(|e| e.to_string())?;
        self.measured.copy_from_slice(measurement.normalized);
        if let (true, Some(estimator)) = (measurement.fresh, self.estimator.as_mut()) {
            let mean_twist = if self.twist_time > 0.0 {
                self.twist_sum / self.twist_time
            } else {
                Vector6::zeros()
            };
            match estimator.update(measurement.frame_time, &self.measured, &mean_twist) {
                // Noise larger than the motion: the estimator keeps its previous depths.
                Ok(_) | Err(DepthError::NonPositiveDepth { .. }) => {}
                Err(other) => return Err(other.to_string()),
            }
            (self.twist_sum, self.twist_time) = (Vector6::zeros(), 0.0);
        }
        if let Some(observer) = &mut self.observer {
            // The observer's estimate from the twist sent over the last period and the last period's depths (D32).
            let depths = self.points.map(|p| p.depth);
            let frame = measurement.fresh.then_some(&self.measured);
            if let Some(step) = observer.propose(time, &self.believed_twist, &depths, frame) {
                observer.commit(&step);
                self.measured = *step.points();
            }
        }
        let from_corners = self.sensing.depth == Some(DepthSource::TargetPose);
        if from_corners {
            let plane = self
                .target
                .plane_from_image(&self.measured)
                .map_err(|e| e.to_string())?;
            self.plane = Some(plane);
        }
        let depths = depths_of(
            self.sensing,
            self.estimator.as_ref(),
            self.plane.as_ref(),
            view,
        );
        assign_depths(depths, &self.measured, &mut self.points).map_err(|e| e.to_string())?;
        if !from_corners {
            // A perfect pose estimate, one period late.
            self.plane = Some(view.plane);
        }
        Ok(())
    }

    /// Records the velocity sent over the next `period`: the camera twist the controller believes it makes, for the
    /// depth estimator (averaged between frames) and the prediction between frames.
    pub(super) fn sent<const N: usize>(
        &mut self,
        believed_jacobian: &KinematicJacobian<N>,
        velocity: &JointVector<N>,
        period: f64,
    ) {
        self.believed_twist = believed_jacobian * velocity;
        self.twist_sum += self.believed_twist * period;
        self.twist_time += period;
    }
}

/// The depths of `sensing`'s source: the estimator's, a constant, the desired image's, the plane of a pose estimate
/// (`plane`: a perfect one, one period late, or the one from the measured corners; the true plane before the first),
/// or the true depths of `view` (no source).
fn depths_of<'b, const N: usize>(
    sensing: &'b Sensing<'_>,
    estimator: Option<&'b DepthEstimator>,
    plane: Option<&'b TargetPlane>,
    view: &'b View<N>,
) -> Depths<'b> {
    match (&sensing.depth, estimator) {
        (_, Some(estimator)) => Depths::Estimated(estimator.depths()),
        (Some(DepthSource::Constant { depth_m }), None) => Depths::Constant(*depth_m),
        (Some(DepthSource::Desired), None) => Depths::Desired(&sensing.desired_points),
        (Some(DepthSource::PreviousPlane | DepthSource::TargetPose), None) => {
            Depths::Plane(plane.unwrap_or(&view.plane))
        }
        (Some(DepthSource::Estimated { .. }) | None, None) => Depths::Desired(&view.points),
    }
}
