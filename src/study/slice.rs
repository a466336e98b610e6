//! A 2-D slice of starting configurations ([`Study::slice`]): the outcome of every method over a grid of two joints
//! moved about the scenario's start, the picture of a convergence domain.

use super::{Study, StudyError};
use crate::scenario::{with_joint_count, ForJointCount, RunKind, ScenarioError};
use rayon::prelude::*;
use serde::Serialize;

/// The most points per axis of a [`Study::slice`]: 201 × 201 runs are as many as a study of 1 250 draws per family,
/// minutes on two cores; a thousand per axis (a million runs) would take most of a day.
pub const MAX_SLICE_POINTS: usize = 201;

/// The outcomes over a 2-D slice of starting configurations ([`Study::slice`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Slice {
    /// The two joints varied.
    pub joints: (usize, usize),
    /// The values of the first joint (m or rad), increasing.
    pub x_values: Vec<f64>,
    /// The values of the second joint (m or rad), increasing.
    pub y_values: Vec<f64>,
    /// Per method, the outcome name of every start (row-major: the second joint outer), or `invalid`.
    pub methods: Vec<(RunKind, Vec<&'static str>)>,
}

impl<'a> Study<'a> {
    /// The outcomes of every method over a 2-D slice of starting configurations: the scenario's start with joints
    /// `joints.0` and `joints.1` moved over `points × points` evenly spaced offsets within `±half_widths` (m or rad of
    /// each joint), on all cores. A start outside the limits or with the target out of the image is `invalid`.
    ///
    /// For the joint count of the scenario's robot, as [`Self::run`].
    ///
    /// # Errors
    /// [`StudyError::InvalidParameter`] for a joint index beyond the robot's joints, non-finite or negative
    /// half-widths, fewer than 2 points or more than [`MAX_SLICE_POINTS`]; model failures.
    pub fn slice(
        &self,
        joints: (usize, usize),
        half_widths: (f64, f64),
        points: usize,
    ) -> Result<Slice, StudyError> {
        struct Work<'s, 'a>(&'s Study<'a>, (usize, usize), (f64, f64), usize);
        impl ForJointCount for Work<'_, '_> {
            type Output = Result<Slice, StudyError>;
            fn call<const N: usize>(self) -> Self::Output {
                self.0.slice_for::<N>(self.1, self.2, self.3)
            }
        }
        with_joint_count(
            self.scenario.joint_count()?,
            Work(self, joints, half_widths, points),
        )?
    }

    fn slice_for<const N: usize>(
        &self,
        joints: (usize, usize),
        half_widths: (f64, f64),
        points: usize,
    ) -> Result<Slice, StudyError> {
        let invalid = |name, value: f64, expected| {
            Err(StudyError::InvalidParameter {
                name,
                value,
                expected,
            })
        };
        if joints.0 >= N || joints.1 >= N || joints.0 == joints.1 {
            return invalid(
                "slice joints",
                joints.1 as f64,
                "two distinct joint indices below N",
            );
        }
        for width in [half_widths.0, half_widths.1] {
            if !(width.is_finite() && width > 0.0) {
                return invalid("slice half-width", width, "finite and > 0");
            }
        }
        if !(2..=MAX_SLICE_POINTS).contains(&points) {
            return invalid("slice points", points as f64, "2 to 201");
        }
        let offsets = |half: f64| -> Vec<f64> {
            (0..points)
                .map(|k| -half + 2.0 * half * k as f64 / (points - 1) as f64)
                .collect()
        };
        let (x_offsets, y_offsets) = (offsets(half_widths.0), offsets(half_widths.1));
        let model = self.scenario.robot_model::<N>()?;
        let cells: Vec<Vec<&'static str>> = (0..points * points)
            .into_par_iter()
            .map(|k| {
                let mut scenario = self.scenario.clone();
                scenario.start.joints[joints.0] += x_offsets[k % points];
                scenario.start.joints[joints.1] += y_offsets[k / points];
                let experiment = match scenario.experiment_on::<N>(model.clone()) {
                    Ok(experiment) => experiment,
                    Err(ScenarioError::Invalid { .. }) => {
                        return Ok(vec!["invalid"; self.methods.len()])
                    }
                    Err(error) => return Err(StudyError::from(error)),
                };
                self.methods
                    .iter()
                    .map(|&method| {
                        let run = experiment.run_with(
                            &scenario.settings(),
                            method,
                            &mut crate::sim::SummaryOnly,
                        )?;
                        Ok(run.outcome.name())
                    })
                    .collect()
            })
            .collect::<Result<_, StudyError>>()?;
        let start = |joint: usize| self.scenario.start.joints[joint];
        Ok(Slice {
            joints,
            x_values: x_offsets.iter().map(|o| start(joints.0) + o).collect(),
            y_values: y_offsets.iter().map(|o| start(joints.1) + o).collect(),
            methods: self
                .methods
                .iter()
                .enumerate()
                .map(|(m, &method)| (method, cells.iter().map(|c| c[m]).collect()))
                .collect(),
        })
    }
}
