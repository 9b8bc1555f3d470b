//! Scene loaders at the edge of the library: the TOML scene format and Wavefront OBJ
//! meshes. Errors name the file, the line and the field.

use std::path::Path;

use super::Scene;

/// A scene file that could not be used.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum LoadError {
    /// The file could not be read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
}

/// Loads a scene from a TOML file.
pub fn load_scene(path: &Path) -> Result<Scene, LoadError> {
    let source = std::fs::read_to_string(path)
        .map_err(|source| LoadError::Io { path: path.display().to_string(), source })?;
    let _ = source;
    todo!()
}
