//! Pinhole camera, projection, eye-in-hand mount and the rectangle target's plane, against hand computations.

use approx::assert_relative_eq;
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use proptest::prelude::*;
use servostack::camera::{
    project_point, project_points, CameraError, CameraIntrinsics, EyeInHand, ImagePoint, MIN_DEPTH,
};
use servostack::target::{RectangleTarget, TargetError, TargetPlane};
use std::f64::consts::FRAC_PI_2;

fn camera() -> CameraIntrinsics {
    CameraIntrinsics::new(800.0, 600.0, 320.0, 240.0, 640.0, 480.0).unwrap()
}

#[test]
fn intrinsics_are_validated() {
    let bad = [
        ([0.0, 600.0, 320.0, 240.0, 640.0, 480.0], "fx", 0.0),
        ([800.0, -1.0, 320.0, 240.0, 640.0, 480.0], "fy", -1.0),
        (
            [800.0, 600.0, f64::INFINITY, 240.0, 640.0, 480.0],
            "cx",
            f64::INFINITY,
        ),
        (
            [800.0, 600.0, 320.0, f64::NEG_INFINITY, 640.0, 480.0],
            "cy",
            f64::NEG_INFINITY,
        ),
        ([800.0, 600.0, 320.0, 240.0, 0.0, 480.0], "width", 0.0),
        // A focal length of 1e−300 px would scale every normalised coordinate by 1e300.
        ([1e-300, 600.0, 320.0, 240.0, 640.0, 480.0], "fx", 1e-300),
        ([800.0, 0.5, 320.0, 240.0, 640.0, 480.0], "fy", 0.5),
        ([800.0, 600.0, 320.0, 240.0, 640.0, 2e6], "height", 2e6),
        ([800.0, 600.0, -3e6, 240.0, 640.0, 480.0], "cx", -3e6),
        (
            [800.0, 600.0, 320.0, 240.0, 640.0, -480.0],
            "height",
            -480.0,
        ),
    ];
    for ([fx, fy, cx, cy, w, h], name, value) in bad {
        let expected = match name {
            "fx" | "fy" => servostack::bounds::FOCAL_LENGTH_PX.text,
            "cx" | "cy" => servostack::bounds::PRINCIPAL_POINT_PX.text,
            _ => servostack::bounds::IMAGE_SIZE_PX.text,
        };
        assert_eq!(
            CameraIntrinsics::new(fx, fy, cx, cy, w, h),
            Err(CameraError::InvalidIntrinsic {
                name,
                value,
                expected
            })
        );
    }
    // The ends of the ranges are admissible: a one-pixel focal length, a million-pixel image.
    assert!(CameraIntrinsics::new(1.0, 1e6, -1e6, 1e6, 1.0, 1e6).is_ok());
    let nan = CameraIntrinsics::new(f64::NAN, 600.0, 320.0, 240.0, 640.0, 480.0);
    assert!(
        matches!(nan, Err(CameraError::InvalidIntrinsic { name: "fx", value, .. }) if value.is_nan())
    );
}

#[test]
fn pixels_and_normalised_coordinates() {
    let cam = camera();
    // u = 320 + 800 · 0.1, v = 240 + 600 · (−0.2).
    assert_eq!(cam.normalized_to_pixel(0.1, -0.2), (400.0, 120.0));
    assert_eq!(cam.pixel_to_normalized(400.0, 120.0), (0.1, -0.2));
    assert_eq!(cam.pixel_to_normalized(320.0, 240.0), (0.0, 0.0));
}

#[test]
fn field_of_view_with_margin() {
    let cam = camera();
    // x = (u − 320)/800: u = 10 → x = −0.3875; u = 5 → x = −0.39375.
    let at_u = |u: f64| ImagePoint::new((u - 320.0) / 800.0, 0.0, 1.0);
    assert!(cam.in_field_of_view(&at_u(10.0), 10.0));
    assert!(!cam.in_field_of_view(&at_u(5.0), 10.0));
    assert!(cam.in_field_of_view(&at_u(5.0), 0.0));
    assert!(!cam.in_field_of_view(&at_u(640.5), 0.0));
    // v = 240 + 600 y: y = 0.39 → v = 474, outside a 10 px margin (limit 470).
    assert!(!cam.in_field_of_view(&ImagePoint::new(0.0, 0.39, 1.0), 10.0));
    assert!(!cam.in_field_of_view(&ImagePoint::new(0.0, 0.0, -1.0), 0.0));
    assert!(!cam.in_field_of_view(&ImagePoint::new(f64::NAN, 0.0, 1.0), 0.0));
    let points = [at_u(100.0), at_u(600.0)];
    assert!(cam.all_in_field_of_view(&points, 20.0));
    assert!(!cam.all_in_field_of_view(&points, 50.0));
}

