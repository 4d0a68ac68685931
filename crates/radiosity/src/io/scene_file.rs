//! Our own scene file: JSON that holds a whole scene (materials, surfaces, camera, settings)
//! and can pull in OBJ, glTF and MGF files.
//!
//! ```json
//! {
//!   "name": "cornell",
//!   "settings": { "elements": 4000, "width": 512, "height": 512 },
//!   "camera": { "eye": [0.278, 0.273, -0.8], "target": [0.278, 0.273, 0],
//!               "up": [0, 1, 0], "fov_deg": 39.30764811610662 },
//!   "include": ["cornell.obj"],
//!   "materials": [
//!     { "name": "white", "reflectance": [0.725, 0.71, 0.68] },
//!     { "name": "lamp", "reflectance": [0.78, 0.78, 0.78], "emission": [17, 12, 4] }
//!   ],
//!   "surfaces": [
//!     { "object": "panel", "group": "lamps", "material": "lamp",
//!       "vertices": [[0.3, 0.5, 0.2], [0.3, 0.5, 0.3], [0.2, 0.5, 0.3], [0.2, 0.5, 0.2]] }
//!   ]
//! }
//! ```
//!
//! All top-level keys are optional; unknown keys anywhere are errors, so a typo does not
//! silently fall back to a default. Lengths are in metres.
//! - `name`: the scene's name; default the file stem.
//! - `materials`: `name` (unique), `reflectance` ρ per RGB channel in [0, 1), `emission`
//!   L_e in W·m⁻²·sr⁻¹ per channel, in [0, 10¹²] (default 0; front side only),
//!   `two_sided` (default false: both sides reflect, see [`Material::two_sided`]) and
//!   `two_sided_emission` (default false: with `two_sided`, the back emits too). Values here
//!   are exact: out-of-range values are errors, never clamped.
//! - `surfaces`: `object` (non-empty; reports aggregate by it), `group` (default empty),
//!   `material` (a name from `materials` or from an included file), `vertices` in metres,
//!   counter-clockwise seen from the lit side. A non-planar quad is split into two triangles
//!   and a planar non-convex polygon is ear-clipped, as for OBJ faces.
//! - `include`: OBJ, glTF (`.gltf`, `.glb`) and MGF files, relative to this file, read by
//!   the format registry ([`crate::io::formats`]) with the same options as the scene file.
//!   Their surfaces come first, in order, then the inline surfaces; their materials join
//!   `materials` (a name defined twice must have the same values); their point and spot
//!   lights join the scene's, and the first included camera is used when the file has none.
//! - `camera`: a pinhole camera; `up` defaults to +y, `fov_deg` is the vertical field of view
//!   in degrees, in (0, 180). Without a camera, renderers frame the scene's bounds.
//! - `lights`: point, spot and goniometric (IES, EULUMDAT) light sources with position,
//!   aim and amount in lm, cd or W·sr⁻¹; see [`crate::io::lights`].
//! - `settings`: defaults for the mesh, solver and renderer, see [`SceneSettings`]; the
//!   command line overrides them. `null` is the same as leaving a setting out.
//!
//! [`save_scene_file`] writes everything inline (includes flattened), so a load → save → load
//! round trip gives the same scene and settings (surfaces' [`Origin`]s then name the saved file).
//! Numbers are written with the shortest representation that parses back to the same `f64`
//! (reading them back exactly needs serde_json's `float_roundtrip` feature).
//!
//! See also: [`crate::io::obj`].

use crate::geometry::split_into_convex;
use crate::io::error::{Location, SceneError};
use crate::io::formats::{load_any_with, load_geometry, LoadOptions};
use crate::io::obj::{material_problem, scene_name};
use crate::io::open::{read_to_string_checked, Kind};
use crate::scene::{Camera, Material, MaterialId, Origin, Scene, Surface};
use glam::DVec3;
use serde::{Deserialize, Serialize};
use serde_json::Value;
use std::collections::HashMap;
use std::path::Path;

