//! Light sources in the JSON scene file: the `lights` array.
//!
//! ```json
//! "lights": [
//!   { "name": "bulb", "type": "point", "position": [2, 2, 2.5], "flux_lm": 800,
//!     "colour": [1, 0.85, 0.7] },
//!   { "name": "spot", "type": "spot", "position": [1, 1, 3], "target": [1, 1, 0],
//!     "inner_deg": 15, "outer_deg": 30, "intensity_cd": 2000 },
//!   { "name": "L1", "type": "goniometric", "file": "recessed_louvre.ies",
//!     "position": [1.5, 1.5, 2.79], "direction": [0, 0, -1], "c0": [1, 0, 0],
//!     "multiplier": 0.9, "lamp_lumens": 4000 }
//! ]
//! ```
//!
//! Keys (unknown keys are errors; lengths in metres):
//! - `name` (required, unique, non-empty) and `type`: `point` (isotropic), `spot` (a cone
//!   with a smooth falloff: full intensity to `inner_deg`, none beyond `outer_deg`, glTF
//!   `KHR_lights_punctual` semantics, 0 ≤ inner < outer ≤ 90) or `goniometric` (a luminaire
//!   measured in an IES LM-63 `.ies` or EULUMDAT `.ldt` `file`, relative to the scene file).
//! - `position` (required) and the aim: the nadir axis (γ = 0, the spot's axis) as a
//!   `direction` or as a `target` point (default `direction` [0, 0, −1], straight down in a
//!   z-up scene), and `c0`, a direction in the C = 0 half-plane of type C photometry (made
//!   perpendicular to the nadir; default the scene's +x, or +y when the nadir is along x).
//! - How much light, at most one of: `flux_lm` (total luminous flux, lm), `intensity_cd`
//!   (peak luminous intensity, cd: on the axis of a spot, the table's maximum for a
//!   goniometric luminaire) — both with an optional `colour` (linear sRGB, default white;
//!   only its chromaticity counts, see [`crate::units`]) — or `intensity`, radiometric
//!   W·sr⁻¹ per RGB channel per unit of the distribution (per candela of the table for a
//!   goniometric luminaire; this is what a saved scene holds). Point and spot lights need
//!   one; a goniometric luminaire defaults to the file's candela values.
//! - `multiplier` (≥ 0, default 1) scales every intensity (a maintenance or dimming
//!   factor); `lamp_lumens` (goniometric only, for files in relative photometry) states the
//!   lamps actually fitted: intensities scale by lamp_lumens / the file's rated lamp lumens,
//!   as lighting programs do (not with `flux_lm` or `intensity_cd`, which fix the amount).
//!
//! Errors name the file, the light and the key. Saving writes each light back
//! radiometrically (`intensity`, multiplier and lamp lumens folded in) with `direction`,
//! `c0` and the photometric file's absolute path, so a saved scene loads back the same.

use crate::io::error::{Location, SceneError};
use crate::light::{Aim, Distribution, Light};
use crate::photometry::Photometry;
use crate::scene::Origin;
use crate::units::radiometric_from_photometric;
use glam::DVec3;
use serde::{Deserialize, Serialize};
use std::path::Path;
use std::sync::Arc;

/// The kinds of light in the scene file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LightKind {
    /// Isotropic point light.
    Point,
    /// Spot light: a cone with a smooth falloff.
    Spot,
    /// A luminaire from a photometric file.
    Goniometric,
}

/// One entry of the scene file's `lights` array, as written (see the module docs).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LightEntry {
    /// Unique name.
    pub name: String,
    /// Kind.
    #[serde(rename = "type")]
    pub kind: LightKind,
    /// Position, m.
    pub position: [f64; 3],
    /// Nadir direction (γ = 0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub direction: Option<[f64; 3]>,
    /// A point the nadir axis passes through, m.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub target: Option<[f64; 3]>,
    /// A direction in the C = 0 half-plane.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub c0: Option<[f64; 3]>,
    /// Radiometric scale, W·sr⁻¹ per channel per unit of the distribution.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub intensity: Option<[f64; 3]>,
    /// Peak luminous intensity, cd.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub intensity_cd: Option<f64>,
    /// Total luminous flux, lm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub flux_lm: Option<f64>,
    /// Colour (linear sRGB chromaticity) of a photometric amount.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub colour: Option<[f64; 3]>,
    /// Scale of every intensity.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub multiplier: Option<f64>,
    /// Lamp lumens fitted (goniometric, relative photometry).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lamp_lumens: Option<f64>,
    /// Spot: half-angle of the full cone, degrees.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub inner_deg: Option<f64>,
    /// Spot: half-angle beyond which nothing is emitted, degrees.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub outer_deg: Option<f64>,
    /// Goniometric: the `.ies` or `.ldt` file, relative to the scene file.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub file: Option<String>,
}

