//! What the solver gives the live viewer, and how it goes over the wire.
//!
//! Three values flow from the solver thread to the browser:
//! - [`ViewMesh`]: the crack-free display mesh, its elements and the scene camera; sent once,
//!   and again (with a larger [`ViewMesh::version`]) when adaptive or hierarchical refinement
//!   changes the elements;
//! - [`ViewFrame`]: the current solution on that mesh, sent as it improves;
//! - [`ViewProgress`]: the stage, step count and convergence, for the progress panel.
//!
//! [`ViewState`] holds the latest of each, shared between the solver thread (which calls
//! [`ViewState::set_mesh`], [`ViewState::set_frame`], [`ViewState::set_progress`] and
//! [`ViewState::finish`]) and the HTTP server (which waits on it for changes).
//!
//! # Wire format of `/api/mesh` and `/api/frame`
//!
//! Both are served as one little-endian binary container (`Content-Type:
//! application/octet-stream`), or as JSON of the Rust value with `?format=json`:
//!
//! | bytes | what |
//! | --- | --- |
//! | 0..4 | magic `RVW1` |
//! | 4..8 | `u32` LE: length `n` of the JSON header |
//! | 8..8+n | UTF-8 JSON header, padded with spaces so that 8 + n is a multiple of 4 |
//! | 8+n.. | the data: the arrays, each starting at a multiple of 4 bytes |
//!
//! The header holds the scalar fields (`kind`, `version` or `mesh_version` and `frame`, the
//! camera, object names, counts) and `arrays`: for each array its `type` (`f32`, `u32` or
//! `u8`), `components` per item, `count` of items and byte `offset` from the start of the
//! data (8 + n), so a page reads it with
//! `new Float32Array(body, 8 + n + offset, count * components)`. The
//! 4-byte alignment is what typed-array views need; little endian is what every browser's
//! typed arrays use in practice (the page checks it once and refuses otherwise).
//!
//! See also `server.rs` for the endpoints and the server-sent events.

use serde::{Deserialize, Serialize};
use std::sync::{Arc, Condvar, Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};
use thiserror::Error;

/// Largest accepted number of display vertices, triangles, elements or edges in a
/// [`ViewMesh`]; far above any mesh a browser can show, it keeps a wrong count from turning
/// into a multi-gigabyte response.
pub const MAX_ITEMS: usize = 50_000_000;

/// Magic bytes that open a binary mesh or frame body.
pub const MAGIC: &[u8; 4] = b"RVW1";

/// Errors of the live viewer: bad data handed to [`ViewState`], and server failures.
#[derive(Debug, Error)]
pub enum ViewError {
    /// A [`ViewMesh`] or [`ViewFrame`] is inconsistent; the text names the field and item.
    #[error("view data: {0}")]
    InvalidData(String),
    /// A [`ViewFrame`] was made for another mesh than the one the viewer shows.
    #[error("view frame {frame} is for mesh version {frame_mesh}, but the viewer shows mesh version {current}")]
    StaleFrame {
        /// The frame's number.
        frame: u64,
        /// The mesh version the frame was computed on.
        frame_mesh: u64,
        /// The mesh version the viewer holds (0 when it holds none).
        current: u64,
    },
    /// The listening socket could not be opened.
    #[error("cannot listen on 127.0.0.1:{port}: {source}")]
    Bind {
        /// The port asked for (0 = any free port).
        port: u16,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// Another I/O failure of the server (accepting, spawning a thread).
    #[error("viewer server: {context}: {source}")]
    Io {
        /// What the server was doing.
        context: &'static str,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// The browser could not be started.
    #[error("cannot open a browser at {url}: {source}")]
    Browser {
        /// The viewer's address.
        url: String,
        /// The operating system's error.
        source: std::io::Error,
    },
}

/// The scene camera the page starts at (the same camera the project's renderer uses).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ViewCamera {
    /// Eye position, m.
    pub eye: [f32; 3],
    /// Point looked at, m.
    pub target: [f32; 3],
    /// Up direction (need not be unit or orthogonal to the view direction).
    pub up: [f32; 3],
    /// Vertical field of view, degrees; the horizontal one follows the window's aspect.
    pub fov_deg: f32,
}

/// The display mesh the viewer draws: crack-free triangles over the solver's elements.
///
/// Triangles are wound counter-clockwise seen from the front of their element (the side its
/// normal points to): the page shows a triangle seen from behind as black unless its element
/// is two-sided, as the renderer does for one-sided surfaces.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ViewMesh {
    /// Version of the mesh: larger than every earlier one the viewer was given. Frames name
    /// the version they were computed on ([`ViewFrame::mesh_version`]).
    pub version: u64,
    /// Display vertices, m.
    pub positions: Vec<[f32; 3]>,
    /// Display triangles, as indices into `positions`.
    pub triangles: Vec<[u32; 3]>,
    /// For each triangle, the element it belongs to.
    pub triangle_element: Vec<u32>,
    /// For each element, the scene object it belongs to (index into `object_names`).
    pub element_object: Vec<u32>,
    /// Object names, as in the scene file.
    pub object_names: Vec<String>,
    /// For each element, its diffuse reflectance ρ per RGB channel (dimensionless, 0..1).
    pub element_reflectance: Vec<[f32; 3]>,
    /// For each element, whether it is lit and seen from both sides.
    pub element_two_sided: Vec<bool>,
    /// Wireframe: edges of the elements (not of the display triangles), as pairs of indices
    /// into `positions`.
    pub element_edges: Vec<[u32; 2]>,
    /// The scene camera the page starts at.
    pub camera: ViewCamera,
    /// Weights of the luminance Y = w·RGB the page's false colour of radiosity uses
    /// (`radiosity::units::luminance_y`), so that the page holds no photometric constant.
    pub luminance_weights: [f32; 3],
}

