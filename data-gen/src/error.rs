//! The crate's one error type.

use std::path::PathBuf;

/// What went wrong in data generation. Every variant names the offending input.
#[derive(Debug, thiserror::Error)]
pub enum DataGenError {
    /// A file could not be read or written.
    #[error("cannot access {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// The file is not valid Wavefront OBJ.
    #[error("{path} is not a readable OBJ file: {message}")]
    ObjParse {
        /// The file.
        path: PathBuf,
        /// The parser's message.
        message: String,
    },
    /// A glTF file is malformed or uses what altrep does not read; `at` is the glTF path of the
    /// offending object (`meshes[3].primitives[0]`, `images[2]`, `accessors[7]`, or `document`).
    #[error("{path}: {at}: {message}")]
    Gltf {
        /// The file.
        path: PathBuf,
        /// The glTF path of the offending object.
        at: String,
        /// What is wrong.
        message: String,
    },
    /// A texture a mesh's materials name could not be read or decoded.
    #[error("texture {path} (material '{material}'): {message}")]
    Texture {
        /// The texture file.
        path: PathBuf,
        /// The material naming it.
        material: String,
        /// What went wrong.
        message: String,
    },
    /// The file's extension names no mesh format altrep reads.
    #[error("{path}: not a mesh altrep reads (.obj, .gltf or .glb)")]
    MeshFormat {
        /// The file.
        path: PathBuf,
    },
    /// The mesh has no (non-degenerate) triangle.
    #[error("mesh {name} has no non-degenerate triangle")]
    EmptyMesh {
        /// File name or label of the mesh.
        name: String,
    },
    /// A coordinate or parameter is NaN or infinite.
    #[error("{what} is not finite (index {index})")]
    NonFinite {
        /// Which quantity.
        what: String,
        /// Index of the first offending element (vertex index, parameter position…).
        index: usize,
    },
    /// A size (image width, grid dimension, sample count) is zero.
    #[error("{what} must be at least 1, got 0")]
    ZeroSize {
        /// Which size.
        what: &'static str,
    },
    /// A parameter is outside its valid range.
    #[error("invalid {name} = {value}: {reason}")]
    InvalidParameter {
        /// The parameter.
        name: &'static str,
        /// Its value, as given.
        value: String,
        /// What it must satisfy.
        reason: &'static str,
    },
    /// No procedural shape has this name.
    #[error("unknown shape '{name}' (known: {known})")]
    UnknownShape {
        /// The name asked for.
        name: String,
        /// The names that exist.
        known: String,
    },
    /// An image could not be encoded or written.
    #[error("cannot write image {path}: {message}")]
    ImageWrite {
        /// The file.
        path: PathBuf,
        /// The encoder's message.
        message: String,
    },
}

/// Checks that `n` is non-zero.
pub(crate) fn nonzero(n: usize, what: &'static str) -> Result<usize, DataGenError> {
    if n == 0 {
        Err(DataGenError::ZeroSize { what })
    } else {
        Ok(n)
    }
}

/// Checks that `x` is finite.
pub(crate) fn finite(x: f64, what: &str, index: usize) -> Result<f64, DataGenError> {
    if x.is_finite() {
        Ok(x)
    } else {
        Err(DataGenError::NonFinite {
            what: what.to_string(),
            index,
        })
    }
}
