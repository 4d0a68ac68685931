//! Saved solutions: the shaded elements, so a solved scene can be rendered again from any
//! viewpoint without solving (`radiosity solve --save`, `radiosity render --solution`).
//!
//! JSON with a format version; radiosity and irradiance in W·m⁻² per element.

use crate::mesh::{Element, Mesh, SurfaceData};
use crate::scene::Camera;
use crate::solve::Solution;
use glam::DVec3;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The current format version.
pub const FORMAT_VERSION: u32 = 1;

/// A stored solution.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SolutionFile {
    /// The format's name, for recognising the file.
    pub format: String,
    /// The format version ([`FORMAT_VERSION`]).
    pub version: u32,
    /// The scene's name.
    pub scene: String,
    /// The scene's camera, if it had one.
    pub camera: Option<StoredCamera>,
    /// Object names.
    pub objects: Vec<String>,
    /// Per-surface material data.
    pub surfaces: Vec<SurfaceData>,
    /// Mesh vertices, m.
    pub vertices: Vec<[f64; 3]>,
    /// The elements.
    pub elements: Vec<Element>,
    /// W·m⁻² per element.
    pub radiosity: Vec<[f64; 3]>,
    /// W·m⁻² per element.
    pub irradiance: Vec<[f64; 3]>,
    /// Ambient term (W·m⁻²) of the stored solution, for `--ambient` display.
    pub ambient: [f64; 3],
}

/// A camera as stored in files.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StoredCamera {
    /// Eye position, m.
    pub eye: [f64; 3],
    /// Point looked at, m.
    pub target: [f64; 3],
    /// Up direction.
    pub up: [f64; 3],
    /// Vertical field of view, degrees.
    pub fov_deg: f64,
}

impl From<Camera> for StoredCamera {
    fn from(c: Camera) -> Self {
        Self {
            eye: c.eye.to_array(),
            target: c.target.to_array(),
            up: c.up.to_array(),
            fov_deg: c.fov_deg,
        }
    }
}

impl From<StoredCamera> for Camera {
    fn from(c: StoredCamera) -> Self {
        Self {
            eye: DVec3::from_array(c.eye),
            target: DVec3::from_array(c.target),
            up: DVec3::from_array(c.up),
            fov_deg: c.fov_deg,
        }
    }
}

/// Why a solution file could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum SolutionFileError {
    #[error("{path}: {source}")]
    /// The file could not be read or written.
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    #[error("{path}: not a radiosity solution file: {source}")]
    /// The file is not a solution file.
    Parse {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: serde_json::Error,
    },
    #[error("{path}: {message}")]
    /// The file is inconsistent.
    Invalid {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
}

impl SolutionFile {
    /// Captures a solved mesh.
    pub fn new(scene: &str, camera: Option<Camera>, mesh: &Mesh, solution: &Solution) -> Self {
        Self {
            format: "radiosity-solution".into(),
            version: FORMAT_VERSION,
            scene: scene.into(),
            camera: camera.map(Into::into),
            objects: mesh.objects.clone(),
            surfaces: mesh.surfaces.clone(),
            vertices: mesh.vertices.iter().map(|v| v.to_array()).collect(),
            elements: mesh.elements.clone(),
            radiosity: solution.radiosity.clone(),
            irradiance: solution.irradiance.clone(),
            ambient: solution.ambient(mesh),
        }
    }

    /// The mesh vertices, m.
    pub fn vertices(&self) -> Vec<DVec3> {
        self.vertices
            .iter()
            .map(|v| DVec3::from_array(*v))
            .collect()
    }

    /// Radiosity for display, with ρ_e · ambient added when asked.
    pub fn display_radiosity(&self, ambient: bool) -> Vec<[f64; 3]> {
        self.elements
            .iter()
            .zip(&self.radiosity)
            .map(|(e, b)| {
                if !ambient {
                    return *b;
                }
                let rho = self.surfaces[e.surface as usize].reflectance;
                std::array::from_fn(|c| b[c] + rho[c] * self.ambient[c])
            })
            .collect()
    }

    /// Writes the file atomically.
    pub fn save(&self, path: &Path) -> Result<(), SolutionFileError> {
        crate::io::atomic::write_atomically(path, |w| {
            serde_json::to_writer(&mut *w, self).map_err(std::io::Error::other)
        })
        .map_err(|source| SolutionFileError::Io {
            path: path.to_path_buf(),
            source,
        })
    }

    /// Reads and validates a file.
    pub fn load(path: &Path) -> Result<Self, SolutionFileError> {
        let text = std::fs::read_to_string(path).map_err(|source| SolutionFileError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let file: SolutionFile =
            serde_json::from_str(&text).map_err(|source| SolutionFileError::Parse {
                path: path.to_path_buf(),
                source,
            })?;
        let invalid = |message: String| SolutionFileError::Invalid {
            path: path.to_path_buf(),
            message,
        };
        if file.format != "radiosity-solution" {
            return Err(invalid(format!("unknown format '{}'", file.format)));
        }
        if file.version != FORMAT_VERSION {
            return Err(invalid(format!(
                "format version {} is not supported (expected {FORMAT_VERSION})",
                file.version
            )));
        }
        let n = file.elements.len();
        if file.radiosity.len() != n || file.irradiance.len() != n {
            return Err(invalid(format!(
                "{n} elements but {} radiosity values",
                file.radiosity.len()
            )));
        }
        for (i, e) in file.elements.iter().enumerate() {
            if e.corners.len() < 3 || e.corners.iter().any(|&c| c as usize >= file.vertices.len()) {
                return Err(invalid(format!(
                    "element {i} refers to a vertex that does not exist"
                )));
            }
            if e.surface as usize >= file.surfaces.len() {
                return Err(invalid(format!(
                    "element {i} refers to surface {} that does not exist",
                    e.surface
                )));
            }
        }
        let finite = file
            .vertices
            .iter()
            .flatten()
            .chain(file.radiosity.iter().flatten())
            .all(|x| x.is_finite());
        if !finite {
            return Err(invalid("non-finite vertex or radiosity value".into()));
        }
        Ok(file)
    }
}
