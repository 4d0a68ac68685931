//! Light sources against closed forms and their photometric files: the inverse-square cosine
//! law of a point light, an IES file's candela table read back on a sphere of sensors, and
//! the luminous-flux balance of the office example (`scenes/office/office.json`).
//!
//! Photometric values use the project's convention (683 lm/W × Y of linear sRGB, see
//! `radiosity::units`); with white light (R = G = B) the lux of an irradiance is
//! 683 × its channel value, so lx·m² at distance r from a light is its intensity in cd.

mod common;

use common::solve::solve;
use glam::DVec3;
use radiosity::io::scene_file::{load_scene_file, parse_scene_file};
use radiosity::measure::Gatherer;
use radiosity::report::Report;
use radiosity::scene::Scene;
use radiosity::solve::SolverKind;
use radiosity::units::lux_from_irradiance;
use std::path::{Path, PathBuf};

fn office_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/office")
}

/// A scene from scene-file JSON whose goniometric `file`s resolve in the office folder.
fn scene_from(json: &str) -> Scene {
    parse_scene_file(json, &office_dir().join("test.json"))
        .unwrap()
        .scene
}

#[test]
fn point_light_over_a_plane_gives_i_cos_theta_over_d_squared() {
    // 1000 cd (white) at d = 2 m over a 40 m × 40 m plane of reflectance 0.5: an open
    // plane does not light itself, so E = I cos θ / r² with cos θ = d / r exactly. The
    // gather is exact for a point source (one shadow ray, no quadrature): 0.1 % leaves room
    // only for rounding in the unit conversions.
    let (i_cd, d) = (1000.0, 2.0);
    let scene = scene_from(&format!(
        r#"{{
        "materials": [{{ "name": "grey", "reflectance": [0.5, 0.5, 0.5] }}],
        "surfaces": [{{ "object": "plane", "material": "grey",
            "vertices": [[-20, -20, 0], [20, -20, 0], [20, 20, 0], [-20, 20, 0]] }}],
        "lights": [{{ "name": "bulb", "type": "point", "position": [0, 0, {d}],
            "intensity_cd": {i_cd} }}]
    }}"#
    ));
    let solved = solve(&scene, 400, SolverKind::GaussSeidel, 1e-6);
    let gather = Gatherer::new(&solved.mesh, &solved.solution.radiosity, &scene.lights);
    for (x, y) in [
        (0.0, 0.0),
        (0.5, 0.0),
        (1.0, 1.0),
        (2.0, -1.5),
        (-3.0, 4.0),
        (7.0, 2.0),
    ] {
        let r2: f64 = x * x + y * y + d * d;
        let cos = d / r2.sqrt();
        let expected = i_cd * cos / r2;
        let got = lux_from_irradiance(gather.irradiance(DVec3::new(x, y, 0.0), DVec3::Z));
        assert!(
            (got - expected).abs() <= 1e-3 * expected,
            "({x}, {y}): {got} lx vs I cos θ / d² = {expected} lx"
        );
    }
}

/// The candela table of an LM-63 file with one tilt-free block, parsed here independently
/// of the library's reader: (γ angles, C angles, candela[c][γ]) × the file's multiplier.
fn candela_table(text: &str) -> (Vec<f64>, Vec<f64>, Vec<Vec<f64>>) {
    let after = text.split("TILT=NONE").nth(1).expect("TILT=NONE");
    let nums: Vec<f64> = after
        .split_whitespace()
        .map(|t| t.parse().expect("a number"))
        .collect();
    let (multiplier, n_gamma, n_c) = (nums[2], nums[3] as usize, nums[4] as usize);
    let rest = &nums[13..]; // 10 numbers on line 1, 3 on line 2
    let gamma = rest[..n_gamma].to_vec();
    let c = rest[n_gamma..n_gamma + n_c].to_vec();
    let cd = rest[n_gamma + n_c..]
        .chunks(n_gamma)
        .take(n_c)
        .map(|row| row.iter().map(|v| v * multiplier).collect())
        .collect();
    (gamma, c, cd)
}

