//! Merging of coplanar neighbours: the input polygons of one object and material that share
//! edges and lie in one plane, and whose union is convex, become that one convex polygon.
//!
//! Real models tessellate flat walls and floors into thousands of triangles; the triangles
//! carry no information the radiosity solution needs (one material, one plane), but a
//! hierarchy built over them would start every link from thousands of pieces. Merged, a
//! wall of 2k² triangles is the wall again, and the hierarchy refines it where the light
//! asks, independently of how finely it was modelled (issue 8: "the hierarchy, not the
//! input, sets the cost"). Cost O(n log n) for n input polygons.
//!
//! A connected coplanar group is replaced only when its convex hull has its area (the
//! union is convex and the pieces do not overlap); a wall with a door hole, or an L-shaped
//! floor, keeps its pieces.

use crate::geometry::Polygon;
use crate::scene::{Scene, Surface};
use glam::{DVec2, DVec3};
use std::collections::HashMap;

/// Two unit normals count as parallel when their dot product exceeds this (0.0026°).
const PARALLEL: f64 = 1.0 - 1e-9;
/// Relative tolerance on plane distances (of the larger polygon's diameter).
const RELATIVE: f64 = 1e-9;
/// Relative tolerance of the hull-versus-union area test: rounding of the Newell areas is
/// about 1e-15; the smallest notch a real model has (a 1 mm step in a 10 m wall) is 1e-4.
const HULL_AREA: f64 = 1e-7;

