//! Comparing the solvers on one mesh: error against a reference versus time and versus
//! iterations (or shots), as a plot (`convergence.svg`, `convergence.png`) and a table
//! (`table.md`).
//!
//! The dense coupling (element × patch matrix plus near-field links,
//! [`radiosity::coupling::Dense`]) is computed once and shared: every solver — the library's
//! own, watched through its observer — gathers from it or shoots its columns, so the
//! comparison measures the solvers and not the form factors.
//!
//! Error measure: the relative area-weighted L1 error of the element radiosity's reflected
//! part,
//!
//!   ε(B) = Σ_e A_e Σ_c |B_e,c − B*_e,c| / Σ_e A_e Σ_c (B*_e,c − E_e,c),
//!
//! against the reference B*: the direct solution (LU) where it fits in memory, else
//! Gauss–Seidel iterated to a relative residual of 1e-12. Emission is exact from the start,
//! so it is left out of the measure; every iterative run starts from B = E, where ε = 1.
//! Started there, Jacobi, Gauss–Seidel and plain progressive refinement (ω = 1) all
//! increase every B_e monotonically towards B* (ρ ≥ 0, F ≥ 0), so for them ε never
//! increases; overshooting (ω > 1) and the ambient term may overshoot B* and are not
//! monotone in general.
//!
//! Times are solver work only (form factors excluded, the same for all): the iterations or
//! shots so far (column look-ups included), or the whole direct solve (patch matrix, LU and
//! refinement). Evaluating the error is not timed.
//!
//! **Hierarchical radiosity** makes its own mesh (the leaves of its refined hierarchy), so
//! it cannot be measured element by element against B*. It is compared by what any mesh
//! has: the per-object area-averaged radiosity ([`Report`]), against the per-object means of
//! the same reference B*,
//!
//!   ε_obj(B) = Σ_o A_o Σ_c |B̄_o,c − B̄*_o,c| / Σ_o A_o Σ_c (B̄*_o,c − Ē_o,c),
//!
//! one full solve per link tolerance of a sweep (8 ε, 4 ε, 2 ε, ε; default ε = 0.01), each
//! timed whole: hierarchy, refinement, link form factors and iterations (nothing shared or
//! precomputed, unlike the other runs). It is one more series, one point per solve. Two
//! caveats when reading it against the other runs: ε_obj(B) ≤ ε(B) for the same B on the
//! study mesh (averaging first can only cancel differences), and B* has the study mesh's
//! own discretisation error, which a fine hierarchical solve does not share, so ε_obj
//! levels off there.
//!
//! **An external reference** ([`compare_against`], `radiosity compare --reference FILE`):
//! per-polygon area-averaged radiosities from outside the engine (the path tracer's of
//! [`crate::path_trace`], Mitsuba's). Every solve is then also measured by its whole error,
//! discretisation and solver: for each polygon of the reference the worst channel's
//! |B̄ − B̄*| / B̄*, its mean and its largest. The classic solvers all converge to the study
//! mesh's solution, so that one row stands for them (timed as its form factors and its
//! reference solve); each hierarchical solve is a row of its own.
//!
//! See also: `radiosity compare`, [`radiosity::solve`].

use crate::font::register_font;
use radiosity::accel::Visibility;
use radiosity::coupling::closure::Enclosure;
use radiosity::coupling::hierarchical::HierarchicalOptions;
use radiosity::coupling::{Coupling, Dense, NearField};
use radiosity::formfactor::{engine, FormFactorMethod};
use radiosity::mesh::Mesh;
use radiosity::pipeline::{solve_scene, solver_memory, SolveSettings};
use radiosity::progress::{NoProgress, Progress};
use radiosity::report::Report;
use radiosity::scene::Scene;
use radiosity::solve::progressive::Progressive;
use radiosity::solve::{
    display_radiosity, solve, Flow, NoObserver, SolveOptions, SolverKind, Step,
};
use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

/// The error levels the table reports the time to reach.
pub const THRESHOLDS: [f64; 3] = [1e-2, 1e-3, 1e-4];

/// The solvers compared.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Method {
    /// Dense LU of the patch-level system with iterative refinement ([`direct`]).
    Direct,
    Jacobi,
    GaussSeidel,
    /// Progressive refinement, ω = 1, plain partial solution.
    Progressive,
    /// The same shots, displayed with the ambient term (`display_radiosity(.., true)`).
    ProgressiveAmbient,
    /// Progressive refinement shooting ω·unshot.
    ProgressiveOvershoot(f64),
    /// Hierarchical radiosity on its own mesh: one whole solve per link tolerance, error
    /// per object (see the module documentation).
    Hierarchical,
}

impl Method {
    /// The name in the plot legend and the table.
    pub fn label(self) -> String {
        match self {
            Method::Direct => "direct (LU)".into(),
            Method::Jacobi => "Jacobi".into(),
            Method::GaussSeidel => "Gauss–Seidel".into(),
            Method::Progressive => "progressive".into(),
            Method::ProgressiveAmbient => "progressive + ambient".into(),
            Method::ProgressiveOvershoot(w) => format!("progressive, overshoot ω = {w}"),
            Method::Hierarchical => "hierarchical (per-object ε, whole solve)".into(),
        }
    }

    /// What one step is.
    pub fn step_name(self) -> &'static str {
        match self {
            Method::Direct => "solve",
            Method::Jacobi | Method::GaussSeidel | Method::Hierarchical => "iterations",
            _ => "shots",
        }
    }

    fn colour(self) -> plotters::style::RGBColor {
        use plotters::style::RGBColor;
        match self {
            Method::Direct => RGBColor(0, 0, 0),
            Method::Jacobi => RGBColor(31, 119, 180),
            Method::GaussSeidel => RGBColor(255, 127, 14),
            Method::Progressive => RGBColor(44, 160, 44),
            Method::ProgressiveAmbient => RGBColor(148, 103, 189),
            Method::ProgressiveOvershoot(_) => RGBColor(214, 39, 40),
            Method::Hierarchical => RGBColor(23, 190, 207),
        }
    }
}

/// Settings of a comparison.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CompareOptions {
    /// ω of the overshooting progressive run, in (1, 2).
    pub overshoot: f64,
    /// Each run stops once its error ε is at or below this (dimensionless).
    pub target_error: f64,
    /// Iteration cap for Jacobi and Gauss–Seidel.
    pub max_iterations: usize,
    /// Shot cap for the progressive runs (`None`: 200 shots per patch).
    pub max_shots: Option<usize>,
    /// Memory the matrices may use, bytes.
    pub memory_limit: u64,
    /// The finest link tolerance ε of the hierarchical series (dimensionless, in (0, 1)).
    pub hierarchical_epsilon: f64,
    /// Hierarchical solves in the series, at 2^(k−1) ε, …, 2 ε, ε (0: no hierarchical series).
    pub hierarchical_solves: usize,
}

impl Default for CompareOptions {
    fn default() -> Self {
        Self {
            // The best of 1.05 … 1.5 on the Cornell box (fewest shots to ε = 1e-4).
            overshoot: 1.1,
            target_error: 1e-5,
            max_iterations: 2000,
            max_shots: None,
            memory_limit: SolveOptions::default().memory_limit,
            // 0.08 … 0.01: from coarser than the solver's default (0.02) to finer.
            hierarchical_epsilon: 0.01,
            hierarchical_solves: 4,
        }
    }
}

/// One point of a convergence history.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// Iterations or shots done (0: the starting guess B = E).
    pub iteration: usize,
    /// Solver time so far, s.
    pub seconds: f64,
    /// Relative error ε (dimensionless; see the module documentation).
    pub error: f64,
}

/// One solver's run.
#[derive(Debug, Clone, PartialEq)]
pub struct Run {
    pub method: Method,
    pub samples: Vec<Sample>,
    /// Why it stopped, or why it was skipped.
    pub note: Option<String>,
}

impl Run {
    /// The first sample at or below `error`.
    pub fn first_below(&self, error: f64) -> Option<&Sample> {
        self.samples.iter().find(|s| s.error <= error)
    }

    pub fn last(&self) -> Option<&Sample> {
        self.samples.last()
    }
}

