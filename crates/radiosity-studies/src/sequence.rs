//! Progressive image sequences: the pictures of progressive refinement after 0, 8, 16, …
//! shots, with or without the ambient term, optionally on an adaptively refined mesh, and a
//! labelled contact sheet of them.
//!
//! After Cohen, Chen, Wallace & Greenberg (1988), "A progressive refinement approach to fast
//! radiosity image generation": the solution is advanced shot by shot
//! ([`Progressive::shoot`]) and a frame is rendered whenever the shot count reaches one of
//! the requested counts, so frame N shows exactly N shots (fewer only when the unshot power
//! fell below the tolerance first: the frame then says so). Frame 0 shows the emitters
//! alone. With the ambient term each frame displays B_e + ρ_e·ambient, ambient =
//! R·Σ_p U_p A_p / Σ A, R = 1/(1 − ρ_avg) (see [`Solution::ambient`]), so early frames are
//! not too dark; both sequences converge to the same image.
//!
//! With adaptive refinement the mesh starts coarse and, after each frame, the elements where
//! the current radiosity changes fast are split ([`radiosity::mesh::refine`]); the state moves onto the
//! refined mesh with [`Progressive::refine`], so later frames show the mesh growing.
//!
//! See also: `radiosity progressive` (the command that writes the frames and the sheet).

use radiosity::accel::Visibility;
use radiosity::coupling::closure::Enclosure;
use radiosity::coupling::{Columns, Coupling, NearField};
use radiosity::display::Shading;
use radiosity::formfactor::engine;
use radiosity::mesh::{Mesh, RefineOptions};
use radiosity::pipeline::{render_elements, PipelineError, Shaded, SolveSettings};
use radiosity::progress::Progress;
use radiosity::render::{srgb_byte, Image, RenderOptions};
use radiosity::scene::{Camera, Scene};
use radiosity::solve::progressive::Progressive;
use radiosity::solve::{Flow, Solution, Step};
use std::f64::consts::PI;
use std::path::Path;

/// The most frames one sequence may ask for (the contact sheet has to stay viewable).
pub const MAX_FRAMES: usize = 64;

/// What to compute.
#[derive(Debug, Clone, PartialEq)]
pub struct SequenceOptions {
    /// Shot counts at which to take a frame, strictly increasing (see [`parse_frames`]).
    pub frames: Vec<usize>,
    /// Display B_e + ρ_e·ambient instead of the plain partial solution.
    pub ambient: bool,
    /// Refine the mesh adaptively between frames, starting from the coarse mesh
    /// ([`radiosity::pipeline::coarse_mesh_options`]).
    pub adaptive: Option<RefineOptions>,
}

/// How to draw each frame.
#[derive(Debug, Clone)]
pub struct View {
    pub camera: Camera,
    pub shading: Shading,
    /// Overlay the element edges (shows the refinement).
    pub wireframe: bool,
    pub render: RenderOptions,
}

/// What one frame shows.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameRecord {
    /// The shot count asked for.
    pub requested: usize,
    /// Shots taken before this frame: `requested`, or fewer when the solution converged first.
    pub shots: usize,
    /// Unshot power as a fraction of the emitted power (dimensionless).
    pub unshot_fraction: f64,
    /// The unshot fraction is at or below the tolerance (or nothing is left to shoot).
    pub converged: bool,
    /// Elements of the mesh the frame was rendered from.
    pub elements: usize,
    /// Solve time so far (form factors, shots and refinement; rendering excluded), s.
    pub seconds: f64,
    /// Area-weighted mean of the displayed radiance B/π over all elements, W·m⁻²·sr⁻¹.
    pub mean_radiance: [f64; 3],
}

impl FrameRecord {
    /// The frame stopped short of the shots it asked for because the solution converged.
    pub fn converged_early(&self) -> bool {
        self.shots < self.requested
    }