/// The scene with coplanar neighbour groups merged, and for each of its surfaces the index
/// of the (first) original surface it came from.
pub fn merge_coplanar(scene: &Scene) -> (Scene, Vec<usize>) {
    let n = scene.surfaces.len();
    let mut parent: Vec<usize> = (0..n).collect();
    fn find(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    // Undirected edges by their endpoints' exact coordinates: shared vertices of a mesh are
    // bit-identical (indexed formats, lattices computed from the same indices).
    let key = |v: DVec3| [v.x.to_bits(), v.y.to_bits(), v.z.to_bits()];
    let mut edges: HashMap<([u64; 3], [u64; 3]), usize> = HashMap::with_capacity(3 * n);
    for (i, s) in scene.surfaces.iter().enumerate() {
        for (a, b) in s.polygon.edges() {
            let (ka, kb) = (key(a), key(b));
            let k = if ka <= kb { (ka, kb) } else { (kb, ka) };
            match edges.entry(k) {
                std::collections::hash_map::Entry::Vacant(e) => {
                    e.insert(i);
                }
                std::collections::hash_map::Entry::Occupied(e) => {
                    let j = *e.get();
                    if mergeable(&scene.surfaces[i], &scene.surfaces[j]) {
                        let (ri, rj) = (find(&mut parent, i), find(&mut parent, j));
                        if ri != rj {
                            parent[ri.max(rj)] = ri.min(rj);
                        }
                    }
                }
            }
        }
    }
    let mut groups: HashMap<usize, Vec<usize>> = HashMap::new();
    for i in 0..n {
        let r = find(&mut parent, i);
        groups.entry(r).or_default().push(i);
    }
    // Each group at the place of its first member, so scene order is kept.
    let mut merged_at: Vec<Option<Vec<usize>>> = vec![None; n];
    for (root, members) in groups {
        merged_at[root] = Some(members);
    }
    let mut surfaces = Vec::with_capacity(n);
    let mut origin = Vec::with_capacity(n);
    for (i, members) in merged_at.into_iter().enumerate() {
        let Some(members) = members else { continue };
        match (members.len() > 1)
            .then(|| convex_union(scene, &members))
            .flatten()
        {
            Some(polygon) => {
                surfaces.push(Surface {
                    polygon,
                    ..scene.surfaces[i].clone()
                });
                origin.push(i);
            }
            None => {
                for m in members {
                    surfaces.push(scene.surfaces[m].clone());
                    origin.push(m);
                }
            }
        }
    }
    // Groups were visited by root; keep the original order of the kept pieces too.
    let mut order: Vec<usize> = (0..surfaces.len()).collect();
    order.sort_by_key(|&k| origin[k]);
    let surfaces = order.iter().map(|&k| surfaces[k].clone()).collect();
    let origin = order.iter().map(|&k| origin[k]).collect();
    (
        Scene {
            surfaces,
            ..scene.clone()
        },
        origin,
    )
}

/// Whether two edge-sharing surfaces may merge: same object and material, same facing, one
/// plane.
fn mergeable(a: &Surface, b: &Surface) -> bool {
    if a.object != b.object || a.material != b.material {
        return false;
    }
    let (pa, pb) = (&a.polygon, &b.polygon);
    if pa.normal().dot(pb.normal()) < PARALLEL {
        return false;
    }
    let size = pa.diameter().max(pb.diameter());
    pb.vertices()
        .iter()
        .all(|v| pa.plane_distance(*v).abs() <= RELATIVE * size)
}

/// The members' union as one convex polygon, if it is one: the convex hull of their
/// vertices in the plane (Andrew's monotone chain, collinear points dropped), accepted when
/// its area equals the members' total area.
fn convex_union(scene: &Scene, members: &[usize]) -> Option<Polygon> {
    let first = &scene.surfaces[members[0]].polygon;
    let normal = first.normal();
    let origin = first.vertices()[0];
    let (u, v) = normal.any_orthonormal_pair();
    let mut points: Vec<(DVec2, DVec3)> = members
        .iter()
        .flat_map(|&m| scene.surfaces[m].polygon.vertices().iter().copied())
        .map(|p| {
            let d = p - origin;
            (DVec2::new(d.dot(u), d.dot(v)), p)
        })
        .collect();
    points.sort_by(|a, b| a.0.x.total_cmp(&b.0.x).then(a.0.y.total_cmp(&b.0.y)));
    points.dedup_by(|a, b| a.0 == b.0);
    if points.len() < 3 {
        return None;
    }
    let cross = |o: DVec2, a: DVec2, b: DVec2| (a - o).perp_dot(b - o);
    let mut hull: Vec<(DVec2, DVec3)> = Vec::with_capacity(points.len() + 1);
    for pass in 0..2 {
        let start = hull.len();
        let iter: Box<dyn Iterator<Item = &(DVec2, DVec3)>> = if pass == 0 {
            Box::new(points.iter())
        } else {
            Box::new(points.iter().rev())
        };
        for p in iter {
            // The exact hull of the points as they are (right turns and exact collinear
            // points dropped).
            while hull.len() >= start + 2 {
                let (o, a) = (hull[hull.len() - 2].0, hull[hull.len() - 1].0);
                if cross(o, a, p.0) <= 0.0 {
                    hull.pop();
                } else {
                    break;
                }
            }
            hull.push(*p);
        }
        hull.pop();
    }
    // Then the vertices that only rounding put off a straight edge (lattice points on the
    // outline): within 1e-9 of the span between their hull neighbours of the line through
    // them. On the hull, in order, a corner is never judged against points beyond it, and
    // a run of such points between two corners goes at once.
    let m = hull.len();
    let hull: Vec<(DVec2, DVec3)> = (0..m)
        .filter(|&k| {
            let (a, b, c) = (hull[(k + m - 1) % m].0, hull[k].0, hull[(k + 1) % m].0);
            let span = (c - a).length();
            cross(a, c, b).abs() > 1e-9 * span * span
        })
        .map(|k| hull[k])
        .collect();
    if hull.len() < 3 {
        return None;
    }
    // The chain turns counter-clockwise about u × v, which is ±n: face it like the members.
    let mut outline: Vec<DVec3> = hull.iter().map(|(_, p)| *p).collect();
    if u.cross(v).dot(normal) < 0.0 {
        outline.reverse();
    }
    // Start where the first member starts when that is a corner (a lattice's first cell
    // holds the original's first vertex): the merged outline then is the original polygon.
    let start = first.vertices()[0];
    if let Some(at) = outline.iter().position(|p| *p == start) {
        outline.rotate_left(at);
    }
    let polygon = Polygon::new(outline).ok()?;
    let total: f64 = members
        .iter()
        .map(|&m| scene.surfaces[m].polygon.area())
        .sum();
    let agrees = polygon.normal().dot(normal) > 0.0;
    ((polygon.area() - total).abs() <= HULL_AREA * total && agrees).then_some(polygon)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_tessellated_cornell_box_merges_back_into_its_polygons() {
        let plain = crate::cornell::cornell_box();
        let fine = crate::generate::tessellated(&plain, 7);
        let (merged, origin) = merge_coplanar(&fine);
        assert_eq!(merged.surfaces.len(), plain.surfaces.len());
        assert_eq!(origin.len(), merged.surfaces.len());
        for (m, p) in merged.surfaces.iter().zip(&plain.surfaces) {
            assert_eq!(m.object, p.object);
            // The lattice of a planar convex polygon tiles it exactly: areas agree to
            // rounding, and the outline has the original's corners (no lattice points left
            // on its edges).
            assert!((m.polygon.area() / p.polygon.area() - 1.0).abs() < 1e-9);
            assert_eq!(
                m.polygon.vertices().len(),
                p.polygon.vertices().len(),
                "{}",
                p.object
            );
            assert!(m.polygon.normal().dot(p.polygon.normal()) > 1.0 - 1e-12);
        }
    }

    #[test]
    fn non_convex_or_foreign_neighbours_stay_apart() {
        let p = |x: f64, z: f64| DVec3::new(x, 0.0, z);
        let quad = |x0: f64, z0: f64, x1: f64, z1: f64| {
            Polygon::new(vec![p(x0, z0), p(x0, z1), p(x1, z1), p(x1, z0)]).unwrap()
        };
        let surface = |object: &str, polygon: Polygon| Surface {
            object: object.into(),
            group: String::new(),
            material: crate::scene::MaterialId(0),
            polygon,
            origin: Default::default(),
        };
        // An L of three unit squares (not convex) and a square of another object beside it.
        let scene = Scene {
            materials: vec![crate::scene::Material::new("m", [0.5; 3], [0.0; 3])],
            surfaces: vec![
                surface("floor", quad(0., 0., 1., 1.)),
                surface("floor", quad(1., 0., 2., 1.)),
                surface("floor", quad(0., 1., 1., 2.)),
                surface("rug", quad(1., 1., 2., 2.)),
            ],
            ..Default::default()
        };
        let (merged, origin) = merge_coplanar(&scene);
        assert_eq!(merged.surfaces.len(), 4);
        assert_eq!(origin, [0, 1, 2, 3]);
        // Two squares of one object in a row do merge into the rectangle.
        let row = Scene {
            surfaces: scene.surfaces[..2].to_vec(),
            ..scene.clone()
        };
        let (merged, _) = merge_coplanar(&row);
        assert_eq!(merged.surfaces.len(), 1);
        assert_eq!(merged.surfaces[0].polygon.vertices().len(), 4);
        assert!((merged.surfaces[0].polygon.area() - 2.0).abs() < 1e-12);
    }
}
