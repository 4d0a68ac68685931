//! `render` and `solve`: load the scene once, resolve the settings in the library, run the
//! pipeline, write the outputs.

use crate::args::{Cli, Command, RenderArgs, SolveArgs, SolveCmdArgs};
use crate::progress::Bars;
use anyhow::{bail, Context, Result};
use radiosity::display::Shading;
use radiosity::export::lightmap::AtlasSize;
use radiosity::export::{ExportOptions, VertexColors};
use radiosity::io::formats::{load_any_with, LoadOptions};
use radiosity::io::scene_file::SceneSettings;
use radiosity::io::solution_file::SolutionFile;
use radiosity::pipeline::{
    render_elements, solve_scene_adaptive_observed, solve_scene_observed, Shaded, Solved,
};
use radiosity::render::RenderOptions;
use radiosity::report::Report;
use radiosity::scene::{Camera, Scene};
use radiosity::settings::{resolve, Overrides, Settings};
use radiosity::solve::SolverKind;
use std::path::{Path, PathBuf};

/// Runs a parsed command line.
pub fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Render(args) => render(args),
        Command::Solve(args) => solve(args),
        Command::Formfactor(args) => crate::cmd_formfactor::run(args),
        Command::Progressive(args) => crate::cmd_progressive::run(args),
        Command::Compare(args) => crate::cmd_compare::run(args),
        Command::View(args) => crate::cmd_view::run(args),
        Command::Completions(args) => crate::cmd_shell::completions(args),
        Command::Man(args) => crate::cmd_shell::man(args),
        Command::Measure(args) => crate::cmd_measure::run(args),
    }
}

/// A scene and its file settings (with the name to report the file by); the built-in
/// Cornell box when no path is given.
pub(crate) struct Loaded {
    pub scene: Scene,
    pub file_settings: SceneSettings,
    pub file: Option<String>,
    /// The readers' warnings and [`radiosity::diagnose::check`]'s, already printed.
    pub warnings: Vec<String>,
}

/// Loads the scene (or the built-in Cornell box) with the reading flags of `solve`, and
/// prints the readers' warnings and those of [`radiosity::diagnose::check`] on stderr (also
/// with --quiet: they are not progress).
pub(crate) fn load_scene(path: Option<&Path>, solve: &SolveArgs) -> Result<Loaded> {
    let load = &solve.load;
    let options = LoadOptions {
        strict: load.strict,
        two_sided: load.two_sided,
        emission_scale: match load.emission_scale {
            None => LoadOptions::default().emission_scale,
            Some(x) if x.is_finite() && x >= 0.0 => x,
            Some(x) => bail!("--emission-scale must be a finite number ≥ 0, got {x}"),
        },
    };
    let mut loaded = match path {
        None => {
            let mut scene = radiosity::cornell::cornell_box();
            if options.two_sided {
                scene.materials.iter_mut().for_each(|m| m.two_sided = true);
            }
            Loaded {
                scene,
                file_settings: SceneSettings::default(),
                file: None,
                warnings: Vec::new(),
            }
        }
        Some(p) => {
            // Scene errors name the file (and line, object) themselves.
            let loaded = load_any_with(p, &options)?;
            Loaded {
                scene: loaded.scene,
                file_settings: loaded.settings,
                file: Some(p.display().to_string()),
                warnings: loaded.warnings,
            }
        }
    };
    loaded.warnings.extend(radiosity::diagnose::check(
        &loaded.scene,
        radiosity::diagnose::SOLVER_USES_LIGHTS,
    ));
    for warning in &loaded.warnings {
        stderr_line!("warning: {warning}");
    }
    Ok(loaded)
}

/// Refuses to overwrite an existing file unless `force` (checked before any work).
pub(crate) fn refuse_overwrite(path: &Path, force: bool) -> Result<()> {
    if !force && path.exists() {
        bail!(
            "{} exists; use --force to overwrite it, or -o/--output another name",
            path.display()
        );
    }
    Ok(())
}

/// The name outputs are given after the input: the file stem (`room.obj` → `room`, a saved
/// `box.solution.json` → `box`), else the scene's name; a name that is empty or not a plain
/// file name (a path, `..`) becomes `render`, so it cannot write elsewhere.
pub(crate) fn output_stem(input: Option<&Path>, scene_name: &str) -> String {
    let stem = input
        .and_then(|p| p.file_stem())
        .map(|s| s.to_string_lossy().into_owned());
    let stem = stem.map(|s| s.strip_suffix(".solution").map(str::to_owned).unwrap_or(s));
    let name = stem.unwrap_or_else(|| scene_name.to_owned());
    let plain = !name.is_empty()
        && name != "."
        && name != ".."
        && !name.contains(['/', '\\'])
        && Path::new(&name).file_name().is_some();
    if plain {
        name
    } else {
        "render".to_owned()
    }
}

impl Loaded {
    /// Defaults < the scene file's settings < the flags, validated by the library.
    pub fn settings(&self, flags: &Overrides) -> Result<Settings> {
        Ok(resolve(
            self.file.as_deref().map(|f| (&self.file_settings, f)),
            flags,
        )?)
    }
}

