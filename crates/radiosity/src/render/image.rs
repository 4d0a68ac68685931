//! A linear-radiance RGB image and its output as OpenEXR (linear float) or PNG (sRGB 8-bit).

use crate::io::atomic::write_atomically;
use std::io::{self, Cursor};
use std::path::{Path, PathBuf};

/// Errors writing or reading an [`Image`]; every one names the file.
#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    #[error("{}: unsupported image format (use a .exr or .png extension)", path.display())]
    /// The extension is not .png or .exr.
    UnsupportedExtension {
        /// The file.
        path: PathBuf,
    },
    #[error("{}: image is {width}x{height} with {len} pixels; expected width*height > 0 pixels", path.display())]
    /// The pixel buffer does not match the size.
    InvalidImage {
        /// The file.
        path: PathBuf,
        /// Width in pixels.
        width: u32,
        /// Height in pixels.
        height: u32,
        /// Pixels held.
        len: usize,
    },
    #[error("{}: {source}", path.display())]
    /// Reading or writing failed.
    Io {
        /// The file.
        path: PathBuf,
        #[source]
        /// The underlying error.
        source: io::Error,
    },
    #[error("{}: OpenEXR: {source}", path.display())]
    /// The OpenEXR codec failed.
    Exr {
        /// The file.
        path: PathBuf,
        #[source]
        /// The underlying error.
        source: exr::error::Error,
    },
    #[error("{}: PNG: {source}", path.display())]
    /// The PNG codec failed.
    Png {
        /// The file.
        path: PathBuf,
        #[source]
        /// The underlying error.
        source: image::ImageError,
    },
}

/// A linear RGB image, row-major with row 0 at the top; each pixel is a radiance in
/// W·m⁻²·sr⁻¹ (or any linear quantity).
///
/// Pixel (x, y) is `pixels[y * width + x]`, x = column left→right, y = row top→bottom,
/// the convention of `tests/reference/cornell.camera.json`.
#[derive(Debug, Clone, PartialEq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Pixels, row-major from the top-left.
    pub pixels: Vec<[f32; 3]>,
}

/// Output file formats, chosen by extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Format {
    Exr,
    Png,
}

impl Format {
    fn of(path: &Path) -> Option<Self> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "exr" => Some(Self::Exr),
            "png" => Some(Self::Png),
            _ => None,
        }
    }
}

/// Checks before rendering that `path` has a supported extension and can be written.
pub fn check_output(path: &Path) -> Result<(), ImageError> {
    Format::of(path).ok_or_else(|| ImageError::UnsupportedExtension {
        path: path.to_owned(),
    })?;
    crate::io::atomic::check_writable(path).map_err(|source| ImageError::Io {
        path: path.to_owned(),
        source,
    })
}

impl Image {
    /// A black `width` × `height` image.
    pub fn new(width: u32, height: u32) -> Self {
        Self {
            width,
            height,
            pixels: vec![[0.0; 3]; width as usize * height as usize],
        }
    }

    /// The pixel in column `x`, row `y` (row 0 at the top).
    ///
    /// Panics if (x, y) is outside the image.
    pub fn get(&self, x: u32, y: u32) -> [f32; 3] {
        assert!(
            x < self.width && y < self.height,
            "pixel ({x}, {y}) outside {}x{} image",
            self.width,
            self.height
        );
        self.pixels[y as usize * self.width as usize + x as usize]
    }

    /// Mean of the pixels in the half-open rectangle [x0, x1) × [y0, y1), accumulated in f64:
    /// the `regions` convention of `tests/reference/cornell_reference.json`.
    ///
    /// Panics if the rectangle is empty or reaches outside the image.
    pub fn region_mean(&self, x0: u32, y0: u32, x1: u32, y1: u32) -> [f64; 3] {
        assert!(
            x0 < x1 && y0 < y1 && x1 <= self.width && y1 <= self.height,
            "region [{x0}, {y0}, {x1}, {y1}) is empty or outside the {}x{} image",
            self.width,
            self.height
        );
        let mut sum = [0.0f64; 3];
        for y in y0..y1 {
            let row = y as usize * self.width as usize;
            for p in &self.pixels[row + x0 as usize..row + x1 as usize] {
                for c in 0..3 {
                    sum[c] += f64::from(p[c]);
                }
            }
        }
        let n = f64::from(x1 - x0) * f64::from(y1 - y0);
        sum.map(|s| s / n)
    }

