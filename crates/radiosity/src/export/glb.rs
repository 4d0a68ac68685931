//! The GLB writer: a glTF 2.0 binary (§4 of the glTF 2.0 specification, GLB File Format) with
//! the baked radiance as vertex colours and as an embedded lightmap.
//!
//! Layout: one scene; one node per object, named as the object; one mesh per object with one
//! primitive per material (TRIANGLES); every attribute in its own tightly packed buffer view:
//! `POSITION` (FLOAT VEC3, with min/max), `NORMAL` (FLOAT VEC3, unit), `TEXCOORD_1` and
//! `TEXCOORD_0` (one FLOAT VEC2 accessor for both: the lightmap coordinates, so viewers that
//! only know one UV set still show the lightmap), `_RADIANCE` (FLOAT VEC3, the exact linear
//! radiance in W·m⁻²·sr⁻¹; an application-specific attribute, whose name must start with an
//! underscore, §3.7.2.1), `COLOR_0` (exposed radiance for display, see
//! [`VertexColors`]), and UNSIGNED_SHORT or UNSIGNED_INT indices.
//! The lightmap PNG is an image in the binary chunk (`mimeType` image/png) behind one texture
//! with a linear, clamp-to-edge sampler (no mipmaps: the gutter is sized for bilinear lookups).
//!
//! How the lightmap is displayed. The radiance is what the eye should see, so it must reach
//! the screen unlit. glTF's `KHR_materials_unlit` would say so, but the two main consumers
//! ignore the emissive texture on unlit materials: three.js's GLTFLoader (r187,
//! `loadMaterial`) skips `emissiveFactor` and `emissiveTexture` when the material type is
//! `MeshBasicMaterial`, which `KHR_materials_unlit` selects, and Blender's importer
//! (glTF-Blender-IO `KHR_materials_unlit.py`) builds the unlit shader from the base colour
//! alone. Both do show `emissiveTexture` × `emissiveFactor` on the standard metallic-roughness
//! material (three.js: `emissiveMap`, sRGB; Blender: Principled BSDF Emission Color with
//! Emission Strength 1). So each material is: `emissiveTexture` = the lightmap on
//! `texCoord` 1, `emissiveFactor` [1, 1, 1], `baseColorFactor` black (no diffuse response to
//! the viewer's lights), `metallicFactor` 0, `roughnessFactor` 1, and
//! `KHR_materials_specular` with `specularFactor` 0, which removes the dielectric specular
//! lobe (three.js: `specularIntensity` 0 gives F0 = F90 = 0; Blender: Specular IOR Level 0).
//! A viewer without that extension adds a faint 4 % specular sheen under its own lights. What
//! the viewer shows is then the PNG: clip(L · 2^exposure) decoded from sRGB, i.e. the same
//! picture as our renderer at that exposure, before the viewer's own tone mapping (three.js
//! defaults to none; Blender's default view transform is not "Standard"). The input
//! material's reflectance and emission are kept in the material's `extras.radiosity`, and the
//! radiance unit and exposure in `asset.extras.radiosity`.

use super::{Baked, BakedScene, ExportError, ExportOptions, ExportPrimitive, VertexColors};
use crate::render::srgb_byte;
use glam::{DMat3, DQuat};
use serde_json::{json, Value};
use std::path::Path;

const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;
const FLOAT: u32 = 5126;
const UNSIGNED_BYTE: u32 = 5121;
const UNSIGNED_SHORT: u32 = 5123;
const UNSIGNED_INT: u32 = 5125;
const LINEAR: u32 = 9729;
const CLAMP_TO_EDGE: u32 = 33071;

