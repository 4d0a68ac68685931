//! Hierarchical radiosity with clustering (`--solver hierarchical`) on the Cornell box:
//! against Mitsuba, energy balance, convergence as ε shrinks, and determinism across thread
//! counts. (The closed furnace cube cases are in tests/furnace.rs.)

use glam::DVec3;
use radiosity::cornell::cornell_box;
use radiosity::pipeline::{solve_scene, SolveSettings, Solved};
use radiosity::progress::NoProgress;
use radiosity::report::Report;
use radiosity::scene::MaterialId;
use radiosity::scene::Scene;
use radiosity::solve::{SolveOptions, SolverKind};
use serde_json::Value;
use std::f64::consts::PI;

fn cornell_reference() -> Value {
    serde_json::from_str(include_str!("reference/cornell_reference.json")).unwrap()
}

/// Mitsuba's per-polygon radiosity of `name` in channel `c` with the light the lamp itself
/// reflects towards it added back (see
/// `the_blocks_tops_match_mitsuba_once_the_lamps_reflection_is_counted`): the value as
/// given plus ρ · H_direct / (π L_e) · (B_lamp − π L_e). Returns (corrected, as given).
fn mitsuba_with_lamp_reflection(scene: &Scene, name: &str, c: usize) -> (f64, f64) {
    let reference = cornell_reference();
    let polygons = reference["per_polygon_area_averaged"]["polygons"]
        .as_array()
        .unwrap();
    let by_name = |name: &str| polygons.iter().find(|p| p["name"] == name).unwrap();
    let lamp_exitance = PI
        * scene
            .surfaces
            .iter()
            .map(|s| scene.material(s))
            .find(|m| m.emission[0] > 0.0)
            .unwrap()
            .emission[c];
    let surface = scene.surfaces.iter().find(|s| s.object == name).unwrap();
    let rho = scene.material(surface).reflectance[c];
    let polygon = by_name(name);
    let raw = polygon["radiosity_avg"][c].as_f64().unwrap();
    let direct = polygon["direct_only_irradiance_avg"][c].as_f64().unwrap();
    let reflected = by_name("light")["radiosity_avg"][c].as_f64().unwrap() - lamp_exitance;
    (raw + rho * direct / lamp_exitance * reflected, raw)
}

fn hierarchical(epsilon: f64) -> SolveSettings {
    let mut settings = SolveSettings {
        solve: SolveOptions {
            solver: SolverKind::Hierarchical,
            tolerance: 1e-6,
            ..Default::default()
        },
        ..Default::default()
    };
    settings.hierarchical.epsilon = epsilon;
    settings
}

fn solve(scene: &Scene, settings: &SolveSettings) -> (Solved, Report) {
    let solved = solve_scene(scene, settings, &NoProgress).unwrap();
    let report = Report::new(&scene.name, &solved.mesh, &solved.solution, "raycast");
    (solved, report)
}

/// Per-polygon relative errors (max over channels) of a Cornell-box report against Mitsuba.
fn cornell_errors(report: &Report) -> Vec<(String, f64)> {
    let reference = cornell_reference();
    reference["per_polygon_area_averaged"]["polygons"]
        .as_array()
        .unwrap()
        .iter()
        .map(|poly| {
            let name = poly["name"].as_str().unwrap();
            let b = report.object(name).unwrap().radiosity;
            let err = (0..3)
                .map(|c| {
                    let want = poly["radiosity_avg"][c].as_f64().unwrap();
                    (b[c] - want).abs() / want
                })
                .fold(0.0, f64::max);
            (name.to_string(), err)
        })
        .collect()
}

#[test]
fn cornell_box_converges_to_mitsuba_as_epsilon_shrinks() {
    let mut means = Vec::new();
    for epsilon in [0.05, 0.01] {
        let (solved, report) = solve(&cornell_box(), &hierarchical(epsilon));
        let errors = cornell_errors(&report);
        let mean = errors.iter().map(|e| e.1).sum::<f64>() / errors.len() as f64;
        let worst =
            errors
                .iter()
                .cloned()
                .fold((String::new(), 0.0), |a, b| if b.1 > a.1 { b } else { a });
        eprintln!(
            "ε = {epsilon}: {} elements, mean {:.2} %, worst {:.2} % ({})",
            solved.mesh.len(),
            100.0 * mean,
            100.0 * worst.1,
            worst.0
        );
        // Energy: emitted = absorbed + escaped (the box is open at the front), to the
        // solver's stopping rule.
        assert!(report.balance_error() < 1e-4, "{}", report.balance_error());
        // Tolerances, measured not tuned per polygon: at ε = 0.01 the mean per-polygon
        // error is 0.80 % and the worst 1.9 % (the short block's side facing the green
        // wall, in the narrow channel between the block and the green wall: 6.0 % before
        // the quick visibility pass stopped lining up with the source's lattice, 4.6 %
        // before links took visibility point by point into their gradient); the bounds
        // allow the reference's own noise (≤ 0.5 %) and about half a per cent more.
        // ε = 0.05 is coarse on purpose.
        if epsilon == 0.01 {
            assert!(mean < 0.012, "mean {mean}");
            assert!(worst.1 < 0.025, "{worst:?}");
        }
        means.push(mean);
    }
    // Convergence: the smaller tolerance is closer to the reference on average.
    assert!(means[1] < means[0], "{means:?}");
}

/// The tops of the Cornell box's blocks, lit straight from the lamp, against Mitsuba's
/// per-polygon values with the light that the lamp itself reflects added back.
///
/// By all the evidence below, the reference's per-polygon irradiance leaves out the light
/// the lamp itself reflects towards each polygon (as if its indirect probe rays that met
/// the lamp counted nothing there), though the lamp's own radiosity in the same file
/// includes that reflection, B_lamp = π L_e + ρ H = 53.878 against π L_e = 53.407.
/// What a polygon misses is its form factor to the lamp (with visibility), which the
/// file's direct-only irradiance gives as H_direct / (π L_e), times the lamp's reflected
/// radiosity, B_lamp − π L_e: 0.77 % of the tall block's top, 0.74 % of the short one's,
/// 0.5 % of the floor and walls, nothing on the ceiling and on faces the lamp does not
/// light. The evidence (tests/reference/PROVENANCE.md): gathering our own solution's
/// radiosities by Monte Carlo from the tall block's top, split by the surface each ray
/// meets, gives the reference's indirect irradiance to 0.3 % once the lamp's share
/// (0.024 W·m⁻², 5.8 % of it) is left out; the floor's to 0.01 %, the short block's top's to
/// 0.5 %. And in the 256 × 256 render of the same file, which sees the lamp's reflection,
/// a region of the floor (`floor_front_left`) has ours within 0.15 %, where the floor's
/// per-polygon value has it 0.9 % high.
#[test]
fn the_blocks_tops_match_mitsuba_once_the_lamps_reflection_is_counted() {
    let scene = cornell_box();
    let (_, report) = solve(&scene, &hierarchical(0.01));
    for name in ["tall_block_top", "short_block_top"] {
        let ours = report.object(name).unwrap();
        for c in 0..3 {
            let (want, raw) = mitsuba_with_lamp_reflection(&scene, name, c);
            let rel = (ours.radiosity[c] - want) / want;
            eprintln!(
                "{name} channel {c}: {:+.2} % ({:+.2} % against the value as given)",
                100.0 * rel,
                100.0 * (ours.radiosity[c] - raw) / raw
            );
            // 0.4 %: the reference's standard error on these faces is 0.08–0.10 % (three
            // standard errors about 0.3 %), and at ε = 0.01 the solve is within about 0.2 % on faces lit
            // straight from the lamp (measured −0.20 to +0.09 %; +0.67 to +0.81 % on the
            // tall block's top against the value as given).
            assert!(
                rel.abs() < 0.004,
                "{name} channel {c}: {} vs {want} ({:+.2} %)",
                ours.radiosity[c],
                100.0 * rel
            );
        }
    }
}

