//! The one error type of mesh import.

use std::fmt;

/// Where in the input an error was found.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum MeshLocation {
    /// The file as a whole (cannot be read, wrong extension, empty header).
    File,
    /// A 1-based line of a text file (OBJ, PLY header, ascii PLY body).
    Line(u64),
    /// A 0-based instance of a PLY element (binary body), or a mesh element.
    Element {
        /// The element's name: a PLY element (`vertex`, `face`, ...), or
        /// `vertex` or `triangle` of an in-memory mesh.
        element: String,
        /// 0-based instance of that element.
        index: u64,
    },
}

/// A mesh that could not be imported, and why.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MeshError {
    /// The file (or in-memory name) being read.
    pub file: String,
    /// Where in the input: the whole file, a line, or an element instance.
    pub location: MeshLocation,
    /// The field that is wrong, e.g. `v coordinate y` or `face vertex_indices`.
    pub field: String,
    /// What the field should have been.
    pub expected: String,
    /// What was found instead (already quoted or summarised).
    pub found: String,
}

impl MeshError {
    /// An error in `file` at `location`: `field` should have been `expected` but was `found`.
    pub fn new(
        file: &str,
        location: MeshLocation,
        field: impl Into<String>,
        expected: impl Into<String>,
        found: impl Into<String>,
    ) -> MeshError {
        MeshError {
            file: file.to_string(),
            location,
            field: field.into(),
            expected: expected.into(),
            found: found.into(),
        }
    }
}

impl fmt::Display for MeshError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file)?;
        match &self.location {
            MeshLocation::File => {}
            MeshLocation::Line(l) => write!(f, ": line {l}")?,
            MeshLocation::Element { element, index } => write!(f, ": {element} {index}")?,
        }
        write!(
            f,
            ": {}: expected {}, found {}",
            self.field, self.expected, self.found
        )
    }
}

impl std::error::Error for MeshError {}

/// Shortens a found token for an error message.
pub(crate) fn quote(token: &[u8]) -> String {
    const MAX: usize = 40;
    let s = String::from_utf8_lossy(&token[..token.len().min(MAX)]).into_owned();
    if token.len() > MAX {
        format!("{s:?}...")
    } else {
        format!("{s:?}")
    }
}
