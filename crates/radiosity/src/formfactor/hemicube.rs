//! `hemicube`: Nusselt's analogue by the hemi-cube (Cohen & Greenberg 1985, "The hemi-cube:
//! a radiosity solution for complex environments").
//!
//! The form factor from a differential area at x (normal n) to a surface equals the part of
//! the unit disc under x covered by the surface projected first onto the unit hemisphere and
//! then orthogonally onto the disc (Nusselt's analogue). Any surface enclosing x projects the
//! same way, so the hemisphere is replaced by a half cube: a top face at height 1
//! (x, y ∈ [−1, 1]) and four side faces of half height (z ∈ [0, 1]), divided into pixels
//! whose *delta form factors* are precomputed:
//!
//!   top pixel at (x, y, 1):   ΔF = ΔA / (π (x² + y² + 1)²),
//!   side pixel at (1, y, z):  ΔF = z ΔA / (π (y² + z² + 1)²).
//!
//! Every polygon is projected onto the five faces through x and z-buffered; the form factor
//! to a polygon is the sum of the ΔF of the pixels it wins:
//!
//!   F_{dx→p} ≈ Σ_{pixels won by p} ΔF.
//!
//! Details that matter for accuracy and robustness:
//! - the ΔF above sample the integrand at pixel centres, so at a finite resolution they sum to
//!   1 + O(1/res²) (1 + 1.3e-4 at 64, 1 + 3.3e-5 at 128), not exactly 1; they are
//!   **normalised** to sum to 1 so that a closed scene gives Σ_p F = 1 exactly (to rounding);
//! - each polygon is clipped to each face's view frustum in the face's own frame (four side
//!   planes through x; no near plane is needed, see [`LocalScene`]), so polygons spanning
//!   several faces, or passing beside x, are handled;
//! - coverage is decided at pixel centres; pixels whose centre lies within 10⁻³ pixel of a
//!   projected edge are decided in 3D, by the side of each edge's plane through x the ray d
//!   through the pixel centre passes, with a slack of 10⁻¹² that makes polygons meeting along
//!   a line overlap by a sliver instead of leaving rounding gaps: a closed scene covers every
//!   pixel (the z-buffer keeps one winner), so its form factors sum to 1;
//! - depth is the reciprocal distance along the pixel ray, which is exactly linear in the
//!   face's screen coordinates for a planar polygon; surfaces are one-sided: a polygon seen
//!   from behind wins pixels like any other (it is opaque) but contributes nothing;
//! - with [`HemicubeParams::jitter`] every hemi-cube is turned about its normal by a random
//!   angle (deterministic in the seed and the hemi-cube's index), so the pixel grid no longer
//!   lines up with the scene's edges: the systematic aliasing error of an axis-aligned scene
//!   becomes noise that averages out over receivers.
//!
//! On a mesh, `row(e)` places one hemi-cube at element e's centre (lifted off its surface by
//! 10⁻⁷ of the scene's size) and rasterises every patch (the point-sampled receiver is the
//! hemi-cube method's own approximation: F_{e→p} ≈ F_{d(centre of e)→p}); `column(p)` is the
//! progressive-refinement use (Cohen, Chen, Wallace & Greenberg 1988): one hemi-cube at patch
//! p's centre rasterising every element gives F_{p→e}, and reciprocity gives
//! F_{e→p} = F_{p→e} A_p / A_e. The hemi-cube's pixels are split into six equal tiles (two
//! halves of the top face, four sides) which `column` renders in parallel.
//!
//! See also: [`super::analytic_point`] (the exact unoccluded value of one hemi-cube).

use super::kernel::{Division, Kernel, Receiver, SourcePolygon};
use super::pair::{Estimate, PairProblem, Source};
use super::quadrature::{element_points, gauss_legendre};
use super::{Engine, FormFactorMethod, Visibility};
use crate::geometry::clip_convex;
use crate::mesh::Mesh;
use glam::DVec3;
use rayon::prelude::*;
use std::cell::RefCell;
use std::f64::consts::PI;

/// Parameters of the hemi-cube method.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct HemicubeParams {
    /// Pixels along the top face's side (the side faces have `resolution` × ⌈resolution/2⌉).
    /// Clamped to [`MIN_RESOLUTION`]..=[`MAX_RESOLUTION`].
    pub resolution: usize,
    /// Turn every hemi-cube about its normal by a random angle (against aliasing).
    pub jitter: bool,
    /// Seed of the jitter angles.
    pub seed: u64,
}

impl Default for HemicubeParams {
    fn default() -> Self {
        Self {
            resolution: 128,
            jitter: false,
            seed: 0,
        }
    }
}

/// Smallest usable resolution (one pixel per half face).
pub const MIN_RESOLUTION: usize = 2;
/// Largest resolution accepted: the ΔF tables take 4·res² × 8 bytes (134 MB at 2048) and each
/// thread's tile buffers res²/2 × 8 bytes (17 MB).
pub const MAX_RESOLUTION: usize = 2048;

/// Gauss order per axis of the points on a polygon source in [`hemicube_pair`] (n² points
/// on a triangle or quad, about n² per 90° on a polygon with more vertices, one hemi-cube
/// each). 8 keeps the quadrature error below 4e-5 on the reference cases
/// (worst: C-14, where the integrand has a log-type kink at the shared edge).
pub const PAIR_SOURCE_ORDER: usize = 8;

/// The delta form factors of a hemi-cube, normalised to sum to 1 over the whole hemi-cube.
///
/// Returns `(top, side)`: `top` has `resolution²` values, row-major with rows along y and
/// columns along x (both from −1 to 1); `side` has `⌈resolution/2⌉ × resolution` values for
/// one side face, rows along z (from 0 at the base to 1) and columns along the face's
/// horizontal axis (from −1 to 1). The four side faces share `side`, so
/// Σ top + 4 Σ side = 1. Unnormalised, the midpoint values
/// `ΔA/(π(x²+y²+1)²)` and `z ΔA/(π(y²+z²+1)²)` sum to 1 + O(1/resolution²) (1 + 3.3e-5
/// at 128); the normalisation removes that defect, which would otherwise show as a closed
/// scene's form factors summing to more than 1.
pub fn delta_form_factors(resolution: usize) -> (Vec<f64>, Vec<f64>) {
    let (mut top, mut side) = raw_delta_form_factors(resolution);
    let total = top.iter().sum::<f64>() + 4.0 * side.iter().sum::<f64>();
    top.iter_mut().for_each(|f| *f /= total);
    side.iter_mut().for_each(|f| *f /= total);
    (top, side)
}

/// The midpoint delta form factors before normalisation.
fn raw_delta_form_factors(resolution: usize) -> (Vec<f64>, Vec<f64>) {
    let res = clamp_resolution(resolution);
    let rows = res.div_ceil(2);
    let du = 2.0 / res as f64;
    let dz = 1.0 / rows as f64;
    let mut top = Vec::with_capacity(res * res);
    for j in 0..res {
        let y = -1.0 + (j as f64 + 0.5) * du;
        for i in 0..res {
            let x = -1.0 + (i as f64 + 0.5) * du;
            let r = x * x + y * y + 1.0;
            top.push(du * du / (PI * r * r));
        }
    }
    let mut side = Vec::with_capacity(rows * res);
    for j in 0..rows {
        let z = (j as f64 + 0.5) * dz;
        for i in 0..res {
            let y = -1.0 + (i as f64 + 0.5) * du;
            let r = y * y + z * z + 1.0;
            side.push(z * du * dz / (PI * r * r));
        }
    }
    (top, side)
}

fn clamp_resolution(resolution: usize) -> usize {
    resolution.clamp(MIN_RESOLUTION, MAX_RESOLUTION)
}

/// Pixel ids: a polygon's index, or one of these.
const NONE: u32 = u32::MAX;
/// Won by an occluder or by a polygon seen from behind: opaque, contributes nothing.
const BLOCKED: u32 = u32::MAX - 1;

/// Pixels within this distance (in pixels) of a projected edge get the 3D test.
const EDGE_MARGIN: f64 = 1e-3;

/// The 3D test counts a ray as inside a polygon when its (unit-normal) distance from
/// every edge plane is ≥ −EDGE_SLACK: polygons that meet along a line (shared edges,
/// T-junctions between surfaces meshed differently, silhouettes) overlap by a sliver far below
/// a pixel instead of leaving rounding gaps, and the z-buffer keeps one winner.
const EDGE_SLACK: f64 = 1e-12;

