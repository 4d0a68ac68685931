//! Wavefront OBJ + MTL input.
//!
//! The mapping onto the scene model:
//! - every face (`f`) becomes one or more [`Surface`]s: [`split_into_convex`] passes planar
//!   convex faces through unchanged, splits a non-planar quad into two triangles and ear-clips a
//!   planar non-convex face; faces are never triangulated otherwise;
//! - a surface's `object` is the current `o` name, else the current `g` name, else
//!   `object_N`; its `group` is the current `g` name (empty if none);
//! - in the MTL, `Kd` is the diffuse reflectance ρ (required, each channel ≥ 0) and `Ke`
//!   the emitted radiance L_e in W·m⁻²·sr⁻¹ (optional, default 0, finite and ≥ 0). All other
//!   MTL statements are ignored; those that would change the look — texture maps (`map_*`,
//!   `bump`, `disp`, `decal`, `refl`, `norm`), specular reflection (`Ks` above 0,
//!   `Pm`/`Pr`) and transparency (`d` below 1, `Tr` above 0, `Tf` below 1, `Ni` with
//!   transparency) — are named in one warning;
//!
//! Real files are messy, so by default ([`ObjOptions::strict`] off) three problems are
//! repaired, each reported in one warning that counts the cases and names the first few by
//! file and line:
//! - a face with zero area (fewer than three distinct vertices, or collinear ones) is skipped
//!   (if every face is, the first one's error is returned);
//! - a reflectance channel ≥ 1 (e.g. `Kd 1 1 1` on glass) is clamped to [`MAX_REFLECTANCE`]:
//!   ρ = 1 would make a closed scene's radiosity system singular, and no real diffuse
//!   surface reflects more than about 99 %;
//! - a face before any `usemtl` gets [`DEFAULT_GREY`], a neutral ρ = 0.5 (about the mean
//!   albedo of an interior; a material named [`DEFAULT_MATERIAL`]).
//!
//! With `strict`, each of these, and every ignored statement above, is an error instead.
//! Malformed syntax, bad indices, NaNs, negative ρ and faces that are not planar are always
//! errors.
//! - `mtllib` names one file (the rest of the line, so names may contain spaces), relative to
//!   the OBJ file; `l` (polyline) statements and unknown statements are ignored; an OBJ has no
//!   camera.
//!
//! Parsing is done by `tobj` (polygons kept: `triangulate: false`). Before tobj sees the text a
//! line-by-line scan validates it, because tobj reports errors without a line, merges `o` and
//! `g`, silently drops unknown `usemtl` names and panics on a few malformed inputs (an MTL `Kd`
//! with two numbers). The scan is what lets every error name its file, line and object.
//! Coordinates need tobj's `use_f64` feature: in `f32`, `0.5528` is off by 3e-8 and areas by
//! 1e-8 relative.
//!
//! See also: [`crate::io::scene_file`] for our own JSON format, which can include OBJ files.

use crate::geometry::{split_into_convex, GeometryError};
use crate::io::error::{Location, SceneError};
use crate::io::open::{read_to_string_checked, Kind};
use crate::scene::{Material, MaterialId, Origin, Scene, Surface};
use glam::DVec3;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Largest reflectance a material keeps when reading leniently; channels ≥ 1 become this.
pub const MAX_REFLECTANCE: f64 = 0.99;

/// Reflectance of the material given to faces that have none (read leniently).
pub const DEFAULT_GREY: [f64; 3] = [0.5, 0.5, 0.5];

/// Name of the material given to faces that have none (made unique if the file uses it).
pub const DEFAULT_MATERIAL: &str = "default grey";

/// How many cases a counting warning names.
const NAMED_CASES: usize = 5;

/// How to read an OBJ file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ObjOptions {
    /// Every repair and every ignored statement is an error (see the module documentation).
    pub strict: bool,
}

/// An OBJ scene and what was repaired or ignored on the way.
#[derive(Debug, Clone, PartialEq)]
pub struct ObjScene {
    /// The scene.
    pub scene: Scene,
    /// One line per kind of repair or ignored statement, each starting with the file.
    pub warnings: Vec<String>,
}

/// Loads an OBJ file and the MTL files it names (relative to the OBJ's directory), with the
/// default (lenient) options; the warnings are dropped (see [`load_obj_with`]).
///
/// The scene is named after the file stem and has no camera. Errors name the file as given
/// in `path`.
pub fn load_obj(path: &Path) -> Result<Scene, SceneError> {
    Ok(load_obj_with(path, &ObjOptions::default())?.scene)
}

