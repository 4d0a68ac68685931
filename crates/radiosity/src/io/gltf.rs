//! glTF 2.0 input: `.gltf` (JSON, with external `.bin` files or `data:` URIs) and `.glb`
//! (the binary container), read into the same [`Scene`] as the other formats.
//!
//! The mapping follows the glTF 2.0 specification (Khronos, version 2.0.1, 2021; sections
//! named below) and its `KHR_lights_punctual` and `KHR_materials_emissive_strength`
//! extensions:
//!
//! - **Scene graph** (§3.5, Scenes; §3.5.3, Transformations): the nodes of the default scene
//!   (`scene`, else the first scene, else every node that is nobody's child). Each node's local
//!   transform (its `matrix`, or T·R·S) is accumulated to world space in `f64`. A node whose
//!   world transform has a negative determinant mirrors its mesh; the spec makes that
//!   determinant define the winding (§3.7.2.1), so such triangles are reversed to keep the front
//!   face the one the author lit. Cycles and nodes with two parents are errors.
//! - **Meshes** (§3.7.2.1, Meshes: Overview): every primitive of every mesh instance.
//!   `TRIANGLES`, `TRIANGLE_STRIP` and `TRIANGLE_FAN` (vertex orders as in §3.7.2.1), indexed or
//!   not; `POINTS` and `LINES`/`LINE_LOOP`/`LINE_STRIP` are an error naming the mesh and
//!   primitive. Each triangle becomes one [`Surface`]: `object` = the node's name, else the
//!   mesh's, else `node<N>`; `group` = the mesh's name. Zero-area triangles are skipped and
//!   reported in one [`GltfWarning::DegenerateTriangles`]. Skins, morph targets and
//!   `EXT_mesh_gpu_instancing` are not applied (bind pose, base shape, one instance per node;
//!   one warning each).
//! - **Materials** (§3.9): ρ = `baseColorFactor`.rgb × the mean of `baseColorTexture` over all
//!   its texels. Texture texels are sRGB-encoded (§3.9.2: "the texture's sRGB value must be
//!   converted to linear"), so each texel is decoded with the IEC 61966-2-1 curve before
//!   averaging; alpha is ignored. The mean over texels, not over the surface, is a
//!   simplification: a texture mapped unevenly (atlases, `KHR_texture_transform`) is weighted
//!   as if it covered the surface uniformly. Reflectance channels above [`MAX_REFLECTANCE`]
//!   (e.g. the default white ρ = 1, which the radiosity equation cannot take) are clamped, in
//!   one warning. The emitted radiance is
//!   L_e = `emissiveFactor` × mean(`emissiveTexture`) × `emissiveStrength` ×
//!   [`GltfOptions::emission_scale`] in W·m⁻²·sr⁻¹: glTF gives emission no physical unit, so
//!   one unit of emissive colour is taken as `emission_scale` W·m⁻²·sr⁻¹ (default 1).
//!   `doubleSided` sets [`Material::two_sided`]. Metallic-roughness, normal and occlusion
//!   textures, `alphaMode` BLEND/MASK and the transmission/volume/unlit/specular-glossiness
//!   extensions are ignored with one warning each. A primitive without a material gets the
//!   spec's default material (white, one-sided).
//! - **Camera** (§3.10): the first node, in depth-first scene order, with a perspective camera.
//!   A camera looks down its local −Z with +Y up (§3.10.1), so eye = M·(0,0,0),
//!   forward = M·(0,0,−1), up = M·(0,1,0); `yfov` (radians) becomes the vertical field of view
//!   in degrees. Orthographic cameras are skipped with a warning.
//! - **Lights** (`KHR_lights_punctual`): point and spot lights become [`Light`]s placed at the
//!   node, aimed down its local −Z ([`Distribution::Isotropic`] / [`Distribution::Spot`], cone
//!   angles converted to degrees). The extension gives the luminous intensity in candela and a
//!   linear RGB colour; the project converts photometric to radiometric quantities at 683 lm/W
//!   with luminance Y = 0.2126 R + 0.7152 G + 0.0722 B of linear sRGB
//!   ([`crate::units::radiometric_from_photometric`]), so the colour sets the chromaticity and
//!   the radiant intensity per channel is I_c = cd / 683 × colour_c / Y(colour) W·sr⁻¹ (a white
//!   light of 683 cd is 1 W·sr⁻¹ per channel). `range` is ignored (the inverse-square law holds
//!   everywhere) and directional lights are not supported; both are reported as warnings, and
//!   a directional light is dropped from the scene.
//! - **Quads**: two consecutive triangles of a primitive that share an edge and together form
//!   a planar convex quadrilateral become one quad surface, as the exporter's author modelled
//!   it (exporters write each quad as two such triangles), so that it meshes on a bilinear
//!   lattice exactly like the same quad read from OBJ.
//!
//! Bad input never panics and never allocates without bound: the GLB container is parsed
//! here (the `gltf` crate's GLB reader underflows on a header length below 12), the JSON is
//! validated by the `gltf` crate (references, enums, required fields), and accessors are read
//! here with checked arithmetic against their buffer views, so an accessor can never claim more
//! elements than its bytes hold; accessors without a buffer view (all-zero sparse bases) are
//! capped relative to the file's buffer bytes, and the total triangle count is checked against
//! [`GltfOptions::max_triangles`] before any triangle is built. With [`GltfOptions::strict`]
//! every warning is an error.
//!
//! See also: [`crate::io::obj`], the other mesh format; `crate::export` for the way back out.

use crate::geometry::{GeometryError, Polygon};
use crate::light::{Aim, Distribution, Light};
use crate::scene::{Camera, Material, MaterialId, Origin, Scene, Surface};
use glam::{DMat4, DQuat, DVec3, DVec4};
use gltf::json::validation::Validate;
use std::collections::{HashMap, HashSet};
use std::fmt;
use std::io::Read;
use std::path::{Path, PathBuf};

/// Largest reflectance a material may keep; channels above it are clamped (ρ = 1 would make the
/// radiosity system singular for a closed scene, and no real diffuse surface exceeds 0.99).
pub const MAX_REFLECTANCE: f64 = 0.99;

/// The project's luminous efficacy for converting photometric to radiometric quantities, lm/W
/// ([`crate::units::LUMINOUS_EFFICACY`]).
pub const LUMENS_PER_WATT: f64 = crate::units::LUMINOUS_EFFICACY;

/// Default of [`GltfOptions::max_triangles`].
pub const DEFAULT_MAX_TRIANGLES: usize = 4_000_000;

/// How many triangles a [`GltfWarning::DegenerateTriangles`] names.
const NAMED_TRIANGLES: usize = 5;

/// Largest texture side (texels) decoded for a reflectance mean.
const MAX_TEXTURE_SIDE: u32 = 16_384;

/// Options for [`load_gltf`].
#[derive(Debug, Clone, PartialEq)]
pub struct GltfOptions {
    /// W·m⁻²·sr⁻¹ of emitted radiance per unit of glTF emissive colour
    /// (`emissiveFactor` × `emissiveStrength`); default 1.0.
    pub emission_scale: f64,
    /// Turn every warning into an error ([`GltfError::Strict`]).
    pub strict: bool,
    /// Refuse scenes with more triangles than this (all mesh instances together, counted from
    /// the accessors before any is read); default [`DEFAULT_MAX_TRIANGLES`].
    pub max_triangles: usize,
}

impl Default for GltfOptions {
    fn default() -> Self {
        Self {
            emission_scale: 1.0,
            strict: false,
            max_triangles: DEFAULT_MAX_TRIANGLES,
        }
    }
}

/// A loaded glTF scene and what was ignored or changed on the way.
#[derive(Debug, Clone, PartialEq)]
pub struct GltfScene {
    /// The scene, named after the file stem.
    pub scene: Scene,
    /// At most one warning of each kind, in the order they were found.
    pub warnings: Vec<GltfWarning>,
}

/// One skipped triangle: the mesh, the primitive index within it and the triangle index within
/// the primitive (after strip/fan expansion).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TriangleRef {
    /// The mesh, as `mesh N 'name'`.
    pub mesh: String,
    /// Primitive index within the mesh.
    pub primitive: usize,
    /// Triangle index within the primitive.
    pub triangle: usize,
}

/// Something in the file that the scene model cannot represent and that was ignored or
/// changed. Each kind appears at most once per load, aggregating every occurrence.
#[derive(Debug, Clone, PartialEq)]
pub enum GltfWarning {
    /// Zero-area triangles (repeated or collinear vertices, or a singular transform) were
    /// skipped; `first` names up to five.
    DegenerateTriangles {
        /// How many were skipped.
        count: usize,
        /// The first few.
        first: Vec<TriangleRef>,
    },
    /// Materials whose reflectance had a channel above [`MAX_REFLECTANCE`], clamped to it.
    ClampedReflectance {
        /// The materials' names.
        materials: Vec<String>,
    },
    /// Texture maps that a diffuse model does not use (metallic-roughness, normal, occlusion).
    IgnoredTextureMaps {
        /// (material, map names).
        maps: Vec<(String, Vec<&'static str>)>,
    },
    /// Transparency and other non-diffuse material features that were ignored: `alphaMode`
    /// BLEND/MASK, transmission, volume, unlit, specular-glossiness.
    IgnoredMaterialFeatures {
        /// (material, feature names).
        features: Vec<(String, Vec<String>)>,
    },
    /// Lights whose `range` was ignored (the inverse-square law is used everywhere).
    IgnoredLightRange {
        /// The lights' names.
        lights: Vec<String>,
    },
    /// Directional lights, which the scene model cannot represent; they are not in the scene.
    DirectionalLightsDropped {
        /// The lights' names.
        lights: Vec<String>,
    },
    /// Other content that was not used: orthographic cameras, skins, morph targets, GPU
    /// instances, trailing vertices that form no triangle.
    Ignored {
        /// What kind of content.
        what: &'static str,
        /// Where it was.
        items: Vec<String>,
    },
}

impl fmt::Display for GltfWarning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            GltfWarning::DegenerateTriangles { count, first } => {
                let named: Vec<String> = first
                    .iter()
                    .map(|t| {
                        format!(
                            "{}, primitive {}, triangle {}",
                            t.mesh, t.primitive, t.triangle
                        )
                    })
                    .collect();
                let more = if *count > first.len() { ", …" } else { "" };
                write!(
                    f,
                    "{count} zero-area triangle(s) skipped ({}{more})",
                    named.join("; ")
                )
            }
            GltfWarning::ClampedReflectance { materials } => write!(
                f,
                "reflectance above {MAX_REFLECTANCE} clamped to {MAX_REFLECTANCE} in {} \
                 material(s): {}",
                materials.len(),
                quoted(materials)
            ),
            GltfWarning::IgnoredTextureMaps { maps } => {
                let list: Vec<String> = maps
                    .iter()
                    .map(|(m, names)| format!("'{m}' ({})", names.join(", ")))
                    .collect();
                write!(
                    f,
                    "texture maps ignored by the diffuse model: {}",
                    list.join("; ")
                )
            }
            GltfWarning::IgnoredMaterialFeatures { features } => {
                let list: Vec<String> = features
                    .iter()
                    .map(|(m, names)| format!("'{m}' ({})", names.join(", ")))
                    .collect();
                write!(
                    f,
                    "material features ignored (surfaces are opaque and Lambertian): {}",
                    list.join("; ")
                )
            }
            GltfWarning::IgnoredLightRange { lights } => write!(
                f,
                "light range ignored (inverse-square falloff everywhere) for {}",
                quoted(lights)
            ),
            GltfWarning::DirectionalLightsDropped { lights } => write!(
                f,
                "directional lights are not supported and were left out: {}",
                quoted(lights)
            ),
            GltfWarning::Ignored { what, items } => {
                write!(f, "{what} ignored: {}", items.join("; "))
            }
        }
    }
}