/// The outcode planes through the hemi-cube centre (local frame, z along the normal): every
/// tile's frustum is an intersection of half-spaces `P·p ≥ 0` or `P·p ≤ 0` of these.
const OUTCODE_PLANES: [DVec3; 8] = [
    DVec3::new(-1.0, 0.0, 1.0),
    DVec3::new(1.0, 0.0, 1.0),
    DVec3::new(0.0, -1.0, 1.0),
    DVec3::new(0.0, 1.0, 1.0),
    DVec3::new(1.0, -1.0, 0.0),
    DVec3::new(1.0, 1.0, 0.0),
    DVec3::new(0.0, 1.0, 0.0),
    DVec3::new(0.0, 0.0, 1.0),
];

/// Outcode of a local point: bit i set when `P_i·p < 0`, bit 8+i when `P_i·p > 0`.
fn outcode(p: DVec3) -> u16 {
    let mut code = 0u16;
    for (i, plane) in OUTCODE_PLANES.iter().enumerate() {
        let s = plane.dot(p);
        if s < 0.0 {
            code |= 1 << i;
        } else if s > 0.0 {
            code |= 1 << (8 + i);
        }
    }
    code
}

/// A rectangle of pixels on one hemi-cube face, with its view frustum.
#[derive(Debug, Clone)]
struct Tile {
    /// Face axes in the hemi-cube's local frame: view direction, screen right, screen up.
    w: DVec3,
    u: DVec3,
    v: DVec3,
    cols: usize,
    rows: usize,
    /// Screen coordinates of the tile's lower-left corner and the pixel size.
    u0: f64,
    v0: f64,
    du: f64,
    dv: f64,
    /// Frustum side planes through the centre: inside where `m·p ≥ 0`.
    planes: [DVec3; 4],
    /// The outcode bit of each plane (set for points outside it).
    plane_bits: [u16; 4],
    /// A polygon all of whose vertices share one of these outcode bits is outside.
    mask: u16,
    /// ΔF per pixel, row-major.
    delta: Vec<f64>,
}

/// The hemi-cube's six tiles and their delta form factors for one resolution.
#[derive(Debug, Clone)]
struct Layout {
    tiles: Vec<Tile>,
}

impl Layout {
    fn new(resolution: usize) -> Self {
        let res = clamp_resolution(resolution);
        let (top, side) = delta_form_factors(res);
        let rows = res.div_ceil(2);
        let du = 2.0 / res as f64;
        let (x, y, z) = (DVec3::X, DVec3::Y, DVec3::Z);
        let mut tiles = Vec::with_capacity(6);
        // The top face in two halves (rows below and above y = 0) so all six tiles have
        // (about) the same number of pixels.
        let half = res / 2;
        for (r0, r1) in [(0, half), (half, res)] {
            tiles.push(Tile::new(
                z,
                x,
                y,
                res,
                r1 - r0,
                -1.0 + r0 as f64 * du,
                du,
                top[r0 * res..r1 * res].to_vec(),
            ));
        }
        // Side faces: view along ±x, ±y; screen up is the normal; right × up = view on every
        // face, as on the top.
        for (w, u) in [(x, y), (-x, -y), (y, -x), (-y, x)] {
            tiles.push(Tile::new(
                w,
                u,
                z,
                res,
                rows,
                0.0,
                1.0 / rows as f64,
                side.clone(),
            ));
        }
        Self { tiles }
    }
}

impl Tile {
    #[allow(clippy::too_many_arguments)]
    fn new(
        w: DVec3,
        u: DVec3,
        v: DVec3,
        cols: usize,
        rows: usize,
        v0: f64,
        dv: f64,
        delta: Vec<f64>,
    ) -> Self {
        let du = 2.0 / cols as f64;
        let (u0, u1) = (-1.0, 1.0);
        let v1 = v0 + rows as f64 * dv;
        let planes = [u - u0 * w, u1 * w - u, v - v0 * w, v1 * w - v];
        let mut plane_bits = [0u16; 4];
        for (m, slot) in planes.iter().zip(&mut plane_bits) {
            let m = m.normalize();
            let bit = OUTCODE_PLANES.iter().enumerate().find_map(|(i, p)| {
                let p = p.normalize();
                if (m - p).length() < 1e-12 {
                    Some(1u16 << i)
                } else if (m + p).length() < 1e-12 {
                    Some(1u16 << (8 + i))
                } else {
                    None
                }
            });
            // Every tile plane is one of the outcode planes by construction.
            debug_assert!(bit.is_some(), "tile plane {m} has no outcode plane");
            *slot = bit.unwrap_or(0);
        }
        let mask = plane_bits.iter().fold(0, |m, b| m | b);
        Self {
            w,
            u,
            v,
            cols,
            rows,
            u0,
            v0,
            du,
            dv,
            planes,
            plane_bits,
            mask,
            delta,
        }
    }

    /// The (unnormalised) direction through the centre of pixel (i, j), local frame.
    #[inline]
    fn ray(&self, i: usize, j: usize) -> DVec3 {
        let su = self.u0 + (i as f64 + 0.5) * self.du;
        let sv = self.v0 + (j as f64 + 0.5) * self.dv;
        self.w + su * self.u + sv * self.v
    }
}

/// A hemi-cube's position and orientation: local x, y along the face axes, z along the normal.
#[derive(Debug, Clone, Copy)]
struct Frame {
    origin: DVec3,
    x: DVec3,
    y: DVec3,
    z: DVec3,
}

impl Frame {
    /// A frame at `origin` about the unit `normal`, turned by `angle` radians about it.
    fn new(origin: DVec3, normal: DVec3, angle: f64) -> Self {
        let (t, b) = normal.any_orthonormal_pair();
        let (s, c) = angle.sin_cos();
        let x = c * t + s * b;
        Self {
            origin,
            x,
            y: normal.cross(x),
            z: normal,
        }
    }

    #[inline]
    fn local(&self, p: DVec3) -> DVec3 {
        let d = p - self.origin;
        DVec3::new(d.dot(self.x), d.dot(self.y), d.dot(self.z))
    }

    #[inline]
    fn local_dir(&self, d: DVec3) -> DVec3 {
        DVec3::new(d.dot(self.x), d.dot(self.y), d.dot(self.z))
    }
}

/// Polygons to rasterise, in world coordinates.
#[derive(Debug, Clone, Default)]
struct PolySet {
    vertices: Vec<DVec3>,
    polys: Vec<PolyRef>,
}

#[derive(Debug, Clone, Copy)]
struct PolyRef {
    start: u32,
    len: u32,
    /// Unit normal on the front side.
    normal: DVec3,
    /// Surface index (polygons of the hemi-cube's own surface are skipped), or `u32::MAX`.
    surface: u32,
    /// The id its front side writes: an index into the result, or [`BLOCKED`].
    id: u32,
}

impl PolySet {
    fn push(&mut self, vertices: &[DVec3], normal: DVec3, surface: u32, id: u32) {
        self.polys.push(PolyRef {
            start: self.vertices.len() as u32,
            len: vertices.len() as u32,
            normal,
            surface,
            id,
        });
        self.vertices.extend_from_slice(vertices);
    }
}

/// Polygons transformed into one hemi-cube's local frame, ready to rasterise.
///
/// No near plane is needed: inside any face's frustum (four planes through the centre) a
/// point p at depth w along the face's view axis has |p| ≤ √3 w, and every point of a
/// polygon whose plane lies at distance h > 0 from the centre has |p| ≥ h; so after clipping
/// to the four planes every vertex has w ≥ h/√3 and the perspective divide is safe. Edge-on
/// polygons (h ≈ 0, zero solid angle) are dropped.
#[derive(Debug, Default)]
struct LocalScene {
    vertices: Vec<DVec3>,
    /// Per vertex k of each polygon: the unit normal of the plane through the centre and
    /// the edge v_k v_{k+1}, ±normalize(v_k × v_{k+1}), signed so the inside is positive.
    edges: Vec<DVec3>,
    polys: Vec<LocalPoly>,
}

#[derive(Debug, Clone, Copy)]
struct LocalPoly {
    start: u32,
    len: u32,
    /// The id its pixels get: the polygon's id when seen from the front, else [`BLOCKED`].
    id: u32,
    /// AND of the vertices' outcodes: a bit set here means all are outside that plane.
    outside: u16,
    /// OR of the vertices' outcodes: a bit clear here means none is outside that plane.
    any_outside: u16,
    /// Reciprocal distance along a ray d from the centre to the polygon's plane: g·d.
    recip: DVec3,
}

