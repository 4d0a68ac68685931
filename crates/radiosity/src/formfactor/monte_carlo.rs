//! `monte-carlo`: the form factor as the probability that a cosine-distributed ray from a
//! uniformly chosen point of A_i lands on A_j first.
//!
//! F_{i→j} = (1/A_i) ∫_{A_i} ∫_{Ω} [ray(x, ω) hits A_j first] (cosθ/π) dω dA_x, so with x
//! uniform on A_i and ω drawn from the cosine density cosθ/π (Malley's method),
//!
//!   F̂ = (1/N) Σ_k H_k,   H_k ∈ {0, 1},   stderr = √(F̂ (1 − F̂) / (N − 1)),
//!
//! an unbiased Bernoulli estimate (Malley 1988; the "hemisphere ray" estimator of Cohen &
//! Wallace 1993, §4.10). It is preferred here to random point pairs, whose estimate
//! A_j cosθ_x cosθ_y V / (π r²) has infinite variance for polygons that share an edge (the
//! 1/r² kernel is not square-integrable there); every ray's weight here is 0 or 1.
//!
//! - Mesh engine ([`MonteCarlo`]): from each element, `rays` rays traced through the shared
//!   BVH; the first surface hit (front side only: backs are black) and the element containing
//!   the hit point receive the ray, so one batch of rays gives the element's whole row, by
//!   patch and by element (the near field). Rows are computed on first use and kept
//!   (sparse: at most `rays` entries per element).
//! - Pair problems ([`monte_carlo_pair`]): rays against `to` and the occluders.
//!
//! Random numbers: PCG-64 (MCG variant) seeded from the seed and the element (or batch)
//! index, so results are deterministic whatever the thread count.

use super::kernel::{Division, Kernel, Receiver, SourcePolygon};
use super::pair::{Estimate, PairProblem, Source};
use super::{Engine, FormFactorMethod, Visibility};
use crate::geometry::newell;
use crate::mesh::Mesh;
use glam::{DVec2, DVec3};
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64Mcg;
use rayon::prelude::*;
use std::f64::consts::PI;
use std::sync::OnceLock;

/// Rays per element in the mesh engine: stderr of each F_{e→p} ≤ 0.5/√4096 ≈ 0.008.
pub const DEFAULT_RAYS: usize = 4096;
/// Rays per direction in pair problems: stderr ≤ 0.5/√2²⁰ ≈ 4.9e-4.
pub const DEFAULT_PAIR_RAYS: usize = 1 << 20;
/// Default seed.
pub const DEFAULT_SEED: u64 = 1;
/// Rays per independently seeded batch in pair problems.
const BATCH: usize = 1 << 14;

/// Parameters of the Monte Carlo mesh engine.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MonteCarloParams {
    /// Rays per element.
    pub rays: usize,
    /// Seed of the random streams.
    pub seed: u64,
}

impl Default for MonteCarloParams {
    fn default() -> Self {
        Self {
            rays: DEFAULT_RAYS,
            seed: DEFAULT_SEED,
        }
    }
}

/// A stream of random numbers for one element or batch.
fn stream(seed: u64, index: u64) -> Pcg64Mcg {
    Pcg64Mcg::seed_from_u64(seed ^ index.wrapping_add(1).wrapping_mul(0x9e37_79b9_7f4a_7c15))
}

/// Uniform points on a convex polygon: a fan of triangles chosen by area.
struct AreaSampler {
    tris: Vec<[DVec3; 3]>,
    cdf: Vec<f64>,
}

impl AreaSampler {
    fn new(v: &[DVec3]) -> Self {
        let tris: Vec<[DVec3; 3]> = v[1..].windows(2).map(|w| [v[0], w[0], w[1]]).collect();
        let mut total = 0.0;
        let mut cdf: Vec<f64> = tris
            .iter()
            .map(|t| {
                total += (t[1] - t[0]).cross(t[2] - t[0]).length();
                total
            })
            .collect();
        cdf.iter_mut().for_each(|c| *c /= total);
        Self { tris, cdf }
    }

