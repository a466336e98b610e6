//! Perspective features of a four-point target that stay defined for a square seen head-on: the normalised
//! differences of opposite side lengths. The replacement of the paper's `P_x, P_y` (task e4) when the target is
//! centrally symmetric, where `I1 → 0` makes `P_x, P_y` undefined ([D9](crate::theory#d9)).

use super::{Feature, FeatureError, InteractionRow, InteractionSource, Observation};

/// Task e4 for centrally symmetric (square) targets: `s = (r_x, r_y)`, 2 rows, for four points numbered around the
/// target (P0 → P1 → P2 → P3, as [`crate::target::RectangleTarget`]):
///
/// ```text
/// l_ij = ‖p_j − p_i‖                         image length of side i–j (normalised units)
/// r_x  = (l_12 − l_30) / (l_12 + l_30)       the two sides P1P2 and P3P0 (along the target's y axis)
/// r_y  = (l_23 − l_01) / (l_23 + l_01)       the two sides P2P3 and P0P1 (along the target's x axis)
/// ```
///
/// A rotation of the camera about its y axis brings one of the sides P1P2, P3P0 closer, so its image grows and the
/// other shrinks: `r_x` measures that perspective (it constrains `ωy`, coupled with `υx`, as the paper's `P_x`); `r_y`
/// likewise for `ωx` (coupled with `υy`). Both are invariant to image scale, so they do not fight `a_n`; both are `0`
/// for any parallelogram image, in particular a square or rectangle seen head-on.
///
/// Interaction matrix, exact by the chain rule over the point rows \[M28\] (`L_{p_k} = (L_{x_k}; L_{y_k})`):
///
/// ```text
/// L_{l_ij} = ((x_j − x_i)(L_{x_j} − L_{x_i}) + (y_j − y_i)(L_{y_j} − L_{y_i})) / l_ij
/// L_r      = 2 (l_b L_{l_a} − l_a L_{l_b}) / (l_a + l_b)²        for r = (l_a − l_b)/(l_a + l_b)
/// ```
///
/// Every [`InteractionSource`] uses this exact form (the paper has no approximation for it); for `Desired`, pass the
/// desired observation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SideRatios;

impl SideRatios {
    /// The (side a, side b) point pairs of `r_x` and `r_y`.
    const SIDES: [[(usize, usize); 2]; 2] = [[(1, 2), (3, 0)], [(2, 3), (0, 1)]];

    /// `(l_ij, L_{l_ij})` of the side from point `i` to point `j`.
    fn side(
        obs: &Observation<'_>,
        i: usize,
        j: usize,
    ) -> Result<(f64, InteractionRow), FeatureError> {
        let too_few = FeatureError::TooFewPoints {
            feature: "side ratios",
            needed: 4,
            got: obs.len(),
        };
        let (pi, lxi, lyi) = obs.point_rows(i).ok_or(too_few.clone())?;
        let (pj, lxj, lyj) = obs.point_rows(j).ok_or(too_few)?;
        let (dx, dy) = (pj.x - pi.x, pj.y - pi.y);
        let length = dx.hypot(dy);
        let scale = pi.x.abs() + pi.y.abs() + pj.x.abs() + pj.y.abs();
        if length <= super::RELATIVE_TOLERANCE * scale || length == 0.0 {
            return Err(FeatureError::DegenerateSegment {
                from: i,
                to: j,
                length,
            });
        }
        Ok((length, ((lxj - lxi) * dx + (lyj - lyi) * dy) / length))
    }

    /// `[(r_x, L_{r_x}), (r_y, L_{r_y})]`.
    fn evaluate(
        &self,
        obs: &Observation<'_>,
        _source: InteractionSource,
    ) -> Result<[(f64, InteractionRow); 2], FeatureError> {
        if obs.len() != 4 {
            return Err(FeatureError::PointCountMismatch {
                feature: "side ratios",
                expected: 4,
                got: obs.len(),
            });
        }
        let ratio = |[(ai, aj), (bi, bj)]: [(usize, usize); 2]| {
            let (la, l_la) = Self::side(obs, ai, aj)?;
            let (lb, l_lb) = Self::side(obs, bi, bj)?;
            let sum = la + lb;
            Ok((
                (la - lb) / sum,
                (l_la * lb - l_lb * la) * (2.0 / (sum * sum)),
            ))
        };
        Ok([ratio(Self::SIDES[0])?, ratio(Self::SIDES[1])?])
    }
}

