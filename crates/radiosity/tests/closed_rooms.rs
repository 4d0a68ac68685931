//! Two defects found on CIE 171 cases, each pinned by a closed room:
//!
//! - Power must not leak out of a closed room. In a closed enclosure of uniform reflectance
//!   ρ every watt emitted is absorbed, Σ(1 − ρ) H A = Φ, so the area-mean irradiance is
//!   Φ / (S (1 − ρ)) (CIE 171:2006 §5.8) and nothing escapes. A 4 m cube with ρ = 0.9 and an
//!   emitter at the centre of each face is symmetric, so every face has that mean. Before the
//!   fix the two-level couplings' far receivers gathered from each patch's plain area mean
//!   (`coupling::far_weights`), and 3.6 W of 600 W "escaped": every face 0.7 % dark.
//! - The stopping rule must bound the error of every surface, not the total: in a room lit
//!   by a downward spot the ceiling sees only reflected light, and at the default tolerance
//!   the old rule (relative to the emitted power) left it 0.4 % short.

mod common;

use common::solve::solve;
use radiosity::formfactor::FormFactorMethod;
use radiosity::io::scene_file::parse_scene_file;
use radiosity::mesh::MeshOptions;
use radiosity::pipeline::{solve_scene, SolveSettings};
use radiosity::progress::NoProgress;
use radiosity::report::Report;
use radiosity::scene::Scene;
use radiosity::solve::{SolveOptions, SolverKind};
use std::path::Path;

/// A quad as JSON vertices, from its corner `o` and edges `u`, `v` (normal u × v).
fn quad(o: [f64; 3], u: [f64; 3], v: [f64; 3]) -> String {
    let p = |a: f64, b: f64| {
        let c: Vec<String> = (0..3)
            .map(|k| format!("{}", o[k] + a * u[k] + b * v[k]))
            .collect();
        format!("[{}]", c.join(", "))
    };
    format!(
        "[{}, {}, {}, {}]",
        p(0., 0.),
        p(1., 0.),
        p(1., 1.),
        p(0., 1.)
    )
}

/// A face: name, corner, edges u and v (normal u × v, pointing into the box).
type Face = (&'static str, [f64; 3], [f64; 3], [f64; 3]);

/// The six inward faces of a box of size `s` at the origin.
fn faces(s: [f64; 3]) -> Vec<Face> {
    let [x, y, z] = s;
    vec![
        ("floor", [0., 0., 0.], [x, 0., 0.], [0., y, 0.]),
        ("ceiling", [0., 0., z], [0., y, 0.], [x, 0., 0.]),
        ("wall_y0", [0., 0., 0.], [0., 0., z], [x, 0., 0.]),
        ("wall_y1", [0., y, 0.], [x, 0., 0.], [0., 0., z]),
        ("wall_x0", [0., 0., 0.], [0., y, 0.], [0., 0., z]),
        ("wall_x1", [x, 0., 0.], [0., 0., z], [0., y, 0.]),
    ]
}

fn scene(json: String) -> Scene {
    parse_scene_file(&json, Path::new("closed_rooms.json"))
        .unwrap()
        .scene
}

/// The 4 m cube, ρ = `rho`, each face cut 3 × 3 with the centre cell emitting 100 W.
fn cube_with_face_centre_emitters(rho: f64) -> Scene {
    furnished(rho, &[])
}

/// [`cube_with_face_centre_emitters`] with `extra` surfaces (material "white") inside.
fn furnished(rho: f64, extra: &[String]) -> Scene {
    let cell = 4.0 / 3.0;
    let radiance = 100.0 / (cell * cell) / std::f64::consts::PI;
    let mut surfaces = Vec::new();
    for (name, o, u, v) in faces([4.0; 3]) {
        for i in 0..3 {
            for j in 0..3 {
                let at: [f64; 3] =
                    std::array::from_fn(|k| o[k] + (i as f64 * u[k] + j as f64 * v[k]) / 3.0);
                let du = u.map(|c| c / 3.0);
                let dv = v.map(|c| c / 3.0);
                let material = if i == 1 && j == 1 { "lamp" } else { "white" };
                surfaces.push(format!(
                    r#"{{ "object": "{name}", "material": "{material}", "vertices": {} }}"#,
                    quad(at, du, dv)
                ));
            }
        }
    }
    surfaces.extend_from_slice(extra);
    scene(format!(
        r#"{{ "materials": [
            {{ "name": "white", "reflectance": [{rho}, {rho}, {rho}] }},
            {{ "name": "lamp", "reflectance": [{rho}, {rho}, {rho}],
               "emission": [{radiance}, {radiance}, {radiance}] }} ],
          "surfaces": [{}] }}"#,
        surfaces.join(",\n")
    ))
}

