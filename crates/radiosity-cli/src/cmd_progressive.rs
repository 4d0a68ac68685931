//! `radiosity progressive`: progressive-refinement image sequences and their contact sheet.

use crate::args::{SolveArgs, ViewArgs};
use crate::commands::{load_scene, render_options, scene_camera};
use crate::progress::Bars;
use anyhow::{bail, Context, Result};
use clap::Args;
use radiosity::display::Shading;
use radiosity::solve::SolverKind;
use radiosity_studies::sequence::{self, frame_file_name, SequenceOptions, View};
use std::path::{Path, PathBuf};

/// `radiosity progressive`.
#[derive(Debug, Args)]
pub struct ProgressiveArgs {
    /// Scene file (.obj, .gltf, .glb, .mgf or .json); the built-in Cornell box if omitted.
    pub scene: Option<PathBuf>,
    /// Output directory (created if missing): frame_NNNN.png per frame, sheet.png.
    #[arg(short, long, value_name = "DIR")]
    pub output: PathBuf,
    /// Shot counts to show, comma-separated and increasing; 0 shows the emitters alone.
    #[arg(long, value_name = "N,N,...", default_value = "0,8,16,25,50,100")]
    pub frames: String,
    /// Also write each frame as linear float RGB radiance (frame_NNNN.exr).
    #[arg(long)]
    pub hdr: bool,
    #[command(flatten)]
    pub view: ViewArgs,
    #[command(flatten)]
    pub solve: SolveArgs,
}

/// Runs `radiosity progressive`.
pub fn run(args: ProgressiveArgs) -> Result<()> {
    let frames = sequence::parse_frames(&args.frames)?;
    let quiet = args.solve.quiet;
    if matches!(args.solve.solver, Some(s) if s != SolverKind::Progressive) {
        bail!("--solver does not apply to `progressive`: it always shoots");
    }
    if args.solve.max_shots.is_some() {
        bail!("--max-shots does not apply to `progressive`: --frames decides the shots");
    }
    let loaded = load_scene(args.scene.as_deref(), &args.solve)?;
    let mut flags = args.solve.overrides();
    // Shooting is what this command shows, whatever the default solver.
    flags.solver = Some(SolverKind::Progressive);
    args.view.add_to(&mut flags);
    let settings = loaded.settings(&flags)?;
    let scene = &loaded.scene;
    let view = View {
        camera: scene_camera(scene, &args.view)?,
        shading: if args.view.flat {
            Shading::Flat
        } else {
            Shading::Smooth
        },
        wireframe: args.view.wireframe,
        render: render_options(&settings),
    };
    prepare_output_dir(&args.output)?;

    let options = SequenceOptions {
        frames,
        ambient: settings.render.ambient,
        adaptive: settings.refine,
    };
    let bars = Bars::new(quiet);
    let result = sequence::run(scene, &settings.solve, &options, &view, &bars)?;
    drop(bars);

    let exposure = settings.render.exposure as f32;
    let dir = &args.output;
    let mut tiles = Vec::with_capacity(result.frames.len());
    for frame in &result.frames {
        let r = &frame.record;
        let png = dir.join(frame_file_name(r.requested, "png"));
        frame
            .image
            .write(&png, exposure)
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
            stderr_line!(
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
    let sheet = sequence::contact_sheet(&tiles, exposure)?;
    sequence::write_png(&sheet, &sheet_path)?;
    if !quiet {
        stderr_line!(
            "wrote {} frames ({}×{}) and the contact sheet {}",
            result.frames.len(),
            settings.render.width,
            settings.render.height,
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
