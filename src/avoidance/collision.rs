//! Collision geometry and signed distances: the one module of the crate that speaks parry3d-f64.
//!
//! Everything public here is nalgebra: shapes are described by [`Geometry`] (sizes in m), placed by an
//! `Isometry3<f64>` (`frame_from_shape`, the pose of the shape in the frame that carries it), and a query returns
//! nalgebra points and normals ([`Proximity`]). parry3d-f64 0.31 works on `glamx` types (`DVec3`, `DQuat`, `DPose3`);
//! the conversions live in the private functions at the bottom of this file, so no other module sees parry or glam.
//!
//! Conventions: the axis of a [`Geometry::Cylinder`] and of a [`Geometry::Capsule`] is the shape's z axis, as in URDF
//! (parry's cylinder is along y: the conversion adds a fixed rotation). A [`Proximity`] between a first and a second
//! collider gives the signed distance `d` (m; negative when they penetrate, minus the penetration depth), the witness
//! points on each surface, and the unit normal `n` pointing **from the first shape towards the second**, all in the
//! common frame the two poses are expressed in (the robot base frame in this crate). Moving the first shape's witness
//! point by `δp` changes `d` by `−nᵀ δp` to first order.
//!
//! Accuracy: parry's GJK terminates exactly on polytopes (boxes, convex hulls), segments and points, so distances and normals
//! involving spheres, boxes and capsules (queried as an inflated segment) are exact to rounding. On a cylinder's
//! curved side GJK only converges: its normal, hence an obstacle-cost gradient, is accurate to about 1e−3 (relative).

use super::CostError;
use nalgebra::{Isometry3, Point3, Unit, Vector3};
use parry3d_f64::math::{Pose as ParryPose, Vector as ParryVector};
use parry3d_f64::query;
use parry3d_f64::shape::{Ball, Capsule, ConvexPolyhedron, Cuboid, Cylinder, SharedShape};

/// A collision shape, in its own frame (sizes in m, all finite and > 0): a primitive centred on the origin, or the
/// convex hull of points (a URDF mesh, [D20](crate::theory#d20)).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Geometry {
    /// A ball of radius `radius_m`.
    Sphere {
        /// Radius (m).
        radius_m: f64,
    },
    /// A box with these full side lengths along x, y, z (the URDF `<box size>`).
    Box {
        /// Side lengths (m).
        size_m: [f64; 3],
    },
    /// A cylinder along z, `length_m` long (end caps at `z = ±length/2`).
    Cylinder {
        /// Radius (m).
        radius_m: f64,
        /// Length along z (m).
        length_m: f64,
    },
    /// A capsule along z: the segment `z ∈ [−length/2, length/2]` swept by a ball of radius `radius_m` (URDF
    /// `<capsule>`: total length `length + 2 radius`).
    Capsule {
        /// Radius (m).
        radius_m: f64,
        /// Length of the axis segment (m).
        length_m: f64,
    },
    /// The convex hull of these points (m; at least three, not all on a line): a URDF `<mesh>` read by
    /// [`crate::avoidance::LinkColliders`] holds the hull's vertices.
    ConvexHull {
        /// The points (m).
        points_m: Vec<[f64; 3]>,
    },
}