    /// Writes the image, choosing the format by the extension of `path` (case-insensitive):
    ///
    /// - `.exr`: linear 32-bit float RGB, exactly the stored values; `exposure_stops` is NOT
    ///   applied (an EXR keeps radiance);
    /// - `.png`: 8-bit sRGB of clamp(L · 2^exposure_stops, 0, 1) through the sRGB transfer
    ///   curve (IEC 61966-2-1), rounded to nearest; NaN shows as black.
    ///
    /// Any other extension is an error naming the path. The file is written atomically (see
    /// [`write_atomically`]): on error no partial file is left under `path`.
    pub fn write(&self, path: &Path, exposure_stops: f32) -> Result<(), ImageError> {
        let format = Format::of(path).ok_or_else(|| ImageError::UnsupportedExtension {
            path: path.to_owned(),
        })?;
        if self.width == 0 || self.height == 0 || self.pixels.len() != self.pixel_count() {
            return Err(ImageError::InvalidImage {
                path: path.to_owned(),
                width: self.width,
                height: self.height,
                len: self.pixels.len(),
            });
        }
        // Both encoders need `Seek`, so encode in memory, then write atomically.
        let bytes = match format {
            Format::Exr => self.encode_exr().map_err(|source| ImageError::Exr {
                path: path.to_owned(),
                source,
            })?,
            Format::Png => self
                .encode_png(exposure_stops)
                .map_err(|source| ImageError::Png {
                    path: path.to_owned(),
                    source,
                })?,
        };
        write_atomically(path, |w| w.write_all(&bytes)).map_err(|source| ImageError::Io {
            path: path.to_owned(),
            source,
        })
    }

    /// Reads the R, G and B channels of the first RGB layer of an OpenEXR file as f32
    /// (half or uint channels are converted). Other channels (alpha, AOVs) are ignored.
    pub fn read_exr(path: &Path) -> Result<Image, ImageError> {
        use exr::prelude::*;
        let bytes = crate::io::open::read_checked(path, crate::io::open::Kind::Geometry).map_err(
            |source| ImageError::Io {
                path: path.to_owned(),
                source,
            },
        )?;
        let exr_err = |source| ImageError::Exr {
            path: path.to_owned(),
            source,
        };
        let image = read()
            .no_deep_data()
            .largest_resolution_level()
            .specific_channels()
            .required("R")
            .required("G")
            .required("B")
            .collect_pixels(
                |size: Vec2<usize>, _| Self {
                    width: size.width() as u32,
                    height: size.height() as u32,
                    pixels: vec![[0.0; 3]; size.area()],
                },
                |image: &mut Self, pos: Vec2<usize>, (r, g, b): (f32, f32, f32)| {
                    let i = pos.y() * image.width as usize + pos.x();
                    image.pixels[i] = [r, g, b];
                },
            )
            .first_valid_layer()
            .all_attributes()
            .from_buffered(Cursor::new(bytes))
            .map_err(exr_err)?;
        Ok(image.layer_data.channel_data.pixels)
    }

    fn pixel_count(&self) -> usize {
        self.width as usize * self.height as usize
    }

    fn encode_exr(&self) -> exr::error::Result<Vec<u8>> {
        use exr::prelude::*;
        let width = self.width as usize;
        let channels = SpecificChannels::rgb(|pos: Vec2<usize>| {
            let [r, g, b] = self.pixels[pos.y() * width + pos.x()];
            (r, g, b)
        });
        let layer = Layer::new(
            (width, self.height as usize),
            LayerAttributes::default(),
            Encoding::FAST_LOSSLESS,
            channels,
        );
        let mut bytes = Vec::new();
        exr::prelude::Image::from_layer(layer)
            .write()
            .to_buffered(Cursor::new(&mut bytes))?;
        Ok(bytes)
    }

    fn encode_png(&self, exposure_stops: f32) -> image::ImageResult<Vec<u8>> {
        let scale = exposure_stops.exp2();
        let data: Vec<u8> = self
            .pixels
            .iter()
            .flat_map(|p| p.map(|l| srgb_byte(l * scale)))
            .collect();
        let mut bytes = Vec::new();
        image::ImageEncoder::write_image(
            image::codecs::png::PngEncoder::new(&mut bytes),
            &data,
            self.width,
            self.height,
            image::ExtendedColorType::Rgb8,
        )?;
        Ok(bytes)
    }
}

