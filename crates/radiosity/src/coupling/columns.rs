//! The element × patch coupling computed column by column, when a source shoots.
//!
//! Progressive refinement needs one column per shot: F_{e→p} for every element `e` and the
//! near receivers' links to `p`'s elements. Computing columns on the fly needs O(n) memory
//! instead of the dense matrix's O(n·m); columns are kept in a cache while it fits in its
//! byte budget, so a patch that shoots again costs nothing. Gathering (for residuals and
//! refinement) computes rows on the fly.
//!
//! Far receivers see a patch at the mean of [`super::far_weights`] (what the near receivers
//! leave of each element's power), as in [`super::Dense`]; a patch's weights come from its
//! near links, computed with its first column (or, for gathering, on their own) and kept.

use super::closure::{column_scale, Enclosure};
use super::{far_weights, Coupling, NearField};
use crate::formfactor::Engine;
use crate::mesh::Mesh;
use rayon::prelude::*;
use std::collections::HashMap;
use std::ops::Range;
use std::sync::{Mutex, OnceLock};
use std::time::Instant;

/// One shot's form factors: far values for every element, and near-field rows for the
/// elements the patch is near to.
struct Column {
    far: Vec<f32>,
    near: Vec<(u32, Vec<f32>)>,
}

impl Column {
    fn bytes(&self) -> usize {
        4 * self.far.len()
            + self
                .near
                .iter()
                .map(|(_, r)| 32 + 4 * r.len())
                .sum::<usize>()
    }
}

struct Cache {
    columns: HashMap<usize, Column>,
    bytes: usize,
    form_factor_seconds: f64,
}

/// Columns computed on demand by an engine, cached within a byte budget.
pub struct Columns<'a> {
    mesh: &'a Mesh,
    engine: &'a dyn Engine,
    near: &'a NearField,
    /// Whether the scene is closed ([`Enclosure::probe`]): what the closure of a patch is.
    enclosure: Enclosure,
    /// Far weights of each patch's elements, in element order ([`super::far_weights`]).
    far_weight: Vec<OnceLock<Vec<f64>>>,
    /// Closure R_p of each patch ([`Self::closure`]), computed with its first column.
    closure: Vec<OnceLock<f64>>,
    cache: Mutex<Cache>,
    cache_limit: usize,
}

impl<'a> Columns<'a> {
    /// A coupling over `mesh` whose columns come from `engine`, linking near pairs
    /// element by element, each column balanced for `enclosure` ([`super::closure`]),
    /// caching up to `cache_limit` bytes of columns.
    pub fn new(
        mesh: &'a Mesh,
        engine: &'a dyn Engine,
        near: &'a NearField,
        enclosure: Enclosure,
        cache_limit: u64,
    ) -> Self {
        Self {
            mesh,
            engine,
            near,
            enclosure,
            far_weight: (0..mesh.patches.len()).map(|_| OnceLock::new()).collect(),
            closure: (0..mesh.patches.len()).map(|_| OnceLock::new()).collect(),
            cache: Mutex::new(Cache {
                columns: HashMap::new(),
                bytes: 0,
                form_factor_seconds: 0.0,
            }),
            cache_limit: usize::try_from(cache_limit).unwrap_or(usize::MAX),
        }
    }

