//! Direct solution by Gaussian elimination: a dense LU factorisation with partial pivoting
//! (faer) of the patch-level system (I − M) per channel, with near-field links summed back
//! to their patches. The element-level remainder (near links resolving a patch's elements)
//! is removed by iterative refinement with the same factors (Wilkinson's defect
//! correction): r = E + ρT(B) − B, solve the patch-level system for the correction's patch
//! means, spread it to the elements, repeat until the residual stops falling (machine
//! precision, typically a handful of steps). With no near field the first step is exact.

use super::{SolveOptions, Transport};
use faer::linalg::solvers::Solve;
use faer::Mat;

/// Returns (B per element, LU solves, relative residual).
pub fn solve(t: &Transport, _options: &SolveOptions) -> (Vec<[f64; 3]>, usize, f64) {
    let mesh = t.mesh;
    let m = mesh.patches.len();
    let matrix = t.patch_matrix();
    let lus: Vec<_> = (0..3)
        .map(|c| {
            Mat::<f64>::from_fn(m, m, |i, j| (i == j) as u8 as f64 - matrix[c][i * m + j])
                .partial_piv_lu()
        })
        .collect();
    // Spreads a patch-level solve of the element residual r into an element correction:
    // δ̄ = (I − M)⁻¹ r̄, δ_e = r_e + ρ_e Σ_q F_{e→q} δ̄_q (full rows, near summed back).
    let correct = |r: &[[f64; 3]]| -> Vec<[f64; 3]> {
        let rp = t.patch_means(r);
        let mut dp = vec![[0.0; 3]; m];
        for (c, lu) in lus.iter().enumerate() {
            let mut rhs = Mat::<f64>::from_fn(m, 1, |i, _| rp[i][c]);
            lu.solve_in_place(rhs.as_mut());
            for (i, d) in dp.iter_mut().enumerate() {
                d[c] = rhs[(i, 0)];
            }
        }
        mesh.elements
            .iter()
            .enumerate()
            .map(|(e, el)| {
                let full = t.coupling.full_row(mesh, e);
                let rho = mesh.reflectance(el);
                std::array::from_fn(|c| {
                    r[e][c] + rho[c] * full.iter().zip(&dp).map(|(f, d)| f * d[c]).sum::<f64>()
                })
            })
            .collect()
    };
    // B starts at 0, so the first residual is E and the first correction the patch solve.
    let mut b = vec![[0.0; 3]; mesh.elements.len()];
    let mut residual = f64::INFINITY;
    let mut steps = 0;
    for _ in 0..50 {
        let next = t.apply(&b);
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
        let res = t.residual(&candidate);
        steps += 1;
        if res >= residual {
            break;
        }
        b = candidate;
        residual = res;
        if residual < 1e-13 {
            break;
        }
    }
    (b, steps, residual)
}
