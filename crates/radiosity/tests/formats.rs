//! The scene formats end to end: the Cornell box read from OBJ, our JSON, glTF and MGF solves
//! to the same radiosity; a solved scene baked to GLB reads back with the solution's vertex
//! radiance; the scenes in `scenes/` load and balance their energy.
//!
//! Paths are relative to the crate root, where cargo runs integration tests.

use radiosity::display::{DisplayMesh, Shading};
use radiosity::io::formats::{load_any_with, LoadOptions};
use radiosity::io::scene_file::LoadedScene;
use radiosity::pipeline::{solve_scene, SolveSettings, Solved};
use radiosity::progress::NoProgress;
use radiosity::report::Report;
use radiosity::scene::Scene;
use radiosity::solve::SolverKind;
use std::path::Path;

fn load(path: &str) -> LoadedScene {
    load_any_with(Path::new(path), &LoadOptions::default())
        .unwrap_or_else(|e| panic!("{path}: {e}"))
}

/// The direct solver (exact up to rounding, so the comparison measures only the inputs) on a
/// coarse mesh.
fn solve(scene: &Scene, elements: usize) -> Solved {
    let mut settings = SolveSettings::default();
    settings.mesh.elements = elements;
    settings.solve.solver = SolverKind::Direct;
    solve_scene(scene, &settings, &NoProgress).expect("solves")
}

fn report(scene: &Scene, solved: &Solved) -> Report {
    Report::new(
        &scene.name,
        &solved.mesh,
        &solved.solution,
        solved.form_factor.name(),
    )
}

#[test]
fn cornell_box_gives_the_same_radiosity_from_every_format() {
    let reference_scene = load("scenes/cornell.obj").scene;
    let reference = report(&reference_scene, &solve(&reference_scene, 400));
    for path in [
        "scenes/cornell.json",
        "scenes/cornell.glb",
        "scenes/cornell.mgf",
    ] {
        let loaded = load(path);
        assert!(loaded.warnings.is_empty(), "{path}: {:?}", loaded.warnings);
        let other = report(&loaded.scene, &solve(&loaded.scene, 400));
        assert_eq!(other.objects.len(), reference.objects.len(), "{path}");
        for (o, r) in other.objects.iter().zip(&reference.objects) {
            assert_eq!(o.name, r.name, "{path}");
            for c in 0..3 {
                // glTF stores f32 (positions within 3.3e-8 m, ρ and L_e within 2⁻²⁴
                // relative), MGF and JSON the OBJ's decimals: every input agrees with the OBJ
                // to ~1e-7 relative, and radiosity depends smoothly on them.
                let tolerance = 1e-6 * r.radiosity[c].abs().max(1e-3);
                assert!(
                    (o.radiosity[c] - r.radiosity[c]).abs() <= tolerance,
                    "{path} {}: channel {c}: {} vs OBJ {}",
                    r.name,
                    o.radiosity[c],
                    r.radiosity[c]
                );
            }
        }
    }
}

/// Reads a FLOAT VEC3 accessor (tightly packed, as the exporter writes them).
fn read_vec3(blob: &[u8], accessor: &gltf::Accessor) -> Vec<[f32; 3]> {
    let view = accessor.view().expect("a buffer view");
    let start = view.offset() + accessor.offset();
    blob[start..start + 12 * accessor.count()]
        .chunks_exact(12)
        .map(|c| [0, 4, 8].map(|o| f32::from_le_bytes([c[o], c[o + 1], c[o + 2], c[o + 3]])))
        .collect()
}

