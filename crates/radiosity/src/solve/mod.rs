//! Solution of the radiosity system B = E + ρ K(B), per RGB channel, on a coupling.
//!
//! The source term is each element's emitted exitance plus the reflected first shot from
//! the light sources, E_i + ρ_i · direct_i ([`Mesh::source`]); every solver and helper here
//! uses it, so point, spot and goniometric lights reach every solver. The solution's
//! irradiance H includes the direct part.
//!
//! The coupling ([`crate::coupling`]) is the operator H = K(B) (irradiance from radiosity);
//! the solvers here only ask it to gather, sweep or shoot:
//! - [`direct`]: Gaussian elimination — a dense LU (faer) of the dense coupling's patch-level
//!   system, then iterative refinement on the element system to machine precision;
//! - [`jacobi`]: B⁽ᵏ⁺¹⁾ = E + ρ K(B⁽ᵏ⁾);
//! - [`gauss_seidel`]: the same, each element updated in place from the newest values;
//! - [`progressive`]: progressive refinement (Cohen, Chen, Wallace & Greenberg 1988),
//!   shooting the source with the largest unshot power, with overshooting and the ambient term.
//!
//! Every solver reports each step (iteration or shot, the converging quantity, elapsed time)
//! to an [`Observer`], which may stop it: the command line's progress display, the solver
//! comparison and the progressive image sequences all watch the same loops.
//!
//! Units: radiosity B, exitance E and irradiance H in W·m⁻²; power in W.

pub mod direct;
pub mod gauss_seidel;
pub mod hierarchical;
pub mod jacobi;
pub mod observer;
pub mod progressive;

pub use observer::{Flow, NoObserver, Observer, Step, StepKind};

use crate::coupling::Coupling;
use crate::mesh::Mesh;
use std::fmt;
use std::str::FromStr;

/// The solvers, by the names used on the command line and in scene files.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum SolverKind {
    /// Dense LU factorisation (Gaussian elimination with partial pivoting, faer).
    Direct,
    /// Jacobi iteration B ← E + M B.
    Jacobi,
    /// Gauss–Seidel iteration, updating in place.
    GaussSeidel,
    /// Progressive refinement / Southwell relaxation (Cohen, Chen, Wallace & Greenberg 1988).
    Progressive,
    /// Hierarchical radiosity with clustering (Hanrahan, Salzman & Aupperle 1991; Sillion
    /// 1995): multi-level links refined by an error oracle, Jacobi with push–pull. The
    /// default: on the Cornell box it matches progressive refinement's accuracy against
    /// Mitsuba in about a third of the time, and it scales to scenes the classic solvers
    /// cannot hold.
    #[default]
    Hierarchical,
}

impl SolverKind {
    /// Every solver.
    pub const ALL: &'static [SolverKind] = &[
        SolverKind::Direct,
        SolverKind::Jacobi,
        SolverKind::GaussSeidel,
        SolverKind::Progressive,
        SolverKind::Hierarchical,
    ];

    /// The solver's name on the command line and in scene files.
    pub fn name(self) -> &'static str {
        match self {
            SolverKind::Direct => "direct",
            SolverKind::Jacobi => "jacobi",
            SolverKind::GaussSeidel => "gauss-seidel",
            SolverKind::Progressive => "progressive",
            SolverKind::Hierarchical => "hierarchical",
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
        Self::ALL
            .iter()
            .copied()
            .find(|k| k.name() == s)
            .ok_or_else(|| {
                let names: Vec<_> = Self::ALL.iter().map(|k| k.name()).collect();
                format!(
                    "unknown solver '{s}' (expected one of: {})",
                    names.join(", ")
                )
            })
    }
}