/// The binary chunk under construction and the JSON arrays that describe it.
#[derive(Default)]
struct Chunk {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Chunk {
    /// Appends `bytes` as a buffer view aligned to 4 bytes (§3.6.2.4: accessor offsets must
    /// be multiples of the component size).
    fn view(&mut self, bytes: &[u8], target: Option<u32>) -> usize {
        while self.bin.len() % 4 != 0 {
            self.bin.push(0);
        }
        let mut view =
            json!({"buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len()});
        if let Some(target) = target {
            view["target"] = json!(target);
        }
        self.bin.extend_from_slice(bytes);
        self.views.push(view);
        self.views.len() - 1
    }

    fn accessor(&mut self, accessor: Value) -> usize {
        self.accessors.push(accessor);
        self.accessors.len() - 1
    }

    fn floats<const N: usize>(&mut self, data: &[[f32; N]], kind: &str, bounds: bool) -> usize {
        let bytes: Vec<u8> = data
            .iter()
            .flatten()
            .flat_map(|x| x.to_le_bytes())
            .collect();
        let view = self.view(&bytes, Some(ARRAY_BUFFER));
        let mut accessor =
            json!({"bufferView": view, "componentType": FLOAT, "count": data.len(), "type": kind});
        if bounds {
            let mut lo = [f32::INFINITY; N];
            let mut hi = [f32::NEG_INFINITY; N];
            for v in data {
                for c in 0..N {
                    lo[c] = lo[c].min(v[c]);
                    hi[c] = hi[c].max(v[c]);
                }
            }
            accessor["min"] = json!(lo.as_slice());
            accessor["max"] = json!(hi.as_slice());
        }
        self.accessor(accessor)
    }
}

/// The GLB file for a baked scene, in memory.
pub fn glb_bytes(
    scene: &BakedScene,
    baked: &Baked,
    options: &ExportOptions,
) -> Result<Vec<u8>, ExportError> {
    let mut chunk = Chunk::default();

    // Materials actually used, in first-use order.
    let mut material_index: Vec<Option<usize>> = vec![None; scene.materials.len()];
    let mut materials = Vec::new();
    let mut meshes = Vec::new();
    let mut nodes = Vec::new();
    for (o, object) in scene.objects.iter().enumerate() {
        let mut primitives = Vec::new();
        for primitive in &baked.objects[o] {
            if primitive.triangles.is_empty() {
                continue;
            }
            let material = *material_index[primitive.material].get_or_insert_with(|| {
                let m = &scene.materials[primitive.material];
                materials.push(material_json(m));
                materials.len() - 1
            });
            primitives.push(primitive_json(&mut chunk, primitive, material, options));
        }
        let mut node = json!({"name": object.name});
        if !primitives.is_empty() {
            meshes.push(json!({"name": object.name, "primitives": primitives}));
            node["mesh"] = json!(meshes.len() - 1);
        }
        nodes.push(node);
    }

    let png = baked
        .lightmap
        .png_bytes(options.exposure_stops)
        .map_err(ExportError::Png)?;
    let image_view = chunk.view(&png, None);

    let mut root = json!({
        "asset": {
            "version": "2.0",
            "generator": concat!("radiosity ", env!("CARGO_PKG_VERSION")),
            "extras": {"radiosity": {
                "_RADIANCE": "linear radiance L, W m^-2 sr^-1",
                "COLOR_0": match options.vertex_colors {
                    VertexColors::Linear => "linear min(L * 2^exposureStops, 1)",
                    VertexColors::DisplaySrgb => "sRGB-encoded clip(L * 2^exposureStops)",
                },
                "lightmap": "sRGB-encoded clip(L * 2^exposureStops), L in W m^-2 sr^-1",
                "exposureStops": options.exposure_stops,
                "texelsPerMetre": baked.lightmap.texels_per_metre,
                "gutterTexels": baked.lightmap.gutter,
            }},
        },
        "extensionsUsed": ["KHR_materials_specular"],
        "scene": 0,
        "materials": materials,
        "samplers": [{"magFilter": LINEAR, "minFilter": LINEAR,
                      "wrapS": CLAMP_TO_EDGE, "wrapT": CLAMP_TO_EDGE}],
        "images": [{"name": "lightmap", "bufferView": image_view, "mimeType": "image/png"}],
        "textures": [{"name": "lightmap", "sampler": 0, "source": 0}],
    });
    if let Some(camera) = scene.camera {
        let look = camera.target - camera.eye;
        let z = (-look).try_normalize();
        let x = z.and_then(|z| camera.up.cross(z).try_normalize());
        let (Some(z), Some(x)) = (z, x) else {
            return Err(ExportError::Invalid {
                object: "camera".to_owned(),
                message: "the view direction is zero or parallel to up".to_owned(),
            });
        };
        // The camera looks down its local −Z with +Y up (§3.10.1): columns x, y, z.
        let rotation = DQuat::from_mat3(&DMat3::from_cols(x, z.cross(x), z)).normalize();
        root["cameras"] = json!([{"name": "camera", "type": "perspective", "perspective": {
            "yfov": camera.fov_deg.to_radians(),
            "znear": 0.01,
            "aspectRatio": 1.0,
        }}]);
        nodes.push(json!({
            "name": "camera",
            "camera": 0,
            "translation": camera.eye.as_vec3().to_array(),
            "rotation": rotation.as_quat().to_array(),
        }));
    }
    root["scenes"] = json!([{"name": scene.name, "nodes": (0..nodes.len()).collect::<Vec<_>>()}]);
    root["nodes"] = json!(nodes);
    if !meshes.is_empty() {
        root["meshes"] = json!(meshes);
    }
    root["accessors"] = json!(chunk.accessors);
    root["bufferViews"] = json!(chunk.views);
    root["buffers"] = json!([{"byteLength": chunk.bin.len()}]);
    container(&root, chunk.bin)
}

/// Writes [`glb_bytes`] to `path` atomically (a temporary file in the same directory, renamed
/// when complete).
pub fn write_glb(
    path: &Path,
    scene: &BakedScene,
    baked: &Baked,
    options: &ExportOptions,
) -> Result<(), ExportError> {
    let bytes = glb_bytes(scene, baked, options)?;
    crate::io::atomic::write_atomically(path, |w| w.write_all(&bytes)).map_err(|source| {
        ExportError::Write {
            path: path.to_owned(),
            source,
        }
    })
}

fn material_json(m: &super::BakedMaterial) -> Value {
    json!({
        "name": m.name,
        "pbrMetallicRoughness": {
            "baseColorFactor": [0.0, 0.0, 0.0, 1.0],
            "metallicFactor": 0.0,
            "roughnessFactor": 1.0,
        },
        "emissiveTexture": {"index": 0, "texCoord": 1},
        "emissiveFactor": [1.0, 1.0, 1.0],
        "doubleSided": m.two_sided,
        "extensions": {"KHR_materials_specular": {"specularFactor": 0.0}},
        "extras": {"radiosity": {
            "reflectance": m.reflectance,
            "emission": m.emission,
        }},
    })
}

fn primitive_json(
    chunk: &mut Chunk,
    p: &ExportPrimitive,
    material: usize,
    options: &ExportOptions,
) -> Value {
    let position = chunk.floats(&p.positions, "VEC3", true);
    let normal = chunk.floats(&p.normals, "VEC3", false);
    let uv = chunk.floats(&p.uv, "VEC2", false);
    let radiance = chunk.floats(&p.radiance, "VEC3", false);
    let scale = options.exposure_stops.exp2();
    let colour = match options.vertex_colors {
        VertexColors::Linear => {
            let exposed: Vec<[f32; 3]> = p
                .radiance
                .iter()
                .map(|l| l.map(|c| (c * scale).min(1.0)))
                .collect();
            chunk.floats(&exposed, "VEC3", false)
        }
        VertexColors::DisplaySrgb => {
            let bytes: Vec<u8> = p
                .radiance
                .iter()
                .flat_map(|l| {
                    let [r, g, b] = l.map(|c| srgb_byte(c * scale));
                    [r, g, b, 255]
                })
                .collect();
            let view = chunk.view(&bytes, Some(ARRAY_BUFFER));
            chunk.accessor(json!({"bufferView": view, "componentType": UNSIGNED_BYTE,
                                  "normalized": true, "count": p.radiance.len(),
                                  "type": "VEC4"}))
        }
    };
    // 65535 is the primitive-restart value, which glTF forbids in index data.
    let (bytes, component): (Vec<u8>, u32) = if p.positions.len() <= 65535 {
        let b = p.triangles.iter().flatten();
        (
            b.flat_map(|&i| (i as u16).to_le_bytes()).collect(),
            UNSIGNED_SHORT,
        )
    } else {
        let b = p.triangles.iter().flatten();
        (b.flat_map(|&i| i.to_le_bytes()).collect(), UNSIGNED_INT)
    };
    let view = chunk.view(&bytes, Some(ELEMENT_ARRAY_BUFFER));
    let indices = chunk.accessor(json!({"bufferView": view, "componentType": component,
                                        "count": 3 * p.triangles.len(), "type": "SCALAR"}));
    json!({
        "attributes": {
            "POSITION": position,
            "NORMAL": normal,
            "TEXCOORD_0": uv,
            "TEXCOORD_1": uv,
            "COLOR_0": colour,
            "_RADIANCE": radiance,
        },
        "indices": indices,
        "material": material,
        "mode": 4,
    })
}

/// The GLB container (§4): 12-byte header, the JSON chunk padded with spaces, the BIN chunk
/// padded with zeros, every chunk 4-byte aligned.
fn container(root: &Value, mut bin: Vec<u8>) -> Result<Vec<u8>, ExportError> {
    let mut json = serde_json::to_vec(root).expect("JSON values always serialise");
    while json.len() % 4 != 0 {
        json.push(b' ');
    }
    while bin.len() % 4 != 0 {
        bin.push(0);
    }
    let total = 12 + 8 + json.len() as u64 + 8 + bin.len() as u64;
    let length = u32::try_from(total).map_err(|_| ExportError::TooLarge { bytes: total })?;
    let mut out = Vec::with_capacity(total as usize);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&length.to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::export::lightmap::AtlasSize;
    use crate::export::tests::{cornell_baked, corner};
    use crate::export::{bake, export, LightmapOptions};
    use glam::{DVec2, DVec3};
    use gltf::accessor::{DataType, Dimensions};

    fn options(vertex_colors: VertexColors) -> ExportOptions {
        ExportOptions {
            lightmap: LightmapOptions {
                size: AtlasSize::Fit { max_side: 256 },
                gutter: 2,
            },
            vertex_colors,
            exposure_stops: -3.0,
        }
    }

    /// Writes the GLB into `$GLB_OUT_DIR` when set, for the Khronos validator and three.js
    /// (`scripts/validate_glb.mjs`).
    fn keep(name: &str, bytes: &[u8]) {
        if let Some(dir) = std::env::var_os("GLB_OUT_DIR") {
            std::fs::write(Path::new(&dir).join(name), bytes).unwrap();
        }
    }

    struct ReadBack {
        gltf: gltf::Gltf,
        blob: Vec<u8>,
    }

    /// A tightly packed FLOAT VEC3 accessor, read by hand (the gltf crate's reader has no
    /// accessor for custom attributes).
    fn read_vec3(back: &ReadBack, accessor: &gltf::Accessor) -> Vec<[f32; 3]> {
        assert_eq!(accessor.data_type(), DataType::F32);
        let view = accessor.view().unwrap();
        assert!(view.stride().is_none());
        let start = view.offset() + accessor.offset();
        back.blob[start..start + 12 * accessor.count()]
            .chunks_exact(12)
            .map(|c| [0, 4, 8].map(|o| f32::from_le_bytes([c[o], c[o + 1], c[o + 2], c[o + 3]])))
            .collect()
    }

    fn read_back(bytes: &[u8]) -> ReadBack {
        let gltf = gltf::Gltf::from_slice(bytes).expect("the gltf crate reads the GLB");
        let blob = gltf.blob.clone().expect("a BIN chunk");
        ReadBack { gltf, blob }
    }

    #[test]
    fn glb_reads_back_with_names_attributes_and_values() {
        let scene = cornell_baked();
        let opts = options(VertexColors::Linear);
        let baked = bake(&scene, &opts).unwrap();
        let bytes = glb_bytes(&scene, &baked, &opts).unwrap();
        keep("cornell_linear.glb", &bytes);
        keep(
            "cornell_lightmap.png",
            &baked.lightmap.png_bytes(-3.0).unwrap(),
        );
        let back = read_back(&bytes);
        let document = &back.gltf.document;
        let names: Vec<&str> = document.nodes().filter_map(|n| n.name()).collect();
        let mut expected: Vec<&str> = scene.objects.iter().map(|o| o.name.as_str()).collect();
        expected.push("camera");
        assert_eq!(names, expected);
        assert_eq!(document.materials().len(), 4);
        assert_eq!(document.images().len(), 1);
        for (o, node) in document.nodes().take(scene.objects.len()).enumerate() {
            let mesh = node.mesh().unwrap();
            assert_eq!(mesh.primitives().len(), 1);
            let primitive = mesh.primitives().next().unwrap();
            let out = &baked.objects[o][0];
            let input = &scene.objects[o].primitives[0];
            let attribute = |s: gltf::Semantic| primitive.get(&s).unwrap();
            for (semantic, dims) in [
                (gltf::Semantic::Positions, Dimensions::Vec3),
                (gltf::Semantic::Normals, Dimensions::Vec3),
                (gltf::Semantic::TexCoords(0), Dimensions::Vec2),
                (gltf::Semantic::TexCoords(1), Dimensions::Vec2),
                (gltf::Semantic::Colors(0), Dimensions::Vec3),
                (
                    gltf::Semantic::Extras("RADIANCE".to_owned()),
                    Dimensions::Vec3,
                ),
            ] {
                let a = attribute(semantic.clone());
                assert_eq!(a.data_type(), DataType::F32, "{semantic:?}");
                assert_eq!(a.dimensions(), dims, "{semantic:?}");
                assert!(!a.normalized(), "{semantic:?}");
                assert_eq!(a.count(), out.positions.len());
            }
            assert_eq!(
                attribute(gltf::Semantic::TexCoords(0)).index(),
                attribute(gltf::Semantic::TexCoords(1)).index()
            );
            assert!(attribute(gltf::Semantic::Positions).min().is_some());
            assert_eq!(primitive.indices().unwrap().data_type(), DataType::U16);
            let material = primitive.material();
            let emissive = material.emissive_texture().unwrap();
            assert_eq!(emissive.tex_coord(), 1);
            assert_eq!(material.emissive_factor(), [1.0; 3]);
            assert_eq!(
                material.pbr_metallic_roughness().base_color_factor(),
                [0.0, 0.0, 0.0, 1.0]
            );
            assert_eq!(
                material.name(),
                Some(scene.materials[input.material].name.as_str())
            );

            let reader = primitive.reader(|_| Some(&back.blob[..]));
            let colours: Vec<[f32; 3]> = reader.read_colors(0).unwrap().into_rgb_f32().collect();
            let radiance = read_vec3(
                &back,
                &attribute(gltf::Semantic::Extras("RADIANCE".to_owned())),
            );
            for k in 0..colours.len() {
                let source = input.radiance[out.source_vertex[k] as usize];
                for ch in 0..3 {
                    // Written and read as f32: equal to the input.
                    assert!((radiance[k][ch] - source[ch]).abs() <= 1e-6 * source[ch].max(1.0));
                    // Exposure −3 stops, clipped at 1.
                    let exposed = (source[ch] / 8.0).min(1.0);
                    assert!((colours[k][ch] - exposed).abs() <= 1e-6);
                }
            }
            let positions: Vec<[f32; 3]> = reader.read_positions().unwrap().collect();
            assert_eq!(positions, out.positions);
            let uv: Vec<[f32; 2]> = reader.read_tex_coords(1).unwrap().into_f32().collect();
            assert!(uv.iter().flatten().all(|x| (0.0..=1.0).contains(x)));
            let triangles: Vec<u32> = reader.read_indices().unwrap().into_u32().collect();
            assert_eq!(triangles.len(), 3 * input.triangles.len());
        }
        // The camera node points the camera where the scene's camera looks.
        let camera_node = document.nodes().last().unwrap();
        assert!(camera_node.camera().is_some());

        // Charts (one per Cornell object) do not overlap: their texel footprints, read back
        // from TEXCOORD_1 and the embedded image's size, are at least two gutters apart.
        let image = document.images().next().unwrap();
        let gltf::image::Source::View { view, .. } = image.source() else {
            panic!("image not in the buffer")
        };
        let png = image::load_from_memory(&back.blob[view.offset()..view.offset() + view.length()])
            .unwrap();
        let (w, h) = (f64::from(png.width()), f64::from(png.height()));
        let gutter = 2.0;
        let footprints: Vec<(DVec2, DVec2)> = document
            .meshes()
            .map(|mesh| {
                let primitive = mesh.primitives().next().unwrap();
                let reader = primitive.reader(|_| Some(&back.blob[..]));
                reader.read_tex_coords(1).unwrap().into_f32().fold(
                    (DVec2::INFINITY, DVec2::NEG_INFINITY),
                    |(lo, hi), t| {
                        let q = DVec2::new(f64::from(t[0]) * w, f64::from(t[1]) * h);
                        (lo.min(q), hi.max(q))
                    },
                )
            })
            .collect();
        for (i, a) in footprints.iter().enumerate() {
            for b in &footprints[i + 1..] {
                // f32 coordinates: 1e-3 texel of slack.
                let gap_x = (b.0.x - a.1.x).max(a.0.x - b.1.x);
                let gap_y = (b.0.y - a.1.y).max(a.0.y - b.1.y);
                assert!(
                    gap_x.max(gap_y) >= 2.0 * gutter - 1e-3,
                    "{a:?} and {b:?} overlap"
                );
            }
        }
    }

    #[test]
    fn srgb_vertex_colours_are_normalized_bytes() {
        let scene = cornell_baked();
        let opts = options(VertexColors::DisplaySrgb);
        let baked = bake(&scene, &opts).unwrap();
        let bytes = glb_bytes(&scene, &baked, &opts).unwrap();
        keep("cornell_srgb.glb", &bytes);
        let back = read_back(&bytes);
        let primitive = back
            .gltf
            .document
            .meshes()
            .next()
            .unwrap()
            .primitives()
            .next()
            .unwrap();
        let colour = primitive.get(&gltf::Semantic::Colors(0)).unwrap();
        assert_eq!(colour.data_type(), DataType::U8);
        assert_eq!(colour.dimensions(), Dimensions::Vec4);
        assert!(colour.normalized());
        let reader = primitive.reader(|_| Some(&back.blob[..]));
        let values: Vec<[u8; 4]> = reader.read_colors(0).unwrap().into_rgba_u8().collect();
        let out = &baked.objects[0][0];
        for (k, v) in values.iter().enumerate() {
            let l = out.radiance[k];
            assert_eq!(
                *v,
                [
                    srgb_byte(l[0] / 8.0),
                    srgb_byte(l[1] / 8.0),
                    srgb_byte(l[2] / 8.0),
                    255
                ]
            );
        }
    }

    #[test]
    fn lightmap_texels_match_the_glb_interpolation() {
        let scene = cornell_baked();
        let opts = options(VertexColors::Linear);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("box.glb");
        let summary = export(&scene, &path, &opts).unwrap();
        assert_eq!(summary.exr, dir.path().join("box_lightmap.exr"));
        assert_eq!(summary.png, dir.path().join("box_lightmap.png"));
        let exr = crate::render::Image::read_exr(&summary.exr).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let back = read_back(&bytes);
        // The PNG embedded in the GLB.
        let image = back.gltf.document.images().next().unwrap();
        let png = match image.source() {
            gltf::image::Source::View { view, mime_type } => {
                assert_eq!(mime_type, "image/png");
                image::load_from_memory(&back.blob[view.offset()..view.offset() + view.length()])
                    .unwrap()
                    .to_rgb8()
            }
            _ => panic!("image not in the buffer"),
        };
        assert_eq!(png.dimensions(), (exr.width, exr.height));
        assert_eq!(png, image::open(&summary.png).unwrap().to_rgb8());
        let (w, h) = (f64::from(exr.width), f64::from(exr.height));
        let mut checked = 0;
        for mesh in back.gltf.document.meshes() {
            for primitive in mesh.primitives() {
                let reader = primitive.reader(|_| Some(&back.blob[..]));
                let uv: Vec<DVec2> = reader
                    .read_tex_coords(1)
                    .unwrap()
                    .into_f32()
                    .map(|t| DVec2::new(f64::from(t[0]) * w, f64::from(t[1]) * h))
                    .collect();
                let radiance = primitive
                    .get(&gltf::Semantic::Extras("RADIANCE".to_owned()))
                    .unwrap();
                let colour: Vec<DVec3> = read_vec3(&back, &radiance)
                    .into_iter()
                    .map(|c| DVec3::from_array(c.map(f64::from)))
                    .collect();
                let indices: Vec<u32> = reader.read_indices().unwrap().into_u32().collect();
                for t in indices.chunks_exact(3) {
                    let [a, b, c] = [t[0], t[1], t[2]].map(|i| i as usize);
                    let area = (uv[b] - uv[a]).perp_dot(uv[c] - uv[a]);
                    let lo = uv[a].min(uv[b]).min(uv[c]).floor();
                    let hi = uv[a].max(uv[b]).max(uv[c]).ceil();
                    for y in lo.y as u32..hi.y as u32 {
                        for x in lo.x as u32..hi.x as u32 {
                            let q = DVec2::new(f64::from(x) + 0.5, f64::from(y) + 0.5);
                            let la = (uv[c] - uv[b]).perp_dot(q - uv[b]) / area;
                            let lb = (uv[a] - uv[c]).perp_dot(q - uv[c]) / area;
                            let lc = 1.0 - la - lb;
                            if la < 1e-6 || lb < 1e-6 || lc < 1e-6 {
                                continue;
                            }
                            let expected = colour[a] * la + colour[b] * lb + colour[c] * lc;
                            let texel = exr.get(x, y);
                            let encoded = png.get_pixel(x, y).0;
                            for ch in 0..3 {
                                // EXR: f32 of the same interpolation (relative 1e-6).
                                assert!(
                                    (f64::from(texel[ch]) - expected[ch]).abs()
                                        <= 1e-5 * expected[ch].max(1.0)
                                );
                                // PNG: 8-bit rounding of the same value.
                                let reference = srgb_byte((expected[ch] / 8.0) as f32);
                                assert!(encoded[ch].abs_diff(reference) <= 1, "({x}, {y})");
                            }
                            checked += 1;
                        }
                    }
                }
            }
        }
        assert!(checked > 5000, "{checked}");
    }

    #[test]
    fn exported_glb_loads_back_with_the_same_geometry_and_camera() {
        let scene = cornell_baked();
        let opts = options(VertexColors::Linear);
        let baked = bake(&scene, &opts).unwrap();
        let bytes = glb_bytes(&scene, &baked, &opts).unwrap();
        let loaded = crate::io::gltf::parse_gltf(
            &bytes,
            "export.glb",
            Path::new("."),
            "export",
            &crate::io::gltf::GltfOptions::default(),
        )
        .unwrap()
        .scene;
        let original = crate::cornell::cornell_box();
        assert_eq!(loaded.object_names(), original.object_names());
        for name in original.object_names() {
            let area = |s: &crate::scene::Scene| -> f64 {
                s.surfaces
                    .iter()
                    .filter(|x| x.object == name)
                    .map(|x| x.polygon.area())
                    .sum()
            };
            // f32 positions: relative 1e-6.
            assert!(
                (area(&loaded) - area(&original)).abs() < 1e-6 * area(&original),
                "{name}"
            );
        }
        let (a, b) = (loaded.camera.unwrap(), original.camera.unwrap());
        assert!(a.eye.distance(b.eye) < 1e-6);
        let look = |c: crate::scene::Camera| (c.target - c.eye).normalize();
        assert!(look(a).distance(look(b)) < 1e-6);
        assert!(a.up.distance(b.up) < 1e-6);
        assert!((a.fov_deg - b.fov_deg).abs() < 1e-5);
    }

    #[test]
    fn corner_scene_with_shared_vertices_is_written() {
        let scene = corner();
        let opts = options(VertexColors::Linear);
        let baked = bake(&scene, &opts).unwrap();
        let bytes = glb_bytes(&scene, &baked, &opts).unwrap();
        keep("corner.glb", &bytes);
        let back = read_back(&bytes);
        let primitive = back
            .gltf
            .document
            .meshes()
            .next()
            .unwrap()
            .primitives()
            .next()
            .unwrap();
        assert_eq!(
            primitive.get(&gltf::Semantic::Positions).unwrap().count(),
            8
        );
    }

    #[test]
    fn failed_export_leaves_no_files() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("missing").join("box.glb");
        let e = export(&cornell_baked(), &path, &options(VertexColors::Linear)).unwrap_err();
        assert!(e.to_string().contains("box_lightmap.exr"), "{e}");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
        // An invalid scene fails before anything is written.
        let path = dir.path().join("box.glb");
        let mut scene = cornell_baked();
        scene.objects[3].primitives[0].radiance[0] = [f32::NAN; 3];
        let e = export(&scene, &path, &options(VertexColors::Linear)).unwrap_err();
        assert!(e
            .to_string()
            .contains(&format!("object '{}'", scene.objects[3].name)));
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }
}
