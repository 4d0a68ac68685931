//! The one polygon clipper: Sutherland–Hodgman clipping of a convex loop against a half-space.
//!
//! Sutherland & Hodgman (1974), "Reentrant polygon clipping": walking the loop, keep every
//! vertex on the inside (signed distance d ≥ 0) and insert the crossing point
//! a + (b − a)·d_a/(d_a − d_b) wherever an edge goes strictly from one side to the other.
//! The crossing is always interpolated from the inside endpoint, so two polygons sharing an
//! edge compute bit-identical crossing vertices. Vertices exactly on the plane are kept and
//! produce no duplicate.
//!
//! The clipper is generic over what a vertex carries ([`ClipVertex`]): points in 2-D or 3-D,
//! or points with shading values (the rasteriser's near-plane clip). Callers give the signed
//! distance as a closure, so planes through the origin, offset planes and axis-aligned
//! bounds are all the same call.

use glam::DVec3;

/// A vertex that can be clipped: it interpolates linearly towards another.
pub trait ClipVertex: Copy {
    /// The point `t` of the way from `self` to `other` (t ∈ [0, 1]).
    fn lerp_to(self, other: Self, t: f64) -> Self;
}

impl ClipVertex for DVec3 {
    fn lerp_to(self, other: Self, t: f64) -> Self {
        self + (other - self) * t
    }
}

impl ClipVertex for [f64; 2] {
    fn lerp_to(self, other: Self, t: f64) -> Self {
        [
            self[0] + (other[0] - self[0]) * t,
            self[1] + (other[1] - self[1]) * t,
        ]
    }
}

/// Where clipped vertices go: a `Vec`, or a fixed-size buffer on a hot path.
pub trait ClipOutput<V> {
    /// Removes every vertex.
    fn clear(&mut self);
    /// Appends a vertex.
    fn push_vertex(&mut self, v: V);
}

impl<V> ClipOutput<V> for Vec<V> {
    fn clear(&mut self) {
        Vec::clear(self);
    }
    fn push_vertex(&mut self, v: V) {
        self.push(v);
    }
}

/// A polygon of at most `N` vertices on the stack, for clipping on hot paths; vertices pushed
/// beyond `N` are dropped (callers size `N` for their input: each clip plane adds at most
/// one vertex).
#[derive(Debug, Clone, Copy)]
pub struct FixedPolygon<V, const N: usize> {
    /// Storage; the first `len` are the polygon.
    pub vertices: [V; N],
    /// Number of vertices.
    pub len: usize,
}

impl<V: Copy + Default, const N: usize> Default for FixedPolygon<V, N> {
    fn default() -> Self {
        Self {
            vertices: [V::default(); N],
            len: 0,
        }
    }
}

impl<V: Copy, const N: usize> FixedPolygon<V, N> {
    /// The vertices.
    pub fn as_slice(&self) -> &[V] {
        &self.vertices[..self.len]
    }
}

impl<V: Copy, const N: usize> ClipOutput<V> for FixedPolygon<V, N> {
    fn clear(&mut self) {
        self.len = 0;
    }
    fn push_vertex(&mut self, v: V) {
        debug_assert!(self.len < N, "clipped polygon overflows {N} vertices");
        if self.len < N {
            self.vertices[self.len] = v;
            self.len += 1;
        }
    }
}

/// Clips the convex loop `input` to `{v : distance(v) ≥ 0}`, writing the result to `output`
/// (cleared first). The result may have fewer than three vertices when little or nothing is
/// inside.
pub fn clip_convex<V: ClipVertex>(
    input: &[V],
    distance: impl Fn(&V) -> f64,
    output: &mut impl ClipOutput<V>,
) {
    output.clear();
    let n = input.len();
    if n == 0 {
        return;
    }
    // Walk the edges a → b from the first vertex, so the result keeps the input's starting
    // vertex when it survives (later stages fan-triangulate from vertex 0).
    let first = distance(&input[0]);
    let mut da = first;
    for i in 0..n {
        let a = input[i];
        let b = input[(i + 1) % n];
        let db = if i + 1 == n { first } else { distance(&b) };
        if da >= 0.0 {
            output.push_vertex(a);
        }
        if (da > 0.0 && db < 0.0) || (da < 0.0 && db > 0.0) {
            let (inside, di, outside, d_out) = if da > 0.0 {
                (a, da, b, db)
            } else {
                (b, db, a, da)
            };
            output.push_vertex(inside.lerp_to(outside, di / (di - d_out)));
        }
        da = db;
    }
}

