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
use crate::bounds::{read_capped, ReadFailure, LENGTH_M};
use crate::robot::first_too_deep;
use nalgebra::Vector3;
use std::collections::BTreeMap;
use std::path::{Component, Path, PathBuf};

/// The largest mesh file read by default (bytes): 64 MiB. The collision meshes of published arms are a few hundred
/// kilobytes, their finest visual meshes a few megabytes; a binary STL of 64 MiB holds 1.3 million triangles, and is
/// read with a peak memory of a few times its size. [`MeshPaths::with_max_file_bytes`] raises it.
pub const MAX_MESH_BYTES: usize = 64 << 20;

/// The deepest element nesting of a COLLADA file accepted: 256 levels. Exporters nest a scene's `<node>` elements as
/// deep as its transform hierarchy (a robot's links: tens); the COLLADA reader follows nodes recursively, and 2 000
/// levels overflow a thread's stack, which aborts the process. 256 levels are checked safe on a 2 MiB thread.
pub const MAX_COLLADA_DEPTH: usize = 256;

/// Where the mesh files a URDF names are found, and how large a file may be.
///
/// * `package://NAME/REST`: `DIR/REST` for the directory `DIR` given for `NAME` by [`MeshPaths::with_package`]; else
///   the first entry `E` of `ROS_PACKAGE_PATH` (`:`-separated) with a directory `E/NAME`, or named `NAME` itself.
///   `REST` must stay inside `DIR`: a `..` component or an absolute `REST` is [`CostError::PathOutsidePackage`]
///   unless [`MeshPaths::allowing_paths_outside_packages`] (the check is on the text of the path; a symbolic link
///   inside the package is followed as the file system says);
/// * `file:///ABSOLUTE`: that path;
/// * any other path: as is when absolute, else relative to the URDF's directory ([`MeshPaths::new`]), `..` included
///   (the URDF's author chose it).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MeshPaths {
    urdf_dir: PathBuf,
    packages: BTreeMap<String, PathBuf>,
    ros_package_path: Vec<PathBuf>,
    max_file_bytes: usize,
    outside_packages: bool,
}

impl Default for MeshPaths {
    /// Paths relative to the working directory, no package, at most [`MAX_MESH_BYTES`] per file.
    fn default() -> Self {
        Self {
            urdf_dir: PathBuf::new(),
            packages: BTreeMap::new(),
            ros_package_path: Vec::new(),
            max_file_bytes: MAX_MESH_BYTES,
            outside_packages: false,
        }
    }
}