impl Geometry {
    /// The sizes of the shape, with their names, for validation and errors (the coordinates of a hull's points are
    /// checked apart: any finite value).
    fn sizes(&self) -> [(&'static str, f64); 3] {
        match *self {
            Self::ConvexHull { .. } => [("points_m", 1.0); 3],
            Self::Sphere { radius_m } => [("radius_m", radius_m); 3],
            Self::Box { size_m } => [
                ("size_m[0]", size_m[0]),
                ("size_m[1]", size_m[1]),
                ("size_m[2]", size_m[2]),
            ],
            Self::Cylinder { radius_m, length_m } | Self::Capsule { radius_m, length_m } => [
                ("radius_m", radius_m),
                ("length_m", length_m),
                ("length_m", length_m),
            ],
        }
    }

    /// The geometry read from a URDF `<collision>` element of `link`; a `<mesh>` is read from the file `meshes`
    /// leads to, scaled, and reduced to the vertices of its convex hull ([D20](crate::theory#d20)).
    ///
    /// # Errors
    /// For a `<mesh>`: [`CostError::UnknownPackage`], [`CostError::MeshFile`], [`CostError::MalformedMesh`],
    /// [`CostError::UnsupportedGeometry`] (a format other than STL, OBJ and COLLADA), [`CostError::InvalidGeometry`] (a
    /// non-finite or zero scale), [`CostError::DegenerateConvexHull`] (a mesh with all its vertices on a line).
    pub(crate) fn from_urdf(
        link: &str,
        geometry: &urdf_rs::Geometry,
        meshes: &super::MeshPaths,
    ) -> Result<Self, CostError> {
        Ok(match geometry {
            urdf_rs::Geometry::Box { size } => Self::Box { size_m: **size },
            urdf_rs::Geometry::Cylinder { radius, length } => Self::Cylinder {
                radius_m: *radius,
                length_m: *length,
            },
            urdf_rs::Geometry::Capsule { radius, length } => Self::Capsule {
                radius_m: *radius,
                length_m: *length,
            },
            urdf_rs::Geometry::Sphere { radius } => Self::Sphere { radius_m: *radius },
            urdf_rs::Geometry::Mesh { filename, scale } => {
                let scale = scale.map_or(Vector3::repeat(1.0), |s| Vector3::from(*s));
                if let Some(&value) = scale.iter().find(|v| !(v.is_finite() && **v != 0.0)) {
                    return Err(CostError::InvalidGeometry {
                        owner: link.to_owned(),
                        field: "mesh scale",
                        value,
                    });
                }
                let path = meshes.resolve(link, filename)?;
                let vertices =
                    super::mesh::read_vertices(link, &path, scale, meshes.max_file_bytes())?;
                let hull =
                    convex_hull(&vertices).ok_or_else(|| CostError::DegenerateConvexHull {
                        owner: link.to_owned(),
                        points: vertices.len(),
                    })?;
                Self::ConvexHull {
                    points_m: hull.points().iter().map(|p| [p.x, p.y, p.z]).collect(),
                }
            }
        })
    }
}

/// The convex hull of a [`Geometry::ConvexHull`]'s points, checked.
///
/// # Errors
/// [`CostError::InvalidGeometry`] for a non-finite coordinate, [`CostError::DegenerateConvexHull`].
fn hull_of_points(owner: &str, points_m: &[[f64; 3]]) -> Result<ConvexPolyhedron, CostError> {
    if let Some(&value) = points_m.iter().flatten().find(|v| !v.is_finite()) {
        return Err(CostError::InvalidGeometry {
            owner: owner.to_owned(),
            field: "points_m",
            value,
        });
    }
    let points: Vec<Vector3<f64>> = points_m.iter().map(|&p| p.into()).collect();
    convex_hull(&points).ok_or_else(|| CostError::DegenerateConvexHull {
        owner: owner.to_owned(),
        points: points.len(),
    })
}

/// parry's convex hull of `points`, `None` when parry builds none (too few points, all on a line).
fn convex_hull(points: &[Vector3<f64>]) -> Option<ConvexPolyhedron> {
    let points: Vec<ParryVector> = points.iter().map(to_parry_vector).collect();
    ConvexPolyhedron::from_convex_hull(&points)
}

/// A [`Geometry`] placed in a frame: the shape's pose `frame_from_shape` in the frame that carries it (a link frame,
/// or the robot base frame for a world obstacle). Built once; queries allocate nothing.
#[derive(Clone)]
pub struct Collider {
    geometry: Geometry,
    frame_from_shape: Isometry3<f64>,
    /// The parry shape and the pose of parry's shape frame in our shape frame (a rotation for the cylinder).
    shape: SharedShape,
    shape_from_parry: Isometry3<f64>,
    /// The radius of a ball about the shape's origin that contains it (m): far pairs are dismissed on it.
    bounding_radius: f64,
    /// A capsule is queried as its axis segment inflated by this radius (m; 0 otherwise): GJK terminates exactly on
    /// a segment, while on the rounded capsule its normal converges only to ~1e−4, which the gradient inherits.
    inflation: f64,
}

impl std::fmt::Debug for Collider {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Collider")
            .field("geometry", &self.geometry)
            .field("frame_from_shape", &self.frame_from_shape)
            .finish()
    }
}

