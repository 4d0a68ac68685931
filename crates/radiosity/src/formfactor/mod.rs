//! Form factors: the coupling between elements (receivers) and patches (sources).
//!
//! F_{e→p} = (1/A_e) ∫_{A_e} ∫_{A_p} cosθ_x cosθ_y V(x, y) / (π r²) dA_y dA_x is the fraction
//! of the power leaving element `e` diffusely that arrives at patch `p`. The solver gathers
//! B_e = E_e + ρ_e Σ_p F_{e→p} B_p. Every method implements [`FormFactors`]; the methods
//! are selected by name ([`FormFactorMethod`]) from the command line and the scene file.
//! Visibility is one shared component ([`Visibility`], rays through a BVH).

pub mod analytic;
pub mod analytic_point;
pub mod analytic_polygon;
pub mod hemicube;
pub mod monte_carlo;
pub mod pair;
pub mod point_sampled;
pub mod quadrature;
pub mod raycast;
pub mod table;

use crate::accel::Bvh;
use crate::mesh::Mesh;
use crate::progress::Progress;
use glam::{DVec3, Vec3};
use rayon::prelude::*;
use std::fmt;
use std::str::FromStr;

/// The form-factor methods, by the names used on the command line and in scene files.
///
/// See also: [`pair`] for the same methods on a single mesh-free problem, and [`table`] for
/// their accuracy and cost on the reference cases.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum FormFactorMethod {
    /// Element centre to patch by Lambert's exact contour formula, probe-ray visibility
    /// ([`analytic::AnalyticPoint`]).
    AnalyticPoint,
    /// Exact polygon-to-polygon (Schröder & Hanrahan 1993) × a ray-estimated visible
    /// fraction ([`analytic::AnalyticPolygon`]).
    AnalyticPolygon,
    /// The finite sum Σ cosθ_x cosθ_y V ΔA_y / (π r²) over sub-areas of the patch
    /// ([`point_sampled::PointSampled`]).
    PointSampled,
    /// Nusselt's analogue by the hemi-cube (Cohen & Greenberg 1985), z-buffer visibility
    /// ([`hemicube::Hemicube`]).
    Hemicube,
    /// Receiver quadrature × exact point-to-polygon × shadow rays (Wallace, Elmquist &
    /// Haines 1989).
    #[default]
    Raycast,
    /// Cosine-distributed rays from random points of the element, binned by the element (and
    /// so the patch) they hit first ([`monte_carlo::MonteCarlo`]).
    MonteCarlo,
}

impl FormFactorMethod {
    /// Every method, in the order of the lecture (exact to sampled).
    pub const ALL: &'static [FormFactorMethod] = &[
        FormFactorMethod::AnalyticPoint,
        FormFactorMethod::AnalyticPolygon,
        FormFactorMethod::PointSampled,
        FormFactorMethod::Hemicube,
        FormFactorMethod::Raycast,
        FormFactorMethod::MonteCarlo,
    ];

    pub fn name(self) -> &'static str {
        match self {
            FormFactorMethod::AnalyticPoint => "analytic-point",
            FormFactorMethod::AnalyticPolygon => "analytic-polygon",
            FormFactorMethod::PointSampled => "point-sampled",
            FormFactorMethod::Hemicube => "hemicube",
            FormFactorMethod::Raycast => "raycast",
            FormFactorMethod::MonteCarlo => "monte-carlo",
        }
    }

    /// Builds the method's engine over a mesh, with the method's default parameters.
    pub fn engine<'a>(
        self,
        mesh: &'a Mesh,
        visibility: &'a Visibility,
    ) -> Box<dyn FormFactors + 'a> {
        match self {
            FormFactorMethod::AnalyticPoint => {
                Box::new(analytic::AnalyticPoint::new(mesh, visibility))
            }
            FormFactorMethod::AnalyticPolygon => {
                Box::new(analytic::AnalyticPolygon::new(mesh, visibility))
            }
            FormFactorMethod::PointSampled => {
                Box::new(point_sampled::PointSampled::new(mesh, visibility))
            }
            // The hemi-cube's z-buffer is its own visibility.
            FormFactorMethod::Hemicube => Box::new(hemicube::Hemicube::new(
                mesh,
                hemicube::HemicubeParams::default(),
            )),
            FormFactorMethod::Raycast => Box::new(raycast::Raycast::new(mesh, visibility)),
            FormFactorMethod::MonteCarlo => {
                Box::new(monte_carlo::MonteCarlo::new(mesh, visibility))
            }
        }
    }
}

