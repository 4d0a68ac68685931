//! The display mesh: shaded triangles for the rasteriser, from elements and their radiosity.
//!
//! Pixel values are radiance L = B/π (W·m⁻²·sr⁻¹) for Lambertian surfaces.
//! - Flat shading: each element shows its own radiosity.
//! - Smooth (Gouraud) shading: each vertex gets the area-weighted mean radiosity of the
//!   elements of the same surface that share it, interpolated across each element.
//!
//! Crack-free: a vertex of any element that lies on another element's edge (a T-junction,
//! e.g. where the light meets the ceiling, or after adaptive refinement) is inserted into that
//! edge, and the element is fanned from its centre, so no gap can open along the edge. The
//! inserted vertex takes the value interpolated along the edge, so shading stays continuous.
//! Surfaces are one-sided: seen from behind they are black, except for the two sides of a
//! two-sided surface, where the side facing the viewer shows ([`back_to_back`]).

use crate::mesh::Element;
use crate::render::ShadedTriangle;
use glam::DVec3;
use std::collections::HashMap;
use std::f64::consts::PI;

/// Shading mode.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Shading {
    /// Each element in its own radiosity.
    Flat,
    #[default]
    /// Gouraud: vertex values interpolated across each element.
    Smooth,
}

/// Hanging vertices on each element edge: `edges[e][k]` lists (t, vertex) along edge k of
/// element e, sorted by t ∈ (0, 1).
pub struct Conformity {
    edges: Vec<Vec<Vec<(f64, u32)>>>,
}

impl Conformity {
    /// Finds every vertex lying strictly inside an element edge (spatial hash, tolerance
    /// 1e-7 of the edge length).
    pub fn find(vertices: &[DVec3], elements: &[Element]) -> Self {
        // Cell size from the mean edge length.
        let mut total = 0.0;
        let mut count = 0usize;
        for e in elements {
            for k in 0..e.corners.len() {
                let a = vertices[e.corners[k] as usize];
                let b = vertices[e.corners[(k + 1) % e.corners.len()] as usize];
                total += a.distance(b);
                count += 1;
            }
        }
        let cell = (total / count.max(1) as f64).max(1e-12);
        let key = |p: DVec3| -> (i64, i64, i64) {
            let q = (p / cell).floor();
            (q.x as i64, q.y as i64, q.z as i64)
        };
        let mut grid: HashMap<(i64, i64, i64), Vec<u32>> = HashMap::new();
        for (i, v) in vertices.iter().enumerate() {
            grid.entry(key(*v)).or_default().push(i as u32);
        }
        let edges = elements
            .iter()
            .map(|e| {
                (0..e.corners.len())
                    .map(|k| {
                        let (ia, ib) = (e.corners[k], e.corners[(k + 1) % e.corners.len()]);
                        let (a, b) = (vertices[ia as usize], vertices[ib as usize]);
                        let d = b - a;
                        let len2 = d.length_squared();
                        let tol = 1e-7 * len2.sqrt();
                        let (lo, hi) = (
                            key(a.min(b) - DVec3::splat(tol)),
                            key(a.max(b) + DVec3::splat(tol)),
                        );
                        let mut found = Vec::new();
                        if (hi.0 - lo.0 + 1) * (hi.1 - lo.1 + 1) * (hi.2 - lo.2 + 1) > 4096 {
                            return found; // a huge edge: skip the search rather than stall
                        }
                        for x in lo.0..=hi.0 {
                            for y in lo.1..=hi.1 {
                                for z in lo.2..=hi.2 {
                                    for &v in grid.get(&(x, y, z)).into_iter().flatten() {
                                        if v == ia || v == ib {
                                            continue;
                                        }
                                        let p = vertices[v as usize];
                                        let t = (p - a).dot(d) / len2;
                                        if t <= 1e-9 || t >= 1.0 - 1e-9 {
                                            continue;
                                        }
                                        if (a + d * t).distance(p) <= tol {
                                            found.push((t, v));
                                        }
                                    }
                                }
                            }
                        }
                        found.sort_by(|x, y| x.0.total_cmp(&y.0));
                        found.dedup_by(|x, y| (x.0 - y.0).abs() < 1e-12);
                        found
                    })
                    .collect()
            })
            .collect();
        Self { edges }
    }

