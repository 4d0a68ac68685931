//! `radiosity measure`: illuminance at point sensors and on work-plane grids, gathered from
//! the solution at each point (`radiosity::measure`), written as JSON, grids also as CSV and
//! false-colour PNG.

use crate::args::SolveArgs;
use crate::commands::{load_scene, run_solve};
use anyhow::{bail, Context, Result};
use clap::Args;
use radiosity::measure::{layout_grid, load_points, Gatherer, GridResult, GridSpec, Sensor};
use radiosity_studies::falsecolour;
use serde_json::json;
use std::path::{Path, PathBuf};

/// `radiosity measure`.
#[derive(Debug, Args)]
pub struct MeasureArgs {
    /// Scene file (.obj or .json); the built-in Cornell box if omitted.
    pub scene: Option<PathBuf>,
    /// Point sensors: {"points": [{"name": "A", "position": [x, y, z], "normal": [x, y, z]}]}.
    #[arg(long, value_name = "POINTS.json")]
    pub points: Option<PathBuf>,
    /// A work-plane grid, height=H[,spacing=P][,surface=NAME][,border=B] in metres: H above
    /// the object NAME (default: the largest one facing up), points every P (default
    /// EN 12464-1's 0.2·5^log10(d)), leaving out a band B along the sides. Repeatable.
    #[arg(long, value_name = "SPEC")]
    pub grid: Vec<String>,
    /// Output JSON (per point irradiance in W/m² and illuminance in lx; grid statistics).
    /// Each grid is also written beside it as OUT_gridN.csv and OUT_gridN.png.
    #[arg(short, long, value_name = "OUT.json")]
    pub output: PathBuf,
    #[command(flatten)]
    pub solve: SolveArgs,
}

/// The CSV and PNG paths of grid `name` beside `output`: `<stem>_<name>.csv/.png`.
fn grid_paths(output: &Path, name: &str) -> (PathBuf, PathBuf) {
    let stem = output
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "measure".into());
    let dir = output.parent().unwrap_or(Path::new(""));
    (
        dir.join(format!("{stem}_{name}.csv")),
        dir.join(format!("{stem}_{name}.png")),
    )
}

/// Runs `radiosity measure`.
pub fn run(args: MeasureArgs) -> Result<()> {
    if args.points.is_none() && args.grid.is_empty() {
        bail!("nothing to measure: give --points FILE and/or --grid height=H,…");
    }
    // Everything that can be wrong with the input is found before the solve.
    let specs: Vec<GridSpec> = args
        .grid
        .iter()
        .map(|g| GridSpec::parse(g))
        .collect::<Result<_, _>>()?;
    let sensors: Vec<Sensor> = match &args.points {
        Some(p) => load_points(p)?,
        None => Vec::new(),
    };
    let loaded = load_scene(args.scene.as_deref(), &args.solve)?;
    let settings = loaded.settings(&args.solve.overrides())?;
    let layouts = specs
        .iter()
        .map(|s| layout_grid(&loaded.scene, s))
        .collect::<Result<Vec<_>, _>>()?;
    let mut outputs = vec![args.output.clone()];
    for k in 0..specs.len() {
        let (csv, png) = grid_paths(&args.output, &format!("grid{}", k + 1));
        outputs.extend([csv, png]);
    }
    for path in &outputs {
        radiosity::io::atomic::check_writable(path)
            .with_context(|| format!("cannot write {}", path.display()))?;
    }

    let solved = run_solve(&loaded.scene, &settings, &args.solve)?;
    let scene = &loaded.scene;
    let gatherer = Gatherer::new(&solved.mesh, &solved.solution.radiosity, &scene.lights);
    let readings = gatherer.read(&sensors);
    let mut grids = Vec::new();
    for (k, (spec, layout)) in specs.iter().zip(layouts).enumerate() {
        let name = format!("grid{}", k + 1);
        let grid = GridResult::measure(&name, spec, layout, &gatherer);
        let (csv, png) = grid_paths(&args.output, &name);
        radiosity::io::atomic::write_atomically(&csv, |w| w.write_all(grid.to_csv().as_bytes()))
            .with_context(|| format!("writing {}", csv.display()))?;
        let title = format!(
            "{}: '{}' + {} m, {}",
            grid.name, grid.layout.surface, spec.height, scene.name
        );
        let image = falsecolour::grid_plot(&grid, &title)
            .map_err(anyhow::Error::msg)
            .with_context(|| format!("drawing {}", png.display()))?;
        falsecolour::write_png(&image, &png).map_err(anyhow::Error::msg)?;
        if !args.solve.quiet {
            let s = &grid.stats;
            stderr_line!(
                "{name} over '{}' at {} m: {} points, Ē = {:.1} lx, Emin = {:.1} lx, Emax = {:.1} lx, U0 = {:.3}, Emin/Emax = {:.3} -> {}, {}",
                grid.layout.surface,
                spec.height,
                s.points,
                s.e_mean,
                s.e_min,
                s.e_max,
                s.u0,
                s.min_over_max,
                csv.display(),
                png.display()
            );
        }
        grids.push(json!({
            "name": grid.name,
            "surface": grid.layout.surface,
            "height": spec.height,
            "border": spec.border,
            "counts": grid.layout.counts,
            "spacing": grid.layout.spacing,
            "normal": grid.layout.normal,
            "u_axis": grid.layout.u_axis,
            "v_axis": grid.layout.v_axis,
            "stats": grid.stats,
            "csv": csv.display().to_string(),
            "png": png.display().to_string(),
            "points": grid.points,
        }));
    }
    let out = json!({
        "scene": scene.name,
        "units": {
            "position": "m",
            "irradiance": "W/m^2",
            "illuminance": "lx",
            "photometric_convention": radiosity::report::Units::default().photometric_convention,
        },
        "method": "gathered at each point: direct from every light with shadow rays, indirect from every element's radiosity with the exact point-to-polygon form factor and shadow rays",
        "points": readings,
        "grids": grids,
    });
    radiosity::io::atomic::write_atomically(&args.output, |w| {
        serde_json::to_writer_pretty(&mut *w, &out).map_err(std::io::Error::other)?;
        writeln!(w)
    })
    .with_context(|| format!("writing {}", args.output.display()))?;
    if !args.solve.quiet {
        stderr_line!("wrote {}", args.output.display());
    }
    Ok(())
}
