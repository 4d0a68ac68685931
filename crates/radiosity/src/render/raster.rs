//! The supersampled z-buffer rasteriser behind [`super::render`].
//!
//! Pipeline per triangle: world → view space (camera basis) → Sutherland–Hodgman clipping
//! against the near plane and a guard band around the view frustum (Sutherland & Hodgman
//! 1974) → perspective projection to the supersample grid → fixed-point snapping →
//! half-space rasterisation with integer edge functions and the top-left fill rule (Pineda
//! 1988; the Direct3D 10 rasterisation rules) → perspective-correct interpolation of
//! radiance as (L/z)/(1/z) → z-buffer on 1/z (larger is nearer).
//!
//! Why integer edge functions: two triangles sharing an edge snap its endpoints identically
//! and evaluate exactly negated edge functions, so with the top-left rule every sample on the
//! shared edge belongs to exactly one of them — no cracks and no double coverage. Clipping
//! computes each new vertex from the edge's inside endpoint towards its outside endpoint,
//! so a shared edge is clipped identically in both triangles as well.
//!
//! The image is rendered in horizontal bands (a whole number of output rows each) in
//! parallel; triangles and wire edges are binned by band, drawn in input order within a band
//! (so the result does not depend on the thread count), and each band's samples are
//! box-filtered into output pixels as soon as it is done, which bounds memory.

use super::{RenderOptions, ShadedTriangle};
use crate::scene::Camera;
use glam::{DVec2, DVec3};
use rayon::prelude::*;
use std::cmp::Ordering;

/// Sub-sample fixed-point precision: vertex positions snap to 1/256 of a sample.
const SUBPIXEL_BITS: u32 = 8;
const SUBPIXEL: i64 = 1 << SUBPIXEL_BITS;

/// Half-width of the guard band as a multiple of the half-screen: geometry is clipped to
/// |s|, |u| ≤ GUARD in normalised screen coordinates. Bounds fixed-point coordinates so the
/// edge functions fit in i64; the clipped edges lie off screen and so cannot crack.
const GUARD: f64 = 2.0;

/// Near-plane distance as a fraction of the scene's bounding-box diagonal.
const NEAR_FRACTION: f64 = 1e-4;

/// Wire-edge visibility: an edge point is drawn where its 1/z is at least
/// (1 − WIRE_DEPTH_BIAS) × the 1/z of the surface nearest at that point, which is the plane
/// of the triangle visible in the sample under the edge's centre line, evaluated exactly at
/// the centre line. An edge lies on its own surfaces, so this holds up to rounding whatever
/// the slope of the surface; edges more than 0.1 % behind the nearest surface stay hidden.
const WIRE_DEPTH_BIAS: f64 = 1e-3;

/// The triangle id of a sample where nothing is drawn.
const NO_TRIANGLE: u32 = u32::MAX;

/// Target number of samples in one band's buffers (colour, depth, triangle: 20 bytes each).
const BAND_SAMPLES: usize = 1 << 18;

/// The camera's view basis and the projection to the supersample grid.
///
/// View coordinates of a point p: x = (p − eye)·right, y = (p − eye)·true_up,
/// z = (p − eye)·look. Sample-grid coordinates (in samples, origin at the top-left corner of
/// the image, y down): X = Ws/2 + f·x/z, Y = Hs/2 − f·y/z with f = Hs / (2 tan(fov/2)), which
/// is the reference camera convention (`tests/reference/cornell.camera.json`).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Projection {
    eye: DVec3,
    right: DVec3,
    up: DVec3,
    look: DVec3,
    /// Supersample grid size.
    width: u32,
    height: u32,
    /// Samples per unit of x/z (= per unit of y/z).
    focal: f64,
    /// tan(fov/2) · aspect and tan(fov/2): the half-extent of the screen in x/z and y/z.
    half_x: f64,
    half_y: f64,
}

