//! Solution of the radiosity system (I − ρF) B = E, per RGB channel.
//!
//! Unknowns live on two levels (substructuring, Cohen et al. 1986): elements gather from
//! patches, B_e = E_e + ρ_e Σ_p F_{e→p} B_p, and a patch's radiosity is the area average of
//! its elements, B_p = Σ_{e∈p} A_e B_e / A_p. Substituting gives the patch system
//!
//!   B_p = E_p + Σ_q M_pq B_q,   M_pq = Σ_{e∈p} (A_e / A_p) ρ_e F_{e→q},
//!
//! Where a patch is close to an element its radiosity is not uniform enough to be gathered
//! at its mean, so near pairs link element to element instead ([`crate::formfactor::NearField`]).
//! The unknowns are then the element radiosities of the two-level system
//!
//!   B_e = E_e + ρ_e H_e,   H_e = Σ_{far q} F_{e→q} B_q + Σ_{near e'} F_{e→e'} B_e'
//!
//! ([`Transport`]). [`jacobi`] and [`gauss_seidel`] iterate it; [`direct`] factorises the
//! patch-level system (near links summed back to their patches) by LU and removes the small
//! near-field remainder by iterative refinement with the same factors; [`progressive`]
//! refinement shoots patches' unshot radiosity (element by element to near receivers).
//! With one element per patch it is the plain element system.
//!
//! Units: radiosity B, exitance E and irradiance H in W·m⁻²; power in W.

pub mod direct;
pub mod gauss_seidel;
pub mod jacobi;
pub mod progressive;

use crate::formfactor::{CouplingMatrix, FormFactors};
use crate::mesh::Mesh;
use crate::progress::Progress;
use rayon::prelude::*;
use std::fmt;
use std::str::FromStr;

/// The solvers, by the names used on the command line and in scene files.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SolverKind {
    /// Dense LU factorisation (Gaussian elimination with partial pivoting, faer).
    Direct,
    /// Jacobi iteration B ← E + M B.
    Jacobi,
    /// Gauss–Seidel iteration, updating in place.
    GaussSeidel,
    /// Progressive refinement / Southwell relaxation (Cohen, Chen, Wallace & Greenberg 1988).
    #[default]
    Progressive,
}

impl SolverKind {
    pub const ALL: &'static [SolverKind] = &[
        SolverKind::Direct,
        SolverKind::Jacobi,
        SolverKind::GaussSeidel,
        SolverKind::Progressive,
    ];

    pub fn name(self) -> &'static str {
        match self {
            SolverKind::Direct => "direct",
            SolverKind::Jacobi => "jacobi",
            SolverKind::GaussSeidel => "gauss-seidel",
            SolverKind::Progressive => "progressive",
        }
    }
}

impl fmt::Display for SolverKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for SolverKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Self::ALL.iter().copied().find(|k| k.name() == s).ok_or_else(|| {
            format!("unknown solver '{s}' (expected one of: direct, jacobi, gauss-seidel, progressive)")
        })
    }
}

/// Solver settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolveOptions {
    pub solver: SolverKind,
    /// Iterative solvers: stop at this relative residual ‖(I − M)B − E‖₂ / ‖E‖₂.
    /// Progressive: stop when the unshot power is below this fraction of the emitted power.
    pub tolerance: f64,
    /// Iteration cap for Jacobi and Gauss–Seidel.
    pub max_iterations: usize,
    /// Shot cap for progressive refinement (`None`: until the tolerance is met, capped at
    /// 100 shots per patch).
    pub max_shots: Option<usize>,
    /// Progressive: shoot ω·(unshot) with ω > 1 (over-relaxation); 1 is plain shooting.
    pub overshoot: f64,
    /// Memory the solver may use, bytes (matrices and caches).
    pub memory_limit: u64,
}

impl Default for SolveOptions {
    fn default() -> Self {
        Self {
            solver: SolverKind::Progressive,
            tolerance: 1e-3,
            max_iterations: 10_000,
            max_shots: None,
            overshoot: 1.0,
            memory_limit: available_memory() / 2,
        }
    }
}

