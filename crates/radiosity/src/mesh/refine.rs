//! Adaptive mesh refinement: split elements where the radiosity changes fast.
//!
//! After Cohen, Greenberg, Immel & Brock (1986): solve on a coarse mesh, estimate where the
//! piecewise-constant radiosity is a poor fit — here the largest difference between an
//! element and the elements sharing a vertex with it on the same surface (a finite-difference
//! gradient times the element size) — and split those elements into four, keeping their
//! patch (the patch → element hierarchy) and their parent. The solution is then recomputed
//! on the refined elements. Split elements leave hanging vertices on unsplit neighbours;
//! [`crate::display`] inserts them into the neighbours' edges (no cracks) and constrains
//! their values to the edge's interpolation (no seams).

use crate::mesh::{Element, Mesh};
use glam::DVec3;
use std::collections::HashMap;

/// How to refine.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RefineOptions {
    /// Split an element when its radiosity differs from a neighbour's by more than this
    /// fraction of the mean radiosity of the reflecting (non-emitting) surfaces.
    pub threshold: f64,
    /// Maximum number of times an element of the initial mesh may be split.
    pub max_depth: u8,
    /// Stop splitting once the mesh has this many elements (the most urgent splits first).
    pub max_elements: Option<usize>,
}

impl Default for RefineOptions {
    fn default() -> Self {
        Self {
            threshold: 0.1,
            max_depth: 3,
            max_elements: None,
        }
    }
}

/// Per-element refinement urgency: max over same-surface neighbours (sharing a vertex) of
/// Σ_c |B_e,c − B_n,c|, in W·m⁻².
pub fn gradients(mesh: &Mesh, radiosity: &[[f64; 3]]) -> Vec<f64> {
    let mut by_vertex: HashMap<u32, Vec<u32>> = HashMap::new();
    for (i, e) in mesh.elements.iter().enumerate() {
        for &c in &e.corners {
            by_vertex.entry(c).or_default().push(i as u32);
        }
    }
    // Hanging vertices (on a neighbour's edge) also make neighbours: find them by position.
    let conformity = crate::display::Conformity::find(&mesh.vertices, &mesh.elements);
    for (i, _) in mesh.elements.iter().enumerate() {
        for v in conformity.hanging_on(i) {
            by_vertex.entry(v).or_default().push(i as u32);
        }
    }
    mesh.elements
        .iter()
        .enumerate()
        .map(|(i, e)| {
            let mut g: f64 = 0.0;
            for c in &e.corners {
                for &n in &by_vertex[c] {
                    let other = &mesh.elements[n as usize];
                    if n as usize == i || other.surface != e.surface {
                        continue;
                    }
                    let d: f64 = (0..3)
                        .map(|ch| (radiosity[i][ch] - radiosity[n as usize][ch]).abs())
                        .sum();
                    g = g.max(d);
                }
            }
            g
        })
        .collect()
}

/// Chooses the elements to split: urgency (gradient × √area, an estimate of the error a
/// split removes) above the threshold, depth below the maximum, most urgent first within the
/// element budget. Emitters are never split (their radiosity is dominated by emission).
pub fn mark(mesh: &Mesh, radiosity: &[[f64; 3]], options: &RefineOptions) -> Vec<bool> {
    let g = gradients(mesh, radiosity);
    let (mut sum, mut area) = (0.0, 0.0);
    for (e, b) in mesh.elements.iter().zip(radiosity) {
        if mesh.exitance(e).iter().all(|&x| x == 0.0) {
            sum += (b[0] + b[1] + b[2]) * e.area;
            area += e.area;
        }
    }
    let mean = if area > 0.0 { sum / area } else { 0.0 };
    let limit = options.threshold * mean;
    let mut candidates: Vec<(f64, usize)> = mesh
        .elements
        .iter()
        .enumerate()
        .filter(|(i, e)| {
            e.depth < options.max_depth
                && g[*i] > limit
                && mesh.exitance(e).iter().all(|&x| x == 0.0)
        })
        .map(|(i, e)| (g[i] * e.area.sqrt(), i))
        .collect();
    candidates.sort_by(|a, b| b.0.total_cmp(&a.0));
    if let Some(max) = options.max_elements {
        // Each split adds three elements.
        let room = max.saturating_sub(mesh.elements.len()) / 3;
        candidates.truncate(room);
    }
    let mut marked = vec![false; mesh.elements.len()];
    for (_, i) in candidates {
        marked[i] = true;
    }
    marked
}

