//! Traversal of a merged hierarchy: one traversal ([`crate::trace`]), which
//! starts at the merged hierarchy's roots and follows its `(hier, node)`
//! references into the inputs, each an [`Instance`] carrying its
//! translation's grid offset. Node boxes move by the offset; an input's
//! triangles are tested in its local frame (the ray origin moved by minus
//! the offset in binary64), so a translated hierarchy's hits are those of
//! the same geometry at the origin (SPEC.md sections 6 and 8).

use std::collections::BTreeMap;

use crate::merge::view::grid_offset;
use crate::mesh::Mesh;
use crate::store::{Hierarchy, HierarchyStore};
use crate::trace::Instance;
use crate::translate::{TranslateError, TranslationTable};

static NO_TRIANGLES: Mesh = Mesh {
    vertices: Vec::new(),
    triangles: Vec::new(),
};

/// Traversal instances for merged hierarchy `merged`: itself (no triangles,
/// no offset) and every input in `meshes` (id to its mesh in local world
/// units) with the grid offset of its translation in `table`. Trace with
/// `TraceScene::with_roots(grid, &instances, &[merged.id])`.
pub fn merged_instances<'a>(
    merged: &'a Hierarchy,
    store: &'a HierarchyStore,
    table: &TranslationTable,
    meshes: &BTreeMap<u8, &'a Mesh>,
) -> Result<Vec<Instance<'a>>, TranslateError> {
    group_instances(&[merged], store, table, meshes)
}

/// Traversal instances for several merged hierarchies, each over a subset
/// of the inputs (paragraph 67), traced together: every merged hierarchy
/// (no triangles, no offset) and every input in `meshes`, once. Trace with
/// the merged hierarchies' ids as roots.
pub fn group_instances<'a>(
    merged: &[&'a Hierarchy],
    store: &'a HierarchyStore,
    table: &TranslationTable,
    meshes: &BTreeMap<u8, &'a Mesh>,
) -> Result<Vec<Instance<'a>>, TranslateError> {
    let mut out: Vec<Instance<'a>> = merged
        .iter()
        .map(|&m| Instance::new(m, &NO_TRIANGLES))
        .collect();
    out.extend(input_instances(store, table, meshes)?);
    Ok(out)
}

/// Traversal instances of the inputs alone, each translated: the separate
/// hierarchies a merged one is compared with.
pub fn input_instances<'a>(
    store: &'a HierarchyStore,
    table: &TranslationTable,
    meshes: &BTreeMap<u8, &'a Mesh>,
) -> Result<Vec<Instance<'a>>, TranslateError> {
    let mut out = Vec::new();
    for (&id, &mesh) in meshes {
        let h = store
            .get(id)
            .ok_or(TranslateError::EmptyEntry { id: id as u32 })?;
        let t = table.read(id as u32)?;
        out.push(Instance {
            hierarchy: h,
            mesh,
            offset: grid_offset(&t, h),
        });
    }
    Ok(out)
}
