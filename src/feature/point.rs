//! Image point features, [\[M28\]](crate::theory#m28) ([§7.1](crate::theory#s7-1)).

use super::{
    Feature, FeatureError, InteractionRow, InteractionRows, InteractionSource, Observation,
};

/// Interaction rows of an image point `(x, y)` with inverse depth `ζ = 1/Z` (1/m), [\[M28\]](crate::theory#m28):
///
/// ```text
/// L_x = [ −ζ   0   xζ   xy      −(1+x²)   y ]
/// L_y = [  0  −ζ   yζ   1+y²    −xy      −x ]
/// ```
pub fn point_interaction(x: f64, y: f64, inverse_depth: f64) -> (InteractionRow, InteractionRow) {
    let z = inverse_depth;
    (
        InteractionRow::new(-z, 0.0, x * z, x * y, -(1.0 + x * x), y),
        InteractionRow::new(0.0, -z, y * z, 1.0 + y * y, -x * y, -x),
    )
}

/// The image point number `index`: `s = (x_k, y_k)` (normalised), interaction rows \[M28\] with the point's exact
/// depth. The paper has no approximate form for points, so every [`InteractionSource`] uses \[M28\] on the observation
/// passed in (for `Desired`, the desired observation, i.e. the desired depths).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Point {
    index: usize,
}

impl Point {
    /// The point of index `index` (0-based) in the observation.
    pub fn new(index: usize) -> Self {
        Self { index }
    }
}

impl Feature for Point {
    fn name(&self) -> &'static str {
        "point"
    }
    fn dim(&self) -> usize {
        2
    }
    fn is_angle(&self, _row: usize) -> bool {
        false
    }
    fn min_points(&self) -> usize {
        self.index.saturating_add(1)
    }
    fn write_value(&self, obs: &Observation<'_>, s: &mut [f64]) -> Result<(), FeatureError> {
        let (p, _, _) = rows(self, obs, self.index)?;
        super::write_values(s, &[p.x, p.y]);
        Ok(())
    }
    fn write_interaction(
        &self,
        obs: &Observation<'_>,
        _source: InteractionSource,
        l: InteractionRows<'_>,
    ) -> Result<(), FeatureError> {
        let (_, lx, ly) = rows(self, obs, self.index)?;
        super::write_rows(l, &[lx, ly]);
        Ok(())
    }
}

/// All N points of the observation, stacked: `s = (x_1, y_1, …, x_N, y_N)` (2N rows), rows \[M28\] (the classical
/// point-based task, [peer scene variant A](crate::theory::peer_scene#variant-a)). Every [`InteractionSource`] uses \[M28\], as for [`Point`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AllPoints {
    count: usize,
}

impl AllPoints {
    /// The largest point count accepted (far beyond any image-point task; it bounds the task storage).
    pub const MAX_POINTS: usize = 4096;

    /// The feature for exactly `count` points (`1 ≤ count ≤ MAX_POINTS`).
    ///
    /// # Errors
    /// [`FeatureError::InvalidParameter`] for a count out of that range.
    pub fn new(count: usize) -> Result<Self, FeatureError> {
        if (1..=Self::MAX_POINTS).contains(&count) {
            Ok(Self { count })
        } else {
            Err(FeatureError::InvalidParameter {
                name: "point count",
                value: count as f64,
                expected: "from 1 to MAX_POINTS",
            })
        }
    }

    fn check_count(&self, obs: &Observation<'_>) -> Result<(), FeatureError> {
        if obs.len() != self.count {
            return Err(FeatureError::PointCountMismatch {
                feature: self.name(),
                expected: self.count,
                got: obs.len(),
            });
        }
        Ok(())
    }
}

impl Feature for AllPoints {
    fn name(&self) -> &'static str {
        "all points"
    }
    fn dim(&self) -> usize {
        2 * self.count
    }
    fn is_angle(&self, _row: usize) -> bool {
        false
    }
    fn min_points(&self) -> usize {
        self.count
    }
    fn write_value(&self, obs: &Observation<'_>, s: &mut [f64]) -> Result<(), FeatureError> {
        self.check_count(obs)?;
        for (xy, p) in s.chunks_exact_mut(2).zip(obs.points()) {
            super::write_values(xy, &[p.x, p.y]);
        }
        Ok(())
    }
    fn write_interaction(
        &self,
        obs: &Observation<'_>,
        _source: InteractionSource,
        mut l: InteractionRows<'_>,
    ) -> Result<(), FeatureError> {
        self.check_count(obs)?;
        for k in 0..self.count {
            let (_, lx, ly) = rows(self, obs, k)?;
            super::write_rows(l.rows_mut(2 * k, 2), &[lx, ly]);
        }
        Ok(())
    }
}