    fn sample(&self, rng: &mut Pcg64Mcg) -> DVec3 {
        let pick: f64 = rng.random();
        let i = self
            .cdf
            .partition_point(|&c| c < pick)
            .min(self.tris.len() - 1);
        let [a, b, c] = self.tris[i];
        let (u, v): (f64, f64) = (rng.random(), rng.random());
        let s = u.sqrt();
        a * (1.0 - s) + b * (s * (1.0 - v)) + c * (s * v)
    }
}

/// A cosine-distributed direction about the unit normal `n` (Malley's method: a uniform
/// point of the unit disk lifted to the hemisphere).
fn cosine_direction(n: DVec3, rng: &mut Pcg64Mcg) -> DVec3 {
    let (u, v): (f64, f64) = (rng.random(), rng.random());
    let r = u.sqrt();
    let phi = 2.0 * PI * v;
    let (t, b) = n.any_orthonormal_pair();
    (t * (r * phi.cos()) + b * (r * phi.sin()) + n * (1.0 - u).max(0.0).sqrt()).normalize()
}

/// A convex polygon as a ray target: plane plus a 2-D point-in-polygon test in O(log n).
struct Target {
    origin: DVec3,
    normal: DVec3,
    u: DVec3,
    w: DVec3,
    flat: Vec<DVec2>,
}

impl Target {
    fn new(v: &[DVec3]) -> Self {
        let normal = newell(v).0;
        let origin = v[0];
        let u = (v[1] - origin).normalize();
        let w = normal.cross(u);
        let flat = v
            .iter()
            .map(|p| DVec2::new((*p - origin).dot(u), (*p - origin).dot(w)))
            .collect();
        Self {
            origin,
            normal,
            u,
            w,
            flat,
        }
    }

    /// The distance along the ray `x + t d` to the target's front, if it hits it.
    fn hit(&self, x: DVec3, d: DVec3) -> Option<f64> {
        let denom = d.dot(self.normal);
        if denom >= 0.0 {
            return None; // parallel, or arriving at the back
        }
        let t = (self.origin - x).dot(self.normal) / denom;
        if t.is_nan() || t <= 0.0 {
            return None;
        }
        let p = x + d * t - self.origin;
        self.contains(DVec2::new(p.dot(self.u), p.dot(self.w)))
            .then_some(t)
    }

