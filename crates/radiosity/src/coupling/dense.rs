//! The dense element × patch coupling, computed up front.
//!
//! Unknowns live on two levels (substructuring, Cohen, Greenberg, Immel & Brock 1986):
//! elements gather from patches at the patch's mean radiosity B̄_q = Σ_{e∈q} w_e B_e (the
//! area mean, w_e = A_e / A_q, where no receiver is near the patch), except that near pairs ([`NearField`]) link element to
//! element:
//!
//!   H_e = Σ_{far q} F_{e→q} B̄_q + Σ_{near e'} F_{e→e'} B_e'.
//!
//! The far factors are a dense row-major matrix of f32 (zero where the pair is near), the
//! near links a sparse list per element. The mean far receivers see, B̄_q, weighs each
//! element by the share of its power the near receivers leave (see [`super::far_weights`]),
//! so that the coupling conserves energy whatever the radiosity does across a patch. The
//! factors are balanced once computed ([`super::closure::balance_dense`]): rows keep their
//! sums, and each patch's column delivers the power reciprocity says it must.

use super::closure::Enclosure;
use super::{far_means, far_weights, weighted_mean, Coupling, NearField};
use crate::formfactor::Engine;
use crate::mesh::Mesh;
use crate::progress::Progress;
use rayon::prelude::*;
use std::ops::Range;
use std::time::Instant;

/// Every element × patch form factor, plus near-field element links.
pub struct Dense<'a> {
    mesh: &'a Mesh,
    patches: usize,
    /// F_{e→p}, row-major, zero for near pairs.
    data: Vec<f32>,
    /// Near-field links of each element: (source element, F_{e→e'}), sorted by source.
    near: Vec<Vec<(u32, f32)>>,
    /// Receivers with near links to each patch (sorted).
    near_receivers: Vec<Vec<u32>>,
    patch_area: Vec<f64>,
    /// Weight of each element in its patch's far mean ([`super::far_weights`]).
    far_weight: Vec<f64>,
    form_factor_seconds: f64,
    /// The far factors column-major (patch by patch, every element), made on the first shot:
    /// a shot reads one patch's column, which the row-major matrix spreads over one cache
    /// line per element (measured by `radiosity compare` on the default Cornell mesh, 4680
    /// elements × 528 patches: progressive to 1e-4, 3374 shots, 453–695 ms reading the
    /// rows' stride, 177–283 ms reading a column copy).
    columns: std::sync::OnceLock<Vec<f32>>,
}

impl<'a> Dense<'a> {
    /// Bytes the far matrix of a mesh needs (the near links add a little).
    pub fn bytes_for(elements: usize, patches: usize) -> u128 {
        elements as u128 * patches as u128 * 4
    }

    /// Computes every row in parallel with `engine`, linking near pairs element by element,
    /// then balances rows and columns for `enclosure` ([`super::closure`]).
    pub fn compute(
        mesh: &'a Mesh,
        engine: &dyn Engine,
        near_field: &NearField,
        enclosure: Enclosure,
        progress: &dyn Progress,
    ) -> Self {
        let started = Instant::now();
        let (n, m) = (mesh.elements.len(), mesh.patches.len());
        let mut data = vec![0.0f32; n * m];
        progress.start("form factors", n as u64);
        let mut near: Vec<Vec<(u32, f32)>> = data
            .par_chunks_mut(m.max(1))
            .enumerate()
            .map(|(e, row)| {
                let mut links = Vec::new();
                // The whole row first (a method may compute rows faster than pairs), then
                // the near patches are resolved into element links.
                engine.row(e, row);
                for &p in &near_field.per_element[e] {
                    row[p as usize] = 0.0;
                    for s in mesh.patches[p as usize].elements.clone() {
                        let v = engine.element_pair(e, s as usize);
                        if v > 0.0 {
                            links.push((s, v as f32));
                        }
                    }
                }
                links.sort_unstable_by_key(|l| l.0);
                progress.inc(1);
                links
            })
            .collect();
        progress.finish();
        // Rows keep their closure, columns get the power reciprocity says they deliver.
        super::closure::balance_dense(mesh, enclosure, m, &mut data, &mut near);
        // Σ_{near e} A_e F_{e→s} per source element s.
        let mut taken = vec![0.0; n];
        for (e, links) in near.iter().enumerate() {
            let a = mesh.elements[e].area;
            for &(s, f) in links {
                taken[s as usize] += a * f as f64;
            }
        }
        let mut far_weight = Vec::with_capacity(n);
        for p in &mesh.patches {
            let range = p.elements.start as usize..p.elements.end as usize;
            far_weight.extend(far_weights(mesh, p, &taken[range]));
        }
        Self {
            mesh,
            patches: m,
            data,
            near,
            near_receivers: near_field.per_patch.clone(),
            patch_area: mesh.patches.iter().map(|p| mesh.patch_area(p)).collect(),
            far_weight,
            form_factor_seconds: started.elapsed().as_secs_f64(),
            columns: std::sync::OnceLock::new(),
        }
    }