impl LocalScene {
    fn add(&mut self, frame: &Frame, set: &PolySet, poly: &PolyRef) {
        let start = self.vertices.len();
        let world = &set.vertices[poly.start as usize..(poly.start + poly.len) as usize];
        let (mut outside, mut any_outside) = (u16::MAX, 0u16);
        let mut above = false;
        let mut radius: f64 = 0.0;
        for &p in world {
            let q = frame.local(p);
            above |= q.z > 0.0;
            let code = outcode(q);
            outside &= code;
            any_outside |= code;
            radius = radius.max(q.length());
            self.vertices.push(q);
        }
        let n = frame.local_dir(poly.normal);
        // Plane n·p = k; the centre (origin) sees the front when it is in front: k < 0.
        let k = n.dot(self.vertices[start]);
        if !above || k.is_nan() || k.abs() <= 1e-12 * radius {
            // Below the hemi-cube's base, or edge-on (zero solid angle).
            self.vertices.truncate(start);
            return;
        }
        let front = k < 0.0;
        let sign = if front { -1.0 } else { 1.0 };
        let verts = &self.vertices[start..];
        for (i, &a) in verts.iter().enumerate() {
            let b = verts[(i + 1) % verts.len()];
            // Unit edge-plane normals; a degenerate edge (zero) constrains nothing.
            self.edges.push(sign * a.cross(b).normalize_or_zero());
        }
        self.polys.push(LocalPoly {
            start: start as u32,
            len: poly.len,
            id: if front { poly.id } else { BLOCKED },
            outside,
            any_outside,
            recip: n / k,
        });
    }

    /// True when the ray `d` (|d| ≤ √3) passes through the polygon or within
    /// [`EDGE_SLACK`] (relative) of its boundary.
    #[inline]
    fn covers(&self, poly: &LocalPoly, d: DVec3) -> bool {
        let edges = &self.edges[poly.start as usize..(poly.start + poly.len) as usize];
        edges.iter().all(|c| c.dot(d) >= -EDGE_SLACK)
    }
}

/// Per-thread scratch buffers for one tile.
#[derive(Default)]
struct Buffers {
    depth: Vec<u32>,
    ids: Vec<u32>,
    clip_a: Vec<DVec3>,
    clip_b: Vec<DVec3>,
    screen: Vec<(f64, f64)>,
    lines: Vec<Line>,
}

thread_local! {
    static BUFFERS: RefCell<Buffers> = RefCell::new(Buffers::default());
}

/// Rasterises every polygon of `scenes` into one tile and adds the ΔF of the pixels each
/// front-facing polygon wins to `sums[id]`.
fn render_tile(tile: &Tile, scenes: &[LocalScene], sums: &mut [f64]) {
    BUFFERS.with(|cell| {
        let mut guard = cell.borrow_mut();
        let bufs = &mut *guard;
        let pixels = tile.cols * tile.rows;
        bufs.depth.clear();
        bufs.depth.resize(pixels, 0);
        bufs.ids.clear();
        bufs.ids.resize(pixels, NONE);
        for scene in scenes {
            for poly in &scene.polys {
                if poly.outside & tile.mask == 0 {
                    raster_polygon(tile, scene, poly, bufs);
                }
            }
        }
        for (&id, &df) in bufs.ids.iter().zip(&tile.delta) {
            if let Some(s) = sums.get_mut(id as usize) {
                *s += df;
            }
        }
    });
}

/// Clips one polygon to the tile's frustum, projects it and fills the pixels whose centres
/// it covers (scanline, with the 3D test near edges), z-buffered.
fn raster_polygon(tile: &Tile, scene: &LocalScene, poly: &LocalPoly, bufs: &mut Buffers) {
    let verts = &scene.vertices[poly.start as usize..(poly.start + poly.len) as usize];
    let Buffers {
        depth,
        ids,
        clip_a,
        clip_b,
        screen,
        lines,
    } = bufs;
    clip_a.clear();
    clip_a.extend_from_slice(verts);
    for (m, bit) in tile.planes.iter().zip(tile.plane_bits) {
        // Only planes some vertex is strictly outside of can cut anything.
        if poly.any_outside & bit != 0 {
            clip_convex(clip_a, |p| m.dot(*p), clip_b);
            std::mem::swap(clip_a, clip_b);
        }
    }
    if clip_a.len() < 3 {
        return;
    }
    // Screen position in pixel units, relative to the tile's lower-left corner. Inside the
    // frustum every point has depth ≥ h/√3 > 0 (see [`LocalScene`]), so the divide is safe.
    screen.clear();
    let (mut ymin, mut ymax) = (f64::INFINITY, f64::NEG_INFINITY);
    for p in clip_a.iter() {
        let depth_w = p.dot(tile.w);
        if depth_w.is_nan() || depth_w <= 0.0 {
            debug_assert!(false, "clipped vertex at depth {depth_w}");
            return;
        }
        let x = (p.dot(tile.u) / depth_w - tile.u0) / tile.du;
        let y = (p.dot(tile.v) / depth_w - tile.v0) / tile.dv;
        ymin = ymin.min(y);
        ymax = ymax.max(y);
        screen.push((x, y));
    }
    // Edge lines a·x + b·y ≥ c (unit normals, inside positive), orientation from the area.
    let n = screen.len();
    let mut area2 = 0.0;
    for i in 0..n {
        let (p, q) = (screen[i], screen[(i + 1) % n]);
        area2 += p.0 * q.1 - q.0 * p.1;
    }
    if area2 == 0.0 {
        return;
    }
    let orient = area2.signum();
    lines.clear();
    for i in 0..n {
        let (p, q) = (screen[i], screen[(i + 1) % n]);
        let (ex, ey) = (q.0 - p.0, q.1 - p.1);
        let len = (ex * ex + ey * ey).sqrt();
        if len > 1e-12 {
            let (a, b) = (-ey * orient / len, ex * orient / len);
            lines.push(Line::new(a, b, a * p.0 + b * p.1));
        }
    }
    // Depth key 1/t = g·d along the pixel ray d = w + su·u + sv·v, linear in the pixel indices.
    let g = poly.recip;
    let key_du = g.dot(tile.u) * tile.du;
    let key_dv = g.dot(tile.v) * tile.dv;
    let key_00 = g.dot(tile.w)
        + g.dot(tile.u) * (tile.u0 + 0.5 * tile.du)
        + g.dot(tile.v) * (tile.v0 + 0.5 * tile.dv);
    let front = poly.id != BLOCKED;
    let rows = tile.rows as i64;
    let j_lo = floor_i64(ymin - 0.5).max(0);
    let j_hi = (ceil_i64(ymax - 0.5)).min(rows - 1);
    let cols = tile.cols as i64;
    for j in j_lo..=j_hi {
        let yc = j as f64 + 0.5;
        // Candidate span (edges pushed out by the margin) and sure span (pulled in).
        let (mut lo_c, mut hi_c) = (f64::NEG_INFINITY, f64::INFINITY);
        let (mut lo_s, mut hi_s) = (f64::NEG_INFINITY, f64::INFINITY);
        let mut empty = false;
        for line in lines.iter() {
            match line.kind {
                LineKind::Lower => {
                    lo_c = lo_c.max(line.loose + line.slope * yc);
                    lo_s = lo_s.max(line.tight + line.slope * yc);
                }
                LineKind::Upper => {
                    hi_c = hi_c.min(line.loose + line.slope * yc);
                    hi_s = hi_s.min(line.tight + line.slope * yc);
                }
                LineKind::Level => {
                    // b·yc ≥ c (± margin): the row is beside a horizontal edge.
                    let lhs = line.slope * yc;
                    if lhs < line.loose {
                        empty = true;
                        break;
                    }
                    if lhs < line.tight {
                        lo_s = f64::INFINITY;
                    }
                }
            }
        }
        if empty || lo_c > hi_c {
            continue;
        }
        // Pixel i's centre is i + 0.5.
        let i_lo = ceil_i64(lo_c - 0.5).max(0);
        let i_hi = floor_i64(hi_c - 0.5).min(cols - 1);
        if i_hi < i_lo {
            continue;
        }
        // Sure pixels: i_lo ≤ s_lo ≤ s_hi ≤ i_hi + 1.
        let s_lo = ceil_i64(lo_s - 0.5).clamp(i_lo, i_hi + 1);
        let s_hi = floor_i64(hi_s - 0.5)
            .saturating_add(1)
            .clamp(s_lo, i_hi + 1);
        let (i_lo, i_hi, s_lo, s_hi) = (i_lo as usize, i_hi as usize, s_lo as usize, s_hi as usize);
        let row = j as usize * tile.cols;
        let key_row = key_00 + key_dv * j as f64;
        let depth_row = &mut depth[row..row + tile.cols];
        let ids_row = &mut ids[row..row + tile.cols];
        let id = poly.id;
        for i in (i_lo..s_lo).chain(s_hi..=i_hi) {
            if scene.covers(poly, tile.ray(i, j as usize)) {
                let key = depth_key(key_row + key_du * i as f64, front);
                if key > depth_row[i] {
                    depth_row[i] = key;
                    ids_row[i] = id;
                }
            }
        }
        let mut fi = s_lo as f64;
        for (d, p) in depth_row[s_lo..s_hi]
            .iter_mut()
            .zip(&mut ids_row[s_lo..s_hi])
        {
            let key = depth_key(key_row + key_du * fi, front);
            fi += 1.0;
            let win = key > *d;
            *d = if win { key } else { *d };
            *p = if win { id } else { *p };
        }
    }
}

