//! The hierarchical solver: refine the links of the hierarchical coupling, iterate, refine
//! again with the radiosities now known, until the links are right for the final tolerance.
//!
//! Multigridding after Hanrahan, Salzman & Aupperle (1991) and Sillion & Drettakis (1995):
//! the link error threshold starts at 4 ε and halves each stage down to ε; each stage
//! refines every link whose error in power exceeds the stage's threshold (with the
//! radiosities of the previous stage, starting from B = E, so the first stage links from the
//! emitters), then runs Jacobi with push–pull from the previous radiosities. The last stage
//! iterates to the solver tolerance.

use super::{
    exitance, iterate_from, non_negative, reflect, Flow, Observer, Solution, SolveOptions,
    SolverKind, Step, StepKind,
};
use crate::coupling::hierarchical::{Hierarchical, HierarchicalError, HierarchicalOptions};
use crate::coupling::Coupling;
use crate::formfactor::FormFactorMethod;
use crate::mesh::Mesh;
use crate::progress::{LinkingEta, Progress};
use crate::scene::Scene;

/// What the hierarchical solve produced.
pub struct HierarchicalSolution {
    /// The leaves of the refined hierarchy.
    pub mesh: Mesh,
    /// Radiosity and irradiance per leaf.
    pub solution: Solution,
    /// Links at the end.
    pub links: usize,
    /// Nodes of the hierarchy at the end.
    pub nodes: usize,
    /// The hierarchy's largest estimated memory, bytes ([`Hierarchical::largest_bytes`]):
    /// what the memory limit is checked against.
    pub bytes: u64,
    /// Whether refinement stopped at the memory limit.
    pub capped: bool,
    /// Links accepted although their error exceeded the threshold (minimum area reached).
    pub forced: usize,
    /// Objects with elements that gathered more than their hemisphere, scaled down, and how
    /// many ([`Hierarchical::overfull_objects`]).
    pub overfull: Vec<(String, usize)>,
}

/// Stages of the threshold schedule: 4 ε, 2 ε, ε. Every stage re-examines the links,
/// rebuilds the leaf mesh and iterates, and the early stages' links mostly split again
/// later. (Five before, from 16 ε. Measured 2026-12-07, alternated on this 2-core machine:
/// the Cornell box's solve, median of 30, 0.174 against 0.189 s, 73,073 links against
/// 72,898, its error against Mitsuba the same (mean 0.78 %, worst 1.82 %, the short block's
/// side facing the green wall); the furnished room of 1000 objects at ε = 0.02 11.6–11.9
/// against 12.5–12.6 s, 1,745 k links against 1,725 k, per object against its solve at
/// ε = 0.005 (area-weighted mean, 95th percentile, worst) 0.366 / 0.974 / 5.64 % against
/// 0.368 / 0.948 / 5.65 %; but the room of 10,000 objects 95.8 against 94.2 s (one run
/// each) with 14.44 M links against 13.17 M and a peak of 1458 against 1403 MB. Two stages
/// took the Cornell box to 0.168 s but its short block's front to 3.7 % against Mitsuba;
/// 16 ε, 4 ε, ε gave 0.181 s and 1.85 %, and in the room of 10,000 objects 14.07 M links.)
const STAGES: u32 = 3;

/// The intermediate stages iterate to this many times the solver's tolerance (at most
/// [`STAGE_TOLERANCE_CAP`]): their radiosities only set the next refinement's thresholds
/// (ε of each receiver's irradiance), and an error of 3 % in them (at the default 1e-3)
/// moves a threshold by 3 %, small against the factor 2 between the stages. Measured
/// against 10 (1 % before): the Cornell box 26 iterations instead of 33, its objects
/// within 8.4e-5 of each other (against Mitsuba, the lamp left out: mean 0.81 %, worst
/// 1.82 % both); the furnished room of 300 objects at ε = 0.02 36 instead of 42, 675,132
/// links instead of 675,133, per-object error against the room at ε = 0.005 (area mean,
/// p95, worst) 0.307 / 1.010 / 1.746 % instead of 0.307 / 1.005 / 1.748 %.
const STAGE_TOLERANCE_FACTOR: f64 = 30.0;

