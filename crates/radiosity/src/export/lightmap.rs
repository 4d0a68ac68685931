//! The lightmap: a texture atlas of the scene's planar charts, with the baked radiance.
//!
//! Every chart is one planar convex surface, so its parametrisation is free of distortion: the
//! chart is projected onto its own plane, in a 2-D frame turned to the chart's minimum-area
//! bounding rectangle (one of its sides is collinear with an edge of the convex hull: Freeman
//! & Shapira 1975, "Determining the minimum-area encasing rectangle for an arbitrary closed
//! curve"; the hull edges are tried in turn), then turned so that its long side is horizontal.
//! At a texel density d (texels per metre) a chart of w × h metres takes a rectangle of
//! (⌈w·d⌉ + 2g) × (⌈h·d⌉ + 2g) texels, g being the gutter. The rectangles are shelf-packed
//! (sorted by height, filled left to right in rows: the "next fit decreasing height" of Coffman,
//! Garey, Johnson & Tarjan 1980). For a requested atlas side S the density is the largest for
//! which the packing fits S × S, found by bisection; the atlas is then cropped to the rows used.
//! Chart footprints are at least 2g texels apart.
//!
//! Baking evaluates the per-vertex radiance, linearly interpolated over each triangle
//! (barycentric weights), at every texel centre inside the chart. Texels outside it but within
//! g texels (Euclidean, centre to chart) get the value at the nearest point of the chart — a
//! dilation that extends the chart's values outwards, so bilinear filtering, which reads texels
//! whose centres lie within √2 texels of the sample point, never mixes in the black of unused
//! texels as long as g ≥ 2. Nothing is written outside a chart's own rectangle.
//!
//! Why not a crate: crates.io has `xatlas-rs` 0.1.3 (MIT), bindings to the C++ xatlas library —
//! a C++ build and FFI (`unsafe`, which the workspace forbids in our code but not in
//! dependencies) for a general mesh unwrapper whose chart segmentation we do not need, since
//! our charts are given. Pure-Rust rectangle packers exist (`etagere` 0.3 and `guillotiere`
//! 0.7, MIT/Apache-2.0, dynamic atlas allocators for glyph caches; `rectangle-pack` 0.4,
//! MIT/Apache-2.0), but packing is the small part here; the chart frames, the fit-to-size
//! search and the baking are domain code either way.

use super::{BakedScene, ExportError, ExportPrimitive};
use crate::render::{srgb_byte, Image};
use glam::{DVec2, DVec3};
use std::collections::BTreeMap;

/// Largest atlas side, texels (the texture limit of most GPUs).
pub const MAX_ATLAS_SIDE: u32 = 16_384;

/// How the atlas is sized.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum AtlasSize {
    /// The highest texel density whose atlas fits `max_side` × `max_side` texels.
    Fit {
        /// Largest width and height, texels.
        max_side: u32,
    },
    /// A fixed density, texels per metre; the atlas grows to hold it (up to
    /// [`MAX_ATLAS_SIDE`]).
    TexelsPerMetre(f64),
}

/// Atlas options.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LightmapOptions {
    /// How the atlas is sized; default `Fit { max_side: 2048 }`.
    pub size: AtlasSize,
    /// Texels of padding on each side of every chart, filled by dilation; at least 2
    /// (bilinear filtering reads up to √2 texels away); default 2.
    pub gutter: u32,
}

impl Default for LightmapOptions {
    fn default() -> Self {
        Self {
            size: AtlasSize::Fit { max_side: 2048 },
            gutter: 2,
        }
    }
}

/// Where one chart went: its rectangle in the atlas, gutter included, in texels (x right,
/// y down from the top-left texel).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ChartRect {
    /// Object index in the scene.
    pub object: usize,
    /// Primitive index in the object.
    pub primitive: usize,
    /// The chart's id.
    pub chart: u32,
    /// Left column.
    pub x: u32,
    /// Top row.
    pub y: u32,
    /// Width, texels.
    pub width: u32,
    /// Height, texels.
    pub height: u32,
}