    /// Point in a convex counter-clockwise polygon: binary search of the fan about vertex 0.
    fn contains(&self, q: DVec2) -> bool {
        let p = &self.flat;
        let n = p.len();
        let q0 = q - p[0];
        if (p[1] - p[0]).perp_dot(q0) < 0.0 || (p[n - 1] - p[0]).perp_dot(q0) > 0.0 {
            return false;
        }
        // The last fan vertex i with (p_i − p_0) × q0 ≥ 0.
        let (mut lo, mut hi) = (1, n - 1);
        while hi - lo > 1 {
            let mid = (lo + hi) / 2;
            if (p[mid] - p[0]).perp_dot(q0) >= 0.0 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        (p[hi] - p[lo]).perp_dot(q - p[lo]) >= 0.0
    }
}

/// `monte-carlo` on a pair problem: `rays` cosine-distributed rays from uniform points of
/// `from` (or from the point), counted when they reach the front of `to` before any occluder.
pub fn monte_carlo_pair(problem: &PairProblem, rays: usize, seed: u64) -> Estimate {
    let rays = rays.max(2);
    let target = Target::new(&problem.to);
    let vis = problem.occluder_visibility();
    let (sampler, point, normal) = match &problem.from {
        Source::Point { point, normal } => (None, *point, *normal),
        Source::Polygon(v) => (Some(AreaSampler::new(v)), v[0], newell(v).0),
    };
    let batches = rays.div_ceil(BATCH);
    let hits: u64 = (0..batches)
        .into_par_iter()
        .map(|b| {
            let mut rng = stream(seed, b as u64);
            let count = BATCH.min(rays - b * BATCH);
            let mut hits = 0u64;
            for _ in 0..count {
                let x = sampler.as_ref().map_or(point, |s| s.sample(&mut rng));
                let d = cosine_direction(normal, &mut rng);
                let Some(t) = target.hit(x, d) else { continue };
                let blocked = vis.as_ref().is_some_and(|v| {
                    let eps = v.offset();
                    t > 2.0 * eps
                        && v.bvh()
                            .occluded(x.as_vec3(), d.as_vec3(), eps as f32, (t - eps) as f32)
                });
                hits += u64::from(!blocked);
            }
            hits
        })
        .sum();
    let n = rays as f64;
    let f = hits as f64 / n;
    Estimate {
        value: f,
        stderr: Some((f * (1.0 - f) / (n - 1.0)).sqrt()),
    }
}

/// The Monte Carlo kernel: `rays` cosine-distributed rays from uniform points of the
/// receiver (or from the point), counted when they reach the front of the source before any
/// surface of the visibility query's scene blocks them. Deterministic in `seed` and the
/// receiver's position.
#[derive(Debug, Clone, Copy)]
pub struct MonteCarloKernel {
    /// Rays per pair.
    pub rays: usize,
    /// Seed.
    pub seed: u64,
}

impl Default for MonteCarloKernel {
    fn default() -> Self {
        Self {
            rays: DEFAULT_RAYS,
            seed: DEFAULT_SEED,
        }
    }
}

impl Kernel for MonteCarloKernel {
    fn method(&self) -> FormFactorMethod {
        FormFactorMethod::MonteCarlo
    }

    fn source(&self, vertices: &[DVec3]) -> SourcePolygon {
        SourcePolygon::new(vertices, 1, 1, Division::Lattice)
    }

    fn form_factor(&self, r: &Receiver, s: &SourcePolygon, visibility: &Visibility) -> f64 {
        let target = Target::new(&s.vertices);
        let sampler = (!r.is_point()).then(|| AreaSampler::new(&r.vertices));
        let key = r.centre.to_array().map(f64::to_bits);
        let mut rng = stream(
            self.seed,
            key[0] ^ key[1].rotate_left(21) ^ key[2].rotate_left(42),
        );
        let mut hits = 0usize;
        for _ in 0..self.rays.max(1) {
            let x = sampler.as_ref().map_or(r.centre, |a| a.sample(&mut rng));
            let d = cosine_direction(r.normal, &mut rng);
            let Some(t) = target.hit(x, d) else { continue };
            let y = x + d * t;
            if visibility.visible(x, r.normal, y, s.normal) {
                hits += 1;
            }
        }
        hits as f64 / self.rays.max(1) as f64
    }
}

/// Finds the element of one surface containing a point: a uniform grid over the surface's
/// plane, each cell listing the elements whose bounds overlap it.
struct ElementLocator {
    origin: DVec3,
    u: DVec3,
    w: DVec3,
    lo: DVec2,
    cell: DVec2,
    dims: [usize; 2],
    cells: Vec<Vec<u32>>,
    /// Per element: its index and 2-D vertex loop.
    loops: Vec<(u32, Vec<DVec2>)>,
}

impl ElementLocator {
    fn new(mesh: &Mesh, surface: usize) -> Self {
        let poly = &mesh.surface_polygons[surface];
        let origin = poly.vertices()[0];
        let u = (poly.vertices()[1] - origin).normalize();
        let w = poly.normal().cross(u);
        let flat = |p: DVec3| DVec2::new((p - origin).dot(u), (p - origin).dot(w));
        let loops: Vec<(u32, Vec<DVec2>)> = mesh
            .elements
            .iter()
            .enumerate()
            .filter(|(_, e)| e.surface as usize == surface)
            .map(|(i, e)| {
                (
                    i as u32,
                    e.corners
                        .iter()
                        .map(|&c| flat(mesh.vertices[c as usize]))
                        .collect(),
                )
            })
            .collect();
        let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
        for q in loops.iter().flat_map(|(_, l)| l) {
            lo = lo.min(*q);
            hi = hi.max(*q);
        }
        let side = ((loops.len().max(1) as f64).sqrt().ceil() as usize).clamp(1, 1024);
        let dims = [side, side];
        let cell = ((hi - lo) / side as f64).max(DVec2::splat(1e-300));
        let mut cells = vec![Vec::new(); side * side];
        for (k, (_, l)) in loops.iter().enumerate() {
            let (mut a, mut b) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
            for q in l {
                a = a.min(*q);
                b = b.max(*q);
            }
            let index = |q: DVec2, axis: usize| {
                (((q[axis] - lo[axis]) / cell[axis]).floor().max(0.0) as usize).min(dims[axis] - 1)
            };
            for i in index(a, 0)..=index(b, 0) {
                for j in index(a, 1)..=index(b, 1) {
                    cells[i * side + j].push(k as u32);
                }
            }
        }
        Self {
            origin,
            u,
            w,
            lo,
            cell,
            dims,
            cells,
            loops,
        }
    }