fn quoted(names: &[String]) -> String {
    names
        .iter()
        .map(|n| format!("'{n}'"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Why a glTF file could not be loaded. Every message starts with the file as the caller named
/// it, then names the node, mesh, primitive, accessor, material, light or camera involved.
#[derive(Debug, thiserror::Error)]
pub enum GltfError {
    /// The file (or an external buffer or image it names) could not be read.
    #[error("{file}: cannot read {what}: {source}")]
    Read {
        /// The glTF file.
        file: String,
        /// What could not be read (`the file`, `buffer 0 'scene.bin'`, …).
        what: String,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The GLB container or the JSON is malformed or fails the spec's schema checks.
    #[error("{file}: {message}")]
    Format {
        /// The glTF file.
        file: String,
        /// What is wrong, with the JSON path or byte offset.
        message: String,
    },
    /// A value that is present and well-formed but unusable, at a named place.
    #[error("{file}: {at}: {message}")]
    Invalid {
        /// The glTF file.
        file: String,
        /// Where: `mesh 0 'Cube', primitive 1`, `accessor 3 (POSITION of …)`, `node 2 'Lamp'`.
        at: String,
        /// What is wrong.
        message: String,
    },
    /// Content the loader does not support (points, lines, quantized positions, compressed
    /// meshes, external URLs).
    #[error("{file}: {at}: {message}")]
    Unsupported {
        /// The glTF file.
        file: String,
        /// Where.
        at: String,
        /// What is not supported.
        message: String,
    },
    /// A triangle that is not a usable polygon for a reason other than zero area (a coordinate
    /// that is not finite or out of range).
    #[error("{file}: {at}: {source}")]
    Geometry {
        /// The glTF file.
        file: String,
        /// The node, mesh, primitive and triangle.
        at: String,
        /// The geometric problem.
        #[source]
        source: GeometryError,
    },
    /// More triangles than [`GltfOptions::max_triangles`].
    #[error(
        "{file}: {count} triangles (all mesh instances) exceed the limit of {limit} \
         (GltfOptions::max_triangles)"
    )]
    TooManyTriangles {
        /// The glTF file.
        file: String,
        /// Triangles the file would produce (at least).
        count: u64,
        /// The limit.
        limit: usize,
    },
    /// The scene has no surface (no triangle survived).
    #[error("{file}: scene has no surfaces")]
    Empty {
        /// The glTF file.
        file: String,
    },
    /// A warning raised in strict mode.
    #[error("{file}: {warning} (strict mode)")]
    Strict {
        /// The glTF file.
        file: String,
        /// The warning.
        warning: GltfWarning,
    },
}

/// Loads a `.gltf` or `.glb` file (recognised by content: a GLB starts with `glTF`).
///
/// External buffers and images are resolved relative to the file's directory; `data:` URIs
/// (base64) are decoded. See the module documentation for the mapping onto [`Scene`].
/// Errors name the file as given in `path`.
pub fn load_gltf(path: &Path, options: &GltfOptions) -> Result<GltfScene, GltfError> {
    let file = path.display().to_string();
    let bytes =
        crate::io::open::read_checked(path, crate::io::open::Kind::Geometry).map_err(|source| {
            GltfError::Read {
                file: file.clone(),
                what: "the file".to_owned(),
                source,
            }
        })?;
    let dir = path.parent().unwrap_or(Path::new("")).to_path_buf();
    let name = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    parse_gltf(&bytes, &file, &dir, &name, options)
}

/// Parses a glTF or GLB already in memory; `file` labels errors and surface origins, `dir`
/// resolves relative URIs, `name` names the scene.
pub fn parse_gltf(
    bytes: &[u8],
    file: &str,
    dir: &Path,
    name: &str,
    options: &GltfOptions,
) -> Result<GltfScene, GltfError> {
    if !(options.emission_scale.is_finite() && options.emission_scale >= 0.0) {
        return Err(GltfError::Invalid {
            file: file.to_owned(),
            at: "options".to_owned(),
            message: format!(
                "emission_scale {} must be finite and ≥ 0",
                options.emission_scale
            ),
        });
    }
    let (json, bin) = if bytes.starts_with(b"glTF") {
        split_glb(bytes, file)?
    } else {
        (bytes, None)
    };
    let document = parse_document(json, file)?;
    let buffers = load_buffers(&document, bin, dir, file)?;
    let mut loader = Loader::new(&document, buffers, file, dir, options);
    loader.scene.name = name.to_owned();
    loader.run()?;
    loader.finish()
}

// ---------------------------------------------------------------------------------------------
// Container, JSON and buffers

const GLB_JSON: u32 = 0x4E4F_534A;
const GLB_BIN: u32 = 0x004E_4942;

/// Splits a GLB (§4, GLB File Format Specification) into its JSON chunk and optional BIN
/// chunk, checking every length against the bytes present.
fn split_glb<'b>(bytes: &'b [u8], file: &str) -> Result<(&'b [u8], Option<&'b [u8]>), GltfError> {
    let err = |message: String| GltfError::Format {
        file: file.to_owned(),
        message: format!("GLB: {message}"),
    };
    let u32_at = |offset: usize| -> Option<u32> {
        let b = bytes.get(offset..offset.checked_add(4)?)?;
        Some(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    };
    let (Some(version), Some(length)) = (u32_at(4), u32_at(8)) else {
        return Err(err(format!(
            "truncated header ({} bytes, 12 needed)",
            bytes.len()
        )));
    };
    if version != 2 {
        return Err(err(format!("version {version}, only 2 is supported")));
    }
    let length = length as usize;
    if length > bytes.len() {
        return Err(err(format!(
            "header says {length} bytes, file has {} (truncated)",
            bytes.len()
        )));
    }
    if length < 12 {
        return Err(err(format!("header length {length} is below 12")));
    }
    let data = &bytes[..length];
    let mut offset = 12;
    let mut chunks: Vec<(u32, &[u8])> = Vec::new();
    while offset < data.len() {
        let (Some(chunk_length), Some(kind)) = (u32_at(offset), u32_at(offset + 4)) else {
            return Err(err(format!("truncated chunk header at byte {offset}")));
        };
        if offset + 8 > data.len() {
            return Err(err(format!("truncated chunk header at byte {offset}")));
        }
        let start = offset + 8;
        let end = start
            .checked_add(chunk_length as usize)
            .filter(|&e| e <= data.len())
            .ok_or_else(|| {
                err(format!(
                    "chunk at byte {offset} claims {chunk_length} bytes, only {} remain \
                     (truncated)",
                    data.len() - start
                ))
            })?;
        chunks.push((kind, &data[start..end]));
        offset = end;
    }
    match chunks.as_slice() {
        [(GLB_JSON, json), rest @ ..] => {
            let bin = rest
                .first()
                .filter(|(kind, _)| *kind == GLB_BIN)
                .map(|(_, b)| *b);
            Ok((json, bin))
        }
        _ => Err(err("the first chunk is not the JSON chunk".to_owned())),
    }
}

/// Extensions a file may require that the loader handles or may safely ignore (with a
/// warning where light transport changes).
const KNOWN_EXTENSIONS: &[&str] = &[
    "KHR_lights_punctual",
    "KHR_materials_emissive_strength",
    "KHR_texture_transform",
    "KHR_materials_unlit",
    "KHR_materials_transmission",
    "KHR_materials_volume",
    "KHR_materials_ior",
    "KHR_materials_specular",
    "KHR_materials_clearcoat",
    "KHR_materials_sheen",
    "KHR_materials_iridescence",
    "KHR_materials_anisotropy",
    "KHR_materials_dispersion",
    "KHR_materials_pbrSpecularGlossiness",
    "KHR_materials_variants",
];

/// Material extensions that change how light leaves a surface beyond its specular lobe:
/// ignored with [`GltfWarning::IgnoredMaterialFeatures`].
const WARNED_MATERIAL_EXTENSIONS: &[&str] = &[
    "KHR_materials_transmission",
    "KHR_materials_volume",
    "KHR_materials_diffuse_transmission",
    "KHR_materials_unlit",
    "KHR_materials_pbrSpecularGlossiness",
];

/// Deserialises and validates the JSON with the `gltf` crate. Its check of
/// `extensionsRequired` only knows the crate's compiled-in extensions, so that one is done
/// here against [`KNOWN_EXTENSIONS`] instead, naming the extension.
fn parse_document(json: &[u8], file: &str) -> Result<gltf::Document, GltfError> {
    let root: gltf::json::Root =
        gltf::json::deserialize::from_slice(json).map_err(|e| GltfError::Format {
            file: file.to_owned(),
            message: format!("JSON: {e}"),
        })?;
    for extension in &root.extensions_required {
        if !KNOWN_EXTENSIONS.contains(&extension.as_str()) {
            return Err(GltfError::Unsupported {
                file: file.to_owned(),
                at: "extensionsRequired".to_owned(),
                message: format!("extension {extension} is required but not supported"),
            });
        }
    }
    precheck_references(&root, file)?;
    let mut problems: Vec<String> = Vec::new();
    root.validate(&root, gltf::json::Path::new, &mut |path, error| {
        let path = path().to_string();
        if !path.starts_with("extensionsRequired") {
            problems.push(format!("{path}: {error}"));
        }
    });
    if !problems.is_empty() {
        let more = if problems.len() > 5 {
            format!(" (and {} more)", problems.len() - 5)
        } else {
            String::new()
        };
        problems.truncate(5);
        return Err(GltfError::Format {
            file: file.to_owned(),
            message: format!("invalid glTF: {}{more}", problems.join("; ")),
        });
    }
    Ok(gltf::Document::from_json_without_validation(root))
}

/// The index check the `gltf` crate's validation needs before it runs: in gltf-json 1.4.1 the
/// primitive hook indexes `accessors[POSITION]` before the index itself is checked, so an
/// out-of-range POSITION panics inside `validate`.
fn precheck_references(root: &gltf::json::Root, file: &str) -> Result<(), GltfError> {
    let invalid = |at: String, message: String| GltfError::Format {
        file: file.to_owned(),
        message: format!("invalid glTF: {at}: {message}"),
    };
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            for (semantic, index) in &primitive.attributes {
                if index.value() >= root.accessors.len() {
                    return Err(invalid(
                        format!("meshes[{m}].primitives[{p}].attributes"),
                        format!(
                            "{semantic:?} refers to accessor {}, file has {}",
                            index.value(),
                            root.accessors.len()
                        ),
                    ));
                }
            }
        }
    }
    Ok(())
}

/// Reads every buffer: the GLB BIN chunk, a base64 `data:` URI, or a file relative to `dir`.
/// Each is cut to its `byteLength`; a shorter source is an error (truncated file).
fn load_buffers(
    document: &gltf::Document,
    bin: Option<&[u8]>,
    dir: &Path,
    file: &str,
) -> Result<Vec<Vec<u8>>, GltfError> {
    let mut buffers = Vec::new();
    for buffer in document.buffers() {
        let at = describe("buffer", buffer.index(), buffer.name());
        let length = buffer.length();
        let data = match buffer.source() {
            gltf::buffer::Source::Bin => bin
                .ok_or_else(|| GltfError::Invalid {
                    file: file.to_owned(),
                    at: at.clone(),
                    message: "has no URI and the file has no GLB BIN chunk".to_owned(),
                })?
                .to_vec(),
            gltf::buffer::Source::Uri(uri) => read_uri(uri, dir, Some(length), file, &at)?,
        };
        if data.len() < length {
            return Err(GltfError::Invalid {
                file: file.to_owned(),
                at,
                message: format!(
                    "byteLength is {length} but only {} bytes are present (truncated)",
                    data.len()
                ),
            });
        }
        let mut data = data;
        data.truncate(length);
        buffers.push(data);
    }
    Ok(buffers)
}

/// The bytes behind a URI: a `data:` URI (base64) or a relative file path (percent-decoded).
/// At most `limit` bytes are read from a file, so a small buffer naming a huge file reads
/// only what it declares.
fn read_uri(
    uri: &str,
    dir: &Path,
    limit: Option<usize>,
    file: &str,
    at: &str,
) -> Result<Vec<u8>, GltfError> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let Some((header, payload)) = rest.split_once(',') else {
            return Err(GltfError::Invalid {
                file: file.to_owned(),
                at: at.to_owned(),
                message: "data URI has no ','".to_owned(),
            });
        };
        if !header.ends_with(";base64") {
            return Err(GltfError::Unsupported {
                file: file.to_owned(),
                at: at.to_owned(),
                message: "data URI is not base64-encoded".to_owned(),
            });
        }
        return decode_base64(payload).map_err(|message| GltfError::Invalid {
            file: file.to_owned(),
            at: at.to_owned(),
            message: format!("data URI: {message}"),
        });
    }
    let scheme = uri
        .split_once(':')
        .filter(|(s, _)| {
            s.len() > 1
                && s.chars()
                    .all(|c| c.is_ascii_alphanumeric() || "+-.".contains(c))
        })
        .map(|(s, _)| s);
    if let Some(scheme) = scheme {
        return Err(GltfError::Unsupported {
            file: file.to_owned(),
            at: at.to_owned(),
            message: format!("URI scheme '{scheme}:' (only relative paths and data URIs)"),
        });
    }
    let relative = percent_decode(uri).ok_or_else(|| GltfError::Invalid {
        file: file.to_owned(),
        at: at.to_owned(),
        message: format!("URI '{uri}' has a malformed percent escape"),
    })?;
    let path: PathBuf = dir.join(&relative);
    let what = format!("{at} ('{}')", path.display());
    let read_error = |source| GltfError::Read {
        file: file.to_owned(),
        what: what.clone(),
        source,
    };
    let handle = crate::io::open::open_checked(&path, crate::io::open::Kind::Geometry)
        .map_err(read_error)?;
    let mut data = Vec::new();
    match limit {
        Some(limit) => handle
            .take(limit as u64)
            .read_to_end(&mut data)
            .map_err(read_error)?,
        None => {
            let mut handle = handle;
            handle.read_to_end(&mut data).map_err(read_error)?
        }
    };
    Ok(data)
}

/// RFC 4648 base64 (standard alphabet; padding optional; ASCII whitespace skipped).
fn decode_base64(text: &str) -> Result<Vec<u8>, String> {
    let mut out = Vec::with_capacity(text.len() / 4 * 3 + 3);
    let mut acc: u32 = 0;
    let mut bits = 0;
    let mut padding = 0;
    for (i, c) in text.bytes().enumerate() {
        let value = match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' => 62,
            b'/' => 63,
            b'=' => {
                padding += 1;
                continue;
            }
            b' ' | b'\n' | b'\r' | b'\t' => continue,
            _ => return Err(format!("invalid base64 character at offset {i}")),
        };
        if padding > 0 {
            return Err(format!("base64 data after padding at offset {i}"));
        }
        acc = (acc << 6) | u32::from(value);
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
            acc &= (1 << bits) - 1;
        }
    }
    if bits >= 6 || padding > 2 {
        return Err("truncated base64 data".to_owned());
    }
    Ok(out)
}

/// Decodes `%XX` escapes (RFC 3986); `None` for a malformed escape or invalid UTF-8.
fn percent_decode(text: &str) -> Option<String> {
    let bytes = text.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = std::str::from_utf8(bytes.get(i + 1..i + 3)?).ok()?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
}

/// `kind N 'name'`, or `kind N` without a name.
fn describe(kind: &str, index: usize, name: Option<&str>) -> String {
    match name {
        Some(n) => format!("{kind} {index} '{n}'"),
        None => format!("{kind} {index}"),
    }
}

// ---------------------------------------------------------------------------------------------
// Accessors

/// Component types (§3.6.2.2, Accessor Data Types).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Component {
    U8,
    U16,
    U32,
    F32,
    Other,
}

impl Component {
    fn of(data_type: gltf::accessor::DataType) -> Self {
        use gltf::accessor::DataType;
        match data_type {
            DataType::U8 => Self::U8,
            DataType::U16 => Self::U16,
            DataType::U32 => Self::U32,
            DataType::F32 => Self::F32,
            DataType::I8 | DataType::I16 => Self::Other,
        }
    }
}

