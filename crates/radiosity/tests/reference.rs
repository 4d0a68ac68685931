//! The Cornell box against independent references (tests/reference/cornell_reference.json:
//! Mitsuba 3 path tracing, 4096 spp, all bounces; see tests/reference/README.md), and the
//! solvers against each other.

use radiosity::cornell::cornell_box;
use radiosity::display::Shading;
use radiosity::pipeline::{render_elements, solve_scene, Shaded, SolveSettings, Solved};
use radiosity::progress::NoProgress;
use radiosity::render::RenderOptions;
use radiosity::report::Report;
use radiosity::solve::{SolveOptions, SolverKind};
use serde_json::Value;
use std::sync::OnceLock;

fn reference() -> &'static Value {
    static R: OnceLock<Value> = OnceLock::new();
    R.get_or_init(|| {
        serde_json::from_str(include_str!("reference/cornell_reference.json")).unwrap()
    })
}

fn solve_with(solver: SolverKind, tolerance: f64) -> Solved {
    let settings = SolveSettings {
        solve: SolveOptions {
            solver,
            tolerance,
            ..Default::default()
        },
        ..Default::default()
    };
    solve_scene(&cornell_box(), &settings, &NoProgress).unwrap()
}

/// The default mesh solved directly (shared by the tests below).
fn direct() -> &'static Solved {
    static S: OnceLock<Solved> = OnceLock::new();
    S.get_or_init(|| solve_with(SolverKind::Direct, 1e-9))
}

fn report(s: &Solved) -> Report {
    Report::new("cornell", &s.mesh, &s.solution, s.form_factor.name())
}

#[test]
fn per_polygon_radiosity_matches_mitsuba_within_3_percent() {
    let report = report(direct());
    let mut worst = (0.0f64, String::new());
    for poly in reference()["per_polygon_area_averaged"]["polygons"]
        .as_array()
        .unwrap()
    {
        let name = poly["name"].as_str().unwrap();
        let ours = report
            .object(name)
            .unwrap_or_else(|| panic!("no object {name}"));
        for c in 0..3 {
            let want = poly["radiosity_avg"][c].as_f64().unwrap();
            let se = poly["radiosity_avg_stderr"][c].as_f64().unwrap();
            // Tolerance: the 3 % for the default mesh (discretisation of the
            // continuous answer into ~4k constant elements, visibility sampled by rays), plus
            // 3 Monte Carlo standard errors of the reference itself.
            let err = (ours.radiosity[c] - want).abs();
            let rel = err / want;
            if rel > worst.0 {
                worst = (
                    rel,
                    format!("{name}[{c}] ours {} ref {want}", ours.radiosity[c]),
                );
            }
            assert!(
                err <= 0.03 * want + 3.0 * se,
                "{name} channel {c}: ours {} vs reference {want} ({:.2} %)",
                ours.radiosity[c],
                100.0 * rel
            );
        }
    }
    eprintln!(
        "worst per-polygon relative error: {:.3} % ({})",
        100.0 * worst.0,
        worst.1
    );
}

#[test]
fn energy_balance_holds() {
    let r = report(direct());
    // Tolerance 1e-6: the direct solver's residual is ~1e-15, and emitted = absorbed +
    // escaped is then exact bookkeeping of where each patch's power went.
    assert!(
        r.balance_error() < 1e-6,
        "balance error {}",
        r.balance_error()
    );
    // The open front of the box lets light escape: some, but less than was emitted.
    for c in 0..3 {
        assert!(r.totals.escaped_power[c] > 0.0);
        assert!(r.totals.escaped_power[c] < 0.5 * r.totals.emitted_power[c]);
    }
}

#[test]
fn iterative_solvers_agree_with_direct_to_their_tolerance() {
    let d = direct();
    let total: f64 = d
        .solution
        .radiosity
        .iter()
        .zip(&d.mesh.elements)
        .map(|(b, e)| (b[0] + b[1] + b[2]) * e.area)
        .sum();
    for solver in [
        SolverKind::Jacobi,
        SolverKind::GaussSeidel,
        SolverKind::Progressive,
    ] {
        let tol = 1e-4;
        let s = solve_with(solver, tol);
        // Power-weighted difference relative to the total radiant power: the matrix
        // solvers stop at a relative residual `tol` and the error is at most
        // residual / (1 − ρ_max) ≈ 4·tol; progressive stops at an unshot fraction `tol`,
        // whose power is missing from B by the same bound. 10·tol leaves margin.
        let diff: f64 = s
            .solution
            .radiosity
            .iter()
            .zip(&d.solution.radiosity)
            .zip(&d.mesh.elements)
            .map(|((a, b), e)| {
                ((a[0] - b[0]).abs() + (a[1] - b[1]).abs() + (a[2] - b[2]).abs()) * e.area
            })
            .sum();
        assert!(
            diff / total < 10.0 * tol,
            "{solver}: relative difference {}",
            diff / total
        );
        assert!(
            s.solution.stats.residual <= tol,
            "{solver} stopped at {}",
            s.solution.stats.residual
        );
        let r = report(&s);
        // Progressive bookkeeping is exact whatever the tolerance: emitted = absorbed +
        // escaped + unshot.
        if solver == SolverKind::Progressive {
            assert!(r.balance_error() < 1e-9);
        } else {
            assert!(r.balance_error() < 10.0 * tol);
        }
    }
}

#[test]
fn region_means_of_a_256_render_match_mitsuba_within_3_percent() {
    let s = direct();
    let scene = cornell_box();
    let camera = scene.camera.unwrap();
    let shaded = Shaded {
        vertices: &s.mesh.vertices,
        elements: &s.mesh.elements,
        radiosity: &s.solution.radiosity,
    };
    let options = RenderOptions {
        width: 256,
        height: 256,
        ..Default::default()
    };
    let image = render_elements(&shaded, &camera, Shading::Smooth, false, &options).unwrap();
    let mut worst = (0.0f64, String::new());
    for (name, region) in reference()["regions"].as_object().unwrap() {
        let r: Vec<u32> = region["rect_x0y0x1y1"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_u64().unwrap() as u32)
            .collect();
        let ours = image.region_mean(r[0], r[1], r[2], r[3]);
        for c in 0..3 {
            let want = region["mean_radiance_rgb"][c].as_f64().unwrap();
            let se = region["est_mc_stderr_of_mean_rgb"][c].as_f64().unwrap();
            let rel = (ours[c] - want).abs() / want;
            if rel > worst.0 {
                worst = (rel, format!("{name}[{c}]"));
            }
            // Tolerance: 3 % (the bound: mesh discretisation and Gouraud
            // interpolation of a smooth field) plus 3 reference standard errors.
            assert!(
                (ours[c] - want).abs() <= 0.03 * want + 3.0 * se,
                "region {name} channel {c}: ours {} vs reference {want} ({:.2} %)",
                ours[c],
                100.0 * (ours[c] - want) / want
            );
        }
    }
    eprintln!(
        "worst region relative error: {:.3} % ({})",
        100.0 * worst.0,
        worst.1
    );
}
