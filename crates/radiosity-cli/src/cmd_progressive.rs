//! `radiosity progressive`: progressive-refinement image sequences and their contact sheet.

use crate::args::{parse_vec3, SolveArgs};
use crate::commands::{load_scene, solve_settings};
use crate::progress::Bars;
use anyhow::{bail, Context, Result};
use clap::Args;
use glam::DVec3;
use radiosity::display::Shading;
use radiosity::refine::RefineOptions;
use radiosity::render::RenderOptions;
use radiosity::scene::{Camera, Scene};
use radiosity::sequence::{self, frame_file_name, SequenceOptions, View};
use std::path::{Path, PathBuf};

#[derive(Debug, Args)]
pub struct ProgressiveArgs {
    /// Scene file (.obj or .json); the built-in Cornell box if omitted.
    pub scene: Option<PathBuf>,
    /// Output directory (created if missing): frame_NNNN.png per frame, sheet.png.
    #[arg(short, long, value_name = "DIR")]
    pub output: PathBuf,
    /// Shot counts to show, comma-separated and increasing; 0 shows the emitters alone.
    #[arg(long, value_name = "N,N,...", default_value = "0,8,16,25,50,100")]
    pub frames: String,
    /// Add the ambient term (Cohen et al. 1988) so early frames are not too dark.
    #[arg(long)]
    pub ambient: bool,
    /// Also write each frame as linear float RGB radiance (frame_NNNN.exr).
    #[arg(long)]
    pub hdr: bool,
    /// Shoot ω × the unshot radiosity (over-relaxation), 0 < ω < 2 [default: 1].
    #[arg(long, value_name = "W")]
    pub overshoot: Option<f64>,
    /// Start from a coarse mesh and refine it between frames where the radiosity changes
    /// fast (use --wireframe to see it grow).
    #[arg(long)]
    pub adaptive: bool,
    /// Split an element when it differs from a neighbour by more than this fraction of the
    /// mean reflected radiosity [default: 0.1].
    #[arg(long, value_name = "X", requires = "adaptive")]
    pub refine_threshold: Option<f64>,
    /// Maximum number of times an element may be split [default: 3].
    #[arg(long, value_name = "D", requires = "adaptive")]
    pub max_depth: Option<u8>,
    #[command(flatten)]
    pub view: ViewArgs,
    #[command(flatten)]
    pub mesh: MeshArgs,
}

/// Camera, image size and display options, as for `render`.
#[derive(Debug, Args)]
pub struct ViewArgs {
    /// Image width in pixels [default: 512].
    #[arg(long)]
    pub width: Option<u32>,
    /// Image height in pixels [default: 512].
    #[arg(long)]
    pub height: Option<u32>,
    /// Camera position x,y,z in metres [default: the scene's camera].
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub eye: Option<DVec3>,
    /// Point the camera looks at, x,y,z.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub target: Option<DVec3>,
    /// Camera up direction x,y,z.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub up: Option<DVec3>,
    /// Vertical field of view in degrees.
    #[arg(long)]
    pub fov: Option<f64>,
    /// Flat shading (one value per element) instead of smooth (Gouraud) shading.
    #[arg(long)]
    pub flat: bool,
    /// Overlay the element edges.
    #[arg(long)]
    pub wireframe: bool,
    /// PNG exposure in stops (pixel = L · 2^exposure before the sRGB curve) [default: 0].
    #[arg(long, allow_hyphen_values = true)]
    pub exposure: Option<f64>,
    /// Anti-aliasing: supersamples per pixel axis (box filter).
    #[arg(long, default_value_t = 4)]
    pub samples: u32,
}

/// Meshing and form-factor options, as for `render`.
#[derive(Debug, Args)]
pub struct MeshArgs {
    /// Maximum element edge length in metres (overrides --elements).
    #[arg(long, value_name = "METRES")]
    pub max_element_size: Option<f64>,
    /// Approximate total number of elements (with --adaptive: of the uniform mesh it
    /// starts at a quarter of) [default: 4000].
    #[arg(long, value_name = "N")]
    pub elements: Option<usize>,
    /// Elements per patch edge: patches shoot, elements receive [default: 3].
    #[arg(long, value_name = "K")]
    pub patch_subdivision: Option<u32>,
    /// Form-factor method [default: raycast].
    #[arg(long)]
    pub form_factor: Option<String>,
    /// Stop shooting once the unshot power is below this fraction of the emitted power
    /// [default: 1e-3].
    #[arg(long)]
    pub tolerance: Option<f64>,
    /// Show no progress bars and no summary.
    #[arg(long, short)]
    pub quiet: bool,
}

impl MeshArgs {
    pub fn solve_args(&self) -> SolveArgs {
        SolveArgs {
            max_element_size: self.max_element_size,
            elements: self.elements,
            patch_subdivision: self.patch_subdivision,
            solver: None,
            form_factor: self.form_factor.clone(),
            tolerance: self.tolerance,
            max_shots: None,
            adaptive: false,
            refine_threshold: None,
            max_depth: None,
            quiet: self.quiet,
        }
    }
}

