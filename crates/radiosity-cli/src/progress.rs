//! Progress on stderr (indicatif): a bar per stage (meshing, form factors) and, for the
//! solver, a bar over the quantity that converges — the unshot fraction or the residual,
//! from its start to the tolerance in log space — with a rate and an ETA from its recent
//! fall ([`ConvergenceEta`]). Each finished stage leaves one line with its time. Hidden when
//! stderr is not a terminal or with `--quiet`.

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use radiosity::progress::{ConvergenceEta, Progress};
use radiosity::solve::{Flow, Observer, Step, StepKind};
use std::io::IsTerminal;
use std::sync::Mutex;
use std::time::Instant;

/// Resolution of the solver bar (per mille of the log-space progress).
const SOLVER_BAR: u64 = 1000;

struct Stage {
    bar: ProgressBar,
    name: String,
    started: Instant,
}

struct SolverState {
    bar: ProgressBar,
    eta: ConvergenceEta,
    started: Instant,
    last_draw: Instant,
}

/// Progress bars for the stages and the solver.
pub struct Bars {
    enabled: bool,
    stage: Mutex<Option<Stage>>,
    solver: Mutex<Option<SolverState>>,
}

impl Bars {
    /// Bars on stderr, unless `quiet` or stderr is not a terminal.
    pub fn new(quiet: bool) -> Self {
        Self {
            enabled: !quiet && std::io::stderr().is_terminal(),
            stage: Mutex::new(None),
            solver: Mutex::new(None),
        }
    }

    fn finish_solver(&self) {
        if let Ok(mut slot) = self.solver.lock() {
            if let Some(s) = slot.take() {
                s.bar.finish_and_clear();
            }
        }
    }
}

impl Progress for Bars {
    fn start(&self, stage: &str, total: u64) {
        if !self.enabled {
            return;
        }
        let bar = ProgressBar::with_draw_target(Some(total), ProgressDrawTarget::stderr());
        bar.set_style(
            ProgressStyle::with_template(
                "{prefix:>14} [{bar:30}] {pos}/{len} {msg} ({elapsed}, eta {eta})",
            )
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
        );
        bar.set_prefix(stage.to_string());
        if let Ok(mut slot) = self.stage.lock() {
            *slot = Some(Stage {
                bar,
                name: stage.to_string(),
                started: Instant::now(),
            });
        }
    }

    fn inc(&self, n: u64) {
        if let Ok(slot) = self.stage.lock() {
            if let Some(s) = slot.as_ref() {
                s.bar.inc(n);
            }
        }
    }

    fn message(&self, text: &str) {
        if let Ok(slot) = self.stage.lock() {
            if let Some(s) = slot.as_ref() {
                s.bar.set_message(text.to_string());
            }
        }
    }

    fn finish(&self) {
        if let Ok(mut slot) = self.stage.lock() {
            if let Some(s) = slot.take() {
                s.bar.finish_and_clear();
                eprintln!(
                    "{:>14}: {} in {:.2} s",
                    s.name,
                    s.bar.position(),
                    s.started.elapsed().as_secs_f64()
                );
            }
        }
    }
}

impl Observer for &Bars {
    fn step(&mut self, step: &Step<'_>) -> Flow {
        if !self.enabled {
            return Flow::Continue;
        }
        let Ok(mut slot) = self.solver.lock() else {
            return Flow::Continue;
        };
        if step.kind == StepKind::Start || slot.is_none() {
            if let Some(old) = slot.take() {
                old.bar.finish_and_clear();
            }
            let bar = ProgressBar::with_draw_target(Some(SOLVER_BAR), ProgressDrawTarget::stderr());
            bar.set_style(
                ProgressStyle::with_template("{prefix:>14} [{bar:30}] {msg}")
                    .unwrap_or_else(|_| ProgressStyle::default_bar())
                    .progress_chars("=> "),
            );
            bar.set_prefix(step.solver.name().to_string());
            *slot = Some(SolverState {
                bar,
                eta: ConvergenceEta::new(step.tolerance),
                started: Instant::now(),
                last_draw: Instant::now(),
            });
        }
        let Some(s) = slot.as_mut() else {
            return Flow::Continue;
        };
        s.eta.update(step.elapsed, step.residual);
        // A few redraws per second at most.
        if s.last_draw.elapsed().as_secs_f64() < 0.1 && step.kind != StepKind::Start {
            return Flow::Continue;
        }
        s.last_draw = Instant::now();
        let (quantity, unit) = match step.kind {
            StepKind::Shot => ("unshot", "shots"),
            _ => ("change", "iterations"),
        };
        let elapsed = s.started.elapsed().as_secs_f64().max(1e-9);
        let rate = step.index as f64 / elapsed;
        let eta = s.eta.eta().map_or("—".to_string(), |t| format!("{t:.1} s"));
        s.bar
            .set_position((s.eta.fraction() * SOLVER_BAR as f64) as u64);
        s.bar.set_message(format!(
            "{quantity} {:.2e} → {:.0e}, {} {unit} ({rate:.0}/s), {elapsed:.1} s, eta {eta}",
            step.residual, step.tolerance, step.index
        ));
        Flow::Continue
    }
}

impl Drop for Bars {
    fn drop(&mut self) {
        self.finish_solver();
    }
}
