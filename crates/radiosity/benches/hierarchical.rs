//! Hierarchical radiosity against scene size: the Cornell box with every polygon tessellated
//! ([`radiosity::generate::tessellated`]: 38 k² triangles, about 610, 2.4k, 9.7k and 39k),
//! solved with `--solver hierarchical` at the default ε. The slope of time against input
//! size is the method's scaling exponent (coplanar pieces merge back: flat). The larger
//! sizes, furnished rooms and peak memory are in the `scale` bench.
//!
//! Run: `cargo bench -p radiosity --bench hierarchical`

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use radiosity::cornell::cornell_box;
use radiosity::generate::tessellated;
use radiosity::pipeline::{solve_scene, SolveSettings};
use radiosity::progress::NoProgress;
use radiosity::solve::{SolveOptions, SolverKind};
use std::time::Duration;

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