/// Why a solve could not run.
#[derive(Debug, thiserror::Error)]
pub enum SolveError {
    #[error(
        "the {solver} solver would need {needed_mib} MiB for {elements} elements × {patches} patches, \
         but only {limit_mib} MiB may be used; use fewer elements or patches (--elements, \
         --patch-subdivision) or the progressive solver"
    )]
    OutOfMemory {
        solver: SolverKind,
        needed_mib: u64,
        limit_mib: u64,
        elements: usize,
        patches: usize,
    },
    #[error("tolerance must be positive and finite, got {0}")]
    BadTolerance(f64),
    #[error(
        "the solution diverged (non-finite radiosity); check that every reflectance is below 1"
    )]
    Diverged,
}

/// What a solver reached.
#[derive(Debug, Clone, PartialEq)]
pub struct SolveStats {
    pub solver: SolverKind,
    /// Iterations (Jacobi, Gauss–Seidel), shots (progressive) or 1 (direct).
    pub iterations: usize,
    /// Relative residual (matrix solvers) or unshot power fraction (progressive).
    pub residual: f64,
    /// Wall-clock seconds for the solve, form factors included.
    pub seconds: f64,
    /// Of which computing form factors.
    pub form_factor_seconds: f64,
}

/// The result: radiosity and irradiance per element.
#[derive(Debug, Clone)]
pub struct Solution {
    /// Radiosity B per element (emission included), W·m⁻².
    pub radiosity: Vec<[f64; 3]>,
    /// Irradiance H per element, W·m⁻².
    pub irradiance: Vec<[f64; 3]>,
    /// Unshot radiosity per element, W·m⁻² (zero for the matrix solvers).
    pub unshot: Vec<[f64; 3]>,
    /// Power leaving the scene (hitting no surface), W.
    pub escaped_power: [f64; 3],
    pub stats: SolveStats,
}

impl Solution {
    /// Emitted power Σ E_e A_e per channel, W.
    pub fn emitted_power(mesh: &Mesh) -> [f64; 3] {
        let mut p = [0.0; 3];
        for e in &mesh.elements {
            let ex = mesh.exitance(e);
            for c in 0..3 {
                p[c] += ex[c] * e.area;
            }
        }
        p
    }

    /// Absorbed power Σ (1 − ρ_e) H_e A_e per channel, W.
    pub fn absorbed_power(&self, mesh: &Mesh) -> [f64; 3] {
        let mut p = [0.0; 3];
        for (e, h) in mesh.elements.iter().zip(&self.irradiance) {
            let rho = mesh.reflectance(e);
            for c in 0..3 {
                p[c] += (1.0 - rho[c]) * h[c] * e.area;
            }
        }
        p
    }

    /// Unshot power Σ u_e A_e per channel, W (energy not yet distributed).
    pub fn unshot_power(&self, mesh: &Mesh) -> [f64; 3] {
        let mut p = [0.0; 3];
        for (e, u) in mesh.elements.iter().zip(&self.unshot) {
            for c in 0..3 {
                p[c] += u[c] * e.area;
            }
        }
        p
    }

    /// The ambient term of Cohen et al. (1988) per channel, W·m⁻²:
    /// ambient = R · Σ u_e A_e / Σ A_e with R = 1 / (1 − ρ_avg), ρ_avg the area-weighted
    /// mean reflectance. Displayed radiosity is B_e + ρ_e · ambient.
    pub fn ambient(&self, mesh: &Mesh) -> [f64; 3] {
        let total_area: f64 = mesh.elements.iter().map(|e| e.area).sum();
        let unshot = self.unshot_power(mesh);
        let mut rho_avg = [0.0; 3];
        for e in &mesh.elements {
            let r = mesh.reflectance(e);
            for c in 0..3 {
                rho_avg[c] += r[c] * e.area / total_area;
            }
        }
        std::array::from_fn(|c| unshot[c] / total_area / (1.0 - rho_avg[c]))
    }