    /// The hanging vertices lying on the edges of element `element`.
    pub fn hanging_on(&self, element: usize) -> impl Iterator<Item = u32> + '_ {
        self.edges[element].iter().flatten().map(|&(_, v)| v)
    }

    /// Number of hanging vertices found.
    pub fn hanging_count(&self) -> usize {
        self.edges.iter().flatten().map(Vec::len).sum()
    }
}

/// The crack-free display mesh with a radiosity at every vertex: the one place per-vertex
/// radiosity is computed, for the rasteriser, the exporters and the viewer alike.
///
/// Every element becomes triangles: itself if it is a triangle without hanging vertices,
/// else a fan from its centre over its boundary with the hanging vertices inserted. Vertex
/// values (W·m⁻²): with smooth shading, the area-weighted mean of the same surface's elements
/// sharing the vertex, hanging vertices constrained to their edge's interpolation; fan
/// centres the mean of the element's corners (the bilinear centre value). With flat shading
/// every element has its own vertices carrying its own radiosity. Vertices are shared between
/// the triangles of one surface (smooth) or one element (flat), never across surfaces.
#[derive(Debug, Clone, Default)]
pub struct DisplayMesh {
    /// Vertex positions, m.
    pub positions: Vec<DVec3>,
    /// Triangles as vertex indices, counter-clockwise seen from the front.
    pub triangles: Vec<[u32; 3]>,
    /// The element each triangle belongs to.
    pub triangle_element: Vec<u32>,
    /// Radiosity at each vertex, W·m⁻².
    pub vertex_radiosity: Vec<[f64; 3]>,
}

impl DisplayMesh {
    /// Builds the display mesh of `elements` (over `vertices`) with element radiosities
    /// `radiosity` (W·m⁻²).
    pub fn build(
        vertices: &[DVec3],
        elements: &[Element],
        radiosity: &[[f64; 3]],
        shading: Shading,
    ) -> Self {
        let conformity = Conformity::find(vertices, elements);
        Self::with_conformity(vertices, elements, radiosity, shading, &conformity)
    }

