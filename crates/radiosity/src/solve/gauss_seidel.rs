//! Gauss–Seidel iteration on the patch system: each B_p is updated in place from the newest
//! values, B_p ← (E_p + Σ_{q≠p} M_pq B_q) / (1 − M_pp). Usually about twice as fast as
//! Jacobi per iteration count; inherently sequential over patches (channels run in parallel).

use super::{PatchSystem, SolveOptions};
use crate::progress::Progress;
use rayon::prelude::*;

/// Returns (B per patch, iterations, relative residual).
pub fn solve(system: &PatchSystem, options: &SolveOptions, progress: &dyn Progress) -> (Vec<[f64; 3]>, usize, f64) {
    let n = system.patches;
    let mut channels: Vec<Vec<f64>> = (0..3)
        .map(|c| system.exitance.iter().map(|e| e[c]).collect())
        .collect();
    let assemble = |ch: &[Vec<f64>]| -> Vec<[f64; 3]> { (0..n).map(|p| [ch[0][p], ch[1][p], ch[2][p]]).collect() };
    let mut residual = system.residual(&assemble(&channels));
    let mut iterations = 0;
    progress.start("gauss-seidel", options.max_iterations as u64);
    while residual > options.tolerance && iterations < options.max_iterations {
        sweep(system, &mut channels);
        iterations += 1;
        residual = system.residual(&assemble(&channels));
        progress.inc(1);
        progress.message(&format!("residual {residual:.2e}"));
    }
    progress.finish();
    (assemble(&channels), iterations, residual)
}

/// One Gauss–Seidel sweep over the patches, in place; `channels[c][p]` is B_p in channel c.
pub fn sweep(system: &PatchSystem, channels: &mut [Vec<f64>]) {
    let n = system.patches;
    channels.par_iter_mut().enumerate().for_each(|(c, b)| {
        let m = &system.matrix[c];
        for p in 0..n {
            let row = &m[p * n..(p + 1) * n];
            let sum: f64 = row.iter().zip(b.iter()).map(|(m, x)| m * x).sum::<f64>() - row[p] * b[p];
            b[p] = (system.exitance[p][c] + sum) / (1.0 - row[p]);
        }
    });
}
