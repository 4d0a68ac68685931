//! CIE 171:2006 analytical test cases: the case loader and the closed forms that give every
//! expected value, written independently of the engine (nothing here calls the `radiosity`
//! library, so the references can judge it).
//!
//! A case is a folder under `tests/cie171/` holding `scene.obj` + `scene.mtl` (metres, +z up,
//! one `o` per convex planar polygon, `Kd` = diffuse reflectance, `Ke` = emitted radiance L_e in
//! W·m⁻²·sr⁻¹, Lambertian, front side only) and `case.json` (what is tested, point lights,
//! measurement points, which closed form applies, exact group means, the tolerance). Radiometric
//! values are chosen so that W·m⁻² equal the CIE's lux.
//!
//! Closed forms (each function names its source):
//! - point source: E = I(ω) cos θ / d² (CIE 171:2006 §5.2);
//! - area source: E = π L_e F(dA → emitter), F by Lambert's contour formula (CIE 171 §5.3, 5.6);
//! - obstruction: the emitter minus the central projection of a convex occluder (CIE 171 §5.7);
//! - flux conservation: Σ I Ω_i = 4π I = Φ (CIE 171 §5.4), solid angles by Van Oosterom &
//!   Strackee (1983);
//! - closed cube: face mean E = Φ / (S_T (1 − ρ)) (CIE 171 §5.8, eq. for E_IRC);
//! - aligned rectangles (Howell's catalogue B-3 and the perpendicular-plane corner factor, by
//!   superposition) as an independent check of the contour formula.
//!
//! Entry points for an engine test: [`all_cases`], [`load_geometry`], [`expectations`].

use glam::DVec3;
use serde::Deserialize;
use std::f64::consts::PI;
use std::path::{Path, PathBuf};

/// Largest `case.json`, `scene.obj` or `scene.mtl` read, bytes (the cases are a few kB; this
/// bounds memory on a corrupt file).
const MAX_FILE_BYTES: u64 = 16 << 20;

/// Relative tolerance of the planarity and convexity checks on OBJ polygons.
const GEOMETRY_EPS: f64 = 1e-9;

/// Everything that can go wrong loading a case or evaluating its closed form.
#[derive(Debug, thiserror::Error)]
pub enum Cie171Error {
    /// A file could not be read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// A file is larger than the loader accepts.
    #[error("{path}: {bytes} bytes is more than the {MAX_FILE_BYTES} accepted")]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// Its size, bytes.
        bytes: u64,
    },
    /// `case.json` is not valid JSON or does not match the case schema.
    #[error("{path}: line {line}, column {column}: {message}")]
    Json {
        /// The file.
        path: PathBuf,
        /// 1-based line of the error.
        line: usize,
        /// 1-based column of the error.
        column: usize,
        /// What is wrong.
        message: String,
    },
    /// A line of `scene.obj` or `scene.mtl` is malformed or refers to something missing.
    #[error("{path}: line {line}: {message}")]
    Scene {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// The central-projection construction of an occluder's shadow does not apply (the
    /// occluder is not wholly between the point and the emitter's plane).
    #[error("at {point}: {message}")]
    Occluder {
        /// The receiving point, m.
        point: DVec3,
        /// What is wrong.
        message: String,
    },
    /// The case is well formed but inconsistent (a point names a missing object, a closed
    /// form does not apply to the geometry, ...).
    #[error("case {case}: {message}")]
    Case {
        /// The case id (its folder name).
        case: String,
        /// What is wrong.
        message: String,
    },
}

fn case_error(case: &str, message: impl Into<String>) -> Cie171Error {
    Cie171Error::Case {
        case: case.to_string(),
        message: message.into(),
    }
}

// ---------------------------------------------------------------------------------------------
// case.json
// ---------------------------------------------------------------------------------------------

/// One CIE 171 test case as described by its `case.json`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Case {
    /// Identifier; equals the case folder's name.
    pub id: String,
    /// One-line title.
    pub title: String,
    /// Where the case comes from in CIE 171:2006 and how faithful it is.
    pub cie: CieReference,
    /// What the case tests.
    pub tests: String,
    /// Engine features the case needs.
    pub requires: Vec<Feature>,
    /// Where the files came from, for cases copied from elsewhere.
    #[serde(default)]
    pub provenance: Option<String>,
    /// The scene files, relative to the case folder.
    pub scene: SceneFiles,
    /// Point lights (OBJ cannot express them).
    #[serde(default)]
    pub point_lights: Vec<PointLight>,
    /// Which closed form gives the expected values.
    pub closed_form: ClosedForm,
    /// Measurement points.
    #[serde(default)]
    pub points: Vec<MeasurementPoint>,
    /// Groups of objects whose area-weighted mean irradiance is exact.
    #[serde(default)]
    pub groups: Vec<GroupSpec>,
    /// The pass criterion for an engine.
    pub tolerance: Tolerance,
    /// The case folder (set by the loader).
    #[serde(skip)]
    pub dir: PathBuf,
}

impl Case {
    /// Path of the case's OBJ file.
    pub fn obj_path(&self) -> PathBuf {
        self.dir.join(&self.scene.obj)
    }

    /// Path of the case's MTL file.
    pub fn mtl_path(&self) -> PathBuf {
        self.dir.join(&self.scene.mtl)
    }

    /// Total radiant power of the point lights, W: 4π I for isotropic, π I₀ for cosine
    /// distributions (∫ I₀ max(0, cos γ) dω = π I₀).
    pub fn point_light_power(&self) -> f64 {
        self.point_lights.iter().map(PointLight::power).sum()
    }
}

/// The CIE 171:2006 reference of a case.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CieReference {
    /// Section of CIE 171:2006 (e.g. "5.7", or "5.3 (extension)" for cases in its spirit).
    pub section: String,
    /// The CIE table holding its reference values.
    pub table: String,
    /// The CIE figure or geometry summary.
    #[serde(default)]
    pub figure: Option<String>,
    /// How the case differs from the CIE's.
    pub fidelity: String,
}

/// An engine feature a case needs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Feature {
    /// Lambertian area emitters (`Ke` in the MTL).
    AreaEmitters,
    /// Point lights.
    PointLights,
    /// A point light with the cosine distribution I = I₀ cos γ.
    CosinePointLightDistribution,
    /// Multiple diffuse reflection.
    Interreflection,
    /// Shadowing by objects between source and receiver.
    Occlusion,
    /// An open scene: light leaves it.
    OpenScene,
}

/// The scene files of a case, relative to its folder.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneFiles {
    /// The OBJ file.
    pub obj: String,
    /// The MTL file.
    pub mtl: String,
}

/// A point light source.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PointLight {
    /// Name.
    pub name: String,
    /// Position, m.
    pub position: [f64; 3],
    /// Isotropic intensity, or the peak (γ = 0) intensity I₀ of a cosine distribution, W·sr⁻¹.
    #[serde(rename = "intensity_W_per_sr")]
    pub intensity: f64,
    /// The shape of the intensity distribution.
    pub distribution: Distribution,
}

