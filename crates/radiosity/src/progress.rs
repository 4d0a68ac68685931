//! Progress reporting from long library stages to whoever is watching (the CLI's bars).

/// Receives progress from long-running stages. Implementations must be cheap and thread-safe.
pub trait Progress: Sync {
    /// A stage with `total` steps begins.
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