impl Projection {
    /// The projection of `camera` onto a `width` × `height` sample grid; `None` for a
    /// degenerate camera (checked by the caller with a better message).
    pub(crate) fn new(camera: &Camera, width: u32, height: u32) -> Option<Self> {
        let look = (camera.target - camera.eye).try_normalize()?;
        let right = look.cross(camera.up).try_normalize()?;
        let up = right.cross(look);
        let half_y = (camera.fov_deg.to_radians() * 0.5).tan();
        let aspect = f64::from(width) / f64::from(height);
        let focal = f64::from(height) / (2.0 * half_y);
        (focal.is_finite() && focal > 0.0 && camera.eye.is_finite()).then_some(Self {
            eye: camera.eye,
            right,
            up,
            look,
            width,
            height,
            focal,
            half_x: half_y * aspect,
            half_y,
        })
    }

    pub(crate) fn view_of(&self, p: DVec3) -> DVec3 {
        let d = p - self.eye;
        DVec3::new(d.dot(self.right), d.dot(self.up), d.dot(self.look))
    }

    /// Sample-grid position of a view-space point with z > 0.
    pub(crate) fn screen_of(&self, v: DVec3) -> DVec2 {
        let inv_z = 1.0 / v.z;
        DVec2::new(
            0.5 * f64::from(self.width) + self.focal * v.x * inv_z,
            0.5 * f64::from(self.height) - self.focal * v.y * inv_z,
        )
    }

    /// The clipping planes (n, w), inside where n·v + w ≥ 0: near, then the guard band.
    fn clip_planes(&self, near: f64) -> [(DVec3, f64); 5] {
        let gx = GUARD * self.half_x;
        let gy = GUARD * self.half_y;
        [
            (DVec3::Z, -near),
            (DVec3::new(1.0, 0.0, gx), 0.0),
            (DVec3::new(-1.0, 0.0, gx), 0.0),
            (DVec3::new(0.0, 1.0, gy), 0.0),
            (DVec3::new(0.0, -1.0, gy), 0.0),
        ]
    }
}

/// The near-plane distance for geometry with the given bounds.
pub(crate) fn near_distance(lo: DVec3, hi: DVec3) -> f64 {
    let diagonal = (hi - lo).length();
    if diagonal.is_finite() && diagonal > 0.0 {
        NEAR_FRACTION * diagonal
    } else {
        1e-9
    }
}

/// A view-space vertex with its radiance, during clipping.
#[derive(Debug, Clone, Copy, Default)]
struct ClipVertex {
    p: DVec3,
    l: DVec3,
}

/// A convex polygon of at most 3 + 5 vertices (each clip plane adds at most one).
type ClipPolygon = crate::geometry::FixedPolygon<ClipVertex, 8>;

impl crate::geometry::ClipVertex for ClipVertex {
    fn lerp_to(self, other: Self, t: f64) -> Self {
        ClipVertex {
            p: self.p + (other.p - self.p) * t,
            l: self.l + (other.l - self.l) * t,
        }
    }
}

/// An affine function of the sample-grid position: f(X, Y) = c + gx·X + gy·Y.
#[derive(Debug, Clone, Copy, Default)]
struct Plane {
    c: f64,
    gx: f64,
    gy: f64,
}

impl Plane {
    /// The plane through (p[i], f[i]); `det` is the signed doubled area of the triangle.
    fn through(p: [DVec2; 3], f: [f64; 3], det: f64) -> Self {
        let (e1, e2) = (p[1] - p[0], p[2] - p[0]);
        let (f1, f2) = (f[1] - f[0], f[2] - f[0]);
        let gx = (f1 * e2.y - f2 * e1.y) / det;
        let gy = (f2 * e1.x - f1 * e2.x) / det;
        Self {
            c: f[0] - gx * p[0].x - gy * p[0].y,
            gx,
            gy,
        }
    }

    fn at(&self, x: f64, y: f64) -> f64 {
        self.c + self.gx * x + self.gy * y
    }
}

/// A triangle ready for rasterisation on the sample grid.
///
/// Edge i is e_i(X, Y) = a_i·X + b_i·Y + c_i in fixed point (X, Y in 1/SUBPIXEL samples),
/// non-negative inside; `c` already holds the −1 bias of edges that are not top-left, so a
/// sample is covered exactly when all three are ≥ 0.
#[derive(Debug, Clone, Copy)]
pub(crate) struct RasterTriangle {
    a: [i64; 3],
    b: [i64; 3],
    c: [i64; 3],
    /// Covered sample range, half-open, clamped to the grid.
    x0: u32,
    x1: u32,
    y0: u32,
    y1: u32,
    inv_z: Plane,
    l_over_z: [Plane; 3],
    /// Bounds of the vertex values: the perspective-correct interpolant is a convex
    /// combination of them, so clamping only removes rounding error on slivers.
    inv_z_range: (f64, f64),
    l_lo: [f64; 3],
    l_hi: [f64; 3],
}