/// Defaults for the later pipeline stages, stored with the scene. Every field is optional;
/// `None` means "the stage's own default" (and is not written). The command line overrides
/// these.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneSettings {
    /// Maximum element edge length, m; overrides `elements` when set.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_element_size: Option<f64>,
    /// Approximate total element count (used when `max_element_size` is not set).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub elements: Option<usize>,
    /// Elements per patch edge (a patch holds about this squared many elements).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub patch_subdivision: Option<u32>,
    /// Form-factor method, by its command-line name (see `FormFactorMethod`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub form_factor: Option<String>,
    /// Solver, by its command-line name: direct, jacobi, gauss-seidel, progressive.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub solver: Option<String>,
    /// Convergence tolerance, dimensionless, > 0: relative residual for the iterative solvers,
    /// unshot fraction of the emitted power for progressive refinement.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tolerance: Option<f64>,
    /// Hierarchical radiosity's link tolerance ε: the largest error in power one link may
    /// carry, as a fraction of the scene's emitted power.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub epsilon: Option<f64>,
    /// Shot cap for progressive refinement.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_shots: Option<usize>,
    /// Whether to display with the progressive-refinement ambient term added.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ambient: Option<bool>,
    /// Image exposure in stops: pixel = L · 2^exposure before the sRGB curve.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub exposure: Option<f64>,
    /// Image width in pixels, ≥ 1.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub width: Option<u32>,
    /// Image height in pixels, ≥ 1.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub height: Option<u32>,
}

/// A scene together with the settings stored in its file.
#[derive(Debug, Clone, PartialEq)]
pub struct LoadedScene {
    /// The scene.
    pub scene: Scene,
    /// The settings stored in the file.
    pub settings: SceneSettings,
    /// What the readers repaired or ignored, one line each, starting with the file.
    pub warnings: Vec<String>,
}

/// The file as serde sees it; see the module documentation.
#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneFile {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    name: Option<String>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    materials: Vec<MaterialEntry>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    surfaces: Vec<SurfaceEntry>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    include: Vec<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    camera: Option<CameraEntry>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    lights: Vec<crate::io::lights::LightEntry>,
    #[serde(default, skip_serializing_if = "is_default")]
    settings: SceneSettings,
}

#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct MaterialEntry {
    name: String,
    reflectance: [f64; 3],
    #[serde(default, skip_serializing_if = "is_default")]
    emission: [f64; 3],
    #[serde(default, skip_serializing_if = "is_default")]
    two_sided: bool,
    #[serde(default, skip_serializing_if = "is_default")]
    two_sided_emission: bool,
}

#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct SurfaceEntry {
    object: String,
    #[serde(default, skip_serializing_if = "String::is_empty")]
    group: String,
    material: String,
    vertices: Vec<[f64; 3]>,
}

#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct CameraEntry {
    eye: [f64; 3],
    target: [f64; 3],
    #[serde(default = "up_default")]
    up: [f64; 3],
    fov_deg: f64,
}

fn up_default() -> [f64; 3] {
    [0.0, 1.0, 0.0]
}

fn is_default<T: Default + PartialEq>(value: &T) -> bool {
    *value == T::default()
}

/// Loads a JSON scene file, its included OBJ files and its settings.
///
/// Errors name the file; JSON errors also give line and column, and errors inside included
/// files name those files and their lines.
pub fn load_scene_file(path: &Path) -> Result<LoadedScene, SceneError> {
    load_scene_file_with(path, &LoadOptions::default())
}

/// [`load_scene_file`] with reader options (passed on to included files).
pub fn load_scene_file_with(path: &Path, options: &LoadOptions) -> Result<LoadedScene, SceneError> {
    let file = path.display().to_string();
    let text = read_to_string_checked(path, Kind::Geometry).map_err(|source| SceneError::Read {
        file: file.clone(),
        source,
    })?;
    parse_scene_file_with(&text, path, options)
}