    /// Radiosity for display: B_e, plus ρ_e · ambient when `ambient` is set.
    pub fn display_radiosity(&self, mesh: &Mesh, ambient: bool) -> Vec<[f64; 3]> {
        if !ambient {
            return self.radiosity.clone();
        }
        let amb = self.ambient(mesh);
        mesh.elements
            .iter()
            .zip(&self.radiosity)
            .map(|(e, b)| {
                let r = mesh.reflectance(e);
                std::array::from_fn(|c| b[c] + r[c] * amb[c])
            })
            .collect()
    }
}

/// Solves the mesh's radiosity system with the chosen solver and form factors.
pub fn solve(
    mesh: &Mesh,
    ff: &dyn FormFactors,
    options: &SolveOptions,
    progress: &dyn Progress,
) -> Result<Solution, SolveError> {
    if !(options.tolerance.is_finite() && options.tolerance > 0.0) {
        return Err(SolveError::BadTolerance(options.tolerance));
    }
    let solution = match options.solver {
        SolverKind::Progressive => progressive::solve(mesh, ff, options, progress)?,
        kind => {
            let (n, m) = (mesh.elements.len(), mesh.patches.len());
            let needed = CouplingMatrix::bytes_for(n, m)
                + match kind {
                    SolverKind::Direct => {
                        2 * 8 * (m as u128) * (m as u128) + 3 * 8 * (m as u128) * (m as u128)
                    }
                    _ => 0,
                };
            check_memory(kind, needed, options.memory_limit, n, m)?;
            let start = std::time::Instant::now();
            let k = CouplingMatrix::compute(ff, mesh, progress);
            let ff_seconds = start.elapsed().as_secs_f64();
            let transport = Transport::new(mesh, &k);
            let (b, iterations, residual) = match kind {
                SolverKind::Direct => direct::solve(&transport, options),
                SolverKind::Jacobi => jacobi::solve(&transport, options, progress),
                _ => gauss_seidel::solve(&transport, options, progress),
            };
            let mut sol = transport.solution(b);
            sol.stats = SolveStats {
                solver: kind,
                iterations,
                residual,
                seconds: start.elapsed().as_secs_f64(),
                form_factor_seconds: ff_seconds,
            };
            sol
        }
    };
    if solution.radiosity.iter().flatten().any(|b| !b.is_finite()) {
        return Err(SolveError::Diverged);
    }
    Ok(solution)
}

fn check_memory(
    kind: SolverKind,
    needed: u128,
    limit: u64,
    n: usize,
    m: usize,
) -> Result<(), SolveError> {
    if needed > limit as u128 {
        return Err(SolveError::OutOfMemory {
            solver: kind,
            needed_mib: (needed >> 20).min(u64::MAX as u128) as u64,
            limit_mib: limit >> 20,
            elements: n,
            patches: m,
        });
    }
    Ok(())
}

/// The two-level transport operator over a computed coupling: H = T(B).
pub struct Transport<'a> {
    pub mesh: &'a Mesh,
    pub coupling: &'a CouplingMatrix,
    patch_area: Vec<f64>,
}

impl<'a> Transport<'a> {
    pub fn new(mesh: &'a Mesh, coupling: &'a CouplingMatrix) -> Self {
        let patch_area = mesh.patches.iter().map(|p| mesh.patch_area(p)).collect();
        Self {
            mesh,
            coupling,
            patch_area,
        }
    }

    /// Emitted exitance E per element.
    pub fn exitance(&self) -> Vec<[f64; 3]> {
        self.mesh
            .elements
            .iter()
            .map(|e| self.mesh.exitance(e))
            .collect()
    }

    /// Area-weighted mean of per-element values over each patch.
    pub fn patch_means(&self, b: &[[f64; 3]]) -> Vec<[f64; 3]> {
        self.mesh
            .patches
            .iter()
            .zip(&self.patch_area)
            .map(|(p, a)| {
                let mut m = [0.0; 3];
                for e in p.elements.clone() {
                    let el = &self.mesh.elements[e as usize];
                    for c in 0..3 {
                        m[c] += b[e as usize][c] * el.area / a;
                    }
                }
                m
            })
            .collect()
    }