/// The z-buffer's key for reciprocal distance `recip` (> 0; larger is nearer): the bits of
/// the f32 value (monotonic for positive floats, below 2³¹) shifted left, with the low bit
/// set for front faces, so that on equal depth — a ray along the edge where a front and a
/// back face meet — the front face wins (the ray grazes the visible side of the edge).
#[inline]
fn depth_key(recip: f64, front: bool) -> u32 {
    ((recip as f32).to_bits() << 1) | front as u32
}

/// ⌊x⌋ as an integer, saturating (`as` saturates; NaN gives 0). Inline, unlike `f64::floor`
/// on baseline x86-64, which calls libm.
#[inline]
fn floor_i64(x: f64) -> i64 {
    let i = x as i64;
    if (i as f64) > x {
        i.saturating_sub(1)
    } else {
        i
    }
}

/// ⌈x⌉ as an integer, saturating.
#[inline]
fn ceil_i64(x: f64) -> i64 {
    let i = x as i64;
    if (i as f64) < x {
        i.saturating_add(1)
    } else {
        i
    }
}

#[derive(Debug, Clone, Copy)]
enum LineKind {
    /// x ≥ bound(y)
    Lower,
    /// x ≤ bound(y)
    Upper,
    /// a horizontal edge: slope·y ≥ bound
    Level,
}

/// A projected edge a·x + b·y ≥ c (unit normal) as bounds on x per row: bound(y) =
/// loose|tight + slope·y, where `loose` moves the edge out by [`EDGE_MARGIN`] and `tight`
/// moves it in.
#[derive(Debug, Clone, Copy)]
struct Line {
    kind: LineKind,
    slope: f64,
    loose: f64,
    tight: f64,
}

impl Line {
    fn new(a: f64, b: f64, c: f64) -> Self {
        if a.abs() > 1e-12 {
            Self {
                kind: if a > 0.0 {
                    LineKind::Lower
                } else {
                    LineKind::Upper
                },
                slope: -b / a,
                loose: (c - EDGE_MARGIN) / a,
                tight: (c + EDGE_MARGIN) / a,
            }
        } else {
            Self {
                kind: LineKind::Level,
                slope: b,
                loose: c - EDGE_MARGIN,
                tight: c + EDGE_MARGIN,
            }
        }
    }
}

/// Renders one hemi-cube at `frame` over the polygons of `set` (except those of
/// `skip_surface`) and returns the form factors per id (`ids` entries).
fn render(
    layout: &Layout,
    frame: &Frame,
    set: &PolySet,
    skip_surface: u32,
    ids: usize,
    parallel: bool,
) -> Vec<f64> {
    if parallel {
        let chunk = set
            .polys
            .len()
            .div_ceil(rayon::current_num_threads().max(1) * 4)
            .max(64);
        let scenes: Vec<LocalScene> = set
            .polys
            .par_chunks(chunk)
            .map(|polys| prepare(frame, set, polys, skip_surface))
            .collect();
        layout
            .tiles
            .par_iter()
            .map(|tile| {
                let mut sums = vec![0.0; ids];
                render_tile(tile, &scenes, &mut sums);
                sums
            })
            .reduce_with(|mut a, b| {
                a.iter_mut().zip(&b).for_each(|(x, y)| *x += y);
                a
            })
            .unwrap_or_else(|| vec![0.0; ids])
    } else {
        let scenes = [prepare(frame, set, &set.polys, skip_surface)];
        let mut sums = vec![0.0; ids];
        for tile in &layout.tiles {
            render_tile(tile, &scenes, &mut sums);
        }
        sums
    }
}

fn prepare(frame: &Frame, set: &PolySet, polys: &[PolyRef], skip_surface: u32) -> LocalScene {
    let mut scene = LocalScene::default();
    for poly in polys {
        if poly.surface != skip_surface || skip_surface == u32::MAX {
            scene.add(frame, set, poly);
        }
    }
    scene
}

/// splitmix64: a well-mixed 64-bit hash, for per-hemi-cube jitter angles.
fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The rotation about the normal of hemi-cube number `index` of kind `salt`.
fn jitter_angle(params: &HemicubeParams, salt: u64, index: u64) -> f64 {
    if !params.jitter {
        return 0.0;
    }
    let h = mix(params.seed ^ mix(index ^ mix(salt)));
    2.0 * PI * (h >> 11) as f64 / (1u64 << 53) as f64
}

/// The hemi-cube form-factor engine over one mesh.
pub struct Hemicube<'a> {
    mesh: &'a Mesh,
    params: HemicubeParams,
    layout: Layout,
    patches: PolySet,
    elements: PolySet,
    patch_area: Vec<f64>,
    /// Distance (m) hemi-cubes are lifted off their surface: 10⁻⁷ of the scene's diagonal.
    offset: f64,
    /// Near patches of each element (sorted; from the coupling's link oracle), drawn as their
    /// elements; empty when there is no near field.
    near: &'a [Vec<u32>],
    /// Near-field links per element (source element, F_{e→e'}), rendered on first use.
    links: Vec<std::sync::OnceLock<Vec<(u32, f64)>>>,
}

impl<'a> Hemicube<'a> {
    /// The engine over `mesh`; `near[e]` lists the patches element `e` links to element by
    /// element (sorted), or `near` is empty for no near field.
    pub fn new(mesh: &'a Mesh, params: HemicubeParams, near: &'a [Vec<u32>]) -> Self {
        let mut patches = PolySet::default();
        for (i, p) in mesh.patches.iter().enumerate() {
            patches.push(
                p.polygon.vertices(),
                p.polygon.normal(),
                p.surface,
                i as u32,
            );
        }
        let mut elements = PolySet::default();
        let mut corners = Vec::with_capacity(4);
        for (i, e) in mesh.elements.iter().enumerate() {
            corners.clear();
            corners.extend(e.corners.iter().map(|&c| mesh.vertices[c as usize]));
            elements.push(&corners, e.normal, e.surface, i as u32);
        }
        let (lo, hi) = mesh.vertices.iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), v| (lo.min(*v), hi.max(*v)),
        );
        let diagonal = if mesh.vertices.is_empty() {
            1.0
        } else {
            (hi - lo).length()
        };
        Self {
            mesh,
            params,
            layout: Layout::new(params.resolution),
            patches,
            elements,
            patch_area: mesh.patches.iter().map(|p| mesh.patch_area(p)).collect(),
            offset: 1e-7 * diagonal.max(f64::MIN_POSITIVE),
            near,
            links: (0..mesh.elements.len())
                .map(|_| std::sync::OnceLock::new())
                .collect(),
        }
    }

    /// One hemi-cube at element `element` over every patch, except that its near patches are
    /// drawn as their elements: the element-to-element links F_{e→e'} of the near field.
    fn near_links(&self, element: usize) -> &[(u32, f64)] {
        self.links[element].get_or_init(|| {
            let Some(near) = self.near.get(element) else {
                return Vec::new();
            };
            if near.is_empty() {
                return Vec::new();
            }
            let m = self.mesh.patches.len() as u32;
            let mut set = PolySet::default();
            let mut sources = Vec::new();
            let mut corners = Vec::with_capacity(4);
            for (i, p) in self.mesh.patches.iter().enumerate() {
                if near.binary_search(&(i as u32)).is_ok() {
                    for s in p.elements.clone() {
                        let el = &self.mesh.elements[s as usize];
                        corners.clear();
                        corners.extend(el.corners.iter().map(|&c| self.mesh.vertices[c as usize]));
                        set.push(&corners, el.normal, el.surface, m + sources.len() as u32);
                        sources.push(s);
                    }
                } else {
                    set.push(
                        p.polygon.vertices(),
                        p.polygon.normal(),
                        p.surface,
                        i as u32,
                    );
                }
            }
            let e = &self.mesh.elements[element];
            let frame = Frame::new(
                e.centre + e.normal * self.offset,
                e.normal,
                jitter_angle(&self.params, 0, element as u64),
            );
            let sums = render(
                &self.layout,
                &frame,
                &set,
                e.surface,
                m as usize + sources.len(),
                false,
            );
            sources
                .iter()
                .zip(&sums[m as usize..])
                .filter(|(_, f)| **f > 0.0)
                .map(|(s, f)| (*s, *f))
                .collect()
        })
    }

    /// The parameters in use.
    pub fn params(&self) -> &HemicubeParams {
        &self.params
    }

    /// Row `e` in full precision: F_{e→p} for every patch p from one hemi-cube at the
    /// centre of element `e`. Σ_p F_{e→p} = 1 (to rounding) in a closed scene.
    pub fn row_f64(&self, element: usize) -> Vec<f64> {
        let e = &self.mesh.elements[element];
        let frame = Frame::new(
            e.centre + e.normal * self.offset,
            e.normal,
            jitter_angle(&self.params, 0, element as u64),
        );
        render(
            &self.layout,
            &frame,
            &self.patches,
            e.surface,
            self.mesh.patches.len(),
            false,
        )
    }

    /// F_{p→e} for every element e from one hemi-cube at the centre of patch `p`.
    pub fn shot_f64(&self, patch: usize) -> Vec<f64> {
        let p = &self.mesh.patches[patch];
        let normal = p.polygon.normal();
        let frame = Frame::new(
            p.polygon.centroid() + normal * self.offset,
            normal,
            jitter_angle(&self.params, 1, patch as u64),
        );
        render(
            &self.layout,
            &frame,
            &self.elements,
            p.surface,
            self.mesh.elements.len(),
            true,
        )
    }
}

