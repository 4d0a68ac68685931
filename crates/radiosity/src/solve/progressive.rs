//! Progressive refinement (Cohen, Chen, Wallace & Greenberg 1988), i.e. Southwell
//! relaxation: repeatedly pick the patch with the largest unshot power U_p·A_p and shoot
//! it to every element,
//!
//!   ΔB_e = ρ_e F_{e→p} ω U_p,   U_q += Σ_{e∈q} A_e ΔB_e / A_q,   U_p ← U_p − ω U_p (+ own gains),
//!
//! computing the column F_{·→p} on the fly (no n² storage; columns are cached while they fit
//! in the memory limit). ω = 1 is plain shooting; ω > 1 overshoots (over-relaxation),
//! leaving a negative unshot radiosity that later shots correct. Stops when the unshot power
//! is below `tolerance` × emitted power, or after `max_shots`.

use super::{Solution, SolveError, SolveOptions, SolveStats, SolverKind};
use crate::formfactor::FormFactors;
use crate::mesh::Mesh;
use crate::progress::Progress;
use std::collections::HashMap;
use std::time::Instant;

/// The state of a progressive solution, which can be advanced shot by shot (for image
/// sequences) and turned into a [`Solution`] at any point.
pub struct Progressive {
    overshoot: f64,
    radiosity: Vec<[f64; 3]>,
    irradiance: Vec<[f64; 3]>,
    unshot: Vec<[f64; 3]>,
    /// Total radiosity each patch has shot so far, W·m⁻² (to gather new elements from).
    shot_total: Vec<[f64; 3]>,
    patch_area: Vec<f64>,
    escaped: [f64; 3],
    emitted: f64,
    shots: usize,
    cache: HashMap<usize, Vec<f32>>,
    cache_limit: usize,
    column: Vec<f32>,
    form_factor_seconds: f64,
}

impl Progressive {
    /// Starts with B = E on every element and U_p = E_p on every patch.
    pub fn new(mesh: &Mesh, options: &SolveOptions) -> Self {
        let radiosity: Vec<[f64; 3]> = mesh.elements.iter().map(|e| mesh.exitance(e)).collect();
        let patch_area: Vec<f64> = mesh.patches.iter().map(|p| mesh.patch_area(p)).collect();
        let unshot = mesh
            .patches
            .iter()
            .zip(&patch_area)
            .map(|(p, a)| {
                let mut u = [0.0; 3];
                for e in p.elements.clone() {
                    let el = &mesh.elements[e as usize];
                    let ex = mesh.exitance(el);
                    for c in 0..3 {
                        u[c] += ex[c] * el.area / a;
                    }
                }
                u
            })
            .collect();
        let emitted = Solution::emitted_power(mesh).iter().sum();
        let column_bytes = mesh.elements.len().max(1) * 4;
        Self {
            shot_total: vec![[0.0; 3]; mesh.patches.len()],
            overshoot: options.overshoot,
            irradiance: vec![[0.0; 3]; mesh.elements.len()],
            radiosity,
            unshot,
            patch_area,
            escaped: [0.0; 3],
            emitted,
            shots: 0,
            cache: HashMap::new(),
            cache_limit: (options.memory_limit as usize / 2) / column_bytes,
            column: vec![0.0; mesh.elements.len()],
            form_factor_seconds: 0.0,
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
        let u: f64 = self
            .unshot
            .iter()
            .zip(&self.patch_area)
            .map(|(u, a)| (u[0].abs() + u[1].abs() + u[2].abs()) * a)
            .sum();
        u / self.emitted
    }

    /// Shoots the patch with the largest unshot power; returns false when nothing is left.
    pub fn shoot(&mut self, mesh: &Mesh, ff: &dyn FormFactors) -> bool {
        let Some((p, power)) = self
            .unshot
            .iter()
            .zip(&self.patch_area)
            .map(|(u, a)| (u[0].abs() + u[1].abs() + u[2].abs()) * a)
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(&b.1))
        else {
            return false;
        };
        if power <= 0.0 {
            return false;
        }
        let started = Instant::now();
        let column: &[f32] = if let Some(c) = self.cache.get(&p) {
            c
        } else {
            ff.column(p, &mut self.column);
            if self.cache.len() < self.cache_limit {
                self.cache.insert(p, self.column.clone());
                &self.cache[&p]
            } else {
                &self.column
            }
        };
        self.form_factor_seconds += started.elapsed().as_secs_f64();
        let shot: [f64; 3] = std::array::from_fn(|c| self.overshoot * self.unshot[p][c]);
        for c in 0..3 {
            self.unshot[p][c] -= shot[c];
            self.shot_total[p][c] += shot[c];
        }
        let mut landed = 0.0;
        for (e, el) in mesh.elements.iter().enumerate() {
            let f = column[e] as f64;
            if f == 0.0 {
                continue;
            }
            landed += f * el.area;
            let rho = mesh.reflectance(el);
            let q = el.patch.0 as usize;
            let aq = self.patch_area[q];
            for c in 0..3 {
                let dh = f * shot[c];
                let db = rho[c] * dh;
                self.irradiance[e][c] += dh;
                self.radiosity[e][c] += db;
                self.unshot[q][c] += db * el.area / aq;
            }
        }
        let ap = self.patch_area[p];
        for c in 0..3 {
            self.escaped[c] += shot[c] * (ap - landed);
        }
        self.shots += 1;
        true
    }

    /// Moves the state onto a refined mesh (same patches; see [`crate::refine`]): elements
    /// that were not split keep their values, new children gather everything shot so far,
    /// H_c = Σ_p F_{c→p} S_p and B_c = E_c + ρ_c H_c, with `ff` built over `refined`.
    pub fn refine(&mut self, old: &Mesh, refined: &Mesh, ff: &dyn FormFactors) {
        use rayon::prelude::*;
        let shot = &self.shot_total;
        let (radiosity, irradiance): (Vec<[f64; 3]>, Vec<[f64; 3]>) = refined
            .elements
            .par_iter()
            .enumerate()
            .map_init(
                || vec![0.0f32; refined.patches.len()],
                |row, (i, e)| match e.parent {
                    Some(parent) if old.elements[parent as usize].depth == e.depth => (
                        self.radiosity[parent as usize],
                        self.irradiance[parent as usize],
                    ),
                    _ => {
                        ff.row(i, row);
                        let mut h = [0.0; 3];
                        for (f, s) in row.iter().zip(shot) {
                            for c in 0..3 {
                                h[c] += *f as f64 * s[c];
                            }
                        }
                        let (rho, ex) = (refined.reflectance(e), refined.exitance(e));
                        (std::array::from_fn(|c| ex[c] + rho[c] * h[c]), h)
                    }
                },
            )
            .unzip();
        self.radiosity = radiosity;
        self.irradiance = irradiance;
        self.column = vec![0.0; refined.elements.len()];
        self.cache.clear();
        self.cache_limit = self.cache_limit * old.elements.len().max(1) / refined.elements.len().max(1);
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