/// One state of the solution on a [`ViewMesh`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ViewFrame {
    /// The [`ViewMesh::version`] this frame was computed on.
    pub mesh_version: u64,
    /// Frame number: larger than every earlier frame's (the page waits for it).
    pub frame: u64,
    /// Radiance L at each display vertex, W·m⁻²·sr⁻¹, for Gouraud shading: the front-side
    /// value the renderer interpolates (its per-vertex radiosity / π). Not zeroed for back
    /// faces: the page blacks out a triangle seen from behind itself, per pixel.
    pub vertex_radiance: Vec<[f32; 3]>,
    /// Radiosity B of each element, W·m⁻² (flat shading shows B/π).
    pub element_radiosity: Vec<[f32; 3]>,
    /// Irradiance H of each element, W·m⁻²; NaN in a channel not known yet (while a solve
    /// runs, H is recovered from B = E + ρH, which says nothing where ρ = 0).
    pub element_irradiance: Vec<[f32; 3]>,
    /// Illuminance of each element, lx, from its irradiance (the library's photometric
    /// convention, `radiosity::units::lux_from_irradiance`); NaN where not known yet. The
    /// page shows these numbers as they are: a better illuminance (e.g. gathered at points)
    /// replaces them here, not in the page.
    pub element_illuminance: Vec<f32>,
}

/// How a solve ended, or that it is still running.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ViewStatus {
    /// Still working.
    #[default]
    Running,
    /// The converging quantity fell below its tolerance.
    Converged,
    /// Stopped before converging (step limit, time limit, interrupted).
    Stopped,
    /// An error ended the solve.
    Failed,
    /// A saved solution is shown; nothing is being solved.
    Loaded,
}

/// How a solve ended, as [`ViewState::finish`] takes it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Outcome {
    /// Converged: the page shows exactly the word `converged`.
    Converged,
    /// Stopped early; the text says why (e.g. "stopped at the shot limit").
    Stopped(String),
    /// Failed; the text is the error.
    Failed(String),
    /// A saved solution was loaded; the text says which.
    Loaded(String),
}

/// The progress panel's content.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ViewProgress {
    /// Stage name: "meshing", "form factors", "solving", …
    pub stage: String,
    /// Steps done in this stage.
    pub steps: u64,
    /// Steps the stage will take, where known (e.g. form-factor rows).
    pub total_steps: Option<u64>,
    /// What a step is called, singular ("shot", "iteration", "row").
    pub step_word: String,
    /// Name of the converging quantity ("unshot fraction", "residual"); empty if none.
    pub quantity: String,
    /// Its current value (dimensionless), if known.
    pub value: Option<f64>,
    /// The value at which the solve counts as converged, if any.
    pub tolerance: Option<f64>,
    /// Seconds since the solve started.
    pub elapsed_s: f64,
    /// Estimated seconds left, if known.
    pub eta_s: Option<f64>,
    /// True once the solve has ended, whichever way.
    pub done: bool,
    /// Running, converged, stopped or failed.
    pub status: ViewStatus,
    /// The final message ("converged", "stopped at the shot limit", the error), or a
    /// stage note while running.
    pub message: String,
}

impl Default for ViewProgress {
    fn default() -> Self {
        Self {
            stage: "starting".to_owned(),
            steps: 0,
            total_steps: None,
            step_word: String::new(),
            quantity: String::new(),
            value: None,
            tolerance: None,
            elapsed_s: 0.0,
            eta_s: None,
            done: false,
            status: ViewStatus::Running,
            message: String::new(),
        }
    }
}

impl ViewProgress {
    /// A running stage with no steps yet.
    pub fn stage(name: &str) -> Self {
        Self {
            stage: name.to_owned(),
            ..Self::default()
        }
    }
}

fn invalid(text: String) -> ViewError {
    ViewError::InvalidData(text)
}

