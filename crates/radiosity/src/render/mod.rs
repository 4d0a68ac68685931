//! The display stage: a supersampled z-buffer software rasteriser and image output.
//!
//! [`render`] draws radiance-shaded triangles (and optional wire edges) as seen by a
//! [`Camera`], with the pixel convention of the reference images
//! (`tests/reference/cornell.camera.json`): pixel (i, j), i = column left→right, j = row
//! top→bottom, looks along normalize(look + s·t·aspect·right + u·t·true_up) with
//! t = tan(fov/2), s = 2(i + ½)/W − 1, u = 1 − 2(j + ½)/H, right = normalize(look × up),
//! true_up = right × look; a pixel's value is the mean radiance over its footprint.
//! [`Image::write`] stores the result as linear OpenEXR or sRGB PNG.
//!
//! See also the rasteriser's own notes in `raster.rs`.

mod image;
mod raster;

pub use image::{check_output, srgb_byte, Image, ImageError};

use crate::scene::Camera;
use glam::DVec3;
use rayon::prelude::*;

/// Largest accepted image width or height, in pixels.
pub const MAX_IMAGE_SIZE: u32 = 16384;
/// Largest accepted number of supersamples per pixel axis.
pub const MAX_SAMPLES_PER_AXIS: u32 = 16;

/// A triangle with linear RGB radiance L (W·m⁻²·sr⁻¹) at each vertex; flat shading = three
/// equal values.
///
/// Both sides are drawn with the same radiance: a caller showing one-sided surfaces passes
/// a zero-radiance triangle for a back face (or orders them so the nearest wins).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShadedTriangle {
    /// Vertex positions, world space (m).
    pub positions: [DVec3; 3],
    /// Radiance at each vertex, W·m⁻²·sr⁻¹, interpolated perspective-correctly.
    pub radiance: [[f32; 3]; 3],
}

/// Image size, supersampling and colours for [`render`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RenderOptions {
    /// Image width in pixels, 1 ..= [`MAX_IMAGE_SIZE`].
    pub width: u32,
    /// Image height in pixels, 1 ..= [`MAX_IMAGE_SIZE`].
    pub height: u32,
    /// Supersamples per pixel axis (box filter), 1 ..= [`MAX_SAMPLES_PER_AXIS`]; default 4.
    pub samples_per_axis: u32,
    /// Radiance where nothing is drawn, W·m⁻²·sr⁻¹.
    pub background: [f32; 3],
    /// Radiance of the wireframe `edges`, W·m⁻²·sr⁻¹.
    pub wire_colour: [f32; 3],
}

impl Default for RenderOptions {
    fn default() -> Self {
        Self {
            width: 256,
            height: 256,
            samples_per_axis: 4,
            background: [0.0; 3],
            wire_colour: [1.0; 3],
        }
    }
}

/// Errors from [`render`]: invalid options, camera or geometry.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RenderError {
    #[error("image size {width}x{height} is not in 1..={MAX_IMAGE_SIZE} on each axis")]
    /// Width or height out of range.
    InvalidSize {
        /// Width in pixels.
        width: u32,
        /// Height in pixels.
        height: u32,
    },
    #[error("samples per axis {0} is not in 1..={MAX_SAMPLES_PER_AXIS}")]
    /// Supersamples out of range.
    InvalidSamples(u32),
    #[error("invalid camera: {0}")]
    /// The camera cannot form an image.
    InvalidCamera(String),
    #[error("triangle {0} has a non-finite vertex position")]
    /// A triangle (by index) has a non-finite coordinate or value.
    NonFiniteTriangle(usize),
    #[error("wire edge {0} has a non-finite endpoint")]
    /// A wireframe edge (by index) has a non-finite coordinate.
    NonFiniteEdge(usize),
}

