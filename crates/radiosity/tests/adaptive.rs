//! Adaptive mesh refinement on the Cornell box: at the same element count it must beat a
//! uniform mesh against the Mitsuba reference, and its display must have no cracks.

use glam::DVec3;
use radiosity::cornell::cornell_box;
use radiosity::display::Shading;
use radiosity::mesh::MeshOptions;
use radiosity::mesh::RefineOptions;
use radiosity::pipeline::{
    render_elements, solve_scene, solve_scene_adaptive, Shaded, SolveSettings, Solved,
};
use radiosity::progress::NoProgress;
use radiosity::render::RenderOptions;
use radiosity::report::Report;
use radiosity::scene::Camera;
use radiosity::solve::{SolveOptions, SolverKind};
use serde_json::Value;

fn settings(elements: usize) -> SolveSettings {
    SolveSettings {
        mesh: MeshOptions {
            elements,
            ..Default::default()
        },
        solve: SolveOptions {
            solver: SolverKind::Direct,
            ..Default::default()
        },
        ..Default::default()
    }
}

/// Mean relative error of per-polygon radiosity and of region means against the reference.
fn errors(s: &Solved) -> (f64, f64) {
    let reference: Value =
        serde_json::from_str(include_str!("reference/cornell_reference.json")).unwrap();
    let report = Report::new("cornell", &s.mesh, &s.solution, "raycast");
    let mut poly = Vec::new();
    for p in reference["per_polygon_area_averaged"]["polygons"]
        .as_array()
        .unwrap()
    {
        let ours = report.object(p["name"].as_str().unwrap()).unwrap();
        for c in 0..3 {
            let want = p["radiosity_avg"][c].as_f64().unwrap();
            poly.push((ours.radiosity[c] - want).abs() / want);
        }
    }
    let camera = cornell_box().camera.unwrap();
    let shaded = Shaded {
        vertices: &s.mesh.vertices,
        elements: &s.mesh.elements,
        radiosity: &s.solution.radiosity,
    };
    let options = RenderOptions {
        width: 256,
        height: 256,
        ..Default::default()
    };
    let image = render_elements(&shaded, &camera, Shading::Smooth, false, &options).unwrap();
    let mut region = Vec::new();
    for r in reference["regions"].as_object().unwrap().values() {
        let rect: Vec<u32> = r["rect_x0y0x1y1"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_u64().unwrap() as u32)
            .collect();
        let ours = image.region_mean(rect[0], rect[1], rect[2], rect[3]);
        for c in 0..3 {
            let want = r["mean_radiance_rgb"][c].as_f64().unwrap();
            region.push((ours[c] - want).abs() / want);
        }
        if std::env::var("VERBOSE").is_ok() {
            eprintln!(
                "{} {:?} {:?}",
                r["surface_group"], ours, r["mean_radiance_rgb"]
            );
        }
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    (mean(&poly), mean(&region))
}

#[test]
fn adaptive_beats_uniform_at_the_same_element_count() {
    let scene = cornell_box();
    let refine = RefineOptions {
        max_elements: Some(2000),
        ..Default::default()
    };
    let adaptive = solve_scene_adaptive(&scene, &settings(2000), &refine, &NoProgress).unwrap();
    // A uniform mesh with the same number of elements (±10 %): search the target count.
    let n = adaptive.mesh.len();
    let mut target = n;
    let uniform = loop {
        let s = solve_scene(&scene, &settings(target), &NoProgress).unwrap();
        let m = s.mesh.len();
        if (m as f64 - n as f64).abs() <= 0.1 * n as f64 {
            break s;
        }
        target = (target as f64 * n as f64 / m as f64) as usize;
    };
    assert!(
        adaptive.mesh.elements.iter().any(|e| e.depth > 0),
        "nothing was refined"
    );
    let (ap, ar) = errors(&adaptive);
    let (up, ur) = errors(&uniform);
    eprintln!(
        "adaptive {} elements: polygon {:.4} region {:.4}; uniform {} elements: polygon {:.4} region {:.4}",
        adaptive.mesh.len(),
        ap,
        ar,
        uniform.mesh.len(),
        up,
        ur
    );
    assert!(ap < up, "per-polygon error: adaptive {ap} vs uniform {up}");
    assert!(ar < ur, "region error: adaptive {ar} vs uniform {ur}");
}

#[test]
fn refined_mesh_renders_without_cracks() {
    let scene = cornell_box();
    let refine = RefineOptions {
        max_elements: Some(1500),
        ..Default::default()
    };
    let solved = solve_scene_adaptive(&scene, &settings(1500), &refine, &NoProgress).unwrap();
    let hanging =
        radiosity::display::Conformity::find(&solved.mesh.vertices, &solved.mesh.elements);
    assert!(
        hanging.hanging_count() > 0,
        "the test needs T-junctions to be meaningful"
    );
    // From inside the box, looking at the back: every pixel sees a surface. The background
    // is a negative sentinel, so a single crack sample makes its pixel negative.
    let camera = Camera {
        eye: DVec3::new(0.278, 0.35, 0.02),
        target: DVec3::new(0.278, 0.2, 0.559),
        up: DVec3::Y,
        fov_deg: 90.0,
    };
    let options = RenderOptions {
        width: 200,
        height: 200,
        background: [-1.0; 3],
        ..Default::default()
    };
    let shaded = Shaded {
        vertices: &solved.mesh.vertices,
        elements: &solved.mesh.elements,
        radiosity: &solved.solution.radiosity,
    };
    for shading in [Shading::Flat, Shading::Smooth] {
        let image = render_elements(&shaded, &camera, shading, false, &options).unwrap();
        let cracks = image
            .pixels
            .iter()
            .filter(|p| p.iter().any(|v| *v < 0.0))
            .count();
        assert_eq!(
            cracks, 0,
            "{shading:?}: {cracks} pixels show the background through the mesh"
        );
    }
}
