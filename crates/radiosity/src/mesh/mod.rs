//! Meshing: each surface is divided into patches, and each patch into elements.
//!
//! This is the two-level substructuring of Cohen, Greenberg, Immel & Brock (1986), "An
//! efficient radiosity approach for realistic image synthesis": patches are the coarse
//! sources of light, elements the fine receivers on which radiosity is resolved and
//! displayed. With `patch_subdivision = 1` every element is its own patch and the system is
//! the plain element-to-element one.
//!
//! Quads are divided on a bilinear lattice, triangles (and the fan triangles of n-gons of up
//! to eight vertices) on a barycentric lattice, so elements of one surface share their
//! vertices: the display mesh has no cracks inside a surface. Polygons of more vertices are
//! cut by a square lattice in their plane ([`grid`]): whole cells inside, clipped cells
//! along the outline, as many as the element size asks for whatever the vertex count.
//!
//! Two-sided surfaces ([`crate::scene::Material::two_sided`]) are meshed once and then given
//! a back-to-back twin: a second surface with the same elements, corners in reverse order
//! (normal reversed), its own vertices (so smoothing never blends the two sides), its own
//! patches, the same reflectance and no emission unless the material asks for
//! `two_sided_emission`. The two sides are ordinary one-sided surfaces for everything
//! downstream: each side's elements see only the half-space in front of them, and the shared
//! plane blocks light from crossing (both sides are in the visibility structure, and each is
//! opaque from both directions), so light reaching one side never reaches the other through
//! the surface. The element budget (`elements`) counts both sides.

pub mod contacts;
pub mod grid;
pub mod merge;
pub mod refine;
pub mod two_sided;

pub use contacts::split_at_contacts;
pub use refine::RefineOptions;

use crate::geometry::{Lattice, Polygon};
use crate::scene::{Scene, SurfaceId};
use glam::DVec3;
use serde::{Deserialize, Serialize};
use std::collections::HashMap;
use std::ops::Range;

/// Index of an element in [`Mesh::elements`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub struct ElementId(pub u32);

/// Index of a patch in [`Mesh::patches`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub struct PatchId(pub u32);

/// The largest mesh we agree to build (elements); beyond it memory and time are absurd here.
pub const MAX_ELEMENTS: usize = 4_000_000;

/// How finely to mesh.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeshOptions {
    /// Maximum element edge length in metres; overrides `elements` when set.
    pub max_element_size: Option<f64>,
    /// Approximate total element count (used when `max_element_size` is `None`).
    pub elements: usize,
    /// Elements per patch edge (a patch holds about this squared many elements).
    pub patch_subdivision: u32,
}

impl Default for MeshOptions {
    fn default() -> Self {
        Self {
            max_element_size: None,
            elements: 4000,
            patch_subdivision: 3,
        }
    }
}

/// Why a mesh could not be built.
#[derive(Debug, thiserror::Error)]
pub enum MeshError {
    #[error("element size must be a positive finite length in metres, got {0}")]
    /// The element size is not a positive length.
    BadElementSize(f64),
    #[error("element count must be at least 1, got {0}")]
    /// The element count is zero.
    BadElementCount(usize),
    #[error("patch subdivision must be between 1 and 64, got {0}")]
    /// The patch subdivision is out of range.
    BadPatchSubdivision(u32),
    #[error(
        "meshing would create about {estimate} elements (limit {limit}); use a larger element size"
    )]
    /// Meshing would exceed the element limit.
    TooManyElements {
        /// The estimate.
        estimate: usize,
        /// The largest accepted.
        limit: usize,
    },
    #[error("the scene has no surfaces")]
    /// Nothing to mesh.
    EmptyScene,
}