impl PointLight {
    /// Position, m.
    pub fn position(&self) -> DVec3 {
        DVec3::from(self.position)
    }

    /// Radiant intensity towards the unit direction `omega` (from the light), W·sr⁻¹.
    pub fn intensity_towards(&self, omega: DVec3) -> f64 {
        match self.distribution {
            Distribution::Isotropic => self.intensity,
            Distribution::Cosine { nadir } => {
                self.intensity * omega.dot(DVec3::from(nadir)).max(0.0)
            }
        }
    }

    /// Total radiant power, W: 4π I (isotropic) or π I₀ (cosine, one hemisphere).
    pub fn power(&self) -> f64 {
        match self.distribution {
            Distribution::Isotropic => 4.0 * PI * self.intensity,
            Distribution::Cosine { .. } => PI * self.intensity,
        }
    }
}

/// A point light's intensity distribution.
#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Distribution {
    /// I(ω) = I for every direction.
    Isotropic,
    /// I(ω) = I₀ max(0, ω·nadir): the CIE 171 §5.2 "diffuse" point source, I = I₀ cos γ.
    Cosine {
        /// Unit vector of γ = 0.
        nadir: [f64; 3],
    },
}

/// The closed form that gives a case's expected values.
#[derive(Debug, Clone, Deserialize)]
#[serde(tag = "name", rename_all = "snake_case", deny_unknown_fields)]
pub enum ClosedForm {
    /// E = Σ I(ω) cos θ / d² over the point lights, no occlusion (CIE 171 §5.2); group means
    /// exact from the solid angle (isotropic) or the projected solid angle (cosine).
    PointSource,
    /// E = Σ π L_e F(dA → visible part of each emitter), F by Lambert's contour formula
    /// (CIE 171 §5.3, 5.6, 5.7); group means by converged Gauss–Legendre quadrature.
    AreaSourceContour {
        /// Names of the emitting objects.
        emitters: Vec<String>,
        /// Group name of one convex occluder between the points and the emitters.
        #[serde(default)]
        occluder: Option<String>,
    },
    /// Point sources in a closed black room: point values as [`ClosedForm::PointSource`],
    /// group means I Ω / A, and Σ E_avg A = Φ (CIE 171 §5.4).
    FluxConservation,
    /// A closed box of one reflectance ρ with the cube's symmetry: every face mean is
    /// Φ / (S_T (1 − ρ)) (CIE 171 §5.8).
    ClosedCubeInterreflection,
}

/// A measurement point.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeasurementPoint {
    /// Identifier (the CIE's letter where there is one).
    pub id: String,
    /// Name of the object the point lies on.
    pub object: String,
    /// Position, m.
    pub position: [f64; 3],
    /// Unit normal of the receiving surface.
    pub normal: [f64; 3],
    /// For occlusion cases: whether the point sees all, part or none of the emitters.
    #[serde(default)]
    pub shadow: Option<Shadow>,
    /// A published value to compare the closed form with.
    #[serde(default)]
    pub crosscheck: Option<CrossCheck>,
}

/// How much of the emitters a point sees past an occluder.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Shadow {
    /// Nothing is hidden.
    Full,
    /// Part is hidden.
    Penumbra,
    /// Everything is hidden.
    Umbra,
}

/// A published reference value (CIE table, third-party validation) for comparison only: the
/// expected value is always the closed form.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CrossCheck {
    /// Where the value comes from.
    pub source: String,
    /// The value, W·m⁻² (= lx, or % for the CIE's normalised tables).
    pub value: f64,
    /// What the value is, if not the total irradiance: "reflected_part" = E − Φ/S_T.
    #[serde(default)]
    pub quantity: Option<String>,
    /// Largest accepted |closed form − value| / |value|.
    #[serde(default)]
    pub agree_within_relative: Option<f64>,
    /// Largest accepted |closed form − value|, W·m⁻².
    #[serde(default, rename = "agree_within_absolute_W_per_m2")]
    pub agree_within_absolute: Option<f64>,
}

impl CrossCheck {
    /// Whether `closed_form` agrees with the published value within the stated bound.
    pub fn agrees(&self, closed_form: f64) -> bool {
        let diff = (closed_form - self.value).abs();
        let bound = self.agree_within_relative.unwrap_or(0.0) * self.value.abs()
            + self.agree_within_absolute.unwrap_or(0.0);
        diff <= bound
    }
}

/// A group of objects whose area-weighted mean irradiance is exact.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GroupSpec {
    /// Identifier.
    pub id: String,
    /// The objects averaged over.
    pub objects: Vec<String>,
    /// A published value to compare the closed form with.
    #[serde(default)]
    pub crosscheck: Option<CrossCheck>,
}

/// The pass criterion for an engine: |E − E_expected| ≤ relative · E_expected + absolute.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Tolerance {
    /// Relative part (0.01 = 1 %).
    pub relative: f64,
    /// Absolute part, W·m⁻² (non-zero only where some expected values are exactly 0).
    #[serde(rename = "absolute_W_per_m2")]
    pub absolute: f64,
    /// Why this tolerance.
    pub why: String,
}

impl Tolerance {
    /// Whether an engine's `got` passes against `expected` (both W·m⁻²).
    pub fn allows(&self, expected: f64, got: f64) -> bool {
        got.is_finite() && (got - expected).abs() <= self.relative * expected.abs() + self.absolute
    }
}

/// The folder holding the case folders: `<crate>/tests/cie171`.
pub fn cases_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests")
        .join("cie171")
}

fn read_bounded(path: &Path) -> Result<String, Cie171Error> {
    let io = |source| Cie171Error::Io {
        path: path.to_path_buf(),
        source,
    };
    let bytes = std::fs::metadata(path).map_err(io)?.len();
    if bytes > MAX_FILE_BYTES {
        return Err(Cie171Error::TooLarge {
            path: path.to_path_buf(),
            bytes,
        });
    }
    std::fs::read_to_string(path).map_err(io)
}

/// Loads and validates the case in folder `dir` (its `case.json`).
pub fn load_case(dir: &Path) -> Result<Case, Cie171Error> {
    let path = dir.join("case.json");
    let text = read_bounded(&path)?;
    let mut case: Case = serde_json::from_str(&text).map_err(|e| Cie171Error::Json {
        path: path.clone(),
        line: e.line(),
        column: e.column(),
        message: e.to_string(),
    })?;
    case.dir = dir.to_path_buf();
    validate_case(&case, dir)?;
    Ok(case)
}

