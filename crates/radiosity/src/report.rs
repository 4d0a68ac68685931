//! The solution report: per-object area averages and power totals, in physical units.
//!
//! Per object (OBJ `o` name): area (m²), reflectance ρ and emitted exitance E = π·L_e
//! (W·m⁻², area-averaged), radiosity B and irradiance H (W·m⁻², area-averaged) and absorbed
//! power Σ(1 − ρ)·H·A (W). Totals: emitted, absorbed and escaped power (W) per channel,
//! element count, solver, iterations, residual and seconds. Energy balance:
//! emitted = absorbed + escaped (+ unshot, for an unconverged progressive solution); the
//! emitted power includes the flux of the light sources (point, spot, goniometric), whose
//! light that lands on no surface counts as escaped.
//!
//! Photometric values stand next to the radiometric ones: illuminance (lx) next to the
//! irradiance, luminance (cd/m²) next to the radiosity, luminous flux (lm) next to each
//! power, by the convention of [`crate::units`]: photometric = 683 lm/W × Y, the luminance
//! Y = 0.2126 R + 0.7152 G + 0.0722 B of the linear-sRGB (BT.709, D65) channel values. The
//! luminance of a Lambertian surface is its radiosity / π.

use crate::light::{Distribution, Light};
use crate::mesh::Mesh;
use crate::solve::Solution;
use crate::units::{lux_from_irradiance, nits_from_radiance, LUMINOUS_EFFICACY};
use serde::{Deserialize, Serialize};

/// One object's line in the report.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ObjectReport {
    /// Object name.
    pub name: String,
    /// m²
    pub area: f64,
    /// Area-weighted mean reflectance ρ per channel.
    pub reflectance: [f64; 3],
    /// W·m⁻²
    pub emitted_exitance: [f64; 3],
    /// W·m⁻², area-averaged
    pub radiosity: [f64; 3],
    /// W·m⁻², area-averaged
    pub irradiance: [f64; 3],
    /// W
    pub absorbed_power: [f64; 3],
    /// lx: illuminance of the area-averaged irradiance, 683 · Y(irradiance).
    #[serde(default)]
    pub illuminance_lx: f64,
    /// cd/m²: luminance of the area-averaged radiosity, 683 · Y(radiosity) / π.
    #[serde(default)]
    pub luminance_cd_m2: f64,
}

/// Scene-wide totals.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Totals {
    /// W
    pub emitted_power: [f64; 3],
    /// W
    pub absorbed_power: [f64; 3],
    /// W: power leaving the scene without landing on any surface.
    pub escaped_power: [f64; 3],
    /// W: power still waiting to be shot (progressive solver; 0 otherwise).
    pub unshot_power: [f64; 3],
    /// Elements in the mesh.
    pub elements: usize,
    /// Patches in the mesh.
    pub patches: usize,
    /// The solver.
    pub solver: String,
    /// The form-factor method.
    pub form_factor: String,
    /// Iterations, shots (progressive) or 1 (direct).
    pub iterations: usize,
    /// Relative residual (matrix solvers) or unshot power fraction (progressive).
    pub residual: f64,
    /// Wall-clock seconds of the solve.
    pub seconds: f64,
    /// Of which computing form factors, s.
    pub form_factor_seconds: f64,
    /// lm: luminous flux of `emitted_power`.
    #[serde(default)]
    pub emitted_lm: f64,
    /// lm: luminous flux of `absorbed_power`.
    #[serde(default)]
    pub absorbed_lm: f64,
    /// lm: luminous flux of `escaped_power`.
    #[serde(default)]
    pub escaped_lm: f64,
}

/// Luminous flux (lm) of a radiant power per channel (W): 683 · Y.
fn lumens(power: [f64; 3]) -> f64 {
    LUMINOUS_EFFICACY * crate::units::luminance_y(power)
}

/// One light source's line in the report.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LightReport {
    /// The light's name.
    pub name: String,
    /// `point`, `spot` or `goniometric`.
    pub kind: String,
    /// The photometric file of a goniometric light.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub file: Option<String>,
    /// Position, m.
    pub position: [f64; 3],
    /// W per channel: radiant flux.
    pub power: [f64; 3],
    /// lm: luminous flux.
    pub flux_lm: f64,
    /// cd: largest luminous intensity.
    pub peak_cd: f64,
}

/// The whole report, as written by `radiosity solve --report`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Report {
    /// The scene's name.
    pub scene: String,
    /// The units of every number.
    pub units: Units,
    /// Per object.
    pub objects: Vec<ObjectReport>,
    /// Whole-scene totals.
    pub totals: Totals,
    /// The light sources that are not surfaces (empty without).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub lights: Vec<LightReport>,
}

/// The units of the report's quantities, spelled out for readers of the JSON.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Units {
    /// Unit of areas.
    pub area: String,
    /// Unit of radiosity.
    pub radiosity: String,
    /// Unit of irradiance.
    pub irradiance: String,
    /// Unit of emitted exitance.
    pub emitted_exitance: String,
    /// Unit of power.
    pub power: String,
    /// Unit of illuminance.
    #[serde(default)]
    pub illuminance_lx: String,
    /// Unit of luminance.
    #[serde(default)]
    pub luminance_cd_m2: String,
    /// Unit of luminous flux.
    #[serde(default)]
    pub luminous_flux: String,
    /// How photometric values are derived from the RGB channels.
    #[serde(default)]
    pub photometric_convention: String,
}