/// The baked atlas.
#[derive(Debug, Clone, PartialEq)]
pub struct Lightmap {
    /// Linear radiance per texel, W·m⁻²·sr⁻¹; row 0 is the top (glTF v = 0). Unused texels are
    /// black.
    pub image: Image,
    /// Texel density, texels per metre.
    pub texels_per_metre: f64,
    /// Gutter, texels.
    pub gutter: u32,
    /// Every chart's rectangle.
    pub charts: Vec<ChartRect>,
    /// Fraction of the atlas's texels whose centre lies inside a chart.
    pub coverage: f64,
}

impl Lightmap {
    /// The lightmap as an 8-bit sRGB PNG: each texel is `srgb_byte(L · 2^exposure_stops)`, the
    /// renderer's PNG encoding.
    pub fn png_bytes(&self, exposure_stops: f32) -> Result<Vec<u8>, image::ImageError> {
        let scale = exposure_stops.exp2();
        let data: Vec<u8> = self
            .image
            .pixels
            .iter()
            .flat_map(|p| p.map(|l| srgb_byte(l * scale)))
            .collect();
        let mut bytes = Vec::new();
        image::ImageEncoder::write_image(
            image::codecs::png::PngEncoder::new(&mut bytes),
            &data,
            self.image.width,
            self.image.height,
            image::ExtendedColorType::Rgb8,
        )?;
        Ok(bytes)
    }
}

/// One chart: its triangles and vertices in a primitive, and their 2-D chart coordinates.
struct Chart {
    object: usize,
    primitive: usize,
    id: u32,
    triangles: Vec<usize>,
    vertices: Vec<u32>,
    /// Per vertex, metres, in [0, w] × [0, h].
    local: Vec<DVec2>,
    /// (w, h), m, w ≥ h.
    size: DVec2,
}

/// Packs the charts of `objects`, stores each vertex's lightmap coordinates in
/// `ExportPrimitive::uv` and bakes the radiance.
pub(crate) fn build(
    scene: &BakedScene,
    objects: &mut [Vec<ExportPrimitive>],
    options: &LightmapOptions,
) -> Result<Lightmap, ExportError> {
    if options.gutter < 2 {
        return Err(ExportError::Atlas(format!(
            "gutter {} is below 2 texels (bilinear filtering would read unfilled texels)",
            options.gutter
        )));
    }
    let mut charts = Vec::new();
    for (o, primitives) in objects.iter().enumerate() {
        for (p, primitive) in primitives.iter().enumerate() {
            charts.extend(charts_of(scene, o, p, primitive)?);
        }
    }
    let gutter = options.gutter;
    let sizes: Vec<DVec2> = charts.iter().map(|c| c.size).collect();
    let (density, width, placed, height) = match options.size {
        AtlasSize::Fit { max_side } => fit(&sizes, gutter, max_side)?,
        AtlasSize::TexelsPerMetre(d) => fixed(&sizes, gutter, d)?,
    };

    let mut rects = Vec::with_capacity(charts.len());
    for (chart, &(x, y, w, h)) in charts.iter().zip(&placed) {
        let primitive = &mut objects[chart.object][chart.primitive];
        let g = f64::from(gutter);
        for (&v, local) in chart.vertices.iter().zip(&chart.local) {
            let tx = f64::from(x) + g + local.x * density;
            let ty = f64::from(y) + g + local.y * density;
            primitive.uv[v as usize] = [
                (tx / f64::from(width)) as f32,
                (ty / f64::from(height)) as f32,
            ];
        }
        rects.push(ChartRect {
            object: chart.object,
            primitive: chart.primitive,
            chart: chart.id,
            x,
            y,
            width: w,
            height: h,
        });
    }

    let mut image = Image::new(width, height);
    let mut distance = vec![f32::INFINITY; image.pixels.len()];
    for (chart, rect) in charts.iter().zip(&rects) {
        let primitive = &objects[chart.object][chart.primitive];
        for &t in &chart.triangles {
            bake_triangle(primitive, t, rect, gutter, &mut image, &mut distance);
        }
    }
    let inside = distance.iter().filter(|&&d| d == 0.0).count();
    Ok(Lightmap {
        coverage: inside as f64 / distance.len() as f64,
        image,
        texels_per_metre: density,
        gutter,
        charts: rects,
    })
}

