//! False-colour pictures for lighting design: illuminance grids as a colour map with iso-lux
//! lines and a legend, and a legend bar beside a false-colour render.
//!
//! The colour scale runs linearly from 0 to the top of a "nice" range (the largest value
//! rounded up to 1, 2 or 5 × 10ᵏ, [`Scale::covering`]); its ticks are the legend's labels and
//! the levels of the iso-lines. Colours follow a perceptually ordered ramp (dark blue, blue,
//! cyan, green, yellow, orange, dark red; the stops approximate Google's "Turbo" map), so
//! that the order of values reads at a glance and iso-lines stay visible on every colour.

use image::{Rgb, RgbImage};
use radiosity::measure::GridResult;
use std::path::Path;

/// A linear colour scale from 0 to `max`, with tick values.
#[derive(Debug, Clone, PartialEq)]
pub struct Scale {
    /// Value at the top of the scale.
    pub max: f64,
    /// Tick values, 0 first, `max` last.
    pub ticks: Vec<f64>,
}

impl Scale {
    /// The scale from 0 to the smallest "nice" number ≥ `max` whose step (1, 2 or 5 × 10ᵏ)
    /// gives 4 to 10 intervals; 0 to 1 for a non-positive or non-finite `max`.
    pub fn covering(max: f64) -> Self {
        let max = if max.is_finite() && max > 0.0 {
            max
        } else {
            1.0
        };
        let raw = max / 8.0;
        let magnitude = 10f64.powf(raw.log10().floor());
        let step = [1.0, 2.0, 5.0, 10.0]
            .iter()
            .map(|m| m * magnitude)
            .find(|s| max / s <= 10.0)
            .unwrap_or(10.0 * magnitude);
        let intervals = (max / step - 1e-9).ceil().max(1.0) as usize;
        let ticks = (0..=intervals).map(|k| k as f64 * step).collect();
        Self {
            max: intervals as f64 * step,
            ticks,
        }
    }

    /// The colour of `value` (sRGB bytes); values beyond the ends take the end colours.
    pub fn colour(&self, value: f64) -> [u8; 3] {
        ramp((value / self.max).clamp(0.0, 1.0))
    }
}

/// The colour ramp at t ∈ [0, 1] (sRGB bytes), linear between seven stops.
pub fn ramp(t: f64) -> [u8; 3] {
    const STOPS: [[f64; 3]; 7] = [
        [48.0, 18.0, 59.0],
        [65.0, 105.0, 226.0],
        [27.0, 208.0, 213.0],
        [98.0, 252.0, 107.0],
        [229.0, 216.0, 55.0],
        [250.0, 124.0, 30.0],
        [122.0, 4.0, 3.0],
    ];
    let x = t.clamp(0.0, 1.0) * (STOPS.len() - 1) as f64;
    let k = (x.floor() as usize).min(STOPS.len() - 2);
    let f = x - k as f64;
    std::array::from_fn(|c| (STOPS[k][c] * (1.0 - f) + STOPS[k + 1][c] * f).round() as u8)
}

/// Text and lines.
const INK: [u8; 3] = [20, 20, 20];
const PAPER: [u8; 3] = [255, 255, 255];
/// Cells without a point (off the surface).
const NO_DATA: [u8; 3] = [200, 200, 200];

/// Formats a tick value: no decimals from 10 up, else up to two.
fn label(v: f64) -> String {
    if v >= 10.0 || v == 0.0 {
        format!("{v:.0}")
    } else if v >= 1.0 {
        format!("{v:.1}")
    } else {
        format!("{v:.2}")
    }
}

