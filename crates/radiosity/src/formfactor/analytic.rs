//! `analytic-point` and `analytic-polygon`: the exact unoccluded form factors as mesh engines
//! and pair solvers, with visibility estimated by shadow rays.
//!
//! - `analytic-point` ([`AnalyticPoint`]): the differential-area-to-polygon form factor of
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
//! - `analytic-polygon` ([`AnalyticPolygon`]): the exact polygon-to-polygon form factor by the
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
//! Both engines also take a single element as the source ([`FormFactors::element_pair`]), for
//! the solver's near field, with the same formulas.

use super::analytic_point::point_to_polygon;
use super::analytic_polygon::polygon_to_polygon;
use super::pair::{Estimate, PairProblem, Source};
use super::quadrature::element_points;
use super::{sub_areas, FormFactors, Visibility};
use crate::geometry::newell;
use crate::mesh::Mesh;
use glam::DVec3;
use std::cmp::Ordering;
use std::collections::BinaryHeap;
use std::sync::OnceLock;

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

/// A source polygon prepared for visibility estimates: probe points and penumbra sub-areas.
pub struct ProbedSource {
    pub vertices: Vec<DVec3>,
    pub normal: DVec3,
    probes: Vec<DVec3>,
    sub_areas: Vec<Vec<DVec3>>,
    sub_points: Vec<DVec3>,
}

impl ProbedSource {
    /// About `probe²` probe points (sub-area centroids) and `penumbra²` penumbra sub-areas.
    pub fn new(vertices: &[DVec3], probe: usize, penumbra: usize) -> Self {
        let probes = sub_areas_centroids(&sub_areas(vertices, probe));
        let pieces = sub_areas(vertices, penumbra);
        Self {
            vertices: vertices.to_vec(),
            normal: newell(vertices).0,
            probes,
            sub_points: sub_areas_centroids(&pieces),
            sub_areas: pieces,
        }
    }
}

impl ProbedSource {
    /// From given probe points and penumbra sub-areas (their centroids are computed).
    pub(crate) fn from_parts(
        vertices: Vec<DVec3>,
        normal: DVec3,
        probes: Vec<DVec3>,
        sub_areas: Vec<Vec<DVec3>>,
    ) -> Self {
        Self {
            vertices,
            normal,
            probes,
            sub_points: sub_areas_centroids(&sub_areas),
            sub_areas,
        }
    }
}

fn sub_areas_centroids(pieces: &[Vec<DVec3>]) -> Vec<DVec3> {
    pieces.iter().map(|p| area_centroid(p)).collect()
}

/// Area centroid of a planar convex polygon.
pub fn area_centroid(v: &[DVec3]) -> DVec3 {
    let (mut sum, mut total) = (DVec3::ZERO, 0.0);
    for w in v[1..].windows(2) {
        let a = (w[0] - v[0]).cross(w[1] - v[0]).length();
        sum += a * (v[0] + w[0] + w[1]) / 3.0;
        total += a;
    }
    if total > 0.0 {
        sum / total
    } else {
        v.iter().copied().sum::<DVec3>() / v.len() as f64
    }
}

/// The fraction of source `s` visible from the receiver points `receivers` (weights summing
/// to 1, normal `n`), from 0 to 1.
///
/// Probe stage: with one receiver point, or with `all_probes`, every point casts a ray to
/// every probe; otherwise each casts one, rotating through the probes (Wallace et al.'s cheap
/// test for elements). All visible gives exactly 1, none exactly 0. Otherwise the fraction is
/// Σ_x w_x Σ_k F_{x→ΔA_k} V(x, y_k) / Σ_x w_x Σ_k F_{x→ΔA_k} over the penumbra sub-areas ΔA_k
/// with centroids y_k, F the exact point-to-polygon factor.
pub fn visible_fraction(
    vis: &Visibility,
    receivers: &[(DVec3, f64)],
    n: DVec3,
    s: &ProbedSource,
    all_probes: bool,
) -> f64 {
    let (mut visible, mut total) = (0usize, 0usize);
    let per_point = if receivers.len() == 1 || all_probes {
        s.probes.len()
    } else {
        1
    };
    for (i, (x, _)) in receivers.iter().enumerate() {
        for k in 0..per_point {
            let y = s.probes[(i + k) % s.probes.len()];
            total += 1;
            visible += usize::from(vis.visible(*x, n, y, s.normal));
        }
    }
    if visible == total {
        return 1.0;
    }
    if visible == 0 {
        return 0.0;
    }
    let (mut seen, mut all) = (0.0, 0.0);
    for (x, w) in receivers {
        for (sub, y) in s.sub_areas.iter().zip(&s.sub_points) {
            let f = w * point_to_polygon(*x, n, sub, s.normal);
            if f > 0.0 {
                all += f;
                if vis.visible(*x, n, *y, s.normal) {
                    seen += f;
                }
            }
        }
    }
    if all > 0.0 {
        seen / all
    } else {
        visible as f64 / total as f64
    }
}

/// The `analytic-point` engine: F_{e→p} ≈ F_{dA(centre_e)→p} × V, exact contour at the
/// element's centre, V from probe rays (see the module docs).
pub struct AnalyticPoint<'a> {
    mesh: &'a Mesh,
    visibility: &'a Visibility,
    sources: Vec<ProbedSource>,
    element_sources: ElementSources,
}