/// Parses scene-file JSON; `path` labels errors and resolves `include`s (it is not read).
pub fn parse_scene_file(json: &str, path: &Path) -> Result<LoadedScene, SceneError> {
    parse_scene_file_with(json, path, &LoadOptions::default())
}

/// [`parse_scene_file`] with reader options (passed on to included files).
pub fn parse_scene_file_with(
    json: &str,
    path: &Path,
    options: &LoadOptions,
) -> Result<LoadedScene, SceneError> {
    let file = path.display().to_string();
    let json = json.strip_prefix('\u{feff}').unwrap_or(json);
    let parsed: SceneFile = serde_json::from_str(json).map_err(|e| json_error(&file, &e))?;
    let whole = || Location::file(&file);
    let invalid = |message: String| SceneError::Invalid {
        at: whole(),
        message,
    };

    let mut scene = Scene {
        name: parsed.name.unwrap_or_else(|| scene_name(&file)),
        ..Scene::default()
    };
    let mut ids: HashMap<String, (MaterialId, String)> = HashMap::new();
    let mut add_material = |scene: &mut Scene, material: Material, from: &str| {
        // Two files may share a material (two OBJ exports with the same "white"); one file
        // may not define a name twice, and a shared name must mean the same material.
        if let Some((id, first)) = ids.get(&material.name) {
            let problem = if first == from {
                "defined twice".to_owned()
            } else if scene.materials[id.0 as usize] == material {
                return Ok(*id);
            } else {
                format!("defined differently in {first}")
            };
            return Err(SceneError::Material {
                at: Location::file(from),
                problem,
                material: material.name,
            });
        }
        let id = MaterialId(scene.materials.len() as u32);
        ids.insert(material.name.clone(), (id, from.to_owned()));
        scene.materials.push(material);
        Ok(id)
    };

    let dir = path.parent().unwrap_or(Path::new(""));
    let mut warnings = Vec::new();
    let mut included_camera = None;
    for include in &parsed.include {
        let include_path = dir.join(include);
        let in_include = |source: SceneError| SceneError::Included {
            file: file.clone(),
            source: Box::new(source),
        };
        let (included, included_warnings) =
            load_geometry(&include_path, options).map_err(in_include)?;
        warnings.extend(included_warnings);
        included_camera = included_camera.or(included.camera);
        scene.lights.extend(included.lights);
        let from = include_path.display().to_string();
        let mut remap = Vec::with_capacity(included.materials.len());
        for material in included.materials {
            remap.push(add_material(&mut scene, material, &from)?);
        }
        scene
            .surfaces
            .extend(included.surfaces.into_iter().map(|s| Surface {
                material: remap[s.material.0 as usize],
                ..s
            }));
    }

    for entry in parsed.materials {
        let material = Material {
            two_sided: entry.two_sided,
            two_sided_emission: entry.two_sided_emission,
            ..Material::new(entry.name, entry.reflectance, entry.emission)
        };
        if let Some(problem) = material_problem(&material) {
            return Err(SceneError::Material {
                at: whole(),
                material: material.name,
                problem,
            });
        }
        if material.name.is_empty() {
            return Err(invalid("a material has an empty name".to_owned()));
        }
        add_material(&mut scene, material, &file)?;
    }

    for (index, entry) in parsed.surfaces.into_iter().enumerate() {
        if entry.object.is_empty() {
            return Err(invalid(format!("surface {index} has an empty object name")));
        }
        let Some(&(material, _)) = ids.get(&entry.material) else {
            return Err(SceneError::UnknownMaterial {
                at: whole(),
                object: entry.object,
                material: entry.material,
            });
        };
        let vertices = entry.vertices.iter().map(|&v| DVec3::from(v)).collect();
        let polygons = split_into_convex(vertices).map_err(|source| SceneError::Geometry {
            at: whole(),
            object: entry.object.clone(),
            source,
        })?;
        scene
            .surfaces
            .extend(polygons.into_iter().map(|polygon| Surface {
                object: entry.object.clone(),
                group: entry.group.clone(),
                material,
                polygon,
                origin: Origin {
                    file: Some(file.clone()),
                    line: None,
                },
            }));
    }

    if let Some(c) = parsed.camera {
        let camera = Camera {
            eye: DVec3::from(c.eye),
            target: DVec3::from(c.target),
            up: DVec3::from(c.up),
            fov_deg: c.fov_deg,
        };
        if let Some(problem) = camera_problem(&camera) {
            return Err(invalid(format!("camera: {problem}")));
        }
        scene.camera = Some(camera);
    }
    scene.lights = crate::io::lights::lights_from_entries(&parsed.lights, dir, &file)?;
    if scene.camera.is_none() {
        scene.camera = included_camera;
    }
    if scene.surfaces.is_empty() {
        return Err(SceneError::Empty { file });
    }
    Ok(LoadedScene {
        scene,
        settings: parsed.settings,
        warnings,
    })
}