/// Renders with a z-buffer at samples_per_axis² samples per pixel, box-filtered to pixels
/// (pixel = mean radiance over its footprint).
///
/// - Visibility: the nearest surface wins at each sample (ties: the earlier triangle); back
///   faces are drawn like front faces. Geometry is clipped at a near plane 10⁻⁴ × the
///   scene's bounding-box diagonal in front of the eye, so any viewpoint works, including
///   one inside the scene.
/// - Coverage: samples at the k×k stratified points (i + (a + ½)/k, j + (b + ½)/k) of each
///   pixel; the top-left fill rule makes triangles that share an edge cover every sample on
///   it exactly once.
/// - Shading: radiance is interpolated perspective-correctly (L/z and 1/z are affine on the
///   screen).
/// - Wireframe: each edge is a line one output pixel wide, drawn over the surfaces where it
///   is not more than 0.1 % farther than the nearest surface at its centre line
///   (so edges of visible surfaces show and hidden ones do not).
///
/// The result does not depend on the number of threads.
///
/// See also [`Image::write`], and `raster.rs` for the algorithm.
pub fn render(
    triangles: &[ShadedTriangle],
    edges: &[[DVec3; 2]],
    camera: &Camera,
    options: &RenderOptions,
) -> Result<Image, RenderError> {
    let (width, height) = (options.width, options.height);
    if !(1..=MAX_IMAGE_SIZE).contains(&width) || !(1..=MAX_IMAGE_SIZE).contains(&height) {
        return Err(RenderError::InvalidSize { width, height });
    }
    let k = options.samples_per_axis;
    if !(1..=MAX_SAMPLES_PER_AXIS).contains(&k) {
        return Err(RenderError::InvalidSamples(k));
    }
    let proj = validate_camera(camera, width * k, height * k)?;
    if let Some(i) = triangles
        .iter()
        .position(|t| !t.positions.iter().all(|p| p.is_finite()))
    {
        return Err(RenderError::NonFiniteTriangle(i));
    }
    if let Some(i) = edges.iter().position(|e| !e.iter().all(|p| p.is_finite())) {
        return Err(RenderError::NonFiniteEdge(i));
    }

    let (lo, hi) = triangles
        .iter()
        .flat_map(|t| t.positions)
        .chain(edges.iter().flatten().copied())
        .fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), p| (lo.min(p), hi.max(p)),
        );
    let near = raster::near_distance(lo, hi);

    let raster_triangles: Vec<raster::RasterTriangle> = triangles
        .par_iter()
        .fold(Vec::new, |mut out, t| {
            raster::setup_triangle(t, &proj, near, &mut out);
            out
        })
        .flatten()
        .collect();
    let half_width = 0.5 * f64::from(k);
    let raster_edges: Vec<raster::RasterEdge> = edges
        .par_iter()
        .filter_map(|e| raster::setup_edge(e, &proj, near, half_width))
        .collect();

    let mut image = Image::new(width, height);
    raster::rasterise(&raster_triangles, &raster_edges, options, &mut image.pixels);
    Ok(image)
}