fn check_len(what: &str, len: usize, expected: usize, of: &str) -> Result<(), ViewError> {
    if len == expected {
        Ok(())
    } else {
        Err(invalid(format!(
            "{what} has {len} entries, but there are {expected} {of}"
        )))
    }
}

fn check_count(what: &str, len: usize) -> Result<(), ViewError> {
    if len > MAX_ITEMS {
        Err(invalid(format!(
            "{what} has {len} entries, more than the viewer accepts ({MAX_ITEMS})"
        )))
    } else {
        Ok(())
    }
}

fn check_finite3(what: &str, values: &[[f32; 3]]) -> Result<(), ViewError> {
    match values.iter().position(|v| v.iter().any(|x| !x.is_finite())) {
        Some(i) => Err(invalid(format!(
            "{what}[{i}] = {:?} is not finite",
            values[i]
        ))),
        None => Ok(()),
    }
}

impl ViewMesh {
    /// Number of elements (the length of every `element_*` list).
    pub fn element_count(&self) -> usize {
        self.element_object.len()
    }

    /// Checks that every list has the right length, every index is in range and every
    /// position and camera value is finite.
    ///
    /// The error names the first offending field and item, e.g. "triangles[12] refers to
    /// vertex 40, the mesh has 38".
    pub fn validate(&self) -> Result<(), ViewError> {
        let vertices = self.positions.len();
        let elements = self.element_count();
        for (what, len) in [
            ("positions", vertices),
            ("triangles", self.triangles.len()),
            ("element_object", elements),
            ("element_edges", self.element_edges.len()),
            ("object_names", self.object_names.len()),
        ] {
            check_count(what, len)?;
        }
        check_finite3("positions", &self.positions)?;
        check_len(
            "triangle_element",
            self.triangle_element.len(),
            self.triangles.len(),
            "triangles",
        )?;
        check_len(
            "element_reflectance",
            self.element_reflectance.len(),
            elements,
            "elements",
        )?;
        check_len(
            "element_two_sided",
            self.element_two_sided.len(),
            elements,
            "elements",
        )?;
        check_finite3("element_reflectance", &self.element_reflectance)?;
        let out_of_range = |list: &str, i: usize, index: u32, of: &str, n: usize| {
            invalid(format!(
                "{list}[{i}] refers to {of} {index}, the mesh has {n}"
            ))
        };
        for (i, t) in self.triangles.iter().enumerate() {
            if let Some(&v) = t.iter().find(|&&v| v as usize >= vertices) {
                return Err(out_of_range("triangles", i, v, "vertex", vertices));
            }
        }
        for (i, e) in self.element_edges.iter().enumerate() {
            if let Some(&v) = e.iter().find(|&&v| v as usize >= vertices) {
                return Err(out_of_range("element_edges", i, v, "vertex", vertices));
            }
        }
        for (i, &e) in self.triangle_element.iter().enumerate() {
            if e as usize >= elements {
                return Err(out_of_range("triangle_element", i, e, "element", elements));
            }
        }
        let objects = self.object_names.len();
        for (i, &o) in self.element_object.iter().enumerate() {
            if o as usize >= objects {
                return Err(out_of_range("element_object", i, o, "object", objects));
            }
        }
        let c = &self.camera;
        let camera_values = c.eye.iter().chain(&c.target).chain(&c.up);
        if camera_values.chain([&c.fov_deg]).any(|x| !x.is_finite()) {
            return Err(invalid(format!("camera {c:?} is not finite")));
        }
        if !(c.fov_deg > 0.0 && c.fov_deg < 180.0) {
            return Err(invalid(format!(
                "camera field of view {}° is not in (0°, 180°)",
                c.fov_deg
            )));
        }
        if c.eye == c.target {
            return Err(invalid(format!(
                "camera eye and target are the same point {:?}",
                c.eye
            )));
        }
        Ok(())
    }
}

impl ViewFrame {
    /// Checks the frame against the mesh it will be drawn on: same mesh version, one
    /// radiance per display vertex, one radiosity and irradiance per element, all finite.
    pub fn validate_for(&self, mesh: &ViewMesh) -> Result<(), ViewError> {
        if self.mesh_version != mesh.version {
            return Err(ViewError::StaleFrame {
                frame: self.frame,
                frame_mesh: self.mesh_version,
                current: mesh.version,
            });
        }
        let elements = mesh.element_count();
        check_len(
            "vertex_radiance",
            self.vertex_radiance.len(),
            mesh.positions.len(),
            "display vertices",
        )?;
        check_len(
            "element_radiosity",
            self.element_radiosity.len(),
            elements,
            "elements",
        )?;
        check_len(
            "element_irradiance",
            self.element_irradiance.len(),
            elements,
            "elements",
        )?;
        check_finite3("vertex_radiance", &self.vertex_radiance)?;
        check_finite3("element_radiosity", &self.element_radiosity)?;
        check_len(
            "element_illuminance",
            self.element_illuminance.len(),
            elements,
            "elements",
        )?;
        // NaN means "not known yet"; infinities are errors.
        let infinite = |x: &f32| x.is_infinite();
        if let Some(i) = self
            .element_irradiance
            .iter()
            .position(|v| v.iter().any(infinite))
        {
            return Err(invalid(format!(
                "element_irradiance[{i}] = {:?} is infinite",
                self.element_irradiance[i]
            )));
        }
        if let Some(i) = self.element_illuminance.iter().position(infinite) {
            return Err(invalid(format!(
                "element_illuminance[{i}] = {} is infinite",
                self.element_illuminance[i]
            )));
        }
        Ok(())
    }
}

