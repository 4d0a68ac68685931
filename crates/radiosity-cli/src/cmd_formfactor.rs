//! `radiosity formfactor`: one form-factor problem with one or every method, or the accuracy
//! table of every method on the reference cases.

use anyhow::{bail, Context, Result};
use clap::Args;
use radiosity::formfactor::pair::{solve_pair, PairProblem, PairSettings};
use radiosity::formfactor::table::{accuracy_table, to_markdown};
use radiosity::formfactor::FormFactorMethod;
use std::path::PathBuf;

#[derive(Debug, Args)]
pub struct FormfactorArgs {
    /// Problem file: {"from": [[x,y,z], ...] or {"point": [x,y,z], "normal": [x,y,z]},
    /// "to": [[x,y,z], ...], "occluders": [[[x,y,z], ...], ...]}; polygons convex and
    /// counter-clockwise seen from their front. Prints one JSON line per method:
    /// {"method", "F_from_to", "F_to_from", "seconds"} (+ "stderr" for monte-carlo).
    #[arg(required_unless_present = "table", value_name = "FILE.json")]
    pub file: Option<PathBuf>,
    /// Method: analytic-point | analytic-polygon | point-sampled | hemicube | raycast |
    /// monte-carlo, or
    /// all [default: raycast].
    #[arg(long, value_name = "NAME")]
    pub method: Option<String>,
    /// point-sampled: sub-areas per polygon [default: 4096, at most 65536]; monte-carlo: rays
    /// per direction [default: 1048576, at most 2^30].
    #[arg(long, value_name = "N")]
    pub samples: Option<usize>,
    /// hemicube: pixels along the hemi-cube's top face [default: 128].
    #[arg(long, value_name = "N")]
    pub resolution: Option<usize>,
    /// Seed of the random methods (monte-carlo, hemicube with --jitter).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// hemicube: rotate each hemi-cube randomly about its normal (against aliasing).
    #[arg(long)]
    pub jitter: bool,
    /// Print, as a Markdown table, every method's maximum and mean error over the reference
    /// cases (Howell's catalog) and its time per form factor.
    #[arg(long, conflicts_with = "file")]
    pub table: bool,
}

/// The most sub-areas per polygon for point-sampled: 2¹⁶ sub-areas make 2³² point pairs,
/// minutes of work; the default is 4096.
const MAX_SUBAREAS: usize = 1 << 16;
/// The most Monte Carlo rays per direction: 2³⁰ (the default is 2²⁰), minutes of work.
const MAX_RAYS: usize = 1 << 30;
/// The largest hemi-cube: 8192² pixels on the top face (the default is 128).
const MAX_RESOLUTION: usize = 8192;

pub fn run(args: FormfactorArgs) -> Result<()> {
    let methods: Vec<FormFactorMethod> = match args.method.as_deref() {
        None => {
            if args.table {
                FormFactorMethod::ALL.to_vec()
            } else {
                vec![FormFactorMethod::default()]
            }
        }
        Some("all") => FormFactorMethod::ALL.to_vec(),
        Some(name) => vec![name.parse().map_err(anyhow::Error::msg)?],
    };
    if let Some(samples) = args.samples {
        // The tightest cap of the methods that will run (the cap is checked before any work,
        // so a typo cannot start a job of days or an allocation that aborts).
        let (cap, what) = if methods.contains(&FormFactorMethod::PointSampled) {
            (
                MAX_SUBAREAS,
                "for point-sampled (sub-areas per polygon; the work grows as their square)",
            )
        } else {
            (MAX_RAYS, "(monte-carlo: rays per direction)")
        };
        if !(1..=cap).contains(&samples) {
            bail!("--samples must be a whole number from 1 to {cap} {what}, got {samples}");
        }
    }
    if let Some(resolution) = args.resolution {
        if !(1..=MAX_RESOLUTION).contains(&resolution) {
            bail!("--resolution must be a whole number from 1 to {MAX_RESOLUTION} pixels, got {resolution}");
        }
    }
    let settings = PairSettings {
        samples: args.samples,
        resolution: args.resolution,
        seed: args.seed,
        jitter: args.jitter,
    };
    if args.table {
        crate::write_stdout(&to_markdown(&accuracy_table(&methods, &settings)))?;
        return Ok(());
    }
    let Some(path) = args.file else {
        bail!("give a problem file, or --table");
    };
    let text = radiosity::io::open::read_to_string_checked(&path, radiosity::io::open::Kind::Small)
        .with_context(|| format!("reading {}", path.display()))?;
    let problem =
        PairProblem::from_json(&text).with_context(|| format!("loading {}", path.display()))?;
    for method in methods {
        crate::write_stdout(&(solve_pair(&problem, method, &settings).to_json_line() + "\n"))?;
    }
    Ok(())
}