#[test]
fn nothing_escapes_a_closed_cube_and_every_face_has_the_closed_form_mean() {
    let rho = 0.9;
    let scene = cube_with_face_centre_emitters(rho);
    let (power, area) = (600.0, 6.0 * 16.0);
    let expected = power / (area * (1.0 - rho)); // 62.5 W·m⁻²
                                                 // Every solver with a two-level coupling, with the exact polygon-to-polygon form factor
                                                 // and with the point-receiver methods (`raycast`, the default, and `analytic-point`),
                                                 // whose rows are closed at every quadrature point but whose column sums (reciprocity)
                                                 // hold only to the receivers' quadrature error: before the closure balancing
                                                 // (`coupling::closure`) they made +0.4 % (raycast) and +0.5 % (analytic-point) of the
                                                 // power on this mesh. The hemi-cube is closed by construction (every pixel sees a
                                                 // surface) but its aliasing breaks the cube's symmetry, so it is held to the balance only.
    let mut cases = Vec::new();
    for solver in [
        SolverKind::Direct,
        SolverKind::GaussSeidel,
        SolverKind::Progressive,
    ] {
        for method in [
            FormFactorMethod::AnalyticPolygon,
            FormFactorMethod::Raycast,
            FormFactorMethod::AnalyticPoint,
            FormFactorMethod::Hemicube,
        ] {
            cases.push((solver, method, 1200));
        }
    }
    for (solver, method, elements) in cases {
        let settings = SolveSettings {
            mesh: MeshOptions {
                elements,
                ..MeshOptions::default()
            },
            form_factor: method,
            solve: SolveOptions {
                solver,
                tolerance: 1e-7,
                ..SolveOptions::default()
            },
            ..SolveSettings::default()
        };
        let solved = solve_scene(&scene, &settings, &NoProgress).unwrap();
        let report = Report::new("cube", &solved.mesh, &solved.solution, method.name());
        let t = &report.totals;
        assert!(
            (t.emitted_power[0] - power).abs() < 1e-9 * power,
            "{:?}",
            t.emitted_power
        );
        // What remains is the f32 storage of the form factors, ~1e-7 of the power (−3e-5 W
        // seen); 1e-4 is far below the old leak, 6e-3.
        assert!(
            t.escaped_power[0].abs() < 1e-4 * power,
            "{solver} {method}: {} W of {power} W escaped",
            t.escaped_power[0]
        );
        // A balance error ε becomes ε / (1 − ρ) = 10 ε on every face: 1e-4 at most, against
        // the old −0.7 %; 1e-4 relative. (The hemi-cube: see above.)
        if method == FormFactorMethod::Hemicube {
            continue;
        }
        for o in &report.objects {
            let rel = (o.irradiance[0] - expected) / expected;
            assert!(
                rel.abs() < 1e-4,
                "{solver} {method} {}: H = {} vs Φ/(S(1−ρ)) = {expected} ({:+.4} %)",
                o.name,
                o.irradiance[0],
                100.0 * rel
            );
        }
    }
}

/// The six outward faces of a box from `lo` to `hi`, as scene-file surfaces of `object`.
fn box_surfaces(object: &str, lo: [f64; 3], hi: [f64; 3]) -> Vec<String> {
    let d = [hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]];
    let (x, y, z) = ([d[0], 0., 0.], [0., d[1], 0.], [0., 0., d[2]]);
    let at = |dx: f64, dy: f64, dz: f64| [lo[0] + dx, lo[1] + dy, lo[2] + dz];
    [
        (at(0., 0., 0.), y, x),   // bottom, −z
        (at(0., 0., d[2]), x, y), // top, +z
        (at(0., 0., 0.), x, z),   // −y
        (at(0., d[1], 0.), z, x), // +y
        (at(0., 0., 0.), z, y),   // −x
        (at(d[0], 0., 0.), y, z), // +x
    ]
    .iter()
    .map(|(o, u, v)| {
        format!(
            r#"{{ "object": "{object}", "material": "white", "vertices": {} }}"#,
            quad(*o, *u, *v)
        )
    })
    .collect()
}

