//! Progress on stderr (indicatif): a bar per stage (meshing, form factors) and, for the
//! solver, a bar over the quantity that converges — the unshot fraction or the residual,
//! from its start to the tolerance in log space — with a rate and an ETA: from its recent
//! fall for the iterative solvers ([`ConvergenceEta`]), from the fall per shot and the cost
//! of first and repeated shots for progressive refinement ([`ShotEta`]). Each finished stage leaves one line with its time. Hidden when
//! stderr is not a terminal or with `--quiet`.
//!
//! For measuring the ETA: with the environment variable `RADIOSITY_PROGRESS_LOG=FILE` every
//! solver step is also written to FILE as one line `elapsed_s step residual tolerance eta_s`
//! (solver seconds; `eta_s` is `-` while there is no estimate), terminal or not.

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use radiosity::progress::{ConvergenceEta, Progress};
use radiosity::solve::{Flow, Observer, SolverKind, Step, StepKind};
use std::collections::VecDeque;
use std::io::{IsTerminal, Write};
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
    /// The `RADIOSITY_PROGRESS_LOG` trace, if asked for.
    log: Option<std::io::BufWriter<std::fs::File>>,
    eta: ConvergenceEta,
    shots: ShotEta,
    started: Instant,
    last_draw: Instant,
}

/// Progress bars for the stages and the solver.
pub struct Bars {
    enabled: bool,
    /// Where to trace the solver's ETA (`RADIOSITY_PROGRESS_LOG`).
    log: Option<std::path::PathBuf>,
    stage: Mutex<Option<Stage>>,
    solver: Mutex<Option<SolverState>>,
}

impl Bars {
    /// Bars on stderr, unless `quiet` or stderr is not a terminal.
    pub fn new(quiet: bool) -> Self {
        Self {
            enabled: !quiet && std::io::stderr().is_terminal(),
            log: std::env::var_os("RADIOSITY_PROGRESS_LOG").map(Into::into),
            stage: Mutex::new(None),
            solver: Mutex::new(None),
        }
    }

    fn finish_solver(&self) {
        if let Ok(mut slot) = self.solver.lock() {
            if let Some(mut s) = slot.take() {
                s.bar.finish_and_clear();
                if let Some(log) = s.log.as_mut() {
                    let _ = std::io::Write::flush(log);
                }
            }
        }
    }
}

impl Progress for Bars {
    fn start(&self, stage: &str, total: u64) {
        if !self.enabled {
            return;
        }
        // A stage whose amount of work is not known ahead (total 0) shows a spinner and
        // its count, with no ETA rather than a wrong one (the hierarchical solver's linking
        // puts its own estimate, from the stages it has run, in its message).
        let (length, template) = if total == 0 {
            (None, "{prefix:>14} {spinner} {pos} {msg} ({elapsed})")
        } else {
            (
                Some(total),
                "{prefix:>14} [{bar:30}] {pos}/{len} {msg} ({elapsed}, eta {eta})",
            )
        };
        let bar = ProgressBar::with_draw_target(length, ProgressDrawTarget::stderr());
        bar.set_style(
            ProgressStyle::with_template(template)
                .unwrap_or_else(|_| ProgressStyle::default_bar())
                .progress_chars("=> "),
        );
        if total == 0 {
            bar.enable_steady_tick(std::time::Duration::from_millis(200));
        }
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
                let message = s.bar.message();
                stderr_line!(
                    "{:>14}: {} in {:.2} s{}",
                    s.name,
                    s.bar.position(),
                    s.started.elapsed().as_secs_f64(),
                    if s.bar.length().is_none() && !message.is_empty() {
                        format!(" ({message})")
                    } else {
                        String::new()
                    }
                );
            }
        }
    }
}