// ---------------------------------------------------------------------------------------------
// The loader

/// One mesh instance: a node with a mesh and its world transform.
struct Instance<'d> {
    node: gltf::Node<'d>,
    world: DMat4,
}

struct Loader<'d> {
    document: &'d gltf::Document,
    buffers: Vec<Vec<u8>>,
    file: String,
    dir: PathBuf,
    options: GltfOptions,
    scene: Scene,
    /// glTF material index (None: the default material) → scene material.
    materials: HashMap<Option<usize>, MaterialId>,
    material_names: HashSet<String>,
    /// Image index → mean linear RGB of its texels.
    image_means: HashMap<usize, [f64; 3]>,
    degenerate: (usize, Vec<TriangleRef>),
    clamped: Vec<String>,
    texture_maps: Vec<(String, Vec<&'static str>)>,
    material_features: Vec<(String, Vec<String>)>,
    light_range: Vec<String>,
    directional: Vec<String>,
    orthographic: Vec<String>,
    skins_and_morphs: Vec<String>,
    leftovers: Vec<String>,
    gpu_instancing: Vec<String>,
    /// Total bytes of all buffers, the yardstick for accessors without a buffer view.
    buffer_bytes: usize,
}

impl<'d> Loader<'d> {
    fn new(
        document: &'d gltf::Document,
        buffers: Vec<Vec<u8>>,
        file: &str,
        dir: &Path,
        options: &GltfOptions,
    ) -> Self {
        let buffer_bytes = buffers.iter().map(Vec::len).sum();
        Self {
            document,
            buffers,
            file: file.to_owned(),
            dir: dir.to_path_buf(),
            options: options.clone(),
            scene: Scene::default(),
            materials: HashMap::new(),
            material_names: HashSet::new(),
            image_means: HashMap::new(),
            degenerate: (0, Vec::new()),
            clamped: Vec::new(),
            texture_maps: Vec::new(),
            material_features: Vec::new(),
            light_range: Vec::new(),
            directional: Vec::new(),
            orthographic: Vec::new(),
            skins_and_morphs: Vec::new(),
            leftovers: Vec::new(),
            gpu_instancing: Vec::new(),
            buffer_bytes,
        }
    }

    fn invalid(&self, at: impl Into<String>, message: impl Into<String>) -> GltfError {
        GltfError::Invalid {
            file: self.file.clone(),
            at: at.into(),
            message: message.into(),
        }
    }

    fn unsupported(&self, at: impl Into<String>, message: impl Into<String>) -> GltfError {
        GltfError::Unsupported {
            file: self.file.clone(),
            at: at.into(),
            message: message.into(),
        }
    }

    fn run(&mut self) -> Result<(), GltfError> {
        let instances = self.instances()?;
        self.check_triangle_budget(&instances)?;
        for instance in &instances {
            if let Some(mesh) = instance.node.mesh() {
                self.add_mesh_instance(instance, &mesh)?;
            }
            if self.scene.camera.is_none() {
                self.take_camera(instance)?;
            }
            self.take_light(instance)?;
        }
        Ok(())
    }

    /// Every node of the scene in depth-first pre-order with its world transform; an explicit
    /// stack (a deep chain cannot overflow the call stack) and a visited set (a cycle or a
    /// node with two parents is an error, not a hang).
    fn instances(&self) -> Result<Vec<Instance<'d>>, GltfError> {
        let document = self.document;
        let roots: Vec<gltf::Node<'d>> = match document
            .default_scene()
            .or_else(|| document.scenes().next())
        {
            Some(scene) => scene.nodes().collect(),
            None => {
                let children: HashSet<usize> = document
                    .nodes()
                    .flat_map(|n| n.children().map(|c| c.index()))
                    .collect();
                document
                    .nodes()
                    .filter(|n| !children.contains(&n.index()))
                    .collect()
            }
        };
        let mut visited = vec![false; document.nodes().len()];
        let mut stack: Vec<(gltf::Node<'d>, DMat4)> = roots
            .into_iter()
            .rev()
            .map(|n| (n, DMat4::IDENTITY))
            .collect();
        let mut out = Vec::new();
        while let Some((node, parent)) = stack.pop() {
            let at = describe("node", node.index(), node.name());
            if std::mem::replace(&mut visited[node.index()], true) {
                return Err(self.invalid(
                    at,
                    "is reached twice (a cycle, a node with two parents, or listed twice in \
                     the scene); glTF node hierarchies must be disjoint trees",
                ));
            }
            let world = parent * self.local_transform(&node, &at)?;
            let children: Vec<gltf::Node<'d>> = node.children().collect();
            for child in children.into_iter().rev() {
                stack.push((child, world));
            }
            out.push(Instance { node, world });
        }
        Ok(out)
    }

    /// The node's local matrix in f64: its `matrix` (column-major), or T·R·S with the
    /// quaternion normalised (§3.5.3). The bottom row must be (0, 0, 0, 1).
    fn local_transform(&self, node: &gltf::Node<'d>, at: &str) -> Result<DMat4, GltfError> {
        let matrix = match node.transform() {
            gltf::scene::Transform::Matrix { matrix } => {
                let cols = matrix.map(|c| c.map(f64::from));
                DMat4::from_cols_array_2d(&cols)
            }
            gltf::scene::Transform::Decomposed {
                translation,
                rotation,
                scale,
            } => {
                let q = DVec4::from_array(rotation.map(f64::from));
                let length = q.length();
                if !(length.is_finite() && length > 1e-6) {
                    return Err(self.invalid(
                        at,
                        format!("rotation {rotation:?} is not a unit quaternion"),
                    ));
                }
                let q = DQuat::from_vec4(q / length);
                DMat4::from_scale_rotation_translation(
                    DVec3::from_array(scale.map(f64::from)),
                    q,
                    DVec3::from_array(translation.map(f64::from)),
                )
            }
        };
        if !matrix.is_finite() {
            return Err(self.invalid(at, "transform has a non-finite value"));
        }
        if matrix.row(3).distance(DVec4::W) > 1e-6 {
            return Err(self.invalid(
                at,
                format!(
                    "matrix is projective (bottom row {:?}, expected [0, 0, 0, 1])",
                    matrix.row(3).to_array()
                ),
            ));
        }
        Ok(matrix)
    }