    /// The element containing `p` (on the surface's plane); at a boundary or outside by
    /// rounding, the nearest candidate (largest minimum signed edge distance).
    fn find(&self, p: DVec3) -> Option<u32> {
        let q = DVec2::new((p - self.origin).dot(self.u), (p - self.origin).dot(self.w));
        let index = |axis: usize| {
            (((q[axis] - self.lo[axis]) / self.cell[axis])
                .floor()
                .max(0.0) as usize)
                .min(self.dims[axis] - 1)
        };
        let candidates = &self.cells[index(0) * self.dims[1] + index(1)];
        let mut best: Option<(f64, u32)> = None;
        for &k in candidates {
            let (element, l) = &self.loops[k as usize];
            let n = l.len();
            let inside = (0..n)
                .map(|i| {
                    let (a, b) = (l[i], l[(i + 1) % n]);
                    (b - a).perp_dot(q - a) / (b - a).length().max(1e-300)
                })
                .fold(f64::INFINITY, f64::min);
            if best.is_none_or(|(d, _)| inside > d) {
                best = Some((inside, *element));
            }
        }
        best.map(|(_, p)| p)
    }
}

/// The `monte-carlo` mesh engine (see the module docs).
pub struct MonteCarlo<'a> {
    mesh: &'a Mesh,
    visibility: &'a Visibility,
    params: MonteCarloParams,
    locators: Vec<ElementLocator>,
    /// Per element: (element hit, rays) for every element hit, sorted by element (and so by
    /// patch: a patch's elements are contiguous).
    rows: Vec<OnceLock<Vec<(u32, u32)>>>,
}

impl<'a> MonteCarlo<'a> {
    /// The engine over `mesh` with the default rays and seed.
    pub fn new(mesh: &'a Mesh, visibility: &'a Visibility) -> Self {
        Self::with_params(mesh, visibility, MonteCarloParams::default())
    }

    /// The engine over `mesh` with the given rays and seed.
    pub fn with_params(
        mesh: &'a Mesh,
        visibility: &'a Visibility,
        params: MonteCarloParams,
    ) -> Self {
        Self {
            mesh,
            visibility,
            params: MonteCarloParams {
                rays: params.rays.max(1),
                ..params
            },
            locators: (0..mesh.surface_polygons.len())
                .map(|s| ElementLocator::new(mesh, s))
                .collect(),
            rows: (0..mesh.elements.len()).map(|_| OnceLock::new()).collect(),
        }
    }

    fn row_of(&self, element: usize) -> &[(u32, u32)] {
        self.rows[element].get_or_init(|| self.trace(element))
    }

