//! Measurement: illuminance at point sensors and on rectangular work-plane grids, gathered at
//! each point from the solution — not interpolated from element values.
//!
//! At a point x with unit normal n (the side that receives) the irradiance is, per RGB
//! channel (W·m⁻²),
//!
//!   E(x) = Σ_lights I(ω) cos θ / d² · V   +   Σ_elements B_j F_{dx→j} V_j,
//!
//! the first term exactly by [`crate::direct::point_irradiance`] (shadow rays to every light),
//! the second from every element's radiosity B_j (emission included) with the exact
//! differential-area-to-polygon factor F (Lambert's contour formula, clipped to the
//! hemisphere above x; [`crate::formfactor::analytic_point::point_to_polygon`]) times its
//! visible part: shadow rays from x to five probes of the element (its centroid and its
//! corners pulled 2 % towards it); when they disagree the element is split in four and each
//! piece is tested again, down to 4 levels (256 pieces), below which the piece counts with
//! the fraction of its probes that are visible. Illuminance is E_v = 683 · Y(E) lx
//! ([`crate::units`]).
//!
//! Grids ([`GridSpec`]): a work plane at height h above an object's polygons (the floor by
//! default), points at the centres of the cells of its bounding rectangle, on axes along the
//! longest edge of the object's largest polygon and across it. The number of points along a
//! side of length L is the nearest whole number to L/p, at least 1, where p is the given
//! spacing or EN 12464-1's p = 0.2 · 5^log10(d) m (d the longer side, capped at 10 m); the
//! spacing then adjusts to fill L exactly. An optional border is left out on every side
//! (EN 12464-1 excludes a 0.5 m band along walls from task areas); points whose foot is not
//! on the object are dropped. Statistics ([`GridStats`]): Emin, Ē (mean of the points), Emax,
//! the uniformity U0 = Emin/Ē and Emin/Emax, in lx.

use crate::accel::Visibility;
use crate::formfactor::analytic_point::point_to_polygon;
use crate::geometry::{newell, subdivide};
use crate::light::Light;
use crate::mesh::Mesh;
use crate::scene::Scene;
use crate::units::lux_from_irradiance;
use glam::DVec3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Deepest split of an element whose probes disagree.
const MAX_VISIBILITY_DEPTH: u32 = 4;
/// How far corner probes are pulled towards the centroid (so that rays do not graze the
/// neighbouring surfaces at a shared edge).
const PROBE_INSET: f64 = 0.02;

/// Why a measurement could not be made.
#[derive(Debug, thiserror::Error)]
pub enum MeasureError {
    /// The points file could not be read.
    #[error("{file}: cannot read: {source}")]
    Read {
        /// The file as named.
        file: String,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// The points file is not valid JSON or not of the expected shape.
    #[error("{file}: line {line}, column {column}: {message}")]
    Json {
        /// The file as named.
        file: String,
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// What is wrong.
        message: String,
    },
    /// A point with an unusable value.
    #[error("{file}: point '{point}': '{key}': {message}")]
    Point {
        /// The file as named.
        file: String,
        /// The point's name (or its index).
        point: String,
        /// The key.
        key: &'static str,
        /// What is wrong.
        message: String,
    },
    /// A grid specification that does not parse or makes no sense.
    #[error("--grid '{spec}': {message}")]
    Grid {
        /// The specification as given.
        spec: String,
        /// What is wrong.
        message: String,
    },
}

/// A point sensor: where, and which way its receiving side faces.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Sensor {
    /// Name (reports name points by it).
    pub name: String,
    /// Position, m.
    pub position: [f64; 3],
    /// Normal of the receiving side (any length > 0).
    pub normal: [f64; 3],
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PointsFile {
    points: Vec<Sensor>,
}

/// Reads `{"points": [{"name": "A", "position": [x, y, z], "normal": [x, y, z]}, …]}`.
/// Errors name the file, and the line and column or the point and key.
pub fn load_points(path: &Path) -> Result<Vec<Sensor>, MeasureError> {
    let file = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|source| MeasureError::Read {
        file: file.clone(),
        source,
    })?;
    parse_points(&text, &file)
}

