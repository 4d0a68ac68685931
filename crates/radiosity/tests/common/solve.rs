//! Solving a scene with the settings most tests vary.

use radiosity::mesh::MeshOptions;
use radiosity::pipeline::{solve_scene, SolveSettings, Solved};
use radiosity::progress::NoProgress;
use radiosity::scene::Scene;
use radiosity::solve::{SolveOptions, SolverKind};

/// Solves `scene` with `solver` (the default form factor) to the stopping `tolerance`; the
/// classic solvers on about `elements` elements (the hierarchical solver makes its own).
pub fn solve(scene: &Scene, elements: usize, solver: SolverKind, tolerance: f64) -> Solved {
    let settings = SolveSettings {
        mesh: MeshOptions {
            elements,
            ..MeshOptions::default()
        },
        solve: SolveOptions {
            solver,
            tolerance,
            ..SolveOptions::default()
        },
        ..SolveSettings::default()
    };
    solve_scene(scene, &settings, &NoProgress).unwrap()
}
