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
//! - the receiver is integrated with an n×n Gauss rule (area average over it, not just its
//!   centre value). The order n is chosen per *receiver*, from its distance to the nearest
//!   other surface relative to its size ([`Kernel::receiver_order`]), and the same points
//!   serve every source: at every point the exact form factors to the surrounding polygons sum to the
//!   solid-angle fraction they cover, so closure Σ_p F_{e→p} = 1 holds exactly (to
//!   rounding) in an unoccluded enclosure;
//! - visibility is probed with one ray per probe point (from up to 4 receiver points to the
//!   patch's probe points); when all agree (fully visible or fully hidden, the common case)
//!   the unoccluded value is used, otherwise (a penumbra) the visible fraction is weighted by
//!   the exact form factors of `penumbra²` source sub-areas, as Wallace et al. do.

use super::analytic_point::point_to_polygon;
use super::kernel::{visible_fraction, Division, Kernel, Receiver, SourcePolygon};
use super::{FormFactorMethod, Visibility};
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
    /// Largest receiver quadrature order.
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

/// The raycast kernel.
#[derive(Debug, Clone, Copy, Default)]
pub struct RaycastKernel {
    /// Its parameters.
    pub params: RaycastParams,
}

impl Kernel for RaycastKernel {
    fn method(&self) -> FormFactorMethod {
        FormFactorMethod::Raycast
    }

    fn source(&self, vertices: &[DVec3]) -> SourcePolygon {
        SourcePolygon::new(
            vertices,
            self.params.probe.max(1),
            self.params.penumbra.max(1),
            Division::Lattice,
        )
    }

    fn points_only_source(&self, vertices: &[DVec3]) -> SourcePolygon {
        SourcePolygon::points_only_new(vertices, self.params.penumbra.max(1), Division::Lattice)
    }

    fn receiver_order(&self, size: f64, clearance: &dyn Fn(f64) -> f64) -> usize {
        // Beyond quality × size the order is 1 whatever the distance: search no farther.
        let distance = clearance(self.params.quality * size);
        if distance <= 1e-9 * size {
            self.params.max_order
        } else {
            ((self.params.quality * size / distance).ceil() as usize)
                .clamp(1, self.params.max_order.max(1))
        }
    }

    fn form_factor(&self, r: &Receiver, s: &SourcePolygon, visibility: &Visibility) -> f64 {
        // Whole-receiver culls: the source entirely behind the receiver's plane, or the
        // receiver entirely behind the source's plane.
        let behind_source = if r.is_point() {
            (r.centre - s.centre).dot(s.normal) <= 1e-12 * s.radius
        } else {
            r.vertices
                .iter()
                .all(|c| (*c - s.centre).dot(s.normal) <= 1e-12 * s.radius)
        };
        if behind_source
            || s.vertices
                .iter()
                .all(|v| (*v - r.centre).dot(r.normal) <= 1e-12 * s.radius)
        {
            return 0.0;
        }
        let unoccluded: f64 = r
            .points
            .iter()
            .map(|&(x, w)| w * point_to_polygon(x, r.normal, &s.vertices, s.normal))
            .sum();
        if unoccluded <= 0.0 {
            return 0.0;
        }
        unoccluded * visible_fraction(visibility, &r.visibility_points, r.normal, s, false)
    }
}
