//! Visual tasks: a visual feature, its desired value, a gain and an interaction source, giving the task function
//! `e_i = s_i − s_i*` ([(F28)](crate::theory#f28)) and its Jacobian for an eye-in-hand camera
//!
//! ```text
//! [M42]  J_i = L_{s_i} · cVe · eJe(q)          (m_i × 6)(6 × 6)(6 × N)
//! ```
//!
//! A [`VisualTask`] is a [`Task`] whose context is a [`VisualContext`]: the current observation (image points, their
//! depths or the target plane, and their moments, computed once for all tasks) and the camera Jacobian `cVe · eJe`
//! (computed once per control period by the robot and camera modules). Evaluation writes `e_i`, `L_i` and `J_i` into
//! the task's preallocated [`TaskValue`] without allocating.
//!
//! The interaction source ([D10](crate::theory#d10)) picks where `L_i` is evaluated: [`InteractionSource::Exact`] (default) and
//! [`InteractionSource::PaperApprox`] on the current observation; [`InteractionSource::Desired`] once, at construction,
//! on the desired observation.
//!
//! [`paper_tasks`] builds the paper's four tasks (centroid, diagonal angle, `a_n`, `P_x`/`P_y`, [§9](crate::theory#s9)) and
//! [`classical_task`] the full six-row task of the classical law ([§7.7](crate::theory#s7-7)), each in one call.
//! [`paper_tasks_with`] lets the fourth task be chosen ([`FourthTask`]): on a square target seen head-on `P_x, P_y`
//! are undefined ([D9](crate::theory#d9)), and [`FourthTask::Auto`] replaces them by the side-length ratios
//! [`SideRatios`].

use crate::feature::{
    AllPoints, AreaNormalization, AreaNormalized, BoxedFeature, Centroid, DiagonalAngle, Feature,
    FeatureError, FeatureSet, InteractionSource, Observation, PaperInvariants, SideRatios,
};
use crate::math::{wrap_angle, KinematicJacobian};
use crate::task::{InteractionMatrix, Task, TaskError, TaskValue};
use nalgebra::DVector;

/// The names of the paper's four tasks, in priority order ([theory §9](crate::theory#s9)): e1, e2, e3, e4.
pub const PAPER_TASK_NAMES: [&str; 4] = ["centroid", "angle", "area", "third_order"];

/// The name of the classical full task.
pub const CLASSICAL_TASK_NAME: &str = "full";

/// The name of the image-points task ([`image_points_task`]), the full method's reserve task.
pub const IMAGE_POINTS_TASK_NAME: &str = "image_points";

/// What a visual task reads at each control period.
#[derive(Debug, Clone, Copy)]
pub struct VisualContext<'a, const N: usize> {
    /// The current observation of the target (points, depths or plane, moments).
    pub observation: &'a Observation<'a>,
    /// The camera Jacobian `cVe · eJe(q)` (6 × N): maps `q̇` to the camera twist `(υ, ω)` in the camera frame.
    pub camera_jacobian: &'a KinematicJacobian<N>,
}

/// A visual task: `e = s − s*` with angle rows wrapped into `(−π, π]` ([D8](crate::theory#d8)), `J = L cVe eJe` [\[M42\]](crate::theory#m42).
pub struct VisualTask {
    name: String,
    feature: BoxedFeature,
    desired: DVector<f64>,
    /// Per row, whether its error is wrapped as an angle ([`Feature::is_angle`], read once here: a feature set
    /// answers it by walking its features, which cost as much as the error itself on every step).
    angle_rows: Box<[bool]>,
    gain: f64,
    source: InteractionSource,
    desired_interaction: Option<InteractionMatrix>,
}

impl std::fmt::Debug for VisualTask {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("VisualTask")
            .field("name", &self.name)
            .field("feature", &self.feature.name())
            .field("desired", &self.desired.as_slice())
            .field("gain", &self.gain)
            .field("source", &self.source)
            .finish()
    }
}