/// Loads an OBJ file and the MTL files it names, with its warnings.
pub fn load_obj_with(path: &Path, options: &ObjOptions) -> Result<ObjScene, SceneError> {
    let file = path.display().to_string();
    let text = read_to_string_checked(path, Kind::Geometry).map_err(|source| SceneError::Read {
        file: file.clone(),
        source,
    })?;
    let dir = path.parent().unwrap_or(Path::new("")).to_path_buf();
    parse_obj_with(
        &text,
        &file,
        |library| read_to_string_checked(&dir.join(library), Kind::Materials),
        options,
    )
}

/// Parses OBJ text already in memory with the default options, dropping the warnings (see
/// [`parse_obj_with`]).
pub fn parse_obj(
    obj: &str,
    file_label: &str,
    load_mtl: impl Fn(&Path) -> Result<String, std::io::Error>,
) -> Result<Scene, SceneError> {
    Ok(parse_obj_with(obj, file_label, load_mtl, &ObjOptions::default())?.scene)
}

/// Parses OBJ text already in memory.
///
/// `file_label` names the input in errors and in each surface's [`Origin`]; the scene is named
/// after its stem. `load_mtl` is called with each `mtllib` path exactly as written in the OBJ
/// and returns the MTL text; MTL errors are labelled with that path joined onto the label's
/// directory.
pub fn parse_obj_with(
    obj: &str,
    file_label: &str,
    load_mtl: impl Fn(&Path) -> Result<String, std::io::Error>,
    options: &ObjOptions,
) -> Result<ObjScene, SceneError> {
    let obj = obj.strip_prefix('\u{feff}').unwrap_or(obj);
    let scan = scan_obj(obj, file_label)?;

    let mut library = MaterialLibrary {
        strict: options.strict,
        ..MaterialLibrary::default()
    };
    for (line, name) in &scan.libraries {
        let label = sibling_label(file_label, name);
        let text =
            load_mtl(Path::new(name)).map_err(|source| SceneError::MissingMaterialLibrary {
                at: Location::line(file_label, *line),
                library: label.clone(),
                source,
            })?;
        library.read_mtl(&text, &label)?;
    }
    let mut warnings = Vec::new();
    if let Some(w) = library
        .clamped
        .warning(&format!("reflectance ≥ 1 clamped to {MAX_REFLECTANCE}"))
    {
        warnings.push(w);
    }
    if let Some(w) = library.ignored_warning() {
        warnings.push(w);
    }
    let mut no_material = Cases::default();
    let mut zero_area = Cases::default();
    let mut first_zero_area: Option<SceneError> = None;
    for usage in &scan.usemtls {
        if !library.ids.contains_key(&usage.material) {
            return Err(SceneError::UnknownMaterial {
                at: Location::line(file_label, usage.line),
                object: usage.object.clone(),
                material: usage.material.clone(),
            });
        }
    }

    // Materials are bound by name from the scan, so tobj gets none.
    let tobj_options = tobj::LoadOptions {
        triangulate: false,
        single_index: false,
        ..Default::default()
    };
    let (models, _) = tobj::load_obj_buf(&mut obj.as_bytes(), &tobj_options, |_| {
        Ok(Default::default())
    })
    .map_err(|e| SceneError::Syntax {
        at: Location::file(file_label),
        message: format!("OBJ parser: {e}"),
    })?;

    let mut records = scan.faces.iter();
    let mut surfaces = Vec::new();
    for mesh in models.iter().map(|m| &m.mesh) {
        let triangles = std::iter::repeat_n(3, mesh.indices.len() / 3);
        let arities: Box<dyn Iterator<Item = usize>> = if mesh.face_arities.is_empty() {
            Box::new(triangles)
        } else {
            Box::new(mesh.face_arities.iter().map(|&n| n as usize))
        };
        let mut start = 0;
        for arity in arities {
            let indices = mesh.indices.get(start..start + arity);
            start += arity;
            let record = records.next();
            let (Some(indices), Some(record)) = (indices, record) else {
                return Err(disagreement(file_label, record.map(|r| r.line)));
            };
            if record.arity != arity {
                return Err(disagreement(file_label, Some(record.line)));
            }
            if record.is_polyline {
                continue;
            }
            let at = || Location::line(file_label, record.line);
            let material = match &record.material {
                None if options.strict => {
                    return Err(SceneError::NoMaterial {
                        at: at(),
                        object: record.object.clone(),
                    })
                }
                None => {
                    no_material.add(at(), &record.object);
                    library.default_grey()
                }
                // Every `usemtl` name was checked above; this only keeps the lookup
                // panic-free.
                Some(name) => match library.ids.get(name) {
                    Some(&material) => material,
                    None => {
                        return Err(SceneError::UnknownMaterial {
                            at: at(),
                            object: record.object.clone(),
                            material: name.clone(),
                        })
                    }
                },
            };
            let mut vertices = Vec::with_capacity(arity);
            for &i in indices {
                let i = i as usize * 3;
                let Some(p) = mesh.positions.get(i..i + 3) else {
                    return Err(disagreement(file_label, Some(record.line)));
                };
                vertices.push(DVec3::new(real(p[0]), real(p[1]), real(p[2])));
            }
            let polygons = match split_into_convex(vertices) {
                Ok(polygons) => polygons,
                Err(
                    source @ (GeometryError::Degenerate { .. } | GeometryError::TooFewVertices(_)),
                ) if !options.strict => {
                    zero_area.add(at(), &record.object);
                    first_zero_area.get_or_insert(SceneError::Geometry {
                        at: at(),
                        object: record.object.clone(),
                        source,
                    });
                    continue;
                }
                Err(source) => {
                    return Err(SceneError::Geometry {
                        at: at(),
                        object: record.object.clone(),
                        source,
                    })
                }
            };
            surfaces.extend(polygons.into_iter().map(|polygon| Surface {
                object: record.object.clone(),
                group: record.group.clone(),
                material,
                polygon,
                origin: Origin {
                    file: Some(file_label.to_owned()),
                    line: Some(record.line),
                },
            }));
        }
    }
    if let Some(record) = records.next() {
        return Err(disagreement(file_label, Some(record.line)));
    }
    if surfaces.is_empty() {
        // Nothing left after skipping: the first skipped face says why better than "empty".
        return Err(first_zero_area.unwrap_or_else(|| SceneError::Empty {
            file: file_label.to_owned(),
        }));
    }
    if let Some(w) = zero_area.warning("zero-area faces skipped") {
        warnings.push(w);
    }
    if let Some(w) = no_material.warning(&format!(
        "faces without a material (no 'usemtl' before them) given '{}', ρ = {}",
        library.materials[library.default_grey.map_or(0, |m| m.0 as usize)].name,
        DEFAULT_GREY[0]
    )) {
        warnings.push(w);
    }
    Ok(ObjScene {
        scene: Scene {
            name: scene_name(file_label),
            materials: library.materials,
            surfaces,
            lights: Vec::new(),
            camera: None,
        },
        warnings,
    })
}