impl PartialEq for Collider {
    fn eq(&self, other: &Self) -> bool {
        self.geometry == other.geometry && self.frame_from_shape == other.frame_from_shape
    }
}

impl Collider {
    /// A collider of `geometry` at `frame_from_shape`. `owner` names the link or obstacle, for errors.
    ///
    /// # Errors
    /// [`CostError::InvalidGeometry`] for a size that is not finite and > 0, or a non-finite pose.
    pub fn new(
        owner: &str,
        geometry: Geometry,
        frame_from_shape: Isometry3<f64>,
    ) -> Result<Self, CostError> {
        if let Some((field, value)) = geometry
            .sizes()
            .into_iter()
            .find(|(_, v)| !(v.is_finite() && *v > 0.0))
        {
            return Err(CostError::InvalidGeometry {
                owner: owner.to_owned(),
                field,
                value,
            });
        }
        let pose_values = frame_from_shape
            .translation
            .vector
            .iter()
            .chain(frame_from_shape.rotation.coords.iter());
        if let Some(&value) = pose_values.clone().find(|v| !v.is_finite()) {
            return Err(CostError::InvalidGeometry {
                owner: owner.to_owned(),
                field: "pose",
                value,
            });
        }
        let (shape, shape_from_parry) = match geometry {
            Geometry::Sphere { radius_m } => (SharedShape::new(Ball::new(radius_m)), identity()),
            Geometry::Box { size_m } => (
                SharedShape::new(Cuboid::new(to_parry_vector(&(Vector3::from(size_m) * 0.5)))),
                identity(),
            ),
            // parry's cylinder is along its y axis: rotate it by +90° about x to lay it along our z.
            Geometry::Cylinder { radius_m, length_m } => (
                SharedShape::new(Cylinder::new(0.5 * length_m, radius_m)),
                Isometry3::rotation(Vector3::x() * std::f64::consts::FRAC_PI_2),
            ),
            Geometry::Capsule { length_m, .. } => (
                SharedShape::new(Capsule::new_z(0.5 * length_m, 0.0).segment),
                identity(),
            ),
            Geometry::ConvexHull { ref points_m } => (
                SharedShape::new(hull_of_points(owner, points_m)?),
                identity(),
            ),
        };
        let inflation = match geometry {
            Geometry::Capsule { radius_m, .. } => radius_m,
            _ => 0.0,
        };
        let bounding_radius = match geometry {
            Geometry::Sphere { radius_m } => radius_m,
            Geometry::Box { size_m } => 0.5 * Vector3::from(size_m).norm(),
            Geometry::Cylinder { radius_m, length_m } => radius_m.hypot(0.5 * length_m),
            Geometry::Capsule { radius_m, length_m } => radius_m + 0.5 * length_m,
            Geometry::ConvexHull { ref points_m } => points_m
                .iter()
                .map(|&p| Vector3::from(p).norm())
                .fold(0.0, f64::max),
        };
        Ok(Self {
            geometry,
            frame_from_shape,
            shape,
            shape_from_parry,
            bounding_radius,
            inflation,
        })
    }

    /// The shape.
    pub fn geometry(&self) -> &Geometry {
        &self.geometry
    }

    /// The pose of the shape in the frame that carries it.
    pub fn frame_from_shape(&self) -> &Isometry3<f64> {
        &self.frame_from_shape
    }

    /// The parry pose of the shape when its carrying frame is at `base_from_frame`.
    fn parry_pose(&self, base_from_frame: &Isometry3<f64>) -> ParryPose {
        to_parry_pose(&(base_from_frame * self.frame_from_shape * self.shape_from_parry))
    }
}

/// The closest points of two colliders closer than a cut-off (see the [module docs](self) for the conventions).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Proximity {
    /// Signed distance (m): positive apart, negative when penetrating.
    pub distance: f64,
    /// The witness point on the first shape (base frame).
    pub point_on_first: Point3<f64>,
    /// The witness point on the second shape (base frame).
    pub point_on_second: Point3<f64>,
    /// The unit normal from the first shape towards the second (base frame).
    pub normal: Unit<Vector3<f64>>,
}