/// The 8-bit sRGB code of a linear value: clamp to [0, 1], apply the sRGB transfer curve
/// (12.92·v below 0.0031308, else 1.055·v^(1/2.4) − 0.055), round to nearest.
pub fn srgb_byte(linear: f32) -> u8 {
    let v = if linear.is_nan() {
        0.0
    } else {
        f64::from(linear.clamp(0.0, 1.0))
    };
    let encoded = if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    };
    (encoded * 255.0).round().clamp(0.0, 255.0) as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gradient(width: u32, height: u32) -> Image {
        let mut image = Image::new(width, height);
        for (i, p) in image.pixels.iter_mut().enumerate() {
            let f = i as f32;
            *p = [f * 0.1, 1.0 / (f + 1.0), -f * 1e-3 + 1e-7];
        }
        image
    }

    #[test]
    fn srgb_curve_values() {
        assert_eq!(srgb_byte(0.0), 0);
        assert_eq!(srgb_byte(-1.0), 0);
        assert_eq!(srgb_byte(f32::NAN), 0);
        assert_eq!(srgb_byte(1.0), 255);
        assert_eq!(srgb_byte(7.0), 255);
        assert_eq!(srgb_byte(f32::INFINITY), 255);
        assert_eq!(srgb_byte(0.5), 188);
        assert_eq!(srgb_byte(0.18), 118);
        // Linear segment: 0.001 * 12.92 * 255 = 3.29.
        assert_eq!(srgb_byte(0.001), 3);
    }

    #[test]
    fn exr_round_trip_is_exact() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("img.exr");
        let image = gradient(7, 5);
        image.write(&path, 3.0).unwrap();
        let back = Image::read_exr(&path).unwrap();
        assert_eq!(back, image, "exposure must not touch EXR data");
    }

    #[test]
    fn png_has_size_and_srgb_values() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("img.PNG");
        let mut image = Image::new(3, 2);
        image.pixels.fill([0.5, 0.25, 2.0]);
        image.pixels[5] = [0.125, 0.0, 0.0];
        image.write(&path, 0.0).unwrap();
        let png = image::open(&path).unwrap().to_rgb8();
        assert_eq!(png.dimensions(), (3, 2));
        assert_eq!(png.get_pixel(0, 0).0, [188, 137, 255]);
        assert_eq!(png.get_pixel(2, 1).0, [99, 0, 0]);

        // One stop up doubles the radiance before encoding.
        image.write(&path, 1.0).unwrap();
        let png = image::open(&path).unwrap().to_rgb8();
        assert_eq!(png.get_pixel(0, 0).0, [255, 188, 255]);
        assert_eq!(png.get_pixel(2, 1).0, [137, 0, 0]);
    }

    #[test]
    fn unknown_extension_is_an_error_naming_the_path() {
        let dir = tempfile::tempdir().unwrap();
        for name in ["img.jpg", "img"] {
            let path = dir.path().join(name);
            let err = Image::new(2, 2).write(&path, 0.0).unwrap_err();
            assert!(matches!(err, ImageError::UnsupportedExtension { .. }));
            assert!(err.to_string().contains(name), "{err}");
            assert!(!path.exists());
        }
    }

    #[test]
    fn unwritable_path_is_an_error_and_leaves_no_file() {
        let dir = tempfile::tempdir().unwrap();
        for name in ["img.png", "img.exr"] {
            let path = dir.path().join("missing").join(name);
            let err = gradient(4, 4).write(&path, 0.0).unwrap_err();
            assert!(matches!(err, ImageError::Io { .. }), "{err}");
            assert!(err.to_string().contains(name), "{err}");
            assert!(!path.exists());
        }
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }

    #[test]
    fn empty_or_inconsistent_image_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("img.png");
        assert!(matches!(
            Image::new(0, 4).write(&path, 0.0),
            Err(ImageError::InvalidImage { .. })
        ));
        let mut image = Image::new(2, 2);
        image.pixels.pop();
        assert!(matches!(
            image.write(&path, 0.0),
            Err(ImageError::InvalidImage { .. })
        ));
        assert!(!path.exists());
    }

    #[test]
    fn read_exr_errors_name_the_path() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("missing.exr");
        let err = Image::read_exr(&missing).unwrap_err();
        assert!(matches!(err, ImageError::Io { .. }));
        assert!(err.to_string().contains("missing.exr"));

        let garbage = dir.path().join("garbage.exr");
        std::fs::write(&garbage, b"not an exr").unwrap();
        let err = Image::read_exr(&garbage).unwrap_err();
        assert!(matches!(err, ImageError::Exr { .. }));
        assert!(err.to_string().contains("garbage.exr"));
    }

    #[test]
    fn get_and_region_mean() {
        let mut image = Image::new(4, 3);
        for y in 0..3 {
            for x in 0..4 {
                image.pixels[(y * 4 + x) as usize] = [x as f32, y as f32, 1.0];
            }
        }
        assert_eq!(image.get(3, 1), [3.0, 1.0, 1.0]);
        assert_eq!(image.region_mean(1, 1, 3, 3), [1.5, 1.5, 1.0]);
        assert_eq!(image.region_mean(0, 0, 4, 3), [1.5, 1.0, 1.0]);
    }

    #[test]
    fn reads_the_reference_exr() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../../shared/reference/cornell_main.exr")
            .canonicalize();
        // A third-party (Mitsuba) file: the shared references lie beside the checkout.
        let Ok(path) = path else {
            eprintln!("skipped: shared/reference/cornell_main.exr not found");
            return;
        };
        let image = Image::read_exr(&path).unwrap();
        assert_eq!((image.width, image.height), (256, 256));
        assert!(image.pixels.iter().all(|p| p.iter().all(|c| c.is_finite())));
    }
}
