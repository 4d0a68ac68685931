//! Photometric units and how the renderer's radiometric RGB maps onto them.
//!
//! The renderer works in radiometric quantities per linear-sRGB channel (W·m⁻²,
//! W·m⁻²·sr⁻¹, W). Photometric inputs (lumens, candela from luminaire files) and outputs
//! (lux, cd/m²) meet them through one convention, used everywhere:
//!
//!   photometric value = [`LUMINOUS_EFFICACY`] × Y(radiometric RGB),
//!   Y(R, G, B) = 0.2126 R + 0.7152 G + 0.0722 B,
//!
//! where Y is the relative luminance of linear RGB with the ITU-R BT.709 primaries and D65
//! white (the sRGB primaries, IEC 61966-2-1), whose white (1, 1, 1) has Y = 1. 683 lm/W is
//! the luminous efficacy of monochromatic 540 THz radiation in the SI definition of the
//! candela; using it for all of RGB treats each channel as if its watts were "light watts",
//! the common rendering convention (a spectral renderer would integrate V(λ) instead).
//!
//! So 1 W of white (1, 1, 1) is 683 lm, an irradiance of (1, 1, 1) W·m⁻² is 683 lx, and a
//! radiance of (1, 1, 1) W·m⁻²·sr⁻¹ is 683 cd/m².
//!
//! See also: [`crate::photometry`] for luminaire files in lm and cd.

/// Luminous efficacy that converts the renderer's watts to lumens, lm/W (SI definition of
/// the candela: 683 lm/W at 540 × 10¹² Hz).
pub const LUMINOUS_EFFICACY: f64 = 683.0;

/// Why a photometric quantity cannot be turned into radiometric RGB.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum UnitsError {
    /// A colour channel is negative, NaN or infinite.
    #[error("colour {colour:?} has a negative or non-finite component")]
    InvalidColour {
        /// The colour given.
        colour: [f64; 3],
    },
    /// The colour has no luminance (Y ≤ 0), so no scale of it reaches a luminous value.
    #[error("colour {colour:?} has luminance Y = {y} ≤ 0: it cannot carry a luminous quantity")]
    NoLuminance {
        /// The colour given.
        colour: [f64; 3],
        /// Its luminance Y.
        y: f64,
    },
    /// The photometric value is negative, NaN or infinite.
    #[error("photometric value {value} is not finite and ≥ 0")]
    InvalidValue {
        /// The value given.
        value: f64,
    },
}

/// Relative luminance Y of linear RGB (dimensionless weights): Y = 0.2126 R + 0.7152 G +
/// 0.0722 B, the ITU-R BT.709-6 luminance-signal coefficients applied to linear values, i.e.
/// the Y row of the linear-sRGB → CIE XYZ matrix (IEC 61966-2-1), so white (1, 1, 1) has
/// Y = 1.
pub fn luminance_y(rgb: [f64; 3]) -> f64 {
    0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2]
}

/// Illuminance, lx, of an irradiance `e` per RGB channel, W·m⁻²: E_v = 683 · Y(E).
pub fn lux_from_irradiance(e: [f64; 3]) -> f64 {
    LUMINOUS_EFFICACY * luminance_y(e)
}

/// Luminance, cd/m² (nits), of a radiance `l` per RGB channel, W·m⁻²·sr⁻¹:
/// L_v = 683 · Y(L).
pub fn nits_from_radiance(l: [f64; 3]) -> f64 {
    LUMINOUS_EFFICACY * luminance_y(l)
}

