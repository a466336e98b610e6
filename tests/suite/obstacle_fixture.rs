//! A shared obstacle scene around the Afma6's reference configuration: three obstacles (a sphere by the camera, a box
//! under the tool arm, a tilted cylinder beside the wrist), every link with collision geometry paired with each.

use nalgebra::{Isometry3, Vector3};
use servostack::avoidance::{Geometry, LinkColliders, Obstacle, ObstacleCost, ObstaclePair};
use servostack::math::JointVector;
use servostack::robot::builtin;

/// The configuration the obstacles are placed around (the reference scenario's desired configuration).
pub fn reference_q() -> JointVector<6> {
    JointVector::<6>::new(0.0, 0.0, 0.0, 0.0, 0.3, 0.0)
}

/// The links of the Afma6 URDF with `<collision>` shapes (the first, the wrist column, is a cylinder).
pub const LINKS: [&str; 4] = [
    "afma6_wrist_1",
    "afma6_wrist_2",
    "afma6_end_effector",
    "afma6_camera",
];

pub fn obstacles() -> Vec<Obstacle> {
    vec![
        Obstacle::new(
            "ball",
            Geometry::Sphere { radius_m: 0.04 },
            Isometry3::translation(0.03, 0.2, 0.05),
        )
        .unwrap(),
        Obstacle::new(
            "crate",
            Geometry::Box {
                size_m: [0.1, 0.1, 0.1],
            },
            Isometry3::new(Vector3::new(-0.07, 0.1, -0.12), Vector3::new(0.1, 0.2, 0.3)),
        )
        .unwrap(),
        Obstacle::new(
            "post",
            Geometry::Cylinder {
                radius_m: 0.03,
                length_m: 0.4,
            },
            // Tilted: parallel to the wrist column, the contact would be a segment, where GJK's normal converges
            // slowly (and the witness points are not unique).
            Isometry3::new(Vector3::new(-0.2, 0.0, 0.0), Vector3::new(0.4, 0.3, 0.0)),
        )
        .unwrap(),
    ]
}

/// The obstacle cost of every (link, obstacle) pair with influence distance `influence` (m).
pub fn obstacle_cost(influence: f64) -> ObstacleCost<6> {
    obstacle_cost_of(influence, true)
}

/// As [`obstacle_cost`]; without cylinders (the wrist column and the post) when `cylinders` is false. parry's GJK
/// terminates exactly on polytopes, segments (capsules) and points (spheres), but only converges on a cylinder's
/// curved side: there its normal, hence the gradient, is accurate to ~1e−3.
pub fn obstacle_cost_of(influence: f64, cylinders: bool) -> ObstacleCost<6> {
    let robot = builtin::afma6().unwrap();
    let links = LinkColliders::from_urdf_str(builtin::AFMA6_URDF, &robot.chain).unwrap();
    let obstacles: Vec<Obstacle> = obstacles()
        .into_iter()
        .filter(|o| cylinders || o.name() != "post")
        .collect();
    let pairs: Vec<ObstaclePair> = LINKS[if cylinders { 0 } else { 1 }..]
        .iter()
        .flat_map(|link| {
            obstacles.iter().map(move |o| ObstaclePair {
                link: (*link).to_owned(),
                obstacle: o.name().to_owned(),
                influence_distance: influence,
            })
        })
        .collect();
    ObstacleCost::new(robot.chain, &links, obstacles, &pairs).unwrap()
}
