//! A table whose legs end inside its top, against the independent path tracer.

use glam::DVec3;
use radiosity::coupling::hierarchical::HierarchicalOptions;
use radiosity::geometry::Polygon;
use radiosity::report::Report;
use radiosity::scene::{Material, MaterialId, Origin, Scene, Surface};
use radiosity::solve::{NoObserver, SolveOptions, SolverKind};
use radiosity::FormFactorMethod;
use radiosity_studies::path_trace::PathTracer;

/// A closed 3 × 3 × 2.5 m room lit by a ceiling panel in its housing, with a table: a
/// closed slab 12 cm thick whose top is at 0.82 m, on four square legs of 6 cm that stand
/// on the floor and end 10 cm inside the slab (an eighth of each leg's faces lies inside
/// it, where they see only the slab's backs).
fn table_room() -> Scene {
    let materials = vec![
        Material::new("wall", [0.6, 0.6, 0.6], [0.0; 3]),
        Material::new("wood", [0.5, 0.35, 0.2], [0.0; 3]),
        Material::new("metal", [0.7, 0.7, 0.7], [0.0; 3]),
        Material::new("lamp", [0.0; 3], [10.0; 3]),
    ];
    let mut surfaces = Vec::new();
    let mut add = |object: &str, material: u32, corners: [DVec3; 4]| {
        surfaces.push(Surface {
            object: object.into(),
            group: String::new(),
            material: MaterialId(material),
            polygon: Polygon::new(corners.to_vec()).unwrap(),
            origin: Origin::default(),
        })
    };
    let p = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
    // A box from `lo` to `hi`, its faces counter-clockwise seen from outside (`out`) or
    // from inside; `ends` false leaves out its top and bottom.
    let cuboid = |add: &mut dyn FnMut(&str, u32, [DVec3; 4]),
                  object: &str,
                  material: u32,
                  lo: DVec3,
                  hi: DVec3,
                  out: bool,
                  ends: bool| {
        let c = |i: u8| {
            p(
                if i & 1 == 0 { lo.x } else { hi.x },
                if i & 2 == 0 { lo.y } else { hi.y },
                if i & 4 == 0 { lo.z } else { hi.z },
            )
        };
        // Outward: bottom (−y), top (+y), −z, +z, −x, +x.
        let faces = [
            ([0, 1, 5, 4], true),
            ([2, 6, 7, 3], true),
            ([0, 2, 3, 1], false),
            ([4, 5, 7, 6], false),
            ([0, 4, 6, 2], false),
            ([1, 3, 7, 5], false),
        ];
        for (f, is_end) in faces {
            if is_end && !ends {
                continue;
            }
            let q = f.map(c);
            add(
                object,
                material,
                if out { q } else { [q[3], q[2], q[1], q[0]] },
            );
        }
    };
    cuboid(
        &mut add,
        "room",
        0,
        p(0., 0., 0.),
        p(3., 2.5, 3.),
        false,
        true,
    );
    cuboid(
        &mut add,
        "table",
        1,
        p(0.8, 0.7, 0.8),
        p(2.2, 0.82, 2.2),
        true,
        true,
    );
    for (x, z) in [(0.95, 0.95), (1.99, 0.95), (0.95, 1.99), (1.99, 1.99)] {
        cuboid(
            &mut add,
            "legs",
            2,
            p(x, 0.0, z),
            p(x + 0.06, 0.8, z + 0.06),
            true,
            false,
        );
    }
    // The lamp: a panel facing down 5 cm under the ceiling, in a housing up to it.
    let (a, b, y) = (1.2, 1.8, 2.45);
    add("lamp", 3, [p(a, y, a), p(b, y, a), p(b, y, b), p(a, y, b)]);
    cuboid(
        &mut add,
        "housing",
        0,
        p(a, y, a),
        p(b, 2.5, b),
        true,
        false,
    );
    Scene {
        name: "table_room".into(),
        materials,
        surfaces,
        lights: Vec::new(),
        camera: None,
    }
}

#[test]
fn legs_that_end_inside_a_table_top_read_what_the_path_tracer_reads() {
    let scene = table_room();
    // Elements no smaller than 1/1000 of the area (53 m²: 0.053 m²), so that the legs'
    // faces (0.048 m²) stay whole and each one's top eighth lies inside the slab.
    let solved = radiosity::solve::hierarchical::solve(
        &scene,
        FormFactorMethod::Raycast,
        HierarchicalOptions {
            min_area_fraction: 1e-3,
            ..HierarchicalOptions::default()
        },
        &SolveOptions {
            solver: SolverKind::Hierarchical,
            ..Default::default()
        },
        &mut NoObserver,
        &radiosity::progress::NoProgress,
    )
    .unwrap();
    let report = Report::new("table_room", &solved.mesh, &solved.solution, "raycast");
    let legs = report.object("legs").unwrap().radiosity;
    let tracer = PathTracer::new(&scene).unwrap();
    let faces: Vec<usize> = (0..scene.surfaces.len())
        .filter(|&i| scene.surfaces[i].object == "legs")
        .collect();
    let mut traced = [0.0; 3];
    let mut variance = [0.0; 3];
    for &i in &faces {
        let e = tracer.polygon(i, 20_000, 11 + i as u64);
        for c in 0..3 {
            traced[c] += e.radiosity[c] / faces.len() as f64;
            variance[c] += (e.radiosity_stderr[c] / faces.len() as f64).powi(2);
        }
    }
    // Measured +0.8, +1.3 and +1.8 % by channel (the path tracer's standard error 0.2 %);
    // +18.7 to +19.4 % while such a leaf's row was closed to its whole hemisphere (the
    // closure gave the legs' faces the light their top eighth cannot see). Bound 3 %: the
    // legs' faces are whole elements (0.048 m², under the minimum) and each link is within
    // ε = 1 % of its receiver's irradiance.
    for c in 0..3 {
        let se = variance[c].sqrt();
        let error = legs[c] / traced[c] - 1.0;
        eprintln!(
            "channel {c}: hierarchical {:.5}, path traced {:.5} ± {se:.5} ({:+.2} %)",
            legs[c],
            traced[c],
            100.0 * error
        );
        assert!(se < 0.005 * traced[c], "channel {c}: standard error {se}");
        assert!(error.abs() < 0.03, "channel {c}: {:+.2} %", 100.0 * error);
    }
}