/// Every case under [`cases_dir`] (each sub-folder with a `case.json`), sorted by id.
pub fn all_cases() -> Result<Vec<Case>, Cie171Error> {
    let root = cases_dir();
    let entries = std::fs::read_dir(&root).map_err(|source| Cie171Error::Io {
        path: root.clone(),
        source,
    })?;
    let mut cases = Vec::new();
    for entry in entries {
        let entry = entry.map_err(|source| Cie171Error::Io {
            path: root.clone(),
            source,
        })?;
        let dir = entry.path();
        if dir.join("case.json").is_file() {
            cases.push(load_case(&dir)?);
        }
    }
    cases.sort_by(|a, b| a.id.cmp(&b.id));
    Ok(cases)
}

fn finite3(v: [f64; 3]) -> bool {
    v.iter().all(|c| c.is_finite())
}

fn is_unit(v: [f64; 3]) -> bool {
    finite3(v) && (DVec3::from(v).length() - 1.0).abs() <= 1e-9
}

fn validate_case(case: &Case, dir: &Path) -> Result<(), Cie171Error> {
    let id = case.id.as_str();
    let folder = dir.file_name().and_then(|n| n.to_str()).unwrap_or("");
    if id != folder {
        return Err(case_error(
            id,
            format!("id differs from its folder name {folder:?}"),
        ));
    }
    let t = &case.tolerance;
    if !(t.relative.is_finite() && t.relative >= 0.0 && t.absolute.is_finite() && t.absolute >= 0.0)
    {
        return Err(case_error(id, "tolerance must be finite and non-negative"));
    }
    for light in &case.point_lights {
        if !(finite3(light.position) && light.intensity.is_finite() && light.intensity >= 0.0) {
            return Err(case_error(
                id,
                format!(
                    "point light {}: position and intensity must be finite, intensity >= 0",
                    light.name
                ),
            ));
        }
        if let Distribution::Cosine { nadir } = light.distribution {
            if !is_unit(nadir) {
                return Err(case_error(
                    id,
                    format!("point light {}: nadir must be a unit vector", light.name),
                ));
            }
        }
    }
    let mut ids: Vec<&str> = case.points.iter().map(|p| p.id.as_str()).collect();
    ids.sort_unstable();
    if let Some(w) = ids.windows(2).find(|w| w[0] == w[1]) {
        return Err(case_error(id, format!("point id {} appears twice", w[0])));
    }
    for p in &case.points {
        if !finite3(p.position) || !is_unit(p.normal) {
            return Err(case_error(
                id,
                format!(
                    "point {}: position must be finite and normal a unit vector",
                    p.id
                ),
            ));
        }
    }
    match &case.closed_form {
        ClosedForm::PointSource | ClosedForm::FluxConservation if case.point_lights.is_empty() => {
            Err(case_error(
                id,
                "the point-source closed forms need at least one point light",
            ))
        }
        ClosedForm::AreaSourceContour { emitters, .. } if emitters.is_empty() => Err(case_error(
            id,
            "area_source_contour needs at least one emitter",
        )),
        ClosedForm::ClosedCubeInterreflection if !case.points.is_empty() => Err(case_error(
            id,
            "closed_cube_interreflection has no exact point values; list only groups",
        )),
        _ => Ok(()),
    }
}

// ---------------------------------------------------------------------------------------------
// scene.obj / scene.mtl
// ---------------------------------------------------------------------------------------------

/// One polygon of a case's scene.
#[derive(Debug, Clone)]
pub struct Object {
    /// Its `o` name.
    pub name: String,
    /// Its `g` group.
    pub group: String,
    /// Its material name.
    pub material: String,
    /// Vertices, counter-clockwise seen from the front, m.
    pub vertices: Vec<DVec3>,
    /// Diffuse reflectance ρ (grey).
    pub reflectance: f64,
    /// Emitted radiance L_e, W·m⁻²·sr⁻¹ (grey, Lambertian, front side).
    pub emitted_radiance: f64,
}

impl Object {
    /// Unit normal of the front side (Newell's method).
    pub fn normal(&self) -> DVec3 {
        polygon_normal(&self.vertices)
    }

    /// Area, m².
    pub fn area(&self) -> f64 {
        polygon_area(&self.vertices)
    }

    /// Emitted exitance M_e = π L_e, W·m⁻².
    pub fn exitance(&self) -> f64 {
        PI * self.emitted_radiance
    }
}

/// A case's scene geometry: its polygons with their materials.
#[derive(Debug, Clone)]
pub struct Geometry {
    /// The polygons, in file order.
    pub objects: Vec<Object>,
}

impl Geometry {
    /// The object named `name`.
    pub fn object(&self, name: &str) -> Option<&Object> {
        self.objects.iter().find(|o| o.name == name)
    }

    /// The objects of group `group`.
    pub fn group(&self, group: &str) -> Vec<&Object> {
        self.objects.iter().filter(|o| o.group == group).collect()
    }

    /// Total area of all objects, m².
    pub fn total_area(&self) -> f64 {
        self.objects.iter().map(Object::area).sum()
    }

    /// Total power emitted by the area emitters, Σ π L_e A, W.
    pub fn emitted_power(&self) -> f64 {
        self.objects.iter().map(|o| o.exitance() * o.area()).sum()
    }
}

fn parse_f64(tok: Option<&str>, path: &Path, line: usize, what: &str) -> Result<f64, Cie171Error> {
    let scene_err = |message: String| Cie171Error::Scene {
        path: path.to_path_buf(),
        line,
        message,
    };
    let tok = tok.ok_or_else(|| scene_err(format!("{what}: missing number")))?;
    let v: f64 = tok
        .parse()
        .map_err(|_| scene_err(format!("{what}: {tok:?} is not a number")))?;
    if v.is_finite() {
        Ok(v)
    } else {
        Err(scene_err(format!("{what}: {tok:?} is not finite")))
    }
}

/// (reflectance, emitted radiance) per material name.
fn parse_mtl(path: &Path) -> Result<Vec<(String, f64, f64)>, Cie171Error> {
    let text = read_bounded(path)?;
    let mut materials: Vec<(String, f64, f64)> = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let mut tok = raw.split_whitespace();
        let Some(key) = tok.next() else { continue };
        let err = |message: String| Cie171Error::Scene {
            path: path.to_path_buf(),
            line,
            message,
        };
        match key {
            "newmtl" => {
                let name = tok
                    .next()
                    .ok_or_else(|| err("newmtl without a name".into()))?;
                materials.push((name.to_string(), 0.0, 0.0));
            }
            "Kd" | "Ke" => {
                let rgb = [
                    parse_f64(tok.next(), path, line, key)?,
                    parse_f64(tok.next(), path, line, key)?,
                    parse_f64(tok.next(), path, line, key)?,
                ];
                if rgb[0] != rgb[1] || rgb[1] != rgb[2] {
                    return Err(err(format!(
                        "{key}: the closed forms need grey values, got {rgb:?}"
                    )));
                }
                let valid = if key == "Kd" {
                    (0.0..1.0).contains(&rgb[0])
                } else {
                    rgb[0] >= 0.0
                };
                if !valid {
                    return Err(err(format!(
                        "{key} {} is out of range (Kd in [0, 1), Ke >= 0)",
                        rgb[0]
                    )));
                }
                let m = materials
                    .last_mut()
                    .ok_or_else(|| err(format!("{key} before any newmtl")))?;
                if key == "Kd" {
                    m.1 = rgb[0];
                } else {
                    m.2 = rgb[0];
                }
            }
            _ => {}
        }
    }
    Ok(materials)
}

