//! `analytic-point` and `analytic-polygon`: the exact unoccluded form factors as mesh engines
//! and pair solvers, with visibility estimated by shadow rays.
//!
//! - `analytic-point` ([`AnalyticPointKernel`]): the differential-area-to-polygon form factor of
//!   Lambert's contour formula (Baum, Rushmeier & Winget 1989, eq. 1;
//!   [`super::analytic_point::point_to_polygon`]),
//!
//!   F_{dA_x→A_p} = (1/2π) Σ_k γ_k · n_x,
//!
//!   evaluated at the element's centre (the classic point approximation of an element's
//!   form factor: exact for a differential element, O(size²/distance²) off for a finite one).
//!   On a pair problem with a polygon `from` the same exact kernel is averaged over `from` by
//!   globally adaptive cubature ([`average_over_polygon`], to 1e-9), so that the answer is
//!   the area-to-area factor F = (1/A_from) ∫ F_{dA_x→to} dA_x.
//! - `analytic-polygon` ([`AnalyticPolygonKernel`]): the exact polygon-to-polygon form factor by the
//!   double contour integral (Sparrow 1963; Schröder & Hanrahan 1993;
//!   [`super::analytic_polygon::polygon_to_polygon`]),
//!
//!   A_a F_ab = 1/(2π) Σ_i Σ_j (â_i · b̂_j) ∫_{edge i} ∫_{edge j} ln r dt ds,
//!
//!   from the element to the patch; a differential `from` uses the point form.
//!
//! Occlusion. Both closed forms are for the unoccluded pair. Both methods multiply them by a
//! visible fraction V ∈ [0, 1] estimated with shadow rays through the shared BVH
//! ([`visible_fraction`], after Wallace, Elmquist & Haines 1989): rays from receiver points to
//! probe points of the source; when they all agree (the common case) V is exactly 1 or 0,
//! so unoccluded pairs keep their exact value; otherwise (a penumbra) V is the fraction of the
//! exact sub-area form factors Σ_k F_{x→ΔA_k} whose sample ray is unblocked. The answer is
//! exact when nothing occludes, or when an occluder hides whole penumbra sub-areas (as in the
//! half-hidden test), and otherwise approximates the shadow boundary at the resolution of the
//! sub-areas.
//!
//! Both are [`Kernel`]s: the mesh engines call them per element and patch, and per pair of
//! elements for the near field.

use super::analytic_point::point_to_polygon;
use super::analytic_polygon::polygon_to_polygon;
use super::kernel::{
    polygon_centroid, visible_fraction, Division, Kernel, Receiver, SourcePolygon,
};
use super::pair::{Estimate, PairProblem, Source};
use super::{FormFactorMethod, Visibility};
use crate::geometry::{newell, sub_areas};
use glam::DVec3;
use std::cmp::Ordering;
use std::collections::BinaryHeap;

/// Visibility probes per source axis in the mesh engines (probe² rays per receiver point).
pub const PROBE: usize = 2;
/// Penumbra sub-areas per source axis in the mesh engines.
pub const PENUMBRA: usize = 4;
/// Finer probing for single pair problems, where cost does not matter.
const PAIR_PROBE: usize = 4;
const PAIR_PENUMBRA: usize = 8;
/// Receiver sub-areas per axis for the visible fraction of a polygon `from` in pair problems.
const PAIR_RECEIVERS: usize = 4;
/// Target absolute error of the adaptive cubature of `analytic-point` over a polygon.
const CUBATURE_TOLERANCE: f64 = 1e-9;
/// Cap on the cubature's subdivisions (each costs 112 kernel evaluations); reached only where
/// visibility makes the integrand discontinuous.
const CUBATURE_MAX_SPLITS: usize = 4000;

/// Area centroid of a planar convex polygon.
pub fn area_centroid(v: &[DVec3]) -> DVec3 {
    polygon_centroid(v)
}

/// The `analytic-point` kernel: F_{R→S} ≈ F_{dA(centre of R)→S} × V, Lambert's exact contour
/// formula at the receiver's centre (the classic point approximation of a finite receiver),
/// V from probe rays from that point (see the module docs).
#[derive(Debug, Clone, Copy, Default)]
pub struct AnalyticPointKernel;

impl Kernel for AnalyticPointKernel {
    fn method(&self) -> FormFactorMethod {
        FormFactorMethod::AnalyticPoint
    }

    fn source(&self, vertices: &[DVec3]) -> SourcePolygon {
        SourcePolygon::new(vertices, PROBE, PENUMBRA, Division::SubAreas)
    }

    fn form_factor(&self, r: &Receiver, s: &SourcePolygon, visibility: &Visibility) -> f64 {
        let f = point_to_polygon(r.centre, r.normal, &s.vertices, s.normal);
        if f <= 0.0 {
            return 0.0;
        }
        f * visible_fraction(visibility, &[(r.centre, 1.0)], r.normal, s, true)
    }
}

