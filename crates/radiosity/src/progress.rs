//! Progress reporting from long library stages to whoever is watching (the CLI's bars).

/// Receives progress from long-running stages. Implementations must be cheap and thread-safe.
pub trait Progress: Sync {
    /// A stage with `total` steps begins (0: how many is not known ahead, as for the
    /// hierarchical solver's linking stages; the steps are still counted by `inc`).
    fn start(&self, stage: &str, total: u64);
    /// `n` more steps are done.
    fn inc(&self, n: u64);
    /// Replaces the stage's message (e.g. the current residual).
    fn message(&self, _text: &str) {}
    /// The stage is finished.
    fn finish(&self);
}

/// Reports nothing.
pub struct NoProgress;

impl Progress for NoProgress {
    fn start(&self, _stage: &str, _total: u64) {}
    fn inc(&self, _n: u64) {}
    fn finish(&self) {}
}

/// Estimates the time a solver needs to bring a converging quantity (a residual, an unshot
/// fraction) down to its tolerance, from how fast ln r has been falling recently.
///
/// Progress is measured in log space, f = ln(r₀/r) / ln(r₀/tol) ∈ [0, 1] (each decade
/// counts the same), and the time left is ln(r/tol) divided by the rate at which ln r fell
/// over the recent window: the last third of the elapsed time, so that a rate that slows
/// down as the solve goes on (progressive refinement's) is followed rather than averaged
/// away.
#[derive(Debug, Clone)]
pub struct ConvergenceEta {
    tolerance: f64,
    first: Option<(f64, f64)>,
    history: std::collections::VecDeque<(f64, f64)>,
}

impl ConvergenceEta {
    /// An estimator for a quantity that stops at `tolerance` (> 0).
    pub fn new(tolerance: f64) -> Self {
        Self {
            tolerance: tolerance.max(f64::MIN_POSITIVE),
            first: None,
            history: std::collections::VecDeque::new(),
        }
    }

    /// Moves the tolerance (a solver whose stopping rule is not on the quantity itself, like
    /// progressive refinement's, reports where it expects to stop as it goes: see
    /// [`crate::solve::Step::tolerance`]).
    pub fn retarget(&mut self, tolerance: f64) {
        self.tolerance = tolerance.max(f64::MIN_POSITIVE);
    }

    /// Records the quantity `r` at `seconds` since the start.
    pub fn update(&mut self, seconds: f64, r: f64) {
        if !(r.is_finite() && r > 0.0) {
            return;
        }
        let sample = (seconds, r.ln());
        if self.first.is_none() {
            self.first = Some(sample);
        }
        self.history.push_back(sample);
        // Keep the window: samples within the last third of the elapsed time, at least two.
        let horizon = seconds - (seconds - self.first.map_or(0.0, |f| f.0)) / 3.0;
        while self.history.len() > 2 && self.history[1].0 <= horizon {
            self.history.pop_front();
        }
    }

    /// The fraction of the way done, in log space, 0 to 1.
    pub fn fraction(&self) -> f64 {
        match (self.first, self.history.back()) {
            (Some((_, l0)), Some(&(_, l))) => {
                let total = l0 - self.tolerance.ln();
                if total <= 0.0 {
                    1.0
                } else {
                    ((l0 - l) / total).clamp(0.0, 1.0)
                }
            }
            _ => 0.0,
        }
    }

    /// Seconds left, if the quantity has been falling.
    pub fn eta(&self) -> Option<f64> {
        let (&(t0, l0), &(t1, l1)) = (self.history.front()?, self.history.back()?);
        let rate = (l0 - l1) / (t1 - t0);
        if !(rate > 0.0 && rate.is_finite()) {
            return None;
        }
        Some(((l1 - self.tolerance.ln()) / rate).max(0.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eta_is_exact_for_geometric_convergence() {
        // r = 0.5^t: ln r falls by ln 2 per second; from r = 2^-3 to 2^-10 takes 7 s.
        let mut eta = ConvergenceEta::new(2f64.powi(-10));
        for k in 0..=3 {
            eta.update(k as f64, 0.5f64.powi(k));
        }
        assert!((eta.eta().unwrap() - 7.0).abs() < 1e-9);
        assert!((eta.fraction() - 0.3).abs() < 1e-12);
        // Not falling: no estimate.
        let mut flat = ConvergenceEta::new(1e-3);
        flat.update(0.0, 0.5);
        flat.update(1.0, 0.5);
        assert!(flat.eta().is_none());
    }

    /// The worst factor by which the ETA is off (predicted ÷ actual time left, or its
    /// inverse) after the first 10 % of a solve in which ln r falls at `rate(t)` per second,
    /// sampled every 10 ms, to r = 10⁻⁶; both times floored at 0.1 s (the resolution a bar
    /// shows).
    fn worst_ratio(rate: impl Fn(f64) -> f64) -> f64 {
        let (tolerance, dt) = (1e-6f64, 0.01);
        let mut samples = vec![(0.0, 0.0)];
        let (mut t, mut ln_r) = (0.0, 0.0);
        while ln_r > tolerance.ln() {
            ln_r -= rate(t) * dt;
            t += dt;
            samples.push((t, ln_r));
        }
        let total = t;
        let mut eta = ConvergenceEta::new(tolerance);
        let mut worst: f64 = 1.0;
        for (t, ln_r) in samples {
            eta.update(t, ln_r.exp());
            let left = total - t;
            if t < 0.1 * total || left <= 0.0 {
                continue;
            }
            let ratio = eta.eta().unwrap().max(0.1) / left.max(0.1);
            worst = worst.max(ratio).max(1.0 / ratio);
        }
        worst
    }

    #[test]
    fn eta_is_within_3x_after_10_percent_for_geometric_and_slowing_convergence() {
        // Geometric (a stationary iteration at a steady cost per sweep): nearly exact.
        assert!(worst_ratio(|_| 1.0) < 1.1);
        // The rate halving every 20 s or 40 s (over a solve of 16–19 s): the window of the
        // last third of the time lags behind it, but by less than 3×.
        for half_life in [20.0, 40.0] {
            let worst = worst_ratio(|t| 0.5f64.powf(t / half_life));
            assert!(worst <= 3.0, "half-life {half_life} s: off by {worst:.2}×");
        }
    }

    #[test]
    fn retarget_moves_the_end_point() {
        // r = e^{−t}: from r = e^{−2}, 10⁻³ is ln(e^{−2}/10⁻³) s away, 10⁻⁵ further.
        let mut eta = ConvergenceEta::new(1e-3);
        for k in 0..=20 {
            let t = k as f64 * 0.1;
            eta.update(t, (-t).exp());
        }
        let to = |tol: f64| ((-2.0f64).exp() / tol).ln();
        assert!((eta.eta().unwrap() - to(1e-3)).abs() < 1e-9);
        eta.retarget(1e-5);
        assert!((eta.eta().unwrap() - to(1e-5)).abs() < 1e-9);
    }
}
