//! Shots per second of progressive refinement on the Cornell box at about 4k and 16k
//! elements, each shot's column of form factors F_{e→p} computed on the fly (raycast, in
//! parallel over the elements; no column cache), as for scenes too large for the matrix.
//!
//! Run with `cargo bench -p radiosity --bench progressive`; the shots/s figures are
//! criterion's "thrpt" lines (elements/s = shots/s).

use std::hint::black_box;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use radiosity::cornell::cornell_box;
use radiosity::coupling::closure::Enclosure;
use radiosity::coupling::{Columns, NearField};
use radiosity::formfactor::{engine, FormFactorMethod, Visibility};
use radiosity::mesh::{Mesh, MeshOptions};
use radiosity::solve::progressive::Progressive;
use radiosity::solve::SolveOptions;

/// Shots per measured iteration.
const SHOTS: usize = 4;

fn shots_per_second(c: &mut Criterion) {
    let mut group = c.benchmark_group("progressive");
    group
        .sample_size(10)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(6))
        .throughput(Throughput::Elements(SHOTS as u64));
    for elements in [4000, 14000] {
        let mesh = Mesh::build(
            &cornell_box(),
            &MeshOptions {
                elements,
                ..Default::default()
            },
        )
        .unwrap();
        let visibility = Visibility::new(&mesh);
        let near = NearField::decide(&mesh);
        let enclosure = Enclosure::probe(&mesh, &visibility);
        let ff = engine(
            FormFactorMethod::Raycast,
            &mesh,
            &visibility,
            &near.per_element,
        );
        // No memory for cached columns: every shot computes its column.
        let coupling = Columns::new(&mesh, ff.as_ref(), &near, enclosure, 0);
        let options = SolveOptions::default();
        // One run carried on across iterations, so the shots measured are a stretch of a
        // real solution (the light first, then the brightest surfaces), not the light's
        // patches over and over.
        let mut state = Progressive::new(&coupling, &options);
        let id = format!(
            "cornell_{}_elements_{}_patches",
            mesh.len(),
            mesh.patches.len()
        );
        group.bench_function(id, |b| {
            b.iter(|| {
                for _ in 0..SHOTS {
                    if !state.shoot(&coupling) {
                        state = Progressive::new(&coupling, &options);
                    }
                }
                black_box(state.shots())
            })
        });
    }
    group.finish();
}

criterion_group!(benches, shots_per_second);
criterion_main!(benches);