    /// Refuses, before reading any vertex, a file whose triangles (indices or vertex counts ×
    /// instances) exceed the limit, and bounds each accessor's claimed count.
    fn check_triangle_budget(&self, instances: &[Instance<'d>]) -> Result<(), GltfError> {
        let mut total: u64 = 0;
        for instance in instances {
            let Some(mesh) = instance.node.mesh() else {
                continue;
            };
            for primitive in mesh.primitives() {
                let count = primitive
                    .indices()
                    .or_else(|| primitive.get(&gltf::Semantic::Positions))
                    .map_or(0, |a| a.count() as u64);
                let triangles = match primitive.mode() {
                    gltf::mesh::Mode::Triangles => count / 3,
                    gltf::mesh::Mode::TriangleStrip | gltf::mesh::Mode::TriangleFan => {
                        count.saturating_sub(2)
                    }
                    _ => 0,
                };
                total = total.saturating_add(triangles);
            }
        }
        if total > self.options.max_triangles as u64 {
            return Err(GltfError::TooManyTriangles {
                file: self.file.clone(),
                count: total,
                limit: self.options.max_triangles,
            });
        }
        Ok(())
    }

    fn add_mesh_instance(
        &mut self,
        instance: &Instance<'d>,
        mesh: &gltf::Mesh<'d>,
    ) -> Result<(), GltfError> {
        let node = &instance.node;
        let node_at = describe("node", node.index(), node.name());
        let mesh_at = describe("mesh", mesh.index(), mesh.name());
        let object = node
            .name()
            .or(mesh.name())
            .map_or_else(|| format!("node{}", node.index()), str::to_owned);
        let group = mesh.name().unwrap_or_default().to_owned();
        if node.extension_value("EXT_mesh_gpu_instancing").is_some() {
            self.gpu_instancing.push(node_at.clone());
        }
        if node.skin().is_some() {
            self.skins_and_morphs
                .push(format!("{node_at}: skin (bind pose used)"));
        }
        if mesh.primitives().any(|p| p.morph_targets().len() > 0) {
            self.skins_and_morphs
                .push(format!("{mesh_at}: morph targets (base shape used)"));
        }
        let flip = instance.world.determinant() < 0.0;
        for primitive in mesh.primitives() {
            let prim_at = format!("{mesh_at}, primitive {}", primitive.index());
            let mode = primitive.mode();
            use gltf::mesh::Mode;
            if matches!(
                mode,
                Mode::Points | Mode::Lines | Mode::LineLoop | Mode::LineStrip
            ) {
                return Err(self.unsupported(
                    &prim_at,
                    format!(
                        "mode {mode:?} is not a surface; only TRIANGLES, TRIANGLE_STRIP and \
                         TRIANGLE_FAN can be loaded"
                    ),
                ));
            }
            let positions = self.read_positions(&primitive, &prim_at)?;
            let indices = match primitive.indices() {
                Some(accessor) => self.read_indices(&accessor, &prim_at, positions.len())?,
                None => (0..positions.len() as u32).collect(),
            };
            let (triangles, unused) = assemble(mode, &indices);
            if unused > 0 {
                self.leftovers.push(format!(
                    "{prim_at}: {} vertices for TRIANGLES, the last {unused} unused",
                    indices.len()
                ));
            }
            let material = self.material(primitive.material())?;
            let surface = |polygon: Polygon| Surface {
                object: object.clone(),
                group: group.clone(),
                material,
                polygon,
                origin: Origin {
                    file: Some(self.file.clone()),
                    line: None,
                },
            };
            // A valid triangle waiting to see whether the next one completes a quad with it.
            let mut pending: Option<([DVec3; 3], Polygon)> = None;
            let mut made = Vec::new();
            for (t, tri) in triangles.iter().enumerate() {
                let mut v = tri.map(|i| {
                    instance
                        .world
                        .transform_point3(DVec3::from_array(positions[i as usize].map(f64::from)))
                });
                if flip {
                    v.swap(1, 2);
                }
                match Polygon::new(v.to_vec()) {
                    Ok(polygon) => {
                        if let Some((first, triangle)) = pending.take() {
                            match merge_quad(&first, &v) {
                                Some(quad) => {
                                    made.push(surface(quad));
                                    continue;
                                }
                                None => made.push(surface(triangle)),
                            }
                        }
                        pending = Some((v, polygon));
                    }
                    Err(GeometryError::Degenerate { .. } | GeometryError::TooFewVertices(_)) => {
                        if let Some((_, triangle)) = pending.take() {
                            made.push(surface(triangle));
                        }
                        self.degenerate.0 += 1;
                        if self.degenerate.1.len() < NAMED_TRIANGLES {
                            self.degenerate.1.push(TriangleRef {
                                mesh: mesh_at.clone(),
                                primitive: primitive.index(),
                                triangle: t,
                            });
                        }
                    }
                    Err(source) => {
                        return Err(GltfError::Geometry {
                            file: self.file.clone(),
                            at: format!("{node_at}, {prim_at}, triangle {t}"),
                            source,
                        })
                    }
                }
            }
            if let Some((_, triangle)) = pending.take() {
                made.push(surface(triangle));
            }
            self.scene.surfaces.append(&mut made);
        }
        Ok(())
    }

    fn read_positions(
        &self,
        primitive: &gltf::Primitive<'d>,
        prim_at: &str,
    ) -> Result<Vec<[f32; 3]>, GltfError> {
        let accessor = primitive
            .get(&gltf::Semantic::Positions)
            .ok_or_else(|| self.invalid(prim_at, "has no POSITION attribute"))?;
        let at = format!(
            "{} (POSITION of {prim_at})",
            describe("accessor", accessor.index(), accessor.name())
        );
        if Component::of(accessor.data_type()) != Component::F32
            || accessor.dimensions() != gltf::accessor::Dimensions::Vec3
            || accessor.normalized()
        {
            return Err(self.unsupported(
                &at,
                format!(
                    "POSITION is {:?} {:?}{}; only float VEC3 is supported \
                     (KHR_mesh_quantization is not)",
                    accessor.data_type(),
                    accessor.dimensions(),
                    if accessor.normalized() {
                        " normalized"
                    } else {
                        ""
                    }
                ),
            ));
        }
        let bytes = self.gather(&accessor, 12, &at)?;
        Ok(bytes
            .chunks_exact(12)
            .map(|c| [0, 4, 8].map(|o| f32::from_le_bytes([c[o], c[o + 1], c[o + 2], c[o + 3]])))
            .collect())
    }

    fn read_indices(
        &self,
        accessor: &gltf::Accessor<'d>,
        prim_at: &str,
        vertex_count: usize,
    ) -> Result<Vec<u32>, GltfError> {
        let at = format!(
            "{} (indices of {prim_at})",
            describe("accessor", accessor.index(), accessor.name())
        );
        let size = match Component::of(accessor.data_type()) {
            Component::U8 => 1,
            Component::U16 => 2,
            Component::U32 => 4,
            _ => 0,
        };
        if size == 0 || accessor.dimensions() != gltf::accessor::Dimensions::Scalar {
            return Err(self.invalid(
                &at,
                format!(
                    "indices are {:?} {:?}; must be unsigned byte, short or int SCALAR",
                    accessor.data_type(),
                    accessor.dimensions()
                ),
            ));
        }
        let bytes = self.gather(accessor, size, &at)?;
        let indices: Vec<u32> = match size {
            1 => bytes.iter().map(|&b| u32::from(b)).collect(),
            2 => bytes
                .chunks_exact(2)
                .map(|c| u32::from(u16::from_le_bytes([c[0], c[1]])))
                .collect(),
            _ => bytes
                .chunks_exact(4)
                .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                .collect(),
        };
        if let Some((k, &i)) = indices
            .iter()
            .enumerate()
            .find(|(_, &i)| i as usize >= vertex_count)
        {
            return Err(self.invalid(
                &at,
                format!("index {k} is {i}, but POSITION has {vertex_count} vertices"),
            ));
        }
        Ok(indices)
    }

    /// The accessor's elements packed tightly (`element` bytes each), honouring `byteStride`
    /// and sparse substitution (§3.6.2.3, Sparse Accessors). Every range is checked against
    /// the bytes present, so the result is never larger than the buffer view it reads (or, for
    /// an accessor without a view, capped at 16 elements per buffer byte plus 64 Ki).
    fn gather(
        &self,
        accessor: &gltf::Accessor<'d>,
        element: usize,
        at: &str,
    ) -> Result<Vec<u8>, GltfError> {
        let count = accessor.count();
        if count == 0 {
            return Err(self.invalid(at, "count is 0 (must be ≥ 1)"));
        }
        let total = count
            .checked_mul(element)
            .ok_or_else(|| self.invalid(at, format!("count {count} overflows")))?;
        let mut out = match accessor.view() {
            Some(view) => {
                let data = self.view_bytes(&view, at)?;
                let stride = view.stride().unwrap_or(element);
                if stride < element {
                    return Err(self.invalid(
                        at,
                        format!("byteStride {stride} is smaller than the element ({element} B)"),
                    ));
                }
                let start = accessor.offset();
                let end = (count - 1)
                    .checked_mul(stride)
                    .and_then(|x| x.checked_add(start))
                    .and_then(|x| x.checked_add(element));
                if end.is_none_or(|e| e > data.len()) {
                    return Err(self.invalid(
                        at,
                        format!(
                            "{count} elements of {element} B (stride {stride}, offset {start}) \
                             do not fit in the {} B of {}",
                            data.len(),
                            describe("bufferView", view.index(), view.name())
                        ),
                    ));
                }
                if stride == element {
                    data[start..start + total].to_vec()
                } else {
                    let mut out = Vec::with_capacity(total);
                    for k in 0..count {
                        let s = start + k * stride;
                        out.extend_from_slice(&data[s..s + element]);
                    }
                    out
                }
            }
            None => {
                let cap = self.buffer_bytes.saturating_mul(16).saturating_add(1 << 16);
                if count > cap {
                    return Err(self.invalid(
                        at,
                        format!(
                            "count {count} without a bufferView is absurd for a file with \
                             {} buffer bytes",
                            self.buffer_bytes
                        ),
                    ));
                }
                vec![0; total]
            }
        };
        if let Some(sparse) = accessor.sparse() {
            self.apply_sparse(&sparse, &mut out, count, element, at)?;
        }
        Ok(out)
    }

    fn apply_sparse(
        &self,
        sparse: &gltf::accessor::sparse::Sparse<'d>,
        out: &mut [u8],
        count: usize,
        element: usize,
        at: &str,
    ) -> Result<(), GltfError> {
        let n = sparse.count();
        if n == 0 || n > count {
            return Err(self.invalid(
                at,
                format!("sparse count {n} must be in 1..={count} (the accessor's count)"),
            ));
        }
        let indices = sparse.indices();
        let size = match indices.index_type() {
            gltf::accessor::sparse::IndexType::U8 => 1,
            gltf::accessor::sparse::IndexType::U16 => 2,
            gltf::accessor::sparse::IndexType::U32 => 4,
        };
        let index_bytes = self.view_bytes(&indices.view(), at)?;
        let index_bytes = index_bytes
            .get(indices.offset()..)
            .and_then(|b| b.get(..n * size))
            .ok_or_else(|| self.invalid(at, "sparse indices do not fit in their bufferView"))?;
        let values = sparse.values();
        let value_bytes = self.view_bytes(&values.view(), at)?;
        let value_bytes = value_bytes
            .get(values.offset()..)
            .and_then(|b| b.get(..n * element))
            .ok_or_else(|| self.invalid(at, "sparse values do not fit in their bufferView"))?;
        let mut previous: Option<usize> = None;
        for k in 0..n {
            let b = &index_bytes[k * size..(k + 1) * size];
            let i = match size {
                1 => usize::from(b[0]),
                2 => usize::from(u16::from_le_bytes([b[0], b[1]])),
                _ => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize,
            };
            if i >= count || previous.is_some_and(|p| i <= p) {
                return Err(self.invalid(
                    at,
                    format!(
                        "sparse index {k} is {i}; indices must increase strictly and stay \
                         below {count}"
                    ),
                ));
            }
            previous = Some(i);
            out[i * element..(i + 1) * element]
                .copy_from_slice(&value_bytes[k * element..(k + 1) * element]);
        }
        Ok(())
    }

    /// The bytes of a buffer view, checked against its buffer.
    fn view_bytes(&self, view: &gltf::buffer::View<'d>, at: &str) -> Result<&[u8], GltfError> {
        let buffer = &self.buffers[view.buffer().index()];
        let start = view.offset();
        start
            .checked_add(view.length())
            .and_then(|end| buffer.get(start..end))
            .ok_or_else(|| {
                self.invalid(
                    at,
                    format!(
                        "{} (offset {start}, {} B) extends past its buffer ({} B)",
                        describe("bufferView", view.index(), view.name()),
                        view.length(),
                        buffer.len()
                    ),
                )
            })
    }

    // -----------------------------------------------------------------------------------------
    // Materials

    fn material(&mut self, material: gltf::Material<'d>) -> Result<MaterialId, GltfError> {
        if let Some(&id) = self.materials.get(&material.index()) {
            return Ok(id);
        }
        let base_name = match (material.index(), material.name()) {
            (_, Some(name)) => name.to_owned(),
            (Some(i), None) => format!("material{i}"),
            (None, None) => "gltf_default".to_owned(),
        };
        let mut name = base_name.clone();
        let mut k = 2;
        while self.material_names.contains(&name) {
            name = format!("{base_name}#{k}");
            k += 1;
        }
        let at = match material.index() {
            Some(i) => describe("material", i, material.name()),
            None => "the default material".to_owned(),
        };

        let pbr = material.pbr_metallic_roughness();
        let factor = pbr.base_color_factor();
        let mut reflectance = [0, 1, 2].map(|c| f64::from(factor[c]));
        if let Some(info) = pbr.base_color_texture() {
            let mean = self.texture_mean(&info.texture(), &at, "baseColorTexture")?;
            for c in 0..3 {
                reflectance[c] *= mean[c];
            }
        }
        if reflectance.iter().any(|r| !r.is_finite() || *r < 0.0) {
            return Err(self.invalid(
                &at,
                format!("baseColorFactor {factor:?} must be finite and ≥ 0"),
            ));
        }
        if reflectance.iter().any(|&r| r > MAX_REFLECTANCE) {
            reflectance = reflectance.map(|r| r.min(MAX_REFLECTANCE));
            self.clamped.push(name.clone());
        }

        let emissive = material.emissive_factor();
        let strength = material.emissive_strength().unwrap_or(1.0);
        let mut emission = [0, 1, 2]
            .map(|c| f64::from(emissive[c]) * f64::from(strength) * self.options.emission_scale);
        if let Some(info) = material.emissive_texture() {
            let mean = self.texture_mean(&info.texture(), &at, "emissiveTexture")?;
            for c in 0..3 {
                emission[c] *= mean[c];
            }
        }
        if emission.iter().any(|e| !e.is_finite() || *e < 0.0) {
            return Err(self.invalid(
                &at,
                format!(
                    "emission (emissiveFactor {emissive:?} × emissiveStrength {strength}) \
                     must be finite and ≥ 0"
                ),
            ));
        }

        let mut maps = Vec::new();
        if pbr.metallic_roughness_texture().is_some() {
            maps.push("metallicRoughnessTexture");
        }
        if material.normal_texture().is_some() {
            maps.push("normalTexture");
        }
        if material.occlusion_texture().is_some() {
            maps.push("occlusionTexture");
        }
        if !maps.is_empty() {
            self.texture_maps.push((name.clone(), maps));
        }
        let mut features = Vec::new();
        match material.alpha_mode() {
            gltf::material::AlphaMode::Opaque => {}
            gltf::material::AlphaMode::Blend => features.push("alphaMode BLEND".to_owned()),
            gltf::material::AlphaMode::Mask => features.push("alphaMode MASK".to_owned()),
        }
        if let Some(extensions) = material.extensions() {
            for key in extensions.keys() {
                if WARNED_MATERIAL_EXTENSIONS.contains(&key.as_str()) {
                    features.push(key.clone());
                }
            }
        }
        if !features.is_empty() {
            self.material_features.push((name.clone(), features));
        }

        let mut m = Material::new(name.clone(), reflectance, emission);
        m.two_sided = material.double_sided();
        let id = MaterialId(self.scene.materials.len() as u32);
        self.scene.materials.push(m);
        self.material_names.insert(name);
        self.materials.insert(material.index(), id);
        Ok(id)
    }

    /// Mean linear RGB of a texture's image over all texels (sRGB-decoded, alpha ignored).
    fn texture_mean(
        &mut self,
        texture: &gltf::Texture<'d>,
        material_at: &str,
        slot: &str,
    ) -> Result<[f64; 3], GltfError> {
        let image = texture.source();
        if let Some(mean) = self.image_means.get(&image.index()) {
            return Ok(*mean);
        }
        let at = format!(
            "{material_at}, {slot} ({}, {})",
            describe("texture", texture.index(), texture.name()),
            describe("image", image.index(), image.name())
        );
        let bytes: Vec<u8> = match image.source() {
            gltf::image::Source::View { view, .. } => self.view_bytes(&view, &at)?.to_vec(),
            gltf::image::Source::Uri { uri, .. } => {
                read_uri(uri, &self.dir, None, &self.file, &at)?
            }
        };
        let mean = image_mean_linear(&bytes).map_err(|m| self.invalid(&at, m))?;
        self.image_means.insert(image.index(), mean);
        Ok(mean)
    }

    // -----------------------------------------------------------------------------------------
    // Camera and lights

    fn take_camera(&mut self, instance: &Instance<'d>) -> Result<(), GltfError> {
        let Some(camera) = instance.node.camera() else {
            return Ok(());
        };
        let at = format!(
            "{} on {}",
            describe("camera", camera.index(), camera.name()),
            describe("node", instance.node.index(), instance.node.name())
        );
        let perspective = match camera.projection() {
            gltf::camera::Projection::Perspective(p) => p,
            gltf::camera::Projection::Orthographic(_) => {
                self.orthographic.push(at);
                return Ok(());
            }
        };
        let yfov = f64::from(perspective.yfov());
        if !(yfov > 0.0 && yfov < std::f64::consts::PI) {
            return Err(self.invalid(at, format!("yfov {yfov} rad must be in (0, π)")));
        }
        let world = instance.world;
        let eye = world.transform_point3(DVec3::ZERO);
        let forward = world.transform_vector3(DVec3::NEG_Z).try_normalize();
        let up = world.transform_vector3(DVec3::Y).try_normalize();
        let (Some(forward), Some(up)) = (forward, up) else {
            return Err(self.invalid(at, "the node's transform collapses the camera's axes"));
        };
        self.scene.camera = Some(Camera {
            eye,
            target: eye + forward,
            up,
            fov_deg: yfov.to_degrees(),
        });
        Ok(())
    }

    fn take_light(&mut self, instance: &Instance<'d>) -> Result<(), GltfError> {
        let Some(light) = instance.node.light() else {
            return Ok(());
        };
        let node = &instance.node;
        let name = light
            .name()
            .or(node.name())
            .map_or_else(|| format!("light{}", light.index()), str::to_owned);
        let at = format!(
            "{} on {}",
            describe("light", light.index(), light.name()),
            describe("node", node.index(), node.name())
        );
        use gltf::khr_lights_punctual::Kind;
        let distribution = match light.kind() {
            Kind::Directional => {
                self.directional.push(name);
                return Ok(());
            }
            Kind::Point => Distribution::Isotropic,
            Kind::Spot {
                inner_cone_angle,
                outer_cone_angle,
            } => {
                let (inner, outer) = (f64::from(inner_cone_angle), f64::from(outer_cone_angle));
                if !(inner >= 0.0 && inner < outer && outer <= std::f64::consts::FRAC_PI_2) {
                    return Err(self.invalid(
                        at,
                        format!(
                            "spot cone angles inner {inner} rad, outer {outer} rad must satisfy \
                             0 ≤ inner < outer ≤ π/2"
                        ),
                    ));
                }
                Distribution::Spot {
                    inner_deg: inner.to_degrees(),
                    outer_deg: outer.to_degrees(),
                }
            }
        };
        if light.range().is_some() {
            self.light_range.push(name.clone());
        }
        let candela = f64::from(light.intensity());
        let colour = light.color().map(f64::from);
        if !candela.is_finite()
            || candela < 0.0
            || colour.iter().any(|c| !c.is_finite() || *c < 0.0)
        {
            return Err(self.invalid(
                at,
                format!("intensity {candela} cd and colour {colour:?} must be finite and ≥ 0"),
            ));
        }
        let world = instance.world;
        let nadir = world.transform_vector3(DVec3::NEG_Z);
        let c0 = world.transform_vector3(DVec3::X);
        let aim = Aim::new(nadir, c0)
            .ok_or_else(|| self.invalid(&at, "the node's transform collapses the light's axes"))?;
        // Luminous intensity `candela` with the chromaticity of `colour`: 683 · Y(I) = cd.
        let intensity = if colour.iter().all(|&c| c == 0.0) {
            [0.0; 3]
        } else {
            crate::units::radiometric_from_photometric(candela, colour)
                .map_err(|e| self.invalid(&at, format!("colour: {e}")))?
        };
        self.scene.lights.push(Light {
            name,
            position: world.transform_point3(DVec3::ZERO),
            aim,
            distribution,
            intensity,
            origin: Origin {
                file: Some(self.file.clone()),
                line: None,
            },
        });
        Ok(())
    }

    // -----------------------------------------------------------------------------------------

    fn finish(mut self) -> Result<GltfScene, GltfError> {
        let mut warnings = Vec::new();
        let (count, first) = std::mem::take(&mut self.degenerate);
        if count > 0 {
            warnings.push(GltfWarning::DegenerateTriangles { count, first });
        }
        if !self.clamped.is_empty() {
            warnings.push(GltfWarning::ClampedReflectance {
                materials: std::mem::take(&mut self.clamped),
            });
        }
        if !self.texture_maps.is_empty() {
            warnings.push(GltfWarning::IgnoredTextureMaps {
                maps: std::mem::take(&mut self.texture_maps),
            });
        }
        if !self.material_features.is_empty() {
            warnings.push(GltfWarning::IgnoredMaterialFeatures {
                features: std::mem::take(&mut self.material_features),
            });
        }
        if !self.light_range.is_empty() {
            warnings.push(GltfWarning::IgnoredLightRange {
                lights: std::mem::take(&mut self.light_range),
            });
        }
        if !self.directional.is_empty() {
            warnings.push(GltfWarning::DirectionalLightsDropped {
                lights: std::mem::take(&mut self.directional),
            });
        }
        if !self.orthographic.is_empty() {
            warnings.push(GltfWarning::Ignored {
                what: "orthographic cameras",
                items: std::mem::take(&mut self.orthographic),
            });
        }
        if !self.skins_and_morphs.is_empty() {
            warnings.push(GltfWarning::Ignored {
                what: "skins and morph targets",
                items: std::mem::take(&mut self.skins_and_morphs),
            });
        }
        if !self.gpu_instancing.is_empty() {
            warnings.push(GltfWarning::Ignored {
                what: "EXT_mesh_gpu_instancing instances (each mesh is placed once, by its node)",
                items: std::mem::take(&mut self.gpu_instancing),
            });
        }
        if !self.leftovers.is_empty() {
            warnings.push(GltfWarning::Ignored {
                what: "trailing vertices that form no triangle",
                items: std::mem::take(&mut self.leftovers),
            });
        }
        if self.options.strict {
            if let Some(warning) = warnings.first() {
                return Err(GltfError::Strict {
                    file: self.file,
                    warning: warning.clone(),
                });
            }
        }
        if self.scene.surfaces.is_empty() {
            return Err(GltfError::Empty { file: self.file });
        }
        Ok(GltfScene {
            scene: self.scene,
            warnings,
        })
    }
}

/// Expands a primitive's index list into triangles (§3.7.2.1): TRIANGLES takes consecutive
/// triples; TRIANGLE_STRIP triangle i is (i, i+1+i%2, i+2−i%2) so every triangle keeps the
/// strip's orientation; TRIANGLE_FAN triangle i is (i+1, i+2, 0). Also returns how many
/// trailing TRIANGLES vertices form no triangle (the Khronos validator treats a count that is
/// not a multiple of 3 as a warning, not an error: KhronosGroup/glTF issue 1674).
/// The quadrilateral two consecutive triangles form, if they share an edge (traversed in
/// opposite directions, so both face the same way) and together make a planar convex quad
/// with no straight corner: `a` = (u, v, w) and `b` = (v, u, x) give (u, x, v, w), rotated to
/// start at `a`'s first vertex. Exporters write a quad as two such triangles (a fan from its
/// first corner), so the quad comes back as the file's author modelled it, and meshes on a
/// bilinear lattice like the same quad read from OBJ.
fn merge_quad(a: &[DVec3; 3], b: &[DVec3; 3]) -> Option<Polygon> {
    for i in 0..3 {
        let (u, v, w) = (a[i], a[(i + 1) % 3], a[(i + 2) % 3]);
        for j in 0..3 {
            if b[j] == v && b[(j + 1) % 3] == u {
                let x = b[(j + 2) % 3];
                if x == w {
                    return None;
                }
                // (u, x, v, w) rotated so that a[0] comes first.
                let quad = [u, x, v, w];
                let start = quad.iter().position(|p| *p == a[0])?;
                let vertices: Vec<DVec3> = (0..4).map(|k| quad[(start + k) % 4]).collect();
                let polygon = Polygon::new(vertices).ok()?;
                if polygon.vertices().len() != 4 {
                    return None;
                }
                // No corner may be (nearly) straight: that quad is really a triangle.
                let p = polygon.vertices();
                let n = polygon.normal();
                let straight = (0..4).any(|k| {
                    let (prev, here, next) = (p[(k + 3) % 4], p[k], p[(k + 1) % 4]);
                    let (e1, e2) = (here - prev, next - here);
                    e1.cross(e2).dot(n) <= 1e-6 * e1.length() * e2.length()
                });
                return (!straight).then_some(polygon);
            }
        }
    }
    None
}

fn assemble(mode: gltf::mesh::Mode, indices: &[u32]) -> (Vec<[u32; 3]>, usize) {
    use gltf::mesh::Mode;
    let n = indices.len();
    let triangles = match mode {
        Mode::Triangles => {
            return (
                indices
                    .chunks_exact(3)
                    .map(|t| [t[0], t[1], t[2]])
                    .collect(),
                n % 3,
            )
        }
        Mode::TriangleStrip => (0..n.saturating_sub(2))
            .map(|i| {
                let odd = i % 2;
                [indices[i], indices[i + 1 + odd], indices[i + 2 - odd]]
            })
            .collect(),
        Mode::TriangleFan => (0..n.saturating_sub(2))
            .map(|i| [indices[i + 1], indices[i + 2], indices[0]])
            .collect(),
        _ => Vec::new(),
    };
    (triangles, 0)
}

/// sRGB transfer function inverse (IEC 61966-2-1): encoded value in [0, 1] → linear.
fn srgb_to_linear(v: f64) -> f64 {
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

/// Decodes a PNG or JPEG and returns the mean of its texels in linear RGB. Grey images count as
/// R = G = B; alpha is ignored. Sizes above 16384 texels a side are refused.
fn image_mean_linear(bytes: &[u8]) -> Result<[f64; 3], String> {
    let mut reader = image::ImageReader::new(std::io::Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| format!("cannot read image: {e}"))?;
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(MAX_TEXTURE_SIDE);
    limits.max_image_height = Some(MAX_TEXTURE_SIDE);
    limits.max_alloc = Some(1 << 30);
    reader.limits(limits);
    let decoded = reader
        .decode()
        .map_err(|e| format!("cannot decode image (PNG and JPEG are supported): {e}"))?;
    let channels = usize::from(decoded.color().channel_count());
    let colour = decoded.color().has_color();
    let mut sum = [0.0f64; 3];
    let mut add = |texel: &[f64]| {
        if colour {
            for c in 0..3 {
                sum[c] += texel[c];
            }
        } else {
            for s in &mut sum {
                *s += texel[0];
            }
        }
    };
    if let Some(samples) = decoded.as_flat_samples_u8() {
        let lut: Vec<f64> = (0..=255u8)
            .map(|b| srgb_to_linear(f64::from(b) / 255.0))
            .collect();
        let mut texel = [0.0; 4];
        for chunk in samples.samples.chunks_exact(channels) {
            for (t, &s) in texel.iter_mut().zip(chunk) {
                *t = lut[usize::from(s)];
            }
            add(&texel);
        }
    } else if let Some(samples) = decoded.as_flat_samples_u16() {
        let mut texel = [0.0; 4];
        for chunk in samples.samples.chunks_exact(channels) {
            for (t, &s) in texel.iter_mut().zip(chunk) {
                *t = srgb_to_linear(f64::from(s) / 65535.0);
            }
            add(&texel);
        }
    } else {
        for p in decoded.to_rgb32f().pixels() {
            add(&p.0.map(|v| srgb_to_linear(f64::from(v).clamp(0.0, 1.0))));
        }
    }
    let n = f64::from(decoded.width()) * f64::from(decoded.height());
    if n == 0.0 {
        return Err("image has no texels".to_owned());
    }
    Ok(sum.map(|s| s / n))
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::{json, Value};

    /// A small glTF writer for the tests: JSON built with `serde_json`, one binary buffer.
    /// Independent of `crate::export` so that the loader is not tested against its own
    /// project's writer.
    struct Builder {
        root: Value,
        bin: Vec<u8>,
    }

    impl Builder {
        fn new() -> Self {
            Self {
                root: json!({
                    "asset": {"version": "2.0", "generator": "radiosity tests"},
                    "scene": 0,
                    "scenes": [{"nodes": []}],
                }),
                bin: Vec::new(),
            }
        }

        /// Appends to the top-level array `key` and returns the index.
        fn push(&mut self, key: &str, value: Value) -> usize {
            let array = self.root[key].as_array_mut();
            match array {
                Some(a) => {
                    a.push(value);
                    a.len() - 1
                }
                None => {
                    self.root[key] = json!([value]);
                    0
                }
            }
        }

        fn view(&mut self, bytes: &[u8]) -> usize {
            self.view_for(bytes, None)
        }

        fn view_for(&mut self, bytes: &[u8], target: Option<u32>) -> usize {
            while self.bin.len() % 4 != 0 {
                self.bin.push(0);
            }
            let offset = self.bin.len();
            self.bin.extend_from_slice(bytes);
            let mut view = json!({"buffer": 0, "byteOffset": offset, "byteLength": bytes.len()});
            if let Some(target) = target {
                view["target"] = json!(target);
            }
            self.push("bufferViews", view)
        }

        fn positions(&mut self, p: &[[f32; 3]]) -> usize {
            let bytes: Vec<u8> = p.iter().flatten().flat_map(|x| x.to_le_bytes()).collect();
            let view = self.view_for(&bytes, Some(34962));
            let mut lo = [f32::INFINITY; 3];
            let mut hi = [f32::NEG_INFINITY; 3];
            for v in p {
                for c in 0..3 {
                    lo[c] = lo[c].min(v[c]);
                    hi[c] = hi[c].max(v[c]);
                }
            }
            self.push(
                "accessors",
                json!({"bufferView": view, "componentType": 5126, "count": p.len(),
                       "type": "VEC3", "min": lo, "max": hi}),
            )
        }

        fn indices(&mut self, i: &[u32]) -> usize {
            let bytes: Vec<u8> = i.iter().flat_map(|&x| (x as u16).to_le_bytes()).collect();
            let view = self.view_for(&bytes, Some(34963));
            self.push(
                "accessors",
                json!({"bufferView": view, "componentType": 5123, "count": i.len(),
                       "type": "SCALAR"}),
            )
        }

        /// A mesh with one primitive.
        fn mesh(&mut self, name: &str, p: &[[f32; 3]], i: Option<&[u32]>, extra: Value) -> usize {
            let position = self.positions(p);
            let mut primitive = json!({"attributes": {"POSITION": position}});
            if let Some(i) = i {
                primitive["indices"] = json!(self.indices(i));
            }
            if let Value::Object(extra) = extra {
                for (k, v) in extra {
                    primitive[k] = v;
                }
            }
            self.push("meshes", json!({"name": name, "primitives": [primitive]}))
        }

        /// A node added to the default scene's roots.
        fn root_node(&mut self, node: Value) -> usize {
            let n = self.push("nodes", node);
            self.root["scenes"][0]["nodes"]
                .as_array_mut()
                .unwrap()
                .push(json!(n));
            n
        }

        fn json_with_buffer(&self, uri: Option<String>) -> Value {
            let mut root = self.root.clone();
            if !self.bin.is_empty() {
                let mut buffer = json!({"byteLength": self.bin.len()});
                if let Some(uri) = uri {
                    buffer["uri"] = json!(uri);
                }
                root["buffers"] = json!([buffer]);
            }
            root
        }

        fn glb(&self) -> Vec<u8> {
            let mut json = serde_json::to_vec(&self.json_with_buffer(None)).unwrap();
            while json.len() % 4 != 0 {
                json.push(b' ');
            }
            let mut bin = self.bin.clone();
            while bin.len() % 4 != 0 {
                bin.push(0);
            }
            let total = 12 + 8 + json.len() + if bin.is_empty() { 0 } else { 8 + bin.len() };
            let mut out = Vec::new();
            out.extend_from_slice(b"glTF");
            out.extend_from_slice(&2u32.to_le_bytes());
            out.extend_from_slice(&(total as u32).to_le_bytes());
            out.extend_from_slice(&(json.len() as u32).to_le_bytes());
            out.extend_from_slice(b"JSON");
            out.extend_from_slice(&json);
            if !bin.is_empty() {
                out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
                out.extend_from_slice(b"BIN\0");
                out.extend_from_slice(&bin);
            }
            out
        }

        fn embedded(&self) -> Vec<u8> {
            let uri = format!(
                "data:application/octet-stream;base64,{}",
                encode_base64(&self.bin)
            );
            serde_json::to_vec_pretty(&self.json_with_buffer(Some(uri))).unwrap()
        }
    }

    fn encode_base64(bytes: &[u8]) -> String {
        const ALPHABET: &[u8] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
        let mut out = String::new();
        for chunk in bytes.chunks(3) {
            let b = [
                chunk[0],
                *chunk.get(1).unwrap_or(&0),
                *chunk.get(2).unwrap_or(&0),
            ];
            let n = u32::from(b[0]) << 16 | u32::from(b[1]) << 8 | u32::from(b[2]);
            for k in 0..4 {
                if k <= chunk.len() {
                    out.push(ALPHABET[(n >> (18 - 6 * k) & 63) as usize] as char);
                } else {
                    out.push('=');
                }
            }
        }
        out
    }

    fn parse(bytes: &[u8], options: &GltfOptions) -> Result<GltfScene, GltfError> {
        parse_gltf(bytes, "test.gltf", Path::new("."), "test", options)
    }

    fn load(bytes: &[u8]) -> GltfScene {
        parse(bytes, &GltfOptions::default()).unwrap()
    }

    fn err(bytes: &[u8]) -> GltfError {
        match parse(bytes, &GltfOptions::default()) {
            Ok(_) => panic!("expected an error"),
            Err(e) => e,
        }
    }

    const QUAD: [[f32; 3]; 4] = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
    ];
    const QUAD_INDICES: [u32; 6] = [0, 1, 2, 0, 2, 3];

    fn quad_builder() -> Builder {
        let mut b = Builder::new();
        b.push(
            "materials",
            json!({
                "name": "lamp",
                "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.25, 0.125, 1.0]},
                "emissiveFactor": [1.0, 0.5, 0.0],
                "doubleSided": true,
                "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 2.0}},
            }),
        );
        b.root["extensionsUsed"] = json!(["KHR_materials_emissive_strength"]);
        let mesh = b.mesh(
            "quad_mesh",
            &QUAD,
            Some(&QUAD_INDICES),
            json!({"material": 0}),
        );
        b.root_node(json!({"name": "quad", "mesh": mesh}));
        b
    }

    #[test]
    fn base64_matches_rfc4648_vectors() {
        let cases = [
            ("", ""),
            ("Zg==", "f"),
            ("Zm8=", "fo"),
            ("Zm9v", "foo"),
            ("Zm9vYg==", "foob"),
            ("Zm9vYmE=", "fooba"),
            ("Zm9vYmFy", "foobar"),
        ];
        for (encoded, plain) in cases {
            assert_eq!(decode_base64(encoded).unwrap(), plain.as_bytes());
            assert_eq!(encode_base64(plain.as_bytes()), encoded);
        }
        assert!(decode_base64("Zm9v!").is_err());
        assert!(decode_base64("Z").is_err());
        assert!(decode_base64("Zg==Zg").is_err());
        assert_eq!(percent_decode("my%20mesh.bin").unwrap(), "my mesh.bin");
        assert!(percent_decode("bad%2").is_none());
    }

    #[test]
    fn unit_quad_comes_back_as_one_quad_with_material() {
        let options = GltfOptions {
            emission_scale: 3.0,
            ..GltfOptions::default()
        };
        let loaded = parse(&quad_builder().embedded(), &options).unwrap();
        assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
        let scene = &loaded.scene;
        assert_eq!(scene.name, "test");
        // Its two triangles (0 1 2, 0 2 3) merge back into the quad, in the file's order.
        assert_eq!(scene.surfaces.len(), 1);
        let quad: Vec<DVec3> = QUAD
            .iter()
            .map(|p| DVec3::from_array(p.map(f64::from)))
            .collect();
        assert_eq!(scene.surfaces[0].polygon.vertices(), quad.as_slice());
        for s in &scene.surfaces {
            assert_eq!(s.object, "quad");
            assert_eq!(s.group, "quad_mesh");
            // The unit square, exactly representable.
            assert_eq!(s.polygon.area(), 1.0);
            assert_eq!(s.polygon.normal(), DVec3::Z);
            assert_eq!(s.origin.file.as_deref(), Some("test.gltf"));
        }
        assert_eq!(scene.total_area(), 1.0);
        let m = scene.material(&scene.surfaces[0]);
        assert_eq!(m.name, "lamp");
        // Factors that are exact in f32, so equality is exact.
        assert_eq!(m.reflectance, [0.5, 0.25, 0.125]);
        // L_e = emissiveFactor × strength (2) × emission_scale (3).
        assert_eq!(m.emission, [6.0, 3.0, 0.0]);
        assert!(m.two_sided);
        assert!(scene.camera.is_none() && scene.lights.is_empty());
    }

    #[test]
    fn only_coplanar_convex_pairs_merge_into_quads() {
        let p = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
        let (a, b, c, d) = (p(0., 0., 0.), p(1., 0., 0.), p(1., 1., 0.), p(0., 1., 0.));
        // Fan of a square from a: the square, starting at a.
        let quad = merge_quad(&[a, b, c], &[a, c, d]).unwrap();
        assert_eq!(quad.vertices(), [a, b, c, d]);
        // The other diagonal, and the pair given in the other order: still the square.
        assert_eq!(merge_quad(&[b, c, d], &[b, d, a]).unwrap().area(), 1.0);
        // Folded along the diagonal (not planar), facing opposite ways, sharing only a vertex,
        // or concave: left as triangles.
        assert!(merge_quad(&[a, b, c], &[a, c, p(0., 1., 0.5)]).is_none());
        assert!(merge_quad(&[a, b, c], &[a, d, c]).is_none());
        assert!(merge_quad(&[a, b, c], &[a, d, p(-1., 0., 0.)]).is_none());
        assert!(merge_quad(&[a, b, c], &[a, c, p(0.9, 0.2, 0.)]).is_none());
        // Two triangles that make a triangle (a straight corner at b): not a quad.
        let e = p(2., 0., 0.);
        assert!(merge_quad(&[a, b, c], &[b, e, c]).is_none());
    }

    #[test]
    fn external_bin_data_uri_and_glb_load_the_same_surfaces() {
        let b = quad_builder();
        let dir = tempfile::tempdir().unwrap();
        // A space in the file name: the URI must be percent-encoded.
        std::fs::write(dir.path().join("my mesh.bin"), &b.bin).unwrap();
        let json =
            serde_json::to_vec(&b.json_with_buffer(Some("my%20mesh.bin".to_owned()))).unwrap();
        let gltf_path = dir.path().join("quad.gltf");
        std::fs::write(&gltf_path, json).unwrap();
        let glb_path = dir.path().join("quad.glb");
        std::fs::write(&glb_path, b.glb()).unwrap();

        let external = load_gltf(&gltf_path, &GltfOptions::default()).unwrap();
        let glb = load_gltf(&glb_path, &GltfOptions::default()).unwrap();
        let embedded = load(&b.embedded());
        assert_eq!(external.scene.name, "quad");
        assert_eq!(external.scene.surfaces.len(), 1);
        for (a, b) in external.scene.surfaces.iter().zip(&glb.scene.surfaces) {
            assert_eq!(a.polygon, b.polygon);
        }
        for (a, b) in external.scene.surfaces.iter().zip(&embedded.scene.surfaces) {
            assert_eq!(a.polygon, b.polygon);
        }
        assert_eq!(external.scene.materials, glb.scene.materials);

        // The external buffer is missing: the error names the file and the buffer path.
        std::fs::remove_file(dir.path().join("my mesh.bin")).unwrap();
        let e = load_gltf(&gltf_path, &GltfOptions::default()).unwrap_err();
        let text = e.to_string();
        assert!(
            text.contains("quad.gltf") && text.contains("my mesh.bin"),
            "{text}"
        );
        // A truncated external buffer is an error, not a short read.
        std::fs::write(dir.path().join("my mesh.bin"), &b.bin[..10]).unwrap();
        let text = load_gltf(&gltf_path, &GltfOptions::default())
            .unwrap_err()
            .to_string();
        assert!(text.contains("truncated"), "{text}");
    }

    #[test]
    fn node_hierarchy_accumulates_trs_and_matrix() {
        let mut b = Builder::new();
        let tri = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let mesh = b.mesh("tri", &tri, None, json!({}));
        // Child: matrix = translation (0, 0, 1), column-major.
        let child = b.push(
            "nodes",
            json!({"name": "child", "mesh": mesh,
                   "matrix": [1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,1,1]}),
        );
        // Parent: T = (1, 2, 3), R = 90° about +z, S = 2.
        let h = std::f32::consts::FRAC_1_SQRT_2;
        b.root_node(json!({"name": "parent", "children": [child],
                           "translation": [1, 2, 3], "rotation": [0, 0, h, h],
                           "scale": [2, 2, 2]}));
        let scene = load(&b.embedded()).scene;
        assert_eq!(scene.surfaces.len(), 1);
        let s = &scene.surfaces[0];
        assert_eq!(s.object, "child");
        // By hand: p → child (+z) → scale 2 → rotate (x, y) → (−y, x) → translate (1, 2, 3).
        // (0,0,0) → (0,0,1) → (0,0,2) → (0,0,2) → (1,2,5)
        // (1,0,0) → (1,0,1) → (2,0,2) → (0,2,2) → (1,4,5)
        // (0,1,0) → (0,1,1) → (0,2,2) → (−2,0,2) → (−1,2,5)
        let expected = [
            DVec3::new(1.0, 2.0, 5.0),
            DVec3::new(1.0, 4.0, 5.0),
            DVec3::new(-1.0, 2.0, 5.0),
        ];
        for (v, e) in s.polygon.vertices().iter().zip(expected) {
            // The quaternion component 1/√2 is rounded to f32 (relative 3e-8); after
            // normalisation the rotation is exact to ~1e-7, times lengths ≤ 2.
            assert!(v.distance(e) < 1e-6, "{v} vs {e}");
        }
        // Area scales by 2² = 4: 0.5 → 2.
        assert!((s.polygon.area() - 2.0).abs() < 1e-6);
        assert!((s.polygon.normal() - DVec3::Z).length() < 1e-6);
    }

    #[test]
    fn mirroring_transform_keeps_the_front_face() {
        for (scale, mirrored) in [([1.0, 1.0, 1.0], false), ([-1.0, 1.0, 1.0], true)] {
            let mut b = Builder::new();
            let mesh = b.mesh("quad", &QUAD, Some(&QUAD_INDICES), json!({}));
            b.root_node(json!({"mesh": mesh, "scale": scale}));
            let scene = load(&b.embedded()).scene;
            assert_eq!(scene.surfaces.len(), 1);
            for s in &scene.surfaces {
                // The quad faces +z; a mirror in x keeps the face in the same plane facing +z
                // (the spec: a negative determinant means clockwise winding).
                assert_eq!(s.polygon.normal(), DVec3::Z, "mirrored: {mirrored}");
                // Unnamed node: object falls back to the mesh name.
                assert_eq!(s.object, "quad");
                if mirrored {
                    assert!(s.polygon.vertices().iter().all(|v| v.x <= 0.0));
                }
            }
        }
    }

    #[test]
    fn strips_and_fans_become_front_facing_triangles() {
        let mut b = Builder::new();
        // Strip over the unit square: (0,0) (1,0) (0,1) (1,1).
        let strip = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [1.0, 1.0, 0.0],
        ];
        let m = b.mesh("strip", &strip, None, json!({"mode": 5}));
        b.root_node(json!({"mesh": m}));
        // Fan: a regular pentagon of circumradius 1 around its centre vertex 0.
        let mut fan = vec![[0.0f32, 0.0, 1.0]];
        for k in 0..=5 {
            let a = 2.0 * std::f32::consts::PI * k as f32 / 5.0;
            fan.push([a.cos(), a.sin(), 1.0]);
        }
        let m = b.mesh("fan", &fan, None, json!({"mode": 6}));
        b.root_node(json!({"mesh": m}));
        let scene = load(&b.embedded()).scene;
        let strip: Vec<&Surface> = scene
            .surfaces
            .iter()
            .filter(|s| s.object == "strip")
            .collect();
        let fan: Vec<&Surface> = scene
            .surfaces
            .iter()
            .filter(|s| s.object == "fan")
            .collect();
        // The strip's two triangles form the square; the fan's five triangles give two
        // convex quads (centre and three rim points) and the last triangle.
        assert_eq!(strip.len(), 1);
        assert_eq!(fan.len(), 3);
        for s in strip.iter().chain(&fan) {
            assert!((s.polygon.normal() - DVec3::Z).length() < 1e-9);
        }
        let strip_area: f64 = strip.iter().map(|s| s.polygon.area()).sum();
        assert_eq!(strip_area, 1.0);
        // Regular pentagon of circumradius 1: (5/2)·sin(72°); vertices are f32 (1e-7).
        let fan_area: f64 = fan.iter().map(|s| s.polygon.area()).sum();
        let exact = 2.5 * (72f64).to_radians().sin();
        assert!((fan_area - exact).abs() < 1e-6, "{fan_area} vs {exact}");
    }