fn feature_error(name: &str, source: FeatureError) -> TaskError {
    TaskError::Feature {
        name: name.into(),
        source,
    }
}

impl VisualTask {
    /// A task driving `feature` to its value in the `desired` observation, with gain `gain` (s⁻¹) and interaction
    /// source `source`. For [`InteractionSource::Desired`], `L` is computed here, once, on `desired`.
    ///
    /// # Errors
    /// [`TaskError::InvalidGain`]; [`TaskError::Feature`] when the feature is undefined on the desired observation.
    pub fn new(
        name: &str,
        feature: BoxedFeature,
        desired: &Observation<'_>,
        gain: f64,
        source: InteractionSource,
    ) -> Result<Self, TaskError> {
        let mut desired_value = DVector::zeros(feature.dim());
        feature
            .value(desired, desired_value.as_mut_slice())
            .map_err(|e| feature_error(name, e))?;
        let desired_interaction = match source {
            InteractionSource::Desired => {
                let mut l = InteractionMatrix::zeros(feature.dim());
                feature
                    .interaction(
                        desired,
                        InteractionSource::Exact,
                        l.rows_mut(0, feature.dim()),
                    )
                    .map_err(|e| feature_error(name, e))?;
                Some(l)
            }
            InteractionSource::Exact | InteractionSource::PaperApprox => None,
        };
        // Validates the gain and the row count.
        TaskValue::<0>::new(name, feature.dim(), gain)?;
        let angle_rows = (0..feature.dim())
            .map(|row| feature.is_angle(row))
            .collect();
        Ok(Self {
            name: name.into(),
            feature,
            desired: desired_value,
            angle_rows,
            gain,
            source,
            desired_interaction,
        })
    }

    /// The desired value `s*`.
    pub fn desired_value(&self) -> &DVector<f64> {
        &self.desired
    }

    /// The feature.
    pub fn feature(&self) -> &dyn Feature {
        self.feature.as_ref()
    }

    /// The interaction source.
    pub fn source(&self) -> InteractionSource {
        self.source
    }
}

impl<'a, const N: usize> Task<N, VisualContext<'a, N>> for VisualTask {
    fn name(&self) -> &str {
        &self.name
    }

    fn rows(&self) -> usize {
        self.feature.dim()
    }

    fn gain(&self) -> f64 {
        self.gain
    }

    fn evaluate(
        &self,
        context: &VisualContext<'a, N>,
        out: &mut TaskValue<N>,
    ) -> Result<(), TaskError> {
        let rows = self.feature.dim();
        if out.rows() != rows {
            return Err(TaskError::DimensionMismatch {
                name: self.name.clone(),
                what: "storage",
                expected: rows,
                found: out.rows(),
            });
        }
        let (error, jacobian, interaction) = out.sensor_parts_mut();
        // s and L_s (one pass over their shared terms, unless L_s is the constant one of the desired pose), both
        // checked finite by the feature.
        let evaluated = match &self.desired_interaction {
            Some(desired) => {
                interaction.copy_from(desired);
                self.feature
                    .value(context.observation, error.as_mut_slice())
            }
            None => self.feature.value_and_interaction(
                context.observation,
                self.source,
                error.as_mut_slice(),
                interaction.rows_mut(0, rows),
            ),
        };
        evaluated.map_err(|e| feature_error(&self.name, e))?;
        // e = s − s*, angles wrapped (F28, D8); `s*` was checked finite at construction.
        for ((e, s_star), &angle) in error
            .iter_mut()
            .zip(self.desired.iter())
            .zip(self.angle_rows.iter())
        {
            let difference = *e - s_star;
            *e = if angle {
                wrap_angle(difference)
            } else {
                difference
            };
        }
        // J = L (cVe eJe)   [M42]
        crate::linalg::mul_rows_to(&*interaction, context.camera_jacobian, jacobian);
        Ok(())
    }
}

