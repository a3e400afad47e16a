//! The k-way Morton merge in front of S608 and S614 (SPEC.md section 8.10):
//! `k` input streams, each one input's level in (Morton, leaf) order with
//! every inner node's child references after the voxel's leaf, become one
//! stream in S614's delivery order, each beat tagged with its input's rank.
//!
//! Every head (a skid buffer per input, so `in*_ready` is registered) has
//! the key `{end, morton, kind}` and its rank: `End` sorts last, the Morton code of
//! the voxel orders voxels, the kind code (inner 0, leaf 1, child reference
//! 2) is the phase within a voxel, and the lower rank wins a tie, so the
//! minimum is one head. A child reference carries no voxel:
//! its key takes the voxel of the last node taken from its input (its
//! parent's). Only when every head is present is the minimum known (a
//! missing head may be smaller), so the merge waits for all `k`; with no
//! back-pressure the skid buffers keep them all present and one beat leaves
//! per clock. When every head is `End`, one `End` leaves and all are taken.

use golden::merge::unit::{level_kind, rank_bits, BeatLayout};
use golden::params::Params;

use super::fields::{coords, field};
use crate::{Module, Signal, Stream};

/// Module name of the merge network for `p`, `k` inputs, rank tag or not.
pub fn morton_merge_name(p: &Params, k: usize, tag_rank: bool) -> String {
    let rank = if tag_rank { "_ranked" } else { "" };
    format!("morton_merge_{}_k{k}{rank}", p.tag())
}

/// The Morton code of a voxel's coordinates, bit `i` of `x`, `y`, `z` at
/// `3i`, `3i + 1`, `3i + 2` (golden `grid::morton3`): wiring only.
pub fn morton_code<'m>(m: &'m Module, xyz: [Signal<'m>; 3]) -> Signal<'m> {
    let d = xyz[0].width();
    let mut high_first = Vec::with_capacity(3 * d as usize);
    for b in (0..d).rev() {
        for c in xyz.iter().rev() {
            high_first.push(c.bit(b));
        }
    }
    m.concat(&high_first).named_after(xyz[0], "morton")
}

/// One input of a merge network as the shared choice sees it: its head
/// (skid-buffered) stream, the registers holding the voxel of the last node
/// taken from it, that head's voxel, and whether taking it is a node (which
/// moves the parent voxel a later child reference keys on).
pub(super) struct MergeHead<'m> {
    /// The skid-buffered head; its `ready` is driven by [`take_minimum_head`].
    pub stream: Stream<'m>,
    /// The voxel of the last node taken from this input.
    pub parent: [Signal<'m>; 3],
    /// The head record's voxel.
    pub xyz: [Signal<'m>; 3],
    /// High when the head is a node (not `End`, not a child reference).
    pub takes_node: Signal<'m>,
}

/// The choice shared by both merge networks: with every head present, the
/// head of least `key` (the lower rank on a tie) leaves when `out_ready`;
/// when all are `End` all leave together. Returns the winner's rank and its
/// head's data; drives every head's `ready` and updates the parent voxels.
pub(super) fn take_minimum_head<'m>(
    m: &'m Module,
    heads: &[MergeHead<'m>],
    keys: &[Signal<'m>],
    all_valid: Signal<'m>,
    all_end: Signal<'m>,
    out_ready: Signal<'m>,
) -> (Signal<'m>, Signal<'m>) {
    let k = heads.len();
    let rb = rank_bits(k);
    // A tournament of pairwise minima over (key, rank); on equal keys the
    // lower rank (the left one) wins. The final round needs only the rank.
    let mut round: Vec<(Signal, Signal)> = keys
        .iter()
        .enumerate()
        .map(|(i, key)| (*key, m.lit(i as u128, rb)))
        .collect();
    let mut depth = 0;
    while round.len() > 1 {
        let last_round = round.len() == 2;
        round = round
            .chunks(2)
            .enumerate()
            .map(|(j, pair)| match pair {
                [(ka, ra), (kb, rb_)] => {
                    let take_b = kb.lt(*ka).name(&format!("take_r{depth}_{j}"));
                    let key = if last_round {
                        *ka
                    } else {
                        take_b.mux(*kb, *ka).name(&format!("min_r{depth}_{j}"))
                    };
                    (key, take_b.mux(*rb_, *ra))
                }
                [one] => *one,
                _ => unreachable!("chunks of two"),
            })
            .collect();
        depth += 1;
    }
    let winner = round[0].1.name("winner_rank");
    let winner_end = all_end.name("winner_is_end");

    let mut options: Vec<Signal> = heads.iter().map(|h| h.stream.data).collect();
    while options.len() < 1usize << rb {
        options.push(heads[k - 1].stream.data);
    }
    let beat = winner.select(&options).name("winner_beat");
    let fire = (all_valid & out_ready).name("net_fire");
    for (i, head) in heads.iter().enumerate() {
        let chosen = winner.eq(m.lit(i as u128, rb));
        // Every head is End when the winner is: all leave together.
        head.stream.ready.drive(fire & (winner_end | chosen));
        let took_node = fire & chosen & !winner_end & head.takes_node;
        for a in 0..3 {
            head.parent[a].next_when(took_node, head.xyz[a]);
        }
    }
    (winner, beat)
}

/// The merge network for `p` and `k >= 2` inputs: streams `in0`..`in{k-1}`
/// of [`BeatLayout::input`] beats; stream `out` of `{rank, beat}` with
/// `tag_rank` (the overlap counter needs the rank), else of `beat`.
pub fn morton_merge_unit(p: &Params, k: usize, tag_rank: bool) -> Module {
    let m = Module::new(&morton_merge_name(p, k, tag_rank));
    let l = BeatLayout::input(p);
    let nl = &l.node;

    let out_ready = m.wire("net_out_ready", 1);
    let mut heads = Vec::with_capacity(k);
    let mut keys = Vec::with_capacity(k);
    let mut all_valid = m.lit(1, 1);
    let mut all_end = m.lit(1, 1);
    for i in 0..k {
        let head =
            Stream::input(&m, &format!("in{i}"), l.width).skid_buffer(&format!("in{i}_head"));
        let kind = field(head.data, &l.kind)
            .expect("kind bits")
            .name(&format!("in{i}_kind"));
        let is_end = kind.eq(level_kind::END).name(&format!("in{i}_is_end"));
        let is_ref = kind.eq(level_kind::CHILD_REF);
        let xyz = coords(field(head.data, &l.rec).expect("record bits"), nl);
        let last: [Signal; 3] = [0, 1, 2].map(|a| {
            m.reg(
                &format!("in{i}_parent_{}", ["x", "y", "z"][a]),
                xyz[a].width(),
            )
        });
        let key_xyz = [0, 1, 2].map(|a| is_ref.mux(last[a], xyz[a]));
        let key = m
            .concat(&[is_end, morton_code(&m, key_xyz), kind])
            .name(&format!("in{i}_key"));
        all_valid = all_valid & head.valid;
        all_end = all_end & is_end;
        let takes_node = !kind.bit(1);
        heads.push(MergeHead {
            stream: head,
            parent: last,
            xyz,
            takes_node,
        });
        keys.push(key);
    }
    let all_valid = all_valid.name("all_heads");
    let (winner, beat) = take_minimum_head(&m, &heads, &keys, all_valid, all_end, out_ready);
    Stream {
        valid: all_valid,
        ready: out_ready,
        data: if tag_rank {
            m.concat(&[winner, beat]).name("net_beat")
        } else {
            beat
        },
    }
    .skid_buffer("out_skid")
    .output("out");
    m
}
