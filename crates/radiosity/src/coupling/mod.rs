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

pub mod columns;
pub mod dense;
pub mod hierarchical;
pub mod near_field;

pub use columns::Columns;
pub use dense::Dense;
pub use near_field::NearField;

use crate::mesh::Mesh;
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