/// Möller–Trumbore: whether the open segment from `x` to `y` crosses triangle `t`.
fn segment_crosses(x: DVec3, y: DVec3, t: [DVec3; 3]) -> bool {
    let (d, e1, e2) = (y - x, t[1] - t[0], t[2] - t[0]);
    let p = d.cross(e2);
    let det = p.dot(e1);
    if det.abs() < 1e-15 {
        return false;
    }
    let s = x - t[0];
    let u = s.dot(p) / det;
    let q = s.cross(e1);
    let v = d.dot(q) / det;
    let along = e2.dot(q) / det;
    u >= 0.0 && v >= 0.0 && u + v <= 1.0 && along > 1e-9 && along < 1.0 - 1e-9
}

/// Midpoints and areas of an n × n bilinear grid over a planar quad.
fn quad_cells(q: &[DVec3], n: usize) -> Vec<(DVec3, f64)> {
    let at = |s: f64, t: f64| {
        q[0] * ((1.0 - s) * (1.0 - t))
            + q[1] * (s * (1.0 - t))
            + q[2] * (s * t)
            + q[3] * ((1.0 - s) * t)
    };
    let h = 1.0 / n as f64;
    let mut cells = Vec::with_capacity(n * n);
    for i in 0..n {
        for j in 0..n {
            let (s, t) = (i as f64 * h, j as f64 * h);
            let [a, b, c, d] = [at(s, t), at(s + h, t), at(s + h, t + h), at(s, t + h)];
            let area = 0.5 * (c - a).cross(d - b).length();
            cells.push((at(s + 0.5 * h, t + 0.5 * h), area));
        }
    }
    cells
}

/// Direct light on the Cornell box's floor, in the two blocks' shadows and penumbrae: the
/// hierarchical solve against an independent brute-force quadrature of the same integral,
/// H̄ = (1/A) ∫_floor ∫_lamp π L_e cos θ_x cos θ_y V / (π r²) dy dx (150 × 150 floor cells ×
/// 12 × 12 lamp cells, visibility by exact segment–triangle tests against the blocks'
/// faces). Only the floor reflects, so its irradiance is the direct light alone.
///
/// Leaf by leaf too: each floor leaf's irradiance against the brute force's mean over the
/// cells it holds.
///
/// Regression: the quick visibility pass aimed every receiver point at one column of the
/// lamp's sub-areas (each k-th), and missed the part of a penumbra that column did not
/// cross: the floor read 1.1 % bright here (1.3 % in the whole box's direct light, 2.2 %
/// against Mitsuba's direct-only value, whose own Monte Carlo error is 0.4 %), 0.02 %
/// after, 0.19 % since links take visibility point by point.
#[test]
fn direct_light_on_the_cornell_floor_matches_a_brute_force_integral() {
    let mut scene = cornell_box();
    let floor = scene
        .surfaces
        .iter()
        .position(|s| s.object == "floor")
        .unwrap();
    let mut floor_material = scene.material(&scene.surfaces[floor]).clone();
    floor_material.name = "floor only".into();
    for m in &mut scene.materials {
        m.reflectance = [0.0; 3];
    }
    scene.surfaces[floor].material = MaterialId(scene.materials.len() as u32);
    scene.materials.push(floor_material);

    let (solved, report) = solve(&scene, &hierarchical(0.02));
    let got = report.object("floor").unwrap().irradiance;

    let lamp = scene
        .surfaces
        .iter()
        .find(|s| scene.material(s).emission[0] > 0.0)
        .unwrap();
    let exitance = scene.material(lamp).emission.map(|l| PI * l);
    let lamp_cells = quad_cells(lamp.polygon.vertices(), 12);
    let lamp_normal = lamp.polygon.normal();
    let blockers: Vec<[DVec3; 3]> = scene
        .surfaces
        .iter()
        .filter(|s| s.object.contains("block"))
        .flat_map(|s| {
            let v = s.polygon.vertices();
            (1..v.len() - 1).map(move |i| [v[0], v[i], v[i + 1]])
        })
        .collect();
    let floor_polygon = &scene.surfaces[floor].polygon;
    let floor_normal = floor_polygon.normal();
    let floor_cells = quad_cells(floor_polygon.vertices(), 150);
    // The floor's leaves, to bin the cells by the leaf that holds their midpoint.
    let mesh = &solved.mesh;
    let leaves: Vec<usize> = (0..mesh.elements.len())
        .filter(|&i| {
            mesh.objects[mesh.surfaces[mesh.elements[i].surface as usize].object as usize]
                == "floor"
        })
        .collect();
    let holds = |i: usize, x: DVec3| {
        let e = &mesh.elements[i];
        let c: Vec<DVec3> = e
            .corners
            .iter()
            .map(|&v| mesh.vertices[v as usize])
            .collect();
        (0..c.len()).all(|k| {
            let (a, b) = (c[k], c[(k + 1) % c.len()]);
            (b - a).cross(x - a).dot(e.normal) >= 0.0
        })
    };
    let mut per_leaf = vec![(0.0, 0.0); mesh.elements.len()];
    let (mut integral, mut area) = (0.0, 0.0);
    for &(x, ax) in &floor_cells {
        let mut f = 0.0;
        for &(y, ay) in &lamp_cells {
            let d = y - x;
            let r2 = d.length_squared();
            let cos_x = floor_normal.dot(d);
            let cos_y = -lamp_normal.dot(d);
            if cos_x <= 0.0 || cos_y <= 0.0 || blockers.iter().any(|&t| segment_crosses(x, y, t)) {
                continue;
            }
            f += cos_x * cos_y * ay / (PI * r2 * r2);
        }
        integral += f * ax;
        area += ax;
        if let Some(&i) = leaves.iter().find(|&&i| holds(i, x)) {
            per_leaf[i].0 += f * ax;
            per_leaf[i].1 += ax;
        }
    }
    for c in 0..3 {
        let want = exitance[c] * integral / area;
        let rel = (got[c] - want) / want;
        // 0.5 %: ε bounds each link's error at 2 % of the floor's irradiance, with either
        // sign; over the floor's thousands of leaves an unbiased solve stays within a small
        // part of that (measured 0.19 %), and the brute force itself is converged to better
        // than 0.1 % (the same integral with 200 × 200 × 24 × 24 cells differs by 0.02 %).
        assert!(
            rel.abs() < 0.005,
            "channel {c}: {} vs {want} ({:+.2} %)",
            got[c],
            100.0 * rel
        );
    }
    // Leaf by leaf (red alone: in every channel the direct light is the lamp's exitance
    // in that channel times the same form factors): the mean absolute difference
    // between each leaf's irradiance and the brute force's mean over the cells it holds,
    // weighted by those cells' area.
    let (mut l1, mut binned) = (0.0, 0.0);
    for &i in &leaves {
        let (sum, cells_area) = per_leaf[i];
        if cells_area > 0.0 {
            let want = exitance[0] * sum / cells_area;
            l1 += cells_area * (solved.solution.irradiance[i][0] - want).abs();
            binned += cells_area;
        }
    }
    let mean = exitance[0] * integral / area;
    let l1 = l1 / binned / mean;
    // 1 %, half of ε: each link's error is bounded by ε of the floor's irradiance, and
    // over the floor's leaves such errors partly cancel; what exceeds it is light a leaf
    // cannot see at all (measured 0.78 %; 1.45 % when the receiver's 2 × 2 points all in an
    // umbra left a partly lit leaf dark, its corners not looked at). The binning adds its
    // own scatter: a leaf's cells are those whose midpoints it holds.
    assert!(
        l1 < 0.01,
        "leaf by leaf: mean absolute difference {:.3} % of the mean",
        100.0 * l1
    );
}

