//! The image loop's renderer and detector, checked by outcome: on random poses of the target (any roll) the detected
//! corners are those of the projected truth, in the target's order, within a pixel; a target out of the image, cut
//! by its edge or seen from behind is a bad frame, not a panic nor wrong corners.

#[path = "../detect.rs"]
mod detect;
#[path = "../render.rs"]
mod render;

use detect::{check_corners, tag36h11_cells, BadFrame, TagDetector};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use render::{GrayImage, Renderer, TagBoard};
use servostack::camera::{BrownConrady, CalibratedCamera, CameraIntrinsics};
use servostack::target::RectangleTarget;

/// The example's camera: the paper scene's intrinsics, `hardware_loop`'s lens.
fn camera() -> CalibratedCamera {
    CalibratedCamera {
        intrinsics: CameraIntrinsics::new(600.0, 600.0, 320.0, 240.0, 640.0, 480.0).unwrap(),
        distortion: BrownConrady::from_coefficients(&[-0.12, 0.03, 4e-4, -3e-4, 0.0]).unwrap(),
    }
}

struct Pipeline {
    camera: CalibratedCamera,
    target: RectangleTarget,
    board: TagBoard,
    renderer: Renderer,
    detector: TagDetector,
    image: GrayImage,
}

impl Pipeline {
    fn new() -> Self {
        let (camera, target) = (camera(), RectangleTarget::new(0.2, 0.1).unwrap());
        let (cells, white) = tag36h11_cells(0).unwrap();
        // Two samples per pixel along each axis (the example takes three): a quicker start, the same checks.
        let renderer = Renderer::new(&camera, 2, 2.0, 11);
        let (width, height) = renderer.size();
        Self {
            camera,
            target,
            board: TagBoard::new(&target, cells, white, 2.0),
            renderer,
            detector: TagDetector::new(width, height, 0).unwrap(),
            image: GrayImage::new(width, height),
        }
    }

    fn detect(&mut self, c_from_o: &Isometry3<f64>) -> Result<[(f64, f64); 4], BadFrame> {
        self.renderer.render(&self.board, c_from_o, &mut self.image);
        self.detector.detect(&self.image)
    }

    /// The projected truth (px) and its smallest distance to the image's edge.
    fn truth(&self, c_from_o: &Isometry3<f64>) -> ([(f64, f64); 4], f64) {
        let corners = self.target.points().map(|p| {
            let p = c_from_o * p;
            self.camera.pixel_of(p.x / p.z, p.y / p.z)
        });
        let margin = corners
            .iter()
            .map(|&(u, v)| u.min(v).min(639.0 - u).min(479.0 - v))
            .fold(f64::INFINITY, f64::min);
        (corners, margin)
    }
}

/// A pose of the target `depth` m ahead, tilted by `tilt` (rad) about x and y, rolled by `roll` about the optical
/// axis, shifted by `(dx, dy)` m.
fn pose(depth: f64, tilt: (f64, f64), roll: f64, shift: (f64, f64)) -> Isometry3<f64> {
    let rotation = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), roll)
        * UnitQuaternion::from_euler_angles(tilt.0, tilt.1, 0.0);
    Isometry3::from_parts(Translation3::new(shift.0, shift.1, depth), rotation)
}

#[test]
fn corners_of_random_poses_match_the_projected_truth_in_order() {
    let mut pipeline = Pipeline::new();
    let mut rng = StdRng::seed_from_u64(47);
    let (mut checked, mut worst) = (0, 0.0_f64);
    while checked < 8 {
        let c_from_o = pose(
            rng.random_range(0.35..0.8),
            (rng.random_range(-0.5..0.5), rng.random_range(-0.5..0.5)),
            rng.random_range(-std::f64::consts::PI..std::f64::consts::PI),
            (rng.random_range(-0.08..0.08), rng.random_range(-0.06..0.06)),
        );
        let (truth, margin) = pipeline.truth(&c_from_o);
        if margin < 10.0 {
            continue; // a draw that does not show the whole tag with room around it
        }
        let corners = pipeline
            .detect(&c_from_o)
            .unwrap_or_else(|bad| panic!("{bad} at {c_from_o:?}"));
        for (k, (c, t)) in corners.iter().zip(&truth).enumerate() {
            let error = (c.0 - t.0).hypot(c.1 - t.1);
            assert!(error < 1.0, "corner {k}: {error:.3} px off at {c_from_o:?}");
            worst = worst.max(error);
        }
        checked += 1;
    }
    println!("largest corner error over {checked} poses: {worst:.3} px");
}

#[test]
fn a_target_out_of_the_image_cut_by_its_edge_or_seen_from_behind_is_a_bad_frame() {
    let mut pipeline = Pipeline::new();
    // Out of the image: the target 0.5 m to the side.
    let aside = pose(0.5, (0.0, 0.0), 0.0, (0.5, 0.0));
    assert_eq!(pipeline.detect(&aside), Err(BadFrame::Lost));
    // Cut by the image's right edge: the tag's right half beyond it.
    let cut = pose(0.5, (0.0, 0.0), 0.0, (0.27, 0.0));
    assert!(pipeline.truth(&cut).1 < 0.0, "the pose must cut the tag");
    let result = pipeline.detect(&cut);
    assert!(
        matches!(result, Err(BadFrame::Lost | BadFrame::PartlyOutside { .. })),
        "{result:?}"
    );
    // Seen from behind: the board's back, no tag.
    let behind = pose(0.5, (0.0, std::f64::consts::PI), 0.0, (0.0, 0.0));
    assert_eq!(pipeline.detect(&behind), Err(BadFrame::Lost));
}

#[test]
fn corners_in_the_wrong_order_or_at_the_edge_are_refused() {
    let front = [
        (100.0, 100.0),
        (300.0, 110.0),
        (290.0, 200.0),
        (110.0, 190.0),
    ];
    assert_eq!(check_corners(&front, 640.0, 480.0), Ok(()));
    // Mirrored (the order reversed) and crossed (two corners swapped).
    let mirrored = [front[0], front[3], front[2], front[1]];
    assert_eq!(
        check_corners(&mirrored, 640.0, 480.0),
        Err(BadFrame::Flipped)
    );
    let crossed = [front[0], front[2], front[1], front[3]];
    assert_eq!(
        check_corners(&crossed, 640.0, 480.0),
        Err(BadFrame::Flipped)
    );
    let edge = [(1.0, 100.0), front[1], front[2], front[3]];
    assert!(matches!(
        check_corners(&edge, 640.0, 480.0),
        Err(BadFrame::PartlyOutside { corner: 0, .. })
    ));
}