pub(crate) fn run_solve(scene: &Scene, settings: &Settings, args: &SolveArgs) -> Result<Solved> {
    let bars = Bars::new(args.quiet);
    let mut observer = &bars;
    let solved = match &settings.refine {
        Some(refine) => {
            solve_scene_adaptive_observed(scene, &settings.solve, refine, &bars, &mut observer)?
        }
        None => solve_scene_observed(scene, &settings.solve, &bars, &mut observer)?,
    };
    drop(bars);
    if !args.quiet {
        let st = &solved.solution.stats;
        let what = if st.solver == SolverKind::Progressive {
            format!(
                "{} shots, unshot power fraction {:.2e}",
                st.iterations, st.residual
            )
        } else {
            format!(
                "{} iterations, relative change {:.2e}",
                st.iterations, st.residual
            )
        };
        stderr_line!(
            "solved '{}': {} elements, {} patches, {} solver with {} form factors: {what} in {:.2} s ({:.2} s form factors)",
            scene.name,
            solved.mesh.len(),
            solved.mesh.patches.len(),
            st.solver,
            solved.form_factor,
            st.seconds,
            st.form_factor_seconds,
        );
        if let Some(h) = &solved.hierarchy {
            stderr_line!(
                "hierarchy: {} links, {} nodes, about {:.0} MiB, link tolerance ε {}",
                h.links,
                h.nodes,
                h.bytes as f64 / f64::from(1 << 20),
                h.epsilon
            );
            for warning in h.warnings() {
                stderr_line!("warning: {warning}");
            }
        }
    }
    Ok(solved)
}

fn solve(args: SolveCmdArgs) -> Result<()> {
    let loaded = load_scene(args.scene.as_deref(), &args.solve)?;
    let settings = loaded.settings(&args.solve.overrides())?;
    let export_options = match &args.bake {
        Some(_) => Some(bake_options(&args)?),
        None => None,
    };
    let mut outputs: Vec<PathBuf> = [&args.report, &args.save]
        .into_iter()
        .flatten()
        .cloned()
        .collect();
    if let Some(glb) = &args.bake {
        let (exr, png) = radiosity::export::lightmap_paths(glb);
        outputs.extend([glb.clone(), exr, png]);
    }
    for path in &outputs {
        refuse_overwrite(path, args.force)?;
        radiosity::io::atomic::check_writable(path)
            .with_context(|| format!("cannot write {}", path.display()))?;
    }
    let solved = run_solve(&loaded.scene, &settings, &args.solve)?;
    let scene = &loaded.scene;
    let mut report = Report::new(
        &scene.name,
        &solved.mesh,
        &solved.solution,
        solved.form_factor.name(),
    )
    .with_lights(&scene.lights);
    report.warnings = loaded.warnings.clone();
    if let Some(h) = &solved.hierarchy {
        report.warnings.extend(h.warnings());
    }
    if !args.solve.quiet {
        let t = &report.totals;
        let fmt = |p: [f64; 3]| format!("({:.4}, {:.4}, {:.4}) W", p[0], p[1], p[2]);
        stderr_line!(
            "power: emitted {}, absorbed {}, escaped {}, unshot {}",
            fmt(t.emitted_power),
            fmt(t.absorbed_power),
            fmt(t.escaped_power),
            fmt(t.unshot_power)
        );
    }
    if let Some(path) = &args.report {
        radiosity::io::atomic::write_atomically(path, |w| {
            serde_json::to_writer_pretty(&mut *w, &report).map_err(std::io::Error::other)?;
            writeln!(w)
        })
        .with_context(|| format!("writing report {}", path.display()))?;
    }
    if let Some(path) = &args.save {
        SolutionFile::new(&scene.name, scene.camera, &solved.mesh, &solved.solution).save(path)?;
    }
    if let (Some(path), Some(options)) = (&args.bake, &export_options) {
        let radiosity = solved.solution.display_radiosity(&solved.mesh, false);
        let baked = radiosity::export::solution::baked_scene(scene, &solved.mesh, &radiosity);
        let summary = radiosity::export::export(&baked, path, options)
            .with_context(|| format!("baking {}", path.display()))?;
        if !args.solve.quiet {
            stderr_line!(
                "wrote {} ({} charts in a {}×{} lightmap, {:.0} texels/m) with {} and {}",
                summary.glb.display(),
                summary.charts,
                summary.atlas.0,
                summary.atlas.1,
                summary.texels_per_metre,
                summary.png.display(),
                summary.exr.display()
            );
        }
    }
    if args.report.is_none() && args.save.is_none() && args.bake.is_none() {
        // Nothing asked to be written: print the report so the solve is not wasted.
        crate::write_stdout(&(serde_json::to_string_pretty(&report)? + "\n"))?;
    }
    Ok(())
}

