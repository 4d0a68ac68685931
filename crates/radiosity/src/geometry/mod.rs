//! Planar convex polygons: the geometric primitive every later stage works on.
//!
//! Lengths are in metres; vertices are `f64` because form-factor and solver accuracy
//! (1e-6 and better) depends on them. Polygons are counter-clockwise seen from their
//! front (lit, emitting) side; the normal is `normalize(cross(v1 - v0, v2 - v0))`, computed
//! robustly with Newell's method.
//!
//! See also: [`split_into_convex`] for turning arbitrary input faces into valid polygons.

pub mod clip;
pub mod lattice;
mod triangulate;

pub use clip::{
    clip_convex, clip_to_halfspace, split_convex, ClipOutput, ClipVertex, FixedPolygon,
};
pub(crate) use lattice::PlaneFrame;
pub use lattice::{for_each_piece, sub_areas, subdivide, Lattice};

use glam::DVec3;

/// Why a list of vertices is not a usable polygon.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GeometryError {
    #[error("polygon has {0} distinct vertices; at least 3 are needed")]
    /// Fewer than three distinct vertices.
    TooFewVertices(usize),
    #[error("polygon has a non-finite coordinate (NaN or infinity)")]
    /// A coordinate is NaN or infinite.
    NonFinite,
    #[error("polygon is degenerate (area {area:.3e} m², collinear or repeated vertices)")]
    /// Zero (or nearly zero) area.
    Degenerate {
        /// Area, m².
        area: f64,
    },
    #[error("polygon is not planar: a vertex lies {deviation:.3e} m off its plane")]
    /// Not planar.
    NonPlanar {
        /// Largest distance of a vertex from the plane, m.
        deviation: f64,
    },
    #[error("polygon is not convex")]
    /// The polygon is not convex.
    NonConvex,
    #[error("polygon crosses itself (edge {edge} crosses another edge)")]
    /// Two edges of the loop cross (a bow-tie quad, a pentagram), or the loop touches
    /// itself so that it cannot be split into triangles; its area would be wrong.
    SelfIntersecting {
        /// The 1-based position in the loop of the first vertex of an edge that crosses
        /// another.
        edge: usize,
    },
    #[error("polygon coordinate {value:e} m is out of range (|x| must stay below {limit:e} m)")]
    /// A coordinate beyond [`COORDINATE_LIMIT`].
    OutOfRange {
        /// The value given.
        value: f64,
        /// The largest accepted.
        limit: f64,
    },
}

/// Coordinates beyond this (metres) are rejected as absurd: 1e6 m is a city-sized scene.
pub const COORDINATE_LIMIT: f64 = 1.0e6;

/// A planar, convex polygon with at least three vertices, counter-clockwise seen from the front.
#[derive(Debug, Clone, PartialEq)]
pub struct Polygon {
    vertices: Vec<DVec3>,
    normal: DVec3,
    area: f64,
}

impl Polygon {
    /// Validates and builds a polygon: finite, in range, non-degenerate, planar and convex.
    ///
    /// Consecutive duplicate vertices are removed first. Planarity tolerance is relative:
    /// 1e-6 of the polygon's diameter (plus 1e-12 m).
    pub fn new(vertices: Vec<DVec3>) -> Result<Self, GeometryError> {
        let vertices = check_vertices(vertices)?;
        let (normal, area) = newell(&vertices);
        let diameter = diameter(&vertices);
        if area.is_nan() || area <= 1e-14 * diameter * diameter || area < 1e-20 {
            return Err(GeometryError::Degenerate { area });
        }
        let deviation = plane_deviation(&vertices, normal);
        if deviation > 1e-6 * diameter + 1e-12 {
            return Err(GeometryError::NonPlanar { deviation });
        }
        if !is_convex(&vertices, normal) {
            return Err(GeometryError::NonConvex);
        }
        Ok(Self {
            vertices,
            normal,
            area,
        })
    }

    /// Builds a polygon already known to be valid (e.g. a sub-polygon of a valid one).
    /// Only the cheap checks run in debug builds.
    pub fn new_unchecked(vertices: Vec<DVec3>) -> Self {
        let (normal, area) = newell(&vertices);
        debug_assert!(vertices.len() >= 3 && area > 0.0);
        Self {
            vertices,
            normal,
            area,
        }
    }