/// The peer scene (docs/peer_scene.md): the 0.2 × 0.1 m rectangle, fronto-parallel at 0.5 m, is seen at (±0.2, ±0.1), plane (0, 0, 2).
#[test]
fn peer_scene_desired_image() {
    let target = RectangleTarget::new(0.2, 0.1).unwrap();
    let expected_points = [(-0.1, -0.05), (0.1, -0.05), (0.1, 0.05), (-0.1, 0.05)];
    for (p, (x, y)) in target.points().iter().zip(expected_points) {
        assert_eq!(*p, Point3::new(x, y, 0.0));
    }
    let c_from_o = Isometry3::translation(0.0, 0.0, 0.5);
    let mut image = [ImagePoint::default(); 4];
    project_points(&c_from_o, target.points(), &mut image).unwrap();
    let expected = [(-0.2, -0.1), (0.2, -0.1), (0.2, 0.1), (-0.2, 0.1)];
    for (p, (x, y)) in image.iter().zip(expected) {
        assert_relative_eq!(p.x, x, epsilon = 1e-15);
        assert_relative_eq!(p.y, y, epsilon = 1e-15);
        assert_eq!(p.depth, 0.5);
    }
    assert_eq!(
        target.plane_in_camera(&c_from_o).unwrap(),
        TargetPlane {
            a: 0.0,
            b: 0.0,
            c: 2.0
        }
    );
}

/// A rotated, shifted target: Rz(90°), t = (0.1, 0, 1). P1 = (0.1, −0.05, 0) → (0.05, 0.1, 0) + t = (0.15, 0.1, 1).
#[test]
fn projection_matches_a_hand_computation() {
    let target = RectangleTarget::new(0.2, 0.1).unwrap();
    let c_from_o = Isometry3::from_parts(
        Translation3::new(0.1, 0.0, 1.0),
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), FRAC_PI_2),
    );
    let mut image = [ImagePoint::default(); 4];
    project_points(&c_from_o, target.points(), &mut image).unwrap();
    assert_relative_eq!(image[1].x, 0.15, epsilon = 1e-15);
    assert_relative_eq!(image[1].y, 0.1, epsilon = 1e-15);
    assert_relative_eq!(image[1].depth, 1.0, epsilon = 1e-15);
    // A point in the camera frame directly: (0.3, −0.6, 2) → (0.15, −0.3, 2).
    assert_eq!(
        project_point(&Point3::new(0.3, -0.6, 2.0)).unwrap(),
        ImagePoint::new(0.15, -0.3, 2.0)
    );
}

/// A target tilted by θ about y at 1 m: n = (sin θ, 0, cos θ), d = cos θ, so (A, B, C) = (tan θ, 0, 1).
#[test]
fn tilted_plane_matches_a_hand_computation() {
    let theta: f64 = 0.3;
    let c_from_o = Isometry3::from_parts(
        Translation3::new(0.0, 0.0, 1.0),
        UnitQuaternion::from_axis_angle(&Vector3::y_axis(), theta),
    );
    let plane = TargetPlane::from_object_pose(&c_from_o).unwrap();
    assert_relative_eq!(plane.a, theta.tan(), epsilon = 1e-15);
    assert_relative_eq!(plane.b, 0.0, epsilon = 1e-15);
    assert_relative_eq!(plane.c, 1.0, epsilon = 1e-15);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// The plane (A, B, C) gives back 1/Z of every projected point of the target, for random poses in front.
    #[test]
    fn plane_reproduces_the_inverse_depth_of_each_point(
        r in proptest::collection::vec(-0.6..0.6f64, 3),
        t in proptest::collection::vec(-0.2..0.2f64, 2),
        z in 0.3..2.0f64,
    ) {
        let target = RectangleTarget::new(0.2, 0.1).unwrap();
        let c_from_o = Isometry3::new(Vector3::new(t[0], t[1], z), Vector3::new(r[0], r[1], r[2]));
        let mut image = [ImagePoint::default(); 4];
        project_points(&c_from_o, target.points(), &mut image).unwrap();
        let plane = target.plane_in_camera(&c_from_o).unwrap();
        for p in &image {
            prop_assert!((plane.inverse_depth(p.x, p.y) * p.depth - 1.0).abs() < 1e-12);
        }
    }
}

