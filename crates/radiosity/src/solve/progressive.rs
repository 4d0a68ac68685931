//! Progressive refinement (Cohen, Chen, Wallace & Greenberg 1988), i.e. Southwell
//! relaxation: repeatedly pick the patch with the largest unshot power Σ_{e∈p} u_e·A_e and
//! shoot it to every element,
//!
//!   ΔH_e = F_{e→p} ω ū_p  (far),   ΔH_e = Σ_{e'∈p} F_{e→e'} ω u_e'  (near field),
//!   ΔB_e = ρ_e ΔH_e,   u_e += ΔB_e,   u_e' ← u_e' − ω u_e' for e' ∈ p,
//!
//! keeping the unshot radiosity u per element (so near receivers see where on the patch the
//! light is) and computing each shot's column on the fly (no n² storage; columns are cached
//! while they fit in the memory limit). ω = 1 is plain shooting; ω > 1 overshoots
//! (over-relaxation), leaving a negative unshot radiosity that later shots correct. Stops
//! when the unshot power is below `tolerance` × emitted power, or after `max_shots`.
//! Bookkeeping is exact: emitted = absorbed + escaped + unshot after every shot.

use super::{Solution, SolveError, SolveOptions, SolveStats, SolverKind};
use crate::formfactor::{FormFactors, NearField};
use crate::mesh::Mesh;
use crate::progress::Progress;
use rayon::prelude::*;
use std::collections::HashMap;
use std::time::Instant;

/// One shot's form factors: far values for every element, and near-field rows for the
/// elements the patch is near to.
struct Column {
    far: Vec<f32>,
    near: Vec<(u32, Vec<f32>)>,
}

/// The state of a progressive solution, which can be advanced shot by shot (for image
/// sequences) and turned into a [`Solution`] at any point.
pub struct Progressive {
    overshoot: f64,
    radiosity: Vec<[f64; 3]>,
    irradiance: Vec<[f64; 3]>,
    /// Unshot radiosity per element, W·m⁻².
    unshot: Vec<[f64; 3]>,
    /// Total radiosity each element has shot so far, W·m⁻² (to gather new elements from).
    shot_total: Vec<[f64; 3]>,
    /// Unshot power per patch, Σ_c |u|·A summed over its elements, W.
    patch_power: Vec<f64>,
    escaped: [f64; 3],
    emitted: f64,
    shots: usize,
    near: Option<NearField>,
    cache: HashMap<usize, Column>,
    cache_limit_bytes: usize,
    cache_bytes: usize,
    form_factor_seconds: f64,
}

impl Progressive {
    /// Starts with B = u = E on every element.
    pub fn new(mesh: &Mesh, options: &SolveOptions) -> Self {
        let radiosity: Vec<[f64; 3]> = mesh.elements.iter().map(|e| mesh.exitance(e)).collect();
        let emitted = Solution::emitted_power(mesh).iter().sum();
        let mut state = Self {
            overshoot: options.overshoot,
            irradiance: vec![[0.0; 3]; mesh.elements.len()],
            unshot: radiosity.clone(),
            shot_total: vec![[0.0; 3]; mesh.elements.len()],
            radiosity,
            patch_power: Vec::new(),
            escaped: [0.0; 3],
            emitted,
            shots: 0,
            near: None,
            cache: HashMap::new(),
            cache_limit_bytes: (options.memory_limit / 2) as usize,
            cache_bytes: 0,
            form_factor_seconds: 0.0,
        };
        state.patch_power = state.patch_powers(mesh);
        state
    }

    fn patch_powers(&self, mesh: &Mesh) -> Vec<f64> {
        mesh.patches
            .iter()
            .map(|p| {
                p.elements
                    .clone()
                    .map(|e| {
                        let u = self.unshot[e as usize];
                        (u[0].abs() + u[1].abs() + u[2].abs()) * mesh.elements[e as usize].area
                    })
                    .sum()
            })
            .collect()
    }

    /// Finds the near field for `ff` now rather than on the first shot (so that timing the
    /// shots, e.g. in [`crate::compare`], leaves this form-factor set-up out).
    pub fn prepare(&mut self, mesh: &Mesh, ff: &dyn FormFactors) {
        if self.near.is_none() {
            self.near = Some(NearField::for_method(mesh, ff));
        }
    }

