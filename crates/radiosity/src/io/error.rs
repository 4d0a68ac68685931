//! Errors from reading and writing scenes.
//!
//! Every variant says where the problem is: the file (as the user named it), the line when
//! the format has lines we can point at, and the object or material involved. Messages read
//! as `file: line N: what is wrong`, so the binary can prefix its own context ("loading
//! scenes/cornell.obj: …") without repeating it.
//!
//! See also: [`crate::io::obj`] and [`crate::io::scene_file`], which raise them.

use crate::geometry::GeometryError;
use std::fmt;

/// A place in an input file: the file as the user named it, and the 1-based line if known.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Location {
    /// The file, as the user named it.
    pub file: String,
    /// The 1-based line, if known.
    pub line: Option<usize>,
}

impl Location {
    /// A location in `file`, at `line` if known.
    pub fn new(file: impl Into<String>, line: Option<usize>) -> Self {
        Self {
            file: file.into(),
            line,
        }
    }

    /// A location with a known line.
    pub fn line(file: impl Into<String>, line: usize) -> Self {
        Self::new(file, Some(line))
    }

    /// A whole-file location (no line).
    pub fn file(file: impl Into<String>) -> Self {
        Self::new(file, None)
    }
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.line {
            Some(line) => write!(f, "{}: line {line}", self.file),
            None => f.write_str(&self.file),
        }
    }
}

/// Why a scene could not be loaded or saved.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The file could not be opened or read (missing, unreadable, not UTF-8).
    #[error("{file}: cannot read: {source}")]
    Read {
        /// The file, as the user named it.
        file: String,
        #[source]
        /// The underlying error.
        source: std::io::Error,
    },
    /// The file could not be written.
    #[error("{file}: cannot write: {source}")]
    Write {
        /// The file, as the user named it.
        file: String,
        #[source]
        /// The underlying error.
        source: std::io::Error,
    },
    /// A line that does not parse: a value that is not a number, the wrong number of values,
    /// a malformed face token.
    #[error("{at}: {message}")]
    Syntax {
        /// Where in the input.
        at: Location,
        /// What is wrong.
        message: String,
    },
    /// A face refers to a vertex (or texture coordinate, or normal) that does not exist.
    /// `index` is as written in the file (negative for relative indices).
    #[error("{at}: face refers to {what} {index}, file has {count}")]
    IndexOutOfRange {
        /// Where in the input.
        at: Location,
        /// What the value is.
        what: &'static str,
        /// The index as written.
        index: i64,
        /// How many there are.
        count: usize,
    },
    /// A vertex coordinate is NaN or infinite.
    #[error("{at}: vertex coordinate {value} is not finite")]
    NonFiniteCoordinate {
        /// Where in the input.
        at: Location,
        /// The value given.
        value: String,
    },
    /// A face is not a usable polygon (degenerate, too few vertices, absurd coordinates,
    /// non-planar with more than four vertices).
    #[error("{at}: object '{object}': {source}")]
    Geometry {
        /// Where in the input.
        at: Location,
        /// The object it belongs to.
        object: String,
        #[source]
        /// The underlying error.
        source: GeometryError,
    },
    /// An OBJ `mtllib` names a file that cannot be read.
    #[error("{at}: cannot read material library '{library}': {source}")]
    MissingMaterialLibrary {
        /// Where in the input.
        at: Location,
        /// The material library named.
        library: String,
        #[source]
        /// The underlying error.
        source: std::io::Error,
    },
    /// A surface names a material that is not defined.
    #[error("{at}: object '{object}': material '{material}' is not defined")]
    UnknownMaterial {
        /// Where in the input.
        at: Location,
        /// The object it belongs to.
        object: String,
        /// The material.
        material: String,
    },
    /// An OBJ face comes before any `usemtl`.
    #[error("{at}: object '{object}': face has no material (no 'usemtl' before it)")]
    NoMaterial {
        /// Where in the input.
        at: Location,
        /// The object it belongs to.
        object: String,
    },
    /// A material with unphysical or inconsistent values (reflectance outside [0, 1),
    /// negative emission, defined twice).
    #[error("{at}: material '{material}': {problem}")]
    Material {
        /// Where in the input.
        at: Location,
        /// The material.
        material: String,
        /// What is wrong.
        problem: String,
    },
    /// A JSON scene file that is not valid JSON or does not match the format; `line` and
    /// `column` are 1-based, as serde_json reports them.
    #[error("{file}: line {line}, column {column}: {message}")]
    Json {
        /// The file, as the user named it.
        file: String,
        /// The 1-based line, if known.
        line: usize,
        /// The 1-based column.
        column: usize,
        /// What is wrong.
        message: String,
    },
    /// A value that parses but makes no sense (a camera looking nowhere, a zero image size).
    #[error("{at}: {message}")]
    Invalid {
        /// Where in the input.
        at: Location,
        /// What is wrong.
        message: String,
    },
    /// The file extension is not one we can load.
    #[error("{file}: unknown scene format (expected a .obj, .gltf, .glb, .mgf or .json file)")]
    UnknownFormat {
        /// The file, as the user named it.
        file: String,
    },
    /// A glTF file that cannot be read (its message names the file and the part of it).
    #[error(transparent)]
    Gltf(#[from] crate::io::gltf::GltfError),
    /// An error in a file included by a scene file; the message names both.
    #[error("{file}: include {source}")]
    Included {
        /// The scene file that includes it, as the user named it.
        file: String,
        /// The error in the included file (which names that file).
        #[source]
        source: Box<SceneError>,
    },
    /// The input defines no surfaces at all.
    #[error("{file}: scene has no surfaces")]
    Empty {
        /// The file, as the user named it.
        file: String,
    },
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_name_file_line_and_object() {
        let e = SceneError::IndexOutOfRange {
            at: Location::line("scenes/cornell.obj", 12),
            what: "vertex",
            index: 40,
            count: 38,
        };
        assert_eq!(
            e.to_string(),
            "scenes/cornell.obj: line 12: face refers to vertex 40, file has 38"
        );
        let e = SceneError::Geometry {
            at: Location::file("a.json"),
            object: "floor".into(),
            source: GeometryError::NonConvex,
        };
        assert_eq!(
            e.to_string(),
            "a.json: object 'floor': polygon is not convex"
        );
    }
}