/// The `analytic-polygon` kernel: F_{R→S} = F^exact_{R→S} × V, the exact unoccluded
/// polygon-to-polygon factor times the visible fraction from the receiver's visibility points
/// (2 × 2 on a polygon); the point form for a point receiver.
#[derive(Debug, Clone, Copy, Default)]
pub struct AnalyticPolygonKernel;

impl Kernel for AnalyticPolygonKernel {
    fn method(&self) -> FormFactorMethod {
        FormFactorMethod::AnalyticPolygon
    }

    fn source(&self, vertices: &[DVec3]) -> SourcePolygon {
        SourcePolygon::new(vertices, PROBE, PENUMBRA, Division::SubAreas)
    }

    fn receiver_order(&self, _size: f64, _clearance: &dyn Fn(f64) -> f64) -> usize {
        2
    }

    fn form_factor(&self, r: &Receiver, s: &SourcePolygon, visibility: &Visibility) -> f64 {
        if r.is_point() {
            return AnalyticPointKernel.form_factor(r, s, visibility);
        }
        // Cheap culls before the contour integral: either polygon wholly behind the other.
        let front = |v: &DVec3, o: DVec3, n: DVec3| (*v - o).dot(n) > 0.0;
        if !s.vertices.iter().any(|v| front(v, r.centre, r.normal))
            || !r.vertices.iter().any(|v| front(v, s.vertices[0], s.normal))
        {
            return 0.0;
        }
        let f = polygon_to_polygon(&r.vertices, &s.vertices);
        if f.is_nan() || f <= 0.0 {
            return 0.0;
        }
        f * visible_fraction(visibility, &r.visibility_points, r.normal, s, false)
    }
}

/// `analytic-point` on a pair problem: the exact point form for a differential `from`; for a
/// polygon `from`, that kernel averaged over `from` by adaptive cubature to 1e-9. With
/// occluders the kernel at each point is multiplied by the visible fraction from that point.
pub fn analytic_point_pair(problem: &PairProblem) -> Estimate {
    let to_normal = newell(&problem.to).0;
    let vis = problem.occluder_visibility();
    let source = vis
        .as_ref()
        .map(|_| SourcePolygon::new(&problem.to, PAIR_PROBE, PAIR_PENUMBRA, Division::SubAreas));
    let kernel = |x: DVec3, n: DVec3| {
        let f = point_to_polygon(x, n, &problem.to, to_normal);
        match (&vis, &source) {
            (Some(vis), Some(s)) if f > 0.0 => f * visible_fraction(vis, &[(x, 1.0)], n, s, true),
            _ => f,
        }
    };
    let value = match &problem.from {
        Source::Point { point, normal } => kernel(*point, *normal),
        Source::Polygon(from) => {
            let n = newell(from).0;
            average_over_polygon(
                from,
                |x| kernel(x, n),
                CUBATURE_TOLERANCE,
                CUBATURE_MAX_SPLITS,
            )
        }
    };
    Estimate::exact(value)
}

/// `analytic-polygon` on a pair problem: the exact polygon-to-polygon factor (the point form
/// for a differential `from`) times the visible fraction from 4×4 receiver sub-areas to 8×8
/// source sub-areas when there are occluders.
pub fn analytic_polygon_pair(problem: &PairProblem) -> Estimate {
    let to_normal = newell(&problem.to).0;
    let (unoccluded, receivers, n) = match &problem.from {
        Source::Point { point, normal } => (
            point_to_polygon(*point, *normal, &problem.to, to_normal),
            vec![(*point, 1.0)],
            *normal,
        ),
        Source::Polygon(from) => {
            let (n, area) = newell(from);
            let receivers = sub_areas(from, PAIR_RECEIVERS)
                .iter()
                .map(|p| (area_centroid(p), newell(p).1 / area))
                .collect();
            (polygon_to_polygon(from, &problem.to), receivers, n)
        }
    };
    let fraction = match problem.occluder_visibility() {
        Some(vis) if unoccluded > 0.0 => {
            let source =
                SourcePolygon::new(&problem.to, PAIR_PROBE, PAIR_PENUMBRA, Division::SubAreas);
            visible_fraction(&vis, &receivers, n, &source, true)
        }
        _ => 1.0,
    };
    Estimate::exact(unoccluded * fraction)
}

