//! Baked output: the solved radiosity as a glTF 2.0 binary (GLB) with a lightmap, for game
//! engines and viewers.
//!
//! Input is a [`BakedScene`]: materials, and objects (one per scene object, named as in the
//! input file) whose primitives carry display triangles with per-vertex linear radiance
//! L = B/π in W·m⁻²·sr⁻¹ (from the crack-free display mesh, `crate::display`) and, per triangle,
//! the chart it belongs to. A chart is one planar convex surface of the scene: its triangles
//! are coplanar and connected. [`bake`] then
//!
//! 1. validates the input and gives every vertex used by two charts one copy per chart (a
//!    vertex on the edge between a wall and the floor needs two lightmap coordinates);
//! 2. packs the charts into a lightmap atlas and bakes the radiance into it
//!    ([`lightmap`]);
//! 3. and [`glb`] writes the GLB: one node and mesh per object, one primitive per material,
//!    `POSITION`, `NORMAL`, `TEXCOORD_0` = `TEXCOORD_1` (lightmap coordinates), `_RADIANCE`
//!    (the exact linear radiance), `COLOR_0` (exposed radiance for display, see
//!    [`VertexColors`]), and the lightmap embedded as the materials' emissive texture.
//!
//! [`export`] does all of it and writes `<name>.glb`, `<name>_lightmap.exr` (linear float
//! radiance, for engines that import HDR lightmaps) and `<name>_lightmap.png` (sRGB after
//! exposure, the texture embedded in the GLB), each atomically.
//!
//! See also: `crate::io::gltf` for reading glTF scenes in.

pub mod glb;
pub mod lightmap;
pub mod solution;

use crate::render::ImageError;
use crate::scene::Camera;
use lightmap::{Lightmap, LightmapOptions};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// A material as the input scene had it (the GLB shows the lightmap instead, and keeps these
/// values in the material's `extras`).
#[derive(Debug, Clone, PartialEq)]
pub struct BakedMaterial {
    /// The material's name.
    pub name: String,
    /// Diffuse reflectance ρ per channel (glTF `baseColorFactor`), dimensionless.
    pub reflectance: [f32; 3],
    /// Emitted radiance L_e per channel, W·m⁻²·sr⁻¹.
    pub emission: [f32; 3],
    /// Both sides reflect (glTF `doubleSided`).
    pub two_sided: bool,
}

/// The display triangles of one object that share one material.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct BakedPrimitive {
    /// Index into [`BakedScene::materials`].
    pub material: usize,
    /// Vertex positions, m.
    pub positions: Vec<[f32; 3]>,
    /// Vertex normals (any non-zero length; normalised on output).
    pub normals: Vec<[f32; 3]>,
    /// Linear radiance L = B/π per vertex and RGB channel, W·m⁻²·sr⁻¹.
    pub radiance: Vec<[f32; 3]>,
    /// Triangles as vertex indices, counter-clockwise seen from the front.
    pub triangles: Vec<[u32; 3]>,
    /// The chart (scene surface) of each triangle; triangles with equal ids in one primitive
    /// form one chart and must be coplanar.
    pub charts: Vec<u32>,
}

/// One object of the scene: a node in the GLB, named as the object was in the input.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct BakedObject {
    /// The object's name (OBJ `o`, glTF node name).
    pub name: String,
    /// One primitive per material.
    pub primitives: Vec<BakedPrimitive>,
}

/// The solved scene ready for export.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct BakedScene {
    /// The scene's name (the GLB's scene name).
    pub name: String,
    /// Materials, indexed by [`BakedPrimitive::material`].
    pub materials: Vec<BakedMaterial>,
    /// Objects in output order.
    pub objects: Vec<BakedObject>,
    /// Written as a glTF camera node when present.
    pub camera: Option<Camera>,
}