/// The closest points of `first` (its frame at `base_from_first`) and `second` (at `base_from_second`) when their
/// signed distance is below `cutoff` (m), else `None` — parry's contact query with prediction distance `cutoff`, after
/// a bounding-ball test that dismisses far pairs without it. Allocation-free while the shapes do not penetrate (parry's EPA, used for the
/// penetration depth of non-ball pairs, allocates).
///
/// # Errors
/// [`CostError::UnsupportedShapePair`] if parry has no algorithm for the pair (none of the [`Geometry`] pairs).
pub fn proximity(
    first: &Collider,
    base_from_first: &Isometry3<f64>,
    second: &Collider,
    base_from_second: &Isometry3<f64>,
    cutoff: f64,
) -> Result<Option<Proximity>, CostError> {
    // Bounding balls farther apart than the cut-off: no query at all.
    let centre = |c: &Collider, base_from_frame: &Isometry3<f64>| {
        (base_from_frame * c.frame_from_shape).translation.vector
    };
    let gap = (centre(first, base_from_first) - centre(second, base_from_second)).norm()
        - first.bounding_radius
        - second.bounding_radius;
    if gap >= cutoff {
        return Ok(None);
    }
    let inflation = first.inflation + second.inflation;
    let contact = query::contact(
        &first.parry_pose(base_from_first),
        first.shape.as_ref(),
        &second.parry_pose(base_from_second),
        second.shape.as_ref(),
        cutoff + inflation,
    )
    .map_err(|_| CostError::UnsupportedShapePair {
        first: first.geometry.clone(),
        second: second.geometry.clone(),
    })?;
    Ok(contact.and_then(|c| {
        let normal = Unit::try_new(from_parry_vector(&c.normal1), 1e-12)?;
        Some(Proximity {
            distance: c.dist - inflation,
            point_on_first: Point3::from(from_parry_vector(&c.point1)) + *normal * first.inflation,
            point_on_second: Point3::from(from_parry_vector(&c.point2))
                - *normal * second.inflation,
            normal,
        })
        .filter(|p| p.distance.is_finite() && p.distance < cutoff)
    }))
}

/// The signed distance (m) between two colliders, whatever it is: positive apart, minus the penetration depth when
/// they overlap. Not for the real-time path (a penetration query may allocate).
///
/// # Errors
/// As [`proximity`].
pub fn signed_distance(
    first: &Collider,
    base_from_first: &Isometry3<f64>,
    second: &Collider,
    base_from_second: &Isometry3<f64>,
) -> Result<f64, CostError> {
    let unsupported = |_| CostError::UnsupportedShapePair {
        first: first.geometry.clone(),
        second: second.geometry.clone(),
    };
    let (pose1, pose2) = (
        first.parry_pose(base_from_first),
        second.parry_pose(base_from_second),
    );
    let distance = query::distance(&pose1, first.shape.as_ref(), &pose2, second.shape.as_ref())
        .map_err(unsupported)?
        .distance;
    let inflation = first.inflation + second.inflation;
    if distance > 0.0 {
        return Ok(distance - inflation);
    }
    let contact = query::contact(
        &pose1,
        first.shape.as_ref(),
        &pose2,
        second.shape.as_ref(),
        0.0,
    )
    .map_err(unsupported)?;
    Ok(contact.map_or(0.0, |c| c.dist.min(0.0)) - inflation)
}

fn identity() -> Isometry3<f64> {
    Isometry3::identity()
}

fn to_parry_vector(v: &Vector3<f64>) -> ParryVector {
    ParryVector::new(v.x, v.y, v.z)
}

fn from_parry_vector(v: &ParryVector) -> Vector3<f64> {
    Vector3::new(v.x, v.y, v.z)
}

fn to_parry_pose(pose: &Isometry3<f64>) -> ParryPose {
    let q = pose.rotation.quaternion();
    ParryPose::from_parts(
        to_parry_vector(&pose.translation.vector),
        parry3d_f64::math::Rot3::from_xyzw(q.i, q.j, q.k, q.w),
    )
}

