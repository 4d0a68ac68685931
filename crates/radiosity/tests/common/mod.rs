//! Support code shared by the integration tests.

// Each integration test is its own crate and uses a different part of the helpers; items one
// test does not use would otherwise warn (and fail `clippy --all-targets -D warnings`).
#[allow(dead_code)]
pub mod cie171;
#[allow(dead_code)]
pub mod solve;
