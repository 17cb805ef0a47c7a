//! Errors from loading a scene. Every error names the file it is about.
use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    #[error("{path}: cannot read file: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// Anything wrong with the content of a file: `what` says where (element, key) and what is wrong.
    #[error("{path}: {what}")]
    Invalid { path: PathBuf, what: String },
}

impl SceneError {
    pub fn invalid(path: impl Into<PathBuf>, what: impl Into<String>) -> Self {
        SceneError::Invalid {
            path: path.into(),
            what: what.into(),
        }
    }
}