fn render(args: RenderArgs) -> Result<()> {
    let mut flags = args.solve.overrides();
    args.view.add_to(&mut flags);
    let shading = if args.view.flat {
        Shading::Flat
    } else {
        Shading::Smooth
    };
    if let (Some(_), Some(out)) = (args.false_colour, &args.output) {
        crate::cmd_falsecolour::check_png(out)?;
    }
    let output_for = |input: Option<&Path>, name: &str| -> Result<PathBuf> {
        let output = args
            .output
            .clone()
            .unwrap_or_else(|| PathBuf::from(format!("{}.png", output_stem(input, name))));
        refuse_overwrite(&output, args.force)?;
        radiosity::render::check_output(&output)?;
        Ok(output)
    };
    // Everything to draw: vertices, elements and displayed radiosity, from a saved solution
    // or a fresh solve, with the camera and the output path checked before any work.
    let (vertices, elements, radiosity, camera, output, settings) = if let Some(path) =
        &args.solution
    {
        // Solution-file errors name the file and the key themselves.
        let file = SolutionFile::load(path)?;
        let settings = resolve(None, &flags)?;
        let output = output_for(Some(path), &file.scene)?;
        let base = file.camera.map(Camera::from).unwrap_or_default();
        let vertices = file.vertices();
        let camera = radiosity::settings::camera(base, centre_of(&vertices), &args.view.camera())?;
        let radiosity = match args.false_colour {
            Some(q) => crate::cmd_falsecolour::values(q, &file.radiosity, &file.irradiance),
            None => file.display_radiosity(settings.render.ambient),
        };
        (vertices, file.elements, radiosity, camera, output, settings)
    } else {
        let loaded = load_scene(args.scene.as_deref(), &args.solve)?;
        let settings = loaded.settings(&flags)?;
        let scene = &loaded.scene;
        let output = output_for(args.scene.as_deref(), &scene.name)?;
        let camera = scene_camera(scene, &args.view)?;
        let solved = run_solve(scene, &settings, &args.solve)?;
        let radiosity = match args.false_colour {
            Some(q) => crate::cmd_falsecolour::values(
                q,
                &solved.solution.radiosity,
                &solved.solution.irradiance,
            ),
            None => solved
                .solution
                .display_radiosity(&solved.mesh, settings.render.ambient),
        };
        let mesh = solved.mesh;
        (
            mesh.vertices,
            mesh.elements,
            radiosity,
            camera,
            output,
            settings,
        )
    };
    if let Some(quantity) = args.false_colour {
        let shaded = Shaded {
            vertices: &vertices,
            elements: &elements,
            radiosity: &radiosity,
        };
        return crate::cmd_falsecolour::render(
            quantity,
            &shaded,
            &camera,
            shading,
            &render_options(&settings),
            &output,
            args.solve.quiet,
        );
    }
    let shaded = Shaded {
        vertices: &vertices,
        elements: &elements,
        radiosity: &radiosity,
    };
    let image = render_elements(
        &shaded,
        &camera,
        shading,
        args.view.wireframe,
        &render_options(&settings),
    )?;
    image
        .write(&output, settings.render.exposure as f32)
        .with_context(|| format!("writing {}", output.display()))?;
    if !args.solve.quiet {
        stderr_line!(
            "wrote {} ({}×{})",
            output.display(),
            settings.render.width,
            settings.render.height
        );
    }
    Ok(())
}

/// The export options from `solve`'s --bake flags, validated.
fn bake_options(args: &SolveCmdArgs) -> Result<ExportOptions> {
    let mut options = ExportOptions::default();
    if args.srgb_vertex_colors {
        options.vertex_colors = VertexColors::DisplaySrgb;
    }
    if let Some(stops) = args.bake_exposure {
        if !(stops.is_finite() && stops.abs() <= 64.0) {
            bail!("--bake-exposure must be a number of stops between -64 and 64, got {stops}");
        }
        options.exposure_stops = stops as f32;
    }
    if let Some(side) = args.lightmap_size {
        let max = radiosity::export::lightmap::MAX_ATLAS_SIDE as i64;
        if !(16..=max).contains(&side) {
            bail!("--lightmap-size must be between 16 and {max} texels, got {side}");
        }
        options.lightmap.size = AtlasSize::Fit {
            max_side: side as u32,
        };
    }
    Ok(options)
}

/// The scene's camera (or one framing it) with the camera flags applied; `--eye` alone looks
/// at the scene's centre.
pub(crate) fn scene_camera(scene: &Scene, view: &crate::args::ViewArgs) -> Result<Camera> {
    let (lo, hi) = scene.bounds();
    Ok(radiosity::settings::camera(
        scene.camera_or_default(),
        Some((lo + hi) * 0.5),
        &view.camera(),
    )?)
}

/// The renderer's options from the resolved settings.
pub(crate) fn render_options(settings: &Settings) -> RenderOptions {
    RenderOptions {
        width: settings.render.width,
        height: settings.render.height,
        samples_per_axis: settings.render.samples,
        ..RenderOptions::default()
    }
}

fn centre_of(vertices: &[glam::DVec3]) -> Option<glam::DVec3> {
    if vertices.is_empty() {
        return None;
    }
    let (lo, hi) = vertices.iter().fold(
        (
            glam::DVec3::splat(f64::INFINITY),
            glam::DVec3::splat(f64::NEG_INFINITY),
        ),
        |(lo, hi), v| (lo.min(*v), hi.max(*v)),
    );
    Some((lo + hi) * 0.5)
}
