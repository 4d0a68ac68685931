//! Procedural scenes of any size, for scaling studies and tests: the Cornell box with every
//! polygon tessellated into many small ones (the same box, so the same answer, from
//! k² times the input), the Cornell box with two finely tessellated spheres (curved
//! surfaces, whose triangles do not merge back into polygons), and a closed room furnished
//! with N boxes and shelves at random (fixed seed), lit by a grid of ceiling panels.

use crate::geometry::Polygon;
use crate::scene::{Material, MaterialId, Origin, Scene, Surface};
use glam::DVec3;
use rand::{RngExt, SeedableRng};

/// `scene` with every quadrilateral cut into a k × k bilinear grid of triangle pairs and
/// every triangle into k² triangles (midpoint lattice); other polygons are kept whole.
/// Object names, materials, lights and camera are kept, so per-object results compare with
/// the untessellated scene's. The Cornell box (18 quads, 2 triangles) gives 38 k² triangles:
/// k = 162 gives 997,272.
pub fn tessellated(scene: &Scene, k: usize) -> Scene {
    let k = k.max(1);
    let mut surfaces = Vec::with_capacity(scene.surfaces.len() * 2 * k * k);
    let push = |surfaces: &mut Vec<Surface>, s: &Surface, tri: [DVec3; 3]| {
        // A lattice of a valid polygon has no degenerate cells.
        if let Ok(polygon) = Polygon::new(tri.to_vec()) {
            surfaces.push(Surface {
                polygon,
                ..s.clone()
            });
        }
    };
    for s in &scene.surfaces {
        let v = s.polygon.vertices();
        match v.len() {
            4 => {
                let at = |i: usize, j: usize| -> DVec3 {
                    let (u, w) = (i as f64 / k as f64, j as f64 / k as f64);
                    v[0] * (1.0 - u) * (1.0 - w)
                        + v[1] * u * (1.0 - w)
                        + v[2] * u * w
                        + v[3] * (1.0 - u) * w
                };
                for i in 0..k {
                    for j in 0..k {
                        push(&mut surfaces, s, [at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
                        push(&mut surfaces, s, [at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
                    }
                }
            }
            3 => {
                // Barycentric lattice: point (i, j) = v0 + i/k (v1 − v0) + j/k (v2 − v0).
                let at = |i: usize, j: usize| -> DVec3 {
                    v[0] + (v[1] - v[0]) * (i as f64 / k as f64)
                        + (v[2] - v[0]) * (j as f64 / k as f64)
                };
                for i in 0..k {
                    for j in 0..k - i {
                        push(&mut surfaces, s, [at(i, j), at(i + 1, j), at(i, j + 1)]);
                        if i + j + 1 < k {
                            push(
                                &mut surfaces,
                                s,
                                [at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)],
                            );
                        }
                    }
                }
            }
            _ => surfaces.push(s.clone()),
        }
    }
    Scene {
        name: format!("{}_tessellated_{k}", scene.name),
        surfaces,
        ..scene.clone()
    }
}

/// Emitted radiance of the room's ceiling panels, W·m⁻²·sr⁻¹.
pub const ROOM_PANEL_RADIANCE: f64 = 20.0;
/// Spacing of the furniture grid (one object per cell), m.
const CELL: f64 = 2.0;
/// Spacing of the ceiling panels, m.
const PANEL_SPACING: f64 = 4.0;
/// Side of a ceiling panel, m.
const PANEL_SIDE: f64 = 0.6;
/// Room height, m.
const HEIGHT: f64 = 3.0;

/// A closed room furnished with `objects` pieces of furniture, placed at random with `seed`
/// (the same seed, the same room): one per cell of a 2 m grid over a square floor of about
/// 2√N m side, each jittered and turned about the vertical so that none overlaps its
/// neighbours; nine in ten are boxes (0.3–1.4 m wide, 0.2–2 m tall, five faces, standing
/// on the floor) and one in ten a shelf unit (two side panels and three planks, 28 faces).
/// Floor, walls and ceiling are single polygons facing in; square luminaires every 4 m: an
/// emitting panel (0.6 m, L = [`ROOM_PANEL_RADIANCE`] W·m⁻²·sr⁻¹) facing down 5 cm below
/// the ceiling, in a housing of four faces up to it, so the room is closed and no light
/// falls on a back face.
/// Every surface is a quad; the room has about 7.6 N quads (15 N triangles) plus the panels.
pub fn furnished_room(objects: usize, seed: u64) -> Scene {
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(seed);
    let per_side = ((objects as f64).sqrt().ceil() as usize).max(1);
    let side = per_side as f64 * CELL;
    let mut materials = vec![
        Material::new("floor", [0.45, 0.4, 0.35], [0.0; 3]),
        Material::new("wall", [0.75, 0.75, 0.7], [0.0; 3]),
        Material::new("ceiling", [0.8, 0.8, 0.8], [0.0; 3]),
        Material::new("panel", [0.0; 3], [ROOM_PANEL_RADIANCE; 3]),
    ];
    let finishes = [
        [0.6, 0.3, 0.2],
        [0.2, 0.4, 0.6],
        [0.7, 0.7, 0.6],
        [0.3, 0.5, 0.3],
        [0.5, 0.5, 0.5],
        [0.8, 0.6, 0.3],
    ];
    for (i, rho) in finishes.iter().enumerate() {
        materials.push(Material::new(format!("finish{i}"), *rho, [0.0; 3]));
    }
    let mut surfaces = Vec::new();
    let mut add = |object: &str, material: u32, corners: [DVec3; 4]| {
        // Every quad built here has positive extent; a degenerate one would be a bug in
        // the generator, skipped rather than aborting a benchmark.
        if let Ok(polygon) = Polygon::new(corners.to_vec()) {
            surfaces.push(Surface {
                object: object.to_owned(),
                group: String::new(),
                material: MaterialId(material),
                polygon,
                origin: Origin::default(),
            });
        }
    };
    let p = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
    let (s, h) = (side, HEIGHT);
    // Shell, facing in (counter-clockwise seen from inside).
    add(
        "floor",
        0,
        [p(0., 0., 0.), p(0., 0., s), p(s, 0., s), p(s, 0., 0.)],
    );
    add(
        "ceiling",
        2,
        [p(0., h, 0.), p(s, h, 0.), p(s, h, s), p(0., h, s)],
    );
    add(
        "wall_south",
        1,
        [p(0., 0., 0.), p(s, 0., 0.), p(s, h, 0.), p(0., h, 0.)],
    );
    add(
        "wall_north",
        1,
        [p(0., 0., s), p(0., h, s), p(s, h, s), p(s, 0., s)],
    );
    add(
        "wall_west",
        1,
        [p(0., 0., 0.), p(0., h, 0.), p(0., h, s), p(0., 0., s)],
    );
    add(
        "wall_east",
        1,
        [p(s, 0., 0.), p(s, 0., s), p(s, h, s), p(s, h, 0.)],
    );
    // Ceiling luminaires: an emitting panel facing down, 5 cm below the ceiling, in a
    // housing of four side faces up to the ceiling (no light is lost on the panel's back).
    let panels = ((side / PANEL_SPACING).round() as usize).max(1);
    let pitch = side / panels as f64;
    let drop = 0.05;
    let a = 0.5 * PANEL_SIDE;
    for i in 0..panels {
        for j in 0..panels {
            let (cx, cz) = ((i as f64 + 0.5) * pitch, (j as f64 + 0.5) * pitch);
            let name = format!("panel_{i}_{j}");
            let y = h - drop;
            add(
                &name,
                3,
                [
                    p(cx - a, y, cz - a),
                    p(cx + a, y, cz - a),
                    p(cx + a, y, cz + a),
                    p(cx - a, y, cz + a),
                ],
            );
            let lo = p(cx - a, y, cz - a);
            let housing = |add: &mut dyn FnMut(&str, u32, [DVec3; 4])| {
                let c = [
                    lo,
                    lo + DVec3::X * PANEL_SIDE,
                    lo + DVec3::new(PANEL_SIDE, 0.0, PANEL_SIDE),
                    lo + DVec3::Z * PANEL_SIDE,
                ];
                let up = DVec3::Y * drop;
                for k in 0..4 {
                    let (p0, q0) = (c[(k + 1) % 4], c[k]);
                    add(&name, 2, [p0, q0, q0 + up, p0 + up]);
                }
            };
            housing(&mut add);
        }
    }
    // Furniture, one piece per grid cell in row order.
    for n in 0..objects {
        let (ci, cj) = (n % per_side, n / per_side);
        let centre = DVec3::new(
            (ci as f64 + 0.5) * CELL + rng.random_range(-0.2..0.2),
            0.0,
            (cj as f64 + 0.5) * CELL + rng.random_range(-0.2..0.2),
        );
        let turn = rng.random_range(0.0..std::f64::consts::PI);
        let (u, w) = (
            DVec3::new(turn.cos(), 0.0, turn.sin()),
            DVec3::new(-turn.sin(), 0.0, turn.cos()),
        );
        let finish = 4 + rng.random_range(0..finishes.len() as u32);
        if rng.random_range(0..10) == 0 {
            let name = format!("shelf_{n}");
            let (width, depth, tall) = (1.2, 0.35, 1.8);
            let board = 0.02;
            for x in [-0.5 * width, 0.5 * width - board] {
                let lo = centre + u * x - w * (0.5 * depth);
                cuboid(
                    &mut add,
                    &name,
                    finish,
                    lo,
                    u * board,
                    w * depth,
                    tall,
                    false,
                );
            }
            for level in [0.1, 0.85, 1.6] {
                let lo = centre + u * (-0.5 * width + board) - w * (0.5 * depth) + DVec3::Y * level;
                let along = u * (width - 2.0 * board);
                cuboid(&mut add, &name, finish, lo, along, w * depth, board, true);
            }
        } else {
            let name = format!("box_{n}");
            let (a, b) = (rng.random_range(0.3..1.4), rng.random_range(0.3..1.4));
            let tall = rng.random_range(0.2..2.0);
            let lo = centre - u * (0.5 * a) - w * (0.5 * b);
            cuboid(&mut add, &name, finish, lo, u * a, w * b, tall, false);
        }
    }
    Scene {
        name: format!("room_{objects}"),
        materials,
        surfaces,
        lights: Vec::new(),
        camera: None,
    }
}

/// The triangles of a UV sphere about `centre`: `rings` bands of `2 · rings` quads between
/// parallels (the bands at the poles as triangles), each quad cut in two, counter-clockwise
/// seen from outside: `4 · rings · (rings − 1)` triangles, their vertices on the sphere.
pub fn uv_sphere(centre: DVec3, radius: f64, rings: usize) -> Vec<[DVec3; 3]> {
    let rings = rings.max(2);
    let columns = 2 * rings;
    let at = |i: usize, j: usize| {
        let theta = std::f64::consts::PI * i as f64 / rings as f64;
        let phi = std::f64::consts::TAU * (j % columns) as f64 / columns as f64;
        centre
            + radius
                * DVec3::new(
                    theta.sin() * phi.cos(),
                    theta.cos(),
                    theta.sin() * phi.sin(),
                )
    };
    let mut triangles = Vec::with_capacity(4 * rings * (rings - 1));
    for i in 0..rings {
        for j in 0..columns {
            let (a, b, c, d) = (at(i, j), at(i, j + 1), at(i + 1, j + 1), at(i + 1, j));
            if i > 0 {
                triangles.push([a, b, c]);
            }
            if i + 1 < rings {
                triangles.push([a, c, d]);
            }
        }
    }
    triangles
}

/// The Cornell box with two white spheres of `rings` bands each ([`uv_sphere`]): one of
/// radius 6.5 cm resting 5 mm above the floor beside the short block's front, one of 6 cm
/// above the short block. `8 · rings · (rings − 1)` sphere triangles (rings = 112 gives
/// 99,456), objects "sphere0" and "sphere1", with the white walls' material.
pub fn cornell_with_spheres(rings: usize) -> Scene {
    let mut scene = crate::cornell::cornell_box();
    let white = scene.surfaces[scene
        .surfaces
        .iter()
        .position(|s| s.object == "back_wall")
        .expect("the Cornell box has a back wall")]
    .material;
    let spheres = [
        (DVec3::new(0.42, 0.07, 0.10), 0.065),
        (DVec3::new(0.15, 0.30, 0.15), 0.06),
    ];
    for (k, (centre, radius)) in spheres.into_iter().enumerate() {
        for t in uv_sphere(centre, radius, rings) {
            // Triangles of a sphere of positive radius have area.
            if let Ok(polygon) = Polygon::new(t.to_vec()) {
                scene.surfaces.push(Surface {
                    object: format!("sphere{k}"),
                    group: String::new(),
                    material: white,
                    polygon,
                    origin: Origin::default(),
                });
            }
        }
    }
    scene.name = format!("cornell_spheres_{rings}");
    scene
}

/// A box with one corner at `lo`, horizontal edges `a` and `b` (a × b pointing up) and
/// height `tall`, faces pointing out; the bottom face only when `bottom` (a box standing on
/// the floor has none).
#[allow(clippy::too_many_arguments)]
fn cuboid(
    add: &mut impl FnMut(&str, u32, [DVec3; 4]),
    name: &str,
    material: u32,
    lo: DVec3,
    a: DVec3,
    b: DVec3,
    tall: f64,
    bottom: bool,
) {
    let (a, b) = if a.cross(b).y < 0.0 { (b, a) } else { (a, b) };
    let up = DVec3::Y * tall;
    let c = [lo, lo + a, lo + a + b, lo + b];
    // Top, counter-clockwise seen from above (a × b points up).
    add(name, material, [c[0] + up, c[1] + up, c[2] + up, c[3] + up]);
    if bottom {
        add(name, material, [c[0], c[3], c[2], c[1]]);
    }
    for i in 0..4 {
        let (p, q) = (c[i], c[(i + 1) % 4]);
        add(name, material, [p, q, q + up, p + up]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tessellating_keeps_every_surface_area_and_orientation() {
        let scene = crate::cornell::cornell_box();
        let fine = tessellated(&scene, 5);
        assert_eq!(fine.surfaces.len(), 38 * 25);
        for name in scene.object_names() {
            let area = |s: &Scene| -> (f64, DVec3) {
                s.surfaces
                    .iter()
                    .filter(|x| x.object == name)
                    .map(|x| (x.polygon.area(), x.polygon.normal() * x.polygon.area()))
                    .fold((0.0, DVec3::ZERO), |(a, n), (b, m)| (a + b, n + m))
            };
            let (a0, n0) = area(&scene);
            let (a1, n1) = area(&fine);
            // Every Cornell polygon is planar, so the cells cover it exactly: only
            // rounding remains (1e-9 relative).
            assert!((a1 / a0 - 1.0).abs() < 1e-9, "{name}: {a0} → {a1}");
            assert!((n1 / a1 - n0 / a0).length() < 1e-9, "{name}");
        }
    }

    #[test]
    fn a_uv_sphere_is_closed_faces_out_and_has_the_sphere_area() {
        let (centre, radius) = (DVec3::new(1.0, 2.0, 3.0), 0.5);
        for rings in [2, 3, 16, 50] {
            let triangles = uv_sphere(centre, radius, rings);
            assert_eq!(triangles.len(), 4 * rings * (rings - 1));
            let (mut area, mut vector) = (0.0, DVec3::ZERO);
            for t in &triangles {
                let n = (t[1] - t[0]).cross(t[2] - t[0]) * 0.5;
                let centroid = (t[0] + t[1] + t[2]) / 3.0;
                assert!(n.dot(centroid - centre) > 0.0, "a triangle faces in");
                for v in t {
                    assert!((v.distance(centre) - radius).abs() < 1e-12);
                }
                area += n.length();
                vector += n;
            }
            // Closed: Σ A n = 0 to rounding.
            assert!(vector.length() < 1e-12 * area);
            // An inscribed polyhedron has less area than the sphere, approaching it as
            // (1 − O(1/rings²)); 5 % of 4πr² at 16 rings or more.
            let sphere = 4.0 * std::f64::consts::PI * radius * radius;
            assert!(area < sphere);
            if rings >= 16 {
                assert!(
                    area > 0.95 * sphere,
                    "{rings} rings: {area} against {sphere}"
                );
            }
        }
        let scene = cornell_with_spheres(10);
        assert_eq!(scene.surfaces.len(), 20 + 2 * 4 * 10 * 9);
    }

    #[test]
    fn a_furnished_room_is_closed_and_its_furniture_faces_out() {
        let room = furnished_room(50, 7);
        assert_eq!(room, furnished_room(50, 7), "a seed gives one room");
        let (lo, hi) = room.bounds();
        // Closed shell: the six shell faces' vector areas cancel (Σ A n = 0 for any closed
        // surface), so the room is watertight up to rounding.
        let shell: DVec3 = room
            .surfaces
            .iter()
            .filter(|s| {
                s.object == "floor" || s.object == "ceiling" || s.object.starts_with("wall")
            })
            .map(|s| s.polygon.normal() * s.polygon.area())
            .sum();
        assert!(shell.length() < 1e-9 * (hi - lo).length_squared());
        // Every box's sides face away from its own centre.
        for s in room
            .surfaces
            .iter()
            .filter(|s| s.object.starts_with("box_"))
        {
            let own: Vec<&Surface> = room
                .surfaces
                .iter()
                .filter(|x| x.object == s.object)
                .collect();
            assert_eq!(own.len(), 5, "{}", s.object);
            let c: DVec3 = own.iter().map(|x| x.polygon.centroid()).sum::<DVec3>() / 5.0;
            assert!(
                s.polygon.normal().dot(s.polygon.centroid() - c) > 0.0,
                "{}",
                s.object
            );
            let (a, b) = s.polygon.bounds();
            assert!(
                a.cmpge(lo).all() && b.cmple(hi).all(),
                "{} inside the room",
                s.object
            );
        }
        let emitters = room
            .surfaces
            .iter()
            .filter(|s| room.material(s).is_emitter())
            .count();
        assert!(emitters > 0);
    }
}