/// The part of the convex loop `vertices` on the side `(p − origin)·normal ≥ 0`;
/// `None` when fewer than three vertices remain (nothing, or only a point or an edge).
pub fn clip_to_halfspace(vertices: &[DVec3], origin: DVec3, normal: DVec3) -> Option<Vec<DVec3>> {
    let mut out = Vec::with_capacity(vertices.len() + 1);
    clip_convex(vertices, |v| (*v - origin).dot(normal), &mut out);
    (out.len() >= 3).then_some(out)
}

/// Splits the convex loop `input` of plane points by the line `p[axis] = at` into the part
/// with `p[axis] ≤ at` (`below`) and the part with `p[axis] ≥ at` (`above`), both cleared
/// first; either may end with fewer than three vertices.
///
/// The two parts share their crossing vertices bit for bit, so that pieces cut from one
/// polygon by a lattice of such lines weld into a mesh without cracks: a crossing is
/// computed once for both sides, lies exactly on the line (its `axis` coordinate is `at`
/// itself, not an interpolated value), and its other coordinate is interpolated from the
/// edge's lesser endpoint (in the order of that coordinate), so that it does not depend on
/// the direction a piece walks the edge either. An edge left on the line x = x_i by an earlier
/// cut, cut by y = y_j, therefore gives the lattice point (x_i, y_j) exactly (interpolating
/// between two equal values returns that value), whichever piece cuts it. Vertices on the
/// line go to both parts.
///
/// O(n) for n vertices; cutting a polygon by k parallel lines in halves (bisection) costs
/// O(n log k).
pub fn split_convex(
    input: &[[f64; 2]],
    axis: usize,
    at: f64,
    below: &mut Vec<[f64; 2]>,
    above: &mut Vec<[f64; 2]>,
) {
    below.clear();
    above.clear();
    let n = input.len();
    let other = 1 - axis;
    for i in 0..n {
        let a = input[i];
        let b = input[(i + 1) % n];
        let (da, db) = (a[axis] - at, b[axis] - at);
        if da <= 0.0 {
            below.push(a);
        }
        if da >= 0.0 {
            above.push(a);
        }
        if (da < 0.0 && db > 0.0) || (da > 0.0 && db < 0.0) {
            let (lo, hi) = if a[other] <= b[other] { (a, b) } else { (b, a) };
            let t = (at - lo[axis]) / (hi[axis] - lo[axis]);
            let mut x = [0.0; 2];
            x[axis] = at;
            x[other] = lo[other] + (hi[other] - lo[other]) * t;
            below.push(x);
            above.push(x);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keeps_the_inside_and_adds_crossings() {
        let square = [DVec3::ZERO, DVec3::X, DVec3::new(1.0, 1.0, 0.0), DVec3::Y];
        let half = clip_to_halfspace(&square, DVec3::new(0.5, 0.0, 0.0), DVec3::X).unwrap();
        assert_eq!(half.len(), 4);
        let area = crate::geometry::newell(&half).1;
        assert!((area - 0.5).abs() < 1e-15);
        // Wholly outside: nothing; touching the plane along an edge: an edge only.
        assert!(clip_to_halfspace(&square, DVec3::new(2.0, 0.0, 0.0), DVec3::X).is_none());
        assert!(clip_to_halfspace(&square, DVec3::X, DVec3::X).is_none());
    }

    #[test]
    fn a_vertex_on_the_plane_is_kept_once() {
        let tri = [
            DVec3::ZERO,
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(0.0, 2.0, 0.0),
        ];
        let mut out = Vec::new();
        // The plane x = 0 passes through two vertices; everything is inside.
        clip_convex(&tri, |v| v.x, &mut out);
        assert_eq!(out.len(), 3);
        // x ≤ 1 cuts one corner: a quad.
        clip_convex(&tri, |v| 1.0 - v.x, &mut out);
        assert_eq!(out.len(), 4);
    }

    #[test]
    fn shared_edges_clip_to_identical_vertices() {
        // Two triangles sharing the edge (0,0)–(1,1), traversed in opposite directions.
        let a = [
            DVec3::ZERO,
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
        ];
        let b = [
            DVec3::ZERO,
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
        ];
        let plane = |v: &DVec3| 0.3 - v.x;
        let (mut ca, mut cb) = (Vec::new(), Vec::new());
        clip_convex(&a, plane, &mut ca);
        clip_convex(&b, plane, &mut cb);
        let on_diagonal = |p: &&DVec3| (p.x - p.y).abs() < 1e-12 && p.x > 0.0;
        let pa = ca.iter().find(on_diagonal).unwrap();
        let pb = cb.iter().find(on_diagonal).unwrap();
        assert_eq!(pa, pb);
    }
}