/// The charts of one primitive with their 2-D frames; a chart whose triangles are not
/// coplanar (a triangle tilted more than 8° from the chart's plane, or facing the other way)
/// is an error, since its projection could fold.
fn charts_of(
    scene: &BakedScene,
    object: usize,
    primitive: usize,
    p: &ExportPrimitive,
) -> Result<Vec<Chart>, ExportError> {
    let mut by_id: BTreeMap<u32, (Vec<usize>, Vec<u32>)> = BTreeMap::new();
    for (t, &id) in p.charts.iter().enumerate() {
        by_id.entry(id).or_default().0.push(t);
    }
    for (v, &id) in p.vertex_chart.iter().enumerate() {
        by_id.entry(id).or_default().1.push(v as u32);
    }
    let position = |v: u32| DVec3::from_array(p.positions[v as usize].map(f64::from));
    let mut out = Vec::new();
    for (id, (triangles, vertices)) in by_id {
        let cross = |t: usize| {
            let [a, b, c] = p.triangles[t].map(position);
            (b - a).cross(c - a)
        };
        let sum: DVec3 = triangles.iter().map(|&t| cross(t)).sum();
        let normal = sum.try_normalize().unwrap_or(DVec3::Z);
        for &t in &triangles {
            let n = cross(t);
            let length = n.length();
            // Cosine of 8°: f32 vertices of a coplanar fan tilt by far less.
            if length > 0.0 && n.dot(normal) < 0.99 * length {
                return Err(ExportError::Invalid {
                    object: scene.objects[object].name.clone(),
                    message: format!(
                        "primitive {primitive}: chart {id} is not planar: triangle {t} is \
                         tilted {:.1}° from the chart's plane",
                        (n.dot(normal) / length)
                            .clamp(-1.0, 1.0)
                            .acos()
                            .to_degrees()
                    ),
                });
            }
        }
        let e1 = normal.any_orthonormal_vector();
        let e2 = normal.cross(e1);
        let flat: Vec<DVec2> = vertices
            .iter()
            .map(|&v| {
                let q = position(v);
                DVec2::new(q.dot(e1), q.dot(e2))
            })
            .collect();
        let axis = min_area_axis(&flat);
        let mut local: Vec<DVec2> = flat
            .iter()
            .map(|q| DVec2::new(q.dot(axis), q.dot(axis.perp())))
            .collect();
        let lo = local.iter().fold(DVec2::INFINITY, |a, q| a.min(*q));
        let hi = local.iter().fold(DVec2::NEG_INFINITY, |a, q| a.max(*q));
        let mut size = (hi - lo).max(DVec2::ZERO);
        for q in &mut local {
            *q -= lo;
        }
        if size.y > size.x {
            // Long side horizontal; (x, y) → (y, w − x) is a rotation, so nothing mirrors.
            let w = size.x;
            for q in &mut local {
                *q = DVec2::new(q.y, w - q.x);
            }
            size = DVec2::new(size.y, size.x);
        }
        if vertices.is_empty() {
            size = DVec2::ZERO;
        }
        out.push(Chart {
            object,
            primitive,
            id,
            triangles,
            vertices,
            local,
            size,
        });
    }
    Ok(out)
}

/// The direction of a side of the minimum-area rectangle enclosing the points: one side is
/// collinear with an edge of their convex hull (Freeman & Shapira 1975), so each hull edge is
/// tried. Returns +x for fewer than two distinct points.
fn min_area_axis(points: &[DVec2]) -> DVec2 {
    let hull = convex_hull(points);
    let mut best = (f64::INFINITY, DVec2::X);
    for k in 0..hull.len() {
        let Some(axis) = (hull[(k + 1) % hull.len()] - hull[k]).try_normalize() else {
            continue;
        };
        let perp = axis.perp();
        let (mut lo, mut hi) = (DVec2::INFINITY, DVec2::NEG_INFINITY);
        for q in &hull {
            let r = DVec2::new(q.dot(axis), q.dot(perp));
            lo = lo.min(r);
            hi = hi.max(r);
        }
        let area = (hi - lo).x * (hi - lo).y;
        if area < best.0 {
            best = (area, axis);
        }
    }
    best.1
}