    /// The contact-sheet label: shot count, unshot power and (adaptive) element count.
    pub fn label(&self, show_elements: bool) -> Vec<String> {
        let mut lines = vec![if self.converged_early() {
            format!("{} shots (converged)", self.shots)
        } else if self.shots == 1 {
            "1 shot".to_owned()
        } else {
            format!("{} shots", self.shots)
        }];
        lines.push(format!("unshot {}", format_fraction(self.unshot_fraction)));
        if show_elements {
            lines.push(format!("{} elements", self.elements));
        }
        lines
    }
}

/// A fraction as a percentage with sensible digits ("41.2 %", "0.35 %", "4.1e-4 %").
pub fn format_fraction(f: f64) -> String {
    let pct = 100.0 * f;
    if pct >= 10.0 {
        format!("{pct:.1} %")
    } else if pct >= 0.01 {
        format!("{pct:.2} %")
    } else if pct == 0.0 {
        "0 %".to_owned()
    } else {
        format!("{pct:.1e} %")
    }
}

/// One frame: its record, the displayed radiosity per element (W·m⁻², ambient included when
/// asked for; indexed like the elements of the mesh at that frame) and the rendered image.
pub struct Frame {
    pub record: FrameRecord,
    pub radiosity: Vec<[f64; 3]>,
    pub image: Image,
}

/// A finished sequence: the frames, and the final mesh and solution.
pub struct Sequence {
    pub frames: Vec<Frame>,
    pub mesh: Mesh,
    pub solution: Solution,
}