/// Parses a points file held in memory; `file` names it in errors.
pub fn parse_points(text: &str, file: &str) -> Result<Vec<Sensor>, MeasureError> {
    let parsed: PointsFile = serde_json::from_str(text.strip_prefix('\u{feff}').unwrap_or(text))
        .map_err(|e| {
            let message = e.to_string();
            let suffix = format!(" at line {} column {}", e.line(), e.column());
            MeasureError::Json {
                file: file.to_owned(),
                line: e.line(),
                column: e.column(),
                message: message.strip_suffix(&suffix).unwrap_or(&message).to_owned(),
            }
        })?;
    for (i, p) in parsed.points.iter().enumerate() {
        let point = if p.name.is_empty() {
            format!("#{}", i + 1)
        } else {
            p.name.clone()
        };
        let bad = |key: &'static str, message: &str| MeasureError::Point {
            file: file.to_owned(),
            point: point.clone(),
            key,
            message: message.to_owned(),
        };
        if p.name.is_empty() {
            return Err(bad("name", "is empty"));
        }
        if p.position.iter().any(|x| !x.is_finite()) {
            return Err(bad("position", "is not finite"));
        }
        let n = DVec3::from(p.normal);
        if !(n.is_finite() && n.length() > 0.0) {
            return Err(bad("normal", "must be finite and non-zero"));
        }
        if parsed.points[..i].iter().any(|q| q.name == p.name) {
            return Err(bad("name", "is used twice"));
        }
    }
    Ok(parsed.points)
}

/// Irradiance at arbitrary points from a solved mesh and the scene's lights.
pub struct Gatherer<'a> {
    mesh: &'a Mesh,
    radiosity: &'a [[f64; 3]],
    lights: &'a [Light],
    vis: Visibility,
    corners: Vec<Vec<DVec3>>,
}

impl<'a> Gatherer<'a> {
    /// Prepares the gather: the visibility over the mesh's surfaces and every element's
    /// corners. `radiosity` is the solution's B per element, W·m⁻².
    pub fn new(mesh: &'a Mesh, radiosity: &'a [[f64; 3]], lights: &'a [Light]) -> Self {
        Self {
            mesh,
            radiosity,
            lights,
            vis: Visibility::new(mesh),
            corners: mesh
                .elements
                .iter()
                .map(|e| mesh.element_corners(e))
                .collect(),
        }
    }

    /// Irradiance at `x` on a receiver facing `n` (any length), W·m⁻² per channel: direct
    /// from the lights plus gathered from every element (module docs).
    pub fn irradiance(&self, x: DVec3, n: DVec3) -> [f64; 3] {
        let n = n.normalize();
        let mut e = self.direct(x, n);
        for (i, el) in self.mesh.elements.iter().enumerate() {
            let b = self.radiosity[i];
            if b.iter().all(|&v| v == 0.0) {
                continue;
            }
            let f = self.visible_factor(x, n, &self.corners[i], el.normal, 0);
            if f > 0.0 {
                for c in 0..3 {
                    e[c] += b[c] * f;
                }
            }
        }
        e
    }

    /// Irradiance at `x` (unit `n`) straight from the lights, W·m⁻² per channel.
    pub fn direct(&self, x: DVec3, n: DVec3) -> [f64; 3] {
        crate::direct::point_irradiance(self.lights, &self.vis, x, n)
    }

    /// F from the differential area at x to the visible part of `poly` (module docs).
    fn visible_factor(&self, x: DVec3, n: DVec3, poly: &[DVec3], pn: DVec3, depth: u32) -> f64 {
        let f = point_to_polygon(x, n, poly, pn);
        if f <= 0.0 {
            return 0.0;
        }
        let centre = poly.iter().copied().sum::<DVec3>() / poly.len() as f64;
        let probes =
            std::iter::once(centre).chain(poly.iter().map(|&v| v + (centre - v) * PROBE_INSET));
        let (mut seen, mut total) = (0usize, 0usize);
        for y in probes {
            if (y - x).dot(n) <= 0.0 {
                continue;
            }
            total += 1;
            seen += usize::from(self.vis.visible(x, n, y, pn));
        }
        if total == 0 {
            // Every probe below the horizon: the sliver above it is tiny; count it as seen
            // from the centre ray's answer.
            return if self.vis.visible(x, n, centre, pn) {
                f
            } else {
                0.0
            };
        }
        if seen == total {
            return f;
        }
        if depth >= MAX_VISIBILITY_DEPTH {
            return f * seen as f64 / total as f64;
        }
        if seen == 0 && depth >= 1 {
            // Hidden from every probe of a piece that is already a quarter or less: count
            // it hidden (a sliver of light through a gap narrower than the piece is lost).
            return 0.0;
        }
        subdivide(poly, 2)
            .iter()
            .map(|piece| self.visible_factor(x, n, piece, pn, depth + 1))
            .sum()
    }