    /// Vertices, counter-clockwise seen from the front.
    pub fn vertices(&self) -> &[DVec3] {
        &self.vertices
    }

    /// Unit normal on the front side.
    pub fn normal(&self) -> DVec3 {
        self.normal
    }

    /// Area in m².
    pub fn area(&self) -> f64 {
        self.area
    }

    /// Area centroid.
    pub fn centroid(&self) -> DVec3 {
        let v0 = self.vertices[0];
        let mut sum = DVec3::ZERO;
        let mut total = 0.0;
        for w in self.vertices[1..].windows(2) {
            let a = (w[0] - v0).cross(w[1] - v0).dot(self.normal) * 0.5;
            sum += a * (v0 + w[0] + w[1]) / 3.0;
            total += a;
        }
        sum / total
    }

    /// Longest edge length in m.
    pub fn max_edge(&self) -> f64 {
        self.edges().map(|(a, b)| a.distance(b)).fold(0.0, f64::max)
    }

    /// Largest distance between two vertices (m).
    pub fn diameter(&self) -> f64 {
        diameter(&self.vertices)
    }

    /// Edges as (start, end) pairs, closing the loop.
    pub fn edges(&self) -> impl Iterator<Item = (DVec3, DVec3)> + '_ {
        let n = self.vertices.len();
        (0..n).map(move |i| (self.vertices[i], self.vertices[(i + 1) % n]))
    }

    /// Fan triangulation from vertex 0 (valid because the polygon is convex).
    pub fn triangles(&self) -> impl Iterator<Item = [DVec3; 3]> + '_ {
        let v0 = self.vertices[0];
        self.vertices[1..].windows(2).map(move |w| [v0, w[0], w[1]])
    }

    /// Signed distance of `p` from the polygon's plane, positive in front.
    pub fn plane_distance(&self, p: DVec3) -> f64 {
        (p - self.vertices[0]).dot(self.normal)
    }

    /// Euclidean distance from `p` to the (filled) polygon.
    pub fn distance_to(&self, p: DVec3) -> f64 {
        let h = self.plane_distance(p);
        let q = p - self.normal * h;
        let inside = self
            .edges()
            .all(|(a, b)| (b - a).cross(q - a).dot(self.normal) >= 0.0);
        if inside {
            return h.abs();
        }
        self.edges()
            .map(|(a, b)| {
                let d = b - a;
                let t = ((p - a).dot(d) / d.length_squared()).clamp(0.0, 1.0);
                p.distance(a + d * t)
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// Axis-aligned bounds (min, max).
    pub fn bounds(&self) -> (DVec3, DVec3) {
        self.vertices.iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), v| (lo.min(*v), hi.max(*v)),
        )
    }

    /// The part of the polygon strictly in front of the plane through `origin` with normal
    /// `normal` (Sutherland–Hodgman clip against one plane). `None` if nothing remains.
    pub fn clip_to_halfspace(&self, origin: DVec3, normal: DVec3) -> Option<Vec<DVec3>> {
        clip_to_halfspace(&self.vertices, origin, normal)
    }
}

/// Triangles (index triples, counter-clockwise like the loop) of a convex loop of `n`
/// vertices, cut by chords in halves: the triangle (i, m, j) on a chord i–j with m halfway
/// between, then the chains i…m and m…j the same way, from the chord 0–(n − 1).
///
/// The fan from vertex 0 has n − 2 triangles that all reach vertex 0, so the bounding boxes
/// of a disc's fan all overlap one another near it, and a box or ray query there meets O(n)
/// of them. Here triangles shrink towards the outline, each level of halving covers a thin
/// band inside the previous one, and a point lies in the boxes of O(log n) of them. Still
/// n − 2 triangles, the loop's edges all among their edges (so neighbouring polygons stay
/// watertight for rays).
pub fn balanced_triangles(n: usize) -> Vec<[usize; 3]> {
    let mut out = Vec::with_capacity(n.saturating_sub(2));
    if n < 3 {
        return out;
    }
    let mut chords = vec![(0, n - 1)];
    while let Some((i, j)) = chords.pop() {
        if j - i < 2 {
            continue;
        }
        let m = i + (j - i) / 2;
        out.push([i, m, j]);
        chords.push((m, j));
        chords.push((i, m));
    }
    out
}

