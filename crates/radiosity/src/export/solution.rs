//! A solved scene as a [`BakedScene`]: the crack-free display mesh
//! ([`DisplayMesh`], the one place per-vertex radiosity is computed), grouped by object and
//! material.
//!
//! - One [`BakedObject`] per scene object (in the scene's order, named as in the input file),
//!   one [`BakedPrimitive`] per material the object uses (in order of first use).
//! - Triangles are the smooth display mesh's, for every element whatever the viewpoint;
//!   vertex radiance L = B/π (W·m⁻²·sr⁻¹) per vertex; normals the element's.
//! - A chart is one meshed surface (a scene surface, or a piece of one split where another
//!   surface touches it), so each chart is planar.
//! - A two-sided surface is exported as its two sides, back to back, each a one-sided sheet
//!   with its own radiance (the GLB's `doubleSided` is off, so each side shows only from its
//!   front and the two never fight for the same pixels).

use super::{BakedMaterial, BakedObject, BakedPrimitive, BakedScene};
use crate::display::{DisplayMesh, Shading};
use crate::mesh::Mesh;
use crate::scene::Scene;
use std::collections::HashMap;
use std::f64::consts::PI;

/// The solved scene ready for [`super::export`]: `mesh` is the mesh `scene` was solved on,
/// `radiosity` the displayed radiosity per element (W·m⁻²), e.g.
/// `Solution::display_radiosity`.
///
/// The camera is the scene's, or its default view ([`Scene::camera_or_default`]).
pub fn baked_scene(scene: &Scene, mesh: &Mesh, radiosity: &[[f64; 3]]) -> BakedScene {
    let display = DisplayMesh::build(&mesh.vertices, &mesh.elements, radiosity, Shading::Smooth);
    let materials: Vec<BakedMaterial> = scene
        .materials
        .iter()
        .map(|m| BakedMaterial {
            name: m.name.clone(),
            reflectance: m.reflectance.map(|x| x as f32),
            emission: m.emission.map(|x| x as f32),
            two_sided: false,
        })
        .collect();
    let mut objects: Vec<BakedObject> = mesh
        .objects
        .iter()
        .map(|name| BakedObject {
            name: name.clone(),
            primitives: Vec::new(),
        })
        .collect();
    // (object, material) → primitive index, and display vertex → primitive vertex.
    let names = scene.object_names();
    let surface_material: Vec<usize> = (0..mesh.surfaces.len())
        .map(|s| material_of(scene, &names, mesh, s))
        .collect();
    let mut primitive_of: HashMap<(usize, usize), usize> = HashMap::new();
    let mut vertex_of: Vec<HashMap<u32, u32>> = Vec::new();
    for (triangle, &element) in display.triangles.iter().zip(&display.triangle_element) {
        let e = &mesh.elements[element as usize];
        let surface = &mesh.surfaces[e.surface as usize];
        let object = surface.object as usize;
        let material = surface_material[e.surface as usize];
        let slot = *primitive_of.entry((object, material)).or_insert_with(|| {
            objects[object].primitives.push(BakedPrimitive {
                material,
                ..BakedPrimitive::default()
            });
            vertex_of.push(HashMap::new());
            vertex_of.len() - 1
        });
        let index = objects[object]
            .primitives
            .iter()
            .position(|p| p.material == material)
            .unwrap_or(0);
        let primitive = &mut objects[object].primitives[index];
        let map = &mut vertex_of[slot];
        let corners = triangle.map(|v| {
            *map.entry(v).or_insert_with(|| {
                primitive
                    .positions
                    .push(display.positions[v as usize].as_vec3().to_array());
                primitive.normals.push(e.normal.as_vec3().to_array());
                primitive
                    .radiance
                    .push(display.vertex_radiosity[v as usize].map(|b| (b / PI) as f32));
                (primitive.positions.len() - 1) as u32
            })
        });
        primitive.triangles.push(corners);
        primitive.charts.push(e.surface);
    }
    objects.retain(|o| !o.primitives.is_empty());
    BakedScene {
        name: scene.name.clone(),
        materials,
        objects,
        camera: Some(scene.camera_or_default()),
    }
}

/// The scene material of a meshed surface: its scene surface's, or (for a mesh built from
/// another view of the scene, e.g. explicit back sides) the first material with the same
/// reflectance.
fn material_of(scene: &Scene, names: &[String], mesh: &Mesh, surface: usize) -> usize {
    let data = &mesh.surfaces[surface];
    if let Some(s) = scene.surfaces.get(data.scene_surface as usize) {
        if names.get(data.object as usize) == Some(&s.object) {
            return s.material.0 as usize;
        }
    }
    scene
        .materials
        .iter()
        .position(|m| m.reflectance == data.reflectance)
        .unwrap_or(0)
}