    fn compute_column(&self, p: usize) -> Column {
        let mut far = vec![0.0f32; self.mesh.elements.len()];
        let receivers = &self.near.per_patch[p];
        // The whole column first (a method may compute columns faster than pairs), then
        // the near receivers are resolved element by element.
        self.engine.column(p, &mut far);
        for &e in receivers {
            far[e as usize] = 0.0;
        }
        let mut near = if receivers.is_empty() {
            Vec::new()
        } else {
            self.near_rows(p)
        };
        // The power the column delivers per unit radiosity, brought to what reciprocity
        // says (`super::closure`): A_p times the closure of the patch's central element.
        let area = |e: u32| self.mesh.elements[e as usize].area;
        let delivered: f64 = far
            .iter()
            .enumerate()
            .map(|(e, &f)| area(e as u32) * f as f64)
            .sum::<f64>()
            + near
                .iter()
                .map(|(e, row)| area(*e) * row.iter().map(|&f| f as f64).sum::<f64>())
                .sum::<f64>();
        let patch = &self.mesh.patches[p];
        let target = self.mesh.patch_area(patch) * self.closure(p);
        let scale = column_scale(delivered, target);
        if scale != 1.0 {
            for f in far.iter_mut() {
                *f = (*f as f64 * scale) as f32;
            }
            for (_, row) in near.iter_mut() {
                for f in row.iter_mut() {
                    *f = (*f as f64 * scale) as f32;
                }
            }
        }
        if !near.is_empty() {
            self.far_weight[p].get_or_init(|| self.weights_from(p, &near));
        }
        Column { far, near }
    }

    /// R_p: the fraction of the hemisphere that sees any surface; 1 in a closed scene, else
    /// Σ_q F_{e→q} (at most 1) of the element of patch `p` nearest its centroid (one row,
    /// computed once per patch).
    fn closure(&self, p: usize) -> f64 {
        if self.enclosure == Enclosure::Closed {
            return 1.0;
        }
        *self.closure[p].get_or_init(|| {
            let patch = &self.mesh.patches[p];
            let centre = patch.polygon.centroid();
            let central = patch
                .elements
                .clone()
                .min_by(|&a, &b| {
                    let d = |e: u32| self.mesh.elements[e as usize].centre.distance(centre);
                    d(a).total_cmp(&d(b))
                })
                .unwrap_or(patch.elements.start);
            let mut row = vec![0.0f32; self.mesh.patches.len()];
            self.engine.row(central as usize, &mut row);
            self.enclosure
                .row_target(row.iter().map(|&f| f as f64).sum())
        })
    }

    /// F_{e→s} from every near receiver e of patch `p` to each of its elements s.
    fn near_rows(&self, p: usize) -> Vec<(u32, Vec<f32>)> {
        let sources = self.mesh.patches[p].elements.clone();
        self.near.per_patch[p]
            .par_iter()
            .map(|&e| {
                let row = sources
                    .clone()
                    .map(|s| self.engine.element_pair(e as usize, s as usize) as f32)
                    .collect();
                (e, row)
            })
            .collect()
    }

    /// Far weights of patch `p` from its near rows.
    fn weights_from(&self, p: usize, near: &[(u32, Vec<f32>)]) -> Vec<f64> {
        let patch = &self.mesh.patches[p];
        let mut taken = vec![0.0; patch.elements.len()];
        for (e, row) in near {
            let a = self.mesh.elements[*e as usize].area;
            for (t, f) in taken.iter_mut().zip(row) {
                *t += a * *f as f64;
            }
        }
        far_weights(self.mesh, patch, &taken)
    }

    /// Far weights of patch `p` (computing its near rows if no column has yet).
    fn weights(&self, p: usize) -> &[f64] {
        self.far_weight[p].get_or_init(|| {
            if self.near.per_patch[p].is_empty() {
                let patch = &self.mesh.patches[p];
                far_weights(self.mesh, patch, &vec![0.0; patch.elements.len()])
            } else {
                self.weights_from(p, &self.near_rows(p))
            }
        })
    }

    /// The far mean of every patch of per-element values `b`.
    fn far_means(&self, b: &[[f64; 3]]) -> Vec<[f64; 3]> {
        (0..self.mesh.patches.len())
            .into_par_iter()
            .map(|p| {
                let range = self.mesh.patches[p].elements.clone();
                let local = &b[range.start as usize..range.end as usize];
                let w = self.weights(p);
                let mut m = [0.0; 3];
                for (v, w) in local.iter().zip(w) {
                    for c in 0..3 {
                        m[c] += v[c] * w;
                    }
                }
                m
            })
            .collect()
    }