fn validate_camera(
    camera: &Camera,
    sample_width: u32,
    sample_height: u32,
) -> Result<raster::Projection, RenderError> {
    let bad = |why: &str| Err(RenderError::InvalidCamera(why.to_owned()));
    if !(camera.eye.is_finite() && camera.target.is_finite() && camera.up.is_finite()) {
        return bad("eye, target and up must be finite");
    }
    if !(camera.fov_deg > 0.0 && camera.fov_deg < 180.0) {
        return bad(&format!(
            "field of view {} degrees is not in (0, 180)",
            camera.fov_deg
        ));
    }
    if (camera.target - camera.eye).length_squared() == 0.0 {
        return bad("eye and target coincide");
    }
    match raster::Projection::new(camera, sample_width, sample_height) {
        Some(p) => Ok(p),
        None => bad("up is parallel to the view direction (or zero)"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Camera at the origin looking along +z, up +y (so image right is world −x).
    fn axis_camera(fov_deg: f64) -> Camera {
        Camera {
            eye: DVec3::ZERO,
            target: DVec3::Z,
            up: DVec3::Y,
            fov_deg,
        }
    }

    fn cornell_camera() -> Camera {
        Camera {
            eye: DVec3::new(0.278, 0.273, -0.8),
            target: DVec3::new(0.278, 0.273, 0.0),
            up: DVec3::Y,
            fov_deg: 39.307_648_116_106_62,
        }
    }

    fn options(width: u32, height: u32, samples_per_axis: u32) -> RenderOptions {
        RenderOptions {
            width,
            height,
            samples_per_axis,
            ..RenderOptions::default()
        }
    }

    /// The reference ray direction (not normalised) through image position (px, py) in
    /// pixel units (pixel centres at +0.5), straight from `cornell.camera.json`.
    fn reference_ray(camera: &Camera, width: u32, height: u32, px: f64, py: f64) -> DVec3 {
        let look = (camera.target - camera.eye).normalize();
        let right = look.cross(camera.up).normalize();
        let up = right.cross(look);
        let t = (camera.fov_deg.to_radians() / 2.0).tan();
        let aspect = f64::from(width) / f64::from(height);
        let s = 2.0 * px / f64::from(width) - 1.0;
        let u = 1.0 - 2.0 * py / f64::from(height);
        look + s * t * aspect * right + u * t * up
    }

    /// The point at view depth `depth` seen at image position (px, py).
    fn world_at(camera: &Camera, width: u32, height: u32, px: f64, py: f64, depth: f64) -> DVec3 {
        camera.eye + depth * reference_ray(camera, width, height, px, py)
    }

    fn flat(positions: [DVec3; 3], l: [f32; 3]) -> ShadedTriangle {
        ShadedTriangle {
            positions,
            radiance: [l; 3],
        }
    }

    /// Two triangles a-b-c, a-c-d sharing the diagonal a-c.
    fn quad(q: [DVec3; 4], l: [f32; 3]) -> [ShadedTriangle; 2] {
        [flat([q[0], q[1], q[2]], l), flat([q[0], q[2], q[3]], l)]
    }

    #[test]
    fn full_screen_quad_has_no_cracks() {
        // A slanted quad larger than the view: its diagonal crosses the whole image.
        let camera = Camera {
            eye: DVec3::new(0.1, -0.2, -2.0),
            target: DVec3::new(0.0, 0.05, 0.0),
            up: DVec3::new(0.05, 1.0, 0.0),
            fov_deg: 50.0,
        };
        let q = [
            DVec3::new(-3.0, -2.5, 0.3),
            DVec3::new(3.1, -2.9, -0.2),
            DVec3::new(2.8, 3.3, 0.1),
            DVec3::new(-2.7, 2.6, 0.4),
        ];
        for (w, h, k) in [(64, 48, 4), (37, 53, 3), (20, 20, 1), (16, 16, 16)] {
            let image = render(&quad(q, [0.5; 3]), &[], &camera, &options(w, h, k)).unwrap();
            assert!(
                image.pixels.iter().all(|p| *p == [0.5; 3]),
                "{w}x{h} k={k}: {:?}",
                image.pixels.iter().find(|p| **p != [0.5; 3])
            );
        }
    }

    #[test]
    fn jittered_mesh_with_mixed_winding_has_no_cracks() {
        // A grid of triangles with jittered vertices, alternate ones wound backwards, some
        // vertices exactly on sample centres (x = 0 is a sample boundary, 1/32 a centre).
        let camera = axis_camera(90.0);
        let n = 9;
        let vertex = |i: usize, j: usize| {
            let jitter = if i == 0 || i == n || j == 0 || j == n {
                0.0
            } else {
                0.07 * (((i * 7 + j * 13) % 5) as f64 - 2.0)
            };
            let x = -1.5 + 3.0 * i as f64 / n as f64 + jitter;
            let y = -1.5 + 3.0 * j as f64 / n as f64 - 0.5 * jitter;
            let (x, y) = if (i, j) == (4, 4) {
                (1.0 / 32.0, 1.0 / 32.0)
            } else {
                (x, y)
            };
            DVec3::new(x, y, 1.0 + 0.1 * x + 0.05 * y)
        };
        let mut triangles = Vec::new();
        for i in 0..n {
            for j in 0..n {
                let [a, b, c, d] = [
                    vertex(i, j),
                    vertex(i + 1, j),
                    vertex(i + 1, j + 1),
                    vertex(i, j + 1),
                ];
                if (i + j) % 2 == 0 {
                    triangles.extend(quad([a, b, c, d], [0.5; 3]));
                } else {
                    triangles.push(flat([a, c, b], [0.5; 3]));
                    triangles.push(flat([a, d, c], [0.5; 3]));
                }
            }
        }
        let image = render(&triangles, &[], &camera, &options(16, 16, 4)).unwrap();
        assert!(image.pixels.iter().all(|p| *p == [0.5; 3]));
    }

    #[test]
    fn pixel_convention_matches_reference_camera() {
        // A square covering exactly the footprint of pixel (40, 100) on the plane z = 0.5.
        let camera = cornell_camera();
        let (w, h) = (256, 256);
        let (i, j) = (40.0, 100.0);
        let depth = 0.5 - camera.eye.z; // look = +z, so view depth = world z − eye z
        let corners = [(i, j), (i + 1.0, j), (i + 1.0, j + 1.0), (i, j + 1.0)]
            .map(|(x, y)| world_at(&camera, w, h, x, y, depth));
        // Column 40 is on the image left, which for this camera is world +x (the red wall);
        // row 100 is above the centre.
        assert!(corners.iter().all(|p| p.x > 0.4 && p.y > 0.3 && p.z == 0.5));
        let image = render(&quad(corners, [1.0; 3]), &[], &camera, &options(w, h, 4)).unwrap();
        for y in 0..h {
            for x in 0..w {
                let expect = if (x, y) == (40, 100) { 1.0 } else { 0.0 };
                assert_eq!(image.get(x, y), [expect; 3], "pixel ({x}, {y})");
            }
        }
    }

    #[test]
    fn edge_through_pixel_centre_gives_half_coverage() {
        let camera = axis_camera(60.0);
        let (w, h) = (9, 9);
        let at = |px, py| world_at(&camera, w, h, px, py, 2.0);
        // A vertical edge through the centre of column 4: exactly half the samples.
        let q = [at(4.5, -5.0), at(20.0, -5.0), at(20.0, 20.0), at(4.5, 20.0)];
        let image = render(&quad(q, [1.0; 3]), &[], &camera, &options(w, h, 4)).unwrap();
        for y in 0..h {
            assert_eq!(image.get(3, y)[0], 0.0);
            assert_eq!(image.get(4, y)[0], 0.5);
            assert_eq!(image.get(5, y)[0], 1.0);
        }
        // A slanted edge through the centre of pixel (4, 4): about half, both ways.
        let slope = 0.37;
        let q = [
            at(4.5 - 20.0 * slope, -15.5),
            at(30.0, -15.5),
            at(30.0, 24.5),
            at(4.5 + 20.0 * slope, 24.5),
        ];
        for k in [4, 8, 16] {
            let image = render(&quad(q, [1.0; 3]), &[], &camera, &options(w, h, k)).unwrap();
            let c = image.get(4, 4)[0];
            assert!((c - 0.5).abs() <= 1.0 / k as f32, "k={k}: coverage {c}");
        }
    }

    #[test]
    fn interpolation_is_perspective_correct() {
        // A quad slanted steeply in depth, radiance affine in world z: L = 1 + 2·(z − 1).
        let camera = axis_camera(60.0);
        let (w, h, k) = (32u32, 32u32, 4u32);
        let radiance = |p: DVec3| 1.0 + 2.0 * (p.z - 1.0);
        let q = [
            DVec3::new(-3.0, -3.0, 1.0),
            DVec3::new(3.0, -3.0, 1.0),
            DVec3::new(3.0, 3.0, 5.0),
            DVec3::new(-3.0, 3.0, 5.0),
        ];
        let shaded = |a: usize, b: usize, c: usize| ShadedTriangle {
            positions: [q[a], q[b], q[c]],
            radiance: [q[a], q[b], q[c]].map(|p| [radiance(p) as f32; 3]),
        };
        let image = render(
            &[shaded(0, 1, 2), shaded(0, 2, 3)],
            &[],
            &camera,
            &options(w, h, k),
        )
        .unwrap();
        // Analytic: intersect each sample's ray with the plane z = 1 + 2(y + 3)/3 and
        // average L over the pixel's samples.
        let hit = |dir: DVec3| {
            // Plane: z − (2/3)·y = 3; ray p = t·dir.
            let t = 3.0 / (dir.z - 2.0 / 3.0 * dir.y);
            t * dir
        };
        for (px, py) in [(16, 10), (5, 20), (27, 3), (16, 29)] {
            let mut mean = 0.0;
            for a in 0..k {
                for b in 0..k {
                    let x = f64::from(px) + (f64::from(a) + 0.5) / f64::from(k);
                    let y = f64::from(py) + (f64::from(b) + 0.5) / f64::from(k);
                    let p = hit(reference_ray(&camera, w, h, x, y));
                    mean += radiance(p);
                }
            }
            let n = f64::from(k * k);
            let got = f64::from(image.get(px, py)[1]);
            assert!(
                (got - mean / n).abs() < 1e-5,
                "({px}, {py}): {got} vs {}",
                mean / n
            );
        }
    }

    #[test]
    fn nearest_surface_wins_in_either_order() {
        let camera = axis_camera(60.0);
        let big = |z: f64| {
            [
                DVec3::new(-5.0, -5.0, z),
                DVec3::new(5.0, -5.0, z),
                DVec3::new(5.0, 5.0, z),
                DVec3::new(-5.0, 5.0, z),
            ]
        };
        let near = quad(big(2.0), [1.0, 0.0, 0.0]);
        let far = quad(big(3.0), [0.0, 1.0, 0.0]);
        let both = [near, far].concat();
        let reversed = [far, near].concat();
        for triangles in [both, reversed] {
            let image = render(&triangles, &[], &camera, &options(8, 8, 2)).unwrap();
            assert!(image.pixels.iter().all(|p| *p == [1.0, 0.0, 0.0]));
        }
    }

    /// Möller–Trumbore: does the ray t·dir (t > 0) from the origin hit the triangle?
    fn ray_hits(dir: DVec3, tri: &[DVec3; 3]) -> bool {
        let (e1, e2) = (tri[1] - tri[0], tri[2] - tri[0]);
        let p = dir.cross(e2);
        let det = e1.dot(p);
        let s = -tri[0];
        let u = s.dot(p) / det;
        let q = s.cross(e1);
        let v = dir.dot(q) / det;
        let t = e2.dot(q) / det;
        u >= 0.0 && v >= 0.0 && u + v <= 1.0 && t > 0.0
    }

    #[test]
    fn triangle_crossing_the_camera_plane_shows_only_its_front() {
        let camera = axis_camera(70.0);
        let (w, h, k) = (24u32, 24u32, 4u32);
        // One vertex behind the eye; unclipped it would project mirrored.
        let tri = [
            DVec3::new(-0.5, -0.3, 2.0),
            DVec3::new(0.6, -0.2, 3.0),
            DVec3::new(0.4, 0.8, -1.0),
        ];
        let image = render(&[flat(tri, [1.0; 3])], &[], &camera, &options(w, h, k)).unwrap();
        let mut mismatched = 0;
        let mut lit = 0;
        for py in 0..h {
            for px in 0..w {
                let mut hits = 0;
                for a in 0..k {
                    for b in 0..k {
                        let x = f64::from(px) + (f64::from(a) + 0.5) / f64::from(k);
                        let y = f64::from(py) + (f64::from(b) + 0.5) / f64::from(k);
                        hits += u32::from(ray_hits(reference_ray(&camera, w, h, x, y), &tri));
                    }
                }
                let expect = hits as f32 / (k * k) as f32;
                let got = image.get(px, py)[0];
                lit += u32::from(got > 0.0);
                // Only samples within snapping distance of an edge may differ.
                assert!(
                    (got - expect).abs() <= 1.0 / 16.0,
                    "({px}, {py}): {got} vs {expect}"
                );
                mismatched += u32::from(got != expect);
            }
        }
        assert!(lit > 50, "front part visible");
        assert!(
            mismatched <= 2,
            "{mismatched} pixels differ from ray casting"
        );
    }

    #[test]
    fn eye_inside_a_closed_box_sees_walls_everywhere() {
        // A cube of 12 triangles around the eye, each face its own radiance.
        let camera = Camera {
            eye: DVec3::new(0.1, 0.2, -0.3),
            target: DVec3::new(0.3, 0.1, 1.0),
            up: DVec3::Y,
            fov_deg: 100.0,
        };
        let c = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
        let faces = [
            [
                c(-1., -1., 1.),
                c(1., -1., 1.),
                c(1., 1., 1.),
                c(-1., 1., 1.),
            ], // z = +1 (front)
            [
                c(-1., -1., -1.),
                c(-1., 1., -1.),
                c(1., 1., -1.),
                c(1., -1., -1.),
            ],
            [
                c(-1., -1., -1.),
                c(-1., -1., 1.),
                c(-1., 1., 1.),
                c(-1., 1., -1.),
            ],
            [
                c(1., -1., -1.),
                c(1., 1., -1.),
                c(1., 1., 1.),
                c(1., -1., 1.),
            ],
            [
                c(-1., -1., -1.),
                c(1., -1., -1.),
                c(1., -1., 1.),
                c(-1., -1., 1.),
            ],
            [
                c(-1., 1., -1.),
                c(-1., 1., 1.),
                c(1., 1., 1.),
                c(1., 1., -1.),
            ],
        ];
        let triangles: Vec<ShadedTriangle> = faces
            .iter()
            .enumerate()
            .flat_map(|(i, q)| quad(*q, [0.1 + 0.1 * i as f32; 3]))
            .collect();
        let mut opts = options(40, 30, 4);
        opts.background = [-1.0; 3];
        let image = render(&triangles, &[], &camera, &opts).unwrap();
        assert!(image.pixels.iter().all(|p| p[0] >= 0.1 - 1e-6));
        // The image centre looks towards +z: the front face.
        assert_eq!(image.get(20, 15), [0.1; 3]);
    }

    #[test]
    fn wire_edges_show_on_visible_surfaces_and_hide_behind_others() {
        let camera = axis_camera(60.0);
        let (w, h) = (32u32, 32u32);
        let at = |px, py, d| world_at(&camera, w, h, px, py, d);
        let rect = |x0, y0, x1, y1, d| [at(x0, y0, d), at(x1, y0, d), at(x1, y1, d), at(x0, y1, d)];
        // An occluder covering the left half at depth 2, a back wall at depth 4.
        let occluder = quad(rect(-1.0, -1.0, 16.0, 33.0, 2.0), [0.2; 3]);
        let wall = quad(rect(-1.0, -1.0, 33.0, 33.0, 4.0), [0.1; 3]);
        let triangles = [occluder, wall].concat();
        let edges = [
            // On the wall through the centres of row 10, all across: visible on the right.
            [at(0.0, 10.5, 4.0), at(32.0, 10.5, 4.0)],
            // On the occluder's surface along the centres of column 8.
            [at(8.5, 20.0, 2.0), at(8.5, 30.0, 2.0)],
            // On the wall along the boundary of rows 11 and 12: half of each.
            [at(20.0, 12.0, 4.0), at(30.0, 12.0, 4.0)],
            // 0.5 % behind the occluder: hidden.
            [at(0.0, 25.5, 2.01), at(16.0, 25.5, 2.01)],
        ];
        let mut opts = options(w, h, 4);
        opts.wire_colour = [9.0; 3];
        let image = render(&triangles, &edges, &camera, &opts).unwrap();
        for x in 0..w {
            let expect = if x < 16 { 0.2 } else { 9.0 };
            assert_eq!(image.get(x, 10), [expect; 3], "column {x}");
            assert_eq!(image.get(x, 9)[0], if x < 16 { 0.2 } else { 0.1 });
        }
        for y in 21..30 {
            assert_eq!(image.get(8, y), [9.0; 3], "row {y}");
            assert_eq!(image.get(7, y), [0.2; 3], "row {y}");
        }
        for x in 21..29 {
            for y in [11, 12] {
                assert!((image.get(x, y)[0] - 4.55).abs() < 1e-6, "({x}, {y})");
            }
        }
        for x in (0..16).filter(|&x| x != 8) {
            assert_eq!(image.get(x, 25), [0.2; 3], "column {x}");
        }
    }

    #[test]
    fn wire_edges_show_on_grazing_surfaces() {
        // A floor at y = −0.5 seen nearly edge-on, with edges across it whose projections run
        // through pixel-row centres, down to about 1° between the view ray and the floor.
        let camera = axis_camera(60.0);
        let (w, h) = (32u32, 32u32);
        let floor = quad(
            [
                DVec3::new(-50.0, -0.5, 0.5),
                DVec3::new(50.0, -0.5, 0.5),
                DVec3::new(50.0, -0.5, 100.0),
                DVec3::new(-50.0, -0.5, 100.0),
            ],
            [0.1; 3],
        );
        for k in [1, 2, 4, 8] {
            let mut opts = options(w, h, k);
            opts.wire_colour = [9.0; 3];
            for row in [16, 17, 18, 20, 24, 28] {
                let py = f64::from(row) + 0.5;
                let d = reference_ray(&camera, w, h, 16.0, py);
                let depth = -0.5 / d.y;
                let edge = [
                    DVec3::new(-50.0, -0.5, depth),
                    DVec3::new(50.0, -0.5, depth),
                ];
                let grazing = (-d.y / d.length()).asin().to_degrees();
                let image = render(&floor, &[edge], &camera, &opts).unwrap();
                for x in 0..w {
                    assert_eq!(
                        image.get(x, row),
                        [9.0; 3],
                        "k={k} row {row} ({grazing:.1}°)"
                    );
                }
            }
        }
    }

    #[test]
    fn invalid_input_is_an_error() {
        let camera = axis_camera(60.0);
        let tri = flat([DVec3::X, DVec3::Y, DVec3::Z], [1.0; 3]);
        for (w, h) in [(0, 10), (10, 0), (16385, 10), (10, 16385)] {
            assert_eq!(
                render(&[tri], &[], &camera, &options(w, h, 4)),
                Err(RenderError::InvalidSize {
                    width: w,
                    height: h
                })
            );
        }
        for k in [0, 17] {
            assert_eq!(
                render(&[tri], &[], &camera, &options(8, 8, k)),
                Err(RenderError::InvalidSamples(k))
            );
        }
        let cameras = [
            Camera {
                fov_deg: 0.0,
                ..camera
            },
            Camera {
                fov_deg: 180.0,
                ..camera
            },
            Camera {
                fov_deg: f64::NAN,
                ..camera
            },
            Camera {
                target: camera.eye,
                ..camera
            },
            Camera {
                up: DVec3::Z,
                ..camera
            },
            Camera {
                up: DVec3::ZERO,
                ..camera
            },
            Camera {
                eye: DVec3::splat(f64::INFINITY),
                ..camera
            },
        ];
        for bad in cameras {
            assert!(
                matches!(
                    render(&[tri], &[], &bad, &options(8, 8, 2)),
                    Err(RenderError::InvalidCamera(_))
                ),
                "{bad:?}"
            );
        }
        let nan = flat([DVec3::X, DVec3::NAN, DVec3::Z], [1.0; 3]);
        assert_eq!(
            render(&[tri, nan], &[], &camera, &options(8, 8, 2)),
            Err(RenderError::NonFiniteTriangle(1))
        );
        assert_eq!(
            render(
                &[],
                &[[DVec3::X, DVec3::INFINITY]],
                &camera,
                &options(8, 8, 2)
            ),
            Err(RenderError::NonFiniteEdge(0))
        );
        // Degenerate geometry is simply invisible.
        let line = flat([DVec3::Z, DVec3::Z * 2.0, DVec3::Z * 3.0], [1.0; 3]);
        let image = render(&[line], &[], &camera, &options(8, 8, 2)).unwrap();
        assert!(image.pixels.iter().all(|p| *p == [0.0; 3]));
    }

    #[test]
    fn result_does_not_depend_on_thread_count() {
        let camera = cornell_camera();
        let mut triangles = Vec::new();
        for i in 0..40 {
            let f = f64::from(i);
            let base = DVec3::new(0.05 + 0.011 * f, 0.03 + 0.013 * f, 0.1 + 0.01 * f);
            triangles.push(ShadedTriangle {
                positions: [
                    base,
                    base + DVec3::new(0.2, 0.05, 0.1),
                    base + DVec3::new(-0.03, 0.25, -0.05),
                ],
                radiance: [
                    [f as f32, 1.0, 0.0],
                    [0.0, f as f32, 1.0],
                    [1.0, 0.0, f as f32],
                ],
            });
        }
        let edges: Vec<[DVec3; 2]> = triangles
            .iter()
            .map(|t| [t.positions[0], t.positions[1]])
            .collect();
        let opts = options(96, 80, 3);
        let many = render(&triangles, &edges, &camera, &opts).unwrap();
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap()
            .install(|| render(&triangles, &edges, &camera, &opts).unwrap());
        assert_eq!(one, many);
    }
}