    /// Readings at every sensor (in parallel).
    pub fn read(&self, sensors: &[Sensor]) -> Vec<Reading> {
        sensors
            .par_iter()
            .map(|s| {
                let (x, n) = (DVec3::from(s.position), DVec3::from(s.normal));
                let irradiance = self.irradiance(x, n);
                Reading {
                    name: s.name.clone(),
                    position: s.position,
                    normal: n.normalize().to_array(),
                    irradiance,
                    illuminance: lux_from_irradiance(irradiance),
                }
            })
            .collect()
    }
}

/// One sensor's result.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Reading {
    /// The sensor's name.
    pub name: String,
    /// Position, m.
    pub position: [f64; 3],
    /// Unit normal of the receiving side.
    pub normal: [f64; 3],
    /// Irradiance per RGB channel, W·m⁻².
    pub irradiance: [f64; 3],
    /// Illuminance, lx (683 · Y(irradiance)).
    pub illuminance: f64,
}

/// A work-plane grid, as given on the command line:
/// `height=H[,spacing=P][,surface=NAME][,border=B]` (metres).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GridSpec {
    /// Height of the work plane above the surface, m.
    pub height: f64,
    /// Point spacing, m; `None`: EN 12464-1's p = 0.2 · 5^log10(d).
    pub spacing: Option<f64>,
    /// The object the grid lies over; `None`: the largest object facing up (+z, else +y).
    pub surface: Option<String>,
    /// Band left out along every side, m.
    pub border: f64,
}

impl GridSpec {
    /// Parses `height=0.75,spacing=0.25[,surface=NAME][,border=0.5]`.
    pub fn parse(spec: &str) -> Result<Self, MeasureError> {
        let fail = |message: String| MeasureError::Grid {
            spec: spec.to_owned(),
            message,
        };
        let (mut height, mut spacing, mut surface, mut border) = (None, None, None, 0.0);
        for part in spec.split(',').map(str::trim).filter(|p| !p.is_empty()) {
            let Some((key, value)) = part.split_once('=') else {
                return Err(fail(format!("'{part}' is not key=value")));
            };
            let (key, value) = (key.trim(), value.trim());
            let number = |what: &str| -> Result<f64, MeasureError> {
                value
                    .parse::<f64>()
                    .ok()
                    .filter(|v| v.is_finite())
                    .ok_or_else(|| fail(format!("{what} '{value}' is not a finite number")))
            };
            match key {
                "height" => height = Some(number("height")?),
                "spacing" => {
                    let s = number("spacing")?;
                    if s <= 0.0 {
                        return Err(fail(format!("spacing {s} must be positive")));
                    }
                    spacing = Some(s);
                }
                "surface" => {
                    if value.is_empty() {
                        return Err(fail("surface is empty".into()));
                    }
                    surface = Some(value.to_owned());
                }
                "border" => {
                    border = number("border")?;
                    if border < 0.0 {
                        return Err(fail(format!("border {border} must be ≥ 0")));
                    }
                }
                other => {
                    return Err(fail(format!(
                        "unknown key '{other}' (expected height, spacing, surface, border)"
                    )))
                }
            }
        }
        let height = height.ok_or_else(|| fail("height=METRES is required".into()))?;
        Ok(Self {
            height,
            spacing,
            surface,
            border,
        })
    }
}

/// EN 12464-1's maximum grid spacing for an area whose longer side is `d` metres:
/// p = 0.2 · 5^log10(d), capped at 10 m.
pub fn en12464_spacing(d: f64) -> f64 {
    (0.2 * 5f64.powf(d.max(1e-9).log10())).min(10.0)
}