/// The radiometric RGB quantity of a given colour that carries a photometric `value`:
/// value / 683 · colour / Y(colour), so that `683 · Y(result) = value`.
///
/// Works for any matching pair: lm → W, cd → W·sr⁻¹, lx → W·m⁻², cd/m² → W·m⁻²·sr⁻¹.
/// The colour fixes only the chromaticity (its scale cancels); white (1, 1, 1) gives
/// value / 683 in every channel.
///
/// Errors: a colour with a negative or non-finite channel, a colour with Y ≤ 0 (black, or
/// nothing the eye sees), a value that is negative or non-finite.
pub fn radiometric_from_photometric(value: f64, colour: [f64; 3]) -> Result<[f64; 3], UnitsError> {
    if !(value.is_finite() && value >= 0.0) {
        return Err(UnitsError::InvalidValue { value });
    }
    if colour.iter().any(|c| !(c.is_finite() && *c >= 0.0)) {
        return Err(UnitsError::InvalidColour { colour });
    }
    let y = luminance_y(colour);
    if y <= 0.0 {
        return Err(UnitsError::NoLuminance { colour, y });
    }
    let scale = value / (LUMINOUS_EFFICACY * y);
    Ok(colour.map(|c| c * scale))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The Y row of the RGB → XYZ matrix derived from the BT.709 primaries and D65 white
    /// chromaticities (the standard construction: solve for the channel scales S that map
    /// (1, 1, 1) to the white point's XYZ; then Y_c = S_c · y_c).
    fn y_row_from_chromaticities() -> [f64; 3] {
        let primaries = [(0.64, 0.33), (0.30, 0.60), (0.15, 0.06)];
        let (xw, yw) = (0.3127, 0.3290);
        let white = [xw / yw, 1.0, (1.0 - xw - yw) / yw];
        // Columns: XYZ of each primary at Y = 1.
        let m: Vec<[f64; 3]> = primaries
            .iter()
            .map(|&(x, y)| [x / y, 1.0, (1.0 - x - y) / y])
            .collect();
        // Solve M S = white by Cramer's rule.
        let det3 = |a: [f64; 3], b: [f64; 3], c: [f64; 3]| {
            a[0] * (b[1] * c[2] - b[2] * c[1]) - b[0] * (a[1] * c[2] - a[2] * c[1])
                + c[0] * (a[1] * b[2] - a[2] * b[1])
        };
        let d = det3(m[0], m[1], m[2]);
        let s = [
            det3(white, m[1], m[2]) / d,
            det3(m[0], white, m[2]) / d,
            det3(m[0], m[1], white) / d,
        ];
        // Y of primary c at scale S_c is S_c · 1.
        s
    }

    #[test]
    fn luminance_weights_are_the_bt709_d65_y_row() {
        let derived = y_row_from_chromaticities();
        let ours = [
            luminance_y([1.0, 0.0, 0.0]),
            luminance_y([0.0, 1.0, 0.0]),
            luminance_y([0.0, 0.0, 1.0]),
        ];
        for c in 0..3 {
            // The published weights are the derived ones rounded to 4 decimals.
            assert!(
                (ours[c] - derived[c]).abs() < 5e-5,
                "channel {c}: {} vs derived {}",
                ours[c],
                derived[c]
            );
        }
        // White has Y = 1 (the weights sum to 1 up to one rounding of the additions).
        assert!((luminance_y([1.0, 1.0, 1.0]) - 1.0).abs() < 1e-15);
    }

    #[test]
    fn lux_and_nits_are_683_y() {
        assert!((lux_from_irradiance([1.0, 1.0, 1.0]) - 683.0).abs() < 1e-12);
        assert!((nits_from_radiance([1.0, 1.0, 1.0]) - 683.0).abs() < 1e-12);
        // Pure green irradiance of 1 W·m⁻²: 683 × 0.7152 lx.
        assert!((lux_from_irradiance([0.0, 1.0, 0.0]) - 488.4816).abs() < 1e-9);
        // Linear in the input: a Lambertian surface of exitance M (W·m⁻²) has radiance M/π,
        // so its luminance in nits is lux/π.
        let m = [3.0, 2.0, 0.5];
        let l = m.map(|v| v / std::f64::consts::PI);
        assert!(
            (nits_from_radiance(l) - lux_from_irradiance(m) / std::f64::consts::PI).abs() < 1e-12
        );
        assert_eq!(LUMINOUS_EFFICACY, 683.0);
    }

    #[test]
    fn radiometric_from_photometric_round_trips() {
        for (value, colour) in [
            (3400.0, [1.0, 1.0, 1.0]),
            (1.0, [1.0, 0.9, 0.7]),
            (250.0, [0.0, 0.0, 2.0]),
            (0.0, [0.2, 0.5, 0.1]),
            (1e-9, [5.0, 1e-3, 0.0]),
        ] {
            let rgb = radiometric_from_photometric(value, colour).unwrap();
            // 683 · Y(value / (683 Y) · colour) = value, to a few roundings.
            let back = LUMINOUS_EFFICACY * luminance_y(rgb);
            assert!(
                (back - value).abs() <= 1e-14 * value.max(1e-300),
                "{value} {colour:?}: {back}"
            );
            // Chromaticity is kept: the result is a non-negative multiple of the colour.
            for c in 0..3 {
                assert!(rgb[c] >= 0.0);
                if colour[c] == 0.0 {
                    assert_eq!(rgb[c], 0.0);
                }
            }
        }
        // White: value / 683 in each channel, e.g. 683 lm → 1 W per channel.
        assert_eq!(
            radiometric_from_photometric(683.0, [1.0, 1.0, 1.0]).unwrap(),
            [1.0, 1.0, 1.0]
        );
        // The colour's scale does not matter.
        let a = radiometric_from_photometric(100.0, [1.0, 0.5, 0.25]).unwrap();
        let b = radiometric_from_photometric(100.0, [4.0, 2.0, 1.0]).unwrap();
        for c in 0..3 {
            assert!((a[c] - b[c]).abs() < 1e-15);
        }
    }

    #[test]
    fn radiometric_from_photometric_rejects_what_carries_no_light() {
        let bad_colours = [
            [0.0, 0.0, 0.0],
            [-0.1, 1.0, 1.0],
            [f64::NAN, 1.0, 1.0],
            [1.0, f64::INFINITY, 1.0],
        ];
        for colour in bad_colours {
            assert!(
                radiometric_from_photometric(1.0, colour).is_err(),
                "{colour:?}"
            );
        }
        assert!(matches!(
            radiometric_from_photometric(1.0, [0.0, 0.0, 0.0]),
            Err(UnitsError::NoLuminance { .. })
        ));
        for value in [-1.0, f64::NAN, f64::INFINITY] {
            assert!(matches!(
                radiometric_from_photometric(value, [1.0, 1.0, 1.0]),
                Err(UnitsError::InvalidValue { .. })
            ));
        }
        let message = radiometric_from_photometric(1.0, [0.0, 0.0, 0.0])
            .unwrap_err()
            .to_string();
        assert!(message.contains("Y = 0"), "{message}");
    }
}
