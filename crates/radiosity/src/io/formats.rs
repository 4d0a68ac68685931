//! The scene-format registry: the one place that picks a reader by file extension, for the
//! command line and for `include` in our scene file.
//!
//! | extension | reader | what it gives |
//! |---|---|---|
//! | `.obj` | [`crate::io::obj`] (+ its `.mtl`) | surfaces, materials |
//! | `.gltf`, `.glb` | [`crate::io::gltf`] | surfaces, materials, the first camera, point and spot lights |
//! | `.mgf` | [`crate::io::mgf`] | surfaces, materials |
//! | `.json` | [`crate::io::scene_file`] | everything, plus settings; includes the formats above |
//!
//! Every reader returns the same [`Scene`] plus warnings (one line each, starting with the
//! file), collected in [`LoadedScene::warnings`]. [`LoadOptions`] holds what the readers
//! share: `strict` (every warning an error), the glTF emission scale, and `two_sided`
//! (every material reflects on both sides).

use crate::io::error::SceneError;
use crate::io::gltf::{load_gltf, GltfOptions};
use crate::io::mgf::{load_mgf_with, MgfOptions};
use crate::io::obj::{load_obj_with, ObjOptions};
use crate::io::scene_file::{load_scene_file_with, LoadedScene, SceneSettings};
use crate::scene::Scene;
use std::path::Path;

/// Options every reader understands.
#[derive(Debug, Clone, PartialEq)]
pub struct LoadOptions {
    /// Turn every warning (repaired or ignored input) into an error.
    pub strict: bool,
    /// glTF: W·m⁻²·sr⁻¹ of emitted radiance per unit of emissive colour (default 1).
    pub emission_scale: f64,
    /// Make every material two-sided (both sides reflect; emission stays on the front).
    pub two_sided: bool,
}

impl Default for LoadOptions {
    fn default() -> Self {
        Self {
            strict: false,
            emission_scale: 1.0,
            two_sided: false,
        }
    }
}

/// The scene formats we read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// Wavefront OBJ + MTL.
    Obj,
    /// glTF 2.0, JSON (`.gltf`) or binary (`.glb`).
    Gltf,
    /// Materials and Geometry Format (Ward 1994).
    Mgf,
    /// Our JSON scene file.
    SceneFile,
}

/// The extensions we read, for messages.
pub const EXTENSIONS: &str = ".obj, .gltf, .glb, .mgf or .json";

impl Format {
    /// The format of a path, by its extension (case-insensitive).
    pub fn of(path: &Path) -> Option<Format> {
        let extension = path.extension()?.to_str()?.to_ascii_lowercase();
        match extension.as_str() {
            "obj" => Some(Format::Obj),
            "gltf" | "glb" => Some(Format::Gltf),
            "mgf" => Some(Format::Mgf),
            "json" => Some(Format::SceneFile),
            _ => None,
        }
    }
}

/// Loads a scene of any format, chosen by extension; settings come only from scene files.
pub fn load_any_with(path: &Path, options: &LoadOptions) -> Result<LoadedScene, SceneError> {
    let mut loaded = match Format::of(path) {
        Some(Format::SceneFile) => load_scene_file_with(path, options)?,
        Some(_) => {
            let (scene, warnings) = load_geometry(path, options)?;
            LoadedScene {
                scene,
                settings: SceneSettings::default(),
                warnings,
            }
        }
        None => {
            return Err(SceneError::UnknownFormat {
                file: path.display().to_string(),
            })
        }
    };
    if options.two_sided {
        for material in &mut loaded.scene.materials {
            material.two_sided = true;
        }
    }
    Ok(loaded)
}

/// Loads an OBJ, glTF or MGF file (what a scene file may include), with its warnings.
pub fn load_geometry(
    path: &Path,
    options: &LoadOptions,
) -> Result<(Scene, Vec<String>), SceneError> {
    let file = path.display().to_string();
    match Format::of(path) {
        Some(Format::Obj) => {
            let loaded = load_obj_with(
                path,
                &ObjOptions {
                    strict: options.strict,
                },
            )?;
            Ok((loaded.scene, loaded.warnings))
        }
        Some(Format::Gltf) => {
            let gltf_options = GltfOptions {
                emission_scale: options.emission_scale,
                strict: options.strict,
                ..GltfOptions::default()
            };
            let loaded = load_gltf(path, &gltf_options)?;
            let warnings = loaded
                .warnings
                .iter()
                .map(|w| format!("{file}: {w}"))
                .collect();
            Ok((loaded.scene, warnings))
        }
        Some(Format::Mgf) => {
            let mgf_options = MgfOptions {
                strict: options.strict,
                ..MgfOptions::default()
            };
            let loaded = load_mgf_with(path, &mgf_options)?;
            let warnings = group_by_message(
                loaded
                    .warnings
                    .iter()
                    .map(|w| (w.at.to_string(), w.message.clone())),
            );
            Ok((loaded.scene, warnings))
        }
        Some(Format::SceneFile) => Err(SceneError::Invalid {
            at: crate::io::error::Location::file(file),
            message: "a scene file cannot be included; include OBJ, glTF or MGF files".to_owned(),
        }),
        None => Err(SceneError::UnknownFormat { file }),
    }
}

/// How many places a grouped warning names.
const NAMED_PLACES: usize = 5;

/// One warning per distinct message: "message (N×: place, place, …)", in first-seen order,
/// so a file with thousands of zero-area faces gives one line that counts them.
fn group_by_message(warnings: impl Iterator<Item = (String, String)>) -> Vec<String> {
    let mut groups: Vec<(String, Vec<String>, usize)> = Vec::new();
    for (at, message) in warnings {
        match groups.iter_mut().find(|(m, _, _)| *m == message) {
            Some((_, places, count)) => {
                *count += 1;
                if places.len() < NAMED_PLACES {
                    places.push(at);
                }
            }
            None => groups.push((message, vec![at], 1)),
        }
    }
    groups
        .into_iter()
        .map(|(message, places, count)| {
            if count == 1 {
                format!("{}: {message}", places[0])
            } else {
                let more = if count > places.len() { ", …" } else { "" };
                format!("{message} ({count}×: {}{more})", places.join(", "))
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn formats_by_extension() {
        assert_eq!(Format::of(Path::new("a/room.OBJ")), Some(Format::Obj));
        assert_eq!(Format::of(Path::new("x.glb")), Some(Format::Gltf));
        assert_eq!(Format::of(Path::new("x.gltf")), Some(Format::Gltf));
        assert_eq!(Format::of(Path::new("x.mgf")), Some(Format::Mgf));
        assert_eq!(Format::of(Path::new("x.json")), Some(Format::SceneFile));
        assert_eq!(Format::of(Path::new("x.txt")), None);
        assert_eq!(Format::of(Path::new("obj")), None);
    }

    #[test]
    fn repeated_warnings_are_counted_once() {
        let lines = (1..=7).map(|i| (format!("r.mgf: line {i}"), "zero area".to_owned()));
        let other = std::iter::once(("r.mgf: line 9".to_owned(), "rs ignored".to_owned()));
        let grouped = group_by_message(lines.chain(other));
        assert_eq!(
            grouped,
            [
                "zero area (7×: r.mgf: line 1, r.mgf: line 2, r.mgf: line 3, r.mgf: line 4, \
                 r.mgf: line 5, …)",
                "r.mgf: line 9: rs ignored"
            ]
        );
    }
}