    /// Shots taken so far.
    pub fn shots(&self) -> usize {
        self.shots
    }

    /// Unshot power as a fraction of the emitted power (0 when nothing emits).
    pub fn unshot_fraction(&self) -> f64 {
        if self.emitted <= 0.0 {
            return 0.0;
        }
        self.patch_power.iter().sum::<f64>() / self.emitted
    }

    fn column(&self, mesh: &Mesh, ff: &dyn FormFactors, near: &NearField, p: usize) -> Column {
        let mut far = vec![0.0f32; mesh.elements.len()];
        let receivers = &near.per_patch[p];
        // The whole column first (a method may compute columns faster than pairs), then
        // the near receivers are resolved element by element.
        ff.column(p, &mut far);
        if receivers.is_empty() {
            return Column {
                far,
                near: Vec::new(),
            };
        }
        for &e in receivers {
            far[e as usize] = 0.0;
        }
        let sources = mesh.patches[p].elements.clone();
        let near_rows = receivers
            .par_iter()
            .map(|&e| {
                let row = sources
                    .clone()
                    .map(|s| ff.element_pair(e as usize, s as usize).unwrap_or(0.0) as f32)
                    .collect();
                (e, row)
            })
            .collect();
        Column {
            far,
            near: near_rows,
        }
    }

    /// Shoots the patch with the largest unshot power; returns false when nothing is left.
    pub fn shoot(&mut self, mesh: &Mesh, ff: &dyn FormFactors) -> bool {
        let Some((p, &power)) = self
            .patch_power
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(b.1))
        else {
            return false;
        };
        if power <= 0.0 {
            return false;
        }
        let started = Instant::now();
        if self.near.is_none() {
            self.near = Some(NearField::for_method(mesh, ff));
        }
        let (column, cached) = match self.cache.remove(&p) {
            Some(c) => (c, true),
            None => {
                let near = self.near.as_ref().expect("near field was just computed");
                (self.column(mesh, ff, near, p), false)
            }
        };
        self.form_factor_seconds += started.elapsed().as_secs_f64();

