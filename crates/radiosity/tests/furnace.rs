//! The closed "furnace" cube (tests/reference/furnace.json): in a closed enclosure with
//! uniform emission E and reflectance ρ every point has B = E / (1 − ρ); with only the floor
//! emitting, the one-element-per-face system has a known exact answer.

use glam::DVec3;
use radiosity::formfactor::FormFactorMethod;
use radiosity::geometry::Polygon;
use radiosity::mesh::{Mesh, MeshOptions};
use radiosity::pipeline::{solve_mesh, SolveSettings};
use radiosity::progress::NoProgress;
use radiosity::report::Report;
use radiosity::scene::{Material, MaterialId, Origin, Scene, Surface};
use radiosity::solve::{NoObserver, SolveOptions, SolverKind};
use serde_json::Value;

fn furnace() -> Value {
    serde_json::from_str(include_str!("reference/furnace.json")).unwrap()
}

const FACES: [(&str, [[f64; 3]; 4]); 6] = [
    (
        "floor",
        [[0., 0., 1.], [1., 0., 1.], [1., 0., 0.], [0., 0., 0.]],
    ),
    (
        "ceiling",
        [[0., 1., 0.], [1., 1., 0.], [1., 1., 1.], [0., 1., 1.]],
    ),
    (
        "wall_x0",
        [[0., 0., 0.], [0., 1., 0.], [0., 1., 1.], [0., 0., 1.]],
    ),
    (
        "wall_x1",
        [[1., 0., 1.], [1., 1., 1.], [1., 1., 0.], [1., 0., 0.]],
    ),
    (
        "wall_z0",
        [[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]],
    ),
    (
        "wall_z1",
        [[0., 1., 1.], [1., 1., 1.], [1., 0., 1.], [0., 0., 1.]],
    ),
];

/// The unit cube with inward-facing faces; `emits(face)` gives each face's exitance E.
fn cube(rho: f64, emits: impl Fn(&str) -> f64) -> Scene {
    let mut materials = Vec::new();
    let mut surfaces = Vec::new();
    for (i, (name, v)) in FACES.iter().enumerate() {
        let e = emits(name);
        materials.push(Material::new(
            name.to_string(),
            [rho; 3],
            [e / std::f64::consts::PI; 3],
        ));
        surfaces.push(Surface {
            object: name.to_string(),
            group: name.to_string(),
            material: MaterialId(i as u32),
            polygon: Polygon::new(v.iter().map(|p| DVec3::from_array(*p)).collect()).unwrap(),
            origin: Origin::default(),
        });
    }
    Scene {
        name: "furnace".into(),
        materials,
        surfaces,
        lights: Vec::new(),
        camera: None,
    }
}

fn run_with(
    scene: &Scene,
    mesh_opts: MeshOptions,
    solver: SolverKind,
    tol: f64,
    method: FormFactorMethod,
) -> (Mesh, Report) {
    let mesh = Mesh::build(scene, &mesh_opts).unwrap();
    let settings = SolveSettings {
        mesh: mesh_opts,
        form_factor: method,
        solve: SolveOptions {
            solver,
            tolerance: tol,
            ..Default::default()
        },
        ..Default::default()
    };
    let sol = solve_mesh(&mesh, &settings, &NoProgress, &mut NoObserver).unwrap();
    let report = Report::new("furnace", &mesh, &sol, method.name());
    (mesh, report)
}

fn run(scene: &Scene, mesh_opts: MeshOptions, solver: SolverKind, tol: f64) -> (Mesh, Report) {
    run_with(scene, mesh_opts, solver, tol, FormFactorMethod::Raycast)
}

fn per_face(n: usize, sub: u32) -> MeshOptions {
    MeshOptions {
        max_element_size: Some(1.0 / n as f64 + 1e-9),
        elements: 0,
        patch_subdivision: sub,
    }
}