/// Newell's method: (unit normal, area) of a planar polygon loop.
pub fn newell(vertices: &[DVec3]) -> (DVec3, f64) {
    let mut n = DVec3::ZERO;
    let c = vertices[0];
    for i in 0..vertices.len() {
        let a = vertices[i] - c;
        let b = vertices[(i + 1) % vertices.len()] - c;
        n += a.cross(b);
    }
    let len = n.length();
    if len > 0.0 {
        (n / len, 0.5 * len)
    } else {
        (DVec3::ZERO, 0.0)
    }
}

fn check_vertices(vertices: Vec<DVec3>) -> Result<Vec<DVec3>, GeometryError> {
    for v in &vertices {
        if !v.is_finite() {
            return Err(GeometryError::NonFinite);
        }
        let m = v.abs().max_element();
        if m > COORDINATE_LIMIT {
            return Err(GeometryError::OutOfRange {
                value: m,
                limit: COORDINATE_LIMIT,
            });
        }
    }
    let mut out: Vec<DVec3> = Vec::with_capacity(vertices.len());
    for v in vertices {
        if out.last() != Some(&v) {
            out.push(v);
        }
    }
    while out.len() > 1 && out.first() == out.last() {
        out.pop();
    }
    if out.len() < 3 {
        return Err(GeometryError::TooFewVertices(out.len()));
    }
    Ok(out)
}

/// Largest distance between two vertices. Exact: by all pairs for small loops, else by
/// rotating calipers (Shamos 1978) over the convex hull of the loop projected onto its plane,
/// O(n log n), so that a face of 10⁵ vertices costs milliseconds rather than minutes.
fn diameter(vertices: &[DVec3]) -> f64 {
    if vertices.len() <= 64 {
        let mut d: f64 = 0.0;
        for (i, a) in vertices.iter().enumerate() {
            for b in &vertices[i + 1..] {
                d = d.max(a.distance(*b));
            }
        }
        return d;
    }
    let (normal, _) = newell(vertices);
    let origin = vertices[0];
    let u = normal.any_orthonormal_vector();
    let w = normal.cross(u);
    let flat: Vec<[f64; 2]> = vertices
        .iter()
        .map(|v| [(*v - origin).dot(u), (*v - origin).dot(w)])
        .collect();
    let hull = convex_hull_2d(flat);
    // Off-plane deviations are below the planarity tolerance; add the largest so the result
    // never understates the 3-D diameter by more than rounding.
    let off = vertices
        .iter()
        .map(|v| (*v - origin).dot(normal).abs())
        .fold(0.0, f64::max);
    calipers_diameter(&hull) + 2.0 * off
}

/// Convex hull of 2-D points (Andrew's monotone chain), counter-clockwise, no collinear points.
fn convex_hull_2d(mut p: Vec<[f64; 2]>) -> Vec<[f64; 2]> {
    p.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    p.dedup();
    if p.len() < 3 {
        return p;
    }
    let cross = |o: [f64; 2], a: [f64; 2], b: [f64; 2]| {
        (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
    };
    let mut hull: Vec<[f64; 2]> = Vec::with_capacity(2 * p.len());
    for &q in p.iter().chain(p.iter().rev().skip(1)) {
        while hull.len() >= 2 && cross(hull[hull.len() - 2], hull[hull.len() - 1], q) <= 0.0 {
            hull.pop();
        }
        hull.push(q);
    }
    hull.pop();
    hull
}

/// Diameter of a convex polygon (counter-clockwise) by rotating calipers.
fn calipers_diameter(hull: &[[f64; 2]]) -> f64 {
    let n = hull.len();
    let dist = |a: [f64; 2], b: [f64; 2]| ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt();
    if n < 3 {
        return if n == 2 { dist(hull[0], hull[1]) } else { 0.0 };
    }
    let area2 = |a: [f64; 2], b: [f64; 2], c: [f64; 2]| {
        ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])).abs()
    };
    let mut best: f64 = 0.0;
    let mut j = 1;
    for i in 0..n {
        let next = (i + 1) % n;
        while area2(hull[i], hull[next], hull[(j + 1) % n]) > area2(hull[i], hull[next], hull[j]) {
            j = (j + 1) % n;
        }
        best = best
            .max(dist(hull[i], hull[j]))
            .max(dist(hull[next], hull[j]));
    }
    best
}