/// Solver settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolveOptions {
    /// The solver.
    pub solver: SolverKind,
    /// Stop when the estimated remaining error of every element relative to its own
    /// radiosity (floored at 5 % of the mean) is at most this: from the change per step
    /// for Jacobi and Gauss–Seidel ([`ErrorEstimate`]), from the unshot power's ambient
    /// term for progressive refinement ([`progressive`]).
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
            solver: SolverKind::default(),
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
    /// The solve would not fit in memory.
    OutOfMemory {
        /// The solver.
        solver: SolverKind,
        /// MiB it would need.
        needed_mib: u64,
        /// MiB that may be used.
        limit_mib: u64,
        /// Elements in the mesh.
        elements: usize,
        /// Patches in the mesh.
        patches: usize,
    },
    #[error("the {solver} solver needs the dense element × patch coupling, not '{coupling}'")]
    /// The solver needs the dense coupling.
    NeedsDense {
        /// The solver.
        solver: SolverKind,
        /// The coupling given.
        coupling: &'static str,
    },
    #[error("tolerance must be positive and finite, got {0}")]
    /// The tolerance is not a positive finite number.
    BadTolerance(f64),
    #[error(
        "the solution diverged (non-finite radiosity); check that every reflectance is below 1"
    )]
    /// The radiosity became non-finite.
    Diverged,
}

/// What a solver reached.
#[derive(Debug, Clone, PartialEq)]
pub struct SolveStats {
    /// The solver.
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
    /// Irradiance H per element, W·m⁻²: from the other surfaces, K(B), plus straight from
    /// the light sources ([`Mesh::direct`]).
    pub irradiance: Vec<[f64; 3]>,
    /// Unshot radiosity per element, W·m⁻² (zero for the matrix solvers).
    pub unshot: Vec<[f64; 3]>,
    /// Power leaving the scene (hitting no surface), W.
    pub escaped_power: [f64; 3],
    /// How the solver got there.
    pub stats: SolveStats,
}

