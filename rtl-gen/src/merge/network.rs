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

use golden::merge::level_choice::unit::rank_bits;

use golden::merge::merge_level::unit::{level_kind, BeatLayout};
use golden::params::Params;

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
/// (skid-buffered) stream of `{key, beat}` and the key's width.
///
/// The key is made as a beat enters its head and held in the skid buffer
/// beside it, and the minimum compares every pair of heads at once (one
/// comparator deep, not a tournament): the key logic and a second round of
/// comparators in the clock that takes a head were the network's critical
/// path (docs/hardware.md 14.7). An input's beats enter in the order they
/// leave, so the last node to enter before a child reference is the last
/// node taken before it.
pub(super) struct MergeHead<'m> {
    /// The skid-buffered head; its `ready` is driven by [`take_minimum_head`].
    pub stream: Stream<'m>,
    /// Bits of the key above the beat.
    pub key_bits: u32,
    /// High when the head loads a word at the next edge.
    load: Signal<'m>,
    /// The `{key, beat}` it loads then.
    next: Signal<'m>,
}

impl<'m> MergeHead<'m> {
    /// Input `in{i}` of `width`-bit beats, each entering its skid buffer
    /// with `key(beat, voxel of the last node that entered)`; `node(beat)`
    /// says whether the beat is a node with the voxel `xyz(beat)`.
    pub(super) fn new(
        m: &'m Module,
        i: usize,
        width: u32,
        key: impl FnOnce(Signal<'m>, [Signal<'m>; 3]) -> Signal<'m>,
        node: impl FnOnce(Signal<'m>) -> Signal<'m>,
        xyz: impl FnOnce(Signal<'m>) -> [Signal<'m>; 3],
    ) -> MergeHead<'m> {
        let input = Stream::input(m, &format!("in{i}"), width);
        let xyz = xyz(input.data);
        let parent: [Signal; 3] = [0, 1, 2].map(|a| {
            m.reg(
                &format!("in{i}_parent_{}", ["x", "y", "z"][a]),
                xyz[a].width(),
            )
        });
        let key = key(input.data, parent).name(&format!("in{i}_key"));
        let entered_node = input.valid & input.ready & node(input.data);
        let key_bits = key.width();
        let head = input
            .map(|d| key.concat(d))
            .skid_buffer_loads(&format!("in{i}_head"));
        for a in 0..3 {
            parent[a].next_when(entered_node, xyz[a]);
        }
        MergeHead {
            stream: head.stream,
            key_bits,
            load: head.load,
            next: head.next,
        }
    }

    /// The head's beat.
    pub(super) fn beat(&self) -> Signal<'m> {
        let w = self.stream.data.width() - self.key_bits;
        self.stream.data.slice(w - 1, 0)
    }

    /// The head's key.
    pub(super) fn key(&self) -> Signal<'m> {
        self.key_of(self.stream.data)
    }

    /// The key of the word the head loads at the next edge.
    fn next_key(&self) -> Signal<'m> {
        self.key_of(self.next)
    }

    /// The key of a `{key, beat}` word.
    fn key_of(&self, word: Signal<'m>) -> Signal<'m> {
        let w = word.width();
        word.slice(w - 1, w - self.key_bits)
    }
}

/// When the choice compares the heads' keys.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum KeyOrder {
    /// In the clock that takes a head: the comparators, the winner and the
    /// heads' `ready` in one clock.
    Combinational,
    /// A clock ahead: each pair's order is a register, loaded with the
    /// comparison of the keys the two heads hold at the next edge (each
    /// head's next word or its present one), so the clock that takes a head
    /// starts from registered order bits. Three comparators per pair: the
    /// per-node merging module's critical path was the comparators, the
    /// winner and the `ready`s into the heads' skid buffers
    /// (docs/hardware.md 14.7).
    Registered,
}