/// What `COLOR_0` holds. The exact radiance is always in the `_RADIANCE` attribute.
///
/// glTF defines `COLOR_n` as a linear colour multiplier, and the Khronos validator rejects
/// FLOAT colours outside [0, 1] (error `ACCESSOR_NON_CLAMPED`), so radiance in
/// W·m⁻²·sr⁻¹, which exceeds 1 wherever a surface is bright, cannot go into `COLOR_0` as is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum VertexColors {
    /// Linear FLOAT VEC3: min(L · 2^exposure, 1) per channel, the exposed radiance clipped to
    /// the displayable range (still linear, as glTF expects).
    #[default]
    Linear,
    /// Display-ready colours: sRGB-encoded after exposure and clipping to [0, 1]
    /// (the curve of `render::image::srgb_byte`), UNSIGNED_BYTE normalized VEC4 with alpha 1.
    /// glTF defines `COLOR_0` as linear, so spec-following viewers will show these too
    /// bright; this is for engines that feed vertex colours straight to the screen.
    DisplaySrgb,
}

/// Options for [`bake`] and [`export`].
#[derive(Debug, Clone, PartialEq)]
pub struct ExportOptions {
    /// Atlas size and gutter.
    pub lightmap: LightmapOptions,
    /// What `COLOR_0` holds.
    pub vertex_colors: VertexColors,
    /// Exposure in stops for everything meant for display (PNG lightmap, `COLOR_0`):
    /// displayed = clip(L · 2^exposure). The EXR and `_RADIANCE` are never scaled.
    pub exposure_stops: f32,
}

impl Default for ExportOptions {
    fn default() -> Self {
        Self {
            lightmap: LightmapOptions::default(),
            vertex_colors: VertexColors::default(),
            exposure_stops: 0.0,
        }
    }
}