        // What patch p shoots: ω·u per element, and its area-weighted mean.
        let sources = mesh.patches[p].elements.clone();
        let area_p: f64 = sources
            .clone()
            .map(|e| mesh.elements[e as usize].area)
            .sum();
        let mut shot = Vec::with_capacity(sources.len());
        let mut mean = [0.0; 3];
        let mut shot_power = [0.0; 3];
        for s in sources.clone() {
            let a = mesh.elements[s as usize].area;
            let u: [f64; 3] = std::array::from_fn(|c| self.overshoot * self.unshot[s as usize][c]);
            for c in 0..3 {
                mean[c] += u[c] * a / area_p;
                shot_power[c] += u[c] * a;
                self.unshot[s as usize][c] -= u[c];
                self.shot_total[s as usize][c] += u[c];
            }
            shot.push(u);
        }
        let mut landed = [0.0; 3];
        let receive = |e: usize, dh: [f64; 3], state: &mut Self, landed: &mut [f64; 3]| {
            let el = &mesh.elements[e];
            let rho = mesh.reflectance(el);
            for c in 0..3 {
                let db = rho[c] * dh[c];
                landed[c] += dh[c] * el.area;
                state.irradiance[e][c] += dh[c];
                state.radiosity[e][c] += db;
                state.unshot[e][c] += db;
            }
        };
        for (e, &f) in column.far.iter().enumerate() {
            if f != 0.0 {
                let f = f as f64;
                receive(e, std::array::from_fn(|c| f * mean[c]), self, &mut landed);
            }
        }
        for (e, row) in &column.near {
            let mut dh = [0.0; 3];
            for (f, u) in row.iter().zip(&shot) {
                for c in 0..3 {
                    dh[c] += *f as f64 * u[c];
                }
            }
            receive(*e as usize, dh, self, &mut landed);
        }
        for c in 0..3 {
            self.escaped[c] += shot_power[c] - landed[c];
        }
        // Keep the column while the cache has room.
        let bytes = 4 * column.far.len()
            + column
                .near
                .iter()
                .map(|(_, r)| 8 + 4 * r.len())
                .sum::<usize>();
        if cached || self.cache_bytes + bytes <= self.cache_limit_bytes {
            if !cached {
                self.cache_bytes += bytes;
            }
            self.cache.insert(p, column);
        }
        // Unshot powers changed on p and on every receiving patch.
        self.patch_power = self.patch_powers(mesh);
        self.shots += 1;
        true
    }

    /// Moves the state onto a refined mesh (same patches; see [`crate::refine`]): elements
    /// that were not split keep their values; new children inherit their parent's unshot
    /// and shot radiosity and gather everything shot so far,
    /// H_c = Σ_{far q} F_{c→q} s̄_q + Σ_{near e'} F_{c→e'} s_e', B_c = E_c + ρ_c H_c,
    /// with `ff` built over `refined`.
    pub fn refine(&mut self, old: &Mesh, refined: &Mesh, ff: &dyn FormFactors) {
        let parent = |e: &crate::mesh::Element| e.parent.map(|p| p as usize);
        let shot_total: Vec<[f64; 3]> = refined
            .elements
            .iter()
            .map(|e| parent(e).map_or([0.0; 3], |p| self.shot_total[p]))
            .collect();
        let unshot: Vec<[f64; 3]> = refined
            .elements
            .iter()
            .map(|e| parent(e).map_or(refined.exitance(e), |p| self.unshot[p]))
            .collect();
        let near = NearField::for_method(refined, ff);
        let shot_means: Vec<[f64; 3]> = refined
            .patches
            .iter()
            .map(|p| {
                let area = refined.patch_area(p);
                let mut m = [0.0; 3];
                for e in p.elements.clone() {
                    for c in 0..3 {
                        m[c] +=
                            shot_total[e as usize][c] * refined.elements[e as usize].area / area;
                    }
                }
                m
            })
            .collect();
        let (radiosity, irradiance): (Vec<[f64; 3]>, Vec<[f64; 3]>) = refined
            .elements
            .par_iter()
            .enumerate()
            .map(|(i, e)| match parent(e) {
                Some(p) if old.elements[p].depth == e.depth => {
                    (self.radiosity[p], self.irradiance[p])
                }
                _ => {
                    let mut h = [0.0; 3];
                    for (q, s) in shot_means.iter().enumerate() {
                        if near.is_near(i, q) {
                            for src in refined.patches[q].elements.clone() {
                                let f = ff.element_pair(i, src as usize).unwrap_or(0.0);
                                for c in 0..3 {
                                    h[c] += f * shot_total[src as usize][c];
                                }
                            }
                        } else {
                            let f = ff.pair(i, q);
                            for c in 0..3 {
                                h[c] += f * s[c];
                            }
                        }
                    }
                    let (rho, ex) = (refined.reflectance(e), refined.exitance(e));
                    (std::array::from_fn(|c| ex[c] + rho[c] * h[c]), h)
                }
            })
            .unzip();
        self.radiosity = radiosity;
        self.irradiance = irradiance;
        self.unshot = unshot;
        self.shot_total = shot_total;
        self.near = Some(near);
        self.cache.clear();
        self.cache_bytes = 0;
        self.patch_power = self.patch_powers(refined);
    }

    /// The current (partial) solution.
    pub fn solution(&self, seconds: f64) -> Solution {
        Solution {
            radiosity: self.radiosity.clone(),
            irradiance: self.irradiance.clone(),
            unshot: self.unshot.clone(),
            escaped_power: self.escaped,
            stats: SolveStats {
                solver: SolverKind::Progressive,
                iterations: self.shots,
                residual: self.unshot_fraction(),
                seconds,
                form_factor_seconds: self.form_factor_seconds,
            },
        }
    }
}

/// Runs progressive refinement to the tolerance or the shot cap.
pub fn solve(
    mesh: &Mesh,
    ff: &dyn FormFactors,
    options: &SolveOptions,
    progress: &dyn Progress,
) -> Result<Solution, SolveError> {
    let start = Instant::now();
    let mut state = Progressive::new(mesh, options);
    let cap = options
        .max_shots
        .unwrap_or_else(|| 100 * mesh.patches.len().max(1));
    progress.start("progressive", cap as u64);
    while state.shots() < cap && state.unshot_fraction() > options.tolerance {
        if !state.shoot(mesh, ff) {
            break;
        }
        progress.inc(1);
        if state.shots() % 16 == 0 {
            progress.message(&format!("unshot {:.2e}", state.unshot_fraction()));
        }
    }
    progress.finish();
    Ok(state.solution(start.elapsed().as_secs_f64()))
}