/// Cases of one kind of repair: how many, and where the first few were.
#[derive(Debug, Default)]
pub(crate) struct Cases {
    file: Option<String>,
    count: usize,
    first: Vec<String>,
}

impl Cases {
    /// Counts one case at `at`, about `what` (an object or material name).
    pub(crate) fn add(&mut self, at: Location, what: &str) {
        self.count += 1;
        if self.first.len() < NAMED_CASES {
            let file = self.file.get_or_insert_with(|| at.file.clone());
            let place = match at.line {
                Some(line) if *file == at.file => format!("line {line}"),
                _ => at.to_string(),
            };
            self.first.push(format!("{place} '{what}'"));
        }
    }

    /// "file: N <what>: line a 'x', line b 'y', …", or `None` if there were none.
    pub(crate) fn warning(&self, what: &str) -> Option<String> {
        let file = self.file.as_ref()?;
        let more = if self.count > self.first.len() {
            ", …"
        } else {
            ""
        };
        Some(format!(
            "{file}: {} {what}: {}{more}",
            self.count,
            self.first.join(", ")
        ))
    }
}

/// The scene name for a file: its stem, or "scene".
pub(crate) fn scene_name(file_label: &str) -> String {
    Path::new(file_label)
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .filter(|s| !s.is_empty())
        .unwrap_or_else(|| "scene".to_owned())
}

/// What is wrong with a material's values, if anything: ρ must be in [0, 1) and L_e finite
/// and ≥ 0 in every channel.
/// The largest emitted radiance accepted, W·m⁻²·sr⁻¹: 10¹² is some 10⁵ times the sun's
/// surface (2·10⁷), and far enough below the largest `f64` (1.8·10³⁰⁸) that the solvers'
/// sums and squares of radiosities stay finite.
pub const MAX_EMISSION: f64 = 1e12;