fn plane_deviation(vertices: &[DVec3], normal: DVec3) -> f64 {
    let centre = vertices.iter().copied().sum::<DVec3>() / vertices.len() as f64;
    vertices
        .iter()
        .map(|v| (*v - centre).dot(normal).abs())
        .fold(0.0, f64::max)
}

/// Convex: every turn is to the left (or straight), and the turns add up to one full turn,
/// so that a star polygon (a pentagram, whose turns are all to the left but add up to two
/// turns) is not taken for convex.
fn is_convex(vertices: &[DVec3], normal: DVec3) -> bool {
    let n = vertices.len();
    let scale = diameter(vertices);
    let mut turning = 0.0;
    for i in 0..n {
        let a = vertices[i];
        let b = vertices[(i + 1) % n];
        let c = vertices[(i + 2) % n];
        let (e, f) = (b - a, c - b);
        let turn = e.cross(f).dot(normal);
        // Collinear consecutive vertices (turn ~ 0) are allowed: they are hanging vertices.
        if turn < -1e-12 * scale * scale {
            return false;
        }
        turning += turn.atan2(e.dot(f));
    }
    // One turn is 2π; a loop winding twice turns 4π. Rounding is far below π.
    (turning - std::f64::consts::TAU).abs() < std::f64::consts::PI
}

/// Turns an input face into valid polygons: convex planar faces pass through; a non-planar
/// quad is split along its shorter diagonal into two triangles; a planar non-convex face is
/// split into triangles by ear clipping. Anything else (non-planar with more than four
/// vertices) is rejected.
pub fn split_into_convex(vertices: Vec<DVec3>) -> Result<Vec<Polygon>, GeometryError> {
    match Polygon::new(vertices.clone()) {
        Ok(p) => Ok(vec![p]),
        Err(GeometryError::NonPlanar { deviation }) => {
            let v = check_vertices(vertices)?;
            if v.len() != 4 {
                return Err(GeometryError::NonPlanar { deviation });
            }
            let (a, b) = if v[0].distance(v[2]) <= v[1].distance(v[3]) {
                ([v[0], v[1], v[2]], [v[0], v[2], v[3]])
            } else {
                ([v[0], v[1], v[3]], [v[1], v[2], v[3]])
            };
            Ok(vec![Polygon::new(a.to_vec())?, Polygon::new(b.to_vec())?])
        }
        Err(GeometryError::NonConvex) => ear_clip(check_vertices(vertices)?),
        Err(e) => Err(e),
    }
}

