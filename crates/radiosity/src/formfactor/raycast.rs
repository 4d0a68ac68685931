//! `raycast`: receiver quadrature × exact point-to-polygon form factor × shadow rays.
//!
//! After Wallace, Elmquist & Haines (1989), "A ray tracing algorithm for progressive
//! radiosity": the form factor from a receiving point x to a source is the exact
//! differential-area-to-polygon value (Lambert's contour formula,
//! [`super::analytic_point`]) of each source sub-area ΔA_k, weighted by the visibility of
//! that sub-area's sample point from x:
//!
//!   F_{dx→p} ≈ Σ_k V(x, y_k) F_{dx→ΔA_k}.
//!
//! Refinements that keep it fast, accurate and conservative:
//! - the receiving element is integrated with an n×n Gauss rule (area average over e, not
//!   just its centre value). The order n is chosen per *element*, from its distance to the
//!   nearest other surface relative to its size, and the same points serve every source
//!   patch: at every point the exact form factors to the surrounding polygons sum to the
//!   solid-angle fraction they cover, so closure Σ_p F_{e→p} = 1 holds exactly (to
//!   rounding) in an unoccluded enclosure;
//! - visibility is probed with one ray per probe point (from up to 4 receiver points to the
//!   patch's probe points); when all agree (fully visible or fully hidden, the common case)
//!   the unoccluded value is used, otherwise (a penumbra) the visible fraction is weighted by
//!   the exact form factors of `penumbra²` source sub-areas, as Wallace et al. do.

use super::analytic::{visible_fraction, ProbedSource};
use super::analytic_point::point_to_polygon;
use super::quadrature::element_points;
use super::{subdivide, FormFactors, Visibility};
use crate::mesh::Mesh;
use glam::DVec3;

/// Parameters of the raycast method.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RaycastParams {
    /// Visibility probe rays per source axis (probe² rays per receiving point).
    pub probe: usize,
    /// Source sub-areas per axis where the probe finds partial visibility.
    pub penumbra: usize,
    /// Receiver quadrature order n = ceil(quality × size / distance to the nearest other
    /// surface), clamped to 1..=`max_order` (used as is for elements touching another surface).
    pub quality: f64,
    pub max_order: usize,
}

impl Default for RaycastParams {
    fn default() -> Self {
        Self {
            probe: 2,
            penumbra: 4,
            quality: 1.0,
            max_order: 16,
        }
    }
}

/// Precomputed per-patch data for the raycast method.
struct SourcePatch {
    probed: ProbedSource,
    centre: DVec3,
    radius: f64,
}

impl SourcePatch {
    fn new(vertices: Vec<DVec3>, normal: DVec3, centre: DVec3, params: &RaycastParams) -> Self {
        let centroid = |v: &[DVec3]| v.iter().copied().sum::<DVec3>() / v.len() as f64;
        let radius = vertices
            .iter()
            .map(|v| v.distance(centre))
            .fold(0.0, f64::max);
        let probes = subdivide(&vertices, params.probe.max(1))
            .iter()
            .map(|s| centroid(s))
            .collect();
        let sub_areas = subdivide(&vertices, params.penumbra.max(1));
        Self {
            probed: ProbedSource::from_parts(vertices, normal, probes, sub_areas),
            centre,
            radius,
        }
    }
}

/// The raycast form-factor engine over one mesh.
pub struct Raycast<'a> {
    mesh: &'a Mesh,
    visibility: &'a Visibility,
    sources: Vec<SourcePatch>,
    /// Receiver quadrature and visibility points of every element.
    receivers: Vec<ReceiverPoints>,
    /// Every element as a source (for near-field element-to-element pairs).
    element_sources: Vec<SourcePatch>,
}

/// An element's quadrature points (weights summing to 1) and the points it casts
/// visibility rays from (the quadrature points up to order 2, else a 2×2 Gauss subset).
struct ReceiverPoints {
    points: Vec<(DVec3, f64)>,
    visibility: Vec<(DVec3, f64)>,
}

impl<'a> Raycast<'a> {
    pub fn new(mesh: &'a Mesh, visibility: &'a Visibility) -> Self {
        Self::with_params(mesh, visibility, RaycastParams::default())
    }