/// The loosest tolerance of an intermediate stage.
const STAGE_TOLERANCE_CAP: f64 = 0.05;

/// The most iterations an intermediate stage takes (from the previous stage's radiosities;
/// the first from B = E), for the same reason. Measured against no cap (after the factor
/// 30 above): the Cornell box 20 iterations instead of 26, the same 72,898 links, its error
/// against Mitsuba 0.81 % mean and 1.82 % worst both; at ε = 0.02 the furnished room of 300
/// objects 24 instead of 36, 675,059 links instead of 675,132, its error against its
/// ε = 0.005 solve (area mean, p95, worst) 0.308 / 1.006 / 1.745 % against 0.307 / 1.010 /
/// 1.746 %, and the room of 1000 objects 24 instead of 34, 0.368 / 1.280 / 5.660 % against
/// 0.368 / 1.283 / 5.661 %, 3 % less CPU. (Three: the Cornell box 18 iterations, worst
/// 1.82 %; two: 18, worst 1.85 %, the later stages then iterating more.) Where a scene
/// converges slowly an intermediate stage's radiosities come out low, but a link's error
/// (δ B_q) and its threshold (ε H_p) scale with them alike, and the final stage iterates to
/// the solver's own tolerance.
const STAGE_ITERATIONS: usize = 4;

