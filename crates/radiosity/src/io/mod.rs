//! Reading and writing: scenes (OBJ+MTL, our JSON scene file), solutions, atomic output.

pub mod atomic;
pub mod error;
pub mod lights;
pub mod obj;
pub mod open;
pub mod scene_file;
pub mod solution_file;

pub use error::SceneError;