    /// As [`DisplayMesh::build`], with the hanging vertices already found.
    pub fn with_conformity(
        vertices: &[DVec3],
        elements: &[Element],
        radiosity: &[[f64; 3]],
        shading: Shading,
        conformity: &Conformity,
    ) -> Self {
        // Vertex radiosity: area-weighted mean over adjacent elements (vertices are shared
        // only within one surface, so this never blends across surfaces).
        let mut vertex_b = vec![[0.0f64; 3]; vertices.len()];
        if shading == Shading::Smooth {
            let mut weight = vec![0.0f64; vertices.len()];
            for (e, b) in elements.iter().zip(radiosity) {
                for &c in &e.corners {
                    for ch in 0..3 {
                        vertex_b[c as usize][ch] += e.area * b[ch];
                    }
                    weight[c as usize] += e.area;
                }
            }
            for (v, w) in vertex_b.iter_mut().zip(&weight) {
                if *w > 0.0 {
                    v.iter_mut().for_each(|x| *x /= w);
                }
            }
            constrain_hanging(vertices, elements, conformity, &mut vertex_b);
        }
        let mut out = DisplayMesh::default();
        // Display vertex of (mesh vertex, surface) for smooth shading.
        let mut shared: HashMap<(u32, u32), u32> = HashMap::new();
        let push = |out: &mut DisplayMesh, p: DVec3, b: [f64; 3]| -> u32 {
            out.positions.push(p);
            out.vertex_radiosity.push(b);
            (out.positions.len() - 1) as u32
        };
        for (i, (e, b)) in elements.iter().zip(radiosity).enumerate() {
            let corner_value = |c: u32| -> [f64; 3] {
                if shading == Shading::Smooth {
                    vertex_b[c as usize]
                } else {
                    *b
                }
            };
            // Boundary loop with hanging vertices inserted (values interpolated).
            let n = e.corners.len();
            let mut loop_ids: Vec<u32> = Vec::with_capacity(n * 2);
            for k in 0..n {
                let (ca, cb) = (e.corners[k], e.corners[(k + 1) % n]);
                let (va, vb) = (corner_value(ca), corner_value(cb));
                let mut vertex = |out: &mut DisplayMesh, v: u32, value: [f64; 3]| -> u32 {
                    if shading == Shading::Smooth {
                        *shared
                            .entry((v, e.surface))
                            .or_insert_with(|| push(out, vertices[v as usize], value))
                    } else {
                        push(out, vertices[v as usize], value)
                    }
                };
                loop_ids.push(vertex(&mut out, ca, va));
                for &(t, v) in &conformity.edges[i][k] {
                    let val = std::array::from_fn(|ch| va[ch] * (1.0 - t) + vb[ch] * t);
                    loop_ids.push(vertex(&mut out, v, val));
                }
            }
            if loop_ids.len() == 3 {
                out.triangles.push([loop_ids[0], loop_ids[1], loop_ids[2]]);
                out.triangle_element.push(i as u32);
                continue;
            }
            // Fan from the centre; its value is the mean of the corners (bilinear centre value).
            let mut centre_value = [0.0; 3];
            for &c in &e.corners {
                let v = corner_value(c);
                for ch in 0..3 {
                    centre_value[ch] += v[ch] / n as f64;
                }
            }
            let centre = e
                .corners
                .iter()
                .map(|&c| vertices[c as usize])
                .sum::<DVec3>()
                / n as f64;
            let c = push(&mut out, centre, centre_value);
            for k in 0..loop_ids.len() {
                out.triangles
                    .push([c, loop_ids[k], loop_ids[(k + 1) % loop_ids.len()]]);
                out.triangle_element.push(i as u32);
            }
        }
        out
    }

    /// The triangles for a camera at `eye`, as radiance L = B/π (W·m⁻²·sr⁻¹): surfaces seen
    /// from behind are black, except that the back of a two-sided surface (one with a twin
    /// facing the other way, `culled_from_behind[element]`) is left out so its twin shows.
    pub fn shaded_triangles(
        &self,
        elements: &[Element],
        culled_from_behind: &dyn Fn(usize) -> bool,
        eye: DVec3,
    ) -> Vec<ShadedTriangle> {
        let to_radiance = |b: [f64; 3]| b.map(|x| (x / PI) as f32);
        let mut out = Vec::with_capacity(self.triangles.len());
        for (t, &e) in self.triangles.iter().zip(&self.triangle_element) {
            let el = &elements[e as usize];
            let front = (eye - el.centre).dot(el.normal) > 0.0;
            if !front && culled_from_behind(e as usize) {
                continue;
            }
            let value = |v: u32| {
                if front {
                    to_radiance(self.vertex_radiosity[v as usize])
                } else {
                    [0.0; 3]
                }
            };
            out.push(ShadedTriangle {
                positions: t.map(|v| self.positions[v as usize]),
                radiance: t.map(value),
            });
        }
        out
    }
}

/// Which elements have a back-to-back twin: another element at the same place (centres
/// within 10⁻⁹ of the scene's size) facing the opposite way, as meshing makes for two-sided
/// surfaces (see [`crate::mesh`]), or, where the two sides are meshed apart (the hierarchical
/// solver refines each side as its light asks), an element facing the opposite way in the
/// same plane that covers its centre. Seen from behind, such an element is left out of the
/// image so that the side facing the viewer shows ([`DisplayMesh::shaded_triangles`]).
pub fn back_to_back(vertices: &[DVec3], elements: &[Element]) -> Vec<bool> {
    let mut out = coincident_twins(elements);
    if out.iter().all(|&t| t) {
        return out;
    }
    covered_from_behind(vertices, elements, &mut out);
    out
}