/// Reads a case's `scene.obj` and `scene.mtl`: one convex planar polygon per `o`.
pub fn load_geometry(case: &Case) -> Result<Geometry, Cie171Error> {
    let materials = parse_mtl(&case.mtl_path())?;
    let path = case.obj_path();
    let text = read_bounded(&path)?;
    let mut vertices: Vec<DVec3> = Vec::new();
    let mut objects: Vec<Object> = Vec::new();
    let (mut group, mut material) = (String::from("default"), None::<String>);
    let mut current: Option<(String, usize)> = None;
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let err = |message: String| Cie171Error::Scene {
            path: path.clone(),
            line,
            message,
        };
        let mut tok = raw.split_whitespace();
        let Some(key) = tok.next() else { continue };
        match key {
            "v" => vertices.push(DVec3::new(
                parse_f64(tok.next(), &path, line, "v")?,
                parse_f64(tok.next(), &path, line, "v")?,
                parse_f64(tok.next(), &path, line, "v")?,
            )),
            "g" => group = tok.next().unwrap_or("default").to_string(),
            "o" => {
                let name = tok.next().ok_or_else(|| err("o without a name".into()))?;
                if let Some((prev, _)) = &current {
                    if objects.last().is_none_or(|o| &o.name != prev) {
                        return Err(err(format!("object {prev} has no face")));
                    }
                }
                if objects.iter().any(|o| o.name == name) {
                    return Err(err(format!("object {name} defined twice")));
                }
                current = Some((name.to_string(), line));
            }
            "usemtl" => {
                material = Some(
                    tok.next()
                        .ok_or_else(|| err("usemtl without a name".into()))?
                        .to_string(),
                )
            }
            "f" => {
                let (name, _) = current
                    .as_ref()
                    .ok_or_else(|| err("face before any o".into()))?;
                if objects.last().is_some_and(|o| &o.name == name) {
                    return Err(err(format!(
                        "object {name} has a second face (one polygon per o)"
                    )));
                }
                let mname = material
                    .clone()
                    .ok_or_else(|| err("face before any usemtl".into()))?;
                let &(_, rho, le) = materials
                    .iter()
                    .find(|m| m.0 == mname)
                    .ok_or_else(|| err(format!("material {mname} is not in {}", case.scene.mtl)))?;
                let mut poly = Vec::new();
                for t in tok {
                    let idx_text = t.split('/').next().unwrap_or("");
                    let idx: i64 = idx_text
                        .parse()
                        .map_err(|_| err(format!("face index {t:?} is not an integer")))?;
                    let n = vertices.len() as i64;
                    let k = if idx > 0 { idx - 1 } else { n + idx };
                    if idx == 0 || k < 0 || k >= n {
                        return Err(err(format!(
                            "face refers to vertex {idx}, file has {n} so far"
                        )));
                    }
                    poly.push(vertices[k as usize]);
                }
                check_polygon(&poly).map_err(|m| err(format!("object {name}: {m}")))?;
                objects.push(Object {
                    name: name.clone(),
                    group: group.clone(),
                    material: mname,
                    vertices: poly,
                    reflectance: rho,
                    emitted_radiance: le,
                });
            }
            _ => {}
        }
    }
    if let Some((name, line)) = current {
        if objects.last().is_none_or(|o| o.name != name) {
            return Err(Cie171Error::Scene {
                path,
                line,
                message: format!("object {name} has no face"),
            });
        }
    }
    let geometry = Geometry { objects };
    check_references(case, &geometry)?;
    Ok(geometry)
}

/// A polygon usable by the closed forms: ≥ 3 vertices, non-degenerate, planar, convex.
fn check_polygon(poly: &[DVec3]) -> Result<(), String> {
    if poly.len() < 3 {
        return Err(format!("{} vertices, need at least 3", poly.len()));
    }
    let area = polygon_area(poly);
    let size = poly
        .iter()
        .map(|p| (*p - poly[0]).length())
        .fold(0.0, f64::max);
    if area.is_nan() || area <= GEOMETRY_EPS * size * size {
        return Err("degenerate (zero area)".into());
    }
    let n = polygon_normal(poly);
    for p in poly {
        if (*p - poly[0]).dot(n).abs() > GEOMETRY_EPS * size {
            return Err("not planar".into());
        }
    }
    for i in 0..poly.len() {
        let (a, b, c) = (
            poly[i],
            poly[(i + 1) % poly.len()],
            poly[(i + 2) % poly.len()],
        );
        if (b - a).cross(c - b).dot(n) < -GEOMETRY_EPS * size * size {
            return Err("not convex".into());
        }
    }
    Ok(())
}