/// A scene of the named polygons, each (vertices, object name, material index).
fn scene_of(
    name: &str,
    materials: Vec<radiosity::scene::Material>,
    polygons: impl Iterator<Item = (Vec<DVec3>, &'static str, u32)>,
) -> Scene {
    Scene {
        name: name.into(),
        materials,
        surfaces: polygons
            .map(|(v, object, m)| radiosity::scene::Surface {
                object: object.into(),
                group: String::new(),
                material: MaterialId(m),
                polygon: radiosity::geometry::Polygon::new(v).unwrap(),
                origin: Default::default(),
            })
            .collect(),
        lights: Vec::new(),
        camera: None,
    }
}

/// The form factor from a point x with normal n to a convex polygon, by Lambert's contour
/// formula: F = (1/2π) Σ_i γ_i n · (r_i × r_{i+1}) / |r_i × r_{i+1}|, r_i = v_i − x, γ_i the
/// angle between r_i and r_{i+1}.
fn lambert(x: DVec3, n: DVec3, polygon: &[DVec3]) -> f64 {
    let mut sum = 0.0;
    for i in 0..polygon.len() {
        let (a, b) = (polygon[i] - x, polygon[(i + 1) % polygon.len()] - x);
        let c = a.cross(b);
        let len = c.length();
        if len > 0.0 {
            sum += a.angle_between(b) * n.dot(c) / len;
        }
    }
    (sum / (2.0 * PI)).abs()
}

/// The part of the convex polygon `polygon` on the front side of the plane through `x`
/// with normal `n` (Sutherland–Hodgman): what a point there can see of it.
fn clip_to_hemisphere(x: DVec3, n: DVec3, polygon: &[DVec3]) -> Vec<DVec3> {
    let mut out = Vec::new();
    for i in 0..polygon.len() {
        let (a, b) = (polygon[i], polygon[(i + 1) % polygon.len()]);
        let (ha, hb) = (n.dot(a - x), n.dot(b - x));
        if ha >= 0.0 {
            out.push(a);
        }
        if (ha >= 0.0) != (hb >= 0.0) {
            out.push(a + (b - a) * (ha / (ha - hb)));
        }
    }
    out
}

/// A white sphere in a black box open on one side whose five walls glow with radiance 1:
/// nothing comes back to the sphere, so at each of its points the irradiance is π times
/// 1 − F(x → opening), the form factor to the opening by Lambert's formula (clipped to the
/// point's hemisphere), independent of the solver. Tessellated into 3,968 triangles far
/// smaller than the minimum element (min_area_fraction 3·10⁻⁴), it receives in clusters of
/// element size: its mean irradiance must match the integral over its triangles, and the
/// links must grow less than its triangles (the same sphere at 960 triangles). Before, every
/// triangle received on its own: a Cornell box with two spheres of 9,800 triangles each took
/// 69 s and 1.92 M links at the default settings (0.8 s and 76,452 links without them).
#[test]
fn a_finely_tessellated_sphere_receives_as_elements_of_the_minimum_size() {
    use radiosity::scene::Material;
    let p = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
    let walls = [
        [p(0., 0., 0.), p(0., 0., 1.), p(1., 0., 1.), p(1., 0., 0.)],
        [p(0., 1., 0.), p(1., 1., 0.), p(1., 1., 1.), p(0., 1., 1.)],
        [p(0., 0., 0.), p(1., 0., 0.), p(1., 1., 0.), p(0., 1., 0.)],
        [p(0., 0., 0.), p(0., 1., 0.), p(0., 1., 1.), p(0., 0., 1.)],
        [p(1., 0., 0.), p(1., 0., 1.), p(1., 1., 1.), p(1., 1., 0.)],
    ];
    let opening = [p(0., 0., 1.), p(0., 1., 1.), p(1., 1., 1.), p(1., 0., 1.)];
    let scene = |rings: usize| {
        scene_of(
            "sphere in a glowing box",
            vec![
                Material::new("glow", [0.0; 3], [1.0; 3]),
                Material::new("white", [0.5; 3], [0.0; 3]),
            ],
            walls.iter().map(|v| (v.to_vec(), "walls", 0)).chain(
                radiosity::generate::uv_sphere(p(0.45, 0.4, 0.6), 0.15, rings)
                    .iter()
                    .map(|t| (t.to_vec(), "sphere", 1)),
            ),
        )
    };
    let mut settings = hierarchical(0.01);
    settings.hierarchical.min_area_fraction = 3e-4;
    let sphere_irradiance = |solved: &Solved| {
        let (mut sum, mut area) = (0.0, 0.0);
        for (e, h) in solved.mesh.elements.iter().zip(&solved.solution.irradiance) {
            if solved.mesh.objects[solved.mesh.surfaces[e.surface as usize].object as usize]
                == "sphere"
            {
                sum += h[0] * e.area;
                area += e.area;
            }
        }
        sum / area
    };
    let fine = scene(32);
    assert_eq!(fine.surfaces.len(), 5 + 3968);
    let (coarse_solved, _) = solve(&scene(16), &settings);
    let (fine_solved, _) = solve(&fine, &settings);
    let (mut expected, mut area) = (0.0, 0.0);
    for s in &fine.surfaces[5..] {
        let v = s.polygon.vertices();
        let (centroid, n) = ((v[0] + v[1] + v[2]) / 3.0, (v[1] - v[0]).cross(v[2] - v[0]));
        let a = 0.5 * n.length();
        let n = n / (2.0 * a);
        let seen = clip_to_hemisphere(centroid, n, &opening);
        let f = if seen.len() >= 3 {
            lambert(centroid, n, &seen)
        } else {
            0.0
        };
        expected += a * PI * (1.0 - f);
        area += a;
    }
    let expected = expected / area;
    let got = sphere_irradiance(&fine_solved);
    // Tolerance 0.2 %: the walls are uniform and unoccluded, so the links carry no visibility
    // error and what remains is each cluster's four sample points against the centroid sum
    // over the triangles (measured 0.01 %).
    assert!(
        (got - expected).abs() <= 0.002 * expected,
        "sphere's mean irradiance {got} W/m², Lambert's integral {expected} W/m²"
    );
    let links = |s: &Solved| s.hierarchy.as_ref().unwrap().links as f64;
    let growth = links(&fine_solved) / links(&coarse_solved);
    // Four times the triangles. With one receiver per triangle the links grew 4.5 times
    // (22 k to 99 k); with element-sized receivers 2.1 times (17.8 k to 37.8 k), the sphere
    // opening down to single triangles as a source for the walls; now that an element-sized
    // source opens only for a receiver that cannot split, 1.6 times (16.3 k to 26.3 k: the
    // walls' pieces near the sphere, not its triangles). The bound lies between the two.
    assert!(
        growth <= 1.85,
        "links grew {growth:.2} times from 960 to 3,968 triangles ({} and {})",
        links(&coarse_solved),
        links(&fine_solved)
    );
}

/// A thin corrugated wall of tiny triangles (both faces, 1 cm apart) standing on a glowing floor panel
/// that lies in front of it: nothing reflects, so the front's mean irradiance is π L times
/// its triangles' form factors to the panel (Lambert's formula over 16 points of each
/// triangle, independent of the solver), and the back, facing away, gets nothing. The
/// wall's triangles are far smaller than the minimum element, so they receive in clusters
/// of element size; such a cluster must not hold both faces, and must open where it touches
/// the panel.
///
/// Regression (measured in the Šibenik cathedral, 73,564 triangles, its stained glass
/// glowing, against the solve with one receiver per triangle): element-sized clusters whose
/// members faced opposite ways shared their light (the stone tracery of the rose window
/// read 48 % dark); and beside the glowing glass the mean of a cluster's four sample points
/// missed the bright rim (24 % dark). Here the gain is small (+1.08 % to +0.69 %).
#[test]
fn a_thin_tessellated_wall_on_a_glowing_floor_is_lit_on_its_front_alone() {
    use radiosity::scene::Material;
    let p = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
    let (nx, ny) = (40, 20);
    let (width, height, thickness) = (1.0, 0.5, 0.01);
    // Triangles of the face at depth z, facing +z when `front`.
    let face = |z: f64, front: bool| {
        let mut tris = Vec::new();
        for i in 0..nx {
            for j in 0..ny {
                let (x0, x1) = (
                    width * i as f64 / nx as f64,
                    width * (i + 1) as f64 / nx as f64,
                );
                let (y0, y1) = (
                    height * j as f64 / ny as f64,
                    height * (j + 1) as f64 / ny as f64,
                );
                // Corrugated 1 mm deep (waves of 7 and 9 cm along x and y), so that the
                // triangles do not merge back into a plane.
                let at =
                    |x: f64, y: f64| p(x, y, z + 0.001 * (2.0 * PI * (x / 0.07 + y / 0.09)).sin());
                let (a, b, c, d) = (at(x0, y0), at(x1, y0), at(x1, y1), at(x0, y1));
                if front {
                    tris.push(vec![a, b, c]);
                    tris.push(vec![a, c, d]);
                } else {
                    tris.push(vec![a, c, b]);
                    tris.push(vec![a, d, c]);
                }
            }
        }
        tris
    };
    let front = face(0.0, true);
    let back = face(-thickness, false);
    let panel = vec![p(0., 0., 0.), p(0., 0., 0.5), p(1., 0., 0.5), p(1., 0., 0.)];
    let radiance = 1.0;
    let scene = scene_of(
        "thin wall on a glowing floor",
        vec![
            Material::new("black", [0.0; 3], [0.0; 3]),
            Material::new("glow", [0.0; 3], [radiance; 3]),
        ],
        std::iter::once((panel.clone(), "panel", 1))
            .chain(front.iter().map(|t| (t.clone(), "front", 0)))
            .chain(back.iter().map(|t| (t.clone(), "back", 0))),
    );
    let mut settings = hierarchical(0.01);
    settings.hierarchical.min_area_fraction = 3e-3;
    let (_, report) = solve(&scene, &settings);
    let (mut expected, mut area) = (0.0, 0.0);
    for t in &front {
        let a = 0.5 * (t[1] - t[0]).cross(t[2] - t[0]).length();
        let mut f = 0.0;
        for i in 0..4 {
            for j in 0..4 - i {
                // 10 points of a 4-level barycentric lattice, at the sub-triangles' centroids.
                let (u, v) = ((i as f64 + 1.0 / 3.0) / 4.0, (j as f64 + 1.0 / 3.0) / 4.0);
                let x = t[0] + (t[1] - t[0]) * u + (t[2] - t[0]) * v;
                let n = (t[1] - t[0]).cross(t[2] - t[0]).normalize();
                let seen = clip_to_hemisphere(x, n, &panel);
                if seen.len() >= 3 {
                    f += lambert(x, n, &seen);
                }
            }
        }
        expected += a * PI * radiance * f / 10.0;
        area += a;
    }
    let expected = expected / area;
    let lit = report.object("front").unwrap().irradiance[0];
    let dark = report.object("back").unwrap().irradiance[0];
    // What remains is the far clusters' four sample points against the lattice over every
    // triangle, and the corrugation's own shading of the grazing light, which the reference
    // leaves out (measured +0.69 %; +1.08 % when the clusters touching the panel received
    // as one). The back must read nothing (measured 6.5e-5 of the front, the clusters'
    // gradients at the rim).
    assert!(
        (lit - expected).abs() <= 0.01 * expected,
        "front: {lit:.5} W/m² against Lambert's integral {expected:.5}"
    );
    assert!(
        dark <= 1e-3 * expected,
        "back: {dark:.5} W/m², front {lit:.5}"
    );
}

/// A dim lamp on the floor against a long wall lit by a bright panel: the irradiance of
/// every element of the wall against Lambert's formula integrated over it (16 × 16 cells),
/// and the wall's power against the same over the wall (2000 × 300 cells). Nothing
/// reflects, so the wall's irradiance is the two sources' direct light.
///
/// Regression: the link from the lamp to the whole wall was accepted, its 4 × 4 receiver
/// points all too far along the wall to see the bright spot above the lamp (the fit's
/// misfit at the points was small), so the wall was never refined there and lost 80 % of
/// the lamp's light (an element 20 % of the wall's mean irradiance off, the wall 2.9 % low).
/// In the furnished rooms of the scale benchmark a wall's bottom strip beside a floor piece
/// gathered links summing to 0.3 of its hemisphere, and 1 to 4 % of the light escaped from
/// the closed rooms. Now a receiver whose points are further apart than the source's size
/// and distance opens before it is linked.
#[test]
fn a_dim_lamp_beside_a_long_wall_lights_the_wall_above_it() {
    use radiosity::geometry::Polygon;
    use radiosity::scene::{Material, Surface};
    let p = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
    // Wall in the plane z = 0 facing +z, 20 m × 3 m; lamp on the floor, 2 m × 2 m, facing up,
    // its edge along the wall's foot at x = 9..11; a panel facing the wall 10 m away gives
    // it 27 times the lamp's light, so that the lamp's link is a small part of the wall's.
    let wall = [p(0., 0., 0.), p(20., 0., 0.), p(20., 3., 0.), p(0., 3., 0.)];
    let lamp = [p(9., 0., 0.), p(9., 0., 2.), p(11., 0., 2.), p(11., 0., 0.)];
    let panel = [
        p(0., 0.5, 10.),
        p(0., 3.5, 10.),
        p(20., 3.5, 10.),
        p(20., 0.5, 10.),
    ];
    let (lamp_radiance, panel_radiance) = (0.5, 3.0);
    let scene = Scene {
        name: "lamp beside a wall".into(),
        materials: vec![
            Material::new("wall", [0.0; 3], [0.0; 3]),
            Material::new("lamp", [0.0; 3], [lamp_radiance; 3]),
            Material::new("panel", [0.0; 3], [panel_radiance; 3]),
        ],
        surfaces: [("wall", wall, 0), ("lamp", lamp, 1), ("panel", panel, 2)]
            .iter()
            .map(|(name, v, m)| Surface {
                object: (*name).into(),
                group: String::new(),
                material: MaterialId(*m),
                polygon: Polygon::new(v.to_vec()).unwrap(),
                origin: Default::default(),
            })
            .collect(),
        lights: Vec::new(),
        camera: None,
    };
    // The exact irradiance at a point of the wall, E = π L per unit of form factor.
    let irradiance = |x: DVec3| {
        PI * (lamp_radiance * lambert(x, DVec3::Z, &lamp)
            + panel_radiance * lambert(x, DVec3::Z, &panel))
    };
    let epsilon = 0.02;
    let (solved, _) = solve(&scene, &hierarchical(epsilon));
    let on_wall: Vec<(Vec<DVec3>, f64, f64)> = solved
        .mesh
        .elements
        .iter()
        .zip(&solved.solution.irradiance)
        .filter(|(e, _)| e.normal.z > 0.5)
        .map(|(e, h)| {
            let corners = e.corners.iter().map(|&v| solved.mesh.vertices[v as usize]);
            (corners.collect(), e.area, h[0])
        })
        .collect();
    let wall_power: f64 = on_wall.iter().map(|(_, a, h)| a * h).sum();
    let (nx, ny) = (2000, 300);
    let (dx, dy) = (20.0 / nx as f64, 3.0 / ny as f64);
    let mut want_power = 0.0;
    for i in 0..nx {
        for j in 0..ny {
            let x = p((i as f64 + 0.5) * dx, (j as f64 + 0.5) * dy, 0.0);
            want_power += irradiance(x) * dx * dy;
        }
    }
    let mean = want_power / 60.0;
    let mut worst: f64 = 0.0;
    for (corners, area, h) in &on_wall {
        assert_eq!(corners.len(), 4, "the wall's elements are quads");
        let exact = quad_cells(corners, 16)
            .iter()
            .map(|&(x, a)| irradiance(x) * a)
            .sum::<f64>()
            / area;
        worst = worst.max((h - exact).abs() / mean);
    }
    eprintln!(
        "{} wall elements, worst {:.2} % of the mean irradiance; wall {wall_power:.4} W vs \
         {want_power:.4} W",
        on_wall.len(),
        100.0 * worst
    );
    // 3 ε of the wall's mean irradiance per element: the oracle bounds each link's error by
    // ε times its receiver's surface irradiance, and an element gathers each source through
    // links at one level or more (measured worst 4.2 %, 20 % before). The wall's power, a
    // sum over all its elements, within ε (measured 0.002 %, 2.9 % low before). The integrals
    // are converged to better than 0.1 % (8 × 8 and 1000 × 150 cells agree to 0.01 %).
    assert!(
        worst < 3.0 * epsilon,
        "an element is {:.2} % off",
        100.0 * worst
    );
    assert!(
        (wall_power - want_power).abs() < epsilon * want_power,
        "wall: {wall_power} W vs {want_power} W"
    );
}

/// The memory limit stops refinement, as the summary warns: with a limit of a third of what
/// the Cornell box's hierarchy takes at ε = 0.02, refinement stops short with fewer links,
/// and the estimate checked against the limit counts the sources' prepared points (about
/// 2.6 kB per polygon node that has been a source, most of the hierarchy's memory beside the
/// links: a flat 400 bytes per node before, an eighth to a quarter of the measured peak).
#[test]
fn refinement_stops_at_the_memory_limit() {
    use radiosity::coupling::hierarchical::HierarchicalOptions;
    use radiosity::formfactor::FormFactorMethod;
    use radiosity::solve::NoObserver;
    let run = |memory_limit: u64| {
        radiosity::solve::hierarchical::solve(
            &cornell_box(),
            FormFactorMethod::Raycast,
            HierarchicalOptions {
                memory_limit,
                ..HierarchicalOptions::default()
            },
            &SolveOptions {
                solver: SolverKind::Hierarchical,
                ..Default::default()
            },
            &mut NoObserver,
            &NoProgress,
        )
        .unwrap()
    };
    let free = run(u64::MAX);
    assert!(!free.capped);
    // Nodes and links alone, at the old flat rates: the estimate is well above them.
    let flat = free.nodes as u64 * 400 + free.links as u64 * 48;
    assert!(free.bytes > 2 * flat, "{} vs {flat}", free.bytes);
    let capped = run(free.bytes / 3);
    assert!(capped.capped);
    assert!(
        capped.links < free.links,
        "{} vs {}",
        capped.links,
        free.links
    );
    // The limit is checked before each round of candidates, so the last round may pass it;
    // it does not run on unchecked.
    assert!(
        capped.bytes < free.bytes,
        "{} vs {}",
        capped.bytes,
        free.bytes
    );
}

/// The Cornell box with every vertex multiplied by `scale` (a model in millimetres is the
/// same room at `scale` = 1000).
fn cornell_scaled(scale: f64) -> Scene {
    let mut scene = cornell_box();
    for surface in &mut scene.surfaces {
        let vertices = surface
            .polygon
            .vertices()
            .iter()
            .map(|v| *v * scale)
            .collect();
        surface.polygon = radiosity::geometry::Polygon::new(vertices).unwrap();
    }
    scene
}

/// Radiosity is intensive: a room drawn in millimetres or in kilometres, with the same
/// emitted radiance and reflectances, has the same radiosity everywhere, and its emitted
/// and absorbed power scale with its area. Real interiors come in any unit; a length in
/// metres hidden anywhere in the pipeline (a ray offset, a merging tolerance, a minimum
/// element or sample spacing) would change the links and move these results by far more
/// than the tolerance. Measured: every object within 2.1e-9 of the metre-sized box at both
/// scales (the rounding of the scaled coordinates, carried through f32 vertices in the ray
/// tracer); 1e-6 leaves a factor of about 500 over that.
#[test]
fn the_solution_does_not_depend_on_the_unit_of_length() {
    let (_, metres) = solve(&cornell_box(), &hierarchical(0.05));
    for scale in [1e3, 1e-3] {
        let (_, scaled) = solve(&cornell_scaled(scale), &hierarchical(0.05));
        assert_eq!(scaled.objects.len(), metres.objects.len());
        for object in &metres.objects {
            let other = scaled.object(&object.name).unwrap();
            for c in 0..3 {
                let (want, got) = (object.radiosity[c], other.radiosity[c]);
                assert!(
                    (got - want).abs() <= 1e-6 * want,
                    "{} at scale {scale}, channel {c}: {got} W/m² against {want}",
                    object.name
                );
            }
        }
        // Emitted power is the area times πL exactly; what is absorbed carries the solution.
        let powers = [
            (
                "emitted",
                metres.totals.emitted_power,
                scaled.totals.emitted_power,
                1e-9,
            ),
            (
                "absorbed",
                metres.totals.absorbed_power,
                scaled.totals.absorbed_power,
                1e-6,
            ),
        ];
        for (what, at_metres, at_scale, tolerance) in powers {
            for c in 0..3 {
                let (want, got) = (at_metres[c] * scale * scale, at_scale[c]);
                assert!(
                    (got - want).abs() <= tolerance * want,
                    "{what} at scale {scale}, channel {c}: {got} W against {want}"
                );
            }
        }
    }
}

#[test]
fn one_and_two_threads_give_the_same_bits() {
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                solve(&cornell_box(), &hierarchical(0.05))
                    .0
                    .solution
                    .radiosity
            })
    };
    let (one, two) = (run(1), run(2));
    assert_eq!(one.len(), two.len());
    for (a, b) in one.iter().zip(&two) {
        for c in 0..3 {
            assert_eq!(a[c].to_bits(), b[c].to_bits());
        }
    }
}

