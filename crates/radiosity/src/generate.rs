//! Procedural scenes of any size, for scaling studies and tests: the Cornell box with every
//! polygon tessellated into many small ones (the same box, so the same answer, from
//! k² times the input), the Cornell box with two finely tessellated spheres (curved
//! surfaces, whose triangles do not merge back into polygons), a closed room furnished
//! with N boxes and shelves at random (fixed seed), lit by a grid of ceiling panels, and a
//! closed meeting room of N chairs made as real interior models are (tessellated cushions,
//! legs that pierce what they hold).

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
        surfaces.extend(surface(object, material, &corners));
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
    for i in 0..panels {
        for j in 0..panels {
            let (cx, cz) = ((i as f64 + 0.5) * pitch, (j as f64 + 0.5) * pitch);
            luminaire(&mut add, &format!("panel_{i}_{j}"), cx, cz, h, 3, 2);
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

/// Spacing of the chairs along the meeting room's table, m.
const CHAIR_PITCH: f64 = 0.7;

/// A closed meeting room with `chairs` chairs around one long table, made as real interior
/// models are: every curved part a mesh of small triangles (`segments` divisions around a
/// leg and across a cushion), legs that pierce the parts they hold up (a chair's five legs
/// end inside its seat, the table's four inside its top), and pieces that touch without
/// sharing edges. The table runs along x, 0.7 m of it per pair of chairs; chairs face it
/// from both sides, each a seat and a back (closed cushions bulging 3 and 2 cm, two sheets of
/// 2·segments² triangles each), five legs (tubes of `segments`/2 sides in `segments`/4 bands)
/// and two arm rests (boxes); the table's top and underside are grids of triangles. Walls,
/// floor and ceiling are single polygons facing in; luminaires as in [`furnished_room`] every
/// 2 m along the table, in two rows, so the room is closed. About 9·segments² triangles per
/// chair and 8·segments² for the table: 24 chairs of 36 segments give about 300 k.
pub fn meeting_room(chairs: usize, segments: usize) -> Scene {
    let segments = segments.max(4);
    let per_side = chairs.div_ceil(2).max(1);
    let table_length = CHAIR_PITCH * per_side as f64 + 0.6;
    let (width, depth, height) = (table_length + 3.0, 6.0, HEIGHT);
    let materials = vec![
        Material::new("carpet", [0.25, 0.22, 0.2], [0.0; 3]),
        Material::new("wall", [0.7, 0.68, 0.62], [0.0; 3]),
        Material::new("ceiling", [0.8, 0.8, 0.8], [0.0; 3]),
        Material::new("panel", [0.0; 3], [ROOM_PANEL_RADIANCE; 3]),
        Material::new("fabric", [0.25, 0.3, 0.5], [0.0; 3]),
        Material::new("metal", [0.6, 0.6, 0.62], [0.0; 3]),
        Material::new("wood", [0.5, 0.35, 0.2], [0.0; 3]),
    ];
    let (carpet, wall, ceiling, panel, fabric, metal, wood) = (0, 1, 2, 3, 4, 5, 6);
    let mut surfaces = Vec::new();
    let mut polygon = |object: &str, material: u32, corners: &[DVec3]| {
        surfaces.extend(surface(object, material, corners));
    };
    // A quad as two triangles, as exporters write it.
    let triangles = |polygon: &mut dyn FnMut(&str, u32, &[DVec3]),
                     object: &str,
                     material: u32,
                     [a, b, c, d]: [DVec3; 4]| {
        polygon(object, material, &[a, b, c]);
        polygon(object, material, &[a, c, d]);
    };
    let p = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
    let (w, d, h) = (width, depth, height);
    // Shell, facing in.
    polygon(
        "floor",
        carpet,
        &[p(0., 0., 0.), p(0., 0., d), p(w, 0., d), p(w, 0., 0.)],
    );
    polygon(
        "ceiling",
        ceiling,
        &[p(0., h, 0.), p(w, h, 0.), p(w, h, d), p(0., h, d)],
    );
    polygon(
        "wall_south",
        wall,
        &[p(0., 0., 0.), p(w, 0., 0.), p(w, h, 0.), p(0., h, 0.)],
    );
    polygon(
        "wall_north",
        wall,
        &[p(0., 0., d), p(0., h, d), p(w, h, d), p(w, 0., d)],
    );
    polygon(
        "wall_west",
        wall,
        &[p(0., 0., 0.), p(0., h, 0.), p(0., h, d), p(0., 0., d)],
    );
    polygon(
        "wall_east",
        wall,
        &[p(w, 0., 0.), p(w, 0., d), p(w, h, d), p(w, h, 0.)],
    );
    let lamps = ((width / 2.0).round() as usize).max(1);
    for i in 0..lamps {
        for (j, z) in [0.35 * depth, 0.65 * depth].into_iter().enumerate() {
            let x = (i as f64 + 0.5) * width / lamps as f64;
            luminaire(
                &mut |o: &str, m: u32, q: [DVec3; 4]| polygon(o, m, &q),
                &format!("panel_{i}_{j}"),
                x,
                z,
                h,
                panel,
                ceiling,
            );
        }
    }
    // A tube about the vertical through `foot`, radius `r`, from the floor up to `top`,
    // facing out, open at both ends (they stand on the floor and end inside a part).
    let tube = |polygon: &mut dyn FnMut(&str, u32, &[DVec3]),
                object: &str,
                foot: DVec3,
                r: f64,
                top: f64| {
        let sides = (segments / 2).max(3);
        let bands = (segments / 4).max(1);
        let at = |k: usize, y: f64| {
            let a = std::f64::consts::TAU * (k % sides) as f64 / sides as f64;
            foot + DVec3::new(r * a.cos(), y, r * a.sin())
        };
        for band in 0..bands {
            let (y0, y1) = (
                top * band as f64 / bands as f64,
                top * (band + 1) as f64 / bands as f64,
            );
            for k in 0..sides {
                triangles(
                    polygon,
                    object,
                    metal,
                    [at(k, y0), at(k, y1), at(k + 1, y1), at(k + 1, y0)],
                );
            }
        }
    };
    // A closed cushion over the rectangle `origin` + s·ex + t·ey (s, t in [0, 1]), bulging
    // `bulge` along ex × ey and a third of it the other way, both sheets facing out.
    let cushion = |polygon: &mut dyn FnMut(&str, u32, &[DVec3]),
                   object: &str,
                   origin: DVec3,
                   ex: DVec3,
                   ey: DVec3,
                   bulge: f64| {
        let n = ex.cross(ey).normalize();
        for (side, height) in [(1.0, bulge), (-1.0, bulge / 3.0)] {
            let at = |i: usize, j: usize| {
                let (s, t) = (i as f64 / segments as f64, j as f64 / segments as f64);
                let lift =
                    height * (std::f64::consts::PI * s).sin() * (std::f64::consts::PI * t).sin();
                origin + ex * s + ey * t + n * (side * lift)
            };
            for i in 0..segments {
                for j in 0..segments {
                    let quad = [at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)];
                    let quad = if side > 0.0 {
                        quad
                    } else {
                        [quad[0], quad[3], quad[2], quad[1]]
                    };
                    triangles(polygon, object, fabric, quad);
                }
            }
        }
    };
    // The table: a 4 cm slab whose top and underside are grids of triangles, its legs
    // ending 2 cm inside it.
    let (x0, x1, z0, z1, top) = (
        1.5,
        1.5 + table_length,
        0.5 * depth - 0.8,
        0.5 * depth + 0.8,
        0.74,
    );
    let slab = 0.04;
    let (nx, nz) = (2 * segments, segments);
    let grid = |i: usize, j: usize, y: f64| {
        p(
            x0 + (x1 - x0) * i as f64 / nx as f64,
            y,
            z0 + (z1 - z0) * j as f64 / nz as f64,
        )
    };
    for i in 0..nx {
        for j in 0..nz {
            let (a, b, c, e) = (
                grid(i, j, top),
                grid(i, j + 1, top),
                grid(i + 1, j + 1, top),
                grid(i + 1, j, top),
            );
            triangles(&mut polygon, "table", wood, [a, b, c, e]);
            let down = DVec3::Y * slab;
            triangles(
                &mut polygon,
                "table",
                wood,
                [a - down, e - down, c - down, b - down],
            );
        }
    }
    cuboid(
        &mut |o: &str, m: u32, q: [DVec3; 4]| {
            // The slab's four edges (its top and bottom are the grids above).
            if (q[0].y - q[1].y).abs() > 0.0 || (q[1].y - q[2].y).abs() > 0.0 {
                polygon(o, m, &q);
            }
        },
        "table",
        wood,
        p(x0, top - slab, z0),
        DVec3::X * (x1 - x0),
        DVec3::Z * (z1 - z0),
        slab,
        false,
    );
    for (x, z) in [
        (x0 + 0.3, z0 + 0.3),
        (x1 - 0.3, z0 + 0.3),
        (x0 + 0.3, z1 - 0.3),
        (x1 - 0.3, z1 - 0.3),
    ] {
        tube(&mut polygon, "table_legs", p(x, 0.0, z), 0.04, top - 0.02);
    }
    // The chairs, alternately on the south and north side, facing the table.
    for k in 0..chairs {
        let x = x0 + 0.3 + CHAIR_PITCH * ((k / 2) as f64 + 0.5);
        let south = k % 2 == 0;
        let z = if south { z0 - 0.45 } else { z1 + 0.45 };
        let name = format!("chair_{k}");
        let seat = 0.45;
        let half = 0.24;
        cushion(
            &mut polygon,
            &format!("{name}_seat"),
            p(x - half, seat, z - half),
            DVec3::Z * (2.0 * half),
            DVec3::X * (2.0 * half),
            0.03,
        );
        // The back, on the side away from the table, bulging toward it.
        let back_z = if south {
            z - half - 0.02
        } else {
            z + half + 0.02
        };
        let (ex, ey) = if south {
            (DVec3::X * (2.0 * half), DVec3::Y * 0.5)
        } else {
            (DVec3::Y * 0.5, DVec3::X * (2.0 * half))
        };
        cushion(
            &mut polygon,
            &format!("{name}_back"),
            p(x - half, seat + 0.08, back_z),
            ex,
            ey,
            0.02,
        );
        for (dx, dz) in [
            (-0.18, -0.18),
            (0.18, -0.18),
            (-0.18, 0.18),
            (0.18, 0.18),
            (0.0, 0.0),
        ] {
            tube(
                &mut polygon,
                &format!("{name}_legs"),
                p(x + dx, 0.0, z + dz),
                0.015,
                seat + 0.002,
            );
        }
        for side in [-1.0, 1.0] {
            let lo = p(x + side * (half + 0.02) - 0.015, seat + 0.2, z - 0.2);
            cuboid(
                &mut |o: &str, m: u32, q: [DVec3; 4]| polygon(o, m, &q),
                &format!("{name}_arms"),
                metal,
                lo,
                DVec3::X * 0.03,
                DVec3::Z * 0.4,
                0.03,
                true,
            );
        }
    }
    Scene {
        name: format!("meeting_room_{chairs}_{segments}"),
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

/// A surface of `object` in `material` with these corners. Every polygon the generators
/// build has positive extent; a degenerate one would be a bug in the generator, skipped
/// (`None`) rather than aborting a benchmark.
fn surface(object: &str, material: u32, corners: &[DVec3]) -> Option<Surface> {
    Polygon::new(corners.to_vec()).ok().map(|polygon| Surface {
        object: object.to_owned(),
        group: String::new(),
        material: MaterialId(material),
        polygon,
        origin: Origin::default(),
    })
}

/// A ceiling luminaire centred on (`cx`, `cz`) under a ceiling at height `h`: a square
/// emitting panel of [`PANEL_SIDE`] facing down, 5 cm below the ceiling (material `panel`),
/// in a housing of four side faces up to the ceiling (material `housing`), so that no light
/// falls on the panel's back.
fn luminaire(
    add: &mut impl FnMut(&str, u32, [DVec3; 4]),
    name: &str,
    cx: f64,
    cz: f64,
    h: f64,
    panel: u32,
    housing: u32,
) {
    let drop = 0.05;
    let a = 0.5 * PANEL_SIDE;
    let y = h - drop;
    let p = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
    add(
        name,
        panel,
        [
            p(cx - a, y, cz - a),
            p(cx + a, y, cz - a),
            p(cx + a, y, cz + a),
            p(cx - a, y, cz + a),
        ],
    );
    let lo = p(cx - a, y, cz - a);
    let c = [
        lo,
        lo + DVec3::X * PANEL_SIDE,
        lo + DVec3::new(PANEL_SIDE, 0.0, PANEL_SIDE),
        lo + DVec3::Z * PANEL_SIDE,
    ];
    let up = DVec3::Y * drop;
    for k in 0..4 {
        let (p0, q0) = (c[(k + 1) % 4], c[k]);
        add(name, housing, [p0, q0, q0 + up, p0 + up]);
    }
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

    #[test]
    fn a_meeting_room_is_closed_and_its_parts_face_out() {
        let segments = 8;
        let room = meeting_room(4, segments);
        // Every closed part (a cushion: two sheets meeting at the rim) has vector area
        // Σ n A = 0 (the divergence theorem), and faces out: its signed volume
        // (1/3) Σ c · n A is positive. The shell faces in: its vector area is 0 too, its
        // volume negative.
        let part = |name: &str| -> (DVec3, f64, usize) {
            room.surfaces
                .iter()
                .filter(|s| s.object == name)
                .map(|s| {
                    let na = s.polygon.normal() * s.polygon.area();
                    (na, s.polygon.centroid().dot(na) / 3.0, 1)
                })
                .fold((DVec3::ZERO, 0.0, 0), |(a, v, n), (b, w, m)| {
                    (a + b, v + w, n + m)
                })
        };
        for chair in 0..4 {
            for piece in ["seat", "back"] {
                let (area, volume, count) = part(&format!("chair_{chair}_{piece}"));
                assert_eq!(count, 4 * segments * segments);
                // A cushion holds a few litres (48 × 48 cm, bulging 3 cm and 1 cm).
                assert!(area.length() < 1e-9, "chair_{chair}_{piece}: {area}");
                assert!(
                    volume > 1e-4 && volume < 1e-2,
                    "chair_{chair}_{piece}: {volume}"
                );
            }
            // Each leg a tube of segments/2 sides in segments/4 bands, two triangles each.
            let (_, _, legs) = part(&format!("chair_{chair}_legs"));
            assert_eq!(legs, 5 * 2 * (segments / 2) * (segments / 4));
        }
        let shell: Vec<&Surface> = room
            .surfaces
            .iter()
            .filter(|s| {
                s.object == "floor" || s.object == "ceiling" || s.object.starts_with("wall")
            })
            .collect();
        let area: DVec3 = shell
            .iter()
            .map(|s| s.polygon.normal() * s.polygon.area())
            .sum();
        let volume: f64 = shell
            .iter()
            .map(|s| s.polygon.centroid().dot(s.polygon.normal()) * s.polygon.area() / 3.0)
            .sum();
        assert!(area.length() < 1e-9, "{area}");
        assert!(volume < 0.0, "the shell faces in: {volume}");
        // A leg's top ends inside what it holds: between the seat's two sheets.
        for s in room.surfaces.iter().filter(|s| s.object == "chair_0_legs") {
            for v in s.polygon.vertices() {
                assert!(v.y >= 0.0 && v.y <= 0.45 + 0.003, "{v}");
            }
        }
        let emitters = room
            .surfaces
            .iter()
            .filter(|s| room.material(s).is_emitter())
            .count();
        assert!(emitters >= 2);
    }
}