/// Andrew's monotone chain convex hull, counter-clockwise, collinear points dropped.
fn convex_hull(points: &[DVec2]) -> Vec<DVec2> {
    let mut p: Vec<DVec2> = points.to_vec();
    p.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    p.dedup();
    if p.len() < 3 {
        return p;
    }
    let turn = |o: DVec2, a: DVec2, b: DVec2| (a - o).perp_dot(b - o);
    let mut hull: Vec<DVec2> = Vec::with_capacity(2 * p.len());
    for pass in 0..2 {
        let start = hull.len();
        let iter: Box<dyn Iterator<Item = &DVec2>> = if pass == 0 {
            Box::new(p.iter())
        } else {
            Box::new(p.iter().rev())
        };
        for &q in iter {
            while hull.len() >= start + 2
                && turn(hull[hull.len() - 2], hull[hull.len() - 1], q) <= 0.0
            {
                hull.pop();
            }
            hull.push(q);
        }
        hull.pop();
    }
    hull
}

/// Rectangle size in texels of a chart of `size` metres at `density`, gutter included.
fn rect_size(size: DVec2, density: f64, gutter: u32) -> Option<(u32, u32)> {
    let side = |m: f64| {
        let t = (m * density).ceil().max(1.0);
        (t <= f64::from(MAX_ATLAS_SIDE)).then(|| t as u32 + 2 * gutter)
    };
    Some((side(size.x)?, side(size.y)?))
}

/// Shelf packing into rows of width `width`: (x, y, w, h) per chart and the height used, or
/// `None` if a chart is wider than the atlas or the height passes `max_height`.
#[allow(clippy::type_complexity)]
fn pack(
    sizes: &[DVec2],
    density: f64,
    gutter: u32,
    width: u32,
    max_height: u32,
) -> Option<(Vec<(u32, u32, u32, u32)>, u32)> {
    let rects: Vec<(u32, u32)> = sizes
        .iter()
        .map(|&s| rect_size(s, density, gutter))
        .collect::<Option<_>>()?;
    let mut order: Vec<usize> = (0..rects.len()).collect();
    order.sort_by(|&a, &b| {
        (rects[b].1, rects[b].0)
            .cmp(&(rects[a].1, rects[a].0))
            .then(a.cmp(&b))
    });
    let mut placed = vec![(0, 0, 0, 0); rects.len()];
    let (mut x, mut y, mut shelf) = (0u32, 0u32, 0u32);
    for i in order {
        let (w, h) = rects[i];
        if w > width {
            return None;
        }
        if x + w > width {
            y = y.checked_add(shelf)?;
            x = 0;
            shelf = 0;
        }
        if y.checked_add(h)? > max_height {
            return None;
        }
        placed[i] = (x, y, w, h);
        x += w;
        shelf = shelf.max(h);
    }
    Some((placed, y + shelf))
}

/// Rounds up to a multiple of 4 (block-compressed texture formats use 4 × 4 blocks).
fn round4(n: u32) -> u32 {
    n.div_ceil(4) * 4
}

type Packing = (f64, u32, Vec<(u32, u32, u32, u32)>, u32);

/// The largest density whose packing fits `max_side` × `max_side` (bisection; the packing's
/// height is monotone in the density up to shelf effects, and the last fitting density is
/// kept).
fn fit(sizes: &[DVec2], gutter: u32, max_side: u32) -> Result<Packing, ExportError> {
    if !(1..=MAX_ATLAS_SIDE).contains(&max_side) {
        return Err(ExportError::Atlas(format!(
            "atlas side {max_side} must be in 1..={MAX_ATLAS_SIDE}"
        )));
    }
    let Some(mut best) = pack(sizes, 0.0, gutter, max_side, max_side) else {
        return Err(ExportError::Atlas(format!(
            "{} charts do not fit {max_side}×{max_side} texels even at one texel each with a \
             {gutter}-texel gutter; raise the atlas size",
            sizes.len()
        )));
    };
    let mut lo = 0.0;
    let area: f64 = sizes.iter().map(|s| s.x * s.y).sum();
    let longest = sizes.iter().map(|s| s.x).fold(0.0, f64::max);
    let side = f64::from(max_side);
    let mut hi = f64::INFINITY;
    if area > 0.0 {
        hi = hi.min(side / area.sqrt());
    }
    if longest > 0.0 {
        hi = hi.min(side / longest);
    }
    if hi.is_finite() {
        for _ in 0..50 {
            let mid = 0.5 * (lo + hi);
            match pack(sizes, mid, gutter, max_side, max_side) {
                Some(p) => {
                    lo = mid;
                    best = p;
                }
                None => hi = mid,
            }
        }
    }
    let height = round4(best.1).clamp(1, max_side);
    Ok((lo, max_side, best.0, height))
}