/// The inverse of [`to_parry_pose`] (used by the conversion tests).
#[cfg(test)]
fn from_parry_pose(pose: &ParryPose) -> Isometry3<f64> {
    use nalgebra::{Quaternion, Translation3, UnitQuaternion};
    let r = pose.rotation;
    Isometry3::from_parts(
        Translation3::from(from_parry_vector(&pose.translation)),
        UnitQuaternion::new_normalize(Quaternion::new(r.w, r.x, r.y, r.z)),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn pose_conversion_round_trips_and_maps_points_alike() {
        let pose = Isometry3::new(Vector3::new(0.3, -0.2, 1.1), Vector3::new(0.4, -1.2, 0.7));
        let parry = to_parry_pose(&pose);
        assert_relative_eq!(from_parry_pose(&parry), pose, epsilon = 1e-15);
        let p = Point3::new(0.1, 0.5, -0.3);
        let mapped = parry * to_parry_vector(&p.coords);
        assert_relative_eq!(
            from_parry_vector(&mapped),
            (pose * p).coords,
            epsilon = 1e-14
        );
    }

    /// Hand-computed distances: sphere–sphere, box–sphere, a cylinder laid along z (its side, not its cap, faces x),
    /// a capsule along z.
    #[test]
    fn hand_computed_signed_distances() {
        let ball = Collider::new("b", Geometry::Sphere { radius_m: 0.1 }, identity()).unwrap();
        let at = |x, y, z| Isometry3::translation(x, y, z);
        let p = proximity(&ball, &at(0.0, 0.0, 0.0), &ball, &at(0.5, 0.0, 0.0), 1.0)
            .unwrap()
            .unwrap();
        assert_relative_eq!(p.distance, 0.3, epsilon = 1e-12);
        assert_relative_eq!(p.normal.into_inner(), Vector3::x(), epsilon = 1e-12);
        assert_relative_eq!(
            p.point_on_first,
            Point3::new(0.1, 0.0, 0.0),
            epsilon = 1e-12
        );
        assert_relative_eq!(
            p.point_on_second,
            Point3::new(0.4, 0.0, 0.0),
            epsilon = 1e-12
        );
        // Beyond the cut-off: nothing.
        assert!(
            proximity(&ball, &at(0.0, 0.0, 0.0), &ball, &at(0.5, 0.0, 0.0), 0.29)
                .unwrap()
                .is_none()
        );
        let cube = Collider::new(
            "c",
            Geometry::Box {
                size_m: [0.2, 0.4, 0.6],
            },
            identity(),
        )
        .unwrap();
        assert_relative_eq!(
            signed_distance(&cube, &at(0.0, 0.0, 0.0), &ball, &at(0.0, 0.0, 0.5)).unwrap(),
            0.1,
            epsilon = 1e-9
        );
        // Penetrating by 0.05 along y.
        assert_relative_eq!(
            signed_distance(&cube, &at(0.0, 0.0, 0.0), &ball, &at(0.0, 0.25, 0.0)).unwrap(),
            -0.05,
            epsilon = 1e-9
        );
        let cylinder = Collider::new(
            "z",
            Geometry::Cylinder {
                radius_m: 0.05,
                length_m: 1.0,
            },
            identity(),
        )
        .unwrap();
        // 0.4 m from the axis sideways; 0.3 m beyond the end cap along z.
        assert_relative_eq!(
            signed_distance(&cylinder, &at(0.0, 0.0, 0.0), &ball, &at(0.4, 0.0, 0.3)).unwrap(),
            0.25,
            epsilon = 1e-6
        );
        assert_relative_eq!(
            signed_distance(&cylinder, &at(0.0, 0.0, 0.0), &ball, &at(0.0, 0.0, 0.9)).unwrap(),
            0.3,
            epsilon = 1e-6
        );
        let capsule = Collider::new(
            "k",
            Geometry::Capsule {
                radius_m: 0.05,
                length_m: 1.0,
            },
            Isometry3::translation(0.0, 0.0, 1.0),
        )
        .unwrap();
        assert_relative_eq!(
            signed_distance(&capsule, &at(0.0, 0.0, 0.0), &ball, &at(0.0, 0.0, 2.0)).unwrap(),
            0.35,
            epsilon = 1e-6
        );
    }

    #[test]
    fn invalid_sizes_and_meshes_are_errors() {
        assert_eq!(
            Collider::new("post", Geometry::Sphere { radius_m: -1.0 }, identity()),
            Err(CostError::InvalidGeometry {
                owner: "post".into(),
                field: "radius_m",
                value: -1.0
            })
        );
        assert!(matches!(
            Collider::new(
                "post",
                Geometry::Box {
                    size_m: [0.1, f64::NAN, 0.1]
                },
                identity()
            ),
            Err(CostError::InvalidGeometry {
                field: "size_m[1]",
                ..
            })
        ));
        // Points on a line, or none, make no polyhedron.
        for points_m in [
            vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]],
            vec![],
        ] {
            let points = points_m.len();
            assert_eq!(
                Collider::new("rod", Geometry::ConvexHull { points_m }, identity()),
                Err(CostError::DegenerateConvexHull {
                    owner: "rod".into(),
                    points
                })
            );
        }
        let nan = Geometry::ConvexHull {
            points_m: vec![[0.0, f64::NAN, 0.0]],
        };
        assert!(matches!(
            Collider::new("plate", nan, identity()),
            Err(CostError::InvalidGeometry {
                field: "points_m",
                ..
            })
        ));
        // A zero mesh scale.
        let mesh = urdf_rs::Geometry::Mesh {
            filename: "arm.stl".into(),
            scale: Some(urdf_rs::Vec3([1.0, 0.0, 1.0])),
        };
        assert!(matches!(
            Geometry::from_urdf("wrist", &mesh, &super::super::MeshPaths::new("")),
            Err(CostError::InvalidGeometry { field: "mesh scale", value, .. }) if value == 0.0
        ));
    }

    /// A convex hull's distances by hand: a unit tetrahedron (0, e_x, e_y, e_z) and a ball on the x axis, and the
    /// hull of a cube's corners plus interior points against the equivalent box.
    #[test]
    fn convex_hull_distances_by_hand() {
        let tetra = Collider::new(
            "t",
            Geometry::ConvexHull {
                points_m: vec![
                    [0.0, 0.0, 0.0],
                    [1.0, 0.0, 0.0],
                    [0.0, 1.0, 0.0],
                    [0.0, 0.0, 1.0],
                ],
            },
            identity(),
        )
        .unwrap();
        let ball = Collider::new("b", Geometry::Sphere { radius_m: 0.1 }, identity()).unwrap();
        let at = |x, y, z| Isometry3::translation(x, y, z);
        // Ball centre at (-0.5, 0.2, 0.2): nearest hull point is on the face x = 0, distance 0.5 − 0.1.
        let p = proximity(&tetra, &at(0.0, 0.0, 0.0), &ball, &at(-0.5, 0.2, 0.2), 1.0)
            .unwrap()
            .unwrap();
        assert_relative_eq!(p.distance, 0.4, epsilon = 1e-12);
        assert_relative_eq!(p.normal.into_inner(), -Vector3::x(), epsilon = 1e-12);
        // Beyond the slanted face x + y + z = 1: centre at (1,1,1), distance (3 − 1)/√3 − 0.1.
        assert_relative_eq!(
            signed_distance(&tetra, &at(0.0, 0.0, 0.0), &ball, &at(1.0, 1.0, 1.0)).unwrap(),
            2.0 / 3f64.sqrt() - 0.1,
            epsilon = 1e-9
        );
        let mut corners: Vec<[f64; 3]> = (0..8)
            .map(|i| {
                [
                    0.1 * (i & 1) as f64,
                    0.2 * ((i >> 1) & 1) as f64,
                    0.3 * (i >> 2) as f64,
                ]
            })
            .collect();
        corners.push([0.05, 0.1, 0.15]); // inside: not a vertex of the hull
        let hull =
            Collider::new("h", Geometry::ConvexHull { points_m: corners }, identity()).unwrap();
        let cube = Collider::new(
            "c",
            Geometry::Box {
                size_m: [0.1, 0.2, 0.3],
            },
            at(0.05, 0.1, 0.15),
        )
        .unwrap();
        for centre in [at(0.4, 0.1, 0.1), at(-0.2, -0.3, 0.5), at(0.05, 0.1, 0.6)] {
            assert_relative_eq!(
                signed_distance(&hull, &identity(), &ball, &centre).unwrap(),
                signed_distance(&cube, &identity(), &ball, &centre).unwrap(),
                epsilon = 1e-9
            );
        }
    }
}