impl RasterTriangle {
    /// The covered samples [xs, xe) of sample row y, computed exactly: each edge function
    /// is affine in x, so each bounds the span from one side.
    fn span(&self, y: u32) -> Option<(usize, usize)> {
        let yc = i64::from(y) * SUBPIXEL + SUBPIXEL / 2;
        let xc = i64::from(self.x0) * SUBPIXEL + SUBPIXEL / 2;
        let (mut lo, mut hi) = (0i64, i64::from(self.x1 - self.x0));
        for i in 0..3 {
            let e0 = self.a[i] * xc + self.b[i] * yc + self.c[i];
            let step = self.a[i] * SUBPIXEL;
            match step.cmp(&0) {
                Ordering::Equal if e0 < 0 => return None,
                Ordering::Equal => {}
                // e0 + step·n ≥ 0  ⇔  n ≥ ceil(−e0 / step)
                Ordering::Greater => lo = lo.max(-(e0.div_euclid(step))),
                // e0 + step·n ≥ 0  ⇔  n ≤ floor(e0 / −step)
                Ordering::Less => hi = hi.min(e0.div_euclid(-step) + 1),
            }
        }
        let x0 = i64::from(self.x0);
        (lo < hi).then(|| ((x0 + lo) as usize, (x0 + hi) as usize))
    }
}

/// Clips, projects and snaps one shaded triangle, appending 0 to 6 raster triangles.
pub(crate) fn setup_triangle(
    tri: &ShadedTriangle,
    proj: &Projection,
    near: f64,
    out: &mut Vec<RasterTriangle>,
) {
    let mut poly = ClipPolygon {
        vertices: [ClipVertex::default(); 8],
        len: 3,
    };
    for i in 0..3 {
        poly.vertices[i] = ClipVertex {
            p: proj.view_of(tri.positions[i]),
            l: DVec3::from(tri.radiance[i].map(f64::from)),
        };
    }
    for plane in proj.clip_planes(near) {
        let d = |v: &ClipVertex| plane.0.dot(v.p) + plane.1;
        if poly.as_slice().iter().any(|v| d(v) < 0.0) {
            let input = poly;
            crate::geometry::clip_convex(input.as_slice(), d, &mut poly);
        }
    }
    if poly.len < 3 {
        return;
    }
    // Project and snap once per polygon vertex, then fan-triangulate: the fan's internal
    // edges are shared exactly, like any other shared edge.
    let mut screen = [DVec2::ZERO; 8];
    let mut fixed = [(0i64, 0i64); 8];
    for i in 0..poly.len {
        screen[i] = proj.screen_of(poly.vertices[i].p);
        let f = screen[i] * SUBPIXEL as f64;
        fixed[i] = (f.x.round() as i64, f.y.round() as i64);
    }
    for k in 1..poly.len - 1 {
        let idx = [0, k, k + 1];
        if let Some(t) = raster_triangle(
            idx.map(|i| fixed[i]),
            idx.map(|i| screen[i]),
            idx.map(|i| poly.vertices[i]),
            proj.width,
            proj.height,
        ) {
            out.push(t);
        }
    }
}