/// The points of a grid, before measuring.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GridLayout {
    /// The object the grid lies over.
    pub surface: String,
    /// Unit normal of the work plane (the receiving side).
    pub normal: [f64; 3],
    /// Unit vector along the grid's rows (index i).
    pub u_axis: [f64; 3],
    /// Unit vector along its columns (index j).
    pub v_axis: [f64; 3],
    /// Cells along u and v.
    pub counts: [usize; 2],
    /// Spacing along u and v, m.
    pub spacing: [f64; 2],
    /// Points: (i, j, position). Cells whose centre is off the surface have none.
    pub points: Vec<(usize, usize, [f64; 3])>,
}

/// Lays out a grid over `spec.surface` of `scene` (see the module docs).
pub fn layout_grid(scene: &Scene, spec: &GridSpec) -> Result<GridLayout, MeasureError> {
    let text = format!(
        "height={}{}{}",
        spec.height,
        spec.spacing
            .map(|s| format!(",spacing={s}"))
            .unwrap_or_default(),
        spec.surface
            .as_ref()
            .map(|s| format!(",surface={s}"))
            .unwrap_or_default()
    );
    let fail = |message: String| MeasureError::Grid {
        spec: text.clone(),
        message,
    };
    let object = match &spec.surface {
        Some(name) => {
            if !scene.surfaces.iter().any(|s| &s.object == name) {
                return Err(fail(format!("the scene has no object '{name}'")));
            }
            name.clone()
        }
        None => default_floor(scene).ok_or_else(|| {
            fail("the scene has no object facing up (+z or +y); name one with surface=NAME".into())
        })?,
    };
    let polygons: Vec<&[DVec3]> = scene
        .surfaces
        .iter()
        .filter(|s| s.object == object)
        .map(|s| s.polygon.vertices())
        .collect();
    // The plane and axes from the largest polygon.
    let largest = polygons
        .iter()
        .max_by(|a, b| newell(a).1.total_cmp(&newell(b).1))
        .copied()
        .unwrap_or(&[]);
    let (normal, _) = newell(largest);
    for p in &polygons {
        let (n, _) = newell(p);
        if n.dot(normal) < 1.0 - 1e-9 || (p[0] - largest[0]).dot(normal).abs() > 1e-6 {
            return Err(fail(format!(
                "object '{object}' is not one plane facing one way; a grid needs a flat surface"
            )));
        }
    }
    let longest = largest
        .iter()
        .zip(largest.iter().cycle().skip(1))
        .map(|(a, b)| *b - *a)
        .max_by(|a, b| a.length().total_cmp(&b.length()))
        .unwrap_or(DVec3::X);
    let u = (longest - normal * longest.dot(normal)).normalize();
    let v = normal.cross(u);
    let origin = largest[0];
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for p in &polygons {
        for q in p.iter() {
            let d = *q - origin;
            let c = [d.dot(u), d.dot(v)];
            for k in 0..2 {
                lo[k] = lo[k].min(c[k]);
                hi[k] = hi[k].max(c[k]);
            }
        }
    }
    for k in 0..2 {
        lo[k] += spec.border;
        hi[k] -= spec.border;
    }
    let size = [hi[0] - lo[0], hi[1] - lo[1]];
    if !(size[0] > 0.0 && size[1] > 0.0) {
        return Err(fail(format!(
            "the border {} m leaves nothing of '{object}'",
            spec.border
        )));
    }
    let p = spec
        .spacing
        .unwrap_or_else(|| en12464_spacing(size[0].max(size[1])));
    let counts = size.map(|l| ((l / p).round() as usize).max(1));
    let limit = 1_000_000;
    if counts[0].saturating_mul(counts[1]) > limit {
        return Err(fail(format!(
            "{} × {} points is more than {limit}; use a larger spacing",
            counts[0], counts[1]
        )));
    }
    let spacing = [size[0] / counts[0] as f64, size[1] / counts[1] as f64];
    let mut points = Vec::new();
    for i in 0..counts[0] {
        for j in 0..counts[1] {
            let a = lo[0] + (i as f64 + 0.5) * spacing[0];
            let b = lo[1] + (j as f64 + 0.5) * spacing[1];
            let foot = origin + u * a + v * b;
            if polygons.iter().any(|p| contains(p, normal, foot)) {
                let x = foot + normal * spec.height;
                points.push((i, j, x.to_array()));
            }
        }
    }
    if points.is_empty() {
        return Err(fail(format!("no grid point falls on '{object}'")));
    }
    Ok(GridLayout {
        surface: object,
        normal: normal.to_array(),
        u_axis: u.to_array(),
        v_axis: v.to_array(),
        counts,
        spacing,
        points,
    })
}