#[test]
fn points_at_or_behind_the_camera_are_rejected() {
    let target = RectangleTarget::new(0.2, 0.1).unwrap();
    let mut image = [ImagePoint::default(); 4];
    let behind = Isometry3::translation(0.0, 0.0, -0.5);
    assert_eq!(
        project_points(&behind, target.points(), &mut image),
        Err(CameraError::PointBehindCamera {
            index: 0,
            depth: -0.5
        })
    );
    // Tilted so that points 1 and 2 (x = +0.1) sit exactly in the plane Z = 0 of the camera.
    let edge = Isometry3::from_parts(
        Translation3::new(0.0, 0.0, 0.1),
        UnitQuaternion::from_axis_angle(&Vector3::y_axis(), FRAC_PI_2),
    );
    match project_points(&edge, target.points(), &mut image) {
        Err(CameraError::PointBehindCamera { index: 1, depth }) => assert!(depth.abs() < 1e-15),
        other => panic!("{other:?}"),
    }
    assert_eq!(
        project_point(&Point3::new(0.0, 0.0, MIN_DEPTH)),
        Err(CameraError::PointBehindCamera {
            index: 0,
            depth: MIN_DEPTH
        })
    );
    assert!(project_point(&Point3::new(0.0, 0.0, 2.0 * MIN_DEPTH)).is_ok());
}

#[test]
fn projection_input_errors() {
    let target = RectangleTarget::new(0.2, 0.1).unwrap();
    let mut three = [ImagePoint::default(); 3];
    let pose = Isometry3::translation(0.0, 0.0, 1.0);
    assert_eq!(
        project_points(&pose, target.points(), &mut three),
        Err(CameraError::LengthMismatch {
            points: 4,
            outputs: 3
        })
    );
    let mut four = [ImagePoint::default(); 4];
    let nan_pose = Isometry3::translation(0.0, f64::NAN, 1.0);
    assert!(matches!(
        project_points(&nan_pose, target.points(), &mut four),
        Err(CameraError::NonFinite { .. })
    ));
    let points = [
        Point3::new(0.0, 0.0, 0.0),
        Point3::new(f64::INFINITY, 0.0, 0.0),
    ];
    assert_eq!(
        project_points(&pose, &points, &mut four[..2]),
        Err(CameraError::NonFinite {
            what: "point 1".into()
        })
    );
}

#[test]
fn degenerate_targets_and_planes() {
    for (w, h) in [(0.0, 0.1), (0.2, -0.1), (f64::INFINITY, 0.1)] {
        assert_eq!(
            RectangleTarget::new(w, h),
            Err(TargetError::DegenerateRectangle {
                width: w,
                height: h
            })
        );
    }
    assert!(matches!(
        RectangleTarget::new(0.2, f64::NAN),
        Err(TargetError::DegenerateRectangle { .. })
    ));
    // The object plane z = 0 seen edge-on: rotated 90° about x, 1 m ahead. The plane is y = 0 in the camera frame.
    let edge_on = Isometry3::from_parts(
        Translation3::new(0.0, 0.0, 1.0),
        UnitQuaternion::from_axis_angle(&Vector3::x_axis(), FRAC_PI_2),
    );
    match TargetPlane::from_object_pose(&edge_on) {
        Err(TargetError::PlaneThroughCentre { distance }) => assert!(distance.abs() < 1e-15),
        other => panic!("{other:?}"),
    }
    let nan_pose = Isometry3::translation(f64::NAN, 0.0, 1.0);
    assert_eq!(
        TargetPlane::from_object_pose(&nan_pose),
        Err(TargetError::NonFinitePose)
    );
}