/// `p` are the snapped positions (coverage), `screen` the exact ones (interpolation).
fn raster_triangle(
    mut p: [(i64, i64); 3],
    mut screen: [DVec2; 3],
    mut v: [ClipVertex; 3],
    width: u32,
    height: u32,
) -> Option<RasterTriangle> {
    let area2 = |p: &[(i64, i64); 3]| {
        (p[1].0 - p[0].0) * (p[2].1 - p[0].1) - (p[1].1 - p[0].1) * (p[2].0 - p[0].0)
    };
    let mut det = area2(&p);
    if det == 0 {
        return None;
    }
    if det < 0 {
        // Back faces are drawn too: orient every triangle the same way on screen.
        p.swap(1, 2);
        screen.swap(1, 2);
        v.swap(1, 2);
        det = -det;
    }

    // Bounding box of covered sample centres (256·s + 128).
    let half = SUBPIXEL / 2;
    let min_x = p.iter().map(|q| q.0).min()?;
    let max_x = p.iter().map(|q| q.0).max()?;
    let min_y = p.iter().map(|q| q.1).min()?;
    let max_y = p.iter().map(|q| q.1).max()?;
    // First sample whose centre is ≥ m, and one past the last whose centre is ≤ m.
    let lo = |m: i64| -(half - m).div_euclid(SUBPIXEL);
    let hi = |m: i64| (m - half).div_euclid(SUBPIXEL) + 1;
    let x0 = lo(min_x).max(0);
    let x1 = hi(max_x).min(i64::from(width));
    let y0 = lo(min_y).max(0);
    let y1 = hi(max_y).min(i64::from(height));
    if x0 >= x1 || y0 >= y1 {
        return None;
    }

    // Edge i runs from vertex i+1 to vertex i+2 (opposite vertex i):
    // e(X, Y) = dx·(Y − ay) − dy·(X − ax), positive on the interior side.
    let mut a = [0i64; 3];
    let mut b = [0i64; 3];
    let mut c = [0i64; 3];
    for i in 0..3 {
        let (pa, pb) = (p[(i + 1) % 3], p[(i + 2) % 3]);
        let (dx, dy) = (pb.0 - pa.0, pb.1 - pa.1);
        a[i] = -dy;
        b[i] = dx;
        c[i] = dy * pa.0 - dx * pa.1;
        // Top-left rule (y down): a left edge has the interior to its right (dy < 0); a top
        // edge is horizontal with the interior below (dx > 0). Other edges exclude e = 0.
        let top_left = dy < 0 || (dy == 0 && dx > 0);
        if !top_left {
            c[i] -= 1;
        }
    }

    // Interpolate from the unsnapped positions, which gives exact perspective-correct
    // values, unless snapping changed the shape a lot (slivers): then from the snapped ones,
    // which the sample is known to lie in. The clamps below bound the rest.
    let sub = SUBPIXEL as f64;
    let snapped_det = det as f64 / (sub * sub);
    let (e1, e2) = (screen[1] - screen[0], screen[2] - screen[0]);
    let exact_det = e1.x * e2.y - e1.y * e2.x;
    let (ps, det_samples) = if exact_det > 0.5 * snapped_det {
        (screen, exact_det)
    } else {
        (
            p.map(|q| DVec2::new(q.0 as f64, q.1 as f64) / sub),
            snapped_det,
        )
    };
    let inv_z = v.map(|q| 1.0 / q.p.z);
    let l_over_z: [Plane; 3] = std::array::from_fn(|ch| {
        Plane::through(
            ps,
            std::array::from_fn(|i| v[i].l[ch] * inv_z[i]),
            det_samples,
        )
    });
    let fold = |f: fn(f64, f64) -> f64, xs: [f64; 3]| f(f(xs[0], xs[1]), xs[2]);
    Some(RasterTriangle {
        a,
        b,
        c,
        x0: x0 as u32,
        x1: x1 as u32,
        y0: y0 as u32,
        y1: y1 as u32,
        inv_z: Plane::through(ps, inv_z, det_samples),
        l_over_z,
        inv_z_range: (fold(f64::min, inv_z), fold(f64::max, inv_z)),
        l_lo: std::array::from_fn(|ch| fold(f64::min, v.map(|q| q.l[ch]))),
        l_hi: std::array::from_fn(|ch| fold(f64::max, v.map(|q| q.l[ch]))),
    })
}

/// A wire edge projected onto the sample grid.
#[derive(Debug, Clone, Copy)]
pub(crate) struct RasterEdge {
    a: DVec2,
    d: DVec2,
    /// 1/z at the two endpoints; 1/z is affine along the screen-space segment.
    inv_z: (f64, f64),
    /// Sample rows that the line's width touches, half-open, clamped to the grid.
    y0: u32,
    y1: u32,
}

