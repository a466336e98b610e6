//! URDF mesh files for collision geometry ([D20](crate::theory#d20)): where a `<mesh filename>` leads, and its
//! vertices.
//!
//! A mesh is read once, when the link shapes are built ([`super::LinkColliders`]); the obstacle cost then works on
//! the convex hull of its vertices ([`super::Geometry::ConvexHull`]). Formats, told apart by the file extension (any
//! case), read by the crate `mesh-loader`: STL, binary and ASCII (a binary file whose header starts with `solid`, as
//! many exporters write, included), Wavefront OBJ, and COLLADA (`.dae`, its `<unit>` and node transforms applied).
//! Vertices are in the file's unit, scaled by the URDF `scale` per axis to metres (URDF meshes are in metres unless
//! scaled).

use super::CostError;
use nalgebra::Vector3;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Where the mesh files a URDF names are found.
///
/// * `package://NAME/REST`: `DIR/REST` for the directory `DIR` given for `NAME` by [`MeshPaths::with_package`]; else
///   the first entry `E` of `ROS_PACKAGE_PATH` (`:`-separated) with a directory `E/NAME`, or named `NAME` itself;
/// * `file:///ABSOLUTE`: that path;
/// * any other path: as is when absolute, else relative to the URDF's directory ([`MeshPaths::new`]).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct MeshPaths {
    urdf_dir: PathBuf,
    packages: BTreeMap<String, PathBuf>,
    ros_package_path: Vec<PathBuf>,
}

impl MeshPaths {
    /// Paths relative to `urdf_dir` (the directory of the URDF file), and the package directories of the
    /// `ROS_PACKAGE_PATH` environment variable when it is set.
    pub fn new(urdf_dir: impl Into<PathBuf>) -> Self {
        let ros = std::env::var("ROS_PACKAGE_PATH").ok();
        Self {
            urdf_dir: urdf_dir.into(),
            packages: BTreeMap::new(),
            ros_package_path: Vec::new(),
        }
        .with_ros_package_path(ros.as_deref())
    }

    /// The same, with `package://name/…` leading into `dir` (searched before `ROS_PACKAGE_PATH`).
    pub fn with_package(mut self, name: impl Into<String>, dir: impl Into<PathBuf>) -> Self {
        self.packages.insert(name.into(), dir.into());
        self
    }

    /// The same, with this `ROS_PACKAGE_PATH` value (`:`-separated directories) in place of the environment's, or
    /// none.
    pub fn with_ros_package_path(mut self, value: Option<&str>) -> Self {
        self.ros_package_path = value
            .into_iter()
            .flat_map(std::env::split_paths)
            .filter(|p| !p.as_os_str().is_empty())
            .collect();
        self
    }

    /// The file a URDF mesh `filename` of `link` leads to.
    ///
    /// # Errors
    /// [`CostError::UnknownPackage`] for a `package://` URI whose package is neither given nor on
    /// `ROS_PACKAGE_PATH`.
    pub fn resolve(&self, link: &str, filename: &str) -> Result<PathBuf, CostError> {
        if let Some(rest) = filename.strip_prefix("package://") {
            let (package, relative) = rest.split_once('/').unwrap_or((rest, ""));
            let from_ros = || {
                self.ros_package_path.iter().find_map(|entry| {
                    let inside = entry.join(package);
                    if inside.is_dir() {
                        Some(inside)
                    } else {
                        (entry.file_name() == Some(package.as_ref()) && entry.is_dir())
                            .then(|| entry.clone())
                    }
                })
            };
            let dir = self
                .packages
                .get(package)
                .cloned()
                .or_else(from_ros)
                .ok_or_else(|| CostError::UnknownPackage {
                    link: link.to_owned(),
                    filename: filename.to_owned(),
                    package: package.to_owned(),
                })?;
            return Ok(dir.join(relative));
        }
        let path = Path::new(filename.strip_prefix("file://").unwrap_or(filename));
        Ok(self.urdf_dir.join(path)) // `join` keeps an absolute `path` as it is
    }
}

/// The vertices of the mesh file of `link` at `path`, each scaled per axis by `scale` (m).
///
/// # Errors
/// [`CostError::MeshFile`] when the file cannot be read, [`CostError::MalformedMesh`] when it is not a valid STL or
/// OBJ or COLLADA file or holds no vertex, [`CostError::UnsupportedGeometry`] for another extension.
pub(crate) fn read_vertices(
    link: &str,
    path: &Path,
    scale: Vector3<f64>,
) -> Result<Vec<Vector3<f64>>, CostError> {
    let extension = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let file = || path.display().to_string();
    let loader = mesh_loader::Loader::default();
    let load = match extension.as_deref() {
        Some("stl") => mesh_loader::Loader::load_stl_from_slice,
        Some("obj") => mesh_loader::Loader::load_obj_from_slice,
        Some("dae") => mesh_loader::Loader::load_collada_from_slice,
        _ => {
            return Err(CostError::UnsupportedGeometry {
                link: link.to_owned(),
                geometry: format!("mesh {:?} (mesh formats: .stl, .obj, .dae)", file()),
            })
        }
    };
    let bytes = std::fs::read(path).map_err(|e| CostError::MeshFile {
        link: link.to_owned(),
        file: file(),
        message: e.to_string(),
    })?;
    let malformed = |message: String| CostError::MalformedMesh {
        link: link.to_owned(),
        file: file(),
        message,
    };
    // Materials an OBJ file names are not geometry: mesh-loader skips those it cannot read.
    let scene = load(&loader, &bytes, path).map_err(|e| malformed(e.to_string()))?;
    let vertices: Vec<[f32; 3]> = scene
        .meshes
        .into_iter()
        .flat_map(|mesh| mesh.vertices)
        .collect();
    if vertices.is_empty() {
        return Err(malformed("no vertex".to_owned()));
    }
    if let Some(v) = vertices.iter().find(|v| !v.iter().all(|x| x.is_finite())) {
        return Err(malformed(format!("vertex {v:?} is not finite")));
    }
    Ok(vertices
        .iter()
        .map(|v| Vector3::new(v[0].into(), v[1].into(), v[2].into()).component_mul(&scale))
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn package_uris_resolve_through_the_map_then_ros_package_path() {
        let dir =
            std::env::temp_dir().join(format!("servostack-mesh-paths-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("ros/arm_description")).unwrap();
        let paths = MeshPaths::new("/robots/urdf")
            .with_ros_package_path(Some(dir.join("ros").to_str().unwrap()))
            .with_package("given", "/given/dir");
        assert_eq!(
            paths.resolve("l", "package://given/meshes/a.stl").unwrap(),
            PathBuf::from("/given/dir/meshes/a.stl")
        );
        assert_eq!(
            paths
                .resolve("l", "package://arm_description/m/b.stl")
                .unwrap(),
            dir.join("ros/arm_description/m/b.stl")
        );
        assert_eq!(
            paths.resolve("l", "meshes/c.obj").unwrap(),
            PathBuf::from("/robots/urdf/meshes/c.obj")
        );
        assert_eq!(
            paths.resolve("l", "file:///abs/d.stl").unwrap(),
            PathBuf::from("/abs/d.stl")
        );
        let err = paths
            .resolve("wrist", "package://nowhere/e.stl")
            .unwrap_err();
        assert_eq!(
            err,
            CostError::UnknownPackage {
                link: "wrist".into(),
                filename: "package://nowhere/e.stl".into(),
                package: "nowhere".into()
            }
        );
        assert!(err.to_string().contains("ROS_PACKAGE_PATH"), "{err}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