    /// Runs `f` on column `p`, from the cache or computed (and cached while room remains).
    fn with_column<R>(&self, p: usize, f: impl FnOnce(&Column) -> R) -> R {
        let cached = self
            .cache
            .lock()
            .ok()
            .and_then(|mut c| c.columns.remove(&p));
        let column = match cached {
            Some(c) => c,
            None => {
                let started = Instant::now();
                let c = self.compute_column(p);
                if let Ok(mut cache) = self.cache.lock() {
                    cache.form_factor_seconds += started.elapsed().as_secs_f64();
                    let bytes = c.bytes();
                    if cache.bytes + bytes > self.cache_limit {
                        drop(cache);
                        return f(&c);
                    }
                    cache.bytes += bytes;
                }
                c
            }
        };
        let result = f(&column);
        if let Ok(mut cache) = self.cache.lock() {
            cache.columns.insert(p, column);
        }
        result
    }

    /// H_e for one element from patch means `bp` and element values `b`, by rows.
    fn irradiance_at(&self, e: usize, bp: &[[f64; 3]], b: &[[f64; 3]]) -> [f64; 3] {
        let mut row = vec![0.0f32; self.mesh.patches.len()];
        self.engine.row(e, &mut row);
        let mut h = [0.0; 3];
        for (q, (f, m)) in row.iter().zip(bp).enumerate() {
            if self.near.is_near(e, q) {
                for s in self.mesh.patches[q].elements.clone() {
                    let f = self.engine.element_pair(e, s as usize);
                    for c in 0..3 {
                        h[c] += f * b[s as usize][c];
                    }
                }
            } else {
                for c in 0..3 {
                    h[c] += *f as f64 * m[c];
                }
            }
        }
        h
    }
}

impl Coupling for Columns<'_> {
    fn name(&self) -> &'static str {
        "columns"
    }

    fn mesh(&self) -> &Mesh {
        self.mesh
    }

    fn gather(&self, b: &[[f64; 3]]) -> Vec<[f64; 3]> {
        let bp = self.far_means(b);
        (0..b.len())
            .into_par_iter()
            .map(|e| self.irradiance_at(e, &bp, b))
            .collect()
    }

    fn gather_elements(&self, elements: &[u32], b: &[[f64; 3]]) -> Vec<[f64; 3]> {
        let bp = self.far_means(b);
        elements
            .par_iter()
            .map(|&e| self.irradiance_at(e as usize, &bp, b))
            .collect()
    }

    fn sources(&self) -> usize {
        self.mesh.patches.len()
    }

    fn source_elements(&self, source: usize) -> Range<u32> {
        self.mesh.patches[source].elements.clone()
    }

    fn shoot(&self, source: usize, shot: &[[f64; 3]], receive: &mut dyn FnMut(usize, [f64; 3])) {
        self.with_column(source, |column| {
            let w = self.weights(source);
            let mut mean = [0.0; 3];
            for (u, w) in shot.iter().zip(w) {
                for c in 0..3 {
                    mean[c] += u[c] * w;
                }
            }
            for (e, &f) in column.far.iter().enumerate() {
                if f != 0.0 {
                    let f = f as f64;
                    receive(e, mean.map(|m| f * m));
                }
            }
            for (e, row) in &column.near {
                let mut dh = [0.0; 3];
                for (f, u) in row.iter().zip(shot) {
                    for c in 0..3 {
                        dh[c] += *f as f64 * u[c];
                    }
                }
                receive(*e as usize, dh);
            }
        })
    }

    fn memory_bytes(&self) -> u64 {
        self.cache.lock().map_or(0, |c| c.bytes as u64)
    }

    fn form_factor_seconds(&self) -> f64 {
        self.cache.lock().map_or(0.0, |c| c.form_factor_seconds)
    }
}
