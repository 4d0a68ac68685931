//! Per-polygon reference radiosities by the independent path tracer
//! ([`radiosity_studies::path_trace`]), as JSON on standard output.
//!
//! `cargo run --release -p radiosity-studies --example path_traced_reference -- SCENE PATHS
//! [SEED]`: SCENE any format `radiosity` reads (the built-in Cornell box for `cornell`),
//! PATHS paths per polygon. `crates/radiosity/tests/reference/cornell_path_traced.json`
//! was made from `../shared/reference/cornell.obj` with 10,000,000 paths and seed 1.

use radiosity::io::formats::{load_any_with, LoadOptions};
use radiosity_studies::path_trace::PathTracer;
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 2 {
        eprintln!("usage: path_traced_reference SCENE PATHS [SEED]");
        std::process::exit(2);
    }
    let scene = if args[0] == "cornell" {
        radiosity::cornell::cornell_box()
    } else {
        match load_any_with(std::path::Path::new(&args[0]), &LoadOptions::default()) {
            Ok(loaded) => loaded.scene,
            Err(e) => {
                eprintln!("{}: {e}", args[0]);
                std::process::exit(1);
            }
        }
    };
    let Ok(paths) = args[1].parse::<usize>() else {
        eprintln!("PATHS must be a whole number, got '{}'", args[1]);
        std::process::exit(2);
    };
    let seed = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(1);
    let tracer = match PathTracer::new(&scene) {
        Ok(t) => t,
        Err(e) => {
            eprintln!("{}: {e}", args[0]);
            std::process::exit(1);
        }
    };
    let started = Instant::now();
    let polygons: Vec<serde_json::Value> = scene
        .surfaces
        .iter()
        .enumerate()
        .map(|(i, s)| {
            let e = tracer.polygon(i, paths, seed);
            eprintln!(
                "{}: B {:?} ± {:?}",
                s.object, e.radiosity, e.radiosity_stderr
            );
            serde_json::json!({
                "name": s.object,
                "radiosity_avg": e.radiosity,
                "radiosity_avg_stderr": e.radiosity_stderr,
                "direct_irradiance_avg": e.direct_irradiance,
                "direct_irradiance_avg_stderr": e.direct_irradiance_stderr,
            })
        })
        .collect();
    let out = serde_json::json!({
        "method": "radiosity_studies::path_trace: Monte Carlo path tracing, next-event estimation and cosine-weighted bounces combined by the power heuristic, Russian roulette after three bounces, one-sided surfaces; Möller–Trumbore in f64 against every triangle",
        "scene": args[0],
        "paths_per_polygon": paths.div_ceil(4096) * 4096,
        "seed": seed,
        "seconds": started.elapsed().as_secs_f64(),
        "units": "W/m^2 (radiosity and irradiance), for emitted radiance in W m^-2 sr^-1",
        "polygons": polygons,
    });
    println!("{}", serde_json::to_string_pretty(&out).unwrap());
}