/// Writes the binary container described in the module documentation.
struct Container {
    arrays: serde_json::Map<String, serde_json::Value>,
    data: Vec<u8>,
}

impl Container {
    fn new() -> Self {
        Self {
            arrays: serde_json::Map::new(),
            data: Vec::new(),
        }
    }

    fn push(&mut self, name: &str, kind: &str, components: usize, count: usize, bytes: Vec<u8>) {
        while self.data.len() % 4 != 0 {
            self.data.push(0);
        }
        self.arrays.insert(
            name.to_owned(),
            serde_json::json!({
                "type": kind,
                "components": components,
                "count": count,
                "offset": self.data.len(),
            }),
        );
        self.data.extend_from_slice(&bytes);
    }

    fn f32s<const N: usize>(&mut self, name: &str, values: &[[f32; N]]) {
        let bytes = values.iter().flatten().flat_map(|x| x.to_le_bytes());
        self.push(name, "f32", N, values.len(), bytes.collect());
    }

    fn u32s<const N: usize>(&mut self, name: &str, values: &[[u32; N]]) {
        let bytes = values.iter().flatten().flat_map(|x| x.to_le_bytes());
        self.push(name, "u32", N, values.len(), bytes.collect());
    }

    /// Finishes the body: magic, header length, padded header, data.
    fn finish(self, mut header: serde_json::Value) -> Vec<u8> {
        header["arrays"] = serde_json::Value::Object(self.arrays);
        let mut text = header.to_string();
        while (8 + text.len()) % 4 != 0 {
            text.push(' ');
        }
        let mut out = Vec::with_capacity(8 + text.len() + self.data.len());
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&(text.len() as u32).to_le_bytes());
        out.extend_from_slice(text.as_bytes());
        out.extend_from_slice(&self.data);
        out
    }
}

/// Encodes a mesh as the binary container (see the module documentation).
pub fn encode_mesh(mesh: &ViewMesh) -> Vec<u8> {
    let mut c = Container::new();
    c.f32s("positions", &mesh.positions);
    c.u32s("triangles", &mesh.triangles);
    let one = |v: &[u32]| v.iter().map(|&x| [x]).collect::<Vec<_>>();
    c.u32s("triangle_element", &one(&mesh.triangle_element));
    c.u32s("element_object", &one(&mesh.element_object));
    c.f32s("element_reflectance", &mesh.element_reflectance);
    let sided: Vec<u8> = mesh
        .element_two_sided
        .iter()
        .map(|&b| u8::from(b))
        .collect();
    c.push("element_two_sided", "u8", 1, sided.len(), sided);
    c.u32s("element_edges", &mesh.element_edges);
    c.finish(serde_json::json!({
        "kind": "mesh",
        "version": mesh.version,
        "camera": mesh.camera,
        "luminance_weights": mesh.luminance_weights,
        "object_names": mesh.object_names,
        "vertex_count": mesh.positions.len(),
        "triangle_count": mesh.triangles.len(),
        "element_count": mesh.element_count(),
    }))
}

/// Encodes a frame as the binary container (see the module documentation).
pub fn encode_frame(frame: &ViewFrame) -> Vec<u8> {
    let mut c = Container::new();
    c.f32s("vertex_radiance", &frame.vertex_radiance);
    c.f32s("element_radiosity", &frame.element_radiosity);
    c.f32s("element_irradiance", &frame.element_irradiance);
    let lux: Vec<[f32; 1]> = frame.element_illuminance.iter().map(|&x| [x]).collect();
    c.f32s("element_illuminance", &lux);
    c.finish(serde_json::json!({
        "kind": "frame",
        "mesh_version": frame.mesh_version,
        "frame": frame.frame,
    }))
}

/// The state notice sent on `/events` and served at `/api/progress`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StateNotice {
    /// Counts every change of the state; the page ignores notices it has seen.
    pub revision: u64,
    /// The current progress.
    pub progress: ViewProgress,
    /// Version of the mesh the server holds, if any.
    pub mesh_version: Option<u64>,
    /// Number of the latest frame the server holds, if any.
    pub frame: Option<u64>,
}