/// Packing at a fixed density into a near-square atlas.
fn fixed(sizes: &[DVec2], gutter: u32, density: f64) -> Result<Packing, ExportError> {
    if !(density.is_finite() && density > 0.0) {
        return Err(ExportError::Atlas(format!(
            "texel density {density} texels/m must be finite and > 0"
        )));
    }
    let too_big = || {
        ExportError::Atlas(format!(
            "at {density} texels/m the atlas would exceed {MAX_ATLAS_SIDE}×{MAX_ATLAS_SIDE} \
             texels; lower the density"
        ))
    };
    let mut area = 0.0;
    let mut widest = 1;
    for &s in sizes {
        let (w, h) = rect_size(s, density, gutter).ok_or_else(too_big)?;
        area += f64::from(w) * f64::from(h);
        widest = widest.max(w);
    }
    // Shelf packing wastes some room; 15 % more than the area keeps the atlas near square.
    let width = ((area * 1.15).sqrt().ceil() as u32)
        .max(widest)
        .min(MAX_ATLAS_SIDE);
    let width = round4(width).min(MAX_ATLAS_SIDE);
    let (placed, height) =
        pack(sizes, density, gutter, width, MAX_ATLAS_SIDE).ok_or_else(too_big)?;
    Ok((
        density,
        width,
        placed,
        round4(height).clamp(1, MAX_ATLAS_SIDE),
    ))
}

/// Writes triangle `t` into the texels of its chart's rectangle: texels whose centre is
/// inside get the barycentric interpolation of the vertex radiance; texels within `gutter`
/// texels get the value at the nearest point of the triangle, unless a nearer triangle of the
/// chart already wrote them (`distance` holds each texel's distance to its writer, texels).
fn bake_triangle(
    primitive: &ExportPrimitive,
    t: usize,
    rect: &ChartRect,
    gutter: u32,
    image: &mut Image,
    distance: &mut [f32],
) {
    let (width, height) = (f64::from(image.width), f64::from(image.height));
    let tri = primitive.triangles[t];
    // Texel coordinates from the stored f32 coordinates, so the bake matches what a GPU
    // samples.
    let corner = tri.map(|v| {
        let [u, w] = primitive.uv[v as usize];
        DVec2::new(f64::from(u) * width, f64::from(w) * height)
    });
    let value = tri.map(|v| DVec3::from_array(primitive.radiance[v as usize].map(f64::from)));
    let [a, b, c] = corner;
    let double_area = (b - a).perp_dot(c - a);
    if double_area.abs() < 1e-12 {
        return;
    }
    let reach = f64::from(gutter);
    let lo = a.min(b).min(c) - DVec2::splat(reach);
    let hi = a.max(b).max(c) + DVec2::splat(reach);
    let x0 = (lo.x.floor().max(0.0) as u32).max(rect.x);
    let y0 = (lo.y.floor().max(0.0) as u32).max(rect.y);
    let x1 = (hi.x.ceil().max(0.0) as u32).min(rect.x + rect.width);
    let y1 = (hi.y.ceil().max(0.0) as u32).min(rect.y + rect.height);
    for y in y0..y1 {
        for x in x0..x1 {
            let q = DVec2::new(f64::from(x) + 0.5, f64::from(y) + 0.5);
            let l1 = (c - b).perp_dot(q - b) / double_area;
            let l2 = (a - c).perp_dot(q - c) / double_area;
            let l3 = 1.0 - l1 - l2;
            let (d, radiance) = if l1 >= 0.0 && l2 >= 0.0 && l3 >= 0.0 {
                (0.0, value[0] * l1 + value[1] * l2 + value[2] * l3)
            } else {
                nearest_on_edges(q, corner, value)
            };
            if d > reach {
                continue;
            }
            let k = y as usize * image.width as usize + x as usize;
            let d = d as f32;
            if d < distance[k] {
                distance[k] = d;
                image.pixels[k] = radiance.as_vec3().to_array();
            }
        }
    }
}

