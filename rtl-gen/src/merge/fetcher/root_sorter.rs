//! The root sorter (SPEC.md section 8.9, "Root sorter"; patent paragraph
//! 107's Morton code sorter, bounded): the roots of one input, translated,
//! in stored order, then `End`; out, the same beats in (translated Morton
//! code, inner before leaf) order, stable, then `End`. Sorting the roots is
//! enough (`golden::merge::fetcher::root_sorter::root_sort_transaction` says why): below the
//! top a translation keeps every child's octant.
//!
//! One shift-register queue of `capacity + 1` entries holds output beats:
//! the sets already complete (each ending in its `End` beat) at the head,
//! then the set still arriving (its entries marked *open*), kept sorted.
//! Each clock the head leaves when its set is complete, and one input beat
//! is inserted: a root at its place among the open entries (every open
//! entry compares its key with the new one in parallel, stable), an `End`
//! after them, closing the set. Both happen in the same clock, so the space
//! the output frees is the space the input needs: with no back-pressure the
//! queue never holds more than `capacity + 1` entries and the input never
//! waits (SPEC.md 8.9 proves it). Skid buffers register both handshakes.

use golden::merge::merge_level::unit::{level_kind, BeatLayout};
use golden::params::{bits_to_hold, Params};

use crate::{Module, Signal, Stream};

/// Module name of the root sorter.
pub fn root_sorter_name(p: &Params, capacity: usize) -> String {
    format!("root_sorter_{}_n{capacity}", p.tag())
}

/// The sort key of a beat: the Morton code of its voxel (bit `i` of x, y, z
/// at `3i`, `3i + 1`, `3i + 2`), then the leaf bit (inner first).
fn sort_key<'m>(m: &'m Module, beat: Signal<'m>, l: &BeatLayout) -> Signal<'m> {
    let rec = beat.view(&l.rec);
    let nl = &l.node;
    let c: Vec<Signal> = (0..3).map(|a| rec.view(nl.coord(a))).collect();
    let mut high_first = Vec::new();
    for i in (0..nl.x().width).rev() {
        high_first.extend([c[2].bit(i), c[1].bit(i), c[0].bit(i)]);
    }
    high_first.push(rec.view(nl.leaf()));
    m.concat(&high_first).named_after(beat, "key")
}

/// One queue entry: an output beat, whether the entry holds one, and whether
/// that beat belongs to the set still arriving (sorted, not yet sent).
#[derive(Clone, Copy)]
struct Entry<'m> {
    beat: Signal<'m>,
    valid: Signal<'m>,
    open: Signal<'m>,
}

impl<'m> Entry<'m> {
    fn reg(m: &'m Module, i: usize, width: u32) -> Entry<'m> {
        Entry {
            beat: m.reg(&format!("e{i}_beat"), width),
            valid: m.reg(&format!("e{i}_valid"), 1),
            open: m.reg(&format!("e{i}_open"), 1),
        }
    }

    /// This entry's signals named `e<i>_beat_<role>`, `e<i>_valid_<role>`,
    /// `e<i>_open_<role>`.
    fn named(self, i: usize, role: &str) -> Entry<'m> {
        let name = |s: Signal<'m>, what: &str| s.name(&format!("e{i}_{what}_{role}"));
        Entry {
            beat: name(self.beat, "beat"),
            valid: name(self.valid, "valid"),
            open: name(self.open, "open"),
        }
    }

    /// `a` when `cond`, else `b`.
    fn mux(cond: Signal<'m>, a: Entry<'m>, b: Entry<'m>) -> Entry<'m> {
        Entry {
            beat: cond.mux(a.beat, b.beat),
            valid: cond.mux(a.valid, b.valid),
            open: cond.mux(a.open, b.open),
        }
    }
}

/// The output beat stored for an input beat: a root as it came with `err`
/// 0; an `End` as a bare `End` beat carrying the set's overflow flag.
fn output_beat<'m>(
    m: &'m Module,
    beat: Signal<'m>,
    is_end: Signal<'m>,
    overflow: Signal<'m>,
    lo: &BeatLayout,
) -> Signal<'m> {
    let err = lo.err.expect("output beats have err");
    let root = m.concat(&[m.lit(0, 1), beat]);
    let end = m.lit(0, lo.width()).with_fields(&[
        (lo.kind, m.lit(level_kind::END as u128, lo.kind.width)),
        (err, overflow),
    ]);
    is_end.mux(end, root)
}