/// Marks the elements whose centre lies on an element facing the opposite way in the same
/// plane (within 10⁻⁹ of the scene's size), through a grid of cells the size of the median
/// element: each element is listed in the cells its bounding box meets (elements spanning
/// more than 16 cells a side are checked for every element instead).
fn covered_from_behind(vertices: &[DVec3], elements: &[Element], out: &mut [bool]) {
    let (lo, hi) = vertices.iter().fold(
        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(lo, hi), v| (lo.min(*v), hi.max(*v)),
    );
    let tol = 1e-9 * (hi - lo).length().max(1e-9);
    // Only elements whose plane also holds elements facing the other way can be covered:
    // planes keyed by the normal up to its sign (components to 10⁻³) and the offset (to 10³
    // tolerances), each side counted. Most scenes have no such plane, and stop here.
    let plane = |e: &Element| {
        let n = e.normal;
        let first = [n.x, n.y, n.z]
            .into_iter()
            .find(|c| c.abs() > 1e-3)
            .unwrap_or(1.0);
        let (n, side) = if first > 0.0 { (n, 0) } else { (-n, 1) };
        let key = (
            (n.x * 1e3).round() as i64,
            (n.y * 1e3).round() as i64,
            (n.z * 1e3).round() as i64,
            (n.dot(e.centre) / (1e3 * tol)).round() as i64,
        );
        (key, side)
    };
    let mut sides: HashMap<(i64, i64, i64, i64), [bool; 2]> = HashMap::new();
    for e in elements {
        let (key, side) = plane(e);
        sides.entry(key).or_default()[side] = true;
    }
    let candidates: Vec<usize> = (0..elements.len())
        .filter(|&i| sides[&plane(&elements[i]).0] == [true, true])
        .collect();
    if candidates.is_empty() {
        return;
    }
    let mut areas: Vec<f64> = candidates.iter().map(|&i| elements[i].area).collect();
    areas.sort_unstable_by(f64::total_cmp);
    let cell = areas[areas.len() / 2].sqrt().max(1e3 * tol);
    let index = |p: DVec3| ((p - lo) / cell).floor().as_ivec3();
    let mut grid: HashMap<glam::IVec3, Vec<u32>> = HashMap::new();
    let mut large: Vec<u32> = Vec::new();
    for &j in &candidates {
        let e = &elements[j];
        let (a, b) = e.corners.iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(a, b), &v| (a.min(vertices[v as usize]), b.max(vertices[v as usize])),
        );
        let (a, b) = (index(a - tol), index(b + tol));
        if (b - a).max_element() > 16 {
            large.push(j as u32);
            continue;
        }
        for x in a.x..=b.x {
            for y in a.y..=b.y {
                for z in a.z..=b.z {
                    grid.entry(glam::IVec3::new(x, y, z))
                        .or_default()
                        .push(j as u32);
                }
            }
        }
    }
    let covers = |j: usize, e: &Element| {
        let f = &elements[j];
        if f.normal.dot(e.normal) >= -0.999_999 || f.normal.dot(e.centre - f.centre).abs() > tol {
            return false;
        }
        let n = f.corners.len();
        (0..n).all(|k| {
            let (p, q) = (
                vertices[f.corners[k] as usize],
                vertices[f.corners[(k + 1) % n] as usize],
            );
            (q - p).cross(e.centre - p).dot(f.normal) >= -tol * (q - p).length()
        })
    };
    for &i in &candidates {
        let e = &elements[i];
        if out[i] {
            continue;
        }
        let near = grid.get(&index(e.centre)).into_iter().flatten();
        out[i] = near
            .chain(&large)
            .any(|&j| j as usize != i && covers(j as usize, e));
    }
}