/// The object facing up (+z first, else +y) with the largest area.
fn default_floor(scene: &Scene) -> Option<String> {
    for up in [DVec3::Z, DVec3::Y] {
        let mut areas: Vec<(String, f64)> = Vec::new();
        for s in &scene.surfaces {
            if s.polygon.normal().dot(up) > 1.0 - 1e-6 {
                match areas.iter_mut().find(|(o, _)| *o == s.object) {
                    Some((_, a)) => *a += s.polygon.area(),
                    None => areas.push((s.object.clone(), s.polygon.area())),
                }
            }
        }
        if let Some((name, _)) = areas.into_iter().max_by(|a, b| a.1.total_cmp(&b.1)) {
            return Some(name);
        }
    }
    None
}

/// Whether `x` (in the plane) lies in the convex polygon `p` with normal `n` (edges
/// included).
fn contains(p: &[DVec3], n: DVec3, x: DVec3) -> bool {
    let scale = p.iter().map(|v| v.distance(p[0])).fold(0.0, f64::max);
    (0..p.len()).all(|k| {
        let (a, b) = (p[k], p[(k + 1) % p.len()]);
        (b - a).cross(x - a).dot(n) >= -1e-12 * scale * scale
    })
}

/// Illuminance statistics of a grid, lx.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GridStats {
    /// Number of points.
    pub points: usize,
    /// Smallest illuminance, lx.
    pub e_min: f64,
    /// Mean illuminance Ē (of the points), lx.
    pub e_mean: f64,
    /// Largest illuminance, lx.
    pub e_max: f64,
    /// Uniformity U0 = Emin / Ē.
    pub u0: f64,
    /// Emin / Emax.
    pub min_over_max: f64,
}

impl GridStats {
    /// The statistics of a set of illuminances (lx); zeros for an empty set.
    pub fn of(values: &[f64]) -> Self {
        if values.is_empty() {
            return Self {
                points: 0,
                e_min: 0.0,
                e_mean: 0.0,
                e_max: 0.0,
                u0: 0.0,
                min_over_max: 0.0,
            };
        }
        let e_min = values.iter().copied().fold(f64::INFINITY, f64::min);
        let e_max = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let e_mean = values.iter().sum::<f64>() / values.len() as f64;
        let ratio = |a: f64, b: f64| if b > 0.0 { a / b } else { 0.0 };
        Self {
            points: values.len(),
            e_min,
            e_mean,
            e_max,
            u0: ratio(e_min, e_mean),
            min_over_max: ratio(e_min, e_max),
        }
    }
}

/// One grid point's result.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GridPoint {
    /// Cell index along u.
    pub i: usize,
    /// Cell index along v.
    pub j: usize,
    /// Position, m.
    pub position: [f64; 3],
    /// Irradiance per RGB channel, W·m⁻².
    pub irradiance: [f64; 3],
    /// Illuminance, lx.
    pub illuminance: f64,
}

/// A measured grid.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GridResult {
    /// The grid's name (`grid1`, `grid2`, … in command-line order).
    pub name: String,
    /// What was asked for.
    pub spec: GridSpec,
    /// Where the points are.
    pub layout: GridLayout,
    /// Emin, Ē, Emax, U0, Emin/Emax (lx).
    pub stats: GridStats,
    /// Every point.
    pub points: Vec<GridPoint>,
}