impl Observer for &Bars {
    fn step(&mut self, step: &Step<'_>) -> Flow {
        if !self.enabled && self.log.is_none() {
            return Flow::Continue;
        }
        let Ok(mut slot) = self.solver.lock() else {
            return Flow::Continue;
        };
        if step.kind == StepKind::Start || slot.is_none() {
            let mut log = None;
            if let Some(mut old) = slot.take() {
                old.bar.finish_and_clear();
                log = old.log.take();
            }
            if log.is_none() {
                log = self.log.as_ref().and_then(|path| {
                    std::fs::File::create(path)
                        .ok()
                        .map(std::io::BufWriter::new)
                });
            }
            let target = if self.enabled {
                ProgressDrawTarget::stderr()
            } else {
                ProgressDrawTarget::hidden()
            };
            let bar = ProgressBar::with_draw_target(Some(SOLVER_BAR), target);
            bar.set_style(
                ProgressStyle::with_template("{prefix:>14} [{bar:30}] {msg}")
                    .unwrap_or_else(|_| ProgressStyle::default_bar())
                    .progress_chars("=> "),
            );
            bar.set_prefix(step.solver.name().to_string());
            *slot = Some(SolverState {
                bar,
                log,
                eta: ConvergenceEta::new(step.tolerance),
                shots: ShotEta::new(step.tolerance, step.mesh.patches.len()),
                started: Instant::now(),
                last_draw: Instant::now(),
            });
        }
        let Some(s) = slot.as_mut() else {
            return Flow::Continue;
        };
        s.eta.retarget(step.tolerance);
        s.eta.update(step.elapsed, step.residual);
        s.shots.update(step);
        let eta = if step.solver == SolverKind::Progressive {
            s.shots.eta()
        } else {
            s.eta.eta()
        };
        if let Some(log) = s.log.as_mut() {
            let shown = eta.map_or("-".to_string(), |t| format!("{t:.3}"));
            let _ = writeln!(
                log,
                "{:.4} {} {:.6e} {:.6e} {shown}",
                step.elapsed, step.index, step.residual, step.tolerance
            );
        }
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
        let eta = eta.map_or("—".to_string(), |t| format!("{t:.1} s"));
        // Not known before the first iteration of a solve (or of a hierarchical stage).
        let value = if step.residual.is_finite() {
            format!("{:.2e}", step.residual)
        } else {
            "—".to_string()
        };
        s.bar
            .set_position((s.eta.fraction() * SOLVER_BAR as f64) as u64);
        s.bar.set_message(format!(
            "{quantity} {value} → {:.0e}, {} {unit} ({rate:.0}/s), {elapsed:.1} s, eta {eta}",
            step.tolerance, step.index
        ));
        Flow::Continue
    }
}

/// The time progressive refinement has left, from two things it does at a steady pace.
///
/// 1. The unshot fraction falls geometrically *per shot* (ln r drops by about the same
///    amount each shot: 2.5–2.7·10⁻⁴ per shot through a whole 43k-element Cornell solve),
///    so the shots left are ln(r/tol) / λ, with λ measured over the last half of the shots
///    and tol the unshot fraction at which the solver expects its stopping rule to stop it
///    ([`Step::tolerance`]; the rule is on every element's error, and on the Cornell box it
///    stops near an unshot fraction of 4·10⁻⁵, not at the tolerance of 10⁻³ itself: aiming
///    at 10⁻³ showed an ETA of 0 s for the last 6 % of the solve).
/// 2. A shot costs much more the first time its patch shoots (its column of form factors is
///    computed, then cached) than later: 15–60 ms against 0.5–5 ms in that solve. A rate
///    from recent time alone therefore overestimated the time left 3–6 times. A shot is a
///    first shot when it takes more than a quarter of the mean first shot and fewer first
///    shots than patches have been seen; every other shot (repeats, recomputed columns,
///    the stopping rule's passes, a busy machine) goes into the mean cost of a repeat. The
///    time left is (first shots left) × (cost of a first shot) + (other shots left) × (cost
///    of a repeat), the first shots left being the patches that have not shot yet, but at
///    most the recent share of first shots times the shots left (a patch that receives no
///    light never shoots).
///
/// Measured on the built-in Cornell box, `solve --solver progressive --elements 40000`
/// (43,542 elements, 4,838 patches, 34,110 shots, 325 s of solver time on 2 shared cores),
/// with `RADIOSITY_PROGRESS_LOG`: after the first 10 % the ETA stayed within 0.66–1.71× of
/// the time actually left at every shot (times floored at the bar's 0.1 s); with 16,000
/// elements (14,337 shots, 69 s) within 0.40–2.44×. Before, aiming at the unshot fraction
/// 10⁻³, it read 0 s for the last 6 % (16 s) of the 40k solve; with the target fixed but the
/// old cost model (a share of expensive repeats once every patch had shot, which noise on a
/// busy machine inflated) it read up to 10× high near the end.
struct ShotEta {
    tolerance: f64,
    patches: usize,
    last_elapsed: f64,
    /// (shots, ln r), the last half of the shots.
    history: VecDeque<(usize, f64)>,
    /// Mean seconds of a first (column-computing) shot and of any other shot.
    miss_cost: Option<f64>,
    hit_cost: Option<f64>,
    /// First shots so far.
    misses: usize,
    /// Recent share of first shots among the shots (exponential average over about
    /// 1 / [`ShotEta::SHARE_ALPHA`] shots).
    first_share: f64,
}