/// The paper's four tasks in priority order ([theory §9](crate::theory#s9)): e1 centroid (2 rows, [`Centroid`] with a-priori depth
/// `a_priori_depth` for [`InteractionSource::PaperApprox`]), e2 diagonal angle from point 0 to point 2 (1 row, [D8](crate::theory#d8)),
/// e3 `a_n` (1 row, with desired depth `desired_depth`, [\[M37\]](crate::theory#m37)), e4 `P_x, P_y` (2 rows, [\[M40\]](crate::theory#m40)). Named as
/// [`PAPER_TASK_NAMES`]. `gains` are the `λ_i` (s⁻¹). Same as [`paper_tasks_with`] and
/// [`FourthTask::PaperInvariants`].
///
/// # Errors
/// Invalid depths or gains, or features undefined on the desired observation (e.g. a square target seen head-on, [D9](crate::theory#d9):
/// use [`paper_tasks_with`] and [`FourthTask::Auto`] there).
pub fn paper_tasks(
    desired: &Observation<'_>,
    desired_depth: f64,
    a_priori_depth: f64,
    gains: [f64; 4],
    source: InteractionSource,
) -> Result<Vec<VisualTask>, TaskError> {
    paper_tasks_with(
        desired,
        desired_depth,
        a_priori_depth,
        gains,
        source,
        FourthTask::PaperInvariants,
    )
}

/// The anisotropy `I1/I3²` of the desired image (see [`crate::feature::Moments::anisotropy`]) below which
/// [`FourthTask::Auto`] takes [`SideRatios`]: `P_x, P_y` divide by `I1` and become ill-conditioned as `I1 → 0`.
/// `0.01` is a head-on rectangle of aspect ratio about 1.1 (the paper's 2:1 rectangle has 0.36).
pub const CENTRAL_SYMMETRY_ANISOTROPY: f64 = 0.01;

/// The feature of the fourth task (e4) of the paper's sequence.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FourthTask {
    /// [`FourthTask::SideRatios`] when the desired image is (nearly) centrally symmetric, i.e. its anisotropy
    /// `I1/I3²` is below [`CENTRAL_SYMMETRY_ANISOTROPY`] (a square seen head-on); [`FourthTask::PaperInvariants`]
    /// otherwise.
    #[default]
    Auto,
    /// The paper's `P_x, P_y` ([`PaperInvariants`], \[M40\]).
    PaperInvariants,
    /// The normalised differences of opposite side lengths ([`SideRatios`]), defined for squares; needs exactly four
    /// points numbered around the target.
    SideRatios,
}

impl FourthTask {
    /// The choice made for `desired`: [`FourthTask::Auto`] resolved, the others unchanged.
    ///
    /// # Errors
    /// [`FeatureError::DegenerateArea`] (or an overflow) when the desired moments are undefined.
    pub fn resolve(self, desired: &Observation<'_>) -> Result<Self, FeatureError> {
        Ok(match self {
            Self::Auto if desired.moments()?.anisotropy()? < CENTRAL_SYMMETRY_ANISOTROPY => {
                Self::SideRatios
            }
            Self::Auto => Self::PaperInvariants,
            chosen => chosen,
        })
    }
}

/// The paper's four tasks as [`paper_tasks`], with the feature of task e4 chosen by `fourth` ([`FourthTask`]). The
/// fourth task keeps the name `PAPER_TASK_NAMES[3]` whatever its feature.
///
/// # Errors
/// As [`paper_tasks`]; [`FourthTask::Auto`] never fails on a square seen head-on.
pub fn paper_tasks_with(
    desired: &Observation<'_>,
    desired_depth: f64,
    a_priori_depth: f64,
    gains: [f64; 4],
    source: InteractionSource,
    fourth: FourthTask,
) -> Result<Vec<VisualTask>, TaskError> {
    paper_feature_list(desired, desired_depth, a_priori_depth, fourth)?
        .into_iter()
        .zip(PAPER_TASK_NAMES)
        .zip(gains)
        .map(|((feature, name), gain)| VisualTask::new(name, feature, desired, gain, source))
        .collect()
}