/// A receiving element: a small convex polygon of one surface.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Element {
    /// The (split) surface it belongs to, an index into [`Mesh::surfaces`].
    pub surface: u32,
    /// The patch it belongs to.
    pub patch: PatchId,
    /// Indices into [`Mesh::vertices`], counter-clockwise seen from the front (3 or 4; more
    /// for the cells along the outline of a polygon of many vertices, [`grid`]).
    pub corners: Vec<u32>,
    /// Area centroid, m.
    pub centre: DVec3,
    /// Unit normal of the front side.
    pub normal: DVec3,
    /// Area in m².
    pub area: f64,
    /// The element this one was split from by adaptive refinement (index in the mesh it
    /// was refined from), if any.
    #[serde(default)]
    pub parent: Option<u32>,
    /// Refinement depth: 0 for elements of the initial mesh.
    #[serde(default)]
    pub depth: u8,
}

/// A shooting patch: a convex polygon made of whole elements of one surface.
#[derive(Debug, Clone, PartialEq)]
pub struct Patch {
    /// The (split) surface it belongs to, an index into [`Mesh::surfaces`].
    pub surface: u32,
    /// Its outline.
    pub polygon: Polygon,
    /// The elements making up this patch (contiguous).
    pub elements: Range<u32>,
}

/// Per-surface material data the solver needs, copied out of the scene.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SurfaceData {
    /// Index into [`Mesh::objects`].
    pub object: u32,
    /// The scene surface this (piece of a) surface comes from.
    #[serde(default)]
    pub scene_surface: u32,
    /// Reflectance ρ per channel.
    pub reflectance: [f64; 3],
    /// Emitted exitance E = π·L_e per channel, W·m⁻².
    pub exitance: [f64; 3],
}

/// The meshed scene: vertices, elements, patches and per-surface material data.
#[derive(Debug, Clone, Default)]
pub struct Mesh {
    /// Vertices shared by the elements of a surface, m.
    pub vertices: Vec<DVec3>,
    /// The receiving elements.
    pub elements: Vec<Element>,
    /// The shooting patches.
    pub patches: Vec<Patch>,
    /// Material data per (split) surface.
    pub surfaces: Vec<SurfaceData>,
    /// Object names, as in the scene.
    pub objects: Vec<String>,
    /// The meshed surface polygons (scene surfaces, split where other surfaces touch them),
    /// indexed like `surfaces`; element `surface` fields index these.
    pub surface_polygons: Vec<Polygon>,
    /// Irradiance of each element straight from the scene's light sources (the first shot,
    /// [`crate::direct`]), W·m⁻²; empty when the scene has none. Filled by the pipeline
    /// once visibility is known ([`crate::direct::illuminate`]).
    pub direct: Vec<[f64; 3]>,
    /// Total flux of the scene's light sources, W per channel (emitted power besides the
    /// emitting surfaces').
    pub light_power: [f64; 3],
    /// The back-to-back twin of each surface of a two-sided material, indexed like
    /// `surfaces` (both ways; shorter or empty where no surface has one).
    pub twin: Vec<Option<u32>>,
}

