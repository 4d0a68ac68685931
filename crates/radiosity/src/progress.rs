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

/// Estimates the time left in the hierarchical solver's linking: every refinement stage
/// still to run, from the work of the stages run so far
/// ([`crate::solve::hierarchical`]: the link tolerance halves from one stage to the next).
///
/// A stage decides its candidate links in rounds: the links re-examined first, then the
/// children of every pair split in the round before. Its amount of work is not known ahead,
/// but its rounds follow one pattern: the second round about twice the first (most
/// re-examined links split), then each round smaller than the one before by a roughly
/// steady factor. So the candidates still to come in the current stage are
/// - in its first round, [`LinkingEta::FIRST_ROUND_SHARE`]⁻¹ times that round
///   ([`LinkingEta::FIRST_ROUND_SHARE_SECOND_STAGE`] in the second stage);
/// - later, once the last two rounds have each fallen, what the rounds so far continue to
///   as a geometric series at the slower of those two steps (at most
///   [`LinkingEta::MOST_DECAY`]); before that, [`LinkingEta::DEFAULT_DECAY`] and at least
///   what the first round's share says (the second stage's rounds can fall once and rise
///   again; taken at the last ratio after any fall, the ETA of the recorded Cornell box
///   below was off by up to 6.0 times, 2.45 now);
///
/// the first round at its own pace, the later ones at the seconds per candidate measured in
/// this stage's later rounds once a tenth of them is done (the previous stage's before);
/// and each later stage is taken to last
/// [`LinkingEta::STAGE_GROWTH`] times the one before. The first stage, which opens the
/// hierarchy from its root, has nothing to go by: no estimate until it ends.
///
/// How far off it is, on recorded linkings and on the solver's own: see the tests below and
/// the README's section on the hierarchical solver.
#[derive(Debug, Clone)]
pub struct LinkingEta {
    stages: u32,
    /// Stages finished: the seconds each took, and the seconds per candidate of its rounds
    /// after the first (see [`LinkingEta::later_rate`]).
    finished: Vec<(f64, Option<f64>)>,
    /// When the current stage started (seconds on the caller's clock).
    started: f64,
    /// The current stage's rounds so far (candidates each).
    rounds: Vec<u64>,
    /// Candidates decided in the current stage.
    decided: u64,
    /// When its second round began, and the candidates decided by then.
    second_round: Option<(f64, u64)>,
    /// When the last chunk was reported.
    last_report: f64,
}

impl LinkingEta {
    /// The share of a stage's candidates that its first round holds, from the third stage
    /// on: measured 0.14 to 0.19 in the last stage (the third of three) of the Cornell box
    /// and the furnished rooms of 30 and 300 objects at ε = 0.02 (0.06 to 0.20 from the
    /// third stage on when there were five).
    pub const FIRST_ROUND_SHARE: f64 = 1.0 / 6.0;
    /// The same in the second stage (the first to re-examine links): measured 0.025 to
    /// 0.062 in the same scenes (its rounds hardly fall at first: most links accepted from
    /// the emitters' light alone split once the light they reflect is known).
    pub const FIRST_ROUND_SHARE_SECOND_STAGE: f64 = 1.0 / 26.0;
    /// The ratio between successive rounds taken after a round that grew: measured 0.5 to
    /// 0.65 after the second round of the last stages of the rooms (0.4 to 0.85 in the
    /// Cornell box's).
    pub const DEFAULT_DECAY: f64 = 0.6;
    /// The largest ratio between successive rounds that a tail is extrapolated with (the
    /// second stages' rounds fall by 0.84 to 0.97 a round once they fall).
    pub const MOST_DECAY: f64 = 0.9;
    /// How much longer a stage takes than the one before, from the second on: the last
    /// stage against the second measured 0.71 to 0.77 times in the room of 300 objects, 0.79
    /// to 0.94 in the room of 30 and 1.30 to 1.42 in the Cornell box (three runs each), so
    /// 0.9 (1.1 to 2.6 between the later stages of five, with median 1.5, before the
    /// schedule had three).
    pub const STAGE_GROWTH: f64 = 0.9;

