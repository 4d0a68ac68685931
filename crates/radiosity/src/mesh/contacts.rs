//! Contact lines: where one surface touches another (a block standing on a floor), radiosity
//! jumps from lit to dark, so the touched surface is split along the contact line before it
//! is meshed.

use crate::accel::Visibility;
use crate::geometry::Polygon;
use crate::scene::Scene;
use glam::{DVec3, Vec3};
use rayon::prelude::*;

/// Splits surfaces along the lines where other surfaces touch them: an edge of another,
/// non-parallel surface lying in a surface's plane and crossing its interior (a block
/// standing on a floor). Radiosity is discontinuous there (lit outside, dark underneath:
/// a D0 discontinuity in the sense of Heckbert 1992 and Lischinski, Tampieri & Greenberg
/// 1992), so no element may straddle it. Each piece is cut by the whole line, which keeps
/// pieces convex. Returns (scene surface index, piece) pairs in scene order.
///
/// Only surfaces whose bounding boxes meet are compared (found through a BVH over all
/// surfaces), so the cost is O(n log n) plus the contacts, not O(n²).
pub fn split_at_contacts(scene: &Scene) -> Vec<(usize, Polygon)> {
    let bvh = Visibility::from_polygons(scene.surfaces.iter().map(|s| s.polygon.vertices()), 1.0);
    let split: Vec<Vec<Polygon>> = scene
        .surfaces
        .par_iter()
        .enumerate()
        .map_init(Vec::new, |found, (si, s)| {
            let vertices = s.polygon.vertices();
            let (mut lo, mut hi) = (vertices[0], vertices[0]);
            for v in vertices {
                lo = lo.min(*v);
                hi = hi.max(*v);
            }
            // The box grown by the contact tolerance and by f32 rounding of the BVH.
            let grow = 1e-7 * s.polygon.diameter() + 1e-6 * lo.abs().max(hi.abs()).max_element();
            bvh.bvh().triangles_in_box(
                (lo - grow).as_vec3() - Vec3::splat(f32::EPSILON),
                (hi + grow).as_vec3() + Vec3::splat(f32::EPSILON),
                found,
            );
            let mut near: Vec<usize> = found.iter().map(|(t, _)| bvh.polygon_of(*t)).collect();
            near.sort_unstable();
            near.dedup();
            split_one(scene, si, &near)
        })
        .collect();
    split
        .into_iter()
        .enumerate()
        .flat_map(|(si, pieces)| pieces.into_iter().map(move |p| (si, p)))
        .collect()
}

/// Cuts surface `si`'s polygon along the edges of the surfaces `near` (scene indices,
/// ascending) that lie in its plane and cross its interior.
fn split_one(scene: &Scene, si: usize, near: &[usize]) -> Vec<Polygon> {
    let polygon = &scene.surfaces[si].polygon;
    let n = polygon.normal();
    let tol = 1e-7 * polygon.diameter();
    let mut segments = Vec::new();
    for &ti in near {
        let t = &scene.surfaces[ti].polygon;
        if ti == si || t.normal().cross(n).length() < 1e-6 {
            continue;
        }
        for (a, b) in t.edges() {
            if polygon.plane_distance(a).abs() <= tol && polygon.plane_distance(b).abs() <= tol {
                segments.push((a, b));
            }
        }
    }
    let mut pieces = Vec::new();
    cut(polygon.clone(), &segments, n, tol, &mut pieces);
    pieces
}

/// Segments above which [`cut`] divides the polygon first.
const DIVIDE_ABOVE: usize = 16;

/// Cuts `piece` along every segment (each piece it crosses is cut by the segment's whole
/// line, which keeps pieces convex) and appends the pieces to `out`. With many segments (a
/// floor under thousands of boxes) the piece is first halved across its longest extent at
/// the median segment midpoint and each half cut by the segments that reach it, so the
/// cost is O(s log s) for s segments spread over the piece rather than O(s²) (each segment
/// against every piece the others made), and no line runs across the whole floor.
fn cut(piece: Polygon, segments: &[(DVec3, DVec3)], n: DVec3, tol: f64, out: &mut Vec<Polygon>) {
    if segments.len() > DIVIDE_ABOVE {
        let (lo, hi) = piece.bounds();
        let axis = (hi - lo).max_position();
        let mut mids: Vec<f64> = segments
            .iter()
            .map(|(a, b)| 0.5 * (a[axis] + b[axis]))
            .collect();
        let middle = mids.len() / 2;
        let (_, &mut at, _) = mids.select_nth_unstable_by(middle, f64::total_cmp);
        let mut normal = DVec3::ZERO;
        normal[axis] = 1.0;
        // The cutting plane must meet the piece's plane (not parallel to it) and leave both
        // halves a share of the segments; otherwise cut directly.
        let origin = {
            let mut o = lo;
            o[axis] = at;
            o
        };
        let below: Vec<(DVec3, DVec3)> = segments
            .iter()
            .copied()
            .filter(|(a, b)| a[axis].min(b[axis]) < at + tol)
            .collect();
        let above: Vec<(DVec3, DVec3)> = segments
            .iter()
            .copied()
            .filter(|(a, b)| a[axis].max(b[axis]) > at - tol)
            .collect();
        let halves =
            (n.cross(normal).length() > 1e-6 && at > lo[axis] + tol && at < hi[axis] - tol)
                .then(|| {
                    let left = piece.clip_to_halfspace(origin, -normal)?;
                    let right = piece.clip_to_halfspace(origin, normal)?;
                    Some((Polygon::new(left).ok()?, Polygon::new(right).ok()?))
                })
                .flatten();
        if let Some((left, right)) = halves {
            if below.len() < segments.len() && above.len() < segments.len() {
                cut(left, &below, n, tol, out);
                cut(right, &above, n, tol, out);
                return;
            }
        }
    }
    let mut pieces = vec![piece];
    for &(a, b) in segments {
        let line = n.cross(b - a).normalize();
        let mut next = Vec::with_capacity(pieces.len() + 1);
        for piece in pieces {
            let split = crosses_interior(&piece, a, b, tol)
                .then(|| {
                    let left = piece.clip_to_halfspace(a, line)?;
                    let right = piece.clip_to_halfspace(a, -line)?;
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
    out.extend(pieces);
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
