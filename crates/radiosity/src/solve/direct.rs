//! Direct solution by Gaussian elimination: a dense LU factorisation with partial pivoting
//! (faer) of the patch-level system (I − M) per channel, with near-field links summed back
//! to their patches. The element-level remainder (near links resolving a patch's elements)
//! is removed by iterative refinement with the same factors (Wilkinson's defect
//! correction): r = E + ρK(B) − B, solve the patch-level system for the correction's patch
//! means, spread it to the elements, repeat until the residual stops falling (machine
//! precision, typically a handful of steps). With no near field the first step is exact.

use super::observer::SolverClock;
use super::{
    reflect, relative_difference, solution_from, Observer, Solution, SolveError, SolveOptions,
    SolveStats, SolverKind, Step, StepKind,
};
use crate::coupling::Coupling;
use faer::linalg::solvers::Solve;
use faer::Mat;

/// LU of the patch-level system, then defect correction on the element system.
pub fn solve(
    coupling: &dyn Coupling,
    _options: &SolveOptions,
    observer: &mut dyn Observer,
) -> Result<Solution, SolveError> {
    let dense = coupling.as_dense().ok_or(SolveError::NeedsDense {
        solver: SolverKind::Direct,
        coupling: coupling.name(),
    })?;
    let mesh = coupling.mesh();
    let mut clock = SolverClock::start();
    let m = mesh.patches.len();
    let matrix = dense.patch_matrix();
    let lus: Vec<_> = (0..3)
        .map(|c| {
            Mat::<f64>::from_fn(m, m, |i, j| (i == j) as u8 as f64 - matrix[c][i * m + j])
                .partial_piv_lu()
        })
        .collect();
    // Spreads a patch-level solve of the element residual r into an element correction:
    // δ̄ = (I − M)⁻¹ r̄, δ_e = r_e + ρ_e Σ_q F_{e→q} δ̄_q (full rows, near summed back).
    let correct = |r: &[[f64; 3]]| -> Vec<[f64; 3]> {
        let rp = dense.patch_means(r);
        let mut dp = vec![[0.0; 3]; m];
        for (c, lu) in lus.iter().enumerate() {
            let mut rhs = Mat::<f64>::from_fn(m, 1, |i, _| rp[i][c]);
            lu.solve_in_place(rhs.as_mut());
            for (i, d) in dp.iter_mut().enumerate() {
                d[c] = rhs[(i, 0)];
            }
        }
        let spread = dense.gather_patch_values(&dp);
        mesh.elements
            .iter()
            .enumerate()
            .map(|(e, el)| {
                let rho = mesh.reflectance(el);
                std::array::from_fn(|c| r[e][c] + rho[c] * spread[e][c])
            })
            .collect()
    };
    // B starts at 0, so the first residual is E and the first correction the patch solve.
    let mut b = vec![[0.0; 3]; mesh.elements.len()];
    let mut residual = f64::INFINITY;
    let mut steps = 0;
    for _ in 0..50 {
        let next = reflect(mesh, &coupling.gather(&b));
        let r: Vec<[f64; 3]> = next
            .iter()
            .zip(&b)
            .map(|(n, x)| std::array::from_fn(|c| n[c] - x[c]))
            .collect();
        let delta = correct(&r);
        let candidate: Vec<[f64; 3]> = b
            .iter()
            .zip(&delta)
            .map(|(x, d)| std::array::from_fn(|c| x[c] + d[c]))
            .collect();
        let after = reflect(mesh, &coupling.gather(&candidate));
        let res = relative_difference(mesh, &candidate, &after);
        steps += 1;
        if res >= residual {
            break;
        }
        b = candidate;
        residual = res;
        clock.report(observer, |elapsed| Step {
            solver: SolverKind::Direct,
            kind: StepKind::Iteration,
            index: steps,
            residual,
            tolerance: 1e-13,
            elapsed,
            mesh,
            radiosity: &b,
            unshot: None,
        });
        if residual < 1e-13 {
            break;
        }
    }
    let seconds = clock.seconds();
    Ok(solution_from(
        coupling,
        b,
        SolveStats {
            solver: SolverKind::Direct,
            iterations: steps,
            residual,
            seconds,
            form_factor_seconds: coupling.form_factor_seconds(),
        },
    ))
}
