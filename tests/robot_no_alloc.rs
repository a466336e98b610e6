//! The kinematic evaluation, the camera pose and Jacobian, projection and point Jacobians allocate nothing.

use nalgebra::{Point3, SMatrix};
use servostack::camera::{project_points, ImagePoint};
use servostack::math::JointVector;
use servostack::robot::{builtin, KinematicsWorkspace};
use servostack::target::RectangleTarget;
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

// SAFETY: forwards to the system allocator, only counting calls.
#[allow(unsafe_code)]
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::SeqCst);
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn kinematics_camera_and_projection_do_not_allocate() {
    let robot = builtin::rail7().unwrap();
    let target = RectangleTarget::new(0.2, 0.1).unwrap();
    let mut ws = KinematicsWorkspace::new();
    let mut image = [ImagePoint::default(); 4];
    let mut point_jacobian = SMatrix::<f64, 3, 7>::zeros();
    let link = robot.chain.link("rail7_cover").unwrap().clone();
    let before = ALLOCATIONS.load(Ordering::SeqCst);
    let mut depth_sum = 0.0;
    for k in 0..100 {
        let q = JointVector::<7>::from_element(0.01 * k as f64);
        let state = robot.chain.kinematics(&mut ws, &q).unwrap();
        let base_from_camera = robot.camera.base_from_camera(state.base_from_tip());
        let camera_jacobian = robot.camera.camera_jacobian(state.tip_jacobian());
        state
            .point_jacobian(&link, &Point3::new(0.1, 0.2, 0.3), &mut point_jacobian)
            .unwrap();
        // The target 0.5 m in front of the camera.
        let c_from_o = nalgebra::Isometry3::translation(0.0, 0.0, 0.5);
        project_points(&c_from_o, target.points(), &mut image).unwrap();
        depth_sum += image[0].depth + camera_jacobian[(0, 0)] + base_from_camera.translation.x;
    }
    let after = ALLOCATIONS.load(Ordering::SeqCst);
    assert!(depth_sum.is_finite());
    assert_eq!(after - before, 0);
}