/// Records what a solve reports to its progress display.
#[derive(Default)]
struct Recorder {
    events: std::sync::Mutex<Vec<String>>,
    examined: std::sync::atomic::AtomicU64,
}

impl radiosity::progress::Progress for Recorder {
    fn start(&self, stage: &str, total: u64) {
        self.events
            .lock()
            .unwrap()
            .push(format!("start {stage} {total}"));
    }
    fn inc(&self, n: u64) {
        self.examined
            .fetch_add(n, std::sync::atomic::Ordering::Relaxed);
    }
    fn message(&self, text: &str) {
        self.events.lock().unwrap().push(format!("message {text}"));
    }
    fn finish(&self) {
        self.events.lock().unwrap().push("finish".into());
    }
}

#[test]
fn linking_is_shown_stage_by_stage_with_the_links_kept() {
    // The refinement (most of a large scene's time) reports each of its three stages as a
    // "linking" stage without a total (its work is not known ahead), with the count of
    // candidate links examined, the links kept and, from the second stage on, an estimate
    // of the linking time left (`progress::LinkingEta`); the first stage has none, and each
    // stage's last message carries its final link count alone.
    let recorder = Recorder::default();
    let solved = solve_scene(&cornell_box(), &hierarchical(0.05), &recorder).unwrap();
    let events = recorder.events.into_inner().unwrap();
    let starts: Vec<&String> = events.iter().filter(|e| e.starts_with("start")).collect();
    assert_eq!(starts.len(), 3, "{starts:?}");
    assert!(starts.iter().all(|e| *e == "start linking 0"), "{starts:?}");
    assert_eq!(events.iter().filter(|e| *e == "finish").count(), 3);
    let with_eta = |stage: usize| {
        events.iter().any(|e| {
            e.starts_with(&format!("message stage {stage} of 3,")) && e.contains("linking eta ")
        })
    };
    assert!(!with_eta(1), "an estimate in the first stage");
    assert!((2..=3).all(with_eta), "{events:?}");
    for (i, e) in events.iter().enumerate() {
        if e == "finish" {
            assert!(events[i - 1].ends_with(" links kept"), "{}", events[i - 1]);
        }
    }
    let last = events
        .iter()
        .rev()
        .find(|e| e.starts_with("message"))
        .unwrap();
    assert!(last.contains("stage 3 of 3, ε 0.050"), "{last}");
    let links: usize = last
        .split(", ")
        .last()
        .and_then(|t| t.strip_suffix(" links kept"))
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("{last}"));
    // The links kept at the end of the last round are the solution's links; at least one
    // candidate was examined per link.
    let mesh_links = radiosity::solve::hierarchical::solve(
        &cornell_box(),
        radiosity::formfactor::FormFactorMethod::Raycast,
        hierarchical(0.05).hierarchical,
        &hierarchical(0.05).solve,
        &mut radiosity::solve::NoObserver,
        &NoProgress,
    )
    .unwrap()
    .links;
    assert_eq!(links, mesh_links);
    assert!(recorder.examined.into_inner() >= links as u64);
    assert!(!solved.mesh.elements.is_empty());
}

