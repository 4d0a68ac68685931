//! The coupling stage: which pieces of the scene exchange light, at what level, and how much.
//!
//! A coupling is the value between form factors and solution. Whatever its shape, it answers
//! the questions every solver asks ([`Coupling`]):
//! - **gather**: the irradiance of every element from the radiosity of every element,
//!   H = K(B) (W·m⁻²), for Jacobi, Gauss–Seidel and residuals;
//! - **shoot**: the irradiance one source's unshot radiosity adds to every receiver, for
//!   progressive refinement;
//! - **memory**: what it holds.
//!
//! Shapes (implementations):
//! - [`Dense`]: every element × patch form factor computed up front (rows in parallel), plus
//!   element-to-element links where a patch is near (the two-level hierarchy of Cohen et al.
//!   1986 refined by the near field);
//! - [`Columns`]: the same links computed column by column when a source shoots, kept in a
//!   cache while it fits;
//! - the hierarchical coupling (`hierarchical`), multi-level links refined by an error
//!   oracle.
//!
//! Which pairs link element to patch and which element to element is decided by one oracle,
//! [`NearField`], in one place.

pub mod closure;
pub mod columns;
pub mod dense;
pub mod hierarchical;
pub mod near_field;

pub use columns::Columns;
pub use dense::Dense;
pub use near_field::NearField;

use crate::mesh::{Mesh, Patch};
use std::ops::Range;

/// How elements exchange light: the operator H = K(B) of the radiosity system
/// B = E + ρ K(B), in the forms solvers need.
pub trait Coupling: Sync {
    /// A short name for reports ("dense", "columns", "hierarchical").
    fn name(&self) -> &'static str;

    /// The mesh whose elements are the unknowns.
    fn mesh(&self) -> &Mesh;

    /// H = K(B): the irradiance (W·m⁻²) of every element from the radiosity B (W·m⁻²) of
    /// every element.
    fn gather(&self, radiosity: &[[f64; 3]]) -> Vec<[f64; 3]>;

    /// H of the listed elements only (default: all, then picked).
    fn gather_elements(&self, elements: &[u32], radiosity: &[[f64; 3]]) -> Vec<[f64; 3]> {
        let h = self.gather(radiosity);
        elements.iter().map(|&e| h[e as usize]).collect()
    }

    /// One Gauss–Seidel sweep: for each element in turn, its irradiance from the newest
    /// radiosities, then `radiosity[e] = update(e, H_e)`. The default gathers once for all
    /// elements (a Jacobi step); couplings that can do better override it.
    fn sweep(
        &self,
        radiosity: &mut [[f64; 3]],
        update: &mut dyn FnMut(usize, [f64; 3]) -> [f64; 3],
    ) {
        let h = self.gather(radiosity);
        for (e, h) in h.into_iter().enumerate() {
            radiosity[e] = update(e, h);
        }
    }

    /// Number of shooting sources (0 if the coupling cannot shoot).
    fn sources(&self) -> usize;

    /// The elements making up source `source` (contiguous).
    fn source_elements(&self, source: usize) -> Range<u32>;

    /// Shoots radiosity `shot` (W·m⁻², one value per element of `source`, in order) and
    /// reports the irradiance it adds to each receiving element, `receive(e, ΔH_e)`.
    fn shoot(&self, source: usize, shot: &[[f64; 3]], receive: &mut dyn FnMut(usize, [f64; 3]));

    /// Bytes of form factors and links held.
    fn memory_bytes(&self) -> u64;

    /// Wall-clock seconds spent computing form factors so far.
    fn form_factor_seconds(&self) -> f64;

    /// The element × patch coupling, if that is what this is (the direct solver factorises
    /// its patch-level system).
    fn as_dense(&self) -> Option<&Dense<'_>> {
        None
    }
}

