//! Jacobi iteration: B⁽ᵏ⁺¹⁾ = E + ρ K(B⁽ᵏ⁾), starting from B⁽⁰⁾ = E. Converges because
//! ρ < 1 and the form factors of each element sum to at most 1.
//!
//! The residual of B⁽ᵏ⁾, ‖E + ρK(B⁽ᵏ⁾) − B⁽ᵏ⁾‖/‖E‖, is exactly the change ‖B⁽ᵏ⁺¹⁾ − B⁽ᵏ⁾‖/‖E‖,
//! so it costs nothing extra; the iteration stops when it falls to the tolerance and returns
//! the newer iterate B⁽ᵏ⁺¹⁾.

use super::observer::SolverClock;
use super::{
    exitance, reflect, relative_difference, solution_from, Flow, Observer, Solution, SolveOptions,
    SolveStats, SolverKind, Step, StepKind,
};
use crate::coupling::Coupling;

/// Iterates to the tolerance or the iteration cap (or until the observer stops it).
pub fn solve(
    coupling: &dyn Coupling,
    options: &SolveOptions,
    observer: &mut dyn Observer,
) -> Solution {
    let mesh = coupling.mesh();
    let mut clock = SolverClock::start();
    let mut b = exitance(mesh);
    let mut residual = f64::INFINITY;
    let mut iterations = 0;
    let mut flow = clock.report(observer, |elapsed| Step {
        solver: SolverKind::Jacobi,
        kind: StepKind::Start,
        index: 0,
        residual,
        tolerance: options.tolerance,
        elapsed,
        mesh,
        radiosity: &b,
        unshot: None,
    });
    while flow == Flow::Continue
        && residual > options.tolerance
        && iterations < options.max_iterations
    {
        let next = reflect(mesh, &coupling.gather(&b));
        residual = relative_difference(mesh, &b, &next);
        b = next;
        iterations += 1;
        flow = clock.report(observer, |elapsed| Step {
            solver: SolverKind::Jacobi,
            kind: StepKind::Iteration,
            index: iterations,
            residual,
            tolerance: options.tolerance,
            elapsed,
            mesh,
            radiosity: &b,
            unshot: None,
        });
    }
    let seconds = clock.seconds();
    solution_from(
        coupling,
        b,
        SolveStats {
            solver: SolverKind::Jacobi,
            iterations,
            residual,
            seconds,
            form_factor_seconds: coupling.form_factor_seconds(),
        },
    )
}