#[test]
fn baked_glb_holds_the_solutions_vertex_radiance() {
    let scene = load("scenes/cornell.glb").scene;
    let solved = solve(&scene, 300);
    let radiosity = solved.solution.display_radiosity(&solved.mesh, false);
    let baked = radiosity::export::solution::baked_scene(&scene, &solved.mesh, &radiosity);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("out.glb");
    let options = radiosity::export::ExportOptions::default();
    let summary = radiosity::export::export(&baked, &path, &options).unwrap();
    assert!(summary.png.exists() && summary.exr.exists());

    // The independent reference: the crack-free display mesh built here from the solution.
    let display = DisplayMesh::build(
        &solved.mesh.vertices,
        &solved.mesh.elements,
        &radiosity,
        Shading::Smooth,
    );
    let bytes = std::fs::read(&path).unwrap();
    let glb = gltf::Gltf::from_slice(&bytes).expect("the gltf crate reads the GLB");
    let blob = glb.blob.clone().expect("a BIN chunk");
    let names: Vec<&str> = glb
        .document
        .nodes()
        .filter(|n| n.mesh().is_some())
        .filter_map(|n| n.name())
        .collect();
    assert_eq!(names, scene.object_names());

    let mut vertices = 0;
    let mut triangles = 0;
    for mesh in glb.document.meshes() {
        for primitive in mesh.primitives() {
            let colour = primitive.get(&gltf::Semantic::Colors(0)).unwrap();
            assert_eq!(colour.data_type(), gltf::accessor::DataType::F32);
            assert_eq!(colour.dimensions(), gltf::accessor::Dimensions::Vec3);
            assert!(primitive.get(&gltf::Semantic::TexCoords(1)).is_some());
            let reader = primitive.reader(|_| Some(&blob[..]));
            let positions: Vec<[f32; 3]> = reader.read_positions().unwrap().collect();
            let colours: Vec<[f32; 3]> = reader.read_colors(0).unwrap().into_rgb_f32().collect();
            let radiance = read_vec3(
                &blob,
                &primitive
                    .get(&gltf::Semantic::Extras("RADIANCE".to_owned()))
                    .unwrap(),
            );
            triangles += reader.read_indices().unwrap().into_u32().count() / 3;
            vertices += positions.len();
            for k in 0..positions.len() {
                // A display vertex at this place (f32: within 1e-6 m) whose radiosity/π is
                // the exported radiance; coincident vertices of neighbouring surfaces may
                // differ, so any one of them must match.
                let p = glam::Vec3::from(positions[k]).as_dvec3();
                let matches = display
                    .positions
                    .iter()
                    .zip(&display.vertex_radiosity)
                    .filter(|(q, _)| q.distance(p) < 1e-6)
                    .any(|(_, b)| {
                        (0..3).all(|c| {
                            let l = b[c] / std::f64::consts::PI;
                            // f32 storage: 2⁻²⁴ relative; 1e-6 absolute for the
                            // clipped COLOR_0 = min(L, 1) (exposure 0).
                            (f64::from(radiance[k][c]) - l).abs() <= 1e-6 * l.max(1.0)
                                && (f64::from(colours[k][c]) - l.min(1.0)).abs() <= 1e-6
                        })
                    });
                assert!(
                    matches,
                    "{:?}: vertex {k} at {p}: no display vertex with radiance {:?}",
                    mesh.name(),
                    radiance[k]
                );
            }
        }
    }
    // Every display triangle is exported once (a vertex shared by k charts is copied k times,
    // so there are at least as many vertices).
    assert_eq!(triangles, display.triangles.len());
    assert!(vertices >= baked.objects.iter().map(|o| o.primitives.len()).sum());
}