#[test]
fn luminaires_light_the_office_as_the_classic_solver_does() {
    // The office example: four IES luminaires (no emitting polygons), so every watt reaches
    // the surfaces through the first shot. Reference: Gauss–Seidel on a fine classic mesh
    // (converged to 1e-6), an independent discretisation of the same equation.
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/office/office.json");
    let scene = radiosity::io::scene_file::load_scene_file(&path)
        .unwrap()
        .scene;
    let (_, ours) = solve(&scene, &hierarchical(0.02));
    let mut classic = SolveSettings {
        solve: SolveOptions {
            solver: SolverKind::GaussSeidel,
            tolerance: 1e-6,
            ..Default::default()
        },
        ..Default::default()
    };
    classic.mesh.elements = 4000;
    let (_, reference) = solve(&scene, &classic);
    for o in &reference.objects {
        let h = ours.object(&o.name).unwrap().irradiance;
        // Tolerance 2 %: ε = 0.02 per link, and the classic mesh's own discretisation error
        // (measured on the floor grid at 0.75 m: 640.0 lx against 642.2 lx, 0.3 %).
        for c in 0..3 {
            let rel = (h[c] - o.irradiance[c]).abs() / o.irradiance[c];
            assert!(
                rel < 0.02,
                "{}[{c}]: {} vs {}",
                o.name,
                h[c],
                o.irradiance[c]
            );
        }
    }
}