/// What is wrong with a camera, if anything: it must be finite, look somewhere, have an `up`
/// not parallel to the view direction and a field of view in (0°, 180°).
pub(crate) fn camera_problem(camera: &Camera) -> Option<String> {
    if !(camera.eye.is_finite() && camera.target.is_finite() && camera.up.is_finite()) {
        return Some("eye, target and up must be finite".to_owned());
    }
    let view = camera.target - camera.eye;
    if view.length() == 0.0 {
        return Some("eye and target coincide".to_owned());
    }
    if view.normalize().cross(camera.up).length() < 1e-9 * camera.up.length()
        || camera.up.length() == 0.0
    {
        return Some("up is zero or parallel to the view direction".to_owned());
    }
    if !(camera.fov_deg > 0.0 && camera.fov_deg < 180.0) {
        return Some(format!("fov_deg {} must be in (0, 180)", camera.fov_deg));
    }
    None
}

/// The scene as scene-file JSON, everything inline (includes flattened, one entry per convex
/// polygon), so that loading it gives the same scene.
pub fn scene_to_json(scene: &Scene, settings: &SceneSettings) -> Value {
    let file = SceneFile {
        name: Some(scene.name.clone()),
        materials: scene
            .materials
            .iter()
            .map(|m| MaterialEntry {
                name: m.name.clone(),
                reflectance: m.reflectance,
                emission: m.emission,
                two_sided: m.two_sided,
                two_sided_emission: m.two_sided && m.two_sided_emission,
            })
            .collect(),
        surfaces: scene
            .surfaces
            .iter()
            .map(|s| SurfaceEntry {
                object: s.object.clone(),
                group: s.group.clone(),
                material: scene.material(s).name.clone(),
                vertices: s.polygon.vertices().iter().map(|v| v.to_array()).collect(),
            })
            .collect(),
        include: Vec::new(),
        camera: scene.camera.map(|c| CameraEntry {
            eye: c.eye.to_array(),
            target: c.target.to_array(),
            up: c.up.to_array(),
            fov_deg: c.fov_deg,
        }),
        lights: scene
            .lights
            .iter()
            .map(crate::io::lights::LightEntry::from_light)
            .collect(),
        settings: settings.clone(),
    };
    // Plain data with string keys and finite numbers: serialisation cannot fail, and a
    // non-finite number (which a validated scene cannot hold) would become null.
    serde_json::to_value(file).unwrap_or(Value::Null)
}

/// Writes the scene as a scene file (see [`scene_to_json`]), atomically: to a temporary file
/// in the same directory, renamed over `path` when complete.
pub fn save_scene_file(
    path: &Path,
    scene: &Scene,
    settings: &SceneSettings,
) -> Result<(), SceneError> {
    let file = path.display().to_string();
    let write_error = |source| SceneError::Write {
        file: file.clone(),
        source,
    };
    let text = to_pretty_json(&scene_to_json(scene, settings));
    crate::io::atomic::write_atomically(path, |w| w.write_all(text.as_bytes())).map_err(write_error)
}