impl Engine for Hemicube<'_> {
    fn method(&self) -> FormFactorMethod {
        FormFactorMethod::Hemicube
    }

    /// Computes the whole row of `element` and returns one entry: correct but costs a full
    /// hemi-cube per call (no cache); use `row` or `column` for bulk work.
    fn pair(&self, element: usize, patch: usize) -> f64 {
        self.row_f64(element)[patch]
    }

    /// F_{e→p} by reciprocity from one hemi-cube at patch `p`: F_{e→p} = F_{p→e} A_p / A_e.
    fn column(&self, patch: usize, out: &mut [f32]) {
        let shot = self.shot_f64(patch);
        let ap = self.patch_area[patch];
        for ((f, fp), e) in out.iter_mut().zip(&shot).zip(&self.mesh.elements) {
            *f = if *fp > 0.0 {
                (fp * ap / e.area) as f32
            } else {
                0.0
            };
        }
    }

    fn row(&self, element: usize, out: &mut [f32]) {
        for (f, v) in out.iter_mut().zip(self.row_f64(element)) {
            *f = v as f32;
        }
    }

    /// From the element's near-field hemi-cube (rendered once per element, then cached);
    /// 0 for a source element outside its near field.
    fn element_pair(&self, element: usize, source: usize) -> f64 {
        self.near_links(element)
            .iter()
            .find(|(s, _)| *s as usize == source)
            .map_or(0.0, |(_, f)| *f)
    }
}

/// The hemi-cube as a kernel on geometry: one hemi-cube at the receiver's centre (the
/// method's own point approximation of a finite receiver, F_{R→S} ≈ F_{d(centre)→S}),
/// lifted off it by 10⁻⁷ of the pair's size, on which the source and every triangle of the
/// visibility query's scene inside the box spanned by the centre and the source are
/// z-buffered; the source's share of the ΔF is the form factor. Triangles in the source's or
/// the receiver's plane cannot block and are left out (they would tie with the source).
pub struct HemicubeKernel {
    params: HemicubeParams,
    layout: Layout,
}

impl HemicubeKernel {
    /// A kernel with the given resolution and jitter.
    pub fn new(params: HemicubeParams) -> Self {
        Self {
            layout: Layout::new(params.resolution),
            params,
        }
    }
}

impl Default for HemicubeKernel {
    fn default() -> Self {
        Self::new(HemicubeParams::default())
    }
}

impl Kernel for HemicubeKernel {
    fn method(&self) -> FormFactorMethod {
        FormFactorMethod::Hemicube
    }

    fn source(&self, vertices: &[DVec3]) -> SourcePolygon {
        SourcePolygon::new(vertices, 1, 1, Division::Lattice)
    }

    fn form_factor(&self, r: &Receiver, s: &SourcePolygon, visibility: &Visibility) -> f64 {
        let size = s.radius.max(r.centre.distance(s.centre));
        let x = r.centre + r.normal * (1e-7 * size.max(f64::MIN_POSITIVE));
        if (x - s.centre).dot(s.normal) <= 0.0 {
            return 0.0; // behind the one-sided source
        }
        let mut set = PolySet::default();
        set.push(&s.vertices, s.normal, u32::MAX, 0);
        let (mut lo, mut hi) = (x, x);
        for v in &s.vertices {
            lo = lo.min(*v);
            hi = hi.max(*v);
        }
        let mut candidates = Vec::new();
        visibility
            .bvh()
            .triangles_in_box(lo.as_vec3(), hi.as_vec3(), &mut candidates);
        let in_plane = |t: &[DVec3; 3], o: DVec3, n: DVec3| {
            t.iter().all(|p| (*p - o).dot(n).abs() <= 1e-9 * size)
        };
        for (_, tri) in &candidates {
            let t = tri.map(|p| p.as_dvec3());
            if in_plane(&t, s.centre, s.normal) || in_plane(&t, r.centre, r.normal) {
                continue;
            }
            let (n, area) = crate::geometry::newell(&t);
            if area > 0.0 {
                set.push(&t, n, u32::MAX, BLOCKED);
            }
        }
        let frame = Frame::new(x, r.normal, jitter_angle(&self.params, 3, 0));
        render(&self.layout, &frame, &set, u32::MAX, 1, false)[0]
    }
}

/// F from `problem.from` to `problem.to` with occluders, by hemi-cubes.
///
/// A differential-area source gets one hemi-cube. A polygon source is integrated by
/// quadrature over its area: Gauss points ([`PAIR_SOURCE_ORDER`]² on a triangle or quad, a
/// polar rule of about [`PAIR_SOURCE_ORDER`]² per 90° on polygons with more vertices), one
/// hemi-cube at each (in parallel), F = Σ_k w_k F_{dx_k→to} (weights summing to 1). Occluders block from
/// both sides; the target is one-sided. Degenerate input (zero-area polygons, a zero
/// normal) gives 0. The estimate is deterministic (no standard error).
pub fn hemicube_pair(problem: &PairProblem, params: &HemicubeParams) -> Estimate {
    // (unit normal, area) of a loop, or None when it has no area.
    let plane = |v: &[DVec3]| {
        let (n, area) = if v.len() >= 3 {
            crate::geometry::newell(v)
        } else {
            (DVec3::ZERO, 0.0)
        };
        (area > 0.0 && n.is_finite()).then_some((n, area))
    };
    let Some((to_normal, _)) = plane(&problem.to) else {
        return Estimate::exact(0.0);
    };
    let layout = Layout::new(params.resolution);
    let mut set = PolySet::default();
    set.push(&problem.to, to_normal, u32::MAX, 0);
    for o in &problem.occluders {
        if let Some((n, _)) = plane(o) {
            set.push(o, n, u32::MAX, BLOCKED);
        }
    }
    let (points, normal) = match &problem.from {
        Source::Point { point, normal } => {
            let n = normal.normalize_or_zero();
            (vec![(*point, 1.0)], n)
        }
        Source::Polygon(vertices) => {
            let Some((n, _)) = plane(vertices) else {
                return Estimate::exact(0.0);
            };
            (source_points(vertices, n, PAIR_SOURCE_ORDER), n)
        }
    };
    if normal == DVec3::ZERO || !normal.is_finite() {
        return Estimate::exact(0.0);
    }
    let value = points
        .par_iter()
        .enumerate()
        .map(|(k, &(x, w))| {
            let frame = Frame::new(x, normal, jitter_angle(params, 2, k as u64));
            w * render(&layout, &frame, &set, u32::MAX, 1, false)[0]
        })
        .sum();
    Estimate::exact(value)
}