pub(crate) fn material_problem(material: &Material) -> Option<String> {
    const CHANNELS: [&str; 3] = ["red", "green", "blue"];
    for (&r, channel) in material.reflectance.iter().zip(CHANNELS) {
        if r.is_nan() {
            return Some(format!("reflectance ({channel}) is NaN"));
        }
        if r < 0.0 {
            return Some(format!("reflectance {r} ({channel}) must be ≥ 0"));
        }
        if r >= 1.0 {
            return Some(format!("reflectance {r} ({channel}) must be < 1"));
        }
    }
    for (&e, channel) in material.emission.iter().zip(CHANNELS) {
        if !e.is_finite() {
            return Some(format!("emission {e} ({channel}) must be finite"));
        }
        if e < 0.0 {
            return Some(format!("emission {e} ({channel}) must be ≥ 0"));
        }
        if e > MAX_EMISSION {
            return Some(format!(
                "emission {e:e} ({channel}) is beyond {MAX_EMISSION:e} W·m⁻²·sr⁻¹"
            ));
        }
    }
    None
}

/// `name` resolved against the directory of `file_label`, as a label for messages.
fn sibling_label(file_label: &str, name: &str) -> String {
    let dir = Path::new(file_label).parent().unwrap_or(Path::new(""));
    let path: PathBuf = dir.join(name);
    path.display().to_string()
}

/// tobj's coordinate type is `f64` with its `use_f64` feature and `f32` without; this accepts
/// either.
fn real<T: Into<f64>>(x: T) -> f64 {
    x.into()
}

/// The scan and tobj saw different faces. The scan accepts only what tobj parses the same way,
/// so this is a bug, reported rather than panicking.
fn disagreement(file_label: &str, line: Option<usize>) -> SceneError {
    debug_assert!(false, "OBJ scan and tobj disagree at line {line:?}");
    SceneError::Syntax {
        at: Location::new(file_label, line),
        message: "the OBJ parser read this face differently from the validator".to_owned(),
    }
}

/// Materials read from MTL files, in definition order.
#[derive(Default)]
struct MaterialLibrary {
    materials: Vec<Material>,
    ids: HashMap<String, MaterialId>,
    defined_at: HashMap<String, Location>,
    /// Repairs are errors.
    strict: bool,
    /// Materials whose reflectance was clamped.
    clamped: Cases,
    /// Ignored statements: keyword → (materials using it, first place).
    ignored: Vec<(String, usize, Location)>,
    /// The material given to faces without one, once it exists.
    default_grey: Option<MaterialId>,
}

impl MaterialLibrary {
    /// The default grey material, added on first use.
    fn default_grey(&mut self) -> MaterialId {
        if let Some(id) = self.default_grey {
            return id;
        }
        let mut name = DEFAULT_MATERIAL.to_owned();
        let mut k = 2;
        while self.ids.contains_key(&name) {
            name = format!("{DEFAULT_MATERIAL} {k}");
            k += 1;
        }
        let id = MaterialId(self.materials.len() as u32);
        self.ids.insert(name.clone(), id);
        self.materials
            .push(Material::new(name, DEFAULT_GREY, [0.0; 3]));
        self.default_grey = Some(id);
        id
    }

    /// Records an ignored statement of the material defined at `at`.
    fn ignore(&mut self, keyword: &str, at: &Location) -> Result<(), SceneError> {
        if self.strict {
            return Err(SceneError::Syntax {
                at: at.clone(),
                message: format!(
                    "'{keyword}' ({}) is not supported (Lambertian, untextured materials only; \
                     without --strict it is ignored with a warning)",
                    ignored_kind(keyword)
                ),
            });
        }
        match self.ignored.iter_mut().find(|(k, _, _)| k == keyword) {
            Some((_, count, _)) => *count += 1,
            None => self.ignored.push((keyword.to_owned(), 1, at.clone())),
        }
        Ok(())
    }

    /// One warning naming every ignored statement, how often and where first.
    fn ignored_warning(&self) -> Option<String> {
        let (_, _, first) = self.ignored.first()?;
        let items: Vec<String> = self
            .ignored
            .iter()
            .map(|(keyword, count, at)| {
                let times = if *count == 1 {
                    String::new()
                } else {
                    format!(" ×{count}")
                };
                format!("{keyword} ({}){times} first at {at}", ignored_kind(keyword))
            })
            .collect();
        Some(format!(
            "{}: ignored material statements (materials are Lambertian and untextured): {}",
            first.file,
            items.join("; ")
        ))
    }