/// What the errors are measured against.
#[derive(Debug, Clone, PartialEq)]
pub enum Reference {
    /// The direct solution.
    Direct,
    /// Gauss–Seidel iterated to this relative residual (the direct solve did not fit).
    GaussSeidel { iterations: usize, residual: f64 },
}

/// The result of [`compare`].
#[derive(Debug, Clone, PartialEq)]
pub struct Comparison {
    pub scene: String,
    pub elements: usize,
    pub patches: usize,
    /// The form-factor method and the seconds it took to fill the matrix (shared, untimed
    /// in the runs).
    pub form_factor: String,
    pub form_factor_seconds: f64,
    pub reference: Reference,
    /// Direct (when it ran), Jacobi, Gauss–Seidel, progressive, progressive + ambient,
    /// progressive with overshooting, and hierarchical (when its series ran; one sample per
    /// solve, in the order of [`Comparison::hierarchical`]).
    pub runs: Vec<Run>,
    /// The hierarchical solves, coarsest tolerance first.
    pub hierarchical: Vec<HierarchicalPoint>,
    /// What the solves were also measured against per polygon ([`ExternalReference::label`]),
    /// when a reference from outside the engine was given.
    pub external_label: Option<String>,
    /// Those measurements: the study mesh's converged solution, then each hierarchical
    /// solve.
    pub external: Vec<ExternalRow>,
}

/// Per-polygon area-averaged radiosities from outside the engine (the path tracer's of
/// [`crate::path_trace`], Mitsuba's of the shared reference), to measure each solve's
/// whole error against (discretisation and solver), not only the solver's against the
/// study mesh's own solution.
#[derive(Debug, Clone, PartialEq)]
pub struct ExternalReference {
    /// What it is (its file).
    pub label: String,
    /// Object name and area-averaged radiosity per channel, W·m⁻².
    pub objects: Vec<(String, [f64; 3])>,
}

impl ExternalReference {
    /// From JSON: `{"polygons": [{"name": …, "radiosity_avg": [r, g, b]}, …]}` (what the
    /// `path_traced_reference` example writes), or that list under
    /// `"per_polygon_area_averaged"` (the shared Mitsuba reference). The error names what
    /// is missing or malformed.
    pub fn from_json(label: &str, value: &serde_json::Value) -> Result<Self, String> {
        let list = value
            .get("polygons")
            .or_else(|| value.get("per_polygon_area_averaged")?.get("polygons"))
            .and_then(serde_json::Value::as_array)
            .ok_or("no \"polygons\" list (nor \"per_polygon_area_averaged.polygons\")")?;
        let mut objects = Vec::with_capacity(list.len());
        for (i, polygon) in list.iter().enumerate() {
            let name = polygon
                .get("name")
                .and_then(serde_json::Value::as_str)
                .ok_or_else(|| format!("polygon {i} has no \"name\""))?;
            let b = polygon
                .get("radiosity_avg")
                .and_then(serde_json::Value::as_array)
                .filter(|a| a.len() == 3)
                .and_then(|a| {
                    let v: Option<Vec<f64>> = a.iter().map(serde_json::Value::as_f64).collect();
                    v.filter(|v| v.iter().all(|x| x.is_finite() && *x >= 0.0))
                })
                .ok_or_else(|| {
                    format!(
                        "polygon {name:?}: \"radiosity_avg\" must be three finite non-negative numbers"
                    )
                })?;
            objects.push((name.to_owned(), [b[0], b[1], b[2]]));
        }
        if objects.is_empty() {
            return Err("the \"polygons\" list is empty".into());
        }
        Ok(Self {
            label: label.to_owned(),
            objects,
        })
    }

    /// Each reference object's error in `report`, the worst channel's |B̄ − B̄*| / B̄*
    /// (channels where B̄* is 0 left out): (mean over the objects, worst, its object). An
    /// object the report lacks is an error naming it.
    fn measure(&self, report: &Report) -> Result<(f64, f64, String), String> {
        let (mut sum, mut worst) = (0.0, (0.0f64, String::new()));
        for (name, want) in &self.objects {
            let got = report
                .object(name)
                .ok_or_else(|| format!("object {name:?} of {} is not in the scene", self.label))?
                .radiosity;
            let error = (0..3)
                .filter(|&c| want[c] > 0.0)
                .map(|c| (got[c] - want[c]).abs() / want[c])
                .fold(0.0, f64::max);
            sum += error;
            if error > worst.0 {
                worst = (error, name.clone());
            }
        }
        Ok((sum / self.objects.len() as f64, worst.0, worst.1))
    }
}

/// One solve measured against an [`ExternalReference`].
#[derive(Debug, Clone, PartialEq)]
pub struct ExternalRow {
    /// Which solve.
    pub solve: String,
    /// Its time, s: for the study mesh its form factors and the reference solve, for a
    /// hierarchical solve the whole solve.
    pub seconds: f64,
    /// Mean over the reference's objects of the worst channel's relative error.
    pub mean: f64,
    /// The largest of those.
    pub worst: f64,
    /// The object it is on.
    pub worst_object: String,
}

/// One hierarchical solve of the series.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HierarchicalPoint {
    /// Link tolerance ε (dimensionless).
    pub epsilon: f64,
    /// Leaves of the refined hierarchy (its mesh's elements).
    pub leaves: usize,
    /// Iterations over all refinement stages.
    pub iterations: usize,
    /// Wall time of the whole solve, s.
    pub seconds: f64,
    /// Per-object error ε_obj (dimensionless; see the module documentation).
    pub error: f64,
}

/// Why a comparison could not run.
#[derive(Debug, thiserror::Error)]
pub enum CompareError {
    #[error(
        "comparing needs the {elements} × {patches} form-factor matrix ({needed_mib} MiB) but \
         only {limit_mib} MiB may be used; use fewer elements or patches \
         (--elements, --patch-subdivision)"
    )]
    OutOfMemory {
        elements: usize,
        patches: usize,
        needed_mib: u64,
        limit_mib: u64,
    },
    #[error("overshoot factor must be in (1, 2), got {0}")]
    BadOvershoot(f64),
    #[error("target error must be in (0, 1), got {0}")]
    BadTarget(f64),
    #[error(
        "the {0} solver diverged (non-finite radiosity); check that every reflectance is below 1"
    )]
    Diverged(String),
    #[error("writing {path}: {message}")]
    Write { path: String, message: String },
    #[error("hierarchical solve at ε = {epsilon}: {message}")]
    Hierarchical { epsilon: f64, message: String },
    #[error("the hierarchical series' finest ε must be in (0, 1), got {0}")]
    BadEpsilon(f64),
    #[error("{0}")]
    External(String),
}

/// ε(B) against a fixed reference (see the module documentation).
struct ErrorMeasure {
    reference: Vec<[f64; 3]>,
    area: Vec<f64>,
    denominator: f64,
}

impl ErrorMeasure {
    fn new(mesh: &Mesh, reference: Vec<[f64; 3]>) -> Self {
        let area: Vec<f64> = mesh.elements.iter().map(|e| e.area).collect();
        let reflected: f64 = mesh
            .elements
            .iter()
            .zip(&reference)
            .map(|(e, b)| {
                let ex = mesh.exitance(e);
                e.area * (0..3).map(|c| (b[c] - ex[c]).abs()).sum::<f64>()
            })
            .sum();
        let total: f64 = area
            .iter()
            .zip(&reference)
            .map(|(a, b)| a * (b[0].abs() + b[1].abs() + b[2].abs()))
            .sum();
        let denominator = error_denominator(reflected, total);
        Self {
            reference,
            area,
            denominator,
        }
    }

    fn error(&self, b: &[[f64; 3]]) -> f64 {
        let sum: f64 = self
            .area
            .iter()
            .zip(b.iter().zip(&self.reference))
            .map(|(a, (x, y))| a * (0..3).map(|c| (x[c] - y[c]).abs()).sum::<f64>())
            .sum();
        sum / self.denominator
    }
}

/// ε_obj(B) against the per-object means of a fixed reference (see the module
/// documentation). Objects are matched by name, so any mesh of the same scene can be
/// measured.
struct ObjectMeasure {
    /// Name, area (m²) and mean reference radiosity (W·m⁻²) per object.
    objects: Vec<(String, f64, [f64; 3])>,
    denominator: f64,
}

