//! Progressive refinement (Cohen, Chen, Wallace & Greenberg 1988), i.e. Southwell
//! relaxation: repeatedly pick the patch with the largest unshot power Σ_{e∈p} u_e·A_e and
//! shoot it to every element,
//!
//!   ΔH_e = F_{e→p} ω ū_p  (far),   ΔH_e = Σ_{e'∈p} F_{e→e'} ω u_e'  (near field),
//!   ΔB_e = ρ_e ΔH_e,   u_e += ΔB_e,   u_e' ← u_e' − ω u_e' for e' ∈ p,
//!
//! keeping the unshot radiosity u per element (so near receivers see where on the patch the
//! light is). The coupling delivers each shot ([`Coupling::shoot`]): the on-the-fly
//! [`crate::coupling::Columns`] computes columns as sources shoot and caches them while they
//! fit in the memory limit. ω = 1 is plain shooting; ω > 1 overshoots
//! (over-relaxation), leaving a negative unshot radiosity that later shots correct.
//! Light sources other than surfaces enter as the first shot: elements start with
//! B = u = E + ρ·direct ([`Mesh::source`]) and H = direct.
//!
//! Stopping rule: not the unshot power as a fraction of the emitted power, which lets a
//! surface lit only by reflected light (a ceiling over downlights) stop short — its
//! radiosity is a small part of the total, so an unshot fraction of 10⁻³ of the whole can
//! still be several 10⁻³ of it — but an estimate of every element's remaining error
//! relative to its own radiosity. The unshot power U, once shot and interreflected, raises
//! the mean irradiance by the ambient term of Cohen et al. (1988), U / (A_T (1 − ρ̄)), so
//! element e's radiosity still lacks about ρ_e times that; the solve stops when
//!
//!   max_e max_c ρ_{e,c} · ambient_c / max(B_e, β B̄) ≤ tolerance,
//!
//! with B_e the element's largest channel, B̄ the area-weighted mean and β = 0.05, the
//! floor the stationary solvers' [`super::ErrorEstimate`] uses, so that black or unlit
//! elements do not hold the solve up. Or after `max_shots`. The residual reported is the
//! unshot power fraction, and the tolerance reported with it ([`Step::tolerance`]) is the
//! unshot fraction at which the rule above is expected to stop the solve: the tolerance ×
//! unshot fraction / remaining error at the rule's latest evaluation (the two fall together
//! once the radiosities have settled), so that an observer extrapolating the residual to the
//! tolerance (a progress bar's ETA) aims where the solve really stops. Bookkeeping is exact: emitted = absorbed + escaped + unshot after
//! every shot.

use super::observer::SolverClock;
use super::{Flow, Observer, Solution, SolveOptions, SolveStats, SolverKind, Step, StepKind};
use crate::coupling::Coupling;
use crate::mesh::Mesh;

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
    /// Unshot power per source, Σ_c |u|·A summed over its elements, W.
    source_power: Vec<f64>,
    escaped: [f64; 3],
    emitted: f64,
    shots: usize,
    /// (unshot fraction, remaining error) when the stopping rule was last evaluated.
    last_check: Option<(f64, f64)>,
    clock: SolverClock,
}

impl Progressive {
    /// Starts with B = u = E + ρ·direct on every element of the coupling's mesh, H = direct
    /// (the first shot from the light sources, whose flux that misses every surface has
    /// escaped).
    pub fn new(coupling: &dyn Coupling, options: &SolveOptions) -> Self {
        let mesh = coupling.mesh();
        let radiosity = super::exitance(mesh);
        let emitted = Solution::emitted_power(mesh).iter().sum();
        let irradiance: Vec<[f64; 3]> = (0..mesh.elements.len()).map(|i| mesh.direct(i)).collect();
        let mut escaped = mesh.light_power;
        for (e, d) in mesh.elements.iter().zip(&irradiance) {
            for c in 0..3 {
                escaped[c] -= d[c] * e.area;
            }
        }
        let mut state = Self {
            overshoot: options.overshoot,
            irradiance,
            unshot: radiosity.clone(),
            shot_total: vec![[0.0; 3]; mesh.elements.len()],
            radiosity,
            source_power: Vec::new(),
            escaped,
            emitted,
            shots: 0,
            last_check: None,
            clock: SolverClock::start(),
        };
        state.source_power = state.source_powers(coupling);
        state.clock.pause();
        state
    }

