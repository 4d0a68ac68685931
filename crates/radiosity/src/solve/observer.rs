//! Watching a solver converge: every solver reports each step to an [`Observer`], which may
//! look at the current radiosity and stop the solve.
//!
//! The time a solver reports ([`Step::elapsed`]) is its own work only: the time spent inside
//! observers (rendering a frame, measuring an error against a reference) is left out, so a
//! study that watches a solver measures the solver, not itself.

use super::SolverKind;
use crate::mesh::Mesh;
use std::time::{Duration, Instant};

/// What one step was.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StepKind {
    /// The state before the first step.
    Start,
    /// A Jacobi or Gauss–Seidel sweep, or a direct solve's refinement step.
    Iteration,
    /// A progressive shot.
    Shot,
}

/// One step of a solver, as an observer sees it.
#[derive(Clone, Copy)]
pub struct Step<'a> {
    /// The solver.
    pub solver: SolverKind,
    /// What the step was.
    pub kind: StepKind,
    /// Steps of this kind so far (0 at [`StepKind::Start`]).
    pub index: usize,
    /// The converging quantity: the relative change or residual of the iterative solvers,
    /// the unshot fraction of the emitted power for progressive refinement (dimensionless).
    pub residual: f64,
    /// The value of `residual` at which the solver stops. Progressive refinement stops on
    /// every element's estimated error, not on the unshot fraction it reports, so it gives
    /// the unshot fraction at which that rule is expected to stop it (from the rule's
    /// latest evaluation; it moves a little as the solve goes on).
    pub tolerance: f64,
    /// Seconds of solver work so far (form factors computed on the fly included; time in
    /// observers excluded).
    pub elapsed: f64,
    /// The mesh whose elements the values belong to.
    pub mesh: &'a Mesh,
    /// Radiosity per element now, W·m⁻².
    pub radiosity: &'a [[f64; 3]],
    /// Unshot radiosity per element (progressive refinement), W·m⁻².
    pub unshot: Option<&'a [[f64; 3]]>,
}

/// Whether a solver should go on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Flow {
    /// Keep going until the solver's own stopping rule.
    Continue,
    /// Stop now and return the current state.
    Stop,
}

/// Watches a solver's steps.
pub trait Observer {
    /// Called at the start and after every step.
    fn step(&mut self, step: &Step<'_>) -> Flow;
}

/// Watches nothing.
#[derive(Debug, Clone, Copy, Default)]
pub struct NoObserver;

impl Observer for NoObserver {
    fn step(&mut self, _step: &Step<'_>) -> Flow {
        Flow::Continue
    }
}

impl<F: FnMut(&Step<'_>) -> Flow> Observer for F {
    fn step(&mut self, step: &Step<'_>) -> Flow {
        self(step)
    }
}

/// A stopwatch that leaves out the time spent in observers, and can be paused between the
/// calls of a solver that is advanced piecewise.
#[derive(Debug)]
pub struct SolverClock {
    total: Duration,
    since: Option<Instant>,
}

impl Default for SolverClock {
    fn default() -> Self {
        Self::start()
    }
}

impl SolverClock {
    /// Starts now.
    pub fn start() -> Self {
        Self {
            total: Duration::ZERO,
            since: Some(Instant::now()),
        }
    }

    /// Stops counting until [`SolverClock::resume`].
    pub fn pause(&mut self) {
        if let Some(since) = self.since.take() {
            self.total += since.elapsed();
        }
    }

    /// Counts again.
    pub fn resume(&mut self) {
        if self.since.is_none() {
            self.since = Some(Instant::now());
        }
    }

    /// Solver seconds so far.
    pub fn seconds(&self) -> f64 {
        (self.total + self.since.map_or(Duration::ZERO, |s| s.elapsed())).as_secs_f64()
    }

    /// Calls the observer with a step built at the current time, excluding the call's time.
    pub fn report<'a>(
        &mut self,
        observer: &mut dyn Observer,
        make: impl FnOnce(f64) -> Step<'a>,
    ) -> Flow {
        let was_running = self.since.is_some();
        self.pause();
        let step = make(self.seconds());
        let flow = observer.step(&step);
        if was_running {
            self.resume();
        }
        flow
    }
}