/// The grid as a picture: each pixel coloured by the illuminance interpolated bilinearly
/// between the grid points (cell centres), iso-lux lines at the scale's ticks, a title with
/// Ē, Emin, Emax and U0, and a legend in lx. The u axis runs to the right, v upwards.
pub fn grid_plot(grid: &GridResult, title: &str) -> Result<RgbImage, String> {
    let font = ab_glyph::FontRef::try_from_slice(crate::font::FONT)
        .map_err(|e| format!("the bundled font: {e}"))?;
    let [nu, nv] = grid.layout.counts;
    let values = grid.raster();
    let scale = Scale::covering(grid.stats.e_max);
    // Pixels per metre: the longer side 560 px.
    let (wu, wv) = (
        nu as f64 * grid.layout.spacing[0],
        nv as f64 * grid.layout.spacing[1],
    );
    let ppm = 560.0 / wu.max(wv);
    let (pw, ph) = (
        ((wu * ppm).round() as u32).max(1),
        ((wv * ppm).round() as u32).max(1),
    );
    let (margin, top, legend_w) = (16u32, 64u32, 110u32);
    let width = margin + pw + margin + legend_w;
    let height = top + ph + margin + 24;
    let mut img = RgbImage::from_pixel(width, height, Rgb(PAPER));
    // Value at pixel (x, y) of the plot, by bilinear interpolation between cell centres
    // (clamped at the border cells); NaN where a needed cell has no point.
    let sample = |x: f64, y: f64| -> f64 {
        let fu = (x / pw as f64 * nu as f64 - 0.5).clamp(0.0, (nu - 1) as f64);
        let fv = (y / ph as f64 * nv as f64 - 0.5).clamp(0.0, (nv - 1) as f64);
        let (i0, j0) = (fu.floor() as usize, fv.floor() as usize);
        let (i1, j1) = ((i0 + 1).min(nu - 1), (j0 + 1).min(nv - 1));
        let (s, t) = (fu - i0 as f64, fv - j0 as f64);
        let v = |i: usize, j: usize| values[j * nu + i];
        let (a, b, c, d) = (v(i0, j0), v(i1, j0), v(i0, j1), v(i1, j1));
        if a.is_nan() || b.is_nan() || c.is_nan() || d.is_nan() {
            // Nearest cell, if it has a point.
            return v(fu.round() as usize, fv.round() as usize);
        }
        (a * (1.0 - s) + b * s) * (1.0 - t) + (c * (1.0 - s) + d * s) * t
    };
    let mut field = vec![f64::NAN; (pw * ph) as usize];
    for py in 0..ph {
        for px in 0..pw {
            // Image rows run down; v runs up.
            let v = sample(px as f64 + 0.5, (ph - 1 - py) as f64 + 0.5);
            field[(py * pw + px) as usize] = v;
            let colour = if v.is_nan() { NO_DATA } else { scale.colour(v) };
            img.put_pixel(margin + px, top + py, Rgb(colour));
        }
    }
    // Iso-lux lines: pixels where the field crosses a tick level towards the right or
    // lower neighbour.
    let levels: Vec<f64> = scale.ticks[1..scale.ticks.len() - 1].to_vec();
    for py in 0..ph {
        for px in 0..pw {
            let a = field[(py * pw + px) as usize];
            let mut on = false;
            for (dx, dy) in [(1u32, 0u32), (0, 1)] {
                let (qx, qy) = (px + dx, py + dy);
                if qx >= pw || qy >= ph {
                    continue;
                }
                let b = field[(qy * pw + qx) as usize];
                if a.is_nan() || b.is_nan() {
                    continue;
                }
                on |= levels
                    .iter()
                    .any(|&l| (a - l) * (b - l) < 0.0 || (a == l && b != l));
            }
            if on {
                img.put_pixel(margin + px, top + py, Rgb(INK));
            }
        }
    }
    // Frame.
    for px in 0..pw + 2 {
        img.put_pixel(margin - 1 + px, top - 1, Rgb(INK));
        img.put_pixel(margin - 1 + px, top + ph, Rgb(INK));
    }
    for py in 0..ph + 2 {
        img.put_pixel(margin - 1, top - 1 + py, Rgb(INK));
        img.put_pixel(margin + pw, top - 1 + py, Rgb(INK));
    }
    let s = &grid.stats;
    crate::sequence::draw_text(&mut img, &font, 17.0, margin as f32, 24.0, title, INK);
    let line = format!(
        "Ē = {:.0} lx   Emin = {:.0} lx   Emax = {:.0} lx   U0 = {:.2}   Emin/Emax = {:.2}",
        s.e_mean, s.e_min, s.e_max, s.u0, s.min_over_max
    );
    crate::sequence::draw_text(&mut img, &font, 14.0, margin as f32, 48.0, &line, INK);
    let foot = format!(
        "{} points, spacing {:.3} × {:.3} m, iso-lux lines every {} lx",
        s.points,
        grid.layout.spacing[0],
        grid.layout.spacing[1],
        label(scale.ticks.get(1).copied().unwrap_or(scale.max))
    );
    crate::sequence::draw_text(
        &mut img,
        &font,
        12.0,
        margin as f32,
        (top + ph + margin + 12) as f32,
        &foot,
        INK,
    );
    draw_legend(
        &mut img,
        &font,
        &scale,
        "lx",
        margin + pw + margin + 8,
        top,
        ph.max(120),
    );
    Ok(img)
}