/// Why a sequence could not be made.
#[derive(Debug, thiserror::Error)]
pub enum SequenceError {
    #[error("--frames: no shot counts given (expected e.g. 0,8,16,25,50,100)")]
    NoFrames,
    #[error("--frames: '{0}' is not a shot count (a whole number ≥ 0)")]
    BadFrame(String),
    #[error("--frames: shot counts must be strictly increasing, but {next} follows {previous}")]
    NotIncreasing { previous: usize, next: usize },
    #[error("--frames: at most {MAX_FRAMES} frames, got {0}")]
    TooManyFrames(usize),
    #[error(transparent)]
    Pipeline(#[from] PipelineError),
    #[error("writing {path}: {message}")]
    Write { path: String, message: String },
}

/// Parses a comma-separated list of shot counts ("0,8,16,25,50,100"): whole numbers,
/// strictly increasing, at most [`MAX_FRAMES`].
pub fn parse_frames(text: &str) -> Result<Vec<usize>, SequenceError> {
    let mut frames = Vec::new();
    for part in text.split(',').map(str::trim) {
        if part.is_empty() && text.trim().is_empty() {
            return Err(SequenceError::NoFrames);
        }
        let n: usize = part
            .parse()
            .map_err(|_| SequenceError::BadFrame(part.to_owned()))?;
        frames.push(n);
    }
    check_frames(&frames)?;
    Ok(frames)
}

fn check_frames(frames: &[usize]) -> Result<(), SequenceError> {
    if frames.is_empty() {
        return Err(SequenceError::NoFrames);
    }
    if frames.len() > MAX_FRAMES {
        return Err(SequenceError::TooManyFrames(frames.len()));
    }
    for w in frames.windows(2) {
        if w[1] <= w[0] {
            return Err(SequenceError::NotIncreasing {
                previous: w[0],
                next: w[1],
            });
        }
    }
    Ok(())
}

/// Solves `scene` by progressive refinement and renders a frame at each requested shot count.
///
/// Shooting stops at the last requested count or when the unshot power falls below
/// `settings.solve.tolerance` (a fraction of the emitted power), whichever comes first;
/// `settings.solve.max_shots` does not apply (the frames decide). With
/// `options.adaptive`, the mesh is refined after every frame but the last. The shots are
/// the library's own ([`Progressive::run`]), watched between frames.
pub fn run(
    scene: &Scene,
    settings: &SolveSettings,
    options: &SequenceOptions,
    view: &View,
    progress: &dyn Progress,
) -> Result<Sequence, SequenceError> {
    check_frames(&options.frames)?;
    let tolerance = settings.solve.tolerance;
    let mesh_options = match options.adaptive {
        Some(_) => radiosity::pipeline::coarse_mesh_options(&settings.mesh),
        None => settings.mesh,
    };
    let mut mesh = Mesh::build(scene, &mesh_options).map_err(PipelineError::from)?;
    // Visibility depends only on the surface polygons, which refinement keeps.
    let visibility = Visibility::new(&mesh);
    // Refinement splits elements but keeps the surfaces: the enclosure stays what it is.
    let enclosure = Enclosure::probe(&mesh, &visibility);
    let mut near = NearField::decide(&mesh);
    // Refinement budget when none is given: the element count of the uniform mesh.
    let refine = options.adaptive.map(|r| RefineOptions {
        max_elements: r.max_elements.or(Some(settings.mesh.elements)),
        ..r
    });
    let last = options.frames[options.frames.len() - 1];
    let cache = settings.solve.memory_limit / 2;
    let mut frames = Vec::with_capacity(options.frames.len());
    let mut state: Option<Progressive> = None;
    let mut form_factor_seconds = 0.0;
    progress.start("progressive", last as u64);
    let mut shown = 0usize;
    for (k, &requested) in options.frames.iter().enumerate() {
        let ff = engine(settings.form_factor, &mesh, &visibility, &near.per_element);
        let coupling = Columns::new(&mesh, ff.as_ref(), &near, enclosure, cache);
        let state = state.get_or_insert_with(|| Progressive::new(&coupling, &settings.solve));
        let mut watch = |step: &Step<'_>| {
            if step.index > shown {
                progress.inc((step.index - shown) as u64);
                shown = step.index;
            }
            if step.index % 8 == 0 {
                progress.message(&format!("unshot {}", format_fraction(step.residual)));
            }
            Flow::Continue
        };
        let exhausted = state.run(&coupling, tolerance, requested, &mut watch);
        form_factor_seconds += coupling.form_factor_seconds();
        let shots = state.shots();
        if shots < requested {
            // Converged early: the bar would otherwise stop short.
            progress.inc((requested.max(shown) - shown) as u64);
            shown = requested.max(shown);
        }
        let solution = state.solution(&coupling);
        let radiosity = solution.display_radiosity(&mesh, options.ambient);
        let shaded = Shaded {
            vertices: &mesh.vertices,
            elements: &mesh.elements,
            radiosity: &radiosity,
        };
        let image = render_elements(
            &shaded,
            &view.camera,
            view.shading,
            view.wireframe,
            &view.render,
        )?;
        let unshot_fraction = state.unshot_fraction();
        let record = FrameRecord {
            requested,
            shots,
            unshot_fraction,
            converged: exhausted || unshot_fraction <= tolerance,
            elements: mesh.len(),
            seconds: solution.stats.seconds,
            mean_radiance: mean_radiance(&mesh, &radiosity),
        };
        let converged = record.converged;
        frames.push(Frame {
            record,
            radiosity,
            image,
        });
        if let Some(refine) = &refine {
            if k + 1 < options.frames.len() && !converged {
                let marked = radiosity::mesh::refine::mark(&mesh, &solution.radiosity, refine);
                if marked.iter().any(|m| *m) {
                    let refined = radiosity::mesh::refine::refine(&mesh, &marked);
                    let refined_near = NearField::decide(&refined);
                    {
                        let refined_ff = engine(
                            settings.form_factor,
                            &refined,
                            &visibility,
                            &refined_near.per_element,
                        );
                        let refined_coupling = Columns::new(
                            &refined,
                            refined_ff.as_ref(),
                            &refined_near,
                            enclosure,
                            cache,
                        );
                        state.refine(&mesh, &refined_coupling);
                    }
                    drop(coupling);
                    drop(ff);
                    mesh = refined;
                    near = refined_near;
                }
            }
        }
    }
    progress.finish();
    let mut solution = {
        let ff = engine(settings.form_factor, &mesh, &visibility, &near.per_element);
        let coupling = Columns::new(&mesh, ff.as_ref(), &near, enclosure, cache);
        state
            .as_ref()
            .map(|s| s.solution(&coupling))
            .ok_or(SequenceError::NoFrames)?
    };
    solution.stats.form_factor_seconds = form_factor_seconds;
    Ok(Sequence {
        frames,
        solution,
        mesh,
    })
}

