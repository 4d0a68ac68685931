//! BVH build time and ray throughput on a Cornell-like box of about 100k triangles.
//!
//! Run with `cargo bench -p radiosity --bench bvh`; the rays/s figures are criterion's
//! "thrpt" lines.

use std::hint::black_box;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use glam::Vec3;
use radiosity::accel::Bvh;
use rayon::prelude::*;

/// Each quad is split into `GRID × GRID` cells of two triangles: 18 quads give 101,124.
const GRID: usize = 53;
/// Rays per iteration.
const RAYS: usize = 100_000;

/// A planar quad given by its corners in order around it.
type Quad = [Vec3; 4];

/// The Cornell box: a closed 5.5 m room and two blocks standing on its floor, rotated like the
/// originals (all six faces of each block, so that the scene is a set of closed solids).
fn cornell_quads() -> Vec<Quad> {
    let s = 5.5;
    let p = |x: f32, y: f32, z: f32| Vec3::new(x, y, z);
    let mut quads = vec![
        [p(0., 0., 0.), p(s, 0., 0.), p(s, 0., s), p(0., 0., s)], // floor
        [p(0., s, 0.), p(0., s, s), p(s, s, s), p(s, s, 0.)],     // ceiling
        [p(0., 0., s), p(s, 0., s), p(s, s, s), p(0., s, s)],     // back
        [p(0., 0., 0.), p(0., s, 0.), p(s, s, 0.), p(s, 0., 0.)], // front
        [p(0., 0., 0.), p(0., 0., s), p(0., s, s), p(0., s, 0.)], // left
        [p(s, 0., 0.), p(s, s, 0.), p(s, s, s), p(s, 0., s)],     // right
    ];
    quads.extend(block(Vec3::new(1.85, 0.0, 1.7), 1.65, 1.65, -0.3));
    quads.extend(block(Vec3::new(3.65, 0.0, 3.5), 1.65, 3.3, 0.3));
    quads
}

/// The six faces of a `width`-square, `height`-tall block centred on `base`, turned by `angle`
/// radians about the vertical.
fn block(base: Vec3, width: f32, height: f32, angle: f32) -> Vec<Quad> {
    let (sin, cos) = angle.sin_cos();
    let h = width / 2.0;
    let corner = |x: f32, y: f32, z: f32| base + Vec3::new(x * cos - z * sin, y, x * sin + z * cos);
    let bottom = [(-h, -h), (h, -h), (h, h), (-h, h)].map(|(x, z)| corner(x, 0.0, z));
    let top = [(-h, -h), (h, -h), (h, h), (-h, h)].map(|(x, z)| corner(x, height, z));
    let mut faces = vec![bottom, [top[3], top[2], top[1], top[0]]];
    for i in 0..4 {
        let j = (i + 1) % 4;
        faces.push([bottom[i], top[i], top[j], bottom[j]]);
    }
    faces
}

/// A point of a quad at parameters `(s, t)` in [0, 1]².
fn quad_point(q: &Quad, s: f32, t: f32) -> Vec3 {
    q[0] + (q[1] - q[0]) * s + (q[3] - q[0]) * t
}

/// The quads cut into `GRID × GRID` cells, two triangles each, sharing vertices exactly.
fn triangulate(quads: &[Quad]) -> Vec<[Vec3; 3]> {
    let mut triangles = Vec::with_capacity(quads.len() * GRID * GRID * 2);
    for q in quads {
        let vertex =
            |i: usize, j: usize| quad_point(q, i as f32 / GRID as f32, j as f32 / GRID as f32);
        for i in 0..GRID {
            for j in 0..GRID {
                let (a, b) = (vertex(i, j), vertex(i + 1, j));
                let (c, d) = (vertex(i + 1, j + 1), vertex(i, j + 1));
                triangles.push([a, b, c]);
                triangles.push([a, c, d]);
            }
        }
    }
    triangles
}

/// xorshift64*, uniform in [0, 1).
struct Rng(u64);

impl Rng {
    fn f32(&mut self) -> f32 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 40) as f32 / (1u64 << 24) as f32
    }
}

/// Segments between uniform points on two different quads: what form-factor visibility asks
/// (points on one planar face never see each other, so that pair is never asked).
fn shadow_segments(quads: &[Quad], count: usize) -> Vec<(Vec3, Vec3)> {
    let mut rng = Rng(0x853C_49E6_748F_EA9B);
    let pick = |rng: &mut Rng| ((rng.f32() * quads.len() as f32) as usize).min(quads.len() - 1);
    (0..count)
        .map(|_| {
            let a = pick(&mut rng);
            let mut b = pick(&mut rng);
            while b == a {
                b = pick(&mut rng);
            }
            let pa = quad_point(&quads[a], rng.f32(), rng.f32());
            let pb = quad_point(&quads[b], rng.f32(), rng.f32());
            (pa, pb)
        })
        .collect()
}

/// Rays from uniform points on the quads in uniformly random directions, for closest hits.
fn random_rays(quads: &[Quad], count: usize) -> Vec<(Vec3, Vec3)> {
    let mut rng = Rng(0xDA94_2042_E4DD_58B5);
    (0..count)
        .map(|_| {
            let q = ((rng.f32() * quads.len() as f32) as usize).min(quads.len() - 1);
            let origin = quad_point(&quads[q], rng.f32(), rng.f32());
            let z = 2.0 * rng.f32() - 1.0;
            let phi = std::f32::consts::TAU * rng.f32();
            let r = (1.0 - z * z).sqrt();
            (origin, Vec3::new(r * phi.cos(), r * phi.sin(), z))
        })
        .collect()
}

fn count_blocked(bvh: &Bvh, segments: &[(Vec3, Vec3)]) -> usize {
    segments
        .iter()
        .filter(|(a, b)| bvh.segment_occluded(*a, *b, 1e-4))
        .count()
}

fn bench_bvh(c: &mut Criterion) {
    let quads = cornell_quads();
    let triangles = triangulate(&quads);
    let bvh = Bvh::build(&triangles);
    let segments = shadow_segments(&quads, RAYS);
    let rays = random_rays(&quads, RAYS);
    let blocked = count_blocked(&bvh, &segments);
    eprintln!(
        "scene: {} triangles; {blocked} of {RAYS} shadow segments blocked; {} threads",
        triangles.len(),
        rayon::current_num_threads()
    );

    let mut group = c.benchmark_group("bvh");
    group
        .sample_size(10)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(3));

    group.throughput(Throughput::Elements(triangles.len() as u64));
    group.bench_function("build", |b| b.iter(|| Bvh::build(black_box(&triangles))));

    group.throughput(Throughput::Elements(RAYS as u64));
    group.bench_function("shadow_rays_1_thread", |b| {
        b.iter(|| count_blocked(&bvh, black_box(&segments)))
    });
    group.bench_function("shadow_rays_all_threads", |b| {
        b.iter(|| {
            black_box(&segments)
                .par_chunks(1024)
                .map(|chunk| count_blocked(&bvh, chunk))
                .sum::<usize>()
        })
    });
    group.bench_function("closest_hits_1_thread", |b| {
        b.iter(|| {
            black_box(&rays)
                .iter()
                .filter_map(|(o, d)| bvh.intersect(*o, *d, 1e-4, f32::INFINITY))
                .map(|hit| hit.t)
                .sum::<f32>()
        })
    });
    group.finish();
}

criterion_group!(benches, bench_bvh);
criterion_main!(benches);