    fn source_powers(&self, coupling: &dyn Coupling) -> Vec<f64> {
        let mesh = coupling.mesh();
        (0..coupling.sources())
            .map(|p| {
                let r = coupling.source_elements(p);
                let r = r.start as usize..r.end as usize;
                self.unshot[r.clone()]
                    .iter()
                    .zip(&mesh.elements[r])
                    .map(|(u, e)| (u[0].abs() + u[1].abs() + u[2].abs()) * e.area)
                    .sum()
            })
            .collect()
    }

    /// Shots taken so far.
    pub fn shots(&self) -> usize {
        self.shots
    }

    /// Radiosity per element now, W·m⁻².
    pub fn radiosity(&self) -> &[[f64; 3]] {
        &self.radiosity
    }

    /// Unshot power as a fraction of the emitted power (0 when nothing emits).
    pub fn unshot_fraction(&self) -> f64 {
        if self.emitted <= 0.0 {
            return 0.0;
        }
        self.source_power.iter().sum::<f64>() / self.emitted
    }

    /// The stopping rule's estimate of the largest remaining error of any element relative
    /// to its own radiosity (see the module docs): max_e max_c ρ_{e,c} ambient_c /
    /// max(B_e, β B̄), 0 when nothing is unshot.
    pub fn remaining_error(&self, mesh: &Mesh) -> f64 {
        let (mut area, mut mean, mut unshot, mut rho) = (0.0, 0.0, [0.0; 3], [0.0; 3]);
        for ((e, b), u) in mesh.elements.iter().zip(&self.radiosity).zip(&self.unshot) {
            let r = mesh.reflectance(e);
            area += e.area;
            mean += e.area * b[0].max(b[1]).max(b[2]);
            for c in 0..3 {
                unshot[c] += e.area * u[c].abs();
                rho[c] += e.area * r[c];
            }
        }
        if area <= 0.0 || unshot.iter().all(|&u| u == 0.0) {
            return 0.0;
        }
        let floor = super::DARK_FLOOR * mean / area;
        let ambient: [f64; 3] = std::array::from_fn(|c| unshot[c] / area / (1.0 - rho[c] / area));
        let mut worst: f64 = 0.0;
        for (e, b) in mesh.elements.iter().zip(&self.radiosity) {
            let scale = b[0].max(b[1]).max(b[2]).max(floor);
            if scale <= 0.0 {
                continue;
            }
            let r = mesh.reflectance(e);
            for c in 0..3 {
                worst = worst.max(r[c] * ambient[c] / scale);
            }
        }
        worst
    }

