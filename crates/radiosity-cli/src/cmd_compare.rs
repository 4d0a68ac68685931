//! `radiosity compare`: every solver on the same mesh, error versus time and iterations.

use crate::cmd_progressive::{prepare_output_dir, MeshArgs};
use crate::commands::{load_scene, solve_settings};
use crate::progress::Bars;
use anyhow::{bail, Context, Result};
use clap::Args;
use radiosity::compare::{compare, CompareOptions};
use radiosity::formfactor::Visibility;
use radiosity::mesh::Mesh;
use std::path::PathBuf;

#[derive(Debug, Args)]
pub struct CompareArgs {
    /// Scene file (.obj or .json); the built-in Cornell box if omitted.
    pub scene: Option<PathBuf>,
    /// Output directory (created if missing): convergence.svg, convergence.png, table.md.
    #[arg(short, long, value_name = "DIR")]
    pub output: PathBuf,
    /// ω of the overshooting progressive run, 1 < ω < 2 [default: 1.5].
    #[arg(long, value_name = "W")]
    pub overshoot: Option<f64>,
    /// Stop each run at this relative error [default: 1e-5].
    #[arg(long, value_name = "E")]
    pub target_error: Option<f64>,
    /// Iteration cap for Jacobi and Gauss–Seidel [default: 2000].
    #[arg(long, value_name = "N")]
    pub max_iterations: Option<usize>,
    /// Shot cap for the progressive runs [default: 200 per patch].
    #[arg(long, value_name = "N")]
    pub max_shots: Option<usize>,
    #[command(flatten)]
    pub mesh: MeshArgs,
}

pub fn run(args: CompareArgs) -> Result<()> {
    if args.mesh.tolerance.is_some() {
        bail!("--tolerance does not apply to `compare`; use --target-error");
    }
    let defaults = CompareOptions::default();
    let options = CompareOptions {
        overshoot: args.overshoot.unwrap_or(defaults.overshoot),
        target_error: args.target_error.unwrap_or(defaults.target_error),
        max_iterations: args.max_iterations.unwrap_or(defaults.max_iterations),
        max_shots: args.max_shots,
        memory_limit: defaults.memory_limit,
    };
    if !(options.overshoot > 1.0 && options.overshoot < 2.0) {
        bail!(
            "--overshoot must be between 1 and 2 (exclusive), got {}",
            options.overshoot
        );
    }
    if !(options.target_error > 0.0 && options.target_error < 1.0) {
        bail!(
            "--target-error must be between 0 and 1 (exclusive), got {}",
            options.target_error
        );
    }
    if options.max_iterations == 0 || options.max_shots == Some(0) {
        bail!("--max-iterations and --max-shots must be at least 1");
    }
    let (scene, file_settings) = load_scene(args.scene.as_deref())?;
    let settings = solve_settings(&args.mesh.solve_args(), &file_settings)?;
    prepare_output_dir(&args.output)?;
    let mesh = Mesh::build(&scene, &settings.mesh).context("meshing")?;
    let visibility = Visibility::new(&mesh);
    let ff = settings.form_factor.engine(&mesh, &visibility);
    let bars = Bars::new(args.mesh.quiet);
    let comparison = compare(&scene.name, &mesh, ff.as_ref(), &options, &bars)?;
    comparison.write(&args.output)?;
    let table = comparison.table_markdown();
    print!("{table}");
    if !args.mesh.quiet {
        eprintln!(
            "wrote {} (convergence.svg, convergence.png, table.md)",
            args.output.display()
        );
    }
    Ok(())
}