#[test]
fn uniform_emission_gives_e_over_one_minus_rho_for_every_solver() {
    let f = furnace();
    for case in f["cases"].as_array().unwrap() {
        if case["case"] != "a_uniform_emission" {
            continue;
        }
        let rho = case["rho"].as_f64().unwrap();
        let expected = case["expected_B_all_faces"].as_f64().unwrap();
        let scene = cube(rho, |_| case["E"].as_f64().unwrap());
        for &solver in SolverKind::ALL {
            for mesh in [per_face(1, 1), per_face(4, 2)] {
                // Tolerance: the solvers stop at a relative residual (or unshot fraction) of
                // 1e-9, far below the 1e-6 asked, so what remains is the closure of the form
                // factors, which is exact for a convex enclosure (the other faces tile each
                // receiving point's hemisphere) up to rounding.
                let (mesh, report) = run(&scene, mesh, solver, 1e-9);
                for o in &report.objects {
                    for c in 0..3 {
                        let rel = (o.radiosity[c] - expected).abs() / expected;
                        assert!(
                            rel < 1e-6,
                            "{solver} {} B={} expected {expected} ({} elements)",
                            o.name,
                            o.radiosity[c],
                            mesh.len()
                        );
                    }
                }
                // Energy balance: all emitted power is absorbed, none escapes.
                assert!(
                    report.balance_error() < 1e-6,
                    "{solver}: balance {}",
                    report.balance_error()
                );
                assert!(report
                    .totals
                    .escaped_power
                    .iter()
                    .all(|e| e.abs() < 1e-6 * report.totals.emitted_power[0]));
            }
        }
    }
}

#[test]
fn floor_emitting_cube_matches_the_six_by_six_system() {
    let f = furnace();
    for case in f["cases"].as_array().unwrap() {
        if case["case"] != "b_floor_emits" {
            continue;
        }
        let rho = case["rho"].as_f64().unwrap();
        let scene = cube(rho, |n| if n == "floor" { 1.0 } else { 0.0 });
        let expected = &case["expected_B_one_element_per_face"];
        // (method, tolerance): the exact polygon-to-polygon form factor reproduces the 6×6
        // system to the precision the coupling matrix stores form factors in (f32, 6e-8
        // relative), hence 2e-7. The default raycast method integrates each receiving face with
        // a 3×3 Gauss rule of the exact point-to-polygon factor (its order follows the
        // face's size over its distance to the nearest other surface); on the adjacent-face
        // kernel, which has a logarithmic singularity along the shared edge, such a rule
        // is accurate to ~1e-4 relative, and B inherits it.
        for (method, tol) in [
            (FormFactorMethod::AnalyticPolygon, 2e-7),
            (FormFactorMethod::Raycast, 1e-4),
        ] {
            let (_, report) = run_with(&scene, per_face(1, 1), SolverKind::Direct, 1e-9, method);
            for o in &report.objects {
                let want = expected[&o.name].as_f64().unwrap();
                let rel = (o.radiosity[0] - want).abs() / want;
                assert!(
                    rel < tol,
                    "{method} rho {rho} {}: B={} expected {want} (rel {rel:e})",
                    o.name,
                    o.radiosity[0]
                );
            }
            assert!(report.balance_error() < 1e-6);
        }
    }
}

#[test]
fn floor_emitting_cube_fine_mesh_approaches_the_continuous_answer() {
    let f = furnace();
    for case in f["cases"].as_array().unwrap() {
        if case["case"] != "b_floor_emits" {
            continue;
        }
        let rho = case["rho"].as_f64().unwrap();
        let scene = cube(rho, |n| if n == "floor" { 1.0 } else { 0.0 });
        let (mesh, report) = run(&scene, per_face(16, 4), SolverKind::Direct, 1e-9);
        let cont = &case["mitsuba_face_avg_B_continuous"];
        let stderr = &case["mitsuba_face_avg_B_continuous_stderr"];
        let coarse = &case["expected_B_one_element_per_face"];
        for o in &report.objects {
            let want = cont[&o.name].as_f64().unwrap();
            let se = stderr[&o.name].as_f64().unwrap();
            // Tolerance: 4 Monte Carlo standard errors of the Mitsuba estimate plus 0.3 %
            // for the remaining discretisation error of a 16×16 mesh whose patches are
            // 4×4 elements (the 1-element answer differs from the continuous one by 1–6 %,
            // so this still demands most of that gap be closed).
            let err = (o.radiosity[0] - want).abs();
            let tol = 4.0 * se + 3e-3 * want;
            assert!(
                err < tol,
                "rho {rho} {}: B={} continuous {want} ± {se} ({} elements)",
                o.name,
                o.radiosity[0],
                mesh.len()
            );
            let gap = (coarse[&o.name].as_f64().unwrap() - want).abs();
            assert!(
                err < 0.5 * gap + 4.0 * se,
                "{}: the fine mesh should beat one element per face",
                o.name
            );
        }
    }
}

