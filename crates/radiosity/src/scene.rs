//! The scene: planar convex surfaces with Lambertian materials, and a camera.
//!
//! Physical conventions (see `tests/reference/README.md`):
//! - reflectance ρ is the Lambertian albedo per RGB channel (BRDF = ρ/π), 0 ≤ ρ < 1;
//! - emission is the emitted radiance L_e in W·m⁻²·sr⁻¹, front side only, so the emitted
//!   exitance (radiosity) is E = π·L_e in W·m⁻²;
//! - a surface is one-sided unless its material is two-sided: a one-sided surface's back is
//!   opaque, black and emits nothing; a two-sided surface reflects on both sides (meshing
//!   gives it a back-to-back twin, see [`crate::mesh`]) and emits from its front only unless
//!   [`Material::two_sided_emission`] is set.
//!
//! Loading from files lives in [`crate::io`]; the built-in Cornell box in [`crate::cornell`].

use crate::geometry::Polygon;
use glam::DVec3;
use std::f64::consts::PI;

/// Index of a material in [`Scene::materials`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct MaterialId(pub u32);

/// Index of a surface in [`Scene::surfaces`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct SurfaceId(pub u32);

/// A Lambertian material.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Material {
    /// The material's name (unique in a scene).
    pub name: String,
    /// Diffuse reflectance ρ per RGB channel (dimensionless, 0 ≤ ρ < 1).
    pub reflectance: [f64; 3],
    /// Emitted radiance L_e per RGB channel, W·m⁻²·sr⁻¹ (front side only).
    pub emission: [f64; 3],
    /// Both sides reflect light (each side with ρ); emission stays on the front side unless
    /// `two_sided_emission` is set. One-sided surfaces (the default) have an opaque, black
    /// back.
    pub two_sided: bool,
    /// With `two_sided`, the back emits L_e too (a lamp panel lit on both faces). Ignored for
    /// one-sided materials.
    pub two_sided_emission: bool,
}

impl Material {
    /// A one-sided material with reflectance ρ and emitted radiance L_e (W·m⁻²·sr⁻¹).
    pub fn new(name: impl Into<String>, reflectance: [f64; 3], emission: [f64; 3]) -> Self {
        Self {
            name: name.into(),
            reflectance,
            emission,
            two_sided: false,
            two_sided_emission: false,
        }
    }

    /// Emitted exitance E = π·L_e, W·m⁻².
    pub fn exitance(&self) -> [f64; 3] {
        self.emission.map(|l| PI * l)
    }

    /// True when any channel emits.
    pub fn is_emitter(&self) -> bool {
        self.emission.iter().any(|&l| l > 0.0)
    }
}

/// Where a surface came from, for error messages.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Origin {
    /// The file, as the user named it.
    pub file: Option<String>,
    /// The 1-based line.
    pub line: Option<usize>,
}

/// One planar convex polygon with a material, belonging to a named object.
#[derive(Debug, Clone, PartialEq)]
pub struct Surface {
    /// Object name (OBJ `o`, else `g`); reports aggregate by it.
    pub object: String,
    /// Surface group (OBJ `g`), informational.
    pub group: String,
    /// Its material.
    pub material: MaterialId,
    /// Its outline, counter-clockwise seen from the lit side, m.
    pub polygon: Polygon,
    /// Where it was defined.
    pub origin: Origin,
}

/// A perspective pinhole camera.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Eye position, m.
    pub eye: DVec3,
    /// Point looked at, m.
    pub target: DVec3,
    /// Up direction.
    pub up: DVec3,
    /// Vertical field of view in degrees (also horizontal for square images).
    pub fov_deg: f64,
}

impl Default for Camera {
    fn default() -> Self {
        Self {
            eye: DVec3::new(0.0, 0.0, -3.0),
            target: DVec3::ZERO,
            up: DVec3::Y,
            fov_deg: 40.0,
        }
    }
}

impl Camera {
    /// A camera that frames the given bounds from the −z side.
    pub fn framing(lo: DVec3, hi: DVec3) -> Self {
        let centre = (lo + hi) * 0.5;
        let radius = ((hi - lo).length() * 0.5).max(1e-6);
        let fov_deg: f64 = 40.0;
        let dist = radius / (fov_deg.to_radians() * 0.5).sin();
        Self {
            eye: centre - DVec3::Z * dist,
            target: centre,
            up: DVec3::Y,
            fov_deg,
        }
    }
}

/// A complete scene: materials, surfaces, light sources and an optional camera.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Scene {
    /// The scene's name (outputs are named after it).
    pub name: String,
    /// Materials, indexed by [`MaterialId`].
    pub materials: Vec<Material>,
    /// Planar convex polygons.
    pub surfaces: Vec<Surface>,
    /// Light sources that are not surfaces (point, spot, goniometric luminaires).
    pub lights: Vec<crate::light::Light>,
    /// The camera stored with the scene, if any.
    pub camera: Option<Camera>,
}

impl Scene {
    /// A surface's material.
    pub fn material(&self, surface: &Surface) -> &Material {
        &self.materials[surface.material.0 as usize]
    }

    /// Axis-aligned bounds of all surfaces.
    pub fn bounds(&self) -> (DVec3, DVec3) {
        self.surfaces.iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), s| {
                let (a, b) = s.polygon.bounds();
                (lo.min(a), hi.max(b))
            },
        )
    }

    /// The scene's camera, or [`crate::viewpoint::default_camera`]: from inside a closed
    /// scene, from the lit side of an open one.
    pub fn camera_or_default(&self) -> Camera {
        self.camera
            .unwrap_or_else(|| crate::viewpoint::default_camera(self))
    }

    /// Total area in m².
    pub fn total_area(&self) -> f64 {
        self.surfaces.iter().map(|s| s.polygon.area()).sum()
    }

    /// Object names in first-appearance order.
    pub fn object_names(&self) -> Vec<String> {
        let mut seen = std::collections::HashSet::new();
        let mut names: Vec<String> = Vec::new();
        for s in &self.surfaces {
            if seen.insert(s.object.as_str()) {
                names.push(s.object.clone());
            }
        }
        names
    }
}