impl ObjectMeasure {
    fn new(scene: &str, mesh: &Mesh, reference: &radiosity::solve::Solution) -> Self {
        let report = Report::new(scene, mesh, reference, "");
        let objects: Vec<(String, f64, [f64; 3])> = report
            .objects
            .iter()
            .filter(|o| o.area > 0.0)
            .map(|o| (o.name.clone(), o.area, o.radiosity))
            .collect();
        let reflected: f64 = report
            .objects
            .iter()
            .filter(|o| o.area > 0.0)
            .map(|o| {
                o.area
                    * (0..3)
                        .map(|c| (o.radiosity[c] - o.emitted_exitance[c]).abs())
                        .sum::<f64>()
            })
            .sum();
        let total: f64 = objects
            .iter()
            .map(|(_, a, b)| a * (b[0].abs() + b[1].abs() + b[2].abs()))
            .sum();
        let denominator = error_denominator(reflected, total);
        Self {
            objects,
            denominator,
        }
    }

    /// ε_obj of a solution on its own mesh; an error names an object of the reference that
    /// is missing from it.
    fn error(&self, report: &Report) -> Result<f64, String> {
        let mut sum = 0.0;
        for (name, area, reference) in &self.objects {
            let b = report
                .object(name)
                .ok_or_else(|| format!("object {name:?} is missing from its mesh"))?
                .radiosity;
            sum += area * (0..3).map(|c| (b[c] - reference[c]).abs()).sum::<f64>();
        }
        Ok(sum / self.denominator)
    }
}

/// Runs every solver on `mesh` (meshed from `scene`) with form factors by `method`
/// (computed once into the dense coupling and shared) and records each one's error after
/// every iteration or shot, by watching the library's own solvers
/// ([`radiosity::solve::Observer`]); then solves `scene` hierarchically at each tolerance of
/// the series ([`CompareOptions::hierarchical_solves`]) and measures it per object.
pub fn compare(
    scene: &Scene,
    mesh: &Mesh,
    method: FormFactorMethod,
    options: &CompareOptions,
    progress: &dyn Progress,
) -> Result<Comparison, CompareError> {
    compare_against(scene, mesh, method, options, None, progress)
}

/// [`compare`], and with `external` each solve's per-polygon error against that reference
/// as well: the study mesh's converged solution (what every classic solver converges to)
/// and each hierarchical solve ([`Comparison::external`]).
pub fn compare_against(
    scene: &Scene,
    mesh: &Mesh,
    method: FormFactorMethod,
    options: &CompareOptions,
    external: Option<&ExternalReference>,
    progress: &dyn Progress,
) -> Result<Comparison, CompareError> {
    if !(options.overshoot > 1.0 && options.overshoot < 2.0) {
        return Err(CompareError::BadOvershoot(options.overshoot));
    }
    if !(options.target_error > 0.0 && options.target_error < 1.0) {
        return Err(CompareError::BadTarget(options.target_error));
    }
    if options.hierarchical_solves > 0
        && !(options.hierarchical_epsilon > 0.0 && options.hierarchical_epsilon < 1.0)
    {
        return Err(CompareError::BadEpsilon(options.hierarchical_epsilon));
    }
    let (n, m) = (mesh.len(), mesh.patches.len());
    // The matrix, and its column copy for the progressive runs' shots.
    let needed = solver_memory(SolverKind::GaussSeidel, n, m) + Dense::bytes_for(n, m);
    if needed > options.memory_limit as u128 {
        return Err(CompareError::OutOfMemory {
            elements: n,
            patches: m,
            needed_mib: (needed >> 20).min(u64::MAX as u128) as u64,
            limit_mib: options.memory_limit >> 20,
        });
    }
    // The LU beside the matrix and its column copy.
    let direct_needs = solver_memory(SolverKind::Direct, n, m) + Dense::bytes_for(n, m);
    let direct_fits = direct_needs <= options.memory_limit as u128;

    let visibility = Visibility::new(mesh);
    let enclosure = Enclosure::probe(mesh, &visibility);
    let near = NearField::decide(mesh);
    let engine = engine(method, mesh, &visibility, &near.per_element);
    let coupling = Dense::compute(mesh, engine.as_ref(), &near, enclosure, progress);
    let form_factor_seconds = coupling.form_factor_seconds();
    let start_b = radiosity::solve::exitance(mesh);
    check_finite(&start_b, Method::Jacobi)?;

    let mut runs = Vec::new();
    // The converged solution on the study mesh and its solve time, for `external`.
    let reference_report;
    let (reference, measure, objects) = if direct_fits {
        progress.start("direct", 1);
        let direct = solve(
            &coupling,
            &SolveOptions {
                solver: SolverKind::Direct,
                ..Default::default()
            },
            &mut NoObserver,
        )
        .map_err(|_| CompareError::Diverged(Method::Direct.label()))?;
        progress.finish();
        let objects = ObjectMeasure::new(&scene.name, mesh, &direct);
        reference_report = (
            Report::new(&scene.name, mesh, &direct, method.name()),
            direct.stats.seconds,
        );
        let measure = ErrorMeasure::new(mesh, direct.radiosity);
        runs.push(Run {
            method: Method::Direct,
            samples: vec![Sample {
                iteration: 1,
                seconds: direct.stats.seconds,
                error: 0.0,
            }],
            note: Some("the reference".into()),
        });
        (Reference::Direct, measure, objects)
    } else {
        let tight = SolveOptions {
            solver: SolverKind::GaussSeidel,
            tolerance: 1e-12,
            max_iterations: 100_000,
            ..Default::default()
        };
        let reference = solve(&coupling, &tight, &mut NoObserver)
            .map_err(|_| CompareError::Diverged(Method::GaussSeidel.label()))?;
        reference_report = (
            Report::new(&scene.name, mesh, &reference, method.name()),
            reference.stats.seconds,
        );
        runs.push(Run {
            method: Method::Direct,
            samples: Vec::new(),
            note: Some(format!(
                "skipped: the dense LU would need {} MiB more than the {} MiB allowed",
                (direct_needs.saturating_sub(options.memory_limit as u128)) >> 20,
                options.memory_limit >> 20
            )),
        });
        (
            Reference::GaussSeidel {
                iterations: reference.stats.iterations,
                residual: reference.stats.residual,
            },
            ErrorMeasure::new(mesh, reference.radiosity.clone()),
            ObjectMeasure::new(&scene.name, mesh, &reference),
        )
    };

    // The iterative solvers run until the observer sees the target error (their own
    // tolerance is set out of reach) or the cap; the observer records every step.
    for (method, solver) in [
        (Method::Jacobi, SolverKind::Jacobi),
        (Method::GaussSeidel, SolverKind::GaussSeidel),
    ] {
        let mut samples = Vec::new();
        let mut diverged = false;
        progress.start(solver.name(), options.max_iterations as u64);
        let mut watch = |step: &Step<'_>| {
            let error = measure.error(step.radiosity);
            diverged |= !error.is_finite();
            samples.push(Sample {
                iteration: step.index,
                seconds: step.elapsed,
                error,
            });
            progress.inc(u64::from(step.index > 0));
            if error <= options.target_error || diverged {
                Flow::Stop
            } else {
                Flow::Continue
            }
        };
        let run_options = SolveOptions {
            solver,
            tolerance: f64::MIN_POSITIVE,
            max_iterations: options.max_iterations,
            ..Default::default()
        };
        let result = solve(&coupling, &run_options, &mut watch);
        progress.finish();
        if diverged || result.is_err() {
            return Err(CompareError::Diverged(method.label()));
        }
        runs.push(finish_run(method, samples, options));
    }

    // Progressive refinement, plain and with the ambient term (the same shots), then with
    // overshooting; columns come from the dense coupling.
    let cap = options.max_shots.unwrap_or(200 * m.max(1));
    for omega in [1.0, options.overshoot] {
        let with_ambient = omega == 1.0;
        let method = if with_ambient {
            Method::Progressive
        } else {
            Method::ProgressiveOvershoot(omega)
        };
        let (mut plain, mut ambient) = (Vec::new(), Vec::new());
        let mut diverged = false;
        progress.start(
            if with_ambient {
                "progressive"
            } else {
                "overshooting"
            },
            cap as u64,
        );
        let mut watch = |step: &Step<'_>| {
            let e = measure.error(step.radiosity);
            let a = match step.unshot {
                Some(unshot) if with_ambient => {
                    let shown = display_radiosity(step.mesh, step.radiosity, unshot, true);
                    measure.error(&shown)
                }
                _ => e,
            };
            diverged |= !(e.is_finite() && a.is_finite());
            plain.push(Sample {
                iteration: step.index,
                seconds: step.elapsed,
                error: e,
            });
            ambient.push(Sample {
                iteration: step.index,
                seconds: step.elapsed,
                error: a,
            });
            progress.inc(u64::from(step.index > 0));
            if (e <= options.target_error && a <= options.target_error) || diverged {
                Flow::Stop
            } else {
                Flow::Continue
            }
        };
        let solve_options = SolveOptions {
            overshoot: omega,
            ..Default::default()
        };
        let mut state = Progressive::new(&coupling, &solve_options);
        let exhausted = state.run(&coupling, 0.0, cap, &mut watch);
        progress.finish();
        if diverged {
            return Err(CompareError::Diverged(method.label()));
        }
        let mut run = finish_run(method, plain, options);
        if exhausted {
            run.note = Some("nothing left to shoot".into());
        }
        runs.push(run);
        if with_ambient {
            runs.push(finish_run(Method::ProgressiveAmbient, ambient, options));
        }
    }
    // The dense coupling is no longer needed; the hierarchy takes the memory it leaves.
    drop(coupling);
    let mut external_rows = Vec::new();
    if let Some(external) = external {
        let (report, seconds) = &reference_report;
        let (mean, worst, worst_object) =
            external.measure(report).map_err(CompareError::External)?;
        external_rows.push(ExternalRow {
            solve: format!("study mesh, {n} elements (every classic solver's limit)"),
            seconds: form_factor_seconds + seconds,
            mean,
            worst,
            worst_object,
        });
    }
    let hierarchical = hierarchical_series(
        scene,
        method,
        &objects,
        options,
        external.map(|e| (e, &mut external_rows)),
        progress,
    )?;
    if !hierarchical.is_empty() {
        let epsilons: Vec<String> = hierarchical
            .iter()
            .map(|p| format!("{}", p.epsilon))
            .collect();
        let note = format!(
            "one whole solve per ε = {} (its own mesh: {} … {} leaves)",
            epsilons.join(", "),
            hierarchical[0].leaves,
            hierarchical[hierarchical.len() - 1].leaves
        );
        runs.push(Run {
            method: Method::Hierarchical,
            samples: hierarchical
                .iter()
                .map(|p| Sample {
                    iteration: p.iterations,
                    seconds: p.seconds,
                    error: p.error,
                })
                .collect(),
            note: Some(note),
        });
    }
    Ok(Comparison {
        scene: scene.name.clone(),
        elements: n,
        patches: m,
        form_factor: method.name().to_owned(),
        form_factor_seconds,
        reference,
        runs,
        hierarchical,
        external_label: external.map(|e| e.label.clone()),
        external: external_rows,
    })
}