    fn trace(&self, element: usize) -> Vec<(u32, u32)> {
        let e = &self.mesh.elements[element];
        let corners: Vec<DVec3> = e
            .corners
            .iter()
            .map(|&c| self.mesh.vertices[c as usize])
            .collect();
        let sampler = AreaSampler::new(&corners);
        let mut rng = stream(self.params.seed, element as u64);
        let lift = e.normal * self.visibility.offset();
        let mut hits: Vec<u32> = Vec::with_capacity(self.params.rays);
        for _ in 0..self.params.rays {
            let x = sampler.sample(&mut rng) + lift;
            let d = cosine_direction(e.normal, &mut rng);
            let Some(hit) = self.visibility.first_hit(x.as_vec3(), d.as_vec3()) else {
                continue; // escaped
            };
            let s = self.visibility.polygon_of(hit.triangle);
            if s == e.surface as usize || d.dot(self.mesh.surface_polygons[s].normal()) >= 0.0 {
                continue; // a back face: absorbed, black
            }
            if let Some(h) = self.locators[s].find(x + d * hit.t as f64) {
                hits.push(h);
            }
        }
        hits.sort_unstable();
        let mut row: Vec<(u32, u32)> = Vec::new();
        for h in hits {
            match row.last_mut() {
                Some((q, n)) if *q == h => *n += 1,
                _ => row.push((h, 1)),
            }
        }
        row
    }

    fn fraction(&self, rays: u32) -> f64 {
        rays as f64 / self.params.rays as f64
    }
}

impl Engine for MonteCarlo<'_> {
    fn method(&self) -> FormFactorMethod {
        FormFactorMethod::MonteCarlo
    }

    fn pair(&self, element: usize, patch: usize) -> f64 {
        let row = self.row_of(element);
        let range = &self.mesh.patches[patch].elements;
        let start = row.partition_point(|(h, _)| *h < range.start);
        let end = row.partition_point(|(h, _)| *h < range.end);
        self.fraction(row[start..end].iter().map(|(_, n)| n).sum())
    }

    /// The share of the element's rays that landed on `source` first.
    fn element_pair(&self, element: usize, source: usize) -> f64 {
        let row = self.row_of(element);
        match row.binary_search_by_key(&(source as u32), |(h, _)| *h) {
            Ok(i) => self.fraction(row[i].1),
            Err(_) => 0.0,
        }
    }

    fn row(&self, element: usize, out: &mut [f32]) {
        out.fill(0.0);
        for &(h, n) in self.row_of(element) {
            out[self.mesh.elements[h as usize].patch.0 as usize] += self.fraction(n) as f32;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn target_contains_its_inside_only() {
        let n = 7;
        let v: Vec<DVec3> = (0..n)
            .map(|k| {
                let a = 2.0 * PI * k as f64 / n as f64;
                DVec3::new(a.cos(), a.sin(), 0.0)
            })
            .collect();
        let t = Target::new(&v);
        let mut rng = stream(3, 0);
        for _ in 0..10_000 {
            let q = DVec3::new(
                rng.random_range(-1.2..1.2),
                rng.random_range(-1.2..1.2),
                0.0,
            );
            // Inside a convex polygon iff left of every edge.
            let inside = (0..n).all(|i| (v[(i + 1) % n] - v[i]).cross(q - v[i]).z >= 0.0);
            let p = q - t.origin;
            assert_eq!(
                t.contains(DVec2::new(p.dot(t.u), p.dot(t.w))),
                inside,
                "{q}"
            );
        }
    }

    #[test]
    fn cosine_directions_have_the_cosine_density() {
        // E[cosθ] = 2/3 for the density cosθ/π; stderr of the mean ≈ 0.24/√N.
        let mut rng = stream(5, 0);
        let n = DVec3::new(1.0, 2.0, -0.5).normalize();
        let m = 200_000;
        let mean: f64 = (0..m)
            .map(|_| cosine_direction(n, &mut rng).dot(n))
            .sum::<f64>()
            / m as f64;
        assert!(
            (mean - 2.0 / 3.0).abs() < 4.0 * 0.24 / (m as f64).sqrt(),
            "{mean}"
        );
    }
}
