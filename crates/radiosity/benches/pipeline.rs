//! The whole method on the Cornell box at about 1k, 4k and 16k elements: form factors
//! (the full element × patch coupling, near field included), the default progressive solve
//! (form factors computed on the fly), and a 512×512 render of the solution.
//!
//! Run: `cargo bench -p radiosity --bench pipeline`

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use radiosity::cornell::cornell_box;
use radiosity::coupling::closure::Enclosure;
use radiosity::coupling::{Dense, NearField};
use radiosity::display::Shading;
use radiosity::formfactor::{engine, FormFactorMethod, Visibility};
use radiosity::mesh::{Mesh, MeshOptions};
use radiosity::pipeline::{render_elements, solve_scene, Shaded, SolveSettings};
use radiosity::progress::NoProgress;
use radiosity::render::RenderOptions;
use std::time::Duration;

const SIZES: [usize; 3] = [1000, 4000, 16000];

fn settings(elements: usize) -> SolveSettings {
    SolveSettings {
        mesh: MeshOptions {
            elements,
            ..Default::default()
        },
        ..Default::default()
    }
}

fn form_factors(c: &mut Criterion) {
    let mut g = c.benchmark_group("cornell_form_factors");
    g.sample_size(10).measurement_time(Duration::from_secs(5));
    let scene = cornell_box();
    for n in SIZES {
        let mesh = Mesh::build(&scene, &settings(n).mesh).unwrap();
        let vis = Visibility::new(&mesh);
        let near = NearField::decide(&mesh);
        let enclosure = Enclosure::probe(&mesh, &vis);
        let ff = engine(FormFactorMethod::Raycast, &mesh, &vis, &near.per_element);
        g.throughput(Throughput::Elements(
            (mesh.len() * mesh.patches.len()) as u64,
        ));
        g.bench_with_input(BenchmarkId::from_parameter(mesh.len()), &mesh, |b, mesh| {
            b.iter(|| Dense::compute(mesh, ff.as_ref(), &near, enclosure, &NoProgress))
        });
    }
    g.finish();
}

fn solve(c: &mut Criterion) {
    let mut g = c.benchmark_group("cornell_solve_progressive");
    g.sample_size(10).measurement_time(Duration::from_secs(5));
    let scene = cornell_box();
    for n in SIZES {
        let s = settings(n);
        let elements = Mesh::build(&scene, &s.mesh).unwrap().len();
        g.throughput(Throughput::Elements(elements as u64));
        g.bench_with_input(BenchmarkId::from_parameter(elements), &s, |b, s| {
            b.iter(|| solve_scene(&scene, s, &NoProgress).unwrap())
        });
    }
    g.finish();
}

fn render(c: &mut Criterion) {
    let mut g = c.benchmark_group("cornell_render_512");
    g.sample_size(10).measurement_time(Duration::from_secs(3));
    let scene = cornell_box();
    let camera = scene.camera.unwrap();
    let options = RenderOptions {
        width: 512,
        height: 512,
        ..Default::default()
    };
    for n in SIZES {
        let solved = solve_scene(&scene, &settings(n), &NoProgress).unwrap();
        let shaded = Shaded {
            vertices: &solved.mesh.vertices,
            elements: &solved.mesh.elements,
            radiosity: &solved.solution.radiosity,
        };
        g.throughput(Throughput::Elements(solved.mesh.len() as u64));
        g.bench_function(BenchmarkId::from_parameter(solved.mesh.len()), |b| {
            b.iter(|| render_elements(&shaded, &camera, Shading::Smooth, false, &options).unwrap())
        });
    }
    g.finish();
}

/// Time to a given accuracy: adaptive meshing with a 2000-element budget reaches about the
/// per-polygon error against Mitsuba (mean ~1.0 %) that a uniform mesh needs ~4700 elements
/// for (measured with `radiosity solve --solver gauss-seidel --elements N [--adaptive]`).
fn adaptive_vs_uniform(c: &mut Criterion) {
    use radiosity::mesh::RefineOptions;
    use radiosity::pipeline::solve_scene_adaptive;
    use radiosity::solve::{SolveOptions, SolverKind};
    let mut g = c.benchmark_group("cornell_same_accuracy");
    g.sample_size(10).measurement_time(Duration::from_secs(8));
    let scene = cornell_box();
    let with = |n: usize| SolveSettings {
        solve: SolveOptions {
            solver: SolverKind::GaussSeidel,
            ..Default::default()
        },
        ..settings(n)
    };
    let refine = RefineOptions {
        max_elements: Some(2000),
        ..Default::default()
    };
    g.bench_function("adaptive_2000", |b| {
        b.iter(|| solve_scene_adaptive(&scene, &with(2000), &refine, &NoProgress).unwrap())
    });
    g.bench_function("uniform_4000", |b| {
        b.iter(|| solve_scene(&scene, &with(4000), &NoProgress).unwrap())
    });
    g.finish();
}

criterion_group!(benches, form_factors, solve, render, adaptive_vs_uniform);
criterion_main!(benches);