/// Clips a world-space segment to the near plane and guard band and projects it.
pub(crate) fn setup_edge(
    edge: &[DVec3; 2],
    proj: &Projection,
    near: f64,
    half_width: f64,
) -> Option<RasterEdge> {
    let (mut p, mut q) = (proj.view_of(edge[0]), proj.view_of(edge[1]));
    for (n, w) in proj.clip_planes(near) {
        let (dp, dq) = (n.dot(p) + w, n.dot(q) + w);
        match (dp >= 0.0, dq >= 0.0) {
            (true, true) => {}
            (false, false) => return None,
            (true, false) => q = p + (q - p) * (dp / (dp - dq)),
            (false, true) => p = q + (p - q) * (dq / (dq - dp)),
        }
    }
    let (a, b) = (proj.screen_of(p), proj.screen_of(q));
    let y_lo = (a.y.min(b.y) - half_width - 0.5).ceil().max(0.0);
    let y_hi = (a.y.max(b.y) + half_width - 0.5).floor() + 1.0;
    let y_hi = y_hi.min(f64::from(proj.height));
    (y_lo < y_hi).then_some(RasterEdge {
        a,
        d: b - a,
        inv_z: (1.0 / p.z, 1.0 / q.z),
        y0: y_lo as u32,
        y1: y_hi as u32,
    })
}

/// The sample rows [own0, own1) of the grid, held with a margin as rows [y0, y1): colour,
/// depth (1/z; 0 = nothing drawn) and the index of the visible triangle. Triangles are
/// drawn into the margin too, so that wire edges can look up the surface under their centre
/// line in the neighbouring rows.
struct Band {
    y0: u32,
    y1: u32,
    own0: u32,
    own1: u32,
    width: u32,
    colour: Vec<[f32; 3]>,
    inv_z: Vec<f32>,
    triangle: Vec<u32>,
}

impl Band {
    fn reset(&mut self, (y0, y1): (u32, u32), (own0, own1): (u32, u32), background: [f32; 3]) {
        let n = (y1 - y0) as usize * self.width as usize;
        (self.y0, self.y1, self.own0, self.own1) = (y0, y1, own0, own1);
        self.colour.clear();
        self.colour.resize(n, background);
        self.inv_z.clear();
        self.inv_z.resize(n, 0.0);
        self.triangle.clear();
        self.triangle.resize(n, NO_TRIANGLE);
    }

    fn draw_triangle(&mut self, t: &RasterTriangle, index: u32) {
        let width = self.width as usize;
        for y in t.y0.max(self.y0)..t.y1.min(self.y1) {
            let Some((xs, xe)) = t.span(y) else { continue };
            let row = (y - self.y0) as usize * width;
            let yf = f64::from(y) + 0.5;
            for x in xs..xe {
                let xf = x as f64 + 0.5;
                let iz = t.inv_z.at(xf, yf).clamp(t.inv_z_range.0, t.inv_z_range.1);
                let idx = row + x;
                // Strictly nearer wins: on exact ties the earlier triangle stays.
                if iz as f32 > self.inv_z[idx] {
                    self.inv_z[idx] = iz as f32;
                    self.triangle[idx] = index;
                    let z = 1.0 / iz;
                    self.colour[idx] = std::array::from_fn(|ch| {
                        (t.l_over_z[ch].at(xf, yf) * z).clamp(t.l_lo[ch], t.l_hi[ch]) as f32
                    });
                }
            }
        }
    }