impl Solution {
    /// Emitted power per channel, W: Σ E_e A_e of the emitting surfaces plus the flux of the
    /// light sources ([`Mesh::light_power`]).
    pub fn emitted_power(mesh: &Mesh) -> [f64; 3] {
        let mut p = mesh.light_power;
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

    /// The ambient term of Cohen et al. (1988) per channel, W·m⁻² (see [`ambient`]).
    pub fn ambient(&self, mesh: &Mesh) -> [f64; 3] {
        ambient(mesh, &self.unshot)
    }

    /// Radiosity for display: B_e, plus ρ_e · ambient when `ambient` is set.
    pub fn display_radiosity(&self, mesh: &Mesh, ambient: bool) -> Vec<[f64; 3]> {
        display_radiosity(mesh, &self.radiosity, &self.unshot, ambient)
    }
}

/// The ambient term of Cohen et al. (1988) per channel, W·m⁻²:
/// ambient = R · Σ u_e A_e / Σ A_e with R = 1 / (1 − ρ_avg), ρ_avg the area-weighted
/// mean reflectance and u the unshot radiosity. Displayed radiosity is B_e + ρ_e · ambient.
pub fn ambient(mesh: &Mesh, unshot: &[[f64; 3]]) -> [f64; 3] {
    let total_area: f64 = mesh.elements.iter().map(|e| e.area).sum();
    let mut power = [0.0; 3];
    let mut rho_avg = [0.0; 3];
    for (e, u) in mesh.elements.iter().zip(unshot) {
        let r = mesh.reflectance(e);
        for c in 0..3 {
            power[c] += u[c] * e.area;
            rho_avg[c] += r[c] * e.area / total_area;
        }
    }
    std::array::from_fn(|c| power[c] / total_area / (1.0 - rho_avg[c]))
}

/// Radiosity for display: B_e, plus ρ_e · [`ambient`] when `with_ambient` is set.
pub fn display_radiosity(
    mesh: &Mesh,
    radiosity: &[[f64; 3]],
    unshot: &[[f64; 3]],
    with_ambient: bool,
) -> Vec<[f64; 3]> {
    if !with_ambient {
        return radiosity.to_vec();
    }
    let amb = ambient(mesh, unshot);
    mesh.elements
        .iter()
        .zip(radiosity)
        .map(|(e, b)| {
            let r = mesh.reflectance(e);
            std::array::from_fn(|c| b[c] + r[c] * amb[c])
        })
        .collect()
}

/// Solves the coupling's radiosity system with the chosen solver, reporting every step to
/// `observer`.
pub fn solve(
    coupling: &dyn Coupling,
    options: &SolveOptions,
    observer: &mut dyn Observer,
) -> Result<Solution, SolveError> {
    if !(options.tolerance.is_finite() && options.tolerance > 0.0) {
        return Err(SolveError::BadTolerance(options.tolerance));
    }
    let solution = match options.solver {
        SolverKind::Progressive => progressive::solve(coupling, options, observer),
        SolverKind::Direct => direct::solve(coupling, options, observer)?,
        SolverKind::Jacobi => jacobi::solve(coupling, options, observer),
        SolverKind::GaussSeidel => gauss_seidel::solve(coupling, options, observer),
        // The hierarchical solver refines its own coupling between sweeps; on a fixed
        // coupling it is Jacobi with push–pull.
        SolverKind::Hierarchical => jacobi::solve(coupling, options, observer),
    };
    check_finite(&solution)?;
    Ok(solution)
}

/// A non-finite radiosity means the system had no bounded solution (ρ ≥ 1 somewhere) or
/// the input overflowed (an absurd emission).
pub fn check_finite(solution: &Solution) -> Result<(), SolveError> {
    if solution.radiosity.iter().flatten().all(|b| b.is_finite()) {
        Ok(())
    } else {
        Err(SolveError::Diverged)
    }
}

/// The source term per element, W·m⁻²: emitted exitance plus the reflected first shot,
/// E + ρ · direct ([`Mesh::source`]); the emitted exitance alone when the scene has no
/// light sources.
pub fn exitance(mesh: &Mesh) -> Vec<[f64; 3]> {
    (0..mesh.elements.len()).map(|i| mesh.source(i)).collect()
}

/// source + ρ H per element (H the irradiance from the other surfaces, K(B)).
pub fn reflect(mesh: &Mesh, irradiance: &[[f64; 3]]) -> Vec<[f64; 3]> {
    mesh.elements
        .iter()
        .zip(irradiance)
        .enumerate()
        .map(|(i, (e, h))| {
            let (rho, ex) = (mesh.reflectance(e), mesh.source(i));
            std::array::from_fn(|c| ex[c] + rho[c] * h[c])
        })
        .collect()
}

/// Area-weighted relative difference ‖a − b‖ / ‖E‖ over elements and channels (‖E‖ from
/// the source term, [`exitance`]; the absolute norm when nothing emits).
pub fn relative_difference(mesh: &Mesh, a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for (i, ((e, x), y)) in mesh.elements.iter().zip(a).zip(b).enumerate() {
        let ex = mesh.source(i);
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

/// The loop of the stationary iterations (Jacobi, Gauss–Seidel): from B = E, apply `step`
/// (which updates B in place) until the estimated remaining error ([`ErrorEstimate`]) is at
/// most the tolerance, the iteration cap is reached, or the observer stops it; every step
/// reported.
pub fn iterate(
    coupling: &dyn Coupling,
    solver: SolverKind,
    options: &SolveOptions,
    observer: &mut dyn Observer,
    step: &mut dyn FnMut(&mut Vec<[f64; 3]>),
) -> Solution {
    iterate_from(
        coupling,
        exitance(coupling.mesh()),
        solver,
        options,
        observer,
        step,
    )
}

/// [`iterate`] from the radiosities `start`.
pub fn iterate_from(
    coupling: &dyn Coupling,
    start: Vec<[f64; 3]>,
    solver: SolverKind,
    options: &SolveOptions,
    observer: &mut dyn Observer,
    step: &mut dyn FnMut(&mut Vec<[f64; 3]>),
) -> Solution {
    let mesh = coupling.mesh();
    let mut clock = observer::SolverClock::start();
    let mut b = start;
    let mut estimate = ErrorEstimate::new(mesh);
    let mut residual = f64::INFINITY;
    let mut iterations = 0;
    let mut kind = StepKind::Start;
    loop {
        let flow = clock.report(observer, |elapsed| Step {
            solver,
            kind,
            index: iterations,
            residual,
            tolerance: options.tolerance,
            elapsed,
            mesh,
            radiosity: &b,
            unshot: None,
        });
        if flow == Flow::Stop
            || residual <= options.tolerance
            || iterations >= options.max_iterations
        {
            break;
        }
        let before = b.clone();
        step(&mut b);
        residual = estimate.update(mesh, &before, &b);
        iterations += 1;
        kind = StepKind::Iteration;
    }
    let seconds = clock.seconds();
    solution_from(
        coupling,
        b,
        SolveStats {
            solver,
            iterations,
            residual,
            seconds,
            form_factor_seconds: coupling.form_factor_seconds(),
        },
    )
}

/// The stopping rule of the stationary iterations: an estimate of the largest remaining
/// error of any element relative to its own radiosity.
///
/// A convergent stationary iteration contracts the error by about q per step, so after a
/// step that changed B by δ the remaining error is about δ·q/(1 − q) (a geometric tail);
/// q is measured as the larger of the last two ratios of successive changes (before three
/// changes are known, q is taken as 0.9, a bright enclosure's): the first step from a
/// starting guess can change B far more than the iteration's contraction explains (the
/// hierarchical solver restarts from the previous stage's radiosities on a refined mesh;
/// one ratio of 0.02 after such a step stopped a glTF room with its books off by 1.2e-4).
/// The change is measured element by element, relative to max(B_e, β·B̄) with B̄ the
/// area-weighted mean radiosity and β = 0.05, so that every surface that matters —
/// including one lit only by reflected light, which converges last — is within the
/// tolerance, while black or unlit elements do not hold the solve up.
///
/// The books must balance too: the energy balance error of the solution, emitted − absorbed
/// − escaped = Σ_e A_e (E_e + ρ_e H_e − B_e) per channel, is the power the next step would
/// still add, relative to the emitted power Φ. Every element's change has the same sign
/// (the iteration rises monotonically from B = E), so those errors add up: in a bright room
/// Σ A B is ten or more times Φ, and elements each within 1e-3 left the balance off by
/// 1.2e-3 (a triangulated glTF room, hierarchical solver). The same geometric tail of the
/// power change, Σ_e A_e |ΔB_e| / Φ per channel, must therefore be within
/// [`BALANCE_SHARE`] of the tolerance.
#[derive(Debug, Clone)]
pub struct ErrorEstimate {
    /// The last two changes, older first.
    previous: [Option<f64>; 2],
    /// The emitted power Φ per channel, W: the balance's scale.
    emitted: [f64; 3],
}

/// The energy balance error the stopping rule allows, as a fraction of the tolerance: with
/// the default tolerance 1e-3, the books balance to 1e-4 of the emitted power.
const BALANCE_SHARE: f64 = 0.1;

/// Fraction of the mean radiosity below which an element's relative change is measured
/// against that floor instead of its own radiosity.
const DARK_FLOOR: f64 = 0.05;

impl ErrorEstimate {
    /// The estimate for iterations on `mesh` (its emitted power sets the balance's scale).
    pub fn new(mesh: &Mesh) -> Self {
        Self {
            previous: [None; 2],
            emitted: Solution::emitted_power(mesh),
        }
    }

    /// Records a step from `before` to `after` and returns the estimated remaining error:
    /// the larger of the elements' relative error and the balance error over
    /// [`BALANCE_SHARE`].
    pub fn update(&mut self, mesh: &Mesh, before: &[[f64; 3]], after: &[[f64; 3]]) -> f64 {
        let (mut sum, mut area) = (0.0, 0.0);
        for (e, b) in mesh.elements.iter().zip(after) {
            sum += e.area * b[0].max(b[1]).max(b[2]);
            area += e.area;
        }
        let floor = if area > 0.0 {
            DARK_FLOOR * sum / area
        } else {
            0.0
        };
        let mut change: f64 = 0.0;
        let mut power = [0.0; 3];
        for ((e, x), y) in mesh.elements.iter().zip(before).zip(after) {
            let scale = y[0].max(y[1]).max(y[2]).max(floor);
            for c in 0..3 {
                let step = (y[c] - x[c]).abs();
                if scale > 0.0 {
                    change = change.max(step / scale);
                }
                power[c] += e.area * step;
            }
        }
        let balance = (0..3)
            .filter(|&c| self.emitted[c] > 0.0)
            .map(|c| power[c] / self.emitted[c])
            .fold(0.0, f64::max);
        let change = change.max(balance / BALANCE_SHARE);
        let q = match self.previous {
            [Some(older), Some(last)] if older > 0.0 && last > 0.0 => {
                (change / last).max(last / older).clamp(0.0, 0.99)
            }
            _ => 0.9,
        };
        self.previous = [self.previous[1], Some(change)];
        change * q / (1.0 - q)
    }
}

/// The relative residual ‖E + ρK(B) − B‖ / ‖E‖ of radiosities `b` (one gather).
pub fn residual(coupling: &dyn Coupling, b: &[[f64; 3]]) -> f64 {
    let mesh = coupling.mesh();
    let next = reflect(mesh, &coupling.gather(b));
    relative_difference(mesh, b, &next)
}

/// Irradiance `h` with negative values raised to zero. The classic couplings' K has no
/// negative entries, so for them this changes nothing; the hierarchical coupling's links
/// transfer affine functions fitted over their receivers, and a fit to a form factor that
/// falls to zero across a receiver can extrapolate below zero at its far corners (leaves of
/// `scenes/mgf_room_lamp.mgf` gathered down to −1.3e-2 W·m⁻² at `--elements 300`). Limiting
/// the fits' slopes instead cost accuracy where nothing was negative (the Cornell box's
/// worst polygon 1.9 % → 2.7 % against Mitsuba at ε = 0.01), and clamping inside the gather
/// would make the coupling non-linear (its closure needs the transpose), so the solver
/// clamps what it reflects and reports.
pub fn non_negative(mut h: Vec<[f64; 3]>) -> Vec<[f64; 3]> {
    for v in h.iter_mut().flatten() {
        *v = v.max(0.0);
    }
    h
}

/// The complete solution for element radiosities `b`: H = max(K(B), 0) + direct, and the
/// escaped power Σ_e B_e A_e + Φ_lights − Σ_e H_e A_e (what leaves all surfaces and lights
/// minus what lands on surfaces).
pub fn solution_from(coupling: &dyn Coupling, b: Vec<[f64; 3]>, stats: SolveStats) -> Solution {
    let mesh = coupling.mesh();
    let mut irradiance = non_negative(coupling.gather(&b));
    let mut escaped = mesh.light_power;
    for (i, ((e, bb), h)) in mesh
        .elements
        .iter()
        .zip(&b)
        .zip(&mut irradiance)
        .enumerate()
    {
        let d = mesh.direct(i);
        for c in 0..3 {
            h[c] += d[c];
            escaped[c] += (bb[c] - h[c]) * e.area;
        }
    }
    Solution {
        radiosity: b,
        irradiance,
        unshot: vec![[0.0; 3]; mesh.elements.len()],
        escaped_power: escaped,
        stats,
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