// ---------------------------------------------------------------------------------------
// Hierarchical radiosity with clustering (the whole scene's hierarchy, refined by ε).

fn solve_hierarchical(scene: &Scene, epsilon: f64) -> (radiosity::pipeline::Solved, Report) {
    let mut settings = SolveSettings {
        solve: SolveOptions {
            solver: SolverKind::Hierarchical,
            tolerance: 1e-6,
            ..Default::default()
        },
        ..Default::default()
    };
    settings.hierarchical.epsilon = epsilon;
    let solved = radiosity::pipeline::solve_scene(scene, &settings, &NoProgress).unwrap();
    let report = Report::new("furnace", &solved.mesh, &solved.solution, "raycast");
    (solved, report)
}

#[test]
fn uniform_emission_in_a_closed_cube_gives_e_over_one_minus_rho() {
    for case in furnace()["cases"].as_array().unwrap() {
        if case["case"] != "a_uniform_emission" {
            continue;
        }
        let rho = case["rho"].as_f64().unwrap();
        let expected = case["expected_B_all_faces"].as_f64().unwrap();
        let scene = cube(rho, |_| case["E"].as_f64().unwrap());
        let (solved, report) = solve_hierarchical(&scene, 0.02);
        // Tolerance: the 1e-4, on every element. The closed cube's links are
        // balanced (`coupling/hierarchical/closure.rs`): every leaf's row sums to 1, so
        // uniform E and ρ give B = E/(1 − ρ) up to the solver's stopping rule (relative
        // change 1e-6 here, times 1/(1 − ρ) ≤ 5): measured 1.2e-7 at ρ = 0.5 and 9.8e-7 at
        // ρ = 0.8. (Before the closure, link errors added up along the edges: elements read
        // up to 8.8 % high at ρ = 0.5 and 11.7 % at ρ = 0.8, face means 6.5e-4 and 2.7e-3.)
        let mut worst_element = 0.0f64;
        for b in &solved.solution.radiosity {
            let err = (b[0] - expected).abs() / expected;
            worst_element = worst_element.max(err);
        }
        assert!(
            worst_element < 1e-4,
            "rho {rho}: element error {worst_element}"
        );
        for o in &report.objects {
            let rel = (o.radiosity[0] - expected).abs() / expected;
            assert!(
                rel < 1e-4,
                "rho {rho}: {} B={} expected {expected}",
                o.name,
                o.radiosity[0]
            );
        }
        // Energy balance of the closed box: everything emitted is absorbed.
        assert!(report.balance_error() < 1e-4);
        eprintln!(
            "rho {rho}: worst element {worst_element:.2e}, {} elements",
            solved.mesh.len()
        );
    }
}

#[test]
fn floor_emitting_cube_matches_mitsubas_continuous_answer() {
    for case in furnace()["cases"].as_array().unwrap() {
        if case["case"] != "b_floor_emits" {
            continue;
        }
        let rho = case["rho"].as_f64().unwrap();
        let scene = cube(rho, |n| if n == "floor" { 1.0 } else { 0.0 });
        let (solved, report) = solve_hierarchical(&scene, 0.01);
        let cont = &case["mitsuba_face_avg_B_continuous"];
        let stderr = &case["mitsuba_face_avg_B_continuous_stderr"];
        for o in &report.objects {
            let want = cont[&o.name].as_f64().unwrap();
            let se = stderr[&o.name].as_f64().unwrap();
            // Tolerance: 4 Monte Carlo standard errors of the reference plus 1 % of it, the
            // ε = 0.01 asked of every link (errors of many links may add up on one face, but
            // they partly cancel; measured within 0.6 %).
            let err = (o.radiosity[0] - want).abs();
            assert!(
                err < 4.0 * se + 0.01 * want,
                "rho {rho} {}: B={} continuous {want} ± {se} ({} elements)",
                o.name,
                o.radiosity[0],
                solved.mesh.len()
            );
        }
        // Energy balance of a closed box: everything emitted is absorbed.
        assert!(report.balance_error() < 1e-4);
    }
}