/// Solves `scene` hierarchically with the form-factor kernel of `method`. The refinement of
/// each stage is reported to `progress` as the stage "linking" with no total (how many
/// candidate links a stage examines is not known ahead), its message the stage, ε, the
/// links so far and, from the second stage on, the linking time left as [`LinkingEta`]
/// estimates it; the iterations go to `observer` as for the other solvers.
pub fn solve(
    scene: &Scene,
    method: FormFactorMethod,
    hierarchy: HierarchicalOptions,
    options: &SolveOptions,
    observer: &mut dyn Observer,
    progress: &dyn Progress,
) -> Result<HierarchicalSolution, HierarchicalError> {
    let started = std::time::Instant::now();
    let mut h = Hierarchical::new(scene, method.kernel(), hierarchy)?;
    // Before any solve: the emitters' radiosity, and as irradiance the mean the emitted
    // power would give (the oracle's scale for every surface).
    let b = exitance(h.mesh());
    let guess = vec![
        [h.emitted_power() / h.mesh().elements.iter().map(|e| e.area).sum::<f64>(); 3];
        b.len()
    ];
    h.set_solution(&b, &guess);
    drop((b, guess));
    let mut solution = None;
    let mut carried = Watch {
        inner: observer,
        offset: 0.0,
        iterations: 0,
        stopped: false,
        observer_seconds: 0.0,
    };
    // The linking's ETA counts the linking alone (the iterations between its stages are a
    // few sweeps each and show their own).
    let mut linking_eta = LinkingEta::new(STAGES);
    let mut linking_seconds = 0.0;
    for stage in (0..STAGES).rev() {
        let epsilon = hierarchy.epsilon * f64::from(1u32 << stage);
        progress.start("linking", 0);
        let label = format!("stage {} of {STAGES}, ε {epsilon:.3}", STAGES - stage);
        progress.message(&label);
        let stage_started = std::time::Instant::now();
        linking_eta.start_stage(linking_seconds);
        // Neither the last stage's solution nor its leaf mesh is read by the refinement, and
        // the remesh after it replaces both: held through it, they were 1.2 GiB of what the
        // room of 10⁵ objects held while linking.
        drop(solution.take());
        h.release_leaf_mesh();
        let mut links_kept = h.link_count();
        h.refine_reporting(epsilon, &mut |step| {
            let now = linking_seconds + stage_started.elapsed().as_secs_f64();
            linking_eta.advance(
                step.round,
                step.round_candidates as u64,
                step.decided as u64,
                now,
            );
            links_kept = step.links;
            progress.inc(step.decided as u64);
            progress.message(&match linking_eta.eta(now) {
                Some(eta) => format!("{label}, {links_kept} links kept, linking eta {eta:.1} s"),
                None => format!("{label}, {links_kept} links kept"),
            });
        });
        linking_seconds += stage_started.elapsed().as_secs_f64();
        linking_eta.finish_stage(linking_seconds);
        progress.message(&format!("{label}, {links_kept} links kept"));
        progress.finish();
        // The final mesh is balanced in full; the others only guide the next refinement.
        let b = if stage == 0 {
            h.finish_refining(scene)
        } else {
            h.remesh_for_refining(scene)
        };
        // Intermediate stages only need radiosities good enough for the next refinement.
        let stage_options = SolveOptions {
            tolerance: if stage == 0 {
                options.tolerance
            } else {
                (options.tolerance * STAGE_TOLERANCE_FACTOR).min(STAGE_TOLERANCE_CAP)
            },
            max_iterations: if stage == 0 {
                options.max_iterations
            } else {
                options.max_iterations.min(STAGE_ITERATIONS)
            },
            ..*options
        };
        let coupling = &h;
        let mesh = coupling.mesh();
        // The steps' times count from the start of the solve.
        carried.offset = started.elapsed().as_secs_f64() - carried.observer_seconds;
        let s = iterate_from(
            coupling,
            b,
            SolverKind::Hierarchical,
            &stage_options,
            &mut carried,
            &mut |x| *x = reflect(mesh, &non_negative(coupling.gather(x))),
        );
        carried.iterations += s.stats.iterations;
        // The next refinement's oracle (none after the last stage).
        if stage > 0 {
            h.set_solution(&s.radiosity, &s.irradiance);
        }
        solution = Some(s);
        if carried.stopped {
            break;
        }
    }
    let mut solution = solution.unwrap_or_else(|| {
        super::solution_from(
            &h,
            exitance(h.mesh()),
            super::SolveStats {
                solver: SolverKind::Hierarchical,
                iterations: 0,
                residual: f64::INFINITY,
                seconds: 0.0,
                form_factor_seconds: 0.0,
            },
        )
    });
    solution.stats.solver = SolverKind::Hierarchical;
    solution.stats.iterations = carried.iterations;
    solution.stats.form_factor_seconds = h.form_factor_seconds();
    // The whole solve's wall-clock time but the observer's: the hierarchy's construction,
    // the refinement, the leaf meshes rebuilt between stages and the iterations. (The
    // refinement and the iterations alone before, which left out 0.02 s of the Cornell
    // box's 0.21 s.)
    solution.stats.seconds = (started.elapsed().as_secs_f64() - carried.observer_seconds).max(0.0);
    Ok(HierarchicalSolution {
        links: h.link_count(),
        nodes: h.node_count(),
        bytes: h.largest_bytes(),
        capped: h.capped,
        forced: h.forced,
        overfull: h.overfull_objects(),
        solution,
        mesh: h.into_mesh(),
    })
}

/// Passes steps on with times and counts carried across the stages.
struct Watch<'o> {
    inner: &'o mut dyn Observer,
    offset: f64,
    iterations: usize,
    stopped: bool,
    /// Seconds spent in the observer, left out of the solve's time.
    observer_seconds: f64,
}

impl Observer for Watch<'_> {
    fn step(&mut self, step: &Step<'_>) -> Flow {
        let carried = Step {
            index: step.index + self.iterations,
            elapsed: step.elapsed + self.offset,
            kind: if step.kind == StepKind::Start && self.iterations > 0 {
                StepKind::Iteration
            } else {
                step.kind
            },
            ..*step
        };
        let called = std::time::Instant::now();
        let flow = self.inner.step(&carried);
        self.observer_seconds += called.elapsed().as_secs_f64();
        self.stopped |= flow == Flow::Stop;
        flow
    }
}