#[test]
fn nothing_escapes_a_furnished_closed_room() {
    // The cube of the previous test with a box floating in it and a box standing on the
    // floor (clear of the floor's lamp). The boxes occlude: a receiver point sees a box and,
    // in part, the wall behind it, and the visibility estimate makes row sums drift from 1
    // (0.976 to 1.025 seen) — the room gained 3.4 W of 600 W (−0.56 % "escaped") with the
    // default `raycast` before the closure balancing. The enclosure probe finds no opening,
    // so every row is held to 1 and every column to its patch's area: nothing escapes but
    // the f32 rounding of the stored factors (1e-4 of the power allows for 1e-6 relative
    // per factor across ~10⁴ stored factors' worth of accumulation, far below the old gain).
    let rho = 0.9;
    let mut extra = box_surfaces("floating", [1.0, 1.2, 1.5], [2.2, 2.0, 2.3]);
    extra.extend(box_surfaces("on_floor", [2.7, 0.3, 0.0], [3.7, 1.2, 0.9]));
    let scene = furnished(rho, &extra);
    let power = 600.0;
    for solver in [
        SolverKind::Direct,
        SolverKind::GaussSeidel,
        SolverKind::Progressive,
    ] {
        let solved = solve(&scene, 2000, solver, 1e-7);
        let report = Report::new("room", &solved.mesh, &solved.solution, "raycast");
        let t = &report.totals;
        assert!((t.emitted_power[0] - power).abs() < 1e-9 * power);
        assert!(
            t.escaped_power[0].abs() < 1e-4 * power,
            "{solver}: {} W of {power} W escaped",
            t.escaped_power[0]
        );
    }
}

#[test]
fn at_the_default_tolerance_a_ceiling_lit_only_by_reflection_is_converged() {
    // A 4 × 4 × 3 m room, ρ = 0.5 everywhere, lit by a spot aimed straight down (outer
    // half-angle 40°: nothing reaches the ceiling directly). Every solver at the default
    // tolerance (1e-3, per element) must give every surface's mean irradiance within 0.1 %
    // of the same system solved to 1e-10 (Gauss–Seidel on the same mesh and form factors).
    let mut surfaces = Vec::new();
    for (name, o, u, v) in faces([4.0, 4.0, 3.0]) {
        surfaces.push(format!(
            r#"{{ "object": "{name}", "material": "grey", "vertices": {} }}"#,
            quad(o, u, v)
        ));
    }
    let scene = scene(format!(
        r#"{{ "materials": [{{ "name": "grey", "reflectance": [0.5, 0.5, 0.5] }}],
          "surfaces": [{}],
          "lights": [{{ "name": "spot", "type": "spot", "position": [2, 2, 2.9],
            "direction": [0, 0, -1], "inner_deg": 20, "outer_deg": 40, "flux_lm": 3000 }}] }}"#,
        surfaces.join(",\n")
    ));
    let solve = |solver: SolverKind, tolerance: f64| {
        let solved = solve(&scene, 1000, solver, tolerance);
        Report::new("room", &solved.mesh, &solved.solution, "raycast")
    };
    let reference = solve(SolverKind::GaussSeidel, 1e-10);
    let ceiling = reference.object("ceiling").unwrap().irradiance[0];
    assert!(ceiling > 0.0);
    let default_tolerance = SolveOptions::default().tolerance;
    for solver in [
        SolverKind::Jacobi,
        SolverKind::GaussSeidel,
        SolverKind::Progressive,
    ] {
        let got = solve(solver, default_tolerance);
        for (o, r) in got.objects.iter().zip(&reference.objects) {
            let rel = (o.irradiance[0] - r.irradiance[0]) / r.irradiance[0];
            assert!(
                rel.abs() < 1e-3,
                "{solver} at tolerance {default_tolerance}: {} H = {} vs {} converged ({:+.4} %)",
                o.name,
                o.irradiance[0],
                r.irradiance[0],
                100.0 * rel
            );
        }
    }
}