impl Mesh {
    /// Meshes every surface of the scene.
    pub fn build(scene: &Scene, options: &MeshOptions) -> Result<Mesh, MeshError> {
        if scene.surfaces.is_empty() {
            return Err(MeshError::EmptyScene);
        }
        if !(1..=64).contains(&options.patch_subdivision) {
            return Err(MeshError::BadPatchSubdivision(options.patch_subdivision));
        }
        // Coplanar neighbours of one object and material (a tessellated wall) mesh as the
        // one convex polygon they make: the budget, not the modelling, sets the elements.
        let (merged, original) = merge::merge_coplanar(scene);
        let scene = &merged;
        let pieces = split_at_contacts(scene);
        let two_sided = |si: usize| scene.material(&scene.surfaces[si]).two_sided;
        // Both sides of a two-sided piece take their share of the element budget.
        let polygons: Vec<&Polygon> = pieces
            .iter()
            .flat_map(|(si, p)| std::iter::repeat_n(p, 1 + usize::from(two_sided(*si))))
            .collect();
        let size = match options.max_element_size {
            Some(h) if h.is_finite() && h > 0.0 => h,
            Some(h) => return Err(MeshError::BadElementSize(h)),
            None => {
                if options.elements == 0 {
                    return Err(MeshError::BadElementCount(0));
                }
                if options.elements > MAX_ELEMENTS {
                    return Err(MeshError::TooManyElements {
                        estimate: options.elements,
                        limit: MAX_ELEMENTS,
                    });
                }
                let size = size_for_count(&polygons, options.elements);
                within_budget(&polygons, size, options.patch_subdivision, options.elements)
            }
        };
        let estimate: f64 = polygons.iter().map(|p| estimate_elements(p, size)).sum();
        if estimate > MAX_ELEMENTS as f64 {
            return Err(MeshError::TooManyElements {
                estimate: estimate.min(usize::MAX as f64) as usize,
                limit: MAX_ELEMENTS,
            });
        }

        let objects = scene.object_names();
        let object_index: std::collections::HashMap<&str, u32> = objects
            .iter()
            .enumerate()
            .map(|(i, o)| (o.as_str(), i as u32))
            .collect();
        let mut mesh = Mesh {
            vertices: Vec::new(),
            elements: Vec::new(),
            patches: Vec::new(),
            surfaces: Vec::new(),
            objects: objects.clone(),
            surface_polygons: Vec::new(),
            direct: Vec::new(),
            light_power: [0.0; 3],
            twin: Vec::new(),
        };
        for (scene_surface, polygon) in pieces.iter() {
            let surface = &scene.surfaces[*scene_surface];
            let material = scene.material(surface);
            let object = object_index
                .get(surface.object.as_str())
                .copied()
                .unwrap_or(0);
            mesh.surfaces.push(SurfaceData {
                object,
                scene_surface: original[*scene_surface] as u32,
                reflectance: material.reflectance,
                exitance: material.exitance(),
            });
            mesh.surface_polygons.push(polygon.clone());
            let (first_vertex, first_element, first_patch) =
                (mesh.vertices.len(), mesh.elements.len(), mesh.patches.len());
            let id = SurfaceId((mesh.surfaces.len() - 1) as u32);
            mesh.mesh_surface(id, polygon, size, options.patch_subdivision);
            if material.two_sided {
                let back_exitance = if material.two_sided_emission {
                    material.exitance()
                } else {
                    [0.0; 3]
                };
                mesh.push_twin(id, first_vertex, first_element, first_patch, back_exitance);
            }
        }
        Ok(mesh)
    }

    /// Number of elements.
    pub fn len(&self) -> usize {
        self.elements.len()
    }

    /// Whether the mesh has no elements.
    pub fn is_empty(&self) -> bool {
        self.elements.is_empty()
    }

    /// The polygon of an element.
    pub fn element_polygon(&self, e: &Element) -> Polygon {
        Polygon::new_unchecked(
            e.corners
                .iter()
                .map(|&c| self.vertices[c as usize])
                .collect(),
        )
    }

    /// Reflectance of an element's surface.
    pub fn reflectance(&self, e: &Element) -> [f64; 3] {
        self.surfaces[e.surface as usize].reflectance
    }

    /// Emitted exitance of an element's surface, W·m⁻².
    pub fn exitance(&self, e: &Element) -> [f64; 3] {
        self.surfaces[e.surface as usize].exitance
    }

    /// Irradiance of element `i` straight from the light sources, W·m⁻² (zero without
    /// lights).
    pub fn direct(&self, i: usize) -> [f64; 3] {
        self.direct.get(i).copied().unwrap_or([0.0; 3])
    }

    /// What element `i` puts into the radiosity system before any interreflection, W·m⁻²:
    /// its emitted exitance plus the reflected first shot, E_i + ρ_i · direct_i. Every
    /// solver solves B = source + ρ K(B).
    pub fn source(&self, i: usize) -> [f64; 3] {
        let e = &self.elements[i];
        let surface = &self.surfaces[e.surface as usize];
        let d = self.direct(i);
        std::array::from_fn(|c| surface.exitance[c] + surface.reflectance[c] * d[c])
    }

