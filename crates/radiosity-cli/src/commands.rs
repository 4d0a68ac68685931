//! The subcommands: each loads, runs the library pipeline and writes its outputs.

use crate::args::{Cli, Command, RenderArgs, SolveArgs, SolveCmdArgs};
use crate::progress::Bars;
use anyhow::{bail, Context, Result};
use radiosity::display::Shading;
use radiosity::formfactor::FormFactorMethod;
use radiosity::io::scene_file::{load_any, SceneSettings};
use radiosity::io::solution_file::SolutionFile;
use radiosity::mesh::MeshOptions;
use radiosity::pipeline::{
    render_elements, solve_scene, solve_scene_adaptive, Shaded, SolveSettings, Solved,
};
use radiosity::refine::RefineOptions;
use radiosity::render::RenderOptions;
use radiosity::report::Report;
use radiosity::scene::{Camera, Scene};
use radiosity::solve::{SolveOptions, SolverKind};
use std::path::{Path, PathBuf};

pub fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Render(args) => render(args),
        Command::Solve(args) => solve(args),
        Command::Formfactor(args) => crate::cmd_formfactor::run(args),
        Command::Progressive(args) => crate::cmd_progressive::run(args),
        Command::Compare(args) => crate::cmd_compare::run(args),
    }
}

/// A scene and its file settings; the built-in Cornell box when no path is given.
pub(crate) fn load_scene(path: Option<&Path>) -> Result<(Scene, SceneSettings)> {
    match path {
        None => Ok((radiosity::cornell::cornell_box(), SceneSettings::default())),
        Some(p) => {
            let loaded = load_any(p).with_context(|| format!("loading {}", p.display()))?;
            Ok((loaded.scene, loaded.settings))
        }
    }
}

/// Command-line flags override the scene file's settings, which override the defaults.
pub(crate) fn solve_settings(args: &SolveArgs, file: &SceneSettings) -> Result<SolveSettings> {
    let defaults = MeshOptions::default();
    let max_element_size = args.max_element_size.or(if args.elements.is_some() {
        None
    } else {
        file.max_element_size
    });
    let mesh = MeshOptions {
        max_element_size,
        elements: args.elements.or(file.elements).unwrap_or(defaults.elements),
        patch_subdivision: args
            .patch_subdivision
            .or(file.patch_subdivision)
            .unwrap_or(defaults.patch_subdivision),
    };
    let solver: SolverKind = match args.solver.as_deref().or(file.solver.as_deref()) {
        Some(s) => s.parse().map_err(anyhow::Error::msg)?,
        None => SolverKind::default(),
    };
    let form_factor: FormFactorMethod =
        match args.form_factor.as_deref().or(file.form_factor.as_deref()) {
            Some(s) => s.parse().map_err(anyhow::Error::msg)?,
            None => FormFactorMethod::default(),
        };
    let mut solve = SolveOptions {
        solver,
        ..Default::default()
    };
    if let Some(t) = args.tolerance.or(file.tolerance) {
        if !(t.is_finite() && t > 0.0 && t < 1.0) {
            bail!("--tolerance must be a number between 0 and 1, got {t}");
        }
        solve.tolerance = t;
    }
    solve.max_shots = args.max_shots.or(file.max_shots);
    Ok(SolveSettings {
        mesh,
        form_factor,
        solve,
    })
}