/// Why a scene could not be exported.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// The input is inconsistent (lengths, indices, non-finite or negative values, a chart
    /// that is not planar).
    #[error("object '{object}': {message}")]
    Invalid {
        /// The object (or `camera`, or a material).
        object: String,
        /// What is wrong.
        message: String,
    },
    /// The charts do not fit the requested atlas.
    #[error("lightmap atlas: {0}")]
    Atlas(String),
    /// Encoding the lightmap PNG failed.
    #[error("lightmap PNG: {0}")]
    Png(#[source] image::ImageError),
    /// Writing the EXR or PNG lightmap file failed (the error names the file).
    #[error(transparent)]
    Image(#[from] ImageError),
    /// Writing the GLB failed.
    #[error("{}: cannot write: {source}", path.display())]
    Write {
        /// The GLB path.
        path: PathBuf,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The GLB would exceed the format's 4 GiB limit.
    #[error("GLB would be {bytes} bytes; the format's limit is 4 GiB")]
    TooLarge {
        /// The size it would have.
        bytes: u64,
    },
}

/// One primitive as written: the input's vertices re-indexed so that each belongs to one
/// chart, with lightmap coordinates.
#[derive(Debug, Clone, PartialEq)]
pub struct ExportPrimitive {
    /// Index into [`BakedScene::materials`].
    pub material: usize,
    /// Vertex positions, m.
    pub positions: Vec<[f32; 3]>,
    /// Unit vertex normals.
    pub normals: Vec<[f32; 3]>,
    /// Linear radiance per vertex, W·m⁻²·sr⁻¹.
    pub radiance: Vec<[f32; 3]>,
    /// Lightmap coordinates in [0, 1]² (u right, v down: glTF's convention, v = 0 is the first
    /// image row).
    pub uv: Vec<[f32; 2]>,
    /// Triangles (new vertex indices), same order as the input.
    pub triangles: Vec<[u32; 3]>,
    /// Chart id of each triangle, as in the input.
    pub charts: Vec<u32>,
    /// The input vertex each output vertex copies.
    pub source_vertex: Vec<u32>,
    /// The chart each output vertex belongs to.
    pub vertex_chart: Vec<u32>,
}

/// The baked result: output primitives (per object, per primitive, parallel to the input)
/// and the lightmap.
#[derive(Debug, Clone, PartialEq)]
pub struct Baked {
    /// `objects[o][p]` is primitive `p` of object `o`.
    pub objects: Vec<Vec<ExportPrimitive>>,
    /// The atlas image and chart placements.
    pub lightmap: Lightmap,
}

/// Paths written by [`export`] and facts about the atlas.
#[derive(Debug, Clone, PartialEq)]
pub struct ExportSummary {
    /// The GLB.
    pub glb: PathBuf,
    /// The linear float lightmap.
    pub exr: PathBuf,
    /// The sRGB lightmap (the one embedded in the GLB).
    pub png: PathBuf,
    /// Atlas width and height, texels.
    pub atlas: (u32, u32),
    /// Texel density, texels per metre.
    pub texels_per_metre: f64,
    /// Number of charts.
    pub charts: usize,
}

/// Validates the scene, splits shared vertices, packs and bakes the lightmap.
pub fn bake(scene: &BakedScene, options: &ExportOptions) -> Result<Baked, ExportError> {
    let mut objects = Vec::with_capacity(scene.objects.len());
    for object in &scene.objects {
        let mut primitives = Vec::with_capacity(object.primitives.len());
        for (p, primitive) in object.primitives.iter().enumerate() {
            primitives.push(prepare(scene, &object.name, p, primitive)?);
        }
        objects.push(primitives);
    }
    let lightmap = lightmap::build(scene, &mut objects, &options.lightmap)?;
    Ok(Baked { objects, lightmap })
}

/// Bakes and writes `glb_path`, and beside it `<stem>_lightmap.exr` and `<stem>_lightmap.png`.
/// Everything is encoded in memory first; each file is then written atomically (a temporary
/// file in the same directory, renamed when complete), so an error leaves no partial file.
pub fn export(
    scene: &BakedScene,
    glb_path: &Path,
    options: &ExportOptions,
) -> Result<ExportSummary, ExportError> {
    let baked = bake(scene, options)?;
    let bytes = glb::glb_bytes(scene, &baked, options)?;
    let (exr, png) = lightmap_paths(glb_path);
    baked.lightmap.image.write(&exr, 0.0)?;
    baked.lightmap.image.write(&png, options.exposure_stops)?;
    crate::io::atomic::write_atomically(glb_path, |w| w.write_all(&bytes)).map_err(|source| {
        ExportError::Write {
            path: glb_path.to_owned(),
            source,
        }
    })?;
    Ok(ExportSummary {
        glb: glb_path.to_owned(),
        exr,
        png,
        atlas: (baked.lightmap.image.width, baked.lightmap.image.height),
        texels_per_metre: baked.lightmap.texels_per_metre,
        charts: baked.lightmap.charts.len(),
    })
}

/// The lightmap files [`export`] writes beside `glb_path`: `<stem>_lightmap.exr` and
/// `<stem>_lightmap.png`.
pub fn lightmap_paths(glb_path: &Path) -> (PathBuf, PathBuf) {
    let stem = glb_path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "scene".to_owned());
    (
        glb_path.with_file_name(format!("{stem}_lightmap.exr")),
        glb_path.with_file_name(format!("{stem}_lightmap.png")),
    )
}

/// Checks one input primitive and re-indexes its vertices so that each belongs to exactly one
/// chart: vertex v used by charts c1, c2, … becomes one output vertex per (v, c), numbered in
/// input vertex order (so an input whose charts share no vertex keeps its numbering, less
/// unused vertices).
fn prepare(
    scene: &BakedScene,
    object: &str,
    index: usize,
    input: &BakedPrimitive,
) -> Result<ExportPrimitive, ExportError> {
    let invalid = |message: String| ExportError::Invalid {
        object: object.to_owned(),
        message: format!("primitive {index}: {message}"),
    };
    let n = input.positions.len();
    if input.normals.len() != n || input.radiance.len() != n {
        return Err(invalid(format!(
            "{n} positions, {} normals and {} radiance values (must be equal)",
            input.normals.len(),
            input.radiance.len()
        )));
    }
    if input.charts.len() != input.triangles.len() {
        return Err(invalid(format!(
            "{} triangles but {} chart ids",
            input.triangles.len(),
            input.charts.len()
        )));
    }
    if input.material >= scene.materials.len() {
        return Err(invalid(format!(
            "material {} does not exist (scene has {})",
            input.material,
            scene.materials.len()
        )));
    }
    if n > u32::MAX as usize / 2 {
        return Err(invalid(format!("{n} vertices are too many")));
    }
    for (t, tri) in input.triangles.iter().enumerate() {
        if let Some(&i) = tri.iter().find(|&&i| i as usize >= n) {
            return Err(invalid(format!(
                "triangle {t} refers to vertex {i}, primitive has {n}"
            )));
        }
    }
    let mut normals = Vec::with_capacity(n);
    for k in 0..n {
        if input.positions[k].iter().any(|x| !x.is_finite()) {
            return Err(invalid(format!("vertex {k} has a non-finite position")));
        }
        let l = input.radiance[k];
        if l.iter().any(|x| !x.is_finite() || *x < 0.0) {
            return Err(invalid(format!(
                "vertex {k} has radiance {l:?}; must be finite and ≥ 0"
            )));
        }
        let v = glam::Vec3::from_array(input.normals[k]);
        let unit = v
            .try_normalize()
            .ok_or_else(|| invalid(format!("vertex {k} has normal {v}, not a direction")))?;
        normals.push(unit.to_array());
    }

    // Charts using each vertex, in order of first use.
    let mut users: Vec<Vec<u32>> = vec![Vec::new(); n];
    for (tri, &chart) in input.triangles.iter().zip(&input.charts) {
        for &i in tri {
            let list = &mut users[i as usize];
            if !list.contains(&chart) {
                list.push(chart);
            }
        }
    }
    let mut new_index: HashMap<(u32, u32), u32> = HashMap::new();
    let mut out = ExportPrimitive {
        material: input.material,
        positions: Vec::new(),
        normals: Vec::new(),
        radiance: Vec::new(),
        uv: Vec::new(),
        triangles: Vec::with_capacity(input.triangles.len()),
        charts: input.charts.clone(),
        source_vertex: Vec::new(),
        vertex_chart: Vec::new(),
    };
    for (v, charts) in users.iter().enumerate() {
        for &chart in charts {
            new_index.insert((v as u32, chart), out.positions.len() as u32);
            out.positions.push(input.positions[v]);
            out.normals.push(normals[v]);
            out.radiance.push(input.radiance[v]);
            out.source_vertex.push(v as u32);
            out.vertex_chart.push(chart);
        }
    }
    for (tri, &chart) in input.triangles.iter().zip(&input.charts) {
        out.triangles.push(tri.map(|i| new_index[&(i, chart)]));
    }
    out.uv = vec![[0.0; 2]; out.positions.len()];
    Ok(out)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use glam::DVec3;

    /// Two unit squares meeting at a right angle along the x axis (floor z = 0 ... and wall
    /// y = 0), sharing the two vertices on the edge.
    pub(crate) fn corner() -> BakedScene {
        let positions = vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
            [1.0, 0.0, 1.0],
            [0.0, 0.0, 1.0],
        ];
        let primitive = BakedPrimitive {
            material: 0,
            normals: vec![[0.0, 0.0, 1.0]; 6],
            radiance: (0..6).map(|k| [k as f32, 1.0, 0.5]).collect(),
            positions,
            triangles: vec![[0, 1, 2], [0, 2, 3], [0, 4, 1], [0, 5, 4]],
            charts: vec![7, 7, 3, 3],
        };
        BakedScene {
            name: "corner".to_owned(),
            materials: vec![BakedMaterial {
                name: "white".to_owned(),
                reflectance: [0.5; 3],
                emission: [0.0; 3],
                two_sided: false,
            }],
            objects: vec![BakedObject {
                name: "corner".to_owned(),
                primitives: vec![primitive],
            }],
            camera: None,
        }
    }

    /// The radiance field of [`cornell_baked`]: linear in position, so interpolation over any
    /// triangle of a chart reproduces it exactly.
    pub(crate) fn linear_radiance(reflectance: [f64; 3], emission: [f64; 3], p: DVec3) -> [f64; 3] {
        let s = 1.0 + p.x + 2.0 * p.y + 3.0 * p.z;
        [0, 1, 2].map(|c| reflectance[c] * s + emission[c])
    }

    /// The Cornell box as a baked scene: each polygon one object and one chart, triangulated as
    /// a fan from its centroid over its corners and edge midpoints (the shape of the display
    /// mesh), with [`linear_radiance`] at the vertices.
    pub(crate) fn cornell_baked() -> BakedScene {
        let scene = crate::cornell::cornell_box();
        let materials = scene
            .materials
            .iter()
            .map(|m| BakedMaterial {
                name: m.name.clone(),
                reflectance: m.reflectance.map(|x| x as f32),
                emission: m.emission.map(|x| x as f32),
                two_sided: m.two_sided,
            })
            .collect();
        let objects = scene
            .surfaces
            .iter()
            .enumerate()
            .map(|(k, s)| {
                let m = scene.material(s);
                let corners = s.polygon.vertices();
                let mut ring = Vec::new();
                for i in 0..corners.len() {
                    let (a, b) = (corners[i], corners[(i + 1) % corners.len()]);
                    ring.push(a);
                    ring.push((a + b) * 0.5);
                }
                let mut points = vec![s.polygon.centroid()];
                points.extend(&ring);
                let n = ring.len() as u32;
                let triangles: Vec<[u32; 3]> =
                    (0..n).map(|i| [0, 1 + i, 1 + (i + 1) % n]).collect();
                BakedObject {
                    name: s.object.clone(),
                    primitives: vec![BakedPrimitive {
                        material: s.material.0 as usize,
                        positions: points.iter().map(|p| p.as_vec3().to_array()).collect(),
                        normals: vec![s.polygon.normal().as_vec3().to_array(); points.len()],
                        radiance: points
                            .iter()
                            .map(|&p| {
                                linear_radiance(m.reflectance, m.emission, p).map(|x| x as f32)
                            })
                            .collect(),
                        charts: vec![k as u32; triangles.len()],
                        triangles,
                    }],
                }
            })
            .collect();
        BakedScene {
            name: "cornell".to_owned(),
            materials,
            objects,
            camera: scene.camera,
        }
    }

    #[test]
    fn shared_vertices_get_one_copy_per_chart() {
        let scene = corner();
        let p = prepare(&scene, "corner", 0, &scene.objects[0].primitives[0]).unwrap();
        // Vertices 0 and 1 lie on both charts: 6 + 2 copies.
        assert_eq!(p.positions.len(), 8);
        assert_eq!(p.source_vertex, [0, 0, 1, 1, 2, 3, 4, 5]);
        assert_eq!(p.vertex_chart, [7, 3, 7, 3, 7, 7, 3, 3]);
        for (t, tri) in p.triangles.iter().enumerate() {
            for (k, &i) in tri.iter().enumerate() {
                let source = scene.objects[0].primitives[0].triangles[t][k];
                assert_eq!(p.source_vertex[i as usize], source);
                assert_eq!(p.vertex_chart[i as usize], p.charts[t]);
                assert_eq!(p.radiance[i as usize], [source as f32, 1.0, 0.5]);
            }
        }
    }

    #[test]
    fn inconsistent_input_is_an_error_naming_the_object() {
        type Edit = Box<dyn Fn(&mut BakedPrimitive)>;
        let cases: Vec<(Edit, &str)> = vec![
            (
                Box::new(|p| p.normals.pop().map(drop).unwrap_or(())),
                "normals",
            ),
            (
                Box::new(|p| p.charts.pop().map(drop).unwrap_or(())),
                "chart ids",
            ),
            (
                Box::new(|p| p.triangles[1][2] = 99),
                "triangle 1 refers to vertex 99",
            ),
            (
                Box::new(|p| p.radiance[2][1] = -1.0),
                "vertex 2 has radiance",
            ),
            (
                Box::new(|p| p.radiance[2][1] = f32::NAN),
                "vertex 2 has radiance",
            ),
            (
                Box::new(|p| p.positions[3][0] = f32::INFINITY),
                "vertex 3 has a non-finite",
            ),
            (Box::new(|p| p.normals[4] = [0.0; 3]), "vertex 4 has normal"),
            (Box::new(|p| p.material = 3), "material 3 does not exist"),
        ];
        for (edit, needle) in cases {
            let mut scene = corner();
            edit(&mut scene.objects[0].primitives[0]);
            let e = bake(&scene, &ExportOptions::default()).unwrap_err();
            let text = e.to_string();
            assert!(text.starts_with("object 'corner': primitive 0: "), "{text}");
            assert!(text.contains(needle), "expected '{needle}' in {text}");
        }
    }
}