/// Area-weighted mean of B/π over all elements, W·m⁻²·sr⁻¹.
pub fn mean_radiance(mesh: &Mesh, radiosity: &[[f64; 3]]) -> [f64; 3] {
    let mut sum = [0.0; 3];
    let mut area = 0.0;
    for (e, b) in mesh.elements.iter().zip(radiosity) {
        for c in 0..3 {
            sum[c] += e.area * b[c];
        }
        area += e.area;
    }
    sum.map(|s| if area > 0.0 { s / area / PI } else { 0.0 })
}

/// The file name of the frame at a shot count: `frame_0008.png` (`ext` without the dot).
pub fn frame_file_name(shots: usize, ext: &str) -> String {
    format!("frame_{shots:04}.{ext}")
}

/// Gap between tiles and around the sheet, pixels.
const GAP: u32 = 8;
/// Sheet background (dark grey, so black frames stay visible as frames).
const SHEET_BACKGROUND: [u8; 3] = [40, 40, 40];
/// The narrowest tile (so that labels fit beside small frames), pixels.
const MIN_TILE_WIDTH: u32 = 150;
/// Frames per row of the contact sheet.
const SHEET_COLUMNS: usize = 6;

/// Label text size for frames of a given width, pixels.
fn label_size(tile_width: u32) -> u32 {
    (tile_width / 13).clamp(13, 26)
}

/// Composes a contact sheet: the frames side by side (up to six per row), each with its
/// label lines beneath, as 8-bit sRGB. `exposure` is in stops, as for the frames' PNGs:
/// pixel = clip(L·2^exposure) → sRGB ([`srgb_byte`]). Labels are set in the bundled DejaVu
/// Sans font.
pub fn contact_sheet(
    tiles: &[(&Image, Vec<String>)],
    exposure: f32,
) -> Result<image::RgbImage, SequenceError> {
    let font =
        ab_glyph::FontRef::try_from_slice(crate::font::FONT).map_err(|e| SequenceError::Write {
            path: "contact sheet".into(),
            message: format!("the bundled font: {e}"),
        })?;
    let columns = tiles.len().clamp(1, SHEET_COLUMNS);
    let rows = tiles.len().div_ceil(columns).max(1);
    let frame_w = tiles.iter().map(|t| t.0.width).max().unwrap_or(1);
    let frame_h = tiles.iter().map(|t| t.0.height).max().unwrap_or(1);
    let tile_w = frame_w.max(MIN_TILE_WIDTH);
    let text = label_size(tile_w);
    let line_h = text * 5 / 4;
    let max_lines = tiles.iter().map(|t| t.1.len()).max().unwrap_or(0) as u32;
    let tile_h = frame_h + GAP + max_lines * line_h;
    let width = GAP + columns as u32 * (tile_w + GAP);
    let height = GAP + rows as u32 * (tile_h + GAP);
    let mut sheet = image::RgbImage::from_pixel(width, height, image::Rgb(SHEET_BACKGROUND));
    let scale = 2f32.powf(exposure);
    for (i, (img, lines)) in tiles.iter().enumerate() {
        let (col, row) = ((i % columns) as u32, (i / columns) as u32);
        let (x0, y0) = (GAP + col * (tile_w + GAP), GAP + row * (tile_h + GAP));
        let left = x0 + (tile_w - img.width) / 2;
        for y in 0..img.height {
            for x in 0..img.width {
                let p = img.pixels[(y * img.width + x) as usize];
                sheet.put_pixel(
                    left + x,
                    y0 + y,
                    image::Rgb(p.map(|v| srgb_byte(v * scale))),
                );
            }
        }
        for (l, line) in lines.iter().enumerate() {
            // Baseline at 80 % of the line: DejaVu's ascent is 0.76 em.
            let baseline = y0 + frame_h + GAP / 2 + l as u32 * line_h + line_h * 4 / 5;
            draw_text(
                &mut sheet,
                &font,
                text as f32,
                x0 as f32 + 2.0,
                baseline as f32,
                line,
                LABEL_COLOUR,
            );
        }
    }
    Ok(sheet)
}

