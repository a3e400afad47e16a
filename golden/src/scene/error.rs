//! The one error type of scene files: the file, the JSON path of the
//! element at fault, what was expected and what was found.

use std::fmt;

/// A scene file that cannot be used, and why.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SceneError {
    /// The scene file (or in-memory name).
    pub file: String,
    /// JSON path of the element at fault, e.g. `objects[2].placement[1]`;
    /// `.` for the document as a whole.
    pub path: String,
    /// What the element should have been.
    pub expected: String,
    /// What was found instead.
    pub found: String,
}

impl SceneError {
    /// An error in `file` at JSON path `path`: expected `expected`, found `found`.
    pub fn new(
        file: &str,
        path: impl Into<String>,
        expected: impl Into<String>,
        found: impl Into<String>,
    ) -> SceneError {
        SceneError {
            file: file.to_string(),
            path: path.into(),
            expected: expected.into(),
            found: found.into(),
        }
    }
}

impl fmt::Display for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}: {}: expected {}, found {}",
            self.file, self.path, self.expected, self.found
        )
    }
}

impl std::error::Error for SceneError {}
