//! Two-sided surfaces as explicit back-to-back pairs of one-sided surfaces, for consumers that
//! work on the scene rather than on [`Mesh`](super::Mesh) (which gives two-sided surfaces
//! their twins itself while meshing, see [`super`]).

use crate::scene::{Material, MaterialId, Scene, Surface};

/// The scene with every surface of a two-sided material followed by its back side: the same
/// polygon with the vertex order reversed, with a material `"<name> (back)"` of the same
/// reflectance that emits only if the material has `two_sided_emission`. Every material of
/// the result is one-sided. `None` when no surface is two-sided (nothing to do).
pub fn with_back_sides(scene: &Scene) -> Option<Scene> {
    if !scene.surfaces.iter().any(|s| scene.material(s).two_sided) {
        return None;
    }
    let mut materials: Vec<Material> = scene
        .materials
        .iter()
        .map(|m| Material {
            two_sided: false,
            two_sided_emission: false,
            ..m.clone()
        })
        .collect();
    let mut back_of: Vec<Option<MaterialId>> = vec![None; scene.materials.len()];
    let mut surfaces = Vec::with_capacity(scene.surfaces.len() * 2);
    for surface in &scene.surfaces {
        surfaces.push(surface.clone());
        let index = surface.material.0 as usize;
        let material = &scene.materials[index];
        if !material.two_sided {
            continue;
        }
        let back = *back_of[index].get_or_insert_with(|| {
            let emission = if material.two_sided_emission {
                material.emission
            } else {
                [0.0; 3]
            };
            materials.push(Material::new(
                unique_name(&scene.materials, &format!("{} (back)", material.name)),
                material.reflectance,
                emission,
            ));
            MaterialId((materials.len() - 1) as u32)
        });
        let mut vertices = surface.polygon.vertices().to_vec();
        vertices.reverse();
        surfaces.push(Surface {
            material: back,
            polygon: crate::geometry::Polygon::new_unchecked(vertices),
            ..surface.clone()
        });
    }
    Some(Scene {
        materials,
        surfaces,
        ..scene.clone()
    })
}

/// `name`, or `name 2`, `name 3`, … if a material already has it.
fn unique_name(materials: &[Material], name: &str) -> String {
    let taken = |n: &str| materials.iter().any(|m| m.name == n);
    if !taken(name) {
        return name.to_owned();
    }
    (2..)
        .map(|k| format!("{name} {k}"))
        .find(|n| !taken(n))
        .unwrap_or_default()
}
