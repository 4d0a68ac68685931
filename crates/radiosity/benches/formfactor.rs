//! Form-factor cost: time per form factor of every method on a reference case, hemi-cube form
//! factors per second by resolution, and the full Cornell box solve per method.
//!
//! Run with `cargo bench -p radiosity --bench formfactor`; "thrpt" lines are form factors
//! per second. Each benchmark takes seconds (10 samples).

use std::hint::black_box;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use radiosity::cornell::cornell_box;
use radiosity::formfactor::hemicube::{Hemicube, HemicubeParams};
use radiosity::formfactor::pair::{estimate, PairSettings};
use radiosity::formfactor::table::reference_cases;
use radiosity::formfactor::{Engine, FormFactorMethod};
use radiosity::mesh::{Mesh, MeshOptions};
use radiosity::pipeline::{solve_scene, SolveSettings};
use radiosity::progress::NoProgress;

/// F_{1→2} of Howell C-11 (unit squares one apart) and C-14 (unit squares sharing an
/// edge), at each method's default settings.
fn bench_pair(c: &mut Criterion) {
    let cases = reference_cases();
    let settings = PairSettings::default();
    for name in ["C-11 a=1 b=1 c=1", "C-14 h=1 l=1 w=1"] {
        let case = cases
            .iter()
            .find(|c| c.name == name)
            .expect("reference case");
        let mut group = c.benchmark_group(format!("pair {name}"));
        group.throughput(Throughput::Elements(1));
        for &method in FormFactorMethod::ALL {
            group.bench_function(method.name(), |b| {
                b.iter(|| estimate(black_box(&case.problem), method, &settings))
            });
        }
        group.finish();
    }
}

/// Hemi-cube rows (one hemi-cube at an element's centre, every patch rasterised) on the
/// default Cornell mesh, at resolutions 64, 128 and 256; throughput in form factors.
fn bench_hemicube(c: &mut Criterion) {
    let mesh = Mesh::build(&cornell_box(), &MeshOptions::default()).expect("Cornell mesh");
    let elements: Vec<usize> = (0..mesh.elements.len())
        .step_by(mesh.elements.len() / 32)
        .collect();
    let mut group = c.benchmark_group(format!(
        "hemicube rows, Cornell {} elements x {} patches",
        mesh.elements.len(),
        mesh.patches.len()
    ));
    group.throughput(Throughput::Elements(
        (elements.len() * mesh.patches.len()) as u64,
    ));
    for resolution in [64, 128, 256] {
        let engine = Hemicube::new(
            &mesh,
            HemicubeParams {
                resolution,
                ..Default::default()
            },
            &[],
        );
        let mut row = vec![0.0f32; mesh.patches.len()];
        group.bench_function(format!("resolution {resolution}"), |b| {
            b.iter(|| {
                for &e in &elements {
                    engine.row(e, &mut row);
                }
                black_box(&row);
            })
        });
    }
    group.finish();
}

/// The whole Cornell box (default mesh, about 4.7k elements; progressive refinement to its
/// default tolerance) with each method: meshing, form factors and solve.
fn bench_cornell(c: &mut Criterion) {
    let scene = cornell_box();
    let mut group = c.benchmark_group("cornell solve");
    group.sample_size(10).warm_up_time(Duration::from_millis(1));
    for &method in FormFactorMethod::ALL {
        let settings = SolveSettings {
            form_factor: method,
            ..Default::default()
        };
        group.bench_function(method.name(), |b| {
            b.iter(|| solve_scene(black_box(&scene), &settings, &NoProgress).expect("solve"))
        });
    }
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2));
    targets = bench_pair, bench_hemicube, bench_cornell
}
criterion_main!(benches);
