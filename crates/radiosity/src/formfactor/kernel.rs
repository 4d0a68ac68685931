//! Form-factor kernels: geometry in, one number out.
//!
//! A kernel computes F from a receiver (a polygon, or a point with a normal) to a source
//! polygon, with visibility answered by a [`Visibility`] query:
//!
//!   F_{R→S} = (1/A_R) ∫_{A_R} ∫_{A_S} cosθ_x cosθ_y V(x, y) / (π r²) dA_y dA_x.
//!
//! A kernel never sees a mesh index: mesh-level engines (rows, columns, hemi-cubes over a
//! mesh, [`super::engine`]) and the hierarchical coupling build receivers and sources from
//! whatever pieces of geometry they link, and call the kernel. Sources are prepared once
//! ([`Kernel::source`]: probe points and penumbra sub-areas for visibility, sub-area samples)
//! because one source serves many receivers.

use super::analytic_point::point_to_polygon;
use super::quadrature::element_points;
use super::FormFactorMethod;
use crate::accel::Visibility;
use crate::geometry::{for_each_piece, newell, sub_areas, subdivide};
use glam::DVec3;

/// A receiving geometry: a polygon with quadrature points, or a single point.
#[derive(Debug, Clone, PartialEq)]
pub struct Receiver {
    /// Corners of the receiving polygon, counter-clockwise seen from its front; empty for a
    /// point receiver.
    pub vertices: Vec<DVec3>,
    /// Unit normal of the receiving side.
    pub normal: DVec3,
    /// Area centroid (the point itself for a point receiver), m.
    pub centre: DVec3,
    /// Quadrature points over the receiver, weights summing to 1.
    pub points: Vec<(DVec3, f64)>,
    /// The points visibility rays leave from, weights summing to 1.
    pub visibility_points: Vec<(DVec3, f64)>,
}

impl Receiver {
    /// A differential area at `x` with unit normal `normal`.
    pub fn point(x: DVec3, normal: DVec3) -> Self {
        Self {
            vertices: Vec::new(),
            normal,
            centre: x,
            points: vec![(x, 1.0)],
            visibility_points: vec![(x, 1.0)],
        }
    }

    /// A convex triangle or quad (or fan of triangles) integrated by an `order × order` Gauss
    /// rule ([`element_points`]); visibility is probed from the same points up to order 2,
    /// else from a 2 × 2 subset (Wallace, Elmquist & Haines 1989 cast few visibility rays).
    pub fn polygon(vertices: Vec<DVec3>, order: usize) -> Self {
        let (normal, _) = newell(&vertices);
        let centre = polygon_centroid(&vertices);
        let mut points = Vec::new();
        element_points(&vertices, centre, order.max(1), &mut points);
        let visibility_points = if order <= 2 {
            points.clone()
        } else {
            let mut vis = Vec::with_capacity(4);
            element_points(&vertices, centre, 2, &mut vis);
            vis
        };
        Self {
            vertices,
            normal,
            centre,
            points,
            visibility_points,
        }
    }

    /// Whether this is a differential area rather than a polygon.
    pub fn is_point(&self) -> bool {
        self.vertices.is_empty()
    }
}

/// A source polygon prepared for kernels: its plane, probe points for the visibility test,
/// and penumbra sub-areas (with centroids) for partially visible pairs.
#[derive(Debug, Clone, PartialEq)]
pub struct SourcePolygon {
    /// Corners, counter-clockwise seen from the emitting side.
    pub vertices: Vec<DVec3>,
    /// Unit normal of the emitting side.
    pub normal: DVec3,
    /// Area centroid, m.
    pub centre: DVec3,
    /// Largest distance from the centre to a corner, m.
    pub radius: f64,
    /// Area, m².
    pub area: f64,
    /// Points visibility rays aim at.
    pub probes: Vec<DVec3>,
    /// Penumbra sub-areas: where probes disagree, visibility is weighted by the exact form
    /// factors of these pieces.
    pub sub_areas: Vec<Vec<DVec3>>,
    /// Centroids of `sub_areas`.
    pub sub_points: Vec<DVec3>,
    /// Areas of `sub_areas`, m².
    pub sub_area_sizes: Vec<f64>,
}