/// Bilinear in (C, γ) between the file's angles — the interpolation the library documents
/// (`Photometry::intensity`) — for a quadrant-symmetric table (C 0–90°, mirrored).
fn bilinear(gamma: &[f64], c: &[f64], cd: &[Vec<f64>], c_deg: f64, g_deg: f64) -> f64 {
    let c_deg = c_deg.rem_euclid(360.0);
    let c_deg = match c_deg {
        x if x <= 90.0 => x,
        x if x <= 180.0 => 180.0 - x,
        x if x <= 270.0 => x - 180.0,
        x => 360.0 - x,
    };
    let find = |a: &[f64], x: f64| {
        let k = a.iter().rposition(|&v| v <= x).unwrap().min(a.len() - 2);
        (k, (x - a[k]) / (a[k + 1] - a[k]))
    };
    let (i, s) = find(c, c_deg);
    let (j, t) = find(gamma, g_deg);
    let at = |i: usize, j: usize| cd[i][j];
    (at(i, j) * (1.0 - t) + at(i, j + 1) * t) * (1.0 - s)
        + (at(i + 1, j) * (1.0 - t) + at(i + 1, j + 1) * t) * s
}

#[test]
fn ies_candela_table_is_reproduced_on_a_sphere_of_sensors() {
    // The office luminaire, tilted (nadir along (1, 1, −2)) and turned (C0 in the plane of
    // the nadir and +x), at the centre of a sphere of sensors of radius 3 m that face it.
    // Every sensor reads E = I(C, γ) / r², so E r² must be the file's candela (at the
    // file's angles) or their bilinear interpolation (between them) to 0.5 %; where the
    // table is near zero the comparison is absolute, 0.5 % of its peak. The only surface is
    // a small black square 100 m away, behind the luminaire's back.
    let text = std::fs::read_to_string(office_dir().join("recessed_louvre.ies")).unwrap();
    let (gamma, c, cd) = candela_table(&text);
    let peak = cd.iter().flatten().fold(0.0f64, |a, &b| a.max(b));
    let nadir = DVec3::new(1.0, 1.0, -2.0).normalize();
    let c0 = (DVec3::X - nadir * nadir.x).normalize();
    let c90 = c0.cross(nadir);
    let centre = DVec3::new(0.3, -0.2, 1.0);
    let back = centre - 100.0 * nadir;
    let scene = scene_from(&format!(
        r#"{{
        "materials": [{{ "name": "black", "reflectance": [0, 0, 0] }}],
        "surfaces": [{{ "object": "far", "material": "black",
            "vertices": [[{x0}, {y0}, {z}], [{x1}, {y0}, {z}], [{x1}, {y1}, {z}], [{x0}, {y1}, {z}]] }}],
        "lights": [{{ "name": "L", "type": "goniometric", "file": "recessed_louvre.ies",
            "position": [{px}, {py}, {pz}], "direction": [{nx}, {ny}, {nz}],
            "c0": [1, 0, 0] }}]
    }}"#,
        x0 = back.x - 0.05,
        x1 = back.x + 0.05,
        y0 = back.y - 0.05,
        y1 = back.y + 0.05,
        z = back.z,
        px = centre.x,
        py = centre.y,
        pz = centre.z,
        nx = nadir.x,
        ny = nadir.y,
        nz = nadir.z,
    ));
    let solved = solve(&scene, 4, SolverKind::GaussSeidel, 1e-6);
    let gather = Gatherer::new(&solved.mesh, &solved.solution.radiosity, &scene.lights);
    let r = 3.0;
    let mut checked = 0;
    let mut c_angles: Vec<f64> = (0..24).map(|k| k as f64 * 15.0).collect();
    c_angles.extend([7.5, 37.5, 52.5, 100.0, 200.0, 290.0]);
    let mut g_angles = gamma.clone();
    g_angles.extend([2.5, 27.5, 52.5, 62.5, 67.5, 72.5, 87.5]);
    for &cdeg in &c_angles {
        for &g in &g_angles {
            let (cr, gr) = (cdeg.to_radians(), g.to_radians());
            let dir = nadir * gr.cos() + (c0 * cr.cos() + c90 * cr.sin()) * gr.sin();
            let x = centre + r * dir;
            let e = lux_from_irradiance(gather.irradiance(x, -dir));
            let got = e * r * r;
            let expected = bilinear(&gamma, &c, &cd, cdeg, g);
            assert!(
                (got - expected).abs() <= 5e-3 * expected.max(peak * 1e-2),
                "C {cdeg}°, γ {g}°: E r² = {got} cd, table {expected} cd"
            );
            checked += 1;
        }
    }
    assert!(checked > 600);
}