    /// Corners of an element, counter-clockwise seen from its front.
    pub fn element_corners(&self, e: &Element) -> Vec<DVec3> {
        e.corners
            .iter()
            .map(|&c| self.vertices[c as usize])
            .collect()
    }

    /// Area of a patch in m² (sum of its elements).
    pub fn patch_area(&self, p: &Patch) -> f64 {
        self.elements[p.elements.start as usize..p.elements.end as usize]
            .iter()
            .map(|e| e.area)
            .sum()
    }

    /// Meshes one surface polygon: a quad on a bilinear lattice of `pu·ku × pv·kv` elements
    /// grouped `ku × kv` into patches; a triangle (or each fan triangle of an n-gon, all on
    /// one level so their shared diagonals conform) on a barycentric lattice of `(m·k)²`
    /// elements grouped `k²` into `m²` patch triangles ([`Lattice`]); a polygon of many
    /// vertices on a square lattice in its plane, `sub × sub` cells a patch ([`grid`]).
    fn mesh_surface(&mut self, surface: SurfaceId, polygon: &Polygon, size: f64, sub: u32) {
        let mut welder = Welder::default();
        let v = polygon.vertices();
        if grid::uses_grid(polygon) {
            for block in grid::mesh_on_grid(polygon, size, sub) {
                let first = self.elements.len() as u32;
                let patch = PatchId(self.patches.len() as u32);
                for cell in &block.elements {
                    self.push_element(surface, patch, cell, &mut welder);
                }
                self.push_patch(surface, Polygon::new_unchecked(block.outline), first);
            }
        } else if v.len() == 4 {
            let len_u = v[0].distance(v[1]).max(v[3].distance(v[2]));
            let len_v = v[0].distance(v[3]).max(v[1].distance(v[2]));
            let (pu, ku) = split_count(len_u, size, sub);
            let (pv, kv) = split_count(len_v, size, sub);
            let fine = Lattice::Quad {
                corners: [v[0], v[1], v[2], v[3]],
                nu: pu * ku,
                nv: pv * kv,
            };
            for a in 0..pu {
                for b in 0..pv {
                    let first = self.elements.len() as u32;
                    let patch = PatchId(self.patches.len() as u32);
                    for i in a * ku..(a + 1) * ku {
                        for j in b * kv..(b + 1) * kv {
                            let corners = [
                                fine.point(i, j),
                                fine.point(i + 1, j),
                                fine.point(i + 1, j + 1),
                                fine.point(i, j + 1),
                            ];
                            self.push_element(surface, patch, &corners, &mut welder);
                        }
                    }
                    let polygon = Polygon::new_unchecked(vec![
                        fine.point(a * ku, b * kv),
                        fine.point((a + 1) * ku, b * kv),
                        fine.point((a + 1) * ku, (b + 1) * kv),
                        fine.point(a * ku, (b + 1) * kv),
                    ]);
                    self.push_patch(surface, polygon, first);
                }
            }
        } else {
            let (m, k) = split_count(triangle_level_length(polygon, size), size, sub);
            let coarse = Lattice::Triangle {
                corners: [DVec3::ZERO; 3],
                n: m,
            };
            for [a0, b0, c0] in polygon.triangles() {
                let fine = Lattice::Triangle {
                    corners: [a0, b0, c0],
                    n: m * k,
                };
                // Patch triangles at level m, each divided into k² elements.
                for patch_cell in coarse.cells() {
                    let [pa, pb, pc] = [patch_cell[0], patch_cell[1], patch_cell[2]];
                    let first = self.elements.len() as u32;
                    let patch = PatchId(self.patches.len() as u32);
                    // Point (a, b) of the patch's own k-lattice, in fine-lattice indices.
                    let lat = |a: u32, b: u32| {
                        let at = |p: u32, q: u32, r: u32| {
                            (p * k) as i64
                                + a as i64 * (q as i64 - p as i64)
                                + b as i64 * (r as i64 - p as i64)
                        };
                        fine.point(at(pa.0, pb.0, pc.0) as u32, at(pa.1, pb.1, pc.1) as u32)
                    };
                    let local = Lattice::Triangle {
                        corners: [DVec3::ZERO; 3],
                        n: k,
                    };
                    for cell in local.cells() {
                        let tri: Vec<DVec3> = cell.iter().map(|&(a, b)| lat(a, b)).collect();
                        self.push_element(surface, patch, &tri, &mut welder);
                    }
                    let polygon = Polygon::new_unchecked(vec![
                        fine.point(pa.0 * k, pa.1 * k),
                        fine.point(pb.0 * k, pb.1 * k),
                        fine.point(pc.0 * k, pc.1 * k),
                    ]);
                    self.push_patch(surface, polygon, first);
                }
            }
        }
    }