/// Distance from `q` to the nearest point of the triangle's edges and the linearly
/// interpolated value there.
fn nearest_on_edges(q: DVec2, corner: [DVec2; 3], value: [DVec3; 3]) -> (f64, DVec3) {
    let mut best = (f64::INFINITY, DVec3::ZERO);
    for k in 0..3 {
        let (a, b) = (corner[k], corner[(k + 1) % 3]);
        let ab = b - a;
        let s = ((q - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0);
        let d = q.distance(a + ab * s);
        if d < best.0 {
            best = (d, value[k] * (1.0 - s) + value[(k + 1) % 3] * s);
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::export::tests::{cornell_baked, corner, linear_radiance};
    use crate::export::{bake, Baked, ExportOptions};

    fn bake_with(scene: &BakedScene, lightmap: LightmapOptions) -> Baked {
        let options = ExportOptions {
            lightmap,
            ..ExportOptions::default()
        };
        bake(scene, &options).unwrap()
    }

    /// The bounding box of a chart's vertices in texel coordinates.
    fn footprint(baked: &Baked, rect: &ChartRect) -> (DVec2, DVec2) {
        let p = &baked.objects[rect.object][rect.primitive];
        let (w, h) = (
            f64::from(baked.lightmap.image.width),
            f64::from(baked.lightmap.image.height),
        );
        let mut lo = DVec2::INFINITY;
        let mut hi = DVec2::NEG_INFINITY;
        for (v, &c) in p.vertex_chart.iter().enumerate() {
            if c == rect.chart {
                let q = DVec2::new(f64::from(p.uv[v][0]) * w, f64::from(p.uv[v][1]) * h);
                lo = lo.min(q);
                hi = hi.max(q);
            }
        }
        (lo, hi)
    }

    #[test]
    fn hull_and_minimum_rectangle_of_a_rotated_rectangle() {
        let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
        let rotate = |x: f64, y: f64| DVec2::new(c * x - s * y, s * x + c * y);
        let mut points = vec![
            rotate(0.0, 0.0),
            rotate(2.0, 0.0),
            rotate(2.0, 1.0),
            rotate(0.0, 1.0),
        ];
        points.push(rotate(1.0, 0.5)); // interior: not on the hull
        points.push(rotate(1.0, 0.0)); // on an edge: collinear, dropped
        assert_eq!(convex_hull(&points).len(), 4);
        let axis = min_area_axis(&points);
        // The 2 × 1 rectangle's own sides: axis at 30° or 120°.
        let along = axis.dot(rotate(1.0, 0.0)).abs();
        assert!((along - 1.0).abs() < 1e-12 || along < 1e-12, "{axis}");
    }

    #[test]
    fn charts_are_packed_without_overlap_inside_the_atlas() {
        let scene = cornell_baked();
        let baked = bake_with(&scene, LightmapOptions::default());
        let lightmap = &baked.lightmap;
        let g = f64::from(lightmap.gutter);
        assert_eq!(lightmap.image.width, 2048);
        assert!(lightmap.image.height <= 2048);
        assert_eq!(lightmap.charts.len(), 20);
        for (i, a) in lightmap.charts.iter().enumerate() {
            assert!(a.x + a.width <= lightmap.image.width);
            assert!(a.y + a.height <= lightmap.image.height);
            for b in &lightmap.charts[i + 1..] {
                let apart = a.x + a.width <= b.x
                    || b.x + b.width <= a.x
                    || a.y + a.height <= b.y
                    || b.y + b.height <= a.y;
                assert!(apart, "{a:?} overlaps {b:?}");
            }
            // The chart's vertices lie in its rectangle inset by the gutter (f32 coordinates:
            // 1e-3 texel of slack at 2048 texels).
            let (lo, hi) = footprint(&baked, a);
            assert!(lo.x >= f64::from(a.x) + g - 1e-3 && lo.y >= f64::from(a.y) + g - 1e-3);
            assert!(hi.x <= f64::from(a.x + a.width) - g + 1e-3);
            assert!(hi.y <= f64::from(a.y + a.height) - g + 1e-3);
        }
        for p in baked.objects.iter().flatten() {
            for uv in &p.uv {
                assert!((0.0..=1.0).contains(&uv[0]) && (0.0..=1.0).contains(&uv[1]));
            }
        }
        // Density: a chart of w metres spans w·d texels (the long side is horizontal).
        let floor = lightmap.charts.iter().find(|r| r.object == 0).unwrap();
        let (lo, hi) = footprint(&baked, floor);
        let d = lightmap.texels_per_metre;
        assert!(
            (hi.x - lo.x - 0.5592 * d).abs() < 0.01,
            "{} vs {}",
            hi.x - lo.x,
            0.5592 * d
        );
        assert!(lightmap.coverage > 0.4, "coverage {}", lightmap.coverage);
    }

    #[test]
    fn fit_density_is_the_largest_that_fits() {
        let scene = cornell_baked();
        let baked = bake_with(
            &scene,
            LightmapOptions {
                size: AtlasSize::Fit { max_side: 512 },
                gutter: 3,
            },
        );
        let d = baked.lightmap.texels_per_metre;
        let mut sizes = Vec::new();
        for (o, primitives) in baked.objects.iter().enumerate() {
            for (p, primitive) in primitives.iter().enumerate() {
                sizes.extend(
                    charts_of(&scene, o, p, primitive)
                        .unwrap()
                        .iter()
                        .map(|c| c.size),
                );
            }
        }
        assert!(pack(&sizes, d, 3, 512, 512).is_some());
        assert!(
            pack(&sizes, d * 1.02, 3, 512, 512).is_none(),
            "density {d} is not tight"
        );
    }

    #[test]
    fn fixed_density_sizes_every_chart() {
        let scene = cornell_baked();
        let baked = bake_with(
            &scene,
            LightmapOptions {
                size: AtlasSize::TexelsPerMetre(200.0),
                gutter: 2,
            },
        );
        let lightmap = &baked.lightmap;
        assert_eq!(lightmap.texels_per_metre, 200.0);
        // The back wall is 0.556 × 0.5488 m: ⌈111.2⌉ + 4 = 116 by ⌈109.76⌉ + 4 = 114.
        let back = scene
            .objects
            .iter()
            .position(|o| o.name == "back_wall")
            .unwrap();
        let rect = lightmap.charts.iter().find(|r| r.object == back).unwrap();
        assert_eq!((rect.width, rect.height), (116, 114));
        assert!(lightmap.image.width % 4 == 0 && lightmap.image.height % 4 == 0);
    }

    #[test]
    fn texels_inside_a_chart_hold_the_interpolated_radiance() {
        let scene = cornell_baked();
        let baked = bake_with(
            &scene,
            LightmapOptions {
                size: AtlasSize::Fit { max_side: 256 },
                gutter: 2,
            },
        );
        let image = &baked.lightmap.image;
        let (w, h) = (f64::from(image.width), f64::from(image.height));
        let mut checked = 0;
        for (o, primitives) in baked.objects.iter().enumerate() {
            let p = &primitives[0];
            let m = &scene.materials[p.material];
            let (rho, le) = (m.reflectance.map(f64::from), m.emission.map(f64::from));
            for tri in &p.triangles {
                let uv = tri.map(|v| {
                    DVec2::new(
                        f64::from(p.uv[v as usize][0]) * w,
                        f64::from(p.uv[v as usize][1]) * h,
                    )
                });
                let pos = tri.map(|v| DVec3::from_array(p.positions[v as usize].map(f64::from)));
                let area = (uv[1] - uv[0]).perp_dot(uv[2] - uv[0]);
                for y in 0..image.height {
                    for x in 0..image.width {
                        let q = DVec2::new(f64::from(x) + 0.5, f64::from(y) + 0.5);
                        let l0 = (uv[2] - uv[1]).perp_dot(q - uv[1]) / area;
                        let l1 = (uv[0] - uv[2]).perp_dot(q - uv[2]) / area;
                        let l2 = 1.0 - l0 - l1;
                        if l0 < 1e-6 || l1 < 1e-6 || l2 < 1e-6 {
                            continue;
                        }
                        // The independent reference: the field at the 3-D point.
                        let point = pos[0] * l0 + pos[1] * l1 + pos[2] * l2;
                        let expected = linear_radiance(rho, le, point);
                        let got = image.get(x, y);
                        for c in 0..3 {
                            // f32 storage of positions, radiance and texel values: ~1e-6
                            // relative; 1e-5 of the value (≤ 20) is ample.
                            assert!(
                                (f64::from(got[c]) - expected[c]).abs()
                                    <= 1e-5 * expected[c].max(1.0),
                                "object {o} texel ({x}, {y}) channel {c}: {} vs {}",
                                got[c],
                                expected[c]
                            );
                        }
                        checked += 1;
                    }
                }
            }
        }
        assert!(checked > 5000, "only {checked} texels checked");
    }

    #[test]
    fn bilinear_taps_around_every_vertex_are_filled() {
        // Every chart has radiance ≥ ρ > 0 in some channel, so a black texel is unfilled.
        let scene = cornell_baked();
        let baked = bake_with(
            &scene,
            LightmapOptions {
                size: AtlasSize::Fit { max_side: 128 },
                gutter: 2,
            },
        );
        let image = &baked.lightmap.image;
        for p in baked.objects.iter().flatten() {
            for uv in &p.uv {
                // Bilinear lookup at uv reads the 2 × 2 texels whose centres surround it.
                let tx = f64::from(uv[0]) * f64::from(image.width) - 0.5;
                let ty = f64::from(uv[1]) * f64::from(image.height) - 0.5;
                for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                    let x = (tx.floor() as i64 + dx) as u32;
                    let y = (ty.floor() as i64 + dy) as u32;
                    let texel = image.get(x, y);
                    assert!(
                        texel.iter().any(|&c| c > 0.0),
                        "unfilled tap ({x}, {y}) for {uv:?}"
                    );
                }
            }
        }
    }

    #[test]
    fn shared_corner_vertices_map_into_both_charts() {
        let baked = bake_with(&corner(), LightmapOptions::default());
        let p = &baked.objects[0][0];
        assert_eq!(baked.lightmap.charts.len(), 2);
        // Copies of one input vertex sit in different rectangles.
        assert_eq!(p.source_vertex[0], p.source_vertex[1]);
        assert!(p.uv[0] != p.uv[1]);
    }

    #[test]
    fn bad_options_and_input_are_errors() {
        let scene = cornell_baked();
        let options = |size, gutter| ExportOptions {
            lightmap: LightmapOptions { size, gutter },
            ..ExportOptions::default()
        };
        for (size, gutter, needle) in [
            (AtlasSize::Fit { max_side: 2048 }, 1, "gutter 1 is below 2"),
            (
                AtlasSize::Fit { max_side: 16 },
                2,
                "20 charts do not fit 16×16",
            ),
            (AtlasSize::Fit { max_side: 0 }, 2, "atlas side 0"),
            (AtlasSize::TexelsPerMetre(-1.0), 2, "texel density -1"),
            (AtlasSize::TexelsPerMetre(1e9), 2, "lower the density"),
        ] {
            let e = bake(&scene, &options(size, gutter)).unwrap_err();
            assert!(e.to_string().contains(needle), "{e}");
        }
        // One chart bent out of its plane.
        let mut scene = corner();
        scene.objects[0].primitives[0].charts = vec![1, 1, 1, 1];
        let e = bake(&scene, &ExportOptions::default())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("object 'corner': primitive 0: chart 1 is not planar"),
            "{e}"
        );
    }

    #[test]
    fn png_is_the_srgb_encoding_after_exposure() {
        let baked = bake_with(&cornell_baked(), LightmapOptions::default());
        let png = baked.lightmap.png_bytes(-2.0).unwrap();
        let decoded = image::load_from_memory(&png).unwrap().to_rgb8();
        let image = &baked.lightmap.image;
        assert_eq!(decoded.dimensions(), (image.width, image.height));
        for (p, q) in image.pixels.iter().zip(decoded.pixels()) {
            assert_eq!(q.0, p.map(|l| srgb_byte(l * 0.25)));
        }
    }
}