impl fmt::Display for FormFactorMethod {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for FormFactorMethod {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Self::ALL
            .iter()
            .copied()
            .find(|m| m.name() == s)
            .ok_or_else(|| {
                let names: Vec<_> = Self::ALL.iter().map(|m| m.name()).collect();
                format!(
                    "unknown form-factor method '{s}' (expected one of: {})",
                    names.join(", ")
                )
            })
    }
}

/// A way of computing element-to-patch form factors.
pub trait FormFactors: Sync {
    /// The method's name.
    fn name(&self) -> &'static str;

    /// F_{e→p}: element `e` (receiver) to patch `p` (source), with visibility.
    fn pair(&self, element: usize, patch: usize) -> f64;

    /// Column `p`: F_{e→p} for every element `e` (what one progressive shot needs).
    fn column(&self, patch: usize, out: &mut [f32]) {
        out.par_iter_mut()
            .enumerate()
            .for_each(|(e, f)| *f = self.pair(e, patch) as f32);
    }

    /// F_{e→e'} from element `e` to the single source element `source`, for near-field
    /// pairs (see [`NearField`]); `None` when the method only resolves whole patches.
    fn element_pair(&self, _element: usize, _source: usize) -> Option<f64> {
        None
    }

    /// Whether [`FormFactors::element_pair`] is available.
    fn resolves_elements(&self) -> bool {
        false
    }

    /// Row `e`: F_{e→p} for every patch `p` (what one gathering step needs).
    fn row(&self, element: usize, out: &mut [f32]) {
        for (p, f) in out.iter_mut().enumerate() {
            *f = self.pair(element, p) as f32;
        }
    }
}

/// Which patches are too close to an element to be treated as one uniform source.
///
/// The substructured system lets an element gather from a whole patch at the patch's mean
/// radiosity. Where the patch is close (within `κ` of its own diameter of the element), the
/// part the element actually sees can be much brighter or darker than the mean (a shadow
/// cast next to a block, a dark floor strip at a wall), so the element gathers from the
/// patch's elements one by one instead: a two-level hierarchy in the spirit of Hanrahan,
/// Salzman & Aupperle (1991), with the link level chosen by this distance oracle.
#[derive(Debug, Clone, Default)]
pub struct NearField {
    /// Near patches of each element (sorted).
    pub per_element: Vec<Vec<u32>>,
    /// Elements for which each patch is near (sorted).
    pub per_patch: Vec<Vec<u32>>,
}

impl NearField {
    /// Patches closer to the element's centre than `kappa` × their diameter.
    pub fn new(mesh: &Mesh, kappa: f64) -> Self {
        let info: Vec<(DVec3, f64, f64)> = mesh
            .patches
            .iter()
            .map(|p| {
                let c = p.polygon.centroid();
                let r = p
                    .polygon
                    .vertices()
                    .iter()
                    .map(|v| v.distance(c))
                    .fold(0.0, f64::max);
                (c, r, p.polygon.diameter())
            })
            .collect();
        let per_element: Vec<Vec<u32>> = mesh
            .elements
            .par_iter()
            .map(|e| {
                info.iter()
                    .zip(&mesh.patches)
                    .enumerate()
                    .filter(|(_, ((c, r, d), p))| {
                        p.surface != e.surface
                            && e.centre.distance(*c) - r < kappa * d
                            && p.polygon.distance_to(e.centre) < kappa * d
                    })
                    .map(|(i, _)| i as u32)
                    .collect()
            })
            .collect();
        let mut per_patch = vec![Vec::new(); mesh.patches.len()];
        for (e, near) in per_element.iter().enumerate() {
            for &p in near {
                per_patch[p as usize].push(e as u32);
            }
        }
        Self {
            per_element,
            per_patch,
        }
    }