/// Area-weighted mean (W·m⁻²) of a shot over a source patch: Σ_s A_s u_s / A_p, where `shot`
/// holds one value per element of `range`.
pub fn shot_mean(mesh: &Mesh, range: Range<u32>, patch_area: f64, shot: &[[f64; 3]]) -> [f64; 3] {
    let mut mean = [0.0; 3];
    for (s, u) in range.zip(shot) {
        let a = mesh.elements[s as usize].area / patch_area;
        for c in 0..3 {
            mean[c] += u[c] * a;
        }
    }
    mean
}

/// Area-weighted mean of per-element values over each patch's elements.
pub fn patch_means(mesh: &Mesh, patch_area: &[f64], b: &[[f64; 3]]) -> Vec<[f64; 3]> {
    mesh.patches
        .iter()
        .zip(patch_area)
        .map(|(p, a)| {
            let mut m = [0.0; 3];
            for e in p.elements.clone() {
                let el = &mesh.elements[e as usize];
                for c in 0..3 {
                    m[c] += b[e as usize][c] * el.area / a;
                }
            }
            m
        })
        .collect()
}

/// The weights with which a patch's **far** receivers see its elements, so that a two-level
/// coupling conserves energy.
///
/// Far receivers gather from a patch p at one mean radiosity B̃_p = Σ_{s∈p} w_s B_s, near
/// receivers from each element s at its own B_s. Element s sends the fraction
/// N_s = Σ_{near e} A_e F_{e→s} / A_s of its power to the near receivers (reciprocity), so
/// only B_s A_s (1 − N_s) is left for the far ones, which receive B̃_p Σ_{far e} A_e F_{e→p} =
/// B̃_p (A_p − Σ_s A_s N_s) in all. Power is conserved for every distribution of B over the
/// patch exactly when
///
///   w_s = A_s (1 − N_s) / Σ_{s'∈p} A_{s'} (1 − N_{s'}).
///
/// The plain area mean (w_s = A_s / A_p) agrees only when every N_s is the same; near a
/// corner the elements next to the other wall give it more of their light than the rest of
/// the patch does, so with the area mean the far receivers were credited with power that the
/// near receivers had already taken, or denied power nobody took — a closed cube with
/// ρ = 0.9 lost 0.6 % of its power per solve ("escaped"), and 1/(1 − ρ) bounces made every
/// face 0.7 % dark. With no near receivers the weights are the area weights.
///
/// `taken[k]` is Σ_{near e} A_e F_{e→s} (m²) for the k-th element s of `patch`. Negative
/// remainders (form-factor error) count as 0; if nothing is left for the far receivers
/// (Σ w < 10⁻⁹ A_p) the area weights are returned. The weights sum to 1 over the patch.
pub fn far_weights(mesh: &Mesh, patch: &Patch, taken: &[f64]) -> Vec<f64> {
    let elements = &mesh.elements[patch.elements.start as usize..patch.elements.end as usize];
    let area: f64 = elements.iter().map(|e| e.area).sum();
    let left: Vec<f64> = elements
        .iter()
        .zip(taken)
        .map(|(e, t)| (e.area - t).max(0.0))
        .collect();
    let total: f64 = left.iter().sum();
    if total < 1e-9 * area || !total.is_finite() {
        return elements.iter().map(|e| e.area / area).collect();
    }
    left.iter().map(|w| w / total).collect()
}

/// Σ_s w_s v_s over the elements `range` of a patch, with `weights` indexed by element
/// (global index).
pub fn weighted_mean(range: Range<u32>, weights: &[f64], values: &[[f64; 3]]) -> [f64; 3] {
    let mut mean = [0.0; 3];
    for (s, v) in range.zip(values) {
        let w = weights[s as usize];
        for c in 0..3 {
            mean[c] += v[c] * w;
        }
    }
    mean
}

/// [`weighted_mean`] of the per-element values `b` (indexed by element) over every patch.
pub fn far_means(mesh: &Mesh, weights: &[f64], b: &[[f64; 3]]) -> Vec<[f64; 3]> {
    mesh.patches
        .iter()
        .map(|p| {
            let r = p.elements.start as usize..p.elements.end as usize;
            weighted_mean(p.elements.clone(), weights, &b[r])
        })
        .collect()
}