    /// Validates MTL text line by line, parses it with tobj and adds its materials.
    fn read_mtl(&mut self, text: &str, label: &str) -> Result<(), SceneError> {
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        let mut lines_of = HashMap::new();
        for (i, raw) in text.lines().enumerate() {
            let at = Location::line(label, i + 1);
            let trimmed = raw.trim();
            let mut words = trimmed.split_whitespace();
            let Some(keyword) = words.next() else {
                continue;
            };
            let rest = trimmed[keyword.len()..].trim();
            let syntax = |message: String| SceneError::Syntax {
                at: at.clone(),
                message,
            };
            match keyword {
                "newmtl" => {
                    if rest.is_empty() {
                        return Err(syntax("'newmtl' needs a material name".to_owned()));
                    }
                    if let Some(first) = self.defined_at.get(rest) {
                        return Err(SceneError::Material {
                            at,
                            material: rest.to_owned(),
                            problem: format!("defined twice (first at {first})"),
                        });
                    }
                    self.defined_at.insert(rest.to_owned(), at.clone());
                    lines_of.insert(rest.to_owned(), at);
                }
                _ => {
                    if let Some(problem) = mtl_statement_problem(keyword, rest) {
                        return Err(syntax(problem));
                    }
                    // A property before any `newmtl` belongs to no material: it would be
                    // dropped silently.
                    if lines_of.is_empty() && MTL_PROPERTIES.contains(&keyword) {
                        return Err(syntax(format!(
                            "'{keyword}' before any 'newmtl': it belongs to no material"
                        )));
                    }
                    if changes_the_look(keyword, rest) {
                        self.ignore(keyword, &at)?;
                    }
                }
            }
        }

        let (materials, _) =
            tobj::load_mtl_buf(&mut text.as_bytes()).map_err(|e| SceneError::Syntax {
                at: Location::file(label),
                message: format!("MTL parser: {e}"),
            })?;
        for m in materials {
            let at = lines_of
                .remove(&m.name)
                .unwrap_or_else(|| Location::file(label));
            let Some(diffuse) = m.diffuse else {
                return Err(SceneError::Material {
                    at,
                    material: m.name,
                    problem: "has no 'Kd' (diffuse reflectance)".to_owned(),
                });
            };
            let mut material = Material::new(
                m.name,
                diffuse.map(real),
                m.emissive.unwrap_or_default().map(real),
            );
            let too_bright = material
                .reflectance
                .iter()
                .any(|r| r.is_finite() && *r >= 1.0);
            if too_bright && !self.strict {
                self.clamped.add(at.clone(), &material.name);
                for r in &mut material.reflectance {
                    if r.is_finite() && *r >= 1.0 {
                        *r = MAX_REFLECTANCE;
                    }
                }
            }
            if let Some(problem) = material_problem(&material) {
                return Err(SceneError::Material {
                    at,
                    material: material.name,
                    problem,
                });
            }
            let id = MaterialId(self.materials.len() as u32);
            self.ids.insert(material.name.clone(), id);
            self.materials.push(material);
        }
        Ok(())
    }
}

/// Whether an MTL statement asks for something the Lambertian, untextured model ignores and
/// that changes how the surface looks: a texture map, specular reflection, transparency.
/// Statements at their neutral values (`Ks 0 0 0`, `d 1`, `Tr 0`) are not reported.
fn changes_the_look(keyword: &str, rest: &str) -> bool {
    let numbers: Vec<f64> = rest
        .split_whitespace()
        .map_while(|w| w.parse().ok())
        .collect();
    let any = |pred: fn(f64) -> bool| numbers.iter().any(|&x| pred(x));
    let lower = keyword.to_ascii_lowercase();
    match lower.as_str() {
        k if k.starts_with("map_") => true,
        "bump" | "disp" | "decal" | "refl" | "norm" => true,
        "ks" | "pm" | "pr" => any(|x| x > 0.0),
        "d" => any(|x| x < 1.0),
        "tr" => any(|x| x > 0.0),
        "tf" => any(|x| x < 1.0),
        _ => false,
    }
}

/// What an ignored statement is, for the warning.
fn ignored_kind(keyword: &str) -> &'static str {
    match keyword.to_ascii_lowercase().as_str() {
        "ks" | "pm" | "pr" => "specular",
        "d" | "tr" | "tf" => "transparency",
        _ => "texture map",
    }
}
/// MTL statements that set a property of the current material.
const MTL_PROPERTIES: [&str; 12] = [
    "Ka", "Kd", "Ks", "Ke", "Ns", "Ni", "d", "Tr", "Tf", "illum", "map_Kd", "map_Ka",
];

