//! Hemi-cube form factors per second at resolutions 64, 128 and 256, on a Cornell-like box
//! (five walls, a ceiling light, two blocks) meshed into a few hundred patches.
//!
//! - `hemicube/row/RES`: one gathering row (one hemi-cube at an element, every patch
//!   rasterised, one thread), throughput = form factors (patches) per row;
//! - `hemicube/column/RES`: one progressive shot (one hemi-cube at a patch, every element
//!   rasterised, the six tiles in parallel), throughput = form factors (elements) per shot.
//!
//! Run: `cargo bench -p radiosity --bench hemicube`.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use glam::DVec3;
use radiosity::formfactor::hemicube::{Hemicube, HemicubeParams};
use radiosity::formfactor::Engine;
use radiosity::geometry::Polygon;
use radiosity::mesh::{Mesh, MeshOptions};
use radiosity::scene::{Material, MaterialId, Origin, Scene, Surface};
use std::hint::black_box;
use std::time::Duration;

/// An axis-aligned box's faces (counter-clockwise seen from outside), without its bottom.
fn block(lo: DVec3, hi: DVec3) -> Vec<Vec<DVec3>> {
    let c = |x: usize, y: usize, z: usize| {
        DVec3::new([lo.x, hi.x][x], [lo.y, hi.y][y], [lo.z, hi.z][z])
    };
    vec![
        vec![c(0, 1, 0), c(0, 1, 1), c(1, 1, 1), c(1, 1, 0)], // top (+y)
        vec![c(0, 0, 0), c(0, 1, 0), c(1, 1, 0), c(1, 0, 0)], // front (−z)
        vec![c(1, 0, 1), c(1, 1, 1), c(0, 1, 1), c(0, 0, 1)], // back (+z)
        vec![c(0, 0, 1), c(0, 1, 1), c(0, 1, 0), c(0, 0, 0)], // −x
        vec![c(1, 0, 0), c(1, 1, 0), c(1, 1, 1), c(1, 0, 1)], // +x
    ]
}

/// A Cornell-like box in metres, open towards −z, light in the ceiling.
fn cornell_like() -> Scene {
    let (w, h, d) = (0.556, 0.549, 0.559);
    let p = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
    let mut polys = vec![
        (
            vec![
                p(0.0, 0.0, 0.0),
                p(0.0, 0.0, d),
                p(w, 0.0, d),
                p(w, 0.0, 0.0),
            ],
            0,
        ), // floor
        (
            vec![p(0.0, h, 0.0), p(w, h, 0.0), p(w, h, d), p(0.0, h, d)],
            0,
        ), // ceiling
        (
            vec![p(0.0, 0.0, d), p(0.0, h, d), p(w, h, d), p(w, 0.0, d)],
            0,
        ), // back
        (
            vec![p(w, 0.0, 0.0), p(w, 0.0, d), p(w, h, d), p(w, h, 0.0)],
            1,
        ), // red (x = w)
        (
            vec![
                p(0.0, 0.0, 0.0),
                p(0.0, h, 0.0),
                p(0.0, h, d),
                p(0.0, 0.0, d),
            ],
            2,
        ), // green
        // The light, 1 mm below the ceiling, facing down.
        (
            vec![
                p(0.213, h - 0.001, 0.227),
                p(0.343, h - 0.001, 0.227),
                p(0.343, h - 0.001, 0.332),
                p(0.213, h - 0.001, 0.332),
            ],
            3,
        ),
    ];
    for f in block(p(0.13, 0.0, 0.065), p(0.29, 0.165, 0.225)) {
        polys.push((f, 0));
    }
    for f in block(p(0.265, 0.0, 0.296), p(0.425, 0.33, 0.456)) {
        polys.push((f, 0));
    }
    let material = |name: &str, rho: [f64; 3], le: [f64; 3]| Material::new(name, rho, le);
    Scene {
        name: "cornell-like".into(),
        materials: vec![
            material("white", [0.725, 0.71, 0.68], [0.0; 3]),
            material("red", [0.63, 0.065, 0.05], [0.0; 3]),
            material("green", [0.14, 0.45, 0.091], [0.0; 3]),
            material("light", [0.78; 3], [17.0, 12.0, 4.0]),
        ],
        surfaces: polys
            .into_iter()
            .enumerate()
            .map(|(i, (v, m))| Surface {
                object: format!("s{i}"),
                group: String::new(),
                material: MaterialId(m),
                polygon: Polygon::new(v).expect("valid polygon"),
                origin: Origin::default(),
            })
            .collect(),
        lights: Vec::new(),
        camera: None,
    }
}

fn bench(c: &mut Criterion) {
    let options = MeshOptions {
        max_element_size: None,
        elements: 1200,
        patch_subdivision: 2,
    };
    let mesh = Mesh::build(&cornell_like(), &options).expect("mesh");
    let (elements, patches) = (mesh.elements.len(), mesh.patches.len());
    eprintln!("cornell-like mesh: {elements} elements, {patches} patches");
    // A floor element near the middle and the light's first patch.
    let receiver = mesh
        .elements
        .iter()
        .position(|e| {
            e.normal.y > 0.9
                && e.centre.y < 1e-9
                && (e.centre.x - 0.4).abs() < 0.03
                && e.centre.z > 0.1
        })
        .unwrap_or(0);
    let shooter = mesh
        .patches
        .iter()
        .position(|p| p.surface == 5)
        .unwrap_or(0);

    let mut group = c.benchmark_group("hemicube");
    group.sample_size(10);
    group.warm_up_time(Duration::from_millis(500));
    group.measurement_time(Duration::from_secs(2));
    for res in [64, 128, 256] {
        let params = HemicubeParams {
            resolution: res,
            ..Default::default()
        };
        let hc = Hemicube::new(&mesh, params, &[]);
        let mut row = vec![0.0f32; patches];
        group.throughput(Throughput::Elements(patches as u64));
        group.bench_with_input(BenchmarkId::new("row", res), &res, |b, _| {
            b.iter(|| hc.row(black_box(receiver), &mut row))
        });
        let mut column = vec![0.0f32; elements];
        group.throughput(Throughput::Elements(elements as u64));
        group.bench_with_input(BenchmarkId::new("column", res), &res, |b, _| {
            b.iter(|| hc.column(black_box(shooter), &mut column))
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
