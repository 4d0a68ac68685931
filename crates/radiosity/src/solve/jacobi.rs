//! Jacobi iteration: B⁽ᵏ⁺¹⁾ = E + ρ K(B⁽ᵏ⁾), starting from B⁽⁰⁾ = E. Converges because
//! ρ < 1 and the form factors of each element sum to at most 1.
//!
//! The residual of B⁽ᵏ⁾, ‖E + ρK(B⁽ᵏ⁾) − B⁽ᵏ⁾‖/‖E‖, is exactly the change ‖B⁽ᵏ⁺¹⁾ − B⁽ᵏ⁾‖/‖E‖,
//! so it costs nothing extra; the iteration stops when it falls to the tolerance and returns
//! the newer iterate B⁽ᵏ⁺¹⁾.

use super::{iterate, reflect, Observer, Solution, SolveOptions, SolverKind};
use crate::coupling::Coupling;

/// Iterates to the tolerance or the iteration cap (or until the observer stops it).
pub fn solve(
    coupling: &dyn Coupling,
    options: &SolveOptions,
    observer: &mut dyn Observer,
) -> Solution {
    let mesh = coupling.mesh();
    iterate(coupling, SolverKind::Jacobi, options, observer, &mut |b| {
        *b = reflect(mesh, &coupling.gather(b));
    })
}