/// Loads a scene by extension with the default options (see [`crate::io::formats`], the
/// registry): `.obj`, `.gltf`/`.glb`, `.mgf` (default settings) or `.json`; anything else is
/// [`SceneError::UnknownFormat`].
pub fn load_any(path: &Path) -> Result<LoadedScene, SceneError> {
    load_any_with(path, &LoadOptions::default())
}

/// serde_json's message without its trailing " at line L column C", which we give separately.
fn json_error(file: &str, error: &serde_json::Error) -> SceneError {
    let message = error.to_string();
    let suffix = format!(" at line {} column {}", error.line(), error.column());
    SceneError::Json {
        file: file.to_owned(),
        line: error.line(),
        column: error.column(),
        message: message.strip_suffix(&suffix).unwrap_or(&message).to_owned(),
    }
}

/// Pretty JSON that keeps short arrays of plain values (colours, vertices, vertex lists) on one
/// line, so a scene file reads like the example in the module docs.
fn to_pretty_json(value: &Value) -> String {
    let mut out = String::new();
    write_pretty(&mut out, value, 0);
    out.push('\n');
    out
}

const LINE_WIDTH: usize = 100;

fn write_pretty(out: &mut String, value: &Value, indent: usize) {
    if let Some(inline) = inline_json(value) {
        if indent + inline.len() <= LINE_WIDTH {
            out.push_str(&inline);
            return;
        }
    }
    let pad = |out: &mut String, n: usize| out.extend(std::iter::repeat_n(' ', n));
    match value {
        Value::Array(items) => {
            out.push('[');
            for (i, item) in items.iter().enumerate() {
                out.push_str(if i == 0 { "\n" } else { ",\n" });
                pad(out, indent + 2);
                write_pretty(out, item, indent + 2);
            }
            out.push('\n');
            pad(out, indent);
            out.push(']');
        }
        Value::Object(map) => {
            let mut entries: Vec<(&String, &Value)> = map.iter().collect();
            entries.sort_by_key(|(key, _)| key_rank(key));
            out.push('{');
            for (i, (key, item)) in entries.into_iter().enumerate() {
                out.push_str(if i == 0 { "\n" } else { ",\n" });
                pad(out, indent + 2);
                out.push_str(&Value::String(key.clone()).to_string());
                out.push_str(": ");
                write_pretty(out, item, indent + 2);
            }
            out.push('\n');
            pad(out, indent);
            out.push('}');
        }
        scalar => out.push_str(&scalar.to_string()),
    }
}

/// Keys in the order a person wants to read them (short things before the long surface list,
/// settings in [`SceneSettings`] order); `serde_json::Map` would sort them alphabetically.
/// Unknown keys go last.
const KEY_ORDER: [&str; 29] = [
    "name",
    "object",
    "group",
    "material",
    "reflectance",
    "emission",
    "two_sided",
    "two_sided_emission",
    "vertices",
    "eye",
    "target",
    "up",
    "fov_deg",
    "settings",
    "max_element_size",
    "elements",
    "patch_subdivision",
    "form_factor",
    "solver",
    "tolerance",
    "max_shots",
    "ambient",
    "exposure",
    "width",
    "height",
    "camera",
    "include",
    "materials",
    "surfaces",
];

fn key_rank(key: &str) -> usize {
    KEY_ORDER
        .iter()
        .position(|k| *k == key)
        .unwrap_or(KEY_ORDER.len())
}