impl LightEntry {
    /// Builds the light, resolving `file` relative to `dir`; `scene_file` names the scene
    /// file in errors.
    pub fn to_light(&self, dir: &Path, scene_file: &str) -> Result<Light, SceneError> {
        let name = &self.name;
        let fail = |key: &str, problem: String| SceneError::Invalid {
            at: Location::file(scene_file),
            message: format!("light '{name}': '{key}': {problem}"),
        };
        if name.is_empty() {
            return Err(SceneError::Invalid {
                at: Location::file(scene_file),
                message: "a light has an empty name".into(),
            });
        }
        let finite = |key: &str, v: [f64; 3]| {
            if v.iter().all(|x| x.is_finite()) {
                Ok(DVec3::from(v))
            } else {
                Err(fail(key, format!("{v:?} is not finite")))
            }
        };
        let position = finite("position", self.position)?;

        // Keys that belong to one kind only.
        let only = |key: &str, present: bool, kind: LightKind| {
            if present && self.kind != kind {
                Err(fail(
                    key,
                    format!("only a {} light has it", kind_name(kind)),
                ))
            } else {
                Ok(())
            }
        };
        only("inner_deg", self.inner_deg.is_some(), LightKind::Spot)?;
        only("outer_deg", self.outer_deg.is_some(), LightKind::Spot)?;
        only("file", self.file.is_some(), LightKind::Goniometric)?;
        only(
            "lamp_lumens",
            self.lamp_lumens.is_some(),
            LightKind::Goniometric,
        )?;

        // Aim.
        let nadir = match (self.direction, self.target) {
            (Some(_), Some(_)) => {
                return Err(fail(
                    "target",
                    "give either 'direction' or 'target', not both".into(),
                ))
            }
            (Some(d), None) => finite("direction", d)?,
            (None, Some(t)) => finite("target", t)? - position,
            (None, None) => DVec3::NEG_Z,
        };
        let nadir_key = if self.target.is_some() {
            "target"
        } else {
            "direction"
        };
        if nadir.length().is_nan() || nadir.length() <= 0.0 {
            return Err(fail(
                nadir_key,
                "the aiming direction is zero (a target at the light's position?)".into(),
            ));
        }
        let aim = match self.c0 {
            Some(c0) => Aim::new(nadir, finite("c0", c0)?)
                .ok_or_else(|| fail("c0", "is zero or parallel to the nadir direction".into()))?,
            None => Aim::new(nadir, DVec3::X)
                .filter(|a| a.nadir.cross(DVec3::X).length() > 1e-6)
                .or_else(|| Aim::new(nadir, DVec3::Y))
                .ok_or_else(|| fail(nadir_key, "cannot be aimed".into()))?,
        };

        // Distribution.
        let distribution = match self.kind {
            LightKind::Point => Distribution::Isotropic,
            LightKind::Spot => {
                let inner = self
                    .inner_deg
                    .ok_or_else(|| fail("inner_deg", "a spot light needs it".into()))?;
                let outer = self
                    .outer_deg
                    .ok_or_else(|| fail("outer_deg", "a spot light needs it".into()))?;
                if !(inner.is_finite() && inner >= 0.0) {
                    return Err(fail("inner_deg", format!("{inner} must be ≥ 0")));
                }
                if !(outer.is_finite() && outer > inner && outer <= 90.0) {
                    return Err(fail(
                        "outer_deg",
                        format!("{outer} must be greater than inner_deg ({inner}) and at most 90"),
                    ));
                }
                Distribution::Spot {
                    inner_deg: inner,
                    outer_deg: outer,
                }
            }
            LightKind::Goniometric => {
                let file = self.file.as_ref().ok_or_else(|| {
                    fail(
                        "file",
                        "a goniometric light needs an .ies or .ldt file".into(),
                    )
                })?;
                let table = crate::photometry::load(&dir.join(file))
                    .map_err(|e| fail("file", e.to_string()))?;
                if table.flux().is_nan() || table.flux() <= 0.0 {
                    return Err(fail("file", format!("{file} emits no light")));
                }
                Distribution::Goniometric(Arc::new(table))
            }
        };

        // Amount.
        let amounts = [
            ("intensity", self.intensity.is_some()),
            ("intensity_cd", self.intensity_cd.is_some()),
            ("flux_lm", self.flux_lm.is_some()),
        ];
        if let [(first, _), (second, _), ..] = amounts
            .iter()
            .filter(|(_, present)| *present)
            .collect::<Vec<_>>()[..]
        {
            return Err(fail(
                second,
                format!("give only one of 'intensity', 'intensity_cd', 'flux_lm' (also '{first}')"),
            ));
        }
        if self.colour.is_some() && self.intensity.is_some() {
            return Err(fail(
                "colour",
                "goes with 'intensity_cd' or 'flux_lm'; 'intensity' is already per channel".into(),
            ));
        }
        if self.lamp_lumens.is_some() && (self.intensity_cd.is_some() || self.flux_lm.is_some()) {
            return Err(fail(
                "lamp_lumens",
                "cannot be combined with 'intensity_cd' or 'flux_lm', which fix the amount".into(),
            ));
        }
        let colour = self.colour.unwrap_or([1.0; 3]);
        let photometric = |key: &str, value: f64| {
            radiometric_from_photometric(value, colour).map_err(|e| fail(key, e.to_string()))
        };
        let mut intensity = match (self.intensity, self.intensity_cd, self.flux_lm) {
            (Some(i), _, _) => {
                if i.iter().any(|x| !(x.is_finite() && *x >= 0.0)) {
                    return Err(fail(
                        "intensity",
                        format!("{i:?} must be finite and ≥ 0 in every channel"),
                    ));
                }
                i
            }
            (_, Some(cd), _) => photometric("intensity_cd", cd)?.map(|v| v / distribution.peak()),
            (_, _, Some(lm)) => photometric("flux_lm", lm)?.map(|v| v / distribution.integral()),
            (None, None, None) => match self.kind {
                LightKind::Goniometric => photometric("colour", 1.0)?,
                _ => {
                    return Err(fail(
                        "intensity_cd",
                        format!(
                            "a {} light needs one of 'flux_lm', 'intensity_cd', 'intensity'",
                            kind_name(self.kind)
                        ),
                    ))
                }
            },
        };
        if let Some(m) = self.multiplier {
            if !(m.is_finite() && m >= 0.0) {
                return Err(fail("multiplier", format!("{m} must be finite and ≥ 0")));
            }
            intensity = intensity.map(|i| i * m);
        }
        if let Some(lamps) = self.lamp_lumens {
            if !(lamps.is_finite() && lamps > 0.0) {
                return Err(fail("lamp_lumens", format!("{lamps} must be positive")));
            }
            let rated = match &distribution {
                Distribution::Goniometric(t) => t.lamp_lumens,
                _ => None,
            };
            let Some(rated) = rated.filter(|r| *r > 0.0) else {
                return Err(fail(
                    "lamp_lumens",
                    "the file is in absolute photometry (no rated lamp lumens to scale)".into(),
                ));
            };
            intensity = intensity.map(|i| i * lamps / rated);
        }
        Ok(Light {
            name: name.clone(),
            position,
            aim,
            distribution,
            intensity,
            origin: Origin {
                file: Some(scene_file.to_owned()),
                line: None,
            },
        })
    }

