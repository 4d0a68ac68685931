//! Reading and writing: scenes (OBJ+MTL, glTF 2.0, MGF, our JSON scene file), solutions,
//! atomic output.

pub mod atomic;
pub mod error;
pub mod formats;
pub mod gltf;
pub mod lights;
pub mod mgf;
pub mod obj;
pub mod open;
pub mod scene_file;
pub mod solution_file;

pub use error::SceneError;