impl Default for Units {
    fn default() -> Self {
        Self {
            area: "m^2".into(),
            radiosity: "W/m^2".into(),
            irradiance: "W/m^2".into(),
            emitted_exitance: "W/m^2".into(),
            power: "W".into(),
            illuminance_lx: "lx".into(),
            luminance_cd_m2: "cd/m^2".into(),
            luminous_flux: "lm".into(),
            photometric_convention: format!(
                "photometric = {LUMINOUS_EFFICACY} lm/W x Y, Y = 0.2126 R + 0.7152 G + 0.0722 B \
                 (linear sRGB / BT.709 primaries, D65 white)"
            ),
        }
    }
}

impl Report {
    /// Aggregates a solution by object.
    pub fn new(scene: &str, mesh: &Mesh, solution: &Solution, form_factor: &str) -> Self {
        let mut objects: Vec<ObjectReport> = mesh
            .objects
            .iter()
            .map(|name| ObjectReport {
                name: name.clone(),
                area: 0.0,
                reflectance: [0.0; 3],
                emitted_exitance: [0.0; 3],
                radiosity: [0.0; 3],
                irradiance: [0.0; 3],
                absorbed_power: [0.0; 3],
                illuminance_lx: 0.0,
                luminance_cd_m2: 0.0,
            })
            .collect();
        for (i, e) in mesh.elements.iter().enumerate() {
            let s = &mesh.surfaces[e.surface as usize];
            let o = &mut objects[s.object as usize];
            let (b, h) = (solution.radiosity[i], solution.irradiance[i]);
            o.area += e.area;
            for c in 0..3 {
                o.reflectance[c] += s.reflectance[c] * e.area;
                o.emitted_exitance[c] += s.exitance[c] * e.area;
                o.radiosity[c] += b[c] * e.area;
                o.irradiance[c] += h[c] * e.area;
                o.absorbed_power[c] += (1.0 - s.reflectance[c]) * h[c] * e.area;
            }
        }
        for o in &mut objects {
            for c in 0..3 {
                o.reflectance[c] /= o.area;
                o.emitted_exitance[c] /= o.area;
                o.radiosity[c] /= o.area;
                o.irradiance[c] /= o.area;
            }
            o.illuminance_lx = lux_from_irradiance(o.irradiance);
            o.luminance_cd_m2 = nits_from_radiance(o.radiosity.map(|b| b / std::f64::consts::PI));
        }
        let mut absorbed = [0.0; 3];
        for o in &objects {
            for c in 0..3 {
                absorbed[c] += o.absorbed_power[c];
            }
        }
        let st = &solution.stats;
        let emitted = Solution::emitted_power(mesh);
        Report {
            scene: scene.to_string(),
            units: Units::default(),
            objects,
            lights: Vec::new(),
            totals: Totals {
                emitted_lm: lumens(emitted),
                absorbed_lm: lumens(absorbed),
                escaped_lm: lumens(solution.escaped_power),
                emitted_power: emitted,
                absorbed_power: absorbed,
                escaped_power: solution.escaped_power,
                unshot_power: solution.unshot_power(mesh),
                elements: mesh.elements.len(),
                patches: mesh.patches.len(),
                solver: st.solver.name().to_string(),
                form_factor: form_factor.to_string(),
                iterations: st.iterations,
                residual: st.residual,
                seconds: st.seconds,
                form_factor_seconds: st.form_factor_seconds,
            },
        }
    }

    /// Relative energy-balance error |emitted − absorbed − escaped − unshot| / emitted,
    /// worst channel.
    pub fn balance_error(&self) -> f64 {
        let t = &self.totals;
        (0..3)
            .filter(|&c| t.emitted_power[c] > 0.0)
            .map(|c| {
                (t.emitted_power[c] - t.absorbed_power[c] - t.escaped_power[c] - t.unshot_power[c])
                    .abs()
                    / t.emitted_power[c]
            })
            .fold(0.0, f64::max)
    }

    /// Adds a line per light source (name, kind, flux in W and lm, peak intensity in cd).
    pub fn with_lights(mut self, lights: &[Light]) -> Self {
        self.lights = lights
            .iter()
            .map(|l| {
                let (kind, file) = match &l.distribution {
                    Distribution::Isotropic => ("point", None),
                    Distribution::Spot { .. } => ("spot", None),
                    Distribution::Goniometric(t) => ("goniometric", Some(t.file.clone())),
                };
                LightReport {
                    name: l.name.clone(),
                    kind: kind.into(),
                    file,
                    position: l.position.to_array(),
                    power: l.power(),
                    flux_lm: l.luminous_flux(),
                    peak_cd: LUMINOUS_EFFICACY * crate::units::luminance_y(l.peak_intensity()),
                }
            })
            .collect();
        self
    }

    /// Looks up an object by name.
    pub fn object(&self, name: &str) -> Option<&ObjectReport> {
        self.objects.iter().find(|o| o.name == name)
    }
}