/// Draws a vertical legend bar (`height` px tall, top at `y0`) with tick labels and the unit
/// at `x0`.
fn draw_legend(
    img: &mut RgbImage,
    font: &ab_glyph::FontRef,
    scale: &Scale,
    unit: &str,
    x0: u32,
    y0: u32,
    height: u32,
) {
    let bar_w = 22u32;
    let height = height.min(img.height().saturating_sub(y0 + 8)).max(2);
    for y in 0..height {
        let v = scale.max * (1.0 - y as f64 / (height - 1) as f64);
        for x in 0..bar_w {
            if x0 + x < img.width() && y0 + y < img.height() {
                img.put_pixel(x0 + x, y0 + y, Rgb(scale.colour(v)));
            }
        }
    }
    for &t in &scale.ticks {
        let y = y0 + ((1.0 - t / scale.max) * (height - 1) as f64).round() as u32;
        for x in 0..bar_w + 5 {
            if x0 + x < img.width() && y < img.height() {
                img.put_pixel(x0 + x, y, Rgb(INK));
            }
        }
        crate::sequence::draw_text(
            img,
            font,
            13.0,
            (x0 + bar_w + 8) as f32,
            y as f32 + 5.0,
            &label(t),
            INK,
        );
    }
    crate::sequence::draw_text(img, font, 14.0, x0 as f32, y0 as f32 - 8.0, unit, INK);
}

/// A rendered false-colour image with a legend bar to its right (white background).
pub fn with_legend(render: &RgbImage, scale: &Scale, unit: &str) -> Result<RgbImage, String> {
    let font = ab_glyph::FontRef::try_from_slice(crate::font::FONT)
        .map_err(|e| format!("the bundled font: {e}"))?;
    let legend_w = 100u32;
    let pad = 24u32;
    let height = render.height().max(160) + 2 * pad;
    let mut img = RgbImage::from_pixel(render.width() + legend_w, height, Rgb(PAPER));
    image::imageops::replace(&mut img, render, 0, i64::from(pad));
    draw_legend(
        &mut img,
        &font,
        scale,
        unit,
        render.width() + 12,
        pad + 8,
        render.height().max(160) - 16,
    );
    Ok(img)
}

/// A false-colour picture of a value field (`width` × `height` pixels, row-major from the
/// top; NaN for background, left white): each pixel coloured by `scale`, iso-lines at the
/// scale's inner ticks, and a legend bar in `unit` to its right.
pub fn field_picture(
    width: u32,
    height: u32,
    field: &[f64],
    scale: &Scale,
    unit: &str,
) -> Result<RgbImage, String> {
    if field.len() != (width as usize) * (height as usize) {
        return Err(format!(
            "a {width}×{height} picture needs {} values, got {}",
            width as usize * height as usize,
            field.len()
        ));
    }
    let mut picture = RgbImage::from_pixel(width, height, Rgb(PAPER));
    for (k, &v) in field.iter().enumerate() {
        if !v.is_nan() {
            picture.put_pixel(k as u32 % width, k as u32 / width, Rgb(scale.colour(v)));
        }
    }
    let inner = &scale.ticks[1..scale.ticks.len().saturating_sub(1).max(1)];
    draw_isolines(&mut picture, field, inner);
    with_legend(&picture, scale, unit)
}

/// Iso-lines on a rendered value image: pixels (not `background`) where `values` crosses
/// one of `levels` towards the right or lower neighbour become `INK`.
pub fn draw_isolines(img: &mut RgbImage, values: &[f64], levels: &[f64]) {
    let (w, h) = (img.width(), img.height());
    for y in 0..h {
        for x in 0..w {
            let a = values[(y * w + x) as usize];
            if a.is_nan() {
                continue;
            }
            let crosses = [(1u32, 0u32), (0, 1)].iter().any(|&(dx, dy)| {
                let (qx, qy) = (x + dx, y + dy);
                if qx >= w || qy >= h {
                    return false;
                }
                let b = values[(qy * w + qx) as usize];
                !b.is_nan() && levels.iter().any(|&l| (a - l) * (b - l) < 0.0)
            });
            if crosses {
                img.put_pixel(x, y, Rgb(INK));
            }
        }
    }
}

/// Writes an RGB image as PNG, atomically.
pub fn write_png(img: &RgbImage, path: &Path) -> Result<(), String> {
    crate::sequence::write_png(img, path).map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scales_cover_the_maximum_with_round_ticks() {
        let s = Scale::covering(734.0);
        assert_eq!(s.max, 800.0);
        assert_eq!(s.ticks.first(), Some(&0.0));
        assert_eq!(s.ticks.last(), Some(&800.0));
        assert!((4..=11).contains(&s.ticks.len()), "{:?}", s.ticks);
        let s = Scale::covering(1.0);
        assert!(s.max >= 1.0 && s.max <= 1.2, "{s:?}");
        assert_eq!(Scale::covering(f64::NAN).max, 1.0);
        assert_eq!(Scale::covering(500.0).max, 500.0);
    }

    #[test]
    fn the_ramp_runs_from_dark_blue_to_dark_red() {
        assert_eq!(ramp(0.0), [48, 18, 59]);
        assert_eq!(ramp(1.0), [122, 4, 3]);
        assert_eq!(ramp(-1.0), ramp(0.0));
    }
}
