//! Light sources that are not surfaces: isotropic point lights, spot lights and goniometric
//! luminaires (photometric files), each placed at a point with an aiming frame.
//!
//! A light's radiant intensity towards a direction ω is, per RGB channel,
//!
//!   I(ω) = `intensity` × D(ω)   (W·sr⁻¹),
//!
//! where D is the dimensionless (isotropic, spot) or candela-valued (goniometric)
//! distribution in the luminaire's own frame and `intensity` the radiometric scale per channel.
//! Photometric inputs convert with the project's convention: luminous quantities are 683 lm/W
//! times the luminance Y of linear sRGB primaries, Y = 0.2126 R + 0.7152 G + 0.0722 B (see
//! [`crate::units`]).
//!
//! The luminaire frame follows type C photometry (IES LM-63, EULUMDAT): the polar angle γ is
//! measured from the nadir axis (γ = 0 straight "down" the luminaire's axis), and the azimuth C
//! from the C = 0 half-plane, counter-clockwise seen from above (looking along the nadir).

use crate::photometry::Photometry;
use crate::scene::Origin;
use glam::DVec3;
use std::f64::consts::PI;
use std::sync::Arc;

/// Where a luminaire points: its nadir axis (γ = 0) and the direction of its C = 0 half-plane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aim {
    /// Unit vector of γ = 0 (for a ceiling luminaire, straight down).
    pub nadir: DVec3,
    /// Unit vector perpendicular to `nadir`, in the C = 0 half-plane.
    pub c0: DVec3,
}

impl Default for Aim {
    /// Pointing down −z (γ = 0 towards −z) with C = 0 along +x: a ceiling luminaire in a
    /// z-up scene.
    fn default() -> Self {
        Self {
            nadir: DVec3::NEG_Z,
            c0: DVec3::X,
        }
    }
}

impl Aim {
    /// An aim from a nadir direction and a direction roughly along C = 0 (made orthogonal).
    /// `None` if either is zero or they are parallel.
    pub fn new(nadir: DVec3, c0_hint: DVec3) -> Option<Self> {
        let nadir = nadir.try_normalize()?;
        let c0 = (c0_hint - nadir * c0_hint.dot(nadir)).try_normalize()?;
        Some(Self { nadir, c0 })
    }

    /// The C = 90° direction: nadir × C0 turned so that C grows counter-clockwise seen
    /// looking along the nadir from above the luminaire.
    pub fn c90(&self) -> DVec3 {
        self.c0.cross(self.nadir)
    }

    /// (C, γ) in degrees of a world direction, C in [0, 360), γ in [0, 180].
    pub fn angles_deg(&self, direction: DVec3) -> (f64, f64) {
        let d = direction.normalize();
        let gamma = d.dot(self.nadir).clamp(-1.0, 1.0).acos().to_degrees();
        let x = d.dot(self.c0);
        let y = d.dot(self.c90());
        let c = if x == 0.0 && y == 0.0 {
            0.0
        } else {
            y.atan2(x).to_degrees().rem_euclid(360.0)
        };
        (c, gamma)
    }
}

/// The shape of a light's intensity distribution, in the luminaire frame.
#[derive(Debug, Clone, PartialEq)]
pub enum Distribution {
    /// The same intensity in every direction: D = 1.
    Isotropic,
    /// A cone about the nadir: D = 1 for γ ≤ `inner_deg`, falling smoothly (smoothstep in
    /// cos γ) to 0 at `outer_deg`, 0 beyond (glTF `KHR_lights_punctual` spot semantics).
    Spot {
        /// Half-angle of the full-intensity cone, degrees.
        inner_deg: f64,
        /// Half-angle beyond which nothing is emitted, degrees (> `inner_deg`, ≤ 90).
        outer_deg: f64,
    },
    /// A measured luminaire: D(C, γ) = the photometric table's luminous intensity in cd
    /// ([`Photometry::intensity`], bilinear between the file's angles), so `intensity` is
    /// W·sr⁻¹ per candela.
    Goniometric(Arc<Photometry>),
}

impl Distribution {
    /// D at polar angle γ and azimuth C (degrees).
    pub fn value(&self, c_deg: f64, gamma_deg: f64) -> f64 {
        match self {
            Distribution::Isotropic => 1.0,
            Distribution::Spot {
                inner_deg,
                outer_deg,
            } => spot_falloff(gamma_deg, *inner_deg, *outer_deg),
            Distribution::Goniometric(table) => table.intensity(c_deg, gamma_deg),
        }
    }

    /// ∫ D dω over the sphere (sr; lm for a goniometric table, whose D is in cd), so that a
    /// light's power is `intensity` × this.
    ///
    /// Isotropic: 4π. Spot: with u = cos γ, D is 1 on [cos inner, 1] and a smoothstep of u on
    /// [cos outer, cos inner], whose integral is half that interval, so
    /// ∫ D dω = 2π (1 − cos inner + (cos inner − cos outer)/2). Goniometric: the table's flux,
    /// exact for its bilinear interpolant ([`Photometry::flux`]).
    pub fn integral(&self) -> f64 {
        match self {
            Distribution::Isotropic => 4.0 * PI,
            Distribution::Spot {
                inner_deg,
                outer_deg,
            } => {
                let ci = inner_deg.to_radians().cos();
                let co = outer_deg.to_radians().cos();
                2.0 * PI * (1.0 - ci + 0.5 * (ci - co))
            }
            Distribution::Goniometric(table) => table.flux(),
        }
    }

