//! `render --false-colour`: surfaces coloured by illuminance (lx) or luminance (cd/m²), with
//! iso-lines at the legend's ticks and a legend bar, as PNG.
//!
//! The rasteriser draws the quantity itself (as a grey level, so smooth shading interpolates
//! values, not colours); each pixel's value is then mapped through the colour scale of
//! `radiosity_studies::falsecolour`, which also draws the iso-lines and the legend.

use anyhow::{bail, Context, Result};
use radiosity::display::Shading;
use radiosity::pipeline::{render_elements, Shaded};
use radiosity::render::RenderOptions;
use radiosity::scene::Camera;
use radiosity::units::{lux_from_irradiance, nits_from_radiance};
use radiosity_studies::falsecolour::{field_picture, write_png, Scale};
use std::f64::consts::PI;
use std::path::Path;

/// What `--false-colour` shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum FalseColour {
    /// Illuminance on each surface, lx (683 · Y of the irradiance).
    Lux,
    /// Luminance of each surface, cd/m² (683 · Y of the radiosity / π).
    Luminance,
}

impl FalseColour {
    fn unit(self) -> &'static str {
        match self {
            FalseColour::Lux => "lx",
            FalseColour::Luminance => "cd/m²",
        }
    }
}

/// `--false-colour` writes PNG only.
pub fn check_png(path: &Path) -> Result<()> {
    let png = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("png"));
    if !png {
        bail!(
            "--false-colour: {} must be a .png file (false colours are not radiance)",
            path.display()
        );
    }
    Ok(())
}

/// The quantity per element, in every channel: lx from the irradiance, or cd/m² from the
/// radiosity.
pub fn values(
    quantity: FalseColour,
    radiosity: &[[f64; 3]],
    irradiance: &[[f64; 3]],
) -> Vec<[f64; 3]> {
    match quantity {
        FalseColour::Lux => irradiance
            .iter()
            .map(|h| [lux_from_irradiance(*h); 3])
            .collect(),
        FalseColour::Luminance => radiosity
            .iter()
            .map(|b| [nits_from_radiance(b.map(|v| v / PI)); 3])
            .collect(),
    }
}

/// Pixel radiance of a covered pixel at value 0; background pixels are 0.
const FLOOR: f64 = 0.02;

/// Renders `shaded` (whose radiosity holds the quantity, see [`values`]) in false colour
/// with iso-lines and a legend, and writes `output` (PNG).
pub fn render(
    quantity: FalseColour,
    shaded: &Shaded,
    camera: &Camera,
    shading: Shading,
    options: &RenderOptions,
    output: &Path,
    quiet: bool,
) -> Result<()> {
    check_png(output)?;
    let max = shaded.radiosity.iter().map(|v| v[0]).fold(0.0, f64::max);
    let scale = Scale::covering(max);
    // Grey levels: FLOOR + (1 − FLOOR) v / max as radiance (radiosity π times that).
    let grey: Vec<[f64; 3]> = shaded
        .radiosity
        .iter()
        .map(|v| [PI * (FLOOR + (1.0 - FLOOR) * v[0] / scale.max); 3])
        .collect();
    let image = render_elements(
        &Shaded {
            vertices: shaded.vertices,
            elements: shaded.elements,
            radiosity: &grey,
        },
        camera,
        shading,
        false,
        options,
    )?;
    let (w, h) = (image.width, image.height);
    let mut field = vec![f64::NAN; (w * h) as usize];
    for (k, p) in image.pixels.iter().enumerate() {
        let l = f64::from(p[0]);
        if l < 0.5 * FLOOR {
            continue; // background
        }
        field[k] = ((l - FLOOR) / (1.0 - FLOOR)).max(0.0) * scale.max;
    }
    let framed =
        field_picture(w, h, &field, &scale, quantity.unit()).map_err(anyhow::Error::msg)?;
    write_png(&framed, output)
        .map_err(anyhow::Error::msg)
        .with_context(|| format!("writing {}", output.display()))?;
    if !quiet {
        stderr_line!(
            "wrote {} ({w}×{h}, false colour {} 0–{} {})",
            output.display(),
            match quantity {
                FalseColour::Lux => "illuminance",
                FalseColour::Luminance => "luminance",
            },
            scale.max,
            quantity.unit()
        );
    }
    Ok(())
}