mod random_rooms {
    use super::*;
    use glam::DVec3;
    use proptest::prelude::*;
    use radiosity::geometry::Polygon;
    use radiosity::scene::{Material, MaterialId, Surface};

    /// A closed box w × h × d with inward faces, face `lamp` emitting 1 W·m⁻²·sr⁻¹ and
    /// reflectances `rho` per face.
    fn room(size: [f64; 3], lamp: usize, rho: [f64; 6]) -> Scene {
        let [w, h, d] = size;
        let p = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
        let faces = [
            (
                "floor",
                [p(0., 0., 0.), p(0., 0., d), p(w, 0., d), p(w, 0., 0.)],
            ),
            (
                "ceiling",
                [p(0., h, 0.), p(w, h, 0.), p(w, h, d), p(0., h, d)],
            ),
            (
                "south",
                [p(0., 0., 0.), p(w, 0., 0.), p(w, h, 0.), p(0., h, 0.)],
            ),
            (
                "north",
                [p(0., 0., d), p(0., h, d), p(w, h, d), p(w, 0., d)],
            ),
            (
                "west",
                [p(0., 0., 0.), p(0., h, 0.), p(0., h, d), p(0., 0., d)],
            ),
            ("east", [p(w, 0., 0.), p(w, 0., d), p(w, h, d), p(w, h, 0.)]),
        ];
        Scene {
            name: "room".into(),
            materials: (0..6)
                .map(|i| {
                    let e = if i == lamp { 1.0 } else { 0.0 };
                    Material::new(format!("m{i}"), [rho[i]; 3], [e; 3])
                })
                .collect(),
            surfaces: faces
                .iter()
                .enumerate()
                .map(|(i, (name, v))| Surface {
                    object: (*name).into(),
                    group: String::new(),
                    material: MaterialId(i as u32),
                    polygon: Polygon::new(v.to_vec()).unwrap(),
                    origin: Default::default(),
                })
                .collect(),
            lights: Vec::new(),
            camera: None,
        }
    }