/// Splits the marked elements into four ([`crate::geometry::subdivide`] of order 2: quads at
/// edge midpoints and centre, triangles at edge midpoints). Patches are unchanged; each child records its parent's index in `mesh`.
/// The first shot (`direct`) is kept for unsplit elements and NaN for the children, which
/// the pipeline then lights ([`crate::direct::illuminate`]).
/// Midpoints are shared with neighbours split in the same or an earlier pass.
pub fn refine(mesh: &Mesh, marked: &[bool]) -> Mesh {
    let mut vertices = mesh.vertices.clone();
    // Vertex welding keyed by (surface, exact position), seeded with the existing vertices.
    let mut weld: HashMap<(u32, [u64; 3]), u32> = HashMap::new();
    let bits = |p: DVec3| [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()];
    for e in &mesh.elements {
        for &c in &e.corners {
            weld.insert((e.surface, bits(mesh.vertices[c as usize])), c);
        }
    }
    let mut vertex = |surface: u32, p: DVec3, vertices: &mut Vec<DVec3>| -> u32 {
        *weld.entry((surface, bits(p))).or_insert_with(|| {
            vertices.push(p);
            (vertices.len() - 1) as u32
        })
    };
    let mut elements =
        Vec::with_capacity(mesh.elements.len() + 3 * marked.iter().filter(|m| **m).count());
    let mut patches = mesh.patches.clone();
    for (pi, patch) in mesh.patches.iter().enumerate() {
        let first = elements.len() as u32;
        for ei in patch.elements.clone() {
            let e = &mesh.elements[ei as usize];
            if !marked[ei as usize] {
                elements.push(Element {
                    parent: Some(ei),
                    ..e.clone()
                });
                continue;
            }
            let p: Vec<DVec3> = e.corners.iter().map(|&c| vertices[c as usize]).collect();
            // Quads at edge midpoints and centre, triangles at edge midpoints: the lattice
            // of order 2, whose edge points are exact midpoints shared with neighbours.
            // A cell of many corners (along the outline of a polygon of many vertices) is cut
            // in four by the square grid of `sub_areas`, not into the slivers of its fan.
            let children = if p.len() > 4 {
                crate::geometry::sub_areas(&p, 2)
            } else {
                crate::geometry::subdivide(&p, 2)
            };
            for child in children {
                let polygon = crate::geometry::Polygon::new_unchecked(child.clone());
                let corners = child
                    .iter()
                    .map(|q| vertex(e.surface, *q, &mut vertices))
                    .collect();
                elements.push(Element {
                    surface: e.surface,
                    patch: e.patch,
                    corners,
                    centre: polygon.centroid(),
                    normal: polygon.normal(),
                    area: polygon.area(),
                    parent: Some(ei),
                    depth: e.depth + 1,
                });
            }
        }
        patches[pi].elements = first..elements.len() as u32;
    }
    // The first shot carries over to unsplit elements; split ones are marked (NaN) for
    // `direct::illuminate` to compute.
    let direct = if mesh.direct.is_empty() {
        Vec::new()
    } else {
        elements
            .iter()
            .map(|e| match e.parent {
                Some(p) if mesh.elements[p as usize].depth == e.depth => mesh.direct[p as usize],
                _ => [f64::NAN; 3],
            })
            .collect()
    };
    Mesh {
        vertices,
        elements,
        patches,
        surfaces: mesh.surfaces.clone(),
        objects: mesh.objects.clone(),
        surface_polygons: mesh.surface_polygons.clone(),
        direct,
        light_power: mesh.light_power,
        twin: mesh.twin.clone(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Polygon;
    use crate::mesh::MeshOptions;
    use crate::scene::{Material, MaterialId, Origin, Scene, Surface};

    fn plane() -> Mesh {
        let scene = Scene {
            name: "p".into(),
            materials: vec![Material::new("m", [0.5; 3], [0.0; 3])],
            surfaces: vec![
                Surface {
                    object: "quad".into(),
                    group: String::new(),
                    material: MaterialId(0),
                    polygon: Polygon::new(vec![
                        DVec3::ZERO,
                        DVec3::X,
                        DVec3::new(1.0, 1.0, 0.0),
                        DVec3::Y,
                    ])
                    .unwrap(),
                    origin: Origin::default(),
                },
                Surface {
                    object: "tri".into(),
                    group: String::new(),
                    material: MaterialId(0),
                    polygon: Polygon::new(vec![
                        DVec3::new(0.0, 0.0, 1.0),
                        DVec3::new(1.0, 0.0, 1.0),
                        DVec3::new(0.0, 1.0, 1.0),
                    ])
                    .unwrap(),
                    origin: Origin::default(),
                },
            ],
            lights: Vec::new(),
            camera: None,
        };
        let opts = MeshOptions {
            max_element_size: Some(0.25),
            elements: 0,
            patch_subdivision: 2,
        };
        Mesh::build(&scene, &opts).unwrap()
    }

    #[test]
    fn refinement_conserves_area_and_shares_midpoints() {
        let mesh = plane();
        let mut marked = vec![false; mesh.len()];
        marked[0] = true;
        marked[1] = true; // neighbours: their shared edge's midpoint must be one vertex
        let last = mesh.len() - 1;
        marked[last] = true;
        let fine = refine(&mesh, &marked);
        assert_eq!(fine.len(), mesh.len() + 9);
        let area = |m: &Mesh, s: u32| {
            m.elements
                .iter()
                .filter(|e| e.surface == s)
                .map(|e| e.area)
                .sum::<f64>()
        };
        for s in 0..2 {
            assert!((area(&mesh, s) - area(&fine, s)).abs() < 1e-12);
        }
        for p in &fine.patches {
            assert!((fine.patch_area(p) - p.polygon.area()).abs() < 1e-12);
            for e in p.elements.clone() {
                assert_eq!(
                    fine.elements[e as usize].patch.0 as usize,
                    fine.patches.iter().position(|q| q == p).unwrap()
                );
            }
        }
        // 2 quads split side by side: 5 + 5 new vertices, sharing 1 edge midpoint → 9 ...
        // plus the triangle's 3 midpoints.
        assert_eq!(fine.vertices.len(), mesh.vertices.len() + 9 + 3);
        assert!(fine
            .elements
            .iter()
            .filter(|e| e.depth == 1)
            .all(|e| e.parent.is_some()));
    }

    #[test]
    fn marks_where_radiosity_jumps() {
        let mesh = plane();
        // A step in radiosity across x = 0.5 on the quad.
        let b: Vec<[f64; 3]> = mesh
            .elements
            .iter()
            .map(|e| match (e.surface, e.centre.x < 0.5) {
                (0, true) => [1.0; 3],
                (0, false) => [0.1; 3],
                _ => [0.5; 3],
            })
            .collect();
        let marked = mark(&mesh, &b, &RefineOptions::default());
        for (e, m) in mesh.elements.iter().zip(&marked) {
            let near_step = e.surface == 0 && (e.centre.x - 0.5).abs() < 0.25;
            assert_eq!(*m, near_step, "element at {:?}", e.centre);
        }
        // The budget limits the splits.
        let few = mark(
            &mesh,
            &b,
            &RefineOptions {
                max_elements: Some(mesh.len() + 3),
                ..Default::default()
            },
        );
        assert_eq!(few.iter().filter(|m| **m).count(), 1);
    }
}