    /// No near field: every element gathers from whole patches.
    pub fn none(mesh: &Mesh) -> Self {
        Self {
            per_element: vec![Vec::new(); mesh.elements.len()],
            per_patch: vec![Vec::new(); mesh.patches.len()],
        }
    }

    /// The near field a method supports: [`NearField::new`] with κ = 1 if it resolves
    /// elements, else none.
    pub fn for_method(mesh: &Mesh, ff: &dyn FormFactors) -> Self {
        if ff.resolves_elements() {
            Self::new(mesh, 1.0)
        } else {
            Self::none(mesh)
        }
    }

    pub fn is_near(&self, element: usize, patch: usize) -> bool {
        self.per_element[element]
            .binary_search(&(patch as u32))
            .is_ok()
    }
}

/// The coupling of every element to every patch: a dense element × patch matrix of
/// F_{e→p} for far pairs (row-major, zero where the pair is near) plus, for near pairs, the
/// element-to-element factors F_{e→e'} of the patch's elements.
#[derive(Debug, Clone)]
pub struct CouplingMatrix {
    pub elements: usize,
    pub patches: usize,
    pub data: Vec<f32>,
    /// Near-field links of each element: (source element, F_{e→e'}).
    pub near: Vec<Vec<(u32, f32)>>,
}

impl CouplingMatrix {
    /// Bytes needed to hold the matrix for a mesh.
    pub fn bytes_for(elements: usize, patches: usize) -> u128 {
        elements as u128 * patches as u128 * 4
    }

    /// Computes every row in parallel.
    pub fn compute(ff: &dyn FormFactors, mesh: &Mesh, progress: &dyn Progress) -> Self {
        let near_field = NearField::for_method(mesh, ff);
        Self::compute_with(ff, mesh, &near_field, progress)
    }

    /// Computes every row in parallel with a given near field.
    pub fn compute_with(
        ff: &dyn FormFactors,
        mesh: &Mesh,
        near_field: &NearField,
        progress: &dyn Progress,
    ) -> Self {
        let (n, m) = (mesh.elements.len(), mesh.patches.len());
        let mut data = vec![0.0f32; n * m];
        progress.start("form factors", n as u64);
        let near: Vec<Vec<(u32, f32)>> = data
            .par_chunks_mut(m.max(1))
            .enumerate()
            .map(|(e, row)| {
                let near_patches = &near_field.per_element[e];
                let mut links = Vec::new();
                // The whole row first (a method may compute rows faster than pairs), then
                // the near patches are resolved into element links.
                ff.row(e, row);
                for &p in near_patches {
                    row[p as usize] = 0.0;
                    for s in mesh.patches[p as usize].elements.clone() {
                        let v = ff.element_pair(e, s as usize).unwrap_or(0.0);
                        if v > 0.0 {
                            links.push((s, v as f32));
                        }
                    }
                }
                progress.inc(1);
                links
            })
            .collect();
        progress.finish();
        Self {
            elements: n,
            patches: m,
            data,
            near,
        }
    }

    pub fn row(&self, e: usize) -> &[f32] {
        &self.data[e * self.patches..(e + 1) * self.patches]
    }

    pub fn get(&self, e: usize, p: usize) -> f64 {
        self.data[e * self.patches + p] as f64
    }

    /// F_{e→p} with the near-field links of `p` summed back into it.
    pub fn full_row(&self, mesh: &Mesh, e: usize) -> Vec<f64> {
        let mut row: Vec<f64> = self.row(e).iter().map(|&f| f as f64).collect();
        for &(s, f) in &self.near[e] {
            row[mesh.elements[s as usize].patch.0 as usize] += f as f64;
        }
        row
    }
}