/// Splits a planar face that is not convex into triangles ([`triangulate::ear_clip`]),
/// after checking that no two of its edges cross ([`triangulate::crossing`]).
fn ear_clip(vertices: Vec<DVec3>) -> Result<Vec<Polygon>, GeometryError> {
    let (normal, _) = newell(&vertices);
    let planar = triangulate::Planar::new(&vertices, normal);
    if let Some(edge) = triangulate::crossing(&planar) {
        return Err(GeometryError::SelfIntersecting { edge: edge + 1 });
    }
    let triangles =
        triangulate::ear_clip(&planar).ok_or(GeometryError::SelfIntersecting { edge: 1 })?;
    triangles
        .into_iter()
        .map(|t| Polygon::new(t.iter().map(|&k| vertices[k]).collect()))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn balanced_triangles_tile_a_disc_and_few_boxes_overlap() {
        let n = 1000;
        let disc: Vec<DVec3> = (0..n)
            .map(|k| {
                let a = std::f64::consts::TAU * k as f64 / n as f64;
                DVec3::new(a.cos(), a.sin(), 0.0)
            })
            .collect();
        let tris = balanced_triangles(n);
        assert_eq!(tris.len(), n - 2);
        let area: f64 = tris
            .iter()
            .map(|t| 0.5 * (disc[t[1]] - disc[t[0]]).cross(disc[t[2]] - disc[t[0]]).z)
            .sum();
        // Every triangle counter-clockwise (a turned one would subtract): the sum is the
        // polygon's area, (n/2) sin(2π/n), to rounding.
        let exact = 0.5 * n as f64 * (std::f64::consts::TAU / n as f64).sin();
        assert!((area - exact).abs() < 1e-12, "{area} against {exact}");
        let mut edges = std::collections::HashSet::new();
        for t in &tris {
            assert!(t[0] < t[1] && t[1] < t[2]);
            for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[0], t[2])] {
                edges.insert((a, b));
            }
        }
        assert!((0..n).all(|k| edges.contains(&(k.min((k + 1) % n), k.max((k + 1) % n)))));
        // The fan's boxes all hold points near vertex 0's side; here any point is in the
        // boxes of a few triangles per halving level (log₂ 1000 ≈ 10 levels).
        for p in [
            DVec3::ZERO,
            DVec3::new(0.99, 0.0, 0.0),
            DVec3::new(-0.5, 0.5, 0.0),
        ] {
            let holding = tris
                .iter()
                .filter(|t| {
                    let (lo, hi) = t.iter().fold(
                        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
                        |(lo, hi), &k| (lo.min(disc[k]), hi.max(disc[k])),
                    );
                    p.x >= lo.x && p.x <= hi.x && p.y >= lo.y && p.y <= hi.y
                })
                .count();
            assert!(holding <= 40, "{holding} boxes hold {p}");
        }
    }

    fn square() -> Vec<DVec3> {
        vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
        ]
    }

    #[test]
    fn unit_square_has_area_one_and_normal_plus_z() {
        let p = Polygon::new(square()).unwrap();
        assert!((p.area() - 1.0).abs() < 1e-15);
        assert!((p.normal() - DVec3::Z).length() < 1e-15);
        assert!((p.centroid() - DVec3::new(0.5, 0.5, 0.0)).length() < 1e-15);
    }

    #[test]
    fn rejects_bad_polygons() {
        let mut v = square();
        v[2].x = f64::NAN;
        assert_eq!(Polygon::new(v), Err(GeometryError::NonFinite));
        let line = vec![DVec3::ZERO, DVec3::X, DVec3::X * 2.0];
        assert!(matches!(
            Polygon::new(line),
            Err(GeometryError::Degenerate { .. })
        ));
        let mut twisted = square();
        twisted[2].z = 0.1;
        assert!(matches!(
            Polygon::new(twisted.clone()),
            Err(GeometryError::NonPlanar { .. })
        ));
        assert_eq!(split_into_convex(twisted).unwrap().len(), 2);
        assert_eq!(
            Polygon::new(vec![DVec3::ZERO, DVec3::X]),
            Err(GeometryError::TooFewVertices(2))
        );
    }

    #[test]
    fn non_convex_is_split_preserving_area() {
        // An L shape of area 3.
        let l = vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(2.0, 1.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(1.0, 2.0, 0.0),
            DVec3::new(0.0, 2.0, 0.0),
        ];
        assert_eq!(Polygon::new(l.clone()), Err(GeometryError::NonConvex));
        let parts = split_into_convex(l).unwrap();
        let area: f64 = parts.iter().map(Polygon::area).sum();
        assert!((area - 3.0).abs() < 1e-12);
        assert!(parts.iter().all(|p| p.normal().z > 0.99));
    }

    #[test]
    fn self_intersecting_polygons_are_rejected() {
        let v = |x: f64, y: f64| DVec3::new(x, y, 0.0);
        // A bow-tie with lobes of different sizes: its Newell area (3/4 − 1/12) is not the
        // area it covers, so accepting it would be silently wrong.
        let bow_tie = vec![v(0.0, 0.0), v(2.0, 2.0), v(2.0, 0.0), v(0.0, 1.0)];
        assert!(matches!(
            split_into_convex(bow_tie),
            Err(GeometryError::SelfIntersecting { .. })
        ));
        // A pentagram: every turn is to the left, but the loop winds twice.
        let star: Vec<DVec3> = (0..5)
            .map(|k| {
                let a = std::f64::consts::TAU * (2 * k) as f64 / 5.0;
                v(a.cos(), a.sin())
            })
            .collect();
        assert_eq!(Polygon::new(star.clone()), Err(GeometryError::NonConvex));
        assert!(matches!(
            split_into_convex(star),
            Err(GeometryError::SelfIntersecting { .. })
        ));
    }

    #[test]
    fn clipping_keeps_front_part() {
        let p = Polygon::new(square()).unwrap();
        let clipped = p
            .clip_to_halfspace(DVec3::new(0.25, 0.0, 0.0), DVec3::X)
            .unwrap();
        let (_, area) = newell(&clipped);
        assert!((area - 0.75).abs() < 1e-15);
        assert!(p
            .clip_to_halfspace(DVec3::new(2.0, 0.0, 0.0), DVec3::X)
            .is_none());
    }
}