/// The choice shared by both merge networks: with every head present, the
/// head of least key (the lower rank on a tie) leaves when `out_ready`;
/// when all are `End` all leave together. Returns the winner (one bit per
/// head) and its head's beat; drives every head's `ready`. `order` changes
/// timing only, not the choice.
pub(super) fn take_minimum_head<'m>(
    m: &'m Module,
    heads: &[MergeHead<'m>],
    all_valid: Signal<'m>,
    all_end: Signal<'m>,
    out_ready: Signal<'m>,
    order: KeyOrder,
) -> (Vec<Signal<'m>>, Signal<'m>) {
    let k = heads.len();
    let keys: Vec<Signal> = heads.iter().map(MergeHead::key).collect();
    let below = |j: usize, i: usize| {
        let name = format!("below_{j}_{i}");
        match order {
            KeyOrder::Combinational => keys[j].lt(keys[i]).name(&name),
            KeyOrder::Registered => {
                let (hi, hj) = (&heads[i], &heads[j]);
                let (next_i, next_j) = (hi.next_key(), hj.next_key());
                let r = m.reg(&name, 1);
                r.next(hi.load.mux(
                    hj.load.mux(next_j.lt(next_i), keys[j].lt(next_i)),
                    hj.load.mux(next_j.lt(keys[i]), r),
                ));
                r
            }
        }
    };
    // Head i wins when it is below every later head and not above any
    // earlier one (the lower rank wins a tie): one order bit per pair.
    let mut wins = vec![m.lit(1, 1); k];
    for i in 0..k {
        for j in i + 1..k {
            let j_below = below(j, i);
            wins[i] = wins[i] & !j_below;
            wins[j] = wins[j] & j_below;
        }
    }
    let wins: Vec<Signal> = wins
        .iter()
        .enumerate()
        .map(|(i, w)| w.name(&format!("wins_{i}")))
        .collect();
    let winner_end = all_end.name("winner_is_end");
    let width = heads[0].beat().width();
    let beat = heads
        .iter()
        .zip(&wins)
        .fold(m.lit(0, width), |acc, (h, w)| {
            acc | w.mux(h.beat(), m.lit(0, width))
        })
        .name("winner_beat");
    let fire = (all_valid & out_ready).name("net_fire");
    for (head, win) in heads.iter().zip(&wins) {
        // Every head is End when the winner is: all leave together.
        head.stream.ready.drive(fire & (winner_end | *win));
    }
    (wins, beat)
}

/// The rank of the one head whose bit of `wins` is set.
pub(super) fn winner_rank<'m>(m: &'m Module, wins: &[Signal<'m>]) -> Signal<'m> {
    let rank_bit = |b: u32| {
        (0..wins.len())
            .filter(|i| i >> b & 1 == 1)
            .map(|i| wins[i])
            .fold(m.lit(0, 1), |acc, w| acc | w)
    };
    let high_first: Vec<Signal> = (0..rank_bits(wins.len())).rev().map(rank_bit).collect();
    m.concat(&high_first).name("winner_rank")
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
    let mut all_valid = m.lit(1, 1);
    let mut all_end = m.lit(1, 1);
    let kind_of = |d| Signal::view(d, &l.kind);
    for i in 0..k {
        let head = MergeHead::new(
            &m,
            i,
            l.width(),
            |d, parent| {
                let kind = kind_of(d).name(&format!("in{i}_kind"));
                let is_end = kind.eq(level_kind::END);
                let is_ref = kind.eq(level_kind::CHILD_REF);
                let xyz = d.view(&l.rec).coords(nl);
                let key_xyz = [0, 1, 2].map(|a| is_ref.mux(parent[a], xyz[a]));
                m.concat(&[is_end, morton_code(&m, key_xyz), kind])
            },
            |d| !kind_of(d).bit(1),
            |d| d.view(&l.rec).coords(nl),
        );
        let is_end = head
            .key()
            .bit(head.key_bits - 1)
            .name(&format!("in{i}_is_end"));
        all_valid = all_valid & head.stream.valid;
        all_end = all_end & is_end;
        heads.push(head);
    }
    let all_valid = all_valid.name("all_heads");
    let (wins, beat) = take_minimum_head(
        &m,
        &heads,
        all_valid,
        all_end,
        out_ready,
        KeyOrder::Combinational,
    );
    Stream {
        valid: all_valid,
        ready: out_ready,
        data: if tag_rank {
            m.concat(&[winner_rank(&m, &wins), beat]).name("net_beat")
        } else {
            beat
        },
    }
    .skid_buffer("out_skid")
    .output("out");
    m
}