    /// Far factors F_{e→p} of element `e` (zero where near).
    pub fn row(&self, e: usize) -> &[f32] {
        &self.data[e * self.patches..(e + 1) * self.patches]
    }

    /// Near-field links of element `e`: (source element, F_{e→e'}).
    pub fn near_links(&self, e: usize) -> &[(u32, f32)] {
        &self.near[e]
    }

    /// Areas of the patches, m².
    pub fn patch_areas(&self) -> &[f64] {
        &self.patch_area
    }

    /// F_{e→p} with the near-field links to `p`'s elements summed back into it.
    pub fn full_row(&self, e: usize) -> Vec<f64> {
        let mut row: Vec<f64> = self.row(e).iter().map(|&f| f as f64).collect();
        for &(s, f) in &self.near[e] {
            row[self.mesh.elements[s as usize].patch.0 as usize] += f as f64;
        }
        row
    }

    /// H_e for one element given patch means `bp` and element values `b`.
    fn irradiance_at(&self, e: usize, bp: &[[f64; 3]], b: &[[f64; 3]]) -> [f64; 3] {
        let mut h = [0.0; 3];
        for (f, q) in self.row(e).iter().zip(bp) {
            let f = *f as f64;
            h[0] += f * q[0];
            h[1] += f * q[1];
            h[2] += f * q[2];
        }
        for &(s, f) in &self.near[e] {
            for c in 0..3 {
                h[c] += f as f64 * b[s as usize][c];
            }
        }
        h
    }

    /// The means far receivers see of per-element values over each patch (weighted by
    /// [`super::far_weights`]; area-weighted where no element is near).
    pub fn patch_means(&self, b: &[[f64; 3]]) -> Vec<[f64; 3]> {
        far_means(self.mesh, &self.far_weight, b)
    }

    /// The patch-level system with near links summed back to their patches,
    /// M_pq = Σ_{e∈p} (A_e / A_p) ρ_e F_{e→q}, per channel, row-major.
    pub fn patch_matrix(&self) -> [Vec<f64>; 3] {
        let m = self.patches;
        let rows: Vec<[Vec<f64>; 3]> = self
            .mesh
            .patches
            .par_iter()
            .zip(&self.patch_area)
            .map(|(patch, area)| {
                let mut row: [Vec<f64>; 3] = std::array::from_fn(|_| vec![0.0; m]);
                for e in patch.elements.clone() {
                    let el = &self.mesh.elements[e as usize];
                    let w = el.area / area;
                    let rho = self.mesh.reflectance(el);
                    let full = self.full_row(e as usize);
                    for c in 0..3 {
                        let scale = w * rho[c];
                        for (dst, f) in row[c].iter_mut().zip(&full) {
                            *dst += scale * f;
                        }
                    }
                }
                row
            })
            .collect();
        let mut matrix: [Vec<f64>; 3] = std::array::from_fn(|_| Vec::with_capacity(m * m));
        for row in rows {
            for c in 0..3 {
                matrix[c].extend_from_slice(&row[c]);
            }
        }
        matrix
    }

    /// Σ_q F_{e→q} v_q per element (full rows, near links summed back): irradiance from
    /// patch-level values `v` spread uniformly over each patch.
    pub fn gather_patch_values(&self, v: &[[f64; 3]]) -> Vec<[f64; 3]> {
        (0..self.mesh.elements.len())
            .into_par_iter()
            .map(|e| {
                let full = self.full_row(e);
                std::array::from_fn(|c| full.iter().zip(v).map(|(f, d)| f * d[c]).sum())
            })
            .collect()
    }
}

