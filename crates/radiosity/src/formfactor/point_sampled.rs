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
//! - Kernel ([`PointSampledKernel`]): x is the receiver's centre and the sum runs over about
//!   `samples` sub-areas of the patch (or, for the solver's near field, of a single source
//!   element).
//! - Pair problems ([`point_sampled_pair`]): a polygon `from` is divided the same way and the
//!   sum averaged over its sub-areas, (1/A_i) Σ_x ΔA_x Σ_y (…), the double finite sum.
//!
//! The error is that of the midpoint rule, O(h²/r²) for sub-areas of size h at distance r,
//! but the kernel is singular where polygons touch (1/r² at a shared edge), and there the
//! sum converges only like O(h): adjacent polygons need many samples.

use super::analytic::area_centroid;
use super::kernel::{Division, Kernel, Receiver, SourcePolygon};
use super::pair::{Estimate, PairProblem, Source};
use super::{FormFactorMethod, Visibility};
use crate::geometry::{newell, sub_areas};
use glam::DVec3;
use rayon::prelude::*;
use std::f64::consts::PI;

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

/// The `point-sampled` kernel: the receiver's centre to about `samples` sub-areas of the
/// source, one shadow ray each.
#[derive(Debug, Clone, Copy)]
pub struct PointSampledKernel {
    /// Sub-areas per source (4 × 4 on a quad by default).
    pub samples: usize,
}

impl Default for PointSampledKernel {
    fn default() -> Self {
        Self {
            samples: DEFAULT_SAMPLES,
        }
    }
}

impl Kernel for PointSampledKernel {
    fn method(&self) -> FormFactorMethod {
        FormFactorMethod::PointSampled
    }

    fn source(&self, vertices: &[DVec3]) -> SourcePolygon {
        let k = ((self.samples.max(1) as f64).sqrt().round() as usize).max(1);
        SourcePolygon::new(vertices, 1, k, Division::SubAreas)
    }

    fn form_factor(&self, r: &Receiver, s: &SourcePolygon, visibility: &Visibility) -> f64 {
        s.sub_points
            .iter()
            .zip(&s.sub_area_sizes)
            .map(|(&y, &area)| {
                let k = kernel(r.centre, r.normal, y, s.normal);
                if k > 0.0 && visibility.visible(r.centre, r.normal, y, s.normal) {
                    k * area
                } else {
                    0.0
                }
            })
            .sum()
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