impl GridResult {
    /// Measures the points of `layout` with `gatherer`.
    pub fn measure(name: &str, spec: &GridSpec, layout: GridLayout, gatherer: &Gatherer) -> Self {
        let n = DVec3::from(layout.normal);
        let points: Vec<GridPoint> = layout
            .points
            .par_iter()
            .map(|&(i, j, p)| {
                let irradiance = gatherer.irradiance(DVec3::from(p), n);
                GridPoint {
                    i,
                    j,
                    position: p,
                    irradiance,
                    illuminance: lux_from_irradiance(irradiance),
                }
            })
            .collect();
        let values: Vec<f64> = points.iter().map(|p| p.illuminance).collect();
        Self {
            name: name.to_owned(),
            spec: spec.clone(),
            stats: GridStats::of(&values),
            layout,
            points,
        }
    }

    /// The grid as CSV: a header, then one line per point
    /// `i,j,x,y,z,illuminance_lx,irradiance_r,irradiance_g,irradiance_b` (m, lx, W·m⁻²).
    pub fn to_csv(&self) -> String {
        let mut out = String::from(
            "i,j,x_m,y_m,z_m,illuminance_lx,irradiance_r_W_m2,irradiance_g_W_m2,irradiance_b_W_m2\n",
        );
        for p in &self.points {
            out.push_str(&format!(
                "{},{},{},{},{},{},{},{},{}\n",
                p.i,
                p.j,
                p.position[0],
                p.position[1],
                p.position[2],
                p.illuminance,
                p.irradiance[0],
                p.irradiance[1],
                p.irradiance[2]
            ));
        }
        out
    }

    /// Illuminance (lx) per cell, row-major over (j, i) — `values[j * counts[0] + i]` — with
    /// NaN where the cell has no point.
    pub fn raster(&self) -> Vec<f64> {
        let [nu, nv] = self.layout.counts;
        let mut values = vec![f64::NAN; nu * nv];
        for p in &self.points {
            values[p.j * nu + p.i] = p.illuminance;
        }
        values
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_specs_parse_and_name_what_is_wrong() {
        let g = GridSpec::parse("height=0.75,spacing=0.25,surface=floor").unwrap();
        assert_eq!(g.height, 0.75);
        assert_eq!(g.spacing, Some(0.25));
        assert_eq!(g.surface.as_deref(), Some("floor"));
        assert_eq!(GridSpec::parse("height=0").unwrap().spacing, None);
        for (bad, says) in [
            ("spacing=0.25", "height"),
            ("height=x", "'x'"),
            ("height=1,spacing=-1", "positive"),
            ("height=1,colour=red", "unknown key 'colour'"),
            ("height", "key=value"),
        ] {
            let e = GridSpec::parse(bad).unwrap_err().to_string();
            assert!(e.contains("--grid") && e.contains(says), "{bad}: {e}");
        }
    }

    /// EN 12464-1: p = 0.2 · 5^log10(d): 0.2 m at 1 m, 1 m at 10 m, 5 m at 100 m.
    #[test]
    fn en12464_spacing_formula() {
        for (d, p) in [(1.0, 0.2), (10.0, 1.0), (100.0, 5.0), (1000.0, 10.0)] {
            assert!((en12464_spacing(d) - p).abs() < 1e-12, "{d}");
        }
    }

    #[test]
    fn stats_are_min_mean_max_and_ratios() {
        let s = GridStats::of(&[300.0, 500.0, 700.0]);
        assert_eq!((s.e_min, s.e_mean, s.e_max), (300.0, 500.0, 700.0));
        assert!((s.u0 - 0.6).abs() < 1e-15 && (s.min_over_max - 300.0 / 700.0).abs() < 1e-15);
    }

    #[test]
    fn points_files_report_file_point_and_key() {
        let ok = r#"{"points": [{"name": "A", "position": [1, 2, 3], "normal": [0, 0, 1]}]}"#;
        assert_eq!(parse_points(ok, "p.json").unwrap().len(), 1);
        let e = parse_points(
            r#"{"points": [{"name": "A", "position": [1, 2, 3], "normal": [0, 0, 0]}]}"#,
            "p.json",
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("p.json") && e.contains("'A'") && e.contains("normal"),
            "{e}"
        );
        let e = parse_points(r#"{"points": [{"name": "A"}]}"#, "p.json")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("p.json: line 1") && e.contains("position"),
            "{e}"
        );
    }
}