/// Solves `scene` hierarchically at 2^(k−1) ε, …, 2 ε, ε (coarsest first), each solve
/// whole and timed whole, with the library's default stopping rule, and measures each
/// per object.
fn hierarchical_series(
    scene: &Scene,
    method: FormFactorMethod,
    objects: &ObjectMeasure,
    options: &CompareOptions,
    mut external: Option<(&ExternalReference, &mut Vec<ExternalRow>)>,
    progress: &dyn Progress,
) -> Result<Vec<HierarchicalPoint>, CompareError> {
    let k = options.hierarchical_solves;
    progress.start("hierarchical", k as u64);
    let mut points = Vec::with_capacity(k);
    for i in (0..k).rev() {
        let epsilon = options.hierarchical_epsilon * 2f64.powi(i as i32);
        let settings = SolveSettings {
            form_factor: method,
            solve: SolveOptions {
                solver: SolverKind::Hierarchical,
                ..Default::default()
            },
            hierarchical: HierarchicalOptions {
                epsilon,
                ..Default::default()
            },
            ..Default::default()
        };
        let failed = |e: &dyn std::error::Error| {
            let mut message = e.to_string();
            let mut source = e.source();
            while let Some(s) = source {
                let _ = write!(message, ": {s}");
                source = s.source();
            }
            CompareError::Hierarchical { epsilon, message }
        };
        let start = Instant::now();
        let solved = solve_scene(scene, &settings, &NoProgress).map_err(|e| failed(&e))?;
        let seconds = start.elapsed().as_secs_f64();
        check_finite(&solved.solution.radiosity, Method::Hierarchical)?;
        let report = Report::new(&scene.name, &solved.mesh, &solved.solution, method.name());
        let error = objects
            .error(&report)
            .map_err(|message| CompareError::Hierarchical { epsilon, message })?;
        if let Some((reference, rows)) = external.as_mut() {
            let (mean, worst, worst_object) =
                reference.measure(&report).map_err(CompareError::External)?;
            rows.push(ExternalRow {
                solve: format!("hierarchical, ε = {epsilon}, {} leaves", solved.mesh.len()),
                seconds,
                mean,
                worst,
                worst_object,
            });
        }
        points.push(HierarchicalPoint {
            epsilon,
            leaves: solved.mesh.len(),
            iterations: solved.solution.stats.iterations,
            seconds,
            error,
        });
        progress.inc(1);
    }
    progress.finish();
    Ok(points)
}

fn check_finite(b: &[[f64; 3]], method: Method) -> Result<(), CompareError> {
    if b.iter().flatten().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(CompareError::Diverged(method.label()))
    }
}

fn finish_run(method: Method, samples: Vec<Sample>, options: &CompareOptions) -> Run {
    let last = samples.last().copied();
    let note = match last {
        Some(s) if s.error <= options.target_error => None,
        Some(s) => Some(format!(
            "stopped at the cap after {} {} (error {:.1e})",
            s.iteration,
            method.step_name(),
            s.error
        )),
        None => None,
    };
    Run {
        method,
        samples,
        note,
    }
}

/// Seconds in a readable unit ("0.42 ms", "12.3 ms", "1.25 s").
pub fn format_seconds(s: f64) -> String {
    if s < 1e-3 {
        format!("{:.1} µs", s * 1e6)
    } else if s < 1.0 {
        format!("{:.2} ms", s * 1e3)
    } else {
        format!("{s:.2} s")
    }
}

impl Comparison {
    /// The run of a method, if it ran.
    pub fn run(&self, method: Method) -> Option<&Run> {
        self.runs.iter().find(|r| r.method == method)
    }