fn check_references(case: &Case, g: &Geometry) -> Result<(), Cie171Error> {
    let id = case.id.as_str();
    let has = |name: &str| g.object(name).is_some();
    for p in &case.points {
        if !has(&p.object) {
            return Err(case_error(
                id,
                format!(
                    "point {} lies on {}, which is not in the scene",
                    p.id, p.object
                ),
            ));
        }
    }
    for grp in &case.groups {
        if grp.objects.is_empty() {
            return Err(case_error(id, format!("group {} lists no objects", grp.id)));
        }
        if let Some(o) = grp.objects.iter().find(|o| !has(o)) {
            return Err(case_error(
                id,
                format!("group {} names {o}, which is not in the scene", grp.id),
            ));
        }
    }
    if let ClosedForm::AreaSourceContour { emitters, occluder } = &case.closed_form {
        for e in emitters {
            match g.object(e) {
                None => return Err(case_error(id, format!("emitter {e} is not in the scene"))),
                Some(o) if o.emitted_radiance <= 0.0 => {
                    return Err(case_error(id, format!("emitter {e} has no Ke")))
                }
                _ => {}
            }
        }
        if let Some(name) = occluder {
            if g.group(name).is_empty() {
                return Err(case_error(
                    id,
                    format!("occluder group {name} is not in the scene"),
                ));
            }
        }
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Polygon geometry
// ---------------------------------------------------------------------------------------------

/// Unit normal of a planar polygon by Newell's method (front side seen counter-clockwise).
pub fn polygon_normal(poly: &[DVec3]) -> DVec3 {
    newell(poly).normalize_or_zero()
}

fn newell(poly: &[DVec3]) -> DVec3 {
    (0..poly.len())
        .map(|i| poly[i].cross(poly[(i + 1) % poly.len()]))
        .sum()
}

/// Area of a planar polygon, ½ |Σ vᵢ × vᵢ₊₁|, m².
pub fn polygon_area(poly: &[DVec3]) -> f64 {
    0.5 * newell(poly).length()
}

/// The part of a polygon on the front side of the plane through `x` with normal `n`
/// (n·(p − x) ≥ 0), by one Sutherland–Hodgman pass (Sutherland & Hodgman 1974).
pub fn clip_to_half_space(poly: &[DVec3], x: DVec3, n: DVec3) -> Vec<DVec3> {
    let mut out = Vec::with_capacity(poly.len() + 1);
    for i in 0..poly.len() {
        let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
        let (da, db) = ((a - x).dot(n), (b - x).dot(n));
        if da >= 0.0 {
            out.push(a);
        }
        if (da >= 0.0) != (db >= 0.0) {
            out.push(a + (b - a) * (da / (da - db)));
        }
    }
    out
}

/// Form factor from a differential area at `x` with unit normal `n` to a polygon, by Lambert's
/// contour formula (Lambert 1760; e.g. Baum, Rushmeier & Winget 1989, eq. 2):
///
///   F = (1/2π) |Σᵢ γᵢ n·(Rᵢ × Rᵢ₊₁) / |Rᵢ × Rᵢ₊₁||,  Rᵢ = vᵢ − x,  γᵢ = ∠(Rᵢ, Rᵢ₊₁).
///
/// The polygon is first clipped to the half-space in front of `x` (the formula holds only for
/// a polygon wholly above the receiver's tangent plane). Dimensionless; no visibility.
pub fn point_to_polygon_form_factor(x: DVec3, n: DVec3, poly: &[DVec3]) -> f64 {
    let p = clip_to_half_space(poly, x, n);
    if p.len() < 3 {
        return 0.0;
    }
    let mut sum = 0.0;
    for i in 0..p.len() {
        let (r1, r2) = (p[i] - x, p[(i + 1) % p.len()] - x);
        let c = r1.cross(r2);
        let len = c.length();
        // An edge seen end-on (or through x) subtends no angle.
        if len <= 1e-300 {
            continue;
        }
        let gamma = len.atan2(r1.dot(r2));
        sum += gamma * n.dot(c) / len;
    }
    (sum / (2.0 * PI)).abs()
}

/// Irradiance at `x` (normal `n`) from a Lambertian emitter polygon of radiance `radiance`
/// (W·m⁻²·sr⁻¹), front side only, no occlusion: E = π L_e F(dA → polygon), W·m⁻².
pub fn emitter_irradiance(x: DVec3, n: DVec3, emitter: &[DVec3], radiance: f64) -> f64 {
    if !in_front_of(emitter, x) {
        return 0.0;
    }
    PI * radiance * point_to_polygon_form_factor(x, n, emitter)
}

/// Whether `x` lies strictly on the front side of the polygon's plane (by more than 1e-12 of
/// the polygon's size: points on the plane receive nothing from a one-sided emitter).
fn in_front_of(poly: &[DVec3], x: DVec3) -> bool {
    let size = poly
        .iter()
        .map(|p| (*p - poly[0]).length())
        .fold(0.0, f64::max);
    (x - poly[0]).dot(polygon_normal(poly)) > 1e-12 * size
}

/// Irradiance at `x` (unit normal `n`) from a point light with no occlusion (CIE 171:2006
/// §5.2): E = I(ω) max(0, cos θ) / d², ω the direction from the light to `x`, W·m⁻².
pub fn point_light_irradiance(light: &PointLight, x: DVec3, n: DVec3) -> f64 {
    let to_light = light.position() - x;
    let d2 = to_light.length_squared();
    if d2 == 0.0 {
        return 0.0;
    }
    let d = d2.sqrt();
    let cos_theta = n.dot(to_light) / d;
    if cos_theta <= 0.0 {
        return 0.0;
    }
    light.intensity_towards(-to_light / d) * cos_theta / d2
}

/// Solid angle of triangle (a, b, c) seen from `x`, by Van Oosterom & Strackee (1983):
/// tan(Ω/2) = |a·(b×c)| / (abc + (a·b)c + (a·c)b + (b·c)a), vectors from `x`; sr.
pub fn solid_angle_triangle(x: DVec3, a: DVec3, b: DVec3, c: DVec3) -> f64 {
    let (a, b, c) = (a - x, b - x, c - x);
    let (la, lb, lc) = (a.length(), b.length(), c.length());
    let num = a.dot(b.cross(c)).abs();
    let den = la * lb * lc + a.dot(b) * lc + a.dot(c) * lb + b.dot(c) * la;
    2.0 * num.atan2(den)
}

/// Solid angle of a convex polygon seen from `x` (a fan of Van Oosterom–Strackee triangles),
/// sr.
pub fn solid_angle_polygon(x: DVec3, poly: &[DVec3]) -> f64 {
    (1..poly.len() - 1)
        .map(|i| solid_angle_triangle(x, poly[0], poly[i], poly[i + 1]))
        .sum()
}

/// Radiant flux from a point light onto the front of a convex polygon, no occlusion, W:
/// I Ω (isotropic) or I₀ π F(dA_light(nadir) → polygon) (cosine: ∫ max(0, cos γ) dω over the
/// polygon is π times the form factor from a differential area facing the nadir, Lambert's
/// contour formula again).
pub fn point_light_flux_on_polygon(light: &PointLight, poly: &[DVec3]) -> f64 {
    let s = light.position();
    if !in_front_of(poly, s) {
        return 0.0;
    }
    match light.distribution {
        Distribution::Isotropic => light.intensity * solid_angle_polygon(s, poly),
        Distribution::Cosine { nadir } => {
            light.intensity * PI * point_to_polygon_form_factor(s, DVec3::from(nadir), poly)
        }
    }
}

/// Mean irradiance of a closed box with one reflectance ρ on every surface and the cube's
/// symmetry, per face (CIE 171:2006 §5.8): the flux balance Σ A_i (1 − ρ) E_i = Φ with equal
/// face means gives E_face = Φ / (S_T (1 − ρ)); `power` Φ in W, `total_area` S_T in m²;
/// W·m⁻². The CIE's internal reflected component is the part ρΦ / (S_T (1 − ρ)).
pub fn closed_cube_mean_irradiance(power: f64, total_area: f64, rho: f64) -> f64 {
    power / (total_area * (1.0 - rho))
}

// ---------------------------------------------------------------------------------------------
// Aligned rectangles: catalogue formulas by superposition (independent of the contour code)
// ---------------------------------------------------------------------------------------------

/// Form factor from a differential area to a parallel a × b rectangle at distance c whose
/// corner lies on the element's normal (Howell's catalogue B-3; Hamilton & Morgan 1952):
/// X = a/c, Y = b/c,
/// F = (1/2π) [X/√(1+X²) atan(Y/√(1+X²)) + Y/√(1+Y²) atan(X/√(1+Y²))].
pub fn parallel_rectangle_corner(a: f64, b: f64, c: f64) -> f64 {
    let (x, y) = (a / c, b / c);
    let (sx, sy) = ((1.0 + x * x).sqrt(), (1.0 + y * y).sqrt());
    (x / sx * (y / sx).atan() + y / sy * (x / sy).atan()) / (2.0 * PI)
}

/// Form factor from a differential area to an a × b rectangle in a perpendicular plane at
/// distance l, the rectangle's corner in the element's plane on the line through the element
/// normal to the rectangle's plane, side b along the element's normal (Hamilton & Morgan
/// 1952; Howell's catalogue, element to perpendicular rectangle): X = a/l, Y = b/l,
/// F = (1/2π) [atan X − atan(X/√(1+Y²)) / √(1+Y²)].
pub fn perpendicular_rectangle_corner(a: f64, b: f64, l: f64) -> f64 {
    let (x, y) = (a / l, b / l);
    let sy = (1.0 + y * y).sqrt();
    (x.atan() - (x / sy).atan() / sy) / (2.0 * PI)
}

/// Form factor from a differential area at `x` with an axis-aligned unit normal `n` to an
/// axis-aligned rectangle, by superposition of the corner formulas ([`parallel_rectangle_corner`],
/// [`perpendicular_rectangle_corner`]) extended as odd functions of the signed offsets; the
/// part of the rectangle behind the element's plane is cut off. `None` if `n` or the
/// rectangle is not axis-aligned.
pub fn aligned_rectangle_form_factor(x: DVec3, n: DVec3, rect: &[DVec3]) -> Option<f64> {
    let axis_of = |v: DVec3| (0..3).find(|&k| (v[k].abs() - 1.0).abs() < 1e-12);
    let q = axis_of(n)?;
    let sign = n[q].signum();
    let p = axis_of(polygon_normal(rect))?;
    if rect.len() != 4 {
        return None;
    }
    let lo = rect
        .iter()
        .fold(DVec3::splat(f64::INFINITY), |m, v| m.min(*v));
    let hi = rect
        .iter()
        .fold(DVec3::splat(f64::NEG_INFINITY), |m, v| m.max(*v));
    // Every vertex at a corner of the bounding box: an axis-aligned rectangle.
    let on_corner = |v: &DVec3| (0..3).all(|k| v[k] == lo[k] || v[k] == hi[k]);
    if !rect.iter().all(on_corner) {
        return None;
    }
    // The corner formulas extended as odd functions of the signed offsets (superposition of
    // the four corner rectangles, Howell's form-factor algebra).
    let signed = |s: f64, t: f64, f: &dyn Fn(f64, f64) -> f64| {
        if s == 0.0 || t == 0.0 {
            0.0
        } else {
            s.signum() * t.signum() * f(s.abs(), t.abs())
        }
    };
    if p == q {
        let c = (lo[p] - x[p]) * sign;
        if c <= 0.0 {
            return Some(0.0);
        }
        let (u, w) = ((q + 1) % 3, (q + 2) % 3);
        let f = |s: f64, t: f64| signed(s, t, &|a, b| parallel_rectangle_corner(a, b, c));
        let (u0, u1, w0, w1) = (lo[u] - x[u], hi[u] - x[u], lo[w] - x[w], hi[w] - x[w]);
        Some(f(u1, w1) - f(u0, w1) - f(u1, w0) + f(u0, w0))
    } else {
        let l = (lo[p] - x[p]).abs();
        if l == 0.0 {
            return Some(0.0);
        }
        let r = 3 - p - q;
        // Heights along the normal, the part below the element's plane cut off.
        let (a, b) = ((lo[q] - x[q]) * sign, (hi[q] - x[q]) * sign);
        let (h0, h1) = (a.min(b).max(0.0), a.max(b).max(0.0));
        let g = |s: f64, h: f64| signed(s, h, &|a, b| perpendicular_rectangle_corner(a, b, l));
        let (s0, s1) = (lo[r] - x[r], hi[r] - x[r]);
        Some(g(s1, h1) - g(s0, h1) - g(s1, h0) + g(s0, h0))
    }
}

// ---------------------------------------------------------------------------------------------
// Occlusion by a convex object: the emitter minus the central projection of the occluder
// ---------------------------------------------------------------------------------------------

/// An orthonormal basis (u, v) of the plane with unit normal `m`, with u × v = m.
fn plane_basis(m: DVec3) -> (DVec3, DVec3) {
    let helper = if m.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
    let u = (helper - m * helper.dot(m)).normalize();
    (u, m.cross(u))
}

fn cross2(o: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
}

/// Convex hull of 2-D points, counter-clockwise, collinear points dropped (Andrew's monotone
/// chain, Andrew 1979). Fewer than 3 points if the points are collinear.
pub fn convex_hull_2d(points: &[[f64; 2]]) -> Vec<[f64; 2]> {
    let mut pts: Vec<[f64; 2]> = points.to_vec();
    pts.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    pts.dedup();
    if pts.len() < 3 {
        return pts;
    }
    let mut hull: Vec<[f64; 2]> = Vec::with_capacity(2 * pts.len());
    for pass in 0..2 {
        let start = hull.len();
        let iter: Box<dyn Iterator<Item = &[f64; 2]>> = if pass == 0 {
            Box::new(pts.iter())
        } else {
            Box::new(pts.iter().rev())
        };
        for &p in iter {
            while hull.len() >= start + 2
                && cross2(hull[hull.len() - 2], hull[hull.len() - 1], p) <= 0.0
            {
                hull.pop();
            }
            hull.push(p);
        }
        hull.pop();
    }
    hull
}

/// Intersection of two convex 2-D polygons (Sutherland & Hodgman 1974: the subject clipped by
/// each edge of `clip`); both counter-clockwise.
pub fn convex_intersection_2d(subject: &[[f64; 2]], clip: &[[f64; 2]]) -> Vec<[f64; 2]> {
    let mut out = subject.to_vec();
    for i in 0..clip.len() {
        if out.is_empty() {
            break;
        }
        let (a, b) = (clip[i], clip[(i + 1) % clip.len()]);
        let input = std::mem::take(&mut out);
        for j in 0..input.len() {
            let (p, q) = (input[j], input[(j + 1) % input.len()]);
            let (dp, dq) = (cross2(a, b, p), cross2(a, b, q));
            if dp >= 0.0 {
                out.push(p);
            }
            if (dp >= 0.0) != (dq >= 0.0) {
                let t = dp / (dp - dq);
                out.push([p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])]);
            }
        }
    }
    out
}