/// Why tobj would reject (or panic on) an MTL statement other than `newmtl`, if it would.
/// `rest` is the line after the keyword, trimmed.
fn mtl_statement_problem(keyword: &str, rest: &str) -> Option<String> {
    let mut words = rest.split_whitespace();
    let is_number = |w: &str| w.parse::<f64>().is_ok();
    let ok = match keyword {
        // tobj reads the first three values and panics when there are fewer.
        "Ka" | "Kd" | "Ks" | "Ke" => words.by_ref().take(3).filter(|w| is_number(w)).count() == 3,
        "Ns" | "Ni" | "d" => words.next().is_some_and(is_number),
        "illum" => words.next().is_some_and(|w| w.parse::<u8>().is_ok()),
        "map_Ka" | "map_Kd" | "map_Ks" | "map_Bump" | "map_bump" | "map_Ns" | "map_ns"
        | "map_NS" | "bump" | "map_d" => !rest.is_empty(),
        _ => true,
    };
    let wants = match keyword {
        "Ka" | "Kd" | "Ks" | "Ke" => "three numbers (r g b)",
        "Ns" | "Ni" | "d" => "a number",
        "illum" => "an illumination model number 0-255",
        _ => "a texture file name",
    };
    (!ok).then(|| format!("'{keyword}' needs {wants}, got '{rest}'"))
}

/// One `f` (or `l`) statement as the scan saw it.
#[derive(Debug)]
struct FaceRecord {
    line: usize,
    object: String,
    group: String,
    material: Option<String>,
    /// Number of vertices as written.
    arity: usize,
    /// An `l` statement: tobj reads it like a face, we skip it.
    is_polyline: bool,
}

/// One `usemtl` statement.
#[derive(Debug)]
struct UseMaterial {
    line: usize,
    object: String,
    material: String,
}

/// What the validating scan of an OBJ file collects.
#[derive(Debug, Default)]
struct ObjScan {
    faces: Vec<FaceRecord>,
    usemtls: Vec<UseMaterial>,
    /// (line, file name as written).
    libraries: Vec<(usize, String)>,
}

/// Kinds of indexed OBJ data, in face-token order `v/vt/vn`.
const ELEMENTS: [&str; 3] = ["vertex", "texture coordinate", "normal"];

/// Validates OBJ text line by line so that tobj only ever sees input it parses correctly,
/// and records what tobj does not report: line numbers, `o`/`g` names, material names.
fn scan_obj(text: &str, file: &str) -> Result<ObjScan, SceneError> {
    // Totals let "face refers to vertex 40, file has 38" distinguish a bad index from a
    // forward reference (tobj resolves indices against the elements read so far).
    let mut totals = [0usize; 3];
    for raw in text.lines() {
        match raw.split_whitespace().next() {
            Some("v") => totals[0] += 1,
            Some("vt") => totals[1] += 1,
            Some("vn") => totals[2] += 1,
            _ => {}
        }
    }

    let mut scan = ObjScan::default();
    let mut counts = [0usize; 3];
    let mut coloured: Option<bool> = None;
    let mut object: Option<String> = None;
    let mut group: Option<String> = None;
    let mut unnamed = 1;
    let mut material: Option<String> = None;
    let object_name = |object: &Option<String>, group: &Option<String>, unnamed: usize| {
        object
            .clone()
            .or_else(|| group.clone())
            .unwrap_or_else(|| format!("object_{unnamed}"))
    };

    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let at = || Location::line(file, line);
        let syntax = |message: String| SceneError::Syntax { at: at(), message };
        let trimmed = raw.trim();
        let mut words = trimmed.split_whitespace();
        let Some(keyword) = words.next() else {
            continue;
        };
        let rest = trimmed[keyword.len()..].trim();
        match keyword {
            "v" => {
                let values: Vec<&str> = words.collect();
                if !matches!(values.len(), 3 | 4 | 6) {
                    return Err(syntax(format!(
                        "vertex needs 3, 4 or 6 values ('x y z', 'x y z w' or 'x y z r g b'), \
                         got {}",
                        values.len()
                    )));
                }
                let mut numbers = [0.0; 6];
                for (n, word) in numbers.iter_mut().zip(&values) {
                    *n = word
                        .parse::<f64>()
                        .map_err(|_| syntax(format!("'{word}' is not a number")))?;
                }
                let mut xyz = [numbers[0], numbers[1], numbers[2]];
                if values.len() == 4 {
                    let w = numbers[3];
                    if w == 0.0 {
                        return Err(syntax("vertex weight w is zero".to_owned()));
                    }
                    xyz = xyz.map(|x| x / w);
                }
                if let Some(bad) = xyz.iter().find(|x| !x.is_finite()) {
                    return Err(SceneError::NonFiniteCoordinate {
                        at: at(),
                        value: bad.to_string(),
                    });
                }
                let has_colour = values.len() == 6;
                if *coloured.get_or_insert(has_colour) != has_colour {
                    return Err(syntax(
                        "vertex colours are given for some vertices but not others".to_owned(),
                    ));
                }
                counts[0] += 1;
            }
            "vt" | "vn" => {
                let (k, n) = if keyword == "vt" { (1, 2) } else { (2, 3) };
                let numbers: Vec<&str> = words.take(n).collect();
                if numbers.len() < n || numbers.iter().any(|w| w.parse::<f64>().is_err()) {
                    return Err(syntax(format!(
                        "{} needs {n} numbers, got '{rest}'",
                        ELEMENTS[k]
                    )));
                }
                counts[k] += 1;
            }
            "f" | "l" => {
                let mut arity = 0;
                for token in words {
                    check_face_token(token, counts, totals, file, line)?;
                    arity += 1;
                }
                scan.faces.push(FaceRecord {
                    line,
                    object: object_name(&object, &group, unnamed),
                    group: group.clone().unwrap_or_default(),
                    material: material.clone(),
                    arity,
                    is_polyline: keyword == "l",
                });
            }
            "o" | "g" => {
                let name = (!rest.is_empty()).then(|| rest.to_owned());
                if name.is_none() {
                    unnamed += 1;
                }
                if keyword == "o" {
                    object = name;
                } else {
                    group = name;
                }
            }
            "usemtl" => {
                if rest.is_empty() {
                    return Err(syntax("'usemtl' needs a material name".to_owned()));
                }
                material = Some(rest.to_owned());
                scan.usemtls.push(UseMaterial {
                    line,
                    object: object_name(&object, &group, unnamed),
                    material: rest.to_owned(),
                });
            }
            "mtllib" => {
                if rest.is_empty() {
                    return Err(syntax("'mtllib' needs a file name".to_owned()));
                }
                scan.libraries.push((line, rest.to_owned()));
            }
            _ => {}
        }
    }
    Ok(scan)
}