    /// `table.md`: per solver, the time (and iterations or shots) to reach each of
    /// [`THRESHOLDS`], and the final error.
    pub fn table_markdown(&self) -> String {
        let mut t = String::new();
        let _ = writeln!(t, "# Solver comparison: {}\n", self.scene);
        let reference = match &self.reference {
            Reference::Direct => {
                "the direct solution B* (dense LU with iterative refinement)".to_owned()
            }
            Reference::GaussSeidel {
                iterations,
                residual,
            } => format!(
                "a converged solution B*: Gauss–Seidel after {iterations} iterations (relative \
                 residual {residual:.1e}); the direct solve did not fit in memory"
            ),
        };
        let _ = writeln!(
            t,
            "- Mesh: {} elements, {} patches. Form factors ({}) computed once in {} and shared \
             by every solver; not included in the times below.",
            self.elements,
            self.patches,
            self.form_factor,
            format_seconds(self.form_factor_seconds)
        );
        let _ = writeln!(
            t,
            "- Error ε: relative area-weighted L1 error of the element radiosity's reflected \
             part against {reference}: ε = Σ_e A_e Σ_c |B_e,c − B*_e,c| / \
             Σ_e A_e Σ_c (B*_e,c − E_e,c)."
        );
        let _ = writeln!(
            t,
            "- Start: every iterative run starts at B = E (ε = 1); the direct solve is one step."
        );
        let _ = writeln!(
            t,
            "- Times: solver work only — the iterations or shots so far, or the whole direct \
             solve (patch matrix, LU, refinement). Evaluating ε is not timed."
        );
        if !self.hierarchical.is_empty() {
            let _ = writeln!(
                t,
                "- Hierarchical: its own mesh (the leaves of its hierarchy), so its error is \
                 per object: ε_obj = Σ_o A_o Σ_c |B̄_o,c − B̄*_o,c| / Σ_o A_o Σ_c (B̄*_o,c − \
                 Ē_o,c), with B̄ the area-averaged radiosity of object o, against the same B*. \
                 One whole solve per link tolerance, timed whole (hierarchy, link form \
                 factors, refinement, iterations); its rows' iterations are that solve's. \
                 ε_obj ≤ ε for the same B, and it levels off at the mesh's own discretisation \
                 error in B*."
            );
        }
        t.push('\n');
        let _ = writeln!(
            t,
            "| solver | ε ≤ 1e-2 | ε ≤ 1e-3 | ε ≤ 1e-4 | final ε | steps run | note |"
        );
        let _ = writeln!(t, "|---|---|---|---|---|---|---|");
        for run in &self.runs {
            let mut cells = Vec::new();
            for th in THRESHOLDS {
                cells.push(match run.first_below(th) {
                    Some(s) if run.method == Method::Direct => format_seconds(s.seconds),
                    Some(s) => format!(
                        "{} ({} {})",
                        format_seconds(s.seconds),
                        s.iteration,
                        run.method.step_name()
                    ),
                    None if run.samples.is_empty() => "—".into(),
                    None => "not reached".into(),
                });
            }
            let (final_error, steps) = match run.last() {
                Some(_) if run.method == Method::Direct => {
                    ("0 (reference)".to_owned(), "1 solve".to_owned())
                }
                Some(s) => (
                    format!("{:.1e}", s.error),
                    format!("{} {}", s.iteration, run.method.step_name()),
                ),
                None => ("—".into(), "—".into()),
            };
            let _ = writeln!(
                t,
                "| {} | {} | {} | {} | {} | {} | {} |",
                run.method.label(),
                cells[0],
                cells[1],
                cells[2],
                final_error,
                steps,
                run.note.as_deref().unwrap_or("")
            );
        }
        if !self.hierarchical.is_empty() {
            let _ = writeln!(
                t,
                "\n## Hierarchical: accuracy against time\n\n\
                 | link tolerance ε | leaves | iterations | time (whole solve) | ε_obj |\n\
                 |---|---|---|---|---|"
            );
            for p in &self.hierarchical {
                let _ = writeln!(
                    t,
                    "| {} | {} | {} | {} | {:.1e} |",
                    p.epsilon,
                    p.leaves,
                    p.iterations,
                    format_seconds(p.seconds),
                    p.error
                );
            }
        }
        if let Some(label) = &self.external_label {
            let _ = writeln!(
                t,
                "\n## Against {label}, per polygon\n\n\
                 Each polygon's area-averaged radiosity against the reference's, the worst \
                 channel's |B̄ − B̄*| / B̄*: the whole error of a solve (its mesh's \
                 discretisation and its solver), where ε above is the solver's alone. Times: \
                 the study mesh's form factors and reference solve; each hierarchical solve \
                 whole.\n\n\
                 | solve | time | mean | worst polygon |\n|---|---|---|---|"
            );
            for r in &self.external {
                let _ = writeln!(
                    t,
                    "| {} | {} | {:.2} % | {:.2} % ({}) |",
                    r.solve,
                    format_seconds(r.seconds),
                    100.0 * r.mean,
                    100.0 * r.worst,
                    r.worst_object
                );
            }
        }
        t
    }

    /// `comparison.json`: the table's content with every sample, for scripts.
    pub fn to_json(&self) -> serde_json::Value {
        use serde_json::json;
        let reference = match &self.reference {
            Reference::Direct => json!({ "kind": "direct" }),
            Reference::GaussSeidel {
                iterations,
                residual,
            } => json!({
                "kind": "gauss-seidel",
                "iterations": iterations,
                "residual": residual,
            }),
        };
        let runs: Vec<serde_json::Value> = self
            .runs
            .iter()
            .map(|run| {
                json!({
                    "solver": run.method.label(),
                    "error": if run.method == Method::Hierarchical {
                        "per-object"
                    } else {
                        "per-element"
                    },
                    "steps": run.method.step_name(),
                    "note": run.note,
                    "samples": run
                        .samples
                        .iter()
                        .map(|s| json!({
                            "iteration": s.iteration,
                            "seconds": s.seconds,
                            "error": s.error,
                        }))
                        .collect::<Vec<_>>(),
                })
            })
            .collect();
        let hierarchical: Vec<serde_json::Value> = self
            .hierarchical
            .iter()
            .map(|p| {
                json!({
                    "epsilon": p.epsilon,
                    "leaves": p.leaves,
                    "iterations": p.iterations,
                    "seconds": p.seconds,
                    "error": p.error,
                })
            })
            .collect();
        json!({
            "scene": self.scene,
            "elements": self.elements,
            "patches": self.patches,
            "form_factor": self.form_factor,
            "form_factor_seconds": self.form_factor_seconds,
            "reference": reference,
            "runs": runs,
            "hierarchical": hierarchical,
            "external": self.external_label.as_ref().map(|label| json!({
                "reference": label,
                "solves": self.external.iter().map(|r| json!({
                    "solve": r.solve,
                    "seconds": r.seconds,
                    "mean": r.mean,
                    "worst": r.worst,
                    "worst_object": r.worst_object,
                })).collect::<Vec<_>>(),
            })),
        })
    }

    /// Writes `table.md`, `comparison.json`, `convergence.svg` and `convergence.png` into
    /// `dir` (which must exist), each atomically.
    pub fn write(&self, dir: &Path) -> Result<(), CompareError> {
        use plotters::prelude::{BitMapBackend, IntoDrawingArea, SVGBackend};
        let table = self.table_markdown();
        let path = dir.join("table.md");
        radiosity::io::atomic::write_atomically(&path, |w| w.write_all(table.as_bytes()))
            .map_err(|e| write_error(&path, e))?;
        let json_path = dir.join("comparison.json");
        let json = serde_json::to_string_pretty(&self.to_json())
            .map_err(|e| write_error(&json_path, e))?;
        radiosity::io::atomic::write_atomically(&json_path, |w| w.write_all(json.as_bytes()))
            .map_err(|e| write_error(&json_path, e))?;

        register_font().map_err(|e| write_error(&path, e))?;
        let svg_path = dir.join("convergence.svg");
        let mut svg = String::new();
        {
            let root = SVGBackend::with_string(&mut svg, PLOT_SIZE).into_drawing_area();
            self.draw(root).map_err(|e| write_error(&svg_path, e))?;
        }
        radiosity::io::atomic::write_atomically(&svg_path, |w| w.write_all(svg.as_bytes()))
            .map_err(|e| write_error(&svg_path, e))?;

        let png_path = dir.join("convergence.png");
        let mut buf = vec![255u8; PLOT_SIZE.0 as usize * PLOT_SIZE.1 as usize * 3];
        {
            let root = BitMapBackend::with_buffer(&mut buf, PLOT_SIZE).into_drawing_area();
            self.draw(root).map_err(|e| write_error(&png_path, e))?;
        }
        let image = image::RgbImage::from_raw(PLOT_SIZE.0, PLOT_SIZE.1, buf)
            .ok_or_else(|| write_error(&png_path, "plot buffer size"))?;
        crate::sequence::write_png(&image, &png_path).map_err(|e| write_error(&png_path, e))?;
        Ok(())
    }