/// One-line JSON for scalars, empty containers and arrays of arrays of scalars; `None` for
/// anything holding an object.
fn inline_json(value: &Value) -> Option<String> {
    match value {
        Value::Object(map) if map.is_empty() => Some("{}".to_owned()),
        Value::Object(_) => None,
        Value::Array(items) => {
            let parts: Option<Vec<String>> = items.iter().map(inline_json).collect();
            Some(format!("[{}]", parts?.join(", ")))
        }
        scalar => Some(scalar.to_string()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(json: &str) -> Result<LoadedScene, SceneError> {
        parse_scene_file(json, Path::new("t.json"))
    }

    const SQUARE: &str = r#"{
        "materials": [{"name": "white", "reflectance": [0.5, 0.5, 0.5]}],
        "surfaces": [{"object": "floor", "material": "white",
                      "vertices": [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]}]
    }"#;

    #[test]
    fn minimal_file_loads_with_defaults() {
        let loaded = parse(SQUARE).unwrap();
        assert_eq!(loaded.scene.name, "t");
        assert_eq!(loaded.scene.materials[0].emission, [0.0; 3]);
        assert_eq!(loaded.scene.surfaces[0].group, "");
        assert_eq!(loaded.scene.camera, None);
        assert_eq!(loaded.settings, SceneSettings::default());
    }

    #[test]
    fn pretty_json_keeps_vertex_lists_on_one_line() {
        let loaded = parse(SQUARE).unwrap();
        let text = to_pretty_json(&scene_to_json(&loaded.scene, &loaded.settings));
        assert!(
            text.contains(r#""vertices": [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]]"#),
            "{text}"
        );
        let back = parse(&text).unwrap();
        assert_eq!(back.scene.surfaces, loaded.scene.surfaces);
    }

    #[test]
    fn settings_round_trip_and_skip_none() {
        let settings = SceneSettings {
            elements: Some(4000),
            form_factor: Some("raycast".into()),
            ambient: Some(false),
            exposure: Some(-1.5),
            ..Default::default()
        };
        let value = serde_json::to_value(&settings).unwrap();
        assert_eq!(value.as_object().unwrap().len(), 4);
        assert_eq!(
            serde_json::from_value::<SceneSettings>(value).unwrap(),
            settings
        );
        let nulls = r#"{"max_element_size": null, "elements": 10}"#;
        let parsed: SceneSettings = serde_json::from_str(nulls).unwrap();
        assert_eq!(parsed.elements, Some(10));
        assert_eq!(parsed.max_element_size, None);
    }

    #[test]
    fn cameras_are_checked() {
        let ok = Camera::default();
        assert_eq!(camera_problem(&ok), None);
        let cases = [
            Camera {
                target: ok.eye,
                ..ok
            },
            Camera { up: DVec3::Z, ..ok },
            Camera {
                up: DVec3::ZERO,
                ..ok
            },
            Camera {
                fov_deg: 180.0,
                ..ok
            },
            Camera { fov_deg: 0.0, ..ok },
            Camera {
                eye: DVec3::splat(f64::NAN),
                ..ok
            },
        ];
        for camera in cases {
            assert!(camera_problem(&camera).is_some(), "{camera:?}");
        }
    }

    #[test]
    fn semantic_errors() {
        let bad_settings =
            SQUARE.replace("\"surfaces\"", "\"settings\": {\"width\": 0}, \"surfaces\"");
        // Settings are validated where they are resolved, naming the file and the key.
        let loaded = parse(&bad_settings).unwrap();
        let e = crate::settings::resolve(
            Some((&loaded.settings, "t.json")),
            &crate::settings::Overrides::default(),
        )
        .unwrap_err();
        assert!(e.to_string().starts_with("t.json: settings.width"), "{e}");
        let dup = SQUARE.replace(
            "}],\n        \"surfaces\"",
            "}, {\"name\": \"white\", \"reflectance\": [0.5, 0.5, 0.5]}],\n        \"surfaces\"",
        );
        let err = parse(&dup).unwrap_err();
        assert!(matches!(err, SceneError::Material { .. }), "{dup}");
        assert_eq!(err.to_string(), "t.json: material 'white': defined twice");
        let bad_camera = SQUARE.replace(
            "\"surfaces\"",
            "\"camera\": {\"eye\": [0,0,0], \"target\": [0,0,0], \"fov_deg\": 40}, \"surfaces\"",
        );
        let err = parse(&bad_camera).unwrap_err();
        assert!(
            err.to_string().contains("t.json: camera: eye and target"),
            "{err}"
        );
    }
}
