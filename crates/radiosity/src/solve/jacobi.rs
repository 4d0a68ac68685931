//! Jacobi iteration on the patch system: B⁽ᵏ⁺¹⁾ = E + M B⁽ᵏ⁾, starting from B⁽⁰⁾ = E.
//! Converges because ρ < 1 makes ‖M‖∞ < 1 (rows of F sum to at most 1).

use super::{PatchSystem, SolveOptions};
use crate::progress::Progress;
use rayon::prelude::*;

/// Returns (B per patch, iterations, relative residual).
pub fn solve(system: &PatchSystem, options: &SolveOptions, progress: &dyn Progress) -> (Vec<[f64; 3]>, usize, f64) {
    let mut b = system.exitance.clone();
    let mut residual = system.residual(&b);
    let mut iterations = 0;
    progress.start("jacobi", options.max_iterations as u64);
    while residual > options.tolerance && iterations < options.max_iterations {
        b = step(system, &b);
        iterations += 1;
        residual = system.residual(&b);
        progress.inc(1);
        progress.message(&format!("residual {residual:.2e}"));
    }
    progress.finish();
    (b, iterations, residual)
}

/// One Jacobi iteration: returns E + M B.
pub fn step(system: &PatchSystem, b: &[[f64; 3]]) -> Vec<[f64; 3]> {
    let n = system.patches;
    (0..n)
        .into_par_iter()
        .map(|p| {
            std::array::from_fn(|c| {
                let row = &system.matrix[c][p * n..(p + 1) * n];
                system.exitance[p][c] + row.iter().zip(b).map(|(m, x)| m * x[c]).sum::<f64>()
            })
        })
        .collect()
}