    fn push_element(
        &mut self,
        surface: SurfaceId,
        patch: PatchId,
        corners: &[DVec3],
        welder: &mut Welder,
    ) {
        let polygon = Polygon::new_unchecked(corners.to_vec());
        let ids = corners
            .iter()
            .map(|p| welder.index(*p, &mut self.vertices))
            .collect();
        self.elements.push(Element {
            surface: surface.0,
            patch,
            corners: ids,
            centre: polygon.centroid(),
            normal: polygon.normal(),
            area: polygon.area(),
            parent: None,
            depth: 0,
        });
    }

    /// Adds the back-to-back twin of surface `front`, whose vertices, elements and patches
    /// start at the given indices and run to the end of the mesh: the same geometry with the
    /// corners reversed, its own copies of the vertices, emitting `exitance` (W·m⁻²).
    fn push_twin(
        &mut self,
        front: SurfaceId,
        first_vertex: usize,
        first_element: usize,
        first_patch: usize,
        exitance: [f64; 3],
    ) {
        let twin = SurfaceId(self.surfaces.len() as u32);
        self.twin.resize(twin.0 as usize + 1, None);
        self.twin[front.0 as usize] = Some(twin.0);
        self.twin[twin.0 as usize] = Some(front.0);
        let data = SurfaceData {
            exitance,
            ..self.surfaces[front.0 as usize].clone()
        };
        self.surfaces.push(data);
        let reversed = |p: &Polygon| {
            let mut v = p.vertices().to_vec();
            v.reverse();
            Polygon::new_unchecked(v)
        };
        let outline = reversed(&self.surface_polygons[front.0 as usize]);
        self.surface_polygons.push(outline);
        let (end_vertex, end_element, end_patch) =
            (self.vertices.len(), self.elements.len(), self.patches.len());
        let vertex_shift = (end_vertex - first_vertex) as u32;
        let patch_shift = (end_patch - first_patch) as u32;
        let element_shift = (end_element - first_element) as u32;
        self.vertices.extend_from_within(first_vertex..end_vertex);
        for e in first_element..end_element {
            let front_element = &self.elements[e];
            // Keep the first corner, reverse the rest: same cell, opposite winding.
            let mut corners: Vec<u32> = front_element
                .corners
                .iter()
                .map(|c| c + vertex_shift)
                .collect();
            corners[1..].reverse();
            let element = Element {
                surface: twin.0,
                patch: PatchId(front_element.patch.0 + patch_shift),
                corners,
                centre: front_element.centre,
                normal: -front_element.normal,
                area: front_element.area,
                parent: None,
                depth: 0,
            };
            self.elements.push(element);
        }
        for p in first_patch..end_patch {
            let patch = &self.patches[p];
            let twin_patch = Patch {
                surface: twin.0,
                polygon: reversed(&patch.polygon),
                elements: patch.elements.start + element_shift..patch.elements.end + element_shift,
            };
            self.patches.push(twin_patch);
        }
    }

    /// Whether surfaces `a` and `b` are one sheet: the same surface, or the two sides of a
    /// two-sided one. They exchange no light (the form factor between the two sides of one
    /// plane is zero; computed from element centres that round off the plane it could be
    /// anything, even NaN), so form-factor engines skip such pairs.
    pub fn same_sheet(&self, a: u32, b: u32) -> bool {
        a == b || self.twin.get(a as usize).copied().flatten() == Some(b)
    }