    /// An estimator for a linking of `stages` stages.
    pub fn new(stages: u32) -> Self {
        Self {
            stages,
            finished: Vec::new(),
            started: 0.0,
            rounds: Vec::new(),
            decided: 0,
            second_round: None,
            last_report: 0.0,
        }
    }

    /// A stage begins at `now` (seconds).
    pub fn start_stage(&mut self, now: f64) {
        self.started = now;
        self.rounds.clear();
        self.decided = 0;
        self.second_round = None;
        self.last_report = now;
    }

    /// At `now`, `decided` more candidates of round `round` (of `round_candidates`) of the
    /// current stage are decided (rounds counted from 0, reported in order).
    pub fn advance(&mut self, round: usize, round_candidates: u64, decided: u64, now: f64) {
        if round >= self.rounds.len() {
            if self.rounds.len() == 1 {
                // The second round's time counts from the first round's last report.
                self.second_round = Some((self.last_report, self.decided));
            }
            self.rounds.push(round_candidates);
        }
        self.decided += decided;
        self.last_report = now;
    }

    /// The current stage ends at `now`.
    pub fn finish_stage(&mut self, now: f64) {
        let rate = self.later_rate(now, 0.0);
        self.finished.push(((now - self.started).max(0.0), rate));
        self.start_stage(now);
    }

    /// The seconds per candidate of the current stage's rounds after the first, once at
    /// least `enough` of them are decided. The first round is mostly links re-examined,
    /// which keep their estimates and cast no rays: ten times cheaper or more.
    fn later_rate(&self, now: f64, enough: f64) -> Option<f64> {
        let (since, before) = self.second_round?;
        let n = self.decided.saturating_sub(before);
        (n > 0 && n as f64 >= enough).then(|| (now - since).max(0.0) / n as f64)
    }

    /// The candidates the current stage is expected to decide in all.
    fn expected_candidates(&self) -> f64 {
        let so_far: f64 = self.rounds.iter().map(|&r| r as f64).sum();
        let share = if self.finished.len() == 1 {
            Self::FIRST_ROUND_SHARE_SECOND_STAGE
        } else {
            Self::FIRST_ROUND_SHARE
        };
        let from_first = self.rounds.first().map_or(0.0, |&r| r as f64 / share);
        let expected = match self.rounds.as_slice() {
            [] => 0.0,
            [_] => from_first,
            [.., before, last] => {
                // Falling: the last two rounds each smaller than the one before (or the
                // first fall after the first round). One round smaller than the one before
                // is not yet a tail: the second stage's rounds rise again after it.
                let rounds = &self.rounds;
                let falling = rounds.len() == 2 && last < before
                    || rounds.len() > 2 && last < before && before < &rounds[rounds.len() - 3];
                let (before, last) = (*before as f64, *last as f64);
                if falling {
                    // At the slower of its last two steps.
                    let earlier = match rounds.len() {
                        2 => 0.0,
                        n => before / rounds[n - 3] as f64,
                    };
                    let ratio = (last / before).max(earlier).min(Self::MOST_DECAY);
                    so_far + last * ratio / (1.0 - ratio)
                } else {
                    // Still growing: at least what the first round's share says.
                    (so_far + last * Self::DEFAULT_DECAY / (1.0 - Self::DEFAULT_DECAY))
                        .max(from_first)
                }
            }
        };
        expected.max(self.decided as f64)
    }