    /// Draws the two panels: error versus time and versus iterations/shots, log–log.
    fn draw<DB: plotters::prelude::DrawingBackend>(
        &self,
        root: plotters::drawing::DrawingArea<DB, plotters::coord::Shift>,
    ) -> Result<(), String>
    where
        DB::ErrorType: 'static,
    {
        use plotters::prelude::*;
        let err = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
        root.fill(&WHITE).map_err(err)?;
        let title = format!(
            "{}: {} elements, {} patches — error against {}",
            self.scene,
            self.elements,
            self.patches,
            match self.reference {
                Reference::Direct => "the direct solution",
                Reference::GaussSeidel { .. } => "a converged Gauss–Seidel solution",
            }
        );
        let root = root.titled(&title, ("sans-serif", 22)).map_err(err)?;
        let (left, right) = root.split_horizontally(PLOT_SIZE.0 / 2);

        // Ranges over every plotted (positive) value.
        let iterative = || self.runs.iter().filter(|r| r.method != Method::Direct);
        let points = || iterative().flat_map(|r| r.samples.iter());
        let min_error = points()
            .map(|s| s.error)
            .filter(|e| *e > 0.0)
            .fold(f64::INFINITY, f64::min)
            .min(1e-4);
        let max_error = points().map(|s| s.error).fold(1.0, f64::max);
        let y_range = (min_error / 2.0)..(max_error * 1.5);
        let mut t_min = points()
            .map(|s| s.seconds)
            .filter(|t| *t > 0.0)
            .fold(f64::INFINITY, f64::min);
        let mut t_max = points().map(|s| s.seconds).fold(0.0, f64::max);
        if let Some(d) = self.run(Method::Direct).and_then(Run::last) {
            t_min = t_min.min(d.seconds);
            t_max = t_max.max(d.seconds);
        }
        // The hierarchical solves are timed whole; the others share form factors computed
        // beforehand, marked so that the two can be read together.
        let form_factor_mark = (!self.hierarchical.is_empty() && self.form_factor_seconds > 0.0)
            .then_some(self.form_factor_seconds);
        if let Some(t) = form_factor_mark {
            t_min = t_min.min(t);
            t_max = t_max.max(t);
        }
        if !(t_min.is_finite() && t_max > t_min) {
            t_min = 1e-6;
            t_max = t_max.max(1e-3);
        }
        let x_time = (t_min / 1.5)..(t_max * 1.5);
        let max_steps = points().map(|s| s.iteration).max().unwrap_or(1).max(2) as f64;
        let x_steps = 1.0..(max_steps * 1.5);

        let mut time_chart = ChartBuilder::on(&left)
            .margin(12)
            .margin_right(28)
            .x_label_area_size(48)
            .y_label_area_size(70)
            .build_cartesian_2d(x_time.log_scale(), y_range.clone().log_scale())
            .map_err(err)?;
        time_chart
            .configure_mesh()
            .x_desc("solver time (s, log scale)")
            .y_desc("relative L1 error ε (log scale)")
            .x_label_formatter(&|x| format!("{x:.0e}"))
            .y_label_formatter(&|y| format!("{y:.0e}"))
            .label_style(("sans-serif", 14))
            .axis_desc_style(("sans-serif", 16))
            .draw()
            .map_err(err)?;
        let mut steps_chart = ChartBuilder::on(&right)
            .margin(12)
            .margin_right(28)
            .x_label_area_size(48)
            .y_label_area_size(70)
            .build_cartesian_2d(x_steps.log_scale(), y_range.clone().log_scale())
            .map_err(err)?;
        steps_chart
            .configure_mesh()
            .x_desc(
                "iterations (Jacobi, Gauss–Seidel, hierarchical) or shots (progressive), log scale",
            )
            .y_desc("relative L1 error ε (log scale)")
            .x_label_formatter(&|x| format!("{x:.0}"))
            .y_label_formatter(&|y| format!("{y:.0e}"))
            .label_style(("sans-serif", 14))
            .axis_desc_style(("sans-serif", 16))
            .draw()
            .map_err(err)?;

        if let Some(t) = form_factor_mark {
            let style = ShapeStyle::from(&RGBColor(127, 127, 127)).stroke_width(2);
            time_chart
                .draw_series(DashedLineSeries::new(
                    vec![(t, y_range.start), (t, y_range.end)],
                    2,
                    4,
                    style,
                ))
                .map_err(err)?
                .label(format!(
                    "form factors, shared, not in the times ({})",
                    format_seconds(t)
                ))
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], style));
        }
        for run in &self.runs {
            let colour = run.method.colour();
            let style = ShapeStyle::from(&colour).stroke_width(2);
            if run.method == Method::Direct {
                // The direct solve is one point in time: a vertical line at its time.
                if let Some(s) = run.last() {
                    let line = vec![(s.seconds, y_range.start), (s.seconds, y_range.end)];
                    time_chart
                        .draw_series(DashedLineSeries::new(line, 6, 4, style))
                        .map_err(err)?
                        .label(format!(
                            "{} ({})",
                            run.method.label(),
                            format_seconds(s.seconds)
                        ))
                        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], style));
                }
                continue;
            }
            let by_time: Vec<(f64, f64)> = run
                .samples
                .iter()
                .filter(|s| s.seconds > 0.0 && s.error > 0.0)
                .map(|s| (s.seconds, s.error))
                .collect();
            if run.method == Method::Hierarchical {
                // Separate solves, not one history: each point is marked.
                time_chart
                    .draw_series(by_time.iter().map(|&p| Circle::new(p, 4, style.filled())))
                    .map_err(err)?;
                steps_chart
                    .draw_series(
                        run.samples
                            .iter()
                            .filter(|s| s.iteration > 0 && s.error > 0.0)
                            .map(|s| Circle::new((s.iteration as f64, s.error), 4, style.filled())),
                    )
                    .map_err(err)?;
            }
            time_chart
                .draw_series(LineSeries::new(by_time, style))
                .map_err(err)?
                .label(run.method.label())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], style));
            let by_steps: Vec<(f64, f64)> = run
                .samples
                .iter()
                .filter(|s| s.iteration > 0 && s.error > 0.0)
                .map(|s| (s.iteration as f64, s.error))
                .collect();
            steps_chart
                .draw_series(LineSeries::new(by_steps, style))
                .map_err(err)?
                .label(run.method.label())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], style));
        }
        for chart in [&mut time_chart, &mut steps_chart] {
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::LowerLeft)
                .label_font(("sans-serif", 14))
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .draw()
                .map_err(err)?;
        }
        root.present().map_err(err)?;
        Ok(())
    }
}

/// Size of the convergence plot, pixels (two panels side by side).
const PLOT_SIZE: (u32, u32) = (1400, 620);

fn write_error(path: &Path, e: impl std::fmt::Display) -> CompareError {
    CompareError::Write {
        path: path.display().to_string(),
        message: e.to_string(),
    }
}

