//! Hierarchical radiosity against scene size: the Cornell box with every polygon tessellated
//! into a k × k grid of triangle pairs (2k² triangles per quad; about 580, 2.3k, 9.2k and
//! 37k input triangles), solved with `--solver hierarchical` at the default ε. The slope of
//! time against input size is the method's scaling exponent (the goal: near-linear).
//!
//! Run: `cargo bench -p radiosity --bench hierarchical`

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use glam::DVec3;
use radiosity::cornell::cornell_box;
use radiosity::geometry::Polygon;
use radiosity::pipeline::{solve_scene, SolveSettings};
use radiosity::progress::NoProgress;
use radiosity::scene::{Scene, Surface};
use radiosity::solve::{SolveOptions, SolverKind};
use std::time::Duration;

/// The scene with every quadrilateral cut into a k × k bilinear grid of triangle pairs
/// (other polygons kept whole).
fn tessellated(scene: &Scene, k: usize) -> Scene {
    let mut surfaces = Vec::new();
    for s in &scene.surfaces {
        let v = s.polygon.vertices();
        if v.len() != 4 {
            surfaces.push(s.clone());
            continue;
        }
        let at = |i: usize, j: usize| -> DVec3 {
            let (u, w) = (i as f64 / k as f64, j as f64 / k as f64);
            v[0] * (1.0 - u) * (1.0 - w)
                + v[1] * u * (1.0 - w)
                + v[2] * u * w
                + v[3] * (1.0 - u) * w
        };
        for i in 0..k {
            for j in 0..k {
                for tri in [
                    [at(i, j), at(i + 1, j), at(i + 1, j + 1)],
                    [at(i, j), at(i + 1, j + 1), at(i, j + 1)],
                ] {
                    if let Ok(polygon) = Polygon::new(tri.to_vec()) {
                        surfaces.push(Surface {
                            polygon,
                            ..s.clone()
                        });
                    }
                }
            }
        }
    }
    Scene {
        surfaces,
        ..scene.clone()
    }
}

fn hierarchical(c: &mut Criterion) {
    let mut g = c.benchmark_group("cornell_tessellated_hierarchical");
    g.sample_size(10).measurement_time(Duration::from_secs(10));
    let settings = SolveSettings {
        solve: SolveOptions {
            solver: SolverKind::Hierarchical,
            ..Default::default()
        },
        ..Default::default()
    };
    for k in [4, 8, 16, 32] {
        let scene = tessellated(&cornell_box(), k);
        g.throughput(Throughput::Elements(scene.surfaces.len() as u64));
        g.bench_with_input(
            BenchmarkId::from_parameter(scene.surfaces.len()),
            &scene,
            |b, scene| b.iter(|| solve_scene(scene, &settings, &NoProgress).unwrap()),
        );
    }
    g.finish();
}

criterion_group!(benches, hierarchical);
criterion_main!(benches);
