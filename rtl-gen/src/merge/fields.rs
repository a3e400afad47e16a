//! Reading and rewriting the fields of a packed record signal by the golden
//! layout's [`Field`]s: the one place the merge generators turn a field
//! description into slices, so no offset is restated.

use golden::layout::Field;

use crate::{Module, Signal};

/// The bits of field `f` of `record`; `None` for a zero-width field (the box
/// bounds when `Q = 0`).
#[track_caller]
pub fn field<'m>(record: Signal<'m>, f: &Field) -> Option<Signal<'m>> {
    (f.width > 0).then(|| record.slice(f.end() - 1, f.offset))
}

/// The contiguous bits from field `first` to field `last` inclusive (e.g.
/// `lod` through `z`: a voxel address).
#[track_caller]
pub fn span<'m>(record: Signal<'m>, first: &Field, last: &Field) -> Signal<'m> {
    record.slice(last.end() - 1, first.offset)
}

/// `record` with the fields of `replace` set to the given signals (each as
/// wide as its field; zero-width fields are skipped), every other bit kept.
#[track_caller]
pub fn with_fields<'m>(
    m: &'m Module,
    record: Signal<'m>,
    replace: &[(Field, Signal<'m>)],
) -> Signal<'m> {
    let mut parts: Vec<(u32, u32, Option<Signal<'m>>)> = replace
        .iter()
        .filter(|(f, _)| f.width > 0)
        .map(|(f, s)| (f.offset, f.end(), Some(*s)))
        .collect();
    parts.sort_by_key(|p| p.0);
    let mut low_first = Vec::new();
    let mut at = 0;
    for (lo, hi, s) in parts {
        if lo > at {
            low_first.push(record.slice(lo - 1, at));
        }
        low_first.extend(s);
        at = hi;
    }
    if at < record.width() {
        low_first.push(record.slice(record.width() - 1, at));
    }
    low_first.reverse();
    m.concat(&low_first)
}
