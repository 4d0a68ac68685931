//! radiosity: physically based diffuse global illumination by the radiosity method.
//!
//! The pipeline is the architecture; data flows one way:
//!
//! ```text
//! Scene ──mesh──▶ Mesh ──formfactor──▶ coupling ──solve──▶ Solution ──render / report──▶ image, JSON
//! ```
//!
//! Units: lengths in metres, emitted radiance L_e in W·m⁻²·sr⁻¹, radiosity, exitance and
//! irradiance in W·m⁻², power in W.

pub mod accel;
pub mod compare;
pub mod cornell;
pub mod display;
pub mod formfactor;
pub mod geometry;
pub mod io;
pub mod light;
pub mod mesh;
pub mod pipeline;
pub mod progress;
pub mod refine;
pub mod render;
pub mod report;
pub mod scene;
pub mod sequence;
pub mod solve;