    /// Seconds left until the last stage's linking ends, at `now`; `None` during the first
    /// stage (see above), while no stage has had a second round to time, or once every stage
    /// has finished.
    pub fn eta(&self, now: f64) -> Option<f64> {
        let stage = self.finished.len() as u32 + 1;
        if self.finished.is_empty() || stage > self.stages {
            return None;
        }
        let elapsed = (now - self.started).max(0.0);
        let first = self.rounds.first().copied().unwrap_or(0);
        let expected = self.expected_candidates();
        // The first round at the pace it goes (nothing to go by before its first chunk).
        let first_left = match self.second_round {
            Some(_) => 0.0,
            None if self.decided > 0 => {
                first.saturating_sub(self.decided) as f64 * elapsed / self.decided as f64
            }
            None => 0.0,
        };
        // The later rounds at this stage's pace once a tenth of them is done, else the
        // last stage that had later rounds (none: nothing to go by).
        let later_expected = (expected - first as f64).max(0.0);
        let previous = self.finished.iter().rev().find_map(|&(_, rate)| rate);
        let rate = self.later_rate(now, 0.1 * later_expected).or(previous)?;
        let later_done = self
            .second_round
            .map_or(0, |(_, before)| self.decided - before);
        let left_here = first_left + (later_expected - later_done as f64).max(0.0) * rate;
        let this_stage = elapsed + left_here;
        let later: f64 = (1..=self.stages - stage)
            .map(|k| this_stage * Self::STAGE_GROWTH.powi(k as i32))
            .sum();
        Some(left_here + later)
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

    /// Rounds (candidates each) and seconds of the three linking stages of hierarchical
    /// solves at ε = 0.02 (release build, 2-core machine, 2026-12-07, seconds the median of
    /// three runs): the Cornell box and the furnished rooms of 30 and 300 objects
    /// (`generate::furnished_room(N, 1)`).
    const RECORDED: [[(&[u64], f64); 3]; 3] = [
        [
            (
                &[
                    1, 4, 4, 12, 32, 80, 146, 180, 160, 136, 140, 132, 178, 384, 394, 676, 890,
                    514, 264, 60, 30, 4,
                ],
                0.0083,
            ),
            (
                &[
                    617, 2236, 2870, 1342, 1496, 1626, 2070, 2416, 2664, 2654, 2230, 1616, 666, 14,
                ],
                0.0435,
            ),
            (
                &[
                    5623, 13788, 8182, 3238, 2644, 1852, 1572, 1060, 842, 532, 500, 692, 256,
                ],
                0.0566,
            ),
        ],
        [
            (
                &[
                    1, 4, 4, 12, 32, 80, 184, 370, 734, 1412, 2292, 3058, 3576, 3868, 3862, 3764,
                    3658, 3772, 4008, 4136, 5536, 4902, 4516, 5144, 3392, 3140, 2358, 1300, 688,
                    358, 42, 4,
                ],
                0.0951,
            ),
            (
                &[
                    4928, 9938, 11630, 12964, 14444, 14350, 13190, 11270, 9468, 9388, 6308, 4600,
                    2750, 1284, 486, 478, 688, 576,
                ],
                0.2375,
            ),
            (
                &[
                    22224, 43868, 21442, 11466, 6044, 3382, 1790, 2932, 534, 772, 136, 20, 16,
                ],
                0.2149,
            ),
        ],
        [
            (
                &[
                    1, 4, 4, 12, 32, 80, 184, 416, 886, 1820, 3514, 6620, 12340, 21082, 29642,
                    35316, 37012, 36640, 35260, 33178, 32334, 33168, 35650, 37692, 37254, 31492,
                    23290, 16434, 10874, 6474, 3124, 1210, 398, 96, 22, 4,
                ],
                0.7729,
            ),
            (
                &[
                    59743, 102134, 103146, 99854, 91682, 83766, 76292, 68822, 60394, 53976, 44224,
                    36736, 29498, 22668, 14972, 7978, 3714, 1390, 492, 168, 28, 8,
                ],
                1.8605,
            ),
            (
                &[
                    126253, 220072, 122526, 76960, 48214, 29526, 17026, 9368, 5242, 3132, 1922,
                    1198, 584, 244, 52, 10, 6,
                ],
                1.4106,
            ),
        ],
    ];

    /// The worst factor by which the linking ETA is off (predicted ÷ actual time left, or
    /// its inverse) over a recorded linking replayed in chunks of at most `chunk`
    /// candidates, a first round's candidate taking a tenth of a later one's (it reuses its
    /// estimate), from the start of the second stage until 5 % of the linking is left (the
    /// last rounds are a few small ones, whose pace no estimate follows).
    fn worst_linking_ratio(stages: &[(&[u64], f64)], chunk: u64) -> f64 {
        let total: f64 = stages.iter().map(|s| s.1).sum();
        let mut eta = LinkingEta::new(stages.len() as u32);
        let (mut now, mut worst) = (0.0f64, 1.0f64);
        for (index, &(rounds, seconds)) in stages.iter().enumerate() {
            let weight = |round: usize| if round == 0 && index > 0 { 0.1 } else { 1.0 };
            let units: f64 = rounds
                .iter()
                .enumerate()
                .map(|(k, &r)| r as f64 * weight(k))
                .sum();
            let per_unit = seconds / units;
            eta.start_stage(now);
            for (k, &candidates) in rounds.iter().enumerate() {
                let mut left_in_round = candidates;
                while left_in_round > 0 {
                    let n = left_in_round.min(chunk);
                    left_in_round -= n;
                    now += n as f64 * weight(k) * per_unit;
                    eta.advance(k, candidates, n, now);
                    let left = total - now;
                    if let Some(predicted) = eta.eta(now) {
                        if left > 0.05 * total {
                            let ratio = predicted.max(1e-3 * total) / left;
                            worst = worst.max(ratio).max(1.0 / ratio);
                        }
                    } else {
                        assert_eq!(index, 0, "no estimate after the first stage");
                    }
                }
            }
            eta.finish_stage(now);
        }
        assert!(eta.eta(now).is_none(), "an estimate after the last stage");
        worst
    }

    #[test]
    fn linking_eta_is_within_a_small_factor_of_recorded_linkings_after_the_first_stage() {
        // In chunks as the solver reports them (65,536) and in finer ones. The bounds are
        // what the estimator's constants, each a median or range over these recordings,
        // give here (1.98× for both rooms, 2.45× for the Cornell box) with a small margin:
        // 2.5× for the rooms; 3× for the Cornell box, whose last stage takes 1.3–1.4 times
        // its second (the rooms' 0.7–0.9) and whose whole linking, 0.11 s, passes below the
        // bar's resolution of 0.1 s. Measured on the solver itself, the rooms of 1000 and
        // 3000 objects (not recorded here) came within 0.76–1.59× and 0.68–1.90× until their
        // last 3 % (see the README).
        for ((scene, stages), bound) in ["Cornell box", "room of 30", "room of 300"]
            .iter()
            .zip(&RECORDED)
            .zip([3.0, 2.5, 2.5])
        {
            for chunk in [65_536, 1024] {
                let worst = worst_linking_ratio(stages, chunk);
                assert!(
                    worst <= bound,
                    "{scene}, chunks of {chunk}: off by {worst:.2}×"
                );
            }
        }
    }

    /// A linking of three stages whose first took 10 s, in its second stage after `rounds`
    /// (candidates each, and the time each ends at).
    fn in_second_stage(rounds: &[(u64, f64)]) -> LinkingEta {
        let mut eta = LinkingEta::new(3);
        eta.start_stage(0.0);
        eta.advance(0, 1, 1, 10.0);
        eta.finish_stage(10.0);
        eta.start_stage(10.0);
        for (k, &(candidates, at)) in rounds.iter().enumerate() {
            eta.advance(k, candidates, candidates, at);
        }
        eta
    }

    #[test]
    fn linking_eta_extrapolates_a_falling_round_tail_and_later_stages() {
        // A second stage of three, rounds 100, 200, 150, 75, 1 s per candidate after the
        // first round (10 s). The rounds fall by 0.75 and then 0.5: the tail is taken at the
        // slower, 75 · 0.75 / 0.25 = 225 candidates (225 s) more. The last stage is taken to
        // last STAGE_GROWTH times this one's 435 + 225 s.
        let rounds = [(100, 20.0), (200, 220.0), (150, 370.0), (75, 445.0)];
        let left_here = 225.0;
        let expected = left_here + (435.0 + left_here) * LinkingEta::STAGE_GROWTH;
        let got = in_second_stage(&rounds).eta(445.0).unwrap();
        assert!(
            (got - expected).abs() < 1e-9 * expected,
            "{got} against {expected}"
        );
        // One smaller round is not yet a tail: after 100, 200, 150 the stage is expected to
        // hold what its first round's share says.
        let expected_here = 100.0 / LinkingEta::FIRST_ROUND_SHARE_SECOND_STAGE;
        let left_here = expected_here - 450.0;
        let expected = left_here + (360.0 + left_here) * LinkingEta::STAGE_GROWTH;
        let got = in_second_stage(&rounds[..3]).eta(370.0).unwrap();
        assert!(
            (got - expected).abs() < 1e-9 * expected,
            "{got} against {expected}"
        );
    }
}
