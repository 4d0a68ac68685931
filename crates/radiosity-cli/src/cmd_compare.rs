//! `radiosity compare`: every solver on the same mesh, error versus time and iterations,
//! and the hierarchical solver (its own mesh, error per object) at a sweep of tolerances;
//! with `--reference`, every solve's per-polygon error against a reference from outside the
//! engine.

use crate::args::SolveArgs;
use crate::cmd_progressive::prepare_output_dir;
use crate::commands::load_scene;
use crate::progress::Bars;
use anyhow::{bail, Context, Result};
use clap::Args;
use radiosity::mesh::Mesh;
use radiosity_studies::compare::{compare_against, CompareOptions, ExternalReference};
use std::path::PathBuf;

/// `radiosity compare`. The shared solve options' help is adjusted where compare differs:
/// its own ω default, and no solver choice or adaptive meshing (it runs every solver on one
/// uniform mesh).
#[derive(Debug, Args)]
#[command(
    mut_arg("overshoot", |a| a.help(
        "ω of the overshooting progressive run, 1 < ω < 2 [default: 1.1]"
    )),
    mut_arg("epsilon", |a| a.help(
        "Hierarchical series: the finest link tolerance X; it solves at 8X, 4X, 2X and X \
         [default: 0.01]"
    )),
    mut_arg("solver", |a| a.hide(true)),
    mut_arg("adaptive", |a| a.hide(true)),
    mut_arg("refine_threshold", |a| a.hide(true)),
    mut_arg("max_depth", |a| a.hide(true))
)]
pub struct CompareArgs {
    /// Scene file (.obj, .gltf, .glb, .mgf or .json); the built-in Cornell box if omitted.
    pub scene: Option<PathBuf>,
    /// Output directory (created if missing): convergence.svg, convergence.png, table.md,
    /// comparison.json.
    #[arg(short, long, value_name = "DIR")]
    pub output: PathBuf,
    /// Stop each run at this relative error [default: 1e-5].
    #[arg(long, value_name = "E", allow_hyphen_values = true)]
    pub target_error: Option<f64>,
    /// Iteration cap for Jacobi and Gauss–Seidel [default: 2000].
    #[arg(long, value_name = "N", allow_hyphen_values = true)]
    pub max_iterations: Option<i64>,
    /// Per-polygon reference radiosities (JSON: a "polygons" list of {"name",
    /// "radiosity_avg"}, as the path tracer's example writes, or the shared Mitsuba
    /// reference's file): every solve's per-polygon error against it is added to the table
    /// (the study mesh's converged solution and each hierarchical solve).
    #[arg(long, value_name = "FILE")]
    pub reference: Option<PathBuf>,
    #[command(flatten)]
    pub solve: SolveArgs,
}

/// Runs `radiosity compare`.
pub fn run(args: CompareArgs) -> Result<()> {
    if args.solve.tolerance.is_some() {
        bail!("--tolerance does not apply to `compare`; use --target-error");
    }
    if args.solve.solver.is_some() || args.solve.adaptive {
        bail!(
            "--solver and --adaptive do not apply to `compare`: it runs every solver on one mesh"
        );
    }
    let defaults = CompareOptions::default();
    let loaded = load_scene(args.scene.as_deref(), &args.solve)?;
    let mut flags = args.solve.overrides();
    // The overshooting run's ω defaults to compare's own choice.
    let overshoot = flags.overshoot.take();
    let settings = loaded.settings(&flags)?;
    let options = CompareOptions {
        overshoot: overshoot.unwrap_or(defaults.overshoot),
        target_error: args.target_error.unwrap_or(defaults.target_error),
        max_iterations: match args.max_iterations {
            None => defaults.max_iterations,
            Some(n) if (1..=1_000_000).contains(&n) => n as usize,
            Some(n) => bail!("--max-iterations must be a whole number from 1 to 1000000, got {n}"),
        },
        max_shots: settings.solve.solve.max_shots,
        memory_limit: defaults.memory_limit,
        // From the flag only: a scene file's ε is one solve's, not the series' finest.
        hierarchical_epsilon: if args.solve.epsilon.is_some() {
            settings.solve.hierarchical.epsilon
        } else {
            defaults.hierarchical_epsilon
        },
        hierarchical_solves: defaults.hierarchical_solves,
    };
    if !(options.overshoot > 1.0 && options.overshoot < 2.0) {
        bail!(
            "--overshoot must be between 1 and 2 (exclusive) for compare, got {}",
            options.overshoot
        );
    }
    if !(options.target_error > 0.0 && options.target_error < 1.0) {
        bail!(
            "--target-error must be between 0 and 1 (exclusive), got {}",
            options.target_error
        );
    }
    let external = match &args.reference {
        None => None,
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("reading the reference {}", path.display()))?;
            let value: serde_json::Value = serde_json::from_str(&text)
                .with_context(|| format!("{}: not JSON", path.display()))?;
            let reference = ExternalReference::from_json(&path.display().to_string(), &value)
                .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
            // Every object named must be in the scene, checked before the long run.
            for (name, _) in &reference.objects {
                if !loaded.scene.surfaces.iter().any(|s| &s.object == name) {
                    bail!("{}: object {name:?} is not in the scene", path.display());
                }
            }
            Some(reference)
        }
    };
    prepare_output_dir(&args.output)?;
    let mut mesh = Mesh::build(&loaded.scene, &settings.solve.mesh).context("meshing")?;
    // The first shot from light sources, as every solve takes it (the hierarchical runs
    // take theirs in the pipeline).
    radiosity::direct::illuminate(&mut mesh, &loaded.scene.lights);
    let bars = Bars::new(args.solve.quiet);
    let comparison = compare_against(
        &loaded.scene,
        &mesh,
        settings.solve.form_factor,
        &options,
        external.as_ref(),
        &bars,
    )?;
    comparison.write(&args.output)?;
    let table = comparison.table_markdown();
    crate::write_stdout(&table)?;
    if !args.solve.quiet {
        stderr_line!(
            "wrote {} (convergence.svg, convergence.png, table.md, comparison.json)",
            args.output.display()
        );
    }
    Ok(())
}