/// ∫ I dω of a quadrant-symmetric table's bilinear interpolant by the midpoint rule on a
/// fine (C, γ) grid (independent of the library's exact integral), lm.
fn table_flux(gamma: &[f64], c: &[f64], cd: &[Vec<f64>]) -> f64 {
    let (nc, ng) = (720, 1800);
    let (dc, dg) = (360.0 / nc as f64, 180.0 / ng as f64);
    let g_max = *gamma.last().unwrap();
    let mut sum = 0.0;
    for i in 0..nc {
        for j in 0..ng {
            let (cdeg, g) = ((i as f64 + 0.5) * dc, (j as f64 + 0.5) * dg);
            if g > g_max {
                continue;
            }
            sum += bilinear(gamma, c, cd, cdeg, g) * g.to_radians().sin();
        }
    }
    sum * dc.to_radians() * dg.to_radians()
}

#[test]
fn office_luminaire_flux_equals_absorbed_plus_escaped_for_every_solver() {
    // Each luminaire's flux is the file's candela table integrated over the sphere × the
    // scene's multiplier; the report's emitted flux must be their sum, and the absorbed +
    // escaped flux must equal it to 1e-3 with every solver at its default tolerance (the
    // progressive solver leaves at most 1e-3 unshot by its stopping rule; the others
    // conserve to their residual). Midpoint quadrature on 720 × 1800 cells is exact to
    // ~1e-6 for this smooth piecewise-bilinear table.
    let path = office_dir().join("office.json");
    let loaded = load_scene_file(&path).unwrap();
    let scene = &loaded.scene;
    let text = std::fs::read_to_string(office_dir().join("recessed_louvre.ies")).unwrap();
    let (gamma, c, cd) = candela_table(&text);
    let file_lm = table_flux(&gamma, &c, &cd);
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    let mut expected_lm = 0.0;
    for (light, entry) in scene.lights.iter().zip(json["lights"].as_array().unwrap()) {
        let multiplier = entry["multiplier"].as_f64().unwrap_or(1.0);
        let lm = file_lm * multiplier;
        assert!(
            (light.luminous_flux() - lm).abs() <= 1e-3 * lm,
            "{}: {} lm vs the file's {lm} lm",
            light.name,
            light.luminous_flux()
        );
        expected_lm += lm;
    }
    assert_eq!(scene.lights.len(), 4);
    for solver in [
        SolverKind::Direct,
        SolverKind::Jacobi,
        SolverKind::GaussSeidel,
        SolverKind::Progressive,
        SolverKind::Hierarchical,
    ] {
        let solved = solve(scene, 800, solver, 1e-3);
        let report = Report::new(&scene.name, &solved.mesh, &solved.solution, "raycast");
        let t = &report.totals;
        assert!(
            (t.emitted_lm - expected_lm).abs() <= 1e-3 * expected_lm,
            "{solver:?}: emitted {} lm vs {expected_lm} lm",
            t.emitted_lm
        );
        let balance = t.absorbed_lm + t.escaped_lm;
        assert!(
            (balance - expected_lm).abs() <= 1e-3 * expected_lm,
            "{solver:?}: absorbed {} + escaped {} lm vs {expected_lm} lm",
            t.absorbed_lm,
            t.escaped_lm
        );
    }
}