/// A body the server has encoded once and serves to every client that asks.
pub(crate) type Encoded = Arc<Vec<u8>>;

#[derive(Default)]
struct Shared {
    mesh: Option<Arc<ViewMesh>>,
    frame: Option<Arc<ViewFrame>>,
    progress: ViewProgress,
    revision: u64,
    mesh_body: Option<(u64, Encoded)>,
    frame_body: Option<(u64, Encoded)>,
    last_frame_at: Option<Instant>,
    /// Event streams opened so far (pages that connected).
    viewers: u64,
}

/// The viewer's state: the latest mesh, frame and progress, shared between the solver thread
/// and the server's threads.
///
/// Every setter wakes the server's event streams; they coalesce bursts into at most a few
/// notices a second, so the solver may call the setters as often as it likes. Building a
/// [`ViewFrame`] costs the solver time, though: ask [`ViewState::frame_due`] first.
#[derive(Default)]
pub struct ViewState {
    shared: Mutex<Shared>,
    changed: Condvar,
}

impl ViewState {
    /// An empty state: no mesh, no frame, progress "starting".
    pub fn new() -> Self {
        Self::default()
    }

    fn lock(&self) -> MutexGuard<'_, Shared> {
        // A panic elsewhere while holding the lock leaves plain data behind; serve it.
        self.shared.lock().unwrap_or_else(PoisonError::into_inner)
    }

    fn changed(&self, mut shared: MutexGuard<'_, Shared>) {
        shared.revision += 1;
        drop(shared);
        self.changed.notify_all();
    }

    /// Replaces the mesh (after [`ViewMesh::validate`]); the frame of the previous mesh is
    /// dropped. The version must exceed the previous mesh's.
    pub fn set_mesh(&self, mesh: ViewMesh) -> Result<(), ViewError> {
        mesh.validate()?;
        let mut shared = self.lock();
        if let Some(old) = &shared.mesh {
            if mesh.version <= old.version {
                return Err(invalid(format!(
                    "mesh version {} does not exceed the current version {}",
                    mesh.version, old.version
                )));
            }
        }
        shared.mesh = Some(Arc::new(mesh));
        shared.frame = None;
        shared.mesh_body = None;
        shared.frame_body = None;
        self.changed(shared);
        Ok(())
    }

    /// Replaces the frame (after [`ViewFrame::validate_for`] the current mesh). Frame
    /// numbers must increase.
    pub fn set_frame(&self, frame: ViewFrame) -> Result<(), ViewError> {
        let mut shared = self.lock();
        let Some(mesh) = &shared.mesh else {
            return Err(ViewError::StaleFrame {
                frame: frame.frame,
                frame_mesh: frame.mesh_version,
                current: 0,
            });
        };
        frame.validate_for(mesh)?;
        if let Some(old) = &shared.frame {
            if frame.frame <= old.frame {
                return Err(invalid(format!(
                    "frame number {} does not exceed the current frame {}",
                    frame.frame, old.frame
                )));
            }
        }
        shared.frame = Some(Arc::new(frame));
        shared.frame_body = None;
        shared.last_frame_at = Some(Instant::now());
        self.changed(shared);
        Ok(())
    }

    /// True when no frame was set in the last `interval` (or none at all): the solver's
    /// cue to build the next [`ViewFrame`]. A quarter of a second matches the event rate.
    pub fn frame_due(&self, interval: Duration) -> bool {
        self.lock()
            .last_frame_at
            .is_none_or(|t| t.elapsed() >= interval)
    }

    /// Replaces the progress. Ignored once [`ViewState::finish`] was called, so a late
    /// report from a worker cannot undo the final status.
    pub fn set_progress(&self, progress: ViewProgress) {
        let mut shared = self.lock();
        if shared.progress.done {
            return;
        }
        shared.progress = ViewProgress {
            done: false,
            status: ViewStatus::Running,
            ..progress
        };
        self.changed(shared);
    }

    /// Marks the solve as ended: the page shows `converged`, or the stop reason, or the
    /// error, in its status line.
    pub fn finish(&self, outcome: Outcome) {
        let mut shared = self.lock();
        let (status, message) = match outcome {
            Outcome::Converged => (ViewStatus::Converged, "converged".to_owned()),
            Outcome::Stopped(text) => (ViewStatus::Stopped, text),
            Outcome::Failed(text) => (ViewStatus::Failed, text),
            Outcome::Loaded(text) => (ViewStatus::Loaded, text),
        };
        let p = &mut shared.progress;
        p.done = true;
        p.status = status;
        p.message = message;
        p.eta_s = None;
        self.changed(shared);
    }

    /// The current notice (revision, progress, mesh version and frame number).
    pub fn notice(&self) -> StateNotice {
        let shared = self.lock();
        StateNotice {
            revision: shared.revision,
            progress: shared.progress.clone(),
            mesh_version: shared.mesh.as_ref().map(|m| m.version),
            frame: shared.frame.as_ref().map(|f| f.frame),
        }
    }

    /// The current mesh, if any.
    pub fn mesh(&self) -> Option<Arc<ViewMesh>> {
        self.lock().mesh.clone()
    }

    /// The current frame, if any.
    pub fn frame(&self) -> Option<Arc<ViewFrame>> {
        self.lock().frame.clone()
    }

    /// The current mesh's binary body, encoded once per mesh version.
    pub(crate) fn mesh_body(&self) -> Option<Encoded> {
        let mesh = {
            let shared = self.lock();
            let mesh = shared.mesh.clone()?;
            if let Some((version, body)) = &shared.mesh_body {
                if *version == mesh.version {
                    return Some(body.clone());
                }
            }
            mesh
        };
        // Encode without holding the lock: the solver must not wait for a slow encoding.
        let body = Arc::new(encode_mesh(&mesh));
        let mut shared = self.lock();
        if shared.mesh.as_ref().map(|m| m.version) == Some(mesh.version) {
            shared.mesh_body = Some((mesh.version, body.clone()));
        }
        Some(body)
    }

    /// The current frame's binary body, encoded once per frame.
    pub(crate) fn frame_body(&self) -> Option<Encoded> {
        let frame = {
            let shared = self.lock();
            let frame = shared.frame.clone()?;
            if let Some((number, body)) = &shared.frame_body {
                if *number == frame.frame {
                    return Some(body.clone());
                }
            }
            frame
        };
        let body = Arc::new(encode_frame(&frame));
        let mut shared = self.lock();
        if shared.frame.as_ref().map(|f| f.frame) == Some(frame.frame) {
            shared.frame_body = Some((frame.frame, body.clone()));
        }
        Some(body)
    }

    /// Waits until the revision differs from `seen`, `stop()` turns true, or `deadline`
    /// passes; returns the revision then.
    pub(crate) fn wait_change(
        &self,
        seen: Option<u64>,
        deadline: Instant,
        stop: &dyn Fn() -> bool,
    ) -> u64 {
        let mut shared = self.lock();
        loop {
            if Some(shared.revision) != seen || stop() {
                return shared.revision;
            }
            let now = Instant::now();
            if now >= deadline {
                return shared.revision;
            }
            shared = self
                .changed
                .wait_timeout(shared, deadline - now)
                .unwrap_or_else(PoisonError::into_inner)
                .0;
        }
    }

    /// Sleeps until `deadline` unless `stop()` turns true first.
    pub(crate) fn wait_stop(&self, deadline: Instant, stop: &dyn Fn() -> bool) {
        let mut shared = self.lock();
        while !stop() {
            let now = Instant::now();
            if now >= deadline {
                return;
            }
            shared = self
                .changed
                .wait_timeout(shared, deadline - now)
                .unwrap_or_else(PoisonError::into_inner)
                .0;
        }
    }

    /// Counts a page that opened the event stream, and wakes [`ViewState::wait_for_viewer`].
    pub(crate) fn viewer_connected(&self) {
        self.lock().viewers += 1;
        self.changed.notify_all();
    }

    /// Waits until a page has opened the event stream (at any time since the state was
    /// made) or `stop()` turns true; returns whether a page did. `stop` is looked at every
    /// 100 ms and whenever the state changes.
    pub fn wait_for_viewer(&self, stop: &dyn Fn() -> bool) -> bool {
        let mut shared = self.lock();
        loop {
            if shared.viewers > 0 {
                return true;
            }
            if stop() {
                return false;
            }
            shared = self
                .changed
                .wait_timeout(shared, Duration::from_millis(100))
                .unwrap_or_else(PoisonError::into_inner)
                .0;
        }
    }

    /// Wakes every waiter so that it re-checks its stop condition. Taking the lock first
    /// orders this after any waiter's check, so no wake-up is lost.
    pub(crate) fn wake_all(&self) {
        drop(self.lock());
        self.changed.notify_all();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit square in z = 0 as two triangles, one element per triangle.
    pub(crate) fn square(version: u64) -> ViewMesh {
        ViewMesh {
            version,
            positions: vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [1.0, 1.0, 0.0],
                [0.0, 1.0, 0.0],
            ],
            triangles: vec![[0, 1, 2], [0, 2, 3]],
            triangle_element: vec![0, 1],
            element_object: vec![0, 0],
            object_names: vec!["square".to_owned()],
            element_reflectance: vec![[0.5, 0.5, 0.5], [0.25, 0.5, 0.75]],
            element_two_sided: vec![false, true],
            element_edges: vec![[0, 1], [1, 2], [2, 0], [2, 3], [3, 0]],
            camera: ViewCamera {
                eye: [0.5, 0.5, 2.0],
                target: [0.5, 0.5, 0.0],
                up: [0.0, 1.0, 0.0],
                fov_deg: 40.0,
            },
            luminance_weights: [0.2126, 0.7152, 0.0722],
        }
    }

    fn frame(mesh_version: u64, frame: u64) -> ViewFrame {
        ViewFrame {
            mesh_version,
            frame,
            vertex_radiance: vec![[0.1, 0.2, 0.3]; 4],
            element_radiosity: vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]],
            element_irradiance: vec![[7.0, 8.0, 9.0], [10.0, 11.0, 12.0]],
            element_illuminance: vec![5.0, f32::NAN],
        }
    }

    #[test]
    fn validation_names_the_offending_item() {
        assert!(square(1).validate().is_ok());
        let mut m = square(1);
        m.triangles[1] = [0, 2, 9];
        let e = m.validate().unwrap_err().to_string();
        assert!(
            e.contains("triangles[1] refers to vertex 9, the mesh has 4"),
            "{e}"
        );
        let mut m = square(1);
        m.triangle_element[0] = 2;
        let e = m.validate().unwrap_err().to_string();
        assert!(e.contains("triangle_element[0] refers to element 2"), "{e}");
        let mut m = square(1);
        m.element_two_sided.pop();
        let e = m.validate().unwrap_err().to_string();
        assert!(e.contains("element_two_sided has 1 entries"), "{e}");
        let mut m = square(1);
        m.positions[2][1] = f32::NAN;
        let e = m.validate().unwrap_err().to_string();
        assert!(e.contains("positions[2]"), "{e}");
        let mut m = square(1);
        m.element_object[1] = 1;
        assert!(m.validate().unwrap_err().to_string().contains("object 1"));
        let mut m = square(1);
        m.camera.fov_deg = 180.0;
        assert!(m.validate().is_err());
        let mut m = square(1);
        m.element_edges[0] = [0, 4];
        assert!(m.validate().is_err());
    }

    #[test]
    fn frames_must_fit_the_current_mesh() {
        let state = ViewState::new();
        // No mesh yet: any frame is stale.
        assert!(matches!(
            state.set_frame(frame(1, 1)),
            Err(ViewError::StaleFrame { current: 0, .. })
        ));
        state.set_mesh(square(1)).unwrap();
        assert!(matches!(
            state.set_frame(frame(2, 1)),
            Err(ViewError::StaleFrame {
                frame_mesh: 2,
                current: 1,
                ..
            })
        ));
        let mut short = frame(1, 1);
        short.vertex_radiance.pop();
        let e = state.set_frame(short).unwrap_err().to_string();
        assert!(
            e.contains("vertex_radiance has 3 entries, but there are 4 display vertices"),
            "{e}"
        );
        let mut nan = frame(1, 1);
        nan.element_irradiance[1][0] = f32::INFINITY;
        assert!(state
            .set_frame(nan)
            .unwrap_err()
            .to_string()
            .contains("element_irradiance[1]"));
        // NaN irradiance is "not known yet", accepted; an infinite illuminance is not.
        let mut unknown = frame(1, 1);
        unknown.element_irradiance[0] = [f32::NAN, 1.0, 2.0];
        assert!(unknown.validate_for(&square(1)).is_ok());
        let mut inf = frame(1, 1);
        inf.element_illuminance[0] = f32::INFINITY;
        assert!(inf
            .validate_for(&square(1))
            .unwrap_err()
            .to_string()
            .contains("element_illuminance[0]"));
        let mut short = frame(1, 1);
        short.element_illuminance.pop();
        assert!(state.set_frame(short).is_err());
        state.set_frame(frame(1, 1)).unwrap();
        // Frame numbers only go up.
        assert!(state.set_frame(frame(1, 1)).is_err());
        state.set_frame(frame(1, 2)).unwrap();
        // A new mesh drops the old frame; versions only go up.
        assert!(state.set_mesh(square(1)).is_err());
        state.set_mesh(square(2)).unwrap();
        assert!(state.frame().is_none());
        assert_eq!(state.notice().mesh_version, Some(2));
    }

    /// Reads one array of the container back, checking alignment and bounds.
    pub(crate) fn read_array(body: &[u8], header: &serde_json::Value, name: &str) -> Vec<u32> {
        let a = &header["arrays"][name];
        let start = 8 + u32::from_le_bytes([body[4], body[5], body[6], body[7]]) as usize;
        let offset = start + a["offset"].as_u64().unwrap() as usize;
        let n = (a["count"].as_u64().unwrap() * a["components"].as_u64().unwrap()) as usize;
        assert_eq!(offset % 4, 0, "{name} is not 4-byte aligned");
        match a["type"].as_str().unwrap() {
            "u8" => body[offset..offset + n]
                .iter()
                .map(|&b| u32::from(b))
                .collect(),
            _ => body[offset..offset + 4 * n]
                .chunks_exact(4)
                .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                .collect(),
        }
    }

    pub(crate) fn read_header(body: &[u8]) -> serde_json::Value {
        assert_eq!(&body[..4], MAGIC);
        let n = u32::from_le_bytes([body[4], body[5], body[6], body[7]]) as usize;
        assert_eq!((8 + n) % 4, 0, "header padding");
        serde_json::from_slice(&body[8..8 + n]).unwrap()
    }

    #[test]
    fn binary_mesh_round_trips() {
        let mesh = square(7);
        let body = encode_mesh(&mesh);
        let h = read_header(&body);
        assert_eq!(h["kind"], "mesh");
        assert_eq!(h["version"], 7);
        assert_eq!(h["object_names"][0], "square");
        assert_eq!(h["camera"]["fov_deg"], 40.0);
        let f = |bits: Vec<u32>| bits.into_iter().map(f32::from_bits).collect::<Vec<_>>();
        let flat3 = |v: &[[f32; 3]]| v.iter().flatten().copied().collect::<Vec<_>>();
        assert_eq!(
            f(read_array(&body, &h, "positions")),
            flat3(&mesh.positions)
        );
        assert_eq!(
            read_array(&body, &h, "triangles"),
            mesh.triangles.iter().flatten().copied().collect::<Vec<_>>()
        );
        assert_eq!(
            read_array(&body, &h, "triangle_element"),
            mesh.triangle_element
        );
        assert_eq!(read_array(&body, &h, "element_object"), mesh.element_object);
        assert_eq!(
            f(read_array(&body, &h, "element_reflectance")),
            flat3(&mesh.element_reflectance)
        );
        assert_eq!(read_array(&body, &h, "element_two_sided"), vec![0, 1]);
        assert_eq!(
            read_array(&body, &h, "element_edges"),
            mesh.element_edges
                .iter()
                .flatten()
                .copied()
                .collect::<Vec<_>>()
        );
        // The edges are the last array and end exactly at the end of the body.
        let e = &h["arrays"]["element_edges"];
        let data_start = 8 + u32::from_le_bytes([body[4], body[5], body[6], body[7]]) as usize;
        let edges_offset = e["offset"].as_u64().unwrap() as usize;
        assert_eq!(data_start + edges_offset + 4 * 10, body.len());
    }

    #[test]
    fn binary_frame_round_trips() {
        let fr = frame(3, 11);
        let body = encode_frame(&fr);
        let h = read_header(&body);
        assert_eq!(
            (
                h["kind"].as_str(),
                h["mesh_version"].as_u64(),
                h["frame"].as_u64()
            ),
            (Some("frame"), Some(3), Some(11))
        );
        let f = |bits: Vec<u32>| bits.into_iter().map(f32::from_bits).collect::<Vec<_>>();
        let flat3 = |v: &[[f32; 3]]| v.iter().flatten().copied().collect::<Vec<_>>();
        assert_eq!(
            f(read_array(&body, &h, "vertex_radiance")),
            flat3(&fr.vertex_radiance)
        );
        assert_eq!(
            f(read_array(&body, &h, "element_radiosity")),
            flat3(&fr.element_radiosity)
        );
        assert_eq!(
            f(read_array(&body, &h, "element_irradiance")),
            flat3(&fr.element_irradiance)
        );
        // NaN ("not known yet") survives bit for bit.
        let lux: Vec<u32> = fr.element_illuminance.iter().map(|x| x.to_bits()).collect();
        assert_eq!(read_array(&body, &h, "element_illuminance"), lux);
        assert_eq!(
            h["luminance_weights"].as_array().map(Vec::len),
            None,
            "frames carry no weights"
        );
        let mesh_header = read_header(&encode_mesh(&square(1)));
        assert_eq!(mesh_header["luminance_weights"][1], 0.7152f32 as f64);
    }

    #[test]
    fn finish_is_final() {
        let state = ViewState::new();
        state.set_progress(ViewProgress::stage("solving"));
        state.finish(Outcome::Converged);
        state.set_progress(ViewProgress::stage("late"));
        let n = state.notice();
        assert!(n.progress.done);
        assert_eq!(n.progress.status, ViewStatus::Converged);
        assert_eq!(n.progress.message, "converged");
        assert_eq!(n.progress.stage, "solving");
        let json = serde_json::to_value(&n).unwrap();
        assert_eq!(json["progress"]["status"], "converged");
    }

    #[test]
    fn frame_due_follows_the_interval() {
        let state = ViewState::new();
        assert!(state.frame_due(Duration::from_secs(3600)));
        state.set_mesh(square(1)).unwrap();
        state.set_frame(frame(1, 1)).unwrap();
        assert!(!state.frame_due(Duration::from_secs(3600)));
        assert!(state.frame_due(Duration::ZERO));
    }
}