impl Feature for SideRatios {
    fn name(&self) -> &'static str {
        "side ratios"
    }
    fn dim(&self) -> usize {
        2
    }
    fn is_angle(&self, _row: usize) -> bool {
        false
    }
    fn min_points(&self) -> usize {
        4
    }
    writes_from_one_evaluation!(Self::evaluate);
}

#[cfg(test)]
mod tests {
    use super::super::testutil::*;
    use super::*;
    use crate::camera::ImagePoint;
    use approx::assert_relative_eq;
    use proptest::prelude::*;

    #[test]
    fn values_by_hand() {
        // A trapezoid: right side P1P2 from (0.1, −0.1) to (0.1, 0.1) (length 0.2), left side P3P0 from (−0.1, 0.05)
        // to (−0.1, −0.05) (length 0.1): r_x = 0.1/0.3. Top P0P1 = √(0.04 + 0.0025), bottom P2P3 the same: r_y = 0.
        let pts = [(-0.1, -0.05), (0.1, -0.1), (0.1, 0.1), (-0.1, 0.05)]
            .map(|(x, y)| ImagePoint::new(x, y, 0.5));
        let obs = Observation::new(&pts, None).unwrap();
        let mut s = [0.0; 2];
        SideRatios.value(&obs, &mut s).unwrap();
        assert_relative_eq!(s[0], 1.0 / 3.0, epsilon = 1e-15);
        assert_relative_eq!(s[1], 0.0, epsilon = 1e-15);
        // Head-on square: both zero.
        let square = rectangle_points_fronto(0.15, 0.15, 0.5);
        SideRatios
            .value(&Observation::new(&square, None).unwrap(), &mut s)
            .unwrap();
        assert_eq!(s, [0.0, 0.0]);
    }

    #[test]
    fn degenerate_inputs_are_errors() {
        let mut pts = rectangle_points_fronto(0.15, 0.15, 0.5);
        pts[2] = pts[1];
        let mut s = [0.0; 2];
        assert!(matches!(
            SideRatios.value(&Observation::new(&pts, None).unwrap(), &mut s),
            Err(FeatureError::DegenerateSegment { from: 1, to: 2, .. })
        ));
        let three = &rectangle_points_fronto(0.15, 0.15, 0.5)[..3];
        assert!(matches!(
            SideRatios.value(&Observation::new(three, None).unwrap(), &mut s),
            Err(FeatureError::TooFewPoints { .. })
        ));
        let five = [ImagePoint::new(0.0, 0.0, 1.0); 5];
        assert!(matches!(
            SideRatios.value(&Observation::new(&five, None).unwrap(), &mut s),
            Err(FeatureError::PointCountMismatch {
                expected: 4,
                got: 5,
                ..
            })
        ));
    }

    /// At a square seen head-on the rows are pure rotations: `r_x` along `ωy`, `r_y` along `ωx` (translations do not
    /// change side-length ratios of a fronto-parallel target to first order).
    #[test]
    fn head_on_square_rows_are_the_two_tilts() {
        let scene = Scene::new(pose(0.0, 0.0, 0.5, 0.0, 0.0, 0.0), rectangle(0.15, 0.15));
        scene.check_exact(&SideRatios, false);
        let l = scene.interaction(&SideRatios, InteractionSource::Exact, false);
        for (row, column) in [(0, 4), (1, 3)] {
            for c in 0..6 {
                if c == column {
                    assert!(l[(row, c)].abs() > 0.1, "{l}");
                } else {
                    assert!(l[(row, c)].abs() < 1e-12, "{l}");
                }
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(32))]
        /// The exact rows match finite differences of real camera motion, for tilted squares and rectangles (current
        /// depths and the plane model alike).
        #[test]
        fn side_ratios_match_camera_motion(pose in tilted_pose_strategy(), aspect in 0.5..1.5f64, use_plane in any::<bool>()) {
            let scene = Scene::new(pose, rectangle(0.15, 0.15 * aspect));
            scene.check_exact(&SideRatios, use_plane);
        }
    }
}