    /// Draws a line of the given half-width (in samples) with round caps: the samples whose
    /// centre lies within `half_width` of the segment, where the segment's point nearest to
    /// the sample is not hidden behind the surface there (see [`WIRE_DEPTH_BIAS`]).
    fn draw_edge(
        &mut self,
        e: &RasterEdge,
        triangles: &[RasterTriangle],
        half_width: f64,
        colour: [f32; 3],
    ) {
        let len2 = e.d.length_squared();
        let b = e.a + e.d;
        let (bx_lo, bx_hi) = (e.a.x.min(b.x) - half_width, e.a.x.max(b.x) + half_width);
        let r2 = half_width * half_width;
        let width = self.width as usize;
        let (min_y, last_row) = (f64::from(self.y0), self.y1 as usize - 1);
        for y in e.y0.max(self.own0)..e.y1.min(self.own1) {
            let yf = f64::from(y) + 0.5;
            // Candidate x range: the thick line's extent in this row, within the bounding box.
            let (mut x_lo, mut x_hi) = (bx_lo, bx_hi);
            if e.d.y.abs() * 64.0 > e.d.x.abs() {
                let xc = e.a.x + (yf - e.a.y) * e.d.x / e.d.y;
                let reach = half_width * len2.sqrt() / e.d.y.abs();
                x_lo = x_lo.max(xc - reach);
                x_hi = x_hi.min(xc + reach);
            }
            let xs = (x_lo - 0.5).floor().max(0.0);
            let xe = ((x_hi - 0.5).ceil() + 1.0).min(f64::from(self.width));
            if xs >= xe {
                continue;
            }
            let row = (y - self.y0) as usize * width;
            for x in xs as usize..xe as usize {
                let p = DVec2::new(x as f64 + 0.5, yf);
                let t = if len2 > 0.0 {
                    ((p - e.a).dot(e.d) / len2).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                let c = e.a + e.d * t;
                if (p - c).length_squared() > r2 {
                    continue;
                }
                // The sample under the centre line; the margin holds it (|c.y − p.y| ≤
                // half_width), the clamps only guard the image border.
                // (`as` truncates, which is floor for these non-negative values.)
                let cx = (c.x.max(0.0) as usize).min(width - 1);
                let cy = (c.y.max(min_y) as usize).min(last_row) - self.y0 as usize;
                let surface = match self.triangle[cy * width + cx] {
                    NO_TRIANGLE => 0.0,
                    i => triangles[i as usize].inv_z.at(c.x, c.y),
                };
                let iz = e.inv_z.0 + (e.inv_z.1 - e.inv_z.0) * t;
                if iz >= surface * (1.0 - WIRE_DEPTH_BIAS) {
                    self.colour[row + x] = colour;
                }
            }
        }
    }

    /// Box-filters the band into output rows: each pixel is the mean of its k×k samples.
    fn resolve(&self, k: u32, out: &mut [[f32; 3]]) {
        let k = k as usize;
        let width = self.width as usize;
        let skip = (self.own0 - self.y0) as usize;
        let out_width = width / k;
        let norm = 1.0 / (k * k) as f64;
        for (py, out_row) in out.chunks_mut(out_width).enumerate() {
            for (px, pixel) in out_row.iter_mut().enumerate() {
                let mut sum = [0.0f64; 3];
                for sy in skip + py * k..skip + (py + 1) * k {
                    let start = sy * width + px * k;
                    for s in &self.colour[start..start + k] {
                        for ch in 0..3 {
                            sum[ch] += f64::from(s[ch]);
                        }
                    }
                }
                *pixel = sum.map(|v| (v * norm) as f32);
            }
        }
    }
}

/// Rasterises into `pixels` (the output image, row-major): see the module comment.
pub(crate) fn rasterise(
    triangles: &[RasterTriangle],
    edges: &[RasterEdge],
    options: &RenderOptions,
    pixels: &mut [[f32; 3]],
) {
    let k = options.samples_per_axis;
    let width = options.width as usize;
    let sample_width = options.width * k;
    let row_samples = sample_width as usize * k as usize;
    // Bands of whole output rows: enough bands to balance the threads, each small enough
    // to stay in cache and to bound memory, at least one output row.
    let by_threads = (options.height as usize).div_ceil(8 * rayon::current_num_threads());
    let by_memory = (BAND_SAMPLES / row_samples).max(1);
    let band_rows = by_threads.min(by_memory).max(1);
    let band_samples_rows = band_rows as u32 * k;
    let n_bands = (options.height as usize).div_ceil(band_rows);

    // Wire edges need the depth up to half a line width beyond the band: draw triangles
    // into that margin as well (only when there are edges).
    let half_width = 0.5 * f64::from(k);
    let margin = if edges.is_empty() { 0 } else { k / 2 + 1 };
    let sample_height = options.height * k;
    let own_rows = |b: usize| {
        let y0 = b as u32 * band_samples_rows;
        (y0, (y0 + band_samples_rows).min(sample_height))
    };
    let held_rows = |b: usize| {
        let (y0, y1) = own_rows(b);
        (y0.saturating_sub(margin), (y1 + margin).min(sample_height))
    };

    // Bins: for each band, the triangles touching its held rows and the edges touching its
    // own rows, in input order.
    let band_of = |y: u32| (y / band_samples_rows) as usize;
    let mut tri_bins = vec![Vec::new(); n_bands];
    for (i, t) in triangles.iter().enumerate() {
        let first = band_of(t.y0.saturating_sub(margin));
        let last = band_of((t.y1 - 1 + margin).min(sample_height - 1));
        for (b, bin) in tri_bins.iter_mut().enumerate().take(last + 1).skip(first) {
            let (y0, y1) = held_rows(b);
            if t.y0 < y1 && y0 < t.y1 {
                bin.push(i as u32);
            }
        }
    }
    let mut edge_bins = vec![Vec::new(); n_bands];
    for (i, e) in edges.iter().enumerate() {
        for bin in &mut edge_bins[band_of(e.y0)..=band_of(e.y1 - 1)] {
            bin.push(i as u32);
        }
    }

    pixels
        .par_chunks_mut(band_rows * width)
        .zip(tri_bins.par_iter().zip(edge_bins.par_iter()))
        .enumerate()
        .for_each_init(
            || Band {
                y0: 0,
                y1: 0,
                own0: 0,
                own1: 0,
                width: sample_width,
                colour: Vec::new(),
                inv_z: Vec::new(),
                triangle: Vec::new(),
            },
            |band, (b, (out, (tri_bin, edge_bin)))| {
                band.reset(held_rows(b), own_rows(b), options.background);
                for &i in tri_bin {
                    band.draw_triangle(&triangles[i as usize], i);
                }
                for &i in edge_bin {
                    let edge = &edges[i as usize];
                    band.draw_edge(edge, triangles, half_width, options.wire_colour);
                }
                band.resolve(k, out);
            },
        );
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cornell_camera() -> Camera {
        Camera {
            eye: DVec3::new(0.278, 0.273, -0.8),
            target: DVec3::new(0.278, 0.273, 0.0),
            up: DVec3::Y,
            fov_deg: 39.307_648_116_106_62,
        }
    }

    #[test]
    fn cornell_basis_matches_reference() {
        let proj = Projection::new(&cornell_camera(), 256, 256).unwrap();
        assert_eq!(proj.right, DVec3::new(-1.0, 0.0, 0.0));
        assert_eq!(proj.up, DVec3::Y);
        assert_eq!(proj.look, DVec3::Z);
    }

    /// The projection inverts the reference ray formula at pixel centres.
    #[test]
    fn projection_inverts_reference_rays() {
        let camera = Camera {
            eye: DVec3::new(0.3, -0.2, 1.0),
            target: DVec3::new(-0.4, 0.5, -2.0),
            up: DVec3::new(0.1, 1.0, 0.2),
            fov_deg: 55.0,
        };
        let (w, h) = (40u32, 25u32);
        let proj = Projection::new(&camera, w, h).unwrap();
        let look = (camera.target - camera.eye).normalize();
        let right = look.cross(camera.up).normalize();
        let up = right.cross(look);
        let t = (camera.fov_deg.to_radians() / 2.0).tan();
        let aspect = f64::from(w) / f64::from(h);
        for (i, j) in [(0, 0), (39, 0), (0, 24), (17, 11), (39, 24)] {
            let s = 2.0 * (f64::from(i) + 0.5) / f64::from(w) - 1.0;
            let u = 1.0 - 2.0 * (f64::from(j) + 0.5) / f64::from(h);
            let dir = (look + s * t * aspect * right + u * t * up).normalize();
            let p = proj.screen_of(proj.view_of(camera.eye + 3.7 * dir));
            assert!((p - DVec2::new(f64::from(i) + 0.5, f64::from(j) + 0.5)).length() < 1e-9);
        }
    }

    #[test]
    fn clipping_a_shared_edge_is_bit_identical() {
        let vertex = |x, y, z, l| ClipVertex {
            p: DVec3::new(x, y, z),
            l: DVec3::splat(l),
        };
        let a = vertex(0.1, 0.2, -0.7, 1.0);
        let b = vertex(-0.3, 0.1, 2.3, 0.0);
        let c = vertex(0.5, -0.9, 1.1, 0.3);
        let d = vertex(-0.8, 0.4, -0.2, 0.7);
        let clip = |v: [ClipVertex; 3]| {
            let mut p = ClipPolygon {
                vertices: [ClipVertex::default(); 8],
                len: 3,
            };
            p.vertices[..3].copy_from_slice(&v);
            let input = p;
            crate::geometry::clip_convex(input.as_slice(), |q| q.p.z - 1e-3, &mut p);
            p.as_slice()
                .iter()
                .filter(|q| ![a, b, c, d].iter().any(|o| o.p == q.p))
                .map(|q| (q.p, q.l))
                .collect::<Vec<_>>()
        };
        // (a, b, c) and (b, a, d) share edge ab, traversed in opposite directions; a is
        // behind the near plane. Each gets two new vertices; the one on ab must be the same.
        let new1 = clip([a, b, c]);
        let new2 = clip([b, a, d]);
        assert_eq!((new1.len(), new2.len()), (2, 2));
        let shared = new1.iter().filter(|v| new2.contains(v)).count();
        assert_eq!(shared, 1, "{new1:?}\n{new2:?}");
    }

    /// Watertightness at the raster level: a random mesh over the whole screen, with mixed
    /// winding, vertices and axis-aligned edges exactly on sample centres, varying depth,
    /// covers every sample exactly once.
    #[test]
    fn shared_edges_cover_every_sample_exactly_once() {
        let camera = Camera {
            eye: DVec3::ZERO,
            target: DVec3::Z,
            up: DVec3::Y,
            fov_deg: 90.0,
        };
        let (w, h) = (64u32, 48u32);
        let proj = Projection::new(&camera, w, h).unwrap();
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        let mut random = move || {
            seed = seed
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let n = 12;
        let mut grid = vec![vec![DVec3::ZERO; n + 1]; n + 1];
        for (i, column) in grid.iter_mut().enumerate() {
            for (j, vertex) in column.iter_mut().enumerate() {
                let mut sx = -8.0 + (f64::from(w) + 16.0) * i as f64 / n as f64;
                let mut sy = -8.0 + (f64::from(h) + 16.0) * j as f64 / n as f64;
                if 0 < i && i < n && 0 < j && j < n {
                    match (i + j) % 3 {
                        // Jittered freely.
                        0 => {
                            sx += 2.5 * (random() - 0.5);
                            sy += 2.5 * (random() - 0.5);
                        }
                        // On a sample centre or corner.
                        1 => {
                            sx = (sx * 2.0).round() / 2.0;
                            sy = (sy * 2.0).round() / 2.0;
                        }
                        // Column on a sample centre: vertical edges through centres.
                        _ => sx = sx.floor() + 0.5,
                    }
                }
                let z = 1.0 + random();
                let view = DVec3::new(
                    (sx - f64::from(w) / 2.0) / proj.focal * z,
                    -(sy - f64::from(h) / 2.0) / proj.focal * z,
                    z,
                );
                // right = −x for this camera.
                *vertex = DVec3::new(-view.x, view.y, view.z);
            }
        }
        let mut triangles = Vec::new();
        for i in 0..n {
            for j in 0..n {
                let (a, b, c, d) = (
                    grid[i][j],
                    grid[i + 1][j],
                    grid[i + 1][j + 1],
                    grid[i][j + 1],
                );
                let tris = if random() < 0.5 {
                    [[a, b, c], [a, c, d]]
                } else {
                    [[a, d, b], [b, d, c]]
                };
                for mut t in tris {
                    if random() < 0.5 {
                        t.swap(1, 2);
                    }
                    let shaded = ShadedTriangle {
                        positions: t,
                        radiance: [[1.0; 3]; 3],
                    };
                    setup_triangle(&shaded, &proj, 1e-4, &mut triangles);
                }
            }
        }
        let mut counts = vec![0u32; (w * h) as usize];
        for t in &triangles {
            for y in t.y0..t.y1 {
                if let Some((xs, xe)) = t.span(y) {
                    for count in &mut counts[(y * w) as usize + xs..(y * w) as usize + xe] {
                        *count += 1;
                    }
                }
            }
        }
        let bad: Vec<_> = (0..counts.len())
            .filter(|&i| counts[i] != 1)
            .map(|i| (i as u32 % w, i as u32 / w, counts[i]))
            .collect();
        assert!(bad.is_empty(), "samples (x, y, count): {bad:?}");
    }
}