    /// The entry that loads back as `light`: radiometric `intensity`, `direction` and `c0`,
    /// and for a goniometric light its file's absolute path.
    pub fn from_light(light: &Light) -> Self {
        let (kind, inner_deg, outer_deg, file) = match &light.distribution {
            Distribution::Isotropic => (LightKind::Point, None, None, None),
            Distribution::Spot {
                inner_deg,
                outer_deg,
            } => (LightKind::Spot, Some(*inner_deg), Some(*outer_deg), None),
            Distribution::Goniometric(table) => {
                (LightKind::Goniometric, None, None, Some(absolute(table)))
            }
        };
        Self {
            name: light.name.clone(),
            kind,
            position: light.position.to_array(),
            direction: Some(light.aim.nadir.to_array()),
            target: None,
            c0: Some(light.aim.c0.to_array()),
            intensity: Some(light.intensity),
            intensity_cd: None,
            flux_lm: None,
            colour: None,
            multiplier: None,
            lamp_lumens: None,
            inner_deg,
            outer_deg,
            file,
        }
    }
}

/// The photometric file's path made absolute (against the working directory), so a scene
/// saved elsewhere still finds it.
fn absolute(table: &Photometry) -> String {
    let path = Path::new(&table.file);
    std::path::absolute(path)
        .unwrap_or_else(|_| path.to_path_buf())
        .display()
        .to_string()
}

fn kind_name(kind: LightKind) -> &'static str {
    match kind {
        LightKind::Point => "point",
        LightKind::Spot => "spot",
        LightKind::Goniometric => "goniometric",
    }
}

/// Builds every light of a scene file's `lights` array; names must be unique.
pub fn lights_from_entries(
    entries: &[LightEntry],
    dir: &Path,
    scene_file: &str,
) -> Result<Vec<Light>, SceneError> {
    let mut lights: Vec<Light> = Vec::with_capacity(entries.len());
    for entry in entries {
        if lights.iter().any(|l| l.name == entry.name) {
            return Err(SceneError::Invalid {
                at: Location::file(scene_file),
                message: format!("light '{}': 'name': defined twice", entry.name),
            });
        }
        lights.push(entry.to_light(dir, scene_file)?);
    }
    Ok(lights)
}