/// The degree-5 seven-point rule on a triangle (Radon 1948; Stroud T2:5-1), barycentric
/// coordinates and weights summing to 1.
fn radon7() -> [([f64; 3], f64); 7] {
    let s15 = 15f64.sqrt();
    let (a1, a2) = ((6.0 - s15) / 21.0, (6.0 + s15) / 21.0);
    let (b1, b2) = (1.0 - 2.0 * a1, 1.0 - 2.0 * a2);
    let (w1, w2) = ((155.0 - s15) / 1200.0, (155.0 + s15) / 1200.0);
    [
        ([1.0 / 3.0; 3], 9.0 / 40.0),
        ([b1, a1, a1], w1),
        ([a1, b1, a1], w1),
        ([a1, a1, b1], w1),
        ([b2, a2, a2], w2),
        ([a2, b2, a2], w2),
        ([a2, a2, b2], w2),
    ]
}

/// One cell of the adaptive cubature: a triangle, its integral by the rule (`coarse`), the
/// integrals of its four children (`kids`), and the error estimate |Σ kids − coarse|.
struct Cell {
    tri: [DVec3; 3],
    kids: [f64; 4],
    err: f64,
}

impl PartialEq for Cell {
    fn eq(&self, other: &Self) -> bool {
        self.err == other.err
    }
}
impl Eq for Cell {}
impl PartialOrd for Cell {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Cell {
    fn cmp(&self, other: &Self) -> Ordering {
        self.err.total_cmp(&other.err)
    }
}

fn children([a, b, c]: [DVec3; 3]) -> [[DVec3; 3]; 4] {
    let (ab, bc, ca) = ((a + b) * 0.5, (b + c) * 0.5, (c + a) * 0.5);
    [[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]
}

/// The mean of `f` over a planar convex polygon, (1/A) ∫ f dA, by globally adaptive cubature:
/// the polygon is fanned into triangles (about its centroid; larger polygons are first cut
/// into grid pieces so that no triangle is a long sliver), each integrated by Radon's
/// degree-5 rule and by the same rule on its four midpoint children; the triangle with the
/// largest difference is split until the differences sum to below `tolerance` (absolute, on
/// the mean) or `max_splits` splits were made. Robust to integrable edge singularities (a
/// polygon sharing an edge with the source).
pub fn average_over_polygon(
    vertices: &[DVec3],
    f: impl Fn(DVec3) -> f64,
    tolerance: f64,
    max_splits: usize,
) -> f64 {
    let area = newell(vertices).1;
    if area.is_nan() || area <= 0.0 {
        return 0.0;
    }
    let rule = radon7();
    let integral = |t: &[DVec3; 3]| {
        let a = 0.5 * (t[1] - t[0]).cross(t[2] - t[0]).length();
        a * rule
            .iter()
            .map(|(l, w)| w * f(l[0] * t[0] + l[1] * t[1] + l[2] * t[2]))
            .sum::<f64>()
    };
    let cell = |tri: [DVec3; 3], coarse: f64| {
        let kids = children(tri).map(|k| integral(&k));
        let err = (kids.iter().sum::<f64>() - coarse).abs();
        Cell { tri, kids, err }
    };
    let pieces = if vertices.len() > 4 {
        sub_areas(vertices, 4)
    } else {
        vec![vertices.to_vec()]
    };
    let mut heap = BinaryHeap::new();
    for piece in &pieces {
        let c = area_centroid(piece);
        for i in 0..piece.len() {
            let tri = [c, piece[i], piece[(i + 1) % piece.len()]];
            heap.push(cell(tri, integral(&tri)));
        }
    }
    let target = tolerance * area;
    let mut err: f64 = heap.iter().map(|c| c.err).sum();
    let mut splits = 0;
    while err > target && splits < max_splits {
        let Some(worst) = heap.pop() else { break };
        err -= worst.err;
        for (tri, coarse) in children(worst.tri).into_iter().zip(worst.kids) {
            let c = cell(tri, coarse);
            err += c.err;
            heap.push(c);
        }
        splits += 1;
        if splits % 256 == 0 {
            // Running sums drift; recompute now and then.
            err = heap.iter().map(|c| c.err).sum();
        }
    }
    heap.iter().map(|c| c.kids.iter().sum::<f64>()).sum::<f64>() / area
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cubature_is_exact_for_quintics_and_converges_at_a_log_singular_edge() {
        let square = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(2.0, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
        ];
        // Mean of x⁵ y over [0,2]×[0,1]: (2⁶/6)(1/2)/2.
        let m = average_over_polygon(&square, |p| p.x.powi(5) * p.y, 1e-12, 0);
        assert!((m - 64.0 / 6.0 * 0.5 / 2.0).abs() < 1e-12, "{m}");
        // Mean of x ln x, the singular part of a point's form factor to a polygon sharing
        // an edge with its own (C-14): ∫_0^2 x ln x dx = 2 ln 2 − 1, over the width 2.
        let exact = (2.0 * 2f64.ln() - 1.0) / 2.0;
        let m = average_over_polygon(&square, |p| p.x * p.x.ln(), 1e-10, 4000);
        assert!((m - exact).abs() < 1e-9, "{m} vs {exact}");
    }
}
