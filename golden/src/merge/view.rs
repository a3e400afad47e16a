//! Reading a merged hierarchy through its inputs' translations: the
//! checker's view ([`MergedCheckView`]); traversal's instances are in
//! [`super::instances`].
//!
//! A merged hierarchy's references lead into input hierarchies whose nodes
//! are stored in their LOCAL grid coordinates; every reader applies each
//! input's translation on the fly: node voxels by [`translate_node`]
//! (equivalently, boxes shifted by the translation's grid offset
//! `t << (D - L)` grid units), triangles by that offset. Traversal tests an
//! input's triangles in its local frame (SPEC.md sections 6 and 8).

use std::collections::BTreeMap;

use glam::DVec3;

use crate::check::CheckView;
use crate::store::{Hierarchy, HierarchyStore, NodeRecord};
use crate::translate::{translate_node, Axis, TranslateError, Translation, TranslationTable};

/// The grid offset of `t` in grid units per axis: `t << (D - L)`.
pub fn grid_offset(t: &Translation, h: &Hierarchy) -> [i64; 3] {
    Axis::ALL.map(|a| t.grid_offset(a, &h.params))
}

/// The checker's view of a merged hierarchy (or of translated inputs):
/// inputs' nodes placed by their translations for every structural check
/// (LODs, voxels, boxes inside parents); their leaves checked against their
/// triangles in their local frame, as built (exact far from the origin, and
/// the coverage rule stays exact).
pub struct MergedCheckView<'a> {
    store: &'a HierarchyStore,
    translations: BTreeMap<u8, Translation>,
    triangles: BTreeMap<u8, &'a [[DVec3; 3]]>,
}

impl<'a> MergedCheckView<'a> {
    /// `local` gives each input's triangles in its local grid units (as it
    /// was built); each id in it must have a valid translation in `table`.
    pub fn new(
        store: &'a HierarchyStore,
        table: &TranslationTable,
        local: &BTreeMap<u8, &'a [[DVec3; 3]]>,
    ) -> Result<MergedCheckView<'a>, TranslateError> {
        let mut translations = BTreeMap::new();
        for &id in local.keys() {
            translations.insert(id, table.read(id as u32)?);
        }
        Ok(MergedCheckView {
            store,
            translations,
            triangles: local.clone(),
        })
    }
}

impl CheckView for MergedCheckView<'_> {
    fn hierarchy(&self, id: u8) -> Option<&Hierarchy> {
        self.store.get(id)
    }

    fn triangles(&self, id: u8) -> Option<&[[DVec3; 3]]> {
        self.triangles.get(&id).copied()
    }

    fn place(&self, id: u8, node: &NodeRecord) -> Result<NodeRecord, String> {
        let Some(t) = self.translations.get(&id) else {
            return Ok(*node); // the merged hierarchy's own records: in the scene already
        };
        let p = self
            .store
            .get(id)
            .map(|h| h.params)
            .ok_or("no such hierarchy")?;
        let voxel = translate_node(node.voxel, t, &p).map_err(|e| e.to_string())?;
        Ok(NodeRecord { voxel, ..*node })
    }

    fn leaves_in_local_frame(&self, id: u8) -> bool {
        self.translations.contains_key(&id)
    }
}
