//! Jacobi iteration: B⁽ᵏ⁺¹⁾ = E + ρ T(B⁽ᵏ⁾), starting from B⁽⁰⁾ = E. Converges because
//! ρ < 1 and the form factors of each element sum to at most 1.

use super::{SolveOptions, Transport};
use crate::progress::Progress;

/// Returns (B per element, iterations, relative residual).
pub fn solve(
    t: &Transport,
    options: &SolveOptions,
    progress: &dyn Progress,
) -> (Vec<[f64; 3]>, usize, f64) {
    let mut b = t.exitance();
    let mut residual = t.residual(&b);
    let mut iterations = 0;
    progress.start("jacobi", options.max_iterations as u64);
    while residual > options.tolerance && iterations < options.max_iterations {
        b = step(t, &b);
        iterations += 1;
        residual = t.residual(&b);
        progress.inc(1);
        progress.message(&format!("residual {residual:.2e}"));
    }
    progress.finish();
    (b, iterations, residual)
}

/// One Jacobi step: E + ρ T(B).
pub fn step(t: &Transport, b: &[[f64; 3]]) -> Vec<[f64; 3]> {
    t.apply(b)
}