/// Point-to-point visibility by shadow rays through a BVH over the scene's surfaces.
///
/// Every surface blocks light from both sides (a back face is opaque). Ray ends are lifted
/// off their surfaces by a small offset proportional to the scene size so that the surfaces
/// the ray starts and ends on are not hit.
pub struct Visibility {
    bvh: Bvh,
    offset: f64,
    /// The polygon each BVH triangle came from (an index into the polygons it was built from:
    /// [`Mesh::surface_polygons`] for [`Visibility::new`]).
    triangle_polygon: Vec<u32>,
}

impl Visibility {
    /// Builds the BVH over the original surface polygons (fan-triangulated).
    pub fn new(mesh: &Mesh) -> Self {
        let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
        for p in &mesh.surface_polygons {
            let (a, b) = p.bounds();
            lo = lo.min(a);
            hi = hi.max(b);
        }
        let diameter = (hi - lo).length().max(1e-9);
        Self::from_polygons(mesh.surface_polygons.iter().map(|p| p.vertices()), diameter)
    }

    /// Builds the BVH over arbitrary opaque convex polygons (fan-triangulated), e.g. the
    /// occluders of a [`pair::PairProblem`]; ray ends are lifted by 1e-5 × `diameter`, the
    /// size of the whole configuration in metres.
    pub fn from_polygons<'p>(
        polygons: impl IntoIterator<Item = &'p [DVec3]>,
        diameter: f64,
    ) -> Self {
        let mut tris = Vec::new();
        let mut triangle_polygon = Vec::new();
        for (i, p) in polygons.into_iter().enumerate() {
            for w in p[1..].windows(2) {
                tris.push([p[0].as_vec3(), w[0].as_vec3(), w[1].as_vec3()]);
                triangle_polygon.push(i as u32);
            }
        }
        Self {
            bvh: Bvh::build(&tris),
            offset: 1e-5 * diameter.max(1e-9),
            triangle_polygon,
        }
    }

    /// How far ray ends are lifted off their surfaces, m.
    pub fn offset(&self) -> f64 {
        self.offset
    }

    /// The polygon (surface) a BVH triangle belongs to.
    pub fn polygon_of(&self, triangle: u32) -> usize {
        self.triangle_polygon[triangle as usize] as usize
    }

    /// True when nothing blocks the segment from `x` (on a surface with normal `nx`) to `y`
    /// (on a surface with normal `ny`).
    pub fn visible(&self, x: DVec3, nx: DVec3, y: DVec3, ny: DVec3) -> bool {
        let a = (x + nx * self.offset).as_vec3();
        let b = (y + ny * self.offset).as_vec3();
        !self.bvh.segment_occluded(a, b, 1e-5)
    }

    /// The underlying BVH.
    pub fn bvh(&self) -> &Bvh {
        &self.bvh
    }

    /// Closest surface hit along a ray (for picking and tests).
    pub fn first_hit(&self, origin: Vec3, dir: Vec3) -> Option<crate::accel::Hit> {
        self.bvh.intersect(origin, dir, 0.0, f32::INFINITY)
    }
}

/// Divides a convex triangle or quad into `k²` sub-polygons (bilinear or barycentric lattice).
pub fn subdivide(vertices: &[DVec3], k: usize) -> Vec<Vec<DVec3>> {
    let mut out = Vec::with_capacity(k * k);
    let kf = k as f64;
    if vertices.len() == 4 {
        let [a, b, c, d] = [vertices[0], vertices[1], vertices[2], vertices[3]];
        let p = |i: usize, j: usize| {
            let (u, v) = (i as f64 / kf, j as f64 / kf);
            (1.0 - u) * (1.0 - v) * a + u * (1.0 - v) * b + u * v * c + (1.0 - u) * v * d
        };
        for i in 0..k {
            for j in 0..k {
                out.push(vec![p(i, j), p(i + 1, j), p(i + 1, j + 1), p(i, j + 1)]);
            }
        }
    } else if vertices.len() == 3 {
        let [a, b, c] = [vertices[0], vertices[1], vertices[2]];
        let p = |i: usize, j: usize| a + (b - a) * (i as f64 / kf) + (c - a) * (j as f64 / kf);
        for i in 0..k {
            for j in 0..k - i {
                out.push(vec![p(i, j), p(i + 1, j), p(i, j + 1)]);
                if j + 1 < k - i {
                    out.push(vec![p(i + 1, j), p(i + 1, j + 1), p(i, j + 1)]);
                }
            }
        }
    } else {
        // General convex polygon: fan triangles, each subdivided.
        let v0 = vertices[0];
        for w in vertices[1..].windows(2) {
            out.extend(subdivide(&[v0, w[0], w[1]], k));
        }
    }
    out
}

