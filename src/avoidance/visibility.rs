//! The visibility cost: keep every target point inside the image ([theory §4](crate::theory#s4), a cost `h` for [\[M18\]](crate::theory#m18)).
//!
//! The image is the box `[x_min, x_max] × [y_min, y_max]` of normalised coordinates (the pixel rectangle
//! `[0, width] × [0, height]` through the intrinsics); the cost is active in a band of `margin` pixels along its border:
//! `x̃_min = (margin − c_x)/f_x`, `x̃_max = (width − margin − c_x)/f_x` (and likewise for y). For the target points
//! `j`, at normalised coordinates `(x_j, y_j)` seen from the camera at configuration `q`, the cost has the form of the
//! joint-limit cost [\[M20\]](crate::theory#m20)–[\[M21\]](crate::theory#m21) with the image coordinates in place of the joints:
//!
//! ```text
//! h(q)  = ½ Σ_j ( δx_j² / Δx + δy_j² / Δy ) ,    Δx = width / f_x ,  Δy = height / f_y   (the image spans)
//!         δx_j = x_j − x̃_max  if x_j > x̃_max ,   x_j − x̃_min  if x_j < x̃_min ,   0 otherwise   (δy_j likewise)
//! ∇h(q) = Σ_j ( (δx_j/Δx) L_x,j + (δy_j/Δy) L_y,j ) · cVe · eJe(q)        (transposed)
//! ```
//!
//! where `(L_x,j ; L_y,j)` is the point's interaction matrix ([theory §7.1](crate::theory#s7-1), [`crate::feature::point_interaction`],
//! with the depth `Z_j` of the point) and `cVe · eJe` the camera Jacobian ([\[M42\]](crate::theory#m42)–[\[M43\]](crate::theory#m43)): `ẋ_j = L_x,j cVe eJe q̇`
//! for a static target. `h` is zero, with a zero gradient, while every point is at least `margin` pixels inside the
//! image; it is dimensionless (normalised image units).
//!
//! **Facing** ([D27](crate::theory#d27), [`VisibilityCost::with_facing`]): a target seen too obliquely is lost as
//! surely as one out of the image. With the target's centre `o` and front normal `n` (base frame) and the optical
//! centre `c(q)`, the incidence `θ` has `cos θ = nᵀ d / ‖d‖`, `d = c − o`; past an activation angle `θ_a` the cost adds
//!
//! ```text
//! h_f(q)  = ½ δ² ,   δ = cos θ_a − cos θ  if θ > θ_a ,  0 otherwise
//! ∇h_f(q) = −δ [ (R_bcᵀ (n − cos θ d/‖d‖) / ‖d‖)ᵀ , 0 0 0 ] · cVe · eJe(q)      (transposed)
//! ```
//!
//! since `∂cos θ/∂c = (n − cos θ d/‖d‖)/‖d‖` and the optical centre moves at `ċ = R_bc v` for the camera twist `(v, ω)`
//! in the camera frame (`R_bc` the camera's orientation in the base): its rotation does not change `θ`.
//!
//! The cost computes the projection itself from `q` (kinematics on the stack, no allocation), so it can be evaluated
//! at the controller's predicted configuration `q̂` ([D6](crate::theory#d6)).

use super::{checked_cost, dead_band, Cost, CostError};
use crate::camera::{project_point, CameraIntrinsics, EyeInHand};
use crate::feature::{point_interaction, InteractionRow};
use crate::math::{all_finite, first_non_finite, JointVector};
use crate::robot::{KinematicsWorkspace, SerialChain};
use nalgebra::{Point3, Vector3};

/// The visibility cost of the [module docs](self), a [`Cost`] named `"visibility"`.
#[derive(Debug, Clone, PartialEq)]
pub struct VisibilityCost<const N: usize> {
    chain: SerialChain<N>,
    camera: EyeInHand,
    points_in_base: Vec<Point3<f64>>,
    margin_px: f64,
    /// `(x̃_min, x̃_max)` and `(ỹ_min, ỹ_max)`.
    thresholds: [(f64, f64); 2],
    /// `(Δx, Δy)`.
    spans: [f64; 2],
    /// The facing term, when set.
    facing: Option<Facing>,
}

/// The facing term of [`VisibilityCost`]: the target's centre and unit front normal (base frame), and `cos θ_a`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Facing {
    centre: Point3<f64>,
    normal: Vector3<f64>,
    cos_activation: f64,
}

impl<const N: usize> VisibilityCost<N> {
    /// The cost for the camera `camera` on `chain`, with `intrinsics`, looking at static points `points_in_base`
    /// (m, robot base frame), active within `margin_px` pixels of the image border.
    ///
    /// # Errors
    /// [`CostError::InvalidMargin`] unless `0 ≤ margin_px < min(width, height)/2`;
    /// [`CostError::InvalidTargetPoints`] without points or with a non-finite one.
    pub fn new(
        chain: SerialChain<N>,
        camera: EyeInHand,
        intrinsics: &CameraIntrinsics,
        points_in_base: &[Point3<f64>],
        margin_px: f64,
    ) -> Result<Self, CostError> {
        let (width, height) = (intrinsics.width(), intrinsics.height());
        if !(margin_px.is_finite() && margin_px >= 0.0 && 2.0 * margin_px < width.min(height)) {
            return Err(CostError::InvalidMargin {
                margin_px,
                width,
                height,
            });
        }
        if points_in_base.is_empty() || !points_in_base.iter().all(|p| all_finite(&p.coords)) {
            return Err(CostError::InvalidTargetPoints);
        }
        let (x_min, y_min) = intrinsics.pixel_to_normalized(margin_px, margin_px);
        let (x_max, y_max) = intrinsics.pixel_to_normalized(width - margin_px, height - margin_px);
        Ok(Self {
            chain,
            camera,
            points_in_base: points_in_base.to_vec(),
            margin_px,
            thresholds: [(x_min, x_max), (y_min, y_max)],
            spans: [width / intrinsics.fx(), height / intrinsics.fy()],
            facing: None,
        })
    }