pub fn run(args: ProgressiveArgs) -> Result<()> {
    let frames = sequence::parse_frames(&args.frames)?;
    let quiet = args.mesh.quiet;
    if let Some(w) = args.overshoot {
        if !(w > 0.0 && w < 2.0) {
            bail!("--overshoot must be between 0 and 2 (exclusive), got {w}");
        }
    }
    let adaptive = if args.adaptive {
        let defaults = RefineOptions::default();
        let threshold = args.refine_threshold.unwrap_or(defaults.threshold);
        if !(threshold.is_finite() && threshold > 0.0) {
            bail!("--refine-threshold must be a positive number, got {threshold}");
        }
        let max_depth = args.max_depth.unwrap_or(defaults.max_depth);
        if max_depth > 8 {
            bail!("--max-depth must be at most 8 (each level quadruples the elements), got {max_depth}");
        }
        Some(RefineOptions {
            threshold,
            max_depth,
            max_elements: None,
        })
    } else {
        None
    };
    let (scene, file_settings) = load_scene(args.scene.as_deref())?;
    let mut settings = solve_settings(&args.mesh.solve_args(), &file_settings)?;
    if let Some(w) = args.overshoot {
        settings.solve.overshoot = w;
    }
    let width = args.view.width.or(file_settings.width).unwrap_or(512);
    let height = args.view.height.or(file_settings.height).unwrap_or(512);
    if width == 0 || height == 0 || width > 16384 || height > 16384 {
        bail!("--width and --height must be between 1 and 16384 pixels, got {width}×{height}");
    }
    let exposure = args.view.exposure.or(file_settings.exposure).unwrap_or(0.0);
    if !exposure.is_finite() || exposure.abs() > 64.0 {
        bail!("--exposure must be a finite number of stops between -64 and 64, got {exposure}");
    }
    let ambient = args.ambient || file_settings.ambient.unwrap_or(false);
    let view = View {
        camera: camera(&args.view, &scene)?,
        shading: if args.view.flat {
            Shading::Flat
        } else {
            Shading::Smooth
        },
        wireframe: args.view.wireframe,
        render: RenderOptions {
            width,
            height,
            samples_per_axis: args.view.samples,
            ..RenderOptions::default()
        },
    };
    prepare_output_dir(&args.output)?;

    let options = SequenceOptions {
        frames,
        ambient,
        adaptive,
    };
    let bars = Bars::new(quiet);
    let result = sequence::run(&scene, &settings, &options, &view, &bars)?;

    let dir = &args.output;
    let mut tiles = Vec::with_capacity(result.frames.len());
    for frame in &result.frames {
        let r = &frame.record;
        let png = dir.join(frame_file_name(r.requested, "png"));
        frame
            .image
            .write(&png, exposure as f32)
            .with_context(|| format!("writing {}", png.display()))?;
        if args.hdr {
            let exr = dir.join(frame_file_name(r.requested, "exr"));
            frame
                .image
                .write(&exr, 0.0)
                .with_context(|| format!("writing {}", exr.display()))?;
        }
        if !quiet {
            let converged = if r.converged_early() {
                format!(
                    " — converged after {} shots (unshot below the tolerance)",
                    r.shots
                )
            } else {
                String::new()
            };
            eprintln!(
                "frame {:>5}: {} shots, unshot {}, {} elements, {:.2} s{converged} → {}",
                r.requested,
                r.shots,
                sequence::format_fraction(r.unshot_fraction),
                r.elements,
                r.seconds,
                png.display()
            );
        }
        tiles.push((&frame.image, r.label(options.adaptive.is_some())));
    }
    let sheet_path = dir.join("sheet.png");
    let sheet = sequence::contact_sheet(&tiles, exposure as f32)?;
    sequence::write_png(&sheet, &sheet_path)?;
    if !quiet {
        eprintln!(
            "wrote {} frames ({width}×{height}) and the contact sheet {}",
            result.frames.len(),
            sheet_path.display()
        );
    }
    Ok(())
}

/// Creates the output directory and checks that files can be created in it, before any
/// work is done.
pub fn prepare_output_dir(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir)
        .with_context(|| format!("creating output directory {}", dir.display()))?;
    let probe = dir.join(format!(".radiosity-write-test-{}", std::process::id()));
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&probe)
        .with_context(|| format!("output directory {} is not writable", dir.display()))?;
    std::fs::remove_file(&probe).with_context(|| format!("cleaning up {}", probe.display()))?;
    Ok(())
}

/// The camera: flags over the scene's camera over one framing the scene.
fn camera(args: &ViewArgs, scene: &Scene) -> Result<Camera> {
    crate::commands::camera_with(
        args.eye,
        args.target,
        args.up,
        args.fov,
        scene.camera_or_default(),
    )
}