/// The classical task ([theory §7.7](crate::theory#s7-7)): `s = (x_g, y_g, α, a_n, P_x, P_y)` in one level, named
/// [`CLASSICAL_TASK_NAME`], with gain `gain` (s⁻¹). As [`classical_task_with`] and [`FourthTask::PaperInvariants`].
///
/// # Errors
/// As [`paper_tasks`].
pub fn classical_task(
    desired: &Observation<'_>,
    desired_depth: f64,
    a_priori_depth: f64,
    gain: f64,
    source: InteractionSource,
) -> Result<VisualTask, TaskError> {
    classical_task_with(
        desired,
        desired_depth,
        a_priori_depth,
        gain,
        source,
        FourthTask::PaperInvariants,
    )
}

/// The classical task with the same six features as the paper's sequence [`paper_tasks_with`] builds for `fourth`
/// (on a square marker, the side ratios in place of `P_x, P_y`), in one level.
///
/// # Errors
/// As [`paper_tasks_with`].
pub fn classical_task_with(
    desired: &Observation<'_>,
    desired_depth: f64,
    a_priori_depth: f64,
    gain: f64,
    source: InteractionSource,
    fourth: FourthTask,
) -> Result<VisualTask, TaskError> {
    let features = paper_feature_list(desired, desired_depth, a_priori_depth, fourth)?;
    let set = FeatureSet::new(features.into_iter().collect());
    VisualTask::new(CLASSICAL_TASK_NAME, Box::new(set), desired, gain, source)
}

/// The image points of `desired`, stacked, as one task (`2N` rows, \[M28\] per point), named [`IMAGE_POINTS_TASK_NAME`],
/// with gain `gain` (s⁻¹). The full method holds it in reserve ([D23](crate::theory#d23)): the labelled corners of a
/// planar target seen from its front take their desired positions at the goal pose only, which the paper's six
/// features do not guarantee.
///
/// # Errors
/// [`TaskError::InvalidGain`]; [`TaskError::Feature`] for an empty desired observation.
pub fn image_points_task(
    desired: &Observation<'_>,
    gain: f64,
    source: InteractionSource,
) -> Result<VisualTask, TaskError> {
    let feature =
        AllPoints::new(desired.len()).map_err(|e| feature_error(IMAGE_POINTS_TASK_NAME, e))?;
    VisualTask::new(
        IMAGE_POINTS_TASK_NAME,
        Box::new(feature),
        desired,
        gain,
        source,
    )
}

/// The four features of the paper's sequence, the fourth chosen by `fourth` ([`FourthTask::resolve`]).
fn paper_feature_list(
    desired: &Observation<'_>,
    desired_depth: f64,
    a_priori_depth: f64,
    fourth: FourthTask,
) -> Result<[BoxedFeature; 4], TaskError> {
    let (centroid, angle, normalization) = paper_features(desired, desired_depth, a_priori_depth)?;
    let fourth_feature: BoxedFeature = match fourth
        .resolve(desired)
        .map_err(|e| feature_error(PAPER_TASK_NAMES[3], e))?
    {
        FourthTask::SideRatios => Box::new(SideRatios),
        FourthTask::Auto | FourthTask::PaperInvariants => {
            Box::new(PaperInvariants::new(normalization))
        }
    };
    Ok([
        Box::new(centroid),
        Box::new(angle),
        Box::new(AreaNormalized::new(normalization)),
        fourth_feature,
    ])
}

fn paper_features(
    desired: &Observation<'_>,
    desired_depth: f64,
    a_priori_depth: f64,
) -> Result<(Centroid, DiagonalAngle, AreaNormalization), TaskError> {
    let error = |e| feature_error("paper features", e);
    Ok((
        Centroid::new(a_priori_depth).map_err(error)?,
        DiagonalAngle::default(),
        AreaNormalization::from_desired(desired, desired_depth).map_err(error)?,
    ))
}