/// Point k with its rows, or [`FeatureError::TooFewPoints`].
fn rows<F: Feature>(
    feature: &F,
    obs: &Observation<'_>,
    k: usize,
) -> Result<
    (
        crate::camera::ImagePoint,
        super::InteractionRow,
        super::InteractionRow,
    ),
    FeatureError,
> {
    obs.point_rows(k).ok_or(FeatureError::TooFewPoints {
        feature: feature.name(),
        needed: k + 1,
        got: obs.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::super::testutil::*;
    use super::*;
    use approx::assert_relative_eq;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]
        #[test]
        fn point_rows_match_camera_motion(pose in tilted_pose_strategy(), k in 0usize..4, plane in any::<bool>()) {
            let scene = Scene::new(pose, rectangle(0.2, 0.14));
            scene.check_exact(&Point::new(k), plane);
        }

        #[test]
        fn all_points_match_camera_motion(pose in tilted_pose_strategy(), plane in any::<bool>()) {
            let scene = Scene::new(pose, rectangle(0.2, 0.1));
            scene.check_exact(&AllPoints::new(4).unwrap(), plane);
        }
    }

    #[test]
    fn hand_computed_point_rows() {
        // x = 0.1, y = -0.2, Z = 2: L_x = [-0.5, 0, 0.05, -0.02, -1.01, -0.2], L_y = [0, -0.5, -0.1, 1.04, 0.02, -0.1].
        let pts = [crate::camera::ImagePoint::new(0.1, -0.2, 2.0)];
        let obs = Observation::new(&pts, None).unwrap();
        let mut l = nalgebra::OMatrix::<f64, nalgebra::Dyn, nalgebra::U6>::zeros(2);
        Point::new(0)
            .interaction(&obs, InteractionSource::Exact, l.rows_mut(0, 2))
            .unwrap();
        let expected = nalgebra::Matrix2x6::new(
            -0.5, 0.0, 0.05, -0.02, -1.01, -0.2, //
            0.0, -0.5, -0.1, 1.04, 0.02, -0.1,
        );
        assert_relative_eq!(l.fixed_rows::<2>(0).into_owned(), expected, epsilon = 1e-15);
    }

    #[test]
    fn bad_point_counts_are_errors() {
        for count in [0, AllPoints::MAX_POINTS + 1, usize::MAX] {
            assert!(matches!(
                AllPoints::new(count),
                Err(FeatureError::InvalidParameter {
                    name: "point count",
                    ..
                })
            ));
        }
        // A huge point index is a too-few-points error, not an overflow.
        let far = Point::new(usize::MAX);
        assert_eq!(far.min_points(), usize::MAX);
        let pts = rectangle_points_fronto(0.2, 0.1, 0.5);
        let obs = Observation::new(&pts[..3], None).unwrap();
        let mut s = [0.0; 2];
        assert_eq!(
            Point::new(3).value(&obs, &mut s),
            Err(FeatureError::TooFewPoints {
                feature: "point",
                needed: 4,
                got: 3
            })
        );
        let mut s8 = [0.0; 8];
        assert_eq!(
            AllPoints::new(4).unwrap().value(&obs, &mut s8),
            Err(FeatureError::TooFewPoints {
                feature: "all points",
                needed: 4,
                got: 3
            })
        );
        let obs4 = Observation::new(&pts, None).unwrap();
        let mut s6 = [0.0; 6];
        assert_eq!(
            AllPoints::new(3).unwrap().value(&obs4, &mut s6),
            Err(FeatureError::PointCountMismatch {
                feature: "all points",
                expected: 3,
                got: 4
            })
        );
        assert_eq!(
            AllPoints::new(4).unwrap().value(&obs4, &mut s6),
            Err(FeatureError::WrongDimension {
                feature: "all points",
                expected: 8,
                got: 6
            })
        );
    }
}