/// The root sorter for `p` with room for `capacity >= 1` roots per set:
/// stream `in` of [`BeatLayout::input`] beats (kinds INNER, LEAF, END),
/// stream `out` of [`BeatLayout::output`] beats (same kinds; `err` on END).
pub fn root_sorter_unit(p: &Params, capacity: usize) -> Module {
    let m = Module::new(&root_sorter_name(p, capacity));
    let (li, lo) = (BeatLayout::input(p), BeatLayout::output(p));
    let n = capacity.max(1);
    // Room for a full set and its `End`: the least that cannot deadlock,
    // and enough for one beat per clock (SPEC.md 8.9).
    let depth = n + 1;
    let input = Stream::input(&m, "in", li.width()).skid_buffer("in_skid");
    let out_ready = m.wire("core_out_ready", 1);
    let kind = input.data.view(&li.kind).name("in_kind");
    let is_end = kind.eq(level_kind::END).name("in_is_end");
    let new_key = sort_key(&m, input.data, &li).name("new_key");

    let q: Vec<Entry> = (0..depth).map(|i| Entry::reg(&m, i, lo.width())).collect();
    // Roots of the arriving set taken so far (at most `n`), and whether one
    // beyond `n` was dropped.
    let count_bits = bits_to_hold(n as u64);
    let taken = m.reg("set_taken", count_bits);
    let overflow = m.reg("set_overflow", 1);

    // The head leaves once its set is complete (its `End` is in the queue).
    let head_done = (q[0].valid & !q[0].open).name("head_done");
    let pop = (head_done & out_ready).name("pop");
    let set_full = taken.eq(n as u64).name("set_full");
    let needs_entry = (is_end | !set_full).name("needs_entry");
    let has_room = (!q[depth - 1].valid | pop).name("has_room");
    input.ready.drive(!needs_entry | has_room);
    let fire = (input.valid & (!needs_entry | has_room)).name("in_fire");
    let insert = (fire & needs_entry).name("insert");
    let close = (fire & is_end).name("close");
    let take_root = (insert & !is_end).name("take_root");
    let drop_root = (fire & !needs_entry).name("drop_root");

    // Entry i moves up by one when the new beat belongs below it: it is
    // empty, or open with a greater key (equal keys stay in arrival order,
    // an `End` goes after every open entry). Complete sets are never
    // greater, so the mask is a suffix of the queue.
    let moves_up: Vec<Signal> = (0..depth)
        .map(|i| {
            let greater = q[i].open & !is_end & sort_key(&m, q[i].beat, &lo).gt(new_key);
            (insert & (!q[i].valid | greater)).name(&format!("e{i}_moves_up"))
        })
        .collect();
    let new_entry = Entry {
        beat: output_beat(&m, input.data, is_end, overflow, &lo).name("new_beat"),
        valid: m.lit(1, 1),
        open: !is_end,
    };
    // The queue after the insertion, one entry longer (the last one only
    // filled when the head leaves in the same clock), then shifted down by
    // one when the head leaves.
    let inserted: Vec<Entry> = (0..=depth)
        .map(|i| {
            let here = q.get(i).copied().unwrap_or(Entry {
                beat: m.lit(0, lo.width()),
                valid: m.lit(0, 1),
                open: m.lit(0, 1),
            });
            let moves = moves_up.get(i).copied().unwrap_or(insert);
            let from_below = if i == 0 {
                new_entry
            } else {
                Entry::mux(moves_up[i - 1], q[i - 1], new_entry)
            };
            let e = Entry::mux(moves, from_below, here);
            // Entries 0 and `depth` are read once each, so they stay inline.
            if i == 0 || i == depth {
                e
            } else {
                e.named(i, "inserted")
            }
        })
        .collect();
    for (i, e) in q.iter().enumerate() {
        let next = Entry::mux(pop, inserted[i + 1], inserted[i]);
        e.beat.next(next.beat);
        e.valid.next(next.valid);
        // An `End` closes the set: every entry becomes sendable.
        e.open.next(!close & next.open);
    }
    taken.next(close.mux(
        m.lit(0, count_bits),
        take_root.mux(taken.add(1, count_bits), taken),
    ));
    overflow.next(close.mux(m.lit(0, 1), overflow | drop_root));

    let out = Stream {
        valid: head_done.name("core_out_valid"),
        ready: out_ready,
        data: q[0].beat.name("core_out_data"),
    };
    out.skid_buffer("out_skid").output("out");
    m
}