fn run_solve(scene: &Scene, settings: &SolveSettings, args: &SolveArgs) -> Result<Solved> {
    let quiet = args.quiet;
    let bars = Bars::new(quiet);
    let solved = if args.adaptive {
        let mut refine = RefineOptions {
            max_elements: Some(settings.mesh.elements),
            ..RefineOptions::default()
        };
        if let Some(x) = args.refine_threshold {
            if !(x.is_finite() && x > 0.0) {
                bail!("--refine-threshold must be a positive number, got {x}");
            }
            refine.threshold = x;
        }
        if let Some(d) = args.max_depth {
            if d > 8 {
                bail!(
                    "--max-depth must be at most 8 (each level quadruples the elements), got {d}"
                );
            }
            refine.max_depth = d;
        }
        solve_scene_adaptive(scene, settings, &refine, &bars)?
    } else {
        solve_scene(scene, settings, &bars)?
    };
    if !quiet {
        let st = &solved.solution.stats;
        let what = if st.solver == SolverKind::Progressive {
            format!(
                "{} shots, unshot power fraction {:.2e}",
                st.iterations, st.residual
            )
        } else {
            format!(
                "{} iterations, relative residual {:.2e}",
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
    let (scene, file_settings) = load_scene(args.scene.as_deref())?;
    let settings = solve_settings(&args.solve, &file_settings)?;
    let solved = run_solve(&scene, &settings, &args.solve)?;
    let report = Report::new(
        &scene.name,
        &solved.mesh,
        &solved.solution,
        solved.form_factor.name(),
    );
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
        SolutionFile::new(&scene.name, scene.camera, &solved.mesh, &solved.solution)
            .save(path)
            .with_context(|| format!("saving solution {}", path.display()))?;
    }
    if args.report.is_none() && args.save.is_none() {
        // Nothing asked to be written: print the report so the solve is not wasted.
        println!("{}", serde_json::to_string_pretty(&report)?);
    }
    Ok(())
}

fn render(args: RenderArgs) -> Result<()> {
    let (name, scene_camera, file_settings, stored) = if let Some(path) = &args.solution {
        let file = SolutionFile::load(path)
            .with_context(|| format!("loading solution {}", path.display()))?;
        (
            file.scene.clone(),
            file.camera.map(Camera::from),
            SceneSettings::default(),
            Some(file),
        )
    } else {
        let (scene, settings) = load_scene(args.scene.as_deref())?;
        (scene.name.clone(), scene.camera, settings, None)
    };
    let output: PathBuf = args.output.clone().unwrap_or_else(|| {
        let stem = if name.is_empty() {
            "render".to_string()
        } else {
            name.clone()
        };
        PathBuf::from(format!("{stem}.png"))
    });
    let width = args.width.or(file_settings.width).unwrap_or(512);
    let height = args.height.or(file_settings.height).unwrap_or(512);
    let max = radiosity::render::MAX_IMAGE_SIZE;
    for (name, v) in [("--width", width), ("--height", height)] {
        if v == 0 || v > max {
            bail!("{name} must be between 1 and {max} pixels, got {v}");
        }
    }
    if args.samples == 0 || args.samples > radiosity::render::MAX_SAMPLES_PER_AXIS {
        bail!(
            "--samples must be between 1 and {}, got {}",
            radiosity::render::MAX_SAMPLES_PER_AXIS,
            args.samples
        );
    }
    let exposure = args.exposure.or(file_settings.exposure).unwrap_or(0.0);
    if !exposure.is_finite() || exposure.abs() > 64.0 {
        bail!("--exposure must be a finite number of stops between -64 and 64, got {exposure}");
    }
    let options = RenderOptions {
        width,
        height,
        samples_per_axis: args.samples,
        ..RenderOptions::default()
    };
    let shading = if args.flat {
        Shading::Flat
    } else {
        Shading::Smooth
    };

    let image = match stored {
        Some(file) => {
            let camera = camera_from(&args, file.camera.map(Camera::from), None)?;
            let vertices = file.vertices();
            let radiosity = file.display_radiosity(args.ambient);
            let shaded = Shaded {
                vertices: &vertices,
                elements: &file.elements,
                radiosity: &radiosity,
            };
            render_elements(&shaded, &camera, shading, args.wireframe, &options)?
        }
        None => {
            let (scene, _) = load_scene(args.scene.as_deref())?;
            let settings = solve_settings(&args.solve, &file_settings)?;
            let camera = camera_from(&args, scene_camera, Some(&scene))?;
            let solved = run_solve(&scene, &settings, &args.solve)?;
            let radiosity = solved
                .solution
                .display_radiosity(&solved.mesh, args.ambient);
            let shaded = Shaded {
                vertices: &solved.mesh.vertices,
                elements: &solved.mesh.elements,
                radiosity: &radiosity,
            };
            render_elements(&shaded, &camera, shading, args.wireframe, &options)?
        }
    };
    image
        .write(&output, exposure as f32)
        .with_context(|| format!("writing {}", output.display()))?;
    if !args.solve.quiet {
        eprintln!("wrote {} ({width}×{height})", output.display());
    }
    Ok(())
}

/// The camera: flags over the scene's camera over one framing the scene.
fn camera_from(
    args: &RenderArgs,
    scene_camera: Option<Camera>,
    scene: Option<&Scene>,
) -> Result<Camera> {
    let base = scene_camera
        .or_else(|| scene.map(Scene::camera_or_default))
        .unwrap_or_default();
    camera_with(args.eye, args.target, args.up, args.fov, base)
}

/// `base` with the given flags applied, checked: a field of view in (0°, 180°), distinct
/// eye and target, and an up direction not parallel to the view.
pub(crate) fn camera_with(
    eye: Option<glam::DVec3>,
    target: Option<glam::DVec3>,
    up: Option<glam::DVec3>,
    fov: Option<f64>,
    base: Camera,
) -> Result<Camera> {
    let camera = Camera {
        eye: eye.unwrap_or(base.eye),
        target: target.unwrap_or(base.target),
        up: up.unwrap_or(base.up),
        fov_deg: fov.unwrap_or(base.fov_deg),
    };
    if !(camera.fov_deg > 0.0 && camera.fov_deg < 180.0) {
        bail!(
            "--fov must be between 0 and 180 degrees, got {}",
            camera.fov_deg
        );
    }
    let look = camera.target - camera.eye;
    if look.length() < 1e-12 {
        bail!("camera eye and target coincide");
    }
    if look.normalize().cross(camera.up).length() < 1e-9 {
        bail!("camera up direction is parallel to the viewing direction");
    }
    Ok(camera)
}