    fn push_patch(&mut self, surface: SurfaceId, polygon: Polygon, first: u32) {
        self.patches.push(Patch {
            surface: surface.0,
            polygon,
            elements: first..self.elements.len() as u32,
        });
    }
}

/// Splits a length into `patches × per_patch` pieces no longer than `size`.
fn split_count(length: f64, size: f64, sub: u32) -> (u32, u32) {
    let elements = ((length / size).ceil() as u32).max(1);
    let patches = elements.div_ceil(sub).max(1);
    let per_patch = elements.div_ceil(patches).max(1);
    (patches, per_patch)
}

/// The length a triangle (or every fan triangle of an n-gon) is divided by: its longest
/// edge, except that a sliver (a long edge, little area) is divided by its area instead —
/// at most 8·√(2A), which only polygons thinner than about 1 : 32 reach (a right
/// isosceles triangle has 8a against its √2·a) — so that it cannot take more than its share
/// of an element budget (elements per edge grow with length, elements with its square).
fn triangle_level_length(polygon: &Polygon, size: f64) -> f64 {
    let longest = polygon
        .triangles()
        .flat_map(|t| {
            [
                t[0].distance(t[1]),
                t[1].distance(t[2]),
                t[2].distance(t[0]),
            ]
        })
        .fold(0.0, f64::max);
    let by_area = 8.0 * (2.0 * polygon.area()).sqrt();
    longest.min(by_area.max(size))
}

fn estimate_elements(polygon: &Polygon, size: f64) -> f64 {
    let v = polygon.vertices();
    if grid::uses_grid(polygon) {
        return grid::grid_count(polygon, size, 1);
    }
    if v.len() == 4 {
        let lu = v[0].distance(v[1]).max(v[3].distance(v[2]));
        let lv = v[0].distance(v[3]).max(v[1].distance(v[2]));
        return ((lu / size).ceil() + 1.0) * ((lv / size).ceil() + 1.0);
    }
    let h = triangle_level_length(polygon, size) / size;
    (h.ceil() + 1.0).powi(2) * (v.len() - 2) as f64
}

