//! radiosity: physically based diffuse global illumination by the radiosity method.
//!
//! The pipeline is the architecture; data flows one way, one module per stage:
//!
//! ```text
//! Scene ──mesh──▶ Mesh ──formfactor──▶ coupling ──solve──▶ Solution ──display / render / report──▶ image, JSON
//! ```
//!
//! - [`scene`] (with [`light`], [`cornell`] and the readers in [`io`]): surfaces, materials,
//!   light sources, camera;
//! - [`geometry`]: convex polygons, the one clipper and the one lattice subdivider;
//! - [`mesh`]: patches and elements, contact lines, adaptive refinement;
//! - [`accel`]: the BVH and the visibility query;
//! - [`direct`]: the first shot from light sources (point, spot, goniometric) onto elements;
//! - [`formfactor`]: form-factor kernels on geometry, and mesh engines built on them;
//! - [`coupling`]: which elements exchange light at what level (dense, columns on the fly);
//! - [`solve`]: direct, Jacobi, Gauss–Seidel, progressive refinement, each reporting its
//!   steps to an observer;
//! - [`display`] and [`render`]: the crack-free display mesh and the rasteriser;
//! - [`report`]: per-object values in physical units (W·m⁻², lx, cd/m²); [`measure`]:
//!   illuminance at sensor points and on work-plane grids; [`pipeline`]: the stages in one
//!   call;
//! - [`export`]: the solved scene as a GLB with a lightmap;
//! - [`generate`]: procedural scenes of any size (tessellated Cornell box, furnished rooms)
//!   for scaling studies;
//! - [`viewpoint`] and [`diagnose`]: a default camera that sees lit surfaces, and warnings
//!   for scenes that would render black.
//!
//! Units: lengths in metres, emitted radiance L_e in W·m⁻²·sr⁻¹, radiosity, exitance and
//! irradiance in W·m⁻², power in W.

#![warn(missing_docs)]

pub mod accel;
pub mod cornell;
pub mod coupling;
pub mod diagnose;
pub mod direct;
pub mod display;
pub mod export;
pub mod formfactor;
pub mod generate;
pub mod geometry;
pub mod io;
pub mod light;
pub mod measure;
pub mod mesh;
pub mod photometry;
pub mod pipeline;
pub mod progress;
pub mod render;
pub mod report;
pub mod scene;
pub mod settings;
pub mod solve;
pub mod units;
pub mod viewpoint;

pub use coupling::Coupling;
pub use formfactor::FormFactorMethod;
pub use mesh::{Mesh, MeshOptions};
pub use pipeline::{solve_scene, SolveSettings, Solved};
pub use scene::{Camera, Material, Scene, Surface};
pub use solve::{Solution, SolveOptions, SolverKind};