/// The part of `emitter`'s plane hidden from `x` by a convex occluder with vertices
/// `occluder`, intersected with the emitter: the emitter ∩ convex hull of the central
/// projections of the occluder's vertices onto the emitter's plane (a convex solid between
/// the point and the plane projects onto the hull of its projected vertices). `Ok(vec![])` if
/// nothing is hidden; [`Cie171Error::Occluder`] if the occluder straddles the emitter's plane
/// or the plane through `x` parallel to it (the construction then does not hold).
pub fn hidden_part_of_emitter(
    x: DVec3,
    emitter: &[DVec3],
    occluder: &[DVec3],
) -> Result<Vec<DVec3>, Cie171Error> {
    let occluder_error = |message: String| Cie171Error::Occluder { point: x, message };
    let m = polygon_normal(emitter);
    let o = emitter[0];
    let hx = (x - o).dot(m);
    if hx <= 0.0 {
        return Err(occluder_error(
            "the point is not in front of the emitter".into(),
        ));
    }
    let size = emitter.iter().map(|p| (*p - o).length()).fold(hx, f64::max);
    let eps = 1e-12 * size;
    let heights: Vec<f64> = occluder.iter().map(|p| (*p - o).dot(m)).collect();
    let between = |h: f64| h > eps && h < hx - eps;
    if heights.iter().all(|&h| h <= eps) || heights.iter().all(|&h| h >= hx - eps) {
        return Ok(Vec::new());
    }
    if !heights.iter().all(|&h| between(h)) {
        return Err(occluder_error(format!(
            "the occluder straddles the emitter's plane or the point's (heights {:.3}..{:.3} m, point at {hx:.3} m)",
            heights.iter().copied().fold(f64::INFINITY, f64::min),
            heights.iter().copied().fold(f64::NEG_INFINITY, f64::max)
        )));
    }
    let (u, v) = plane_basis(m);
    let to2 = |p: DVec3| [(p - o).dot(u), (p - o).dot(v)];
    let projected: Vec<[f64; 2]> = occluder
        .iter()
        .zip(&heights)
        .map(|(p, &h)| to2(x + (*p - x) * (hx / (hx - h))))
        .collect();
    let hull = convex_hull_2d(&projected);
    if hull.len() < 3 {
        return Ok(Vec::new());
    }
    let mut subject: Vec<[f64; 2]> = emitter.iter().map(|p| to2(*p)).collect();
    // Counter-clockwise in (u, v) (u × v = m and the emitter is counter-clockwise about m).
    let signed: f64 = (0..subject.len())
        .map(|i| cross2([0.0, 0.0], subject[i], subject[(i + 1) % subject.len()]))
        .sum();
    if signed < 0.0 {
        subject.reverse();
    }
    let inter = convex_intersection_2d(&subject, &hull);
    Ok(inter.iter().map(|q| o + u * q[0] + v * q[1]).collect())
}