#[test]
fn mgf_room_balances_its_lamps_power() {
    let loaded = load("scenes/mgf_room.mgf");
    let scene = &loaded.scene;
    // Progressive refinement with the exact polygon-to-polygon factors: the room has ~1700
    // meshed surfaces (the two-sided shade counts twice), too many for a quick direct solve.
    let mut settings = SolveSettings::default();
    settings.solve.solver = SolverKind::Progressive;
    settings.mesh.elements = 1200;
    settings.form_factor = radiosity::FormFactorMethod::AnalyticPolygon;
    let solved = solve_scene(scene, &settings, &NoProgress).expect("solves");
    let report = report(scene, &solved);
    // The bulb: ed = 1000 lm / (π·0.1²) lm·m⁻² over a ring tessellated into 24 triangles
    // of area ½·r²·sin(15°) each; luminous power = 683 lm/W × Σ_c Y_c Φ_c.
    let ring_area = 24.0 * 0.5 * 0.1f64 * 0.1 * (15f64).to_radians().sin();
    let lumens_expected = 1000.0 / (std::f64::consts::PI * 0.01) * ring_area;
    let emitted = report.totals.emitted_power;
    let lumens = 683.0 * (0.2126 * emitted[0] + 0.7152 * emitted[1] + 0.0722 * emitted[2]);
    // Only rounding separates the two (the MGF colour is normalised to Y = 1).
    assert!(
        (lumens - lumens_expected).abs() < 1e-9 * lumens_expected,
        "{lumens} lm vs {lumens_expected} lm"
    );
    // Emitted = absorbed + escaped (the open side) + unshot, to rounding.
    assert!(report.balance_error() < 1e-9, "{}", report.balance_error());
    // The open front lets some light out, but most of it stays in the room.
    let escaped = report.totals.escaped_power;
    assert!((0..3).all(|c| escaped[c] > 0.0 && escaped[c] < 0.5 * emitted[c]));
    for object in &report.objects {
        assert!(object.radiosity.iter().all(|b| b.is_finite() && *b >= 0.0));
        assert!(object.irradiance.iter().all(|e| e.is_finite() && *e >= 0.0));
    }
}

#[test]
fn trimesh_exported_room_is_lit_as_a_closed_room_should_be() {
    // scenes/trimesh_room.glb is written by trimesh (scenes/tools/make_trimesh_room.py), a
    // third-party glTF exporter; its lamp has emissiveFactor 1, scaled to 20 W·m⁻²·sr⁻¹.
    let options = LoadOptions {
        emission_scale: 20.0,
        ..LoadOptions::default()
    };
    let loaded = load_any_with(Path::new("scenes/trimesh_room.glb"), &options).unwrap();
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    let scene = &loaded.scene;
    assert_eq!(scene.object_names(), ["room", "table", "lamp"]);
    let mut settings = SolveSettings::default();
    settings.mesh.elements = 600;
    let solved = solve_scene(scene, &settings, &NoProgress).unwrap();
    let report = report(scene, &solved);
    // Φ = π·L_e·A = π × 20 × 0.25 m² per channel.
    let phi = std::f64::consts::PI * 20.0 * 0.25;
    for c in 0..3 {
        assert!((report.totals.emitted_power[c] - phi).abs() < 1e-4 * phi);
        // Closed: what is not absorbed is still unshot (≤ 1e-3 of Φ by the tolerance) or
        // leaked through seams by the ray-cast visibility (allow 2 %).
        assert!(report.totals.absorbed_power[c] > 0.97 * phi);
    }
    // Hand calculation: in a closed room everything emitted is absorbed,
    // Σ A_i (1 − ρ_i) H_i = Φ; if the irradiance H were uniform it would be
    // Φ / Σ A_i (1 − ρ_i). The real H varies (brighter under the lamp), so allow 10 %.
    for c in 0..3 {
        let absorbing: f64 = report
            .objects
            .iter()
            .map(|o| o.area * (1.0 - o.reflectance[c]))
            .sum();
        let uniform = phi / absorbing;
        let area: f64 = report.objects.iter().map(|o| o.area).sum();
        let mean: f64 = report
            .objects
            .iter()
            .map(|o| o.area * o.irradiance[c])
            .sum::<f64>()
            / area;
        assert!(
            (mean - uniform).abs() < 0.1 * uniform,
            "channel {c}: mean irradiance {mean} W/m² vs {uniform} W/m²"
        );
    }
}