/// The normaliser of the error measures: the reflected part Σ A |B − E|, or, when nothing
/// is reflected (no emitter, or all black), the whole radiosity Σ A |B|, or 1.
fn error_denominator(reflected: f64, total: f64) -> f64 {
    if reflected > 0.0 {
        reflected
    } else if total > 0.0 {
        total
    } else {
        1.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use radiosity::cornell::cornell_box;
    use radiosity::mesh::MeshOptions;
    use radiosity::progress::NoProgress;
    use std::sync::OnceLock;

    fn mesh() -> &'static Mesh {
        static M: OnceLock<Mesh> = OnceLock::new();
        M.get_or_init(|| {
            let options = MeshOptions {
                elements: 400,
                ..Default::default()
            };
            Mesh::build(&cornell_box(), &options).unwrap()
        })
    }

    fn scene() -> &'static Scene {
        static S: OnceLock<Scene> = OnceLock::new();
        S.get_or_init(cornell_box)
    }

    /// The test series: ε = 0.08, 0.04, 0.02 (the finest of the default series, 0.01, adds
    /// 2–4 s and sits at the 400-element reference's own error; see below).
    fn options() -> CompareOptions {
        CompareOptions {
            hierarchical_epsilon: 0.02,
            hierarchical_solves: 3,
            ..Default::default()
        }
    }

    fn run_with(options: &CompareOptions) -> Result<Comparison, CompareError> {
        compare(
            scene(),
            mesh(),
            FormFactorMethod::default(),
            options,
            &NoProgress,
        )
    }

    /// The path tracer's per-polygon reference of the Cornell box (see
    /// `crates/radiosity/tests/reference/PROVENANCE.md`).
    fn path_traced() -> ExternalReference {
        let value: serde_json::Value = serde_json::from_str(include_str!(
            "../../radiosity/tests/reference/cornell_path_traced.json"
        ))
        .unwrap();
        ExternalReference::from_json("cornell_path_traced.json", &value).unwrap()
    }

    /// The Cornell box at ~400 elements, every solver, also measured against the path
    /// tracer's reference (shared by the tests below).
    fn comparison() -> &'static Comparison {
        static C: OnceLock<Comparison> = OnceLock::new();
        C.get_or_init(|| {
            compare_against(
                scene(),
                mesh(),
                FormFactorMethod::default(),
                &options(),
                Some(&path_traced()),
                &NoProgress,
            )
            .unwrap()
        })
    }

    /// Against the path tracer, the study mesh's converged solution and each hierarchical
    /// solve are measured per polygon, in the table and the JSON. The hierarchical solves
    /// come closer as ε shrinks (measured means 3.2, 1.5 and 1.0 % at ε = 0.08, 0.04,
    /// 0.02), and at 0.02 every polygon is within 3.5 % (measured 2.85 %, the short
    /// block's front); the 400-element mesh's solution is measured too.
    #[test]
    fn an_external_reference_measures_every_solve_per_polygon() {
        let c = comparison();
        assert_eq!(
            c.external_label.as_deref(),
            Some("cornell_path_traced.json")
        );
        assert_eq!(c.external.len(), 1 + c.hierarchical.len());
        assert!(c.external[0].solve.starts_with("study mesh"));
        for r in &c.external {
            assert!(
                r.mean.is_finite() && r.mean > 0.0 && r.worst >= r.mean,
                "{r:?}"
            );
        }
        let means: Vec<f64> = c.external[1..].iter().map(|r| r.mean).collect();
        assert!(means.windows(2).all(|w| w[1] < w[0]), "{means:?}");
        let finest = c.external.last().unwrap();
        assert!(finest.worst < 0.035, "{finest:?}");
        let table = c.table_markdown();
        assert!(table.contains("## Against cornell_path_traced.json, per polygon"));
        assert!(table.contains(&finest.worst_object));
        let json = c.to_json();
        assert_eq!(
            json["external"]["solves"].as_array().unwrap().len(),
            c.external.len()
        );
    }

    /// The two formats are read, what is wrong is named, and a solve that lacks one of the
    /// reference's objects is an error naming it; the reference measured against itself
    /// has no error.
    #[test]
    fn external_references_are_read_and_checked() {
        let ours = serde_json::json!({
            "polygons": [{"name": "a", "radiosity_avg": [1.0, 2.0, 0.0]}]
        });
        let mitsuba = serde_json::json!({
            "per_polygon_area_averaged": {"polygons": [{"name": "a", "radiosity_avg": [1.0, 2.0, 0.0]}]}
        });
        let a = ExternalReference::from_json("x", &ours).unwrap();
        assert_eq!(a, ExternalReference::from_json("x", &mitsuba).unwrap());
        assert_eq!(a.objects, vec![("a".to_owned(), [1.0, 2.0, 0.0])]);
        for (bad, says) in [
            (serde_json::json!({}), "no \"polygons\""),
            (serde_json::json!({"polygons": []}), "empty"),
            (
                serde_json::json!({"polygons": [{"radiosity_avg": [1, 1, 1]}]}),
                "polygon 0 has no",
            ),
            (
                serde_json::json!({"polygons": [{"name": "b", "radiosity_avg": [1, -1, 1]}]}),
                "\"b\"",
            ),
            (
                serde_json::json!({"polygons": [{"name": "b", "radiosity_avg": [1, 1]}]}),
                "three finite",
            ),
        ] {
            let e = ExternalReference::from_json("x", &bad).unwrap_err();
            assert!(e.contains(says), "{e}");
        }
        let direct = solve(
            &Dense::compute(
                mesh(),
                engine(
                    FormFactorMethod::default(),
                    mesh(),
                    &Visibility::new(mesh()),
                    &NearField::decide(mesh()).per_element,
                )
                .as_ref(),
                &NearField::decide(mesh()),
                Enclosure::probe(mesh(), &Visibility::new(mesh())),
                &NoProgress,
            ),
            &SolveOptions {
                solver: SolverKind::Direct,
                ..Default::default()
            },
            &mut NoObserver,
        )
        .unwrap();
        let report = Report::new("cornell", mesh(), &direct, "");
        let itself = ExternalReference {
            label: "itself".into(),
            objects: report
                .objects
                .iter()
                .map(|o| (o.name.clone(), o.radiosity))
                .collect(),
        };
        let (mean, worst, _) = itself.measure(&report).unwrap();
        assert_eq!((mean, worst), (0.0, 0.0));
        let missing = ExternalReference {
            label: "r.json".into(),
            objects: vec![("no_such_object".into(), [1.0; 3])],
        };
        let e = missing.measure(&report).unwrap_err();
        assert!(e.contains("no_such_object") && e.contains("r.json"), "{e}");
    }

    /// The runs on the study mesh (all but hierarchical).
    fn on_the_mesh(c: &Comparison) -> impl Iterator<Item = &Run> {
        c.runs.iter().filter(|r| r.method != Method::Hierarchical)
    }

    fn errors(run: &Run) -> Vec<f64> {
        run.samples.iter().map(|s| s.error).collect()
    }

    #[test]
    fn every_solver_converges_to_the_direct_solution() {
        let c = comparison();
        assert_eq!(c.reference, Reference::Direct);
        assert_eq!(c.runs.len(), 7);
        let target = CompareOptions::default().target_error;
        for run in on_the_mesh(c) {
            let last = run.last().unwrap();
            assert!(
                last.error <= target,
                "{}: final error {}",
                run.method.label(),
                last.error
            );
            assert!(
                run.note.is_none() || run.method == Method::Direct,
                "{:?}",
                run.note
            );
            // Time only moves forward.
            assert!(run.samples.windows(2).all(|w| w[1].seconds >= w[0].seconds));
        }
        // Every iterative run starts at B = E, where the reflected part is all missing: ε = 1.
        for m in [
            Method::Jacobi,
            Method::GaussSeidel,
            Method::Progressive,
            Method::ProgressiveOvershoot(1.1),
        ] {
            let first = c.run(m).unwrap().samples[0];
            assert_eq!(first.iteration, 0);
            assert!((first.error - 1.0).abs() < 1e-12, "{m:?}: {}", first.error);
        }
    }

    #[test]
    fn errors_never_increase_for_monotone_solvers() {
        // From B = E with M, ρ, F ≥ 0, Jacobi, Gauss–Seidel and plain shooting only ever add
        // non-negative amounts to every B_e, approaching B* from below, so ε cannot increase.
        // Slack: 1e-9 relative, for the f64 rounding of sums over ~400 elements.
        let c = comparison();
        for m in [Method::Jacobi, Method::GaussSeidel, Method::Progressive] {
            let e = errors(c.run(m).unwrap());
            for (k, w) in e.windows(2).enumerate() {
                assert!(
                    w[1] <= w[0] * (1.0 + 1e-9),
                    "{m:?}: error rose from {} to {} at step {}",
                    w[0],
                    w[1],
                    k + 1
                );
            }
            assert!(e.len() > 3);
        }
        // Hence the table's times to 1e-2, 1e-3, 1e-4 increase along each run.
        for run in on_the_mesh(c) {
            let t: Vec<f64> = THRESHOLDS
                .iter()
                .map(|&th| run.first_below(th).unwrap().seconds)
                .collect();
            assert!(
                t[0] <= t[1] && t[1] <= t[2],
                "{}: {t:?}",
                run.method.label()
            );
        }
    }

    #[test]
    fn solvers_rank_as_the_theory_says() {
        let c = comparison();
        let steps = |m: Method, th: f64| c.run(m).unwrap().first_below(th).unwrap().iteration;
        // Gauss–Seidel uses each new value at once: fewer sweeps than Jacobi (about half).
        for th in THRESHOLDS {
            assert!(
                steps(Method::GaussSeidel, th) < steps(Method::Jacobi, th),
                "at {th}"
            );
        }
        // Mild overshooting (ω = 1.1) saves shots over plain shooting at every threshold.
        for th in THRESHOLDS {
            assert!(
                steps(Method::ProgressiveOvershoot(1.1), th) < steps(Method::Progressive, th),
                "at {th}"
            );
        }
        // The ambient term brings early partial solutions closer: after 8 and 16 shots its
        // displayed error is below the plain partial solution's.
        let plain = errors(c.run(Method::Progressive).unwrap());
        let ambient = errors(c.run(Method::ProgressiveAmbient).unwrap());
        for shots in [0, 8, 16] {
            assert!(
                ambient[shots] < plain[shots],
                "after {shots} shots: {} vs {}",
                ambient[shots],
                plain[shots]
            );
        }
    }

    #[test]
    fn table_and_plots_are_written_atomically() {
        let c = comparison();
        let dir = tempfile::tempdir().unwrap();
        c.write(dir.path()).unwrap();
        let mut names: Vec<String> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        names.sort();
        assert_eq!(
            names,
            [
                "comparison.json",
                "convergence.png",
                "convergence.svg",
                "table.md"
            ],
            "no temporary files left"
        );
        let table = std::fs::read_to_string(dir.path().join("table.md")).unwrap();
        for run in &c.runs {
            assert!(
                table.contains(&format!("| {} |", run.method.label())),
                "{table}"
            );
        }
        assert!(table.contains("ε ≤ 1e-4"));
        let png = image::open(dir.path().join("convergence.png")).unwrap();
        assert_eq!((png.width(), png.height()), PLOT_SIZE);
        // Not blank: the lines are drawn in colour.
        let rgb = png.to_rgb8();
        let green = Method::Progressive.colour();
        assert!(
            rgb.pixels()
                .filter(|p| p.0 == [green.0, green.1, green.2])
                .count()
                > 100
        );
        let svg = std::fs::read_to_string(dir.path().join("convergence.svg")).unwrap();
        assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
        assert!(svg.contains("Gauss–Seidel") && svg.contains("solver time (s, log scale)"));
        assert!(svg.contains(&Method::Hierarchical.label()));
        // The hierarchical series in the table's own section and in the JSON, point by point.
        assert!(table.contains("## Hierarchical: accuracy against time"));
        for p in &c.hierarchical {
            assert!(
                table.contains(&format!("| {} | {} |", p.epsilon, p.leaves)),
                "{table}"
            );
        }
        let json: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(dir.path().join("comparison.json")).unwrap(),
        )
        .unwrap();
        assert_eq!(json["runs"].as_array().unwrap().len(), c.runs.len());
        let series = json["hierarchical"].as_array().unwrap();
        assert_eq!(series.len(), c.hierarchical.len());
        for (j, p) in series.iter().zip(&c.hierarchical) {
            assert_eq!(j["epsilon"].as_f64(), Some(p.epsilon));
            assert_eq!(j["error"].as_f64(), Some(p.error));
        }
        assert_eq!(json["runs"][6]["error"], "per-object");
    }

    #[test]
    fn hierarchical_error_falls_as_its_tolerance_shrinks() {
        let c = comparison();
        let run = c
            .run(Method::Hierarchical)
            .expect("the hierarchical series");
        let epsilons: Vec<f64> = c.hierarchical.iter().map(|p| p.epsilon).collect();
        assert_eq!(epsilons, [0.08, 0.04, 0.02]);
        assert_eq!(run.samples.len(), 3);
        for (s, p) in run.samples.iter().zip(&c.hierarchical) {
            assert_eq!(
                (s.seconds, s.error, s.iteration),
                (p.seconds, p.error, p.iterations)
            );
            assert!(p.seconds > 0.0 && p.iterations > 0);
        }
        // A smaller tolerance refines more links, down to more leaves, and costs more time.
        for w in c.hierarchical.windows(2) {
            assert!(w[1].leaves > w[0].leaves, "{w:?}");
        }
        // ... and lands closer to B* per object. Measured (release, this mesh): ε_obj =
        // 2.5 %, 1.8 %, 1.1 %; against Mitsuba (cornell_reference.json) the same solves are
        // 1.9 %, 1.2 %, 0.6 % off and the 400-element B* itself 0.9 %, which is why ε = 0.01
        // (0.96 % here) is left out: it is at the reference's own error, where the order of
        // two nearby values would be noise. Each halving must gain at least 10 % (measured
        // 27 % and 41 %; since wide receiving clusters link uniformly: 1.0 % at ε = 0.08, 0.53 %
        // at 0.02),
        // and the default ε lands within 2 %, the per-polygon mark.
        for w in c.hierarchical.windows(2) {
            assert!(w[1].error < 0.9 * w[0].error, "{w:?}");
        }
        let fine = c.hierarchical[2].error;
        assert!(fine < 0.02, "{fine}");
    }

    #[test]
    fn per_object_error_of_scaled_reflection_is_the_scale() {
        // Closed form: B = E + (1 + δ)(B* − E) with B* ≥ E gives ε_obj = δ exactly (every
        // object's mean reflected part grows by δ), whatever the mesh; B* itself gives 0.
        let mesh = mesh();
        let settings = SolveSettings {
            mesh: MeshOptions {
                elements: 400,
                ..Default::default()
            },
            solve: SolveOptions {
                solver: SolverKind::GaussSeidel,
                ..Default::default()
            },
            ..Default::default()
        };
        let solved = solve_scene(scene(), &settings, &NoProgress).unwrap();
        assert_eq!(solved.mesh.len(), mesh.len());
        let measure = ObjectMeasure::new("cornell", &solved.mesh, &solved.solution);
        let report = |b: Vec<[f64; 3]>| {
            let mut solution = solved.solution.clone();
            solution.radiosity = b;
            Report::new("cornell", &solved.mesh, &solution, "")
        };
        let same = measure
            .error(&report(solved.solution.radiosity.clone()))
            .unwrap();
        assert!(same.abs() < 1e-15, "{same}");
        let e = radiosity::solve::exitance(&solved.mesh);
        let delta = 0.01;
        let scaled: Vec<[f64; 3]> = solved
            .solution
            .radiosity
            .iter()
            .zip(&e)
            .map(|(b, e)| std::array::from_fn(|c| e[c] + (1.0 + delta) * (b[c] - e[c])))
            .collect();
        let got = measure.error(&report(scaled)).unwrap();
        // f64 rounding over ~400 elements and 20 objects.
        assert!((got - delta).abs() < 1e-12, "{got}");
    }

    #[test]
    fn without_room_for_the_lu_the_reference_is_a_converged_gauss_seidel() {
        let mesh = mesh();
        let (n, m) = (mesh.len() as u64, mesh.patches.len() as u64);
        // Room for the matrix and its column copy, but not for the dense LU's 40 bytes per
        // patch pair.
        let limit = 2 * n * m * 4 + 30 * m * m;
        let c = run_with(&CompareOptions {
            memory_limit: limit,
            hierarchical_solves: 0,
            ..Default::default()
        })
        .unwrap();
        assert!(c.run(Method::Hierarchical).is_none() && c.hierarchical.is_empty());
        assert!(
            matches!(c.reference, Reference::GaussSeidel { residual, .. } if residual <= 1e-12),
            "{:?}",
            c.reference
        );
        let direct = c.run(Method::Direct).unwrap();
        assert!(
            direct.samples.is_empty() && direct.note.as_deref().unwrap().starts_with("skipped")
        );
        // The same answer as the direct reference: the runs match the direct comparison's.
        let jacobi = |c: &Comparison| {
            c.run(Method::Jacobi)
                .unwrap()
                .first_below(1e-3)
                .unwrap()
                .iteration
        };
        assert_eq!(jacobi(&c), jacobi(comparison()));
        assert!(c.table_markdown().contains("skipped"));

        let err = run_with(&CompareOptions {
            memory_limit: 1 << 10,
            ..Default::default()
        })
        .err()
        .unwrap();
        assert!(matches!(err, CompareError::OutOfMemory { .. }));
        assert!(err.to_string().contains("--elements"));
    }
}
