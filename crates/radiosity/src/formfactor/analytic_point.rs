//! `analytic-point`: the exact differential-area-to-polygon form factor, unoccluded.
//!
//! Lambert's contour formula (Nusselt's analogue in closed form; Baum, Rushmeier & Winget
//! 1989, eq. 1): for a differential area at `x` with unit normal `n` and a polygon with
//! vertices v_k (relative vectors r_k = v_k − x),
//!
//!   F_{dA→A} = (1/2π) Σ_k γ_k · n,   γ_k = angle(r_k, r_{k+1}) · normalize(r_k × r_{k+1}).
//!
//! The polygon is first clipped to the hemisphere above `x` (only the part in front of the
//! tangent plane is seen) and contributes only if `x` is in front of it (surfaces are
//! one-sided). The result is in [0, 1].

use crate::geometry::{clip_convex, FixedPolygon};
use glam::DVec3;
use std::f64::consts::PI;

/// F from a differential area at `x` (unit normal `n`) to the convex polygon `vertices`
/// (counter-clockwise seen from its front, unit normal `polygon_normal`), unoccluded.
pub fn point_to_polygon(x: DVec3, n: DVec3, vertices: &[DVec3], polygon_normal: DVec3) -> f64 {
    // One-sided: x must be strictly in front of the polygon's plane.
    let height = (x - vertices[0]).dot(polygon_normal);
    if height <= 0.0 {
        return 0.0;
    }
    let side = |v: &DVec3| (*v - x).dot(n);
    if vertices.iter().all(|v| side(v) >= 0.0) {
        contour_sum(x, n, vertices)
    } else if vertices.len() < 16 {
        // Clipping adds at most one vertex; small polygons stay on the stack.
        let mut clipped = FixedPolygon::<DVec3, 16>::default();
        clip_convex(vertices, side, &mut clipped);
        if clipped.len >= 3 {
            contour_sum(x, n, clipped.as_slice())
        } else {
            0.0
        }
    } else {
        match crate::geometry::clip_to_halfspace(vertices, x, n) {
            Some(clipped) => contour_sum(x, n, &clipped),
            None => 0.0,
        }
    }
}

/// The contour sum for a polygon already inside the hemisphere above `x`: n · Γ.
#[inline]
pub(crate) fn contour_sum(x: DVec3, n: DVec3, vertices: &[DVec3]) -> f64 {
    lambert_vector(x, vertices).dot(n).clamp(0.0, 1.0)
}

/// Lambert's contour formula in vector form: Γ(x → q) with F_{dA(x, n) → q} = n · Γ for
/// every normal n whose hemisphere holds all of q (Baum, Rushmeier & Winget 1989, eq. 1):
/// Γ = −(1/2π) Σ_k γ_k · (r_k × r_{k+1})/|r_k × r_{k+1}|, r_k = v_k − x. Seen from the front
/// the polygon winds clockwise about its normal, hence the sign.
#[inline]
pub fn lambert_vector(x: DVec3, vertices: &[DVec3]) -> DVec3 {
    let count = vertices.len();
    let mut sum = DVec3::ZERO;
    let mut a = vertices[count - 1] - x;
    for v in vertices {
        let b = *v - x;
        let c = a.cross(b);
        let s = c.length();
        if s > 0.0 {
            sum += c * (s.atan2(a.dot(b)) / s);
        }
        a = b;
    }
    -sum / (2.0 * PI)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rect(x0: f64, x1: f64, y0: f64, y1: f64, z: f64) -> Vec<DVec3> {
        // facing −z (towards the origin below it)
        vec![
            DVec3::new(x0, y0, z),
            DVec3::new(x0, y1, z),
            DVec3::new(x1, y1, z),
            DVec3::new(x1, y0, z),
        ]
    }

    /// Howell B-3: differential element to a parallel rectangle, normal through a corner.
    fn b3(a: f64, b: f64, c: f64) -> f64 {
        let (x, y) = (a / c, b / c);
        let (sx, sy) = ((1.0 + x * x).sqrt(), (1.0 + y * y).sqrt());
        (x / sx * (y / sx).atan() + y / sy * (x / sy).atan()) / (2.0 * PI)
    }

    #[test]
    fn matches_howell_b3() {
        for &(a, b, c) in &[(1.0, 1.0, 1.0), (2.0, 1.0, 1.0), (0.5, 3.0, 1.0)] {
            let f = point_to_polygon(DVec3::ZERO, DVec3::Z, &rect(0.0, a, 0.0, b, c), -DVec3::Z);
            assert!((f - b3(a, b, c)).abs() < 1e-12, "{f} vs {}", b3(a, b, c));
        }
    }

    #[test]
    fn infinite_plane_sees_everything_and_back_sees_nothing() {
        let big = rect(-1e4, 1e4, -1e4, 1e4, 1.0);
        let f = point_to_polygon(DVec3::ZERO, DVec3::Z, &big, -DVec3::Z);
        assert!((f - 1.0).abs() < 1e-3);
        // Behind the polygon (one-sided): nothing.
        let f = point_to_polygon(DVec3::new(0.0, 0.0, 2.0), DVec3::Z, &big, -DVec3::Z);
        assert_eq!(f, 0.0);
    }

    #[test]
    fn half_below_horizon_is_clipped() {
        // A wall straddling the tangent plane: only the upper half counts.
        let wall = vec![
            DVec3::new(-1.0, 1.0, -1.0),
            DVec3::new(1.0, 1.0, -1.0),
            DVec3::new(1.0, 1.0, 1.0),
            DVec3::new(-1.0, 1.0, 1.0),
        ];
        let upper = vec![
            DVec3::new(-1.0, 1.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(1.0, 1.0, 1.0),
            DVec3::new(-1.0, 1.0, 1.0),
        ];
        let f = point_to_polygon(DVec3::ZERO, DVec3::Z, &wall, -DVec3::Y);
        let g = point_to_polygon(DVec3::ZERO, DVec3::Z, &upper, -DVec3::Y);
        assert!(f > 0.0 && (f - g).abs() < 1e-15);
    }
}