impl ShotEta {
    /// Weight of the newest shot in the mean costs.
    const ALPHA: f64 = 0.02;
    /// Weight of the newest shot in the share of first shots.
    const SHARE_ALPHA: f64 = 0.005;
    /// A shot longer than this fraction of the mean first shot is a first shot.
    const FIRST_SHOT: f64 = 0.25;

    fn new(tolerance: f64, patches: usize) -> Self {
        Self {
            tolerance: tolerance.max(f64::MIN_POSITIVE),
            patches,
            last_elapsed: 0.0,
            history: VecDeque::new(),
            miss_cost: None,
            hit_cost: None,
            misses: 0,
            first_share: 1.0,
        }
    }

    fn average(slot: &mut Option<f64>, x: f64) {
        *slot = Some(slot.map_or(x, |m| m + Self::ALPHA * (x - m)));
    }

    fn update(&mut self, step: &Step<'_>) {
        self.observe(
            step.kind,
            step.index,
            step.elapsed,
            step.residual,
            step.tolerance,
        );
    }

    /// Records a step: its kind, the shots so far, the solver seconds so far, the unshot
    /// fraction and where the solver expects to stop it ([`Step::tolerance`]).
    fn observe(
        &mut self,
        kind: StepKind,
        index: usize,
        elapsed: f64,
        residual: f64,
        tolerance: f64,
    ) {
        self.tolerance = tolerance.max(f64::MIN_POSITIVE);
        let d = (elapsed - self.last_elapsed).max(0.0);
        self.last_elapsed = elapsed;
        if kind == StepKind::Shot {
            let first = self.misses < self.patches
                && self.miss_cost.is_none_or(|m| d > Self::FIRST_SHOT * m);
            if first {
                self.misses += 1;
                Self::average(&mut self.miss_cost, d);
            } else {
                Self::average(&mut self.hit_cost, d);
            }
            self.first_share += Self::SHARE_ALPHA * (f64::from(u8::from(first)) - self.first_share);
        }
        if residual.is_finite() && residual > 0.0 {
            self.history.push_back((index, residual.ln()));
            while self.history.len() > 2 && self.history[1].0 <= index / 2 {
                self.history.pop_front();
            }
        }
    }

    fn eta(&self) -> Option<f64> {
        let (&(k0, l0), &(k1, l1)) = (self.history.front()?, self.history.back()?);
        let lambda = (l0 - l1) / (k1 - k0) as f64;
        if !(lambda > 0.0 && lambda.is_finite()) {
            return None;
        }
        let shots = ((l1 - self.tolerance.ln()) / lambda).max(0.0);
        let unshot_patches = self.patches.saturating_sub(self.misses) as f64;
        let first = (shots * self.first_share).min(unshot_patches);
        let miss = self.miss_cost?;
        Some(first * miss + (shots - first) * self.hit_cost.unwrap_or(miss))
    }
}

