//! The leaves above the merging level, merged over the fetchers.

use golden::merge::fetcher::FetchLayout;

use super::get;
use crate::merge::network::morton_code;
use crate::{Module, Signal};

/// What the leaves merge needs: the fetchers' `leaves` streams
/// (`(valid, data, input)`), which inputs the merge uses, the controller's
/// `busy` and the header's handshake that ends the merge.
pub(super) struct LeafInputs<'a, 'm> {
    pub(super) fl: &'a FetchLayout,
    pub(super) busy: Signal<'m>,
    pub(super) header_fire: Signal<'m>,
    pub(super) used: &'a [Signal<'m>],
    pub(super) leaves_in: &'a [(Signal<'m>, Signal<'m>, usize)],
    pub(super) fetchers: &'a [crate::Instance<'m>],
    pub(super) rb: u32,
}

/// The leaves above the merging level (or `lo`), merged over the used
/// fetchers by (LOD, Morton, rank): `take` while a leaf is chosen, `data`
/// its beat (rec, ref, lod), `lod` its LOD, `done` once every used fetcher
/// sent its leaves `end` (held to the end of the merge).
pub(super) struct MergedLeaves<'m> {
    pub(super) done: Signal<'m>,
    pub(super) take: Signal<'m>,
    pub(super) data: Signal<'m>,
    pub(super) lod: Signal<'m>,
}

pub(super) fn merge_leaves<'m>(m: &'m Module, t: LeafInputs<'_, 'm>) -> MergedLeaves<'m> {
    let LeafInputs {
        fl,
        busy,
        header_fire,
        used,
        leaves_in,
        fetchers,
        rb,
    } = t;
    let lit = |v: u64, w: u32| m.lit(v as u128, w);
    let (one, zero) = (lit(1, 1), lit(0, 1));
    let leaves_done = m.reg("leaves_done", 1);
    let active = (busy & !leaves_done).name("leaves_active");
    let nl = &fl.node;
    let mut all_valid = active;
    let mut all_end = one;
    let mut heads = Vec::new();
    for &(v, d, i) in leaves_in {
        let end = get(d, &fl.leaf_end);
        let rec = get(d, &fl.leaf_rec);
        let xyz = rec.coords(nl);
        let key = m
            .concat(&[!used[i] | end, get(d, &fl.leaf_lod), morton_code(m, xyz)])
            .name(&format!("leaf_key{i}"));
        all_valid = all_valid & (!used[i] | v);
        all_end = all_end & (!used[i] | end);
        // What a winner carries on: rec, ref, lod (not the end flag).
        heads.push((key, d.slice(fl.leaf_lod.end() - 1, 0)));
    }
    let all_valid = all_valid.name("leaves_all_valid");
    let all_end = all_end.name("leaves_all_end");
    // The lowest key wins, the lower rank on a tie (strictly lower keys
    // replace).
    let (mut best_key, mut best_data) = heads[0];
    let mut best = lit(0, rb);
    for (j, &(key, d)) in heads.iter().enumerate().skip(1) {
        let better = key.lt(best_key);
        if j + 1 < heads.len() {
            best_key = better.mux(key, best_key);
        }
        best_data = better.mux(d, best_data);
        best = better.mux(lit(j as u64, rb), best);
    }
    let best = best.name("leaf_best");
    let best_data = best_data.name("leaf_best_data");
    let take_leaf = (all_valid & !all_end).name("leaf_take");
    for (f, &(_, _, i)) in fetchers.iter().zip(leaves_in) {
        f.connect(
            "leaves_ready",
            used[i] & all_valid & (all_end | best.eq(lit(i as u64, rb))),
        );
    }
    leaves_done.next((all_valid & all_end).mux(one, header_fire.mux(zero, leaves_done)));
    let best_lod = get(best_data, &fl.leaf_lod);
    MergedLeaves {
        done: leaves_done,
        take: take_leaf,
        data: best_data,
        lod: best_lod,
    }
}