/// How a source is divided into probes and penumbra sub-areas.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Division {
    /// [`subdivide`]: k² similar pieces per triangle, k × k on quads; probes at the pieces'
    /// lattice centres (vertex means).
    Lattice,
    /// [`sub_areas`]: about k² pieces of similar size and shape whatever the polygon; probes
    /// at the pieces' area centroids.
    SubAreas,
}

impl SourcePolygon {
    /// Prepares `vertices` with about `probe²` probe points and `penumbra²` penumbra
    /// sub-areas, divided by `division`.
    pub fn new(vertices: &[DVec3], probe: usize, penumbra: usize, division: Division) -> Self {
        let divide = |k: usize| match division {
            Division::Lattice => subdivide(vertices, k.max(1)),
            Division::SubAreas => sub_areas(vertices, k.max(1)),
        };
        let probes = divide(probe)
            .iter()
            .map(|p| match division {
                Division::Lattice => p.iter().copied().sum::<DVec3>() / p.len() as f64,
                Division::SubAreas => polygon_centroid(p),
            })
            .collect();
        let sub_areas = divide(penumbra);
        let sub_points = sub_areas.iter().map(|p| polygon_centroid(p)).collect();
        let sub_area_sizes = sub_areas.iter().map(|p| newell(p).1).collect();
        Self {
            probes,
            sub_areas,
            ..Self::from_sub_points(vertices, sub_points, sub_area_sizes)
        }
    }

    /// The source over `vertices` with the given sub-area centroids and areas, and no
    /// probes or outlines.
    fn from_sub_points(
        vertices: &[DVec3],
        sub_points: Vec<DVec3>,
        sub_area_sizes: Vec<f64>,
    ) -> Self {
        let (normal, area) = newell(vertices);
        let centre = polygon_centroid(vertices);
        let radius = vertices
            .iter()
            .map(|v| v.distance(centre))
            .fold(0.0, f64::max);
        Self {
            vertices: vertices.to_vec(),
            normal,
            centre,
            radius,
            area,
            probes: Vec::new(),
            sub_areas: Vec::new(),
            sub_points,
            sub_area_sizes,
        }
    }

    /// [`SourcePolygon::new`] followed by [`SourcePolygon::points_only`], without building
    /// the probes and outlines that it drops: the same centroids and areas, to the bit (the
    /// lattice cells' corners are the same points, summed in the same order). Building the
    /// outlines was 3 % of the hierarchical solve of the Cornell box.
    pub fn points_only_new(vertices: &[DVec3], penumbra: usize, division: Division) -> Self {
        let (mut sub_points, mut sub_area_sizes) = (Vec::new(), Vec::new());
        let mut add = |piece: &[DVec3]| {
            sub_points.push(polygon_centroid(piece));
            sub_area_sizes.push(newell(piece).1);
        };
        match division {
            Division::Lattice => for_each_piece(vertices, penumbra.max(1), &mut add),
            Division::SubAreas => sub_areas(vertices, penumbra.max(1))
                .iter()
                .for_each(|piece| add(piece)),
        }
        Self::from_sub_points(vertices, sub_points, sub_area_sizes)
    }

    /// The source without its probes and sub-area outlines, keeping the sub-areas'
    /// centroids and areas (`sub_points`, `sub_area_sizes`): all that a caller sampling the
    /// kernel point by point needs (the hierarchical coupling with the ray-cast kernel), in
    /// under a third of the memory (a quad's 16 sub-areas: 2.2 kB of outlines, 0.5 kB of
    /// centroids and areas). [`Kernel::form_factor`] must not be given it.
    pub fn points_only(mut self) -> Self {
        self.probes = Vec::new();
        self.sub_areas = Vec::new();
        self
    }
}