impl MeshPaths {
    /// Paths relative to `urdf_dir` (the directory of the URDF file), and the package directories of the
    /// `ROS_PACKAGE_PATH` environment variable when it is set.
    pub fn new(urdf_dir: impl Into<PathBuf>) -> Self {
        let ros = std::env::var("ROS_PACKAGE_PATH").ok();
        Self {
            urdf_dir: urdf_dir.into(),
            ..Self::default()
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

    /// The same, reading mesh files of at most `bytes` bytes (default [`MAX_MESH_BYTES`]); a larger file is
    /// [`CostError::MeshTooLarge`], refused before it is read.
    pub fn with_max_file_bytes(mut self, bytes: usize) -> Self {
        self.max_file_bytes = bytes;
        self
    }

    /// The largest mesh file read (bytes).
    pub fn max_file_bytes(&self) -> usize {
        self.max_file_bytes
    }

    /// The same, letting `package://NAME/REST` lead outside the package's directory (`..` components, an absolute
    /// `REST`), for URDFs whose packages share files by relative paths.
    pub fn allowing_paths_outside_packages(mut self) -> Self {
        self.outside_packages = true;
        self
    }

    /// The file a URDF mesh `filename` of `link` leads to.
    ///
    /// # Errors
    /// [`CostError::UnknownPackage`] for a `package://` URI whose package is neither given nor on
    /// `ROS_PACKAGE_PATH`; [`CostError::PathOutsidePackage`] for one whose path leaves the package's directory.
    pub fn resolve(&self, link: &str, filename: &str) -> Result<PathBuf, CostError> {
        if let Some(rest) = filename.strip_prefix("package://") {
            let (package, relative) = rest.split_once('/').unwrap_or((rest, ""));
            let escapes = Path::new(relative)
                .components()
                .any(|c| !matches!(c, Component::Normal(_) | Component::CurDir));
            if escapes && !self.outside_packages {
                return Err(CostError::PathOutsidePackage {
                    link: link.to_owned(),
                    filename: filename.to_owned(),
                });
            }
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

/// The mesh file formats read, told apart by the file extension (any case).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum MeshFormat {
    /// `.stl`, binary or ASCII.
    Stl,
    /// `.obj`, Wavefront.
    Obj,
    /// `.dae`, COLLADA.
    Collada,
}

impl MeshFormat {
    /// The format of a file by its extension, `None` for another one.
    pub(crate) fn of_path(path: &Path) -> Option<Self> {
        match path.extension()?.to_str()?.to_ascii_lowercase().as_str() {
            "stl" => Some(Self::Stl),
            "obj" => Some(Self::Obj),
            "dae" => Some(Self::Collada),
            _ => None,
        }
    }
}

/// The vertices of the mesh file of `link` at `path`, each scaled per axis by `scale` (m); a file of more than
/// `max_bytes` bytes is refused before it is read.
///
/// # Errors
/// [`CostError::MeshFile`] when the file cannot be read, [`CostError::MeshTooLarge`],
/// [`CostError::MalformedMesh`] as [`mesh_vertices`] says, [`CostError::UnsupportedGeometry`] for another extension.
pub(crate) fn read_vertices(
    link: &str,
    path: &Path,
    scale: Vector3<f64>,
    max_bytes: usize,
) -> Result<Vec<Vector3<f64>>, CostError> {
    let file = || path.display().to_string();
    let format = MeshFormat::of_path(path).ok_or_else(|| CostError::UnsupportedGeometry {
        link: link.to_owned(),
        geometry: format!("mesh {:?} (mesh formats: .stl, .obj, .dae)", file()),
    })?;
    let bytes = read_capped(path, max_bytes).map_err(|failure| match failure {
        ReadFailure::Io(e) => CostError::MeshFile {
            link: link.to_owned(),
            file: file(),
            message: e.to_string(),
        },
        ReadFailure::TooLarge(bytes) => CostError::MeshTooLarge {
            link: link.to_owned(),
            file: file(),
            bytes,
            limit: max_bytes,
        },
    })?;
    scaled_vertices(link, &file(), format, &bytes, scale)
}

/// The vertices of a mesh file's `bytes` ([`mesh_vertices`]) scaled per axis by `scale` (m), each coordinate
/// within [`LENGTH_M`] (a vertex a kilometre away is a unit error, and its squares would overflow the distance
/// queries).
///
/// # Errors
/// [`CostError::MalformedMesh`] naming `link` and `file`.
pub(crate) fn scaled_vertices(
    link: &str,
    file: &str,
    format: MeshFormat,
    bytes: &[u8],
    scale: Vector3<f64>,
) -> Result<Vec<Vector3<f64>>, CostError> {
    let malformed = |message: String| CostError::MalformedMesh {
        link: link.to_owned(),
        file: file.to_owned(),
        message,
    };
    let vertices: Vec<Vector3<f64>> = mesh_vertices(format, bytes)
        .map_err(malformed)?
        .iter()
        .map(|v| v.component_mul(&scale))
        .collect();
    match vertices
        .iter()
        .find(|v| !LENGTH_M.contains_all(v.as_slice()))
    {
        Some(v) => Err(malformed(format!(
            "vertex ({}, {}, {}) m (scaled) is not {}",
            v.x, v.y, v.z, LENGTH_M.text
        ))),
        None => Ok(vertices),
    }
}

/// The vertices of a mesh file's `bytes` in `format`, in the file's unit.
///
/// # Errors
/// What is wrong, when the bytes are not a valid file of the format, hold no vertex or a non-finite one, or (COLLADA)
/// nest elements deeper than [`MAX_COLLADA_DEPTH`], checked before the parser sees them.
pub(crate) fn mesh_vertices(format: MeshFormat, bytes: &[u8]) -> Result<Vec<Vector3<f64>>, String> {
    let loader = mesh_loader::Loader::default();
    // The path only names the file in the reader's messages, and leads to the material files an OBJ file names:
    // materials are not geometry, and an empty path (no parent directory) makes the reader skip them, so an OBJ
    // file never makes the crate read another file.
    if format == MeshFormat::Collada {
        if let Some(line) = first_too_deep(bytes, MAX_COLLADA_DEPTH) {
            return Err(format!(
                "elements nested deeper than {MAX_COLLADA_DEPTH} levels at line {line}"
            ));
        }
    }
    // mesh-loader 0.1 panics on some malformed COLLADA files (an index out of bounds, a missing key: found by the
    // fuzz harness). Reading a mesh is no real-time step, so such a panic is caught here and named as a malformed file
    // (with `panic = "abort"` it would still abort).
    let read = std::panic::catch_unwind(|| match format {
        MeshFormat::Stl => loader.load_stl_from_slice(bytes, "mesh.stl"),
        MeshFormat::Obj => loader.load_obj_from_slice(bytes, ""),
        MeshFormat::Collada => loader.load_collada_from_slice(bytes, "mesh.dae"),
    });
    let scene = match read {
        Ok(scene) => scene.map_err(|e| e.to_string())?,
        Err(payload) => {
            let message = payload
                .downcast_ref::<&str>()
                .map(|s| (*s).to_owned())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_default();
            return Err(format!("the mesh reader failed on this file ({message})"));
        }
    };
    let vertices: Vec<[f32; 3]> = scene
        .meshes
        .into_iter()
        .flat_map(|mesh| mesh.vertices)
        .collect();
    if vertices.is_empty() {
        return Err("no vertex".to_owned());
    }
    if let Some(v) = vertices.iter().find(|v| !v.iter().all(|x| x.is_finite())) {
        return Err(format!("vertex {v:?} is not finite"));
    }
    Ok(vertices
        .iter()
        .map(|v| Vector3::new(v[0].into(), v[1].into(), v[2].into()))
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
