//! `point-sampled`: the lecture's finite-sum approximation of the form-factor integral.
//!
//! The inner integral of F_{i→j} = (1/A_i) ∫_{A_i} ∫_{A_j} cosθ_x cosθ_y V(x, y) / (π r²) dA_y dA_x
//! is replaced by a sum over small sub-areas ΔA_y of the receiving polygon A_j, each taken
//! at its centroid y (Cohen & Wallace 1993, "Radiosity and Realistic Image Synthesis", §4.9;
//! the classic "point sampling" of the kernel):
//!
//!   F_{dA_x→A_j} ≈ Σ_y cosθ_x cosθ_y V(x, y) ΔA_y / (π r²),
//!
//! with θ_x, θ_y the angles between the ray x→y and the normals (one-sided: back-facing
//! terms are 0) and V(x, y) ∈ {0, 1} from one shadow ray through the shared BVH.
//!
//! - Mesh engine ([`PointSampled`]): x is the element's centre and the sum runs over about
//!   `samples` sub-areas of the patch (or, for the solver's near field, of a single source
//!   element).
//! - Pair problems ([`point_sampled_pair`]): a polygon `from` is divided the same way and the
//!   sum averaged over its sub-areas, (1/A_i) Σ_x ΔA_x Σ_y (…), the double finite sum.
//!
//! The error is that of the midpoint rule, O(h²/r²) for sub-areas of size h at distance r,
//! but the kernel is singular where polygons touch (1/r² at a shared edge), and there the
//! sum converges only like O(h): adjacent polygons need many samples.

use super::analytic::area_centroid;
use super::pair::{Estimate, PairProblem, Source};
use super::{sub_areas, FormFactors, Visibility};
use crate::geometry::newell;
use crate::mesh::Mesh;
use glam::DVec3;
use rayon::prelude::*;
use std::f64::consts::PI;
use std::sync::OnceLock;

/// Sub-areas per patch in the mesh engine (4 × 4 on a quad patch).
pub const DEFAULT_SAMPLES: usize = 16;
/// Sub-areas per polygon in pair problems (64 × 64 on a quad).
pub const DEFAULT_PAIR_SAMPLES: usize = 4096;

/// One sub-area: centroid and area.
#[derive(Debug, Clone, Copy)]
struct Sample {
    point: DVec3,
    area: f64,
}

/// About `samples` sub-areas of a convex polygon (k × k with k = round(√samples) for a
/// triangle or quad; a clipped grid for larger polygons).
fn samples_of(vertices: &[DVec3], samples: usize) -> Vec<Sample> {
    let k = ((samples.max(1) as f64).sqrt().round() as usize).max(1);
    sub_areas(vertices, k)
        .iter()
        .map(|p| Sample {
            point: area_centroid(p),
            area: newell(p).1,
        })
        .collect()
}

/// The kernel cosθ_x cosθ_y / (π r²) for a ray from x (normal nx) to y (normal ny), 0 when
/// either side faces away.
#[inline]
fn kernel(x: DVec3, nx: DVec3, y: DVec3, ny: DVec3) -> f64 {
    let d = y - x;
    let r2 = d.length_squared();
    let (cx, cy) = (d.dot(nx), -d.dot(ny));
    if cx <= 0.0 || cy <= 0.0 || r2 <= 0.0 {
        return 0.0;
    }
    cx * cy / (PI * r2 * r2)
}

/// The `point-sampled` mesh engine: element centre to the sub-areas of the patch.
pub struct PointSampled<'a> {
    mesh: &'a Mesh,
    visibility: &'a Visibility,
    samples: usize,
    sources: Vec<(Vec<Sample>, DVec3)>,
    /// Elements as sources for the near field, divided on first use.
    element_sources: Vec<OnceLock<Vec<Sample>>>,
}

impl<'a> PointSampled<'a> {
    pub fn new(mesh: &'a Mesh, visibility: &'a Visibility) -> Self {
        Self::with_samples(mesh, visibility, DEFAULT_SAMPLES)
    }

    /// With about `samples` sub-areas per patch.
    pub fn with_samples(mesh: &'a Mesh, visibility: &'a Visibility, samples: usize) -> Self {
        let sources = mesh
            .patches
            .iter()
            .map(|p| {
                (
                    samples_of(p.polygon.vertices(), samples),
                    p.polygon.normal(),
                )
            })
            .collect();
        Self {
            mesh,
            visibility,
            samples,
            sources,
            element_sources: (0..mesh.elements.len()).map(|_| OnceLock::new()).collect(),
        }
    }
}

impl PointSampled<'_> {
    fn receive(&self, element: usize, samples: &[Sample], ny: DVec3) -> f64 {
        let e = &self.mesh.elements[element];
        samples
            .iter()
            .map(|s| {
                let k = kernel(e.centre, e.normal, s.point, ny);
                if k > 0.0 && self.visibility.visible(e.centre, e.normal, s.point, ny) {
                    k * s.area
                } else {
                    0.0
                }
            })
            .sum()
    }
}

impl FormFactors for PointSampled<'_> {
    fn name(&self) -> &'static str {
        "point-sampled"
    }

    fn pair(&self, element: usize, patch: usize) -> f64 {
        if self.mesh.elements[element].surface == self.mesh.patches[patch].surface {
            return 0.0;
        }
        let (samples, ny) = &self.sources[patch];
        self.receive(element, samples, *ny)
    }

    /// The same sum over about as many sub-areas of the single source element.
    fn element_pair(&self, element: usize, source: usize) -> Option<f64> {
        let (e, s) = (&self.mesh.elements[element], &self.mesh.elements[source]);
        if e.surface == s.surface {
            return Some(0.0);
        }
        let samples = self.element_sources[source].get_or_init(|| {
            let corners: Vec<DVec3> = s
                .corners
                .iter()
                .map(|&c| self.mesh.vertices[c as usize])
                .collect();
            samples_of(&corners, self.samples)
        });
        Some(self.receive(element, samples, s.normal))
    }

    fn resolves_elements(&self) -> bool {
        true
    }
}

/// `point-sampled` on a pair problem with about `samples` sub-areas on each polygon (a
/// differential `from` is its own single point). Deterministic; no standard error (the error
/// is a discretisation bias, not noise).
pub fn point_sampled_pair(problem: &PairProblem, samples: usize) -> Estimate {
    let ny = newell(&problem.to).0;
    let to = samples_of(&problem.to, samples);
    let vis = problem.occluder_visibility();
    let (from, nx, area) = match &problem.from {
        Source::Point { point, normal } => (
            vec![Sample {
                point: *point,
                area: 1.0,
            }],
            *normal,
            1.0,
        ),
        Source::Polygon(v) => {
            let (n, a) = newell(v);
            (samples_of(v, samples), n, a)
        }
    };
    let sum: f64 = from
        .par_iter()
        .map(|x| {
            let inner: f64 = to
                .iter()
                .map(|y| {
                    let k = kernel(x.point, nx, y.point, ny);
                    let visible = k > 0.0
                        && vis
                            .as_ref()
                            .is_none_or(|v| v.visible(x.point, nx, y.point, ny));
                    if visible {
                        k * y.area
                    } else {
                        0.0
                    }
                })
                .sum();
            x.area * inner
        })
        .sum();
    Estimate::exact(sum / area)
}
