//! The observation every feature reads ([`Observation`]): validated image points, their inverse depths (from the target
//! plane or the points' own depths) and their moments, computed once.

use super::{point_interaction, FeatureError, InteractionRow, Moments};
use crate::camera::ImagePoint;
use crate::target::TargetPlane;

/// Validated image points with their inverse depths and their moments, computed once and read by every feature
/// ([theory §7.1](crate::theory#s7-1), [§7.4](crate::theory#s7-4)).
#[derive(Debug, Clone)]
pub struct Observation<'a> {
    points: &'a [ImagePoint],
    plane: Option<TargetPlane>,
    /// Computed at the first [`Observation::moments`] call, so that features that read the points only (e.g.
    /// [`AllPoints`]) do not pay for them; kept even when they overflowed (`moments()` then fails).
    moments: std::cell::OnceCell<Moments>,
}

impl<'a> Observation<'a> {
    /// Validates `points` (normalised coordinates and depths in the camera frame) and the optional target plane
    /// `1/Z = A x + B y + C` (1/m, camera frame), then computes the [`Moments`] of the point set. Allocates nothing.
    ///
    /// The inverse depth of point k is `A x_k + B y_k + C` when `plane` is given, `1/Z_k` otherwise.
    ///
    /// # Errors
    /// [`FeatureError::TooFewPoints`] for an empty slice; [`FeatureError::NonFinitePoint`] /
    /// [`FeatureError::NonFinitePlane`] for NaN or infinite inputs (every field is checked, even the depths that a
    /// plane makes unused); [`FeatureError::PointBehindCamera`] when a depth in use is `≤ 0`;
    /// [`FeatureError::PlaneBehindCamera`] when the plane gives `1/Z ≤ 0` at a point. (Overflowing moments are reported
    /// by [`Observation::moments`].)
    pub fn new(
        points: &'a [ImagePoint],
        plane: Option<&TargetPlane>,
    ) -> Result<Self, FeatureError> {
        if points.is_empty() {
            return Err(FeatureError::TooFewPoints {
                feature: "observation",
                needed: 1,
                got: 0,
            });
        }
        if let Some(p) = plane {
            if !(p.a.is_finite() && p.b.is_finite() && p.c.is_finite()) {
                return Err(FeatureError::NonFinitePlane {
                    a: p.a,
                    b: p.b,
                    c: p.c,
                });
            }
        }
        for (index, p) in points.iter().enumerate() {
            if !(p.x.is_finite() && p.y.is_finite() && p.depth.is_finite()) {
                return Err(FeatureError::NonFinitePoint {
                    index,
                    x: p.x,
                    y: p.y,
                    depth: p.depth,
                });
            }
            match plane {
                Some(plane) => {
                    let inverse_depth = plane.inverse_depth(p.x, p.y);
                    if !(inverse_depth > 0.0 && inverse_depth.is_finite()) {
                        return Err(FeatureError::PlaneBehindCamera {
                            index,
                            inverse_depth,
                        });
                    }
                }
                None if p.depth <= 0.0 => {
                    return Err(FeatureError::PointBehindCamera {
                        index,
                        depth: p.depth,
                    })
                }
                None => {}
            }
        }
        Ok(Self {
            points,
            plane: plane.copied(),
            moments: std::cell::OnceCell::new(),
        })
    }

