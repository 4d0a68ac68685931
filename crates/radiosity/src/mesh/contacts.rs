//! Contact lines: where one surface touches another (a block standing on a floor), radiosity
//! jumps from lit to dark, so the touched surface is split along the contact line before it
//! is meshed.

use crate::geometry::Polygon;
use crate::scene::Scene;
use glam::DVec3;

/// Splits surfaces along the lines where other surfaces touch them: an edge of another,
/// non-parallel surface lying in a surface's plane and crossing its interior (a block
/// standing on a floor). Radiosity is discontinuous there (lit outside, dark underneath:
/// a D0 discontinuity in the sense of Heckbert 1992 and Lischinski, Tampieri & Greenberg
/// 1992), so no element may straddle it. Each piece is cut by the whole line, which keeps
/// pieces convex. Returns (scene surface index, piece) pairs in scene order.
pub fn split_at_contacts(scene: &Scene) -> Vec<(usize, Polygon)> {
    let mut out = Vec::new();
    for (si, s) in scene.surfaces.iter().enumerate() {
        let n = s.polygon.normal();
        let tol = 1e-7 * s.polygon.diameter();
        let mut pieces = vec![s.polygon.clone()];
        for (ti, t) in scene.surfaces.iter().enumerate() {
            if ti == si || t.polygon.normal().cross(n).length() < 1e-6 {
                continue;
            }
            for (a, b) in t.polygon.edges() {
                if s.polygon.plane_distance(a).abs() > tol
                    || s.polygon.plane_distance(b).abs() > tol
                {
                    continue;
                }
                let cut = n.cross(b - a).normalize();
                let mut next = Vec::with_capacity(pieces.len() + 1);
                for piece in pieces {
                    let split = crosses_interior(&piece, a, b, tol)
                        .then(|| {
                            let left = piece.clip_to_halfspace(a, cut)?;
                            let right = piece.clip_to_halfspace(a, -cut)?;
                            Some((Polygon::new(left).ok()?, Polygon::new(right).ok()?))
                        })
                        .flatten();
                    match split {
                        Some((l, r)) if l.area() > tol * tol && r.area() > tol * tol => {
                            next.push(l);
                            next.push(r);
                        }
                        _ => next.push(piece),
                    }
                }
                pieces = next;
            }
        }
        out.extend(pieces.into_iter().map(|p| (si, p)));
    }
    out
}

/// Whether the segment a–b (in the polygon's plane) passes through the polygon's interior.
fn crosses_interior(polygon: &Polygon, a: DVec3, b: DVec3, tol: f64) -> bool {
    // Cyrus–Beck clipping of the segment against the polygon's edges (inward normals).
    let n = polygon.normal();
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    let d = b - a;
    for (p, q) in polygon.edges() {
        let inward = n.cross(q - p);
        let len = inward.length();
        let num = (a - p).dot(inward) / len;
        let den = d.dot(inward) / len;
        if den.abs() < 1e-15 {
            if num <= tol {
                return false; // parallel and on or outside this edge
            }
            continue;
        }
        let t = -num / den;
        if den > 0.0 {
            t0 = t0.max(t);
        } else {
            t1 = t1.min(t);
        }
    }
    (t1 - t0) * d.length() > tol
}