#[test]
fn nothing_escapes_closed_rooms_with_the_hierarchical_solver() {
    // The closed cube with face-centre lamps and the furnished closed room above, solved
    // hierarchically at the default ε. The links' rows and columns are balanced
    // (`coupling/hierarchical/closure.rs`): every leaf gathers exactly 1 for unit radiosity
    // everywhere and delivers exactly its area's worth of power, so in a closed scene
    // what leaves the surfaces arrives on them up to the solver's stopping rule. Measured:
    // cube 1e-15 of the power (2.87 W of 600 W escaped before the closure), furnished room
    // 2.6e-5 (the solver's stopping rule at ρ = 0.9); bound the issue's 1e-4.
    let rho = 0.9;
    let (power, area) = (600.0, 6.0 * 16.0);
    let expected = power / (area * (1.0 - rho));
    let mut extra = box_surfaces("floating", [1.0, 1.2, 1.5], [2.2, 2.0, 2.3]);
    extra.extend(box_surfaces("on_floor", [2.7, 0.3, 0.0], [3.7, 1.2, 0.9]));
    for (name, scene) in [
        ("cube", cube_with_face_centre_emitters(rho)),
        ("furnished", furnished(rho, &extra)),
    ] {
        let solved = solve(&scene, 2000, SolverKind::Hierarchical, 1e-7);
        let report = Report::new(name, &solved.mesh, &solved.solution, "raycast");
        let t = &report.totals;
        let worst_face = report
            .objects
            .iter()
            .filter(|_| name == "cube")
            .map(|o| ((o.irradiance[0] - expected) / expected).abs())
            .fold(0.0, f64::max);
        eprintln!(
            "{name}: {} W of {power} W escaped ({:.2e}); worst face mean {worst_face:.2e}; {} leaves",
            t.escaped_power[0],
            t.escaped_power[0] / power,
            solved.mesh.len()
        );
        assert!((t.emitted_power[0] - power).abs() < 1e-9 * power);
        assert!(
            t.escaped_power[0].abs() < 1e-4 * power,
            "{name}: {} W of {power} W escaped",
            t.escaped_power[0]
        );
    }
}

#[test]
fn no_light_reaches_the_floor_under_a_box_or_leaves_a_furnished_room() {
    // A box standing on the floor of the closed cube with no bottom face, as furniture is
    // often modelled (the scale benchmark's furnished rooms): the floor under it sees only
    // the backs of the box's faces and can get no light. A cluster link gives all its
    // members the same light; the floor under the box, clustered with the floor around it,
    // got 0.62 W·m⁻² here and, reflecting it into nothing, lost it (5.3e-4 of the power
    // escaped). Polygons that see only the backs of surfaces now form a subtree of their own
    // that no link reaches: measured 0 W·m⁻² and 2e-15 escaped; bound the issue's 1e-4.
    let rho = 0.9;
    let (lo, hi) = ([0.5, 2.9, 0.0], [1.6, 3.6, 0.9]);
    let mut extra = box_surfaces("on_floor", lo, hi);
    extra.remove(0); // no bottom
    let scene = furnished(rho, &extra);
    let solved = solve(&scene, 2000, SolverKind::Hierarchical, 1e-7);
    let under: Vec<f64> = solved
        .mesh
        .elements
        .iter()
        .zip(&solved.solution.irradiance)
        .filter(|(e, _)| {
            let c = e.centre;
            c.z.abs() < 1e-9 && (lo[0]..hi[0]).contains(&c.x) && (lo[1]..hi[1]).contains(&c.y)
        })
        .map(|(_, h)| h[0])
        .collect();
    let report = Report::new("room", &solved.mesh, &solved.solution, "raycast");
    let t = &report.totals;
    let escaped = t.escaped_power[0] / t.emitted_power[0];
    eprintln!("floor under the box: {under:?} W/m²; {escaped:.2e} of the power escaped");
    assert!(!under.is_empty(), "no floor element under the box");
    assert!(
        under.iter().all(|&h| h == 0.0),
        "light reached the floor under the box: {under:?}"
    );
    assert!(escaped.abs() < 1e-4, "{escaped:.2e} of the power escaped");
}

#[test]
fn a_furnished_room_of_the_scale_benchmark_keeps_its_light() {
    // The scale benchmark's closed room of 30 pieces of furniture at the default ε. In such
    // rooms the joint balance of rows and columns (`coupling/hierarchical/closure.rs`) asks
    // a few leaves for corrections larger than their links, and those are held to a bound
    // while the rest are balanced: what escapes is what the held leaves leave open.
    // Measured 0.6e-5 to 1.5e-5 by channel; bound 1e-4, the issue's energy balance. (While the whole balance was
    // given up for the rows alone whenever one leaf went beyond: 4.2e-4 here, 1.6e-3 to
    // 2.2e-3 by channel once receivers' corners were looked at, 0.4 % at 100 and 300
    // objects; 1.1 % when a floor piece beside a wall could be linked to the whole wall
    // through points that all missed the bright strip above it.)
    assert_keeps_light(&radiosity::generate::furnished_room(30, 1), 1e-4);
}