    /// The largest value D takes (1 for isotropic and spot lights, the table's largest
    /// candela for a goniometric one).
    pub fn peak(&self) -> f64 {
        match self {
            Distribution::Isotropic | Distribution::Spot { .. } => 1.0,
            Distribution::Goniometric(table) => table.max_intensity(),
        }
    }
}

/// glTF's spot attenuation: smoothstep of cos γ between cos(outer) and cos(inner).
fn spot_falloff(gamma_deg: f64, inner_deg: f64, outer_deg: f64) -> f64 {
    if gamma_deg <= inner_deg {
        return 1.0;
    }
    if gamma_deg >= outer_deg {
        return 0.0;
    }
    let (ci, co) = (inner_deg.to_radians().cos(), outer_deg.to_radians().cos());
    let t = ((gamma_deg.to_radians().cos() - co) / (ci - co)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// A light source placed in the scene.
#[derive(Debug, Clone, PartialEq)]
pub struct Light {
    /// Name (reports and errors name lights by it).
    pub name: String,
    /// Position, m.
    pub position: DVec3,
    /// Aiming frame of the distribution.
    pub aim: Aim,
    /// Shape of the distribution.
    pub distribution: Distribution,
    /// Radiometric scale per RGB channel, W·sr⁻¹ per unit of the distribution's value.
    pub intensity: [f64; 3],
    /// Where the light was defined, for error messages.
    pub origin: Origin,
}

impl Light {
    /// Radiant intensity towards the world direction `direction` (any length), W·sr⁻¹.
    pub fn radiant_intensity(&self, direction: DVec3) -> [f64; 3] {
        let (c, gamma) = self.aim.angles_deg(direction);
        let d = self.distribution.value(c, gamma);
        self.intensity.map(|i| i * d)
    }

    /// Radiant flux (power) per RGB channel, W: `intensity` × ∫ D dω
    /// ([`Distribution::integral`]).
    pub fn power(&self) -> [f64; 3] {
        let integral = self.distribution.integral();
        self.intensity.map(|i| i * integral)
    }

    /// Luminous flux, lm: 683 · Y(power) (see [`crate::units`]).
    pub fn luminous_flux(&self) -> f64 {
        crate::units::LUMINOUS_EFFICACY * crate::units::luminance_y(self.power())
    }

    /// The largest radiant intensity in any direction per channel, W·sr⁻¹.
    pub fn peak_intensity(&self) -> [f64; 3] {
        let peak = self.distribution.peak();
        self.intensity.map(|i| i * peak)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn angles_follow_type_c_convention() {
        let aim = Aim::default();
        let (_, g) = aim.angles_deg(DVec3::NEG_Z);
        assert!(g.abs() < 1e-12);
        let (c, g) = aim.angles_deg(DVec3::X);
        assert!((g - 90.0).abs() < 1e-12 && c.abs() < 1e-12);
        // Seen from above (looking down −z, +y up the page, +x to the right), C grows
        // counter-clockwise from +x: C = 90° is +y.
        let (c, _) = aim.angles_deg(DVec3::Y);
        assert!((c - 90.0).abs() < 1e-12, "C = {c}");
    }

    #[test]
    fn spot_is_full_inside_and_dark_outside() {
        let d = Distribution::Spot {
            inner_deg: 20.0,
            outer_deg: 30.0,
        };
        assert_eq!(d.value(0.0, 10.0), 1.0);
        assert_eq!(d.value(0.0, 31.0), 0.0);
        let mid = d.value(0.0, 25.0);
        assert!(mid > 0.0 && mid < 1.0);
    }

    /// ∫ D dω against a midpoint sum over γ (D depends on γ only): the closed forms of
    /// [`Distribution::integral`].
    #[test]
    fn integrals_match_quadrature() {
        for d in [
            Distribution::Isotropic,
            Distribution::Spot {
                inner_deg: 20.0,
                outer_deg: 35.0,
            },
            Distribution::Spot {
                inner_deg: 0.0,
                outer_deg: 90.0,
            },
        ] {
            let n = 200_000;
            let h = PI / n as f64;
            let sum: f64 = (0..n)
                .map(|k| {
                    let g = (k as f64 + 0.5) * h;
                    d.value(0.0, g.to_degrees()) * g.sin() * h
                })
                .sum::<f64>()
                * 2.0
                * PI;
            // Midpoint rule, error O(h²) ≈ 1e-10 here.
            assert!(
                (sum - d.integral()).abs() < 1e-8,
                "{d:?}: {sum} vs {}",
                d.integral()
            );
        }
    }
}