impl<'a> AnalyticPoint<'a> {
    pub fn new(mesh: &'a Mesh, visibility: &'a Visibility) -> Self {
        Self {
            mesh,
            visibility,
            sources: probed_patches(mesh),
            element_sources: ElementSources::new(mesh),
        }
    }
}

/// Elements as sources for the near field, prepared on first use.
struct ElementSources(Vec<OnceLock<ProbedSource>>);

impl ElementSources {
    fn new(mesh: &Mesh) -> Self {
        Self((0..mesh.elements.len()).map(|_| OnceLock::new()).collect())
    }

    fn get(&self, mesh: &Mesh, e: usize) -> &ProbedSource {
        self.0[e].get_or_init(|| ProbedSource::new(&corners(mesh, e), PROBE, PENUMBRA))
    }
}

fn probed_patches(mesh: &Mesh) -> Vec<ProbedSource> {
    mesh.patches
        .iter()
        .map(|p| ProbedSource::new(p.polygon.vertices(), PROBE, PENUMBRA))
        .collect()
}

impl AnalyticPoint<'_> {
    fn receive(&self, element: usize, s: &ProbedSource) -> f64 {
        let e = &self.mesh.elements[element];
        let f = point_to_polygon(e.centre, e.normal, &s.vertices, s.normal);
        if f <= 0.0 {
            return 0.0;
        }
        f * visible_fraction(self.visibility, &[(e.centre, 1.0)], e.normal, s, true)
    }
}

impl FormFactors for AnalyticPoint<'_> {
    fn name(&self) -> &'static str {
        "analytic-point"
    }

    fn pair(&self, element: usize, patch: usize) -> f64 {
        if self.mesh.elements[element].surface == self.mesh.patches[patch].surface {
            return 0.0;
        }
        self.receive(element, &self.sources[patch])
    }

    fn element_pair(&self, element: usize, source: usize) -> Option<f64> {
        let (e, s) = (&self.mesh.elements[element], &self.mesh.elements[source]);
        if e.surface == s.surface {
            return Some(0.0);
        }
        Some(self.receive(element, self.element_sources.get(self.mesh, source)))
    }

    fn resolves_elements(&self) -> bool {
        true
    }
}

/// The corners of element `e`.
fn corners(mesh: &Mesh, e: usize) -> Vec<DVec3> {
    mesh.elements[e]
        .corners
        .iter()
        .map(|&c| mesh.vertices[c as usize])
        .collect()
}

/// The `analytic-polygon` engine: F_{e→p} = F^exact_{e→p} × V, the exact unoccluded
/// polygon-to-polygon factor times the visible fraction from 2×2 receiver points.
pub struct AnalyticPolygon<'a> {
    mesh: &'a Mesh,
    visibility: &'a Visibility,
    sources: Vec<ProbedSource>,
    element_sources: ElementSources,
}

impl<'a> AnalyticPolygon<'a> {
    pub fn new(mesh: &'a Mesh, visibility: &'a Visibility) -> Self {
        Self {
            mesh,
            visibility,
            sources: probed_patches(mesh),
            element_sources: ElementSources::new(mesh),
        }
    }
}

impl AnalyticPolygon<'_> {
    fn receive(&self, element: usize, s: &ProbedSource) -> f64 {
        let e = &self.mesh.elements[element];
        let corners = corners(self.mesh, element);
        // Cheap culls before the contour integral: either polygon wholly behind the other.
        let front = |v: &DVec3, o: DVec3, n: DVec3| (*v - o).dot(n) > 0.0;
        if !s.vertices.iter().any(|v| front(v, e.centre, e.normal))
            || !corners.iter().any(|v| front(v, s.vertices[0], s.normal))
        {
            return 0.0;
        }
        let f = polygon_to_polygon(&corners, &s.vertices);
        if f.is_nan() || f <= 0.0 {
            return 0.0;
        }
        let mut receivers = Vec::with_capacity(4);
        element_points(&corners, e.centre, 2, &mut receivers);
        f * visible_fraction(self.visibility, &receivers, e.normal, s, false)
    }
}

impl FormFactors for AnalyticPolygon<'_> {
    fn name(&self) -> &'static str {
        "analytic-polygon"
    }

    fn pair(&self, element: usize, patch: usize) -> f64 {
        if self.mesh.elements[element].surface == self.mesh.patches[patch].surface {
            return 0.0;
        }
        self.receive(element, &self.sources[patch])
    }

    fn element_pair(&self, element: usize, source: usize) -> Option<f64> {
        let (e, s) = (&self.mesh.elements[element], &self.mesh.elements[source]);
        if e.surface == s.surface {
            return Some(0.0);
        }
        Some(self.receive(element, self.element_sources.get(self.mesh, source)))
    }

    fn resolves_elements(&self) -> bool {
        true
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
        .map(|_| ProbedSource::new(&problem.to, PAIR_PROBE, PAIR_PENUMBRA));
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
            let source = ProbedSource::new(&problem.to, PAIR_PROBE, PAIR_PENUMBRA);
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
