//! Rasteriser throughput: a closed box of about 4k and 16k radiance-shaded triangles seen
//! from inside, 256×256 at 4×4 samples per pixel, with and without its wireframe.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use glam::DVec3;
use radiosity::render::{render, RenderOptions, ShadedTriangle};
use radiosity::scene::Camera;
use std::hint::black_box;

/// A unit cube with each face split into n × n quads (12·n² triangles), wound inwards,
/// with a smooth radiance field at the vertices.
fn closed_box(n: usize) -> (Vec<ShadedTriangle>, Vec<[DVec3; 2]>) {
    let radiance = |p: DVec3| {
        [
            (0.2 + 0.8 * p.x) as f32,
            (0.3 + 0.5 * p.y * p.z) as f32,
            (0.5 + 0.4 * (p.x - p.z)) as f32,
        ]
    };
    let mut triangles = Vec::with_capacity(12 * n * n);
    let mut edges = Vec::with_capacity(6 * 2 * n * (n + 1));
    for axis in 0..3 {
        for side in [0.0, 1.0] {
            let point = |u: f64, v: f64| {
                let mut p = [0.0; 3];
                p[axis] = side;
                p[(axis + 1) % 3] = u;
                p[(axis + 2) % 3] = v;
                DVec3::from(p)
            };
            for i in 0..n {
                for j in 0..n {
                    let (u0, u1) = (i as f64 / n as f64, (i + 1) as f64 / n as f64);
                    let (v0, v1) = (j as f64 / n as f64, (j + 1) as f64 / n as f64);
                    let q = [point(u0, v0), point(u1, v0), point(u1, v1), point(u0, v1)];
                    for t in [[q[0], q[1], q[2]], [q[0], q[2], q[3]]] {
                        triangles.push(ShadedTriangle {
                            positions: t,
                            radiance: t.map(radiance),
                        });
                    }
                    edges.push([q[0], q[1]]);
                    edges.push([q[0], q[3]]);
                }
            }
        }
    }
    (triangles, edges)
}

fn bench_render(c: &mut Criterion) {
    let camera = Camera {
        eye: DVec3::new(0.5, 0.5, 0.05),
        target: DVec3::new(0.5, 0.45, 1.0),
        up: DVec3::Y,
        fov_deg: 90.0,
    };
    let options = RenderOptions {
        width: 256,
        height: 256,
        samples_per_axis: 4,
        ..RenderOptions::default()
    };
    let mut group = c.benchmark_group("render_256x256_4x4");
    group.sample_size(10);
    for n in [18, 37] {
        let (triangles, edges) = closed_box(n);
        group.throughput(Throughput::Elements(triangles.len() as u64));
        group.bench_with_input(
            BenchmarkId::new("triangles", triangles.len()),
            &triangles,
            |b, t| b.iter(|| render(black_box(t), &[], &camera, &options).unwrap()),
        );
        group.bench_with_input(
            BenchmarkId::new("triangles+wireframe", triangles.len()),
            &triangles,
            |b, t| b.iter(|| render(black_box(t), &edges, &camera, &options).unwrap()),
        );
    }
    group.finish();
}

criterion_group!(benches, bench_render);
criterion_main!(benches);