/// Divides a convex polygon into about `k²` convex pieces of similar size and shape:
/// triangles by [`subdivide`] (`k²` similar triangles), quads on a `ku × kv` bilinear lattice
/// with `ku / kv` following the quad's aspect ratio (so that the pieces of a long strip are
/// not long strips themselves), larger polygons by clipping a square grid of side √A / k laid
/// along their first edge (so that a 256-gon is not cut into slivers).
///
/// The pieces tile the polygon exactly (their areas sum to its area, to rounding).
pub fn sub_areas(vertices: &[DVec3], k: usize) -> Vec<Vec<DVec3>> {
    let k = k.max(1);
    if vertices.len() == 4 {
        let [a, b, c, d] = [vertices[0], vertices[1], vertices[2], vertices[3]];
        let lu = a.distance(b).max(d.distance(c));
        let lv = a.distance(d).max(b.distance(c));
        let ku = ((k as f64 * (lu / lv).sqrt()).round() as usize).clamp(1, k * k);
        let kv = ((k * k) as f64 / ku as f64).round().max(1.0) as usize;
        let p = |i: usize, j: usize| {
            let (u, v) = (i as f64 / ku as f64, j as f64 / kv as f64);
            (1.0 - u) * (1.0 - v) * a + u * (1.0 - v) * b + u * v * c + (1.0 - u) * v * d
        };
        let mut out = Vec::with_capacity(ku * kv);
        for i in 0..ku {
            for j in 0..kv {
                out.push(vec![p(i, j), p(i + 1, j), p(i + 1, j + 1), p(i, j + 1)]);
            }
        }
        return out;
    }
    if vertices.len() <= 4 {
        return subdivide(vertices, k);
    }
    let (normal, area) = crate::geometry::newell(vertices);
    let origin = vertices[0];
    let u = (vertices[1] - origin).normalize();
    let w = normal.cross(u);
    let flat: Vec<[f64; 2]> = vertices
        .iter()
        .map(|v| [(*v - origin).dot(u), (*v - origin).dot(w)])
        .collect();
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for p in &flat {
        for a in 0..2 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    let side = area.sqrt() / k as f64;
    let cells = |a: usize| (((hi[a] - lo[a]) / side).ceil() as usize).max(1);
    let (nu, nw) = (cells(0), cells(1));
    let (hu, hw) = ((hi[0] - lo[0]) / nu as f64, (hi[1] - lo[1]) / nw as f64);
    let mut out = Vec::new();
    for i in 0..nu {
        for j in 0..nw {
            let (u0, w0) = (lo[0] + i as f64 * hu, lo[1] + j as f64 * hw);
            let mut piece = flat.clone();
            // The outer cells reach the bounding box: only inner cell walls cut.
            if i > 0 {
                piece = clip_flat(&piece, 0, u0, true);
            }
            if i + 1 < nu {
                piece = clip_flat(&piece, 0, u0 + hu, false);
            }
            if j > 0 {
                piece = clip_flat(&piece, 1, w0, true);
            }
            if j + 1 < nw {
                piece = clip_flat(&piece, 1, w0 + hw, false);
            }
            if piece.len() < 3 {
                continue;
            }
            let loop3: Vec<DVec3> = piece.iter().map(|p| origin + u * p[0] + w * p[1]).collect();
            if crate::geometry::newell(&loop3).1 > 1e-12 * area {
                out.push(loop3);
            }
        }
    }
    out
}

/// Sutherland–Hodgman clip of a 2-D convex loop to `p[axis] ≥ bound` (`above`) or
/// `p[axis] ≤ bound`.
fn clip_flat(poly: &[[f64; 2]], axis: usize, bound: f64, above: bool) -> Vec<[f64; 2]> {
    let side = |p: &[f64; 2]| {
        if above {
            p[axis] - bound
        } else {
            bound - p[axis]
        }
    };
    let n = poly.len();
    let mut out = Vec::with_capacity(n + 2);
    for i in 0..n {
        let (a, b) = (poly[i], poly[(i + 1) % n]);
        let (da, db) = (side(&a), side(&b));
        if da >= 0.0 {
            out.push(a);
        }
        if (da > 0.0 && db < 0.0) || (da < 0.0 && db > 0.0) {
            let t = da / (da - db);
            out.push([a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t]);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::newell;

    fn assert_tiles(poly: &[DVec3], pieces: &[Vec<DVec3>], what: &str) {
        let (normal, area) = newell(poly);
        let sum: f64 = pieces.iter().map(|p| newell(p).1).sum();
        assert!(
            (sum - area).abs() < 1e-12 * area,
            "{what}: pieces cover {sum}, polygon {area}"
        );
        for p in pieces {
            // Same orientation, inside the polygon.
            assert!(
                newell(p).0.dot(normal) > 0.999_999,
                "{what}: a piece is turned over"
            );
            for v in p {
                let n = poly.len();
                let inside = (0..n).all(|i| {
                    (poly[(i + 1) % n] - poly[i])
                        .cross(*v - poly[i])
                        .dot(normal)
                        >= -1e-12
                });
                assert!(inside, "{what}: piece vertex {v} outside");
            }
        }
    }

    #[test]
    fn sub_areas_tile_polygons_with_pieces_of_similar_size() {
        // A 4 × 0.5 strip: near-square pieces (11 of 0.36 × 0.5), not 4 × 4 long strips.
        let strip = vec![
            DVec3::ZERO,
            DVec3::new(4.0, 0.0, 0.0),
            DVec3::new(4.0, 0.5, 0.0),
            DVec3::new(0.0, 0.5, 0.0),
        ];
        let pieces = sub_areas(&strip, 4);
        assert!((8..=32).contains(&pieces.len()), "{} pieces", pieces.len());
        assert_tiles(&strip, &pieces, "strip");
        for p in &pieces {
            let (a, b) = (p[0].distance(p[1]), p[1].distance(p[2]));
            assert!(a.max(b) / a.min(b) <= 2.0, "a {a} × {b} piece");
        }
        // A square: exactly k × k squares.
        let square = vec![DVec3::ZERO, DVec3::X, DVec3::new(1.0, 1.0, 0.0), DVec3::Y];
        assert_eq!(sub_areas(&square, 5).len(), 25);
        let triangle = vec![DVec3::ZERO, DVec3::X, DVec3::new(0.2, 0.9, 0.3)];
        let pieces = sub_areas(&triangle, 3);
        assert_eq!(pieces.len(), 9);
        assert_tiles(&triangle, &pieces, "triangle");
        // A 64-gon: about k² pieces, none a sliver reaching across the disk.
        let disk: Vec<DVec3> = (0..64)
            .map(|i| {
                let a = std::f64::consts::TAU * i as f64 / 64.0;
                DVec3::new(a.cos(), a.sin(), 0.0)
            })
            .collect();
        let pieces = sub_areas(&disk, 4);
        assert!((8..=32).contains(&pieces.len()), "{} pieces", pieces.len());
        assert_tiles(&disk, &pieces, "64-gon");
        let side = newell(&disk).1.sqrt() / 4.0;
        for p in &pieces {
            let diameter = p
                .iter()
                .flat_map(|a| p.iter().map(move |b| a.distance(*b)))
                .fold(0.0, f64::max);
            assert!(
                diameter <= side * 2f64.sqrt() + 1e-12,
                "piece of diameter {diameter}"
            );
        }
    }
}