/// Label text colour on the sheet (sRGB).
const LABEL_COLOUR: [u8; 3] = [235, 235, 235];

/// Draws one line of text with its baseline at `baseline`, starting at `x` (pixels),
/// blending each glyph's coverage over the image; clipped at the image's edges.
pub(crate) fn draw_text(
    image: &mut image::RgbImage,
    font: &ab_glyph::FontRef,
    size: f32,
    x: f32,
    baseline: f32,
    text: &str,
    colour: [u8; 3],
) {
    use ab_glyph::{point, Font, ScaleFont};
    let scaled = font.as_scaled(size);
    let mut caret = x;
    let mut previous = None;
    for c in text.chars() {
        let id = scaled.glyph_id(c);
        if let Some(p) = previous {
            caret += scaled.kern(p, id);
        }
        previous = Some(id);
        let glyph = id.with_scale_and_position(size, point(caret, baseline));
        caret += scaled.h_advance(id);
        let Some(outline) = scaled.outline_glyph(glyph) else {
            continue; // a space
        };
        let bounds = outline.px_bounds();
        outline.draw(|gx, gy, coverage| {
            let px = bounds.min.x as i64 + i64::from(gx);
            let py = bounds.min.y as i64 + i64::from(gy);
            if px < 0 || py < 0 || px >= i64::from(image.width()) || py >= i64::from(image.height())
            {
                return;
            }
            let a = coverage.clamp(0.0, 1.0);
            let p = image.get_pixel_mut(px as u32, py as u32);
            for (v, c) in p.0.iter_mut().zip(colour) {
                *v = (f32::from(*v) * (1.0 - a) + f32::from(c) * a).round() as u8;
            }
        });
    }
}

/// Writes an 8-bit RGB image as PNG, atomically (a temporary name, renamed when complete).
pub fn write_png(image: &image::RgbImage, path: &Path) -> Result<(), SequenceError> {
    use image::ImageEncoder;
    radiosity::io::atomic::write_atomically(path, |w| {
        image::codecs::png::PngEncoder::new(w)
            .write_image(
                image.as_raw(),
                image.width(),
                image.height(),
                image::ExtendedColorType::Rgb8,
            )
            .map_err(std::io::Error::other)
    })
    .map_err(|e| SequenceError::Write {
        path: path.display().to_string(),
        message: e.to_string(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_parse_and_reject_bad_lists() {
        assert_eq!(
            parse_frames("0,8,16, 25,50,100").unwrap(),
            vec![0, 8, 16, 25, 50, 100]
        );
        assert_eq!(parse_frames("7").unwrap(), vec![7]);
        assert!(matches!(parse_frames(""), Err(SequenceError::NoFrames)));
        assert!(matches!(parse_frames("0,x"), Err(SequenceError::BadFrame(s)) if s == "x"));
        assert!(matches!(parse_frames("0,-8"), Err(SequenceError::BadFrame(s)) if s == "-8"));
        assert!(matches!(parse_frames("0,,8"), Err(SequenceError::BadFrame(s)) if s.is_empty()));
        assert!(matches!(
            parse_frames("0,16,8"),
            Err(SequenceError::NotIncreasing {
                previous: 16,
                next: 8
            })
        ));
        assert!(matches!(
            parse_frames("3,3"),
            Err(SequenceError::NotIncreasing { .. })
        ));
        let many: Vec<String> = (0..=MAX_FRAMES).map(|i| i.to_string()).collect();
        assert!(matches!(
            parse_frames(&many.join(",")),
            Err(SequenceError::TooManyFrames(_))
        ));
    }

    #[test]
    fn fractions_format_readably() {
        assert_eq!(format_fraction(0.412), "41.2 %");
        assert_eq!(format_fraction(0.0035), "0.35 %");
        assert_eq!(format_fraction(4.1e-6), "4.1e-4 %");
        assert_eq!(format_fraction(0.0), "0 %");
    }
}