#[test]
fn eye_in_hand_mount() {
    let e_from_c = Isometry3::new(Vector3::new(0.0, -0.06, 0.03), Vector3::new(0.0, 0.0, 0.4));
    let mount = EyeInHand::new(e_from_c).unwrap();
    let base_from_tip = Isometry3::new(Vector3::new(0.5, 0.2, 0.7), Vector3::new(0.1, -0.2, 0.3));
    // The camera origin in the base frame is the tip pose applied to the mount translation.
    let origin = mount.base_from_camera(&base_from_tip) * Point3::origin();
    assert_relative_eq!(
        origin,
        base_from_tip * Point3::new(0.0, -0.06, 0.03),
        epsilon = 1e-15
    );
    let bad = Isometry3::translation(0.0, f64::NAN, 0.0);
    assert_eq!(
        EyeInHand::new(bad),
        Err(CameraError::NonFinite {
            what: "e_from_c".into()
        })
    );
}

/// A scene on the Afma6 whose camera sees the target at `desired` (ViSP `cdMo`) at the reference configuration.
fn scene_seen_from(desired: &Isometry3<f64>) -> servostack::sim::Scene<6> {
    let robot = servostack::robot::builtin::afma6().unwrap();
    servostack::sim::Scene::with_target_seen_from(
        robot.chain,
        robot.mount,
        camera(),
        RectangleTarget::new(0.2, 0.1).unwrap(),
        &crate::obstacle_fixture::reference_q(),
        desired,
        0.1,
    )
    .unwrap()
}

proptest! {
    /// D27: the incidence is the angle between the target's front normal and the line from its centre to the optical
    /// centre, whatever the camera's orientation. A camera placed at polar angle θ from the front normal (azimuth φ,
    /// distance d), turned any way, sees the target at θ; with the goal on the other side of the plane, the front is
    /// that side, and the same camera sees it at 180° − θ.
    #[test]
    fn incidence_is_the_polar_angle_from_the_front_normal(
        theta_deg in 0.0..180.0f64,
        phi in -3.1..3.1f64,
        distance in 0.05..3.0f64,
        roll in -3.1..3.1f64,
        pitch in -1.5..1.5f64,
        yaw in -3.1..3.1f64,
    ) {
        let theta = theta_deg.to_radians();
        // The goal camera looks along +z of the target frame from z = −0.5: the front normal is −z.
        let front = scene_seen_from(&Isometry3::translation(0.0, 0.0, 0.5));
        // Turned half a turn about x, it looks along −z from z = +0.5: the front normal is +z.
        let back = scene_seen_from(&Isometry3::from_parts(
            Translation3::new(0.0, 0.0, 0.5),
            UnitQuaternion::from_euler_angles(std::f64::consts::PI, 0.0, 0.0),
        ));
        let position = Vector3::new(
            theta.sin() * phi.cos(),
            theta.sin() * phi.sin(),
            -theta.cos(),
        ) * distance;
        let o_from_c = Isometry3::from_parts(
            Translation3::from(position),
            UnitQuaternion::from_euler_angles(roll, pitch, yaw),
        );
        let c_from_o = o_from_c.inverse();
        prop_assert!((front.target_incidence_deg(&c_from_o) - theta_deg).abs() < 1e-6);
        prop_assert!((back.target_incidence_deg(&c_from_o) - (180.0 - theta_deg)).abs() < 1e-6);
    }
}

/// D27: at the goal pose of any scene the target is seen at its goal incidence (0 head-on, 20° for a camera turned
/// 20° about the target's centre), and a camera on the target's centre is in its plane (90°).
#[test]
fn goal_incidence_and_the_degenerate_camera() {
    let head_on = Isometry3::translation(0.0, 0.0, 0.5);
    assert!(
        scene_seen_from(&head_on)
            .target_incidence_deg(&head_on)
            .abs()
            < 1e-9
    );
    // The camera 0.5 m from the centre, 20° off the normal about the target's y axis, looking at it.
    let o_from_c = Isometry3::from_parts(
        Translation3::new(
            0.5 * 20f64.to_radians().sin(),
            0.0,
            -0.5 * 20f64.to_radians().cos(),
        ),
        UnitQuaternion::from_euler_angles(0.0, -20f64.to_radians(), 0.0),
    );
    let turned = o_from_c.inverse();
    // The target's centre is on the optical axis of the turned camera.
    let centre = turned.transform_point(&Point3::origin());
    assert!(centre.x.abs() < 1e-12 && centre.y.abs() < 1e-12 && centre.z > 0.0);
    let scene = scene_seen_from(&turned);
    assert!((scene.target_incidence_deg(&turned) - 20.0).abs() < 1e-9);
    assert_eq!(scene.target_incidence_deg(&Isometry3::identity()), 90.0);
}