impl Coupling for Dense<'_> {
    fn name(&self) -> &'static str {
        "dense"
    }

    fn mesh(&self) -> &Mesh {
        self.mesh
    }

    fn gather(&self, b: &[[f64; 3]]) -> Vec<[f64; 3]> {
        let bp = self.patch_means(b);
        (0..b.len())
            .into_par_iter()
            .map(|e| self.irradiance_at(e, &bp, b))
            .collect()
    }

    fn gather_elements(&self, elements: &[u32], b: &[[f64; 3]]) -> Vec<[f64; 3]> {
        let bp = self.patch_means(b);
        elements
            .par_iter()
            .map(|&e| self.irradiance_at(e as usize, &bp, b))
            .collect()
    }

    /// In place, element by element, with the patch means kept current as elements change.
    fn sweep(&self, b: &mut [[f64; 3]], update: &mut dyn FnMut(usize, [f64; 3]) -> [f64; 3]) {
        let mut bp = self.patch_means(b);
        for (e, el) in self.mesh.elements.iter().enumerate() {
            let h = self.irradiance_at(e, &bp, b);
            let new = update(e, h);
            let q = el.patch.0 as usize;
            for c in 0..3 {
                bp[q][c] += (new[c] - b[e][c]) * self.far_weight[e];
            }
            b[e] = new;
        }
    }

    fn sources(&self) -> usize {
        self.patches
    }

    fn source_elements(&self, source: usize) -> Range<u32> {
        self.mesh.patches[source].elements.clone()
    }

    /// Column `source` of the far matrix at the shot's far mean, and the near receivers'
    /// links to the source's elements at each element's own shot.
    fn shoot(&self, source: usize, shot: &[[f64; 3]], receive: &mut dyn FnMut(usize, [f64; 3])) {
        let range = self.source_elements(source);
        let mean = weighted_mean(range.clone(), &self.far_weight, shot);
        let elements = self.mesh.elements.len();
        let columns = self.columns.get_or_init(|| {
            let mut t = vec![0.0f32; self.data.len()];
            for (e, row) in self.data.chunks_exact(self.patches.max(1)).enumerate() {
                for (p, &f) in row.iter().enumerate() {
                    t[p * elements + e] = f;
                }
            }
            t
        });
        let column = &columns[source * elements..(source + 1) * elements];
        for (e, &f) in column.iter().enumerate() {
            if f != 0.0 {
                let f = f as f64;
                receive(e, mean.map(|m| f * m));
            }
        }
        for &e in &self.near_receivers[source] {
            let links = &self.near[e as usize];
            let start = links.partition_point(|l| l.0 < range.start);
            let mut dh = [0.0; 3];
            for &(s, f) in links[start..].iter().take_while(|l| l.0 < range.end) {
                let u = shot[(s - range.start) as usize];
                for c in 0..3 {
                    dh[c] += f as f64 * u[c];
                }
            }
            receive(e as usize, dh);
        }
    }

    fn memory_bytes(&self) -> u64 {
        let columns = self.columns.get().map_or(0, Vec::len);
        ((self.data.len() + columns) * 4
            + self.near.iter().map(|l| 24 + l.len() * 8).sum::<usize>()) as u64
    }

    fn form_factor_seconds(&self) -> f64 {
        self.form_factor_seconds
    }

    fn as_dense(&self) -> Option<&Dense<'_>> {
        Some(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::Visibility;
    use crate::coupling::closure::Enclosure;
    use crate::formfactor::{engine, FormFactorMethod};
    use crate::mesh::MeshOptions;
    use crate::progress::NoProgress;

    /// A shot is the gather of one source alone: for every patch p and radiosity u on its
    /// elements only (different per element and channel), what `shoot(p, u)` delivers to
    /// each element equals `gather` of u placed on p — far factors read column by column
    /// from the column copy, near links from the element lists. Both sum the same f32
    /// factors in f64 (in a different order), so they agree to rounding: 1e-12 relative.
    #[test]
    fn every_patch_shoots_what_the_gather_of_that_patch_alone_receives() {
        let scene = crate::cornell::cornell_box();
        let options = MeshOptions {
            elements: 300,
            ..Default::default()
        };
        let mesh = Mesh::build(&scene, &options).unwrap();
        let visibility = Visibility::new(&mesh);
        let near = NearField::decide(&mesh);
        let enclosure = Enclosure::probe(&mesh, &visibility);
        let engine = engine(
            FormFactorMethod::Raycast,
            &mesh,
            &visibility,
            &near.per_element,
        );
        let coupling = Dense::compute(&mesh, engine.as_ref(), &near, enclosure, &NoProgress);
        let n = mesh.elements.len();
        let (mut near_checked, mut reaching) = (0, 0);
        for p in 0..coupling.sources() {
            let range = coupling.source_elements(p);
            let shot: Vec<[f64; 3]> = range
                .clone()
                .map(|e| {
                    let x = 1.0 + (e % 7) as f64;
                    [x, 2.0 * x, 0.5 + x * x]
                })
                .collect();
            let mut b = vec![[0.0; 3]; n];
            for (e, u) in range.clone().zip(&shot) {
                b[e as usize] = *u;
            }
            let gathered = coupling.gather(&b);
            let mut shot_in = vec![[0.0; 3]; n];
            coupling.shoot(p, &shot, &mut |e, dh| {
                for c in 0..3 {
                    shot_in[e][c] += dh[c];
                }
            });
            near_checked += coupling.near_receivers[p].len();
            // (A patch of floor under a block reaches nothing: both sides are zero.)
            let scale = gathered
                .iter()
                .flatten()
                .fold(0.0f64, |m, x| m.max(x.abs()));
            reaching += usize::from(scale > 0.0);
            for e in 0..n {
                for c in 0..3 {
                    let (g, s) = (gathered[e][c], shot_in[e][c]);
                    assert!(
                        (g - s).abs() <= 1e-12 * scale,
                        "patch {p} → element {e}, channel {c}: gather {g}, shoot {s}"
                    );
                }
            }
        }
        assert!(near_checked > 0, "no near links were exercised");
        assert!(
            reaching > coupling.sources() * 3 / 4,
            "only {reaching} of {} patches reach anything",
            coupling.sources()
        );
    }
}