/// Area centroid of a planar convex polygon (the vertex mean if it has no area).
pub fn polygon_centroid(v: &[DVec3]) -> DVec3 {
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

/// A form-factor method as a kernel on geometry.
pub trait Kernel: Sync + Send {
    /// The method this kernel implements.
    fn method(&self) -> FormFactorMethod;

    /// Prepares a convex source polygon (counter-clockwise seen from its emitting side).
    fn source(&self, vertices: &[DVec3]) -> SourcePolygon;

    /// [`Kernel::source`] as [`SourcePolygon::points_only`] leaves it, for a caller that
    /// samples the kernel point by point and never calls [`Kernel::form_factor`] with it.
    /// A kernel may build it without the outlines that are dropped.
    fn points_only_source(&self, vertices: &[DVec3]) -> SourcePolygon {
        self.source(vertices).points_only()
    }

    /// The Gauss order per axis at which a receiving polygon of diameter `size` (m) is
    /// integrated; `clearance(limit)` gives its distance (m) to the nearest other surface
    /// that can exchange light with it when that is below `limit` m, else ∞ (computed only
    /// if the kernel asks; the search costs what lies within `limit`). Default 1: the centre.
    fn receiver_order(&self, _size: f64, _clearance: &dyn Fn(f64) -> f64) -> usize {
        1
    }

    /// F from `receiver` to `source`, with visibility from `visibility`. Dimensionless, ≥ 0;
    /// 0 when either faces away from the other (surfaces are one-sided).
    fn form_factor(
        &self,
        receiver: &Receiver,
        source: &SourcePolygon,
        visibility: &Visibility,
    ) -> f64;
}

/// The fraction of `source` visible from the receiver points `receivers` (weights summing
/// to 1, unit normal `n`), from 0 to 1.
///
/// Probe stage (after Wallace, Elmquist & Haines 1989): with one receiver point, or with
/// `all_probes`, every point casts a ray to every probe; otherwise each casts one, rotating
/// through the probes; probes behind a point's tangent plane are skipped. All visible gives
/// exactly 1, none exactly 0. Otherwise (or when no probe was in front) the fraction is
/// Σ_x w_x Σ_k F_{x→ΔA_k} V(x, y_k) / Σ_x w_x Σ_k F_{x→ΔA_k} over the penumbra sub-areas ΔA_k
/// with centroids y_k, F the exact point-to-polygon factor.
pub fn visible_fraction(
    vis: &Visibility,
    receivers: &[(DVec3, f64)],
    n: DVec3,
    s: &SourcePolygon,
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
            // A probe behind the receiver's tangent plane says nothing about what it sees.
            if (y - *x).dot(n) <= 0.0 {
                continue;
            }
            total += 1;
            visible += usize::from(vis.visible(*x, n, y, s.normal));
        }
    }
    if total > 0 && visible == total {
        return 1.0;
    }
    if total > 0 && visible == 0 {
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
    } else if total > 0 {
        visible as f64 / total as f64
    } else {
        // Nothing of the source is in front of any receiver point (a coplanar neighbour
        // tilted by rounding): nothing is seen. (Was 0/0 = NaN, which made the
        // `analytic-point` rows of closed boxes NaN.)
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The source built without outlines is, to the bit, the full source with its outlines
    /// dropped: a triangle, a skewed quad and a pentagon (its fan triangles), for both
    /// divisions and several sub-area counts.
    #[test]
    fn a_points_only_source_is_the_full_one_less_its_outlines() {
        let polygons = [
            vec![
                DVec3::new(0.0, 0.0, 0.0),
                DVec3::new(1.3, 0.1, 0.0),
                DVec3::new(0.2, 0.9, 0.0),
            ],
            vec![
                DVec3::new(0.0, 0.0, 0.5),
                DVec3::new(2.0, 0.0, 0.5),
                DVec3::new(2.2, 0.7, 0.5),
                DVec3::new(-0.1, 0.6, 0.5),
            ],
            (0..5)
                .map(|k| {
                    let a = k as f64 * std::f64::consts::TAU / 5.0;
                    DVec3::new(a.cos(), 0.3, a.sin())
                })
                .rev()
                .collect(),
        ];
        for vertices in &polygons {
            for division in [Division::Lattice, Division::SubAreas] {
                for penumbra in [1, 3, 4] {
                    let full = SourcePolygon::new(vertices, 2, penumbra, division).points_only();
                    let lean = SourcePolygon::points_only_new(vertices, penumbra, division);
                    assert!(!lean.sub_points.is_empty());
                    assert_eq!(
                        full,
                        lean,
                        "{} vertices, {division:?}, {penumbra}",
                        vertices.len()
                    );
                }
            }
        }
    }
}