    /// The cost with the facing term of the [module docs](self): the target, centred on `centre` (m, base frame) with
    /// its front towards `front_normal` (base frame, normalised here), seen more obliquely than `activation_deg`
    /// degrees from that normal adds `½ (cos θ_a − cos θ)²`.
    ///
    /// # Errors
    /// [`CostError::InvalidFacing`] for an angle outside `[0, 180)`, a non-finite centre, a zero or non-finite normal.
    pub fn with_facing(
        mut self,
        centre: Point3<f64>,
        front_normal: Vector3<f64>,
        activation_deg: f64,
    ) -> Result<Self, CostError> {
        let length = front_normal.norm();
        let valid = (0.0..180.0).contains(&activation_deg)
            && all_finite(&centre.coords)
            && length.is_finite()
            && length > 0.0;
        if !valid {
            return Err(CostError::InvalidFacing { activation_deg });
        }
        self.facing = Some(Facing {
            centre,
            normal: front_normal / length,
            cos_activation: activation_deg.to_radians().cos(),
        });
        Ok(self)
    }

    /// The margin (px) within which the cost is active.
    pub fn margin_px(&self) -> f64 {
        self.margin_px
    }

    /// `h(q)` and, when asked, `∇h(q)`.
    fn evaluate(
        &self,
        q: &JointVector<N>,
        mut gradient: Option<&mut JointVector<N>>,
    ) -> Result<f64, CostError> {
        if let Some((joint, value)) = first_non_finite(q) {
            return Err(CostError::NonFiniteConfiguration { joint, value });
        }
        // The pose alone (the workspace is fixed-size, on the stack); the Jacobians only when the gradient is asked
        // for and not zero (a target inside the dead band and facing the camera, most of the time).
        let mut workspace = KinematicsWorkspace::new();
        let base_from_tip = self.chain.tip_pose(&mut workspace, q)?;
        let camera_from_base = self.camera.base_from_camera(&base_from_tip).inverse();
        let [(x_low, x_high), (y_low, y_high)] = self.thresholds;
        let [x_span, y_span] = self.spans;
        let mut value = 0.0;
        // Σ_j (δx_j/Δx) L_x,j + (δy_j/Δy) L_y,j: the twist-space gradient, mapped to joints once at the end.
        let mut twist_gradient = InteractionRow::zeros();
        for (index, point) in self.points_in_base.iter().enumerate() {
            let p = camera_from_base * point;
            // `q` is finite (checked above), so the only projection failure is a point at or behind the camera.
            let image = project_point(&p).map_err(|_| CostError::PointBehindCamera {
                point: index,
                depth: p.z,
            })?;
            let (x, y, depth) = (image.x, image.y, image.depth);
            let (dx, dy) = (dead_band(x, x_low, x_high), dead_band(y, y_low, y_high));
            let (wx, wy) = (dx / x_span, dy / y_span);
            value += 0.5 * (dx * wx + dy * wy);
            if wx != 0.0 || wy != 0.0 {
                let (lx, ly) = point_interaction(x, y, 1.0 / depth);
                twist_gradient += lx * wx + ly * wy;
            }
        }
        if let Some(facing) = &self.facing {
            let base_from_camera = camera_from_base.inverse();
            let d = base_from_camera.translation.vector - facing.centre.coords;
            let distance = d.norm();
            // The optical centre on the target's centre is in its plane: θ = 90°, with no direction to move it along.
            let (cos, direction) = if distance > 0.0 {
                let cos = facing.normal.dot(&d) / distance;
                (cos, (facing.normal - d * (cos / distance)) / distance)
            } else {
                (0.0, Vector3::zeros())
            };
            let delta = (facing.cos_activation - cos).max(0.0);
            value += 0.5 * delta * delta;
            if delta > 0.0 {
                // ∂cos θ/∂v = R_bcᵀ ∂cos θ/∂c: the linear part of the twist-space gradient.
                let in_camera = base_from_camera
                    .rotation
                    .inverse_transform_vector(&direction);
                for (entry, component) in twist_gradient.iter_mut().zip(in_camera.iter()) {
                    *entry -= delta * component;
                }
            }
        }
        if let Some(g) = gradient.as_deref_mut() {
            *g = if twist_gradient == InteractionRow::zeros() {
                JointVector::zeros()
            } else {
                let state = self.chain.jacobians_after_tip_pose(&mut workspace);
                let camera_jacobian = self.camera.camera_jacobian(state.tip_jacobian());
                (twist_gradient * camera_jacobian).transpose()
            };
        }
        checked_cost(Cost::<N>::name(self), value, gradient.as_deref())
    }
}

impl<const N: usize> Cost<N> for VisibilityCost<N> {
    fn value(&self, q: &JointVector<N>) -> Result<f64, CostError> {
        self.evaluate(q, None)
    }

    fn value_and_gradient(
        &self,
        q: &JointVector<N>,
        gradient: &mut JointVector<N>,
    ) -> Result<f64, CostError> {
        self.evaluate(q, Some(gradient))
    }

    fn name(&self) -> &str {
        "visibility"
    }
}