    proptest! {
        // A fixed seed: the same 6 rooms on every run (plus the saved long-box case).
        #![proptest_config(ProptestConfig {
            cases: 6,
            rng_seed: proptest::test_runner::RngSeed::Fixed(8),
            ..ProptestConfig::default()
        })]

        /// Random closed boxes (aspect up to 1:4, any face the lamp, ρ 0.2–0.8 per face):
        /// hierarchical at ε = 0.01 against the direct solve on a 2400-element mesh, per
        /// face. Tolerance 1.5 %: each link carries at most ε = 1 % of its receiver's
        /// irradiance and a face mean averages many links, plus the direct solve's own
        /// discretisation error on a 2400-element box; measured worst 0.69 % (0.80 % before
        /// the links of closed scenes were balanced, `coupling/hierarchical/closure.rs`) on
        /// a long box lit from an end face, kept in hierarchical.proptest-regressions
        /// (scaling each leaf's whole row of links to its unit-radiosity sum put that floor
        /// 6.7 % high: the deficit is in the coarse links from dim sources, and the closure
        /// now puts it there).
        #[test]
        fn hierarchical_agrees_with_the_direct_solve(
            w in 0.5f64..2.0, h in 0.5f64..2.0, d in 0.5f64..2.0,
            lamp in 0usize..6,
            rho in proptest::array::uniform6(0.2f64..0.8),
        ) {
            let scene = room([w, h, d], lamp, rho);
            let (_, hr) = solve(&scene, &hierarchical(0.01));
            let mut direct = SolveSettings {
                solve: SolveOptions {
                    solver: SolverKind::Direct,
                    ..Default::default()
                },
                ..Default::default()
            };
            direct.mesh.elements = 2400;
            let (_, dr) = solve(&scene, &direct);
            for (a, b) in hr.objects.iter().zip(&dr.objects) {
                prop_assert_eq!(&a.name, &b.name);
                let rel = (a.radiosity[0] - b.radiosity[0]).abs() / b.radiosity[0];
                prop_assert!(rel < 0.015, "{}: {} vs {}", a.name, a.radiosity[0], b.radiosity[0]);
            }
        }
    }
}