/// Quadrature points on a convex polygon, weights summing to 1: Gauss–Legendre through the
/// bilinear (quad) or collapsed (triangle) map for 3–4 vertices; for more vertices a polar
/// rule about the centroid, ∫∫ f ρ dρ dφ: the fan is cut at vertices into sectors of at most
/// 90° inside which the boundary turns by less than 0.1 rad at every vertex (so R(φ), the
/// distance to the boundary, is smooth or nearly so), each integrated with `order` Gauss
/// points in radius × `order`·(angle/90°) (at least 2) in angle.
fn source_points(vertices: &[DVec3], normal: DVec3, order: usize) -> Vec<(DVec3, f64)> {
    let centroid = crate::geometry::Polygon::new_unchecked(vertices.to_vec()).centroid();
    let mut out = Vec::new();
    if vertices.len() <= 4 {
        element_points(vertices, centroid, order, &mut out);
        return out;
    }
    let (e1, e2) = normal.any_orthonormal_pair();
    // Counter-clockwise about the normal, as the polygon winds.
    let e2 = if e1.cross(e2).dot(normal) < 0.0 {
        -e2
    } else {
        e2
    };
    let flat: Vec<(f64, f64)> = vertices
        .iter()
        .map(|v| ((*v - centroid).dot(e1), (*v - centroid).dot(e2)))
        .collect();
    let m = flat.len();
    let angle_of = |k: usize| flat[k % m].1.atan2(flat[k % m].0);
    // Unwrapped angles of the vertices, increasing (counter-clockwise about the normal).
    let mut angles = Vec::with_capacity(m + 1);
    for k in 0..=m {
        let mut a = angle_of(k);
        if let Some(&prev) = angles.last() {
            while a < prev {
                a += 2.0 * PI;
            }
        }
        angles.push(a);
    }
    // The polygon turns by this much at vertex k (mod m): a kink in R(φ) there.
    let turn = |k: usize| {
        let (p, q, r) = (flat[(k + m - 1) % m], flat[k % m], flat[(k + 1) % m]);
        let (a, b) = ((q.0 - p.0, q.1 - p.1), (r.0 - q.0, r.1 - q.1));
        (a.0 * b.1 - a.1 * b.0).atan2(a.0 * b.0 + a.1 * b.1).abs()
    };
    let rule = gauss_legendre(order.max(1));
    let mut k0 = 0;
    while k0 < m {
        // A sector spans fan triangles while it stays within 90° and the boundary turns by
        // less than MAX_KINK at the vertices inside it (Gauss in φ needs R(φ) smooth).
        const MAX_KINK: f64 = 0.1;
        let mut k1 = k0 + 1;
        while k1 < m && angles[k1 + 1] - angles[k0] <= 0.5 * PI + 1e-12 && turn(k1) < MAX_KINK {
            k1 += 1;
        }
        let (a0, a1) = (angles[k0], angles[k1]);
        // Angular points in proportion to the sector's angle (`order` for 90°, at least 2).
        let angular = gauss_legendre(
            ((order as f64 * (a1 - a0) / (0.5 * PI)).ceil() as usize).clamp(2, order.max(2)),
        );
        for &(s, ws) in &angular {
            let phi = a0 + s * (a1 - a0);
            let dir = (phi.cos(), phi.sin());
            // R(φ): distance from the centroid to the edge crossed at this angle.
            let k = (k0..k1).find(|&k| phi <= angles[k + 1]).unwrap_or(k1 - 1);
            let (p, q) = (flat[k], flat[(k + 1) % m]);
            let (ex, ey) = (q.0 - p.0, q.1 - p.1);
            let denom = dir.0 * ey - dir.1 * ex;
            let r = if denom.abs() > 0.0 {
                (p.0 * ey - p.1 * ex) / denom
            } else {
                0.0
            };
            for &(t, wt) in &rule {
                let rho = t * r;
                let x = centroid + e1 * (rho * dir.0) + e2 * (rho * dir.1);
                out.push((x, ws * (a1 - a0) * wt * t * r * r));
            }
        }
        k0 = k1;
    }
    let total: f64 = out.iter().map(|p| p.1).sum();
    out.iter_mut().for_each(|p| p.1 /= total);
    out
}

#[cfg(test)]
mod tests {
    use super::super::analytic_point::point_to_polygon;
    use super::*;
    use crate::geometry::Polygon;
    use crate::mesh::MeshOptions;
    use crate::scene::{Material, MaterialId, Origin, Scene, Surface};
    use serde_json::Value;

    /// An axis-aligned rectangle in the plane z = `z`, facing −z (down) or +z.
    fn rect_z(x0: f64, x1: f64, y0: f64, y1: f64, z: f64, facing_down: bool) -> Vec<DVec3> {
        let mut v = vec![
            DVec3::new(x0, y0, z),
            DVec3::new(x1, y0, z),
            DVec3::new(x1, y1, z),
            DVec3::new(x0, y1, z),
        ];
        if facing_down {
            v.reverse();
        }
        v
    }

    /// F from a differential area at the origin facing +z.
    fn from_origin(to: Vec<DVec3>, occluders: Vec<Vec<DVec3>>) -> PairProblem {
        PairProblem {
            from: Source::Point {
                point: DVec3::ZERO,
                normal: DVec3::Z,
            },
            to,
            occluders,
        }
    }

    fn at(resolution: usize) -> HemicubeParams {
        HemicubeParams {
            resolution,
            ..Default::default()
        }
    }

    /// The six faces of the box [lo, hi], facing inwards (or outwards).
    fn box_faces(lo: DVec3, hi: DVec3, inwards: bool) -> Vec<Vec<DVec3>> {
        let c = |x: usize, y: usize, z: usize| {
            DVec3::new([lo.x, hi.x][x], [lo.y, hi.y][y], [lo.z, hi.z][z])
        };
        // Counter-clockwise seen from inside.
        let mut faces = vec![
            vec![c(0, 0, 0), c(1, 0, 0), c(1, 1, 0), c(0, 1, 0)], // z = lo, facing +z
            vec![c(0, 0, 1), c(0, 1, 1), c(1, 1, 1), c(1, 0, 1)], // z = hi
            vec![c(0, 0, 0), c(0, 1, 0), c(0, 1, 1), c(0, 0, 1)], // x = lo
            vec![c(1, 0, 0), c(1, 0, 1), c(1, 1, 1), c(1, 1, 0)], // x = hi
            vec![c(0, 0, 0), c(0, 0, 1), c(1, 0, 1), c(1, 0, 0)], // y = lo
            vec![c(0, 1, 0), c(1, 1, 0), c(1, 1, 1), c(0, 1, 1)], // y = hi
        ];
        if !inwards {
            faces.iter_mut().for_each(|f| f.reverse());
        }
        faces
    }

    fn scene_of(polys: Vec<Vec<DVec3>>) -> Scene {
        Scene {
            name: "test".into(),
            materials: vec![Material::new("grey", [0.5; 3], [0.0; 3])],
            surfaces: polys
                .into_iter()
                .enumerate()
                .map(|(i, v)| Surface {
                    object: format!("s{i}"),
                    group: String::new(),
                    material: MaterialId(0),
                    polygon: Polygon::new(v).unwrap(),
                    origin: Origin::default(),
                })
                .collect(),
            lights: Vec::new(),
            camera: None,
        }
    }

    fn mesh_of(polys: Vec<Vec<DVec3>>, size: f64, sub: u32) -> Mesh {
        let options = MeshOptions {
            max_element_size: Some(size),
            elements: 0,
            patch_subdivision: sub,
        };
        Mesh::build(&scene_of(polys), &options).unwrap()
    }

    #[test]
    fn delta_form_factors_sum_to_one() {
        for res in [2, 3, 16, 64, 128, 255, 256] {
            let (top, side) = delta_form_factors(res);
            assert_eq!(top.len(), res * res);
            assert_eq!(side.len(), res.div_ceil(2) * res);
            let sum = top.iter().sum::<f64>() + 4.0 * side.iter().sum::<f64>();
            // Normalised: only summation rounding remains (~50k terms × 1e-16).
            assert!((sum - 1.0).abs() < 1e-12, "res {res}: {sum}");
        }
    }

    #[test]
    fn raw_delta_form_factors_converge_to_one_at_second_order() {
        // The midpoint rule's defect shrinks like 1/res²: this fails if either formula (or
        // the side faces' half height) is wrong, which the normalisation would otherwise hide.
        let defect = |res| {
            let (t, s) = raw_delta_form_factors(res);
            1.0 - (t.iter().sum::<f64>() + 4.0 * s.iter().sum::<f64>())
        };
        let (d32, d64) = (defect(32), defect(64));
        assert!(d32.abs() < 1e-3, "{d32}");
        assert!((d32 / d64 - 4.0).abs() < 0.2, "defects {d32} {d64}");
    }

    #[test]
    fn tile_outcode_masks_agree_with_frusta() {
        let layout = Layout::new(8);
        let mut h = 1u64;
        for _ in 0..20000 {
            let mut r = || {
                h = mix(h);
                (h >> 11) as f64 / (1u64 << 53) as f64 * 4.0 - 2.0
            };
            let p = DVec3::new(r(), r(), r());
            for t in &layout.tiles {
                let by_mask = outcode(p) & t.mask != 0;
                let by_planes = t.planes.iter().any(|m| m.dot(p) < 0.0);
                assert_eq!(by_mask, by_planes, "{p}");
            }
        }
    }

