//! Direct solution of the patch system by Gaussian elimination: a dense LU factorisation
//! with partial pivoting (faer) of (I − M) for each channel, then B = (I − M)⁻¹ E.

use super::PatchSystem;
use faer::linalg::solvers::Solve;
use faer::Mat;

/// Returns (B per patch, 1, relative residual).
pub fn solve(system: &PatchSystem) -> (Vec<[f64; 3]>, usize, f64) {
    let n = system.patches;
    let mut b = vec![[0.0; 3]; n];
    for c in 0..3 {
        let m = &system.matrix[c];
        let a = Mat::<f64>::from_fn(n, n, |i, j| (i == j) as u8 as f64 - m[i * n + j]);
        let lu = a.partial_piv_lu();
        let mut rhs = Mat::<f64>::from_fn(n, 1, |i, _| system.exitance[i][c]);
        lu.solve_in_place(rhs.as_mut());
        for (i, bi) in b.iter_mut().enumerate() {
            bi[c] = rhs[(i, 0)];
        }
    }
    let residual = system.residual(&b);
    (b, 1, residual)
}