    #[test]
    fn points_and_lines_are_errors_naming_mesh_and_primitive() {
        for mode in [0, 1, 2, 3] {
            let mut b = Builder::new();
            let m = b.mesh("wires", &QUAD, None, json!({"mode": mode}));
            b.root_node(json!({"mesh": m}));
            let e = err(&b.embedded());
            assert!(matches!(e, GltfError::Unsupported { .. }), "{e}");
            let text = e.to_string();
            assert!(
                text.starts_with("test.gltf: mesh 0 'wires', primitive 0: mode"),
                "{text}"
            );
        }
    }

    #[test]
    fn zero_area_triangles_are_skipped_with_one_warning() {
        let mut b = Builder::new();
        let p = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [2.0, 0.0, 0.0],
        ];
        // Triangle 0 fine; 1 repeats a vertex; 2 is collinear; 3 fine.
        let i = [0, 1, 2, 0, 1, 1, 0, 1, 3, 1, 2, 0];
        let m = b.mesh("sliver", &p, Some(&i), json!({}));
        b.root_node(json!({"mesh": m}));
        let loaded = load(&b.embedded());
        assert_eq!(loaded.scene.surfaces.len(), 2);
        let expected = GltfWarning::DegenerateTriangles {
            count: 2,
            first: vec![
                TriangleRef {
                    mesh: "mesh 0 'sliver'".to_owned(),
                    primitive: 0,
                    triangle: 1,
                },
                TriangleRef {
                    mesh: "mesh 0 'sliver'".to_owned(),
                    primitive: 0,
                    triangle: 2,
                },
            ],
        };
        // The default material has ρ = 1: clamped, the second warning.
        assert_eq!(loaded.warnings[0], expected);
        assert_eq!(
            loaded.warnings[0].to_string(),
            "2 zero-area triangle(s) skipped (mesh 0 'sliver', primitive 0, triangle 1; \
             mesh 0 'sliver', primitive 0, triangle 2)"
        );
        let strict = GltfOptions {
            strict: true,
            ..GltfOptions::default()
        };
        match parse(&b.embedded(), &strict) {
            Err(GltfError::Strict { warning, .. }) => assert_eq!(warning, expected),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn application_specific_attributes_are_accepted() {
        let mut b = quad_builder();
        // `_TEMPERATURE` (spec: custom semantics start with an underscore) reuses POSITION.
        b.root["meshes"][0]["primitives"][0]["attributes"]["_TEMPERATURE"] = json!(0);
        assert_eq!(load(&b.embedded()).scene.surfaces.len(), 1);
    }

    #[test]
    fn gpu_instancing_is_reported() {
        let mut b = quad_builder();
        b.root["nodes"][0]["extensions"] = json!({"EXT_mesh_gpu_instancing": {"attributes": {}}});
        let loaded = load(&b.embedded());
        assert_eq!(loaded.scene.surfaces.len(), 1);
        assert!(matches!(
            &loaded.warnings[0],
            GltfWarning::Ignored { items, .. } if items == &["node 0 'quad'".to_owned()]
        ));
    }

    #[test]
    fn trailing_triangle_vertices_are_dropped_with_a_warning() {
        let mut b = Builder::new();
        let m = b.mesh("quad", &QUAD, Some(&[0, 1, 2, 0, 2]), json!({}));
        b.root_node(json!({"mesh": m}));
        let loaded = load(&b.embedded());
        assert_eq!(loaded.scene.surfaces.len(), 1);
        assert_eq!(
            loaded.warnings[1],
            GltfWarning::Ignored {
                what: "trailing vertices that form no triangle",
                items: vec![
                    "mesh 0 'quad', primitive 0: 5 vertices for TRIANGLES, the last 2 unused"
                        .to_owned()
                ]
            }
        );
    }

    #[test]
    fn default_material_is_white_clamped_with_a_warning() {
        let mut b = Builder::new();
        let m = b.mesh("quad", &QUAD, Some(&QUAD_INDICES), json!({}));
        b.root_node(json!({"mesh": m}));
        let loaded = load(&b.embedded());
        let m = &loaded.scene.materials[0];
        assert_eq!(m.name, "gltf_default");
        assert_eq!(m.reflectance, [MAX_REFLECTANCE; 3]);
        assert_eq!(m.emission, [0.0; 3]);
        assert!(!m.two_sided);
        assert_eq!(
            loaded.warnings,
            vec![GltfWarning::ClampedReflectance {
                materials: vec!["gltf_default".to_owned()]
            }]
        );
    }

    fn png_bytes(width: u32, height: u32, rgb: &[u8]) -> Vec<u8> {
        let mut out = Vec::new();
        image::ImageEncoder::write_image(
            image::codecs::png::PngEncoder::new(&mut out),
            rgb,
            width,
            height,
            image::ExtendedColorType::Rgb8,
        )
        .unwrap();
        out
    }

    /// A unit cube (24 vertices, 12 triangles, outward counter-clockwise faces) centred at
    /// `centre`.
    fn cube(centre: [f32; 3]) -> (Vec<[f32; 3]>, Vec<u32>) {
        let mut p = Vec::new();
        let mut i = Vec::new();
        for axis in 0..3 {
            for sign in [-1.0f32, 1.0] {
                let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
                let base = p.len() as u32;
                for (a, b) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                    let mut q = centre;
                    q[axis] += 0.5 * sign;
                    q[u] += 0.5 * a;
                    q[v] += 0.5 * b * sign;
                    p.push(q);
                }
                i.extend([base, base + 1, base + 2, base, base + 2, base + 3]);
            }
        }
        (p, i)
    }