    pub fn with_params(mesh: &'a Mesh, visibility: &'a Visibility, params: RaycastParams) -> Self {
        let sources = mesh
            .patches
            .iter()
            .map(|p| {
                SourcePatch::new(
                    p.polygon.vertices().to_vec(),
                    p.polygon.normal(),
                    p.polygon.centroid(),
                    &params,
                )
            })
            .collect();
        let element_orders: Vec<usize> = mesh
            .elements
            .iter()
            .map(|e| {
                let c = &e.corners;
                let mut size: f64 = 0.0;
                for i in 0..c.len() {
                    for j in i + 1..c.len() {
                        size = size.max(
                            mesh.vertices[c[i] as usize].distance(mesh.vertices[c[j] as usize]),
                        );
                    }
                }
                // Nearest other surface that can exchange light with this element.
                let distance = mesh
                    .surface_polygons
                    .iter()
                    .enumerate()
                    .filter(|(s, poly)| {
                        *s != e.surface as usize
                            && poly
                                .vertices()
                                .iter()
                                .any(|v| (*v - e.centre).dot(e.normal) > 0.0)
                            && c.iter()
                                .any(|&k| poly.plane_distance(mesh.vertices[k as usize]) > 0.0)
                    })
                    .map(|(_, poly)| poly.distance_to(e.centre))
                    .fold(f64::INFINITY, f64::min);
                if distance <= 1e-9 * size {
                    params.max_order
                } else {
                    ((params.quality * size / distance).ceil() as usize)
                        .clamp(1, params.max_order.max(1))
                }
            })
            .collect();
        let receivers = mesh
            .elements
            .iter()
            .zip(&element_orders)
            .map(|(e, &order)| {
                let verts: Vec<DVec3> = e
                    .corners
                    .iter()
                    .map(|&c| mesh.vertices[c as usize])
                    .collect();
                let mut points = Vec::with_capacity(order * order);
                element_points(&verts, e.centre, order, &mut points);
                let visibility = if order <= 2 {
                    points.clone()
                } else {
                    let mut vis = Vec::with_capacity(4);
                    element_points(&verts, e.centre, 2, &mut vis);
                    vis
                };
                ReceiverPoints { points, visibility }
            })
            .collect();
        let element_sources = mesh
            .elements
            .iter()
            .map(|e| {
                let vertices = e
                    .corners
                    .iter()
                    .map(|&c| mesh.vertices[c as usize])
                    .collect();
                SourcePatch::new(vertices, e.normal, e.centre, &params)
            })
            .collect();
        Self {
            mesh,
            visibility,
            sources,
            receivers,
            element_sources,
        }
    }
}

impl FormFactors for Raycast<'_> {
    fn name(&self) -> &'static str {
        "raycast"
    }

    fn pair(&self, element: usize, patch: usize) -> f64 {
        let p = &self.mesh.patches[patch];
        if self.mesh.elements[element].surface == p.surface {
            return 0.0;
        }
        self.receive(element, &self.sources[patch])
    }

    fn element_pair(&self, element: usize, source: usize) -> Option<f64> {
        let (e, s) = (&self.mesh.elements[element], &self.mesh.elements[source]);
        if e.surface == s.surface {
            return Some(0.0);
        }
        Some(self.receive(element, &self.element_sources[source]))
    }

    fn resolves_elements(&self) -> bool {
        true
    }
}

impl Raycast<'_> {
    /// F from element `element` to the source `s`, with visibility.
    fn receive(&self, element: usize, s: &SourcePatch) -> f64 {
        let e = &self.mesh.elements[element];
        // Whole-element culls: the source entirely behind the element's plane, or the
        // element entirely behind the source's plane.
        let corners = || e.corners.iter().map(|&c| self.mesh.vertices[c as usize]);
        if s.probed
            .vertices
            .iter()
            .all(|v| (*v - e.centre).dot(e.normal) <= 1e-12 * s.radius)
            || corners().all(|c| (c - s.centre).dot(s.probed.normal) <= 1e-12 * s.radius)
        {
            return 0.0;
        }
        let points = &self.receivers[element];
        let unoccluded: f64 = points
            .points
            .iter()
            .map(|&(x, w)| w * point_to_polygon(x, e.normal, &s.probed.vertices, s.probed.normal))
            .sum();
        if unoccluded <= 0.0 {
            return 0.0;
        }
        let fraction = visible_fraction(
            self.visibility,
            &points.visibility,
            e.normal,
            &s.probed,
            false,
        );
        unoccluded * fraction
    }
}