/// Elements with a back-to-back twin at the same place (see [`back_to_back`]).
fn coincident_twins(elements: &[Element]) -> Vec<bool> {
    let mut out = vec![false; elements.len()];
    if elements.is_empty() {
        return out;
    }
    let (lo, hi) = elements.iter().fold(
        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(lo, hi), e| (lo.min(e.centre), hi.max(e.centre)),
    );
    let tol = 1e-9 * (hi - lo).length().max(1e-9);
    // Cells much larger than the tolerance: a twin is in the same cell or a neighbour.
    let cell = 1e3 * tol;
    let key = |p: DVec3| {
        let q = ((p - lo) / cell).floor();
        (q.x as i64, q.y as i64, q.z as i64)
    };
    let mut grid: HashMap<(i64, i64, i64), Vec<u32>> = HashMap::new();
    for (i, e) in elements.iter().enumerate() {
        grid.entry(key(e.centre)).or_default().push(i as u32);
    }
    for (i, e) in elements.iter().enumerate() {
        let (x, y, z) = key(e.centre);
        'search: for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    for &j in grid.get(&(x + dx, y + dy, z + dz)).into_iter().flatten() {
                        let f = &elements[j as usize];
                        if j as usize != i
                            && f.normal.dot(e.normal) < -0.999_999
                            && f.centre.distance(e.centre) <= tol
                        {
                            out[i] = true;
                            break 'search;
                        }
                    }
                }
            }
        }
    }
    out
}

/// Builds the shaded triangles for a camera at `eye` (see [`DisplayMesh`]).
pub fn shaded_triangles(
    vertices: &[DVec3],
    elements: &[Element],
    radiosity: &[[f64; 3]],
    shading: Shading,
    conformity: &Conformity,
    eye: DVec3,
) -> Vec<ShadedTriangle> {
    DisplayMesh::with_conformity(vertices, elements, radiosity, shading, conformity)
        .shaded_triangles(elements, &|_| false, eye)
}

/// A hanging vertex of the same surface (left by adaptive refinement) takes the value
/// interpolated along the coarse edge it lies on, so both sides of the edge shade alike (no
/// seam). Longer edges first, so chains of hanging vertices resolve coarse to fine.
fn constrain_hanging(
    vertices: &[DVec3],
    elements: &[Element],
    conformity: &Conformity,
    vertex_b: &mut [[f64; 3]],
) {
    let mut surface_of = vec![u32::MAX; vertices.len()];
    for e in elements {
        for &c in &e.corners {
            surface_of[c as usize] = e.surface;
        }
    }
    let mut constraints: Vec<(f64, u32, u32, f64, u32)> = Vec::new();
    for (i, e) in elements.iter().enumerate() {
        let n = e.corners.len();
        for k in 0..n {
            let (a, b) = (e.corners[k], e.corners[(k + 1) % n]);
            for &(t, v) in &conformity.edges[i][k] {
                if surface_of[v as usize] == e.surface {
                    let len = vertices[a as usize].distance(vertices[b as usize]);
                    constraints.push((len, a, b, t, v));
                }
            }
        }
    }
    constraints.sort_by(|x, y| y.0.total_cmp(&x.0));
    for (_, a, b, t, v) in constraints {
        let (va, vb) = (vertex_b[a as usize], vertex_b[b as usize]);
        vertex_b[v as usize] = std::array::from_fn(|c| va[c] * (1.0 - t) + vb[c] * t);
    }
}

/// Element edges as line segments (for the wireframe overlay), each shared edge once.
pub fn element_edges(vertices: &[DVec3], elements: &[Element]) -> Vec<[DVec3; 2]> {
    let mut seen = std::collections::HashSet::new();
    let mut out = Vec::new();
    for e in elements {
        for k in 0..e.corners.len() {
            let (a, b) = (e.corners[k], e.corners[(k + 1) % e.corners.len()]);
            if seen.insert((a.min(b), a.max(b))) {
                out.push([vertices[a as usize], vertices[b as usize]]);
            }
        }
    }
    out
}