impl Drop for Bars {
    fn drop(&mut self) {
        self.finish_solver();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The worst factor by which the ETA is off (predicted ÷ actual time left, or its
    /// inverse) after the first 10 % of a synthetic progressive solve: `patches` patches, a
    /// first shot costing 30 ms and any other 0.5 ms (the Cornell solve's orders of
    /// magnitude), patch first shots spread over the solve as 1 − exp(−k/κ) (Southwell picks
    /// the brightest patches again and again while dim ones wait), ln r falling by
    /// `lambda(k)` at shot k, and the stopping rule evaluated at every 16th shot. Both times
    /// are floored at 0.1 s, the resolution the bar shows them at.
    fn worst_ratio(patches: usize, kappa: f64, lambda: impl Fn(usize) -> f64) -> f64 {
        let tolerance: f64 = 1e-4;
        let (miss, hit) = (0.03, 0.0005);
        let mut steps = vec![(StepKind::Start, 0, 0.0, 1.0)];
        let (mut t, mut ln_r, mut k, mut shot_patches) = (0.0, 0.0, 0, 0);
        while !(k % 16 == 0 && ln_r <= tolerance.ln()) {
            assert!(
                k < 1_000_000,
                "the synthetic solve must reach its tolerance"
            );
            let due = (patches as f64 * (1.0 - (-((k + 1) as f64) / kappa).exp())) as usize + 1;
            let first = due > shot_patches && shot_patches < patches;
            shot_patches += usize::from(first);
            t += if first { miss } else { hit };
            ln_r -= lambda(k);
            k += 1;
            steps.push((StepKind::Shot, k, t, ln_r.exp()));
        }
        let total = t;
        let mut eta = ShotEta::new(tolerance, patches);
        let mut worst: f64 = 1.0;
        for (kind, k, t, r) in steps {
            eta.observe(kind, k, t, r, tolerance);
            let left = total - t;
            if t < 0.1 * total || left <= 0.0 {
                continue;
            }
            let predicted = eta
                .eta()
                .expect("an estimate once the unshot fraction falls");
            let ratio = predicted.max(0.1) / left.max(0.1);
            worst = worst.max(ratio).max(1.0 / ratio);
        }
        worst
    }

    #[test]
    fn shot_eta_is_within_3x_after_10_percent_for_geometric_convergence() {
        // ln r falls by 10⁻³ per shot: about 9,200 shots, 19 s. κ from 2 to 10 × the patch
        // count: from first shots all done early to some patches never shooting (those
        // must not count as work left).
        for kappa in [1000.0, 2500.0, 5000.0] {
            let worst = worst_ratio(500, kappa, |_| 1e-3);
            assert!(worst <= 3.0, "κ = {kappa}: off by {worst:.2}×");
        }
    }

    #[test]
    fn shot_eta_is_within_3x_after_10_percent_when_convergence_slows() {
        // The fall per shot halves every 8,000 shots (the total fall, 11.5, just exceeds the
        // 9.2 to the tolerance: ~18,500 shots, the rate falling to a fifth): late shots do
        // less than the recent ones the rate was measured on.
        for (kappa, half_life) in [(1000.0, 8000.0), (2500.0, 8000.0), (5000.0, 8000.0)] {
            let worst = worst_ratio(500, kappa, |k| 1e-3 * 0.5f64.powf(k as f64 / half_life));
            assert!(
                worst <= 3.0,
                "κ = {kappa}, half-life {half_life}: off by {worst:.2}×"
            );
        }
    }

    #[test]
    fn shot_eta_aims_at_the_tolerance_the_solver_reports() {
        // r = e^{−k/1000}, one cost per shot: the time left is exactly the shots to the
        // reported tolerance times 1 ms, whichever tolerance the solver reports.
        let mut eta = ShotEta::new(1e-3, 1);
        for k in 0..=2000usize {
            eta.observe(
                StepKind::Shot,
                k,
                k as f64 * 1e-3,
                (-(k as f64) / 1000.0).exp(),
                1e-3,
            );
        }
        // ln(e^{-2} / 10^{-3}) · 1000 shots · 1 ms.
        let expected = ((-2.0f64).exp() / 1e-3).ln();
        assert!((eta.eta().unwrap() - expected).abs() < 1e-6 * expected);
        eta.observe(StepKind::Shot, 2001, 2.001, (-2.001f64).exp(), 1e-5);
        let expected = ((-2.001f64).exp() / 1e-5).ln();
        assert!((eta.eta().unwrap() - expected).abs() < 1e-3 * expected);
    }
}