/// Form factor from a differential area at `x` (normal `n`) to the part of `emitter` not hidden
/// by a convex occluder: F(emitter) − F(emitter ∩ projected occluder) (both by Lambert's contour
/// formula; F is additive over disjoint parts, also after the horizon clip).
pub fn visible_form_factor(
    x: DVec3,
    n: DVec3,
    emitter: &[DVec3],
    occluder: &[DVec3],
) -> Result<f64, Cie171Error> {
    let full = point_to_polygon_form_factor(x, n, emitter);
    let hidden = hidden_part_of_emitter(x, emitter, occluder)?;
    let blocked = if hidden.len() >= 3 {
        point_to_polygon_form_factor(x, n, &hidden)
    } else {
        0.0
    };
    Ok((full - blocked).max(0.0))
}

// ---------------------------------------------------------------------------------------------
// Quadrature over a receiver (group means of area-source cases)
// ---------------------------------------------------------------------------------------------

/// Nodes and weights of the n-point Gauss–Legendre rule on [0, 1] (Newton iteration on the
/// Legendre polynomial from Tricomi's initial guesses; Golub & Welsch give the same nodes).
pub fn gauss_legendre_01(n: usize) -> Vec<(f64, f64)> {
    let mut rule = Vec::with_capacity(n);
    for i in 0..n {
        let mut z = (PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
        let mut dp;
        let mut iterations = 0;
        loop {
            // P_n(z) by the three-term recurrence, and its derivative.
            let (mut p1, mut p2) = (1.0, 0.0);
            for j in 1..=n {
                let p3 = p2;
                p2 = p1;
                p1 = ((2 * j - 1) as f64 * z * p2 - (j - 1) as f64 * p3) / j as f64;
            }
            dp = n as f64 * (z * p1 - p2) / (z * z - 1.0);
            let dz = p1 / dp;
            z -= dz;
            iterations += 1;
            if dz.abs() <= 1e-15 || iterations >= 100 {
                break;
            }
        }
        rule.push(((1.0 - z) / 2.0, 1.0 / ((1.0 - z * z) * dp * dp)));
    }
    rule
}

/// Area-weighted mean of `f` over a triangle or convex quadrilateral, by an n × n
/// Gauss–Legendre product rule on each of `panels × panels` sub-squares of the bilinear
/// parameter square (a triangle as a quadrilateral with two equal vertices: the Duffy map).
/// W·m⁻² when `f` is an irradiance.
pub fn polygon_mean(
    poly: &[DVec3],
    panels: usize,
    n: usize,
    f: &mut dyn FnMut(DVec3) -> f64,
) -> f64 {
    let q = match poly.len() {
        3 => [poly[0], poly[1], poly[2], poly[2]],
        4 => [poly[0], poly[1], poly[2], poly[3]],
        _ => return f64::NAN,
    };
    let rule = gauss_legendre_01(n);
    let (mut sum, mut area) = (0.0, 0.0);
    let h = 1.0 / panels as f64;
    for pi in 0..panels {
        for pj in 0..panels {
            for &(s, ws) in &rule {
                for &(t, wt) in &rule {
                    let (u, v) = ((pi as f64 + s) * h, (pj as f64 + t) * h);
                    let p = q[0] * ((1.0 - u) * (1.0 - v))
                        + q[1] * (u * (1.0 - v))
                        + q[2] * (u * v)
                        + q[3] * ((1.0 - u) * v);
                    let du = (q[1] - q[0]) * (1.0 - v) + (q[2] - q[3]) * v;
                    let dv = (q[3] - q[0]) * (1.0 - u) + (q[2] - q[1]) * u;
                    let w = ws * wt * h * h * du.cross(dv).length();
                    sum += w * f(p);
                    area += w;
                }
            }
        }
    }
    sum / area
}

// ---------------------------------------------------------------------------------------------
// Expected values per case
// ---------------------------------------------------------------------------------------------

/// An expected irradiance at a measurement point.
#[derive(Debug, Clone)]
pub struct ExpectedPoint {
    /// Point id.
    pub id: String,
    /// Object the point lies on.
    pub object: String,
    /// Position, m.
    pub position: DVec3,
    /// Unit normal.
    pub normal: DVec3,
    /// Expected irradiance, W·m⁻².
    pub irradiance: f64,
}

/// An expected area-weighted mean irradiance over a group of objects.
#[derive(Debug, Clone)]
pub struct ExpectedGroup {
    /// Group id.
    pub id: String,
    /// The objects averaged over.
    pub objects: Vec<String>,
    /// Their total area, m².
    pub area: f64,
    /// Expected mean irradiance Σ E_i A_i / Σ A_i, W·m⁻².
    pub irradiance: f64,
}

/// Everything an engine test compares with, for one case.
#[derive(Debug, Clone)]
pub struct Expectations {
    /// Point values.
    pub points: Vec<ExpectedPoint>,
    /// Exact group means.
    pub groups: Vec<ExpectedGroup>,
    /// The pass criterion.
    pub tolerance: Tolerance,
}

/// Quadrature resolution for the group means of area-source cases: 8 × 8 panels of a
/// 10-point Gauss–Legendre rule (6400 points per receiver polygon). Converged to ≲ 1e-11
/// relative on every case here; the test `group_means_are_converged` compares it with twice
/// the panels.
pub const GROUP_PANELS: usize = 8;
/// Gauss–Legendre order per panel, see [`GROUP_PANELS`].
pub const GROUP_ORDER: usize = 10;

/// The irradiance at `x` (normal `n`) of a case's closed form, W·m⁻² (geometry from
/// [`load_geometry`]).
pub fn closed_form_irradiance(
    case: &Case,
    geometry: &Geometry,
    x: DVec3,
    n: DVec3,
) -> Result<f64, Cie171Error> {
    match &case.closed_form {
        ClosedForm::PointSource | ClosedForm::FluxConservation => Ok(case
            .point_lights
            .iter()
            .map(|l| point_light_irradiance(l, x, n))
            .sum()),
        ClosedForm::AreaSourceContour { emitters, occluder } => {
            let occ: Vec<DVec3> = occluder
                .as_ref()
                .map(|g| {
                    geometry
                        .group(g)
                        .iter()
                        .flat_map(|o| o.vertices.clone())
                        .collect()
                })
                .unwrap_or_default();
            let mut e = 0.0;
            for name in emitters {
                let em = geometry.object(name).ok_or_else(|| {
                    case_error(&case.id, format!("emitter {name} is not in the scene"))
                })?;
                if !in_front_of(&em.vertices, x) {
                    continue;
                }
                let f = if occ.is_empty() {
                    point_to_polygon_form_factor(x, n, &em.vertices)
                } else {
                    visible_form_factor(x, n, &em.vertices, &occ)
                        .map_err(|e| case_error(&case.id, format!("emitter {name}: {e}")))?
                };
                e += em.exitance() * f;
            }
            Ok(e)
        }
        ClosedForm::ClosedCubeInterreflection => Err(case_error(
            &case.id,
            "closed_cube_interreflection has no point values (only face means are exact)",
        )),
    }
}

/// The uniform reflectance of a closed-cube case, or an error naming the odd object.
fn uniform_reflectance(case: &Case, g: &Geometry) -> Result<f64, Cie171Error> {
    let rho = g.objects.first().map(|o| o.reflectance).unwrap_or(0.0);
    if let Some(o) = g.objects.iter().find(|o| o.reflectance != rho) {
        return Err(case_error(
            &case.id,
            format!(
                "closed_cube_interreflection needs one reflectance; {} has {} (others {rho})",
                o.name, o.reflectance
            ),
        ));
    }
    Ok(rho)
}

/// The exact mean irradiance over a group, W·m⁻².
pub fn closed_form_group_mean(
    case: &Case,
    geometry: &Geometry,
    objects: &[String],
    panels: usize,
    order: usize,
) -> Result<f64, Cie171Error> {
    let objs: Vec<&Object> = objects
        .iter()
        .map(|n| {
            geometry
                .object(n)
                .ok_or_else(|| case_error(&case.id, format!("{n} is not in the scene")))
        })
        .collect::<Result<_, _>>()?;
    let area: f64 = objs.iter().map(|o| o.area()).sum();
    match &case.closed_form {
        ClosedForm::PointSource | ClosedForm::FluxConservation => {
            let flux: f64 = objs
                .iter()
                .flat_map(|o| {
                    case.point_lights
                        .iter()
                        .map(|l| point_light_flux_on_polygon(l, &o.vertices))
                })
                .sum();
            Ok(flux / area)
        }
        ClosedForm::AreaSourceContour { .. } => {
            let mut weighted = 0.0;
            for o in &objs {
                let n = o.normal();
                let mut err = None;
                let mean = polygon_mean(&o.vertices, panels, order, &mut |p| {
                    closed_form_irradiance(case, geometry, p, n).unwrap_or_else(|e| {
                        err = Some(e.to_string());
                        f64::NAN
                    })
                });
                if !mean.is_finite() {
                    return Err(case_error(
                        &case.id,
                        format!(
                            "mean over {}: {}",
                            o.name,
                            err.unwrap_or_else(|| "needs 3 or 4 vertices".into())
                        ),
                    ));
                }
                weighted += mean * o.area();
            }
            Ok(weighted / area)
        }
        ClosedForm::ClosedCubeInterreflection => {
            let rho = uniform_reflectance(case, geometry)?;
            let power = case.point_light_power() + geometry.emitted_power();
            Ok(closed_cube_mean_irradiance(
                power,
                geometry.total_area(),
                rho,
            ))
        }
    }
}

/// All expected values of a case: its points (closed form) and exact group means, with the
/// pass tolerance. This is what an engine test compares its sensor irradiance with.
pub fn expectations(case: &Case) -> Result<Expectations, Cie171Error> {
    let geometry = load_geometry(case)?;
    let mut points = Vec::with_capacity(case.points.len());
    for p in &case.points {
        let (x, n) = (DVec3::from(p.position), DVec3::from(p.normal));
        points.push(ExpectedPoint {
            id: p.id.clone(),
            object: p.object.clone(),
            position: x,
            normal: n,
            irradiance: closed_form_irradiance(case, &geometry, x, n)?,
        });
    }
    let mut groups = Vec::with_capacity(case.groups.len());
    for g in &case.groups {
        groups.push(ExpectedGroup {
            id: g.id.clone(),
            objects: g.objects.clone(),
            area: g
                .objects
                .iter()
                .filter_map(|o| geometry.object(o))
                .map(Object::area)
                .sum(),
            irradiance: closed_form_group_mean(
                case,
                &geometry,
                &g.objects,
                GROUP_PANELS,
                GROUP_ORDER,
            )?,
        });
    }
    Ok(Expectations {
        points,
        groups,
        tolerance: case.tolerance.clone(),
    })
}