    #[test]
    fn small_parallel_square_over_differential_area_matches_analytic() {
        // Squares of side s = 0.2 at height 1 (inside the top face), off-centre so their
        // edges fall at arbitrary phases of the pixel grid. Pixel-centre sampling moves each
        // edge by at most half a pixel per pixel column (or row) it crosses, and ΔF ≤ ΔA/π,
        // so |error| ≤ ½ · perimeter · du / π = 0.4 du/π (du = 2/res: 9.9e-4 at res 256);
        // the O(du²) midpoint error of the ΔF is far below that.
        let s = 0.2;
        for (cx, cy) in [(0.3, -0.2), (0.1, 0.05), (-0.45, 0.33), (0.0, 0.0)] {
            let to = rect_z(
                cx - s / 2.0,
                cx + s / 2.0,
                cy - s / 2.0,
                cy + s / 2.0,
                1.0,
                true,
            );
            let exact = point_to_polygon(DVec3::ZERO, DVec3::Z, &to, -DVec3::Z);
            for res in [64, 128, 256] {
                let f = hemicube_pair(&from_origin(to.clone(), vec![]), &at(res)).value;
                let tol = 0.5 * 4.0 * s * (2.0 / res as f64) / PI;
                assert!(
                    (f - exact).abs() <= tol,
                    "({cx},{cy}) res {res}: {f} vs {exact}"
                );
            }
        }
    }

    #[test]
    fn large_polygon_spanning_five_faces_matches_analytic() {
        // A tilted quad seen across the top face and all four side faces: the clipping to
        // each face's frustum must add up. Bound as above with the perimeter projected onto
        // the cube (< 8 face units here): 4 du/π = 4e-3 at res 256; observed ~1e-4.
        let to = vec![
            DVec3::new(-3.0, -2.5, 0.8),
            DVec3::new(-2.0, 3.0, 1.4),
            DVec3::new(2.5, 2.0, 1.1),
            DVec3::new(3.0, -3.0, 0.4),
        ];
        let (normal, _) = crate::geometry::newell(&to);
        assert!(normal.z < 0.0);
        let exact = point_to_polygon(DVec3::ZERO, DVec3::Z, &to, normal);
        for res in [32, 128, 256] {
            let f = hemicube_pair(&from_origin(to.clone(), vec![]), &at(res)).value;
            let tol = 4.0 * (2.0 / res as f64) / PI;
            assert!((f - exact).abs() < tol, "res {res}: {f} vs {exact}");
        }
    }

    #[test]
    fn reference_cases_within_tolerance_at_default_resolution() {
        // Deterministic: the same pixels every run. Errors are edge aliasing (|err| ≲
        // ½ · projected perimeter · du/π per source point, ~1e-2 in the worst aligned case,
        // and averaged down over the 64 source points of a polygon source) plus the source
        // quadrature (8×8 Gauss, < 4e-5 on these cases, worst on C-14's shared edge). Measured
        // at res 128: max 4.7e-4 (plain), 4.6e-4 (jittered); tolerance 1e-3 keeps a factor 2.
        let reference: Value =
            serde_json::from_str(include_str!("../../tests/reference/formfactors.json")).unwrap();
        let points = |v: &Value| -> Vec<DVec3> {
            v.as_array()
                .unwrap()
                .iter()
                .map(|p| {
                    let c: Vec<f64> = p
                        .as_array()
                        .unwrap()
                        .iter()
                        .map(|x| x.as_f64().unwrap())
                        .collect();
                    DVec3::new(c[0], c[1], c[2])
                })
                .collect()
        };
        let cases = reference["cases"].as_array().unwrap();
        assert_eq!(cases.len(), 20);
        let mut worst: f64 = 0.0;
        for case in cases {
            let from = match case.get("dA1") {
                Some(d) => {
                    let pn = points(&Value::Array(vec![d["point"].clone(), d["normal"].clone()]));
                    Source::Point {
                        point: pn[0],
                        normal: pn[1],
                    }
                }
                None => Source::Polygon(points(&case["A1"])),
            };
            let problem = PairProblem {
                from,
                to: points(&case["A2"]),
                occluders: vec![],
            };
            let exact = case["F12"].as_f64().unwrap();
            for params in [
                HemicubeParams::default(),
                HemicubeParams {
                    jitter: true,
                    seed: 1,
                    ..Default::default()
                },
            ] {
                let f = hemicube_pair(&problem, &params).value;
                worst = worst.max((f - exact).abs());
                assert!(
                    (f - exact).abs() < 1e-3,
                    "{} {}: {f} vs {exact} ({params:?})",
                    case["case"],
                    case["params"]
                );
            }
        }
        assert!(worst > 0.0);
    }

    #[test]
    fn occluder_covering_the_view_gives_zero() {
        let to = rect_z(-1.0, 1.0, -1.0, 1.0, 2.0, true);
        let big = rect_z(-5.0, 5.0, -5.0, 5.0, 1.0, false);
        let open = hemicube_pair(&from_origin(to.clone(), vec![]), &Default::default()).value;
        assert!(open > 0.1);
        // Either side of an occluder blocks.
        for occluder in [big.clone(), big.iter().rev().copied().collect()] {
            let f = hemicube_pair(
                &from_origin(to.clone(), vec![occluder]),
                &Default::default(),
            );
            assert_eq!(f.value, 0.0);
        }
        // Two parallel unit squares with a blocker between them.
        let problem = PairProblem {
            from: Source::Polygon(rect_z(-1.0, 1.0, -1.0, 1.0, 0.0, false)),
            to,
            occluders: vec![big],
        };
        assert_eq!(hemicube_pair(&problem, &Default::default()).value, 0.0);
    }

    #[test]
    fn occluder_behind_the_target_changes_nothing_and_half_occluder_halves() {
        let to = rect_z(-1.0, 1.0, -1.0, 1.0, 2.0, true);
        let open = hemicube_pair(&from_origin(to.clone(), vec![]), &Default::default()).value;
        let behind = rect_z(-5.0, 5.0, -5.0, 5.0, 3.0, true);
        let f = hemicube_pair(&from_origin(to.clone(), vec![behind]), &Default::default()).value;
        assert_eq!(f, open);
        // An occluder over x < 0 hides exactly the half of the symmetric target's pixels there.
        let half = rect_z(-5.0, 0.0, -5.0, 5.0, 1.0, true);
        let f = hemicube_pair(&from_origin(to, vec![half]), &Default::default()).value;
        assert!((f - 0.5 * open).abs() < 1e-12, "{f} vs {}", 0.5 * open);
    }

    #[test]
    fn degenerate_input_gives_zero_without_panicking() {
        let to = rect_z(-1.0, 1.0, -1.0, 1.0, 2.0, true);
        let cases = [
            from_origin(vec![], vec![]),
            from_origin(vec![DVec3::ZERO, DVec3::X], vec![]),
            from_origin(vec![DVec3::X, DVec3::X * 2.0, DVec3::X * 3.0], vec![]),
            PairProblem {
                from: Source::Point {
                    point: DVec3::ZERO,
                    normal: DVec3::ZERO,
                },
                to: to.clone(),
                occluders: vec![],
            },
            PairProblem {
                from: Source::Polygon(vec![DVec3::ZERO, DVec3::Y]),
                to: to.clone(),
                occluders: vec![],
            },
        ];
        for problem in &cases {
            assert_eq!(hemicube_pair(problem, &Default::default()).value, 0.0);
        }
        // Degenerate occluders are ignored.
        let open = hemicube_pair(&from_origin(to.clone(), vec![]), &Default::default()).value;
        let f = hemicube_pair(
            &from_origin(to, vec![vec![], vec![DVec3::Z]]),
            &Default::default(),
        );
        assert_eq!(f.value, open);
    }

    #[test]
    fn polar_source_rule_has_the_polygon_centroid() {
        // Weights sum to 1 (normalised) and the first moment is the centroid, for
        // many-sided polygons wound either way about their normal. Not exact: a sector's
        // angular integrand R(φ)³ is smooth but not polynomial (≤ 1e-6 of the size here), and
        // on the 256-gon sectors span small kinks (measured 7e-6); tolerance 2e-5.
        for sides in [5, 7, 16, 36, 37, 64, 256] {
            for flip in [false, true] {
                let mut v: Vec<DVec3> = (0..sides)
                    .map(|k| {
                        let a = 2.0 * PI * k as f64 / sides as f64 + 0.3;
                        DVec3::new(0.2 + 1.5 * a.cos(), -0.4 + a.sin(), 0.7)
                    })
                    .collect();
                if flip {
                    v.reverse();
                }
                let poly = Polygon::new(v.clone()).unwrap();
                let points = source_points(&v, poly.normal(), PAIR_SOURCE_ORDER);
                let total: f64 = points.iter().map(|p| p.1).sum();
                let mean: DVec3 = points.iter().map(|p| p.0 * p.1).sum();
                assert!((total - 1.0).abs() < 1e-12);
                println!(
                    "{sides}: {:e} {}",
                    (mean - poly.centroid()).length(),
                    points.len()
                );
                assert!(
                    (mean - poly.centroid()).length() < 2e-5,
                    "{sides}: {mean} vs {}",
                    poly.centroid()
                );
                assert!(points.iter().all(|p| poly.distance_to(p.0) < 1e-12));
            }
        }
    }