/// Six coincident copies of a grey ceiling (ρ = 0.95, separate objects so that they do not
/// merge) over a floor of the same grey, lit by a small lamp under the ceiling: the floor's
/// links count every copy in full, so its leaves gather about three times their
/// hemisphere. No surface can do that: such leaves are scaled back to their hemisphere and
/// the solve says so, naming the object. The physics that must hold whatever the input:
/// the surfaces absorb no more than is emitted, nothing escapes in negative amounts, the
/// power balances (to the solver's stopping rule, 1e-4), and nothing that does not emit
/// is brighter than ρ_max times the brightest emitter (its irradiance is at most the
/// largest radiosity, which is then the lamp's).
///
/// Regression (measured on this scene with `radiosity solve` before the scaling): 3,482
/// sweeps, the floor at 0.875 W/m² (40 times what one ceiling gives it, 0.0217 W/m²), 5.2
/// times the emitted power absorbed and −4.2 times it escaping, without a warning; in the conference room
/// (331,179 triangles written with six digits: stacks of near-coincident triangles) leaves
/// gathered up to 3.9 times their hemisphere and the solve ran on for hours.
#[test]
fn coincident_copies_of_a_surface_gather_no_more_than_the_hemisphere() {
    use radiosity::scene::Material;
    let p = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
    let floor = vec![p(0., 0., 0.), p(0., 0., 1.), p(1., 0., 1.), p(1., 0., 0.)];
    let ceiling = vec![
        p(0., 0.5, 0.),
        p(1., 0.5, 0.),
        p(1., 0.5, 1.),
        p(0., 0.5, 1.),
    ];
    let lamp = vec![
        p(0.45, 0.45, 0.45),
        p(0.55, 0.45, 0.45),
        p(0.55, 0.45, 0.55),
        p(0.45, 0.45, 0.55),
    ];
    const CEILINGS: [&str; 6] = [
        "ceiling0", "ceiling1", "ceiling2", "ceiling3", "ceiling4", "ceiling5",
    ];
    let (rho, radiance) = (0.95, 1.0);
    let scene = scene_of(
        "coincident ceilings",
        vec![
            Material::new("grey", [rho; 3], [0.0; 3]),
            Material::new("glow", [0.0; 3], [radiance; 3]),
        ],
        [(floor, "floor", 0), (lamp, "lamp", 1)]
            .into_iter()
            .chain(CEILINGS.iter().map(|&name| (ceiling.clone(), name, 0))),
    );
    let (solved, report) = solve(&scene, &hierarchical(0.01));
    let t = &report.totals;
    assert!(
        t.absorbed_power[0] <= t.emitted_power[0] && t.escaped_power[0] >= 0.0,
        "emitted {:?} W, absorbed {:?} W, escaped {:?} W",
        t.emitted_power,
        t.absorbed_power,
        t.escaped_power
    );
    assert!(report.balance_error() < 1e-4, "{}", report.balance_error());
    let bound = rho * PI * radiance;
    for name in std::iter::once("floor").chain(CEILINGS) {
        let b = report.object(name).unwrap().radiosity[0];
        assert!(b <= bound, "{name}: {b} W/m² above {bound} W/m²");
    }
    let overfull = &solved.hierarchy.as_ref().unwrap().overfull;
    assert!(
        overfull
            .iter()
            .any(|(object, n)| object == "floor" && *n > 0),
        "{overfull:?}"
    );
}

/// The per-polygon reference made by our independent path tracer
/// (`radiosity_studies::path_trace`; tests/reference/cornell_path_traced.json, provenance
/// in tests/reference/PROVENANCE.md).
fn path_traced() -> Value {
    serde_json::from_str(include_str!("reference/cornell_path_traced.json")).unwrap()
}

/// The path-traced reference and Mitsuba's per-polygon values (with the lamp's reflection
/// added back, see the test above) agree within their standard errors: every polygon and
/// channel within 3.5 of the two combined (57 comparisons: a normal variable exceeds 3.5
/// once in 2,000; measured at most 2.4, the floor, where Mitsuba's direct light reads
/// 0.9 % below both the path tracer and a deterministic quadrature), and on average within
/// 0.4 % (measured 0.14 %). So neither reference carries an error the other does not show.
#[test]
fn the_path_traced_reference_agrees_with_mitsuba() {
    let mitsuba = cornell_reference();
    let traced = path_traced();
    let polygons = mitsuba["per_polygon_area_averaged"]["polygons"]
        .as_array()
        .unwrap();
    let by_name = |name: &str| polygons.iter().find(|p| p["name"] == name).unwrap();
    let scene = cornell_box();
    let mut sum = 0.0;
    let mut count = 0;
    for t in traced["polygons"].as_array().unwrap() {
        let name = t["name"].as_str().unwrap();
        if name == "light" {
            continue;
        }
        let m = by_name(name);
        for c in 0..3 {
            let (want, _) = mitsuba_with_lamp_reflection(&scene, name, c);
            let got = t["radiosity_avg"][c].as_f64().unwrap();
            let se = (m["radiosity_avg_stderr"][c].as_f64().unwrap().powi(2)
                + t["radiosity_avg_stderr"][c].as_f64().unwrap().powi(2))
            .sqrt();
            let z = (want - got) / se;
            assert!(
                z.abs() < 3.5,
                "{name} channel {c}: Mitsuba {want}, traced {got}, z {z}"
            );
            sum += (want / got - 1.0).abs();
            count += 1;
        }
    }
    assert!(
        sum / f64::from(count) < 0.004,
        "mean {}",
        sum / f64::from(count)
    );
}

/// A finer ε reaches half a per cent on every polygon of the Cornell box, against the
/// path-traced reference, whose standard errors (0.01–0.11 %) leave room to see it: at
/// ε = 0.000625 (about 1.3 s on two cores) the worst polygon is measured within 0.46 % (the
/// short block's front, approached from above: 0.75 % at ε = 0.0025, 0.59 % at 0.00125),
/// the mean 0.16 %. The bounds, 0.6 % and 0.25 %, are the 0.5 % with the
/// reference's largest standard error, and the measured mean with as much again.
#[test]
fn a_fine_epsilon_is_within_half_a_per_cent_of_the_path_traced_reference() {
    let epsilon = 0.000625;
    let (_, report) = solve(&cornell_box(), &hierarchical(epsilon));
    let traced = path_traced();
    let mut worst = (String::new(), 0.0f64);
    let mut sum = 0.0;
    let polygons = traced["polygons"].as_array().unwrap();
    for t in polygons {
        let name = t["name"].as_str().unwrap();
        let b = report.object(name).unwrap().radiosity;
        let err = (0..3)
            .map(|c| (b[c] / t["radiosity_avg"][c].as_f64().unwrap() - 1.0).abs())
            .fold(0.0, f64::max);
        sum += err;
        if err > worst.1 {
            worst = (name.to_string(), err);
        }
    }
    let mean = sum / polygons.len() as f64;
    eprintln!(
        "ε = {epsilon} against the path tracer: mean {:.3} %, worst {:.3} % ({})",
        100.0 * mean,
        100.0 * worst.1,
        worst.0
    );
    assert!(worst.1 < 0.006, "{worst:?}");
    assert!(mean < 0.0025, "mean {mean}");
}