/// Element edge length giving about `count` elements over the scene's total area.
fn size_for_count(polygons: &[&Polygon], count: usize) -> f64 {
    // Square elements of side h cover the area with A/h² elements, but every polygon rounds
    // its element counts up; a few bisection steps on the real count correct for that.
    let area: f64 = polygons.iter().map(|p| p.area()).sum();
    let count_for = |h: f64| -> f64 {
        polygons
            .iter()
            .map(|p| {
                let v = p.vertices();
                if grid::uses_grid(p) {
                    grid::grid_count(p, h, 1)
                } else if v.len() == 4 {
                    let lu = v[0].distance(v[1]).max(v[3].distance(v[2]));
                    let lv = v[0].distance(v[3]).max(v[1].distance(v[2]));
                    ((lu / h).ceil().max(1.0)) * ((lv / h).ceil().max(1.0))
                } else {
                    // The polygon's own longest edge (not the fan's diagonals): an estimate
                    // that the meshes of the test scenes and benchmarks were tuned with.
                    let l = p.max_edge().min((8.0 * (2.0 * p.area()).sqrt()).max(h));
                    (l / h).ceil().max(1.0).powi(2) * (v.len() - 2) as f64
                }
            })
            .sum()
    };
    let mut lo = (area / count as f64).sqrt() * 0.2;
    let mut hi = (area / count as f64).sqrt() * 5.0;
    for _ in 0..40 {
        let mid = (lo * hi).sqrt();
        if count_for(mid) > count as f64 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    hi
}

/// The number of elements [`Mesh::mesh_surface`] makes of `polygons` at element size
/// `size` with `sub` elements per patch edge (estimated, [`grid::grid_count`], for polygons
/// of many vertices).
fn exact_count(polygons: &[&Polygon], size: f64, sub: u32) -> f64 {
    let pieces = |length: f64| {
        let (patches, per_patch) = split_count(length, size, sub);
        f64::from(patches) * f64::from(per_patch)
    };
    polygons
        .iter()
        .map(|p| {
            let v = p.vertices();
            if grid::uses_grid(p) {
                grid::grid_count(p, size, sub)
            } else if v.len() == 4 {
                let lu = v[0].distance(v[1]).max(v[3].distance(v[2]));
                let lv = v[0].distance(v[3]).max(v[1].distance(v[2]));
                pieces(lu) * pieces(lv)
            } else {
                pieces(triangle_level_length(p, size)).powi(2) * (v.len() - 2) as f64
            }
        })
        .sum()
}

/// `size`, grown until the mesh has at most twice `count` elements.
///
/// [`size_for_count`] estimates from each polygon's own edges; a polygon whose fan
/// triangles are slivers (one mistyped vertex makes a 400 m spike on a 1 m floor) is
/// divided along its longest edge on both lattice directions, so the real count can be
/// hundreds of times the budget. The guard only acts then (twice the budget leaves the
/// estimate's ordinary rounding alone), so ordinary meshes do not change; it grows the
/// size by 5 % steps (the count falls as 1/size², about 10 % a step) until the count is
/// within the budget itself.
fn within_budget(polygons: &[&Polygon], size: f64, sub: u32, count: usize) -> f64 {
    let budget = count as f64;
    if exact_count(polygons, size, sub) <= 2.0 * budget {
        return size;
    }
    let mut size = size;
    // 1.05^1500 ≈ 10³¹: far beyond any scene's extent over its smallest element.
    for _ in 0..1500 {
        size *= 1.05;
        if exact_count(polygons, size, sub) <= budget {
            break;
        }
    }
    size
}

/// Shares vertices that are bit-identical within one surface.
#[derive(Default)]
struct Welder {
    map: HashMap<[u64; 3], u32>,
}

impl Welder {
    fn index(&mut self, p: DVec3, vertices: &mut Vec<DVec3>) -> u32 {
        let key = [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()];
        *self.map.entry(key).or_insert_with(|| {
            vertices.push(p);
            (vertices.len() - 1) as u32
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{Material, MaterialId, Origin, Surface};

    fn scene_with(polys: Vec<Vec<DVec3>>) -> Scene {
        Scene {
            name: "t".into(),
            materials: vec![Material::new("m", [0.5; 3], [0.0; 3])],
            surfaces: polys
                .into_iter()
                .enumerate()
                .map(|(i, v)| Surface {
                    object: format!("o{i}"),
                    group: String::new(),
                    material: MaterialId(0),
                    polygon: Polygon::new(v).unwrap(),
                    origin: Origin::default(),
                })
                .collect(),
            lights: Vec::new(),
            camera: None,
        }
    }

    #[test]
    fn quad_mesh_conserves_area_and_shares_vertices() {
        let s = scene_with(vec![vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(2.0, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
        ]]);
        let opts = MeshOptions {
            max_element_size: Some(0.25),
            elements: 0,
            patch_subdivision: 2,
        };
        let m = Mesh::build(&s, &opts).unwrap();
        assert_eq!(m.elements.len(), 8 * 4);
        assert_eq!(m.vertices.len(), 9 * 5);
        assert_eq!(m.patches.len(), 4 * 2);
        let area: f64 = m.elements.iter().map(|e| e.area).sum();
        assert!((area - 2.0).abs() < 1e-12);
        for p in &m.patches {
            assert!((m.patch_area(p) - p.polygon.area()).abs() < 1e-12);
        }
    }

    #[test]
    fn triangle_and_pentagon_meshes_conform() {
        let s = scene_with(vec![
            vec![DVec3::ZERO, DVec3::X, DVec3::Y],
            vec![
                DVec3::new(0.0, 0.0, 1.0),
                DVec3::new(1.0, 0.0, 1.0),
                DVec3::new(1.5, 0.8, 1.0),
                DVec3::new(0.5, 1.5, 1.0),
                DVec3::new(-0.5, 0.8, 1.0),
            ],
        ]);
        let opts = MeshOptions {
            max_element_size: Some(0.1),
            elements: 0,
            patch_subdivision: 3,
        };
        let m = Mesh::build(&s, &opts).unwrap();
        for (i, surf) in s.surfaces.iter().enumerate() {
            let area: f64 = m
                .elements
                .iter()
                .filter(|e| e.surface == i as u32)
                .map(|e| e.area)
                .sum();
            assert!((area - surf.polygon.area()).abs() < 1e-12);
        }
        // Euler characteristic of a conforming triangulated disc: V - E + F = 1.
        for i in 0..2u32 {
            let els: Vec<_> = m.elements.iter().filter(|e| e.surface == i).collect();
            let mut verts = std::collections::HashSet::new();
            let mut edges = std::collections::HashSet::new();
            for e in &els {
                for k in 0..e.corners.len() {
                    let (a, b) = (e.corners[k], e.corners[(k + 1) % e.corners.len()]);
                    verts.insert(a);
                    edges.insert((a.min(b), a.max(b)));
                }
            }
            let chi = verts.len() as i64 - edges.len() as i64 + els.len() as i64;
            assert_eq!(chi, 1, "surface {i} mesh has cracks");
        }
    }

    #[test]
    fn element_count_target_is_close() {
        let s = scene_with(vec![vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
        ]]);
        let opts = MeshOptions {
            max_element_size: None,
            elements: 400,
            patch_subdivision: 1,
        };
        let m = Mesh::build(&s, &opts).unwrap();
        assert!((m.elements.len() as f64 - 400.0).abs() <= 40.0);
    }

    #[test]
    fn a_sliver_cannot_defeat_the_element_budget() {
        // One mistyped vertex (y = 400 for 0.4) turned a floor into a 400 m spike: its fan
        // triangles are slivers, which used to get 24,337 elements for a budget of 200.
        let s = scene_with(vec![
            vec![
                DVec3::new(0.0, 0.0, 0.0),
                DVec3::new(1.0, 0.0, 0.0),
                DVec3::new(0.2, 400.0, 0.0),
            ],
            vec![
                DVec3::new(0.0, 0.0, 1.0),
                DVec3::new(0.0, 1.0, 1.0),
                DVec3::new(1.0, 1.0, 1.0),
                DVec3::new(1.0, 0.0, 1.0),
            ],
        ]);
        for sub in [1, 3] {
            let opts = MeshOptions {
                max_element_size: None,
                elements: 200,
                patch_subdivision: sub,
            };
            let m = Mesh::build(&s, &opts).unwrap();
            // The guard lets ordinary rounding through up to twice the budget.
            assert!(m.elements.len() <= 400, "{} elements", m.elements.len());
            assert_eq!(
                m.elements.len() as f64,
                exact_count(
                    &[&s.surfaces[0].polygon, &s.surfaces[1].polygon],
                    within_budget(
                        &[&s.surfaces[0].polygon, &s.surfaces[1].polygon],
                        size_for_count(&[&s.surfaces[0].polygon, &s.surfaces[1].polygon], 200),
                        sub,
                        200
                    ),
                    sub
                )
            );
        }
    }

    #[test]
    fn absurd_sizes_are_errors() {
        let s = scene_with(vec![vec![DVec3::ZERO, DVec3::X, DVec3::Y]]);
        let mut o = MeshOptions {
            max_element_size: Some(1e-9),
            ..Default::default()
        };
        assert!(matches!(
            Mesh::build(&s, &o),
            Err(MeshError::TooManyElements { .. })
        ));
        o.max_element_size = Some(f64::NAN);
        assert!(matches!(
            Mesh::build(&s, &o),
            Err(MeshError::BadElementSize(_))
        ));
        o.max_element_size = Some(-1.0);
        assert!(matches!(
            Mesh::build(&s, &o),
            Err(MeshError::BadElementSize(_))
        ));
    }
}