/// Solves `scene` hierarchically at the default ε and tolerance and checks that, in every
/// channel, less than `bound` of the emitted power escapes.
fn assert_keeps_light(scene: &Scene, bound: f64) {
    let default_tolerance = SolveOptions::default().tolerance;
    let solved = solve(scene, 2000, SolverKind::Hierarchical, default_tolerance);
    let report = Report::new(&scene.name, &solved.mesh, &solved.solution, "raycast");
    let t = &report.totals;
    for c in 0..3 {
        let escaped = t.escaped_power[c] / t.emitted_power[c];
        eprintln!("channel {c}: {escaped:.2e} of the power escaped");
        assert!(
            escaped.abs() < bound,
            "channel {c}: {escaped:.2e} of the power escaped"
        );
    }
}

#[test]
fn a_meeting_room_of_tessellated_chairs_keeps_its_light() {
    // The scale benchmark's meeting room (`generate::meeting_room`): two chairs whose
    // cushions are closed meshes of small triangles and whose tubular legs stand on the
    // floor and end inside the seats, as real interior models are made, in a closed room at
    // the default ε. Measured 2.1e-4 to 2.3e-4 of the power escaping by channel: a leaf
    // that straddles a surface piercing it (a leg's top band through a seat's underside, a
    // floor leaf around a leg's open end) is uniform, so the share of its light that leaves
    // its part inside the other object meets only backs. (0.9e-4 to 1.3e-4 while such a
    // leaf's row was closed to its whole hemisphere, which made the legs 3 to 5 % too
    // bright; with the legs lifted 1 mm off the floor, 3e-5 then; without legs, 1e-5.)
    // Bound 5e-4: a leak of the kind the furnished rooms had (1e-3 to 1e-2 before their
    // fixes) fails it.
    assert_keeps_light(&radiosity::generate::meeting_room(2, 12), 5e-4);
}

#[test]
fn a_two_sided_box_lights_the_floor_under_it() {
    // A two-sided box with no bottom standing on a floor, a lamp inside it facing up: the
    // floor under the box sees only the box's faces from behind, but they are two-sided,
    // and their back-to-back twins light it. It is not buried (the hierarchy leaves out
    // polygons that see only backs; a ray meeting a face and its twin at the same distance
    // counts the twin). Hierarchical against the direct solve on the classic mesh, the
    // floor's mean radiosity: 2 % (ε = 0.02 per link, plus the classic mesh's own error on
    // 2000 elements; measured 0.7 %).
    let mut surfaces = vec![format!(
        r#"{{ "object": "floor", "material": "floor", "vertices": {} }}"#,
        quad([0., 0., 0.], [4., 0., 0.], [0., 4., 0.])
    )];
    let mut dome = box_surfaces("dome", [1.0, 1.0, 0.0], [3.0, 3.0, 2.0]);
    dome.remove(0); // no bottom
    surfaces.extend(dome.iter().map(|s| s.replace(r#""white""#, r#""dome""#)));
    surfaces.push(format!(
        r#"{{ "object": "lamp", "material": "lamp", "vertices": {} }}"#,
        quad([1.8, 1.8, 1.0], [0.4, 0., 0.], [0., 0.4, 0.])
    ));
    let scene = scene(format!(
        r#"{{ "materials": [
            {{ "name": "floor", "reflectance": [0.5, 0.5, 0.5] }},
            {{ "name": "dome", "reflectance": [0.8, 0.8, 0.8], "two_sided": true }},
            {{ "name": "lamp", "reflectance": [0, 0, 0], "emission": [10, 10, 10] }} ],
          "surfaces": [{}] }}"#,
        surfaces.join(",\n")
    ));
    let floor = |solver: SolverKind| {
        let solved = solve(&scene, 2000, solver, 1e-6);
        let report = Report::new("dome", &solved.mesh, &solved.solution, "raycast");
        report.object("floor").unwrap().radiosity[0]
    };
    let (hierarchical, direct) = (floor(SolverKind::Hierarchical), floor(SolverKind::Direct));
    eprintln!("floor: hierarchical {hierarchical}, direct {direct} W·m⁻²");
    assert!(direct > 0.0);
    assert!(
        (hierarchical - direct).abs() < 0.02 * direct,
        "floor: hierarchical {hierarchical} vs direct {direct} W·m⁻²"
    );
}
