//! Test helpers: a planar target seen by a camera, projection, real camera motion and finite differences.

use super::{Feature, InteractionSource, Observation};
use crate::camera::ImagePoint;
use crate::target::TargetPlane;
use nalgebra::{
    Dim, Dyn, Isometry3, Matrix, OMatrix, Point3, RawStorage, Translation3, UnitQuaternion,
    Vector3, Vector6, U6,
};
use proptest::prelude::*;

/// Interaction matrix storage used by the tests.
pub type Rows = OMatrix<f64, Dyn, U6>;

/// The corners of a `w × h` rectangle in the plane z = 0 of the object frame, numbered around it (the order of the [peer scene](crate::theory::peer_scene#scene)).
pub fn rectangle(w: f64, h: f64) -> Vec<Point3<f64>> {
    let (a, b) = (w / 2.0, h / 2.0);
    vec![
        Point3::new(-a, -b, 0.0),
        Point3::new(a, -b, 0.0),
        Point3::new(a, b, 0.0),
        Point3::new(-a, b, 0.0),
    ]
}

/// Hand-written image of a centred fronto-parallel `w × h` rectangle at depth `z`.
pub fn rectangle_points_fronto(w: f64, h: f64, z: f64) -> [ImagePoint; 4] {
    let (a, b) = (w / (2.0 * z), h / (2.0 * z));
    [(-a, -b), (a, -b), (a, b), (-a, b)].map(|(x, y)| ImagePoint::new(x, y, z))
}

/// Pose of the object in the camera frame: object origin at `(tx, ty, z)`, object rotated by the roll-pitch-yaw
/// angles `(rx, ry, rz)` (rx, ry tilt the target plane, rz turns it in its plane).
pub fn pose(tx: f64, ty: f64, z: f64, rx: f64, ry: f64, rz: f64) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(tx, ty, z),
        UnitQuaternion::from_euler_angles(rx, ry, rz),
    )
}

/// Random poses of a target about 0.8 m ahead, tilted by up to 0.5 rad, any in-plane rotation.
pub fn tilted_pose_strategy() -> impl Strategy<Value = Isometry3<f64>> {
    tilted_pose_strategy_yaw(-3.1..3.1)
}

/// As [`tilted_pose_strategy`], with the in-plane rotation drawn from `yaw`.
pub fn tilted_pose_strategy_yaw(
    yaw: std::ops::Range<f64>,
) -> impl Strategy<Value = Isometry3<f64>> {
    (-0.1..0.1f64, -0.1..0.1f64, 0.6..1.0f64, tilt(), tilt(), yaw)
        .prop_map(|(tx, ty, z, rx, ry, rz)| pose(tx, ty, z, rx, ry, rz))
}

/// A tilt angle of magnitude 0.15..0.5 rad, either sign (so that the target is never near fronto-parallel).
fn tilt() -> impl Strategy<Value = f64> {
    (0.15..0.5f64, any::<bool>()).prop_map(|(t, negative)| if negative { -t } else { t })
}

/// A planar target (object-frame points in z = 0) seen from a camera pose.
#[derive(Debug, Clone)]
pub struct Scene {
    /// Object pose in the camera frame.
    pub c_from_o: Isometry3<f64>,
    /// Object points (object frame, z = 0).
    pub object: Vec<Point3<f64>>,
}

impl Scene {
    /// A scene.
    pub fn new(c_from_o: Isometry3<f64>, object: Vec<Point3<f64>>) -> Self {
        Self { c_from_o, object }
    }

    /// Projection of the object points and the plane `1/Z = A x + B y + C` = n/d in the camera frame.
    pub fn image(&self) -> (Vec<ImagePoint>, TargetPlane) {
        let points = self
            .object
            .iter()
            .map(|p| {
                let pc = self.c_from_o * p;
                ImagePoint::new(pc.x / pc.z, pc.y / pc.z, pc.z)
            })
            .collect();
        let n = self.c_from_o.rotation * Vector3::z();
        let d = n.dot(&self.c_from_o.translation.vector);
        let plane = TargetPlane {
            a: n.x / d,
            b: n.y / d,
            c: n.z / d,
        };
        (points, plane)
    }

    /// The scene after the camera moved by the twist `twist · h` (camera frame): points move as `Ẋ = −υ − ω × X`.
    pub fn moved(&self, twist: &Vector6<f64>, h: f64) -> Self {
        let motion = Isometry3::new(
            twist.fixed_rows::<3>(0).into_owned() * h,
            twist.fixed_rows::<3>(3).into_owned() * h,
        );
        Self::new(motion.inverse() * self.c_from_o, self.object.clone())
    }

    /// The feature value.
    pub fn value<F: Feature + ?Sized>(&self, f: &F, use_plane: bool) -> Vec<f64> {
        let (pts, plane) = self.image();
        let obs = Observation::new(&pts, use_plane.then_some(&plane)).unwrap();
        let mut s = vec![0.0; f.dim()];
        f.value(&obs, &mut s).unwrap();
        s
    }

    /// The feature's interaction matrix for `source`, evaluated on this scene.
    pub fn interaction<F: Feature + ?Sized>(
        &self,
        f: &F,
        source: InteractionSource,
        use_plane: bool,
    ) -> Rows {
        let (pts, plane) = self.image();
        let obs = Observation::new(&pts, use_plane.then_some(&plane)).unwrap();
        let mut l = Rows::zeros(f.dim());
        f.interaction(&obs, source, l.rows_mut(0, f.dim())).unwrap();
        l
    }

    /// Central finite differences of the feature under real camera motion (angle rows through `Feature::error`).
    pub fn finite_difference<F: Feature + ?Sized>(&self, f: &F) -> Rows {
        let h = 1e-5;
        let mut l = Rows::zeros(f.dim());
        let mut e = vec![0.0; f.dim()];
        for j in 0..6 {
            let twist = Vector6::from_fn(|i, _| if i == j { 1.0 } else { 0.0 });
            let plus = self.moved(&twist, h).value(f, false);
            let minus = self.moved(&twist, -h).value(f, false);
            f.error(&plus, &minus, &mut e).unwrap();
            for (r, e) in e.iter().enumerate() {
                l[(r, j)] = e / (2.0 * h);
            }
        }
        l
    }

    /// Asserts that the exact (and `Desired`, evaluated here) interaction matrix matches finite differences of real
    /// camera motion to 1e−6 relative to its largest entry.
    pub fn check_exact<F: Feature + ?Sized>(&self, f: &F, use_plane: bool) {
        let fd = self.finite_difference(f);
        for source in [InteractionSource::Exact, InteractionSource::Desired] {
            let l = self.interaction(f, source, use_plane);
            assert_close(&l, &fd, 1e-6);
        }
    }
}

/// Asserts `max |a − b| ≤ rel · max |b|` (same shape, `max |b| > 0`).
pub fn assert_close<R: Dim, C: Dim, S1: RawStorage<f64, R, C>, S2: RawStorage<f64, R, C>>(
    a: &Matrix<f64, R, C, S1>,
    b: &Matrix<f64, R, C, S2>,
    rel: f64,
) {
    assert_eq!(a.shape(), b.shape());
    let scale = b.amax();
    assert!(scale > 0.0, "reference is zero");
    let err = a
        .iter()
        .zip(b.iter())
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max);
    assert!(
        err <= rel * scale,
        "error {err:e} > {rel:e} · {scale:e}\n{a}\n{b}"
    );
}