    /// Shoots the source with the largest unshot power; returns false when nothing is left.
    pub fn shoot(&mut self, coupling: &dyn Coupling) -> bool {
        let mesh = coupling.mesh();
        let Some((p, &power)) = self
            .source_power
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(b.1))
        else {
            return false;
        };
        if power <= 0.0 {
            return false;
        }
        // What source p shoots: ω·u per element.
        let sources = coupling.source_elements(p);
        let mut shot = Vec::with_capacity(sources.len());
        let mut shot_power = [0.0; 3];
        for s in sources.clone() {
            let a = mesh.elements[s as usize].area;
            let u: [f64; 3] = std::array::from_fn(|c| self.overshoot * self.unshot[s as usize][c]);
            for c in 0..3 {
                shot_power[c] += u[c] * a;
                self.unshot[s as usize][c] -= u[c];
                self.shot_total[s as usize][c] += u[c];
            }
            shot.push(u);
        }
        let mut landed = [0.0; 3];
        let Self {
            irradiance,
            radiosity,
            unshot,
            ..
        } = self;
        // Called once per receiving element per shot: index each array once.
        coupling.shoot(p, &shot, &mut |e, dh| {
            let el = &mesh.elements[e];
            let rho = mesh.reflectance(el);
            let (h, b, u) = (&mut irradiance[e], &mut radiosity[e], &mut unshot[e]);
            for c in 0..3 {
                let db = rho[c] * dh[c];
                landed[c] += dh[c] * el.area;
                h[c] += dh[c];
                b[c] += db;
                u[c] += db;
            }
        });
        for c in 0..3 {
            self.escaped[c] += shot_power[c] - landed[c];
        }
        // Unshot powers changed on p and on every receiving source.
        self.source_power = self.source_powers(coupling);
        self.shots += 1;
        true
    }

    /// Shoots until every element's estimated remaining error ([`Progressive::remaining_error`])
    /// is at most `tolerance`, `max_shots` shots were taken in all, nothing is left, or the
    /// observer stops it; every shot is reported. Returns whether it ran out of power to
    /// shoot.
    ///
    /// The stopping rule takes a pass over every element, as much as a shot's own
    /// bookkeeping, so it is evaluated at every k-th shot, k = elements / sources (1 to 16):
    /// the solve may take up to k − 1 shots more than the rule needs, never fewer.
    pub fn run(
        &mut self,
        coupling: &dyn Coupling,
        tolerance: f64,
        max_shots: usize,
        observer: &mut dyn Observer,
    ) -> bool {
        let mesh = coupling.mesh();
        self.clock.resume();
        let kind = if self.shots == 0 {
            StepKind::Start
        } else {
            StepKind::Shot
        };
        self.check(mesh);
        let mut flow = self.report(mesh, kind, tolerance, observer);
        let mut exhausted = false;
        // At fixed shot counts (multiples of k), so that a solve run in pieces (image
        // sequences) stops where one run does.
        let check_every = (mesh.elements.len() / coupling.sources().max(1)).clamp(1, 16);
        while flow == Flow::Continue && self.shots < max_shots {
            if self.shots % check_every == 0 && self.check(mesh) <= tolerance {
                break;
            }
            if !self.shoot(coupling) {
                exhausted = true;
                break;
            }
            flow = self.report(mesh, StepKind::Shot, tolerance, observer);
        }
        self.clock.pause();
        exhausted
    }

    /// Evaluates the stopping rule's [`Progressive::remaining_error`] and keeps it with the
    /// unshot fraction for [`Progressive::stopping_fraction`].
    fn check(&mut self, mesh: &Mesh) -> f64 {
        let error = self.remaining_error(mesh);
        self.last_check = Some((self.unshot_fraction(), error));
        error
    }

    /// The unshot fraction at which the stopping rule is expected to stop the solve for
    /// `tolerance`: r·tolerance/e with r and e the unshot fraction and the remaining error at
    /// the rule's latest evaluation (e is proportional to r through the ambient term, with a
    /// factor that settles as the radiosities do); `tolerance` itself before any evaluation
    /// or when nothing was left.
    pub fn stopping_fraction(&self, tolerance: f64) -> f64 {
        match self.last_check {
            Some((r, e)) if r > 0.0 && e > 0.0 && (r / e).is_finite() => tolerance * r / e,
            _ => tolerance,
        }
    }

    fn report(
        &mut self,
        mesh: &Mesh,
        kind: StepKind,
        tolerance: f64,
        observer: &mut dyn Observer,
    ) -> Flow {
        let residual = self.unshot_fraction();
        let tolerance = self.stopping_fraction(tolerance);
        let index = self.shots;
        let Self {
            clock,
            radiosity,
            unshot,
            ..
        } = self;
        clock.report(observer, |elapsed| Step {
            solver: SolverKind::Progressive,
            kind,
            index,
            residual,
            tolerance,
            elapsed,
            mesh,
            radiosity,
            unshot: Some(unshot),
        })
    }

    /// Moves the state onto a refined mesh (same patches; see [`crate::mesh::refine`]):
    /// elements that were not split keep their values; new children inherit their parent's
    /// unshot and shot radiosity and gather everything shot so far,
    /// H_c = K(s)_c with s the radiosity shot so far, B_c = E_c + ρ_c H_c, where `refined`
    /// couples the refined mesh.
    pub fn refine(&mut self, old: &Mesh, refined: &dyn Coupling) {
        let mesh = refined.mesh();
        let parent = |e: &crate::mesh::Element| e.parent.map(|p| p as usize);
        let shot_total: Vec<[f64; 3]> = mesh
            .elements
            .iter()
            .map(|e| parent(e).map_or([0.0; 3], |p| self.shot_total[p]))
            .collect();
        let unshot: Vec<[f64; 3]> = mesh
            .elements
            .iter()
            .enumerate()
            .map(|(i, e)| parent(e).map_or(mesh.source(i), |p| self.unshot[p]))
            .collect();
        let kept = |e: &crate::mesh::Element| matches!(parent(e), Some(p) if old.elements[p].depth == e.depth);
        let new: Vec<u32> = mesh
            .elements
            .iter()
            .enumerate()
            .filter(|(_, e)| !kept(e))
            .map(|(i, _)| i as u32)
            .collect();
        let gathered = refined.gather_elements(&new, &shot_total);
        let mut radiosity = Vec::with_capacity(mesh.elements.len());
        let mut irradiance = Vec::with_capacity(mesh.elements.len());
        for e in &mesh.elements {
            if kept(e) {
                let p = parent(e).unwrap_or_default();
                radiosity.push(self.radiosity[p]);
                irradiance.push(self.irradiance[p]);
            } else {
                radiosity.push([0.0; 3]);
                irradiance.push([0.0; 3]);
            }
        }
        for (&i, h) in new.iter().zip(gathered) {
            let e = &mesh.elements[i as usize];
            let (rho, ex) = (mesh.reflectance(e), mesh.source(i as usize));
            let d = mesh.direct(i as usize);
            radiosity[i as usize] = std::array::from_fn(|c| ex[c] + rho[c] * h[c]);
            irradiance[i as usize] = std::array::from_fn(|c| h[c] + d[c]);
        }
        self.radiosity = radiosity;
        self.irradiance = irradiance;
        self.unshot = unshot;
        self.shot_total = shot_total;
        self.source_power = self.source_powers(refined);
    }

    /// The current (partial) solution.
    pub fn solution(&self, coupling: &dyn Coupling) -> Solution {
        Solution {
            radiosity: self.radiosity.clone(),
            irradiance: self.irradiance.clone(),
            unshot: self.unshot.clone(),
            escaped_power: self.escaped,
            stats: SolveStats {
                solver: SolverKind::Progressive,
                iterations: self.shots,
                residual: self.unshot_fraction(),
                seconds: self.clock.seconds(),
                form_factor_seconds: coupling.form_factor_seconds(),
            },
        }
    }
}

/// The default shot cap: 100 shots per source.
pub fn default_max_shots(coupling: &dyn Coupling) -> usize {
    100 * coupling.sources().max(1)
}

/// Runs progressive refinement to the tolerance or the shot cap.
pub fn solve(
    coupling: &dyn Coupling,
    options: &SolveOptions,
    observer: &mut dyn Observer,
) -> Solution {
    let mut state = Progressive::new(coupling, options);
    let cap = options
        .max_shots
        .unwrap_or_else(|| default_max_shots(coupling));
    state.run(coupling, options.tolerance, cap, observer);
    state.solution(coupling)
}