    /// The observed points.
    pub fn points(&self) -> &'a [ImagePoint] {
        self.points
    }

    /// The target plane, when one was given.
    pub fn plane(&self) -> Option<&TargetPlane> {
        self.plane.as_ref()
    }

    /// The moments of the point set, computed once, at the first call, and shared by every feature afterwards.
    ///
    /// # Errors
    /// [`FeatureError::NonFiniteResult`] when the moments overflow (coordinates beyond about 1e75).
    pub fn moments(&self) -> Result<&Moments, FeatureError> {
        let moments = self.moments.get_or_init(|| {
            Moments::compute(self.points, |p| inverse_depth(self.plane.as_ref(), p))
        });
        if moments.is_finite() {
            Ok(moments)
        } else {
            Err(FeatureError::NonFiniteResult { feature: "moments" })
        }
    }

    /// Number of observed points (at least 1).
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Always `false`: an observation has at least one point.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Inverse depth `1/Z_k` (1/m) of point `k` (plane model when known), or `None` when `k` is out of range.
    pub fn inverse_depth(&self, k: usize) -> Option<f64> {
        self.points
            .get(k)
            .map(|p| inverse_depth(self.plane.as_ref(), p))
    }

    /// The image point k and its interaction rows `(L_x, L_y)` \[M28\], or `None` when `k` is out of range.
    pub(super) fn point_rows(
        &self,
        k: usize,
    ) -> Option<(ImagePoint, InteractionRow, InteractionRow)> {
        let p = self.points.get(k)?;
        let (lx, ly) = point_interaction(p.x, p.y, inverse_depth(self.plane.as_ref(), p));
        Some((*p, lx, ly))
    }
}

/// Inverse depth of a validated point: plane model when known, `1/Z` otherwise.
fn inverse_depth(plane: Option<&TargetPlane>, p: &ImagePoint) -> f64 {
    match plane {
        Some(plane) => plane.inverse_depth(p.x, p.y),
        None => 1.0 / p.depth,
    }
}

#[cfg(test)]
mod tests {
    use super::super::testutil::*;
    use super::*;
    use approx::assert_relative_eq;
    use proptest::prelude::*;

    #[test]
    fn bad_observations_are_errors() {
        assert_eq!(
            Observation::new(&[], None).err(),
            Some(FeatureError::TooFewPoints {
                feature: "observation",
                needed: 1,
                got: 0
            })
        );
        let mut pts = rectangle_points_fronto(0.2, 0.1, 0.5);
        pts[1].y = f64::NAN;
        assert!(matches!(
            Observation::new(&pts, None),
            Err(FeatureError::NonFinitePoint { index: 1, .. })
        ));
        let mut pts = rectangle_points_fronto(0.2, 0.1, 0.5);
        pts[3].depth = f64::INFINITY;
        assert!(matches!(
            Observation::new(&pts, None),
            Err(FeatureError::NonFinitePoint { index: 3, .. })
        ));
        for depth in [0.0, -0.2] {
            let mut pts = rectangle_points_fronto(0.2, 0.1, 0.5);
            pts[2].depth = depth;
            assert_eq!(
                Observation::new(&pts, None).err(),
                Some(FeatureError::PointBehindCamera { index: 2, depth })
            );
        }
        let pts = rectangle_points_fronto(0.2, 0.1, 0.5);
        let nan_plane = TargetPlane {
            a: 0.0,
            b: f64::NAN,
            c: 2.0,
        };
        assert!(matches!(
            Observation::new(&pts, Some(&nan_plane)),
            Err(FeatureError::NonFinitePlane { .. })
        ));
        // A plane that passes through the camera's field of view behind it: 1/Z = 10 x + 1 is ≤ 0 at x = −0.2.
        let behind = TargetPlane {
            a: 10.0,
            b: 0.0,
            c: 1.0,
        };
        assert_eq!(
            Observation::new(&pts, Some(&behind)).err(),
            Some(FeatureError::PlaneBehindCamera {
                index: 0,
                inverse_depth: -1.0
            })
        );
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(32))]
        /// With the true plane, inverse depths and moments agree with the per-point depths.
        #[test]
        fn plane_and_depths_agree(pose in tilted_pose_strategy()) {
            let (pts, plane) = Scene::new(pose, rectangle(0.2, 0.14)).image();
            let with_plane = Observation::new(&pts, Some(&plane)).unwrap();
            let with_depths = Observation::new(&pts, None).unwrap();
            for (k, p) in pts.iter().enumerate() {
                assert_relative_eq!(with_plane.inverse_depth(k).unwrap(), 1.0 / p.depth, max_relative = 1e-12);
            }
            prop_assert_eq!(with_plane.inverse_depth(4), None);
            let (a, b) = (with_plane.moments().unwrap(), with_depths.moments().unwrap());
            assert_relative_eq!(a.interaction_mu(2, 1).unwrap(), b.interaction_mu(2, 1).unwrap(), max_relative = 1e-10);
        }
    }
}