    /// H_e for one element given patch means `bp` and element values `b`.
    pub fn irradiance_at(&self, e: usize, bp: &[[f64; 3]], b: &[[f64; 3]]) -> [f64; 3] {
        let mut h = [0.0; 3];
        for (f, q) in self.coupling.row(e).iter().zip(bp) {
            let f = *f as f64;
            h[0] += f * q[0];
            h[1] += f * q[1];
            h[2] += f * q[2];
        }
        for &(s, f) in &self.coupling.near[e] {
            for c in 0..3 {
                h[c] += f as f64 * b[s as usize][c];
            }
        }
        h
    }

    /// H = T(B) for every element, in parallel.
    pub fn irradiance(&self, b: &[[f64; 3]]) -> Vec<[f64; 3]> {
        let bp = self.patch_means(b);
        (0..b.len())
            .into_par_iter()
            .map(|e| self.irradiance_at(e, &bp, b))
            .collect()
    }

    /// B' = E + ρ T(B).
    pub fn apply(&self, b: &[[f64; 3]]) -> Vec<[f64; 3]> {
        let h = self.irradiance(b);
        self.mesh
            .elements
            .iter()
            .zip(h)
            .map(|(e, h)| {
                let (rho, ex) = (self.mesh.reflectance(e), self.mesh.exitance(e));
                std::array::from_fn(|c| ex[c] + rho[c] * h[c])
            })
            .collect()
    }

    /// Area-weighted relative residual ‖E + ρT(B) − B‖ / ‖E‖ over elements and channels.
    pub fn residual(&self, b: &[[f64; 3]]) -> f64 {
        let next = self.apply(b);
        let (mut num, mut den) = (0.0, 0.0);
        for ((e, x), y) in self.mesh.elements.iter().zip(b).zip(&next) {
            let ex = self.mesh.exitance(e);
            for c in 0..3 {
                num += e.area * (y[c] - x[c]).powi(2);
                den += e.area * ex[c] * ex[c];
            }
        }
        if den > 0.0 {
            (num / den).sqrt()
        } else {
            num.sqrt()
        }
    }

    /// The solution for element radiosities `b`: H = T(B), and the escaped power
    /// Σ_e B_e A_e − Σ_e H_e A_e (what leaves all surfaces minus what lands on them).
    pub fn solution(&self, b: Vec<[f64; 3]>) -> Solution {
        let irradiance = self.irradiance(&b);
        let mut escaped = [0.0; 3];
        for ((e, bb), h) in self.mesh.elements.iter().zip(&b).zip(&irradiance) {
            for c in 0..3 {
                escaped[c] += (bb[c] - h[c]) * e.area;
            }
        }
        Solution {
            radiosity: b,
            irradiance,
            unshot: vec![[0.0; 3]; self.mesh.elements.len()],
            escaped_power: escaped,
            stats: SolveStats {
                solver: SolverKind::Direct,
                iterations: 0,
                residual: 0.0,
                seconds: 0.0,
                form_factor_seconds: 0.0,
            },
        }
    }

    /// The patch-level system with near links summed back to their patches:
    /// M_pq = Σ_{e∈p} (A_e / A_p) ρ_e F_{e→q}, per channel, row-major.
    pub fn patch_matrix(&self) -> [Vec<f64>; 3] {
        let m = self.mesh.patches.len();
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
                    let full = self.coupling.full_row(self.mesh, e as usize);
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
}

/// Memory available to this process in bytes (Linux `MemAvailable`; 8 GiB if unknown).
pub fn available_memory() -> u64 {
    std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("MemAvailable:"))
                .and_then(|l| l.split_whitespace().nth(1))
                .and_then(|kb| kb.parse::<u64>().ok())
        })
        .map(|kb| kb * 1024)
        .unwrap_or(8 << 30)
}