/// Checks one face token `v`, `v/vt`, `v//vn` or `v/vt/vn`: integers, not 0, and referring to
/// an element defined earlier in the file (negative indices count back from the last one).
fn check_face_token(
    token: &str,
    counts: [usize; 3],
    totals: [usize; 3],
    file: &str,
    line: usize,
) -> Result<(), SceneError> {
    let syntax = |message: String| SceneError::Syntax {
        at: Location::line(file, line),
        message,
    };
    if token.split('/').count() > 3 {
        return Err(syntax(format!(
            "face vertex '{token}' has more than three indices (v/vt/vn)"
        )));
    }
    for (k, part) in token.split('/').enumerate() {
        if part.is_empty() {
            if k == 0 {
                return Err(syntax(format!("face vertex '{token}' has no vertex index")));
            }
            continue;
        }
        let index: i64 = part
            .parse()
            .map_err(|_| syntax(format!("face vertex '{token}': '{part}' is not an index")))?;
        let what = ELEMENTS[k];
        let resolved = match index {
            0 => {
                return Err(syntax(format!(
                    "face refers to {what} 0; OBJ indices start at 1"
                )))
            }
            i if i > 0 => usize::try_from(i - 1).ok(),
            i => usize::try_from(i.unsigned_abs())
                .ok()
                .and_then(|back| counts[k].checked_sub(back)),
        };
        match resolved {
            Some(r) if r < counts[k] => {}
            Some(r) if r < totals[k] => {
                return Err(syntax(format!(
                    "face refers to {what} {index}, which is defined only later in the file"
                )))
            }
            _ => {
                return Err(SceneError::IndexOutOfRange {
                    at: Location::line(file, line),
                    what,
                    index,
                    count: if index < 0 { counts[k] } else { totals[k] },
                })
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn no_mtl(_: &Path) -> Result<String, std::io::Error> {
        Err(std::io::ErrorKind::NotFound.into())
    }

    const MTL: &str = "newmtl white\nKd 0.5 0.5 0.5\n";

    fn with_mtl(_: &Path) -> Result<String, std::io::Error> {
        Ok(MTL.to_owned())
    }

    #[test]
    fn relative_indices_and_slashes_resolve() {
        let obj = "mtllib m.mtl\nusemtl white\nv 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nvn 0 0 1\n\
                   f -3/1/1 -2//1 -1/-1/-1\n";
        let scene = parse_obj(obj, "t.obj", with_mtl).unwrap();
        assert_eq!(scene.surfaces.len(), 1);
        assert!((scene.surfaces[0].polygon.area() - 0.5).abs() < 1e-15);
        assert_eq!(scene.surfaces[0].object, "object_1");
        assert_eq!(scene.surfaces[0].group, "");
    }

    #[test]
    fn object_falls_back_to_group_and_keeps_group() {
        let obj = "mtllib m.mtl\nusemtl white\nv 0 0 0\nv 1 0 0\nv 1 1 0\n\
                   g walls\nf 1 2 3\no box\nf 1 2 3\ng lid\nf 1 2 3\n";
        let scene = parse_obj(obj, "t.obj", with_mtl).unwrap();
        let names: Vec<(&str, &str)> = scene
            .surfaces
            .iter()
            .map(|s| (s.object.as_str(), s.group.as_str()))
            .collect();
        assert_eq!(
            names,
            [("walls", "walls"), ("box", "walls"), ("box", "lid")]
        );
    }

    #[test]
    fn coordinates_are_exact_f64() {
        // Fails if tobj is built without its `use_f64` feature.
        let obj = "mtllib m.mtl\nusemtl white\nv 0.5528 0 0\nv 0 0.1 0\nv 0 0 0.3\nf 1 2 3\n";
        let scene = parse_obj(obj, "t.obj", with_mtl).unwrap();
        let v = scene.surfaces[0].polygon.vertices();
        assert_eq!(v[0].x, 0.5528, "enable tobj's `use_f64` feature");
        assert_eq!(v[1].y, 0.1);
        assert_eq!(scene.materials[0].reflectance, [0.5; 3]);
    }

    #[test]
    fn polylines_are_skipped_and_faces_stay_polygons() {
        let obj = "mtllib m.mtl\nusemtl white\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n\
                   l 1 2 3\nf 1 2 3 4\n";
        let scene = parse_obj(obj, "t.obj", with_mtl).unwrap();
        assert_eq!(scene.surfaces.len(), 1);
        assert_eq!(scene.surfaces[0].polygon.vertices().len(), 4);
        assert_eq!(scene.surfaces[0].origin.line, Some(8));
    }

    #[test]
    fn bad_tokens_are_syntax_errors_with_lines() {
        let cases = [
            ("v 0 0\n", 1),
            ("v 0 0 0 0 0\n", 1),
            ("v 0 0 0 0\n", 1),
            ("v 0 0 0\nvt 0\n", 2),
            ("v 0 0 0\nf 1/1/1/1 1 1\n", 2),
            ("v 0 0 0\nf /1 1 1\n", 2),
            ("v 0 0 0\nf 0 1 1\n", 2),
            ("v 0 0 0\nf 1 x 1\n", 2),
            ("v 0 0 0\nf 1 2 1\nv 1 1 1\n", 2),
            ("v 0 0 0 1 1 1\nv 0 0 0\n", 2),
            ("usemtl\n", 1),
        ];
        for (obj, line) in cases {
            match parse_obj(obj, "t.obj", no_mtl) {
                Err(SceneError::Syntax { at, .. }) => assert_eq!(at.line, Some(line), "{obj}"),
                other => panic!("{obj:?}: {other:?}"),
            }
        }
    }

    #[test]
    fn mtl_statements_that_would_panic_tobj_are_errors() {
        for mtl in [
            "newmtl a\nKd 0.5 0.5\n",
            "newmtl a\nKe 1\n",
            "newmtl\n",
            "Ns\n",
        ] {
            let obj = "mtllib m.mtl\n";
            let err = parse_obj(obj, "t.obj", |_| Ok(mtl.to_owned())).unwrap_err();
            assert!(matches!(err, SceneError::Syntax { .. }), "{mtl:?}: {err}");
            assert!(err.to_string().starts_with("m.mtl: line"), "{err}");
        }
    }

    #[test]
    fn material_problems() {
        let m = |reflectance, emission| Material::new("m", reflectance, emission);
        assert_eq!(
            material_problem(&m([0.0, 0.5, 0.999], [0.0, 1.0, 2.0])),
            None
        );
        let p = material_problem(&m([0.5, 1.2, 0.5], [0.0; 3])).unwrap();
        assert_eq!(p, "reflectance 1.2 (green) must be < 1");
        assert!(material_problem(&m([f64::NAN, 0.5, 0.5], [0.0; 3])).is_some());
        assert!(material_problem(&m([-0.1, 0.5, 0.5], [0.0; 3])).is_some());
        assert!(material_problem(&m([0.5; 3], [0.0, -1.0, 0.0])).is_some());
        assert!(material_problem(&m([0.5; 3], [f64::INFINITY, 0.0, 0.0])).is_some());
        assert!(material_problem(&m([0.5; 3], [1e308, 0.0, 0.0])).is_some());
        assert!(material_problem(&m([0.5; 3], [MAX_EMISSION, 0.0, 0.0])).is_none());
    }
}
