//! Saved solutions: the shaded elements, so a solved scene can be rendered again from any
//! viewpoint without solving (`radiosity solve --save`, `radiosity render --solution`).
//!
//! JSON with a format version; radiosity and irradiance in W·m⁻² per element.

use crate::geometry::COORDINATE_LIMIT;
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

    /// Reads and validates a file (a regular file of at most
    /// [`Kind::Solution`](crate::io::open::Kind::Solution)'s cap).
    pub fn load(path: &Path) -> Result<Self, SolutionFileError> {
        let text = crate::io::open::read_to_string_checked(path, crate::io::open::Kind::Solution)
            .map_err(|source| SolutionFileError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::parse(&text, path)
    }

    /// Parses and validates solution-file JSON; `path` labels errors (it is not read).
    ///
    /// Everything a renderer trusts is checked, and an error names the key: indices in
    /// range; vertices finite and within [`COORDINATE_LIMIT`]; each surface's reflectance
    /// in [0, 1) and exitance finite and ≥ 0; radiosity and irradiance finite and ≥ 0; the
    /// ambient term finite, ≥ 0 and no larger than the stored radiosity allows (unshot
    /// radiosity is part of B, so ambient ≤ max B / (1 − ρ̄)); the camera usable.
    pub fn parse(text: &str, path: &Path) -> Result<Self, SolutionFileError> {
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        let file: SolutionFile =
            serde_json::from_str(text).map_err(|source| SolutionFileError::Parse {
                path: path.to_path_buf(),
                source,
            })?;
        file.validate()
            .map_err(|message| SolutionFileError::Invalid {
                path: path.to_path_buf(),
                message,
            })?;
        Ok(file)
    }

    /// What is wrong with the file's contents, naming the key, if anything.
    fn validate(&self) -> Result<(), String> {
        const CHANNELS: [&str; 3] = ["red", "green", "blue"];
        if self.format != "radiosity-solution" {
            return Err(format!(
                "format: unknown format '{}' (expected 'radiosity-solution')",
                self.format
            ));
        }
        if self.version != FORMAT_VERSION {
            return Err(format!(
                "version: format version {} is not supported (expected {FORMAT_VERSION})",
                self.version
            ));
        }
        let n = self.elements.len();
        if n == 0 {
            return Err("elements: the solution has no elements".into());
        }
        for (key, len) in [
            ("radiosity", self.radiosity.len()),
            ("irradiance", self.irradiance.len()),
        ] {
            if len != n {
                return Err(format!("{key}: {len} values for {n} elements"));
            }
        }
        for (i, v) in self.vertices.iter().enumerate() {
            if let Some(x) = v
                .iter()
                .find(|x| !x.is_finite() || x.abs() > COORDINATE_LIMIT)
            {
                return Err(format!(
                    "vertices[{i}]: coordinate {x} is not finite or beyond {COORDINATE_LIMIT:e} m"
                ));
            }
        }
        for (i, s) in self.surfaces.iter().enumerate() {
            if s.object as usize >= self.objects.len() {
                return Err(format!(
                    "surfaces[{i}].object: object {} does not exist ({} objects)",
                    s.object,
                    self.objects.len()
                ));
            }
            for (c, &r) in s.reflectance.iter().enumerate() {
                if !(0.0..1.0).contains(&r) {
                    return Err(format!(
                        "surfaces[{i}].reflectance: {r} ({}) must be ≥ 0 and < 1",
                        CHANNELS[c]
                    ));
                }
            }
            for (c, &e) in s.exitance.iter().enumerate() {
                if !(e.is_finite() && e >= 0.0) {
                    return Err(format!(
                        "surfaces[{i}].exitance: {e} ({}) must be finite and ≥ 0",
                        CHANNELS[c]
                    ));
                }
            }
        }
        for (i, e) in self.elements.iter().enumerate() {
            if e.corners.len() < 3 {
                return Err(format!(
                    "elements[{i}].corners: {} corners, at least 3 needed",
                    e.corners.len()
                ));
            }
            if let Some(&c) = e
                .corners
                .iter()
                .find(|&&c| c as usize >= self.vertices.len())
            {
                return Err(format!(
                    "elements[{i}].corners: vertex {c} does not exist ({} vertices)",
                    self.vertices.len()
                ));
            }
            if e.surface as usize >= self.surfaces.len() {
                return Err(format!(
                    "elements[{i}].surface: surface {} does not exist ({} surfaces)",
                    e.surface,
                    self.surfaces.len()
                ));
            }
            let sound =
                e.area.is_finite() && e.area >= 0.0 && e.centre.is_finite() && e.normal.is_finite();
            if !sound {
                return Err(format!(
                    "elements[{i}]: area, centre and normal must be finite (area ≥ 0)"
                ));
            }
        }
        for (key, values) in [
            ("radiosity", &self.radiosity),
            ("irradiance", &self.irradiance),
        ] {
            for (i, v) in values.iter().enumerate() {
                for (c, &x) in v.iter().enumerate() {
                    if !(x.is_finite() && x >= 0.0) {
                        return Err(format!(
                            "{key}[{i}]: {x} W·m⁻² ({}) must be finite and ≥ 0",
                            CHANNELS[c]
                        ));
                    }
                }
            }
        }
        // The ambient term is R · (mean unshot radiosity), R = 1 / (1 − ρ̄) with ρ̄ the
        // area-weighted mean reflectance, and unshot radiosity never exceeds B.
        let total_area: f64 = self.elements.iter().map(|e| e.area).sum();
        for c in 0..3 {
            let a = self.ambient[c];
            if !(a.is_finite() && a >= 0.0) {
                return Err(format!(
                    "ambient: {a} W·m⁻² ({}) must be finite and ≥ 0",
                    CHANNELS[c]
                ));
            }
            let max_b = self.radiosity.iter().map(|b| b[c]).fold(0.0, f64::max);
            let rho_avg = if total_area > 0.0 {
                self.elements
                    .iter()
                    .map(|e| self.surfaces[e.surface as usize].reflectance[c] * e.area)
                    .sum::<f64>()
                    / total_area
            } else {
                0.0
            };
            let bound = max_b / (1.0 - rho_avg).max(1e-12);
            if a > bound * (1.0 + 1e-9) + 1e-300 {
                return Err(format!(
                    "ambient: {a:e} W·m⁻² ({}) is more than the stored radiosity allows \
                     (at most {bound:e}: max B / (1 − mean ρ))",
                    CHANNELS[c]
                ));
            }
        }
        if let Some(camera) = self.camera {
            if let Some(problem) = crate::io::scene_file::camera_problem(&Camera::from(camera)) {
                return Err(format!("camera: {problem}"));
            }
        }
        Ok(())
    }
}