    fn srgb_decode(byte: u8) -> f64 {
        let v = f64::from(byte) / 255.0;
        if v <= 0.04045 {
            v / 12.92
        } else {
            ((v + 0.055) / 1.055).powf(2.4)
        }
    }

    #[test]
    fn textured_cube_uses_the_linear_mean_of_the_texture() {
        let mut b = Builder::new();
        // Two texels: white and black in red; 188 and 0 in green; blue constant 128.
        let png = png_bytes(2, 1, &[255, 188, 128, 0, 0, 128]);
        let view = b.view(&png);
        b.push(
            "images",
            json!({"bufferView": view, "mimeType": "image/png"}),
        );
        b.push("textures", json!({"source": 0}));
        b.push(
            "materials",
            json!({"name": "painted",
                   "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.8, 0.8, 1],
                                            "baseColorTexture": {"index": 0},
                                            "metallicRoughnessTexture": {"index": 0}},
                   "normalTexture": {"index": 0}}),
        );
        let (p, i) = cube([0.5, 0.5, 0.5]);
        let m = b.mesh("cube", &p, Some(&i), json!({"material": 0}));
        b.root_node(json!({"name": "box", "mesh": m}));
        let loaded = load(&b.glb());
        let scene = &loaded.scene;
        // Six faces, each a quad again.
        assert_eq!(scene.surfaces.len(), 6);
        // Unit cube: area 6, every normal pointing away from the centre.
        assert!((scene.total_area() - 6.0).abs() < 1e-12);
        for s in &scene.surfaces {
            let out = s.polygon.centroid() - DVec3::splat(0.5);
            assert!(out.dot(s.polygon.normal()) > 0.0);
        }
        // ρ = factor × mean of the sRGB-decoded texels (not the decoded mean of codes):
        // red (1 + 0)/2 = 0.5 (decoding the mean code 127.5 would give 0.212).
        let expected = [
            0.8 * 0.5,
            0.8 * srgb_decode(188) / 2.0,
            0.8 * srgb_decode(128),
        ];
        let rho = scene.materials[0].reflectance;
        for c in 0..3 {
            // The factor 0.8 is f32 (relative 3e-8).
            assert!(
                (rho[c] - expected[c]).abs() < 1e-7,
                "{rho:?} vs {expected:?}"
            );
        }
        assert_eq!(
            loaded.warnings,
            vec![GltfWarning::IgnoredTextureMaps {
                maps: vec![(
                    "painted".to_owned(),
                    vec!["metallicRoughnessTexture", "normalTexture"]
                )]
            }]
        );
    }

    #[test]
    fn jpeg_texture_decodes() {
        // A uniform 8×8 JPEG: only the DC coefficient, so the decoded value is within a code
        // or two of the input.
        let mut jpeg = Vec::new();
        let rgb = [200u8, 100, 50].repeat(64);
        image::ImageEncoder::write_image(
            image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpeg, 95),
            &rgb,
            8,
            8,
            image::ExtendedColorType::Rgb8,
        )
        .unwrap();
        let mut b = Builder::new();
        let view = b.view(&jpeg);
        b.push(
            "images",
            json!({"bufferView": view, "mimeType": "image/jpeg"}),
        );
        b.push("textures", json!({"source": 0}));
        b.push(
            "materials",
            json!({"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}),
        );
        let m = b.mesh("quad", &QUAD, Some(&QUAD_INDICES), json!({"material": 0}));
        b.root_node(json!({"mesh": m}));
        let rho = load(&b.glb()).scene.materials[0].reflectance;
        for (c, code) in [200u8, 100, 50].into_iter().enumerate() {
            // ±3 codes of JPEG colour-conversion error, in linear terms.
            let (lo, hi) = (srgb_decode(code - 3), srgb_decode(code + 3));
            assert!(rho[c] > lo && rho[c] < hi, "channel {c}: {}", rho[c]);
        }
    }

    #[test]
    fn first_perspective_camera_looks_down_local_minus_z() {
        let mut b = Builder::new();
        let m = b.mesh("quad", &QUAD, Some(&QUAD_INDICES), json!({}));
        b.root_node(json!({"mesh": m}));
        b.push(
            "cameras",
            json!({"type": "orthographic",
                                 "orthographic": {"xmag": 1, "ymag": 1, "znear": 0.1, "zfar": 10}}),
        );
        b.push(
            "cameras",
            json!({"type": "perspective",
                                 "perspective": {"yfov": 0.5, "znear": 0.1}}),
        );
        b.push(
            "cameras",
            json!({"type": "perspective",
                                 "perspective": {"yfov": 1.0, "znear": 0.1}}),
        );
        let h = std::f32::consts::FRAC_1_SQRT_2;
        b.root_node(json!({"name": "ortho", "camera": 0}));
        // +90° about +x: local −Z → world +y, local +Y → world +z.
        b.root_node(json!({"name": "cam", "camera": 1, "translation": [1, 2, 3],
                           "rotation": [h, 0, 0, h]}));
        b.root_node(json!({"name": "second", "camera": 2}));
        let loaded = load(&b.embedded());
        let camera = loaded.scene.camera.unwrap();
        assert_eq!(camera.eye, DVec3::new(1.0, 2.0, 3.0));
        let forward = camera.target - camera.eye;
        // Rotation by an f32 quaternion: accurate to ~1e-7.
        assert!((forward - DVec3::Y).length() < 1e-6, "{forward}");
        assert!((camera.up - DVec3::Z).length() < 1e-6, "{}", camera.up);
        assert!((camera.fov_deg - 0.5f64.to_degrees()).abs() < 1e-9);
        assert!(matches!(
            &loaded.warnings[1],
            GltfWarning::Ignored { what: "orthographic cameras", items } if items[0].contains("ortho")
        ));
    }

    #[test]
    fn punctual_lights_convert_candela_to_watts_per_steradian() {
        let mut b = Builder::new();
        let m = b.mesh("quad", &QUAD, Some(&QUAD_INDICES), json!({}));
        b.root_node(json!({"mesh": m}));
        b.root["extensionsUsed"] = json!(["KHR_lights_punctual"]);
        b.root["extensions"] = json!({"KHR_lights_punctual": {"lights": [
            {"name": "bulb", "type": "point", "intensity": 683.0, "color": [1.0, 0.5, 0.0]},
            {"name": "spot", "type": "spot", "intensity": 100.0, "range": 5.0,
             "spot": {"innerConeAngle": std::f64::consts::FRAC_PI_8,
                      "outerConeAngle": std::f64::consts::FRAC_PI_4}},
            {"name": "sun", "type": "directional", "intensity": 3.0},
        ]}});
        let h = std::f32::consts::FRAC_1_SQRT_2;
        b.root_node(json!({"name": "n0", "translation": [1, 2, 3],
                           "extensions": {"KHR_lights_punctual": {"light": 0}}}));
        // −90° about +x: local −Z → world −y.
        b.root_node(
            json!({"name": "n1", "rotation": [-h, 0, 0, h], "translation": [0, 4, 0],
                           "extensions": {"KHR_lights_punctual": {"light": 1}}}),
        );
        b.root_node(json!({"name": "n2", "extensions": {"KHR_lights_punctual": {"light": 2}}}));
        let loaded = load(&b.embedded());
        let lights = &loaded.scene.lights;
        assert_eq!(lights.len(), 2);
        let bulb = &lights[0];
        assert_eq!(bulb.name, "bulb");
        assert_eq!(bulb.position, DVec3::new(1.0, 2.0, 3.0));
        assert_eq!(bulb.distribution, Distribution::Isotropic);
        // The spec's intensity is the luminous intensity (cd); the colour only tints:
        // 683 · Y(I) = 683 cd, and I ∝ colour.
        let y = |c: [f64; 3]| 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
        assert!((LUMENS_PER_WATT * y(bulb.intensity) - 683.0).abs() < 1e-9);
        let scale = 1.0 / y([1.0, 0.5, 0.0]);
        for (c, want) in [1.0, 0.5, 0.0].into_iter().enumerate() {
            assert!((bulb.intensity[c] - want * scale).abs() < 1e-12);
        }

        let spot = &lights[1];
        assert_eq!(spot.position, DVec3::new(0.0, 4.0, 0.0));
        assert!(
            (spot.aim.nadir - DVec3::NEG_Y).length() < 1e-6,
            "{}",
            spot.aim.nadir
        );
        match spot.distribution {
            Distribution::Spot {
                inner_deg,
                outer_deg,
            } => {
                // The angles are f32 in the file: 22.5° and 45° to ~1e-6°.
                assert!((inner_deg - 22.5).abs() < 1e-5 && (outer_deg - 45.0).abs() < 1e-5);
            }
            ref d => panic!("{d:?}"),
        }
        for c in 0..3 {
            assert!((spot.intensity[c] - 100.0 / 683.0).abs() < 1e-12);
        }
        assert_eq!(
            loaded.warnings,
            vec![
                GltfWarning::ClampedReflectance {
                    materials: vec!["gltf_default".to_owned()]
                },
                GltfWarning::IgnoredLightRange {
                    lights: vec!["spot".to_owned()]
                },
                GltfWarning::DirectionalLightsDropped {
                    lights: vec!["sun".to_owned()]
                },
            ]
        );
    }

    #[test]
    fn sparse_accessor_substitutes_vertices() {
        let mut b = Builder::new();
        let m = b.mesh("quad", &QUAD, Some(&QUAD_INDICES), json!({}));
        b.root_node(json!({"mesh": m}));
        // Move vertex 2 from (1,1,0) to (2,2,0) with a sparse accessor over the same view.
        let idx = b.view(&2u16.to_le_bytes());
        let val: Vec<u8> = [2.0f32, 2.0, 0.0]
            .iter()
            .flat_map(|x| x.to_le_bytes())
            .collect();
        let val = b.view(&val);
        b.root["accessors"][0]["sparse"] = json!({"count": 1,
            "indices": {"bufferView": idx, "componentType": 5123},
            "values": {"bufferView": val}});
        b.root["accessors"][0]["max"] = json!([2.0, 2.0, 0.0]);
        let scene = load(&b.embedded()).scene;
        // Quad (0,0) (1,0) (2,2) (0,1): area = 1/2·|diagonal cross| = 2.
        assert_eq!(scene.total_area(), 2.0);
        assert_eq!(
            scene.surfaces[0].polygon.vertices()[2],
            DVec3::new(2.0, 2.0, 0.0)
        );
    }

    #[test]
    fn every_truncation_of_a_glb_is_an_error_not_a_panic() {
        let glb = quad_builder().glb();
        for n in 0..glb.len() {
            let result = parse(&glb[..n], &GltfOptions::default());
            assert!(result.is_err(), "prefix of {n} bytes loaded");
        }
        // Header length below 12 (the gltf crate's own reader would underflow).
        let mut bad = glb.clone();
        bad[8..12].copy_from_slice(&4u32.to_le_bytes());
        assert!(err(&bad).to_string().contains("below 12"));
        // Flipped bytes anywhere must not panic either.
        for k in 0..glb.len() {
            let mut flipped = glb.clone();
            flipped[k] ^= 0xA5;
            let _ = parse(&flipped, &GltfOptions::default());
        }
    }

    /// Applies `edit` to the quad's JSON and returns the error text.
    fn error_after(edit: impl FnOnce(&mut Value)) -> String {
        let b = quad_builder();
        let mut root = b.json_with_buffer(Some(format!(
            "data:application/octet-stream;base64,{}",
            encode_base64(&b.bin)
        )));
        edit(&mut root);
        let json = serde_json::to_vec(&root).unwrap();
        let text = err(&json).to_string();
        assert!(text.starts_with("test.gltf: "), "{text}");
        text
    }

    #[test]
    fn malformed_files_give_errors_that_name_the_place() {
        type Edit = Box<dyn FnOnce(&mut Value)>;
        let cases: Vec<(Edit, &str)> = vec![
            (
                Box::new(|r| r["accessors"][0]["count"] = json!(1000)),
                "accessor 0 (POSITION of mesh 0 'quad_mesh', primitive 0): 1000 elements",
            ),
            (
                Box::new(|r| r["accessors"][1]["count"] = json!(3u64 << 20)),
                "accessor 1 (indices of mesh 0 'quad_mesh', primitive 0): 3145728 elements",
            ),
            (
                Box::new(|r| r["accessors"][1]["count"] = json!(1u64 << 40)),
                "366503875925 triangles (all mesh instances) exceed the limit",
            ),
            (
                Box::new(|r| r["bufferViews"][0]["byteLength"] = json!(4096)),
                "bufferView 0 (offset 0, 4096 B) extends past its buffer",
            ),
            (
                Box::new(|r| r["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(9)),
                "refers to accessor 9",
            ),
            (
                Box::new(|r| {
                    r["nodes"][0]["extensions"] = json!({"KHR_lights_punctual": {"light": 3}})
                }),
                "light: Index out of bounds",
            ),
            (
                Box::new(|r| r["nodes"][0]["children"] = json!([0])),
                "node 0 'quad': is reached twice",
            ),
            (
                Box::new(|r| r["accessors"][0]["componentType"] = json!(5123)),
                "only float VEC3",
            ),
            (
                Box::new(|r| r["accessors"][1]["componentType"] = json!(5126)),
                "indices are F32",
            ),
            (
                Box::new(|r| r["extensionsRequired"] = json!(["KHR_draco_mesh_compression"])),
                "extension KHR_draco_mesh_compression is required but not supported",
            ),
            (
                Box::new(|r| r["nodes"][0]["rotation"] = json!([0, 0, 0, 0])),
                "node 0 'quad': rotation [0.0, 0.0, 0.0, 0.0] is not a unit quaternion",
            ),
            (
                Box::new(|r| {
                    r["nodes"][0]["matrix"] =
                        json!([1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0.5, 0, 0, 0, 1])
                }),
                "projective",
            ),
            (
                Box::new(|r| r["nodes"][0]["translation"] = json!([2e6, 0, 0])),
                "node 0 'quad', mesh 0 'quad_mesh', primitive 0, triangle 0: polygon coordinate",
            ),
            (
                Box::new(|r| {
                    r["materials"][0]["pbrMetallicRoughness"]["baseColorFactor"] =
                        json!([-1, 0, 0, 1])
                }),
                "material 0 'lamp': baseColorFactor",
            ),
            (
                Box::new(|r| r["meshes"][0]["primitives"][0]["material"] = json!(7)),
                "invalid glTF",
            ),
            (
                Box::new(|r| r["buffers"][0]["uri"] = json!("https://example.com/x.bin")),
                "URI scheme 'https:'",
            ),
            (
                Box::new(|r| {
                    r["buffers"][0]["uri"] = json!("data:application/octet-stream;base64,@@")
                }),
                "invalid base64",
            ),
            (
                Box::new(|r| r["scenes"] = json!([{"nodes": [0, 0]}])),
                "reached twice",
            ),
        ];
        for (edit, needle) in cases {
            let text = error_after(edit);
            assert!(text.contains(needle), "expected '{needle}' in: {text}");
        }
        let text = err(b"{ not json").to_string();
        assert!(text.starts_with("test.gltf: JSON:"), "{text}");
        // Indices that point past the vertices.
        let mut b = Builder::new();
        let m = b.mesh("bad", &QUAD, Some(&[0, 1, 9]), json!({}));
        b.root_node(json!({"mesh": m}));
        let text = err(&b.embedded()).to_string();
        assert!(
            text.contains("index 2 is 9, but POSITION has 4 vertices"),
            "{text}"
        );
    }

    #[test]
    fn triangle_budget_is_checked_before_reading() {
        let options = GltfOptions {
            max_triangles: 1,
            ..GltfOptions::default()
        };
        match parse(&quad_builder().embedded(), &options) {
            Err(GltfError::TooManyTriangles {
                count: 2, limit: 1, ..
            }) => {}
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn a_file_without_triangles_is_empty() {
        let mut b = Builder::new();
        b.root_node(json!({"name": "nothing"}));
        assert!(matches!(err(&b.embedded()), GltfError::Empty { .. }));
    }

    #[test]
    fn material_features_and_names() {
        let mut b = Builder::new();
        for (name, extra) in [
            (
                "glass",
                json!({"alphaMode": "BLEND",
                             "extensions": {"KHR_materials_transmission": {"transmissionFactor": 1.0}}}),
            ),
            ("glass", json!({"alphaMode": "MASK"})),
        ] {
            let mut m = json!({"name": name, "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1]}});
            for (k, v) in extra.as_object().unwrap() {
                m[k] = v.clone();
            }
            b.push("materials", m);
        }
        for k in 0..2 {
            let m = b.mesh("quad", &QUAD, Some(&QUAD_INDICES), json!({"material": k}));
            b.root_node(json!({"mesh": m}));
        }
        let loaded = load(&b.embedded());
        let names: Vec<&str> = loaded
            .scene
            .materials
            .iter()
            .map(|m| m.name.as_str())
            .collect();
        // Material names stay unique in a scene.
        assert_eq!(names, ["glass", "glass#2"]);
        assert_eq!(
            loaded.warnings,
            vec![GltfWarning::IgnoredMaterialFeatures {
                features: vec![
                    (
                        "glass".to_owned(),
                        vec![
                            "alphaMode BLEND".to_owned(),
                            "KHR_materials_transmission".to_owned()
                        ]
                    ),
                    ("glass#2".to_owned(), vec!["alphaMode MASK".to_owned()]),
                ]
            }]
        );
    }

    // -----------------------------------------------------------------------------------------
    // The Cornell box as GLB

    fn manifest_path(relative: &str) -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join(relative)
    }

    /// Converts `scenes/cornell.obj` + `.mtl` (verbatim copies of the shared reference) into a
    /// GLB: a node per OBJ object (named as in the OBJ, mesh named after its `g` group), the
    /// polygon fanned into triangles; a material per MTL material with baseColorFactor = Kd,
    /// emissiveFactor = Ke / max(Ke) and KHR_materials_emissive_strength = max(Ke), so
    /// L_e = Ke with emission_scale 1; the camera of `cornell.camera.json` (= `cornell_camera`).
    fn cornell_glb() -> Vec<u8> {
        let obj = crate::io::obj::load_obj(&manifest_path("scenes/cornell.obj")).unwrap();
        let camera = crate::cornell::cornell_camera();
        let shared = manifest_path("../../../shared/reference/cornell.camera.json");
        if let Ok(text) = std::fs::read_to_string(shared) {
            let json: Value = serde_json::from_str(&text).unwrap();
            let v = |k: &str| DVec3::from_array(serde_json::from_value(json[k].clone()).unwrap());
            assert_eq!(v("position"), camera.eye);
            assert_eq!(v("look_dir"), (camera.target - camera.eye).normalize());
            assert_eq!(v("up"), camera.up);
            assert_eq!(json["fov_deg"].as_f64(), Some(camera.fov_deg));
        }
        let mut b = Builder::new();
        b.root["asset"]["generator"] =
            json!("radiosity: scenes/cornell.obj converted by io::gltf tests");
        b.root["extensionsUsed"] = json!(["KHR_materials_emissive_strength"]);
        for m in &obj.materials {
            let max = m.emission.iter().copied().fold(0.0, f64::max);
            let mut material = json!({
                "name": m.name,
                "pbrMetallicRoughness": {
                    "baseColorFactor": [m.reflectance[0], m.reflectance[1], m.reflectance[2], 1.0],
                    "metallicFactor": 0.0,
                    "roughnessFactor": 1.0,
                },
            });
            if max > 0.0 {
                material["emissiveFactor"] = json!(m.emission.map(|e| e / max));
                material["extensions"] =
                    json!({"KHR_materials_emissive_strength": {"emissiveStrength": max}});
            }
            b.push("materials", material);
        }
        for s in &obj.surfaces {
            let p: Vec<[f32; 3]> = s
                .polygon
                .vertices()
                .iter()
                .map(|v| v.as_vec3().to_array())
                .collect();
            let fan: Vec<u32> = (1..p.len() as u32 - 1)
                .flat_map(|k| [0, k, k + 1])
                .collect();
            let mesh = b.mesh(&s.group, &p, Some(&fan), json!({"material": s.material.0}));
            b.root_node(json!({"name": s.object, "mesh": mesh}));
        }
        // Looking along +z with +y up is the local −Z turned 180° about +y.
        let camera_index = b.push(
            "cameras",
            json!({"name": "cornell", "type": "perspective",
                   "perspective": {"yfov": camera.fov_deg.to_radians(), "znear": 0.01,
                                   "aspectRatio": 1.0}}),
        );
        b.root_node(json!({"name": "camera", "camera": camera_index,
                           "translation": camera.eye.to_array(), "rotation": [0, 1, 0, 0]}));
        b.glb()
    }

    #[test]
    fn cornell_glb_is_the_obj() {
        let path = manifest_path("scenes/cornell.glb");
        let bytes = cornell_glb();
        if std::env::var_os("BLESS").is_some() {
            std::fs::write(&path, &bytes).unwrap();
        }
        let on_disk = std::fs::read(&path).expect("scenes/cornell.glb (run with BLESS=1)");
        assert!(
            on_disk == bytes,
            "scenes/cornell.glb is stale: regenerate with BLESS=1"
        );

        let gltf = load_gltf(&path, &GltfOptions::default()).unwrap();
        assert!(gltf.warnings.is_empty(), "{:?}", gltf.warnings);
        let gltf = gltf.scene;
        let obj = crate::io::obj::load_obj(&manifest_path("scenes/cornell.obj")).unwrap();
        assert_eq!(gltf.name, "cornell");
        assert_eq!(gltf.object_names(), obj.object_names());
        // 18 quads written as 36 triangles come back as the quads, plus the red wall's two
        // triangles: the OBJ's 20 polygons.
        assert_eq!(gltf.surfaces.len(), 20);
        assert_eq!(gltf.materials.len(), obj.materials.len());
        for (g, o) in gltf.materials.iter().zip(&obj.materials) {
            assert_eq!(g.name, o.name);
            assert!(!g.two_sided);
            for c in 0..3 {
                // Kd and Ke/max(Ke) are stored as f32: one rounding, relative 2^-24; the
                // emission adds the f32 strength (exact for 17) — allow 2^-23.
                let tol = |x: f64| x.abs() * f64::from(f32::EPSILON);
                assert!((g.reflectance[c] - o.reflectance[c]).abs() <= tol(o.reflectance[c]));
                assert!((g.emission[c] - o.emission[c]).abs() <= tol(o.emission[c]));
            }
        }
        for o in &obj.surfaces {
            let parts: Vec<&Surface> = gltf
                .surfaces
                .iter()
                .filter(|g| g.object == o.object)
                .collect();
            assert_eq!(parts.len(), 1, "{}", o.object);
            // The same vertices in the same order (f32: within 3.3e-8 m), so it meshes alike.
            for (g, w) in parts[0].polygon.vertices().iter().zip(o.polygon.vertices()) {
                assert!(g.distance(*w) < 1e-6, "{}: {g} vs {w}", o.object);
            }
            let area: f64 = parts.iter().map(|g| g.polygon.area()).sum();
            // f32 vertices (≤ 3.3e-8 m off): areas agree to ~1e-7 relative.
            assert!(
                (area - o.polygon.area()).abs() < 1e-6 * o.polygon.area(),
                "{}",
                o.object
            );
            for g in parts {
                assert_eq!(g.group, o.group);
                assert_eq!(gltf.material(g).name, obj.material(o).name);
                assert!(g.polygon.normal().dot(o.polygon.normal()) > 1.0 - 1e-9);
                for v in g.polygon.vertices() {
                    // glTF stores f32: |x − f32(x)| ≤ 2^-24·0.56 m ≈ 3.3e-8 m.
                    let nearest = o
                        .polygon
                        .vertices()
                        .iter()
                        .map(|w| w.distance(*v))
                        .fold(f64::INFINITY, f64::min);
                    assert!(nearest < 1e-6, "{}: {v}", o.object);
                }
            }
        }
        let camera = gltf.camera.unwrap();
        let reference = crate::cornell::cornell_camera();
        assert!(camera.eye.distance(reference.eye) < 1e-6);
        let look = (camera.target - camera.eye).normalize();
        assert!(look.distance((reference.target - reference.eye).normalize()) < 1e-6);
        assert!(camera.up.distance(reference.up) < 1e-6);
        // yfov is f32 radians: relative 6e-8 of 39.3°.
        assert!((camera.fov_deg - reference.fov_deg).abs() < 1e-5);
    }
}
