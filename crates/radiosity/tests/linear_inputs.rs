//! Inputs far larger than the scenes we ship load and mesh in time linear in their size
//! (issue 12: "one face of 200k vertices, or 300k separate faces, never finish … the parsers
//! and geometry must be linear too").
//!
//! Sized so that a quadratic step in the parser, the polygon checks or the mesher (n² =
//! 4·10¹⁰ to 9·10¹⁰ operations) would run for many minutes and time the suite out, while the
//! linear path takes seconds in a release build. The answers are checked against closed
//! forms: the surface count, and the meshed area (elements tile their surfaces exactly).

use radiosity::io::obj::parse_obj;
use radiosity::mesh::{Mesh, MeshOptions};
use std::fmt::Write;

const MTL: &str = "newmtl white\nKd 0.7 0.7 0.7\nnewmtl light\nKd 0.8 0.8 0.8\nKe 10 10 10\n";

/// A 2 m × 1 m lamp at y = 3 facing down (vertices 1–4), then `body` with the material
/// `white`.
fn obj_with_lamp(body: &str) -> String {
    format!(
        "mtllib lamp.mtl\nusemtl light\nv 2 3 2\nv 4 3 2\nv 4 3 3\nv 2 3 3\nf 1 2 3 4\n\
         usemtl white\n{body}"
    )
}

fn parse(obj: &str) -> radiosity::scene::Scene {
    parse_obj(obj, "big.obj", |_| Ok(MTL.to_string())).expect("the scene parses")
}

fn meshed_area(mesh: &Mesh) -> f64 {
    mesh.elements.iter().map(|e| e.area).sum()
}

#[test]
fn three_hundred_thousand_separate_faces_load_and_mesh() {
    // 600 × 500 separate 9 mm squares on a 1 cm pitch, facing up (+y), each with its own
    // four vertices.
    let (nx, nz, side) = (600, 500, 0.009);
    let mut body = String::new();
    let mut v = 5;
    for i in 0..nx {
        for j in 0..nz {
            let (x, z) = (f64::from(i) * 0.01, f64::from(j) * 0.01);
            let _ = write!(
                body,
                "v {x} 0 {z}\nv {x} 0 {z1}\nv {x1} 0 {z1}\nv {x1} 0 {z}\nf {v} {} {} {}\n",
                v + 1,
                v + 2,
                v + 3,
                x1 = x + side,
                z1 = z + side,
            );
            v += 4;
        }
    }
    let scene = parse(&obj_with_lamp(&body));
    let faces = (nx * nz) as usize;
    assert_eq!(scene.surfaces.len(), faces + 1);
    let mesh = Mesh::build(&scene, &MeshOptions::default()).expect("the scene meshes");
    // Every face keeps at least one element, whatever the budget.
    assert!(mesh.elements.len() > faces);
    // Squares + lamp; 1e-9 relative: rounding of 300k small areas in f64.
    let expected = faces as f64 * side * side + 2.0;
    let area = meshed_area(&mesh);
    assert!(
        (area - expected).abs() < 1e-9 * expected,
        "meshed area {area} m², expected {expected} m²"
    );
}

#[test]
fn a_face_of_two_hundred_thousand_vertices_loads_and_meshes() {
    // A regular 200,000-gon of circumradius 2 m at y = 0, counter-clockwise seen from above.
    let n = 200_000usize;
    let r = 2.0f64;
    let mut body = String::new();
    for k in 0..n {
        let a = std::f64::consts::TAU * k as f64 / n as f64;
        let _ = writeln!(body, "v {} 0 {}", r * a.cos(), -r * a.sin());
    }
    body.push('f');
    for k in 0..n {
        let _ = write!(body, " {}", k + 5);
    }
    body.push('\n');
    let scene = parse(&obj_with_lamp(&body));
    assert_eq!(scene.surfaces.len(), 2);
    let mesh = Mesh::build(&scene, &MeshOptions::default()).expect("the scene meshes");
    // The n-gon's area is (n/2) r² sin(2π/n); plus the lamp's 2 m². 1e-9 relative: the
    // f64 sums over 2·10⁵ fan triangles.
    let expected = 0.5 * n as f64 * r * r * (std::f64::consts::TAU / n as f64).sin() + 2.0;
    let area = meshed_area(&mesh);
    assert!(
        (area - expected).abs() < 1e-9 * expected,
        "meshed area {area} m², expected {expected} m²"
    );
}