    #[test]
    fn regression_rows_beside_a_horizontal_edge_are_tested_not_filled() {
        // A projected edge parallel to the pixel rows, passing within the 1e-3 pixel margin of
        // a row of pixel centres, must leave that row to the exact test. (The span bound was
        // +∞ there and ⌈+∞⌉ + 1 wrapped around, so the whole row was filled as "sure".)
        let du = 2.0 / 64.0;
        let yc = -1.0 + 40.5 * du; // a row of pixel centres on the top face
        let f = |y_top: f64| {
            let to = rect_z(-0.5, 0.5, -0.5, y_top, 1.0, true);
            hemicube_pair(&from_origin(to, vec![]), &at(64)).value
        };
        let (beside, clear, across) = (f(yc - 5e-4 * du), f(yc - 0.3 * du), f(yc + 5e-4 * du));
        assert_eq!(beside, clear);
        assert!(across > clear);
        assert_eq!(
            (floor_i64(f64::INFINITY), ceil_i64(f64::NEG_INFINITY)),
            (i64::MAX, i64::MIN)
        );
        assert_eq!(
            (
                floor_i64(-1.5),
                ceil_i64(-1.5),
                floor_i64(2.0),
                ceil_i64(2.0)
            ),
            (-2, -1, 2, 2)
        );
    }

    #[test]
    fn back_of_target_contributes_nothing() {
        let to = rect_z(-1.0, 1.0, -1.0, 1.0, 2.0, false);
        assert_eq!(
            hemicube_pair(&from_origin(to, vec![]), &Default::default()).value,
            0.0
        );
    }

    #[test]
    fn jitter_turns_aliasing_into_noise_without_moving_the_mean() {
        // A small square seen at a coarse resolution (16): the plain hemi-cube's pixel grid
        // has a fixed phase against the square's edges, a systematic error. Turning each
        // hemi-cube by a random angle spreads that error into noise whose mean over 400
        // seeds must agree with the exact value within 4 standard errors (seeds are fixed,
        // so the test is deterministic; a jitter restricted to multiples of 90° fails it, as
        // does one that changes nothing). Its bias (the jittered mean is a ring quadrature
        // in the pixel centres' elevations, O(du²)) is below 1e-5 here.
        let to = rect_z(-0.6, -0.3, 0.18, 0.48, 1.0, true);
        let exact = point_to_polygon(DVec3::ZERO, DVec3::Z, &to, -DVec3::Z);
        let problem = from_origin(to, vec![]);
        for res in [16, 32] {
            let plain = hemicube_pair(&problem, &at(res)).value;
            let n = 400;
            let values: Vec<f64> = (0..n)
                .map(|seed| {
                    let params = HemicubeParams {
                        resolution: res,
                        jitter: true,
                        seed,
                    };
                    hemicube_pair(&problem, &params).value
                })
                .collect();
            let mean = values.iter().sum::<f64>() / n as f64;
            let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
            let se = (var / n as f64).sqrt();
            assert!(se > 1e-6, "res {res}: jitter left the value unchanged");
            assert!(
                (mean - exact).abs() < 4.0 * se,
                "res {res}: mean {mean} vs {exact} ± {se}"
            );
            if res == 16 {
                // The plain estimate's aliasing error is far outside the jittered mean's error.
                assert!(
                    (plain - exact).abs() > 10.0 * se,
                    "{plain} vs {exact} ± {se}"
                );
            }
        }
    }

    #[test]
    fn rows_of_a_closed_box_sum_to_one() {
        // Every hemi-cube pixel sees some patch of a closed enclosure, so Σ_p F_{e→p} = ΣΔF = 1
        // up to the summation's rounding (~1e-15 per pixel over 50k pixels); a single missed or
        // doubled pixel at a shared edge would show as ~1e-5. The floating box adds
        // occlusion and back faces (its faces seen from the outer walls' side are fronts,
        // nothing sees its backs) without breaking closure.
        let mut faces = box_faces(DVec3::ZERO, DVec3::new(1.0, 1.3, 0.8), true);
        faces.extend(box_faces(
            DVec3::new(0.3, 0.4, 0.2),
            DVec3::new(0.6, 0.7, 0.5),
            false,
        ));
        let mesh = mesh_of(faces, 0.2, 2);
        for jitter in [false, true] {
            let hc = Hemicube::new(
                &mesh,
                HemicubeParams {
                    resolution: 64,
                    jitter,
                    seed: 7,
                },
                &[],
            );
            for e in 0..mesh.elements.len() {
                let row = hc.row_f64(e);
                let sum: f64 = row.iter().sum();
                assert!((sum - 1.0).abs() < 1e-12, "element {e}: {sum}");
                assert!(row.iter().all(|f| *f >= 0.0));
                // Nothing of its own surface.
                let own = mesh.elements[e].surface;
                assert!(mesh
                    .patches
                    .iter()
                    .zip(&row)
                    .all(|(p, f)| p.surface != own || *f == 0.0));
            }
            // The same from the patches' side (F_{p→e} over elements).
            for p in 0..mesh.patches.len() {
                let sum: f64 = hc.shot_f64(p).iter().sum();
                assert!((sum - 1.0).abs() < 1e-12, "patch {p}: {sum}");
            }
        }
    }

    #[test]
    fn rows_match_the_exact_point_form_factor_in_an_empty_box() {
        // Unoccluded, a row is F from the element's centre to each patch: compare with the
        // exact contour integral. Patches are 0.5 wide, so each projects with a perimeter of
        // at most ~4 face units: bound ½ · 4 · du/π = 0.02 at res 64, 5e-3 at res 256 (the
        // hemi-cube is lifted 1e-7 off the surface: negligible).
        let mesh = mesh_of(box_faces(DVec3::ZERO, DVec3::ONE, true), 0.25, 2);
        for res in [64, 256] {
            let hc = Hemicube::new(&mesh, at(res), &[]);
            let tol = 2.0 * (2.0 / res as f64) / PI;
            for (e, el) in mesh.elements.iter().enumerate().step_by(7) {
                let row = hc.row_f64(e);
                for (p, patch) in mesh.patches.iter().enumerate() {
                    let exact = if patch.surface == el.surface {
                        0.0
                    } else {
                        point_to_polygon(
                            el.centre,
                            el.normal,
                            patch.polygon.vertices(),
                            patch.polygon.normal(),
                        )
                    };
                    assert!(
                        (row[p] - exact).abs() < tol,
                        "e {e} p {p} res {res}: {} vs {exact}",
                        row[p]
                    );
                }
                assert_eq!(hc.pair(e, 3), row[3]);
            }
        }
    }

    #[test]
    fn column_is_the_shot_by_reciprocity() {
        let mesh = mesh_of(
            box_faces(DVec3::ZERO, DVec3::new(1.0, 0.6, 0.9), true),
            0.15,
            3,
        );
        let hc = Hemicube::new(&mesh, at(64), &[]);
        let mut column = vec![0.0f32; mesh.elements.len()];
        for p in [0, 5, mesh.patches.len() - 1] {
            hc.column(p, &mut column);
            let shot = hc.shot_f64(p);
            let ap = mesh.patch_area(&mesh.patches[p]);
            // Power balance: Σ_e A_e F_{e→p} = A_p Σ_e F_{p→e} = A_p in a closed box
            // (f32 storage: relative 1e-7 per entry).
            let landed: f64 = column
                .iter()
                .zip(&mesh.elements)
                .map(|(f, e)| *f as f64 * e.area)
                .sum();
            assert!((landed - ap).abs() < 1e-6 * ap, "{landed} vs {ap}");
            for (e, el) in mesh.elements.iter().enumerate() {
                let expect = shot[e] * ap / el.area;
                assert!((column[e] as f64 - expect).abs() <= 1e-6 * expect.max(1e-30));
            }
        }
    }

    #[test]
    fn rows_are_parallel_safe_and_deterministic() {
        let mesh = mesh_of(box_faces(DVec3::ZERO, DVec3::ONE, true), 0.25, 2);
        let hc = Hemicube::new(
            &mesh,
            HemicubeParams {
                resolution: 32,
                jitter: true,
                seed: 3,
            },
            &[],
        );
        let serial: Vec<Vec<f64>> = (0..mesh.elements.len()).map(|e| hc.row_f64(e)).collect();
        let parallel: Vec<Vec<f64>> = (0..mesh.elements.len())
            .into_par_iter()
            .map(|e| hc.row_f64(e))
            .collect();
        assert_eq!(serial, parallel);
    }
}
