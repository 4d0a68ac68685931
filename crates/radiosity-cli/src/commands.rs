//! `render` and `solve`: load the scene once, resolve the settings in the library, run the
//! pipeline, write the outputs.

use crate::args::{Cli, Command, RenderArgs, SolveArgs, SolveCmdArgs};
use crate::progress::Bars;
use anyhow::{Context, Result};
use radiosity::display::Shading;
use radiosity::io::scene_file::{load_any, SceneSettings};
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
}

pub(crate) fn load_scene(path: Option<&Path>) -> Result<Loaded> {
    match path {
        None => Ok(Loaded {
            scene: radiosity::cornell::cornell_box(),
            file_settings: SceneSettings::default(),
            file: None,
        }),
        Some(p) => {
            // Scene errors name the file (and line, object) themselves.
            let loaded = load_any(p)?;
            Ok(Loaded {
                scene: loaded.scene,
                file_settings: loaded.settings,
                file: Some(p.display().to_string()),
            })
        }
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
        eprintln!(
            "solved '{}': {} elements, {} patches, {} solver with {} form factors: {what} in {:.2} s ({:.2} s form factors)",
            scene.name,
            solved.mesh.len(),
            solved.mesh.patches.len(),
            st.solver,
            solved.form_factor,
            st.seconds,
            st.form_factor_seconds,
        );
    }
    Ok(solved)
}

fn solve(args: SolveCmdArgs) -> Result<()> {
    let loaded = load_scene(args.scene.as_deref())?;
    let settings = loaded.settings(&args.solve.overrides())?;
    for path in [&args.report, &args.save].into_iter().flatten() {
        radiosity::io::atomic::check_writable(path)
            .with_context(|| format!("cannot write {}", path.display()))?;
    }
    let solved = run_solve(&loaded.scene, &settings, &args.solve)?;
    let scene = &loaded.scene;
    let report = Report::new(
        &scene.name,
        &solved.mesh,
        &solved.solution,
        solved.form_factor.name(),
    )
    .with_lights(&scene.lights);
    if !args.solve.quiet {
        let t = &report.totals;
        let fmt = |p: [f64; 3]| format!("({:.4}, {:.4}, {:.4}) W", p[0], p[1], p[2]);
        eprintln!(
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
    if args.report.is_none() && args.save.is_none() {
        // Nothing asked to be written: print the report so the solve is not wasted.
        println!("{}", serde_json::to_string_pretty(&report)?);
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
    let output_for = |name: &str| -> Result<PathBuf> {
        let output = args.output.clone().unwrap_or_else(|| default_output(name));
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
        let output = output_for(&file.scene)?;
        let base = file.camera.map(Camera::from).unwrap_or_default();
        let vertices = file.vertices();
        let camera = radiosity::settings::camera(base, centre_of(&vertices), &args.view.camera())?;
        let radiosity = match args.false_colour {
            Some(q) => crate::cmd_falsecolour::values(q, &file.radiosity, &file.irradiance),
            None => file.display_radiosity(settings.render.ambient),
        };
        (vertices, file.elements, radiosity, camera, output, settings)
    } else {
        let loaded = load_scene(args.scene.as_deref())?;
        let settings = loaded.settings(&flags)?;
        let scene = &loaded.scene;
        let output = output_for(&scene.name)?;
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
        eprintln!(
            "wrote {} ({}×{})",
            output.display(),
            settings.render.width,
            settings.render.height
        );
    }
    Ok(())
}

/// `<name>.png` in the working directory; a name that is empty or not a plain file name
/// (a path, `..`) becomes `render.png`, so a scene's name cannot write elsewhere.
fn default_output(name: &str) -> PathBuf {
    let plain = !name.is_empty()
        && name != "."
        && name != ".."
        && !name.contains(['/', '\\'])
        && Path::new(name).file_name().is_some();
    PathBuf::from(format!("{}.png", if plain { name } else { "render" }))
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
